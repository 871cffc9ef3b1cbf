/* test_reconstruct.c: the smooth display of common/reconstruct.c. Truths that do not
 * depend on the module: a linear function's cell averages (closed form), the input's own
 * averages, exact zeros, and the geometry of the test scenes. Then through the player on
 * real bakes: no light into a dark room through a wall standing on a shared edge, and no
 * seam across the shared edges of a subdivided box (jump across an edge against the
 * jump inside a quad, the Haar blocks beside it to show the measure sees seams). */
#include "common/basis.h"
#include "formats/gto.h"
#include "formats/scene.h"
#include "common/reconstruct.h"
#include "common/smooth.h"
#include "player/relight.h"
#include "precompute/bake.h"
#include "scene_build.h"
#include "test.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Every stored node's averages kept, slopes limited (the module's parts one at a time). */
static const wrt_recon_params all = {99, 0, 1, 0, 0, 0};

static uint64_t rng = 88172645463325252ull;
static double rnd(void) { /* xorshift, uniform in [0, 1) */
    rng ^= rng << 13; rng ^= rng >> 7; rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

/* Bilinear lookup clamped to the quad's texels, as GL_LINEAR + CLAMP_TO_EDGE. */
static double lookup(const float *t, int res, int nc, int ch, double u, double v) {
    double fx = u * res - 0.5, fy = v * res - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0, s = 0;
    for (int k = 0; k < 4; k++) {
        int x = x0 + (k & 1), y = y0 + (k >> 1);
        x = x < 0 ? 0 : x >= res ? res - 1 : x;
        y = y < 0 ? 0 : y >= res ? res - 1 : y;
        s += ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty) * t[((size_t)y * res + x) * nc + ch];
    }
    return s;
}

static void edge_uv(int e, double t, double d, double *u, double *v) {
    switch (e) {
    case 0: *u = t; *v = d; break;
    case 1: *u = 1 - d; *v = t; break;
    case 2: *u = t; *v = 1 - d; break;
    default: *u = d; *v = t; break;
    }
}

/* A random known mask for levels < L: levels < full all known, deeper nodes known with
 * probability p where their parent is. */
static uint8_t *random_known(int L, int full, double p) {
    uint8_t *k = calloc((((size_t)1 << (2 * L)) - 1) / 3 + 1, 1);
    for (int l = 0; l < L; l++)
        for (int y = 0; y < (1 << l); y++)
            for (int x = 0; x < (1 << l); x++) {
                int parent = l == 0 || k[wrt_recon_node(l - 1, x / 2, y / 2)];
                k[wrt_recon_node(l, x, y)] = (uint8_t)(l < full || (parent && rnd() < p));
            }
    return k;
}

/* Every node known and no refinement past the input: the output is the input (values in
 * [0, 1); the sums of the synthesis round at 6e-8). */
static void test_all_known_is_identity(void) {
    double c[1][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}};
    uint32_t m = 0;
    wrt_recon *rc = wrt_recon_create(1, (const double (*)[4][3])c, &m);
    float in[64 * 3], out[64 * 3];
    for (int i = 0; i < 64 * 3; i++) in[i] = (float)rnd();
    const float *ip[1] = {in};
    float *op[1] = {out};
    CHECK(wrt_recon_run(rc, 0, 3, 3, 3, ip, NULL, op, &all) == 0, "run");
    double md = 0;
    for (int i = 0; i < 64 * 3; i++) md = fmax(md, fabs(out[i] - in[i]));
    CHECK(md < 1e-6, "max |out - in| = %g (float rounding only)", md);
    wrt_recon_destroy(rc);
}

/* Every cell average the bake knows (a cell whose ancestors all hold functions) is kept
 * by the smooth output, two levels finer. */
static void test_known_averages_kept(void) {
    double c[1][4][3] = {{{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}}};
    uint32_t m = 0;
    wrt_recon *rc = wrt_recon_create(1, (const double (*)[4][3])c, &m);
    int L = 4, Lo = 6, n = 1 << L, no = 1 << Lo;
    float *in = malloc((size_t)n * n * sizeof(float)), *out = malloc((size_t)no * no * sizeof(float));
    for (int trial = 0; trial < 4; trial++) {
        for (int i = 0; i < n * n; i++) in[i] = (float)(1 + rnd()); /* positive: no clamping */
        uint8_t *k = random_known(L, 2, 0.6);
        const float *ip[1] = {in};
        const uint8_t *kp[1] = {k};
        float *op[1] = {out};
        CHECK(wrt_recon_run(rc, 0, L, Lo, 1, ip, kp, op, &all) == 0, "run");
        double worst = 0;
        int cells = 0;
        for (int l = 1; l <= L; l++) { /* cells at level l: known if the parent chain is */
            int s = 1 << l, f = no / s, fi = n / s;
            for (int y = 0; y < s; y++)
                for (int x = 0; x < s; x++) {
                    int known = 1;
                    for (int a = l - 1; a >= 0; a--) known &= k[wrt_recon_node(a, x >> (l - a), y >> (l - a))];
                    if (!known) continue;
                    double so = 0, si = 0;
                    for (int b = 0; b < f; b++)
                        for (int a = 0; a < f; a++) so += out[(size_t)(y * f + b) * no + x * f + a];
                    for (int b = 0; b < fi; b++)
                        for (int a = 0; a < fi; a++) si += in[(size_t)(y * fi + b) * n + x * fi + a];
                    worst = fmax(worst, fabs(so / (f * f) - si / (fi * fi)) / (si / (fi * fi)));
                    cells++;
                }
        }
        CHECK(cells > 100, "%d known cells checked", cells);
        CHECK(worst < 1e-5, "trial %d: worst relative change of a known cell average %g", trial, worst);
        free(k);
    }
    free(in); free(out);
    wrt_recon_destroy(rc);
}

/* A linear function's averages on two coplanar quads (the second with its corners
 * listed from another corner, so the shared edge is read through the mapping), nothing
 * known below the root: the output's inner texels are the function's averages, the
 * shared edge's texels its value on the edge (and the texels beside them give back the
 * difference, not checked here). */
static double lin(double x, double y) { return 1 + 2 * x + 3 * y; }

static void test_linear_reproduced(void) {
    /* both face +z; quad 1 listed from (2,0): its u runs along +y, its v along -x */
    double d[2][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                         {{2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {1, 0, 0}}};
    uint32_t m[2] = {0, 0};
    wrt_recon *rc = wrt_recon_create(2, (const double (*)[4][3])d, m);
    int ne, fl;
    CHECK(wrt_recon_neighbour(rc, 0, 1, &ne, &fl) == 1, "quad 0's edge u = 1 borders quad 1");
    CHECK(wrt_recon_ngroups(rc) == 1, "one group");
    int L = 3, Lo = 5, n = 1 << L, no = 1 << Lo;
    float in[2][64], out[2][1024];
    uint8_t *k = random_known(L, 1, 0); /* the root only */
    for (int q = 0; q < 2; q++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) { /* average of a linear function = value at the centre */
                double u = (i + 0.5) / n, v = (j + 0.5) / n, x = 0, y = 0;
                double w[4] = {(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v};
                for (int a = 0; a < 4; a++) { x += w[a] * d[q][a][0]; y += w[a] * d[q][a][1]; }
                in[q][j * n + i] = (float)lin(x, y);
            }
    const float *ip[2] = {in[0], in[1]};
    const uint8_t *kp[2] = {k, k};
    float *op[2] = {out[0], out[1]};
    CHECK(wrt_recon_run(rc, 0, L, Lo, 1, ip, kp, op, &all) == 0, "run");
    double worst = 0, worst_edge = 0;
    for (int q = 0; q < 2; q++)
        for (int j = 0; j < no; j++)
            for (int i = 0; i < no; i++) {
                double u = (i + 0.5) / no, v = (j + 0.5) / no, x = 0, y = 0;
                int border = i == 0 || j == 0 || i == no - 1 || j == no - 1;
                if ((q == 0 && i == no - 2) || (q == 1 && j == no - 2)) continue; /* give back what the edge gained */
                if (border) { /* edge texels hold the value on the edge where shared */
                    if (!(q == 0 && i == no - 1 && j > 0 && j < no - 1)) continue;
                    u = 1;
                }
                double w[4] = {(1 - u) * (1 - v), u * (1 - v), u * v, (1 - u) * v};
                for (int a = 0; a < 4; a++) { x += w[a] * d[q][a][0]; y += w[a] * d[q][a][1]; }
                double e = fabs(out[q][j * no + i] - lin(x, y));
                if (border) worst_edge = fmax(worst_edge, e);
                else worst = fmax(worst, e);
            }
    CHECK(worst < 1e-5, "inner texels off a linear function by %g", worst);
    CHECK(worst_edge < 1e-5, "shared-edge texels off its value on the edge by %g", worst_edge);
    free(k);
    wrt_recon_destroy(rc);
}

/* Four coplanar quads around a common corner, listed from different corners, random
 * blocky light and random refinement: the smooth display has no jump across the shared
 * edges (the two quads' lookups a hair either side agree), while the input's blocks do;
 * and each quad keeps its mean. */
static void test_continuous_across_edges(void) {
    double d[4][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                         {{1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}},
                         {{1, 2, 0}, {0, 2, 0}, {0, 1, 0}, {1, 1, 0}},  /* rotated half a turn */
                         {{1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {1, 2, 0}}};
    uint32_t m[4] = {7, 7, 7, 7};
    wrt_recon *rc = wrt_recon_create(4, (const double (*)[4][3])d, m);
    CHECK(wrt_recon_ngroups(rc) == 1, "one group (%d)", wrt_recon_ngroups(rc));
    int L = 4, Lo = 5, n = 1 << L, no = 1 << Lo, nc = 3;
    float *in[4], *out[4];
    uint8_t *k[4];
    for (int q = 0; q < 4; q++) {
        in[q] = malloc((size_t)n * n * nc * sizeof(float));
        out[q] = malloc((size_t)no * no * nc * sizeof(float));
        for (int i = 0; i < n * n * nc; i++) in[q][i] = (float)(0.5 + rnd());
        k[q] = random_known(L, 2, 0.5);
    }
    CHECK(wrt_recon_run(rc, 0, L, Lo, nc, (const float *const *)in, (const uint8_t *const *)k, out, &all) == 0, "run");
    double jump = 0, jump_in = 0;
    int edges = 0;
    for (int q = 0; q < 4; q++)
        for (int e = 0; e < 4; e++) {
            int ne, fl, o = wrt_recon_neighbour(rc, q, e, &ne, &fl);
            if (o < 0) continue;
            edges++;
            for (int s = 0; s <= 64; s++) {
                double t = s / 64.0, u, v, u2, v2;
                edge_uv(e, t, 1e-9, &u, &v);
                edge_uv(ne, fl ? 1 - t : t, 1e-9, &u2, &v2);
                for (int ch = 0; ch < nc; ch++) {
                    jump = fmax(jump, fabs(lookup(out[q], no, nc, ch, u, v) - lookup(out[o], no, nc, ch, u2, v2)));
                    jump_in = fmax(jump_in, fabs(lookup(in[q], n, nc, ch, u, v) - lookup(in[o], n, nc, ch, u2, v2)));
                }
            }
        }
    CHECK(edges == 8, "8 shared edge sides (%d)", edges);
    double worst_mean = 0; /* each quad's texel sum (its display's integral) is the input's */
    for (int q = 0; q < 4; q++)
        for (int ch = 0; ch < nc; ch++) {
            double si = 0, so = 0;
            for (int i = 0; i < n * n; i++) si += in[q][i * nc + ch] / (n * n);
            for (int i = 0; i < no * no; i++) so += out[q][i * nc + ch] / (no * no);
            worst_mean = fmax(worst_mean, fabs(so - si) / si);
        }
    CHECK(worst_mean < 1e-5, "a quad's mean moved by %g of itself", worst_mean);
    CHECK(jump < 1e-5, "largest jump across a shared edge %g", jump);
    CHECK(jump_in > 0.1, "the blocks it started from jump by %g there", jump_in);
    for (int q = 0; q < 4; q++) { free(in[q]); free(out[q]); free(k[q]); }
    wrt_recon_destroy(rc);
}

/* RGB at once (the SIMD path for 3 channels) against the scalar path, bit for bit: the
 * same light given as 6 channels (RGB twice, so that the sharpness test, which takes the
 * largest over the channels, decides alike), with the default parameters (the sharpness
 * test, the limiter, the clamp) on blocky light with dark, bright and negative cells and
 * random refinement. */
static void test_rgb_is_scalar(void) {
    double d[4][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                         {{1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}},
                         {{1, 2, 0}, {0, 2, 0}, {0, 1, 0}, {1, 1, 0}},
                         {{1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {1, 2, 0}}};
    uint32_t m[4] = {7, 7, 7, 7};
    wrt_recon *rc = wrt_recon_create(4, (const double (*)[4][3])d, m);
    int L = 4, Lo = 5, n = 1 << L, no = 1 << Lo;
    float *in[4], *out[4], *in6[4], *out6[4];
    uint8_t *k[4];
    for (int q = 0; q < 4; q++) {
        in[q] = malloc((size_t)n * n * 3 * sizeof(float));
        out[q] = malloc((size_t)no * no * 3 * sizeof(float));
        in6[q] = malloc((size_t)n * n * 6 * sizeof(float));
        out6[q] = malloc((size_t)no * no * 6 * sizeof(float));
        for (int i = 0; i < n * n * 3; i++) { /* smooth light with details of every size, some dark */
            double u = rnd(), x = (double)(i / 3 % n) / n, y = (double)(i / 3 / n) / n, t = rnd();
            in[q][i] = (float)(u < 0.1 ? 0 : u < 0.15 ? -0.2 * rnd() : 1 + x + 2 * y * (1 + i % 3) + 0.6 * t * t * t * t);
        }
        for (int i = 0; i < n * n; i++)
            for (int c = 0; c < 6; c++) in6[q][i * 6 + c] = in[q][i * 3 + c % 3];
        k[q] = random_known(L, 1, 0.7);
    }
    CHECK(wrt_recon_run(rc, 0, L, Lo, 3, (const float *const *)in, (const uint8_t *const *)k, out, NULL) == 0, "run");
    CHECK(wrt_recon_run(rc, 0, L, Lo, 6, (const float *const *)in6, (const uint8_t *const *)k, out6, NULL) == 0, "run");
    long differ = 0, zeros = 0, chan_differ = 0;
    for (int q = 0; q < 4; q++)
        for (int i = 0; i < no * no; i++)
            for (int c = 0; c < 3; c++) {
                differ += memcmp(&out[q][i * 3 + c], &out6[q][i * 6 + c], sizeof(float)) != 0;
                zeros += out[q][i * 3 + c] == 0;
                chan_differ += out[q][i * 3 + c] != out[q][i * 3];
            }
    CHECK(differ == 0, "%ld of %d texel channels differ between RGB at once and the scalar path", differ,
          4 * no * no * 3);
    CHECK(zeros > 100 && chan_differ > 1000, "the channels differ (%ld) and the clamp acts (%ld zeros)", chan_differ, zeros);
    for (int q = 0; q < 4; q++) { free(in[q]); free(out[q]); free(in6[q]); free(out6[q]); free(k[q]); }
    wrt_recon_destroy(rc);
}

/* The linear display (wrt_recon_params.linear): on four coplanar quads with blocky light
 * of dark and bright cells (where the default's limiter, sharpness test and clamp act),
 * the output of A + B is the output of A plus that of B to float rounding, each quad's
 * mean is kept, and the default's output of A + B is not the sum (so the check can
 * fail). */
static void test_linear_superposes(void) {
    double d[4][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                         {{1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}},
                         {{1, 2, 0}, {0, 2, 0}, {0, 1, 0}, {1, 1, 0}},
                         {{1, 1, 0}, {2, 1, 0}, {2, 2, 0}, {1, 2, 0}}};
    uint32_t m[4] = {7, 7, 7, 7};
    wrt_recon *rc = wrt_recon_create(4, (const double (*)[4][3])d, m);
    int L = 4, Lo = 5, n = 1 << L, no = 1 << Lo, nc = 3;
    float *in[3][4], *out[3][4];
    uint8_t *k[4];
    for (int q = 0; q < 4; q++) {
        for (int c = 0; c < 3; c++) {
            in[c][q] = malloc((size_t)n * n * nc * sizeof(float));
            out[c][q] = malloc((size_t)no * no * nc * sizeof(float));
        }
        for (int i = 0; i < n * n * nc; i++) {
            in[0][q][i] = rnd() < 0.3 ? 0.0f : (float)(rnd() * 10);    /* A: dark and bright cells */
            in[1][q][i] = rnd() < 0.5 ? (float)(0.1 * rnd()) : 5.0f;   /* B: a shadow-like pattern */
            in[2][q][i] = in[0][q][i] + in[1][q][i];
        }
        k[q] = random_known(L, 2, 0.5);
    }
    const wrt_recon_params linear = {WRT_RECON_KEEP, WRT_RECON_SHARP, 1, 1, 0, 0}, dflt = {WRT_RECON_KEEP, WRT_RECON_SHARP, 1, 0, 0, 0};
    double dev[2], worst_mean = 0;
    for (int mode = 0; mode < 2; mode++) {
        for (int c = 0; c < 3; c++)
            CHECK(wrt_recon_run(rc, 0, L, Lo, nc, (const float *const *)in[c], (const uint8_t *const *)k, out[c],
                                mode ? &dflt : &linear) == 0, "run");
        double peak = 0, worst = 0;
        for (int q = 0; q < 4; q++)
            for (int i = 0; i < no * no * nc; i++) {
                peak = fmax(peak, fabs(out[2][q][i]));
                worst = fmax(worst, fabs((double)out[2][q][i] - out[0][q][i] - out[1][q][i]));
            }
        dev[mode] = worst / peak;
        if (mode == 0)
            for (int q = 0; q < 4; q++)
                for (int ch = 0; ch < nc; ch++) {
                    double si = 0, so = 0;
                    for (int i = 0; i < n * n; i++) si += in[2][q][i * nc + ch] / (n * n);
                    for (int i = 0; i < no * no; i++) so += out[2][q][i * nc + ch] / (no * no);
                    worst_mean = fmax(worst_mean, fabs(so - si) / si);
                }
    }
    printf("  A + B against A and B apart: linear %.3g of the peak, default %.3g\n", dev[0], dev[1]);
    CHECK(dev[0] < 1e-6, "linear display: A + B differs from the sum by %g of the peak", dev[0]);
    CHECK(dev[1] > 1e-3, "the default display superposes (%g): the check cannot fail", dev[1]);
    CHECK(worst_mean < 1e-5, "linear display: a quad's mean moved by %g of itself", worst_mean);
    for (int q = 0; q < 4; q++) {
        for (int c = 0; c < 3; c++) { free(in[c][q]); free(out[c][q]); }
        free(k[q]);
    }
    wrt_recon_destroy(rc);
}

/* No smoothing across a crease, between materials, back to back, or across a shared
 * edge a wall stands on: a dark quad stays exactly dark beside a bright one, and the
 * same pair with no wall does share light (so the check can fail). */
static void test_no_light_across(void) {
    double floor2[2][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 0, -1}, {0, 0, -1}},
                              {{1, 0, 0}, {2, 0, 0}, {2, 0, -1}, {1, 0, -1}}};
    double wall[4][3] = {{1, 0, 0}, {1, 0, -1}, {1, 1, -1}, {1, 1, 0}};
    double crease[2][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 0, -1}, {0, 0, -1}},
                              {{1, 0, 0}, {1, 0, -1}, {1, 1, -1}, {1, 1, 0}}};
    double backs[2][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 0, -1}, {0, 0, -1}},
                             {{1, 0, 0}, {1, 0, -1}, {2, 0, -1}, {2, 0, 0}}};
    uint32_t m2[2] = {0, 0}, m2b[2] = {0, 1}, m3[3] = {0, 0, 0};
    wrt_recon *rc;
    rc = wrt_recon_create(2, (const double (*)[4][3])crease, m2);
    CHECK(wrt_recon_neighbour(rc, 0, 1, NULL, NULL) < 0 && wrt_recon_ngroups(rc) == 2, "no smoothing round a crease");
    wrt_recon_destroy(rc);
    rc = wrt_recon_create(2, (const double (*)[4][3])backs, m2);
    CHECK(wrt_recon_ngroups(rc) == 2, "none between quads facing opposite ways");
    wrt_recon_destroy(rc);
    rc = wrt_recon_create(2, (const double (*)[4][3])floor2, m2b);
    CHECK(wrt_recon_ngroups(rc) == 2, "none between two materials");
    wrt_recon_destroy(rc);
    double three[3][4][3];
    memcpy(three, floor2, sizeof floor2);
    memcpy(three[2], wall, sizeof wall);
    for (int with_wall = 0; with_wall < 2; with_wall++) {
        rc = wrt_recon_create(2 + with_wall, (const double (*)[4][3])three, m3);
        int L = 3, Lo = 5, n = 1 << L, no = 1 << Lo;
        float lit[64], dark[64] = {0}, o0[1024], o1[1024], o2[1024];
        for (int i = 0; i < n * n; i++) lit[i] = (float)(1 + rnd());
        const float *ip[3] = {lit, dark, dark};
        float *op[3] = {o0, o1, o2};
        int g = wrt_recon_group(rc, 1);
        if (g != wrt_recon_group(rc, 0)) CHECK(wrt_recon_run(rc, wrt_recon_group(rc, 0), L, Lo, 1, ip, NULL, op, &all) == 0, "run");
        CHECK(wrt_recon_run(rc, g, L, Lo, 1, ip, NULL, op, &all) == 0, "run");
        double mx = 0;
        for (int i = 0; i < no * no; i++) mx = fmax(mx, o1[i]);
        if (with_wall) CHECK(mx == 0, "a wall on the shared edge: the dark quad stays 0 (max %g)", mx);
        else CHECK(mx > 0.1, "no wall: the same quads share light (max %g)", mx);
        wrt_recon_destroy(rc);
    }
}

/* ------------------------------------------------------- curved meshes ---- */

/* An icosphere of radius 1 (an icosahedron, each face cut in four, 80 triangles), each
 * triangle as its three quads (wrt_triangle_quads, as the loader makes them), the corner
 * normals radial: on a sphere the loader's normalized means of the vertices' normals at
 * the midpoints and the centroid are radial too, so this is what a smooth-shaded
 * icosphere's glTF gives. Returns the number of quads (240). */
static int icosphere(double (*c)[4][3], float (*nrm)[4][3]) {
    const double t = (1 + sqrt(5.0)) / 2;
    double v[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                       {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    static const int f[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                 {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                 {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    int nq = 0;
    for (int i = 0; i < 20; i++) {
        wrt_v3 a = v3_norm(v3(v[f[i][0]][0], v[f[i][0]][1], v[f[i][0]][2]));
        wrt_v3 b = v3_norm(v3(v[f[i][1]][0], v[f[i][1]][1], v[f[i][1]][2]));
        wrt_v3 cc = v3_norm(v3(v[f[i][2]][0], v[f[i][2]][1], v[f[i][2]][2]));
        wrt_v3 ab = v3_norm(v3_add(a, b)), bc = v3_norm(v3_add(b, cc)), ca = v3_norm(v3_add(cc, a));
        wrt_v3 tri[4][3] = {{a, ab, ca}, {ab, b, bc}, {ca, bc, cc}, {ab, bc, ca}};
        for (int k = 0; k < 4; k++) {
            wrt_quad parts[3];
            if (wrt_triangle_quads(tri[k][0], tri[k][1], tri[k][2], parts) != WRT_OK) return 0;
            for (int p = 0; p < 3; p++, nq++)
                for (int j = 0; j < 4; j++) {
                    wrt_v3 x = parts[p].p[j], n = v3_norm(x);
                    c[nq][j][0] = x.x; c[nq][j][1] = x.y; c[nq][j][2] = x.z;
                    nrm[nq][j][0] = (float)n.x; nrm[nq][j][1] = (float)n.y; nrm[nq][j][2] = (float)n.z;
                }
        }
    }
    return nq;
}

/* Quad q's display (out, 2^Lo a side) and its neighbours' along every shared edge whose
 * two quads are not coplanar (the triangles' edges, not the edges between a triangle's
 * own quads), read at the edge: the largest jump relative to the values there, and the
 * number of such edges. The neighbours are found from the geometry (both ends within
 * 1e-9), not from the module's adjacency. */
static double curved_edge_jump(int nq, const double (*c)[4][3], float *const *out, int Lo, int *nedges) {
    static const int ends[4][2] = {{0, 1}, {1, 2}, {3, 2}, {0, 3}};
    int no = 1 << Lo;
    double worst = 0;
    *nedges = 0;
    for (int q = 0; q < nq; q++)
        for (int e = 0; e < 4; e++)
            for (int o = q + 1; o < nq; o++)
                for (int g = 0; g < 4; g++) {
                    const double *a = c[q][ends[e][0]], *b = c[q][ends[e][1]];
                    const double *x = c[o][ends[g][0]], *y = c[o][ends[g][1]];
                    int fl;
                    if (fabs(a[0] - x[0]) + fabs(a[1] - x[1]) + fabs(a[2] - x[2]) < 1e-9 &&
                        fabs(b[0] - y[0]) + fabs(b[1] - y[1]) + fabs(b[2] - y[2]) < 1e-9) fl = 0;
                    else if (fabs(a[0] - y[0]) + fabs(a[1] - y[1]) + fabs(a[2] - y[2]) < 1e-9 &&
                             fabs(b[0] - x[0]) + fabs(b[1] - x[1]) + fabs(b[2] - x[2]) < 1e-9) fl = 1;
                    else continue;
                    /* coplanar pairs (inside a triangle) are the flat rule's, not counted */
                    wrt_v3 pq = v3_cross(v3_sub(v3(c[q][1][0], c[q][1][1], c[q][1][2]), v3(c[q][0][0], c[q][0][1], c[q][0][2])),
                                         v3_sub(v3(c[q][3][0], c[q][3][1], c[q][3][2]), v3(c[q][0][0], c[q][0][1], c[q][0][2])));
                    wrt_v3 po = v3_cross(v3_sub(v3(c[o][1][0], c[o][1][1], c[o][1][2]), v3(c[o][0][0], c[o][0][1], c[o][0][2])),
                                         v3_sub(v3(c[o][3][0], c[o][3][1], c[o][3][2]), v3(c[o][0][0], c[o][0][1], c[o][0][2])));
                    if (v3_dot(v3_norm(pq), v3_norm(po)) > 1 - 1e-9) continue;
                    (*nedges)++;
                    for (int k = 0; k < 16; k++) {
                        double tt = (k + 0.5) / 16, u, v, u2, v2;
                        edge_uv(e, tt, 0, &u, &v);
                        edge_uv(g, fl ? 1 - tt : tt, 0, &u2, &v2);
                        double va = lookup(out[q], no, 1, 0, u, v), vb = lookup(out[o], no, 1, 0, u2, v2);
                        worst = fmax(worst, fabs(va - vb) / (0.5 * (va + vb)));
                    }
                }
    return worst;
}

/* Quad q's n x n cells (at in + q n n): f = 1 + 0.5 z + 0.3 x at each cell's centre, a
 * smooth function on a sphere. */
static void smooth_cells(int nq, const double (*c)[4][3], int n, float *in) {
    for (int q = 0; q < nq; q++) {
        wrt_quad Q;
        memset(&Q, 0, sizeof Q);
        for (int j = 0; j < 4; j++) Q.p[j] = v3(c[q][j][0], c[q][j][1], c[q][j][2]);
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                wrt_v3 p = wrt_quad_point(&Q, (x + 0.5) / n, (y + 0.5) / n);
                in[(size_t)q * n * n + y * n + x] = (float)(1 + 0.5 * p.z + 0.3 * p.x);
            }
    }
}

/* The icosphere's quads, corner normals, one material, and n x n input and no x no output
 * cells for each (ico_free frees them). */
typedef struct ico_bufs {
    double (*c)[4][3];
    float (*nrm)[4][3];
    uint32_t *mat;
    float *in, *out;
    int nq;
} ico_bufs;

static ico_bufs ico_make(int n, int no) {
    ico_bufs b;
    b.c = malloc(240 * sizeof *b.c);
    b.nrm = malloc(240 * sizeof *b.nrm);
    b.nq = icosphere(b.c, b.nrm);
    CHECK(b.nq == 240, "icosphere of %d quads", b.nq);
    b.mat = calloc(240, sizeof *b.mat);
    b.in = malloc((size_t)240 * n * n * sizeof(float));
    b.out = malloc((size_t)240 * no * no * sizeof(float));
    return b;
}

static void ico_free(ico_bufs *b) { free(b->c); free(b->nrm); free(b->mat); free(b->in); free(b->out); }

/* A smooth-shaded icosphere: with its corner normals the display joins all 240 quads in
 * one group and is continuous across every edge between triangles (the texels on both
 * sides agree at the edge); without them (the flat rule) each triangle is its own group
 * and the display jumps there (by 1.1%). The light: f = 1 + 0.5 z + 0.3 x (cell centres), a smooth
 * function on the sphere. Then a cube, flat-shaded (each face's own normals): its edges
 * are creases and stay so, and a fold of 2 degrees whose two sides keep their own normals
 * (a crease below the tolerance's 1.1 degrees would be joined) is not joined either. */
static void test_smooth_mesh(void) {
    int L = 3, Lo = 4, n = 1 << L, no = 1 << Lo;
    ico_bufs ib = ico_make(n, no);
    double (*c)[4][3] = ib.c;
    float (*nrm)[4][3] = ib.nrm, *in = ib.in, *out = ib.out;
    uint32_t *mat = ib.mat;
    int nq = ib.nq;
    const float *ip[240];
    float *op[240];
    smooth_cells(nq, (const double (*)[4][3])c, n, in);
    for (int q = 0; q < nq; q++) {
        ip[q] = in + (size_t)q * n * n;
        op[q] = out + (size_t)q * no * no;
    }
    double jump[2];
    int ngr[2], nedges[2];
    for (int smooth = 0; smooth < 2; smooth++) {
        wrt_recon *rc = wrt_recon_create_smooth(nq, (const double (*)[4][3])c, mat, smooth ? (const float (*)[4][3])nrm : NULL,
                                                WRT_RECON_SMOOTH_COS, NULL);
        ngr[smooth] = wrt_recon_ngroups(rc);
        for (int gr = 0; gr < ngr[smooth]; gr++)
            CHECK(wrt_recon_run(rc, gr, L, Lo, 1, ip, NULL, op, NULL) == 0, "run group %d", gr);
        jump[smooth] = curved_edge_jump(nq, (const double (*)[4][3])c, op, Lo, &nedges[smooth]);
        wrt_recon_destroy(rc);
    }
    printf("icosphere, 240 quads: groups %d flat rule, %d with normals; %d edges between triangles: largest "
           "jump at the edge %.3g%% flat rule, %.3g%% with normals\n", ngr[0], ngr[1], nedges[1], 100 * jump[0],
           100 * jump[1]);
    CHECK(nedges[1] == 240, "the 80 triangles' 120 edges are %d quad edges (240, two halves each)", nedges[1]);
    CHECK(ngr[0] == 80 && ngr[1] == 1, "groups: %d flat (80, one a triangle), %d with normals (1)", ngr[0], ngr[1]);
    CHECK(jump[1] < 1e-5, "with normals the display is continuous across the triangles' edges (jump %g)", jump[1]);
    CHECK(jump[0] > 0.005, "the flat rule jumps there (%g): the measure sees seams", jump[0]);
    /* A flat-shaded cube: each face one quad, its normals its own. */
    double cube[6][4][3] = {{{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}},
                            {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{0, 1, 0}, {0, 1, 1}, {1, 1, 1}, {1, 1, 0}},
                            {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}}};
    float cn[6][4][3];
    for (int q = 0; q < 6; q++) {
        wrt_v3 a = v3(cube[q][0][0], cube[q][0][1], cube[q][0][2]);
        wrt_v3 nn = v3_norm(v3_cross(v3_sub(v3(cube[q][1][0], cube[q][1][1], cube[q][1][2]), a),
                                     v3_sub(v3(cube[q][3][0], cube[q][3][1], cube[q][3][2]), a)));
        for (int j = 0; j < 4; j++) { cn[q][j][0] = (float)nn.x; cn[q][j][1] = (float)nn.y; cn[q][j][2] = (float)nn.z; }
    }
    wrt_recon *rc = wrt_recon_create_smooth(6, (const double (*)[4][3])cube, mat, (const float (*)[4][3])cn,
                                            WRT_RECON_SMOOTH_COS, NULL);
    int joined = 0;
    for (int q = 0; q < 6; q++)
        for (int e = 0; e < 4; e++) joined += wrt_recon_neighbour(rc, q, e, NULL, NULL) >= 0;
    CHECK(wrt_recon_ngroups(rc) == 6 && joined == 0, "a flat-shaded cube: %d groups (6), %d joined edges (0)",
          wrt_recon_ngroups(rc), joined);
    wrt_recon_destroy(rc);
    /* The same cube with each corner's normal the mean of its three faces' (smooth
     * shaded): then its edges are smooth and all six faces one group. */
    for (int q = 0; q < 6; q++)
        for (int j = 0; j < 4; j++) {
            wrt_v3 m = v3_norm(v3(cube[q][j][0] - 0.5, cube[q][j][1] - 0.5, cube[q][j][2] - 0.5));
            cn[q][j][0] = (float)m.x; cn[q][j][1] = (float)m.y; cn[q][j][2] = (float)m.z;
        }
    rc = wrt_recon_create_smooth(6, (const double (*)[4][3])cube, mat, (const float (*)[4][3])cn, WRT_RECON_SMOOTH_COS, NULL);
    CHECK(wrt_recon_ngroups(rc) == 1, "a smooth-shaded cube: %d groups (1)", wrt_recon_ngroups(rc));
    wrt_recon_destroy(rc);
    /* A fold of 2 degrees, each side with its own flat normals: a crease, not joined; the
     * same fold with the mean normal on the shared edge: joined. */
    double fold[2][4][3] = {{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}},
                            {{1, 0, 0}, {2, 0, sin(2 * WRT_PI / 180)}, {2, 1, sin(2 * WRT_PI / 180)}, {1, 1, 0}}};
    wrt_v3 n1 = v3_norm(v3(-sin(2 * WRT_PI / 180), 0, 1)), nm = v3_norm(v3(-sin(1 * WRT_PI / 180), 0, 1));
    float fn[2][4][3];
    for (int pass = 0; pass < 2; pass++) {
        for (int j = 0; j < 4; j++) {
            int on_edge0 = j == 1 || j == 2, on_edge1 = j == 0 || j == 3;
            wrt_v3 a = pass && on_edge0 ? nm : v3(0, 0, 1), b = pass && on_edge1 ? nm : n1;
            fn[0][j][0] = (float)a.x; fn[0][j][1] = (float)a.y; fn[0][j][2] = (float)a.z;
            fn[1][j][0] = (float)b.x; fn[1][j][1] = (float)b.y; fn[1][j][2] = (float)b.z;
        }
        rc = wrt_recon_create_smooth(2, (const double (*)[4][3])fold, mat, (const float (*)[4][3])fn, WRT_RECON_SMOOTH_COS, NULL);
        CHECK(wrt_recon_ngroups(rc) == (pass ? 1 : 2), "a 2-degree fold, %s: %d groups", pass ? "mean normal on the edge" : "a crease",
              wrt_recon_ngroups(rc));
        wrt_recon_destroy(rc);
    }
    ico_free(&ib);
}

/* The three quads of triangle (a, b, c) split through its centroid and edge midpoints,
 * as the loader splits an unpaired triangle (a quad around each vertex), and their corner
 * normals from the vertex normals na, nb, nc (midpoints and centroid: the normalised mean). */
static void tri_quads(const wrt_v3 *p, const wrt_v3 *n, double (*c)[4][3], float (*cn)[4][3]) {
    wrt_v3 g = v3_scale(v3_add(v3_add(p[0], p[1]), p[2]), 1.0 / 3), gn = v3_norm(v3_add(v3_add(n[0], n[1]), n[2]));
    for (int i = 0; i < 3; i++) {
        int nx = (i + 1) % 3, pv = (i + 2) % 3;
        wrt_v3 pt[4] = {p[i], v3_scale(v3_add(p[i], p[nx]), 0.5), g, v3_scale(v3_add(p[i], p[pv]), 0.5)};
        wrt_v3 nn[4] = {n[i], v3_norm(v3_add(n[i], n[nx])), gn, v3_norm(v3_add(n[i], n[pv]))};
        for (int k = 0; k < 4; k++) {
            c[i][k][0] = pt[k].x; c[i][k][1] = pt[k].y; c[i][k][2] = pt[k].z;
            cn[i][k][0] = (float)nn[k].x; cn[i][k][1] = (float)nn[k].y; cn[i][k][2] = (float)nn[k].z;
        }
    }
}

/* Two triangles bent 20 degrees along their shared edge, each lit as a flat facet (every
 * cell its own constant: 1 and 2), as a UV sphere's faceted bake gives a smooth surface.
 * Smooth (the shared edge's vertex normals the mean of the two faces'): one group, the
 * quads at the edge curved, and the display blends across the edge: continuous there, no
 * more than 0.3 of the step outside [1, 2] (before, the facets' own cells were kept
 * with the slopes limited, and the edge's averaging pushed the texels beside the edge to
 * 0 and 3: the tiles' dark and bright lines), each quad's mean kept. Creased (each face its own normals): two groups, and each triangle's
 * display is exactly its constant (the step of 1 at the edge stays). */
static void test_smooth_strip(void) {
    double s20 = sin(20 * WRT_PI / 180), c20 = cos(20 * WRT_PI / 180);
    wrt_v3 P[4] = {v3(0, -1, 0), v3(0, 0, 1), v3(0, 0, -1), v3(s20, c20, 0)};
    wrt_v3 f1 = v3(1, 0, 0), f2 = v3_norm(v3_cross(v3_sub(P[2], P[1]), v3_sub(P[3], P[1])));
    if (f2.x < 0) f2 = v3_scale(f2, -1);
    int L = 2, Lo = 4, n = 1 << L, no = 1 << Lo;
    for (int smooth = 0; smooth < 2; smooth++) {
        wrt_v3 ne = smooth ? v3_norm(v3_add(f1, f2)) : f1;
        wrt_v3 t1[3] = {P[0], P[1], P[2]}, n1[3] = {f1, ne, ne};
        wrt_v3 t2[3] = {P[1], P[3], P[2]}, n2[3] = {smooth ? ne : f2, f2, smooth ? ne : f2};
        double c[6][4][3];
        float cn[6][4][3];
        tri_quads(t1, n1, c, cn);
        tri_quads(t2, n2, c + 3, cn + 3);
        uint32_t mat[6] = {0};
        float in[6][16], out[6][256];
        const float *ip[6];
        float *op[6];
        for (int q = 0; q < 6; q++) {
            for (int k = 0; k < n * n; k++) in[q][k] = q < 3 ? 1.0f : 2.0f;
            ip[q] = in[q];
            op[q] = out[q];
        }
        wrt_recon *rc = wrt_recon_create_smooth(6, (const double (*)[4][3])c, mat, (const float (*)[4][3])cn,
                                                WRT_RECON_SMOOTH_COS, NULL);
        int ng = wrt_recon_ngroups(rc), ncurved = 0;
        for (int q = 0; q < 6; q++) ncurved += wrt_recon_curved(rc, q);
        /* the display before (curved quads as flat: their cells kept, slopes limited) */
        const wrt_recon_params before = {WRT_RECON_KEEP, WRT_RECON_SHARP, 1, 0, 1, 0};
        double blo = INFINITY, bhi = -INFINITY;
        for (int gr = 0; gr < ng; gr++) CHECK(wrt_recon_run(rc, gr, L, Lo, 1, ip, NULL, op, &before) == 0, "run %d", gr);
        for (int q = 0; q < 6; q++)
            for (int k = 0; k < no * no; k++) { blo = fmin(blo, out[q][k]); bhi = fmax(bhi, out[q][k]); }
        /* session 7's display (each curved quad its facet's mean, the prediction unlimited) */
        const wrt_recon_params means = {WRT_RECON_KEEP, WRT_RECON_SHARP, 1, 0, 0, 1};
        for (int gr = 0; gr < ng; gr++) CHECK(wrt_recon_run(rc, gr, L, Lo, 1, ip, NULL, op, &means) == 0, "run %d", gr);
        double lo = INFINITY, hi = -INFINITY, worst_mean = 0;
        for (int q = 0; q < 6; q++) {
            double sum = 0;
            for (int k = 0; k < no * no; k++) { lo = fmin(lo, out[q][k]); hi = fmax(hi, out[q][k]); sum += out[q][k]; }
            worst_mean = fmax(worst_mean, fabs(sum / (no * no) - in[q][0]));
        }
        int nedges, nedges7;
        double jump7 = curved_edge_jump(6, (const double (*)[4][3])c, op, Lo, &nedges7);
        /* the vertex blend (the default) */
        for (int gr = 0; gr < ng; gr++) CHECK(wrt_recon_run(rc, gr, L, Lo, 1, ip, NULL, op, NULL) == 0, "run %d", gr);
        double vlo = INFINITY, vhi = -INFINITY;
        for (int q = 0; q < 6; q++)
            for (int k = 0; k < no * no; k++) { vlo = fmin(vlo, out[q][k]); vhi = fmax(vhi, out[q][k]); }
        double jump = curved_edge_jump(6, (const double (*)[4][3])c, op, Lo, &nedges);
        /* the far vertices P0 (quad 0's corner 0) and P3 (quad 4's corner 0: tri_quads(t2)
         * starts at P1) each lie on one facet: their value is that facet's */
        float v0 = out[0][0], v3 = out[4][0];
        printf("two triangles bent 20 degrees, %s: %d groups, %d curved quads, texels %.4f .. %.4f, jump at the edge "
               "%.3g; session 7: texels %.4f .. %.4f, jump %.3g, worst quad mean off by %.3g; before: texels %.4f .. "
               "%.4f\n", smooth ? "smooth" : "creased", ng, ncurved, vlo, vhi, jump, lo, hi, jump7, worst_mean, blo, bhi);
        if (smooth) {
            CHECK(ng == 1 && ncurved == 4, "smooth strip: %d groups (1), %d curved quads (4: those on the edge)", ng, ncurved);
            CHECK(nedges == 2 && jump < 1e-6 && jump7 < 1e-6,
                  "smooth strip: continuous across the shared edge's %d halves (jump %g, session 7 %g)", nedges, jump, jump7);
            /* a step of 1 between the facets (the hardest case: a sphere's facets differ by a
             * gradient): session 7's unlimited prediction overshoots it by 0.254, under 0.3;
             * the flat facets' display made lines from 0 to 3 beside the edge; the vertex
             * blend is a mean of the facets' values: never outside them */
            CHECK(lo >= 0.7 && hi <= 2.3, "smooth strip, session 7: texels within 0.7 .. 2.3 (%g .. %g)", lo, hi);
            CHECK(blo < 0.5 && bhi > 2.5, "smooth strip, the display before: the lines beside the edge (%g .. %g)", blo, bhi);
            CHECK(worst_mean < 1e-5, "smooth strip, session 7: each quad keeps its mean (off by %g)", worst_mean);
            CHECK(vlo >= 1 && vhi <= 2 && vhi - vlo > 0.99, "smooth strip, vertex blend: texels %g .. %g (1 .. 2)", vlo, vhi);
            CHECK(v0 == 1 && v3 == 2, "smooth strip, vertex blend: the far vertices %g and %g (1 and 2)", v0, v3);
        } else {
            CHECK(ng == 2 && ncurved == 0, "creased strip: %d groups (2), %d curved quads (0)", ng, ncurved);
            CHECK(lo == 1 && hi == 2 && blo == 1 && bhi == 2 && vlo == 1 && vhi == 2,
                  "creased strip: texels %g .. %g (session 7 %g .. %g, before %g .. %g)", vlo, vhi, lo, hi, blo, bhi);
            for (int q = 0; q < 6; q++)
                for (int k = 0; k < no * no; k++)
                    if (out[q][k] != in[q][0]) { CHECK(0, "creased strip: quad %d texel %d is %g, not %g", q, k, out[q][k], in[q][0]); q = 6; break; }
        }
        wrt_recon_destroy(rc);
    }
}

/* The display of a smooth-shaded icosphere whose bake saw flat facets, against the smooth
 * surface's truth. 80 triangles (240 quads), radial vertex normals; a distant environment
 * of radiance a + b w.d gives a flat facet of normal n the irradiance E(n) = pi a + (2 pi / 3)
 * b n.d (closed form), the same over the whole facet: each quad's cells are its facet's
 * E(n_face), as the bake computes a flat facet's light. The smooth surface the player and
 * the path tracer shade has at x the interpolated normal n_s(x) (common/smooth.h), so its
 * truth is E(n_s(x)), which varies across a facet and is continuous across its edges.
 * Measured at 8 x 8 points a quad (the display read as the GPU reads it, bilinear and
 * clamped): the vertex blend's largest and RMS error against that truth, and its largest
 * step between neighbouring texels (inside a quad and across its edges) against the
 * truth's own; session 7's display (each facet its own mean) for comparison, which keeps
 * the facets: about a facet's spread of E inside each. */
static void test_smooth_blend(void) {
    int L = 3, Lo = 4, n = 1 << L, no = 1 << Lo;
    ico_bufs ib = ico_make(n, no);
    const float *ip[240];
    float *op[240];
    wrt_v3 d = v3_norm(v3(1, 2, 3));
    const double Ea = 1, Eb = 0.5; /* pi a and (2 pi / 3) b */
    wrt_smooth_src *src = malloc(240 * sizeof *src);
    for (int q = 0; q < ib.nq; q++) {
        wrt_v3 p[4];
        for (int k = 0; k < 4; k++) p[k] = v3(ib.c[q][k][0], ib.c[q][k][1], ib.c[q][k][2]);
        wrt_v3 fn = v3_norm(v3_cross(v3_sub(p[2], p[0]), v3_sub(p[3], p[1])));
        if (v3_dot(fn, p[0]) < 0) fn = v3_scale(fn, -1);
        wrt_smooth_make(p, fn, (const float (*)[3])ib.nrm[q], -1, &src[q]);
        ip[q] = ib.in + (size_t)q * n * n;
        op[q] = ib.out + (size_t)q * no * no;
        for (int k = 0; k < n * n; k++) ib.in[(size_t)q * n * n + k] = (float)(Ea + Eb * v3_dot(fn, d));
    }
    CHECK(src[0].curved && src[0].nsrc == 3, "the icosphere's quads are curved triangle parts (%d, %d)", src[0].curved,
          src[0].nsrc);
    wrt_recon *rc = wrt_recon_create_smooth(ib.nq, (const double (*)[4][3])ib.c, ib.mat, (const float (*)[4][3])ib.nrm,
                                            WRT_RECON_SMOOTH_COS, NULL);
    CHECK(wrt_recon_ngroups(rc) == 1, "one group (%d)", wrt_recon_ngroups(rc));
    double worst[2], rms[2], step[2], tstep = 0, across[2];
    for (int mode = 0; mode < 2; mode++) { /* 0 the vertex blend, 1 session 7's display */
        const wrt_recon_params means = {WRT_RECON_KEEP, WRT_RECON_SHARP, 1, 0, 0, 1};
        CHECK(wrt_recon_run(rc, 0, L, Lo, 1, ip, NULL, op, mode ? &means : NULL) == 0, "run");
        double w = 0, s2 = 0, st = 0;
        int cnt = 0;
        for (int q = 0; q < ib.nq; q++) {
            wrt_quad Q;
            memset(&Q, 0, sizeof Q);
            for (int k = 0; k < 4; k++) Q.p[k] = v3(ib.c[q][k][0], ib.c[q][k][1], ib.c[q][k][2]);
            for (int y = 0; y < 8; y++)
                for (int x = 0; x < 8; x++) {
                    double u = (x + 0.5) / 8, v = (y + 0.5) / 8, sw[4];
                    wrt_v3 pt = wrt_quad_point(&Q, u, v), ns, ps;
                    wrt_smooth_weights(&src[q], pt, sw);
                    wrt_smooth_at(&src[q], sw, pt, v3(0, 0, 0), &ns, &ps);
                    double truth = Ea + Eb * v3_dot(ns, d), shown = lookup(op[q], no, 1, 0, u, v);
                    w = fmax(w, fabs(shown - truth) / truth);
                    s2 += (shown - truth) * (shown - truth) / (truth * truth);
                    cnt++;
                }
            /* neighbouring texels inside the quad, and (once) the truth's at their centres */
            for (int y = 0; y < no; y++)
                for (int x = 0; x < no; x++) {
                    const float *t = op[q] + y * no + x;
                    if (x + 1 < no) st = fmax(st, fabs(t[1] - t[0]) / t[0]);
                    if (y + 1 < no) st = fmax(st, fabs(t[no] - t[0]) / t[0]);
                    if (mode || x + 1 >= no) continue;
                    double e2[2];
                    for (int h = 0; h < 2; h++) {
                        double sw[4];
                        wrt_v3 pt = wrt_quad_point(&Q, (x + h + 0.5) / no, (y + 0.5) / no), ns, ps;
                        wrt_smooth_weights(&src[q], pt, sw);
                        wrt_smooth_at(&src[q], sw, pt, v3(0, 0, 0), &ns, &ps);
                        e2[h] = Ea + Eb * v3_dot(ns, d);
                    }
                    tstep = fmax(tstep, fabs(e2[1] - e2[0]) / e2[0]);
                }
        }
        int ne;
        worst[mode] = w;
        rms[mode] = sqrt(s2 / cnt);
        step[mode] = st;
        across[mode] = curved_edge_jump(ib.nq, (const double (*)[4][3])ib.c, op, Lo, &ne);
    }
    printf("icosphere lit as flat facets, against E at the smooth normal: vertex blend worst %.2f%% rms %.2f%%, largest "
           "step between texels %.3f%%, across edges %.3g%%; session 7's display worst %.2f%% rms %.2f%%, step %.3f%%, "
           "across %.3g%%; the truth's step %.3f%%\n", 100 * worst[0], 100 * rms[0], 100 * step[0], 100 * across[0],
           100 * worst[1], 100 * rms[1], 100 * step[1], 100 * across[1], 100 * tstep);
    /* measured: worst 11.1%, rms 3.78% (session 7: 14.4%, 4.59%): a mean of unit normals is
     * shorter than one (a facet's normal is 20 degrees from its vertices' here), so the
     * blend of the facets' E shrinks E's part that varies with the normal by about
     * 1 - cos 20 degrees at a vertex and again inside (docs/triangles.md); the worst is at
     * the centroids where n.d is least */
    CHECK(worst[0] < 0.12 && rms[0] < 0.04 && rms[0] < rms[1], "vertex blend against the smooth truth: worst %g, rms %g "
          "(bounds 12%%, 4%%, and under session 7's %g)", worst[0], rms[0], rms[1]);
    CHECK(step[0] < 2 * tstep + 1e-4, "vertex blend: no step between texels beyond twice the truth's (%g, truth %g)", step[0],
          tstep);
    CHECK(across[0] < 1e-5, "vertex blend: continuous across the triangles' edges (%g)", across[0]);
    CHECK(step[1] > 8 * tstep, "session 7's display keeps the facets: a step of %g between texels (truth %g)", step[1], tstep);
    wrt_recon_destroy(rc);
    ico_free(&ib);
    free(src);
}

/* ------------------------------------------------------- through the player ---- */

/* A UV sphere of radius 1 as the loader makes Blender's: its ring band of paired quads
 * (planar trapezoids) and its two pole fans of unpaired triangles, each cut into three
 * quads (tri_quads), so that every quad edge on the fans' rims is half of a band quad's
 * edge (a T-junction). Corner normals radial on the band; on the fans the vertex normals
 * radial, or (crease 1) each triangle's flat normal, which splits them from the band.
 * seg segments, rings rings; returns the number of quads, seg (rings - 2) + 6 seg, the
 * band's first. */
static int uv_sphere(int seg, int rings, int crease, double (*c)[4][3], float (*cn)[4][3]) {
    int nq = 0;
    for (int i = 1; i < rings - 1; i++)
        for (int j = 0; j < seg; j++, nq++) {
            int ii[4] = {i, i + 1, i + 1, i}, jj[4] = {j, j, j + 1, j + 1}; /* south, then east: outward */
            for (int k = 0; k < 4; k++) {
                double th = WRT_PI * ii[k] / rings, ph = 2 * WRT_PI * jj[k] / seg;
                double x = sin(th) * cos(ph), y = sin(th) * sin(ph), z = cos(th);
                c[nq][k][0] = x; c[nq][k][1] = y; c[nq][k][2] = z;
                cn[nq][k][0] = (float)x; cn[nq][k][1] = (float)y; cn[nq][k][2] = (float)z;
            }
        }
    for (int pole = 0; pole < 2; pole++)
        for (int j = 0; j < seg; j++, nq += 3) {
            int ring = pole ? rings - 1 : 1;
            double th = WRT_PI * ring / rings, p0 = 2 * WRT_PI * j / seg, p1 = 2 * WRT_PI * (j + 1) / seg;
            wrt_v3 P[3] = {v3(0, 0, pole ? -1 : 1), v3(sin(th) * cos(p0), sin(th) * sin(p0), cos(th)),
                           v3(sin(th) * cos(p1), sin(th) * sin(p1), cos(th))};
            if (v3_dot(v3_cross(v3_sub(P[1], P[0]), v3_sub(P[2], P[0])), P[0]) < 0) { wrt_v3 t = P[1]; P[1] = P[2]; P[2] = t; }
            wrt_v3 fl = v3_norm(v3_cross(v3_sub(P[1], P[0]), v3_sub(P[2], P[0])));
            wrt_v3 N[3] = {crease ? fl : P[0], crease ? fl : P[1], crease ? fl : P[2]};
            tri_quads(P, N, c + nq, cn + nq);
        }
    return nq;
}

/* The largest jump of the display (out, 2^Lo a side) across the T-junctions of quads c:
 * wherever an edge of one quad lies along a longer edge of another (found from the
 * geometry, 1e-9, not from the module's adjacency), 16 points along the shorter one,
 * read at the edge on both sides, relative to the mean there; *nt the number of such
 * edge pairs, *jump_mid the largest jump at the points that lie more than a texel of the
 * shorter edge's quad from its ends. */
static double tjunction_jump(int nq, const double (*c)[4][3], float *const *out, int Lo, int *nt, double *jump_mid) {
    static const int ends[4][2] = {{0, 1}, {1, 2}, {3, 2}, {0, 3}};
    int no = 1 << Lo;
    double worst = 0;
    *nt = 0;
    *jump_mid = 0;
    for (int q = 0; q < nq; q++)
        for (int e = 0; e < 4; e++) {
            wrt_v3 a = v3(c[q][ends[e][0]][0], c[q][ends[e][0]][1], c[q][ends[e][0]][2]);
            wrt_v3 b = v3(c[q][ends[e][1]][0], c[q][ends[e][1]][1], c[q][ends[e][1]][2]), d = v3_sub(b, a);
            for (int o = 0; o < nq; o++)
                for (int g = 0; g < 4 && o != q; g++) {
                    wrt_v3 x = v3(c[o][ends[g][0]][0], c[o][ends[g][0]][1], c[o][ends[g][0]][2]);
                    wrt_v3 y = v3(c[o][ends[g][1]][0], c[o][ends[g][1]][1], c[o][ends[g][1]][2]);
                    double tx = v3_dot(v3_sub(x, a), d) / v3_dot(d, d), ty = v3_dot(v3_sub(y, a), d) / v3_dot(d, d);
                    wrt_v3 px = v3_add(a, v3_scale(d, tx)), py = v3_add(a, v3_scale(d, ty));
                    if (v3_len(v3_sub(px, x)) > 1e-9 || v3_len(v3_sub(py, y)) > 1e-9) continue; /* not collinear */
                    if (fmin(tx, ty) < -1e-9 || fmax(tx, ty) > 1 + 1e-9 || fabs(ty - tx) > 1 - 1e-9) continue;
                    (*nt)++; /* o's edge g lies inside q's edge e, shorter */
                    for (int k = 0; k < 16; k++) {
                        double s = (k + 0.5) / 16, t = tx + s * (ty - tx), u, v, u2, v2;
                        edge_uv(e, t, 0, &u, &v);
                        edge_uv(g, s, 0, &u2, &v2);
                        double va = lookup(out[q], no, 1, 0, u, v), vb = lookup(out[o], no, 1, 0, u2, v2);
                        double j = fabs(va - vb) / (0.5 * (va + vb));
                        worst = fmax(worst, j);
                        if (s > 1.0 / no && s < 1 - 1.0 / no) *jump_mid = fmax(*jump_mid, j);
                    }
                }
        }
    return worst;
}

/* Where a UV sphere's band of paired quads meets its pole fans (each rim edge of the band
 * against two half-edges of a triangle's quads: a T-junction), the smooth display joins
 * them: one group, not three, and continuous across the rims to a stated bound for a
 * smooth function (f = 1 + 0.5 z + 0.3 x at the cells' centres); on main they were
 * three groups, each extrapolating at its rim. With the fans' normals flat (a crease at
 * the rims) they stay apart, and a step from 1 on the band to 2 on the fans stays exact. */
static void test_tjunction_sphere(void) {
    enum { SEG = 16, RINGS = 8, NQ = SEG * (RINGS - 2) + 6 * SEG };
    double (*c)[4][3] = malloc(NQ * sizeof *c);
    float (*cn)[4][3] = malloc(NQ * sizeof *cn);
    uint32_t mat[NQ] = {0};
    int L = 3, Lo = 3, n = 1 << L, no = 1 << Lo;
    float *in = malloc((size_t)NQ * n * n * sizeof(float)), *out = malloc((size_t)NQ * no * no * sizeof(float));
    const float *ip[NQ];
    float *op[NQ];
    for (int crease = 0; crease < 2; crease++) {
        int nq = uv_sphere(SEG, RINGS, crease, c, cn), band = SEG * (RINGS - 2);
        CHECK(nq == NQ, "UV sphere of %d quads (%d)", nq, NQ);
        smooth_cells(nq, (const double (*)[4][3])c, n, in);
        for (int q = 0; q < nq; q++) {
            ip[q] = in + (size_t)q * n * n;
            op[q] = out + (size_t)q * no * no;
            for (int k = 0; k < n * n && crease; k++) in[(size_t)q * n * n + k] = q < band ? 1.0f : 2.0f;
        }
        wrt_recon *rc = wrt_recon_create_smooth(nq, (const double (*)[4][3])c, mat, (const float (*)[4][3])cn,
                                                WRT_RECON_SMOOTH_COS, NULL);
        int ng = wrt_recon_ngroups(rc), npart = 0;
        for (int q = 0; q < nq; q++)
            for (int e = 0; e < 4; e++)
                for (int i = 0; wrt_recon_partial(rc, q, e, i, NULL, NULL) >= 0; i++) npart++;
        /* session 7's display: each quad keeps its mean (the texel sum, the display's integral) */
        const wrt_recon_params means = {WRT_RECON_KEEP, WRT_RECON_SHARP, 1, 0, 0, 1};
        for (int gr = 0; gr < ng; gr++) CHECK(wrt_recon_run(rc, gr, L, Lo, 1, ip, NULL, op, &means) == 0, "run %d", gr);
        double worst_mean = 0;
        for (int q = 0; q < nq; q++) {
            double si = 0, so = 0;
            for (int k = 0; k < n * n; k++) si += ip[q][k];
            for (int k = 0; k < no * no; k++) so += op[q][k];
            worst_mean = fmax(worst_mean, fabs(so / (no * no) - si / (n * n)) / (si / (n * n)));
        }
        CHECK(worst_mean < 1e-5, "session 7's display: every quad keeps its mean (off by %g of itself)", worst_mean);
        for (int gr = 0; gr < ng; gr++) CHECK(wrt_recon_run(rc, gr, L, Lo, 1, ip, NULL, op, NULL) == 0, "run %d", gr);
        int nt, nedges;
        double mid, jump = tjunction_jump(nq, (const double (*)[4][3])c, op, Lo, &nt, &mid);
        double whole = curved_edge_jump(nq, (const double (*)[4][3])c, op, Lo, &nedges);
        printf("UV sphere %d x %d, %s fans: %d groups, %d partial neighbour entries, %d T-junction edge pairs: largest "
               "jump %.3g%% (%.3g%% a texel from the ends); whole curved edges %d, jump %.3g%%\n", SEG, RINGS,
               crease ? "creased" : "smooth", ng, npart, nt, 100 * jump, 100 * mid, nedges, 100 * whole);
        CHECK(nt == 4 * SEG, "%d half-edges of the fans against the band's rims (%d)", nt, 4 * SEG);
        if (!crease) {
            CHECK(ng == 1, "smooth UV sphere: one group (%d; band and caps apart: 3)", ng);
            CHECK(npart == 8 * SEG, "partial neighbours: %d (%d: each rim edge of the band its two halves, each half the rim edge)", npart, 8 * SEG);
            /* measured 0.212% with the vertex blend (session 7's display 0.246%; main, three
             * groups: 5.6%): at the T's vertex, where the half-edges' corner texel is flat
             * for half of their texel and the whole edge's display is not (first order);
             * 0.110% a texel from the ends */
            CHECK(jump < 0.005, "continuous across the T-junctions: largest jump %g (bound 0.5%%)", jump);
            CHECK(mid < 0.002, "away from the T's vertex and the rim's corners: jump %g (bound 0.2%%)", mid);
            CHECK(whole < 1e-5, "and across the whole curved edges: %g", whole);
        } else {
            CHECK(ng == 1 + 2 * SEG && npart == 0, "creased fans: %d groups (the band and each flat triangle: %d), %d "
                  "partial neighbours (0)", ng, 1 + 2 * SEG, npart);
            int exact = 1;
            for (int q = 0; q < nq && exact; q++)
                for (int k = 0; k < no * no; k++)
                    if (op[q][k] != (q < band ? 1.0f : 2.0f)) { exact = 0; CHECK(0, "creased: quad %d texel %d is %g", q, k, op[q][k]); break; }
            CHECK(exact && jump > 0.6, "the crease stays sharp: band 1, fans 2 exactly (jump %g)", jump);
        }
        wrt_recon_destroy(rc);
    }
    free(c); free(cn); free(in); free(out);
}

static char tmpdir[256];

typedef struct player { wrt_gto g; wrt_relight *rl, *rh; char path[300]; } player;

/* Bakes s at `quality`, writes and maps the .gto, makes a smooth and a Haar relighter
 * lit by `l`. */
static int player_open(const wrt_scene *s, int quality, const wrt_light *l, player *p) {
    static int counter;
    memset(p, 0, sizeof *p);
    wrt_bake_options o = {0};
    o.quality = quality;
    o.threads = 2;
    wrt_bake_result r;
    if (wrt_bake_run(s, &o, &r) != WRT_OK) { CHECK(0, "bake: %s", wrt_last_error()); return 0; }
    snprintf(p->path, sizeof p->path, "%s/r%d.gto", tmpdir, counter++);
    wrt_scene sc = *s; /* no names */
    sc.quads = malloc((size_t)s->nquads * sizeof *sc.quads);
    memcpy(sc.quads, s->quads, (size_t)s->nquads * sizeof *sc.quads);
    for (int q = 0; q < sc.nquads; q++) sc.quads[q].name = -1;
    wrt_gto_contents gc = {.scene = &sc, .fkeys = r.fkeys, .nfuncs = r.nfuncs, .col_start = r.op.col,
                           .rows = r.op.row, .vals = r.op.val, .op_kind = (uint32_t)r.op_kind,
                           .material_alevel = r.material_alevel};
    wrt_status st = wrt_gto_write(p->path, &gc);
    wrt_bake_result_free(&r);
    free(sc.quads);
    if (st != WRT_OK || wrt_gto_open(p->path, &p->g) != WRT_OK) { CHECK(0, "gto: %s", wrt_last_error()); return 0; }
    wrt_relight_options ro = {.threads = 2};
    CHECK(wrt_relight_create(&p->g, &ro, &p->rl) == WRT_OK, "relight: %s", wrt_last_error());
    ro.haar_blocks = 1;
    CHECK(wrt_relight_create(&p->g, &ro, &p->rh) == WRT_OK, "relight: %s", wrt_last_error());
    if (!p->rl || !p->rh) return 0;
    double eye[3] = {0, 0.5, 0};
    wrt_relight *both[2] = {p->rl, p->rh};
    for (int k = 0; k < 2; k++) {
        wrt_relight_set_eye(both[k], eye);
        wrt_relight_set_lights(both[k], l, NULL, 1);
        wrt_relight_update(both[k], NULL);
    }
    return 1;
}

static void player_close(player *p) {
    wrt_relight_destroy(p->rl);
    wrt_relight_destroy(p->rh);
    wrt_gto_close(&p->g);
    unlink(p->path);
}

static wrt_light point_light(wrt_v3 pos) {
    wrt_light l;
    memset(&l, 0, sizeof l);
    l.type = WRT_LIGHT_POINT;
    l.pos = pos;
    l.dir = v3(0, -1, 0);
    l.color[0] = l.color[1] = l.color[2] = 1;
    l.intensity = 1;
    l.outer_cone = (float)(M_PI / 4);
    return l;
}

static double tex_max(const wrt_relight *r, int q) {
    const float *t = wrt_relight_tex(r, q);
    int res = wrt_relight_tex_res(r, q);
    double mx = 0;
    for (int i = 0; i < res * res * 3; i++) mx = fmax(mx, t[i]);
    return mx;
}

/* Two closed rooms sharing a wall (back to back, no thickness), each face 2 x 2 quads, so
 * the floors (and ceilings, far walls) of the two rooms are coplanar neighbours whose
 * shared edge has the wall standing on it; the light in room A: room B's textures stay
 * below 1e-4 of room A's. */
static void test_two_rooms_dark(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.75, 0.75, 0.75);
    tsb_box_inward(&s, v3(-1, 0, -0.5), v3(0, 1, 0.5), 2, m);
    int na = s.nquads;
    tsb_box_inward(&s, v3(0, 0, -0.5), v3(1, 1, 0.5), 2, m);
    wrt_light l = point_light(v3(-0.5, 0.5, 0));
    player p;
    if (!player_open(&s, 3, &l, &p)) { tsb_free(&s); return; }
    double a = 0, b = 0;
    for (int q = 0; q < s.nquads; q++) {
        double mx = tex_max(p.rl, q);
        if (q < na) a = fmax(a, mx); else b = fmax(b, mx);
    }
    fprintf(stderr, "  two rooms: brightest texel of the dark room %.3g, of the lit room %.3g\n", b, a);
    CHECK(a > 0, "room A is lit (%g)", a);
    CHECK(b <= 1e-4 * a, "room B's brightest texel %g is %g of room A's", b, a > 0 ? b / a : 0);
    player_close(&p);
    tsb_free(&s);
}

/* A closed box, each face 4 x 4 quads, light inside: the jump of the display across the
 * shared edges (a quarter texel either side) is no larger than the jump across each quad's
 * middle line at the same distance, where the Haar blocks jump more than twice as much
 * across the edges as inside (measured: 2.5 times). */
static void test_box_no_seams(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.75, 0.75, 0.75);
    tsb_box_inward(&s, v3(-0.5, 0, -0.5), v3(0.5, 1, 0.5), 4, m);
    wrt_light l = point_light(v3(0.1, 0.8, 0.2));
    player p;
    if (!player_open(&s, 3, &l, &p)) { tsb_free(&s); return; }
    double (*c)[4][3] = malloc((size_t)s.nquads * sizeof *c);
    uint32_t *mat = calloc((size_t)s.nquads, sizeof(uint32_t));
    for (int q = 0; q < s.nquads; q++)
        for (int k = 0; k < 4; k++) { c[q][k][0] = s.quads[q].p[k].x; c[q][k][1] = s.quads[q].p[k].y; c[q][k][2] = s.quads[q].p[k].z; }
    wrt_recon *rc = wrt_recon_create(s.nquads, (const double (*)[4][3])c, mat);
    CHECK(wrt_recon_ngroups(rc) == 6, "six faces, six groups (%d)", wrt_recon_ngroups(rc));
    double across[2] = {0, 0}, inside[2] = {0, 0};
    wrt_relight *both[2] = {p.rl, p.rh};
    for (int k = 0; k < 2; k++)
        for (int q = 0; q < s.nquads; q++)
            for (int e = 0; e < 4; e++) {
                int ne, fl, o = wrt_recon_neighbour(rc, q, e, &ne, &fl);
                if (o < q) continue;
                int rq = wrt_relight_tex_res(both[k], q), ro = wrt_relight_tex_res(both[k], o);
                const float *tq = wrt_relight_tex(both[k], q), *to = wrt_relight_tex(both[k], o);
                for (int i = 0; i < 16; i++) {
                    double t = (i + 0.5) / 16, u, v, u2, v2;
                    edge_uv(e, t, 0.25 / rq, &u, &v);
                    edge_uv(ne, fl ? 1 - t : t, 0.25 / ro, &u2, &v2);
                    double a = lookup(tq, rq, 3, 1, u, v), b = lookup(to, ro, 3, 1, u2, v2);
                    edge_uv(e, t, 0.5 - 0.25 / rq, &u, &v);
                    edge_uv(e, t, 0.5 + 0.25 / rq, &u2, &v2);
                    double c0 = lookup(tq, rq, 3, 1, u, v), c1 = lookup(tq, rq, 3, 1, u2, v2);
                    across[k] += fabs(a - b);
                    inside[k] += fabs(c0 - c1);
                }
            }
    fprintf(stderr, "  seams: smooth across %.4g inside %.4g; Haar blocks across %.4g inside %.4g\n", across[0],
            inside[0], across[1], inside[1]);
    CHECK(across[0] <= inside[0], "smooth: jump across shared edges %g, inside quads %g", across[0], inside[0]);
    CHECK(across[1] > 2 * inside[1], "the Haar blocks do show seams: across %g, inside %g", across[1], inside[1]);
    free(c); free(mat);
    wrt_recon_destroy(rc);
    player_close(&p);
    tsb_free(&s);
}

/* The neighbour search's grid (reconstruct.c qgrid): on a 60 x 60 grid of unit quads whose
 * shared corners are each quad's own copy, moved by up to 0.3 of the tolerance (1e-6 of
 * the scene's size) per coordinate (x not on the line x = 30), every inner edge finds the quad across it; a wall
 * standing on the line x = 30 over the whole grid (one quad over many of the grid's cells,
 * on the list every query returns) blocks the 60 edges on that line on both sides. A
 * search that missed a candidate in a neighbouring cell, or the wall, fails it. */
static void test_neighbour_grid(void) {
    enum { G = 60 };
    int n = G * G + 1;
    double (*c)[4][3] = malloc((size_t)n * sizeof *c);
    uint32_t *m = calloc((size_t)n, sizeof *m);
    double tol = 1e-6 * sqrt(2.0 * G * G + 6.0 * 6.0);
    uint64_t h = 12345;
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            int q = j * G + i;
            double x[4] = {i, i + 1, i + 1, i}, y[4] = {j, j, j + 1, j + 1};
            for (int k = 0; k < 4; k++) {
                double *p = c[q][k];
                p[0] = x[k]; p[1] = y[k]; p[2] = 0;
                for (int a = 0; a < 2; a++) {
                    h = h * 6364136223846793005ULL + 1442695040888963407ULL;
                    /* the line x = 30 kept straight: the wall's edge, 60 long, must lie
                     * within tol of each short edge's line there */
                    if (a == 1 || x[k] != 30) p[a] += 0.3 * tol * (2.0 * (double)(h >> 11) / 9007199254740992.0 - 1);
                }
            }
        }
    double wall[4][3] = {{30, 0, 0}, {30, G, 0}, {30, G, 6}, {30, 0, 6}};
    memcpy(c[G * G], wall, sizeof wall);
    m[G * G] = 1;
    wrt_recon *rc = wrt_recon_create(n, (const double (*)[4][3])c, m);
    CHECK(rc != NULL, "the grid's reconstruction made");
    int found = 0, blocked = 0, wrong = 0;
    for (int j = 0; j < G && rc; j++)
        for (int i = 0; i < G; i++) {
            int q = j * G + i, ne, fl;
            /* edges 0: v = 0 (below), 1: u = 1 (right), 2: v = 1 (above), 3: u = 0 (left) */
            int want[4] = {j > 0 ? q - G : -1, i < G - 1 ? q + 1 : -1, j < G - 1 ? q + G : -1, i > 0 ? q - 1 : -1};
            if (i == 29) want[1] = -1;
            if (i == 30) want[3] = -1;
            for (int e = 0; e < 4; e++) {
                int o = wrt_recon_neighbour(rc, q, e, &ne, &fl);
                if (o != want[e]) wrong++;
                else if (o >= 0) found++;
            }
            blocked += (i == 29 && wrt_recon_neighbour(rc, q, 1, &ne, &fl) < 0) +
                       (i == 30 && wrt_recon_neighbour(rc, q, 3, &ne, &fl) < 0);
        }
    CHECK(wrong == 0 && found == 4 * G * (G - 1) - 2 * G && blocked == 2 * G,
          "grid of %d quads: %d edges with the quad across them (want %d), %d blocked by the wall (want %d), %d wrong",
          G * G, found, 4 * G * (G - 1) - 2 * G, blocked, 2 * G, wrong);
    wrt_recon_destroy(rc);
    free(c); free(m);
}

int main(int argc, char **argv) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wrt_test_reconstruct_XXXXXX");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    TEST_RUN(test_all_known_is_identity);
    TEST_RUN(test_neighbour_grid);
    TEST_RUN(test_known_averages_kept);
    TEST_RUN(test_linear_reproduced);
    TEST_RUN(test_continuous_across_edges);
    TEST_RUN(test_rgb_is_scalar);
    TEST_RUN(test_linear_superposes);
    TEST_RUN(test_no_light_across);
    TEST_RUN(test_smooth_mesh);
    TEST_RUN(test_smooth_strip);
    TEST_RUN(test_tjunction_sphere);
    TEST_RUN(test_smooth_blend);
    TEST_RUN(test_two_rooms_dark);
    TEST_RUN(test_box_no_seams);
    rmdir(tmpdir);
    TEST_END();
}
