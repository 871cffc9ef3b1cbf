/* gltf_shim.cpp: reads glTF 2.0 (.gltf JSON or .glb) with tinygltf and hands scene.c
 * plain C arrays (see gltf_shim.h). tinygltf parses the JSON and decodes buffers and
 * images; it does not bounds-check accessors, so every accessor is validated here
 * (component type, element type, count x stride inside its bufferView, bufferView
 * inside its buffer, computed without overflow) before a byte is read, and every
 * index is checked against the vertex count. The node hierarchy of the default scene
 * (or scene 0) is flattened with full transforms (matrix, or T*R*S, nested); a node
 * reached twice (a cycle, or a shared child) is refused. GLB framing, the JSON depth
 * and the strict schema/KHR checks on the raw JSON are in gltf_strict.cpp, run here
 * before tinygltf sees the file. Every exception is caught at the boundary. Depends on
 * tinygltf 2.7, nlohmann json and stb_image (Debian packages). This is the scene-input
 * stage that precedes the paper's precomputation (Kontkanen et al. 2006, section 3). */
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include <sys/stat.h>

#define TINYGLTF_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <tiny_gltf.h>

#include "gltf_shim.h"
#include "gltf_internal.h"
extern "C" {
#include "../common/limits.h"
#include "../common/text.h"
}

/* The error thrown inside the shim (shim_error, gltf_internal.h), with its message. */
__attribute__((format(printf, 2, 3))) shim_error make_error(wrt_status s, const char *fmt, ...) {
    char buf[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return shim_error{s, buf};
}

namespace {

/* Largest decoded texture we accept (texels), and most triangles in one scene. */
const double kMaxTexels = 64.0 * 1024 * 1024;
const size_t kMaxSceneTriangles = 50u * 1000u * 1000u;
const size_t kMaxSceneVertices = 150u * 1000u * 1000u;

void copy_name(char dst[64], const std::string &src, const char *fallback, size_t index) {
    if (src.empty()) {
        snprintf(dst, 64, "%s%zu", fallback, index);
    } else {
        wrt_utf8_copy(dst, 64, src.c_str()); /* cut at a character boundary */
    }
}

/* ---- 4x4 column-major matrices ---- */
struct mat4 {
    double m[16];
};

mat4 mat_identity() {
    mat4 r{};
    r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1;
    return r;
}

mat4 mat_mul(const mat4 &a, const mat4 &b) {
    mat4 r{};
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a.m[k * 4 + row] * b.m[c * 4 + k];
            r.m[c * 4 + row] = s;
        }
    return r;
}

void mat_point(const mat4 &a, const double p[3], double out[3]) {
    for (int r = 0; r < 3; r++)
        out[r] = a.m[r] * p[0] + a.m[4 + r] * p[1] + a.m[8 + r] * p[2] + a.m[12 + r];
}

void mat_dir(const mat4 &a, const double d[3], double out[3]) {
    for (int r = 0; r < 3; r++) out[r] = a.m[r] * d[0] + a.m[4 + r] * d[1] + a.m[8 + r] * d[2];
    double l = std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    if (l > 0 && std::isfinite(l))
        for (int r = 0; r < 3; r++) out[r] /= l;
}

/* Determinant of the upper-left 3x3 (the linear part). */
double mat_det3(const mat4 &a) {
    const double *m = a.m;
    return m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
           m[8] * (m[1] * m[6] - m[5] * m[2]);
}

/* The node's local transform: its matrix if it has one, else T * R * S. */
mat4 node_local(const tinygltf::Node &n, size_t index, const char *label) {
    if (n.matrix.size() == 16) {
        mat4 r;
        for (int i = 0; i < 16; i++) r.m[i] = n.matrix[i];
        return r;
    }
    if (!n.matrix.empty())
        throw make_error(WRT_ERR_PARSE, "%s: node %zu: matrix has %zu numbers, expected 16", label,
                         index, n.matrix.size());
    if ((!n.translation.empty() && n.translation.size() != 3) ||
        (!n.rotation.empty() && n.rotation.size() != 4) || (!n.scale.empty() && n.scale.size() != 3))
        throw make_error(WRT_ERR_PARSE,
                         "%s: node %zu: translation/rotation/scale must have 3/4/3 numbers", label,
                         index);
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    for (size_t i = 0; i < n.translation.size(); i++) t[i] = n.translation[i];
    for (size_t i = 0; i < n.rotation.size(); i++) q[i] = n.rotation[i];
    for (size_t i = 0; i < n.scale.size(); i++) s[i] = n.scale[i];
    double ql = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(ql > 0) || !std::isfinite(ql))
        throw make_error(WRT_ERR_PARSE, "%s: node %zu: rotation quaternion has zero length", label,
                         index);
    double x = q[0] / ql, y = q[1] / ql, z = q[2] / ql, w = q[3] / ql;
    /* rotation matrix columns */
    double r[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)};
    mat4 m = mat_identity();
    for (int c = 0; c < 3; c++)
        for (int row = 0; row < 3; row++) m.m[c * 4 + row] = r[c * 3 + row] * s[c];
    m.m[12] = t[0];
    m.m[13] = t[1];
    m.m[14] = t[2];
    return m;
}

/* ---- accessors ---- */
size_t component_size(int ct) {
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

double read_component(const unsigned char *p, int ct, bool normalized) {
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
        int8_t v;
        memcpy(&v, p, 1);
        return normalized ? std::fmax(v / 127.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0 : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t v;
        memcpy(&v, p, 2);
        return normalized ? std::fmax(v / 32767.0, -1.0) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t v;
        memcpy(&v, p, 2);
        return normalized ? v / 65535.0 : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: {
        uint32_t v;
        memcpy(&v, p, 4);
        return v;
    }
    default: {
        float v;
        memcpy(&v, p, 4);
        return v;
    }
    }
}

/* Where one accessor's elements lie, after validation. */
struct accessor_view {
    const unsigned char *base;
    size_t count, stride, ncomp;
    int ct;
    bool normalized;
};

/* Validates accessor `ai` for use as `what` of mesh m primitive p: it must have
 * `want_type` elements of a component type in `allowed`, and count x stride must lie
 * inside its bufferView, itself inside its buffer. Throws a shim_error naming all. */
accessor_view check_accessor(const tinygltf::Model &model, int ai, const char *what, int want_type,
                             const std::vector<int> &allowed, size_t mi, size_t pi,
                             const char *label) {
    char where[200];
    snprintf(where, sizeof where, "%s: mesh %zu primitive %zu: %s accessor %d", label, mi, pi, what, ai);
    if (ai < 0 || size_t(ai) >= model.accessors.size())
        throw make_error(WRT_ERR_PARSE, "%s does not exist (the file has %zu accessors)", where,
                         model.accessors.size());
    const tinygltf::Accessor &a = model.accessors[size_t(ai)];
    if (a.sparse.isSparse)
        throw make_error(WRT_ERR_UNSUPPORTED, "%s is sparse (not supported)", where);
    bool ok_ct = false;
    for (int c : allowed) ok_ct = ok_ct || c == a.componentType;
    if (!ok_ct || component_size(a.componentType) == 0)
        throw make_error(WRT_ERR_PARSE, "%s has componentType %d, not allowed here", where,
                         a.componentType);
    if (a.type != want_type)
        throw make_error(WRT_ERR_PARSE, "%s has type %d, expected %s", where, a.type,
                         want_type == TINYGLTF_TYPE_VEC3 ? "VEC3" : want_type == TINYGLTF_TYPE_VEC2 ? "VEC2" : "SCALAR");
    if (a.count == 0) throw make_error(WRT_ERR_PARSE, "%s has count 0", where);
    if (a.bufferView < 0 || size_t(a.bufferView) >= model.bufferViews.size())
        throw make_error(WRT_ERR_PARSE, "%s refers to bufferView %d, which does not exist (%zu)", where,
                         a.bufferView, model.bufferViews.size());
    const tinygltf::BufferView &bv = model.bufferViews[size_t(a.bufferView)];
    if (bv.buffer < 0 || size_t(bv.buffer) >= model.buffers.size())
        throw make_error(WRT_ERR_PARSE, "%s: bufferView %d refers to buffer %d, which does not exist",
                         where, a.bufferView, bv.buffer);
    const tinygltf::Buffer &buf = model.buffers[size_t(bv.buffer)];
    size_t blen = buf.data.size();
    if (bv.byteOffset > blen || bv.byteLength > blen - bv.byteOffset)
        throw make_error(WRT_ERR_PARSE,
                         "%s: bufferView %d (offset %zu, length %zu) runs past the end of buffer %d "
                         "(%zu bytes; truncated or missing data?)",
                         where, a.bufferView, bv.byteOffset, bv.byteLength, bv.buffer, blen);
    size_t ncomp = want_type == TINYGLTF_TYPE_VEC3 ? 3 : want_type == TINYGLTF_TYPE_VEC2 ? 2 : 1;
    size_t esize = ncomp * component_size(a.componentType);
    size_t stride = bv.byteStride ? bv.byteStride : esize;
    if (stride < esize)
        throw make_error(WRT_ERR_PARSE, "%s: byteStride %zu is smaller than the element (%zu bytes)",
                         where, stride, esize);
    size_t vlen = bv.byteLength;
    if (a.byteOffset > vlen || esize > vlen - a.byteOffset ||
        (a.count - 1) > (vlen - a.byteOffset - esize) / stride)
        throw make_error(WRT_ERR_PARSE,
                         "%s: count %zu x stride %zu at offset %zu does not fit in bufferView %d "
                         "(%zu bytes)",
                         where, a.count, stride, a.byteOffset, a.bufferView, vlen);
    accessor_view v;
    v.base = buf.data.data() + bv.byteOffset + a.byteOffset;
    v.count = a.count;
    v.stride = stride;
    v.ncomp = ncomp;
    v.ct = a.componentType;
    v.normalized = a.normalized;
    return v;
}

/* ---- textures ---- */
double srgb_to_linear(double c) {
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

/* Mean of the texture's RGB(A) texels; false if it has no decoded image. */
bool texture_mean(const tinygltf::Model &model, int tex, bool srgb, double mean[4]) {
    if (tex < 0 || size_t(tex) >= model.textures.size()) return false;
    int src = model.textures[size_t(tex)].source;
    if (src < 0 || size_t(src) >= model.images.size()) return false;
    const tinygltf::Image &im = model.images[size_t(src)];
    if (im.width <= 0 || im.height <= 0 || im.component < 1 || im.component > 4 || im.bits != 8)
        return false;
    size_t n = size_t(im.width) * size_t(im.height);
    size_t nc = size_t(im.component);
    if (im.image.size() < n * nc) return false;
    double lut[256];
    for (int i = 0; i < 256; i++) lut[i] = srgb ? srgb_to_linear(i / 255.0) : i / 255.0;
    double sum[4] = {0, 0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        const unsigned char *t = &im.image[i * nc];
        for (size_t c = 0; c < 4; c++) {
            if (c < 3) {
                size_t k = nc >= 3 ? c : 0; /* grey images replicate */
                sum[c] += lut[t[k]];
            } else {
                sum[3] += nc == 4 ? t[3] / 255.0 : (nc == 2 ? t[1] / 255.0 : 1.0);
            }
        }
    }
    for (int c = 0; c < 4; c++) mean[c] = sum[c] / double(n);
    return true;
}

/* glTF's wrap mode as texture.h's (0 repeat, 1 clamp, 2 mirror). */
int wrap_mode(int gl) {
    return gl == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE ? 1 : gl == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT ? 2 : 0;
}

/* Keeps a base-colour texture's texels (sRGB bytes, RGB) and its sampler's wrap modes
 * (the image was checked by texture_mean). */
void keep_texture(const tinygltf::Model &model, int tex, wrt_gltf_material &o) {
    const tinygltf::Texture &t = model.textures[size_t(tex)];
    const tinygltf::Image &im = model.images[size_t(t.source)];
    size_t n = size_t(im.width) * size_t(im.height), nc = size_t(im.component);
    unsigned char *rgb = static_cast<unsigned char *>(malloc(n * 3));
    if (!rgb) throw std::bad_alloc();
    for (size_t i = 0; i < n; i++)
        for (size_t c = 0; c < 3; c++) rgb[i * 3 + c] = im.image[i * nc + (nc >= 3 ? c : 0)];
    o.base_tex = rgb;
    o.base_tex_w = im.width;
    o.base_tex_h = im.height;
    o.base_tex_wrap[0] = o.base_tex_wrap[1] = 0;
    if (t.sampler >= 0 && size_t(t.sampler) < model.samplers.size()) {
        o.base_tex_wrap[0] = wrap_mode(model.samplers[size_t(t.sampler)].wrapS);
        o.base_tex_wrap[1] = wrap_mode(model.samplers[size_t(t.sampler)].wrapT);
    }
}

/* Image decoder given to tinygltf: stb_image, 8 bits per channel, size-capped. */
bool decode_image(tinygltf::Image *image, const int image_idx, std::string *err, std::string *warn,
                  int req_width, int req_height, const unsigned char *bytes, int size, void *user) {
    int w = 0, h = 0, comp = 0;
    if (!stbi_info_from_memory(bytes, size, &w, &h, &comp)) {
        if (warn) *warn += "image " + std::to_string(image_idx) + ": unknown or broken image format\n";
        return true; /* the texture is then ignored, with a warning */
    }
    if (w <= 0 || h <= 0 || double(w) * double(h) > kMaxTexels) {
        if (err) *err += "image " + std::to_string(image_idx) + ": absurd size\n";
        return false;
    }
    unsigned char *px = stbi_load_from_memory(bytes, size, &w, &h, &comp, 4);
    if (!px) {
        if (warn) *warn += "image " + std::to_string(image_idx) + ": could not decode\n";
        return true;
    }
    image->width = w;
    image->height = h;
    image->component = 4;
    image->bits = 8;
    image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    image->image.assign(px, px + size_t(w) * size_t(h) * 4);
    stbi_image_free(px);
    return true;
}

/* ---- file access given to tinygltf: regular files only, size-checked ---- */
const long long kMaxExternalFile = 4LL << 30;

bool fs_exists(const std::string &path, void *) {
    struct stat st;
    return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string fs_expand(const std::string &path, void *) { return path; }

/* What the file callbacks know: the files read, the scene's folder (resolved) and
 * whether files outside it may be read. */
struct fs_context {
    std::vector<std::string> files;
    std::string base_real; /* realpath of the scene's folder, "" if it has none */
    bool allow_outside = false;
};

/* The second line of defence behind the uri check of the strict pass: the file, links
 * resolved, must lie inside the scene's folder (also resolved). */
bool inside_base(const fs_context &c, const std::string &path) {
    if (c.allow_outside) return true;
    if (c.base_real.empty()) return false;
    char *r = realpath(path.c_str(), nullptr);
    if (!r) return false;
    std::string rp = r;
    free(r);
    const std::string &b = c.base_real;
    return rp.size() > b.size() && rp.compare(0, b.size(), b) == 0 && (b == "/" || rp[b.size()] == '/');
}

bool fs_read(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *user) {
    fs_context *ctx = static_cast<fs_context *>(user);
    if (ctx && !inside_base(*ctx, path)) {
        if (err) *err += path + ": outside the scene's folder (refused unless --allow-outside-files)\n";
        return false;
    }
    if (ctx) ctx->files.push_back(path); /* an input */
    FILE *f = fopen(path.c_str(), "rb");
    if (!f) {
        if (err) *err += "cannot open " + path + ": " + strerror(errno) + "\n";
        return false;
    }
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size <= 0 ||
        st.st_size > kMaxExternalFile) {
        fclose(f);
        if (err) *err += path + ": not a regular non-empty file under 4 GiB\n";
        return false;
    }
    out->resize(size_t(st.st_size));
    size_t got = fread(out->data(), 1, out->size(), f);
    fclose(f);
    if (got != out->size()) {
        if (err) *err += path + ": short read\n";
        return false;
    }
    return true;
}

bool fs_write(std::string *err, const std::string &, const std::vector<unsigned char> &, void *) {
    if (err) *err += "writing is not supported\n";
    return false;
}

/* ---- the reader ---- */
struct reader {
    const tinygltf::Model &model;
    const char *label;
    std::vector<wrt_gltf_prim> prims;
    std::vector<wrt_gltf_light> lights;
    wrt_gltf_camera camera{};
    std::vector<char> visited;
    size_t total_tris = 0, total_verts = 0;

    reader(const tinygltf::Model &m, const char *l) : model(m), label(l) {}

    ~reader() {
        for (wrt_gltf_prim &p : prims) {
            free(p.pos);
            free(p.idx);
            free(p.uv);
            free(p.nrm);
        }
    }

    /* NORMAL (glTF: FLOAT VEC3, one per vertex), to world space by the cofactor matrix of
     * the node's linear part (its inverse transpose times the determinant; the sign of the
     * determinant keeps a mirrored node's normals outward), then made unit. A normal that
     * is not finite or of zero length is refused with its accessor element. */
    void read_normals(const tinygltf::Primitive &p, size_t npos, const mat4 &world, size_t mi, size_t pi,
                      size_t node, wrt_gltf_prim &q) {
        auto na = p.attributes.find("NORMAL");
        if (na == p.attributes.end()) return;
        accessor_view nv = check_accessor(model, na->second, "NORMAL", TINYGLTF_TYPE_VEC3,
                                          {TINYGLTF_COMPONENT_TYPE_FLOAT}, mi, pi, label);
        if (nv.count != npos)
            throw make_error(WRT_ERR_PARSE, "%s: mesh %zu primitive %zu: NORMAL has %zu elements, POSITION %zu",
                             label, mi, pi, nv.count, npos);
        const double *m = world.m; /* column-major: m[c * 4 + r] */
        double cof[3][3], det = mat_det3(world), sg = det < 0 ? -1.0 : 1.0;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) {
                int r1 = (r + 1) % 3, r2 = (r + 2) % 3, c1 = (c + 1) % 3, c2 = (c + 2) % 3;
                cof[r][c] = m[c1 * 4 + r1] * m[c2 * 4 + r2] - m[c2 * 4 + r1] * m[c1 * 4 + r2];
            }
        q.nrm = static_cast<float *>(malloc(npos * 3 * sizeof(float)));
        if (!q.nrm) throw std::bad_alloc();
        size_t cs = component_size(nv.ct);
        for (size_t v = 0; v < npos; v++) {
            double ln[3], wn[3], l2 = 0;
            for (size_t c = 0; c < 3; c++) ln[c] = read_component(nv.base + v * nv.stride + c * cs, nv.ct, false);
            for (int r = 0; r < 3; r++) {
                wn[r] = sg * (cof[r][0] * ln[0] + cof[r][1] * ln[1] + cof[r][2] * ln[2]);
                l2 += wn[r] * wn[r];
            }
            double l = std::sqrt(l2);
            double l_local = std::sqrt(ln[0] * ln[0] + ln[1] * ln[1] + ln[2] * ln[2]);
            /* A unit normal that the node's transform collapses (a scale of 0 on an axis):
             * the transform is at fault, not the normal (the message named the normal). */
            if (!(l > 1e-12) && std::isfinite(l) && l_local > 1e-6 && std::isfinite(l_local))
                throw make_error(WRT_ERR_PARSE,
                                 "%s: nodes[%zu]: its world transform has zero scale (determinant %g): it "
                                 "flattens mesh %zu (primitive %zu, NORMAL element %zu (%g, %g, %g) has no "
                                 "direction after it)",
                                 label, node, det, mi, pi, v, ln[0], ln[1], ln[2]);
            if (!(l > 1e-12) || !std::isfinite(l) || !std::isfinite(ln[0] + ln[1] + ln[2]))
                throw make_error(WRT_ERR_PARSE,
                                 "%s: meshes[%zu].primitives[%zu].attributes.NORMAL element %zu: (%g, %g, %g) "
                                 "is not a direction (glTF normals are unit vectors)",
                                 label, mi, pi, v, ln[0], ln[1], ln[2]);
            for (int r = 0; r < 3; r++) q.nrm[3 * v + size_t(r)] = float(wn[r] / l);
        }
    }

    void add_primitive(size_t mi, size_t pi, size_t node, const mat4 &world) {
        const tinygltf::Primitive &p = model.meshes[mi].primitives[pi];
        if (p.mode != TINYGLTF_MODE_TRIANGLES)
            throw make_error(WRT_ERR_UNSUPPORTED,
                             "%s: mesh %zu primitive %zu: mode %d is not supported (only TRIANGLES, 4)",
                             label, mi, pi, p.mode);
        auto it = p.attributes.find("POSITION");
        if (it == p.attributes.end())
            throw make_error(WRT_ERR_PARSE, "%s: mesh %zu primitive %zu has no POSITION attribute",
                             label, mi, pi);
        if (p.material < -1 || (p.material >= 0 && size_t(p.material) >= model.materials.size()))
            throw make_error(WRT_ERR_PARSE, "%s: mesh %zu primitive %zu: material %d does not exist",
                             label, mi, pi, p.material);
        accessor_view pv = check_accessor(
            model, it->second, "POSITION", TINYGLTF_TYPE_VEC3,
            {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_BYTE,
             TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_SHORT,
             TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
            mi, pi, label);
        size_t ntri;
        accessor_view iv{};
        if (p.indices >= 0) {
            iv = check_accessor(model, p.indices, "indices", TINYGLTF_TYPE_SCALAR,
                                {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                                 TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                 TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
                                mi, pi, label);
            if (iv.count % 3)
                throw make_error(WRT_ERR_PARSE,
                                 "%s: mesh %zu primitive %zu: indices accessor %d has count %zu, not a "
                                 "multiple of 3",
                                 label, mi, pi, p.indices, iv.count);
            ntri = iv.count / 3;
        } else {
            if (pv.count % 3)
                throw make_error(WRT_ERR_PARSE,
                                 "%s: mesh %zu primitive %zu: non-indexed with %zu vertices, not a "
                                 "multiple of 3",
                                 label, mi, pi, pv.count);
            ntri = pv.count / 3;
        }
        total_tris += ntri;
        total_verts += pv.count;
        if (total_tris > kMaxSceneTriangles || total_verts > kMaxSceneVertices)
            throw make_error(WRT_ERR_UNSUPPORTED,
                             "%s: mesh %zu primitive %zu: the scene exceeds %zu triangles or %zu "
                             "vertices",
                             label, mi, pi, kMaxSceneTriangles, kMaxSceneVertices);
        wrt_gltf_prim out{};
        out.mesh = int(mi);
        out.prim = int(pi);
        out.node = int(node);
        out.material = p.material;
        prims.push_back(out);
        wrt_gltf_prim &q = prims.back();
        q.pos = static_cast<double *>(malloc(pv.count * 3 * sizeof(double)));
        q.idx = static_cast<uint32_t *>(malloc(ntri * 3 * sizeof(uint32_t)));
        if (!q.pos || !q.idx) throw std::bad_alloc();
        q.npos = pv.count;
        q.ntri = ntri;
        for (size_t v = 0; v < pv.count; v++) {
            double lp[3];
            const unsigned char *e = pv.base + v * pv.stride;
            size_t cs = component_size(pv.ct);
            for (size_t c = 0; c < 3; c++) lp[c] = read_component(e + c * cs, pv.ct, pv.normalized);
            mat_point(world, lp, &q.pos[v * 3]);
        }
        for (size_t i = 0; i < ntri * 3; i++) {
            size_t k = i;
            if (p.indices >= 0) {
                k = size_t(read_component(iv.base + i * iv.stride, iv.ct, false));
                if (k >= pv.count)
                    throw make_error(WRT_ERR_PARSE,
                                     "%s: mesh %zu primitive %zu triangle %zu: index %zu (indices "
                                     "accessor %d element %zu) is past the vertex count %zu",
                                     label, mi, pi, i / 3, k, p.indices, i, pv.count);
            }
            q.idx[i] = uint32_t(k);
        }
        /* TEXCOORD_0 (glTF: FLOAT, or normalized UNSIGNED_BYTE / UNSIGNED_SHORT), one per
         * vertex, for the quad-to-source map's (u, v) frames */
        auto tc = p.attributes.find("TEXCOORD_0");
        if (tc != p.attributes.end()) {
            accessor_view tv = check_accessor(
                model, tc->second, "TEXCOORD_0", TINYGLTF_TYPE_VEC2,
                {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                 TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                mi, pi, label);
            if (tv.count != pv.count)
                throw make_error(WRT_ERR_PARSE,
                                 "%s: mesh %zu primitive %zu: TEXCOORD_0 has %zu elements, POSITION %zu",
                                 label, mi, pi, tv.count, pv.count);
            q.uv = static_cast<float *>(malloc(pv.count * 2 * sizeof(float)));
            if (!q.uv) throw std::bad_alloc();
            size_t cs = component_size(tv.ct);
            for (size_t v = 0; v < tv.count; v++)
                for (size_t c = 0; c < 2; c++)
                    q.uv[2 * v + c] = float(read_component(tv.base + v * tv.stride + c * cs, tv.ct, tv.normalized));
            for (size_t i = 0; i < 2 * tv.count && q.uv; i++)
                if (!std::isfinite(q.uv[i])) { /* unusable: the map says "no (u, v)" */
                    free(q.uv);
                    q.uv = nullptr;
                }
        }
        read_normals(p, pv.count, world, mi, pi, node, q);
        /* glTF: a node whose world transform has a negative determinant turns its
         * triangles' front faces clockwise; swapping two corners keeps the rest of the
         * loader on counter-clockwise fronts. */
        if (mat_det3(world) < 0) {
            q.mirrored = 1;
            for (size_t t = 0; t < ntri; t++) std::swap(q.idx[3 * t + 1], q.idx[3 * t + 2]);
        }
    }

    void add_light(int li, size_t node, const mat4 &world) {
        if (li < 0 || size_t(li) >= model.lights.size())
            throw make_error(WRT_ERR_PARSE, "%s: node %zu: light %d does not exist (%zu lights)", label,
                             node, li, model.lights.size());
        const tinygltf::Light &l = model.lights[size_t(li)];
        wrt_gltf_light o{};
        o.type = l.type == "point" ? WRT_GLTF_LIGHT_POINT
                 : l.type == "spot" ? WRT_GLTF_LIGHT_SPOT
                 : l.type == "directional" ? WRT_GLTF_LIGHT_DIRECTIONAL
                                           : WRT_GLTF_LIGHT_OTHER;
        copy_name(o.name, l.name, "light", size_t(li));
        o.node = int(node);
        /* The light's axis is the node's -Z: a singular transform has none, a mirroring one
         * (negative determinant) turns it around. */
        double det = mat_det3(world);
        if (!(std::fabs(det) > 1e-18) || !std::isfinite(det))
            throw make_error(WRT_ERR_PARSE,
                             "%s: nodes[%zu]: light %d's world transform has zero scale (determinant "
                             "%g): no position frame or direction",
                             label, node, li, det);
        if (det < 0 && (o.type == WRT_GLTF_LIGHT_SPOT || o.type == WRT_GLTF_LIGHT_DIRECTIONAL))
            throw make_error(WRT_ERR_PARSE,
                             "%s: nodes[%zu]: %s light %d's world transform has a negative scale "
                             "(determinant %g): it mirrors the light's direction",
                             label, node, o.type == WRT_GLTF_LIGHT_SPOT ? "spot" : "directional", li, det);
        const double origin[3] = {0, 0, 0}, minus_z[3] = {0, 0, -1};
        mat_point(world, origin, o.pos);
        mat_dir(world, minus_z, o.dir);
        for (int c = 0; c < 3; c++) o.color[c] = l.color.size() == 3 ? l.color[size_t(c)] : 1.0;
        o.intensity = l.intensity;
        o.range = l.range;
        o.inner_cone = l.spot.innerConeAngle;
        o.outer_cone = l.spot.outerConeAngle;
        lights.push_back(o);
    }

    void add_camera(int ci, size_t node, const mat4 &world) {
        if (ci < 0 || size_t(ci) >= model.cameras.size())
            throw make_error(WRT_ERR_PARSE, "%s: node %zu: camera %d does not exist", label, node, ci);
        const tinygltf::Camera &c = model.cameras[size_t(ci)];
        if (camera.present || c.type != "perspective") return;
        double det = mat_det3(world);
        if (!(std::fabs(det) > 1e-18) || !std::isfinite(det))
            throw make_error(WRT_ERR_PARSE,
                             "%s: nodes[%zu]: camera %d's world transform has zero scale (determinant "
                             "%g): no view direction",
                             label, node, ci, det);
        camera.present = 1;
        camera.node = int(node);
        const double origin[3] = {0, 0, 0}, minus_z[3] = {0, 0, -1}, plus_y[3] = {0, 1, 0};
        mat_point(world, origin, camera.pos);
        mat_dir(world, minus_z, camera.dir);
        mat_dir(world, plus_y, camera.up);
        camera.yfov = c.perspective.yfov;
        camera.aspect = c.perspective.aspectRatio;
        camera.znear = c.perspective.znear;
        camera.zfar = c.perspective.zfar;
    }

    void visit(int ni, const mat4 &parent, size_t depth) {
        if (ni < 0 || size_t(ni) >= model.nodes.size())
            throw make_error(WRT_ERR_PARSE, "%s: node %d does not exist (%zu nodes)", label, ni,
                             model.nodes.size());
        size_t n = size_t(ni);
        if (visited[n])
            throw make_error(WRT_ERR_PARSE,
                             "%s: node %zu is reached twice (a cycle or a shared child: the node "
                             "hierarchy must be a forest)",
                             label, n);
        visited[n] = 1;
        if (depth > 512)
            throw make_error(WRT_ERR_UNSUPPORTED, "%s: node %zu: hierarchy deeper than 512 levels",
                             label, n);
        const tinygltf::Node &node = model.nodes[n];
        mat4 world = mat_mul(parent, node_local(node, n, label));
        for (int i = 0; i < 16; i++)
            if (!std::isfinite(world.m[i]))
                throw make_error(WRT_ERR_PARSE, "%s: node %zu: transform is not finite", label, n);
        if (node.mesh >= 0) {
            if (size_t(node.mesh) >= model.meshes.size())
                throw make_error(WRT_ERR_PARSE, "%s: node %zu: mesh %d does not exist (%zu meshes)",
                                 label, n, node.mesh, model.meshes.size());
            size_t mi = size_t(node.mesh);
            for (size_t pi = 0; pi < model.meshes[mi].primitives.size(); pi++)
                add_primitive(mi, pi, n, world);
        }
        if (node.camera >= 0) add_camera(node.camera, n, world);
        auto ext = node.extensions.find("KHR_lights_punctual");
        if (ext != node.extensions.end() && ext->second.IsObject() && ext->second.Has("light")) {
            const tinygltf::Value &lv = ext->second.Get("light");
            if (!lv.IsNumber())
                throw make_error(WRT_ERR_PARSE, "%s: node %zu: KHR_lights_punctual.light is not a number",
                                 label, n);
            add_light(lv.GetNumberAsInt(), n, world);
        }
        for (int child : node.children) visit(child, world, depth + 1);
    }

    void run() {
        if (model.scenes.empty())
            throw make_error(WRT_ERR_PARSE, "%s: the file has no scene", label);
        size_t si = 0;
        if (model.defaultScene >= 0) {
            if (size_t(model.defaultScene) >= model.scenes.size())
                throw make_error(WRT_ERR_PARSE, "%s: default scene %d does not exist (%zu scenes)", label,
                                 model.defaultScene, model.scenes.size());
            si = size_t(model.defaultScene);
        }
        visited.assign(model.nodes.size(), 0);
        for (int root : model.scenes[si].nodes) visit(root, mat_identity(), 0);
    }
};

void fill(const tinygltf::Model &model, const char *label, wrt_gltf_data *out, reader &rd) {
    /* materials */
    size_t nm = model.materials.size();
    out->materials = static_cast<wrt_gltf_material *>(calloc(nm ? nm : 1, sizeof(wrt_gltf_material)));
    if (!out->materials) throw std::bad_alloc();
    out->nmaterials = nm;
    for (size_t i = 0; i < nm; i++) {
        const tinygltf::Material &m = model.materials[i];
        wrt_gltf_material &o = out->materials[i];
        copy_name(o.name, m.name, "material", i);
        const auto &pbr = m.pbrMetallicRoughness;
        for (int c = 0; c < 4; c++)
            o.base_color[c] = pbr.baseColorFactor.size() == 4 ? pbr.baseColorFactor[size_t(c)] : 1.0;
        o.metallic = pbr.metallicFactor;
        o.roughness = pbr.roughnessFactor;
        for (int c = 0; c < 3; c++)
            o.emissive[c] = m.emissiveFactor.size() == 3 ? m.emissiveFactor[size_t(c)] : 0.0;
        o.double_sided = m.doubleSided ? 1 : 0;
        o.emissive_strength = 1.0; /* KHR_materials_emissive_strength (checked by the strict pass) */
        auto es = m.extensions.find("KHR_materials_emissive_strength");
        if (es != m.extensions.end() && es->second.IsObject() && es->second.Has("emissiveStrength") &&
            es->second.Get("emissiveStrength").IsNumber())
            o.emissive_strength = es->second.Get("emissiveStrength").GetNumberAsDouble();
        /* A texture that is named must be read: never silently the factor alone. */
        auto need = [&](int tex, bool srgb, double mean[4], const char *what) -> int {
            if (tex < 0) return 0;
            if (!texture_mean(model, tex, srgb, mean))
                throw make_error(WRT_ERR_PARSE,
                                 "%s: materials[%zu].%s: texture %d has no decoded image (missing, "
                                 "unknown format or not 8 bits per channel)",
                                 label, i, what, tex);
            return 1;
        };
        o.has_base_tex = need(pbr.baseColorTexture.index, true, o.base_tex_mean,
                              "pbrMetallicRoughness.baseColorTexture");
        if (o.has_base_tex && pbr.baseColorTexture.texCoord == 0) keep_texture(model, pbr.baseColorTexture.index, o);
        double mr[4];
        o.has_mr_tex = need(pbr.metallicRoughnessTexture.index, false, mr,
                            "pbrMetallicRoughness.metallicRoughnessTexture");
        for (int c = 0; c < 3; c++) o.mr_tex_mean[c] = o.has_mr_tex ? mr[c] : 1.0;
        double em[4];
        o.has_emissive_tex = need(m.emissiveTexture.index, true, em, "emissiveTexture");
        for (int c = 0; c < 3; c++) o.emissive_tex_mean[c] = o.has_emissive_tex ? em[c] : 1.0;
    }
    /* mesh names */
    size_t nmesh = model.meshes.size();
    out->mesh_names = static_cast<char(*)[64]>(calloc(nmesh ? nmesh : 1, 64));
    if (!out->mesh_names) throw std::bad_alloc();
    out->nmeshes = nmesh;
    for (size_t i = 0; i < nmesh; i++) copy_name(out->mesh_names[i], model.meshes[i].name, "mesh", i);
    /* primitives: ownership of the arrays moves to out */
    out->prims = static_cast<wrt_gltf_prim *>(calloc(rd.prims.size() + 1, sizeof(wrt_gltf_prim)));
    if (!out->prims) throw std::bad_alloc();
    for (size_t i = 0; i < rd.prims.size(); i++) out->prims[i] = rd.prims[i];
    out->nprims = rd.prims.size();
    rd.prims.clear();
    out->lights = static_cast<wrt_gltf_light *>(calloc(rd.lights.size() + 1, sizeof(wrt_gltf_light)));
    if (!out->lights) throw std::bad_alloc();
    for (size_t i = 0; i < rd.lights.size(); i++) out->lights[i] = rd.lights[i];
    out->nlights = rd.lights.size();
    out->camera = rd.camera;
}

wrt_status read_impl(const void *data, size_t size, const char *base_dir, const char *label,
                     int allow_outside, wrt_gltf_data *out) {
    if (!data || size == 0) throw make_error(WRT_ERR_PARSE, "%s: empty input", label);
    if (size > 0xFFFFFFF0u) throw make_error(WRT_ERR_UNSUPPORTED, "%s: larger than 4 GiB", label);
    const unsigned char *b = static_cast<const unsigned char *>(data);
    bool glb = size >= 4 && memcmp(b, "glTF", 4) == 0;
    const char *text = reinterpret_cast<const char *>(b);
    size_t text_len = size;
    if (glb) {
        check_glb(b, size, label);
        uint32_t len0;
        memcpy(&len0, b + 12, 4);
        text += 20;
        text_len = len0;
    }
    check_json_depth(text, text_len, label);
    std::string strict_warnings, ignored;
    strict_pass(text, text_len, label, allow_outside, &strict_warnings, &ignored);
    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(decode_image, nullptr);
    fs_context fsc;
    fsc.allow_outside = allow_outside != 0;
    std::string dir = base_dir ? base_dir : "";
    if (char *r = realpath(dir.empty() ? "." : dir.c_str(), nullptr)) {
        fsc.base_real = r;
        free(r);
    }
    tinygltf::FsCallbacks fs = {fs_exists, fs_expand, fs_read, fs_write, &fsc};
    loader.SetFsCallbacks(fs);
    tinygltf::Model model;
    std::string err, warn;
    bool ok = glb ? loader.LoadBinaryFromMemory(&model, &err, &warn, b, unsigned(size), dir)
                  : loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char *>(b),
                                               unsigned(size), dir);
    if (!ok) {
        while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
        for (char &c : err)
            if (c == '\n') c = ';';
        if (err.empty()) err = "tinygltf refused the file";
        throw make_error(WRT_ERR_PARSE, "%s: %.600s", label, err.c_str());
    }
    for (const std::string &ext : model.extensionsRequired)
        if (ext != "KHR_lights_punctual" && ext != "KHR_mesh_quantization" &&
            ext != "KHR_texture_transform" && ext != "KHR_materials_emissive_strength")
            throw make_error(WRT_ERR_UNSUPPORTED, "%s: required extension %.80s is not supported", label,
                             ext.c_str());
    reader rd(model, label);
    rd.run();
    fill(model, label, out, rd);
    out->warnings = strdup((strict_warnings + warn).c_str());
    out->ignored = strdup(ignored.c_str());
    if (!out->warnings || !out->ignored) throw std::bad_alloc();
    std::string files;
    for (const std::string &f : fsc.files) files += f + '\n';
    out->files = strdup(files.c_str());
    if (!out->files) throw std::bad_alloc();
    return WRT_OK;
}

} // namespace

extern "C" wrt_status wrt_gltf_read(const void *data, size_t size, const char *base_dir,
                                    const char *label, int allow_outside, wrt_gltf_data *out) {
    if (!out) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gltf_read: out is NULL");
    memset(out, 0, sizeof *out);
    if (!label) label = "<memory>";
    try {
        return read_impl(data, size, base_dir, label, allow_outside, out);
    } catch (const shim_error &e) {
        wrt_gltf_free(out);
        return wrt_fail(e.status, "%s", e.msg.c_str());
    } catch (const std::bad_alloc &) {
        wrt_gltf_free(out);
        return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory while reading glTF", label);
    } catch (const std::exception &e) {
        wrt_gltf_free(out);
        return wrt_fail(WRT_ERR_PARSE, "%s: %s", label, e.what());
    } catch (...) {
        wrt_gltf_free(out);
        return wrt_fail(WRT_ERR_PARSE, "%s: unknown error while reading glTF", label);
    }
}

extern "C" void wrt_gltf_free(wrt_gltf_data *d) {
    if (!d) return;
    for (size_t i = 0; i < d->nprims; i++) {
        free(d->prims[i].pos);
        free(d->prims[i].idx);
        free(d->prims[i].uv);
        free(d->prims[i].nrm);
    }
    free(d->prims);
    for (size_t i = 0; d->materials && i < d->nmaterials; i++) free(d->materials[i].base_tex);
    free(d->materials);
    free(d->lights);
    free(d->mesh_names);
    free(d->warnings);
    free(d->ignored);
    free(d->files);
    memset(d, 0, sizeof *d);
}
