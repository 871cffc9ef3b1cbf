/* render_tex.h: the player's base-colour textures (render_tex.c, docs/textures.md), the
 * part of the renderer (render.c) that reads the .gto's textures section. Internal to
 * player/. Depends on OpenGL 4.5 core and formats/gto.h. */
#ifndef WRT_RENDER_TEX_H
#define WRT_RENDER_TEX_H

#include <GL/glcorearb.h>

#include "../formats/gto.h"

/* Packs the file's textures into one sRGB texture (shelves of a 2048-texel row) and
 * sets the vertex array's attributes 7 (the quad's texture: x, y, w, h in the atlas;
 * w 0: none), 8 (TEXCOORD_0 and the wrap modes) and 9 (baseColorFactor) from buffer
 * binding 3. Returns the texture (a 1 x 1 one when the file has none) and the buffer. */
GLuint wrt_render_tex_build(const wrt_gto *g, GLuint vao, GLuint *vbo);

#endif
