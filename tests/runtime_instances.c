/* tests/runtime_instances.c A.gto B.gto: the runtime library through its public header
 * alone (include/wrt.h; linked with libwrt.a only). Two runtimes on different files in
 * one process give bitwise what each gives alone: used in turn, interleaved, and at the
 * same time from two threads; B is opened from memory the caller read. Also: a caller's
 * allocator sees every block returned, every allocation of open and of an update failing in
 * turn gives WRT_ERR_NOMEM with nothing leaked (and the next update gives bitwise the right
 * answer), a caller's job hook (serial, and two threads of its own) gives bitwise what the
 * runtime's pool gives, and bad calls fail with a status and a message.
 * Run by tests/runtime.sh; prints "N passed, N failed". */
#include <wrt.h>

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
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

/* Step k of a fixed light path: the file's lights, light 0 moved. The first failing
 * status (or WRT_OK). */
static wrt_status step(wrt_runtime *rt, int k, wrt_error *err) {
    wrt_runtime_light l[8];
    int n = wrt_runtime_light_count(rt);
    if (n > 8) n = 8;
    if (n == 0) { memset(l, 0, sizeof l[0]); l[0].position[1] = 0.5; l[0].intensity = 5; n = 1; }
    for (int i = 0; i < n && wrt_runtime_light_count(rt); i++) wrt_runtime_get_light(rt, i, &l[i], NULL);
    l[0].position[0] += 0.05 * cos(k);
    l[0].position[2] += 0.05 * sin(k);
    double eye[3] = {0.1 * k, 1, 3};
    wrt_status s;
    if ((s = wrt_runtime_set_lights(rt, l, n, err)) || (s = wrt_runtime_set_eye(rt, eye, err)) ||
        (s = wrt_runtime_update(rt, NULL, err)))
        return s;
    return WRT_OK;
}

enum { STEPS = 3 };

typedef struct job { wrt_runtime *rt; result out[STEPS]; } job;
static void *run_job(void *p) {
    job *j = p;
    for (int k = 0; k < STEPS; k++) { step(j->rt, k, NULL); grab(j->rt, &j->out[k]); }
    return NULL;
}

/* A counting allocator (thread-safe: the update's workers call it at once); with
 * fail_at > 0, attempt number fail_at fails. */
typedef struct counter { atomic_long attempts, allocs, frees; long fail_at; } counter;
static void *c_alloc(void *u, size_t n) {
    counter *c = u;
    long k = atomic_fetch_add(&c->attempts, 1) + 1;
    if (c->fail_at > 0 && k == c->fail_at) return NULL;
    atomic_fetch_add(&c->allocs, 1);
    return malloc(n);
}
static void c_free(void *u, void *p) { if (p) atomic_fetch_add(&((counter *)u)->frees, 1); free(p); }

/* Job hooks: all items on the calling thread, in order; or on the calling thread and one
 * thread of the hook's own, items taken from a shared counter. */
static atomic_int hook_calls;
static void serial_hook(void *user, int n, void (*fn)(void *ctx, int i), void *ctx) {
    (void)user;
    atomic_fetch_add(&hook_calls, 1);
    for (int i = n - 1; i >= 0; i--) fn(ctx, i); /* backwards: order must not matter */
}
typedef struct hook_loop { int n; atomic_int next; void (*fn)(void *ctx, int i); void *ctx; } hook_loop;
static void *hook_thread(void *p) {
    hook_loop *h = p;
    for (int i; (i = atomic_fetch_add(&h->next, 1)) < h->n;) h->fn(h->ctx, i);
    return NULL;
}
static void two_thread_hook(void *user, int n, void (*fn)(void *ctx, int i), void *ctx) {
    (void)user;
    atomic_fetch_add(&hook_calls, 1);
    hook_loop h = {n, 0, fn, ctx};
    pthread_t t;
    int started = pthread_create(&t, NULL, hook_thread, &h) == 0;
    hook_thread(&h);
    if (started) pthread_join(t, NULL);
}

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
    counter cnt = {0};
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
        for (int k = 0; k < STEPS; k++) { step(rt, k, NULL); grab(rt, &alone[w][k]); }
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
        step(b, k, NULL);
        step(a, k, NULL);
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
    CHECK(cnt.allocs > 0 && cnt.allocs == cnt.frees, "allocator: %ld blocks, %ld freed", (long)cnt.allocs, (long)cnt.frees);
    /* every allocation of open failing in turn: WRT_ERR_NOMEM, everything given back */
    int nomem_ok = 1, tries = 0;
    for (long k = 1; k < 1000; k++, tries++) {
        counter fc = {0};
        fc.fail_at = k;
        wrt_runtime_options fo = {.threads = 2, .allocator = {c_alloc, c_free, &fc}};
        wrt_runtime *f;
        wrt_status st = wrt_runtime_open_memory(bdata, bsize, &fo, &f, &err);
        if (st == WRT_OK) { wrt_runtime_close(f); nomem_ok &= fc.allocs == fc.frees; break; }
        nomem_ok &= st == WRT_ERR_NOMEM && f == NULL && fc.allocs == fc.frees && err.message[0];
    }
    CHECK(nomem_ok && tries > 5, "each of the %d allocations of open failing: WRT_ERR_NOMEM, nothing leaked", tries);
    /* every allocation of the first update (lights, projection, synthesis, smooth display
     * scratch, on 2 threads) failing in turn: WRT_ERR_NOMEM with a message; the same step
     * again then gives bitwise the right textures and cells; nothing leaked */
    for (int w = 0; w < 2; w++) {
        int upd_ok = 1, fails = 0, steps_ok = 1;
        long k;
        for (k = 1; k < 2000; k++) {
            counter fc = {0};
            wrt_runtime_options fo = {.threads = 2, .allocator = {c_alloc, c_free, &fc}};
            wrt_runtime *f;
            if ((w == 0 ? wrt_runtime_open_file(argv[1], &fo, &f, &err) : wrt_runtime_open_memory(bdata, bsize, &fo, &f, &err))) {
                upd_ok = 0;
                break;
            }
            fc.fail_at = atomic_load(&fc.attempts) + k;
            err.message[0] = 0;
            wrt_status st = step(f, 0, &err);
            int hit = atomic_load(&fc.attempts) >= fc.fail_at;
            fc.fail_at = 0;
            if (st != WRT_OK) {
                fails++;
                upd_ok &= st == WRT_ERR_NOMEM && err.status == WRT_ERR_NOMEM && strstr(err.message, "memory") != NULL;
                st = step(f, 0, &err);
            }
            result rr;
            int got = st == WRT_OK;
            if (got) { grab(f, &rr); steps_ok &= same(&rr, &alone[w][0]); free(rr.tex); free(rr.cells); }
            steps_ok &= got;
            wrt_runtime_close(f);
            upd_ok &= atomic_load(&fc.allocs) == atomic_load(&fc.frees);
            if (!hit) break; /* the update needed fewer than k allocations: all tried */
        }
        printf("update out of memory, file %d: %d allocations failed in turn\n", w, fails);
        CHECK(upd_ok && steps_ok && fails > 3 && fails == k - 1,
              "file %d: each of the %ld allocations of an update failing: %d gave WRT_ERR_NOMEM (%s), retried "
              "bitwise right (%s), nothing leaked", w, k - 1, fails, upd_ok ? "all" : "not all", steps_ok ? "yes" : "no");
    }
    /* a job hook instead of the pool: bitwise the same results, and the hook was used */
    for (int hk = 0; hk < 2; hk++) {
        int hook_ok = 1;
        atomic_store(&hook_calls, 0);
        for (int w = 0; w < 2; w++) {
            wrt_runtime_options ho = {.threads = hk ? 2 : 1, .parallel_for = hk ? two_thread_hook : serial_hook};
            wrt_runtime *h;
            if ((w == 0 ? wrt_runtime_open_file(argv[1], &ho, &h, &err) : wrt_runtime_open_memory(bdata, bsize, &ho, &h, &err))) {
                hook_ok = 0;
                continue;
            }
            for (int k = 0; k < STEPS; k++) {
                result rr;
                hook_ok &= step(h, k, NULL) == WRT_OK;
                grab(h, &rr);
                hook_ok &= same(&rr, &alone[w][k]);
                free(rr.tex); free(rr.cells);
            }
            wrt_runtime_close(h);
        }
        printf("%s job hook: %d loops\n", hk ? "two-thread" : "serial", atomic_load(&hook_calls));
        CHECK(hook_ok && atomic_load(&hook_calls) > 0, "%s job hook: bitwise the pool's results (%d loops on the hook)",
              hk ? "two-thread" : "serial", atomic_load(&hook_calls));
    }
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
