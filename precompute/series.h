/* series.h: the Neumann series G - I = T + T^2 + ... with compression (series.c), the
 * last stage of the bake. Depends on bake_ctx.h. */
#ifndef WRT_SERIES_H
#define WRT_SERIES_H

#include "bake_ctx.h"

/* The Neumann series (series.c): fills res->op and the series counters. */
wrt_status wrt_series_run(const bake_ctx *b, wrt_bake_result *res);
/* Whether the series will multiply by T kept as E1 U (series_tree.c): the bake's assembly
 * then keeps E1 (wrt_clusters_assemble) */
int wrt_series_factored_wanted(const bake_ctx *b);


#endif
