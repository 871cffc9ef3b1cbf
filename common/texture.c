/* texture.c: sampling a base-colour texture (texture.h, docs/textures.md). */
#include "texture.h"

#include <math.h>

/* Texel index along an axis of n texels for the integer coordinate i, wrapped. */
static int wrap_index(int i, int n, int mode) {
    if (mode == WRT_WRAP_CLAMP) return i < 0 ? 0 : i >= n ? n - 1 : i;
    if (mode == WRT_WRAP_MIRROR) {
        int p = 2 * n, k = ((i % p) + p) % p;
        return k < n ? k : p - 1 - k;
    }
    return ((i % n) + n) % n;
}

void wrt_texture_srgb_table(float lut[256]) {
    for (int i = 0; i < 256; i++) {
        double c = i / 255.0;
        lut[i] = (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
    }
}

void wrt_texture_sample(const wrt_texture *t, double s, double tt, float out[3]) {
    if (!isfinite(s)) s = 0;
    if (!isfinite(tt)) tt = 0;
    /* keep the coordinates small before the float-to-int steps (the texture repeats) */
    if (t->wrap[0] != WRT_WRAP_CLAMP) s -= 2.0 * floor(s / 2.0);
    else s = s < -1 ? -1 : s > 2 ? 2 : s;
    if (t->wrap[1] != WRT_WRAP_CLAMP) tt -= 2.0 * floor(tt / 2.0);
    else tt = tt < -1 ? -1 : tt > 2 ? 2 : tt;
    double x = s * t->w - 0.5, y = tt * t->h - 0.5;
    double fx = floor(x), fy = floor(y);
    double ax = x - fx, ay = y - fy;
    int x0 = (int)fx, y0 = (int)fy;
    int xi[2] = {wrap_index(x0, t->w, t->wrap[0]), wrap_index(x0 + 1, t->w, t->wrap[0])};
    int yi[2] = {wrap_index(y0, t->h, t->wrap[1]), wrap_index(y0 + 1, t->h, t->wrap[1])};
    double w[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
    for (int c = 0; c < 3; c++) {
        double v = 0;
        for (int k = 0; k < 4; k++)
            v += w[k] * t->lut[t->srgb[((size_t)yi[k >> 1] * (size_t)t->w + (size_t)xi[k & 1]) * 3 + (size_t)c]];
        out[c] = (float)v;
    }
}

void wrt_texture_albedo(const wrt_texture *t, double s, double tt, float out[3]) {
    wrt_texture_sample(t, s, tt, out);
    for (int c = 0; c < 3; c++) {
        float a = t->factor[c] * out[c];
        out[c] = a < 0 ? 0 : a > 1 ? 1 : a;
    }
}

void wrt_quad_uv_at(const wrt_quad *q, double u, double v, double st[2]) {
    double w0 = (1 - u) * (1 - v), w1 = u * (1 - v), w2 = u * v, w3 = (1 - u) * v;
    for (int d = 0; d < 2; d++) st[d] = w0 * q->uv[0][d] + w1 * q->uv[1][d] + w2 * q->uv[2][d] + w3 * q->uv[3][d];
}

void wrt_quad_inverse(const wrt_quad *q, wrt_v3 p, double *u, double *v) {
    /* in the plane's frame (t, b): solve P(u, v) = p by Newton from the centre */
    double uu = 0.5, vv = 0.5;
    for (int it = 0; it < 8; it++) {
        wrt_v3 r = v3_sub(wrt_quad_point(q, uu, vv), p);
        wrt_v3 du = v3_add(v3_scale(v3_sub(q->p[1], q->p[0]), 1 - vv), v3_scale(v3_sub(q->p[2], q->p[3]), vv));
        wrt_v3 dv = v3_add(v3_scale(v3_sub(q->p[3], q->p[0]), 1 - uu), v3_scale(v3_sub(q->p[2], q->p[1]), uu));
        double a = v3_dot(du, q->t), b = v3_dot(dv, q->t), c = v3_dot(du, q->b), d = v3_dot(dv, q->b);
        double rx = v3_dot(r, q->t), ry = v3_dot(r, q->b), det = a * d - b * c;
        if (!(fabs(det) > 0)) break;
        double dx = (d * rx - b * ry) / det, dy = (a * ry - c * rx) / det;
        uu -= dx;
        vv -= dy;
        if (q->parallelogram || (fabs(dx) < 1e-12 && fabs(dy) < 1e-12)) break;
    }
    *u = uu < 0 ? 0 : uu > 1 ? 1 : uu;
    *v = vv < 0 ? 0 : vv > 1 ? 1 : vv;
}

void wrt_texture_quad_mean(const wrt_texture *t, const wrt_quad *q, double rho[3]) {
    /* the footprint's extent in texels sets the sampling: >= 2 samples a texel */
    double smin = INFINITY, smax = -INFINITY, tmin = INFINITY, tmax = -INFINITY;
    for (int k = 0; k < 4; k++) {
        smin = fmin(smin, q->uv[k][0]); smax = fmax(smax, q->uv[k][0]);
        tmin = fmin(tmin, q->uv[k][1]); tmax = fmax(tmax, q->uv[k][1]);
    }
    double ext = fmax((smax - smin) * t->w, (tmax - tmin) * t->h);
    int n = (int)ceil(2 * ext);
    n = n < 4 ? 4 : n > 256 ? 256 : n;
    double sum[3] = {0, 0, 0}, wsum = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double u = (i + 0.5) / n, v = (j + 0.5) / n, st[2];
            double jac = wrt_quad_jacobian(q, u, v);
            wrt_quad_uv_at(q, u, v, st);
            float a[3];
            wrt_texture_albedo(t, st[0], st[1], a);
            for (int c = 0; c < 3; c++) sum[c] += jac * a[c];
            wsum += jac;
        }
    for (int c = 0; c < 3; c++) rho[c] = wsum > 0 ? sum[c] / wsum : 0;
}
