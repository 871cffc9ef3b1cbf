/* series_recut.c: the tree series' column ranges re-cut under wrt-bake-mpi (docs/mpi.md
 * "Session 12"). The ranges are cut at the first product (series.c
 * series_tree_share_start), but the terms fade unevenly: a range whose columns keep their
 * light while the others' fade ends with the most work (atrium at 5,048 elements, four
 * ranks: 36 / 40 / 52 / 64 s of CPU in the products). Before each product every rank
 * counts its columns' cost in the product's entries (per column j, one plus the entries
 * of the left factor's columns that the right factor's column j reads: the rule of
 * wrt_dist_mul_cuts, integers, so the decision and the cut are the same on every rank
 * whatever the timing; one counter a rank exchanged). Where the most loaded rank's cost
 * is above WRT_SERIES_RECUT_AT times the mean and the excess is worth it
 * (WRT_SERIES_RECUT_WORTH), the costs are gathered, the ranges cut again on them and the
 * columns that change owner, of the term about to be multiplied (for the factored
 * products U P, made already) and of the sum, go to their new rank (wrt_dist_share_move:
 * rounds of at most 32 MiB, the columns kept moved in place). On the atrium at detail 1
 * on four ranks the first product's cut left the second product 1.45 times uneven (the
 * first term's light is the direct links', the next ones spread), the later ones drifting
 * by about 6% a bounce. Which rank holds a column changes no
 * value: the products, the sums and the stored compression are per column, the norms
 * summed in column order over the ranks, so the file keeps wrt-bake's bytes. */
#include <stdlib.h>
#include <string.h>

#include "dist.h"
#include "series_internal.h"

/* Re-cut where the most loaded rank's predicted cost is above this many times the mean */
#ifndef WRT_SERIES_RECUT_AT
#define WRT_SERIES_RECUT_AT 1.10
#endif

/* ... and where the cost the most loaded rank has above the mean, times the ranks, is at
 * least this share of the largest product's (the late products, cheap, keep their cut:
 * on the atrium at detail 1 on four ranks the last two were 1.17 times uneven at 6% of
 * the largest's cost, and a re-cut moves the sum's columns, by then the most bytes) */
#ifndef WRT_SERIES_RECUT_WORTH
#define WRT_SERIES_RECUT_WORTH 0.02
#endif

/* This rank's columns' costs in the product a y: cost[j - c0] for j in [c0, c1) */
static uint64_t recut_costs(const wrt_csc *a, const wrt_csc *y, uint32_t c0, uint32_t c1, uint64_t *cost) {
    uint64_t sum = 0;
    for (uint32_t j = c0; j < c1; j++) {
        uint64_t c = 0;
        for (uint64_t k = y->col[j]; k < y->col[j + 1]; k++) c += 1 + (a->col[y->row[k] + 1] - a->col[y->row[k]]);
        cost[j - c0] = c;
        sum += c;
    }
    return sum;
}

wrt_status wrt_series_share_recut(series_state *s, const wrt_csc *a, wrt_csc *y) {
    wrt_bake_dist *d = s->b->opt.dist;
    int nr = d->nranks, me = d->rank;
    if (d->recut_at < 0) return WRT_OK;
    double at = d->recut_at > 0 ? d->recut_at : WRT_SERIES_RECUT_AT, worth = d->recut_at > 0 ? 0 : WRT_SERIES_RECUT_WORTH;
    uint32_t *cut = s->cut, n = cut[nr], c0 = cut[me], c1 = cut[me + 1];
    uint64_t *mine = wrt_xmalloc(((size_t)(c1 - c0) + 1) * sizeof *mine);
    uint64_t *load = wrt_xcalloc((size_t)nr, sizeof *load);
    uint64_t own = load[me] = recut_costs(a, y, c0, c1, mine);
    /* every rank's load (one counter each), then the decision, the same on every rank */
    wrt_status st = wrt_dist_sum_u64(d, load, nr);
    uint64_t total = 0, most = 0;
    for (int r = 0; r < nr && st == WRT_OK; r++) {
        total += load[r];
        if (load[r] > most) most = load[r];
    }
    free(load);
    if (total > d->products_peak) d->products_peak = total;
    /* uneven, and the work the most loaded rank would save worth the columns' moves */
    double over = (double)most * nr - (double)total;
    if (st != WRT_OK || total == 0 || (double)most * nr <= at * (double)total || over < worth * (double)d->products_peak) {
        d->products_cost += own;
        free(mine);
        return st;
    }
    uint64_t *all = wrt_xmalloc(((size_t)n + 1) * sizeof *all);
    st = wrt_dist_share_costs(d, mine, cut, all);
    free(mine);
    uint32_t *to = wrt_xmalloc(((size_t)nr + 1) * sizeof *to);
    if (st == WRT_OK) {
        wrt_dist_cost_cuts(all, n, nr, to);
        for (uint32_t j = to[me]; j < to[me + 1]; j++) d->products_cost += all[j];
    }
    free(all);
    if (st == WRT_OK && memcmp(to, cut, ((size_t)nr + 1) * sizeof *to)) {
        uint64_t sent = d->bytes_sent[WRT_DIST_SERIES];
        st = wrt_dist_share_move(d, y, cut, to);
        if (st == WRT_OK) st = wrt_dist_share_move(d, &s->S, cut, to);
        if (st == WRT_OK) {
            memcpy(cut, to, ((size_t)nr + 1) * sizeof *to);
            d->recuts++;
            d->recut_bytes += d->bytes_sent[WRT_DIST_SERIES] - sent;
        }
    }
    free(to);
    return st;
}
