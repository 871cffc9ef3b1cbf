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

#endif
