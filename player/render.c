/* render.c: the OpenGL 4.5 core renderer of render.h. Three passes: (1) for each
 * enabled light whose position changed, six faces of a cube shadow map (one layer of a
 * cube-map-array depth texture per light) holding the nearest depth seen from the light; (2) the
 * scene into a float framebuffer object: per pixel, direct light from every enabled
 * light (KHR_lights_punctual: I color / d^2 cos, spot cone and range windows, the glTF
 * metallic-roughness BRDF as in common/brdf.c, shadow test) plus the indirect outgoing
 * radiance from the atlas of per-quad textures (paper section 5, "rendering"); (3) for
 * a window, a full-screen triangle tone mapping the float picture. All geometry is kept
 * relative to the centre of the scene's bounding box (double on the CPU, float on the
 * GPU) so that scenes far from the origin keep their precision.
 * A directional light (sun) has no position: its shadow map is orthographic, along its
 * direction over the scene's bounding sphere, one layer of a 2D-array depth texture
 * 4 times as fine as the cube faces (a sun's map spans the whole scene; made only when a
 * sun is lit, else 1 x 1); its direct light is intensity (lux) x colour x cos, no
 * falloff, no range.
 * Depends on OpenGL 4.5 core (prototypes from libGL), formats/gto.h. */
#define GL_GLEXT_PROTOTYPES 1
#include "render.h"

#include "../cli/cli.h"
#include "render_tex.h"
#include "render_glsl.h"
#include "../common/scene_types.h"
#include "../common/smooth.h"

#include <GL/glcorearb.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- state */

#define SHADOW_NEAR 1e-3 /* near plane of the shadow cube faces, relative to their far plane */

typedef struct slot { int x, y, res; } slot; /* atlas position of the quad's inner texels */

struct wrt_render {
    const wrt_gto *g;
    double origin[3];
    double radius;           /* of the scene's bounding sphere */
    int width, height;
    GLuint prog_scene, prog_shadow, prog_present;
    GLuint vao, vbo_geom, vbo_rect, ibo, vao_empty;
    GLuint vbo_emit;         /* per vertex: its material's emitted radiance x scale */
    GLuint ssbo_smooth;      /* per quad: its smooth source (common/smooth.h), 8 vec4 */
    int smooth;              /* 1: some quad is curved (the file's normals section) */
    GLuint vbo_tex, base_tex; /* base-colour textures (render_tex.h) */
    GLuint fbo, color, depth;
    int samples;             /* MSAA samples; > 1: draw into ms_fbo, resolve into fbo */
    GLuint ms_fbo, ms_color, ms_depth;
    GLuint shadow_tex, shadow_fbo;
    int shadow_res, shadow_layers;
    GLuint sun_tex;          /* the suns' orthographic maps, one layer per light index */
    int sun_res, sun_layers; /* 1 x 1 x 1 until a sun is drawn */
    int nlights;
    wrt_light lights[WRT_RENDER_MAX_LIGHTS];
    float scales[WRT_RENDER_MAX_LIGHTS];
    int shadow_dirty[WRT_RENDER_MAX_LIGHTS];
    /* atlas */
    GLuint atlas;
    int atlas_w, atlas_h;
    int layout_dirty;        /* a quad's resolution changed: re-pack */
    float **tex;             /* per quad staged texture (res x res x 3), NULL if none */
    int *res;                /* per quad staged resolution */
    unsigned char *dirty;    /* per quad: staged but not uploaded */
    slot *slots;
    float *scratch;          /* one bordered block */
};

const char *wrt_render_mode_name(wrt_render_mode m) {
    return m == WRT_MODE_DIRECT ? "direct" : m == WRT_MODE_INDIRECT ? "indirect" : "both";
}

/* ---------------------------------------------------------------- matrices (column-major) */

static void mat_mul(const double a[16], const double b[16], double out[16]) {
    double t[16];
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 4; r++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
            t[c * 4 + r] = s;
        }
    memcpy(out, t, sizeof t);
}

static void mat_look_at(const double eye[3], const double at[3], const double up[3], double m[16]) {
    wrt_v3 e = v3(eye[0], eye[1], eye[2]);
    wrt_v3 f = v3_norm(v3_sub(v3(at[0], at[1], at[2]), e));
    wrt_v3 s = v3_cross(f, v3(up[0], up[1], up[2]));
    if (v3_len(s) < 1e-9) s = v3_cross(f, fabs(f.y) < 0.9 ? v3(0, 1, 0) : v3(1, 0, 0));
    s = v3_norm(s);
    wrt_v3 u = v3_cross(s, f);
    double t[16] = {s.x, u.x, -f.x, 0, s.y, u.y, -f.y, 0, s.z, u.z, -f.z, 0,
                    -v3_dot(s, e), -v3_dot(u, e), v3_dot(f, e), 1};
    memcpy(m, t, sizeof t);
}

static void mat_perspective(double yfov, double aspect, double zn, double zf, double m[16]) {
    double f = 1.0 / tan(yfov / 2);
    memset(m, 0, 16 * sizeof(double));
    m[0] = f / aspect;
    m[5] = f;
    m[10] = (zf + zn) / (zn - zf);
    m[11] = -1;
    m[14] = 2 * zf * zn / (zn - zf);
}

static void mat_to_float(const double m[16], float out[16]) {
    for (int i = 0; i < 16; i++) out[i] = (float)m[i];
}

/* ---------------------------------------------------------------- GL helpers */

static GLuint compile(GLenum type, const char *src, char *log, size_t logn) {
    GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        glGetShaderInfoLog(s, (GLsizei)logn, NULL, log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

static wrt_status link_program(const char *vs, const char *fs, const char *what, GLuint *out) {
    char log[2048] = "";
    GLuint v = compile(GL_VERTEX_SHADER, vs, log, sizeof log);
    if (!v) return wrt_fail(WRT_ERR_GL, "%s vertex shader: %s", what, log);
    GLuint f = compile(GL_FRAGMENT_SHADER, fs, log, sizeof log);
    if (!f) {
        glDeleteShader(v);
        return wrt_fail(WRT_ERR_GL, "%s fragment shader: %s", what, log);
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        glDeleteProgram(p);
        return wrt_fail(WRT_ERR_GL, "%s program: %s", what, log);
    }
    *out = p;
    return WRT_OK;
}

static GLint loc(GLuint p, const char *name) { return glGetUniformLocation(p, name); }

const char *wrt_render_gl_info(void) {
    static char buf[256];
    snprintf(buf, sizeof buf, "OpenGL %s | %s", (const char *)glGetString(GL_VERSION),
             (const char *)glGetString(GL_RENDERER));
    return buf;
}

void wrt_render_finish(void) { glFinish(); }

/* ---------------------------------------------------------------- scene geometry */

void wrt_render_scene_bounds(const wrt_gto *g, double lo[3], double hi[3]) {
    for (int k = 0; k < 3; k++) { lo[k] = INFINITY; hi[k] = -INFINITY; }
    for (uint32_t q = 0; q < g->nquads; q++)
        for (int c = 0; c < 4; c++)
            for (int k = 0; k < 3; k++) {
                double x = g->quads[q].p[c][k];
                if (x < lo[k]) lo[k] = x;
                if (x > hi[k]) hi[k] = x;
            }
    if (g->nquads == 0)
        for (int k = 0; k < 3; k++) { lo[k] = -1; hi[k] = 1; }
}

void wrt_render_default_view(const wrt_gto *g, wrt_view *v) {
    memset(v, 0, sizeof *v);
    if (g->camera && g->camera->yfov > 0) {
        for (int k = 0; k < 3; k++) {
            v->eye[k] = g->camera->pos[k];
            v->target[k] = g->camera->pos[k] + g->camera->dir[k];
            v->up[k] = g->camera->up[k];
        }
        v->yfov = g->camera->yfov;
        return;
    }
    double lo[3], hi[3];
    wrt_render_scene_bounds(g, lo, hi);
    double r = 0;
    for (int k = 0; k < 3; k++) {
        v->target[k] = 0.5 * (lo[k] + hi[k]);
        r += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    }
    r = 0.5 * sqrt(r);
    v->yfov = 45 * WRT_PI / 180;
    v->eye[0] = v->target[0];
    v->eye[1] = v->target[1];
    v->eye[2] = v->target[2] + r / tan(v->yfov / 2) * 1.1;
    v->up[1] = 1;
}

void wrt_render_light_from_gto(const wrt_gto_light *in, wrt_light *out) {
    memset(out, 0, sizeof *out);
    out->type = in->type == WRT_LIGHT_SPOT ? WRT_LIGHT_SPOT
                : in->type == WRT_LIGHT_DIRECTIONAL ? WRT_LIGHT_DIRECTIONAL : WRT_LIGHT_POINT;
    memcpy(out->name, in->name, sizeof out->name);
    out->name[sizeof out->name - 1] = 0;
    out->pos = v3(in->pos[0], in->pos[1], in->pos[2]);
    out->dir = v3_norm(v3(in->dir[0], in->dir[1], in->dir[2]));
    for (int k = 0; k < 3; k++) out->color[k] = in->color[k];
    out->intensity = in->intensity;
    out->range = in->range;
    out->inner_cone = in->inner_cone;
    out->outer_cone = in->outer_cone;
}

enum { VTX_FLOATS = 3 + 3 + 2 + 4 + 2 + 3 + 4 }; /* ..., the vertex normal (location 10), the smooth weights (11) */

void wrt_render_set_emitter_scales(wrt_render *r, const float *scales) {
    const wrt_gto *g = r->g;
    size_t nv = (size_t)g->nquads * 4;
    float *e = wrt_xcalloc(nv ? 3 * nv : 3, sizeof(float));
    for (uint32_t q = 0; q < g->nquads; q++) {
        uint32_t mi = g->quads[q].material;
        if (mi >= g->nmaterials) continue;
        float s = scales ? scales[mi] : 1.0f;
        for (int c = 0; c < 4; c++)
            for (int k = 0; k < 3; k++) e[((size_t)q * 4 + (size_t)c) * 3 + (size_t)k] = g->materials[mi].emissive[k] * s;
    }
    glNamedBufferSubData(r->vbo_emit, 0, (GLsizeiptr)((nv ? nv : 1) * 3 * sizeof(float)), e);
    free(e);
}

/* The quads' smooth sources (common/smooth.h), or NULL for a file without the normals
 * section; *curved: how many quads are curved. A triangle's part is known by the source
 * map, or without one by its corners. */
static wrt_smooth_src *smooth_sources(const wrt_gto *g, int *curved) {
    *curved = 0;
    if (!g->normals || !g->nquads) return NULL;
    wrt_smooth_src *src = wrt_xmalloc((size_t)g->nquads * sizeof *src);
    for (uint32_t q = 0; q < g->nquads; q++) {
        const wrt_gto_quad *Q = &g->quads[q];
        wrt_v3 p[4];
        for (int c = 0; c < 4; c++) p[c] = v3(Q->p[c][0], Q->p[c][1], Q->p[c][2]);
        int part = g->srcmap ? g->srcmap[q].kind == WRT_ELEM_TRIANGLE : -1;
        wrt_smooth_make(p, v3(Q->n[0], Q->n[1], Q->n[2]), (const float(*)[3])g->normals[q].n, part, &src[q]);
        *curved += src[q].curved;
    }
    return src;
}

/* The shader's storage buffer of the sources: per quad its vertices relative to the
 * origin (w of the first: 1 if curved) and their normals. */
static void upload_smooth(wrt_render *r, const wrt_smooth_src *src) {
    size_t n = src ? (size_t)r->g->nquads : 1;
    float *b = wrt_xcalloc(n * 32, sizeof(float));
    for (size_t q = 0; src && q < n; q++) {
        const wrt_smooth_src *s = &src[q];
        float *o = b + q * 32;
        o[3] = (float)(s->curved != 0);
        for (int k = 0; k < s->nsrc && s->curved; k++) {
            o[4 * k + 0] = (float)(s->p[k].x - r->origin[0]);
            o[4 * k + 1] = (float)(s->p[k].y - r->origin[1]);
            o[4 * k + 2] = (float)(s->p[k].z - r->origin[2]);
            o[16 + 4 * k + 0] = (float)s->n[k].x;
            o[16 + 4 * k + 1] = (float)s->n[k].y;
            o[16 + 4 * k + 2] = (float)s->n[k].z;
        }
    }
    glCreateBuffers(1, &r->ssbo_smooth);
    glNamedBufferStorage(r->ssbo_smooth, (GLsizeiptr)(n * 32 * sizeof(float)), b, 0);
    free(b);
}

static void build_geometry(wrt_render *r) {
    const wrt_gto *g = r->g;
    int curved;
    wrt_smooth_src *src = smooth_sources(g, &curved);
    r->smooth = curved > 0;
    upload_smooth(r, curved > 0 ? src : NULL);
    if (!curved) {
        free(src);
        src = NULL;
    }
    size_t nv = (size_t)g->nquads * 4;
    float *vtx = wrt_xmalloc((nv ? nv : 1) * VTX_FLOATS * sizeof(float));
    uint32_t *idx = wrt_xmalloc(((size_t)g->nquads * 6 + 1) * sizeof(uint32_t));
    static const float corner_uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    for (uint32_t q = 0; q < g->nquads; q++) {
        const wrt_gto_quad *Q = &g->quads[q];
        const wrt_gto_material *m = Q->material < g->nmaterials ? &g->materials[Q->material] : NULL;
        for (int c = 0; c < 4; c++) {
            float *o = vtx + ((size_t)q * 4 + c) * VTX_FLOATS;
            for (int k = 0; k < 3; k++) o[k] = (float)(Q->p[c][k] - r->origin[k]);
            for (int k = 0; k < 3; k++) o[3 + k] = Q->n[k];
            o[6] = corner_uv[c][0];
            o[7] = corner_uv[c][1];
            for (int k = 0; k < 3; k++) o[8 + k] = m ? m->base_color[k] : 0.8f;
            o[11] = m ? m->metallic : 0;
            o[12] = m ? m->roughness : 1;
            o[13] = m ? (float)(m->lambertian != 0) : 1;
            for (int k = 0; k < 3; k++) o[14 + k] = g->normals ? g->normals[q].n[c][k] : Q->n[k];
            for (int k = 0; k < 4; k++) o[17 + k] = src ? (float)src[q].w[c][k] : (float)(k == 0);
        }
        static const int tri[6] = {0, 1, 2, 0, 2, 3};
        for (int k = 0; k < 6; k++) idx[q * 6 + k] = q * 4 + (uint32_t)tri[k];
    }
    free(src);
    glCreateBuffers(1, &r->vbo_geom);
    glNamedBufferStorage(r->vbo_geom, (GLsizeiptr)((nv ? nv : 1) * VTX_FLOATS * sizeof(float)), vtx, 0);
    glCreateBuffers(1, &r->vbo_rect);
    glNamedBufferStorage(r->vbo_rect, (GLsizeiptr)((nv ? nv : 1) * 4 * sizeof(float)), NULL,
                         GL_DYNAMIC_STORAGE_BIT);
    glCreateBuffers(1, &r->ibo);
    glNamedBufferStorage(r->ibo, (GLsizeiptr)(((size_t)g->nquads * 6 + 1) * sizeof(uint32_t)), idx, 0);
    free(vtx);
    free(idx);

    glCreateVertexArrays(1, &r->vao);
    GLuint a = r->vao;
    glVertexArrayVertexBuffer(a, 0, r->vbo_geom, 0, VTX_FLOATS * sizeof(float));
    glVertexArrayVertexBuffer(a, 1, r->vbo_rect, 0, 4 * sizeof(float));
    glVertexArrayElementBuffer(a, r->ibo);
    static const int sizes[5] = {3, 3, 2, 4, 2};
    int off = 0;
    for (int i = 0; i < 5; i++) {
        glEnableVertexArrayAttrib(a, (GLuint)i);
        glVertexArrayAttribFormat(a, (GLuint)i, sizes[i], GL_FLOAT, GL_FALSE, (GLuint)(off * sizeof(float)));
        glVertexArrayAttribBinding(a, (GLuint)i, 0);
        off += sizes[i];
    }
    glEnableVertexArrayAttrib(a, 5);
    glVertexArrayAttribFormat(a, 5, 4, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(a, 5, 1);
    glCreateBuffers(1, &r->vbo_emit);
    glNamedBufferStorage(r->vbo_emit, (GLsizeiptr)((nv ? nv : 1) * 3 * sizeof(float)), NULL, GL_DYNAMIC_STORAGE_BIT);
    wrt_render_set_emitter_scales(r, NULL);
    glVertexArrayVertexBuffer(a, 2, r->vbo_emit, 0, 3 * sizeof(float));
    glEnableVertexArrayAttrib(a, 6);
    glVertexArrayAttribFormat(a, 6, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(a, 6, 2);
    r->base_tex = wrt_render_tex_build(g, a, &r->vbo_tex);
    glEnableVertexArrayAttrib(a, 10);
    glVertexArrayAttribFormat(a, 10, 3, GL_FLOAT, GL_FALSE, (GLuint)(off * sizeof(float)));
    glVertexArrayAttribBinding(a, 10, 0);
    glEnableVertexArrayAttrib(a, 11);
    glVertexArrayAttribFormat(a, 11, 4, GL_FLOAT, GL_FALSE, (GLuint)((off + 3) * sizeof(float)));
    glVertexArrayAttribBinding(a, 11, 0);
    glCreateVertexArrays(1, &r->vao_empty);
}

static wrt_status make_fbo(wrt_render *r) {
    if (r->fbo) {
        glDeleteFramebuffers(1, &r->fbo);
        glDeleteTextures(1, &r->color);
        glDeleteTextures(1, &r->depth);
    }
    if (r->ms_fbo) {
        glDeleteFramebuffers(1, &r->ms_fbo);
        glDeleteTextures(1, &r->ms_color);
        glDeleteTextures(1, &r->ms_depth);
        r->ms_fbo = 0;
    }
    if (r->samples > 1) {
        /* the multisampled picture, resolved (averaged per pixel: a box filter of the
         * linear radiance) into the single-sampled one after each draw */
        glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &r->ms_color);
        glTextureStorage2DMultisample(r->ms_color, r->samples, GL_RGBA32F, r->width, r->height, GL_TRUE);
        glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &r->ms_depth);
        glTextureStorage2DMultisample(r->ms_depth, r->samples, GL_DEPTH_COMPONENT32F, r->width, r->height, GL_TRUE);
        glCreateFramebuffers(1, &r->ms_fbo);
        glNamedFramebufferTexture(r->ms_fbo, GL_COLOR_ATTACHMENT0, r->ms_color, 0);
        glNamedFramebufferTexture(r->ms_fbo, GL_DEPTH_ATTACHMENT, r->ms_depth, 0);
        GLenum st = glCheckNamedFramebufferStatus(r->ms_fbo, GL_FRAMEBUFFER);
        if (st != GL_FRAMEBUFFER_COMPLETE)
            return wrt_fail(WRT_ERR_GL, "%d-sample float framebuffer %dx%d incomplete (0x%x)", r->samples, r->width,
                            r->height, st);
    }
    glCreateTextures(GL_TEXTURE_2D, 1, &r->color);
    glTextureStorage2D(r->color, 1, GL_RGBA32F, r->width, r->height);
    glTextureParameteri(r->color, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(r->color, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(r->color, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(r->color, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glCreateTextures(GL_TEXTURE_2D, 1, &r->depth);
    glTextureStorage2D(r->depth, 1, GL_DEPTH_COMPONENT32F, r->width, r->height);
    glCreateFramebuffers(1, &r->fbo);
    glNamedFramebufferTexture(r->fbo, GL_COLOR_ATTACHMENT0, r->color, 0);
    glNamedFramebufferTexture(r->fbo, GL_DEPTH_ATTACHMENT, r->depth, 0);
    GLenum st = glCheckNamedFramebufferStatus(r->fbo, GL_FRAMEBUFFER);
    if (st != GL_FRAMEBUFFER_COMPLETE)
        return wrt_fail(WRT_ERR_GL, "float framebuffer %dx%d incomplete (0x%x)", r->width, r->height, st);
    return WRT_OK;
}

static void make_shadow_maps(wrt_render *r, int layers) {
    if (r->shadow_tex && layers <= r->shadow_layers) return;
    if (r->shadow_tex) glDeleteTextures(1, &r->shadow_tex);
    r->shadow_layers = layers < 1 ? 1 : layers;
    glCreateTextures(GL_TEXTURE_CUBE_MAP_ARRAY, 1, &r->shadow_tex);
    glTextureStorage3D(r->shadow_tex, 1, GL_DEPTH_COMPONENT32F, r->shadow_res, r->shadow_res,
                       6 * r->shadow_layers);
    /* hardware depth comparison with bilinear filtering: 2 x 2 percentage-closer filtering */
    glTextureParameteri(r->shadow_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(r->shadow_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(r->shadow_tex, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTextureParameteri(r->shadow_tex, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    glTextureParameteri(r->shadow_tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(r->shadow_tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    for (int i = 0; i < WRT_RENDER_MAX_LIGHTS; i++) r->shadow_dirty[i] = 1;
}

/* The suns' maps: `layers` layers of res x res (the texture is made again when it grows). */
static void make_sun_maps(wrt_render *r, int res, int layers) {
    if (r->sun_tex && res == r->sun_res && layers <= r->sun_layers) return;
    if (r->sun_tex) glDeleteTextures(1, &r->sun_tex);
    r->sun_res = res;
    r->sun_layers = layers < 1 ? 1 : layers;
    glCreateTextures(GL_TEXTURE_2D_ARRAY, 1, &r->sun_tex);
    glTextureStorage3D(r->sun_tex, 1, GL_DEPTH_COMPONENT32F, res, res, r->sun_layers);
    glTextureParameteri(r->sun_tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(r->sun_tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(r->sun_tex, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTextureParameteri(r->sun_tex, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    glTextureParameteri(r->sun_tex, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(r->sun_tex, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    for (int i = 0; i < WRT_RENDER_MAX_LIGHTS; i++)
        if (r->lights[i].type == WRT_LIGHT_DIRECTIONAL) r->shadow_dirty[i] = 1;
}

wrt_status wrt_render_create(const wrt_gto *g, const wrt_render_options *opt, wrt_render **out) {
    *out = NULL;
    int w = opt && opt->width > 0 ? opt->width : 640, h = opt && opt->height > 0 ? opt->height : 480;
    if (w > 16384 || h > 16384) return wrt_fail(WRT_ERR_INVALID_ARG, "picture size %dx%d too large", w, h);
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    if (major * 10 + minor < 45)
        return wrt_fail(WRT_ERR_GL, "OpenGL 4.5 needed, the context is %d.%d", major, minor);
    wrt_render *r = wrt_xcalloc(1, sizeof *r);
    r->g = g;
    r->width = w;
    r->height = h;
    r->shadow_res = opt && opt->shadow_res > 0 ? opt->shadow_res : 512;
    r->samples = opt && opt->msaa > 1 ? opt->msaa : 1;
    if (r->samples > 1) {
        GLint maxs = 1;
        glGetIntegerv(GL_MAX_SAMPLES, &maxs);
        if (r->samples > maxs) r->samples = maxs > 1 ? maxs : 1;
    }
    double lo[3], hi[3], d2 = 0;
    wrt_render_scene_bounds(g, lo, hi);
    for (int k = 0; k < 3; k++) {
        r->origin[k] = 0.5 * (lo[k] + hi[k]);
        d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
    }
    r->radius = 0.5 * sqrt(d2);
    if (!(r->radius > 0)) r->radius = 1;
    wrt_status s;
    if ((s = link_program(wrt_glsl_scene_vs, wrt_glsl_scene_fs, "scene", &r->prog_scene)) ||
        (s = link_program(wrt_glsl_shadow_vs, wrt_glsl_shadow_fs, "shadow", &r->prog_shadow)) ||
        (s = link_program(wrt_glsl_present_vs, wrt_glsl_present_fs, "present", &r->prog_present))) {
        wrt_render_destroy(r);
        return s;
    }
    build_geometry(r);
    /* a scene with curved elements gets finer shadow maps by default: the smooth surface's
     * terminator needs them (blender_smooth, Suzanne's direct light against the path tracer:
     * 14.7% at 512, 13.0% at 1024, 10.6% at 2048; a frame on llvmpipe 1.6 to 2.2 times the
     * 512 one; 96 MiB of GPU memory a point light; docs/triangles.md) */
    if (!(opt && opt->shadow_res > 0) && r->smooth) r->shadow_res = WRT_RENDER_SHADOW_RES_CURVED;
    if ((s = make_fbo(r))) {
        wrt_render_destroy(r);
        return s;
    }
    size_t nq = g->nquads ? g->nquads : 1;
    r->tex = wrt_xcalloc(nq, sizeof *r->tex);
    r->res = wrt_xcalloc(nq, sizeof *r->res);
    r->dirty = wrt_xcalloc(nq, 1);
    r->slots = wrt_xcalloc(nq, sizeof *r->slots);
    r->layout_dirty = 1;
    glCreateFramebuffers(1, &r->shadow_fbo);
    make_shadow_maps(r, 1);
    make_sun_maps(r, 1, 1);
    *out = r;
    return WRT_OK;
}

void wrt_render_destroy(wrt_render *r) {
    if (!r) return;
    glDeleteProgram(r->prog_scene);
    glDeleteProgram(r->prog_shadow);
    glDeleteProgram(r->prog_present);
    glDeleteVertexArrays(1, &r->vao);
    glDeleteVertexArrays(1, &r->vao_empty);
    glDeleteBuffers(1, &r->vbo_geom);
    glDeleteBuffers(1, &r->vbo_rect);
    glDeleteBuffers(1, &r->vbo_emit);
    glDeleteBuffers(1, &r->ssbo_smooth);
    glDeleteBuffers(1, &r->vbo_tex);
    glDeleteTextures(1, &r->base_tex);
    glDeleteBuffers(1, &r->ibo);
    glDeleteFramebuffers(1, &r->fbo);
    glDeleteFramebuffers(1, &r->shadow_fbo);
    glDeleteTextures(1, &r->color);
    glDeleteTextures(1, &r->depth);
    glDeleteFramebuffers(1, &r->ms_fbo);
    glDeleteTextures(1, &r->ms_color);
    glDeleteTextures(1, &r->ms_depth);
    glDeleteTextures(1, &r->shadow_tex);
    glDeleteTextures(1, &r->sun_tex);
    glDeleteTextures(1, &r->atlas);
    if (r->tex)
        for (uint32_t q = 0; q < r->g->nquads; q++) free(r->tex[q]);
    free(r->tex);
    free(r->res);
    free(r->dirty);
    free(r->slots);
    free(r->scratch);
    free(r);
}

wrt_status wrt_render_resize(wrt_render *r, int width, int height) {
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
        return wrt_fail(WRT_ERR_INVALID_ARG, "picture size %dx%d", width, height);
    if (width == r->width && height == r->height) return WRT_OK;
    r->width = width;
    r->height = height;
    return make_fbo(r);
}

/* ---------------------------------------------------------------- lights */

void wrt_render_set_lights(wrt_render *r, const wrt_light *lights, const float *scales, int n) {
    if (n > WRT_RENDER_MAX_LIGHTS) {
        wrt_log(WRT_LOG_WARN, "%d lights: only the first %d are drawn", n, WRT_RENDER_MAX_LIGHTS);
        n = WRT_RENDER_MAX_LIGHTS;
    }
    for (int i = 0; i < n; i++) {
        float s = scales ? scales[i] : 1.0f;
        int moved = i >= r->nlights || r->lights[i].pos.x != lights[i].pos.x ||
                    r->lights[i].pos.y != lights[i].pos.y || r->lights[i].pos.z != lights[i].pos.z ||
                    (r->scales[i] == 0) != (s == 0);
        /* a sun's map follows its direction; a change of type redraws the map */
        if (i < r->nlights && (r->lights[i].type != lights[i].type ||
                               (lights[i].type == WRT_LIGHT_DIRECTIONAL &&
                                (r->lights[i].dir.x != lights[i].dir.x || r->lights[i].dir.y != lights[i].dir.y ||
                                 r->lights[i].dir.z != lights[i].dir.z))))
            moved = 1;
        if (moved) r->shadow_dirty[i] = 1;
        r->lights[i] = lights[i];
        r->scales[i] = s;
    }
    r->nlights = n;
}

/* Distance from the light to the farthest corner of the scene: the shadow map's far plane
 * (a sun: the half-width and half-depth of its orthographic map, about the scene's centre). */
static double light_far(const wrt_render *r, const wrt_light *l) {
    if (l->type == WRT_LIGHT_DIRECTIONAL) return r->radius * 1.01 + 1e-9;
    double d = v3_len(v3_sub(l->pos, v3(r->origin[0], r->origin[1], r->origin[2]))) + r->radius;
    return d * 1.01 + 1e-9;
}

/* A sun's orthographic view-projection (column-major), points relative to the scene's
 * centre: x, y along the frame lit_sun builds from the direction d, depth along d (nearer
 * the sun, smaller), all over [-R, R]. */
static void sun_view_projection(wrt_v3 d, double R, float vpf[16]) {
    wrt_v3 up0 = fabs(d.y) < 0.99 ? v3(0, 1, 0) : v3(1, 0, 0);
    wrt_v3 rt = v3_norm(v3_cross(d, up0)), up = v3_cross(rt, d);
    double m[16] = {rt.x / R, up.x / R, d.x / R, 0, rt.y / R, up.y / R, d.y / R, 0,
                    rt.z / R, up.z / R, d.z / R, 0, 0, 0, 0, 1};
    mat_to_float(m, vpf);
}

static void draw_shadow_maps(wrt_render *r) {
    int any = 0;
    for (int i = 0; i < r->nlights; i++) any |= r->shadow_dirty[i] && r->scales[i] != 0;
    if (!any) return;
    make_shadow_maps(r, r->nlights);
    static const double dirs[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    static const double ups[6][3] = {{0, -1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}, {0, -1, 0}, {0, -1, 0}};
    glUseProgram(r->prog_shadow);
    glBindFramebuffer(GL_FRAMEBUFFER, r->shadow_fbo);
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
    glViewport(0, 0, r->shadow_res, r->shadow_res);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glBindVertexArray(r->vao);
    for (int i = 0; i < r->nlights; i++) {
        if (!r->shadow_dirty[i] || r->scales[i] == 0) continue;
        const wrt_light *l = &r->lights[i];
        double p[3] = {l->pos.x - r->origin[0], l->pos.y - r->origin[1], l->pos.z - r->origin[2]};
        double zf = light_far(r, l), zn = zf * SHADOW_NEAR; /* as in the scene shader */
        double proj[16], view[16], vp[16];
        float vpf[16];
        if (l->type == WRT_LIGHT_DIRECTIONAL) { /* one orthographic map */
            int res = r->shadow_res * 4 < 4096 ? r->shadow_res * 4 : 4096;
            make_sun_maps(r, res, r->nlights);
            sun_view_projection(v3_norm(l->dir), zf, vpf);
            glUniformMatrix4fv(loc(r->prog_shadow, "u_vp"), 1, GL_FALSE, vpf);
            glNamedFramebufferTextureLayer(r->shadow_fbo, GL_DEPTH_ATTACHMENT, r->sun_tex, 0, i);
            glViewport(0, 0, res, res);
            glClear(GL_DEPTH_BUFFER_BIT);
            glDrawElements(GL_TRIANGLES, (GLsizei)(r->g->nquads * 6), GL_UNSIGNED_INT, NULL);
            glViewport(0, 0, r->shadow_res, r->shadow_res);
            r->shadow_dirty[i] = 0;
            continue;
        }
        mat_perspective(WRT_PI / 2, 1.0, zn, zf, proj);
        for (int f = 0; f < 6; f++) {
            double at[3] = {p[0] + dirs[f][0], p[1] + dirs[f][1], p[2] + dirs[f][2]};
            mat_look_at(p, at, ups[f], view);
            mat_mul(proj, view, vp);
            mat_to_float(vp, vpf);
            glUniformMatrix4fv(loc(r->prog_shadow, "u_vp"), 1, GL_FALSE, vpf);
            glNamedFramebufferTextureLayer(r->shadow_fbo, GL_DEPTH_ATTACHMENT, r->shadow_tex, 0, 6 * i + f);
            glClear(GL_DEPTH_BUFFER_BIT);
            glDrawElements(GL_TRIANGLES, (GLsizei)(r->g->nquads * 6), GL_UNSIGNED_INT, NULL);
        }
        r->shadow_dirty[i] = 0;
    }
}

/* ---------------------------------------------------------------- atlas */

int wrt_render_set_quad_tex(wrt_render *r, int q, int res, const float *rgb) {
    if (q < 0 || (uint32_t)q >= r->g->nquads || res <= 0 || !rgb) return 0;
    size_t n = (size_t)res * res * 3;
    if (res != r->res[q] || !r->tex[q]) {
        if (res != r->slots[q].res || !r->tex[q]) r->layout_dirty = 1;
        free(r->tex[q]);
        r->tex[q] = wrt_xmalloc(n * sizeof(float));
        memcpy(r->tex[q], rgb, n * sizeof(float));
        r->res[q] = res;
        r->dirty[q] = 1;
        return 1;
    }
    if (memcmp(r->tex[q], rgb, n * sizeof(float)) == 0) return 0;
    memcpy(r->tex[q], rgb, n * sizeof(float));
    r->dirty[q] = 1;
    return 1;
}

static int cmp_by_res(const void *a, const void *b, void *ctx) {
    const int *res = ctx;
    int qa = *(const int *)a, qb = *(const int *)b;
    if (res[qa] != res[qb]) return res[qb] - res[qa];
    return qa - qb;
}

/* Shelf packing, largest first: quads of the same resolution share rows. */
static wrt_status pack_atlas(wrt_render *r) {
    uint32_t nq = r->g->nquads;
    GLint maxsz = 16384;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxsz);
    int *order = wrt_xmalloc((nq ? nq : 1) * sizeof(int));
    int *res = wrt_xmalloc((nq ? nq : 1) * sizeof(int));
    double area = 0;
    int maxres = 1;
    for (uint32_t q = 0; q < nq; q++) {
        order[q] = (int)q;
        res[q] = r->res[q] > 0 ? r->res[q] : 1;
        area += (double)(res[q] + 2) * (res[q] + 2);
        if (res[q] > maxres) maxres = res[q];
    }
    qsort_r(order, nq, sizeof(int), cmp_by_res, res);
    int w = 64;
    while (w < maxsz && ((double)w * w < area * 1.2 || w < maxres + 2)) w *= 2;
    int x = 0, y = 0, shelf = 0;
    for (uint32_t i = 0; i < nq; i++) {
        int q = order[i], s = res[q] + 2;
        if (x + s > w) { x = 0; y += shelf; shelf = 0; }
        r->slots[q].x = x + 1;
        r->slots[q].y = y + 1;
        r->slots[q].res = res[q];
        x += s;
        if (s > shelf) shelf = s;
    }
    int h = y + shelf;
    free(order);
    free(res);
    if (h < 1) h = 1;
    if (h > maxsz)
        return wrt_fail(WRT_ERR_GL, "indirect light atlas %dx%d exceeds the GPU's %d texels", w, h, (int)maxsz);
    if (r->atlas) glDeleteTextures(1, &r->atlas);
    glCreateTextures(GL_TEXTURE_2D, 1, &r->atlas);
    glTextureStorage2D(r->atlas, 1, GL_RGB32F, w, h);
    glTextureParameteri(r->atlas, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(r->atlas, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(r->atlas, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(r->atlas, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    float zero[3] = {0, 0, 0};
    glClearTexImage(r->atlas, 0, GL_RGB, GL_FLOAT, zero);
    r->atlas_w = w;
    r->atlas_h = h;
    float *rect = wrt_xmalloc(((size_t)nq * 16 + 1) * sizeof(float));
    for (uint32_t q = 0; q < nq; q++)
        for (int c = 0; c < 4; c++) {
            float *o = rect + ((size_t)q * 4 + c) * 4;
            o[0] = (float)r->slots[q].x;
            o[1] = (float)r->slots[q].y;
            o[2] = r->tex[q] ? (float)r->slots[q].res : 0.0f; /* 0: no indirect light for this quad */
            o[3] = 0;
        }
    if (nq) glNamedBufferSubData(r->vbo_rect, 0, (GLsizeiptr)((size_t)nq * 16 * sizeof(float)), rect);
    free(rect);
    free(r->scratch);
    r->scratch = wrt_xmalloc((size_t)(maxres + 2) * (maxres + 2) * 3 * sizeof(float));
    for (uint32_t q = 0; q < nq; q++) r->dirty[q] = r->tex[q] != NULL;
    r->layout_dirty = 0;
    return WRT_OK;
}

/* Copies quad q's texture into the scratch block with a one-texel border that repeats
 * the edge texels, and sends it. */
static void upload_quad(wrt_render *r, uint32_t q) {
    int n = r->res[q], s = n + 2;
    const float *src = r->tex[q];
    float *dst = r->scratch;
    for (int j = 0; j < s; j++) {
        int sj = j - 1 < 0 ? 0 : j - 1 >= n ? n - 1 : j - 1;
        for (int i = 0; i < s; i++) {
            int si = i - 1 < 0 ? 0 : i - 1 >= n ? n - 1 : i - 1;
            memcpy(dst + ((size_t)j * s + i) * 3, src + ((size_t)sj * n + si) * 3, 3 * sizeof(float));
        }
    }
    glTextureSubImage2D(r->atlas, 0, r->slots[q].x - 1, r->slots[q].y - 1, s, s, GL_RGB, GL_FLOAT, dst);
}

int wrt_render_upload(wrt_render *r) {
    if (r->layout_dirty && pack_atlas(r) != WRT_OK) return -1;
    int count = 0;
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    for (uint32_t q = 0; q < r->g->nquads; q++) {
        if (!r->dirty[q] || !r->tex[q]) continue;
        upload_quad(r, q);
        r->dirty[q] = 0;
        count++;
    }
    return count;
}

/* ---------------------------------------------------------------- drawing */

/* The view-projection matrix of v (positions relative to r->origin) and the eye. */
/* The near and far planes for an eye at `eye` (relative to the origin): the scene's
 * bounding sphere between them. */
static void near_far(const wrt_render *r, const double eye[3], double *zn, double *zf) {
    double de = v3_len(v3(eye[0], eye[1], eye[2]));
    *zf = (de + r->radius) * 1.05;
    *zn = fmax(*zf * 1e-5, (de - r->radius) * 0.5);
    if (*zn > *zf * 0.5) *zn = *zf * 1e-5;
}

static void view_projection(const wrt_render *r, const wrt_view *v, double vp[16], double eye[3]) {
    double at[3], view[16], proj[16];
    for (int k = 0; k < 3; k++) {
        eye[k] = v->eye[k] - r->origin[k];
        at[k] = v->target[k] - r->origin[k];
    }
    double zn, zf;
    near_far(r, eye, &zn, &zf);
    mat_look_at(eye, at, v->up, view);
    mat_perspective(v->yfov > 0 ? v->yfov : WRT_PI / 4, (double)r->width / r->height, zn, zf, proj);
    mat_mul(proj, view, vp);
}

int wrt_render_project(const wrt_render *r, const wrt_view *v, const double p[3], double px[2]) {
    double vp[16], eye[3], q[4];
    view_projection(r, v, vp, eye);
    double x[4] = {p[0] - r->origin[0], p[1] - r->origin[1], p[2] - r->origin[2], 1};
    for (int i = 0; i < 4; i++) q[i] = vp[i] * x[0] + vp[4 + i] * x[1] + vp[8 + i] * x[2] + vp[12 + i] * x[3];
    if (!(q[3] > 1e-9)) return 0;
    px[0] = (q[0] / q[3] * 0.5 + 0.5) * r->width;
    px[1] = (0.5 - q[1] / q[3] * 0.5) * r->height;
    return 1;
}

int wrt_render_visible(const wrt_render *r, const wrt_view *v, const double p[3], double px[2]) {
    double vp[16], eye[3], q[4];
    view_projection(r, v, vp, eye);
    double x[4] = {p[0] - r->origin[0], p[1] - r->origin[1], p[2] - r->origin[2], 1};
    for (int i = 0; i < 4; i++) q[i] = vp[i] * x[0] + vp[4 + i] * x[1] + vp[8 + i] * x[2] + vp[12 + i] * x[3];
    if (!(q[3] > 1e-9)) return 0;
    px[0] = (q[0] / q[3] * 0.5 + 0.5) * r->width;
    px[1] = (0.5 - q[1] / q[3] * 0.5) * r->height;
    int ix = (int)floor(px[0]), iy = r->height - 1 - (int)floor(px[1]);
    if (ix < 0 || iy < 0 || ix >= r->width || iy >= r->height) return 1; /* outside the picture: nothing hides it */
    float d = 1;
    glGetTextureSubImage(r->depth, 0, ix, iy, 0, 1, 1, 1, GL_DEPTH_COMPONENT, GL_FLOAT, sizeof d, &d);
    if (!(d < 1)) return 1; /* nothing drawn there */
    double zn, zf;
    near_far(r, eye, &zn, &zf);
    double zs = 2 * zn * zf / (zf + zn - (2.0 * d - 1) * (zf - zn)); /* the surface's distance along the view */
    return q[3] <= zs * 1.002;
}

int wrt_render_samples(const wrt_render *r) { return r->samples; }

void wrt_render_draw(wrt_render *r, const wrt_view *v, wrt_render_mode mode) {
    if (r->layout_dirty) wrt_render_upload(r);
    draw_shadow_maps(r);
    double eye[3], vp[16];
    view_projection(r, v, vp, eye);
    float vpf[16];
    mat_to_float(vp, vpf);

    glBindFramebuffer(GL_FRAMEBUFFER, r->ms_fbo ? r->ms_fbo : r->fbo);
    glDrawBuffer(GL_COLOR_ATTACHMENT0);
    glViewport(0, 0, r->width, r->height);
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    /* Quads are one-sided (glTF: back faces of a single-sided material are culled); a
     * doubleSided quad arrives as two back-to-back quads, 1e-4 of the scene apart, which
     * the depth buffer alone could not order. Counter-clockwise about the normal. */
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    GLuint p = r->prog_scene;
    glUseProgram(p);
    glUniformMatrix4fv(loc(p, "u_vp"), 1, GL_FALSE, vpf);
    glUniform3f(loc(p, "u_eye"), (float)eye[0], (float)eye[1], (float)eye[2]);
    glUniform1i(loc(p, "u_mode"), (int)mode);
    glUniform1i(loc(p, "u_nlights"), r->nlights);
    glUniform1f(loc(p, "u_shadow_texel"), 2.0f / (float)r->shadow_res);
    float lpos[WRT_RENDER_MAX_LIGHTS][4], lcol[WRT_RENDER_MAX_LIGHTS][4], ldir[WRT_RENDER_MAX_LIGHTS][4],
        lcone[WRT_RENDER_MAX_LIGHTS][4];
    for (int i = 0; i < r->nlights; i++) {
        const wrt_light *l = &r->lights[i];
        float s = l->intensity * r->scales[i];
        lpos[i][0] = (float)(l->pos.x - r->origin[0]);
        lpos[i][1] = (float)(l->pos.y - r->origin[1]);
        lpos[i][2] = (float)(l->pos.z - r->origin[2]);
        lpos[i][3] = (float)light_far(r, l);
        for (int k = 0; k < 3; k++) lcol[i][k] = l->color[k] * s;
        lcol[i][3] = l->type == WRT_LIGHT_SPOT ? 1.0f : l->type == WRT_LIGHT_DIRECTIONAL ? 2.0f : 0.0f;
        wrt_v3 d = v3_norm(l->dir);
        ldir[i][0] = (float)d.x;
        ldir[i][1] = (float)d.y;
        ldir[i][2] = (float)d.z;
        ldir[i][3] = l->range > 0 && l->type != WRT_LIGHT_DIRECTIONAL ? l->range : 0.0f;
        lcone[i][0] = cosf(l->outer_cone);
        lcone[i][1] = cosf(l->inner_cone);
        lcone[i][2] = (float)i;
        lcone[i][3] = s != 0 ? 1.0f : 0.0f;
    }
    if (r->nlights) {
        glUniform4fv(loc(p, "u_lpos"), r->nlights, &lpos[0][0]);
        glUniform4fv(loc(p, "u_lcol"), r->nlights, &lcol[0][0]);
        glUniform4fv(loc(p, "u_ldir"), r->nlights, &ldir[0][0]);
        glUniform4fv(loc(p, "u_lcone"), r->nlights, &lcone[0][0]);
    }
    glBindTextureUnit(0, r->shadow_tex);
    glUniform1i(loc(p, "u_shadow"), 0);
    glBindTextureUnit(2, r->sun_tex);
    glUniform1i(loc(p, "u_sun"), 2);
    glUniform1f(loc(p, "u_sun_texel"), 2.0f / (float)r->sun_res);
    glBindTextureUnit(1, r->atlas);
    glUniform1i(loc(p, "u_atlas"), 1);
    glBindTextureUnit(3, r->base_tex);
    glUniform1i(loc(p, "u_tex"), 3);
    glUniform2f(loc(p, "u_atlas_size"), (float)(r->atlas_w ? r->atlas_w : 1), (float)(r->atlas_h ? r->atlas_h : 1));
    glUniform1i(loc(p, "u_smooth"), r->smooth);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, r->ssbo_smooth);
    glBindVertexArray(r->vao);
    glDrawElements(GL_TRIANGLES, (GLsizei)(r->g->nquads * 6), GL_UNSIGNED_INT, NULL);
    if (r->ms_fbo)
        glBlitNamedFramebuffer(r->ms_fbo, r->fbo, 0, 0, r->width, r->height, 0, 0, r->width, r->height,
                               GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT, GL_NEAREST); /* depth: wrt_render_visible */
}

void wrt_render_present(wrt_render *r, int fb_w, int fb_h, float exposure_ev) {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glDrawBuffer(GL_BACK);
    glViewport(0, 0, fb_w, fb_h);
    glDisable(GL_DEPTH_TEST);
    glUseProgram(r->prog_present);
    glBindTextureUnit(0, r->color);
    glUniform1i(loc(r->prog_present, "u_img"), 0);
    glUniform1f(loc(r->prog_present, "u_scale"), exp2f(exposure_ev));
    glBindVertexArray(r->vao_empty);
    glDrawArrays(GL_TRIANGLES, 0, 3);
}

void wrt_render_read_linear(wrt_render *r, float *rgb) {
    size_t w = (size_t)r->width, h = (size_t)r->height;
    float *tmp = wrt_xmalloc(w * h * 3 * sizeof(float));
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glReadPixels(0, 0, r->width, r->height, GL_RGB, GL_FLOAT, tmp);
    for (size_t y = 0; y < h; y++) memcpy(rgb + y * w * 3, tmp + (h - 1 - y) * w * 3, w * 3 * sizeof(float));
    free(tmp);
}

void wrt_render_read_window(int fb_w, int fb_h, uint8_t *rgb) {
    size_t w = (size_t)fb_w, h = (size_t)fb_h;
    uint8_t *tmp = wrt_xmalloc(w * h * 3);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glReadBuffer(GL_BACK);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, fb_w, fb_h, GL_RGB, GL_UNSIGNED_BYTE, tmp);
    for (size_t y = 0; y < h; y++) memcpy(rgb + y * w * 3, tmp + (h - 1 - y) * w * 3, w * 3);
    free(tmp);
}

void wrt_render_tonemap(const float *rgb, size_t npixels, float exposure_ev, uint8_t *out) {
    wrt_tonemap_rgb8(rgb, npixels, exposure_ev, out);
}
