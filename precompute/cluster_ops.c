/* cluster_ops.c: the operator of the `--clusters` bake in the cluster tree's orthonormal
 * basis (cluster.h, common/cluster_tree.h, docs/clusters.md).
 *
 * T arrives in the quads' basis, balanced pair by pair (balance.c, in its open-scene
 * mode). Its rows and columns are extended by one index per tree node, nf + node, the
 * node's scaling function phi_node; the cluster links are entries there. In a closed
 * scene each column's power is then made what its function emits, rho int h sqrt(J)
 * (balance.c's rule, which the per-pair balance cannot apply when part of a column's
 * light travels by cluster links): a quad's root column delivers its own entries plus
 * sqrt(a_q / a_B) times the column of phi_B of every ancestor B; the difference is
 * spread over those contributions in proportion to their power, as new entries in the
 * quad's column (so light only grows where it already went: the dark room of two rooms
 * gets none). Last, the rows and then the columns are taken to the tree basis: each
 * column's coefficients on phi_node (quad roots are the leaves') are pushed up the tree,
 * (s_L, s_R) -> (s_P = wL s_L + wR s_R, d_P = wR s_L - wL s_R), and d_P lands in psi_P's
 * root slot, s_root in phi_root's (common/cluster_tree.h's bijection). The transform is
 * exact (orthonormal); the file then holds the same operator in another basis.
 * The series' products use T factored, T = E1 U (wrt_clusters_assemble's E1: the links'
 * receivers pushed down, their senders on the nodes; wrt_clusters_pull_up: U X).
 * Depends on cluster.h, balance.h (power weights), links.h and sparse.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "balance.h"
#include "cluster.h"
#include "links.h"
#include "common/threads.h"

uint32_t *wrt_clusters_root_index(const uint64_t *fkeys, uint32_t nf, uint32_t nq) {
    uint32_t *r = wrt_xmalloc((nq ? nq : 1) * sizeof *r);
    for (uint32_t q = 0; q < nq; q++) {
        int64_t i = wrt_fkey_find(fkeys, nf, wrt_fkey_make(q, wrt_node_root(), 0, wrt_node_root(), 0));
        r[q] = i < 0 ? 0 : (uint32_t)i;
    }
    return r;
}

typedef struct ops {
    const wrt_ctree *t;
    uint32_t nf;
    const uint32_t *root;     /* per quad: its root slot */
    int32_t *node_of;         /* per function: the leaf node of a quad's root, else -1 */
    double *wl, *wr;          /* per internal node */
    const wrt_clusters *cl;
} ops;

static int32_t ext_node(const ops *o, uint32_t row) {
    return row >= o->nf ? (int32_t)(row - o->nf) : o->node_of[row];
}

/* Rows of every column of E to the tree basis; triplets out with row and column swapped
 * (so that building them gives the transpose). */
static wrt_triplet *row_transform(const ops *o, const wrt_csc *E, uint64_t *nout) {
    const wrt_ctree *t = o->t;
    size_t nn = t->nnodes;
    double *s = wrt_xcalloc(nn * 3, sizeof *s);
    uint32_t *mark = wrt_xcalloc(nn, sizeof *mark), *touched = wrt_xmalloc(nn * sizeof *touched);
    uint64_t cap = E->nnz + 16, n = 0;
    wrt_triplet *out = wrt_xmalloc(cap * sizeof *out);
    for (uint32_t c = 0; c < E->n; c++) {
        uint32_t nt = 0, epoch = c + 1;
        for (uint64_t k = E->col[c]; k < E->col[c + 1]; k++) {
            uint32_t r = E->row[k];
            const float *v = &E->val[3 * k];
            int32_t p = ext_node(o, r);
            if (p < 0) {
                if (n + 1 > cap) { cap *= 2; out = wrt_xrealloc(out, cap * sizeof *out); }
                out[n++] = (wrt_triplet){c, r, {v[0], v[1], v[2]}};
                continue;
            }
            for (int ch = 0; ch < 3; ch++) s[(size_t)p * 3 + ch] += v[ch];
            for (int32_t q = p; q >= 0 && mark[q] != epoch; q = t->parent[q]) { mark[q] = epoch; touched[nt++] = (uint32_t)q; }
        }
        if (!nt) continue;
        /* children before parents: descending node numbers */
        for (uint32_t i = 1; i < nt; i++) { /* insertion sort: short lists, mostly in order */
            uint32_t x = touched[i], j = i;
            while (j > 0 && touched[j - 1] < x) { touched[j] = touched[j - 1]; j--; }
            touched[j] = x;
        }
        if (n + nt + 1 > cap) { cap = 2 * (n + nt + 1); out = wrt_xrealloc(out, cap * sizeof *out); }
        for (uint32_t i = 0; i < nt; i++) {
            uint32_t p = touched[i];
            if (t->left[p] < 0) continue;
            int32_t L = t->left[p], R = t->right[p];
            double wl = o->wl[p], wr = o->wr[p];
            float dv[3];
            for (int ch = 0; ch < 3; ch++) {
                double sl = s[(size_t)L * 3 + ch], sr = s[(size_t)R * 3 + ch];
                s[(size_t)p * 3 + ch] += wl * sl + wr * sr;
                dv[ch] = (float)(wr * sl - wl * sr);
            }
            if (dv[0] != 0 || dv[1] != 0 || dv[2] != 0) out[n++] = (wrt_triplet){c, o->root[t->slot[p]], {dv[0], dv[1], dv[2]}};
        }
        if (mark[0] == epoch) {
            float sv[3] = {(float)s[0], (float)s[1], (float)s[2]};
            if (sv[0] != 0 || sv[1] != 0 || sv[2] != 0) out[n++] = (wrt_triplet){c, o->root[t->root_slot], {sv[0], sv[1], sv[2]}};
        }
        for (uint32_t i = 0; i < nt; i++)
            for (int ch = 0; ch < 3; ch++) s[(size_t)touched[i] * 3 + ch] = 0;
    }
    free(s); free(mark); free(touched);
    *nout = n;
    return out;
}

/* The centre of the extended index c's support: a node's box centre, a quad root's quad's
 * centre; 0 if c is neither (no direction known). */
static int ext_centre(const ops *o, const bake_ctx *b, uint32_t c, wrt_v3 *x) {
    const wrt_clusters *cl = o->cl;
    int32_t p = ext_node(o, c);
    if (p < 0) return 0;
    if (c < o->nf) {
        const wrt_quad *q = &b->quads[o->cl->tree.right[p]];
        *x = wrt_quad_point(q, 0.5, 0.5);
    } else {
        *x = v3_scale(v3_add(cl->bmin[p], cl->bmax[p]), 0.5);
    }
    return 1;
}

/* The push-down weights of node A's quads toward the point y: w_q = max(0, n_q . (y -
 * x_q) / |y - x_q|), normalised so that sum_q a_q w_q = a_A (the link's power is kept:
 * the closed rule, applied on the nodes, still holds); all 1 (uniform) if no quad faces
 * y. A quad facing away from the other end of a link gets none of its light (a column's
 * back, the far side of a cluster seen edge-on). */
static void orient_weights(const ops *o, const bake_ctx *b, uint32_t A, wrt_v3 y, double *w) {
    const wrt_clusters *cl = o->cl;
    const wrt_ctree *t = o->t;
    double s = 0;
    for (uint32_t i = cl->lo[A]; i < cl->hi[A]; i++) {
        const wrt_quad *q = &b->quads[cl->perm[i]];
        wrt_v3 d = v3_sub(y, wrt_quad_point(q, 0.5, 0.5));
        double len = v3_len(d), c = len > 0 ? v3_dot(q->n, d) / len : 0;
        w[i - cl->lo[A]] = c > 0 ? c : 0;
        s += t->area[t->leaf[cl->perm[i]]] * w[i - cl->lo[A]];
    }
    double f = s > 0 ? t->area[A] / s : 0;
    for (uint32_t i = 0; i < cl->hi[A] - cl->lo[A]; i++) w[i] = f > 0 ? w[i] * f : 1;
}

/* Every column's entries on phi_node (rows >= nf) pushed down to the quads' roots,
 * phi_A = sum over quads q of A of sqrt(a_q / a_A) phi_q, each quad's share weighted by
 * its orientation toward the column's own support when orient (orient_weights; uniform
 * where the column has none); triplets out with row and column swapped, as
 * row_transform. Only the receivers (rows) are weighted: the receiving node's power is
 * kept so, while weighting the senders' side (the columns, on the transpose) would
 * change what each quad's column delivers, which the closed rule has already made what
 * it emits (furnace 0.99: flux 0.944 of the truth when both sides were weighted). */
static wrt_triplet *push_down(const ops *o, const bake_ctx *b, const wrt_csc *E, int orient, uint64_t *nout) {
    const wrt_clusters *cl = o->cl;
    const wrt_ctree *t = o->t;
    uint64_t cap = E->nnz + 16, n = 0;
    wrt_triplet *out = wrt_xmalloc(cap * sizeof *out);
    double *w = wrt_xmalloc(((size_t)b->nq + 1) * sizeof *w);
    for (uint32_t c = 0; c < E->n; c++) {
        wrt_v3 y;
        int dir = orient && ext_centre(o, b, c, &y);
        for (uint64_t k = E->col[c]; k < E->col[c + 1]; k++) {
            uint32_t r = E->row[k];
            const float *v = &E->val[3 * k];
            uint32_t lo = 0, hi = 0;
            if (r >= o->nf) { lo = cl->lo[r - o->nf]; hi = cl->hi[r - o->nf]; }
            if (n + (hi - lo) + 1 > cap) { cap = 2 * (n + (hi - lo) + 1); out = wrt_xrealloc(out, cap * sizeof *out); }
            if (r < o->nf) { out[n++] = (wrt_triplet){c, r, {v[0], v[1], v[2]}}; continue; }
            uint32_t A = r - o->nf;
            double aA = t->area[A];
            if (dir) orient_weights(o, b, A, y, w);
            for (uint32_t i = lo; i < hi; i++) {
                uint32_t q = cl->perm[i];
                double wq = sqrt(t->area[t->leaf[q]] / aA) * (dir ? w[i - lo] : 1);
                if (wq == 0) continue;
                out[n++] = (wrt_triplet){c, o->root[q], {(float)(wq * v[0]), (float)(wq * v[1]), (float)(wq * v[2])}};
            }
        }
    }
    free(w);
    *nout = n;
    return out;
}

/* Power weight of every extended index: the quads' functions' (balance.c), and phi_node's. */
static double *ext_power(const bake_ctx *b, const ops *o, const uint64_t *fkeys) {
    const wrt_ctree *t = o->t;
    double *pw = wrt_power_weights(b, fkeys, o->nf);
    pw = wrt_xrealloc(pw, ((size_t)o->nf + t->nnodes + 1) * sizeof *pw);
    double *pn = pw + o->nf;
    for (uint32_t p = t->nnodes; p-- > 0;)
        pn[p] = t->left[p] < 0 ? pw[o->root[t->right[p]]] : o->wl[p] * pn[t->left[p]] + o->wr[p] * pn[t->right[p]];
    return pw;
}

/* Is row r of the extended matrix a tree function (a quad's root or a node's phi)? */
static int tree_row(const ops *o, uint32_t r) { return ext_node(o, r) >= 0; }

/* One column's contributions to quad function j's power: pass 0 sums them (and their
 * magnitudes), pass 1 appends the correction entries. */
typedef struct fix_col {
    const ops *o; const wrt_csc *E; const double *pw;
    uint32_t j; double have[3], want[3], wsum[3];
    wrt_triplet *add; uint64_t n, cap;
} fix_col;

static void fix_visit(fix_col *fc, uint32_t col, double f, int direct, int pass) {
    const wrt_csc *E = fc->E;
    for (uint64_t k = E->col[col]; k < E->col[col + 1]; k++) {
        uint32_t r = E->row[k];
        double pr = fc->pw[r];
        if (pr == 0) continue;
        int tree = tree_row(fc->o, r) && pr > 0; /* the correction goes to these only */
        if (!tree && pass) continue;
        float dv[3];
        for (int ch = 0; ch < 3; ch++) {
            double g = pr * f * E->val[3 * k + ch];
            if (!pass) {
                /* a general quad's wavelet rows carry power too (wrt_func_power): a
                 * triangle's part receives as much again in them as its root misses */
                if (!direct) fc->have[ch] += g;
                if (tree) fc->wsum[ch] += fabs(g);
            } else {
                dv[ch] = fc->wsum[ch] > 0 ? (float)((fc->want[ch] - fc->have[ch]) * fabs(g) / fc->wsum[ch] / pr) : 0;
            }
        }
        if (!pass || (dv[0] == 0 && dv[1] == 0 && dv[2] == 0)) continue;
        if (fc->n + 1 > fc->cap) { fc->cap = 2 * fc->cap + 64; fc->add = wrt_xrealloc(fc->add, fc->cap * sizeof *fc->add); }
        fc->add[fc->n++] = (wrt_triplet){r, fc->j, {dv[0], dv[1], dv[2]}};
    }
}

/* Closed scene: each quad function's column made to deliver what it emits (file comment). */
static uint64_t closed_fix(const bake_ctx *b, const ops *o, const uint64_t *fkeys, wrt_csc *E) {
    const wrt_ctree *t = o->t;
    uint32_t nf = o->nf;
    double *pw = ext_power(b, o, fkeys);
    double (*P)[3] = wrt_xcalloc((size_t)E->n, sizeof *P);
    for (uint32_t c = 0; c < E->n; c++)
        for (uint64_t k = E->col[c]; k < E->col[c + 1]; k++) /* every row with power */
            for (int ch = 0; ch < 3; ch++) P[c][ch] += pw[E->row[k]] * E->val[3 * k + ch];
    fix_col fc = {.o = o, .E = E, .pw = pw};
    for (uint32_t j = 0; j < nf; j++) {
        if (!wrt_fkey_angular_root(fkeys[j])) continue;
        uint32_t q = wrt_fkey_quad(fkeys[j]);
        int32_t leaf = o->node_of[j];
        fc.j = j;
        for (int ch = 0; ch < 3; ch++) { fc.have[ch] = P[j][ch]; fc.want[ch] = b->rho[q][ch] * pw[j]; fc.wsum[ch] = 0; }
        for (int pass = 0; pass < 2; pass++) {
            fix_visit(&fc, j, 1, 1, pass);
            if (leaf >= 0)
                for (int32_t a = t->parent[leaf]; a >= 0; a = t->parent[a])
                    fix_visit(&fc, nf + (uint32_t)a, sqrt(t->area[leaf] / t->area[a]), 0, pass);
        }
    }
    wrt_triplet *add = fc.add;
    uint64_t n = fc.n;
    free(P); free(pw);
    if (n) {
        uint64_t m = E->nnz;
        wrt_triplet *all = wrt_xmalloc((m + n) * sizeof *all);
        for (uint32_t c = 0; c < E->n; c++)
            for (uint64_t k = E->col[c]; k < E->col[c + 1]; k++)
                all[k] = (wrt_triplet){E->row[k], c, {E->val[3 * k], E->val[3 * k + 1], E->val[3 * k + 2]}};
        memcpy(all + m, add, n * sizeof *add);
        uint32_t ne = E->n;
        wrt_csc_free(E);
        *E = wrt_csc_from_triplets(ne, all, m + n);
        free(all);
    }
    free(add);
    return n;
}

static void ops_init(ops *o, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf, uint32_t nq) {
    const wrt_ctree *t = &cl->tree;
    o->t = t;
    o->nf = nf;
    o->cl = cl;
    uint32_t *root = wrt_clusters_root_index(fkeys, nf, nq);
    o->root = root;
    o->node_of = wrt_xmalloc(((size_t)nf + 1) * sizeof *o->node_of);
    for (uint32_t f = 0; f < nf; f++) o->node_of[f] = -1;
    for (uint32_t q = 0; q < nq; q++) o->node_of[root[q]] = (int32_t)t->leaf[q];
    o->wl = wrt_xcalloc(t->nnodes, sizeof *o->wl);
    o->wr = wrt_xcalloc(t->nnodes, sizeof *o->wr);
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0) {
            o->wl[p] = sqrt(t->area[t->left[p]] / t->area[p]);
            o->wr[p] = sqrt(t->area[t->right[p]] / t->area[p]);
        }
}

static void ops_free(ops *o) {
    free((void *)o->root); free(o->node_of); free(o->wl); free(o->wr);
}

/* M^T: a counting pass per row, then the entries in column order (rows ascending) */
static wrt_csc transpose(const wrt_csc *M) {
    uint32_t n = M->n;
    wrt_csc R = {.n = n, .nnz = M->nnz};
    R.col = wrt_xcalloc((size_t)n + 2, sizeof *R.col);
    R.row = wrt_xmalloc((M->nnz ? M->nnz : 1) * sizeof *R.row);
    R.val = wrt_xmalloc((M->nnz ? M->nnz : 1) * 3 * sizeof *R.val);
    for (uint64_t k = 0; k < M->nnz; k++) R.col[M->row[k] + 2]++;
    for (uint32_t i = 0; i < n; i++) R.col[i + 2] += R.col[i + 1];
    for (uint32_t c = 0; c < n; c++)
        for (uint64_t k = M->col[c]; k < M->col[c + 1]; k++) {
            uint64_t d = R.col[M->row[k] + 1]++;
            R.row[d] = c;
            memcpy(&R.val[3 * d], &M->val[3 * k], 3 * sizeof *R.val);
        }
    return R;
}

uint64_t wrt_clusters_assemble(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf,
                               int closed, int build_t, wrt_csc *T, wrt_csc *E1) {
    const wrt_ctree *t = &cl->tree;
    ops o;
    ops_init(&o, cl, fkeys, nf, (uint32_t)b->nq);
    uint32_t ne = nf + t->nnodes;
    /* T's entries and the cluster links' in the extended index space */
    uint64_t m = T->nnz, n = m + 2 * cl->nlinks;
    wrt_triplet *tr = wrt_xmalloc((n ? n : 1) * sizeof *tr);
    for (uint32_t c = 0; c < T->n; c++)
        for (uint64_t k = T->col[c]; k < T->col[c + 1]; k++)
            tr[k] = (wrt_triplet){T->row[k], c, {T->val[3 * k], T->val[3 * k + 1], T->val[3 * k + 2]}};
    for (size_t i = 0; i < cl->nlinks; i++) {
        const wrt_clink *l = &cl->links[i];
        uint32_t ea = t->left[l->a] < 0 ? o.root[t->right[l->a]] : nf + l->a;
        uint32_t eb = t->left[l->b] < 0 ? o.root[t->right[l->b]] : nf + l->b;
        tr[m + 2 * i] = (wrt_triplet){ea, eb, {l->tab[0], l->tab[1], l->tab[2]}};
        tr[m + 2 * i + 1] = (wrt_triplet){eb, ea, {l->tba[0], l->tba[1], l->tba[2]}};
    }
    wrt_csc_free(T);
    wrt_csc E = wrt_csc_from_triplets(ne, tr, n);
    free(tr);
    uint64_t added = closed ? closed_fix(b, &o, fkeys, &E) : 0;
    /* the links pushed down to the quads: rows, then (on the transpose) columns */
    uint64_t n1, n2;
    wrt_triplet *t1 = push_down(&o, b, &E, 1, &n1);
    wrt_csc_free(&E);
    E = wrt_csc_from_triplets(ne, t1, n1);
    free(t1);
    if (E1) *E1 = transpose(&E); /* E is E1's transpose here (push_down swaps) */
    if (!build_t && E1) { /* T = E1 U never formed (series_first.c): T left empty */
        wrt_csc_free(&E);
        *T = (wrt_csc){.n = nf, .col = wrt_xcalloc((size_t)nf + 1, sizeof *T->col)};
        ops_free(&o);
        return added;
    }
    wrt_triplet *t2 = push_down(&o, b, &E, 0, &n2);
    wrt_csc_free(&E);
    *T = wrt_csc_from_triplets(nf, t2, n2);
    free(t2);
    ops_free(&o);
    return added;
}

/* X with the node rows appended (cluster.h): per column, each quad root's coefficient
 * summed into its leaf, then up the tree, Y_P = wL Y_L + wR Y_R (children before
 * parents: descending node numbers); a node row kept where E1's column there has
 * entries. Each column alone, on `threads` threads, into its own arrays, then joined in
 * column order: the same entries whatever the thread count. */
typedef struct pull_ctx {
    const wrt_ctree *t;
    const wrt_csc *E1, *X;
    uint32_t nf;
    const int32_t *leaf_of;
    const double *wl, *wr;
    double **s;               /* per thread: 3 per node, kept zero between columns */
    uint32_t **mark, **touched;
    uint32_t **nrow;          /* per column: its node rows (NULL: none) */
    float **nval;
    uint32_t *ncount;
    const uint32_t *cols;     /* the columns of X with entries, the loop's items */
} pull_ctx;

static int desc_u32(const void *a, const void *b) {
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x < y) - (x > y);
}

static void pull_column(size_t ci, int th, void *user) {
    pull_ctx *c = user;
    const wrt_ctree *t = c->t;
    const wrt_csc *X = c->X, *E1 = c->E1;
    uint32_t col = c->cols[ci], nt = 0, epoch = col + 1, nf = c->nf, ne = E1->n;
    double *s = c->s[th];
    uint32_t *mark = c->mark[th], *touched = c->touched[th];
    for (uint64_t k = X->col[col]; k < X->col[col + 1]; k++) {
        uint32_t r = X->row[k];
        int32_t p = r < nf ? c->leaf_of[r] : -1;
        if (p < 0) continue;
        for (int ch = 0; ch < 3; ch++) s[(size_t)p * 3 + ch] += X->val[3 * k + ch];
        for (int32_t a = p; a >= 0 && mark[a] != epoch; a = t->parent[a]) { mark[a] = epoch; touched[nt++] = (uint32_t)a; }
    }
    if (!nt) return;
    qsort(touched, nt, sizeof *touched, desc_u32);
    for (uint32_t i = 0; i < nt; i++) {
        uint32_t p = touched[i];
        if (t->left[p] < 0) continue;
        int32_t L = t->left[p], R = t->right[p];
        for (int ch = 0; ch < 3; ch++)
            s[(size_t)p * 3 + ch] = c->wl[p] * s[(size_t)L * 3 + ch] + c->wr[p] * s[(size_t)R * 3 + ch];
    }
    uint32_t n = 0;
    uint32_t *row = wrt_xmalloc((size_t)nt * sizeof *row);
    float *val = wrt_xmalloc((size_t)nt * 3 * sizeof *val);
    /* ascending rows: parents first */
    for (uint32_t i = nt; i-- > 0;) {
        uint32_t p = touched[i], e = nf + p;
        double *v = &s[(size_t)p * 3];
        if (e < ne && E1->col[e + 1] > E1->col[e] && (v[0] != 0 || v[1] != 0 || v[2] != 0)) {
            row[n] = e;
            for (int ch = 0; ch < 3; ch++) val[3 * n + ch] = (float)v[ch];
            n++;
        }
        v[0] = v[1] = v[2] = 0;
    }
    c->nrow[col] = row; c->nval[col] = val; c->ncount[col] = n;
}

wrt_csc wrt_clusters_pull_up(const wrt_ctree *t, const uint32_t *root, uint32_t nq, const wrt_csc *E1, uint32_t nf,
                             const wrt_csc *X, int threads) {
    uint32_t ne = E1->n, nc = X->n < ne ? X->n : ne;
    int th = wrt_threads_resolve(threads);
    int32_t *leaf_of = wrt_xmalloc(((size_t)nf + 1) * sizeof *leaf_of);
    for (uint32_t f = 0; f < nf; f++) leaf_of[f] = -1;
    for (uint32_t q = 0; q < nq; q++) leaf_of[root[q]] = (int32_t)t->leaf[q];
    double *wl = wrt_xcalloc((size_t)t->nnodes + 1, sizeof *wl), *wr = wrt_xcalloc((size_t)t->nnodes + 1, sizeof *wr);
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0) {
            wl[p] = sqrt(t->area[t->left[p]] / t->area[p]);
            wr[p] = sqrt(t->area[t->right[p]] / t->area[p]);
        }
    pull_ctx c = {.t = t, .E1 = E1, .X = X, .nf = nf, .leaf_of = leaf_of, .wl = wl, .wr = wr};
    c.s = wrt_xmalloc((size_t)th * sizeof *c.s);
    c.mark = wrt_xmalloc((size_t)th * sizeof *c.mark);
    c.touched = wrt_xmalloc((size_t)th * sizeof *c.touched);
    for (int i = 0; i < th; i++) {
        c.s[i] = wrt_xcalloc((size_t)t->nnodes * 3 + 3, sizeof *c.s[i]);
        c.mark[i] = wrt_xcalloc((size_t)t->nnodes + 1, sizeof *c.mark[i]);
        c.touched[i] = wrt_xmalloc(((size_t)t->nnodes + 1) * sizeof *c.touched[i]);
    }
    c.nrow = wrt_xcalloc((size_t)nc + 1, sizeof *c.nrow);
    c.nval = wrt_xcalloc((size_t)nc + 1, sizeof *c.nval);
    c.ncount = wrt_xcalloc((size_t)nc + 1, sizeof *c.ncount);
    /* only X's columns with entries (the series by blocks of columns pulls up a block,
     * every other column empty: 5.4M a pull-up at 53,122 atrium elements) */
    uint32_t *cols = wrt_xmalloc(((size_t)nc + 1) * sizeof *cols), ncols = 0;
    for (uint32_t j = 0; j < nc; j++)
        if (X->col[j + 1] > X->col[j]) cols[ncols++] = j;
    c.cols = cols;
    wrt_parallel_for(ncols, th, pull_column, &c);
    uint64_t total = X->col[nc];
    for (uint32_t i = 0; i < ncols; i++) total += c.ncount[cols[i]];
    wrt_csc Y = {.n = ne, .nnz = total};
    Y.col = wrt_xcalloc((size_t)ne + 1, sizeof *Y.col);
    Y.row = wrt_xmalloc((total ? total : 1) * sizeof *Y.row);
    Y.val = wrt_xmalloc((total ? total : 1) * 3 * sizeof *Y.val);
    uint64_t n = 0;
    for (uint32_t j = 0; j < nc; j++) {
        if (X->col[j + 1] == X->col[j]) { /* empty: nothing pulled up either */
            Y.col[j + 1] = n;
            continue;
        }
        uint64_t k0 = X->col[j], m = X->col[j + 1] - k0;
        memcpy(&Y.row[n], &X->row[k0], m * sizeof *Y.row);
        memcpy(&Y.val[3 * n], &X->val[3 * k0], 3 * m * sizeof *Y.val);
        n += m;
        memcpy(&Y.row[n], c.nrow[j] ? c.nrow[j] : Y.row, c.ncount[j] * sizeof *Y.row);
        memcpy(&Y.val[3 * n], c.nval[j] ? c.nval[j] : Y.val, 3 * (size_t)c.ncount[j] * sizeof *Y.val);
        n += c.ncount[j];
        free(c.nrow[j]); free(c.nval[j]);
        Y.col[j + 1] = n;
    }
    for (uint32_t j = nc; j < ne; j++) Y.col[j + 1] = n;
    for (int i = 0; i < th; i++) { free(c.s[i]); free(c.mark[i]); free(c.touched[i]); }
    free(c.s); free(c.mark); free(c.touched); free(c.nrow); free(c.nval); free(c.ncount);
    free(leaf_of); free(wl); free(wr); free(cols);
    return Y;
}

uint64_t wrt_clusters_pushed_entries(const wrt_clusters *cl, int senders) {
    uint64_t n = 0;
    for (size_t i = 0; i < cl->nlinks; i++) {
        uint64_t na = cl->hi[cl->links[i].a] - cl->lo[cl->links[i].a], nb = cl->hi[cl->links[i].b] - cl->lo[cl->links[i].b];
        n += senders ? 2 * na * nb : na + nb;
    }
    return n;
}

void wrt_clusters_to_tree(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf, wrt_csc *M) {
    ops o;
    ops_init(&o, cl, fkeys, nf, (uint32_t)b->nq);
    uint64_t n1, n2;
    wrt_triplet *t1 = row_transform(&o, M, &n1);
    wrt_csc_free(M);
    wrt_csc E = wrt_csc_from_triplets(nf, t1, n1);
    free(t1);
    wrt_triplet *t2 = row_transform(&o, &E, &n2);
    wrt_csc_free(&E);
    *M = wrt_csc_from_triplets(nf, t2, n2);
    free(t2);
    ops_free(&o);
}

void wrt_clusters_series_weights(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf,
                                 double *rw, double *cw, double *pw, double *boost) {
    const wrt_ctree *t = &cl->tree;
    uint32_t *root = wrt_clusters_root_index(fkeys, nf, (uint32_t)b->nq);
    for (uint32_t p = 0; p < t->nnodes; p++) {
        if (t->left[p] < 0) continue;
        uint32_t f = root[t->slot[p]];
        rw[f] = 1 / sqrt(t->area[p]); cw[f] = sqrt(t->area[p]);
        if (boost) boost[f] = 1;
    }
    rw[root[t->root_slot]] = 1 / sqrt(t->area[0]); cw[root[t->root_slot]] = sqrt(t->area[0]);
    if (boost) boost[root[t->root_slot]] = 1;
    double *scratch = wrt_xmalloc(2 * (size_t)t->nnodes * sizeof *scratch);
    wrt_ctree_forward_d(t, root, pw, 1, scratch);
    free(scratch);
    free(root);
}

static int trip_row_cmp(const void *a, const void *b) {
    uint32_t x = ((const wrt_triplet *)a)->row, y = ((const wrt_triplet *)b)->row;
    return (x > y) - (x < y);
}

static int node_desc_cmp(const void *a, const void *b) {
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x < y) - (x > y);
}

/* The receivers' side of M (its rows) to the tree basis, a column at a time, each column
 * compressed by W as soon as it is made (rows' weights: the tree's, from
 * wrt_clusters_series_weights); M's columns as they are. Stops, returning 0 and *R empty,
 * once the result would pass limit entries; else 1. *raw: the entries before compression
 * (of the columns made). */
int wrt_clusters_rows_to_tree(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf,
                              const wrt_csc *M, double eps, const wrt_csc_weights *W, uint64_t limit, wrt_csc *R,
                              uint64_t *raw) {
    ops o;
    ops_init(&o, cl, fkeys, nf, (uint32_t)b->nq);
    const wrt_ctree *t = o.t;
    size_t nn = t->nnodes;
    double *s = wrt_xcalloc(nn * 3, sizeof *s);
    uint32_t *mark = wrt_xcalloc(nn, sizeof *mark), *touched = wrt_xmalloc(nn * sizeof *touched);
    uint64_t maxcol = 0;
    *raw = 0;
    for (uint32_t c = 0; c < M->n; c++) maxcol = M->col[c + 1] - M->col[c] > maxcol ? M->col[c + 1] - M->col[c] : maxcol;
    size_t ccap = maxcol + nn + 1;
    wrt_triplet *tc = wrt_xmalloc(ccap * sizeof *tc);
    uint32_t *crow = wrt_xmalloc(ccap * sizeof *crow);
    float *cval = wrt_xmalloc(3 * ccap * sizeof *cval);
    uint8_t *keep = wrt_xmalloc(ccap);
    uint32_t *need = wrt_xcalloc(nn, sizeof *need);
    int32_t *rowtree = wrt_xmalloc(((size_t)nf + 1) * sizeof *rowtree); /* per row after: psi_P's node, -2 phi_root */
    for (uint32_t f = 0; f < nf; f++) rowtree[f] = -1;
    for (uint32_t p = 0; p < nn; p++)
        if (t->left[p] >= 0) rowtree[o.root[t->slot[p]]] = (int32_t)p;
    rowtree[o.root[t->root_slot]] = -2;
    *R = (wrt_csc){.n = M->n};
    R->col = wrt_xmalloc(((size_t)M->n + 1) * sizeof *R->col);
    uint64_t cap = M->nnz / 4 + 16 < limit ? M->nnz / 4 + 16 : limit + 1, n = 0;
    R->row = wrt_xmalloc(cap * sizeof *R->row);
    R->val = wrt_xmalloc(3 * cap * sizeof *R->val);
    R->col[0] = 0;
    int ok = 1;
    for (uint32_t c = 0; c < M->n && ok; c++) {
        uint32_t nt = 0, epoch = c + 1;
        size_t m = 0;
        for (uint64_t k = M->col[c]; k < M->col[c + 1]; k++) {
            uint32_t r = M->row[k];
            const float *v = &M->val[3 * k];
            int32_t p = ext_node(&o, r);
            if (p < 0) {
                tc[m++] = (wrt_triplet){r, c, {v[0], v[1], v[2]}};
                continue;
            }
            for (int ch = 0; ch < 3; ch++) s[(size_t)p * 3 + ch] += v[ch];
            for (int32_t q = p; q >= 0 && mark[q] != epoch; q = t->parent[q]) { mark[q] = epoch; touched[nt++] = (uint32_t)q; }
        }
        qsort(touched, nt, sizeof *touched, node_desc_cmp); /* children before parents */
        for (uint32_t i = 0; i < nt; i++) {
            uint32_t p = touched[i];
            if (t->left[p] < 0) continue;
            int32_t L = t->left[p], Rn = t->right[p];
            double wl = o.wl[p], wr = o.wr[p];
            float dv[3];
            for (int ch = 0; ch < 3; ch++) {
                double sl = s[(size_t)L * 3 + ch], sr = s[(size_t)Rn * 3 + ch];
                s[(size_t)p * 3 + ch] += wl * sl + wr * sr;
                dv[ch] = (float)(wr * sl - wl * sr);
            }
            if (dv[0] != 0 || dv[1] != 0 || dv[2] != 0) tc[m++] = (wrt_triplet){o.root[t->slot[p]], c, {dv[0], dv[1], dv[2]}};
        }
        if (nt && mark[0] == epoch) {
            float sv[3] = {(float)s[0], (float)s[1], (float)s[2]};
            if (sv[0] != 0 || sv[1] != 0 || sv[2] != 0) tc[m++] = (wrt_triplet){o.root[t->root_slot], c, {sv[0], sv[1], sv[2]}};
        }
        for (uint32_t i = 0; i < nt; i++)
            for (int ch = 0; ch < 3; ch++) s[(size_t)touched[i] * 3 + ch] = 0;
        qsort(tc, m, sizeof *tc, trip_row_cmp);
        for (size_t i = 0; i < m; i++) {
            crow[i] = tc[i].row;
            memcpy(&cval[3 * i], tc[i].v, sizeof tc[i].v);
        }
        *raw += m;
        /* the kept entries' ancestors kept too: a point's light is phi_root's and its
         * ancestors' psi_P's, and without them what is kept below is a wavelet of no mean
         * (the column's power lost: the 320-triangle icosphere furnace -0.68%) */
        wrt_csc_compress_col_kept(crow, cval, m, c, eps, W, keep);
        uint32_t epoch2 = c + 1;
        for (size_t i = 0; i < m; i++) {
            if (!keep[i]) continue;
            int32_t p = rowtree[crow[i]];
            int32_t from = p >= 0 ? t->parent[p] : p == -1 ? t->parent[t->leaf[wrt_fkey_quad(fkeys[crow[i]])]] : -1;
            for (int32_t q = from; q >= 0 && need[q] != epoch2; q = t->parent[q]) need[q] = epoch2;
        }
        for (size_t i = 0; i < m; i++) {
            int32_t p = rowtree[crow[i]];
            keep[i] = p == -2 || (p >= 0 && need[p] == epoch2);
        }
        uint64_t kept = wrt_csc_compress_col_force(crow, cval, m, c, eps, W, keep);
        if (n + kept > limit) {
            ok = 0;
            break;
        }
        if (n + kept > cap) {
            cap = 2 * (n + kept) < limit ? 2 * (n + kept) : limit;
            R->row = wrt_xrealloc(R->row, cap * sizeof *R->row);
            R->val = wrt_xrealloc(R->val, 3 * cap * sizeof *R->val);
        }
        memcpy(&R->row[n], crow, kept * sizeof *crow);
        memcpy(&R->val[3 * n], cval, 3 * kept * sizeof *cval);
        n += kept;
        R->col[c + 1] = n;
    }
    free(s); free(mark); free(touched); free(tc); free(crow); free(cval); free(keep); free(need); free(rowtree);
    ops_free(&o);
    if (!ok) {
        wrt_csc_free(R);
        return 0;
    }
    R->nnz = n;
    R->row = wrt_xrealloc(R->row, (n ? n : 1) * sizeof *R->row);
    R->val = wrt_xrealloc(R->val, 3 * (n ? n : 1) * sizeof *R->val);
    return 1;
}
