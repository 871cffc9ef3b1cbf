/* cluster_tree.h: the binary cluster tree over a scene's quads and its orthonormal Haar
 * basis (docs/clusters.md), shared by the bake (precompute/cluster.c builds the tree and
 * expresses the operator in the basis) and the runtime (which transforms the projected
 * light forward before the multiply and the result back before synthesis).
 *
 * Leaves are single quads; an internal node P with children L, R has area
 * a_P = a_L + a_R. With phi_q the root function of quad q (spatial and angular root,
 * common/basis.h), a node's scaling function and wavelet are
 *   phi_P = wL phi_L + wR phi_R,   psi_P = wR phi_L - wL phi_R,
 *   wL = sqrt(a_L / a_P), wR = sqrt(a_R / a_P)
 * and phi_root with psi_P of every internal P are N orthonormal functions spanning the
 * quads' roots. Bijection onto the quads' root slots: psi_P sits in the slot of the
 * leftmost quad of P's right subtree, phi_root in the slot of the tree's leftmost quad.
 * Nodes are numbered so that children come after their parent (node 0 is the root).
 * Depends on wrt_common.h (status). Thread-safe on distinct data. */
#ifndef WRT_CLUSTER_TREE_H
#define WRT_CLUSTER_TREE_H

#include <stdint.h>

#include "wrt_common.h"

typedef struct wrt_ctree {
    uint32_t nq;        /* quads (leaves) */
    uint32_t nnodes;    /* 2 nq - 1 */
    int32_t *left;      /* per node: left child, or -1 for a leaf */
    int32_t *right;     /* per node: right child, or the quad of a leaf */
    double *area;       /* per node */
    /* derived by wrt_ctree_finish: */
    int32_t *parent;    /* -1 for the root */
    uint32_t *slot;     /* per node: the quad whose root slot holds psi_P (internal) or the
                         * leaf's own quad (leaf) */
    uint32_t root_slot; /* the quad whose root slot holds phi_root */
    uint32_t *leaf;     /* per quad: its leaf node */
    uint32_t depth;     /* longest path from the root, in edges */
} wrt_ctree;

/* Allocates the three stored arrays for nq quads (zeroed); the derived ones are NULL.
 * WRT_ERR_NOMEM (nothing left allocated). The runtime library's code never aborts. */
wrt_status wrt_ctree_alloc(wrt_ctree *t, uint32_t nq);
/* Checks the stored arrays (children after parents, every node reached once, every quad
 * a leaf once, areas positive and finite, each internal area the sum of its children's
 * within 1e-6) and derives the rest. On failure names the node and the fault and
 * returns WRT_ERR_CORRUPT with `what` (e.g. the section's name) in the message, or
 * WRT_ERR_NOMEM. */
wrt_status wrt_ctree_finish(wrt_ctree *t, const char *what);
void wrt_ctree_free(wrt_ctree *t);

/* In-place transforms of the quads' root coefficients, RGB: v[3 * root[q] + c] is quad
 * q's root coefficient. forward: quad roots -> tree functions in the same slots;
 * inverse: back. scratch: 6 * nnodes doubles. Orthonormal: inverse(forward(v)) = v up to
 * rounding, and sums of squares are kept. */
void wrt_ctree_forward_f(const wrt_ctree *t, const uint32_t *root, float *v, double *scratch);
void wrt_ctree_inverse_f(const wrt_ctree *t, const uint32_t *root, float *v, double *scratch);
void wrt_ctree_forward_d(const wrt_ctree *t, const uint32_t *root, double *v, int nch, double *scratch);
void wrt_ctree_inverse_d(const wrt_ctree *t, const uint32_t *root, double *v, int nch, double *scratch);

#endif
