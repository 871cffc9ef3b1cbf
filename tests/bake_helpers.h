/* bake_helpers.h: small helpers the bake's tests share (test_bake.c, test_stress.c):
 * points, options, the key of a quad's root function, and reading one operator entry. */
#ifndef WRT_TEST_BAKE_HELPERS_H
#define WRT_TEST_BAKE_HELPERS_H

#include "common/basis.h"
#include "precompute/bake.h"

static inline wrt_v3 P(double x, double y, double z) { return v3(x, y, z); }

static inline wrt_bake_options opts(int q, int minl, int maxl) {
    wrt_bake_options o = {0};
    o.quality = q; o.min_slevel = minl; o.max_slevel = maxl;
    o.glossy_quality = q; /* glossy links refined like the others: the tests set their depth */
    o.threads = 2;
    return o;
}

static inline uint64_t root_key(int q) { return wrt_fkey_make((uint32_t)q, wrt_node_root(), 0, wrt_node_root(), 0); }

/* Channel 0 of entry (rk, sk) of m, 0 if absent. */
static inline double entry(const wrt_bake_result *r, const wrt_csc *m, uint64_t rk, uint64_t sk) {
    int64_t i = wrt_fkey_find(r->fkeys, r->nfuncs, rk), j = wrt_fkey_find(r->fkeys, r->nfuncs, sk);
    if (i < 0 || j < 0) return 0;
    for (uint64_t k = m->col[j]; k < m->col[j + 1]; k++)
        if (m->row[k] == (uint32_t)i) return m->val[3 * k];
    return 0;
}

#endif
