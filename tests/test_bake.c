/* test_bake.c: the bake (precompute/) against truths that do not depend on it: closed-form
 * form factors, reciprocity, the per-cell distribution of light from one small cell
 * (closed-form rectangle-to-rectangle form factors), the furnace, the effect counters, and
 * identical output whatever the thread count. */
#include <stdlib.h>
#include <string.h>

#include "common/basis.h"
#include "common/brdf.h"
#include "common/brdf_table.h"
#include "ff_closed.h"
#include "precompute/bake.h"
#include "bake_helpers.h"
#include "claims.h"
#include "scene_build.h"
#include "test.h"





/* Coefficients (channel 0 = 1 = 2) of a uniform irradiance E0 over cell (level, cx, cy)
 * of quad q (a parallelogram of area A): E0 sqrt(A/pi) * integral over the cell of h. */
static void inject_cell(const wrt_bake_result *r, int q, double area, int level, int cx, int cy, double E0, double *x) {
    double sz = ldexp(1.0, -level), cu = (cx + 0.5) * sz, cv = (cy + 0.5) * sz;
    for (uint32_t f = 0; f < r->nfuncs; f++) {
        uint64_t k = r->fkeys[f];
        if (wrt_fkey_quad(k) != (uint32_t)q || !wrt_fkey_angular_root(k)) continue;
        wrt_node n = wrt_fkey_snode(k);
        if (n.level >= level) continue; /* finer functions integrate to zero over the cell */
        double v = E0 * sqrt(area / M_PI) * sz * sz * wrt_haar2(n, wrt_fkey_stype(k), cu, cv);
        for (int c = 0; c < 3; c++) x[3 * f + c] += v;
    }
}

/* Mean irradiance over cell (level, cx, cy) of quad q from coefficients y. */
static double cell_irradiance(const wrt_bake_result *r, int q, double area, int level, int cx, int cy, const double *y) {
    double sz = ldexp(1.0, -level), cu = (cx + 0.5) * sz, cv = (cy + 0.5) * sz, e = 0;
    for (uint32_t f = 0; f < r->nfuncs; f++) {
        uint64_t k = r->fkeys[f];
        if (wrt_fkey_quad(k) != (uint32_t)q || !wrt_fkey_angular_root(k)) continue;
        wrt_node n = wrt_fkey_snode(k);
        if (n.level >= level) continue;
        e += y[3 * f] * wrt_haar2(n, wrt_fkey_stype(k), cu, cv);
    }
    return e * sqrt(M_PI / area);
}

static void test_closed_forms_themselves(void) {
    CHECK_NEAR(ffc_parallel(0, 1, 0, 1, 0, 1, 0, 1, 1), 0.19982, 5e-5, "facing unit squares");
    CHECK_NEAR(ffc_perpendicular(0, 1, 0, 1, 0, 1, 0, 1), 0.20004, 5e-5, "perpendicular unit squares");
}

static void test_point_polygon(void) {
    /* point under the centre of a unit square at height 1: 4 corner rectangles 0.5 x 0.5 */
    double A = 0.5, B = 0.5, a1 = sqrt(1 + A * A), b1 = sqrt(1 + B * B);
    double corner = (A / a1 * atan(B / a1) + B / b1 * atan(A / b1)) / (2 * M_PI);
    wrt_v3 sq[4] = {P(-.5, -.5, 1), P(.5, -.5, 1), P(.5, .5, 1), P(-.5, .5, 1)};
    double f = wrt_ff_point_polygon(P(0, 0, 0), P(0, 0, 1), sq, 4);
    CHECK_NEAR(f, 4 * corner, 1e-12, "point to square");
    /* half of the square behind the point's tangent plane is clipped away */
    wrt_v3 wall[4] = {P(1, -.5, -1), P(1, .5, -1), P(1, .5, 1), P(1, -.5, 1)};
    double fw = wrt_ff_point_polygon(P(0, 0, 0), P(0, 0, 1), wall, 4);
    wrt_v3 upper[4] = {P(1, -.5, 0), P(1, .5, 0), P(1, .5, 1), P(1, -.5, 1)};
    CHECK_NEAR(fw, wrt_ff_point_polygon(P(0, 0, 0), P(0, 0, 1), upper, 4), 1e-12, "clipping");
    /* small and far (every edge under tan 1/4: the arc tangent's series), and long and
     * thin (two edges by the series, two by atan2), against the corner rectangles */
    double dims[2][2] = {{0.05, 0.05}, {0.05, 2.0}};
    for (int c = 0; c < 2; c++) {
        A = dims[c][0]; B = dims[c][1]; a1 = sqrt(1 + A * A); b1 = sqrt(1 + B * B);
        corner = (A / a1 * atan(B / a1) + B / b1 * atan(A / b1)) / (2 * M_PI);
        wrt_v3 r[4] = {P(-A, -B, 1), P(A, -B, 1), P(A, B, 1), P(-A, B, 1)};
        f = wrt_ff_point_polygon(P(0, 0, 0), P(0, 0, 1), r, 4);
        CHECK_NEAR(f / (4 * corner), 1, 1e-11, c ? "point to a long thin rectangle" : "point to a small far square");
    }
}

static void facing_scene(wrt_scene *s, double rho) {
    tsb_init(s);
    int m = tsb_material(s, rho, rho, rho);
    tsb_quad(s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), m);   /* floor, +z */
    tsb_quad(s, P(0, 0, 1), P(0, 1, 1), P(1, 1, 1), P(1, 0, 1), m);   /* ceiling, -z */
}

static void perpendicular_scene(wrt_scene *s, double rho) {
    tsb_init(s);
    int m = tsb_material(s, rho, rho, rho);
    tsb_quad(s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), m);   /* floor, +z */
    tsb_quad(s, P(0, 0, 0), P(0, 1, 0), P(0, 1, 1), P(0, 0, 1), m);   /* wall x = 0, +x */
}

static void test_form_factors(void) {
    wrt_scene s;
    wrt_bake_result r;
    wrt_bake_options o = opts(5, 0, 0);
    facing_scene(&s, 1.0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double f = entry(&r, &r.dto, root_key(0), root_key(1)), ff = ffc_parallel(0, 1, 0, 1, 0, 1, 0, 1, 1);
    CHECK_CLAIM("ff-facing", f / ff - 1, CLAIM_FF, "facing unit squares: F = %.7f, closed form %.7f, rays %llu", f, ff,
                (unsigned long long)r.c.rays_traced);
    CHECK(r.c.rays_traced == 0 && r.c.rays_skipped_unoccluded > 0, "no occluder possible: no rays (%llu)",
          (unsigned long long)r.c.rays_traced);
    CHECK(r.c.entries_angular == 0, "diffuse: no angular entries");
    wrt_bake_result_free(&r);
    tsb_free(&s);

    perpendicular_scene(&s, 1.0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    f = entry(&r, &r.dto, root_key(0), root_key(1));
    double fp = ffc_perpendicular(0, 1, 0, 1, 0, 1, 0, 1);
    CHECK_CLAIM("ff-perpendicular", f / fp - 1, CLAIM_FF, "perpendicular unit squares: F = %.7f, closed form %.7f, "
                "leaves %llu", f, fp, (unsigned long long)r.c.links_leaf);
    double g = entry(&r, &r.dto, root_key(1), root_key(0));
    CHECK_CLAIM("ff-reciprocity", g / fp - 1, CLAIM_FF, "the reverse entry (equal areas) %.7f vs closed form %.7f", g, fp);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

static void test_reciprocity(void) {
    /* a 2 x 1 floor and a 0.5 x 0.7 tilted-free wall: A_i F_ij = A_j F_ji, and with rho = 1
     * T[r][s] = F_rs sqrt(A_r/A_s) is then symmetric */
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 1, 1, 1);
    tsb_quad(&s, P(0, 0, 0), P(2, 0, 0), P(2, 1, 0), P(0, 1, 0), m);
    tsb_quad(&s, P(0.3, 0.2, 0.4), P(0.3, 0.9, 0.4), P(0.3, 0.9, 0.9), P(0.3, 0.2, 0.9), m);
    wrt_bake_result r;
    wrt_bake_options o = opts(6, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double a = entry(&r, &r.dto, root_key(0), root_key(1)), b = entry(&r, &r.dto, root_key(1), root_key(0));
    double A0 = 2, A1 = 0.35;
    double F01 = a / sqrt(A0 / A1), F10 = b / sqrt(A1 / A0);
    CHECK_CLAIM("reciprocity", A0 * F01 / (A1 * F10) - 1, CLAIM_RECIPROCITY, "2 x 1 floor and 0.5 x 0.7 wall: A0 F01 = %.7f, "
                "A1 F10 = %.7f", A0 * F01, A1 * F10);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* Light one level-2 cell of the sender, compare the 16 receiver cells with closed forms. */
static void distribution_case(int perpendicular, int ex, int ey, int own_thresholds, double tol, double *worst_out) {
    wrt_scene s;
    if (perpendicular) perpendicular_scene(&s, 1.0);
    else facing_scene(&s, 1.0);
    wrt_bake_result r;
    wrt_bake_options o = opts(7, 2, 5);
    /* one receiver threshold at every level (quality 7's 0.0025), as the claim was measured:
     * with quality 7's finer threshold for the cells coarser than 8 x 8 (bake.c) the worst
     * cell measured 0.11% (parallel) and 0.23% (perpendicular) instead of 0.03% and 0.09%.
     * That is the power balance's share (balance.c re-derives root rows over more mixed
     * levels): without the balance the cells are within 0.0043% under either threshold. */
    if (!own_thresholds) o.eps_receiver = o.eps_receiver_coarse = 0.16 * ldexp(1.0, -6);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    inject_cell(&r, 1, 1.0, 2, ex, ey, 1.0, x);
    wrt_csc_apply(&r.dto, x, y);
    /* sender cell (ex, ey): u along p1 - p0, v along p3 - p0 of quad 1 */
    double u0 = ex / 4.0, u1 = u0 + 0.25, v0 = ey / 4.0, v1 = v0 + 0.25;
    double emax = 0, worst = 0;
    double truth[16], got[16];
    for (int j = 0; j < 16; j++) {
        int cx = j % 4, cy = j / 4;
        double x1 = cx / 4.0, x2 = x1 + 0.25, y1 = cy / 4.0, y2 = y1 + 0.25;
        /* facing: quad 1 u runs along y, v along x; perpendicular: u along y, v along z */
        truth[j] = perpendicular ? ffc_perpendicular(x1, x2, y1, y2, v0, v1, u0, u1)
                                 : ffc_parallel(x1, x2, y1, y2, v0, v1, u0, u1, 1.0);
        got[j] = cell_irradiance(&r, 0, 1.0, 2, cx, cy, y);
        emax = fmax(emax, truth[j]);
    }
    for (int j = 0; j < 16; j++) {
        double err = fabs(got[j] - truth[j]) / fmax(truth[j], 0.1 * emax);
        worst = fmax(worst, err);
        CHECK(err <= tol, "%s: cell %d: %.6f vs closed form %.6f (%.4f%%)", perpendicular ? "perpendicular" : "parallel",
              j, got[j], truth[j], 100 * err);
    }
    *worst_out = worst;
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

static void test_distribution(void) {
    double w1, w2, w3;
    distribution_case(0, 1, 2, 0, CLAIM_DIST, &w1);
    distribution_case(1, 0, 1, 0, CLAIM_DIST, &w2);
    distribution_case(1, 2, 3, 0, CLAIM_DIST, &w3);
    CHECK_CLAIM("distribution-parallel", w1, CLAIM_DIST, "worst of 16 receiver cells, sender cell (1, 2)");
    CHECK_CLAIM("distribution-perpendicular", fmax(w2, w3), CLAIM_DIST, "worst of 2 x 16 receiver cells, sender cells "
                "(0, 1): %.4f%%, (2, 3): %.4f%%", 100 * w2, 100 * w3);
    /* the same cases at quality 7's own thresholds (the finer one for coarse cells) */
    distribution_case(0, 1, 2, 1, CLAIM_DIST_OWN, &w1);
    distribution_case(1, 0, 1, 1, CLAIM_DIST_OWN, &w2);
    distribution_case(1, 2, 3, 1, CLAIM_DIST_OWN, &w3);
    CHECK_CLAIM("distribution-parallel-own-thresholds", w1, CLAIM_DIST_OWN, "quality 7's thresholds, sender cell (1, 2)");
    CHECK_CLAIM("distribution-perpendicular-own-thresholds", fmax(w2, w3), CLAIM_DIST_OWN, "quality 7's thresholds, "
                "sender cells (0, 1): %.4f%%, (2, 3): %.4f%%", 100 * w2, 100 * w3);
}


/* The oracle's share rule (bake.h depth_share): a floor of 8 x 8 small quads (each 1/128
 * of the scene's area) beside a whole wall, perpendicular, albedo 1. With the rule at 0.125
 * (weight sqrt(share / 0.125) = 0.25, what an atrium element of share 6e-5 gets from the
 * default 1e-3) the small quads' pairs must refine less, and what they keep must still
 * match the closed forms: each small quad's form factor to the wall (its root entry, the
 * shared edge's singularity included), the wall's 4 x 4 cells lit by the uniform floor,
 * and each small quad's 2 x 2 cells lit by the uniform wall (the detail the rule
 * coarsens). Returns the DTO's entries. */
static void inject_root(const wrt_bake_result *r, int q, double area, double *x) {
    int64_t f = wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q));
    for (int c = 0; c < 3; c++) x[3 * f + c] += sqrt(area / M_PI);
}

static uint64_t depth_share_case(double share, double *ff_err, double *wall_err, double *cell_err) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 1, 1, 1);
    const int n = 8;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double x0 = (double)i / n, x1 = (double)(i + 1) / n, y0 = (double)j / n, y1 = (double)(j + 1) / n;
            tsb_quad(&s, P(x0, y0, 0), P(x1, y0, 0), P(x1, y1, 0), P(x0, y1, 0), m); /* floor, +z */
        }
    int wall = tsb_quad(&s, P(0, 0, 0), P(0, 1, 0), P(0, 1, 1), P(0, 0, 1), m); /* x = 0, +x; u along y, v along z */
    wrt_bake_result r;
    wrt_bake_options o = opts(5, 0, 0);
    o.depth_share = share;
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double a = 1.0 / (n * n);
    *ff_err = *wall_err = *cell_err = 0;
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    for (int q = 0; q < n * n; q++) {
        double x0 = (double)(q % n) / n, y0 = (double)(q / n) / n;
        double f = entry(&r, &r.dto, root_key(q), root_key(wall)) / sqrt(a);
        double t = ffc_perpendicular(x0, x0 + 1.0 / n, y0, y0 + 1.0 / n, 0, 1, 0, 1);
        *ff_err = fmax(*ff_err, fabs(f / t - 1));
        inject_root(&r, q, a, x); /* the floor at unit radiosity */
    }
    wrt_csc_apply(&r.dto, x, y);
    for (int j = 0; j < 16; j++) { /* the wall's cells: u (y) = cx, v (z) = cy */
        int cx = j % 4, cy = j / 4;
        double t = ffc_perpendicular(cy / 4.0, cy / 4.0 + 0.25, cx / 4.0, cx / 4.0 + 0.25, 0, 1, 0, 1);
        *wall_err = fmax(*wall_err, fabs(cell_irradiance(&r, wall, 1.0, 2, cx, cy, y) / t - 1));
    }
    memset(x, 0, 3 * r.nfuncs * sizeof *x);
    inject_root(&r, wall, 1.0, x); /* the wall at unit radiosity */
    wrt_csc_apply(&r.dto, x, y);
    for (int q = 0; q < n * n; q++)
        for (int c = 0; c < 4; c++) { /* quad q's 2 x 2 cells: u along x, v along y */
            double h = 0.5 / n, x0 = (double)(q % n) / n + (c & 1) * h, y0 = (double)(q / n) / n + (c >> 1) * h;
            double t = ffc_perpendicular(x0, x0 + h, y0, y0 + h, 0, 1, 0, 1);
            *cell_err = fmax(*cell_err, fabs(cell_irradiance(&r, q, a, 1, c & 1, c >> 1, y) / t - 1));
        }
    uint64_t nnz = r.dto.nnz;
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
    return nnz;
}

static void test_depth_share(void) {
    double ff0, wall0, cell0, ff1, wall1, cell1;
    uint64_t off = depth_share_case(-1, &ff0, &wall0, &cell0), on = depth_share_case(0.125, &ff1, &wall1, &cell1);
    printf("depth share: DTO entries %llu off, %llu on; worst form factor %.4f%% / %.4f%%, wall cell %.4f%% / "
           "%.4f%%, small quads' cells %.4f%% / %.4f%%\n", (unsigned long long)off, (unsigned long long)on,
           100 * ff0, 100 * ff1, 100 * wall0, 100 * wall1, 100 * cell0, 100 * cell1);
    CHECK(on < 0.7 * off, "the rule refines the small quads' pairs less: %llu entries against %llu",
          (unsigned long long)on, (unsigned long long)off);
    /* measured 0.24% with the rule off and on (the quad at the shared edge's end) */
    CHECK(ff1 <= 3e-3, "small quad to wall form factors within 0.3%% of the closed form: %.4f%%", 100 * ff1);
    CHECK(wall1 <= 1e-3, "the wall's cells lit by the floor within 0.1%%: %.4f%%", 100 * wall1); /* 0.010% */
    CHECK(cell1 <= 1e-2, "the small quads' 2 x 2 cells lit by the wall within 1%%: %.4f%%", 100 * cell1); /* 0.25% */
    /* the default share leaves a quad of 1/128 of the scene as it was */
    double ffd, walld, celld;
    CHECK(depth_share_case(0, &ffd, &walld, &celld) == off, "the default 1e-3 leaves shares of 7.8e-3 alone");
}

/* Uniform irradiance 1 injected on every quad of a closed box of albedo rho, G - I applied:
 * returns the indirect flux over its truth rho / (1 - rho) x flux in, and the worst quad's
 * relative error in *worst_quad. */
static double furnace(double rho, int n, int quality, int no_balance, double *worst_quad, wrt_bake_result *out) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, rho, rho, rho);
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), n, m);
    wrt_bake_result r;
    wrt_bake_options o = opts(quality, 0, 0);
    o.no_balance = no_balance;
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double *irr = root_response(&s, &r);
    double flux_in = 0, flux = 0, worst = 0, expect = rho / (1 - rho);
    for (int q = 0; q < s.nquads; q++) {
        double e = irr[3 * q];
        flux_in += s.quads[q].area;
        flux += e * s.quads[q].area;
        worst = fmax(worst, fabs(e / expect - 1));
    }
    free(irr);
    tsb_free(&s);
    if (out) *out = r;
    else wrt_bake_result_free(&r);
    *worst_quad = worst;
    return flux / flux_in / expect;
}

static void test_furnace(void) {
    double rhos[2] = {0.5, 0.9};
    for (int i = 0; i < 2; i++) {
        wrt_bake_result r;
        double worst, ratio = furnace(rhos[i], 2, 5, 0, &worst, &r);
        char id[64];
        snprintf(id, sizeof id, "furnace-flux-%.2f", rhos[i]);
        CHECK_CLAIM(id, ratio - 1, CLAIM_FURNACE, "box of 24 quads, quality 5: indirect flux / truth %.6f", ratio);
        snprintf(id, sizeof id, "furnace-quad-%.2f", rhos[i]);
        CHECK_CLAIM(id, worst, CLAIM_FURNACE, "box of 24 quads, quality 5: the worst quad's indirect irradiance");
        printf("furnace: %u funcs, dto %llu entries %llu links, gto %llu entries, t_dto %.2f s t_gto %.2f s, leaves %llu\n",
               r.nfuncs, (unsigned long long)r.dto.nnz, (unsigned long long)r.c.links_dto,
               (unsigned long long)r.op.nnz, r.c.t_dto, r.c.t_gto, (unsigned long long)r.c.links_leaf);
        printf("furnace rho %.2f: indirect flux / (direct rho/(1-rho)) = %.4f, bounces %llu, energy left %.2e, "
               "tail %.2e\n", rhos[i], ratio, (unsigned long long)r.c.bounces, r.c.energy_left, r.c.tail_fraction);
        wrt_bake_result_free(&r);
    }
    /* The same box without the power balance, which in a closed box makes every column's
     * total right by construction: the transport's own accuracy, against the stated bound
     * (the balance may correct at most this much at albedo 0.5) */
    double worst_off, ratio_off = furnace(0.5, 2, 5, 1, &worst_off, NULL);
    CHECK_CLAIM("furnace-unbalanced-0.50", fmax(worst_off, fabs(ratio_off - 1)), CLAIM_UNBALANCED,
                "rho 0.5 with --no-balance: flux %+.4f%%, worst quad %.4f%%", 100 * (ratio_off - 1), 100 * worst_off);
}

/* A closed box of coloured albedo (0.5, 0.9, 0.99): each channel is its own furnace,
 * rho_c / (1 - rho_c) on every quad, so a fault that takes one channel's albedo, tail
 * ratio or coefficient for another (the balance, the series, compression, the sparse
 * products) shows as a channel off by a factor up to 99. */
static void test_coloured_furnace(void) {
    double rho[3] = {0.5, 0.9, 0.99};
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, rho[0], rho[1], rho[2]);
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 1, m);
    wrt_bake_result r;
    wrt_bake_options o = opts(4, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double *irr = root_response(&s, &r);
    for (int c = 0; c < 3; c++) {
        double truth = rho[c] / (1 - rho[c]), worst = 0;
        for (int q = 0; q < s.nquads; q++) worst = fmax(worst, fabs(irr[3 * q + c] / truth - 1));
        char id[48];
        snprintf(id, sizeof id, "furnace-coloured-channel-%d", c);
        CHECK_CLAIM(id, worst, CLAIM_FURNACE, "albedo %.2f: worst quad vs %.6g (bounces %llu)", rho[c], truth,
                    (unsigned long long)r.c.bounces);
    }
    free(irr);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* A closed box whose floor is 8 x 8 small quads beside whole walls (albedo 0.9): the
 * furnace's truth rho / (1 - rho) still holds on every quad, but a small quad's root
 * entries to the far walls are form factors of ~0.003, the size compression weighs, and
 * its links see the walls through few cells. The flux is held at the furnace claim; single
 * quads are a measured limit (4.0% at quality 4, 1.8% at 5, 5.5% at 3), stated in README. */
static void test_small_quads_furnace(void) {
    double rho = 0.9, truth = rho / (1 - rho);
    wrt_scene s, fine;
    tsb_init(&s);
    int m = tsb_material(&s, rho, rho, rho);
    /* a closed box whose floor is 8 x 8 small quads: a small quad's root entries to the
     * far walls are form factors of ~0.003, under the threshold, and carry power */
    tsb_init(&fine);
    tsb_material(&fine, rho, rho, rho);
    tsb_box_inward(&fine, P(0, 0, 0), P(1, 1, 1), 8, 0);
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 1, m);
    for (int q = 0; q < fine.nquads; q++)
        if (fine.quads[q].n.z > 0.5)
            tsb_quad(&s, fine.quads[q].p[0], fine.quads[q].p[1], fine.quads[q].p[2], fine.quads[q].p[3], m);
    for (int q = 0; q < s.nquads; q++) /* drop the coarse floor (the first +z quad) */
        if (s.quads[q].n.z > 0.5) { memmove(&s.quads[q], &s.quads[q + 1], (size_t)(s.nquads - q - 1) * sizeof *s.quads); s.nquads--; break; }
    tsb_free(&fine);
    wrt_bake_result r;
    wrt_bake_options o = opts(4, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double *irr = root_response(&s, &r);
    double flux = 0, area = 0, worst = 0;
    for (int q = 0; q < s.nquads; q++) {
        double e = irr[3 * q];
        worst = fmax(worst, fabs(e / truth - 1));
        flux += e * s.quads[q].area;
        area += s.quads[q].area;
    }
    CHECK_CLAIM("furnace-small-quads-flux", flux / area / truth - 1, CLAIM_FURNACE, "albedo 0.9, a floor of 8 x 8 "
                "quads, quality 4: %llu entries in G - I, bounces %llu", (unsigned long long)r.op.nnz,
                (unsigned long long)r.c.bounces);
    CHECK_CLAIM("furnace-small-quads-quad", worst, CLAIM_FURNACE_SMALL_QUADS, "the same box: the worst quad");
    free(irr);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* Power of each sender column of T: sum_r sqrt(A_r) T[root_r][j] (parallelograms), the
 * power its unit coefficient delivers; in a closed box a diffuse sender's root function
 * delivers rho sqrt(A_s) (all it emits is caught) and a wavelet 0 (it emits nothing net).
 * Returns the worst error of each kind relative to rho sqrt(A_s). */
static void column_power(const wrt_scene *s, const wrt_bake_result *r, double rho, double *root_err, double *wav_err) {
    double *pw = calloc(r->nfuncs, sizeof *pw);
    for (int q = 0; q < s->nquads; q++) pw[wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q))] = sqrt(s->quads[q].area);
    *root_err = *wav_err = 0;
    for (uint32_t j = 0; j < r->nfuncs; j++) {
        double p = 0, scale = rho * sqrt(s->quads[wrt_fkey_quad(r->fkeys[j])].area);
        for (uint64_t k = r->dto.col[j]; k < r->dto.col[j + 1]; k++) p += pw[r->dto.row[k]] * r->dto.val[3 * k];
        if (wrt_fkey_stype(r->fkeys[j]) == 0 && wrt_fkey_snode(r->fkeys[j]).level == 0)
            *root_err = fmax(*root_err, fabs(p / scale - 1));
        else
            *wav_err = fmax(*wav_err, fabs(p) / scale);
    }
    free(pw);
}

/* Dominant eigenvalue of T by power iteration from a uniform start. */
static double dominant_eigenvalue(const wrt_scene *s, const wrt_bake_result *r) {
    double *x = calloc(3 * r->nfuncs, sizeof *x), *y = calloc(3 * r->nfuncs, sizeof *y), lambda = 0;
    for (int q = 0; q < s->nquads; q++) x[3 * wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q))] = 1;
    for (int it = 0; it < 300; it++) {
        memset(y, 0, 3 * r->nfuncs * sizeof *y);
        wrt_csc_apply(&r->dto, x, y);
        double nx = 0, ny = 0;
        for (uint32_t f = 0; f < 3 * r->nfuncs; f++) { nx += x[f] * x[f]; ny += y[f] * y[f]; }
        lambda = sqrt(ny / nx);
        for (uint32_t f = 0; f < 3 * r->nfuncs; f++) x[f] = y[f] / sqrt(ny);
    }
    free(x); free(y);
    return lambda;
}

/* The series' in-place sum (wrt_csc_add3_into) against the sum written out densely in
 * double: random 40 x 40 matrices of about 30% entries with empty columns and shared
 * rows, a per-channel scale; the same entries as wrt_csc_add3, bit for bit. */
static void test_add_in_place(void) {
    enum { N = 40 };
    uint32_t seed = 777;
    wrt_triplet ta[N * N], tb[N * N];
    uint64_t na = 0, nb = 0;
    static double dense[N][N][3];
    const double s[3] = {1, 0.5, -2};
    for (uint32_t j = 0; j < N; j++)
        for (uint32_t i = 0; i < N; i++) {
            for (int c = 0; c < 3; c++) dense[i][j][c] = 0;
            for (int w = 0; w < 2; w++) {
                seed = seed * 1664525u + 1013904223u;
                if ((seed >> 8) % 10 >= 3 || j % 7 == 3) continue;
                wrt_triplet *e = w ? &tb[nb++] : &ta[na++];
                e->row = i; e->col = j;
                for (int c = 0; c < 3; c++) {
                    e->v[c] = (float)((double)((seed >> 4) % 1000) / 997.0 - 0.4 + c);
                    dense[i][j][c] += (w ? s[c] : 1) * e->v[c];
                }
            }
        }
    wrt_csc a = wrt_csc_from_triplets(N, ta, na), b = wrt_csc_from_triplets(N, tb, nb);
    wrt_csc want = wrt_csc_add3(&a, &b, s);
    wrt_csc_add3_into(&a, &b, s);
    CHECK(a.nnz == want.nnz, "in-place sum has %llu entries, wrt_csc_add3 %llu", (unsigned long long)a.nnz,
          (unsigned long long)want.nnz);
    int same = a.nnz == want.nnz && !memcmp(a.col, want.col, (N + 1) * sizeof *a.col) &&
               !memcmp(a.row, want.row, a.nnz * sizeof *a.row) && !memcmp(a.val, want.val, 3 * a.nnz * sizeof *a.val);
    CHECK(same, "in-place sum differs from wrt_csc_add3");
    double worst = 0;
    for (uint32_t j = 0; j < N; j++)
        for (uint64_t k = a.col[j]; k < a.col[j + 1]; k++)
            for (int c = 0; c < 3; c++) {
                worst = fmax(worst, fabs(a.val[3 * k + c] - dense[a.row[k]][j][c]));
                dense[a.row[k]][j][c] = 0;
            }
    for (uint32_t i = 0; i < N; i++)
        for (uint32_t j = 0; j < N; j++)
            for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(dense[i][j][c]) > 0 ? 1 : 0);
    CHECK(worst < 1e-5, "in-place sum off the dense sum by %.3g (or an entry missing)", worst);
    printf("in-place sum: %llu + %llu entries -> %llu, worst difference from the dense sum %.2e\n",
           (unsigned long long)na, (unsigned long long)nb, (unsigned long long)a.nnz, worst);
    wrt_csc_free(&a); wrt_csc_free(&b); wrt_csc_free(&want);
}

/* Compression keeps each column's power (sum of power weight x entry), the property the
 * series relies on (precompute/sparse.h), also in a column whose power nearly cancels:
 * a wavelet sender's entries to receiver roots are of both signs and sum to what it
 * emits, 0. Columns built here: rows 0..7 carry power (weights 1..8), rows 8..11 do not;
 * each column keeps a few large entries of both signs and drops several small ones of one
 * sign, whose power exceeds what the kept entries of that sign carry (the case that
 * leaked before: +5e-4 of the light by the 10th term of a closed box with a box inside).
 * The truth is each column's power before compression, summed here in double. Both the
 * plain compression and the product's (A times the identity) are checked. */
static void test_compression_keeps_power(void) {
    enum { N = 12, C = 64 };
    double pw[N], rw[N], cw[N];
    for (int i = 0; i < N; i++) { pw[i] = i < 8 ? 1 + i : 0; rw[i] = cw[i] = 1; }
    wrt_triplet t[C * N];
    uint64_t nt = 0;
    uint32_t seed = 12345;
    double before[N][3];
    wrt_csc id = {0};
    {
        wrt_triplet it[N];
        for (uint32_t i = 0; i < N; i++) { it[i].row = it[i].col = i; it[i].v[0] = it[i].v[1] = it[i].v[2] = 1; }
        id = wrt_csc_from_triplets(N, it, N);
    }
    int checked[2] = {0, 0}, bad[2] = {0, 0};
    double worst[2] = {0, 0};
    for (int trial = 0; trial < C; trial++) {
        /* one N x N matrix per trial; column 0 is the cancelling one, the others random */
        nt = 0;
        for (uint32_t j = 0; j < N; j++) {
            for (uint32_t i = 0; i < N; i++) {
                seed = seed * 1664525u + 1013904223u;
                double u = (seed >> 8) / 16777216.0;
                float v;
                if (j == 0) {
                    /* kept: +0.02 on row 0, -0.5 on row 1, +-0.3 on rows 8..9; dropped: +0.004..0.009 on rows 2..7 */
                    v = i == 0 ? 0.02f : i == 1 ? -0.5f : i == 8 ? 0.3f : i == 9 ? -0.3f : i < 8 ? (float)(0.004 + 0.005 * u) : 0;
                } else {
                    v = (float)((u - 0.45) * (u < 0.5 ? 0.02 : 1.0));
                }
                if (v == 0) continue;
                t[nt].row = i; t[nt].col = j;
                for (int c = 0; c < 3; c++) t[nt].v[c] = v * (float)(1 + 0.1 * c);
                nt++;
            }
        }
        wrt_csc a = wrt_csc_from_triplets(N, t, nt);
        for (uint32_t j = 0; j < N; j++)
            for (int c = 0; c < 3; c++) {
                before[j][c] = 0;
                for (uint64_t k = a.col[j]; k < a.col[j + 1]; k++) before[j][c] += pw[a.row[k]] * a.val[3 * k + c];
            }
        wrt_csc_weights W = {rw, cw, pw, NULL, 0, NULL, 0};
        wrt_csc m = wrt_csc_mul(&a, &id, 0.01, &W, 2);
        wrt_csc cc = wrt_csc_copy_compress(&a, 0.01, &W);
        wrt_csc_compress(&a, 0.01, &W);
        /* the compressed copy (the series' first term) is the in-place compression's matrix */
        int same = cc.nnz == a.nnz && !memcmp(cc.col, a.col, (N + 1) * sizeof *a.col) &&
                   !memcmp(cc.row, a.row, a.nnz * sizeof *a.row) && !memcmp(cc.val, a.val, 3 * a.nnz * sizeof *a.val);
        CHECK(same, "trial %d: wrt_csc_copy_compress differs from wrt_csc_compress (%llu / %llu entries)", trial,
              (unsigned long long)cc.nnz, (unsigned long long)a.nnz);
        wrt_csc_free(&cc);
        const wrt_csc *ms[2] = {&a, &m};
        for (int w = 0; w < 2; w++)
            for (uint32_t j = 0; j < N; j++)
                for (int c = 0; c < 3; c++) {
                    double after = 0, size = 0;
                    for (uint64_t k = ms[w]->col[j]; k < ms[w]->col[j + 1]; k++) {
                        after += pw[ms[w]->row[k]] * ms[w]->val[3 * k + c];
                        size += pw[ms[w]->row[k]] * fabs(ms[w]->val[3 * k + c]);
                    }
                    /* a loss larger than all the column's kept power cannot be handed over
                     * without changing signs (documented); column 0 is built to take it */
                    if (j != 0 && size < fabs(before[j][c] - after)) continue;
                    double e = size > 0 ? fabs(after - before[j][c]) / size : fabs(after - before[j][c]);
                    worst[w] = fmax(worst[w], e);
                    bad[w] += e > 1e-6;
                    checked[w]++;
                }
        wrt_csc_free(&a); wrt_csc_free(&m);
    }
    wrt_csc_free(&id);
    for (int w = 0; w < 2; w++) {
        const char *what = w ? "the product's compression" : "compression";
        printf("%s keeps power: %d columns x channels, worst change %.2e of the column's kept power\n", what,
               checked[w], worst[w]);
        CHECK(bad[w] == 0, "%s: %d of %d columns x channels changed power by more than 1e-6 (worst %.2e)", what, bad[w],
              checked[w], worst[w]);
        CHECK(checked[w] > C * N, "%s: %d columns x channels checked", what, checked[w]);
    }
}

/* The small senders' rule (sparse.h boost_w, series.c): a column whose light is spread
 * thin over many receivers (every entry under the threshold: a closed scene of many small
 * elements) keeps its entries at rows that carry power, at the boosted threshold; a
 * column whose large entries already hold all but boost_lost of its power keeps the plain
 * threshold's entries, the dropped power handed to them; rows that carry no power are
 * never held by the rule. Checked against the column's own sums, in the compression and
 * in a product's (times the identity). */
static void test_small_sender_column(void) {
    enum { N = 48 };
    double pw[N], rw[N], cw[N], boost[N];
    for (int i = 0; i < N; i++) { pw[i] = i < 40 ? 1 : 0; rw[i] = cw[i] = 1; boost[i] = 4; }
    wrt_triplet t[3 * N], it[N];
    uint64_t nt = 0;
    for (uint32_t i = 0; i < N; i++) {
        it[i].row = it[i].col = i;
        it[i].v[0] = it[i].v[1] = it[i].v[2] = 1;
        /* column 0: 0.005 on every row (power rows 0..39: 0.2 of power, all under 0.01);
         * column 1: 0.9 on row 0, 0.004 on rows 1..20 (0.08: 8.2% of its power) and on
         * the powerless rows 40..47 */
        float v0 = 0.005f, v1 = i == 0 ? 0.9f : (i <= 20 || i >= 40) ? 0.004f : 0;
        t[nt].row = i; t[nt].col = 0; t[nt].v[0] = t[nt].v[1] = t[nt].v[2] = v0; nt++;
        if (v1 != 0) { t[nt].row = i; t[nt].col = 1; t[nt].v[0] = t[nt].v[1] = t[nt].v[2] = v1; nt++; }
    }
    wrt_csc id = wrt_csc_from_triplets(N, it, N);
    /* boost_lost 0.1: column 1 loses 8.2% at the plain threshold, so it is not boosted;
     * 0.05: it is. Column 0 loses all its power plainly: boosted in both. */
    const double lost[2] = {0.1, 0.05};
    for (int c = 0; c < 2; c++) {
        wrt_csc_weights W = {rw, cw, pw, boost, lost[c], NULL, 0};
        for (int prod = 0; prod < 2; prod++) {
            wrt_csc a = wrt_csc_from_triplets(N, t, nt), m;
            if (prod) m = wrt_csc_mul(&a, &id, 0.01, &W, 2);
            else { wrt_csc_compress(&a, 0.01, &W); m = a; memset(&a, 0, sizeof a); }
            uint64_t n0 = m.col[1] - m.col[0], n1 = m.col[2] - m.col[1];
            double p0 = 0, p1 = 0, top = 0;
            for (uint64_t k = m.col[0]; k < m.col[1]; k++) p0 += pw[m.row[k]] * m.val[3 * k];
            for (uint64_t k = m.col[1]; k < m.col[2]; k++) {
                p1 += pw[m.row[k]] * m.val[3 * k];
                if (m.row[k] == 0) top = m.val[3 * k];
            }
            const char *what = prod ? "product" : "compression";
            CHECK(n0 == 40 && fabs(p0 - 0.2) < 1e-6, "%s, lost %.2f: the spread column keeps %llu entries (40), power %.6f "
                  "(0.2)", what, lost[c], (unsigned long long)n0, p0);
            if (c == 0)
                CHECK(n1 == 1 && fabs(top - 0.98) < 1e-6, "%s: the held column keeps %llu entries (1), row 0 %.6f "
                      "(0.9 + the 0.08 dropped)", what, (unsigned long long)n1, top);
            else
                CHECK(n1 == 21 && fabs(top - 0.9) < 1e-6 && fabs(p1 - 0.98) < 1e-6, "%s: the boosted column keeps "
                      "%llu entries (21: not the powerless rows), row 0 %.6f (0.9), power %.6f (0.98)", what,
                      (unsigned long long)n1, top, p1);
            wrt_csc_free(&a); wrt_csc_free(&m);
        }
    }
    wrt_csc_free(&id);
}

/* The power balance (balance.c): links refined to mixed levels leave fine sender
 * wavelets delivering net power; the balance restores each column's power to the
 * pointwise closed forms, which in a closed box sum to exactly what is emitted. */
static void test_power_balance(void) {
    wrt_scene s;
    tsb_init(&s);
    double rho = 0.9;
    int m = tsb_material(&s, rho, rho, rho);
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 2, m);
    double lam[2], re[2], we[2];
    for (int nb = 0; nb < 2; nb++) {
        wrt_bake_options o = opts(5, 0, 0);
        o.dto_only = 1;
        o.no_balance = nb;
        wrt_bake_result r;
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
        column_power(&s, &r, rho, &re[nb], &we[nb]);
        lam[nb] = dominant_eigenvalue(&s, &r);
        printf("power balance %s: root columns' power error %.2e, wavelet columns' net power %.2e (of rho sqrt(A)), "
               "dominant eigenvalue %.6f for rho %.2f, %llu root entries set in %.3f s\n", nb ? "off" : "on", re[nb],
               we[nb], lam[nb], rho, (unsigned long long)r.c.balance_entries, r.c.t_balance);
        wrt_bake_result_free(&r);
    }
    CHECK(re[0] < 1e-5 && we[0] < 1e-5, "balanced: root power error %.2e, wavelet net power %.2e", re[0], we[0]);
    CHECK(fabs(lam[0] / rho - 1) < 1e-5, "balanced: dominant eigenvalue %.7f vs rho %.2f", lam[0], rho);
    /* the reason for the balance, measured: without it the operator gains energy */
    CHECK(we[1] > 1e-3 && lam[1] > rho * 1.001, "unbalanced: wavelet net power %.2e, eigenvalue %.6f", we[1], lam[1]);
    tsb_free(&s);
}

/* The same for a glossy sender (balance.c's second part): in a closed box of
 * roughness-0.05 metal, the power of each (spatial root, angular g) column of T must be
 * <g, a>, the angular function's projection of the directional albedo a(w), here
 * estimated independently of the bake by importance-sampling the BRDF on a 32 x 32 grid
 * of the concentric square. The links alone sample the narrow lobe at a few directions. */
static void test_glossy_power_balance(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.8, 0.8, 0.8);
    s.materials[m].lambertian = 0;
    s.materials[m].roughness = 0.05f;
    s.materials[m].metallic = 1;
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 1, m);
    enum { G = 32, NS = 2048 };
    double *a = calloc(G * G, sizeof *a);
    for (int c = 0; c < G * G; c++) {
        double d[3], acc = 0;
        wrt_concentric_dir((c % G + 0.5) / G, (c / G + 0.5) / G, d);
        for (int i = 0; i < NS; i++) {
            double w[3];
            wrt_brdf_sample(&s.materials[m], P(0, 0, 1), P(d[0], d[1], d[2]), (i + 0.5) / NS,
                            fmod(0.5 + i * 0.7548776662466927, 1.0), fmod(0.5 + i * 0.5698402909980532, 1.0), w);
            if (isfinite(w[0])) acc += w[0];
        }
        a[c] = acc / NS;
    }
    double worst[2] = {0, 0}, root[2] = {0, 0};
    for (int nb = 0; nb < 2; nb++) {
        wrt_bake_options o = opts(3, 0, 2);
        o.max_alevel = 2;
        o.dto_only = 1;
        o.no_balance = nb;
        wrt_bake_result r;
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
        double *pw = calloc(r.nfuncs, sizeof *pw);
        for (int q = 0; q < s.nquads; q++) pw[wrt_fkey_find(r.fkeys, r.nfuncs, root_key(q))] = sqrt(s.quads[q].area);
        int cols = 0;
        for (uint32_t j = 0; j < r.nfuncs; j++) {
            uint64_t k = r.fkeys[j];
            if (wrt_fkey_quad(k) != 0 || wrt_fkey_stype(k) != 0 || wrt_fkey_snode(k).level != 0) continue;
            double p = 0, t = 0;
            for (uint64_t e = r.dto.col[j]; e < r.dto.col[j + 1]; e++) p += pw[r.dto.row[e]] * r.dto.val[3 * e];
            for (int c = 0; c < G * G; c++)
                t += wrt_haar2(wrt_fkey_anode(k), wrt_fkey_atype(k), (c % G + 0.5) / G, (c / G + 0.5) / G) * a[c];
            t /= G * G;
            if (wrt_fkey_angular_root(k)) root[nb] = p / t - 1;
            else worst[nb] = fmax(worst[nb], fabs(p - t) / a[G * G / 2 + G / 2]);
            cols++;
        }
        CHECK(cols == 16, "16 angular functions at level 2 (got %d)", cols);
        printf("glossy power balance %s: root column power %+.3f%% of <1, a>; worst angular wavelet column off "
               "<g, a> by %.2f%% of the albedo\n", nb ? "off" : "on", 100 * root[nb], 100 * worst[nb]);
        free(pw);
        wrt_bake_result_free(&r);
    }
    CHECK(fabs(root[0]) < 0.005 && worst[0] < 0.001, "balanced: root %.4f, wavelets %.4f", root[0], worst[0]);
    CHECK(worst[1] > 0.01, "unbalanced: the links alone miss the lobe (wavelets off by %.4f)", worst[1]);
    free(a);
    tsb_free(&s);
}

static void test_coplanar_and_backfacing(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.8, 0.8, 0.8);
    tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), m);
    tsb_quad(&s, P(1, 0, 0), P(2, 0, 0), P(2, 1, 0), P(1, 1, 0), m);      /* coplanar neighbour */
    tsb_quad(&s, P(0, 0, -1), P(1, 0, -1), P(1, 1, -1), P(0, 1, -1), m);  /* below, facing away (+z, behind) */
    wrt_bake_result r;
    wrt_bake_options o = opts(5, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    CHECK(r.c.pairs_exchange == 0, "no pair can exchange light (%llu)", (unsigned long long)r.c.pairs_exchange);
    CHECK(r.c.pairs_skipped_facing == 6, "6 ordered pairs skipped (%llu)", (unsigned long long)r.c.pairs_skipped_facing);
    CHECK(r.c.rays_traced == 0 && r.dto.nnz == 0 && r.op.nnz == 0, "no rays, no entries");
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

static void test_threads_identical(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.7, 0.5, 0.3);
    tsb_box_inward(&s, P(0, 0, 0), P(2, 1, 1.5), 1, m);
    /* an occluder inside */
    tsb_quad(&s, P(0.8, 0.2, 0.5), P(1.2, 0.2, 0.5), P(1.2, 0.6, 0.5), P(0.8, 0.6, 0.5), m);
    tsb_quad(&s, P(0.8, 0.2, 0.5), P(0.8, 0.6, 0.5), P(1.2, 0.6, 0.5), P(1.2, 0.2, 0.5), m);
    wrt_bake_result a, b;
    wrt_bake_options o1 = opts(4, 0, 0), o2 = opts(4, 0, 0);
    o1.threads = 1; o2.threads = 2;
    CHECK(wrt_bake_run(&s, &o1, &a) == WRT_OK, "%s", wrt_last_error());
    CHECK(wrt_bake_run(&s, &o2, &b) == WRT_OK, "%s", wrt_last_error());
    CHECK(a.nfuncs == b.nfuncs && a.op.nnz == b.op.nnz, "same sizes");
    if (a.nfuncs == b.nfuncs && a.op.nnz == b.op.nnz) {
        CHECK(memcmp(a.fkeys, b.fkeys, a.nfuncs * 8) == 0, "same functions");
        CHECK(memcmp(a.op.row, b.op.row, a.op.nnz * 4) == 0 && memcmp(a.op.val, b.op.val, a.op.nnz * 12) == 0,
              "same operator bytes");
    }
    CHECK(a.c.rays_traced > 0, "occluded pairs trace rays (%llu)", (unsigned long long)a.c.rays_traced);
    wrt_bake_result_free(&a);
    wrt_bake_result_free(&b);
    tsb_free(&s);
}

/* consume_dto (wrt-bake's): the series takes T's arrays for its sum, with the power
 * iteration and the power targets computed before; the stored operator and the series'
 * figures must be the bits of the path that keeps T, and T gone. A coloured box with an
 * occluder (its series stops on the settled ratio and adds the tail) and the same box
 * at albedo 0.95 (more bounces, a larger tail). Consumed, the sum is streamed through
 * scratch files by column blocks (series_stream.h): by default, by blocks of 3 entries
 * (a block a column, the merges' and the norm's block boundaries everywhere), and in
 * memory (series_block < 0), each the same bits. */
static void test_consume_identical(void) {
    for (int k = 0; k < 6; k++) {
        if (k >= 2) { /* the streamed sum's block sizes */
            long long blocks[2] = {3, -1};
            wrt_scene s;
            tsb_init(&s);
            int m = k & 1 ? tsb_material(&s, 0.95, 0.9, 0.8) : tsb_material(&s, 0.7, 0.5, 0.3);
            tsb_box_inward(&s, P(0, 0, 0), P(2, 1, 1.5), 1, m);
            tsb_quad(&s, P(0.8, 0.2, 0.5), P(1.2, 0.2, 0.5), P(1.2, 0.6, 0.5), P(0.8, 0.6, 0.5), m);
            wrt_bake_result a, b;
            wrt_bake_options o1 = opts(4, 0, 0), o2 = opts(4, 0, 0);
            o2.consume_dto = 1;
            o2.series_block = blocks[(k - 2) / 2];
            CHECK(wrt_bake_run(&s, &o1, &a) == WRT_OK, "%s", wrt_last_error());
            CHECK(wrt_bake_run(&s, &o2, &b) == WRT_OK, "%s", wrt_last_error());
            int same = a.op.nnz == b.op.nnz && a.nfuncs == b.nfuncs &&
                       !memcmp(a.op.col, b.op.col, ((size_t)a.nfuncs + 1) * sizeof *a.op.col) &&
                       !memcmp(a.op.row, b.op.row, a.op.nnz * sizeof *a.op.row) &&
                       !memcmp(a.op.val, b.op.val, 3 * a.op.nnz * sizeof *a.op.val);
            CHECK(same && a.c.bounces == b.c.bounces && a.c.energy_left == b.c.energy_left &&
                      a.c.tail_fraction == b.c.tail_fraction && a.c.tail_fraction > 0,
                  "series_block %lld, albedo case %d: the operator or the figures differ (%llu / %llu entries, "
                  "energy left %.17g / %.17g)", o2.series_block, k & 1, (unsigned long long)a.op.nnz,
                  (unsigned long long)b.op.nnz, a.c.energy_left, b.c.energy_left);
            /* streamed, the late terms are added in the overlay and the early ones by
             * rewriting the file: both paths are taken */
            if (o2.series_block > 0)
                CHECK(b.c.sum_kept > 0 && b.c.sum_written > 0, "series_block %lld, albedo case %d: terms kept %llu, "
                      "written %llu", o2.series_block, k & 1, (unsigned long long)b.c.sum_kept,
                      (unsigned long long)b.c.sum_written);
            wrt_bake_result_free(&a);
            wrt_bake_result_free(&b);
            tsb_free(&s);
            continue;
        }
        wrt_scene s;
        tsb_init(&s);
        int m = k ? tsb_material(&s, 0.95, 0.9, 0.8) : tsb_material(&s, 0.7, 0.5, 0.3);
        tsb_box_inward(&s, P(0, 0, 0), P(2, 1, 1.5), 1, m);
        tsb_quad(&s, P(0.8, 0.2, 0.5), P(1.2, 0.2, 0.5), P(1.2, 0.6, 0.5), P(0.8, 0.6, 0.5), m);
        tsb_quad(&s, P(0.8, 0.2, 0.5), P(0.8, 0.6, 0.5), P(1.2, 0.6, 0.5), P(1.2, 0.2, 0.5), m);
        wrt_bake_result a, b;
        wrt_bake_options o1 = opts(4, 0, 0), o2 = opts(4, 0, 0);
        o2.consume_dto = 1;
        CHECK(wrt_bake_run(&s, &o1, &a) == WRT_OK, "%s", wrt_last_error());
        CHECK(wrt_bake_run(&s, &o2, &b) == WRT_OK, "%s", wrt_last_error());
        CHECK(a.dto.nnz > 0 && b.dto.nnz == 0 && !b.dto.row, "T kept (%llu entries) / consumed (%llu)",
              (unsigned long long)a.dto.nnz, (unsigned long long)b.dto.nnz);
        int same = a.op.nnz == b.op.nnz && a.nfuncs == b.nfuncs &&
                   !memcmp(a.op.col, b.op.col, ((size_t)a.nfuncs + 1) * sizeof *a.op.col) &&
                   !memcmp(a.op.row, b.op.row, a.op.nnz * sizeof *a.op.row) &&
                   !memcmp(a.op.val, b.op.val, 3 * a.op.nnz * sizeof *a.op.val);
        CHECK(same, "albedo case %d: the operator differs (%llu / %llu entries)", k, (unsigned long long)a.op.nnz,
              (unsigned long long)b.op.nnz);
        CHECK(a.c.bounces == b.c.bounces && a.c.series_ratio == b.c.series_ratio && a.c.energy_left == b.c.energy_left &&
                  a.c.tail_fraction == b.c.tail_fraction,
              "albedo case %d: the series' figures differ (bounces %llu / %llu, ratio %.9g / %.9g)", k,
              (unsigned long long)a.c.bounces, (unsigned long long)b.c.bounces, a.c.series_ratio, b.c.series_ratio);
        CHECK(a.c.tail_fraction > 0, "albedo case %d: the tail is used (%.3g)", k, a.c.tail_fraction);
        printf("consumed T: case %d, %llu entries stored, %llu bounces, ratio %.6f, tail %.3g, the same bits\n", k,
               (unsigned long long)b.op.nnz, (unsigned long long)b.c.bounces, b.c.series_ratio, b.c.tail_fraction);
        wrt_bake_result_free(&a);
        wrt_bake_result_free(&b);
        tsb_free(&s);
    }
}

/* Glossy sender (rough dielectric, roughness 0.4) lit by isotropic incident radiance
 * E/pi (angular root only): the irradiance it sends to a diffuse receiver cell is
 * integral over S of a(y->x) E/pi cos cos / d^2, a the directional albedo; brute force
 * with wrt_brdf_eval only. */
static double albedo(const wrt_material *m, wrt_v3 n, wrt_v3 wo) {
    /* cosine-weighted quadrature over the concentric square, 48 x 48 */
    double s = 0;
    int N = 24;
    wrt_v3 t = fabs(n.x) < 0.9 ? v3_norm(v3_cross(n, v3(1, 0, 0))) : v3_norm(v3_cross(n, v3(0, 1, 0)));
    wrt_v3 b = v3_cross(n, t);
    for (int i = 0; i < N; i++) for (int j = 0; j < N; j++) {
        double d[3], f[3];
        wrt_concentric_dir((i + 0.5) / N, (j + 0.5) / N, d);
        wrt_v3 wi = v3_add(v3_add(v3_scale(t, d[0]), v3_scale(b, d[1])), v3_scale(n, d[2]));
        wrt_brdf_eval(m, n, wi, wo, f);
        s += f[1] * M_PI;
    }
    return s / (N * N);
}

static void test_glossy_sender(void) {
    wrt_scene s;
    tsb_init(&s);
    int md = tsb_material(&s, 0.8, 0.8, 0.8);
    int mg = tsb_material(&s, 0.7, 0.7, 0.7);
    s.materials[mg].lambertian = 0; s.materials[mg].roughness = 0.4f; s.materials[mg].metallic = 0;
    tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), md);      /* receiver floor */
    tsb_quad(&s, P(0, 0, 0), P(0, 1, 0), P(0, 1, 1), P(0, 0, 1), mg);      /* glossy wall x = 0 */
    wrt_bake_result r;
    wrt_bake_options o = opts(5, 1, 5);
    o.max_alevel = 2; /* angular wavelets below the root on both sides */
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    CHECK(r.c.entries_angular > 0 && r.c.links_dto_glossy > 0, "glossy links carry angular entries (%llu)",
          (unsigned long long)r.c.entries_angular);
    CHECK(r.c.links_dto_diffuse == 0, "every pair here touches the glossy wall");
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    int64_t f = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(1));
    for (int c = 0; c < 3; c++) x[3 * f + c] = sqrt(1.0 / M_PI); /* E = 1 uniform, isotropic */
    wrt_csc_apply(&r.dto, x, y);
    double worst = 0;
    for (int cell = 0; cell < 4; cell++) {
        int cx = cell & 1, cy = cell >> 1;
        double got = cell_irradiance(&r, 0, 1.0, 1, cx, cy, y);
        /* brute force: receiver cell points x 20 x 20, sender 40 x 40 */
        double truth = 0;
        int NR = 6, NS = 24;
        for (int a = 0; a < NR * NR; a++) {
            wrt_v3 xp = P((cx + (a % NR + 0.5) / NR) * 0.5, (cy + (a / NR + 0.5) / NR) * 0.5, 0);
            for (int k = 0; k < NS * NS; k++) {
                wrt_v3 yp = P(0, (k % NS + 0.5) / NS, (k / NS + 0.5) / NS);
                wrt_v3 d = v3_sub(xp, yp);
                double d2 = v3_dot(d, d), dl = sqrt(d2);
                wrt_v3 wo = v3_scale(d, 1 / dl);
                double cy_ = wo.x, cx_ = -wo.z;
                if (cy_ <= 0 || cx_ <= 0) continue;
                truth += albedo(&s.materials[mg], P(1, 0, 0), wo) / M_PI * cx_ * cy_ / d2;
            }
        }
        truth /= (double)NR * NR * NS * NS;
        double err = fabs(got / truth - 1);
        worst = fmax(worst, err);
        CHECK(err < 0.03, "glossy sender cell %d: %.5f vs brute force %.5f", cell, got, truth);
    }
    printf("glossy sender: %llu angular entries, %u angular functions, worst cell error %.2f%%, dto %.2f s gto %.2f s\n",
           (unsigned long long)r.c.entries_angular, r.c.nfuncs_angular, 100 * worst, r.c.t_dto, r.c.t_gto);
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* The scene of the tests below: a diffuse unit floor z = 0 (quad 0, albedo 0.8) and a
 * glossy metal unit wall x = 0 (quad 1, 0.9, roughness 0.35) facing +x; returns the
 * wall's material. */
static int floor_and_glossy_wall(wrt_scene *s) {
    tsb_init(s);
    int md = tsb_material(s, 0.8, 0.8, 0.8);
    int mg = tsb_material(s, 0.9, 0.9, 0.9);
    s->materials[mg].lambertian = 0; s->materials[mg].roughness = 0.35f; s->materials[mg].metallic = 1;
    tsb_quad(s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), md);      /* floor, +z */
    tsb_quad(s, P(0, 0, 0), P(0, 1, 0), P(0, 1, 1), P(0, 0, 1), mg);      /* glossy wall x = 0, +x */
    return mg;
}

/* Brute force for the two tests below: the irradiance that the unit wall x = 0 (normal n,
 * material m), lit by a point light of intensity I at `light`, reflects onto cell
 * (level, cx, cy) of the unit floor z = 0: the integral over the wall of
 * f(w_l, y->x) E_dir(y) cos_y cos_x / d^2 with wrt_brdf_eval only, nr x nr points in the
 * cell, ns x ns on the wall. */
static double wall_reflection(const wrt_material *m, wrt_v3 n, wrt_v3 light, double I, int level, int cx, int cy,
                              int nr, int ns) {
    double sz = ldexp(1.0, -level), truth = 0;
    for (int a = 0; a < nr * nr; a++) {
        wrt_v3 xp = P((cx + (a % nr + 0.5) / nr) * sz, (cy + (a / nr + 0.5) / nr) * sz, 0);
        for (int k = 0; k < ns * ns; k++) {
            wrt_v3 yp = P(0, (k % ns + 0.5) / ns, (k / ns + 0.5) / ns);
            wrt_v3 d = v3_sub(xp, yp), dl = v3_sub(light, yp);
            double d2 = v3_dot(d, d), l2 = v3_dot(dl, dl);
            wrt_v3 wo = v3_scale(d, 1 / sqrt(d2)), wi = v3_scale(dl, 1 / sqrt(l2));
            double cy_ = wo.x, cx_ = -wo.z, ci = wi.x, f[3];
            if (cy_ <= 0 || cx_ <= 0 || ci <= 0) continue;
            wrt_brdf_eval(m, n, wi, wo, f);
            truth += f[0] * I * ci / l2 * cx_ * cy_ / d2;
        }
    }
    return truth / ((double)nr * nr * ns * ns);
}

/* Sample i of an N x N midpoint grid on the quad W lit by a point light of intensity I
 * at `light`: the point's (u, v), its irradiance e, the light's direction dl and that
 * direction's concentric coordinates (a, b) in W's frame; 0 where the light is behind W
 * (the two tests below project E onto the wall's functions with it). */
typedef struct wall_sample {
    double u, v, e, a, b;
    wrt_v3 dl;
} wall_sample;

static int wall_light_sample(const wrt_quad *W, wrt_v3 light, double I, int i, int N, wall_sample *w) {
    w->u = (i % N + 0.5) / N, w->v = (i / N + 0.5) / N;
    wrt_v3 p = wrt_quad_point(W, w->u, w->v), d = v3_sub(light, p);
    double d2 = v3_dot(d, d);
    w->dl = v3_scale(d, 1 / sqrt(d2));
    double c = v3_dot(w->dl, W->n);
    if (c <= 0) return 0;
    double loc[3] = {v3_dot(w->dl, W->t), v3_dot(w->dl, W->b), c};
    w->e = I * c / d2;
    wrt_concentric_inv(loc, &w->a, &w->b);
    return 1;
}

/* Glossy sender lit by a point light: the light's direction is a delta, so the sender's
 * reflected light is the BRDF averaged over the light's angular cell (the truncation of
 * the delta's expansion); at the BRDF's own level (3 here) that stays within 10% per cell.
 * incident radiance has angular wavelets (E projected with g at the light direction);
 * the irradiance the wall sends to a diffuse floor cell, through T, against brute force
 * integral over S of f(w_l, y->x) E_dir(y) cos_y cos_x / d^2 with wrt_brdf_eval only. */
static void test_glossy_sender_point_light(void) {
    wrt_scene s;
    int mg = floor_and_glossy_wall(&s);
    wrt_bake_result r;
    wrt_bake_options o = opts(6, 1, 5);
    o.dto_only = 1;
    o.max_alevel = 3; /* the BRDF rule's level for roughness 0.35; levels 1 and 2 blur the lobe (17%, 34%) */
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    const wrt_quad *W = &s.quads[1];
    wrt_v3 light = P(0.8, 0.5, 0.9);
    double I = 1.0;
    /* E coefficients on the wall: dense midpoint rule over (u, v) */
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    int N = 128;
    uint32_t *wf = malloc(r.nfuncs * sizeof *wf), nw = 0;
    for (uint32_t f = 0; f < r.nfuncs; f++)
        if (wrt_fkey_quad(r.fkeys[f]) == 1) wf[nw++] = f;
    for (int i = 0; i < N * N; i++) {
        wall_sample w;
        if (!wall_light_sample(W, light, I, i, N, &w)) continue;
        double u = w.u, v = w.v, e = w.e, a = w.a, b = w.b;
        for (uint32_t t = 0; t < nw; t++) {
            uint32_t f = wf[t];
            uint64_t k = r.fkeys[f];
            double h = wrt_haar2(wrt_fkey_snode(k), wrt_fkey_stype(k), u, v);
            if (h == 0) continue;
            double g = wrt_haar2(wrt_fkey_anode(k), wrt_fkey_atype(k), a, b);
            for (int ch = 0; ch < 3; ch++) x[3 * f + ch] += e * h * g * sqrt(W->area / M_PI) / ((double)N * N);
        }
    }
    wrt_csc_apply(&r.dto, x, y);
    double worst = 0;
    for (int cell = 0; cell < 4; cell++) {
        int cx = cell & 1, cy = cell >> 1;
        double got = cell_irradiance(&r, 0, 1.0, 1, cx, cy, y);
        double truth = wall_reflection(&s.materials[mg], W->n, light, I, 1, cx, cy, 6, 48);
        double err = fabs(got / truth - 1);
        worst = fmax(worst, err);
        CHECK(err < 0.10, "glossy sender under a point light, cell %d: %.5f vs brute force %.5f", cell, got, truth);
    }
    printf("glossy sender under a point light: worst cell error %.2f%% (bake %.1f s)\n", 100 * worst, r.c.t_dto + r.c.t_gto);
    free(x); free(y); free(wf);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* The first-bounce operator K (dto.c): the same wall and point light as above, but the
 * wall's reflected light projected on its OUTGOING angular functions with the BRDF at the
 * light's exact direction (c), and the floor's irradiance Y = K c against the same brute
 * force. btilde_g(w_l) = pi int f_r(w_l, M(a, b)) g(a, b) da db is integrated here by a
 * midpoint rule over the concentric square with wrt_brdf_eval (not the bake's table).
 * Also K's root entry (angular roots both sides) is the geometric form factor: closed form. */
static void k_btilde(const wrt_material *m, wrt_v3 n, wrt_v3 t, wrt_v3 b, wrt_v3 wl, int L, double *out) {
    int N = 4 << L, ng = 1 << (2 * L);
    for (int g = 0; g < ng; g++) out[g] = 0;
    for (int i = 0; i < N * N; i++) {
        double a = (i % N + 0.5) / N, bb = (i / N + 0.5) / N, d[3], f[3];
        wrt_concentric_dir(a, bb, d);
        wrt_v3 wo = v3_add(v3_add(v3_scale(t, d[0]), v3_scale(b, d[1])), v3_scale(n, d[2]));
        wrt_brdf_eval(m, n, wl, wo, f);
        for (int g = 0; g < ng; g++) {
            int lv, x, y, ty;
            wrt_brdf_angular_func(g, &lv, &x, &y, &ty);
            wrt_node an = {(uint8_t)lv, (uint16_t)x, (uint16_t)y};
            out[g] += M_PI * f[0] * wrt_haar2(an, ty, a, bb) / ((double)N * N);
        }
    }
}

/* K's entry from the wall's root (quad 1, outgoing root) to the floor's root (quad 0):
 * F(floor <- wall) sqrt(A_floor / A_wall), the closed-form form factor here */
static double k_root_entry(const wrt_bake_result *r) {
    int64_t rr = wrt_fkey_find(r->fkeys, r->nfuncs, root_key(0));
    for (uint32_t j = 0; j < r->nkcols; j++)
        if (r->kkeys[j] == root_key(1))
            for (uint64_t k = r->kcol_start[j]; k < r->kcol_start[j + 1]; k++)
                if ((int64_t)r->krows[k] == rr) return r->kvals[k];
    return 0;
}

static void test_first_bounce_operator(void) {
    wrt_scene s;
    int mg = floor_and_glossy_wall(&s);
    wrt_bake_result r;
    wrt_bake_options o = opts(5, 1, 5);
    o.dto_only = 1; /* incident level 1 (the default's), K at the material's level 3 */
    o.max_alevel = 1;
    if (getenv("K_LEVEL")) o.first_bounce_level = atoi(getenv("K_LEVEL"));
    if (getenv("K_Q")) o.quality = o.glossy_quality = atoi(getenv("K_Q")), o.max_slevel = 0;
    /* K's root entry as the links integrate it (no power balance): the closed form */
    wrt_bake_options ob = o;
    ob.no_balance = 1;
    CHECK(wrt_bake_run(&s, &ob, &r) == WRT_OK, "%s", wrt_last_error());
    double kroot0 = k_root_entry(&r), fp = ffc_perpendicular(0, 1, 0, 1, 0, 1, 0, 1);
    CHECK_CLAIM("k-root-form-factor", kroot0 / fp - 1, CLAIM_FF, "K's root entry %.7f, closed form %.7f", kroot0, fp);
    wrt_bake_result_free(&r);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    CHECK(r.nkcols > 0 && r.knnz > 0, "a glossy quad gets a first-bounce operator (%u columns, %llu entries)", r.nkcols,
          (unsigned long long)r.knnz);
    int kl = 0;
    uint32_t off_quad = 0, unsorted = 0;
    for (uint32_t j = 0; j < r.nkcols; j++) {
        off_quad += wrt_fkey_quad(r.kkeys[j]) != 1;
        if (!wrt_fkey_angular_root(r.kkeys[j])) kl = kl > wrt_fkey_anode(r.kkeys[j]).level + 1 ? kl : wrt_fkey_anode(r.kkeys[j]).level + 1;
        unsorted += j && r.kkeys[j - 1] >= r.kkeys[j];
    }
    CHECK(off_quad == 0 && unsorted == 0, "K's columns are the glossy wall's functions, ascending (%u off the wall, %u out "
          "of order)", off_quad, unsorted);
    if (!getenv("K_LEVEL")) CHECK(kl == 3, "K's outgoing level follows the lobe of roughness 0.35: %d", kl);
    /* with the power balance (balance.c): the root's power from rays, near the closed form */
    double kroot = k_root_entry(&r);
    CHECK_CLAIM("k-root-balanced", kroot / fp - 1, CLAIM_K_BALANCED_ROOT, "K's root entry after the power balance "
                "%.7f, closed form %.7f", kroot, fp);

    const wrt_quad *W = &s.quads[1];
    wrt_v3 light = P(0.8, 0.5, 0.9);
    double I = 1.0;
    int N = 64, ng = 256;
    double *c = calloc(r.nkcols, sizeof *c), *y = calloc(3 * r.nfuncs, sizeof *y), bt[256];
    double *xe = calloc(3 * r.nfuncs, sizeof *xe), *ye = calloc(3 * r.nfuncs, sizeof *ye);
    int bad = 0;
    for (int i = 0; i < N * N; i++) {
        wall_sample w;
        if (!wall_light_sample(W, light, I, i, N, &w)) continue;
        double u = w.u, v = w.v, e = w.e, la = w.a, lb = w.b;
        wrt_v3 dl = w.dl;
        for (uint32_t f = 0; f < r.nfuncs; f++) { /* today's path: the light's direction in the incident cells */
            uint64_t k = r.fkeys[f];
            if (wrt_fkey_quad(k) != 1) continue;
            double h = wrt_haar2(wrt_fkey_snode(k), wrt_fkey_stype(k), u, v);
            if (h != 0) xe[3 * f] += e * h * wrt_haar2(wrt_fkey_anode(k), wrt_fkey_atype(k), la, lb) * sqrt(W->area / M_PI) / ((double)N * N);
        }
        k_btilde(&s.materials[mg], W->n, W->t, W->b, dl, kl, bt);
        for (uint32_t j = 0; j < r.nkcols; j++) {
            uint64_t k = r.kkeys[j];
            double h = wrt_haar2(wrt_fkey_snode(k), wrt_fkey_stype(k), u, v);
            if (h == 0) continue;
            wrt_node an = wrt_fkey_anode(k);
            int g = wrt_fkey_angular_root(k) ? 0 : wrt_brdf_angular_index(an.level, an.x, an.y, wrt_fkey_atype(k));
            if (g < 0 || g >= ng) g = 0, bad++;
            c[j] += e * h * bt[g] * sqrt(W->area / M_PI) / ((double)N * N);
        }
    }
    CHECK(bad == 0, "K's angular functions within level 3 (%d outside)", bad);
    for (uint32_t j = 0; j < r.nkcols; j++)
        for (uint64_t k = r.kcol_start[j]; k < r.kcol_start[j + 1]; k++) y[3 * r.krows[k]] += r.kvals[k] * c[j];
    wrt_csc_apply(&r.dto, xe, ye);
    double worst = 0, worst_t = 0, ss = 0, ss_t = 0, st = 0;
    for (int cell = 0; cell < 16; cell++) {
        int cx = cell & 3, cy = cell >> 2;
        double got = cell_irradiance(&r, 0, 1.0, 2, cx, cy, y), truth = 0;
        double got_t = cell_irradiance(&r, 0, 1.0, 2, cx, cy, ye);
        truth = wall_reflection(&s.materials[mg], W->n, light, I, 2, cx, cy, 4, 64);
        worst = fmax(worst, fabs(got / truth - 1));
        worst_t = fmax(worst_t, fabs(got_t / truth - 1));
        ss += (got - truth) * (got - truth); ss_t += (got_t - truth) * (got_t - truth); st += truth * truth;
        if (getenv("K_DEBUG")) printf("cell %d %d: K c %.5f truth %.5f (%+.2f%%)\n", cx, cy, got, truth, 100 * (got / truth - 1));
    }
    CHECK_CLAIM("k-point-light-cells", worst, CLAIM_K_CELLS, "the floor's 4 x 4 cells lit by the glossy wall's first "
                "bounce (K c) against brute force: worst %.2f%% (%u columns, %llu entries)", 100 * worst, r.nkcols,
                (unsigned long long)r.knnz);
    CHECK_CLAIM("k-point-light-rmse", sqrt(ss / st), CLAIM_K_RMSE, "the same cells' relative rmse %.2f%%; through T, the "
                "light's direction in the incident level-1 cells: %.2f%% (worst %.2f%%)", 100 * sqrt(ss / st),
                100 * sqrt(ss_t / st), 100 * worst_t);
    CHECK(sqrt(ss / st) < 0.5 * sqrt(ss_t / st), "K at least halves the error of the truncated direction");
    free(c); free(y); free(xe); free(ye);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* Glossy receiver under a diffuse wall of uniform radiosity: the incident radiance it
 * stores, averaged over one spatial cell and one angular cell, against ray casting. */
static void test_glossy_receiver(void) {
    wrt_scene s;
    tsb_init(&s);
    int md = tsb_material(&s, 1.0, 1.0, 1.0);
    int mg = tsb_material(&s, 0.5, 0.5, 0.5);
    s.materials[mg].lambertian = 0; s.materials[mg].roughness = 0.3f; s.materials[mg].metallic = 1;
    tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), mg);      /* glossy floor */
    tsb_quad(&s, P(0, 0, 0), P(0, 1, 0), P(0, 1, 1), P(0, 0, 1), md);      /* diffuse wall */
    wrt_bake_result r;
    wrt_bake_options o = opts(5, 1, 5);
    o.max_alevel = 2;
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    int64_t f = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(1));
    for (int c = 0; c < 3; c++) x[3 * f + c] = sqrt(1.0 / M_PI); /* wall irradiance 1: radiosity 1, L = 1/pi */
    wrt_csc_apply(&r.dto, x, y);
    /* floor frame: t = +x, b = +y, n = +z; spatial cell (level 1, 0, 0), angular cells level 2 */
    double emax = 0, worst = 0, got[16], truth[16];
    for (int ac = 0; ac < 16; ac++) {
        int ax = ac % 4, ay = ac / 4;
        double acu = (ax + 0.5) / 4, acv = (ay + 0.5) / 4, g = 0;
        for (uint32_t k = 0; k < r.nfuncs; k++) {
            uint64_t key = r.fkeys[k];
            if (wrt_fkey_quad(key) != 0) continue;
            wrt_node sn = wrt_fkey_snode(key), an = wrt_fkey_anode(key);
            if (sn.level >= 1 || an.level >= 2) continue;
            g += y[3 * k] * wrt_haar2(sn, wrt_fkey_stype(key), 0.25, 0.25) *
                 wrt_haar2(an, wrt_fkey_atype(key), acu, acv);
        }
        got[ac] = g / sqrt(M_PI * 1.0);
        /* truth: mean of L_in over the cell x angular cell by ray casting to the wall */
        int N = 24, hit = 0, tot = 0;
        for (int i = 0; i < N * N; i++) for (int j = 0; j < 64; j++) {
            double px = (i % N + 0.5) / N * 0.5, py = (i / N + 0.5) / N * 0.5, d[3];
            double a = (ax + (j % 8 + 0.5) / 8) / 4, b = (ay + (j / 8 + 0.5) / 8) / 4;
            wrt_concentric_dir(a, b, d);
            tot++;
            if (d[0] >= 0) continue;
            double t = -px / d[0], hy = py + t * d[1], hz = t * d[2];
            if (hy >= 0 && hy <= 1 && hz >= 0 && hz <= 1) hit++;
        }
        truth[ac] = (double)hit / tot / M_PI;
        emax = fmax(emax, truth[ac]);
    }
    for (int ac = 0; ac < 16; ac++) {
        double err = fabs(got[ac] - truth[ac]) / emax;
        worst = fmax(worst, err);
        CHECK(err < 0.15, "angular cell %d: L_in %.4f vs ray cast %.4f", ac, got[ac], truth[ac]);
    }
    printf("glossy receiver: worst angular-cell error %.1f%% of the peak\n", 100 * worst);
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

int main(int argc, char **argv) {
    TEST_RUN(test_glossy_sender);
    TEST_RUN(test_glossy_sender_point_light);
    TEST_RUN(test_glossy_receiver);
    TEST_RUN(test_first_bounce_operator);
    TEST_RUN(test_closed_forms_themselves);
    TEST_RUN(test_point_polygon);
    TEST_RUN(test_form_factors);
    TEST_RUN(test_reciprocity);
    TEST_RUN(test_distribution);
    TEST_RUN(test_depth_share);
    TEST_RUN(test_furnace);
    TEST_RUN(test_coloured_furnace);
    TEST_RUN(test_small_quads_furnace);
    TEST_RUN(test_compression_keeps_power);
    TEST_RUN(test_small_sender_column);
    TEST_RUN(test_add_in_place);
    TEST_RUN(test_power_balance);
    TEST_RUN(test_glossy_power_balance);
    TEST_RUN(test_coplanar_and_backfacing);
    TEST_RUN(test_threads_identical);
    TEST_RUN(test_consume_identical);
    TEST_END();
}
