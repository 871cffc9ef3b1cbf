/* examples/relight.c: the runtime library (include/wrt.h) in a few lines. Opens the .gto
 * given on the command line, lowers its first light (or adds one at the scene's centre),
 * relights, and prints each quad's mean outgoing indirect radiance.
 *   cc relight.c $(pkg-config --cflags --libs wrt) -o relight && ./relight scene.gto */
#include <stdio.h>
#include <wrt.h>

int main(int argc, char **argv) {
    if (argc != 2) { fprintf(stderr, "usage: %s FILE.gto\n", argv[0]); return 1; }
    wrt_runtime *rt;
    wrt_error err;
    /* NULL options: the defaults (all cores, textures up to 64 x 64 texels). */
    if (wrt_runtime_open_file(argv[1], NULL, &rt, &err)) {
        fprintf(stderr, "%s: %s\n", argv[1], err.message);
        return 2;
    }
    /* The scene's box (of every quad's corners): to place the eye and a light. */
    double lo[3], hi[3];
    wrt_runtime_get_bounds(rt, lo, hi, NULL);
    wrt_runtime_light light = {0}; /* zero: a white point light, on */
    if (wrt_runtime_light_count(rt) > 0) {
        wrt_runtime_get_light(rt, 0, &light, NULL);
        light.position[1] -= 0.1 * (hi[1] - lo[1]); /* move it down a tenth of the box */
    } else {
        for (int c = 0; c < 3; c++) light.position[c] = 0.5 * (lo[c] + hi[c]);
        light.intensity = 10;
    }
    double eye[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), hi[2] + (hi[2] - lo[2])};
    if (wrt_runtime_set_lights(rt, &light, 1, &err) || wrt_runtime_set_eye(rt, eye, &err) ||
        wrt_runtime_update(rt, NULL, &err)) {
        fprintf(stderr, "%s: %s\n", argv[1], err.message);
        wrt_runtime_close(rt);
        return 7;
    }
    /* One line per quad: index and mean outgoing indirect radiance (linear RGB). */
    for (int q = 0; q < wrt_runtime_quad_count(rt); q++) {
        float m[3];
        wrt_runtime_quad_mean(rt, q, m, NULL);
        printf("%d %.6g %.6g %.6g\n", q, m[0], m[1], m[2]);
    }
    wrt_runtime_close(rt);
    return 0;
}
