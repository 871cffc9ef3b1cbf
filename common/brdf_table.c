/* brdf_table.c: the angular BRDF table (see brdf_table.h). */
#include "brdf_table.h"

#include <string.h>

#include "basis.h"
#include "brdf.h"
#include "threads.h"


int wrt_brdf_angular_index(int level, int x, int y, int type) {
    if (level < 0 || level >= WRT_BRDF_TABLE_LEVELS || x < 0 || y < 0 || x >= (1 << level) || y >= (1 << level) ||
        type < 0 || type > 3)
        return -1;
    if (type == 0) return level == 0 ? 0 : -1;
    int before = ((1 << (2 * level)) - 1) / 3;
    return 1 + 3 * (before + y * (1 << level) + x) + (type - 1);
}

void wrt_brdf_angular_func(int idx, int *level, int *x, int *y, int *type) {
    if (idx <= 0) { *level = *x = *y = *type = 0; return; }
    int m = (idx - 1) / 3, l = 0;
    *type = (idx - 1) % 3 + 1;
    while (m >= (1 << (2 * l))) { m -= 1 << (2 * l); l++; }
    *level = l; *x = m % (1 << l); *y = m / (1 << l);
}

/* Gauss-Legendre nodes and weights of `order` points on [0, 1] (Newton on P_n). */
static void gauss_legendre(int order, double *x, double *w) {
    for (int i = 0; i < order; i++) {
        double z = cos(WRT_PI * (i + 0.75) / (order + 0.5)), dp = 1;
        for (int it = 0; it < 100; it++) {
            double p0 = 1, p1 = z;
            for (int k = 2; k <= order; k++) { double p2 = ((2 * k - 1) * z * p1 - (k - 1) * p0) / k; p0 = p1; p1 = p2; }
            if (order == 1) p1 = z, p0 = 1;
            dp = order * (z * p1 - p0) / (z * z - 1);
            double dz = p1 / dp;
            z -= dz;
            if (fabs(dz) < 1e-16) break;
        }
        x[i] = 0.5 * (1 - z);
        w[i] = 1.0 / ((1 - z * z) * dp * dp); /* 2 / ((1 - z^2) P'^2), halved for [0, 1] */
    }
}

/* Haar analysis of the leaf-cell values v (nc x nc, nc = 2^L, 3 channels; scaling
 * coefficients of level L) into pyr[index * 3 + c]; v is scratch. */
static void haar_analyse3(double *v, int L, double *pyr) {
    for (int l = L - 1; l >= 0; l--) {
        int n = 1 << l, n2 = 2 * n;
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                for (int c = 0; c < 3; c++) {
                    double a = v[((2 * y) * n2 + 2 * x) * 3 + c], b = v[((2 * y) * n2 + 2 * x + 1) * 3 + c];
                    double d = v[((2 * y + 1) * n2 + 2 * x) * 3 + c], e = v[((2 * y + 1) * n2 + 2 * x + 1) * 3 + c];
                    int k = wrt_brdf_angular_index(l, x, y, 1);
                    pyr[k * 3 + c] = (a - b + d - e) * 0.5;
                    pyr[(k + 1) * 3 + c] = (a + b - d - e) * 0.5;
                    pyr[(k + 2) * 3 + c] = (a - b - d + e) * 0.5;
                    v[(y * n + x) * 3 + c] = (a + b + d + e) * 0.5;
                }
    }
    for (int c = 0; c < 3; c++) pyr[c] = v[c];
}

/* The integral of f over the square [a0, a0 + h] x [b0, b0 + h] of the concentric domain by
 * the order x order Gauss rule, split in four while the square is wider than the lobe's
 * width `lw` and meets the box `box` around the mirror direction (a narrow lobe falls
 * between the points of a fixed rule: a roughness-0.05 metal loses 3/4 of its albedo). */
typedef struct rule {
    const wrt_material *m; wrt_v3 wo;
    int order; double gx[8], gw[8];
    double lw, box[4]; /* amin, amax, bmin, bmax */
} rule;

static void integrate_square(const rule *R, double a0, double b0, double h, int depth, double acc[3]) {
    if (h > R->lw && depth < 10 && a0 < R->box[1] && a0 + h > R->box[0] && b0 < R->box[3] && b0 + h > R->box[2]) {
        for (int k = 0; k < 4; k++) integrate_square(R, a0 + (k & 1) * h / 2, b0 + (k >> 1) * h / 2, h / 2, depth + 1, acc);
        return;
    }
    for (int p = 0; p < R->order * R->order; p++) {
        int ox = p % R->order, oy = p / R->order;
        double wi[3], f[3];
        wrt_concentric_dir(a0 + R->gx[ox] * h, b0 + R->gx[oy] * h, wi);
        wrt_brdf_eval(R->m, v3(0, 0, 1), v3(wi[0], wi[1], wi[2]), R->wo, f);
        double wt = R->gw[ox] * R->gw[oy] * h * h;
        for (int c = 0; c < 3; c++) acc[c] += f[c] * wt;
    }
}

void wrt_brdf_beta_direct(const wrt_material *m, const double wo[3], int sub, int order, double *out) {
    enum { L = WRT_BRDF_TABLE_LEVELS, N = 1 << L };
    double v[N * N * 3];
    rule R = {.m = m, .wo = v3(wo[0], wo[1], wo[2]), .order = order < 1 ? 1 : order > 8 ? 8 : order};
    if (sub < 1) sub = 1;
    gauss_legendre(R.order, R.gx, R.gw);
    /* The specular lobe: around the mirror direction, about alpha wide in the concentric
     * square's coordinates (the half vector's spread alpha, doubled by the reflection,
     * halved by the map's scale at the pole). */
    double alpha = m->lambertian ? 1 : (double)m->roughness * m->roughness;
    double mir[3] = {-wo[0], -wo[1], wo[2]}, am, bm;
    wrt_concentric_inv(mir, &am, &bm);
    R.lw = alpha < 1e-3 ? 1e-3 : alpha;
    double half = 8 * R.lw;
    R.box[0] = am - half; R.box[1] = am + half; R.box[2] = bm - half; R.box[3] = bm + half;
    double h = 1.0 / ((double)N * sub);
    for (int cj = 0; cj < N; cj++)
        for (int ci = 0; ci < N; ci++) {
            double acc[3] = {0, 0, 0};
            for (int p = 0; p < sub * sub; p++)
                integrate_square(&R, (ci * sub + p % sub) * h, (cj * sub + p / sub) * h, h, 0, acc);
            /* scaling coefficient of the leaf: integral x 2^L */
            for (int c = 0; c < 3; c++) v[(cj * N + ci) * 3 + c] = acc[c] * N;
        }
    haar_analyse3(v, L, out);
    for (int k = 0; k < WRT_BRDF_TABLE_NANG * 3; k++) out[k] *= WRT_PI;
}

typedef struct build_job { const wrt_material *m; float *tab; } build_job;

static void build_cell(size_t cell, int thread, void *user) {
    (void)thread;
    build_job *j = user;
    wrt_brdf_table_build_cell(j->m, (int)cell, j->tab);
}

void wrt_brdf_table_build_cell(const wrt_material *m, int cell_index, float *tab) {
    size_t cell = (size_t)cell_index;
    double wo[3], out[WRT_BRDF_TABLE_NANG * 3];
    wrt_concentric_dir((cell % WRT_BRDF_TABLE_RES + 0.5) / WRT_BRDF_TABLE_RES,
                       (cell / WRT_BRDF_TABLE_RES + 0.5) / WRT_BRDF_TABLE_RES, wo);
    wrt_brdf_beta_direct(m, wo, 1, 4, out);
    float *t = tab + cell * WRT_BRDF_TABLE_NANG * 3;
    for (int k = 0; k < WRT_BRDF_TABLE_NANG * 3; k++) t[k] = (float)out[k];
}

void wrt_brdf_table_build(const wrt_material *m, int threads, float *tab) {
    build_job j = {m, tab};
    wrt_parallel_for((size_t)WRT_BRDF_TABLE_RES * WRT_BRDF_TABLE_RES, threads, build_cell, &j);
}

void wrt_brdf_table_lookup(const float *tab, int nang, double a, double b, double *out) {
    enum { R = WRT_BRDF_TABLE_RES };
    double fx = a * R - 0.5, fy = b * R - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    for (int k = 0; k < 3 * nang; k++) out[k] = 0;
    for (int c = 0; c < 4; c++) {
        int cx = x0 + (c & 1), cy = y0 + (c >> 1);
        double w = ((c & 1) ? tx : 1 - tx) * ((c >> 1) ? ty : 1 - ty);
        cx = cx < 0 ? 0 : cx >= R ? R - 1 : cx;
        cy = cy < 0 ? 0 : cy >= R ? R - 1 : cy;
        const float *t = tab + (size_t)(cy * R + cx) * WRT_BRDF_TABLE_NANG * 3;
        for (int k = 0; k < 3 * nang; k++) out[k] += w * t[k];
    }
}
