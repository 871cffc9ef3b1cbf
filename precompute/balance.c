/* balance.c: the power balance of the DTO's diffuse senders (issue 6's furnace).
 *
 * Refinement stops each pair's links at different levels, and a link (S, R) sees the
 * sender's radiosity on S only as far as S's children: the detail of finer sender
 * functions (refined by links to other receivers) reaches R as nothing. The true share
 * of such a zero-mean function is not nothing (the kernel varies over S), and the shares
 * the fine links do deliver are no longer balanced by the coarse ones: the function
 * delivers net power. In a closed box T then gains energy, its dominant eigenvalue
 * exceeds rho by a few tenths of a percent, and 1 / (1 - rho) amplifies that (measured:
 * +4% at rho 0.9, +55% at 0.99, divergence at 0.999).
 *
 * The balance re-derives, for every diffuse sender function j of quad s and every
 * receiver quad r, the power that j delivers to r: the root entry T[root_r][j]. The
 * sender's functions are piecewise constant on the leaves of its function tree (the
 * children of the cells that carry wavelets), so that power is
 *   rho_s sum_f h_j(f) v_r(f),   v_r(f) = sum over the pair's leaf links (S, R) with
 *   S over f of  int_f sqrt(J_S) F(y -> R) / sqrt(J_R) du'
 * where F is Lambert's closed form. Where the cells are near each other the integral
 * takes 2 x 2 Gauss-Legendre points on the smaller of f and R and the closed form on the
 * other (the link integration's own rule), elsewhere the centre of f. The receiver's
 * wavelet rows, the distribution within r, are left as the links computed them.
 *
 * Pairs with a possible occluder keep their links' entries, which sample visibility per
 * point: the closed form times each link's visible share would blur shadow edges across
 * the link's sender cell (measured on cornell, two boxes, at quality 5: 2.59% cell error
 * against the path tracer, 2.39% leaving those pairs alone). What their links cannot
 * hold is added: the transfer of the sender functions strictly inside each link's sender
 * cell, from the closed form at the tree leaves times the link's visible share.
 *
 * In a closed scene (no ray escapes: scene_closed) every function's light is caught,
 * so its column's power over all receivers must be what it emits, rho_s int h_j sqrt(J):
 * the difference is spread over the column's root entries in proportion to their power.
 * That makes the furnace exact, with occluders inside too.
 *
 * Cost: per (unoccluded pair, tree leaf) 1 or 4 closed forms to the whole receiver
 * quad where the links allow it (pair_leaf_values), else 1 or 4 per (leaf link, tree leaf
 * under its sender cell); per (occluded link, tree leaf under it) 1. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/basis.h"
#include "../common/threads.h"
#include "../common/brdf_table.h"
#include "balance.h"
#include "cover.h"
#include "links.h"
#include "dist.h"

#define GL2 0.28867513459481287 /* 2 x 2 Gauss-Legendre: centre +- GL2 x side */


/* one receiving side of a pair, as seen from sender quad s */
typedef struct src_ref { uint32_t pair; uint8_t swap; } src_ref;

typedef struct bal_ctx {
    const bake_ctx *b;
    size_t np;
    const int *pr, *ps;
    const pair_out *out;
    const uint64_t *fkeys;
    uint32_t nf;
    src_ref **refs; size_t *nrefs;  /* per sender quad */
    int closed;                     /* every ray from every quad meets a quad's front */
    wrt_triplet **res; uint64_t *nres;
    const int *owner; int rank;     /* wrt-bake-mpi: each sender's rank (NULL: all here; dist.h) */
    int *order;                     /* the senders in the order the threads take them */
} bal_ctx;

static int cmp_u32(const void *pa, const void *pb) {
    uint32_t a = *(const uint32_t *)pa, b = *(const uint32_t *)pb;
    return a < b ? -1 : a > b;
}

/* index of k in the sorted set, or -1 */
static ptrdiff_t find_u32(const uint32_t *set, size_t n, uint32_t k) {
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (set[mid] < k) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && set[lo] == k ? (ptrdiff_t)lo : -1;
}
static int in_set(const uint32_t *set, size_t n, uint32_t k) { return find_u32(set, n, k) >= 0; }

/* index of the first key >= k in the sorted keys (n if none) */
static uint32_t first_key_at_least(const uint64_t *keys, uint32_t n, uint64_t k) {
    uint32_t a = 0, z = n;
    while (a < z) {
        uint32_t m = a + (z - a) / 2;
        if (keys[m] < k) a = m + 1;
        else z = m;
    }
    return a;
}

double wrt_func_power(const wrt_quad *q, wrt_node n, int type) {
    if (q->parallelogram) return type == 0 ? sqrt(q->area) * wrt_pow2(-(int)n.level) : 0;
    /* sqrt(J) is smooth (J is linear in u and v on a planar quad): 2 x 2 points per quadrant */
    double sz = wrt_node_size(n), x0 = wrt_node_x0(n), y0 = wrt_node_y0(n), acc = 0;
    for (int c = 0; c < 4; c++) {
        double sign = type ? wrt_haar_sign(type, c & 1, c >> 1) : 1;
        for (int k = 0; k < 4; k++) {
            double u = x0 + sz * (0.5 * (c & 1) + 0.25 + ((k & 1) ? 0.5 : -0.5) * GL2);
            double v = y0 + sz * (0.5 * (c >> 1) + 0.25 + ((k & 2) ? 0.5 : -0.5) * GL2);
            acc += sign * sqrt(wrt_quad_jacobian(q, u, v));
        }
    }
    return acc * sz * sz / 16 * wrt_pow2(n.level);
}

double *wrt_power_weights(const bake_ctx *b, const uint64_t *fkeys, uint32_t nf) {
    double *pw = wrt_xcalloc((size_t)nf + 1, sizeof *pw);
    for (uint32_t i = 0; i < nf; i++) {
        uint64_t k = fkeys[i];
        if (wrt_fkey_angular_root(k))
            pw[i] = wrt_func_power(&b->quads[wrt_fkey_quad(k)], wrt_fkey_snode(k), wrt_fkey_stype(k));
    }
    return pw;
}

/* 1 if the ray from o along dir meets the front of a quad other than `self` */
static int caught(const bake_ctx *b, wrt_v3 o, wrt_v3 dir, int self) {
    int hit = wrt_bake_first_hit(b, o, dir);
    return hit >= 0 && hit != self && v3_dot(dir, b->quads[hit].n) < 0;
}



/* int_c sqrt(J_A) F(y -> cell d of quad B) du' over cell c of quad A with 2 x 2 points on c
 * (param measure), without B's Jacobian; poly is cell d's polygon (wrt_cell_poly: the
 * callers evaluate many cells c against one d and make it once) */
static double side_integral(const wrt_quad *A, wrt_node c, const wrt_quad *B, const wrt_v3 poly[4], double plane_eps,
                            int npts) {
    double sz = wrt_node_size(c), x0 = wrt_node_x0(c), y0 = wrt_node_y0(c), acc = 0;
    double off = npts == 1 ? 0 : GL2;
    for (int q = 0; q < npts; q++) {
        double u = x0 + sz * (0.5 + ((q & 1) ? off : -off)), v = y0 + sz * (0.5 + ((q & 2) ? off : -off));
        wrt_v3 y = wrt_quad_point(A, u, v);
        /* y must see B's front: behind B's plane it receives nothing (dto.c's rule) */
        if (v3_dot(v3_sub(y, B->p[0]), B->n) <= plane_eps) continue;
        acc += sqrt(wrt_quad_jacobian(A, u, v)) * wrt_ff_point_polygon(y, A->n, poly, 4);
    }
    return acc * sz * sz / npts;
}

static double jac_at(const wrt_quad *q, wrt_node n) {
    double h = 0.5 * wrt_node_size(n);
    return wrt_quad_jacobian(q, wrt_node_x0(n) + h, wrt_node_y0(n) + h);
}


/* The function tree of quad s: the spatial cells carrying wavelets (of the angular root
 * only, or of any angular function), closed under parents, sorted; and its leaves, the
 * children of tree cells that are not tree cells (the root if the tree is empty), sorted.
 * The quad's functions are piecewise constant on the leaves. */
static void sender_tree(const uint64_t *fkeys, uint32_t nf, int s, int angular_root_only, uint32_t **tree_out,
                        size_t *nt_out, uint32_t **leaves_out, size_t *nl_out) {
    uint64_t lo_key = (uint64_t)s << 42, hi_key = (uint64_t)(s + 1) << 42;
    uint32_t lo, hi;
    lo = first_key_at_least(fkeys, nf, lo_key);
    hi = first_key_at_least(fkeys, nf, hi_key);
    size_t tcap = 16, nt = 0;
    uint32_t *tree = wrt_xmalloc(tcap * sizeof *tree);
    for (uint32_t i = lo; i < hi; i++) {
        uint64_t k = fkeys[i];
        if ((angular_root_only && !wrt_fkey_angular_root(k)) || wrt_fkey_stype(k) == 0) continue;
        for (wrt_node n = wrt_fkey_snode(k);; n = wrt_node_parent(n)) {
            if (nt + 1 > tcap) { tcap *= 2; tree = wrt_xrealloc(tree, tcap * sizeof *tree); }
            tree[nt++] = wrt_node_pack(n);
            if (n.level == 0) break;
        }
    }
    qsort(tree, nt, sizeof *tree, cmp_u32);
    size_t u = 0;
    for (size_t i = 0; i < nt; i++) if (!u || tree[u - 1] != tree[i]) tree[u++] = tree[i];
    nt = u;
    size_t nl = 0;
    uint32_t *leaves = wrt_xmalloc((3 * nt + 1) * sizeof *leaves);
    if (!nt) leaves[nl++] = wrt_node_pack(wrt_node_root());
    for (size_t i = 0; i < nt; i++) {
        wrt_node n = wrt_node_unpack(tree[i]);
        for (int q = 0; q < 4; q++) {
            uint32_t ck = wrt_node_pack(wrt_node_child(n, q & 1, q >> 1));
            if (!in_set(tree, nt, ck)) leaves[nl++] = ck;
        }
    }
    qsort(leaves, nl, sizeof *leaves, cmp_u32);
    *tree_out = tree; *nt_out = nt; *leaves_out = leaves; *nl_out = nl;
}

/* For a link (S, R) of an occluded pair: the transfer of the sender functions strictly
 * inside S, which the link's block cannot hold (it resolves S's children only), from the
 * closed form at the centre of each tree leaf under S times the link's visible share.
 * Returns the integral over n and adds the Haar coefficients of the tree cells strictly
 * inside S to add[] (column 1 + 3 cell + type - 1). */
typedef struct walk_ctx {
    const wrt_quad *Sq, *Rq;
    wrt_node Rn;
    wrt_v3 Rpoly[4];   /* Rn's polygon */
    const uint32_t *tree;
    size_t nt;
    double scale;      /* vis / sqrt(J_R) */
    double plane_eps;
    double *add;
} walk_ctx;

static double walk_inside(const walk_ctx *w, wrt_node n, int inside) {
    ptrdiff_t ti = find_u32(w->tree, w->nt, wrt_node_pack(n));
    if (ti < 0) return w->scale * side_integral(w->Sq, n, w->Rq, w->Rpoly, w->plane_eps, 1);
    double ch[4];
    for (int q = 0; q < 4; q++) ch[q] = walk_inside(w, wrt_node_child(n, q & 1, q >> 1), 1);
    if (inside) {
        double sc = wrt_pow2(n.level);
        for (int t = 1; t <= 3; t++) {
            double a = 0;
            for (int q = 0; q < 4; q++) a += wrt_haar_sign(t, q & 1, q >> 1) * ch[q];
            w->add[1 + 3 * (size_t)ti + (size_t)(t - 1)] += sc * a;
        }
    }
    return ch[0] + ch[1] + ch[2] + ch[3];
}

/* One sender quad's balance in the making, shared by the stages of balance_sender */
typedef struct sender_data {
    bal_ctx *c;
    const bake_ctx *b;
    int s;
    const wrt_quad *Sq;
    const double *rho;
    size_t nt, nl;
    uint32_t *tree, *leaves;
    int *rloc, *recv, nrecv;
    uint8_t *rkeep, *has;
    size_t ncol;
    double *addv, *v, *tc, *cur, *wp, *nw;
    /* the tree's walk, made once a sender (sender_walk): the leaves' places in the order the
     * walk from each tree cell meets them (children 3 to 0, depth first), each tree cell's
     * range of it, and each leaf's centre and square root of its area */
    uint32_t *dfs, (*range)[2];
    wrt_v3 *lcen;
    double *larea, *lside;
} sender_data;

static wrt_v3 cell_centre(const wrt_quad *q, wrt_node n) {
    return wrt_quad_point(q, wrt_node_x0(n) + 0.5 * wrt_node_size(n), wrt_node_y0(n) + 0.5 * wrt_node_size(n));
}

static void walk_fill(sender_data *d, wrt_node n, size_t *len) {
    ptrdiff_t ti = find_u32(d->tree, d->nt, wrt_node_pack(n));
    if (ti < 0) {
        ptrdiff_t li = find_u32(d->leaves, d->nl, wrt_node_pack(n));
        if (li >= 0) d->dfs[(*len)++] = (uint32_t)li;
        return;
    }
    d->range[ti][0] = (uint32_t)*len;
    for (int q = 3; q >= 0; q--) walk_fill(d, wrt_node_child(n, q & 1, q >> 1), len);
    d->range[ti][1] = (uint32_t)*len;
}

/* The walk's tables (sender_data) */
static void sender_walk(sender_data *d) {
    const wrt_quad *Sq = d->Sq;
    d->dfs = wrt_xmalloc((d->nl + 1) * sizeof *d->dfs);
    d->range = wrt_xmalloc((d->nt + 1) * sizeof *d->range);
    d->lcen = wrt_xmalloc((d->nl + 1) * sizeof *d->lcen);
    d->larea = wrt_xmalloc((d->nl + 1) * sizeof *d->larea);
    d->lside = wrt_xmalloc((d->nl + 1) * sizeof *d->lside);
    size_t len = 0;
    if (d->nt) walk_fill(d, wrt_node_root(), &len);
    for (size_t i = 0; i < d->nl; i++) {
        wrt_node e = wrt_node_unpack(d->leaves[i]);
        d->lcen[i] = cell_centre(Sq, e);
        d->larea[i] = Sq->area * wrt_pow2(-2 * (int)e.level);
        d->lside[i] = sqrt(d->larea[i]);
    }
}

/* Stage 1: the sender's receivers (each once; rloc maps a quad to its place) and the
 * per-receiver arrays */
static void sender_receivers(sender_data *d) {
    bal_ctx *c = d->c;
    const bake_ctx *b = d->b;
    int s = d->s;
    size_t nt = d->nt, nl = d->nl;
    /* receivers */
    int *rloc = wrt_xmalloc((size_t)b->nq * sizeof *rloc);
    for (int q = 0; q < b->nq; q++) rloc[q] = -1;
    int nrecv = 0;
    int *recv = wrt_xmalloc(c->nrefs[s] * sizeof *recv);
    for (size_t i = 0; i < c->nrefs[s]; i++) {
        src_ref rf = c->refs[s][i];
        int r = rf.swap ? c->ps[rf.pair] : c->pr[rf.pair];
        if (rloc[r] < 0) { rloc[r] = nrecv; recv[nrecv++] = r; }
    }
    uint8_t *rkeep = wrt_xcalloc((size_t)nrecv + 1, 1);
    size_t ncol = 1 + 3 * nt;
    double *addv = wrt_xcalloc((size_t)nrecv * ncol, sizeof *addv); /* occluded pairs: what the links miss */
    double *v = wrt_xcalloc((size_t)nrecv * nl, sizeof *v);  /* per receiver: best rule */
    d->rloc = rloc; d->recv = recv; d->nrecv = nrecv; d->rkeep = rkeep; d->ncol = ncol; d->addv = addv; d->v = v;
}

/* One evaluation of an unoccluded pair's leaf link (S, R) at a cell e (a tree leaf under
 * S, or S itself inside a leaf): the leaf's place, R, e, the link's visible share and how
 * it is integrated (EVAL_FAR: the closed form at e's centre; EVAL_ON_E: 2 x 2 points on e;
 * EVAL_ON_R: 2 x 2 points on R). A leaf's links are also marked EVAL_ALONE, taken one by
 * one, where one has S inside the leaf or a visible share under 1. */
enum { EVAL_FAR = 1, EVAL_ON_E = 2, EVAL_ON_R = 4, EVAL_ALONE = 8 };
typedef struct { uint32_t li, rn, e; float vis; uint8_t how; } leaf_eval;
typedef struct { leaf_eval *a; size_t n, cap; double *cover; uint8_t *how; uint8_t *done; } eval_list;

/* The receiver's share of the leaf link (S, R) at cell e: 2 x 2 points where the cells are
 * near each other, on the smaller of the two (int_R sqrt(J_R) F(x -> e) du / sqrt(J_S)
 * when that is the receiver cell); elsewhere one point at the centre of e for every link,
 * so that at that point the closed forms of all links sum to the covered share. (Until
 * session 23 the centre's closed form was taken for the near cells too and then not
 * used: a seventh of the balance's closed forms on the 12 x 12 maze, 10.75M of 80.6M.) */
static uint8_t eval_how(wrt_v3 ce, double ae, double se, wrt_v3 cR, double aR, double sR) {
    if (v3_len(v3_sub(ce, cR)) >= 3 * (se + sR)) return EVAL_FAR;
    return ae > aR * (1 + 1e-9) ? EVAL_ON_R : EVAL_ON_E;
}

static double eval_one(const bake_ctx *b, const wrt_quad *Sq, wrt_node e, const wrt_quad *Rq, wrt_node Rn, uint8_t how) {
    wrt_v3 poly[4];
    if (how == EVAL_ON_R) {
        wrt_cell_poly(Sq, e, poly);
        return side_integral(Rq, Rn, Sq, poly, b->plane_eps, 4) / sqrt(jac_at(Sq, e));
    }
    wrt_cell_poly(Rq, Rn, poly);
    return side_integral(Sq, e, Rq, poly, b->plane_eps, how == EVAL_ON_E ? 4 : 1) / sqrt(jac_at(Rq, Rn));
}

/* An unoccluded pair's leaf values (sender_leaf_values), added to vr. Lambert's closed
 * form is additive over polygons, and for a fixed leaf e the receiver cells R of the
 * links whose sender cell holds e tile the receiver quad (the links tile S x R). So where
 * every link at e is integrated on e's side (far, or near with the points on e), each has
 * the visible share 1 and the receiver is a parallelogram (one Jacobian), their sum is the
 * closed form to the whole receiver quad, taken once: at e's centre where all are far,
 * else at the 2 x 2 points on e for all of them (the far ones then get the near rule's
 * points, no less exact). On the 12 x 12 maze that is 8.1M closed forms instead of 63.7M,
 * and 10,852 (pair, leaf) groups out of 3.8M left to the links one by one (a link
 * integrated on the receiver's side). The tiling is checked: the links' receiver cells
 * at e must cover exactly the quad's parameter area (a sum of powers of 1/4, exact). */
static void pair_leaf_values(sender_data *d, const pair_out *po, int swap, const wrt_quad *Rq, double *vr,
                             eval_list *ev) {
    const bake_ctx *b = d->b;
    const wrt_quad *Sq = d->Sq;
    size_t nt = d->nt, nl = d->nl;
    const uint32_t *tree = d->tree;
    ev->n = 0;
    for (size_t k = 0; k < po->nleaf; k++) {
        const leaf_rec *lr = &po->leaf[k];
        if (lr->vis <= 0) continue;
        wrt_node Sn = wrt_node_unpack(swap ? lr->rn : lr->sn), Rn = wrt_node_unpack(swap ? lr->sn : lr->rn);
        wrt_v3 cR = cell_centre(Rq, Rn);
        double aR = Rq->area * wrt_pow2(-2 * (int)Rn.level), sR = sqrt(aR), cover = wrt_pow2(-2 * (int)Rn.level);
        ptrdiff_t ti = find_u32(tree, nt, wrt_node_pack(Sn));
        /* evaluation cells: the tree leaves under Sn (the walk's range), or Sn itself
         * inside a leaf (the deepest ancestor whose parent is a tree cell) */
        uint32_t i0 = 0, i1 = 0, lone = 0;
        if (ti >= 0) {
            i0 = d->range[ti][0];
            i1 = d->range[ti][1];
        } else {
            wrt_node a = Sn;
            while (a.level > 0 && !in_set(tree, nt, wrt_node_pack(wrt_node_parent(a)))) a = wrt_node_parent(a);
            ptrdiff_t lpos = find_u32(d->leaves, nl, wrt_node_pack(a));
            if (lpos < 0) continue;
            lone = (uint32_t)lpos;
            i1 = 1;
        }
        for (uint32_t i = i0; i < i1; i++) {
            uint32_t li, ek;
            uint8_t how;
            if (ti >= 0) {
                li = d->dfs[i];
                ek = d->leaves[li];
                how = eval_how(d->lcen[li], d->larea[li], d->lside[li], cR, aR, sR);
            } else { /* e = Sn, inside the leaf: never merged */
                double ae = Sq->area * wrt_pow2(-2 * (int)Sn.level);
                li = lone;
                ek = wrt_node_pack(Sn);
                how = eval_how(cell_centre(Sq, Sn), ae, sqrt(ae), cR, aR, sR);
            }
            if (ev->n == ev->cap) {
                ev->cap = ev->cap ? 2 * ev->cap : 256;
                ev->a = wrt_xrealloc(ev->a, ev->cap * sizeof *ev->a);
            }
            ev->a[ev->n++] = (leaf_eval){li, wrt_node_pack(Rn), ek, lr->vis, how};
            if (ti < 0 || lr->vis != 1) how |= EVAL_ALONE; /* not merged */
            ev->how[li] |= how;
            ev->cover[li] += cover;
        }
    }
    wrt_v3 rpoly[4];
    wrt_cell_poly(Rq, wrt_node_root(), rpoly);
    double jq = sqrt(Rq->area);
    for (size_t i = 0; i < ev->n; i++) {
        const leaf_eval *x = &ev->a[i];
        uint32_t li = x->li;
        uint8_t how = ev->how[li];
        wrt_node e = wrt_node_unpack(x->e);
        if (Rq->parallelogram && !(how & (EVAL_ON_R | EVAL_ALONE)) && ev->cover[li] == 1.0) {
            if (!ev->done[li]) {
                ev->done[li] = 1;
                vr[li] += side_integral(Sq, e, Rq, rpoly, b->plane_eps, (how & EVAL_ON_E) ? 4 : 1) / jq;
            }
            continue;
        }
        vr[li] += x->vis * eval_one(b, Sq, e, Rq, wrt_node_unpack(x->rn), x->how);
    }
    for (size_t i = 0; i < ev->n; i++) { /* cleared for the next pair */
        uint32_t li = ev->a[i].li;
        ev->how[li] = 0;
        ev->cover[li] = 0;
        ev->done[li] = 0;
    }
}

/* Stage 2: per receiver, the value of each leaf under the sender (unoccluded pairs), or
 * what the links miss inside their cells (occluded ones) */
static void sender_leaf_values(sender_data *d) {
    bal_ctx *c = d->c;
    const bake_ctx *b = d->b;
    int s = d->s;
    const wrt_quad *Sq = d->Sq;
    size_t nt = d->nt, nl = d->nl, ncol = d->ncol;
    const uint32_t *tree = d->tree;
    const int *rloc = d->rloc;
    uint8_t *rkeep = d->rkeep;
    double *addv = d->addv, *v = d->v;
    eval_list evl = {.cover = wrt_xcalloc(nl + 1, sizeof(double)), .how = wrt_xcalloc(nl + 1, 1),
                     .done = wrt_xcalloc(nl + 1, 1)}, *ev = &evl;
    for (size_t i = 0; i < c->nrefs[s]; i++) {
        src_ref rf = c->refs[s][i];
        const pair_out *po = &c->out[rf.pair];
        int r = rf.swap ? c->ps[rf.pair] : c->pr[rf.pair];
        const wrt_quad *Rq = &b->quads[r];
        double *vr = &v[(size_t)rloc[r] * nl];
        if (po->occluded) {
            rkeep[rloc[r]] = 1;
            walk_ctx w = {.Sq = Sq, .Rq = Rq, .tree = tree, .nt = nt, .plane_eps = b->plane_eps,
                          .add = &addv[(size_t)rloc[r] * ncol]};
            for (size_t k = 0; k < po->nleaf; k++) {
                const leaf_rec *lr = &po->leaf[k];
                wrt_node Sn = wrt_node_unpack(rf.swap ? lr->rn : lr->sn);
                if (lr->vis <= 0 || !in_set(tree, nt, wrt_node_pack(Sn))) continue;
                w.Rn = wrt_node_unpack(rf.swap ? lr->sn : lr->rn);
                wrt_cell_poly(Rq, w.Rn, w.Rpoly);
                w.scale = lr->vis / sqrt(jac_at(Rq, w.Rn));
                walk_inside(&w, Sn, 0);
            }
            continue;
        }
        pair_leaf_values(d, po, rf.swap, Rq, vr, ev);
    }
    free(evl.a); free(evl.cover); free(evl.how); free(evl.done);
}

/* Stage 3: the Haar analysis of the leaf values over the sender's tree, per receiver */
static void sender_analysis(sender_data *d) {
    size_t nt = d->nt, nl = d->nl, ncol = d->ncol;
    const uint32_t *tree = d->tree, *leaves = d->leaves;
    int nrecv = d->nrecv;
    const double *v = d->v;
    /* Haar analysis over the tree: per receiver and for the total. Columns: the root and
     * the three wavelets of each tree cell. Sums over cells are built bottom-up through a
     * map cell -> sum (tree cells and leaves, sorted). */
    double *tc = wrt_xcalloc(ncol * ((size_t)nrecv + 1), sizeof *tc); /* [receiver][column] */
    size_t nall = nt + nl;
    uint32_t *all = wrt_xmalloc((nall + 1) * sizeof *all);
    memcpy(all, tree, nt * sizeof *all);
    memcpy(all + nt, leaves, nl * sizeof *all);
    qsort(all, nall, sizeof *all, cmp_u32);
    double *sum = wrt_xmalloc((nall + 1) * sizeof *sum);
    /* the places in `all` of each leaf, of each tree cell and of its children (-1: none),
     * found once for all receivers */
    size_t *lpos = wrt_xmalloc((nl + 1) * sizeof *lpos);
    ptrdiff_t (*cpos)[5] = wrt_xmalloc((nt + 1) * sizeof *cpos);
    for (size_t i = 0; i < nl; i++) lpos[i] = (size_t)find_u32(all, nall, leaves[i]);
    for (size_t ti = 0; ti < nt; ti++) {
        wrt_node n = wrt_node_unpack(tree[ti]);
        for (int q = 0; q < 4; q++) cpos[ti][q] = find_u32(all, nall, wrt_node_pack(wrt_node_child(n, q & 1, q >> 1)));
        cpos[ti][4] = find_u32(all, nall, tree[ti]);
    }
    ptrdiff_t rpos = nt ? find_u32(all, nall, wrt_node_pack(wrt_node_root())) : -1;
    for (int ri = 0; ri < nrecv; ri++) {
        const double *src = &v[(size_t)ri * nl];
        double *out = &tc[(size_t)ri * ncol];
        for (size_t i = 0; i < nall; i++) sum[i] = 0;
        for (size_t i = 0; i < nl; i++) sum[lpos[i]] = src[i];
        /* tree cells deepest first: packed keys sort by level (top bits) */
        for (size_t ti = nt; ti-- > 0;) {
            double ch[4];
            for (int q = 0; q < 4; q++) ch[q] = cpos[ti][q] >= 0 ? sum[cpos[ti][q]] : 0;
            sum[cpos[ti][4]] = ch[0] + ch[1] + ch[2] + ch[3];
            double scale = wrt_pow2(wrt_node_unpack(tree[ti]).level);
            for (int t = 1; t <= 3; t++) {
                double w = 0;
                for (int q = 0; q < 4; q++) w += wrt_haar_sign(t, q & 1, q >> 1) * ch[q];
                out[1 + 3 * ti + (t - 1)] = scale * w;
            }
        }
        out[0] = nt ? sum[rpos] : src[0];
    }
    free(lpos); free(cpos);
    free(sum); free(all);
    d->tc = tc;
}

/* What sender_emitted below reads of the pairs' entries, whatever the pair (a superset:
 * it also checks the quads and the sender's node) */
int wrt_balance_reads_entry(const bake_ctx *b, const pair_entry *e) {
    if (!wrt_fkey_angular_root(e->s)) return 0;
    uint32_t q = wrt_fkey_quad(e->r);
    if (e->r == wrt_fkey_make(q, wrt_node_root(), 0, wrt_node_root(), 0)) return 1;
    return !b->quads[q].parallelogram && wrt_fkey_angular_root(e->r);
}

/* Stage 4: the root entries the pairs emitted, and the power of the wavelet rows */
static void sender_emitted(sender_data *d) {
    bal_ctx *c = d->c;
    const bake_ctx *b = d->b;
    int s = d->s;
    size_t nt = d->nt, ncol = d->ncol;
    const uint32_t *tree = d->tree;
    const int *rloc = d->rloc;
    int nrecv = d->nrecv;
    /* the root entries the pairs emitted */
    double *cur = wrt_xcalloc((size_t)nrecv * ncol * 3, sizeof *cur);
    double *wp = wrt_xcalloc((size_t)nrecv * ncol * 3, sizeof *wp); /* wavelet rows' power */
    uint8_t *has = wrt_xcalloc((size_t)nrecv * ncol + 1, 1);
    for (size_t i = 0; i < c->nrefs[s]; i++) {
        src_ref rf = c->refs[s][i];
        int r = rf.swap ? c->ps[rf.pair] : c->pr[rf.pair];
        size_t ri = (size_t)rloc[r];
        uint64_t rootr = wrt_fkey_make((uint32_t)r, wrt_node_root(), 0, wrt_node_root(), 0);
        const pair_out *po = &c->out[rf.pair];
        const wrt_quad *Rq = &b->quads[r];
        for (size_t k = 0; k < po->count; k++) {
            const pair_entry *e = &po->e[k];
            if (wrt_fkey_quad(e->r) != (uint32_t)r || wrt_fkey_quad(e->s) != (uint32_t)s || !wrt_fkey_angular_root(e->s))
                continue;
            int wavelet_row = e->r != rootr;
            /* a general quad's wavelet rows carry power too (wrt_func_power), which the
             * root entry must leave room for; a parallelogram's carry none */
            if (wavelet_row && (Rq->parallelogram || !wrt_fkey_angular_root(e->r))) continue;
            size_t j = 0;
            int st = wrt_fkey_stype(e->s);
            if (st) {
                uint32_t ck = wrt_node_pack(wrt_fkey_snode(e->s));
                ptrdiff_t p = find_u32(tree, nt, ck);
                if (p < 0) continue;
                j = 1 + 3 * (size_t)p + (size_t)(st - 1);
            } else if (wrt_fkey_snode(e->s).level != 0) {
                continue;
            }
            if (wavelet_row) {
                double pwr = wrt_func_power(Rq, wrt_fkey_snode(e->r), wrt_fkey_stype(e->r));
                for (int ch = 0; ch < 3; ch++) wp[(ri * ncol + j) * 3 + ch] += pwr * e->v[ch];
                continue;
            }
            has[ri * ncol + j] = 1;
            for (int ch = 0; ch < 3; ch++) cur[(ri * ncol + j) * 3 + ch] += e->v[ch];
        }
    }
    d->cur = cur; d->wp = wp; d->has = has;
}

/* Stage 5: the new root entries from the analysis (occluded pairs keep the links' own) */
static void sender_new_entries(sender_data *d) {
    const bake_ctx *b = d->b;
    const wrt_quad *Sq = d->Sq;
    const double *rho = d->rho;
    size_t ncol = d->ncol;
    const int *recv = d->recv;
    int nrecv = d->nrecv;
    const uint8_t *rkeep = d->rkeep, *has = d->has;
    const double *tc = d->tc, *addv = d->addv, *cur = d->cur;
    /* new root entries: rho_s times the analysis, dropped under the entry floor; where an
     * occluder may lie between, the links' own entries stay (see the top) */
    double *nw = wrt_xcalloc((size_t)nrecv * ncol * 3, sizeof *nw);
    double floor_ = b->entry_floor;
    for (int ri = 0; ri < nrecv; ri++) {
        double wfloor = sqrt(Sq->area / b->quads[recv[ri]].area);
        for (size_t j = 0; j < ncol; j++) {
            double t = tc[(size_t)ri * ncol + j], *o = &nw[((size_t)ri * ncol + j) * 3];
            if (rkeep[ri]) {
                /* the links' own entry, plus what they miss of functions inside their cells */
                double ad = addv[(size_t)ri * ncol + j], ma = fabs(ad) * fmax(rho[0], fmax(rho[1], rho[2]));
                int keep = has[(size_t)ri * ncol + j] || ma * wfloor >= floor_;
                for (int ch = 0; ch < 3; ch++) o[ch] = cur[((size_t)ri * ncol + j) * 3 + ch] + (keep ? rho[ch] * ad : 0);
                continue;
            }
            double m = fabs(t) * fmax(rho[0], fmax(rho[1], rho[2]));
            if (m * wfloor >= floor_) for (int ch = 0; ch < 3; ch++) o[ch] = rho[ch] * t;
        }
    }
    d->nw = nw;
}

/* Stage 6: in a closed scene, each column's power made what its function emits */
static void sender_power(sender_data *d) {
    bal_ctx *c = d->c;
    const bake_ctx *b = d->b;
    const wrt_quad *Sq = d->Sq;
    const double *rho = d->rho;
    size_t ncol = d->ncol;
    const uint32_t *tree = d->tree;
    const int *recv = d->recv;
    int nrecv = d->nrecv;
    const uint8_t *rkeep = d->rkeep;
    const double *tc = d->tc, *wp = d->wp;
    double *nw = d->nw;
    /* in a closed scene, each column's power over all receivers made what the function
     * emits: the difference spread over its kept root entries in proportion to their
     * power. (In an open one the per-receiver values stand: pulling them toward a
     * sender-side total, sampled on the sender's leaves, cost the 1-degree wedge 0.65
     * points and the right angle 0.05, near the shared edge where that rule is weakest.) */
    int closed = c->closed;
    double *wroot = wrt_xmalloc(((size_t)nrecv + 1) * sizeof *wroot);
    for (int ri = 0; ri < nrecv; ri++) wroot[ri] = wrt_func_power(&b->quads[recv[ri]], wrt_node_root(), 0);
    for (size_t j = 0; j < ncol; j++) {
        double want[3], have[3] = {0, 0, 0}, wsum = 0;
        wrt_node jn = j ? wrt_node_unpack(tree[(j - 1) / 3]) : wrt_node_root();
        double emitted = wrt_func_power(Sq, jn, j ? (int)((j - 1) % 3) + 1 : 0);
        for (int ch = 0; ch < 3; ch++) want[ch] = rho[ch] * emitted;
        for (int ri = 0; ri < nrecv; ri++) {
            double wr = wroot[ri];
            const double *o = &nw[((size_t)ri * ncol + j) * 3], *w = &wp[((size_t)ri * ncol + j) * 3];
            if (rkeep[ri] && !closed) continue;
            for (int ch = 0; ch < 3; ch++) have[ch] += wr * o[ch] + w[ch];
            wsum += wr * fabs(o[0] + o[1] + o[2]);
        }
        if (!(wsum > 0)) {
            /* every share fell under the floor: a quad far smaller than all it sees. Its
             * root column is all the light it sends, so it keeps its shares whatever their
             * size; a wavelet column's power is a rounding residue and is let go */
            if (j) continue;
            for (int ri = 0; ri < nrecv; ri++) {
                if (rkeep[ri]) continue;
                double wr = wroot[ri], t = tc[(size_t)ri * ncol + j];
                double *o = &nw[((size_t)ri * ncol + j) * 3];
                for (int ch = 0; ch < 3; ch++) { o[ch] = rho[ch] * t; have[ch] += wr * o[ch]; }
                wsum += wr * fabs(o[0] + o[1] + o[2]);
            }
            if (!(wsum > 0)) continue;
        }
        if (!closed) continue;
        for (int ri = 0; ri < nrecv; ri++) {
            if (rkeep[ri] && !closed) continue;
            double wr = wroot[ri];
            double *o = &nw[((size_t)ri * ncol + j) * 3];
            double share = wr * fabs(o[0] + o[1] + o[2]) / wsum;
            if (share == 0) continue;
            for (int ch = 0; ch < 3; ch++) o[ch] += (want[ch] - have[ch]) * share / wr;
        }
    }
    free(wroot);
}

/* Stage 7: the new entries as deltas against the emitted ones, the sender's result */
static void sender_deltas(sender_data *d) {
    bal_ctx *c = d->c;
    int s = d->s;
    size_t ncol = d->ncol;
    const uint32_t *tree = d->tree;
    const int *recv = d->recv;
    int nrecv = d->nrecv;
    const double *nw = d->nw, *cur = d->cur;
    /* deltas against the emitted entries */
    size_t cap = 64, ne = 0;
    wrt_triplet *res = wrt_xmalloc(cap * sizeof *res);
    for (int ri = 0; ri < nrecv; ri++) {
        int r = recv[ri];
        uint64_t rootr = wrt_fkey_make((uint32_t)r, wrt_node_root(), 0, wrt_node_root(), 0);
        int64_t rix = wrt_fkey_find(c->fkeys, c->nf, rootr);
        if (rix < 0) continue;
        for (size_t j = 0; j < ncol; j++) {
            size_t at = (size_t)ri * ncol + j;
            const double *o = &nw[at * 3], *cu = &cur[at * 3];
            if (o[0] == cu[0] && o[1] == cu[1] && o[2] == cu[2]) continue;
            wrt_node n = j ? wrt_node_unpack(tree[(j - 1) / 3]) : wrt_node_root();
            uint64_t ck = wrt_fkey_make((uint32_t)s, n, j ? (int)((j - 1) % 3) + 1 : 0, wrt_node_root(), 0);
            int64_t ci = wrt_fkey_find(c->fkeys, c->nf, ck);
            if (ci < 0) continue;
            if (ne + 1 > cap) { cap *= 2; res = wrt_xrealloc(res, cap * sizeof *res); }
            res[ne].row = (uint32_t)rix;
            res[ne].col = (uint32_t)ci;
            for (int ch = 0; ch < 3; ch++) res[ne].v[ch] = (float)(o[ch] - cu[ch]);
            ne++;
        }
    }
    c->res[s] = res; c->nres[s] = ne;
}

static void balance_sender(size_t si, int th, void *user) {
    (void)th;
    bal_ctx *c = user;
    const bake_ctx *b = c->b;
    int s = c->order ? c->order[si] : (int)si;
    c->res[s] = NULL; c->nres[s] = 0;
    if (!c->nrefs[s] || (c->owner && c->owner[s] != c->rank)) return;
    sender_data d = {.c = c, .b = b, .s = s, .Sq = &b->quads[s], .rho = b->rho[s]};
    sender_tree(c->fkeys, c->nf, s, 1, &d.tree, &d.nt, &d.leaves, &d.nl);
    sender_receivers(&d);
    sender_walk(&d);
    sender_leaf_values(&d);
    sender_analysis(&d);
    sender_emitted(&d);
    sender_new_entries(&d);
    sender_power(&d);
    sender_deltas(&d);
    free(d.cur); free(d.wp); free(d.has); free(d.nw); free(d.rkeep); free(d.addv);
    free(d.tc); free(d.v); free(d.recv); free(d.rloc); free(d.leaves); free(d.tree);
    free(d.dfs); free(d.range); free(d.lcen); free(d.larea); free(d.lside);
}


/* A scene is closed when light cannot leave it: 256 cosine-distributed rays from points
 * spread over each quad all meet the front of a quad. Then every function's light is
 * caught, and its column's power must be what it emits, whatever lies between. */
static int scene_closed(const bake_ctx *b, int *open_quad) {
    *open_quad = -1;
    enum { N = 256 };
    for (int q = 0; q < b->nq; q++) {
        const wrt_quad *Q = &b->quads[q];
        for (int i = 0; i < N; i++) {
            uint64_t h = wrt_mix64(((uint64_t)q << 20) ^ (uint64_t)i);
            double u = ((i % 16) + (double)(h & 0xFFFF) / 65536.0) / 16, v = ((i / 16) + (double)((h >> 16) & 0xFFFF) / 65536.0) / 16;
            int k = (i * 7 + 5) % N;
            double a = ((k % 16) + (double)((h >> 32) & 0xFFFF) / 65536.0) / 16, bb = ((k / 16) + (double)(h >> 48) / 65536.0) / 16;
            double d[3];
            wrt_concentric_dir(a, bb, d);
            wrt_v3 dir = v3_add(v3_add(v3_scale(Q->t, d[0]), v3_scale(Q->b, d[1])), v3_scale(Q->n, d[2]));
            if (!caught(b, v3_mad(wrt_quad_point(Q, u, v), Q->n, b->ray_eps), dir, q)) {
                *open_quad = q;
                return 0;
            }
        }
    }
    return 1;
}

int wrt_balance_run(const bake_ctx *b, size_t np, const int *pr, const int *ps, const pair_out *out,
                    const uint64_t *fkeys, uint32_t nf, wrt_triplet **tr, uint64_t *nt, uint64_t *cap) {
    bal_ctx c = {.b = b, .np = np, .pr = pr, .ps = ps, .out = out, .fkeys = fkeys, .nf = nf};
    int open_quad;
    c.closed = scene_closed(b, &open_quad);
    int closed = c.closed;
    if (b->balance_open) c.closed = 0; /* --clusters: cluster_ops.c applies the closed rule */
    int nq = b->nq;
    c.refs = wrt_xcalloc((size_t)(nq ? nq : 1), sizeof *c.refs);
    c.nrefs = wrt_xcalloc((size_t)(nq ? nq : 1), sizeof *c.nrefs);
    size_t *capr = wrt_xcalloc((size_t)(nq ? nq : 1), sizeof *capr);
    for (size_t i = 0; i < np; i++) {
        if (!out[i].nleaf) continue;
        for (int d = 0; d < 2; d++) {
            if (!(out[i].leaf_dirs & (1 << d))) continue;
            int s = d ? pr[i] : ps[i];
            if (b->alevel[b->scene->quads[s].material]) continue;
            if (c.nrefs[s] == capr[s]) {
                capr[s] = capr[s] ? 2 * capr[s] : 8;
                c.refs[s] = wrt_xrealloc(c.refs[s], capr[s] * sizeof *c.refs[s]);
            }
            c.refs[s][c.nrefs[s]++] = (src_ref){(uint32_t)i, (uint8_t)d};
        }
    }
    c.res = wrt_xcalloc((size_t)(nq ? nq : 1), sizeof *c.res);
    c.nres = wrt_xcalloc((size_t)(nq ? nq : 1), sizeof *c.nres);
    int *owner = NULL;
    if (wrt_dist_on(b->opt.dist)) { /* wrt-bake-mpi: the senders divided by their leaf links */
        double *cost = wrt_xmalloc((size_t)(nq ? nq : 1) * sizeof *cost);
        for (int s = 0; s < nq; s++) cost[s] = (double)c.nrefs[s];
        owner = wrt_xmalloc((size_t)(nq ? nq : 1) * sizeof *owner);
        wrt_dist_assign(cost, (uint64_t)nq, b->opt.dist->nranks, owner);
        free(cost);
        c.owner = owner;
        c.rank = b->opt.dist->rank;
    }
    /* the senders taken largest first (by their leaf links), so that the threads do not
     * wait at the end on one large sender that came late; each sender's entries stay in
     * its own slot, merged in sender order below, so the result is the same */
    c.order = wrt_xmalloc((size_t)(nq ? nq : 1) * sizeof *c.order);
    uint64_t *key = wrt_xmalloc((size_t)(nq ? nq : 1) * sizeof *key);
    for (int s = 0; s < nq; s++) {
        uint64_t leaves = 0;
        for (size_t i = 0; i < c.nrefs[s]; i++) leaves += out[c.refs[s][i].pair].nleaf;
        if (leaves > 0xFFFFFFFFu) leaves = 0xFFFFFFFFu;
        key[s] = ((0xFFFFFFFFu - leaves) << 32) | (uint32_t)s; /* descending leaves, then index */
    }
    wrt_sort_u64(key, (size_t)nq);
    for (int s = 0; s < nq; s++) c.order[s] = (int)(key[s] & 0xFFFFFFFFu);
    free(key);
    wrt_parallel_for((size_t)nq, b->opt.threads, balance_sender, &c);
    free(c.order);
    if (owner && wrt_dist_merge_triplets(b->opt.dist, owner, c.res, c.nres, (size_t)nq) != WRT_OK)
        atomic_store(b->cancel, 1); /* the bake stops after the balance (bake.c) */
    free(owner);
    for (int s = 0; s < nq; s++) {
        if (*nt + c.nres[s] > *cap) {
            *cap = (*nt + c.nres[s]) * 2;
            *tr = wrt_xrealloc(*tr, *cap * sizeof **tr);
        }
        if (c.nres[s]) memcpy(*tr + *nt, c.res[s], c.nres[s] * sizeof **tr);
        *nt += c.nres[s];
        free(c.res[s]); free(c.refs[s]);
    }
    free(c.res); free(c.nres); free(c.refs); free(c.nrefs); free(capr);
    return closed ? 1 : -(open_quad + 1);
}

/* ---- glossy senders ----
 * A glossy sender's function (spatial h, angular g) emits, per unit coefficient, the
 * power sqrt(A) int h(u) du int btilde_g(w_o) C(y, w_o) cos dw_o / pi, where C is 1 where
 * the ray from y in direction w_o meets the front of a quad (the light is caught) and
 * btilde the material's table (bake.c). The links sample btilde_g only at the directions
 * from their receiver points to the sender's quadrant centres, which for a narrow lobe
 * and a fine angular function misses its net power (measured on a closed box of
 * roughness-0.05 metal at angular level 2: +-2% of the root's power per level-1 wavelet,
 * and a point light's first bounce 3% under the albedo's lower bound). The column's
 * power is set to the integral above, with C from 16 rays per (tree leaf, angular cell
 * of the material's level) and btilde integrated over the cell from its table; in a
 * closed scene every ray is caught and the target is exact. The difference is spread
 * over the column's root entries in proportion to their power. */

typedef struct gbal_ctx {
    const bake_ctx *b;
    const uint64_t *fkeys;
    uint32_t nf;
    wrt_csc *T;
    const double *pw;
    uint64_t *changed;      /* per quad */
} gbal_ctx;

static int angular_index(wrt_node n, int t) {
    if (t == 0) return 0;
    int base = ((1 << (2 * n.level)) - 1) / 3;
    return 1 + 3 * (base + n.y * (1 << n.level) + n.x) + (t - 1);
}


/* The value of the spatial function (sn, st) on tree leaf f (the function is piecewise
 * constant on the leaves): 0 where f is outside its support, and for the scaling function
 * only the root's (1 everywhere). */
static double leaf_value(wrt_node sn, int st, wrt_node f) {
    if (f.level <= sn.level) return st == 0 && sn.level == 0 ? 1 : 0;
    if ((f.x >> (f.level - sn.level)) != sn.x || (f.y >> (f.level - sn.level)) != sn.y) return 0;
    if (!st) return sn.level ? 0 : 1;
    int d = f.level - sn.level - 1;
    return wrt_pow2(sn.level) * wrt_haar_sign(st, (f.x >> d) & 1, (f.y >> d) & 1);
}

static void balance_glossy_sender(size_t si, int th, void *user) {
    (void)th;
    gbal_ctx *c = user;
    const bake_ctx *b = c->b;
    int s = (int)si, m = b->scene->quads[s].material, L = b->alevel[m];
    c->changed[s] = 0;
    if (!L || !b->btilde[m]) return;
    const wrt_quad *Sq = &b->quads[s];
    int na = 1 << (2 * L), side = 1 << L, tr = WRT_BRDF_TABLE_RES >> L;
    size_t nt, nl;
    uint32_t *tree, *leaves;
    sender_tree(c->fkeys, c->nf, s, 0, &tree, &nt, &leaves, &nl);
    /* B[k][g][ch]: btilde_g integrated over angular cell k (cos dw / pi = da db) */
    double *B = wrt_xcalloc((size_t)na * na * 3, sizeof *B);
    const float *tab = b->btilde[m];
    for (int cell = 0; cell < WRT_BRDF_TABLE_RES * WRT_BRDF_TABLE_RES; cell++) {
        int k = ((cell / WRT_BRDF_TABLE_RES) / tr) * side + (cell % WRT_BRDF_TABLE_RES) / tr;
        for (int g = 0; g < na; g++)
            for (int ch = 0; ch < 3; ch++)
                B[((size_t)k * na + g) * 3 + ch] +=
                    tab[((size_t)cell * WRT_BRDF_TABLE_NANG + g) * 3 + ch] / (WRT_BRDF_TABLE_RES * WRT_BRDF_TABLE_RES);
    }
    /* V[f][g][ch] = sqrt(J) |f| sum_k C(f, k) B[k][g][ch] */
    double *V = wrt_xcalloc(nl * na * 3, sizeof *V);
    double *cap = wrt_xmalloc((size_t)na * sizeof *cap);
    enum { M = 16 };
    for (size_t li = 0; li < nl; li++) {
        wrt_node f = wrt_node_unpack(leaves[li]);
        double sz = wrt_node_size(f), x0 = wrt_node_x0(f), y0 = wrt_node_y0(f);
        for (int k = 0; k < na; k++) {
            int hits = 0;
            uint64_t h = wrt_mix64(((uint64_t)s << 40) ^ ((uint64_t)leaves[li] << 8) ^ (uint64_t)k);
            for (int i = 0; i < M; i++) {
                uint64_t hi = wrt_mix64(h + (uint64_t)i);
                double ju = (double)(hi & 0xFFFF) / 65536.0, jv = (double)((hi >> 16) & 0xFFFF) / 65536.0;
                double ja = (double)((hi >> 32) & 0xFFFF) / 65536.0, jb = (double)((hi >> 48) & 0xFFFF) / 65536.0;
                int dj = (i * 5 + 3) % M;
                double u = x0 + sz * ((i % 4) + ju) / 4, v = y0 + sz * ((i / 4) + jv) / 4;
                double a = ((k % side) + ((dj % 4) + ja) / 4) / side, bb = ((k / side) + ((dj / 4) + jb) / 4) / side;
                double d[3];
                wrt_concentric_dir(a, bb, d);
                wrt_v3 dir = v3_add(v3_add(v3_scale(Sq->t, d[0]), v3_scale(Sq->b, d[1])), v3_scale(Sq->n, d[2]));
                hits += caught(b, v3_mad(wrt_quad_point(Sq, u, v), Sq->n, b->ray_eps), dir, s);
            }
            cap[k] = (double)hits / M;
        }
        double w = sqrt(jac_at(Sq, f)) * sz * sz;
        for (int k = 0; k < na; k++) {
            if (cap[k] == 0) continue;
            for (int g = 0; g < na; g++)
                for (int ch = 0; ch < 3; ch++) V[(li * na + g) * 3 + ch] += w * cap[k] * B[((size_t)k * na + g) * 3 + ch];
        }
    }
    /* every column of the quad */
    uint64_t lo_key = (uint64_t)s << 42;
    uint32_t lo = 0;
    lo = first_key_at_least(c->fkeys, c->nf, lo_key);
    wrt_csc *T = c->T;
    for (uint32_t j = lo; j < c->nf && wrt_fkey_quad(c->fkeys[j]) == (uint32_t)s; j++) {
        uint64_t key = c->fkeys[j];
        wrt_node sn = wrt_fkey_snode(key);
        int st = wrt_fkey_stype(key), g = angular_index(wrt_fkey_anode(key), wrt_fkey_atype(key));
        if (g >= na) continue;
        double want[3] = {0, 0, 0};
        for (size_t li = 0; li < nl; li++) {
            double hv = leaf_value(sn, st, wrt_node_unpack(leaves[li]));
            if (hv != 0)
                for (int ch = 0; ch < 3; ch++) want[ch] += hv * V[(li * na + g) * 3 + ch];
        }
        double have[3] = {0, 0, 0}, wsum = 0;
        for (uint64_t k = T->col[j]; k < T->col[j + 1]; k++) {
            double pwr = c->pw[T->row[k]];
            if (pwr == 0) continue;
            for (int ch = 0; ch < 3; ch++) have[ch] += pwr * T->val[3 * k + ch];
            wsum += pwr * (fabs(T->val[3 * k]) + fabs(T->val[3 * k + 1]) + fabs(T->val[3 * k + 2]));
        }
        if (!(wsum > 0)) continue;
        for (uint64_t k = T->col[j]; k < T->col[j + 1]; k++) {
            double pwr = c->pw[T->row[k]];
            if (pwr == 0) continue;
            double share = pwr * (fabs(T->val[3 * k]) + fabs(T->val[3 * k + 1]) + fabs(T->val[3 * k + 2])) / wsum;
            for (int ch = 0; ch < 3; ch++) T->val[3 * k + ch] = (float)(T->val[3 * k + ch] + (want[ch] - have[ch]) * share / pwr);
            c->changed[s]++;
        }
    }
    free(cap); free(V); free(B); free(tree); free(leaves);
}

/* Runs a balance's per-sender function over the quads in parallel, each sender counting
 * the columns it changed in (*changed)[sender] (an array this allocates and frees in
 * ctx); returns the total (the glossy balance's and K's). */
static uint64_t balance_senders(const bake_ctx *b, wrt_parallel_fn fn, void *ctx, uint64_t **changed) {
    int nq = b->nq;
    *changed = wrt_xcalloc((size_t)(nq ? nq : 1), sizeof **changed);
    wrt_parallel_for((size_t)nq, b->opt.threads, fn, ctx);
    uint64_t n = 0;
    for (int s = 0; s < nq; s++) n += (*changed)[s];
    free(*changed);
    *changed = NULL;
    return n;
}

uint64_t wrt_balance_glossy(const bake_ctx *b, const uint64_t *fkeys, uint32_t nf, wrt_csc *T) {
    double *pw = wrt_power_weights(b, fkeys, nf);
    gbal_ctx c = {.b = b, .fkeys = fkeys, .nf = nf, .T = T, .pw = pw};
    uint64_t n = balance_senders(b, balance_glossy_sender, &c, &c.changed);
    free(pw);
    return n;
}

/* The power balance of the first-bounce operator K (dto.c), the glossy balance's rule
 * with the sender's outgoing angular function g in place of btilde_g: K's column j
 * (spatial h_j, outgoing g) must deliver over all receivers
 *   sum_f h_j(f) sqrt(J) |f| sum_k C(f, k) int_k g da db
 * (f the leaves of the quad's K function tree, k the cells of K's level, C the share of
 * rays from f into k that meet a quad). The links' own integration loses power along
 * edges a receiver shares with the sender's plane (a box standing on a glossy floor: its
 * sides 6-9% low against the path tracer, and T without its balance the same); the
 * difference is spread over the column's root entries in proportion to their power.
 * Rays: 256 per leaf (4 per (leaf, cell) at level 3). */
typedef struct kbal_ctx {
    const bake_ctx *b;
    const double *pw;
    wrt_bake_result *res;
    uint64_t *changed;
} kbal_ctx;

static void balance_k_sender(size_t si, int th, void *user) {
    (void)th;
    kbal_ctx *c = user;
    const bake_ctx *b = c->b;
    wrt_bake_result *res = c->res;
    int s = (int)si, m = b->scene->quads[s].material, L = b->klevel[m];
    c->changed[s] = 0;
    if (!L) return;
    uint32_t lo = first_key_at_least(res->kkeys, res->nkcols, (uint64_t)s << 42);
    uint32_t hi = first_key_at_least(res->kkeys, res->nkcols, (uint64_t)(s + 1) << 42);
    if (lo == hi) return;
    const wrt_quad *Sq = &b->quads[s];
    int na = 1 << (2 * L), side = 1 << L, M = na >= 256 ? 2 : na >= 64 ? 4 : 256 / na;
    size_t nt, nl;
    uint32_t *tree, *leaves;
    sender_tree(res->kkeys + lo, hi - lo, s, 0, &tree, &nt, &leaves, &nl);
    /* G[k][g] = int_k g da db: g's value on cell k times the cell's area 4^-L */
    double *G = wrt_xcalloc((size_t)na * na, sizeof *G);
    for (int k = 0; k < na; k++) {
        double a = ((k % side) + 0.5) / side, bb = ((k / side) + 0.5) / side;
        for (int g = 0; g < na; g++) {
            int lv, x, y, ty;
            wrt_brdf_angular_func(g, &lv, &x, &y, &ty);
            wrt_node an = {(uint8_t)lv, (uint16_t)x, (uint16_t)y};
            G[(size_t)k * na + g] = wrt_haar2(an, ty, a, bb) / na;
        }
    }
    double *V = wrt_xcalloc(nl * (size_t)na, sizeof *V), *cap = wrt_xmalloc((size_t)na * sizeof *cap);
    for (size_t li = 0; li < nl; li++) {
        wrt_node f = wrt_node_unpack(leaves[li]);
        double sz = wrt_node_size(f), x0 = wrt_node_x0(f), y0 = wrt_node_y0(f);
        for (int k = 0; k < na; k++) {
            int hits = 0;
            uint64_t h = wrt_mix64(((uint64_t)s << 40) ^ ((uint64_t)leaves[li] << 8) ^ (uint64_t)k ^ 0x4b00000000000000ULL);
            for (int i = 0; i < M; i++) {
                uint64_t hv = wrt_mix64(h + (uint64_t)i);
                double ju = (double)(hv & 0xFFFF) / 65536.0, jv = (double)((hv >> 16) & 0xFFFF) / 65536.0;
                double ja = (double)((hv >> 32) & 0xFFFF) / 65536.0, jb = (double)((hv >> 48) & 0xFFFF) / 65536.0;
                /* a point of the leaf drawn apart from the direction: tying the point's
                 * stratum to the direction's cell biased the target (2.9% on a wall's
                 * root column with one ray a cell) */
                double u = x0 + sz * ju, v = y0 + sz * jv;
                double a = ((k % side) + ja) / side, bb = ((k / side) + jb) / side, d[3];
                wrt_concentric_dir(a, bb, d);
                wrt_v3 dir = v3_add(v3_add(v3_scale(Sq->t, d[0]), v3_scale(Sq->b, d[1])), v3_scale(Sq->n, d[2]));
                hits += caught(b, v3_mad(wrt_quad_point(Sq, u, v), Sq->n, b->ray_eps), dir, s);
            }
            cap[k] = (double)hits / M;
        }
        double w = sqrt(jac_at(Sq, f)) * sz * sz;
        for (int k = 0; k < na; k++)
            if (cap[k] != 0)
                for (int g = 0; g < na; g++) V[li * na + g] += w * cap[k] * G[(size_t)k * na + g];
    }
    for (uint32_t j = lo; j < hi; j++) {
        uint64_t key = res->kkeys[j];
        wrt_node sn = wrt_fkey_snode(key);
        int st = wrt_fkey_stype(key), g = angular_index(wrt_fkey_anode(key), wrt_fkey_atype(key));
        if (g >= na) continue;
        double want = 0;
        for (size_t li = 0; li < nl; li++) want += leaf_value(sn, st, wrt_node_unpack(leaves[li])) * V[li * na + g];
        double have = 0, wsum = 0;
        for (uint64_t k = res->kcol_start[j]; k < res->kcol_start[j + 1]; k++) {
            double pwr = c->pw[res->krows[k]];
            if (pwr == 0) continue;
            have += pwr * res->kvals[k];
            wsum += pwr * fabs(res->kvals[k]);
        }
        if (!(wsum > 0)) continue;
        for (uint64_t k = res->kcol_start[j]; k < res->kcol_start[j + 1]; k++) {
            double pwr = c->pw[res->krows[k]];
            if (pwr == 0) continue;
            res->kvals[k] = (float)(res->kvals[k] + (want - have) * fabs(res->kvals[k]) / wsum);
            c->changed[s]++;
        }
    }
    free(cap); free(V); free(G); free(tree); free(leaves);
}

uint64_t wrt_balance_k(const bake_ctx *b, wrt_bake_result *res) {
    double *pw = wrt_power_weights(b, res->fkeys, res->nfuncs);
    kbal_ctx c = {.b = b, .pw = pw, .res = res};
    uint64_t n = balance_senders(b, balance_k_sender, &c, &c.changed);
    free(pw);
    return n;
}
