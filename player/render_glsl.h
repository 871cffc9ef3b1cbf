/* render_glsl.h: the GLSL 4.50 sources of render.c's three passes (the scene with its
 * direct light and shadow lookups, the shadow maps' depth, the tone-mapped present).
 * Depends on nothing. */
#ifndef WRT_RENDER_GLSL_H
#define WRT_RENDER_GLSL_H

extern const char *const wrt_glsl_scene_vs, *const wrt_glsl_scene_fs;
extern const char *const wrt_glsl_shadow_vs, *const wrt_glsl_shadow_fs;
extern const char *const wrt_glsl_present_vs, *const wrt_glsl_present_fs;

#endif
