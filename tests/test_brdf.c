/* test_brdf.c: checks of common/brdf.c against properties any physical BRDF must
 * have and against brute-force integration that does not use the code's sampler:
 * the Lambertian value, reciprocity, energy conservation (white furnace), the
 * importance sampler's mean weight = directional albedo, finiteness at roughness 0
 * and grazing angles, and the angular level rule. */
#include "test.h"
#include "common/brdf.h"
#include "common/basis.h"
#include "common/brdf_table.h"
#include <stdlib.h>

static uint64_t rng_state = 0x9e3779b97f4a7c15ULL;
static double rnd(void) {
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

static wrt_material make_mat(double r, double g, double b, double metallic, double roughness) {
    wrt_material m;
    memset(&m, 0, sizeof m);
    m.base_color[0] = (float)r; m.base_color[1] = (float)g; m.base_color[2] = (float)b;
    m.metallic = (float)metallic; m.roughness = (float)roughness;
    m.lambertian = metallic == 0 && roughness == 1;
    return m;
}

/* Uniform direction on the hemisphere around +z from (u1, u2): pdf 1 / (2 pi). */
static wrt_v3 uniform_hemi(double u1, double u2) {
    double z = u1, s = sqrt(fmax(0, 1 - z * z)), phi = 2 * WRT_PI * u2;
    return v3(s * cos(phi), s * sin(phi), z);
}

static wrt_v3 dir_at(double theta) { return v3(sin(theta), 0, cos(theta)); }

/* Directional albedo for viewer wo (normal +z) by stratified uniform-hemisphere
 * integration: k x k strata, one jittered sample each. Returns per channel; *se gets
 * a conservative standard-error estimate of the mean channel. */
static void albedo_brute(const wrt_material *m, wrt_v3 wo, int k, double out[3], double *se) {
    double s[3] = {0, 0, 0}, s2 = 0;
    wrt_v3 n = v3(0, 0, 1);
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++) {
            wrt_v3 wi = uniform_hemi((i + rnd()) / k, (j + rnd()) / k);
            double f[3];
            wrt_brdf_eval(m, n, wi, wo, f);
            double c = wi.z * 2 * WRT_PI;
            for (int ch = 0; ch < 3; ch++) s[ch] += f[ch] * c;
            double mm = (f[0] + f[1] + f[2]) / 3 * c;
            s2 += mm * mm;
        }
    double N = (double)k * k;
    for (int ch = 0; ch < 3; ch++) out[ch] = s[ch] / N;
    double mean = (out[0] + out[1] + out[2]) / 3;
    *se = sqrt(fmax(0, s2 / N - mean * mean) / N); /* stratification only lowers it */
}

static void test_lambertian_value(void) {
    wrt_material m = make_mat(0.2, 0.5, 0.9, 0, 1);
    CHECK(m.lambertian, "material should be Lambertian");
    wrt_v3 n = v3_norm(v3(0.3, -0.2, 0.9));
    for (int i = 0; i < 100; i++) {
        wrt_v3 a = v3_norm(v3(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5));
        wrt_v3 b = v3_norm(v3(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5));
        double f[3];
        wrt_brdf_eval(&m, n, a, b, f);
        int above = v3_dot(n, a) > 0 && v3_dot(n, b) > 0;
        for (int c = 0; c < 3; c++) {
            double want = above ? m.base_color[c] / WRT_PI : 0;
            CHECK(f[c] == want, "f[%d] = %.17g, want %.17g", c, f[c], want);
        }
    }
}

static void test_reciprocity(void) {
    wrt_material mats[4] = {make_mat(0.9, 0.6, 0.3, 0, 0.5), make_mat(0.9, 0.6, 0.3, 1, 0.2),
                            make_mat(0.5, 0.5, 0.5, 0.5, 0.05), make_mat(0.8, 0.8, 0.8, 0, 0)};
    wrt_v3 n = v3_norm(v3(-0.1, 0.4, 0.8));
    double worst = 0;
    for (int k = 0; k < 4; k++)
        for (int i = 0; i < 2000; i++) {
            wrt_v3 a = v3_norm(v3(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5));
            wrt_v3 b = v3_norm(v3(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5));
            double f1[3], f2[3];
            wrt_brdf_eval(&mats[k], n, a, b, f1);
            wrt_brdf_eval(&mats[k], n, b, a, f2);
            for (int c = 0; c < 3; c++) {
                double d = fabs(f1[c] - f2[c]) / fmax(1e-300, fmax(fabs(f1[c]), fabs(f2[c])));
                if (f1[c] != f2[c] && d > worst) worst = d;
            }
        }
    CHECK(worst < 1e-12, "reciprocity: worst relative difference %.3g", worst);
}

static void test_white_furnace(void) {
    double rough[5] = {0.3, 0.5, 0.7, 0.85, 1.0};
    double thetas[4] = {0.0, 0.6, 1.1, 1.45};
    for (int i = 0; i < 5; i++) {
        wrt_material m = make_mat(1, 1, 1, 1, rough[i]);
        for (int j = 0; j < 4; j++) {
            double a[3], se;
            albedo_brute(&m, dir_at(thetas[j]), 400, a, &se);
            CHECK(a[0] <= 1 + 3 * se, "roughness %.2f theta %.2f: albedo %.5f > 1 (se %.2g)",
                  rough[i], thetas[j], a[0], se);
            CHECK(a[0] > 0.25, "roughness %.2f theta %.2f: albedo %.5f implausibly low",
                  rough[i], thetas[j], a[0]);
        }
    }
    /* Closed form: white metal, alpha = 1, normal incidence: D = 1/pi, V = 1/(2(1 + mu)),
     * albedo = int_0^1 mu / (1 + mu) dmu = 1 - ln 2 (single scattering loses ~70%). */
    wrt_material rough1 = make_mat(1, 1, 1, 1, 1);
    double a1[3], se1;
    albedo_brute(&rough1, dir_at(0), 600, a1, &se1);
    CHECK_NEAR(a1[0], 1 - log(2.0), 4 * se1, "alpha = 1 normal-incidence albedo");
    wrt_material lam = make_mat(0.7, 0.7, 0.7, 0, 1);
    for (int j = 0; j < 4; j++) {
        double a[3], se;
        albedo_brute(&lam, dir_at(thetas[j]), 400, a, &se);
        CHECK_NEAR(a[0], 0.7, 4 * se + 1e-9, "Lambertian albedo at theta %.2f", thetas[j]);
        double w[3];
        wrt_brdf_sample(&lam, v3(0, 0, 1), dir_at(thetas[j]), rnd(), rnd(), rnd(), w);
        CHECK(w[0] == (double)lam.base_color[0], "Lambertian sample weight %.17g", w[0]);
    }
}

static void test_sampler_matches_albedo(void) {
    wrt_material mats[5] = {make_mat(1, 1, 1, 1, 0.3), make_mat(0.9, 0.6, 0.3, 0, 0.5),
                            make_mat(0.5, 0.8, 0.5, 0.5, 0.4), make_mat(0.8, 0.8, 0.8, 0, 0.8),
                            make_mat(0.95, 0.9, 0.8, 1, 0.7)};
    double thetas[3] = {0.2, 0.9, 1.35};
    wrt_v3 n = v3(0, 0, 1);
    for (int k = 0; k < 5; k++)
        for (int j = 0; j < 3; j++) {
            wrt_v3 wo = dir_at(thetas[j]);
            double ab[3], seb;
            albedo_brute(&mats[k], wo, 500, ab, &seb);
            int N = 200000;
            double s[3] = {0, 0, 0}, s2 = 0;
            for (int i = 0; i < N; i++) {
                double w[3];
                wrt_v3 wi = wrt_brdf_sample(&mats[k], n, wo, rnd(), rnd(), rnd(), w);
                (void)wi;
                for (int c = 0; c < 3; c++) s[c] += w[c];
                double mm = (w[0] + w[1] + w[2]) / 3;
                s2 += mm * mm;
            }
            double mean = (s[0] + s[1] + s[2]) / 3 / N;
            double ses = sqrt(fmax(0, s2 / N - mean * mean) / N);
            double brute = (ab[0] + ab[1] + ab[2]) / 3;
            double tol = 4 * sqrt(ses * ses + seb * seb) + 1e-4;
            CHECK_NEAR(mean, brute, tol, "material %d theta %.2f: sampler mean vs brute force "
                       "(se %.2g, %.2g)", k, thetas[j], ses, seb);
            for (int c = 0; c < 3; c++)
                CHECK_NEAR(s[c] / N, ab[c], 4 * sqrt(ses * ses + seb * seb) * 3 + 2e-3,
                           "material %d theta %.2f channel %d", k, thetas[j], c);
        }
}

static void test_no_nan(void) {
    wrt_material mats[3] = {make_mat(1, 1, 1, 1, 0), make_mat(0.5, 0.5, 0.5, 0, 0),
                            make_mat(0.5, 0.5, 0.5, 0.3, 0.01)};
    wrt_v3 n = v3(0, 0, 1);
    int bad = 0;
    double grazing[4] = {1e-12, 1e-6, 1e-3, 0.5};
    for (int k = 0; k < 3; k++)
        for (int g = 0; g < 4; g++) {
            wrt_v3 wo = v3_norm(v3(1, 0, grazing[g]));
            wrt_v3 mirror = v3(-wo.x, -wo.y, wo.z);
            double f[3];
            wrt_brdf_eval(&mats[k], n, mirror, wo, f);
            for (int c = 0; c < 3; c++) bad += !isfinite(f[c]) || f[c] < 0;
            wrt_brdf_eval(&mats[k], n, wo, wo, f);
            for (int c = 0; c < 3; c++) bad += !isfinite(f[c]) || f[c] < 0;
            for (int i = 0; i < 2000; i++) {
                double w[3];
                wrt_v3 wi = wrt_brdf_sample(&mats[k], n, wo, rnd(), rnd(), rnd(), w);
                bad += !v3_finite(wi);
                for (int c = 0; c < 3; c++) bad += !isfinite(w[c]) || w[c] < 0;
            }
        }
    CHECK(bad == 0, "%d non-finite or negative values", bad);
    /* A mirror reflects (nearly) everything into the mirror direction: the sampled
     * weight equals Fresnel there, so the mean weight of a white metal is ~1. */
    double sum = 0;
    for (int i = 0; i < 10000; i++) {
        double w[3];
        wrt_brdf_sample(&mats[0], n, dir_at(0.5), rnd(), rnd(), rnd(), w);
        sum += w[0];
    }
    CHECK_NEAR(sum / 10000, 1.0, 0.01, "white mirror albedo");
}

/* ---- truths written here from the specification, not from common/brdf.c ---- */

/* Gauss-Legendre nodes and weights on [-1, 1] (Newton on the Legendre recurrence). */
static void gauss_legendre(int n, double *x, double *w) {
    for (int i = 0; i < n; i++) {
        double z = cos(WRT_PI * (i + 0.75) / (n + 0.5)), dp = 1;
        for (int it = 0; it < 100; it++) {
            double p0 = 1, p1 = z;
            for (int k = 2; k <= n; k++) { double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k; p0 = p1; p1 = p2; }
            dp = n * (z * p1 - p0) / (z * z - 1);
            double dz = p1 / dp;
            z -= dz;
            if (fabs(dz) < 1e-16) break;
        }
        x[i] = z;
        w[i] = 2 / ((1 - z * z) * dp * dp);
    }
}

/* Smith's Lambda for GGX (Heitz 2014, "Understanding the masking-shadowing function",
 * eq. 72): (-1 + sqrt(1 + alpha^2 tan^2 theta)) / 2; the height-correlated G2 is
 * 1 / (1 + Lambda(wo) + Lambda(wi)). */
static double ggx_lambda(double mu, double alpha) {
    if (mu >= 1) return 0;
    return 0.5 * (-1 + sqrt(1 + alpha * alpha * (1 - mu * mu) / (mu * mu)));
}

static double ggx_D(double ch, double alpha) {
    double a2 = alpha * alpha, t = ch * ch * (a2 - 1) + 1;
    return a2 / (WRT_PI * t * t);
}

/* Directional albedo of a white metal (F = 1) of roughness r (alpha = r^2) seen from
 * polar angle theta, by Gauss-Legendre quadrature (panels x 8 points per axis) over the
 * half-vector h distributed as D(h) cos(theta_h): s = 1 - (1 - u)^4 in [0, 1) with
 * cos^2 theta_h = (1 - s) / (1 + (alpha^2 - 1) s) and phi in [0, 2 pi), dP = ds dphi / 2 pi.
 * With wi the mirror of wo about h, f cos_i dw_i = f cos_i 4 (wo.h) dw_h, so
 *   E = int G2 (wo.h) / (cos_o cos_h) dP           (m == NULL: the specification's f)
 *   E = int f(wi, wo) cos_i 4 (wo.h) / (D cos_h) dP (m: f from wrt_brdf_eval)
 * The first uses nothing of the code; the second the code's f on the same nodes. */
static double ggx_albedo_quadrature(double theta, double r, int panels, const wrt_material *m) {
    double alpha = r * r, gx[8], gw[8], sum = 0;
    gauss_legendre(8, gx, gw);
    wrt_v3 n = v3(0, 0, 1), wo = dir_at(theta);
    double co = wo.z;
    for (int i = 0; i < panels; i++)
        for (int a = 0; a < 8; a++) {
            /* s = 1 - (1 - u)^4: nodes gather near s = 1 (theta_h toward the horizon), where
             * wi crosses the horizon for narrow lobes */
            double u = (i + 0.5 + 0.5 * gx[a]) / panels, s = 1 - pow(1 - u, 4);
            double ws = 0.5 * gw[a] / panels * 4 * pow(1 - u, 3);
            double c2 = (1 - s) / (1 + (alpha * alpha - 1) * s), ch = sqrt(c2), sh = sqrt(fmax(0, 1 - c2));
            for (int j = 0; j < panels; j++)
                for (int b = 0; b < 8; b++) {
                    double phi = 2 * WRT_PI * (j + 0.5 + 0.5 * gx[b]) / panels, wp = 0.5 * gw[b] / panels;
                    wrt_v3 h = v3(sh * cos(phi), sh * sin(phi), ch);
                    double oh = v3_dot(wo, h);
                    if (oh <= 0) continue;
                    wrt_v3 wi = v3_sub(v3_scale(h, 2 * oh), wo);
                    if (wi.z <= 0) continue;
                    double val;
                    if (!m) {
                        val = oh / (co * ch) / (1 + ggx_lambda(co, alpha) + ggx_lambda(wi.z, alpha));
                    } else {
                        double f[3];
                        wrt_brdf_eval(m, n, wi, wo, f);
                        val = f[0] * wi.z * 4 * oh / (ggx_D(ch, alpha) * ch);
                    }
                    sum += ws * wp * val;
                }
        }
    return sum;
}

/* White-furnace directional albedo of the GGX metal (F = 1): the specification's
 * single-scattering albedo by an independent high-order quadrature (checked against the
 * closed form 1 - ln 2 at alpha = 1, normal incidence, and against itself at twice the
 * points), against the code's f on the same nodes and the code's importance sampler. */
static void test_ggx_albedo_quadrature(void) {
    double t_closed = ggx_albedo_quadrature(0, 1, 96, NULL);
    CHECK_NEAR(t_closed, 1 - log(2.0), 1e-5, "the quadrature at alpha 1, normal incidence vs 1 - ln 2");
    double rough[5] = {0.2, 0.3, 0.5, 0.7, 1.0}, thetas[4] = {0.0, 0.6, 1.1, 1.45};
    double worst_code = 0, worst_sampler = 0, worst_conv = 0;
    for (int i = 0; i < 5; i++) {
        wrt_material m = make_mat(1, 1, 1, 1, rough[i]);
        for (int j = 0; j < 4; j++) {
            double t1 = ggx_albedo_quadrature(thetas[j], rough[i], 24, NULL);
            double t2 = ggx_albedo_quadrature(thetas[j], rough[i], 48, NULL);
            double conv = fabs(t1 - t2);
            worst_conv = fmax(worst_conv, conv);
            CHECK(conv < 5e-5, "roughness %.2f theta %.2f: the quadrature converges (%.8f vs %.8f)", rough[i], thetas[j], t1, t2);
            double code = ggx_albedo_quadrature(thetas[j], rough[i], 48, &m);
            worst_code = fmax(worst_code, fabs(code - t2));
            CHECK_NEAR(code, t2, 1e-6 + conv, "roughness %.2f theta %.2f: albedo with the code's f vs the specification's",
                       rough[i], thetas[j]);
            int N = 1 << 16;
            double sw = 0, sw2 = 0;
            for (int k = 0; k < N; k++) {
                double w[3];
                wrt_brdf_sample(&m, v3(0, 0, 1), dir_at(thetas[j]), (k + 0.5) / N, fmod(0.5 + k * 0.7548776662466927, 1.0),
                                fmod(0.5 + k * 0.5698402909980532, 1.0), w);
                sw += w[0]; sw2 += w[0] * w[0];
            }
            double mean = sw / N, se = sqrt(fmax(0, sw2 / N - mean * mean) / N);
            worst_sampler = fmax(worst_sampler, fabs(mean - t2));
            CHECK_NEAR(mean, t2, 4 * se + conv, "roughness %.2f theta %.2f: the sampler's mean weight (se %.2g)", rough[i],
                       thetas[j], se);
            printf("GGX white furnace roughness %.2f theta %.2f: albedo %.6f (quadrature), code's f %.6f, sampler %.5f\n",
                   rough[i], thetas[j], t2, code, mean);
        }
    }
    printf("GGX white furnace: worst |code - quadrature| %.2e, |sampler - quadrature| %.2e, quadrature convergence %.2e\n",
           worst_code, worst_sampler, worst_conv);
}

/* Schlick's Fresnel, F = F0 + (1 - F0)(1 - v.h)^5, read off as the ratio of a coloured
 * metal's f to a white metal's (F = 1) at the same directions: F0 = base colour at normal
 * incidence, F -> 1 at grazing; and the dielectric's F0 = 0.04 (glTF specification,
 * Appendix B), from a black dielectric (no diffuse term) against the white metal. */
static void test_fresnel(void) {
    double base[3] = {0.2, 0.5, 0.9};
    wrt_material col = make_mat(base[0], base[1], base[2], 1, 0.5), white = make_mat(1, 1, 1, 1, 0.5);
    wrt_material diel = make_mat(0, 0, 0, 0, 0.5);
    wrt_v3 n = v3(0, 0, 1);
    double angles[4] = {0, 1.0, 1.5, 1.5707};
    for (int k = 0; k < 4; k++) {
        wrt_v3 wo = dir_at(angles[k]), wi = v3(-wo.x, -wo.y, wo.z); /* mirror: h = n, v.h = cos theta */
        double vh = wo.z, s5 = pow(1 - vh, 5), fc[3], fw[3], fd[3];
        wrt_brdf_eval(&col, n, wi, wo, fc);
        wrt_brdf_eval(&white, n, wi, wo, fw);
        wrt_brdf_eval(&diel, n, wi, wo, fd);
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(fc[c] / fw[c], col.base_color[c] + (1 - col.base_color[c]) * s5, 1e-6, "metal F at theta %.4f, channel %d", angles[k], c);
        CHECK_NEAR(fd[0] / fw[0], 0.04 + 0.96 * s5, 1e-6, "dielectric F at theta %.4f", angles[k]);
        if (k == 0) {
            CHECK_NEAR(fd[0] / fw[0], 0.04, 1e-12, "dielectric F0 = 0.04 at normal incidence");
            /* and the white metal's value itself: D(n) = 1 / (pi alpha^2), V = 1/4 at normal incidence */
            CHECK_NEAR(fw[0], 1 / (4 * WRT_PI * 0.0625), 1e-12 * fw[0], "white metal at normal incidence = 1 / (4 pi alpha^2)");
        }
        if (k == 3) CHECK(fc[0] / fw[0] > 0.999 && fd[0] / fw[0] > 0.999, "F -> 1 at grazing (%.6f, %.6f)", fc[0] / fw[0],
                          fd[0] / fw[0]);
    }
}

static void test_angular_level(void) {
    wrt_material lam = make_mat(0.5, 0.5, 0.5, 0, 1);
    CHECK(wrt_brdf_angular_level(&lam) == 0, "Lambertian level");
    struct { double rough; int level; } cases[] = {
        {1.0, 1}, {0.7, 1}, {0.5, 1}, {0.4, 2}, {0.3, 3}, {0.1, 3}, {0.0, 3}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        wrt_material m = make_mat(0.5, 0.5, 0.5, 1, cases[i].rough);
        int l = wrt_brdf_angular_level(&m);
        CHECK(l == cases[i].level, "roughness %.2f: level %d, want %d", cases[i].rough, l,
              cases[i].level);
        CHECK(l >= 0 && l <= WRT_MAX_ALEVEL, "level in range");
    }
}

/* The shared angular table (common/brdf_table.h) against direct integration: at the
 * table's directions, every angular function of levels 0..2 (what the bake uses) within
 * 0.2% (relative RMS) of a 64-times finer Gauss rule, and the root (the directional
 * albedo) within 0.5% of a spherical-coordinate midpoint sum that knows nothing of the
 * concentric map. */
static void test_brdf_table(void) {
    wrt_material mats[2] = {make_mat(0.8, 0.6, 0.4, 0, 0.3), make_mat(0.9, 0.9, 0.9, 1, 0.05)};
    float *tab = malloc(WRT_BRDF_TABLE_FLOATS * sizeof *tab);
    static double ref[WRT_BRDF_TABLE_NANG * 3];
    for (int mi = 0; mi < 2; mi++) {
        wrt_brdf_table_build(&mats[mi], 0, tab);
        double e2 = 0, r2 = 0;
        int cells[4][2] = {{16, 16}, {5, 20}, {27, 9}, {2, 30}};
        for (int d = 0; d < 4; d++) {
            int i = cells[d][0], j = cells[d][1];
            double wo[3];
            wrt_concentric_dir((i + 0.5) / WRT_BRDF_TABLE_RES, (j + 0.5) / WRT_BRDF_TABLE_RES, wo);
            wrt_brdf_beta_direct(&mats[mi], wo, 8, 8, ref);
            const float *t = tab + (size_t)(j * WRT_BRDF_TABLE_RES + i) * WRT_BRDF_TABLE_NANG * 3;
            for (int k = 0; k < 64 * 3; k++) { e2 += (t[k] - ref[k]) * (t[k] - ref[k]); r2 += ref[k] * ref[k]; }
            if (mi == 0) {
                enum { NT = 2000, NP = 400 };
                double alb = 0;
                wrt_v3 vo = v3(wo[0], wo[1], wo[2]);
                for (int a = 0; a < NT; a++)
                    for (int b = 0; b < NP; b++) {
                        double th = (a + 0.5) / NT * WRT_PI / 2, ph = (b + 0.5) / NP * 2 * WRT_PI, f[3];
                        wrt_v3 wi = v3(sin(th) * cos(ph), sin(th) * sin(ph), cos(th));
                        wrt_brdf_eval(&mats[0], v3(0, 0, 1), wi, vo, f);
                        alb += f[1] * cos(th) * sin(th) * (WRT_PI / 2 / NT) * (2 * WRT_PI / NP);
                    }
                CHECK_NEAR(t[1], alb, 0.005 * alb, "albedo at table direction (%d, %d)", i, j);
            }
        }
        printf("brdf table, %s: relative RMS %.2e against a 64x finer Gauss rule (64 functions, 4 directions)\n",
               mi ? "roughness-0.05 metal" : "roughness-0.3 dielectric", sqrt(e2 / r2));
        CHECK(sqrt(e2 / r2) < 2e-3, "table vs direct integration: %.3e", sqrt(e2 / r2));
    }
    free(tab);
}

int main(int argc, char **argv) {
    TEST_RUN(test_lambertian_value);
    TEST_RUN(test_reciprocity);
    TEST_RUN(test_white_furnace);
    TEST_RUN(test_sampler_matches_albedo);
    TEST_RUN(test_no_nan);
    TEST_RUN(test_angular_level);
    TEST_RUN(test_brdf_table);
    TEST_RUN(test_ggx_albedo_quadrature);
    TEST_RUN(test_fresnel);
    TEST_END();
}
