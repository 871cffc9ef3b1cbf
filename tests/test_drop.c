/* test_drop.c: the stored operator's drop rule (precompute/drop_rule.h) against truths
 * that do not depend on it: the rule's closed-form scales, and power in a closed box
 * (every bounce keeps rho of the light, so the indirect flux is rho / (1 - rho) of what
 * is injected, however it is distributed): light injected on one small cell excites
 * the fine sender wavelets whose entries the rule drops most, and the compression must
 * hand their power to the entries it keeps. */
#include <stdlib.h>
#include <string.h>

#include "common/basis.h"
#include "precompute/bake.h"
#include "precompute/drop_rule.h"
#include "bake_helpers.h"
#include "claims.h"
#include "scene_build.h"
#include "test.h"

static void test_scales(void) {
    wrt_drop_rule r = {0.5, 1, 3, 0};
    wrt_node root = wrt_node_root(), l2 = {2, 1, 3};
    uint64_t kr = wrt_fkey_make(7, root, 0, root, 0), k0 = wrt_fkey_make(7, root, 2, root, 0);
    uint64_t k2 = wrt_fkey_make(7, l2, 1, root, 0), k4 = wrt_fkey_make(7, (wrt_node){4, 9, 2}, 3, root, 0);
    CHECK(wrt_drop_depth(kr) == 0 && wrt_drop_depth(k0) == 1 && wrt_drop_depth(k2) == 3 && wrt_drop_depth(k4) == 5,
          "depths %d %d %d %d, want 0 1 3 5", wrt_drop_depth(kr), wrt_drop_depth(k0), wrt_drop_depth(k2), wrt_drop_depth(k4));
    CHECK(wrt_drop_col_scale(&r, kr) == 1 && fabs(wrt_drop_col_scale(&r, k2) - 1 / sqrt(8.0)) < 1e-15 &&
          fabs(wrt_drop_col_scale(&r, k4) - 1 / sqrt(32.0)) < 1e-15, "sender scales %.17g %.17g",
          wrt_drop_col_scale(&r, k2), wrt_drop_col_scale(&r, k4));
    CHECK(wrt_drop_row_scale(&r, k2) == 1 && wrt_drop_row_scale(&r, k4) == 0.25, "receiver scales %.17g %.17g",
          wrt_drop_row_scale(&r, k2), wrt_drop_row_scale(&r, k4));
    /* sized: a quad of side 4 with size_ref 1 counts depth from its supports of side 1 (d - 2) */
    wrt_drop_rule sz = {0.5, 1, 3, 1.0};
    CHECK(fabs(wrt_drop_col_scale_sized(&sz, k4, 4) - exp2(-1.5)) < 1e-15 &&
          fabs(wrt_drop_col_scale_sized(&sz, k4, 0.5) - exp2(-2.5)) < 1e-15 && wrt_drop_col_scale_sized(&sz, k4, 64) == 1 &&
          wrt_drop_col_scale_sized(&sz, kr, 4) == 1 && fabs(wrt_drop_col_scale_sized(&r, k4, 4) - exp2(-2.5)) < 1e-15,
          "sized sender scales %.17g %.17g %.17g", wrt_drop_col_scale_sized(&sz, k4, 4), wrt_drop_col_scale_sized(&sz, k4, 0.5),
          wrt_drop_col_scale_sized(&sz, k4, 64));
    wrt_drop_rule off = {0, 0, 0, 0};
    CHECK(wrt_drop_col_scale(&off, k4) == 1 && wrt_drop_row_scale(&off, k4) == 1 && wrt_drop_col_scale(NULL, k4) == 1,
          "a rule of zeros scales nothing");
}

/* Light on cell (3, cx, cy) of quad q of a closed box of albedo rho; the indirect flux
 * (the roots' coefficients times sqrt(pi A): wavelets carry none) over the flux in. */
static double cell_furnace(double rho, double ds, double dr, uint64_t *entries) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, rho, rho, rho);
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 2, m);
    wrt_bake_options o = opts(5, 0, 0);
    o.drop_sender = ds; o.drop_receiver = dr; o.drop_receiver_from = 3; /* -1: none */
    wrt_bake_result r;
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double *x = calloc(3 * (size_t)r.nfuncs, sizeof *x), *y = calloc(3 * (size_t)r.nfuncs, sizeof *y);
    const int q = 5, level = 3, cx = 5, cy = 2;
    double A = s.quads[q].area, sz = ldexp(1.0, -level), cu = (cx + 0.5) * sz, cv = (cy + 0.5) * sz;
    for (uint32_t f = 0; f < r.nfuncs; f++) { /* uniform irradiance 1 on the cell */
        uint64_t k = r.fkeys[f];
        if (wrt_fkey_quad(k) != (uint32_t)q || !wrt_fkey_angular_root(k)) continue;
        wrt_node n = wrt_fkey_snode(k);
        if (n.level >= level) continue;
        double v = sqrt(A / M_PI) * sz * sz * wrt_haar2(n, wrt_fkey_stype(k), cu, cv);
        for (int c = 0; c < 3; c++) x[3 * f + c] = v;
    }
    wrt_csc_apply(&r.op, x, y);
    double in = 0, out = 0;
    for (int p = 0; p < s.nquads; p++) {
        int64_t f = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(p));
        double k = sqrt(M_PI * s.quads[p].area);
        in += x[3 * f] * k;
        out += y[3 * f] * k;
    }
    CHECK(fabs(in / (A * sz * sz) - 1) < 1e-12, "flux in %.15g, want the cell's area %.15g", in, A * sz * sz);
    *entries = r.op.nnz;
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
    return out / in / (rho / (1 - rho));
}

static void test_power_kept(void) {
    uint64_t e0, e1;
    double f0 = cell_furnace(0.9, -1, -1, &e0), f1 = cell_furnace(0.9, 1, 1, &e1);
    printf("closed box, rho 0.9, light on one level-3 cell: indirect flux / truth %.6f with %llu entries, %.6f with "
           "--drop-sender 1 --drop-receiver 1 (%llu entries)\n", f0, (unsigned long long)e0, f1, (unsigned long long)e1);
    CHECK(e1 < e0, "the rule drops entries: %llu -> %llu", (unsigned long long)e0, (unsigned long long)e1);
    CHECK_CLAIM("drop-furnace-cell", f1 - 1, CLAIM_FURNACE, "the rule on: flux / truth %.6f", f1);
    CHECK_CLAIM("drop-furnace-cell-off", f0 - 1, CLAIM_FURNACE, "the rule off: flux / truth %.6f", f0);
}

int main(int argc, char **argv) {
    TEST_RUN(test_scales);
    TEST_RUN(test_power_kept);
    TEST_END();
}
