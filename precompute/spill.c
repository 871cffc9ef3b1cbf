/* spill.c: a sparse matrix in an unlinked scratch file (spill.h). The file holds the
 * entries in blocks of SPILL_BLOCK, each block its rows then its values; the column starts
 * stay in memory (8 bytes a column). Depends on sparse.h, wrt_common.h. */
#include "spill.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/wrt_common.h"

#define SPILL_BLOCK 65536u

int wrt_spill_open(wrt_spill *sp, uint32_t n) {
    memset(sp, 0, sizeof *sp);
    sp->f = tmpfile(); /* $TMPDIR or /tmp, unlinked */
    if (!sp->f) return 0;
    sp->n = n;
    sp->col = wrt_xcalloc((size_t)n + 1, sizeof *sp->col);
    sp->row = wrt_xmalloc(SPILL_BLOCK * sizeof *sp->row);
    sp->val = wrt_xmalloc(3 * SPILL_BLOCK * sizeof *sp->val);
    return 1;
}

/* The write buffer's entries out as one block. */
static int spill_flush(wrt_spill *sp) {
    size_t m = (size_t)sp->have;
    sp->have = 0;
    return m == 0 || (fwrite(sp->row, sizeof *sp->row, m, sp->f) == m && fwrite(sp->val, 3 * sizeof *sp->val, m, sp->f) == m);
}

int wrt_spill_append(wrt_spill *sp, const wrt_csc *m) {
    for (uint32_t j = 0; j < m->n; j++) sp->col[sp->ncols + j + 1] = sp->col[sp->ncols + j] + (m->col[j + 1] - m->col[j]);
    sp->ncols += m->n;
    for (uint64_t k = m->col[0], end = m->col[m->n]; k < end;) {
        uint64_t take = end - k < SPILL_BLOCK - sp->have ? end - k : SPILL_BLOCK - sp->have;
        memcpy(&sp->row[sp->have], &m->row[k], take * sizeof *sp->row);
        memcpy(&sp->val[3 * sp->have], &m->val[3 * k], 3 * take * sizeof *sp->val);
        sp->have += take;
        sp->nnz += take;
        k += take;
        if (sp->have == SPILL_BLOCK && !spill_flush(sp)) return 0;
    }
    return 1;
}

int wrt_spill_finish(wrt_spill *sp) {
    for (uint32_t j = sp->ncols; j < sp->n; j++) sp->col[j + 1] = sp->col[j]; /* columns never appended: empty */
    sp->ncols = sp->n;
    if (!spill_flush(sp) || fflush(sp->f) != 0) return 0;
    return wrt_spill_rewind(sp);
}

int wrt_spill_write(wrt_spill *sp, const wrt_csc *m) {
    if (!wrt_spill_open(sp, m->n)) return 0;
    if (wrt_spill_append(sp, m) && wrt_spill_finish(sp)) return 1;
    wrt_spill_free(sp);
    return 0;
}

int wrt_spill_rewind(wrt_spill *sp) {
    sp->base = sp->have = 0;
    sp->ncols = 0;
    return fseek(sp->f, 0, SEEK_SET) == 0;
}

/* The block holding entry k in the buffers (k at or past the current block's start). */
static int spill_reach(wrt_spill *sp, uint64_t k) {
    while (k >= sp->base + sp->have) {
        sp->base += sp->have;
        sp->have = sp->nnz - sp->base < SPILL_BLOCK ? sp->nnz - sp->base : SPILL_BLOCK;
        if (!sp->have) return 0;
        if (fread(sp->row, sizeof *sp->row, sp->have, sp->f) != sp->have ||
            fread(sp->val, 3 * sizeof *sp->val, sp->have, sp->f) != sp->have)
            return 0;
    }
    return 1;
}

int wrt_spill_read(wrt_spill *sp, uint32_t count, wrt_csc *out) {
    memset(out, 0, sizeof *out);
    if (count > sp->n - sp->ncols) return 0;
    uint64_t k0 = sp->col[sp->ncols], k1 = sp->col[sp->ncols + count];
    out->n = count;
    out->nnz = k1 - k0;
    out->col = wrt_xmalloc(((size_t)count + 1) * sizeof *out->col);
    for (uint32_t j = 0; j <= count; j++) out->col[j] = sp->col[sp->ncols + j] - k0;
    out->row = wrt_xmalloc((out->nnz ? out->nnz : 1) * sizeof *out->row);
    out->val = wrt_xmalloc((out->nnz ? out->nnz : 1) * 3 * sizeof *out->val);
    for (uint64_t k = k0; k < k1;) {
        if (!spill_reach(sp, k)) {
            wrt_csc_free(out);
            return 0;
        }
        uint64_t take = sp->base + sp->have - k < k1 - k ? sp->base + sp->have - k : k1 - k;
        memcpy(&out->row[k - k0], &sp->row[k - sp->base], take * sizeof *out->row);
        memcpy(&out->val[3 * (k - k0)], &sp->val[3 * (k - sp->base)], 3 * take * sizeof *out->val);
        k += take;
    }
    sp->ncols += count;
    return 1;
}

/* Entries [k, k + count) of a finished file, at most the rest of their block, read at
 * their offsets (pread: the stream's position and buffers are not touched). */
static int spill_pread(const wrt_spill *sp, uint64_t k, uint64_t count, uint32_t *row, float *val) {
    uint64_t blk = k / SPILL_BLOCK, in = k % SPILL_BLOCK, len = sp->nnz - blk * SPILL_BLOCK;
    if (len > SPILL_BLOCK) len = SPILL_BLOCK;
    off_t at = (off_t)(blk * SPILL_BLOCK * (sizeof *row + 3 * sizeof *val));
    size_t rb = (size_t)count * sizeof *row, vb = (size_t)count * 3 * sizeof *val;
    int fd = fileno(sp->f);
    return pread(fd, row, rb, at + (off_t)(in * sizeof *row)) == (ssize_t)rb &&
           pread(fd, val, vb, at + (off_t)(len * sizeof *row + in * 3 * sizeof *val)) == (ssize_t)vb;
}

int wrt_spill_apply(const wrt_spill *sp, const double *x, double *y) {
    uint32_t *row = wrt_xmalloc(SPILL_BLOCK * sizeof *row);
    float *val = wrt_xmalloc(3 * SPILL_BLOCK * sizeof *val);
    int ok = 1;
    uint64_t base = 0, have = 0;
    for (uint32_t j = 0; j < sp->n && ok; j++) {
        const double *xj = &x[3 * j];
        int zero = xj[0] == 0 && xj[1] == 0 && xj[2] == 0;
        for (uint64_t k = sp->col[j]; k < sp->col[j + 1]; k++) {
            if (k >= base + have) {
                base = k;
                have = SPILL_BLOCK - k % SPILL_BLOCK;
                if (have > sp->nnz - k) have = sp->nnz - k;
                if (!(ok = spill_pread(sp, k, have, row, val))) break;
            }
            if (zero) continue;
            uint32_t i = row[k - base];
            const float *v = &val[3 * (k - base)];
            for (int c = 0; c < 3; c++) y[3 * i + c] += (double)v[c] * xj[c];
        }
    }
    free(row); free(val);
    return ok;
}

void wrt_spill_free(wrt_spill *sp) {
    if (sp->f) fclose(sp->f);
    free(sp->col); free(sp->row); free(sp->val);
    memset(sp, 0, sizeof *sp);
}
