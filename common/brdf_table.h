/* brdf_table.h: the one angular table of a glossy material, shared by the bake (the
 * links' BRDF factor, precompute/dto.c) and the runtime (synthesis, player/relight_synth.c),
 * so both project the BRDF the same way.
 *
 * For an outgoing direction w_o and every angular Haar function g of node levels
 * 0..WRT_BRDF_TABLE_LEVELS-1 over the concentric square (basis.h, wrt_concentric_dir):
 *   beta_g(w_o) = integral f_r(w, w_o) g(M^-1 w) cos dw = pi * int_[0,1]^2 f_r(M(a,b), w_o) g(a,b) da db
 * (the concentric map takes da db to cos dw / pi). For g = the root, beta is the
 * directional albedo.
 *
 * Method: w_o on a WRT_BRDF_TABLE_RES^2 grid of the concentric square (cell centres,
 * bilinear in between); the integral over each of the 16 x 16 leaf cells of the finest
 * level by a 4 x 4 Gauss-Legendre product rule (4096 BRDF evaluations a direction), then
 * an exact Haar analysis of the cell integrals (g is constant on leaf cells). Error
 * against direct high-order integration: docs/bench.md ("BRDF table").
 *
 * Layout: tab[(cell * WRT_BRDF_TABLE_NANG + g) * 3 + c], cell = j * RES + i for w_o at
 * concentric ((i + 0.5) / RES, (j + 0.5) / RES); g indexed as wrt_brdf_angular_index says,
 * so the first 4^L entries are the functions of node levels < L. Depends on brdf.h,
 * basis.h, threads.h. */
#ifndef WRT_BRDF_TABLE_H
#define WRT_BRDF_TABLE_H

#include "scene_types.h"

#define WRT_BRDF_TABLE_RES 32     /* outgoing directions per side */
#define WRT_BRDF_TABLE_LEVELS 4   /* angular node levels 0..3 (basis.h: 2 bits of level) */
#define WRT_BRDF_TABLE_NANG 256   /* 4^LEVELS angular functions */

/* Index of the angular Haar function (node level, x, y, type 0..3) in a table: 0 for
 * the root scaling function, then level by level, node by node (row-major), the three
 * wavelets. -1 if out of range. wrt_brdf_angular_func is its inverse. */
int wrt_brdf_angular_index(int level, int x, int y, int type);
void wrt_brdf_angular_func(int idx, int *level, int *x, int *y, int *type);

/* Floats in one material's table. */
#define WRT_BRDF_TABLE_FLOATS ((size_t)WRT_BRDF_TABLE_RES * WRT_BRDF_TABLE_RES * WRT_BRDF_TABLE_NANG * 3)

/* Fills tab (WRT_BRDF_TABLE_FLOATS floats, caller's memory) for material m on `threads`
 * threads (0 = all cores; the result does not depend on it). No allocation, no failure. */
void wrt_brdf_table_build(const wrt_material *m, int threads, float *tab);
/* One outgoing direction's row of that table (cell in [0, WRT_BRDF_TABLE_RES^2)): for
 * callers that run the cells on threads of their own. */
void wrt_brdf_table_build_cell(const wrt_material *m, int cell, float *tab);

/* beta_g at the outgoing direction with concentric coordinates (a, b), bilinear between
 * the table's directions (clamped at the border), for g in [0, nang): out[3 * g + c]. */
void wrt_brdf_table_lookup(const float *tab, int nang, double a, double b, double *out);

/* One integral of the table, for tests and measurement: beta_g(w_o) for every g by the
 * product Gauss-Legendre rule with `sub` x `sub` sub-cells of `order` points a side in each
 * leaf cell (the table uses sub 1, order 4); out[NANG * 3]. order in 1..8. */
void wrt_brdf_beta_direct(const wrt_material *m, const double wo[3], int sub, int order, double *out);

#endif
