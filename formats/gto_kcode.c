/* gto_kcode.c: the compact first-bounce operator K of .gto version 2.0 (critical section
 * kcode, 260, in place of krows and kvals; GTO_FORMAT.md "The compact first-bounce
 * operator"; issue 23). K is one channel; its columns are cut into blocks as the
 * operator's (up to 64 entries, row steps below 256; a block's first row and base
 * exponent), an entry is a u8 row delta and a 16-bit code: a 14-bit signed mantissa and
 * a 2-bit exponent above the block's base (3 bytes an entry instead of 8; the study
 * behind the choice is docs/bench.md, "K compact"). The encoder (used by the writer),
 * the section's checker (reader and writer) and the decoder (wrt_gto_k_entries, for the
 * runtime and the tools). Part of the runtime library. Depends on gto_layout.h, basis.h
 * and libm. */
#include "gto_layout.h"

#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/basis.h"

/* One block's base and codes: entries [a, b) of vals. The base is the block's largest
 * step exponent less 3 (within WRT_GTO_BASE_MIN..MAX), an entry's e its own less the
 * base, clamped to 0..3; mantissas rounded to nearest (ties to even). */
static int16_t kencode_block(const float *vals, uint64_t a, uint64_t b, void *out) {
    uint16_t *codes = out;
    int emax = WRT_GTO_BASE_MIN;
    for (uint64_t i = a; i < b; i++) {
        double m = fabs(vals[i]);
        if (m > 0) { int e = gto_step_exp(m, WRT_GTO_KMANT_MAX); if (e > emax) emax = e; }
    }
    int base = emax - 3;
    if (base < WRT_GTO_BASE_MIN) base = WRT_GTO_BASE_MIN;
    if (base > WRT_GTO_BASE_MAX) base = WRT_GTO_BASE_MAX; /* only for values the float checks refuse */
    for (uint64_t i = a; i < b; i++) {
        double m = fabs(vals[i]);
        int e = m > 0 ? gto_step_exp(m, WRT_GTO_KMANT_MAX) : base;
        if (e < base) e = base;
        if (e > base + 3) e = base + 3;
        double q = isfinite(vals[i]) ? nearbyint(ldexp(vals[i], -e)) : 0; /* the writer refuses those */
        if (q > WRT_GTO_KMANT_MAX) q = WRT_GTO_KMANT_MAX;
        if (q < -WRT_GTO_KMANT_MAX) q = -WRT_GTO_KMANT_MAX;
        codes[i] = (uint16_t)((uint32_t)(e - base) << 14 | ((uint32_t)(int32_t)q & 0x3fffu));
    }
    return (int16_t)base;
}

uint8_t *gto_kcode_encode(uint32_t nkcols, const uint64_t *kcol_start, const uint32_t *krows,
                          const float *kvals, uint64_t *size) {
    return gto_blocks_encode(nkcols, kcol_start, krows, kvals, WRT_GTO_KCODEC, 2, kencode_block, size);
}

void wrt_gto_k_entries(const wrt_gto *g, uint32_t *rows, float *vals) {
    if (!g->k_codes) {
        if (g->knnz) {
            memcpy(rows, g->krows, sizeof *rows * g->knnz);
            memcpy(vals, g->kvals, sizeof *vals * g->knnz);
        }
        return;
    }
    uint64_t e = 0;
    for (uint64_t k = 0; k < g->knblocks; k++) {
        const wrt_gto_block *b = &g->k_blocks[k];
        uint32_t row = b->row0;
        for (uint32_t i = 0; i < b->n; i++, e++) {
            row += g->k_deltas[e];
            rows[e] = row;
            vals[e] = wrt_gto_kdecode(g->k_codes[e], b->base);
        }
    }
}

/* ------------------------------------------------------------------------------------
 * The checker: the header, zero padding, bcol from 0 to nblocks and monotone, each
 * column's blocks holding its entries (kcol_start), each block's count, reserved byte and
 * base in range, rows strictly ascending within the column, below nfuncs and not of the
 * column's own quad, and no mantissa -8192. kkeys, kcol_start and fkeys are valid.
 * ---------------------------------------------------------------------------------- */

/* Entry i's row of K column j: below nfuncs and not a function of the column's own quad
 * (gto_check_column_blocks' row_ok). */
static int krow_ok(vctx *v, uint32_t j, uint64_t i, uint64_t row) {
    const wrt_gto *g = v->g;
    if (row >= g->nfuncs) {
        gto_obad(v, "entry %" PRIu64 " (K column %u): row %" PRIu64 " out of range (%u functions)", i, j, row, g->nfuncs);
        return 0;
    }
    uint32_t q = wrt_fkey_quad(g->kkeys[j]);
    if (wrt_fkey_quad(g->fkeys[row]) == q) {
        gto_obad(v, "entry %" PRIu64 " (K column %u): row %" PRIu64 " is a function of quad %u, the column's own quad", i,
                 j, row, q);
        return 0;
    }
    return 1;
}

void gto_check_kcode(vctx *v, const uint8_t *base, uint64_t first, uint64_t n) {
    const wrt_gto *g = v->g;
    gto_opcode_layout o = gto_kcode_place(g->nkcols, g->knblocks, g->knnz);
    if (first + n != o.size) return; /* the whole section, once its last chunk is summed */
    const gto_opcode_head *h = (const gto_opcode_head *)base;
    if (h->codec != WRT_GTO_KCODEC || h->block_max != WRT_GTO_BLOCK_MAX)
        return gto_obad(v, "unknown encoding %u with blocks of %u (this reader: %d, %d)", h->codec, h->block_max,
                    WRT_GTO_KCODEC, WRT_GTO_BLOCK_MAX);
    if (h->nblocks != g->knblocks || h->nnz != g->knnz || !gto_zero_bytes(h->reserved, 0, sizeof h->reserved))
        return gto_obad(v, "header: %" PRIu64 " blocks and %" PRIu64 " entries, expected %" PRIu64 " and %" PRIu64
                    ", or reserved bytes not zero", h->nblocks, h->nnz, g->knblocks, g->knnz);
    if (!gto_zero_bytes(base, o.bcol + 4 * ((uint64_t)g->nkcols + 1), o.blocks) ||
        !gto_zero_bytes(base, o.blocks + 8 * g->knblocks, o.codes) || !gto_zero_bytes(base, o.codes + 2 * g->knnz, o.deltas))
        return gto_obad(v, "non-zero padding between its arrays");
    const uint32_t *bcol = (const uint32_t *)(base + o.bcol);
    const uint16_t *codes = (const uint16_t *)(base + o.codes);
    const wrt_gto_block *blk = (const wrt_gto_block *)(base + o.blocks);
    if (bcol[0] != 0 || bcol[g->nkcols] != g->knblocks)
        return gto_obad(v, "bcol runs from %u to %u, expected 0 to %" PRIu64, bcol[0], bcol[g->nkcols], g->knblocks);
    for (uint32_t j = 0; j < g->nkcols; j++)
        if (bcol[j + 1] < bcol[j])
            return gto_obad(v, "bcol not monotone at K column %u (%u after %u)", j + 1, bcol[j + 1], bcol[j]);
    for (uint32_t j = 0; j < g->nkcols && !v->bad; j++)
        gto_check_column_blocks(v, "K column", "kcol_start", blk, base + o.deltas, j, bcol[j], bcol[j + 1],
                                g->kcol_start[j], g->kcol_start[j + 1], krow_ok);
    for (uint64_t i = 0; i < g->knnz && !v->bad; i++)
        if ((codes[i] & 0x3fffu) == 0x2000u)
            return gto_obad(v, "entry %" PRIu64 ": mantissa -8192 (the encoding uses -8191..8191)", i);
}
