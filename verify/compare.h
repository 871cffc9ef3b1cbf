/* compare.h: measures how far a bake (.gto) is from the path-traced reference
 * (verify/reference.h) for the scene it was baked from, for a few light positions:
 * the relative RMSE of the indirect incident irradiance over cell averages (every quad
 * cut into an n x n grid of (u,v) cells; the wavelet cell average is the exact average
 * of the Haar reconstruction from X, the reference's the Monte Carlo cell average), the
 * relative RMSE of the indirect radiance image seen by the scene camera (the player's
 * textures sampled bilinearly at the camera rays' hits, against the reference's image),
 * and the reference's own error floor in the same units. Also times the player's update
 * per light change. This is the measurement behind the accuracy/time study (the paper's
 * section 6, Figures 6-9: error against precomputation time, memory and run time).
 * Depends on verify/reference.h, player/relight.h, formats/gto.h, formats/scene.h, Embree 3.
 *
 * Units. For one light, with w_c the cell's area (pixels: 1), W the wavelet value, R the
 * reference's, s its standard error, summed over cells (or valid pixels) and channels:
 *   rmse  = sqrt(sum w (W - R)^2 / sum w R^2)
 *   floor = sqrt(sum w s^2 / sum w R^2)        the reference's noise in the same units
 *   debiased = sqrt(max(0, sum w ((W - R)^2 - s^2)) / sum w R^2)
 * Since E[(W - R)^2] = (W - truth)^2 + s^2, `debiased` estimates the error against the
 * exact answer, and an rmse not clearly above the floor says nothing. Figures over
 * several lights are the means of the per-light figures, over the lights whose reference
 * has any indirect light (a light that lights nothing has no relative error).
 *
 * Not thread-safe: one call at a time on a wrt_compare_ref (each call uses its threads). */
#ifndef WRT_COMPARE_H
#define WRT_COMPARE_H

#include "formats/gto.h"
#include "formats/scene.h"

#define WRT_COMPARE_MAX_LIGHTS 16

typedef struct wrt_compare_options {
    int cells;          /* cells per quad side (0 = 4) */
    long cell_paths;    /* reference paths per light over all cells (0 = 2,000,000); at
                         * least `pilot` per cell are always spent */
    int pilot;          /* paths per cell of the first pass that apportions the rest (0 = 32) */
    int width;          /* image width in pixels (0 = 96; the height follows the camera's
                         * aspect, or equals the width); -1 = no image comparison */
    int spp;            /* reference paths per pixel (0 = 512) */
    int sub;            /* camera rays per pixel side for the wavelet image (0 = 4) */
    int bench_updates;  /* timed light changes for the median (0 = 21) */
    int threads;        /* 0 = all cores */
    uint64_t seed;      /* 0 = 1 */
    /* the glossy display's before/after switches, passed to the runtime (include/wrt.h) */
    int no_final_gather, no_light_splat, gather_points;
    int linear_display; /* the runtime's linear display (wrt.h) instead of the default smooth one */
} wrt_compare_options;

/* Fills the zero fields of *o with the defaults above. */
void wrt_compare_defaults(wrt_compare_options *o);

/* The default light positions: the scene's first light as it is, then count - 1 copies of
 * it (same type, colour, intensity, spot axis and cones) moved to fixed fractions of the
 * scene's bounding box, away from its walls, skipping a position enclosed by the back of
 * surfaces (inside a closed block, where it would light nothing). A scene without a light gets a white point
 * light of intensity diag^2 (diag: the box diagonal) at those positions. Returns the
 * number written (<= count, <= WRT_COMPARE_MAX_LIGHTS; 1 when the first light is a sun,
 * which has no position to move). Deterministic. */
int wrt_compare_default_lights(const wrt_scene *s, int count, wrt_light *out);

/* The reference for one scene and a set of lights (each light alone), computed once and
 * compared with any number of bakes. */
typedef struct wrt_compare_ref wrt_compare_ref;

typedef struct wrt_compare_ref_info {
    double seconds;     /* wall time of the path tracing */
    uint64_t rays;
    long cell_paths;    /* per light, as spent */
    int width, height, spp, valid_pixels;
    double cell_floor, image_floor; /* means over the lights (relative units above) */
} wrt_compare_ref_info;

/* Path-traces the reference: the scene (which must outlive the result), lights[0..n)
 * (copied), options (NULL = defaults). Errors: WRT_ERR_INVALID_ARG (no lights, no quads,
 * too many lights, bad options), WRT_ERR_UNSUPPORTED (Embree). */
wrt_status wrt_compare_ref_create(const wrt_scene *s, const wrt_light *lights, int nlights,
                                  const wrt_compare_options *o, wrt_compare_ref **out);
void wrt_compare_ref_destroy(wrt_compare_ref *r); /* NULL is a no-op */
void wrt_compare_ref_get_info(const wrt_compare_ref *r, wrt_compare_ref_info *info);

typedef struct wrt_compare_light_result {
    double cell_rmse, cell_floor, cell_debiased;
    double image_rmse, image_floor, image_debiased; /* -1 without the image comparison */
    double cell_ratio;  /* sum w W / sum w R over cells and channels: the bake's overall bias */
    /* The display (common/reconstruct.h): the cells of the smooth textures on Lambertian
     * quads (the Haar cells elsewhere), and the image of the Haar cells as blocks, the
     * display before the smooth reconstruction (same floors as above). */
    double cell_rmse_smooth, cell_debiased_smooth;
    double image_rmse_haar, image_debiased_haar;
    /* Seams of the display (smooth; _haar: the Haar blocks): over the edges shared by
     * coplanar neighbours (reconstruct.h), the mean jump between the two quads a quarter
     * texel either side of the edge, and inside: the jump across each quad's middle line
     * at the same distance; both relative to the light's value there. 0 without shared
     * edges. */
    double seam_across, seam_inside, seam_across_haar, seam_inside_haar;
} wrt_compare_light_result;

typedef struct wrt_compare_result {
    int nlights;
    wrt_compare_light_result light[WRT_COMPARE_MAX_LIGHTS];
    wrt_compare_light_result mean;  /* means over the lights */
    double ms_update_median;        /* wrt_relight_update per light change, milliseconds */
    double ms_update_min, ms_update_max;
    double cpu_ms_update_median;    /* the process's CPU time per light change (all threads) */
    double ms_eye_median, cpu_ms_eye_median; /* the same per camera move (wall, CPU) */
    double seconds;                 /* wall time of this comparison */
} wrt_compare_result;

/* Compares the bake `g` (baked from the reference's scene: same quads, checked) with the
 * reference: relights it for each light alone, with the eye at the scene camera.
 * Errors: WRT_ERR_INVALID_ARG (a different scene), what wrt_relight_create returns. */
wrt_status wrt_compare_gto(const wrt_compare_ref *r, const wrt_gto *g, wrt_compare_result *out);

/* Times the player's update per light change without a reference: relights `g` with
 * `light` alone (eye at `eye`), then moves it `updates` times around a circle of 2% of
 * the scene's size and times each set_lights + update (wall and process CPU time); then
 * moves the eye `updates` times around a circle of the same radius and times each
 * set_eye + update (a camera move: glossy quads' view-dependent radiance).
 * Fills the ms_* and cpu_ms_* fields of *out (and nothing else). */
wrt_status wrt_compare_bench(const wrt_gto *g, const wrt_light *light, const double eye[3], int updates,
                             const wrt_compare_options *o, wrt_compare_result *out);

/* For tests and pictures: the last comparison's wavelet (wavelet = 1; 2: the Haar cells
 * as blocks) and reference (0) indirect images of light `light` (width x height RGB, top
 * row first; NULL if none). Valid until the next
 * wrt_compare_gto or destroy. Invalid pixels (a camera ray missed or saw a back face) are 0. */
const float *wrt_compare_image(const wrt_compare_ref *r, int light, int wavelet);
/* Cell averages of quad q for light `light`: n x n x RGB, cell (i, j) at (j n + i) x 3,
 * of the last comparison (wavelet = 1) or of the reference (0; with its standard errors
 * in *se if se is not NULL). */
const double *wrt_compare_cells(const wrt_compare_ref *r, int light, int q, int wavelet, const double **se);

#endif
