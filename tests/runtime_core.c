/* tests/runtime_core.c RANGED.gto: the public API (include/wrt.h) beside the relighting
 * core it wraps (player/relight.h), on a file whose light has a glTF range: the file's
 * light through wrt_runtime_get_light / wrt_runtime_set_lights gives bitwise the core's
 * result for the same light (its range included), as stored and moved; and the core
 * given the light without its range gives something else (so the range is what is
 * compared). Links the runtime part, not libwrt.a (the core is internal). Run by
 * tests/runtime.sh; prints "N passed, N failed". */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "include/wrt.h"
#include "player/relight.h"

static int passed, failed;
#define CHECK(c, ...) do { if (c) passed++; else { failed++; fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__); \
    fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); } } while (0)

/* The core's light for the file's light i, moved by dx along x. */
static wrt_light core_light(const wrt_gto *g, int i, double dx, int keep_range) {
    const wrt_gto_light *f = &g->lights[i];
    wrt_light l;
    memset(&l, 0, sizeof l);
    l.type = f->type == WRT_LIGHT_SPOT ? WRT_LIGHT_SPOT : WRT_LIGHT_POINT;
    l.pos = v3(f->pos[0] + dx, f->pos[1], f->pos[2]);
    l.dir = l.type == WRT_LIGHT_SPOT ? v3_norm(v3(f->dir[0], f->dir[1], f->dir[2])) : v3(0, 0, -1);
    int black = f->color[0] == 0 && f->color[1] == 0 && f->color[2] == 0;
    for (int c = 0; c < 3; c++) l.color[c] = black ? 1.0f : f->color[c];
    l.intensity = f->intensity;
    l.range = keep_range ? f->range : 0;
    l.inner_cone = l.type == WRT_LIGHT_SPOT ? f->inner_cone : 0;
    l.outer_cone = l.type == WRT_LIGHT_SPOT ? f->outer_cone : (float)(WRT_PI / 4);
    return l;
}

int main(int argc, char **argv) {
    if (argc != 2) { fprintf(stderr, "usage: %s RANGED.gto\n", argv[0]); return 1; }
    wrt_gto g;
    if (wrt_gto_open(argv[1], &g)) { fprintf(stderr, "%s: %s\n", argv[1], wrt_last_error()); return 1; }
    CHECK(g.nlights >= 1 && g.lights[0].range > 0, "the file's light has a range (%g)",
          g.nlights ? (double)g.lights[0].range : 0.0);
    wrt_relight_options ro = {.threads = 1, .max_tex_res = 64};
    wrt_relight *core;
    wrt_runtime *rt;
    wrt_error err;
    wrt_runtime_options o = {.threads = 1};
    if (wrt_relight_create(&g, &ro, &core) || wrt_runtime_open_file(argv[1], &o, &rt, &err)) {
        fprintf(stderr, "create: %s\n", wrt_last_error());
        return 1;
    }
    double eye[3] = {2.5, 0.8, 1.5};
    wrt_relight_set_eye(core, eye);
    wrt_runtime_set_eye(rt, eye, NULL);
    for (int step = 0; step < 3; step++) {
        double dx = 0.05 * step;
        wrt_runtime_light l;
        wrt_runtime_get_light(rt, 0, &l, NULL);
        l.position[0] += dx;
        wrt_status s = wrt_runtime_set_lights(rt, &l, 1, &err);
        if (!s) s = wrt_runtime_update(rt, NULL, &err);
        for (int keep = 1; keep >= 0; keep--) {
            wrt_light cl = core_light(&g, 0, dx, keep);
            float one = 1;
            wrt_relight_set_lights(core, &cl, &one, 1);
            int n = wrt_relight_update(core, NULL);
            int same = s == WRT_OK && n >= 0, lit = 0;
            for (uint32_t q = 0; q < g.nquads; q++) {
                int res;
                const float *a = wrt_runtime_quad_texture(rt, (int)q, &res), *b = wrt_relight_tex(core, (int)q);
                same &= a && b && res == wrt_relight_tex_res(core, (int)q) &&
                        !memcmp(a, b, (size_t)res * res * 3 * sizeof(float));
                for (int i = 0; a && i < res * res * 3; i++) lit |= a[i] > 0;
            }
            CHECK(lit && (keep ? same : !same), "step %d: the API's ranged light %s the core's light %s its range "
                  "(lit: %d)", step, keep ? "is bitwise" : "differs from", keep ? "with" : "without", lit);
        }
    }
    wrt_runtime_close(rt);
    wrt_relight_destroy(core);
    wrt_gto_close(&g);
    printf("%s: %d passed, %d failed\n", argv[0], passed, failed);
    return failed != 0;
}
