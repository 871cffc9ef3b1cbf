/* ff_closed.h: closed-form form factors between axis-aligned rectangles (sum-of-corners
 * rule) and from a point to a polygon (Lambert), the truths the bake's tests compare against. Checked in the tests themselves
 * against the classic values 0.1998 (unit squares facing at distance 1) and 0.2000
 * (unit squares at right angles sharing an edge). */
#ifndef WRT_TEST_FF_CLOSED_H
#define WRT_TEST_FF_CLOSED_H

#include <math.h>

#include "common/wrt_common.h"

static double ffc_gpar(double x, double y, double eta, double xi, double z) {
    double dx = x - xi, dy = y - eta, r, t = 0;
    r = sqrt(dx * dx + z * z);
    if (r > 0) t += dy * r * atan(dy / r);
    r = sqrt(dy * dy + z * z);
    if (r > 0) t += dx * r * atan(dx / r);
    double a = dx * dx + dy * dy + z * z;
    if (a > 0) t -= 0.5 * z * z * log(a);
    return t / (2 * M_PI);
}

/* Rectangle 1: z = 0, [x1,x2] x [y1,y2]; rectangle 2: z = c, [xi1,xi2] x [e1,e2], facing. F_12. */
static inline double ffc_parallel(double x1, double x2, double y1, double y2, double xi1, double xi2,
                                  double e1, double e2, double c) {
    double X[2] = {x1, x2}, Y[2] = {y1, y2}, E[2] = {e1, e2}, XI[2] = {xi1, xi2}, s = 0;
    for (int i = 0; i < 2; i++) for (int j = 0; j < 2; j++) for (int k = 0; k < 2; k++) for (int l = 0; l < 2; l++)
        s += ((i + j + k + l) % 2 ? -1 : 1) * ffc_gpar(X[i], Y[j], E[k], XI[l], c);
    return s / ((x2 - x1) * (y2 - y1));
}

static double ffc_gper(double x, double y, double eta, double xi) {
    double dy = y - eta, r = sqrt(x * x + xi * xi), t = 0;
    if (r > 0) t += dy * r * atan(dy / r);
    double a = x * x + xi * xi + dy * dy;
    if (a > 0) t -= 0.25 * (x * x + xi * xi - dy * dy) * log(a);
    return t / (2 * M_PI);
}

/* Rectangle 1: z = 0, [x1,x2] x [y1,y2] (x >= 0, normal +z); rectangle 2: x = 0,
 * z in [xi1,xi2], y in [e1,e2] (normal +x). F_12. */
static inline double ffc_perpendicular(double x1, double x2, double y1, double y2, double xi1, double xi2,
                                       double e1, double e2) {
    double X[2] = {x1, x2}, Y[2] = {y1, y2}, E[2] = {e1, e2}, XI[2] = {xi1, xi2}, s = 0;
    for (int i = 0; i < 2; i++) for (int j = 0; j < 2; j++) for (int k = 0; k < 2; k++) for (int l = 0; l < 2; l++)
        s += ((i + j + k + l) % 2 ? -1 : 1) * ffc_gper(X[i], Y[j], E[k], XI[l]);
    return s / ((x2 - x1) * (y2 - y1));
}

/* Lambert's closed form, written out apart from the bake's (precompute/dto.c, whose edge
 * term takes a series and half angles for speed): the form factor from a point x (unit
 * normal n) to a convex polygon v[0..m-1] wholly in front of x's tangent plane, 1 / (2 pi)
 * times the sum over the edges of the angle each subtends (atan2) times the cosine between
 * n and the normal of the edge's plane. */
static inline double ffc_point_polygon(wrt_v3 x, wrt_v3 n, const wrt_v3 *v, int m) {
    double s = 0;
    for (int k = 0; k < m; k++) {
        wrt_v3 a = v3_sub(v[k], x), b = v3_sub(v[(k + 1) % m], x);
        wrt_v3 c = v3_cross(a, b);
        double lc = v3_len(c);
        if (!(lc > 0)) continue;
        s += atan2(lc, v3_dot(a, b)) * v3_dot(c, n) / lc;
    }
    return fabs(s) / (2 * M_PI);
}

#endif
