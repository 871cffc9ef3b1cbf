/* series_first.h: T = E1 U read without T (series_first.c; docs/clusters.md "T never
 * formed"): T's columns one at a time, T x and v T. Used by the series (series_internal.h)
 * and the tests. */
#ifndef WRT_SERIES_FIRST_H
#define WRT_SERIES_FIRST_H

#include <stdint.h>

#include "sparse.h"
#include "../common/cluster_tree.h"

/* T's columns from E1 (cluster.h: rows the functions, columns the functions then one per
 * tree node), one at a time: the working arrays of one caller (not shared by threads) */
typedef struct wrt_tcols {
    const wrt_ctree *t;
    const wrt_csc *E1;
    uint32_t nf;
    int32_t *leaf_of;   /* per function: the leaf of the quad whose root it is, else -1 */
    float *acc;         /* 3 per row */
    uint32_t *mark, epoch, *rows, *path, *tmp; /* tmp: the rows' sort */
} wrt_tcols;

/* root: per quad its root slot (wrt_clusters_root_index) */
void wrt_tcols_init(wrt_tcols *c, const wrt_ctree *t, const uint32_t *root, const wrt_csc *E1, uint32_t nf);
void wrt_tcols_free(wrt_tcols *c);
/* T's column f, rows ascending, into arrays malloc'd here (the caller frees them); its
 * entries. The same entries and value bits as the assembly's T (cluster_ops.c's second
 * push-down: the same roundings, in the same order). */
uint64_t wrt_tcols_col(wrt_tcols *c, uint32_t f, uint32_t **row, float **val);
/* y += T x = E1 (U x), x and y 3 nf values (RGB) */
void wrt_factored_apply(const wrt_ctree *t, const uint32_t *root, const wrt_csc *E1, uint32_t nf, const double *x,
                        double *y);
/* out = v T = (v E1) U, 3 nf values, on `threads` threads (the same bits whatever their number) */
void wrt_factored_rowmul(const wrt_ctree *t, const uint32_t *root, const wrt_csc *E1, uint32_t nf, const double *v,
                         double *out, int threads);

#endif
