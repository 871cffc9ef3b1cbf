/* tools/light_bw.c FILE.gto [UPDATES]: a light change against the memory it reads (issue
 * 23, docs/bench.md "The light change against the memory bandwidth"). Measures this
 * machine's single-thread memory bandwidth (a 256 MB array summed, and memcpy'd; the best
 * of 5 passes each), then relights FILE through the public library on one thread,
 * moving light 1 around a circle (2% of the scene's diagonal) UPDATES times (default
 * 41), and prints one JSON object: the bandwidths, the median CPU milliseconds of a light
 * change (and the wall milliseconds of its stages, as the library times them), the operator's entries a multiply streams (the lit columns'
 * only) and the bytes they take at least (5 compact, 16 float), and the time those bytes take
 * at the read bandwidth as a fraction of the light change and of its multiply, and a
 * hash (FNV-1a) of every quad's texture bytes after every update, so that two builds'
 * light changes can be compared bit for bit. Not installed. */
#include <wrt.h>

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double wall_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* FNV-1a of every quad's texture after an update, folded into h. */
static uint64_t texture_hash(const wrt_runtime *rt, uint64_t h) {
    for (int q = 0; q < wrt_runtime_quad_count(rt); q++) {
        int res = 0;
        const float *t = wrt_runtime_quad_texture(rt, q, &res);
        const unsigned char *b = (const unsigned char *)t;
        size_t n = t ? (size_t)res * res * 3 * sizeof(float) : 0;
        for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 1099511628211ull;
    }
    return h;
}

/* GB/s of reading (sum) and of memcpy (bytes read + written) over 256 MB, best of 5,
 * from CPU time (the machine is shared: wall time counts the other processes). */
static void bandwidth(double *read_gbs, double *copy_gbs) {
    size_t n = (size_t)64 << 20; /* floats: 256 MB */
    float *a = malloc(n * sizeof *a), *b = malloc(n * sizeof *b);
    if (!a || !b) { fprintf(stderr, "light_bw: out of memory\n"); exit(1); }
    for (size_t i = 0; i < n; i++) a[i] = b[i] = (float)(i & 1023);
    double best_r = 1e9, best_c = 1e9, sink = 0;
    for (int pass = 0; pass < 5; pass++) {
        double t0 = cpu_now();
        float s0 = 0, s1 = 0, s2 = 0, s3 = 0;
        for (size_t i = 0; i < n; i += 4) { s0 += a[i]; s1 += a[i + 1]; s2 += a[i + 2]; s3 += a[i + 3]; }
        double t1 = cpu_now();
        memcpy(b, a, n * sizeof *a);
        double t2 = cpu_now();
        sink += s0 + s1 + s2 + s3 + b[pass];
        if (t1 - t0 < best_r) best_r = t1 - t0;
        if (t2 - t1 < best_c) best_c = t2 - t1;
    }
    *read_gbs = n * sizeof(float) / best_r * 1e-9;
    *copy_gbs = 2.0 * n * sizeof(float) / best_c * 1e-9;
    if (sink == 12345.678) puts(""); /* keeps the sums */
    free(a);
    free(b);
}

int main(int argc, char **argv) {
    if (argc < 2) { fprintf(stderr, "usage: light_bw FILE.gto [UPDATES]\n"); return 2; }
    int n = argc > 2 ? atoi(argv[2]) : 41;
    if (n < 1 || n > 100000) { fprintf(stderr, "light_bw: UPDATES %s: 1 to 100000\n", argv[2]); return 2; }
    double rd, cp;
    bandwidth(&rd, &cp);
    wrt_runtime_options o;
    memset(&o, 0, sizeof o);
    o.size = sizeof o;
    o.threads = 1;
    wrt_runtime *rt;
    wrt_error err;
    if (wrt_runtime_open_file(argv[1], &o, &rt, &err) != WRT_OK) {
        fprintf(stderr, "light_bw: %s\n", err.message);
        return 1;
    }
    wrt_runtime_file_info fi;
    wrt_runtime_get_file_info(rt, &fi, NULL);
    int nl = wrt_runtime_light_count(rt);
    if (nl < 1) { fprintf(stderr, "light_bw: %s has no light\n", argv[1]); return 1; }
    if (nl > 16) nl = 16;
    wrt_runtime_light l[16];
    for (int i = 0; i < nl; i++) wrt_runtime_get_light(rt, i, &l[i], NULL);
    double lo[3], hi[3];
    wrt_runtime_get_bounds(rt, lo, hi, NULL);
    double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    double eye[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
    wrt_runtime_set_eye(rt, eye, NULL);
    wrt_runtime_set_lights(rt, l, nl, NULL);
    wrt_runtime_update(rt, NULL, NULL); /* the first projects every light */
    double *ms = malloc(sizeof(double) * n * 6), p0[3] = {l[0].position[0], l[0].position[1], l[0].position[2]};
    wrt_runtime_update_stats s0, s1, st;
    wrt_runtime_get_update_stats(rt, &s0, NULL);
    double w0 = wall_now(), hash_s = 0;
    uint64_t h = texture_hash(rt, 14695981039346656037ull);
    for (int k = 0; k < n; k++) {
        double a = 2 * M_PI * (k + 1) / n, rad = 0.02 * diag;
        l[0].position[0] = p0[0] + rad * cos(a);
        l[0].position[2] = p0[2] + rad * sin(a);
        l[0].direction[0] += 0.01 * (k % 2 ? -1 : 1);
        wrt_runtime_set_lights(rt, l, nl, NULL);
        double t0 = cpu_now();
        if (wrt_runtime_update(rt, NULL, &err) != WRT_OK) { fprintf(stderr, "light_bw: %s\n", err.message); return 1; }
        ms[k] = (cpu_now() - t0) * 1e3;
        wrt_runtime_get_update_stats(rt, &st, NULL);
        for (int j = 0; j < 5; j++) ms[(size_t)(j + 1) * n + k] = st.ms[j];
        double h0 = wall_now();
        h = texture_hash(rt, h);
        hash_s += wall_now() - h0;
    }
    double wall = (wall_now() - w0 - hash_s) * 1e3 / n;
    wrt_runtime_get_update_stats(rt, &s1, NULL);
    double med[6];
    for (int j = 0; j < 6; j++) med[j] = median(ms + (size_t)j * n, n);
    double entries = (double)(s1.entries_streamed - s0.entries_streamed) / n;
    /* bytes an entry the multiply reads at least: a compact file's (2.x) 32-bit code and
     * 1-byte row step (its 8-byte block headers left out), a float file's 4-byte row and
     * three 4-byte values; a first-bounce operator K (glossy) is not counted */
    double bpe = fi.version_major >= 2 ? 5.0 : 16.0;
    double mb = entries * bpe * 1e-6, at_bw_ms = mb * 1e-3 / rd * 1e3;
    printf("{\"file\": \"%s\", \"bytes\": %llu, \"entries\": %llu, \"read_gb_s\": %.2f, \"memcpy_gb_s\": %.2f, "
           "\"updates\": %d, \"cpu_ms_light_change\": %.3f, \"wall_ms_light_change\": %.3f, \"stage_ms_wall\": "
           "{\"projection\": %.3f, \"multiply\": %.3f, \"brdf\": %.3f, \"synthesis\": %.3f, \"smoothing\": %.3f}, "
           "\"entries_streamed\": %.0f, \"bytes_per_entry\": %.2f, \"operator_mb_read\": %.2f, "
           "\"ms_at_read_bandwidth\": %.3f, \"fraction_of_light_change\": %.3f, \"fraction_of_multiply\": %.3f, "
           "\"textures_fnv\": \"%016llx\"}\n",
           argv[1], fi.bytes, fi.entries, rd, cp, n, med[0], wall, med[1], med[2], med[3], med[4], med[5], entries, bpe,
           mb, at_bw_ms, med[0] > 0 ? at_bw_ms / med[0] : 0, med[2] > 0 ? at_bw_ms / med[2] : 0, (unsigned long long)h);
    free(ms);
    wrt_runtime_close(rt);
    return 0;
}
