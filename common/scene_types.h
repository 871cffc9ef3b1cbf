/* scene_types.h: what a scene is made of, shared by every layer (the loader fills
 * it, the bake reads it, the runtime and the path tracer light it): quads, glTF
 * metallic-roughness materials, KHR_lights_punctual point, spot and directional lights, a camera,
 * all in world space. Depends on wrt_common.h only.
 *
 * Quad parameterization (documented in README.md): corners p[0..3] in order around
 * the quad, P(u,v) = (1-u)(1-v) p0 + u(1-v) p1 + u v p2 + (1-u) v p3, (u,v) in [0,1]^2.
 * For a parallelogram (p2 = p1 + p3 - p0) this is affine with constant Jacobian
 * J = area; for a general planar convex quad J(u,v) is bilinear (see wrt_quad_jacobian).
 * The normal is normalize((p1-p0) x (p3-p0)) and agrees with the glTF winding
 * (counter-clockwise front faces). Tangent frame: t = normalize(p1-p0), b = n x t. */
#ifndef WRT_SCENE_TYPES_H
#define WRT_SCENE_TYPES_H

#include "wrt_common.h"

typedef struct wrt_quad {
    wrt_v3 p[4];        /* corners, world space */
    wrt_v3 n, t, b;     /* unit normal and tangent frame */
    double area;
    int parallelogram;  /* 1 if affine (constant Jacobian) */
    int material;       /* index into scene materials */
    int mesh, prim;     /* glTF mesh and primitive index it came from */
    int tri[2];         /* WRT_ELEM_QUAD: the two triangle indices within the primitive;
                           WRT_ELEM_TRIANGLE: tri[0] the triangle, tri[1] = -1 */
    int name;           /* index into scene->names (mesh name) */
    int kind;           /* WRT_ELEM_QUAD (0, two triangles paired) or WRT_ELEM_TRIANGLE */
    int part;           /* WRT_ELEM_TRIANGLE: which of the triangle's three quads (0..2), else 0 */
    int node;           /* glTF node that placed the mesh (-1 if unknown) */
    int twin;           /* 1: the back twin of a double-sided material's quad twin_of
                           (zero-initialised: not a twin) */
    int twin_of;        /* with twin: the index of its front quad, which precedes it */
    int has_uv;         /* 1: uv holds the primitive's TEXCOORD_0 at each corner */
    float uv[4][2];     /* TEXCOORD_0 at p0..p3 (a triangle element's midpoints and centroid
                           interpolated linearly, as glTF does across a triangle) */
    int has_nrm;        /* 1: vn holds the mesh's vertex normals (glTF NORMAL) at each corner */
    float vn[4][3];     /* unit normals at p0..p3, world space (a triangle element's midpoints
                           and centroid: the normalized mean of its corners' normals); used to
                           shade and to join the smooth display across a smooth mesh's edges,
                           never by the bake's transport (that stays with the flat quads) */
} wrt_quad;

/* Element kinds. A triangle that does not pair into a planar convex quad is cut into
 * three planar convex quads through its centroid and edge midpoints: part k has the
 * corners V_k, (V_k + V_k+1)/2, the centroid, (V_k+2 + V_k)/2, with V_0..V_2 the
 * triangle's corners in its front-face winding (docs/triangles.md). */
enum { WRT_ELEM_QUAD = 0, WRT_ELEM_TRIANGLE = 1 };

typedef struct wrt_material {
    char name[64];
    float base_color[3];  /* linear RGB: baseColorFactor x mean of baseColorTexture */
    float metallic;       /* glTF default 1 */
    float roughness;      /* glTF default 1 */
    float emissive[3];    /* emitted radiance L_e: emissiveFactor x KHR_materials_emissive_strength
                             x mean emissiveTexture (docs/emitters.md) */
    int lambertian;       /* 1 if roughness == 1 and metallic == 0: pure diffuse, albedo base_color */
    int has_texture;
    int base_tex;         /* 1 + index into the scene's textures of its baseColorTexture on
                             TEXCOORD_0 (common/texture.h), 0: none (docs/textures.md) */
} wrt_material;

/* A directional light (KHR_lights_punctual's `directional`, a sun) has no position and no
 * range: it sends light along `dir` from infinitely far, irradiance `intensity` (lux) on a
 * surface facing it. */
typedef enum { WRT_LIGHT_POINT = 0, WRT_LIGHT_SPOT = 1, WRT_LIGHT_DIRECTIONAL = 2 } wrt_light_type;

typedef struct wrt_light {
    wrt_light_type type;
    char name[64];
    wrt_v3 pos;          /* (0, 0, 0) for a directional light */
    wrt_v3 dir;          /* unit; spot axis or the direction a sun's light travels = node's -Z */
    float color[3];      /* linear RGB, default 1,1,1 */
    float intensity;     /* candela (point, spot), lux (directional) */
    float range;         /* 0 = infinite (always 0 for a directional light) */
    float inner_cone;    /* radians, default 0 */
    float outer_cone;    /* radians, default pi/4 */
} wrt_light;

/* "point", "spot" or "directional", as KHR_lights_punctual names them. */
static inline const char *wrt_light_type_name(wrt_light_type t) {
    return t == WRT_LIGHT_SPOT ? "spot" : t == WRT_LIGHT_DIRECTIONAL ? "directional" : "point";
}

typedef struct wrt_camera {
    wrt_v3 pos, dir, up; /* dir: unit view direction (-Z of node), up: unit (+Y of node) */
    double yfov;         /* radians */
    double aspect;       /* 0 = from viewport */
    double znear, zfar;  /* zfar 0 = infinite */
    int from_file;       /* 0 if a default framing the scene was made */
} wrt_camera;

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

#endif
