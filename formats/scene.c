/* scene.c: builds a wrt_scene from a glTF 2.0 file. The glTF reading itself (JSON,
 * buffers, accessor validation, node flattening) is in gltf_shim.cpp; this file turns
 * its triangles back into the quads the method works on (Kontkanen et al. 2006, section
 * 3: the scene is a set of planar patches, each carrying its own wavelet basis), reports
 * every triangle that does not fit with mesh/primitive/triangle, combines the
 * metallic-roughness material factors with their texture means, converts the punctual
 * lights and picks or makes the camera. The scene summary (text or JSON) is printed by
 * scene_report.c. Depends on wrt_common and the glTF shim.
 *
 * Pairing: within one primitive, vertices are matched by position (tolerance 1e-6 of
 * the scene's diagonal), so shared or separate vertices, indexed or not, give the same
 * adjacency. Two triangles sharing an edge form a quad candidate when they are
 * coplanar, wound the same way and their union is strictly convex. Triangles with a
 * single candidate are paired first (any complete pairing must pair them so); the rest
 * go in index order, each taking its best free candidate: a parallelogram first, then
 * one across the triangle's longest edge (a quad's diagonal), then the lowest index. */
#define _POSIX_C_SOURCE 200809L
#include "scene.h"
#include "../common/texture.h"
#include "gltf_shim.h"
#include "scene_internal.h"
#include "../common/limits.h"
#include "../common/text.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <stdarg.h>
#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define WRT_WELD_REL 1e-6        /* vertex match tolerance, relative to the scene diagonal */
#define WRT_HUGE_COORD WRT_MAX_COORD /* coordinates beyond this are treated as non-finite (common/limits.h) */
#define WRT_COLLINEAR_REL 1e-7   /* |cross| / size^2 under this is collinear */
#define WRT_PARALLELOGRAM_REL 1e-5
#define WRT_MAX_EDGE_FAN 8       /* edges shared by more triangles are not paired across */
#define WRT_TWIN_GAP 1e-4        /* a double-sided quad's back twin, set back by this x diagonal */

/* ------------------------------------------------------------------ quads */

wrt_status wrt_quad_finish(wrt_quad *q) {
    for (int i = 0; i < 4; i++)
        if (!v3_finite(q->p[i])) return wrt_fail(WRT_ERR_GEOMETRY, "quad corner %d is not finite", i);
    wrt_v3 d0 = v3_sub(q->p[2], q->p[0]), d1 = v3_sub(q->p[3], q->p[1]);
    double size = fmax(v3_len(d0), v3_len(d1));
    wrt_v3 c = v3_cross(v3_sub(q->p[1], q->p[0]), v3_sub(q->p[3], q->p[0]));
    double clen = v3_len(c);
    q->area = 0.5 * v3_len(v3_cross(d0, d1));
    if (!(size > 0) || !isfinite(size) || !(clen > WRT_COLLINEAR_REL * size * size) ||
        !(q->area > WRT_COLLINEAR_REL * size * size))
        return wrt_fail(WRT_ERR_GEOMETRY, "degenerate quad (area %.3g, size %.3g)", q->area, size);
    q->n = v3_scale(c, 1.0 / clen);
    q->t = v3_norm(v3_sub(q->p[1], q->p[0]));
    q->b = v3_cross(q->n, q->t);
    wrt_v3 off = v3_sub(q->p[2], v3_sub(v3_add(q->p[1], q->p[3]), q->p[0]));
    q->parallelogram = v3_len(off) <= WRT_PARALLELOGRAM_REL * size;
    if (q->parallelogram) q->area = clen;
    return WRT_OK;
}

/* ------------------------------------------------------------------ growing arrays */

typedef struct problem_list {
    wrt_problem *v;
    int n, cap;
} problem_list;

static void add_problem(problem_list *l, int kind, int mesh, int prim, int tri, const char *fmt, ...)
    __attribute__((format(printf, 6, 7)));
static void add_problem(problem_list *l, int kind, int mesh, int prim, int tri, const char *fmt, ...) {
    if (l->n == l->cap) {
        l->cap = l->cap ? l->cap * 2 : 16;
        l->v = wrt_xrealloc(l->v, (size_t)l->cap * sizeof *l->v);
    }
    wrt_problem *p = &l->v[l->n++];
    p->kind = kind;
    p->mesh = mesh;
    p->prim = prim;
    p->tri = tri;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(p->what, sizeof p->what, fmt, ap);
    va_end(ap);
}

typedef struct quad_list {
    wrt_quad *v;
    int n, cap;
} quad_list;

static wrt_quad *add_quad(quad_list *l) {
    if (l->n == l->cap) {
        l->cap = l->cap ? l->cap * 2 : 64;
        l->v = wrt_xrealloc(l->v, (size_t)l->cap * sizeof *l->v);
    }
    wrt_quad *q = &l->v[l->n++];
    memset(q, 0, sizeof *q);
    return q;
}

/* ------------------------------------------------------------------ vertex matching */

typedef struct cell_entry {
    int64_t k[3];
    uint32_t v;
} cell_entry;

static int cmp_cell(const void *pa, const void *pb) {
    const cell_entry *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->k[i] != b->k[i]) return a->k[i] < b->k[i] ? -1 : 1;
    return (a->v > b->v) - (a->v < b->v);
}

static int coord_ok(const double *p) {
    for (int i = 0; i < 3; i++)
        if (!isfinite(p[i]) || fabs(p[i]) > WRT_HUGE_COORD) return 0;
    return 1;
}

static wrt_v3 pos_at(const wrt_gltf_prim *p, uint32_t i) {
    return v3(p->pos[3 * (size_t)i], p->pos[3 * (size_t)i + 1], p->pos[3 * (size_t)i + 2]);
}

/* rep[v] = lowest-index representative vertex within eps of v (UINT32_MAX if not finite). */
static void match_vertices(const wrt_gltf_prim *p, wrt_v3 origin, double eps, uint32_t *rep) {
    size_t n = p->npos, m = 0;
    cell_entry *e = wrt_xmalloc((n ? n : 1) * sizeof *e);
    for (size_t v = 0; v < n; v++) {
        rep[v] = UINT32_MAX;
        const double *c = &p->pos[3 * v];
        if (!coord_ok(c)) continue;
        e[m].k[0] = (int64_t)floor((c[0] - origin.x) / eps);
        e[m].k[1] = (int64_t)floor((c[1] - origin.y) / eps);
        e[m].k[2] = (int64_t)floor((c[2] - origin.z) / eps);
        e[m].v = (uint32_t)v;
        m++;
    }
    qsort(e, m, sizeof *e, cmp_cell);
    /* entries are sorted by cell then vertex index; walk vertices in index order */
    size_t *where = wrt_xmalloc((n ? n : 1) * sizeof *where);
    for (size_t i = 0; i < m; i++) where[e[i].v] = i;
    for (size_t v = 0; v < n; v++) {
        const double *c = &p->pos[3 * v];
        if (!coord_ok(c)) continue;
        const cell_entry *me = &e[where[v]];
        uint32_t best = (uint32_t)v;
        for (int dx = -1; dx <= 1; dx++)
            for (int dy = -1; dy <= 1; dy++)
                for (int dz = -1; dz <= 1; dz++) {
                    cell_entry key = {{me->k[0] + dx, me->k[1] + dy, me->k[2] + dz}, 0};
                    size_t lo = 0, hi = m; /* first entry >= key */
                    while (lo < hi) {
                        size_t mid = lo + (hi - lo) / 2;
                        if (cmp_cell(&e[mid], &key) < 0) lo = mid + 1; else hi = mid;
                    }
                    for (size_t i = lo; i < m && e[i].k[0] == key.k[0] && e[i].k[1] == key.k[1] &&
                                        e[i].k[2] == key.k[2] && e[i].v < best; i++) {
                        uint32_t w = e[i].v;
                        if (rep[w] != w) continue;
                        const double *d = &p->pos[3 * (size_t)w];
                        if (fabs(d[0] - c[0]) <= eps && fabs(d[1] - c[1]) <= eps &&
                            fabs(d[2] - c[2]) <= eps) {
                            best = w;
                            break;
                        }
                    }
                }
        rep[v] = best;
    }
    free(where);
    free(e);
}

/* ------------------------------------------------------------------ pairing */

typedef struct edge_entry {
    uint32_t lo, hi;
    int tri;
} edge_entry;

static int cmp_edge(const void *pa, const void *pb) {
    const edge_entry *a = pa, *b = pb;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
    return (a->tri > b->tri) - (a->tri < b->tri);
}

typedef struct cand {
    int t, s;
    int score;   /* higher is preferred */
} cand;

static int cmp_cand(const void *pa, const void *pb) {
    const cand *a = pa, *b = pb;
    if (a->t != b->t) return a->t < b->t ? -1 : 1;
    if (a->score != b->score) return a->score > b->score ? -1 : 1;
    return (a->s > b->s) - (a->s < b->s);
}

/* Why a triangle could not pair with a neighbour (the first reason found is kept). */
typedef struct tri_info {
    int bad;          /* 1 if the triangle itself is unusable (problem already added) */
    int fail_kind;    /* WRT_PROBLEM_* from a rejected neighbour, 0 if none */
    int fail_with;
    double fail_value;
    int ncand;        /* valid candidates before matching */
    wrt_v3 n;         /* unit normal from the triangle's winding */
    double longest2;  /* squared longest edge */
} tri_info;

typedef struct pair_ctx {
    const wrt_gltf_prim *p;
    const uint32_t *rep;
    tri_info *info;
    double planar_tol;
} pair_ctx;

/* Builds the quad of triangles t and s across their shared edge (reps ru, rv):
 * p0 = t's own corner, then around in t's winding. Returns 0 if it is a valid
 * planar strictly convex quad, else a WRT_PROBLEM_* (or -1 for opposite winding). */
static int eval_pair(const pair_ctx *c, int t, int s, wrt_v3 q[4], double *value, int *para) {
    const uint32_t *it = &c->p->idx[3 * (size_t)t], *is = &c->p->idx[3 * (size_t)s];
    int k = -1, ks = -1;
    for (int i = 0; i < 3; i++) {
        uint32_t r = c->rep[it[i]];
        if (r != c->rep[is[0]] && r != c->rep[is[1]] && r != c->rep[is[2]]) k = i;
        uint32_t rs = c->rep[is[i]];
        if (rs != c->rep[it[0]] && rs != c->rep[it[1]] && rs != c->rep[it[2]]) ks = i;
    }
    if (k < 0 || ks < 0) return WRT_PROBLEM_DEGENERATE; /* same three corners */
    q[0] = pos_at(c->p, it[k]);
    q[1] = pos_at(c->p, it[(k + 1) % 3]);
    q[2] = pos_at(c->p, is[ks]);
    q[3] = pos_at(c->p, it[(k + 2) % 3]);
    wrt_v3 nt = c->info[t].n, ns = c->info[s].n;
    double size = fmax(v3_len(v3_sub(q[2], q[0])), v3_len(v3_sub(q[3], q[1])));
    double dev = fmax(fabs(v3_dot(v3_sub(q[2], q[0]), nt)), fabs(v3_dot(v3_sub(q[0], q[2]), ns)));
    *value = dev / size;
    if (!(dev <= c->planar_tol * size)) return WRT_PROBLEM_NONPLANAR;
    if (v3_dot(nt, ns) <= 0) return -1;
    wrt_v3 n = v3_norm(v3_add(nt, ns));
    double thr = WRT_COLLINEAR_REL * size * size;
    int collinear = 0;
    for (int i = 0; i < 4; i++) {
        wrt_v3 e1 = v3_sub(q[(i + 1) % 4], q[i]), e2 = v3_sub(q[(i + 2) % 4], q[(i + 1) % 4]);
        double turn = v3_dot(v3_cross(e1, e2), n);
        if (turn < -thr) { *value = i; return WRT_PROBLEM_NONCONVEX; }
        if (turn <= thr) collinear = 1;
    }
    if (collinear) return WRT_PROBLEM_DEGENERATE;
    wrt_v3 off = v3_sub(q[2], v3_sub(v3_add(q[1], q[3]), q[0]));
    *para = v3_len(off) <= WRT_PARALLELOGRAM_REL * size;
    return 0;
}

const char *wrt_scene_problem_name(int kind) {
    switch (kind) {
    case WRT_PROBLEM_UNPAIRED: return "unpaired";
    case WRT_PROBLEM_NONPLANAR: return "non-planar";
    case WRT_PROBLEM_DEGENERATE: return "degenerate";
    case WRT_PROBLEM_NONCONVEX: return "non-convex";
    case WRT_PROBLEM_NONFINITE: return "non-finite";
    case WRT_PROBLEM_SLIVER: return "sliver";
    default: return "problem";
    }
}

/* Why triangle t found no partner, from what its neighbours said. */
static int single_reason(const tri_info *in) {
    if (in->ncand > 0) return WRT_SINGLE_TAKEN;
    switch (in->fail_kind) {
    case WRT_PROBLEM_NONPLANAR: return WRT_SINGLE_NONPLANAR;
    case WRT_PROBLEM_NONCONVEX:
    case WRT_PROBLEM_DEGENERATE: return WRT_SINGLE_NONCONVEX;
    case WRT_PROBLEM_UNPAIRED: return in->fail_with >= 0 ? WRT_SINGLE_WINDING : WRT_SINGLE_FAN;
    default: return WRT_SINGLE_ALONE;
    }
}

wrt_status wrt_triangle_quads(wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_quad out[3]) {
    wrt_v3 v[3] = {a, b, c}, g = v3_scale(v3_add(v3_add(a, b), c), 1.0 / 3.0);
    for (int k = 0; k < 3; k++) {
        wrt_quad *q = &out[k];
        memset(q, 0, sizeof *q);
        q->p[0] = v[k];
        q->p[1] = v3_scale(v3_add(v[k], v[(k + 1) % 3]), 0.5);
        q->p[2] = g;
        q->p[3] = v3_scale(v3_add(v[(k + 2) % 3], v[k]), 0.5);
        q->kind = WRT_ELEM_TRIANGLE;
        q->part = k;
        q->tri[1] = -1;
        q->node = -1;
        wrt_status st = wrt_quad_finish(q);
        if (st != WRT_OK) return st;
    }
    return WRT_OK;
}

/* TEXCOORD_0 of triangle t's three quads (the triangle's corners, its edge midpoints and
 * its centroid, interpolated linearly as glTF interpolates across a triangle). */
static void triangle_parts_uv(const wrt_gltf_prim *p, int t, wrt_quad q[3]) {
    if (!p->uv) return;
    const uint32_t *ix = &p->idx[3 * (size_t)t];
    for (int k = 0; k < 3; k++) {
        const float *a = &p->uv[2 * ix[k]], *b = &p->uv[2 * ix[(k + 1) % 3]], *c = &p->uv[2 * ix[(k + 2) % 3]];
        for (int d = 0; d < 2; d++) {
            q[k].uv[0][d] = a[d];
            q[k].uv[1][d] = 0.5f * (a[d] + b[d]);
            q[k].uv[2][d] = (a[d] + b[d] + c[d]) / 3.0f;
            q[k].uv[3][d] = 0.5f * (c[d] + a[d]);
        }
        q[k].has_uv = 1;
    }
}

/* TEXCOORD_0 of a quad paired from triangles t and s: each corner is a vertex of t (or,
 * for the one t lacks, of s) at exactly that position; across a UV seam t's wins. */
static void pair_uv(const wrt_gltf_prim *p, int t, int s, wrt_quad *q) {
    if (!p->uv) return;
    for (int i = 0; i < 4; i++) {
        int found = 0;
        for (int j = 0; j < 6 && !found; j++) {
            uint32_t v = p->idx[3 * (size_t)(j < 3 ? t : s) + (size_t)(j % 3)];
            wrt_v3 x = pos_at(p, v);
            if (x.x == q->p[i].x && x.y == q->p[i].y && x.z == q->p[i].z) {
                q->uv[i][0] = p->uv[2 * v];
                q->uv[i][1] = p->uv[2 * v + 1];
                found = 1;
            }
        }
        if (!found) return; /* cannot happen: eval_pair takes corners from t and s */
    }
    q->has_uv = 1;
}

/* Appends triangle t of p as its three quads (wrt_triangle_quads). Returns 0, or -1
 * (nothing appended) if a part is degenerate, which the sliver test makes rare. */
static int add_triangle_parts(const wrt_gltf_prim *p, int t, int material, quad_list *ql) {
    const uint32_t *ix = &p->idx[3 * (size_t)t];
    wrt_quad parts[3];
    if (wrt_triangle_quads(pos_at(p, ix[0]), pos_at(p, ix[1]), pos_at(p, ix[2]), parts) != WRT_OK) return -1;
    triangle_parts_uv(p, t, parts);
    wrt_scene_triangle_parts_nrm(p, t, parts);
    for (int k = 0; k < 3; k++) {
        wrt_quad *q = add_quad(ql);
        *q = parts[k];
        q->material = material;
        q->mesh = p->mesh;
        q->prim = p->prim;
        q->tri[0] = t;
        q->name = p->mesh;
        q->node = p->node;
    }
    return 0;
}

/* Pairs one primitive's triangles into quads (appended to ql); every other usable
 * triangle becomes three quads of its own (add_triangle_parts), counted in s by
 * reason. Triangles that are degenerate, slivers (narrowest height under
 * WRT_SLIVER_REL x diag) or not finite are appended to pl and left out. */
/* Stage 1 of the pairing: each triangle checked (problems to pl, bad ones marked) and its
 * edges listed by their matched vertices; returns the number of edges. */
static size_t pair_classify(const wrt_gltf_prim *p, size_t ntri, const uint32_t *rep, double diag, tri_info *info,
                            edge_entry *edges, problem_list *pl) {
    size_t nedges = 0;
    for (size_t t = 0; t < ntri; t++) {
        const uint32_t *ix = &p->idx[3 * t];
        uint32_t r[3] = {rep[ix[0]], rep[ix[1]], rep[ix[2]]};
        int ti = (int)t;
        if (r[0] == UINT32_MAX || r[1] == UINT32_MAX || r[2] == UINT32_MAX) {
            int bad = r[0] == UINT32_MAX ? 0 : r[1] == UINT32_MAX ? 1 : 2;
            add_problem(pl, WRT_PROBLEM_NONFINITE, p->mesh, p->prim, ti,
                        "vertex %u has a NaN, infinite or huge coordinate "
                        "(meshes[%d].primitives[%d].attributes.POSITION element %u, node %d)",
                        ix[bad], p->mesh, p->prim, ix[bad], p->node);
            info[t].bad = 1;
            continue;
        }
        if (r[0] == r[1] || r[1] == r[2] || r[0] == r[2]) {
            add_problem(pl, WRT_PROBLEM_DEGENERATE, p->mesh, p->prim, ti,
                        "zero area: two corners coincide");
            info[t].bad = 1;
            continue;
        }
        wrt_v3 a = pos_at(p, ix[0]), b = pos_at(p, ix[1]), c = pos_at(p, ix[2]);
        wrt_v3 cr = v3_cross(v3_sub(b, a), v3_sub(c, a));
        double l2 = fmax(v3_dot(v3_sub(b, a), v3_sub(b, a)),
                         fmax(v3_dot(v3_sub(c, b), v3_sub(c, b)), v3_dot(v3_sub(a, c), v3_sub(a, c))));
        if (!(v3_len(cr) > WRT_COLLINEAR_REL * l2)) {
            add_problem(pl, WRT_PROBLEM_DEGENERATE, p->mesh, p->prim, ti,
                        "zero area: collinear corners");
            info[t].bad = 1;
            continue;
        }
        double height = v3_len(cr) / sqrt(l2); /* the narrowest: over the longest edge */
        if (!(height >= WRT_SLIVER_REL * diag)) {
            add_problem(pl, WRT_PROBLEM_SLIVER, p->mesh, p->prim, ti,
                        "sliver: narrowest height %.3g, under %g of the scene diagonal %.3g", height,
                        WRT_SLIVER_REL, diag);
            info[t].bad = 1;
            continue;
        }
        info[t].n = v3_norm(cr);
        info[t].longest2 = l2;
        for (int e = 0; e < 3; e++) {
            uint32_t u = r[e], v = r[(e + 1) % 3];
            edges[nedges].lo = u < v ? u : v;
            edges[nedges].hi = u < v ? v : u;
            edges[nedges].tri = ti;
            nedges++;
        }
    }
    return nedges;
}

/* Stage 2: the candidate pairs along each shared edge, both ways (failures noted in info). */
static cand *pair_candidates(pair_ctx *ctx_in, const edge_entry *edges, size_t nedges, tri_info *info, size_t *ncands_out) {
    pair_ctx ctx = *ctx_in;
    cand *cands = NULL;
    size_t ncands = 0, capc = 0;
    for (size_t i = 0; i < nedges;) {
        size_t j = i;
        while (j < nedges && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) j++;
        if (j - i <= WRT_MAX_EDGE_FAN) {
            for (size_t a = i; a < j; a++)
                for (size_t b = a + 1; b < j; b++) {
                    int t = edges[a].tri, s = edges[b].tri;
                    if (t == s) continue;
                    wrt_v3 q[4];
                    double value = 0;
                    int para = 0;
                    int why = eval_pair(&ctx, t, s, q, &value, &para);
                    if (why != 0) {
                        int kind = why < 0 ? WRT_PROBLEM_UNPAIRED : why;
                        if (!info[t].fail_kind) {
                            info[t].fail_kind = kind; info[t].fail_with = s; info[t].fail_value = value;
                        }
                        if (!info[s].fail_kind) {
                            info[s].fail_kind = kind; info[s].fail_with = t; info[s].fail_value = value;
                        }
                        continue;
                    }
                    /* the shared edge is the diagonal: is it each triangle's longest edge? */
                    double diag2 = v3_dot(v3_sub(q[3], q[1]), v3_sub(q[3], q[1]));
                    int score = 4 * para + (diag2 >= info[t].longest2 * (1 - 1e-9)) +
                                (diag2 >= info[s].longest2 * (1 - 1e-9));
                    if (ncands + 2 > capc) {
                        capc = capc ? capc * 2 : 64;
                        cands = wrt_xrealloc(cands, capc * sizeof *cands);
                    }
                    cands[ncands++] = (cand){t, s, score};
                    cands[ncands++] = (cand){s, t, score};
                }
        } else {
            for (size_t a = i; a < j; a++) {
                int t = edges[a].tri;
                if (!info[t].fail_kind) {
                    info[t].fail_kind = WRT_PROBLEM_UNPAIRED; info[t].fail_with = -1;
                    info[t].fail_value = (double)(j - i);
                }
            }
        }
        i = j;
    }
    *ncands_out = ncands;
    return cands;
}

/* Stage 3: the matching, forced pairs (one free candidate) first; mate[t] is t's pair or -1. */
static void pair_match(cand *cands, size_t ncands, size_t ntri, tri_info *info, int *mate) {
    if (ncands) qsort(cands, ncands, sizeof *cands, cmp_cand);
    size_t *first = wrt_xcalloc(ntri + 1, sizeof *first);
    for (size_t i = 0; i < ncands; i++) first[cands[i].t + 1]++;
    for (size_t t = 0; t < ntri; t++) first[t + 1] += first[t];
    int *deg = wrt_xcalloc(ntri, sizeof *deg);
    int *stack = wrt_xmalloc(ntri * sizeof *stack);
    size_t nstack = 0;
    for (size_t t = 0; t < ntri; t++) {
        mate[t] = -1;
        deg[t] = (int)(first[t + 1] - first[t]);
        info[t].ncand = deg[t];
    }
    for (size_t t = ntri; t-- > 0;)
        if (deg[t] == 1) stack[nstack++] = (int)t;
    size_t next = 0;
    for (;;) {
        int t = -1, s = -1;
        while (nstack && t < 0) {
            int c = stack[--nstack];
            if (mate[c] >= 0 || deg[c] != 1) continue;
            for (size_t k = first[c]; k < first[c + 1]; k++)
                if (mate[cands[k].s] < 0) { t = c; s = cands[k].s; break; }
        }
        if (t < 0) {
            while (next < ntri && (mate[next] >= 0 || deg[next] == 0)) next++;
            if (next == ntri) break;
            t = (int)next;
            for (size_t k = first[t]; k < first[t + 1]; k++)
                if (mate[cands[k].s] < 0) { s = cands[k].s; break; }
            if (s < 0) { deg[t] = 0; continue; } /* cannot happen: deg counts free candidates */
        }
        mate[t] = s;
        mate[s] = t;
        int ends[2] = {t, s};
        for (int e = 0; e < 2; e++)
            for (size_t k = first[ends[e]]; k < first[ends[e] + 1]; k++) {
                int o = cands[k].s;
                if (mate[o] >= 0) continue;
                if (--deg[o] == 1) stack[nstack++] = o;
            }
    }
    free(stack);
    free(deg);
    free(first);
}

/* Stage 4: the quads, paired ones first where they finish, every other good triangle as three. */
static void pair_emit(const wrt_gltf_prim *p, pair_ctx *ctx_in, size_t ntri, tri_info *info, const int *mate, int material,
                      quad_list *ql, problem_list *pl, wrt_scene *sc) {
    pair_ctx ctx = *ctx_in;
    for (size_t t = 0; t < ntri; t++) {
        int ti = (int)t;
        if (info[t].bad) continue;
        int s = mate[t];
        if (s >= 0) {
            if (s < ti) continue;
            wrt_v3 q[4];
            double value = 0;
            int para = 0;
            eval_pair(&ctx, ti, s, q, &value, &para);
            wrt_quad *quad = add_quad(ql);
            for (int i = 0; i < 4; i++) quad->p[i] = q[i];
            if (wrt_quad_finish(quad) == WRT_OK) {
                quad->material = material;
                quad->mesh = p->mesh;
                quad->prim = p->prim;
                quad->tri[0] = ti;
                quad->tri[1] = s;
                quad->name = p->mesh;
                quad->kind = WRT_ELEM_QUAD;
                quad->node = p->node;
                pair_uv(p, ti, s, quad);
                wrt_scene_pair_nrm(p, ti, s, quad);
                sc->npaired++;
                continue;
            }
            /* eval_pair accepted it but the quad is degenerate (cannot happen with the
             * same thresholds): the two stay triangles */
            ql->n--;
            int two[2] = {ti, s};
            for (int k = 0; k < 2; k++) {
                if (add_triangle_parts(p, two[k], material, ql) == 0) {
                    sc->nsingle++;
                    sc->why_single[WRT_SINGLE_NONCONVEX]++;
                } else {
                    add_problem(pl, WRT_PROBLEM_DEGENERATE, p->mesh, p->prim, two[k],
                                "zero area: its three quads are degenerate");
                }
            }
            continue;
        }
        if (add_triangle_parts(p, ti, material, ql) == 0) {
            sc->nsingle++;
            sc->why_single[single_reason(&info[t])]++;
        } else {
            add_problem(pl, WRT_PROBLEM_DEGENERATE, p->mesh, p->prim, ti,
                        "zero area: its three quads are degenerate");
        }
    }
}

static void pair_primitive(const wrt_gltf_prim *p, wrt_v3 origin, double eps, double planar_tol,
                           double diag, int material, quad_list *ql, problem_list *pl, wrt_scene *sc) {
    size_t ntri = p->ntri;
    if (ntri == 0) return;
    uint32_t *rep = wrt_xmalloc(p->npos * sizeof *rep);
    match_vertices(p, origin, eps, rep);
    tri_info *info = wrt_xcalloc(ntri, sizeof *info);
    edge_entry *edges = wrt_xmalloc(3 * ntri * sizeof *edges);
    size_t nedges = pair_classify(p, ntri, rep, diag, info, edges, pl);
    qsort(edges, nedges, sizeof *edges, cmp_edge);

    pair_ctx ctx = {p, rep, info, planar_tol};
    size_t ncands = 0;
    cand *cands = pair_candidates(&ctx, edges, nedges, info, &ncands);
    int *mate = wrt_xmalloc(ntri * sizeof *mate);
    pair_match(cands, ncands, ntri, info, mate);

    pair_emit(p, &ctx, ntri, info, mate, material, ql, pl, sc);
    free(mate);
    free(cands);
    free(edges);
    free(info);
    free(rep);
}

/* ------------------------------------------------------------------ loading */

static float clamp01(double x, int *changed) {
    double y = fmin(fmax(x, 0.0), 1.0);
    if (!(y == x)) *changed = 1;
    return (float)y;
}

static int finite3(const double *v) { return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]); }

static void convert_materials(wrt_gltf_data *g, int need_default, wrt_scene *s,
                              const char *label) {
    int n = (int)g->nmaterials + (need_default ? 1 : 0);
    s->materials = wrt_xcalloc((size_t)(n ? n : 1), sizeof *s->materials);
    s->nmaterials = n;
    for (int i = 0; i < (int)g->nmaterials; i++) {
        wrt_gltf_material *m = &g->materials[i];
        wrt_material *o = &s->materials[i];
        int changed = 0;
        wrt_utf8_copy(o->name, sizeof o->name, m->name);
        for (int c = 0; c < 3; c++) {
            double bc = m->base_color[c] * (m->has_base_tex ? m->base_tex_mean[c] : 1.0);
            o->base_color[c] = clamp01(bc, &changed);
            double em = m->emissive[c] * m->emissive_strength * (m->has_emissive_tex ? m->emissive_tex_mean[c] : 1.0);
            o->emissive[c] = (float)(isfinite(em) && em > 0 ? em : 0.0);
        }
        o->metallic = clamp01(m->metallic * (m->has_mr_tex ? m->mr_tex_mean[2] : 1.0), &changed);
        o->roughness = clamp01(m->roughness * (m->has_mr_tex ? m->mr_tex_mean[1] : 1.0), &changed);
        o->has_texture = m->has_base_tex || m->has_mr_tex || m->has_emissive_tex;
        if (m->base_tex) { /* kept for per-element albedo (docs/textures.md); ownership moves */
            s->textures = wrt_xrealloc(s->textures, (size_t)(s->ntextures + 1) * sizeof *s->textures);
            wrt_texture *t = &s->textures[s->ntextures++];
            t->w = m->base_tex_w;
            t->h = m->base_tex_h;
            t->wrap[0] = m->base_tex_wrap[0];
            t->wrap[1] = m->base_tex_wrap[1];
            t->srgb = m->base_tex;
            wrt_texture_srgb_table(t->lut);
            for (int c = 0; c < 3; c++) {
                t->factor[c] = (float)m->base_color[c];
                t->mean[c] = (float)m->base_tex_mean[c];
            }
            m->base_tex = NULL;
            o->base_tex = s->ntextures;
        }
        if (changed)
            wrt_log(WRT_LOG_WARN, "%s: material %d '%s': factor outside [0, 1] clamped", label, i,
                    o->name);
    }
    if (need_default) {
        wrt_material *o = &s->materials[n - 1];
        snprintf(o->name, sizeof o->name, "%s", "glTF default");
        o->base_color[0] = o->base_color[1] = o->base_color[2] = 1.0f;
        o->metallic = 1.0f;
        o->roughness = 1.0f;
    }
    for (int i = 0; i < n; i++) {
        wrt_material *o = &s->materials[i];
        o->lambertian = o->roughness == 1.0f && o->metallic == 0.0f;
        if (o->emissive[0] > 0 || o->emissive[1] > 0 || o->emissive[2] > 0) s->nemissive++;
    }
}

static wrt_status convert_lights(const wrt_gltf_data *g, wrt_scene *s, const char *label) {
    s->lights = wrt_xcalloc(g->nlights ? g->nlights : 1, sizeof *s->lights);
    for (size_t i = 0; i < g->nlights; i++) {
        const wrt_gltf_light *l = &g->lights[i];
        if (l->type == WRT_GLTF_LIGHT_OTHER) {
            wrt_log(WRT_LOG_WARN, "%s: light '%s' (node %d): unknown-type lights are not supported, skipped",
                    label, l->name, l->node);
            continue;
        }
        int sun = l->type == WRT_GLTF_LIGHT_DIRECTIONAL;
        if (!finite3(l->pos) || !finite3(l->dir) || !finite3(l->color) || !isfinite(l->intensity) ||
            !isfinite(l->range) || !isfinite(l->inner_cone) || !isfinite(l->outer_cone))
            return wrt_fail(WRT_ERR_PARSE, "%s: light '%s' (node %d) has a non-finite value", label,
                            l->name, l->node);
        if (l->intensity < 0 || l->range < 0 || l->color[0] < 0 || l->color[1] < 0 || l->color[2] < 0)
            return wrt_fail(WRT_ERR_PARSE, "%s: light '%s' (node %d) has a negative intensity, range or color",
                            label, l->name, l->node);
        if (!sun && !wrt_coord3_ok(l->pos[0], l->pos[1], l->pos[2]))
            return wrt_fail(WRT_ERR_PARSE,
                            "%s: light '%s' (node %d): position (%g, %g, %g) is outside +-%g, what the "
                            "computation can carry (common/limits.h)",
                            label, l->name, l->node, l->pos[0], l->pos[1], l->pos[2], WRT_MAX_COORD);
        if (l->intensity > WRT_MAX_LIGHT_INTENSITY)
            return wrt_fail(WRT_ERR_PARSE, "%s: light '%s' (node %d): intensity %g is above %g %s (common/limits.h)",
                            label, l->name, l->node, l->intensity, WRT_MAX_LIGHT_INTENSITY, sun ? "lux" : "cd");
        /* A sun's direction is its node's -Z; a node whose matrix collapses it has none. */
        if (sun && !(fabs(v3_len(v3(l->dir[0], l->dir[1], l->dir[2])) - 1) < 1e-6))
            return wrt_fail(WRT_ERR_PARSE, "%s: light '%s' (node %d): directional light without a direction "
                            "(the node's -Z axis is degenerate)", label, l->name, l->node);
        wrt_light *o = &s->lights[s->nlights++];
        o->type = sun ? WRT_LIGHT_DIRECTIONAL : l->type == WRT_GLTF_LIGHT_SPOT ? WRT_LIGHT_SPOT : WRT_LIGHT_POINT;
        wrt_utf8_copy(o->name, sizeof o->name, l->name);
        o->pos = sun ? v3(0, 0, 0) : v3(l->pos[0], l->pos[1], l->pos[2]); /* a sun has no position */
        o->dir = v3(l->dir[0], l->dir[1], l->dir[2]);
        for (int c = 0; c < 3; c++) o->color[c] = (float)l->color[c];
        o->intensity = (float)l->intensity;
        o->range = sun ? 0.0f : (float)l->range; /* the specification: range does not apply to a sun */
        if (sun && l->range > 0)
            wrt_log(WRT_LOG_WARN, "%s: directional light '%s': range %g ignored (KHR_lights_punctual: it does "
                    "not apply to directional lights)", label, l->name, l->range);
        double inner = l->inner_cone, outer = l->outer_cone;
        if (o->type == WRT_LIGHT_SPOT) {
            if (!(outer > 0 && outer <= WRT_PI / 2 && inner >= 0 && inner < outer)) {
                wrt_log(WRT_LOG_WARN,
                        "%s: spot light '%s': cone angles inner %g outer %g outside 0 <= inner < "
                        "outer <= pi/2, clamped",
                        label, l->name, inner, outer);
                outer = fmin(fmax(outer, 1e-3), WRT_PI / 2);
                inner = fmin(fmax(inner, 0.0), outer * 0.999);
            }
        }
        o->inner_cone = (float)inner;
        o->outer_cone = (float)outer;
        if (o->type == WRT_LIGHT_SPOT && !(o->inner_cone < o->outer_cone)) /* as every later stage needs them */
            return wrt_fail(WRT_ERR_PARSE, "%s: spot light '%s' (node %d): cone angles inner %.9g and outer %.9g are "
                            "equal in single precision (the falloff divides by their cosines' difference)",
                            label, l->name, l->node, inner, outer);
    }
    return WRT_OK;
}

static wrt_status make_camera(const wrt_gltf_data *g, wrt_scene *s, const char *label) {
    wrt_camera *c = &s->camera;
    const wrt_gltf_camera *gc = &g->camera;
    if (gc->present) {
        if (!finite3(gc->pos) || !finite3(gc->dir) || !finite3(gc->up) || !(gc->yfov >= WRT_MIN_YFOV) ||
            !(gc->yfov < WRT_PI) || !isfinite(gc->aspect) || !isfinite(gc->znear) ||
            !isfinite(gc->zfar))
            return wrt_fail(WRT_ERR_PARSE, "%s: camera of node %d: yfov %g (radians, [%g, pi) in "
                            "common/limits.h) or transform not usable", label, gc->node, gc->yfov, WRT_MIN_YFOV);
        if (!wrt_coord3_ok(gc->pos[0], gc->pos[1], gc->pos[2]))
            return wrt_fail(WRT_ERR_PARSE,
                            "%s: camera of node %d: position (%g, %g, %g) is outside +-%g, what the "
                            "computation can carry (common/limits.h)",
                            label, gc->node, gc->pos[0], gc->pos[1], gc->pos[2], WRT_MAX_COORD);
        c->pos = v3(gc->pos[0], gc->pos[1], gc->pos[2]);
        c->dir = v3(gc->dir[0], gc->dir[1], gc->dir[2]);
        c->up = v3(gc->up[0], gc->up[1], gc->up[2]);
        /* A view needs an up that is not along the view direction (else the picture is
         * black): the node's +Y and -Z, after a skewing matrix, may be nearly parallel. */
        double sin_up = v3_len(v3_cross(v3_norm(c->dir), v3_norm(c->up)));
        if (!(sin_up > 1e-4))
            return wrt_fail(WRT_ERR_PARSE,
                            "%s: camera of node %d: its up direction (the node's +Y) is parallel to its "
                            "view direction (-Z): no picture can be framed",
                            label, gc->node);
        c->yfov = gc->yfov;
        c->aspect = gc->aspect > 0 ? gc->aspect : 0;
        c->znear = gc->znear > 0 ? gc->znear : 0.01;
        c->zfar = gc->zfar > c->znear ? gc->zfar : 0;
        c->from_file = 1;
        return WRT_OK;
    }
    wrt_v3 center = v3_scale(v3_add(s->bbox_min, s->bbox_max), 0.5);
    double r = 0.5 * v3_len(v3_sub(s->bbox_max, s->bbox_min));
    if (!(r > 0)) r = 1;
    c->yfov = 0.8;
    double dist = r / sin(0.5 * c->yfov);
    c->pos = v3(center.x, center.y, center.z + dist);
    c->dir = v3(0, 0, -1);
    c->up = v3(0, 1, 0);
    c->aspect = 0;
    c->znear = 0.01 * r;
    c->zfar = 2 * (dist + r);
    c->from_file = 0;
    return WRT_OK;
}

/* Load stage 1: the scene extent over every usable vertex, the scale of the matching tolerance
 * (need_default: a primitive without a material). */
static void scene_extent(const wrt_gltf_data *g, wrt_v3 *lo_out, wrt_v3 *hi_out, int *need_default) {
    wrt_v3 lo = v3(DBL_MAX, DBL_MAX, DBL_MAX), hi = v3(-DBL_MAX, -DBL_MAX, -DBL_MAX);
    for (size_t i = 0; i < g->nprims; i++) {
        const wrt_gltf_prim *p = &g->prims[i];
        if (p->material < 0) *need_default = 1;
        for (size_t v = 0; v < p->npos; v++) {
            const double *c = &p->pos[3 * v];
            if (!coord_ok(c)) continue;
            lo = v3(fmin(lo.x, c[0]), fmin(lo.y, c[1]), fmin(lo.z, c[2]));
            hi = v3(fmax(hi.x, c[0]), fmax(hi.y, c[1]), fmax(hi.z, c[2]));
        }
    }
    if (lo.x > hi.x) lo = hi = v3(0, 0, 0);
    *lo_out = lo;
    *hi_out = hi;
}

/* Load stage 2: the problem triangles counted and reported; refuses the scene (freeing g and
 * s) for non-finite ones unless opt allows them. */
static wrt_status scene_report_problems(problem_list pl, wrt_gltf_data *g, const wrt_load_options *opt,
                                        const char *label, wrt_scene *s) {
    wrt_status st;
    /* Non-finite triangles refuse the scene (unless drop_bad); degenerate ones and
     * slivers are dropped and counted, with one warning naming the first few. */
    for (int pass = 0; pass < 2; pass++) {
        char buf[700];
        size_t used = 0;
        int n = 0, shown = 0;
        for (int i = 0; i < pl.n; i++) {
            const wrt_problem *pr = &pl.v[i];
            if ((pr->kind == WRT_PROBLEM_NONFINITE) != (pass == 0)) continue;
            n++;
            if (shown == 3 || used >= sizeof buf) continue;
            const char *mname = pr->mesh >= 0 && pr->mesh < s->nnames ? s->names[pr->mesh] : "?";
            int w = snprintf(buf + used, sizeof buf - used, "%smesh %d '%s' primitive %d triangle %d: %s (%s)",
                             shown ? "; " : "", pr->mesh, mname, pr->prim, pr->tri, pr->what,
                             wrt_scene_problem_name(pr->kind));
            if (w < 0) break;
            used += (size_t)w;
            shown++;
        }
        if (pass == 0) s->nnonfinite = n;
        else s->ndropped = n;
        if (n == 0 || opt->report_only) continue;
        if (pass == 0 && !opt->drop_bad) {
            st = wrt_fail(WRT_ERR_GEOMETRY, "%s: %d bad triangle%s refused: %s%s", label, n,
                          n == 1 ? "" : "s", buf, n > shown ? "; ..." : "");
            wrt_gltf_free(g);
            wrt_scene_free(s);
            return st;
        }
        if (pass == 0)
            wrt_log(WRT_LOG_WARN, "%s: dropped %d bad triangle%s: %s%s", label, n, n == 1 ? "" : "s", buf,
                    n > shown ? "; ..." : "");
        else
            wrt_log(WRT_LOG_WARN,
                    "%s: dropped %d degenerate triangle%s (zero area, or narrower than %g of the scene "
                    "diagonal): %s%s",
                    label, n, n == 1 ? "" : "s", WRT_SLIVER_REL, buf, n > shown ? "; ..." : "");
    }
    return WRT_OK;
}

/* Load stage 3: the back-to-back twins of doubleSided quads, appended to ql. */
static void scene_add_twins(quad_list *ql, const wrt_gltf_data *g, double diag, wrt_scene *s) {
    /* doubleSided (glTF: no back-face culling, both sides lit): each such quad gets a
     * back-to-back twin facing the other way, set back by WRT_TWIN_GAP of the scene's
     * diagonal so that a ray meets the side it comes from first (two coincident faces
     * would be hit in arbitrary order). Every part of the method then treats the two
     * sides as the one-sided quads it knows. */
    int nfront = ql->n;
    for (int i = 0; i < nfront; i++) {
        int m = ql->v[i].material;
        if (m < 0 || m >= (int)g->nmaterials || !g->materials[m].double_sided) continue;
        wrt_quad *b = add_quad(ql);
        const wrt_quad *f = &ql->v[i]; /* after add_quad: it may move the array */
        wrt_v3 back = v3_scale(f->n, -WRT_TWIN_GAP * (diag > 0 ? diag : 1.0));
        b->p[0] = v3_add(f->p[0], back);
        b->p[1] = v3_add(f->p[3], back);
        b->p[2] = v3_add(f->p[2], back);
        b->p[3] = v3_add(f->p[1], back);
        b->material = f->material;
        b->mesh = f->mesh;
        b->prim = f->prim;
        b->tri[0] = f->tri[0];
        b->tri[1] = f->tri[1];
        b->name = f->name;
        b->kind = f->kind;
        b->part = f->part;
        b->node = f->node;
        b->twin = 1;
        b->twin_of = i;
        b->has_uv = f->has_uv; /* the corners run p0 p3 p2 p1: so do their (u, v) */
        for (int c = 0; c < 4; c++)
            for (int d = 0; d < 2; d++) b->uv[c][d] = f->uv[(4 - c) % 4][d];
        b->has_nrm = f->has_nrm; /* the back faces the other way: so do its normals */
        for (int c = 0; c < 4; c++)
            for (int d = 0; d < 3; d++) b->vn[c][d] = -f->vn[(4 - c) % 4][d];
        if (wrt_quad_finish(b) != WRT_OK) ql->n--; /* cannot happen: f was finished */
        else s->ntwins++;
    }
}

/* Load stage 4: the bounding box of the kept geometry (lo, hi: the extent, for no quads). */
static void scene_bbox(wrt_scene *s, wrt_v3 lo, wrt_v3 hi, const wrt_load_options *opt, const char *label) {
    if (s->nquads > 0) {
        lo = v3(DBL_MAX, DBL_MAX, DBL_MAX);
        hi = v3(-DBL_MAX, -DBL_MAX, -DBL_MAX);
        for (int i = 0; i < s->nquads; i++)
            for (int k = 0; k < 4; k++) {
                wrt_v3 c = s->quads[i].p[k];
                lo = v3(fmin(lo.x, c.x), fmin(lo.y, c.y), fmin(lo.z, c.z));
                hi = v3(fmax(hi.x, c.x), fmax(hi.y, c.y), fmax(hi.z, c.z));
            }
    } else {
        if (!opt->report_only) wrt_log(WRT_LOG_WARN, "%s: the scene has no quads", label);
    }
    s->bbox_min = lo;
    s->bbox_max = hi;
}

static wrt_status load_common(const void *data, size_t size, const char *base_dir, const char *label,
                              const wrt_load_options *opt, wrt_scene *out) {
    wrt_load_options defaults = {0};
    if (!opt) opt = &defaults;
    double planar_tol = opt->planar_tol > 0 ? opt->planar_tol : 1e-4;
    if (!isfinite(planar_tol) || planar_tol >= 1)
        return wrt_fail(WRT_ERR_INVALID_ARG, "planar_tol %g must be in (0, 1)", opt->planar_tol);
    wrt_gltf_data g;
    wrt_status st = wrt_gltf_read(data, size, base_dir, label, opt->allow_outside_files, &g);
    if (st != WRT_OK) return st;
    if (g.warnings && g.warnings[0]) {
        for (char *w = g.warnings; *w; w++)
            if (*w == '\n') *w = ' ';
        wrt_log(WRT_LOG_WARN, "%s: %s", label, g.warnings);
    }
    wrt_scene *s = out;
    s->source_hash = wrt_hash64(data, size, WRT_HASH_SEED);

    wrt_v3 lo, hi;
    int need_default = 0;
    scene_extent(&g, &lo, &hi, &need_default);
    double diag = v3_len(v3_sub(hi, lo));
    double eps = diag > 0 ? WRT_WELD_REL * diag : 1.0;
    if (diag > 0 && diag < WRT_MIN_EXTENT) { /* common/limits.h */
        wrt_gltf_free(&g);
        return wrt_fail(WRT_ERR_GEOMETRY, "%s: the scene is %g m across (its bounding box's diagonal), below the "
                        "%g m wrt works at (common/limits.h): check the nodes' scale and the file's units", label,
                        diag, WRT_MIN_EXTENT);
    }

    convert_materials(&g, need_default, s, label);
    s->nnames = (int)g.nmeshes;
    s->names = wrt_xcalloc(g.nmeshes ? g.nmeshes : 1, sizeof *s->names);
    for (size_t i = 0; i < g.nmeshes; i++) memcpy(s->names[i], g.mesh_names[i], 64);

    quad_list ql = {0};
    problem_list pl = {0};
    size_t ntri = 0;
    for (size_t i = 0; i < g.nprims; i++) {
        const wrt_gltf_prim *p = &g.prims[i];
        int material = p->material >= 0 ? p->material : s->nmaterials - 1;
        pair_primitive(p, lo, eps, planar_tol, diag, material, &ql, &pl, s);
        ntri += p->ntri;
        s->nmirrored += p->mirrored;
    }
    s->quads = ql.v;
    s->nquads = ql.n;
    s->problems = pl.v;
    s->nproblems = pl.n;
    s->ntriangles = (int)ntri;

    st = scene_report_problems(pl, &g, opt, label, s);
    if (st != WRT_OK) return st;
    s->ncoincident = wrt_scene_coincident(s, diag, label, opt->report_only); /* scene_dups.c */

    scene_add_twins(&ql, &g, diag, s);
    s->quads = ql.v;
    s->nquads = ql.n;
    s->ignored = wrt_xmalloc(strlen(g.ignored ? g.ignored : "") + 1);
    strcpy(s->ignored, g.ignored ? g.ignored : "");
    s->files = wrt_xmalloc(strlen(g.files ? g.files : "") + 1);
    strcpy(s->files, g.files ? g.files : "");

    scene_bbox(s, lo, hi, opt, label);

    st = convert_lights(&g, s, label);
    if (st == WRT_OK) st = make_camera(&g, s, label);
    wrt_gltf_free(&g);
    if (st != WRT_OK) wrt_scene_free(s);
    return st;
}

wrt_status wrt_scene_load_memory(const void *data, size_t size, const char *base_dir,
                                 const wrt_load_options *opt, wrt_scene *out) {
    if (!out) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_scene_load_memory: out is NULL");
    memset(out, 0, sizeof *out);
    if (!data && size) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_scene_load_memory: data is NULL");
    return load_common(data, size, base_dir ? base_dir : "", "<memory>", opt, out);
}

wrt_status wrt_scene_load(const char *path, const wrt_load_options *opt, wrt_scene *out) {
    if (!out) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_scene_load: out is NULL");
    memset(out, 0, sizeof *out);
    if (!path) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_scene_load: path is NULL");
    /* O_NONBLOCK: a FIFO or a device is refused by fstat instead of blocking the open;
     * the size comes from fstat of the regular file, never from seeking. */
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    if (fd < 0) return wrt_fail(WRT_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat sb;
    if (fstat(fd, &sb) != 0) {
        int e = errno;
        close(fd);
        return wrt_fail(WRT_ERR_IO, "%s: cannot stat: %s", path, strerror(e));
    }
    if (!S_ISREG(sb.st_mode)) {
        close(fd);
        return wrt_fail(WRT_ERR_PARSE, "%s: not a regular file (%s)", path,
                        S_ISDIR(sb.st_mode) ? "a directory" : S_ISFIFO(sb.st_mode) ? "a FIFO"
                        : S_ISCHR(sb.st_mode) || S_ISBLK(sb.st_mode) ? "a device" : "a special file");
    }
    if (sb.st_size == 0) {
        close(fd);
        return wrt_fail(WRT_ERR_PARSE, "%s: empty file", path);
    }
    if ((uint64_t)sb.st_size > 0xFFFFFFF0u) {
        close(fd);
        return wrt_fail(WRT_ERR_UNSUPPORTED, "%s: larger than 4 GiB", path);
    }
    size_t len = (size_t)sb.st_size, got = 0;
    unsigned char *buf = wrt_xmalloc(len);
    while (got < len) {
        ssize_t r = read(fd, buf + got, len - got);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) break;
        got += (size_t)r;
    }
    close(fd);
    if (got != len) {
        free(buf);
        return wrt_fail(WRT_ERR_IO, "%s: short read (%zu of %zu bytes)", path, got, len);
    }
    /* external buffers and images resolve against the file's folder */
    char dir[4096];
    const char *slash = strrchr(path, '/');
    if (slash) {
        size_t n = (size_t)(slash - path);
        if (n >= sizeof dir) n = sizeof dir - 1;
        memcpy(dir, path, n);
        dir[n] = 0;
        if (n == 0) snprintf(dir, sizeof dir, "/");
    } else {
        snprintf(dir, sizeof dir, ".");
    }
    wrt_status st = load_common(buf, len, dir, path, opt, out);
    free(buf);
    return st;
}

void wrt_scene_free(wrt_scene *s) {
    if (!s) return;
    free(s->quads);
    free(s->materials);
    free(s->lights);
    free(s->names);
    free(s->problems);
    free(s->ignored);
    free(s->files);
    for (int i = 0; i < s->ntextures; i++) free(s->textures[i].srgb);
    free(s->textures);
    memset(s, 0, sizeof *s);
}
