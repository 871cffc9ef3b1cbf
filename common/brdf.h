/* brdf.h: the glTF 2.0 metallic-roughness BRDF (specification, Appendix B) shared
 * by the bake, the player and the reference path tracer, so they agree on what a
 * material reflects. Directions are unit vectors pointing away from the surface.
 *   c_diff = lerp(base, 0, metallic), f0 = lerp(0.04, base, metallic), alpha = roughness^2
 *   F = f0 + (1 - f0)(1 - |v.h|)^5, D = GGX(alpha), V = Smith height-correlated
 *   f = (1 - F) c_diff / pi + F D V
 * A Lambertian material (roughness 1, metallic 0) is f = base / pi exactly (we drop
 * the 4% specular of the full model there: it decides that the bake needs no angular
 * refinement, and README.md says so). */
#ifndef WRT_BRDF_H
#define WRT_BRDF_H

#include "scene_types.h"

/* f_r(wi, wo) for material m at a surface with normal n; out = RGB. Zero if
 * either direction is below the surface. */
void wrt_brdf_eval(const wrt_material *m, wrt_v3 n, wrt_v3 wi, wrt_v3 wo, double out[3]);

/* Angular resolution (max angular Haar level, 0..WRT_MAX_ALEVEL) a material needs;
 * 0 for Lambertian materials. */
int wrt_brdf_angular_level(const wrt_material *m);

/* Samples wi for a given wo proportional (approximately) to the BRDF times cosine.
 * u1,u2 uniform in [0,1). Returns the weight f cos / pdf in w[3], 0 if invalid. */
wrt_v3 wrt_brdf_sample(const wrt_material *m, wrt_v3 n, wrt_v3 wo, double u1, double u2,
                       double u3, double w[3]);

#endif
