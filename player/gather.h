/* gather.h: the last bounce on glossy quads at the display's resolution (a final
 * gather, docs/glossy/gather_runtime.md). What the eye sees on a glossy surface,
 *   L_o(x, w_o) = sum over incident cells a of L_in(x, a) beta(a, w_o),
 *   beta(a, w_o) = integral over cell a of f_r(w_i, w_o) cos(theta_i) dw_i,
 * with a one of GATHER_DIRS x GATHER_DIRS cells of the cosine-weighted concentric map
 * (common/basis.h) and x one of n x n points of the quad (n = 16; on a sharp lobe, narrow
 * or a metal's, one per texel of its texture, up to 32: gather.c says why). At creation one ray per (point, cell) finds the quad and (u, v)
 * the cell sees (geometry only); beta is tabulated per glossy material at GATHER_BRES x
 * GATHER_BRES outgoing directions.
 * At a light change the radiance L_in reads is rebuilt: a hit quad sends albedo/pi x
 * (direct + indirect irradiance), the direct from the caller's lights (with shadows) on a GATHER_DTEX grid
 * of the seen quad, the indirect from the caller's texture of it (albedo/pi x indirect
 * irradiance; a diffuse quad's displayed texture), both resampled onto a GATHER_RG grid
 * whose nearest cell each ray reads (a table made at creation). A diffuse quad's albedo
 * is its base colour (exact); a glossy quad's is the caller's mean directional albedo,
 * a diffuse stand-in for its lobe (exact for uniform incident light; a glossy quad seen
 * in another shows no sharp reflection of its own). L_in itself is not stored: each
 * point reads its cells' radiance through the table when it sums (at a light change and
 * at an eye move), against its beta row toward the eye: the four table rows around w_o
 * blended when the eye moves and kept (bfloat16) while it stays. Everything is linear in the lights. Loops and memory are the caller's
 * (wrt_gather_env: the relighter's job hook or pool, and its allocator). Depends on
 * Embree 3, common/brdf.h and common/basis.h. */
#ifndef WRT_GATHER_H
#define WRT_GATHER_H

#include <embree3/rtcore.h>

#include "../common/scene_types.h"
#include "../common/wrt_common.h"

typedef struct wrt_gather wrt_gather;

/* A lobe that reflects a sharp image (narrow, or a metal's moderate one): the gather takes
 * a point per texel of its quad's texture, up to WRT_GATHER_SHARP_RES a side, and the
 * caller shows such a quad at that resolution whatever its cells in the file. */
#define WRT_GATHER_SHARP_RES 32
int wrt_gather_sharp(const wrt_material *m);

typedef struct wrt_gather_quad {
    wrt_v3 p[4], n, t, b;     /* corners (bilinear in u, v as relight_internal.h), frame */
    const wrt_material *mat;  /* NULL or Lambertian: diffuse; else glossy (gathered) */
    float albedo[3];          /* what a ray that sees it gets: albedo/pi x direct + tex */
} wrt_gather_quad;

/* The caller's parallel loop (fn(ctx, item) for item in [0, n), any threads; the user or context pointer comes first in every callback, as in include/wrt.h) and
 * allocator (zeroed blocks; NULL: no memory). */
typedef void (*wrt_gather_item_fn)(void *ctx, size_t item);
typedef struct wrt_gather_env {
    void (*run)(void *user, size_t n, wrt_gather_item_fn fn, void *ctx);
    void *(*alloc)(void *user, size_t bytes);
    void (*free)(void *user, void *p);
    void *user;
    /* Optional (NULL: none): called by wrt_gather_create on the calling thread after each
     * piece of its work (`piece` points' rays, or as many rows of a BRDF table), with the
     * fraction of the creation done, rising to 1; returning 0 cancels it. */
    int (*progress)(void *user, double fraction);
    int piece;  /* points (or table rows) a piece: a few for each thread of `run`; 0: 8 */
    int simd;   /* the light change's sums: 0 the widest the processor has (AVX2 or SSE2), 1
                 * plain loops, 2 SSE2 (the same bits whichever: tests and A/B timings) */
    int wide;   /* 1: every quad's sum entries in the general form (a 4-byte offset, RGB betas);
                 * 0: the narrow form where it holds (gather.c: a 2-byte cell index and one
                 * beta for a grey lobe), the same bits (tests and A/B timings) */
} wrt_gather_env;

/* Direct irradiance (RGB, shadows included) from the lights at the n points x[0..n) of a
 * quad with unit normal nrm (a row of the direct grid: the caller may trace their shadow
 * rays as packets): out[3 k + c] at x[k]. */
typedef void (*wrt_gather_direct_fn)(void *user, const wrt_v3 *x, int n, wrt_v3 nrm, double *out);

/* NULL *out and WRT_OK when no quad is glossy. out_res[q] (may be NULL): the side of the
 * texture wrt_gather_eye will write for quad q (a narrow lobe gets a point per texel).
 * points: 16 or 32 gives every glossy quad that many points a side (before/after
 * figures); 0 (or any other value): chosen per quad. Errors: WRT_ERR_NOMEM, WRT_ERR_CANCELLED
 * (env->progress returned 0: everything freed). */
wrt_status wrt_gather_create(int nq, const wrt_gather_quad *q, const int *out_res, RTCScene scene, wrt_v3 origin,
                             double eps, int points, const wrt_gather_env *env, wrt_gather **out);
void wrt_gather_destroy(wrt_gather *g); /* NULL: no-op */

/* What a light change's sums read: their entries (*entries, may be NULL) and the bytes
 * those take (offsets or indices and betas; the radiance cells they read not counted). */
size_t wrt_gather_entry_bytes(const wrt_gather *g, size_t *entries);

/* Rebuilds L_in from the lights (direct) and the quads' displayed textures tex[q] of
 * tex_res[q] texels a side (outgoing indirect radiance, RGB). */
void wrt_gather_lights(wrt_gather *g, wrt_gather_direct_fn direct, void *user, const float *const *tex,
                       const int *tex_res);

/* Writes the gathered outgoing radiance toward the eye into out[q] (out_res[q] a side)
 * of every glossy quad q; other quads' out[q] are not touched. */
void wrt_gather_eye(wrt_gather *g, const double eye[3], float *const *out, const int *out_res);

#endif
