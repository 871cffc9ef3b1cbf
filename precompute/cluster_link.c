/* cluster_link.c: the top-down linking of the cluster tree (cluster.h; the rules are
 * described at the top of cluster.c and in docs/clusters.md): culling by boxes and
 * normal cones, the sampled oracle that makes cluster links, and the leaf pairs handed
 * to the per-pair DTO. Depends on cluster.h, Embree 3 and common/threads.h. */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "cluster.h"
#include "dist.h"

#define CL_SAMPLES 8

typedef struct task { uint32_t a, b; } task;

typedef struct sink {
    wrt_clink *l; size_t nl, capl;
    int *pr, *ps; uint8_t *oc; size_t np, capp;
    uint64_t visited, culled, oracle, refused_vis, refused_spread, rays, partial;
    uint64_t occ_tests, occ_nodes; /* WRT_DTO_TIMES: may_occlude calls, tree nodes visited */
    double t_oracle, t_leaf;       /* WRT_DTO_TIMES: thread-seconds */
} sink;

typedef struct lctx {
    const bake_ctx *b;
    const wrt_clusters *cl;
    double sep, spread, eps;
    uint32_t grain;
    task *tasks; size_t nt, capt; /* the serial top's hand-off */
    sink *sinks;
    const int *owner; int rank;   /* wrt-bake-mpi: each task's rank (NULL: all here; dist.h) */
    int timing;                   /* WRT_DTO_TIMES set: the sinks' timers run */
    _Atomic uint64_t (*why)[24];  /* WRT_DTO_TIMES: the pairs' outcomes by log2 of the quads */
    _Atomic uint64_t *why_rays;   /* and the oracle's rays by outcome */
    wrt_v3 *px;                   /* per uniform node: its CL_SAMPLES points (node_points) */
    uint32_t *pq;                 /* and their quads */
} lctx;

/* WRT_DTO_TIMES: what became of the node pairs, by the log2 of their quads: the oracle's
 * outcomes, and the pairs refined before it (several albedos, not separated) or culled */
enum { W_AGREE, W_POWER, W_DROP, W_NONE_FACING, W_BLOCKED_AWAY, W_BLOCKED, W_HIDDEN, W_PARTIAL, W_SPREAD, W_MIXED_ALBEDO, W_NEAR, W_CULLED, W_N };
static const char *why_name[W_N] = {"linked: agree", "linked: power", "dropped: blocked", "refused: none facing",
                                    "refused: blocked, away", "refused: blocked, lost",
                                    "refused: hidden", "refused: partial", "refused: spread",
                                    "refined: albedos", "refined: near", "culled"};
static void tally(const lctx *c, uint32_t a, uint32_t bn, int w, uint64_t rays) {
    if (!c->why) return;
    atomic_fetch_add_explicit(&c->why_rays[w], rays, memory_order_relaxed);
    uint32_t n = c->cl->hi[a] - c->cl->lo[a] + c->cl->hi[bn] - c->cl->lo[bn];
    int l = 0;
    while ((1u << l) < n && l < 23) l++;
    atomic_fetch_add_explicit(&c->why[w][l], 1, memory_order_relaxed);
}

static uint32_t count(const wrt_clusters *cl, uint32_t a) { return cl->hi[a] - cl->lo[a]; }
static int is_leaf(const wrt_clusters *cl, uint32_t a) { return cl->tree.left[a] < 0; }
static double radius(const wrt_clusters *cl, uint32_t a) { return 0.5 * v3_len(v3_sub(cl->bmax[a], cl->bmin[a])); }
static wrt_v3 centre(const wrt_clusters *cl, uint32_t a) { return v3_scale(v3_add(cl->bmax[a], cl->bmin[a]), 0.5); }

/* 1 if every point of B's box lies behind (within plane_eps) every plane of A's quads:
 * max over the boxes of axis . (y - x), plus the cone's slack times the largest distance. */
static int behind(const lctx *c, uint32_t a, uint32_t bn) {
    const wrt_clusters *cl = c->cl;
    wrt_v3 n = cl->axis[a];
    if (v3_len(n) == 0) return 0;
    double m = 0;
    for (int k = 0; k < 3; k++) {
        double nk = k == 0 ? n.x : k == 1 ? n.y : n.z;
        double bmin = k == 0 ? cl->bmin[bn].x : k == 1 ? cl->bmin[bn].y : cl->bmin[bn].z;
        double bmax = k == 0 ? cl->bmax[bn].x : k == 1 ? cl->bmax[bn].y : cl->bmax[bn].z;
        double amin = k == 0 ? cl->bmin[a].x : k == 1 ? cl->bmin[a].y : cl->bmin[a].z;
        double amax = k == 0 ? cl->bmax[a].x : k == 1 ? cl->bmax[a].y : cl->bmax[a].z;
        m += nk > 0 ? nk * (bmax - amin) : nk * (bmin - amax);
    }
    double cw = cl->cosw[a];
    double slack = sqrt(fmax(0, 2 - 2 * cw));
    wrt_v3 lo = v3(fmin(cl->bmin[a].x, cl->bmin[bn].x), fmin(cl->bmin[a].y, cl->bmin[bn].y), fmin(cl->bmin[a].z, cl->bmin[bn].z));
    wrt_v3 hi = v3(fmax(cl->bmax[a].x, cl->bmax[bn].x), fmax(cl->bmax[a].y, cl->bmax[bn].y), fmax(cl->bmax[a].z, cl->bmax[bn].z));
    m += slack * v3_len(v3_sub(hi, lo));
    return m <= c->b->plane_eps;
}

/* Can a quad under node p lie between quads r and s (bake.c's test, on the quads whose
 * boxes meet the shrunk box of r and s)? */
static int occ_query(const lctx *c, sink *k, uint32_t p, wrt_v3 lo, wrt_v3 hi, int r, int s) {
    const wrt_clusters *cl = c->cl;
    k->occ_nodes++;
    const wrt_v3 *a = &cl->bmin[p], *z = &cl->bmax[p];
    if (!(a->x < hi.x && z->x > lo.x && a->y < hi.y && z->y > lo.y && a->z < hi.z && z->z > lo.z)) return 0;
    if (is_leaf(cl, p)) {
        int o = cl->tree.right[p];
        const bake_ctx *b = c->b;
        if (o != r && o != s) k->occ_tests++;
        return o != r && o != s && wrt_bake_may_occlude(b, &b->quads[r], &b->quads[s], &b->quads[o]);
    }
    return occ_query(c, k, (uint32_t)cl->tree.left[p], lo, hi, r, s) ||
           occ_query(c, k, (uint32_t)cl->tree.right[p], lo, hi, r, s);
}

static void leaf_pair(const lctx *c, sink *k, int qa, int qb) {
    const bake_ctx *b = c->b;
    int r = qa < qb ? qa : qb, s = qa < qb ? qb : qa;
    if (!wrt_bake_can_exchange(b, &b->quads[r], &b->quads[s])) { k->culled++; return; }
    wrt_v3 lo = b->quads[r].p[0], hi = lo;
    for (int i = 0; i < 8; i++) {
        wrt_v3 p = i < 4 ? b->quads[r].p[i] : b->quads[s].p[i - 4];
        lo = v3(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
        hi = v3(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
    }
    double e = b->plane_eps;
    int oc = occ_query(c, k, 0, v3_add(lo, v3(e, e, e)), v3_sub(hi, v3(e, e, e)), r, s);
    if (k->np == k->capp) {
        k->capp = k->capp ? 2 * k->capp : 64;
        k->pr = wrt_xrealloc(k->pr, k->capp * sizeof *k->pr);
        k->ps = wrt_xrealloc(k->ps, k->capp * sizeof *k->ps);
        k->oc = wrt_xrealloc(k->oc, k->capp);
    }
    k->pr[k->np] = r; k->ps[k->np] = s; k->oc[k->np] = (uint8_t)(oc | 2); k->np++;
}

static double u01(uint64_t h) { return (double)(h >> 11) * 0x1.0p-53; }

/* CL_SAMPLES area-stratified points of node p and their quads, computed once per node
 * (the oracle meets a node in many pairs: 22M calls at 43,780 elements) */
static void node_points_make(const lctx *c, uint32_t p, wrt_v3 *x, uint32_t *qi) {
    const wrt_clusters *cl = c->cl;
    double a0 = cl->pref[cl->lo[p]], a1 = cl->pref[cl->hi[p]];
    for (int i = 0; i < CL_SAMPLES; i++) {
        uint64_t h = wrt_mix64(((uint64_t)p << 8) ^ (uint64_t)i ^ 0xC1u);
        double t = a0 + (a1 - a0) * (i + u01(h)) / CL_SAMPLES;
        uint32_t lo = cl->lo[p], hi = cl->hi[p] - 1; /* last prefix entry <= t */
        while (lo < hi) {
            uint32_t m = lo + (hi - lo + 1) / 2;
            if (cl->pref[m] <= t) lo = m; else hi = m - 1;
        }
        const wrt_quad *q = &c->b->quads[cl->perm[lo]];
        uint64_t h2 = wrt_mix64(h);
        x[i] = v3_mad(wrt_quad_point(q, u01(h2), u01(wrt_mix64(h2))), q->n, c->b->ray_eps);
        qi[i] = cl->perm[lo];
    }
}

static void node_points_task(size_t p, int th, void *user) {
    (void)th;
    const lctx *c = user;
    if (c->cl->uniform[p]) node_points_make(c, (uint32_t)p, c->px + p * CL_SAMPLES, c->pq + p * CL_SAMPLES);
}

/* node p's points (and their quads' normals) */
static void node_points(const lctx *c, uint32_t p, wrt_v3 *x, wrt_v3 *n) {
    for (int i = 0; i < CL_SAMPLES; i++) {
        x[i] = c->px[(size_t)p * CL_SAMPLES + i];
        n[i] = c->b->quads[c->pq[(size_t)p * CL_SAMPLES + i]].n;
    }
}

static void add_link(sink *k, uint32_t a, uint32_t bn, const float tab[3], const float tba[3]) {
    if (k->nl == k->capl) {
        k->capl = k->capl ? 2 * k->capl : 64;
        k->l = wrt_xrealloc(k->l, k->capl * sizeof *k->l);
    }
    wrt_clink *l = &k->l[k->nl++];
    l->a = a; l->b = bn;
    memcpy(l->tab, tab, sizeof l->tab); memcpy(l->tba, tba, sizeof l->tba);
}

/* The oracle's sampled kernel: kv[i][j] = cos cos / (pi d^2) between point i of a and
 * point j of b, 0 where either faces away or the ray is blocked. Per point, its state:
 * 1 sees some of the other side, 2 faces it but every ray is blocked, 4 faces away from
 * every point of it. *unocc gets the sum of the kernel without visibility. Returns the
 * blocked rays. */
enum { S = CL_SAMPLES, PT_FREE = 1, PT_HIDDEN = 2, PT_AWAY = 4 };

static int sample_kernel(const lctx *c, sink *k, uint32_t a, uint32_t bn, double kv[S][S], double *unocc, int sa[S],
                         int sb[S]) {
    wrt_v3 xa[S], na[S], xb[S], nb[S];
    int facing_a[S] = {0}, facing_b[S] = {0}, free_a[S] = {0}, free_b[S] = {0}, nblk = 0;
    node_points(c, a, xa, na);
    node_points(c, bn, xb, nb);
    for (int i = 0; i < S; i++)
        for (int j = 0; j < S; j++) {
            wrt_v3 d = v3_sub(xb[j], xa[i]);
            double d2 = v3_dot(d, d), ci = v3_dot(na[i], d), cj = -v3_dot(nb[j], d);
            kv[i][j] = 0;
            if (!(ci > 0 && cj > 0 && d2 > 0)) continue; /* one side faces away: no light, no ray */
            facing_a[i]++; facing_b[j]++;
            *unocc += ci * cj / (WRT_PI * d2 * d2);
            k->rays++;
            if (wrt_bake_occluded(c->b, xa[i], xb[j])) { nblk++; continue; } /* ends already lifted */
            free_a[i]++; free_b[j]++;
            kv[i][j] = ci * cj / (WRT_PI * d2 * d2);
        }
    /* a point facing away counts as hidden unless it also faces away from the other
     * node's centre, which gives its quad no share of the link (cluster_ops.c) */
    wrt_v3 ca = centre(c->cl, a), cb = centre(c->cl, bn);
    for (int i = 0; i < S; i++) {
        sa[i] = free_a[i] ? PT_FREE : facing_a[i] || v3_dot(na[i], v3_sub(cb, xa[i])) > 0 ? PT_HIDDEN : PT_AWAY;
        sb[i] = free_b[i] ? PT_FREE : facing_b[i] || v3_dot(nb[i], v3_sub(ca, xb[i])) > 0 ? PT_HIDDEN : PT_AWAY;
    }
    return nblk;
}

/* Largest minus smallest of v[i] over the points whose state st[i] is free, and the
 * largest (the quads of points facing away get no share: cluster_ops.c) */
static double spread_of(const double *v, const int *st, double *hi) {
    double lo = HUGE_VAL, h = 0;
    for (int i = 0; i < S; i++)
        if (st[i] == PT_FREE) { lo = fmin(lo, v[i]); h = fmax(h, v[i]); }
    if (lo > h) lo = h;
    *hi = h;
    return h - lo;
}

/* The oracle: 1 if the pair is done (a cluster link, or no light), 0 to refine.
 * A cluster link is isotropic: every quad of a receives the sampled mean irradiance
 * from b's mean radiosity, visibility included (a mean over the rays, blocked ones 0).
 * Its error, for unit radiosity on the sender, is bounded by the receiver's area times
 * the spread of the per-point irradiances (and the same the other way): it is accepted
 * when that spread is within c->spread of the largest (the kernel agrees, as before) or
 * when the error is at most c->eps of the scene's area (the power criterion: far or
 * small exchanges). A side whose points include both some that see the other and some
 * that do not (hidden, or facing away) would, pushed down uniformly, light quads that
 * get no light (the dark room behind a wall): then only an error of
 * WRT_CLUSTER_EPS_HIDDEN (or c->eps, if smaller) times the scene's area passes. */
static int oracle(const lctx *c, sink *k, uint32_t a, uint32_t bn) {
    const wrt_clusters *cl = c->cl;
    double kv[S][S], fa[S] = {0}, fb[S] = {0}, sum = 0;
    int sa[S], sb[S], ma = 0, mb = 0;
    k->oracle++;
    double unocc = 0;
    uint64_t r0 = k->rays;
    int nblk = sample_kernel(c, k, a, bn, kv, &unocc, sa, sb);
    uint64_t nr = k->rays - r0;
    double aa = cl->tree.area[a], ab = cl->tree.area[bn];
    for (int i = 0; i < S; i++)
        for (int j = 0; j < S; j++) { fa[i] += ab * kv[i][j] / S; fb[j] += aa * kv[i][j] / S; sum += kv[i][j]; }
    for (int i = 0; i < S; i++) { ma |= sa[i]; mb |= sb[i]; }
    double rho = fmax(fmax(cl->rho[a][0], cl->rho[a][1]), cl->rho[a][2]);
    double rhob = fmax(fmax(cl->rho[bn][0], cl->rho[bn][1]), cl->rho[bn][2]);
    double bound = c->eps * cl->tree.area[0];
    if (sum == 0) {
        /* every facing ray blocked: no light, dropped if the light that the 64 rays
         * could have missed through an opening between them (at most the transfer
         * without visibility; with a point facing away, below) is within the bound; else refined, as
         * dropping always loses light (an open box with a plate across it, not closed
         * so no rule restores it: flux 0.986 of the truth dropping every blocked pair,
         * 0.992 so; the maze asset at quality 1: 7,849 leaf pairs against 7,816) */
        double lost = fmax(rho, rhob) * aa * ab * unocc / (S * S);
        int away = (ma & PT_AWAY) || (mb & PT_AWAY);
        if (nblk && away && !c->b->opt.cluster_keep_away) {
            /* some point faces away: it may stand for facing quads the samples missed, so
             * the light the rays could have missed is bounded by the kernel's bound instead,
             * 1 / (pi d^2) at the boxes' distance d. Refining these pairs instead (before
             * session 14, --clusters-keep-away) took most of them down to leaf pairs: 3.4M
             * of the 7.5M oracle calls and 0.46M leaf pairs at 22,224 elements, the same
             * path tracer's error at 5,048 (docs/clusters.md, "The DTO phase's growth") */
            double d2 = 0;
            for (int ax = 0; ax < 3; ax++) {
                double lo_a = ax == 0 ? cl->bmin[a].x : ax == 1 ? cl->bmin[a].y : cl->bmin[a].z;
                double hi_a = ax == 0 ? cl->bmax[a].x : ax == 1 ? cl->bmax[a].y : cl->bmax[a].z;
                double lo_b = ax == 0 ? cl->bmin[bn].x : ax == 1 ? cl->bmin[bn].y : cl->bmin[bn].z;
                double hi_b = ax == 0 ? cl->bmax[bn].x : ax == 1 ? cl->bmax[bn].y : cl->bmax[bn].z;
                double g = fmax(0, fmax(lo_b - hi_a, lo_a - hi_b));
                d2 += g * g;
            }
            if (d2 > 0 && fmax(rho, rhob) * aa * ab / (WRT_PI * d2) <= bound) { tally(c, a, bn, W_DROP, nr); return 1; }
        }
        if (nblk && !away && lost <= bound) { tally(c, a, bn, W_DROP, nr); return 1; }
        tally(c, a, bn, !nblk ? W_NONE_FACING : (ma & PT_AWAY) || (mb & PT_AWAY) ? W_BLOCKED_AWAY : W_BLOCKED, nr);
        k->refused_spread++;
        return 0;
    }
    int mixed = (ma & PT_HIDDEN) || (mb & PT_HIDDEN);
    double ha, hb, da = spread_of(fa, sa, &ha), db = spread_of(fb, sb, &hb);
    double err = fmax(rho * aa * da, rhob * ab * db);
    if (mixed) bound = fmin(c->eps, WRT_CLUSTER_EPS_HIDDEN) * cl->tree.area[0];
    int agree = !mixed && da <= c->spread * ha && db <= c->spread * hb;
    if (!agree && !(err <= bound)) {
        if (mixed || nblk) k->refused_vis++; else k->refused_spread++;
        tally(c, a, bn, mixed ? W_HIDDEN : nblk ? W_PARTIAL : W_SPREAD, nr);
        return 0;
    }
    if (nblk) k->partial++;
    tally(c, a, bn, agree ? W_AGREE : W_POWER, nr);
    double t = sqrt(aa * ab) * sum / (S * S);
    float tab[3], tba[3];
    for (int ch = 0; ch < 3; ch++) { tab[ch] = (float)(cl->rho[bn][ch] * t); tba[ch] = (float)(cl->rho[a][ch] * t); }
    add_link(k, a, bn, tab, tba);
    return 1;
}

static void push_task(lctx *c, uint32_t a, uint32_t bn) {
    if (c->nt == c->capt) {
        c->capt = c->capt ? 2 * c->capt : 256;
        c->tasks = wrt_xrealloc(c->tasks, c->capt * sizeof *c->tasks);
    }
    c->tasks[c->nt++] = (task){a, bn};
}

static int separated(const lctx *c, uint32_t a, uint32_t bn) {
    const wrt_clusters *cl = c->cl;
    return v3_len(v3_sub(centre(cl, a), centre(cl, bn))) >= c->sep * (radius(cl, a) + radius(cl, bn));
}

/* Two disjoint nodes; serial: hand pairs of at most grain quads off as tasks */
static void link_pair(lctx *c, sink *k, uint32_t a, uint32_t bn, int serial) {
    const wrt_clusters *cl = c->cl;
    if (serial && count(cl, a) + count(cl, bn) <= c->grain) { push_task(c, a, bn); return; }
    k->visited++;
    if (behind(c, a, bn) || behind(c, bn, a)) { k->culled++; tally(c, a, bn, W_CULLED, 0); return; }
    int la = is_leaf(cl, a), lb = is_leaf(cl, bn);
    if (la && lb) {
        double t0 = c->timing ? wrt_now() : 0;
        leaf_pair(c, k, cl->tree.right[a], cl->tree.right[bn]);
        if (c->timing) k->t_leaf += wrt_now() - t0;
        return;
    }
    if (c->why && !(cl->uniform[a] && cl->uniform[bn])) tally(c, a, bn, W_MIXED_ALBEDO, 0);
    else if (c->why && !separated(c, a, bn)) tally(c, a, bn, W_NEAR, 0);
    if (cl->uniform[a] && cl->uniform[bn] && separated(c, a, bn)) {
        double t0 = c->timing ? wrt_now() : 0;
        int done = oracle(c, k, a, bn);
        if (c->timing) k->t_oracle += wrt_now() - t0;
        if (done) return;
    }
    int split_a = lb || (!la && radius(cl, a) >= radius(cl, bn));
    if (split_a) {
        link_pair(c, k, (uint32_t)cl->tree.left[a], bn, serial);
        link_pair(c, k, (uint32_t)cl->tree.right[a], bn, serial);
    } else {
        link_pair(c, k, a, (uint32_t)cl->tree.left[bn], serial);
        link_pair(c, k, a, (uint32_t)cl->tree.right[bn], serial);
    }
}

static void link_self(lctx *c, sink *k, uint32_t a, int serial) {
    const wrt_clusters *cl = c->cl;
    if (is_leaf(cl, a)) return;
    if (serial && count(cl, a) <= c->grain) { push_task(c, a, a); return; }
    uint32_t L = (uint32_t)cl->tree.left[a], R = (uint32_t)cl->tree.right[a];
    link_self(c, k, L, serial);
    link_self(c, k, R, serial);
    link_pair(c, k, L, R, serial);
}

static void run_task(size_t i, int th, void *user) {
    (void)th;
    lctx *c = user;
    task t = c->tasks[i];
    if (c->owner && c->owner[i] != c->rank) return; /* another rank's: merged after */
    if (t.a == t.b) link_self(c, &c->sinks[i + 1], t.a, 0);
    else link_pair(c, &c->sinks[i + 1], t.a, t.b, 0);
}

/* wrt-bake-mpi: each task's rank (dist.h), by an estimated cost. A task's node pairs are
 * refined down to leaf pairs where the two nodes are near (their count's product) and
 * end at the oracle where they are far: the product weighted by how large the nodes look
 * from each other, (r_a + r_b)^2 / (d^2 + (r_a + r_b)^2), plus the nodes' sizes; a node
 * with itself, its count squared over two. A first guess, not fitted. */
static int *task_owners(const lctx *c, int nranks) {
    const wrt_clusters *cl = c->cl;
    double *cost = wrt_xmalloc((c->nt ? c->nt : 1) * sizeof *cost);
    for (size_t i = 0; i < c->nt; i++) {
        uint32_t a = c->tasks[i].a, bn = c->tasks[i].b;
        double na = count(cl, a), nb = count(cl, bn);
        if (a == bn) { cost[i] = 0.5 * na * na + na; continue; }
        wrt_v3 d = v3_sub(centre(cl, a), centre(cl, bn));
        double rr = radius(cl, a) + radius(cl, bn), d2 = v3_dot(d, d);
        cost[i] = na * nb * rr * rr / (d2 + rr * rr) + na + nb;
    }
    int *owner = wrt_xmalloc((c->nt ? c->nt : 1) * sizeof *owner);
    wrt_dist_assign(cost, c->nt, nranks, owner);
    free(cost);
    return owner;
}

/* A task's results as bytes (dist.h's records): its 7 counters and its sizes, then its
 * links, then its leaf pairs' receivers, senders and flags. */
static uint64_t sink_size(void *user, size_t i) {
    const sink *k = (const sink *)user + i;
    return 9 * 8 + k->nl * sizeof *k->l + k->np * (2 * sizeof(int) + 1);
}

static void sink_pack(void *user, size_t i, uint8_t *p) {
    const sink *k = (const sink *)user + i;
    uint64_t h[9] = {k->visited, k->culled, k->oracle, k->refused_vis, k->refused_spread, k->rays, k->partial,
                     k->nl, k->np};
    memcpy(p, h, sizeof h);
    p += sizeof h;
    if (k->nl) memcpy(p, k->l, k->nl * sizeof *k->l);
    p += k->nl * sizeof *k->l;
    if (k->np) {
        memcpy(p, k->pr, k->np * sizeof(int));
        memcpy(p + k->np * sizeof(int), k->ps, k->np * sizeof(int));
        memcpy(p + 2 * k->np * sizeof(int), k->oc, k->np);
    }
}

static void sink_unpack(void *user, size_t i, const uint8_t *p, uint64_t len) {
    (void)len;
    sink *k = (sink *)user + i;
    uint64_t h[9];
    memcpy(h, p, sizeof h);
    p += sizeof h;
    *k = (sink){.visited = h[0], .culled = h[1], .oracle = h[2], .refused_vis = h[3], .refused_spread = h[4],
                .rays = h[5], .partial = h[6], .nl = h[7], .np = h[8]};
    k->capl = k->nl;
    k->capp = k->np;
    k->l = k->nl ? wrt_xmalloc(k->nl * sizeof *k->l) : NULL;
    if (k->nl) memcpy(k->l, p, k->nl * sizeof *k->l);
    p += k->nl * sizeof *k->l;
    if (k->np) {
        k->pr = wrt_xmalloc(k->np * sizeof(int));
        k->ps = wrt_xmalloc(k->np * sizeof(int));
        k->oc = wrt_xmalloc(k->np);
        memcpy(k->pr, p, k->np * sizeof(int));
        memcpy(k->ps, p + k->np * sizeof(int), k->np * sizeof(int));
        memcpy(k->oc, p + 2 * k->np * sizeof(int), k->np);
    }
}

wrt_status wrt_clusters_link(const bake_ctx *b, wrt_clusters *cl) {
    if (!b->nq) return WRT_OK;
    lctx c = {.b = b, .cl = cl};
    c.sep = b->opt.cluster_sep > 0 ? b->opt.cluster_sep : WRT_CLUSTER_SEP_DEFAULT;
    c.spread = b->opt.cluster_spread > 0 ? b->opt.cluster_spread : WRT_CLUSTER_SPREAD_DEFAULT;
    c.eps = b->opt.cluster_eps > 0 ? b->opt.cluster_eps : b->opt.cluster_eps < 0 ? 0 : WRT_CLUSTER_EPS_DEFAULT;
    c.grain = (uint32_t)fmax(32, b->nq / 128);
    c.timing = getenv("WRT_DTO_TIMES") != NULL;
    if (c.timing) c.why = wrt_xcalloc(W_N, sizeof *c.why), c.why_rays = wrt_xcalloc(W_N, sizeof *c.why_rays);
    double t_start = wrt_now();
    size_t nn = cl->tree.nnodes;
    c.px = wrt_xmalloc(nn * CL_SAMPLES * sizeof *c.px);
    c.pq = wrt_xmalloc(nn * CL_SAMPLES * sizeof *c.pq);
    wrt_parallel_for(nn, b->opt.threads, node_points_task, &c);
    sink top = {0};
    link_self(&c, &top, 0, 1);
    double t_top = wrt_now();
    /* sinks[0]: the serial top's own results, first; then the tasks' in order */
    c.sinks = wrt_xcalloc(c.nt + 1, sizeof *c.sinks);
    c.sinks[0] = top;
    wrt_bake_dist *d = b->opt.dist;
    int *owner = NULL;
    if (wrt_dist_on(d)) { /* the tasks divided; every rank gets every task's results, in task order */
        owner = task_owners(&c, d->nranks);
        c.owner = owner;
        c.rank = d->rank;
    }
    wrt_parallel_for(c.nt, b->opt.threads, run_task, &c);
    double t_tasks = wrt_now();
    if (c.timing) {
        sink s = {0};
        for (size_t i = 0; i <= c.nt; i++) {
            const sink *k = &c.sinks[i];
            s.t_oracle += k->t_oracle; s.t_leaf += k->t_leaf; s.occ_tests += k->occ_tests;
            s.occ_nodes += k->occ_nodes; s.np += k->np; s.oracle += k->oracle; s.visited += k->visited;
        }
        fprintf(stderr, "dto-times: link top %.3f s (%zu tasks), tasks %.3f s wall; thread-s: oracle %.3f, leaf pairs %.3f "
                "(%llu pairs, %.1f may_occlude tests and %.1f tree nodes a pair); visits %llu, oracle calls %llu\n",
                t_top - t_start, c.nt, t_tasks - t_top, s.t_oracle, s.t_leaf, (unsigned long long)s.np,
                s.np ? (double)s.occ_tests / (double)s.np : 0, s.np ? (double)s.occ_nodes / (double)s.np : 0,
                (unsigned long long)s.visited, (unsigned long long)s.oracle);
        fprintf(stderr, "dto-times:   the node pairs' outcomes by their quads (up to 2^l):\ndto-times:   %-20s", "l");
        for (int l = 1; l < 24; l++) fprintf(stderr, " %7d", l);
        fprintf(stderr, " %11s\n", "rays");
        for (int w = 0; w < W_N; w++) {
            fprintf(stderr, "dto-times:   %-20s", why_name[w]);
            for (int l = 1; l < 24; l++) fprintf(stderr, " %7llu", (unsigned long long)atomic_load(&c.why[w][l]));
            fprintf(stderr, " %11llu\n", (unsigned long long)atomic_load(&c.why_rays[w]));
        }
        free(c.why); free((void *)c.why_rays);
    }
    wrt_status st = WRT_OK;
    if (owner) {
        wrt_dist_items f = {sink_size, sink_pack, sink_unpack, c.sinks + 1};
        st = wrt_dist_merge_items(d, WRT_DIST_DTO, owner, c.nt, &f);
        free(owner);
    }
    size_t nl = 0, np = 0;
    for (size_t i = 0; i <= c.nt; i++) { nl += c.sinks[i].nl; np += c.sinks[i].np; }
    cl->links = wrt_xmalloc((nl ? nl : 1) * sizeof *cl->links);
    cl->pr = wrt_xmalloc((np ? np : 1) * sizeof *cl->pr);
    cl->ps = wrt_xmalloc((np ? np : 1) * sizeof *cl->ps);
    cl->occl = wrt_xmalloc(np ? np : 1);
    for (size_t i = 0; i <= c.nt; i++) {
        sink *k = &c.sinks[i];
        if (k->nl) memcpy(cl->links + cl->nlinks, k->l, k->nl * sizeof *k->l);
        if (k->np) {
            memcpy(cl->pr + cl->np, k->pr, k->np * sizeof *k->pr);
            memcpy(cl->ps + cl->np, k->ps, k->np * sizeof *k->ps);
            memcpy(cl->occl + cl->np, k->oc, k->np);
        }
        cl->nlinks += k->nl; cl->np += k->np;
        cl->pairs_visited += k->visited; cl->pairs_culled += k->culled; cl->oracle_calls += k->oracle;
        cl->oracle_refused_vis += k->refused_vis; cl->oracle_refused_spread += k->refused_spread;
        cl->rays += k->rays; cl->links_partial += k->partial;
        free(k->l); free(k->pr); free(k->ps); free(k->oc);
    }
    free(c.sinks); free(c.tasks); free(c.px); free(c.pq);
    return st;
}
