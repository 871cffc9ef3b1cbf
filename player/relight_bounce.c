/* relight_bounce.c: the first glossy bounce through the first-bounce operator K (a file
 * with g->nkcols > 0; formats/GTO_FORMAT.md, docs/algorithm.md). A departure from
 * Kontkanen et al. 2006, whose section 5 sends every bounce through the operator: on a
 * quad with K columns the projection (relight_project.c) also gives, per light, c over
 * K's columns, the quad's outgoing functions: g(w_l) replaced by the BRDF table's
 * btilde_g(w_l) at the light's exact direction (RGB, no spread). Per update Y = K c (K by
 * rows, in groups of rows sharing a spatial node), E' = E with that quad's functions set
 * to 0, plus Y, and X = Op E' + Y (relight_multiply.c): the direct light a glossy quad
 * reflects reaches the others with its exact lobe (at K's outgoing level), every later
 * bounce through Op. A file without K takes the path without it unchanged, to the bit.
 * This file checks and lays out K at creation and computes Y and E' per update. Depends
 * on relight_internal.h, the mapped K (formats/gto.h), SSE2 and AVX where present. */
#include "relight_internal.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef WRT_K_AVX
#include <immintrin.h>
#endif

/* What the relighter relies on in K (the reader checks the rest): WRT_ERR_CORRUPT naming
 * the column or entry. */
static wrt_status k_check(const wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nk = g->nkcols, nq = g->nquads;
    if (!g->kkeys || !g->kcol_start || (g->knnz && !g->k_codes && (!g->krows || !g->kvals)))
        return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: %u columns without their arrays", nk);
    if (g->kcol_start[0] != 0 || g->kcol_start[nk] != g->knnz)
        return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column starts do not run from 0 to %llu entries",
                        (unsigned long long)g->knnz);
    for (uint32_t j = 0; j < nk; j++) {
        wrt_fkey k = g->kkeys[j];
        wrt_node sn = wrt_fkey_snode(k), an = wrt_fkey_anode(k);
        int st = wrt_fkey_stype(k), at = wrt_fkey_atype(k);
        uint32_t q = wrt_fkey_quad(k);
        if (j && k <= g->kkeys[j - 1]) return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: keys not ascending", j);
        if (q >= nq || !r->qi[q].glossy)
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: quad %u is not a glossy quad", j, q);
        if (!(sn.x < (1u << sn.level) && sn.y < (1u << sn.level) && (st != 0 || sn.level == 0) && an.x < (1u << an.level) &&
              an.y < (1u << an.level) && (at != 0 || an.level == 0)))
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: key is not a basis function", j);
        if (g->kcol_start[j + 1] < g->kcol_start[j])
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: start not monotone", j);
    }
    for (uint64_t e = 0; e < g->knnz && !g->k_codes; e++) /* the compact form's rows: the reader's */
        if (g->krows[e] >= g->nfuncs)
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: entry %llu: row %u outside the %u functions",
                            (unsigned long long)e, g->krows[e], g->nfuncs);
    return WRT_OK;
}

/* K's transpose: row f's entries are te[ts[f] .. ts[f + 1]), columns ascending. K's
 * entries are krows, kvals (the file's floats, or the compact section decoded). */
static void k_transpose(const wrt_gto *g, const uint32_t *krows, const float *kvals, uint32_t *ts, kt_entry *te) {
    uint32_t nf = g->nfuncs;
    for (uint64_t e = 0; e < g->knnz; e++) ts[krows[e] + 1]++;
    for (uint32_t f = 0; f < nf; f++) ts[f + 1] += ts[f];
    for (uint32_t j = 0; j < g->nkcols; j++)
        for (uint64_t e = g->kcol_start[j]; e < g->kcol_start[j + 1]; e++) {
            uint32_t p = ts[krows[e]]++;
            te[p].col = j;
            te[p].val = kvals[e];
        }
    for (uint32_t f = nf; f > 0; f--) ts[f] = ts[f - 1];
    ts[0] = 0;
}

/* The fours (2 to 4 consecutive rows of one quad and spatial node: a glossy receiver's
 * incident angular functions, or a node's three wavelets, with the root's node its root
 * function) into r->k.k4_row/k4_n/k4_start, and their union's size (a merge of ascending
 * lists); in4[f] = 1 for each row in a four. Returns the entries of the unions. */
static uint64_t k_find_fours(wrt_relight *r, const uint32_t *ts, const kt_entry *te, uint8_t *in4) {
    const wrt_gto *g = r->g;
    uint32_t nf = g->nfuncs;
    uint64_t n4 = 0;
    for (uint32_t f = 0; f < nf;) {
        uint32_t n = 1;
        while (n < 4 && f + n < nf && (g->fkeys[f + n] >> 18) == (g->fkeys[f] >> 18)) n++;
        if (n < 2) { f++; continue; }
        r->k.k4_row[r->k.nk4] = f;
        r->k.k4_n[r->k.nk4] = (uint8_t)n;
        uint32_t p[4];
        for (uint32_t k = 0; k < n; k++) p[k] = ts[f + k];
        for (;;) {
            uint32_t m = UINT32_MAX;
            for (uint32_t k = 0; k < n; k++) if (p[k] < ts[f + k + 1] && te[p[k]].col < m) m = te[p[k]].col;
            if (m == UINT32_MAX) break;
            for (uint32_t k = 0; k < n; k++) if (p[k] < ts[f + k + 1] && te[p[k]].col == m) p[k]++;
            n4++;
        }
        r->k.k4_start[++r->k.nk4] = (uint32_t)n4;
        for (uint32_t k = 0; k < n; k++) in4[f + k] = 1;
        f += n;
    }
    return n4;
}

/* Fills the rows one by one (those in no four: r->k.kt) and the fours' unions (r->k.k4_cols,
 * 4 values each in r->k.k4_vals). */
static void k_fill(wrt_relight *r, const uint32_t *ts, const kt_entry *te, const uint8_t *in4) {
    uint32_t nf = r->g->nfuncs;
    uint64_t q1 = 0;
    for (uint32_t f = 0; f < nf; f++) {
        r->k.kt_start[f] = (uint32_t)q1;
        if (in4[f]) continue;
        for (uint32_t e = ts[f]; e < ts[f + 1]; e++) r->k.kt[q1++] = te[e];
    }
    r->k.kt_start[nf] = (uint32_t)q1;
    for (uint32_t i = 0; i < r->k.nk4; i++) {
        uint32_t f = r->k.k4_row[i], n = r->k.k4_n[i], p[4], b = r->k.k4_start[i];
        for (uint32_t k = 0; k < n; k++) p[k] = ts[f + k];
        for (;; b++) {
            uint32_t m = UINT32_MAX;
            for (uint32_t k = 0; k < n; k++) if (p[k] < ts[f + k + 1] && te[p[k]].col < m) m = te[p[k]].col;
            if (m == UINT32_MAX) break;
            r->k.k4_cols[b] = m;
            for (uint32_t k = 0; k < 4; k++)
                r->k.k4_vals[(size_t)b * 4 + k] = k < n && p[k] < ts[f + k + 1] && te[p[k]].col == m ? te[p[k]++].val : 0;
        }
    }
}

/* A half-precision float (IEEE 754 binary16) from a float of magnitude below 65520,
 * rounded to nearest even, and back (exact). */
static uint16_t half_of(float f) {
    double a = fabs((double)f);
    uint16_t sign = signbit(f) ? 0x8000u : 0;
    if (a < ldexp(1.0, -14)) return (uint16_t)(sign | (uint16_t)rint(ldexp(a, 24))); /* subnormal (or 1024: the least normal) */
    int e;
    double m = frexp(a, &e); /* a = m 2^e, m in [0.5, 1) */
    double q = rint(ldexp(m, 11)); /* 1024..2048: the significand */
    if (q == 2048) { q = 1024; e++; }
    return (uint16_t)(sign | (uint16_t)((e + 14) << 10) | (uint16_t)(q - 1024));
}

static float half_value(uint16_t h) {
    int e = (h >> 10) & 31, m = h & 1023;
    double v = e ? ldexp(1024 + m, e - 25) : ldexp(m, -24);
    return (float)(h & 0x8000u ? -v : v);
}

/* The fours' values as halves: each four's scaled by 2^-k4_exp[i] so that its largest
 * lies in [2^14, 2^15) (K's values are far below half precision's least normal, 2^-14),
 * then rounded to half precision (11 significant bits, the file's compact K has 14):
 * with F16C the multiply reads 8 bytes an entry's values instead of 16, and converts them
 * in one instruction; without, k4_vals holds the same halves as floats (the same sums). */
static void k_halves(wrt_relight *r, uint64_t n4) {
    for (uint32_t i = 0; i < r->k.nk4; i++) {
        uint32_t b0 = r->k.k4_start[i], b1 = r->k.k4_start[i + 1];
        float mx = 0;
        for (size_t k = (size_t)b0 * 4; k < (size_t)b1 * 4; k++) mx = fmaxf(mx, fabsf(r->k.k4_vals[k]));
        int e = 0;
        if (mx > 0) frexp(mx, &e);
        int sx = e - 15;
        sx = sx < -126 ? -126 : sx > 127 ? 127 : sx; /* 2^sx a normal float */
        r->k.k4_exp[i] = (int16_t)sx;
        for (size_t k = (size_t)b0 * 4; k < (size_t)b1 * 4; k++) {
            uint16_t h = half_of((float)ldexp(r->k.k4_vals[k], -sx));
            if (r->k.f16c) r->k.k4_h[k] = h;
            else r->k.k4_vals[k] = half_value(h);
        }
    }
    if (r->k.f16c) { relight_free(r, r->k.k4_vals); r->k.k4_vals = NULL; }
    (void)n4;
}

/* K by rows: Y = K c sums each row in registers, in column order (no store per entry).
 * Two to four consecutive rows of one quad and spatial node (a glossy receiver's
 * incident angular functions; a node's wavelets) have nearly the same columns (97% on
 * the glossy asset, where the fours of glossy receivers hold 87% of K's entries): their
 * union is stored once with 4 values an entry, one load of c serving the rows. Y on the
 * glossy asset's 1.5 M entries, one thread: the columns' scatter 1.1 ms, rows one by
 * one 0.87 ms, fours 0.58 ms, with AVX 0.45 ms, with the nodes' wavelets too 0.42 ms.
 * WRT_ERR_NOMEM. */
static wrt_status k_by_rows(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nf = g->nfuncs;
    uint32_t *ts = relight_calloc(r, (size_t)nf + 1, sizeof(uint32_t));
    kt_entry *te = relight_calloc(r, (size_t)g->knnz + 1, sizeof(kt_entry));
    r->k.kt_start = relight_calloc(r, (size_t)nf + 1, sizeof(uint32_t));
    r->k.k4_row = relight_calloc(r, (size_t)nf / 2 + 1, sizeof(uint32_t));
    r->k.k4_start = relight_calloc(r, (size_t)nf / 2 + 2, sizeof(uint32_t));
    r->k.k4_n = relight_calloc(r, (size_t)nf / 2 + 1, 1);
    uint8_t *in4 = relight_calloc(r, (size_t)nf + 1, 1);
    /* the compact K (section kcode) decoded once here; the float K used in place */
    uint32_t *drows = g->k_codes ? relight_calloc(r, (size_t)g->knnz + 1, sizeof(uint32_t)) : NULL;
    float *dvals = g->k_codes ? relight_calloc(r, (size_t)g->knnz + 1, sizeof(float)) : NULL;
    wrt_status st = WRT_OK;
    if (r->oom) goto done;
    if (g->k_codes) wrt_gto_k_entries(g, drows, dvals);
    k_transpose(g, g->k_codes ? drows : g->krows, g->k_codes ? dvals : g->kvals, ts, te);
    uint64_t n4 = k_find_fours(r, ts, te, in4), n1 = 0;
    for (uint32_t f = 0; f < nf; f++) if (!in4[f]) n1 += ts[f + 1] - ts[f];
    r->k.kt = relight_calloc(r, (size_t)n1 + 1, sizeof(kt_entry));
    r->k.k4_cols = relight_calloc(r, (size_t)n4 + 1, sizeof(uint32_t));
    r->k.k4_vals = relight_calloc(r, (size_t)n4 * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    r->k.k4_exp = relight_calloc(r, (size_t)r->k.nk4 + 1, sizeof(int16_t));
    if (r->k.f16c) r->k.k4_h = relight_calloc(r, (size_t)n4 * 4 + 8, sizeof(uint16_t));
    if (r->oom) goto done;
    k_fill(r, ts, te, in4);
    k_halves(r, n4);
    if (g->nkcols <= 65536) { /* the columns in 16 bits: 10 bytes a union entry instead of 12 */
        r->k.k4_c16 = relight_calloc(r, (size_t)n4 + 1, sizeof(uint16_t));
        if (r->oom) goto done;
        for (uint64_t b = 0; b < n4; b++) r->k.k4_c16[b] = (uint16_t)r->k.k4_cols[b];
        relight_free(r, r->k.k4_cols);
        r->k.k4_cols = NULL;
    }
done:
    if (r->oom) st = wrt_fail(WRT_ERR_NOMEM, "relight: out of memory");
    relight_free(r, ts); relight_free(r, te); relight_free(r, in4); relight_free(r, drows); relight_free(r, dvals);
    return st;
}

/* Per column its spatial level and pyramid slot and its angular index; per quad its range
 * of columns, deepest spatial level and the angular functions among them (the
 * projection's K slots). */
static void k_columns(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nk = g->nkcols;
    for (uint32_t j = 0; j < nk;) { /* keys ascend: each quad's columns are contiguous */
        uint32_t q = wrt_fkey_quad(g->kkeys[j]), j1 = j;
        quad_info *qi = &r->qi[q];
        qi->kfirst = j;
        for (; j1 < nk && wrt_fkey_quad(g->kkeys[j1]) == q; j1++) {
            wrt_fkey k = g->kkeys[j1];
            wrt_node sn = wrt_fkey_snode(k), an = wrt_fkey_anode(k);
            r->k.fn_slevel[j1] = sn.level;
            r->k.fn_spidx[j1] = haar_index(sn.level, sn.x, sn.y, wrt_fkey_stype(k));
            r->k.fn_ang[j1] = (uint8_t)haar_index(an.level, an.x, an.y, wrt_fkey_atype(k));
            if (sn.level > qi->kslevel) qi->kslevel = sn.level;
            if (r->k.fn_ang[j1] + 1 > qi->nkang) qi->nkang = r->k.fn_ang[j1] + 1;
        }
        qi->kcount = j1 - j;
        j = j1;
    }
}

/* The first-bounce operator K (g->nkcols > 0): checks, then lays out K by rows and per
 * column and quad. K's angular levels are < 4 (2 bits in a key), all in the BRDF table
 * (levels 0..3). WRT_ERR_CORRUPT naming the column, WRT_ERR_NOMEM. */
_Static_assert(WRT_BRDF_TABLE_LEVELS >= 4 && NANG == WRT_BRDF_TABLE_NANG,
               "a key's angular node level (2 bits, 0..3) must be in the BRDF table: L_K <= 4 is covered");
wrt_status relight_setup_first_bounce(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nk = g->nkcols;
    wrt_status st = k_check(r);
    if (st != WRT_OK) return st;
    r->k.fn_slevel = relight_calloc(r, nk, 1);
    r->k.fn_ang = relight_calloc(r, nk, 1);
    r->k.fn_spidx = relight_calloc(r, nk, sizeof(uint32_t));
    r->k.C = relight_calloc(r, (size_t)nk * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    r->k.Y = relight_calloc(r, (size_t)g->nfuncs * 3 + 1, sizeof(float));
    r->k.Ep = relight_calloc(r, (size_t)g->nfuncs * 3 + 1, sizeof(float));
    r->k.Y4 = relight_calloc(r, (size_t)g->nfuncs * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
#ifdef WRT_K_AVX
    __builtin_cpu_init();
    r->k.avx = __builtin_cpu_supports("avx") && !r->opt.no_avx; /* no_avx: tests, A/B */
    r->k.f16c = r->k.avx && __builtin_cpu_supports("f16c");
#endif
    if (g->knnz > UINT32_MAX) return wrt_fail(WRT_ERR_NOMEM, "relight: first-bounce operator of %llu entries: too large",
                                              (unsigned long long)g->knnz);
    if ((st = k_by_rows(r)) != WRT_OK) return st;
    k_columns(r);
    return WRT_OK;
}

/* 2^e, a normal float (e in -126..127). */
static inline float k_scale(int e) {
    union { uint32_t u; float f; } v;
    v.u = (uint32_t)(e + 127) << 23;
    return v.f;
}

/* A union entry's column (k4_c16 or k4_cols). */
#define K_COL(c16_, c32_, b_) ((size_t)((c16_) ? (c16_)[b_] : (c32_)[b_]))

/* Y = K c on the rows in fours (K by rows, r->k.k4_*): one load of c serves four rows. Each
 * row sums its entries in four partial sums (entry k of the four's union into sum k mod 4),
 * folded as (s0 + s1) + (s2 + s3): the same operations, in the same order, as the AVX
 * version below, which runs entries 4j and 4j + 1 side by side in one register and 4j + 2,
 * 4j + 3 in another (so Y is the same to the bit with or without AVX). Four sums rather
 * than two: the adds' latency, not the loads, bound the loop with two. */
static void k_fours(wrt_relight *r) {
    const float *C = r->k.C, *kv = r->k.k4_vals;
    const uint32_t *kc = r->k.k4_cols;
    const uint16_t *kc16 = r->k.k4_c16;
    for (uint32_t i = 0; i < r->k.nk4; i++) {
        float *y = r->k.Y4 + (size_t)r->k.k4_row[i] * 4;
        uint32_t b = r->k.k4_start[i], end = r->k.k4_start[i + 1], b0 = b;
#ifdef __SSE2__
        __m128 a[4][4]; /* [partial sum][row] */
        for (int p = 0; p < 4; p++) for (int k = 0; k < 4; k++) a[p][k] = _mm_setzero_ps();
#define K_FOUR(p_, bb) do { \
            __m128 cv_ = _mm_load_ps(C + K_COL(kc16, kc, bb) * 4), v_ = _mm_load_ps(kv + (size_t)(bb) * 4); \
            a[p_][0] = _mm_add_ps(a[p_][0], _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0x00))); \
            a[p_][1] = _mm_add_ps(a[p_][1], _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0x55))); \
            a[p_][2] = _mm_add_ps(a[p_][2], _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0xAA))); \
            a[p_][3] = _mm_add_ps(a[p_][3], _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0xFF))); } while (0)
        for (; b < end; b++) K_FOUR((b - b0) & 3, b);
#undef K_FOUR
        int n = r->k.k4_n[i]; /* 2 to 4 rows: the next group's rows follow */
        __m128 sc = _mm_set1_ps(k_scale(r->k.k4_exp[i]));
        for (int k = 0; k < n; k++)
            _mm_store_ps(y + 4 * k, _mm_mul_ps(_mm_add_ps(_mm_add_ps(a[0][k], a[1][k]), _mm_add_ps(a[2][k], a[3][k])), sc));
#else
        float a[4][4][3] = {{{0}}}, sc = k_scale(r->k.k4_exp[i]);
        for (; b < end; b++)
            for (int k = 0; k < 4; k++)
                for (int c = 0; c < 3; c++) a[(b - b0) & 3][k][c] += C[K_COL(kc16, kc, b) * 4 + c] * kv[(size_t)b * 4 + k];
        for (int k = 0; k < r->k.k4_n[i]; k++)
            for (int c = 0; c < 3; c++) y[k * 4 + c] = ((a[0][k][c] + a[1][k][c]) + (a[2][k][c] + a[3][k][c])) * sc;
#endif
    }
}

#ifdef WRT_K_AVX
/* The AVX loop with the values as halves (F16C): the same products of the same values in
 * the same order as k_fours over k4_vals' floats. c16: the columns are k4_c16's (a
 * constant in each caller below, so each gets its own loop). */
__attribute__((target("avx,f16c"), always_inline)) static inline void k_fours_avx_in(wrt_relight *r, int c16) {
    const float *C = r->k.C;
    const uint16_t *kh = r->k.k4_h;
    const uint32_t *kc = r->k.k4_cols;
    const uint16_t *kc16 = r->k.k4_c16;
#define KC(b_) ((size_t)(c16 ? kc16[b_] : kc[b_]))
    for (uint32_t i = 0; i < r->k.nk4; i++) {
        float *y = r->k.Y4 + (size_t)r->k.k4_row[i] * 4;
        uint32_t b = r->k.k4_start[i], end = r->k.k4_start[i + 1];
        /* a: partial sums 0 (low half) and 1 (high); d: 2 and 3 */
        __m256 a0 = _mm256_setzero_ps(), a1 = a0, a2 = a0, a3 = a0, d0 = a0, d1 = a0, d2 = a0, d3 = a0;
#define K_PAIR(s0_, s1_, s2_, s3_, bb_) do { \
            __m256 cv_ = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(C + KC(bb_) * 4)), \
                                              _mm_load_ps(C + KC((bb_) + 1) * 4), 1); \
            __m256 v_ = _mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(kh + (size_t)(bb_) * 4))); \
            s0_ = _mm256_add_ps(s0_, _mm256_mul_ps(cv_, _mm256_permute_ps(v_, 0x00))); \
            s1_ = _mm256_add_ps(s1_, _mm256_mul_ps(cv_, _mm256_permute_ps(v_, 0x55))); \
            s2_ = _mm256_add_ps(s2_, _mm256_mul_ps(cv_, _mm256_permute_ps(v_, 0xAA))); \
            s3_ = _mm256_add_ps(s3_, _mm256_mul_ps(cv_, _mm256_permute_ps(v_, 0xFF))); } while (0)
        for (; b + 4 <= end; b += 4) {
            K_PAIR(a0, a1, a2, a3, b);
            K_PAIR(d0, d1, d2, d3, b + 2);
        }
        if (b + 2 <= end) { K_PAIR(a0, a1, a2, a3, b); b += 2; }
#undef K_PAIR
        __m128 p[4][4] = {{_mm256_castps256_ps128(a0), _mm256_castps256_ps128(a1), _mm256_castps256_ps128(a2), _mm256_castps256_ps128(a3)},
                          {_mm256_extractf128_ps(a0, 1), _mm256_extractf128_ps(a1, 1), _mm256_extractf128_ps(a2, 1), _mm256_extractf128_ps(a3, 1)},
                          {_mm256_castps256_ps128(d0), _mm256_castps256_ps128(d1), _mm256_castps256_ps128(d2), _mm256_castps256_ps128(d3)},
                          {_mm256_extractf128_ps(d0, 1), _mm256_extractf128_ps(d1, 1), _mm256_extractf128_ps(d2, 1), _mm256_extractf128_ps(d3, 1)}};
        if (b < end) { /* a last entry: number 4j or 4j + 2 of the union (partial sum 0 or 2) */
            int ps = (int)((b - r->k.k4_start[i]) & 3);
            __m128 cv = _mm_load_ps(C + KC(b) * 4), v = _mm_cvtph_ps(_mm_loadl_epi64((const __m128i *)(kh + (size_t)b * 4)));
            p[ps][0] = _mm_add_ps(p[ps][0], _mm_mul_ps(cv, _mm_shuffle_ps(v, v, 0x00)));
            p[ps][1] = _mm_add_ps(p[ps][1], _mm_mul_ps(cv, _mm_shuffle_ps(v, v, 0x55)));
            p[ps][2] = _mm_add_ps(p[ps][2], _mm_mul_ps(cv, _mm_shuffle_ps(v, v, 0xAA)));
            p[ps][3] = _mm_add_ps(p[ps][3], _mm_mul_ps(cv, _mm_shuffle_ps(v, v, 0xFF)));
        }
        int n = r->k.k4_n[i]; /* 2 to 4 rows: the next group's rows follow */
        __m128 sc = _mm_set1_ps(k_scale(r->k.k4_exp[i]));
        for (int k = 0; k < n; k++)
            _mm_store_ps(y + 4 * k, _mm_mul_ps(_mm_add_ps(_mm_add_ps(p[0][k], p[1][k]), _mm_add_ps(p[2][k], p[3][k])), sc));
    }
#undef KC
}
__attribute__((target("avx,f16c"))) static void k_fours_avx(wrt_relight *r) {
    if (r->k.k4_c16) k_fours_avx_in(r, 1);
    else k_fours_avx_in(r, 0);
}
#endif

/* The first glossy bounce (K-SPEC): c = the sum over lights of their scaled projections
 * onto K's columns (cached per light, as E's), Y = K c (one channel K, RGB c; rows summed
 * in column order), and E' = E with every function of a quad that has K columns set to 0
 * (its direct light reaches the others through Y instead), plus Y. The multiply then
 * gives X = Op E' + Y. */
void relight_first_bounce(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nk = g->nkcols, nf = g->nfuncs;
    memset(r->k.C, 0, (size_t)nk * 4 * sizeof(float));
    for (int i = 0; i < r->nlights; i++) {
        const light_state *ls = &r->lights[i];
        if (ls->scale == 0 || !ls->have_proj) continue;
        for (size_t j = 0; j < nk; j++)
            for (int c = 0; c < 3; c++) r->k.C[j * 4 + c] += ls->scale * ls->kc[j * 3 + c];
    }
    const uint32_t *ks = r->k.kt_start;
    const kt_entry *kt = r->k.kt;
    const float *C = r->k.C;
    for (uint32_t f = 0; f < nf; f++) { /* Y = K c, row by row, two partial sums */
        uint32_t e = ks[f], end = ks[f + 1];
        float *y = r->k.Y4 + (size_t)f * 4;
#ifdef __SSE2__
        __m128 s0 = _mm_setzero_ps(), s1 = _mm_setzero_ps();
        for (; e + 2 <= end; e += 2) {
            s0 = _mm_add_ps(s0, _mm_mul_ps(_mm_load_ps(C + (size_t)kt[e].col * 4), _mm_set1_ps(kt[e].val)));
            s1 = _mm_add_ps(s1, _mm_mul_ps(_mm_load_ps(C + (size_t)kt[e + 1].col * 4), _mm_set1_ps(kt[e + 1].val)));
        }
        if (e < end) s0 = _mm_add_ps(s0, _mm_mul_ps(_mm_load_ps(C + (size_t)kt[e].col * 4), _mm_set1_ps(kt[e].val)));
        _mm_store_ps(y, _mm_add_ps(s0, s1));
#else
        float s0[3] = {0, 0, 0}, s1[3] = {0, 0, 0};
        for (; e + 2 <= end; e += 2)
            for (int c = 0; c < 3; c++) {
                s0[c] += C[(size_t)kt[e].col * 4 + c] * kt[e].val;
                s1[c] += C[(size_t)kt[e + 1].col * 4 + c] * kt[e + 1].val;
            }
        if (e < end) for (int c = 0; c < 3; c++) s0[c] += C[(size_t)kt[e].col * 4 + c] * kt[e].val;
        for (int c = 0; c < 3; c++) y[c] = s0[c] + s1[c];
#endif
    }
#ifdef WRT_K_AVX
    if (r->k.f16c) k_fours_avx(r);
    else
#endif
        k_fours(r);
    memcpy(r->k.Ep, r->E, (size_t)nf * 3 * sizeof(float));
    for (uint32_t q = 0; q < g->nquads; q++)
        if (r->qi[q].kcount)
            memset(r->k.Ep + (size_t)g->quads[q].func_first * 3, 0, (size_t)g->quads[q].func_count * 3 * sizeof(float));
    for (size_t f = 0; f < nf; f++)
        for (int c = 0; c < 3; c++) {
            r->k.Y[f * 3 + c] = r->k.Y4[f * 4 + c];
            r->k.Ep[f * 3 + c] += r->k.Y4[f * 4 + c];
        }
}
