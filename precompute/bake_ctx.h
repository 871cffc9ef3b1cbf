/* bake_ctx.h: what the parts of the bake share and nothing else does: the bake
 * context (the scene in a local frame, Embree's scene, options, the BRDF tables),
 * per-thread counters and small cell helpers. The stages have narrow headers of their
 * own, called in this order by the driver (bake.c): dto.h -> balance.h -> series.h. */
#ifndef WRT_BAKE_CTX_H
#define WRT_BAKE_CTX_H

#include <math.h>
#include <stdatomic.h>
#include <embree3/rtcore.h>

#include "../common/basis.h"
#include "../common/brdf_table.h"
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
    uint8_t *klevel;        /* outgoing angular level of the first-bounce operator K per material (0: none) */
    double (*kbmax)[1 << (2 * WRT_K_MAX_LEVEL)];    /* per material: max over directions and channels of |btilde_g| (K's emission) */
    double k_floor;         /* K's entries with |K| sqrt(A_S/A_R) kbmax_g below this are dropped */
    float **btilde;         /* per glossy material: common/brdf_table.h's table, or NULL */
    atomic_int *cancel;
    /* Memory of the pairs' link tables in flight (dto.c): a table's growth is refused
     * before it is allocated when the sum would pass pool_limit bytes; pool_refused then
     * holds the size it would have reached, and the bake is cancelled. */
    atomic_ullong *pool_bytes, *pool_refused;
    double pool_limit;
    /* --clusters (cluster.h): the tree and its links; the pair balance then runs in its
     * open-scene mode and the closed-scene rule is applied with the links (cluster_ops.c) */
    const struct wrt_clusters *cl;
    int balance_open;
    double depth_area;      /* depth_share x the scene's area (0: the share rule off; dto.c) */
    uint8_t *cover;         /* per quad: 1 if some part is inside closed geometry (cover.c) */
    struct stage_clock *clock; /* WRT_DTO_TIMES: the DTO phase's stage timer (bake.c) */
} bake_ctx;

/* The DTO phase's stage timer (WRT_DTO_TIMES): on, and the last mark's wall and CPU */
typedef struct stage_clock { int on; double w, c; } stage_clock;

typedef struct bake_thread_counters {
    uint64_t samples, rays_traced, rays_skipped_facing, rays_skipped_unoccluded;
    uint64_t links_refined, links_leaf, links_invisible;
    uint64_t cover_x, cover_y; /* WRT_DTO_TIMES: receiver and sender points tested for cover */
    uint64_t cover_exact;      /* those tested with rays, not by the quad's map (cover.c) */
    double t_rays;
    char pad[64];
} bake_thread_counters;

/* btilde_g(w_o) for every angular function g of material m's level, RGB (out[3 * g + c]),
 * at the outgoing direction with concentric coordinates (a, b) in the quad's frame:
 * the shared table of common/brdf_table.h. */
static inline void wrt_bake_btilde(const bake_ctx *b, int m, double a, double bb, double *out) {
    wrt_brdf_table_lookup(b->btilde[m], 1 << (2 * b->alevel[m]), a, bb, out);
}

/* The oracle's weight of quad q's detail (bake.h depth_share): sqrt(A_q / depth_area) for a
 * quad under depth_area, else 1 (and 1 with the rule off). */
static inline double wrt_depth_weight(const bake_ctx *b, int q) {
    double a = b->quads[q].area;
    return a < b->depth_area ? sqrt(a / b->depth_area) : 1.0;
}

/* splitmix64's finalizer: sample keys and hash slots from integers. */
static inline uint64_t wrt_mix64(uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* 1 if the segment a -> b is blocked by some quad; both ends must already be lifted off
 * their quads along the normals (by ray_eps): the ray is not trimmed (dto.c). */
int wrt_bake_occluded(const bake_ctx *b, wrt_v3 a, wrt_v3 bpt);

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

#endif
