/* reference.h: wrt's brute-force reference, a Monte Carlo path tracer over the same
 * scene (formats/scene.h) and the same BRDFs (common/brdf.h) as the bake, with Embree 3
 * for ray casting. It shares nothing else with the wavelet code, so that comparing the
 * two checks the wavelet transport (Kontkanen et al. 2006, sections 4-5) against an
 * independent estimate of the same rendering equation.
 *
 * Light model (KHR_lights_punctual): a point or spot light of intensity I (candela) and
 * colour c gives, at distance r with incidence cosine mu, the irradiance I c mu / r^2,
 * times for a spot clamp((cos - cos_outer) / (cos_inner - cos_outer), 0, 1)^2 with cos
 * the angle between the spot axis and the direction from the light to the point, and
 * times glTF's recommended range window clamp(1 - (r / range)^4, 0, 1)^2 when range > 0.
 * A directional light (sun) of intensity I (lux) travelling along unit d gives I c mu,
 * mu = max(0, -d . n), no falloff and no range; its shadow ray toward -d must leave the
 * scene.
 * Surfaces reflect only on their front (normal) side; a ray reaching the back of a quad
 * is absorbed. Lights are not hit by rays (they are points). An emissive material
 * (wrt_material.emissive, the emitted radiance L_e) sends L_e from its quads' fronts:
 * a path that meets one adds its throughput times L_e (emission on hit, no next-event
 * estimation toward emitters; docs/emitters.md), so the emitters' light on a surface
 * counts as "indirect" (it arrives along the sampled paths), and an emitter seen by the
 * camera adds L_e to the image's "direct".
 *
 * "Direct" irradiance is light arriving straight from the lights; "indirect" is light
 * that reflected at least once. Paths end by unbiased Russian roulette (after three
 * reflections, survival probability = the path throughput's largest channel, capped at
 * 0.98) or at max_bounces reflections, the only source of bias: an enclosure of albedo
 * rho loses the fraction rho^max_bounces of its indirect light, so max_bounces <= 0
 * (no cap except a safety stop at 100000) is the unbiased choice.
 *
 * Results do not depend on the thread count: every (point, sample) draws its random
 * numbers from a counter-based hash of (seed, point index, sample index), and every
 * point's sum is accumulated in a fixed order by one thread.
 *
 * Thread-safety: a wrt_ref may be used by one call at a time; each call runs its own
 * threads (threads <= 0: as many as the machine has cores). */
#ifndef WRT_REFERENCE_H
#define WRT_REFERENCE_H

#include "formats/scene.h"

typedef struct wrt_ref wrt_ref;

/* Builds the Embree scene for `scene` (which must outlive the wrt_ref). Returns NULL
 * with wrt_last_error() set on failure (no quads, Embree error). */
wrt_ref *wrt_ref_create(const wrt_scene *scene);
void wrt_ref_destroy(wrt_ref *r); /* NULL is a no-op */

/* Irradiance arriving at the front side of surface points: points[i] lies on quad
 * quad_of_point[i]. direct_rgb (npoints x 3) is exact (deterministic, shadow rays only);
 * indirect_rgb (npoints x 3) is the mean of `samples` cosine-weighted paths, and
 * indirect_stderr (npoints x 3, may be NULL) its standard error. Any output may be NULL. */
wrt_status wrt_ref_irradiance(wrt_ref *r, const wrt_light *lights, int nlights,
                              const wrt_v3 *points, const int *quad_of_point, int npoints,
                              int samples, int max_bounces, int threads, uint64_t seed,
                              double *direct_rgb, double *indirect_rgb, double *indirect_stderr);

/* Mean irradiance over each cell of an n x n grid on quad `quad`'s (u,v) square:
 * cell (i, j) covers u in [i/n, (i+1)/n), v in [j/n, (j+1)/n) and is stored at
 * index (j n + i) x 3. Each of `samples` samples takes a point uniformly in (u,v) in
 * the cell (uniform in area for a parallelogram) and one indirect path, so the result
 * is a cell average comparable with a Haar scaling coefficient. direct_rgb (may be
 * NULL) is the cell average of direct irradiance at the same points. */
wrt_status wrt_ref_cell_irradiance(wrt_ref *r, const wrt_light *lights, int nlights, int quad,
                                   int n, int samples, int max_bounces, int threads,
                                   uint64_t seed, double *direct_rgb, double *indirect_rgb,
                                   double *indirect_stderr);

/* An image of radiance leaving the first surface hit toward the camera: width x height
 * RGB floats, row 0 at the top, in `direct`, `indirect` and `both` (direct + indirect),
 * and the standard error of the indirect per pixel and channel in `indirect_stderr`.
 * spp jittered samples per pixel; camera aspect 0 = width / height. Outputs may be NULL.
 * The image is of the surface the player shows: where the first hit is a curved element
 * (vertex normals off its plane, common/smooth.h) it is shaded with the interpolated
 * normal (the direct light's cosine and BRDF, and the first reflection's directions,
 * those below the flat facet carrying nothing) and its shadow rays leave from the point
 * moved towards the smooth surface; every later bounce, and the point and cell
 * irradiance above, are the flat elements' (the transport the bake computes). Flat
 * elements (every scene without curved meshes) are as before, sample for sample. */
wrt_status wrt_ref_render(wrt_ref *r, const wrt_light *lights, int nlights,
                          const wrt_camera *camera, int width, int height, int spp,
                          int max_bounces, int threads, uint64_t seed, float *direct,
                          float *indirect, float *both, float *indirect_stderr);

/* Rays (intersection + shadow) cast by this wrt_ref since it was created. */
uint64_t wrt_ref_rays(const wrt_ref *r);

#endif
