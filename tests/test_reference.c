/* test_reference.c: the reference path tracer (verify/reference.c) against closed forms
 * and against a numerical integral computed here: the direct irradiance of a point
 * light over a plane (I h / (h^2 + x^2)^(3/2)), spot and range falloff, shadows and
 * one-sided surfaces, the furnace (a closed cube of albedo rho around a point light
 * receives the indirect flux 4 pi I rho / (1 - rho)), a single bounce between two
 * squares by a dense midpoint rule, a rendered pixel, and thread-count independence.
 * Scenes are built in memory. */
#include "test.h"
#include "verify/reference.h"

#include <stdlib.h>

/* Builds a quad from a corner and two edges; normal e1 x e2 (the glTF front side). */
static wrt_quad make_quad(wrt_v3 o, wrt_v3 e1, wrt_v3 e2, int material) {
    wrt_quad q;
    memset(&q, 0, sizeof q);
    q.p[0] = o;
    q.p[1] = v3_add(o, e1);
    q.p[2] = v3_add(v3_add(o, e1), e2);
    q.p[3] = v3_add(o, e2);
    wrt_v3 c = v3_cross(e1, e2);
    q.area = v3_len(c);
    q.n = v3_norm(c);
    q.t = v3_norm(e1);
    q.b = v3_cross(q.n, q.t);
    q.parallelogram = 1;
    q.material = material;
    return q;
}

static wrt_material diffuse(double rho) {
    wrt_material m;
    memset(&m, 0, sizeof m);
    m.base_color[0] = m.base_color[1] = m.base_color[2] = (float)rho;
    m.metallic = 0;
    m.roughness = 1;
    m.lambertian = 1;
    return m;
}

static wrt_light point_light(wrt_v3 pos, double intensity) {
    wrt_light l;
    memset(&l, 0, sizeof l);
    l.type = WRT_LIGHT_POINT;
    l.pos = pos;
    l.dir = v3(0, 0, -1);
    l.color[0] = l.color[1] = l.color[2] = 1;
    l.intensity = (float)intensity;
    l.outer_cone = (float)(WRT_PI / 4);
    return l;
}

static wrt_scene make_scene(wrt_quad *quads, int nq, wrt_material *mats, int nm) {
    wrt_scene s;
    memset(&s, 0, sizeof s);
    s.quads = quads; s.nquads = nq;
    s.materials = mats; s.nmaterials = nm;
    return s;
}

/* (a) Direct irradiance over a large plane, with a spot, a range window, a shadow
 * and the back side: all deterministic, so 1e-6 relative. */
static void test_direct_closed_form(void) {
    double L = 100;
    wrt_quad quads[2];
    quads[0] = make_quad(v3(-L, -L, 0), v3(2 * L, 0, 0), v3(0, 2 * L, 0), 0);
    /* a small blocker at (10, 10, 1), halfway from (20, 20, 0) to the light */
    quads[1] = make_quad(v3(9, 9, 1), v3(2, 0, 0), v3(0, 2, 0), 0);
    wrt_material mats[1] = {diffuse(0.5)};
    wrt_scene s = make_scene(quads, 2, mats, 1);
    wrt_ref *r = wrt_ref_create(&s);
    CHECK(r != NULL, "create: %s", wrt_last_error());
    if (!r) return;
    double h = 2, I = 10;
    wrt_light l = point_light(v3(0, 0, h), I);
    l.color[1] = 0.5f;
    double xs[6] = {0, 0.5, 1, 3, 10, 60};
    wrt_v3 pts[7];
    int qs[7] = {0, 0, 0, 0, 0, 0, 0};
    for (int i = 0; i < 6; i++) pts[i] = v3(xs[i] * 0.6, xs[i] * 0.8, 0);
    pts[6] = v3(20, 20, 0);
    double dir[21];
    CHECK(wrt_ref_irradiance(r, &l, 1, pts, qs, 7, 1, 1, 2, 1, dir, NULL, NULL) == WRT_OK, "run");
    double worst = 0;
    for (int i = 0; i < 6; i++) {
        double want = I * h / pow(h * h + xs[i] * xs[i], 1.5);
        worst = fmax(worst, fabs(dir[3 * i] / want - 1));
        worst = fmax(worst, fabs(dir[3 * i + 1] / (0.5 * want) - 1));
    }
    CHECK(worst < 1e-6, "point light: worst relative error %.3g", worst);
    CHECK(dir[18] == 0, "shadowed point gets %g", dir[18]);

    /* spot pointing down, inner 0.2, outer 0.5 rad, and a range of 8 */
    wrt_light sp = l;
    sp.type = WRT_LIGHT_SPOT;
    sp.color[1] = 1;
    sp.inner_cone = 0.2f; sp.outer_cone = 0.5f; sp.range = 8;
    CHECK(wrt_ref_irradiance(r, &sp, 1, pts, qs, 6, 1, 1, 2, 1, dir, NULL, NULL) == WRT_OK, "run");
    worst = 0;
    for (int i = 0; i < 6; i++) {
        double d = sqrt(h * h + xs[i] * xs[i]), cs = h / d;
        double f = (cs - cos((double)sp.outer_cone)) / (cos((double)sp.inner_cone) - cos((double)sp.outer_cone));
        f = f < 0 ? 0 : f > 1 ? 1 : f;
        double w = 1 - pow(d / 8, 4);
        w = w < 0 ? 0 : w;
        double want = I * h / (d * d * d) * f * f * w * w;
        double err = want > 0 ? fabs(dir[3 * i] / want - 1) : fabs(dir[3 * i]);
        worst = fmax(worst, err);
    }
    CHECK(worst < 1e-6, "spot light: worst error %.3g", worst);
    CHECK(dir[6] > 0 && dir[9] == 0, "spot: inside %g, outside %g", dir[6], dir[9]);

    /* a sun (directional, lux) travelling along (0.3, 0.4, -1): I cos everywhere, no
     * falloff, its range ignored; the point whose ray toward it crosses the blocker at
     * (10, 10, 1) gets 0 */
    wrt_light sun = point_light(v3(0, 0, 0), 7);
    sun.type = WRT_LIGHT_DIRECTIONAL;
    sun.dir = v3_norm(v3(0.3, 0.4, -1));
    sun.range = 1;
    pts[6] = v3(10.3, 10.4, 0);
    CHECK(wrt_ref_irradiance(r, &sun, 1, pts, qs, 7, 1, 1, 2, 1, dir, NULL, NULL) == WRT_OK, "run");
    worst = 0;
    double want_sun = 7 / v3_len(v3(0.3, 0.4, -1));
    for (int i = 0; i < 6; i++) worst = fmax(worst, fabs(dir[3 * i] / want_sun - 1));
    CHECK(worst < 1e-6, "sun: worst relative error %.3g", worst);
    CHECK(dir[18] == 0, "point in the blocker's sun shadow gets %g", dir[18]);
    pts[6] = v3(20, 20, 0);

    /* a light below the plane lights its back side: nothing arrives at the front */
    wrt_light below = point_light(v3(0, 0, -h), I);
    CHECK(wrt_ref_irradiance(r, &below, 1, pts, qs, 3, 1, 1, 2, 1, dir, NULL, NULL) == WRT_OK, "run");
    CHECK(dir[0] == 0 && dir[3] == 0 && dir[6] == 0, "back side lit: %g", dir[0]);
    wrt_ref_destroy(r);
}

/* The closed cube [0,1]^3 with inward normals, all walls albedo rho. */
static void make_cube(wrt_quad q[6]) {
    wrt_v3 X = v3(1, 0, 0), Y = v3(0, 1, 0), Z = v3(0, 0, 1), O = v3(0, 0, 0);
    q[0] = make_quad(O, X, Y, 0);           /* floor, +z */
    q[1] = make_quad(Z, Y, X, 0);           /* ceiling, -z */
    q[2] = make_quad(O, Y, Z, 0);           /* x = 0, +x */
    q[3] = make_quad(X, Z, Y, 0);           /* x = 1, -x */
    q[4] = make_quad(O, Z, X, 0);           /* y = 0, +y */
    q[5] = make_quad(Y, X, Z, 0);           /* y = 1, -y */
}

/* Total flux over the cube: sum over cells of mean irradiance x cell area, and its
 * standard error (cells are independent). */
static void cube_flux(wrt_ref *r, const wrt_light *l, int n, int spc, int maxb, int threads,
                      double *direct, double *indirect, double *se) {
    double *d = malloc(sizeof(double) * 3 * n * n), *m = malloc(sizeof(double) * 3 * n * n);
    double *e = malloc(sizeof(double) * 3 * n * n);
    double cell = 1.0 / (n * n), fd = 0, fi = 0, var = 0;
    for (int q = 0; q < 6; q++) {
        wrt_status st = wrt_ref_cell_irradiance(r, l, 1, q, n, spc, maxb, threads, 7, d, m, e);
        CHECK(st == WRT_OK, "cells: %s", wrt_last_error());
        for (int i = 0; i < n * n; i++) {
            fd += d[3 * i] * cell;
            fi += m[3 * i] * cell;
            var += e[3 * i] * e[3 * i] * cell * cell;
        }
    }
    *direct = fd; *indirect = fi; *se = sqrt(var);
    free(d); free(m); free(e);
}

/* (b) The furnace. */
static void test_furnace(void) {
    wrt_quad quads[6];
    make_cube(quads);
    double rhos[2] = {0.5, 0.9};
    int spc[2] = {64, 400};
    for (int k = 0; k < 2; k++) {
        wrt_material mats[1] = {diffuse(rhos[k])};
        wrt_scene s = make_scene(quads, 6, mats, 1);
        wrt_ref *r = wrt_ref_create(&s);
        CHECK(r != NULL, "create: %s", wrt_last_error());
        if (!r) return;
        double I = 3;
        wrt_light l = point_light(v3(0.3, 0.6, 0.45), I);
        double fd, fi, se, t0 = wrt_now();
        uint64_t rays0 = wrt_ref_rays(r);
        cube_flux(r, &l, 16, spc[k], 0, 2, &fd, &fi, &se);
        double dt = wrt_now() - t0;
        double want = 4 * WRT_PI * I * rhos[k] / (1 - rhos[k]);
        fprintf(stderr, "  furnace rho %.1f: indirect flux %.5g want %.5g (rel err %.2f%%, "
                "%.2f se, se %.2f%%), direct %.5g want %.5g; %.2f s, %.3g Mrays/s\n",
                rhos[k], fi, want, 100 * (fi / want - 1), (fi - want) / se, 100 * se / want, fd,
                4 * WRT_PI * I, dt, (wrt_ref_rays(r) - rays0) / dt / 1e6);
        CHECK(fabs(fi - want) <= 3 * se, "rho %.1f: flux %.6g vs %.6g, se %.3g", rhos[k], fi, want, se);
        CHECK(fabs(fi / want - 1) <= 0.02, "rho %.1f: relative error %.3g", rhos[k], fi / want - 1);
        CHECK_NEAR(fd, 4 * WRT_PI * I, 0.01 * 4 * WRT_PI * I, "direct flux = 4 pi I");
        if (k == 0) {
            /* one reflection only: the walls receive 4 pi I rho */
            cube_flux(r, &l, 8, 64, 1, 2, &fd, &fi, &se);
            double w1 = 4 * WRT_PI * I * rhos[k];
            CHECK(fabs(fi - w1) <= 3 * se && fabs(fi / w1 - 1) < 0.02,
                  "single bounce flux %.6g vs %.6g (se %.3g)", fi, w1, se);
        }
        wrt_ref_destroy(r);
    }
}

/* (c) One bounce between two facing unit squares, against a midpoint rule. */
static void test_two_squares(void) {
    wrt_quad quads[2];
    quads[0] = make_quad(v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), 0); /* lit, faces +z */
    quads[1] = make_quad(v3(0, 0, 1), v3(0, 1, 0), v3(1, 0, 0), 1); /* faces -z, black */
    double rho = 0.6, I = 2;
    wrt_material mats[2] = {diffuse(rho), diffuse(0)};
    wrt_scene s = make_scene(quads, 2, mats, 2);
    wrt_ref *r = wrt_ref_create(&s);
    CHECK(r != NULL, "create: %s", wrt_last_error());
    if (!r) return;
    wrt_v3 L = v3(0.4, 0.55, 0.5);
    wrt_light l = point_light(L, I);
    wrt_v3 c = v3(0.5, 0.5, 1);
    /* E(c) = int_A (rho/pi) E_dir(y) cos_y cos_c / d^2 dA, here cos_y = cos_c = 1/d */
    int M = 1500;
    double sum = 0;
    for (int i = 0; i < M; i++)
        for (int j = 0; j < M; j++) {
            wrt_v3 y = v3((i + 0.5) / M, (j + 0.5) / M, 0);
            wrt_v3 dl = v3_sub(L, y);
            double rl = v3_len(dl);
            double edir = I * dl.z / (rl * rl * rl);
            wrt_v3 dc = v3_sub(c, y);
            double d2 = v3_dot(dc, dc);
            sum += rho / WRT_PI * edir / (d2 * d2);
        }
    double want = sum / ((double)M * M);
    int q = 1;
    double dir[3], ind[3], se[3], t0 = wrt_now();
    CHECK(wrt_ref_irradiance(r, &l, 1, &c, &q, 1, 200000, 0, 2, 11, dir, ind, se) == WRT_OK, "run");
    fprintf(stderr, "  two squares: indirect %.6g want %.6g (rel err %.2f%%, se %.2f%%), %.2f s\n",
            ind[0], want, 100 * (ind[0] / want - 1), 100 * se[0] / want, wrt_now() - t0);
    CHECK(fabs(ind[0] / want - 1) < 0.02, "indirect %.6g vs %.6g", ind[0], want);
    CHECK(fabs(ind[0] - want) < 4 * se[0], "indirect %.6g vs %.6g (se %.3g)", ind[0], want, se[0]);
    double dwant = I * 0.5 / pow(v3_len(v3_sub(L, c)), 3);
    CHECK_NEAR(dir[0], dwant, 1e-6 * dwant, "direct at the top square's centre");
    wrt_ref_destroy(r);
}

/* A rendered pixel straight below the light: radiance rho/pi * I / h^2 (direct). */
static void test_render_pixel(void) {
    wrt_quad quads[1] = {make_quad(v3(-10, -10, 0), v3(20, 0, 0), v3(0, 20, 0), 0)};
    wrt_material mats[1] = {diffuse(0.7)};
    wrt_scene s = make_scene(quads, 1, mats, 1);
    wrt_ref *r = wrt_ref_create(&s);
    CHECK(r != NULL, "create: %s", wrt_last_error());
    if (!r) return;
    wrt_light l = point_light(v3(0, 0, 3), 5);
    wrt_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.pos = v3(0, 0, 5); cam.dir = v3(0, 0, -1); cam.up = v3(0, 1, 0);
    cam.yfov = 1e-7;
    float d[3], ind[3], both[3], se[3];
    CHECK(wrt_ref_render(r, &l, 1, &cam, 1, 1, 4, 0, 1, 3, d, ind, both, se) == WRT_OK, "render");
    double want = 0.7 / WRT_PI * 5 / 9;
    CHECK_NEAR(d[0], want, 1e-5 * want, "direct radiance");
    CHECK(ind[0] == 0 && both[0] == d[0], "a lone plane has no indirect light: %g", ind[0]);
    wrt_ref_destroy(r);
}

/* The renderer's indirect radiance at a Lambertian point is rho/pi times the indirect
 * irradiance there (two independent estimators of the same quantity). */
static void test_render_matches_irradiance(void) {
    wrt_quad quads[6];
    make_cube(quads);
    double rho = 0.6;
    wrt_material mats[1] = {diffuse(rho)};
    wrt_scene s = make_scene(quads, 6, mats, 1);
    wrt_ref *r = wrt_ref_create(&s);
    CHECK(r != NULL, "create: %s", wrt_last_error());
    if (!r) return;
    wrt_light l = point_light(v3(0.7, 0.3, 0.8), 1);
    wrt_v3 x = v3(0.4, 0.45, 0);
    int q = 0;
    double dir[3], ind[3], se[3];
    wrt_ref_irradiance(r, &l, 1, &x, &q, 1, 40000, 0, 2, 21, dir, ind, se);
    wrt_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.pos = v3(0.4, 0.45, 0.5); cam.dir = v3(0, 0, -1); cam.up = v3(0, 1, 0);
    cam.yfov = 1e-7;
    float d[3], ri[3], both[3], rse[3];
    wrt_ref_render(r, &l, 1, &cam, 1, 1, 40000, 0, 2, 22, d, ri, both, rse);
    double k = rho / WRT_PI;
    CHECK_NEAR(d[0], k * dir[0], 1e-5 * k * dir[0], "direct radiance = rho/pi E_dir");
    double tol = 4 * sqrt(rse[0] * rse[0] + k * k * se[0] * se[0]);
    CHECK_NEAR(ri[0], k * ind[0], tol, "indirect radiance = rho/pi E_ind (se %.3g, %.3g)",
               rse[0], k * se[0]);
    fprintf(stderr, "  render vs irradiance: %.5g vs %.5g (%.2f combined se)\n", ri[0], k * ind[0],
            (ri[0] - k * ind[0]) / (tol / 4));
    wrt_ref_destroy(r);
}

/* Same seed, 1 or 2 threads: bit-identical results. */
static void test_thread_independence(void) {
    wrt_quad quads[6];
    make_cube(quads);
    wrt_material mats[1] = {diffuse(0.7)};
    mats[0].lambertian = 0; /* exercise the full BRDF and its sampler too */
    mats[0].roughness = 0.4f; mats[0].metallic = 0.3f;
    wrt_scene s = make_scene(quads, 6, mats, 1);
    wrt_ref *r = wrt_ref_create(&s);
    CHECK(r != NULL, "create: %s", wrt_last_error());
    if (!r) return;
    wrt_light l = point_light(v3(0.5, 0.5, 0.5), 1);
    double a[3 * 64], b[3 * 64], ea[3 * 64], eb[3 * 64];
    wrt_ref_cell_irradiance(r, &l, 1, 0, 8, 8, 0, 1, 5, NULL, a, ea);
    wrt_ref_cell_irradiance(r, &l, 1, 0, 8, 8, 0, 2, 5, NULL, b, eb);
    CHECK(memcmp(a, b, sizeof a) == 0 && memcmp(ea, eb, sizeof ea) == 0, "cells differ");
    wrt_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.pos = v3(0.5, 0.5, 0.9); cam.dir = v3(0, 0, -1); cam.up = v3(0, 1, 0);
    cam.yfov = 1.2;
    enum { W = 24, H = 16 };
    static float i1[W * H * 3], i2[W * H * 3];
    wrt_ref_render(r, &l, 1, &cam, W, H, 4, 0, 1, 9, NULL, NULL, i1, NULL);
    wrt_ref_render(r, &l, 1, &cam, W, H, 4, 0, 2, 9, NULL, NULL, i2, NULL);
    CHECK(memcmp(i1, i2, sizeof i1) == 0, "images differ");
    int finite = 1;
    for (int i = 0; i < W * H * 3; i++) finite &= isfinite(i1[i]) && i1[i] >= 0;
    CHECK(finite, "image has non-finite or negative values");
    wrt_ref_destroy(r);
}

static void test_bad_arguments(void) {
    wrt_scene empty;
    memset(&empty, 0, sizeof empty);
    CHECK(wrt_ref_create(&empty) == NULL, "empty scene accepted");
    wrt_quad quads[1] = {make_quad(v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), 3)};
    wrt_material mats[1] = {diffuse(0.5)};
    wrt_scene s = make_scene(quads, 1, mats, 1);
    CHECK(wrt_ref_create(&s) == NULL, "bad material index accepted");
    quads[0].material = 0;
    wrt_ref *r = wrt_ref_create(&s);
    wrt_light l = point_light(v3(0, 0, 1), 1);
    wrt_v3 p = v3(0.5, 0.5, 0);
    int q = 5;
    double e[3];
    CHECK(wrt_ref_irradiance(r, &l, 1, &p, &q, 1, 1, 1, 1, 1, e, NULL, NULL) == WRT_ERR_INVALID_ARG,
          "bad quad index accepted");
    CHECK(wrt_ref_cell_irradiance(r, &l, 1, 0, 4, 0, 1, 1, 1, NULL, e, NULL) == WRT_ERR_INVALID_ARG,
          "zero samples accepted");
    wrt_ref_destroy(r);
    wrt_ref_destroy(NULL);
}

int main(int argc, char **argv) {
    TEST_RUN(test_direct_closed_form);
    TEST_RUN(test_furnace);
    TEST_RUN(test_two_squares);
    TEST_RUN(test_render_pixel);
    TEST_RUN(test_render_matches_irradiance);
    TEST_RUN(test_thread_independence);
    TEST_RUN(test_bad_arguments);
    TEST_END();
}
