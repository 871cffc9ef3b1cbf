/* gltf_shim.cpp: reads glTF 2.0 (.gltf JSON or .glb) with tinygltf and hands scene.c
 * plain C arrays (see gltf_shim.h). tinygltf parses the JSON and decodes buffers and
 * images; it does not bounds-check accessors, so every accessor is validated here
 * (component type, element type, count x stride inside its bufferView, bufferView
 * inside its buffer, computed without overflow) before a byte is read, and every
 * index is checked against the vertex count. The node hierarchy of the default scene
 * (or scene 0) is flattened with full transforms (matrix, or T*R*S, nested); a node
 * reached twice (a cycle, or a shared child) is refused. GLB framing is checked here
 * before tinygltf sees it. Every exception is caught at the boundary. Depends on
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
extern "C" {
#include "../common/limits.h"
#include "../common/text.h"
}

namespace {

/* Largest decoded texture we accept (texels), and most triangles in one scene. */
const double kMaxTexels = 64.0 * 1024 * 1024;
const size_t kMaxSceneTriangles = 50u * 1000u * 1000u;
const size_t kMaxSceneVertices = 150u * 1000u * 1000u;
/* Deepest JSON nesting (arrays and objects) accepted. A glTF needs about 8 levels; the
 * JSON parsers below recurse per level, so a file nested thousands deep (in `extras`,
 * where anything goes) would overflow the stack: the depth is counted on the raw text
 * before any parser sees it. */
const size_t kMaxJsonDepth = 128;

/* An error with its status; thrown inside the shim, turned into wrt_fail at the boundary. */
struct shim_error {
    wrt_status status;
    std::string msg;
};

__attribute__((format(printf, 2, 3))) shim_error make_error(wrt_status s, const char *fmt, ...) {
    char buf[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return shim_error{s, buf};
}

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

/* GLB framing: header, JSON chunk, optional BIN chunk, all inside `size`. */
void check_glb(const unsigned char *b, size_t size, const char *label) {
    if (size < 20) throw make_error(WRT_ERR_PARSE, "%s: GLB shorter than its 20-byte header", label);
    uint32_t version, length, len0, type0;
    memcpy(&version, b + 4, 4);
    memcpy(&length, b + 8, 4);
    memcpy(&len0, b + 12, 4);
    memcpy(&type0, b + 16, 4);
    if (version != 2)
        throw make_error(WRT_ERR_UNSUPPORTED, "%s: GLB version %u (only 2 is supported)", label, version);
    if (length > size)
        throw make_error(WRT_ERR_PARSE, "%s: GLB header says %u bytes but the file has %zu (truncated)",
                         label, length, size);
    if (type0 != 0x4E4F534Au || len0 == 0 || uint64_t(len0) + 20 > length)
        throw make_error(WRT_ERR_PARSE, "%s: GLB JSON chunk (length %u) is missing or runs past the end",
                         label, len0);
    if (length < size)
        throw make_error(WRT_ERR_PARSE,
                         "%s: %zu bytes after the end of the GLB (its header says %u bytes, the file has "
                         "%zu): trailing data is not allowed",
                         label, size - length, length, size);
    /* After the JSON chunk: at most one BIN chunk, first, then chunks of other types
     * (which readers ignore), each inside the file, ending exactly at `length`. */
    uint64_t at = 20ull + len0;
    int nbin = 0;
    for (int k = 1; at < length; k++) {
        if (at + 8 > length)
            throw make_error(WRT_ERR_PARSE, "%s: GLB chunk %d header truncated at offset %llu", label, k,
                             (unsigned long long)at);
        uint32_t len1, type1;
        memcpy(&len1, b + at, 4);
        memcpy(&type1, b + at + 4, 4);
        if (at + 8 + len1 > length)
            throw make_error(WRT_ERR_PARSE,
                             "%s: GLB %s %d (length %u at offset %llu) runs past the end (%u bytes)",
                             label, k == 1 ? "BIN chunk, chunk" : "chunk", k, len1, (unsigned long long)at,
                             length);
        if (type1 == 0x004E4942u) {
            if (k != 1 || ++nbin > 1)
                throw make_error(WRT_ERR_PARSE,
                                 "%s: GLB chunk %d at offset %llu is a second BIN chunk or not the "
                                 "second chunk (the specification allows one BIN chunk, right after JSON)",
                                 label, k, (unsigned long long)at);
        } else if (type1 == 0x4E4F534Au) {
            throw make_error(WRT_ERR_PARSE, "%s: GLB chunk %d at offset %llu is a second JSON chunk", label, k,
                             (unsigned long long)at);
        } else if (k == 1) {
            throw make_error(WRT_ERR_PARSE,
                             "%s: GLB BIN chunk (length %u at offset %llu) is not BIN (type 0x%08x)", label,
                             len1, (unsigned long long)at, type1);
        }
        at += 8ull + len1;
    }
}

/* The nesting depth of JSON text, counted before any parser sees it (strings skipped,
 * escapes included). Throws when it passes kMaxJsonDepth. */
void check_json_depth(const char *t, size_t n, const char *label) {
    size_t depth = 0;
    bool in_str = false;
    for (size_t i = 0; i < n; i++) {
        char c = t[i];
        if (in_str) {
            if (c == '\\') i++;
            else if (c == '"') in_str = false;
            continue;
        }
        if (c == '"') {
            in_str = true;
        } else if (c == '[' || c == '{') {
            if (++depth > kMaxJsonDepth)
                throw make_error(WRT_ERR_PARSE,
                                 "%s: JSON nested deeper than %zu levels (at byte %zu of the JSON text); "
                                 "refused before parsing",
                                 label, kMaxJsonDepth, i);
        } else if ((c == ']' || c == '}') && depth > 0) {
            depth--;
        }
    }
}

/* References tinygltf checks with terse messages ("primitive indices accessor out of
 * bounds") are checked here first on the raw JSON, so the error says which mesh,
 * primitive or accessor. Malformed JSON is left to tinygltf's parser error. */
void check_references(const nlohmann::json &j, const char *label) {
    if (!j.is_object()) return;
    auto count = [&](const char *k) -> size_t {
        auto it = j.find(k);
        return it != j.end() && it->is_array() ? it->size() : 0;
    };
    size_t nacc = count("accessors"), nbv = count("bufferViews"), nbuf = count("buffers"),
           nmat = count("materials");
    auto bad = [](const nlohmann::json &v, size_t n) {
        if (!v.is_number()) return false; /* wrong types are tinygltf's to report */
        double d = v.get<double>();
        return !(d >= 0 && d < double(n));
    };
    auto num = [](const nlohmann::json &v) { return v.get<double>(); };
    auto meshes = j.find("meshes");
    if (meshes != j.end() && meshes->is_array())
        for (size_t mi = 0; mi < meshes->size(); mi++) {
            const nlohmann::json &m = (*meshes)[mi];
            if (!m.is_object()) continue;
            auto prims = m.find("primitives");
            if (prims == m.end() || !prims->is_array()) continue;
            for (size_t pi = 0; pi < prims->size(); pi++) {
                const nlohmann::json &p = (*prims)[pi];
                if (!p.is_object()) continue;
                auto ind = p.find("indices");
                if (ind != p.end() && bad(*ind, nacc))
                    throw make_error(WRT_ERR_PARSE,
                                     "%s: mesh %zu primitive %zu: indices accessor %.0f does not exist "
                                     "(the file has %zu accessors)",
                                     label, mi, pi, num(*ind), nacc);
                auto mat = p.find("material");
                if (mat != p.end() && bad(*mat, nmat))
                    throw make_error(WRT_ERR_PARSE,
                                     "%s: mesh %zu primitive %zu: material %.0f does not exist (%zu "
                                     "materials)",
                                     label, mi, pi, num(*mat), nmat);
                auto attrs = p.find("attributes");
                if (attrs == p.end() || !attrs->is_object()) continue;
                for (auto it = attrs->begin(); it != attrs->end(); ++it)
                    if (bad(it.value(), nacc))
                        throw make_error(WRT_ERR_PARSE,
                                         "%s: mesh %zu primitive %zu: %.40s accessor %.0f does not exist "
                                         "(the file has %zu accessors)",
                                         label, mi, pi, it.key().c_str(), num(it.value()), nacc);
            }
        }
    auto accs = j.find("accessors");
    if (accs != j.end() && accs->is_array())
        for (size_t ai = 0; ai < accs->size(); ai++) {
            const nlohmann::json &a = (*accs)[ai];
            if (!a.is_object()) continue;
            auto bv = a.find("bufferView");
            if (bv != a.end() && bad(*bv, nbv))
                throw make_error(WRT_ERR_PARSE,
                                 "%s: accessor %zu: bufferView %.0f does not exist (%zu bufferViews)",
                                 label, ai, num(*bv), nbv);
        }
    auto bvs = j.find("bufferViews");
    if (bvs != j.end() && bvs->is_array())
        for (size_t vi = 0; vi < bvs->size(); vi++) {
            const nlohmann::json &v = (*bvs)[vi];
            if (!v.is_object()) continue;
            auto b = v.find("buffer");
            if (b != v.end() && bad(*b, nbuf))
                throw make_error(WRT_ERR_PARSE, "%s: bufferView %zu: buffer %.0f does not exist (%zu buffers)",
                                 label, vi, num(*b), nbuf);
        }
}

/* ---- the strict pass: every field the reader uses, checked on the raw JSON ----
 * tinygltf reads a field of the wrong type or length as absent (its default), so the
 * fields the project uses are checked here first against the glTF 2.0 schema and the
 * KHR_lights_punctual specification: types, array lengths, ranges, finite after
 * conversion to float, references that exist. An invalid field is refused with its JSON
 * path; a valid but unusual one is warned about; a field the bake does not use is listed
 * (by path pattern, with a count) so that --scan can show it as ignored. */
typedef nlohmann::json json;

struct strict_check {
    const json &root;
    const char *label;
    bool allow_outside = false;
    std::string warnings;
    std::vector<std::pair<std::string, size_t>> ignored; /* path pattern, how many */

    strict_check(const json &r, const char *l) : root(r), label(l) {}

    [[noreturn]] __attribute__((format(printf, 3, 4))) void fail(const std::string &path, const char *fmt, ...) {
        char buf[512];
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(buf, sizeof buf, fmt, ap);
        va_end(ap);
        throw make_error(WRT_ERR_PARSE, "%s: %.200s: %s", label, path.c_str(), buf);
    }
    __attribute__((format(printf, 3, 4))) void warn(const std::string &path, const char *fmt, ...) {
        char buf[512];
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(buf, sizeof buf, fmt, ap);
        va_end(ap);
        warnings += path + ": " + buf + "\n";
    }
    void ignore(const std::string &pattern) {
        for (auto &p : ignored)
            if (p.first == pattern) { p.second++; return; }
        ignored.push_back({pattern, 1});
    }
    /* Members other than `used` (and name/extras, which carry no light) are ignored. */
    void ignore_others(const json &o, const std::string &pattern, std::initializer_list<const char *> used) {
        for (auto it = o.begin(); it != o.end(); ++it) {
            const std::string &k = it.key();
            if (k == "name" || k == "extras") continue;
            bool u = false;
            for (const char *x : used) u = u || k == x;
            if (!u) ignore(pattern + "." + k);
        }
    }
    static std::string at(const std::string &p, const char *k) { return p + "." + k; }
    static std::string at(const std::string &p, size_t i) { return p + "[" + std::to_string(i) + "]"; }

    const json *member(const json &o, const char *k) {
        auto it = o.find(k);
        return it == o.end() ? nullptr : &*it;
    }
    const json &object(const json &v, const std::string &path) {
        if (!v.is_object()) fail(path, "must be an object");
        return v;
    }
    const json *array_member(const json &o, const char *k, const std::string &path) {
        const json *v = member(o, k);
        if (v && !v->is_array()) fail(at(path, k), "must be an array");
        return v;
    }
    size_t count(const char *k) {
        const json *v = member(root, k);
        return v && v->is_array() ? v->size() : 0;
    }
    /* A number (not a string, not a boolean) in [lo, hi] (bounds exclusive where asked),
     * finite also as a float when `as_float`. */
    double number(const json &v, const std::string &path, double lo, double hi, bool lo_excl = false,
                  bool hi_excl = false, bool as_float = true) {
        if (!v.is_number()) fail(path, "must be a number, not %s", v.type_name());
        double d = v.get<double>();
        if (!std::isfinite(d)) fail(path, "is not finite");
        if (as_float && std::fabs(d) > double(FLT_MAX))
            fail(path, "%g is not finite as a 32-bit float (largest %g)", d, double(FLT_MAX));
        if (d < lo || (lo_excl && d == lo) || d > hi || (hi_excl && d == hi))
            fail(path, "%g is outside %s%g, %g%s", d, lo_excl ? "(" : "[", lo, hi, hi_excl ? ")" : "]");
        return d;
    }
    long long integer(const json &v, const std::string &path, long long lo, long long hi) {
        if (!v.is_number()) fail(path, "must be an integer, not %s", v.type_name());
        double d = v.get<double>();
        if (!(d == std::floor(d)) || !std::isfinite(d)) fail(path, "%g is not an integer", d);
        if (d < double(lo) || d > double(hi)) fail(path, "%.0f is outside [%lld, %lld]", d, lo, hi);
        return (long long)d;
    }
    /* An index into the top-level array `what`. */
    long long ref(const json &v, const std::string &path, const char *what) {
        size_t n = count(what);
        if (!v.is_number()) fail(path, "must be an index into %s, not %s", what, v.type_name());
        double d = v.get<double>();
        if (!(d == std::floor(d)) || d < 0 || d >= double(n))
            fail(path, "refers to %s %g, which does not exist (the file has %zu)", what, d, n);
        return (long long)d;
    }
    void numbers(const json &v, const std::string &path, size_t len, double lo, double hi) {
        if (!v.is_array()) fail(path, "must be an array of %zu numbers, not %s", len, v.type_name());
        if (v.size() != len) fail(path, "has %zu elements, expected %zu", v.size(), len);
        for (size_t i = 0; i < len; i++) number(v[i], at(path, i), lo, hi);
    }
    void boolean(const json &v, const std::string &path) {
        if (!v.is_boolean()) fail(path, "must be true or false, not %s", v.type_name());
    }
    const std::string &string(const json &v, const std::string &path) {
        if (!v.is_string()) fail(path, "must be a string, not %s", v.type_name());
        return v.get_ref<const std::string &>();
    }

    void asset() {
        const json *a = member(root, "asset");
        if (!a) fail("asset", "is missing (required)");
        object(*a, "asset");
        const json *v = member(*a, "version");
        if (!v) fail("asset.version", "is missing (required)");
        const std::string &s = string(*v, "asset.version");
        int major = -1, minor = -1, used = 0;
        if (sscanf(s.c_str(), "%d.%d%n", &major, &minor, &used) != 2 || size_t(used) != s.size())
            fail("asset.version", "'%.40s' is not MAJOR.MINOR", s.c_str());
        if (major != 2)
            throw make_error(WRT_ERR_UNSUPPORTED, "%s: asset.version: '%.40s': only glTF 2.x is supported",
                             label, s.c_str());
        if (const json *mv = member(*a, "minVersion")) {
            const std::string &m = string(*mv, "asset.minVersion");
            int mj = -1, mn = -1;
            if (sscanf(m.c_str(), "%d.%d", &mj, &mn) != 2 || mj != 2 || mn > 0)
                throw make_error(WRT_ERR_UNSUPPORTED,
                                 "%s: asset.minVersion: '%.40s': this reader implements glTF 2.0", label,
                                 m.c_str());
        }
        if (minor > 0) warn("asset.version", "'%s': newer than 2.0; read as 2.0", s.c_str());
    }

    void texture_info(const json &t, const std::string &path, const std::string &pattern, bool used) {
        object(t, path);
        const json *i = member(t, "index");
        if (!i) fail(at(path, "index"), "is missing (required)");
        long long ti = ref(*i, at(path, "index"), "textures");
        if (const json *tc = member(t, "texCoord")) integer(*tc, at(path, "texCoord"), 0, INT32_MAX);
        const json &tex = root["textures"][size_t(ti)];
        if (used && !member(tex, "source"))
            fail(path, "texture %lld has no source image (an extension's image is not supported)", ti);
        if (used) ignore_others(t, pattern, {"index", "texCoord"});
    }

    void materials() {
        const json *ms = array_member(root, "materials", "");
        if (!ms) return;
        for (size_t i = 0; i < ms->size(); i++) {
            std::string p = at("materials", i);
            const json &m = object((*ms)[i], p);
            if (const json *pbr = member(m, "pbrMetallicRoughness")) {
                std::string pp = at(p, "pbrMetallicRoughness");
                object(*pbr, pp);
                if (const json *v = member(*pbr, "baseColorFactor")) numbers(*v, at(pp, "baseColorFactor"), 4, 0, 1);
                if (const json *v = member(*pbr, "metallicFactor")) number(*v, at(pp, "metallicFactor"), 0, 1);
                if (const json *v = member(*pbr, "roughnessFactor")) number(*v, at(pp, "roughnessFactor"), 0, 1);
                if (const json *v = member(*pbr, "baseColorTexture"))
                    texture_info(*v, at(pp, "baseColorTexture"), "materials[*].pbrMetallicRoughness.baseColorTexture", true);
                if (const json *v = member(*pbr, "metallicRoughnessTexture"))
                    texture_info(*v, at(pp, "metallicRoughnessTexture"),
                                 "materials[*].pbrMetallicRoughness.metallicRoughnessTexture", true);
                ignore_others(*pbr, "materials[*].pbrMetallicRoughness",
                              {"baseColorFactor", "metallicFactor", "roughnessFactor", "baseColorTexture",
                               "metallicRoughnessTexture"});
            }
            if (const json *v = member(m, "emissiveFactor")) numbers(*v, at(p, "emissiveFactor"), 3, 0, 1);
            if (const json *v = member(m, "emissiveTexture"))
                texture_info(*v, at(p, "emissiveTexture"), "materials[*].emissiveTexture", true);
            if (const json *v = member(m, "normalTexture")) texture_info(*v, at(p, "normalTexture"), "", false);
            if (const json *v = member(m, "occlusionTexture")) texture_info(*v, at(p, "occlusionTexture"), "", false);
            if (const json *v = member(m, "doubleSided")) boolean(*v, at(p, "doubleSided"));
            if (const json *v = member(m, "alphaMode")) {
                const std::string &s = string(*v, at(p, "alphaMode"));
                if (s != "OPAQUE" && s != "MASK" && s != "BLEND")
                    fail(at(p, "alphaMode"), "'%.40s' is not OPAQUE, MASK or BLEND", s.c_str());
                if (s != "OPAQUE") warn(at(p, "alphaMode"), "%s: transparency is not modelled, the surface is opaque", s.c_str());
            }
            if (const json *v = member(m, "alphaCutoff")) number(*v, at(p, "alphaCutoff"), 0, FLT_MAX);
            ignore_others(m, "materials[*]", {"pbrMetallicRoughness", "emissiveFactor", "emissiveTexture", "doubleSided"});
        }
    }

    void images() {
        const json *is = array_member(root, "images", "");
        if (!is) return;
        for (size_t i = 0; i < is->size(); i++) {
            std::string p = at("images", i);
            local_uri(object((*is)[i], p), p);
        }
    }

    void textures() {
        const json *ts = array_member(root, "textures", "");
        if (!ts) return;
        for (size_t i = 0; i < ts->size(); i++) {
            std::string p = at("textures", i);
            const json &t = object((*ts)[i], p);
            if (const json *s = member(t, "source")) ref(*s, at(p, "source"), "images");
            if (const json *s = member(t, "sampler")) ref(*s, at(p, "sampler"), "samplers");
        }
    }

    void lights() {
        const json *ex = member(root, "extensions");
        if (!ex) return;
        object(*ex, "extensions");
        for (auto it = ex->begin(); it != ex->end(); ++it)
            if (it.key() != "KHR_lights_punctual") ignore("extensions." + it.key());
        const json *kl = member(*ex, "KHR_lights_punctual");
        if (!kl) return;
        std::string kp = "extensions.KHR_lights_punctual";
        object(*kl, kp);
        const json *ls = array_member(*kl, "lights", kp);
        if (!ls) return;
        for (size_t i = 0; i < ls->size(); i++) {
            std::string p = at(at(kp, "lights"), i);
            const json &l = object((*ls)[i], p);
            const json *t = member(l, "type");
            if (!t) fail(at(p, "type"), "is missing (required)");
            const std::string &type = string(*t, at(p, "type"));
            if (type != "point" && type != "spot" && type != "directional")
                fail(at(p, "type"), "'%.40s' is not point, spot or directional", type.c_str());
            if (const json *v = member(l, "color")) numbers(*v, at(p, "color"), 3, 0, 1);
            if (const json *v = member(l, "intensity")) number(*v, at(p, "intensity"), 0, WRT_MAX_LIGHT_INTENSITY);
            if (const json *v = member(l, "range")) number(*v, at(p, "range"), 0, FLT_MAX, true);
            const json *sp = member(l, "spot");
            if (type == "spot") {
                if (!sp) fail(at(p, "spot"), "is missing (required for a spot light)");
                std::string spp = at(p, "spot");
                object(*sp, spp);
                double inner = 0, outer = M_PI / 4;
                if (const json *v = member(*sp, "innerConeAngle"))
                    inner = number(*v, at(spp, "innerConeAngle"), 0, M_PI / 2, false, true);
                if (const json *v = member(*sp, "outerConeAngle"))
                    outer = number(*v, at(spp, "outerConeAngle"), 0, M_PI / 2, true, false);
                if (!(inner < outer))
                    fail(spp, "innerConeAngle %g must be less than outerConeAngle %g", inner, outer);
            } else if (sp) {
                ignore("extensions.KHR_lights_punctual.lights[*].spot (on a " + type + " light)");
            }
        }
    }

    void cameras() {
        const json *cs = array_member(root, "cameras", "");
        if (!cs) return;
        for (size_t i = 0; i < cs->size(); i++) {
            std::string p = at("cameras", i);
            const json &c = object((*cs)[i], p);
            const json *t = member(c, "type");
            if (!t) fail(at(p, "type"), "is missing (required)");
            const std::string &type = string(*t, at(p, "type"));
            if (type != "perspective" && type != "orthographic")
                fail(at(p, "type"), "'%.40s' is not perspective or orthographic", type.c_str());
            if (type == "orthographic") {
                ignore("cameras[*] (orthographic)");
                continue;
            }
            const json *pe = member(c, "perspective");
            std::string pp = at(p, "perspective");
            if (!pe) fail(pp, "is missing (required for a perspective camera)");
            object(*pe, pp);
            const json *y = member(*pe, "yfov");
            if (!y) fail(at(pp, "yfov"), "is missing (required)");
            number(*y, at(pp, "yfov"), 0, M_PI, true, true);
            const json *zn = member(*pe, "znear");
            if (!zn) fail(at(pp, "znear"), "is missing (required)");
            double znear = number(*zn, at(pp, "znear"), 0, FLT_MAX, true);
            if (const json *zf = member(*pe, "zfar")) {
                double zfar = number(*zf, at(pp, "zfar"), 0, FLT_MAX, true);
                if (!(zfar > znear)) fail(at(pp, "zfar"), "%g must be greater than znear %g", zfar, znear);
            }
            if (const json *a = member(*pe, "aspectRatio")) number(*a, at(pp, "aspectRatio"), 0, FLT_MAX, true);
        }
    }

    void nodes() {
        const json *ns = array_member(root, "nodes", "");
        if (!ns) return;
        for (size_t i = 0; i < ns->size(); i++) {
            std::string p = at("nodes", i);
            const json &n = object((*ns)[i], p);
            const json *mat = member(n, "matrix");
            if (mat) numbers(*mat, at(p, "matrix"), 16, -DBL_MAX, DBL_MAX);
            const char *trs[3] = {"translation", "rotation", "scale"};
            const size_t len[3] = {3, 4, 3};
            for (int k = 0; k < 3; k++) {
                const json *v = member(n, trs[k]);
                if (!v) continue;
                if (mat) fail(p, "has both matrix and %s (the specification allows one or the other)", trs[k]);
                numbers(*v, at(p, trs[k]), len[k], k == 1 ? -1 : -DBL_MAX, k == 1 ? 1 : DBL_MAX);
                if (k == 1) {
                    double q2 = 0;
                    for (size_t c = 0; c < 4; c++) q2 += (*v)[c].get<double>() * (*v)[c].get<double>();
                    if (!(std::fabs(std::sqrt(q2) - 1) <= 1e-3))
                        warn(at(p, "rotation"), "quaternion of length %g, not unit; normalized", std::sqrt(q2));
                }
            }
            if (const json *v = member(n, "mesh")) ref(*v, at(p, "mesh"), "meshes");
            if (const json *v = member(n, "camera")) ref(*v, at(p, "camera"), "cameras");
            if (const json *ch = array_member(n, "children", p))
                for (size_t c = 0; c < ch->size(); c++) ref((*ch)[c], at(at(p, "children"), c), "nodes");
            if (const json *ex = member(n, "extensions")) {
                object(*ex, at(p, "extensions"));
                for (auto it = ex->begin(); it != ex->end(); ++it)
                    if (it.key() != "KHR_lights_punctual") ignore("nodes[*].extensions." + it.key());
                if (const json *kl = member(*ex, "KHR_lights_punctual")) {
                    std::string kp = at(at(p, "extensions"), "KHR_lights_punctual");
                    object(*kl, kp);
                    const json *l = member(*kl, "light");
                    if (!l) fail(at(kp, "light"), "is missing (required)");
                    const json *root_ext = member(root, "extensions");
                    size_t nl = 0;
                    if (root_ext && root_ext->is_object()) {
                        const json *rk = member(*root_ext, "KHR_lights_punctual");
                        if (rk && rk->is_object()) {
                            const json *ls = member(*rk, "lights");
                            if (ls && ls->is_array()) nl = ls->size();
                        }
                    }
                    if (!l->is_number() || l->get<double>() != std::floor(l->get<double>()) ||
                        l->get<double>() < 0 || l->get<double>() >= double(nl))
                        fail(at(kp, "light"), "refers to light %s, which does not exist (the file has %zu)",
                             l->dump().substr(0, 40).c_str(), nl);
                }
            }
            ignore_others(n, "nodes[*]", {"matrix", "translation", "rotation", "scale", "mesh", "camera",
                                          "children", "extensions"});
        }
    }

    /* POSITION is FLOAT unless the file declares KHR_mesh_quantization (which allows
     * BYTE, UNSIGNED_BYTE, SHORT and UNSIGNED_SHORT, normalized or not). */
    void position_type(long long ai, const std::string &path) {
        const json &a = root["accessors"][size_t(ai)];
        const json *ct = a.is_object() ? member(a, "componentType") : nullptr;
        if (!ct || !ct->is_number() || ct->get<double>() == 5126) return; /* accessors() reports the rest */
        bool quantized = false;
        if (const json *eu = member(root, "extensionsUsed"))
            if (eu->is_array())
                for (const json &e : *eu) quantized = quantized || (e.is_string() && e.get<std::string>() == "KHR_mesh_quantization");
        if (!quantized)
            fail(path, "accessor %lld has componentType %.0f, not FLOAT (5126): integer positions need the "
                 "KHR_mesh_quantization extension in extensionsUsed", ai, ct->get<double>());
    }

    /* A buffer's or image's uri must stay inside the scene's folder: no absolute path,
     * no ".." segment (also percent-encoded), no scheme other than data:, unless the
     * caller allows it. */
    void local_uri(const json &o, const std::string &path) {
        const json *u = member(o, "uri");
        if (!u) return;
        const std::string &uri = string(*u, at(path, "uri"));
        if (uri.compare(0, 5, "data:") == 0 || allow_outside) return;
        std::string d; /* percent-decoded */
        for (size_t i = 0; i < uri.size(); i++) {
            if (uri[i] == '%' && i + 2 < uri.size() && isxdigit((unsigned char)uri[i + 1]) &&
                isxdigit((unsigned char)uri[i + 2])) {
                d += char(strtol(uri.substr(i + 1, 2).c_str(), nullptr, 16));
                i += 2;
            } else {
                d += uri[i];
            }
        }
        bool bad = d.empty() || d[0] == '/' || d[0] == '\\' || d.find(':') != std::string::npos ||
                   d.find('\\') != std::string::npos || d.find('\0') != std::string::npos;
        for (size_t i = 0; !bad && i < d.size();) {
            size_t j = d.find('/', i);
            if (j == std::string::npos) j = d.size();
            if (d.compare(i, j - i, "..") == 0) bad = true;
            i = j + 1;
        }
        if (bad)
            fail(at(path, "uri"), "'%.80s' leaves the scene's folder (an absolute path, a scheme or a '..'); "
                 "refused unless --allow-outside-files", uri.c_str());
    }

    void meshes() {
        const json *ms = array_member(root, "meshes", "");
        if (!ms) return;
        for (size_t i = 0; i < ms->size(); i++) {
            std::string p = at("meshes", i);
            const json &m = object((*ms)[i], p);
            const json *ps = array_member(m, "primitives", p);
            if (!ps) fail(at(p, "primitives"), "is missing (required)");
            for (size_t k = 0; k < ps->size(); k++) {
                std::string pp = at(at(p, "primitives"), k);
                const json &pr = object((*ps)[k], pp);
                if (const json *v = member(pr, "mode")) integer(*v, at(pp, "mode"), 0, 6);
                if (const json *v = member(pr, "material")) ref(*v, at(pp, "material"), "materials");
                if (const json *v = member(pr, "indices")) ref(*v, at(pp, "indices"), "accessors");
                const json *at_ = member(pr, "attributes");
                if (!at_) fail(at(pp, "attributes"), "is missing (required)");
                object(*at_, at(pp, "attributes"));
                for (auto it = at_->begin(); it != at_->end(); ++it) {
                    long long ai = ref(it.value(), at(at(pp, "attributes"), it.key().c_str()), "accessors");
                    if (it.key() == "POSITION") position_type(ai, at(at(pp, "attributes"), "POSITION"));
                    if (it.key() != "POSITION" && it.key() != "TEXCOORD_0") ignore("meshes[*].primitives[*].attributes." + it.key());
                }
                ignore_others(pr, "meshes[*].primitives[*]", {"mode", "material", "indices", "attributes"});
            }
            ignore_others(m, "meshes[*]", {"primitives"});
        }
    }

    void accessors() {
        const json *as = array_member(root, "accessors", "");
        if (!as) return;
        for (size_t i = 0; i < as->size(); i++) {
            std::string p = at("accessors", i);
            const json &a = object((*as)[i], p);
            if (const json *v = member(a, "bufferView")) ref(*v, at(p, "bufferView"), "bufferViews");
            if (const json *v = member(a, "byteOffset")) integer(*v, at(p, "byteOffset"), 0, INT64_MAX / 2);
            const json *ct = member(a, "componentType");
            if (!ct) fail(at(p, "componentType"), "is missing (required)");
            long long c = integer(*ct, at(p, "componentType"), 5120, 5126);
            if (c == 5124) fail(at(p, "componentType"), "5124 (signed int) is not a glTF component type");
            const json *cnt = member(a, "count");
            if (!cnt) fail(at(p, "count"), "is missing (required)");
            integer(*cnt, at(p, "count"), 1, INT64_MAX / 2);
            const json *t = member(a, "type");
            if (!t) fail(at(p, "type"), "is missing (required)");
            string(*t, at(p, "type"));
            if (const json *v = member(a, "normalized")) {
                boolean(*v, at(p, "normalized"));
                if (v->get<bool>() && (c == 5126 || c == 5125))
                    fail(at(p, "normalized"), "is true on a %s accessor (the specification allows it only "
                         "on 8- and 16-bit integer components)", c == 5126 ? "FLOAT" : "UNSIGNED_INT");
            }
        }
    }

    void buffer_views() {
        const json *bs = array_member(root, "bufferViews", "");
        if (bs)
            for (size_t i = 0; i < bs->size(); i++) {
                std::string p = at("bufferViews", i);
                const json &b = object((*bs)[i], p);
                const json *buf = member(b, "buffer");
                if (!buf) fail(at(p, "buffer"), "is missing (required)");
                ref(*buf, at(p, "buffer"), "buffers");
                if (const json *v = member(b, "byteOffset")) integer(*v, at(p, "byteOffset"), 0, INT64_MAX / 2);
                const json *bl = member(b, "byteLength");
                if (!bl) fail(at(p, "byteLength"), "is missing (required)");
                integer(*bl, at(p, "byteLength"), 1, INT64_MAX / 2);
                if (const json *v = member(b, "byteStride")) {
                    long long s = integer(*v, at(p, "byteStride"), 4, 252);
                    if (s % 4) fail(at(p, "byteStride"), "%lld is not a multiple of 4", s);
                }
            }
        const json *bufs = array_member(root, "buffers", "");
        if (bufs)
            for (size_t i = 0; i < bufs->size(); i++) {
                std::string p = at("buffers", i);
                const json &b = object((*bufs)[i], p);
                local_uri(b, p);
                const json *bl = member(b, "byteLength");
                if (!bl) fail(at(p, "byteLength"), "is missing (required)");
                integer(*bl, at(p, "byteLength"), 1, INT64_MAX / 2);
            }
    }

    void scenes() {
        const json *ss = array_member(root, "scenes", "");
        if (const json *s = member(root, "scene")) ref(*s, "scene", "scenes");
        if (!ss) return;
        for (size_t i = 0; i < ss->size(); i++) {
            std::string p = at("scenes", i);
            const json &s = object((*ss)[i], p);
            if (const json *ns = array_member(s, "nodes", p))
                for (size_t k = 0; k < ns->size(); k++) ref((*ns)[k], at(at(p, "nodes"), k), "nodes");
        }
    }

    void run() {
        if (!root.is_object()) fail("(top level)", "must be a JSON object");
        asset();
        scenes();
        nodes();
        meshes();
        accessors();
        buffer_views();
        materials();
        textures();
        images();
        cameras();
        lights();
        for (auto it = root.begin(); it != root.end(); ++it) {
            static const char *used[] = {"asset", "scene", "scenes", "nodes", "meshes", "accessors",
                                         "bufferViews", "buffers", "materials", "textures", "images",
                                         "cameras", "extensions", "extensionsUsed", "extensionsRequired",
                                         "extras"};
            bool u = false;
            for (const char *k : used) u = u || it.key() == k;
            if (!u) ignore(it.key());
        }
    }

    std::string ignored_text() const {
        std::string s;
        for (const auto &p : ignored) {
            if (!s.empty()) s += "; ";
            s += p.first;
            if (p.second > 1) s += " (" + std::to_string(p.second) + ")";
        }
        return s;
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
    {
        nlohmann::json j = nlohmann::json::parse(text, text + text_len, nullptr, false);
        if (!j.is_discarded()) { /* malformed JSON is left to tinygltf's parser error */
            check_references(j, label);
            strict_check sc(j, label);
            sc.allow_outside = allow_outside != 0;
            sc.run();
            strict_warnings = sc.warnings;
            ignored = sc.ignored_text();
        }
    }
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
    }
    free(d->prims);
    free(d->materials);
    free(d->lights);
    free(d->mesh_names);
    free(d->warnings);
    free(d->ignored);
    free(d->files);
    memset(d, 0, sizeof *d);
}
