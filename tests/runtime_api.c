/* tests/runtime_api.c FACING.gto RANGED.gto [MORE.gto ...] [--glossy GLOSSY.gto]: the library's boundary through its public
 * header and libwrt.a alone. FACING is assets/test/facing.gltf baked (two unit squares
 * facing each other at z = 0 and z = 1, a point light at z = 0.5), RANGED the same scene
 * with the light's glTF range set to 0.75 (tests/runtime.sh makes both). Checks:
 *  - the version query against the header's macros; the options' size (0, sizeof, one
 *    too large, too small) and the allocator's both-or-neither rule;
 *  - handles: NULL, not a runtime, used after close, closed twice, NULL out-pointers and
 *    bad indices give a status (or -1 / NULL), never a crash;
 *  - bounds on what enters: a position of 1e308, an intensity of 3.4e38, a colour that
 *    takes the intensity past the bound, a bad range, and the bounds themselves accepted;
 *    a spot axis of length 1e300 gives bitwise what its unit axis gives;
 *  - the getters against the glTF file itself (lights with name and range, materials,
 *    camera, bounds, the quad-to-source map: mesh index and name, normal, area);
 *  - range: get_light then set_lights keeps it; a range short of every quad gives exact
 *    zeros, a huge one bitwise the unbounded light, and 0.75 scales each quad's mean
 *    direct irradiance by what brute-force integration of the glTF window gives;
 *  - allocations of a steady-state update, counted through the public allocator, on
 *    FACING and on each MORE file (at 46ed865: two blocks an update on FACING, the smooth
 *    display's scratch, one per group of quads, from common/reconstruct.c's
 *    wrt_recon_run).
 *  - superposition: every quad's texture of two lights set together against the sum of
 *    each alone, on FACING and each MORE file (and GLOSSY, eye set): within 1e-5 of the
 *    peak texel with linear_display (measured 1.4e-7 to 1.2e-6: the 2 x 2 maze, the
 *    glossy floor, the Cornell box), the default display's deviation printed beside it
 *    (0.061 on the 2 x 2 maze, 0.0026 on the glossy floor, 0.034 on the Cornell box);
 *  - with --glossy GLOSSY.gto: the open's progress (at least 10 calls, never falling,
 *    the last exactly 1, the first below 0.5), and a cancel from the callback at its
 *    first, middle and last call: WRT_ERR_CANCELLED, *out NULL, and as many frees as
 *    allocations through the counting allocator (nothing leaked).
 *  - wrt_runtime_open_path (API 4): WRT_OPEN_PRIVATE reads the file through the allocator
 *    (one block of the file's size more than a mapped open), and a copy of FACING opened
 *    so, then truncated to 0 bytes and removed, still relights to bitwise the mapped
 *    open's textures; a FIFO is refused at once (WRT_ERR_NOT_OURS, naming it), a missing
 *    file with WRT_ERR_IO naming it, a corrupt copy (a byte complemented) with
 *    WRT_ERR_CORRUPT naming it, a `how` of 2 with WRT_ERR_INVALID_ARG; the file info
 *    against the file's size on disk.
 * Prints "N passed, N failed". */
#include <wrt.h>

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <sys/stat.h>
#include <unistd.h>

static int passed, failed, skipped;
#define CHECK(c, ...) do { if (c) passed++; else { failed++; fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__); \
    fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); } } while (0)

/* ---- allocators: counting (sizes of the first blocks kept), and quarantining (free
 * keeps the block, so that reading a closed handle is defined for this test) ---- */
typedef struct counter { atomic_long allocs, frees, bytes; atomic_int nsizes; size_t sizes[64]; int record; } counter;
static void *c_alloc(void *u, size_t n) {
    counter *c = u;
    atomic_fetch_add(&c->allocs, 1);
    atomic_fetch_add(&c->bytes, (long)n);
    if (c->record) {
        int k = atomic_fetch_add(&c->nsizes, 1);
        if (k < 64) c->sizes[k] = n;
    }
    return malloc(n);
}
static void c_free(void *u, void *p) { if (p) atomic_fetch_add(&((counter *)u)->frees, 1); free(p); }

typedef struct quarantine { void *kept[4096]; int n; } quarantine;
static void *q_alloc(void *u, size_t n) { (void)u; return malloc(n); }
static void q_free(void *u, void *p) {
    quarantine *q = u;
    if (!p) return;
    if (q->n < 4096) q->kept[q->n++] = p; else free(p);
}
static void q_release(quarantine *q) { for (int i = 0; i < q->n; i++) free(q->kept[i]); q->n = 0; }

static int near(double a, double b, double tol) { return fabs(a - b) <= tol; }

/* Every quad's texture, concatenated (malloc'd; *n floats). */
static float *grab(wrt_runtime *rt, size_t *n) {
    size_t total = 0;
    int nq = wrt_runtime_quad_count(rt);
    for (int q = 0; q < nq; q++) { int res; wrt_runtime_quad_texture(rt, q, &res); total += (size_t)res * res * 3; }
    float *t = malloc(total * sizeof(float) + 1), *p = t;
    for (int q = 0; q < nq; q++) {
        int res;
        const float *x = wrt_runtime_quad_texture(rt, q, &res);
        memcpy(p, x, (size_t)res * res * 3 * sizeof(float));
        p += (size_t)res * res * 3;
    }
    *n = total;
    return t;
}

/* Relights with one light and returns the textures. */
static float *relight(wrt_runtime *rt, const wrt_runtime_light *l, size_t *n) {
    wrt_error err;
    double eye[3] = {2.5, 0.8, 1.5};
    wrt_status s;
    if ((s = wrt_runtime_set_lights(rt, l, 1, &err)) || (s = wrt_runtime_set_eye(rt, eye, &err)) ||
        (s = wrt_runtime_update(rt, NULL, &err))) {
        fprintf(stderr, "relight: %s\n", err.message);
        *n = 0;
        return NULL;
    }
    return grab(rt, n);
}

static int same(const float *a, size_t na, const float *b, size_t nb) {
    return a && b && na == nb && !memcmp(a, b, na * sizeof(float));
}

/* glTF's range window (KHR_lights_punctual): clamp(1 - (d/r)^4, 0, 1)^2, r = 0: 1. */
static double window(double d, double r) {
    if (r <= 0) return 1;
    double t = d / r, w = 1 - t * t * t * t;
    w = w < 0 ? 0 : w > 1 ? 1 : w;
    return w * w;
}

/* Mean irradiance over the unit square at z = z0 (|x|, |y| <= 0.5) from a unit point light
 * at (0, 0, 0.5), with range r: brute force, 600 x 600 midpoints. */
static double square_irradiance(double z0, double r) {
    const int n = 600;
    double acc = 0, h = 0.5 - z0, ah = fabs(h);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double x = -0.5 + (i + 0.5) / n, y = -0.5 + (j + 0.5) / n;
            double d2 = x * x + y * y + h * h, d = sqrt(d2);
            acc += (ah / d) / d2 * window(d, r);
        }
    return acc / ((double)n * n);
}

static void test_version(void) {
    CHECK(wrt_version() == WRT_VERSION && WRT_VERSION == 100, "wrt_version %d, header %d", wrt_version(), WRT_VERSION);
    CHECK(!strcmp(wrt_version_string(), WRT_VERSION_STRING) && !strcmp(WRT_VERSION_STRING, "0.1.0"),
          "wrt_version_string '%s'", wrt_version_string());
    CHECK(wrt_api_version() == WRT_API_VERSION && WRT_API_VERSION == 5, "wrt_api_version %d", wrt_api_version());
    CHECK(!strcmp(wrt_status_str(WRT_ERR_INVALID_ARG), "invalid argument") &&
          !strcmp(wrt_status_str((wrt_status)99), "unknown status"), "wrt_status_str");
}

static void test_options(const char *path) {
    wrt_error err;
    wrt_runtime *rt = (wrt_runtime *)&err;
    wrt_runtime_options o = {.size = sizeof o, .threads = 1};
    CHECK(wrt_runtime_open_file(path, &o, &rt, &err) == WRT_OK && rt, "size = sizeof: %s", err.message);
    CHECK(wrt_runtime_close(rt) == WRT_OK, "close");
    o.size = 0;
    CHECK(wrt_runtime_open_file(path, &o, &rt, &err) == WRT_OK && rt, "size 0: %s", err.message);
    wrt_runtime_close(rt);
    o.size = sizeof o + 8;
    rt = (wrt_runtime *)&err;
    wrt_status s = wrt_runtime_open_file(path, &o, &rt, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && rt == NULL && strstr(err.message, "size"), "size too large: %d '%s'", s,
          err.message);
    o.size = sizeof(int);
    s = wrt_runtime_open_file(path, &o, &rt, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && rt == NULL, "size too small: %d '%s'", s, err.message);
    /* a negative thread count was taken as 0 (all cores) without a word (issue 25) */
    o.size = sizeof o;
    o.threads = -3;
    s = wrt_runtime_open_file(path, &o, &rt, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && rt == NULL && strstr(err.message, "threads -3"), "threads -3: %d '%s'", s,
          err.message);
    o.threads = 1;
    wrt_runtime_options d = {0};
    CHECK(wrt_runtime_defaults(&d) == WRT_OK && d.max_tex_res == 64 && d.threads == 0 && d.allocator.alloc &&
          d.allocator.free && d.size == 0, "defaults: max_tex_res %d, threads %d", d.max_tex_res, d.threads);
    CHECK(wrt_runtime_defaults(NULL) == WRT_ERR_INVALID_ARG, "defaults(NULL)");
    d = (wrt_runtime_options){.size = sizeof d + 1};
    CHECK(wrt_runtime_defaults(&d) == WRT_ERR_INVALID_ARG, "defaults with a size too large");
    counter c = {0};
    wrt_runtime_options half = {.allocator = {c_alloc, NULL, &c}};
    s = wrt_runtime_open_file(path, &half, &rt, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && rt == NULL && c.allocs == 0, "allocator with alloc only: %d '%s'", s, err.message);
}

static void test_handles(const char *path) {
    wrt_error err;
    wrt_status s;
    /* NULL handle */
    CHECK(wrt_runtime_update(NULL, NULL, &err) == WRT_ERR_INVALID_ARG && strstr(err.message, "NULL"),
          "update(NULL): '%s'", err.message);
    CHECK(wrt_runtime_close(NULL) == WRT_OK, "close(NULL) is a no-op");
    CHECK(wrt_runtime_quad_count(NULL) == -1 && wrt_runtime_light_count(NULL) == -1 &&
          wrt_runtime_material_count(NULL) == -1, "counts of NULL: -1");
    int res = 7;
    CHECK(wrt_runtime_quad_texture(NULL, 0, &res) == NULL && res == 0, "texture of NULL");
    /* NULL out-pointers */
    CHECK(wrt_runtime_open_file(path, NULL, NULL, &err) == WRT_ERR_INVALID_ARG, "open with out NULL");
    wrt_runtime *none = (wrt_runtime *)&err;
    CHECK(wrt_runtime_open_file(NULL, NULL, &none, &err) == WRT_ERR_INVALID_ARG && none == NULL, "open of a NULL path");
    /* not a runtime: a zeroed block */
    static uint64_t junk[512];
    wrt_runtime *fake = (wrt_runtime *)junk;
    CHECK(wrt_runtime_update(fake, NULL, &err) == WRT_ERR_INVALID_ARG && strstr(err.message, "not a live runtime"),
          "not a runtime: '%s'", err.message);
    CHECK(wrt_runtime_close(fake) == WRT_ERR_INVALID_ARG, "close of a non-runtime");
    /* a live one, with a quarantining allocator: after close its memory stays ours */
    static quarantine qa;
    wrt_runtime_options o = {.threads = 1, .allocator = {q_alloc, q_free, &qa}};
    wrt_runtime *rt;
    if (wrt_runtime_open_file(path, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    int nq = wrt_runtime_quad_count(rt);
    double p[4][3], d3[3], i3[3], ms[4];
    float m3[3];
    wrt_runtime_light l;
    wrt_runtime_quad qd;
    wrt_runtime_material mat;
    wrt_runtime_camera cam;
    CHECK(wrt_runtime_get_light(rt, 0, NULL, &err) == WRT_ERR_INVALID_ARG, "get_light out NULL");
    CHECK(wrt_runtime_get_light(rt, 1, &l, &err) == WRT_ERR_INVALID_ARG && strstr(err.message, "no light 1"),
          "get_light index: '%s'", err.message);
    CHECK(wrt_runtime_get_quad(rt, 0, NULL, &err) == WRT_ERR_INVALID_ARG, "get_quad out NULL");
    CHECK(wrt_runtime_get_quad(rt, nq, &qd, &err) == WRT_ERR_INVALID_ARG && wrt_runtime_get_quad(rt, -1, &qd, NULL),
          "get_quad index");
    CHECK(wrt_runtime_quad_corners(rt, nq, p, &err) == WRT_ERR_INVALID_ARG, "corners index");
    CHECK(wrt_runtime_quad_mean(rt, -1, m3, &err) == WRT_ERR_INVALID_ARG && wrt_runtime_quad_mean(rt, 0, NULL, NULL),
          "mean index / NULL");
    CHECK(wrt_runtime_quad_irradiance(rt, nq, d3, i3, &err) == WRT_ERR_INVALID_ARG &&
          wrt_runtime_quad_irradiance(rt, 0, NULL, i3, NULL), "irradiance index / NULL");
    CHECK(wrt_runtime_quad_texture(rt, nq, &res) == NULL && res == 0, "texture index");
    CHECK(wrt_runtime_get_material(rt, 0, NULL, &err) && wrt_runtime_get_material(rt, 99, &mat, &err),
          "get_material NULL / index");
    CHECK(wrt_runtime_get_camera(rt, NULL, &err) == WRT_ERR_INVALID_ARG, "get_camera NULL");
    CHECK(wrt_runtime_get_bounds(rt, NULL, d3, &err) == WRT_ERR_INVALID_ARG, "get_bounds NULL");
    CHECK(wrt_runtime_timings(rt, NULL, &err) == WRT_ERR_INVALID_ARG, "timings NULL");
    CHECK(wrt_runtime_set_eye(rt, NULL, &err) == WRT_ERR_INVALID_ARG, "set_eye NULL");
    CHECK(wrt_runtime_set_lights(rt, NULL, 1, &err) == WRT_ERR_INVALID_ARG, "set_lights NULL array");
    CHECK(wrt_runtime_update(rt, NULL, &err) == WRT_OK, "update before close: %s", err.message);
    /* use after close, double close */
    CHECK(wrt_runtime_close(rt) == WRT_OK, "close");
    int changed = 5;
    s = wrt_runtime_update(rt, &changed, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && changed == 0 && strstr(err.message, "not a live runtime"),
          "update after close: %d '%s'", s, err.message);
    CHECK(wrt_runtime_set_lights(rt, &l, 0, &err) == WRT_ERR_INVALID_ARG, "set_lights after close");
    CHECK(wrt_runtime_get_quad(rt, 0, &qd, &err) == WRT_ERR_INVALID_ARG, "get_quad after close");
    CHECK(wrt_runtime_get_camera(rt, &cam, &err) == WRT_ERR_INVALID_ARG, "get_camera after close");
    CHECK(wrt_runtime_quad_cells(rt, 0, 2, ms, &err) == WRT_ERR_INVALID_ARG, "quad_cells after close");
    CHECK(wrt_runtime_timings(rt, ms, &err) == WRT_ERR_INVALID_ARG, "timings after close");
    CHECK(wrt_runtime_quad_count(rt) == -1 && wrt_runtime_quad_texture(rt, 0, &res) == NULL, "getters after close");
    int freed = qa.n;
    CHECK(wrt_runtime_close(rt) == WRT_ERR_INVALID_ARG && qa.n == freed, "double close: a status, nothing freed twice");
    q_release(&qa);
}

static void test_bounds(const char *path) {
    wrt_error err;
    wrt_runtime *rt;
    wrt_runtime_options o = {.threads = 1};
    if (wrt_runtime_open_file(path, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    wrt_runtime_light base = {0};
    base.position[2] = 0.5;
    base.intensity = 1;
    struct { const char *what; wrt_runtime_light l; int ok; } cases[12];
    int n = 0;
#define CASE(w, ok_, ...) do { cases[n].what = w; cases[n].l = base; { wrt_runtime_light *L = &cases[n].l; __VA_ARGS__; } \
    cases[n++].ok = ok_; } while (0)
    CASE("position 1e308", 0, L->position[0] = 1e308);
    CASE("position -1.0001e9", 0, L->position[1] = -1.0001e9);
    CASE("position 1e9 (the bound)", 1, L->position[1] = 1e9);
    CASE("intensity 3.4e38", 0, L->intensity = 3.4e38f);
    CASE("intensity 1e20 (the bound)", 1, L->intensity = 1e20f);
    CASE("intensity 1e20 x colour 2", 0, L->intensity = 1e20f; L->color[0] = 2; L->color[1] = 1; L->color[2] = 1);
    CASE("colour 1e30 at intensity 0", 0, L->intensity = 0; L->color[2] = 1e30f);
    CASE("range -1", 0, L->range = -1);
    CASE("range NaN", 0, L->range = NAN);
    CASE("range 1e30", 1, L->range = 1e30f);
    CASE("spot axis 0", 0, L->kind = WRT_LIGHT_KIND_SPOT);
    CASE("spot axis 1e308", 1, L->kind = WRT_LIGHT_KIND_SPOT; L->direction[2] = -1e308);
    for (int i = 0; i < n; i++) {
        err.message[0] = 0;
        wrt_status s = wrt_runtime_set_lights(rt, &cases[i].l, 1, &err);
        CHECK(cases[i].ok ? s == WRT_OK : s == WRT_ERR_INVALID_ARG && strstr(err.message, "light 0"),
              "%s: %s (status %d, '%s')", cases[i].what, cases[i].ok ? "accepted" : "refused", s, err.message);
    }
    double far[3] = {0, 1e308, 0}, edge[3] = {0, 0, -1e9};
    CHECK(wrt_runtime_set_eye(rt, far, &err) == WRT_ERR_INVALID_ARG && strstr(err.message, "WRT_MAX_COORD"),
          "eye at 1e308: '%s'", err.message);
    CHECK(wrt_runtime_set_eye(rt, edge, &err) == WRT_OK, "eye at -1e9 accepted");
    /* a spot's axis of any length: bitwise what its unit axis gives */
    wrt_runtime_light a = base, b = base;
    a.kind = b.kind = WRT_LIGHT_KIND_SPOT;
    a.direction[2] = -1e300;
    b.direction[2] = -1;
    a.outer_cone = b.outer_cone = 0.6f;
    size_t na, nb;
    float *ta = relight(rt, &a, &na), *tb = relight(rt, &b, &nb);
    int lit = 0;
    for (size_t i = 0; tb && i < nb; i++) lit |= tb[i] > 0;
    CHECK(same(ta, na, tb, nb) && lit, "spot axis (0,0,-1e300) gives bitwise the unit axis' textures (lit: %d)", lit);
    free(ta); free(tb);
    wrt_runtime_close(rt);
}

static void test_getters(const char *path) {
    wrt_error err;
    wrt_runtime *rt;
    wrt_runtime_options o = {.threads = 1};
    if (wrt_runtime_open_file(path, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    /* assets/test/facing.gltf: one light "light", point, white, intensity 1 at (0, 0, 0.5) */
    wrt_runtime_light l;
    CHECK(wrt_runtime_light_count(rt) == 1 && wrt_runtime_get_light(rt, 0, &l, &err) == WRT_OK, "one light");
    CHECK(!strcmp(l.name, "light") && l.kind == WRT_LIGHT_KIND_POINT && l.position[0] == 0 && l.position[1] == 0 &&
          l.position[2] == 0.5 && l.intensity == 1 && l.color[0] == 1 && l.color[2] == 1 && l.range == 0 && !l.off,
          "light: '%s' kind %d at (%g, %g, %g), intensity %g, range %g", l.name, l.kind, l.position[0],
          l.position[1], l.position[2], l.intensity, l.range);
    /* material "grey": base colour 0.75, metallic 0, roughness 1 */
    wrt_runtime_material m;
    CHECK(wrt_runtime_material_count(rt) == 1 && wrt_runtime_get_material(rt, 0, &m, &err) == WRT_OK, "one material");
    CHECK(!strcmp(m.name, "grey") && near(m.base_color[0], 0.75, 1e-7) && near(m.base_color[2], 0.75, 1e-7) &&
          m.metallic == 0 && m.roughness == 1 && m.lambertian == 1,
          "material '%s' (%g %g %g) metallic %g roughness %g", m.name, m.base_color[0], m.base_color[1],
          m.base_color[2], m.metallic, m.roughness);
    /* camera at (2.5, 0.8, 1.5), yfov 0.7853982, znear 0.01, zfar 1000 */
    wrt_runtime_camera c;
    CHECK(wrt_runtime_get_camera(rt, &c, &err) == WRT_OK && c.from_file && near(c.position[0], 2.5, 1e-6) &&
          near(c.position[1], 0.8, 1e-6) && near(c.position[2], 1.5, 1e-6) && near(c.yfov, 0.7853982, 1e-6) &&
          near(c.znear, 0.01, 1e-9) && near(c.zfar, 1000, 1e-9) &&
          near(c.direction[0] * c.direction[0] + c.direction[1] * c.direction[1] + c.direction[2] * c.direction[2], 1, 1e-9),
          "camera at (%g, %g, %g), yfov %g", c.position[0], c.position[1], c.position[2], c.yfov);
    /* bounds: the two squares, [-0.5, 0.5]^2 x [0, 1] */
    double lo[3], hi[3];
    CHECK(wrt_runtime_get_bounds(rt, lo, hi, &err) == WRT_OK && lo[0] == -0.5 && lo[1] == -0.5 && lo[2] == 0 &&
          hi[0] == 0.5 && hi[1] == 0.5 && hi[2] == 1, "bounds (%g %g %g) - (%g %g %g)", lo[0], lo[1], lo[2], hi[0],
          hi[1], hi[2]);
    /* the quad-to-source map: square_a (mesh 0) at z = 0 facing +z, square_b (mesh 1) at
     * z = 1 facing -z (its vertex normals), each of area 1; the .gto 1.2 source map: node
     * k places mesh k, primitive 0, its triangles 0 and 1 paired, not a twin, no TEXCOORD_0 */
    int nq = wrt_runtime_quad_count(rt), seen[2] = {0, 0}, map_ok = nq == 2;
    for (int q = 0; q < nq; q++) {
        wrt_runtime_quad qd;
        if (wrt_runtime_get_quad(rt, q, &qd, &err)) { map_ok = 0; continue; }
        double z = qd.corners[0][2];
        int want = z == 0 ? 0 : 1;
        for (int k = 0; k < 4; k++) map_ok &= qd.corners[k][2] == z;
        map_ok &= qd.mesh == want && !strcmp(qd.mesh_name, want ? "square_b" : "square_a");
        map_ok &= near(qd.normal[2], want ? -1 : 1, 1e-12) && near(qd.area, 1, 1e-6) && qd.material == 0;
        map_ok &= qd.node == want && qd.primitive == 0 && qd.triangles[0] + qd.triangles[1] == 1 &&
                  qd.triangles[0] * qd.triangles[1] == 0 && qd.twin == 0 && qd.twin_of == -1 &&
                  qd.kind == WRT_QUAD_KIND_PAIR && qd.part == 0 && qd.has_uv == 0;
        double p[4][3];
        map_ok &= wrt_runtime_quad_corners(rt, q, p, NULL) == WRT_OK && !memcmp(p, qd.corners, sizeof p);
        seen[want]++;
        printf("quad %d: node %d mesh %d '%s' primitive %d triangles %d %d, z %g, normal z %g, area %g\n", q, qd.node,
               qd.mesh, qd.mesh_name, qd.primitive, qd.triangles[0], qd.triangles[1], z, qd.normal[2], qd.area);
    }
    CHECK(map_ok && seen[0] == 1 && seen[1] == 1, "quad-to-source map: each square's node, mesh, name, primitive, triangles, normal, area");
    wrt_runtime_close(rt);
}

static void test_range(const char *facing, const char *ranged) {
    wrt_error err;
    wrt_runtime *rt;
    wrt_runtime_options o = {.threads = 1};
    if (wrt_runtime_open_file(ranged, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    wrt_runtime_light l;
    CHECK(wrt_runtime_get_light(rt, 0, &l, &err) == WRT_OK && l.range == 0.75f, "the file's range: %g", l.range);
    size_t n0, n1, n2, n3;
    float *got = relight(rt, &l, &n0); /* get_light then set_lights */
    double dir_r[2][3], ind[3], dir_u[2][3];
    for (int q = 0; q < 2; q++) wrt_runtime_quad_irradiance(rt, q, dir_r[q], ind, NULL);
    wrt_runtime_light u = l;
    u.range = 0;
    float *unb = relight(rt, &u, &n1);
    for (int q = 0; q < 2; q++) wrt_runtime_quad_irradiance(rt, q, dir_u[q], ind, NULL);
    CHECK(got && unb && !same(got, n0, unb, n1), "get_light then set_lights keeps the range (the result differs from "
          "the unbounded light's)");
    /* each square's mean direct irradiance, ranged over unbounded, against brute force */
    for (int q = 0; q < 2; q++) {
        wrt_runtime_quad qd;
        wrt_runtime_get_quad(rt, q, &qd, NULL);
        double z0 = qd.corners[0][2];
        double want = square_irradiance(z0, 0.75) / square_irradiance(z0, 0), have = dir_r[q][0] / dir_u[q][0];
        printf("quad %d (z %g): ranged / unbounded direct irradiance %.5f, brute force %.5f\n", q, z0, have, want);
        CHECK(fabs(have - want) <= 0.01 * want, "quad %d: ranged / unbounded %.5f, brute force %.5f", q, have, want);
    }
    /* a range short of every quad (nearest point 0.5 away): exact zeros */
    wrt_runtime_light s = l;
    s.range = 0.45f;
    float *shortr = relight(rt, &s, &n2);
    int zero = shortr != NULL;
    for (size_t i = 0; shortr && i < n2; i++) zero &= shortr[i] == 0;
    CHECK(zero, "range 0.45: every texel exactly 0");
    /* a huge range: bitwise the unbounded light */
    s.range = 1e30f;
    float *huge = relight(rt, &s, &n3);
    CHECK(same(huge, n3, unb, n1), "range 1e30: bitwise the unbounded light");
    free(got); free(unb); free(shortr); free(huge);
    wrt_runtime_close(rt);
    /* the unranged file's light, given the range by hand: the same as the ranged file's */
    if (wrt_runtime_open_file(facing, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    wrt_runtime_get_light(rt, 0, &u, NULL);
    u.range = 0.75f;
    size_t nf;
    float *byhand = relight(rt, &u, &nf);
    wrt_runtime_close(rt);
    wrt_runtime_open_file(ranged, &o, &rt, &err);
    float *again = relight(rt, &l, &n0);
    CHECK(same(byhand, nf, again, n0), "range set by hand on the unranged file: bitwise the ranged file's light");
    free(byhand); free(again);
    wrt_runtime_close(rt);
}

/* 10 updates with a moving light after the first: allocations through the public hooks. */
static void test_steady_allocations(const char *path) {
    counter c = {0};
    wrt_error err;
    wrt_runtime *rt;
    wrt_runtime_options o = {.threads = 2, .allocator = {c_alloc, c_free, &c}};
    if (wrt_runtime_open_file(path, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    wrt_runtime_light l;
    wrt_runtime_get_light(rt, 0, &l, NULL);
    double eye[3] = {2.5, 0.8, 1.5};
    wrt_runtime_set_eye(rt, eye, NULL);
    wrt_status s = wrt_runtime_set_lights(rt, &l, 1, &err);
    if (!s) s = wrt_runtime_update(rt, NULL, &err);
    CHECK(s == WRT_OK, "first update: %s", err.message);
    long a0 = atomic_load(&c.allocs), b0 = atomic_load(&c.bytes);
    c.record = 1;
    int changed_all = 1;
    for (int k = 1; k <= 10 && !s; k++) {
        wrt_runtime_light m = l;
        m.position[0] += 0.02 * cos(k);
        m.position[1] += 0.02 * sin(k);
        int changed = 0;
        if (!(s = wrt_runtime_set_lights(rt, &m, 1, &err))) s = wrt_runtime_update(rt, &changed, &err);
        changed_all &= changed > 0;
    }
    long na = atomic_load(&c.allocs) - a0, nb = atomic_load(&c.bytes) - b0;
    CHECK(s == WRT_OK && changed_all, "10 updates with a moving light, each changing textures");
    printf("%s: steady state: %ld allocations (%ld bytes) through the allocator in 10 updates after the first", path, na, nb);
    int ns = atomic_load(&c.nsizes);
    for (int i = 0; i < ns && i < 12; i++) printf("%s%zu", i ? ", " : "; sizes: ", c.sizes[i]);
    printf("%s\n", ns > 12 ? ", ..." : "");
    CHECK(na == 0, "a steady-state update allocates nothing: %ld allocations in 10 updates", na);
    wrt_runtime_close(rt);
    CHECK(c.allocs == c.frees, "allocator: %ld blocks, %ld freed", (long)c.allocs, (long)c.frees);
}

/* The atlas: the layout is deterministic, tiles inside and apart; the fill puts each
 * quad's texture bit for bit in its block, repeats its edge texels in the border, leaves
 * 0 elsewhere, writes nothing past width x height x 3 and allocates nothing; bad
 * arguments are refused with a message. */
static void test_atlas(const char *path) {
    counter c = {0};
    wrt_error err;
    wrt_runtime *rt;
    wrt_runtime_options o = {.threads = 1, .allocator = {c_alloc, c_free, &c}};
    if (wrt_runtime_open_file(path, &o, &rt, &err)) { CHECK(0, "open: %s", err.message); return; }
    int nq = wrt_runtime_quad_count(rt), w = 0, h = 0, w2 = 0, h2 = 0;
    wrt_atlas_rect *r = calloc((size_t)nq, sizeof *r), *r2 = calloc((size_t)nq, sizeof *r2);
    CHECK(wrt_runtime_atlas_layout(rt, 0, r, &w, &h, &err) == WRT_OK && wrt_runtime_atlas_layout(rt, 0, r2, &w2, &h2, NULL) == WRT_OK &&
          w == w2 && h == h2 && !memcmp(r, r2, (size_t)nq * sizeof *r), "layout: deterministic, %d x %d for %d quads", w, h, nq);
    unsigned char *cover = calloc((size_t)w * h, 1);
    int inside = 1, apart = 1;
    for (int q = 0; q < nq; q++) {
        int res;
        wrt_runtime_quad_texture(rt, q, &res);
        inside &= r[q].res == res && r[q].x >= 1 && r[q].y >= 1 && r[q].x + res + 1 <= w && r[q].y + res + 1 <= h;
        if (!inside) break;
        for (int j = r[q].y - 1; j <= r[q].y + res; j++)
            for (int i = r[q].x - 1; i <= r[q].x + res; i++) apart &= !cover[(size_t)j * w + i]++;
    }
    CHECK(inside && apart, "tiles (texture + border of 1) inside the atlas and apart");
    wrt_runtime_light l;
    wrt_runtime_get_light(rt, 0, &l, NULL);
    size_t n;
    free(relight(rt, &l, &n));
    size_t nf = (size_t)w * h * 3;
    float *rgb = malloc((nf + 3) * sizeof *rgb);
    for (size_t i = 0; i < nf + 3; i++) rgb[i] = -7.0f;
    long a0 = atomic_load(&c.allocs);
    CHECK(wrt_runtime_atlas_fill(rt, r, w, h, rgb, nf, &err) == WRT_OK, "fill: %s", err.message);
    CHECK(atomic_load(&c.allocs) == a0, "fill allocates nothing");
    CHECK(rgb[nf] == -7.0f && rgb[nf + 1] == -7.0f && rgb[nf + 2] == -7.0f, "nothing written past the atlas");
    int exact = 1, border = 1, zero = 1;
    double peak = 0;
    for (int q = 0; q < nq && inside; q++) {
        int res;
        const float *t = wrt_runtime_quad_texture(rt, q, &res);
        for (int j = -1; j <= res; j++)
            for (int i = -1; i <= res; i++) {
                int si = i < 0 ? 0 : i >= res ? res - 1 : i, sj = j < 0 ? 0 : j >= res ? res - 1 : j;
                const float *a = rgb + ((size_t)(r[q].y + j) * w + (size_t)(r[q].x + i)) * 3, *b = t + ((size_t)sj * res + si) * 3;
                int eq = !memcmp(a, b, 3 * sizeof *a);
                if (i == si && j == sj) exact &= eq; else border &= eq;
                if (a[0] > peak) peak = a[0];
            }
    }
    for (size_t k = 0; k < (size_t)w * h; k++)
        if (!cover[k]) zero &= rgb[3 * k] == 0 && rgb[3 * k + 1] == 0 && rgb[3 * k + 2] == 0;
    CHECK(exact && border && zero && peak > 0, "fill: blocks bit for bit (peak %g), borders repeat edges, 0 between", peak);
    /* refusals */
    wrt_status st = wrt_runtime_atlas_layout(rt, 2, r2, NULL, NULL, &err);
    CHECK(st == WRT_ERR_INVALID_ARG && strstr(err.message, "widest tile"), "width 2 refused: %s", err.message);
    st = wrt_runtime_atlas_fill(rt, r, w, h, rgb, nf - 1, &err);
    CHECK(st == WRT_ERR_INVALID_ARG && strstr(err.message, "the buffer has"), "short buffer refused: %s", err.message);
    r2[0] = r[0];
    r2[0].res *= 2;
    memcpy(r2 + 1, r + 1, (size_t)(nq - 1) * sizeof *r2);
    st = wrt_runtime_atlas_fill(rt, r2, w, h, rgb, nf, &err);
    CHECK(st == WRT_ERR_INVALID_ARG && strstr(err.message, "quad 0's rect"), "a rect of the wrong size refused: %s", err.message);
    r2[0] = r[0];
    r2[0].x = w - r[0].res;
    st = wrt_runtime_atlas_fill(rt, r2, w, h, rgb, nf, &err);
    CHECK(st == WRT_ERR_INVALID_ARG, "a rect whose border leaves the atlas refused: %s", err.message);
    CHECK(wrt_runtime_atlas_fill(rt, NULL, w, h, rgb, nf, &err) == WRT_ERR_INVALID_ARG &&
          wrt_runtime_atlas_layout(NULL, 0, r, NULL, NULL, &err) == WRT_ERR_INVALID_ARG, "NULL rects, NULL handle refused");
    free(rgb); free(cover); free(r); free(r2);
    wrt_runtime_close(rt);
}

/* ---- superposition: quad textures of lights A and B set together against the sum of
 * each alone. Returns the largest texel deviation over the pair's peak texel (all quads,
 * RGB); -1 on failure. The eye is set, so glossy quads are drawn too. */
static double superposition(const char *path, int linear) {
    wrt_runtime_options o = {.size = sizeof o, .threads = 1, .linear_display = linear};
    wrt_runtime *rt;
    wrt_error err;
    if (wrt_runtime_open_file(path, &o, &rt, &err)) { fprintf(stderr, "%s: %s\n", path, err.message); return -1; }
    double lo[3], hi[3];
    wrt_runtime_get_bounds(rt, lo, hi, NULL);
    wrt_runtime_light l[2] = {{.intensity = 1}, {.intensity = 2, .color = {1, 0.5f, 0.25f}}};
    for (int c = 0; c < 3; c++) { /* two points inside the box, apart */
        l[0].position[c] = lo[c] + (c == 1 ? 0.8 : 0.3) * (hi[c] - lo[c]);
        l[1].position[c] = lo[c] + (c == 1 ? 0.6 : 0.7) * (hi[c] - lo[c]);
    }
    double eye[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    wrt_runtime_set_eye(rt, eye, NULL);
    int nq = wrt_runtime_quad_count(rt);
    size_t total = 0;
    for (int q = 0; q < nq; q++) { int res; wrt_runtime_quad_texture(rt, q, &res); total += (size_t)res * res * 3; }
    float *t[3];
    for (int k = 0; k < 3; k++) t[k] = calloc(total + 1, sizeof(float));
    double dev = -1;
    for (int k = 0; k < 3; k++) { /* A alone, B alone, both */
        if (wrt_runtime_set_lights(rt, k == 2 ? l : &l[k], k == 2 ? 2 : 1, &err) || wrt_runtime_update(rt, NULL, &err))
            goto done;
        size_t off = 0;
        for (int q = 0; q < nq; q++) {
            int res;
            const float *tex = wrt_runtime_quad_texture(rt, q, &res);
            memcpy(t[k] + off, tex, (size_t)res * res * 3 * sizeof(float));
            off += (size_t)res * res * 3;
        }
    }
    double peak = 0, worst = 0;
    for (size_t i = 0; i < total; i++) {
        peak = fmax(peak, fabs(t[2][i]));
        worst = fmax(worst, fabs((double)t[2][i] - t[0][i] - t[1][i]));
    }
    dev = peak > 0 ? worst / peak : -1;
done:
    for (int k = 0; k < 3; k++) free(t[k]);
    wrt_runtime_close(rt);
    return dev;
}

static void test_superposition(const char *path) {
    double lin = superposition(path, 1), def = superposition(path, 0);
    printf("superposition %s: linear display %.3g of the peak, default display %.3g\n", path, lin, def);
    CHECK(lin >= 0 && lin <= 1e-5, "linear display: the pair differs from the sum by %.3g of the peak", lin);
    CHECK(def >= 0, "default display");
}

/* ---- progress and cancel of the open, on a glossy file (the final gather's rays) ---- */
typedef struct prog { int n, cancel_at, bad_order; double last, first, t_last, gap; double fr[4096]; } prog;
static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}
static int on_progress(void *u, double f) {
    prog *p = u;
    double t = now_s();
    if (p->n == 0) p->first = f;
    else {
        if (f < p->last) p->bad_order++;
        if (t - p->t_last > p->gap) p->gap = t - p->t_last;
    }
    if (p->n < 4096) p->fr[p->n] = f;
    p->n++;
    p->last = f;
    p->t_last = t;
    return p->n != p->cancel_at;
}

static void test_progress(const char *glossy) {
    prog p = {0};
    counter c = {0};
    wrt_runtime_options o = {.size = sizeof o, .threads = 2, .allocator = {c_alloc, c_free, &c},
                             .progress = on_progress, .progress_user = &p};
    wrt_runtime *rt;
    wrt_error err;
    double t0 = now_s();
    wrt_status s = wrt_runtime_open_file(glossy, &o, &rt, &err);
    double t1 = now_s();
    CHECK(s == WRT_OK && rt, "open with progress: %s", err.message);
    printf("progress %s: %d calls in %.2f s, largest gap %.0f ms, first %.3g, last %.3g\n", glossy, p.n, t1 - t0,
           1e3 * p.gap, p.first, p.last);
    CHECK(p.n >= 10 && p.bad_order == 0 && p.last == 1.0 && p.first >= 0 && p.first < 0.5,
          "progress: %d calls, %d out of order, last %g", p.n, p.bad_order, p.last);
    int full = p.n;
    wrt_runtime_close(rt);
    CHECK(c.allocs == c.frees, "open and close: %ld allocations, %ld frees", (long)c.allocs, (long)c.frees);
    /* cancel at the first call, in the middle, and at the last (fraction 1) */
    int at[3] = {1, full / 2, full};
    for (int k = 0; k < 3; k++) {
        prog pc = {.cancel_at = at[k]};
        counter cc = {0};
        wrt_runtime_options oc = o;
        oc.allocator = (wrt_allocator){c_alloc, c_free, &cc};
        oc.progress_user = &pc;
        rt = (wrt_runtime *)&err;
        s = wrt_runtime_open_file(glossy, &oc, &rt, &err);
        CHECK(s == WRT_ERR_CANCELLED && err.status == WRT_ERR_CANCELLED && rt == NULL && pc.n == at[k],
              "cancel at call %d: status %d, %d calls, '%s'", at[k], s, pc.n, err.message);
        CHECK(cc.allocs > 0 && cc.allocs == cc.frees, "cancel at call %d: %ld allocations, %ld frees", at[k],
              (long)cc.allocs, (long)cc.frees);
    }
}

/* Copies file `from` to `to` (the test's scratch): 0 on success. */
static int copy_file(const char *from, const char *to, long flip) {
    FILE *a = fopen(from, "rb"), *b = fopen(to, "wb");
    int ok = a && b;
    for (long i = 0; ok; i++) {
        int c = fgetc(a);
        if (c == EOF) break;
        if (i == flip) c ^= 0xff;
        ok = fputc(c, b) != EOF;
    }
    if (a) fclose(a);
    if (b && fclose(b)) ok = 0;
    return ok ? 0 : -1;
}

static void test_open_path(const char *path) {
    wrt_error err;
    wrt_runtime *map = NULL, *priv = NULL, *none = (wrt_runtime *)1;
    char copy[512], fifo[512];
    snprintf(copy, sizeof copy, "%s.private-copy.%d", path, (int)getpid());
    snprintf(fifo, sizeof fifo, "%s.fifo.%d", path, (int)getpid());
    struct stat sb;
    if (copy_file(path, copy, -1) || stat(copy, &sb)) { CHECK(0, "cannot copy %s to %s", path, copy); return; }
    counter cm = {0}, cp = {0};
    wrt_runtime_options om = {.size = sizeof om, .allocator = {c_alloc, c_free, &cm}};
    wrt_runtime_options op = {.size = sizeof op, .allocator = {c_alloc, c_free, &cp}};
    CHECK(wrt_runtime_open_path(copy, WRT_OPEN_MAP, &om, &map, &err) == WRT_OK, "open_path MAP: %s", err.message);
    CHECK(wrt_runtime_open_path(copy, WRT_OPEN_PRIVATE, &op, &priv, &err) == WRT_OK, "open_path PRIVATE: %s",
          err.message);
    if (!map || !priv) { wrt_runtime_close(map); wrt_runtime_close(priv); remove(copy); return; }
    CHECK(cp.allocs == cm.allocs + 1 && cp.bytes >= cm.bytes + (long)sb.st_size,
          "PRIVATE: %d allocations of %zu bytes, MAP %d of %zu, the file %lld bytes", (int)cp.allocs, (size_t)cp.bytes,
          (int)cm.allocs, (size_t)cm.bytes, (long long)sb.st_size);
    wrt_runtime_file_info fi;
    CHECK(wrt_runtime_get_file_info(priv, &fi, &err) == WRT_OK && fi.bytes == (unsigned long long)sb.st_size &&
          fi.private_copy == 1 && fi.version_major == 3 && fi.functions > 0 && fi.entries > 0,
          "file info: %llu bytes (on disk %lld), private %d, version %u.%u, %llu functions, %llu entries", fi.bytes,
          (long long)sb.st_size, fi.private_copy, fi.version_major, fi.version_minor, fi.functions, fi.entries);
    CHECK(wrt_runtime_get_file_info(priv, NULL, &err) == WRT_ERR_INVALID_ARG, "file info out NULL");
    wrt_runtime_close(map);
    map = NULL;
    CHECK(wrt_runtime_open_file(path, NULL, &map, &err) == WRT_OK, "open_file: %s", err.message);
    /* the private copy outlives its file: truncated, then removed */
    CHECK(truncate(copy, 0) == 0 && remove(copy) == 0, "truncate and remove the copy");
    wrt_runtime_light l = {0};
    wrt_runtime_get_light(map, 0, &l, NULL);
    size_t na = 0, nb = 0;
    float *a = relight(map, &l, &na), *b = relight(priv, &l, &nb);
    CHECK(a && b && same(a, na, b, nb), "PRIVATE after the file went: textures bitwise the mapped open's (%zu, %zu floats)",
          na, nb);
    free(a);
    free(b);
    wrt_runtime_close(map);
    CHECK(wrt_runtime_close(priv) == WRT_OK && cp.frees == cp.allocs, "PRIVATE close: %d frees of %d allocations",
          (int)cp.frees, (int)cp.allocs);
    wrt_status s = wrt_runtime_open_path(copy, WRT_OPEN_PRIVATE, NULL, &none, &err);
    CHECK(s == WRT_ERR_IO && none == NULL && strstr(err.message, copy), "missing: %d '%s'", s, err.message);
    if (mkfifo(fifo, 0600) == 0) {
        none = (wrt_runtime *)1;
        s = wrt_runtime_open_path(fifo, WRT_OPEN_PRIVATE, NULL, &none, &err); /* would block if it read */
        CHECK(s == WRT_ERR_NOT_OURS && none == NULL && strstr(err.message, "FIFO") && strstr(err.message, fifo),
              "FIFO: %d '%s'", s, err.message);
        remove(fifo);
    }
    if (copy_file(path, copy, (long)sb.st_size / 2) == 0) {
        s = wrt_runtime_open_path(copy, WRT_OPEN_PRIVATE, NULL, &none, &err);
        CHECK(s == WRT_ERR_CORRUPT && none == NULL && !strncmp(err.message, copy, strlen(copy)), "corrupt: %d '%s'", s,
              err.message);
        remove(copy);
    }
    s = wrt_runtime_open_path(path, 2, NULL, &none, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && none == NULL && strstr(err.message, "how"), "how 2: %d '%s'", s, err.message);
}

int main(int argc, char **argv) {
    const char *glossy = NULL; /* --glossy FILE (last): a glossy bake for the open's progress */
    if (argc >= 3 && !strcmp(argv[argc - 2], "--glossy")) { glossy = argv[argc - 1]; argc -= 2; }
    if (argc < 3) { fprintf(stderr, "usage: %s FACING.gto RANGED.gto [MORE.gto ...] [--glossy GLOSSY.gto]\n", argv[0]); return 1; }
    test_version();
    test_options(argv[1]);
    test_handles(argv[1]);
    test_bounds(argv[1]);
    test_getters(argv[1]);
    test_range(argv[1], argv[2]);
    test_open_path(argv[1]);
    for (int i = 1; i < argc; i++) if (i != 2) test_steady_allocations(argv[i]);
    for (int i = 1; i < argc; i++) if (i != 2) test_atlas(argv[i]);
    for (int i = 1; i < argc; i++) if (i != 2) test_superposition(argv[i]);
    if (glossy) { test_superposition(glossy); test_progress(glossy); }
    if (skipped) printf("%s: %d passed, %d failed, %d skipped\n", argv[0], passed, failed, skipped);
    else printf("%s: %d passed, %d failed\n", argv[0], passed, failed);
    return failed != 0;
}
