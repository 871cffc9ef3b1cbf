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

#define MAX_TREF 4    /* edges of other quads passing through one corner (a T-junction's vertex) */

/* The quads around a corner, and the edges it lies inside of (a T-junction: the vertex
 * where a triangle's two half-edges meet lies inside the paired quad's whole edge): each
 * T-reference is quad tquad's edge tedge at its parameter ts. */
typedef struct corner_set {
    int n, nt;
    int quad[MAX_AROUND], corner[MAX_AROUND];
    int tquad[MAX_TREF], tedge[MAX_TREF];
    double ts[MAX_TREF];
} corner_set;

/* A neighbour along a part of an edge (a T-junction, or any overlap of two collinear
 * edges that do not share both ends): the overlap is [t0, t1] (t0 < t1) on this edge, in
 * its parameter (0 at E_END[e][0], 1 at E_END[e][1]), and runs from s0 to s1 on the
 * neighbour's edge f, in that edge's parameter. */
typedef struct part_nb { int o, f, bent; double t0, t1, s0, s1; } part_nb; /* bent: joined by the corner normals */

struct wrt_recon {
    int n, ngroups;
    int (*nb)[4], (*nbe)[4], (*flip)[4];
    uint8_t (*bent)[4];          /* the edge's neighbour was joined by the corner normals */
    uint8_t *curved;             /* joined to a neighbour across a bent edge (corner normals) */
    int *group, *slot;           /* slot: position within its group */
    int *gfirst, *gquads;        /* members of group g: gquads[gfirst[g] .. gfirst[g+1]) */
    corner_set (*around)[4];     /* quads around each corner (itself included), ascending */
    int *pfirst;                 /* edge e of quad q: its partial neighbours pnb[pfirst[4q+e] .. pfirst[4q+e+1]) */
    part_nb *pnb;                /* ascending quad, edge, t0 */
    /* The vertex blend (groups with a curved quad; NULL without normals): each member's
     * smooth source (a triangle's part: its triangle; a paired quad: its corners), its
     * vertices numbered within the group, and the weight the member's mean gives each of
     * them (its interior angle at that vertex where it is one of its own corners, else 0). */
    uint8_t *bkind;              /* 0: no blend (the group has no curved quad), 3: a triangle's part, 4: a paired quad */
    uint8_t *bshow;              /* 1: shows the blend (curved, or its corner normals leave its plane) */
    int (*bvid)[4];
    float (*bw)[4];
    int *gnv;                    /* group g's source vertices (0: the group is not blended) */
    uint8_t *gall;               /* 1: every member of group g shows the blend (only the means are read) */
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
static int partial_pair(int n, const double (*corners)[4][3], const v3 *nrm, double tol, const float (*normals)[4][3],
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
    if (edge_blocked(n, corners, q, o, p0, p1, tol)) return 0;
    part_nb x = {o, f, !coplanar, t0, t1, s0, s1};
    part_nb y = {q, e, !coplanar, s0 < s1 ? s0 : s1, s0 < s1 ? s1 : s0, s0 < s1 ? t0 : t1, s0 < s1 ? t1 : t0};
    *pq = x;
    *po = y;
    return 1;
}

/* Stage 2b: the partial neighbours of the edges left without a whole one (T-junctions:
 * a paired quad's whole edge against the two half-edges of a triangle's quads). Open
 * edges are swept along x; a pair is tested where their extents meet. -1 on out of memory. */
static int recon_partial(wrt_recon *rc, int n, const double (*corners)[4][3], const uint32_t *material, const v3 *nrm,
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
            if (!partial_pair(n, corners, nrm, tol, normals, cos_tol, u->q, u->e, w->q, w->e, &pq, &po)) continue;
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
    recon_neighbours(rc, n, corners, material, nrm, tol, normals, cos_tol);
    if (recon_partial(rc, n, corners, material, nrm, tol, normals, cos_tol) != 0) {
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

/* Quad o's edge row (the m cells along its edge f, at the current level, in b) as a
 * function of the edge's parameter: each cell its average plus a slope across it (central;
 * one-sided in the end cells; none when m = 1; MC-limited when `limit`), which keeps every
 * cell's average. Its mean over [sa, sb] (0 <= sa < sb <= 1) in channel ch: over whole
 * cells their mean, inside one cell the value at the range's centre (the along-edge part
 * of the children's prediction). */
static double row_mean(const float *b, int f, int m, int nc, int ch, double sa, double sb, int limit) {
    int k0 = (int)floor(sa * m), k1 = (int)ceil(sb * m) - 1;
    if (k0 < 0) k0 = 0;
    if (k1 > m - 1) k1 = m - 1;
    double acc = 0;
    for (int k = k0; k <= k1; k++) {
        double lo = fmax(sa, (double)k / m), hi = fmin(sb, (double)(k + 1) / m);
        if (!(hi > lo)) continue;
        double av = b[edge_cell(f, m, k) * nc + ch], sl = 0;
        if (m > 1) {
            double W = k > 0 ? b[edge_cell(f, m, k - 1) * nc + ch] : 0, E = k < m - 1 ? b[edge_cell(f, m, k + 1) * nc + ch] : 0;
            if (k == 0) sl = E - av;
            else if (k == m - 1) sl = av - W;
            else sl = limit ? minmod3((float)(2 * (av - W)), (float)(0.5 * (E - W)), (float)(2 * (E - av))) : 0.5 * (E - W);
        }
        acc += (hi - lo) * (av + sl * (0.5 * (lo + hi) * m - (k + 0.5)));
    }
    return acc / (sb - sa);
}

/* Quad o's edge row at parameter s, channel ch: linear between the cells' centres, the end
 * cells' values beyond them (what a clamped bilinear lookup shows along the edge). */
static double row_point(const float *b, int f, int m, int nc, int ch, double s) {
    double x = s * m - 0.5;
    if (x <= 0) return b[edge_cell(f, m, 0) * nc + ch];
    if (x >= m - 1) return b[edge_cell(f, m, m - 1) * nc + ch];
    int k = (int)floor(x);
    double t = x - k;
    return (1 - t) * b[edge_cell(f, m, k) * nc + ch] + t * b[edge_cell(f, m, k + 1) * nc + ch];
}

/* The partial neighbours of quad q's edge e over [ta, tb] of it, channel ch: their edge
 * rows' means over the matching ranges (cur + slot * stride: a member's cells at the
 * current level m), weighted by the lengths they cover; *cov the covered fraction of
 * [ta, tb] (0: none, the value 0). */
static double partial_mean(const wrt_recon *rc, int q, int e, int m, int nc, int ch, double ta, double tb, int limit,
                           const float *cur, size_t stride, double *cov) {
    double acc = 0, c = 0;
    for (int k = rc->pfirst[4 * q + e]; k < rc->pfirst[4 * q + e + 1]; k++) {
        const part_nb *p = &rc->pnb[k];
        double lo = fmax(ta, p->t0), hi = fmin(tb, p->t1);
        if (!(hi > lo)) continue;
        double r = (p->s1 - p->s0) / (p->t1 - p->t0);
        double sa = p->s0 + (lo - p->t0) * r, sb = p->s0 + (hi - p->t0) * r;
        if (sa > sb) { double t = sa; sa = sb; sb = t; }
        sa = fmax(sa, 0);
        sb = fmin(sb, 1);
        if (!(sb > sa)) continue;
        acc += (hi - lo) * row_mean(cur + (size_t)rc->slot[p->o] * stride, p->f, m, nc, ch, sa, sb, limit);
        c += hi - lo;
    }
    *cov = c / (tb - ta);
    return c > 0 ? acc / c : 0;
}

size_t wrt_recon_scratch(const wrt_recon *rc, int gr, int L, int Lo, int nc) {
    int nm;
    wrt_recon_members(rc, gr, &nm);
    size_t pyr_n = (((size_t)1 << (2 * (L + 1))) - 1) / 3 * nc; /* levels 0..L */
    size_t full = ((size_t)1 << (2 * Lo)) * nc;
    size_t ext_n = (((size_t)1 << Lo) + 2) * (((size_t)1 << Lo) + 2) * nc;
    size_t blend_n = rc->gnv && gr >= 0 && gr < rc->ngroups ? (size_t)rc->gnv[gr] * (nc + 1) + (size_t)nm * 4 * nc : 0;
    return (size_t)nm * (pyr_n + 2 * full) + (ext_n > blend_n ? ext_n : blend_n) + 4; /* + 4: the RGB loads' fourth lane */
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
                         float *buf, int nm, size_t pyr_n, size_t full, int cur_half, int limit) {
    /* The extended grid: own cells, ghost rows from the neighbours or extrapolated. */
    for (int j = 0; j < m; j++)
        memcpy(ext + ((size_t)(j + 1) * w + 1) * nc, a + (size_t)j * m * nc, (size_t)m * nc * sizeof(float));
    for (int e = 0; e < 4; e++) {
        int o = rc->nb[q][e];
        const float *b = o >= 0 ? CUR(rc->slot[o]) : NULL;
        int part = o < 0 && rc->pfirst[4 * q + e] < rc->pfirst[4 * q + e + 1];
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
            double cov = 0;
            if (part) /* a T-junction: the neighbours' cells over the same stretch of the edge */
                for (int ch = 0; ch < nc && (ch == 0 || cov >= 0.5); ch++)
                    g[ch] = (float)partial_mean(rc, q, e, m, nc, ch, (double)k / m, (double)(k + 1) / m, limit,
                                                CUR(0), 2 * full, &cov);
            if (b) {
                const float *src = b + edge_cell(rc->nbe[q][e], m, rc->flip[q][e] ? m - 1 - k : k) * nc;
                memcpy(g, src, nc * sizeof(float));
            } else if (cov >= 0.5) {
                continue;
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

/* 1 if quad q's edge e lies inside one longer edge of a partial neighbour (a triangle's
 * half-edge against a paired quad's whole edge): its display follows the longer edge's. */
static int edge_inside(const wrt_recon *rc, int q, int e) {
    int k = rc->pfirst[4 * q + e];
    if (rc->nb[q][e] >= 0 || rc->pfirst[4 * q + e + 1] != k + 1) return 0;
    const part_nb *p = &rc->pnb[k];
    return p->t0 == 0 && p->t1 == 1 && fabs(p->s1 - p->s0) < 1;
}

/* Stage 4: the output, with shared edges and corners averaged across the group. */
static void recon_output(const wrt_recon *rc, int nm, const int *mem, int Lo, int nc, float *const *out,
                         float *buf, size_t pyr_n, size_t full, int cur_half, int limit) {
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
            if (nbq < 0 && rc->pfirst[4 * q + e] < rc->pfirst[4 * q + e + 1] && !edge_inside(rc, q, e)) {
                /* a longer edge at a T-junction: the mean of its cells and the shorter
                 * edges' beside the same stretch */
                for (int k = 1; k < m - 1; k++) {
                    size_t mi = edge_cell(e, m, k) * nc, ii = inner_cell(e, m, k) * nc;
                    double cov;
                    for (int ch = 0; ch < nc; ch++) {
                        double v = partial_mean(rc, q, e, m, nc, ch, (double)k / m, (double)(k + 1) / m, limit, CUR(0),
                                                2 * full, &cov);
                        if (cov < 0.5) break;
                        o[mi + ch] = (float)(0.5 * (a[mi + ch] + v));
                        if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
                    }
                }
            }
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
            if (cs->n < 2 || cs->nt) continue;
            size_t mi = corner_cell(k, m) * nc, ii = corner_inner(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                float sum = 0;
                for (int t = 0; t < cs->n; t++) sum += CUR(rc->slot[cs->quad[t]])[corner_cell(cs->corner[t], m) * nc + ch];
                o[mi + ch] = sum / (float)cs->n;
                if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
            }
        }
    }
    if (m < 2) return;
    /* Then the shorter edges at T-junctions show what the longer edge shows (its texels,
     * final now, read along it at each texel's position), and a T-junction's vertex its
     * value there: the texel centres of the two sides never line up, and the longer side's
     * display is the one both can show (a half-texel corner zone of each size, else). */
    for (int s = 0; s < nm; s++) {
        int q = mem[s];
        const float *a = CUR(s);
        float *o = out[q];
        for (int e = 0; e < 4; e++) {
            if (!edge_inside(rc, q, e)) continue;
            const part_nb *p = &rc->pnb[rc->pfirst[4 * q + e]];
            for (int k = 1; k < m - 1; k++) {
                size_t mi = edge_cell(e, m, k) * nc, ii = inner_cell(e, m, k) * nc;
                double sv = p->s0 + ((k + 0.5) / m) * (p->s1 - p->s0);
                for (int ch = 0; ch < nc; ch++) {
                    o[mi + ch] = (float)row_point(out[p->o], p->f, m, nc, ch, sv);
                    if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
                }
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            if (!cs->nt) continue;
            size_t mi = corner_cell(k, m) * nc, ii = corner_inner(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                double ts = 0;
                for (int t = 0; t < cs->nt; t++) ts += row_point(out[cs->tquad[t]], cs->tedge[t], m, nc, ch, cs->ts[t]);
                o[mi + ch] = (float)(ts / cs->nt);
                if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
            }
        }
    }
}

/* The position of texel i of m along u or v for the vertex blend: the edge itself for the
 * edge texels (what a clamped bilinear lookup shows at the edge, so that both sides show
 * the same value there), the texel's centre inside. */
static double blend_pos(int i, int m) {
    return m == 1 ? 0.5 : i == 0 ? 0 : i == m - 1 ? 1 : (i + 0.5) / m;
}

/* Corner values cv (4 x nc) bilinearly at (u, v), channel ch. */
static float blend_at(const float *cv, int nc, int ch, double u, double v) {
    return (float)((1 - u) * (1 - v) * cv[ch] + u * (1 - v) * cv[nc + ch] + u * v * cv[2 * nc + ch] +
                   (1 - u) * v * cv[3 * nc + ch]);
}

/* 1 if quad q's edge e borders a quad that shows the vertex blend (a whole or a partial neighbour). */
static int edge_to_blend(const wrt_recon *rc, int q, int e) {
    if (rc->nb[q][e] >= 0) return rc->bshow[rc->nb[q][e]];
    for (int k = rc->pfirst[4 * q + e]; k < rc->pfirst[4 * q + e + 1]; k++)
        if (rc->bshow[rc->pnb[k].o]) return 1;
    return 0;
}

/* Stage 5, a group with a curved quad: the vertex blend. Each source vertex takes the
 * mean of the members' means around it, weighted by their interior angles there (the
 * weights of the mesh's vertex normals); a quad that shows the blend (bshow) shows that of
 * its source's vertex values (barycentric over a triangle, bilinear over a paired quad;
 * bilinear in the part's (u, v) is exact, the weights being affine in the position),
 * sampled at blend_pos, so that the two sides of a whole shared edge hold the same values.
 * A shorter edge inside a longer one (a T-junction) then shows the longer edge's display,
 * as in recon_output. Any other member's texels on an edge or corner it shares with a
 * blended quad show the blend of its own source there (the same values: the blend is
 * continuous); nothing is given back inside (no member's mean is kept: a facet's own
 * light is spread to its vertices). tmp: blend_n floats (wrt_recon_scratch). */
static void recon_blend(const wrt_recon *rc, int gr, int nm, const int *mem, int Lo, int nc, float *const *out,
                        const float *buf, size_t pyr_n, float *tmp) {
    static const float W3[4][3] = {{1, 0, 0}, {0.5f, 0.5f, 0}, {1.0f / 3, 1.0f / 3, 1.0f / 3}, {0.5f, 0, 0.5f}};
    int nv = rc->gnv[gr], m = 1 << Lo;
    float *vs = tmp, *vw = tmp + (size_t)nv * nc, *cv = vw + nv;
    memset(vs, 0, ((size_t)nv * (nc + 1)) * sizeof(float));
    for (int s = 0; s < nm; s++) { /* the means: level 0 of each member's pyramid */
        int q = mem[s];
        const float *mean = buf + (size_t)s * pyr_n;
        for (int i = 0; i < rc->bkind[q]; i++) {
            float w = rc->bw[q][i];
            if (!(w > 0)) continue;
            int v = rc->bvid[q][i];
            for (int ch = 0; ch < nc; ch++) vs[(size_t)v * nc + ch] += w * mean[ch];
            vw[v] += w;
        }
    }
    for (int s = 0; s < nm; s++) { /* each member's corner values */
        int q = mem[s], k3 = rc->bkind[q] == 3;
        const float *mean = buf + (size_t)s * pyr_n;
        float *c = cv + (size_t)s * 4 * nc;
        for (int k = 0; k < 4; k++)
            for (int ch = 0; ch < nc; ch++) {
                double acc = 0;
                for (int i = 0; i < rc->bkind[q]; i++) {
                    double wi = k3 ? W3[k][i] : (i == k);
                    if (wi == 0) continue;
                    int v = rc->bvid[q][i];
                    acc += wi * (vw[v] > 0 ? vs[(size_t)v * nc + ch] / vw[v] : mean[ch]);
                }
                c[k * nc + ch] = (float)acc;
            }
    }
    for (int s = 0; s < nm; s++) {
        int q = mem[s];
        const float *c = cv + (size_t)s * 4 * nc;
        float *o = out[q];
        if (rc->bshow[q]) {
            for (int j = 0; j < m; j++)
                for (int i = 0; i < m; i++)
                    for (int ch = 0; ch < nc; ch++)
                        o[((size_t)j * m + i) * nc + ch] = blend_at(c, nc, ch, blend_pos(i, m), blend_pos(j, m));
            continue;
        }
        if (m < 2) continue;
        for (int e = 0; e < 4; e++) {
            if (!edge_to_blend(rc, q, e)) continue;
            for (int k = 1; k < m - 1; k++) {
                double t = blend_pos(k, m), u = e == 1 ? 1 : e == 3 ? 0 : t, v = e == 0 ? 0 : e == 2 ? 1 : t;
                size_t mi = edge_cell(e, m, k) * nc;
                for (int ch = 0; ch < nc; ch++) o[mi + ch] = blend_at(c, nc, ch, u, v);
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            int touch = 0;
            for (int t = 0; t < cs->n; t++) touch |= rc->bshow[cs->quad[t]];
            for (int t = 0; t < cs->nt; t++) touch |= rc->bshow[cs->tquad[t]];
            if (!touch) continue;
            size_t mi = corner_cell(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) o[mi + ch] = c[k * nc + ch];
        }
    }
    if (m < 2) return;
    for (int s = 0; s < nm; s++) { /* T-junctions: the shorter edges show the longer one's display */
        int q = mem[s];
        float *o = out[q];
        if (!rc->bshow[q]) continue;
        for (int e = 0; e < 4; e++) {
            if (!edge_inside(rc, q, e)) continue;
            const part_nb *p = &rc->pnb[rc->pfirst[4 * q + e]];
            for (int k = 1; k < m - 1; k++) {
                size_t mi = edge_cell(e, m, k) * nc;
                double sv = p->s0 + ((k + 0.5) / m) * (p->s1 - p->s0);
                for (int ch = 0; ch < nc; ch++) o[mi + ch] = (float)row_point(out[p->o], p->f, m, nc, ch, sv);
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            if (!cs->nt) continue;
            size_t mi = corner_cell(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                double ts = 0;
                for (int t = 0; t < cs->nt; t++) ts += row_point(out[cs->tquad[t]], cs->tedge[t], m, nc, ch, cs->ts[t]);
                o[mi + ch] = (float)(ts / cs->nt);
            }
        }
    }
}

/* Stages 2 to 5 for a group not wholly blended: the levels, the output, then the blend
 * where some member shows it. */
static void recon_levels(const wrt_recon *rc, int nm, const int *mem, int L, int Lo, int nc, const uint8_t *const *known,
                         float *const *out, float *buf, size_t pyr_n, size_t full, int keep, float sharp, int limit,
                         int facets, int blend, int gr) {
    float *ext = buf + (size_t)nm * (pyr_n + 2 * full);
    int cur_half = 0;
    for (int s = 0; s < nm; s++) memcpy(CUR(s), buf + (size_t)s * pyr_n, nc * sizeof(float));
    for (int l = 0; l < Lo; l++) {
        int m = 1 << l, w = m + 2;
        for (int s = 0; s < nm; s++) {
            int q = mem[s];
            const float *a = CUR(s);
            float *nx = NXT(s);
            recon_extend(rc, q, m, w, nc, a, ext, buf, nm, pyr_n, full, cur_half, limit);
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
    recon_output(rc, nm, mem, Lo, nc, out, buf, pyr_n, full, cur_half, limit);
    if (blend) recon_blend(rc, gr, nm, mem, Lo, nc, out, buf, pyr_n, ext);
}

void wrt_recon_run_in(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                      const uint8_t *const *known, float *const *out, const wrt_recon_params *prm, float *buf) {
    int keep = prm ? prm->keep : WRT_RECON_KEEP, limit = prm ? prm->limit : 1, linear = prm ? prm->linear : 0;
    int facets = prm ? prm->facets : 0, facet_means = prm ? prm->facet_means : 0;
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
    int blend = rc->gnv && rc->gnv[gr] > 0 && !facets && !facet_means;
    if (blend && rc->gall[gr]) /* every member shows the blend: only the means are read */
        recon_blend(rc, gr, nm, mem, Lo, nc, out, buf, pyr_n, ext);
    else
        recon_levels(rc, nm, mem, L, Lo, nc, known, out, buf, pyr_n, full, keep, sharp, limit, facets, blend, gr);
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
