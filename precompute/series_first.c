/* series_first.c: the series' uses of T with T never formed (docs/clusters.md "T never
 * formed"), the default with --clusters: the bake keeps E1 (the cluster links' receivers
 * pushed down, their senders on the nodes' columns) and T = E1 U (U the uniform pull-up of
 * the senders, cluster.h). What read T's columns reads them from E1 here:
 *  - the sum's first state, T W^T (and with it the nodes-apart test, and from it the
 *    first term: series_tree.c): T's column of a quad's root is made
 *    when the senders' transform (cluster_send.c) reaches the quad's leaf, from E1's column
 *    there plus sqrt(a_q / a_B) times E1's column of phi_B for every ancestor B, summed in
 *    the assembly's order and precision (cluster_ops.c's second push-down: each
 *    contribution rounded to float, then added in float, ancestors from the root down), so
 *    the column is T's to the bit and the transform's result today's. Only one quad's
 *    column is held at a time besides the transform's path and the results, so the
 *    pushed-down link blocks (O(N^2) root entries) are never held; but each is made, so
 *    a walk costs T's entries (4.76G at 100,256 atrium elements).
 *  - the power iteration, T x = E1 (U x), and the power targets, v T = (v E1) U, in double
 *    (T's float entries were rounded sums: the ratios and targets agree to rounding);
 *  - the column power rule's correction, (u_q - have_q) times T's root column, made like
 *    the first term (series_tree.c).
 * Depends on cluster.h, series_internal.h. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "cluster.h"
#include "series_first.h"
#include "series_internal.h"

enum { TCOL_SUM, TCOL_POWER };
/* the most threads the senders' walk takes (one column builder each) */
#define WRT_TCOL_THREADS 64

void wrt_tcols_init(wrt_tcols *c, const wrt_ctree *t, const uint32_t *root, const wrt_csc *E1, uint32_t nf) {
    memset(c, 0, sizeof *c);
    c->t = t;
    c->E1 = E1;
    c->nf = nf;
    c->leaf_of = wrt_xmalloc(((size_t)nf + 1) * sizeof *c->leaf_of);
    for (uint32_t f = 0; f < nf; f++) c->leaf_of[f] = -1;
    for (uint32_t q = 0; q < t->nq; q++) c->leaf_of[root[q]] = (int32_t)t->leaf[q];
    c->acc = wrt_xmalloc(((size_t)nf + 1) * 3 * sizeof *c->acc);
    c->mark = wrt_xcalloc((size_t)nf + 1, sizeof *c->mark);
    c->rows = wrt_xmalloc(((size_t)nf + 1) * sizeof *c->rows);
    c->path = wrt_xmalloc(((size_t)t->depth + 2) * sizeof *c->path);
    c->tmp = wrt_xmalloc(((size_t)nf + 1) * sizeof *c->tmp);
}

void wrt_tcols_free(wrt_tcols *c) {
    free(c->leaf_of); free(c->acc); free(c->mark); free(c->rows); free(c->path); free(c->tmp);
    memset(c, 0, sizeof *c);
}

/* a[0..n) (distinct, each under nf) ascending: by 11-bit digits, least first (the
 * columns' rows, thousands a column: qsort's calls were 15% of the series' start) */
static void sort_rows(uint32_t *a, uint32_t *tmp, uint32_t n, uint32_t nf) {
    if (n < 48) {
        for (uint32_t i = 1; i < n; i++) {
            uint32_t v = a[i], j = i;
            for (; j > 0 && a[j - 1] > v; j--) a[j] = a[j - 1];
            a[j] = v;
        }
        return;
    }
    uint32_t *src = a, *dst = tmp;
    for (uint32_t shift = 0; shift < 32 && (nf - 1) >> shift; shift += 11) {
        uint32_t count[2048] = {0};
        for (uint32_t i = 0; i < n; i++) count[(src[i] >> shift) & 2047]++;
        for (uint32_t d = 0, at = 0; d < 2048; d++) {
            uint32_t m = count[d];
            count[d] = at;
            at += m;
        }
        for (uint32_t i = 0; i < n; i++) dst[count[(src[i] >> shift) & 2047]++] = src[i];
        uint32_t *x = src;
        src = dst;
        dst = x;
    }
    if (src != a) memcpy(a, src, n * sizeof *a);
}

/* E1's column e into the accumulator, each value times w rounded to float (scaled 0: as
 * it is), added in float where the row has one already */
static void tcol_add(wrt_tcols *c, uint32_t e, double w, int scaled, uint32_t *n) {
    const wrt_csc *E = c->E1;
    for (uint64_t k = E->col[e]; k < E->col[e + 1]; k++) {
        uint32_t r = E->row[k];
        float v[3];
        for (int ch = 0; ch < 3; ch++) v[ch] = scaled ? (float)(w * E->val[3 * k + ch]) : E->val[3 * k + ch];
        if (c->mark[r] != c->epoch) {
            c->mark[r] = c->epoch;
            c->rows[(*n)++] = r;
            memcpy(&c->acc[3 * (size_t)r], v, sizeof v);
        } else {
            for (int ch = 0; ch < 3; ch++) c->acc[3 * (size_t)r + ch] += v[ch];
        }
    }
}

uint64_t wrt_tcols_col(wrt_tcols *c, uint32_t f, uint32_t **row, float **val) {
    const wrt_ctree *t = c->t;
    uint32_t n = 0;
    if (++c->epoch == 0) { /* wrapped: the marks cleared */
        memset(c->mark, 0, ((size_t)c->nf + 1) * sizeof *c->mark);
        c->epoch = 1;
    }
    tcol_add(c, f, 1, 0, &n);
    int32_t L = c->leaf_of[f];
    if (L >= 0) {
        /* the ancestors (and the leaf) from the root down: the push-down's order */
        uint32_t np = 0;
        for (int32_t a = L; a >= 0; a = t->parent[a]) c->path[np++] = (uint32_t)a;
        for (uint32_t i = np; i-- > 0;) {
            uint32_t B = c->path[i];
            if (c->nf + B < c->E1->n) tcol_add(c, c->nf + B, sqrt(t->area[L] / t->area[B]), 1, &n);
        }
        sort_rows(c->rows, c->tmp, n, c->nf);
    }
    *row = wrt_xmalloc((n ? n : 1) * sizeof **row);
    *val = wrt_xmalloc((n ? n : 1) * 3 * sizeof **val);
    for (uint32_t i = 0; i < n; i++) {
        (*row)[i] = c->rows[i];
        memcpy(&(*val)[3 * (size_t)i], &c->acc[3 * (size_t)c->rows[i]], 3 * sizeof **val);
    }
    return n;
}

typedef struct {
    wrt_tcols tc;
    const series_state *s;
    int mode;
    uint64_t entries;     /* T's entries of the columns made (TCOL_SUM) */
    const double *u, *d;  /* TCOL_POWER: the targets and what the sum's columns deliver */
} tcol_ctx;

static void tcol_init(tcol_ctx *c, const series_state *s, int mode) {
    memset(c, 0, sizeof *c);
    wrt_tcols_init(&c->tc, &s->b->cl->tree, s->troot, s->E1, s->res->nfuncs);
    c->s = s;
    c->mode = mode;
}

/* The column of f the builder asks for (wrt_col_fn): T's (the sum), or the power rule's
 * correction (wrt_series_tree_power: a root column alone) */
static uint64_t tcol_fn(void *user, uint32_t f, uint32_t **row, float **val) {
    tcol_ctx *c = user;
    const series_state *s = c->s;
    if (c->mode == TCOL_POWER && c->tc.leaf_of[f] < 0) {
        *row = NULL;
        *val = NULL;
        return 0;
    }
    uint64_t n = wrt_tcols_col(&c->tc, f, row, val);
    if (c->mode == TCOL_SUM) {
        if (c->tc.leaf_of[f] >= 0) c->entries += n; /* the other columns counted whole after */
    } else {
        const double *pw = s->pw;
        double tp[3] = {0, 0, 0}, scale[3];
        for (uint64_t e = 0; e < n; e++)
            for (int ch = 0; ch < 3; ch++) tp[ch] += pw[(*row)[e]] * (*val)[3 * e + ch];
        for (int ch = 0; ch < 3; ch++)
            scale[ch] = tp[ch] > 0 ? (c->u[3 * (size_t)f + ch] - c->d[3 * (size_t)f + ch]) / tp[ch] : 0;
        uint64_t k = 0;
        for (uint64_t e = 0; e < n; e++) {
            if (pw[(*row)[e]] == 0) continue;
            (*row)[k] = (*row)[e];
            for (int ch = 0; ch < 3; ch++) (*val)[3 * k + ch] = (float)(scale[ch] * (*val)[3 * e + ch]);
            k++;
        }
        n = k;
    }
    return n;
}

/* One tcol context a thread of the walk (cluster_send.c send_split), mode's */
typedef struct {
    tcol_ctx c[WRT_TCOL_THREADS];
    void *u[WRT_TCOL_THREADS];
    int n;
} tcol_set;

static void tcol_set_init(tcol_set *set, const series_state *s, int mode) {
    int th = wrt_threads_resolve(s->threads);
    set->n = th < 1 ? 1 : th > WRT_TCOL_THREADS ? WRT_TCOL_THREADS : th;
    for (int i = 0; i < set->n; i++) {
        tcol_init(&set->c[i], s, mode);
        set->u[i] = &set->c[i];
    }
}

/* the entries counted (TCOL_SUM), summed over the threads' contexts; freed */
static uint64_t tcol_set_free(tcol_set *set) {
    uint64_t e = 0;
    for (int i = 0; i < set->n; i++) {
        e += set->c[i].entries;
        wrt_tcols_free(&set->c[i].tc);
    }
    return e;
}

void wrt_series_factored_sum(series_state *s, wrt_csc *S, const wrt_apart_opt *ap) {
    const wrt_ctree *t = &s->b->cl->tree;
    uint32_t nf = s->res->nfuncs;
    tcol_set set;
    tcol_set_init(&set, s, TCOL_SUM);
    *S = wrt_clusters_senders_cols_apart(t, s->troot, nf, tcol_fn, set.u, set.n, s->eps, &s->TW, 0, nf,
                                         &s->res->c.cluster_senders_raw, ap);
    /* T's entries, as the file's statistics count them: its root columns, all made by
     * the walk, and the others, E1's */
    uint64_t entries = 0;
    for (uint32_t f = 0; f < nf; f++)
        if (set.c[0].tc.leaf_of[f] < 0) entries += s->E1->col[f + 1] - s->E1->col[f];
    entries += tcol_set_free(&set);
    s->res->c.entries_dto = entries;
    s->res->c.entries_spatial = entries - s->res->c.entries_angular;
}

wrt_csc wrt_series_factored_power_cols(const series_state *s, const double *u, const double *d, double eps,
                                       const wrt_csc_weights *W) {
    tcol_set set;
    uint64_t raw;
    tcol_set_init(&set, s, TCOL_POWER);
    for (int i = 0; i < set.n; i++) {
        set.c[i].u = u;
        set.c[i].d = d;
    }
    uint32_t nf = s->res->nfuncs;
    wrt_csc C = wrt_clusters_senders_cols_th(&s->b->cl->tree, s->troot, nf, tcol_fn, set.u, set.n, eps, W, 0, nf, &raw);
    tcol_set_free(&set);
    return C;
}

/* The pull-up of x's quad roots to the nodes (U x's node rows), bottom up (descending
 * node numbers), into xe[3 (nf + node)]: xe holds x first */
static void pull_vec(const wrt_ctree *t, const uint32_t *root, uint32_t nf, const double *x, double *xe) {
    memcpy(xe, x, 3 * (size_t)nf * sizeof *xe);
    double *v = xe + 3 * (size_t)nf;
    for (uint32_t p = t->nnodes; p-- > 0;) {
        double *vp = &v[3 * (size_t)p];
        if (t->left[p] < 0) {
            memcpy(vp, &x[3 * (size_t)root[t->right[p]]], 3 * sizeof *vp);
            continue;
        }
        uint32_t L = (uint32_t)t->left[p], R = (uint32_t)t->right[p];
        double wl = sqrt(t->area[L] / t->area[p]), wr = sqrt(t->area[R] / t->area[p]);
        for (int ch = 0; ch < 3; ch++) vp[ch] = wl * v[3 * (size_t)L + ch] + wr * v[3 * (size_t)R + ch];
    }
}

void wrt_factored_apply(const wrt_ctree *t, const uint32_t *root, const wrt_csc *E1, uint32_t nf, const double *x,
                        double *y) {
    uint32_t ne = E1->n;
    double *xe = wrt_xmalloc(3 * ((size_t)ne + 1) * sizeof *xe), *ye = wrt_xcalloc(3 * ((size_t)ne + 1), sizeof *ye);
    pull_vec(t, root, nf, x, xe);
    wrt_csc_apply(E1, xe, ye);
    for (size_t i = 0; i < 3 * (size_t)nf; i++) y[i] += ye[i];
    free(xe); free(ye);
}

void wrt_factored_rowmul(const wrt_ctree *t, const uint32_t *root, const wrt_csc *E1, uint32_t nf, const double *v,
                         double *out, int threads) {
    uint32_t ne = E1->n;
    double *z = wrt_xmalloc(3 * ((size_t)ne + 1) * sizeof *z);
    wrt_csc_rowmul(E1, v, z, threads);
    /* h_B = sum over B and its ancestors A of z_A / sqrt(a_A), top down (parents first);
     * column root(q) then gets sqrt(a_q) h at q's leaf, sum_B sqrt(a_q / a_B) z_B */
    double *h = wrt_xmalloc(3 * ((size_t)t->nnodes + 1) * sizeof *h);
    for (uint32_t p = 0; p < t->nnodes; p++) {
        int32_t a = t->parent[p];
        double ra = 1 / sqrt(t->area[p]);
        for (int ch = 0; ch < 3; ch++) {
            double zp = nf + p < ne ? z[3 * ((size_t)nf + p) + ch] : 0;
            h[3 * (size_t)p + ch] = zp * ra + (a >= 0 ? h[3 * (size_t)a + ch] : 0);
        }
    }
    memcpy(out, z, 3 * (size_t)nf * sizeof *out);
    for (uint32_t q = 0; q < t->nq; q++) {
        uint32_t L = t->leaf[q], f = root[q];
        double sa = sqrt(t->area[L]);
        for (int ch = 0; ch < 3; ch++) out[3 * (size_t)f + ch] += sa * h[3 * (size_t)L + ch];
    }
    free(z); free(h);
}

void wrt_series_factored_apply(void *user, const double *x, double *y) {
    const series_state *s = user;
    wrt_factored_apply(&s->b->cl->tree, s->troot, s->E1, s->res->nfuncs, x, y);
}

static void factored_rowmul(void *user, const double *v, double *out) {
    const series_state *s = user;
    wrt_factored_rowmul(&s->b->cl->tree, s->troot, s->E1, s->res->nfuncs, v, out, s->threads);
}

double *wrt_series_factored_targets(series_state *s, int *bounces) {
    return wrt_series_power_targets_fn(s->res->nfuncs, factored_rowmul, s, s->pw, s->b->opt.max_bounces, bounces);
}
