/* scenegen.h: what the two files of wrt-scenegen share: the options, the scene model
 * the scene builders fill (scenegen.c) and the glTF writer reads (scenegen_gltf.c),
 * the growing text buffer and write_gltf. Internal to the program. Depends on
 * common/wrt_common.h (wrt_v3). */
#ifndef WRT_TOOLS_SCENEGEN_H
#define WRT_TOOLS_SCENEGEN_H

#include "common/wrt_common.h"

enum { LIGHT_DEFAULT = -1, LIGHT_NONE = 0, LIGHT_POINT = 1, LIGHT_SPOT = 2, LIGHT_SUN = 3 };

typedef struct sg_options {
    int res;          /* subdivisions per quad edge (every surface) */
    double albedo;    /* the white/grey walls */
    double scale;     /* uniform scale applied to the whole scene */
    wrt_v3 offset;    /* translation applied after scaling */
    double dist;      /* facing: distance between the squares */
    double angle;     /* grazing: opening angle in degrees */
    double thick;     /* tworooms: thickness of the shared wall */
    int light;        /* LIGHT_*: override the scene's light type */
    double intensity; /* > 0: override every light's intensity (candela, final) */
    int cells;        /* maze: cells per side */
    uint64_t seed;    /* maze: layout seed */
    double roughness; /* cornell-glossy, glossy-box: the metal's roughness */
    double detail;    /* atrium: tessellation (elements grow as detail^2); cornell-shapes: segments x detail */
} sg_options;

typedef struct sg_material {
    char name[64];
    double rgb[3];
    double metallic, roughness;
    double emissive[3];  /* emissiveFactor (0: none) */
    double strength;     /* KHR_materials_emissive_strength (0 or 1: not written) */
} sg_material;

typedef struct sg_mesh {
    char name[64];
    int material;
    float *pos, *nrm; /* 4 vertices per quad, xyz each */
    int nquads, cap;
    float *tpos, *tnrm; /* 3 vertices per triangle (after the quads' in the file), xyz each */
    int ntris, tcap;
} sg_mesh;

typedef struct sg_light {
    char name[64];
    int type; /* LIGHT_POINT, LIGHT_SPOT or LIGHT_SUN (directional: no position, lux) */
    wrt_v3 pos, dir;
    double rgb[3];
    double intensity; /* candela at scale 1; lux for a sun (independent of the scale) */
    double inner, outer; /* spot cone half-angles, radians */
} sg_light;

typedef struct sg_scene {
    char name[64];
    sg_options opt;
    sg_material mats[16];
    int nmats;
    sg_mesh meshes[32];
    int nmeshes;
    sg_light lights[8];
    int nlights;
    wrt_v3 eye, target, up;
    double yfov;
} sg_scene;

typedef struct sbuf {
    char *p;
    size_t n, cap;
} sbuf;

/* Builders shared with the scene files other than scenegen.c (defined there): a
 * material and a mesh (their index), a white point light (candela), the camera, a
 * triangle a b c (counter-clockwise seen from its front, normal per vertex) and a
 * planar convex quad a b c d (counter-clockwise seen from its front; written as the
 * two indexed triangles a b c, a c d). */
int sg_add_material(sg_scene *s, const char *name, double r, double g, double b, double metallic, double roughness);
int sg_add_mesh(sg_scene *s, const char *name, int material);
void sg_add_point_light(sg_scene *s, const char *name, wrt_v3 pos, double intensity);
void sg_set_camera(sg_scene *s, wrt_v3 eye, wrt_v3 target, double yfov_deg);
void sg_push_tri(sg_scene *s, int mesh, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 na, wrt_v3 nb, wrt_v3 nc);
void sg_push_quad(sg_scene *s, int mesh, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 d);

/* The atrium (scenegen_atrium.c). */
void scene_atrium(sg_scene *s);

/* Writes scene s as one self-contained glTF 2.0 text (one base64 buffer) into out. */
void write_gltf(const sg_scene *s, sbuf *out);

#endif
