/* wrt_runtime.c: the public runtime API (include/wrt.h) over the relighting core
 * (relight.h) and the .gto reader (formats/gto.h). Keeps no global state. */
#include "../include/wrt.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/basis.h"
#include "relight.h"

#define MAX_LIGHTS 64

struct wrt_runtime {
    wrt_allocator al;
    wrt_gto g;
    wrt_relight *rl;
    wrt_light lights[MAX_LIGHTS];
    float scales[MAX_LIGHTS];
    int nlights;
    wrt_relight_timings tm;
};

static void *sys_alloc(size_t n, void *u) { (void)u; return malloc(n); }
static void sys_free(void *p, void *u) { (void)u; free(p); }

static wrt_status fail(wrt_error *err, wrt_status s) {
    if (err) {
        err->status = s;
        snprintf(err->message, sizeof err->message, "%s", s ? wrt_last_error() : "");
    }
    return s;
}

void wrt_runtime_defaults(wrt_runtime_options *o) {
    if (o->threads < 0) o->threads = 0;
    if (o->max_tex_res <= 0) o->max_tex_res = 64;
    if (!o->allocator.alloc || !o->allocator.free) {
        o->allocator.alloc = sys_alloc;
        o->allocator.free = sys_free;
        o->allocator.user = NULL;
    }
}

static wrt_status open_common(const void *data, size_t size, const char *path, const wrt_runtime_options *opt,
                              wrt_runtime **out, wrt_error *err) {
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open: out is NULL"));
    *out = NULL;
    wrt_runtime_options o = {0};
    if (opt) o = *opt;
    if (o.max_tex_res < 0 || (o.max_tex_res & (o.max_tex_res - 1)) || o.max_tex_res > 1024 || o.threads > 64 ||
        o.proj_level < 0 || o.proj_level > WRT_MAX_SLEVEL)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open: options out of range (max_tex_res %d, "
                                  "threads %d, proj_level %d)", o.max_tex_res, o.threads, o.proj_level));
    wrt_runtime_defaults(&o);
    wrt_runtime *rt = o.allocator.alloc(sizeof *rt, o.allocator.user);
    if (!rt) return fail(err, wrt_fail(WRT_ERR_NOMEM, "wrt_runtime_open: out of memory"));
    memset(rt, 0, sizeof *rt);
    rt->al = o.allocator;
    wrt_status s = path ? wrt_gto_open(path, &rt->g) : wrt_gto_open_memory(data, size, &rt->g);
    if (s) { rt->al.free(rt, rt->al.user); return fail(err, s); }
    wrt_relight_options ro = {.proj_level = o.proj_level, .max_tex_res = o.max_tex_res, .threads = o.threads,
                              .alloc = o.allocator.alloc, .free = o.allocator.free, .alloc_user = o.allocator.user,
                              .haar_blocks = o.haar_blocks, .parallel_for = o.parallel_for,
                              .parallel_user = o.parallel_user, .log = o.log, .log_user = o.log_user};
    if ((s = wrt_relight_create(&rt->g, &ro, &rt->rl))) {
        wrt_gto_close(&rt->g);
        rt->al.free(rt, rt->al.user);
        return fail(err, s);
    }
    *out = rt;
    return WRT_OK;
}

wrt_status wrt_runtime_open_file(const char *path, const wrt_runtime_options *opt, wrt_runtime **out, wrt_error *err) {
    if (!path) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open_file: path is NULL"));
    return open_common(NULL, 0, path, opt, out, err);
}

wrt_status wrt_runtime_open_memory(const void *data, size_t size, const wrt_runtime_options *opt, wrt_runtime **out,
                                   wrt_error *err) {
    if (!data || ((uintptr_t)data & 7))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open_memory: data is NULL or not 8-byte aligned"));
    return open_common(data, size, NULL, opt, out, err);
}

void wrt_runtime_close(wrt_runtime *rt) {
    if (!rt) return;
    wrt_relight_destroy(rt->rl);
    wrt_gto_close(&rt->g);
    rt->al.free(rt, rt->al.user);
}

int wrt_runtime_light_count(const wrt_runtime *rt) { return (int)rt->g.nlights; }

wrt_status wrt_runtime_get_light(const wrt_runtime *rt, int i, wrt_runtime_light *out, wrt_error *err) {
    if (i < 0 || i >= (int)rt->g.nlights)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_light: no light %d (the file has %u)", i,
                                  rt->g.nlights));
    const wrt_gto_light *l = &rt->g.lights[i];
    memset(out, 0, sizeof *out);
    out->kind = l->type == WRT_LIGHT_SPOT ? WRT_LIGHT_KIND_SPOT
                : l->type == WRT_LIGHT_DIRECTIONAL ? WRT_LIGHT_KIND_DIRECTIONAL : WRT_LIGHT_KIND_POINT;
    for (int c = 0; c < 3; c++) {
        out->position[c] = l->pos[c];
        out->direction[c] = l->dir[c];
        out->color[c] = l->color[c];
    }
    out->intensity = l->intensity;
    out->inner_cone = l->inner_cone;
    out->outer_cone = l->outer_cone;
    return WRT_OK;
}

wrt_status wrt_runtime_set_lights(wrt_runtime *rt, const wrt_runtime_light *in, int n, wrt_error *err) {
    if (n < 0 || n > MAX_LIGHTS || (n && !in))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_lights: %d lights (0..%d)", n, MAX_LIGHTS));
    wrt_light ls[MAX_LIGHTS];
    float sc[MAX_LIGHTS];
    for (int i = 0; i < n; i++) {
        const wrt_runtime_light *l = &in[i];
        wrt_v3 p = v3(l->position[0], l->position[1], l->position[2]);
        wrt_v3 d = v3(l->direction[0], l->direction[1], l->direction[2]);
        float outer = l->outer_cone > 0 ? l->outer_cone : (float)(WRT_PI / 4);
        int spot = l->kind == WRT_LIGHT_KIND_SPOT, sun = l->kind == WRT_LIGHT_KIND_DIRECTIONAL;
        if ((l->kind != WRT_LIGHT_KIND_POINT && !spot && !sun) || (sun && (!v3_finite(d) || v3_len(d) == 0)) ||
            (!sun && !v3_finite(p)) || !isfinite(l->intensity) ||
            l->intensity < 0 || !isfinite(l->color[0] + l->color[1] + l->color[2]) ||
            l->color[0] < 0 || l->color[1] < 0 || l->color[2] < 0 ||
            (spot && (!v3_finite(d) || v3_len(d) == 0 || !(outer <= WRT_PI / 2) || !(l->inner_cone >= 0) ||
                      !(l->inner_cone < outer))))
            return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_lights: light %d is invalid (kind, a "
                                      "non-finite or negative value, or a spot's axis or cones)", i));
        memset(&ls[i], 0, sizeof ls[i]);
        ls[i].type = spot ? WRT_LIGHT_SPOT : sun ? WRT_LIGHT_DIRECTIONAL : WRT_LIGHT_POINT;
        ls[i].pos = sun ? v3(0, 0, 0) : p;
        ls[i].dir = spot || sun ? v3_norm(d) : v3(0, 0, -1);
        int black = l->color[0] == 0 && l->color[1] == 0 && l->color[2] == 0;
        for (int c = 0; c < 3; c++) ls[i].color[c] = black ? 1.0f : l->color[c];
        ls[i].intensity = l->intensity;
        ls[i].inner_cone = spot ? l->inner_cone : 0;
        ls[i].outer_cone = spot ? outer : (float)(WRT_PI / 4);
        sc[i] = l->off ? 0.0f : 1.0f;
    }
    wrt_status s = wrt_relight_set_lights(rt->rl, ls, sc, n);
    if (s) return fail(err, s);
    memcpy(rt->lights, ls, (size_t)n * sizeof *ls);
    memcpy(rt->scales, sc, (size_t)n * sizeof *sc);
    rt->nlights = n;
    return WRT_OK;
}

wrt_status wrt_runtime_set_eye(wrt_runtime *rt, const double eye[3], wrt_error *err) {
    if (!eye || !isfinite(eye[0]) || !isfinite(eye[1]) || !isfinite(eye[2]))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_eye: not a finite position"));
    wrt_relight_set_eye(rt->rl, eye);
    return WRT_OK;
}

wrt_status wrt_runtime_update(wrt_runtime *rt, int *changed, wrt_error *err) {
    int n = wrt_relight_update(rt->rl, &rt->tm);
    if (changed) *changed = n > 0 ? n : 0;
    return n < 0 ? fail(err, WRT_ERR_NOMEM) : WRT_OK;
}

int wrt_runtime_quad_count(const wrt_runtime *rt) { return (int)rt->g.nquads; }

void wrt_runtime_quad_corners(const wrt_runtime *rt, int q, double p[4][3]) {
    memcpy(p, rt->g.quads[q].p, sizeof(double) * 12);
}

const float *wrt_runtime_quad_texture(const wrt_runtime *rt, int q, int *res) {
    if (res) *res = wrt_relight_tex_res(rt->rl, q);
    return wrt_relight_tex(rt->rl, q);
}

static wrt_quad quad_of(const wrt_gto_quad *gq) {
    wrt_quad wq;
    memset(&wq, 0, sizeof wq);
    for (int i = 0; i < 4; i++) wq.p[i] = v3(gq->p[i][0], gq->p[i][1], gq->p[i][2]);
    wq.area = gq->area;
    wq.parallelogram = (gq->flags & 1) != 0;
    return wq;
}

void wrt_runtime_quad_mean(const wrt_runtime *rt, int q, float rgb[3]) {
    int res = wrt_relight_tex_res(rt->rl, q);
    const float *tex = wrt_relight_tex(rt->rl, q);
    wrt_quad wq = quad_of(&rt->g.quads[q]);
    double acc[3] = {0, 0, 0}, wsum = 0;
    for (int j = 0; j < res; j++)
        for (int i = 0; i < res; i++) {
            double w = wq.parallelogram ? 1 : wrt_quad_jacobian(&wq, (i + 0.5) / res, (j + 0.5) / res);
            for (int c = 0; c < 3; c++) acc[c] += w * tex[((size_t)j * res + i) * 3 + c];
            wsum += w;
        }
    for (int c = 0; c < 3; c++) rgb[c] = wsum > 0 ? (float)(acc[c] / wsum) : 0.0f;
}

/* Each Haar function's exact average over each cell it overlaps, times sqrt(pi/J) (exact
 * for a parallelogram; for a general quad its cell mean by 8 x 8 midpoints, an
 * approximation since J varies within the cell). */
wrt_status wrt_runtime_quad_cells(const wrt_runtime *rt, int q, int n, double *out, wrt_error *err) {
    if (q < 0 || q >= (int)rt->g.nquads || n < 1 || n > 1024 || !out)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_quad_cells: quad %d, n %d", q, n));
    const wrt_gto *g = &rt->g;
    const float *X = wrt_relight_X(rt->rl);
    const wrt_gto_quad *gq = &g->quads[q];
    memset(out, 0, (size_t)n * n * 3 * sizeof(double));
    for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++) {
        wrt_fkey k = g->fkeys[f];
        if (!wrt_fkey_angular_root(k)) continue;
        const float *x = X + (size_t)f * 3;
        if (x[0] == 0 && x[1] == 0 && x[2] == 0) continue;
        wrt_node nd = wrt_fkey_snode(k);
        int type = wrt_fkey_stype(k);
        double sz = wrt_node_size(nd), h = sz / 2, val = ldexp(1.0, nd.level);
        for (int cy = 0; cy < 2; cy++)
            for (int cx = 0; cx < 2; cx++) {
                double r0 = wrt_node_x0(nd) + cx * h, s0 = wrt_node_y0(nd) + cy * h;
                double sgn = val * wrt_haar_sign(type, cx, cy);
                int i0 = (int)floor(r0 * n), i1 = (int)ceil((r0 + h) * n), j0 = (int)floor(s0 * n),
                    j1 = (int)ceil((s0 + h) * n);
                if (i1 > n) i1 = n;
                if (j1 > n) j1 = n;
                for (int j = j0; j < j1; j++)
                    for (int i = i0; i < i1; i++) {
                        double ox = fmin(r0 + h, (i + 1.0) / n) - fmax(r0, (double)i / n);
                        double oy = fmin(s0 + h, (j + 1.0) / n) - fmax(s0, (double)j / n);
                        if (ox <= 0 || oy <= 0) continue;
                        double a = sgn * ox * oy * n * n;
                        for (int c = 0; c < 3; c++) out[((size_t)j * n + i) * 3 + c] += a * x[c];
                    }
            }
    }
    wrt_quad wq = quad_of(gq);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double fac = 0;
            if (wq.parallelogram) fac = sqrt(WRT_PI / wq.area);
            else {
                for (int b = 0; b < 8; b++)
                    for (int a = 0; a < 8; a++)
                        fac += sqrt(WRT_PI / wrt_quad_jacobian(&wq, (i + (a + 0.5) / 8) / n, (j + (b + 0.5) / 8) / n));
                fac /= 64;
            }
            for (int c = 0; c < 3; c++) out[((size_t)j * n + i) * 3 + c] *= fac;
        }
    return WRT_OK;
}

void wrt_runtime_quad_irradiance(const wrt_runtime *rt, int q, double direct[3], double indirect[3]) {
    wrt_relight_quad_irradiance(rt->rl, q, direct, indirect);
}

void wrt_runtime_timings(const wrt_runtime *rt, double ms[4]) {
    ms[0] = rt->tm.projection; ms[1] = rt->tm.multiply; ms[2] = rt->tm.brdf; ms[3] = rt->tm.synthesis;
}
