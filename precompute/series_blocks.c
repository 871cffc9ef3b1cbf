/* series_blocks.c: the factored product E1 (U P) by blocks of P's columns, in one process
 * (series.c series_factored_term; docs/clusters.md "U P by blocks of columns"). U acts on
 * each column of P alone and the product computes each column alone, so block by block
 * the product's columns are the same entries as with U P made whole: only a block of U P
 * is held beside P and the term being made, not the whole of it (1.9 times P's entries
 * on the atrium). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "budget.h"
#include "cluster.h"
#include "dist.h"
#include "series_internal.h"

/* A block holds at most 1/WRT_FAC_BLOCKS of P's entries (a column more where one column
 * alone passes that): measured at 16 and 4 (docs/clusters.md) */
#ifndef WRT_FAC_BLOCKS
#define WRT_FAC_BLOCKS 16
#endif

/* Columns [c0, c1) of P as a matrix of its own without a copy of the entries: the arrays
 * start at the block's first entry, the other columns empty (col: P->n + 1, the caller's) */
static wrt_csc block_view(const wrt_csc *P, uint32_t c0, uint32_t c1, uint64_t *col) {
    uint64_t a = P->col[c0], z = P->col[c1];
    for (uint32_t j = 0; j <= P->n; j++) col[j] = j <= c0 ? 0 : j >= c1 ? z - a : P->col[j] - a;
    return (wrt_csc){.n = P->n, .nnz = z - a, .col = col, .row = P->row + a, .val = P->val + 3 * a};
}

/* The end of the block that starts at column c0 */
static uint32_t block_end(const wrt_csc *P, uint32_t c0, uint64_t target) {
    uint32_t c1 = c0 + 1;
    while (c1 < P->n && P->col[c1 + 1] - P->col[c0] <= target) c1++;
    return c1;
}

/* The product's entries, estimated from every stride-th column of P pulled up alone and
 * multiplied (computed and discarded), scaled by P's entries over the sample's: the same
 * whatever the thread count */
static uint64_t blocks_estimate(const series_state *s, uint32_t stride) {
    const wrt_csc *P = &s->P;
    wrt_csc Ps = {.n = P->n};
    Ps.col = wrt_xcalloc((size_t)P->n + 1, sizeof *Ps.col);
    uint64_t n = 0;
    for (uint32_t j = 0; j < P->n; j += stride) n += P->col[j + 1] - P->col[j];
    Ps.row = wrt_xmalloc((n ? n : 1) * sizeof *Ps.row);
    Ps.val = wrt_xmalloc((n ? n : 1) * 3 * sizeof *Ps.val);
    n = 0;
    for (uint32_t j = 0; j < P->n; j++) {
        if (j % stride == 0) {
            uint64_t k0 = P->col[j], m = P->col[j + 1] - k0;
            memcpy(&Ps.row[n], &P->row[k0], m * sizeof *Ps.row);
            memcpy(&Ps.val[3 * n], &P->val[3 * k0], 3 * m * sizeof *Ps.val);
            n += m;
        }
        Ps.col[j + 1] = n;
    }
    Ps.nnz = n;
    wrt_csc Xs = wrt_series_factored_right(s, &Ps);
    wrt_csc_free(&Ps);
    uint64_t kept = n ? wrt_csc_mul_estimate(&s->Tr, &Xs, s->eps, &s->FW, 1, s->threads) : 0;
    wrt_csc_free(&Xs);
    return n ? (uint64_t)((double)kept * (double)P->nnz / (double)n + 0.5) : 0;
}

/* The memory of the product by blocks, beside what is resident (P among it): a block of U P
 * with the pull-up's scratch, 2.6 bytes a byte of the block's P (as U P made whole was
 * counted: docs/clusters.md), and the product's need as series.c counts it (16 bytes an
 * entry, the sample's spread 1.25, the 32nd of its columns being made; sampled finer
 * where twice the coarse sample's need would pass the budget: finer where it passed a
 * quarter of the budget, every product of a large bake paid a sixteenth of its cost
 * again, as at 100,256 atrium elements under --max-memory 20000) three times: the product raised the resident
 * memory by 1.4 to 3.2 times its entries' bytes at the atrium's large products (the
 * chunks appended by realloc, the freed column arrays), and the sum's pass after it grows
 * S by the term's entries, which P's freed arrays, fragmented in the heap, do not cover
 * (docs/clusters.md "U P by blocks of columns"). */
static wrt_status blocks_check(series_state *s, int bounce, uint64_t block_max) {
    const bake_ctx *b = s->b;
    const double per = 16.0;
    uint64_t est = blocks_estimate(s, 64);
    double need = per * 1.25 * (1 + 1.0 / 32) * (double)est, up = per * 2.6 * (double)block_max;
    if ((double)wrt_bake_rss_bytes() + 2 * (3 * need + up) > b->opt.max_memory_mb * 1024.0 * 1024.0) {
        est = blocks_estimate(s, 16);
        need = per * 1.25 * (1 + 1.0 / 32) * (double)est;
    }
    need = 3 * need + up;
    char what[64];
    snprintf(what, sizeof what, "bounce %d of the series, E1 (U P) by blocks", bounce);
    return wrt_bake_memory_check(b->opt.max_memory_mb, &s->C->mem_estimate_mb, (uint64_t)need, what);
}

wrt_status wrt_series_factored_blocks(series_state *s, int bounce, int checked, wrt_csc *N) {
    const wrt_csc *P = &s->P;
    uint64_t target = P->nnz / (uint64_t)(s->fac_parts > 0 ? s->fac_parts : WRT_FAC_BLOCKS), block_max = 0;
    for (uint32_t c0 = 0, c1; c0 < P->n; c0 = c1) {
        c1 = block_end(P, c0, target);
        if (P->col[c1] - P->col[c0] > block_max) block_max = P->col[c1] - P->col[c0];
    }
    wrt_status st = WRT_OK;
    if (!checked) st = blocks_check(s, bounce, block_max); /* the freed memory given back first */
    else wrt_bake_memory_trim();
    if (st != WRT_OK) return st;
    uint32_t ne = s->Tr.n;
    *N = (wrt_csc){.n = ne};
    N->col = wrt_xcalloc((size_t)ne + 1, sizeof *N->col);
    N->row = wrt_xmalloc(sizeof *N->row);
    N->val = wrt_xmalloc(3 * sizeof *N->val);
    uint64_t *col = wrt_xmalloc(((size_t)P->n + 1) * sizeof *col), xnnz = 0;
    double up_w = 0, up_c = 0, mul_w = 0, mul_c = 0;
    for (uint32_t c0 = 0, c1; c0 < P->n && c0 < ne; c0 = c1) {
        c1 = block_end(P, c0, target);
        if (c1 > ne) c1 = ne;
        double w0 = wrt_now(), t0 = wrt_dist_cpu_now();
        wrt_csc V = block_view(P, c0, c1, col);
        wrt_csc X = wrt_series_factored_right(s, &V);
        double w1 = wrt_now(), t1 = wrt_dist_cpu_now();
        wrt_csc_mul_append(&s->Tr, &X, s->eps, &s->FW, s->threads, c0, c1, N);
        xnnz += X.nnz;
        wrt_csc_free(&X);
        up_w += w1 - w0; up_c += t1 - t0;
        mul_w += wrt_now() - w1; mul_c += wrt_dist_cpu_now() - t1;
    }
    free(col);
    if (s->timing) /* WRT_DTO_TIMES: the bake's stages timed (bake.c) */
        fprintf(stderr,
                "series-times: bounce %2d  U P %6.2f s wall %6.2f cpu  product %7.2f s wall %7.2f cpu  P %llu  U P %llu"
                "  next %llu  (blocks)\n",
                bounce, up_w, up_c, mul_w, mul_c, (unsigned long long)P->nnz, (unsigned long long)xnnz,
                (unsigned long long)N->nnz);
    wrt_series_factored_trim(s, N);
    return WRT_OK;
}
