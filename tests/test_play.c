/* test_play.c: the player's pipeline from file to picture without the bake: builds a
 * small Cornell-like room in C (walls of 2 x 2 quads, a box, a point light), with an
 * approximate one-bounce operator between the quads' root functions (point-to-point
 * form factors, no visibility: a stand-in, not a bake), writes it with wrt_gto_write,
 * maps it with wrt_gto_open, relights it (player/relight.c) and draws it headless
 * (player/render.c). Checks: the picture is lit, indirect-only is lit and flat per quad
 * (a root-only operator gives each quad one outgoing radiance, rho/pi x the indirect
 * irradiance relight reports), and both = direct + indirect. Without a display:
 * player/view.c on the room through the library's API (a light moved against the walls
 * stops 1e-3 of the diagonal short of them, from either side; the default camera of the
 * room without a camera is outside when its open side shows the lit inside, and inside,
 * where the light is seen, when that side is closed by a wall seen from both sides).
 *   test_play --write-gto OUT.gto   writes the room for tests/play.sh. */
#include "tests/test.h"
#include "common/basis.h"
#include "formats/gto.h"
#include "formats/scene.h"
#include "formats/image.h"
#include "player/platform.h"
#include "player/relight.h"
#include "player/render.h"
#include "player/view.h"

#include <stdlib.h>
#include <unistd.h>

#define MAXQ 64

static wrt_quad quads[MAXQ];
static int nq;
static wrt_material mats[4];
static wrt_light light;
static char names[3][64] = {"room", "box", "ceiling"};
static int closed_room; /* 1: no camera, and the open side closed by a wall seen from both sides */

static void add_quad(wrt_v3 p0, wrt_v3 p1, wrt_v3 p2, wrt_v3 p3, int mat, int name) {
    wrt_quad *q = &quads[nq++];
    memset(q, 0, sizeof *q);
    q->p[0] = p0; q->p[1] = p1; q->p[2] = p2; q->p[3] = p3;
    q->t = v3_norm(v3_sub(p1, p0));
    q->n = v3_norm(v3_cross(v3_sub(p1, p0), v3_sub(p3, p0)));
    q->b = v3_cross(q->n, q->t);
    q->area = v3_len(v3_cross(v3_sub(p1, p0), v3_sub(p3, p0)));
    q->parallelogram = 1;
    q->material = mat;
    q->name = name;
}

/* A rectangle split into k x k quads: corner o, edges e1, e2 (normal e1 x e2). */
static void add_rect(wrt_v3 o, wrt_v3 e1, wrt_v3 e2, int k, int mat, int name) {
    for (int j = 0; j < k; j++)
        for (int i = 0; i < k; i++) {
            wrt_v3 a = v3_add(o, v3_add(v3_scale(e1, (double)i / k), v3_scale(e2, (double)j / k)));
            wrt_v3 b = v3_add(a, v3_scale(e1, 1.0 / k)), d = v3_add(a, v3_scale(e2, 1.0 / k));
            add_quad(a, b, v3_add(b, v3_scale(e2, 1.0 / k)), d, mat, name);
        }
}

static void build_room(wrt_scene *s) {
    nq = 0;
    memset(mats, 0, sizeof mats);
    const float col[3][3] = {{0.75f, 0.75f, 0.75f}, {0.75f, 0.1f, 0.1f}, {0.1f, 0.75f, 0.1f}};
    const char *mn[3] = {"white", "red", "green"};
    for (int m = 0; m < 3; m++) {
        memcpy(mats[m].base_color, col[m], sizeof col[m]);
        mats[m].roughness = 1;
        mats[m].lambertian = 1;
        snprintf(mats[m].name, sizeof mats[m].name, "%s", mn[m]);
    }
    /* glossy material for the box top */
    mats[3].base_color[0] = mats[3].base_color[1] = mats[3].base_color[2] = 0.6f;
    mats[3].roughness = 0.3f;
    mats[3].metallic = 0.0f;
    snprintf(mats[3].name, sizeof mats[3].name, "glossy");
    /* room [-1,1] x [0,2] x [-1,1], normals inward, open at z = +1 */
    add_rect(v3(-1, 0, 1), v3(2, 0, 0), v3(0, 0, -2), 2, 0, 0);  /* floor, +y */
    add_rect(v3(-1, 2, -1), v3(2, 0, 0), v3(0, 0, 2), 2, 0, 2);  /* ceiling, -y */
    add_rect(v3(-1, 0, -1), v3(2, 0, 0), v3(0, 2, 0), 2, 0, 0);  /* back, +z */
    add_rect(v3(-1, 0, 1), v3(0, 0, -2), v3(0, 2, 0), 2, 1, 0);  /* left red, +x */
    add_rect(v3(1, 0, -1), v3(0, 0, 2), v3(0, 2, 0), 2, 2, 0);   /* right green, -x */
    /* a box [-0.5,0] x [0,0.6] x [-0.5,0], outward normals */
    double x0 = -0.5, x1 = 0, y1 = 0.6, z0 = -0.5, z1 = 0;
    add_rect(v3(x0, y1, z1), v3(x1 - x0, 0, 0), v3(0, 0, z0 - z1), 1, 3, 1); /* top +y */
    add_rect(v3(x0, 0, z1), v3(x1 - x0, 0, 0), v3(0, y1, 0), 1, 0, 1);      /* front +z */
    add_rect(v3(x1, 0, z0), v3(x0 - x1, 0, 0), v3(0, y1, 0), 1, 0, 1);      /* back -z */
    add_rect(v3(x0, 0, z0), v3(0, 0, z1 - z0), v3(0, y1, 0), 1, 0, 1);      /* left -x */
    add_rect(v3(x1, 0, z1), v3(0, 0, z0 - z1), v3(0, y1, 0), 1, 0, 1);      /* right +x */
    if (closed_room) { /* the front wall, -z, and its outside, +z, as a double-sided material's twin */
        add_rect(v3(1, 0, 1), v3(-2, 0, 0), v3(0, 2, 0), 2, 0, 0);
        add_rect(v3(-1, 0, 1.0001), v3(2, 0, 0), v3(0, 2, 0), 2, 0, 0);
    }
    memset(&light, 0, sizeof light);
    light.type = WRT_LIGHT_POINT;
    snprintf(light.name, sizeof light.name, "lamp");
    light.pos = v3(0.2, 1.7, 0.1);
    light.dir = v3(0, -1, 0);
    light.color[0] = light.color[1] = light.color[2] = 1;
    light.intensity = 4;
    light.outer_cone = (float)(WRT_PI / 4);
    memset(s, 0, sizeof *s);
    s->quads = quads;
    s->nquads = nq;
    s->materials = mats;
    s->nmaterials = 4;
    s->lights = &light;
    s->nlights = 1;
    s->names = names;
    s->nnames = 3;
    s->camera.pos = v3(0, 1, 3.4);
    s->camera.dir = v3(0, 0, -1);
    s->camera.up = v3(0, 1, 0);
    s->camera.yfov = 0.75;
    s->camera.znear = 0.01;
    s->camera.from_file = 1;
    if (closed_room) memset(&s->camera, 0, sizeof s->camera);
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Functions: every spatial function down to level 2 under the angular root; for the
 * glossy quad also angular level 0 wavelets. Operator: root to root, one bounce,
 * X_r = rho_s F_rs sqrt(A_r / A_s) E_s with F_rs ~ cos_r cos_s A_s / (pi d^2). */
static wrt_status write_room(const char *path) {
    wrt_scene s;
    build_room(&s);
    enum { SL = 2 };
    uint64_t *keys = wrt_xmalloc(MAXQ * 400 * sizeof(uint64_t));
    uint32_t nk = 0;
    wrt_node root = wrt_node_root();
    for (int q = 0; q < nq; q++) {
        for (int l = 0; l <= SL; l++)
            for (int y = 0; y < (1 << l); y++)
                for (int x = 0; x < (1 << l); x++) {
                    wrt_node n = {(uint8_t)l, (uint16_t)x, (uint16_t)y};
                    if (l == 0) keys[nk++] = wrt_fkey_make((uint32_t)q, n, 0, root, 0);
                    for (int t = 1; t <= 3; t++) keys[nk++] = wrt_fkey_make((uint32_t)q, n, t, root, 0);
                }
        if (!mats[quads[q].material].lambertian)
            for (int t = 1; t <= 3; t++) keys[nk++] = wrt_fkey_make((uint32_t)q, root, 0, root, t);
    }
    qsort(keys, nk, sizeof *keys, cmp_u64);
    int *root_of = wrt_xmalloc(MAXQ * sizeof(int));
    for (uint32_t i = 0; i < nk; i++)
        if ((keys[i] & ((1ull << 42) - 1)) == 0) root_of[wrt_fkey_quad(keys[i])] = (int)i;
    uint64_t *col = wrt_xcalloc(nk + 1, sizeof(uint64_t));
    uint32_t *rows = wrt_xmalloc((size_t)MAXQ * MAXQ * sizeof(uint32_t));
    float *vals = wrt_xmalloc((size_t)MAXQ * MAXQ * 3 * sizeof(float));
    uint64_t e = 0;
    for (uint32_t i = 0; i < nk; i++) {
        col[i] = e;
        int sq = (int)wrt_fkey_quad(keys[i]);
        if (root_of[sq] != (int)i) continue;
        for (int rq = 0; rq < nq; rq++) {
            if (rq == sq) continue;
            wrt_v3 cs = v3_scale(v3_add(quads[sq].p[0], quads[sq].p[2]), 0.5);
            wrt_v3 cr = v3_scale(v3_add(quads[rq].p[0], quads[rq].p[2]), 0.5);
            wrt_v3 d = v3_sub(cs, cr);
            double d2 = v3_dot(d, d), dl = sqrt(d2);
            double cr_ = v3_dot(quads[rq].n, d) / dl, cs_ = -v3_dot(quads[sq].n, d) / dl;
            if (cr_ <= 0 || cs_ <= 0) continue;
            double F = fmin(cr_ * cs_ * quads[sq].area / (WRT_PI * d2), 0.3);
            rows[e] = (uint32_t)root_of[rq];
            for (int c = 0; c < 3; c++)
                vals[3 * e + c] = (float)(mats[quads[sq].material].base_color[c] * F *
                                          sqrt(quads[rq].area / quads[sq].area));
            e++;
        }
        /* rows ascending within the column */
        uint64_t b = col[i];
        for (uint64_t x = b + 1; x < e; x++)
            for (uint64_t y = x; y > b && rows[y - 1] > rows[y]; y--) {
                uint32_t tr = rows[y]; rows[y] = rows[y - 1]; rows[y - 1] = tr;
                for (int c = 0; c < 3; c++) { float tv = vals[3 * y + c]; vals[3 * y + c] = vals[3 * (y - 1) + c]; vals[3 * (y - 1) + c] = tv; }
            }
    }
    col[nk] = e;
    wrt_gto_contents c;
    memset(&c, 0, sizeof c);
    c.scene = &s;
    c.fkeys = keys;
    c.nfuncs = nk;
    c.col_start = col;
    c.rows = rows;
    c.vals = vals;
    c.op_kind = WRT_GTO_OP_INDIRECT;
    c.provenance = "{\"scene\": \"test_play room\", \"operator\": \"one bounce between roots, point form factors\"}";
    wrt_status st = wrt_gto_write(path, &c);
    free(keys); free(root_of); free(col); free(rows); free(vals);
    return st;
}

/* ------------------------------------------------------------------ cases */

static char dir[64], gto_path[128];
enum { W = 160, H = 120 };
static float img[3][W * H * 3];

static void test_write_and_draw(void) {
    CHECK(write_room(gto_path) == WRT_OK, "%s", wrt_last_error());
    wrt_gto g;
    wrt_status s = wrt_gto_open(gto_path, &g);
    CHECK(s == WRT_OK, "%s", wrt_last_error());
    if (s) return;
    CHECK(g.nquads == (uint32_t)nq, "quads %u", g.nquads);
    wrt_relight *rl = NULL;
    wrt_relight_options ro = {.max_tex_res = 16, .threads = 2};
    CHECK(wrt_relight_create(&g, &ro, &rl) == WRT_OK, "%s", wrt_last_error());
    wrt_render *rd = NULL;
    wrt_render_options o = {W, H, 256, 1};
    CHECK(wrt_render_create(&g, &o, &rd) == WRT_OK, "%s", wrt_last_error());
    if (rl && rd) {
        wrt_light l;
        wrt_render_light_from_gto(&g.lights[0], &l);
        wrt_view v;
        wrt_render_default_view(&g, &v);
        wrt_relight_set_lights(rl, &l, NULL, 1);
        wrt_relight_set_eye(rl, v.eye);
        wrt_relight_timings t;
        int changed = wrt_relight_update(rl, &t);
        CHECK(changed > 0, "textures changed: %d", changed);
        for (uint32_t q = 0; q < g.nquads; q++)
            wrt_render_set_quad_tex(rd, (int)q, wrt_relight_tex_res(rl, (int)q), wrt_relight_tex(rl, (int)q));
        CHECK(wrt_render_upload(rd) == (int)g.nquads, "every quad uploaded");
        wrt_render_set_lights(rd, &l, NULL, 1);
        for (int m = 0; m < 3; m++) {
            wrt_render_draw(rd, &v, (wrt_render_mode)m);
            wrt_render_read_linear(rd, img[m]);
        }
        double sb = 0, sd = 0, si = 0, err = 0;
        for (int i = 0; i < W * H * 3; i++) {
            sb += img[0][i]; sd += img[1][i]; si += img[2][i];
            err += fabs(img[0][i] - img[1][i] - img[2][i]);
        }
        CHECK(sd > 0 && si > 0, "direct %g and indirect %g lit", sd, si);
        CHECK(err / sb < 1e-5, "both = direct + indirect: %.3g", err / sb);
        /* the back wall's lower-left quad: indirect radiance is rho/pi x its indirect irradiance */
        int q = 8; /* back wall starts at quad 8 */
        double dir_e[3], ind_e[3];
        wrt_relight_quad_irradiance(rl, q, dir_e, ind_e);
        const float *tex = wrt_relight_tex(rl, q);
        int res = wrt_relight_tex_res(rl, q);
        double mean = 0;
        for (int i = 0; i < res * res; i++) mean += tex[3 * i] / (res * res);
        CHECK_NEAR(mean, 0.75 / WRT_PI * ind_e[0], 1e-4 * mean + 1e-9, "texture vs irradiance");
        CHECK(dir_e[0] > 0 && ind_e[0] > 0, "direct %g indirect %g", dir_e[0], ind_e[0]);
        const char *dump = getenv("WRT_TEST_DUMP");
        if (dump) {
            static uint8_t b8[W * H * 3];
            char path[512];
            for (int m = 0; m < 3; m++) {
                snprintf(path, sizeof path, "%s/play_%d.png", dump, m);
                wrt_render_tonemap(img[m], W * H, 0, b8);
                wrt_image_write_rgb8(path, b8, W, H);
            }
        }
    }
    wrt_render_destroy(rd);
    wrt_relight_destroy(rl);
    wrt_gto_close(&g);
    unlink(gto_path);
}

/* player/view.c through the API: the walls stop a moving light; the default camera. */
static void test_view(void) {
    char path[160];
    snprintf(path, sizeof path, "%s/view.gto", dir);
    for (closed_room = 0; closed_room <= 1; closed_room++) {
        CHECK(write_room(path) == WRT_OK, "%s", wrt_last_error());
        wrt_runtime *rt = NULL;
        wrt_error err;
        CHECK(wrt_runtime_open_file(path, NULL, &rt, &err) == WRT_OK, "%s", err.message);
        wrt_play_geom *g = NULL;
        if (!rt || wrt_play_geom_create(rt, &g)) { CHECK(0, "geometry: %s", wrt_last_error()); wrt_runtime_close(rt); continue; }
        wrt_runtime_camera cam;
        CHECK(wrt_runtime_get_camera(rt, &cam, NULL) == WRT_OK && cam.from_file == !closed_room,
              "camera from_file %d (closed %d)", cam.from_file, closed_room);
        double lo[3], hi[3];
        wrt_runtime_get_bounds(rt, lo, hi, NULL);
        double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                           (hi[2] - lo[2]) * (hi[2] - lo[2])), gap = 1e-3 * diag;
        /* the lamp towards the back wall (z = -1, 1.1 away) and beyond: stops short of it */
        double a[3] = {0.2, 1.7, 0.1}, b[3] = {0.2, 1.7, -3}, f = wrt_play_geom_clip_move(g, a, b);
        CHECK_NEAR(f, (1.1 - gap) / 3.1, 1e-9, "through the back wall: fraction %.12g", f);
        double b2[3] = {0.2, 1.7, 0.9};
        CHECK(wrt_play_geom_clip_move(g, a, b2) == 1, "nothing in the way: the whole move");
        double c[3] = {-0.25, 0.3, 0.5}, d[3] = {-0.25, 0.3, -0.25}; /* into the box, through its front (z = 0) */
        f = wrt_play_geom_clip_move(g, c, d);
        CHECK_NEAR(f, (0.5 - gap) / 0.75, 1e-9, "into the box: fraction %.12g", f);
        f = wrt_play_geom_clip_move(g, d, c); /* out of it: the same wall's back */
        CHECK_NEAR(f, (0.25 - gap) / 0.75, 1e-9, "out of the box, its wall seen from behind: fraction %.12g", f);
        wrt_runtime_light l;
        wrt_runtime_get_light(rt, 0, &l, NULL);
        wrt_view v;
        double score = -1;
        int k = wrt_play_default_view(g, &l, 1, &v, &score);
        int inside = v.eye[0] > -1 && v.eye[0] < 1 && v.eye[1] > 0 && v.eye[1] < 2 && v.eye[2] > -1 && v.eye[2] < 1;
        int in_box = v.eye[0] > -0.5 && v.eye[0] < 0 && v.eye[1] < 0.6 && v.eye[2] > -0.5 && v.eye[2] < 0;
        if (!closed_room)
            CHECK(k == 0 && !inside && v.eye[2] > 1 && score >= 0.1, "open room: outside, from +z (candidate %d, eye "
                  "%g %g %g, %.2f of the view lit)", k, v.eye[0], v.eye[1], v.eye[2], score);
        else
            CHECK(k > 0 && inside && !in_box && score >= 0.3, "closed room: inside, not in the box (candidate %d, eye "
                  "%g %g %g, %.2f of the view lit)", k, v.eye[0], v.eye[1], v.eye[2], score);
        wrt_play_geom_destroy(g);
        wrt_runtime_close(rt);
        remove(path);
    }
    closed_room = 0;
}

/* Under AddressSanitizer: Mesa's driver, which EGL loads and unloads, leaves one block
 * of 128 bytes that LeakSanitizer cannot attribute to any module (the leak checks of
 * this program's own allocations were clean before this was switched off). */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "detect_leaks=0"; }

int main(int argc, char **argv) {
    if (argc == 3 && !strcmp(argv[1], "--write-gto")) {
        wrt_status s = write_room(argv[2]);
        if (s) fprintf(stderr, "test_play: %s\n", wrt_last_error());
        return s ? 1 : 0;
    }
    snprintf(dir, sizeof dir, "/tmp/wrt_test_play_XXXXXX");
    if (!mkdtemp(dir)) return 1;
    snprintf(gto_path, sizeof gto_path, "%s/room.gto", dir);
    TEST_RUN(test_view); /* no display needed */
    wrt_platform *p = NULL;
    if (wrt_platform_egl_create(&p) != WRT_OK) {
        fprintf(stderr, "no headless OpenGL: %s\n", wrt_last_error());
        test_failed++;
        TEST_END();
    }
    TEST_RUN(test_write_and_draw);
    wrt_platform_destroy(p);
    rmdir(dir);
    TEST_END();
}
