/* gltf_strict.cpp: the glTF reader's checks on the raw file, before tinygltf sees it:
 * the GLB framing (header, chunks, lengths), the JSON nesting depth (counted on the text,
 * so no recursive parser can overflow the stack), the references tinygltf reports
 * tersely (which mesh, primitive or accessor), and the strict pass: every field the
 * reader uses checked against the glTF 2.0 schema and KHR_lights_punctual (types,
 * lengths, ranges, finite as float, uris), unusual values warned about, unused fields
 * listed as ignored. Called by gltf_shim.cpp (gltf_internal.h). Depends on nlohmann
 * json (the parser tinygltf uses) and common/limits.h. */
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include <sys/stat.h>

#include <nlohmann/json.hpp>

#include "gltf_internal.h"
extern "C" {
#include "../common/limits.h"
#include "../common/text.h"
}

namespace {
/* Deepest JSON nesting (arrays and objects) accepted. A glTF needs about 8 levels; the
 * JSON parsers below recurse per level, so a file nested thousands deep (in `extras`,
 * where anything goes) would overflow the stack: the depth is counted on the raw text
 * before any parser sees it. */
const size_t kMaxJsonDepth = 128;
} // namespace

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

namespace {

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
            bool has_ext = false;
            if (const json *ex = member(m, "extensions")) {
                has_ext = true;
                std::string pe = at(p, "extensions");
                object(*ex, pe);
                if (const json *es = member(*ex, "KHR_materials_emissive_strength")) {
                    std::string ps = at(pe, "KHR_materials_emissive_strength");
                    object(*es, ps);
                    /* emitted radiance = emissiveFactor x emissiveStrength (docs/emitters.md) */
                    if (const json *v = member(*es, "emissiveStrength"))
                        number(*v, at(ps, "emissiveStrength"), 0, WRT_MAX_EMISSIVE);
                    ignore_others(*es, "materials[*].extensions.KHR_materials_emissive_strength", {"emissiveStrength"});
                }
                for (auto it = ex->begin(); it != ex->end(); ++it)
                    if (it.key() != "KHR_materials_emissive_strength") ignore("materials[*].extensions." + it.key());
            }
            if (has_ext)
                ignore_others(m, "materials[*]", {"pbrMetallicRoughness", "emissiveFactor", "emissiveTexture", "doubleSided", "extensions"});
            else
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
            if (mat) {
                numbers(*mat, at(p, "matrix"), 16, -DBL_MAX, DBL_MAX);
                /* Column-major: elements 3, 7, 11, 15 are the last row. glTF node matrices
                 * are decomposable to translation, rotation and scale, so the row is
                 * (0, 0, 0, 1); a projective row was ignored by the transforms. */
                double row[4] = {(*mat)[3].get<double>(), (*mat)[7].get<double>(), (*mat)[11].get<double>(),
                                 (*mat)[15].get<double>()};
                if (std::fabs(row[0]) > 1e-6 || std::fabs(row[1]) > 1e-6 || std::fabs(row[2]) > 1e-6 ||
                    std::fabs(row[3] - 1) > 1e-6)
                    fail(at(p, "matrix"), "last row (%g, %g, %g, %g) is not (0, 0, 0, 1): not an affine transform "
                         "(glTF node matrices are translation x rotation x scale)", row[0], row[1], row[2], row[3]);
            }
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
                    if (it.key() != "POSITION" && it.key() != "TEXCOORD_0" && it.key() != "NORMAL") ignore("meshes[*].primitives[*].attributes." + it.key());
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
                data_uri(b, p, bl->get<double>());
            }
    }

    /* A buffer's data: uri, checked before tinygltf decodes it: its media type, its base64
     * text and its decoded length against byteLength. tinygltf's own messages were "File
     * not found" for a media type it does not take and "Failed to decode 'uri'" for a
     * length that differs, each followed by 600 bytes of base64. */
    void data_uri(const json &b, const std::string &p, double byte_length) {
        const json *u = member(b, "uri");
        if (!u || !u->is_string()) return;
        const std::string &uri = u->get_ref<const std::string &>();
        if (uri.compare(0, 5, "data:") != 0) return;
        size_t comma = uri.find(',');
        std::string head = uri.substr(0, comma == std::string::npos ? 0 : comma);
        if (head != "data:application/octet-stream;base64" && head != "data:application/gltf-buffer;base64")
            fail(at(p, "uri"), "a data uri of type '%.60s': a buffer's is application/octet-stream or "
                 "application/gltf-buffer, in base64", comma == std::string::npos ? "(no comma)" : head.c_str() + 5);
        size_t n = uri.size() - comma - 1, pad = 0;
        for (size_t i = comma + 1; i < uri.size(); i++) {
            unsigned char c = (unsigned char)uri[i];
            if (c == '=' && i + 2 >= uri.size() && (n % 4 == 0)) { pad++; continue; }
            if (!std::isalnum(c) && c != '+' && c != '/')
                fail(at(p, "uri"), "byte %zu of the data uri (0x%02x) is not base64", i, c);
            if (pad) fail(at(p, "uri"), "'=' inside the base64 text (byte %zu)", i - 1);
        }
        double decoded = (double)(n / 4 * 3) + (n % 4 ? (double)(n % 4) - 1 : 0) - (double)pad;
        if (decoded != byte_length)
            fail(at(p, "byteLength"), "%.17g, but its data uri holds %.17g bytes", byte_length, decoded);
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
                                         "samplers", /* wrap modes of base-colour textures */
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

} // namespace

void strict_pass(const char *text, size_t text_len, const char *label, int allow_outside,
                 std::string *strict_warnings, std::string *ignored) {
    nlohmann::json j = nlohmann::json::parse(text, text + text_len, nullptr, false);
    if (!j.is_discarded()) { /* malformed JSON is left to tinygltf's parser error */
        check_references(j, label);
        strict_check sc(j, label);
        sc.allow_outside = allow_outside != 0;
        sc.run();
        *strict_warnings = sc.warnings;
        *ignored = sc.ignored_text();
    }
}
