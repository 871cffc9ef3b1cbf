/* series_tree.c: the Neumann series with its terms in the senders' tree basis, the
 * default with --clusters (docs/clusters.md "The series in the senders' tree basis"): the
 * first term T W^T, the tree columns' weights, the stored compression's weights in that
 * basis and the column power rule carried into it. The bounces themselves are series.c's,
 * with T as the left factor. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "budget.h"
#include "cluster.h"
#include "dist.h"
#include "series.h"
#include "series_internal.h"

/* The senders' tree basis's column weights (series_senders, series_tree_start): the
 * columns of W (cw, boost may be NULL: 1) with the root slots taken by the tree's
 * functions, weight sqrt(a_P), and the small senders' factor of a node under the share
 * as of a quad (phi_root is never under it); into *cw and *boost (n + 1 each, malloc'd) */
void wrt_series_tree_cols(const series_state *s, const uint32_t *root, const double *cw_in, double **cw_out,
                             double **boost_out) {
    const bake_ctx *b = s->b;
    const wrt_ctree *t = &b->cl->tree;
    uint32_t n = s->res->nfuncs;
    double *cw = wrt_xmalloc(((size_t)n + 1) * sizeof *cw), *boost = wrt_xmalloc(((size_t)n + 1) * sizeof *boost);
    for (uint32_t i = 0; i < n; i++) {
        cw[i] = cw_in ? cw_in[i] : 1;
        boost[i] = 1;
    }
    double small = wrt_series_small_area(b);
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0) {
            cw[root[t->slot[p]]] = sqrt(t->area[p]);
            if (t->area[p] < small) boost[root[t->slot[p]]] = small / t->area[p];
        }
    cw[root[t->root_slot]] = sqrt(t->area[0]);
    *cw_out = cw;
    *boost_out = boost;
}

/* The products keep a tree column's entries down to this many times less than a quad's:
 * its rows cancel where its functions' light does (two rooms: a light in one room has
 * coefficients on tree functions spanning both, whose rows in the other room sum to 0),
 * and an entry dropped there is light through the wall. Two rooms at quality 3: the dark
 * room at 1.6e-3 of the lit room's mean with 1, 2.7e-5 with 10, 5.4e-6 with 30. */
#ifndef WRT_SERIES_TREE_TIGHT
#define WRT_SERIES_TREE_TIGHT 10.0
#endif

/* The series' final weights (series_final_weights), in the senders' tree basis where the
 * terms are (series_tree_on); own[0..2] the arrays to free */
double wrt_series_final_weights_tree(series_state *s, wrt_csc_weights *W, double *own[3]) {
    double eps = wrt_series_final_weights(s, W, &own[0]);
    own[1] = own[2] = NULL;
    if (s->tree) {
        wrt_series_tree_cols(s, s->troot, W->col_w, &own[1], &own[2]);
        W->col_w = own[1];
        W->boost_w = own[2];
    }
    return eps;
}

/* The column power rule's correction from T (series_tree_power): column root(q) =
 * (u_q - have_q) times T's column there (its rows that carry power), its power 1, in the
 * senders' tree basis */
static wrt_csc tree_power_cols(const series_state *s, const double *u, const double *d, double eps,
                               const wrt_csc_weights *W) {
    const wrt_csc *T = s->T;
    const double *pw = s->pw;
    uint32_t n = s->S.n, nq = (uint32_t)s->b->nq;
    wrt_csc C = {.n = n};
    C.col = wrt_xcalloc((size_t)n + 1, sizeof *C.col);
    uint64_t cnt = 0;
    for (uint32_t q = 0; q < nq; q++) {
        uint32_t f = s->troot[q];
        for (uint64_t e = T->col[f]; e < T->col[f + 1]; e++) cnt += pw[T->row[e]] != 0;
    }
    C.row = wrt_xmalloc((cnt ? cnt : 1) * sizeof *C.row);
    C.val = wrt_xmalloc((cnt ? cnt : 1) * 3 * sizeof *C.val);
    uint8_t *isroot = wrt_xcalloc((size_t)n + 1, 1);
    for (uint32_t q = 0; q < nq; q++) isroot[s->troot[q]] = 1;
    uint64_t k = 0;
    for (uint32_t f = 0; f < n; f++) {
        if (isroot[f]) {
            double tp[3] = {0, 0, 0}, scale[3];
            for (uint64_t e = T->col[f]; e < T->col[f + 1]; e++)
                for (int ch = 0; ch < 3; ch++) tp[ch] += pw[T->row[e]] * T->val[3 * e + ch];
            for (int ch = 0; ch < 3; ch++)
                scale[ch] = tp[ch] > 0 ? (u[3 * (size_t)f + ch] - d[3 * (size_t)f + ch]) / tp[ch] : 0;
            for (uint64_t e = T->col[f]; e < T->col[f + 1]; e++) {
                if (pw[T->row[e]] == 0) continue;
                C.row[k] = T->row[e];
                for (int ch = 0; ch < 3; ch++) C.val[3 * k + ch] = (float)(scale[ch] * T->val[3 * e + ch]);
                k++;
            }
        }
        C.col[f + 1] = k;
    }
    C.nnz = k;
    uint64_t raw;
    wrt_clusters_senders(&s->b->cl->tree, s->troot, &C, eps, W, 1, &raw);
    free(isroot);
    return C;
}

/* The column power rule (series_power.c) with the terms in the senders' tree basis
 * (series_tree_on). A tree column spans parts of the scene that may not see each other
 * (two rooms), its rows there cancelling for a light on one side alone: spreading its
 * difference over its own entries, as a quad's column's is, broke that (the dark room at
 * 1.6e-3 of the lit room's light). So the root columns' powers are taken back to the
 * quads' basis (the inverse transform of the row vector), each quad's difference to its
 * target is carried where its own light lands first, along T's column (its rows that
 * carry power, in proportion), and that correction, a matrix of the quads' root columns,
 * is added in the tree's basis (cluster_send.c; the stored operator's weights with the
 * nodes apart held finer, below). The quads' other
 * columns (their wavelets) are fixed as in the quads' series. Without it the 320-triangle
 * icosphere furnace's G - I was 0.14% under the DTO's own series. */
void wrt_series_tree_power(series_state *s, wrt_series_power_stats *ps) {
    const bake_ctx *b = s->b;
    const wrt_ctree *t = &b->cl->tree;
    const double *pw = s->pw;
    uint32_t n = s->S.n, nq = (uint32_t)b->nq;
    memset(ps, 0, sizeof *ps);
    double *u = s->no_t ? wrt_series_factored_targets(s, &ps->bounces)
                        : wrt_series_power_targets(s->T, pw, s->threads, b->opt.max_bounces, &ps->bounces);
    double *d = wrt_xcalloc(3 * (size_t)n + 1, sizeof *d);
    double *scratch = wrt_xmalloc((6 * (size_t)t->nnodes + 1) * sizeof *scratch);
    for (uint32_t q = 0; q < nq; q++) {
        uint32_t f = s->troot[q];
        for (uint64_t e = s->S.col[f]; e < s->S.col[f + 1]; e++)
            for (int ch = 0; ch < 3; ch++) d[3 * (size_t)f + ch] += pw[s->S.row[e]] * s->S.val[3 * e + ch];
    }
    wrt_ctree_inverse_d(t, s->troot, d, 3, scratch);
    /* compressed with the stored operator's threshold and weights, its tree columns'
     * WRT_SERIES_TREE_TIGHT factor off but the factor of the nodes apart (and their
     * ancestors) kept: at the products' level (the factors both on) the correction added
     * 78% of the stored operator's entries at 22,224 atrium elements (31.6M to 40.7M);
     * with the stored operator's own weights (both off) the two rooms' dark room took
     * 1.5e-3 of the lit room's light (test_cluster), with the apart factor kept 3.0e-5 */
    wrt_csc_weights W;
    double *own[3];
    double eps = wrt_series_final_weights_tree(s, &W, own);
    for (uint32_t q = 0; q < nq; q++) own[1][s->troot[q]] = s->tcw[s->troot[q]] / WRT_SERIES_TREE_TIGHT;
    wrt_csc C = s->no_t ? wrt_series_factored_power_cols(s, u, d, eps, &W) : tree_power_cols(s, u, d, eps, &W);
    free(own[0]); free(own[1]); free(own[2]);
    const double one[3] = {1, 1, 1};
    wrt_csc_add3_into(&s->S, &C, one);
    wrt_csc_free(&C);
    /* the tree's columns now hold their targets: the rule leaves them as they are */
    for (uint32_t q = 0; q < nq; q++) {
        uint32_t f = s->troot[q];
        for (int ch = 0; ch < 3; ch++) {
            double have = 0;
            for (uint64_t e = s->S.col[f]; e < s->S.col[f + 1]; e++) have += pw[s->S.row[e]] * s->S.val[3 * e + ch];
            u[3 * (size_t)f + ch] = have;
        }
    }
    wrt_series_power_apply(u, pw, s->threads, &s->S, ps);
    free(u); free(d); free(scratch);
}

/* ---- The series in the senders' tree basis (the default with --clusters; docs/clusters.md
 * "The series in the senders' tree basis"). Every term is held as P_k W^T, the stored
 * operator's form (cluster_send.c): the rows the quads' functions, the quads' root
 * columns replaced by the tree's functions, a small quad's far light held once per
 * cluster instead of once per (quad, receiver). The terms are then multiplied from the
 * left, P_{k+1} W^T = (T D)(P_k W^T), which keeps every column's basis as it is: T in the
 * quads' basis on both sides, D the coarse cut (series_coarse_cut on T's columns: the
 * same products as P_k (D T) from the right, P_k = T (D T)^{k-1} = (T D)^{k-1} T), and
 * the product's cost the term's entries at coarse rows times T's column there, so the
 * fewer entries of the tree's columns make it cheaper. The first term is T W^T, each tree
 * column compressed as cluster_send.c does (the products' threshold, the node's weight
 * sqrt(a_P), the small senders' factor of a node under the share); every product's columns
 * the same (TW); the stored compression the same with the final threshold
 * (series_final_weights_tree); the column power rule's targets taken forward to the tree's
 * basis (u W^T: series_tail). The sum is held in memory and T is kept (no streaming),
 * or with T unformed E1 (series_first.c).
 * Under wrt-bake-mpi each rank holds one column range of the terms and of the sum
 * (series.c series_tree_share_start: a column of the next term needs T and the same
 * column of the term before alone). */

/* ... and the columns of the nodes whose halves' light lands apart, and of their
 * ancestors (wrt_clusters_apart), this many times less again. A light on one side of a
 * wall has coefficients on every node spanning it, and at a row on the other side those
 * columns' entries cancel (their sum is 0). With every term compressed on its own, the
 * late terms' entries there come near the threshold and are dropped in some columns and
 * kept in others (phi_root's, whose weight sqrt(a) is the largest, last): the rest is
 * light through the wall, the same sign term after term. Two rooms of albedos 0.8 and 0.5
 * (tests/test_cluster.c), quality 1: the dark room at 4.1e-4 of the lit room's mean
 * without this, 4.1e-5 with 10, 7.4e-6 with 100; lit at 0.5 and dark at 0.8 (the leak
 * bounced on in the brighter room): 9.2e-3, 5.2e-4, 4.0e-5. */
#ifndef WRT_SERIES_TREE_APART
#define WRT_SERIES_TREE_APART 100.0
#endif

static void series_tree_apart(series_state *s) {
    const wrt_ctree *t = &s->b->cl->tree;
    uint8_t *apart = wrt_xmalloc((size_t)t->nnodes + 1);
    int walked = s->no_t;
    if (walked) {
        /* the sum's first state (whole: by shares cut to the rank's range later) made in
         * the same walk as the test, each node's weight raised as the walk decides it,
         * before its column is compressed (the same columns as after a walk of its own).
         * T's root columns, made from E1 and each quad's ancestors, cost the most of the
         * series' start: at 100,256 atrium elements about 600 s for four walks */
        wrt_apart_opt ap = {s->pw, apart, s->tcw, WRT_SERIES_TREE_APART};
        wrt_series_factored_sum(s, &s->S, &ap);
    } else {
        wrt_clusters_apart(t, s->troot, s->T, NULL, NULL, s->pw, apart);
    }
    uint32_t n = 0;
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0 && apart[p]) {
            if (!walked) s->tcw[s->troot[t->slot[p]]] *= WRT_SERIES_TREE_APART;
            n++;
        }
    if (apart[0] && !walked) s->tcw[s->troot[t->root_slot]] *= WRT_SERIES_TREE_APART;
    s->res->c.cluster_apart_nodes = n;
    free(s->apart);
    s->apart = apart;
}

/* The stored operator's rows in the tree's basis (wrt_series_receivers): the rows and
 * the columns of the nodes apart (and of their ancestors) held WRT_SERIES_TREE_APART times
 * finer. A node apart's psi_P row takes its far half's share of phi_P's light back, and a
 * column of a node apart has rows on both sides of the wall that cancel against the other
 * such columns': either dropped, the light lands on both sides. Two rooms (test_cluster),
 * the dark room's largest over the lit room's mean: 2.9e-4 with neither, 6.3e-5 with the
 * rows alone, 1.3e-4 with the columns alone (10 times), 3.6e-6 with both (the senders'
 * tree basis alone: 3.5e-6); with the ancestors' rule (wrt_series_receivers) 3.4e-6. */
void wrt_series_receivers_apart(const series_state *s, double *rw, double *cw) {
    const wrt_ctree *t = &s->b->cl->tree;
    if (!s->apart) return;
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0 && s->apart[p]) {
            rw[s->troot[t->slot[p]]] *= WRT_SERIES_TREE_APART;
            cw[s->troot[t->slot[p]]] *= WRT_SERIES_TREE_APART;
        }
    if (s->apart[0]) {
        rw[s->troot[t->root_slot]] *= WRT_SERIES_TREE_APART;
        cw[s->troot[t->root_slot]] *= WRT_SERIES_TREE_APART;
    }
}

/* The stored operator's rows taken to the tree's basis too (the default;
 * docs/clusters.md "The receivers' side in the tree's basis"): seen from a sender, a far
 * cluster's quads receive light in proportion to sqrt(a_q), which phi_P carries alone,
 * its wavelets near 0. Compressed by the stored operator's rule with the tree's weights on
 * both sides (the nodes apart held finer), and kept where it has fewer entries (or always,
 * 2), the file then in the tree's basis on both sides (section ctree without csend: the
 * runtime takes the result back to the quads, O(N)). Each column keeps the ancestors of
 * every entry it keeps (wrt_clusters_rows_to_tree): without them the column's power was
 * lost (the 320-triangle icosphere furnace -0.68%; 19% of the columns' power at 2,704
 * atrium elements). Holding the tree's rows twice finer than a quad's kept 22% more
 * entries at 22,224 atrium elements for 0.02 and 0.03 points of cells and image: not
 * done. A trial the budget cannot hold is not made (always: refused).
 * --clusters-quads-receivers: not tried. */
wrt_status wrt_series_receivers(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_result *res = s->res;
    /* after the series in the senders' tree basis, on the rank that holds the operator */
    if (!s->tree || b->opt.cluster_receivers < 0 || !res->c.cluster_senders_basis || (s->share && b->opt.dist->rank != 0))
        return WRT_OK;
    int always = b->opt.cluster_receivers > 1;
    /* E1 is done with (the series is summed): its memory is the trial's */
    if (b->opt.cluster_factored < 2) wrt_csc_free(&res->dto_e1);
    /* the result may grow to the budget's room, a growth's copy (realloc) beside it: half
     * the room, 16 bytes an entry; kept where fewer than the senders' basis (always:
     * twice as many) */
    uint64_t limit = always ? 2 * s->S.nnz + 1024 : s->S.nnz;
    wrt_bake_memory_trim();
    double room = b->opt.max_memory_mb * 1048576.0 - (double)wrt_bake_rss_bytes();
    uint64_t fit = room > 0 ? (uint64_t)(room / 32) : 0;
    if (fit < limit) limit = fit;
    wrt_csc_weights W;
    double *own[3];
    double eps = wrt_series_final_weights_tree(s, &W, own);
    uint32_t n = res->nfuncs;
    double *rw = wrt_xmalloc(3 * ((size_t)n + 1) * sizeof *rw), *pw = rw + n + 1, *cw = pw + n + 1;
    memcpy(rw, W.row_w, n * sizeof *rw);
    memcpy(pw, W.power_w, n * sizeof *pw);
    wrt_clusters_series_weights(b, b->cl, res->fkeys, n, rw, cw, pw, NULL); /* cw: the columns' are W's */
    wrt_series_receivers_apart(s, rw, own[1]);
    W.row_w = rw;
    W.power_w = pw;
    wrt_csc R;
    int made = wrt_clusters_rows_to_tree(b, b->cl, res->fkeys, n, &s->S, eps, &W, limit, &R,
                                         &res->c.cluster_receivers_raw);
    free(rw); free(own[0]); free(own[1]); free(own[2]);
    if (s->timing)
        fprintf(stderr, "series-times: receivers' tree %llu entries before compression, %s (senders' %llu)\n",
                (unsigned long long)res->c.cluster_receivers_raw, made ? "made" : "over the senders' and stopped",
                (unsigned long long)s->S.nnz);
    if (!made) {
        if (always)
            return wrt_fail(WRT_ERR_NOMEM, "the receivers' tree basis: over %llu entries (twice the senders' basis, or "
                            "what the memory budget holds: --max-memory)", (unsigned long long)limit);
        return WRT_OK;
    }
    double mb = (double)wrt_bake_rss_bytes() / 1048576.0;
    if (mb > s->C->mem_estimate_mb) s->C->mem_estimate_mb = mb;
    res->c.cluster_receivers_entries = R.nnz;
    if (R.nnz < s->S.nnz || always) {
        wrt_csc_free(&s->S);
        s->S = R;
        res->c.cluster_senders_basis = 0;
        res->c.cluster_tree_basis = 1;
        res->c.entries_gto = s->S.nnz;
    } else {
        wrt_csc_free(&R);
    }
    wrt_series_mark(s, "receivers' tree");
    return WRT_OK;
}

int wrt_series_tree_on(const bake_ctx *b) {
    return b->cl && b->opt.cluster_series >= 0 && !b->opt.cluster_tree && b->opt.cluster_senders >= 0 &&
           !b->opt.gathered && !b->opt.report_gathered;
}

typedef struct {
    const series_state *s;
    const uint8_t *tree;
    wrt_csc *P;
    uint32_t c0;
    uint64_t *len;
} first_ctx;

static void first_col(size_t i, int th, void *user) {
    (void)th;
    first_ctx *x = user;
    uint32_t c = x->c0 + (uint32_t)i;
    uint64_t a = x->P->col[c], m = x->P->col[c + 1] - a;
    if (!x->tree[c]) m = wrt_csc_compress_col(x->P->row + a, x->P->val + 3 * a, m, c, x->s->eps, &x->s->W);
    x->len[i] = m;
}

/* The first term's columns [c0, c1) (the others empty) from the sum's first state S: its
 * tree columns are the sum's (T's root columns transformed, each compressed at the
 * products' threshold and the tree's weights), its other columns T's compressed as
 * series_first_terms does. Until session 16 the tree columns were made from the quads'
 * root columns compressed first, in a walk of their own: a second compression that moved
 * the kept entries by under the threshold, for the walk's cost again (docs/clusters.md
 * "The series' start"). */
wrt_csc wrt_series_first_range(const series_state *s, const wrt_csc *S, uint32_t c0, uint32_t c1) {
    uint32_t n = S->n;
    uint8_t *tree = wrt_xcalloc((size_t)n + 1, 1);
    for (uint32_t q = 0; q < (uint32_t)s->b->nq; q++) tree[s->troot[q]] = 1;
    wrt_csc P = wrt_series_csc_range(S, c0, c1);
    uint64_t *len = wrt_xmalloc(((size_t)(c1 - c0) + 1) * sizeof *len);
    first_ctx x = {s, tree, &P, c0, len};
    wrt_parallel_for(c1 - c0, s->threads, first_col, &x);
    uint64_t k = 0;
    for (uint32_t c = c0; c < c1; c++) {
        uint64_t a = P.col[c], m = len[c - c0];
        memmove(P.row + k, P.row + a, m * sizeof *P.row);
        memmove(P.val + 3 * k, P.val + 3 * a, 3 * m * sizeof *P.val);
        P.col[c] = k; /* a column's start is read before it is written (a <= its old start) */
        k += m;
    }
    for (uint32_t c = c0; c < n; c++) P.col[c + 1] = c + 1 < c1 ? P.col[c + 1] : k;
    P.nnz = k;
    P.row = wrt_xrealloc(P.row, (k ? k : 1) * sizeof *P.row);
    P.val = wrt_xrealloc(P.val, (k ? k : 1) * 3 * sizeof *P.val);
    free(len); free(tree);
    return P;
}

typedef struct {
    const series_state *s;
    const uint8_t *tree;
    const wrt_csc *S;
    uint64_t *len;
    uint32_t **row; /* a column's scratch copy a thread */
    float **val;
} count_ctx;

static void count_col(size_t c, int th, void *user) {
    count_ctx *x = user;
    const wrt_csc *S = x->S;
    uint64_t a = S->col[c], m = S->col[c + 1] - a;
    if (!x->tree[c] && m) {
        memcpy(x->row[th], S->row + a, m * sizeof *S->row);
        memcpy(x->val[th], S->val + 3 * a, 3 * m * sizeof *S->val);
        m = wrt_csc_compress_col(x->row[th], x->val[th], m, (uint32_t)c, x->s->eps, &x->s->W);
    }
    x->len[c] = m;
}

/* The first term's column starts alone (its entries made a block at a time later,
 * series_cols.c): held whole beside the sum's first state, E1 and its compressed copy,
 * it was the start's largest transient */
static wrt_csc first_counts(const series_state *s, const wrt_csc *S) {
    uint32_t n = S->n;
    int th = wrt_threads_resolve(s->threads);
    if (th < 1) th = 1;
    uint64_t longest = 1;
    uint8_t *tree = wrt_xcalloc((size_t)n + 1, 1);
    for (uint32_t q = 0; q < (uint32_t)s->b->nq; q++) tree[s->troot[q]] = 1;
    for (uint32_t c = 0; c < n; c++)
        if (!tree[c] && S->col[c + 1] - S->col[c] > longest) longest = S->col[c + 1] - S->col[c];
    count_ctx x = {s, tree, S, wrt_xmalloc(((size_t)n + 1) * sizeof *x.len), wrt_xmalloc(th * sizeof *x.row),
                   wrt_xmalloc(th * sizeof *x.val)};
    for (int i = 0; i < th; i++) {
        x.row[i] = wrt_xmalloc(longest * sizeof **x.row);
        x.val[i] = wrt_xmalloc(3 * longest * sizeof **x.val);
    }
    wrt_parallel_for(n, th, count_col, &x);
    wrt_csc P = {.n = n};
    P.col = wrt_xcalloc((size_t)n + 1, sizeof *P.col);
    for (uint32_t c = 0; c < n; c++) P.col[c + 1] = P.col[c] + x.len[c];
    P.nnz = P.col[n];
    for (int i = 0; i < th; i++) { free(x.row[i]); free(x.val[i]); }
    free(x.row); free(x.val); free(x.len); free(tree);
    return P;
}

/* The sum's first state, T W^T (whole), from T (still in memory) or from E1 where T is
 * unformed, and the first term from it */
void wrt_series_tree_start(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_result *res = s->res;
    s->troot = wrt_clusters_root_index(res->fkeys, res->nfuncs, (uint32_t)b->nq);
    wrt_series_tree_cols(s, s->troot, s->W.col_w, &s->tcw, &s->tboost);
    s->TW = s->W;
    s->TW.col_w = s->tcw;
    s->TW.boost_w = s->tboost;
    /* the products' threshold on the tree's columns WRT_SERIES_TREE_TIGHT times lower */
    const wrt_ctree *t = &b->cl->tree;
    double tight = WRT_SERIES_TREE_TIGHT;
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0) s->tcw[s->troot[t->slot[p]]] *= tight;
    s->tcw[s->troot[t->root_slot]] *= tight;
    series_tree_apart(s); /* with T unformed, the sum's first state too */
    wrt_series_mark(s, "nodes apart, the sum");
    if (!s->no_t) {
        /* T formed: the sum from its copy, its other columns uncompressed, as the quads'
         * series' sum starts; the compressed T (series_first_terms) stays the right factor
         * where it was the first term too */
        s->S = wrt_csc_copy(s->T);
        wrt_clusters_senders(t, s->troot, &s->S, s->eps, &s->TW, 1, &res->c.cluster_senders_raw);
        if (s->shared) s->Tr = s->P;
        else wrt_csc_free(&s->P);
        memset(&s->P, 0, sizeof s->P);
        s->shared = 0;
    }
    /* by blocks in one process, the first term's column starts alone (its entries made
     * per block); else (wrt-bake-mpi's cuts read it, or the whole-term series) whole */
    if (wrt_series_cols_on(s) && !wrt_dist_on(b->opt.dist)) s->P = first_counts(s, &s->S);
    else s->P = wrt_series_first_range(s, &s->S, 0, s->S.n);
    res->c.cluster_senders_basis = 1;
    res->c.cluster_senders_quads = 0;
}

/* ---- The left factor kept factored (docs/clusters.md "The left factor kept factored"):
 * T = E1 U, E1 with the cluster links' receivers pushed down to the quads and their
 * senders not (column nf + B: phi_B), U the uniform pull-up of the senders
 * (wrt_clusters_pull_up). A product T D P_k is then E1 (U D P_k): U D P_k is the term with
 * one row per linked node, Y_B = sum over B's quads of sqrt(a_q / a_B) times the term's
 * row at q's root, and the product reads E1's column of phi_B once per entry of that row
 * instead of T's columns of all of B's quads, each of which held the link's |A| entries.
 * Used by the series in the senders' tree basis (by default; --clusters-pushed: T with
 * the links pushed down, as before) where the bake kept E1 and the scene has no angular functions (the glossy balance
 * changes T after E1 is taken). */
int wrt_series_factored_wanted(const bake_ctx *b) {
    return wrt_series_tree_on(b) && b->opt.cluster_factored >= 0;
}

int wrt_series_factored_on(const bake_ctx *b, const wrt_bake_result *res) {
    return wrt_series_factored_wanted(b) && res->dto_e1.col && res->c.nfuncs_angular == 0;
}

/* The right factor's memory (wrt_series_factored_start, _bands): Tr, E1 compressed (at
 * most E1's entries, 16 bytes each), and its bands' index (wrt_series_factored_bands: put in
 * Tr's own arrays since session 18, not copied): a bound, not a measured factor */
wrt_status wrt_series_factored_check(const series_state *s) {
    const wrt_csc *E1 = &s->res->dto_e1;
    uint64_t n = (uint64_t)E1->n + 1;
    uint64_t need = 16 * E1->nnz + 8 * n + (s->b->opt.series_skip > 0 ? wrt_csc_bands_index_bytes(E1->n) : 0);
    return wrt_bake_memory_check(s->b->opt.max_memory_mb, &s->res->c.mem_estimate_mb, need,
                                 "the series' right factor");
}

/* Tr = E1 compressed at the products' threshold: a node column's entry weighed as a
 * sender of the node's area (sqrt(a_B), the small senders' factor of a node under the
 * share), a quad function's as in T; the products' weights with the node columns'; E1
 * freed. The coarse cut is series.c's, on Tr's function columns. */
void wrt_series_factored_start(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_result *res = s->res;
    const wrt_ctree *t = &b->cl->tree;
    uint32_t nf = res->nfuncs, ne = res->dto_e1.n;
    double small = wrt_series_small_area(b);
    double *cw = wrt_xmalloc(((size_t)ne + 1) * sizeof *cw), *boost = wrt_xmalloc(((size_t)ne + 1) * sizeof *boost);
    s->fcw = wrt_xmalloc(((size_t)ne + 1) * sizeof *s->fcw);
    s->fboost = wrt_xmalloc(((size_t)ne + 1) * sizeof *s->fboost);
    for (uint32_t c = 0; c <= ne; c++) {
        int node = c >= nf && c < ne;
        double a = node ? t->area[c - nf] : 0;
        cw[c] = node ? sqrt(a) : c < nf && s->W.col_w ? s->W.col_w[c] : 1;
        boost[c] = node ? (a < small ? small / a : 1) : c < nf && s->W.boost_w ? s->W.boost_w[c] : 1;
        s->fcw[c] = c < nf && s->TW.col_w ? s->TW.col_w[c] : 1;
        s->fboost[c] = c < nf && s->TW.boost_w ? s->TW.boost_w[c] : 1;
    }
    wrt_csc_weights W1 = s->W;
    W1.col_w = cw;
    W1.boost_w = s->W.boost_w ? boost : NULL;
    s->FW = s->TW;
    s->FW.col_w = s->fcw;
    s->FW.boost_w = s->TW.boost_w ? s->fboost : NULL;
    double right = b->opt.series_right > 0 ? b->opt.series_right : 0;
    s->Tr = right > 0 ? wrt_csc_copy_compress(&res->dto_e1, right * s->eps, &W1) : wrt_csc_copy(&res->dto_e1);
    s->shared = 0;
    if (b->opt.cluster_factored < 2 && !s->no_t) wrt_csc_free(&res->dto_e1); /* 2: kept in the result (tests) */
    free(cw); free(boost);
}

/* Tr's entries by size, once Tr is final (compressed and cut): the products then skip the
 * contributions under series_skip x eps (sparse.h wrt_csc_bands; docs/clusters.md
 * "Contributions under the threshold not summed") */
void wrt_series_factored_bands(series_state *s) {
    if (!(s->b->opt.series_skip > 0)) return;
    /* Tr's columns put in the bands' order in place (its other readers, the pull-up and
     * the ranks' cuts, read only its column counts): Tr keeps the entries, one copy held
     * (series.c series_free_right), and none made beside it (until session 18 the bands
     * were a copy, Tr's freed after: a second Tr at the series' start, the bake's peak on
     * the 53,122-element atrium at quality 5) */
    wrt_csc_bands_make_in_place(&s->Tr, s->FW.row_w, s->FW.power_w, &s->Trb, s->threads);
    s->FW.bands = &s->Trb;
    s->FW.skip = s->b->opt.series_skip;
}

/* U P: the term with its node rows, for the product E1 (U P) */
wrt_csc wrt_series_factored_right(const series_state *s, const wrt_csc *P) {
    const bake_ctx *b = s->b;
    return wrt_clusters_pull_up(&b->cl->tree, s->troot, (uint32_t)b->nq, &s->Tr, s->res->nfuncs, P, s->threads);
}

/* The product's columns back to the functions' (the node columns are empty) */
void wrt_series_factored_trim(const series_state *s, wrt_csc *N) {
    uint32_t nf = s->res->nfuncs;
    if (N->n <= nf) return;
    N->n = nf;
    N->col = wrt_xrealloc(N->col, ((size_t)nf + 1) * sizeof *N->col);
}

/* P back from U P: its rows of the functions, the first columns */
wrt_csc wrt_series_factored_left(const series_state *s, const wrt_csc *X) {
    uint32_t nf = s->res->nfuncs;
    wrt_csc P = {.n = nf};
    P.col = wrt_xcalloc((size_t)nf + 1, sizeof *P.col);
    uint64_t n = 0;
    for (uint32_t c = 0; c < nf && c < X->n; c++)
        for (uint64_t k = X->col[c]; k < X->col[c + 1]; k++) n += X->row[k] < nf;
    P.row = wrt_xmalloc((n ? n : 1) * sizeof *P.row);
    P.val = wrt_xmalloc((n ? n : 1) * 3 * sizeof *P.val);
    n = 0;
    for (uint32_t c = 0; c < nf; c++) {
        if (c < X->n)
            for (uint64_t k = X->col[c]; k < X->col[c + 1]; k++) {
                if (X->row[k] >= nf) continue;
                P.row[n] = X->row[k];
                memcpy(&P.val[3 * n], &X->val[3 * k], 3 * sizeof *P.val);
                n++;
            }
        P.col[c + 1] = n;
    }
    P.nnz = n;
    return P;
}

/* By shares, the sum's first state (whole, wrt_series_tree_start) cut to this rank's
 * columns [c0, c1), the others empty */
void wrt_series_tree_sum_start(series_state *s, uint32_t c0, uint32_t c1) {
    uint32_t n = s->S.n;
    if (c0 == 0 && c1 == n) return;
    /* the range kept, in place: the columns before it dropped, its entries moved down */
    wrt_csc *m = &s->S;
    uint64_t a = m->col[c0], z = m->col[c1];
    memmove(m->row, m->row + a, (z - a) * sizeof *m->row);
    memmove(m->val, m->val + 3 * a, (z - a) * 3 * sizeof *m->val);
    for (uint32_t j = 0; j < c0; j++) m->col[j + 1] = 0;
    for (uint32_t j = c0; j < c1; j++) m->col[j + 1] -= a;
    for (uint32_t j = c1; j < n; j++) m->col[j + 1] = z - a;
    m->nnz = z - a;
    m->row = wrt_xrealloc(m->row, (m->nnz ? m->nnz : 1) * sizeof *m->row);
    m->val = wrt_xrealloc(m->val, (m->nnz ? m->nnz : 1) * 3 * sizeof *m->val);
}

/* --clusters: the stored operator's columns in the tree's basis (cluster_send.c), each
 * tree column compressed by the stored operator's rule (wrt_series_final_weights) with its
 * node's weight sqrt(a_P), and the small senders' factor (series_small_area) on the psi_P
 * of a node under the share as on a small quad's mean: a cluster of small quads holds its
 * far light at the kernel's level as each of its quads did, once for the cluster. Kept
 * where it has fewer entries (b->opt.cluster_senders). Measured on the atrium at 2,704
 * elements, quality 1, against the path tracer (docs/clusters.md): without the factor on
 * the psi_P, 1.99M entries and cells +0.41 points, with its square root 2.47M and +0.22,
 * with it 3.51M and +0.10 (the quads' basis: 6.58M). */
void wrt_series_senders(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_result *res = s->res;
    wrt_csc_weights W;
    double *own;
    double eps = wrt_series_final_weights(s, &W, &own);
    uint32_t *root = wrt_clusters_root_index(res->fkeys, res->nfuncs, (uint32_t)b->nq);
    double *cw, *boost;
    wrt_series_tree_cols(s, root, W.col_w, &cw, &boost);
    W.col_w = cw;
    W.boost_w = boost; /* only the tree's columns are compressed here */
    res->c.cluster_senders_quads = s->S.nnz;
    res->c.cluster_senders_basis = wrt_clusters_senders(&b->cl->tree, root, &s->S, eps, &W, b->opt.cluster_senders > 0,
                                                        &res->c.cluster_senders_raw);
    res->c.entries_gto = s->S.nnz;
    free(root); free(cw); free(boost); free(own);
}
