/* spill.h: a sparse matrix of RGB entries held in an unlinked scratch file instead of
 * memory (spill.c): written column by column in order, read back column by column in
 * order, or applied to a vector. The series keeps T there for its power iteration and,
 * when it streams, its sum S between bounces (series_stream.c): the file's pages are the
 * page cache's, which the system can write out and drop, not the bake's resident memory;
 * the file goes with the process however it ends. Depends on sparse.h. Not thread-safe:
 * one reader or writer at a time (wrt_spill_apply apart: it has its own buffers). */
#ifndef WRT_SPILL_H
#define WRT_SPILL_H

#include <stdio.h>

#include "sparse.h"

typedef struct wrt_spill {
    FILE *f;
    uint32_t n;         /* the matrix's columns (and rows) */
    uint32_t ncols;     /* columns written so far, or read so far */
    uint64_t nnz, *col; /* entries written; column starts (n + 1), complete once written */
    uint32_t *row;      /* one block's rows and values: the write buffer, or the read one */
    float *val;
    uint64_t base, have; /* reading: the block in the buffers holds entries [base, base + have) */
} wrt_spill;

/* An empty matrix of n columns in a new scratch file. 0 where no file could be made
 * (*sp then holds nothing to free). */
int wrt_spill_open(wrt_spill *sp, uint32_t n);
/* Appends the columns of m (m->n of them, the next ones in order; rows are the whole
 * matrix's). 0 on a write error. */
int wrt_spill_append(wrt_spill *sp, const wrt_csc *m);
/* Ends the writing (the last block out, the file flushed); the file is then read from
 * its start. 0 on a write error. */
int wrt_spill_finish(wrt_spill *sp);
/* The whole of m in a new scratch file: open, append, finish. 0 where it failed. */
int wrt_spill_write(wrt_spill *sp, const wrt_csc *m);
/* Back to the start for reading. 0 on a seek error. */
int wrt_spill_rewind(wrt_spill *sp);
/* The next columns [ncols, ncols + count) read into out (out->n = count, its own arrays,
 * malloc'd, column starts from 0). 0 on a read error (out then empty). */
int wrt_spill_read(wrt_spill *sp, uint32_t count, wrt_csc *out);
/* y += M x of a finished file: wrt_csc_apply's operations in its order (the same bits).
 * It reads at the entries' offsets with its own buffers, so it may run beside a reader of
 * the same file (the sum's first state is T's file). 0 on a read error. */
int wrt_spill_apply(const wrt_spill *sp, const double *x, double *y);
/* Closes the file and frees the arrays; a zeroed or freed one is a no-op. */
void wrt_spill_free(wrt_spill *sp);

#endif
