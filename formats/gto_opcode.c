/* gto_opcode.c: the compact operator of .gto version 2.0 (section opcode; GTO_FORMAT.md
 * "The compact operator"; issue 23). Each column's entries are cut into blocks of up to
 * 64 whose rows step by less than 256; a block has its first row and a base exponent,
 * an entry a u8 row delta and a 32-bit code: three 10-bit signed mantissas sharing a
 * 2-bit exponent above the block's base (about 5.5 bytes an entry instead of 16; the
 * study behind the choice is docs/bench.md, "Compact entries"). The encoder (used by the
 * writer) and the section's checker (reader and writer). Part of the runtime library
 * for the checker. Depends on gto_layout.h and libm. */
#include "gto_layout.h"

#include <inttypes.h>
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

/* One block's base and codes: entries [a, b) of vals (3 channels each), 32-bit codes. */
static int16_t encode_block(const float *vals, uint64_t a, uint64_t b, void *out) {
    uint32_t *codes = out;
    int emax = WRT_GTO_BASE_MIN;
    for (uint64_t i = a; i < b; i++) {
        double m = max3(vals + i * 3);
        if (m > 0) { int e = gto_step_exp(m, MANT_MAX); if (e > emax) emax = e; }
    }
    int base = emax - 3;
    if (base < WRT_GTO_BASE_MIN) base = WRT_GTO_BASE_MIN;
    if (base > WRT_GTO_BASE_MAX) base = WRT_GTO_BASE_MAX; /* only for values the float checks refuse */
    for (uint64_t i = a; i < b; i++) {
        double m = max3(vals + i * 3);
        int e = m > 0 ? gto_step_exp(m, MANT_MAX) : base;
        if (e < base) e = base;
        if (e > base + 3) e = base + 3;
        uint32_t code = (uint32_t)(e - base) << 30;
        for (int c = 0; c < 3; c++) {
            double q = nearbyint(ldexp(vals[i * 3 + c], -e));
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

uint8_t *gto_blocks_encode(uint32_t ncols, const uint64_t *col_start, const uint32_t *rows, const float *vals,
                           uint32_t codec, uint32_t code_bytes, gto_block_coder code, uint64_t *size) {
    uint64_t nnz = col_start[ncols], nb = 0;
    for (uint32_t s = 0; s < ncols; s++)
        for (uint64_t a = col_start[s]; a < col_start[s + 1]; a = gto_block_end(rows, a, col_start[s + 1])) nb++;
    gto_opcode_layout o = gto_blocks_place(ncols, nb, nnz, code_bytes);
    uint8_t *p = calloc(1, o.size);
    if (!p) return NULL;
    gto_opcode_head *h = (gto_opcode_head *)p;
    h->codec = codec;
    h->block_max = WRT_GTO_BLOCK_MAX;
    h->nblocks = nb;
    h->nnz = nnz;
    uint32_t *bcol = (uint32_t *)(p + o.bcol);
    wrt_gto_block *blk = (wrt_gto_block *)(p + o.blocks);
    uint8_t *deltas = p + o.deltas;
    uint64_t k = 0;
    for (uint32_t s = 0; s < ncols; s++) {
        bcol[s] = (uint32_t)k;
        uint64_t end = col_start[s + 1];
        for (uint64_t a = col_start[s], b; a < end; a = b, k++) {
            b = gto_block_end(rows, a, end);
            blk[k].row0 = rows[a];
            blk[k].n = (uint8_t)(b - a);
            blk[k].base = code(vals, a, b, p + o.codes);
            deltas[a] = 0;
            for (uint64_t i = a + 1; i < b; i++) deltas[i] = (uint8_t)(rows[i] - rows[i - 1]);
        }
    }
    bcol[ncols] = (uint32_t)k;
    *size = o.size;
    return p;
}

uint8_t *gto_opcode_encode(uint32_t nfuncs, const uint64_t *col_start, const uint32_t *rows,
                           const float *vals, uint64_t *size) {
    return gto_blocks_encode(nfuncs, col_start, rows, vals, WRT_GTO_CODEC, 4, encode_block, size);
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

void gto_check_opcode(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto *g = v->g;
    gto_opcode_layout o = gto_opcode_place(g->nfuncs, g->nblocks, g->nnz);
    if (first + n != o.size) return; /* the whole section, once its last chunk is summed */
    const gto_opcode_head *h = (const gto_opcode_head *)base;
    if (h->codec != WRT_GTO_CODEC || h->block_max != WRT_GTO_BLOCK_MAX)
        return gto_obad(v, "unknown encoding %u with blocks of %u (this reader: %d, %d)", h->codec, h->block_max,
                    WRT_GTO_CODEC, WRT_GTO_BLOCK_MAX);
    if (h->nblocks != g->nblocks || h->nnz != g->nnz || !gto_zero_bytes(h->reserved, 0, sizeof h->reserved))
        return gto_obad(v, "header: %" PRIu64 " blocks and %" PRIu64 " entries, expected %" PRIu64 " and %" PRIu64
                    ", or reserved bytes not zero", h->nblocks, h->nnz, g->nblocks, g->nnz);
    if (!gto_zero_bytes(base, o.bcol + 4 * ((uint64_t)g->nfuncs + 1), o.blocks) ||
        !gto_zero_bytes(base, o.blocks + 8 * g->nblocks, o.codes) || !gto_zero_bytes(base, o.codes + 4 * g->nnz, o.deltas))
        return gto_obad(v, "non-zero padding between its arrays");
    const uint32_t *bcol = (const uint32_t *)(base + o.bcol), *codes = (const uint32_t *)(base + o.codes);
    const wrt_gto_block *blk = (const wrt_gto_block *)(base + o.blocks);
    const uint64_t *cs = g->col_start;
    if (bcol[0] != 0 || bcol[g->nfuncs] != g->nblocks)
        return gto_obad(v, "bcol runs from %u to %u, expected 0 to %" PRIu64, bcol[0], bcol[g->nfuncs], g->nblocks);
    for (uint32_t s = 0; s < g->nfuncs; s++) /* so every column's blocks lie inside */
        if (bcol[s + 1] < bcol[s])
            return gto_obad(v, "bcol not monotone at column %u (%u after %u)", s + 1, bcol[s + 1], bcol[s]);
    for (uint32_t s = 0; s < g->nfuncs && !v->bad; s++)
        gto_check_column_blocks(v, "column", "col_start", blk, base + o.deltas, s, bcol[s], bcol[s + 1], cs[s],
                                cs[s + 1], NULL);
    uint32_t any = 0;
    for (uint64_t i = 0; i < g->nnz; i++) {
        uint32_t c = codes[i];
        any |= ((c & 0x3ffu) == 0x200u) | (((c >> 10) & 0x3ffu) == 0x200u) | (((c >> 20) & 0x3ffu) == 0x200u);
    }
    if (any)
        for (uint64_t i = 0; i < g->nnz; i++)
            for (int c = 0; c < 3; c++)
                if (((codes[i] >> (10 * c)) & 0x3ffu) == 0x200u)
                    return gto_obad(v, "entry %" PRIu64 " channel %d: mantissa -512 (the encoding uses -511..511)", i, c);
}
