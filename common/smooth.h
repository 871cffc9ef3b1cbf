/* smooth.h: the smooth surface that a mesh's vertex normals describe over one flat
 * element, for shading: the interpolated shading normal and the shadow test's point
 * moved off the flat facet towards that surface (the shadow terminator of smooth
 * normals on large facets; the idea of Hanika 2021, "Hacking the shadow terminator").
 *
 * An element's source is the mesh polygon its corners came from: a triangle's part
 * (WRT_ELEM_TRIANGLE: corners V_k, the two edge midpoints, the centroid) has the whole
 * triangle as its source, rebuilt from the part alone (V = 2 x midpoint - V_k; the
 * normal at V is V_k's normal mirrored about the midpoint's, which is their normalized
 * mean); a paired quad has its four corners, taken as the two triangles (0 1 2) and
 * (0 2 3), as the player draws it. At a point x of the element with barycentric weights
 * w_i over the source vertices P_i (normals N_i):
 *   shading normal  n_s = normalize(sum w_i N_i)
 *   shadow point    x'  = sum w_i (x - dot(x - P_i, N_i) N_i), used only where it lies
 *                         on the outer side of the facet (dot(x' - x, n_face) > 0).
 * A flat element (every corner normal within half a degree of its face normal, the rule
 * of the .gto's normals section) is left alone: n_s = n_face, x' = x. The player's
 * shader (player/render.c) evaluates the same formulas on the same source records; the
 * path tracer (verify/reference.c) uses these for its camera image.
 * Depends on wrt_common.h only. */
#ifndef WRT_SMOOTH_H
#define WRT_SMOOTH_H

#include "wrt_common.h"

/* cosine under which a corner normal leaves its face's plane (half a degree; as
 * formats/gto_write.c's normals section) */
#define WRT_SMOOTH_COS (1 - 4e-5)

typedef struct wrt_smooth_src {
    int curved;        /* 0: a flat element, nothing below is used */
    int nsrc;          /* 3 (a triangle) or 4 (a paired quad) */
    wrt_v3 p[4];       /* source vertices */
    wrt_v3 n[4];       /* their unit normals */
    double w[4][4];    /* w[c]: the weights of the element's corner c over the sources */
} wrt_smooth_src;

/* The source of an element with corners p, flat normal fn, corner normals vn (NULL: flat)
 * and tri_part 1 for a triangle's part, 0 for a paired quad, -1 unknown (decided from
 * the corners: a part's centroid is (2 p1 + 2 p3 - p0) / 3). */
void wrt_smooth_make(const wrt_v3 p[4], wrt_v3 fn, const float (*vn)[3], int tri_part, wrt_smooth_src *s);

/* The weights at point x (on the element's plane, or near it) over the sources. */
void wrt_smooth_weights(const wrt_smooth_src *s, wrt_v3 x, double w[4]);

/* Shading normal ns and shadow point xs at x with weights w (flat element: fn and x). */
void wrt_smooth_at(const wrt_smooth_src *s, const double w[4], wrt_v3 x, wrt_v3 fn, wrt_v3 *ns, wrt_v3 *xs);

/* The shading normal n bent toward the eye where it faces away from it (n.v < 0, v the
 * unit direction toward the eye; a curved mesh's grazing outline, where the interpolated
 * normal turns past the silhouette): n - (n.v - eps) v, normalized, which sees the eye at
 * n.v = eps > 0; else n. The player's shader applies the same rule. */
#define WRT_SMOOTH_FACING_EPS 0.01
wrt_v3 wrt_smooth_facing(wrt_v3 n, wrt_v3 v);

#endif
