/* dist.h: the bake divided among processes (wrt-bake-mpi, docs/mpi.md) without the bake
 * knowing how they talk: the caller gives one collective, an all-gather of bytes, and
 * the bake divides the DTO's quad pairs and the series' product columns among the
 * ranks, then merges every rank's share in pair and column order, so that each rank
 * holds what the single process holds and the file is byte for byte the same.
 * This part uses no MPI (mpi/main_mpi.c implements the collective with it). */
#ifndef WRT_DIST_H
#define WRT_DIST_H

#include <stddef.h>
#include <stdint.h>

#include "../common/wrt_common.h"
#include "sparse.h"

typedef struct wrt_bake_dist {
    int rank, nranks;
    /* Every rank calls it with its `len` bytes at `mine`; it returns in *all (malloc'd)
     * the ranks' bytes one after the other in rank order, and in lens[r] rank r's byte
     * count (lens has nranks slots). WRT_OK, or a failure (wrt_fail) after which the
     * bake stops. */
    wrt_status (*allgather)(void *user, const void *mine, uint64_t len, void **all, uint64_t *lens);
    void *user;
    /* Optional (NULL: the series gathers every product whole on every rank): every rank
     * calls it with nranks segments one after the other at `send`, sendlens[q] bytes for
     * rank q; it returns in *recv (malloc'd) the segments addressed to this rank, from
     * rank 0 to nranks - 1, and in recvlens[q] rank q's byte count. WRT_OK, or a failure
     * (wrt_fail) after which the bake stops. */
    wrt_status (*alltoall)(void *user, const void *send, const uint64_t *sendlens, void **recv, uint64_t *recvlens);
    /* what this rank sent and received, per phase (filled by the bake; docs/mpi.md) */
    uint64_t bytes_sent[3], bytes_recv[3]; /* WRT_DIST_DTO, WRT_DIST_SERIES, WRT_DIST_COUNTERS */
    double cpu_dto, cpu_series;           /* this process's CPU seconds in each phase */
    double cpu_products;                  /* part of cpu_series: the tree series' products by
                                           * column ranges (series.c), this rank's columns */
    double recut_at;                      /* the tree series' ranges re-cut where the most
                                           * loaded rank's cost is above this many times the
                                           * mean, whatever the work saved (0: the defaults of
                                           * series_recut.c; below 0: cut once, never again) */
    uint32_t recuts;                      /* the tree series' ranges re-cut (series_recut.c) */
    uint64_t recut_bytes;                 /* the bytes this rank sent in those re-cuts */
    uint64_t products_cost;               /* the cost model's units of this rank's products
                                           * (series_recut.c), for the report */
    uint64_t products_peak;               /* the largest product's cost, all the ranks' */
    double cpu_links, cpu_assemble;       /* parts of cpu_dto: the cluster tree and its links
                                           * (--clusters), and T's assembly (keys, balance, matrix) */
    uint64_t peak_dto;                    /* this process's peak resident bytes up to the series */
    uint64_t piece_bytes;                 /* the bytes of one round of a per-item merge, all the
                                           * ranks' shares (wrt_dist_merge_items; 0: 32 MiB) */
} wrt_bake_dist;

enum { WRT_DIST_DTO = 0, WRT_DIST_SERIES = 1, WRT_DIST_COUNTERS = 2 };

/* 1 when the bake is divided (dist given and more than one rank). */
static inline int wrt_dist_on(const wrt_bake_dist *d) { return d && d->nranks > 1; }

/* The ranks' shares of n items of estimated cost cost[i]: owner[i] is the rank that
 * computes item i (largest cost first, each to the rank with the least cost so far,
 * ties to the lower rank and index: the same on every rank). */
void wrt_dist_assign(const double *cost, uint64_t n, int nranks, int *owner);

/* The contiguous column ranges of a product A B balanced by its cost (per column j,
 * the entries of A's columns that B's column j reads): rank r computes columns
 * [cut[r], cut[r + 1]); cut has nranks + 1 slots. */
void wrt_dist_mul_cuts(const wrt_csc *a, const wrt_csc *b, int nranks, uint32_t *cut);

/* C = A B as wrt_csc_mul, each rank computing its columns, the result on every rank. */
wrt_status wrt_dist_mul(wrt_bake_dist *d, const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w,
                        int threads, wrt_csc *out);

/* The series by shares (series.c, docs/mpi.md "Each rank holds its share of the
 * series"): a term's columns [cut[r], cut[r + 1]) are rank r's alone, and a product's
 * column j reads the previous term's columns that the right factor's column j names. */

/* Every rank's needed columns of a term: need[q * n + i] is 1 where a column j of rank q's
 * range [cut[q], cut[q + 1]) of the right factor r has an entry at row i (r whole). */
uint8_t *wrt_dist_share_need(const wrt_csc *r, int nranks, const uint32_t *cut);

/* From this rank's columns of a term (own: its range filled, the others empty), the
 * columns this rank needs (need as above): each rank sends each other the columns of its
 * range that the other needs (all-to-alls in rounds of piece_bytes). *in: those columns
 * and every one of this rank's own (so that own may be freed), the others empty. */
wrt_status wrt_dist_share_fetch(wrt_bake_dist *d, const wrt_csc *own, const uint32_t *cut, const uint8_t *need,
                                wrt_csc *in);

/* Every rank's columns of a matrix (own: its range filled; freed once sent) gathered on
 * rank 0 as one matrix in column order (*all); on the other ranks *all is empty (n
 * columns, no entries). */
wrt_status wrt_dist_share_to_root(wrt_bake_dist *d, wrt_csc *own, const uint32_t *cut, wrt_csc *all);

/* The contiguous column ranges of n columns of integer cost cost[j] (the same cut on every
 * rank): rank r's ends where the running cost first reaches (r + 1) / nranks of the
 * total. cut has nranks + 1 slots. */
void wrt_dist_cost_cuts(const uint64_t *cost, uint32_t n, int nranks, uint32_t *cut);

/* Every rank's costs of its range [cut[rank], cut[rank + 1]) (mine, one per column)
 * gathered: all[j] for the cut[nranks] columns, on every rank. */
wrt_status wrt_dist_share_costs(wrt_bake_dist *d, const uint64_t *mine, const uint32_t *cut, uint64_t *all);

/* A share re-cut: m holds this rank's range of cut (the others empty) and afterwards its
 * range of `to`, the columns that change owner sent in the rounds of share_send and the
 * ones it keeps moved in place (the matrix is not copied whole). */
wrt_status wrt_dist_share_move(wrt_bake_dist *d, wrt_csc *m, const uint32_t *cut, const uint32_t *to);

/* A sum in the single process's order over the ranks' shares: rank 0 calls fn(user, acc)
 * from *acc, then rank 1 from rank 0's result, ...; every rank ends with the last (the
 * same bits as one process summing its whole storage order). fn returns 0 on a failure,
 * which then fails every rank. */
wrt_status wrt_dist_chain_sum(wrt_bake_dist *d, double *acc, int (*fn)(void *user, double *acc), void *user);

/* Per-item records merged: item i (of n) is computed by rank owner[i], which packs it
 * into size(user, i) bytes; after the exchange every other rank unpacks it (len bytes),
 * within a rank's items in index order (the ranks' items interleaved by rounds: the
 * merge goes in rounds of about piece_bytes). The bytes count in `phase`. */
typedef struct wrt_dist_items {
    uint64_t (*size)(void *user, size_t i);
    void (*pack)(void *user, size_t i, uint8_t *p);
    void (*unpack)(void *user, size_t i, const uint8_t *p, uint64_t len);
    void *user;
} wrt_dist_items;
wrt_status wrt_dist_merge_items(wrt_bake_dist *d, int phase, const int *owner, size_t n, const wrt_dist_items *f);

/* The DTO's pairs (dto.h): each rank has computed out[i] for the pairs it owns
 * (owner[i] == rank); afterwards every rank holds every pair's out[i] as the DTO made it
 * (a diffuse pair's compact records stay compact). */
struct pair_out;
wrt_status wrt_dist_merge_pairs(wrt_bake_dist *d, const int *owner, struct pair_out *out, size_t np);

/* Per-item results (n items, item s computed by rank owner[s]: res[s], nres[s]
 * triplets); afterwards every rank holds every item's (the balance's senders). */
wrt_status wrt_dist_merge_triplets(wrt_bake_dist *d, const int *owner, wrt_triplet **res, uint64_t *nres, size_t n);

/* Rows of `width` bytes, row i computed by rank owner[i]: `mine` holds this rank's
 * rows in order; returns every row in order (malloc'd), NULL where the exchange failed. */
uint8_t *wrt_dist_gather_rows(wrt_bake_dist *d, const int *owner, size_t nrows, const uint8_t *mine, size_t width);

/* This process's CPU seconds so far (all its threads). */
double wrt_dist_cpu_now(void);

/* Sums n uint64 counters over the ranks (in place). */
wrt_status wrt_dist_sum_u64(wrt_bake_dist *d, uint64_t *v, int n);

#endif
