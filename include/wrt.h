/* wrt.h: the wrt runtime library (libwrt): relights a scene baked by wrt-bake (a .gto
 * file) for moving point and spot lights, without any window or GPU. Each update
 * projects the direct light onto the scene's wavelet basis, applies the baked indirect
 * transport operator and turns the result into one texture of outgoing indirect
 * radiance per quad (linear RGB floats); draw your direct light as you like and add it.
 *
 *   wrt_runtime *rt;
 *   wrt_error err;
 *   if (wrt_runtime_open_file("scene.gto", NULL, &rt, &err)) { puts(err.message); return 1; }
 *   wrt_runtime_light l;
 *   wrt_runtime_get_light(rt, 0, &l);          // the file's first light (or fill one in)
 *   l.position[1] -= 0.2;
 *   wrt_runtime_set_lights(rt, &l, 1, &err);
 *   wrt_runtime_set_eye(rt, eye);              // glossy quads need the eye
 *   wrt_runtime_update(rt, NULL, &err);
 *   for (int q = 0; q < wrt_runtime_quad_count(rt); q++) {
 *       int res; const float *tex = wrt_runtime_quad_texture(rt, q, &res);  // res x res x RGB
 *   }
 *   wrt_runtime_close(rt);
 *
 * Build: cc app.c $(pkg-config --cflags --libs wrt)  (add --static for libwrt.a).
 *
 * Rules. Every call that can fail returns a wrt_status (WRT_OK = 0) and, if `err` is not
 * NULL, fills it with the status and a message naming what failed; nothing aborts or
 * exits, out of memory included (an update that runs out returns WRT_ERR_NOMEM; the
 * textures may then be partly updated, and the next update redoes them all). Option
 * structs are zero-initialised for the defaults (wrt_runtime_defaults shows them).
 * Results do not depend on the thread count or on a job hook.
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
 * tracer used for shadow rays) builds its scene at open on threads of its own.
 *
 * Quads. A quad's texture covers its parameter square: texel (i, j) of res x res covers
 * u in [i/res, (i+1)/res), v in [j/res, (j+1)/res), row j after row j-1, where the point
 * at (u, v) is (1-u)(1-v) p0 + u(1-v) p1 + u v p2 + (1-u) v p3 for the quad's corners
 * p0..p3 (wrt_runtime_quad_corners). Units: radiance in the lights' units (candela for
 * intensity, metres for positions: W/(m^2 sr) for a light of 1 W/sr). */
#ifndef WRT_H
#define WRT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define WRT_API_VERSION 1

/* What every fallible call returns (shared by all of wrt's tools and libraries). */
typedef enum wrt_status {
    WRT_OK = 0,
    WRT_ERR_IO,          /* could not open, read or write a file */
    WRT_ERR_NOT_OURS,    /* not our kind of file (foreign magic) */
    WRT_ERR_CORRUPT,     /* our kind of file, but broken: truncated, bad offsets, checksum */
    WRT_ERR_UNSUPPORTED, /* valid, but a version or feature we do not support */
    WRT_ERR_PARSE,       /* malformed input (glTF JSON, buffers, accessors) */
    WRT_ERR_GEOMETRY,    /* geometry we refuse: unpaired triangles, non-planar/degenerate quads, NaN */
    WRT_ERR_INVALID_ARG, /* absurd option or argument */
    WRT_ERR_NOMEM,
    WRT_ERR_CANCELLED,   /* a progress callback asked to stop */
    WRT_ERR_ACCURACY,    /* a required accuracy was not met */
    WRT_ERR_GL,          /* OpenGL / EGL / window system failure */
    WRT_STATUS_COUNT
} wrt_status;

/* Short constant text for a status ("ok", "i/o error", ...). */
const char *wrt_status_str(wrt_status s);

/* What went wrong, filled by a failing call (when not NULL). */
typedef struct wrt_error {
    wrt_status status;
    char message[256];
} wrt_error;

/* Memory. alloc(size, user) returns memory aligned for any type, or NULL (the call then
 * fails with WRT_ERR_NOMEM); free(p, user) releases it. All zero: malloc and free.
 * Used for the runtime's handle, every array it keeps (operator indexing, textures,
 * coefficient vectors, BRDF tables, lights) and the scratch its workers grow during an
 * update (called from those threads at once: must be thread-safe). Embree's scene and
 * the thread pool's control block keep their own (malloc). */
typedef struct wrt_allocator {
    void *(*alloc)(size_t size, void *user);
    void (*free)(void *p, void *user);
    void *user;
} wrt_allocator;

typedef struct wrt_runtime_options {
    int threads;        /* worker threads of an update: 0 = all cores, 1 = the caller's thread only */
    int max_tex_res;    /* cap on a quad's texture side in texels, a power of two: 0 = 64 */
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
} wrt_runtime_options;

/* Fills the zero fields of *o with the defaults. */
void wrt_runtime_defaults(wrt_runtime_options *o);

typedef struct wrt_runtime wrt_runtime;

/* Opens and validates a .gto file (mapped read-only; every section's bounds and
 * checksums are checked). `opt` may be NULL. On failure *out is NULL.
 * Errors: WRT_ERR_IO, WRT_ERR_NOT_OURS, WRT_ERR_CORRUPT, WRT_ERR_UNSUPPORTED,
 * WRT_ERR_INVALID_ARG, WRT_ERR_NOMEM. */
wrt_status wrt_runtime_open_file(const char *path, const wrt_runtime_options *opt, wrt_runtime **out,
                                 wrt_error *err);
/* The same for a file image the caller holds (mapped or read): `data` must be 8-byte
 * aligned and stay valid and unchanged until wrt_runtime_close. */
wrt_status wrt_runtime_open_memory(const void *data, size_t size, const wrt_runtime_options *opt,
                                   wrt_runtime **out, wrt_error *err);
/* Releases everything (and unmaps a file it opened). NULL is a no-op. */
void wrt_runtime_close(wrt_runtime *rt);

enum { WRT_LIGHT_KIND_POINT = 0, WRT_LIGHT_KIND_SPOT = 1, WRT_LIGHT_KIND_DIRECTIONAL = 2 };

/* A light (KHR_lights_punctual's model). Zero-initialised: a white point light of
 * intensity 0 at the origin, on. */
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
} wrt_runtime_light;

/* The lights stored in the file (as baked from the glTF scene). */
int wrt_runtime_light_count(const wrt_runtime *rt);
wrt_status wrt_runtime_get_light(const wrt_runtime *rt, int index, wrt_runtime_light *out, wrt_error *err);

/* Sets the lights (copied; n >= 0, at most 64). Only lights that changed are
 * re-projected at the next update. Errors: WRT_ERR_INVALID_ARG (non-finite values,
 * negative intensity, cones out of range, too many), WRT_ERR_NOMEM. */
wrt_status wrt_runtime_set_lights(wrt_runtime *rt, const wrt_runtime_light *lights, int n, wrt_error *err);
/* Sets the eye (world position); only glossy quads depend on it, and they stay black
 * until it is set. Errors: WRT_ERR_INVALID_ARG (non-finite). */
wrt_status wrt_runtime_set_eye(wrt_runtime *rt, const double eye[3], wrt_error *err);

/* Recomputes what changed since the last update. *changed (if not NULL) receives the
 * number of quads whose texture changed (0: nothing to upload). Errors: WRT_ERR_NOMEM
 * (then *changed is 0, and the next successful update redoes every texture). */
wrt_status wrt_runtime_update(wrt_runtime *rt, int *changed, wrt_error *err);

/* The scene's quads: count, corners (p[4][3], world space), and after an update each
 * one's texture of outgoing indirect radiance (res x res x RGB, see "Quads" above;
 * valid until the next update) and its mean over the quad (area-weighted, RGB). */
int wrt_runtime_quad_count(const wrt_runtime *rt);
void wrt_runtime_quad_corners(const wrt_runtime *rt, int q, double p[4][3]);
const float *wrt_runtime_quad_texture(const wrt_runtime *rt, int q, int *res);
void wrt_runtime_quad_mean(const wrt_runtime *rt, int q, float rgb[3]);

/* Cell averages of quad q's incident indirect irradiance (W/m^2 per W/sr of the lights)
 * on an n x n grid of (u, v) cells, exact for the Haar reconstruction: out[(j n + i) 3 + c]
 * for cell (i, j). n in 1..1024. Errors: WRT_ERR_INVALID_ARG. */
wrt_status wrt_runtime_quad_cells(const wrt_runtime *rt, int q, int n, double *out, wrt_error *err);

/* Mean incident irradiance over quad q (RGB), direct (from the light's projection) and
 * indirect, for the current lights. */
void wrt_runtime_quad_irradiance(const wrt_runtime *rt, int q, double direct[3], double indirect[3]);

/* Milliseconds of the last update's stages (projection, multiply, brdf, synthesis). */
void wrt_runtime_timings(const wrt_runtime *rt, double ms[4]);

#ifdef __cplusplus
}
#endif

#endif
