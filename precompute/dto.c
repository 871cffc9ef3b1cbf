/* dto.c: the Direct Transport Operator T by hierarchical refinement (paper 4.3;
 * docs/algorithm.md), for one ordered pair of quads at a time.
 *
 * A link couples a receiver cell (spatial quadtree node of quad R) with a sender cell
 * (node of quad S). The oracle samples the kernel on the link's support and refines
 * the receiver and the sender independently (standard decomposition). Refinement
 * partitions the (R x S) domain: children of a link partition its support, so no leaf
 * is reached twice and every leaf is integrated once (the visited set the paper needs
 * for its basis-function traversal is, here, the link table that the analysis merges
 * into). At a leaf the block of 4 x 4 coefficients (scaling + 3 wavelets of each cell)
 * is integrated: the receiver by stratified quasi-Monte Carlo points, the sender in
 * closed form (Lambert's point-to-polygon form factor of each sender quadrant, times a
 * visibility ray to a stratified point in it when an occluder can lie between the
 * quads). The closed-form inner integral keeps the 1/d^2 singularity of quads that share
 * an edge bounded. Then the Haar analysis is taken to the root in the receiver and in the
 * sender subspace independently: every non-root scaling entry is pushed into its parent
 * link (created if never visited) as (phi_P + s1 psi1_P + s2 psi2_P + s1 s2 psi3_P)/2,
 * so only true entries of the standard basis remain (a link holds 9, 12 or 16 entries).
 *
 * Entry of receiver function r (quad R, spatial Haar h_r, angular root) and sender
 * function s (quad S, h_s, angular root), for a diffuse sender of albedo rho:
 *   T[r][s] = rho/pi * int int h_r(u) h_s(u') V cos cos / d^2 sqrt(J_R J_S) du du'
 * (basis.h's normalisation), so the root entry of two parallelograms is
 * rho F_RS sqrt(A_R / A_S).
 *
 * Glossy materials (paper 4.3.2: angular refinement decided by the BRDF alone, down to
 * its resolution). A glossy quad's functions carry the full angular Haar basis of its
 * material's level L (4^L functions: root and wavelets of levels < L). A link touching a
 * glossy quad holds, for each of its 16 spatial entries, the block over the receiver's
 * and the sender's angular functions (RGB), with
 *   T[r][s] = int int h_r h_s g_r(x<-y) btilde_{g_s}(y->x) V cos cos / (pi d^2) sqrt(J_R J_S)
 * where btilde_g(w_o) = integral f_r(w, w_o) g(M^-1 w) cos dw (bake.c tabulates it per
 * material; a diffuse side has btilde_root = albedo, g = 1). Directions are taken from the
 * receiver sample to the centre of each sender quadrant, so the oracle also refines in
 * space until a sender cell covers at most one receiver angular cell (projected solid
 * angle pi 4^-L) and a receiver cell at most one sender angular cell. Diffuse-diffuse
 * links keep one channel and no angular function at all.
 *
 * The first-bounce operator K (flags bit 2, for a glossy sender S): the same links and
 * integral with btilde_{g_s}(y->x) replaced by the value of the sender's OUTGOING angular
 * Haar function g_s(M_S^-1(y->x)) at the level bake_ctx.klevel gives S's material, one
 * channel, no albedo:
 *   K[r][s] = int int h_r h_s g_r(x<-y) g_s(y->x) V cos cos / (pi d^2) sqrt(J_R J_S)
 * The player projects the direct light reflected by S onto S's outgoing functions with the
 * BRDF at the light's exact direction (c_s, RGB), and K c is then the first bounce of that
 * light, T E_S, without truncating the light's direction to an incident angular cell
 * (formats/GTO_FORMAT.md, "First-bounce operator"). */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <embree3/rtcore.h>

#include "../common/basis.h"
#include "../common/reconstruct.h"
#include "../common/rt_scene.h"
#include "cover.h"
#include "dto.h"

/* ---- Lambert's closed form, clipped to the half-space in front of x ---- */

/* One edge's term of Lambert's sum, a -> b (unit vectors from x): the angle g between
 * them times (a x b).n / |a x b|. An edge that subtends a small angle (tan g = t <= 1/4:
 * most edges of a cell a few cell sizes away) takes g / sin g = P(t^2) / cos g with
 * atan(t) / t's series to t^16 (at most 7.4e-13 of the value off) instead of
 * atan2 and a square root: the arc tangent was a sixth of a maze bake (perf). The
 * reversed edge's term is exactly the negation (a x b and its dot with n change sign,
 * the rest is unchanged), bit for bit. */
static inline __attribute__((always_inline)) double atan_ratio(double t2) { /* atan(t) / t for t^2 = t2 <= 1/16 */
    /* sum over k of (-t2)^k / (2k + 1), k = 0..8, by Estrin's scheme: pairs in x = -t2,
     * then pairs of pairs in x^2 and x^4, four products deep instead of Horner's eight
     * dependent multiply-adds (an edge's latency, not its count, is what costs) */
    double x = -t2, x2 = x * x, x4 = x2 * x2;
    double p01 = 1.0 + x * (1.0 / 3), p23 = 1.0 / 5 + x * (1.0 / 7), p45 = 1.0 / 9 + x * (1.0 / 11),
           p67 = 1.0 / 13 + x * (1.0 / 15);
    double q0 = p01 + x2 * p23, q1 = p45 + x2 * p67;
    return (q0 + x4 * q1) + (x4 * x4) * (1.0 / 17);
}

static inline __attribute__((always_inline)) double ff_edge(wrt_v3 a, wrt_v3 b, wrt_v3 n) {
    wrt_v3 c = v3_cross(a, b);
    double s2 = v3_dot(c, c), d = v3_dot(a, b);
    if (d > 0 && s2 <= 0.0625 * d * d) {
        double r = 1 / d; /* one division, not two */
        return v3_dot(c, n) * atan_ratio(s2 * r * r) * r;
    }
    /* up to twice that angle, by the half angle: tan(g / 2) = sin g / (1 + cos g) = t, so
     * g / sin g = 2 atan(t) / t / (1 + cos g), the same series at the same t (session 23:
     * the edges of 14 to 28 degrees, which went to atan2, in the balance's near cells) */
    double h = 1 + d;
    if (h > 0 && s2 <= 0.0625 * h * h) {
        double r = 1 / h;
        return v3_dot(c, n) * 2 * atan_ratio(s2 * r * r) * r;
    }
    double sl = sqrt(s2);
    if (sl < 1e-300) return 0;
    return atan2(sl, d) * v3_dot(c, n) / sl;
}

/* The form factor from the sum of a polygon's edge terms (both paths below). */
static inline double ff_of_sum(double sum) {
    return fabs(sum) / (2 * WRT_PI);
}

/* A quad seen wholly from the front of x's plane: the clipping below keeps its four
 * corners as they are, so this takes each corner's difference and its dot with n once
 * (not twice) and walks the edges without the general loop's two integer divisions an
 * edge (i + 1) % count: the same operations on the same values, the same bits. Returns
 * -1 where some corner is behind the plane (then the general path clips). */
static inline double ff_point_quad_front(wrt_v3 x, wrt_v3 n, const wrt_v3 *poly) {
    wrt_v3 d[4];
    for (int i = 0; i < 4; i++) {
        d[i] = v3_sub(poly[i], x);
        if (!(v3_dot(d[i], n) >= 0)) return -1;
    }
    for (int i = 0; i < 4; i++) d[i] = v3_norm(d[i]);
    double sum = 0;
    sum += ff_edge(d[0], d[1], n);
    sum += ff_edge(d[1], d[2], n);
    sum += ff_edge(d[2], d[3], n);
    sum += ff_edge(d[3], d[0], n);
    return ff_of_sum(sum);
}

double wrt_ff_point_polygon(wrt_v3 x, wrt_v3 n, const wrt_v3 *poly, int count) {
    if (count == 4) {
        double f = ff_point_quad_front(x, n, poly);
        if (f >= 0) return f;
    }
    wrt_v3 clip[16];
    int nc = 0;
    for (int i = 0; i < count && nc < 14; i++) {
        wrt_v3 a = v3_sub(poly[i], x), b = v3_sub(poly[(i + 1) % count], x);
        double da = v3_dot(a, n), db = v3_dot(b, n);
        if (da >= 0) clip[nc++] = a;
        if ((da >= 0) != (db >= 0)) {
            double t = da / (da - db);
            clip[nc++] = v3_add(a, v3_scale(v3_sub(b, a), t));
        }
    }
    if (nc < 3) return 0;
    /* each corner normalised once (it was twice, once for each of its edges: the same
     * values, half the square roots and divisions) */
    for (int i = 0; i < nc; i++) clip[i] = v3_norm(clip[i]);
    double sum = 0;
    for (int i = 0; i < nc; i++) sum += ff_edge(clip[i], clip[(i + 1) % nc], n);
    return ff_of_sum(sum);
}

/* The form factors from x (normal n) to the four quadrants of a sender cell, given its
 * 3 x 3 corner grid g[row v][column u]: when no corner lies behind x's tangent plane no
 * quadrant is clipped, and the 12 distinct edges are shared by the quadrants (an inner
 * edge is walked once each way), so 9 normalisations and 12 edge terms replace 16 and
 * 16. The sums are taken in wrt_ff_point_polygon's order, so f[] is the same bit for bit.
 * Returns 0, computing nothing, when some corner is behind the plane. */
static int ff_point_quadrants(wrt_v3 x, wrt_v3 n, const wrt_v3 g[3][3], double f[4]) {
    wrt_v3 u[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            wrt_v3 d = v3_sub(g[i][j], x);
            if (!(v3_dot(d, n) >= 0)) return 0;
            u[i][j] = d;
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) u[i][j] = v3_norm(u[i][j]);
    double h[3][2], v[2][3]; /* h[i][j]: g[i][j] -> g[i][j+1]; v[i][j]: g[i][j] -> g[i+1][j] */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 2; j++) h[i][j] = ff_edge(u[i][j], u[i][j + 1], n);
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 3; j++) v[i][j] = ff_edge(u[i][j], u[i + 1][j], n);
    for (int q = 0; q < 4; q++) {
        int cx = q & 1, cy = q >> 1;
        double sum = 0;
        sum += h[cy][cx];
        sum += v[cy][cx + 1];
        sum += -h[cy + 1][cx];
        sum += -v[cy][cx];
        f[q] = fabs(sum) / (2 * WRT_PI);
    }
    return 1;
}

/* ---- per-pair link table ---- */
typedef struct block {
    wrt_node rn, sn;
    size_t data; /* offset of this block's values in pair_ctx.pool */
} block;

typedef struct pair_ctx {
    const bake_ctx *b;
    int r, s;
    int occluded;            /* some quad may lie between R and S */
    int sym;                 /* diffuse pair: links serve both directions (reciprocity) */
    int dual;                /* sym, and a quad has covered parts (cover.c): each direction keeps its
                              * own visibility, channel 0 for R <- S, 1 for S <- R */
    int kmode;               /* the first-bounce operator K: sender's outgoing functions, no albedo */
    double *kval; int *kidx; uint8_t *kseen; int nk; /* K: k_directions' scratch, nang each */
    double rho_max;
    int lr, ls;              /* angular levels of receiver and sender (0: diffuse) */
    int nar, nas, nang, nch; /* angular functions per side, their product, channels */
    size_t bsize;            /* doubles per block: 16 nang nch */
    block *blocks; size_t nblocks, cap;
    double *pool; size_t pool_cap;
    uint64_t *hkeys; uint32_t *hvals; size_t hcap, hcount;
    bake_thread_counters *tc;
    int cancelled;
    int record;              /* keep the leaves for the power balance */
    leaf_rec *leaf; size_t nleaf, leaf_cap;
    double wr, ws;           /* the receiver's and the sender's share weights (refine()) */
} pair_ctx;

/* value (i, j, angular pair a, channel ch) of block bl */
#define BV(pc, bl, i, j, a, ch) (pc)->pool[(bl)->data + ((((size_t)(i) * 4 + (j)) * (pc)->nang + (a)) * (pc)->nch + (ch))]

static uint64_t link_key(wrt_node rn, wrt_node sn) { return ((uint64_t)wrt_node_pack(rn) << 32) | wrt_node_pack(sn); }

static double u01(uint64_t h) { return (double)(h >> 11) * 0x1.0p-53; }

static void hash_grow(pair_ctx *pc) {
    size_t ncap = pc->hcap ? pc->hcap * 2 : 256;
    uint64_t *nk = wrt_xmalloc(ncap * sizeof *nk);
    uint32_t *nv = wrt_xmalloc(ncap * sizeof *nv);
    for (size_t i = 0; i < ncap; i++) nv[i] = UINT32_MAX;
    for (size_t i = 0; i < pc->hcap; i++) {
        if (pc->hvals[i] == UINT32_MAX) continue;
        size_t h = wrt_mix64(pc->hkeys[i]) & (ncap - 1);
        while (nv[h] != UINT32_MAX) h = (h + 1) & (ncap - 1);
        nk[h] = pc->hkeys[i]; nv[h] = pc->hvals[i];
    }
    free(pc->hkeys); free(pc->hvals);
    pc->hkeys = nk; pc->hvals = nv; pc->hcap = ncap;
}

/* Index of the block of link (rn, sn), creating a zero one if needed. Pointers into
 * blocks and pool are invalidated by a creation. */
static size_t get_block(pair_ctx *pc, wrt_node rn, wrt_node sn) {
    if (2 * (pc->hcount + 1) > pc->hcap) hash_grow(pc);
    uint64_t k = link_key(rn, sn);
    size_t h = wrt_mix64(k) & (pc->hcap - 1);
    while (pc->hvals[h] != UINT32_MAX) {
        if (pc->hkeys[h] == k) return pc->hvals[h];
        h = (h + 1) & (pc->hcap - 1);
    }
    if (pc->nblocks == pc->cap) {
        pc->cap = pc->cap ? pc->cap * 2 : 64;
        pc->blocks = wrt_xrealloc(pc->blocks, pc->cap * sizeof *pc->blocks);
    }
    size_t need = (pc->nblocks + 1) * pc->bsize;
    if (need > pc->pool_cap) {
        /* memory: the growth is counted against the bake's budget before it is made; over
         * it the bake is cancelled (the values written from here on are never used) and
         * the last block is reused so the refinement can unwind */
        const bake_ctx *b = pc->b;
        unsigned long long add = (unsigned long long)(need * 2 - pc->pool_cap) * sizeof *pc->pool;
        if (b->pool_bytes && pc->nblocks > 0) {
            unsigned long long now = atomic_fetch_add(b->pool_bytes, add) + add;
            if ((double)now > b->pool_limit) {
                atomic_fetch_sub(b->pool_bytes, add);
                unsigned long long prev = atomic_load(b->pool_refused);
                while (now > prev && !atomic_compare_exchange_weak(b->pool_refused, &prev, now)) {}
                atomic_store(b->cancel, 1);
                pc->cancelled = 1;
                return pc->nblocks - 1;
            }
        } else if (b->pool_bytes) {
            atomic_fetch_add(b->pool_bytes, add);
        }
        pc->pool_cap = need * 2;
        pc->pool = wrt_xrealloc(pc->pool, pc->pool_cap * sizeof *pc->pool);
    }
    block *bl = &pc->blocks[pc->nblocks];
    bl->rn = rn; bl->sn = sn;
    bl->data = pc->nblocks * pc->bsize;
    memset(&pc->pool[bl->data], 0, pc->bsize * sizeof *pc->pool);
    pc->hkeys[h] = k; pc->hvals[h] = (uint32_t)pc->nblocks;
    pc->hcount++;
    return pc->nblocks++;
}

/* 1 if the segment a -> b is blocked by some quad (bake_ctx.h). */
int wrt_bake_occluded(const bake_ctx *b, wrt_v3 a, wrt_v3 bpt) {
    /* Both ends are already lifted off their quads by ray_eps along the normals, so the
     * ray cannot meet its own quads; trimming ray_eps off each end as well let rays
     * through walls thinner than ray_eps when an end lay within ray_eps of the wall's
     * foot (light leaked between two rooms sharing a zero-thickness wall). */
    return wrt_rt_blocked(b->rtc, a, bpt);
}


/* Angular function index <-> (node, type): 0 is the root scaling; then level by level,
 * node by node (row-major), the three wavelets. 4^L functions up to level L. */
void wrt_angular_func(int idx, wrt_node *n, int *type) {
    if (idx == 0) { *n = wrt_node_root(); *type = 0; return; }
    int m = (idx - 1) / 3, t = (idx - 1) % 3 + 1, l = 0;
    while (m >= (1 << (2 * l))) { m -= 1 << (2 * l); l++; }
    wrt_node nn = {(uint8_t)l, (uint16_t)(m % (1 << l)), (uint16_t)(m / (1 << l))};
    *n = nn; *type = t;
}

/* Values of all 4^L angular functions at (a, b); returns how many are non-zero and
 * their indices in idx[] (1 + 3L at most). */
static int angular_values(int L, double a, double b, int *idx, double *val) {
    int k = 0;
    idx[k] = 0; val[k++] = 1;
    int base = 1;
    for (int l = 0; l < L; l++) {
        int side = 1 << l;
        int x = (int)(a * side), y = (int)(b * side);
        if (x >= side) x = side - 1;
        if (y >= side) y = side - 1;
        wrt_node n = {(uint8_t)l, (uint16_t)x, (uint16_t)y};
        for (int t = 1; t <= 3; t++) {
            idx[k] = base + 3 * (y * side + x) + (t - 1);
            val[k++] = wrt_haar2(n, t, a, b);
        }
        base += 3 * side * side;
    }
    return k;
}

#define MAX_RS 64

typedef struct link_samples {
    double G[MAX_RS][4];   /* visible form factor x_k -> sender quadrant q, times 1/sqrt(J_S) */
    double G2[MAX_RS][4];  /* dual links: the same with x_k's side sending (cover.c) */
    double F[MAX_RS][4];   /* the same as a plain form factor (for the oracle) */
    int qr[MAX_RS];        /* receiver quadrant of x_k */
    double jr[MAX_RS];     /* sqrt(J_R) at x_k */
    wrt_v3 d[MAX_RS][4];   /* unit direction x_k -> centre of sender quadrant q */
    wrt_v3 x[MAX_RS];      /* the receiver points */
    double fgeom, fvis;    /* sums of the sampled form factors, all and visible */
} link_samples;

/* Samples the kernel on link (rn, sn). Returns 1 if some geometric transfer was seen
 * but every sample was blocked (mutually invisible supports). */
static int eval_link(pair_ctx *pc, int ri, int si, wrt_node rn, wrt_node sn, link_samples *ls, int ns) {
    const bake_ctx *b = pc->b;
    const wrt_quad *R = &b->quads[ri], *S = &b->quads[si];
    uint64_t h = wrt_mix64(((uint64_t)ri << 32 | (uint32_t)si) ^ wrt_mix64(link_key(rn, sn)));
    double ru = u01(wrt_mix64(h + 1)), rv = u01(wrt_mix64(h + 2)), su = u01(wrt_mix64(h + 3)), sv = u01(wrt_mix64(h + 4));
    double rsz = wrt_node_size(rn), rx0 = wrt_node_x0(rn), ry0 = wrt_node_y0(rn);
    wrt_v3 spoly[4][4], scentre[4];
    double sinvj[4];
    for (int q = 0; q < 4; q++) {
        wrt_node c = wrt_node_child(sn, q & 1, q >> 1);
        wrt_cell_poly(S, c, spoly[q]);
        double cu = wrt_node_x0(c) + 0.5 * wrt_node_size(c), cv = wrt_node_y0(c) + 0.5 * wrt_node_size(c);
        scentre[q] = wrt_quad_point(S, cu, cv);
        sinvj[q] = 1.0 / sqrt(wrt_quad_jacobian(S, cu, cv));
    }
    int per_q = ns / 4, side = per_q == 4 ? 2 : per_q == 16 ? 4 : per_q == 9 ? 3 : 1;
    (void)ru; (void)rv;
    if (side * side != per_q) side = 1, per_q = 1;
    wrt_v3 sgrid[3][3]; /* the sender cell's corners, shared by its quadrants */
    for (int q = 0; q < 4; q++) {
        int cx = q & 1, cy = q >> 1;
        sgrid[cy][cx] = spoly[q][0]; sgrid[cy][cx + 1] = spoly[q][1];
        sgrid[cy + 1][cx + 1] = spoly[q][2]; sgrid[cy + 1][cx] = spoly[q][3];
    }
    int any_geom = 0, any_vis = 0;
    int k = 0;
    ls->fgeom = ls->fvis = 0;
    /* covered points (cover.c): a sender point inside closed geometry is no sample of its
     * cell's visibility (the cell's mean already counts it dark). Where the far side sends
     * (G), a covered target is replaced by another point of its quadrant; where x_k's side
     * sends (G2, dual links), the quadrant's exposed samples stand for it: G2 is scaled by
     * the quadrant's weight over its exposed samples' */
    int redraw = pc->occluded && (!pc->sym || pc->dual) && b->cover && b->cover[si];
    int xcov_test = pc->dual && b->cover[ri];
    int timed = b->clock && b->clock->on; /* WRT_DTO_TIMES: the rays' thread time */
    double wq_all[4] = {0, 0, 0, 0}, wq_exp[4] = {0, 0, 0, 0};
    for (int q = 0; q < 4; q++) {
        int cx = q & 1, cy = q >> 1;
        for (int s = 0; s < per_q; s++, k++) {
            /* 2 x 2 Gauss-Legendre points per receiver quadrant (equal weights): exact for
             * bicubic integrands, where jittered strata left a few percent in the cell
             * distribution test; other sample counts use rotated strata */
            double fu, fv, wq = 1;
            if (side == 2) {
                fu = 0.5 + ((s & 1) ? 0.28867513459481287 : -0.28867513459481287);
                fv = 0.5 + ((s & 2) ? 0.28867513459481287 : -0.28867513459481287);
            } else if (side == 4) {
                /* 4 x 4 Gauss-Legendre: nodes 1/2 +- x/2, weights w/2, scaled so that the
                 * quadrant's weights sum to per_q like the equal-weight rules */
                static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526};
                static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538};
                fu = 0.5 + 0.5 * gx[s % 4];
                fv = 0.5 + 0.5 * gx[s / 4];
                wq = 0.25 * gw[s % 4] * gw[s / 4] * per_q;
            } else {
                fu = (s % side + ru) / side;
                fv = (s / side + rv) / side;
            }
            double u = rx0 + (cx + fu) * 0.5 * rsz, v = ry0 + (cy + fv) * 0.5 * rsz;
            wrt_v3 x = wrt_quad_point(R, u, v);
            ls->qr[k] = q;
            ls->x[k] = x;
            ls->jr[k] = sqrt(wrt_quad_jacobian(R, u, v)) * wq;
            if (pc->dual) {
                wq_all[q] += ls->jr[k];
                pc->tc->cover_x += xcov_test;
                if (!xcov_test || !wrt_bake_covered_uv(b, ri, u, v, v3_mad(x, R->n, b->ray_eps), &pc->tc->cover_exact))
                    wq_exp[q] += ls->jr[k];
            }
            double sd = v3_dot(v3_sub(x, S->p[0]), S->n), fq[4];
            int shared = sd > b->plane_eps && ff_point_quadrants(x, R->n, sgrid, fq);
            for (int t = 0; t < 4; t++) {
                ls->G[k][t] = ls->F[k][t] = ls->G2[k][t] = 0;
                ls->d[k][t] = v3_norm(v3_sub(scentre[t], x));
                if (sd <= b->plane_eps) { pc->tc->rays_skipped_facing++; continue; }
                double f = shared ? fq[t] : wrt_ff_point_polygon(x, R->n, spoly[t], 4);
                pc->tc->samples++;
                if (f <= 0) { pc->tc->rays_skipped_facing++; continue; }
                any_geom = 1;
                ls->fgeom += f;
                if (pc->occluded) {
                    /* a stratified target in the sender quadrant, different per sample */
                    double gu = fmod(((k % 4) + su) / 4.0 + 0.618033988749895 * (k / 4), 1.0);
                    double gv = fmod(((k / 4) % 4 + sv) / 4.0 + 0.754877666246693 * (k % 4), 1.0);
                    wrt_node c = wrt_node_child(sn, t & 1, t >> 1);
                    double tu = wrt_node_x0(c) + gu * wrt_node_size(c), tv = wrt_node_y0(c) + gv * wrt_node_size(c);
                    wrt_v3 y = wrt_quad_point(S, tu, tv);
                    double t0 = timed ? wrt_now() : 0; /* a clock read per ray costs 4% of the phase */
                    int blocked = wrt_bake_occluded(b, v3_mad(x, R->n, b->ray_eps), v3_mad(y, S->n, b->ray_eps));
                    int blocked_far = blocked; /* the visibility where the far side sends */
                    for (int tr = 0; blocked_far && redraw && tr < WRT_COVER_REDRAWS &&
                                     (pc->tc->cover_y++, wrt_bake_covered_uv(b, si, tu, tv, v3_mad(y, S->n, b->ray_eps),
                                                                             &pc->tc->cover_exact));
                         tr++) {
                        gu = fmod(gu + 0.618033988749895, 1.0);
                        gv = fmod(gv + 0.754877666246693, 1.0);
                        tu = wrt_node_x0(c) + gu * wrt_node_size(c);
                        tv = wrt_node_y0(c) + gv * wrt_node_size(c);
                        y = wrt_quad_point(S, tu, tv);
                        blocked_far = wrt_bake_occluded(b, v3_mad(x, R->n, b->ray_eps), v3_mad(y, S->n, b->ray_eps));
                        pc->tc->rays_traced++;
                    }
                    if (pc->dual && blocked && !blocked_far) { any_vis = 1; ls->G[k][t] = f * sinvj[t]; }
                    if (!pc->dual) blocked = blocked_far;
                    if (timed) pc->tc->t_rays += wrt_now() - t0;
                    pc->tc->rays_traced++;
                    if (blocked) continue;
                } else {
                    pc->tc->rays_skipped_unoccluded++;
                }
                any_vis = 1;
                ls->fvis += f;
                ls->F[k][t] = f;
                ls->G[k][t] = ls->G2[k][t] = f * sinvj[t];
            }
        }
    }
    if (pc->dual)
        for (k = 0; k < 4 * per_q; k++) {
            int q = ls->qr[k];
            double sc = wq_exp[q] > 0 ? wq_all[q] / wq_exp[q] : 0;
            for (int t = 0; t < 4; t++) {
                ls->G2[k][t] *= sc;
                any_vis |= ls->G2[k][t] != 0;
            }
        }
    return any_geom && !any_vis;
}

/* K: the mean of (receiver incident function x sender outgoing function) over the
 * directions in which x sees sender quadrant t of cell sn, weighted by the form factor:
 * the quadrant is split (up to 4 times) while a part of it spans more than a quarter of
 * an angular cell of K's level (form factor 4^-L / 4), each part taking the direction to
 * its centre on both sides. One direction for the whole quadrant (T's rule) put a shared
 * edge's grazing directions where the quadrant's centre is: a metal wall's reflection on
 * the floor beside it came out 2-9% low at level 4 (test_bake), and a glossy receiver's
 * incident functions beside an edge it shares with the sender a block of entries 17% low.
 * Accumulates into pc->kval by the block's angular index (receiver index x nas + sender
 * index), listing the indices touched in pc->kidx. */
static void k_dir_add(pair_ctx *pc, wrt_v3 x, const wrt_v3 poly[4], int depth, double *fsum) {
    const wrt_quad *R = &pc->b->quads[pc->r], *S = &pc->b->quads[pc->s];
    double f = wrt_ff_point_polygon(x, R->n, poly, 4);
    if (f <= 0) return;
    if (depth < 4 && f > 0.25 * wrt_pow2(-2 * pc->ls)) {
        wrt_v3 m01 = v3_scale(v3_add(poly[0], poly[1]), 0.5), m12 = v3_scale(v3_add(poly[1], poly[2]), 0.5);
        wrt_v3 m23 = v3_scale(v3_add(poly[2], poly[3]), 0.5), m30 = v3_scale(v3_add(poly[3], poly[0]), 0.5);
        wrt_v3 mc = v3_scale(v3_add(m01, m23), 0.5);
        wrt_v3 sp[4][4] = {{poly[0], m01, mc, m30}, {m01, poly[1], m12, mc}, {mc, m12, poly[2], m23}, {m30, mc, m23, poly[3]}};
        for (int c = 0; c < 4; c++) k_dir_add(pc, x, sp[c], depth + 1, fsum);
        return;
    }
    wrt_v3 y = v3_scale(v3_add(v3_add(poly[0], poly[1]), v3_add(poly[2], poly[3])), 0.25);
    wrt_v3 wdir = v3_norm(v3_sub(x, y));
    double loc[3] = {v3_dot(wdir, S->t), v3_dot(wdir, S->b), v3_dot(wdir, S->n)}, a, bb;
    if (loc[2] < 0) loc[2] = 0;
    wrt_concentric_inv(loc, &a, &bb);
    int sidx[1 + 3 * WRT_K_MAX_LEVEL], ridx[1 + 3 * WRT_MAX_ALEVEL];
    double sv[1 + 3 * WRT_K_MAX_LEVEL], rv[1 + 3 * WRT_MAX_ALEVEL];
    int ns = angular_values(pc->ls, a, bb, sidx, sv), nr = 1;
    ridx[0] = 0; rv[0] = 1;
    if (pc->lr) { /* the receiver's incident functions at the direction x -> y */
        double rl[3] = {-v3_dot(wdir, R->t), -v3_dot(wdir, R->b), -v3_dot(wdir, R->n)}, ra, rb;
        if (rl[2] < 0) rl[2] = 0;
        wrt_concentric_inv(rl, &ra, &rb);
        nr = angular_values(pc->lr, ra, rb, ridx, rv);
    }
    for (int i = 0; i < nr; i++)
        for (int j = 0; j < ns; j++) {
            int ai = ridx[i] * pc->nas + sidx[j];
            if (!pc->kseen[ai]) { pc->kseen[ai] = 1; pc->kidx[pc->nk++] = ai; }
            pc->kval[ai] += f * rv[i] * sv[j];
        }
    *fsum += f;
}

/* The directions of sender quadrant t seen from x: the number of angular indices in
 * pc->kidx, their normalised values in pc->kval (cleared by the caller after use). */
static int k_directions(pair_ctx *pc, wrt_v3 x, wrt_node sn, int t) {
    const wrt_quad *S = &pc->b->quads[pc->s];
    wrt_v3 poly[4];
    wrt_cell_poly(S, wrt_node_child(sn, t & 1, t >> 1), poly);
    double fsum = 0;
    pc->nk = 0;
    k_dir_add(pc, x, poly, 0, &fsum);
    for (int i = 0; i < pc->nk; i++) pc->kval[pc->kidx[i]] = fsum > 0 ? pc->kval[pc->kidx[i]] / fsum : 0;
    return pc->nk;
}

/* Adds the leaf's integral to its block. */
static void integrate_leaf(pair_ctx *pc, wrt_node rn, wrt_node sn, const link_samples *ls, int ns, int swapped) {
    const bake_ctx *b = pc->b;
    const wrt_quad *R = &b->quads[pc->r], *S = &b->quads[pc->s];
    double scale = wrt_pow2((int)sn.level - (int)rn.level) / ns;
    size_t bi = get_block(pc, rn, sn);
    block *bl = &pc->blocks[bi];
    if ((pc->nch == 1 || pc->dual) && !pc->kmode) {
        /* c[i][j] = 2^ls 2^-lr / N sum_k sign_i(qr_k) sqrt(J_R) sum_q sign_j(q) G_kq; with
         * `swapped` the samples were taken on S and the closed form on R: the kernel is
         * symmetric, so the block is the transpose, with the levels exchanged */
        if (swapped) scale = wrt_pow2((int)rn.level - (int)sn.level) / ns;
        /* a dual link (cover.c): G, the far side sending, is channel 0 (R <- S) unless the
         * samples were taken on S; G2 the other channel */
        for (int k = 0; k < ns; k++) {
            int q = ls->qr[k];
            /* the sender side's Haar sums of G (and G2), once a sample: the same sums in the
             * same order as when they were taken for each of the 4 i (4 times over), the same bits */
            double hg[4], hg2[4];
            for (int j = 0; j < 4; j++) {
                double acc = 0;
                for (int t = 0; t < 4; t++) acc += wrt_haar_sign(j, t & 1, t >> 1) * ls->G[k][t];
                hg[j] = acc;
                if (!pc->dual) continue;
                acc = 0;
                for (int t = 0; t < 4; t++) acc += wrt_haar_sign(j, t & 1, t >> 1) * ls->G2[k][t];
                hg2[j] = acc;
            }
            for (int i = 0; i < 4; i++) {
                double si = wrt_haar_sign(i, q & 1, q >> 1) * ls->jr[k] * scale;
                for (int j = 0; j < 4; j++) {
                    if (swapped) BV(pc, bl, j, i, 0, pc->dual) += si * hg[j];
                    else BV(pc, bl, i, j, 0, 0) += si * hg[j];
                    if (!pc->dual) continue;
                    if (swapped) BV(pc, bl, j, i, 0, 0) += si * hg2[j];
                    else BV(pc, bl, i, j, 0, 1) += si * hg2[j];
                }
            }
        }
        return;
    }
    const double *srho = b->rho[pc->s];
    int ridx[1 + 3 * WRT_MAX_ALEVEL];
    double rval[1 + 3 * WRT_MAX_ALEVEL];
    double beta[64 * 3];
    for (int k = 0; k < ns; k++) {
        int q = ls->qr[k];
        for (int t = 0; t < 4; t++) {
            double g = ls->G[k][t];
            if (g == 0) continue;
            wrt_v3 d = ls->d[k][t];
            int nr = 1;
            ridx[0] = 0; rval[0] = 1;
            if (pc->lr) {
                double loc[3] = {v3_dot(d, R->t), v3_dot(d, R->b), v3_dot(d, R->n)}, a, bb;
                if (loc[2] < 0) loc[2] = 0;
                wrt_concentric_inv(loc, &a, &bb);
                nr = angular_values(pc->lr, a, bb, ridx, rval);
            }
            if (pc->kmode) {
                /* K: the sender's outgoing Haar functions at y -> x, one channel, over the
                 * directions in which x sees the quadrant (k_directions) */
                int nk = k_directions(pc, ls->x[k], sn, t);
                for (int i = 0; i < 4; i++) {
                    double si = wrt_haar_sign(i, q & 1, q >> 1) * ls->jr[k] * scale;
                    for (int j = 0; j < 4; j++) {
                        double wij = si * wrt_haar_sign(j, t & 1, t >> 1) * g;
                        double *dst = &BV(pc, bl, i, j, 0, 0);
                        for (int e = 0; e < nk; e++) dst[pc->kidx[e]] += wij * pc->kval[pc->kidx[e]];
                    }
                }
                for (int e = 0; e < nk; e++) { pc->kval[pc->kidx[e]] = 0; pc->kseen[pc->kidx[e]] = 0; }
                continue;
            }
            if (pc->ls) {
                wrt_v3 w = v3_scale(d, -1);
                double loc[3] = {v3_dot(w, S->t), v3_dot(w, S->b), v3_dot(w, S->n)}, a, bb;
                if (loc[2] < 0) loc[2] = 0;
                wrt_concentric_inv(loc, &a, &bb);
                wrt_bake_btilde(b, b->scene->quads[pc->s].material, a, bb, beta);
            } else {
                beta[0] = srho[0]; beta[1] = srho[1]; beta[2] = srho[2];
            }
            for (int i = 0; i < 4; i++) {
                double si = wrt_haar_sign(i, q & 1, q >> 1) * ls->jr[k] * scale;
                for (int j = 0; j < 4; j++) {
                    double w = si * wrt_haar_sign(j, t & 1, t >> 1) * g;
                    for (int ia = 0; ia < nr; ia++) {
                        double wa = w * rval[ia];
                        double *dst = &BV(pc, bl, i, j, ridx[ia] * pc->nas, 0);
                        for (int is = 0; is < pc->nas; is++) {
                            dst[3 * is] += wa * beta[3 * is];
                            dst[3 * is + 1] += wa * beta[3 * is + 1];
                            dst[3 * is + 2] += wa * beta[3 * is + 2];
                        }
                    }
                }
            }
        }
    }
}

/* (max - min) / mean of the Jacobian over cell n of q (bilinear: its extremes are at the
 * corners); 0 for a parallelogram. */
static double jac_spread(const wrt_quad *q, wrt_node n) {
    if (q->parallelogram) return 0;
    double x0 = wrt_node_x0(n), y0 = wrt_node_y0(n), sz = wrt_node_size(n), lo = INFINITY, hi = 0, sum = 0;
    for (int c = 0; c < 4; c++) {
        double j = wrt_quad_jacobian(q, x0 + (c & 1) * sz, y0 + (c >> 1) * sz);
        lo = fmin(lo, j); hi = fmax(hi, j); sum += j;
    }
    return sum > 0 ? 4 * (hi - lo) / sum : 0;
}

static void refine(pair_ctx *pc, wrt_node rn, wrt_node sn) {
    const bake_ctx *b = pc->b;
    if (pc->cancelled || atomic_load(b->cancel)) { pc->cancelled = 1; return; }
    int ns = b->opt.receiver_samples;
    link_samples ls;
    /* Quadrature points go on the smaller cell and the closed form on the larger: a
     * coarse receiver seeing a fine sender cell near a shared edge integrates the peaked
     * point-to-cell form factor badly with 16 points, and those errors do not cancel over
     * receivers, so the operator gained energy (furnace). A diffuse link serves both
     * directions with a symmetric kernel, so its roles can be exchanged freely. */
    int swapped = 0;
    if (pc->sym) {
        double ar = b->quads[pc->r].area * wrt_pow2(-2 * (int)rn.level);
        double as = b->quads[pc->s].area * wrt_pow2(-2 * (int)sn.level);
        swapped = ar > as * (1 + 1e-9);
    }
    int invisible = swapped ? eval_link(pc, pc->s, pc->r, sn, rn, &ls, ns) : eval_link(pc, pc->r, pc->s, rn, sn, &ls, ns);
    if (invisible) { pc->tc->links_invisible++; return; }
    /* The error of stopping here is the kernel's variation that the link's 2 x 2 x 2 x 2
     * block cannot hold: over the receiver, the spread of the point-to-sender form factor
     * within each receiver quadrant; over the sender, the spread between the sender's
     * quadrants seen from one point. Each is weighted by sqrt of the cell's share of its
     * quad's area (its weight in the quad's L2 error) and by the sender's albedo, which
     * keeps the 1/d^2 singularity of shared edges from refining without end (the spread
     * there does not shrink with the cell) and makes the rule independent of scale. */
    double qlo[4] = {INFINITY, INFINITY, INFINITY, INFINITY}, qhi[4] = {0, 0, 0, 0}, vs = 0, fmaxall = 0, fsum = 0;
    for (int k = 0; k < ns; k++) {
        double f = 0, gmin = INFINITY, gmax = 0;
        for (int t = 0; t < 4; t++) {
            f += ls.F[k][t];
            gmin = fmin(gmin, ls.F[k][t]); gmax = fmax(gmax, ls.F[k][t]);
        }
        qlo[ls.qr[k]] = fmin(qlo[ls.qr[k]], f); qhi[ls.qr[k]] = fmax(qhi[ls.qr[k]], f);
        vs = fmax(vs, 4 * (gmax - gmin));
        fmaxall = fmax(fmaxall, f);
        fsum += f;
    }
    double vq = 0;
    for (int q = 0; q < 4; q++) vq = fmax(vq, qhi[q] - qlo[q]);
    /* ... and by the quad's share weight (wrt_depth_weight): a quad that holds less than
     * depth_share of the scene's area weighs its detail by sqrt(its share / depth_share),
     * its weight in the scene's area-weighted L2 error relative to a quad of that share, so
     * that where the spread does not shrink (a shared edge) refinement stops at cells of an
     * absolute size, not at a fixed fraction of each quad however small. */
    double vr = (swapped ? vs : vq) * pc->rho_max * wrt_node_size(rn) * pc->wr;
    double vsn = (swapped ? vq : vs) * pc->rho_max * wrt_node_size(sn) * pc->ws;
    /* A cell whose Jacobian varies (a triangle's part, a general convex quad) cannot hold
     * a constant: its functions are h / sqrt(J), so uniform radiosity is carried as
     * mean(sqrt J) / sqrt(J), off by about half J's relative spread over each cell, and
     * the link moves its light with that tilt. The kernel's spreads above do not see it
     * (two parallel triangles' kernel is smooth), so such cells are also refined while
     * the link's mean form factor times twice the spread is above the threshold
     * (docs/triangles.md: at quality 5, the twin at d = 1 +0.21% -> +0.043%, the shared
     * edge -0.15% -> -0.055%; once the spread, the rule never fired; four times, +0.053% and
     * -0.045% for +29% entries). A parallelogram's spread is 0: its links are as before. */
    if (fsum > 0) {
        double fbar = 2 * fsum / ns * pc->rho_max;
        vr = fmax(vr, fbar * jac_spread(&b->quads[pc->r], rn) * wrt_node_size(rn));
        vsn = fmax(vsn, fbar * jac_spread(&b->quads[pc->s], sn) * wrt_node_size(sn));
    }
    int glossy = pc->lr || pc->ls;
    int maxl = glossy ? b->opt.max_slevel_glossy : b->opt.max_slevel, minl = b->opt.min_slevel;
    /* links that touch a glossy surface use the glossy quality's thresholds (one receiver
     * threshold) when it is below the quality; other links split cells coarser than the
     * display keeps (bake.c) by their own receiver threshold. A link that serves both
     * directions refines both sides by the finer threshold, each side's at its own level */
    double eps_r, eps_s;
    if (glossy && b->opt.glossy_quality != b->opt.quality) {
        eps_r = b->opt.eps_receiver_glossy;
        eps_s = b->opt.eps_sender_glossy;
        if (pc->sym) eps_r = eps_s = fmin(eps_r, eps_s);
    } else {
        eps_r = rn.level < WRT_RECON_KEEP ? b->opt.eps_receiver_coarse : b->opt.eps_receiver;
        eps_s = b->opt.eps_sender;
        if (pc->sym) {
            double eps_rs = sn.level < WRT_RECON_KEEP ? b->opt.eps_receiver_coarse : b->opt.eps_receiver;
            eps_r = fmin(eps_r, eps_s);
            eps_s = fmin(eps_rs, eps_s);
        }
    }
    int ref_r = rn.level < maxl && (vr > eps_r || rn.level < minl);
    int ref_s = sn.level < maxl && (vsn > eps_s || sn.level < minl);
    /* glossy: a sender cell should not cover more than one receiver angular cell, nor a
     * receiver cell more than one sender angular cell (projected solid angle pi 4^-L);
     * weighted like the spreads above, since next to a shared edge a cell of any size
     * covers a large solid angle and no spatial refinement can resolve it */
    if (pc->lr && sn.level < maxl && fmaxall * wrt_node_size(sn) > wrt_pow2(-2 * pc->lr)) ref_s = 1;
    if (pc->ls && rn.level < maxl) {
        const wrt_quad *R = &b->quads[pc->r], *S = &b->quads[pc->s];
        double ar = R->area * wrt_pow2(-2 * (int)rn.level), as = S->area * wrt_pow2(-2 * (int)sn.level);
        if (fsum / ns * ar / as * wrt_node_size(rn) > wrt_pow2(-2 * pc->ls)) ref_r = 1;
    }
    if (!ref_r && !ref_s) {
        pc->tc->links_leaf++;
        integrate_leaf(pc, rn, sn, &ls, ns, swapped);
        if (pc->record) {
            if (pc->nleaf == pc->leaf_cap) {
                pc->leaf_cap = pc->leaf_cap ? 2 * pc->leaf_cap : 64;
                pc->leaf = wrt_xrealloc(pc->leaf, pc->leaf_cap * sizeof *pc->leaf);
            }
            double vis = !pc->occluded ? 1.0 : ls.fgeom > 0 ? ls.fvis / ls.fgeom : 1.0;
            pc->leaf[pc->nleaf++] = (leaf_rec){wrt_node_pack(rn), wrt_node_pack(sn), (float)vis};
        }
        return;
    }
    pc->tc->links_refined++;
    int nr = ref_r ? 4 : 1, nsn = ref_s ? 4 : 1;
    for (int a = 0; a < nr; a++) {
        wrt_node rc = ref_r ? wrt_node_child(rn, a & 1, a >> 1) : rn;
        for (int c = 0; c < nsn; c++) {
            wrt_node sc = ref_s ? wrt_node_child(sn, c & 1, c >> 1) : sn;
            refine(pc, rc, sc);
        }
    }
}

/* Haar analysis to the root in one subspace (side 0: receiver rows, 1: sender columns). */
static void push_up(pair_ctx *pc, int side) {
    int maxl = 0;
    for (size_t i = 0; i < pc->nblocks; i++) {
        int l = side ? pc->blocks[i].sn.level : pc->blocks[i].rn.level;
        if (l > maxl) maxl = l;
    }
    size_t per = (size_t)pc->nang * pc->nch;
    for (int L = maxl; L >= 1; L--) {
        for (size_t i = 0; i < pc->nblocks; i++) {
            block cb = pc->blocks[i];
            wrt_node n = side ? cb.sn : cb.rn;
            if (n.level != L) continue;
            wrt_node p = wrt_node_parent(n);
            int cx = n.x & 1, cy = n.y & 1;
            size_t pi = side ? get_block(pc, cb.rn, p) : get_block(pc, p, cb.sn);
            block *pb = &pc->blocks[pi], *cbp = &pc->blocks[i];
            for (int t = 0; t < 4; t++) {
                double w = 0.5 * wrt_haar_sign(t, cx, cy);
                for (int o = 0; o < 4; o++) {
                    double *dst = side ? &BV(pc, pb, o, t, 0, 0) : &BV(pc, pb, t, o, 0, 0);
                    const double *src = side ? &BV(pc, cbp, o, 0, 0, 0) : &BV(pc, cbp, 0, o, 0, 0);
                    for (size_t a = 0; a < per; a++) dst[a] += w * src[a];
                }
            }
            for (int o = 0; o < 4; o++) {
                double *src = side ? &BV(pc, cbp, o, 0, 0, 0) : &BV(pc, cbp, 0, o, 0, 0);
                memset(src, 0, per * sizeof *src);
            }
        }
    }
}

/* ---- a diffuse pair's compact entries (dto.h's pair_dent) ---- */

#define DENT_LOC_BITS 26
#define DENT_LOC_MASK ((UINT64_C(1) << DENT_LOC_BITS) - 1)
#define DENT_FWD (UINT64_C(1) << 52)
#define DENT_TR (UINT64_C(1) << 53)

/* A function's key within its quad: wrt_fkey's cell and type (bits 16..41), the angular
 * part being the root (bits 0..15 zero). */
static uint64_t dent_loc(wrt_node n, int type) { return wrt_fkey_make(0, n, type, wrt_node_root(), 0) >> 16; }

/* The entries of block bl of a diffuse pair (one channel, no angular function), kept by
 * the same rule as wrt_dto_pair's general loop and in its order, as records: one per
 * receiver and sender function with a kept entry or transposed entry. */
static void emit_dents(pair_ctx *pc, const block *bl, double wfloor, pair_out *out, size_t *cap) {
    const bake_ctx *b = pc->b;
    const double *rho = b->rho[pc->s], *rho_r = b->rho[pc->r];
    int any = 0, anyt = 0;
    for (int ri = 0; ri < 4; ri++) {
        if (ri == 0 && bl->rn.level != 0) continue;
        for (int sj = 0; sj < 4; sj++) {
            if (sj == 0 && bl->sn.level != 0) continue;
            double g = BV(pc, bl, ri, sj, 0, 0), m = 0, mt = 0;
            for (int ch = 0; ch < 3; ch++) m = fmax(m, fabs(g * rho[ch]));
            int fwd = m != 0 && m * wfloor >= b->entry_floor, tr = 0;
            if (pc->sym) {
                for (int ch = 0; ch < 3; ch++) mt = fmax(mt, fabs(g * rho_r[ch]));
                tr = mt != 0 && mt / wfloor >= b->entry_floor;
            }
            if (!fwd && !tr) continue;
            if (out->nd == *cap) {
                *cap = *cap ? 2 * *cap : 64;
                out->d = wrt_xrealloc(out->d, *cap * sizeof *out->d);
            }
            uint64_t keys = dent_loc(bl->rn, ri) | dent_loc(bl->sn, sj) << DENT_LOC_BITS;
            out->d[out->nd++] = (pair_dent){keys | (fwd ? DENT_FWD : 0) | (tr ? DENT_TR : 0), g};
            out->count += (size_t)(fwd + tr);
            any |= fwd;
            anyt |= tr;
        }
    }
    out->links += (uint64_t)(any + anyt);
}

/* The arrays cut to what they hold (they grew by doubling). */
static void pair_shrink(pair_out *o) {
    if (o->d) {
        o->d = wrt_xrealloc(o->d, (o->nd ? o->nd : 1) * sizeof *o->d);
    } else if (o->e) {
        o->e = wrt_xrealloc(o->e, (o->count ? o->count : 1) * sizeof *o->e);
    }
}

const pair_entry *wrt_pair_entries(const bake_ctx *b, const pair_out *o, pair_entry **buf, size_t *cap) {
    if (!o->d) return o->e;
    if (o->count > *cap) {
        *cap = o->count;
        free(*buf);
        *buf = wrt_xmalloc(*cap * sizeof **buf);
    }
    const double *rho = b->rho[o->s], *rho_r = b->rho[o->r];
    uint64_t qr = (uint64_t)(uint32_t)o->r << 42, qs = (uint64_t)(uint32_t)o->s << 42;
    pair_entry *e = *buf;
    size_t n = 0;
    for (size_t i = 0; i < o->nd; i++) {
        const pair_dent *d = &o->d[i];
        uint64_t rk = qr | (d->keys & DENT_LOC_MASK) << 16, sk = qs | (d->keys >> DENT_LOC_BITS & DENT_LOC_MASK) << 16;
        if (d->keys & DENT_FWD) {
            e[n] = (pair_entry){.r = rk, .s = sk};
            for (int ch = 0; ch < 3; ch++) e[n].v[ch] = (float)(d->g * rho[ch]);
            n++;
        }
        if (d->keys & DENT_TR) {
            e[n] = (pair_entry){.r = sk, .s = rk};
            for (int ch = 0; ch < 3; ch++) e[n].v[ch] = (float)(d->g * rho_r[ch]);
            n++;
        }
    }
    return e;
}

void wrt_dto_times_cover(const bake_thread_counters *tc, int nt, size_t np, uint64_t rays) {
    uint64_t cx = 0, cy = 0, ce = 0;
    for (int t = 0; t < nt; t++) { cx += tc[t].cover_x; cy += tc[t].cover_y; ce += tc[t].cover_exact; }
    fprintf(stderr, "dto-times:   %zu pairs, %llu rays, cover tests at %llu receiver and %llu sender points, %llu of "
            "them with rays (the rest by the quads' maps, cover.c)\n", np, (unsigned long long)rays,
            (unsigned long long)cx, (unsigned long long)cy, (unsigned long long)ce);
}

size_t wrt_pair_bytes(const pair_out *o) {
    return o->d ? o->nd * sizeof *o->d : o->count * sizeof *o->e;
}

void wrt_dto_pair(const bake_ctx *b, int r, int s, int flags, bake_thread_counters *tc, pair_out *out) {
    /* a quad with covered parts (cover.c) has its visibility sampled, whatever lies between */
    int cov = b->cover && (b->cover[r] || b->cover[s]);
    pair_ctx pc = {.b = b, .r = r, .s = s, .occluded = (flags & 1) || cov, .tc = tc};
    int sym = (flags & 2) != 0;
    const double *rho = b->rho[s], *rho_r = b->rho[r];
    pc.rho_max = fmax(rho[0], fmax(rho[1], rho[2]));
    if (sym) pc.rho_max = fmax(pc.rho_max, fmax(rho_r[0], fmax(rho_r[1], rho_r[2])));
    pc.sym = sym;
    pc.wr = wrt_depth_weight(b, r);
    pc.ws = wrt_depth_weight(b, s);
    pc.kmode = (flags & 4) != 0;
    pc.lr = b->alevel[b->scene->quads[r].material];
    pc.ls = pc.kmode ? b->klevel[b->scene->quads[s].material] : b->alevel[b->scene->quads[s].material];
    pc.nar = 1 << (2 * pc.lr);
    pc.nas = 1 << (2 * pc.ls);
    pc.nang = pc.nar * pc.nas;
    pc.nch = pc.kmode ? 1 : (pc.lr || pc.ls) ? 3 : 1;
    pc.dual = sym && cov;
    if (pc.dual) pc.nch = 2;
    pc.bsize = 16 * (size_t)pc.nang * pc.nch;
    if (pc.kmode) {
        pc.kval = wrt_xcalloc((size_t)pc.nang, sizeof *pc.kval);
        pc.kidx = wrt_xmalloc((size_t)pc.nang * sizeof *pc.kidx);
        pc.kseen = wrt_xcalloc((size_t)pc.nang, 1);
    }
    memset(out, 0, sizeof *out);
    if (pc.rho_max <= 0 && !pc.ls) return;
    if (pc.ls) pc.rho_max = fmax(pc.rho_max, 1e-3);
    /* leaves are kept for the power balance where the sender is diffuse */
    pc.record = !b->opt.no_balance && !pc.ls;
    refine(&pc, wrt_node_root(), wrt_node_root());
    if (pc.record) {
        out->leaf = pc.leaf; out->nleaf = pc.nleaf;
        out->leaf_dirs = 1 | (sym ? 2 : 0);
        out->occluded = pc.occluded;
        pc.leaf = NULL;
    }
    if (pc.cancelled) { out->cancelled = 1; goto done; }
    push_up(&pc, 0);
    push_up(&pc, 1);
    size_t cap = 0;
    double wfloor = sqrt(b->quads[s].area / b->quads[r].area); /* series.c's weighting */
    wrt_node an[1 << (2 * WRT_K_MAX_LEVEL)];
    int at[1 << (2 * WRT_K_MAX_LEVEL)];
    const double *kbmax = b->kbmax[b->scene->quads[s].material];
    for (int a = 0; a < pc.nar || a < pc.nas; a++) wrt_angular_func(a, &an[a], &at[a]);
    out->r = r; out->s = s;
    /* a diffuse pair's entries are held as compact records (pair_dent) */
    int compact = !pc.kmode && pc.nch == 1;
    size_t dcap = 0;
    for (size_t i = 0; i < pc.nblocks; i++) {
        const block *bl = &pc.blocks[i];
        int any = 0, anyt = 0;
        if (compact) {
            emit_dents(&pc, bl, wfloor, out, &dcap);
            continue;
        }
        for (int ri = 0; ri < 4; ri++) {
            if (ri == 0 && bl->rn.level != 0) continue;
            for (int sj = 0; sj < 4; sj++) {
                if (sj == 0 && bl->sn.level != 0) continue;
                for (int ia = 0; ia < pc.nar; ia++) {
                    for (int is = 0; is < pc.nas; is++) {
                        double v[3];
                        int a = ia * pc.nas + is;
                        double wk = 1;
                        if (pc.kmode) {
                            v[0] = v[1] = v[2] = BV(&pc, bl, ri, sj, a, 0);
                            wk = kbmax[is];
                        } else if (pc.nch == 1 || pc.dual) {
                            double g = BV(&pc, bl, ri, sj, a, 0);
                            for (int ch = 0; ch < 3; ch++) v[ch] = g * rho[ch];
                        } else {
                            for (int ch = 0; ch < 3; ch++) v[ch] = BV(&pc, bl, ri, sj, a, ch);
                        }
                        double m = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
                        if (out->count + 2 > cap) {
                            cap = cap ? 2 * cap : 64;
                            out->e = wrt_xrealloc(out->e, cap * sizeof *out->e);
                        }
                        if (m != 0 && (pc.kmode ? m * wfloor * wk >= b->k_floor : m * wfloor >= b->entry_floor)) {
                            pair_entry *e = &out->e[out->count++];
                            e->r = wrt_fkey_make((uint32_t)r, bl->rn, ri, an[ia], at[ia]);
                            e->s = wrt_fkey_make((uint32_t)s, bl->sn, sj, an[is], at[is]);
                            for (int ch = 0; ch < 3; ch++) e->v[ch] = (float)v[ch];
                            any = 1;
                            if (ia || is) out->angular++;
                        }
                        if (sym) {
                            /* T[s][r] = rho_R K[r][s]: the kernel is symmetric under basis.h's
                             * normalisation, so the transposed entry needs no integral */
                            double g = BV(&pc, bl, ri, sj, a, pc.dual), mt = 0, vt[3];
                            for (int ch = 0; ch < 3; ch++) { vt[ch] = g * rho_r[ch]; mt = fmax(mt, fabs(vt[ch])); }
                            if (mt != 0 && mt / wfloor >= b->entry_floor) {
                                pair_entry *e = &out->e[out->count++];
                                e->r = wrt_fkey_make((uint32_t)s, bl->sn, sj, an[is], at[is]);
                                e->s = wrt_fkey_make((uint32_t)r, bl->rn, ri, an[ia], at[ia]);
                                for (int ch = 0; ch < 3; ch++) e->v[ch] = (float)vt[ch];
                                anyt = 1;
                            }
                        }
                    }
                }
            }
        }
        out->links += any + anyt;
    }
    out->glossy = pc.lr || pc.ls;
    out->kmode = pc.kmode;
    pair_shrink(out);
done:
    if (b->pool_bytes) atomic_fetch_sub(b->pool_bytes, (unsigned long long)pc.pool_cap * sizeof *pc.pool);
    free(pc.blocks); free(pc.pool); free(pc.hkeys); free(pc.hvals); free(pc.leaf);
    free(pc.kval); free(pc.kidx); free(pc.kseen);
}
