/* cluster_send.c: the stored operator with the cluster tree's basis on the senders' side
 * only, G W^T (cluster.h, docs/clusters.md "The senders' side in the tree's basis").
 *
 * The small senders' rule (series.c) holds a small quad's mean-to-mean light to every
 * receiver whose kernel is above a fixed share: one entry per (small sender, receiver),
 * O(N^2) in the quads' basis. Seen from a receiver far from a cluster, its quads' entries
 * are proportional to sqrt(a_q) (the same kernel over the cluster): then the cluster's
 * scaling function phi_C = sum_q sqrt(a_q / a_C) phi_q carries them all, and the wavelets
 * psi_P below C (the differences of the halves) are near 0 there and are dropped. So the
 * quads' root columns are replaced by the columns of the tree's orthonormal functions
 * (phi_root and every internal node's psi_P, in the slots of common/cluster_tree.h's
 * bijection), built bottom-up per node (phi_P = wL phi_L + wR phi_R, psi_P = wR phi_L -
 * wL phi_R, on the columns), each psi_P compressed as soon as it is made with the
 * series' rule (its weight sqrt(a_P), the small senders' factor of a node under the
 * share); the rows stay the quads'. Only the columns of the current path from the root
 * are held uncompressed (depth x one column), so memory is the result's.
 * The transform is exact (orthonormal); what compression drops is what the psi_P carry
 * under the threshold, and each column's power is kept (the dropped power handed to the
 * kept entries, sparse.c). The runtime takes the projected light forward to the tree's
 * basis (O(N)) and multiplies; the result is in the quads' basis, no inverse.
 * Depends on cluster.h, sparse.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "cluster.h"

/* a column in double precision: rows ascending */
typedef struct dcol_s {
    uint32_t *row;
    double *val; /* 3 per row */
    uint64_t n;
} dcol;

typedef struct {
    const wrt_ctree *t;
    const uint32_t *root; /* per quad: its root slot */
    const wrt_csc *M;
    wrt_col_fn fn;        /* or the columns from here (M NULL) */
    void *user;
    uint32_t c0, c1;      /* the slots stored: [c0, c1) */
    double drop;
    const wrt_csc_weights *W;
    uint32_t **orow;      /* per slot: the tree function's compressed column */
    float **oval;
    uint64_t *on;
    uint64_t raw;         /* the tree columns' entries before compression */
    const double *pw;     /* wrt_clusters_apart: the rows' power weights, and per node the */
    uint8_t *apart;       /* result (orow NULL: nothing is emitted) */
    double *apart_w, apart_f; /* emitting: the weight of a node apart's slot times apart_f first */
    void *const *users;   /* send_split: one fn user a thread (users[0] is user) */
    int nusers;
    struct dcol_s *pre;   /* send_split: the subtrees' phi columns made on the threads, */
    uint8_t *pre_have;    /* per node, taken by node_phi instead of walking them */
} send_ctx;

static void dcol_free(dcol *c) {
    free(c->row); free(c->val);
    c->row = NULL; c->val = NULL; c->n = 0;
}

/* compresses the column c (float copy) as slot's and stores it */
static void emit(send_ctx *x, uint32_t slot, const uint32_t *row, const double *val, uint64_t n) {
    if (slot < x->c0 || slot >= x->c1) { /* not kept: counted (raw) as a whole walk's */
        for (uint64_t i = 0; i < n; i++)
            x->raw += (float)val[3 * i] != 0 || (float)val[3 * i + 1] != 0 || (float)val[3 * i + 2] != 0;
        return;
    }
    uint32_t *r = wrt_xmalloc((n ? n : 1) * sizeof *r);
    float *v = wrt_xmalloc((n ? n : 1) * 3 * sizeof *v);
    uint64_t k = 0;
    for (uint64_t i = 0; i < n; i++) {
        float f[3] = {(float)val[3 * i], (float)val[3 * i + 1], (float)val[3 * i + 2]};
        if (f[0] == 0 && f[1] == 0 && f[2] == 0) continue;
        r[k] = row[i];
        memcpy(&v[3 * k], f, sizeof f);
        k++;
    }
    x->raw += k;
    k = wrt_csc_compress_col(r, v, k, slot, x->drop, x->W);
    /* held at the compressed size: kept at the column's full length, the slots held the
     * uncompressed tree columns' bytes until the walk ended (T's own size: at 43,780
     * atrium elements 15.6 GB of the series' start, against a result of 1.5 GB) */
    r = wrt_xrealloc(r, (k ? k : 1) * sizeof *r);
    v = wrt_xrealloc(v, (k ? k : 1) * 3 * sizeof *v);
    x->orow[slot] = r; x->oval[slot] = v; x->on[slot] = k;
}

static double cmax(const double *v) { /* no NaN here: fmax's calls were 3% of the walk */
    double a = fabs(v[0]), b = fabs(v[1]), c = fabs(v[2]);
    double m = a > b ? a : b;
    return m > c ? m : c;
}

/* Whether node p's halves are apart (wrt_clusters_apart): of the light of each half (the
 * columns wr phi_L and wl phi_R, each row's largest channel times its power weight), the
 * share that lands on rows the other half's light reaches too (the smaller of the two
 * there), under WRT_CLUSTER_APART of the smaller half's: 1 for halves whose light meets
 * everywhere, 0 for two rooms that do not see each other. */
static int halves_apart(const send_ctx *x, const dcol *L, const dcol *R, double wl, double wr) {
    double a = 0, b = 0, both = 0;
    uint64_t i = 0, j = 0;
    while (i < L->n || j < R->n) {
        int l = j >= R->n || (i < L->n && L->row[i] <= R->row[j]);
        int r = i >= L->n || (j < R->n && R->row[j] <= L->row[i]);
        double u = l ? wr * cmax(&L->val[3 * i]) : 0, v = r ? wl * cmax(&R->val[3 * j]) : 0;
        double p = x->pw[l ? L->row[i] : R->row[j]];
        a += p * u;
        b += p * v;
        both += p * fmin(u, v);
        i += l;
        j += r;
    }
    double small = fmin(a, b);
    return small > 0 && both < WRT_CLUSTER_APART * small;
}

/* phi of node p's column; psi of every internal node below (and p) emitted */
static dcol node_phi(send_ctx *x, uint32_t p) {
    const wrt_ctree *t = x->t;
    dcol out = {0};
    if (x->pre_have && x->pre_have[p]) { /* walked on a thread (send_split) */
        x->pre_have[p] = 0;
        return x->pre[p];
    }
    if (t->left[p] < 0) {
        uint32_t c = x->root[t->right[p]];
        const uint32_t *row = NULL;
        const float *val = NULL;
        uint32_t *frow = NULL;
        float *fval = NULL;
        if (x->M) {
            out.n = x->M->col[c + 1] - x->M->col[c];
            row = x->M->row + x->M->col[c];
            val = x->M->val + 3 * x->M->col[c];
        } else {
            out.n = x->fn(x->user, c, &frow, &fval);
            row = frow;
            val = fval;
        }
        out.row = wrt_xmalloc((out.n ? out.n : 1) * sizeof *out.row);
        out.val = wrt_xmalloc((out.n ? out.n : 1) * 3 * sizeof *out.val);
        for (uint64_t k = 0; k < out.n; k++) {
            out.row[k] = row[k];
            for (int ch = 0; ch < 3; ch++) out.val[3 * k + ch] = val[3 * k + ch];
        }
        free(frow); free(fval);
        return out;
    }
    dcol L = node_phi(x, (uint32_t)t->left[p]);
    dcol R = node_phi(x, (uint32_t)t->right[p]);
    double wl = sqrt(t->area[t->left[p]] / t->area[p]), wr = sqrt(t->area[t->right[p]] / t->area[p]);
    uint64_t cap = L.n + R.n;
    out.row = wrt_xmalloc((cap ? cap : 1) * sizeof *out.row);
    out.val = wrt_xmalloc((cap ? cap : 1) * 3 * sizeof *out.val);
    double *dv = wrt_xmalloc((cap ? cap : 1) * 3 * sizeof *dv);
    uint64_t i = 0, j = 0, n = 0;
    while (i < L.n || j < R.n) {
        uint32_t r;
        double sl[3] = {0, 0, 0}, sr[3] = {0, 0, 0};
        if (j >= R.n || (i < L.n && L.row[i] < R.row[j])) {
            r = L.row[i];
            memcpy(sl, &L.val[3 * i++], sizeof sl);
        } else if (i >= L.n || R.row[j] < L.row[i]) {
            r = R.row[j];
            memcpy(sr, &R.val[3 * j++], sizeof sr);
        } else {
            r = L.row[i];
            memcpy(sl, &L.val[3 * i++], sizeof sl);
            memcpy(sr, &R.val[3 * j++], sizeof sr);
        }
        out.row[n] = r;
        for (int ch = 0; ch < 3; ch++) {
            out.val[3 * n + ch] = wl * sl[ch] + wr * sr[ch];
            dv[3 * n + ch] = wr * sl[ch] - wl * sr[ch];
        }
        n++;
    }
    out.n = n;
    if (x->apart) x->apart[p] = halves_apart(x, &L, &R, wl, wr) || x->apart[t->left[p]] || x->apart[t->right[p]];
    if (x->apart_w && x->apart[p]) x->apart_w[x->root[t->slot[p]]] *= x->apart_f;
    dcol_free(&L);
    dcol_free(&R);
    if (x->orow) emit(x, x->root[t->slot[p]], out.row, dv, n);
    free(dv);
    return out;
}

typedef struct {
    send_ctx *cx; /* one a thread */
    const uint32_t *nodes;
    dcol *pre;
} split_ctx;

static void split_run(size_t i, int th, void *user) {
    split_ctx *sc = user;
    sc->pre[sc->nodes[i]] = node_phi(&sc->cx[th], sc->nodes[i]);
}

/* With a fn user a thread: the tree cut at the first level with 8 subtrees a thread (or
 * 256; the leaves above it kept), each subtree walked on a thread with its own user, its
 * phi column kept for node_phi, its tree columns emitted into their own slots and its
 * halves' test into its own nodes; the walk from the root then takes them. The same
 * columns, bits and counts as one thread (raw: a sum of counts). */
static void send_split(send_ctx *x) {
    const wrt_ctree *t = x->t;
    if (x->nusers < 2 || t->nnodes < 2) return;
    uint32_t cap = 2 * 256 + 2, n = 1, *nodes = wrt_xmalloc(cap * sizeof *nodes), *next = wrt_xmalloc(cap * sizeof *next);
    nodes[0] = 0;
    while (n < 8 * (uint32_t)x->nusers && n < 256) {
        uint32_t m = 0, grew = 0;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t p = nodes[i];
            if (t->left[p] >= 0) {
                next[m++] = (uint32_t)t->left[p];
                next[m++] = (uint32_t)t->right[p];
                grew = 1;
            } else {
                next[m++] = p;
            }
        }
        uint32_t *tmp = nodes;
        nodes = next;
        next = tmp;
        n = m;
        if (!grew) break;
    }
    send_ctx *cx = wrt_xmalloc((size_t)x->nusers * sizeof *cx);
    for (int i = 0; i < x->nusers; i++) {
        cx[i] = *x;
        cx[i].user = x->users[i];
        cx[i].raw = 0;
        cx[i].pre = NULL;
        cx[i].pre_have = NULL;
    }
    x->pre = wrt_xcalloc((size_t)t->nnodes + 1, sizeof *x->pre);
    x->pre_have = wrt_xcalloc((size_t)t->nnodes + 1, 1);
    split_ctx sc = {cx, nodes, x->pre};
    wrt_parallel_for(n, x->nusers, split_run, &sc);
    for (int i = 0; i < x->nusers; i++) x->raw += cx[i].raw;
    for (uint32_t i = 0; i < n; i++) x->pre_have[nodes[i]] = 1;
    free(cx); free(nodes); free(next);
}

static void send_split_free(send_ctx *x) {
    free(x->pre); free(x->pre_have);
    x->pre = NULL;
    x->pre_have = NULL;
}

/* The tree walked: every tree column made, compressed and kept in its slot (x's arrays,
 * allocated here for nf functions); the functions that are tree slots marked (returned) */
static uint8_t *send_walk(send_ctx *x, uint32_t nf) {
    const wrt_ctree *t = x->t;
    x->orow = wrt_xcalloc((size_t)nf + 1, sizeof *x->orow);
    x->oval = wrt_xcalloc((size_t)nf + 1, sizeof *x->oval);
    x->on = wrt_xcalloc((size_t)nf + 1, sizeof *x->on);
    uint8_t *tree = wrt_xcalloc((size_t)nf + 1, 1);
    for (uint32_t q = 0; q < t->nq; q++) tree[x->root[q]] = 1;
    send_split(x);
    dcol top = node_phi(x, 0);
    send_split_free(x);
    if (x->apart_w && x->apart[0]) x->apart_w[x->root[t->root_slot]] *= x->apart_f;
    emit(x, x->root[t->root_slot], top.row, top.val, top.n);
    dcol_free(&top);
    return tree;
}

void wrt_clusters_apart(const wrt_ctree *t, const uint32_t *root, const wrt_csc *M, wrt_col_fn fn, void *user,
                        const double *pw, uint8_t *apart) {
    wrt_clusters_apart_th(t, root, M, fn, &user, 1, pw, apart);
}

void wrt_clusters_apart_th(const wrt_ctree *t, const uint32_t *root, const wrt_csc *M, wrt_col_fn fn,
                           void *const *users, int nusers, const double *pw, uint8_t *apart) {
    send_ctx x = {.t = t, .root = root, .M = M, .fn = fn, .user = users[0], .pw = pw, .apart = apart,
                  .users = users, .nusers = nusers};
    memset(apart, 0, t->nnodes);
    send_split(&x);
    dcol top = node_phi(&x, 0);
    send_split_free(&x);
    dcol_free(&top);
}

int wrt_clusters_senders(const wrt_ctree *t, const uint32_t *root, wrt_csc *M, double drop,
                         const wrt_csc_weights *W, int always, uint64_t *raw) {
    uint32_t nf = M->n;
    send_ctx x = {.t = t, .root = root, .M = M, .c1 = nf, .drop = drop, .W = W};
    uint8_t *tree = send_walk(&x, nf);
    /* the result: the tree columns in their slots, the other columns as they were; kept
     * only where it has fewer entries (or always) */
    uint64_t total = 0;
    for (uint32_t c = 0; c < nf; c++) total += tree[c] ? x.on[c] : M->col[c + 1] - M->col[c];
    *raw = x.raw;
    int use = always || total < M->nnz;
    if (!use) {
        for (uint32_t c = 0; c < nf; c++) { free(x.orow[c]); free(x.oval[c]); }
        free(x.orow); free(x.oval); free(x.on); free(tree);
        return 0;
    }
    /* built in M's own arrays, not beside them (here the whole gathered operator: on rank
     * 0 of wrt-bake-mpi the bake's peak, docs/mpi.md session 10): the columns are written
     * in order over what is read already, M's entries moved up first by the most that a
     * column's new end passes the next column's old start (d) */
    uint64_t k = 0, d = 0, nnz = M->nnz;
    for (uint32_t c = 0; c < nf; c++) {
        k += tree[c] ? x.on[c] : M->col[c + 1] - M->col[c];
        if (k > M->col[c + 1] && k - M->col[c + 1] > d) d = k - M->col[c + 1];
    }
    if (d) {
        M->row = wrt_xrealloc(M->row, (nnz + d) * sizeof *M->row);
        M->val = wrt_xrealloc(M->val, (nnz + d) * 3 * sizeof *M->val);
        memmove(&M->row[d], M->row, nnz * sizeof *M->row);
        memmove(&M->val[3 * d], M->val, 3 * nnz * sizeof *M->val);
    }
    uint64_t a = M->col[0] + d;
    k = 0;
    for (uint32_t c = 0; c < nf; c++) {
        uint64_t e = M->col[c + 1] + d;
        if (tree[c]) {
            memcpy(&M->row[k], x.orow[c], x.on[c] * sizeof *M->row);
            memcpy(&M->val[3 * k], x.oval[c], 3 * x.on[c] * sizeof *M->val);
            k += x.on[c];
            free(x.orow[c]); free(x.oval[c]);
        } else {
            memmove(&M->row[k], &M->row[a], (e - a) * sizeof *M->row);
            memmove(&M->val[3 * k], &M->val[3 * a], 3 * (e - a) * sizeof *M->val);
            k += e - a;
        }
        M->col[c + 1] = k;
        a = e;
    }
    M->nnz = total;
    M->row = wrt_xrealloc(M->row, (total ? total : 1) * sizeof *M->row);
    M->val = wrt_xrealloc(M->val, (total ? total : 1) * 3 * sizeof *M->val);
    free(x.orow); free(x.oval); free(x.on); free(tree);
    return 1;
}

wrt_csc wrt_clusters_senders_cols(const wrt_ctree *t, const uint32_t *root, uint32_t nf, wrt_col_fn fn, void *user,
                                  double drop, const wrt_csc_weights *W, uint32_t c0, uint32_t c1, uint64_t *raw) {
    return wrt_clusters_senders_cols_th(t, root, nf, fn, &user, 1, drop, W, c0, c1, raw);
}

wrt_csc wrt_clusters_senders_cols_th(const wrt_ctree *t, const uint32_t *root, uint32_t nf, wrt_col_fn fn,
                                     void *const *users, int nusers, double drop, const wrt_csc_weights *W,
                                     uint32_t c0, uint32_t c1, uint64_t *raw) {
    return wrt_clusters_senders_cols_apart(t, root, nf, fn, users, nusers, drop, W, c0, c1, raw, NULL);
}

wrt_csc wrt_clusters_senders_cols_apart(const wrt_ctree *t, const uint32_t *root, uint32_t nf, wrt_col_fn fn,
                                        void *const *users, int nusers, double drop, const wrt_csc_weights *W,
                                        uint32_t c0, uint32_t c1, uint64_t *raw, const wrt_apart_opt *ap) {
    void *user = users[0];
    send_ctx x = {.t = t, .root = root, .fn = fn, .user = user, .c0 = c0, .c1 = c1, .drop = drop, .W = W,
                  .users = users, .nusers = nusers};
    if (ap) { /* the halves' test on the same columns, their weights raised as it decides */
        x.pw = ap->pw;
        x.apart = ap->apart;
        x.apart_w = ap->w;
        x.apart_f = ap->factor;
        memset(ap->apart, 0, t->nnodes);
    }
    uint8_t *tree = send_walk(&x, nf);
    /* the columns in order, appended (the arrays grow by doubling: realloc moves large
     * blocks by remapping, so the result is held about once) */
    wrt_csc M = {.n = nf};
    M.col = wrt_xcalloc((size_t)nf + 1, sizeof *M.col);
    uint64_t cap = 1024, k = 0;
    M.row = wrt_xmalloc(cap * sizeof *M.row);
    M.val = wrt_xmalloc(cap * 3 * sizeof *M.val);
    for (uint32_t c = 0; c < nf; c++) {
        uint32_t *r = NULL;
        float *v = NULL;
        uint64_t n = 0;
        if (tree[c]) { r = x.orow[c]; v = x.oval[c]; n = x.on[c]; }
        else if (c >= c0 && c < c1) n = fn(user, c, &r, &v);
        if (k + n > cap) {
            while (k + n > cap) cap *= 2;
            M.row = wrt_xrealloc(M.row, cap * sizeof *M.row);
            M.val = wrt_xrealloc(M.val, cap * 3 * sizeof *M.val);
        }
        if (n) {
            memcpy(&M.row[k], r, n * sizeof *r);
            memcpy(&M.val[3 * k], v, 3 * n * sizeof *v);
        }
        k += n;
        free(r); free(v);
        M.col[c + 1] = k;
    }
    M.nnz = k;
    M.row = wrt_xrealloc(M.row, (k ? k : 1) * sizeof *M.row);
    M.val = wrt_xrealloc(M.val, (k ? k : 1) * 3 * sizeof *M.val);
    *raw = x.raw;
    free(x.orow); free(x.oval); free(x.on); free(tree);
    return M;
}
