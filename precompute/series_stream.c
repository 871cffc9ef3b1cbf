/* series_stream.c: the series' sum in a scratch file between bounces (series_stream.h).
 * Column j of S + s P depends on column j of S and of P alone, and so does column j of a
 * compression (its weights are the row's, the column's and the power the column moves
 * among its own entries), so the sum can be carried through by blocks of columns: a block
 * of S read back, merged with the same columns of the term in memory (wrt_csc_add3 on
 * the block: the same entries and roundings as wrt_csc_add3_into on the whole), written
 * to the next file, freed. The sum's norm is summed block after block in storage order,
 * as wrt_csc_norm sums it. Memory: a block, the term, and the column starts. Depends on
 * spill.h, sparse.h. */
#include "series_stream.h"

#include <stdlib.h>
#include <string.h>

#include "../common/wrt_common.h"

void wrt_sum_stream_start(wrt_sum_stream *ss, wrt_spill *first, uint64_t block) {
    memset(ss, 0, sizeof *ss);
    ss->cur = first;
    ss->block = block ? block : 1;
    ss->c1 = UINT32_MAX;
}

void wrt_sum_stream_range(wrt_sum_stream *ss, uint32_t c0, uint32_t c1) {
    ss->c0 = c0;
    ss->c1 = c1;
}

uint64_t wrt_sum_stream_nnz(const wrt_sum_stream *ss) { return ss->cur->nnz; }

/* The end of the block that starts at column j0: columns until the sum's and the term's
 * entries in them reach the block size (one column at least). */
static uint32_t block_end(const wrt_sum_stream *ss, const wrt_csc *P, uint32_t j0) {
    const uint64_t *c = ss->cur->col;
    uint32_t n = ss->cur->n, j1 = j0 + 1;
    while (j1 < n && (c[j1 + 1] - c[j0]) + (P ? P->col[j1 + 1] - P->col[j0] : 0) <= ss->block) j1++;
    return j1;
}

/* Columns [j0, j1) of S + s P (P may be NULL: S's block alone), from the sum's file (read
 * in order) into *m. 0 on a read error. */
static int merged_block(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], uint32_t j0, uint32_t j1, wrt_csc *m) {
    wrt_csc a;
    if (!wrt_spill_read(ss->cur, j1 - j0, &a)) return 0;
    if (!P) {
        *m = a;
        return 1;
    }
    /* the term's columns as a view: its column starts index its own arrays */
    wrt_csc pv = {.n = j1 - j0, .nnz = P->col[j1] - P->col[j0], .col = P->col + j0, .row = P->row, .val = P->val};
    *m = wrt_csc_add3(&a, &pv, s);
    wrt_csc_free(&a);
    return 1;
}

/* The block's columns outside the kept range [c0, c1) emptied (block m starts at column j0) */
static void keep_range(const wrt_sum_stream *ss, uint32_t j0, wrt_csc *m) {
    if (ss->c0 <= j0 && (uint64_t)j0 + m->n <= ss->c1) return;
    uint64_t w = 0, k = 0;
    for (uint32_t c = 0; c < m->n; c++) {
        uint64_t end = m->col[c + 1];
        int keep = j0 + c >= ss->c0 && j0 + c < ss->c1;
        for (; k < end; k++) {
            if (!keep) continue;
            m->row[w] = m->row[k];
            memmove(&m->val[3 * w], &m->val[3 * k], 3 * sizeof *m->val);
            w++;
        }
        m->col[c + 1] = w;
    }
    m->nnz = w;
}

int wrt_sum_stream_sumsq(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq) {
    if (!wrt_spill_rewind(ss->cur)) return 0;
    double acc = *sumsq;
    for (uint32_t j0 = 0, n = ss->cur->n; j0 < n;) {
        uint32_t j1 = block_end(ss, P, j0);
        wrt_csc m;
        if (!merged_block(ss, P, s, j0, j1, &m)) return 0;
        keep_range(ss, j0, &m);
        acc = wrt_csc_sumsq(&m, acc);
        wrt_csc_free(&m);
        j0 = j1;
    }
    *sumsq = acc;
    return 1;
}

int wrt_sum_stream_add(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq) {
    wrt_spill next;
    if (!wrt_spill_rewind(ss->cur) || !wrt_spill_open(&next, ss->cur->n)) return 0;
    double acc = 0;
    int ok = 1;
    for (uint32_t j0 = 0, n = ss->cur->n; j0 < n && ok;) {
        uint32_t j1 = block_end(ss, P, j0);
        wrt_csc m;
        ok = merged_block(ss, P, s, j0, j1, &m);
        if (!ok) break;
        keep_range(ss, j0, &m);
        acc = wrt_csc_sumsq(&m, acc);
        ok = wrt_spill_append(&next, &m);
        wrt_csc_free(&m);
        j0 = j1;
    }
    if (ok) ok = wrt_spill_finish(&next);
    if (!ok) {
        wrt_spill_free(&next);
        return 0;
    }
    if (ss->cur == &ss->own) wrt_spill_free(&ss->own);
    ss->own = next;
    ss->cur = &ss->own;
    *sumsq = acc;
    return 1;
}

int wrt_sum_stream_final(wrt_sum_stream *ss, const wrt_csc *P, const double k[3], double *sumsq, double drop,
                         const wrt_csc_weights *W, int (*check)(void *user, uint64_t kept, uint64_t projected),
                         void *user, wrt_csc *out) {
    uint32_t n = ss->cur->n;
    memset(out, 0, sizeof *out);
    if (!wrt_spill_rewind(ss->cur)) return 0;
    out->n = n;
    out->col = wrt_xcalloc((size_t)n + 1, sizeof *out->col);
    uint64_t cap = 1, total = ss->cur->nnz + (P ? P->nnz : 0), done = 0, last = 0;
    out->row = wrt_xmalloc(cap * sizeof *out->row);
    out->val = wrt_xmalloc(3 * cap * sizeof *out->val);
    double acc = 0;
    int ret = 1;
    for (uint32_t j0 = 0; j0 < n;) {
        uint32_t j1 = block_end(ss, P, j0);
        wrt_csc m;
        if (!merged_block(ss, P, k, j0, j1, &m)) {
            ret = 0;
            break;
        }
        keep_range(ss, j0, &m);
        done += (ss->cur->col[j1] - ss->cur->col[j0]) + (P ? P->col[j1] - P->col[j0] : 0);
        if (P) acc = wrt_csc_sumsq(&m, acc);
        /* the block's columns compressed with their own column weights */
        wrt_csc_weights wb = {0};
        if (W)
            wb = (wrt_csc_weights){W->row_w, W->col_w ? W->col_w + j0 : NULL, W->power_w,
                                   W->boost_w ? W->boost_w + j0 : NULL, W->boost_lost};
        wrt_csc_compress(&m, drop, W ? &wb : NULL);
        if (out->nnz + m.nnz > cap) {
            while (cap < out->nnz + m.nnz) cap *= 2;
            out->row = wrt_xrealloc(out->row, cap * sizeof *out->row);
            out->val = wrt_xrealloc(out->val, 3 * cap * sizeof *out->val);
        }
        memcpy(&out->row[out->nnz], m.row, m.nnz * sizeof *m.row);
        memcpy(&out->val[3 * out->nnz], m.val, 3 * m.nnz * sizeof *m.val);
        for (uint32_t j = j0; j < j1; j++) out->col[j + 1] = out->nnz + m.col[j - j0 + 1];
        out->nnz += m.nnz;
        wrt_csc_free(&m);
        j0 = j1;
        /* at each tenth of the input, the kept entries' total projected from there (the
         * first tenth: what is kept so far) */
        uint64_t tenth = total ? done * 10 / total : 10;
        if (tenth == last) continue;
        last = tenth;
        uint64_t projected = tenth ? (uint64_t)((double)out->nnz * (double)total / (double)done) : out->nnz;
        if (check && !check(user, out->nnz, projected)) {
            ret = -1;
            break;
        }
    }
    if (ret != 1) {
        wrt_csc_free(out);
        return ret;
    }
    /* the arrays cut to the entries */
    out->row = wrt_xrealloc(out->row, (out->nnz ? out->nnz : 1) * sizeof *out->row);
    out->val = wrt_xrealloc(out->val, 3 * (out->nnz ? out->nnz : 1) * sizeof *out->val);
    if (P) *sumsq = acc;
    return 1;
}

void wrt_sum_stream_free(wrt_sum_stream *ss) {
    wrt_spill_free(&ss->own);
    memset(ss, 0, sizeof *ss);
}
