/* compare.c: a bake against the path-traced reference, as specified in compare.h.
 * The reference's cell averages are spent in two passes: a pilot of a few paths per
 * cell estimates each quad's area-weighted variance, then the rest of the budget goes to
 * the quads in proportion to the square root of it (the allocation that minimises the
 * area-weighted sum of squared standard errors, i.e. the floor), the two passes pooled.
 * The wavelet image is made here, not by the player's GL display: the camera's rays
 * (sub x sub per pixel, the reference's camera model) find a quad and its (u,v) with
 * Embree, and the player's texture (player/relight.h) is sampled there bilinearly, as
 * the display's GL_LINEAR filter does, clamped to the quad's own texels. Depends on
 * verify/reference.h, player/relight.h, common/basis.h, Embree 3. Paper section 6. */
#include "verify/compare.h"

#include "common/basis.h"
#include "include/wrt.h"
#include "common/rt_scene.h"
#include "verify/reference.h"
#include "common/texture.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct wrt_compare_ref {
    const wrt_scene *scene;
    wrt_compare_options opt;
    wrt_light lights[WRT_COMPARE_MAX_LIGHTS];
    int nlights, n, width, height;
    /* reference, per light */
    double *cell_mean[WRT_COMPARE_MAX_LIGHTS], *cell_se[WRT_COMPARE_MAX_LIGHTS]; /* nquads n^2 x 3 */
    float *img[WRT_COMPARE_MAX_LIGHTS], *img_se[WRT_COMPARE_MAX_LIGHTS];         /* w h x 3 */
    /* camera rays of the wavelet image: per pixel sub^2 hits (quad, u, v) */
    int *hit_quad; float *hit_uv; unsigned char *valid;
    /* last comparison */
    double *wcells[WRT_COMPARE_MAX_LIGHTS];
    float *wimg[WRT_COMPARE_MAX_LIGHTS], *wimg_haar[WRT_COMPARE_MAX_LIGHTS];
    wrt_compare_ref_info info;
};

void wrt_compare_defaults(wrt_compare_options *o) {
    if (o->cells <= 0) o->cells = 4;
    if (o->cell_paths <= 0) o->cell_paths = 2000000;
    if (o->pilot <= 0) o->pilot = 32;
    if (o->width == 0) o->width = 96;
    if (o->spp <= 0) o->spp = 512;
    if (o->sub <= 0) o->sub = 4;
    if (o->bench_updates <= 0) o->bench_updates = 21;
    if (o->seed == 0) o->seed = 1;
}

/* Nearest quad hit by the ray p + t d (t > 0), or -1: Moller-Trumbore on both triangles. */
static int nearest_quad(const wrt_scene *s, wrt_v3 p, wrt_v3 d) {
    double best = INFINITY;
    int hit = -1;
    for (int q = 0; q < s->nquads; q++) {
        const wrt_v3 *c = s->quads[q].p;
        for (int t = 0; t < 2; t++) {
            wrt_v3 a = c[0], b = c[t ? 2 : 1], e = c[t ? 3 : 2];
            wrt_v3 e1 = v3_sub(b, a), e2 = v3_sub(e, a), h = v3_cross(d, e2);
            double det = v3_dot(e1, h);
            if (fabs(det) < 1e-12) continue;
            wrt_v3 sv = v3_sub(p, a);
            double u = v3_dot(sv, h) / det;
            if (u < 0 || u > 1) continue;
            wrt_v3 qv = v3_cross(sv, e1);
            double v = v3_dot(d, qv) / det;
            if (v < 0 || u + v > 1) continue;
            double tt = v3_dot(e2, qv) / det;
            if (tt > 1e-9 && tt < best) { best = tt; hit = q; }
        }
    }
    return hit;
}

/* 1 if p looks enclosed by the back of surfaces (inside a closed block, where a light
 * lights nothing): most of 26 directions first meet a quad from behind. */
static int inside_solid(const wrt_scene *s, wrt_v3 p) {
    int back = 0, n = 0;
    for (int x = -1; x <= 1; x++)
        for (int y = -1; y <= 1; y++)
            for (int z = -1; z <= 1; z++) {
                if (!x && !y && !z) continue;
                wrt_v3 d = v3_norm(v3(x + 0.013 * y, y + 0.017 * z, z + 0.011 * x));
                int q = nearest_quad(s, p, d);
                n++;
                if (q >= 0 && v3_dot(d, s->quads[q].n) > 0) back++;
            }
    return 2 * back > n;
}

int wrt_compare_default_lights(const wrt_scene *s, int count, wrt_light *out) {
    /* Fractions of the box: upper half, a quarter in from the sides, spread around. */
    static const double frac[][3] = {
        {0.30, 0.70, 0.30}, {0.70, 0.60, 0.35}, {0.35, 0.55, 0.70}, {0.65, 0.80, 0.65},
        {0.50, 0.65, 0.50}, {0.25, 0.75, 0.55}, {0.75, 0.70, 0.50}, {0.55, 0.60, 0.25},
        {0.45, 0.85, 0.75}, {0.30, 0.60, 0.45}, {0.70, 0.75, 0.70}, {0.50, 0.55, 0.30},
        {0.40, 0.80, 0.40}, {0.60, 0.65, 0.60}, {0.35, 0.70, 0.60}};
    if (count > WRT_COMPARE_MAX_LIGHTS) count = WRT_COMPARE_MAX_LIGHTS;
    if (count <= 0) return 0;
    wrt_v3 lo = s->bbox_min, hi = s->bbox_max, ext = v3_sub(hi, lo);
    wrt_light base;
    int k = 0;
    if (s->nlights > 0) {
        base = s->lights[0];
        out[k++] = base;
        if (base.type == WRT_LIGHT_DIRECTIONAL) return k; /* a sun has no position to move */
    } else {
        memset(&base, 0, sizeof base);
        base.type = WRT_LIGHT_POINT;
        snprintf(base.name, sizeof base.name, "point");
        base.dir = v3(0, -1, 0);
        base.color[0] = base.color[1] = base.color[2] = 1;
        double d = v3_len(ext);
        base.intensity = (float)(d > 0 ? d * d : 1);
        base.outer_cone = (float)(WRT_PI / 4);
        if (s->nemissive > 0) {
            /* lit by its emissive surfaces alone (docs/emitters.md): one dark light, so
             * that both sides compare the emitters' light and nothing else */
            snprintf(base.name, sizeof base.name, "emitters only");
            base.intensity = 0;
            base.pos = v3_scale(v3_add(lo, hi), 0.5);
            out[k++] = base;
            return k;
        }
    }
    int nfrac = (int)(sizeof frac / sizeof frac[0]);
    for (int i = 0; k < count && i < 4 * nfrac; i++) {
        /* Past the table, the same fractions pulled toward the centre. */
        const double *f = frac[i % nfrac];
        double pull = 1 - 0.2 * (i / nfrac);
        wrt_v3 p = v3(lo.x + (0.5 + pull * (f[0] - 0.5)) * ext.x, lo.y + (0.5 + pull * (f[1] - 0.5)) * ext.y,
                      lo.z + (0.5 + pull * (f[2] - 0.5)) * ext.z);
        if (inside_solid(s, p)) continue;
        out[k] = base;
        out[k].pos = p;
        k++;
    }
    return k;
}

/* ---- the reference ---- */

/* Cell averages of every quad for one light, in two passes (see the file comment). */
static wrt_status ref_cells(wrt_compare_ref *c, wrt_ref *ref, int li, double *mean, double *se) {
    const wrt_scene *s = c->scene;
    const wrt_compare_options *o = &c->opt;
    int n = c->n, nc = n * n, nq = s->nquads;
    const wrt_light *l = &c->lights[li];
    uint64_t seed = o->seed * 1000003u + (uint64_t)li * 7919u;
    double *weight = wrt_xcalloc((size_t)nq, sizeof(double));
    double *m2 = wrt_xmalloc((size_t)nc * 3 * sizeof(double)), *s2 = wrt_xmalloc((size_t)nc * 3 * sizeof(double));
    wrt_status st = WRT_OK;
    double wsum = 0;
    for (int q = 0; q < nq && st == WRT_OK; q++) {
        double *mq = mean + (size_t)q * nc * 3, *sq = se + (size_t)q * nc * 3;
        st = wrt_ref_cell_irradiance(ref, l, 1, q, n, o->pilot, 0, o->threads, seed, NULL, mq, sq);
        double acc = 0; /* area-weighted per-sample variance of the quad's cells */
        for (int k = 0; k < nc * 3; k++) acc += sq[k] * sq[k] * o->pilot;
        weight[q] = sqrt(acc * s->quads[q].area / nc);
        wsum += weight[q];
    }
    long left = o->cell_paths - (long)o->pilot * nc * nq;
    for (int q = 0; q < nq && st == WRT_OK && left > 0; q++) {
        /* 90% by the optimal allocation, 10% spread evenly (a pilot can miss light) */
        double share = 0.1 / nq + (wsum > 0 ? 0.9 * weight[q] / wsum : 0.9 / nq);
        long per_cell = (long)(share * (double)left / nc);
        if (per_cell < 1) continue;
        if (per_cell > 1 << 28) per_cell = 1 << 28;
        double *mq = mean + (size_t)q * nc * 3, *sq = se + (size_t)q * nc * 3;
        st = wrt_ref_cell_irradiance(ref, l, 1, q, n, (int)per_cell, 0, o->threads, seed + 1, NULL, m2, s2);
        double n1 = o->pilot, n2 = (double)per_cell, nt = n1 + n2;
        for (int k = 0; k < nc * 3; k++) {
            mq[k] = (n1 * mq[k] + n2 * m2[k]) / nt;
            sq[k] = sqrt(n1 * n1 * sq[k] * sq[k] + n2 * n2 * s2[k] * s2[k]) / nt;
        }
    }
    free(weight); free(m2); free(s2);
    return st;
}


/* (u,v) of a point x on the quad's plane: the parallelogram's affine inverse, then
 * Newton steps on the bilinear map for a general convex quad. */
static void quad_uv(const wrt_quad *q, wrt_v3 x, double *uo, double *vo) {
    wrt_v3 e1 = v3_sub(q->p[1], q->p[0]), e3 = v3_sub(q->p[3], q->p[0]), d = v3_sub(x, q->p[0]);
    double a = v3_dot(e1, e1), b = v3_dot(e1, e3), cc = v3_dot(e3, e3);
    double r1 = v3_dot(d, e1), r2 = v3_dot(d, e3), det = a * cc - b * b;
    double u = det != 0 ? (r1 * cc - r2 * b) / det : 0.5, v = det != 0 ? (a * r2 - b * r1) / det : 0.5;
    for (int it = 0; it < 8 && !q->parallelogram; it++) {
        wrt_v3 f = v3_sub(wrt_quad_point(q, u, v), x);
        wrt_v3 du = v3_add(v3_scale(e1, 1 - v), v3_scale(v3_sub(q->p[2], q->p[3]), v));
        wrt_v3 dv = v3_add(v3_scale(e3, 1 - u), v3_scale(v3_sub(q->p[2], q->p[1]), u));
        double A = v3_dot(du, du), B = v3_dot(du, dv), C = v3_dot(dv, dv);
        double g1 = v3_dot(f, du), g2 = v3_dot(f, dv), D = A * C - B * B;
        if (D == 0) break;
        u -= (g1 * C - g2 * B) / D;
        v -= (A * g2 - B * g1) / D;
    }
    *uo = u < 0 ? 0 : u > 1 ? 1 : u;
    *vo = v < 0 ? 0 : v > 1 ? 1 : v;
}

/* The camera of the reference's images (verify/reference.c, wrt_ref_render). */
typedef struct cam { wrt_v3 pos, fwd, right, up; } cam;

static int make_cam(const wrt_camera *c, int w, int h, cam *out) {
    wrt_v3 fwd = v3_norm(c->dir), right = v3_norm(v3_cross(fwd, c->up));
    if (!(v3_len(fwd) > 0.5) || !(v3_len(right) > 0.5) || !(c->yfov > 0 && c->yfov < WRT_PI)) return 0;
    wrt_v3 up = v3_cross(right, fwd);
    double th = tan(c->yfov / 2), aspect = c->aspect > 0 ? c->aspect : (double)w / h;
    out->pos = c->pos; out->fwd = fwd;
    out->right = v3_scale(right, th * aspect); out->up = v3_scale(up, th);
    return 1;
}

/* Casts the wavelet image's camera rays once: hits and valid pixels. */
static wrt_status camera_hits(wrt_compare_ref *c) {
    const wrt_scene *s = c->scene;
    int w = c->width, h = c->height, sub = c->opt.sub, ns = sub * sub;
    cam cm;
    if (!make_cam(&s->camera, w, h, &cm)) return wrt_fail(WRT_ERR_INVALID_ARG, "compare: degenerate camera");
    wrt_v3 *corners = malloc((size_t)(s->nquads > 0 ? s->nquads : 1) * 4 * sizeof *corners);
    if (!corners) return wrt_fail(WRT_ERR_NOMEM, "compare: no memory for %d quads", s->nquads);
    for (int i = 0; i < s->nquads; i++)
        for (int k = 0; k < 4; k++) corners[4 * i + k] = s->quads[i].p[k];
    wrt_rt_scene rs;
    wrt_status st = wrt_rt_scene_build(corners, s->nquads, v3(0, 0, 0), NULL, WRT_RT_ROBUST, &rs);
    free(corners);
    if (st != WRT_OK) return st;
    RTCScene sc = rs.scene;
    size_t npix = (size_t)w * h;
    c->hit_quad = wrt_xmalloc(npix * ns * sizeof(int));
    c->hit_uv = wrt_xmalloc(npix * ns * 2 * sizeof(float));
    c->valid = wrt_xmalloc(npix);
    int nvalid = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t p = (size_t)y * w + x;
            int ok = 1;
            for (int k = 0; k < ns; k++) {
                double sx = 2 * (x + (k % sub + 0.5) / sub) / w - 1, sy = 1 - 2 * (y + (k / sub + 0.5) / sub) / h;
                wrt_v3 d = v3_norm(v3_add(cm.fwd, v3_add(v3_scale(cm.right, sx), v3_scale(cm.up, sy))));
                struct RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                struct RTCRayHit rh;
                memset(&rh, 0, sizeof rh);
                rh.ray.org_x = (float)cm.pos.x; rh.ray.org_y = (float)cm.pos.y; rh.ray.org_z = (float)cm.pos.z;
                rh.ray.dir_x = (float)d.x; rh.ray.dir_y = (float)d.y; rh.ray.dir_z = (float)d.z;
                rh.ray.tfar = INFINITY;
                rh.ray.mask = 0xFFFFFFFFu;
                rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rtcIntersect1(sc, &ctx, &rh);
                int qi = -1;
                double u = 0, v = 0;
                if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
                    const wrt_quad *q = &s->quads[rh.hit.primID];
                    if (v3_dot(d, q->n) < 0) {
                        qi = (int)rh.hit.primID;
                        quad_uv(q, v3_mad(cm.pos, d, rh.ray.tfar), &u, &v);
                    }
                }
                if (qi < 0) ok = 0;
                c->hit_quad[p * ns + k] = qi;
                c->hit_uv[(p * ns + k) * 2] = (float)u;
                c->hit_uv[(p * ns + k) * 2 + 1] = (float)v;
            }
            c->valid[p] = (unsigned char)ok;
            nvalid += ok;
        }
    wrt_rt_scene_release(&rs);
    c->info.valid_pixels = nvalid;
    return WRT_OK;
}

/* rmse, floor and debiased error from the three weighted sums (compare.h, "Units"). */
static void rel_errors(double sq_diff, double sq_se, double sq_ref, double *rmse, double *floor_, double *deb) {
    if (!(sq_ref > 0)) { *rmse = *floor_ = *deb = 0; return; }
    *rmse = sqrt(sq_diff / sq_ref);
    *floor_ = sqrt(sq_se / sq_ref);
    *deb = sqrt(fmax(0, sq_diff - sq_se) / sq_ref);
}

wrt_status wrt_compare_ref_create(const wrt_scene *s, const wrt_light *lights, int nlights,
                                  const wrt_compare_options *o, wrt_compare_ref **out) {
    *out = NULL;
    if (!s || s->nquads <= 0) return wrt_fail(WRT_ERR_INVALID_ARG, "compare: scene has no quads");
    if (nlights < 1 || nlights > WRT_COMPARE_MAX_LIGHTS)
        return wrt_fail(WRT_ERR_INVALID_ARG, "compare: %d lights (1..%d)", nlights, WRT_COMPARE_MAX_LIGHTS);
    wrt_compare_ref *c = wrt_xcalloc(1, sizeof *c);
    c->scene = s;
    if (o) c->opt = *o;
    wrt_compare_defaults(&c->opt);
    if (c->opt.cells > 64 || c->opt.sub > 16 || c->opt.width > 4096) {
        free(c);
        return wrt_fail(WRT_ERR_INVALID_ARG, "compare: cells <= 64, sub <= 16, width <= 4096");
    }
    memcpy(c->lights, lights, (size_t)nlights * sizeof *lights);
    c->nlights = nlights;
    c->n = c->opt.cells;
    if (c->opt.width > 0) {
        c->width = c->opt.width;
        double a = s->camera.aspect > 0 ? s->camera.aspect : 1;
        c->height = (int)lround(c->width / a);
        if (c->height < 1) c->height = 1;
    }
    double t0 = wrt_now();
    wrt_ref *ref = wrt_ref_create(s);
    if (!ref) { free(c); return WRT_ERR_INVALID_ARG; }
    wrt_status st = WRT_OK;
    if (c->width > 0) st = camera_hits(c);
    size_t ncell = (size_t)s->nquads * c->n * c->n * 3, npix = (size_t)c->width * c->height * 3;
    double cfl = 0, ifl = 0;
    int nlit = 0;
    for (int li = 0; li < nlights && st == WRT_OK; li++) {
        c->cell_mean[li] = wrt_xmalloc(ncell * sizeof(double));
        c->cell_se[li] = wrt_xmalloc(ncell * sizeof(double));
        c->wcells[li] = wrt_xcalloc(ncell, sizeof(double));
        st = ref_cells(c, ref, li, c->cell_mean[li], c->cell_se[li]);
        if (st != WRT_OK) break;
        double se2 = 0, r2 = 0, rm, fl, db;
        for (int q = 0; q < s->nquads; q++)
            for (int k = 0; k < c->n * c->n * 3; k++) {
                size_t i = (size_t)q * c->n * c->n * 3 + k;
                double w = s->quads[q].area;
                se2 += w * c->cell_se[li][i] * c->cell_se[li][i];
                r2 += w * c->cell_mean[li][i] * c->cell_mean[li][i];
            }
        rel_errors(0, se2, r2, &rm, &fl, &db);
        cfl += fl;
        nlit += r2 > 0;
        if (c->width > 0) {
            c->img[li] = wrt_xmalloc(npix * sizeof(float));
            c->img_se[li] = wrt_xmalloc(npix * sizeof(float));
            c->wimg[li] = wrt_xcalloc(npix, sizeof(float));
            c->wimg_haar[li] = wrt_xcalloc(npix, sizeof(float));
            st = wrt_ref_render(ref, &c->lights[li], 1, &s->camera, c->width, c->height, c->opt.spp, 0,
                                c->opt.threads, c->opt.seed * 1000003u + (uint64_t)li * 7919u + 17,
                                NULL, c->img[li], NULL, c->img_se[li]);
            se2 = r2 = 0;
            for (size_t p = 0; p < (size_t)c->width * c->height; p++) {
                if (!c->valid[p]) { for (int ch = 0; ch < 3; ch++) c->img[li][p * 3 + ch] = 0; continue; }
                for (int ch = 0; ch < 3; ch++) {
                    se2 += (double)c->img_se[li][p * 3 + ch] * c->img_se[li][p * 3 + ch];
                    r2 += (double)c->img[li][p * 3 + ch] * c->img[li][p * 3 + ch];
                }
            }
            rel_errors(0, se2, r2, &rm, &fl, &db);
            ifl += fl;
        }
    }
    c->info.seconds = wrt_now() - t0;
    c->info.rays = wrt_ref_rays(ref);
    wrt_ref_destroy(ref);
    if (st != WRT_OK) { wrt_compare_ref_destroy(c); return st; }
    c->info.cell_paths = c->opt.cell_paths;
    c->info.width = c->width; c->info.height = c->height;
    c->info.spp = c->width > 0 ? c->opt.spp : 0;
    if (nlit == 0) {
        wrt_compare_ref_destroy(c);
        return wrt_fail(WRT_ERR_INVALID_ARG, "compare: no light reaches any surface indirectly");
    }
    c->info.cell_floor = cfl / nlit;
    c->info.image_floor = c->width > 0 ? ifl / nlit : -1;
    *out = c;
    return WRT_OK;
}

void wrt_compare_ref_destroy(wrt_compare_ref *c) {
    if (!c) return;
    for (int i = 0; i < WRT_COMPARE_MAX_LIGHTS; i++) {
        free(c->cell_mean[i]); free(c->cell_se[i]); free(c->img[i]); free(c->img_se[i]);
        free(c->wcells[i]); free(c->wimg[i]); free(c->wimg_haar[i]);
    }
    free(c->hit_quad); free(c->hit_uv); free(c->valid);
    free(c);
}

void wrt_compare_ref_get_info(const wrt_compare_ref *c, wrt_compare_ref_info *info) { *info = c->info; }

/* ---- the wavelet side ---- */

/* A scene light as the runtime library takes it. */
static wrt_runtime_light runtime_light(const wrt_light *l) {
    wrt_runtime_light o;
    memset(&o, 0, sizeof o);
    o.kind = l->type == WRT_LIGHT_SPOT ? WRT_LIGHT_KIND_SPOT
             : l->type == WRT_LIGHT_DIRECTIONAL ? WRT_LIGHT_KIND_DIRECTIONAL : WRT_LIGHT_KIND_POINT;
    o.position[0] = l->pos.x; o.position[1] = l->pos.y; o.position[2] = l->pos.z;
    o.direction[0] = l->dir.x; o.direction[1] = l->dir.y; o.direction[2] = l->dir.z;
    for (int c = 0; c < 3; c++) o.color[c] = l->color[c];
    o.intensity = l->intensity;
    o.inner_cone = l->inner_cone;
    o.outer_cone = l->outer_cone;
    o.range = l->range;
    return o;
}

static wrt_status set_light(wrt_runtime *r, const wrt_light *l) {
    wrt_runtime_light rl = runtime_light(l);
    return wrt_runtime_set_lights(r, &rl, 1, NULL);
}

/* The runtime on the bake's bytes (already mapped and checked by the caller). */
static wrt_status open_runtime(const wrt_gto *g, const wrt_compare_options *o, int haar_blocks, wrt_runtime **r) {
    wrt_runtime_options ro = {.size = sizeof ro};
    ro.threads = o->threads;
    ro.haar_blocks = haar_blocks;
    ro.no_final_gather = o->no_final_gather;
    ro.no_light_splat = o->no_light_splat;
    ro.gather_points = o->gather_points;
    ro.linear_display = o->linear_display;
    return wrt_runtime_open_memory(g->map, g->size, &ro, r, NULL);
}

/* Bilinear lookup of a quad's texture at (u,v), clamped to its own texels. */
static void tex_lookup(const float *tex, int res, double u, double v, double out[3]) {
    double fx = u * res - 0.5, fy = v * res - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    out[0] = out[1] = out[2] = 0;
    for (int k = 0; k < 4; k++) {
        int x = x0 + (k & 1), y = y0 + (k >> 1);
        x = x < 0 ? 0 : x >= res ? res - 1 : x;
        y = y < 0 ? 0 : y >= res ? res - 1 : y;
        double w = ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty);
        for (int c = 0; c < 3; c++) out[c] += w * tex[((size_t)y * res + x) * 3 + c];
    }
}

/* Cell averages of the indirect irradiance as the player shows it (compare.h): on a
 * Lambertian quad the texture (outgoing radiance, base/pi x irradiance) sampled as
 * tex_lookup does, 8 x 8 points a cell, times pi/base; elsewhere (glossy quads, a black
 * channel) the Haar cells already in out. */
static void display_cells(const wrt_gto *g, const wrt_runtime *r, int q, int n, double *out) {
    const wrt_gto_material *mt = &g->materials[g->quads[q].material];
    int res;
    const float *tex = wrt_runtime_quad_texture(r, q, &res);
    if (!mt->lambertian || !tex) return;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double acc[3] = {0, 0, 0};
            for (int b = 0; b < 8; b++)
                for (int a = 0; a < 8; a++) {
                    double v[3];
                    tex_lookup(tex, res, (i + (a + 0.5) / 8) / n, (j + (b + 0.5) / 8) / n, v);
                    for (int c = 0; c < 3; c++) acc[c] += v[c] / 64;
                }
            for (int c = 0; c < 3; c++)
                if (mt->base_color[c] > 0) out[((size_t)j * n + i) * 3 + c] = acc[c] * WRT_PI / mt->base_color[c];
        }
}

/* A textured quad's display (docs/textures.md): the runtime's outgoing radiance is the
 * material's mean albedo x irradiance / pi; the pixel's is its texel's albedo x the same
 * irradiance, so v is scaled by albedo(uv) / mean albedo, channel by channel. */
static void texture_modulate(const wrt_scene *s, int q, double u, double v, double out[3]) {
    const wrt_quad *qq = &s->quads[q];
    const wrt_material *m = &s->materials[qq->material];
    if (m->base_tex <= 0 || m->base_tex > s->ntextures || !qq->has_uv || !m->lambertian) return;
    double st[2];
    float a[3];
    wrt_quad_uv_at(qq, u, v, st);
    wrt_texture_albedo(&s->textures[m->base_tex - 1], st[0], st[1], a);
    for (int c = 0; c < 3; c++) out[c] = m->base_color[c] > 0 ? out[c] * a[c] / m->base_color[c] : 0;
}

/* The image of relighter `r` for light li into `wi` and its errors against the reference. */
static void image_errors(const wrt_compare_ref *c, int li, const wrt_runtime *r, float *wi, double *rmse,
                         double *floor_, double *deb) {
    double d2 = 0, se2 = 0, r2 = 0;
    int ns = c->opt.sub * c->opt.sub;
    for (size_t p = 0; p < (size_t)c->width * c->height; p++) {
        double acc[3] = {0, 0, 0};
        if (c->valid[p]) {
            for (int k = 0; k < ns; k++) {
                int q = c->hit_quad[p * ns + k];
                double v[3];
                int res;
                const float *tex = wrt_runtime_quad_texture(r, q, &res);
                tex_lookup(tex, res, c->hit_uv[(p * ns + k) * 2], c->hit_uv[(p * ns + k) * 2 + 1], v);
                texture_modulate(c->scene, q, c->hit_uv[(p * ns + k) * 2], c->hit_uv[(p * ns + k) * 2 + 1], v);
                for (int ch = 0; ch < 3; ch++) acc[ch] += v[ch] / ns;
            }
            for (int ch = 0; ch < 3; ch++) {
                double ref = c->img[li][p * 3 + ch], e = c->img_se[li][p * 3 + ch];
                d2 += (acc[ch] - ref) * (acc[ch] - ref);
                se2 += e * e;
                r2 += ref * ref;
            }
        }
        for (int ch = 0; ch < 3; ch++) wi[p * 3 + ch] = (float)acc[ch];
    }
    rel_errors(d2, se2, r2, rmse, floor_, deb);
}

/* (u, v) of the point at t along edge e of a quad (reconstruct.h's numbering), d inside. */
static void edge_uv(int e, double t, double d, double *u, double *v) {
    switch (e) {
    case 0: *u = t; *v = d; break;
    case 1: *u = 1 - d; *v = t; break;
    case 2: *u = t; *v = 1 - d; break;
    default: *u = d; *v = t; break;
    }
}

/* Point at t along edge e of quad q (edge_uv's numbering: 0 from p0 to p1, 1 from p1 to
 * p2, 2 from p3 to p2, 3 from p0 to p3). */
static void edge_point(const wrt_gto *g, int q, int e, double t, double out[3]) {
    static const int ends[4][2] = {{0, 1}, {1, 2}, {3, 2}, {0, 3}};
    const double *a = g->quads[q].p[ends[e][0]], *b = g->quads[q].p[ends[e][1]];
    for (int k = 0; k < 3; k++) out[k] = a[k] + t * (b[k] - a[k]);
}

static double dist3(const double a[3], const double b[3]) {
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* The quads' corners by grid cell (cells of 4 x the seams' tolerance; a 64-bit hash of
 * the cell, sorted with the quad): the candidates of shared_edge, so that it reads the
 * quads with a corner near the edge's end instead of every quad (O(N^2): about 10
 * minutes at 100,256 atrium elements). */
typedef struct corner_grid { size_t n; uint64_t *key; int *quad; double h; } corner_grid;

static uint64_t cell_key(long long ix, long long iy, long long iz) {
    uint64_t k = (uint64_t)ix * 0x9E3779B97F4A7C15ull ^ (uint64_t)iy * 0xC2B2AE3D27D4EB4Full ^ (uint64_t)iz * 0x165667B19E3779F9ull;
    return k ^ (k >> 29);
}

static long long cell_of(double x, double h) { return (long long)floor(x / h); }

typedef struct { uint64_t key; int quad; } corner_entry;

static int corner_cmp(const void *a, const void *b) {
    const corner_entry *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->quad > y->quad) - (x->quad < y->quad);
}

static int int_cmp(const void *a, const void *b) { return (*(const int *)a > *(const int *)b) - (*(const int *)a < *(const int *)b); }

static int corner_grid_make(const wrt_gto *g, double tol, corner_grid *cg) {
    cg->n = 4 * (size_t)g->nquads;
    cg->h = 4 * tol;
    corner_entry *e = malloc((cg->n ? cg->n : 1) * sizeof *e);
    cg->key = malloc((cg->n ? cg->n : 1) * sizeof *cg->key);
    cg->quad = malloc((cg->n ? cg->n : 1) * sizeof *cg->quad);
    if (!e || !cg->key || !cg->quad) { free(e); free(cg->key); free(cg->quad); return -1; }
    for (uint32_t q = 0; q < g->nquads; q++)
        for (int k = 0; k < 4; k++) {
            const double *p = g->quads[q].p[k];
            e[4 * q + k] = (corner_entry){cell_key(cell_of(p[0], cg->h), cell_of(p[1], cg->h), cell_of(p[2], cg->h)), (int)q};
        }
    qsort(e, cg->n, sizeof *e, corner_cmp);
    for (size_t i = 0; i < cg->n; i++) { cg->key[i] = e[i].key; cg->quad[i] = e[i].quad; }
    free(e);
    return 0;
}

/* The quads with a corner in the 27 cells around point a, ascending, once each, into
 * out; the count, or SIZE_MAX where there were more than cap corners. */
static size_t corner_near(const corner_grid *cg, const double a[3], int *out, size_t cap) {
    size_t m = 0;
    long long cx = cell_of(a[0], cg->h), cy = cell_of(a[1], cg->h), cz = cell_of(a[2], cg->h);
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                uint64_t k = cell_key(cx + dx, cy + dy, cz + dz);
                size_t lo = 0, hi = cg->n;
                while (lo < hi) {
                    size_t mid = lo + (hi - lo) / 2;
                    if (cg->key[mid] < k) lo = mid + 1;
                    else hi = mid;
                }
                for (; lo < cg->n && cg->key[lo] == k; lo++) {
                    if (m == cap) return SIZE_MAX;
                    out[m++] = cg->quad[lo];
                }
            }
    qsort(out, m, sizeof *out, int_cmp);
    size_t u = 0;
    for (size_t i = 0; i < m; i++)
        if (!u || out[i] != out[u - 1]) out[u++] = out[i];
    return u;
}

/* Quad q's neighbour across edge e, found here from the file's geometry alone (not from the
 * display's own adjacency, so that a neighbour the display misses still counts as a seam):
 * a quad of the same material, facing the same way in the same plane, whose edge has the
 * same two ends: the first in the quads' order, as a scan of every quad finds it (the
 * candidates, those with a corner near the edge's first end, in that order). -1 if none;
 * *nedge its edge, *flip 1 if it runs the other way. */
static int shared_edge(const wrt_gto *g, const corner_grid *cg, int q, int e, double tol, int *nedge, int *flip) {
    double a[3], b[3], c[3], d[3];
    edge_point(g, q, e, 0, a);
    edge_point(g, q, e, 1, b);
    const float *nq = g->quads[q].n;
    int cand[256];
    size_t nc = corner_near(cg, a, cand, sizeof cand / sizeof *cand);
    int scan = nc == SIZE_MAX; /* more corners there than cand holds: every quad, in order */
    for (size_t i = 0; i < (scan ? g->nquads : nc); i++) {
        int o = scan ? (int)i : cand[i];
        if (o == q || g->quads[o].material != g->quads[q].material) continue;
        const float *no = g->quads[o].n;
        if (nq[0] * no[0] + nq[1] * no[1] + nq[2] * no[2] < 1 - 1e-5) continue;
        for (int f = 0; f < 4; f++) {
            edge_point(g, o, f, 0, c);
            edge_point(g, o, f, 1, d);
            if (dist3(a, c) < tol && dist3(b, d) < tol) { *nedge = f; *flip = 0; return o; }
            if (dist3(a, d) < tol && dist3(b, c) < tol) { *nedge = f; *flip = 1; return o; }
        }
    }
    return -1;
}

/* Seams (compare.h): over every edge two coplanar quads of one material share, 32 points
 * along it, the display's jump between the two quads a quarter texel inside each, and the
 * jump across the parallel line through the quad's middle at the same distance; each
 * summed over RGB and divided by the sum of the values there. */
static void seam_jumps(const wrt_gto *g, const wrt_runtime *r, double tol, double *across, double *inside) {
    double ja = 0, ji = 0, sa = 0, si = 0;
    corner_grid cg;
    *across = *inside = 0;
    if (corner_grid_make(g, tol, &cg) != 0) return;
    for (int q = 0; q < (int)g->nquads; q++)
        for (int e = 0; e < 4; e++) {
            int ne = 0, fl = 0, o = shared_edge(g, &cg, q, e, tol, &ne, &fl);
            if (o < q) continue; /* none, or counted from the other side */
            int rq, ro;
            const float *tq = wrt_runtime_quad_texture(r, q, &rq), *to = wrt_runtime_quad_texture(r, o, &ro);
            double dq = 0.25 / rq, dn = 0.25 / ro;
            for (int k = 0; k < 32; k++) {
                double t = (k + 0.5) / 32, u, v, a[3], b[3], c0[3], c1[3];
                edge_uv(e, t, dq, &u, &v);
                tex_lookup(tq, rq, u, v, a);
                edge_uv(ne, fl ? 1 - t : t, dn, &u, &v);
                tex_lookup(to, ro, u, v, b);
                edge_uv(e, t, 0.5 - dq, &u, &v);
                tex_lookup(tq, rq, u, v, c0);
                edge_uv(e, t, 0.5 + dq, &u, &v);
                tex_lookup(tq, rq, u, v, c1);
                for (int c = 0; c < 3; c++) {
                    ja += fabs(a[c] - b[c]); sa += (a[c] + b[c]) / 2;
                    ji += fabs(c0[c] - c1[c]); si += (c0[c] + c1[c]) / 2;
                }
            }
        }
    free(cg.key); free(cg.quad);
    *across = sa > 0 ? ja / sa : 0;
    *inside = si > 0 ? ji / si : 0;
}

/* Adds quad q's cells (w: the bake's n x n RGB values) against the reference's for light
 * li to the area-weighted sums of squared differences, of the reference's variance and of
 * its squares; sw and sr (may be NULL) get the bake's and the reference's sums. */
static void add_cell_errors(const wrt_compare_ref *c, int li, int q, double a, const double *w, double *d2,
                            double *se2, double *r2, double *sw, double *sr) {
    int nc3 = c->n * c->n * 3;
    const double *m = c->cell_mean[li] + (size_t)q * nc3, *e = c->cell_se[li] + (size_t)q * nc3;
    for (int k = 0; k < nc3; k++) {
        *d2 += a * (w[k] - m[k]) * (w[k] - m[k]);
        *se2 += a * e[k] * e[k];
        *r2 += a * m[k] * m[k];
        if (sw) { *sw += a * w[k]; *sr += a * m[k]; }
    }
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

wrt_status wrt_compare_gto(const wrt_compare_ref *cc, const wrt_gto *g, wrt_compare_result *out) {
    wrt_compare_ref *c = (wrt_compare_ref *)cc; /* keeps the last comparison's images */
    const wrt_scene *s = c->scene;
    memset(out, 0, sizeof *out);
    double t0 = wrt_now();
    if ((int)g->nquads != s->nquads)
        return wrt_fail(WRT_ERR_INVALID_ARG, "compare: the bake has %u quads, the scene %d: not baked from it",
                        g->nquads, s->nquads);
    double size = v3_len(v3_sub(s->bbox_max, s->bbox_min));
    for (int q = 0; q < s->nquads; q++)
        for (int k = 0; k < 4; k++) {
            const double *p = g->quads[q].p[k];
            wrt_v3 d = v3_sub(v3(p[0], p[1], p[2]), s->quads[q].p[k]);
            if (!(v3_len(d) <= 1e-6 * (size > 0 ? size : 1)))
                return wrt_fail(WRT_ERR_INVALID_ARG, "compare: quad %d of the bake differs from the scene's: not baked from it", q);
        }
    wrt_runtime *r, *rh; /* rh: the same bake shown as Haar blocks, for the before/after figures */
    wrt_status st = open_runtime(g, &c->opt, 0, &r);
    if (st != WRT_OK) return st;
    st = open_runtime(g, &c->opt, 1, &rh);
    if (st != WRT_OK) { wrt_runtime_close(r); return st; }
    double eye[3] = {s->camera.pos.x, s->camera.pos.y, s->camera.pos.z};
    wrt_runtime_set_eye(r, eye, NULL);
    wrt_runtime_set_eye(rh, eye, NULL);
    int n = c->n, nc = n * n;
    out->nlights = c->nlights;
    int nlit = 0;
    for (int li = 0; li < c->nlights; li++) {
        if ((st = set_light(r, &c->lights[li])) || (st = wrt_runtime_update(r, NULL, NULL)) ||
            (st = set_light(rh, &c->lights[li])) || (st = wrt_runtime_update(rh, NULL, NULL))) {
            wrt_runtime_close(r);
            wrt_runtime_close(rh);
            return st;
        }
        wrt_compare_light_result *lr = &out->light[li];
        double d2 = 0, se2 = 0, r2 = 0, sw = 0, sr = 0;
        for (int q = 0; q < s->nquads; q++) {
            double *w = c->wcells[li] + (size_t)q * nc * 3;
            wrt_runtime_quad_cells(r, q, n, w, NULL);
            add_cell_errors(c, li, q, s->quads[q].area, w, &d2, &se2, &r2, &sw, &sr);
        }
        rel_errors(d2, se2, r2, &lr->cell_rmse, &lr->cell_floor, &lr->cell_debiased);
        /* The same cells of the smooth display (Lambertian quads; the Haar cells elsewhere). */
        d2 = se2 = r2 = 0;
        double *w = wrt_xmalloc((size_t)nc * 3 * sizeof(double));
        for (int q = 0; q < s->nquads; q++) {
            memcpy(w, c->wcells[li] + (size_t)q * nc * 3, (size_t)nc * 3 * sizeof(double));
            display_cells(g, r, q, n, w);
            add_cell_errors(c, li, q, s->quads[q].area, w, &d2, &se2, &r2, NULL, NULL);
        }
        free(w);
        double fl;
        rel_errors(d2, se2, r2, &lr->cell_rmse_smooth, &fl, &lr->cell_debiased_smooth);
        lr->cell_ratio = sr > 0 ? sw / sr : 0;
        lr->image_rmse = lr->image_floor = lr->image_debiased = -1;
        lr->image_rmse_haar = lr->image_debiased_haar = -1;
        if (c->width > 0) {
            image_errors(c, li, r, c->wimg[li], &lr->image_rmse, &lr->image_floor, &lr->image_debiased);
            image_errors(c, li, rh, c->wimg_haar[li], &lr->image_rmse_haar, &fl, &lr->image_debiased_haar);
        }
        seam_jumps(g, r, 1e-6 * (size > 0 ? size : 1), &lr->seam_across, &lr->seam_inside);
        seam_jumps(g, rh, 1e-6 * (size > 0 ? size : 1), &lr->seam_across_haar, &lr->seam_inside_haar);
        if (lr->cell_rmse == 0 && lr->cell_floor == 0) continue; /* no indirect light at all */
        wrt_compare_light_result *m = &out->mean;
        m->cell_rmse += lr->cell_rmse;
        m->cell_floor += lr->cell_floor;
        m->cell_debiased += lr->cell_debiased;
        m->image_rmse += lr->image_rmse;
        m->image_floor += lr->image_floor;
        m->image_debiased += lr->image_debiased;
        m->cell_ratio += lr->cell_ratio;
        m->cell_rmse_smooth += lr->cell_rmse_smooth;
        m->cell_debiased_smooth += lr->cell_debiased_smooth;
        m->image_rmse_haar += lr->image_rmse_haar;
        m->image_debiased_haar += lr->image_debiased_haar;
        m->seam_across += lr->seam_across; m->seam_inside += lr->seam_inside;
        m->seam_across_haar += lr->seam_across_haar; m->seam_inside_haar += lr->seam_inside_haar;
        nlit++;
    }
    if (nlit > 0) {
        wrt_compare_light_result *m = &out->mean;
        m->cell_rmse /= nlit; m->cell_floor /= nlit; m->cell_debiased /= nlit;
        m->image_rmse /= nlit; m->image_floor /= nlit; m->image_debiased /= nlit;
        m->cell_ratio /= nlit;
        m->cell_rmse_smooth /= nlit; m->cell_debiased_smooth /= nlit;
        m->image_rmse_haar /= nlit; m->image_debiased_haar /= nlit;
        m->seam_across /= nlit; m->seam_inside /= nlit; m->seam_across_haar /= nlit; m->seam_inside_haar /= nlit;
    }
    wrt_runtime_close(r);
    wrt_runtime_close(rh);
    st = wrt_compare_bench(g, &c->lights[0], eye, c->opt.bench_updates, &c->opt, out);
    out->seconds = wrt_now() - t0;
    return st;
}

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* The timed updates: `updates` moves around a circle (angle a), each followed by an
 * update; wall and CPU milliseconds of each, sorted. */
typedef struct bench_ctx { wrt_light light; wrt_v3 p0, d0; double rad, eye[3]; } bench_ctx;
static void bench_light(wrt_runtime *r, double a, bench_ctx *c) {
    if (c->light.type == WRT_LIGHT_DIRECTIONAL) { /* a sun turns about +Y, by 0.1 a radians */
        double t = 0.1 * a, ct = cos(t), st = sin(t);
        c->light.dir = v3(ct * c->d0.x + st * c->d0.z, c->d0.y, -st * c->d0.x + ct * c->d0.z);
    } else
        c->light.pos = v3(c->p0.x + c->rad * cos(a), c->p0.y, c->p0.z + c->rad * sin(a));
    set_light(r, &c->light);
}
static void bench_eye(wrt_runtime *r, double a, bench_ctx *c) {
    double e[3] = {c->eye[0] + c->rad * cos(a), c->eye[1], c->eye[2] + c->rad * sin(a)};
    wrt_runtime_set_eye(r, e, NULL);
}
static void time_circle(wrt_runtime *r, int updates, void (*move)(wrt_runtime *, double, bench_ctx *), bench_ctx *c,
                        double *ms, double *cpu) {
    for (int k = 0; k < updates; k++) {
        double t1 = wrt_now(), c1 = cpu_now();
        move(r, 2 * WRT_PI * (k + 1) / updates, c);
        wrt_runtime_update(r, NULL, NULL);
        ms[k] = (wrt_now() - t1) * 1e3;
        cpu[k] = (cpu_now() - c1) * 1e3;
    }
    qsort(ms, (size_t)updates, sizeof(double), cmp_double);
    qsort(cpu, (size_t)updates, sizeof(double), cmp_double);
}

wrt_status wrt_compare_bench(const wrt_gto *g, const wrt_light *light, const double eye[3], int updates,
                             const wrt_compare_options *o, wrt_compare_result *out) {
    if (updates < 1) return wrt_fail(WRT_ERR_INVALID_ARG, "compare: %d timed updates", updates);
    wrt_runtime *r;
    wrt_status st = open_runtime(g, o, 0, &r);
    if (st != WRT_OK) return st;
    if ((st = wrt_runtime_set_eye(r, eye, NULL)) || (st = set_light(r, light)) || (st = wrt_runtime_update(r, NULL, NULL))) {
        wrt_runtime_close(r);
        return st;
    }
    wrt_v3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
    for (uint32_t q = 0; q < g->nquads; q++)
        for (int k = 0; k < 4; k++) {
            const double *p = g->quads[q].p[k];
            lo = v3(fmin(lo.x, p[0]), fmin(lo.y, p[1]), fmin(lo.z, p[2]));
            hi = v3(fmax(hi.x, p[0]), fmax(hi.y, p[1]), fmax(hi.z, p[2]));
        }
    double *ms = wrt_xmalloc((size_t)updates * sizeof(double)), *cpu = wrt_xmalloc((size_t)updates * sizeof(double));
    double rad = 0.02 * v3_len(v3_sub(hi, lo));
    bench_ctx bc = {.light = *light, .p0 = light->pos, .d0 = light->dir, .rad = rad, .eye = {eye[0], eye[1], eye[2]}};
    time_circle(r, updates, bench_light, &bc, ms, cpu);
    out->ms_update_median = ms[updates / 2];
    out->ms_update_min = ms[0];
    out->ms_update_max = ms[updates - 1];
    out->cpu_ms_update_median = cpu[updates / 2];
    time_circle(r, updates, bench_eye, &bc, ms, cpu); /* camera moves, the light where it started */
    out->ms_eye_median = ms[updates / 2];
    out->cpu_ms_eye_median = cpu[updates / 2];
    free(ms); free(cpu);
    wrt_runtime_close(r);
    return WRT_OK;
}
const float *wrt_compare_image(const wrt_compare_ref *c, int light, int wavelet) {
    if (light < 0 || light >= c->nlights || c->width <= 0) return NULL;
    return wavelet == 2 ? c->wimg_haar[light] : wavelet ? c->wimg[light] : c->img[light];
}

const double *wrt_compare_cells(const wrt_compare_ref *c, int light, int q, int wavelet, const double **se) {
    if (light < 0 || light >= c->nlights || q < 0 || q >= c->scene->nquads) return NULL;
    size_t off = (size_t)q * c->n * c->n * 3;
    if (se) *se = wavelet ? NULL : c->cell_se[light] + off;
    return (wavelet ? c->wcells[light] : c->cell_mean[light]) + off;
}
