/* rt_scene.h: wrt's one Embree scene builder: a set of quads (one RTC_GEOMETRY_TYPE_QUAD
 * geometry, primitive i = quad i) in a frame whose origin the caller picks (the scene's
 * centre keeps float vertices precise far from the world origin), and the one rule for
 * offsetting rays off surfaces: wrt_ray_eps. Used by the bake, the runtime, the path
 * tracer and the comparison. Depends on Embree 3 and wrt_common.h. */
#ifndef WRT_RT_SCENE_H
#define WRT_RT_SCENE_H

#include <embree3/rtcore.h>

#include "wrt_common.h"

/* Ray offset along normals and at ray ends: 1e-5 of the frame's size, the larger of the
 * quads' bounding-box diagonal and the largest |coordinate| in the frame (float vertices
 * carry an error of about 6e-8 of their magnitude; 1e-5 stays well above it). */
double wrt_ray_eps(const wrt_v3 *corners, size_t ncorners, wrt_v3 origin);

enum {
    WRT_RT_ROBUST = 1,       /* RTC_SCENE_FLAG_ROBUST: no cracks between quads sharing an edge */
    WRT_RT_HIGH_QUALITY = 2, /* RTC_BUILD_QUALITY_HIGH */
};

typedef struct wrt_rt_scene {
    RTCDevice dev;
    RTCScene scene;
    wrt_v3 origin;  /* world position of the frame's origin: trace from p - origin */
    double eps;     /* wrt_ray_eps of the quads */
} wrt_rt_scene;

/* Builds the scene of nq quads whose corners are `corners[4 q .. 4 q + 3]` (world space),
 * vertices stored relative to `origin`. `device_config` is rtcNewDevice's (NULL: Embree's
 * default, all cores). On failure *s is zeroed. Errors: WRT_ERR_UNSUPPORTED (no device,
 * a failed build), WRT_ERR_NOMEM. */
wrt_status wrt_rt_scene_build(const wrt_v3 *corners, int nq, wrt_v3 origin, const char *device_config, int flags,
                              wrt_rt_scene *s);
void wrt_rt_scene_release(wrt_rt_scene *s); /* a zeroed s: no-op */

/* 1 if the segment a -> b (frame coordinates, both ends already lifted off their surfaces)
 * meets a primitive of `scene`; the far end is trimmed by 1e-7 of the length only, so a
 * wall thinner than the ray offset still blocks. */
int wrt_rt_blocked(RTCScene scene, wrt_v3 a, wrt_v3 b);
/* The primitive a ray from o along dir (unit length) meets first, or -1. */
int wrt_rt_first_hit(RTCScene scene, wrt_v3 o, wrt_v3 dir);

#endif
