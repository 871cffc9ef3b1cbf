/* relight_project.c: the projection of a light onto the 4D Haar basis (Kontkanen et al.
 * 2006, section 5.1; docs/algorithm.md): for each quad, the coefficients E of the direct
 * light on its functions and, on a quad with columns of the first-bounce operator K,
 * the light's c over those columns. Depends on relight_internal.h (the quads, the
 * workers' scratch, the parallel loop), common/basis.h, Embree 3 (shadow rays) and the
 * BRDF table (K's btilde).
 *
 * Projection: an adaptive quadtree per quad and light. Every cell of the 8 x 8 grid
 * (PROJ_MIN_LEVEL; 4 x 4 on a diffuse quad, proj_min_level; coarser if the quad holds
 * no finer functions) is either split
 * unseen, while it is wider than 1/8 of its distance to the light (1/11.3 on quads with
 * angular functions), so that 1/d^2 and the cosine change by at most ~1/8 across a
 * cell, or sampled (4 samples at fixed rotated-grid positions, one shadow ray each). A
 * sampled cell is split again when its samples see a shadow edge (some lit, some
 * occluded), or on a glossy quad the light in different cells of the finest angular
 * level, or when its neighbour sees the opposite (the edge runs between them); down to
 * the cap, min(slevel + 1, 6), which resolves every function the file holds on the quad.
 * A cell that is not split is a leaf: the projected function is constant over it, so
 * its finer wavelets are exactly zero, cost no rays and are not stored (E stays sparse
 * for the multiply). Every decision depends on the geometry and the light's position
 * and shape only, never on its intensity, colour or other lights, so each light's E is
 * linear in that light. A positive options.proj_level samples every cell of that level
 * instead (edges still split down to the cap); options.proj_reference samples every cell
 * of the cap (the tests' truth). Shadow rays are traced only where a quad may shade the
 * cell: bounding cones from the light, then a separation test against the pyramid from
 * the light to the quad (and to each coarse cell); quads wholly outside a spot's cone or
 * beyond its range are skipped. The same exact zeros and values as tracing every ray.
 * A directional light (sun) is the same with the light at infinity: E = intensity x cos
 * toward -dir, no falloff and no range; its shadow rays must leave the scene; cells are
 * never split for distance (a planar quad's lit irradiance is constant), so its grid is
 * the 8 x 8 one and only shadow edges split cells, down to the cap; the pyramids become
 * prisms along its direction and the cones cylinders.
 *
 * Departures from the paper, by design: direct light on a glossy quad is projected onto
 * the angular functions too (the light direction, spread over one cell of the finest
 * angular level centred on it, evaluated in the angular Haar basis), so it bounces
 * glossily; a quad's texture has 2^(slevel+1) texels a side (capped), so the finest
 * stored wavelet is represented exactly as a texel average; glossy pruning
 * (Figure 5) is done per angular function: one whose BRDF weight beta is below 1e-3 of
 * the root's over every direction the quad sends toward the eye is skipped.
 *
 * On a quad with K columns (relight_bounce.c) the same samples also give c: g(w_l)
 * replaced by the BRDF table's btilde_g(w_l) at the light's exact direction (k_sample). */
#include "relight_internal.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef WRT_K_AVX
#include <immintrin.h>
#endif

#define PROJ_CELL_K 8.0      /* cells at most d / PROJ_CELL_K wide */
#define PROJ_CELL_K_GLOSSY 11.3 /* on quads with angular functions (measured: error below 1.2x)*/

/* Fixed rotated-grid sample positions within a cell (4 samples). */
static const double cell_samples[4][2] = {{0.375, 0.125}, {0.875, 0.375}, {0.625, 0.875}, {0.125, 0.625}};

/* The grid every cell of which is sampled (or split unseen by the level rule) on quad q:
 * 8 x 8 where the light's direction matters (angular functions, K's columns), 4 x 4 on
 * a diffuse quad, whose E only feeds the transport (the direct light is drawn apart):
 * the finer wavelets of a smooth light are small there, and the level rule and the
 * shadow edges still split cells down to the cap (docs/bench.md, session 6). */
static int proj_min_level(const quad_info *q) {
    return q->nang > 1 || q->kcount ? PROJ_MIN_LEVEL : PROJ_MIN_LEVEL_DIFFUSE;
}

/* The deepest spatial level the projection resolves: the quad's functions' and its K
 * columns' (kslevel is 0 without K). */
int relight_projection_cap(const wrt_relight *r, const quad_info *q) {
    int cap = (q->slevel > q->kslevel ? q->slevel : q->kslevel) + 1;
    if (cap > PROJ_MAX_LEVEL) cap = PROJ_MAX_LEVEL;
    if (r->opt.proj_level > 0 && r->opt.proj_level < cap) cap = r->opt.proj_level;
    return cap;
}

static int projection_level(const wrt_relight *r, const quad_info *q, double d) {
    int cap = (q->slevel > q->kslevel ? q->slevel : q->kslevel) + 1;
    if (cap > PROJ_MAX_LEVEL) cap = PROJ_MAX_LEVEL;
    int L;
    if (r->opt.proj_level > 0) L = r->opt.proj_level;
    else {
        double ratio = PROJ_CELL_K * q->diam / (d > 1e-300 ? d : 1e-300);
        L = ratio <= 1 ? 0 : (int)ceil(log2(ratio));
        int lo = cap < 2 ? cap : 2;
        if (L < lo) L = lo;
    }
    return L > cap ? cap : L;
}

#define VIS_LIT 1
#define VIS_SHADOWED 2
#define VIS_EVAL 4      /* cell state: evaluated at this level */
#define VIS_ANGMIX 8    /* cell state: its lit samples see the light in different angular cells */
#define VIS_ANG_SHIFT 8 /* cell state: 1 + the angular cell of its lit samples, above this bit */

/* What every cell of one quad's projection shares. */
typedef struct proj_setup {
    const quad_info *q;
    const light_c *lc;
    int nslot, nsamp, grid_n, rays; /* grid_n > 0: n x n samples a cell, else cell_samples */
    int ang_res;                    /* angular cells a side (0: diffuse quad) */
    const int16_t *slot_of;
    int nkang;                      /* K's angular indices 0..nkang-1 on the quad: 3 slots */
                                    /* each, after the E slots (nslot - 3 nkang of them) */
    const float *beta;              /* the quad's material's BRDF table (with K) */
    int avx;                        /* K's slots eight lanes at a time (AVX at run time) */
} proj_setup;

#ifdef WRT_K_AVX
/* k_sample's blend eight lanes at a time (the SSE loop's operations on each value: the
 * same bits); returns the values done. */
__attribute__((target("avx"))) static int k_sample_avx(const float wt[4], const float *const row[4], int n, float *acc) {
    __m256 w0 = _mm256_set1_ps(wt[0]), w1 = _mm256_set1_ps(wt[1]), w2 = _mm256_set1_ps(wt[2]), w3 = _mm256_set1_ps(wt[3]);
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        __m256 s01 = _mm256_add_ps(_mm256_mul_ps(w0, _mm256_loadu_ps(row[0] + i)), _mm256_mul_ps(w1, _mm256_loadu_ps(row[1] + i)));
        __m256 s23 = _mm256_add_ps(_mm256_mul_ps(w2, _mm256_loadu_ps(row[2] + i)), _mm256_mul_ps(w3, _mm256_loadu_ps(row[3] + i)));
        _mm256_storeu_ps(acc + i, _mm256_add_ps(_mm256_loadu_ps(acc + i), _mm256_add_ps(s01, s23)));
    }
    return i;
}
#endif

/* K's slots of one sample (K-SPEC, "The maths"): the sample's weight `val` (E_dir V
 * sqrt(J/pi) x its share of the cell) times btilde_g(w_l), the BRDF table's beta_g at the
 * light's exact direction (concentric (a, b) in the quad's frame; bilinear between the
 * table's directions, as wrt_relight_beta), for each angular index g < nkang: acc[3 g + c]
 * (single precision, as the table; a cell's few samples). No light-direction splat: the
 * first bounce of the delta is exact. (Merging the taps of a cell's samples per table
 * direction first was measured slower: they seldom share one.) */
static void k_sample(const proj_setup *ps, double a, double b, double val, float *acc) {
    double fx = a * BETA_RES - 0.5, fy = b * BETA_RES - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    float wt[4];
    const float *row[4];
    for (int k = 0; k < 4; k++) {
        int cx = x0 + (k & 1), cy = y0 + (k >> 1);
        cx = cx < 0 ? 0 : cx >= BETA_RES ? BETA_RES - 1 : cx;
        cy = cy < 0 ? 0 : cy >= BETA_RES ? BETA_RES - 1 : cy;
        wt[k] = (float)(val * ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty));
        row[k] = ps->beta + (size_t)(cy * BETA_RES + cx) * NANG * 3;
    }
    int n = 3 * ps->nkang, i = 0;
#ifdef WRT_K_AVX
    if (ps->avx) i = k_sample_avx(wt, row, n, acc);
#endif
#ifdef __SSE2__
    __m128 w0 = _mm_set1_ps(wt[0]), w1 = _mm_set1_ps(wt[1]), w2 = _mm_set1_ps(wt[2]), w3 = _mm_set1_ps(wt[3]);
    for (; i + 4 <= n; i += 4) {
        __m128 s01 = _mm_add_ps(_mm_mul_ps(w0, _mm_loadu_ps(row[0] + i)), _mm_mul_ps(w1, _mm_loadu_ps(row[1] + i)));
        __m128 s23 = _mm_add_ps(_mm_mul_ps(w2, _mm_loadu_ps(row[2] + i)), _mm_mul_ps(w3, _mm_loadu_ps(row[3] + i)));
        _mm_storeu_ps(acc + i, _mm_add_ps(_mm_loadu_ps(acc + i), _mm_add_ps(s01, s23)));
    }
#endif
    for (; i < n; i++) acc[i] += (wt[0] * row[0][i] + wt[1] * row[1][i]) + (wt[2] * row[2][i] + wt[3] * row[3][i]);
}

/* Cell (i, j) of level l: out[slot] = the level-l scaling coefficient (cell average x
 * 2^-l) of E_dir V g sqrt(J/pi) for each angular slot, from the cell's samples.
 * Returns VIS_LIT if a sample is lit, | VIS_SHADOWED if a sample facing the light is
 * occluded. */
static uint32_t eval_cell(const wrt_relight *r, worker *w, const proj_setup *ps, int l, int i, int j, int rays, double *out,
                          double *flux) {
    w->nsamples += ps->nsamp * (1 + rays);
    const quad_info *q = ps->q;
    int nslot = ps->nslot, angular = nslot - 3 * ps->nkang > 1, root_slot = ps->slot_of[0];
    for (int s = 0; s < nslot; s++) out[s] = 0;
    double cellw = ldexp(1.0, -l), wgt = cellw / ps->nsamp, inv_pi = 1.0 / WRT_PI;
    double sj = q->parallelogram ? sqrt(q->area * inv_pi) : 0, fl = 0;
    uint32_t vis = 0, ang_cell = 0;
    float kacc[3 * NANG]; /* K's slots, summed in single precision over the cell's samples */
    if (ps->nkang) memset(kacc, 0, 3 * (size_t)ps->nkang * sizeof(float));
    /* the samples four at a time: their points and light first, then their shadow rays
     * as one packet, then each sample's terms in sample order */
    wrt_v3 xs[4], dirs[4];
    double us[4], vs[4], ds[4], es[4];
    int need[4], lit[4];
    for (int k = 0; k < ps->nsamp; k++) {
        int k4 = k & 3;
        if (k4 == 0) {
            int n4 = ps->nsamp - k < 4 ? ps->nsamp - k : 4;
            for (int t = 0; t < n4; t++) {
                int kk = k + t;
                double ou = ps->grid_n ? (kk % ps->grid_n + 0.5) / ps->grid_n : cell_samples[kk][0];
                double ov = ps->grid_n ? (kk / ps->grid_n + 0.5) / ps->grid_n : cell_samples[kk][1];
                us[t] = (i + ou) * cellw; vs[t] = (j + ov) * cellw;
                xs[t] = quad_point(q, us[t], vs[t]);
                ds[t] = 0;
                es[t] = light_irradiance(ps->lc, xs[t], q->n, &dirs[t], &ds[t]);
                need[t] = rays && es[t] != 0;
            }
            if (rays) light_visible4(r, n4, xs, q->n, dirs, ds, need, lit);
            else lit[0] = lit[1] = lit[2] = lit[3] = 1;
        }
        double u = us[k4], v = vs[k4], e = es[k4];
        wrt_v3 dir = dirs[k4];
        if (e == 0) continue;
        if (!lit[k4]) { vis |= VIS_SHADOWED; continue; }
        double J = q->parallelogram ? 0 : quad_jacobian(q, u, v);
        double val = e * (q->parallelogram ? sj : sqrt(J * inv_pi)) * wgt;
        fl += e * J * wgt;
        vis |= VIS_LIT;
        if (root_slot >= 0) out[root_slot] += val;
        if (!angular && !ps->nkang) continue;
        double loc[3] = {v3_dot(dir, q->t), v3_dot(dir, q->b), v3_dot(dir, q->n)}, a, b;
        wrt_concentric_inv(loc, &a, &b);
        if (ps->nkang) k_sample(ps, a, b, val, kacc);
        if (!angular) continue;
        if (ps->ang_res) { /* where the wavelets of the finest angular level change sign */
            int ar = ps->ang_res, ax = (int)(a * ar), ay = (int)(b * ar);
            uint32_t id = 1 + (uint32_t)((ay < ar ? ay : ar - 1) * ar + (ax < ar ? ax : ar - 1));
            if (ang_cell && id != ang_cell) vis |= VIS_ANGMIX;
            ang_cell = id;
        }
        /* The light's direction, a delta, spread over one cell of the finest angular level
         * centred on it (light_splat): its Haar coefficients are then the bilinear blend of
         * the functions' values at the four nearest finest-cell centres, so the reflected
         * lobe is centred on the light's direction instead of on its cell's centre. */
        int nc = 1, ar = ps->ang_res;
        double ca[4] = {a}, cb[4] = {b}, cw[4] = {1};
        if (!r->opt.no_light_splat && ar > 0) {
            double fa = a * ar - 0.5, fb = b * ar - 0.5;
            int ia = (int)floor(fa), ib = (int)floor(fb);
            double ta = fa - ia, tb = fb - ib;
            nc = 4;
            for (int c = 0; c < 4; c++) {
                int xa = ia + (c & 1), xb = ib + (c >> 1);
                xa = xa < 0 ? 0 : xa > ar - 1 ? ar - 1 : xa;
                xb = xb < 0 ? 0 : xb > ar - 1 ? ar - 1 : xb;
                ca[c] = (xa + 0.5) / ar; cb[c] = (xb + 0.5) / ar;
                cw[c] = ((c & 1) ? ta : 1 - ta) * ((c >> 1) ? tb : 1 - tb);
            }
        }
        for (int c = 0; c < nc; c++) {
            if (cw[c] == 0) continue;
            double vc = val * cw[c];
            for (int al = 0; al < ANG_LEVELS; al++) {
                int an = 1 << al;
                int ax = (int)(ca[c] * an), ay = (int)(cb[c] * an);
                if (ax > an - 1) ax = an - 1;
                if (ay > an - 1) ay = an - 1;
                double su = ca[c] * an - ax < 0.5 ? 1.0 : -1.0, sv = cb[c] * an - ay < 0.5 ? 1.0 : -1.0;
                uint32_t kk = haar_index(al, ax, ay, 1);
                double gv[3] = {an * su, an * sv, an * su * sv};
                for (int t = 0; t < 3; t++) {
                    int sl = ps->slot_of[kk + t];
                    if (sl >= 0) out[sl] += vc * gv[t];
                }
            }
        }
    }
    for (int s = 0; s < 3 * ps->nkang; s++) out[nslot - 3 * ps->nkang + s] = kacc[s];
    if (flux) *flux = fl * cellw; /* the cell's flux: its mean of E J times its area 4^-l */
    return vis | (vis & VIS_ANGMIX ? 0 : ang_cell << VIS_ANG_SHIFT);
}

/* Visibility class (VIS bits) of cell (x, y) of level l: its own if it was evaluated
 * at l, else that of the evaluated ancestor (a leaf of the quadtree) that covers it. */
static uint32_t state_at(const worker *w, int Ld, int l, int x, int y) {
    for (int k = l; k >= Ld; k--) {
        uint32_t s = w->pstate[LEVEL_OFF(k) + ((size_t)(y >> (l - k)) << k) + (size_t)(x >> (l - k))];
        if (s & VIS_EVAL) return s;
    }
    return 0;
}

/* A cell is split when its samples see a shadow edge (some lit, some occluded) or, on
 * a glossy quad, the light in different angular cells; or when it is all lit and a
 * neighbour all occluded (or the reverse), or both see the light in different angular
 * cells: the edge then runs between their samples. */
static int needs_refine(const worker *w, int Ld, int l, int x, int y) {
    int n = 1 << l;
    uint32_t s = w->pstate[LEVEL_OFF(l) + (size_t)y * n + x];
    int v = (int)(s & 3);
    if (v == (VIS_LIT | VIS_SHADOWED) || (s & VIS_ANGMIX)) return 1;
    if (v == 0) return 0;
    int opp = v ^ (VIS_LIT | VIS_SHADOWED);
    static const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    for (int k = 0; k < 4; k++) {
        int nx = x + nb[k][0], ny = y + nb[k][1];
        if (nx < 0 || ny < 0 || nx >= n || ny >= n) continue;
        uint32_t ns = state_at(w, Ld, l, nx, ny);
        if ((int)(ns & 3) == opp) return 1;
        if (v == VIS_LIT && (ns & 3) == VIS_LIT && !(ns & VIS_ANGMIX) && (ns >> VIS_ANG_SHIFT) != (s >> VIS_ANG_SHIFT))
            return 1;
    }
    return 0;
}

/* The level rule, cell by cell: a cell is split while it is wider than 1/PROJ_CELL_K of
 * its distance to the light, so that 1/d^2 and the cosine change by at most ~1/8
 * across it. Geometry and the light's position only. */
static int too_close(const proj_setup *ps, int l, int i, int j) {
    if (ps->lc->sun) return 0; /* no falloff: a planar quad's irradiance is constant where lit */
    const quad_info *q = ps->q;
    double h = ldexp(1.0, -l), u0 = i * h, v0 = j * h;
    wrt_v3 c00 = quad_point(q, u0, v0), c11 = quad_point(q, u0 + h, v0 + h);
    wrt_v3 c10 = quad_point(q, u0 + h, v0), c01 = quad_point(q, u0, v0 + h);
    double diam = fmax(v3_len(v3_sub(c11, c00)), v3_len(v3_sub(c10, c01)));
    wrt_v3 mid = quad_point(q, u0 + 0.5 * h, v0 + 0.5 * h);
    double d = v3_len(v3_sub(mid, ps->lc->pos)) - 0.5 * diam;
    return (q->nang > 1 ? PROJ_CELL_K_GLOSSY : PROJ_CELL_K) * diam > d;
}

/* Occluder culling: a shadow ray from a point of quad A (or of one of its cells) to the
 * light can only hit a quad B that meets the pyramid spanned by the light and A. These
 * tests are conservative (a B they keep may still miss), exact up to a 1e-9 relative
 * tolerance on points on a plane, and depend on the geometry and the light's position
 * only. */
static int all_below(const wrt_v3 *pts, int n, wrt_v3 o, wrt_v3 nrm, double size) {
    double tol = 1e-9 * size * sqrt(v3_dot(nrm, nrm)); /* size: bounds |pts[k] - o| */
    for (int k = 0; k < n; k++)
        if (v3_dot(v3_sub(pts[k], o), nrm) > tol) return 0;
    return 1;
}

/* The planes of the pyramid of light l and the convex planar polygon c[0..3] (normal n,
 * light on its front), or for a sun the prism toward it: what pyramid_clear tests every
 * quad b against, made once per polygon. A plane is a point o, a normal and all_below's
 * tolerance for it. */
typedef struct pyr_planes {
    int np, sun;
    wrt_v3 o[6], nrm[6];
    double tol[6];
    wrt_v3 pts[5];  /* the polygon's corners and the light (a sun: the corners only) */
    wrt_v3 s;       /* a sun: the unit direction toward it */
} pyr_planes;

static void pyr_plane(pyr_planes *pp, wrt_v3 o, wrt_v3 nrm, double size) {
    pp->o[pp->np] = o;
    pp->nrm[pp->np] = nrm;
    pp->tol[pp->np++] = 1e-9 * size * sqrt(v3_dot(nrm, nrm)); /* as all_below's */
}

static void pyramid_setup(pyr_planes *pp, const wrt_v3 c[4], wrt_v3 n, const light_c *lc, double size) {
    pp->np = 0;
    pp->sun = lc->sun;
    for (int k = 0; k < 4; k++) pp->pts[k] = c[k];
    pyr_plane(pp, c[0], n, size); /* b on or behind the polygon's plane */
    if (lc->sun) {
        wrt_v3 s = v3_scale(lc->dir, -1);
        pp->s = s;
        wrt_v3 mid = v3_scale(v3_add(v3_add(c[0], c[1]), v3_add(c[2], c[3])), 0.25);
        for (int k = 0; k < 4; k++) { /* the sides: planes through an edge and s, normals inward */
            wrt_v3 sn = v3_cross(v3_sub(c[(k + 1) & 3], c[k]), s);
            if (v3_dot(sn, v3_sub(mid, c[k])) < 0) sn = v3_scale(sn, -1);
            pyr_plane(pp, c[k], sn, size);
        }
        return;
    }
    wrt_v3 l = lc->pos;
    pp->pts[4] = l;
    pyr_plane(pp, l, v3_scale(n, -1), size); /* beyond the light's parallel plane */
    /* the pyramid's sides: inward normals (e_k - l) x (e_k+1 - l) for a ccw polygon */
    wrt_v3 mid = v3_sub(v3_scale(v3_add(v3_add(c[0], c[1]), v3_add(c[2], c[3])), 0.25), l);
    for (int k = 0; k < 4; k++) {
        wrt_v3 sn = v3_cross(v3_sub(c[(k + 1) & 3], l), v3_sub(c[k], l));
        if (v3_dot(sn, mid) < 0) sn = v3_scale(sn, -1); /* inward whatever the winding */
        pyr_plane(pp, l, sn, size);
    }
}

/* 1 if quad b cannot meet the pyramid (or a sun's prism) of pp: b wholly below one of its
 * planes, or b's plane leaves the polygon and the light (a sun: the polygon, and the sun's
 * direction does not rise above it) on one side. */
static int pyramid_clear(const pyr_planes *pp, const quad_info *b, double size) {
    for (int k = 0; k < pp->np; k++) {
        int below = 1;
        for (int t = 0; t < 4 && below; t++) below = !(v3_dot(v3_sub(b->p[t], pp->o[k]), pp->nrm[k]) > pp->tol[k]);
        if (below) return 1;
    }
    wrt_v3 nb = v3_scale(b->n, -1);
    if (pp->sun)
        return (all_below(pp->pts, 4, b->p[0], b->n, size) && v3_dot(pp->s, b->n) <= 0) ||
               (all_below(pp->pts, 4, b->p[0], nb, size) && v3_dot(pp->s, nb) <= 0);
    return all_below(pp->pts, 5, b->p[0], b->n, size) || all_below(pp->pts, 5, b->p[0], nb, size);
}

/* Cell (i, j) of level l of quad q: 1 if none of the quad's possible occluders can
 * shade it. */
static int cell_clear(const wrt_relight *r, const worker *w, const quad_info *q, const light_c *l, int lv, int i, int j) {
    double h = ldexp(1.0, -lv), u0 = i * h, v0 = j * h;
    wrt_v3 c[4] = {quad_point(q, u0, v0), quad_point(q, u0 + h, v0), quad_point(q, u0 + h, v0 + h), quad_point(q, u0, v0 + h)};
    pyr_planes pp;
    pyramid_setup(&pp, c, q->n, l, r->proj.size);
    for (int k = 0; k < w->nocc; k++)
        if (!pyramid_clear(&pp, &r->qi[w->occ[k]], r->proj.size)) return 0;
    return 1;
}

/* Quad b against quad a's light cone (ca), pyramid (pp) and, for a sun, cylinder: 1 if
 * b may shade some point of a. */
static int may_shade(const wrt_relight *r, const light_c *l, const light_cone *ca, const quad_info *qa,
                     const pyr_planes *pp, uint32_t b) {
    const light_cone *cb = &r->proj.cones[b];
    if (cb->dmin >= ca->dmax) return 0; /* entirely farther than a */
    /* radii in [0, pi/2]: their sum in [0, pi], where cos decreases */
    if (ca->cosa > -1 && cb->cosa > -1 && v3_dot(ca->u, cb->u) < ca->cosa * cb->cosa - ca->sina * cb->sina) return 0;
    if (l->sun) { /* the two bounding spheres' shadows along the sun's direction are apart */
        wrt_v3 dc = v3_sub(r->qi[b].centre, qa->centre);
        wrt_v3 perp = v3_sub(dc, v3_scale(l->dir, v3_dot(dc, l->dir)));
        if (v3_len(perp) >= qa->radius + r->qi[b].radius) return 0;
    }
    return !pyramid_clear(pp, &r->qi[b], r->proj.size);
}

/* 1 if no quad under node n (sphere nd, cone cn) can pass may_shade's tests against quad
 * a. Each test is may_shade's on the node's sphere, with a margin far above rounding; it
 * fails for every quad under the node because each quad's sphere lies in the node's:
 *  - distance: a quad's nearest point to the light is no nearer than the node's;
 *  - cones: a quad's cone lies in the node's, so the angle between a's axis and the
 *    quad's exceeds a's radius plus the quad's by at least d, the amount by which the
 *    angle to the node's axis exceeds a's radius plus the node's. The test is on
 *    cosines, and a cosine gap G >= 2 sin(d/2) on the node's gives the quad's only
 *    G^2 / 2 in the worst case (tiny cones, where cos is flat: 2 sin(x + d/2) sin(d/2)
 *    with x = a's radius plus the quad's, near 0); so the node's gap must be 1e-6, for
 *    the quad's 5e-13, far above the rounding of may_shade's test (and above the ~2e-8
 *    error of a cone's cosa near a hemisphere). A margin of 1e-9 left the quad's gap at
 *    5e-19 at worst, below that rounding: a quad 4e-8 radians across, an occluder 4e-9
 *    radians outside its cone (test_occluder_tree_tiny_cones), the scan kept it and
 *    the tree did not;
 *  - a sun's cylinders: the distance across the light is 1-Lipschitz;
 *  - the pyramid: a plane with the whole sphere below it has every corner below it. */
static int node_clear(const wrt_relight *r, const light_c *l, const light_cone *ca, const quad_info *qa,
                      const pyr_planes *pp, const double *nlen, const occ_node *nd, const light_cone *cn) {
    double m = 1e-9 * r->proj.size;
    if (cn->dmin >= ca->dmax + m) return 1;
    if (ca->cosa > -1 && cn->cosa > -1 && v3_dot(ca->u, cn->u) < ca->cosa * cn->cosa - ca->sina * cn->sina - 1e-6)
        return 1;
    if (l->sun) {
        wrt_v3 dc = v3_sub(nd->c, qa->centre);
        wrt_v3 perp = v3_sub(dc, v3_scale(l->dir, v3_dot(dc, l->dir)));
        if (v3_len(perp) >= qa->radius + nd->rad + m) return 1;
    }
    for (int k = 0; k < pp->np; k++)
        if (v3_dot(v3_sub(nd->c, pp->o[k]), pp->nrm[k]) + nd->rad * nlen[k] <= 0) return 1;
    return 0;
}

/* The quads that may shade some point of quad a (into w->occ): bounding cones from the
 * light first (for a sun: bounding cylinders along its direction), then the pyramid
 * tests; by the tree over the quads' spheres (relight_occ.c), in its leaves' order.
 * -1 if there is no memory for the list. */
static int find_occluders(wrt_relight *r, worker *w, int a, const light_c *l) {
    uint32_t nq = r->g->nquads;
    w->nocc = 0;
    uint32_t *occ = relight_grow(r, w->occ, &w->nocc_cap, nq + 1, sizeof(uint32_t));
    if (!occ) return -1;
    w->occ = occ;
    const light_cone *ca = &r->proj.cones[a];
    const quad_info *qa = &r->qi[a];
    pyr_planes pp;
    pyramid_setup(&pp, qa->p, qa->n, l, r->proj.size);
    double nlen[6];
    for (int k = 0; k < pp.np; k++) nlen[k] = sqrt(v3_dot(pp.nrm[k], pp.nrm[k]));
    if (r->opt.occ_scan) {
        for (uint32_t b = 0; b < nq; b++)
            if ((int)b != a && may_shade(r, l, ca, qa, &pp, b)) w->occ[w->nocc++] = b;
        w->noccs += w->nocc;
        return 0;
    }
    uint32_t stack[128]; /* the tree's depth is at most 61 (relight_occ.c) */
    int sp = 0;
    if (r->proj.nonode) stack[sp++] = 0;
    while (sp) {
        uint32_t n = stack[--sp];
        const occ_node *nd = &r->proj.onode[n];
        if (node_clear(r, l, ca, qa, &pp, nlen, nd, &r->proj.ocones[n])) continue;
        if (nd->count) {
            for (uint32_t k = nd->first; k < nd->first + nd->count; k++) {
                uint32_t b = r->proj.oorder[k];
                if ((int)b != a && may_shade(r, l, ca, qa, &pp, b)) w->occ[w->nocc++] = b;
            }
            continue;
        }
        stack[sp++] = nd->right;
        stack[sp++] = n + 1;
    }
    w->noccs += w->nocc;
    return 0;
}

typedef struct proj_ctx { const wrt_light *light; const light_c *lc; double *root; float *kc; } proj_ctx;

/* The coefficients c of quad q's K columns from the projection's pyramid (w->pyr: levels
 * above the rule's grid Ld; w->pwav: wavelets of split cells; K's slots from `ebase`, 3
 * a function), as E's are taken in project_quad, times the light's colour, into kc
 * (the light's c, indexed by column; the quad's range was zeroed). */
static void k_extract(const wrt_relight *r, const worker *w, const quad_info *q, const float *col, int ebase, int nslot,
                      int Ld, int last, float *kc) {
    for (uint32_t j = q->kfirst; j < q->kfirst + q->kcount; j++) {
        int sl = ebase + 3 * r->k.fn_ang[j], lev = r->k.fn_slevel[j];
        uint32_t sp = r->k.fn_spidx[j];
        const double *cv;
        if (sp == 0 || lev < Ld) cv = w->pyr + (size_t)sp * nslot + sl;
        else if (lev < last) { /* a wavelet of a split cell, or zero */
            uint32_t k = sp - 1, cell = k / 3 - (uint32_t)LEVEL_OFF(lev);
            if (!w->prefined[LEVEL_OFF(lev) + cell]) continue;
            cv = w->pwav + ((LEVEL_OFF(lev) + cell) * 3 + k % 3) * nslot + sl;
        } else continue; /* finer than any split cell: zero */
        for (int c = 0; c < 3; c++) kc[(size_t)j * 3 + c] = (float)(cv[c] * col[c]);
    }
}

/* The start of quad qidx's projection: its output record, its roots and K's c zeroed.
 * Returns the level rule's grid level for it, or -1 when the light reaches none of it
 * (no functions, no intensity, on or behind its plane, beyond the range, wholly outside
 * a spot's cone): exactly zero. */
static int proj_begin(wrt_relight *r, worker *w, int qidx, const proj_ctx *ctx) {
    const wrt_light *l = ctx->light;
    const quad_info *q = &r->qi[qidx];
    out_rec *rec = &r->proj.recs[qidx];
    rec->worker = (int)(w - r->workers);
    rec->start = w->on;
    rec->count = 0;
    for (int c = 0; c < 3; c++) ctx->root[qidx * 3 + c] = 0;
    if (q->kcount) memset(ctx->kc + (size_t)q->kfirst * 3, 0, (size_t)q->kcount * 3 * sizeof(float));
    if (r->g->quads[qidx].func_count == 0 || l->intensity == 0) return -1;
    /* A light on or behind the quad's plane lights nothing (exactly zero). */
    if (ctx->lc->sun ? v3_dot(l->dir, q->n) >= 0 : v3_dot(v3_sub(l->pos, q->p[0]), q->n) <= 0) return -1;
    int Ld = r->proj.qlevel[qidx];
    if (Ld < 0) return -1; /* beyond the light's range */
    if (l->type == WRT_LIGHT_SPOT && r->proj.cones[qidx].cosa > -1) { /* wholly outside the spot's cone */
        const light_cone *cn = &r->proj.cones[qidx];
        double co = ctx->lc->cos_outer, so = sqrt(fmax(0, 1 - co * co));
        if (l->outer_cone < WRT_PI / 2 && v3_dot(l->dir, cn->u) < co * cn->cosa - so * cn->sina) return -1;
    }
    return Ld;
}

/* The slots each cell's samples fill: E's angular slots (the root, plus the quad's
 * angular functions when it has any), then K's, 3 (RGB) per angular function of its
 * columns. On a quad with K columns, E's angular functions are not projected: the
 * multiply reads E' (E off that quad, + Y), so only E's angular root is kept (the quad's
 * direct irradiance, wrt_relight_quad_irradiance), and no cell is split for the light
 * crossing an angular cell (c's btilde is smooth in the light's direction). */
static void proj_slots(const wrt_relight *r, const quad_info *q, const light_c *lc, int16_t slot_of[NANG], proj_setup *ps) {
    int eang = q->nang > 0 && !q->kcount;
    int nslot = eang ? q->nang : 1;
    const uint16_t *alist = r->ang_list + q->ang_first;
    for (int a = 0; a < NANG; a++) slot_of[a] = -1;
    if (eang) for (int s = 0; s < q->nang; s++) slot_of[alist[s]] = (int16_t)s;
    else slot_of[0] = 0;
    nslot += 3 * q->nkang;
    proj_setup p = {q, lc, nslot, 4, 0, 1, 0, slot_of, q->nkang, r->beta[q->material], r->k.avx};
    if (eang && q->nang > 1) p.ang_res = 2 << q->alevel;
    *ps = p;
}

/* Splits cell (x, y) of level lv: its four children join the cells of level lv + 1. */
static size_t push_children(worker *w, size_t nc, int n, int x, int y) {
    int n2 = 2 * n;
    w->pcells[nc++] = (uint16_t)((2 * y) * n2 + 2 * x);
    w->pcells[nc++] = (uint16_t)((2 * y) * n2 + 2 * x + 1);
    w->pcells[nc++] = (uint16_t)((2 * y + 1) * n2 + 2 * x);
    w->pcells[nc++] = (uint16_t)((2 * y + 1) * n2 + 2 * x + 1);
    return nc;
}

/* Top-down: sample the cells of level lv from Ld, split those on an edge, down to the
 * cap (r->opt.proj_reference: every cell of the grid Ld, no split). lstart[lv] is where
 * level lv's cells start in w->pcells; *last the deepest level sampled. Returns the VIS
 * bits of every sample together. */
static int proj_sample_tree(const wrt_relight *r, worker *w, const proj_setup *ps, int Ld, int cap,
                            int local_rule, size_t lstart[PROJ_MAX_LEVEL + 2], int *last) {
    const quad_info *q = ps->q;
    int nslot = ps->nslot;
    size_t nc = 0;
    for (size_t c = 0; c < ((size_t)1 << (2 * Ld)); c++) w->pcells[nc++] = (uint16_t)c;
    lstart[Ld] = 0;
    lstart[Ld + 1] = nc;
    int any = 0;
    *last = Ld;
    for (int lv = Ld;; lv++) {
        int n = 1 << lv;
        size_t off = LEVEL_OFF(lv);
        size_t start = nc;
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            int c = w->pcells[k], x = c % n, y = c / n;
            /* clear of occluders: its parent is, or (near the top) the test says so */
            int clear = !ps->rays || (lv > Ld && w->pclear[LEVEL_OFF(lv - 1) + (size_t)(y / 2) * (n / 2) + x / 2]) ||
                        (lv <= proj_min_level(q) + 1 && r->opt.proj_reference == 0 && cell_clear(r, w, q, ps->lc, lv, x, y));
            w->pclear[off + c] = (uint8_t)clear;
            if (local_rule && lv < cap && too_close(ps, lv, x, y)) { /* split unseen */
                w->prefined[off + c] = 1;
                nc = push_children(w, nc, n, x, y);
                continue;
            }
            uint32_t vis = eval_cell(r, w, ps, lv, x, y, !clear, w->pval + (off + c) * nslot,
                                     q->parallelogram ? NULL : w->pflux + off + c);
            w->pstate[off + c] = VIS_EVAL | vis;
            any |= (int)(vis & 3);
        }
        *last = lv;
        if (lv == cap || r->opt.proj_reference > 0) break;
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            int c = w->pcells[k], x = c % n, y = c / n;
            if (!(w->pstate[off + c] & VIS_EVAL) || !needs_refine(w, Ld, lv, x, y)) continue;
            w->prefined[off + c] = 1;
            nc = push_children(w, nc, n, x, y);
        }
        if (nc == start) break;
        lstart[lv + 2] = nc;
    }
    return any;
}

/* Bottom-up: a split cell's scaling coefficient and wavelets from its children. */
static void proj_combine(worker *w, int nslot, int Ld, int last, const size_t lstart[PROJ_MAX_LEVEL + 2]) {
    for (int lv = last - 1; lv >= Ld; lv--) {
        int n = 1 << lv, n2 = 2 * n;
        size_t off = LEVEL_OFF(lv), off2 = LEVEL_OFF(lv + 1);
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            int c = w->pcells[k], x = c % n, y = c / n;
            if (!w->prefined[off + c]) continue;
            const double *a = w->pval + (off2 + (size_t)(2 * y) * n2 + 2 * x) * nslot, *b = a + nslot;
            const double *d = w->pval + (off2 + (size_t)(2 * y + 1) * n2 + 2 * x) * nslot, *e = d + nslot;
            double *wv = w->pwav + (off + c) * 3 * nslot, *pv = w->pval + (off + c) * nslot;
            for (int s = 0; s < nslot; s++) {
                wv[s] = (a[s] - b[s] + d[s] - e[s]) * 0.5;             /* type 1: sign by cx */
                wv[nslot + s] = (a[s] + b[s] - d[s] - e[s]) * 0.5;     /* type 2: sign by cy */
                wv[2 * nslot + s] = (a[s] - b[s] - d[s] + e[s]) * 0.5; /* type 3 */
                pv[s] = (a[s] + b[s] + d[s] + e[s]) * 0.5;
            }
        }
    }
}

/* Appends (function f, value cv x colour) to the worker's output; 0, or -1 if there is no
 * memory (both arrays grow to 2 x ocap, keeping what they hold). */
static int proj_emit(wrt_relight *r, worker *w, uint32_t f, double cv, const float *col) {
    if (w->on == w->ocap) {
        size_t ci = w->ocap, cvc = 3 * w->ocap;
        uint32_t *ni = relight_grow_keep(r, w->oidx, &ci, w->ocap ? 2 * w->ocap : 1024, sizeof(uint32_t), w->on);
        if (!ni) return -1;
        w->oidx = ni;
        float *nv = relight_grow_keep(r, w->oval, &cvc, 3 * ci, sizeof(float), 3 * w->on);
        if (!nv) return -1; /* oidx grew, ocap did not: a later try grows oval only */
        w->oval = nv;
        w->ocap = ci;
    }
    w->oidx[w->on] = f;
    for (int c = 0; c < 3; c++) w->oval[w->on * 3 + c] = (float)(cv * col[c]);
    w->on++;
    return 0;
}

/* The coefficient of function f in slot sl from the projection's pyramid (w->pyr: levels
 * above the rule's grid Ld; w->pwav: wavelets of split cells); 0 where it is exactly zero
 * (finer than any split cell, or under a cell that was not split). */
static double proj_coef(const wrt_relight *r, const worker *w, size_t f, int sl, int nslot, int Ld, int last) {
    uint32_t sp = r->fn_spidx[f];
    int lev = r->fn_slevel[f];
    if (sp == 0 || lev < Ld) return w->pyr[(size_t)sp * nslot + sl];
    if (lev >= last) return 0;
    uint32_t k = sp - 1, cell = k / 3 - (uint32_t)LEVEL_OFF(lev);
    if (!w->prefined[LEVEL_OFF(lev) + cell]) return 0;
    return w->pwav[((LEVEL_OFF(lev) + cell) * 3 + k % 3) * nslot + sl];
}

/* On a quad that is not a parallelogram the functions are h / sqrt(J), and a constant
 * irradiance is not in their span: the orthogonal projection keeps only the part of it
 * that they hold, and its flux falls short of the light's by int (g - Pg)^2 / int g^2 of
 * the light's own, g = sqrt(J) and P the projection on the functions the quad holds
 * (measured on a triangle's part, whose J varies 3 to 1: 1.07% with the root alone, 0.27%
 * with the functions of level 0, 0.068% of level 1; always short). The root coefficient
 * takes the difference, so that the quad receives the flux its samples measured (the
 * sum over the tree's leaves of their mean E J times their area): a point light in a
 * closed furnace then delivers 4 pi I whatever the quality. Linear in the light. */
static void proj_flux_fix(const wrt_relight *r, worker *w, const wrt_gto_quad *gq, const quad_info *q, int sl, int nslot,
                          int Ld, int last, const size_t lstart[PROJ_MAX_LEVEL + 2]) {
    int root = q->root_func;
    if (root < 0 || r->fn_flux[root] <= 0) return;
    double want = 0, have = 0;
    for (int lv = Ld; lv <= last; lv++) /* the leaves: cells sampled and not split */
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            size_t c = LEVEL_OFF(lv) + w->pcells[k];
            if ((w->pstate[c] & VIS_EVAL) && !w->prefined[c]) want += w->pflux[c];
        }
    for (size_t f = gq->func_first; f < (size_t)gq->func_first + gq->func_count; f++)
        if (r->fn_ang[f] == 0 && r->fn_flux[f] != 0) have += proj_coef(r, w, f, sl, nslot, Ld, last) * r->fn_flux[f];
    w->pyr[sl] += (want - have) / r->fn_flux[root];
}

/* Keeps the coefficients whose function exists on the quad (w->pyr: levels above the
 * rule's grid Ld; w->pwav: wavelets of split cells), times the light's colour, in the
 * worker's output (rec counts them). */
static void proj_keep(wrt_relight *r, worker *w, const wrt_gto_quad *gq, const int16_t *slot_of, int nslot, int Ld,
                      int last, const float *col, out_rec *rec) {
    size_t f0 = gq->func_first, fc = gq->func_count;
    for (size_t f = f0; f < f0 + fc; f++) {
        int sl = slot_of[r->fn_ang[f]];
        if (sl < 0) continue;
        double cv = proj_coef(r, w, f, sl, nslot, Ld, last);
        if (cv == 0) continue;
        if (proj_emit(r, w, (uint32_t)f, cv, col) != 0) return;
        rec->count++;
    }
}

/* Projects light ctx->light onto quad qidx's functions (section 5.1), adaptively: every
 * cell of the level rule's grid (r->proj.qlevel) is sampled; cells on a shadow edge are
 * split, level by level, down to the cap. A cell that is not split is a leaf: its function
 * is constant over it, so its finer wavelets are exactly zero and are not stored. The
 * split decisions depend on the light's position and the geometry only (never on
 * intensity or colour), so E stays linear in each light. */
static void project_quad(wrt_relight *r, worker *w, int qidx, void *vctx) {
    proj_ctx *ctx = vctx;
    const wrt_light *l = ctx->light;
    const quad_info *q = &r->qi[qidx];
    int Ld = proj_begin(r, w, qidx, ctx);
    if (Ld < 0) return;
    int cap = relight_projection_cap(r, q);
    int16_t slot_of[NANG];
    proj_setup ps;
    proj_slots(r, q, ctx->lc, slot_of, &ps);
    int nslot = ps.nslot, ebase = nslot - 3 * q->nkang; /* K's slots after E's */
    int local_rule = r->opt.proj_level == 0;
    if (r->opt.proj_reference > 0) { /* every cell of the finest grid */
        Ld = cap;
        local_rule = 0;
        if (r->opt.proj_reference > 1) ps.grid_n = r->opt.proj_reference > 8 ? 8 : r->opt.proj_reference;
        ps.nsamp = ps.grid_n ? ps.grid_n * ps.grid_n : 4;
    }
    if (Ld > cap) Ld = cap;
    GROW(r, w->pval, w->pval_cap, LEVEL_OFF(cap + 1) * nslot);
    GROW(r, w->pwav, w->pwav_cap, LEVEL_OFF(cap) * 3 * nslot + 1);
    if (!q->parallelogram) GROW(r, w->pflux, w->pflux_cap, LEVEL_OFF(cap + 1));
    memset(w->pstate + LEVEL_OFF(Ld), 0, (LEVEL_OFF(cap + 1) - LEVEL_OFF(Ld)) * sizeof(uint32_t));
    memset(w->prefined + LEVEL_OFF(Ld), 0, LEVEL_OFF(cap + 1) - LEVEL_OFF(Ld));
    /* Quads that may shade this one; none: no rays at all. */
    if (r->opt.proj_reference == 0) {
        if (find_occluders(r, w, qidx, ctx->lc) != 0) return;
        if (w->nocc == 0) ps.rays = 0;
    }
    size_t lstart[PROJ_MAX_LEVEL + 2];
    int last;
    int any = proj_sample_tree(r, w, &ps, Ld, cap, local_rule, lstart, &last);
    if (!(any & VIS_LIT)) return;
    proj_combine(w, nslot, Ld, last, lstart);
    /* Levels above the rule's grid: plain Haar analysis of that grid. */
    GROW(r, w->pyr, w->pyr_cap, ((size_t)1 << (2 * Ld)) * nslot);
    relight_haar_analyse(w->pval + LEVEL_OFF(Ld) * nslot, Ld, nslot, w->pyr);
    if (!q->parallelogram && slot_of[0] >= 0)
        proj_flux_fix(r, w, &r->g->quads[qidx], q, slot_of[0], nslot, Ld, last, lstart);
    const float *col = l->color;
    double I0 = slot_of[0] >= 0 ? w->pyr[slot_of[0]] : 0;
    for (int c = 0; c < 3; c++) ctx->root[qidx * 3 + c] = I0 * col[c];
    proj_keep(r, w, &r->g->quads[qidx], slot_of, nslot, Ld, last, col, &r->proj.recs[qidx]);
    if (q->nkang) k_extract(r, w, q, col, ebase, nslot, Ld, last, ctx->kc);
}

/* 0, or -1 if memory ran out (the light stays unprojected). */
int relight_project_light(wrt_relight *r, light_state *ls) {
    for (int t = 0; t < r->nthreads; t++) r->workers[t].on = 0;
    light_c lc = relight_light_consts(&ls->light);
    int sun = lc.sun; /* no position: the culling tests only compare points of the scene */
    r->proj.size = 2 * (r->rt.scene_diag + (sun ? 0 : v3_len(v3_sub(ls->light.pos, r->rt.origin))));
    proj_ctx ctx = {&ls->light, &lc, ls->root, ls->kc};
    /* Levels first (cheap), so that the loop knows its work; bounding cones. */
    double work = 0;
    for (uint32_t q = 0; q < r->g->nquads; q++) {
        relight_sphere_cone(r, &lc, r->qi[q].centre, r->qi[q].radius, &r->proj.cones[q]);
        /* A sun: no falloff, so the rule's distance is infinite and the level is the
         * coarsest the rule allows (proj_min_level's grid); only shadow edges split cells,
         * down to the cap (the finest level the quad's functions have). */
        double dmin = sun ? INFINITY : relight_quad_dist(&r->qi[q], ls->light.pos);
        int L = !sun && ls->light.range > 0 && dmin >= ls->light.range ? -1 : projection_level(r, &r->qi[q], dmin);
        if (L >= 0) work += ldexp(r->opt.proj_reference > 0 ? 4096.0 : 4.0, 2 * L);
        if (L >= 0 && r->opt.proj_level == 0) { /* the rule is applied cell by cell from here */
            int cap = relight_projection_cap(r, &r->qi[q]);
            int lmin = proj_min_level(&r->qi[q]);
            L = cap < lmin ? cap : lmin;
        }
        r->proj.qlevel[q] = (int8_t)L;
    }
    for (uint32_t n = 0; n < r->proj.nonode; n++)
        relight_sphere_cone(r, &lc, r->proj.onode[n].c, r->proj.onode[n].rad, &r->proj.ocones[n]);
    if (ls->last_work > 0) work = ls->last_work; /* the light moves a little: as much as last time */
    for (int t = 0; t < r->nthreads; t++) r->workers[t].nsamples = r->workers[t].noccs = 0;
    relight_parallel_for(r, (int)r->g->nquads, work, project_quad, &ctx);
    for (int t = 0; t < r->nthreads; t++) r->run.n.occluders += r->workers[t].noccs;
    if (atomic_load(&r->upd_oom)) return -1;
    ls->last_work = 0;
    for (int t = 0; t < r->nthreads; t++) ls->last_work += 0.25 * (double)r->workers[t].nsamples; /* ~50 ns each */
    size_t total = 0;
    for (uint32_t q = 0; q < r->g->nquads; q++) total += r->proj.recs[q].count;
    if (total > ls->cap) {
        size_t ci = ls->cap, cv = 3 * ls->cap;
        uint32_t *ni = relight_grow(r, ls->idx, &ci, total, sizeof(uint32_t));
        if (!ni) return -1;
        ls->idx = ni;
        float *nv = relight_grow(r, ls->val, &cv, 3 * ci, sizeof(float));
        if (!nv) return -1;
        ls->val = nv;
        ls->cap = ci;
    }
    size_t k = 0;
    for (uint32_t q = 0; q < r->g->nquads; q++) {
        const out_rec *rec = &r->proj.recs[q];
        if (!rec->count) continue;
        const worker *w = &r->workers[rec->worker];
        memcpy(ls->idx + k, w->oidx + rec->start, rec->count * sizeof(uint32_t));
        memcpy(ls->val + 3 * k, w->oval + 3 * rec->start, rec->count * 3 * sizeof(float));
        k += rec->count;
    }
    ls->n = total;
    ls->projected = ls->have_proj = 1;
    ls->proj_gen++; /* its product (relight_multiply_lights) is made again */
    return 0;
}
