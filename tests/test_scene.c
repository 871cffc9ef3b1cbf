/* test_scene.c: tests of the glTF scene loader (formats/scene.c, formats/gltf_shim.cpp).
 * Each case writes a small glTF (JSON with a base64 data URI, or a GLB, or files in a
 * temporary folder) whose expected quads, transforms, materials, lights and camera are
 * known by construction, loads it and compares. The bad-input cases check the status
 * and a piece of the message that names what and where. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include "tests/test.h"
#include "formats/scene.h"
#include "common/texture.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[256];

/* ---------------------------------------------------------------- building glTF text */

static char *b64(const void *data, size_t n) {
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const unsigned char *d = data;
    char *out = malloc(4 * ((n + 2) / 3) + 1), *o = out;
    for (size_t i = 0; i < n; i += 3) {
        unsigned v = (unsigned)d[i] << 16 | (i + 1 < n ? (unsigned)d[i + 1] << 8 : 0) |
                     (i + 2 < n ? d[i + 2] : 0);
        *o++ = tab[(v >> 18) & 63];
        *o++ = tab[(v >> 12) & 63];
        *o++ = i + 1 < n ? tab[(v >> 6) & 63] : '=';
        *o++ = i + 2 < n ? tab[v & 63] : '=';
    }
    *o = 0;
    return out;
}

static char *fmt(const char *f, ...) __attribute__((format(printf, 1, 2)));
static char *fmt(const char *f, ...) {
    va_list ap;
    va_start(ap, f);
    char *s = NULL;
    if (vasprintf(&s, f, ap) < 0) s = NULL;
    va_end(ap);
    return s;
}

/* Replaces the first `from` in s (which must be there) by `to`; frees s. */
static char *replace(char *s, const char *from, const char *to) {
    char *at = strstr(s, from);
    CHECK(at != NULL, "'%s' not in the generated glTF", from);
    if (!at) return s;
    char *r = fmt("%.*s%s%s", (int)(at - s), s, to, at + strlen(from));
    free(s);
    return r;
}

typedef struct spec {
    const float *pos;
    int nv;
    const uint32_t *idx; /* NULL: non-indexed */
    int ni;
    const char *prim_extra;  /* appended inside the primitive, e.g. ",\"material\":0" */
    const char *nodes;       /* JSON array; default one node with mesh 0 */
    const char *roots;       /* JSON array of the scene's root nodes; default [0] */
    const char *top;         /* extra top-level members, each followed by a comma */
    const char *buffer_uri;  /* default: a data URI with the bytes */
} spec;

/* The buffer holds positions then indices. */
static size_t spec_bytes(const spec *sp, unsigned char **out) {
    size_t n = (size_t)sp->nv * 12 + (size_t)(sp->idx ? sp->ni : 0) * 4;
    unsigned char *b = malloc(n ? n : 1);
    memcpy(b, sp->pos, (size_t)sp->nv * 12);
    if (sp->idx) memcpy(b + (size_t)sp->nv * 12, sp->idx, (size_t)sp->ni * 4);
    *out = b;
    return n;
}

static char *gltf_text(const spec *sp) {
    unsigned char *bytes;
    size_t n = spec_bytes(sp, &bytes);
    char *data = b64(bytes, n);
    char *uri = sp->buffer_uri ? fmt(",\"uri\":\"%s\"", sp->buffer_uri)
                               : fmt(",\"uri\":\"data:application/octet-stream;base64,%s\"", data);
    if (sp->buffer_uri && strcmp(sp->buffer_uri, "GLB") == 0) {
        free(uri);
        uri = fmt("%s", "");
    }
    char *idx_acc = sp->idx ? fmt(",{\"bufferView\":1,\"componentType\":5125,\"count\":%d,\"type\":\"SCALAR\"}", sp->ni)
                            : fmt("%s", "");
    char *idx_bv = sp->idx ? fmt(",{\"buffer\":0,\"byteOffset\":%d,\"byteLength\":%d}", sp->nv * 12, sp->ni * 4)
                           : fmt("%s", "");
    char *s = fmt("{\"asset\":{\"version\":\"2.0\"},%s\"scene\":0,\"scenes\":[{\"nodes\":%s}],"
                  "\"nodes\":%s,"
                  "\"meshes\":[{\"name\":\"plane\",\"primitives\":[{\"attributes\":{\"POSITION\":0}%s%s}]}],"
                  "\"buffers\":[{\"byteLength\":%zu%s}],"
                  "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%d}%s],"
                  "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":%d,\"type\":\"VEC3\"}%s]}",
                  sp->top ? sp->top : "", sp->roots ? sp->roots : "[0]",
                  sp->nodes ? sp->nodes : "[{\"mesh\":0}]", sp->idx ? ",\"indices\":1" : "",
                  sp->prim_extra ? sp->prim_extra : "", n, uri, sp->nv * 12, idx_bv, sp->nv, idx_acc);
    free(bytes);
    free(data);
    free(uri);
    free(idx_acc);
    free(idx_bv);
    return s;
}

static wrt_status load_text(const char *text, int drop_bad, wrt_scene *s) {
    wrt_load_options opt = {.drop_bad = drop_bad};
    return wrt_scene_load_memory(text, strlen(text), tmpdir, &opt, s);
}

static wrt_status load_spec(const spec *sp, int drop_bad, wrt_scene *s) {
    char *t = gltf_text(sp);
    wrt_status st = load_text(t, drop_bad, s);
    free(t);
    return st;
}

static void write_file(const char *name, const void *data, size_t n) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL, "cannot write %s", path);
    if (!f) return;
    fwrite(data, 1, n, f);
    fclose(f);
}

/* ---------------------------------------------------------------- geometry helpers */

static const float unit_square[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
static const uint32_t square_idx[] = {0, 1, 2, 0, 2, 3};

static int has_corner(const wrt_quad *q, double x, double y, double z, double tol) {
    for (int i = 0; i < 4; i++)
        if (fabs(q->p[i].x - x) <= tol && fabs(q->p[i].y - y) <= tol && fabs(q->p[i].z - z) <= tol)
            return 1;
    return 0;
}

/* Checks a loaded unit square: 1 quad, the 4 corners, CCW about `nz` (+1 or -1 along z). */
static void check_unit_square(const wrt_scene *s, double nz) {
    CHECK(s->nquads == 1, "nquads %d", s->nquads);
    if (s->nquads != 1) return;
    const wrt_quad *q = &s->quads[0];
    CHECK(has_corner(q, 0, 0, 0, 1e-9) && has_corner(q, 1, 0, 0, 1e-9) && has_corner(q, 1, 1, 0, 1e-9) &&
              has_corner(q, 0, 1, 0, 1e-9),
          "corners");
    wrt_v3 c = v3_cross(v3_sub(q->p[1], q->p[0]), v3_sub(q->p[3], q->p[0]));
    CHECK(c.z * nz > 0, "(p1-p0)x(p3-p0) = (%g %g %g), expected along z %g", c.x, c.y, c.z, nz);
    CHECK_NEAR(q->n.z, nz, 1e-12, "normal");
    CHECK_NEAR(q->area, 1.0, 1e-12, "area");
    CHECK(q->parallelogram == 1, "parallelogram");
    CHECK_NEAR(v3_dot(q->t, q->b), 0.0, 1e-12, "t.b");
    CHECK_NEAR(v3_dot(v3_cross(q->t, q->b), q->n), 1.0, 1e-12, "t x b = n");
    CHECK(s->nproblems == 0, "nproblems %d", s->nproblems);
    CHECK(s->ntriangles == 2, "ntriangles %d", s->ntriangles);
}

/* ---------------------------------------------------------------- good input */

static void quad_shared_vertices(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    wrt_scene s;
    wrt_status st = load_spec(&sp, 0, &s);
    CHECK(st == WRT_OK, "%s", wrt_last_error());
    check_unit_square(&s, 1);
    CHECK(s.nmaterials == 1 && s.quads[0].material == 0, "default material added");
    CHECK(strcmp(s.names[s.quads[0].name], "plane") == 0, "mesh name");
    wrt_scene_free(&s);
}

static void quad_separate_vertices(void) {
    const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 1, 1, 0, 0, 1, 0, 0, 0, 0};
    const uint32_t idx[] = {0, 1, 2, 5, 3, 4};
    spec sp = {.pos = pos, .nv = 6, .idx = idx, .ni = 6, .prim_extra = 0};
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    check_unit_square(&s, 1);
    wrt_scene_free(&s);
}

static void quad_non_indexed(void) {
    const float pos[] = {1, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 1, 1, 0};
    spec sp = {.pos = pos, .nv = 6, .idx = NULL, .ni = 0, .prim_extra = 0};
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    check_unit_square(&s, 1);
    wrt_scene_free(&s);
}

static void quad_reversed_order(void) {
    /* both triangles wound clockwise seen from +z: the front face looks down -z */
    const uint32_t idx[] = {3, 2, 0, 2, 1, 0};
    spec sp = {.pos = unit_square, .nv = 4, .idx = idx, .ni = 6, .prim_extra = 0};
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    check_unit_square(&s, -1);
    wrt_scene_free(&s);
}

static void trapezoid(void) {
    const float pos[] = {0, 0, 0, 4, 0, 0, 3, 2, 0, 1, 2, 0};
    const uint32_t idx[] = {1, 2, 0, 2, 3, 0};
    spec sp = {.pos = pos, .nv = 4, .idx = idx, .ni = 6, .prim_extra = 0};
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1, "nquads %d", s.nquads);
    if (s.nquads == 1) {
        const wrt_quad *q = &s.quads[0];
        CHECK(q->parallelogram == 0, "a trapezoid is not a parallelogram");
        CHECK_NEAR(q->area, 6.0, 1e-9, "area (4+2)/2*2");
        CHECK_NEAR(q->n.z, 1.0, 1e-12, "normal");
        /* the bilinear Jacobian integrates to the area */
        double sum = 0;
        for (int i = 0; i < 16; i++)
            for (int j = 0; j < 16; j++) sum += wrt_quad_jacobian(q, (i + 0.5) / 16, (j + 0.5) / 16);
        CHECK_NEAR(sum / 256, 6.0, 1e-9, "mean Jacobian");
        /* corners are consecutive around the outline */
        for (int i = 0; i < 4; i++) {
            wrt_v3 e1 = v3_sub(q->p[(i + 1) % 4], q->p[i]), e2 = v3_sub(q->p[(i + 2) % 4], q->p[(i + 1) % 4]);
            CHECK(v3_cross(e1, e2).z > 0, "convex CCW turn at corner %d", i + 1);
        }
    }
    wrt_scene_free(&s);
}

static void grid_pairing(void) {
    /* 3x2 cells of a 4x3 vertex grid, triangles listed in a scrambled order with alternating
     * diagonals: every cell must come back as one unit square */
    float pos[12 * 3];
    for (int y = 0; y < 3; y++)
        for (int x = 0; x < 4; x++) {
            pos[3 * (y * 4 + x)] = (float)x;
            pos[3 * (y * 4 + x) + 1] = (float)y;
            pos[3 * (y * 4 + x) + 2] = 0;
        }
    uint32_t idx[12 * 3];
    int nt = 0;
    for (int y = 0; y < 2; y++)
        for (int x = 0; x < 3; x++) {
            uint32_t a = (uint32_t)(y * 4 + x), b = a + 1, c = a + 5, d = a + 4;
            if ((x + y) % 2) {
                uint32_t t1[3] = {a, b, c}, t2[3] = {a, c, d};
                memcpy(&idx[3 * nt++], t1, sizeof t1);
                memcpy(&idx[3 * nt++], t2, sizeof t2);
            } else {
                uint32_t t1[3] = {b, c, d}, t2[3] = {d, a, b};
                memcpy(&idx[3 * nt++], t2, sizeof t2);
                memcpy(&idx[3 * nt++], t1, sizeof t1);
            }
        }
    /* scramble: reverse the triangle order */
    for (int i = 0; i < nt / 2; i++)
        for (int k = 0; k < 3; k++) {
            uint32_t t = idx[3 * i + k];
            idx[3 * i + k] = idx[3 * (nt - 1 - i) + k];
            idx[3 * (nt - 1 - i) + k] = t;
        }
    spec sp = {.pos = pos, .nv = 12, .idx = idx, .ni = nt * 3, .prim_extra = 0};
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 6, "nquads %d", s.nquads);
    for (int i = 0; i < s.nquads; i++) {
        CHECK_NEAR(s.quads[i].area, 1.0, 1e-12, "quad %d is a unit cell", i);
        CHECK(s.quads[i].parallelogram, "quad %d parallelogram", i);
    }
    CHECK(s.nproblems == 0, "nproblems %d", s.nproblems);
    wrt_scene_free(&s);
}

static void grid_uniform_shuffled(void) {
    /* 5x4 cells of 2 x 1 rectangles, all split along the same diagonal, triangles in a
     * shuffled order, every cell's triangles with their own vertices */
    enum { NX = 5, NY = 4, NT = NX * NY * 2 };
    float pos[NT * 9];
    uint32_t idx[NT * 3];
    int order[NT];
    for (int i = 0; i < NT; i++) order[i] = i;
    unsigned r = 12345;
    for (int i = NT - 1; i > 0; i--) {
        r = r * 1103515245u + 12345u;
        int j = (int)((r >> 8) % (unsigned)(i + 1)), t = order[i];
        order[i] = order[j];
        order[j] = t;
    }
    for (int c = 0; c < NX * NY; c++) {
        float x = (float)(2 * (c % NX)), y = (float)(c / NX);
        float tri[2][9] = {{x, y, 0, x + 2, y, 0, x + 2, y + 1, 0}, {x, y, 0, x + 2, y + 1, 0, x, y + 1, 0}};
        for (int k = 0; k < 2; k++) memcpy(&pos[9 * order[2 * c + k]], tri[k], sizeof tri[k]);
    }
    for (int i = 0; i < NT * 3; i++) idx[i] = (uint32_t)i;
    spec sp = {.pos = pos, .nv = NT * 3, .idx = idx, .ni = NT * 3};
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == NX * NY, "nquads %d", s.nquads);
    for (int i = 0; i < s.nquads; i++) {
        const wrt_quad *q = &s.quads[i];
        double minx = fmin(fmin(q->p[0].x, q->p[1].x), fmin(q->p[2].x, q->p[3].x));
        double miny = fmin(fmin(q->p[0].y, q->p[1].y), fmin(q->p[2].y, q->p[3].y));
        CHECK_NEAR(q->area, 2.0, 1e-12, "quad %d is a cell", i);
        CHECK(has_corner(q, minx + 2, miny + 1, 0, 0) && has_corner(q, minx, miny, 0, 0), "quad %d is a rectangle cell", i);
    }
    wrt_scene_free(&s);
}

static void nested_transforms(void) {
    /* parent: T(1,2,3) R(90 deg about z) S(2); child: matrix translating by (1,0,0), with
     * the mesh; grandchild: a spot light rotated 90 deg about x (its -z becomes +y) */
    const double h = sqrt(0.5);
    char *nodes = fmt("[{\"translation\":[1,2,3],\"rotation\":[0,0,%.17g,%.17g],\"scale\":[2,2,2],\"children\":[1]},"
                      "{\"matrix\":[1,0,0,0, 0,1,0,0, 0,0,1,0, 1,0,0,1],\"mesh\":0,\"children\":[2]},"
                      "{\"rotation\":[%.17g,0,0,%.17g],\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}]",
                      h, h, h, h);
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    sp.nodes = nodes;
    sp.top = "\"extensionsUsed\":[\"KHR_lights_punctual\"],\"extensions\":{\"KHR_lights_punctual\":{\"lights\":"
             "[{\"type\":\"spot\",\"name\":\"lamp\",\"spot\":{}}]}},";
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1, "nquads %d", s.nquads);
    if (s.nquads == 1) {
        const wrt_quad *q = &s.quads[0];
        /* local (x,y,0) -> child (x+1,y,0) -> scale (2x+2,2y,0) -> rot (-2y,2x+2,0) -> +(1,2,3) */
        CHECK(has_corner(q, 1, 4, 3, 1e-6), "corner (0,0) -> (1,4,3)");
        CHECK(has_corner(q, 1, 6, 3, 1e-6), "corner (1,0) -> (1,6,3)");
        CHECK(has_corner(q, -1, 6, 3, 1e-6), "corner (1,1) -> (-1,6,3)");
        CHECK(has_corner(q, -1, 4, 3, 1e-6), "corner (0,1) -> (-1,4,3)");
        CHECK_NEAR(q->area, 4.0, 1e-6, "area scaled by 2x2");
        CHECK_NEAR(q->n.z, 1.0, 1e-9, "normal stays +z");
        CHECK_NEAR(s.bbox_min.x, -1, 1e-6, "bbox");
        CHECK_NEAR(s.bbox_max.y, 6, 1e-6, "bbox");
    }
    CHECK(s.nlights == 1, "nlights %d", s.nlights);
    if (s.nlights == 1) {
        const wrt_light *l = &s.lights[0];
        CHECK(l->type == WRT_LIGHT_SPOT, "spot");
        CHECK(strcmp(l->name, "lamp") == 0, "name %s", l->name);
        CHECK_NEAR(l->pos.x, 1, 1e-9, "light at the child's origin (1,4,3)");
        CHECK_NEAR(l->pos.y, 4, 1e-9, "light pos y");
        CHECK_NEAR(l->pos.z, 3, 1e-9, "light pos z");
        /* -z -> (rot x) +y -> (rot z 90) -x */
        CHECK_NEAR(l->dir.x, -1, 1e-9, "light dir x");
        CHECK_NEAR(l->dir.y, 0, 1e-9, "light dir y");
        CHECK_NEAR(l->dir.z, 0, 1e-9, "light dir z");
        CHECK_NEAR(l->inner_cone, 0, 1e-7, "default inner cone");
        CHECK_NEAR(l->outer_cone, WRT_PI / 4, 1e-6, "default outer cone");
        CHECK_NEAR(l->intensity, 1, 0, "default intensity");
        CHECK_NEAR(l->color[0] + l->color[1] + l->color[2], 3, 0, "default color");
        CHECK_NEAR(l->range, 0, 0, "default range");
    }
    free(nodes);
    wrt_scene_free(&s);
}

static void scene_choice(void) {
    /* only the default scene's nodes count: scene 1 holds the mesh, scene 0 an empty node */
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    sp.nodes = "[{\"mesh\":0},{}]";
    char *t = gltf_text(&sp);
    t = replace(t, "\"scene\":0,\"scenes\":[{\"nodes\":[0]}]", "\"scene\":1,\"scenes\":[{\"nodes\":[1]},{\"nodes\":[0]}]");
    wrt_scene s;
    CHECK(load_text(t, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1, "default scene 1 has the quad: %d", s.nquads);
    wrt_scene_free(&s);
    t = replace(t, "\"scene\":1,", "");
    test_capture_begin();
    wrt_status st = load_text(t, 0, &s);
    test_capture_end();
    CHECK(st == WRT_OK, "%s", wrt_last_error());
    CHECK(strstr(test_log, "no quads") != NULL, "%s", test_log);
    CHECK(s.nquads == 0, "no default scene: scene 0 (empty) is used: %d", s.nquads);
    wrt_scene_free(&s);
    free(t);
}

/* A 2x1 24-bit BMP with the given RGB texels (stb_image reads BMP). */
static size_t bmp_2x1(unsigned char out[62], const unsigned char rgb[6]) {
    memset(out, 0, 62);
    out[0] = 'B'; out[1] = 'M';
    out[2] = 62;           /* file size */
    out[10] = 54;          /* pixel offset */
    out[14] = 40;          /* info header size */
    out[18] = 2;           /* width */
    out[22] = 1;           /* height */
    out[26] = 1;           /* planes */
    out[28] = 24;          /* bits */
    out[34] = 8;           /* image size */
    for (int i = 0; i < 2; i++) {
        out[54 + 3 * i] = rgb[3 * i + 2];
        out[54 + 3 * i + 1] = rgb[3 * i + 1];
        out[54 + 3 * i + 2] = rgb[3 * i];
    }
    return 62;
}

static double srgb_lin(double c) { return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4); }

static void materials(void) {
    unsigned char bmp[62], bmp2[62];
    const unsigned char base_texels[6] = {128, 64, 255, 128, 0, 255};
    const unsigned char mr_texels[6] = {0, 128, 64, 0, 128, 64};
    bmp_2x1(bmp, base_texels);
    bmp_2x1(bmp2, mr_texels);
    char *i0 = b64(bmp, 62), *i1 = b64(bmp2, 62);
    char *top = fmt(
        "\"materials\":["
        "{\"name\":\"no factors\"},"
        "{\"name\":\"matte\",\"pbrMetallicRoughness\":{\"metallicFactor\":0,\"baseColorFactor\":[0.5,0.25,0.125,1]}},"
        "{\"name\":\"satin\",\"pbrMetallicRoughness\":{\"metallicFactor\":0,\"roughnessFactor\":0.5}},"
        "{\"name\":\"lamp\\\"shade\",\"emissiveFactor\":[1,0.5,0],"
        "\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":4}}},"
        "{\"name\":\"textured\",\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,1,1,1],\"baseColorTexture\":{\"index\":0},"
        "\"metallicRoughnessTexture\":{\"index\":1}}}],"
        "\"textures\":[{\"source\":0},{\"source\":1}],"
        "\"images\":[{\"uri\":\"data:image/bmp;base64,%s\"},{\"uri\":\"data:image/bmp;base64,%s\"}],",
        i0, i1);
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = ",\"material\":1"};
    sp.top = top;
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nmaterials == 5, "no default added when every primitive has a material: %d", s.nmaterials);
    if (s.nmaterials == 5) {
        const wrt_material *m = s.materials;
        CHECK(m[0].metallic == 1 && m[0].roughness == 1, "spec defaults metallic 1 roughness 1");
        CHECK(m[0].base_color[0] == 1 && m[0].base_color[2] == 1, "default base color");
        CHECK(m[0].lambertian == 0, "missing metallicFactor means metal, not lambertian");
        CHECK(m[1].lambertian == 1, "metallic 0 roughness 1 is lambertian");
        CHECK_NEAR(m[1].base_color[1], 0.25, 1e-7, "base color factor");
        CHECK(m[2].lambertian == 0, "roughness 0.5 is glossy");
        CHECK(s.nemissive == 1, "nemissive %d", s.nemissive);
        CHECK_NEAR(m[3].emissive[1], 2.0, 1e-7, "emissive factor x KHR_materials_emissive_strength");
        CHECK(s.ntextures == 1 && m[4].base_tex == 1 && s.textures[0].w == 2 && s.textures[0].h == 1,
              "the base-colour texture is kept: %d textures, base_tex %d", s.ntextures, m[4].base_tex);
        if (s.ntextures == 1)
            CHECK(s.textures[0].srgb[0] == 128 && fabs(s.textures[0].lut[128] - srgb_lin(128 / 255.0)) < 1e-6,
                  "kept texel %d, decoded %g", s.textures[0].srgb[0], s.textures[0].lut[128]);
        CHECK(strcmp(m[3].name, "lamp\"shade") == 0, "name %s", m[3].name);
        /* base: factor x mean of sRGB-decoded texels */
        CHECK_NEAR(m[4].base_color[0], 0.5 * srgb_lin(128 / 255.0), 1e-6, "R");
        CHECK_NEAR(m[4].base_color[1], 0.5 * (srgb_lin(64 / 255.0) + 0), 1e-6, "G");
        CHECK_NEAR(m[4].base_color[2], 1.0, 1e-6, "B");
        /* metallic = B, roughness = G, linear */
        CHECK_NEAR(m[4].metallic, 64 / 255.0, 1e-6, "metallic from B");
        CHECK_NEAR(m[4].roughness, 128 / 255.0, 1e-6, "roughness from G");
        CHECK(m[4].has_texture == 1, "has_texture");
        CHECK(s.quads[0].material == 1, "quad material");
    }
    /* the JSON summary names materials, escapes strings, counts quads per material */
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_scene_print_summary(&s, 1, f);
    fclose(f);
    CHECK(strstr(buf, "\"quads\":1,") != NULL, "%s", buf);
    CHECK(strstr(buf, "\"name\":\"lamp\\\"shade\"") != NULL, "escaped name: %s", buf);
    CHECK(strstr(buf, "{\"name\":\"matte\",\"base_color\":[0.5,0.25,0.125],\"metallic\":0,\"roughness\":1") != NULL,
          "%s", buf);
    CHECK(strstr(buf, "\"lambertian\":true,\"textured\":false,\"quads\":1}") != NULL, "%s", buf);
    CHECK(strchr(buf, '\n') == buf + len - 1, "one line");
    free(buf);
    wrt_scene_free(&s);
    free(top);
    free(i0);
    free(i1);
}

static void lights_and_camera(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    sp.nodes = "[{\"mesh\":0,\"children\":[1,2,3,4]},"
               "{\"translation\":[0,0,5],\"camera\":0},"
               "{\"translation\":[0.5,0.5,2],\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}},"
               "{\"translation\":[0,1,2],\"extensions\":{\"KHR_lights_punctual\":{\"light\":1}}},"
               "{\"translation\":[3,4,5],\"rotation\":[0.6,0,0,0.8],"
               "\"extensions\":{\"KHR_lights_punctual\":{\"light\":2}}}]";
    sp.top = "\"cameras\":[{\"type\":\"perspective\",\"perspective\":{\"yfov\":0.7,\"znear\":0.1,\"aspectRatio\":1.5}}],"
             "\"extensionsUsed\":[\"KHR_lights_punctual\"],\"extensions\":{\"KHR_lights_punctual\":{\"lights\":["
             "{\"type\":\"point\"},"
             "{\"type\":\"spot\",\"color\":[1,0.5,0.25],\"intensity\":30,\"range\":10,"
             "\"spot\":{\"innerConeAngle\":0.2,\"outerConeAngle\":0.5}},"
             "{\"type\":\"directional\",\"name\":\"sun\",\"intensity\":7,\"range\":3,\"color\":[1,0.9,0.8]}]}},";
    wrt_scene s;
    test_capture_begin();
    wrt_status st = load_spec(&sp, 0, &s);
    test_capture_end();
    CHECK(st == WRT_OK, "%s", wrt_last_error());
    /* the sun's range does not apply (KHR_lights_punctual): dropped with a warning */
    CHECK(strstr(test_log, "range 3 ignored") && strstr(test_log, "sun"), "sun's range: %s", test_log);
    CHECK(s.nlights == 3, "nlights %d", s.nlights);
    if (s.nlights == 3) {
        /* rotation about +x by 2 atan2(0.6, 0.8) = 73.74 deg: -Z goes to (0, sin, -cos) with
         * cos = 0.8^2 - 0.6^2 = 0.28, sin = 2 0.6 0.8 = 0.96 */
        const wrt_light *sun = &s.lights[2];
        CHECK(sun->type == WRT_LIGHT_DIRECTIONAL, "directional, type %d", sun->type);
        CHECK_NEAR(sun->dir.x, 0, 1e-12, "sun dir x");
        CHECK_NEAR(sun->dir.y, 0.96, 1e-12, "sun dir y");
        CHECK_NEAR(sun->dir.z, -0.28, 1e-12, "sun dir z");
        CHECK(sun->pos.x == 0 && sun->pos.y == 0 && sun->pos.z == 0, "a sun has no position");
        CHECK(sun->range == 0, "a sun has no range: %g", sun->range);
        CHECK_NEAR(sun->intensity, 7, 0, "sun lux");
        CHECK_NEAR(sun->color[2], 0.8, 1e-7, "sun colour");
        CHECK(!strcmp(sun->name, "sun"), "sun name %s", sun->name);
        CHECK(s.lights[0].type == WRT_LIGHT_POINT, "point");
        CHECK_NEAR(s.lights[0].pos.z, 2, 0, "point z");
        CHECK_NEAR(s.lights[0].intensity, 1, 0, "default intensity");
        CHECK(s.lights[1].type == WRT_LIGHT_SPOT, "spot");
        CHECK_NEAR(s.lights[1].dir.z, -1, 1e-12, "spot points down -z");
        CHECK_NEAR(s.lights[1].intensity, 30, 0, "intensity");
        CHECK_NEAR(s.lights[1].range, 10, 0, "range");
        CHECK_NEAR(s.lights[1].inner_cone, 0.2, 1e-7, "inner");
        CHECK_NEAR(s.lights[1].outer_cone, 0.5, 1e-7, "outer");
        CHECK_NEAR(s.lights[1].color[2], 0.25, 0, "color");
    }
    CHECK(s.camera.from_file == 1, "camera from file");
    CHECK_NEAR(s.camera.pos.z, 5, 0, "camera pos");
    CHECK_NEAR(s.camera.dir.z, -1, 1e-12, "camera looks -z");
    CHECK_NEAR(s.camera.up.y, 1, 1e-12, "camera up +y");
    CHECK_NEAR(s.camera.yfov, 0.7, 0, "yfov");
    CHECK_NEAR(s.camera.aspect, 1.5, 0, "aspect");
    CHECK_NEAR(s.camera.znear, 0.1, 0, "znear");
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_scene_print_summary(&s, 1, f);
    fclose(f);
    CHECK(strstr(buf, "\"type\":\"spot\",\"name\":\"light1\",\"position\":[0,1,2],\"direction\":[0,0,-1],"
                      "\"color\":[1,0.5,0.25],\"intensity\":30,\"range\":10,\"inner_cone\":0.2,"
                      "\"outer_cone\":0.5}") != NULL, "%s", buf);
    CHECK(strstr(buf, "{\"type\":\"directional\",\"name\":\"sun\",\"position\":[0,0,0]") != NULL, "%s", buf);
    free(buf);
    f = open_memstream(&buf, &len);
    wrt_scene_print_summary(&s, 0, f);
    fclose(f);
    CHECK(strstr(buf, "1 quads (1 parallelograms") != NULL, "%s", buf);
    CHECK(strstr(buf, "spot") != NULL && strstr(buf, "intensity 30 cd") != NULL, "%s", buf);
    CHECK(strstr(buf, "[3] sun   sun              dir (0.000, 0.960, -0.280) intensity 7 lux") != NULL, "%s", buf);
    {   /* a point light shines every way: its line shows no direction */
        const char *p = strstr(buf, "[1] point"), *e = p ? strchr(p, '\n') : NULL, *d = p ? strstr(p, "dir (") : NULL;
        CHECK(p && e && (!d || d > e) && strstr(p, "intensity 1 cd") && strstr(p, "intensity 1 cd") < e, "%s", buf);
    }
    free(buf);
    wrt_scene_free(&s);

    /* no camera: a default one frames the bounding box */
    spec plain = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    CHECK(load_spec(&plain, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.camera.from_file == 0, "default camera");
    CHECK_NEAR(s.camera.pos.x, 0.5, 1e-12, "centered x");
    CHECK_NEAR(s.camera.pos.y, 0.5, 1e-12, "centered y");
    CHECK(s.camera.pos.z > 1, "in front of the square: z %g", s.camera.pos.z);
    CHECK_NEAR(s.camera.dir.z, -1, 0, "looks at it");
    wrt_scene_free(&s);
}

static void glb_and_hash(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    sp.buffer_uri = "GLB";
    char *json = gltf_text(&sp);
    size_t jl = strlen(json), jp = (jl + 3) & ~(size_t)3;
    unsigned char *bin;
    size_t bl = spec_bytes(&sp, &bin), bp = (bl + 3) & ~(size_t)3;
    size_t total = 12 + 8 + jp + 8 + bp;
    unsigned char *g = calloc(1, total);
    uint32_t w[3] = {0x46546C67u, 2, (uint32_t)total};
    memcpy(g, w, 12);
    uint32_t c0[2] = {(uint32_t)jp, 0x4E4F534Au};
    memcpy(g + 12, c0, 8);
    memset(g + 20, ' ', jp);
    memcpy(g + 20, json, jl);
    uint32_t c1[2] = {(uint32_t)bp, 0x004E4942u};
    memcpy(g + 20 + jp, c1, 8);
    memcpy(g + 28 + jp, bin, bl);
    wrt_scene s;
    CHECK(wrt_scene_load_memory(g, total, NULL, NULL, &s) == WRT_OK, "%s", wrt_last_error());
    check_unit_square(&s, 1);
    CHECK(s.source_hash == wrt_hash64(g, total, WRT_HASH_SEED), "source hash");
    wrt_scene_free(&s);

    write_file("quad.glb", g, total);
    char path[512];
    snprintf(path, sizeof path, "%s/quad.glb", tmpdir);
    CHECK(wrt_scene_load(path, NULL, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1, "from file");
    wrt_scene_free(&s);

    /* truncated GLB: every prefix fails cleanly */
    for (size_t n = 1; n < total; n += (n < 40 ? 1 : 7)) {
        wrt_status st = wrt_scene_load_memory(g, n, NULL, NULL, &s);
        CHECK(st == WRT_ERR_PARSE, "prefix %zu: %d", n, st);
    }
    CHECK(wrt_scene_load_memory(g, total - 4, NULL, NULL, &s) == WRT_ERR_PARSE, "4 short");
    CHECK(strstr(wrt_last_error(), "truncated") != NULL, "%s", wrt_last_error());
    /* a BIN chunk claiming more than the file holds */
    uint32_t big = (uint32_t)bp + 8;
    memcpy(g + 20 + jp, &big, 4);
    CHECK(wrt_scene_load_memory(g, total, NULL, NULL, &s) == WRT_ERR_PARSE, "BIN past end");
    CHECK(strstr(wrt_last_error(), "BIN chunk") != NULL, "%s", wrt_last_error());
    free(g);
    free(bin);
    free(json);
}

static void external_buffers(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    unsigned char *bytes;
    size_t n = spec_bytes(&sp, &bytes);
    write_file("quad.bin", bytes, n);
    write_file("short.bin", bytes, n - 10);
    sp.buffer_uri = "quad.bin";
    char *t = gltf_text(&sp);
    write_file("ext.gltf", t, strlen(t));
    char path[512];
    snprintf(path, sizeof path, "%s/ext.gltf", tmpdir);
    wrt_scene s;
    CHECK(wrt_scene_load(path, NULL, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1, "external buffer");
    CHECK(s.files && strstr(s.files, "/quad.bin\n"), "the external file is listed as an input: %s", s.files);
    wrt_scene_free(&s);
    free(t);

    sp.buffer_uri = "nothere.bin";
    t = gltf_text(&sp);
    write_file("missing.gltf", t, strlen(t));
    snprintf(path, sizeof path, "%s/missing.gltf", tmpdir);
    CHECK(wrt_scene_load(path, NULL, &s) == WRT_ERR_PARSE, "missing buffer");
    CHECK(strstr(wrt_last_error(), "nothere.bin") && strstr(wrt_last_error(), "missing.gltf"), "%s",
          wrt_last_error());
    free(t);

    sp.buffer_uri = "short.bin";
    t = gltf_text(&sp);
    write_file("short.gltf", t, strlen(t));
    snprintf(path, sizeof path, "%s/short.gltf", tmpdir);
    CHECK(wrt_scene_load(path, NULL, &s) == WRT_ERR_PARSE, "truncated buffer");
    CHECK(strstr(wrt_last_error(), "short.bin") != NULL || strstr(wrt_last_error(), "buffer") != NULL, "%s",
          wrt_last_error());
    free(t);

    /* a buffer URI naming a folder */
    char sub[512];
    snprintf(sub, sizeof sub, "%s/sub", tmpdir);
    CHECK(mkdir(sub, 0700) == 0, "mkdir");
    sp.buffer_uri = "sub";
    t = gltf_text(&sp);
    write_file("dir.gltf", t, strlen(t));
    snprintf(path, sizeof path, "%s/dir.gltf", tmpdir);
    CHECK(wrt_scene_load(path, NULL, &s) == WRT_ERR_PARSE, "folder as buffer");
    CHECK(strstr(wrt_last_error(), "sub") != NULL, "%s", wrt_last_error());
    rmdir(sub);
    free(t);

    snprintf(path, sizeof path, "%s/no such file.gltf", tmpdir);
    CHECK(wrt_scene_load(path, NULL, &s) == WRT_ERR_IO, "no file");
    CHECK(strstr(wrt_last_error(), "no such file.gltf") != NULL, "%s", wrt_last_error());
    free(bytes);
}

/* ---------------------------------------------------------------- bad input */

/* Loads text, expects status `want` and `needle` (and `needle2` if given) in the message. */
static void expect_fail(const char *what, const char *text, wrt_status want, const char *needle,
                        const char *needle2) {
    wrt_scene s;
    wrt_status st = load_text(text, 0, &s);
    CHECK(st == want, "%s: status %d (%s), expected %d: %s", what, st, wrt_status_str(st), want,
          wrt_last_error());
    CHECK(strstr(wrt_last_error(), needle) != NULL, "%s: '%s' not in: %s", what, needle, wrt_last_error());
    if (needle2)
        CHECK(strstr(wrt_last_error(), needle2) != NULL, "%s: '%s' not in: %s", what, needle2,
              wrt_last_error());
    CHECK(s.nquads == 0 && s.quads == NULL, "%s: output zeroed", what);
    if (st == WRT_OK) wrt_scene_free(&s);
}

static void bad_json(void) {
    expect_fail("malformed", "{\"asset\":{\"version\":\"2.0\"},\"scenes\":[", WRT_ERR_PARSE, "<memory>", NULL);
    expect_fail("not json", "hello", WRT_ERR_PARSE, "<memory>", NULL);
    expect_fail("empty", "", WRT_ERR_PARSE, "empty", NULL);
    expect_fail("no scene", "{\"asset\":{\"version\":\"2.0\"}}", WRT_ERR_PARSE, "no scene", NULL);
    expect_fail("cycle", "{\"asset\":{\"version\":\"2.0\"},\"scenes\":[{\"nodes\":[0]}],"
                         "\"nodes\":[{\"children\":[1]},{\"children\":[0]}]}",
                WRT_ERR_PARSE, "node 0 is reached twice", NULL);
}

static void bad_accessors(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    char *t = replace(gltf_text(&sp), "\"indices\":1", "\"indices\":7");
    expect_fail("accessor out of range", t, WRT_ERR_PARSE, "mesh 0 primitive 0: indices accessor 7 does not exist", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"count\":4,", "\"count\":2147483648,");
    expect_fail("absurd count", t, WRT_ERR_PARSE, "count 2147483648", "POSITION accessor 0");
    free(t);
    t = replace(gltf_text(&sp), "\"count\":6,", "\"count\":4294967295,");
    expect_fail("absurd index count", t, WRT_ERR_PARSE, "4294967295", "indices accessor 1");
    free(t);
    t = replace(gltf_text(&sp), "\"byteLength\":48}", "\"byteLength\":4800}");
    expect_fail("bufferView past buffer", t, WRT_ERR_PARSE, "bufferView 0", "runs past the end of buffer 0");
    free(t);
    t = replace(gltf_text(&sp), "\"byteLength\":48}", "\"byteLength\":48,\"byteStride\":8}");
    expect_fail("stride too small", t, WRT_ERR_PARSE, "byteStride 8", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"componentType\":5125", "\"componentType\":5126");
    expect_fail("float indices", t, WRT_ERR_PARSE, "componentType 5126", "indices accessor 1");
    free(t);
    t = replace(gltf_text(&sp), "\"type\":\"VEC3\"", "\"type\":\"VEC2\"");
    expect_fail("VEC2 positions", t, WRT_ERR_PARSE, "expected VEC3", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"bufferView\":1,", "\"bufferView\":9,");
    expect_fail("bufferView out of range", t, WRT_ERR_PARSE, "accessor 1: bufferView 9 does not exist", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"POSITION\":0", "\"POSITION\":-1");
    expect_fail("negative accessor", t, WRT_ERR_PARSE, "POSITION accessor -1 does not exist", NULL);
    free(t);
    /* truncated data URI: the buffer holds fewer bytes than byteLength */
    t = gltf_text(&sp);
    char *comma = strstr(t, "base64,");
    char *end = comma ? strchr(comma, '"') : NULL;
    if (end) memmove(end - 16, end, strlen(end) + 1);
    expect_fail("truncated data uri", t, WRT_ERR_PARSE, "<memory>", "but its data uri holds 60 bytes");
    free(t);
    const uint32_t past[] = {0, 1, 2, 0, 2, 9};
    spec sp2 = {.pos = unit_square, .nv = 4, .idx = past, .ni = 6, .prim_extra = 0};
    t = gltf_text(&sp2);
    expect_fail("index past vertex count", t, WRT_ERR_PARSE, "triangle 1: index 9", "vertex count 4");
    free(t);
    t = replace(gltf_text(&sp), "\"indices\":1", "\"indices\":1,\"mode\":1");
    expect_fail("lines", t, WRT_ERR_UNSUPPORTED, "mode 1", "primitive 0");
    free(t);
    t = replace(gltf_text(&sp), "\"POSITION\":0", "\"NORMAL\":0");
    expect_fail("no positions", t, WRT_ERR_PARSE, "no POSITION", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"indices\":1", "\"indices\":1,\"material\":3");
    expect_fail("material out of range", t, WRT_ERR_PARSE, "material 3 does not exist", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"scene\":0,", "\"extensionsRequired\":[\"KHR_draco_mesh_compression\"],\"scene\":0,");
    expect_fail("required extension", t, WRT_ERR_UNSUPPORTED, "required extension KHR_draco_mesh_compression", NULL);
    free(t);
    t = replace(gltf_text(&sp), "[{\"mesh\":0}]", "[{\"mesh\":0,\"extensions\":{\"KHR_lights_punctual\":{\"light\":5}}}]");
    expect_fail("light out of range", t, WRT_ERR_PARSE, "KHR_lights_punctual.light: refers to light 5", NULL);
    free(t);
}


/* The strict pass: each field the reader uses, invalid in one way, is refused with its
 * JSON path and what is wrong; nothing becomes a default silently. */
static void strict_case(const char *what, const char *top, const char *prim_extra, const char *nodes,
                        wrt_status want, const char *needle, const char *needle2) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = prim_extra};
    sp.top = top;
    sp.nodes = nodes;
    char *t = gltf_text(&sp);
    expect_fail(what, t, want, needle, needle2);
    free(t);
}

#define LIGHTS(x) "\"extensionsUsed\":[\"KHR_lights_punctual\"],\"extensions\":{\"KHR_lights_punctual\":{\"lights\":[" x "]}},"
#define LIGHT_NODE(extra) "[{\"mesh\":0,\"children\":[1]},{" extra "\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}]"

static void strict_fields(void) {
    const char *mat0 = ",\"material\":0";
    strict_case("baseColorFactor of 3", "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.5,0.5]}}],",
                mat0, NULL, WRT_ERR_PARSE, "materials[0].pbrMetallicRoughness.baseColorFactor: has 3 elements, expected 4", NULL);
    strict_case("baseColorFactor of 5", "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.5,0.5,1,1]}}],",
                mat0, NULL, WRT_ERR_PARSE, "baseColorFactor: has 5 elements, expected 4", NULL);
    strict_case("baseColorFactor string", "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":\"grey\"}}],",
                mat0, NULL, WRT_ERR_PARSE, "baseColorFactor: must be an array of 4 numbers, not string", NULL);
    strict_case("baseColorFactor element string", "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,\"0.5\",0.5,1]}}],",
                mat0, NULL, WRT_ERR_PARSE, "baseColorFactor[1]: must be a number, not string", NULL);
    strict_case("metallicFactor string", "\"materials\":[{\"pbrMetallicRoughness\":{\"metallicFactor\":\"0\"}}],",
                mat0, NULL, WRT_ERR_PARSE, "materials[0].pbrMetallicRoughness.metallicFactor: must be a number, not string", NULL);
    strict_case("roughness above 1", "\"materials\":[{\"pbrMetallicRoughness\":{\"roughnessFactor\":1.5}}],",
                mat0, NULL, WRT_ERR_PARSE, "roughnessFactor: 1.5 is outside [0, 1]", NULL);
    strict_case("emissiveFactor string", "\"materials\":[{\"emissiveFactor\":[\"1\",0,0]}],",
                mat0, NULL, WRT_ERR_PARSE, "materials[0].emissiveFactor[0]: must be a number", NULL);
    strict_case("missing texture", "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":3}}}],",
                mat0, NULL, WRT_ERR_PARSE, "baseColorTexture.index: refers to textures 3, which does not exist (the file has 0)", NULL);
    strict_case("texture without image", "\"materials\":[{\"emissiveTexture\":{\"index\":0}}],\"textures\":[{\"source\":2}],",
                mat0, NULL, WRT_ERR_PARSE, "textures[0].source: refers to images 2, which does not exist", NULL);
    strict_case("undecodable image", "\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0}}}],"
                "\"textures\":[{\"source\":0}],\"images\":[{\"uri\":\"data:image/png;base64,AAAAAAAAAAAA\"}],",
                mat0, NULL, WRT_ERR_PARSE, "materials[0].pbrMetallicRoughness.baseColorTexture: texture 0 has no decoded image", NULL);
    strict_case("doubleSided string", "\"materials\":[{\"doubleSided\":\"yes\"}],", mat0, NULL, WRT_ERR_PARSE,
                "materials[0].doubleSided: must be true or false, not string", NULL);
    strict_case("light colour of 2", LIGHTS("{\"type\":\"point\",\"color\":[1,1]}"), NULL, LIGHT_NODE(""), WRT_ERR_PARSE,
                "extensions.KHR_lights_punctual.lights[0].color: has 2 elements, expected 3", NULL);
    strict_case("light intensity string", LIGHTS("{\"type\":\"point\",\"intensity\":\"5\"}"), NULL, LIGHT_NODE(""),
                WRT_ERR_PARSE, "lights[0].intensity: must be a number, not string", NULL);
    strict_case("intensity 1e39", LIGHTS("{\"type\":\"point\",\"intensity\":1e39}"), NULL, LIGHT_NODE(""), WRT_ERR_PARSE,
                "lights[0].intensity: 1e+39 is not finite as a 32-bit float", NULL);
    strict_case("range 0", LIGHTS("{\"type\":\"point\",\"range\":0}"), NULL, LIGHT_NODE(""), WRT_ERR_PARSE,
                "lights[0].range: 0 is outside (0,", NULL);
    strict_case("spot cones crossed", LIGHTS("{\"type\":\"spot\",\"spot\":{\"innerConeAngle\":0.6,\"outerConeAngle\":0.5}}"),
                NULL, LIGHT_NODE(""), WRT_ERR_PARSE, "lights[0].spot: innerConeAngle 0.6 must be less than outerConeAngle 0.5", NULL);
    strict_case("light type", LIGHTS("{\"type\":\"area\"}"), NULL, LIGHT_NODE(""), WRT_ERR_PARSE,
                "lights[0].type: 'area' is not point, spot or directional", NULL);
    strict_case("zero scale light", LIGHTS("{\"type\":\"spot\",\"spot\":{}}"), NULL, LIGHT_NODE("\"scale\":[1,0,1],"),
                WRT_ERR_PARSE, "nodes[1]: light 0's world transform has zero scale", NULL);
    strict_case("zero scale parent", LIGHTS("{\"type\":\"point\"}"), NULL,
                "[{\"mesh\":0,\"scale\":[0,0,0],\"children\":[1]},{\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}]",
                WRT_ERR_PARSE, "nodes[1]: light 0's world transform has zero scale", NULL);
    strict_case("negative scale spot", LIGHTS("{\"type\":\"spot\",\"spot\":{}}"), NULL, LIGHT_NODE("\"scale\":[1,1,-1],"),
                WRT_ERR_PARSE, "nodes[1]: spot light 0's world transform has a negative scale", NULL);
    strict_case("negative scale sun", LIGHTS("{\"type\":\"directional\"}"), NULL, LIGHT_NODE("\"scale\":[1,1,-1],"),
                WRT_ERR_PARSE, "nodes[1]: directional light 0's world transform has a negative scale", NULL);
    strict_case("matrix and TRS", NULL, NULL,
                "[{\"mesh\":0,\"matrix\":[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1],\"translation\":[1,0,0]}]", WRT_ERR_PARSE,
                "nodes[0]: has both matrix and translation", NULL);
    strict_case("scale of 2", NULL, NULL, "[{\"mesh\":0,\"scale\":[1,1]}]", WRT_ERR_PARSE,
                "nodes[0].scale: has 2 elements, expected 3", NULL);
    strict_case("camera znear 0", "\"cameras\":[{\"type\":\"perspective\",\"perspective\":{\"yfov\":0.7,\"znear\":0}}],", NULL,
                "[{\"mesh\":0,\"children\":[1]},{\"camera\":0,\"translation\":[0,0,3]}]", WRT_ERR_PARSE,
                "cameras[0].perspective.znear: 0 is outside (0,", NULL);
    strict_case("camera zfar below znear", "\"cameras\":[{\"type\":\"perspective\",\"perspective\":{\"yfov\":0.7,\"znear\":1,\"zfar\":0.5}}],",
                NULL, "[{\"mesh\":0}]", WRT_ERR_PARSE, "cameras[0].perspective.zfar: 0.5 must be greater than znear 1", NULL);
    strict_case("camera zero scale", "\"cameras\":[{\"type\":\"perspective\",\"perspective\":{\"yfov\":0.7,\"znear\":0.1}}],", NULL,
                "[{\"mesh\":0,\"children\":[1]},{\"camera\":0,\"scale\":[0,0,0]}]", WRT_ERR_PARSE,
                "nodes[1]: camera 0's world transform has zero scale", NULL);
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6};
    char *t = replace(gltf_text(&sp), "\"version\":\"2.0\"", "\"version\":\"3.0\"");
    expect_fail("asset version 3.0", t, WRT_ERR_UNSUPPORTED, "asset.version: '3.0': only glTF 2.x is supported", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"version\":\"2.0\"", "\"version\":2");
    expect_fail("asset version number", t, WRT_ERR_PARSE, "asset.version: must be a string, not number", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"componentType\":5126,", "\"byteOffset\":-4,\"componentType\":5126,");
    expect_fail("negative byteOffset", t, WRT_ERR_PARSE, "accessors[0].byteOffset: -4 is outside [0,", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"byteOffset\":0,", "\"byteOffset\":-8,");
    expect_fail("negative bufferView byteOffset", t, WRT_ERR_PARSE, "bufferViews[0].byteOffset: -8 is outside [0,", NULL);
    free(t);
    t = replace(gltf_text(&sp), "\"count\":4,", "\"count\":4.5,");
    expect_fail("fractional count", t, WRT_ERR_PARSE, "accessors[0].count: 4.5 is not an integer", NULL);
    free(t);
}

/* Valid but unusual fields are warned about; fields the bake does not use are listed. */
static void strict_warnings_and_ignored(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = ",\"material\":0"};
    sp.top = "\"materials\":[{\"alphaMode\":\"BLEND\",\"normalTexture\":{\"index\":0}}],\"textures\":[{\"source\":0}],"
             "\"images\":[{\"uri\":\"data:image/png;base64,AAAA\"}],\"animations\":[],";
    sp.nodes = "[{\"mesh\":0,\"rotation\":[0,0,0,0.9]}]";
    char *t = gltf_text(&sp);
    t = replace(t, "\"attributes\":{\"POSITION\":0}", "\"attributes\":{\"POSITION\":0,\"COLOR_0\":0}");
    wrt_scene s;
    test_capture_begin();
    wrt_status st = load_text(t, 0, &s);
    test_capture_end();
    CHECK(st == WRT_OK, "%s", wrt_last_error());
    CHECK(strstr(test_log, "materials[0].alphaMode: BLEND: transparency is not modelled") != NULL, "%s", test_log);
    CHECK(strstr(test_log, "nodes[0].rotation: quaternion of length 0.9, not unit") != NULL, "%s", test_log);
    if (st == WRT_OK) {
        CHECK(strstr(s.ignored, "materials[*].alphaMode") != NULL, "%s", s.ignored);
        CHECK(strstr(s.ignored, "materials[*].normalTexture") != NULL, "%s", s.ignored);
        CHECK(strstr(s.ignored, "meshes[*].primitives[*].attributes.COLOR_0") != NULL &&
                  strstr(s.ignored, "NORMAL") == NULL, "%s", s.ignored); /* NORMAL is read (shading) */
        CHECK(strstr(s.ignored, "animations") != NULL, "%s", s.ignored);
        char *buf = NULL;
        size_t len = 0;
        FILE *f = open_memstream(&buf, &len);
        wrt_scene_print_summary(&s, 0, f);
        fclose(f);
        CHECK(strstr(buf, "ignored (not used by the bake): ") != NULL && strstr(buf, "attributes.COLOR_0"), "%s", buf);
        free(buf);
        wrt_scene_free(&s);
    }
    free(t);
}

/* doubleSided: each quad gets a back-to-back twin, facing the other way, set back by
 * 1e-4 of the diagonal; a one-sided material gets none. */
static void double_sided(void) {
    spec sp = {.pos = unit_square, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = ",\"material\":0"};
    sp.top = "\"materials\":[{\"doubleSided\":true}],";
    wrt_scene s;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 2 && s.ntwins == 1, "quads %d twins %d", s.nquads, s.ntwins);
    if (s.nquads == 2) {
        const wrt_quad *f = &s.quads[0], *b = &s.quads[1];
        CHECK_NEAR(f->n.z, 1, 1e-12, "front faces +z");
        CHECK_NEAR(b->n.z, -1, 1e-12, "twin faces -z");
        CHECK_NEAR(b->area, f->area, 1e-12, "same area");
        double gap = 1e-4 * sqrt(2.0);
        for (int k = 0; k < 4; k++) CHECK_NEAR(b->p[k].z, -gap, 1e-15, "twin set back by 1e-4 diagonal");
        CHECK(has_corner(b, 1, 1, -gap, 1e-12) && has_corner(b, 0, 1, -gap, 1e-12), "same outline");
        CHECK(b->material == 0 && b->mesh == 0, "same material and mesh");
    }
    wrt_scene_free(&s);
    sp.top = "\"materials\":[{\"doubleSided\":false}],";
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1 && s.ntwins == 0, "one-sided: quads %d", s.nquads);
    wrt_scene_free(&s);
}

/* A scene that is not a regular file is refused before it is read: a FIFO at once
 * (no writer: a blocking open would wait for ever), a directory without an allocation
 * of its "size". */
static void not_regular(void) {
    char fifo[512], dir[512];
    snprintf(fifo, sizeof fifo, "%s/pipe.gltf", tmpdir);
    snprintf(dir, sizeof dir, "%s/folder.gltf", tmpdir);
    unlink(fifo);
    CHECK(mkfifo(fifo, 0600) == 0, "mkfifo");
    mkdir(dir, 0700);
    wrt_scene s;
    double t0 = wrt_now();
    wrt_status st = wrt_scene_load(fifo, NULL, &s);
    CHECK(st == WRT_ERR_PARSE && strstr(wrt_last_error(), "pipe.gltf: not a regular file (a FIFO)"),
          "FIFO: %s", wrt_last_error());
    CHECK(wrt_now() - t0 < 5, "FIFO refused in %.1f s", wrt_now() - t0);
    st = wrt_scene_load(dir, NULL, &s);
    CHECK(st == WRT_ERR_PARSE && strstr(wrt_last_error(), "folder.gltf: not a regular file (a directory)"),
          "directory: %s", wrt_last_error());
    unlink(fifo);
    rmdir(dir);
}

static void bad_geometry(void) {
    const float nan_pos[] = {0, 0, 0, 1, 0, 0, NAN, 1, 0, 0, 1, 0};
    spec sp = {.pos = nan_pos, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    char *t = gltf_text(&sp);
    expect_fail("NaN", t, WRT_ERR_GEOMETRY, "triangle 0: vertex 2 has a NaN", "mesh 0 'plane' primitive 0");
    free(t);
    const float inf_pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, INFINITY, 0};
    sp.pos = inf_pos;
    t = gltf_text(&sp);
    expect_fail("Inf", t, WRT_ERR_GEOMETRY, "triangle 1: vertex 3 has a NaN, infinite", NULL);
    free(t);
    /* a stray NaN triangle beside a good quad: refused by default, dropped with drop_bad */
    const float posn[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 5, 5, 6, NAN, 5, 5, 6, 5};
    const uint32_t idxn[] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    spec spn = {.pos = posn, .nv = 7, .idx = idxn, .ni = 9, .prim_extra = 0};
    t = gltf_text(&spn);
    expect_fail("stray NaN triangle", t, WRT_ERR_GEOMETRY, "triangle 2: vertex 5 has a NaN",
                "meshes[0].primitives[0].attributes.POSITION element 5");
    wrt_scene s;
    test_capture_begin();
    wrt_status st = load_text(t, 1, &s);
    test_capture_end();
    CHECK(st == WRT_OK, "%s", wrt_last_error());
    CHECK(s.nquads == 1 && s.nproblems == 1 && s.nnonfinite == 1, "kept %d quads, %d problems", s.nquads,
          s.nproblems);
    CHECK(s.nproblems == 1 && s.problems[0].tri == 2 && s.problems[0].kind == WRT_PROBLEM_NONFINITE, "problem");
    CHECK(strstr(test_log, "dropped 1 bad triangle") != NULL, "%s", test_log);
    CHECK_NEAR(s.bbox_max.x, 1, 0, "bbox of kept geometry");
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    wrt_scene_print_summary(&s, 1, f);
    fclose(f);
    CHECK(strstr(buf, "\"problems\":[{\"kind\":\"non-finite\",\"mesh\":0,\"primitive\":0,\"triangle\":2,") != NULL,
          "%s", buf);
    free(buf);
    wrt_scene_free(&s);
    free(t);
}

/* Checks that s holds, from element `first` on, triangle `tri` (corners a, b, c in their
 * front-face winding) as three quads through its centroid and edge midpoints. */
static void check_triangle_parts(const wrt_scene *s, int first, int tri, wrt_v3 a, wrt_v3 b, wrt_v3 c) {
    CHECK(first + 3 <= s->nquads, "triangle %d: %d quads", tri, s->nquads);
    if (first + 3 > s->nquads) return;
    wrt_v3 v[3] = {a, b, c}, g = v3_scale(v3_add(v3_add(a, b), c), 1.0 / 3);
    wrt_v3 n = v3_norm(v3_cross(v3_sub(b, a), v3_sub(c, a)));
    double area = 0.5 * v3_len(v3_cross(v3_sub(b, a), v3_sub(c, a))), sum = 0;
    for (int k = 0; k < 3; k++) {
        const wrt_quad *q = &s->quads[first + k];
        CHECK(q->kind == WRT_ELEM_TRIANGLE && q->part == k && q->tri[0] == tri && q->tri[1] == -1,
              "triangle %d part %d: kind %d part %d tri %d/%d", tri, k, q->kind, q->part, q->tri[0], q->tri[1]);
        wrt_v3 want[4] = {v[k], v3_scale(v3_add(v[k], v[(k + 1) % 3]), 0.5), g,
                          v3_scale(v3_add(v[(k + 2) % 3], v[k]), 0.5)};
        for (int i = 0; i < 4; i++)
            CHECK(v3_len(v3_sub(q->p[i], want[i])) < 1e-6, "triangle %d part %d corner %d", tri, k, i);
        CHECK(v3_dot(q->n, n) > 1 - 1e-9, "triangle %d part %d faces the triangle's front", tri, k);
        CHECK(!q->parallelogram, "a part is a general quad");
        /* each part is a third of the triangle: two of the six triangles the medians cut */
        CHECK_NEAR(q->area, area / 3, 1e-6 * area, "triangle %d part %d area", tri, k);
        double mean = 0;
        for (int i = 0; i < 16; i++)
            for (int j = 0; j < 16; j++) mean += wrt_quad_jacobian(q, (i + 0.5) / 16, (j + 0.5) / 16) / 256;
        CHECK_NEAR(mean, area / 3, 1e-9 * area, "triangle %d part %d: the Jacobian integrates to its area", tri, k);
        sum += q->area;
    }
    CHECK_NEAR(sum, area, 1e-6 * area, "triangle %d: parts cover it", tri);
}

/* Triangles that do not pair become elements of their own (issue 21): lone, non-planar,
 * non-convex or wound against their neighbour; degenerate ones and slivers are dropped
 * with a warning and counted, not refused. */
static void triangle_elements(void) {
    wrt_scene s;
    const uint32_t one[] = {0, 1, 2};
    spec sp1 = {.pos = unit_square, .nv = 4, .idx = one, .ni = 3, .prim_extra = 0};
    CHECK(load_spec(&sp1, 0, &s) == WRT_OK, "single triangle: %s", wrt_last_error());
    CHECK(s.nquads == 3 && s.nsingle == 1 && s.npaired == 0 && s.why_single[WRT_SINGLE_ALONE] == 1 &&
              s.nproblems == 0,
          "single triangle: %d quads, %d single", s.nquads, s.nsingle);
    check_triangle_parts(&s, 0, 0, v3(0, 0, 0), v3(1, 0, 0), v3(1, 1, 0));
    wrt_scene_free(&s);

    const float bent[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0.5f};
    spec sp = {.pos = bent, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "non-planar pair: %s", wrt_last_error());
    CHECK(s.nquads == 6 && s.nsingle == 2 && s.why_single[WRT_SINGLE_NONPLANAR] == 2, "non-planar: %d quads", s.nquads);
    check_triangle_parts(&s, 0, 0, v3(0, 0, 0), v3(1, 0, 0), v3(1, 1, 0));
    check_triangle_parts(&s, 3, 1, v3(0, 0, 0), v3(1, 1, 0), v3(0, 1, 0.5));
    wrt_scene_free(&s);

    const float dart[] = {0, 0, 0, 2, 0, 0, 0.5f, 0.5f, 0, 0, 2, 0};
    sp.pos = dart;
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "non-convex pair: %s", wrt_last_error());
    CHECK(s.nquads == 6 && s.why_single[WRT_SINGLE_NONCONVEX] == 2, "non-convex: %d quads", s.nquads);
    check_triangle_parts(&s, 3, 1, v3(0, 0, 0), v3(0.5, 0.5, 0), v3(0, 2, 0));
    wrt_scene_free(&s);

    const uint32_t flipped[] = {0, 1, 2, 0, 3, 2};
    spec spf = {.pos = unit_square, .nv = 4, .idx = flipped, .ni = 6, .prim_extra = 0};
    CHECK(load_spec(&spf, 0, &s) == WRT_OK, "opposite windings: %s", wrt_last_error());
    CHECK(s.nquads == 6 && s.why_single[WRT_SINGLE_WINDING] == 2, "opposite windings: %d quads", s.nquads);
    check_triangle_parts(&s, 3, 1, v3(0, 0, 0), v3(0, 1, 0), v3(1, 1, 0)); /* faces -z */
    CHECK(s.nquads == 6 && s.quads[0].n.z > 0.999 && s.quads[3].n.z < -0.999, "one up, one down");
    wrt_scene_free(&s);

    /* a quad plus a stray triangle: the quad as before, then the triangle's three parts */
    const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 5, 5, 6, 5, 5, 5, 6, 5};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    spec sp3 = {.pos = pos, .nv = 7, .idx = idx, .ni = 9, .prim_extra = 0};
    CHECK(load_spec(&sp3, 0, &s) == WRT_OK, "stray triangle: %s", wrt_last_error());
    CHECK(s.nquads == 4 && s.npaired == 1 && s.nsingle == 1 && s.quads[0].kind == WRT_ELEM_QUAD &&
              s.quads[0].tri[0] == 0 && s.quads[0].tri[1] == 1,
          "stray triangle: %d quads", s.nquads);
    check_triangle_parts(&s, 1, 2, v3(5, 5, 5), v3(6, 5, 5), v3(5, 6, 5));
    wrt_scene_free(&s);

    /* zero area (corners coincide or are collinear): dropped, counted, one warning */
    const float flat[] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0};
    sp.pos = flat;
    test_capture_begin();
    CHECK(load_spec(&sp, 0, &s) == WRT_OK, "zero area: %s", wrt_last_error());
    test_capture_end();
    CHECK(s.nquads == 0 && s.ndropped == 2 && s.nproblems == 2 && s.problems[0].kind == WRT_PROBLEM_DEGENERATE,
          "zero area: %d quads %d dropped", s.nquads, s.ndropped);
    CHECK(strstr(test_log, "dropped 2 degenerate triangles") && strstr(test_log, "triangle 0: zero area"),
          "%s", test_log);
    wrt_scene_free(&s);

    /* a sliver: a triangle 1e-6 high beside a unit square (diagonal ~ 1.4): its height is
     * under WRT_SLIVER_REL x diagonal = 1.4e-5; the square stays */
    const float sliv[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0.5f, 1e-6f, 1};
    spec sps = {.pos = sliv, .nv = 7, .idx = idx, .ni = 9, .prim_extra = 0};
    test_capture_begin();
    CHECK(load_spec(&sps, 0, &s) == WRT_OK, "sliver: %s", wrt_last_error());
    test_capture_end();
    CHECK(s.nquads == 1 && s.ndropped == 1 && s.nproblems == 1 && s.problems[0].kind == WRT_PROBLEM_SLIVER &&
              s.problems[0].tri == 2,
          "sliver: %d quads %d dropped", s.nquads, s.ndropped);
    CHECK(strstr(test_log, "triangle 2: sliver: narrowest height 1e-06") != NULL, "%s", test_log);
    wrt_scene_free(&s);
    /* ... and a triangle 1e-4 high is kept (three quads) */
    const float thin[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 0.5f, 1e-4f, 1};
    sps.pos = thin;
    CHECK(load_spec(&sps, 0, &s) == WRT_OK && s.nquads == 4 && s.ndropped == 0, "thin kept: %d quads", s.nquads);
    wrt_scene_free(&s);

    /* report_only (--scan): a NaN triangle is counted, nothing is refused or logged */
    const float nan_pos[] = {0, 0, 0, 1, 0, 0, NAN, 1, 0, 0, 1, 0};
    spec spn = {.pos = nan_pos, .nv = 4, .idx = square_idx, .ni = 6, .prim_extra = 0};
    char *t = gltf_text(&spn);
    wrt_load_options ro = {.report_only = 1};
    test_capture_begin();
    CHECK(wrt_scene_load_memory(t, strlen(t), tmpdir, &ro, &s) == WRT_OK, "report_only: %s", wrt_last_error());
    test_capture_end();
    CHECK(s.nnonfinite == 2 && s.nquads == 0 && test_log[0] == 0, "report_only: %d non-finite, log '%s'",
          s.nnonfinite, test_log);
    wrt_scene_free(&s);
    free(t);
}

/* glTF: a node whose world transform has a negative determinant flips the winding, so
 * a mirrored mesh still faces the way it faced before the mirror (here +z). */
static void mirrored_nodes(void) {
    const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 2, 1, 0, 2, 0, 1, 2};
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3, 4, 5, 6};
    const char *nodes[] = {"[{\"mesh\":0,\"scale\":[-1,1,1]}]", "[{\"mesh\":0,\"scale\":[1,1,-1]}]",
                           "[{\"scale\":[-2,1,1],\"children\":[1]},{\"mesh\":0,\"scale\":[1,-1,1]}]"};
    const double zsign[] = {1, -1, 1}; /* the mirror of z turns the plane's normal with it */
    for (int c = 0; c < 3; c++) {
        spec sp = {.pos = pos, .nv = 7, .idx = idx, .ni = 9, .nodes = nodes[c]};
        wrt_scene s;
        CHECK(load_spec(&sp, 0, &s) == WRT_OK, "mirror %d: %s", c, wrt_last_error());
        CHECK(s.nquads == 4 && s.nmirrored == (c < 2), "mirror %d: %d quads, %d mirrored", c, s.nquads, s.nmirrored);
        for (int q = 0; q < s.nquads; q++)
            CHECK(s.quads[q].n.z * zsign[c] > 0.999999, "mirror %d element %d faces %g", c, q, s.quads[q].n.z);
        wrt_scene_free(&s);
    }
}

/* glTF NORMAL to world space: by the inverse transpose of the node's linear part, made
 * unit, so a stretched or mirrored node keeps its normals perpendicular to what they were
 * perpendicular to (closed forms: the local normal (1, 0, 1)/sqrt 2 under scale (2, 1, 1)
 * is (1/2, 0, 1)/|.|; under the mirror (-1, 1, 1) it is (-1, 0, 1)/sqrt 2), at every
 * corner of the square's paired quad. A zero normal is refused with its accessor element. */
static void normals_transformed(void) {
    const float data[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0,               /* POSITION */
                          1, 0, 1, 1, 0, 1, 1, 0, 1, 1, 0, 1};              /* NORMAL, not unit */
    const uint32_t idx[] = {0, 1, 2, 0, 2, 3};
    unsigned char bytes[sizeof data + sizeof idx];
    memcpy(bytes, data, sizeof data);
    memcpy(bytes + sizeof data, idx, sizeof idx);
    char *b = b64(bytes, sizeof bytes);
    const char *scales[3] = {"[2,1,1]", "[-1,1,1]", "[1,1,1]"};
    const double want[3][3] = {{0.5, 0, 1}, {-1, 0, 1}, {0, 0, 0}};
    for (int c = 0; c < 3; c++) {
        char *t = fmt("{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],"
                      "\"nodes\":[{\"mesh\":0,\"scale\":%s}],"
                      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"NORMAL\":1},\"indices\":2}]}],"
                      "\"buffers\":[{\"byteLength\":%zu,\"uri\":\"data:application/octet-stream;base64,%s\"}],"
                      "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48},"
                      "{\"buffer\":0,\"byteOffset\":48,\"byteLength\":48},{\"buffer\":0,\"byteOffset\":96,\"byteLength\":24}],"
                      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
                      "{\"bufferView\":1,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
                      "{\"bufferView\":2,\"componentType\":5125,\"count\":6,\"type\":\"SCALAR\"}]}",
                      scales[c], sizeof bytes, b);
        if (c == 2) { /* a zero normal: refused, naming it */
            free(t);
            float bad[24];
            memcpy(bad, data, sizeof bad);
            bad[15] = bad[17] = 0; /* vertex 1's normal */
            unsigned char bb[sizeof bytes];
            memcpy(bb, bad, sizeof bad);
            memcpy(bb + sizeof bad, idx, sizeof idx);
            char *b2 = b64(bb, sizeof bb);
            t = fmt("{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
                    "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0,\"NORMAL\":1},\"indices\":2}]}],"
                    "\"buffers\":[{\"byteLength\":%zu,\"uri\":\"data:application/octet-stream;base64,%s\"}],"
                    "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48},"
                    "{\"buffer\":0,\"byteOffset\":48,\"byteLength\":48},{\"buffer\":0,\"byteOffset\":96,\"byteLength\":24}],"
                    "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
                    "{\"bufferView\":1,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"},"
                    "{\"bufferView\":2,\"componentType\":5125,\"count\":6,\"type\":\"SCALAR\"}]}",
                    sizeof bb, b2);
            free(b2);
            wrt_scene s;
            CHECK(load_text(t, 0, &s) != WRT_OK &&
                      strstr(wrt_last_error(), "meshes[0].primitives[0].attributes.NORMAL element 1") != NULL,
                  "a zero normal: %s", wrt_last_error());
            free(t);
            continue;
        }
        wrt_scene s;
        CHECK(load_text(t, 0, &s) == WRT_OK, "scale %s: %s", scales[c], wrt_last_error());
        free(t);
        double l = sqrt(want[c][0] * want[c][0] + want[c][2] * want[c][2]), worst = 0;
        int has = s.nquads == 1 && s.quads[0].has_nrm;
        for (int k = 0; k < 4 && has; k++)
            for (int d = 0; d < 3; d++) worst = fmax(worst, fabs(s.quads[0].vn[k][d] - want[c][d] / l));
        CHECK(has && worst < 1e-6 && s.quads[0].n.z > 0.999999, "scale %s: %d quads, normals off by %g, faces z %g",
              scales[c], s.nquads, worst, s.nquads ? s.quads[0].n.z : 0);
        wrt_scene_free(&s);
    }
    free(b);
}

/* The committed files under tests/data (also the fuzzing seeds). */
static void data_files(void) {
    static const struct { const char *name; wrt_status st; const char *needle; } cases[] = {
        {"quad.gltf", WRT_OK, ""},
        {"quad.glb", WRT_OK, ""},
        {"scene.gltf", WRT_OK, ""},
        {"bad_json.gltf", WRT_ERR_PARSE, "bad_json.gltf"},
        {"bad_count.gltf", WRT_ERR_PARSE, "count 2147483648"},
        {"bad_index.gltf", WRT_ERR_PARSE, "triangle 1: index 7"},
        {"bad_cycle.gltf", WRT_ERR_PARSE, "reached twice"},
        {"bad_nan.gltf", WRT_ERR_GEOMETRY, "has a NaN"},
        /* loadable since issue 21: two triangles of their own, and a lone triangle */
        {"bad_nonplanar.gltf", WRT_OK, ""},
        {"bad_unpaired.gltf", WRT_OK, ""},
        {"bad_truncated.glb", WRT_ERR_PARSE, "truncated"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char path[256];
        snprintf(path, sizeof path, "tests/data/%s", cases[i].name);
        wrt_scene s;
        wrt_status st = wrt_scene_load(path, NULL, &s);
        CHECK(st == cases[i].st, "%s: status %d: %s", path, st, wrt_last_error());
        if (st != WRT_OK) {
            CHECK(strstr(wrt_last_error(), cases[i].needle) && strstr(wrt_last_error(), cases[i].name),
                  "%s: '%s' not in: %s", path, cases[i].needle, wrt_last_error());
            continue;
        }
        if (strcmp(cases[i].name, "scene.gltf") == 0) {
            CHECK(s.nquads == 2 && s.nlights == 2 && s.camera.from_file && s.nmaterials == 2,
                  "scene.gltf: %d quads %d lights", s.nquads, s.nlights);
            /* floor: local y=0 plane, parent scaled 1.5 and lifted by -1: world y = -1 */
            CHECK(s.nquads == 2 && fabs(s.quads[0].p[0].y + 1) < 1e-6, "floor at y=-1");
            CHECK(s.nquads == 2 && fabs(s.quads[0].area - 9) < 1e-5, "floor area (2*1.5)^2 = %g", s.quads[0].area);
            CHECK(s.nquads == 2 && s.quads[0].n.y > 0.999999, "floor faces up");
        } else if (strcmp(cases[i].name, "bad_nonplanar.gltf") == 0) {
            CHECK(s.nquads == 6 && s.nsingle == 2, "%s: two triangles, %d quads", path, s.nquads);
        } else if (strcmp(cases[i].name, "bad_unpaired.gltf") == 0) {
            CHECK(s.nquads == 3 && s.nsingle == 1, "%s: one triangle, %d quads", path, s.nquads);
        } else {
            CHECK(s.nquads == 1, "%s: one quad", path);
        }
        wrt_scene_free(&s);
    }
}

static void quad_finish(void) {
    wrt_quad q = {0};
    q.p[0] = v3(0, 0, 0); q.p[1] = v3(2, 0, 0); q.p[2] = v3(3, 1, 0); q.p[3] = v3(1, 1, 0);
    CHECK(wrt_quad_finish(&q) == WRT_OK, "parallelogram");
    CHECK(q.parallelogram == 1, "flag");
    CHECK_NEAR(q.area, 2, 1e-12, "area");
    CHECK_NEAR(q.t.x, 1, 1e-12, "t = p1-p0");
    CHECK_NEAR(q.b.y, 1, 1e-12, "b = n x t");
    q.p[2] = v3(3, 1 + 1e-3, 0);
    CHECK(wrt_quad_finish(&q) == WRT_OK && q.parallelogram == 0, "off by 1e-3 is not a parallelogram");
    q.p[1] = v3(1, 1, 0); q.p[2] = v3(2, 2, 0); q.p[3] = v3(3, 3, 0);
    CHECK(wrt_quad_finish(&q) == WRT_ERR_GEOMETRY, "collinear");
}

int main(int argc, char **argv) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wrt_test_scene_XXXXXX");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 2; }
    TEST_RUN(quad_shared_vertices);
    TEST_RUN(quad_separate_vertices);
    TEST_RUN(quad_non_indexed);
    TEST_RUN(quad_reversed_order);
    TEST_RUN(trapezoid);
    TEST_RUN(grid_pairing);
    TEST_RUN(grid_uniform_shuffled);
    TEST_RUN(nested_transforms);
    TEST_RUN(scene_choice);
    TEST_RUN(materials);
    TEST_RUN(lights_and_camera);
    TEST_RUN(glb_and_hash);
    TEST_RUN(external_buffers);
    TEST_RUN(bad_json);
    TEST_RUN(bad_accessors);
    TEST_RUN(bad_geometry);
    TEST_RUN(triangle_elements);
    TEST_RUN(mirrored_nodes);
    TEST_RUN(normals_transformed);
    TEST_RUN(strict_fields);
    TEST_RUN(strict_warnings_and_ignored);
    TEST_RUN(double_sided);
    TEST_RUN(not_regular);
    TEST_RUN(data_files);
    TEST_RUN(quad_finish);
    const char *names[] = {"quad.glb", "quad.bin", "short.bin", "ext.gltf", "missing.gltf", "short.gltf", "dir.gltf"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        char p[512];
        snprintf(p, sizeof p, "%s/%s", tmpdir, names[i]);
        unlink(p);
    }
    rmdir(tmpdir);
    TEST_END();
}
