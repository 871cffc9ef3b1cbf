/* bake_internal.h: what the parts of the bake share and nothing else does: the bake
 * context (the scene in a local frame, Embree's scene, options) and per-thread counters. */
#ifndef WRT_BAKE_INTERNAL_H
#define WRT_BAKE_INTERNAL_H

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
    float **btilde;         /* per glossy material: BT_RES^2 x 4^L x 3 table of btilde */
    atomic_int *cancel;
} bake_ctx;

typedef struct bake_thread_counters {
    uint64_t samples, rays_traced, rays_skipped_facing, rays_skipped_unoccluded;
    uint64_t links_refined, links_leaf, links_invisible;
    double t_rays;
    char pad[64];
} bake_thread_counters;

typedef struct pair_entry { uint64_t r, s; float v[3]; } pair_entry;
typedef struct pair_out {
    pair_entry *e; size_t count;
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
 * at the outgoing direction with concentric coordinates (a, b) in the quad's frame. */
#define WRT_BT_RES 32
void wrt_bake_btilde(const bake_ctx *b, int m, double a, double bb, double *out);
/* Builds b->btilde for every glossy material (bake.c). */
void wrt_bake_btilde_build(bake_ctx *b);
void wrt_angular_func(int idx, wrt_node *n, int *type);

/* The Neumann series (series.c): fills res->op and the series counters. */
wrt_status wrt_series_run(const bake_ctx *b, wrt_bake_result *res);

#endif
