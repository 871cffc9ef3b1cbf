/* test_accuracy.c: the bake and the player against the path tracer (verify/reference.h,
 * through verify/compare.h, the measurement of the accuracy study) on assets/cornell.gltf,
 * an open scene, at the default quality, with COLOURED lights and coloured walls (its red
 * and green walls, the back wall tinted blue), so that a fault mixing channels anywhere
 * (the bake's albedos, the balance, the tail, the projection's light colour, the
 * multiply, the synthesis) shows in some channel. Asserts the cell error at the study's
 * figure plus a point, each channel's energy against the path tracer's, and the same
 * with the power balance off: in an open scene the balance cannot make the totals right
 * by construction, so this is a truth check of the transport and of what the balance
 * changes. Thresholds: tests/claims.h. About 10 s. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "claims.h"
#include "formats/gto.h"
#include "precompute/bake.h"
#include "test.h"
#include "verify/compare.h"

static char tmpdir[256];

/* Loads cornell and tints its back wall blue (a new material). */
static int load_scene(wrt_scene *s) {
    wrt_load_options lo = {0};
    if (wrt_scene_load("assets/cornell.gltf", &lo, s) != WRT_OK) return 0;
    s->materials = realloc(s->materials, (size_t)(s->nmaterials + 1) * sizeof *s->materials);
    wrt_material *m = &s->materials[s->nmaterials];
    *m = s->materials[0];
    snprintf(m->name, sizeof m->name, "blue");
    m->base_color[0] = 0.3f; m->base_color[1] = 0.4f; m->base_color[2] = 0.75f;
    int nb = 0;
    for (int q = 0; q < s->nquads; q++)
        if (s->quads[q].name >= 0 && strcmp(s->names[s->quads[q].name], "back_wall") == 0) {
            s->quads[q].material = s->nmaterials;
            nb++;
        }
    s->nmaterials++;
    return nb > 0;
}

typedef struct measured {
    double cell_rmse, cell_floor, cell_debiased, ratio, chan[3];
} measured;

/* Bakes s at quality 5 (balance on or off), writes and opens the .gto, compares. */
static int bake_and_compare(const wrt_scene *s, const wrt_compare_ref *ref, int nl, int no_balance, measured *out) {
    wrt_bake_options o = {0};
    o.quality = 5;
    o.threads = 2;
    o.no_balance = no_balance;
    wrt_bake_result r;
    wrt_status st = wrt_bake_run(s, &o, &r);
    CHECK(st == WRT_OK, "bake: %s", wrt_last_error());
    if (st != WRT_OK) return 0;
    char path[300];
    snprintf(path, sizeof path, "%s/b%d.gto", tmpdir, no_balance);
    wrt_gto_contents gc = {
        .scene = s, .fkeys = r.fkeys, .nfuncs = r.nfuncs, .col_start = r.op.col, .rows = r.op.row,
        .vals = r.op.val, .op_kind = (uint32_t)r.op_kind, .material_alevel = r.material_alevel,
    };
    st = wrt_gto_write(path, &gc);
    wrt_bake_result_free(&r);
    CHECK(st == WRT_OK, "gto write: %s", wrt_last_error());
    if (st != WRT_OK) return 0;
    wrt_gto g;
    st = wrt_gto_open(path, &g);
    CHECK(st == WRT_OK, "gto open: %s", wrt_last_error());
    if (st != WRT_OK) return 0;
    wrt_compare_result res;
    st = wrt_compare_gto(ref, &g, &res);
    CHECK(st == WRT_OK, "compare: %s", wrt_last_error());
    if (st == WRT_OK) {
        out->cell_rmse = res.mean.cell_rmse;
        out->cell_floor = res.mean.cell_floor;
        out->cell_debiased = res.mean.cell_debiased;
        out->ratio = res.mean.cell_ratio;
        /* each channel's energy: sum over cells of area x irradiance, bake over reference */
        double w[3] = {0, 0, 0}, t[3] = {0, 0, 0};
        int n = 4;
        for (int l = 0; l < nl; l++)
            for (int q = 0; q < s->nquads; q++) {
                const double *W = wrt_compare_cells(ref, l, q, 1, NULL), *R = wrt_compare_cells(ref, l, q, 0, NULL);
                if (!W || !R) continue;
                for (int k = 0; k < n * n; k++)
                    for (int c = 0; c < 3; c++) {
                        w[c] += s->quads[q].area * W[3 * k + c];
                        t[c] += s->quads[q].area * R[3 * k + c];
                    }
            }
        for (int c = 0; c < 3; c++) out->chan[c] = t[c] > 0 ? w[c] / t[c] : 0;
    }
    wrt_gto_close(&g);
    unlink(path);
    return st == WRT_OK;
}

static void test_cornell_coloured(void) {
    wrt_scene s;
    if (!load_scene(&s)) {
        CHECK(0, "assets/cornell.gltf with a back_wall: %s", wrt_last_error());
        return;
    }
    wrt_light lights[2];
    int nl = wrt_compare_default_lights(&s, 2, lights);
    CHECK(nl == 2, "two light positions (%d)", nl);
    float colours[2][3] = {{1, 0.55f, 0.25f}, {0.3f, 0.6f, 1}};
    for (int l = 0; l < nl; l++)
        for (int c = 0; c < 3; c++) lights[l].color[c] = colours[l][c];
    wrt_compare_options co = {0};
    co.cell_paths = 1000000;
    co.width = -1;
    co.bench_updates = 3;
    co.threads = 2;
    wrt_compare_defaults(&co);
    wrt_compare_ref *ref = NULL;
    wrt_status st = wrt_compare_ref_create(&s, lights, nl, &co, &ref);
    CHECK(st == WRT_OK, "reference: %s", wrt_last_error());
    if (st != WRT_OK) { wrt_scene_free(&s); return; }
    measured on = {0}, off = {0};
    if (bake_and_compare(&s, ref, nl, 0, &on)) {
        CHECK_CLAIM("gate-cell-error", on.cell_debiased, CLAIM_GATE_CELL,
                    "cornell, coloured lights and walls, quality 5: cell error %.4f (debiased; raw %.4f, reference "
                    "floor %.4f); the study measures %.3f with a white light", on.cell_debiased, on.cell_rmse,
                    on.cell_floor, STUDY_CORNELL_Q5_CELL);
        CHECK_CLAIM("gate-energy", on.ratio - 1, CLAIM_GATE_ENERGY, "bake / path tracer energy over all cells %.5f",
                    on.ratio);
        for (int c = 0; c < 3; c++) {
            char id[40];
            snprintf(id, sizeof id, "gate-energy-channel-%d", c);
            CHECK_CLAIM(id, on.chan[c] - 1, CLAIM_GATE_ENERGY, "channel %d: bake / path tracer energy %.5f", c, on.chan[c]);
        }
    }
    if (bake_and_compare(&s, ref, nl, 1, &off)) {
        CHECK_CLAIM("gate-unbalanced-cell-error", off.cell_debiased, CLAIM_GATE_CELL_UNBALANCED,
                    "the same bake with --no-balance: cell error %.4f (debiased; raw %.4f), energy %.5f", off.cell_debiased,
                    off.cell_rmse, off.ratio);
        CHECK_CLAIM("gate-balance-effect", on.ratio / off.ratio - 1, CLAIM_GATE_BALANCE_EFFECT,
                    "what the balance changes in this open scene's energy: %.5f with, %.5f without", on.ratio, off.ratio);
    }
    wrt_compare_ref_destroy(ref);
    wrt_scene_free(&s);
}

int main(int argc, char **argv) {
    setvbuf(stdout, NULL, _IOLBF, 0);
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wrt_accuracy_XXXXXX");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    TEST_RUN(test_cornell_coloured);
    rmdir(tmpdir);
    TEST_END();
}
