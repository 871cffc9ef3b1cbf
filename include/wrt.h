/* wrt.h: the wrt runtime library (libwrt): relights a scene baked by wrt-bake (a .gto
 * file) for moving point and spot lights, without any window or GPU. Each update
 * projects the direct light onto the scene's wavelet basis, applies the baked indirect
 * transport operator and turns the result into one texture of outgoing indirect
 * radiance per quad (linear RGB floats); draw your direct light as you like and add it.
 *
 * Example (tests/install.sh extracts the lines between the markers and compiles them
 * against the installed header and libwrt.a, so it stays true):
 *
 * WRT_EXAMPLE_BEGIN
 *   #include <stdio.h>
 *   #include <wrt.h>
 *   int main(int argc, char **argv) {
 *       wrt_runtime *rt;
 *       wrt_error err;
 *       if (argc < 2 || wrt_runtime_open_file(argv[1], NULL, &rt, &err)) {
 *           fprintf(stderr, "%s\n", argc < 2 ? "usage: app FILE.gto" : err.message);
 *           return 1;
 *       }
 *       wrt_runtime_light l = {0};              // zero: a white point light at the origin, on
 *       if (wrt_runtime_light_count(rt) > 0)
 *           wrt_runtime_get_light(rt, 0, &l, &err); // the file's first light (name, range too)
 *       l.position[1] -= 0.2;
 *       double eye[3] = {0, 1, 3};
 *       if (wrt_runtime_set_lights(rt, &l, 1, &err) || wrt_runtime_set_eye(rt, eye, &err) ||
 *           wrt_runtime_update(rt, NULL, &err)) {    // glossy quads need the eye
 *           fprintf(stderr, "%s\n", err.message);
 *           wrt_runtime_close(rt);
 *           return 1;
 *       }
 *       for (int q = 0; q < wrt_runtime_quad_count(rt); q++) {
 *           int res;
 *           const float *tex = wrt_runtime_quad_texture(rt, q, &res); // res x res x RGB
 *           wrt_runtime_quad src;                    // where it came from in the glTF
 *           wrt_runtime_get_quad(rt, q, &src, NULL);
 *           printf("quad %d: mesh %d, %d x %d texels, first %g\n", q, src.mesh, res, res, tex[0]);
 *       }
 *       return wrt_runtime_close(rt) == WRT_OK ? 0 : 1;
 *   }
 * WRT_EXAMPLE_END
 *
 * Build: cc app.c $(pkg-config --cflags --libs wrt), or with `pkg-config --static` for
 * libwrt.a (then libwrt.so is not needed at run time; wrt.pc puts libwrt.a first and
 * links libwrt.so --as-needed, so that the archive takes every reference).
 *
 * Rules. Every call that can fail returns a wrt_status (WRT_OK = 0) and, if `err` is not
 * NULL, fills it with the status and a message naming what failed; nothing aborts or
 * exits, out of memory included (an update that runs out returns WRT_ERR_NOMEM; the
 * textures may then be partly updated, and the next update redoes them all). Option
 * structs are zero-initialised for the defaults (wrt_runtime_defaults shows them); their
 * first field, `size`, lets them grow without breaking callers built against an older
 * header. Results do not depend on the thread count or on a job hook. Only the functions
 * declared here (WRT_API) are exported by libwrt.so, and libwrt.a holds one object whose
 * only global symbols are these: nothing else of wrt can clash with your symbols.
 *
 * Handles. A runtime handle carries a magic number, set at open and cleared at close.
 * Every call checks it: a NULL handle, a handle that is not a runtime and a handle used
 * after wrt_runtime_close (close included: a double close) give WRT_ERR_INVALID_ARG ("not
 * a live runtime") instead of a crash, the count getters -1, wrt_runtime_quad_texture
 * NULL. After close the handle's memory goes back to your allocator: the check is sure as
 * long as that memory has not been handed out again (keep it, as a debugging allocator
 * does, to make it sure always). A NULL out-pointer gives WRT_ERR_INVALID_ARG.
 *
 * Bounds. What the computation carries, checked where values enter (WRT_ERR_INVALID_ARG
 * naming the value): positions (lights, eye) and light ranges finite, each coordinate
 * within +-WRT_MAX_COORD metres; a light's intensity finite, >= 0, and intensity x its
 * largest colour channel at most WRT_MAX_INTENSITY candela (so radiance stays far inside
 * float range even a micrometre from a surface); colour channels finite and >= 0.
 *
 * Threads. The runtime keeps its state in its handle: any number of runtimes may live
 * in one process and each gives exactly what it gives alone. One runtime is used by one
 * thread at a time (its calls are not synchronised); different runtimes from different
 * threads at once are fine. Process-wide state the library touches, all of it safe from
 * any thread: (1) a thread-local buffer with the calling thread's last error message
 * (copied into your wrt_error before a call returns, so only `err` matters to you);
 * (2) when wrt_runtime_options.log is NULL, warnings go to wrt's process-wide log
 * (stderr: "wrt: warning: ..."), whose sink the library only reads; set `log` to
 * receive them per runtime instead. Your allocator and job hook are called from the
 * update's worker threads (or your hook's threads) at once, so they must be thread-safe.
 * Without a job hook each runtime keeps its own pool of `threads` - 1 worker threads,
 * parked between updates; with one it starts no thread of its own. Embree (the ray
 * tracer used for shadow rays) builds its scene at open on threads of its own. Opening
 * a file with glossy materials traces the final gather's rays and tabulates their BRDFs
 * at open: seconds for a large glossy scene (about 10 s for the glossy asset on 2 cores);
 * wrt_runtime_options.progress (API 3) reports that work and can cancel it.
 *
 * Quads. A quad's texture covers its parameter square: texel (i, j) of res x res covers
 * u in [i/res, (i+1)/res), v in [j/res, (j+1)/res), row j after row j-1, where the point
 * at (u, v) is (1-u)(1-v) p0 + u(1-v) p1 + u v p2 + (1-u) v p3 for the quad's corners
 * p0..p3 (wrt_runtime_get_quad). Units: radiance in the lights' units (candela for
 * intensity, metres for positions: W/(m^2 sr) for a light of 1 W/sr). */
#ifndef WRT_H
#define WRT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* What libwrt exports: every function declared with it, nothing else (the library is
 * built with -fvisibility=hidden; tests/exports.sh checks `nm -D` against this header). */
#if defined(__GNUC__) || defined(__clang__)
#define WRT_API __attribute__((visibility("default")))
#else
#define WRT_API
#endif

/* The library's version (the tools' --version and the .gto provenance print the same
 * string), and the version of this header's API: 2 since the options' `size`, the
 * user-first allocator and the status-returning accessors; 3 since wrt_runtime_quad's
 * kind, part and (u, v) fields (it grew: rebuild callers), the atlas helper, and the
 * options' linear_display and progress; 4 since wrt_runtime_open_path (a private copy of
 * the file) and wrt_runtime_get_file_info; 5 since wrt_runtime_set_budget and
 * wrt_runtime_get_update_stats (functions only added: API 3 callers still work). Compare the macros with
 * wrt_version() and wrt_api_version() at run time to catch a program built against
 * another header than the library it runs with. */
#define WRT_VERSION_MAJOR 0
#define WRT_VERSION_MINOR 1
#define WRT_VERSION_PATCH 0
#define WRT_VERSION_STRING "0.1.0"
#define WRT_VERSION (WRT_VERSION_MAJOR * 10000 + WRT_VERSION_MINOR * 100 + WRT_VERSION_PATCH)
#define WRT_API_VERSION 5

/* What every fallible call returns (shared by all of wrt's tools and libraries). */
typedef enum wrt_status {
    WRT_OK = 0,
    WRT_ERR_IO,          /* could not open, read or write a file */
    WRT_ERR_NOT_OURS,    /* not our kind of file (foreign magic) */
    WRT_ERR_CORRUPT,     /* our kind of file, but broken: truncated, bad offsets, checksum */
    WRT_ERR_UNSUPPORTED, /* valid, but a version or feature we do not support */
    WRT_ERR_PARSE,       /* malformed input (glTF JSON, buffers, accessors) */
    WRT_ERR_GEOMETRY,    /* geometry we refuse: unpaired triangles, non-planar/degenerate quads, NaN */
    WRT_ERR_INVALID_ARG, /* absurd option or argument, NULL out-pointer, dead handle */
    WRT_ERR_NOMEM,
    WRT_ERR_CANCELLED,   /* a progress callback asked to stop */
    WRT_ERR_ACCURACY,    /* a required accuracy was not met */
    WRT_ERR_GL,          /* OpenGL / EGL / window system failure */
    WRT_STATUS_COUNT
} wrt_status;

/* Short constant text for a status ("ok", "i/o error", ...). Thread-safe. */
WRT_API const char *wrt_status_str(wrt_status s);

/* The library's WRT_VERSION, WRT_VERSION_STRING and WRT_API_VERSION as it was built
 * (constant; thread-safe). */
WRT_API int wrt_version(void);
WRT_API const char *wrt_version_string(void);
WRT_API int wrt_api_version(void);

/* What went wrong, filled by a failing call (when not NULL). */
typedef struct wrt_error {
    wrt_status status;
    char message[256];
} wrt_error;

/* Memory. alloc(user, size) returns memory aligned for any type, or NULL (the call then
 * fails with WRT_ERR_NOMEM); free(user, p) releases it (p may be NULL). Both NULL: malloc
 * and free; one of them NULL: refused (WRT_ERR_INVALID_ARG). Used for the runtime's
 * handle, every array it keeps (operator indexing, textures, coefficient vectors, BRDF
 * tables, lights) and the scratch its workers grow during an update (called from those
 * threads at once: must be thread-safe). Embree's scene and the thread pool's control
 * block keep their own (malloc). The user pointer comes first in every callback of this
 * header (allocator, job hook, log). */
typedef struct wrt_allocator {
    void *(*alloc)(void *user, size_t size);
    void (*free)(void *user, void *p);
    void *user;
} wrt_allocator;

typedef struct wrt_runtime_options {
    /* sizeof(wrt_runtime_options) as the caller's header has it, so that the struct can
     * grow: fields beyond `size` bytes are taken as zero (their default). 0 means the
     * layout of API version 2, the first with `size` (the fields up to no_avx): the
     * fields added since (API 3: linear_display, progress, progress_user) are read only
     * when `size` covers them, so set size = sizeof(wrt_runtime_options) to use them. A
     * size smaller than the version-2 layout, or larger than the library knows, is
     * refused (WRT_ERR_INVALID_ARG, naming both sizes). */
    size_t size;
    int threads;        /* worker threads of an update: 0 = all cores, 1 = the caller's thread only, at most 64 (negative: refused) */
    int max_tex_res;    /* cap on a quad's texture side in texels, a power of two up to 1024: 0 = 64 */
    int proj_level;     /* spatial level of the direct light's projection: 0 = chosen per quad */
    wrt_allocator allocator;
    int haar_blocks;    /* 1: textures show the bake's Haar cells as blocks, without the smooth
                         * reconstruction (for before/after comparisons); 0 = smooth */
    /* Job hook (optional): your scheduler instead of the runtime's thread pool. It must
     * call fn(ctx, i) once for every i in [0, n), on threads of its choosing, at most
     * `threads` (0: the online cores) of them at once, and return when all are done;
     * the calling thread may take part. The runtime calls it from its own calls (open,
     * update) for each parallel loop of 2 items or more: quads to project or synthesize,
     * chunks of the multiply, groups of quads to smooth, BRDF table rows. Calls of fn
     * beyond `threads` at once wait for a free slot. NULL: the runtime's pool. */
    void (*parallel_for)(void *user, int n, void (*fn)(void *ctx, int i), void *ctx);
    void *parallel_user;
    /* Log (optional): the runtime's warnings (level 0 error, 1 warning, 2 info), e.g.
     * function keys the file holds that it ignores, Embree's errors (these possibly from
     * worker threads: thread-safe). NULL: wrt's process-wide log (stderr). */
    void (*log)(void *user, int level, const char *message);
    void *log_user;
    /* The glossy display's before/after switches (0: the default display). Every knob
     * that changes a result is a field here; the library reads no environment variable. */
    int no_final_gather; /* 1: glossy quads show the coarse angular synthesis only, no final gather */
    int no_light_splat;  /* 1: a light's direction on a glossy quad truncated to its finest
                          * angular cell instead of spread over one cell centred on it */
    int gather_points;   /* 0: the default (a point per texel on a sharp lobe, else 16); 16 or 32:
                          * final-gather points a side on every glossy quad; others refused */
    int no_avx;          /* 1: the first-bounce rows summed without AVX (same sums; A/B timings) */
    /* Superposition. 1: the linear display: the smooth reconstruction is one fixed linear
     * operator per quad group (no slope limiter, the bake's finer averages kept or
     * predicted by a choice made from the file alone, negative undershoots kept, not
     * clamped), so the textures of two lights set together equal the sum of each
     * light's alone to float rounding (measured: 1.2e-6 of the peak texel at most on the
     * Cornell box, quality 5), and an engine may keep a texture per light and add them. A texel may then be
     * slightly negative beside a shadow edge: clamp the sum, not the terms. 0 (the
     * default): the display limits its slopes and keeps sharp details depending on the
     * values, and clamps at 0: the textures do NOT superpose (two lights together differ
     * from the sum of each alone by up to 3.4% of the peak texel on the Cornell box, and
     * by far more of a single texel's own value). Either way wrt_runtime_quad_mean, wrt_runtime_quad_cells and
     * wrt_runtime_quad_irradiance superpose (to float rounding), and so do the textures
     * with haar_blocks. Image error against the path tracer: README, "Accuracy and cost". */
    int linear_display;
    /* Progress of the open (optional): wrt_runtime_open_file and _memory call
     * progress(progress_user, fraction) on the calling thread with the fraction of the
     * open done, never decreasing, at least every 100 ms or so of its work (the BRDF
     * tables and the final gather's rays of a glossy file, in pieces of a few
     * milliseconds) and last with exactly 1. Returning 0 cancels: the open frees
     * everything it made and returns WRT_ERR_CANCELLED (*out NULL). A file without
     * glossy quads opens in milliseconds and gets one call, with 1. NULL: no calls. */
    int (*progress)(void *user, double fraction);
    void *progress_user;
} wrt_runtime_options;

/* Fills the zero fields of *o with the defaults (o->size as above; a size 0 stays 0).
 * Errors: WRT_ERR_INVALID_ARG (o NULL, or its size refused). */
WRT_API wrt_status wrt_runtime_defaults(wrt_runtime_options *o);

typedef struct wrt_runtime wrt_runtime;

/* Opens and validates a .gto file (mapped read-only; every section's bounds and
 * checksums are checked). `opt` may be NULL (the defaults). On failure *out is NULL.
 * Errors: WRT_ERR_IO, WRT_ERR_NOT_OURS, WRT_ERR_CORRUPT, WRT_ERR_UNSUPPORTED,
 * WRT_ERR_INVALID_ARG (options, NULL path or out), WRT_ERR_NOMEM, WRT_ERR_CANCELLED
 * (options.progress returned 0: everything the open made is freed). */
WRT_API wrt_status wrt_runtime_open_file(const char *path, const wrt_runtime_options *opt, wrt_runtime **out,
                                         wrt_error *err);
/* The same for a file image the caller holds (mapped or read): `data` must be 8-byte
 * aligned and stay valid and unchanged until wrt_runtime_close. */
WRT_API wrt_status wrt_runtime_open_memory(const void *data, size_t size, const wrt_runtime_options *opt,
                                           wrt_runtime **out, wrt_error *err);
/* Releases everything (and unmaps a file it opened). NULL: a no-op (WRT_OK). A handle
 * already closed, or not a runtime: WRT_ERR_INVALID_ARG, nothing released. */
WRT_API wrt_status wrt_runtime_close(wrt_runtime *rt);

enum { WRT_LIGHT_KIND_POINT = 0, WRT_LIGHT_KIND_SPOT = 1, WRT_LIGHT_KIND_DIRECTIONAL = 2 };
#define WRT_MAX_LIGHTS 64
#define WRT_MAX_COORD 1e9      /* metres: bound on each coordinate of a light or the eye */
#define WRT_MAX_INTENSITY 1e20 /* candela: bound on intensity x the largest colour channel */

/* A light (KHR_lights_punctual's model). Zero-initialised: a white point light of
 * intensity 0 at the origin, unbounded, on. */
typedef struct wrt_runtime_light {
    int kind;               /* WRT_LIGHT_KIND_POINT, _SPOT or _DIRECTIONAL (a sun) */
    double position[3];     /* ignored for a directional light */
    double direction[3];    /* spot axis, or the way a sun's light travels (need not be unit
                             * length; ignored for a point light) */
    float color[3];         /* linear RGB; all zero means white */
    float intensity;        /* candela; lux for a directional light (irradiance facing it) */
    float inner_cone;       /* spot: radians from the axis at full intensity (0..outer) */
    float outer_cone;       /* spot: radians from the axis where it reaches 0 (0 = pi/4) */
    int off;                /* 1: switched off (contributes nothing) */
    float range;            /* metres: glTF's range, beyond which the light gives nothing (its
                             * falloff windowed by (1 - (d/range)^4)^2, KHR_lights_punctual's
                             * recommendation); 0 = unbounded */
    char name[64];          /* the glTF light's name from wrt_runtime_get_light ("" if none);
                             * ignored by wrt_runtime_set_lights */
} wrt_runtime_light;

/* The lights stored in the file (as baked from the glTF scene): count (-1: not a live
 * handle) and each one, name and range included, ready for wrt_runtime_set_lights.
 * Errors: WRT_ERR_INVALID_ARG (handle, index, out NULL). */
WRT_API int wrt_runtime_light_count(const wrt_runtime *rt);
WRT_API wrt_status wrt_runtime_get_light(const wrt_runtime *rt, int index, wrt_runtime_light *out, wrt_error *err);

/* Sets the lights (copied; n in 0..WRT_MAX_LIGHTS). Only lights that changed are
 * re-projected at the next update. Errors: WRT_ERR_INVALID_ARG (kind, non-finite or
 * negative values, values past the bounds above, a spot's axis or cones, too many),
 * WRT_ERR_NOMEM; the lights are then as before. */
WRT_API wrt_status wrt_runtime_set_lights(wrt_runtime *rt, const wrt_runtime_light *lights, int n, wrt_error *err);
/* Sets the eye (world position); only glossy quads depend on it, and they stay black
 * until it is set. Errors: WRT_ERR_INVALID_ARG (NULL, non-finite, past WRT_MAX_COORD). */
WRT_API wrt_status wrt_runtime_set_eye(wrt_runtime *rt, const double eye[3], wrt_error *err);

/* Recomputes what changed since the last update. *changed (if not NULL) receives the
 * number of quads whose texture changed (0: nothing to upload). Errors:
 * WRT_ERR_INVALID_ARG (handle), WRT_ERR_NOMEM (then *changed is 0, and the next
 * successful update redoes every texture). */
WRT_API wrt_status wrt_runtime_update(wrt_runtime *rt, int *changed, wrt_error *err);

/* ---- A time budget and small changes skipped (API 5; docs/runtime.md) ----
 * budget_ms > 0: each wrt_runtime_update works within about that many milliseconds and
 * leaves the rest for the next update (stats.pending); call update every frame, even when
 * nothing changed, until pending is 0. Work goes in units (one light's projection, the
 * multiply, a slice of the quads' textures, a slice of the smoothed groups, the glossy
 * gather), a unit starts only while time is left, and every call does at least one, so a
 * call overruns by at most one unit (the multiply is the largest: a few milliseconds on a
 * large scene). The textures between show the last finished stage; once pending is 0
 * they are bit for bit what one update without a budget gives. 0 (the default): none.
 * skip_below in [0, 1): a light change whose projected direct light moves by less than
 * that fraction of the light last applied (relative L2 norm) costs no multiply, no
 * texture and no gather (its projection is paid: it is how the change is measured); the
 * changes add up until one passes. 0 (the default): every change is applied.
 * Errors: WRT_ERR_INVALID_ARG (handle; a value out of range, named), WRT_ERR_NOMEM
 * (skip_below's copy of the light, 12 bytes a function; the settings are then as before). */
WRT_API wrt_status wrt_runtime_set_budget(wrt_runtime *rt, double budget_ms, double skip_below, wrt_error *err);

/* What the updates did: the last update's state and counts since the open. */
typedef struct wrt_runtime_update_stats {
    int pending;                  /* 1: the last update ran out of budget: work is left */
    int skipped;                  /* 1: the last update's light change was below skip_below */
    double ms[5];                 /* the last update: projection, multiply, brdf, synthesis, smoothing */
    long long updates;            /* wrt_runtime_update calls */
    long long projections;        /* lights projected */
    long long multiplies;         /* X = Op E */
    long long skips;              /* light changes below skip_below */
    long long quads_synthesized;  /* quads' wavelet textures synthesized */
    long long groups_smoothed;    /* groups of quads through the smooth display */
    long long gathers;            /* glossy final gathers */
    long long entries_streamed;   /* operator entries the multiplies read (the lit columns' only) */
} wrt_runtime_update_stats;
/* Errors: WRT_ERR_INVALID_ARG (handle, out NULL). */
WRT_API wrt_status wrt_runtime_get_update_stats(const wrt_runtime *rt, wrt_runtime_update_stats *out, wrt_error *err);

/* ---- Emissive surfaces (docs/emitters.md) ----
 * Every material with emission (glTF emissiveFactor x KHR_materials_emissive_strength)
 * is a source: its light on the other surfaces (direct and bounced) is in the quads'
 * textures and cells, linear in its scale; the emitter's own radiance (what the camera
 * sees on it) is the material's `emissive` times the scale, for the caller to draw.
 * Each starts at scale 1. Count: emissive materials used by some quad (-1: not a live
 * handle). Scale: material index, >= 0 and finite (0 switches it off), the scale times
 * the material's largest emissive channel at most WRT_MAX_INTENSITY; the next
 * wrt_runtime_update applies it. Errors: WRT_ERR_INVALID_ARG. */
WRT_API int wrt_runtime_emitter_count(const wrt_runtime *rt);
WRT_API wrt_status wrt_runtime_set_emitter_scale(wrt_runtime *rt, int material, float scale, wrt_error *err);

/* ---- The scene, for drawing it from the library alone ---- */

/* A material (glTF metallic-roughness, as the bake used it). */
typedef struct wrt_runtime_material {
    char name[64];
    float base_color[3];    /* linear RGB: baseColorFactor x the mean of baseColorTexture */
    float metallic, roughness;
    float emissive[3];      /* emitted radiance L_e (a source: see "Emissive surfaces") */
    int lambertian;         /* 1: pure diffuse (roughness 1, metallic 0): albedo base_color */
} wrt_runtime_material;
/* Count (-1: not a live handle) and each material. Errors: WRT_ERR_INVALID_ARG. */
WRT_API int wrt_runtime_material_count(const wrt_runtime *rt);
WRT_API wrt_status wrt_runtime_get_material(const wrt_runtime *rt, int index, wrt_runtime_material *out,
                                            wrt_error *err);

/* The glTF camera the bake read (from_file 0: the scene had none; the other fields are
 * then zero and the caller frames the scene itself, e.g. from wrt_runtime_get_bounds). */
typedef struct wrt_runtime_camera {
    int from_file;
    double position[3], direction[3], up[3]; /* direction: unit view direction; up: unit */
    double yfov;            /* radians */
    double aspect;          /* 0: from the viewport */
    double znear, zfar;     /* zfar 0: infinite */
} wrt_runtime_camera;
WRT_API wrt_status wrt_runtime_get_camera(const wrt_runtime *rt, wrt_runtime_camera *out, wrt_error *err);

/* The axis-aligned box of every quad's corners (world space, metres). Errors:
 * WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_get_bounds(const wrt_runtime *rt, double lo[3], double hi[3], wrt_error *err);

/* A quad and where it came from in the glTF scene the bake read: the quad-to-source map,
 * so that an engine can put the results on its own meshes. The bake makes each quad
 * either from two triangles of one primitive that share an edge (kind
 * WRT_QUAD_KIND_PAIR: its corners are those triangles' four vertices) or from one
 * triangle cut in three through its centroid and edge midpoints (WRT_QUAD_KIND_TRIANGLE,
 * part k = 0..2: corners V_k, (V_k + V_k+1)/2, the centroid, (V_k+2 + V_k)/2, with
 * V_0..V_2 the triangle's vertices in its front-face winding). A twin is the back of a
 * quad whose material is doubleSided, set back by 1e-4 of the scene's diagonal and
 * facing the other way: same node, mesh, primitive and triangles as its front, corners
 * p0 p3 p2 p1 of the front's (moved back), so its texture is the front's mirrored in u
 * and v swapped. Files written before .gto version 1.2 (and those written without the
 * map) store only the mesh: the other source fields are then -1 ("not stored in this
 * file"), never a guess. */
enum { WRT_QUAD_KIND_PAIR = 0, WRT_QUAD_KIND_TRIANGLE = 1 };
typedef struct wrt_runtime_quad {
    double corners[4][3];   /* p0..p3, world space (see "Quads" above) */
    double normal[3];       /* unit: normalize((p1-p0) x (p3-p0)), glTF's front side */
    double area;            /* m^2 */
    int material;           /* index for wrt_runtime_get_material */
    int parallelogram;      /* 1: affine in (u, v) */
    int node;               /* glTF node that placed the mesh; -1: not stored */
    int mesh;               /* glTF mesh index; -1: none */
    char mesh_name[64];     /* that mesh's name ("" if none) */
    int primitive;          /* index within the mesh's primitives; -1: not stored */
    int triangles[2];       /* the primitive's triangles (t: indices 3t, 3t+1, 3t+2 of its index
                             * list, or of its vertices if it has none): a pair's two; a triangle
                             * kind's one and -1; -1 -1: not stored */
    int twin;               /* 1: the back twin of quad twin_of, 0: not a twin, -1: not stored */
    int twin_of;            /* the front quad of a twin (a lower index), else -1 */
    /* Since API version 3. */
    int kind;               /* WRT_QUAD_KIND_PAIR or _TRIANGLE; -1: not stored */
    int part;               /* WRT_QUAD_KIND_TRIANGLE: which third (0..2); else 0 (-1: not stored) */
    int has_uv;             /* 1: uv holds the primitive's TEXCOORD_0; 0: the primitive has none
                             * (or the file does not store it) */
    float uv[4][2];         /* TEXCOORD_0 at corners p0..p3 (glTF's convention: v down the image).
                             * A pair's corners are vertices, so their TEXCOORD_0 as stored (where
                             * the two triangles' vertices differ across a UV seam, the first
                             * triangle's); a triangle's midpoints and centroid interpolate its
                             * vertices' linearly. The point (u, v) of the quad has the TEXCOORD
                             * (1-u)(1-v) uv0 + u(1-v) uv1 + u v uv2 + (1-u) v uv3: exactly glTF's
                             * where both are affine (a parallelogram mapped to a parallelogram),
                             * else close to glTF's per-triangle interpolation. 0 when !has_uv. */
} wrt_runtime_quad;

/* The scene's quads: count (-1: not a live handle) and each one. Errors:
 * WRT_ERR_INVALID_ARG (handle, index, out NULL). */
WRT_API int wrt_runtime_quad_count(const wrt_runtime *rt);
WRT_API wrt_status wrt_runtime_get_quad(const wrt_runtime *rt, int q, wrt_runtime_quad *out, wrt_error *err);
/* Just the corners (p[4][3], world space). Errors: WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_quad_corners(const wrt_runtime *rt, int q, double p[4][3], wrt_error *err);

/* ---- Results, after an update ---- */

/* Quad q's texture of outgoing indirect radiance (res x res x RGB, see "Quads" above;
 * valid until the next update or close). NULL and *res 0 for a bad handle or index. */
WRT_API const float *wrt_runtime_quad_texture(const wrt_runtime *rt, int q, int *res);
/* Its mean over the quad (area-weighted, RGB). Errors: WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_quad_mean(const wrt_runtime *rt, int q, float rgb[3], wrt_error *err);

/* Cell averages of quad q's incident indirect irradiance (W/m^2 per W/sr of the lights)
 * on an n x n grid of (u, v) cells, exact for the Haar reconstruction: out[(j n + i) 3 + c]
 * for cell (i, j). n in 1..1024. Errors: WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_quad_cells(const wrt_runtime *rt, int q, int n, double *out, wrt_error *err);

/* Mean incident irradiance over quad q (RGB), direct (from the light's projection) and
 * indirect, for the current lights. Errors: WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_quad_irradiance(const wrt_runtime *rt, int q, double direct[3], double indirect[3],
                                               wrt_error *err);

/* ---- A lightmap atlas: every quad's texture in one texture, ready to upload ---- */

/* Where quad q's texture lies in the atlas: its res x res texels at columns [x, x+res)
 * and rows [y, y+res), texel (i, j) of the quad's texture at column x+i, row y+j (so u
 * runs along a row and v down the rows); around them a border of 1 texel that repeats
 * the edge texels (corners included), so bilinear filtering up to half a texel outside
 * the quad's square reads its own edge, never a neighbour. A point (u, v) of the quad
 * samples the atlas at ((x + u res) / width, (y + v res) / height). */
typedef struct wrt_atlas_rect {
    int x, y;   /* the first texel of the quad's own res x res block */
    int res;    /* the quad's texture side (fixed from open to close) */
} wrt_atlas_rect;

/* Packs the quads' tiles ((res + 2) squares with their borders) into rows of `width`
 * texels: largest first, then by quad index, left to right, a new row when one is full.
 * Deterministic: the same file and options give the same layout. width 0: the smallest
 * power of two that holds the widest tile and is at least the square root of the tiles'
 * total area. rects: wrt_runtime_quad_count(rt) entries (yours). *width_out and
 * *height_out (may be NULL) receive the atlas's size; texels no tile covers are 0 after
 * a fill. No allocation. Errors: WRT_ERR_INVALID_ARG (handle, NULL rects, width
 * negative or narrower than the widest tile (res + 2), an atlas past 2^31 texels). */
WRT_API wrt_status wrt_runtime_atlas_layout(const wrt_runtime *rt, int width, wrt_atlas_rect *rects, int *width_out,
                                            int *height_out, wrt_error *err);
/* Writes the textures of the last update into `rgb` (width x height RGB floats, rows of
 * `width`, row 0 first; `nfloats` >= width * height * 3) by a layout of
 * wrt_runtime_atlas_layout for this runtime: each quad's block, its border, and 0 where
 * no tile lies. Allocates nothing, reads only the runtime (no update between layout and
 * fill is needed: the sizes do not change). Linear in the textures: the atlas of two
 * lights is the sum of each's exactly when the textures are (see wrt_runtime_quad_texture).
 * Errors: WRT_ERR_INVALID_ARG (handle, NULL pointers, nfloats too small, a rect that is
 * not the quad's size or does not fit with its border). */
WRT_API wrt_status wrt_runtime_atlas_fill(const wrt_runtime *rt, const wrt_atlas_rect *rects, int width, int height,
                                          float *rgb, size_t nfloats, wrt_error *err);

/* Milliseconds of the last update's stages (projection, multiply, brdf, synthesis).
 * Errors: WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_timings(const wrt_runtime *rt, double ms[4], wrt_error *err);

/* ---- Opening for an application that keeps a file open (API 4) ---- */

/* How wrt_runtime_open_path holds the file. WRT_OPEN_MAP: mapped read-only, as
 * wrt_runtime_open_file does (the file must then not change while it is open: a new bake
 * renamed over it is fine, a write into it or a truncate is not). WRT_OPEN_PRIVATE: read
 * whole into memory from the options' allocator, so that the file may be rewritten,
 * truncated or removed while the runtime lives (what a viewer that reloads after a new
 * bake needs); it costs the file's size in memory. Either way the file is validated once. */
enum { WRT_OPEN_MAP = 0, WRT_OPEN_PRIVATE = 1 };
/* Opens `path` as `how` says; otherwise as wrt_runtime_open_file (same options, same
 * errors; messages name the path). A path that is not a regular file (a directory, a FIFO,
 * a device) is refused before it is read, without blocking: WRT_ERR_NOT_OURS. `how`
 * neither value: WRT_ERR_INVALID_ARG. */
WRT_API wrt_status wrt_runtime_open_path(const char *path, int how, const wrt_runtime_options *opt,
                                         wrt_runtime **out, wrt_error *err);

/* What the open file holds, for a viewer's title or a benchmark's record. */
typedef struct wrt_runtime_file_info {
    unsigned version_major, version_minor; /* the .gto format version of the file */
    unsigned long long bytes;              /* the file's size */
    unsigned long long functions;          /* basis functions of the operator */
    unsigned long long entries;            /* the operator's stored entries (RGB each) */
    int private_copy;                      /* 1: opened WRT_OPEN_PRIVATE */
} wrt_runtime_file_info;
/* Errors: WRT_ERR_INVALID_ARG (handle, out NULL). */
WRT_API wrt_status wrt_runtime_get_file_info(const wrt_runtime *rt, wrt_runtime_file_info *out, wrt_error *err);

#ifdef __cplusplus
}
#endif

#endif
