/* bake_ctx.h: what the parts of the bake share and nothing else does: the bake
 * context (the scene in a local frame, Embree's scene, options) and per-thread counters. */
#ifndef WRT_BAKE_CTX_H
#define WRT_BAKE_CTX_H

#include <stdatomic.h>
#include <embree3/rtcore.h>

#include "../common/basis.h"
#include "bake.h"

typedef struct bake_ctx {
    wrt_bake_options opt;
    const wrt_scene *scene;
    int nq;
    wrt_quad *quads;        /* the scene's quads, translated to the bounding box centre */
    double (*rho)[3];       /* diffuse albedo per quad */
    RTCDevice dev;
    RTCScene rtc;
    double scene_size;      /* bounding box diagonal */
    double ray_eps;         /* offsets along normals and at ray ends */
    double plane_eps;       /* "in front of a plane" tolerance */
    double entry_floor;     /* entries below this are dropped at emission */
    uint8_t *alevel;        /* angular level per material (0: Lambertian) */
    float **btilde;         /* per glossy material: common/brdf_table.h's table, or NULL */
    atomic_int *cancel;
} bake_ctx;

typedef struct bake_thread_counters {
    uint64_t samples, rays_traced, rays_skipped_facing, rays_skipped_unoccluded;
    uint64_t links_refined, links_leaf, links_invisible;
    double t_rays;
    char pad[64];
} bake_thread_counters;

typedef struct pair_entry { uint64_t r, s; float v[3]; } pair_entry;
/* A leaf link of a pair with a diffuse sender, kept for the power balance (balance.c):
 * the receiver and sender cells (dto.c's node packing) and the visible share of the
 * link's sampled form factor (1 where no occluder can lie between the quads). */
typedef struct leaf_rec { uint32_t rn, sn; float vis; } leaf_rec;
typedef struct pair_out {
    pair_entry *e; size_t count;
    leaf_rec *leaf; size_t nleaf;
    int occluded;          /* an occluder may lie between the quads */
    int leaf_dirs;         /* bit 0: the leaves serve sender s; bit 1: also sender r (reciprocal pair) */
    uint64_t links;
    uint64_t angular;      /* entries with an angular wavelet on either side */
    int glossy;            /* the pair touches a glossy quad */
    int cancelled;
} pair_out;

/* Refines, integrates and analyses the links from quad s to quad r (dto.c). */
/* flags: bit 0 an occluder may lie between, bit 1 diffuse pair computed once for both
 * directions (the entries of T[s][r] are emitted too). */
void wrt_dto_pair(const bake_ctx *b, int r, int s, int flags, bake_thread_counters *tc, pair_out *out);

/* btilde_g(w_o) for every angular function g of material m's level, RGB (out[3 * g + c]),
 * at the outgoing direction with concentric coordinates (a, b) in the quad's frame:
 * the shared table of common/brdf_table.h. */
void wrt_bake_btilde(const bake_ctx *b, int m, double a, double bb, double *out);
/* Builds b->btilde for every glossy material (bake.c). */
void wrt_bake_btilde_build(bake_ctx *b);
void wrt_angular_func(int idx, wrt_node *n, int *type);

/* splitmix64's finalizer: sample keys and hash slots from integers. */
static inline uint64_t wrt_mix64(uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* The corners of cell n of quad q, in order. */
static inline void wrt_cell_poly(const wrt_quad *q, wrt_node n, wrt_v3 out[4]) {
    double x0 = wrt_node_x0(n), y0 = wrt_node_y0(n), sz = wrt_node_size(n);
    out[0] = wrt_quad_point(q, x0, y0);
    out[1] = wrt_quad_point(q, x0 + sz, y0);
    out[2] = wrt_quad_point(q, x0 + sz, y0 + sz);
    out[3] = wrt_quad_point(q, x0, y0 + sz);
}

static inline uint32_t wrt_node_pack(wrt_node n) { return ((uint32_t)n.level << 26) | ((uint32_t)n.y << 13) | n.x; }
static inline wrt_node wrt_node_unpack(uint32_t k) {
    wrt_node n = {(uint8_t)(k >> 26), (uint16_t)(k & 0x1FFF), (uint16_t)((k >> 13) & 0x1FFF)};
    return n;
}

/* The power balance (balance.c): correction triplets for the quads' root rows of T, so
 * that every diffuse sender function delivers the power its pointwise form factors say.
 * Appends to *tr (count *nt, capacity *cap). Returns 1 if the scene was found closed. */
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

/* The Neumann series (series.c): fills res->op and the series counters. */
wrt_status wrt_series_run(const bake_ctx *b, wrt_bake_result *res);

#endif
