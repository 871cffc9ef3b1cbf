/* relight_cluster.c: the runtime's side of the cluster tree (docs/clusters.md,
 * common/cluster_tree.h). A file baked with `--clusters` stores the operator with the
 * quads' root slots holding the tree's orthonormal functions: the projected light E is
 * taken to that basis before the multiply (O(N)) and the result X back to the quads'
 * roots before synthesis (O(N)); everything else is unchanged. With section csend the
 * tree's basis is on the senders' side only (the columns): the light goes forward, the
 * result is already on the quads' functions, no inverse. Linear, and exact up to
 * float rounding: the light change stays linear in the lights and exact in the mean.
 * Depends on relight_internal.h. */
#include "relight_internal.h"

wrt_status relight_setup_clusters(wrt_relight *r) {
    const wrt_gto *g = r->g;
    if (!g->ctree) return WRT_OK;
    if (g->nkcols)
        return wrt_fail(WRT_ERR_UNSUPPORTED, "relight: a cluster tree with a first-bounce operator is not supported");
    uint32_t nq = g->nquads, nf = g->nfuncs;
    r->ct.root = relight_calloc(r, nq + 1, sizeof *r->ct.root);
    r->ct.Et = relight_calloc(r, (size_t)nf * 3 + 1, sizeof *r->ct.Et);
    r->ct.scratch = relight_calloc(r, (size_t)g->nctree * 6 + 1, sizeof *r->ct.scratch);
    if (r->oom) return WRT_ERR_NOMEM;
    for (uint32_t q = 0; q < nq; q++) {
        uint32_t f = g->quads[q].func_first;
        if (g->quads[q].func_count == 0 || f >= nf ||
            g->fkeys[f] != wrt_fkey_make(q, wrt_node_root(), 0, wrt_node_root(), 0))
            return wrt_fail(WRT_ERR_CORRUPT, "relight: quad %u has no root function for the cluster tree", q);
        r->ct.root[q] = f;
    }
    wrt_status st = wrt_ctree_alloc(&r->ct.t, nq);
    if (st != WRT_OK) return st;
    for (uint32_t i = 0; i < g->nctree; i++) {
        r->ct.t.left[i] = g->ctree[i].left; r->ct.t.right[i] = g->ctree[i].right; r->ct.t.area[i] = g->ctree[i].area;
    }
    st = wrt_ctree_finish(&r->ct.t, "relight: cluster tree");
    if (st != WRT_OK) { wrt_ctree_free(&r->ct.t); return st; }
    r->ct.on = 1;
    r->ct.inv = !g->ctree_senders; /* senders only: the result is the quads' already */
    return WRT_OK;
}

const float *relight_cluster_forward(wrt_relight *r, const float *src) {
    if (!r->ct.on) return src;
    memcpy(r->ct.Et, src, (size_t)r->g->nfuncs * 3 * sizeof(float));
    wrt_ctree_forward_f(&r->ct.t, r->ct.root, r->ct.Et, r->ct.scratch);
    return r->ct.Et;
}

void relight_cluster_inverse(wrt_relight *r) {
    if (!r->ct.on || !r->ct.inv) return;
    const wrt_gto *g = r->g;
    wrt_ctree_inverse_f(&r->ct.t, r->ct.root, r->X, r->ct.scratch);
    /* relight_multiply compared the tree's coefficients with the last X: again, on the quads' */
    for (uint32_t q = 0; q < g->nquads; q++) {
        const wrt_gto_quad *gq = &g->quads[q];
        size_t a = (size_t)gq->func_first * 3, n = (size_t)gq->func_count * 3;
        /* marks are added: a quad a budgeted update has not synthesized yet stays marked */
        if (r->redo_all || memcmp(r->X + a, r->Xprev + a, n * sizeof(float)) != 0) r->resynth[q] = 1;
        int nz = 0;
        for (size_t k = a; k < a + n && !nz; k++) nz = r->X[k] != 0;
        r->x_nonzero[q] = (uint8_t)nz;
    }
}
