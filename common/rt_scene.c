/* rt_scene.c: the Embree quad-scene builder and the ray-offset rule (rt_scene.h). */
#include "rt_scene.h"

#include <string.h>

double wrt_ray_eps(const wrt_v3 *c, size_t n, wrt_v3 origin) {
    if (!n) return 1e-5;
    wrt_v3 lo = c[0], hi = c[0];
    double far = 0;
    for (size_t i = 0; i < n; i++) {
        lo = v3(fmin(lo.x, c[i].x), fmin(lo.y, c[i].y), fmin(lo.z, c[i].z));
        hi = v3(fmax(hi.x, c[i].x), fmax(hi.y, c[i].y), fmax(hi.z, c[i].z));
        wrt_v3 d = v3_sub(c[i], origin);
        far = fmax(far, fmax(fabs(d.x), fmax(fabs(d.y), fabs(d.z))));
    }
    double size = fmax(v3_len(v3_sub(hi, lo)), far);
    return 1e-5 * (size > 0 ? size : 1);
}

static void log_error(void *user, enum RTCError code, const char *str) {
    (void)user;
    wrt_log(WRT_LOG_WARN, "Embree error %d: %s", (int)code, str ? str : "");
}

wrt_status wrt_rt_scene_build(const wrt_v3 *corners, int nq, wrt_v3 origin, const char *device_config, int flags,
                              wrt_rt_scene *s) {
    memset(s, 0, sizeof *s);
    s->origin = origin;
    s->eps = wrt_ray_eps(corners, (size_t)(nq > 0 ? nq : 0) * 4, origin);
    s->dev = rtcNewDevice(device_config);
    /* A device that cannot be made (its thread pool, its memory) is a resource failure
     * of this machine, not bad input: out of memory (the programs' exit 7). */
    if (!s->dev) {
        int e = (int)rtcGetDeviceError(NULL);
        return wrt_fail(WRT_ERR_NOMEM, "Embree: cannot create a device (error %d%s)", e,
                        e == RTC_ERROR_OUT_OF_MEMORY ? ": out of memory" : "");
    }
    rtcSetDeviceErrorFunction(s->dev, log_error, NULL);
    s->scene = rtcNewScene(s->dev);
    if (!s->scene) {
        wrt_rt_scene_release(s);
        return wrt_fail(WRT_ERR_NOMEM, "Embree: cannot create a scene (out of memory)");
    }
    if (flags & WRT_RT_ROBUST) rtcSetSceneFlags(s->scene, RTC_SCENE_FLAG_ROBUST);
    if (flags & WRT_RT_HIGH_QUALITY) rtcSetSceneBuildQuality(s->scene, RTC_BUILD_QUALITY_HIGH);
    if (nq > 0) {
        RTCGeometry g = rtcNewGeometry(s->dev, RTC_GEOMETRY_TYPE_QUAD);
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), (size_t)nq * 4);
        unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT4, 4 * sizeof(unsigned), (size_t)nq);
        if (!vb || !ib) {
            rtcReleaseGeometry(g);
            wrt_rt_scene_release(s);
            return wrt_fail(WRT_ERR_NOMEM, "Embree: no memory for %d quads", nq);
        }
        for (size_t i = 0; i < (size_t)nq * 4; i++) {
            wrt_v3 p = v3_sub(corners[i], origin);
            vb[3 * i] = (float)p.x;
            vb[3 * i + 1] = (float)p.y;
            vb[3 * i + 2] = (float)p.z;
            ib[i] = (unsigned)i;
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(s->scene, g);
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(s->scene);
    enum RTCError err = rtcGetDeviceError(s->dev);
    if (err != RTC_ERROR_NONE) {
        wrt_rt_scene_release(s);
        if (err == RTC_ERROR_OUT_OF_MEMORY) return wrt_fail(WRT_ERR_NOMEM, "Embree: out of memory building the scene");
        return wrt_fail(WRT_ERR_UNSUPPORTED, "Embree: the scene build failed (error %d)", (int)err);
    }
    return WRT_OK;
}

void wrt_rt_scene_release(wrt_rt_scene *s) {
    if (s->scene) rtcReleaseScene(s->scene);
    if (s->dev) rtcReleaseDevice(s->dev);
    memset(s, 0, sizeof *s);
}

int wrt_rt_blocked(RTCScene scene, wrt_v3 a, wrt_v3 b) {
    wrt_v3 d = v3_sub(b, a);
    double len = v3_len(d);
    if (len <= 0) return 0;
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay ray;
    ray.org_x = (float)a.x; ray.org_y = (float)a.y; ray.org_z = (float)a.z;
    ray.dir_x = (float)(d.x / len); ray.dir_y = (float)(d.y / len); ray.dir_z = (float)(d.z / len);
    ray.tnear = 0;
    ray.tfar = (float)(len * (1 - 1e-7));
    ray.time = 0; ray.mask = 0xFFFFFFFF; ray.id = 0; ray.flags = 0;
    if (ray.tfar <= ray.tnear) return 0;
    rtcOccluded1(scene, &ctx, &ray);
    return ray.tfar < 0;
}

int wrt_rt_first_hit(RTCScene scene, wrt_v3 o, wrt_v3 dir) {
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    memset(&rh, 0, sizeof rh);
    rh.ray.org_x = (float)o.x; rh.ray.org_y = (float)o.y; rh.ray.org_z = (float)o.z;
    rh.ray.dir_x = (float)dir.x; rh.ray.dir_y = (float)dir.y; rh.ray.dir_z = (float)dir.z;
    rh.ray.tnear = 0; rh.ray.tfar = INFINITY; rh.ray.mask = 0xFFFFFFFF;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? -1 : (int)rh.hit.primID;
}
