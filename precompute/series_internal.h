/* series_internal.h: the Neumann series' working state (series.c) and the stages kept in
 * files of their own: the series in the senders' tree basis (series_tree.c). Not part of
 * the bake's interface: only series*.c include it. */
#ifndef WRT_SERIES_INTERNAL_H
#define WRT_SERIES_INTERNAL_H

#include "bake_ctx.h"
#include "cluster.h"
#include "series_power.h"
#include "spill.h"
#include "series_stream.h"

/* The power iteration of series_bounces (see there) on T (in memory, or spilled): the
 * start vector's image, then one step an iteration giving the ratios rc[3] */
typedef struct {
    uint32_t n;
    double *x, *y, vp_prev[3];
    /* y += T x made by apply(user, x, y) where T is not held (series_first.c); n set */
    void (*apply)(void *user, const double *x, double *y);
    void *user;
} power_iter;
/* The iteration started at the power weights pw (series_iter.c) */
void wrt_power_iter_start(power_iter *p, const wrt_csc *T, const double *pw);
/* The next iterate: x = y / its power, y = T x (T, or the scratch file sp where T is
 * NULL, or p->apply); rc the ratio of the powers. 0 where sp could not be read back. */
int wrt_power_iter_step(power_iter *p, const wrt_csc *T, wrt_spill *sp, const double *pw, double rc[3]);
void wrt_power_iter_free(power_iter *p);

/* The series' working state, shared by its stages */
typedef struct {
    const bake_ctx *b;
    wrt_bake_result *res;
    wrt_bake_counters *C;
    const wrt_csc *T;
    double eps;
    int threads;
    double *rw, *cw, *pw, *boost;
    wrt_csc_weights W;
    wrt_csc S, P;
    wrt_csc Tr;     /* --series-right: T compressed, the right factor of the later bounces */
    int shared;     /* 1 while P and Tr are one matrix (the first term, at 1 x eps) */
    double rc[3], ratio;
    /* series_consume: T's arrays taken by S; what the bounces and the tail needed of T
     * computed before: the power iteration's ratios and the power targets */
    int consumed;
    wrt_spill Tf;   /* T in the scratch file, for the power iteration */
    /* streamed: S in scratch files between bounces (series_stream.h), not in memory */
    int streamed;
    wrt_sum_stream ss;
    double *u;      /* 3n: the power targets (series_power.h) */
    int u_bounces;
    power_iter pi;
    /* wrt-bake-mpi by shares (series_share_start): P, Tr and the streamed sum hold only
     * this rank's columns [cut[rank], cut[rank + 1]); need: every rank's needed columns
     * of a term (dist.h) */
    int share;
    uint32_t *cut;
    uint8_t *need;
    uint64_t p_all; /* by shares: the term's entries on all the ranks */
    /* the terms in the senders' tree basis (series_tree_on): TW the products' weights with
     * the tree's columns (tcw, tboost), troot each quad's root slot */
    int tree;
    uint32_t *troot;
    double *tcw, *tboost;
    uint8_t *apart;           /* per tree node: wrt_clusters_apart's flag (series_tree_apart) */
    wrt_csc_weights TW;
    /* the products' left factor kept as T = E1 U (wrt_series_factored_on): Tr is then E1
     * compressed and cut (nf + nodes columns), each product E1 (U P_k); FW the products'
     * weights with the node columns' (fcw, fboost: 1) */
    int fac;
    double *fcw, *fboost;
    wrt_csc_weights FW;
    int timing;        /* WRT_DTO_TIMES set: each product's times on stderr */
    wrt_csc_bands Trb; /* Tr by bands, with series_skip (FW.bands) */
    /* T never formed (series_first.c): T = E1 U read from E1 (the bake's, kept to the end) */
    int no_t;
    const wrt_csc *E1;
    int fac_parts;  /* wrt_series_factored_blocks' blocks a product (0: WRT_FAC_BLOCKS) */
    double mark_w, mark_c; /* WRT_DTO_TIMES: the last stage's end (wrt_series_mark) */
} series_state;

/* WRT_DTO_TIMES set: the stage just ended, its wall and CPU seconds, on stderr */
void wrt_series_mark(series_state *s, const char *stage);

/* The factored tree series by blocks of columns through every bounce (series_cols.c):
 * whether it runs; the bounces, the tail and the stored operator's compression into s->S
 * (the first term s->P and the sum's first state s->S consumed); a diverging series
 * refused (ratio >= 1 with `energy`, the light left, not yet under 1e-6) */
int wrt_series_cols_on(const series_state *s);
/* Columns [c0, c1) of m in arrays of their own, the others empty (series.c) */
wrt_csc wrt_series_csc_range(const wrt_csc *m, uint32_t c0, uint32_t c1);
wrt_status wrt_series_cols(series_state *s);
wrt_status wrt_series_diverging(const series_state *s, double energy, int bounces);

/* The small senders' rule's area (series.c): a quad under it holds its mean's light */
double wrt_series_small_area(const bake_ctx *b);
/* The stored operator's compression threshold and weights (series.c); *own to free */
double wrt_series_final_weights(series_state *s, wrt_csc_weights *W, double **own);

/* The series in the senders' tree basis (series_tree.c; docs/clusters.md) */
int wrt_series_tree_on(const bake_ctx *b);
void wrt_series_tree_start(series_state *s);
/* by shares: the sum's first state cut to this rank's columns [c0, c1) */
void wrt_series_tree_sum_start(series_state *s, uint32_t c0, uint32_t c1);
/* Under wrt-bake-mpi by tree shares, before the product a y (y: this rank's columns of the
 * right factor): the ranges re-cut by the product's cost where it is uneven, y's and the
 * sum's columns moved with them (series_recut.c) */
wrt_status wrt_series_share_recut(series_state *s, const wrt_csc *a, wrt_csc *y);
void wrt_series_tree_cols(const series_state *s, const uint32_t *root, const double *cw_in, double **cw_out,
                          double **boost_out);
double wrt_series_final_weights_tree(series_state *s, wrt_csc_weights *W, double *own[3]);
void wrt_series_tree_power(series_state *s, wrt_series_power_stats *ps);
/* The left factor kept as T = E1 U (series_tree.c) */
int wrt_series_factored_on(const bake_ctx *b, const wrt_bake_result *res);
/* checked before wrt_series_factored_start: the right factor's memory against the budget */
wrt_status wrt_series_factored_check(const series_state *s);
void wrt_series_factored_start(series_state *s);
void wrt_series_factored_bands(series_state *s);
/* --clusters: the stored operator's columns in the tree's basis (series_tree.c) */
void wrt_series_senders(series_state *s);
/* The first term's columns [c0, c1) from the sum's first state S (series_tree.c) */
wrt_csc wrt_series_first_range(const series_state *s, const wrt_csc *S, uint32_t c0, uint32_t c1);
wrt_csc wrt_series_factored_right(const series_state *s, const wrt_csc *P);
void wrt_series_factored_trim(const series_state *s, wrt_csc *N);
wrt_csc wrt_series_factored_left(const series_state *s, const wrt_csc *X);
/* In one process, the term after P, E1 (U P), by blocks of P's columns, its memory checked
 * unless `checked` (series_blocks.c); P kept */
wrt_status wrt_series_factored_blocks(series_state *s, int bounce, int checked, wrt_csc *N);

/* T never formed (series_first.c): the sum's first state, T W^T, whole, with the nodes
 * apart (ap; NULL: not); y += T x (a power_iter's apply); the power targets; the column
 * power rule's correction in the senders' tree basis, compressed */
void wrt_series_factored_sum(series_state *s, wrt_csc *S, const wrt_apart_opt *ap);
void wrt_series_factored_apply(void *user, const double *x, double *y);
double *wrt_series_factored_targets(series_state *s, int *bounces);
/* Frees the products' right factor (Tr and its bands); again: nothing */
void wrt_series_free_right(series_state *s);
wrt_csc wrt_series_factored_power_cols(const series_state *s, const double *u, const double *d, double eps,
                                       const wrt_csc_weights *W);

/* The stored operator's rows in the tree's basis: the rows and columns of the nodes apart
 * held finer (series_tree.c) */
void wrt_series_receivers_apart(const series_state *s, double *rw, double *cw);
/* ... and the rows to the tree's basis, kept where fewer (series_tree.c) */
wrt_status wrt_series_receivers(series_state *s);

#endif
