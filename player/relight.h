/* relight.h: the player's run-time core (paper section 5): each time a light moves,
 * project the direct light onto the wavelet basis (E), apply the baked indirect
 * operator (X = Op E, Op = G - I or the gathered T_fine G, both indirect only), turn
 * incident into outgoing radiance with each quad's BRDF, and synthesize one texture of
 * outgoing indirect radiance per quad. Independent of OpenGL: the display (render.c)
 * only uploads the textures. Depends on formats/gto.h, common/basis.h, common/brdf.h,
 * Embree 3 (shadow rays for the projection). Not thread-safe: one caller at a time. */
#ifndef WRT_RELIGHT_H
#define WRT_RELIGHT_H

#include "../formats/gto.h"

typedef struct wrt_relight wrt_relight;

typedef struct wrt_relight_options {
    int proj_level;      /* spatial projection level; 0 = chosen per quad from the light (default) */
    int max_tex_res;     /* cap on a quad's texture resolution (0 = 64) */
    int threads;         /* 0 = all cores */
    int proj_reference;  /* n > 0: sample every cell of every quad's finest grid (no
                          * adaptivity; slow, for tests): n = 1 with the 4 samples a
                          * cell the adaptive projection takes, n = 2..8 with n x n */
    int haar_blocks;     /* 1: textures are the Haar cells as they are (no smooth
                          * reconstruction, common/reconstruct.h): for before/after */
    int recon_extra;     /* smooth texture's levels past the finest cells' (0 = the
                          * default: none; negative: coarser) */
    int recon_keep;      /* the bake's cell averages kept as computed down to 2^keep cells
                          * a side, resampled smoothly below (0 = the default, 3) */
    int no_gather;       /* 1: glossy quads show the coarse angular synthesis only, no
                          * final gather (player/gather.h); for before/after figures */
    int no_light_splat;  /* 1: the light's direction on a glossy quad truncated to its
                          * finest angular cell instead of spread over one cell centred
                          * on it (a bake without K; before/after figures) */
    int gather_points;   /* 16 or 32: every glossy quad's final-gather points a side;
                          * 0 (the default): a point per texel on a sharp lobe, else 16 */
    int no_avx;          /* 1: K's rows in fours without AVX (the same sums to the bit;
                          * for the test that says so, and A/B timings) */
    int occ_scan;        /* 1: the projection's occluder search tests every quad instead
                          * of walking the tree of their spheres (the same occluders; for
                          * the test that says so, and A/B timings) */
    int linear_display;  /* 1: the smooth reconstruction is a fixed linear operator
                          * (wrt_recon_params.linear: no limiter, no sharpness test, no
                          * clamp), so textures superpose across lights; 0: the default */
    void *(*alloc)(void *user, size_t size); /* every block of the relighter (both or neither; */
    void (*free)(void *user, void *p);        /* NULL: malloc and free), the update's scratch */
    void *alloc_user;                         /* too (then from the worker threads: thread-safe) */
    /* Job hook (include/wrt.h, wrt_runtime_options.parallel_for): runs fn(ctx, i) for i in
     * [0, n) with at most `threads` calls at once; NULL: the relighter's own thread pool. */
    void (*parallel_for)(void *user, int n, void (*fn)(void *ctx, int i), void *ctx);
    void *parallel_user;
    void (*log)(void *user, int level, const char *msg); /* NULL: wrt_log (common/) */
    void *log_user;
    /* Progress of wrt_relight_create (include/wrt.h, wrt_runtime_options.progress): called
     * on the creating thread with the fraction done, never decreasing, after every piece of
     * a few milliseconds of the long stages (BRDF tables, the final gather's rays) and last
     * with 1; returning 0 cancels the creation (WRT_ERR_CANCELLED, everything freed). */
    int (*progress)(void *user, double fraction);
    void *progress_user;
    /* > 0: a light change whose E moves by less than this fraction of the E last
     * multiplied (relative L2 norm over every function and channel) costs no multiply and
     * no synthesis: X stays; the changes add up until one passes it (Enlighten's rule;
     * issue 23). In [0, 1); 0 (the default): every change is applied. */
    double skip_below;
    /* > 0: the time budget of an update in milliseconds (issue 23, "as engines expect"):
     * an update does its work in units (one light's projection, the multiply, a slice of
     * the quads to synthesize, a slice of the groups to smooth, the final gather) and
     * starts a unit only while the budget lasts, except the first unit of every call, so
     * each call makes progress and overruns the budget by at most one unit. What is left
     * waits for the next update (timings.pending); an update that finds nothing new
     * carries on with it. The textures reach exactly (bit for bit) what one unbudgeted
     * update gives. Finite, >= 0; 0 (the default): no budget. */
    double budget_ms;
} wrt_relight_options;

typedef struct wrt_relight_timings { /* milliseconds of the last update */
    double projection, multiply, brdf, synthesis;
    double reconstruction;  /* of synthesis: the smooth display of the changed quads' groups */
    int quads_resynthesized;
    int lights_changed;
    int skipped;            /* 1: the light change was below skip_below: X kept */
    int pending;            /* 1: budget_ms ran out: work is left for the next update */
} wrt_relight_timings;

/* Work done since creation, counted in units of an update (for tests and --bench): a
 * light change below skip_below adds to skips and to nothing after the projection. */
typedef struct wrt_relight_counters {
    long long updates, projections, multiplies, skips, quads_synthesized, groups_smoothed, gathers;
    long long entries_streamed; /* the operator's entries the multiplies read (lit columns only) */
    long long occluders;        /* the projections' possible occluders, summed over quads */
} wrt_relight_counters;
void wrt_relight_get_counters(const wrt_relight *r, wrt_relight_counters *out);

/* Changes options.budget_ms and options.skip_below (same ranges) between updates; work
 * left pending stays pending. Errors: WRT_ERR_INVALID_ARG (naming the value),
 * WRT_ERR_NOMEM (skip_below's copy of E; the options are then as before). */
wrt_status wrt_relight_set_budget(wrt_relight *r, double budget_ms, double skip_below);

/* `g` must outlive the relighter (it points into the mapping). Errors: WRT_ERR_INVALID_ARG,
 * WRT_ERR_NOMEM, WRT_ERR_CANCELLED (options.progress returned 0). */
wrt_status wrt_relight_create(const wrt_gto *g, const wrt_relight_options *opt, wrt_relight **out);
void wrt_relight_destroy(wrt_relight *r); /* NULL is a no-op */

/* Sets the lights (copied). scales[i] multiplies light i (0 switches it off); scales may
 * be NULL (all 1). Only lights that changed are re-projected at the next update. More
 * lights than ever before allocate each new one's arrays (about 16 bytes a function).
 * Errors: WRT_ERR_NOMEM (the lights are then as before). */
wrt_status wrt_relight_set_lights(wrt_relight *r, const wrt_light *lights, const float *scales, int n);
/* Emissive surfaces (docs/emitters.md): every material with emission is a source, on at
 * scale 1 after creation; its light on other surfaces is in X (linear in the scale).
 * wrt_relight_emitter_count: emissive materials used by some quad. set_emitter_scale:
 * material's scale (>= 0, finite; 0 switches it off; a material without emission takes
 * it and nothing changes). Errors: WRT_ERR_INVALID_ARG. */
int wrt_relight_emitter_count(const wrt_relight *r);
wrt_status wrt_relight_set_emitter_scale(wrt_relight *r, int material, float scale);
float wrt_relight_emitter_scale(const wrt_relight *r, int material);

/* Sets the eye position; only glossy quads depend on it. */
void wrt_relight_set_eye(wrt_relight *r, const double eye[3]);

/* Recomputes what changed since the last call. Returns the number of quads whose
 * texture changed (0: nothing to upload), or -1 if memory ran out (wrt_last_error says
 * where; the textures may then be partly updated, and the next update redoes them all).
 * `t` may be NULL. Allocates nothing: the scratch is made by wrt_relight_create and a
 * light's by wrt_relight_set_lights when the count grows (test_relight checks it). */
int wrt_relight_update(wrt_relight *r, wrt_relight_timings *t);

/* Quad q's texture of outgoing indirect radiance (linear RGB floats, res x res texels,
 * texel (i, j) covers u in [i/res, (i+1)/res), v in [j/res, (j+1)/res), stored row j
 * after row j-1). Valid until the next update. Unless options.haar_blocks, it is the
 * smooth reconstruction of common/reconstruct.h, meant to be sampled bilinearly and
 * clamped to the quad's texels: texels on an edge shared with a coplanar neighbour hold
 * the value on the edge, the same on both sides. */
int wrt_relight_tex_res(const wrt_relight *r, int q);
const float *wrt_relight_tex(const wrt_relight *r, int q);

/* Mean incident irradiance over quad q (RGB), direct (from the projection) and indirect
 * (from X), for --stats-json and the tests. */
void wrt_relight_quad_irradiance(const wrt_relight *r, int q, double direct[3], double indirect[3]);

/* The coefficient vectors themselves (length g->nfuncs, RGB interleaved), for tests.
 * With the final gather (the default when a quad is glossy) the rows of X that are a
 * glossy quad's non-root angular functions are not computed (0): nothing displays them.
 * With the first-bounce operator K, E's non-root angular functions on a quad that has K
 * columns are not projected (0): the multiply reads E' instead (wrt_relight_Y). */
const float *wrt_relight_E(const wrt_relight *r);
const float *wrt_relight_X(const wrt_relight *r);

/* ---- Additions beyond the fixed interface (tests, --bench) ----
 * Notes on the calls above: glossy (non-Lambertian) quads are synthesized only once
 * wrt_relight_set_eye has been called; wrt_relight_X and wrt_relight_E keep their
 * address for the relighter's lifetime; the first update after create projects every
 * light (create itself tabulates the BRDF of each glossy material: ~0.2 s each on 2 cores). */

/* Index of the angular Haar function (node level 0..3, node x, y, type 0..3) in the
 * angular tables: 0 for the root scaling function, then level by level, node by node,
 * three wavelets each (256 in all). */
int wrt_relight_angular_index(int level, int x, int y, int type);

/* BRDF weight of material m for angular function `ang` and an outgoing direction given
 * by its concentric coordinates (a_o, b_o) in the quad's frame:
 * beta_g(w_o) = pi * integral over [0,1]^2 of f_r(M(a,b), w_o) g(a,b) da db, from the
 * shared table of common/brdf_table.h (bilinear). Returns 0 (out = 0) if m has no table (Lambertian or unused
 * by any quad). For g = the root, beta is the directional albedo. */
int wrt_relight_beta(const wrt_relight *r, int m, double a_o, double b_o, int ang, double out[3]);

/* The first glossy bounce Y = K c (length g->nfuncs, RGB interleaved) of the last update,
 * when the file holds the first-bounce operator K (g->nkcols > 0; X = Op E' + Y, E' = E
 * off the quads with K columns + Y); NULL without K. For tests. */
const float *wrt_relight_Y(const wrt_relight *r);

/* Micro-benchmark: moves light 0 around a small circle (2% of the scene diagonal) for
 * `updates` updates, restores it, and returns the mean milliseconds per update (mean
 * timings in *mean if not NULL); -1 if no light is set (or no memory). */
double wrt_relight_bench(wrt_relight *r, int updates, wrt_relight_timings *mean);

#endif
