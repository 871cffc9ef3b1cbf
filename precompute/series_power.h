/* series_power.h: the stored G - I given each column's power from the DTO's own series
 * (series_power.c). */
#ifndef WRT_SERIES_POWER_H
#define WRT_SERIES_POWER_H

#include <stdint.h>

#include "sparse.h"

typedef struct wrt_series_power_stats {
    int bounces;              /* terms of pw^T T^n iterated before the tail */
    uint64_t columns_fixed;   /* columns whose power was corrected */
    uint64_t columns_left;    /* columns that could not take their difference */
    double power_before, power_target; /* sum over columns, first channel */
} wrt_series_power_stats;

/* Spreads over each column j of S (G - I, compressed) the difference between
 * sum_{n >= 1} (pw^T T^n)_j and the power S's column delivers, channel by channel. */
void wrt_series_power_fix(const wrt_csc *T, const double *pw, int threads, int max_bounces, wrt_csc *S,
                          wrt_series_power_stats *stats);
/* The same in two steps, so that T can be freed between them (series.c, when the bake
 * may consume T): the targets sum_{n >= 1} pw^T T^n (3n values, malloc'd; *bounces the
 * terms iterated), then their spreading over S's columns (stats' sums added to; zero
 * them first). wrt_series_power_fix is the two in a row. */
double *wrt_series_power_targets(const wrt_csc *T, const double *pw, int threads, int max_bounces, int *bounces);
/* The targets with v T made by mul(user, v, out) (3n values each): T given as a product
 * (series_first.c, T = E1 U) */
typedef void (*wrt_rowmul_fn)(void *user, const double *v, double *out);
double *wrt_series_power_targets_fn(size_t n, wrt_rowmul_fn mul, void *user, const double *pw, int max_bounces,
                                    int *bounces);
/* out = v M (3 values a column of M, each a dot product with its column), on `threads`
 * threads: the same bits whatever their number */
void wrt_csc_rowmul(const wrt_csc *M, const double *v, double *out, int threads);
void wrt_series_power_apply(const double *u, const double *pw, int threads, wrt_csc *S, wrt_series_power_stats *stats);

#endif
