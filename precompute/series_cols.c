/* series_cols.c: the factored tree series (--clusters, one process) by blocks of columns
 * through every bounce (docs/clusters.md "The series by blocks of columns").
 *
 * Multiplied from the left, term k+1's column j is E1 (U P_k)'s column j: it reads term
 * k's column j alone, and the products' compression, the sum and the stored operator's
 * compression are column by column too. So a block of columns can go through every
 * bounce on its own, its sum compressed for storing as soon as its last term is added
 * (and written to a scratch file, read back when the series has freed its arrays), and
 * the next block starts from nothing. Held beside E1 are then one block's terms and sum,
 * not the whole of them (at 22,224 atrium elements the third term alone held 78.6M
 * entries, at 43,780 216M: 3.5 GB).
 *
 * What the whole-term series decided from the terms' norms is decided here before any
 * block starts, from the power iteration alone (so every column takes the same number of
 * bounces and the same tail ratios whatever the blocks):
 *  - the bounces: the ratios' settling rule of series.c, with the light left measured as
 *    the power iteration's term over its sum (the smooth light's share; the terms' norms
 *    fall faster, their detail decaying first, so this stops no sooner);
 *  - the tail's ratios, the same iteration's.
 * A block whose next term is empty (every entry under the threshold) stops there, its
 * tail from its last term, as the whole series stopped when its next term was empty.
 * The norms the bake reports (energy_left, tail_fraction) are summed over the blocks. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "budget.h"
#include "dist.h"
#include "spill.h"
#include "series_internal.h"

int wrt_series_cols_on(const series_state *s) {
    const bake_ctx *b = s->b;
    /* under wrt-bake-mpi by tree shares, each rank its range; without shares
     * (WRT_MPI_SHARE=0, a comparison) each rank all of them (the blocks do not change a
     * column's entries: the same bytes as one process either way) */
    return s->tree && s->fac && b->opt.series_columns > 0 && !b->opt.gathered && !b->opt.report_gathered;
}

/* The bounces and the tail's ratios from the power iteration alone (series.c's rules) */
static wrt_status cols_plan(series_state *s, int *bounces, double *energy, double tail[3]) {
    const bake_ctx *b = s->b;
    if (!s->pi.x) wrt_power_iter_start(&s->pi, s->T, s->pw);
    double rc_prev[3] = {-1, -1, -1}, v[3] = {1, 1, 1}, sum[3] = {1, 1, 1};
    int stable = 0, n = 1;
    double e = 1;
    s->ratio = 0;
    while (n < b->opt.max_bounces) {
        double r[3];
        if (!wrt_power_iter_step(&s->pi, s->T, &s->Tf, s->pw, r))
            return wrt_fail(WRT_ERR_IO, "the series could not read back its scratch copy of T");
        n++;
        e = 0;
        for (int ch = 0; ch < 3; ch++) {
            v[ch] *= fmax(r[ch], 0);
            sum[ch] += v[ch];
            e = fmax(e, sum[ch] > 0 ? v[ch] / sum[ch] : 0);
        }
        int settled = 1;
        s->ratio = 0;
        for (int ch = 0; ch < 3; ch++) {
            s->rc[ch] = r[ch];
            s->ratio = fmax(s->ratio, r[ch]);
            double dr = fabs(r[ch] - rc_prev[ch]);
            settled &= rc_prev[ch] >= 0 &&
                       (dr <= 1e-5 * r[ch] || (r[ch] < 1 && dr / ((1 - r[ch]) * (1 - r[ch])) * e <= 1e-6));
            rc_prev[ch] = r[ch];
        }
        stable = settled ? stable + 1 : 0;
        if (e < 1e-6) break;
        if (!b->opt.no_tail && stable >= 3 && n >= 8) break;
    }
    *bounces = n;
    *energy = e;
    /* the tail's share of the light, were it added: k v / (sum + k v) */
    for (int ch = 0; ch < 3; ch++) {
        double k = s->rc[ch] > 0 && s->rc[ch] < 1 ? s->rc[ch] / (1 - s->rc[ch]) : 0;
        tail[ch] = sum[ch] + k * v[ch] > 0 ? k * v[ch] / (sum[ch] + k * v[ch]) : 0;
    }
    return WRT_OK;
}

wrt_status wrt_series_diverging(const series_state *s, double energy, int bounces) {
    /* Terms that keep growing (the ratio settled at or above 1, or still above 1 at the
     * cap) mean the discrete operator's dominant eigenvalue is >= 1: the sum so far is
     * a truncation of a divergent series, not an approximation of G - I. */
    const bake_ctx *b = s->b;
    if (!(s->ratio >= 1 && energy >= 1e-6)) return WRT_OK;
    double rmax = 0;
    for (int q = 0; q < b->nq; q++) rmax = fmax(rmax, fmax(b->rho[q][0], fmax(b->rho[q][1], b->rho[q][2])));
    return wrt_fail(WRT_ERR_ACCURACY,
                    "the light transport series diverges: each bounce multiplies the light by %.4f after %d "
                    "bounces (largest albedo %.4f; the discretised transport gains energy: lower the albedo or "
                    "raise the quality)", s->ratio, bounces, rmax);
}

/* S += k P on the columns where P has entries and N none (a column ended) */
static void cols_tail_ended(wrt_csc *S, const wrt_csc *P, const wrt_csc *N, const double k[3]) {
    uint32_t n = P->n < N->n ? P->n : N->n;
    uint64_t m = 0;
    for (uint32_t j = 0; j < n; j++)
        if (N->col[j + 1] == N->col[j]) m += P->col[j + 1] - P->col[j];
    if (!m) return;
    wrt_csc D = {.n = P->n, .nnz = m};
    D.col = wrt_xcalloc((size_t)P->n + 1, sizeof *D.col);
    D.row = wrt_xmalloc(m * sizeof *D.row);
    D.val = wrt_xmalloc(3 * m * sizeof *D.val);
    m = 0;
    for (uint32_t j = 0; j < P->n; j++) {
        if (j < n && N->col[j + 1] == N->col[j]) {
            uint64_t a = P->col[j], z = P->col[j + 1];
            memcpy(D.row + m, P->row + a, (z - a) * sizeof *D.row);
            memcpy(D.val + 3 * m, P->val + 3 * a, 3 * (z - a) * sizeof *D.val);
            m += z - a;
        }
        D.col[j + 1] = m;
    }
    wrt_csc_add3_into(S, &D, k);
    wrt_csc_free(&D);
}

/* The end of the block that starts at c0: at most `target` of P's entries (a column more
 * where one column alone passes it) */
static uint32_t cols_end(const wrt_csc *P, uint32_t c0, uint64_t target) {
    uint32_t c1 = c0 + 1;
    while (c1 < P->n && P->col[c1 + 1] - P->col[c0] <= target) c1++;
    return c1;
}

/* The next columns [c0, c1) of a scratch file read back as a matrix of n columns, the
 * others empty (wrt_series_csc_range's form) */
static int cols_read_range(wrt_spill *f, uint32_t c0, uint32_t c1, uint32_t n, wrt_csc *out) {
    wrt_csc part;
    if (!wrt_spill_read(f, c1 - c0, &part)) return 0;
    *out = (wrt_csc){.n = n, .nnz = part.nnz, .row = part.row, .val = part.val};
    out->col = wrt_xcalloc((size_t)n + 1, sizeof *out->col);
    for (uint32_t j = c0; j < n; j++) out->col[j + 1] = part.col[(j < c1 ? j : c1 - 1) + 1 - c0];
    free(part.col);
    return 1;
}

wrt_status wrt_series_cols(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_counters *C = s->C;
    int bounces = 1;
    double energy = 0, tail[3];
    wrt_status st = cols_plan(s, &bounces, &energy, tail);
    if (st != WRT_OK) return st;
    wrt_series_mark(s, "power iteration");
    C->series_ratio = s->ratio;
    C->bounces = (uint64_t)bounces;
    C->energy_left = energy;
    if ((st = wrt_series_diverging(s, energy, bounces)) != WRT_OK) return st;
    int add = !b->opt.no_tail && s->ratio > 0 && s->ratio < 1;
    double k[3] = {0, 0, 0};
    for (int ch = 0; ch < 3 && add; ch++) k[ch] = s->rc[ch] > 0 && s->rc[ch] < 1 ? s->rc[ch] / (1 - s->rc[ch]) : 0;
    wrt_csc_weights W;
    double *own[3];
    double eps = wrt_series_final_weights_tree(s, &W, own);
    /* the first term and the sum's first state, whole (made once: the senders' transform
     * walks the whole tree for any range), cut into the blocks as they come */
    wrt_csc P1 = s->P, S0 = s->S;
    memset(&s->P, 0, sizeof s->P);
    memset(&s->S, 0, sizeof s->S);
    uint32_t n = S0.n;
    int nblocks = b->opt.series_columns;
    uint64_t target = P1.nnz / (uint64_t)nblocks;
    /* the first term's entries are made again block by block from the sum's first state
     * (the same columns, series_tree.c): held whole beside it, at 100,256 atrium
     * elements they were 108M entries (1.7 GB); its column starts cut the blocks */
    int remake = s->tree && P1.n == n;
    if (remake) {
        free(P1.row); free(P1.val);
        P1.row = NULL;
        P1.val = NULL;
    }
    /* the stored operator's blocks go to a scratch file as they are made, and come back
     * once the series' own arrays are freed: held beside them, at 53,122 atrium elements
     * they were 3.4 GB of its 8.3 GB peak */
    wrt_spill F;
    if (!wrt_spill_open(&F, n)) {
        wrt_csc_free(&P1);
        wrt_csc_free(&S0);
        free(own[0]); free(own[1]); free(own[2]);
        return wrt_fail(WRT_ERR_IO, "the series could not make a scratch file for the stored operator");
    }
    /* E1 (T never formed) is read again only by the power rule's correction, after the
     * blocks: it waits in a scratch file meanwhile (where none can be made, in memory) */
    wrt_spill E1f = {0};
    int e1_out = s->no_t && s->res->dto_e1.col && wrt_spill_write(&E1f, &s->res->dto_e1);
    uint32_t ne = s->res->dto_e1.n;
    if (e1_out) wrt_csc_free(&s->res->dto_e1);
    /* and the sum's first state, read back a block at a time (the blocks go in column
     * order): held whole, it stayed beside every block */
    wrt_spill S0f = {0};
    int s0_out = remake && wrt_spill_write(&S0f, &S0);
    if (s0_out) {
        free(S0.row); free(S0.val);
        S0.row = NULL;
        S0.val = NULL;
    }
    int timing = s->timing;
    s->timing = 0; /* the products' own lines: one a block below instead */
    /* each product whole on the block's columns (a block of U P is then a block's share
     * of it: in 16 parts again, the pull-up's pass over every column, 16 x 16 times a
     * bounce, cost 25% of the series at 5,048 atrium elements) */
    s->fac_parts = 1;
    const double one[3] = {1, 1, 1};
    for (uint32_t c0 = 0, c1; c0 < n && st == WRT_OK; c0 = c1) {
        c1 = P1.n == n ? cols_end(&P1, c0, target) : n;
        double w0 = wrt_now(), t0 = wrt_dist_cpu_now();
        wrt_csc Sb;
        if (s0_out) {
            if (!cols_read_range(&S0f, c0, c1, n, &Sb)) {
                st = wrt_fail(WRT_ERR_IO, "the series could not read back the sum's first state from its scratch file");
                break;
            }
        } else {
            Sb = wrt_series_csc_range(&S0, c0, c1);
        }
        s->P = remake ? wrt_series_first_range(s, &Sb, c0, c1) : wrt_series_csc_range(&P1, c0, c1);
        uint64_t first = s->P.nnz, largest = s->P.nnz, stored = 0;
        int made = 1;
        while (made < bounces && s->P.nnz) {
            wrt_csc N;
            st = wrt_series_factored_blocks(s, made + 1, 0, &N);
            if (st != WRT_OK) break;
            /* a column whose next term is empty (every entry under the threshold) ends
             * there, its tail from its last term */
            if (add) cols_tail_ended(&Sb, &s->P, &N, k);
            if (!N.nnz) {
                wrt_csc_free(&N);
                break;
            }
            wrt_csc_add3_into(&Sb, &N, one);
            wrt_csc_free(&s->P);
            s->P = N;
            if (N.nnz > largest) largest = N.nnz;
            made++;
        }
        if (st == WRT_OK) {
            /* the columns still going at the last bounce: their tail */
            if (add && made == bounces) wrt_csc_add3_into(&Sb, &s->P, k);
            C->sum_held += Sb.nnz;
            wrt_csc_compress(&Sb, eps, &W);
            wrt_csc part = {.n = c1 - c0, .nnz = Sb.col[c1] - Sb.col[c0], .col = Sb.col + c0, .row = Sb.row, .val = Sb.val};
            stored = part.nnz;
            if (!wrt_spill_append(&F, &part))
                st = wrt_fail(WRT_ERR_IO, "the series could not write the stored operator to its scratch file");
        }
        wrt_csc_free(&Sb);
        wrt_csc_free(&s->P);
        if (timing)
            fprintf(stderr,
                    "series-cols: columns %6u-%6u  bounces %2d  first %10llu  largest term %10llu  stored %10llu"
                    "  %7.2f s wall %7.2f cpu\n",
                    c0, c1, made, (unsigned long long)first, (unsigned long long)largest,
                    (unsigned long long)stored, wrt_now() - w0, wrt_dist_cpu_now() - t0);
        if (st == WRT_OK && b->opt.progress &&
            !b->opt.progress("gto", P1.nnz ? (double)P1.col[c1] / (double)P1.nnz : 1, b->opt.progress_user))
            st = wrt_fail(WRT_ERR_CANCELLED, "bake cancelled");
    }
    s->timing = timing;
    s->fac_parts = 0;
    wrt_csc_free(&P1);
    wrt_csc_free(&S0);
    free(own[0]); free(own[1]); free(own[2]);
    wrt_power_iter_free(&s->pi);
    wrt_series_free_right(s);
    wrt_csc_mul_scratch_free();
    wrt_bake_memory_trim(); /* the series' arrays, freed, back to the system before F comes back */
    if (st == WRT_OK && e1_out && !wrt_spill_read(&E1f, ne, &s->res->dto_e1))
        st = wrt_fail(WRT_ERR_IO, "the series could not read back E1 from its scratch file");
    wrt_spill_free(&E1f);
    wrt_spill_free(&S0f);
    if (st == WRT_OK && !(wrt_spill_finish(&F) && wrt_spill_read(&F, n, &s->S)))
        st = wrt_fail(WRT_ERR_IO, "the series could not read back the stored operator from its scratch file");
    wrt_spill_free(&F);
    wrt_series_mark(s, "blocks");
    if (st != WRT_OK) return st;
    C->tail_fraction = add ? fmax(tail[0], fmax(tail[1], tail[2])) : 0;
    return WRT_OK;
}
