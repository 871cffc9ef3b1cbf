/* cluster.h: the cluster hierarchy of the bake (`--clusters`, docs/clusters.md): the
 * binary tree over the quads (cluster.c), the top-down linking that hands near pairs of
 * quads to the per-pair DTO (dto.c) and couples well separated clusters by one entry
 * (cluster.c), and the operator's expression in the tree's orthonormal Haar basis
 * (cluster_ops.c). Called by the driver (bake.c) and the series (series.c). Depends on
 * bake_ctx.h and common/cluster_tree.h. */
#ifndef WRT_CLUSTER_H
#define WRT_CLUSTER_H

#include "bake_ctx.h"
#include "sparse.h"
#include "../common/cluster_tree.h"

/* A cluster link between nodes a and b (disjoint): T[phi_a][phi_b] = tab (b's albedo),
 * T[phi_b][phi_a] = tba (a's albedo). */
typedef struct wrt_clink { uint32_t a, b; float tab[3], tba[3]; } wrt_clink;

typedef struct wrt_clusters {
    wrt_ctree tree;
    uint32_t *perm;          /* quads in leaf order */
    double *pref;            /* prefix areas over perm (nq + 1) */
    uint32_t *lo, *hi;       /* per node: its quads are perm[lo, hi) */
    wrt_v3 *bmin, *bmax;     /* per node: bounding box of its quads' corners */
    wrt_v3 *axis;            /* per node: unit mean normal (0 if they cancel) */
    double *cosw;            /* per node: min over its quads of n . axis */
    float (*rho)[3];         /* per node: the albedo if uniform */
    uint8_t *uniform;        /* per node: all quads diffuse with one albedo */
    wrt_clink *links; size_t nlinks;
    /* the leaf pairs for the DTO, in a fixed order: r < s, flags as bake.c's */
    int *pr, *ps; uint8_t *occl; size_t np;
    uint64_t pairs_visited, pairs_culled, oracle_calls, oracle_refused_vis, oracle_refused_spread;
    uint64_t rays, links_partial; /* links_partial: cluster links with some rays blocked */
} wrt_clusters;

/* Thresholds (0 = default): separation (distance of centres over the sum of radii) and
 * the relative spread of the sampled kernel that a cluster link accepts. */
#define WRT_CLUSTER_SEP_DEFAULT 1.5
#define WRT_CLUSTER_SPREAD_DEFAULT 0.15
/* The power criterion (cluster_link.c's oracle): a pair whose estimated transported-power
 * error, for unit radiosity on the sender, is at most eps times the scene's area is
 * linked whatever its kernel's spread or partial visibility; where one side's sample
 * points both see and do not see the other (walls), only an error of at most
 * WRT_CLUSTER_EPS_HIDDEN times the area (or eps, if smaller) passes.
 * eps was 1e-4 until session 21, and the hidden bound 1e-3 of it: a small receiver took
 * a spread of up to 1e-4 of the scene's area over its own, pushed down uniformly, and the
 * atrium's far wall showed the clusters as tiles. At 1e-6 (the hidden bound where it was)
 * the atrium at quality 5 went from cells 12.54% to 9.86% and image 8.75% to 5.98% at
 * 22,224 elements, 12.58% to 9.89% and 9.33% to 6.46% at 53,122, for the same leaf pairs
 * and about the same time at scale; tightening the hidden bound too took 4 times the leaf
 * pairs at 22,224 and did not fit the default budget at 53,122 (docs/clusters.md "The
 * power criterion 100 times tighter"). */
#define WRT_CLUSTER_EPS_DEFAULT 1e-6
#define WRT_CLUSTER_EPS_HIDDEN 1e-7

/* The tree over b->quads (cluster.c). */
void wrt_clusters_build(const bake_ctx *b, wrt_clusters *cl);
/* The links and leaf pairs, top-down from (root, root), on b->opt.threads threads;
 * deterministic whatever the thread count. Under wrt-bake-mpi (b->opt.dist) the pairs
 * below the serial top are divided among the ranks and merged in their order, so every
 * rank gets the same; WRT_OK, or the exchange's failure (cluster_link.c). */
wrt_status wrt_clusters_link(const bake_ctx *b, wrt_clusters *cl);
void wrt_clusters_free(wrt_clusters *cl);

/* T (quads' basis, balanced) with the cluster links added, in a closed scene each
 * column's power made what its function emits, the links then pushed down to the quads'
 * roots (cluster_ops.c). Replaces *T. Returns the entries the closed-scene rule added.
 * E1 (may be NULL): the left factor of T = E1 U, kept: the links' receivers pushed down
 * (rows: the quads' functions), their senders not (columns: the quads' functions, then
 * phi_node at nf + node; n = nf + nodes, the rows beyond nf empty). U is the uniform
 * pull-up of the senders, column q of T = E1's column q plus sqrt(a_q / a_B) times E1's
 * column of phi_B for every ancestor B of q's leaf (wrt_clusters_pull_up). build_t 0
 * (with E1): T is not formed (the second push-down skipped), *T left an empty nf x nf
 * matrix; the series then works from E1 and U alone (series_first.c). */
uint64_t wrt_clusters_assemble(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf,
                               int closed, int build_t, wrt_csc *T, wrt_csc *E1);
/* U X for X of the quads' basis (nf rows; columns up to E1->n): X's entries with, per
 * column, the node rows nf + B, Y_B = sum over the quads q of B of sqrt(a_q / a_B) X at
 * q's root (root: per quad its root slot), kept where E1's column nf + B has entries.
 * n = E1->n (the columns beyond X's empty). Then T X = E1 (U X) (cluster_ops.c). On
 * `threads` threads (0: all cores), the same entries whatever their number. */
wrt_csc wrt_clusters_pull_up(const wrt_ctree *t, const uint32_t *root, uint32_t nq, const wrt_csc *E1, uint32_t nf,
                             const wrt_csc *X, int threads);
/* The entries the cluster links become once pushed down to the quads' roots: 2 |A| |B|
 * per link where senders (T), |A| + |B| where only the receivers are (E1) (an upper
 * bound: quads facing away get none) (cluster_ops.c). */
uint64_t wrt_clusters_pushed_entries(const wrt_clusters *cl, int senders);
/* A matrix of the quads' basis (nf x nf) expressed in the tree basis: rows, then columns
 * (cluster_ops.c). Replaces *M. */
void wrt_clusters_to_tree(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf, wrt_csc *M);
/* M's rows (the receivers' side) to the tree basis, into *R, each column compressed by W
 * (eps) as it is made; M's columns as they were. 0 (and *R empty) where the result would
 * pass limit entries, else 1; *raw the entries before the compression. */
int wrt_clusters_rows_to_tree(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf,
                              const wrt_csc *M, double eps, const wrt_csc_weights *W, uint64_t limit, wrt_csc *R,
                              uint64_t *raw);
/* The stored operator M (nf x nf, quads' basis) with the tree's basis on the senders'
 * side only, M W^T (cluster_send.c): the quads' root columns replaced by the columns of
 * phi_root and each internal node's psi_P in their slots (common/cluster_tree.h), each
 * compressed as it is made by `drop` and W (indexed by the slot: the caller gives the
 * node's weights there); the other columns as they are. root: per quad its root slot.
 * Replaces *M and returns 1 where the result has fewer entries than *M, or always; else
 * 0, *M unchanged. *raw: the tree columns' entries before their compression. */
int wrt_clusters_senders(const wrt_ctree *t, const uint32_t *root, wrt_csc *M, double drop,
                         const wrt_csc_weights *W, int always, uint64_t *raw);
/* A column of a matrix given on demand: column f's entries (rows ascending, 3 floats
 * each) in arrays malloc'd by the callee and freed by the caller; returns their number */
typedef uint64_t (*wrt_col_fn)(void *user, uint32_t f, uint32_t **row, float **val);
/* wrt_clusters_senders with the matrix's columns from fn (the matrix is never held whole),
 * always in the tree's basis, only columns [c0, c1) kept (the others empty; the tree is
 * still walked whole, a node's function needing all its quads' columns): the tree columns
 * compressed as there, the others as fn gives them; *raw the whole walk's (cluster_send.c). */
wrt_csc wrt_clusters_senders_cols(const wrt_ctree *t, const uint32_t *root, uint32_t nf, wrt_col_fn fn, void *user,
                                  double drop, const wrt_csc_weights *W, uint32_t c0, uint32_t c1, uint64_t *raw);
/* The same on nusers threads, each with its own fn user (the tree's subtrees walked on
 * them): the same result */
wrt_csc wrt_clusters_senders_cols_th(const wrt_ctree *t, const uint32_t *root, uint32_t nf, wrt_col_fn fn,
                                     void *const *users, int nusers, double drop, const wrt_csc_weights *W,
                                     uint32_t c0, uint32_t c1, uint64_t *raw);
/* ... and wrt_clusters_apart's test made in the same walk (ap NULL: not): ap->apart its
 * result, and each node apart's slot weight in ap->w (W's column weights) times
 * ap->factor before its column is compressed (the root slot's where the root is apart) */
typedef struct {
    const double *pw;
    uint8_t *apart;
    double *w, factor;
} wrt_apart_opt;
wrt_csc wrt_clusters_senders_cols_apart(const wrt_ctree *t, const uint32_t *root, uint32_t nf, wrt_col_fn fn,
                                        void *const *users, int nusers, double drop, const wrt_csc_weights *W,
                                        uint32_t c0, uint32_t c1, uint64_t *raw, const wrt_apart_opt *ap);
/* The series' weights of the root slots for the tree functions: areas of their nodes
 * (rw = 1/sqrt(a), cw = sqrt(a)), the small senders' factor 1 there (boost, may be NULL:
 * a node is not a small sender) and the power weights transformed (cluster_ops.c). */
void wrt_clusters_series_weights(const bake_ctx *b, const wrt_clusters *cl, const uint64_t *fkeys, uint32_t nf,
                                 double *rw, double *cw, double *pw, double *boost);
/* Per node of t, 1 where the node or a node below it has two halves whose light (the
 * quads' root columns of M, nf x nf, the quads' basis: wr phi_L and wl phi_R) lands on
 * rows apart: the rows' power (pw) both reach is under WRT_CLUSTER_APART of the smaller
 * half's (two rooms sharing a wall). A light on one side alone has coefficients on such
 * nodes' functions whose rows on the other side cancel (cluster_send.c, series_tree.c).
 * M NULL: the columns from fn, as wrt_clusters_senders_cols. */
#define WRT_CLUSTER_APART 0.01
void wrt_clusters_apart(const wrt_ctree *t, const uint32_t *root, const wrt_csc *M, wrt_col_fn fn, void *user,
                        const double *pw, uint8_t *apart);
void wrt_clusters_apart_th(const wrt_ctree *t, const uint32_t *root, const wrt_csc *M, wrt_col_fn fn,
                           void *const *users, int nusers, const double *pw, uint8_t *apart);
/* The root slot (function index) of every quad; malloc'd (cluster_ops.c). */
uint32_t *wrt_clusters_root_index(const uint64_t *fkeys, uint32_t nf, uint32_t nq);

/* bake.c's pair tests, shared with the linking. */
int wrt_bake_can_exchange(const bake_ctx *b, const wrt_quad *r, const wrt_quad *s);
int wrt_bake_may_occlude(const bake_ctx *b, const wrt_quad *r, const wrt_quad *s, const wrt_quad *o);

#endif
