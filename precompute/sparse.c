/* sparse.c: CSC matrices of RGB entries: construction, Gustavson products with a
 * dense accumulator per thread, sums and thresholding. See sparse.h. */
#include "sparse.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "../common/threads.h"
#include "../common/wrt_common.h"
#include "sparse_order.h"

static int cmp_triplet(const void *pa, const void *pb) {
    const wrt_triplet *a = pa, *b = pb;
    if (a->col != b->col) return a->col < b->col ? -1 : 1;
    if (a->row != b->row) return a->row < b->row ? -1 : 1;
    return 0;
}

static wrt_csc from_triplets_qsort(uint32_t n, wrt_triplet *t, uint64_t count) {
    qsort(t, count, sizeof *t, cmp_triplet);
    wrt_csc m = {.n = n};
    m.col = wrt_xcalloc((size_t)n + 1, sizeof *m.col);
    m.row = wrt_xmalloc((count ? count : 1) * sizeof *m.row);
    m.val = wrt_xmalloc((count ? count : 1) * 3 * sizeof *m.val);
    uint64_t k = 0;
    for (uint64_t i = 0; i < count; i++) {
        if (k > 0 && i > 0 && t[i - 1].col == t[i].col && m.row[k - 1] == t[i].row) {
            for (int c = 0; c < 3; c++) m.val[3 * (k - 1) + c] += t[i].v[c];
            continue;
        }
        m.row[k] = t[i].row;
        memcpy(&m.val[3 * k], t[i].v, sizeof t[i].v);
        m.col[t[i].col + 1]++;
        k++;
    }
    for (uint32_t j = 0; j < n; j++) m.col[j + 1] += m.col[j];
    m.nnz = k;
    return m;
}

/* The triplets t[0, count) scattered into m's arrays at next[col]++ in the order of their
 * rows, those of one row in their order in t (a counting pass over the rows, its order
 * kept as a 32-bit index, 4 bytes an entry), so rows ascend within a column. */
static void scatter_by_row(uint32_t n, const wrt_triplet *t, uint64_t count, wrt_csc *m, uint64_t *next) {
    uint64_t *rstart = wrt_xcalloc((size_t)n + 2, sizeof *rstart);
    for (uint64_t i = 0; i < count; i++) rstart[t[i].row + 1]++;
    for (uint32_t j = 0; j < n; j++) rstart[j + 1] += rstart[j];
    uint32_t *order = wrt_xmalloc((count ? count : 1) * sizeof *order);
    for (uint64_t i = 0; i < count; i++) order[rstart[t[i].row]++] = (uint32_t)i;
    free(rstart);
    for (uint64_t k = 0; k < count; k++) {
        const wrt_triplet *e = &t[order[k]];
        uint64_t at = next[e->col]++;
        m->row[at] = e->row;
        memcpy(&m->val[3 * at], e->v, sizeof e->v);
    }
    free(order);
}

/* Duplicates, side by side in their order in t after scatter_by_row, summed in place;
 * the arrays cut to the entries left. */
static void sum_duplicates(wrt_csc *m, uint64_t count) {
    uint64_t k = 0, start = 0;
    for (uint32_t j = 0; j < m->n; j++) {
        uint64_t end = m->col[j + 1];
        for (uint64_t i = start; i < end; i++) {
            if (i > start && m->row[k - 1] == m->row[i]) {
                for (int c = 0; c < 3; c++) m->val[3 * (k - 1) + c] += m->val[3 * i + c];
                continue;
            }
            m->row[k] = m->row[i];
            if (k != i) memcpy(&m->val[3 * k], &m->val[3 * i], 3 * sizeof *m->val);
            k++;
        }
        start = end;
        m->col[j + 1] = k;
    }
    m->nnz = k;
    if (k < count) {
        m->row = wrt_xrealloc(m->row, (k ? k : 1) * sizeof *m->row);
        m->val = wrt_xrealloc(m->val, (k ? k : 1) * 3 * sizeof *m->val);
    }
}

/* Builds from triplets: duplicates of one (row, col) are summed in their order in t (the
 * order a stable sort by (col, row) leaves them, as qsort's merge sort did). Two counting
 * passes instead of a comparison sort: the rows' order as an index (4 bytes an entry),
 * then each triplet scattered in that order into its column, so rows ascend within a
 * column. On the 12 x 12 maze (32M entries) qsort took seconds and a second copy of the
 * 20-byte triplets; this takes 4 bytes an entry beside the result. */
wrt_csc wrt_csc_from_triplets(uint32_t n, wrt_triplet *t, uint64_t count) {
    if (count >= UINT32_MAX) return from_triplets_qsort(n, t, count); /* the index is 32-bit */
    wrt_csc m = {.n = n};
    m.col = wrt_xcalloc((size_t)n + 2, sizeof *m.col);
    for (uint64_t i = 0; i < count; i++) m.col[t[i].col + 1]++;
    for (uint32_t j = 0; j < n; j++) m.col[j + 1] += m.col[j];
    m.row = wrt_xmalloc((count ? count : 1) * sizeof *m.row);
    m.val = wrt_xmalloc((count ? count : 1) * 3 * sizeof *m.val);
    uint64_t *next = wrt_xmalloc(((size_t)n + 1) * sizeof *next);
    memcpy(next, m.col, ((size_t)n + 1) * sizeof *next);
    scatter_by_row(n, t, count, &m, next);
    free(next);
    sum_duplicates(&m, count);
    return m;
}

/* The same matrix, built by ranges of columns (about a 32nd of the entries each, taken two
 * at a time): the two ranges' triplets are taken out of t in their order and t is cut to
 * what is left, then each range is scattered as above, the two on two threads (their
 * columns, and so their places in the matrix, are apart). The triplets (20 bytes an
 * entry) shrink as the matrix (16) grows, instead of both being held with the index (40
 * bytes an entry: on the 12 x 12 maze the bake's peak, 1.35 GB, issue 22).
 * The triplets are held as two arrays, t's first half and its second (moved out of t's
 * end a 64th at a time, t cut behind each piece), and each pass over them runs on two
 * threads, one an array: the first takes its ranges' triplets out in order to the front
 * of each range's buffer, the second from the back in reverse (turned round before the
 * scatter), so every range's triplets are in t's order, and the matrix is the same
 * whatever the threads (on the 12 x 12 maze the passes, 16 over 30M triplets, were a
 * second of one thread while the other waited). */
#define TRIPLET_RANGES 32
typedef struct {
    uint32_t n;
    wrt_triplet *rt[2];
    uint64_t in[2], front[2]; /* range r's triplets; those from the first array */
    wrt_csc *m;
    uint64_t *next;
    /* the passes: the two arrays and their triplets, the pass's columns */
    wrt_triplet *t[2];
    uint64_t left[2];
    uint32_t cut[3];
} range_job;

static void take_ranges(size_t h, int th, void *user) {
    (void)th;
    range_job *j = user;
    wrt_triplet *t = j->t[h];
    const uint32_t *cut = j->cut;
    uint64_t w = 0, k[2] = {0, 0};
    for (uint64_t i = 0; i < j->left[h]; i++) {
        uint32_t c = t[i].col;
        int r = c >= cut[0] && c < cut[1] ? 0 : c >= cut[1] && c < cut[2] ? 1 : -1;
        if (r < 0) t[w++] = t[i];
        else if (h == 0) j->rt[r][k[r]++] = t[i];
        else j->rt[r][j->in[r] - 1 - k[r]++] = t[i];
    }
    j->left[h] = w;
    j->t[h] = wrt_xrealloc(t, (w ? w : 1) * sizeof *t);
    if (h == 0) memcpy(j->front, k, sizeof k);
}

static void scatter_range(size_t i, int th, void *user) {
    (void)th;
    range_job *j = user;
    wrt_triplet *rt = j->rt[i];
    for (uint64_t a = j->front[i], b = j->in[i]; b > a + 1; a++, b--) { /* the second array's, in order */
        wrt_triplet x = rt[a];
        rt[a] = rt[b - 1];
        rt[b - 1] = x;
    }
    scatter_by_row(j->n, rt, j->in[i], j->m, j->next);
}

wrt_csc wrt_csc_from_triplets_free(uint32_t n, wrt_triplet *t, uint64_t count, int threads) {
    if (count >= UINT32_MAX || count < 2 * TRIPLET_RANGES) {
        wrt_csc m = wrt_csc_from_triplets(n, t, count);
        free(t);
        return m;
    }
    wrt_csc m = {.n = n};
    m.col = wrt_xcalloc((size_t)n + 2, sizeof *m.col);
    for (uint64_t i = 0; i < count; i++) m.col[t[i].col + 1]++;
    for (uint32_t j = 0; j < n; j++) m.col[j + 1] += m.col[j];
    /* untouched until written: the pages come as the ranges fill them */
    m.row = wrt_xmalloc(count * sizeof *m.row);
    m.val = wrt_xmalloc(count * 3 * sizeof *m.val);
    uint64_t *next = wrt_xmalloc(((size_t)n + 1) * sizeof *next);
    memcpy(next, m.col, ((size_t)n + 1) * sizeof *next);
    range_job rj = {.n = n, .m = &m, .next = next};
    /* the second half moved out, from t's end back, t cut behind each piece */
    uint64_t half = count / 2, piece = count / 64 + 1;
    rj.left[0] = half;
    rj.left[1] = count - half;
    rj.t[1] = wrt_xmalloc(rj.left[1] * sizeof *rj.t[1]);
    for (uint64_t end = count; end > half;) {
        uint64_t from = end - half > piece ? end - piece : half;
        memcpy(rj.t[1] + (from - half), t + from, (end - from) * sizeof *t);
        t = wrt_xrealloc(t, from * sizeof *t);
        end = from;
    }
    rj.t[0] = t;
    for (uint32_t c0 = 0; c0 < n;) {
        uint32_t *cut = rj.cut;
        cut[0] = c0;
        for (int r = 1; r < 3; r++) { /* range r - 1 is [cut[r - 1], cut[r]), empty past the end */
            uint32_t a = cut[r - 1], c1 = a < n ? a + 1 : n;
            while (c1 < n && m.col[c1 + 1] - m.col[a] <= count / TRIPLET_RANGES) c1++;
            cut[r] = c1;
        }
        for (int r = 0; r < 2; r++) {
            rj.in[r] = m.col[cut[r + 1]] - m.col[cut[r]];
            rj.rt[r] = wrt_xmalloc((rj.in[r] ? rj.in[r] : 1) * sizeof *rj.rt[r]);
        }
        wrt_parallel_for(2, threads, take_ranges, &rj);
        wrt_parallel_for(2, threads, scatter_range, &rj);
        free(rj.rt[0]); free(rj.rt[1]);
        c0 = cut[2];
    }
    free(rj.t[0]); free(rj.t[1]); free(next);
    sum_duplicates(&m, count);
    return m;
}

void wrt_csc_free(wrt_csc *m) {
    free(m->col); free(m->row); free(m->val);
    memset(m, 0, sizeof *m);
}

wrt_csc wrt_csc_copy(const wrt_csc *m) {
    wrt_csc c = *m;
    c.col = wrt_xmalloc(((size_t)m->n + 1) * sizeof *c.col);
    c.row = wrt_xmalloc((m->nnz ? m->nnz : 1) * sizeof *c.row);
    c.val = wrt_xmalloc((m->nnz ? m->nnz : 1) * 3 * sizeof *c.val);
    memcpy(c.col, m->col, ((size_t)m->n + 1) * sizeof *c.col);
    memcpy(c.row, m->row, m->nnz * sizeof *c.row);
    memcpy(c.val, m->val, m->nnz * 3 * sizeof *c.val);
    return c;
}

/* The accumulator holds a row's three channels in four doubles (32 bytes, the fourth
 * always 0), so that one 4-wide add takes them where AVX is there. */
#define ACC_STRIDE 4

typedef double acc_v4 __attribute__((vector_size(32)));
typedef float acc_v4f __attribute__((vector_size(16)));

/* Per-column results of a product, merged in column order afterwards. */
typedef struct col_out { uint32_t *row; float *val; uint32_t count; } col_out;
typedef struct mul_ctx {
    const wrt_csc *a, *b;
    double drop;
    const double *row_w, *col_w;
    col_out *out;
    double **acc;       /* per thread: 3n doubles */
    uint64_t **bits;    /* per thread: one bit per row, set while the column touches it */
    uint64_t **top;     /* per thread: one bit per word of bits that has a bit set */
    uint32_t **list;    /* per thread: touched rows */
    const double *power_w;
    int avx;            /* the scatter's 4-wide vectors in one AVX instruction */
    const double *boost_w;
    double boost_lost;
    const wrt_csc_bands *bands; /* with skip > 0: A by bands (wrt_csc_bands) */
    double skip;
    const struct mul_order *ord; /* with skip > 0 and no bands: A's order (mul_order) */
} mul_ctx;

/* The small senders' factor of a column (wrt_csc_weights boost_w): 1, or boost when the
 * entries under the plain test drop more than boost_lost of the column's power. The n
 * entries are at rows rows[t]; their values are acc[ACC_STRIDE rows[t]] (a product's accumulator)
 * or, acc NULL, val[3 t] (a stored column). */
static double column_boost(double boost, double boost_lost, const uint32_t *rows, uint64_t n, const double *acc,
                           const float *val, double cw, const double *row_w, const double *pw, double drop,
                           double skipped) {
    if (!(boost > 1) || !pw) return 1;
    double all = skipped, lost = skipped;
    for (uint64_t t = 0; t < n; t++) {
        uint32_t i = rows[t];
        if (pw[i] == 0) continue;
        double m0, m1, m2;
        if (acc) {
            m0 = fabs(acc[ACC_STRIDE * (size_t)i]); m1 = fabs(acc[ACC_STRIDE * (size_t)i + 1]);
            m2 = fabs(acc[ACC_STRIDE * (size_t)i + 2]);
        }
        else { m0 = fabs(val[3 * t]); m1 = fabs(val[3 * t + 1]); m2 = fabs(val[3 * t + 2]); }
        double p = pw[i] * (m0 + m1 + m2), m = fmax(m0, fmax(m1, m2));
        all += p;
        if (!(m > 0 && m * cw * (row_w ? row_w[i] : 1.0) >= drop)) lost += p;
    }
    return lost > boost_lost * all ? boost : 1;
}

/* Compression without losing power: the power (sum of power_w x entry) of the entries a
 * column drops is given, channel by channel, to its kept entries that carry power and
 * have the loss's sign, in proportion to theirs, when they can take it without more than
 * doubling. A column whose power nearly cancels (a wavelet sender's: its receivers'
 * powers sum to what it emits, 0) cannot; its loss then goes to all its kept entries
 * that carry power, each moved by the same fraction of its size (under 1: no entry
 * changes sign). Without the hand-over a closed scene at albedo 0.999 lost 3e-5 of its
 * light per product; without the second rule the wavelet columns' leftover power fed
 * the roots +5e-4 of the light by the 10th term (a closed box with a box inside, albedo
 * 0.9, 2 x 2 quads a wall, quality 5: mean +0.032% instead of +0.005%). */
static void spread_power_channel(const uint32_t *rows, uint32_t n, double *acc, const double *pw, double lost, int ch) {
    double same = 0, all = 0;
    for (uint32_t t = 0; t < n; t++) {
        uint32_t i = rows[t];
        double v = acc[ACC_STRIDE * i + ch];
        if (pw[i] == 0 || v == 0) continue;
        all += pw[i] * fabs(v);
        if ((v > 0) == (lost > 0)) same += pw[i] * fabs(v);
    }
    int any_sign = !(same > 0 && fabs(lost) <= same);
    double wsum = any_sign ? all : same;
    if (!(wsum > 0) || fabs(lost) > wsum) return;
    for (uint32_t t = 0; t < n; t++) {
        uint32_t i = rows[t];
        double v = acc[ACC_STRIDE * i + ch];
        if (pw[i] != 0 && v != 0 && (any_sign || (v > 0) == (lost > 0))) acc[ACC_STRIDE * i + ch] = v + lost * fabs(v) / wsum;
    }
}

static void spread_power(const uint32_t *rows, uint32_t n, double *acc, const double *pw, const double lost[3]) {
    for (int ch = 0; ch < 3; ch++)
        if (lost[ch] != 0) spread_power_channel(rows, n, acc, pw, lost[ch], ch);
}

/* One entry of the scatter: acc[row i] += af bw, the row marked in the word held in
 * *word (bitmap word *cw), which is stored when the rows leave it. */
static inline __attribute__((always_inline)) void scatter_entry(uint32_t i, acc_v4f af, const acc_v4 *bw, double *acc,
                                                                uint64_t *bits, uint64_t *top, uint32_t *cw,
                                                                uint64_t *word) {
    if (i >> 6 != *cw) {
        bits[*cw] |= *word;
        top[*cw >> 6] |= (uint64_t)1 << (*cw & 63);
        *cw = i >> 6;
        *word = 0;
    }
    *word |= (uint64_t)1 << (i & 63);
    acc_v4 *ac = (acc_v4 *)&acc[ACC_STRIDE * (size_t)i];
    *ac += __builtin_convertvector(af, acc_v4) * *bw;
}

/* frexp's exponent (r = f 2^e, f in [0.5, 1)) read off the bits where r is a normal
 * positive double; frexp itself elsewhere (a library call per contribution took 9% of the
 * late products) */
static inline int exponent_of(double r) {
    uint64_t u;
    memcpy(&u, &r, sizeof u);
    uint64_t ex = (u >> 52) & 0x7ff;
    if (!(u >> 63) && ex > 0 && ex < 0x7ff) return (int)ex - 1022;
    if (ex == 0x7ff) return INT_MAX / 2; /* infinite or NaN: above every band, nothing skipped */
    int e = 0;
    (void)frexp(r, &e);
    return e;
}

/* Column k of A's contributions to a product's column through the order (mul_order):
 * the power rows and the bands whose largest contribution (top 2^-b times B's entry's
 * largest channel) reaches lim; lim 0: all of them */
static inline __attribute__((always_inline)) void scatter_ordered(const mul_order *o, uint32_t k, uint64_t ka,
                                                                  uint64_t ke, double lim, const acc_v4 *bw,
                                                                  const uint32_t *arow, const float *aval,
                                                                  uint64_t last, double *acc, uint64_t *bits,
                                                                  uint64_t *top) {
    /* the order's arrays in locals (the stores through acc and the bitmaps could alias
     * *o), and the larger of two magnitudes without fmax, a library call here */
    const uint16_t *at16 = o->at16, *st16 = o->start16;
    const uint32_t *at32 = o->at32, *st32 = o->start32;
    uint64_t end = ke - ka;
    size_t at = (size_t)k * WRT_CSC_BANDS;
    if (lim > 0 && (st16 ? st16[at] : st32[at]) < end) { /* not all power rows */
        double m0 = fabs((*bw)[0]), m1 = fabs((*bw)[1]), m2 = fabs((*bw)[2]);
        double bm = m0 > m1 ? m0 : m1;
        bm = bm > m2 ? bm : m2;
        /* r = top bm / lim = f 2^e, f in [0.5, 1): band b's contributions are under
         * r 2^(1 - b) lim, so the bands from e + 1 on are under lim */
        int e = exponent_of((double)o->top[k] * bm / lim) + 1;
        if (e < WRT_CSC_BANDS) {
            at += (size_t)(e < 0 ? 0 : e);
            end = st16 ? st16[at] : st32[at];
        }
    }
    /* each row marked in memory at once: in the bands' order the rows are sparse, few
     * neighbours share a bitmap word, and holding the word (scatter_entry) mispredicted */
    for (uint64_t t = 0; t < end; t++) {
        uint64_t ea = ka + (at16 ? at16[ka + t] : at32[ka + t]);
        acc_v4f af;
        if (ea < last) {
            memcpy(&af, &aval[3 * ea], sizeof af);
            af[3] = 0;
        } else {
            af = (acc_v4f){aval[3 * ea], aval[3 * ea + 1], aval[3 * ea + 2], 0};
        }
        uint32_t i = arow[ea];
        bits[i >> 6] |= (uint64_t)1 << (i & 63);
        top[i >> 12] |= (uint64_t)1 << ((i >> 6) & 63);
        acc_v4 *ac = (acc_v4 *)&acc[ACC_STRIDE * (size_t)i];
        *ac += __builtin_convertvector(af, acc_v4) * *bw;
    }
}

/* Column j of the product, accumulated: acc[row] += A[row][k] B[k][j] over B's column j,
 * each touched row marked in the bitmaps. acc is all zero between columns (cleared as the
 * rows are read out), so a touch only marks the bitmaps. The rows of A's column ascend,
 * so the bitmap word being marked is held in a register and stored when the rows leave
 * it: or-ing into memory at every entry chained each entry's store to the next one's
 * load (the same word, most of the time), a quarter of the product's time (perf). The
 * three channels go as one 4-wide vector: each is the same double product and sum as the
 * plain loop's, so the same bits, in one AVX instruction or two SSE2 ones. An entry's
 * three floats are read as one 16-byte load (the fourth float, the next entry's first,
 * set to 0 in the register) instead of three loads and two inserts: the products 0.74x
 * (the maze asset's first two, replayed from their dumped factors on one thread, the
 * output's hash unchanged). A's last entry, which has no float after it, is read alone. */
static inline __attribute__((always_inline)) void scatter_column(const mul_ctx *c, size_t j, double *acc,
                                                                 uint64_t *bits, uint64_t *top, double *skipped) {
    const wrt_csc *a = c->a, *b = c->b;
    /* with bands: of column k only the bands whose largest weighted contribution can reach
     * skip x drop (lim, in units of B's entry's largest channel); the rest's power is
     * summed into skipped[0..2], its magnitude into skipped[3] */
    const wrt_csc_bands *bd = c->bands;
    double lim = 0;
    if (bd || c->ord) {
        double cw = (c->col_w ? c->col_w[j] : 1.0) * (c->boost_w && c->boost_w[j] > 1 ? c->boost_w[j] : 1.0);
        lim = cw > 0 ? c->skip * c->drop / cw : 0;
    }
    /* A's arrays in locals: the stores through acc and the bitmaps could alias *a, and
     * the compiler reloaded a->val and a->col[k + 1] at every entry */
    const uint64_t *acol = a->col;
    const uint32_t *arow = a->row;
    const float *aval = a->val;
    const uint64_t last = a->nnz ? a->nnz - 1 : 0; /* the entries before it: 16-byte loads */
    const mul_one *one = c->ord ? c->ord->one : NULL;
    for (uint64_t kb = b->col[j]; kb < b->col[j + 1]; kb++) {
        uint32_t k = b->row[kb];
        const float *bv = &b->val[3 * kb];
        if (one && one[k].row >= WRT_ONE_EMPTY) {
            if (one[k].row == WRT_ONE_EMPTY) continue;
        } else if (one) { /* a lone entry at a power row: scatter_ordered's sum, from one record */
            uint32_t i = one[k].row;
            acc_v4 bw1 = {(double)bv[0], (double)bv[1], (double)bv[2], 0};
            acc_v4f af;
            memcpy(&af, &one[k], sizeof af);
            af[3] = 0;
            bits[i >> 6] |= (uint64_t)1 << (i & 63);
            top[i >> 12] |= (uint64_t)1 << ((i >> 6) & 63);
            acc_v4 *ac = (acc_v4 *)&acc[ACC_STRIDE * (size_t)i];
            *ac += __builtin_convertvector(af, acc_v4) * bw1;
            continue;
        }
        uint64_t ka = acol[k], ke = acol[k + 1];
        if (ka == ke) continue;
        acc_v4 bw = {(double)bv[0], (double)bv[1], (double)bv[2], 0};
        if (bd && lim > 0) {
            double bm = fmax(fabs(bw[0]), fmax(fabs(bw[1]), fabs(bw[2])));
            int e = 0;
            (void)frexp(bd->top[k] * bm / lim, &e); /* r = f 2^e, f in [0.5, 1): log2 r < e */
            int from = e + 1 < 0 ? 0 : e + 1 > WRT_CSC_BANDS ? WRT_CSC_BANDS : e + 1;
            if (from < WRT_CSC_BANDS) {
                const float *r = &bd->rest[((size_t)k * WRT_CSC_BANDS + (size_t)from) * 4];
                skipped[0] += bw[0] * r[0]; skipped[1] += bw[1] * r[1]; skipped[2] += bw[2] * r[2];
                skipped[3] += bm * r[3];
                ke = ka + bd->start[(size_t)k * WRT_CSC_BANDS + (size_t)from];
                if (ka == ke) continue;
            }
        }
        if (c->ord) {
            scatter_ordered(c->ord, k, ka, ke, lim, &bw, arow, aval, last, acc, bits, top);
            continue;
        }
        uint32_t cw = arow[ka] >> 6;
        uint64_t word = 0, kf = ke < last ? ke : last;
        for (; ka < kf; ka++) {
            acc_v4f af;
            memcpy(&af, &aval[3 * ka], sizeof af);
            af[3] = 0;
            scatter_entry(arow[ka], af, &bw, acc, bits, top, &cw, &word);
        }
        for (; ka < ke; ka++) {
            const float *av = &aval[3 * ka];
            acc_v4f af = {av[0], av[1], av[2], 0};
            scatter_entry(arow[ka], af, &bw, acc, bits, top, &cw, &word);
        }
        bits[cw] |= word;
        top[cw >> 6] |= (uint64_t)1 << (cw & 63);
    }
}

static void scatter_plain(const mul_ctx *c, size_t j, double *acc, uint64_t *bits, uint64_t *top, double *skipped) {
    scatter_column(c, j, acc, bits, top, skipped);
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx"))) static void scatter_avx(const mul_ctx *c, size_t j, double *acc, uint64_t *bits,
                                                       uint64_t *top, double *skipped) {
    scatter_column(c, j, acc, bits, top, skipped);
}
#endif

static void mul_column(size_t j, int th, void *user) {
    mul_ctx *c = user;
    /* an empty column of B gives an empty column (its record stays zero): the readout
     * below walks n / 4,096 bitmap words whatever the column, and the series' products
     * by blocks of columns (series_cols.c) and their estimates run over every column, all
     * but a block's empty: at 53,122 atrium elements 5.4M columns of 1,300 words a product */
    if (c->b->col[j] == c->b->col[j + 1]) return;
    double *acc = c->acc[th];
    uint32_t *list = c->list[th];
    uint64_t *bits = c->bits[th], *top = c->top[th];
    const wrt_csc *a = c->a;
    double skipped[4] = {0, 0, 0, 0};
#if defined(__x86_64__) && defined(__GNUC__)
    if (c->avx) scatter_avx(c, j, acc, bits, top, skipped);
    else
#endif
        scatter_plain(c, j, acc, bits, top, skipped);
    /* The touched rows in ascending order, read off the two bitmaps (and cleared on the
     * way): sorting each column's touched rows (a radix sort, qsort before it) took 13% of
     * the 12 x 12 maze's bake (perf), reading the bitmaps a few words per 4,096 rows. */
    uint32_t nl = 0, ntop = (a->n >> 12) + 1;
    for (uint32_t u = 0; u < ntop; u++) {
        uint64_t tw = top[u];
        top[u] = 0;
        while (tw) {
            uint32_t wi = u * 64 + (uint32_t)__builtin_ctzll(tw);
            tw &= tw - 1;
            uint64_t bw = bits[wi];
            bits[wi] = 0;
            while (bw) {
                list[nl++] = wi * 64 + (uint32_t)__builtin_ctzll(bw);
                bw &= bw - 1;
            }
        }
    }
    uint32_t kept = 0, kept_power = 0, best = UINT32_MAX;
    double cw = c->col_w ? c->col_w[j] : 1.0, lost[3] = {0, 0, 0}, bestw = 0, bestv[3] = {0, 0, 0};
    const double *pw = c->power_w;
    double bst = c->boost_w ? column_boost(c->boost_w[j], c->boost_lost, list, nl, acc, NULL, cw, c->row_w, pw, c->drop,
                                           skipped[3])
                            : 1;
    if (pw)
        for (int ch = 0; ch < 3; ch++) lost[ch] = skipped[ch];
    for (uint32_t t = 0; t < nl; t++) {
        uint32_t i = list[t];
        double m0 = fabs(acc[ACC_STRIDE * i]), m1 = fabs(acc[ACC_STRIDE * i + 1]), m2 = fabs(acc[ACC_STRIDE * i + 2]);
        double m = m0 > m1 ? m0 : m1;
        m = m > m2 ? m : m2;
        if (m > 0 && m * cw * (bst > 1 && pw[i] != 0 ? bst : 1) * (c->row_w ? c->row_w[i] : 1.0) >= c->drop) {
            list[kept++] = i;
            kept_power += pw && pw[i] != 0;
        } else {
            if (pw && pw[i] != 0) {
                for (int ch = 0; ch < 3; ch++) lost[ch] += pw[i] * acc[ACC_STRIDE * i + ch];
                if (pw[i] * (m0 + m1 + m2) > bestw) {
                    bestw = pw[i] * (m0 + m1 + m2); best = i;
                    for (int ch = 0; ch < 3; ch++) bestv[ch] = acc[ACC_STRIDE * i + ch];
                }
            }
            acc[ACC_STRIDE * i] = acc[ACC_STRIDE * i + 1] = acc[ACC_STRIDE * i + 2] = 0;
        }
    }
    if (pw && (lost[0] != 0 || lost[1] != 0 || lost[2] != 0)) {
        if (!kept_power && best != UINT32_MAX) {
            /* no entry that carries power survived: the largest of those dropped stays */
            uint32_t at = kept;
            while (at > 0 && list[at - 1] > best) { list[at] = list[at - 1]; at--; }
            list[at] = best;
            kept++;
            for (int ch = 0; ch < 3; ch++) acc[ACC_STRIDE * best + ch] = bestv[ch];
            for (int ch = 0; ch < 3; ch++) lost[ch] -= pw[best] * acc[ACC_STRIDE * best + ch];
        }
        spread_power(list, kept, acc, pw, lost);
    }
    col_out *o = &c->out[j];
    o->count = kept;
    o->row = kept ? wrt_xmalloc(kept * sizeof *o->row) : NULL;
    o->val = kept ? wrt_xmalloc(kept * 3 * sizeof *o->val) : NULL;
    for (uint32_t t = 0; t < kept; t++) {
        uint32_t i = list[t];
        o->row[t] = i;
        for (int ch = 0; ch < 3; ch++) o->val[3 * t + ch] = (float)acc[ACC_STRIDE * i + ch];
        acc[ACC_STRIDE * i] = acc[ACC_STRIDE * i + 1] = acc[ACC_STRIDE * i + 2] = 0;
    }
}

void wrt_sort_u64(uint64_t *a, size_t n) {
    if (n < 64) {
        for (size_t i = 1; i < n; i++) {
            uint64_t v = a[i];
            size_t j = i;
            while (j > 0 && a[j - 1] > v) { a[j] = a[j - 1]; j--; }
            a[j] = v;
        }
        return;
    }
    uint64_t all_or = 0;
    for (size_t i = 0; i < n; i++) all_or |= a[i];
    uint64_t *tmp = wrt_xmalloc(n * sizeof *tmp), *src = a, *dst = tmp;
    size_t *count = wrt_xmalloc((65536 + 1) * sizeof *count);
    for (int shift = 0; shift < 64; shift += 16) {
        if (!((all_or >> shift) & 0xFFFF)) continue; /* a digit that is zero everywhere */
        memset(count, 0, (65536 + 1) * sizeof *count);
        for (size_t i = 0; i < n; i++) count[((src[i] >> shift) & 0xFFFF) + 1]++;
        for (int d = 0; d < 65536; d++) count[d + 1] += count[d];
        for (size_t i = 0; i < n; i++) dst[count[(src[i] >> shift) & 0xFFFF]++] = src[i];
        uint64_t *t = src; src = dst; dst = t;
    }
    if (src != a) memcpy(a, src, n * sizeof *a);
    free(tmp); free(count);
}

/* The products' scratch for n rows and t threads: each thread's accumulator, touched
 * rows' bitmaps and row list. All of it is zero again when a product ends (a column
 * clears what it touched), so one set is kept for the next product of the same size: the
 * series by blocks of columns makes two products a bounce (the estimate and the product),
 * 14 bounces a block, and at 53,122 atrium elements each set is 360 MB to allocate and
 * zero. A product that finds the kept set taken or of another size makes its own; the
 * series gives the kept set back at its end (wrt_csc_mul_scratch_free). */
typedef struct mul_scratch {
    uint32_t n;
    int t;
    double **acc;
    uint64_t **bits, **top;
    uint32_t **list;
} mul_scratch;

static mul_scratch kept_scratch;
static pthread_mutex_t kept_mu = PTHREAD_MUTEX_INITIALIZER;

static void scratch_free(mul_scratch *s) {
    for (int i = 0; i < s->t && s->acc; i++) { free(s->acc[i]); free(s->bits[i]); free(s->top[i]); free(s->list[i]); }
    free(s->acc); free(s->bits); free(s->top); free(s->list);
    memset(s, 0, sizeof *s);
}

static mul_scratch scratch_take(uint32_t n, int t) {
    mul_scratch s = {0};
    pthread_mutex_lock(&kept_mu);
    if (kept_scratch.acc && kept_scratch.n == n && kept_scratch.t == t) {
        s = kept_scratch;
        memset(&kept_scratch, 0, sizeof kept_scratch);
    }
    pthread_mutex_unlock(&kept_mu);
    if (s.acc) return s;
    s = (mul_scratch){.n = n, .t = t};
    s.acc = wrt_xcalloc((size_t)t, sizeof *s.acc);
    s.bits = wrt_xcalloc((size_t)t, sizeof *s.bits);
    s.top = wrt_xcalloc((size_t)t, sizeof *s.top);
    s.list = wrt_xcalloc((size_t)t, sizeof *s.list);
    for (int i = 0; i < t; i++) {
        s.acc[i] = wrt_xcalloc_aligned64(((size_t)n * ACC_STRIDE + ACC_STRIDE) * sizeof(double));
        s.bits[i] = wrt_xcalloc(((size_t)n >> 6) + 1, sizeof(uint64_t));
        s.top[i] = wrt_xcalloc(((size_t)n >> 12) + 1, sizeof(uint64_t));
        s.list[i] = wrt_xmalloc(((size_t)n + 1) * sizeof(uint32_t));
    }
    return s;
}

static void scratch_give(mul_scratch *s) {
    pthread_mutex_lock(&kept_mu);
    mul_scratch old = kept_scratch;
    kept_scratch = *s;
    pthread_mutex_unlock(&kept_mu);
    scratch_free(&old); /* the older set: the newer is the likelier size */
}

void wrt_csc_mul_scratch_free(void) {
    pthread_mutex_lock(&kept_mu);
    mul_scratch s = kept_scratch;
    memset(&kept_scratch, 0, sizeof kept_scratch);
    pthread_mutex_unlock(&kept_mu);
    scratch_free(&s);
}

/* The product's context: its inputs, one output record per column of the n x n result, and
 * each of the t threads' scratch (mul_scratch). */
static mul_ctx mul_ctx_make(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int t,
                            int order) {
    uint32_t n = a->n;
    mul_ctx c = {.a = a, .b = b, .drop = drop};
    if (w) {
        c.row_w = w->row_w; c.col_w = w->col_w; c.power_w = w->power_w;
        c.boost_w = w->boost_w; c.boost_lost = w->boost_lost;
        /* the bands only as A itself (its arrays: Tr takes the bands', series_tree.c); for
         * another matrix of the same size they would stand in for it */
        if (w->bands && w->skip > 0 && w->bands->a.row == a->row && w->bands->a.val == a->val) {
            c.bands = w->bands;
            c.skip = w->skip;
            c.a = &w->bands->a;
        } else if (!w->bands && w->skip > 0 && order) {
            c.skip = w->skip;
            c.ord = wrt_mul_order_make(a, w->row_w, w->power_w, t);
        }
    }
    c.out = wrt_xcalloc(n ? n : 1, sizeof *c.out);
#if defined(__x86_64__) && defined(__GNUC__)
    c.avx = __builtin_cpu_supports("avx");
#endif
    mul_scratch s = scratch_take(n, t);
    c.acc = s.acc; c.bits = s.bits; c.top = s.top; c.list = s.list;
    return c;
}

/* Gives the scratch back (kept for the next product) and frees the rest of what
 * mul_ctx_make allocated (the output records' own arrays are the caller's). */
static void mul_ctx_free(mul_ctx *c, int t) {
    mul_scratch s = {.n = c->a->n, .t = t, .acc = c->acc, .bits = c->bits, .top = c->top, .list = c->list};
    scratch_give(&s);
    free(c->out);
    wrt_mul_order_free((mul_order *)c->ord);
}

typedef struct mul_chunk_ctx { mul_ctx *c; uint32_t j0; } mul_chunk_ctx;

static void mul_chunk_column(size_t i, int th, void *user) {
    mul_chunk_ctx *cc = user;
    mul_column(cc->j0 + i, th, cc->c);
}

/* Appends columns [j0, j1) of the product to m (whose columns before j0 are complete),
 * freeing their per-column arrays. */
static void append_columns(wrt_csc *m, col_out *out, uint32_t j0, uint32_t j1) {
    for (uint32_t j = j0; j < j1; j++) m->col[j + 1] = m->col[j] + out[j].count;
    uint64_t total = m->col[j1];
    m->row = wrt_xrealloc(m->row, (total ? total : 1) * sizeof *m->row);
    m->val = wrt_xrealloc(m->val, (total ? total : 1) * 3 * sizeof *m->val);
    for (uint32_t j = j0; j < j1; j++) {
        if (out[j].count) {
            memcpy(&m->row[m->col[j]], out[j].row, out[j].count * sizeof *m->row);
            memcpy(&m->val[3 * m->col[j]], out[j].val, out[j].count * 3 * sizeof *m->val);
        }
        free(out[j].row); free(out[j].val);
        out[j].row = NULL; out[j].val = NULL;
    }
    m->nnz = total;
}

/* The columns are computed in 32 chunks, each appended to the result as it finishes: the
 * product's entries are held once plus a chunk's, not twice (every column's own arrays,
 * then their gathered copy, which was the series' peak; issue 22). Same entries, same
 * order, whatever the chunking or the threads. */
wrt_csc wrt_csc_mul(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int threads) {
    return wrt_csc_mul_cols(a, b, drop, w, threads, 0, a->n);
}

/* Columns [c0, c1) of the product, the others empty (precompute/dist.c divides a product
 * among processes by columns): each column is computed alone, so they are the same
 * entries as in the whole product. */
wrt_csc wrt_csc_mul_cols(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int threads,
                         uint32_t c0, uint32_t c1) {
    uint32_t n = a->n;
    wrt_csc m = {.n = n};
    m.col = wrt_xcalloc((size_t)n + 1, sizeof *m.col);
    m.row = wrt_xmalloc(sizeof *m.row);
    m.val = wrt_xmalloc(3 * sizeof *m.val);
    wrt_csc_mul_append(a, b, drop, w, threads, c0, c1, &m);
    return m;
}

void wrt_csc_mul_append(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w, int threads,
                        uint32_t c0, uint32_t c1, wrt_csc *out) {
    uint32_t n = a->n;
    if (c1 > n) c1 = n;
    if (c0 > c1) c0 = c1;
    int t = wrt_threads_resolve(threads);
    mul_ctx c = mul_ctx_make(a, b, drop, w, t, 1);
    wrt_csc m = *out;
    wrt_pool *pool = NULL;
    if (t > 1 && wrt_pool_create(t, &pool) != WRT_OK) pool = NULL;
    uint32_t chunk = n / 32 + 1;
    for (uint32_t j0 = c0; j0 < c1; j0 += chunk) {
        uint32_t j1 = c1 - j0 > chunk ? j0 + chunk : c1;
        mul_chunk_ctx cc = {&c, j0};
        if (pool) wrt_pool_run(pool, j1 - j0, 0, mul_chunk_column, &cc);
        else for (uint32_t j = j0; j < j1; j++) mul_column(j, 0, &c);
        append_columns(&m, c.out, j0, j1);
    }
    for (uint32_t j = c1; j < n; j++) m.col[j + 1] = m.col[c1];
    if (pool) wrt_pool_destroy(pool);
    mul_ctx_free(&c, t);
    *out = m;
}

typedef struct mul_sample_ctx { mul_ctx *c; const uint32_t *cols; } mul_sample_ctx;

static void mul_sample_column(size_t i, int th, void *user) {
    mul_sample_ctx *sc = user;
    size_t j = sc->cols[i];
    mul_column(j, th, sc->c);
    col_out *o = &sc->c->out[j];
    free(o->row); free(o->val);
    o->row = NULL; o->val = NULL;
}

uint64_t wrt_csc_mul_estimate(const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w,
                              uint32_t stride, int threads) {
    uint32_t n = a->n;
    if (stride < 1) stride = 1;
    if (n == 0) return 0;
    int t = wrt_threads_resolve(threads);
    mul_ctx c = mul_ctx_make(a, b, drop, w, t, 0);
    size_t m = ((size_t)n + stride - 1) / stride;
    /* only the sampled columns B has entries in are made (an empty one's count is 0):
     * the series' estimates by blocks of columns sample a block of B, the rest empty */
    uint32_t *cols = wrt_xmalloc((m + 1) * sizeof *cols), nc = 0;
    for (size_t i = 0; i < m; i++) {
        size_t j = i * stride;
        if (b->col[j + 1] > b->col[j]) cols[nc++] = (uint32_t)j;
    }
    mul_sample_ctx sc = {&c, cols};
    wrt_parallel_for(nc, t, mul_sample_column, &sc);
    /* the sampled columns' counts, scaled by the share of B's entries they hold (a
     * product column's fill follows its B column's), so a few dense columns are not
     * missed or overweighted by the stride */
    uint64_t kept = 0, bs = 0;
    for (uint32_t i = 0; i < nc; i++) {
        size_t j = cols[i];
        kept += c.out[j].count;
        bs += b->col[j + 1] - b->col[j];
    }
    free(cols);
    mul_ctx_free(&c, t);
    double scale = bs > 0 ? (double)b->nnz / (double)bs : (double)n / (double)m;
    return (uint64_t)((double)kept * scale + 0.5);
}

wrt_csc wrt_csc_add(const wrt_csc *a, const wrt_csc *b, double s) {
    const double s3[3] = {s, s, s};
    return wrt_csc_add3(a, b, s3);
}

wrt_csc wrt_csc_add3(const wrt_csc *a, const wrt_csc *b, const double s[3]) {
    uint32_t n = a->n;
    wrt_csc m = {.n = n};
    uint64_t cap = a->nnz + b->nnz;
    m.col = wrt_xcalloc((size_t)n + 1, sizeof *m.col);
    m.row = wrt_xmalloc((cap ? cap : 1) * sizeof *m.row);
    m.val = wrt_xmalloc((cap ? cap : 1) * 3 * sizeof *m.val);
    uint64_t k = 0;
    /* a's entries before b's next row (all the rest where b's column is done) are copied
     * as one run: the series' sum S + P, where P holds a few entries a column and S
     * millions, was copied entry by entry, serially, at every bounce. The same entries. */
    for (uint32_t j = 0; j < n; j++) {
        uint64_t ia = a->col[j], ea = a->col[j + 1], ib = b->col[j], eb = b->col[j + 1];
        while (ia < ea || ib < eb) {
            uint32_t rb = ib < eb ? b->row[ib] : UINT32_MAX;
            uint64_t run = ia;
            while (run < ea && a->row[run] < rb) run++;
            if (run > ia) {
                memcpy(&m.row[k], &a->row[ia], (run - ia) * sizeof *m.row);
                memcpy(&m.val[3 * k], &a->val[3 * ia], 3 * (run - ia) * sizeof *m.val);
                k += run - ia;
                ia = run;
            }
            if (ib == eb) break;
            m.row[k] = rb;
            if (ia < ea && a->row[ia] == rb) {
                for (int c = 0; c < 3; c++) m.val[3 * k + c] = (float)((double)a->val[3 * ia + c] + s[c] * b->val[3 * ib + c]);
                ia++;
            } else {
                for (int c = 0; c < 3; c++) m.val[3 * k + c] = (float)(s[c] * b->val[3 * ib + c]);
            }
            ib++;
            k++;
        }
        m.col[j + 1] = k;
    }
    m.nnz = k;
    return m;
}

void wrt_csc_add3_into(wrt_csc *a, const wrt_csc *b, const double s[3]) {
    uint32_t n = a->n;
    /* the merged columns' ends */
    uint64_t *col = wrt_xmalloc(((size_t)n + 1) * sizeof *col);
    col[0] = 0;
    for (uint32_t j = 0; j < n; j++) {
        uint64_t ia = a->col[j], ea = a->col[j + 1], ib = b->col[j], eb = b->col[j + 1], m = 0;
        while (ia < ea && ib < eb) {
            uint32_t ra = a->row[ia], rb = b->row[ib];
            ia += ra <= rb;
            ib += rb <= ra;
            m++;
        }
        col[j + 1] = col[j] + m + (ea - ia) + (eb - ib);
    }
    uint64_t total = col[n];
    a->row = wrt_xrealloc(a->row, (total ? total : 1) * sizeof *a->row);
    a->val = wrt_xrealloc(a->val, (total ? total : 1) * 3 * sizeof *a->val);
    /* merge from the last column and the last entry down: an entry of a moves to the
     * same place or later, so nothing is overwritten before it is read */
    for (uint32_t j = n; j-- > 0;) {
        uint64_t ia = a->col[j + 1], ib = b->col[j + 1], k = col[j + 1];
        const uint64_t ea = a->col[j], eb = b->col[j];
        while (ia > ea || ib > eb) {
            uint32_t ra = ia > ea ? a->row[ia - 1] : 0, rb = ib > eb ? b->row[ib - 1] : 0;
            int take_a = ia > ea && (ib == eb || ra >= rb), take_b = ib > eb && (ia == ea || rb >= ra);
            float v[3];
            uint32_t r = take_a ? ra : rb;
            if (take_a) {
                ia--;
                for (int c = 0; c < 3; c++) v[c] = a->val[3 * ia + c];
                if (take_b) { /* the same row in both: as wrt_csc_add3 rounds it */
                    ib--;
                    for (int c = 0; c < 3; c++) v[c] = (float)((double)v[c] + s[c] * b->val[3 * ib + c]);
                }
            } else {
                ib--;
                for (int c = 0; c < 3; c++) v[c] = (float)(s[c] * b->val[3 * ib + c]);
            }
            k--;
            a->row[k] = r;
            for (int c = 0; c < 3; c++) a->val[3 * k + c] = v[c];
        }
    }
    free(a->col);
    a->col = col;
    a->nnz = total;
}

/* Column j of a compression: the entries [start, end) of (srow, sval) that pass the
 * threshold (or the largest power entry, if no power entry would), written from index k
 * of (drow, dval) on, the power of the dropped ones handed to the kept ones. The
 * destination may be the source (in place: k <= start, each entry read before it is
 * overwritten); drow NULL only counts. Returns the new k. */
static uint64_t compress_column(const uint32_t *srow, const float *sval, uint64_t start, uint64_t end, uint32_t *drow,
                                float *dval, uint64_t k, double cw, double boost, double drop, const wrt_csc_weights *w,
                                const uint8_t *force) {
    uint64_t first = k, best = UINT64_MAX;
    double lost[3] = {0, 0, 0};
    const double *pw = w ? w->power_w : NULL;
    double bst = column_boost(boost, w ? w->boost_lost : 0, &srow[start], end - start, NULL, &sval[3 * start], cw,
                              w ? w->row_w : NULL, pw, drop, 0);
    if (pw) {
        /* if no entry that carries power would survive, the largest of them stays */
        double bestw = 0;
        int any = 0;
        for (uint64_t i = start; i < end && !any; i++) {
            const float *v = &sval[3 * i];
            double mx = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
            if (pw[srow[i]] == 0) continue;
            if (mx > 0 && mx * cw * bst * (w->row_w ? w->row_w[srow[i]] : 1.0) >= drop) any = 1;
            else if (pw[srow[i]] * (fabs(v[0]) + fabs(v[1]) + fabs(v[2])) > bestw) {
                bestw = pw[srow[i]] * (fabs(v[0]) + fabs(v[1]) + fabs(v[2]));
                best = i;
            }
        }
        if (any) best = UINT64_MAX;
    }
    for (uint64_t i = start; i < end; i++) {
        const float *v = &sval[3 * i];
        double mx = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
        double bi = bst > 1 && pw[srow[i]] != 0 ? bst : 1; /* bst > 1 only where pw is given */
        if (i == best || (force && force[i - start]) ||
            (mx > 0 && mx * cw * bi * (w && w->row_w ? w->row_w[srow[i]] : 1.0) >= drop)) {
            if (drow) {
                drow[k] = srow[i];
                memmove(&dval[3 * k], v, 3 * sizeof *v);
            }
            k++;
        } else if (pw && pw[srow[i]] != 0) {
            for (int ch = 0; ch < 3; ch++) lost[ch] += pw[srow[i]] * v[ch];
        }
    }
    if (drow && pw && (lost[0] != 0 || lost[1] != 0 || lost[2] != 0)) {
        /* the product's rule (spread_power) */
        for (int ch = 0; ch < 3; ch++) {
            if (lost[ch] == 0) continue;
            double same = 0, all = 0;
            for (uint64_t i = first; i < k; i++) {
                double v = dval[3 * i + ch];
                if (pw[drow[i]] == 0 || v == 0) continue;
                all += pw[drow[i]] * fabs(v);
                if ((v > 0) == (lost[ch] > 0)) same += pw[drow[i]] * fabs(v);
            }
            int any_sign = !(same > 0 && fabs(lost[ch]) <= same);
            double wsum = any_sign ? all : same;
            if (!(wsum > 0) || fabs(lost[ch]) > wsum) continue;
            for (uint64_t i = first; i < k; i++) {
                double v = dval[3 * i + ch];
                if (pw[drow[i]] != 0 && v != 0 && (any_sign || (v > 0) == (lost[ch] > 0)))
                    dval[3 * i + ch] = (float)(v + lost[ch] * fabs(v) / wsum);
            }
        }
    }
    return k;
}

static double col_boost(const wrt_csc_weights *w, uint32_t j) {
    return w && w->boost_w ? w->boost_w[j] : 1.0;
}

uint64_t wrt_csc_compress_col(uint32_t *row, float *val, uint64_t n, uint32_t j, double drop,
                              const wrt_csc_weights *w) {
    return compress_column(row, val, 0, n, row, val, 0, w && w->col_w ? w->col_w[j] : 1.0, col_boost(w, j), drop, w,
                           NULL);
}

uint64_t wrt_csc_compress_col_kept(const uint32_t *row, const float *val, uint64_t n, uint32_t j, double drop,
                                   const wrt_csc_weights *w, uint8_t *kept) {
    uint32_t *r = wrt_xmalloc((n ? n : 1) * sizeof *r);
    float *v = wrt_xmalloc(3 * (n ? n : 1) * sizeof *v);
    memcpy(r, row, n * sizeof *r);
    memcpy(v, val, 3 * n * sizeof *v);
    uint64_t m = compress_column(r, v, 0, n, r, v, 0, w && w->col_w ? w->col_w[j] : 1.0, col_boost(w, j), drop, w, NULL);
    /* the kept rows are a subsequence of the rows, in order */
    memset(kept, 0, n);
    for (uint64_t i = 0, a = 0; i < n && a < m; i++)
        if (row[i] == r[a]) { kept[i] = 1; a++; }
    free(r); free(v);
    return m;
}

uint64_t wrt_csc_compress_col_force(uint32_t *row, float *val, uint64_t n, uint32_t j, double drop,
                                    const wrt_csc_weights *w, const uint8_t *force) {
    return compress_column(row, val, 0, n, row, val, 0, w && w->col_w ? w->col_w[j] : 1.0, col_boost(w, j), drop, w,
                           force);
}

void wrt_csc_compress(wrt_csc *m, double drop, const wrt_csc_weights *w) {
    uint64_t k = 0, start = 0;
    for (uint32_t j = 0; j < m->n; j++) {
        uint64_t end = m->col[j + 1];
        double cw = w && w->col_w ? w->col_w[j] : 1.0;
        k = compress_column(m->row, m->val, start, end, m->row, m->val, k, cw, col_boost(w, j), drop, w, NULL);
        start = end;
        m->col[j + 1] = k;
    }
    m->nnz = k;
}

/* A counting pass sizes the result, then the columns are compressed into it: the same
 * entries as wrt_csc_compress on a copy, without the full copy (on the 12 x 12 maze the
 * series' first term: 515 MB for a moment, issue 22). */
wrt_csc wrt_csc_copy_compress(const wrt_csc *m, double drop, const wrt_csc_weights *w) {
    wrt_csc c = {.n = m->n};
    c.col = wrt_xmalloc(((size_t)m->n + 1) * sizeof *c.col);
    uint64_t k = 0;
    for (uint32_t j = 0; j < m->n; j++)
        k = compress_column(m->row, m->val, m->col[j], m->col[j + 1], NULL, NULL, k,
                            w && w->col_w ? w->col_w[j] : 1.0, col_boost(w, j), drop, w, NULL);
    c.row = wrt_xmalloc((k ? k : 1) * sizeof *c.row);
    c.val = wrt_xmalloc((k ? k : 1) * 3 * sizeof *c.val);
    c.col[0] = k = 0;
    for (uint32_t j = 0; j < m->n; j++) {
        k = compress_column(m->row, m->val, m->col[j], m->col[j + 1], c.row, c.val, k,
                            w && w->col_w ? w->col_w[j] : 1.0, col_boost(w, j), drop, w, NULL);
        c.col[j + 1] = k;
    }
    c.nnz = k;
    return c;
}

double wrt_csc_sumsq(const wrt_csc *m, double s) {
    if (!m->nnz) return s;
    const float *v = &m->val[3 * m->col[0]];
    for (uint64_t i = 0; i < 3 * m->nnz; i++) s += (double)v[i] * v[i];
    return s;
}

double wrt_csc_norm(const wrt_csc *m) { return sqrt(wrt_csc_sumsq(m, 0)); }

double wrt_csc_max(const wrt_csc *m) {
    double mx = 0;
    for (uint64_t i = 0; i < 3 * m->nnz; i++) mx = fmax(mx, fabs(m->val[i]));
    return mx;
}

void wrt_csc_apply(const wrt_csc *m, const double *x, double *y) {
    for (uint32_t j = 0; j < m->n; j++) {
        const double *xj = &x[3 * j];
        if (xj[0] == 0 && xj[1] == 0 && xj[2] == 0) continue;
        for (uint64_t k = m->col[j]; k < m->col[j + 1]; k++) {
            uint32_t i = m->row[k];
            for (int c = 0; c < 3; c++) y[3 * i + c] += (double)m->val[3 * k + c] * xj[c];
        }
    }
}
