/* sparse.h: square sparse matrices of RGB entries in compressed sparse column form
 * (column = sender basis function, as the .gto stores them), and the products, sums
 * and non-linear compression the Neumann series needs (paper section 4.4).
 * Values are float RGB; products accumulate in double. Thread-safe on distinct data. */
#ifndef WRT_SPARSE_H
#define WRT_SPARSE_H

#include <stddef.h>
#include <stdint.h>

typedef struct wrt_csc {
    uint32_t n;      /* n x n */
    uint64_t nnz;
    uint64_t *col;   /* n + 1 */
    uint32_t *row;   /* nnz, ascending within a column */
    float *val;      /* nnz x 3 */
} wrt_csc;

typedef struct wrt_triplet { uint32_t row, col; float v[3]; } wrt_triplet;

/* Builds from triplets (t is left as it was, or sorted; duplicates are summed in their order in t). */
wrt_csc wrt_csc_from_triplets(uint32_t n, wrt_triplet *t, uint64_t count);
/* The same matrix, t freed (malloc'd; it shrinks while the matrix grows: 20 bytes an entry
 * at the most, not 40), on `threads` threads (0: all cores). */
wrt_csc wrt_csc_from_triplets_free(uint32_t n, wrt_triplet *t, uint64_t count, int threads);
void wrt_csc_free(wrt_csc *m);
wrt_csc wrt_csc_copy(const wrt_csc *m);

/* Weights of the compression test: an entry (i, j) is kept when its largest channel
 * magnitude times row_w[i] times col_w[j] reaches `drop` (NULL weights are 1). */
/* power_w (may be NULL): each row's power weight (0 for rows that carry no power); the
 * power of a column's dropped entries is then given to its kept ones, in proportion. */
/* boost_w (may be NULL): the small senders' rule (precompute/series.c): column j's entries
 * at rows that carry power are held against drop / boost_w[j] instead of drop, but only
 * where the entries the other weights would drop carry more than boost_lost of the
 * column's power (sum over its power rows of power_w x |entry|, channels added): an
 * error bound per column, so a column whose light the plain threshold already holds
 * keeps the plain threshold's entries. */
/* bands, skip (bands may be NULL; see wrt_csc_bands): a product's single contributions
 * a_ik b_kj whose weighted size is under skip x drop are not summed; their power goes to
 * the column's kept entries with what the compression drops. Without bands (skip > 0),
 * only the contributions at rows that carry no power (power_w 0) are skipped, A's entries
 * read in an order the product makes (sparse.c mul_order). */
struct wrt_csc_bands;
typedef struct wrt_csc_weights {
    const double *row_w, *col_w, *power_w, *boost_w;
    double boost_lost;
    const struct wrt_csc_bands *bands;
    double skip;
} wrt_csc_weights;

/* A product's left factor A with each column's entries ordered by size (series' products,
 * issue 22): band b of column k holds the entries whose largest channel times row_w is in
 * [top_k 2^-b, top_k 2^(1-b)) (the last band everything smaller), each band by row; rest
 * the power (power_w x entry, per channel, then of the channels' magnitudes) of the bands
 * from b on. A product whose weights carry these bands (and skip > 0) reads them in place
 * of A, and reads of column k only the bands that can reach skip x drop. */
#define WRT_CSC_BANDS 16
typedef struct wrt_csc_bands {
    wrt_csc a;
    uint32_t *start;  /* n x WRT_CSC_BANDS: where band b of column k starts, from the column's start in a */
    double *top;      /* n */
    float *rest;      /* n x WRT_CSC_BANDS x 4 (summed in double, stored rounded) */
} wrt_csc_bands;
/* The bands' index of an n-column matrix, in bytes (a's entries not counted) */
uint64_t wrt_csc_bands_index_bytes(uint32_t n);
void wrt_csc_bands_make(const wrt_csc *a, const double *row_w, const double *power_w, wrt_csc_bands *out);
/* the same bands made in a's own arrays (each column through a scratch column, by chunks
 * of columns on `threads`: the same bytes at any count): out->a.row and val are a's,
 * which keeps owning them (free them once, by a or by out, not both); a's columns are left
 * in the bands' order */
void wrt_csc_bands_make_in_place(wrt_csc *a, const double *row_w, const double *power_w, wrt_csc_bands *out,
                                 int threads);
void wrt_csc_bands_free(wrt_csc_bands *b);

/* C = A B, compressed by `drop` and `w` (may be NULL). Deterministic whatever `threads`. */
wrt_csc wrt_csc_mul(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int threads);
/* Only columns [c0, c1) of that product (the others empty), the same entries. */
wrt_csc wrt_csc_mul_cols(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int threads,
                         uint32_t c0, uint32_t c1);
/* Columns [c0, c1) of that product appended to m (a->n columns, complete up to c0, the
 * others set to end at c1), grown as the product grows (series_blocks.c) */
void wrt_csc_mul_append(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int threads,
                        uint32_t c0, uint32_t c1, wrt_csc *m);
/* The bytes a product with w's skip and no bands adds for its left factor a (the order it
 * reads a's columns in, made and freed by the product; sparse.c mul_order) */
uint64_t wrt_csc_mul_order_bytes(const wrt_csc *a);
/* Estimated entries of wrt_csc_mul(a, b, drop, w) from every stride-th column of the
 * product (computed and discarded), scaled by the share of B's entries those columns
 * hold: what the product will allocate, known before it is allocated. */
uint64_t wrt_csc_mul_estimate(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w,
                              uint32_t stride, int threads);
/* Frees the scratch the products keep for the next product of their size (sparse.c
 * mul_scratch): the series calls it when its products are done. */
void wrt_csc_mul_scratch_free(void);
/* C = A + s B, and with a scale per channel. */
wrt_csc wrt_csc_add(const wrt_csc *a, const wrt_csc *b, double s);
wrt_csc wrt_csc_add3(const wrt_csc *a, const wrt_csc *b, const double s[3]);
/* a += s b in place, per channel, with the same entries and roundings as wrt_csc_add3:
 * a's arrays grow by at most b's entries instead of a copy of both being made. */
void wrt_csc_add3_into(wrt_csc *a, const wrt_csc *b, const double s[3]);
/* Removes entries below `drop` (weighted as in wrt_csc_mul). */
void wrt_csc_compress(wrt_csc *m, double drop, const wrt_csc_weights *w);
/* One column's entries (row, val)[0, n), as column j of a matrix, compressed in place
 * with the same rule as wrt_csc_compress; returns the entries kept. */
uint64_t wrt_csc_compress_col(uint32_t *row, float *val, uint64_t n, uint32_t j, double drop,
                              const wrt_csc_weights *w);
/* Which of column j's n entries its compression keeps (kept[i] 1), the column unchanged;
 * and the compression with the entries where force[i] is set kept whatever their size */
uint64_t wrt_csc_compress_col_kept(const uint32_t *row, const float *val, uint64_t n, uint32_t j, double drop,
                                   const wrt_csc_weights *w, uint8_t *kept);
uint64_t wrt_csc_compress_col_force(uint32_t *row, float *val, uint64_t n, uint32_t j, double drop,
                                    const wrt_csc_weights *w, const uint8_t *force);
/* A compressed copy of m: the same entries and values as wrt_csc_compress on a copy,
 * without the copy. */
wrt_csc wrt_csc_copy_compress(const wrt_csc *m, double drop, const wrt_csc_weights *w);
/* Sorts n 64-bit keys ascending (LSD radix; for the bake's function keys). */
void wrt_sort_u64(uint64_t *a, size_t n);
/* Frobenius norm over all channels. */
double wrt_csc_norm(const wrt_csc *m);
/* s plus the squares of every value, in storage order (the norm's sum, continued from s:
 * a matrix held by blocks of columns gives the whole one's bits) */
double wrt_csc_sumsq(const wrt_csc *m, double s);
/* Largest channel magnitude of any entry. */
double wrt_csc_max(const wrt_csc *m);
/* y += M x for RGB vectors (x, y of length 3n). */
void wrt_csc_apply(const wrt_csc *m, const double *x, double *y);

#endif
