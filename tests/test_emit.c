/* test_emit.c: emissive surfaces as sources (docs/emitters.md), against truths independent
 * of the transport code: a unit square emitting a uniform radiosity B faces a black unit
 * square at distance 1; the irradiance on each receiver cell is exactly B F(cell ->
 * emitter), the closed-form rectangle form factor (ff_closed.h). Checked through the
 * library (bake, .gto, wrt_runtime with no light at all), and through the path tracer
 * (emission on hit). Then: the emitter's scale is exactly linear (0.5 halves every
 * coefficient, 0 leaves nothing), and an emitter whose albedo is 0 in a channel is said
 * not to be carried there. Depends on the bake, the .gto writer, the runtime library,
 * the reference path tracer and the test harness. */
#include "test.h"

#include <float.h>
#include <stdlib.h>
#include <unistd.h>

#include "ff_closed.h"
#include "include/wrt.h"
#include "formats/gto.h"
#include "precompute/bake.h"
#include "scene_build.h"
#include "verify/reference.h"

static char tmpdir[256];

#define NCELL 4
#define LE (1.0 / M_PI) /* emitted radiance: radiosity B = pi L_e = 1 */

/* Emitter: z = 0, [0,1]^2, facing +z, albedo rho_e; receiver: z = 1, facing -z,
 * albedo 0 (nothing comes back, so its irradiance is the emitter's direct light
 * alone), u along +y and v along +x. */
static void facing_scene(wrt_scene *s, double rho_e, const double le[3]) {
    tsb_init(s);
    int me = tsb_material(s, rho_e, rho_e, rho_e);
    for (int c = 0; c < 3; c++) s->materials[me].emissive[c] = (float)le[c];
    int mr = tsb_material(s, 0, 0, 0);
    tsb_quad(s, v3(0, 0, 0), v3(1, 0, 0), v3(1, 1, 0), v3(0, 1, 0), me);
    tsb_quad(s, v3(0, 0, 1), v3(0, 1, 1), v3(1, 1, 1), v3(1, 0, 1), mr);
    for (int q = 0; q < s->nquads; q++) s->quads[q].name = -1;
    s->camera.pos = v3(0.5, -2, 0.5);
    s->camera.dir = v3(0, 1, 0);
    s->camera.up = v3(0, 0, 1);
}

/* Bakes s at quality 5 and writes it to tmpdir/name; 0 on failure. */
static int bake_to(const wrt_scene *s, const char *name, char *path, size_t cap) {
    wrt_bake_options o = {0};
    o.quality = 5;
    o.threads = 2;
    wrt_bake_result r;
    wrt_status st = wrt_bake_run(s, &o, &r);
    CHECK(st == WRT_OK, "bake: %s", wrt_last_error());
    if (st != WRT_OK) return 0;
    snprintf(path, cap, "%s/%s", tmpdir, name);
    wrt_gto_contents gc = {.scene = s, .fkeys = r.fkeys, .nfuncs = r.nfuncs, .col_start = r.op.col,
                           .rows = r.op.row, .vals = r.op.val, .op_kind = (uint32_t)r.op_kind,
                           .material_alevel = r.material_alevel};
    st = wrt_gto_write(path, &gc);
    wrt_bake_result_free(&r);
    CHECK(st == WRT_OK, "gto write: %s", wrt_last_error());
    return st == WRT_OK;
}

/* The closed form: mean irradiance B F over receiver cell (i, j) (u = y, v = x). */
static double truth_cell(int i, int j) {
    double y0 = (double)i / NCELL, y1 = (double)(i + 1) / NCELL, x0 = (double)j / NCELL, x1 = (double)(j + 1) / NCELL;
    return 1.0 * ffc_parallel(x0, x1, y0, y1, 0, 1, 0, 1, 1);
}

static void test_closed_form(void) {
    CHECK_NEAR(ffc_parallel(0, 1, 0, 1, 0, 1, 0, 1, 1), 0.19982, 1e-4, "unit squares at 1: F");
    wrt_scene s;
    const double le[3] = {LE, LE, LE};
    facing_scene(&s, 0.5, le);
    char path[512];
    if (!bake_to(&s, "facing.gto", path, sizeof path)) { tsb_free(&s); return; }
    wrt_runtime *rt = NULL;
    wrt_error err;
    CHECK(wrt_runtime_open_file(path, NULL, &rt, &err) == WRT_OK, "open: %s", err.message);
    if (!rt) { tsb_free(&s); return; }
    CHECK(wrt_runtime_emitter_count(rt) == 1, "emitters %d", wrt_runtime_emitter_count(rt));
    CHECK(wrt_runtime_update(rt, NULL, &err) == WRT_OK, "update: %s", err.message);
    double cells[NCELL * NCELL * 3], worst = 0, sum = 0, tsum = 0;
    CHECK(wrt_runtime_quad_cells(rt, 1, NCELL, cells, &err) == WRT_OK, "cells: %s", err.message);
    for (int j = 0; j < NCELL; j++)
        for (int i = 0; i < NCELL; i++) {
            double t = truth_cell(i, j), w = cells[(j * NCELL + i) * 3];
            worst = fmax(worst, fabs(w / t - 1));
            sum += w; tsum += t;
            CHECK(cells[(j * NCELL + i) * 3 + 1] == w && cells[(j * NCELL + i) * 3 + 2] == w, "grey");
        }
    printf("  receiver of a B = 1 square at 1: mean %.5f (closed form %.5f, %+.2f%%), worst %d x %d cell %.2f%%\n",
           sum / (NCELL * NCELL), tsum / (NCELL * NCELL), 100 * (sum / tsum - 1), NCELL, NCELL, 100 * worst);
    CHECK(fabs(sum / tsum - 1) < 0.01, "receiver mean off the closed form by %.3f%%", 100 * (sum / tsum - 1));
    CHECK(worst < 0.03, "worst cell off the closed form by %.3f%%", 100 * worst);
    /* the emitter itself receives nothing (the receiver is black) */
    double ed[3], ei[3];
    wrt_runtime_quad_irradiance(rt, 0, ed, ei, NULL);
    CHECK(ei[0] == 0, "emitter's own indirect %g", ei[0]);

    /* exact linearity in the scale; 0 switches it off */
    double half[NCELL * NCELL * 3];
    CHECK(wrt_runtime_set_emitter_scale(rt, 0, 0.5f, &err) == WRT_OK, "scale: %s", err.message);
    wrt_runtime_update(rt, NULL, NULL);
    wrt_runtime_quad_cells(rt, 1, NCELL, half, NULL);
    double dev = 0;
    for (int k = 0; k < NCELL * NCELL * 3; k++) dev = fmax(dev, fabs(half[k] - 0.5 * cells[k]));
    CHECK(dev == 0, "scale 0.5: max |X(0.5) - X(1)/2| = %g", dev);
    wrt_runtime_set_emitter_scale(rt, 0, 0, NULL);
    wrt_runtime_update(rt, NULL, NULL);
    wrt_runtime_quad_cells(rt, 1, NCELL, half, NULL);
    dev = 0;
    for (int k = 0; k < NCELL * NCELL * 3; k++) dev = fmax(dev, fabs(half[k]));
    CHECK(dev == 0, "scale 0: max |X| = %g", dev);
    CHECK(wrt_runtime_set_emitter_scale(rt, 0, -1, &err) == WRT_ERR_INVALID_ARG && strstr(err.message, "scale"),
          "negative scale refused: %s", err.message);
    CHECK(wrt_runtime_set_emitter_scale(rt, 7, 1, &err) == WRT_ERR_INVALID_ARG && strstr(err.message, "material 7"),
          "bad material refused: %s", err.message);
    /* A finite scale past what the computation carries (FLT_MAX on this emitter gave inf
     * in every texture, silently): refused beyond WRT_MAX_INTENSITY as the lights are,
     * and the largest scale allowed keeps every cell finite and linear (issue 25). */
    CHECK(wrt_runtime_set_emitter_scale(rt, 0, FLT_MAX, &err) == WRT_ERR_INVALID_ARG &&
              strstr(err.message, "WRT_MAX_INTENSITY"), "FLT_MAX scale refused: %s", err.message);
    wrt_runtime_material mat;
    CHECK(wrt_runtime_get_material(rt, 0, &mat, &err) == WRT_OK, "material: %s", err.message);
    float emax = fmaxf(mat.emissive[0], fmaxf(mat.emissive[1], mat.emissive[2]));
    float top = (float)(WRT_MAX_INTENSITY / emax * 0.999);
    CHECK(wrt_runtime_set_emitter_scale(rt, 0, top, &err) == WRT_OK, "scale %g: %s", (double)top, err.message);
    CHECK(wrt_runtime_update(rt, NULL, &err) == WRT_OK, "update: %s", err.message);
    wrt_runtime_quad_cells(rt, 1, NCELL, half, NULL);
    dev = 0;
    int nonfinite = 0;
    for (int k = 0; k < NCELL * NCELL * 3; k++) {
        nonfinite += !isfinite(half[k]);
        if (cells[k] > 0) dev = fmax(dev, fabs(half[k] / (top * cells[k]) - 1));
    }
    int res = 0;
    const float *tex = wrt_runtime_quad_texture(rt, 1, &res);
    for (int k = 0; tex && k < res * res * 3; k++) nonfinite += !isfinite(tex[k]);
    CHECK(nonfinite == 0 && dev < 1e-5, "scale %g: %d non-finite values, max relative deviation from linear %g",
          (double)top, nonfinite, dev);
    wrt_runtime_close(rt);

    /* the path tracer, emission on hit, against the same closed form */
    wrt_ref *ref = wrt_ref_create(&s);
    CHECK(ref != NULL, "ref: %s", wrt_last_error());
    if (ref) {
        double ind[NCELL * NCELL * 3], se[NCELL * NCELL * 3];
        CHECK(wrt_ref_cell_irradiance(ref, NULL, 0, 1, NCELL, 4000, 0, 2, 7, NULL, ind, se) == WRT_OK, "ref cells");
        int bad = 0;
        double z = 0;
        for (int j = 0; j < NCELL; j++)
            for (int i = 0; i < NCELL; i++) {
                int k = (j * NCELL + i) * 3;
                double zz = fabs(ind[k] - truth_cell(i, j)) / se[k];
                z = fmax(z, zz);
                bad += zz > 4.5;
            }
        printf("  path tracer on the same cells: worst |error| %.2f standard errors\n", z);
        CHECK(bad == 0, "%d path-traced cells beyond 4.5 standard errors of B F", bad);
        wrt_ref_destroy(ref);
    }
    tsb_free(&s);
}

/* Albedo 0 in the blue channel: red and green carried, blue not (and said so). */
static void test_black_channel(void) {
    wrt_scene s;
    const double le[3] = {LE, LE, LE};
    facing_scene(&s, 0.5, le);
    s.materials[0].base_color[2] = 0;
    char path[512];
    if (!bake_to(&s, "black.gto", path, sizeof path)) { tsb_free(&s); return; }
    wrt_runtime *rt = NULL;
    wrt_error err;
    CHECK(wrt_runtime_open_file(path, NULL, &rt, &err) == WRT_OK, "open: %s", err.message);
    if (rt) {
        wrt_runtime_update(rt, NULL, NULL);
        double d[3], i[3];
        wrt_runtime_quad_irradiance(rt, 1, d, i, NULL);
        CHECK_NEAR(i[0], 0.19982, 0.002, "red carried");
        CHECK(i[2] == 0, "blue not carried: %g", i[2]);
        wrt_runtime_close(rt);
    }
    tsb_free(&s);
}

int main(int argc, char **argv) {
    (void)argc; (void)argv;
    setvbuf(stdout, NULL, _IOLBF, 0);
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wrt_emit_XXXXXX");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 2; }
    TEST_RUN(test_closed_form);
    TEST_RUN(test_black_channel);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_END();
}
