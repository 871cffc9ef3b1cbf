/* texture.h: a material's base-colour texture as every layer samples it (docs/textures.md):
 * the loader fills it from glTF's baseColorTexture (TEXCOORD_0), the bake averages it over
 * each element's UV footprint, the path tracer samples it at a hit, the player and
 * wrt-compare modulate the display with it. Texels are kept as the image's sRGB bytes (3
 * a texel, a quarter of linear floats' memory) and decoded through the texture's table,
 * sampled bilinearly with texel centres at ((i + 0.5) / w, (j + 0.5) / h) and glTF's
 * wrap modes; row 0 is the top of the image, at t = 0 (glTF's UV convention).
 * Depends on scene_types.h. */
#ifndef WRT_TEXTURE_H
#define WRT_TEXTURE_H

#include <stdint.h>

#include "scene_types.h"

enum { WRT_WRAP_REPEAT = 0, WRT_WRAP_CLAMP = 1, WRT_WRAP_MIRROR = 2 };

typedef struct wrt_texture {
    int w, h;
    int wrap[2];          /* WRT_WRAP_* along s and t */
    uint8_t *srgb;        /* w x h x 3 sRGB-encoded bytes, row 0 first (owned) */
    float lut[256];       /* the linear value of each byte (wrt_texture_srgb_table) */
    float factor[3];      /* the material's baseColorFactor (RGB) */
    float mean[3];        /* mean texel (the loader's; the material's base_color is
                             clamp(factor x mean)) */
} wrt_texture;

/* Fills lut with sRGB decoding: lut[i] = linear value of byte i. */
void wrt_texture_srgb_table(float lut[256]);
/* Bilinear texel value at texture coordinates (s, t). */
void wrt_texture_sample(const wrt_texture *t, double s, double tt, float out[3]);
/* The albedo there: clamp(factor x texel, 0, 1). */
void wrt_texture_albedo(const wrt_texture *t, double s, double tt, float out[3]);
/* TEXCOORD_0 at (u, v) of a quad that has them (bilinear in its corners' values). */
void wrt_quad_uv_at(const wrt_quad *q, double u, double v, double st[2]);
/* The (u, v) of a point on the quad's plane: exact for a parallelogram, Newton on the
 * bilinear map otherwise; clamped to [0, 1]^2. */
void wrt_quad_inverse(const wrt_quad *q, wrt_v3 p, double *u, double *v);
/* Mean albedo over quad q's (u, v) square, area-weighted: n x n midpoint samples of the
 * texture's bilinear albedo, n from the footprint's size in texels (at least 4, at most
 * 256 a side). The quad must have UVs. */
void wrt_texture_quad_mean(const wrt_texture *t, const wrt_quad *q, double rho[3]);

#endif
