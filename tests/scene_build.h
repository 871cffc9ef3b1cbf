/* scene_build.h: scenes built in memory for the tests (no glTF): quads from corners,
 * diffuse materials, boxes. Test-only helpers. */
#ifndef WRT_TEST_SCENE_BUILD_H
#define WRT_TEST_SCENE_BUILD_H

#include <stdlib.h>
#include <string.h>
#include "formats/scene.h"

/* An empty scene with a valid camera (looking down -Z from the origin), which the .gto
 * writer requires; tests that need a particular view set their own. */
static inline void tsb_init(wrt_scene *s) {
    memset(s, 0, sizeof *s);
    s->camera.dir = v3(0, 0, -1);
    s->camera.up = v3(0, 1, 0);
    s->camera.yfov = 0.8;
    s->camera.znear = 0.01;
}

static inline int tsb_material(wrt_scene *s, double r, double g, double b) {
    s->materials = realloc(s->materials, (size_t)(s->nmaterials + 1) * sizeof *s->materials);
    wrt_material *m = &s->materials[s->nmaterials];
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "m%d", s->nmaterials);
    m->base_color[0] = (float)r; m->base_color[1] = (float)g; m->base_color[2] = (float)b;
    m->roughness = 1; m->metallic = 0; m->lambertian = 1;
    return s->nmaterials++;
}

/* Corners in order p0 p1 p2 p3 (normal = (p1-p0) x (p3-p0)). */
static inline int tsb_quad(wrt_scene *s, wrt_v3 p0, wrt_v3 p1, wrt_v3 p2, wrt_v3 p3, int mat) {
    s->quads = realloc(s->quads, (size_t)(s->nquads + 1) * sizeof *s->quads);
    wrt_quad *q = &s->quads[s->nquads];
    memset(q, 0, sizeof *q);
    q->p[0] = p0; q->p[1] = p1; q->p[2] = p2; q->p[3] = p3;
    wrt_v3 eu = v3_sub(p1, p0), ev = v3_sub(p3, p0);
    wrt_v3 c = v3_cross(eu, ev);
    q->n = v3_norm(c);
    q->t = v3_norm(eu);
    q->b = v3_cross(q->n, q->t);
    wrt_v3 d = v3_sub(p2, v3_sub(v3_add(p1, p3), p0));
    q->parallelogram = v3_len(d) < 1e-9 * (v3_len(eu) + v3_len(ev));
    q->area = q->parallelogram ? v3_len(c)
                               : 0.5 * (v3_len(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0))) +
                                        v3_len(v3_cross(v3_sub(p2, p0), v3_sub(p3, p0))));
    q->material = mat;
    q->mesh = 0; q->prim = 0; q->tri[0] = 2 * s->nquads; q->tri[1] = 2 * s->nquads + 1;
    for (int i = 0; i < 4; i++) {
        wrt_v3 p = q->p[i];
        if (s->nquads == 0 && i == 0) { s->bbox_min = p; s->bbox_max = p; }
        s->bbox_min = v3(fmin(s->bbox_min.x, p.x), fmin(s->bbox_min.y, p.y), fmin(s->bbox_min.z, p.z));
        s->bbox_max = v3(fmax(s->bbox_max.x, p.x), fmax(s->bbox_max.y, p.y), fmax(s->bbox_max.z, p.z));
    }
    return s->nquads++;
}

/* An axis-aligned closed box [lo, hi], faces pointing inwards, each face split n x n. */
static inline void tsb_box_inward(wrt_scene *s, wrt_v3 lo, wrt_v3 hi, int n, int mat) {
    double L[3] = {lo.x, lo.y, lo.z}, H[3] = {hi.x, hi.y, hi.z};
    for (int axis = 0; axis < 3; axis++) {
        for (int side = 0; side < 2; side++) {
            int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
            for (int i = 0; i < n; i++) for (int j = 0; j < n; j++) {
                double u0 = L[a1] + (H[a1] - L[a1]) * i / n, u1 = L[a1] + (H[a1] - L[a1]) * (i + 1) / n;
                double w0 = L[a2] + (H[a2] - L[a2]) * j / n, w1 = L[a2] + (H[a2] - L[a2]) * (j + 1) / n;
                double c[4][3];
                double pos = side ? H[axis] : L[axis];
                double uu[4] = {u0, u1, u1, u0}, ww[4] = {w0, w0, w1, w1};
                for (int k = 0; k < 4; k++) { c[k][axis] = pos; c[k][a1] = uu[k]; c[k][a2] = ww[k]; }
                /* normal = e_a1 x e_a2 = +e_axis; inward on the low side, so flip the high side */
                wrt_v3 p[4];
                for (int k = 0; k < 4; k++) p[k] = v3(c[k][0], c[k][1], c[k][2]);
                if (side) tsb_quad(s, p[0], p[3], p[2], p[1], mat);
                else tsb_quad(s, p[0], p[1], p[2], p[3], mat);
            }
        }
    }
}

static inline void tsb_free(wrt_scene *s) { free(s->quads); free(s->materials); free(s->lights); memset(s, 0, sizeof *s); }

#endif
