/* overlay.c: the overlay of overlay.h. The 5x7 font of cli/font.h (also wrt-compare's),
 * uploaded once as an R8 texture; each rectangle or character is two triangles of one
 * vertex buffer (position, font texel or -1 for a solid fill, colour) drawn with one
 * call. */
#define GL_GLEXT_PROTOTYPES 1
#include "overlay.h"
#include "../cli/font.h"

#include <GL/glcorearb.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CELL_W WRT_FONT_CELL_W
#define CELL_H WRT_FONT_CELL_H
#define NGLYPH WRT_FONT_NGLYPH

const unsigned char *wrt_overlay_glyph(int c) { return wrt_font[wrt_font_index(c)]; }

static const char *vs_src =
    "#version 450 core\n"
    "layout(location=0) in vec2 a_p;\n"
    "layout(location=1) in vec2 a_t;\n"
    "layout(location=2) in vec4 a_c;\n"
    "uniform vec2 u_fb;\n"
    "out vec2 v_t; out vec4 v_c;\n"
    "void main() {\n"
    "  v_t = a_t; v_c = a_c;\n"
    "  gl_Position = vec4(a_p.x / u_fb.x * 2.0 - 1.0, 1.0 - a_p.y / u_fb.y * 2.0, 0.0, 1.0);\n"
    "}\n";
static const char *fs_src =
    "#version 450 core\n"
    "in vec2 v_t; in vec4 v_c;\n"
    "uniform sampler2D u_font;\n"
    "out vec4 o_c;\n"
    "void main() {\n"
    "  float a = v_t.x < 0.0 ? 1.0 : texelFetch(u_font, ivec2(floor(v_t)), 0).r;\n"
    "  o_c = vec4(v_c.rgb, v_c.a * a);\n"
    "}\n";

typedef struct vtx { float x, y, u, v, c[4]; } vtx;

struct wrt_overlay {
    GLuint prog, vao, vbo, tex;
    size_t vbo_cap;
    vtx *v;
    size_t n, cap;
    int fb_w, fb_h;
};

static GLuint compile(GLenum type, const char *src) {
    GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[1024];
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        wrt_fail(WRT_ERR_GL, "overlay shader: %s", log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

wrt_status wrt_overlay_create(wrt_overlay **out) {
    *out = NULL;
    GLuint vs = compile(GL_VERTEX_SHADER, vs_src), fs = vs ? compile(GL_FRAGMENT_SHADER, fs_src) : 0;
    if (!vs || !fs) {
        if (vs) glDeleteShader(vs);
        return WRT_ERR_GL;
    }
    wrt_overlay *o = wrt_xcalloc(1, sizeof *o);
    o->prog = glCreateProgram();
    glAttachShader(o->prog, vs);
    glAttachShader(o->prog, fs);
    glLinkProgram(o->prog);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(o->prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        glDeleteProgram(o->prog);
        free(o);
        return wrt_fail(WRT_ERR_GL, "overlay shader: link failed");
    }
    /* the font texture: glyph g's cell at x = g * CELL_W, rows top to bottom */
    int tw = NGLYPH * CELL_W, th = CELL_H;
    unsigned char *px = wrt_xcalloc((size_t)tw * th, 1);
    for (int g = 0; g < NGLYPH; g++)
        for (int r = 0; r < 8; r++)
            for (int b = 0; b < 5; b++)
                if (wrt_font[g][r] & (1 << (4 - b))) px[(size_t)(r + 1) * tw + g * CELL_W + b] = 255;
    glCreateTextures(GL_TEXTURE_2D, 1, &o->tex);
    glTextureStorage2D(o->tex, 1, GL_R8, tw, th);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTextureSubImage2D(o->tex, 0, 0, 0, tw, th, GL_RED, GL_UNSIGNED_BYTE, px);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    free(px);
    glCreateVertexArrays(1, &o->vao);
    glCreateBuffers(1, &o->vbo);
    glVertexArrayVertexBuffer(o->vao, 0, o->vbo, 0, sizeof(vtx));
    glEnableVertexArrayAttrib(o->vao, 0);
    glEnableVertexArrayAttrib(o->vao, 1);
    glEnableVertexArrayAttrib(o->vao, 2);
    glVertexArrayAttribFormat(o->vao, 0, 2, GL_FLOAT, GL_FALSE, offsetof(vtx, x));
    glVertexArrayAttribFormat(o->vao, 1, 2, GL_FLOAT, GL_FALSE, offsetof(vtx, u));
    glVertexArrayAttribFormat(o->vao, 2, 4, GL_FLOAT, GL_FALSE, offsetof(vtx, c));
    for (int k = 0; k < 3; k++) glVertexArrayAttribBinding(o->vao, (GLuint)k, 0);
    *out = o;
    return WRT_OK;
}

void wrt_overlay_destroy(wrt_overlay *o) {
    if (!o) return;
    glDeleteProgram(o->prog);
    glDeleteVertexArrays(1, &o->vao);
    glDeleteBuffers(1, &o->vbo);
    glDeleteTextures(1, &o->tex);
    free(o->v);
    free(o);
}

void wrt_overlay_begin(wrt_overlay *o, int fb_w, int fb_h) {
    o->n = 0;
    o->fb_w = fb_w;
    o->fb_h = fb_h;
}

static void quad(wrt_overlay *o, float x, float y, float w, float h, float u0, float v0, float u1, float v1,
                 const float c[4]) {
    if (o->n + 6 > o->cap) {
        o->cap = o->cap ? 2 * o->cap : 1536;
        o->v = wrt_xrealloc(o->v, o->cap * sizeof *o->v);
    }
    const float xs[6] = {x, x + w, x + w, x, x + w, x}, ys[6] = {y, y, y + h, y, y + h, y + h};
    const float us[6] = {u0, u1, u1, u0, u1, u0}, vs[6] = {v0, v0, v1, v0, v1, v1};
    for (int k = 0; k < 6; k++) {
        vtx *t = &o->v[o->n++];
        t->x = xs[k]; t->y = ys[k]; t->u = us[k]; t->v = vs[k];
        memcpy(t->c, c, sizeof t->c);
    }
}

void wrt_overlay_rect(wrt_overlay *o, float x, float y, float w, float h, const float rgba[4]) {
    quad(o, x, y, w, h, -1, -1, -1, -1, rgba);
}

void wrt_overlay_measure(const char *s, int scale, float *w, float *h) {
    int col = 0, cols = 0, lines = 1;
    for (; *s; s++) {
        if (*s == '\n') { lines++; col = 0; continue; }
        if (++col > cols) cols = col;
    }
    *w = (float)(cols * CELL_W * scale);
    *h = (float)(lines * CELL_H * scale);
}

float wrt_overlay_text(wrt_overlay *o, float x, float y, int scale, const float rgba[4], const char *s) {
    float cx = x, cy = y, widest = 0;
    for (; *s; s++) {
        if (*s == '\n') { cx = x; cy += CELL_H * scale; continue; }
        int g = wrt_font_index((unsigned char)*s);
        if (g) quad(o, cx, cy, (float)(CELL_W * scale), (float)(CELL_H * scale), (float)(g * CELL_W), 0,
                    (float)((g + 1) * CELL_W), CELL_H, rgba);
        cx += CELL_W * scale;
        if (cx - x > widest) widest = cx - x;
    }
    return widest;
}

void wrt_overlay_draw(wrt_overlay *o) {
    if (!o->n) return;
    size_t bytes = o->n * sizeof(vtx);
    if (bytes > o->vbo_cap) {
        glNamedBufferData(o->vbo, (GLsizeiptr)bytes, o->v, GL_STREAM_DRAW);
        o->vbo_cap = bytes;
    } else {
        glNamedBufferSubData(o->vbo, 0, (GLsizeiptr)bytes, o->v);
    }
    glViewport(0, 0, o->fb_w, o->fb_h);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE); /* the scene pass culls back faces; these quads wind either way */
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(o->prog);
    glUniform2f(glGetUniformLocation(o->prog, "u_fb"), (float)o->fb_w, (float)o->fb_h);
    glBindTextureUnit(0, o->tex);
    glUniform1i(glGetUniformLocation(o->prog, "u_font"), 0);
    glBindVertexArray(o->vao);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)o->n);
    glDisable(GL_BLEND);
}
