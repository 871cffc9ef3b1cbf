/* sparse_order.h: the plain products' order of A's entries for the skip (sparse_order.c,
 * beside wrt_csc_bands, which ranks entries by the same rule). Internal to sparse*.c: the
 * product (sparse.c) reads the order in its scatter, which must stay inline there.
 * Depends on sparse.h. */
#ifndef WRT_SPARSE_ORDER_H
#define WRT_SPARSE_ORDER_H

#include "sparse.h"

/* A column of A that holds one entry, at a row that carries power (the late terms: each
 * column keeps its largest power entry and little else), as one 16-byte record: the
 * product reads it instead of the column's start, its order and its entry, four places
 * apart (the 12 x 12 maze's late products took 25 ns a contribution). row WRT_ONE_EMPTY:
 * the column is empty; WRT_ONE_OTHER: read the column itself. */
#define WRT_ONE_EMPTY (UINT32_MAX - 1)
#define WRT_ONE_OTHER UINT32_MAX
typedef struct mul_one { float v[3]; uint32_t row; } mul_one;
_Static_assert(sizeof(mul_one) == 16, "a lone entry is read as one 16-byte load");

/* The skip without moving A's entries (wrt_csc_weights skip without bands: the plain
 * series' products, issue 22). Each column of A is read through a list of its entries'
 * places in it: first those at rows that carry power (power_w != 0), always summed, then
 * the others by size, band b holding those whose largest channel times row_w is in
 * [top 2^-b, top 2^(1-b)) of the column's largest such entry (top; band_of, as in
 * wrt_csc_bands; the last band everything smaller), each band by row. Only contributions
 * that carry no power are skipped, so a skip loses no power and needs no rest: the flux
 * of every term is what the full product's compression gives. On the 12 x 12 maze 97.8%
 * of the rows a product's column touched were then dropped by the compression; 75% of
 * the second product's contributions lie under 1/64 of the threshold. The places are
 * 16-bit where every column has under 65,536 entries (2 bytes an entry; 32-bit
 * otherwise). */
typedef struct mul_order {
    uint16_t *at16, *start16; /* at: nnz, the places (from the column's start); start: */
    uint32_t *at32, *start32; /* n x WRT_CSC_BANDS, where band b's places begin */
    float *top;               /* n */
    mul_one *one;             /* n, where A has under two entries a column on average; or NULL */
} mul_order;

/* A's order for a product that skips with weights row_w and power_w, made on `threads`
 * threads (the same bytes at any count); freed by wrt_mul_order_free (NULL: nothing) */
mul_order *wrt_mul_order_make(const wrt_csc *a, const double *row_w, const double *power_w, int threads);
void wrt_mul_order_free(mul_order *o);

#endif
