/* bake_helpers.h: small helpers the bake's tests share (test_bake.c, test_stress.c, test_sparse.c):
 * points, options, the key of a quad's root function, reading one operator entry, and a
 * closed scene's response to uniform irradiance. */
#ifndef WRT_TEST_BAKE_HELPERS_H
#define WRT_TEST_BAKE_HELPERS_H

#include <math.h>
#include <stdlib.h>

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

/* Uniform irradiance 1 injected on every quad's root function, G - I applied: each quad's
 * indirect irradiance per channel, e[3 * q + c] (calloc'd, the caller frees). */
static inline double *root_response(const wrt_scene *s, const wrt_bake_result *r) {
    double *x = calloc(3 * r->nfuncs, sizeof *x), *y = calloc(3 * r->nfuncs, sizeof *y);
    double *e = calloc(3 * (size_t)s->nquads, sizeof *e);
    for (int q = 0; q < s->nquads; q++) {
        int64_t f = wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q));
        for (int c = 0; c < 3; c++) x[3 * f + c] = sqrt(s->quads[q].area / M_PI);
    }
    wrt_csc_apply(&r->op, x, y);
    for (int q = 0; q < s->nquads; q++) {
        int64_t f = wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q));
        for (int c = 0; c < 3; c++) e[3 * q + c] = y[3 * f + c] * sqrt(M_PI / s->quads[q].area);
    }
    free(x); free(y);
    return e;
}

#endif
