/* render_tex.c: base-colour textures in the player (render_tex.h, docs/textures.md).
 * The .gto holds each textured material's texels (section textures); they are packed
 * into one GL_SRGB8 texture so that a texel fetch returns linear values, and each
 * vertex carries its quad's place in it, its TEXCOORD_0 (from the source map) and the
 * material's factor. The fragment shader (render.c) filters bilinearly with glTF's wrap
 * modes itself (texelFetch), since the textures share one atlas. */
#define GL_GLEXT_PROTOTYPES 1
#include "render_tex.h"

#include <stdlib.h>
#include <string.h>

#include "../common/wrt_common.h"

#define ATLAS_W 2048
#define TEX_FLOATS 11 /* x, y, w, h; s, t, wrap_s, wrap_t; factor r, g, b */

GLuint wrt_render_tex_build(const wrt_gto *g, GLuint vao, GLuint *vbo) {
    uint32_t nt = wrt_gto_texture_count(g), nm = g->nmaterials;
    float (*place)[4] = wrt_xcalloc(nm ? nm : 1, sizeof *place); /* per material */
    int *which = wrt_xcalloc(nm ? nm : 1, sizeof *which);        /* 1 + texture index */
    int x = 0, y = 0, shelf = 0;
    for (uint32_t i = 0; i < nt; i++) { /* shelves: left to right, then a new row */
        wrt_gto_texture t;
        wrt_gto_texture_get(g, i, &t);
        if (x + (int)t.w > ATLAS_W) { y += shelf; x = 0; shelf = 0; }
        place[t.material][0] = (float)x; place[t.material][1] = (float)y;
        place[t.material][2] = (float)t.w; place[t.material][3] = (float)t.h;
        which[t.material] = (int)i + 1;
        x += (int)t.w;
        if ((int)t.h > shelf) shelf = (int)t.h;
    }
    int aw = nt ? ATLAS_W : 1, ah = nt ? y + shelf : 1;
    GLuint tex;
    glCreateTextures(GL_TEXTURE_2D, 1, &tex);
    glTextureStorage2D(tex, 1, GL_SRGB8, aw, ah);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    for (uint32_t m = 0; m < nm; m++) {
        if (!which[m]) continue;
        wrt_gto_texture t;
        wrt_gto_texture_get(g, (uint32_t)which[m] - 1, &t);
        glTextureSubImage2D(tex, 0, (GLint)place[m][0], (GLint)place[m][1], (GLsizei)t.w, (GLsizei)t.h, GL_RGB,
                            GL_UNSIGNED_BYTE, t.srgb);
    }
    if (!nt) {
        static const unsigned char black[3] = {0, 0, 0};
        glTextureSubImage2D(tex, 0, 0, 0, 1, 1, GL_RGB, GL_UNSIGNED_BYTE, black);
    }
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    size_t nv = (size_t)g->nquads * 4;
    float *v = wrt_xcalloc(nv ? nv * TEX_FLOATS : TEX_FLOATS, sizeof(float));
    for (uint32_t q = 0; q < g->nquads; q++) {
        uint32_t m = g->quads[q].material;
        const wrt_gto_srcmap *sm = g->srcmap ? &g->srcmap[q] : NULL;
        if (m >= nm || !which[m] || !sm || !(sm->flags & WRT_GTO_SRC_UV)) continue;
        wrt_gto_texture t;
        wrt_gto_texture_get(g, (uint32_t)which[m] - 1, &t);
        for (int c = 0; c < 4; c++) {
            float *o = v + ((size_t)q * 4 + (size_t)c) * TEX_FLOATS;
            memcpy(o, place[m], 4 * sizeof(float));
            o[4] = sm->uv[c][0]; o[5] = sm->uv[c][1];
            o[6] = (float)t.wrap[0]; o[7] = (float)t.wrap[1];
            o[8] = t.factor[0]; o[9] = t.factor[1]; o[10] = t.factor[2];
        }
    }
    glCreateBuffers(1, vbo);
    glNamedBufferStorage(*vbo, (GLsizeiptr)((nv ? nv : 1) * TEX_FLOATS * sizeof(float)), v, 0);
    free(v);
    free(place);
    free(which);
    glVertexArrayVertexBuffer(vao, 3, *vbo, 0, TEX_FLOATS * sizeof(float));
    static const int size[3] = {4, 4, 3}, off[3] = {0, 4, 8};
    for (int a = 0; a < 3; a++) {
        glEnableVertexArrayAttrib(vao, (GLuint)(7 + a));
        glVertexArrayAttribFormat(vao, (GLuint)(7 + a), size[a], GL_FLOAT, GL_FALSE, (GLuint)(off[a] * sizeof(float)));
        glVertexArrayAttribBinding(vao, (GLuint)(7 + a), 3);
    }
    return tex;
}
