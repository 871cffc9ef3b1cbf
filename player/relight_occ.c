/* relight_occ.c: the tree over the quads' bounding spheres that the projection's occluder
 * search walks (relight_project.c find_occluders), and the bounding cone of a sphere seen
 * from a light, for the quads and the tree's nodes alike. Depends on relight_internal.h.
 *
 * For each quad A the search looks for the quads B that may shade some point of A from
 * the light. Testing every B made a light change O(N^2) (4.2 s of 4.5 at 53,122 atrium
 * elements). The tree is made once, when the relighter is made: its nodes split their
 * quads at the median of their centres along the widest axis, down to OCC_LEAF quads a
 * leaf; each node's sphere holds its quads' spheres. The search skips a node when a test
 * on its sphere shows that every quad under it would fail the same test made on the quad
 * (the proofs by each test in find_occluders); on a leaf each quad gets the same tests
 * as before, so the occluders found are the same set. */
#include "relight_internal.h"

#include <stdlib.h>

#define OCC_LEAF 4

typedef struct occ_key { double x; uint32_t q; } occ_key;

static int key_cmp(const void *a, const void *b) {
    const occ_key *x = a, *y = b;
    if (x->x != y->x) return x->x < y->x ? -1 : 1;
    return (x->q > y->q) - (x->q < y->q);
}

static double axis_of(wrt_v3 v, int k) { return k == 0 ? v.x : k == 1 ? v.y : v.z; }

/* Node `n` over oorder[first, first + count), then its subtree after it; returns the
 * next free node. keys: count entries of scratch. */
static uint32_t occ_make(wrt_relight *r, uint32_t n, uint32_t first, uint32_t count, occ_key *keys, int depth) {
    occ_node *nd = &r->proj.onode[n];
    const uint32_t *ord = r->proj.oorder + first;
    wrt_v3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
    wrt_v3 clo = lo, chi = hi; /* the centres' box: where the split goes */
    for (uint32_t k = 0; k < count; k++) {
        const quad_info *q = &r->qi[ord[k]];
        wrt_v3 c = q->centre;
        double e = q->radius;
        lo = v3(fmin(lo.x, c.x - e), fmin(lo.y, c.y - e), fmin(lo.z, c.z - e));
        hi = v3(fmax(hi.x, c.x + e), fmax(hi.y, c.y + e), fmax(hi.z, c.z + e));
        clo = v3(fmin(clo.x, c.x), fmin(clo.y, c.y), fmin(clo.z, c.z));
        chi = v3(fmax(chi.x, c.x), fmax(chi.y, c.y), fmax(chi.z, c.z));
    }
    nd->c = v3_scale(v3_add(lo, hi), 0.5);
    nd->rad = 0;
    for (uint32_t k = 0; k < count; k++) {
        const quad_info *q = &r->qi[ord[k]];
        nd->rad = fmax(nd->rad, v3_len(v3_sub(q->centre, nd->c)) + q->radius);
    }
    nd->rad *= 1 + 1e-12; /* holds every quad's sphere despite the rounding above */
    nd->first = first;
    if (count <= OCC_LEAF || depth >= 60) { /* the median split keeps depth near log2 N */
        nd->count = count;
        nd->right = 0;
        return n + 1;
    }
    nd->count = 0;
    wrt_v3 ext = v3_sub(chi, clo);
    int ax = ext.x >= ext.y && ext.x >= ext.z ? 0 : ext.y >= ext.z ? 1 : 2;
    for (uint32_t k = 0; k < count; k++) keys[k] = (occ_key){axis_of(r->qi[ord[k]].centre, ax), ord[k]};
    qsort(keys, count, sizeof *keys, key_cmp);
    for (uint32_t k = 0; k < count; k++) r->proj.oorder[first + k] = keys[k].q;
    uint32_t half = count / 2;
    uint32_t next = occ_make(r, n + 1, first, half, keys, depth + 1);
    r->proj.onode[n].right = next;
    return occ_make(r, next, first + half, count - half, keys, depth + 1);
}

int relight_occ_build(wrt_relight *r) {
    uint32_t nq = r->g->nquads;
    r->proj.onode = relight_calloc(r, 2 * (size_t)nq + 1, sizeof(occ_node));
    r->proj.ocones = relight_calloc(r, 2 * (size_t)nq + 1, sizeof(light_cone));
    r->proj.oorder = relight_calloc(r, nq + 1, sizeof(uint32_t));
    occ_key *keys = relight_calloc(r, nq + 1, sizeof(occ_key));
    if (!r->proj.onode || !r->proj.ocones || !r->proj.oorder || !keys) { relight_free(r, keys); return -1; }
    for (uint32_t q = 0; q < nq; q++) r->proj.oorder[q] = q;
    r->proj.nonode = nq ? occ_make(r, 0, 0, nq, keys, 0) : 0;
    relight_free(r, keys);
    return 0;
}

void relight_sphere_cone(const wrt_relight *r, const light_c *l, wrt_v3 centre, double radius, light_cone *cn) {
    wrt_v3 dc = v3_sub(centre, l->pos);
    double D = v3_len(dc);
    cn->dmin = D > radius ? D - radius : 0;
    cn->dmax = D + radius;
    if (l->sun) { /* distance along the sun's light (signed), no cone: find_occluders' cylinders */
        double t = v3_dot(v3_sub(centre, r->rt.origin), l->dir);
        cn->dmin = t - radius;
        cn->dmax = t + radius;
        cn->u = v3(0, 0, 1); cn->sina = 0; cn->cosa = -1;
    } else if (D > radius) {
        cn->u = v3_scale(dc, 1.0 / D);
        cn->sina = radius / D;
        cn->cosa = sqrt(1 - cn->sina * cn->sina);
    } else { cn->u = v3(0, 0, 1); cn->sina = 0; cn->cosa = -1; } /* the light is inside */
}
