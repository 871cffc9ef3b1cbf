/* cluster.c: the cluster tree over the quads and the top-down linking of the bake's
 * `--clusters` mode (docs/clusters.md; clustering after Smits, Arvo and Greenberg 1994
 * and Sillion 1995, face clusters after Willmott et al. 1999).
 *
 * The tree: top-down, a node's quads are split first by orientation where their normals
 * spread (at the widest gap of the normal component that varies most, when that gap
 * passes 0.3), so that clusters of near-coplanar quads form below, then by the median
 * of their centroids along the widest axis. Leaves are single quads.
 *
 * The linking: from (root, root), a node is linked with itself through its children and
 * two disjoint nodes A, B as follows. Culled when all of B lies behind every quad of A or
 * the reverse (boxes and normal cones). Two single quads go to the per-pair DTO
 * (dto.c), with the occluder test of bake.c run on the quads the tree's boxes do not
 * rule out. Two clusters of diffuse quads of one albedo each, well separated (distance
 * of the bounding spheres' centres over the sum of radii at least 1.5), are sampled at
 * 8 x 8 area-weighted point pairs with a visibility ray each: every pair facing and
 * visible, and the per-point sums agreeing within 15% on both sides, make one cluster
 * link, T[phi_A][phi_B] = rho_B sqrt(a_A a_B) mean(cos cos / (pi d^2)); every ray blocked
 * drops the pair (no light); a mix of blocked and free rays, a pair seen edge-on or a
 * spread above the threshold splits the larger node (cluster_link.c). The top of the
 * recursion runs on one thread and hands the pairs of at most `grain` quads to all
 * threads as tasks, whose results are merged in task order (identical whatever the
 * thread count). Depends on bake_ctx.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cluster.h"

#define CL_ORIENT_GAP 0.3 /* normal-component gap that splits by orientation */

typedef struct key_q { double k; uint32_t q; } key_q;
static int cmp_kq(const void *pa, const void *pb) {
    const key_q *a = pa, *b = pb;
    if (a->k != b->k) return a->k < b->k ? -1 : 1;
    return a->q < b->q ? -1 : a->q > b->q;
}

static double comp(wrt_v3 v, int ax) { return ax == 0 ? v.x : ax == 1 ? v.y : v.z; }
static wrt_v3 centroid(const wrt_quad *q) {
    return v3_scale(v3_add(v3_add(q->p[0], q->p[1]), v3_add(q->p[2], q->p[3])), 0.25);
}

typedef struct key_rho { double r[3]; uint32_t q; } key_rho;
static int cmp_rho(const void *pa, const void *pb) {
    const key_rho *a = pa, *b = pb;
    for (int c = 0; c < 3; c++)
        if (a->r[c] != b->r[c]) return a->r[c] < b->r[c] ? -1 : 1;
    return a->q < b->q ? -1 : a->q > b->q;
}

/* --clusters-albedo-split: quads of several albedos are split by albedo, at the boundary
 * between two albedos nearest the middle; 0 if they have one albedo. */
static uint32_t split_albedo(const bake_ctx *b, uint32_t *perm, uint32_t lo, uint32_t hi) {
    uint32_t n = hi - lo;
    int one = 1;
    for (uint32_t i = lo + 1; i < hi && one; i++)
        one = memcmp(b->rho[perm[i]], b->rho[perm[lo]], sizeof b->rho[perm[lo]]) == 0;
    if (one) return 0;
    key_rho *k = wrt_xmalloc(n * sizeof *k);
    for (uint32_t i = 0; i < n; i++) {
        memcpy(k[i].r, b->rho[perm[lo + i]], sizeof k[i].r);
        k[i].q = perm[lo + i];
    }
    qsort(k, n, sizeof *k, cmp_rho);
    uint32_t best = 0, bd = UINT32_MAX;
    for (uint32_t i = 0; i < n; i++) {
        perm[lo + i] = k[i].q;
        if (i && memcmp(k[i].r, k[i - 1].r, sizeof k[i].r) != 0) {
            uint32_t d = i > n / 2 ? i - n / 2 : n / 2 - i;
            if (d < bd) { bd = d; best = i; }
        }
    }
    free(k);
    return lo + best;
}

/* Where to split perm[lo, hi) (sorted in place): the index of the right half's start. */
static uint32_t split_at(const bake_ctx *b, uint32_t *perm, uint32_t lo, uint32_t hi, key_q *tmp) {
    uint32_t n = hi - lo;
    if (b->opt.cluster_albedo_split) {
        uint32_t m = split_albedo(b, perm, lo, hi);
        if (m) return m;
    }
    double nmin[3] = {2, 2, 2}, nmax[3] = {-2, -2, -2}, cmin[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, cmax[3];
    for (int k = 0; k < 3; k++) cmax[k] = -HUGE_VAL;
    for (uint32_t i = lo; i < hi; i++) {
        const wrt_quad *q = &b->quads[perm[i]];
        wrt_v3 c = centroid(q);
        for (int k = 0; k < 3; k++) {
            nmin[k] = fmin(nmin[k], comp(q->n, k)); nmax[k] = fmax(nmax[k], comp(q->n, k));
            cmin[k] = fmin(cmin[k], comp(c, k)); cmax[k] = fmax(cmax[k], comp(c, k));
        }
    }
    int na = 0, ca = 0;
    for (int k = 1; k < 3; k++) {
        if (nmax[k] - nmin[k] > nmax[na] - nmin[na]) na = k;
        if (cmax[k] - cmin[k] > cmax[ca] - cmin[ca]) ca = k;
    }
    if (nmax[na] - nmin[na] > CL_ORIENT_GAP) { /* orientation: the widest gap */
        for (uint32_t i = 0; i < n; i++) tmp[i] = (key_q){comp(b->quads[perm[lo + i]].n, na), perm[lo + i]};
        qsort(tmp, n, sizeof *tmp, cmp_kq);
        double gap = 0;
        uint32_t at = 0;
        for (uint32_t i = 1; i < n; i++)
            if (tmp[i].k - tmp[i - 1].k > gap) { gap = tmp[i].k - tmp[i - 1].k; at = i; }
        if (gap > CL_ORIENT_GAP) {
            for (uint32_t i = 0; i < n; i++) perm[lo + i] = tmp[i].q;
            return lo + at;
        }
    }
    for (uint32_t i = 0; i < n; i++) tmp[i] = (key_q){comp(centroid(&b->quads[perm[lo + i]]), ca), perm[lo + i]};
    qsort(tmp, n, sizeof *tmp, cmp_kq);
    for (uint32_t i = 0; i < n; i++) perm[lo + i] = tmp[i].q;
    return lo + n / 2;
}

/* The node's box, area, normal cone and albedo from its quads. */
static void node_summary(const bake_ctx *b, wrt_clusters *cl, uint32_t p) {
    wrt_v3 lo = v3(HUGE_VAL, HUGE_VAL, HUGE_VAL), hi = v3(-HUGE_VAL, -HUGE_VAL, -HUGE_VAL), ns = v3(0, 0, 0);
    double area = 0;
    int uni = 1;
    for (uint32_t i = cl->lo[p]; i < cl->hi[p]; i++) {
        int qi = (int)cl->perm[i];
        const wrt_quad *q = &b->quads[qi];
        for (int k = 0; k < 4; k++) {
            lo = v3(fmin(lo.x, q->p[k].x), fmin(lo.y, q->p[k].y), fmin(lo.z, q->p[k].z));
            hi = v3(fmax(hi.x, q->p[k].x), fmax(hi.y, q->p[k].y), fmax(hi.z, q->p[k].z));
        }
        ns = v3_add(ns, v3_scale(q->n, q->area));
        area += q->area;
        if (b->alevel[q->material] || memcmp(b->rho[qi], b->rho[cl->perm[cl->lo[p]]], sizeof b->rho[qi]) != 0) uni = 0;
    }
    double len = v3_len(ns), cw = 1;
    wrt_v3 axis = len > 1e-9 * area ? v3_scale(ns, 1 / len) : v3(0, 0, 0);
    for (uint32_t i = cl->lo[p]; i < cl->hi[p]; i++) cw = fmin(cw, v3_dot(b->quads[cl->perm[i]].n, axis));
    cl->bmin[p] = lo; cl->bmax[p] = hi; cl->axis[p] = axis; cl->cosw[p] = cw;
    cl->tree.area[p] = area;
    cl->uniform[p] = (uint8_t)uni;
    for (int c = 0; c < 3; c++) cl->rho[p][c] = (float)b->rho[cl->perm[cl->lo[p]]][c];
}

typedef struct build_ctx { const bake_ctx *b; wrt_clusters *cl; uint32_t next; key_q *tmp; } build_ctx;

static uint32_t build_node(build_ctx *bc, uint32_t lo, uint32_t hi) {
    wrt_clusters *cl = bc->cl;
    uint32_t p = bc->next++;
    cl->lo[p] = lo; cl->hi[p] = hi;
    if (hi - lo == 1) {
        cl->tree.left[p] = -1;
        cl->tree.right[p] = (int32_t)cl->perm[lo];
    } else {
        uint32_t m = split_at(bc->b, cl->perm, lo, hi, bc->tmp);
        cl->tree.left[p] = (int32_t)build_node(bc, lo, m);
        cl->tree.right[p] = (int32_t)build_node(bc, m, hi);
    }
    node_summary(bc->b, cl, p);
    return p;
}

void wrt_clusters_build(const bake_ctx *b, wrt_clusters *cl) {
    memset(cl, 0, sizeof *cl);
    uint32_t nq = (uint32_t)b->nq;
    if (wrt_ctree_alloc(&cl->tree, nq) != WRT_OK) abort(); /* the bake's allocations abort (wrt_xmalloc) */
    size_t nn = cl->tree.nnodes ? cl->tree.nnodes : 1;
    cl->perm = wrt_xmalloc((nq ? nq : 1) * sizeof *cl->perm);
    for (uint32_t q = 0; q < nq; q++) cl->perm[q] = q;
    cl->lo = wrt_xmalloc(nn * sizeof *cl->lo); cl->hi = wrt_xmalloc(nn * sizeof *cl->hi);
    cl->bmin = wrt_xmalloc(nn * sizeof *cl->bmin); cl->bmax = wrt_xmalloc(nn * sizeof *cl->bmax);
    cl->axis = wrt_xmalloc(nn * sizeof *cl->axis); cl->cosw = wrt_xmalloc(nn * sizeof *cl->cosw);
    cl->rho = wrt_xmalloc(nn * sizeof *cl->rho); cl->uniform = wrt_xmalloc(nn);
    if (!nq) return;
    /* the tree, nodes numbered in preorder (children after their parent) */
    build_ctx bc = {b, cl, 0, wrt_xmalloc(nq * sizeof *bc.tmp)};
    build_node(&bc, 0, nq);
    free(bc.tmp);
    cl->pref = wrt_xmalloc(((size_t)nq + 1) * sizeof *cl->pref);
    cl->pref[0] = 0;
    for (uint32_t i = 0; i < nq; i++) cl->pref[i + 1] = cl->pref[i] + b->quads[cl->perm[i]].area;
    if (wrt_ctree_finish(&cl->tree, "cluster tree") != WRT_OK) abort(); /* built above: only memory can fail */
}

void wrt_clusters_free(wrt_clusters *cl) {
    wrt_ctree_free(&cl->tree);
    free(cl->perm); free(cl->pref); free(cl->lo); free(cl->hi); free(cl->bmin); free(cl->bmax);
    free(cl->axis); free(cl->cosw); free(cl->rho); free(cl->uniform); free(cl->links);
    free(cl->pr); free(cl->ps); free(cl->occl);
    memset(cl, 0, sizeof *cl);
}
