/* view.c: wrt-play's geometry questions about the scene it shows, answered from the
 * library's getters (include/wrt.h) alone: the default camera of a scene whose file has
 * none, and where a light moved by the window's keys must stop (at a wall, never through
 * it). Brute-force rays against every quad: a few thousand rays once at start for the
 * camera, one segment per key-repeat for a light. See view.h. */
#include "view.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/wrt_common.h"

struct wrt_play_geom {
    int n;
    wrt_v3 *p;      /* 4 corners a quad */
    wrt_v3 *nrm;    /* unit front normal */
    double diag;    /* the scene box's diagonal */
    double lo[3], hi[3];
};

wrt_status wrt_play_geom_create(const wrt_runtime *rt, wrt_play_geom **out) {
    *out = NULL;
    int n = wrt_runtime_quad_count(rt);
    if (n < 0) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_play_geom_create: not a live runtime");
    wrt_play_geom *g = calloc(1, sizeof *g);
    if (!g) return wrt_fail(WRT_ERR_NOMEM, "out of memory for the scene's geometry");
    g->n = n;
    g->p = malloc((size_t)(n ? n : 1) * 4 * sizeof *g->p);
    g->nrm = malloc((size_t)(n ? n : 1) * sizeof *g->nrm);
    if (!g->p || !g->nrm) {
        wrt_play_geom_destroy(g);
        return wrt_fail(WRT_ERR_NOMEM, "out of memory for the scene's geometry (%d quads)", n);
    }
    for (int q = 0; q < n; q++) {
        double c[4][3];
        wrt_runtime_quad Q;
        if (wrt_runtime_quad_corners(rt, q, c, NULL) || wrt_runtime_get_quad(rt, q, &Q, NULL)) {
            wrt_play_geom_destroy(g);
            return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_play_geom_create: quad %d unreadable", q);
        }
        for (int k = 0; k < 4; k++) g->p[4 * q + k] = v3(c[k][0], c[k][1], c[k][2]);
        g->nrm[q] = v3(Q.normal[0], Q.normal[1], Q.normal[2]);
    }
    if (n == 0 || wrt_runtime_get_bounds(rt, g->lo, g->hi, NULL))
        for (int k = 0; k < 3; k++) { g->lo[k] = -1; g->hi[k] = 1; }
    g->diag = v3_len(v3(g->hi[0] - g->lo[0], g->hi[1] - g->lo[1], g->hi[2] - g->lo[2]));
    *out = g;
    return WRT_OK;
}

void wrt_play_geom_destroy(wrt_play_geom *g) {
    if (!g) return;
    free(g->p);
    free(g->nrm);
    free(g);
}

/* The ray o + t d (t in (tmin, tmax)) against triangle a b c: t, or -1. */
static double ray_tri(wrt_v3 o, wrt_v3 d, wrt_v3 a, wrt_v3 b, wrt_v3 c, double tmin, double tmax) {
    wrt_v3 e1 = v3_sub(b, a), e2 = v3_sub(c, a), pv = v3_cross(d, e2);
    double det = v3_dot(e1, pv);
    if (fabs(det) < 1e-300) return -1;
    double inv = 1 / det;
    wrt_v3 tv = v3_sub(o, a);
    double u = v3_dot(tv, pv) * inv;
    if (u < 0 || u > 1) return -1;
    wrt_v3 qv = v3_cross(tv, e1);
    double v = v3_dot(d, qv) * inv;
    if (v < 0 || u + v > 1) return -1;
    double t = v3_dot(e2, qv) * inv;
    return t > tmin && t < tmax ? t : -1;
}

/* The nearest quad the ray meets in (tmin, tmax): its index (*t its distance), or -1.
 * front_only: quads seen from behind are passed through, as the renderer culls them. */
static int ray_first(const wrt_play_geom *g, wrt_v3 o, wrt_v3 d, double tmin, double tmax, int front_only, double *t) {
    int best = -1;
    double bt = tmax;
    for (int q = 0; q < g->n; q++) {
        if (front_only && v3_dot(d, g->nrm[q]) >= 0) continue;
        const wrt_v3 *p = &g->p[4 * q];
        double s = ray_tri(o, d, p[0], p[1], p[2], tmin, bt);
        if (s < 0) s = ray_tri(o, d, p[0], p[2], p[3], tmin, bt);
        if (s > 0) { bt = s; best = q; }
    }
    if (t) *t = bt;
    return best;
}

double wrt_play_geom_clip_move(const wrt_play_geom *g, const double from[3], const double to[3]) {
    wrt_v3 a = v3(from[0], from[1], from[2]), b = v3(to[0], to[1], to[2]), d = v3_sub(b, a);
    double len = v3_len(d);
    if (!(len > 0)) return 1;
    d = v3_scale(d, 1 / len);
    double gap = 1e-3 * g->diag, t; /* stop this far before the wall, on the light's side */
    if (ray_first(g, a, d, 0, len + gap, 0, &t) < 0) return 1;
    return fmax(0, t - gap) / len;
}

/* Whether surface point x (unit normal n, of the side seen) receives light l directly. */
static int lit_by(const wrt_play_geom *g, wrt_v3 x, wrt_v3 n, const wrt_runtime_light *l) {
    wrt_v3 to_l, ldir = v3_norm(v3(l->direction[0], l->direction[1], l->direction[2]));
    double dist;
    if (l->kind == WRT_LIGHT_KIND_DIRECTIONAL) {
        to_l = v3_scale(ldir, -1);
        dist = 4 * g->diag;
    } else {
        wrt_v3 lp = v3(l->position[0], l->position[1], l->position[2]);
        to_l = v3_sub(lp, x);
        dist = v3_len(to_l);
        if (!(dist > 0)) return 0;
        to_l = v3_scale(to_l, 1 / dist);
        if (l->kind == WRT_LIGHT_KIND_SPOT) {
            float outer = l->outer_cone > 0 ? l->outer_cone : (float)(WRT_PI / 4);
            if (v3_dot(v3_scale(to_l, -1), ldir) < cos(outer)) return 0;
        }
    }
    if (v3_dot(to_l, n) <= 0) return 0;
    wrt_v3 o = v3_mad(x, n, 1e-6 * g->diag);
    return ray_first(g, o, to_l, 0, dist, 0, NULL) < 0;
}

/* What a camera at eye looking along fwd shows: the fraction of a grid of rays over its
 * frustum that meet, at a distance of at least 2% of the scene, the front of a quad
 * that some light reaches directly. */
static double view_score(const wrt_play_geom *g, wrt_v3 eye, wrt_v3 fwd, double yfov, const wrt_runtime_light *ls,
                         int nl) {
    enum { RAYS = 7 };
    wrt_v3 up = v3(0, 1, 0), right = v3_norm(v3_cross(fwd, up)), vup = v3_cross(right, fwd);
    double th = tan(yfov / 2), tw = th * 4.0 / 3.0;
    int good = 0;
    for (int j = 0; j < RAYS; j++)
        for (int i = 0; i < RAYS; i++) {
            double sx = (2.0 * (i + 0.5) / RAYS - 1) * tw, sy = (2.0 * (j + 0.5) / RAYS - 1) * th;
            wrt_v3 d = v3_norm(v3_add(fwd, v3_add(v3_scale(right, sx), v3_scale(vup, sy))));
            double t;
            int q = ray_first(g, eye, d, 0, 1e30, 1, &t);
            if (q < 0 || t < 0.02 * g->diag) continue;
            wrt_v3 x = v3_mad(eye, d, t);
            for (int k = 0; k < nl; k++)
                if (!ls[k].off && lit_by(g, x, g->nrm[q], &ls[k])) { good++; break; }
        }
    return (double)good / (RAYS * RAYS);
}

/* Whether some light (on) reaches point x directly, whatever way x faces. */
static int sees_light(const wrt_play_geom *g, wrt_v3 x, const wrt_runtime_light *ls, int nl) {
    for (int k = 0; k < nl; k++) {
        if (ls[k].off) continue;
        const wrt_runtime_light *l = &ls[k];
        wrt_v3 to_l;
        double dist;
        if (l->kind == WRT_LIGHT_KIND_DIRECTIONAL) {
            to_l = v3_scale(v3_norm(v3(l->direction[0], l->direction[1], l->direction[2])), -1);
            dist = 4 * g->diag;
        } else {
            to_l = v3_sub(v3(l->position[0], l->position[1], l->position[2]), x);
            dist = v3_len(to_l);
            if (!(dist > 0)) return 1;
            to_l = v3_scale(to_l, 1 / dist);
        }
        if (ray_first(g, x, to_l, 0, dist, 0, NULL) < 0) return 1;
    }
    return 0;
}

/* The mean distance to the first quad over the 17 directions of the cube's faces, edges
 * and corners that do not point up, or -1 when one escapes: x is then not inside a
 * room (open or not at the top: a maze lit from above is a set of rooms). */
static double openness(const wrt_play_geom *g, wrt_v3 x) {
    double sum = 0;
    int n = 0;
    for (int i = -1; i <= 1; i++)
        for (int j = -1; j <= 0; j++)
            for (int k = -1; k <= 1; k++) {
                if (!i && !j && !k) continue;
                double t;
                if (ray_first(g, x, v3_norm(v3(i, j, k)), 0, 1e30, 0, &t) < 0) return -1;
                sum += t;
                n++;
            }
    return sum / n;
}

int wrt_play_default_view(const wrt_play_geom *g, const wrt_runtime_light *lights, int nlights, wrt_view *v,
                          double *score) {
    memset(v, 0, sizeof *v);
    v->yfov = 45 * WRT_PI / 180;
    v->up[1] = 1;
    wrt_v3 c = v3(0.5 * (g->lo[0] + g->hi[0]), 0.5 * (g->lo[1] + g->hi[1]), 0.5 * (g->lo[2] + g->hi[2]));
    double r = 0.5 * g->diag;
    /* 1. the box framed from +Z, outside it, when that shows lit surface over a tenth of
     * the picture at least (a scene open to the front, a set of objects) */
    wrt_v3 eye = v3(c.x, c.y, c.z + r / tan(v->yfov / 2) * 1.1), fwd = v3(0, 0, -1);
    double s0 = view_score(g, eye, fwd, v->yfov, lights, nlights);
    int chosen = 0;
    if (s0 < 0.1) {
        /* 2. else the most open point inside the box that a light reaches (the middle of
         * the lights' largest room: never inside a closed object, whose inside no light
         * reaches, nor outside a closed room, where rays escape), on a 5 x 3 x 5 grid */
        double best = 0;
        for (int iy = 0; iy < 3; iy++)
            for (int iz = 0; iz < 5; iz++)
                for (int ix = 0; ix < 5; ix++) {
                    wrt_v3 e = v3(g->lo[0] + (ix + 0.5) / 5 * (g->hi[0] - g->lo[0]),
                                  g->lo[1] + (iy + 1) / 4.0 * (g->hi[1] - g->lo[1]),
                                  g->lo[2] + (iz + 0.5) / 5 * (g->hi[2] - g->lo[2]));
                    double o = openness(g, e);
                    if (o > best && sees_light(g, e, lights, nlights)) { best = o; eye = e; chosen = 1 + ix + 5 * (iz + 5 * iy); }
                }
        /* 3. looking along the horizontal direction (of 8) that sees farthest */
        if (chosen) {
            double far = -1;
            for (int d = 0; d < 8; d++) {
                wrt_v3 dir = v3(sin(d * WRT_PI / 4), 0, -cos(d * WRT_PI / 4));
                double dist;
                if (ray_first(g, eye, dir, 0, 1e30, 1, &dist) < 0) dist = 0; /* nothing there: a view of nothing */
                if (dist > far + 1e-9 * g->diag) { far = dist; fwd = dir; }
            }
        }
    }
    for (int i = 0; i < 3; i++) {
        v->eye[i] = (&eye.x)[i];
        v->target[i] = (&eye.x)[i] + (&fwd.x)[i];
    }
    if (score) *score = chosen ? view_score(g, eye, fwd, v->yfov, lights, nlights) : s0;
    return chosen;
}
