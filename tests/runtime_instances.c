/* tests/runtime_instances.c A.gto B.gto: the runtime library through its public header
 * alone (include/wrt.h; linked with libwrt.a only). Two runtimes on different files in
 * one process give bitwise what each gives alone: used in turn, interleaved, and at the
 * same time from two threads; B is opened from memory the caller read. Also: a caller's
 * allocator sees every block returned, and bad calls fail with a status and a message.
 * Run by tests/runtime.sh; prints "N passed, N failed". */
#include <wrt.h>

#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int passed, failed;
#define CHECK(c, ...) do { if (c) passed++; else { failed++; fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__); \
    fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); } } while (0)

/* Everything a runtime produced: every quad's texture and 4 x 4 cell averages. */
typedef struct result { float *tex; size_t ntex; double *cells; size_t ncells; } result;

static void grab(wrt_runtime *rt, result *r) {
    int nq = wrt_runtime_quad_count(rt);
    r->ntex = 0;
    for (int q = 0; q < nq; q++) { int res; wrt_runtime_quad_texture(rt, q, &res); r->ntex += (size_t)res * res * 3; }
    r->tex = malloc(r->ntex * sizeof(float) + 1);
    r->ncells = (size_t)nq * 16 * 3;
    r->cells = malloc(r->ncells * sizeof(double) + 1);
    size_t k = 0;
    for (int q = 0; q < nq; q++) {
        int res;
        const float *t = wrt_runtime_quad_texture(rt, q, &res);
        memcpy(r->tex + k, t, (size_t)res * res * 3 * sizeof(float));
        k += (size_t)res * res * 3;
        wrt_runtime_quad_cells(rt, q, 4, r->cells + (size_t)q * 48, NULL);
    }
}

static int same(const result *a, const result *b) {
    return a->ntex == b->ntex && a->ncells == b->ncells && !memcmp(a->tex, b->tex, a->ntex * sizeof(float)) &&
           !memcmp(a->cells, b->cells, a->ncells * sizeof(double));
}

/* Step k of a fixed light path: the file's lights, light 0 moved. */
static void step(wrt_runtime *rt, int k) {
    wrt_runtime_light l[8];
    int n = wrt_runtime_light_count(rt);
    if (n > 8) n = 8;
    if (n == 0) { memset(l, 0, sizeof l[0]); l[0].position[1] = 0.5; l[0].intensity = 5; n = 1; }
    for (int i = 0; i < n && wrt_runtime_light_count(rt); i++) wrt_runtime_get_light(rt, i, &l[i], NULL);
    l[0].position[0] += 0.05 * cos(k);
    l[0].position[2] += 0.05 * sin(k);
    double eye[3] = {0.1 * k, 1, 3};
    wrt_runtime_set_lights(rt, l, n, NULL);
    wrt_runtime_set_eye(rt, eye, NULL);
    wrt_runtime_update(rt, NULL, NULL);
}

enum { STEPS = 3 };

typedef struct job { wrt_runtime *rt; result out[STEPS]; } job;
static void *run_job(void *p) {
    job *j = p;
    for (int k = 0; k < STEPS; k++) { step(j->rt, k); grab(j->rt, &j->out[k]); }
    return NULL;
}

/* A counting allocator; with fail_at > 0, allocation number fail_at fails. */
typedef struct counter { long allocs, frees, fail_at; } counter;
static void *c_alloc(size_t n, void *u) {
    counter *c = u;
    if (c->fail_at > 0 && c->allocs + 1 == c->fail_at) { c->fail_at = -1; return NULL; }
    c->allocs++;
    return malloc(n);
}
static void c_free(void *p, void *u) { if (p) ((counter *)u)->frees++; free(p); }

static void *read_all(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *p = aligned_alloc(64, ((size_t)n + 63) / 64 * 64);
    if (p && fread(p, 1, (size_t)n, f) != (size_t)n) { free(p); p = NULL; }
    fclose(f);
    *size = (size_t)n;
    return p;
}

int main(int argc, char **argv) {
    if (argc != 3) { fprintf(stderr, "usage: %s A.gto B.gto\n", argv[0]); return 1; }
    size_t bsize;
    void *bdata = read_all(argv[2], &bsize);
    CHECK(bdata != NULL, "read %s", argv[2]);
    if (!bdata) return 1;
    wrt_runtime_options opt = {.threads = 2};
    counter cnt = {0, 0, 0};
    opt.allocator = (wrt_allocator){c_alloc, c_free, &cnt};
    wrt_error err;
    result alone[2][STEPS];
    /* each alone */
    for (int w = 0; w < 2; w++) {
        wrt_runtime *rt;
        wrt_status s = w == 0 ? wrt_runtime_open_file(argv[1], &opt, &rt, &err)
                              : wrt_runtime_open_memory(bdata, bsize, &opt, &rt, &err);
        CHECK(s == WRT_OK, "open %d: %s", w, err.message);
        if (s) return 1;
        for (int k = 0; k < STEPS; k++) { step(rt, k); grab(rt, &alone[w][k]); }
        wrt_runtime_close(rt);
    }
    CHECK(!same(&alone[0][0], &alone[1][0]), "the two files give different results");
    /* both open, interleaved */
    wrt_runtime *a, *b;
    CHECK(wrt_runtime_open_file(argv[1], &opt, &a, &err) == WRT_OK, "%s", err.message);
    CHECK(wrt_runtime_open_memory(bdata, bsize, &opt, &b, &err) == WRT_OK, "%s", err.message);
    int inter_ok = 1;
    for (int k = 0; k < STEPS; k++) {
        result ra, rb;
        step(b, k);
        step(a, k);
        grab(a, &ra); grab(b, &rb);
        inter_ok &= same(&ra, &alone[0][k]) && same(&rb, &alone[1][k]);
        free(ra.tex); free(ra.cells); free(rb.tex); free(rb.cells);
    }
    CHECK(inter_ok, "interleaved: bitwise what each gives alone");
    wrt_runtime_close(a);
    wrt_runtime_close(b);
    /* both at once from two threads */
    job ja = {0}, jb = {0};
    CHECK(wrt_runtime_open_file(argv[1], &opt, &ja.rt, &err) == WRT_OK, "%s", err.message);
    CHECK(wrt_runtime_open_memory(bdata, bsize, &opt, &jb.rt, &err) == WRT_OK, "%s", err.message);
    pthread_t ta, tb;
    pthread_create(&ta, NULL, run_job, &ja);
    pthread_create(&tb, NULL, run_job, &jb);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    int thr_ok = 1;
    for (int k = 0; k < STEPS; k++) {
        thr_ok &= same(&ja.out[k], &alone[0][k]) && same(&jb.out[k], &alone[1][k]);
        free(ja.out[k].tex); free(ja.out[k].cells); free(jb.out[k].tex); free(jb.out[k].cells);
    }
    CHECK(thr_ok, "two threads at once: bitwise what each gives alone");
    wrt_runtime_close(ja.rt);
    wrt_runtime_close(jb.rt);
    CHECK(cnt.allocs > 0 && cnt.allocs == cnt.frees, "allocator: %ld blocks, %ld freed", cnt.allocs, cnt.frees);
    /* every allocation of open failing in turn: WRT_ERR_NOMEM, everything given back */
    int nomem_ok = 1, tries = 0;
    for (long k = 1; k < 1000; k++, tries++) {
        counter fc = {0, 0, k};
        wrt_runtime_options fo = {.threads = 2, .allocator = {c_alloc, c_free, &fc}};
        wrt_runtime *f;
        wrt_status st = wrt_runtime_open_memory(bdata, bsize, &fo, &f, &err);
        if (st == WRT_OK) { wrt_runtime_close(f); nomem_ok &= fc.allocs == fc.frees; break; }
        nomem_ok &= st == WRT_ERR_NOMEM && f == NULL && fc.allocs == fc.frees && err.message[0];
    }
    CHECK(nomem_ok && tries > 5, "each of the %d allocations of open failing: WRT_ERR_NOMEM, nothing leaked", tries);
    /* errors: status and message, nothing aborts */
    wrt_runtime *x = (wrt_runtime *)&cnt;
    wrt_status s = wrt_runtime_open_file("/nonexistent/none.gto", NULL, &x, &err);
    CHECK(s == WRT_ERR_IO && err.status == WRT_ERR_IO && strstr(err.message, "none.gto") && x == NULL,
          "missing file: status %d, message '%s'", s, err.message);
    s = wrt_runtime_open_memory(bdata, bsize > 100 ? 100 : bsize, NULL, &x, &err);
    CHECK(s == WRT_ERR_CORRUPT || s == WRT_ERR_NOT_OURS, "truncated image: status %d ('%s')", s, err.message);
    CHECK(wrt_runtime_open_file(argv[1], NULL, &a, &err) == WRT_OK, "%s", err.message);
    wrt_runtime_light bad = {0};
    bad.position[0] = NAN;
    s = wrt_runtime_set_lights(a, &bad, 1, &err);
    CHECK(s == WRT_ERR_INVALID_ARG && err.message[0], "NaN light: status %d ('%s')", s, err.message);
    wrt_runtime_close(a);
    for (int w = 0; w < 2; w++)
        for (int k = 0; k < STEPS; k++) { free(alone[w][k].tex); free(alone[w][k].cells); }
    free(bdata);
    printf("%s: %d passed, %d failed\n", argv[0], passed, failed);
    return failed != 0;
}
