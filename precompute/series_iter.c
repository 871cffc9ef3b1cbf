/* series_iter.c: the power iteration of the series' bounces (series.c, series_bounces):
 * the ratio of successive terms' powers, pw^T T^n, that decides the geometric tail,
 * iterated on T in memory, on T's scratch file (spill.h), or through apply where T is
 * not held (series_first.c). Depends on series_internal.h. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/wrt_common.h"
#include "budget.h"
#include "dist.h"
#include "series_internal.h"

void wrt_series_mark(series_state *s, const char *stage) {
    if (!s->timing) return;
    double w = wrt_now(), c = wrt_dist_cpu_now();
    double peak = (double)wrt_bake_stage_peak_bytes() / 1048576.0;
    if (s->mark_w > 0)
        fprintf(stderr, "series-times: %-26s %9.3f s wall %9.3f s cpu  peak %8.0f MB  now %8.0f MB\n", stage,
                w - s->mark_w, c - s->mark_c, peak, (double)wrt_bake_rss_bytes() / 1048576.0);
    else
        fprintf(stderr, "series-times: %-26s now %8.0f MB\n", "(start)", (double)wrt_bake_rss_bytes() / 1048576.0);
    s->mark_w = w;
    s->mark_c = c;
}

void wrt_power_iter_start(power_iter *p, const wrt_csc *T, const double *pw) {
    uint32_t n = p->apply ? p->n : T->n;
    p->n = n;
    p->x = wrt_xcalloc(3 * (size_t)n + 1, sizeof *p->x);
    p->y = wrt_xcalloc(3 * (size_t)n + 1, sizeof *p->y);
    for (uint32_t i = 0; i < n; i++)
        if (pw[i] != 0) p->x[3 * i] = p->x[3 * i + 1] = p->x[3 * i + 2] = pw[i];
    if (p->apply) p->apply(p->user, p->x, p->y);
    else wrt_csc_apply(T, p->x, p->y);
    for (int ch = 0; ch < 3; ch++) p->vp_prev[ch] = 0;
    for (uint32_t i = 0; i < n; i++)
        for (int ch = 0; ch < 3; ch++) p->vp_prev[ch] += pw[i] * p->y[3 * i + ch];
}

/* next iterate: x = y / its power, y = T x; rc the ratio of the powers. 0 where the
 * spilled T could not be read back. */
int wrt_power_iter_step(power_iter *p, const wrt_csc *T, wrt_spill *sp, const double *pw, double rc[3]) {
    uint32_t n = p->n;
    double *x = p->x, *y = p->y, *vp_prev = p->vp_prev;
    double vs = fmax(vp_prev[0], fmax(vp_prev[1], vp_prev[2]));
    for (size_t i = 0; i < 3 * (size_t)n; i++) x[i] = vs > 0 ? y[i] / vs : 0;
    for (int ch = 0; ch < 3; ch++) vp_prev[ch] = vs > 0 ? vp_prev[ch] / vs : 0;
    memset(y, 0, 3 * (size_t)n * sizeof *y);
    if (p->apply) p->apply(p->user, x, y);
    else if (T) wrt_csc_apply(T, x, y);
    else if (!wrt_spill_apply(sp, x, y)) return 0;
    double vp[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; i++)
        for (int ch = 0; ch < 3; ch++) vp[ch] += pw[i] * y[3 * i + ch];
    for (int ch = 0; ch < 3; ch++) {
        rc[ch] = vp_prev[ch] > 0 ? vp[ch] / vp_prev[ch] : 0;
        vp_prev[ch] = vp[ch];
    }
    return 1;
}

void wrt_power_iter_free(power_iter *p) {
    free(p->x); free(p->y);
    p->x = p->y = NULL;
}
