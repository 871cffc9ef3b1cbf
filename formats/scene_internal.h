/* scene_internal.h: declarations shared by the two halves of the glTF scene builder,
 * scene.c (loading, pairing) and scene_report.c (the summary): the name of a problem
 * kind, used by scene.c's messages and the summary alike. Not part of any API. */
#ifndef WRT_SCENE_INTERNAL_H
#define WRT_SCENE_INTERNAL_H

#include "scene.h"

/* The short name of a WRT_PROBLEM_* kind ("unpaired", "non-planar", ...). */
const char *wrt_scene_problem_name(int kind);

/* scene_dups.c: counts the pairs of elements that occupy the same place facing the same
 * way (centroids within 1e-5 of `diag`, the same normal and area) and, unless quiet, warns
 * naming the first three pairs (index, mesh, primitive, triangles, node). Counts up to
 * 10,000 pairs. */
int wrt_scene_coincident(const wrt_scene *s, double diag, const char *label, int quiet);
/* scene_normals.c: NORMAL at the corners of triangle t's three quads (q from
 * wrt_triangle_quads) and of the quad paired from triangles t and s; nothing if the
 * primitive has no normals. */
struct wrt_gltf_prim;
struct wrt_quad;
void wrt_scene_triangle_parts_nrm(const struct wrt_gltf_prim *p, int t, struct wrt_quad *q);
void wrt_scene_pair_nrm(const struct wrt_gltf_prim *p, int t, int s, struct wrt_quad *q);

#endif
