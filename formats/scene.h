/* scene.h: the scene wrt works on, as loaded from a glTF 2.0 file of triangles.
 * Elements (planar convex quads), glTF metallic-roughness materials,
 * KHR_lights_punctual point and spot lights, and a camera, all in world space after
 * flattening the node hierarchy. The loader (scene.c, with the tinygltf shim
 * gltf_shim.cpp) pairs glTF's triangles into planar convex quads; every triangle left
 * over becomes three quads of its own (docs/triangles.md). Triangles too small to
 * matter are dropped and counted; unusable ones (non-finite corners) are refused with
 * mesh/primitive/triangle.
 * The scene's parts (quad, material, light, camera) are common/scene_types.h. */
#ifndef WRT_SCENE_H
#define WRT_SCENE_H

#include "../common/scene_types.h"

typedef struct wrt_problem {
    int kind;            /* WRT_PROBLEM_* */
    int mesh, prim, tri; /* where; tri = -1 if not a triangle */
    char what[160];
} wrt_problem;

/* Problems: DEGENERATE and SLIVER triangles are always dropped (counted, one warning);
 * NONFINITE ones refuse the scene unless drop_bad. UNPAIRED, NONPLANAR and NONCONVEX
 * are no longer problems (such triangles become triangle elements, counted in
 * wrt_scene.why_single); the values stay for the reasons' names. */
enum {
    WRT_PROBLEM_UNPAIRED = 1, /* triangle with no partner forming a quad */
    WRT_PROBLEM_NONPLANAR,
    WRT_PROBLEM_DEGENERATE,   /* zero area / collinear */
    WRT_PROBLEM_NONCONVEX,
    WRT_PROBLEM_NONFINITE,    /* NaN or Inf coordinates */
    WRT_PROBLEM_SLIVER,       /* narrowest height under WRT_SLIVER_REL of the scene diagonal */
};

/* A triangle whose smallest height (twice its area over its longest edge) is below
 * this fraction of the scene's bounding-box diagonal is a sliver: dropped and counted.
 * 1e-5 is the rays' offset scale (common/rt_scene.h): a narrower triangle cannot be hit
 * or left reliably. */
#define WRT_SLIVER_REL 1e-5

/* Why a triangle became an element of its own (wrt_scene.why_single). */
enum {
    WRT_SINGLE_ALONE = 0,   /* no triangle shares an edge with it */
    WRT_SINGLE_TAKEN,       /* every partner it could pair with was paired with another */
    WRT_SINGLE_NONPLANAR,   /* the neighbour is not in its plane (a curved surface, a fold) */
    WRT_SINGLE_NONCONVEX,   /* the two would make a non-convex or degenerate quad */
    WRT_SINGLE_WINDING,     /* the neighbour is wound the other way */
    WRT_SINGLE_FAN,         /* its edges are each shared by more than WRT_MAX_EDGE_FAN triangles */
    WRT_SINGLE_NREASONS
};

typedef struct wrt_scene {
    wrt_quad *quads; int nquads;
    wrt_material *materials; int nmaterials;
    wrt_light *lights; int nlights;
    wrt_camera camera;
    char (*names)[64]; int nnames; /* mesh names */
    wrt_problem *problems; int nproblems; /* all found, whether refused or dropped */
    int ntriangles;        /* triangles read */
    int npaired;           /* elements made of two triangles (WRT_ELEM_QUAD, fronts only) */
    int nsingle;           /* triangles made elements of their own (3 WRT_ELEM_TRIANGLE quads each) */
    int why_single[WRT_SINGLE_NREASONS]; /* nsingle by reason */
    int ndropped;          /* triangles dropped as degenerate or slivers (always) */
    int nnonfinite;        /* triangles with a non-finite corner: refused, or dropped with drop_bad */
    int nmirrored;         /* primitive instances placed by a mirroring node (winding flipped) */
    int nemissive;         /* materials with non-zero emission (reported only) */
    int ncoincident;       /* pairs of elements in the same place facing the same way (warned;
                              counting stops at 10,000) */
    wrt_v3 bbox_min, bbox_max;
    uint64_t source_hash;  /* hash of the source file bytes */
    int ntwins;            /* back-to-back twins added for doubleSided materials (in nquads) */
    char *ignored;         /* glTF fields the bake does not use, "; "-separated (owned) */
    char *files;           /* external files read (buffers, images), one a line (owned) */
    struct wrt_texture *textures; int ntextures; /* base-colour textures (common/texture.h),
                              one per textured material, wrt_material.base_tex - 1 (owned) */
} wrt_scene;

typedef struct wrt_load_options {
    int drop_bad;        /* 0: refuse a scene with a non-finite triangle; 1: drop it with a warning */
    double planar_tol;   /* relative tolerance for planarity (0 = default 1e-4) */
    int allow_outside_files; /* 1: buffers and images may lie outside the scene's folder */
    int report_only;     /* 1: never refuse for geometry and log nothing about it; the
                            problems and counts say what a bake would refuse or drop (--scan) */
} wrt_load_options;

/* Loads a .gltf or .glb. On failure returns a status with wrt_last_error() naming
 * what and where, and leaves *out zeroed. The caller frees with wrt_scene_free. */
wrt_status wrt_scene_load(const char *path, const wrt_load_options *opt, wrt_scene *out);
/* Same from memory (used by the fuzz target); `base_dir` resolves external buffers. */
wrt_status wrt_scene_load_memory(const void *data, size_t size, const char *base_dir,
                                 const wrt_load_options *opt, wrt_scene *out);
void wrt_scene_free(wrt_scene *s);

/* Builds the quad's derived fields (n, t, b, area, parallelogram) from p[].
 * Returns WRT_OK or WRT_ERR_GEOMETRY if degenerate. */
wrt_status wrt_quad_finish(wrt_quad *q);

/* A triangle's three quads through its centroid and edge midpoints (the triangle
 * element, docs/triangles.md): part k = (V_k, (V_k + V_k+1)/2, centroid,
 * (V_k+2 + V_k)/2) with V = (a, b, c) in the front-face winding, so each part's normal
 * is the triangle's. Each is a planar convex quad (the affine image of a convex quad of
 * the reference triangle) of a third of the area, never a parallelogram. Fills kind,
 * part, tri[1] = -1, node = -1 and the derived fields; the caller sets material, mesh,
 * prim, tri[0], name. Returns WRT_OK, or WRT_ERR_GEOMETRY if the triangle is degenerate. */
wrt_status wrt_triangle_quads(wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_quad out[3]);

/* Writes a human summary (or one JSON object if json) of the scene to `f`. */
#include <stdio.h>
void wrt_scene_print_summary(const wrt_scene *s, int json, FILE *f);

#endif
