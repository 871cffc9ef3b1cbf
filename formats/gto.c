/* gto.c: writes, maps and validates the .gto file, the baked light transport operator
 * (the sparse gathered or indirect GTO of Kontkanen et al. 2006, section 4.4, with the
 * quads, materials, lights and camera the run-time of section 5 needs). The layout is
 * specified in GTO_FORMAT.md; the on-disk records are the structs of gto.h, checked by
 * the static asserts below. The reader validates the header and every section's place
 * before it touches a byte of payload, then reads each payload byte once: a section's
 * checksum and its index checks run together, chunk by chunk, while the chunk is in
 * cache. The writer checks its input with the same code, writes a temporary file,
 * syncs it and renames it over the target. Depends on wrt_common, scene.h, basis.h and
 * POSIX (mmap, mkstemp, fsync, rename, sigaction). */
#include "gto.h"
#include "scene.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdalign.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <dirent.h>
#include <pthread.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../common/basis.h"

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the .gto file is little-endian and is used in place: a big-endian port needs a converting reader"
#endif

/* ------------------------------------------------------------------------------------
 * Layout: header, section table, sections. See GTO_FORMAT.md.
 * ---------------------------------------------------------------------------------- */

#define GTO_MAGIC "\x89WRT\r\n\x1a\n"
#define GTO_MAGIC_LEN 8
#define GTO_BOM 0x01020304u         /* written natively: bytes 04 03 02 01 */
#define GTO_BOM_SWAPPED 0x04030201u
#define GTO_ALIGN 64u
#define GTO_MAX_SECTIONS 64u

typedef struct gto_header {
    uint8_t magic[8];
    uint32_t byte_order;
    uint16_t version_major, version_minor;
    uint64_t file_size;
    uint32_t header_size;   /* 64 + 48 * nsections */
    uint32_t nsections;
    uint32_t op_kind;
    uint32_t flags;         /* 0 in version 1.0 */
    uint64_t header_checksum;
    uint8_t reserved[16];
} gto_header;

typedef struct gto_section {
    uint32_t id, elem_size;
    uint64_t offset, size, count, checksum;
    uint32_t flags, reserved; /* 0 in version 1.0 */
} gto_section;

_Static_assert(sizeof(gto_header) == 64, "header is 64 bytes");
_Static_assert(offsetof(gto_header, byte_order) == 8, "layout");
_Static_assert(offsetof(gto_header, version_major) == 12, "layout");
_Static_assert(offsetof(gto_header, version_minor) == 14, "layout");
_Static_assert(offsetof(gto_header, file_size) == 16, "layout");
_Static_assert(offsetof(gto_header, header_size) == 24, "layout");
_Static_assert(offsetof(gto_header, nsections) == 28, "layout");
_Static_assert(offsetof(gto_header, op_kind) == 32, "layout");
_Static_assert(offsetof(gto_header, header_checksum) == 40, "layout");
_Static_assert(sizeof(gto_section) == 48, "section entry is 48 bytes");
_Static_assert(offsetof(gto_section, offset) == 8, "layout");
_Static_assert(offsetof(gto_section, size) == 16, "layout");
_Static_assert(offsetof(gto_section, count) == 24, "layout");
_Static_assert(offsetof(gto_section, checksum) == 32, "layout");

_Static_assert(sizeof(wrt_gto_quad) == 168, "quad record");
_Static_assert(offsetof(wrt_gto_quad, n) == 96, "layout");
_Static_assert(offsetof(wrt_gto_quad, area) == 132, "layout");
_Static_assert(offsetof(wrt_gto_quad, material) == 136, "layout");
_Static_assert(offsetof(wrt_gto_quad, func_first) == 144, "layout");
_Static_assert(offsetof(wrt_gto_quad, func_count) == 148, "layout");
_Static_assert(offsetof(wrt_gto_quad, flags) == 152, "layout");
_Static_assert(offsetof(wrt_gto_quad, slevel) == 156, "layout");
_Static_assert(offsetof(wrt_gto_quad, reserved) == 164, "layout");
_Static_assert(sizeof(wrt_gto_material) == 104, "material record");
_Static_assert(offsetof(wrt_gto_material, base_color) == 64, "layout");
_Static_assert(offsetof(wrt_gto_material, emissive) == 84, "layout");
_Static_assert(offsetof(wrt_gto_material, lambertian) == 96, "layout");
_Static_assert(offsetof(wrt_gto_material, alevel) == 100, "layout");
_Static_assert(sizeof(wrt_gto_light) == 144, "light record");
_Static_assert(offsetof(wrt_gto_light, type) == 64, "layout");
_Static_assert(offsetof(wrt_gto_light, pos) == 80, "layout");
_Static_assert(offsetof(wrt_gto_light, dir) == 104, "layout");
_Static_assert(offsetof(wrt_gto_light, intensity) == 128, "layout");
_Static_assert(offsetof(wrt_gto_light, outer_cone) == 140, "layout");
_Static_assert(sizeof(wrt_gto_camera) == 104, "camera record");
_Static_assert(offsetof(wrt_gto_camera, yfov) == 72, "layout");
_Static_assert(offsetof(wrt_gto_camera, zfar) == 96, "layout");
_Static_assert(sizeof(wrt_gto_stats) == 152, "stats record");
_Static_assert(offsetof(wrt_gto_stats, links_dto) == 32, "layout");
_Static_assert(offsetof(wrt_gto_stats, entries_dto) == 56, "layout");
_Static_assert(offsetof(wrt_gto_stats, rays_traced) == 72, "layout");
_Static_assert(offsetof(wrt_gto_stats, bounces) == 88, "layout");
_Static_assert(offsetof(wrt_gto_stats, energy_left) == 96, "layout");
_Static_assert(offsetof(wrt_gto_stats, reserved) == 104, "layout");
_Static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE 754 binary32/binary64");

enum {
    SEC_QUADS = 1, SEC_MATERIALS, SEC_LIGHTS, SEC_CAMERA, SEC_NAMES, SEC_FKEYS,
    SEC_COL_START, SEC_ROWS, SEC_VALS, SEC_STATS, SEC_PROVENANCE,
    /* version 1.1: the first-bounce operator K, all four or none */
    SEC_KKEYS, SEC_KCOL_START, SEC_KROWS, SEC_KVALS,
    SEC_KNOWN_END
};
#define SEC_KNOWN (SEC_KNOWN_END - 1)
#define SEC_REQUIRED SEC_PROVENANCE /* ids 1 .. this are in every file */
#define GTO_MINOR_K 1               /* the minor version that added K */

static const struct { const char *name; uint32_t elem_size; } sec_info[SEC_KNOWN_END] = {
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
};

static const char *sec_name(uint32_t id) {
    return (id >= 1 && id <= SEC_KNOWN) ? sec_info[id].name : "unknown";
}

static uint64_t align_up(uint64_t x) { return (x + GTO_ALIGN - 1) & ~(uint64_t)(GTO_ALIGN - 1); }

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

typedef struct vctx {
    const wrt_gto *g;   /* counts and pointers of the sections checked so far */
    int bad;
    char err[256];
    uint64_t col;       /* rows: current column */
    uint64_t kcol;      /* krows: current column */
    uint32_t kq;        /* krows: quad + 1 whose function range is [kq_lo, kq_hi) (0: none) */
    uint32_t kq_lo, kq_hi;
} vctx;

static void vbad(vctx *v, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void vbad(vctx *v, const char *fmt, ...) {
    if (v->bad) return;
    v->bad = 1;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(v->err, sizeof v->err, fmt, ap);
    va_end(ap);
}

/* Checks elements [first, first + n) of a section whose payload starts at `base`. */
typedef void (*chunk_check)(vctx *v, const uint8_t *base, uint64_t first, uint64_t n);

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
                if (!isfinite(q[i].p[k][j]))
                    return vbad(v, "quad %" PRIu64 ": corner %d is not finite", i, k);
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
            if (!(m[i].emissive[c] >= 0) || !isfinite(m[i].emissive[c]))
                return vbad(v, "material %" PRIu64 ": emissive[%d] %g is not finite and >= 0", i, c,
                            (double)m[i].emissive[c]);
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
        if (l[i].type > WRT_LIGHT_SPOT)
            return vbad(v, "light %" PRIu64 ": unknown type %u", i, l[i].type);
        if (!fin3d(l[i].pos) || !fin3d(l[i].dir) || (l[i].type == WRT_LIGHT_SPOT && !unit3d(l[i].dir)))
            return vbad(v, "light %" PRIu64 ": position or direction not finite (or not unit)", i);
        for (int c = 0; c < 3; c++)
            if (!(l[i].color[c] >= 0) || !isfinite(l[i].color[c]))
                return vbad(v, "light %" PRIu64 ": color[%d] %g is not finite and >= 0", i, c,
                            (double)l[i].color[c]);
        if (!(l[i].intensity >= 0) || !isfinite(l[i].intensity) || !(l[i].range >= 0) ||
            !isfinite(l[i].range))
            return vbad(v, "light %" PRIu64 ": intensity %g or range %g is not finite and >= 0", i,
                        (double)l[i].intensity, (double)l[i].range);
        if (!(l[i].inner_cone >= 0) || !(l[i].outer_cone >= l[i].inner_cone) ||
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
        /* yfov 0: the scene has no camera (a scene built in code); the player frames it */
        if (c[i].yfov == 0 && c[i].aspect == 0 && c[i].znear == 0 && c[i].zfar == 0) continue;
        if (!unit3d(c[i].dir) || !unit3d(c[i].up))
            return vbad(v, "camera: direction or up not of unit length");
        if (!(c[i].yfov > 0 && c[i].yfov < WRT_PI) || !(c[i].aspect >= 0) || !isfinite(c[i].aspect) ||
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

/* Any float (as bits) with an all-ones exponent (NaN or infinity): adding one to the
 * exponent field carries into the sign bit exactly then. */
static uint32_t scan_nonfinite(const uint32_t *u, size_t n) {
    uint32_t acc = 0;
    size_t i = 0;
    for (; i + SCAN_BLOCK <= n; i += SCAN_BLOCK) {
        uint32_t a = 0;
        for (int j = 0; j < SCAN_BLOCK; j++) a |= (u[i + j] & 0x7f800000u) + 0x00800000u;
        acc |= a;
    }
    for (; i < n; i++) acc |= (u[i] & 0x7f800000u) + 0x00800000u;
    return acc >> 31;
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
            if ((u[j] & 0x7f800000u) == 0x7f800000u)
                return vbad(v, "vals[%" PRIu64 "] channel %d is %s", first + j / 3, (int)(j % 3),
                            (u[j] & 0x007fffffu) ? "NaN" : "infinite");
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
            if ((u[j] & 0x7f800000u) == 0x7f800000u)
                return vbad(v, "kvals[%" PRIu64 "] is %s", first + j,
                            (u[j] & 0x007fffffu) ? "NaN" : "infinite");
    }
}

/* What needs a later section: each quad's function range against fkeys. */
static void check_quad_ranges(vctx *v) {
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

static chunk_check sec_checker(uint32_t id) {
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
    default: return NULL;
    }
}

/* One pass over a section: checksum and checks, 8192 elements at a time. Returns the
 * checksum; v->bad tells whether a check failed. */
static uint64_t scan_section(const uint8_t *p, uint64_t count, uint32_t elem, chunk_check fn,
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

/* ------------------------------------------------------------------------------------
 * Reader
 * ---------------------------------------------------------------------------------- */

/* Where each section is, once the table has been checked (0 if absent). */
typedef struct gto_layout {
    gto_header h;
    const gto_section *table;
    const gto_section *sec[SEC_KNOWN_END];
} gto_layout;

/* Stage 1: the header and the section table, no payload byte read. */
static wrt_status parse_layout(const uint8_t *b, size_t len, gto_layout *L) {
    memset(L, 0, sizeof *L);
    if (len == 0) return wrt_fail(WRT_ERR_CORRUPT, "empty file (0 bytes)");
    size_t m = len < GTO_MAGIC_LEN ? len : GTO_MAGIC_LEN;
    if (memcmp(b, GTO_MAGIC, m) != 0) return wrt_fail(WRT_ERR_NOT_OURS, "not a .gto file (bad magic)");
    if (len < sizeof(gto_header))
        return wrt_fail(WRT_ERR_CORRUPT, "truncated: expected at least %zu bytes of header, found %zu",
                        sizeof(gto_header), len);
    memcpy(&L->h, b, sizeof L->h);
    const gto_header *h = &L->h;
    if (h->byte_order == GTO_BOM_SWAPPED)
        return wrt_fail(WRT_ERR_UNSUPPORTED, "big-endian file; this reader reads little-endian only");
    if (h->byte_order != GTO_BOM)
        return wrt_fail(WRT_ERR_CORRUPT, "bad byte-order mark 0x%08x", h->byte_order);
    if (h->version_major > WRT_GTO_VERSION)
        return wrt_fail(WRT_ERR_UNSUPPORTED,
                        "file version %u.%u is newer than this reader's version %d.%d",
                        h->version_major, h->version_minor, WRT_GTO_VERSION, WRT_GTO_VERSION_MINOR);
    if (h->version_major < WRT_GTO_VERSION)
        return wrt_fail(WRT_ERR_UNSUPPORTED,
                        "file version %u.%u is older than this reader's version %d.%d",
                        h->version_major, h->version_minor, WRT_GTO_VERSION, WRT_GTO_VERSION_MINOR);
    if (h->file_size > len)
        return wrt_fail(WRT_ERR_CORRUPT, "truncated: expected %" PRIu64 " bytes, found %zu",
                        h->file_size, len);
    if (h->file_size < len)
        return wrt_fail(WRT_ERR_CORRUPT, "trailing data: expected %" PRIu64 " bytes, found %zu",
                        h->file_size, len);
    if (h->nsections == 0 || h->nsections > GTO_MAX_SECTIONS)
        return wrt_fail(WRT_ERR_CORRUPT, "bad section count %u", h->nsections);
    if (h->header_size != sizeof(gto_header) + sizeof(gto_section) * h->nsections)
        return wrt_fail(WRT_ERR_CORRUPT, "header size %u does not match %u sections",
                        h->header_size, h->nsections);
    if (h->header_size > len)
        return wrt_fail(WRT_ERR_CORRUPT, "section table (%u bytes) beyond end of file (%zu bytes)",
                        h->header_size, len);
    {
        alignas(8) uint8_t buf[sizeof(gto_header) + sizeof(gto_section) * GTO_MAX_SECTIONS];
        memcpy(buf, b, h->header_size);
        memset(buf + offsetof(gto_header, header_checksum), 0, 8);
        uint64_t sum = wrt_gto_checksum(buf, h->header_size);
        if (sum != h->header_checksum)
            return wrt_fail(WRT_ERR_CORRUPT, "header checksum mismatch (stored 0x%016" PRIx64
                            ", computed 0x%016" PRIx64 ")", h->header_checksum, sum);
    }
    L->table = (const gto_section *)(b + sizeof(gto_header));
    if (h->op_kind > WRT_GTO_OP_GATHERED)
        return wrt_fail(WRT_ERR_UNSUPPORTED, "unknown operator kind %u", h->op_kind);
    uint64_t prev_end = h->header_size;
    uint32_t prev_id = 0;
    for (uint32_t i = 0; i < h->nsections; i++) {
        const gto_section *s = &L->table[i];
        const char *nm = sec_name(s->id);
        if (s->id <= prev_id)
            return wrt_fail(WRT_ERR_CORRUPT, "section table entry %u (id %u, %s) out of order or repeated",
                            i, s->id, nm);
        prev_id = s->id;
        if (s->offset > len || s->size > len - s->offset)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: offset %" PRIu64 " + size %" PRIu64
                            " beyond end of file (%zu bytes)", nm, s->offset, s->size, len);
        if (s->offset % GTO_ALIGN)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: offset %" PRIu64 " not %u-byte aligned",
                            nm, s->offset, GTO_ALIGN);
        if (s->offset != align_up(prev_end))
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: offset %" PRIu64 ", expected %" PRIu64
                            " (sections follow each other)", nm, s->offset, align_up(prev_end));
        if (s->id <= SEC_KNOWN && s->elem_size != sec_info[s->id].elem_size)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: element size %u, expected %u", nm,
                            s->elem_size, sec_info[s->id].elem_size);
        if (s->elem_size == 0 || s->count > s->size / s->elem_size ||
            s->count * s->elem_size != s->size)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: size %" PRIu64 " is not %" PRIu64
                            " elements of %u bytes", nm, s->size, s->count, s->elem_size);
        if (s->id <= SEC_KNOWN) L->sec[s->id] = s;
        prev_end = s->offset + s->size;
    }
    if (prev_end != len)
        return wrt_fail(WRT_ERR_CORRUPT, "last section ends at %" PRIu64 ", file has %zu bytes",
                        prev_end, len);
    for (uint32_t id = 1; id <= SEC_REQUIRED; id++)
        if (!L->sec[id]) return wrt_fail(WRT_ERR_CORRUPT, "missing section %s", sec_name(id));
    /* The first-bounce operator: all four sections or none. */
    int nk = 0;
    for (uint32_t id = SEC_KKEYS; id <= SEC_KVALS; id++) nk += L->sec[id] != NULL;
    if (nk != 0 && nk != SEC_KVALS - SEC_KKEYS + 1)
        for (uint32_t id = SEC_KKEYS; id <= SEC_KVALS; id++)
            if (!L->sec[id])
                return wrt_fail(WRT_ERR_CORRUPT, "missing section %s (the first-bounce sections kkeys, "
                                "kcol_start, krows and kvals come all four or none)", sec_name(id));
    return WRT_OK;
}

/* A compressed-column operator's four sections: one column start per key and one past
 * the end, one value per row entry (the operator's and K's). */
static wrt_status check_csc_counts(const gto_section *const *S, uint32_t keys, uint32_t col_start,
                                   uint32_t rows, uint32_t vals, const char *columns) {
    if (S[col_start]->count != S[keys]->count + 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " entries, expected %" PRIu64 " (%s + 1)",
                        sec_name(col_start), S[col_start]->count, S[keys]->count + 1, columns);
    if (S[vals]->count != S[rows]->count)
        return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " entries, %s has %" PRIu64,
                        sec_name(vals), S[vals]->count, sec_name(rows), S[rows]->count);
    return WRT_OK;
}

/* Stage 2: counts that must agree across sections, and zero padding. */
static wrt_status check_counts(const uint8_t *b, const gto_layout *L, wrt_gto *g) {
    const gto_section *const *S = L->sec;
    static const uint32_t u32_counted[] = {SEC_QUADS, SEC_MATERIALS, SEC_LIGHTS, SEC_NAMES, SEC_FKEYS};
    for (size_t i = 0; i < sizeof u32_counted / sizeof *u32_counted; i++)
        if (S[u32_counted[i]]->count > UINT32_MAX - 1)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " elements, too many",
                            sec_name(u32_counted[i]), S[u32_counted[i]]->count);
    if (S[SEC_CAMERA]->count != 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section camera: %" PRIu64 " records, expected 1",
                        S[SEC_CAMERA]->count);
    if (S[SEC_STATS]->count != 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section stats: %" PRIu64 " records, expected 1",
                        S[SEC_STATS]->count);
    wrt_status st = check_csc_counts(S, SEC_FKEYS, SEC_COL_START, SEC_ROWS, SEC_VALS, "functions");
    if (st != WRT_OK) return st;
    if (S[SEC_KKEYS]) { /* then all four (parse_layout) */
        if (S[SEC_KKEYS]->count == 0)
            return wrt_fail(WRT_ERR_CORRUPT, "section kkeys: 0 columns (the first-bounce sections "
                            "are written only with a first-bounce operator)");
        if (S[SEC_KKEYS]->count > UINT32_MAX - 1)
            return wrt_fail(WRT_ERR_CORRUPT, "section kkeys: %" PRIu64 " elements, too many",
                            S[SEC_KKEYS]->count);
        st = check_csc_counts(S, SEC_KKEYS, SEC_KCOL_START, SEC_KROWS, SEC_KVALS, "K's columns");
        if (st != WRT_OK) return st;
    }
    /* Every byte outside the sections is header, table or zero padding. */
    uint64_t prev_end = L->h.header_size;
    for (uint32_t i = 0; i < L->h.nsections; i++) {
        const gto_section *s = &L->table[i];
        for (uint64_t o = prev_end; o < s->offset; o++)
            if (b[o])
                return wrt_fail(WRT_ERR_CORRUPT, "non-zero padding byte at %" PRIu64 " before section %s",
                                o, sec_name(s->id));
        prev_end = s->offset + s->size;
    }
    g->version = L->h.version_major;
    g->version_minor = L->h.version_minor;
    g->op_kind = L->h.op_kind;
    g->nquads = (uint32_t)S[SEC_QUADS]->count;
    g->nmaterials = (uint32_t)S[SEC_MATERIALS]->count;
    g->nlights = (uint32_t)S[SEC_LIGHTS]->count;
    g->nnames = (uint32_t)S[SEC_NAMES]->count;
    g->nfuncs = (uint32_t)S[SEC_FKEYS]->count;
    g->nnz = S[SEC_ROWS]->count;
#define SECPTR(id) ((const void *)(b + S[id]->offset))
    g->quads = SECPTR(SEC_QUADS);
    g->materials = SECPTR(SEC_MATERIALS);
    g->lights = SECPTR(SEC_LIGHTS);
    g->camera = SECPTR(SEC_CAMERA);
    g->names = SECPTR(SEC_NAMES);
    g->fkeys = SECPTR(SEC_FKEYS);
    g->col_start = SECPTR(SEC_COL_START);
    g->rows = SECPTR(SEC_ROWS);
    g->vals = SECPTR(SEC_VALS);
    g->stats = SECPTR(SEC_STATS);
    g->provenance = SECPTR(SEC_PROVENANCE);
    g->provenance_len = (size_t)S[SEC_PROVENANCE]->size;
    if (S[SEC_KKEYS]) {
        g->nkcols = (uint32_t)S[SEC_KKEYS]->count;
        g->knnz = S[SEC_KROWS]->count;
        g->kkeys = SECPTR(SEC_KKEYS);
        g->kcol_start = SECPTR(SEC_KCOL_START);
        g->krows = SECPTR(SEC_KROWS);
        g->kvals = SECPTR(SEC_KVALS);
    }
#undef SECPTR
    return WRT_OK;
}

/* Stage 3: the single pass over the payload. */
static wrt_status check_payload(const uint8_t *b, const gto_layout *L, const wrt_gto *g) {
    vctx v;
    memset(&v, 0, sizeof v);
    v.g = g;
    for (uint32_t i = 0; i < L->h.nsections; i++) {
        const gto_section *s = &L->table[i];
        uint64_t sum = scan_section(b + s->offset, s->count, s->elem_size, sec_checker(s->id), &v);
        if (sum != s->checksum)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: checksum mismatch (stored 0x%016" PRIx64
                            ", computed 0x%016" PRIx64 ")", sec_name(s->id), s->checksum, sum);
        if (v.bad) return wrt_fail(WRT_ERR_CORRUPT, "section %s: %s", sec_name(s->id), v.err);
    }
    check_quad_ranges(&v);
    if (v.bad) return wrt_fail(WRT_ERR_CORRUPT, "section quads: %s", v.err);
    return WRT_OK;
}

static wrt_status validate(const uint8_t *b, size_t len, wrt_gto *out) {
    gto_layout L;
    wrt_status st = parse_layout(b, len, &L);
    if (st == WRT_OK) st = check_counts(b, &L, out);
    if (st == WRT_OK) st = check_payload(b, &L, out);
    return st;
}

wrt_status wrt_gto_open_memory(const void *data, size_t size, wrt_gto *out) {
    memset(out, 0, sizeof *out);
    if (!data && size) return wrt_fail(WRT_ERR_INVALID_ARG, "no data");
    if ((uintptr_t)data % 8) return wrt_fail(WRT_ERR_INVALID_ARG, ".gto image not 8-byte aligned");
    wrt_status st = validate(data, size, out);
    if (st != WRT_OK) { memset(out, 0, sizeof *out); return st; }
    out->map = (void *)data;
    out->size = size;
    out->owns_map = 0;
    return WRT_OK;
}

/* Maps the whole of an open regular file read-only. *map is NULL for an empty file. */
static wrt_status map_fd(int fd, const char *path, void **map, size_t *len) {
    *map = NULL; *len = 0;
    struct stat st;
    if (fstat(fd, &st) != 0) return wrt_fail(WRT_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode))
        return wrt_fail(WRT_ERR_NOT_OURS, "%s: not a regular file (%s)", path,
                        S_ISDIR(st.st_mode) ? "a directory" : S_ISFIFO(st.st_mode) ? "a FIFO"
                        : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "a device" : "a special file");
    if ((uint64_t)st.st_size > SIZE_MAX) return wrt_fail(WRT_ERR_IO, "%s: too large", path);
    *len = (size_t)st.st_size;
    if (*len) {
        void *p = mmap(NULL, *len, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
        if (p == MAP_FAILED) return wrt_fail(WRT_ERR_IO, "%s: cannot map: %s", path, strerror(errno));
        *map = p;
    }
    return WRT_OK;
}

/* Maps a whole file read-only. O_NONBLOCK: a FIFO or device is refused by the fstat
 * that follows instead of blocking the open. */
static wrt_status map_file(const char *path, void **map, size_t *len) {
    *map = NULL; *len = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    if (fd < 0) return wrt_fail(WRT_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    wrt_status st = map_fd(fd, path, map, len);
    close(fd);
    return st;
}

static wrt_status prefix_error(const char *path, wrt_status st) {
    char msg[1024];
    snprintf(msg, sizeof msg, "%s", wrt_last_error());
    return wrt_fail(st, "%s: %s", path, msg);
}

/* Validates a mapping of `len` bytes of `path` (NULL when the file is empty) and hands it
 * to `out`, which then owns it; on failure unmaps it and names the path in the error. */
static wrt_status adopt_map(void *map, size_t len, const char *path, wrt_gto *out) {
    static const uint64_t empty = 0;
    wrt_status st = validate(map ? map : (const void *)&empty, len, out);
    if (st != WRT_OK) {
        if (map) munmap(map, len);
        memset(out, 0, sizeof *out);
        return prefix_error(path, st);
    }
    out->map = map;
    out->size = len;
    out->owns_map = 1;
    return WRT_OK;
}

wrt_status wrt_gto_open(const char *path, wrt_gto *out) {
    memset(out, 0, sizeof *out);
    void *map; size_t len;
    wrt_status st = map_file(path, &map, &len);
    if (st != WRT_OK) return st;
    return adopt_map(map, len, path, out);
}

void wrt_gto_close(wrt_gto *g) {
    if (!g) return;
    if (g->owns_map && g->map) munmap(g->map, g->size);
    memset(g, 0, sizeof *g);
}

/* ------------------------------------------------------------------------------------
 * Writer
 * ---------------------------------------------------------------------------------- */

/* Temporaries being written, for the signal handler: state 0 free, 1 claimed, 2 armed.
 * Lock-free atomics, so the handler may read them. */
_Static_assert(ATOMIC_INT_LOCK_FREE == 2, "the signal handler needs lock-free atomics");
#define TMP_SLOTS 8
static struct { atomic_int state; char path[PATH_MAX]; } tmp_slots[TMP_SLOTS];
static wrt_gto_write_hook write_hook;

void wrt_gto_set_write_hook(wrt_gto_write_hook hook) { write_hook = hook; }

static int tmp_arm(const char *path) {
    if (strlen(path) >= PATH_MAX) return -1;
    for (int i = 0; i < TMP_SLOTS; i++) {
        int expect = 0;
        if (atomic_compare_exchange_strong(&tmp_slots[i].state, &expect, 1)) {
            strcpy(tmp_slots[i].path, path);
            atomic_store(&tmp_slots[i].state, 2);
            return i;
        }
    }
    return -1; /* more concurrent writes than slots: this one is not cleaned on a signal */
}

static void tmp_disarm(int slot) {
    if (slot >= 0) atomic_store(&tmp_slots[slot].state, 0);
}

void wrt_gto_remove_temporaries(void) {
    int saved = errno;
    for (int i = 0; i < TMP_SLOTS; i++)
        if (atomic_load(&tmp_slots[i].state) == 2) unlink(tmp_slots[i].path);
    errno = saved;
}

static void cleanup_handler(int sig) {
    int saved = errno;
    wrt_gto_remove_temporaries();
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = SIG_DFL;
    sigemptyset(&sa.sa_mask);
    sigaction(sig, &sa, NULL);
    raise(sig); /* blocked until the handler returns, then kills with the default action */
    errno = saved;
}

void wrt_gto_install_signal_cleanup(void) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (size_t i = 0; i < sizeof sigs / sizeof *sigs; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) != 0) continue;
        if (old.sa_handler == SIG_IGN || old.sa_handler == cleanup_handler) continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = cleanup_handler;
        sigemptyset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
}

static int write_all(int fd, const void *data, uint64_t n) {
    const uint8_t *p = data;
    while (n) {
        size_t part = n > (1u << 30) ? (1u << 30) : (size_t)n;
        ssize_t w = write(fd, p, part);
        if (w < 0) {
            if (errno == EINTR) continue;
            return -1;
        }
        if (w == 0) { errno = EIO; return -1; }
        p += w;
        n -= (uint64_t)w;
    }
    return 0;
}

static void copy_name(char dst[64], const char *src) {
    memset(dst, 0, 64);
    if (src) memcpy(dst, src, strnlen(src, 63));
}

typedef struct wsec { uint32_t id; uint64_t count; const void *data; } wsec;

/* Removes PATH.tmp.PID.* left by a process that no longer exists (killed while
 * writing). Temporaries of live processes, and names of another form, are left. */
static void remove_stale_temporaries(const char *path) {
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    size_t dl = slash ? (size_t)(slash - path) : 0;
    char *dir = wrt_xmalloc(dl + 2);
    if (slash) { memcpy(dir, path, dl); dir[dl] = 0; if (dl == 0) strcpy(dir, "/"); }
    else strcpy(dir, ".");
    DIR *d = opendir(dir);
    size_t bl = strlen(base);
    if (d) {
        struct dirent *e;
        while ((e = readdir(d))) {
            const char *n = e->d_name;
            if (strncmp(n, base, bl) != 0 || strncmp(n + bl, ".tmp.", 5) != 0) continue;
            char *end;
            errno = 0;
            long pid = strtol(n + bl + 5, &end, 10);
            if (errno || end == n + bl + 5 || *end != '.' || pid <= 0 || pid == (long)getpid()) continue;
            if (kill((pid_t)pid, 0) == 0 || errno != ESRCH) continue; /* alive, or not ours to judge */
            int fd = dirfd(d);
            if (unlinkat(fd, n, 0) == 0)
                wrt_log(WRT_LOG_INFO, "removed %s/%s, left by process %ld, which is gone", dir, n, pid);
        }
        closedir(d);
    }
    free(dir);
}

static int force_named;
void wrt_gto_force_named_temporaries(int on) { force_named = on; }

/* Creates the temporary for `path` in its folder: O_TMPFILE if the file system has it
 * (and not forced off), else a named one, armed for the signal handler. */
static wrt_status tmp_create(const char *path, wrt_gto_pending *p) {
    remove_stale_temporaries(path);
    p->path = wrt_xmalloc(strlen(path) + 1);
    strcpy(p->path, path);
    size_t pl = strlen(path);
    int e = 0;
#ifdef O_TMPFILE
    if (!force_named) {
        char *dir = wrt_xmalloc(pl + 2);
        strcpy(dir, path);
        char *slash = strrchr(dir, '/');
        if (!slash) strcpy(dir, ".");
        else if (slash == dir) dir[1] = 0;
        else *slash = 0;
        p->fd = open(dir, O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
        e = errno;
        free(dir);
        if (p->fd >= 0) return WRT_OK;
        if (e != EOPNOTSUPP && e != EISDIR && e != EINVAL) {
            wrt_gto_discard(p);
            return wrt_fail(WRT_ERR_IO, "cannot create a temporary file for %s: %s", path, strerror(e));
        }
    }
#endif
    p->tmp = wrt_xmalloc(pl + 40);
    snprintf(p->tmp, pl + 40, "%s.tmp.%ld.XXXXXX", path, (long)getpid());
    sigset_t all, old;
    sigfillset(&all);
    pthread_sigmask(SIG_BLOCK, &all, &old);
    p->fd = mkostemp(p->tmp, O_CLOEXEC);
    e = errno;
    if (p->fd >= 0) p->slot = tmp_arm(p->tmp);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (p->fd < 0) {
        free(p->tmp);
        p->tmp = NULL;
        wrt_gto_discard(p);
        return wrt_fail(WRT_ERR_IO, "cannot create a temporary file for %s: %s", path, strerror(e));
    }
    return WRT_OK;
}

wrt_status wrt_gto_check_output(const char *path, const char *const *inputs, int ninputs) {
    if (!path || !path[0]) return wrt_fail(WRT_ERR_INVALID_ARG, "no output path");
    struct stat so;
    int exists = stat(path, &so) == 0;
    if (exists && S_ISDIR(so.st_mode))
        return wrt_fail(WRT_ERR_IO, "%s: the output is a directory", path);
    for (int i = 0; i < ninputs && exists; i++) {
        struct stat si;
        if (inputs[i] && stat(inputs[i], &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino)
            return wrt_fail(WRT_ERR_INVALID_ARG, "%s: the output is the input %s (same file)", path,
                            inputs[i]);
    }
    /* Can a temporary be made beside it? (Made and dropped now, before any work.) */
    wrt_gto_pending p;
    memset(&p, 0, sizeof p);
    p.fd = -1;
    p.slot = -1;
    wrt_status st = tmp_create(path, &p);
    wrt_gto_discard(&p);
    return st;
}

wrt_status wrt_gto_write_pending(const char *path, const wrt_gto_contents *c, wrt_gto_pending *p) {
    if (!p) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_write_pending: no result");
    memset(p, 0, sizeof *p);
    p->fd = -1;
    p->slot = -1;
    if (!path || !c || !c->scene) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_write: no path or contents");
    const wrt_scene *sc = c->scene;
    uint32_t nf = c->nfuncs;
    if (sc->nquads < 0 || sc->nmaterials < 0 || sc->nlights < 0 || sc->nnames < 0)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: negative scene counts", path);
    if (nf && (!c->fkeys || !c->col_start))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %u functions but no keys or columns",
                        path, nf);
    static const uint64_t zero_col = 0;
    const uint64_t *col_start = c->col_start ? c->col_start : &zero_col;
    uint64_t nnz = col_start[nf];
    if (nnz && (!c->rows || !c->vals))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %" PRIu64 " entries but no rows or vals",
                        path, nnz);
    if (c->op_kind > WRT_GTO_OP_GATHERED)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: unknown operator kind %u", path, c->op_kind);
    /* The first-bounce operator K: written only when it has columns. */
    uint32_t nk = c->nkcols;
    if (nk && (!c->kkeys || !c->kcol_start))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: K has %u columns but no kkeys or kcol_start",
                        path, nk);
    if (nk == UINT32_MAX)
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: kkeys: %u columns, too many", path, nk);
    uint64_t knnz = nk ? c->kcol_start[nk] : 0;
    if (knnz && (!c->krows || !c->kvals))
        return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: K has %" PRIu64 " entries but no krows or kvals",
                        path, knnz);
    uint32_t nq = (uint32_t)sc->nquads;

    /* The records. */
    wrt_gto_quad *quads = wrt_xcalloc(nq ? nq : 1, sizeof *quads);
    for (uint32_t i = 0; i < nf; i++) {
        uint32_t q = wrt_fkey_quad(c->fkeys[i]);
        if (q >= nq) {
            free(quads);
            return wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: fkeys[%u] names quad %u, but there are %u quads",
                            path, i, q, nq);
        }
        wrt_gto_quad *r = &quads[q];
        if (r->func_count == 0) r->func_first = i;
        r->func_count++;
        uint32_t sl = wrt_fkey_snode(c->fkeys[i]).level, al = wrt_fkey_anode(c->fkeys[i]).level;
        if (sl > r->slevel) r->slevel = sl;
        if (al > r->alevel) r->alevel = al;
    }
    uint32_t next = 0;
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_quad *s = &sc->quads[q];
        wrt_gto_quad *r = &quads[q];
        if (r->func_count == 0) r->func_first = next;
        next = r->func_first + r->func_count;
        for (int k = 0; k < 4; k++) { r->p[k][0] = s->p[k].x; r->p[k][1] = s->p[k].y; r->p[k][2] = s->p[k].z; }
        r->n[0] = (float)s->n.x; r->n[1] = (float)s->n.y; r->n[2] = (float)s->n.z;
        r->t[0] = (float)s->t.x; r->t[1] = (float)s->t.y; r->t[2] = (float)s->t.z;
        r->b[0] = (float)s->b.x; r->b[1] = (float)s->b.y; r->b[2] = (float)s->b.z;
        r->area = (float)s->area;
        r->material = (uint32_t)s->material; /* negative -> huge -> refused by the check */
        r->name = (s->name < 0) ? WRT_GTO_NO_NAME : (uint32_t)s->name;
        r->flags = s->parallelogram ? 1u : 0u;
    }
    uint32_t nm = (uint32_t)sc->nmaterials;
    wrt_gto_material *mats = wrt_xcalloc(nm ? nm : 1, sizeof *mats);
    for (uint32_t i = 0; i < nm; i++) {
        const wrt_material *s = &sc->materials[i];
        copy_name(mats[i].name, s->name);
        memcpy(mats[i].base_color, s->base_color, sizeof mats[i].base_color);
        mats[i].metallic = s->metallic;
        mats[i].roughness = s->roughness;
        memcpy(mats[i].emissive, s->emissive, sizeof mats[i].emissive);
        mats[i].lambertian = s->lambertian ? 1u : 0u;
        mats[i].alevel = c->material_alevel ? c->material_alevel[i] : 0u;
    }
    uint32_t nl = (uint32_t)sc->nlights;
    wrt_gto_light *lights = wrt_xcalloc(nl ? nl : 1, sizeof *lights);
    for (uint32_t i = 0; i < nl; i++) {
        const wrt_light *s = &sc->lights[i];
        copy_name(lights[i].name, s->name);
        lights[i].type = (uint32_t)s->type;
        memcpy(lights[i].color, s->color, sizeof lights[i].color);
        lights[i].pos[0] = s->pos.x; lights[i].pos[1] = s->pos.y; lights[i].pos[2] = s->pos.z;
        lights[i].dir[0] = s->dir.x; lights[i].dir[1] = s->dir.y; lights[i].dir[2] = s->dir.z;
        lights[i].intensity = s->intensity;
        lights[i].range = s->range;
        lights[i].inner_cone = s->inner_cone;
        lights[i].outer_cone = s->outer_cone;
    }
    uint32_t nn = (uint32_t)sc->nnames;
    char (*names)[64] = wrt_xcalloc(nn ? nn : 1, 64);
    for (uint32_t i = 0; i < nn; i++) copy_name(names[i], sc->names[i]);
    wrt_gto_camera cam;
    memset(&cam, 0, sizeof cam);
    const wrt_camera *sca = &sc->camera;
    cam.pos[0] = sca->pos.x; cam.pos[1] = sca->pos.y; cam.pos[2] = sca->pos.z;
    cam.dir[0] = sca->dir.x; cam.dir[1] = sca->dir.y; cam.dir[2] = sca->dir.z;
    cam.up[0] = sca->up.x; cam.up[1] = sca->up.y; cam.up[2] = sca->up.z;
    cam.yfov = sca->yfov; cam.aspect = sca->aspect; cam.znear = sca->znear; cam.zfar = sca->zfar;
    wrt_gto_stats stats = c->stats;
    const char *prov = c->provenance ? c->provenance : "";

    wsec secs[SEC_KNOWN] = {
        {SEC_QUADS, nq, quads}, {SEC_MATERIALS, nm, mats}, {SEC_LIGHTS, nl, lights},
        {SEC_CAMERA, 1, &cam}, {SEC_NAMES, nn, names}, {SEC_FKEYS, nf, c->fkeys},
        {SEC_COL_START, (uint64_t)nf + 1, col_start}, {SEC_ROWS, nnz, c->rows},
        {SEC_VALS, nnz, c->vals}, {SEC_STATS, 1, &stats}, {SEC_PROVENANCE, strlen(prov), prov},
        {SEC_KKEYS, nk, c->kkeys}, {SEC_KCOL_START, (uint64_t)nk + 1, c->kcol_start},
        {SEC_KROWS, knnz, c->krows}, {SEC_KVALS, knnz, c->kvals},
    };
    /* Without K the file is version 1.0 with its 11 sections, byte for byte as before
     * K existed: the minor is the lowest that has everything the file holds. */
    const int nsec = nk ? SEC_KNOWN : SEC_REQUIRED;

    static const uint64_t nothing = 0;
    for (int i = 0; i < nsec; i++)
        if (!secs[i].data) secs[i].data = &nothing; /* only for empty sections */

    /* Header, table, and the checks the reader will make, on our own input. */
    alignas(8) uint8_t head[sizeof(gto_header) + sizeof(gto_section) * SEC_KNOWN];
    const uint32_t hsize = (uint32_t)(sizeof(gto_header) + sizeof(gto_section) * (size_t)nsec);
    memset(head, 0, sizeof head);
    gto_header *h = (gto_header *)head;
    gto_section *tab = (gto_section *)(head + sizeof(gto_header));
    memcpy(h->magic, GTO_MAGIC, GTO_MAGIC_LEN);
    h->byte_order = GTO_BOM;
    h->version_major = WRT_GTO_VERSION;
    h->version_minor = nk ? GTO_MINOR_K : 0;
    h->nsections = (uint32_t)nsec;
    h->header_size = hsize;
    h->op_kind = c->op_kind;

    wrt_gto view;
    memset(&view, 0, sizeof view);
    view.nquads = nq; view.nmaterials = nm; view.nlights = nl; view.nnames = nn; view.nfuncs = nf;
    view.nnz = nnz; view.quads = quads; view.materials = mats; view.fkeys = c->fkeys;
    view.col_start = col_start;
    view.nkcols = nk; view.knnz = knnz; view.kkeys = c->kkeys; view.kcol_start = c->kcol_start;
    vctx v;
    memset(&v, 0, sizeof v);
    v.g = &view;
    uint64_t off = hsize;
    wrt_status st = WRT_OK;
    for (int i = 0; i < nsec && st == WRT_OK; i++) {
        uint32_t es = sec_info[secs[i].id].elem_size;
        tab[i].id = secs[i].id;
        tab[i].elem_size = es;
        tab[i].offset = align_up(off);
        tab[i].count = secs[i].count;
        tab[i].size = secs[i].count * es;
        tab[i].checksum = scan_section(secs[i].data, secs[i].count, es, sec_checker(secs[i].id), &v);
        off = tab[i].offset + tab[i].size;
        if (v.bad)
            st = wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: %s: %s", path,
                          sec_name(secs[i].id), v.err);
    }
    if (st == WRT_OK) {
        check_quad_ranges(&v);
        if (v.bad) st = wrt_fail(WRT_ERR_INVALID_ARG, "refusing to write %s: quads: %s", path, v.err);
    }
    h->file_size = off;
    h->header_checksum = wrt_gto_checksum(head, hsize);

    /* The temporary: unnamed where the file system allows (O_TMPFILE: nothing is left
     * behind whatever kills us), else named PATH.tmp.PID.XXXXXX and armed for the
     * signal handler; a later write to the same path removes a named one whose process
     * is gone. */
    if (st == WRT_OK) st = tmp_create(path, p);
    if (st == WRT_OK) {
        char proc[64];
        snprintf(proc, sizeof proc, "/proc/self/fd/%d", p->fd);
        if (write_hook) write_hook(p->tmp ? p->tmp : proc);
        mode_t um = umask(0);
        umask(um);
        static const uint8_t zeros[GTO_ALIGN];
        int bad = fchmod(p->fd, 0666 & ~um) != 0 || write_all(p->fd, head, hsize) != 0;
        uint64_t at = hsize;
        for (int i = 0; i < nsec && !bad; i++) {
            bad = write_all(p->fd, zeros, tab[i].offset - at) != 0 ||
                  write_all(p->fd, secs[i].data, tab[i].size) != 0;
            at = tab[i].offset + tab[i].size;
        }
        if (!bad) bad = fsync(p->fd) != 0;
        if (bad) {
            int e = errno;
            wrt_gto_discard(p);
            st = wrt_fail(WRT_ERR_IO, "cannot write %s: %s", path, strerror(e));
        }
    }
    free(quads); free(mats); free(lights); free(names);
    return st;
}

wrt_status wrt_gto_write(const char *path, const wrt_gto_contents *c) {
    wrt_gto_pending p;
    wrt_status st = wrt_gto_write_pending(path, c, &p);
    if (st == WRT_OK) st = wrt_gto_commit(&p);
    return st;
}

wrt_status wrt_gto_open_pending(const wrt_gto_pending *p, wrt_gto *out) {
    memset(out, 0, sizeof *out);
    if (!p || p->fd < 0) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_open_pending: nothing pending");
    void *map; size_t len;
    wrt_status st = map_fd(p->fd, p->path, &map, &len);
    if (st != WRT_OK) return st;
    return adopt_map(map, len, p->path, out);
}

wrt_status wrt_gto_commit(wrt_gto_pending *p) {
    if (!p || p->fd < 0) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_gto_commit: nothing pending");
    wrt_status st = WRT_OK;
    int e = 0;
    if (!p->tmp) {
        /* Give the unnamed file a name (armed for the signal handler while it has one),
         * then rename it over the target: the target is the old file or the new one. */
        size_t pl = strlen(p->path);
        char *name = wrt_xmalloc(pl + 48);
        char proc[64];
        snprintf(proc, sizeof proc, "/proc/self/fd/%d", p->fd);
        static atomic_uint counter;
        int linked = 0;
        for (int tries = 0; tries < 100 && !linked; tries++) {
            snprintf(name, pl + 48, "%s.tmp.%ld.%u", p->path, (long)getpid(),
                     atomic_fetch_add(&counter, 1u));
            sigset_t all, old;
            sigfillset(&all);
            pthread_sigmask(SIG_BLOCK, &all, &old);
            if (linkat(AT_FDCWD, proc, AT_FDCWD, name, AT_SYMLINK_FOLLOW) == 0) {
                linked = 1;
                p->slot = tmp_arm(name);
            } else {
                e = errno;
            }
            pthread_sigmask(SIG_SETMASK, &old, NULL);
            if (!linked && e != EEXIST) break;
        }
        if (!linked) {
            free(name);
            wrt_gto_discard(p);
            return wrt_fail(WRT_ERR_IO, "cannot write %s: cannot name the temporary: %s", p->path ? p->path : "",
                            strerror(e));
        }
        p->tmp = name;
    }
    if (close(p->fd) != 0) { st = WRT_ERR_IO; e = errno; }
    p->fd = -1;
    if (st == WRT_OK && rename(p->tmp, p->path) != 0) { st = WRT_ERR_IO; e = errno; }
    if (st != WRT_OK) {
        unlink(p->tmp);
        tmp_disarm(p->slot);
        p->slot = -1;
        wrt_status r = wrt_fail(WRT_ERR_IO, "cannot write %s: %s", p->path, strerror(e));
        wrt_gto_discard(p);
        return r;
    }
    tmp_disarm(p->slot);
    p->slot = -1;
    free(p->tmp);
    p->tmp = NULL; /* the name is the target's now */
    /* Make the rename durable. */
    char *dir = wrt_xmalloc(strlen(p->path) + 2);
    strcpy(dir, p->path);
    char *slash = strrchr(dir, '/');
    if (!slash) strcpy(dir, ".");
    else if (slash == dir) dir[1] = 0;
    else *slash = 0;
    int dfd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0 || fsync(dfd) != 0)
        wrt_log(WRT_LOG_WARN, "wrote %s but could not sync its directory: %s", p->path, strerror(errno));
    if (dfd >= 0) close(dfd);
    free(dir);
    wrt_gto_discard(p);
    return WRT_OK;
}

void wrt_gto_discard(wrt_gto_pending *p) {
    if (!p) return;
    if (p->fd >= 0) close(p->fd);
    if (p->tmp) unlink(p->tmp);
    tmp_disarm(p->slot);
    free(p->tmp);
    free(p->path);
    memset(p, 0, sizeof *p);
    p->fd = -1;
    p->slot = -1;
}

/* ------------------------------------------------------------------------------------
 * Inspection
 * ---------------------------------------------------------------------------------- */

/* The first value of "key" in the provenance JSON, a string (unescaped quotes end it)
 * or a number, into out (empty if absent); printable ASCII only. */
static void prov_value(const char *p, size_t n, const char *key, char *out, size_t outn) {
    out[0] = 0;
    char pat[64];
    int pl = snprintf(pat, sizeof pat, "\"%s\":", key);
    if (pl <= 0 || (size_t)pl >= sizeof pat || !p) return;
    for (size_t i = 0; i + (size_t)pl < n; i++) {
        if (memcmp(p + i, pat, (size_t)pl)) continue;
        size_t j = i + (size_t)pl, o = 0;
        int str = j < n && p[j] == '"';
        if (str) j++;
        for (; j < n && o + 1 < outn; j++) {
            char c = p[j];
            if (str ? c == '"' : (c == ',' || c == '}' || c == ' ')) break;
            if (str && c == '\\' && j + 1 < n) c = p[++j];
            out[o++] = (c >= 0x20 && c < 0x7f) ? c : '?';
        }
        out[o] = 0;
        return;
    }
}

/* Minimal JSON syntax check (so --info --json can embed the provenance as is). */
static const char *js_ws(const char *p, const char *e) {
    while (p < e && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) p++;
    return p;
}
static const char *js_value(const char *p, const char *e, int depth);
static const char *js_string(const char *p, const char *e) {
    if (p >= e || *p != '"') return NULL;
    for (p++; p < e; p++) {
        unsigned char ch = (unsigned char)*p;
        if (ch == '"') return p + 1;
        if (ch < 0x20) return NULL;
        if (ch == '\\') {
            if (++p >= e) return NULL;
            if (*p == 'u') {
                for (int i = 0; i < 4; i++)
                    if (++p >= e || !strchr("0123456789abcdefABCDEF", *p) || !*p) return NULL;
            } else if (!strchr("\"\\/bfnrt", *p) || !*p) return NULL;
        }
    }
    return NULL;
}
static const char *js_value(const char *p, const char *e, int depth) {
    if (depth > 64) return NULL;
    p = js_ws(p, e);
    if (p >= e) return NULL;
    if (*p == '"') return js_string(p, e);
    if (*p == '{' || *p == '[') {
        char close = *p == '{' ? '}' : ']';
        int obj = *p == '{';
        p = js_ws(p + 1, e);
        if (p < e && *p == close) return p + 1;
        for (;;) {
            if (obj) {
                p = js_string(js_ws(p, e), e);
                if (!p) return NULL;
                p = js_ws(p, e);
                if (p >= e || *p != ':') return NULL;
                p++;
            }
            p = js_value(p, e, depth + 1);
            if (!p) return NULL;
            p = js_ws(p, e);
            if (p < e && *p == ',') { p++; continue; }
            if (p < e && *p == close) return p + 1;
            return NULL;
        }
    }
    static const char *const lits[] = {"true", "false", "null"};
    for (int i = 0; i < 3; i++) {
        size_t n = strlen(lits[i]);
        if ((size_t)(e - p) >= n && memcmp(p, lits[i], n) == 0) return p + n;
    }
    /* number: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)? */
    const char *q = p;
    if (q < e && *q == '-') q++;
    if (q >= e || *q < '0' || *q > '9') return NULL;
    if (*q == '0') q++;
    else while (q < e && *q >= '0' && *q <= '9') q++;
    if (q < e && *q == '.') {
        if (++q >= e || *q < '0' || *q > '9') return NULL;
        while (q < e && *q >= '0' && *q <= '9') q++;
    }
    if (q < e && (*q == 'e' || *q == 'E')) {
        q++;
        if (q < e && (*q == '+' || *q == '-')) q++;
        if (q >= e || *q < '0' || *q > '9') return NULL;
        while (q < e && *q >= '0' && *q <= '9') q++;
    }
    return q;
}

static int is_json_object(const char *s, size_t n) {
    const char *e = s + n, *p = js_ws(s, e);
    if (p >= e || *p != '{') return 0;
    p = js_value(p, e, 0);
    return p && js_ws(p, e) == e;
}

static void put_jstr(FILE *f, const char *s, size_t n) {
    fputc('"', f);
    for (size_t i = 0; i < n; i++) {
        unsigned char ch = (unsigned char)s[i];
        if (ch == '"' || ch == '\\') fprintf(f, "\\%c", ch);
        else if (ch == '\n') fputs("\\n", f);
        else if (ch == '\t') fputs("\\t", f);
        else if (ch < 0x20 || ch == 0x7f) fprintf(f, "\\u%04x", ch);
        else fputc(ch, f);
    }
    fputc('"', f);
}

/* "512 B", "3.4 kB", "12.5 MB", "1.20 GB". */
static const char *human_bytes(uint64_t n, char buf[32]) {
    if (n < 1000) snprintf(buf, 32, "%" PRIu64 " B", n);
    else if (n < 1000000) snprintf(buf, 32, "%.1f kB", n / 1e3);
    else if (n < 1000000000) snprintf(buf, 32, "%.1f MB", n / 1e6);
    else snprintf(buf, 32, "%.2f GB", n / 1e9);
    return buf;
}

static const char *op_kind_name(uint32_t k) {
    return k == WRT_GTO_OP_INDIRECT ? "indirect" : k == WRT_GTO_OP_GATHERED ? "gathered" : "unknown";
}

wrt_status wrt_gto_print_info(const char *path, int json, FILE *f) {
    void *map; size_t len;
    wrt_status st = map_file(path, &map, &len);
    int map_ok = st == WRT_OK;
    static const uint64_t empty = 0;
    const uint8_t *b = map ? map : (const uint8_t *)&empty;
    gto_layout L;
    memset(&L, 0, sizeof L);
    wrt_gto g;
    memset(&g, 0, sizeof g);
    int have_header = 0, have_layout = 0, ok = 0;
    double dt = 0;
    if (st == WRT_OK) {
        have_header = len >= sizeof(gto_header) && memcmp(b, GTO_MAGIC, GTO_MAGIC_LEN) == 0;
        if (have_header) memcpy(&L.h, b, sizeof L.h);
        double t0 = wrt_now();
        st = parse_layout(b, len, &L);
        have_layout = st == WRT_OK;
        if (st == WRT_OK) st = check_counts(b, &L, &g);
        if (st == WRT_OK) st = check_payload(b, &L, &g);
        dt = wrt_now() - t0;
        ok = st == WRT_OK;
    }
    char err[1024] = "";
    if (!ok) snprintf(err, sizeof err, "%s", wrt_last_error());
    double mbs = dt > 0 ? (double)len / dt / 1e6 : 0;

    /* Figures of the operator. */
    uint32_t max_sl = 0, max_al = 0, max_fpq = 0, max_col = 0;
    uint64_t op_bytes = 0, nangular = 0;
    if (ok) {
        for (uint32_t q = 0; q < g.nquads; q++) {
            if (g.quads[q].slevel > max_sl) max_sl = g.quads[q].slevel;
            if (g.quads[q].alevel > max_al) max_al = g.quads[q].alevel;
            if (g.quads[q].func_count > max_fpq) max_fpq = g.quads[q].func_count;
        }
        for (uint32_t s = 0; s < g.nfuncs; s++) {
            uint64_t n = g.col_start[s + 1] - g.col_start[s];
            if (n > max_col) max_col = (uint32_t)n;
            if (!wrt_fkey_angular_root(g.fkeys[s])) nangular++;
        }
        op_bytes = L.sec[SEC_FKEYS]->size + L.sec[SEC_COL_START]->size + L.sec[SEC_ROWS]->size +
                   L.sec[SEC_VALS]->size;
    }
    double density = g.nfuncs ? (double)g.nnz / ((double)g.nfuncs * g.nfuncs) : 0;
    const wrt_gto_stats *S = g.stats;
    /* Figures of the first-bounce operator K, if any. */
    uint32_t k_quads = 0, k_max_sl = 0, k_max_al = 0, k_max_col = 0;
    uint64_t k_bytes = 0;
    if (ok && g.nkcols) {
        for (uint32_t j = 0; j < g.nkcols; j++) {
            if (j == 0 || wrt_fkey_quad(g.kkeys[j]) != wrt_fkey_quad(g.kkeys[j - 1])) k_quads++;
            uint32_t sl = wrt_fkey_snode(g.kkeys[j]).level, al = wrt_fkey_anode(g.kkeys[j]).level;
            if (sl > k_max_sl) k_max_sl = sl;
            if (al > k_max_al) k_max_al = al;
            uint64_t n = g.kcol_start[j + 1] - g.kcol_start[j];
            if (n > k_max_col) k_max_col = (uint32_t)n;
        }
        k_bytes = L.sec[SEC_KKEYS]->size + L.sec[SEC_KCOL_START]->size + L.sec[SEC_KROWS]->size +
                  L.sec[SEC_KVALS]->size;
    }

    if (json) {
        fputs("{\"file\": ", f);
        put_jstr(f, path, strlen(path));
        fprintf(f, ", \"bytes\": %zu, \"ok\": %s, \"status\": \"%s\", \"error\": ", len,
                ok ? "true" : "false", wrt_status_str(st));
        put_jstr(f, err, strlen(err));
        if (have_header)
            fprintf(f, ", \"version\": \"%u.%u\", \"op_kind\": \"%s\", \"recorded_bytes\": %" PRIu64,
                    L.h.version_major, L.h.version_minor, op_kind_name(L.h.op_kind), L.h.file_size);
        if (have_layout) {
            fputs(", \"sections\": [", f);
            for (uint32_t i = 0; i < L.h.nsections; i++) {
                const gto_section *s = &L.table[i];
                fprintf(f, "%s{\"id\": %u, \"name\": \"%s\", \"offset\": %" PRIu64 ", \"bytes\": %" PRIu64
                        ", \"count\": %" PRIu64 ", \"elem_size\": %u, \"checksum\": \"0x%016" PRIx64 "\"}",
                        i ? ", " : "", s->id, sec_name(s->id), s->offset, s->size, s->count,
                        s->elem_size, s->checksum);
            }
            fputs("]", f);
        }
        if (ok) {
            fprintf(f, ", \"counts\": {\"quads\": %u, \"materials\": %u, \"lights\": %u, \"names\": %u, "
                    "\"functions\": %u, \"entries\": %" PRIu64 ", \"k_columns\": %u, \"k_entries\": %" PRIu64 "}",
                    g.nquads, g.nmaterials, g.nlights, g.nnames, g.nfuncs, g.nnz, g.nkcols, g.knnz);
            fprintf(f, ", \"operator\": {\"bytes\": %" PRIu64 ", \"density\": %.6g, "
                    "\"mean_entries_per_column\": %.3f, \"max_entries_per_column\": %u, "
                    "\"max_functions_per_quad\": %u, \"angular_functions\": %" PRIu64 ", "
                    "\"max_spatial_level\": %u, \"max_angular_level\": %u}",
                    op_bytes, density, g.nfuncs ? (double)g.nnz / g.nfuncs : 0.0, max_col, max_fpq,
                    nangular, max_sl, max_al);
            if (g.nkcols)
                fprintf(f, ", \"first_bounce\": {\"columns\": %u, \"entries\": %" PRIu64 ", \"bytes\": %" PRIu64
                        ", \"glossy_quads\": %u, \"mean_entries_per_column\": %.3f, \"max_entries_per_column\": %u, "
                        "\"max_spatial_level\": %u, \"max_angular_node_level\": %u}",
                        g.nkcols, g.knnz, k_bytes, k_quads, (double)g.knnz / g.nkcols, k_max_col, k_max_sl,
                        k_max_al);
            else
                fputs(", \"first_bounce\": null", f);
            fprintf(f, ", \"stats\": {\"t_dto\": %.6g, \"t_gto\": %.6g, \"t_write\": %.6g, \"t_total\": %.6g, "
                    "\"links_dto\": %" PRIu64 ", \"links_gto\": %" PRIu64 ", \"links_gathered\": %" PRIu64 ", "
                    "\"entries_dto\": %" PRIu64 ", \"entries_op\": %" PRIu64 ", \"rays_traced\": %" PRIu64 ", "
                    "\"rays_skipped\": %" PRIu64 ", \"bounces\": %" PRIu64 ", \"energy_left\": %.6g}",
                    S->t_dto, S->t_gto, S->t_write, S->t_total, S->links_dto, S->links_gto,
                    S->links_gathered, S->entries_dto, S->entries_op, S->rays_traced, S->rays_skipped,
                    S->bounces, S->energy_left);
            fputs(", \"provenance\": ", f);
            if (g.provenance_len == 0) fputs("null", f);
            else if (is_json_object(g.provenance, g.provenance_len)) fwrite(g.provenance, 1, g.provenance_len, f);
            else put_jstr(f, g.provenance, g.provenance_len);
            fprintf(f, ", \"check_seconds\": %.6f, \"check_mb_per_s\": %.1f", dt, mbs);
        }
        fputs("}\n", f);
    } else {
        fprintf(f, "file:       %s (%zu bytes)\n", path, len);
        if (have_header)
            fprintf(f, "format:     .gto version %u.%u (this reader: %d.%d), little-endian, operator %s\n",
                    L.h.version_major, L.h.version_minor, WRT_GTO_VERSION, WRT_GTO_VERSION_MINOR,
                    L.h.op_kind == WRT_GTO_OP_INDIRECT ? "indirect (G - I)"
                    : L.h.op_kind == WRT_GTO_OP_GATHERED ? "gathered (T_fine G)" : "unknown");
        if (have_layout) {
            fprintf(f, "sections:   %-11s %10s %12s %12s  %s\n", "name", "offset", "bytes", "count", "checksum");
            for (uint32_t i = 0; i < L.h.nsections; i++) {
                const gto_section *s = &L.table[i];
                fprintf(f, "            %-11s %10" PRIu64 " %12" PRIu64 " %12" PRIu64 "  %016" PRIx64 "\n",
                        sec_name(s->id), s->offset, s->size, s->count, s->checksum);
            }
        }
        if (ok) {
            fprintf(f, "scene:      %u quads, %u materials, %u lights, %u names\n", g.nquads,
                    g.nmaterials, g.nlights, g.nnames);
            char hb[32];
            fprintf(f, "operator:   %u functions (%" PRIu64 " with angular detail), %" PRIu64
                    " entries, %s, density %.3g\n", g.nfuncs, nangular, g.nnz, human_bytes(op_bytes, hb),
                    density);
            fprintf(f, "            entries per column: mean %.1f, max %u; functions per quad: max %u; "
                    "deepest level: spatial %u, angular %u\n",
                    g.nfuncs ? (double)g.nnz / g.nfuncs : 0.0, max_col, max_fpq, max_sl, max_al);
            if (g.nkcols)
                fprintf(f, "first bounce: K, %u columns on %u glossy quad%s, %" PRIu64 " entries, %s; entries "
                        "per column: mean %.1f, max %u; deepest level: spatial %u, angular node %u\n",
                        g.nkcols, k_quads, k_quads == 1 ? "" : "s", g.knnz, human_bytes(k_bytes, hb),
                        (double)g.knnz / g.nkcols, k_max_col, k_max_sl, k_max_al);
            else
                fprintf(f, "first bounce: none (no K sections)\n");
            /* only the times the bake recorded (none with --reproducible) */
            if (S->t_dto > 0 || S->t_gto > 0) {
                fprintf(f, "bake:       DTO %.2f s, GTO %.2f s", S->t_dto, S->t_gto);
                if (S->t_write > 0) fprintf(f, ", write %.2f s", S->t_write);
                if (S->t_total > 0) fprintf(f, ", total %.2f s", S->t_total);
                fputc('\n', f);
            } else {
                fprintf(f, "bake:       no timings recorded (--reproducible)\n");
            }
            fprintf(f, "            links: DTO %" PRIu64 ", GTO %" PRIu64 ", gathered %" PRIu64
                    "; entries: DTO %" PRIu64 ", operator %" PRIu64 "\n", S->links_dto, S->links_gto,
                    S->links_gathered, S->entries_dto, S->entries_op);
            fprintf(f, "            rays: %" PRIu64 " traced, %" PRIu64 " skipped; bounces %" PRIu64
                    "; energy left %.3g\n", S->rays_traced, S->rays_skipped, S->bounces, S->energy_left);
            {
                /* the provenance is JSON: its main facts here, all of it with --json */
                char tool[64], ver[32], src[512], hash[40], q[16];
                prov_value(g.provenance, g.provenance_len, "tool", tool, sizeof tool);
                prov_value(g.provenance, g.provenance_len, "version", ver, sizeof ver);
                prov_value(g.provenance, g.provenance_len, "source", src, sizeof src);
                prov_value(g.provenance, g.provenance_len, "source_hash", hash, sizeof hash);
                prov_value(g.provenance, g.provenance_len, "quality", q, sizeof q);
                if (tool[0] || src[0])
                    fprintf(f, "provenance: %s %s from %s (hash %s), quality %s; --info --json shows all of it\n",
                            tool[0] ? tool : "?", ver, src[0] ? src : "?", hash[0] ? hash : "?", q[0] ? q : "?");
                else /* not wrt-bake's: as written, up to 300 bytes */
                    fprintf(f, "provenance: %.*s%s\n", g.provenance_len > 300 ? 300 : (int)g.provenance_len,
                            g.provenance, g.provenance_len > 300 ? "..." : "");
            }
            fprintf(f, "integrity:  ok (checksums and indices verified: %s in %.2f ms, %.0f MB/s)\n",
                    human_bytes(len, hb), dt * 1e3, mbs);
        } else {
            fprintf(f, "integrity:  FAILED (%s): %s\n", wrt_status_str(st), err);
        }
    }
    if (map) munmap(map, len);
    if (!ok && map_ok) wrt_fail(st, "%s: %s", path, err);
    return st;
}
