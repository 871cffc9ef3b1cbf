/* scene_normals.c: the mesh's vertex normals (glTF NORMAL, world space, from the reader)
 * carried to each element's corners: a paired quad's four vertices, a triangle's three
 * quads at its corners, edge midpoints and centroid (docs/triangles.md, "Vertex normals").
 * They shade the direct light and join the smooth display across a smooth mesh's edges;
 * the bake's transport never reads them. Depends on gltf_shim.h and scene_types.h. */
#include "gltf_shim.h"
#include "scene_internal.h"
#include "../common/scene_types.h"

#include <math.h>
#include <string.h>

/* NORMAL of triangle t's three quads: the normalized mean of the corners' normals at
 * each midpoint and at the centroid (where that mean vanishes, which only opposite
 * normals on one triangle give, the quad's own normal). */
void wrt_scene_triangle_parts_nrm(const wrt_gltf_prim *p, int t, wrt_quad *q) {
    if (!p->nrm) return;
    const uint32_t *ix = &p->idx[3 * (size_t)t];
    for (int k = 0; k < 3; k++) {
        const float *a = &p->nrm[3 * ix[k]], *b = &p->nrm[3 * ix[(k + 1) % 3]], *c = &p->nrm[3 * ix[(k + 2) % 3]];
        double m[4][3];
        for (int d = 0; d < 3; d++) {
            m[0][d] = a[d];
            m[1][d] = (double)a[d] + b[d];
            m[2][d] = (double)a[d] + b[d] + c[d];
            m[3][d] = (double)c[d] + a[d];
        }
        for (int i = 0; i < 4; i++) {
            double l = sqrt(m[i][0] * m[i][0] + m[i][1] * m[i][1] + m[i][2] * m[i][2]);
            wrt_v3 n = l > 1e-6 ? v3(m[i][0] / l, m[i][1] / l, m[i][2] / l) : q[k].n;
            q[k].vn[i][0] = (float)n.x; q[k].vn[i][1] = (float)n.y; q[k].vn[i][2] = (float)n.z;
        }
        q[k].has_nrm = 1;
    }
}

/* NORMAL of a quad paired from triangles t and s, corner by corner as pair_uv. */
void wrt_scene_pair_nrm(const wrt_gltf_prim *p, int t, int s, wrt_quad *q) {
    if (!p->nrm) return;
    for (int i = 0; i < 4; i++) {
        int found = 0;
        for (int j = 0; j < 6 && !found; j++) {
            uint32_t v = p->idx[3 * (size_t)(j < 3 ? t : s) + (size_t)(j % 3)];
            const double *x = &p->pos[3 * (size_t)v];
            if (x[0] == q->p[i].x && x[1] == q->p[i].y && x[2] == q->p[i].z) {
                memcpy(q->vn[i], &p->nrm[3 * (size_t)v], sizeof q->vn[i]);
                found = 1;
            }
        }
        if (!found) return; /* cannot happen: eval_pair takes corners from t and s */
    }
    q->has_nrm = 1;
}

