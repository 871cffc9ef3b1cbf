/* test_gather.c: the final gather on glossy quads (player/gather.h) inside a closed box.
 * Under uniform incident radiance L the gathered radiance toward the eye is L times the
 * BRDF's directional albedo rho(w_o) = int f_r cos dw, a closed form this test integrates
 * by a fine quadrature of its own; the rows the gather keeps toward the eye (bfloat16,
 * made when the eye moves) must give that, follow the eye, and stay linear in the light. */
#include "test.h"

#include <stdlib.h>

#include "common/brdf.h"
#include "common/rt_scene.h"
#include "player/gather.h"

/* The box [-1, 1]^3 seen from inside: quad 0 the glossy floor, 1-5 diffuse walls. */
#define NQ 6
typedef struct box { wrt_v3 c[NQ * 4]; wrt_gather_quad q[NQ]; wrt_material mat; wrt_rt_scene rt; } box;

static void set_quad(box *b, int i, wrt_v3 p0, wrt_v3 p1, wrt_v3 p2, wrt_v3 p3) {
    wrt_v3 p[4] = {p0, p1, p2, p3};
    wrt_gather_quad *q = &b->q[i];
    memcpy(q->p, p, sizeof p);
    memcpy(b->c + 4 * i, p, sizeof p);
    q->t = v3_norm(v3_sub(p1, p0));
    q->b = v3_norm(v3_sub(p3, p0));
    q->n = v3_norm(v3_cross(q->t, q->b));
    for (int c = 0; c < 3; c++) q->albedo[c] = 0.6f;
}

static int box_make(box *b) {
    memset(b, 0, sizeof *b);
    /* corners ordered so that t x b, the normal, points into the box */
    set_quad(b, 0, v3(-1, -1, -1), v3(-1, -1, 1), v3(1, -1, 1), v3(1, -1, -1));  /* floor, +y */
    set_quad(b, 1, v3(-1, 1, -1), v3(1, 1, -1), v3(1, 1, 1), v3(-1, 1, 1));      /* ceiling, -y */
    set_quad(b, 2, v3(-1, -1, -1), v3(1, -1, -1), v3(1, 1, -1), v3(-1, 1, -1));  /* back, +z */
    set_quad(b, 3, v3(-1, -1, 1), v3(-1, 1, 1), v3(1, 1, 1), v3(1, -1, 1));      /* front, -z */
    set_quad(b, 4, v3(-1, -1, -1), v3(-1, 1, -1), v3(-1, 1, 1), v3(-1, -1, 1));  /* left, +x */
    set_quad(b, 5, v3(1, -1, -1), v3(1, -1, 1), v3(1, 1, 1), v3(1, 1, -1));      /* right, -x */
    b->mat.base_color[0] = 0.5f; b->mat.base_color[1] = 0.4f; b->mat.base_color[2] = 0.3f;
    b->mat.roughness = 0.3f;
    b->q[0].mat = &b->mat;
    return wrt_rt_scene_build(b->c, NQ, v3(0, 0, 0), NULL, WRT_RT_ROBUST, &b->rt) == WRT_OK;
}

static void run_serial(void *user, size_t n, wrt_gather_item_fn fn, void *ctx) {
    (void)user;
    for (size_t i = 0; i < n; i++) fn(ctx, i);
}
static void *alloc_z(void *user, size_t bytes) { (void)user; return calloc(1, bytes); }
static void free_z(void *user, void *p) { (void)user; free(p); }

static wrt_gather *gather_make_form(box *b, int simd, int wide) {
    wrt_gather_env env = {run_serial, alloc_z, free_z, NULL, NULL, 0, simd, wide};
    wrt_gather *g = NULL;
    int res[NQ] = {16, 16, 16, 16, 16, 16};
    if (wrt_gather_create(NQ, b->q, res, b->rt.scene, b->rt.origin, b->rt.eps, 16, &env, &g) != WRT_OK) return NULL;
    return g;
}
static wrt_gather *gather_make_simd(box *b, int simd) { return gather_make_form(b, simd, 0); }
static wrt_gather *gather_make(box *b) { return gather_make_simd(b, 0); }

/* Direct irradiance: pi x scale (a wall of albedo 0.6 then sends 0.6 x scale), times a
 * ramp in x when *user asks for light that varies. */
typedef struct light { double scale; int ramp; } light;
static void direct(void *user, const wrt_v3 *x, int n, wrt_v3 nrm, double *out) {
    (void)nrm;
    const light *l = user;
    for (int k = 0; k < n; k++) {
        double e = WRT_PI * l->scale * (l->ramp ? 1.5 + x[k].x : 1.0);
        out[3 * k] = e; out[3 * k + 1] = 0.5 * e; out[3 * k + 2] = 0.25 * e;
    }
}

/* rho(w_o) per channel by the midpoint rule in (theta, phi): 500 x 500 nodes. */
static void albedo(const wrt_material *m, wrt_v3 wo, double out[3]) {
    const int nt = 500, np = 500;
    double s[3] = {0, 0, 0};
    for (int i = 0; i < nt; i++) {
        double th = (i + 0.5) * (WRT_PI / 2) / nt, st = sin(th), ct = cos(th);
        for (int j = 0; j < np; j++) {
            double ph = (j + 0.5) * 2 * WRT_PI / np, f[3];
            wrt_brdf_eval(m, v3(0, 0, 1), v3(st * cos(ph), st * sin(ph), ct), wo, f);
            for (int c = 0; c < 3; c++) s[c] += f[c] * ct * st;
        }
    }
    for (int c = 0; c < 3; c++) out[c] = s[c] * (WRT_PI / 2 / nt) * (2 * WRT_PI / np);
}

/* Uniform incident radiance: every floor point's gathered radiance toward the eye is
 * L rho(w_o), within the gather's own discretisation (beta from 3 x 3 samples a cell,
 * bilinear between 32 x 32 outgoing directions, bfloat16 rows). */
static void test_uniform_box(void) {
    box b;
    if (!box_make(&b)) { CHECK(0, "Embree scene"); return; }
    wrt_gather *g = gather_make(&b);
    CHECK(g != NULL, "gather made");
    if (!g) { wrt_rt_scene_release(&b.rt); return; }
    const float *tex[NQ] = {0};
    int tres[NQ] = {0};
    float outbuf[NQ][16 * 16 * 3];
    float *out[NQ];
    int ores[NQ];
    for (int i = 0; i < NQ; i++) { out[i] = outbuf[i]; ores[i] = 16; }
    light l = {1.0, 0};
    wrt_gather_lights(g, direct, &l, tex, tres);
    double eye[3] = {0.2, 0.3, -0.1};
    wrt_gather_eye(g, eye, out, ores);
    double worst = 0, sum = 0, sumref = 0;
    for (int pj = 0; pj < 16; pj++) {
        int pi = (5 * pj + 2) % 16; /* a point a row, spread over the columns: the quadrature is slow */
        {
            double u = (pi + 0.5) / 16, v = (pj + 0.5) / 16;
            const wrt_gather_quad *Q = &b.q[0];
            wrt_v3 x = v3_add(v3_add(Q->p[0], v3_scale(v3_sub(Q->p[1], Q->p[0]), u)), v3_scale(v3_sub(Q->p[3], Q->p[0]), v));
            wrt_v3 wo = v3_norm(v3_sub(v3(eye[0], eye[1], eye[2]), x));
            double rho[3];
            albedo(&b.mat, v3(v3_dot(wo, Q->t), v3_dot(wo, Q->b), v3_dot(wo, Q->n)), rho);
            static const double L[3] = {0.6, 0.3, 0.15};
            for (int c = 0; c < 3; c++) {
                double got = outbuf[0][(pj * 16 + pi) * 3 + c], want = L[c] * rho[c];
                worst = fmax(worst, fabs(got - want) / want);
                sum += got; sumref += want;
            }
        }
    }
    printf("uniform box: worst point %.4f%%, mean %.4f%% off L rho(w_o)\n", 100 * worst, 100 * (sum / sumref - 1));
    /* measured 0.056% worst, -0.010% mean; rows truncated to bfloat16 instead of rounded
     * would be about -0.3% */
    CHECK(worst < 0.005, "a floor point's gathered radiance %.4f%% off L rho(w_o) (0.5%% allowed)", 100 * worst);
    CHECK(fabs(sum / sumref - 1) < 0.001, "the mean %.4f%% off (0.1%% allowed)", 100 * (sum / sumref - 1));
    wrt_gather_destroy(g);
    wrt_rt_scene_release(&b.rt);
}

/* The kept rows follow the eye: moving it away and back gives the same bits as a gather
 * that only ever saw the second eye, under light that varies across the walls; and the
 * result is linear in the light (twice the light, twice every value, exactly). */
static void test_rows_follow_eye(void) {
    box b;
    if (!box_make(&b)) { CHECK(0, "Embree scene"); return; }
    wrt_gather *g1 = gather_make(&b), *g2 = gather_make(&b);
    CHECK(g1 && g2, "gathers made");
    if (g1 && g2) {
        const float *tex[NQ] = {0};
        int tres[NQ] = {0}, ores[NQ];
        static float o1[NQ][16 * 16 * 3], o2[NQ][16 * 16 * 3], o3[NQ][16 * 16 * 3];
        float *p1[NQ], *p2[NQ], *p3[NQ];
        for (int i = 0; i < NQ; i++) { p1[i] = o1[i]; p2[i] = o2[i]; p3[i] = o3[i]; ores[i] = 16; }
        light l = {1.0, 1};
        double e1[3] = {-0.6, 0.8, 0.7}, e2[3] = {0.5, 0.1, -0.4};
        wrt_gather_lights(g1, direct, &l, tex, tres);
        wrt_gather_eye(g1, e1, p1, ores);
        wrt_gather_eye(g1, e2, p1, ores); /* the eye moves: rows made again */
        wrt_gather_lights(g2, direct, &l, tex, tres);
        wrt_gather_eye(g2, e2, p2, ores);
        CHECK(memcmp(o1[0], o2[0], sizeof o1[0]) == 0, "after an eye move the values are a fresh gather's");
        wrt_gather_eye(g2, e1, p3, ores); /* the first eye's values differ from the second's */
        int differ = memcmp(o3[0], o2[0], sizeof o2[0]) != 0;
        CHECK(differ, "the two eyes see different values");
        wrt_gather_eye(g2, e2, p3, ores);
        l.scale = 2.0; /* a light change with the eye still: twice the light */
        wrt_gather_lights(g2, direct, &l, tex, tres);
        wrt_gather_eye(g2, e2, p3, ores);
        int bad = 0;
        for (int k = 0; k < 16 * 16 * 3; k++) bad += o3[0][k] != 2 * o2[0][k];
        CHECK(bad == 0, "%d of %d values not exactly twice", bad, 16 * 16 * 3);
    }
    wrt_gather_destroy(g1);
    wrt_gather_destroy(g2);
    wrt_rt_scene_release(&b.rt);
}

/* Walls 1-5 with 8 x 8 textures of a pattern (mul, mod) and the floor without; every
 * output 16 texels a side. */
static void walls_textured(float tx[NQ][8 * 8 * 3], int mul, int mod, const float *tex[NQ], int tres[NQ], int ores[NQ]) {
    for (int q = 0; q < NQ; q++) {
        for (int k = 0; k < 8 * 8 * 3; k++) tx[q][k] = (float)(0.05 + 0.01 * ((k * mul + q * 3) % mod));
        tex[q] = q ? tx[q] : NULL;
        tres[q] = 8;
        ores[q] = 16;
    }
}

/* The light change's sums, plain loops, four lanes (SSE2) and eight (AVX2 where the
 * processor has it): the same bits, under light that varies across the walls and walls
 * with textures (a case where a lane out of order would change the rounding). */
static void test_sums_same_bits(void) {
    box b;
    if (!box_make(&b)) { CHECK(0, "Embree scene"); return; }
    wrt_gather *g[3];
    static float o[3][NQ][16 * 16 * 3], tx[NQ][8 * 8 * 3];
    const float *tex[NQ];
    int tres[NQ], ores[NQ];
    walls_textured(tx, 7, 11, tex, tres, ores);
    light l = {1.0, 1};
    double eye[3] = {-0.3, 0.6, 0.45};
    for (int v = 0; v < 3; v++) {
        g[v] = gather_make_simd(&b, v);
        CHECK(g[v] != NULL, "gather made (simd %d)", v);
        if (!g[v]) continue;
        float *p[NQ];
        for (int q = 0; q < NQ; q++) p[q] = o[v][q];
        wrt_gather_lights(g[v], direct, &l, tex, tres);
        wrt_gather_eye(g[v], eye, p, ores);
        wrt_gather_destroy(g[v]);
    }
    double m = 0;
    for (int k = 0; k < 16 * 16 * 3; k++) m = fmax(m, o[0][0][k]);
    CHECK(m > 0, "the floor gathers light");
    CHECK(memcmp(o[0][0], o[1][0], sizeof o[0][0]) == 0, "the widest sums and the plain loops: the same bits");
    CHECK(memcmp(o[2][0], o[1][0], sizeof o[0][0]) == 0, "SSE2 and the plain loops: the same bits");
    wrt_rt_scene_release(&b.rt);
}

/* A grey lobe's narrow entries (a 2-byte cell index, one beta for R, G and B) against the
 * general ones (a 4-byte offset, three betas): the same bits from every loop (plain, SSE2,
 * the widest; the general entries' plain loop), in fewer bytes, under light that varies
 * across the walls and textures. */
static void test_narrow_same_bits(void) {
    box b;
    if (!box_make(&b)) { CHECK(0, "Embree scene"); return; }
    for (int c = 0; c < 3; c++) b.mat.base_color[c] = 0.55f; /* grey */
    static float o[4][NQ][16 * 16 * 3], tx[NQ][8 * 8 * 3];
    const float *tex[NQ];
    int tres[NQ], ores[NQ];
    walls_textured(tx, 5, 13, tex, tres, ores);
    light l = {1.0, 1};
    double eye[3] = {0.35, 0.5, -0.6};
    size_t bytes[2] = {0, 0}, ent[2] = {0, 0};
    for (int v = 0; v < 4; v++) { /* narrow: simd 0, 1, 2; wide: the plain loops */
        int wide = v / 3, simd = v < 3 ? v : 1;
        wrt_gather *g = gather_make_form(&b, simd, wide);
        CHECK(g != NULL, "gather made (simd %d, wide %d)", simd, wide);
        if (!g) continue;
        float *p[NQ];
        for (int q = 0; q < NQ; q++) p[q] = o[v][q];
        wrt_gather_lights(g, direct, &l, tex, tres);
        wrt_gather_eye(g, eye, p, ores);
        bytes[wide] = wrt_gather_entry_bytes(g, &ent[wide]);
        wrt_gather_destroy(g);
    }
    double m = 0;
    for (int k = 0; k < 16 * 16 * 3; k++) m = fmax(m, o[0][0][k]);
    CHECK(m > 0, "the floor gathers light");
    for (int v = 1; v < 4; v++)
        CHECK(memcmp(o[0][0], o[v][0], sizeof o[0][0]) == 0, "narrow, widest sums and form %d (simd %d, wide %d): the same bits",
              v, v < 3 ? v : 1, v / 3);
    printf("narrow entries: %zu entries, %zu bytes (general %zu)\n", ent[0], bytes[0], bytes[1]);
    CHECK(ent[0] == ent[1] && ent[0] > 0, "the same entries (%zu, %zu)", ent[0], ent[1]);
    CHECK(bytes[0] * 10 == bytes[1] * 4, "4 bytes an entry instead of 10 (%zu, %zu)", bytes[0], bytes[1]);
    wrt_rt_scene_release(&b.rt);
}

int main(int argc, char **argv) {
    TEST_RUN(test_uniform_box);
    TEST_RUN(test_rows_follow_eye);
    TEST_RUN(test_sums_same_bits);
    TEST_RUN(test_narrow_same_bits);
    TEST_END();
}
