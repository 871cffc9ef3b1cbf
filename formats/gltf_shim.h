/* gltf_shim.h: the C face of the glTF 2.0 reader (gltf_shim.cpp, on tinygltf).
 * It parses a .gltf (JSON) or .glb held in memory, validates every accessor it
 * reads against its bufferView and buffer, flattens the default scene's node
 * hierarchy (TRS and matrices, nested) and hands back plain C arrays: per
 * primitive instance the world-space positions and the triangle index list,
 * the raw material factors with the mean of each texture, the KHR_lights_punctual
 * lights with world transforms and the first perspective camera. Pairing the
 * triangles into quads and everything else is scene.c's work. No C++ type
 * crosses this header and no exception leaves the shim. */
#ifndef WRT_GLTF_SHIM_H
#define WRT_GLTF_SHIM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif
#include "../common/wrt_common.h"

/* One primitive as placed in the world by one node. */
typedef struct wrt_gltf_prim {
    int mesh, prim, node;  /* glTF indices */
    int material;          /* -1: none (the glTF default material applies) */
    double *pos;           /* 3 * npos doubles, world space */
    size_t npos;
    uint32_t *idx;         /* 3 * ntri vertex indices, each < npos (generated if non-indexed);
                              in the world's front-face winding (see mirrored) */
    size_t ntri;
    float *uv;             /* 2 * npos floats: TEXCOORD_0 per vertex; NULL if the primitive has none */
    float *nrm;            /* 3 * npos floats: NORMAL per vertex in world space (by the inverse
                              transpose of the node's transform), unit; NULL if none */
    int mirrored;          /* 1: the node's world transform has a negative determinant; glTF
                              then flips the winding, so each triangle's 2nd and 3rd indices
                              are swapped here and the front faces stay counter-clockwise */
} wrt_gltf_prim;

/* A material's raw values; texture means are over all texels, in linear space
 * (base color and emissive texels are decoded from sRGB first). */
typedef struct wrt_gltf_material {
    char name[64];
    double base_color[4];
    double metallic, roughness;
    double emissive[3];
    double emissive_strength; /* KHR_materials_emissive_strength (1 without it) */
    int has_base_tex, has_mr_tex, has_emissive_tex; /* 1 if the texture was decoded */
    int double_sided;        /* material.doubleSided */
    double base_tex_mean[4];
    double mr_tex_mean[3];   /* R, G (roughness), B (metallic) */
    double emissive_tex_mean[3];
    /* baseColorTexture on TEXCOORD_0, kept for per-element albedo (docs/textures.md):
     * sRGB texels (w x h x 3 bytes, row 0 first, owned; NULL if none or on another
     * TEXCOORD) and the sampler's wrap modes (0 repeat, 1 clamp, 2 mirror) */
    unsigned char *base_tex; int base_tex_w, base_tex_h, base_tex_wrap[2];
} wrt_gltf_material;

enum { WRT_GLTF_LIGHT_POINT = 0, WRT_GLTF_LIGHT_SPOT = 1, WRT_GLTF_LIGHT_DIRECTIONAL = 2,
       WRT_GLTF_LIGHT_OTHER = 3 };

typedef struct wrt_gltf_light {
    int type;                /* WRT_GLTF_LIGHT_* */
    char name[64];
    int node;
    double pos[3], dir[3];   /* world origin of the node, normalized -Z axis */
    double color[3], intensity, range, inner_cone, outer_cone;
} wrt_gltf_light;

typedef struct wrt_gltf_camera {
    int present;             /* 0: the scene has no perspective camera node */
    int node;
    double pos[3], dir[3], up[3];
    double yfov, aspect, znear, zfar;
} wrt_gltf_camera;

typedef struct wrt_gltf_data {
    wrt_gltf_prim *prims; size_t nprims;
    wrt_gltf_material *materials; size_t nmaterials;
    wrt_gltf_light *lights; size_t nlights;
    wrt_gltf_camera camera;
    char (*mesh_names)[64]; size_t nmeshes;
    char *warnings;          /* warnings, one a line, "" if none (owned) */
    char *ignored;           /* fields the bake does not use, "; "-separated path patterns
                                with a count where more than one, "" if none (owned) */
    char *files;             /* external files read (buffers, images), one a line (owned) */
} wrt_gltf_data;

/* Parses `size` bytes (JSON text, or GLB when they start with "glTF"). External
 * buffers and images are resolved against `base_dir` ("" = current directory) and must
 * lie inside it (links resolved) unless `allow_outside`: a uri that is absolute, has a
 * scheme or a ".." segment is refused with its JSON path. JSON nested deeper than 128
 * levels is refused before it is parsed.
 * `label` (the file name) prefixes every error message. On failure returns
 * WRT_ERR_PARSE / WRT_ERR_UNSUPPORTED / WRT_ERR_IO with wrt_last_error() naming
 * what and where, and leaves *out zeroed. Free with wrt_gltf_free. Thread-safe
 * (no shared state). */
wrt_status wrt_gltf_read(const void *data, size_t size, const char *base_dir, const char *label,
                         int allow_outside, wrt_gltf_data *out);
void wrt_gltf_free(wrt_gltf_data *d);

#ifdef __cplusplus
}
#endif
#endif
