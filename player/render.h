/* render.h: the player's OpenGL 4.5 core renderer (the display of paper section 5).
 * Draws the baked scene's quads as triangles with direct light computed per pixel from
 * every enabled point or spot light (KHR_lights_punctual falloff, the glTF
 * metallic-roughness BRDF of common/brdf.h ported to GLSL, a cube shadow map per light),
 * plus indirect light read bilinearly from an atlas of per-quad textures of outgoing
 * radiance (one texel of border around each quad, copied from its edge, so filtering
 * never mixes two quads). The picture is linear radiance in a float framebuffer object;
 * it is read back as such (EXR) or tone mapped (exposure, Reinhard, sRGB) for a PNG or
 * the window. Independent of the relighting core: the caller hands it the textures.
 * Depends on OpenGL 4.5 core (a current context, see platform.h), formats/gto.h.
 * Not thread-safe: call from the thread whose context is current. */
#ifndef WRT_RENDER_H
#define WRT_RENDER_H

#include <stdint.h>
#include "../formats/gto.h"

#define WRT_RENDER_MAX_LIGHTS 16
#define WRT_RENDER_SHADOW_RES_CURVED 2048 /* the default shadow map size of a scene with curved elements */

typedef enum wrt_render_mode {
    WRT_MODE_BOTH = 0,     /* direct + indirect */
    WRT_MODE_DIRECT = 1,   /* direct only (shadowed lights) */
    WRT_MODE_INDIRECT = 2, /* indirect only (the baked transport) */
    WRT_MODE_COUNT
} wrt_render_mode;
const char *wrt_render_mode_name(wrt_render_mode m);

typedef struct wrt_view {
    double eye[3], target[3], up[3]; /* world space */
    double yfov;                     /* vertical field of view, radians */
} wrt_view;

typedef struct wrt_render_options {
    int width, height;  /* size of the picture (framebuffer object) */
    int shadow_res;     /* cube shadow map face size; 0 = 512, or WRT_RENDER_SHADOW_RES_CURVED
                         * for a file with curved elements (its normals section) */
    int msaa;           /* multisample anti-aliasing samples per pixel; 0 or 1 = none (capped
                         * at what the GPU allows) */
} wrt_render_options;

typedef struct wrt_render wrt_render;

/* Builds the vertex buffers (positions relative to the centre of the scene's bounding
 * box, computed in double), the shaders and the framebuffer. `g` must outlive the
 * renderer. Errors: WRT_ERR_GL (shader compilation, incomplete framebuffer, no 4.5),
 * WRT_ERR_INVALID_ARG (size). */
wrt_status wrt_render_create(const wrt_gto *g, const wrt_render_options *opt, wrt_render **out);
void wrt_render_destroy(wrt_render *r); /* NULL is a no-op */

/* Changes the picture size (window resize). */
wrt_status wrt_render_resize(wrt_render *r, int width, int height);

/* Sets the lights (copied; at most WRT_RENDER_MAX_LIGHTS are drawn). scales[i]
 * multiplies light i, 0 switches it off; scales may be NULL. Shadow maps of the lights
 * that changed are redrawn at the next draw. */
void wrt_render_set_lights(wrt_render *r, const wrt_light *lights, const float *scales, int n);

/* Stages quad q's texture of outgoing indirect radiance: res x res linear RGB texels,
 * row j (v) after row j-1, texel i of a row at u in [i/res, (i+1)/res) (as
 * wrt_relight_tex). Copied. Returns 1 if it differs from what was staged before. */
int wrt_render_set_quad_tex(wrt_render *r, int q, int res, const float *rgb);
/* The emissive surfaces' radiance drawn in the direct pass (docs/emitters.md): each
 * material's emission times scales[material] (NULL: all 1, as after create). */
void wrt_render_set_emitter_scales(wrt_render *r, const float *scales);
/* Sends the staged textures that changed to the GPU (re-packs the atlas if a quad's
 * resolution changed). Returns the number of quads uploaded, or -1 with an error
 * (atlas larger than the GPU allows: wrt_last_error()). */
int wrt_render_upload(wrt_render *r);

/* Draws the picture (shadow maps first where lights changed) into the framebuffer object. */
void wrt_render_draw(wrt_render *r, const wrt_view *v, wrt_render_mode mode);
/* Where world point p lands in the picture: pixels from the top-left corner; 0 if it
 * is behind the eye. */
int wrt_render_project(const wrt_render *r, const wrt_view *v, const double p[3], double px[2]);
/* As wrt_render_project, and 1 only if nothing drawn in the last picture (its depth
 * buffer) lies in front of p: the overlay's marks in the scene, not through its walls.
 * Reads one depth value back from the GPU (a short stall): for a few points a frame. */
int wrt_render_visible(const wrt_render *r, const wrt_view *v, const double p[3], double px[2]);
/* The samples per pixel in use (1 = no MSAA). */
int wrt_render_samples(const wrt_render *r);
/* Tone maps the picture into the current default framebuffer (a window) of fb_w x fb_h. */
void wrt_render_present(wrt_render *r, int fb_w, int fb_h, float exposure_ev);
/* Reads the picture back: width x height linear RGB floats, the top row first. */
void wrt_render_read_linear(wrt_render *r, float *rgb);
/* Reads the default framebuffer's back buffer (a window): 8-bit RGB, the top row first. */
void wrt_render_read_window(int fb_w, int fb_h, uint8_t *rgb);
/* Blocks until the GPU is done (timings). */
void wrt_render_finish(void);

/* The display curve, on the CPU, the same as the shader of wrt_render_present:
 * x * 2^ev, Reinhard x / (1 + x) per channel, then sRGB encoding (wrt_tonemap_rgb8 of
 * cli/cli.h, which every tool's PNG uses). */
void wrt_render_tonemap(const float *rgb, size_t npixels, float exposure_ev, uint8_t *out);

/* "OpenGL 4.5 (Core Profile) Mesa ... | llvmpipe ..." of the current context. */
const char *wrt_render_gl_info(void);

/* The default camera: the file's, or one framing the scene's bounding box. */
void wrt_render_default_view(const wrt_gto *g, wrt_view *v);
/* A light of the file as the scene struct holds it. */
void wrt_render_light_from_gto(const wrt_gto_light *in, wrt_light *out);
/* The scene's bounding box. */
void wrt_render_scene_bounds(const wrt_gto *g, double lo[3], double hi[3]);

#endif
