/* scene.h: the scene wrt works on, as loaded from a quad-based glTF 2.0 file.
 * Quads, glTF metallic-roughness materials, KHR_lights_punctual point and spot
 * lights, and a camera, all in world space after flattening the node hierarchy.
 * The loader (scene.c, with the tinygltf shim gltf_shim.cpp) pairs glTF's triangles
 * into planar convex quads and reports every problem with mesh/primitive/triangle.
 *
 * Quad parameterization (documented in README.md): corners p[0..3] in order around
 * the quad, P(u,v) = (1-u)(1-v) p0 + u(1-v) p1 + u v p2 + (1-u) v p3, (u,v) in [0,1]^2.
 * For a parallelogram (p2 = p1 + p3 - p0) this is affine with constant Jacobian
 * J = area; for a general planar convex quad J(u,v) is bilinear (see wrt_quad_jacobian).
 * The normal is normalize((p1-p0) x (p3-p0)) and agrees with the glTF winding
 * (counter-clockwise front faces). Tangent frame: t = normalize(p1-p0), b = n x t. */
#ifndef WRT_SCENE_H
#define WRT_SCENE_H

#include "../common/wrt_common.h"

typedef struct wrt_quad {
    wrt_v3 p[4];        /* corners, world space */
    wrt_v3 n, t, b;     /* unit normal and tangent frame */
    double area;
    int parallelogram;  /* 1 if affine (constant Jacobian) */
    int material;       /* index into scene materials */
    int mesh, prim;     /* glTF mesh and primitive index it came from */
    int tri[2];         /* the two triangle indices within the primitive */
    int name;           /* index into scene->names (mesh name) */
} wrt_quad;

typedef struct wrt_material {
    char name[64];
    float base_color[3];  /* linear RGB: baseColorFactor x mean of baseColorTexture */
    float metallic;       /* glTF default 1 */
    float roughness;      /* glTF default 1 */
    float emissive[3];    /* emissiveFactor x mean emissiveTexture (reported, not emitted) */
    int lambertian;       /* 1 if roughness == 1 and metallic == 0: pure diffuse, albedo base_color */
    int has_texture;
} wrt_material;

typedef enum { WRT_LIGHT_POINT = 0, WRT_LIGHT_SPOT = 1 } wrt_light_type;

typedef struct wrt_light {
    wrt_light_type type;
    char name[64];
    wrt_v3 pos;
    wrt_v3 dir;          /* unit; spot axis = node's -Z */
    float color[3];      /* linear RGB, default 1,1,1 */
    float intensity;     /* candela (point, spot) */
    float range;         /* 0 = infinite */
    float inner_cone;    /* radians, default 0 */
    float outer_cone;    /* radians, default pi/4 */
} wrt_light;

typedef struct wrt_camera {
    wrt_v3 pos, dir, up; /* dir: unit view direction (-Z of node), up: unit (+Y of node) */
    double yfov;         /* radians */
    double aspect;       /* 0 = from viewport */
    double znear, zfar;  /* zfar 0 = infinite */
    int from_file;       /* 0 if a default framing the scene was made */
} wrt_camera;

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
} wrt_scene;

typedef struct wrt_load_options {
    int drop_bad;        /* 0: refuse a scene with any problem; 1: drop bad triangles with a warning */
    double planar_tol;   /* relative tolerance for planarity (0 = default 1e-4) */
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
/* Point at (u,v) and the Jacobian |dP/du x dP/dv| there. */
static inline wrt_v3 wrt_quad_point(const wrt_quad *q, double u, double v) {
    double w0 = (1 - u) * (1 - v), w1 = u * (1 - v), w2 = u * v, w3 = (1 - u) * v;
    return v3(w0 * q->p[0].x + w1 * q->p[1].x + w2 * q->p[2].x + w3 * q->p[3].x,
              w0 * q->p[0].y + w1 * q->p[1].y + w2 * q->p[2].y + w3 * q->p[3].y,
              w0 * q->p[0].z + w1 * q->p[1].z + w2 * q->p[2].z + w3 * q->p[3].z);
}
static inline double wrt_quad_jacobian(const wrt_quad *q, double u, double v) {
    if (q->parallelogram) return q->area;
    wrt_v3 du = v3_add(v3_scale(v3_sub(q->p[1], q->p[0]), 1 - v), v3_scale(v3_sub(q->p[2], q->p[3]), v));
    wrt_v3 dv = v3_add(v3_scale(v3_sub(q->p[3], q->p[0]), 1 - u), v3_scale(v3_sub(q->p[2], q->p[1]), u));
    return v3_len(v3_cross(du, dv));
}

/* Writes a human summary (or one JSON object if json) of the scene to `f`. */
#include <stdio.h>
void wrt_scene_print_summary(const wrt_scene *s, int json, FILE *f);

#endif
