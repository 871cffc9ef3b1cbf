/* sparse_order.c: A's entries by size for the skip of a product: wrt_csc_bands (the
 * entries moved into bands, --clusters' tree series) and the plain products' order
 * (mul_order: a list of places, the entries left where they are). Both rank an entry by
 * its largest channel times its row's weight against its column's largest (band_of).
 * See sparse.h and sparse_order.h. */
#include "sparse_order.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "../common/wrt_common.h"

/* An entry's band in its column (wrt_csc_bands): its weighted size against the column's top */
static int band_of(double m, double top) {
    if (!(m > 0) || !(top > 0)) return WRT_CSC_BANDS - 1;
    int e = 0;
    (void)frexp(m / top, &e); /* m / top in [2^(e-1), 2^e), e <= 1 */
    int b = 1 - e;
    return b < 0 ? 0 : b >= WRT_CSC_BANDS ? WRT_CSC_BANDS - 1 : b;
}

static double entry_size(const float *v, const double *row_w, uint32_t i) {
    double m = fmax(fabs((double)v[0]), fmax(fabs((double)v[1]), fabs((double)v[2])));
    return m * (row_w ? row_w[i] : 1.0);
}

/* column k's entries (rows src_row, values src_val, m of them) written into out->a from
 * a->col[k] on, band by band; out->start, top and rest of column k. A product skips from
 * band 0 to WRT_CSC_BANDS - 1 on (WRT_CSC_BANDS: nothing skipped), so those bands' starts
 * (32-bit offsets from the column's start) and rests are stored, the rests summed in
 * double and stored as floats: 336 bytes a column, not the 688 of 64-bit positions and
 * doubles (session 23; 274,910 columns: 92 MB instead of 189) */
static void bands_col(uint32_t k, uint64_t c0, const uint32_t *src_row, const float *src_val, uint64_t m,
                      const double *row_w, const double *power_w, wrt_csc_bands *out) {
    const size_t nb = WRT_CSC_BANDS;
    double top = 0;
    for (uint64_t e = 0; e < m; e++) top = fmax(top, entry_size(&src_val[3 * e], row_w, src_row[e]));
    out->top[k] = top;
    uint64_t count[WRT_CSC_BANDS + 1] = {0};
    for (uint64_t e = 0; e < m; e++) count[band_of(entry_size(&src_val[3 * e], row_w, src_row[e]), top) + 1]++;
    uint64_t st[WRT_CSC_BANDS + 1];
    st[0] = 0;
    for (int b = 0; b < WRT_CSC_BANDS; b++) st[b + 1] = st[b] + count[b + 1];
    uint32_t *so = &out->start[(size_t)k * nb];
    for (int b = 0; b < WRT_CSC_BANDS; b++) so[b] = (uint32_t)st[b];
    uint64_t next[WRT_CSC_BANDS];
    for (int b = 0; b < WRT_CSC_BANDS; b++) next[b] = c0 + st[b];
    double r[(WRT_CSC_BANDS + 1) * 4] = {0};
    for (uint64_t e = 0; e < m; e++) { /* rows ascend within each band, as in A */
        const float *v = &src_val[3 * e];
        uint32_t i = src_row[e];
        int b = band_of(entry_size(v, row_w, i), top);
        uint64_t to = next[b]++;
        out->a.row[to] = i;
        memcpy(&out->a.val[3 * to], v, 3 * sizeof *v);
        double p = power_w ? power_w[i] : 0;
        if (p != 0) {
            double *rb = &r[(size_t)b * 4];
            rb[0] += p * v[0]; rb[1] += p * v[1]; rb[2] += p * v[2];
            rb[3] += p * fmax(fabs((double)v[0]), fmax(fabs((double)v[1]), fabs((double)v[2])));
        }
    }
    for (int b = WRT_CSC_BANDS - 1; b >= 0; b--) /* from band b on */
        for (int q = 0; q < 4; q++) r[(size_t)b * 4 + q] += r[(size_t)(b + 1) * 4 + q];
    float *ro = &out->rest[(size_t)k * nb * 4];
    for (size_t q = 0; q < nb * 4; q++) ro[q] = (float)r[q];
}

uint64_t wrt_csc_bands_index_bytes(uint32_t n) {
    return ((uint64_t)n + 1) * (WRT_CSC_BANDS * (sizeof(uint32_t) + 4 * sizeof(float)) + sizeof(double) + sizeof(uint64_t));
}

static void bands_init(const wrt_csc *a, wrt_csc_bands *out) {
    const size_t nb = WRT_CSC_BANDS;
    uint32_t n = a->n;
    memset(out, 0, sizeof *out);
    out->a.n = n;
    out->a.nnz = a->nnz;
    out->a.col = wrt_xmalloc(((size_t)n + 1) * sizeof *out->a.col);
    memcpy(out->a.col, a->col, ((size_t)n + 1) * sizeof *out->a.col);
    out->start = wrt_xmalloc(((size_t)n * nb + 1) * sizeof *out->start);
    out->top = wrt_xcalloc((size_t)n + 1, sizeof *out->top);
    out->rest = wrt_xcalloc((size_t)n * nb * 4 + 1, sizeof *out->rest);
}

void wrt_csc_bands_make(const wrt_csc *a, const double *row_w, const double *power_w, wrt_csc_bands *out) {
    bands_init(a, out);
    out->a.row = wrt_xmalloc((a->nnz ? a->nnz : 1) * sizeof *out->a.row);
    out->a.val = wrt_xmalloc((a->nnz ? a->nnz : 1) * 3 * sizeof *out->a.val);
    for (uint32_t k = 0; k < a->n; k++)
        bands_col(k, a->col[k], a->row + a->col[k], a->val + 3 * a->col[k], a->col[k + 1] - a->col[k], row_w,
                  power_w, out);
}

typedef struct bands_ctx {
    wrt_csc *a;
    const double *row_w, *power_w;
    wrt_csc_bands *out;
    uint32_t chunks;
} bands_ctx;

/* columns [n c / chunks, n (c + 1) / chunks) through a scratch column of their own */
static void bands_chunk(size_t c, int th, void *user) {
    (void)th;
    bands_ctx *x = user;
    wrt_csc *a = x->a;
    uint32_t k0 = (uint32_t)((uint64_t)a->n * c / x->chunks), k1 = (uint32_t)((uint64_t)a->n * (c + 1) / x->chunks);
    uint64_t longest = 1;
    for (uint32_t k = k0; k < k1; k++)
        if (a->col[k + 1] - a->col[k] > longest) longest = a->col[k + 1] - a->col[k];
    uint32_t *row = wrt_xmalloc(longest * sizeof *row);
    float *val = wrt_xmalloc(3 * longest * sizeof *val);
    for (uint32_t k = k0; k < k1; k++) {
        uint64_t c0 = a->col[k], m = a->col[k + 1] - c0;
        memcpy(row, a->row + c0, m * sizeof *row);
        memcpy(val, a->val + 3 * c0, 3 * m * sizeof *val);
        bands_col(k, c0, row, val, m, x->row_w, x->power_w, x->out);
    }
    free(row); free(val);
}

/* Each column on its own (its entries, its index): by chunks of columns on the threads,
 * the same bytes at any thread count (16M entries took 1.4 s on one thread) */
void wrt_csc_bands_make_in_place(wrt_csc *a, const double *row_w, const double *power_w, wrt_csc_bands *out,
                                 int threads) {
    bands_init(a, out);
    out->a.row = a->row;
    out->a.val = a->val;
    bands_ctx x = {a, row_w, power_w, out, 64};
    wrt_parallel_for(x.chunks, threads, bands_chunk, &x);
}

void wrt_csc_bands_free(wrt_csc_bands *b) {
    wrt_csc_free(&b->a);
    free(b->start); free(b->top); free(b->rest);
    memset(b, 0, sizeof *b);
}

typedef struct order_ctx {
    const wrt_csc *a;
    const double *row_w, *power_w;
    mul_order *o;
    uint32_t chunks;
} order_ctx;

/* Entry e of A in the order: -1 at a row that carries power (read first, always summed),
 * else its band below the column's top tp */
static inline int order_group(const wrt_csc *a, uint64_t e, const double *rw, const double *pw, double tp) {
    uint32_t i = a->row[e];
    return pw && pw[i] != 0 ? -1 : band_of(entry_size(&a->val[3 * e], rw, i), tp);
}

/* columns [n c / chunks, n (c + 1) / chunks) of A's order, each on its own */
static void order_chunk(size_t c, int th, void *user) {
    (void)th;
    order_ctx *x = user;
    const wrt_csc *a = x->a;
    const double *rw = x->row_w, *pw = x->power_w;
    mul_order *o = x->o;
    uint32_t k0 = (uint32_t)((uint64_t)a->n * c / x->chunks), k1 = (uint32_t)((uint64_t)a->n * (c + 1) / x->chunks);
    for (uint32_t k = k0; k < k1; k++) {
        uint64_t c0 = a->col[k], m = a->col[k + 1] - c0;
        double tp = 0;
        for (uint64_t e = 0; e < m; e++)
            if (!pw || pw[a->row[c0 + e]] == 0) tp = fmax(tp, entry_size(&a->val[3 * (c0 + e)], rw, a->row[c0 + e]));
        o->top[k] = (float)tp;
        tp = o->top[k]; /* the bands of the stored top */
        if (o->one) {
            mul_one *r = &o->one[k];
            r->row = m == 0 ? WRT_ONE_EMPTY : WRT_ONE_OTHER;
            if (m == 1 && pw && pw[a->row[c0]] != 0) {
                r->row = a->row[c0];
                memcpy(r->v, &a->val[3 * c0], sizeof r->v);
            }
        }
        uint64_t next[WRT_CSC_BANDS + 1] = {0};
        for (uint64_t e = 0; e < m; e++) {
            int b = order_group(a, c0 + e, rw, pw, tp);
            if (b + 1 < WRT_CSC_BANDS) next[b + 2]++;
        }
        /* next[b + 1]: where band b starts (b = -1 the power rows, from 0) */
        for (int b = 1; b <= WRT_CSC_BANDS; b++) next[b] += next[b - 1];
        for (int b = 0; b < WRT_CSC_BANDS; b++) {
            size_t at = (size_t)k * WRT_CSC_BANDS + (size_t)b;
            if (o->start16) o->start16[at] = (uint16_t)next[b + 1];
            else o->start32[at] = (uint32_t)next[b + 1];
        }
        for (uint64_t e = 0; e < m; e++) {
            int b = order_group(a, c0 + e, rw, pw, tp);
            uint64_t to = c0 + next[b + 1]++;
            if (o->at16) o->at16[to] = (uint16_t)e;
            else o->at32[to] = (uint32_t)e;
        }
    }
}

static int order_narrow(const wrt_csc *a) {
    for (uint32_t k = 0; k < a->n; k++)
        if (a->col[k + 1] - a->col[k] > UINT16_MAX) return 0;
    return 1;
}

uint64_t wrt_csc_mul_order_bytes(const wrt_csc *a) {
    uint64_t w = order_narrow(a) ? 2 : 4;
    return w * a->nnz + ((uint64_t)a->n * WRT_CSC_BANDS) * w + 4 * (uint64_t)a->n +
           (a->nnz < 2 * (uint64_t)a->n ? sizeof(mul_one) * (uint64_t)a->n : 0) + 64;
}

mul_order *wrt_mul_order_make(const wrt_csc *a, const double *row_w, const double *power_w, int threads) {
    mul_order *o = wrt_xcalloc(1, sizeof *o);
    size_t nb = (size_t)a->n * WRT_CSC_BANDS + 1;
    if (order_narrow(a)) {
        o->at16 = wrt_xmalloc((a->nnz + 1) * sizeof *o->at16);
        o->start16 = wrt_xmalloc(nb * sizeof *o->start16);
    } else {
        o->at32 = wrt_xmalloc((a->nnz + 1) * sizeof *o->at32);
        o->start32 = wrt_xmalloc(nb * sizeof *o->start32);
    }
    o->top = wrt_xmalloc(((size_t)a->n + 1) * sizeof *o->top);
    if (a->nnz < 2 * (uint64_t)a->n) o->one = wrt_xmalloc(((size_t)a->n + 1) * sizeof *o->one);
    order_ctx x = {a, row_w, power_w, o, 64};
    wrt_parallel_for(x.chunks, threads, order_chunk, &x);
    return o;
}

void wrt_mul_order_free(mul_order *o) {
    if (!o) return;
    free(o->at16); free(o->start16); free(o->at32); free(o->start32); free(o->top); free(o->one);
    free(o);
}

