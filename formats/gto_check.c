/* gto_check.c: what the .gto reader and writer both run over a section's payload: the
 * section checksum (GTO_FORMAT.md, "Checksums") and the content checks of every section
 * (indices in range, keys sorted, numbers finite and in their meaning's range), one
 * chunk at a time so that each payload byte is read once while it is in cache. The
 * reader (gto_read.c) runs them on the mapping, the writer (gto_write.c) on its own
 * input before it writes a byte. Part of the runtime library (the reader needs it).
 * Depends on gto_layout.h, wrt_common, basis.h (the function keys) and libm. */
#include "gto_layout.h"
#include "../common/cluster_tree.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "../common/basis.h"
#include "../common/limits.h"

const gto_sec_desc gto_sec_info[SEC_KNOWN_END] = {
    [SEC_QUADS] = {"quads", sizeof(wrt_gto_quad)},
    [SEC_MATERIALS] = {"materials", sizeof(wrt_gto_material)},
    [SEC_LIGHTS] = {"lights", sizeof(wrt_gto_light)},
    [SEC_CAMERA] = {"camera", sizeof(wrt_gto_camera)},
    [SEC_NAMES] = {"names", 64},
    [SEC_FKEYS] = {"fkeys", 8},
    [SEC_COL_START] = {"col_start", 8},
    [SEC_ROWS] = {"rows", 4},
    [SEC_VALS] = {"vals", 12},
    [SEC_STATS] = {"stats", sizeof(wrt_gto_stats)},
    [SEC_PROVENANCE] = {"provenance", 1},
    [SEC_KKEYS] = {"kkeys", 8},
    [SEC_KCOL_START] = {"kcol_start", 8},
    [SEC_KROWS] = {"krows", 4},
    [SEC_KVALS] = {"kvals", 4},
    [SEC_SRCMAP] = {"srcmap", sizeof(wrt_gto_srcmap)},
    [SEC_OPCODE] = {"opcode", 1},
    [SEC_NORMALS] = {"normals", sizeof(wrt_gto_normals)},
    [SEC_TEXTURES] = {"textures", 1},
};

/* ------------------------------------------------------------------------------------
 * Checksum: 4 lanes, each absorbing one 64-bit little-endian word per 32-byte stripe by
 * v = (v ^ w) * K1; v ^= v >> 32. For a fixed v the step is a bijection of w and for a
 * fixed w a bijection of v (odd multiplier, xorshift), so a change confined to one
 * word always changes that lane and, through the bijective final mix, the result. The
 * tail is zero-padded to a stripe and the length enters the final mix.
 * ---------------------------------------------------------------------------------- */

#define H_K1 0x9E3779B97F4A7C15ull
#define H_K2 0xC2B2AE3D27D4EB4Full
#define H_K3 0x165667B19E3779F9ull

typedef struct hstate { uint64_t v[4]; } hstate;

static void h_init(hstate *s) {
    for (int i = 0; i < 4; i++) s->v[i] = H_K2 * (uint64_t)(i + 1);
}

static inline uint64_t h_ld64(const uint8_t *p) { uint64_t w; memcpy(&w, p, 8); return w; }
static inline uint64_t h_step(uint64_t v, uint64_t w) { v = (v ^ w) * H_K1; return v ^ (v >> 32); }

/* n must be a multiple of 32. */
static void h_blocks(hstate *s, const uint8_t *p, size_t n) {
    uint64_t a = s->v[0], b = s->v[1], c = s->v[2], d = s->v[3];
    for (; n >= 32; n -= 32, p += 32) {
        a = h_step(a, h_ld64(p));
        b = h_step(b, h_ld64(p + 8));
        c = h_step(c, h_ld64(p + 16));
        d = h_step(d, h_ld64(p + 24));
    }
    s->v[0] = a; s->v[1] = b; s->v[2] = c; s->v[3] = d;
}

static uint64_t h_final(hstate *s, const uint8_t *tail, size_t ntail, uint64_t total) {
    if (ntail) {
        uint8_t buf[32] = {0};
        memcpy(buf, tail, ntail);
        h_blocks(s, buf, 32);
    }
    uint64_t h = total ^ H_K3;
    for (int i = 0; i < 4; i++) h = h_step(h, s->v[i]);
    h ^= h >> 33; h *= H_K2; h ^= h >> 29; h *= H_K3; h ^= h >> 32;
    return h;
}

uint64_t wrt_gto_checksum(const void *data, size_t n) {
    hstate s;
    h_init(&s);
    size_t full = n & ~(size_t)31;
    h_blocks(&s, data, full);
    return h_final(&s, (const uint8_t *)data + full, n - full, n);
}

/* ------------------------------------------------------------------------------------
 * Content checks, shared by the reader (on the mapping) and the writer (on its input).
 * A chunk checker records the first problem in the context and keeps quiet after it;
 * the caller reports it only once the section's checksum is known to be right, so a
 * flipped byte reads as a checksum error, not as the index error it may cause.
 * ---------------------------------------------------------------------------------- */

static void vbad(vctx *v, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void vbad(vctx *v, const char *fmt, ...) {
    if (v->bad) return;
    v->bad = 1;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(v->err, sizeof v->err, fmt, ap);
    va_end(ap);
}

static int has_nul64(const char *s) { return memchr(s, 0, 64) != NULL; }

static void check_quads_local(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_quad *q = (const wrt_gto_quad *)base;
    for (uint64_t i = first; i < first + n; i++) {
        if (q[i].material >= v->g->nmaterials)
            return vbad(v, "quad %" PRIu64 ": material %u out of range (%u materials)", i,
                        q[i].material, v->g->nmaterials);
        if (q[i].name != WRT_GTO_NO_NAME && q[i].name >= v->g->nnames)
            return vbad(v, "quad %" PRIu64 ": name %u out of range (%u names)", i, q[i].name,
                        v->g->nnames);
        for (int k = 0; k < 4; k++)
            for (int j = 0; j < 3; j++)
                if (!wrt_in_bound(q[i].p[k][j], WRT_MAX_COORD)) /* common/limits.h: what the runtime carries */
                    return vbad(v, "quad %" PRIu64 ": corner %d is not finite or beyond %g", i, k, WRT_MAX_COORD);
        const float *f[3] = {q[i].n, q[i].t, q[i].b};
        for (int k = 0; k < 3; k++) {
            double l = sqrt((double)f[k][0] * f[k][0] + (double)f[k][1] * f[k][1] + (double)f[k][2] * f[k][2]);
            if (!(fabs(l - 1) <= 1e-3))
                return vbad(v, "quad %" PRIu64 ": %s is not a unit vector", i, k == 0 ? "normal" : k == 1 ? "tangent" : "bitangent");
        }
        if (!(q[i].area > 0) || !isfinite(q[i].area))
            return vbad(v, "quad %" PRIu64 ": area %g is not finite and > 0", i, (double)q[i].area);
    }
}

/* Every number handed out is checked: finite, and in the range its meaning allows
 * (0 <= x <= 1 for a factor, unit length for a direction, ...). */
static int in01(double x) { return x >= 0 && x <= 1; }            /* false for NaN */
static int fin3d(const double *x) { return isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2]); }
static int unit3d(const double *x) {
    double l = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    return fabs(l - 1) <= 1e-3;
}

static void check_materials(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_material *m = (const wrt_gto_material *)base;
    for (uint64_t i = first; i < first + n; i++) {
        if (!has_nul64(m[i].name)) return vbad(v, "material %" PRIu64 ": name not terminated", i);
        for (int c = 0; c < 3; c++) {
            if (!in01(m[i].base_color[c]))
                return vbad(v, "material %" PRIu64 ": base_color[%d] %g is not in [0, 1]", i, c,
                            (double)m[i].base_color[c]);
            if (!(m[i].emissive[c] >= 0) || !(m[i].emissive[c] <= WRT_MAX_EMISSIVE))
                return vbad(v, "material %" PRIu64 ": emissive[%d] %g is not in [0, %g] (common/limits.h)", i, c,
                            (double)m[i].emissive[c], WRT_MAX_EMISSIVE);
        }
        if (!in01(m[i].metallic) || !in01(m[i].roughness))
            return vbad(v, "material %" PRIu64 ": metallic %g or roughness %g is not in [0, 1]", i,
                        (double)m[i].metallic, (double)m[i].roughness);
        if (m[i].lambertian > 1 || m[i].alevel > WRT_MAX_ALEVEL)
            return vbad(v, "material %" PRIu64 ": lambertian %u or alevel %u out of range", i,
                        m[i].lambertian, m[i].alevel);
    }
}

static void check_lights(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_light *l = (const wrt_gto_light *)base;
    for (uint64_t i = first; i < first + n; i++) {
        if (!has_nul64(l[i].name)) return vbad(v, "light %" PRIu64 ": name not terminated", i);
        if (l[i].type > WRT_LIGHT_DIRECTIONAL)
            return vbad(v, "light %" PRIu64 ": unknown type %u", i, l[i].type);
        if (!fin3d(l[i].pos) || !fin3d(l[i].dir) || (l[i].type != WRT_LIGHT_POINT && !unit3d(l[i].dir)))
            return vbad(v, "light %" PRIu64 ": position or direction not finite (or not unit)", i);
        for (int c = 0; c < 3; c++)
            if (!(l[i].color[c] >= 0) || !isfinite(l[i].color[c]))
                return vbad(v, "light %" PRIu64 ": color[%d] %g is not finite and >= 0", i, c,
                            (double)l[i].color[c]);
        if (!(l[i].intensity >= 0) || !isfinite(l[i].intensity) || !(l[i].range >= 0) ||
            !isfinite(l[i].range))
            return vbad(v, "light %" PRIu64 ": intensity %g or range %g is not finite and >= 0", i,
                        (double)l[i].intensity, (double)l[i].range);
        /* finite, now within what the runtime carries */
        if (!wrt_in_bound(l[i].pos[0], WRT_MAX_COORD) || !wrt_in_bound(l[i].pos[1], WRT_MAX_COORD) ||
            !wrt_in_bound(l[i].pos[2], WRT_MAX_COORD) || !(l[i].intensity <= WRT_MAX_LIGHT_INTENSITY) ||
            !(l[i].color[0] <= WRT_MAX_COLOR && l[i].color[1] <= WRT_MAX_COLOR && l[i].color[2] <= WRT_MAX_COLOR))
            return vbad(v, "light %" PRIu64 ": position beyond %g, intensity above %g or a colour channel above %g "
                        "(common/limits.h)", i, WRT_MAX_COORD, WRT_MAX_LIGHT_INTENSITY, WRT_MAX_COLOR);
        if (!(l[i].inner_cone >= 0) || !(l[i].outer_cone >= l[i].inner_cone) ||
            (l[i].type == WRT_LIGHT_SPOT && !(l[i].outer_cone > l[i].inner_cone)) || /* the runtime's rule */
            !(l[i].outer_cone <= (float)(WRT_PI / 2) * 1.0001f))
            return vbad(v, "light %" PRIu64 ": cone angles %g / %g not 0 <= inner <= outer <= pi/2", i,
                        (double)l[i].inner_cone, (double)l[i].outer_cone);
    }
}

static void check_camera(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_camera *c = (const wrt_gto_camera *)base;
    for (uint64_t i = first; i < first + n; i++) {
        if (!fin3d(c[i].pos) || !fin3d(c[i].dir) || !fin3d(c[i].up))
            return vbad(v, "camera: position, direction or up not finite");
        if (!wrt_coord3_ok(c[i].pos[0], c[i].pos[1], c[i].pos[2])) /* common/limits.h */
            return vbad(v, "camera: position (%g, %g, %g) beyond %g", c[i].pos[0], c[i].pos[1], c[i].pos[2],
                        WRT_MAX_COORD);
        /* yfov 0: the scene has no camera (a scene built in code); the player frames it */
        if (c[i].yfov == 0 && c[i].aspect == 0 && c[i].znear == 0 && c[i].zfar == 0) continue;
        if (!unit3d(c[i].dir) || !unit3d(c[i].up))
            return vbad(v, "camera: direction or up not of unit length");
        if (!(c[i].yfov >= WRT_MIN_YFOV && c[i].yfov < WRT_PI) || !(c[i].aspect >= 0) || !isfinite(c[i].aspect) ||
            !(c[i].znear > 0) || !isfinite(c[i].znear) || !(c[i].zfar >= 0) || !isfinite(c[i].zfar))
            return vbad(v, "camera: yfov %g, aspect %g, znear %g or zfar %g out of range", c[i].yfov,
                        c[i].aspect, c[i].znear, c[i].zfar);
    }
}

static void check_stats(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_stats *s = (const wrt_gto_stats *)base;
    for (uint64_t i = first; i < first + n; i++) {
        const double t[5] = {s[i].t_dto, s[i].t_gto, s[i].t_write, s[i].t_total, s[i].energy_left};
        for (int k = 0; k < 5; k++)
            if (!(t[k] >= 0) || !isfinite(t[k]))
                return vbad(v, "stats: %s %g is not finite and >= 0",
                            k == 4 ? "energy_left" : "a time", t[k]);
    }
}

static void check_names(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    for (uint64_t i = first; i < first + n; i++)
        if (!has_nul64((const char *)base + 64 * i))
            return vbad(v, "name %" PRIu64 ": not terminated", i);
}

/* Branch-free scans, in blocks of 16 so that the compiler vectorizes them at -O2 (its
 * cheap cost model wants a known trip count); the slow loops that follow a hit only
 * run to name the first bad element. */
#define SCAN_BLOCK 16

static uint32_t scan_not_ascending_u64(const uint64_t *k, size_t n) { /* any k[i] <= k[i-1] */
    uint32_t bad = 0;
    size_t i = 1;
    for (; i + SCAN_BLOCK <= n; i += SCAN_BLOCK) {
        uint32_t b = 0;
        for (int j = 0; j < SCAN_BLOCK; j++) b |= k[i + j] <= k[i + j - 1];
        bad |= b;
    }
    for (; i < n; i++) bad |= k[i] <= k[i - 1];
    return bad;
}

static uint32_t scan_decreasing_u64(const uint64_t *k, size_t n) { /* any k[i] < k[i-1] */
    uint32_t bad = 0;
    size_t i = 1;
    for (; i + SCAN_BLOCK <= n; i += SCAN_BLOCK) {
        uint32_t b = 0;
        for (int j = 0; j < SCAN_BLOCK; j++) b |= k[i + j] < k[i + j - 1];
        bad |= b;
    }
    for (; i < n; i++) bad |= k[i] < k[i - 1];
    return bad;
}

/* Entries of one column: any r >= nf, or not strictly ascending. */
static uint32_t scan_column(const uint32_t *r, size_t n, uint32_t nf) {
    uint32_t mx = r[0], bad = 0;
    size_t i = 1;
    for (; i + SCAN_BLOCK <= n; i += SCAN_BLOCK) {
        uint32_t m = mx, b = 0;
        for (int j = 0; j < SCAN_BLOCK; j++) {
            uint32_t x = r[i + j];
            m = x > m ? x : m;
            b |= x <= r[i + j - 1];
        }
        mx = m;
        bad |= b;
    }
    for (; i < n; i++) {
        mx = r[i] > mx ? r[i] : mx;
        bad |= r[i] <= r[i - 1];
    }
    return bad | (mx >= nf);
}

/* The largest magnitude an operator value may have: 2^48 (2.8e14). A light's radiant
 * factor is at most 1e18 (common/limits.h), so one product stays below 3e32 and the sums a
 * light change makes stay inside float range; a forged file's 3e38, finite but absurd,
 * would turn into infinities and NaN pixels. Legitimate entries are transport
 * coefficients: about 1 in a room, 1e6 where areas differ by 1e12. */
#define GTO_MAX_VALUE_EXP 48
#define GTO_MAX_VALUE ((double)(1ull << GTO_MAX_VALUE_EXP))
/* Any float (as bits) whose exponent is at least 127 + 48 (|x| >= 2^48, infinity or NaN
 * included): adding 256 - (127 + 48) to the exponent field carries into the sign bit
 * exactly then. */
#define GTO_BIG_CARRY ((uint32_t)(256 - (127 + GTO_MAX_VALUE_EXP)) << 23)
static uint32_t scan_nonfinite(const uint32_t *u, size_t n) {
    uint32_t acc = 0;
    size_t i = 0;
    for (; i + SCAN_BLOCK <= n; i += SCAN_BLOCK) {
        uint32_t a = 0;
        for (int j = 0; j < SCAN_BLOCK; j++) a |= (u[i + j] & 0x7f800000u) + GTO_BIG_CARRY;
        acc |= a;
    }
    for (; i < n; i++) acc |= (u[i] & 0x7f800000u) + GTO_BIG_CARRY;
    return acc >> 31;
}
/* What is wrong with a value scan_nonfinite flagged, or NULL. */
static const char *value_problem(uint32_t u) {
    if ((u & 0x7f800000u) == 0x7f800000u) return (u & 0x007fffffu) ? "NaN" : "infinite";
    return ((u & 0x7f800000u) + GTO_BIG_CARRY) >> 31 ? "beyond 2^48 (2.8e14), more than any transport coefficient" : NULL;
}

static void check_fkeys(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const uint64_t *k = (const uint64_t *)base;
    uint64_t i = first ? first - 1 : 0; /* include the last key of the previous chunk */
    if (scan_not_ascending_u64(k + i, (size_t)(first + n - i))) {
        for (i++; i < first + n; i++)
            if (k[i] <= k[i - 1])
                return vbad(v, "fkeys not strictly ascending at index %" PRIu64
                            " (0x%016" PRIx64 " after 0x%016" PRIx64 ")", i, k[i], k[i - 1]);
    }
    /* Sorted so far: the last key has the largest quad. */
    uint32_t q = wrt_fkey_quad(k[first + n - 1]);
    if (q >= v->g->nquads)
        return vbad(v, "fkeys[%" PRIu64 "] names quad %u, but there are %u quads", first + n - 1,
                    q, v->g->nquads);
}

/* Column starts (col_start, kcol_start): from 0, never decreasing, ending at nnz. */
static void check_starts(vctx *v, const char *nm, const uint64_t *c, uint64_t first, uint64_t n,
                         uint64_t ncols, uint64_t nnz) {
    if (first == 0 && c[0] != 0) return vbad(v, "%s[0] is %" PRIu64 ", not 0", nm, c[0]);
    uint64_t i = first ? first - 1 : 0;
    if (scan_decreasing_u64(c + i, (size_t)(first + n - i))) {
        for (i++; i < first + n; i++)
            if (c[i] < c[i - 1])
                return vbad(v, "%s not monotone at column %" PRIu64 " (%" PRIu64
                            " after %" PRIu64 ")", nm, i, c[i], c[i - 1]);
    }
    if (first + n == ncols + 1 && c[ncols] != nnz)
        return vbad(v, "%s[%" PRIu64 "] is %" PRIu64 ", but there are %" PRIu64 " entries",
                    nm, ncols, c[ncols], nnz);
}

static void check_col_start(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    check_starts(v, "col_start", (const uint64_t *)base, first, n, v->g->nfuncs, v->g->nnz);
}

/* rows: each < nfuncs and strictly ascending within its column. col_start is valid. */
static void check_rows(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const uint32_t *r = (const uint32_t *)base;
    const uint64_t *cs = v->g->col_start;
    uint32_t nf = v->g->nfuncs;
    uint64_t e = first, end = first + n, col = v->col;
    while (e < end) {
        while (cs[col + 1] <= e) col++;  /* e < nnz = cs[nf], so col < nf */
        uint64_t cend = cs[col + 1] < end ? cs[col + 1] : end;
        /* A column cut by the chunk boundary continues from its previous entry. */
        uint64_t from = e > cs[col] ? e - 1 : e;
        if (scan_column(r + from, (size_t)(cend - from), nf)) {
            for (; e < cend; e++) {
                if (r[e] >= nf)
                    return vbad(v, "rows[%" PRIu64 "] = %u out of range (%u functions) in column %"
                                PRIu64, e, r[e], nf, col);
                if (e > cs[col] && r[e] <= r[e - 1])
                    return vbad(v, "rows not strictly ascending in column %" PRIu64
                                " at entry %" PRIu64, col, e);
            }
        }
        e = cend;
    }
    v->col = col;
}

static void check_vals(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const uint32_t *u = (const uint32_t *)base + 3 * first;
    if (scan_nonfinite(u, (size_t)(3 * n))) {
        for (uint64_t j = 0; j < 3 * n; j++)
            if (value_problem(u[j]))
                return vbad(v, "vals[%" PRIu64 "] channel %d is %s", first + j / 3, (int)(j % 3), value_problem(u[j]));
    }
}

/* ---- The first-bounce operator K (version 1.1). Its sections come after the ones
 * they refer to (quads, materials, fkeys), so those are already checked. ---- */

/* What is wrong with a key's form (NULL: nothing): nodes inside their level's grid, the
 * scaling function (type 0) on root nodes only, the spare bits zero. Levels are
 * bounded by the caller. */
static const char *fkey_malformed(uint64_t k) {
    wrt_node s = wrt_fkey_snode(k), a = wrt_fkey_anode(k);
    if ((s.x >> s.level) || (s.y >> s.level)) return "spatial node outside its level's grid";
    if ((a.x >> a.level) || (a.y >> a.level)) return "angular node outside its level's grid";
    if (s.level > 0 && wrt_fkey_stype(k) == 0) return "spatial scaling function (type 0) on a non-root node";
    if (a.level > 0 && wrt_fkey_atype(k) == 0) return "angular scaling function (type 0) on a non-root node";
    if (k & 63) return "spare bits not zero";
    return NULL;
}

/* kkeys: strictly ascending (across chunks), each on a glossy quad, spatial level <=
 * WRT_MAX_SLEVEL, well formed (any angular node level a key can name, 0..3, is one K may
 * use: L_K <= WRT_K_MAX_LEVEL). */
static void check_kkeys(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const uint64_t *k = (const uint64_t *)base;
    const wrt_gto *g = v->g;
    uint64_t i = first ? first - 1 : 0;
    if (scan_not_ascending_u64(k + i, (size_t)(first + n - i))) {
        for (i++; i < first + n; i++)
            if (k[i] <= k[i - 1])
                return vbad(v, "kkeys not strictly ascending at index %" PRIu64
                            " (0x%016" PRIx64 " after 0x%016" PRIx64 ")", i, k[i], k[i - 1]);
    }
    for (i = first; i < first + n; i++) {
        uint32_t q = wrt_fkey_quad(k[i]);
        if (q >= g->nquads)
            return vbad(v, "kkeys[%" PRIu64 "] names quad %u, but there are %u quads", i, q, g->nquads);
        uint32_t m = g->quads[q].material;
        if (g->materials[m].lambertian)
            return vbad(v, "kkeys[%" PRIu64 "] names quad %u, whose material %u is Lambertian "
                        "(K's columns are functions of glossy quads)", i, q, m);
        unsigned sl = wrt_fkey_snode(k[i]).level;
        if (sl > WRT_MAX_SLEVEL)
            return vbad(v, "kkeys[%" PRIu64 "]: spatial level %u, at most %d", i, sl, WRT_MAX_SLEVEL);
        const char *why = fkey_malformed(k[i]);
        if (why) return vbad(v, "kkeys[%" PRIu64 "]: malformed key 0x%016" PRIx64 " (%s)", i, k[i], why);
    }
}

static void check_kcol_start(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    check_starts(v, "kcol_start", (const uint64_t *)base, first, n, v->g->nkcols, v->g->knnz);
}

/* The index range [lo, hi) of quad q's functions in fkeys (checked ascending). */
static void fkeys_of_quad(const wrt_gto *g, uint32_t q, uint32_t *lo, uint32_t *hi) {
    for (int side = 0; side < 2; side++) {
        if ((uint64_t)q + side >= (1u << 22)) { *hi = g->nfuncs; break; } /* the last quad a key holds */
        uint64_t key = (uint64_t)(q + side) << 42; /* the quad is the key's top bits (22 bits) */
        uint32_t a = 0, b = g->nfuncs;
        while (a < b) {
            uint32_t mid = a + (b - a) / 2;
            if (g->fkeys[mid] < key) a = mid + 1;
            else b = mid;
        }
        *(side ? hi : lo) = a;
    }
}

/* Entries of one K column: any r >= nf, not strictly ascending, or in [lo, hi). */
static uint32_t scan_kcolumn(const uint32_t *r, size_t n, uint32_t nf, uint32_t lo, uint32_t hi) {
    uint32_t own = 0, w = hi - lo;
    size_t i = 0;
    for (; i + SCAN_BLOCK <= n; i += SCAN_BLOCK) {
        uint32_t b = 0;
        for (int j = 0; j < SCAN_BLOCK; j++) b |= r[i + j] - lo < w;
        own |= b;
    }
    for (; i < n; i++) own |= r[i] - lo < w;
    return own | scan_column(r, n, nf);
}

/* krows: each < nfuncs, strictly ascending within its column, and a function of
 * another quad than the column's (K carries light from one quad to another).
 * kkeys and kcol_start are valid. */
static void check_krows(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto *g = v->g;
    const uint32_t *r = (const uint32_t *)base;
    const uint64_t *cs = g->kcol_start;
    uint32_t nf = g->nfuncs;
    uint64_t e = first, end = first + n, col = v->kcol;
    while (e < end) {
        while (cs[col + 1] <= e) col++;  /* e < knnz = cs[nkcols], so col < nkcols */
        uint64_t cend = cs[col + 1] < end ? cs[col + 1] : end;
        uint64_t from = e > cs[col] ? e - 1 : e;
        uint32_t q = wrt_fkey_quad(g->kkeys[col]);
        if (v->kq != q + 1) { /* kkeys are sorted by quad: once per quad */
            fkeys_of_quad(g, q, &v->kq_lo, &v->kq_hi);
            v->kq = q + 1;
        }
        if (scan_kcolumn(r + from, (size_t)(cend - from), nf, v->kq_lo, v->kq_hi)) {
            for (; e < cend; e++) {
                if (r[e] >= nf)
                    return vbad(v, "krows[%" PRIu64 "] = %u out of range (%u functions) in column %"
                                PRIu64, e, r[e], nf, col);
                if (e > cs[col] && r[e] <= r[e - 1])
                    return vbad(v, "krows not strictly ascending in column %" PRIu64
                                " at entry %" PRIu64, col, e);
                if (r[e] >= v->kq_lo && r[e] < v->kq_hi)
                    return vbad(v, "krows[%" PRIu64 "] = %u in column %" PRIu64 " is a function of "
                                "quad %u, the column's own quad", e, r[e], col, q);
            }
        }
        e = cend;
    }
    v->kcol = col;
}

static void check_kvals(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const uint32_t *u = (const uint32_t *)base + first;
    if (scan_nonfinite(u, (size_t)n)) {
        for (uint64_t j = 0; j < n; j++)
            if (value_problem(u[j])) return vbad(v, "kvals[%" PRIu64 "] is %s", first + j, value_problem(u[j]));
    }
}

/* What needs a later section: each quad's function range against fkeys. */
void gto_check_quad_ranges(vctx *v) {
    const wrt_gto *g = v->g;
    uint64_t next = 0;
    for (uint32_t q = 0; q < g->nquads; q++) {
        const wrt_gto_quad *r = &g->quads[q];
        if (r->func_first > g->nfuncs || r->func_count > g->nfuncs - r->func_first)
            return vbad(v, "quad %u: functions [%u, +%u) beyond the %u functions", q,
                        r->func_first, r->func_count, g->nfuncs);
        if (r->func_first != next)
            return vbad(v, "quad %u: functions start at %u, expected %" PRIu64
                        " (ranges must follow each other)", q, r->func_first, next);
        if (r->func_count && (wrt_fkey_quad(g->fkeys[r->func_first]) != q ||
                              wrt_fkey_quad(g->fkeys[r->func_first + r->func_count - 1]) != q))
            return vbad(v, "quad %u: its function range holds keys of another quad", q);
        next += r->func_count;
    }
    if (next != g->nfuncs)
        return vbad(v, "quads cover %" PRIu64 " functions, but there are %u", next, g->nfuncs);
}

/* ---- The quad-to-source map (version 1.2): one record per quad (the count is checked
 * with the layout). A twin names an earlier quad, whose record is then already checked:
 * a front that is not a twin itself and comes from the same triangles. ---- */
static void check_srcmap(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_srcmap *all = (const wrt_gto_srcmap *)base;
    for (uint64_t q = first; q < first + n; q++) {
        const wrt_gto_srcmap *r = &all[q];
        if (r->node < -1 || r->mesh < -1 || r->prim < -1 || r->tri[0] < -1 || r->tri[1] < -1)
            return vbad(v, "srcmap[%" PRIu64 "]: negative index (node %d, mesh %d, primitive %d, triangles %d %d)",
                        q, r->node, r->mesh, r->prim, r->tri[0], r->tri[1]);
        if (r->kind > WRT_ELEM_TRIANGLE)
            return vbad(v, "srcmap[%" PRIu64 "]: unknown element kind %u", q, r->kind);
        if (r->part > (r->kind == WRT_ELEM_TRIANGLE ? 2u : 0u))
            return vbad(v, "srcmap[%" PRIu64 "]: part %u of a %s", q, r->part,
                        r->kind == WRT_ELEM_TRIANGLE ? "triangle (0..2)" : "paired quad (0)");
        if (r->kind == WRT_ELEM_TRIANGLE && r->tri[1] != -1)
            return vbad(v, "srcmap[%" PRIu64 "]: a triangle's quad with a second triangle %d", q, r->tri[1]);
        if (r->flags & ~(WRT_GTO_SRC_TWIN | WRT_GTO_SRC_UV) || r->reserved)
            return vbad(v, "srcmap[%" PRIu64 "]: unknown flags 0x%x or reserved %u not zero", q, r->flags,
                        r->reserved);
        if (r->flags & WRT_GTO_SRC_TWIN) {
            if (r->twin_of < 0 || (uint64_t)r->twin_of >= q)
                return vbad(v, "srcmap[%" PRIu64 "]: twin of quad %d, not an earlier quad", q, r->twin_of);
            const wrt_gto_srcmap *f = &all[r->twin_of];
            if (f->flags & WRT_GTO_SRC_TWIN)
                return vbad(v, "srcmap[%" PRIu64 "]: twin of quad %d, itself a twin", q, r->twin_of);
            if (f->node != r->node || f->mesh != r->mesh || f->prim != r->prim || f->tri[0] != r->tri[0] ||
                f->tri[1] != r->tri[1] || f->kind != r->kind || f->part != r->part)
                return vbad(v, "srcmap[%" PRIu64 "]: twin of quad %d, which comes from other triangles", q,
                            r->twin_of);
        } else if (r->twin_of != -1) {
            return vbad(v, "srcmap[%" PRIu64 "]: not a twin but twin_of %d (expected -1)", q, r->twin_of);
        }
        for (int k = 0; k < 8; k++) {
            float x = r->uv[k / 2][k % 2];
            if ((r->flags & WRT_GTO_SRC_UV) ? !isfinite(x) : x != 0.0f)
                return vbad(v, "srcmap[%" PRIu64 "]: uv of corner %d %s", q, k / 2,
                            (r->flags & WRT_GTO_SRC_UV) ? "not finite" : "not zero without the uv flag");
        }
    }
}

/* Corner normals: finite and unit (within 1e-3: they were made unit in double precision
 * and stored as floats). */
static void check_normals(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto_normals *all = (const wrt_gto_normals *)base;
    for (uint64_t q = first; q < first + n; q++)
        for (int k = 0; k < 4; k++) {
            const float *c = all[q].n[k];
            double l2 = (double)c[0] * c[0] + (double)c[1] * c[1] + (double)c[2] * c[2];
            if (!(fabs(l2 - 1) <= 2e-3))
                return vbad(v, "normals[%" PRIu64 "]: corner %d (%g, %g, %g) is not a unit vector", q, k,
                            (double)c[0], (double)c[1], (double)c[2]);
        }
}

chunk_check gto_sec_checker(uint32_t id) {
    switch (id) {
    case SEC_QUADS: return check_quads_local;
    case SEC_MATERIALS: return check_materials;
    case SEC_LIGHTS: return check_lights;
    case SEC_CAMERA: return check_camera;
    case SEC_STATS: return check_stats;
    case SEC_NAMES: return check_names;
    case SEC_FKEYS: return check_fkeys;
    case SEC_COL_START: return check_col_start;
    case SEC_ROWS: return check_rows;
    case SEC_VALS: return check_vals;
    case SEC_KKEYS: return check_kkeys;
    case SEC_KCOL_START: return check_kcol_start;
    case SEC_KROWS: return check_krows;
    case SEC_KVALS: return check_kvals;
    case SEC_SRCMAP: return check_srcmap;
    case SEC_NORMALS: return check_normals;
    case SEC_OPCODE: return gto_check_opcode;
    case SEC_KCODE: return gto_check_kcode;
    case SEC_OPSTREAM: return gto_check_opstream;
    default: return NULL;
    }
}

/* One pass over a section: checksum and checks, 8192 elements at a time. Returns the
 * checksum; v->bad tells whether a check failed. */
uint64_t gto_scan_section(const uint8_t *p, uint64_t count, uint32_t elem, chunk_check fn,
                          vctx *v) {
    hstate s;
    h_init(&s);
    const uint64_t chunk = 8192; /* elements; chunk * elem is a multiple of 32 */
    uint64_t done = 0, size = count * elem;
    while (count - done > chunk) {
        h_blocks(&s, p + done * elem, chunk * elem);
        if (fn && !v->bad) fn(v, p, done, chunk);
        done += chunk;
    }
    uint64_t rest = size - done * elem, full = rest & ~(uint64_t)31;
    h_blocks(&s, p + done * elem, full);
    uint64_t sum = h_final(&s, p + done * elem + full, rest - full, size);
    if (fn && !v->bad && count > done) fn(v, p, done, count - done);
    return sum;
}

wrt_status gto_check_ctree(const wrt_gto_cnode *nodes, uint32_t n, uint32_t nq, wrt_status fail, const char *what) {
    if (nq == 0 || n != 2 * nq - 1)
        return wrt_fail(fail, "%s: %u nodes for %u quads (need 2 x quads - 1)", what, n, nq);
    wrt_ctree t;
    wrt_status ast = wrt_ctree_alloc(&t, nq);
    if (ast != WRT_OK) return ast;
    for (uint32_t i = 0; i < n; i++) { t.left[i] = nodes[i].left; t.right[i] = nodes[i].right; t.area[i] = nodes[i].area; }
    wrt_status st = wrt_ctree_finish(&t, what);
    wrt_ctree_free(&t);
    if (st != WRT_OK && fail != st && st != WRT_ERR_NOMEM) {
        char msg[512];
        snprintf(msg, sizeof msg, "%s", wrt_last_error());
        return wrt_fail(fail, "%s", msg);
    }
    return st;
}
