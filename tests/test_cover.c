/* test_cover.c: light sent from a quad that an object partly covers (precompute/cover.c,
 * docs/triangles.md "Covered sender points"), against the closed form.
 *
 * A unit floor S (albedo 1) under a unit ceiling R at distance 1, facing. A thin closed
 * black box (height 2e-4) stands on the floor over x < 1/3: that part of the floor is
 * inside it, so the floor's radiosity is 0 there for any light. The floor is given the
 * radiosity such a floor has, 1 where it is exposed and 0 under the box, projected onto
 * every spatial function the bake made for it; the flux arriving on the ceiling, over its
 * area, must be the closed-form form factor from the ceiling to the exposed strip
 * x in [1/3, 1] (the box hides at most a strip 2e-4 wide beside its edge from the ceiling,
 * under 0.03% of that). The edge x = 1/3 lies inside a cell at every level. Before the
 * fix the links counted the covered part dark twice (its mean and its blocked rays) in
 * every cell the edge crosses.
 * Measured before the fix: -13.1% at quality 3, -3.2% at 5; after: +0.30%, +0.041%.
 * The other direction: uniform radiosity on the ceiling, the flux arriving on the floor
 * (the covered part receiving nothing) is the same form factor times the ceiling's area.
 * Links: bake, formats, common. */
#include <stdlib.h>
#include <string.h>

#include "common/basis.h"
#include "common/rt_scene.h"
#include "precompute/bake.h"
#include "precompute/cover.h"
#include "bake_helpers.h"
#include "ff_closed.h"
#include "scene_build.h"
#include "test.h"

#define EDGE (1.0 / 3.0)
#define HEIGHT 2e-4

/* the closed box [lo, hi] with its faces outward (normal (p1 - p0) x (p3 - p0)) */
static void box_outward(wrt_scene *s, wrt_v3 lo, wrt_v3 hi, int mat) {
    wrt_v3 c[8];
    for (int k = 0; k < 8; k++) c[k] = v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
    static const int f[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int i = 0; i < 6; i++) tsb_quad(s, c[f[i][0]], c[f[i][1]], c[f[i][2]], c[f[i][3]], mat);
}

/* int over [a, b] of the indicator u > EDGE */
static double exposed_len(double a, double b) { return fmax(0, b - fmax(a, EDGE)); }

/* the flux functional of a spatial Haar function on a unit square (J = 1), restricted to
 * u in [lo, hi]: int h(u, v) [lo <= u <= hi] du dv */
static double haar_part(wrt_node n, int type, int exposed_only) {
    double size = wrt_node_size(n), h = 0.5 * size, sum = 0;
    for (int cy = 0; cy < 2; cy++)
        for (int cx = 0; cx < 2; cx++) {
            double sign = type == 0 ? 1 : wrt_haar_sign(type, cx, cy);
            double u0 = wrt_node_x0(n) + cx * h;
            double len = exposed_only ? exposed_len(u0, u0 + h) : h;
            sum += sign * len * h;
        }
    return sum / size;
}

/* radiosity on quad `from` (1 where exposed if exposed_only, else everywhere), T applied,
 * the flux arriving on quad `to` over its area (1) */
static double flux_to(const wrt_bake_result *r, int from, int to, int exposed_only) {
    double *x = calloc(3 * r->nfuncs, sizeof *x), *y = calloc(3 * r->nfuncs, sizeof *y);
    for (uint32_t f = 0; f < r->nfuncs; f++) {
        uint64_t k = r->fkeys[f];
        if (!wrt_fkey_angular_root(k) || (int)wrt_fkey_quad(k) != from) continue;
        double m = haar_part(wrt_fkey_snode(k), wrt_fkey_stype(k), exposed_only);
        for (int c = 0; c < 3; c++) x[3 * f + c] = m / sqrt(M_PI);
    }
    wrt_csc_apply(&r->dto, x, y);
    double flux = 0;
    for (uint32_t f = 0; f < r->nfuncs; f++) {
        uint64_t k = r->fkeys[f];
        if (wrt_fkey_angular_root(k) && (int)wrt_fkey_quad(k) == to)
            flux += sqrt(M_PI) * y[3 * f] * haar_part(wrt_fkey_snode(k), wrt_fkey_stype(k), 0);
    }
    free(x); free(y);
    return flux;
}

static void test_covered_floor(void) {
    double truth = ffc_parallel(0, 1, 0, 1, EDGE, 1, 0, 1, 1); /* ceiling -> exposed strip */
    for (int quality = 3; quality <= 5; quality += 2) {
        wrt_scene s;
        tsb_init(&s);
        int white = tsb_material(&s, 1, 1, 1), black = tsb_material(&s, 0, 0, 0);
        int floor = tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), white);
        int ceiling = tsb_quad(&s, P(0, 0, 1), P(0, 1, 1), P(1, 1, 1), P(1, 0, 1), white);
        box_outward(&s, P(0, 0, 0), P(EDGE, 1, HEIGHT), black);
        wrt_bake_result r;
        wrt_bake_options o = opts(quality, 0, 0);
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "bake: %s", wrt_last_error());
        double up = flux_to(&r, floor, ceiling, 1), down = flux_to(&r, ceiling, floor, 0);
        printf("covered floor, quality %d: floor -> ceiling %.6f, ceiling -> floor %.6f, closed form %.6f "
               "(%+.3f%%, %+.3f%%)\n", quality, up, down, truth, 100 * (up / truth - 1), 100 * (down / truth - 1));
        CHECK(fabs(up / truth - 1) < 4e-3, "floor -> ceiling, quality %d: %.6f vs %.6f", quality, up, truth);
        /* the covered part receives nothing: counting the floor's exposed share on this side
         * as well would give +50%; the receiver's quadrature across the box's edge is what
         * is left, -6.5% at quality 3 and -0.72% at 5 (the same before the fix) */
        if (quality == 5)
            CHECK(fabs(down / truth - 1) < 1e-2, "ceiling -> floor, quality %d: %.6f vs %.6f", quality, down, truth);
        wrt_bake_result_free(&r);
        tsb_free(&s);
    }
}

/* The prism over the polygon poly (n corners, counter-clockwise seen from +z) from z = 0
 * to z = h: its sides outward, its top cap as the quads (0, k, k + 1, k + 2) of a fan (n
 * even), no bottom (the floor's points see only upwards). */
static void prism(wrt_scene *s, const double (*poly)[2], int n, double h, int mat) {
    for (int i = 0; i < n; i++) {
        const double *a = poly[i], *b = poly[(i + 1) % n];
        tsb_quad(s, P(a[0], a[1], 0), P(b[0], b[1], 0), P(b[0], b[1], h), P(a[0], a[1], h), mat);
    }
    for (int k = 1; k + 2 < n; k += 2)
        tsb_quad(s, P(poly[0][0], poly[0][1], h), P(poly[k][0], poly[k][1], h), P(poly[k + 1][0], poly[k + 1][1], h),
                 P(poly[k + 2][0], poly[k + 2][1], h), mat);
}

/* The covered quads' maps (cover.c) against the rays they stand for: a unit floor under
 * a convex octagonal column and a non-convex L-shaped block. At random points of the
 * floor the map's answer must be the five rays' wherever a cell's corners agree: the
 * octagon's cover is convex, so every disagreement is the L's, in the cells around its
 * one reflex corner (at most 4 of the 32 x 32). The covered share of the floor must be
 * the two footprints' area. */
static void test_cover_map(void) {
    wrt_scene s;
    tsb_init(&s);
    int white = tsb_material(&s, 1, 1, 1);
    tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), white);
    double oct[8][2], r = 0.15;
    for (int i = 0; i < 8; i++) {
        double a = (i + 0.5) * M_PI / 4;
        oct[i][0] = 0.3 + r * cos(a); oct[i][1] = 0.5 + r * sin(a);
    }
    prism(&s, (const double (*)[2])oct, 8, 0.3, white);
    static const double ell[6][2] = {{0.61, 0.2}, {0.9, 0.2}, {0.9, 0.5}, {0.7, 0.5}, {0.7, 0.83}, {0.61, 0.83}};
    prism(&s, ell, 6, 0.3, white);
    double truth = 2 * sqrt(2) * r * r + 0.29 * 0.3 + 0.09 * 0.33;
    bake_ctx b;
    memset(&b, 0, sizeof b);
    b.nq = s.nquads;
    b.quads = s.quads;
    b.opt.threads = 2;
    wrt_v3 *corners = malloc((size_t)s.nquads * 4 * sizeof *corners);
    for (int i = 0; i < s.nquads; i++)
        for (int k = 0; k < 4; k++) corners[4 * i + k] = s.quads[i].p[k];
    wrt_rt_scene rs;
    CHECK(wrt_rt_scene_build(corners, s.nquads, v3(0, 0, 0), "threads=1", WRT_RT_ROBUST, &rs) == WRT_OK, "embree");
    free(corners);
    b.rtc = rs.scene;
    b.ray_eps = rs.eps;
    b.cover = wrt_bake_cover_flags(&b);
    CHECK(b.cover[0] == 1, "the floor is flagged");
    const int n = 40000;
    int covered = 0, differ = 0, uneq = 0;
    uint64_t h = 1, rays = 0;
    for (int i = 0; i < n; i++) {
        double u = (double)((h = wrt_mix64(h)) >> 11) * 0x1.0p-53, v = (double)((h = wrt_mix64(h)) >> 11) * 0x1.0p-53;
        wrt_v3 o = v3_mad(wrt_quad_point(&b.quads[0], u, v), b.quads[0].n, b.ray_eps);
        int exact = wrt_bake_covered(&b, o, &b.quads[0]), map = wrt_bake_covered_uv(&b, 0, u, v, o, &rays);
        covered += exact;
        differ += exact != map;
        uneq += exact != map && u < 0.5; /* the octagon's side */
    }
    double share = (double)covered / n, sd = sqrt(truth * (1 - truth) / n);
    printf("cover map: covered share %.4f (footprints %.4f, sd %.4f); map and rays differ at %d of %d points "
           "(%d on the convex side), %.1f%% of the points tested with rays\n", share, truth, sd, differ, n, uneq,
           100.0 * (double)rays / n);
    CHECK(fabs(share - truth) < 5 * sd, "covered share %.4f vs %.4f", share, truth);
    CHECK(uneq == 0, "the convex cover's map differs from its rays at %d points", uneq);
    CHECK(differ <= n * 4 / (WRT_COVER_MAP * WRT_COVER_MAP), "map and rays differ at %d points", differ);
    CHECK(rays < (uint64_t)n / 4, "%llu of %d points tested with rays", (unsigned long long)rays, n);
    free(b.cover);
    wrt_rt_scene_release(&rs);
    tsb_free(&s);
}

int main(int argc, char **argv) {
    setvbuf(stdout, NULL, _IOLBF, 0);
    TEST_RUN(test_cover_map);
    TEST_RUN(test_covered_floor);
    TEST_END();
}
