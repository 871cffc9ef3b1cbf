/* relight_base.c: what every part of the relighter uses (relight_internal.h): the
 * parallel loop on the relighter's thread pool or the caller's job hook, the caller's
 * allocator and the update's scratch that grows on demand, the log, the 2D Haar analysis
 * and synthesis of a quad's pyramid (docs/algorithm.md, the basis), the distance to a
 * quad and a light's constants. No part of the paper of its own: the plumbing under
 * sections 5.1-5.4. Depends on common/threads.h and common/wrt_common.h. */
#include "relight_internal.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

/* ---------------------------------------------------------------- threads ---- */

typedef struct job { wrt_relight *r; job_fn fn; void *ctx; } job;

static void job_item(size_t item, int thread, void *user) {
    job *j = user;
    j->fn(j->r, &j->r->workers[thread], (int)item, j->ctx);
}

/* Below this much work (units of about one shadow ray, ~0.2 us) a loop runs on the
 * calling thread: starting threads, and waiting for the slowest, would cost more. */
#define PARALLEL_MIN_WORK 10000.0

/* The caller's job hook runs items on threads of its choosing, at most nthreads at once:
 * each item takes a free worker slot (its scratch) for its duration. More calls at once
 * than promised wait for a slot. */
static void hook_item(void *user, int item) {
    job *j = user;
    wrt_relight *r = j->r;
    for (;;) {
        for (int t = 0; t < r->nthreads; t++) {
            unsigned char free_slot = 0;
            if (atomic_load_explicit(&r->wbusy[t], memory_order_relaxed) == 0 &&
                atomic_compare_exchange_strong(&r->wbusy[t], &free_slot, 1)) {
                j->fn(r, &r->workers[t], item, j->ctx);
                atomic_store(&r->wbusy[t], 0);
                return;
            }
        }
        sched_yield();
    }
}

/* Creation's progress (relight_internal.h). */
int relight_progress(wrt_relight *r, double fraction) {
    if (!r->opt.progress) return 1;
    if (!(fraction > r->prog_last)) fraction = r->prog_last; /* never falls (NaN too) */
    if (fraction > 1) fraction = 1;
    r->prog_last = fraction;
    return r->opt.progress(r->opt.progress_user, fraction) != 0;
}

/* Runs fn over items 0..n-1 on up to nthreads threads (one if `work` is small; with a job
 * hook, every loop of 2 items or more goes to the hook); returns the number of threads
 * used. Results must not depend on which worker ran an item (callers write per item, or
 * merge per item in item order). */
int relight_parallel_for(wrt_relight *r, int n, double work, job_fn fn, void *ctx) {
    if (n <= 0) return 0;
    job j = {r, fn, ctx};
    if (r->opt.parallel_for) {
        if (n == 1) { fn(r, &r->workers[0], 0, ctx); return 1; }
        r->opt.parallel_for(r->opt.parallel_user, n, hook_item, &j);
        return r->nthreads;
    }
    return wrt_pool_run(r->pool, (size_t)n, work < PARALLEL_MIN_WORK ? 1 : 0, job_item, &j);
}

/* The relighter's own arrays come from the caller's allocator (wrt_relight_options;
 * malloc/free by default); a failure marks r->oom and the call returns WRT_ERR_NOMEM.
 * The workers' scratch, grown during updates, too: grow below. */
void *relight_calloc(wrt_relight *r, size_t count, size_t size) {
    if (size && count > SIZE_MAX / size) { r->oom = 1; return NULL; }
    size_t n = count * size;
    if (!n) n = 1;
    void *p = r->opt.alloc ? r->opt.alloc(r->opt.alloc_user, n) : malloc(n);
    if (!p) { r->oom = 1; return NULL; }
    return memset(p, 0, n);
}
void relight_free(const wrt_relight *r, void *p) {
    if (!p) return;
    if (r->opt.alloc && r->opt.free) r->opt.free(r->opt.alloc_user, p);
    else free(p);
}

/* Scratch of at least `need` elements: p itself if it holds them, else a larger block
 * from the caller's allocator (the first `keep` elements copied, p freed, *cap updated).
 * NULL if there is no memory: p and *cap are left as they were and r->upd_oom is set (the
 * update then fails with WRT_ERR_NOMEM). Called from worker threads. */
void *relight_grow_keep(wrt_relight *r, void *p, size_t *cap, size_t need, size_t elem, size_t keep) {
    if (need <= *cap) return p;
    size_t c = *cap ? *cap : 64;
    while (c < need) c *= 2;
    void *np = c > SIZE_MAX / elem ? NULL : r->opt.alloc ? r->opt.alloc(r->opt.alloc_user, c * elem) : malloc(c * elem);
    if (!np) { atomic_store(&r->upd_oom, 1); return NULL; }
    if (keep && p) memcpy(np, p, keep * elem);
    relight_free(r, p);
    *cap = c;
    return np;
}
void *relight_grow(wrt_relight *r, void *p, size_t *cap, size_t need, size_t elem) {
    return relight_grow_keep(r, p, cap, need, elem, 0);
}


/* Haar analysis in place: `v` holds 4^L scaling coefficients of level L (row-major,
 * nc channels interleaved); on return pyr[haar_index * nc + c] holds the root scaling
 * and every wavelet of levels < L. `v` is used as scratch. */
void relight_haar_analyse(double *v, int L, int nc, double *pyr) {
    for (int l = L - 1; l >= 0; l--) {
        int n = 1 << l, n2 = 2 * n;
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                for (int c = 0; c < nc; c++) {
                    double a = v[((2 * y) * n2 + 2 * x) * nc + c];
                    double b = v[((2 * y) * n2 + 2 * x + 1) * nc + c];
                    double d = v[((2 * y + 1) * n2 + 2 * x) * nc + c];
                    double e = v[((2 * y + 1) * n2 + 2 * x + 1) * nc + c];
                    uint32_t k = haar_index(l, x, y, 1);
                    pyr[k * nc + c] = (a - b + d - e) * 0.5;            /* type 1: sign by cx */
                    pyr[(k + 1) * nc + c] = (a + b - d - e) * 0.5;      /* type 2: sign by cy */
                    pyr[(k + 2) * nc + c] = (a - b - d + e) * 0.5;      /* type 3 */
                    v[(y * n + x) * nc + c] = (a + b + d + e) * 0.5;
                }
    }
    for (int c = 0; c < nc; c++) pyr[c] = v[c];
}

/* Inverse of haar_analyse in single precision for 3 channels padded to 4 (SIMD): from
 * the pyramid `pyr` (levels < L, 4 floats a coefficient) to `out` (4^L texels, `ostride`
 * floats apart, 3 written); `v` is scratch for 4^(L-1) x 4 floats (at least 4); pyr and
 * v 16-byte aligned. The textures are floats; 6 levels of additions add ~1e-6 relative. */
void relight_haar_synthesize4f(const float *pyr, int L, float *v, float *out, int ostride) {
    if (L == 0) { memcpy(out, pyr, 3 * sizeof(float)); return; }
    memcpy(v, pyr, 4 * sizeof(float));
    for (int l = 0; l < L; l++) {
        int n = 1 << l, n2 = 2 * n, last = l == L - 1;
        for (int y = n - 1; y >= 0; y--) /* backwards: in place in v until the last level */
            for (int x = n - 1; x >= 0; x--) {
                const float *w1 = pyr + (size_t)haar_index(l, x, y, 1) * 4, *w2 = w1 + 4, *w3 = w1 + 8;
                const float *pv = v + ((size_t)y * n + x) * 4;
                float q[4][4]; /* children (2x, 2y), (2x+1, 2y), (2x, 2y+1), (2x+1, 2y+1) */
#ifdef __SSE2__
                __m128 p = _mm_load_ps(pv), a1 = _mm_load_ps(w1), a2 = _mm_load_ps(w2), a3 = _mm_load_ps(w3);
                __m128 h = _mm_set1_ps(0.5f), s0 = _mm_add_ps(p, a2), s1 = _mm_sub_ps(p, a2);
                __m128 c0 = _mm_mul_ps(h, _mm_add_ps(s0, _mm_add_ps(a1, a3)));
                __m128 c1 = _mm_mul_ps(h, _mm_sub_ps(s0, _mm_add_ps(a1, a3)));
                __m128 c2 = _mm_mul_ps(h, _mm_add_ps(s1, _mm_sub_ps(a1, a3)));
                __m128 c3 = _mm_mul_ps(h, _mm_sub_ps(s1, _mm_sub_ps(a1, a3)));
                if (!last) {
                    float *a = v + ((size_t)(2 * y) * n2 + 2 * x) * 4, *d = v + ((size_t)(2 * y + 1) * n2 + 2 * x) * 4;
                    _mm_store_ps(a, c0); _mm_store_ps(a + 4, c1); _mm_store_ps(d, c2); _mm_store_ps(d + 4, c3);
                    continue;
                }
                _mm_storeu_ps(q[0], c0); _mm_storeu_ps(q[1], c1); _mm_storeu_ps(q[2], c2); _mm_storeu_ps(q[3], c3);
#else
                for (int c = 0; c < 4; c++) {
                    float s0 = pv[c] + w2[c], s1 = pv[c] - w2[c];
                    q[0][c] = 0.5f * (s0 + (w1[c] + w3[c]));
                    q[1][c] = 0.5f * (s0 - (w1[c] + w3[c]));
                    q[2][c] = 0.5f * (s1 + (w1[c] - w3[c]));
                    q[3][c] = 0.5f * (s1 - (w1[c] - w3[c]));
                }
                if (!last) {
                    float *a = v + ((size_t)(2 * y) * n2 + 2 * x) * 4, *d = v + ((size_t)(2 * y + 1) * n2 + 2 * x) * 4;
                    memcpy(a, q[0], 16); memcpy(a + 4, q[1], 16); memcpy(d, q[2], 16); memcpy(d + 4, q[3], 16);
                    continue;
                }
#endif
                float *a = out + ((size_t)(2 * y) * n2 + 2 * x) * ostride, *d = out + ((size_t)(2 * y + 1) * n2 + 2 * x) * ostride;
                memcpy(a, q[0], 12); memcpy(a + ostride, q[1], 12); memcpy(d, q[2], 12); memcpy(d + ostride, q[3], 12);
            }
    }
}

static double seg_dist(wrt_v3 p, wrt_v3 a, wrt_v3 b) {
    wrt_v3 ab = v3_sub(b, a);
    double l2 = v3_dot(ab, ab), t = l2 > 0 ? v3_dot(v3_sub(p, a), ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return v3_len(v3_sub(p, v3_mad(a, ab, t)));
}

/* Distance from p to the (planar convex) quad. */
double relight_quad_dist(const quad_info *q, wrt_v3 p) {
    double h = v3_dot(v3_sub(p, q->p[0]), q->n);
    wrt_v3 f = v3_mad(p, q->n, -h); /* foot in the plane */
    int inside = 1;
    for (int k = 0; k < 4; k++) {
        wrt_v3 e = v3_sub(q->p[(k + 1) & 3], q->p[k]);
        if (v3_dot(v3_cross(e, v3_sub(f, q->p[k])), q->n) < 0) inside = 0;
    }
    if (inside) return fabs(h);
    double d = INFINITY;
    for (int k = 0; k < 4; k++) {
        double s = seg_dist(p, q->p[k], q->p[(k + 1) & 3]);
        if (s < d) d = s;
    }
    return d;
}

light_c relight_light_consts(const wrt_light *l) {
    light_c c;
    c.pos = l->pos;
    c.dir = l->dir;
    c.intensity = l->intensity;
    c.sun = l->type == WRT_LIGHT_DIRECTIONAL;
    c.range = c.sun ? 0 : l->range;
    c.spot = l->type == WRT_LIGHT_SPOT;
    c.cos_outer = cos(l->outer_cone);
    double den = cos(l->inner_cone) - c.cos_outer;
    c.inv_den = 1.0 / (den > 1e-3 ? den : 1e-3);
    return c;
}

void relight_log(const wrt_relight *r, int level, const char *fmt, ...) {
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (r->opt.log) r->opt.log(r->opt.log_user, level, buf);
    else wrt_log(level, "%s", buf);
}
