/* reference.c: the brute-force reference path tracer (see reference.h for the light
 * model, the estimators and their bias). Depends on Embree 3 for ray casting (each
 * quad is one RTC_GEOMETRY_TYPE_QUAD primitive in a robust scene), common/brdf.h for
 * reflection and formats/scene.h for the scene; it shares no code with the wavelet
 * bake or player, so that it can check them (Kontkanen et al. 2006, section 6 compares
 * against path-traced references the same way).
 *
 * Geometry is kept in double on our side: normals and planes are recomputed from the
 * quad corners, hit points are snapped back onto the hit quad's plane, and ray origins
 * are offset along the normal by a scale-relative epsilon (wrt_ray_eps, common/rt_scene.h: 1e-5 x the scene's size)
 * so that Embree's single-precision intersections never see their own surface. */
#include "reference.h"
#include "common/brdf.h"
#include "common/threads.h"
#include "common/rt_scene.h"
#include "common/texture.h"
#include "common/smooth.h"

#include <embree3/rtcore.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define REF_RR_START 3         /* Russian roulette from this reflection on */
#define REF_RR_MAX_SURVIVAL 0.98
#define REF_MAX_BOUNCES_SAFETY 100000

typedef struct ref_quad {
    wrt_v3 n, t, b;  /* unit normal (from the corners) and a tangent frame */
    double d;        /* plane: dot(n, x) = d */
    const wrt_material *m;
    int sm;          /* its smooth surface in wrt_ref.smooth (a curved element), or -1 */
} ref_quad;

struct wrt_ref {
    const wrt_scene *scene;
    RTCDevice device;
    RTCScene rtc;
    ref_quad *quads;
    wrt_smooth_src *smooth; /* the curved elements' smooth surfaces (common/smooth.h) */
    double eps;      /* origin offset along the normal */
    _Atomic uint64_t rays;
};

/* ---- random numbers: counter-based, so results ignore the thread schedule ---- */
typedef struct ref_rng { uint64_t s; } ref_rng;

static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
static ref_rng rng_make(uint64_t seed, uint64_t domain, uint64_t item, uint64_t sample) {
    uint64_t h = mix64(seed ^ 0x51ed2701f3a5c7b9ULL);
    h = mix64(h ^ (domain * 0x9e3779b97f4a7c15ULL));
    h = mix64(h ^ (item + 0x632be59bd9b4e019ULL));
    h = mix64(h ^ (sample * 0xd6e8feb86659fd93ULL + 1));
    ref_rng r = {h};
    return r;
}
static double rng_next(ref_rng *r) {
    r->s += 0x9e3779b97f4a7c15ULL;
    return (double)(mix64(r->s) >> 11) * 0x1.0p-53;
}

/* ---- creation ---- */

static void frame_of(wrt_v3 n, wrt_v3 *t, wrt_v3 *b) {
    wrt_v3 a = fabs(n.x) < 0.6 ? v3(1, 0, 0) : v3(0, 1, 0);
    *t = v3_norm(v3_cross(a, n));
    *b = v3_cross(n, *t);
}

wrt_ref *wrt_ref_create(const wrt_scene *scene) {
    if (!scene || scene->nquads <= 0) {
        wrt_fail(WRT_ERR_INVALID_ARG, "reference: scene has no quads");
        return NULL;
    }
    wrt_ref *r = wrt_xcalloc(1, sizeof *r);
    r->scene = scene;
    r->quads = wrt_xcalloc((size_t)scene->nquads, sizeof *r->quads);
    int nsmooth = 0;
    for (int i = 0; i < scene->nquads; i++) {
        const wrt_quad *q = &scene->quads[i];
        if (q->material < 0 || q->material >= scene->nmaterials) {
            wrt_fail(WRT_ERR_INVALID_ARG, "reference: quad %d has material %d of %d", i,
                     q->material, scene->nmaterials);
            wrt_ref_destroy(r);
            return NULL;
        }
        wrt_v3 n = v3_norm(v3_cross(v3_sub(q->p[1], q->p[0]), v3_sub(q->p[3], q->p[0])));
        if (!v3_finite(n) || v3_len(n) < 0.5) {
            wrt_fail(WRT_ERR_GEOMETRY, "reference: quad %d is degenerate", i);
            wrt_ref_destroy(r);
            return NULL;
        }
        ref_quad *rq = &r->quads[i];
        rq->n = n;
        frame_of(n, &rq->t, &rq->b);
        rq->d = v3_dot(n, q->p[0]);
        rq->m = &scene->materials[q->material];
        rq->sm = -1;
        wrt_smooth_src src;
        wrt_smooth_make(q->p, n, q->has_nrm ? (const float(*)[3])q->vn : NULL,
                        q->kind == WRT_ELEM_TRIANGLE, &src);
        if (src.curved) {
            if (!r->smooth) r->smooth = wrt_xmalloc((size_t)scene->nquads * sizeof *r->smooth);
            rq->sm = nsmooth;
            r->smooth[nsmooth++] = src;
        }
    }
    wrt_v3 *corners = malloc((size_t)(scene->nquads > 0 ? scene->nquads : 1) * 4 * sizeof *corners);
    if (!corners) {
        wrt_fail(WRT_ERR_NOMEM, "reference: no memory for %d quads", scene->nquads);
        wrt_ref_destroy(r);
        return NULL;
    }
    for (int i = 0; i < scene->nquads; i++)
        for (int k = 0; k < 4; k++) corners[4 * i + k] = scene->quads[i].p[k];
    wrt_rt_scene rs;
    wrt_status st = wrt_rt_scene_build(corners, scene->nquads, v3(0, 0, 0), NULL, WRT_RT_ROBUST | WRT_RT_HIGH_QUALITY, &rs);
    free(corners);
    if (st != WRT_OK) {
        wrt_ref_destroy(r);
        return NULL;
    }
    r->device = rs.dev;
    r->rtc = rs.scene;
    r->eps = rs.eps;
    return r;
}

void wrt_ref_destroy(wrt_ref *r) {
    if (!r) return;
    if (r->rtc) rtcReleaseScene(r->rtc);
    if (r->device) rtcReleaseDevice(r->device);
    free(r->quads);
    free(r->smooth);
    free(r);
}

uint64_t wrt_ref_rays(const wrt_ref *r) { return r ? atomic_load(&r->rays) : 0; }

/* ---- ray casting ---- */
typedef struct ref_thread {
    wrt_ref *r;
    const wrt_light *lights;
    int nlights;
    int max_bounces;
    uint64_t rays;
} ref_thread;

/* Nearest hit along o + t d, t in (0, tfar); returns the quad index or -1, and *t. */
static int cast(ref_thread *th, wrt_v3 o, wrt_v3 d, double *t) {
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRayHit rh;
    memset(&rh, 0, sizeof rh);
    rh.ray.org_x = (float)o.x; rh.ray.org_y = (float)o.y; rh.ray.org_z = (float)o.z;
    rh.ray.dir_x = (float)d.x; rh.ray.dir_y = (float)d.y; rh.ray.dir_z = (float)d.z;
    rh.ray.tnear = 0;
    rh.ray.tfar = INFINITY;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(th->r->rtc, &ctx, &rh);
    th->rays++;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return -1;
    *t = rh.ray.tfar;
    return (int)rh.hit.primID;
}

/* 1 if nothing blocks the segment from o to target. */
static int visible(ref_thread *th, wrt_v3 o, wrt_v3 target) {
    wrt_v3 d = v3_sub(target, o);
    double len = v3_len(d);
    if (!(len > th->r->eps)) return 1;
    d = v3_scale(d, 1 / len);
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay ray;
    memset(&ray, 0, sizeof ray);
    ray.org_x = (float)o.x; ray.org_y = (float)o.y; ray.org_z = (float)o.z;
    ray.dir_x = (float)d.x; ray.dir_y = (float)d.y; ray.dir_z = (float)d.z;
    ray.tnear = 0;
    ray.tfar = (float)(len - th->r->eps);
    ray.mask = 0xFFFFFFFFu;
    rtcOccluded1(th->r->rtc, &ctx, &ray);
    th->rays++;
    return ray.tfar >= 0; /* Embree sets tfar to -inf on a hit */
}

/* 1 if the ray from o along unit direction d leaves the scene (a sun's shadow ray). */
static int escapes(ref_thread *th, wrt_v3 o, wrt_v3 d) {
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    struct RTCRay ray;
    memset(&ray, 0, sizeof ray);
    ray.org_x = (float)o.x; ray.org_y = (float)o.y; ray.org_z = (float)o.z;
    ray.dir_x = (float)d.x; ray.dir_y = (float)d.y; ray.dir_z = (float)d.z;
    ray.tnear = 0;
    ray.tfar = INFINITY;
    ray.mask = 0xFFFFFFFFu;
    rtcOccluded1(th->r->rtc, &ctx, &ray);
    th->rays++;
    return ray.tfar >= 0;
}

/* 1 if light l is seen from o (toward wl, the unit direction to it). */
static int light_seen(ref_thread *th, wrt_v3 o, const wrt_light *l, wrt_v3 wl) {
    return l->type == WRT_LIGHT_DIRECTIONAL ? escapes(th, o, wl) : visible(th, o, l->pos);
}

/* Unshadowed irradiance (per unit area normal to n) from light l at x, and the unit
 * direction *wl toward it; 0 behind the surface. A directional light (sun): intensity x
 * cos toward -dir, no falloff, no range. */
static int light_irradiance(const wrt_light *l, wrt_v3 x, wrt_v3 n, wrt_v3 *wl, double e[3]) {
    e[0] = e[1] = e[2] = 0;
    if (l->type == WRT_LIGHT_DIRECTIONAL) {
        *wl = v3_scale(v3_norm(l->dir), -1);
        double mu = v3_dot(n, *wl), s = l->intensity * mu;
        if (!(mu > 0) || !(s > 0)) return 0;
        for (int c = 0; c < 3; c++) e[c] = s * l->color[c];
        return 1;
    }
    wrt_v3 d = v3_sub(l->pos, x);
    double r2 = v3_dot(d, d);
    if (!(r2 > 0)) return 0;
    double r = sqrt(r2);
    *wl = v3_scale(d, 1 / r);
    double mu = v3_dot(n, *wl);
    if (!(mu > 0)) return 0;
    double s = l->intensity * mu / r2;
    if (l->type == WRT_LIGHT_SPOT) {
        double cs = -v3_dot(l->dir, *wl);
        double ci = cos(l->inner_cone), co = cos(l->outer_cone);
        double f;
        if (ci - co > 1e-12) {
            f = (cs - co) / (ci - co);
            f = f < 0 ? 0 : f > 1 ? 1 : f;
        } else {
            f = cs > co ? 1 : 0;
        }
        s *= f * f;
    }
    if (l->range > 0) {
        double q = r / l->range, w = 1 - q * q * q * q;
        w = w < 0 ? 0 : w;
        s *= w * w;
    }
    if (!(s > 0)) return 0;
    for (int c = 0; c < 3; c++) e[c] = s * l->color[c];
    return 1;
}

/* Shadowed direct irradiance at x (front side of normal n), summed over the lights. */
static void direct_irradiance(ref_thread *th, wrt_v3 x, wrt_v3 n, double e[3]) {
    e[0] = e[1] = e[2] = 0;
    wrt_v3 o = v3_mad(x, n, th->r->eps);
    for (int i = 0; i < th->nlights; i++) {
        double el[3];
        wrt_v3 wl;
        if (!light_irradiance(&th->lights[i], x, n, &wl, el)) continue;
        if (!light_seen(th, o, &th->lights[i], wl)) continue;
        for (int c = 0; c < 3; c++) e[c] += el[c];
    }
}

/* The material at point y of quad qi: its own, or with a base-colour texture (and UVs)
 * a copy whose base colour is the texture's albedo at y's UV (docs/textures.md). */
static const wrt_material *hit_material(const wrt_ref *r, int qi, wrt_v3 y, wrt_material *tmp) {
    const wrt_material *m = r->quads[qi].m;
    const wrt_scene *s = r->scene;
    const wrt_quad *q = &s->quads[qi];
    if (m->base_tex <= 0 || m->base_tex > s->ntextures || !q->has_uv) return m;
    double u, v, st[2];
    wrt_quad_inverse(q, y, &u, &v);
    wrt_quad_uv_at(q, u, v, st);
    *tmp = *m;
    wrt_texture_albedo(&s->textures[m->base_tex - 1], st[0], st[1], tmp->base_color);
    return tmp;
}

/* Direct light reflected at x toward wo (material m): sum over lights f(wl, wo) E_l,
 * shaded with normal ns, the shadow rays leaving from xs (off the face of normal fn). */
static void direct_radiance_at(ref_thread *th, wrt_v3 fn, wrt_v3 ns, const wrt_material *m, wrt_v3 x, wrt_v3 xs,
                               wrt_v3 wo, double out[3]) {
    out[0] = out[1] = out[2] = 0;
    wrt_v3 o = v3_mad(xs, fn, th->r->eps);
    for (int i = 0; i < th->nlights; i++) {
        double el[3], f[3];
        wrt_v3 wl;
        if (!light_irradiance(&th->lights[i], x, ns, &wl, el)) continue;
        wrt_brdf_eval(m, ns, wl, wo, f);
        if (f[0] == 0 && f[1] == 0 && f[2] == 0) continue;
        if (!light_seen(th, o, &th->lights[i], wl)) continue;
        for (int c = 0; c < 3; c++) out[c] += f[c] * el[c];
    }
}

/* The same on the flat element q (the transport's: every bounce after the camera's). */
static void direct_radiance(ref_thread *th, const ref_quad *q, const wrt_material *m, wrt_v3 x, wrt_v3 wo,
                            double out[3]) {
    direct_radiance_at(th, q->n, q->n, m, x, x, wo, out);
}

/* Radiance arriving at o from direction d (o already offset off its surface), with
 * throughput t0: everything the first hit y1 sends back, which is light that reflected
 * `first` or more times by the time it reaches y1's NEE. Reflections are counted
 * from `first` and stop after max_bounces. */
static void trace(ref_thread *th, ref_rng *rng, wrt_v3 o, wrt_v3 d, const double t0[3],
                  int first, double out[3]) {
    double T[3] = {t0[0], t0[1], t0[2]};
    out[0] = out[1] = out[2] = 0;
    for (int k = first;; k++) {
        double t;
        int qi = cast(th, o, d, &t);
        if (qi < 0) return;
        const ref_quad *q = &th->r->quads[qi];
        if (v3_dot(d, q->n) >= 0) return; /* back side: absorbed */
        wrt_v3 y = v3_mad(o, d, t);
        y = v3_mad(y, q->n, q->d - v3_dot(q->n, y)); /* snap onto the plane */
        wrt_v3 wo = v3_scale(d, -1);
        double ld[3];
        wrt_material mt;
        const wrt_material *m = hit_material(th->r, qi, y, &mt);
        direct_radiance(th, q, m, y, wo, ld);
        /* An emissive surface's radiance, met by the path (no next-event estimation toward
         * emitters, so nothing is counted twice and no MIS weight is needed) */
        for (int c = 0; c < 3; c++) out[c] += T[c] * (ld[c] + q->m->emissive[c]);
        if (k >= th->max_bounces) return;
        double w[3];
        double u1 = rng_next(rng), u2 = rng_next(rng), u3 = rng_next(rng);
        wrt_v3 wi = wrt_brdf_sample(m, q->n, wo, u1, u2, u3, w);
        for (int c = 0; c < 3; c++) T[c] *= w[c];
        double tmax = fmax(T[0], fmax(T[1], T[2]));
        if (!(tmax > 0)) return;
        if (k >= REF_RR_START) {
            double p = tmax < REF_RR_MAX_SURVIVAL ? tmax : REF_RR_MAX_SURVIVAL;
            if (rng_next(rng) >= p) return;
            for (int c = 0; c < 3; c++) T[c] /= p;
        }
        o = v3_mad(y, q->n, th->r->eps);
        d = wi;
    }
}

/* One cosine-weighted sample of indirect irradiance at x on quad q: pi L(w). */
static void indirect_sample(ref_thread *th, ref_rng *rng, const ref_quad *q, wrt_v3 x, double e[3]) {
    double u1 = rng_next(rng), u2 = rng_next(rng);
    double rr = sqrt(u1), phi = 2 * WRT_PI * u2, z = sqrt(fmax(0, 1 - u1));
    double lx = rr * cos(phi), ly = rr * sin(phi);
    wrt_v3 d = v3(q->t.x * lx + q->b.x * ly + q->n.x * z, q->t.y * lx + q->b.y * ly + q->n.y * z,
                  q->t.z * lx + q->b.z * ly + q->n.z * z);
    static const double one[3] = {1, 1, 1};
    trace(th, rng, v3_mad(x, q->n, th->r->eps), d, one, 1, e);
    for (int c = 0; c < 3; c++) e[c] *= WRT_PI;
}

/* ---- threads: items handed out by an atomic counter, each written by one thread ---- */
typedef struct ref_job {
    wrt_ref *r;
    const wrt_light *lights;
    int nlights, max_bounces, nitems;
    void (*fn)(struct ref_job *job, ref_thread *th, int item);
    void *ctx;
} ref_job;

typedef struct ref_run { ref_job *job; ref_thread th[64]; } ref_run;

static void job_item(size_t item, int thread, void *user) {
    ref_run *run = user;
    run->job->fn(run->job, &run->th[thread], (int)item);
}

/* The items on common/threads.c's pool; each thread's state (and ray count) apart. */
static void job_run(ref_job *job, int threads) {
    ref_run run;
    run.job = job;
    for (int t = 0; t < 64; t++) run.th[t] = (ref_thread){job->r, job->lights, job->nlights, job->max_bounces, 0};
    wrt_parallel_for((size_t)(job->nitems > 0 ? job->nitems : 0), threads, job_item, &run);
    uint64_t rays = 0;
    for (int t = 0; t < 64; t++) rays += run.th[t].rays;
    atomic_fetch_add(&job->r->rays, rays);
}

static wrt_status check_common(wrt_ref *r, const wrt_light *lights, int nlights, int samples) {
    if (!r) return wrt_fail(WRT_ERR_INVALID_ARG, "reference: no reference");
    if (nlights < 0 || (nlights > 0 && !lights))
        return wrt_fail(WRT_ERR_INVALID_ARG, "reference: %d lights", nlights);
    if (samples < 1) return wrt_fail(WRT_ERR_INVALID_ARG, "reference: %d samples", samples);
    return WRT_OK;
}

static int bounce_cap(int max_bounces) {
    return max_bounces <= 0 ? REF_MAX_BOUNCES_SAFETY : max_bounces;
}

/* Mean and standard error of the mean from a sum and a sum of squares of n samples. */
static void mean_se(double sum, double sum2, int n, double *mean, double *se) {
    double m = sum / n;
    *mean = m;
    if (se) {
        double var = n > 1 ? (sum2 - n * m * m) / (n - 1) : 0;
        *se = sqrt(fmax(0, var) / n);
    }
}

/* ---- irradiance at points ---- */
typedef struct points_ctx {
    const wrt_v3 *points;
    const int *quad_of_point;
    int samples;
    uint64_t seed;
    double *direct, *indirect, *se;
} points_ctx;

static void points_item(ref_job *job, ref_thread *th, int i) {
    points_ctx *c = job->ctx;
    const ref_quad *q = &job->r->quads[c->quad_of_point[i]];
    wrt_v3 x = c->points[i];
    if (c->direct) direct_irradiance(th, x, q->n, &c->direct[3 * i]);
    if (!c->indirect && !c->se) return;
    double s[3] = {0, 0, 0}, s2[3] = {0, 0, 0};
    for (int k = 0; k < c->samples; k++) {
        ref_rng rng = rng_make(c->seed, 1, (uint64_t)i, (uint64_t)k);
        double e[3];
        indirect_sample(th, &rng, q, x, e);
        for (int ch = 0; ch < 3; ch++) { s[ch] += e[ch]; s2[ch] += e[ch] * e[ch]; }
    }
    for (int ch = 0; ch < 3; ch++) {
        double m, se;
        mean_se(s[ch], s2[ch], c->samples, &m, &se);
        if (c->indirect) c->indirect[3 * i + ch] = m;
        if (c->se) c->se[3 * i + ch] = se;
    }
}

wrt_status wrt_ref_irradiance(wrt_ref *r, const wrt_light *lights, int nlights,
                              const wrt_v3 *points, const int *quad_of_point, int npoints,
                              int samples, int max_bounces, int threads, uint64_t seed,
                              double *direct_rgb, double *indirect_rgb, double *indirect_stderr) {
    wrt_status st = check_common(r, lights, nlights, samples);
    if (st != WRT_OK) return st;
    if (npoints < 0 || (npoints > 0 && (!points || !quad_of_point)))
        return wrt_fail(WRT_ERR_INVALID_ARG, "reference: %d points", npoints);
    for (int i = 0; i < npoints; i++)
        if (quad_of_point[i] < 0 || quad_of_point[i] >= r->scene->nquads)
            return wrt_fail(WRT_ERR_INVALID_ARG, "reference: point %d on quad %d of %d", i,
                            quad_of_point[i], r->scene->nquads);
    points_ctx c = {points, quad_of_point, samples, seed, direct_rgb, indirect_rgb, indirect_stderr};
    ref_job job = {.r = r, .lights = lights, .nlights = nlights,
                   .max_bounces = bounce_cap(max_bounces), .nitems = npoints,
                   .fn = points_item, .ctx = &c};
    job_run(&job, threads);
    return WRT_OK;
}

/* ---- cell averages on a quad ---- */
typedef struct cells_ctx {
    int quad, n, samples;
    uint64_t seed;
    double *direct, *indirect, *se;
} cells_ctx;

static void cells_item(ref_job *job, ref_thread *th, int cell) {
    cells_ctx *c = job->ctx;
    const wrt_quad *wq = &job->r->scene->quads[c->quad];
    const ref_quad *q = &job->r->quads[c->quad];
    int i = cell % c->n, j = cell / c->n;
    double sd[3] = {0, 0, 0}, s[3] = {0, 0, 0}, s2[3] = {0, 0, 0};
    for (int k = 0; k < c->samples; k++) {
        ref_rng rng = rng_make(c->seed, 2 + ((uint64_t)c->quad << 8), (uint64_t)cell, (uint64_t)k);
        double u = (i + rng_next(&rng)) / c->n, v = (j + rng_next(&rng)) / c->n;
        wrt_v3 x = wrt_quad_point(wq, u, v);
        x = v3_mad(x, q->n, q->d - v3_dot(q->n, x));
        if (c->direct) {
            double e[3];
            direct_irradiance(th, x, q->n, e);
            for (int ch = 0; ch < 3; ch++) sd[ch] += e[ch];
        }
        if (c->indirect || c->se) {
            double e[3];
            indirect_sample(th, &rng, q, x, e);
            for (int ch = 0; ch < 3; ch++) { s[ch] += e[ch]; s2[ch] += e[ch] * e[ch]; }
        }
    }
    for (int ch = 0; ch < 3; ch++) {
        double m, se;
        mean_se(s[ch], s2[ch], c->samples, &m, &se);
        if (c->direct) c->direct[3 * cell + ch] = sd[ch] / c->samples;
        if (c->indirect) c->indirect[3 * cell + ch] = m;
        if (c->se) c->se[3 * cell + ch] = se;
    }
}

wrt_status wrt_ref_cell_irradiance(wrt_ref *r, const wrt_light *lights, int nlights, int quad,
                                   int n, int samples, int max_bounces, int threads,
                                   uint64_t seed, double *direct_rgb, double *indirect_rgb,
                                   double *indirect_stderr) {
    wrt_status st = check_common(r, lights, nlights, samples);
    if (st != WRT_OK) return st;
    if (quad < 0 || quad >= r->scene->nquads)
        return wrt_fail(WRT_ERR_INVALID_ARG, "reference: quad %d of %d", quad, r->scene->nquads);
    if (n < 1 || n > 4096) return wrt_fail(WRT_ERR_INVALID_ARG, "reference: %d x %d cells", n, n);
    cells_ctx c = {quad, n, samples, seed, direct_rgb, indirect_rgb, indirect_stderr};
    ref_job job = {.r = r, .lights = lights, .nlights = nlights,
                   .max_bounces = bounce_cap(max_bounces), .nitems = n * n,
                   .fn = cells_item, .ctx = &c};
    job_run(&job, threads);
    return WRT_OK;
}

/* ---- images ---- */
typedef struct render_ctx {
    int width, height, spp;
    uint64_t seed;
    wrt_v3 pos, fwd, right, up; /* right and up scaled by the half-extent of the view */
    float *direct, *indirect, *both, *se;
} render_ctx;

static void render_row(ref_job *job, ref_thread *th, int y) {
    render_ctx *c = job->ctx;
    for (int x = 0; x < c->width; x++) {
        uint64_t pix = (uint64_t)y * (uint64_t)c->width + (uint64_t)x;
        double sd[3] = {0, 0, 0}, s[3] = {0, 0, 0}, s2[3] = {0, 0, 0};
        for (int k = 0; k < c->spp; k++) {
            ref_rng rng = rng_make(c->seed, 3, pix, (uint64_t)k);
            double sx = 2 * (x + rng_next(&rng)) / c->width - 1;
            double sy = 1 - 2 * (y + rng_next(&rng)) / c->height;
            wrt_v3 d = v3_norm(v3_add(c->fwd, v3_add(v3_scale(c->right, sx), v3_scale(c->up, sy))));
            double ind[3] = {0, 0, 0}, t;
            int qi = cast(th, c->pos, d, &t);
            if (qi >= 0 && v3_dot(d, job->r->quads[qi].n) < 0) {
                const ref_quad *q = &job->r->quads[qi];
                wrt_v3 p = v3_mad(c->pos, d, t);
                p = v3_mad(p, q->n, q->d - v3_dot(q->n, p));
                wrt_v3 wo = v3_scale(d, -1);
                double dr[3];
                wrt_material mt;
                const wrt_material *m = hit_material(job->r, qi, p, &mt);
                /* the smooth surface of a curved element (common/smooth.h): shaded with the
                 * interpolated normal, its shadow rays from the point moved towards it */
                wrt_v3 ns = q->n, ps = p;
                if (q->sm >= 0) {
                    double sw[4];
                    wrt_smooth_weights(&job->r->smooth[q->sm], p, sw);
                    wrt_smooth_at(&job->r->smooth[q->sm], sw, p, q->n, &ns, &ps);
                    ns = wrt_smooth_facing(ns, wo); /* the grazing outline: not black */
                }
                direct_radiance_at(th, q->n, ns, m, p, ps, wo, dr);
                for (int ch = 0; ch < 3; ch++) sd[ch] += dr[ch] + q->m->emissive[ch]; /* emitter seen */
                double w[3];
                double u1 = rng_next(&rng), u2 = rng_next(&rng), u3 = rng_next(&rng);
                wrt_v3 wi = wrt_brdf_sample(m, ns, wo, u1, u2, u3, w);
                /* about a shading normal a direction may go below the facet: light from
                 * inside the object, none */
                if (q->sm >= 0 && !(v3_dot(wi, q->n) > 0)) w[0] = w[1] = w[2] = 0;
                if (w[0] > 0 || w[1] > 0 || w[2] > 0)
                    trace(th, &rng, v3_mad(p, q->n, job->r->eps), wi, w, 1, ind);
            }
            for (int ch = 0; ch < 3; ch++) { s[ch] += ind[ch]; s2[ch] += ind[ch] * ind[ch]; }
        }
        for (int ch = 0; ch < 3; ch++) {
            double m, se, dm = sd[ch] / c->spp;
            mean_se(s[ch], s2[ch], c->spp, &m, &se);
            size_t o = 3 * pix + (size_t)ch;
            if (c->direct) c->direct[o] = (float)dm;
            if (c->indirect) c->indirect[o] = (float)m;
            if (c->both) c->both[o] = (float)(dm + m);
            if (c->se) c->se[o] = (float)se;
        }
    }
}

wrt_status wrt_ref_render(wrt_ref *r, const wrt_light *lights, int nlights,
                          const wrt_camera *camera, int width, int height, int spp,
                          int max_bounces, int threads, uint64_t seed, float *direct,
                          float *indirect, float *both, float *indirect_stderr) {
    wrt_status st = check_common(r, lights, nlights, spp);
    if (st != WRT_OK) return st;
    if (!camera) return wrt_fail(WRT_ERR_INVALID_ARG, "reference: no camera");
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        return wrt_fail(WRT_ERR_INVALID_ARG, "reference: image %d x %d", width, height);
    if (!(camera->yfov > 0 && camera->yfov < WRT_PI))
        return wrt_fail(WRT_ERR_INVALID_ARG, "reference: camera yfov %g", camera->yfov);
    wrt_v3 fwd = v3_norm(camera->dir);
    wrt_v3 right = v3_norm(v3_cross(fwd, camera->up));
    if (!v3_finite(fwd) || !(v3_len(fwd) > 0.5) || !(v3_len(right) > 0.5))
        return wrt_fail(WRT_ERR_INVALID_ARG, "reference: camera direction and up are degenerate");
    wrt_v3 up = v3_cross(right, fwd);
    double th = tan(camera->yfov / 2);
    double aspect = camera->aspect > 0 ? camera->aspect : (double)width / height;
    render_ctx c = {width, height, spp, seed, camera->pos, fwd, v3_scale(right, th * aspect),
                    v3_scale(up, th), direct, indirect, both, indirect_stderr};
    ref_job job = {.r = r, .lights = lights, .nlights = nlights,
                   .max_bounces = bounce_cap(max_bounces), .nitems = height, .fn = render_row, .ctx = &c};
    job_run(&job, threads);
    return WRT_OK;
}
