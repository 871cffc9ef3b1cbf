/* reconstruct.c: the adjacency of the smooth single-level reconstruction (reconstruct.h):
 * neighbours, T-junctions, groups, corner sets and the vertex blend's set-up; the run is
 * reconstruct_run.c. */
#include "reconstruct.h"
#include "reconstruct_internal.h"

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

/* A uniform grid over the quads' boxes, each grown by tol, for the neighbour and the
 * blocked-edge searches: the quads whose grown box meets a query box, in ascending order
 * (the order the searches scanned every quad in, so the same results), without scanning
 * every quad: the scans made the create O(N^2) (a 53,122-element atrium did not open in
 * 5 minutes). A quad over more than QGRID_BIG cells is on a list every query returns. */
#define QGRID_BIG 64
typedef struct {
    const wrt_recon_allocator *al;
    double lo[3], h;
    int dim[3];
    int *start, *item; /* cell c's quads: item[start[c] .. start[c + 1]) */
    int *big, nbig;
    int *stamp, epoch; /* per quad: the query that last took it */
    int n;
    int *out;          /* edge_blocked's query's quads */
} qgrid;

static int cmp_int(const void *x, const void *y) {
    int a = *(const int *)x, b = *(const int *)y;
    return (a > b) - (a < b);
}

static void quad_box(const double (*c)[3], double tol, double *lo, double *hi) {
    for (int a = 0; a < 3; a++) {
        lo[a] = fmin(fmin(c[0][a], c[1][a]), fmin(c[2][a], c[3][a])) - tol;
        hi[a] = fmax(fmax(c[0][a], c[1][a]), fmax(c[2][a], c[3][a])) + tol;
    }
}

static int qg_cell(const qgrid *g, int a, double x) {
    double t = floor((x - g->lo[a]) / g->h);
    return !(t >= 0) ? 0 : t >= g->dim[a] ? g->dim[a] - 1 : (int)t;
}

/* The cells [i0, i1] of box lo-hi, per axis; their count */
static double qg_range(const qgrid *g, const double *lo, const double *hi, int *i0, int *i1) {
    double c = 1;
    for (int a = 0; a < 3; a++) {
        i0[a] = qg_cell(g, a, lo[a]);
        i1[a] = qg_cell(g, a, hi[a]);
        c *= i1[a] - i0[a] + 1;
    }
    return c;
}

static void qgrid_free(qgrid *g) {
    rc_free(g->al, g->start); rc_free(g->al, g->item); rc_free(g->al, g->big);
    rc_free(g->al, g->stamp); rc_free(g->al, g->out);
    memset(g, 0, sizeof *g);
}

/* 0, or -1 on out of memory */
static int qgrid_build(qgrid *g, int n, const double (*corners)[4][3], double tol, const wrt_recon_allocator *al) {
    memset(g, 0, sizeof *g);
    g->al = al;
    g->n = n;
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY}, mean = 0, blo[3], bhi[3];
    for (int a = 0; a < 3; a++) g->lo[a] = INFINITY;
    for (int q = 0; q < n; q++) {
        quad_box(corners[q], tol, blo, bhi);
        double ext = 0;
        for (int a = 0; a < 3; a++) {
            g->lo[a] = fmin(g->lo[a], blo[a]);
            hi[a] = fmax(hi[a], bhi[a]);
            ext = fmax(ext, bhi[a] - blo[a]);
        }
        mean += ext / n;
    }
    if (n == 0) for (int a = 0; a < 3; a++) g->lo[a] = hi[a] = 0;
    g->h = mean > 0 && isfinite(mean) ? mean : 1;
    for (;;) { /* at most about 4 cells a quad */
        double cells = 1;
        for (int a = 0; a < 3; a++) {
            double d = floor((hi[a] - g->lo[a]) / g->h) + 1;
            g->dim[a] = d > 1 && d < 1e6 ? (int)d : d >= 1e6 ? 1000000 : 1;
            cells *= g->dim[a];
        }
        if (cells <= 4.0 * n + 64) break;
        g->h *= 1.5;
    }
    size_t nc = (size_t)g->dim[0] * g->dim[1] * g->dim[2];
    g->start = rc_alloc(al, (nc + 1) * sizeof *g->start);
    g->stamp = rc_alloc(al, ((size_t)n + 1) * sizeof *g->stamp);
    g->out = rc_alloc(al, ((size_t)n + 1) * sizeof *g->out);
    g->big = rc_alloc(al, ((size_t)n + 1) * sizeof *g->big);
    if (!g->start || !g->stamp || !g->out || !g->big) { qgrid_free(g); return -1; }
    memset(g->start, 0, (nc + 1) * sizeof *g->start);
    memset(g->stamp, 0, ((size_t)n + 1) * sizeof *g->stamp);
    int i0[3], i1[3];
    size_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (int q = 0; q < n; q++) {
            quad_box(corners[q], tol, blo, bhi);
            if (qg_range(g, blo, bhi, i0, i1) > QGRID_BIG) {
                if (pass == 0) g->big[g->nbig++] = q;
                continue;
            }
            for (int z = i0[2]; z <= i1[2]; z++)
                for (int y = i0[1]; y <= i1[1]; y++)
                    for (int x = i0[0]; x <= i1[0]; x++) {
                        size_t c = ((size_t)z * g->dim[1] + y) * g->dim[0] + x;
                        if (pass == 0) g->start[c + 1]++;
                        else g->item[g->start[c]++] = q;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < nc; c++) g->start[c + 1] += g->start[c];
            total = g->start[nc];
            g->item = rc_alloc(al, (total ? total : 1) * sizeof *g->item);
            if (!g->item) { qgrid_free(g); return -1; }
        } else { /* start[c] now holds cell c's end: back to its start */
            for (size_t c = nc; c > 0; c--) g->start[c] = g->start[c - 1];
            g->start[0] = 0;
        }
    }
    return 0;
}

/* The quads whose grown box meets box lo-hi, ascending, into out; their number */
static int qgrid_query(qgrid *g, const double *lo, const double *hi, int *out) {
    if (++g->epoch == 0x7fffffff) {
        memset(g->stamp, 0, ((size_t)g->n + 1) * sizeof *g->stamp);
        g->epoch = 1;
    }
    int i0[3], i1[3], m = 0;
    qg_range(g, lo, hi, i0, i1);
    for (int z = i0[2]; z <= i1[2]; z++)
        for (int y = i0[1]; y <= i1[1]; y++)
            for (int x = i0[0]; x <= i1[0]; x++) {
                size_t c = ((size_t)z * g->dim[1] + y) * g->dim[0] + x;
                for (int k = g->start[c]; k < g->start[c + 1]; k++) {
                    int q = g->item[k];
                    if (g->stamp[q] != g->epoch) { g->stamp[q] = g->epoch; out[m++] = q; }
                }
            }
    for (int k = 0; k < g->nbig; k++) {
        int q = g->big[k];
        if (g->stamp[q] != g->epoch) { g->stamp[q] = g->epoch; out[m++] = q; }
    }
    qsort(out, (size_t)m, sizeof *out, cmp_int);
    return m;
}

/* 1 if some quad other than q and o has an edge lying along segment a-b (collinear and
 * overlapping it by more than tol): a wall or a box's side standing on the edge. Such an
 * edge lies within tol of the segment where they overlap, so its quad's grown box meets
 * the segment's box: the grid's quads there are all that can. */
static int edge_blocked(qgrid *g, const double (*corners)[4][3], int q, int o, v3 a, v3 b, double tol) {
    v3 d = sub(b, a);
    double l = len(d);
    if (!(l > 0)) return 1;
    double lo[3] = {fmin(a.x, b.x), fmin(a.y, b.y), fmin(a.z, b.z)}, hi[3] = {fmax(a.x, b.x), fmax(a.y, b.y), fmax(a.z, b.z)};
    int m = qgrid_query(g, lo, hi, g->out);
    for (int i = 0; i < m; i++) {
        int k = g->out[i];
        if (k == q || k == o) continue;
        for (int e = 0; e < 4; e++) {
            v3 c0 = mk(corners[k][E_END[e][0]]), c1 = mk(corners[k][E_END[e][1]]);
            if (line_dist(c0, a, b) > tol || line_dist(c1, a, b) > tol) continue;
            double t0 = dot(sub(c0, a), d) / l, t1 = dot(sub(c1, a), d) / l;
            double lo2 = fmax(fmin(t0, t1), 0), hi2 = fmin(fmax(t0, t1), l);
            if (hi2 - lo2 > tol) return 1;
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
static void recon_neighbours(wrt_recon *rc, qgrid *g, int *cand, int n, const double (*corners)[4][3], const uint32_t *material, v3 *nrm,
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
            /* a neighbour has a corner within tol of a: its grown box holds a */
            int m = qgrid_query(g, a, a, cand);
            for (int i = 0; i < m && rc->nb[q][e] < 0; i++) {
                int o = cand[i];
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
                    if (edge_blocked(g, corners, q, o, mk(a), mk(b), tol)) break;
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

/* ------------------------------------------------------------ T-junctions ---- */

/* An edge without a neighbour, with its extent along x (for the sweep). */
typedef struct open_edge { int q, e; double lo, hi, box[4]; } open_edge; /* box: y and z extents */
/* A partial neighbour of quad q's edge e, while they are collected. */
typedef struct part_entry { int q, e; part_nb p; } part_entry;

static int cmp_open(const void *x, const void *y) {
    const open_edge *a = x, *b = y;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->q != b->q) return a->q < b->q ? -1 : 1;
    return a->e - b->e;
}

static int cmp_part(const void *x, const void *y) {
    const part_entry *a = x, *b = y;
    if (a->q != b->q) return a->q < b->q ? -1 : 1;
    if (a->e != b->e) return a->e - b->e;
    if (a->p.t0 != b->p.t0) return a->p.t0 < b->p.t0 ? -1 : 1;
    if (a->p.o != b->p.o) return a->p.o < b->p.o ? -1 : 1;
    return a->p.f - b->p.f;
}

/* Parameter of point p on the line of segment a-b (0 at a, 1 at b), snapped to 0 or 1
 * within tol (world). */
static double seg_param(v3 p, v3 a, v3 b, double tol) {
    v3 d = sub(b, a);
    double l = len(d), t = dot(sub(p, a), d) / (l * l);
    if (fabs(t) * l <= tol) t = 0;
    else if (fabs(t - 1) * l <= tol) t = 1;
    return t;
}

static v3 seg_point(v3 a, v3 b, double t) {
    v3 r = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)};
    return r;
}

/* Quad q's corner normals interpolated along its edge e at parameter t, unit. */
static v3 edge_normal(const float (*normals)[4][3], int q, int e, double t) {
    const float *a = normals[q][E_END[e][0]], *b = normals[q][E_END[e][1]];
    v3 r = {(1 - t) * a[0] + t * b[0], (1 - t) * a[1] + t * b[1], (1 - t) * a[2] + t * b[2]};
    double l = len(r);
    if (l > 0) { r.x /= l; r.y /= l; r.z /= l; }
    return r;
}

static v3 quad_centre(const double (*c)[3]) {
    v3 r = {0.25 * (c[0][0] + c[1][0] + c[2][0] + c[3][0]), 0.25 * (c[0][1] + c[1][1] + c[2][1] + c[3][1]),
            0.25 * (c[0][2] + c[1][2] + c[2][2] + c[3][2])};
    return r;
}

/* 0, or 1 if quad q's edge e and quad o's edge f (same material, both without a whole
 * neighbour) are partial smooth neighbours: collinear, overlapping by more than tol but
 * not the same segment (that is the whole-edge rule's, which refused it), the two quads on
 * either side of the line, coplanar or with corner normals agreeing at both ends of the
 * overlap (no fold), and no other quad's edge along the overlap. Fills *pq (q's view) and
 * *po (o's view). */
static int partial_pair(qgrid *g, const double (*corners)[4][3], const v3 *nrm, double tol, const float (*normals)[4][3],
                        double cos_tol, int q, int e, int o, int f, part_nb *pq, part_nb *po) {
    v3 a = mk(corners[q][E_END[e][0]]), b = mk(corners[q][E_END[e][1]]);
    v3 c = mk(corners[o][E_END[f][0]]), d = mk(corners[o][E_END[f][1]]);
    double lab = len(sub(b, a)), lcd = len(sub(d, c));
    if (!(lab > tol) || !(lcd > tol) || line_dist(c, a, b) > tol || line_dist(d, a, b) > tol) return 0;
    double tc = seg_param(c, a, b, tol), td = seg_param(d, a, b, tol);
    if ((tc == 0 && td == 1) || (tc == 1 && td == 0)) return 0;
    double t0 = fmax(fmin(tc, td), 0), t1 = fmin(fmax(tc, td), 1);
    if (!((t1 - t0) * lab > tol)) return 0; /* a point at most */
    v3 dir = sub(b, a);
    if (dot(cross(sub(quad_centre(corners[q]), a), dir), cross(sub(quad_centre(corners[o]), a), dir)) >= 0) return 0;
    v3 p0 = seg_point(a, b, t0), p1 = seg_point(a, b, t1);
    double s0 = seg_param(p0, c, d, tol), s1 = seg_param(p1, c, d, tol);
    int coplanar = dot(nrm[q], nrm[o]) >= 1 - 1e-9;
    for (int k = 0; k < 4 && coplanar; k++)
        if (fabs(dot(sub(mk(corners[o][k]), a), nrm[q])) > tol) coplanar = 0;
    if (!coplanar) { /* a curved mesh's edge: the normals agree where the overlap starts and ends */
        if (!normals || dot(nrm[q], nrm[o]) < -0.5) return 0;
        if (dot(edge_normal(normals, q, e, t0), edge_normal(normals, o, f, s0)) < cos_tol ||
            dot(edge_normal(normals, q, e, t1), edge_normal(normals, o, f, s1)) < cos_tol) return 0;
    }
    if (edge_blocked(g, corners, q, o, p0, p1, tol)) return 0;
    part_nb x = {o, f, !coplanar, t0, t1, s0, s1};
    part_nb y = {q, e, !coplanar, s0 < s1 ? s0 : s1, s0 < s1 ? s1 : s0, s0 < s1 ? t0 : t1, s0 < s1 ? t1 : t0};
    *pq = x;
    *po = y;
    return 1;
}

/* Stage 2b: the partial neighbours of the edges left without a whole one (T-junctions:
 * a paired quad's whole edge against the two half-edges of a triangle's quads). Open
 * edges are swept along x; a pair is tested where their extents meet. -1 on out of memory. */
static int recon_partial(wrt_recon *rc, qgrid *g, int n, const double (*corners)[4][3], const uint32_t *material, const v3 *nrm,
                         double tol, const float (*normals)[4][3], double cos_tol) {
    const wrt_recon_allocator *al = &rc->al;
    size_t nopen = 0, cap = 16, np = 0;
    for (int q = 0; q < n; q++)
        for (int e = 0; e < 4; e++) nopen += rc->nb[q][e] < 0;
    open_edge *op = rc_alloc(al, (nopen ? nopen : 1) * sizeof *op);
    part_entry *pe = rc_alloc(al, cap * sizeof *pe);
    rc->pfirst = rc_alloc(al, ((size_t)4 * n + 1) * sizeof(int));
    if (!op || !pe || !rc->pfirst) { rc_free(al, op); rc_free(al, pe); return -1; }
    nopen = 0;
    for (int q = 0; q < n; q++)
        for (int e = 0; e < 4; e++) {
            if (rc->nb[q][e] >= 0) continue;
            const double *x0 = corners[q][E_END[e][0]], *x1 = corners[q][E_END[e][1]];
            open_edge oe = {q, e, fmin(x0[0], x1[0]) - tol, fmax(x0[0], x1[0]) + tol,
                            {fmin(x0[1], x1[1]) - tol, fmax(x0[1], x1[1]) + tol, fmin(x0[2], x1[2]) - tol,
                             fmax(x0[2], x1[2]) + tol}};
            op[nopen++] = oe;
        }
    qsort(op, nopen, sizeof *op, cmp_open);
    for (size_t i = 0; i < nopen; i++)
        for (size_t j = i + 1; j < nopen && op[j].lo <= op[i].hi; j++) {
            const open_edge *u = op[i].q < op[j].q || (op[i].q == op[j].q && op[i].e < op[j].e) ? &op[i] : &op[j];
            const open_edge *w = u == &op[i] ? &op[j] : &op[i];
            if (u->q == w->q || material[u->q] != material[w->q] || u->box[0] > w->box[1] || w->box[0] > u->box[1] ||
                u->box[2] > w->box[3] || w->box[2] > u->box[3]) continue;
            part_nb pq, po;
            if (!partial_pair(g, corners, nrm, tol, normals, cos_tol, u->q, u->e, w->q, w->e, &pq, &po)) continue;
            if (np + 2 > cap) {
                part_entry *grown = rc_alloc(al, 2 * cap * sizeof *pe);
                if (!grown) { rc_free(al, op); rc_free(al, pe); return -1; }
                memcpy(grown, pe, np * sizeof *pe);
                rc_free(al, pe);
                pe = grown;
                cap *= 2;
            }
            part_entry x = {u->q, u->e, pq}, y = {w->q, w->e, po};
            pe[np++] = x;
            pe[np++] = y;
        }
    rc_free(al, op);
    qsort(pe, np, sizeof *pe, cmp_part);
    rc->pnb = rc_alloc(al, (np ? np : 1) * sizeof *rc->pnb);
    if (!rc->pnb) { rc_free(al, pe); return -1; }
    size_t k = 0;
    for (int qe = 0; qe < 4 * n; qe++) {
        rc->pfirst[qe] = (int)k;
        while (k < np && 4 * pe[k].q + pe[k].e == qe) {
            rc->pnb[k] = pe[k].p;
            if (pe[k].p.bent) rc->curved[pe[k].q] = 1;
            k++;
        }
    }
    rc->pfirst[4 * n] = (int)k;
    rc_free(al, pe);
    return 0;
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
                for (int k = rc->pfirst[4 * x + e]; k < rc->pfirst[4 * x + e + 1]; k++) {
                    o = rc->pnb[k].o;
                    if (rc->group[o] < 0) { rc->group[o] = ng; stack[sp++] = o; }
                }
            }
        }
        ng++;
    }
    return ng;
}

static void corner_add(corner_set *cs, int o, int ok) {
    for (int s = 0; s < cs->n; s++)
        if (cs->quad[s] == o && cs->corner[s] == ok) return;
    if (cs->n < MAX_AROUND) { cs->quad[cs->n] = o; cs->corner[cs->n] = ok; cs->n++; }
}

/* A T-reference: the same edge from two sides keeps the smaller parameter (the same
 * point, up to rounding), so that every member of the set sums the same values. */
static void corner_add_t(corner_set *cs, int o, int f, double sv) {
    for (int s = 0; s < cs->nt; s++)
        if (cs->tquad[s] == o && cs->tedge[s] == f) { cs->ts[s] = fmin(cs->ts[s], sv); return; }
    if (cs->nt < MAX_TREF) { cs->tquad[cs->nt] = o; cs->tedge[cs->nt] = f; cs->ts[cs->nt] = sv; cs->nt++; }
}

/* Stage 4 (after the group lists): the quads around each corner, walking the smooth edges
 * (whole and partial). */
static void recon_corner_sets(wrt_recon *rc, int n) {
    for (int q = 0; q < n; q++)
        for (int k = 0; k < 4; k++) {
            corner_set *cs = &rc->around[q][k];
            cs->n = 1; cs->nt = 0; cs->quad[0] = q; cs->corner[0] = k;
            for (int h = 0; h < cs->n; h++) {
                int x = cs->quad[h], xk = cs->corner[h];
                for (int e = 0; e < 4; e++) {
                    int end = E_END[e][0] == xk ? 0 : E_END[e][1] == xk ? 1 : -1;
                    if (end < 0) continue;
                    int o = rc->nb[x][e];
                    if (o >= 0) corner_add(cs, o, E_END[rc->nbe[x][e]][rc->flip[x][e] ? 1 - end : end]);
                    /* a partial neighbour reaching this end: its corner there, or (a
                     * T-junction) the point inside its edge */
                    for (int p = rc->pfirst[4 * x + e]; p < rc->pfirst[4 * x + e + 1]; p++) {
                        const part_nb *pn = &rc->pnb[p];
                        if (end ? pn->t1 != 1 : pn->t0 != 0) continue;
                        double sv = end ? pn->s1 : pn->s0;
                        if (sv == 0 || sv == 1) corner_add(cs, pn->o, E_END[pn->f][sv == 1]);
                        else corner_add_t(cs, pn->o, pn->f, sv);
                    }
                }
            }
            for (int a = 1; a < cs->n; a++) /* ascending quad: the same sum from every side */
                for (int b = a; b > 0 && cs->quad[b - 1] > cs->quad[b]; b--) {
                    int t = cs->quad[b]; cs->quad[b] = cs->quad[b - 1]; cs->quad[b - 1] = t;
                    t = cs->corner[b]; cs->corner[b] = cs->corner[b - 1]; cs->corner[b - 1] = t;
                }
            for (int a = 1; a < cs->nt; a++) /* and ascending quad and edge */
                for (int b = a; b > 0 && cs->tquad[b - 1] * 4 + cs->tedge[b - 1] > cs->tquad[b] * 4 + cs->tedge[b]; b--) {
                    int t = cs->tquad[b]; cs->tquad[b] = cs->tquad[b - 1]; cs->tquad[b - 1] = t;
                    t = cs->tedge[b]; cs->tedge[b] = cs->tedge[b - 1]; cs->tedge[b - 1] = t;
                    double d = cs->ts[b]; cs->ts[b] = cs->ts[b - 1]; cs->ts[b - 1] = d;
                }
        }
}

/* A corner normal further than this cosine from its quad's normal leaves the plane: half a
 * degree, common/smooth.h's WRT_SMOOTH_COS (the .gto's normals section's rule). */
#define BLEND_COS (1 - 4e-5)

/* A source vertex while they are numbered: its group, position and (quad, vertex) slot. */
typedef struct src_point { int g, slot; double p[3]; } src_point;

static int cmp_src(const void *x, const void *y) {
    const src_point *a = x, *b = y;
    if (a->g != b->g) return a->g < b->g ? -1 : 1;
    if (a->p[0] != b->p[0]) return a->p[0] < b->p[0] ? -1 : 1;
    return a->slot - b->slot;
}

/* Angle at corner a between the directions to b and c. */
static double corner_angle(v3 a, v3 b, v3 c) {
    v3 u = sub(b, a), w = sub(c, a);
    return atan2(len(cross(u, w)), dot(u, w));
}

/* Stage 5 (with corner normals): the vertex blend's sources in every group that holds a
 * curved quad. A member is a triangle's part when its corner 2 is the centroid of the
 * triangle its corners 0, 1, 3 (a vertex and two edge midpoints) describe, as
 * common/smooth.c decides; the part's far vertices are 2 x midpoint - corner 0. Source
 * vertices within 10 x tol of each other in one group are one vertex. -1 on out of memory. */
static int recon_blend_setup(wrt_recon *rc, int n, const double (*corners)[4][3], const float (*normals)[4][3],
                             double tol) {
    const wrt_recon_allocator *al = &rc->al;
    size_t m = n > 0 ? (size_t)n : 1;
    rc->bkind = rc_alloc(al, m);
    rc->bshow = rc_alloc(al, m);
    rc->bvid = rc_alloc(al, m * sizeof *rc->bvid);
    rc->bw = rc_alloc(al, m * sizeof *rc->bw);
    rc->gnv = rc_alloc(al, ((size_t)rc->ngroups + 1) * sizeof(int));
    rc->gall = rc_alloc(al, (size_t)rc->ngroups + 1);
    uint8_t *gcurved = rc_alloc(al, (size_t)rc->ngroups + 1);
    src_point *sp = rc_alloc(al, 4 * m * sizeof *sp);
    if (!rc->gall || !rc->bkind || !rc->bshow || !rc->bvid || !rc->bw || !rc->gnv || !gcurved || !sp) {
        rc_free(al, gcurved); rc_free(al, sp);
        return -1;
    }
    memset(gcurved, 0, (size_t)rc->ngroups + 1);
    for (int q = 0; q < n; q++) gcurved[rc->group[q]] |= rc->curved[q];
    size_t np = 0;
    for (int q = 0; q < n; q++) {
        rc->bkind[q] = rc->bshow[q] = 0;
        for (int i = 0; i < 4; i++) rc->bvid[q][i] = -1, rc->bw[q][i] = 0;
        if (!gcurved[rc->group[q]]) continue;
        v3 p[4], fn = quad_normal(corners[q]);
        rc->bshow[q] = rc->curved[q];
        for (int k = 0; k < 4; k++) {
            p[k] = mk(corners[q][k]);
            v3 cn = {normals[q][k][0], normals[q][k][1], normals[q][k][2]};
            if (dot(cn, fn) < BLEND_COS) rc->bshow[q] = 1;
        }
        v3 g = {(2 * (p[1].x + p[3].x) - p[0].x) / 3, (2 * (p[1].y + p[3].y) - p[0].y) / 3,
                (2 * (p[1].z + p[3].z) - p[0].z) / 3};
        double size = len(sub(p[1], p[0])) + len(sub(p[3], p[0]));
        int part = len(sub(g, p[2])) <= 1e-6 * size;
        v3 src[4] = {p[0], p[1], p[2], p[3]};
        if (part) {
            v3 f1 = {2 * p[1].x - p[0].x, 2 * p[1].y - p[0].y, 2 * p[1].z - p[0].z};
            v3 f3 = {2 * p[3].x - p[0].x, 2 * p[3].y - p[0].y, 2 * p[3].z - p[0].z};
            src[1] = f1;
            src[2] = f3;
            rc->bw[q][0] = (float)corner_angle(p[0], p[1], p[3]);
        } else {
            for (int k = 0; k < 4; k++) rc->bw[q][k] = (float)corner_angle(p[k], p[(k + 1) % 4], p[(k + 3) % 4]);
        }
        rc->bkind[q] = part ? 3 : 4;
        for (int i = 0; i < rc->bkind[q]; i++) {
            src_point x = {rc->group[q], 4 * q + i, {src[i].x, src[i].y, src[i].z}};
            sp[np++] = x;
        }
    }
    qsort(sp, np, sizeof *sp, cmp_src);
    double tv = 10 * tol;
    for (int g = 0; g < rc->ngroups; g++) rc->gnv[g] = 0;
    for (size_t i = 0; i < np; i++) {
        int id = -1;
        for (size_t j = i; j-- > 0 && sp[j].g == sp[i].g && sp[i].p[0] - sp[j].p[0] <= tv;)
            if (fabs(sp[i].p[1] - sp[j].p[1]) <= tv && fabs(sp[i].p[2] - sp[j].p[2]) <= tv) {
                id = rc->bvid[sp[j].slot / 4][sp[j].slot % 4];
                break;
            }
        if (id < 0) id = rc->gnv[sp[i].g]++;
        rc->bvid[sp[i].slot / 4][sp[i].slot % 4] = id;
    }
    for (int g = 0; g < rc->ngroups; g++) rc->gall[g] = gcurved[g];
    for (int q = 0; q < n; q++) rc->gall[rc->group[q]] &= rc->bshow[q];
    rc_free(al, gcurved);
    rc_free(al, sp);
    return 0;
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
    qgrid grid;
    int *cand = rc_alloc(&al, ((size_t)n + 1) * sizeof *cand);
    if (!cand || qgrid_build(&grid, n, corners, tol, &al) != 0) {
        rc_free(&al, cand); rc_free(&al, nrm); rc_free(&al, stack); wrt_recon_destroy(rc);
        return NULL;
    }
    recon_neighbours(rc, &grid, cand, n, corners, material, nrm, tol, normals, cos_tol);
    int pst = recon_partial(rc, &grid, n, corners, material, nrm, tol, normals, cos_tol);
    qgrid_free(&grid);
    rc_free(&al, cand);
    if (pst != 0) {
        rc_free(&al, nrm); rc_free(&al, stack); wrt_recon_destroy(rc);
        return NULL;
    }
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
    if (normals && recon_blend_setup(rc, n, corners, normals, tol) != 0) {
        wrt_recon_destroy(rc);
        return NULL;
    }
    return rc;
}

void wrt_recon_destroy(wrt_recon *rc) {
    if (!rc) return;
    const wrt_recon_allocator al = rc->al;
    rc_free(&al, rc->nb); rc_free(&al, rc->nbe); rc_free(&al, rc->flip); rc_free(&al, rc->bent); rc_free(&al, rc->curved);
    rc_free(&al, rc->group); rc_free(&al, rc->slot);
    rc_free(&al, rc->gfirst); rc_free(&al, rc->gquads); rc_free(&al, rc->around);
    rc_free(&al, rc->pfirst); rc_free(&al, rc->pnb);
    rc_free(&al, rc->bkind); rc_free(&al, rc->bshow); rc_free(&al, rc->bvid); rc_free(&al, rc->bw); rc_free(&al, rc->gnv); rc_free(&al, rc->gall);
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

int wrt_recon_partial(const wrt_recon *rc, int q, int e, int i, int *nedge, double range[4]) {
    if (q < 0 || q >= rc->n || e < 0 || e > 3) return -1;
    int k = rc->pfirst[4 * q + e] + i;
    if (i < 0 || k >= rc->pfirst[4 * q + e + 1]) return -1;
    const part_nb *p = &rc->pnb[k];
    if (nedge) *nedge = p->f;
    if (range) { range[0] = p->t0; range[1] = p->t1; range[2] = p->s0; range[3] = p->s1; }
    return p->o;
}

int wrt_recon_neighbour(const wrt_recon *rc, int q, int e, int *nedge, int *flip) {
    if (q < 0 || q >= rc->n || e < 0 || e > 3) return -1;
    if (nedge) *nedge = rc->nbe[q][e];
    if (flip) *flip = rc->flip[q][e];
    return rc->nb[q][e];
}
