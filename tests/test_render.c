/* test_render.c: tests of the player's renderer (player/render.c) in a headless EGL
 * context, on scenes built in memory, against values computed here by hand: the
 * direct radiance of a Lambertian floor under a point light (rho/pi I cos / d^2) and a
 * spot light (cone falloff), a glossy floor against common/brdf.c, a shadow, the
 * indirect atlas read back exactly (no bleeding between neighbouring quads, bilinear
 * between texels), both = direct + indirect, the same picture for a scene moved 10^6 away from the origin, and the tone curve. */
#include "tests/test.h"
#include "player/render.h"
#include "player/platform.h"
#include "formats/image.h"
#include "common/brdf.h"

#include <stdlib.h>

#define W 160
#define H 120
#define FOV (60.0 * WRT_PI / 180.0)

static wrt_gto_quad quads[8];
static wrt_gto_material mats[2];
static wrt_gto g;
static double shift; /* the whole scene and camera translated by (shift, shift, shift) */

static void add_quad(int i, double x0, double x1, double y, double z0, double z1, int mat) {
    wrt_gto_quad *q = &quads[i];
    memset(q, 0, sizeof *q);
    double p[4][3] = {{x0, y, z1}, {x1, y, z1}, {x1, y, z0}, {x0, y, z0}}; /* normal +y */
    for (int c = 0; c < 4; c++)
        for (int k = 0; k < 3; k++) q->p[c][k] = p[c][k] + shift;
    q->n[1] = 1;
    q->t[0] = 1;
    q->b[2] = -1;
    q->area = (float)((x1 - x0) * (z1 - z0));
    q->material = (uint32_t)mat;
    q->flags = 1;
}

/* floor [-1,1]^2 at y = 0 in two halves (x < 0, x > 0); optional occluder at y = 0.5 */
static void build(int occluder) {
    memset(&g, 0, sizeof g);
    add_quad(0, -1, 0, 0, -1, 1, 0);
    add_quad(1, 0, 1, 0, -1, 1, 0);
    if (occluder) add_quad(2, -0.1, 0.1, 0.5, -0.1, 0.1, 0);
    memset(mats, 0, sizeof mats);
    for (int k = 0; k < 3; k++) mats[0].base_color[k] = 0.5f;
    mats[0].roughness = 1;
    mats[0].lambertian = 1;
    g.quads = quads;
    g.nquads = occluder ? 3 : 2;
    g.materials = mats;
    g.nmaterials = 1;
}

static wrt_view top_view(void) {
    wrt_view v = {{shift, 3 + shift, shift}, {shift, shift, shift}, {0, 0, -1}, FOV};
    return v;
}

/* World point on the floor (y = 0) seen through the centre of pixel (c, r), r = 0 at the top. */
static void pixel_to_floor(int c, int r, double *x, double *z) {
    double t = tan(FOV / 2), a = (double)W / H;
    double nx = (c + 0.5) / W * 2 - 1, ny = 1 - (r + 0.5) / H * 2;
    *x = nx * t * a * 3;  /* screen right = world +x */
    *z = -ny * t * 3;     /* screen up = world -z */
}
static void floor_to_pixel(double x, double z, int *c, int *r) {
    double t = tan(FOV / 2), a = (double)W / H;
    *c = (int)floor((x / (t * a * 3) + 1) / 2 * W);
    *r = (int)floor((1 - (-z / (t * 3))) / 2 * H);
}

static wrt_light point_light(double intensity) {
    wrt_light l;
    memset(&l, 0, sizeof l);
    l.type = WRT_LIGHT_POINT;
    l.pos = v3(shift, 1 + shift, shift);
    l.dir = v3(0, -1, 0);
    l.color[0] = l.color[1] = l.color[2] = 1;
    l.intensity = (float)intensity;
    l.outer_cone = (float)(WRT_PI / 4);
    return l;
}

static float img[W * H * 3], img2[W * H * 3], img3[W * H * 3];

static void render(wrt_render_mode mode, const wrt_light *l, int nl, float *out) {
    wrt_render_options o = {W, H, 512, 1};
    wrt_render *r = NULL;
    wrt_status s = wrt_render_create(&g, &o, &r);
    CHECK(s == WRT_OK, "create: %s", wrt_last_error());
    if (s) return;
    wrt_render_set_lights(r, l, NULL, nl);
    wrt_view v = top_view();
    wrt_render_draw(r, &v, mode);
    wrt_render_read_linear(r, out);
    wrt_render_destroy(r);
    const char *dump = getenv("WRT_TEST_DUMP"); /* a folder: look at the pictures */
    if (dump) {
        static int count;
        static uint8_t b8[W * H * 3];
        char path[512];
        snprintf(path, sizeof path, "%s/render_%02d.png", dump, count++);
        wrt_render_tonemap(out, W * H, 0, b8);
        wrt_image_write_rgb8(path, b8, W, H);
    }
}

static double px(const float *im, int c, int r, int k) { return im[((size_t)r * W + c) * 3 + k]; }

static void test_point_light_lambert(void) {
    build(0);
    wrt_light l = point_light(10);
    render(WRT_MODE_DIRECT, &l, 1, img);
    double worst = 0;
    int n = 0;
    for (int r = 2; r < H; r += 7)
        for (int c = 1; c < W; c += 9) {
            double x, z;
            pixel_to_floor(c, r, &x, &z);
            if (fabs(x) > 0.98 || fabs(z) > 0.98 || fabs(x) < 0.02) continue;
            double d2 = x * x + z * z + 1;
            double want = 0.5 / WRT_PI * 10 * (1 / sqrt(d2)) / d2;
            double e = fabs(px(img, c, r, 1) - want) / want;
            if (e > worst) worst = e;
            n++;
        }
    CHECK(n > 50, "samples %d", n);
    CHECK(worst < 2e-3, "worst relative error of the direct radiance %.3g", worst);
    CHECK_NEAR(px(img, 0, 0, 0), 0.0, 0.0, "outside the floor: background");
}

/* A glossy floor: the shader's BRDF against common/brdf.c's wrt_brdf_eval. */
static void test_glossy_brdf(void) {
    build(0);
    const float base[3] = {0.9f, 0.6f, 0.3f};
    memcpy(mats[0].base_color, base, sizeof base);
    mats[0].metallic = 0.5f;
    mats[0].roughness = 0.4f;
    mats[0].lambertian = 0;
    wrt_material m;
    memset(&m, 0, sizeof m);
    memcpy(m.base_color, base, sizeof base);
    m.metallic = 0.5f;
    m.roughness = 0.4f;
    wrt_light l = point_light(10);
    l.pos = v3(0.4, 1, 0.2); /* off the view axis: the highlight is not at the centre */
    render(WRT_MODE_DIRECT, &l, 1, img);
    double worst = 0, peak = 0;
    int n = 0;
    for (int r = 1; r < H; r += 3)
        for (int c = 1; c < W; c += 3) {
            double x, z;
            pixel_to_floor(c, r, &x, &z);
            if (fabs(x) > 0.98 || fabs(z) > 0.98 || fabs(x) < 0.02) continue;
            wrt_v3 p = v3(x, 0, z), nn = v3(0, 1, 0);
            wrt_v3 tl = v3_sub(l.pos, p), wi = v3_norm(tl), wo = v3_norm(v3_sub(v3(0, 3, 0), p));
            double f[3], d2 = v3_dot(tl, tl);
            wrt_brdf_eval(&m, nn, wi, wo, f);
            for (int k = 0; k < 3; k++) {
                double want = f[k] * 10 * wi.y / d2, got = px(img, c, r, k);
                double e = fabs(got - want) / (want + 1e-3);
                if (e > worst) worst = e;
                if (want > peak) peak = want;
            }
            n++;
        }
    CHECK(n > 400, "samples %d", n);
    CHECK(peak > 2, "a highlight was sampled: peak %g", peak);
    CHECK(worst < 2e-3, "worst relative error against wrt_brdf_eval %.3g", worst);
    build(0);
}

static void test_shadow(void) {
    build(1);
    wrt_light l = point_light(10);
    render(WRT_MODE_DIRECT, &l, 1, img);
    int c, r;
    floor_to_pixel(0.15, 0.0, &c, &r); /* in the occluder's shadow (|x| < 0.2), not under it */
    CHECK_NEAR(px(img, c, r, 0), 0.0, 1e-6, "shadowed floor at x=0.15");
    floor_to_pixel(-0.02, 0.16, &c, &r);
    CHECK_NEAR(px(img, c, r, 0), 0.0, 1e-6, "shadowed floor at z=0.16");
    floor_to_pixel(0.3, 0.0, &c, &r);
    double x, z;
    pixel_to_floor(c, r, &x, &z);
    double d2 = x * x + z * z + 1, want = 0.5 / WRT_PI * 10 / (d2 * sqrt(d2));
    CHECK_NEAR(px(img, c, r, 0), want, want * 2e-3, "lit floor at x=0.3");
    /* top of the occluder, 0.5 below the light */
    floor_to_pixel(0.0, 0.0, &c, &r);
    CHECK(px(img, c, r, 0) > 5, "occluder top lit: %g", px(img, c, r, 0));
}

static void test_spot(void) {
    build(0);
    wrt_light l = point_light(10);
    l.type = WRT_LIGHT_SPOT;
    l.outer_cone = (float)(30 * WRT_PI / 180);
    l.inner_cone = (float)(20 * WRT_PI / 180);
    render(WRT_MODE_DIRECT, &l, 1, img);
    double co = cos(l.outer_cone), ci = cos(l.inner_cone), worst = 0;
    int n = 0, zero = 0;
    for (int r = 2; r < H; r += 5)
        for (int c = 1; c < W; c += 5) {
            double x, z;
            pixel_to_floor(c, r, &x, &z);
            if (fabs(x) > 0.98 || fabs(z) > 0.98 || fabs(x) < 0.02) continue;
            double d2 = x * x + z * z + 1, cd = 1 / sqrt(d2);
            double t = (cd - co) / (ci - co);
            t = t < 0 ? 0 : t > 1 ? 1 : t;
            double want = 0.5 / WRT_PI * 10 * cd / d2 * t * t;
            double e = fabs(px(img, c, r, 2) - want);
            if (e > worst) worst = e;
            n++;
            zero += want == 0 && px(img, c, r, 2) == 0;
        }
    CHECK(worst < 2e-3, "worst absolute error under the spot %.3g (peak 1.59)", worst);
    CHECK(zero > 10, "pixels outside the cone black: %d", zero);
    /* range window: range 1.2, at d = 1.1: (1 - (d/r)^4)^2 */
    l.type = WRT_LIGHT_POINT;
    l.range = 1.2f;
    render(WRT_MODE_DIRECT, &l, 1, img);
    int c, r;
    floor_to_pixel(0.45, 0.0, &c, &r);
    double x, z;
    pixel_to_floor(c, r, &x, &z);
    double d2 = x * x + z * z + 1, q = d2 * d2 / pow(1.2, 4), w = (1 - q) * (1 - q);
    double want = 0.5 / WRT_PI * 10 / (d2 * sqrt(d2)) * w;
    CHECK_NEAR(px(img, c, r, 0), want, 2e-3 * want + 1e-6, "range window");
}

/* Indirect light: constant 1 on the left half, 3 on the right, and a gradient test. */
static void test_atlas(void) {
    build(0);
    wrt_render_options o = {W, H, 256, 1};
    wrt_render *r = NULL;
    CHECK(wrt_render_create(&g, &o, &r) == WRT_OK, "%s", wrt_last_error());
    if (!r) return;
    enum { RES = 8 };
    float a[RES * RES * 3], b[RES * RES * 3];
    for (int i = 0; i < RES * RES; i++) {
        int u = i % RES;
        for (int k = 0; k < 3; k++) {
            a[i * 3 + k] = 1.0f;
            b[i * 3 + k] = k == 0 ? 3.0f : (float)((u + 0.5) / RES); /* green, blue: u */
        }
    }
    CHECK(wrt_render_set_quad_tex(r, 0, RES, a) == 1, "first staging changes");
    CHECK(wrt_render_set_quad_tex(r, 1, RES, b) == 1, "first staging changes");
    CHECK(wrt_render_upload(r) == 2, "two quads uploaded");
    CHECK(wrt_render_set_quad_tex(r, 0, RES, a) == 0, "same texture: nothing to upload");
    CHECK(wrt_render_upload(r) == 0, "nothing uploaded");
    wrt_view v = top_view();
    wrt_render_draw(r, &v, WRT_MODE_INDIRECT);
    wrt_render_read_linear(r, img);
    int c, rr;
    floor_to_pixel(-0.01, 0.3, &c, &rr); /* just left of the seam: no bleeding from the right quad */
    CHECK_NEAR(px(img, c, rr, 0), 1.0, 1e-6, "left quad at the seam");
    floor_to_pixel(0.01, 0.3, &c, &rr);
    CHECK_NEAR(px(img, c, rr, 0), 3.0, 1e-6, "right quad at the seam");
    /* the right quad's u = x: bilinear reproduces a linear ramp between texel centres */
    double worst = 0;
    for (c = 0; c < W; c++) {
        double x, z;
        pixel_to_floor(c, H / 2, &x, &z);
        if (x < 1.0 / RES || x > 1 - 1.0 / RES) continue;
        double e = fabs(px(img, c, H / 2, 1) - x);
        if (e > worst) worst = e;
    }
    CHECK(worst < 2e-3, "bilinear ramp error %.3g", worst);
    /* a changed texture is re-uploaded alone */
    a[0] = 5;
    CHECK(wrt_render_set_quad_tex(r, 0, RES, a) == 1, "changed");
    CHECK(wrt_render_upload(r) == 1, "one quad re-uploaded");
    /* a new resolution re-packs */
    float big[16 * 16 * 3];
    for (int i = 0; i < 16 * 16 * 3; i++) big[i] = 2.0f;
    wrt_render_set_quad_tex(r, 0, 16, big);
    CHECK(wrt_render_upload(r) == 2, "re-pack uploads every quad");
    wrt_render_draw(r, &v, WRT_MODE_INDIRECT);
    wrt_render_read_linear(r, img);
    floor_to_pixel(-0.5, 0.3, &c, &rr);
    CHECK_NEAR(px(img, c, rr, 1), 2.0, 1e-6, "after re-pack");
    floor_to_pixel(0.01, 0.3, &c, &rr);
    CHECK_NEAR(px(img, c, rr, 0), 3.0, 1e-6, "right quad kept after re-pack");

    /* both = direct + indirect */
    wrt_light l = point_light(10);
    wrt_render_set_lights(r, &l, NULL, 1);
    wrt_render_draw(r, &v, WRT_MODE_DIRECT);
    wrt_render_read_linear(r, img);
    wrt_render_draw(r, &v, WRT_MODE_INDIRECT);
    wrt_render_read_linear(r, img2);
    wrt_render_draw(r, &v, WRT_MODE_BOTH);
    wrt_render_read_linear(r, img3);
    double maxe = 0;
    for (int i = 0; i < W * H * 3; i++) {
        double e = fabs(img3[i] - (img[i] + img2[i])) / (fabs(img3[i]) + 1e-6);
        if (e > maxe) maxe = e;
    }
    CHECK(maxe < 1e-5, "both = direct + indirect, worst relative %.3g", maxe);
    /* scale 0 switches the light off */
    float zero = 0;
    wrt_render_set_lights(r, &l, &zero, 1);
    wrt_render_draw(r, &v, WRT_MODE_DIRECT);
    wrt_render_read_linear(r, img);
    double sum = 0;
    for (int i = 0; i < W * H * 3; i++) sum += img[i];
    CHECK_NEAR(sum, 0.0, 0.0, "light switched off");
    wrt_render_destroy(r);
}

/* The same picture 10^6 units from the origin. */
static void test_far_from_origin(void) {
    shift = 0;
    build(1);
    wrt_light l = point_light(10);
    render(WRT_MODE_DIRECT, &l, 1, img);
    shift = 1e6;
    build(1);
    l = point_light(10);
    render(WRT_MODE_DIRECT, &l, 1, img2);
    shift = 0;
    double num = 0, den = 0;
    for (int i = 0; i < W * H * 3; i++) {
        num += fabs(img[i] - img2[i]);
        den += img[i];
    }
    CHECK(num / den < 1e-4, "relative L1 difference at 1e6 from the origin: %.3g", num / den);
}

static void test_tonemap(void) {
    float lin[4 * 3] = {0, 0, 0, 1, 1, 1, 1e9f, 0.25f, 3.0f, NAN, -1, 0.5f};
    uint8_t o[12];
    wrt_render_tonemap(lin, 4, 0, o);
    CHECK(o[0] == 0 && o[3] == 188 && o[6] == 255, "tone curve: %d %d %d", o[0], o[3], o[6]);
    CHECK(o[9] == 0 && o[10] == 0, "NaN and negative to 0: %d %d", o[9], o[10]);
    wrt_render_tonemap(lin, 4, 1, o);
    CHECK(o[3] == 213, "exposure +1: x=2 -> 2/3 -> sRGB 0.8372 -> 213: %d", o[3]);

}

/* Under AddressSanitizer: Mesa's driver, which EGL loads and unloads, leaves one block
 * of 128 bytes that LeakSanitizer cannot attribute to any module (the leak checks of
 * this program's own allocations were clean before this was switched off). */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "detect_leaks=0"; }

int main(int argc, char **argv) {
    wrt_platform *p = NULL;
    if (wrt_platform_egl_create(&p) != WRT_OK) {
        fprintf(stderr, "no headless OpenGL: %s\n", wrt_last_error());
        test_failed++;
        TEST_END();
    }
    fprintf(stderr, "%s\n", wrt_render_gl_info());
    TEST_RUN(test_point_light_lambert);
    TEST_RUN(test_glossy_brdf);
    TEST_RUN(test_shadow);
    TEST_RUN(test_spot);
    TEST_RUN(test_atlas);
    TEST_RUN(test_far_from_origin);
    TEST_RUN(test_tonemap);
    wrt_platform_destroy(p);
    TEST_END();
}
