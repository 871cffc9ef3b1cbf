/* limits.h: the ranges of the numbers that enter wrt (from a glTF scene, a command line or
 * the library), chosen from what the computation can carry, checked where they enter so
 * that a finite but absurd value is refused with a message instead of turning into inf
 * or NaN several stages later. Depends on wrt_common.h. docs/limits.md argues each bound.
 *
 *   WRT_MAX_COORD      1e9   |x|, |y|, |z| of a vertex, light or eye. A distance between
 *                            two such points is at most 2 sqrt(3) 1e9 = 3.5e9, its fourth
 *                            power 1.4e38: the kernel terms (cos cos / r^2, and the r^4 of
 *                            unnormalized dot products) stay below FLT_MAX (3.4e38) even
 *                            where the runtime computes them in single precision.
 *   WRT_MIN_EXTENT     1e-6  the diagonal of a scene's bounding box, in metres: below a
 *                            micrometre (visible light's wavelengths are 0.4-0.7 um)
 *                            geometric optics, which the method assumes, does not hold,
 *                            and an element's area (its sides down to 1e-5 of the
 *                            diagonal) approaches what a 32-bit float in the .gto holds
 *                            once the scene shrinks further (1e-20 m: areas of 1e-40 are 0).
 *   WRT_MIN_YFOV       1e-4  a camera's vertical field of view in radians (0.006 degrees,
 *                            far narrower than any lens): the projection's 1/tan(yfov/2)
 *                            must leave a pixel's offset visible in single precision; at
 *                            1e-10 half the Cornell box's picture came out black.
 *   WRT_MAX_LIGHT_INTENSITY 1e12 candela of a point or spot light (a 100 W bulb is ~140 cd,
 *                            the sun seen from 1 m ~3e27 cd is not a punctual light).
 *   WRT_MAX_COLOR      1e3   a colour channel given on a command line (glTF's are [0, 1]).
 *   WRT_MAX_LIGHT_SCALE 1e3  a --light-scale factor; also an emitter's scale
 *                            (--emitter-scale, wrt_runtime_set_emitter_scale).
 *   WRT_MAX_EMISSIVE   1e12  a glTF material's emissiveStrength (its emitted radiance is
 *                            emissiveFactor, in [0, 1], times it; the sun's disc is about
 *                            1.6e9 cd/m^2). At 3e38 the emitter's power (pi L_e A) was inf
 *                            in float and the indirect light NaN.
 *   So a light's radiant factor intensity x colour x scale is at most 1e18, and the
 *   irradiance it gives, 1e18 / d^2, stays below FLT_MAX for every distance d > 1e-10,
 *   with a margin of 1e9 for the sums over the operator's columns. The library (include/wrt.h)
 *   takes the same WRT_MAX_COORD and bounds intensity x colour by its WRT_MAX_INTENSITY, 1e20,
 *   which every scene and command-line light within these bounds stays under.
 */
#ifndef WRT_LIMITS_H
#define WRT_LIMITS_H

#include <math.h>

#include "../include/wrt.h" /* WRT_MAX_COORD (1e9) and the library's WRT_MAX_INTENSITY (1e20, intensity x colour) */

#define WRT_MIN_EXTENT 1e-6
#define WRT_MIN_YFOV 1e-4
#define WRT_MAX_LIGHT_INTENSITY 1e12
#define WRT_MAX_COLOR 1e3
#define WRT_MAX_LIGHT_SCALE 1e3
#define WRT_MAX_EMISSIVE 1e12

/* 1 if x is finite and |x| <= bound. */
static inline int wrt_in_bound(double x, double bound) { return isfinite(x) && fabs(x) <= bound; }
/* 1 if all three coordinates are within WRT_MAX_COORD. */
static inline int wrt_coord3_ok(double x, double y, double z) {
    return wrt_in_bound(x, WRT_MAX_COORD) && wrt_in_bound(y, WRT_MAX_COORD) && wrt_in_bound(z, WRT_MAX_COORD);
}

#endif
