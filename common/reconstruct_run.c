/* reconstruct_run.c: the smooth single-level reconstruction of each quad's indirect light
 * (reconstruct.h) over the adjacency reconstruct.c builds. */
#include "reconstruct.h"
#include "reconstruct_internal.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#ifdef __SSE4_1__
#include <smmintrin.h>
#endif

/* ------------------------------------------------------- reconstruction ---- */

/* Cell k (0 .. m-1, along the edge's direction) of edge e of an m x m grid. */
static size_t edge_cell(int e, int m, int k) {
    switch (e) {
    case 0: return (size_t)k;
    case 1: return (size_t)k * m + (m - 1);
    case 2: return (size_t)(m - 1) * m + k;
    default: return (size_t)k * m;
    }
}

/* The cell one step inside from edge cell k of edge e (m >= 3): not on any edge. */
static size_t inner_cell(int e, int m, int k) {
    switch (e) {
    case 0: return (size_t)m + k;
    case 1: return (size_t)k * m + (m - 2);
    case 2: return (size_t)(m - 2) * m + k;
    default: return (size_t)k * m + 1;
    }
}

/* The cell diagonally inside corner k (m >= 3). */
static size_t corner_inner(int k, int m) {
    return k == 0 ? (size_t)m + 1 : k == 1 ? (size_t)m + m - 2 : k == 2 ? (size_t)(m - 2) * m + m - 2 : (size_t)(m - 2) * m + 1;
}

static size_t corner_cell(int k, int m) {
    return k == 0 ? 0 : k == 1 ? (size_t)(m - 1) : k == 2 ? (size_t)m * m - 1 : (size_t)(m - 1) * m;
}

/* The argument of least magnitude if all three have one sign, else 0 (the MC limiter). */
static inline float minmod3(float a, float b, float c) {
    if (a > 0 && b > 0 && c > 0) { float m = a < b ? a : b; return m < c ? m : c; }
    if (a < 0 && b < 0 && c < 0) { float m = a > b ? a : b; return m > c ? m : c; }
    return 0;
}

/* How far the bake's four children of cell c (rows r0, r1, two cells each; parent
 * average par) lie from the limited prediction below, as a fraction of the larger of the
 * cell's average and the quad's mean (mean: the quad's level 0), both the largest over
 * the channels. The
 * children's own offsets are compared (each child minus the parent, the prediction's
 * minus its centre), so that a cell the coarser levels already moved is judged alike. */
/* fmaxf for the values here (never -0): the larger, or the one that is not NaN; inline
 * (the library's fmaxf is a call at -O2). */
static inline float max_nn(float a, float b) { return a != a ? b : (b > a ? b : a); }

#ifdef __SSE4_1__
static inline __m128 minmod3v(__m128 a, __m128 b, __m128 c);
/* details_missed for RGB at once (nc 3): each lane does the scalar code's operations in
 * its order; the maxima's order does not matter (max is exact, and NaN is ignored as
 * max_nn ignores it), so the result is the same float. The fourth lane is loaded and
 * masked out. */
static float details_missed3(const float *c, size_t ws, const float *par, const float *r0, const float *r1,
                             const float *mean) {
    const __m128 sign = _mm_set1_ps(-0.0f), lanes = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
    const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), q = _mm_set1_ps(0.25f);
    __m128 av = _mm_loadu_ps(c), E = _mm_loadu_ps(c + 3), W = _mm_loadu_ps(c - 3);
    __m128 N = _mm_loadu_ps(c + ws), S = _mm_loadu_ps(c - ws);
    __m128 dx = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, W)), _mm_mul_ps(half, _mm_sub_ps(E, W)),
                                    _mm_mul_ps(two, _mm_sub_ps(E, av))), q);
    __m128 dy = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, S)), _mm_mul_ps(half, _mm_sub_ps(N, S)),
                                    _mm_mul_ps(two, _mm_sub_ps(N, av))), q);
    __m128 ndx = _mm_xor_ps(dx, sign), p = _mm_loadu_ps(par);
    __m128 pred[4] = {_mm_sub_ps(ndx, dy), _mm_sub_ps(dx, dy), _mm_add_ps(ndx, dy), _mm_add_ps(dx, dy)};
    __m128 bake[4] = {_mm_sub_ps(_mm_loadu_ps(r0), p), _mm_sub_ps(_mm_loadu_ps(r0 + 3), p),
                      _mm_sub_ps(_mm_loadu_ps(r1), p), _mm_sub_ps(_mm_loadu_ps(r1 + 3), p)};
    __m128 d = _mm_setzero_ps();
    for (int t = 0; t < 4; t++) d = _mm_max_ps(_mm_andnot_ps(sign, _mm_sub_ps(bake[t], pred[t])), d);
    __m128 aa = _mm_andnot_ps(sign, av), am = _mm_andnot_ps(sign, _mm_loadu_ps(mean));
    __m128 sv = _mm_blendv_ps(_mm_max_ps(am, aa), am, _mm_cmpunord_ps(aa, aa)); /* max_nn(|av|, |mean|) */
    d = _mm_and_ps(d, lanes);
    sv = _mm_and_ps(_mm_max_ps(sv, _mm_setzero_ps()), lanes);
    d = _mm_max_ps(d, _mm_movehl_ps(d, d));
    d = _mm_max_ss(d, _mm_shuffle_ps(d, d, 1));
    sv = _mm_max_ps(sv, _mm_movehl_ps(sv, sv));
    sv = _mm_max_ss(sv, _mm_shuffle_ps(sv, sv, 1));
    float dmax = _mm_cvtss_f32(d), smax = _mm_cvtss_f32(sv);
    return smax > 0 ? dmax / smax : (dmax > 0 ? INFINITY : 0);
}
#endif

static float details_missed(const float *c, int nc, size_t ws, const float *par, const float *r0, const float *r1,
                            const float *mean) {
#ifdef __SSE4_1__
    if (nc == 3) return details_missed3(c, ws, par, r0, r1, mean);
#endif
    float dmax = 0, smax = 0;
    for (int ch = 0; ch < nc; ch++) {
        float av = c[ch], E = c[nc + ch], W = c[ch - nc], N = c[ws + ch], S = c[ch - ws];
        float dx = minmod3(2 * (av - W), 0.5f * (E - W), 2 * (E - av)) * 0.25f;
        float dy = minmod3(2 * (av - S), 0.5f * (N - S), 2 * (N - av)) * 0.25f;
        float pred[4] = {-dx - dy, dx - dy, -dx + dy, dx + dy};
        float bake[4] = {r0[ch] - par[ch], r0[nc + ch] - par[ch], r1[ch] - par[ch], r1[nc + ch] - par[ch]};
        for (int t = 0; t < 4; t++) dmax = max_nn(dmax, fabsf(bake[t] - pred[t]));
        smax = max_nn(smax, max_nn(fabsf(av), fabsf(mean[ch])));
    }
    return smax > 0 ? dmax / smax : (dmax > 0 ? INFINITY : 0);
}

/* Quad o's edge row (the m cells along its edge f, at the current level, in b) as a
 * function of the edge's parameter: each cell its average plus a slope across it (central;
 * one-sided in the end cells; none when m = 1; MC-limited when `limit`), which keeps every
 * cell's average. Its mean over [sa, sb] (0 <= sa < sb <= 1) in channel ch: over whole
 * cells their mean, inside one cell the value at the range's centre (the along-edge part
 * of the children's prediction). */
static double row_mean(const float *b, int f, int m, int nc, int ch, double sa, double sb, int limit) {
    int k0 = (int)floor(sa * m), k1 = (int)ceil(sb * m) - 1;
    if (k0 < 0) k0 = 0;
    if (k1 > m - 1) k1 = m - 1;
    double acc = 0;
    for (int k = k0; k <= k1; k++) {
        double lo = fmax(sa, (double)k / m), hi = fmin(sb, (double)(k + 1) / m);
        if (!(hi > lo)) continue;
        double av = b[edge_cell(f, m, k) * nc + ch], sl = 0;
        if (m > 1) {
            double W = k > 0 ? b[edge_cell(f, m, k - 1) * nc + ch] : 0, E = k < m - 1 ? b[edge_cell(f, m, k + 1) * nc + ch] : 0;
            if (k == 0) sl = E - av;
            else if (k == m - 1) sl = av - W;
            else sl = limit ? minmod3((float)(2 * (av - W)), (float)(0.5 * (E - W)), (float)(2 * (E - av))) : 0.5 * (E - W);
        }
        acc += (hi - lo) * (av + sl * (0.5 * (lo + hi) * m - (k + 0.5)));
    }
    return acc / (sb - sa);
}

/* Quad o's edge row at parameter s, channel ch: linear between the cells' centres, the end
 * cells' values beyond them (what a clamped bilinear lookup shows along the edge). */
static double row_point(const float *b, int f, int m, int nc, int ch, double s) {
    double x = s * m - 0.5;
    if (x <= 0) return b[edge_cell(f, m, 0) * nc + ch];
    if (x >= m - 1) return b[edge_cell(f, m, m - 1) * nc + ch];
    int k = (int)floor(x);
    double t = x - k;
    return (1 - t) * b[edge_cell(f, m, k) * nc + ch] + t * b[edge_cell(f, m, k + 1) * nc + ch];
}

/* The partial neighbours of quad q's edge e over [ta, tb] of it, channel ch: their edge
 * rows' means over the matching ranges (cur + slot * stride: a member's cells at the
 * current level m), weighted by the lengths they cover; *cov the covered fraction of
 * [ta, tb] (0: none, the value 0). */
static double partial_mean(const wrt_recon *rc, int q, int e, int m, int nc, int ch, double ta, double tb, int limit,
                           const float *cur, size_t stride, double *cov) {
    double acc = 0, c = 0;
    for (int k = rc->pfirst[4 * q + e]; k < rc->pfirst[4 * q + e + 1]; k++) {
        const part_nb *p = &rc->pnb[k];
        double lo = fmax(ta, p->t0), hi = fmin(tb, p->t1);
        if (!(hi > lo)) continue;
        double r = (p->s1 - p->s0) / (p->t1 - p->t0);
        double sa = p->s0 + (lo - p->t0) * r, sb = p->s0 + (hi - p->t0) * r;
        if (sa > sb) { double t = sa; sa = sb; sb = t; }
        sa = fmax(sa, 0);
        sb = fmin(sb, 1);
        if (!(sb > sa)) continue;
        acc += (hi - lo) * row_mean(cur + (size_t)rc->slot[p->o] * stride, p->f, m, nc, ch, sa, sb, limit);
        c += hi - lo;
    }
    *cov = c / (tb - ta);
    return c > 0 ? acc / c : 0;
}

size_t wrt_recon_scratch(const wrt_recon *rc, int gr, int L, int Lo, int nc) {
    int nm;
    wrt_recon_members(rc, gr, &nm);
    size_t pyr_n = (((size_t)1 << (2 * (L + 1))) - 1) / 3 * nc; /* levels 0..L */
    size_t full = ((size_t)1 << (2 * Lo)) * nc;
    size_t ext_n = (((size_t)1 << Lo) + 2) * (((size_t)1 << Lo) + 2) * nc;
    size_t blend_n = rc->gnv && gr >= 0 && gr < rc->ngroups ? (size_t)rc->gnv[gr] * (nc + 1) + (size_t)nm * 4 * nc : 0;
    return (size_t)nm * (pyr_n + 2 * full) + (ext_n > blend_n ? ext_n : blend_n) + 4; /* + 4: the RGB loads' fourth lane */
}

int wrt_recon_run(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                  const uint8_t *const *known, float *const *out, const wrt_recon_params *prm) {
    int nm;
    wrt_recon_members(rc, gr, &nm);
    if (nm == 0) return 0;
    float *buf = rc_alloc(&rc->al, wrt_recon_scratch(rc, gr, L, Lo, nc) * sizeof(float));
    if (!buf) return -1;
    wrt_recon_run_in(rc, gr, L, Lo, nc, in, known, out, prm, buf);
    rc_free(&rc->al, buf);
    return 0;
}

#define CUR(s) (buf + (size_t)nm * pyr_n + (size_t)(s) * 2 * full + (size_t)cur_half * full)
#define NXT(s) (buf + (size_t)nm * pyr_n + (size_t)(s) * 2 * full + (size_t)(1 - cur_half) * full)

/* Stage 1: pyramids of the input: level l at offset (4^l - 1)/3 cells. */
static void recon_pyramids(int nm, const int *mem, int L, int nc, const float *const *in, float *buf, size_t pyr_n) {
    for (int s = 0; s < nm; s++) {
        float *pyr = buf + (size_t)s * pyr_n;
        size_t offL = (((size_t)1 << (2 * L)) - 1) / 3 * nc;
        memcpy(pyr + offL, in[mem[s]], ((size_t)1 << (2 * L)) * nc * sizeof(float));
        for (int l = L - 1; l >= 0; l--) {
            int m = 1 << l;
            float *p = pyr + (((size_t)1 << (2 * l)) - 1) / 3 * nc, *c = pyr + (((size_t)1 << (2 * (l + 1))) - 1) / 3 * nc;
#ifdef __SSE4_1__
            if (nc == 3) { /* RGB at once, the same sums in the same order (4th lane not stored) */
                const __m128 q = _mm_set1_ps(0.25f);
                size_t r = (size_t)2 * m * 3;
                for (int j = 0; j < m; j++)
                    for (int i = 0; i < m; i++) {
                        const float *c0 = c + ((size_t)(2 * j) * 2 * m + 2 * i) * 3;
                        __m128 v = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_loadu_ps(c0), _mm_loadu_ps(c0 + 3)),
                                                         _mm_loadu_ps(c0 + r)), _mm_loadu_ps(c0 + r + 3));
                        float *o = p + ((size_t)j * m + i) * 3;
                        __m128 pv = _mm_mul_ps(q, v);
                        _mm_storel_pi((__m64 *)o, pv);
                        _mm_store_ss(o + 2, _mm_movehl_ps(pv, pv));
                    }
                continue;
            }
#endif
            for (int j = 0; j < m; j++)
                for (int i = 0; i < m; i++)
                    for (int ch = 0; ch < nc; ch++) {
                        size_t c0 = ((size_t)(2 * j) * 2 * m + 2 * i) * nc + ch, r = (size_t)2 * m * nc;
                        p[((size_t)j * m + i) * nc + ch] = 0.25f * (c[c0] + c[c0 + nc] + c[c0 + r] + c[c0 + r + nc]);
                    }
        }
    }
}

/* Stage 2, per quad and level: the extended grid of quad q (own cells, ghosts, corners). */
static void recon_extend(const wrt_recon *rc, int q, int m, int w, int nc, const float *a, float *ext,
                         float *buf, int nm, size_t pyr_n, size_t full, int cur_half, int limit) {
    /* The extended grid: own cells, ghost rows from the neighbours or extrapolated. */
    for (int j = 0; j < m; j++)
        memcpy(ext + ((size_t)(j + 1) * w + 1) * nc, a + (size_t)j * m * nc, (size_t)m * nc * sizeof(float));
    for (int e = 0; e < 4; e++) {
        int o = rc->nb[q][e];
        const float *b = o >= 0 ? CUR(rc->slot[o]) : NULL;
        int part = o < 0 && rc->pfirst[4 * q + e] < rc->pfirst[4 * q + e + 1];
        for (int k = 0; k < m; k++) {
            size_t gi; /* ghost position in ext, and the inner cells beside it */
            size_t in0 = edge_cell(e, m, k), in1;
            switch (e) {
            case 0: gi = (size_t)k + 1; in1 = in0 + m; break;
            case 1: gi = (size_t)(k + 1) * w + m + 1; in1 = in0 - 1; break;
            case 2: gi = (size_t)(m + 1) * w + k + 1; in1 = in0 - m; break;
            default: gi = (size_t)(k + 1) * w; in1 = in0 + 1; break;
            }
            float *g = ext + gi * nc;
            double cov = 0;
            if (part) /* a T-junction: the neighbours' cells over the same stretch of the edge */
                for (int ch = 0; ch < nc && (ch == 0 || cov >= 0.5); ch++)
                    g[ch] = (float)partial_mean(rc, q, e, m, nc, ch, (double)k / m, (double)(k + 1) / m, limit,
                                                CUR(0), 2 * full, &cov);
            if (b) {
                const float *src = b + edge_cell(rc->nbe[q][e], m, rc->flip[q][e] ? m - 1 - k : k) * nc;
                memcpy(g, src, nc * sizeof(float));
            } else if (cov >= 0.5) {
                continue;
            } else if (m >= 2) {
                for (int ch = 0; ch < nc; ch++) g[ch] = 2 * a[in0 * nc + ch] - a[in1 * nc + ch];
            } else {
                memcpy(g, a + in0 * nc, nc * sizeof(float));
            }
        }
    }
    /* Corners of the extended grid: bilinear extrapolation from the ghosts. */
    static const int cx[4] = {0, 1, 1, 0}, cy[4] = {0, 0, 1, 1};
    for (int k = 0; k < 4; k++) {
        int gx = cx[k] ? m + 1 : 0, gy = cy[k] ? m + 1 : 0, ix = cx[k] ? m : 1, iy = cy[k] ? m : 1;
        float *g = ext + ((size_t)gy * w + gx) * nc;
        const float *eu = ext + ((size_t)iy * w + gx) * nc, *ev = ext + ((size_t)gy * w + ix) * nc,
                    *ai = ext + ((size_t)iy * w + ix) * nc;
        for (int ch = 0; ch < nc; ch++) g[ch] = eu[ch] + ev[ch] - ai[ch];
    }
}

#ifdef __SSE4_1__
/* Three channels in one SSE register: the fourth lane is loaded (the next value, or the
 * scratch's padding) and never stored. Every lane does the scalar code's operations in
 * its order (no FMA at -march=x86-64-v2), so the texels are the same bits. */
static inline void st3(float *p, __m128 v) {
    _mm_storel_pi((__m64 *)p, v);
    _mm_store_ss(p + 2, _mm_movehl_ps(v, v));
}

/* minmod3 lane by lane: MINPS and MAXPS are the scalar ?: (a < b ? a : b, a > b ? a : b). */
static inline __m128 minmod3v(__m128 a, __m128 b, __m128 c) {
    __m128 z = _mm_setzero_ps();
    __m128 pos = _mm_and_ps(_mm_and_ps(_mm_cmpgt_ps(a, z), _mm_cmpgt_ps(b, z)), _mm_cmpgt_ps(c, z));
    __m128 neg = _mm_and_ps(_mm_and_ps(_mm_cmplt_ps(a, z), _mm_cmplt_ps(b, z)), _mm_cmplt_ps(c, z));
    __m128 mn = _mm_min_ps(_mm_min_ps(a, b), c), mx = _mm_max_ps(_mm_max_ps(a, b), c);
    return _mm_or_ps(_mm_and_ps(pos, mn), _mm_and_ps(neg, mx));
}

/* The smooth prediction of recon_children for one cell, RGB at once. */
static inline void children3(const float *c, size_t ws, int limit, float *o0, float *o1) {
    const __m128 av = _mm_loadu_ps(c), E = _mm_loadu_ps(c + 3), W = _mm_loadu_ps(c - 3);
    const __m128 N = _mm_loadu_ps(c + ws), S = _mm_loadu_ps(c - ws);
    __m128 dx = _mm_mul_ps(_mm_sub_ps(E, W), _mm_set1_ps(0.125f));
    __m128 dy = _mm_mul_ps(_mm_sub_ps(N, S), _mm_set1_ps(0.125f));
    __m128 dxy = _mm_add_ps(_mm_sub_ps(_mm_sub_ps(_mm_loadu_ps(c + ws + 3), _mm_loadu_ps(c + ws - 3)),
                                       _mm_loadu_ps(c + 3 - ws)), _mm_loadu_ps(c - 3 - ws));
    dxy = _mm_mul_ps(dxy, _mm_set1_ps(1.0f / 64));
    if (limit) {
        const __m128 two = _mm_set1_ps(2.0f), half = _mm_set1_ps(0.5f), q = _mm_set1_ps(0.25f);
        __m128 lx = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, W)), _mm_mul_ps(half, _mm_sub_ps(E, W)),
                                        _mm_mul_ps(two, _mm_sub_ps(E, av))), q);
        __m128 ly = _mm_mul_ps(minmod3v(_mm_mul_ps(two, _mm_sub_ps(av, S)), _mm_mul_ps(half, _mm_sub_ps(N, S)),
                                        _mm_mul_ps(two, _mm_sub_ps(N, av))), q);
        dxy = _mm_andnot_ps(_mm_or_ps(_mm_cmpneq_ps(lx, dx), _mm_cmpneq_ps(ly, dy)), dxy);
        dx = lx;
        dy = ly;
    }
    __m128 am = _mm_sub_ps(av, dx), ap = _mm_add_ps(av, dx);
    st3(o0, _mm_add_ps(_mm_sub_ps(am, dy), dxy));
    st3(o0 + 3, _mm_sub_ps(_mm_sub_ps(ap, dy), dxy));
    st3(o1, _mm_sub_ps(_mm_add_ps(am, dy), dxy));
    st3(o1 + 3, _mm_add_ps(_mm_add_ps(ap, dy), dxy));
}
#endif

/* Stage 3, per quad and level: quad s's children at level l + 1 from its extended grid. */
static void recon_children(int s, int q, int l, int L, int m, int w, int nc, const float *ext, float *nx,
                           const uint8_t *const *known, const float *buf, size_t pyr_n, int keep, float sharp,
                           int limit) {
    /* Children: two output rows per input row. */
    const float *pyr = buf + (size_t)s * pyr_n;
    const float *pl = l < L ? pyr + (((size_t)1 << (2 * l)) - 1) / 3 * nc : NULL;
    const float *pc = l < L ? pyr + (((size_t)1 << (2 * (l + 1))) - 1) / 3 * nc : NULL;
    const uint8_t *kn = l < L && known && known[q] ? known[q] + wrt_recon_node(l, 0, 0) : NULL;
    int m2 = 2 * m, all_known = l < L && !kn;
    size_t rs = (size_t)m2 * nc, ws = (size_t)w * nc; /* output and ext row strides */
    for (int j = 0; j < m; j++) {
        const float *rowc = ext + ((size_t)(j + 1) * w + 1) * nc;
        float *o0 = nx + (size_t)(2 * j) * rs, *o1 = o0 + rs;
        const float *p0 = pc ? pc + (size_t)(2 * j) * rs : NULL, *p1 = p0 ? p0 + rs : NULL;
        for (int i = 0; i < m; i++) {
            const float *c = rowc + (size_t)i * nc;
            size_t x0 = (size_t)(2 * i) * nc, x1 = x0 + nc;
            int is_known = all_known || (kn && kn[(size_t)j * m + i]);
            if (is_known && l >= keep) /* past `keep`: only the details the prediction misses */
                is_known = sharp > 0 && details_missed(c, nc, ws, pl + ((size_t)j * m + i) * nc, p0 + x0, p1 + x0, pyr) > sharp;
#ifdef __SSE4_1__
            if (nc == 3) {
                if (!is_known) { children3(c, ws, limit, o0 + x0, o1 + x0); continue; }
                __m128 dv = _mm_sub_ps(_mm_loadu_ps(c), _mm_loadu_ps(pl + ((size_t)j * m + i) * 3));
                st3(o0 + x0, _mm_add_ps(_mm_loadu_ps(p0 + x0), dv));
                st3(o0 + x1, _mm_add_ps(_mm_loadu_ps(p0 + x1), dv));
                st3(o1 + x0, _mm_add_ps(_mm_loadu_ps(p1 + x0), dv));
                st3(o1 + x1, _mm_add_ps(_mm_loadu_ps(p1 + x1), dv));
                continue;
            }
#endif
            if (is_known) {
                for (int ch = 0; ch < nc; ch++) {
                    float dv = c[ch] - pl[((size_t)j * m + i) * nc + ch];
                    o0[x0 + ch] = p0[x0 + ch] + dv;
                    o0[x1 + ch] = p0[x1 + ch] + dv;
                    o1[x0 + ch] = p1[x0 + ch] + dv;
                    o1[x1 + ch] = p1[x1 + ch] + dv;
                }
                continue;
            }
            for (int ch = 0; ch < nc; ch++) {
                float av = c[ch], E = c[nc + ch], W = c[ch - nc], N = c[ws + ch], S = c[ch - ws];
                float dx = (E - W) * 0.125f, dy = (N - S) * 0.125f;
                float dxy = (c[ws + nc + ch] - c[ws - nc + ch] - c[ch + nc - ws] + c[ch - nc - ws]) * (1.0f / 64);
                if (limit) { /* no new extremum: a dark cell beside a lit one stays dark */
                    float lx = minmod3(2 * (av - W), 0.5f * (E - W), 2 * (E - av)) * 0.25f;
                    float ly = minmod3(2 * (av - S), 0.5f * (N - S), 2 * (N - av)) * 0.25f;
                    if (lx != dx || ly != dy) dxy = 0;
                    dx = lx;
                    dy = ly;
                }
                o0[x0 + ch] = av - dx - dy + dxy;
                o0[x1 + ch] = av + dx - dy - dxy;
                o1[x0 + ch] = av - dx + dy - dxy;
                o1[x1 + ch] = av + dx + dy + dxy;
            }
        }
    }
}

/* 1 if quad q's edge e lies inside one longer edge of a partial neighbour (a triangle's
 * half-edge against a paired quad's whole edge): its display follows the longer edge's. */
static int edge_inside(const wrt_recon *rc, int q, int e) {
    int k = rc->pfirst[4 * q + e];
    if (rc->nb[q][e] >= 0 || rc->pfirst[4 * q + e + 1] != k + 1) return 0;
    const part_nb *p = &rc->pnb[k];
    return p->t0 == 0 && p->t1 == 1 && fabs(p->s1 - p->s0) < 1;
}

/* Stage 4: the output, with shared edges and corners averaged across the group. */
static void recon_output(const wrt_recon *rc, int nm, const int *mem, int Lo, int nc, float *const *out,
                         float *buf, size_t pyr_n, size_t full, int cur_half, int limit) {
    /* Output: shared-edge texels the mean of the two cells beside the edge, corner texels
     * the mean of the cells around the corner; everything else the finest averages. */
    int m = 1 << Lo;
    for (int s = 0; s < nm; s++) {
        int q = mem[s];
        const float *a = CUR(s);
        float *o = out[q];
        memcpy(o, a, full * sizeof(float));
        if (m < 2) continue;
        for (int e = 0; e < 4; e++) {
            int nbq = rc->nb[q][e];
            if (nbq < 0 && rc->pfirst[4 * q + e] < rc->pfirst[4 * q + e + 1] && !edge_inside(rc, q, e)) {
                /* a longer edge at a T-junction: the mean of its cells and the shorter
                 * edges' beside the same stretch */
                for (int k = 1; k < m - 1; k++) {
                    size_t mi = edge_cell(e, m, k) * nc, ii = inner_cell(e, m, k) * nc;
                    double cov;
                    for (int ch = 0; ch < nc; ch++) {
                        double v = partial_mean(rc, q, e, m, nc, ch, (double)k / m, (double)(k + 1) / m, limit, CUR(0),
                                                2 * full, &cov);
                        if (cov < 0.5) break;
                        o[mi + ch] = (float)(0.5 * (a[mi + ch] + v));
                        if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
                    }
                }
            }
            if (nbq < 0) continue;
            const float *b = CUR(rc->slot[nbq]);
            for (int k = 1; k < m - 1; k++) {
                size_t mi = edge_cell(e, m, k) * nc, ii = inner_cell(e, m, k) * nc;
                size_t bi = edge_cell(rc->nbe[q][e], m, rc->flip[q][e] ? m - 1 - k : k) * nc;
                for (int ch = 0; ch < nc; ch++) {
                    o[mi + ch] = 0.5f * (a[mi + ch] + b[bi + ch]);
                    if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
                }
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            if (cs->n < 2 || cs->nt) continue;
            size_t mi = corner_cell(k, m) * nc, ii = corner_inner(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                float sum = 0;
                for (int t = 0; t < cs->n; t++) sum += CUR(rc->slot[cs->quad[t]])[corner_cell(cs->corner[t], m) * nc + ch];
                o[mi + ch] = sum / (float)cs->n;
                if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
            }
        }
    }
    if (m < 2) return;
    /* Then the shorter edges at T-junctions show what the longer edge shows (its texels,
     * final now, read along it at each texel's position), and a T-junction's vertex its
     * value there: the texel centres of the two sides never line up, and the longer side's
     * display is the one both can show (a half-texel corner zone of each size, else). */
    for (int s = 0; s < nm; s++) {
        int q = mem[s];
        const float *a = CUR(s);
        float *o = out[q];
        for (int e = 0; e < 4; e++) {
            if (!edge_inside(rc, q, e)) continue;
            const part_nb *p = &rc->pnb[rc->pfirst[4 * q + e]];
            for (int k = 1; k < m - 1; k++) {
                size_t mi = edge_cell(e, m, k) * nc, ii = inner_cell(e, m, k) * nc;
                double sv = p->s0 + ((k + 0.5) / m) * (p->s1 - p->s0);
                for (int ch = 0; ch < nc; ch++) {
                    o[mi + ch] = (float)row_point(out[p->o], p->f, m, nc, ch, sv);
                    if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
                }
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            if (!cs->nt) continue;
            size_t mi = corner_cell(k, m) * nc, ii = corner_inner(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                double ts = 0;
                for (int t = 0; t < cs->nt; t++) ts += row_point(out[cs->tquad[t]], cs->tedge[t], m, nc, ch, cs->ts[t]);
                o[mi + ch] = (float)(ts / cs->nt);
                if (m >= 4) o[ii + ch] -= o[mi + ch] - a[mi + ch];
            }
        }
    }
}

/* The position of texel i of m along u or v for the vertex blend: the edge itself for the
 * edge texels (what a clamped bilinear lookup shows at the edge, so that both sides show
 * the same value there), the texel's centre inside. */
static double blend_pos(int i, int m) {
    return m == 1 ? 0.5 : i == 0 ? 0 : i == m - 1 ? 1 : (i + 0.5) / m;
}

/* Corner values cv (4 x nc) bilinearly at (u, v), channel ch. */
static float blend_at(const float *cv, int nc, int ch, double u, double v) {
    return (float)((1 - u) * (1 - v) * cv[ch] + u * (1 - v) * cv[nc + ch] + u * v * cv[2 * nc + ch] +
                   (1 - u) * v * cv[3 * nc + ch]);
}

/* 1 if quad q's edge e borders a quad that shows the vertex blend (a whole or a partial neighbour). */
static int edge_to_blend(const wrt_recon *rc, int q, int e) {
    if (rc->nb[q][e] >= 0) return rc->bshow[rc->nb[q][e]];
    for (int k = rc->pfirst[4 * q + e]; k < rc->pfirst[4 * q + e + 1]; k++)
        if (rc->bshow[rc->pnb[k].o]) return 1;
    return 0;
}

/* Stage 5, a group with a curved quad: the vertex blend. Each source vertex takes the
 * mean of the members' means around it, weighted by their interior angles there (the
 * weights of the mesh's vertex normals); a quad that shows the blend (bshow) shows that of
 * its source's vertex values (barycentric over a triangle, bilinear over a paired quad;
 * bilinear in the part's (u, v) is exact, the weights being affine in the position),
 * sampled at blend_pos, so that the two sides of a whole shared edge hold the same values.
 * A shorter edge inside a longer one (a T-junction) then shows the longer edge's display,
 * as in recon_output. Any other member's texels on an edge or corner it shares with a
 * blended quad show the blend of its own source there (the same values: the blend is
 * continuous); nothing is given back inside (no member's mean is kept: a facet's own
 * light is spread to its vertices). tmp: blend_n floats (wrt_recon_scratch). */
static void recon_blend(const wrt_recon *rc, int gr, int nm, const int *mem, int Lo, int nc, float *const *out,
                        const float *buf, size_t pyr_n, float *tmp) {
    static const float W3[4][3] = {{1, 0, 0}, {0.5f, 0.5f, 0}, {1.0f / 3, 1.0f / 3, 1.0f / 3}, {0.5f, 0, 0.5f}};
    int nv = rc->gnv[gr], m = 1 << Lo;
    float *vs = tmp, *vw = tmp + (size_t)nv * nc, *cv = vw + nv;
    memset(vs, 0, ((size_t)nv * (nc + 1)) * sizeof(float));
    for (int s = 0; s < nm; s++) { /* the means: level 0 of each member's pyramid */
        int q = mem[s];
        const float *mean = buf + (size_t)s * pyr_n;
        for (int i = 0; i < rc->bkind[q]; i++) {
            float w = rc->bw[q][i];
            if (!(w > 0)) continue;
            int v = rc->bvid[q][i];
            for (int ch = 0; ch < nc; ch++) vs[(size_t)v * nc + ch] += w * mean[ch];
            vw[v] += w;
        }
    }
    for (int s = 0; s < nm; s++) { /* each member's corner values */
        int q = mem[s], k3 = rc->bkind[q] == 3;
        const float *mean = buf + (size_t)s * pyr_n;
        float *c = cv + (size_t)s * 4 * nc;
        for (int k = 0; k < 4; k++)
            for (int ch = 0; ch < nc; ch++) {
                double acc = 0;
                for (int i = 0; i < rc->bkind[q]; i++) {
                    double wi = k3 ? W3[k][i] : (i == k);
                    if (wi == 0) continue;
                    int v = rc->bvid[q][i];
                    acc += wi * (vw[v] > 0 ? vs[(size_t)v * nc + ch] / vw[v] : mean[ch]);
                }
                c[k * nc + ch] = (float)acc;
            }
    }
    for (int s = 0; s < nm; s++) {
        int q = mem[s];
        const float *c = cv + (size_t)s * 4 * nc;
        float *o = out[q];
        if (rc->bshow[q]) {
            for (int j = 0; j < m; j++)
                for (int i = 0; i < m; i++)
                    for (int ch = 0; ch < nc; ch++)
                        o[((size_t)j * m + i) * nc + ch] = blend_at(c, nc, ch, blend_pos(i, m), blend_pos(j, m));
            continue;
        }
        if (m < 2) continue;
        for (int e = 0; e < 4; e++) {
            if (!edge_to_blend(rc, q, e)) continue;
            for (int k = 1; k < m - 1; k++) {
                double t = blend_pos(k, m), u = e == 1 ? 1 : e == 3 ? 0 : t, v = e == 0 ? 0 : e == 2 ? 1 : t;
                size_t mi = edge_cell(e, m, k) * nc;
                for (int ch = 0; ch < nc; ch++) o[mi + ch] = blend_at(c, nc, ch, u, v);
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            int touch = 0;
            for (int t = 0; t < cs->n; t++) touch |= rc->bshow[cs->quad[t]];
            for (int t = 0; t < cs->nt; t++) touch |= rc->bshow[cs->tquad[t]];
            if (!touch) continue;
            size_t mi = corner_cell(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) o[mi + ch] = c[k * nc + ch];
        }
    }
    if (m < 2) return;
    for (int s = 0; s < nm; s++) { /* T-junctions: the shorter edges show the longer one's display */
        int q = mem[s];
        float *o = out[q];
        if (!rc->bshow[q]) continue;
        for (int e = 0; e < 4; e++) {
            if (!edge_inside(rc, q, e)) continue;
            const part_nb *p = &rc->pnb[rc->pfirst[4 * q + e]];
            for (int k = 1; k < m - 1; k++) {
                size_t mi = edge_cell(e, m, k) * nc;
                double sv = p->s0 + ((k + 0.5) / m) * (p->s1 - p->s0);
                for (int ch = 0; ch < nc; ch++) o[mi + ch] = (float)row_point(out[p->o], p->f, m, nc, ch, sv);
            }
        }
        for (int k = 0; k < 4; k++) {
            const corner_set *cs = &rc->around[q][k];
            if (!cs->nt) continue;
            size_t mi = corner_cell(k, m) * nc;
            for (int ch = 0; ch < nc; ch++) {
                double ts = 0;
                for (int t = 0; t < cs->nt; t++) ts += row_point(out[cs->tquad[t]], cs->tedge[t], m, nc, ch, cs->ts[t]);
                o[mi + ch] = (float)(ts / cs->nt);
            }
        }
    }
}

/* Stages 2 to 5 for a group not wholly blended: the levels, the output, then the blend
 * where some member shows it. */
static void recon_levels(const wrt_recon *rc, int nm, const int *mem, int L, int Lo, int nc, const uint8_t *const *known,
                         float *const *out, float *buf, size_t pyr_n, size_t full, int keep, float sharp, int limit,
                         int facets, int blend, int gr) {
    float *ext = buf + (size_t)nm * (pyr_n + 2 * full);
    int cur_half = 0;
    for (int s = 0; s < nm; s++) memcpy(CUR(s), buf + (size_t)s * pyr_n, nc * sizeof(float));
    for (int l = 0; l < Lo; l++) {
        int m = 1 << l, w = m + 2;
        for (int s = 0; s < nm; s++) {
            int q = mem[s];
            const float *a = CUR(s);
            float *nx = NXT(s);
            recon_extend(rc, q, m, w, nc, a, ext, buf, nm, pyr_n, full, cur_half, limit);
            /* a curved quad's cells are a flat facet's: its mean, and the details the unlimited
             * prediction misses by more than half of `sharp` (blender_smooth q3, one light,
             * image error 13.25% before; sharp / 2 13.31%, sharp 13.47%, 0.3 sharp 13.30%
             * with faint facets again; the path tracer shades the flat facets) */
            int curved = rc->curved[q] && !facets;
            recon_children(s, q, l, L, m, w, nc, ext, nx, known, buf, pyr_n, curved ? 0 : keep,
                           curved ? 0.5f * sharp : sharp, curved ? 0 : limit);
        }
        cur_half = 1 - cur_half;
    }
    recon_output(rc, nm, mem, Lo, nc, out, buf, pyr_n, full, cur_half, limit);
    if (blend) recon_blend(rc, gr, nm, mem, Lo, nc, out, buf, pyr_n, ext);
}

void wrt_recon_run_in(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                      const uint8_t *const *known, float *const *out, const wrt_recon_params *prm, float *buf) {
    int keep = prm ? prm->keep : WRT_RECON_KEEP, limit = prm ? prm->limit : 1, linear = prm ? prm->linear : 0;
    int facets = prm ? prm->facets : 0, facet_means = prm ? prm->facet_means : 0;
    float sharp = prm ? prm->sharp : WRT_RECON_SHARP;
    if (linear) { /* a choice from the mask and `keep` alone */
        limit = 0;
        sharp = 0;
    }
    int nm;
    const int *mem = wrt_recon_members(rc, gr, &nm);
    if (nm == 0) return;
    size_t pyr_n = (((size_t)1 << (2 * (L + 1))) - 1) / 3 * nc; /* levels 0..L */
    size_t full = ((size_t)1 << (2 * Lo)) * nc;
    float *ext = buf + (size_t)nm * (pyr_n + 2 * full);
    recon_pyramids(nm, mem, L, nc, in, buf, pyr_n);
    int blend = rc->gnv && rc->gnv[gr] > 0 && !facets && !facet_means;
    if (blend && rc->gall[gr]) /* every member shows the blend: only the means are read */
        recon_blend(rc, gr, nm, mem, Lo, nc, out, buf, pyr_n, ext);
    else
        recon_levels(rc, nm, mem, L, Lo, nc, known, out, buf, pyr_n, full, keep, sharp, limit, facets, blend, gr);
    /* Light is never negative: the prediction can undershoot beside a sharp edge (the
     * linear display keeps the undershoot: a clamp does not superpose). */
    for (int s = 0; s < nm && !linear; s++) {
        float *o = out[mem[s]];
        size_t k = 0;
#ifdef __SSE4_1__
        /* MAXPS(0, x) is 0 > x ? 0 : x: the scalar clamp's bits, NaN and -0 kept */
        for (; k + 4 <= full; k += 4) _mm_storeu_ps(o + k, _mm_max_ps(_mm_setzero_ps(), _mm_loadu_ps(o + k)));
#endif
        for (; k < full; k++) o[k] = o[k] < 0 ? 0 : o[k];
    }
#undef CUR
#undef NXT
}
