/* smooth.c: the smooth surface of an element's vertex normals (smooth.h). */
#include "smooth.h"

#include <string.h>

/* Barycentric weights of x projected onto the plane of triangle (a, b, c). */
static void barycentric(wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 x, double out[3]) {
    wrt_v3 e1 = v3_sub(b, a), e2 = v3_sub(c, a), d = v3_sub(x, a);
    double d00 = v3_dot(e1, e1), d01 = v3_dot(e1, e2), d11 = v3_dot(e2, e2);
    double d20 = v3_dot(d, e1), d21 = v3_dot(d, e2), den = d00 * d11 - d01 * d01;
    if (!(den > 0)) { out[0] = 1; out[1] = out[2] = 0; return; }
    out[1] = (d11 * d20 - d01 * d21) / den;
    out[2] = (d00 * d21 - d01 * d20) / den;
    out[0] = 1 - out[1] - out[2];
}

static wrt_v3 fv3(const float *f) { return v3(f[0], f[1], f[2]); }

void wrt_smooth_make(const wrt_v3 p[4], wrt_v3 fn, const float (*vn)[3], int tri_part, wrt_smooth_src *s) {
    memset(s, 0, sizeof *s);
    if (!vn) return;
    for (int k = 0; k < 4; k++)
        if (v3_dot(fv3(vn[k]), fn) < WRT_SMOOTH_COS) s->curved = 1;
    if (!s->curved) return;
    if (tri_part < 0) {
        wrt_v3 g = v3_scale(v3_sub(v3_scale(v3_add(p[1], p[3]), 2), p[0]), 1.0 / 3);
        double size = v3_len(v3_sub(p[1], p[0])) + v3_len(v3_sub(p[3], p[0]));
        tri_part = v3_len(v3_sub(g, p[2])) <= 1e-6 * size;
    }
    memset(s->w, 0, sizeof s->w);
    if (tri_part) {
        /* V_k, and the triangle's other two vertices beyond the midpoints p1 and p3; the
         * midpoint's normal is the normalized mean of its two vertices' unit normals, so
         * the far vertex's is V_k's mirrored about it */
        s->nsrc = 3;
        wrt_v3 n0 = v3_norm(fv3(vn[0]));
        s->p[0] = p[0];
        s->n[0] = n0;
        for (int j = 1; j <= 2; j++) {
            int c = j == 1 ? 1 : 3;
            wrt_v3 m = v3_norm(fv3(vn[c]));
            s->p[j] = v3_sub(v3_scale(p[c], 2), p[0]);
            s->n[j] = v3_norm(v3_sub(v3_scale(m, 2 * v3_dot(n0, m)), n0));
        }
        s->w[0][0] = 1;
        s->w[1][0] = s->w[1][1] = 0.5;
        s->w[2][0] = s->w[2][1] = s->w[2][2] = 1.0 / 3;
        s->w[3][0] = s->w[3][2] = 0.5;
    } else {
        s->nsrc = 4;
        for (int k = 0; k < 4; k++) {
            s->p[k] = p[k];
            s->n[k] = v3_norm(fv3(vn[k]));
            s->w[k][k] = 1;
        }
    }
}

void wrt_smooth_weights(const wrt_smooth_src *s, wrt_v3 x, double w[4]) {
    double b[3];
    w[0] = 1;
    w[1] = w[2] = w[3] = 0;
    if (!s->curved) return;
    barycentric(s->p[0], s->p[1], s->p[2], x, b);
    if (s->nsrc == 3 || b[1] >= 0) {
        for (int k = 0; k < 3; k++) w[k] = b[k];
        return;
    }
    /* a paired quad beyond its diagonal 0-2: the triangle (0 2 3) */
    barycentric(s->p[0], s->p[2], s->p[3], x, b);
    w[0] = b[0];
    w[1] = 0;
    w[2] = b[1];
    w[3] = b[2];
}

void wrt_smooth_at(const wrt_smooth_src *s, const double w[4], wrt_v3 x, wrt_v3 fn, wrt_v3 *ns, wrt_v3 *xs) {
    *ns = fn;
    *xs = x;
    if (!s->curved) return;
    wrt_v3 n = v3(0, 0, 0), t = v3(0, 0, 0);
    for (int i = 0; i < s->nsrc; i++) {
        n = v3_mad(n, s->n[i], w[i]);
        /* x projected onto vertex i's tangent plane */
        t = v3_mad(t, v3_mad(x, s->n[i], -v3_dot(v3_sub(x, s->p[i]), s->n[i])), w[i]);
    }
    if (v3_len(n) > 1e-9) *ns = v3_norm(n);
    if (v3_dot(v3_sub(t, x), fn) > 0) *xs = t;
}

wrt_v3 wrt_smooth_facing(wrt_v3 n, wrt_v3 v) {
    double nv = v3_dot(n, v);
    if (!(nv < 0)) return n;
    return v3_norm(v3_mad(n, v, WRT_SMOOTH_FACING_EPS - nv));
}
