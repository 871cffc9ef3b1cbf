/* test_texture.c: base-colour textures (docs/textures.md) against truths independent of
 * the transport: each element's albedo is its own footprint's mean (exact values: an
 * element inside one square of a checker has that square's albedo, one straddling two
 * squares half and half has their mean, since bilinear filtering's blend is
 * antisymmetric about the edge); the path tracer samples the texture at the hit (a
 * camera ray on a dark square sees the dark albedo); and the bounce off a checker floor
 * lit near one bright square, bake + runtime against the path tracer, with the same
 * bake made from the material's mean albedo as the counter-example (the floor then
 * reflects half the light it should). Depends on the bake, the .gto writer, the runtime
 * library, the path tracer, common/texture.h and the test harness. */
#include "test.h"

#include <stdlib.h>
#include <unistd.h>

#include "common/texture.h"
#include <stdint.h>
#include "include/wrt.h"
#include "formats/gto.h"
#include "precompute/bake.h"
#include "scene_build.h"
#include "verify/reference.h"

static char tmpdir[256];

#define TEX 64       /* texels a side */
#define SQ 16        /* texels a checker square */
#define HI_BYTE 231 /* sRGB bytes of the checker's squares: albedo about 0.80 and 0.05 */
#define LO_BYTE 63
static float HI, LO;  /* their linear values, from the sRGB formula (set in main) */

/* A TEX x TEX checker of SQ-texel squares, HI where (i/SQ + j/SQ) is even; clamped. */
static wrt_texture checker(void) {
    wrt_texture t;
    memset(&t, 0, sizeof t);
    t.w = t.h = TEX;
    t.wrap[0] = t.wrap[1] = WRT_WRAP_CLAMP;
    t.srgb = malloc((size_t)TEX * TEX * 3);
    for (int j = 0; j < TEX; j++)
        for (int i = 0; i < TEX; i++)
            for (int c = 0; c < 3; c++)
                t.srgb[((size_t)j * TEX + (size_t)i) * 3 + (size_t)c] = ((i / SQ + j / SQ) % 2) ? LO_BYTE : HI_BYTE;
    wrt_texture_srgb_table(t.lut);
    for (int c = 0; c < 3; c++) { t.factor[c] = 1; t.mean[c] = 0.5f * (HI + LO); }
    return t;
}

static wrt_quad uv_quad(double s0, double s1, double t0, double t1) {
    wrt_quad q;
    memset(&q, 0, sizeof q);
    q.p[0] = v3(0, 0, 0); q.p[1] = v3(1, 0, 0); q.p[2] = v3(1, 0, -1); q.p[3] = v3(0, 0, -1);
    wrt_quad_finish(&q);
    q.has_uv = 1;
    double st[4][2] = {{s0, t0}, {s1, t0}, {s1, t1}, {s0, t1}};
    for (int k = 0; k < 4; k++) { q.uv[k][0] = (float)st[k][0]; q.uv[k][1] = (float)st[k][1]; }
    return q;
}

static void test_element_mean(void) {
    wrt_texture t = checker();
    double rho[3];
    /* inside square (0, 0) (texels 1..15): exactly HI; inside (1, 0): LO */
    wrt_quad q = uv_quad(1.0 / TEX, 15.0 / TEX, 1.0 / TEX, 15.0 / TEX);
    wrt_texture_quad_mean(&t, &q, rho);
    CHECK_NEAR(rho[0], HI, 1e-6, "inside a bright square");
    q = uv_quad(17.0 / TEX, 31.0 / TEX, 1.0 / TEX, 15.0 / TEX);
    wrt_texture_quad_mean(&t, &q, rho);
    CHECK_NEAR(rho[1], LO, 1e-6, "inside a dark square");
    /* half over square (0, 0), half over (1, 0): the mean of the two */
    q = uv_quad(8.0 / TEX, 24.0 / TEX, 4.0 / TEX, 12.0 / TEX);
    wrt_texture_quad_mean(&t, &q, rho);
    CHECK_NEAR(rho[2], 0.5 * (HI + LO), 1e-4, "straddling an edge: %.6f", rho[2]);
    /* the whole texture: the checker's mean (clamped edges change nothing here) */
    q = uv_quad(0, 1, 0, 1);
    wrt_texture_quad_mean(&t, &q, rho);
    CHECK_NEAR(rho[0], 0.5 * (HI + LO), 1e-4, "whole texture: %.6f", rho[0]);
    /* UV sampling: repeat wraps, mirror reflects */
    float a[3], b[3];
    t.wrap[0] = t.wrap[1] = WRT_WRAP_REPEAT;
    wrt_texture_sample(&t, 8.0 / TEX, 8.0 / TEX, a);
    wrt_texture_sample(&t, 1 + 8.0 / TEX, -1 + 8.0 / TEX, b);
    CHECK(a[0] == HI && b[0] == HI, "repeat: %g %g", a[0], b[0]);
    t.wrap[0] = WRT_WRAP_MIRROR;
    wrt_texture_sample(&t, -8.0 / TEX, 8.0 / TEX, b);
    CHECK(b[0] == HI, "mirror: %g", b[0]);
    wrt_texture_sample(&t, -24.0 / TEX, 8.0 / TEX, b);
    CHECK(b[0] == LO, "mirror, second square: %g", b[0]);
    free(t.srgb);
}

/* A 1 m floor of 4 x 4 elements, one checker square each (UV (0..1) over the floor),
 * and a wall at x = -0.5 facing +x; a point light 0.15 m above the bright corner
 * square (0, 0). With mean_albedo the floor's material loses its texture. */
static void floor_scene(wrt_scene *s, int mean_albedo) {
    tsb_init(s);
    int mf = tsb_material(s, 1, 1, 1);
    int mw = tsb_material(s, 0.5, 0.5, 0.5);
    s->textures = calloc(1, sizeof *s->textures);
    s->textures[0] = checker();
    s->ntextures = 1;
    if (mean_albedo) for (int c = 0; c < 3; c++) s->materials[mf].base_color[c] = 0.5f * (HI + LO);
    else s->materials[mf].base_tex = 1;
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
            double x0 = -0.5 + 0.25 * i, x1 = x0 + 0.25, z0 = 0.5 - 0.25 * j, z1 = z0 - 0.25;
            int q = tsb_quad(s, v3(x0, 0, z0), v3(x1, 0, z0), v3(x1, 0, z1), v3(x0, 0, z1), mf);
            wrt_quad *qq = &s->quads[q];
            qq->has_uv = 1;
            double st[4][2] = {{i * 0.25, j * 0.25}, {(i + 1) * 0.25, j * 0.25}, {(i + 1) * 0.25, (j + 1) * 0.25},
                               {i * 0.25, (j + 1) * 0.25}};
            for (int k = 0; k < 4; k++) { qq->uv[k][0] = (float)st[k][0]; qq->uv[k][1] = (float)st[k][1]; }
        }
    tsb_quad(s, v3(-0.5, 0, 0.5), v3(-0.5, 0, -0.5), v3(-0.5, 1, -0.5), v3(-0.5, 1, 0.5), mw);
    for (int q = 0; q < s->nquads; q++) s->quads[q].name = -1;
    s->lights = calloc(1, sizeof *s->lights);
    s->nlights = 1;
    wrt_light *l = &s->lights[0];
    l->type = WRT_LIGHT_POINT;
    l->pos = v3(-0.375, 0.15, 0.375);
    l->dir = v3(0, -1, 0);
    l->color[0] = l->color[1] = l->color[2] = 1;
    l->intensity = 1;
    l->outer_cone = (float)(M_PI / 4);
    s->camera.pos = v3(-0.375, 1, 0.375);
    s->camera.dir = v3(0, -1, 0);
    s->camera.up = v3(0, 0, -1);
}

static void free_scene(wrt_scene *s) {
    for (int i = 0; i < s->ntextures; i++) free(s->textures[i].srgb);
    free(s->textures);
    s->textures = NULL;
    tsb_free(s);
}

/* Bakes the scene at quality 5 and returns the wall's (quad 16) n x n cell irradiance. */
static int bake_wall_cells(const wrt_scene *s, const char *name, int n, double *cells) {
    wrt_bake_options o = {0};
    o.quality = 5;
    o.threads = 2;
    wrt_bake_result r;
    if (wrt_bake_run(s, &o, &r) != WRT_OK) { CHECK(0, "bake: %s", wrt_last_error()); return 0; }
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    wrt_gto_contents gc = {.scene = s, .fkeys = r.fkeys, .nfuncs = r.nfuncs, .col_start = r.op.col,
                           .rows = r.op.row, .vals = r.op.val, .op_kind = (uint32_t)r.op_kind,
                           .material_alevel = r.material_alevel};
    wrt_status st = wrt_gto_write(path, &gc);
    wrt_bake_result_free(&r);
    if (st != WRT_OK) { CHECK(0, "gto write: %s", wrt_last_error()); return 0; }
    wrt_runtime *rt = NULL;
    wrt_error err;
    if (wrt_runtime_open_file(path, NULL, &rt, &err) != WRT_OK) { CHECK(0, "open: %s", err.message); return 0; }
    wrt_runtime_light l;
    CHECK(wrt_runtime_get_light(rt, 0, &l, &err) == WRT_OK, "light: %s", err.message);
    wrt_runtime_set_lights(rt, &l, 1, NULL);
    wrt_runtime_update(rt, NULL, NULL);
    st = wrt_runtime_quad_cells(rt, 16, n, cells, &err);
    CHECK(st == WRT_OK, "cells: %s", err.message);
    wrt_runtime_close(rt);
    return st == WRT_OK;
}

static void test_checker_bounce(void) {
    enum { N = 2 };
    wrt_scene s, m;
    floor_scene(&s, 0);
    floor_scene(&m, 1);
    double tex[N * N * 3], mean[N * N * 3], ref[N * N * 3], se[N * N * 3];
    if (!bake_wall_cells(&s, "tex.gto", N, tex) || !bake_wall_cells(&m, "mean.gto", N, mean)) {
        free_scene(&s); free_scene(&m);
        return;
    }
    wrt_ref *r = wrt_ref_create(&s);
    CHECK(r != NULL, "ref: %s", wrt_last_error());
    if (r) {
        CHECK(wrt_ref_cell_irradiance(r, s.lights, 1, 16, N, 40000, 0, 2, 11, NULL, ref, se) == WRT_OK, "ref cells");
        double et = 0, em = 0, sref = 0, stex = 0, smean = 0, sse = 0;
        for (int k = 0; k < N * N; k++) {
            et = fmax(et, fabs(tex[3 * k] / ref[3 * k] - 1));
            em = fmax(em, fabs(mean[3 * k] / ref[3 * k] - 1));
            sref += ref[3 * k]; stex += tex[3 * k]; smean += mean[3 * k]; sse += se[3 * k] * se[3 * k];
        }
        printf("  wall lit by the checker's bright corner: textured bake %+.1f%% (worst of %d x %d cells %.1f%%), "
               "mean-albedo bake %+.1f%% (worst %.1f%%) of the path tracer (se %.2f%%)\n",
               100 * (stex / sref - 1), N, N, 100 * et, 100 * (smean / sref - 1), 100 * em, 100 * sqrt(sse) / sref);
        CHECK(fabs(stex / sref - 1) < 0.04, "textured bake's wall off the path tracer by %.2f%%", 100 * (stex / sref - 1));
        CHECK(et < 0.08, "textured bake's worst cell %.2f%%", 100 * et);
        CHECK(smean / sref - 1 < -0.15, "the mean albedo should miss the bright square's bounce: %+.1f%%",
              100 * (smean / sref - 1));
        /* a camera ray straight down on the dark square (1, 0) sees its albedo: the
         * direct radiance there is LO E / pi */
        float both[3];
        wrt_camera cam = s.camera;
        cam.pos = v3(-0.125, 0.5, 0.375);
        cam.yfov = 1e-5;
        CHECK(wrt_ref_render(r, s.lights, 1, &cam, 1, 1, 1, 1, 1, 3, both, NULL, NULL, NULL) == WRT_OK, "render");
        wrt_v3 x = v3(-0.125, 0, 0.375), d = v3_sub(s.lights[0].pos, x);
        double dd = v3_len(d), e = d.y / dd / (dd * dd);
        CHECK_NEAR(both[0], LO * e / M_PI, 2e-3 * LO * e / M_PI, "path tracer's direct on the dark square");
        wrt_ref_destroy(r);
    }
    free_scene(&s);
    free_scene(&m);
}

/* The .gto's textures section (version 1.3): the floor's checker read back (sRGB bytes of
 * 0.8 and 0.05, computed here from the sRGB formula), and a corrupted record refused. */
static void test_gto_section(void) {
    char path[512];
    snprintf(path, sizeof path, "%s/tex.gto", tmpdir);
    wrt_gto g;
    CHECK(wrt_gto_open(path, &g) == WRT_OK, "open: %s", wrt_last_error());
    if (!g.map) return;
    CHECK(g.version_minor == 3, "version 1.%u", g.version_minor);
    wrt_gto_texture t;
    CHECK(wrt_gto_texture_count(&g) == 1 && wrt_gto_texture_get(&g, 0, &t), "one texture");
    CHECK(!wrt_gto_texture_get(&g, 1, &t), "index 1 out of range");
    wrt_gto_texture_get(&g, 0, &t);
    CHECK(t.material == 0 && t.w == TEX && t.h == TEX && t.wrap[0] == WRT_WRAP_CLAMP, "record");
    int hi = HI_BYTE, lo = LO_BYTE;
    CHECK(t.srgb[0] == hi && t.srgb[3 * SQ] == lo && t.srgb[3 * (TEX * SQ)] == lo, "texels %d %d %d (want %d %d)",
          t.srgb[0], t.srgb[3 * SQ], t.srgb[3 * (TEX * SQ)], hi, lo);
    CHECK(t.factor[0] == 1 && fabsf(t.mean[0] - 0.5f * (HI + LO)) < 1e-6f, "factor %g mean %g", t.factor[0], t.mean[0]);
    /* a wrap mode of 7 in a copy: refused, naming the section */
    uint8_t *copy = malloc(g.size);
    memcpy(copy, g.map, g.size);
    size_t rec = (size_t)(g.textures - (const uint8_t *)g.map) + 8;
    uint32_t bad = 7;
    memcpy(copy + rec + 12, &bad, 4);
    wrt_gto g2;
    CHECK(wrt_gto_open_memory(copy, g.size, &g2) == WRT_ERR_CORRUPT && strstr(wrt_last_error(), "section textures"),
          "corrupt wrap refused: %s", wrt_last_error());
    free(copy);
    wrt_gto_close(&g);
}

int main(int argc, char **argv) {
    (void)argc; (void)argv;
    setvbuf(stdout, NULL, _IOLBF, 0);
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wrt_tex_XXXXXX");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 2; }
    HI = (float)pow((HI_BYTE / 255.0 + 0.055) / 1.055, 2.4);
    LO = (float)pow((LO_BYTE / 255.0 + 0.055) / 1.055, 2.4);
    TEST_RUN(test_element_mean);
    TEST_RUN(test_checker_bounce);
    TEST_RUN(test_gto_section);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_END();
}
