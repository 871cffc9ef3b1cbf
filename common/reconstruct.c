/* reconstruct.c: smooth single-level reconstruction of each quad's indirect light, as
 * specified in reconstruct.h. */
#include "reconstruct.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#ifdef __SSE4_1__
#include <smmintrin.h>
#endif

/* Edge e runs from corner E_END[e][0] to E_END[e][1], along increasing u (edges 0, 2)
 * or v (edges 1, 3). */
static const int E_END[4][2] = {{0, 1}, {1, 2}, {3, 2}, {0, 3}};
#define MAX_AROUND 40 /* quads around one corner within a group (a 32-segment UV sphere's pole: 32) */

typedef struct corner_set { int n; int quad[MAX_AROUND], corner[MAX_AROUND]; } corner_set;

struct wrt_recon {
    int n, ngroups;
    int (*nb)[4], (*nbe)[4], (*flip)[4];
    uint8_t (*bent)[4];          /* the edge's neighbour was joined by the corner normals */
    uint8_t *curved;             /* joined to a neighbour across a bent edge (corner normals) */
    int *group, *slot;           /* slot: position within its group */
    int *gfirst, *gquads;        /* members of group g: gquads[gfirst[g] .. gfirst[g+1]) */
    corner_set (*around)[4];     /* quads around each corner (itself included), ascending */
    wrt_recon_allocator al;      /* alloc NULL: malloc and free */
};

static void *rc_alloc(const wrt_recon_allocator *al, size_t n) { return al->alloc ? al->alloc(al->user, n ? n : 1) : malloc(n ? n : 1); }
static void rc_free(const wrt_recon_allocator *al, void *p) { if (p) { if (al->alloc) al->free(al->user, p); else free(p); } }

/* ------------------------------------------------------------ adjacency ---- */

typedef struct { double x, y, z; } v3;
static v3 mk(const double *p) { v3 r = {p[0], p[1], p[2]}; return r; }
static v3 sub(v3 a, v3 b) { v3 r = {a.x - b.x, a.y - b.y, a.z - b.z}; return r; }
static double dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static v3 cross(v3 a, v3 b) { v3 r = {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; return r; }
static double len(v3 a) { return sqrt(dot(a, a)); }

static int same_point(const double *a, const double *b, double tol) {
    return fabs(a[0] - b[0]) <= tol && fabs(a[1] - b[1]) <= tol && fabs(a[2] - b[2]) <= tol;
}

static v3 quad_normal(const double (*c)[3]) {
    v3 n = cross(sub(mk(c[2]), mk(c[0])), sub(mk(c[3]), mk(c[1])));
    double l = len(n);
    if (l > 0) { n.x /= l; n.y /= l; n.z /= l; }
    return n;
}

/* Distance from p to the line through a, b (b != a). */
static double line_dist(v3 p, v3 a, v3 b) {
    v3 d = sub(b, a);
    double l = len(d);
    return l > 0 ? len(cross(sub(p, a), d)) / l : len(sub(p, a));
}

/* 1 if some quad other than q and o has an edge lying along segment a-b (collinear and
 * overlapping it by more than tol): a wall or a box's side standing on the edge. */
static int edge_blocked(int n, const double (*corners)[4][3], int q, int o, v3 a, v3 b, double tol) {
    v3 d = sub(b, a);
    double l = len(d);
    if (!(l > 0)) return 1;
    for (int k = 0; k < n; k++) {
        if (k == q || k == o) continue;
        for (int e = 0; e < 4; e++) {
            v3 c0 = mk(corners[k][E_END[e][0]]), c1 = mk(corners[k][E_END[e][1]]);
            if (line_dist(c0, a, b) > tol || line_dist(c1, a, b) > tol) continue;
            double t0 = dot(sub(c0, a), d) / l, t1 = dot(sub(c1, a), d) / l;
            double lo = fmax(fmin(t0, t1), 0), hi = fmin(fmax(t0, t1), l);
            if (hi - lo > tol) return 1;
        }
    }
    return 0;
}

wrt_recon *wrt_recon_create(int n, const double (*corners)[4][3], const uint32_t *material) {
    return wrt_recon_create_with(n, corners, material, NULL);
}

/* Stage 1 of the create: the tolerance, 1e-6 of the scene's size. */
static double recon_tolerance(int n, const double (*corners)[4][3]) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int q = 0; q < n; q++)
        for (int k = 0; k < 4; k++)
            for (int c = 0; c < 3; c++) {
                lo[c] = fmin(lo[c], corners[q][k][c]);
                hi[c] = fmax(hi[c], corners[q][k][c]);
            }
    double size = n > 0 ? sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                               (hi[2] - lo[2]) * (hi[2] - lo[2])) : 1;
    double tol = 1e-6 * (size > 0 ? size : 1);
    return tol;
}

/* With corner normals: 1 if quads q and o, sharing q's edge e as o's edge f (fl: the other
 * way), are one smooth surface there: the normals at both ends agree within cos_tol and
 * the faces are not folded onto each other (flat normals more than 120 degrees apart). */
static int smooth_edge(const float (*normals)[4][3], double cos_tol, const v3 *nrm, int q, int e, int o, int f,
                       int fl) {
    if (!normals || dot(nrm[q], nrm[o]) < -0.5) return 0;
    for (int end = 0; end < 2; end++) {
        const float *a = normals[q][E_END[e][end]], *b = normals[o][E_END[f][fl ? 1 - end : end]];
        if ((double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2] < cos_tol) return 0;
    }
    return 1;
}

/* Stage 2: each quad edge's smooth neighbour (same material; coplanar, or with corner
 * normals agreeing along the edge; a shared edge), mutual. */
static void recon_neighbours(wrt_recon *rc, int n, const double (*corners)[4][3], const uint32_t *material, v3 *nrm,
                             double tol, const float (*normals)[4][3], double cos_tol) {
    for (int q = 0; q < n; q++) {
        nrm[q] = quad_normal(corners[q]);
        for (int e = 0; e < 4; e++) rc->nb[q][e] = -1, rc->nbe[q][e] = 0, rc->flip[q][e] = 0, rc->bent[q][e] = 0;
    }
    for (int q = 0; q < n; q++) rc->curved[q] = 0;
    for (int q = 0; q < n; q++)
        for (int e = 0; e < 4; e++) {
            uint8_t *bent = rc->bent[q];
            const double *a = corners[q][E_END[e][0]], *b = corners[q][E_END[e][1]];
            for (int o = 0; o < n && rc->nb[q][e] < 0; o++) {
                if (o == q || material[o] != material[q]) continue;
                int coplanar = dot(nrm[q], nrm[o]) >= 1 - 1e-9;
                for (int k = 0; k < 4 && coplanar; k++)
                    if (fabs(dot(sub(mk(corners[o][k]), mk(a)), nrm[q])) > tol) coplanar = 0;
                if (!coplanar && !normals) continue;
                for (int f = 0; f < 4; f++) {
                    const double *c = corners[o][E_END[f][0]], *d = corners[o][E_END[f][1]];
                    int fl;
                    if (same_point(a, c, tol) && same_point(b, d, tol)) fl = 0;
                    else if (same_point(a, d, tol) && same_point(b, c, tol)) fl = 1;
                    else continue;
                    if (!coplanar && !smooth_edge(normals, cos_tol, nrm, q, e, o, f, fl)) break;
                    if (edge_blocked(n, corners, q, o, mk(a), mk(b), tol)) break;
                    rc->nb[q][e] = o; rc->nbe[q][e] = f; rc->flip[q][e] = fl;
                    bent[e] = !coplanar;
                    break;
                }
            }
        }
    /* A neighbour relation must be mutual (it is, up to the tolerance; enforce it). */
    for (int q = 0; q < n; q++)
        for (int e = 0; e < 4; e++) {
            int o = rc->nb[q][e];
            if (o >= 0 && rc->nb[o][rc->nbe[q][e]] != q) rc->nb[q][e] = -1;
        }
    for (int q = 0; q < n; q++)
        for (int e = 0; e < 4; e++)
            if (rc->nb[q][e] >= 0 && rc->bent[q][e]) rc->curved[q] = 1;
}

/* Stage 3: groups, the connected components, numbered by their smallest quad; returns their count. */
static int recon_components(wrt_recon *rc, int n, int *stack) {
    for (int q = 0; q < n; q++) rc->group[q] = -1;
    int ng = 0;
    for (int q = 0; q < n; q++) {
        if (rc->group[q] >= 0) continue;
        int sp = 0;
        stack[sp++] = q;
        rc->group[q] = ng;
        while (sp) {
            int x = stack[--sp];
            for (int e = 0; e < 4; e++) {
                int o = rc->nb[x][e];
                if (o >= 0 && rc->group[o] < 0) { rc->group[o] = ng; stack[sp++] = o; }
            }
        }
        ng++;
    }
    return ng;
}

/* Stage 4 (after the group lists): the quads around each corner, walking the smooth edges. */
static void recon_corner_sets(wrt_recon *rc, int n) {
    for (int q = 0; q < n; q++)
        for (int k = 0; k < 4; k++) {
            corner_set *cs = &rc->around[q][k];
            cs->n = 1; cs->quad[0] = q; cs->corner[0] = k;
            for (int h = 0; h < cs->n; h++) {
                int x = cs->quad[h], xk = cs->corner[h];
                for (int e = 0; e < 4; e++) {
                    int end = E_END[e][0] == xk ? 0 : E_END[e][1] == xk ? 1 : -1;
                    int o = rc->nb[x][e];
                    if (end < 0 || o < 0) continue;
                    int ok = E_END[rc->nbe[x][e]][rc->flip[x][e] ? 1 - end : end], seen = 0;
                    for (int s = 0; s < cs->n; s++) seen |= cs->quad[s] == o && cs->corner[s] == ok;
                    if (!seen && cs->n < MAX_AROUND) { cs->quad[cs->n] = o; cs->corner[cs->n] = ok; cs->n++; }
                }
            }
            for (int a = 1; a < cs->n; a++) /* ascending quad: the same sum from every side */
                for (int b = a; b > 0 && cs->quad[b - 1] > cs->quad[b]; b--) {
                    int t = cs->quad[b]; cs->quad[b] = cs->quad[b - 1]; cs->quad[b - 1] = t;
                    t = cs->corner[b]; cs->corner[b] = cs->corner[b - 1]; cs->corner[b - 1] = t;
                }
        }
}

wrt_recon *wrt_recon_create_with(int n, const double (*corners)[4][3], const uint32_t *material,
                                 const wrt_recon_allocator *alloc) {
    return wrt_recon_create_smooth(n, corners, material, NULL, 1, alloc);
}

wrt_recon *wrt_recon_create_smooth(int n, const double (*corners)[4][3], const uint32_t *material,
                                   const float (*normals)[4][3], double cos_tol, const wrt_recon_allocator *alloc) {
    wrt_recon_allocator al = {0};
    if (alloc && alloc->alloc && alloc->free) al = *alloc;
    wrt_recon *rc = rc_alloc(&al, sizeof *rc);
    if (!rc) return NULL;
    memset(rc, 0, sizeof *rc);
    rc->al = al;
    rc->n = n;
    size_t m = n > 0 ? (size_t)n : 1;
    rc->nb = rc_alloc(&al, m * sizeof *rc->nb);
    rc->nbe = rc_alloc(&al, m * sizeof *rc->nbe);
    rc->flip = rc_alloc(&al, m * sizeof *rc->flip);
    rc->bent = rc_alloc(&al, m * sizeof *rc->bent);
    rc->curved = rc_alloc(&al, m);
    rc->group = rc_alloc(&al, m * sizeof(int));
    rc->slot = rc_alloc(&al, m * sizeof(int));
    rc->gfirst = rc_alloc(&al, (m + 1) * sizeof(int));
    rc->gquads = rc_alloc(&al, m * sizeof(int));
    rc->around = rc_alloc(&al, m * sizeof *rc->around);
    v3 *nrm = rc_alloc(&al, m * sizeof(v3));
    int *stack = rc_alloc(&al, m * sizeof(int));
    if (!rc->nb || !rc->nbe || !rc->flip || !rc->bent || !rc->curved || !rc->group || !rc->slot || !rc->gfirst || !rc->gquads ||
        !rc->around || !nrm || !stack) {
        rc_free(&al, nrm); rc_free(&al, stack); wrt_recon_destroy(rc);
        return NULL;
    }
    double tol = recon_tolerance(n, corners);
    recon_neighbours(rc, n, corners, material, nrm, tol, normals, cos_tol);
    int ng = recon_components(rc, n, stack);
    rc->ngroups = ng;
    /* Each group's members, in quad order, and each quad's slot in its group. */
    int *cnt = rc_alloc(&al, ((size_t)ng + 1) * sizeof(int));
    if (!cnt) { rc_free(&al, nrm); rc_free(&al, stack); wrt_recon_destroy(rc); return NULL; }
    memset(cnt, 0, ((size_t)ng + 1) * sizeof(int));
    for (int q = 0; q < n; q++) cnt[rc->group[q] + 1]++;
    rc->gfirst[0] = 0;
    for (int g = 0; g < ng; g++) rc->gfirst[g + 1] = rc->gfirst[g] + cnt[g + 1];
    memset(cnt, 0, ((size_t)ng + 1) * sizeof(int));
    for (int q = 0; q < n; q++) {
        int g = rc->group[q];
        rc->slot[q] = cnt[g];
        rc->gquads[rc->gfirst[g] + cnt[g]++] = q;
    }
    rc_free(&al, cnt);
    recon_corner_sets(rc, n);
    rc_free(&al, nrm);
    rc_free(&al, stack);
    return rc;
}

void wrt_recon_destroy(wrt_recon *rc) {
    if (!rc) return;
    const wrt_recon_allocator al = rc->al;
    rc_free(&al, rc->nb); rc_free(&al, rc->nbe); rc_free(&al, rc->flip); rc_free(&al, rc->bent); rc_free(&al, rc->curved);
    rc_free(&al, rc->group); rc_free(&al, rc->slot);
    rc_free(&al, rc->gfirst); rc_free(&al, rc->gquads); rc_free(&al, rc->around);
    rc_free(&al, rc);
}

int wrt_recon_ngroups(const wrt_recon *rc) { return rc->ngroups; }
int wrt_recon_group(const wrt_recon *rc, int q) { return q >= 0 && q < rc->n ? rc->group[q] : -1; }

const int *wrt_recon_members(const wrt_recon *rc, int gr, int *count) {
    if (gr < 0 || gr >= rc->ngroups) { *count = 0; return NULL; }
    *count = rc->gfirst[gr + 1] - rc->gfirst[gr];
    return rc->gquads + rc->gfirst[gr];
}

int wrt_recon_curved(const wrt_recon *rc, int q) { return q >= 0 && q < rc->n ? rc->curved[q] : 0; }

int wrt_recon_neighbour(const wrt_recon *rc, int q, int e, int *nedge, int *flip) {
    if (q < 0 || q >= rc->n || e < 0 || e > 3) return -1;
    if (nedge) *nedge = rc->nbe[q][e];
    if (flip) *flip = rc->flip[q][e];
    return rc->nb[q][e];
}

/* ------------------------------------------------------- reconstruction ---- */

/* Cell k (0 .. m-1, along the edge's direction) of edge e of an m x m grid. */
static size_t edge_cell(int e, int m, int k) {
    switch (e) {
    case 0: return (size_t)k;
    case 1: return (size_t)k * m + (m - 1);
    case 2: return (size_t)(m - 1) * m + k;
    default: return (size_t)k * m;
    }
}

/* The cell one step inside from edge cell k of edge e (m >= 3): not on any edge. */
static size_t inner_cell(int e, int m, int k) {
    switch (e) {
    case 0: return (size_t)m + k;
    case 1: return (size_t)k * m + (m - 2);
    case 2: return (size_t)(m - 2) * m + k;
    default: return (size_t)k * m + 1;
    }
}

/* The cell diagonally inside corner k (m >= 3). */
static size_t corner_inner(int k, int m) {
    return k == 0 ? (size_t)m + 1 : k == 1 ? (size_t)m + m - 2 : k == 2 ? (size_t)(m - 2) * m + m - 2 : (size_t)(m - 2) * m + 1;
}

static size_t corner_cell(int k, int m) {
    return k == 0 ? 0 : k == 1 ? (size_t)(m - 1) : k == 2 ? (size_t)m * m - 1 : (size_t)(m - 1) * m;
}

/* The argument of least magnitude if all three have one sign, else 0 (the MC limiter). */
static inline float minmod3(float a, float b, float c) {
    if (a > 0 && b > 0 && c > 0) { float m = a < b ? a : b; return m < c ? m : c; }
    if (a < 0 && b < 0 && c < 0) { float m = a > b ? a : b; return m > c ? m : c; }
    return 0;
}

/* How far the bake's four children of cell c (rows r0, r1, two cells each; parent
 * average par) lie from the limited prediction below, as a fraction of the larger of the
 * cell's average and the quad's mean (mean: the quad's level 0), both the largest over
 * the channels. The
 * children's own offsets are compared (each child minus the parent, the prediction's
 * minus its centre), so that a cell the coarser levels already moved is judged alike. */
/* fmaxf for the values here (never -0): the larger, or the one that is not NaN; inline
 * (the library's fmaxf is a call at -O2). */
static inline float max_nn(float a, float b) { return a != a ? b : (b > a ? b : a); }

#ifdef __SSE4_1__
static inline __m128 minmod3v(__m128 a, __m128 b, __m128 c);
/* details_missed for RGB at once (nc 3): each lane does the scalar code's operations in
 * its order; the maxima's order does not matter (max is exact, and NaN is ignored as
 * max_nn ignores it), so the result is the same float. The fourth lane is loaded and
 * masked out. */
static float details_missed3(const float *c, size_t ws, const float *par, const float *r0, const float *r1,
                             const float *mean) {
    const __m128 sign = _mm_set1_ps(-0.0f), lanes = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
    const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), q = _mm_set1_ps(0.25f);
    __m128 av = _mm_loadu_ps(c), E = _mm_loadu_ps(c + 3), W = _mm_loadu_ps(c - 3);
    __m128 N = _mm_loadu_ps(c + ws), S = _mm_loadu_ps(c - ws);
    __m128 dx = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, W)), _mm_mul_ps(half, _mm_sub_ps(E, W)),
                                    _mm_mul_ps(two, _mm_sub_ps(E, av))), q);
    __m128 dy = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, S)), _mm_mul_ps(half, _mm_sub_ps(N, S)),
                                    _mm_mul_ps(two, _mm_sub_ps(N, av))), q);
    __m128 ndx = _mm_xor_ps(dx, sign), p = _mm_loadu_ps(par);
    __m128 pred[4] = {_mm_sub_ps(ndx, dy), _mm_sub_ps(dx, dy), _mm_add_ps(ndx, dy), _mm_add_ps(dx, dy)};
    __m128 bake[4] = {_mm_sub_ps(_mm_loadu_ps(r0), p), _mm_sub_ps(_mm_loadu_ps(r0 + 3), p),
                      _mm_sub_ps(_mm_loadu_ps(r1), p), _mm_sub_ps(_mm_loadu_ps(r1 + 3), p)};
    __m128 d = _mm_setzero_ps();
    for (int t = 0; t < 4; t++) d = _mm_max_ps(_mm_andnot_ps(sign, _mm_sub_ps(bake[t], pred[t])), d);
    __m128 aa = _mm_andnot_ps(sign, av), am = _mm_andnot_ps(sign, _mm_loadu_ps(mean));
    __m128 sv = _mm_blendv_ps(_mm_max_ps(am, aa), am, _mm_cmpunord_ps(aa, aa)); /* max_nn(|av|, |mean|) */
    d = _mm_and_ps(d, lanes);
    sv = _mm_and_ps(_mm_max_ps(sv, _mm_setzero_ps()), lanes);
    d = _mm_max_ps(d, _mm_movehl_ps(d, d));
    d = _mm_max_ss(d, _mm_shuffle_ps(d, d, 1));
    sv = _mm_max_ps(sv, _mm_movehl_ps(sv, sv));
    sv = _mm_max_ss(sv, _mm_shuffle_ps(sv, sv, 1));
    float dmax = _mm_cvtss_f32(d), smax = _mm_cvtss_f32(sv);
    return smax > 0 ? dmax / smax : (dmax > 0 ? INFINITY : 0);
}
#endif

static float details_missed(const float *c, int nc, size_t ws, const float *par, const float *r0, const float *r1,
                            const float *mean) {
#ifdef __SSE4_1__
    if (nc == 3) return details_missed3(c, ws, par, r0, r1, mean);
#endif
    float dmax = 0, smax = 0;
    for (int ch = 0; ch < nc; ch++) {
        float av = c[ch], E = c[nc + ch], W = c[ch - nc], N = c[ws + ch], S = c[ch - ws];
        float dx = minmod3(2 * (av - W), 0.5f * (E - W), 2 * (E - av)) * 0.25f;
        float dy = minmod3(2 * (av - S), 0.5f * (N - S), 2 * (N - av)) * 0.25f;
        float pred[4] = {-dx - dy, dx - dy, -dx + dy, dx + dy};
        float bake[4] = {r0[ch] - par[ch], r0[nc + ch] - par[ch], r1[ch] - par[ch], r1[nc + ch] - par[ch]};
        for (int t = 0; t < 4; t++) dmax = max_nn(dmax, fabsf(bake[t] - pred[t]));
        smax = max_nn(smax, max_nn(fabsf(av), fabsf(mean[ch])));
    }
    return smax > 0 ? dmax / smax : (dmax > 0 ? INFINITY : 0);
}

size_t wrt_recon_scratch(const wrt_recon *rc, int gr, int L, int Lo, int nc) {
    int nm;
    wrt_recon_members(rc, gr, &nm);
    size_t pyr_n = (((size_t)1 << (2 * (L + 1))) - 1) / 3 * nc; /* levels 0..L */
    size_t full = ((size_t)1 << (2 * Lo)) * nc;
    size_t ext_n = (((size_t)1 << Lo) + 2) * (((size_t)1 << Lo) + 2) * nc;
    return (size_t)nm * (pyr_n + 2 * full) + ext_n + 4; /* + 4: the RGB loads' fourth lane */
}

int wrt_recon_run(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                  const uint8_t *const *known, float *const *out, const wrt_recon_params *prm) {
    int nm;
    wrt_recon_members(rc, gr, &nm);
    if (nm == 0) return 0;
    float *buf = rc_alloc(&rc->al, wrt_recon_scratch(rc, gr, L, Lo, nc) * sizeof(float));
    if (!buf) return -1;
    wrt_recon_run_in(rc, gr, L, Lo, nc, in, known, out, prm, buf);
    rc_free(&rc->al, buf);
    return 0;
}

#define CUR(s) (buf + (size_t)nm * pyr_n + (size_t)(s) * 2 * full + (size_t)cur_half * full)
#define NXT(s) (buf + (size_t)nm * pyr_n + (size_t)(s) * 2 * full + (size_t)(1 - cur_half) * full)

/* Stage 1: pyramids of the input: level l at offset (4^l - 1)/3 cells. */
static void recon_pyramids(int nm, const int *mem, int L, int nc, const float *const *in, float *buf, size_t pyr_n) {
    for (int s = 0; s < nm; s++) {
        float *pyr = buf + (size_t)s * pyr_n;
        size_t offL = (((size_t)1 << (2 * L)) - 1) / 3 * nc;
        memcpy(pyr + offL, in[mem[s]], ((size_t)1 << (2 * L)) * nc * sizeof(float));
        for (int l = L - 1; l >= 0; l--) {
            int m = 1 << l;
            float *p = pyr + (((size_t)1 << (2 * l)) - 1) / 3 * nc, *c = pyr + (((size_t)1 << (2 * (l + 1))) - 1) / 3 * nc;
#ifdef __SSE4_1__
            if (nc == 3) { /* RGB at once, the same sums in the same order (4th lane not stored) */
                const __m128 q = _mm_set1_ps(0.25f);
                size_t r = (size_t)2 * m * 3;
                for (int j = 0; j < m; j++)
                    for (int i = 0; i < m; i++) {
                        const float *c0 = c + ((size_t)(2 * j) * 2 * m + 2 * i) * 3;
                        __m128 v = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_loadu_ps(c0), _mm_loadu_ps(c0 + 3)),
                                                         _mm_loadu_ps(c0 + r)), _mm_loadu_ps(c0 + r + 3));
                        float *o = p + ((size_t)j * m + i) * 3;
                        __m128 pv = _mm_mul_ps(q, v);
                        _mm_storel_pi((__m64 *)o, pv);
                        _mm_store_ss(o + 2, _mm_movehl_ps(pv, pv));
                    }
                continue;
            }
#endif
            for (int j = 0; j < m; j++)
                for (int i = 0; i < m; i++)
                    for (int ch = 0; ch < nc; ch++) {
                        size_t c0 = ((size_t)(2 * j) * 2 * m + 2 * i) * nc + ch, r = (size_t)2 * m * nc;
                        p[((size_t)j * m + i) * nc + ch] = 0.25f * (c[c0] + c[c0 + nc] + c[c0 + r] + c[c0 + r + nc]);
                    }
        }
    }
}

/* Stage 2, per quad and level: the extended grid of quad q (own cells, ghosts, corners). */
static void recon_extend(const wrt_recon *rc, int q, int m, int w, int nc, const float *a, float *ext,
                         float *buf, int nm, size_t pyr_n, size_t full, int cur_half) {
    /* The extended grid: own cells, ghost rows from the neighbours or extrapolated. */
    for (int j = 0; j < m; j++)
        memcpy(ext + ((size_t)(j + 1) * w + 1) * nc, a + (size_t)j * m * nc, (size_t)m * nc * sizeof(float));
    for (int e = 0; e < 4; e++) {
        int o = rc->nb[q][e];
        const float *b = o >= 0 ? CUR(rc->slot[o]) : NULL;
        for (int k = 0; k < m; k++) {
            size_t gi; /* ghost position in ext, and the inner cells beside it */
            size_t in0 = edge_cell(e, m, k), in1;
            switch (e) {
            case 0: gi = (size_t)k + 1; in1 = in0 + m; break;
            case 1: gi = (size_t)(k + 1) * w + m + 1; in1 = in0 - 1; break;
            case 2: gi = (size_t)(m + 1) * w + k + 1; in1 = in0 - m; break;
            default: gi = (size_t)(k + 1) * w; in1 = in0 + 1; break;
            }
            float *g = ext + gi * nc;
            if (b) {
                const float *src = b + edge_cell(rc->nbe[q][e], m, rc->flip[q][e] ? m - 1 - k : k) * nc;
                memcpy(g, src, nc * sizeof(float));
            } else if (m >= 2) {
                for (int ch = 0; ch < nc; ch++) g[ch] = 2 * a[in0 * nc + ch] - a[in1 * nc + ch];
            } else {
                memcpy(g, a + in0 * nc, nc * sizeof(float));
            }
        }
    }
    /* Corners of the extended grid: bilinear extrapolation from the ghosts. */
    static const int cx[4] = {0, 1, 1, 0}, cy[4] = {0, 0, 1, 1};
    for (int k = 0; k < 4; k++) {
        int gx = cx[k] ? m + 1 : 0, gy = cy[k] ? m + 1 : 0, ix = cx[k] ? m : 1, iy = cy[k] ? m : 1;
        float *g = ext + ((size_t)gy * w + gx) * nc;
        const float *eu = ext + ((size_t)iy * w + gx) * nc, *ev = ext + ((size_t)gy * w + ix) * nc,
                    *ai = ext + ((size_t)iy * w + ix) * nc;
        for (int ch = 0; ch < nc; ch++) g[ch] = eu[ch] + ev[ch] - ai[ch];
    }
}

#ifdef __SSE4_1__
/* Three channels in one SSE register: the fourth lane is loaded (the next value, or the
 * scratch's padding) and never stored. Every lane does the scalar code's operations in
 * its order (no FMA at -march=x86-64-v2), so the texels are the same bits. */
static inline void st3(float *p, __m128 v) {
    _mm_storel_pi((__m64 *)p, v);
    _mm_store_ss(p + 2, _mm_movehl_ps(v, v));
}

/* minmod3 lane by lane: MINPS and MAXPS are the scalar ?: (a < b ? a : b, a > b ? a : b). */
static inline __m128 minmod3v(__m128 a, __m128 b, __m128 c) {
    __m128 z = _mm_setzero_ps();
    __m128 pos = _mm_and_ps(_mm_and_ps(_mm_cmpgt_ps(a, z), _mm_cmpgt_ps(b, z)), _mm_cmpgt_ps(c, z));
    __m128 neg = _mm_and_ps(_mm_and_ps(_mm_cmplt_ps(a, z), _mm_cmplt_ps(b, z)), _mm_cmplt_ps(c, z));
    __m128 mn = _mm_min_ps(_mm_min_ps(a, b), c), mx = _mm_max_ps(_mm_max_ps(a, b), c);
    return _mm_or_ps(_mm_and_ps(pos, mn), _mm_and_ps(neg, mx));
}

/* The smooth prediction of recon_children for one cell, RGB at once. */
static inline void children3(const float *c, size_t ws, int limit, float *o0, float *o1) {
    const __m128 av = _mm_loadu_ps(c), E = _mm_loadu_ps(c + 3), W = _mm_loadu_ps(c - 3);
    const __m128 N = _mm_loadu_ps(c + ws), S = _mm_loadu_ps(c - ws);
    __m128 dx = _mm_mul_ps(_mm_sub_ps(E, W), _mm_set1_ps(0.125f));
    __m128 dy = _mm_mul_ps(_mm_sub_ps(N, S), _mm_set1_ps(0.125f));
    __m128 dxy = _mm_add_ps(_mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(c + ws + 3), _mm_loadu_ps(c + ws - 3)),
                                       _mm_loadu_ps(c + 3 - ws)), _mm_loadu_ps(c - 3 - ws));
    dxy = _mm_mul_ps(dxy, _mm_set1_ps(1.0f / 64));
    if (limit) {
        const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), q = _mm_set1_ps(0.25f);
        __m128 lx = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, W)), _mm_mul_ps(half, _mm_sub_ps(E, W)),
                                        _mm_mul_ps(two, _mm_sub_ps(E, av))), q);
        __m128 ly = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, S)), _mm_mul_ps(half, _mm_sub_ps(N, S)),
                                        _mm_mul_ps(two, _mm_sub_ps(N, av))), q);
        dxy = _mm_andnot_ps(_mm_or_ps(_mm_cmpneq_ps(lx, dx), _mm_cmpneq_ps(ly, dy)), dxy);
        dx = lx;
        dy = ly;
    }
    __m128 am = _mm_sub_ps(av, dx), ap = _mm_add_ps(av, dx);
    st3(o0, _mm_add_ps(_mm_sub_ps(am, dy), dxy));
    st3(o0 + 3, _mm_sub_ps(_mm_sub_ps(ap, dy), dxy));
    st3(o1, _mm_sub_ps(_mm_add_ps(am, dy), dxy));
    st3(o1 + 3, _mm_add_ps(_mm_add_ps(ap, dy), dxy));
}
#endif

/* Stage 3, per quad and level: quad s's children at level l + 1 from its extended grid. */
static void recon_children(int s, int q, int l, int L, int m, int w, int nc, const float *ext, float *nx,
                           const uint8_t *const *known, const float *buf, size_t pyr_n, int keep, float sharp,
                           int limit) {
    /* Children: two output rows per input row. */
    const float *pyr = buf + (size_t)s * pyr_n;
    const float *pl = l < L ? pyr + (((size_t)1 << (2 * l)) - 1) / 3 * nc : NULL;
    const float *pc = l < L ? pyr + (((size_t)1 << (2 * (l + 1))) - 1) / 3 * nc : NULL;
    const uint8_t *kn = l < L && known && known[q] ? known[q] + wrt_recon_node(l, 0, 0) : NULL;
    int m2 = 2 * m, all_known = l < L && !kn;
    size_t rs = (size_t)m2 * nc, ws = (size_t)w * nc; /* output and ext row strides */
    for (int j = 0; j < m; j++) {
        const float *rowc = ext + ((size_t)(j + 1) * w + 1) * nc;
        float *o0 = nx + (size_t)(2 * j) * rs, *o1 = o0 + rs;
        const float *p0 = pc ? pc + (size_t)(2 * j) * rs : NULL, *p1 = p0 ? p0 + rs : NULL;
        for (int i = 0; i < m; i++) {
            const float *c = rowc + (size_t)i * nc;
            size_t x0 = (size_t)(2 * i) * nc, x1 = x0 + nc;
            int is_known = all_known || (kn && kn[(size_t)j * m + i]);
            if (is_known && l >= keep) /* past `keep`: only the details the prediction misses */
                is_known = sharp > 0 && details_missed(c, nc, ws, pl + ((size_t)j * m + i) * nc, p0 + x0, p1 + x0, pyr) > sharp;
#ifdef __SSE4_1__
            if (nc == 3) {
                if (!is_known) { children3(c, ws, limit, o0 + x0, o1 + x0); continue; }
                __m128 dv = _mm_sub_ps(_mm_loadu_ps(c), _mm_loadu_ps(pl + ((size_t)j * m + i) * 3));
                st3(o0 + x0, _mm_add_ps(_mm_loadu_ps(p0 + x0), dv));
                st3(o0 + x1, _mm_add_ps(_mm_loadu_ps(p0 + x1), dv));
                st3(o1 + x0, _mm_add_ps(_mm_loadu_ps(p1 + x0), dv));
                st3(o1 + x1, _mm_add_ps(_mm_loadu_ps(p1 + x1), dv));
                continue;
            }
#endif
            if (is_known) {
                for (int ch = 0; ch < nc; ch++) {
                    float dv = c[ch] - pl[((size_t)j * m + i) * nc + ch];
                    o0[x0 + ch] = p0[x0 + ch] + dv;
                    o0[x1 + ch] = p0[x1 + ch] + dv;
                    o1[x0 + ch] = p1[x0 + ch] + dv;
                    o1[x1 + ch] = p1[x1 + ch] + dv;
                }
                continue;
            }
            for (int ch = 0; ch < nc; ch++) {
                float av = c[ch], E = c[nc + ch], W = c[ch - nc], N = c[ws + ch], S = c[ch - ws];
                float dx = (E - W) * 0.125f, dy = (N - S) * 0.125f;
                float dxy = (c[ws + nc + ch] - c[ws - nc + ch] - c[ch + nc - ws] + c[ch - nc - ws]) * (1.0f / 64);
                if (limit) { /* no new extremum: a dark cell beside a lit one stays dark */
                    float lx = minmod3(2 * (av - W), 0.5f * (E - W), 2 * (E - av)) * 0.25f;
                    float ly = minmod3(2 * (av - S), 0.5f * (N - S), 2 * (N - av)) * 0.25f;
                    if (lx != dx || ly != dy) dxy = 0;
                    dx = lx;
                    dy = ly;
                }
                o0[x0 + ch] = av - dx - dy + dxy;
                o0[x1 + ch] = av + dx - dy - dxy;
                o1[x0 + ch] = av - dx + dy - dxy;
                o1[x1 + ch] = av + dx + dy + dxy;
            }
        }
    }
}

/* Stage 4: the output, with shared edges and corners averaged across the group. */
static void recon_output(const wrt_recon *rc, int nm, const int *mem, int Lo, int nc, float *const *out,
                         float *buf, size_t pyr_n, size_t full, int cur_half) {
    /* Output: shared-edge texels the mean of the two cells beside the edge, corner texels
     * the mean of the cells around the corner; everything else the finest averages. */
    int m = 1 << Lo;
    for (int s = 0; s < nm; s++) {
        int q = mem[s];
        const float *a = CUR(s);
        float *o = out[q];
        memcpy(o, a, full * sizeof(float));
        if (m < 2) continue;
        for (int e = 0; e < 4; e++) {
            int nbq = rc->nb[q][e];
            if (nbq < 0) continue;
            const float *b = CUR(rc->slot[nbq]);
            for (int k = 1; k < m - 1; k++) {
                size_t mi = edge_cell(e, m, k) * nc, ii = inner_cell(e, m, k) * nc;
                size_t bi = edge_cell(rc->nbe[q][e], m, rc->flip[q][e] ? m - 1 - k : k) * nc;
                for (int ch = 0; ch < nc; ch++) {
                    o[mi + ch] = 0.5f * (a[mi + ch] + b[bi + ch]);
                    if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
                }
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            if (cs->n < 2) continue;
            size_t mi = corner_cell(k, m) * nc, ii = corner_inner(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                float sum = 0;
                for (int t = 0; t < cs->n; t++) sum += CUR(rc->slot[cs->quad[t]])[corner_cell(cs->corner[t], m) * nc + ch];
                o[mi + ch] = sum / (float)cs->n;
                if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
            }
        }
    }
}

void wrt_recon_run_in(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                      const uint8_t *const *known, float *const *out, const wrt_recon_params *prm, float *buf) {
    int keep = prm ? prm->keep : WRT_RECON_KEEP, limit = prm ? prm->limit : 1, linear = prm ? prm->linear : 0;
    int facets = prm ? prm->facets : 0;
    float sharp = prm ? prm->sharp : WRT_RECON_SHARP;
    if (linear) { /* a choice from the mask and `keep` alone */
        limit = 0;
        sharp = 0;
    }
    int nm;
    const int *mem = wrt_recon_members(rc, gr, &nm);
    if (nm == 0) return;
    size_t pyr_n = (((size_t)1 << (2 * (L + 1))) - 1) / 3 * nc; /* levels 0..L */
    size_t full = ((size_t)1 << (2 * Lo)) * nc;
    float *ext = buf + (size_t)nm * (pyr_n + 2 * full);
    recon_pyramids(nm, mem, L, nc, in, buf, pyr_n);
    int cur_half = 0;
    for (int s = 0; s < nm; s++) memcpy(CUR(s), buf + (size_t)s * pyr_n, nc * sizeof(float));
    for (int l = 0; l < Lo; l++) {
        int m = 1 << l, w = m + 2;
        for (int s = 0; s < nm; s++) {
            int q = mem[s];
            const float *a = CUR(s);
            float *nx = NXT(s);
            recon_extend(rc, q, m, w, nc, a, ext, buf, nm, pyr_n, full, cur_half);
            /* a curved quad's cells are a flat facet's: its mean, and the details the unlimited
             * prediction misses by more than half of `sharp` (blender_smooth q3, one light,
             * image error 13.25% before; sharp / 2 13.31%, sharp 13.47%, 0.3 sharp 13.30%
             * with faint facets again; the path tracer shades the flat facets) */
            int curved = rc->curved[q] && !facets;
            recon_children(s, q, l, L, m, w, nc, ext, nx, known, buf, pyr_n, curved ? 0 : keep,
                           curved ? 0.5f * sharp : sharp, curved ? 0 : limit);
        }
        cur_half = 1 - cur_half;
    }
    recon_output(rc, nm, mem, Lo, nc, out, buf, pyr_n, full, cur_half);
    /* Light is never negative: the prediction can undershoot beside a sharp edge (the
     * linear display keeps the undershoot: a clamp does not superpose). */
    for (int s = 0; s < nm && !linear; s++) {
        float *o = out[mem[s]];
        size_t k = 0;
#ifdef __SSE4_1__
        /* MAXPS(0, x) is 0 > x ? 0 : x: the scalar clamp's bits, NaN and -0 kept */
        for (; k + 4 <= full; k += 4) _mm_storeu_ps(o + k, _mm_max_ps(_mm_setzero_ps(), _mm_loadu_ps(o + k)));
#endif
        for (; k < full; k++) o[k] = o[k] < 0 ? 0 : o[k];
    }
#undef CUR
#undef NXT
}
