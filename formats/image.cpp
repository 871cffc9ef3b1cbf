/* image.cpp: the OpenImageIO shim behind image.h. Every entry point catches all
 * exceptions and turns them, like OpenImageIO's own error strings, into a wrt_status
 * with a message. Writes go to a temporary file beside the target, which is renamed
 * over it only once complete. Depends on OpenImageIO 2.4 and wrt_common. */
#include <cmath>
#include <cstdarg>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdio>

/* wrt_common.h is a C header without linkage braces: give it C linkage here. */
extern "C" {
#include "image.h"
#include "../common/outfile.h"
}

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <exception>
#include <memory>
#include <new>
#include <system_error>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <strings.h>
#include <unistd.h>
#include <vector>

using namespace OIIO;

/* Out of memory before main. The programs that write images link OpenImageIO, whose
 * dependencies start threads and allocate in their static constructors; under a memory
 * limit (ulimit -v, about 450 MB here) one of them throws std::system_error
 * ("Resource temporarily unavailable") before main runs, and the C++ rule for an
 * exception leaving a static initializer is std::terminate: abort(), exit 134, no
 * message of ours. Nothing in main can catch it, and the constructors of shared
 * libraries run before the program's own. The one hook that runs earlier is the
 * executable's .preinit_array, which installs this terminate handler: an uncaught
 * bad_alloc, or a system_error saying memory or threads ran out, becomes the documented
 * out-of-memory exit (7) with one line; anything else still aborts as before. (Below
 * ~400 MB the dynamic loader itself cannot map the libraries and exits 127 with its own
 * message, before any code of ours.) */
static void out_of_memory_terminate() {
    const char *what = nullptr;
    try {
        std::exception_ptr e = std::current_exception();
        if (e) std::rethrow_exception(e);
    } catch (const std::bad_alloc &) {
        what = "std::bad_alloc";
    } catch (const std::system_error &e) {
        if (e.code() == std::errc::resource_unavailable_try_again || e.code() == std::errc::not_enough_memory)
            what = e.what();
    } catch (...) {
    }
    if (!what) abort();
    char msg[256];
    int n = snprintf(msg, sizeof msg, "%s: error: out of memory (%s, uncaught, possibly before main while the "
                     "libraries loaded)\n", program_invocation_short_name, what);
    ssize_t w = write(2, msg, n > 0 ? (size_t)n : 0);
    (void)w;
    _exit(7); /* WRT_EXIT_NOMEM */
}

static void install_terminate(int, char **, char **) { std::set_terminate(out_of_memory_terminate); }
/* Runs before the initializers of every shared library (an executable's only). */
__attribute__((section(".preinit_array"), used)) static void (*const wrt_preinit)(int, char **, char **) =
    install_terminate;

static std::string ext_of(const char *path) {
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash)) return "";
    return dot;
}

/* Writes all n bytes of p to fd, then syncs it; 0 on success, else errno. */
static int write_all(int fd, const unsigned char *p, size_t n) {
    while (n > 0) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return w < 0 ? errno : EIO;
        p += w;
        n -= (size_t)w;
    }
    return fsync(fd) != 0 ? errno : 0;
}

/* Encodes the image into memory (OpenImageIO's IOVecOutput) when the format can; else
 * lets the writer fill tmp by name and then reads it back whole. OpenImageIO's PNG
 * writer ignores failed writes (a full disk, ulimit -f: a cut file and success), so
 * the bytes must reach the disk through a path that checks every write. */
static bool encode(ImageOutput *out, const std::string &tmp, int fd, ImageSpec spec, TypeDesc type, const void *px,
                   std::string &err) {
    if (out->supports("ioproxy")) {
        std::vector<unsigned char> bytes;
        Filesystem::IOVecOutput mem(bytes);
        Filesystem::IOProxy *proxy = &mem;
        spec.attribute("oiio:ioproxy", TypeDesc::PTR, &proxy);
        bool ok = out->open(tmp, spec) && out->write_image(type, px);
        ok = out->close() && ok;
        if (!ok) { err = out->geterror(); return false; }
        int e = write_all(fd, bytes.data(), bytes.size());
        if (e) { err = strerror(e); return false; }
        return true;
    }
    bool ok = out->open(tmp, spec) && out->write_image(type, px);
    ok = out->close() && ok;
    if (!ok) { err = out->geterror(); return false; }
    std::vector<float> back((size_t)spec.width * spec.height * 3);
    auto in = ImageInput::open(tmp);
    ok = in && in->spec().width == spec.width && in->spec().height == spec.height &&
         in->read_image(0, 0, 0, 3, TypeDesc::FLOAT, back.data());
    if (!ok) err = "the written file does not read back whole (" + (in ? in->geterror() : geterror()) + ")";
    return ok;
}

static wrt_status write_any(const char *path, const void *px, TypeDesc type, int w, int h) {
    if (!path || !px || w <= 0 || h <= 0 || (int64_t)w * h > (int64_t)1 << 28)
        return wrt_fail(WRT_ERR_INVALID_ARG, "image %s: bad size %dx%d", path ? path : "(null)", w, h);
    /* A regular file only (common/outfile.h): a link, FIFO or device is refused. */
    if (wrt_output_check(path) != WRT_OK) return WRT_ERR_IO;
    std::string tmp;
    int fd = -1;
    try {
        /* The temporary is made here with O_EXCL (never through a link planted at its
         * name); the bytes are then written to it (encode). */
        std::string ext = ext_of(path);
        char *name = nullptr;
        fd = wrt_output_tmpfile(path, ext.c_str(), &name);
        if (fd < 0) return WRT_ERR_IO;
        tmp = name;
        free(name);
        std::unique_ptr<ImageOutput> out = ImageOutput::create(path);
        if (!out) {
            std::string e = geterror();
            close(fd);
            unlink(tmp.c_str());
            return wrt_fail(WRT_ERR_IO, "%s: no writer for this file type: %s", path, e.c_str());
        }
        ImageSpec spec(w, h, 3, type);
        if (type == TypeDesc::FLOAT) spec.attribute("compression", "zip");
        std::string e;
        bool ok = encode(out.get(), tmp, fd, spec, type, px, e);
        ok = close(fd) == 0 && ok;
        fd = -1;
        if (!ok) {
            unlink(tmp.c_str());
            return wrt_fail(WRT_ERR_IO, "%s: write failed: %s", path, e.empty() ? strerror(errno) : e.c_str());
        }
        if (wrt_output_check(path) != WRT_OK) { /* it became a link or a FIFO while we wrote */
            unlink(tmp.c_str());
            return WRT_ERR_IO;
        }
        if (rename(tmp.c_str(), path) != 0) {
            unlink(tmp.c_str());
            return wrt_fail(WRT_ERR_IO, "%s: cannot rename the temporary file over it", path);
        }
        return WRT_OK;
    } catch (const std::bad_alloc &) {
        if (fd >= 0) close(fd);
        if (!tmp.empty()) unlink(tmp.c_str());
        return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory while writing", path);
    } catch (const std::exception &e) {
        if (fd >= 0) close(fd);
        if (!tmp.empty()) unlink(tmp.c_str());
        return wrt_fail(WRT_ERR_IO, "%s: %s", path, e.what());
    } catch (...) {
        if (fd >= 0) close(fd);
        if (!tmp.empty()) unlink(tmp.c_str());
        return wrt_fail(WRT_ERR_IO, "%s: unknown error while writing", path);
    }
}

extern "C" wrt_status wrt_image_write_exr(const char *path, const float *rgb, int width, int height) {
    return write_any(path, rgb, TypeDesc::FLOAT, width, height);
}

extern "C" wrt_status wrt_image_write_rgb8(const char *path, const uint8_t *rgb, int width, int height) {
    return write_any(path, rgb, TypeDesc::UINT8, width, height);
}

extern "C" wrt_status wrt_image_read(const char *path, float **rgb, int *width, int *height) {
    *rgb = nullptr;
    *width = *height = 0;
    try {
        std::unique_ptr<ImageInput> in = ImageInput::open(path);
        if (!in) {
            std::string e = geterror();
            return wrt_fail(WRT_ERR_IO, "%s: cannot read: %s", path, e.c_str());
        }
        const ImageSpec &spec = in->spec();
        int w = spec.width, h = spec.height, c = spec.nchannels;
        if (w <= 0 || h <= 0 || c <= 0 || (int64_t)w * h > (int64_t)1 << 28)
            return wrt_fail(WRT_ERR_CORRUPT, "%s: bad image size %dx%dx%d", path, w, h, c);
        std::vector<float> all((size_t)w * h * c);
        if (!in->read_image(0, 0, 0, c, TypeDesc::FLOAT, all.data())) {
            std::string e = in->geterror();
            return wrt_fail(WRT_ERR_CORRUPT, "%s: read failed: %s", path, e.c_str());
        }
        in->close();
        float *o = (float *)malloc((size_t)w * h * 3 * sizeof(float));
        if (!o) return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory", path);
        for (size_t i = 0; i < (size_t)w * h; i++)
            for (int k = 0; k < 3; k++) o[3 * i + k] = all[i * c + (k < c ? k : 0)];
        *rgb = o;
        *width = w;
        *height = h;
        return WRT_OK;
    } catch (const std::bad_alloc &) {
        return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory while reading", path);
    } catch (const std::exception &e) {
        return wrt_fail(WRT_ERR_IO, "%s: %s", path, e.what());
    } catch (...) {
        return wrt_fail(WRT_ERR_IO, "%s: unknown error while reading", path);
    }
}

extern "C" int wrt_image_is_exr(const char *path) {
    std::string e = path ? ext_of(path) : "";
    return strcasecmp(e.c_str(), ".exr") == 0;
}
