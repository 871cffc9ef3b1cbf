/* brdf.c: the glTF 2.0 metallic-roughness BRDF (glTF specification, Appendix B)
 * evaluated, importance-sampled and sized for the angular Haar basis. Shared by the
 * bake (transport of non-diffuse quads), the player and the reference path tracer.
 * Depends on wrt_common.h, scene.h (wrt_material) and basis.h (WRT_MAX_ALEVEL).
 * Implements the reflectance model the paper assumes per surface (Kontkanen et al.
 * 2006, section 4: the BRDF enters the transport operator through its angular Haar
 * projection; section 4.2 fixes the angular resolution a lobe needs).
 *
 * Model: c_diff = lerp(base, 0, metallic), f0 = lerp(0.04, base, metallic),
 * alpha = max(roughness^2, WRT_BRDF_MIN_ALPHA), F = f0 + (1 - f0)(1 - v.h)^5,
 * D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2), V = the height-correlated Smith
 * visibility G2 / (4 |n.l| |n.v|), f = (1 - F) c_diff / pi + F D V.
 * A Lambertian material returns base / pi exactly (brdf.h says why). */
#include "brdf.h"
#include "basis.h"

/* Smallest GGX width: roughness 0 (a mirror) would make D a delta; with this floor the
 * peak D = 1 / (pi alpha^2) ~ 3e5 stays finite and the sampler still finds it. */
#define WRT_BRDF_MIN_ALPHA 1e-3

static double material_alpha(const wrt_material *m) {
    double r = m->roughness < 0 ? 0 : m->roughness > 1 ? 1 : m->roughness;
    double a = r * r;
    return a < WRT_BRDF_MIN_ALPHA ? WRT_BRDF_MIN_ALPHA : a;
}

static double clamp01(double x) { return x < 0 ? 0 : x > 1 ? 1 : x; }

/* c_diff and f0 per channel. */
static void material_colors(const wrt_material *m, double cdiff[3], double f0[3]) {
    double metal = clamp01(m->metallic);
    for (int c = 0; c < 3; c++) {
        double base = m->base_color[c];
        cdiff[c] = base * (1 - metal);
        f0[c] = 0.04 * (1 - metal) + base * metal;
    }
}

static double ggx_d(double nh, double a2) {
    double t = nh * nh * (a2 - 1) + 1;
    return a2 / (WRT_PI * t * t);
}

/* Height-correlated Smith visibility V = G2 / (4 n.l n.v) for GGX, n.l, n.v > 0. */
static double smith_v(double nl, double nv, double a2) {
    double gv = nl * sqrt(nv * nv * (1 - a2) + a2);
    double gl = nv * sqrt(nl * nl * (1 - a2) + a2);
    double s = gv + gl;
    return s > 0 ? 0.5 / s : 0;
}

/* Smith masking G1 for GGX (the separable factor used by visible-normal sampling). */
static double smith_g1(double nv, double a2) {
    return 2 * nv / (nv + sqrt(a2 + (1 - a2) * nv * nv));
}

void wrt_brdf_eval(const wrt_material *m, wrt_v3 n, wrt_v3 wi, wrt_v3 wo, double out[3]) {
    double nl = v3_dot(n, wi), nv = v3_dot(n, wo);
    out[0] = out[1] = out[2] = 0;
    if (!(nl > 0) || !(nv > 0)) return;
    if (m->lambertian) {
        for (int c = 0; c < 3; c++) out[c] = m->base_color[c] / WRT_PI;
        return;
    }
    double cdiff[3], f0[3];
    material_colors(m, cdiff, f0);
    double a = material_alpha(m), a2 = a * a;
    wrt_v3 h = v3_norm(v3_add(wi, wo));
    double vh = clamp01(v3_dot(wo, h)), nh = clamp01(v3_dot(n, h));
    double s5 = pow(1 - vh, 5);
    double dv = ggx_d(nh, a2) * smith_v(nl, nv, a2);
    for (int c = 0; c < 3; c++) {
        double F = f0[c] + (1 - f0[c]) * s5;
        out[c] = (1 - F) * cdiff[c] / WRT_PI + F * dv;
    }
}

/* The angular level: a GGX lobe of width alpha has its half-vectors within about
 * alpha radians of the mirror half-vector, so the reflected directions spread over
 * about 2 alpha either side, a full width of ~4 alpha. Near the pole the concentric
 * map is close to an isometry of the unit disk, whose diameter 2 splits into 2^l
 * cells at level l: a cell is ~2^(1-l) wide. The coarsest level with a cell narrower
 * than the lobe, 2^(1-l) < 4 alpha, is l = ceil(log2(1/alpha)) - 1; finer levels
 * would only resolve detail the lobe does not have. A non-Lambertian material gets at
 * least level 1 (its Fresnel and specular terms are not constant in angle) and at most
 * WRT_MAX_ALEVEL (sharper lobes are blurred to 8 x 8 cells: the paper's limit too). */
int wrt_brdf_angular_level(const wrt_material *m) {
    if (m->lambertian) return 0;
    double a = material_alpha(m);
    int l = (int)ceil(log2(1.0 / a) - 1e-9) - 1;
    if (l < 1) l = 1;
    if (l > WRT_MAX_ALEVEL) l = WRT_MAX_ALEVEL;
    return l;
}

/* Orthonormal frame (t, b, n) around unit n (Frisvad-style branch on the sign). */
static void make_frame(wrt_v3 n, wrt_v3 *t, wrt_v3 *b) {
    double s = n.z >= 0 ? 1.0 : -1.0;
    double a = -1.0 / (s + n.z), bb = n.x * n.y * a;
    *t = v3(1 + s * n.x * n.x * a, s * bb, -s * n.x);
    *b = v3(bb, s + n.y * n.y * a, -n.y);
}

static wrt_v3 to_world(wrt_v3 t, wrt_v3 b, wrt_v3 n, double x, double y, double z) {
    return v3(t.x * x + b.x * y + n.x * z, t.y * x + b.y * y + n.y * z, t.z * x + b.z * y + n.z * z);
}

static double mean3(const double v[3]) { return (v[0] + v[1] + v[2]) / 3; }

/* Probability of choosing the specular lobe: its share of the reflected energy,
 * estimated from Fresnel at normal incidence to the viewer. */
static double spec_probability(const double cdiff[3], const double f0[3], double nv) {
    double s5 = pow(1 - clamp01(nv), 5);
    double fs[3];
    for (int c = 0; c < 3; c++) fs[c] = f0[c] + (1 - f0[c]) * s5;
    double es = mean3(fs);
    double ed = (1 - es) * mean3(cdiff);
    if (es + ed <= 0) return 1;
    double p = es / (es + ed);
    return p < 0.05 ? 0.05 : p > 1 ? 1 : p;
}

/* GGX visible-normal sampling (Heitz 2018) in the local frame: v has z > 0; returns
 * a half-vector with z >= 0 distributed as D_v(h) = G1(v) max(0, v.h) D(h) / v.z. */
static wrt_v3 sample_vndf(wrt_v3 v, double a, double u1, double u2) {
    wrt_v3 vh = v3_norm(v3(a * v.x, a * v.y, v.z));
    double l2 = vh.x * vh.x + vh.y * vh.y;
    wrt_v3 t1 = l2 > 0 ? v3_scale(v3(-vh.y, vh.x, 0), 1 / sqrt(l2)) : v3(1, 0, 0);
    wrt_v3 t2 = v3_cross(vh, t1);
    double r = sqrt(u1), phi = 2 * WRT_PI * u2;
    double p1 = r * cos(phi), p2 = r * sin(phi);
    double s = 0.5 * (1 + vh.z);
    p2 = (1 - s) * sqrt(fmax(0, 1 - p1 * p1)) + s * p2;
    double p3 = sqrt(fmax(0, 1 - p1 * p1 - p2 * p2));
    wrt_v3 nh = v3_add(v3_add(v3_scale(t1, p1), v3_scale(t2, p2)), v3_scale(vh, p3));
    return v3_norm(v3(a * nh.x, a * nh.y, fmax(1e-12, nh.z)));
}

wrt_v3 wrt_brdf_sample(const wrt_material *m, wrt_v3 n, wrt_v3 wo, double u1, double u2,
                       double u3, double w[3]) {
    w[0] = w[1] = w[2] = 0;
    wrt_v3 t, b;
    make_frame(n, &t, &b);
    wrt_v3 vl = v3(v3_dot(wo, t), v3_dot(wo, b), v3_dot(wo, n));
    if (!(vl.z > 0)) return n;
    if (m->lambertian) {
        double r = sqrt(u1), phi = 2 * WRT_PI * u2;
        double x = r * cos(phi), y = r * sin(phi), z = sqrt(fmax(0, 1 - u1));
        for (int c = 0; c < 3; c++) w[c] = m->base_color[c]; /* f cos / pdf = base exactly */
        return to_world(t, b, n, x, y, z);
    }
    double cdiff[3], f0[3];
    material_colors(m, cdiff, f0);
    double a = material_alpha(m), a2 = a * a;
    double ps = spec_probability(cdiff, f0, vl.z);
    wrt_v3 ll;
    if (u3 < ps) {
        wrt_v3 h = sample_vndf(vl, a, u1, u2);
        double vh = v3_dot(vl, h);
        ll = v3_sub(v3_scale(h, 2 * vh), vl);
    } else {
        double r = sqrt(u1), phi = 2 * WRT_PI * u2;
        ll = v3(r * cos(phi), r * sin(phi), sqrt(fmax(0, 1 - u1)));
    }
    if (!(ll.z > 0)) return n;
    /* Mixture pdf of ll, so that either branch gives an unbiased weight. */
    wrt_v3 h = v3_norm(v3_add(ll, vl));
    double nh = clamp01(h.z);
    double pdf_spec = smith_g1(vl.z, a2) * ggx_d(nh, a2) / (4 * vl.z);
    double pdf = ps * pdf_spec + (1 - ps) * ll.z / WRT_PI;
    if (!(pdf > 0) || !isfinite(pdf)) return n;
    wrt_v3 wi = to_world(t, b, n, ll.x, ll.y, ll.z);
    double f[3];
    wrt_brdf_eval(m, n, wi, wo, f);
    double cosl = v3_dot(n, wi);
    if (!(cosl > 0)) return n;
    for (int c = 0; c < 3; c++) w[c] = f[c] * cosl / pdf;
    return wi;
}
