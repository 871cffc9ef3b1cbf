/* scene.h: the scene wrt works on, as loaded from a quad-based glTF 2.0 file.
 * Quads, glTF metallic-roughness materials, KHR_lights_punctual point and spot
 * lights, and a camera, all in world space after flattening the node hierarchy.
 * The loader (scene.c, with the tinygltf shim gltf_shim.cpp) pairs glTF's triangles
 * into planar convex quads and reports every problem with mesh/primitive/triangle.
 * The scene's parts (quad, material, light, camera) are common/scene_types.h. */
#ifndef WRT_SCENE_H
#define WRT_SCENE_H

#include "../common/scene_types.h"

typedef struct wrt_problem {
    int kind;            /* WRT_PROBLEM_* */
    int mesh, prim, tri; /* where; tri = -1 if not a triangle */
    char what[160];
} wrt_problem;

enum {
    WRT_PROBLEM_UNPAIRED = 1, /* triangle with no partner forming a quad */
    WRT_PROBLEM_NONPLANAR,
    WRT_PROBLEM_DEGENERATE,   /* zero area / collinear */
    WRT_PROBLEM_NONCONVEX,
    WRT_PROBLEM_NONFINITE,    /* NaN or Inf coordinates */
};

typedef struct wrt_scene {
    wrt_quad *quads; int nquads;
    wrt_material *materials; int nmaterials;
    wrt_light *lights; int nlights;
    wrt_camera camera;
    char (*names)[64]; int nnames; /* mesh names */
    wrt_problem *problems; int nproblems; /* all found, whether refused or dropped */
    int ntriangles;        /* triangles read */
    int nemissive;         /* materials with non-zero emission (reported only) */
    wrt_v3 bbox_min, bbox_max;
    uint64_t source_hash;  /* hash of the source file bytes */
    int ntwins;            /* back-to-back twins added for doubleSided materials (in nquads) */
    char *ignored;         /* glTF fields the bake does not use, "; "-separated (owned) */
    char *files;           /* external files read (buffers, images), one a line (owned) */
} wrt_scene;

typedef struct wrt_load_options {
    int drop_bad;        /* 0: refuse a scene with any problem; 1: drop bad triangles with a warning */
    double planar_tol;   /* relative tolerance for planarity (0 = default 1e-4) */
    int allow_outside_files; /* 1: buffers and images may lie outside the scene's folder */
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

/* Writes a human summary (or one JSON object if json) of the scene to `f`. */
#include <stdio.h>
void wrt_scene_print_summary(const wrt_scene *s, int json, FILE *f);

#endif
