/* cluster_tree.c: checks of a cluster tree and the orthonormal Haar transform on it
 * (cluster_tree.h; docs/clusters.md). Forward: children before parents (descending node
 * numbers), each pair (s_L, s_R) -> (s_P, d_P); inverse: the same rotations backwards.
 * Depends on wrt_common.h only. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cluster_tree.h"

wrt_status wrt_ctree_alloc(wrt_ctree *t, uint32_t nq) {
    memset(t, 0, sizeof *t);
    t->nq = nq;
    t->nnodes = nq ? 2 * nq - 1 : 0;
    size_t n = t->nnodes ? t->nnodes : 1;
    t->left = calloc(n, sizeof *t->left);
    t->right = calloc(n, sizeof *t->right);
    t->area = calloc(n, sizeof *t->area);
    if (!t->left || !t->right || !t->area) {
        wrt_ctree_free(t);
        return wrt_fail(WRT_ERR_NOMEM, "cluster tree: out of memory (%u quads)", nq);
    }
    return WRT_OK;
}

void wrt_ctree_free(wrt_ctree *t) {
    if (!t) return;
    free(t->left); free(t->right); free(t->area);
    free(t->parent); free(t->slot); free(t->leaf);
    memset(t, 0, sizeof *t);
}

/* Checks one node's children and area; NULL if fine, else what is wrong. */
static const char *node_fault(const wrt_ctree *t, uint32_t p, uint8_t *seen) {
    double a = t->area[p];
    if (!(a > 0) || !isfinite(a)) return "area not positive and finite";
    if (t->left[p] < 0) {
        if (t->left[p] != -1) return "leaf marker not -1";
        if (t->right[p] < 0 || (uint32_t)t->right[p] >= t->nq) return "leaf quad out of range";
        if (t->leaf[t->right[p]] != UINT32_MAX) return "quad is a leaf twice";
        t->leaf[t->right[p]] = p;
        return NULL;
    }
    for (int k = 0; k < 2; k++) {
        int32_t c = k ? t->right[p] : t->left[p];
        if (c <= (int32_t)p || (uint32_t)c >= t->nnodes) return "child not after its parent or out of range";
        if (seen[c]) return "node has two parents";
        seen[c] = 1;
        t->parent[c] = (int32_t)p;
    }
    double s = t->area[t->left[p]] + t->area[t->right[p]];
    if (!(fabs(s - a) <= 1e-6 * a)) return "area not the sum of its children's";
    return NULL;
}

wrt_status wrt_ctree_finish(wrt_ctree *t, const char *what) {
    if (t->nq == 0) return wrt_fail(WRT_ERR_CORRUPT, "%s: no quads", what);
    if (t->nnodes != 2 * t->nq - 1)
        return wrt_fail(WRT_ERR_CORRUPT, "%s: %u nodes for %u quads (need %u)", what, t->nnodes, t->nq, 2 * t->nq - 1);
    size_t n = t->nnodes;
    t->parent = malloc(n * sizeof *t->parent);
    t->slot = malloc(n * sizeof *t->slot);
    t->leaf = malloc(t->nq * sizeof *t->leaf);
    uint8_t *seen = calloc(n, 1);
    uint32_t *lm = malloc(n * sizeof *lm), *dep = calloc(n, sizeof *dep);
    if (!t->parent || !t->slot || !t->leaf || !seen || !lm || !dep) {
        free(seen); free(lm); free(dep);
        free(t->parent); free(t->slot); free(t->leaf);
        t->parent = NULL; t->slot = NULL; t->leaf = NULL;
        return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory", what);
    }
    for (uint32_t q = 0; q < t->nq; q++) t->leaf[q] = UINT32_MAX;
    t->parent[0] = -1;
    seen[0] = 1;
    wrt_status st = WRT_OK;
    for (uint32_t p = 0; p < n && st == WRT_OK; p++) {
        const char *f = node_fault(t, p, seen);
        if (f) st = wrt_fail(WRT_ERR_CORRUPT, "%s: node %u: %s", what, p, f);
    }
    for (uint32_t q = 0; q < t->nq && st == WRT_OK; q++)
        if (t->leaf[q] == UINT32_MAX) st = wrt_fail(WRT_ERR_CORRUPT, "%s: quad %u is in no leaf", what, q);
    if (st == WRT_OK) {
        /* leftmost quads, bottom-up; slots and depths */
        for (uint32_t p = (uint32_t)n; p-- > 0;)
            lm[p] = t->left[p] < 0 ? (uint32_t)t->right[p] : lm[t->left[p]];
        t->depth = 0;
        for (uint32_t p = 0; p < n; p++) {
            if (p) dep[p] = dep[t->parent[p]] + 1;
            if (dep[p] > t->depth) t->depth = dep[p];
            t->slot[p] = t->left[p] < 0 ? (uint32_t)t->right[p] : lm[t->right[p]];
        }
        t->root_slot = lm[0];
    }
    free(seen); free(lm); free(dep);
    if (st != WRT_OK) {
        free(t->parent); free(t->slot); free(t->leaf);
        t->parent = NULL; t->slot = NULL; t->leaf = NULL;
    }
    return st;
}

/* s: nnodes x nch scaling coefficients, d: the wavelets; leaves' s read from v */
static void forward_core(const wrt_ctree *t, int nch, double *s, double *d) {
    for (uint32_t p = t->nnodes; p-- > 0;) {
        if (t->left[p] < 0) continue;
        int32_t L = t->left[p], R = t->right[p];
        double wl = sqrt(t->area[L] / t->area[p]), wr = sqrt(t->area[R] / t->area[p]);
        for (int c = 0; c < nch; c++) {
            double sl = s[(size_t)L * nch + c], sr = s[(size_t)R * nch + c];
            s[(size_t)p * nch + c] = wl * sl + wr * sr;
            d[(size_t)p * nch + c] = wr * sl - wl * sr;
        }
    }
}

static void inverse_core(const wrt_ctree *t, int nch, double *s, const double *d) {
    for (uint32_t p = 0; p < t->nnodes; p++) {
        if (t->left[p] < 0) continue;
        int32_t L = t->left[p], R = t->right[p];
        double wl = sqrt(t->area[L] / t->area[p]), wr = sqrt(t->area[R] / t->area[p]);
        for (int c = 0; c < nch; c++) {
            double sp = s[(size_t)p * nch + c], dp = d[(size_t)p * nch + c];
            s[(size_t)L * nch + c] = wl * sp + wr * dp;
            s[(size_t)R * nch + c] = wr * sp - wl * dp;
        }
    }
}

void wrt_ctree_forward_d(const wrt_ctree *t, const uint32_t *root, double *v, int nch, double *scratch) {
    double *s = scratch, *d = scratch + (size_t)t->nnodes * nch;
    for (uint32_t q = 0; q < t->nq; q++)
        for (int c = 0; c < nch; c++) s[(size_t)t->leaf[q] * nch + c] = v[(size_t)root[q] * nch + c];
    forward_core(t, nch, s, d);
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0)
            for (int c = 0; c < nch; c++) v[(size_t)root[t->slot[p]] * nch + c] = d[(size_t)p * nch + c];
    for (int c = 0; c < nch; c++) v[(size_t)root[t->root_slot] * nch + c] = s[c];
}

void wrt_ctree_inverse_d(const wrt_ctree *t, const uint32_t *root, double *v, int nch, double *scratch) {
    double *s = scratch, *d = scratch + (size_t)t->nnodes * nch;
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0)
            for (int c = 0; c < nch; c++) d[(size_t)p * nch + c] = v[(size_t)root[t->slot[p]] * nch + c];
    for (int c = 0; c < nch; c++) s[c] = v[(size_t)root[t->root_slot] * nch + c];
    inverse_core(t, nch, s, d);
    for (uint32_t q = 0; q < t->nq; q++)
        for (int c = 0; c < nch; c++) v[(size_t)root[q] * nch + c] = s[(size_t)t->leaf[q] * nch + c];
}

/* float vectors of RGB through the double transform */
static void float_pass(const wrt_ctree *t, const uint32_t *root, float *v, double *scratch, int inv) {
    double *s = scratch, *d = scratch + (size_t)t->nnodes * 3;
    if (!inv) {
        for (uint32_t q = 0; q < t->nq; q++)
            for (int c = 0; c < 3; c++) s[(size_t)t->leaf[q] * 3 + c] = v[(size_t)root[q] * 3 + c];
        forward_core(t, 3, s, d);
        for (uint32_t p = 0; p < t->nnodes; p++)
            if (t->left[p] >= 0)
                for (int c = 0; c < 3; c++) v[(size_t)root[t->slot[p]] * 3 + c] = (float)d[(size_t)p * 3 + c];
        for (int c = 0; c < 3; c++) v[(size_t)root[t->root_slot] * 3 + c] = (float)s[c];
        return;
    }
    for (uint32_t p = 0; p < t->nnodes; p++)
        if (t->left[p] >= 0)
            for (int c = 0; c < 3; c++) d[(size_t)p * 3 + c] = v[(size_t)root[t->slot[p]] * 3 + c];
    for (int c = 0; c < 3; c++) s[c] = v[(size_t)root[t->root_slot] * 3 + c];
    inverse_core(t, 3, s, d);
    for (uint32_t q = 0; q < t->nq; q++)
        for (int c = 0; c < 3; c++) v[(size_t)root[q] * 3 + c] = (float)s[(size_t)t->leaf[q] * 3 + c];
}

void wrt_ctree_forward_f(const wrt_ctree *t, const uint32_t *root, float *v, double *scratch) {
    float_pass(t, root, v, scratch, 0);
}
void wrt_ctree_inverse_f(const wrt_ctree *t, const uint32_t *root, float *v, double *scratch) {
    float_pass(t, root, v, scratch, 1);
}
