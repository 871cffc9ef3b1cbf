/* gto_opcode.c: the compact operator of .gto versions 2.0 (section opcode) and 3.0 (section
 * opstream, 261: the same blocks, codes and deltas without the blocks' counts and
 * col_start, which the reader rebuilds; GTO_FORMAT.md "The compact operator's stream").
 * Version 2.0's section opcode (GTO_FORMAT.md
 * "The compact operator"; issue 23). Each column's entries are cut into blocks of up to
 * 64 whose rows step by less than 256; a block has its first row and a base exponent,
 * an entry a u8 row delta and a 32-bit code: three 10-bit signed mantissas sharing a
 * 2-bit exponent above the block's base (about 5.5 bytes an entry instead of 16; the
 * study behind the choice is docs/bench.md, "Compact entries"). The encoder (used by the
 * writer) and the section's checker (reader and writer). Part of the runtime library
 * for the checker. Depends on gto_layout.h and libm. */
#include "gto_layout.h"

#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MANT_MAX 511 /* |mantissa| <= 511: 10 bits, two's complement, -512 unused */

/* The smallest E with mant_max * 2^E >= m (m > 0, finite; gto_layout.h). */
int gto_step_exp(double m, double mant_max) {
    int k;
    double f = frexp(m / mant_max, &k); /* m / mant_max = f 2^k, f in [0.5, 1) */
    return f == 0.5 ? k - 1 : k;
}

static double max3(const float *v) { return fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2]))); }

/* One block's base and codes: entries [a, b) of vals (3 channels each), 32-bit codes.
 * Each entry's step exponent is found once (a block holds at most WRT_GTO_BLOCK_MAX), and
 * ldexp(v, -e) is v times 2^-e: the same value (a float times a power of two within a
 * double's range is exact), without a call per channel (the encoder was half a second
 * of one thread on the 12 x 12 maze's 20M entries). */
static int16_t encode_block(const float *vals, uint64_t a, uint64_t b, void *out) {
    uint32_t *codes = out;
    int emax = WRT_GTO_BASE_MIN, es[WRT_GTO_BLOCK_MAX];
    for (uint64_t i = a; i < b; i++) {
        double m = max3(vals + i * 3);
        es[i - a] = m > 0 ? gto_step_exp(m, MANT_MAX) : INT_MIN;
        if (m > 0 && es[i - a] > emax) emax = es[i - a];
    }
    int base = emax - 3;
    if (base < WRT_GTO_BASE_MIN) base = WRT_GTO_BASE_MIN;
    if (base > WRT_GTO_BASE_MAX) base = WRT_GTO_BASE_MAX; /* only for values the float checks refuse */
    double scale[4];
    for (int k = 0; k < 4; k++) scale[k] = ldexp(1.0, -(base + k));
    for (uint64_t i = a; i < b; i++) {
        int e = es[i - a];
        if (e < base) e = base;
        if (e > base + 3) e = base + 3;
        uint32_t code = (uint32_t)(e - base) << 30;
        for (int c = 0; c < 3; c++) {
            double q = nearbyint((double)vals[i * 3 + c] * scale[e - base]);
            if (q > MANT_MAX) q = MANT_MAX;
            if (q < -MANT_MAX) q = -MANT_MAX;
            code |= ((uint32_t)(int32_t)q & 0x3ffu) << (10 * c);
        }
        codes[i] = code;
    }
    return (int16_t)base;
}

/* The end of the block that starts at entry a of a column ending at `end` (gto_layout.h;
 * section kcode's blocks are cut the same way). */
uint64_t gto_block_end(const uint32_t *rows, uint64_t a, uint64_t end) {
    uint64_t b = a + 1;
    while (b < end && b - a < WRT_GTO_BLOCK_MAX && rows[b] - rows[b - 1] < 256) b++;
    return b;
}

/* Cuts ncols columns of entries into blocks (gto_block_end) in column order: the number
 * of blocks, and with bcol given, each column's first block in bcol, each entry's row
 * delta (0 at a block's first) and, for block k of entries [a, b), block(ctx, k, a, b). */
typedef void (*block_fn)(void *ctx, uint64_t k, uint64_t a, uint64_t b);
static uint64_t cut_blocks(uint32_t ncols, const uint64_t *col_start, const uint32_t *rows, uint32_t *bcol,
                           uint8_t *deltas, block_fn block, void *ctx) {
    uint64_t k = 0;
    for (uint32_t s = 0; s < ncols; s++) {
        if (bcol) bcol[s] = (uint32_t)k;
        uint64_t end = col_start[s + 1];
        for (uint64_t a = col_start[s], b; a < end; a = b, k++) {
            b = gto_block_end(rows, a, end);
            if (!bcol) continue;
            block(ctx, k, a, b);
            deltas[a] = 0;
            for (uint64_t i = a + 1; i < b; i++) deltas[i] = (uint8_t)(rows[i] - rows[i - 1]);
        }
    }
    if (bcol) bcol[ncols] = (uint32_t)k;
    return k;
}

/* A new compact payload of `size` bytes with its header, or NULL. */
static uint8_t *new_payload(uint64_t size, uint32_t codec, uint64_t nb, uint64_t nnz) {
    uint8_t *p = calloc(1, size);
    if (!p) return NULL;
    gto_opcode_head *h = (gto_opcode_head *)p;
    h->codec = codec;
    h->block_max = WRT_GTO_BLOCK_MAX;
    h->nblocks = nb;
    h->nnz = nnz;
    return p;
}

/* Where the blocks' records go: 2.0's wrt_gto_block (blk) or 3.0's row0 and base arrays. */
typedef struct block_out {
    const uint32_t *rows; const float *vals;
    gto_block_coder code; uint8_t *codes;
    wrt_gto_block *blk;
    uint32_t *row0; int8_t *base;
} block_out;
static void put_block(void *ctx, uint64_t k, uint64_t a, uint64_t b) {
    block_out *o = ctx;
    int16_t base = o->code(o->vals, a, b, o->codes);
    if (o->blk) o->blk[k] = (wrt_gto_block){o->rows[a], (uint8_t)(b - a), 0, base};
    else { o->row0[k] = o->rows[a]; o->base[k] = (int8_t)base; }
}

uint8_t *gto_blocks_encode(uint32_t ncols, const uint64_t *col_start, const uint32_t *rows, const float *vals,
                           uint32_t codec, uint32_t code_bytes, gto_block_coder code, uint64_t *size) {
    uint64_t nnz = col_start[ncols], nb = cut_blocks(ncols, col_start, rows, NULL, NULL, NULL, NULL);
    gto_opcode_layout o = gto_blocks_place(ncols, nb, nnz, code_bytes);
    uint8_t *p = new_payload(o.size, codec, nb, nnz);
    if (!p) return NULL;
    block_out bo = {rows, vals, code, p + o.codes, (wrt_gto_block *)(p + o.blocks), NULL, NULL};
    cut_blocks(ncols, col_start, rows, (uint32_t *)(p + o.bcol), p + o.deltas, put_block, &bo);
    *size = o.size;
    return p;
}

uint8_t *gto_opcode_encode(uint32_t nfuncs, const uint64_t *col_start, const uint32_t *rows,
                           const float *vals, uint64_t *size) {
    return gto_blocks_encode(nfuncs, col_start, rows, vals, WRT_GTO_CODEC, 4, encode_block, size);
}

/* Section opstream (3.0): the blocks cut and coded as opcode's, laid out without their
 * counts (a block's first delta, 0, marks its start) and without col_start. */
uint8_t *gto_opstream_encode(uint32_t nfuncs, const uint64_t *col_start, const uint32_t *rows,
                             const float *vals, uint64_t *size) {
    uint64_t nnz = col_start[nfuncs], nb = cut_blocks(nfuncs, col_start, rows, NULL, NULL, NULL, NULL);
    gto_opstream_layout o = gto_opstream_place(nfuncs, nb, nnz);
    uint8_t *p = new_payload(o.size, WRT_GTO_CODEC3, nb, nnz);
    if (!p) return NULL;
    block_out bo = {rows, vals, encode_block, p + o.codes, NULL, (uint32_t *)(p + o.row0), (int8_t *)(p + o.base)};
    cut_blocks(nfuncs, col_start, rows, (uint32_t *)(p + o.bcol), p + o.deltas, put_block, &bo);
    *size = o.size;
    return p;
}

/* ------------------------------------------------------------------------------------
 * The checker: the header, zero padding, bcol from 0 to nblocks, each column's blocks
 * holding its entries (col_start), each block's count, reserved byte and base in range,
 * rows strictly ascending within the column and below nfuncs, and no mantissa -512.
 * ---------------------------------------------------------------------------------- */

void gto_obad(vctx *v, const char *fmt, ...) {
    if (v->bad) return;
    v->bad = 1;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(v->err, sizeof v->err, fmt, ap);
    va_end(ap);
}

int gto_zero_bytes(const uint8_t *p, uint64_t a, uint64_t b) {
    for (uint64_t i = a; i < b; i++)
        if (p[i]) return 0;
    return 1;
}

/* Column s's blocks [k0, k1) against its entries [e0, e1), for both compact sections
 * (`what` names a column in the messages: "column", "K column"; `starts` its entries'
 * array: "col_start", "kcol_start"): each block's count, reserved byte and base, rows
 * strictly ascending from block to block, a block's first delta 0 and the others not,
 * and the rows below nfuncs: every entry's through row_ok when given (which records the
 * problem and returns 0), else the last row of each block. */
void gto_check_column_blocks(vctx *v, const char *what, const char *starts, const wrt_gto_block *blk,
                             const uint8_t *d, uint32_t s, uint64_t k0, uint64_t k1, uint64_t e0, uint64_t e1,
                             gto_row_check row_ok) {
    uint32_t nf = v->g->nfuncs;
    uint64_t e = e0;
    int64_t last = -1;
    for (uint64_t k = k0; k < k1; k++) {
        const wrt_gto_block *b = &blk[k];
        if (b->n == 0 || b->n > WRT_GTO_BLOCK_MAX || b->reserved)
            return gto_obad(v, "block %" PRIu64 " (%s %u): %u entries (1..%d) or reserved byte %u", k, what, s, b->n,
                        WRT_GTO_BLOCK_MAX, b->reserved);
        if (b->base < WRT_GTO_BASE_MIN || b->base > WRT_GTO_BASE_MAX)
            return gto_obad(v, "block %" PRIu64 " (%s %u): base exponent %d outside [%d, %d]", k, what, s, b->base,
                        WRT_GTO_BASE_MIN, WRT_GTO_BASE_MAX);
        if (b->n > e1 - e)
            return gto_obad(v, "%s %u: its blocks hold more than its %" PRIu64 " entries (%s)", what, s, e1 - e0, starts);
        if ((int64_t)b->row0 <= last)
            return gto_obad(v, "block %" PRIu64 " (%s %u): first row %u not above the previous block's last, %" PRId64,
                        k, what, s, b->row0, last);
        if (d[e] != 0)
            return gto_obad(v, "entry %" PRIu64 " (%s %u): row delta %u on a block's first entry (must be 0)", e, what, s,
                        d[e]);
        uint64_t row = b->row0;
        for (uint64_t i = e; i < e + b->n; i++) {
            if (i > e && d[i] == 0)
                return gto_obad(v, "entry %" PRIu64 " (%s %u): row delta 0, rows must ascend", i, what, s);
            row += i > e ? d[i] : 0;
            if (row_ok && !row_ok(v, s, i, row)) return;
        }
        if (row >= nf)
            return gto_obad(v, "block %" PRIu64 " (%s %u): rows up to %" PRIu64 " out of range (%u functions)", k, what,
                        s, row, nf);
        last = (int64_t)row;
        e += b->n;
    }
    if (e != e1)
        return gto_obad(v, "%s %u: its blocks hold %" PRIu64 " entries, %s says %" PRIu64, what, s, e - e0, starts,
                    e1 - e0);
}

/* No mantissa -512 among the codes (the encoding uses -511..511). */
static void check_mantissas(vctx *v, const uint32_t *codes, uint64_t nnz) {
    uint32_t any = 0;
    for (uint64_t i = 0; i < nnz; i++) {
        uint32_t c = codes[i];
        any |= ((c & 0x3ffu) == 0x200u) | (((c >> 10) & 0x3ffu) == 0x200u) | (((c >> 20) & 0x3ffu) == 0x200u);
    }
    if (any)
        for (uint64_t i = 0; i < nnz; i++)
            for (int c = 0; c < 3; c++)
                if (((codes[i] >> (10 * c)) & 0x3ffu) == 0x200u)
                    return gto_obad(v, "entry %" PRIu64 " channel %d: mantissa -512 (the encoding uses -511..511)", i, c);
}

/* The header of a compact section: its codec, blocks of 64, the counts of the layout. */
static int check_head(vctx *v, const uint8_t *base, uint32_t codec, uint64_t nblocks, uint64_t nnz) {
    const gto_opcode_head *h = (const gto_opcode_head *)base;
    if (h->codec != codec || h->block_max != WRT_GTO_BLOCK_MAX) {
        gto_obad(v, "unknown encoding %u with blocks of %u (this reader: %u, %d)", h->codec, h->block_max, codec,
                 WRT_GTO_BLOCK_MAX);
        return 0;
    }
    if (h->nblocks != nblocks || h->nnz != nnz || !gto_zero_bytes(h->reserved, 0, sizeof h->reserved)) {
        gto_obad(v, "header: %" PRIu64 " blocks and %" PRIu64 " entries, expected %" PRIu64 " and %" PRIu64
                 ", or reserved bytes not zero", h->nblocks, h->nnz, nblocks, nnz);
        return 0;
    }
    return 1;
}

/* bcol (ncols + 1) from 0 to nblocks, never decreasing. */
static int check_bcol(vctx *v, const uint32_t *bcol, uint32_t ncols, uint64_t nblocks) {
    if (bcol[0] != 0 || bcol[ncols] != nblocks) {
        gto_obad(v, "bcol runs from %u to %u, expected 0 to %" PRIu64, bcol[0], bcol[ncols], nblocks);
        return 0;
    }
    for (uint32_t s = 0; s < ncols; s++) /* so every column's blocks lie inside */
        if (bcol[s + 1] < bcol[s]) {
            gto_obad(v, "bcol not monotone at column %u (%u after %u)", s + 1, bcol[s + 1], bcol[s]);
            return 0;
        }
    return 1;
}

/* Section opstream (3.0), once its last chunk is summed: the header and zero padding,
 * bcol, then the blocks in column order: block k starts at the entry after block k - 1's
 * last, with delta 0, and runs to the next delta 0 (or the last entry), 1..64 entries;
 * its base in range, its first row above the previous block's last in the column, its
 * last row below nfuncs. The blocks must cover the entries exactly; each column's first
 * entry is col_start, rebuilt into v->col_out (the reader) or compared with the
 * writer's. No mantissa -512. */
void gto_check_opstream(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto *g = v->g;
    uint32_t nf = g->nfuncs;
    uint64_t nnz = g->nnz, nb = g->nblocks;
    gto_opstream_layout o = gto_opstream_place(nf, nb, nnz);
    if (first + n != o.size) return; /* the whole section, once its last chunk is summed */
    if (!check_head(v, base, WRT_GTO_CODEC3, nb, nnz)) return;
    if (!gto_zero_bytes(base, o.bcol + 4 * ((uint64_t)nf + 1), o.row0) || !gto_zero_bytes(base, o.row0 + 4 * nb, o.codes) ||
        !gto_zero_bytes(base, o.codes + 4 * nnz, o.base) || !gto_zero_bytes(base, o.base + nb, o.deltas))
        return gto_obad(v, "non-zero padding between its arrays");
    const uint32_t *bcol = (const uint32_t *)(base + o.bcol), *row0 = (const uint32_t *)(base + o.row0);
    const int8_t *bases = (const int8_t *)(base + o.base);
    const uint8_t *d = base + o.deltas;
    if (!check_bcol(v, bcol, nf, nb)) return;
    uint64_t e = 0;
    for (uint32_t s = 0; s < nf; s++) {
        if (v->col_out) v->col_out[s] = e;
        else if (g->col_start[s] != e)
            return gto_obad(v, "column %u: its blocks start at entry %" PRIu64 ", col_start says %" PRIu64, s, e,
                            g->col_start[s]);
        int64_t last = -1;
        for (uint64_t k = bcol[s]; k < bcol[s + 1]; k++) {
            if (e >= nnz)
                return gto_obad(v, "block %" PRIu64 " (column %u): starts past the last of the %" PRIu64 " entries", k,
                                s, nnz);
            if (d[e] != 0)
                return gto_obad(v, "entry %" PRIu64 " (column %u): row delta %u where block %" PRIu64 " starts (must be 0)",
                                e, s, d[e], k);
            if (bases[k] < WRT_GTO_BASE_MIN || bases[k] > WRT_GTO_BASE_MAX)
                return gto_obad(v, "block %" PRIu64 " (column %u): base exponent %d outside [%d, %d]", k, s, bases[k],
                                WRT_GTO_BASE_MIN, WRT_GTO_BASE_MAX);
            if ((int64_t)row0[k] <= last)
                return gto_obad(v, "block %" PRIu64 " (column %u): first row %u not above the previous block's last, %"
                                PRId64, k, s, row0[k], last);
            uint64_t row = row0[k], e0 = e;
            for (e++; e < nnz && d[e] != 0; e++) row += d[e];
            if (e - e0 > WRT_GTO_BLOCK_MAX)
                return gto_obad(v, "block %" PRIu64 " (column %u): %" PRIu64 " entries (1..%d)", k, s, e - e0,
                                WRT_GTO_BLOCK_MAX);
            if (row >= nf)
                return gto_obad(v, "block %" PRIu64 " (column %u): rows up to %" PRIu64 " out of range (%u functions)", k,
                                s, row, nf);
            last = (int64_t)row;
        }
    }
    if (e != nnz)
        return gto_obad(v, "its blocks hold %" PRIu64 " entries, the header says %" PRIu64, e, nnz);
    if (v->col_out) v->col_out[nf] = e;
    else if (g->col_start[nf] != e)
        return gto_obad(v, "its blocks hold %" PRIu64 " entries, col_start says %" PRIu64, e, g->col_start[nf]);
    check_mantissas(v, (const uint32_t *)(base + o.codes), nnz);
}

void gto_check_opcode(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto *g = v->g;
    gto_opcode_layout o = gto_opcode_place(g->nfuncs, g->nblocks, g->nnz);
    if (first + n != o.size) return; /* the whole section, once its last chunk is summed */
    if (!check_head(v, base, WRT_GTO_CODEC, g->nblocks, g->nnz)) return;
    if (!gto_zero_bytes(base, o.bcol + 4 * ((uint64_t)g->nfuncs + 1), o.blocks) ||
        !gto_zero_bytes(base, o.blocks + 8 * g->nblocks, o.codes) || !gto_zero_bytes(base, o.codes + 4 * g->nnz, o.deltas))
        return gto_obad(v, "non-zero padding between its arrays");
    const uint32_t *bcol = (const uint32_t *)(base + o.bcol), *codes = (const uint32_t *)(base + o.codes);
    const wrt_gto_block *blk = (const wrt_gto_block *)(base + o.blocks);
    const uint64_t *cs = g->col_start;
    if (!check_bcol(v, bcol, g->nfuncs, g->nblocks)) return;
    for (uint32_t s = 0; s < g->nfuncs && !v->bad; s++)
        gto_check_column_blocks(v, "column", "col_start", blk, base + o.deltas, s, bcol[s], bcol[s + 1], cs[s],
                                cs[s + 1], NULL);
    check_mantissas(v, codes, g->nnz);
}
