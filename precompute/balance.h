/* balance.h: the power balance of T's root rows (balance.c), after the DTO and before
 * the series, and the power a basis function carries (used by the series' stop rule).
 * Depends on dto.h (the links' records). */
#ifndef WRT_BALANCE_H
#define WRT_BALANCE_H

#include "dto.h"

/* The power balance (balance.c): correction triplets for the quads' root rows of T, so
 * that every diffuse sender function delivers the power its pointwise form factors say.
 * Appends to *tr (count *nt, capacity *cap). Returns 1 if the scene was found closed,
 * else -(q + 1) for the first quad q one of whose rays met no surface (where it is open). */
/* 1 if wrt_balance_run reads the pair entry e (a diffuse sender's entry to a receiver's
 * root, or to a general quad's wavelet): the pairs' other entries may be freed before it
 * runs (bake.c, once they are T's triplets). */
int wrt_balance_reads_entry(const bake_ctx *b, const pair_entry *e);
int wrt_balance_run(const bake_ctx *b, size_t np, const int *pr, const int *ps, const pair_out *out,
                     const uint64_t *fkeys, uint32_t nf, wrt_triplet **tr, uint64_t *nt, uint64_t *cap);

/* int h(u) sqrt(J(u)) du for the spatial function (n, type) of quad q (balance.c): the
 * power (irradiance x area) a unit coefficient carries, and the coefficient of a uniform
 * irradiance 1. sqrt(A) for a parallelogram's root, 0 for its wavelets; a general quad's
 * wavelets carry a little. */
double wrt_func_power(const wrt_quad *q, wrt_node n, int type);
/* wrt_func_power of every function with an angular root (0 for the others); malloc'd. */
double *wrt_power_weights(const bake_ctx *b, const uint64_t *fkeys, uint32_t nf);

/* The power balance of glossy senders (balance.c), on the assembled T: returns the
 * number of entries adjusted. */
uint64_t wrt_balance_glossy(const bake_ctx *b, const uint64_t *fkeys, uint32_t nf, wrt_csc *T);
/* The same for the first-bounce operator K's columns (res->kkeys, kvals adjusted in
 * place; res->fkeys indexed): returns the number of entries adjusted. */
uint64_t wrt_balance_k(const bake_ctx *b, wrt_bake_result *res);

#endif
