/* series_stream.h: the series' sum S = T + P_2 + ... held in a scratch file between
 * bounces instead of memory (series_stream.c, issue 22). Each bounce merges the file with
 * the new term by column blocks into a new file and measures the sum's norm on the way;
 * the last pass adds the tail, compresses the columns for the stored operator and keeps
 * only those. The entries, their order and every rounding are wrt_csc_add3's and
 * wrt_csc_compress's, column by column, so the result is the in-memory series' to the bit
 * whatever the block size. Depends on spill.h, sparse.h. */
#ifndef WRT_SERIES_STREAM_H
#define WRT_SERIES_STREAM_H

#include "spill.h"

/* Entries of the sum and the term read per block when wrt_bake_options.series_block is 0 */
#define WRT_SERIES_BLOCK_DEFAULT (1u << 20)

/* A term whose entries, with the overlay's, are at most the sum's over this is kept in the
 * overlay instead of rewriting the sum's file (wrt_sum_stream_add) */
#define WRT_SUM_OVERLAY_SHARE 8
/* Blocks the last pass (wrt_sum_stream_final) holds at once, each of 1 / this of the
 * block size */
#define WRT_SUM_FINAL_GROUP 2

typedef struct wrt_sum_stream {
    wrt_spill own;     /* the sum's file once a term has been added */
    wrt_spill *cur;    /* the sum's file: &own, or the first term's file (not owned) */
    uint64_t block;    /* entries per block */
    uint32_t c0, c1;   /* the columns kept (wrt-bake-mpi's share of the sum); all by default */
    /* The sum is the file's entries with the overlay's in their places: the overlay holds
     * the sum's values (n columns, its own arrays) wherever a term added since the file
     * was written has an entry (col NULL: none). */
    wrt_csc over;
    uint64_t nnz;      /* the sum's entries: the file's and the overlay's others */
    uint64_t kept, written; /* the terms added in the overlay, and by rewriting the file */
    int threads;       /* the last pass's (wrt_sum_stream_final) */
} wrt_sum_stream;

/* The sum starts as the matrix in `first` (a finished spill, which must outlive the
 * stream; it is read, never written). */
void wrt_sum_stream_start(wrt_sum_stream *ss, wrt_spill *first, uint64_t block, int threads);
/* From the next pass on, the sum keeps only columns [c0, c1) (the others are dropped:
 * a rank's share of the sum, docs/mpi.md). */
void wrt_sum_stream_range(wrt_sum_stream *ss, uint32_t c0, uint32_t c1);
/* *sumsq continued over the values of S + s P (P may be NULL: S alone) in storage order,
 * as wrt_sum_stream_add's (the same bits from the same start), nothing written. 0 on an
 * I/O error. */
int wrt_sum_stream_sumsq(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq);
/* The sum's entries now. */
uint64_t wrt_sum_stream_nnz(const wrt_sum_stream *ss);
/* S += s P, per channel (P has the sum's columns); *sumsq the sum of the squares of the
 * new sum's values in storage order (wrt_csc_sumsq's, the same bits). 0 on an I/O error.
 * A small term (with the overlay, at most 1 / WRT_SUM_OVERLAY_SHARE of the sum's entries;
 * all columns kept) goes to the overlay: the file is read, not rewritten. The values are
 * the same either way: each entry is the file's, then every term's added in order with
 * wrt_csc_add3's rounding. */
int wrt_sum_stream_add(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq);
/* The last pass: S + k P where P is not NULL (*sumsq as above, else untouched), each
 * column compressed by wrt_csc_compress(drop, W), into *out (in memory, its own arrays).
 * check(user, entries kept so far, their projected total) is called at each tenth of the
 * input and stops the pass when it returns 0 (a memory budget). The blocks are merged and
 * compressed WRT_SUM_FINAL_GROUP at a time on the stream's threads (column by column: the
 * same entries).
 * Returns 1, 0 on an I/O error, -1 where check stopped it. */
int wrt_sum_stream_final(wrt_sum_stream *ss, const wrt_csc *P, const double k[3], double *sumsq, double drop,
                         const wrt_csc_weights *W, int (*check)(void *user, uint64_t kept, uint64_t projected),
                         void *user, wrt_csc *out);
void wrt_sum_stream_free(wrt_sum_stream *ss);

#endif
