/* test_sparse.c: the series' sparse algebra (precompute/sparse.c) against brute force.
 * The product is checked against sums over the triplets themselves (no CSC involved),
 * on a matrix large enough for several of the product's column chunks and several words
 * of its row bitmaps; the construction from triplets against a sequential float sum of
 * the duplicates in their input order (the order the bake's power entries rely on); the
 * product by blocks of columns against the whole; the series' coarse right factor
 * (--series-right) against a furnace's closed form. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "precompute/bake.h"
#include "precompute/sparse.h"
#include "bake_helpers.h"
#include "scene_build.h"
#include "test.h"

static uint32_t lcg(uint32_t *s) { *s = *s * 1664525u + 1013904223u; return *s >> 8; }

/* Duplicates are summed in float, in the order they come in the triplets: 1e8, 1, -1e8
 * gives 0 in that order (1e8 + 1 rounds to 1e8) and 1 in the order 1e8, -1e8, 1. */
static void test_duplicates_in_order(void) {
    wrt_triplet t[7] = {
        {2, 1, {1e8f, 1, 0}}, {0, 1, {5, 5, 5}}, {2, 1, {1, 1e8f, 0}}, {2, 1, {-1e8f, -1e8f, 0}},
        {1, 0, {3, 0, 0}},    {2, 1, {0, 1, 7}}, {1, 0, {0.5f, 0, 0}},
    };
    float want[3] = {0, 0, 0};
    for (int k = 0; k < 7; k++)
        if (t[k].row == 2 && t[k].col == 1)
            for (int c = 0; c < 3; c++) want[c] += t[k].v[c];
    wrt_csc m = wrt_csc_from_triplets(3, t, 7);
    CHECK(m.nnz == 3, "3 distinct entries, got %llu", (unsigned long long)m.nnz);
    CHECK(m.col[0] == 0 && m.col[1] == 1 && m.col[2] == 3 && m.col[3] == 3, "column starts 0 1 3 3");
    CHECK(m.row[0] == 1 && m.row[1] == 0 && m.row[2] == 2, "rows ascend within columns");
    CHECK(m.val[0] == 3.5f, "(1, 0): 3 + 0.5 = %g", m.val[0]);
    CHECK(m.val[3 * 2] == want[0] && m.val[3 * 2 + 1] == want[1] && m.val[3 * 2 + 2] == want[2],
          "(2, 1) summed in input order: %g %g %g, want %g %g %g", m.val[6], m.val[7], m.val[8], want[0], want[1],
          want[2]);
    CHECK(want[0] == 0 && want[1] == 1, "the case is order-sensitive (%g, %g)", want[0], want[1]);
    wrt_csc_free(&m);
}

/* Built by ranges of columns, freeing the triplets as it goes (T's assembly in the bake):
 * every entry the float sum of its (row, col) triplets in their order in t, found by
 * brute force, rows ascending within columns; large values (1e8 and 1 in one entry) make
 * the sums depend on the order. */
static void test_triplets_by_ranges(void) {
    enum { N = 300, COUNT = 9000 };
    uint32_t seed = 4242;
    wrt_triplet *t = malloc(COUNT * sizeof *t);
    for (int i = 0; i < COUNT; i++) {
        t[i] = (wrt_triplet){lcg(&seed) % 40, lcg(&seed) % N, {0}};
        for (int c = 0; c < 3; c++) {
            uint32_t r = lcg(&seed) % 7;
            t[i].v[c] = r == 0 ? 1e8f : r == 1 ? -1e8f : (float)(r - 3);
        }
    }
    wrt_triplet *copy = malloc(COUNT * sizeof *copy);
    memcpy(copy, t, COUNT * sizeof *t);
    wrt_csc m = wrt_csc_from_triplets_free(N, copy, COUNT, 1); /* copy freed */
    int ok = 1, order_ok = 1;
    uint64_t distinct = 0;
    for (uint32_t j = 0; j < N; j++) {
        for (uint64_t k = m.col[j]; k < m.col[j + 1]; k++) {
            if (k > m.col[j] && m.row[k - 1] >= m.row[k]) order_ok = 0;
            float want[3] = {0, 0, 0};
            int first = 1;
            for (int i = 0; i < COUNT; i++)
                if (t[i].col == j && t[i].row == m.row[k]) {
                    for (int c = 0; c < 3; c++) want[c] = first ? t[i].v[c] : want[c] + t[i].v[c];
                    first = 0;
                }
            if (first || memcmp(want, &m.val[3 * k], sizeof want)) ok = 0;
        }
        uint8_t seen[40] = {0};
        for (int i = 0; i < COUNT; i++)
            if (t[i].col == j && !seen[t[i].row]) { seen[t[i].row] = 1; distinct++; }
    }
    CHECK(m.nnz == distinct, "%llu entries, %llu distinct (row, col) in the triplets", (unsigned long long)m.nnz,
          (unsigned long long)distinct);
    CHECK(order_ok, "rows ascend within columns");
    CHECK(ok, "an entry is not the sum of its triplets in their order");
    wrt_csc w = wrt_csc_from_triplets(N, t, COUNT);
    CHECK(w.nnz == m.nnz && !memcmp(w.col, m.col, (N + 1) * sizeof *w.col) && !memcmp(w.row, m.row, m.nnz * 4) &&
              !memcmp(w.val, m.val, 12 * m.nnz),
          "the same bits as the whole build");
    /* the ranges scattered two at a time on two threads: the same bits */
    copy = malloc(COUNT * sizeof *copy);
    memcpy(copy, t, COUNT * sizeof *t);
    wrt_csc m2 = wrt_csc_from_triplets_free(N, copy, COUNT, 2);
    CHECK(m2.nnz == m.nnz && !memcmp(m2.col, m.col, (N + 1) * sizeof *m.col) && !memcmp(m2.row, m.row, m.nnz * 4) &&
              !memcmp(m2.val, m.val, 12 * m.nnz),
          "two threads: the same bits as one");
    /* an odd count (the triplets' two halves unequal, the last piece of the second short) */
    enum { ODD = COUNT - 7 };
    copy = malloc(ODD * sizeof *copy);
    memcpy(copy, t, ODD * sizeof *t);
    wrt_csc m3 = wrt_csc_from_triplets_free(N, copy, ODD, 2), w3 = wrt_csc_from_triplets(N, t, ODD);
    CHECK(m3.nnz == w3.nnz && !memcmp(m3.col, w3.col, (N + 1) * sizeof *m3.col) &&
              !memcmp(m3.row, w3.row, m3.nnz * 4) && !memcmp(m3.val, w3.val, 12 * m3.nnz),
          "%d triplets by ranges on two threads: the same bits as the whole build", (int)ODD);
    wrt_csc_free(&m3);
    wrt_csc_free(&w3);
    wrt_csc_free(&m);
    wrt_csc_free(&m2);
    wrt_csc_free(&w);
    free(t);
}

/* C = A B at drop 0 against sum_k A_ik B_kj over the triplets; 1 and 2 threads give the same
 * bytes. n = 9,000: 32 chunks of 282 columns, 3 words of the upper row bitmap. */
static void test_product_brute_force(void) {
    enum { N = 9000, PER = 6 };
    uint32_t seed = 777;
    wrt_triplet *ta = malloc(N * PER * sizeof *ta), *tb = malloc(N * PER * sizeof *tb);
    for (uint32_t j = 0; j < N; j++)
        for (int e = 0; e < PER; e++) {
            /* A: rows spread over the whole range (far rows in other bitmap words);
             * B: near the diagonal, with repeats (duplicates summed) */
            ta[j * PER + e] = (wrt_triplet){lcg(&seed) % N, j, {0}};
            tb[j * PER + e] = (wrt_triplet){(j + lcg(&seed) % 5) % N, j, {0}};
            for (int c = 0; c < 3; c++) {
                ta[j * PER + e].v[c] = (float)((lcg(&seed) % 2001) / 1000.0 - 1.0);
                tb[j * PER + e].v[c] = (float)((lcg(&seed) % 2001) / 1000.0 - 1.0);
            }
        }
    wrt_csc a = wrt_csc_from_triplets(N, ta, N * PER), b = wrt_csc_from_triplets(N, tb, N * PER);
    wrt_csc c1 = wrt_csc_mul(&a, &b, 0, NULL, 1), c2 = wrt_csc_mul(&a, &b, 0, NULL, 2);
    int same = c1.nnz == c2.nnz && !memcmp(c1.col, c2.col, (N + 1) * sizeof *c1.col) &&
               !memcmp(c1.row, c2.row, c1.nnz * sizeof *c1.row) && !memcmp(c1.val, c2.val, 3 * c1.nnz * sizeof *c1.val);
    CHECK(same, "1 and 2 threads give different products");
    /* by blocks of columns appended one after the other (series_blocks.c), uneven and one
     * of them inside a chunk: the same columns, entries and order as the whole product */
    wrt_csc cb = {.n = N};
    cb.col = calloc(N + 1, sizeof *cb.col);
    cb.row = malloc(sizeof *cb.row);
    cb.val = malloc(3 * sizeof *cb.val);
    const uint32_t cuts[] = {0, 17, 5000, 5001, N};
    for (int i = 0; i < 4; i++) wrt_csc_mul_append(&a, &b, 0, NULL, 2, cuts[i], cuts[i + 1], &cb);
    CHECK(cb.nnz == c1.nnz && !memcmp(cb.col, c1.col, (N + 1) * sizeof *cb.col) &&
              !memcmp(cb.row, c1.row, c1.nnz * sizeof *cb.row) && !memcmp(cb.val, c1.val, 3 * c1.nnz * sizeof *cb.val),
          "the product by blocks of columns differs from the whole product");
    wrt_csc_free(&cb);
    /* the truth, column by column, from the triplets */
    double *col = calloc(3 * (size_t)N, sizeof *col);
    uint8_t *hit = calloc(N, 1);
    double worst = 0;
    int order_ok = 1, count_ok = 1, cols_checked = 0;
    for (uint32_t j = 0; j < N; j += 7) {
        memset(col, 0, 3 * (size_t)N * sizeof *col);
        memset(hit, 0, N);
        for (int eb = 0; eb < PER; eb++) {
            const wrt_triplet *bt = &tb[j * PER + eb];
            for (uint32_t k = 0; k < N * PER; k++) {
                if (ta[k].col != bt->row) continue;
                hit[ta[k].row] = 1;
                for (int c = 0; c < 3; c++) col[3 * ta[k].row + c] += (double)ta[k].v[c] * bt->v[c];
            }
        }
        uint32_t want = 0;
        for (uint32_t i = 0; i < N; i++) want += hit[i];
        count_ok &= c1.col[j + 1] - c1.col[j] == want;
        for (uint64_t k = c1.col[j]; k < c1.col[j + 1]; k++) {
            if (k > c1.col[j] && c1.row[k] <= c1.row[k - 1]) order_ok = 0;
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(c1.val[3 * k + c] - col[3 * c1.row[k] + c]));
        }
        cols_checked++;
    }
    CHECK(count_ok, "a column's entry count differs from the rows its sums touch");
    CHECK(order_ok, "rows not strictly ascending within a column");
    CHECK(worst < 1e-5, "product off the brute-force sums by %.3g", worst);
    printf("product: %llu x %llu entries -> %llu; %d columns against brute force, worst %.2e\n",
           (unsigned long long)a.nnz, (unsigned long long)b.nnz, (unsigned long long)c1.nnz, cols_checked, worst);
    free(col); free(hit); free(ta); free(tb);
    wrt_csc_free(&a); wrt_csc_free(&b); wrt_csc_free(&c1); wrt_csc_free(&c2);
}


/* The largest relative difference between x's and y's values where both have the same
 * entries in the same places; infinity where they do not */
static double same_entries_within(const wrt_csc *x, const wrt_csc *y) {
    if (x->nnz != y->nnz || memcmp(x->col, y->col, ((size_t)x->n + 1) * sizeof *x->col) ||
        memcmp(x->row, y->row, x->nnz * sizeof *x->row))
        return INFINITY;
    double worst = 0;
    for (uint64_t e = 0; e < 3 * x->nnz; e++)
        worst = fmax(worst, fabs(x->val[e] - y->val[e]) / fmax(fabs(y->val[e]), 1e-30));
    return worst;
}

/* The skip tests' B (n x n): 8 columns, each reading all 2 per small columns of A with 1
 * and one of the 64 large columns after them */
static wrt_csc skip_test_b(uint32_t n, uint32_t per) {
    wrt_triplet *tb = malloc(8 * (2 * (size_t)per + 1) * sizeof *tb);
    uint32_t nb = 0;
    for (uint32_t j = 0; j < 8; j++) {
        for (uint32_t k = 0; k < 2 * per; k++) tb[nb++] = (wrt_triplet){k, j, {1, 1, 1}};
        tb[nb++] = (wrt_triplet){2 * per + j * 7 % 64, j, {1, 1, 1}};
    }
    wrt_csc b = wrt_csc_from_triplets(n, tb, nb);
    free(tb);
    return b;
}

/* The products' skipped contributions (wrt_csc_bands, series_skip): against the product that
 * sums everything, on a matrix whose column sums are known by brute force.
 * - Each of A's columns has its largest entry 11.3 times the small one, elsewhere (rows
 *   150 on), so the small entries lie in band 4 of their column, not at its top.
 * - Column j of B reads 64 columns of A whose only entries, at row 0 and row 1, are
 *   contributions of 1.02 and of 0.45 times skip x drop (weighted): 64 of each sum to
 *   about 4 and 1.8 times the threshold, so the plain product keeps both rows. The rule
 *   must sum every contribution at or above skip x drop (row 0 kept, at its plain value)
 *   and never any under half of it (row 1 dropped, its power carried to row 0): the band
 *   boundary, to within the factor 2 of a band.
 * - Each column also reads one large entry whose own row stays, so the power has where to go.
 * - The power (power_w x entry) of every column is the plain product's, channel by channel.
 * - A skip too small to reach any band gives the plain product's entries. */
static void test_product_skip(void) {
    enum { NA = 200, PER = 64 };
    const double drop = 0.01, skip = 1.0 / 16;
    double rw[NA], cw[NA], pw[NA];
    /* rows 100 on carry no power (so the plain product's row 0 is its brute-force sum) */
    for (uint32_t i = 0; i < NA; i++) { rw[i] = 1; cw[i] = 1; pw[i] = i < 100 ? 1.0 + (i % 3) : 0; }
    rw[1] = 2; /* row 1's contributions weighed twice: the rule reads the weighted size */
    /* A: column k < 2 PER: row 0 at 1.02 skip drop (k even) or row 1 at 0.45 skip drop / 2
     * (k odd, weighed by rw = 2), with two other rows far smaller; column 2 PER + m: row 2 + m
     * at 5 drop (the large entries) */
    wrt_triplet ta[3 * 2 * PER + 64];
    uint32_t na = 0;
    for (uint32_t k = 0; k < 2 * PER; k++) {
        double v = k % 2 == 0 ? 1.02 * skip * drop : 0.45 * skip * drop / 2;
        double top = 11.3 * v * (k % 2 ? 2 : 1); /* weighed as row 1's, rw = 2 */
        ta[na++] = (wrt_triplet){k % 2, k, {(float)v, (float)(0.7 * v), (float)(0.3 * v)}};
        ta[na++] = (wrt_triplet){100 + k % 50, k, {(float)(1e-4 * v), 0, (float)(1e-4 * v)}};
        ta[na++] = (wrt_triplet){150 + k % 50, k, {(float)top, (float)top, (float)top}};
    }
    for (uint32_t m = 0; m < 64; m++) ta[na++] = (wrt_triplet){2 + m, 2 * PER + m, {0.05f, 0.04f, 0.03f}};
    wrt_csc a = wrt_csc_from_triplets(NA, ta, na), b = skip_test_b(NA, PER);
    wrt_csc_weights w = {rw, cw, pw, NULL, 0, NULL, 0};
    wrt_csc plain = wrt_csc_mul(&a, &b, drop, &w, 2);
    wrt_csc_bands bands;
    wrt_csc_bands_make(&a, rw, pw, &bands);
    { /* the same bands made in a copy's own arrays (the series' Tr): the same bits */
        wrt_csc ac = wrt_csc_copy(&a);
        wrt_csc_bands ip;
        wrt_csc_bands_make_in_place(&ac, rw, pw, &ip, 2);
        const size_t nbs = (size_t)a.n * WRT_CSC_BANDS;
        CHECK(ip.a.row == ac.row && ip.a.val == ac.val && ip.a.nnz == bands.a.nnz &&
                  !memcmp(ip.a.col, bands.a.col, ((size_t)a.n + 1) * sizeof *ip.a.col) &&
                  !memcmp(ip.a.row, bands.a.row, bands.a.nnz * sizeof *ip.a.row) &&
                  !memcmp(ip.a.val, bands.a.val, 3 * bands.a.nnz * sizeof *ip.a.val) &&
                  !memcmp(ip.start, bands.start, nbs * sizeof *ip.start) &&
                  !memcmp(ip.top, bands.top, a.n * sizeof *ip.top) &&
                  !memcmp(ip.rest, bands.rest, 4 * nbs * sizeof *ip.rest),
              "bands made in place differ from the bands made in a copy");
        ip.a.row = NULL; /* ac's */
        ip.a.val = NULL;
        wrt_csc_bands_free(&ip);
        wrt_csc_free(&ac);
    }
    wrt_csc_weights ws = w;
    ws.bands = &bands;
    ws.skip = skip;
    /* the bands stand in for A only when given as A itself (as the series' Tr is) */
    wrt_csc notA = wrt_csc_mul(&a, &b, drop, &ws, 2);
    CHECK(notA.nnz == plain.nnz && !memcmp(notA.row, plain.row, notA.nnz * 4) &&
              !memcmp(notA.val, plain.val, 12 * notA.nnz),
          "bands made from another matrix were used in its place");
    wrt_csc_free(&notA);
    wrt_csc sk1 = wrt_csc_mul(&bands.a, &b, drop, &ws, 1), sk2 = wrt_csc_mul(&bands.a, &b, drop, &ws, 2);
    CHECK(sk1.nnz == sk2.nnz && !memcmp(sk1.row, sk2.row, sk1.nnz * 4) && !memcmp(sk1.val, sk2.val, 12 * sk1.nnz),
          "skipping: 1 and 2 threads give different products");
    int rows_ok = 1, power_ok = 1, row0_ok = 1;
    double worst_power = 0, worst0 = 0;
    for (uint32_t j = 0; j < 8; j++) {
        int p0 = 0, p1 = 0, s0 = 0, s1 = 0;
        double pp[3] = {0}, sp[3] = {0}, v0p = 0, v0s = 0;
        for (uint64_t e = plain.col[j]; e < plain.col[j + 1]; e++) {
            p0 |= plain.row[e] == 0; p1 |= plain.row[e] == 1;
            for (int c = 0; c < 3; c++) pp[c] += pw[plain.row[e]] * plain.val[3 * e + c];
        }
        for (uint64_t e = sk1.col[j]; e < sk1.col[j + 1]; e++) {
            s0 |= sk1.row[e] == 0; s1 |= sk1.row[e] == 1;
            for (int c = 0; c < 3; c++) sp[c] += pw[sk1.row[e]] * sk1.val[3 * e + c];
        }
        /* row 0's value: the plain product's, give or take the power row 1 hands over */
        double brute0 = PER * 1.02 * skip * drop;
        for (uint64_t e = plain.col[j]; e < plain.col[j + 1]; e++) if (plain.row[e] == 0) v0p = plain.val[3 * e];
        for (uint64_t e = sk1.col[j]; e < sk1.col[j + 1]; e++) if (sk1.row[e] == 0) v0s = sk1.val[3 * e];
        rows_ok &= p0 && p1 && s0 && !s1;
        row0_ok &= v0s >= brute0 * (1 - 1e-5);
        worst0 = fmax(worst0, fabs(v0p - brute0) / brute0);
        for (int c = 0; c < 3; c++) {
            double d = fabs(sp[c] - pp[c]) / fabs(pp[c]);
            worst_power = fmax(worst_power, d);
            power_ok &= d < 1e-6;
        }
    }
    CHECK(worst0 < 1e-5, "plain product's row 0 off the brute-force sum by %.3g", worst0);
    CHECK(rows_ok, "rows kept: the plain product keeps rows 0 and 1; skipping keeps row 0 (contributions at 1.02 x "
                   "skip x drop) and drops row 1 (at 0.45 x)");
    CHECK(row0_ok, "skipping lost some of row 0's contributions (at 1.02 x skip x drop)");
    CHECK(power_ok, "skipping: a column's power off the plain product's by %.3g", worst_power);
    /* a skip under every band: the plain product's entries */
    ws.skip = 1e-12;
    wrt_csc tiny = wrt_csc_mul(&bands.a, &b, drop, &ws, 2);
    double worst = same_entries_within(&tiny, &plain);
    CHECK(worst < 1e-6, "a skip under every band: not the plain product (%.3g)", worst);
    printf("skip %g: %llu entries against %llu plain; column power within %.2e; row 0 plain within %.2e of brute "
           "force\n", skip, (unsigned long long)sk1.nnz, (unsigned long long)plain.nnz, worst_power, worst0);
    wrt_csc_bands_free(&bands);
    wrt_csc_free(&a); wrt_csc_free(&b); wrt_csc_free(&plain); wrt_csc_free(&sk1); wrt_csc_free(&sk2);
    wrt_csc_free(&tiny);
}

/* wrt_csc_apply against a plain loop over the matrix's entries, with a vector whose three channels
 * differ (a furnace's uniform light has equal channels and cannot tell them apart) */
/* The plain series' skip (sparse.h: skip without bands, A read in the order the product
 * makes, sparse.c mul_order): only contributions at rows that carry no power are skipped.
 * - Column j of B reads 2 PER columns of A. Even ones hold row 100 at 1.02 x skip x drop
 *   and odd ones row 101 at 0.45 x skip x drop (weighted: row_w 2 there), both rows
 *   without power; every one also holds row 0 (power) at 0.45 x skip x drop and a large
 *   entry without power 11.3 times the small one's weighted size elsewhere (rows 150 on),
 *   so the small entries lie in a band of their column below its top.
 * - The plain product keeps rows 0, 100 and 101 (PER contributions of each sum past the
 *   threshold). The skip must sum every contribution at or above skip x drop (row 100
 *   kept at its plain value) and never one under half of it (row 101 dropped), and never
 *   skip a power row, however small (row 0 at its plain value).
 * - The power (power_w x entry) of every column is the plain product's, channel by
 *   channel: the skip drops no power, so nothing has to be handed over for it.
 * - A skip under every band gives the plain product's entries (summed in another order:
 *   to float rounding). */
static void test_product_skip_order(void) {
    enum { NA = 300, PER = 64 };
    const double drop = 0.01, skip = 1.0 / 16;
    double rw[NA], cw[NA], pw[NA];
    for (uint32_t i = 0; i < NA; i++) { rw[i] = 1; cw[i] = 1; pw[i] = i < 100 ? 1.0 + (i % 3) : 0; }
    rw[101] = 2;
    wrt_triplet ta[4 * 2 * PER + 64];
    uint32_t na = 0;
    for (uint32_t k = 0; k < 2 * PER; k++) {
        double v = k % 2 == 0 ? 1.02 * skip * drop : 0.45 * skip * drop / 2;
        double top = 11.3 * 1.02 * skip * drop;
        ta[na++] = (wrt_triplet){0, k, {(float)(0.45 * skip * drop), (float)(0.2 * skip * drop), 0}};
        ta[na++] = (wrt_triplet){100 + k % 2, k, {(float)v, (float)(0.7 * v), (float)(0.3 * v)}};
        ta[na++] = (wrt_triplet){150 + k % 50, k, {(float)top, (float)top, (float)top}};
        ta[na++] = (wrt_triplet){200 + k % 50, k, {(float)(1e-4 * v), 0, (float)(1e-4 * v)}};
    }
    for (uint32_t m = 0; m < 64; m++) ta[na++] = (wrt_triplet){2 + m, 2 * PER + m, {0.05f, 0.04f, 0.03f}};
    wrt_csc a = wrt_csc_from_triplets(NA, ta, na), b = skip_test_b(NA, PER);
    wrt_csc_weights w = {rw, cw, pw, NULL, 0, NULL, 0};
    wrt_csc plain = wrt_csc_mul(&a, &b, drop, &w, 2);
    wrt_csc_weights ws = w;
    ws.skip = skip;
    wrt_csc sk1 = wrt_csc_mul(&a, &b, drop, &ws, 1), sk2 = wrt_csc_mul(&a, &b, drop, &ws, 2);
    CHECK(sk1.nnz == sk2.nnz && !memcmp(sk1.col, sk2.col, ((size_t)NA + 1) * sizeof *sk1.col) &&
              !memcmp(sk1.row, sk2.row, sk1.nnz * 4) && !memcmp(sk1.val, sk2.val, 12 * sk1.nnz),
          "skipping by the order: 1 and 2 threads give different products");
    int rows_ok = 1, power_ok = 1, kept_ok = 1;
    double worst_power = 0, worst_kept = 0;
    const double brute100 = PER * 1.02 * skip * drop, brute0 = 2 * PER * 0.45 * skip * drop;
    for (uint32_t j = 0; j < 8; j++) {
        int p[3] = {0}, s[3] = {0};
        const uint32_t want[3] = {0, 100, 101};
        double pp[3] = {0}, sp[3] = {0}, vp[2] = {0}, vs[2] = {0};
        for (uint64_t e = plain.col[j]; e < plain.col[j + 1]; e++) {
            for (int q = 0; q < 3; q++) p[q] |= plain.row[e] == want[q];
            for (int c = 0; c < 3; c++) pp[c] += pw[plain.row[e]] * plain.val[3 * e + c];
            if (plain.row[e] == 0) vp[0] = plain.val[3 * e];
            if (plain.row[e] == 100) vp[1] = plain.val[3 * e];
        }
        for (uint64_t e = sk1.col[j]; e < sk1.col[j + 1]; e++) {
            for (int q = 0; q < 3; q++) s[q] |= sk1.row[e] == want[q];
            for (int c = 0; c < 3; c++) sp[c] += pw[sk1.row[e]] * sk1.val[3 * e + c];
            if (sk1.row[e] == 0) vs[0] = sk1.val[3 * e];
            if (sk1.row[e] == 100) vs[1] = sk1.val[3 * e];
        }
        rows_ok &= p[0] && p[1] && p[2] && s[0] && s[1] && !s[2];
        /* rows 0 and 100: every contribution summed, the plain product's brute-force sums */
        double d0 = fabs(vs[0] - brute0) / brute0, d1 = fabs(vs[1] - brute100) / brute100;
        worst_kept = fmax(worst_kept, fmax(d0, d1));
        kept_ok &= d0 < 1e-5 && d1 < 1e-5 && fabs(vp[0] - brute0) < 1e-5 * brute0 &&
                   fabs(vp[1] - brute100) < 1e-5 * brute100;
        for (int c = 0; c < 3; c++) {
            double d = fabs(sp[c] - pp[c]) / fabs(pp[c]);
            worst_power = fmax(worst_power, d);
            power_ok &= d < 1e-6;
        }
    }
    CHECK(rows_ok, "rows kept: the plain product keeps rows 0, 100 and 101; skipping by the order keeps row 0 "
                   "(power), row 100 (contributions at 1.02 x skip x drop) and drops row 101 (at 0.45 x)");
    CHECK(kept_ok, "skipping by the order: rows 0 and 100 off their brute-force sums by %.3g", worst_kept);
    CHECK(power_ok, "skipping by the order: a column's power off the plain product's by %.3g", worst_power);
    ws.skip = 1e-12;
    wrt_csc tiny = wrt_csc_mul(&a, &b, drop, &ws, 2);
    double worst = same_entries_within(&tiny, &plain);
    CHECK(worst < 1e-6, "skipping by the order under every band: not the plain product (%.3g)", worst);
    printf("skip by the order %g: %llu entries against %llu plain; column power within %.2e; kept rows within %.2e "
           "of brute force\n", skip, (unsigned long long)sk1.nnz, (unsigned long long)plain.nnz, worst_power,
           worst_kept);
    wrt_csc_free(&a); wrt_csc_free(&b); wrt_csc_free(&plain); wrt_csc_free(&sk1); wrt_csc_free(&sk2);
    wrt_csc_free(&tiny);
}

/* The order's 32-bit places (a column of 65,536 entries or more; sparse.c mul_order):
 * column 0 of A holds every row of 70,000, which puts the whole order in 32 bits;
 * columns 1 to 40 hold rows 0 to 1,999 at sizes from 1 down to 1e-3, each read by B at
 * 0.01. A row's 40 contributions sum past the threshold from size 2.5e-3 on, but at
 * skip 1/16 those under 2^-8 lie in bands left out: the skip keeps fewer entries than the
 * plain product, the same column power, the same entries at 1 and 2 threads, and under
 * every band the plain product's entries. */
static void test_product_skip_order_wide(void) {
    enum { N = 70000, COLS = 40, ROWS = 2000 };
    const double drop = 1e-3;
    double *rw = malloc(N * sizeof *rw), *pw = malloc(N * sizeof *pw);
    for (uint32_t i = 0; i < N; i++) { rw[i] = 1; pw[i] = i % 97 == 0 ? 1 : 0; }
    wrt_triplet *ta = malloc((N + COLS * ROWS) * sizeof *ta), tb[3 * (COLS + 1)];
    uint32_t na = 0, nb = 0;
    for (uint32_t i = 0; i < N; i++) {
        float v = (float)pow(10.0, -5.0 * (double)((i * 7919u) % N) / N);
        ta[na++] = (wrt_triplet){i, 0, {v, 0.5f * v, 0.25f * v}};
    }
    for (uint32_t k = 1; k <= COLS; k++)
        for (uint32_t i = 0; i < ROWS; i++) {
            float v = (float)pow(10.0, -3.0 * (double)((i * 131u + k) % ROWS) / ROWS);
            ta[na++] = (wrt_triplet){i, k, {v, 0.7f * v, 0.4f * v}};
        }
    for (uint32_t j = 0; j < 3; j++)
        for (uint32_t k = 0; k <= COLS; k++) tb[nb++] = (wrt_triplet){k, j, {0.01f, 0.01f * (float)(j + 1), 0.01f}};
    wrt_csc a = wrt_csc_from_triplets(N, ta, na), b = wrt_csc_from_triplets(N, tb, nb);
    wrt_csc_weights w = {rw, NULL, pw, NULL, 0, NULL, 0};
    wrt_csc plain = wrt_csc_mul(&a, &b, drop, &w, 2);
    wrt_csc_weights ws = w;
    ws.skip = 1e-12;
    wrt_csc tiny = wrt_csc_mul(&a, &b, drop, &ws, 2);
    double worst = same_entries_within(&tiny, &plain);
    CHECK(worst < 1e-6, "32-bit order under every band: not the plain product (%.3g)", worst);
    ws.skip = 1.0 / 16;
    wrt_csc sk1 = wrt_csc_mul(&a, &b, drop, &ws, 1), sk2 = wrt_csc_mul(&a, &b, drop, &ws, 2);
    CHECK(same_entries_within(&sk1, &sk2) == 0, "32-bit order: 1 and 2 threads give different products");
    double worst_power = 0;
    for (uint32_t j = 0; j < 3; j++)
        for (int c = 0; c < 3; c++) {
            double pp = 0, sp = 0;
            for (uint64_t e = plain.col[j]; e < plain.col[j + 1]; e++) pp += pw[plain.row[e]] * plain.val[3 * e + c];
            for (uint64_t e = sk1.col[j]; e < sk1.col[j + 1]; e++) sp += pw[sk1.row[e]] * sk1.val[3 * e + c];
            worst_power = fmax(worst_power, fabs(sp - pp) / fabs(pp));
        }
    CHECK(worst_power < 1e-6, "32-bit order: a column's power off the plain product's by %.3g", worst_power);
    CHECK(sk1.nnz < plain.nnz, "32-bit order at 1/16: %llu entries, the plain product %llu (nothing skipped)",
          (unsigned long long)sk1.nnz, (unsigned long long)plain.nnz);
    printf("skip by the 32-bit order: %llu entries against %llu plain; column power within %.2e\n",
           (unsigned long long)sk1.nnz, (unsigned long long)plain.nnz, worst_power);
    free(rw); free(pw); free(ta);
    wrt_csc_free(&a); wrt_csc_free(&b); wrt_csc_free(&plain); wrt_csc_free(&tiny);
    wrt_csc_free(&sk1); wrt_csc_free(&sk2);
}

static void test_apply_brute_force(void) {
    enum { N = 500, PER = 5 };
    uint32_t seed = 4242;
    wrt_triplet *t = malloc(N * PER * sizeof *t);
    double *x = malloc(3 * N * sizeof *x), *y = calloc(3 * N, sizeof *y), *want = calloc(3 * N, sizeof *want);
    for (uint32_t i = 0; i < 3 * N; i++) x[i] = (lcg(&seed) % 2001) / 1000.0 - 1.0;
    for (uint32_t j = 0; j < N; j++)
        for (int e = 0; e < PER; e++) {
            wrt_triplet *q = &t[j * PER + e];
            *q = (wrt_triplet){lcg(&seed) % N, j, {0}};
            for (int c = 0; c < 3; c++) q->v[c] = (float)((lcg(&seed) % 2001) / 1000.0 - 1.0);
        }
    wrt_csc m = wrt_csc_from_triplets(N, t, N * PER);
    /* the truth: y_r += sum of the duplicates (summed in float, as the CSC holds them) x_c */
    for (uint32_t j = 0; j < N; j++)
        for (uint64_t k = m.col[j]; k < m.col[j + 1]; k++)
            for (int c = 0; c < 3; c++) want[3 * m.row[k] + c] += (double)m.val[3 * k + c] * x[3 * j + c];
    wrt_csc_apply(&m, x, y);
    double worst = 0, scale = 0;
    for (uint32_t i = 0; i < 3 * N; i++) { worst = fmax(worst, fabs(y[i] - want[i])); scale = fmax(scale, fabs(want[i])); }
    CHECK(scale > 0.1 && worst <= 1e-12 * scale, "apply: largest difference %.3g of %.3g", worst, scale);
    free(t); free(x); free(y); free(want);
    wrt_csc_free(&m);
}

/* The products' right factor compressed (series.c): a closed box of 2 x 2 quads a face,
 * coloured albedo 0.5 / 0.9 / 0.99, quality 4: every quad's indirect irradiance is
 * rho / (1 - rho) per channel, with the full T and with the default right factor (4 x
 * eps), within the furnace claim, flux and every quad, and the two within 0.1% of each
 * other on every quad and channel. Measured beyond the default: at 16 x eps the flux is
 * 0.31% off, at 64 x eps 2.6% (the columns' dropped power outgrows what their kept
 * entries may take, and is lost), which is why the default is 4. */
static void test_series_right_furnace(void) {
    const double rho[3] = {0.5, 0.9, 0.99}, fs[2] = {-1, 0};
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, rho[0], rho[1], rho[2]);
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 2, m);
    double *e[2];
    for (int k = 0; k < 2; k++) {
        wrt_bake_result r;
        wrt_bake_options o = opts(4, 0, 0);
        o.series_right = fs[k];
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
        e[k] = root_response(&s, &r);
        double worst = 0, flux_err = 0;
        for (int c = 0; c < 3; c++) {
            double flux = 0, area = 0, truth = rho[c] / (1 - rho[c]);
            for (int q = 0; q < s.nquads; q++) {
                worst = fmax(worst, fabs(e[k][3 * q + c] / truth - 1));
                flux += e[k][3 * q + c] * s.quads[q].area;
                area += s.quads[q].area;
            }
            flux_err = fmax(flux_err, fabs(flux / (area * truth) - 1));
        }
        CHECK(flux_err < 5e-4, "series_right %g: flux off rho / (1 - rho) by %.3g%%", fs[k], 100 * flux_err);
        CHECK(worst < 5e-4, "series_right %g: worst quad off rho / (1 - rho) by %.3g%%", fs[k], 100 * worst);
        printf("series right factor %g: flux off the closed form by %.4f%%, worst quad %.4f%%, %llu bounces, "
               "%llu entries\n", fs[k], 100 * flux_err, 100 * worst, (unsigned long long)r.c.bounces,
               (unsigned long long)r.op.nnz);
        wrt_bake_result_free(&r);
    }
    double diff = 0;
    for (int q = 0; q < s.nquads; q++)
        for (int c = 0; c < 3; c++) diff = fmax(diff, fabs(e[1][3 * q + c] / e[0][3 * q + c] - 1));
    CHECK(diff < 1e-3, "default right factor off the full T's response by %.3g%%", 100 * diff);
    for (int k = 0; k < 2; k++) free(e[k]);
    tsb_free(&s);
}

int main(int argc, char **argv) {
    TEST_RUN(test_duplicates_in_order);
    TEST_RUN(test_triplets_by_ranges);
    TEST_RUN(test_product_brute_force);
    TEST_RUN(test_apply_brute_force);
    TEST_RUN(test_series_right_furnace);
    TEST_RUN(test_product_skip);
    TEST_RUN(test_product_skip_order);
    TEST_RUN(test_product_skip_order_wide);
    TEST_END();
}
