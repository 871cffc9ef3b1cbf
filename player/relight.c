/* relight.c: the player's run-time core (Kontkanen et al. 2006, section 5): projects
 * point and spot lights onto the 4D Haar basis of common/basis.h (5.1), multiplies by
 * the baked indirect operator touching only non-zero sources (5.2), applies each
 * quad's BRDF (5.3) and synthesizes one texture of outgoing indirect radiance per quad
 * (5.4). Depends on formats/gto.h (the mapped operator), common/basis.h, common/brdf.h
 * and Embree 3 (shadow rays of the projection); pthreads for the parallel loops.
 *
 * Projection: an adaptive quadtree per quad and light. Every cell of the 8 x 8 grid
 * (PROJ_MIN_LEVEL; coarser if the quad holds no finer functions) is either split
 * unseen, while it is wider than 1/8 of its distance to the light (1/11.3 on quads with
 * angular functions), so that 1/d^2 and the cosine change by at most ~1/8 across a
 * cell, or sampled (4 samples at fixed rotated-grid positions, one shadow ray each). A
 * sampled cell is split again when its samples see a shadow edge (some lit, some
 * occluded), or on a glossy quad the light in different cells of the finest angular
 * level, or when its neighbour sees the opposite (the edge runs between them); down to
 * the cap, min(slevel + 1, 6), which resolves every function the file holds on the quad.
 * A cell that is not split is a leaf: the projected function is constant over it, so
 * its finer wavelets are exactly zero, cost no rays and are not stored (E stays sparse
 * for the multiply). Every decision depends on the geometry and the light's position
 * and shape only, never on its intensity, colour or other lights, so each light's E is
 * linear in that light. A positive options.proj_level samples every cell of that level
 * instead (edges still split down to the cap); options.proj_reference samples every cell
 * of the cap (the tests' truth). Shadow rays are traced only where a quad may shade the
 * cell: bounding cones from the light, then a separation test against the pyramid from
 * the light to the quad (and to each coarse cell); quads wholly outside a spot's cone or
 * beyond its range are skipped. The same exact zeros and values as tracing every ray.
 *
 * Departures from the paper, by design: direct light on a glossy quad is projected onto
 * the angular functions too (the light direction, spread over one cell of the finest
 * angular level centred on it, evaluated in the angular Haar basis), so it bounces
 * glossily; a quad's texture has 2^(slevel+1) texels a side (capped), so the finest
 * stored wavelet is represented exactly as a texel average; glossy pruning
 * (Figure 5) is done per angular function: one whose BRDF weight beta is below 1e-3 of
 * the root's over every direction the quad sends toward the eye is skipped.
 *
 * The first glossy bounce (a file with the first-bounce operator K, g->nkcols > 0;
 * formats/GTO_FORMAT.md): on a quad with K columns the same projection also gives, per
 * light, c over K's columns, the quad's outgoing functions: g(w_l) replaced by the BRDF
 * table's btilde_g(w_l) at the light's exact direction (RGB, no spread). Per update Y = K c
 * (K by rows, in groups of rows sharing a spatial node), E' = E with that quad's functions
 * set to 0, plus Y, and X = Op E' + Y: the direct light a glossy quad reflects reaches the
 * others with its exact lobe (at K's outgoing level), every later bounce through Op. A
 * file without K takes the path above unchanged, to the bit. */
#include "relight.h"

#include <embree3/rtcore.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define WRT_K_AVX 1 /* Y = K c's rows in fours with AVX where the processor has it */
#endif
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sched.h>
#include <stdarg.h>
#include <stdio.h>
#include <unistd.h>

#include "../common/basis.h"
#include "../common/brdf.h"
#include "../common/brdf_table.h"
#include "../common/threads.h"
#include "../common/rt_scene.h"
#include "../common/reconstruct.h"
#include "gather.h"

#define PROJ_MAX_LEVEL 6     /* finest projection grid: 64 x 64 cells per quad */
#define PROJ_CELL_K 8.0      /* cells at most d / PROJ_CELL_K wide */
#define PROJ_CELL_K_GLOSSY 11.3 /* on quads with angular functions (measured: error below 1.2x)*/
#define PROJ_MIN_LEVEL 3     /* every quad is sampled on at least 8 x 8 cells (if it has them) */
#define ANG_LEVELS 4         /* angular node levels 0..3 (basis.h: 2 bits of level) */
#define NANG 256             /* angular functions over node levels 0..3: 4^ANG_LEVELS */
#define BETA_RES WRT_BRDF_TABLE_RES /* beta table: common/brdf_table.h, shared with the bake */
#define FN_INVALID 255       /* fn_slevel of a key that is not a basis function */
#define PRUNE_REL 1e-3       /* glossy synthesis: skip |beta_g| < PRUNE_REL beta_root */

/* Index of a 2D Haar function in a quadtree pyramid: 0 the root scaling function, then
 * level by level, node by node (row-major), the three wavelets. Levels < L use 4^L slots. */
static inline uint32_t haar_index(int level, int x, int y, int type) {
    if (type == 0) return 0;
    uint32_t before = ((1u << (2 * level)) - 1) / 3;
    return 1 + 3 * (before + (uint32_t)y * (1u << level) + (uint32_t)x) + (uint32_t)(type - 1);
}

int wrt_relight_angular_index(int level, int x, int y, int type) {
    if (level < 0 || level >= ANG_LEVELS || x < 0 || y < 0 || x >= (1 << level) || y >= (1 << level) || type < 0 || type > 3)
        return -1;
    if (type == 0 && level != 0) return -1;
    return (int)haar_index(level, x, y, type);
}

/* Haar analysis in place: `v` holds 4^L scaling coefficients of level L (row-major,
 * nc channels interleaved); on return pyr[haar_index * nc + c] holds the root scaling
 * and every wavelet of levels < L. `v` is used as scratch. */
static void haar_analyse(double *v, int L, int nc, double *pyr) {
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
static void haar_synthesize4f(const float *pyr, int L, float *v, float *out, int ostride) {
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

typedef struct quad_info {
    wrt_v3 p[4], n, t, b;
    double area, diam, mean_factor; /* mean_factor: mean irradiance per root coefficient */
    wrt_v3 centre; double radius;   /* bounding sphere */
    int parallelogram, slevel, material, glossy;
    int alevel;                     /* deepest angular node level among its functions */
    int synth_full;                 /* its angular-root functions fill the texture's pyramid */
    int tex_level;                  /* texture is 2^tex_level a side */
    size_t tex_off;                 /* offset of its texels (x3 floats) */
    int stex_level;                 /* smooth texture (reconstruct.h): 2^stex_level a side */
    size_t stex_off;                /* offset of its smooth texels (x3 floats) */
    uint8_t *known;                 /* nodes below tex_level holding a function (reconstruct.h) */
    int root_func;                  /* index of (spatial root, angular root), -1 if absent */
    int nang;                       /* angular functions present */
    uint32_t ang_first;             /* into relight.ang_list / ang_start */
    uint32_t kfirst, kcount;        /* its columns of the first-bounce operator K (g->kkeys) */
    int kslevel;                    /* deepest spatial level among them (0: none) */
    int nkang;                      /* 1 + the largest angular index among them: the
                                     * projection's K slots, 3 (RGB) per angular index */
} quad_info;

/* A light's constants, hoisted out of the per-sample loop. */
typedef struct light_c {
    wrt_v3 pos, dir;
    double intensity, range, cos_outer, inv_den;
    int spot;
} light_c;

typedef struct light_state {
    wrt_light light;
    light_c lc;                     /* light_consts(&light), for the gather's direct light */
    float scale;
    int projected;                  /* E below is the projection of `light` */
    uint32_t *idx; float *val;      /* sparse E at scale 1: function index, RGB */
    size_t n, cap;
    float *kc;                      /* c over K's columns at scale 1, RGB (NULL without K) */
    double *root;                   /* nquads x 3: projected (root, root) coefficient */
    double last_work;               /* its last projection's work (samples and rays, in
                                     * parallel_for's units): an estimate of the next one's */
} light_state;

typedef struct worker {
    double *grid; size_t grid_cap;  /* projection grids / synthesis cells */
    double *pyr; size_t pyr_cap;
    float *acc; size_t acc_cap;     /* glossy texel accumulator */
    float *fpyr, *fgrid; size_t fpyr_cap, fgrid_cap; /* synthesis pyramid and scratch, x 4 */
    float *wts; int *cells; size_t view_cap; /* glossy per-texel bilinear lookups */
    uint32_t *oidx; float *oval; size_t on, ocap; /* projection output */
    uint32_t *pstate;               /* adaptive projection, per cell of levels 0..max: */
    uint8_t *prefined;              /* VIS bits and angular cell; split or not */
    uint8_t *pclear;                /* no occluder can shade the cell: no rays */
    uint32_t *occ; int nocc;        /* the quads that may shade the quad in progress */
    size_t nocc_cap;
    uint16_t *pcells;               /* cells sampled, level by level */
    double *pval; size_t pval_cap;  /* scaling coefficients of those cells, x slots */
    double *pwav; size_t pwav_cap;  /* wavelets of split cells, x 3 x slots */
    double brdf_time;
    long nsamples;                  /* samples and shadow rays of the projection */
} worker;

typedef struct out_rec { int worker; size_t start, count; } out_rec;

/* A quad's bounding sphere seen from a light: unit direction to its centre, the cosine
 * and sine of its angular radius (cos = -1: the light is inside), distance range. */
typedef struct light_cone { wrt_v3 u; double cosa, sina, dmin, dmax; } light_cone;

/* An entry of the first-bounce operator K by rows: column and value, read together. */
typedef struct kt_entry { uint32_t col; float val; } kt_entry;

/* The operator the multiply reads: the file's, or (with the final gather) a copy of the
 * entries whose receiver is displayed (r->op_own). */
typedef struct op_view {
    const uint64_t *col_start; /* nfuncs + 1 */
    const uint32_t *rows;
    const float *vals;         /* nnz x 3 */
    uint64_t nnz;
} op_view;

struct wrt_relight {
    int light_splat;                /* the light's direction spread over one finest angular cell */
    const wrt_gto *g;
    op_view op;
    void *op_own[3];                /* op's arrays when they are the relighter's copy */
    wrt_relight_options opt;
    int nthreads, max_tex_level;
    int8_t *qlevel;                 /* projection level per quad for the light in progress */
    light_cone *cones;              /* per quad, as seen from the light in progress */
    quad_info *qi;
    wrt_material *mats;
    float **beta;                   /* per material: [BETA_RES^2][NANG][3], NULL if unused */
    /* per function */
    uint8_t *fn_slevel, *fn_ang;
    uint32_t *fn_spidx;
    uint32_t *ang_perm;             /* functions of each quad grouped by angular index */
    uint16_t *ang_list;             /* present angular indices per quad (qi.ang_first) */
    uint32_t *ang_start;            /* for each (quad, present angular): range in ang_perm, +1 */
    uint8_t *ang_full;              /* for each (quad, present angular): fills the pyramid */
    /* Embree */
    RTCDevice dev; RTCScene scene;
    wrt_v3 origin; double eps, scene_diag;
    double size;                    /* per light: bounds the distances in the culling tests */
    /* state */
    light_state *lights; int nlights, lights_cap;
    int e_dirty, eye_dirty, have_eye;
    double eye[3];
    float *E, *X, *Xprev;
    float *X4;                      /* X being summed: 4 floats a function (RGB, unused) */
    uint32_t *cols;                 /* non-zero columns of E */
    float *tex; uint8_t *tex_nonzero, *x_nonzero, *resynth;
    float *texk;                    /* per texel of non-parallelograms: 2^Lt sqrt(pi/J)/pi */
    out_rec *recs;
    worker *workers;
    int *synth_list;                /* nquads + 1: quads to synthesize this update */
    int oom;                        /* an allocation failed */
    atomic_int upd_oom;             /* an allocation of the update's scratch failed */
    int redo_all;                   /* an update failed part way: the next one redoes every quad */
    _Atomic unsigned char *wbusy;   /* job hook: worker slots in use (nthreads) */
    wrt_pool *pool;                 /* nthreads threads, parked between loops (NULL with a hook) */
    wrt_recon *recon;               /* smooth display: NULL with options.haar_blocks */
    float *stex;                    /* the smooth textures */
    uint8_t *regroup;               /* per group: reconstruct at this update */
    const float **rin;              /* per quad, for wrt_recon_run (groups are disjoint) */
    const uint8_t **rknown;
    float **rout;
    wrt_gather *gather;             /* final gather on glossy quads (gather.h); NULL: none */
    const float **gtex; float **gout; int *gres; /* per quad: displayed texture, side */
    int *gires;                     /* per quad: side of gtex (a glossy quad's: gdiff) */
    float **gdiff;                  /* per glossy quad: albedo/pi x indirect irradiance */
    float (*galb)[3];               /* per material: mean directional albedo (glossy) */
    int glin_dirty;                 /* the gather's incident light waits for an update */
    /* The first-bounce operator K (g->nkcols > 0; docs in wrt_relight_update's K path). */
    uint8_t *kfn_slevel, *kfn_ang;  /* per K column: spatial level, angular index */
    uint32_t *kfn_spidx;            /* per K column: spatial pyramid slot */
    float *C;                       /* c summed over the lights: nkcols x 4 (RGB, unused) */
    uint32_t *kt_start;             /* K by rows (its transpose, columns ascending in a row): */
    kt_entry *kt;                   /* row f is entries [kt_start[f], kt_start[f + 1]), except */
    uint32_t nk4, *k4_row, *k4_start; /* rows in fours (below): the k4_n[i] rows from */
    uint8_t *k4_n;                  /* k4_row[i] are entries [k4_start[i], k4_start[i + 1]) of */
    uint32_t *k4_cols; float *k4_vals; /* k4_cols, with 4 values each in k4_vals (0 where a
                                    * row has none, and for rows past k4_n[i]) */
    float *Y;                       /* Y = K c: nfuncs x 3 */
    float *Y4;                      /* Y being summed: 4 floats a function (RGB, unused) */
    int k_avx;                      /* the processor has AVX (Y's rows in fours with it) */
    float *Ep;                      /* E' = E off the quads with K columns, + Y: nfuncs x 3 */
};

/* ---------------------------------------------------------------- threads ---- */

typedef void (*job_fn)(wrt_relight *r, worker *w, int item, void *ctx);
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

/* Runs fn over items 0..n-1 on up to nthreads threads (one if `work` is small; with a job
 * hook, every loop of 2 items or more goes to the hook); returns the number of threads
 * used. Results must not depend on which worker ran an item (callers write per item, or
 * merge per item in item order). */
static int parallel_for(wrt_relight *r, int n, double work, job_fn fn, void *ctx) {
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
static void *ra_calloc(wrt_relight *r, size_t count, size_t size) {
    if (size && count > SIZE_MAX / size) { r->oom = 1; return NULL; }
    size_t n = count * size;
    if (!n) n = 1;
    void *p = r->opt.alloc ? r->opt.alloc(n, r->opt.alloc_user) : malloc(n);
    if (!p) { r->oom = 1; return NULL; }
    return memset(p, 0, n);
}
static void ra_free(const wrt_relight *r, void *p) {
    if (!p) return;
    if (r->opt.alloc && r->opt.free) r->opt.free(p, r->opt.alloc_user);
    else free(p);
}

/* Scratch of at least `need` elements: p itself if it holds them, else a larger block
 * from the caller's allocator (the first `keep` elements copied, p freed, *cap updated).
 * NULL if there is no memory: p and *cap are left as they were and r->upd_oom is set (the
 * update then fails with WRT_ERR_NOMEM). Called from worker threads. */
static void *grow_keep(wrt_relight *r, void *p, size_t *cap, size_t need, size_t elem, size_t keep) {
    if (need <= *cap) return p;
    size_t c = *cap ? *cap : 64;
    while (c < need) c *= 2;
    void *np = c > SIZE_MAX / elem ? NULL : r->opt.alloc ? r->opt.alloc(c * elem, r->opt.alloc_user) : malloc(c * elem);
    if (!np) { atomic_store(&r->upd_oom, 1); return NULL; }
    if (keep && p) memcpy(np, p, keep * elem);
    ra_free(r, p);
    *cap = c;
    return np;
}
static void *grow(wrt_relight *r, void *p, size_t *cap, size_t need, size_t elem) {
    return grow_keep(r, p, cap, need, elem, 0);
}
#define GROW(r, ptr, cap, need) /* grows w->ptr, or returns (void) from the caller */ \
    do { void *np_ = grow(r, ptr, &(cap), need, sizeof *(ptr)); if (!np_) return; ptr = np_; } while (0)

/* -------------------------------------------------------------- geometry ---- */

static wrt_v3 quad_point(const quad_info *q, double u, double v) {
    double w0 = (1 - u) * (1 - v), w1 = u * (1 - v), w2 = u * v, w3 = (1 - u) * v;
    return v3(w0 * q->p[0].x + w1 * q->p[1].x + w2 * q->p[2].x + w3 * q->p[3].x,
              w0 * q->p[0].y + w1 * q->p[1].y + w2 * q->p[2].y + w3 * q->p[3].y,
              w0 * q->p[0].z + w1 * q->p[1].z + w2 * q->p[2].z + w3 * q->p[3].z);
}

static double quad_jacobian(const quad_info *q, double u, double v) {
    if (q->parallelogram) return q->area;
    wrt_v3 du = v3_add(v3_scale(v3_sub(q->p[1], q->p[0]), 1 - v), v3_scale(v3_sub(q->p[2], q->p[3]), v));
    wrt_v3 dv = v3_add(v3_scale(v3_sub(q->p[3], q->p[0]), 1 - u), v3_scale(v3_sub(q->p[2], q->p[1]), u));
    return v3_len(v3_cross(du, dv));
}

static double seg_dist(wrt_v3 p, wrt_v3 a, wrt_v3 b) {
    wrt_v3 ab = v3_sub(b, a);
    double l2 = v3_dot(ab, ab), t = l2 > 0 ? v3_dot(v3_sub(p, a), ab) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return v3_len(v3_sub(p, v3_mad(a, ab, t)));
}

/* Distance from p to the (planar convex) quad. */
static double quad_dist(const quad_info *q, wrt_v3 p) {
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

/* ----------------------------------------------------------- projection ---- */

/* Fixed rotated-grid sample positions within a cell (4 samples). */
static const double cell_samples[4][2] = {{0.375, 0.125}, {0.875, 0.375}, {0.625, 0.875}, {0.125, 0.625}};

/* Cells of levels 0..l-1 of a quadtree: the offset of level l in per-level arrays. */
#define LEVEL_OFF(l) ((((size_t)1 << (2 * (l))) - 1) / 3)
#define PROJ_TREE_CELLS LEVEL_OFF(PROJ_MAX_LEVEL + 1)

/* The deepest spatial level the projection resolves: the quad's functions' and its K
 * columns' (kslevel is 0 without K). */
static int projection_cap(const wrt_relight *r, const quad_info *q) {
    int cap = (q->slevel > q->kslevel ? q->slevel : q->kslevel) + 1;
    if (cap > PROJ_MAX_LEVEL) cap = PROJ_MAX_LEVEL;
    if (r->opt.proj_level > 0 && r->opt.proj_level < cap) cap = r->opt.proj_level;
    return cap;
}

static int projection_level(const wrt_relight *r, const quad_info *q, double d) {
    int cap = (q->slevel > q->kslevel ? q->slevel : q->kslevel) + 1;
    if (cap > PROJ_MAX_LEVEL) cap = PROJ_MAX_LEVEL;
    int L;
    if (r->opt.proj_level > 0) L = r->opt.proj_level;
    else {
        double ratio = PROJ_CELL_K * q->diam / (d > 1e-300 ? d : 1e-300);
        L = ratio <= 1 ? 0 : (int)ceil(log2(ratio));
        int lo = cap < 2 ? cap : 2;
        if (L < lo) L = lo;
    }
    return L > cap ? cap : L;
}

static light_c light_consts(const wrt_light *l) {
    light_c c;
    c.pos = l->pos;
    c.dir = l->dir;
    c.intensity = l->intensity;
    c.range = l->range;
    c.spot = l->type == WRT_LIGHT_SPOT;
    c.cos_outer = cos(l->outer_cone);
    double den = cos(l->inner_cone) - c.cos_outer;
    c.inv_den = 1.0 / (den > 1e-3 ? den : 1e-3);
    return c;
}

/* 1 if nothing blocks the shadow ray from just above x (unit normal n) along the unit
 * direction dir toward a light at distance d; Embree sets tfar to -inf on a hit. */
static int light_visible(const wrt_relight *r, wrt_v3 x, wrt_v3 n, wrt_v3 dir, double d) {
    wrt_v3 o = v3_sub(v3_mad(x, n, r->eps), r->origin);
    struct RTCRay ray;
    ray.org_x = (float)o.x; ray.org_y = (float)o.y; ray.org_z = (float)o.z;
    ray.dir_x = (float)dir.x; ray.dir_y = (float)dir.y; ray.dir_z = (float)dir.z;
    ray.tnear = 0;
    ray.tfar = (float)(d - 2 * r->eps);
    ray.time = 0; ray.mask = 0xFFFFFFFFu; ray.id = 0; ray.flags = 0;
    if (!(ray.tfar > 0)) return 1;
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    rtcOccluded1(r->scene, &ic, &ray);
    return !(ray.tfar < 0);
}

/* Direct irradiance (without colour) from light l at x with unit normal n, and the
 * unit direction toward the light; 0 if none arrives (visibility excluded). */
static double light_irradiance(const light_c *l, wrt_v3 x, wrt_v3 n, wrt_v3 *w, double *dist) {
    wrt_v3 dl = v3_sub(l->pos, x);
    double d2 = v3_dot(dl, dl);
    if (!(d2 > 0)) return 0;
    double cosx = v3_dot(dl, n);
    if (cosx <= 0) return 0;
    double d = sqrt(d2), inv_d = 1.0 / d;
    *w = v3_scale(dl, inv_d);
    *dist = d;
    double e = l->intensity * cosx * inv_d / d2;
    if (l->spot) {
        double cd = -v3_dot(*w, l->dir); /* angle between the axis and light -> x */
        double s = (cd - l->cos_outer) * l->inv_den;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
        e *= s * s;
    }
    if (l->range > 0) {
        double t = d / l->range, t4 = t * t * t * t;
        double win = 1 - t4;
        win = win < 0 ? 0 : win;
        e *= win * win;
    }
    return e;
}

#define VIS_LIT 1
#define VIS_SHADOWED 2
#define VIS_EVAL 4      /* cell state: evaluated at this level */
#define VIS_ANGMIX 8    /* cell state: its lit samples see the light in different angular cells */
#define VIS_ANG_SHIFT 8 /* cell state: 1 + the angular cell of its lit samples, above this bit */

/* What every cell of one quad's projection shares. */
typedef struct proj_setup {
    const quad_info *q;
    const light_c *lc;
    int nslot, nsamp, grid_n, rays; /* grid_n > 0: n x n samples a cell, else cell_samples */
    int ang_res;                    /* angular cells a side (0: diffuse quad) */
    const int16_t *slot_of;
    int nkang;                      /* K's angular indices 0..nkang-1 on the quad: 3 slots */
                                    /* each, after the E slots (nslot - 3 nkang of them) */
    const float *beta;              /* the quad's material's BRDF table (with K) */
} proj_setup;

/* K's slots of one sample (K-SPEC, "The maths"): the sample's weight `val` (E_dir V
 * sqrt(J/pi) x its share of the cell) times btilde_g(w_l), the BRDF table's beta_g at the
 * light's exact direction (concentric (a, b) in the quad's frame; bilinear between the
 * table's directions, as wrt_relight_beta), for each angular index g < nkang: acc[3 g + c]
 * (single precision, as the table; a cell's few samples). No light-direction splat: the
 * first bounce of the delta is exact. (Merging the taps of a cell's samples per table
 * direction first was measured slower: they seldom share one.) */
static void k_sample(const proj_setup *ps, double a, double b, double val, float *acc) {
    double fx = a * BETA_RES - 0.5, fy = b * BETA_RES - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    float wt[4];
    const float *row[4];
    for (int k = 0; k < 4; k++) {
        int cx = x0 + (k & 1), cy = y0 + (k >> 1);
        cx = cx < 0 ? 0 : cx >= BETA_RES ? BETA_RES - 1 : cx;
        cy = cy < 0 ? 0 : cy >= BETA_RES ? BETA_RES - 1 : cy;
        wt[k] = (float)(val * ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty));
        row[k] = ps->beta + (size_t)(cy * BETA_RES + cx) * NANG * 3;
    }
    int n = 3 * ps->nkang, i = 0;
#ifdef __SSE2__
    __m128 w0 = _mm_set1_ps(wt[0]), w1 = _mm_set1_ps(wt[1]), w2 = _mm_set1_ps(wt[2]), w3 = _mm_set1_ps(wt[3]);
    for (; i + 4 <= n; i += 4) {
        __m128 s01 = _mm_add_ps(_mm_mul_ps(w0, _mm_loadu_ps(row[0] + i)), _mm_mul_ps(w1, _mm_loadu_ps(row[1] + i)));
        __m128 s23 = _mm_add_ps(_mm_mul_ps(w2, _mm_loadu_ps(row[2] + i)), _mm_mul_ps(w3, _mm_loadu_ps(row[3] + i)));
        _mm_storeu_ps(acc + i, _mm_add_ps(_mm_loadu_ps(acc + i), _mm_add_ps(s01, s23)));
    }
#endif
    for (; i < n; i++) acc[i] += (wt[0] * row[0][i] + wt[1] * row[1][i]) + (wt[2] * row[2][i] + wt[3] * row[3][i]);
}

/* Cell (i, j) of level l: out[slot] = the level-l scaling coefficient (cell average x
 * 2^-l) of E_dir V g sqrt(J/pi) for each angular slot, from the cell's samples.
 * Returns VIS_LIT if a sample is lit, | VIS_SHADOWED if a sample facing the light is
 * occluded. */
static uint32_t eval_cell(const wrt_relight *r, worker *w, const proj_setup *ps, int l, int i, int j, int rays, double *out) {
    w->nsamples += ps->nsamp * (1 + rays);
    const quad_info *q = ps->q;
    int nslot = ps->nslot, angular = nslot - 3 * ps->nkang > 1, root_slot = ps->slot_of[0];
    for (int s = 0; s < nslot; s++) out[s] = 0;
    double cellw = ldexp(1.0, -l), wgt = cellw / ps->nsamp, inv_pi = 1.0 / WRT_PI;
    double sj = q->parallelogram ? sqrt(q->area * inv_pi) : 0;
    uint32_t vis = 0, ang_cell = 0;
    float kacc[3 * NANG]; /* K's slots, summed in single precision over the cell's samples */
    if (ps->nkang) memset(kacc, 0, 3 * (size_t)ps->nkang * sizeof(float));
    for (int k = 0; k < ps->nsamp; k++) {
        double ou = ps->grid_n ? (k % ps->grid_n + 0.5) / ps->grid_n : cell_samples[k][0];
        double ov = ps->grid_n ? (k / ps->grid_n + 0.5) / ps->grid_n : cell_samples[k][1];
        double u = (i + ou) * cellw, v = (j + ov) * cellw;
        wrt_v3 x = quad_point(q, u, v), dir;
        double d = 0;
        double e = light_irradiance(ps->lc, x, q->n, &dir, &d);
        if (e == 0) continue;
        if (rays && !light_visible(r, x, q->n, dir, d)) { vis |= VIS_SHADOWED; continue; }
        double val = e * (q->parallelogram ? sj : sqrt(quad_jacobian(q, u, v) * inv_pi)) * wgt;
        vis |= VIS_LIT;
        if (root_slot >= 0) out[root_slot] += val;
        if (!angular && !ps->nkang) continue;
        double loc[3] = {v3_dot(dir, q->t), v3_dot(dir, q->b), v3_dot(dir, q->n)}, a, b;
        wrt_concentric_inv(loc, &a, &b);
        if (ps->nkang) k_sample(ps, a, b, val, kacc);
        if (!angular) continue;
        if (ps->ang_res) { /* where the wavelets of the finest angular level change sign */
            int ar = ps->ang_res, ax = (int)(a * ar), ay = (int)(b * ar);
            uint32_t id = 1 + (uint32_t)((ay < ar ? ay : ar - 1) * ar + (ax < ar ? ax : ar - 1));
            if (ang_cell && id != ang_cell) vis |= VIS_ANGMIX;
            ang_cell = id;
        }
        /* The light's direction, a delta, spread over one cell of the finest angular level
         * centred on it (light_splat): its Haar coefficients are then the bilinear blend of
         * the functions' values at the four nearest finest-cell centres, so the reflected
         * lobe is centred on the light's direction instead of on its cell's centre. */
        int nc = 1, ar = ps->ang_res;
        double ca[4] = {a}, cb[4] = {b}, cw[4] = {1};
        if (r->light_splat && ar > 0) {
            double fa = a * ar - 0.5, fb = b * ar - 0.5;
            int ia = (int)floor(fa), ib = (int)floor(fb);
            double ta = fa - ia, tb = fb - ib;
            nc = 4;
            for (int c = 0; c < 4; c++) {
                int xa = ia + (c & 1), xb = ib + (c >> 1);
                xa = xa < 0 ? 0 : xa > ar - 1 ? ar - 1 : xa;
                xb = xb < 0 ? 0 : xb > ar - 1 ? ar - 1 : xb;
                ca[c] = (xa + 0.5) / ar; cb[c] = (xb + 0.5) / ar;
                cw[c] = ((c & 1) ? ta : 1 - ta) * ((c >> 1) ? tb : 1 - tb);
            }
        }
        for (int c = 0; c < nc; c++) {
            if (cw[c] == 0) continue;
            double vc = val * cw[c];
            for (int al = 0; al < ANG_LEVELS; al++) {
                int an = 1 << al;
                int ax = (int)(ca[c] * an), ay = (int)(cb[c] * an);
                if (ax > an - 1) ax = an - 1;
                if (ay > an - 1) ay = an - 1;
                double su = ca[c] * an - ax < 0.5 ? 1.0 : -1.0, sv = cb[c] * an - ay < 0.5 ? 1.0 : -1.0;
                uint32_t kk = haar_index(al, ax, ay, 1);
                double gv[3] = {an * su, an * sv, an * su * sv};
                for (int t = 0; t < 3; t++) {
                    int sl = ps->slot_of[kk + t];
                    if (sl >= 0) out[sl] += vc * gv[t];
                }
            }
        }
    }
    for (int s = 0; s < 3 * ps->nkang; s++) out[nslot - 3 * ps->nkang + s] = kacc[s];
    return vis | (vis & VIS_ANGMIX ? 0 : ang_cell << VIS_ANG_SHIFT);
}

/* Visibility class (VIS bits) of cell (x, y) of level l: its own if it was evaluated
 * at l, else that of the evaluated ancestor (a leaf of the quadtree) that covers it. */
static uint32_t state_at(const worker *w, int Ld, int l, int x, int y) {
    for (int k = l; k >= Ld; k--) {
        uint32_t s = w->pstate[LEVEL_OFF(k) + ((size_t)(y >> (l - k)) << k) + (size_t)(x >> (l - k))];
        if (s & VIS_EVAL) return s;
    }
    return 0;
}

/* A cell is split when its samples see a shadow edge (some lit, some occluded) or, on
 * a glossy quad, the light in different angular cells; or when it is all lit and a
 * neighbour all occluded (or the reverse), or both see the light in different angular
 * cells: the edge then runs between their samples. */
static int needs_refine(const worker *w, int Ld, int l, int x, int y) {
    int n = 1 << l;
    uint32_t s = w->pstate[LEVEL_OFF(l) + (size_t)y * n + x];
    int v = (int)(s & 3);
    if (v == (VIS_LIT | VIS_SHADOWED) || (s & VIS_ANGMIX)) return 1;
    if (v == 0) return 0;
    int opp = v ^ (VIS_LIT | VIS_SHADOWED);
    static const int nb[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
    for (int k = 0; k < 4; k++) {
        int nx = x + nb[k][0], ny = y + nb[k][1];
        if (nx < 0 || ny < 0 || nx >= n || ny >= n) continue;
        uint32_t ns = state_at(w, Ld, l, nx, ny);
        if ((int)(ns & 3) == opp) return 1;
        if (v == VIS_LIT && (ns & 3) == VIS_LIT && !(ns & VIS_ANGMIX) && (ns >> VIS_ANG_SHIFT) != (s >> VIS_ANG_SHIFT))
            return 1;
    }
    return 0;
}

/* The level rule, cell by cell: a cell is split while it is wider than 1/PROJ_CELL_K of
 * its distance to the light, so that 1/d^2 and the cosine change by at most ~1/8
 * across it. Geometry and the light's position only. */
static int too_close(const proj_setup *ps, int l, int i, int j) {
    const quad_info *q = ps->q;
    double h = ldexp(1.0, -l), u0 = i * h, v0 = j * h;
    wrt_v3 c00 = quad_point(q, u0, v0), c11 = quad_point(q, u0 + h, v0 + h);
    wrt_v3 c10 = quad_point(q, u0 + h, v0), c01 = quad_point(q, u0, v0 + h);
    double diam = fmax(v3_len(v3_sub(c11, c00)), v3_len(v3_sub(c10, c01)));
    wrt_v3 mid = quad_point(q, u0 + 0.5 * h, v0 + 0.5 * h);
    double d = v3_len(v3_sub(mid, ps->lc->pos)) - 0.5 * diam;
    return (q->nang > 1 ? PROJ_CELL_K_GLOSSY : PROJ_CELL_K) * diam > d;
}

/* Occluder culling: a shadow ray from a point of quad A (or of one of its cells) to the
 * light can only hit a quad B that meets the pyramid spanned by the light and A. These
 * tests are conservative (a B they keep may still miss), exact up to a 1e-9 relative
 * tolerance on points on a plane, and depend on the geometry and the light's position
 * only. */
static int all_below(const wrt_v3 *pts, int n, wrt_v3 o, wrt_v3 nrm, double size) {
    double tol = 1e-9 * size * sqrt(v3_dot(nrm, nrm)); /* size: bounds |pts[k] - o| */
    for (int k = 0; k < n; k++)
        if (v3_dot(v3_sub(pts[k], o), nrm) > tol) return 0;
    return 1;
}

/* 1 if quad b cannot meet the pyramid of light l and the convex planar polygon c[0..3]
 * (normal n, light on its front). */
static int pyramid_clear(const wrt_v3 c[4], wrt_v3 n, wrt_v3 l, const quad_info *b, double size) {
    /* b on or behind the polygon's plane, or beyond the light's parallel plane */
    if (all_below(b->p, 4, c[0], n, size) || all_below(b->p, 4, l, v3_scale(n, -1), size)) return 1;
    /* the pyramid's sides: inward normals (e_k - l) x (e_k+1 - l) for a ccw polygon */
    wrt_v3 mid = v3_sub(v3_scale(v3_add(v3_add(c[0], c[1]), v3_add(c[2], c[3])), 0.25), l);
    for (int k = 0; k < 4; k++) {
        wrt_v3 sn = v3_cross(v3_sub(c[(k + 1) & 3], l), v3_sub(c[k], l));
        if (v3_dot(sn, mid) < 0) sn = v3_scale(sn, -1); /* inward whatever the winding */
        if (all_below(b->p, 4, l, sn, size)) return 1;
    }
    /* b's plane leaves the light and the polygon on one side */
    wrt_v3 pts[5] = {c[0], c[1], c[2], c[3], l};
    if (all_below(pts, 5, b->p[0], b->n, size) || all_below(pts, 5, b->p[0], v3_scale(b->n, -1), size)) return 1;
    return 0;
}

/* Cell (i, j) of level l of quad q: 1 if none of the quad's possible occluders can
 * shade it. */
static int cell_clear(const wrt_relight *r, const worker *w, const quad_info *q, wrt_v3 l, int lv, int i, int j) {
    double h = ldexp(1.0, -lv), u0 = i * h, v0 = j * h;
    wrt_v3 c[4] = {quad_point(q, u0, v0), quad_point(q, u0 + h, v0), quad_point(q, u0 + h, v0 + h), quad_point(q, u0, v0 + h)};
    for (int k = 0; k < w->nocc; k++)
        if (!pyramid_clear(c, q->n, l, &r->qi[w->occ[k]], r->size)) return 0;
    return 1;
}

/* The quads that may shade some point of quad a (into w->occ): bounding cones from the
 * light first, then the pyramid tests. -1 if there is no memory for the list. */
static int find_occluders(wrt_relight *r, worker *w, int a, wrt_v3 l) {
    uint32_t nq = r->g->nquads;
    w->nocc = 0;
    uint32_t *occ = grow(r, w->occ, &w->nocc_cap, nq + 1, sizeof(uint32_t));
    if (!occ) return -1;
    w->occ = occ;
    const light_cone *ca = &r->cones[a];
    const quad_info *qa = &r->qi[a];
    for (uint32_t b = 0; b < nq; b++) {
        if ((int)b == a) continue;
        const light_cone *cb = &r->cones[b];
        if (cb->dmin >= ca->dmax) continue; /* entirely farther than a */
        /* radii in [0, pi/2]: their sum in [0, pi], where cos decreases */
        if (ca->cosa > -1 && cb->cosa > -1 && v3_dot(ca->u, cb->u) < ca->cosa * cb->cosa - ca->sina * cb->sina) continue;
        if (pyramid_clear(qa->p, qa->n, l, &r->qi[b], r->size)) continue;
        w->occ[w->nocc++] = b;
    }
    return 0;
}

typedef struct proj_ctx { const wrt_light *light; const light_c *lc; double *root; float *kc; } proj_ctx;

/* The coefficients c of quad q's K columns from the projection's pyramid (w->pyr: levels
 * above the rule's grid Ld; w->pwav: wavelets of split cells; K's slots from `ebase`, 3
 * a function), as E's are taken in project_quad, times the light's colour, into kc
 * (the light's c, indexed by column; the quad's range was zeroed). */
static void k_extract(const wrt_relight *r, const worker *w, const quad_info *q, const float *col, int ebase, int nslot,
                      int Ld, int last, float *kc) {
    for (uint32_t j = q->kfirst; j < q->kfirst + q->kcount; j++) {
        int sl = ebase + 3 * r->kfn_ang[j], lev = r->kfn_slevel[j];
        uint32_t sp = r->kfn_spidx[j];
        const double *cv;
        if (sp == 0 || lev < Ld) cv = w->pyr + (size_t)sp * nslot + sl;
        else if (lev < last) { /* a wavelet of a split cell, or zero */
            uint32_t k = sp - 1, cell = k / 3 - (uint32_t)LEVEL_OFF(lev);
            if (!w->prefined[LEVEL_OFF(lev) + cell]) continue;
            cv = w->pwav + ((LEVEL_OFF(lev) + cell) * 3 + k % 3) * nslot + sl;
        } else continue; /* finer than any split cell: zero */
        for (int c = 0; c < 3; c++) kc[(size_t)j * 3 + c] = (float)(cv[c] * col[c]);
    }
}

/* Projects light ctx->light onto quad qidx's functions (section 5.1), adaptively: every
 * cell of the level rule's grid (r->qlevel) is sampled; cells on a shadow edge are split,
 * level by level, down to the cap. A cell that is not split is a leaf: its function is
 * constant over it, so its finer wavelets are exactly zero and are not stored. The split
 * decisions depend on the light's position and the geometry only (never on intensity
 * or colour), so E stays linear in each light. */
static void project_quad(wrt_relight *r, worker *w, int qidx, void *vctx) {
    proj_ctx *ctx = vctx;
    const wrt_light *l = ctx->light;
    const quad_info *q = &r->qi[qidx];
    const wrt_gto_quad *gq = &r->g->quads[qidx];
    out_rec *rec = &r->recs[qidx];
    rec->worker = (int)(w - r->workers);
    rec->start = w->on;
    rec->count = 0;
    for (int c = 0; c < 3; c++) ctx->root[qidx * 3 + c] = 0;
    if (q->kcount) memset(ctx->kc + (size_t)q->kfirst * 3, 0, (size_t)q->kcount * 3 * sizeof(float));
    if (gq->func_count == 0 || l->intensity == 0) return;
    /* A light on or behind the quad's plane lights nothing (exactly zero). */
    if (v3_dot(v3_sub(l->pos, q->p[0]), q->n) <= 0) return;
    int Ld = r->qlevel[qidx];
    if (Ld < 0) return; /* beyond the light's range */
    if (l->type == WRT_LIGHT_SPOT && r->cones[qidx].cosa > -1) { /* wholly outside the spot's cone */
        const light_cone *cn = &r->cones[qidx];
        double co = ctx->lc->cos_outer, so = sqrt(fmax(0, 1 - co * co));
        if (l->outer_cone < WRT_PI / 2 && v3_dot(l->dir, cn->u) < co * cn->cosa - so * cn->sina) return;
    }
    int cap = projection_cap(r, q);
    /* Angular slots: the root, plus the quad's angular functions when it has any. */
    /* On a quad with K columns, E's angular functions are not projected: the multiply
     * reads E' (E off that quad, + Y), so only E's angular root is kept (the quad's
     * direct irradiance, wrt_relight_quad_irradiance), and no cell is split for the
     * light crossing an angular cell (c's btilde is smooth in the light's direction). */
    int eang = q->nang > 0 && !q->kcount;
    int nslot = eang ? q->nang : 1;
    const uint16_t *alist = r->ang_list + q->ang_first;
    int16_t slot_of[NANG];
    for (int a = 0; a < NANG; a++) slot_of[a] = -1;
    if (eang) for (int s = 0; s < q->nang; s++) slot_of[alist[s]] = (int16_t)s;
    else slot_of[0] = 0;
    int ebase = nslot; /* K's slots after E's: 3 (RGB) per angular function of its columns */
    nslot += 3 * q->nkang;
    proj_setup ps = {q, ctx->lc, nslot, 4, 0, 1, 0, slot_of, q->nkang, r->beta[q->material]};
    if (eang && q->nang > 1) ps.ang_res = 2 << q->alevel;
    int local_rule = r->opt.proj_level == 0;
    if (r->opt.proj_reference > 0) { /* every cell of the finest grid */
        Ld = cap;
        local_rule = 0;
        if (r->opt.proj_reference > 1) ps.grid_n = r->opt.proj_reference > 8 ? 8 : r->opt.proj_reference;
        ps.nsamp = ps.grid_n ? ps.grid_n * ps.grid_n : 4;
    }
    if (Ld > cap) Ld = cap;
    GROW(r, w->pval, w->pval_cap, LEVEL_OFF(cap + 1) * nslot);
    GROW(r, w->pwav, w->pwav_cap, LEVEL_OFF(cap) * 3 * nslot + 1);
    memset(w->pstate + LEVEL_OFF(Ld), 0, (LEVEL_OFF(cap + 1) - LEVEL_OFF(Ld)) * sizeof(uint32_t));
    memset(w->prefined + LEVEL_OFF(Ld), 0, LEVEL_OFF(cap + 1) - LEVEL_OFF(Ld));
    /* Quads that may shade this one; none: no rays at all. */
    if (r->opt.proj_reference == 0) {
        if (find_occluders(r, w, qidx, l->pos) != 0) return;
        if (w->nocc == 0) ps.rays = 0;
    }
    /* Top-down: sample the cells of level l, split those on an edge. */
    size_t lstart[PROJ_MAX_LEVEL + 2], nc = 0;
    for (size_t c = 0; c < ((size_t)1 << (2 * Ld)); c++) w->pcells[nc++] = (uint16_t)c;
    lstart[Ld] = 0;
    lstart[Ld + 1] = nc;
    int any = 0, last = Ld;
    for (int lv = Ld;; lv++) {
        int n = 1 << lv;
        size_t off = LEVEL_OFF(lv);
        size_t start = nc;
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            int c = w->pcells[k], x = c % n, y = c / n, n2 = 2 * n;
            /* clear of occluders: its parent is, or (near the top) the test says so */
            int clear = !ps.rays || (lv > Ld && w->pclear[LEVEL_OFF(lv - 1) + (size_t)(y / 2) * (n / 2) + x / 2]) ||
                        (lv <= PROJ_MIN_LEVEL + 1 && r->opt.proj_reference == 0 && cell_clear(r, w, q, l->pos, lv, x, y));
            w->pclear[off + c] = (uint8_t)clear;
            if (local_rule && lv < cap && too_close(&ps, lv, x, y)) { /* split unseen */
                w->prefined[off + c] = 1;
                w->pcells[nc++] = (uint16_t)((2 * y) * n2 + 2 * x);
                w->pcells[nc++] = (uint16_t)((2 * y) * n2 + 2 * x + 1);
                w->pcells[nc++] = (uint16_t)((2 * y + 1) * n2 + 2 * x);
                w->pcells[nc++] = (uint16_t)((2 * y + 1) * n2 + 2 * x + 1);
                continue;
            }
            uint32_t vis = eval_cell(r, w, &ps, lv, x, y, !clear, w->pval + (off + c) * nslot);
            w->pstate[off + c] = VIS_EVAL | vis;
            any |= (int)(vis & 3);
        }
        last = lv;
        if (lv == cap || r->opt.proj_reference > 0) break;
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            int c = w->pcells[k], x = c % n, y = c / n, n2 = 2 * n;
            if (!(w->pstate[off + c] & VIS_EVAL) || !needs_refine(w, Ld, lv, x, y)) continue;
            w->prefined[off + c] = 1;
            w->pcells[nc++] = (uint16_t)((2 * y) * n2 + 2 * x);
            w->pcells[nc++] = (uint16_t)((2 * y) * n2 + 2 * x + 1);
            w->pcells[nc++] = (uint16_t)((2 * y + 1) * n2 + 2 * x);
            w->pcells[nc++] = (uint16_t)((2 * y + 1) * n2 + 2 * x + 1);
        }
        if (nc == start) break;
        lstart[lv + 2] = nc;
    }
    if (!(any & VIS_LIT)) return;
    /* Bottom-up: a split cell's scaling coefficient and wavelets from its children. */
    for (int lv = last - 1; lv >= Ld; lv--) {
        int n = 1 << lv, n2 = 2 * n;
        size_t off = LEVEL_OFF(lv), off2 = LEVEL_OFF(lv + 1);
        for (size_t k = lstart[lv]; k < lstart[lv + 1]; k++) {
            int c = w->pcells[k], x = c % n, y = c / n;
            if (!w->prefined[off + c]) continue;
            const double *a = w->pval + (off2 + (size_t)(2 * y) * n2 + 2 * x) * nslot, *b = a + nslot;
            const double *d = w->pval + (off2 + (size_t)(2 * y + 1) * n2 + 2 * x) * nslot, *e = d + nslot;
            double *wv = w->pwav + (off + c) * 3 * nslot, *pv = w->pval + (off + c) * nslot;
            for (int s = 0; s < nslot; s++) {
                wv[s] = (a[s] - b[s] + d[s] - e[s]) * 0.5;             /* type 1: sign by cx */
                wv[nslot + s] = (a[s] + b[s] - d[s] - e[s]) * 0.5;     /* type 2: sign by cy */
                wv[2 * nslot + s] = (a[s] - b[s] - d[s] + e[s]) * 0.5; /* type 3 */
                pv[s] = (a[s] + b[s] + d[s] + e[s]) * 0.5;
            }
        }
    }
    /* Levels above the rule's grid: plain Haar analysis of that grid. */
    GROW(r, w->pyr, w->pyr_cap, ((size_t)1 << (2 * Ld)) * nslot);
    haar_analyse(w->pval + LEVEL_OFF(Ld) * nslot, Ld, nslot, w->pyr);
    const float *col = l->color;
    double I0 = slot_of[0] >= 0 ? w->pyr[slot_of[0]] : 0;
    for (int c = 0; c < 3; c++) ctx->root[qidx * 3 + c] = I0 * col[c];
    /* Keep the coefficients whose function exists on the quad. */
    size_t f0 = gq->func_first, fc = gq->func_count;
    for (size_t f = f0; f < f0 + fc; f++) {
        int sl = slot_of[r->fn_ang[f]];
        if (sl < 0) continue;
        uint32_t sp = r->fn_spidx[f];
        int lev = r->fn_slevel[f];
        double cv;
        if (sp == 0 || lev < Ld) cv = w->pyr[(size_t)sp * nslot + sl];
        else if (lev < last) { /* a wavelet of a split cell, or zero */
            uint32_t k = sp - 1, cell = k / 3 - (uint32_t)LEVEL_OFF(lev);
            if (!w->prefined[LEVEL_OFF(lev) + cell]) continue;
            cv = w->pwav[((LEVEL_OFF(lev) + cell) * 3 + k % 3) * nslot + sl];
        } else continue; /* finer than any split cell: zero */
        if (cv == 0) continue;
        if (w->on == w->ocap) { /* both grow to 2 x ocap, keeping what they hold */
            size_t ci = w->ocap, cvc = 3 * w->ocap;
            uint32_t *ni = grow_keep(r, w->oidx, &ci, w->ocap ? 2 * w->ocap : 1024, sizeof(uint32_t), w->on);
            if (!ni) return;
            w->oidx = ni;
            float *nv = grow_keep(r, w->oval, &cvc, 3 * ci, sizeof(float), 3 * w->on);
            if (!nv) return; /* oidx grew, ocap did not: a later try grows oval only */
            w->oval = nv;
            w->ocap = ci;
        }
        w->oidx[w->on] = (uint32_t)f;
        for (int c = 0; c < 3; c++) w->oval[w->on * 3 + c] = (float)(cv * col[c]);
        w->on++;
        rec->count++;
    }
    if (q->nkang) k_extract(r, w, q, col, ebase, nslot, Ld, last, ctx->kc);
}

/* 0, or -1 if memory ran out (the light stays unprojected). */
static int project_light(wrt_relight *r, light_state *ls) {
    for (int t = 0; t < r->nthreads; t++) r->workers[t].on = 0;
    light_c lc = light_consts(&ls->light);
    r->size = 2 * (r->scene_diag + v3_len(v3_sub(ls->light.pos, r->origin)));
    proj_ctx ctx = {&ls->light, &lc, ls->root, ls->kc};
    /* Levels first (cheap), so that the loop knows its work; bounding cones. */
    double work = 0;
    for (uint32_t q = 0; q < r->g->nquads; q++) {
        const quad_info *qi = &r->qi[q];
        light_cone *cn = &r->cones[q];
        wrt_v3 dc = v3_sub(qi->centre, ls->light.pos);
        double D = v3_len(dc);
        cn->dmin = D > qi->radius ? D - qi->radius : 0;
        cn->dmax = D + qi->radius;
        if (D > qi->radius) {
            cn->u = v3_scale(dc, 1.0 / D);
            cn->sina = qi->radius / D;
            cn->cosa = sqrt(1 - cn->sina * cn->sina);
        } else { cn->u = v3(0, 0, 1); cn->sina = 0; cn->cosa = -1; } /* the light is inside */
        double dmin = quad_dist(&r->qi[q], ls->light.pos);
        int L = ls->light.range > 0 && dmin >= ls->light.range ? -1 : projection_level(r, &r->qi[q], dmin);
        if (L >= 0) work += ldexp(r->opt.proj_reference > 0 ? 4096.0 : 4.0, 2 * L);
        if (L >= 0 && r->opt.proj_level == 0) { /* the rule is applied cell by cell from here */
            int cap = projection_cap(r, &r->qi[q]);
            L = cap < PROJ_MIN_LEVEL ? cap : PROJ_MIN_LEVEL;
        }
        r->qlevel[q] = (int8_t)L;
    }
    if (ls->last_work > 0) work = ls->last_work; /* the light moves a little: as much as last time */
    for (int t = 0; t < r->nthreads; t++) r->workers[t].nsamples = 0;
    parallel_for(r, (int)r->g->nquads, work, project_quad, &ctx);
    if (atomic_load(&r->upd_oom)) return -1;
    ls->last_work = 0;
    for (int t = 0; t < r->nthreads; t++) ls->last_work += 0.25 * (double)r->workers[t].nsamples; /* ~50 ns each */
    size_t total = 0;
    for (uint32_t q = 0; q < r->g->nquads; q++) total += r->recs[q].count;
    if (total > ls->cap) {
        size_t ci = ls->cap, cv = 3 * ls->cap;
        uint32_t *ni = grow(r, ls->idx, &ci, total, sizeof(uint32_t));
        if (!ni) return -1;
        ls->idx = ni;
        float *nv = grow(r, ls->val, &cv, 3 * ci, sizeof(float));
        if (!nv) return -1;
        ls->val = nv;
        ls->cap = ci;
    }
    size_t k = 0;
    for (uint32_t q = 0; q < r->g->nquads; q++) {
        const out_rec *rec = &r->recs[q];
        if (!rec->count) continue;
        const worker *w = &r->workers[rec->worker];
        memcpy(ls->idx + k, w->oidx + rec->start, rec->count * sizeof(uint32_t));
        memcpy(ls->val + 3 * k, w->oval + 3 * rec->start, rec->count * 3 * sizeof(float));
        k += rec->count;
    }
    ls->n = total;
    ls->projected = 1;
    return 0;
}

/* ------------------------------------------------------------ BRDF table ---- */

int wrt_relight_beta(const wrt_relight *r, int material, double a_o, double b_o, int ang, double out[3]) {
    out[0] = out[1] = out[2] = 0;
    if (material < 0 || material >= (int)r->g->nmaterials || !r->beta[material] || ang < 0 || ang >= NANG) return 0;
    double fx = a_o * BETA_RES - 0.5, fy = b_o * BETA_RES - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    for (int k = 0; k < 4; k++) {
        int cx = x0 + (k & 1), cy = y0 + (k >> 1);
        double wgt = ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty);
        cx = cx < 0 ? 0 : cx >= BETA_RES ? BETA_RES - 1 : cx;
        cy = cy < 0 ? 0 : cy >= BETA_RES ? BETA_RES - 1 : cy;
        const float *b = r->beta[material] + ((size_t)(cy * BETA_RES + cx) * NANG + ang) * 3;
        for (int c = 0; c < 3; c++) out[c] += wgt * b[c];
    }
    return 1;
}

/* ------------------------------------------------------------- synthesis ---- */

/* Outgoing radiance of a Lambertian quad: base/pi x irradiance, texel averages. The
 * texel factor 2^Lt sqrt(pi/J)/pi (h value x sqrt(pi/J) x 1/pi) and the base colour
 * are folded into the coefficients (synthesis is linear); a non-parallelogram's
 * varying factor is applied after, from r->texk. */
static void synth_diffuse(wrt_relight *r, worker *w, int qidx, const float *base, float *tex) {
    const quad_info *q = &r->qi[qidx];
    const wrt_gto_quad *gq = &r->g->quads[qidx];
    int Lt = q->tex_level, res = 1 << Lt;
    size_t ncell = (size_t)res * res;
    GROW(r, w->fpyr, w->fpyr_cap, ncell * 4);
    GROW(r, w->fgrid, w->fgrid_cap, ncell + 4);
    float *pyr = w->fpyr;
    if (!q->synth_full) memset(pyr, 0, ncell * 4 * sizeof(float)); /* else every slot is written */
    float kc[3];
    double k = q->parallelogram ? ldexp(1.0, Lt) * sqrt(WRT_PI / q->area) / WRT_PI : 1;
    for (int c = 0; c < 3; c++) kc[c] = (float)(k * base[c]);
    for (size_t f = gq->func_first; f < (size_t)gq->func_first + gq->func_count; f++) {
        if (r->fn_ang[f] != 0) continue;
        if (r->fn_slevel[f] >= Lt && r->fn_spidx[f] != 0) continue; /* averages to 0 per texel */
        float *pc = pyr + (size_t)r->fn_spidx[f] * 4;
        for (int c = 0; c < 3; c++) pc[c] = r->X[f * 3 + c] * kc[c];
        pc[3] = 0;
    }
    haar_synthesize4f(pyr, Lt, w->fgrid, tex, 3);
    if (!q->parallelogram) {
        const float *tk = r->texk + q->tex_off / 3;
        for (size_t t = 0; t < ncell; t++)
            for (int c = 0; c < 3; c++) tex[t * 3 + c] *= tk[t];
    }
}

/* Outgoing radiance toward the eye of a glossy quad:
 * L_o(x) = sum_f X_f h_f(u,v) / sqrt(pi J) beta_{g_f}(w_o(x)). */
static void synth_glossy(wrt_relight *r, worker *w, int qidx) {
    const quad_info *q = &r->qi[qidx];
    int Lt = q->tex_level, res = 1 << Lt;
    size_t ncell = (size_t)res * res;
    float *tex = r->tex + q->tex_off;
    const float *beta = r->beta[q->material];
    double t0 = wrt_now();
    GROW(r, w->acc, w->acc_cap, ncell * 3);
    if (ncell * 4 > w->view_cap) {
        size_t cc = w->view_cap, cw = w->view_cap;
        int *nc = grow(r, w->cells, &cc, ncell * 4, sizeof(int));
        if (!nc) return;
        w->cells = nc;
        float *nw = grow(r, w->wts, &cw, cc, sizeof(float));
        if (!nw) return;
        w->wts = nw;
        w->view_cap = cc;
    }
    memset(w->acc, 0, ncell * 3 * sizeof(float));
    /* Per texel: the outgoing direction's bilinear cells in the beta table, weights
     * folded with 2^Lt / sqrt(pi J); and the box of table cells the quad looks through. */
    int bx0 = BETA_RES, bx1 = -1, by0 = BETA_RES, by1 = -1;
    wrt_v3 eye = v3(r->eye[0], r->eye[1], r->eye[2]);
    double lev = ldexp(1.0, Lt);
    for (int j = 0; j < res; j++)
        for (int i = 0; i < res; i++) {
            double u = (i + 0.5) / res, v = (j + 0.5) / res;
            size_t t = (size_t)j * res + i;
            wrt_v3 x = quad_point(q, u, v), wo = v3_norm(v3_sub(eye, x));
            double loc[3] = {v3_dot(wo, q->t), v3_dot(wo, q->b), v3_dot(wo, q->n)}, a, b;
            if (loc[2] <= 0) { for (int k = 0; k < 4; k++) { w->cells[t * 4 + k] = 0; w->wts[t * 4 + k] = 0; } continue; }
            wrt_concentric_inv(loc, &a, &b);
            double k0 = lev / sqrt(WRT_PI * quad_jacobian(q, u, v));
            double fx = a * BETA_RES - 0.5, fy = b * BETA_RES - 0.5;
            int x0 = (int)floor(fx), y0 = (int)floor(fy);
            double tx = fx - x0, ty = fy - y0;
            for (int k = 0; k < 4; k++) {
                int cx = x0 + (k & 1), cy = y0 + (k >> 1);
                cx = cx < 0 ? 0 : cx >= BETA_RES ? BETA_RES - 1 : cx;
                cy = cy < 0 ? 0 : cy >= BETA_RES ? BETA_RES - 1 : cy;
                if (cx < bx0) bx0 = cx;
                if (cx > bx1) bx1 = cx;
                if (cy < by0) by0 = cy;
                if (cy > by1) by1 = cy;
                w->cells[t * 4 + k] = cy * BETA_RES + cx;
                w->wts[t * 4 + k] = (float)(k0 * ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty));
            }
        }
    /* Root's beta over the box, for the pruning threshold. */
    double root_max = 0;
    for (int cy = by0; cy <= by1; cy++)
        for (int cx = bx0; cx <= bx1; cx++)
            for (int c = 0; c < 3; c++) {
                double bv = fabs(beta[((size_t)(cy * BETA_RES + cx) * NANG) * 3 + c]);
                if (bv > root_max) root_max = bv;
            }
    w->brdf_time += wrt_now() - t0;
    if (bx1 < 0) { memset(tex, 0, ncell * 3 * sizeof(float)); return; }
    GROW(r, w->fpyr, w->fpyr_cap, ncell * 4);
    GROW(r, w->fgrid, w->fgrid_cap, ncell + 4);
    GROW(r, w->grid, w->grid_cap, ncell * 3); /* used as floats */
    float *pyr = w->fpyr, *vals = (float *)w->grid;
    const uint16_t *alist = r->ang_list + q->ang_first;
    const uint32_t *astart = r->ang_start + q->ang_first + qidx; /* nang + 1 entries */
    for (int s = 0; s < q->nang; s++) {
        int g = alist[s];
        if (g != 0) { /* Figure 5 pruning: negligible for every direction toward the eye */
            double mx = 0;
            for (int cy = by0; cy <= by1; cy++)
                for (int cx = bx0; cx <= bx1; cx++)
                    for (int c = 0; c < 3; c++) {
                        double bv = fabs(beta[((size_t)(cy * BETA_RES + cx) * NANG + g) * 3 + c]);
                        if (bv > mx) mx = bv;
                    }
            if (mx <= PRUNE_REL * root_max) continue;
        }
        if (!r->ang_full[q->ang_first + s]) memset(pyr, 0, ncell * 4 * sizeof(float));
        int nz = 0;
        for (uint32_t p = astart[s]; p < astart[s + 1]; p++) {
            uint32_t f = r->ang_perm[p];
            if (r->fn_slevel[f] >= Lt && r->fn_spidx[f] != 0) continue;
            float *pc = pyr + (size_t)r->fn_spidx[f] * 4;
            for (int c = 0; c < 3; c++) {
                float xv = r->X[(size_t)f * 3 + c];
                pc[c] = xv;
                nz |= xv != 0;
            }
            pc[3] = 0;
        }
        if (!nz) continue;
        haar_synthesize4f(pyr, Lt, w->fgrid, vals, 3);
        for (size_t t = 0; t < ncell; t++) {
            float bsum[3] = {0, 0, 0};
            for (int k = 0; k < 4; k++) {
                const float *b = beta + ((size_t)w->cells[t * 4 + k] * NANG + g) * 3;
                float wk = w->wts[t * 4 + k];
                for (int c = 0; c < 3; c++) bsum[c] += wk * b[c];
            }
            for (int c = 0; c < 3; c++) w->acc[t * 3 + c] += vals[t * 3 + c] * bsum[c];
        }
    }
    memcpy(tex, w->acc, ncell * 3 * sizeof(float));
}

typedef struct synth_ctx { const int *list; } synth_ctx;

static void synth_item(wrt_relight *r, worker *w, int item, void *vctx) {
    synth_ctx *ctx = vctx;
    int q = ctx->list[item];
    if (r->qi[q].glossy) synth_glossy(r, w, q);
    else synth_diffuse(r, w, q, r->mats[r->qi[q].material].base_color, r->tex + r->qi[q].tex_off);
}

/* --------------------------------------------------------- reconstruction ---- */

/* The smooth texture has the resolution of the finest cells (2^(slevel+1) a side, capped
 * by max_tex_res): one level finer was measured no better (cornell, quality 5: image error
 * 3.42% against 3.44%) for 4 times the texels, one level coarser worse (3.66%). Which of
 * the bake's averages are kept: reconstruct.h's defaults, chosen by measurement (README,
 * "Smooth display"). */
#define RECON_EXTRA 0

/* The smooth display (reconstruct.h): neighbours and groups from the quads' corners and
 * materials; every member of a group gets the group's deepest texel level (so the group
 * is resampled at one resolution), its smooth texture RECON_EXTRA levels finer (capped);
 * per quad, which nodes hold a function. Recomputes the texel offsets and *tex_total. */
/* The final gather on glossy quads (gather.h) unless the options or WRT_FINAL_GATHER=0
 * turn it off (the coarse angular synthesis alone: for before/after measurements). */
static int gather_wanted(const wrt_relight *r) {
    const char *fg = getenv("WRT_FINAL_GATHER");
    return !r->opt.no_gather && !(fg && strcmp(fg, "0") == 0);
}

static wrt_status setup_reconstruction(wrt_relight *r, size_t *tex_total) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads;
    double (*corners)[4][3] = ra_calloc(r, nq ? nq : 1, sizeof *corners);
    uint32_t *mat = ra_calloc(r, nq ? nq : 1, sizeof(uint32_t));
    if (r->oom) { ra_free(r, corners); ra_free(r, mat); return WRT_ERR_NOMEM; }
    for (uint32_t q = 0; q < nq; q++) {
        memcpy(corners[q], g->quads[q].p, sizeof corners[q]);
        mat[q] = g->quads[q].material;
    }
    wrt_recon_allocator ral = {r->opt.alloc, r->opt.free, r->opt.alloc_user};
    r->recon = wrt_recon_create_with((int)nq, (const double (*)[4][3])corners, mat, &ral);
    ra_free(r, corners);
    ra_free(r, mat);
    if (!r->recon) return WRT_ERR_NOMEM;
    int ng = wrt_recon_ngroups(r->recon);
    r->regroup = ra_calloc(r, (size_t)ng + 1, 1);
    r->rin = ra_calloc(r, (size_t)nq + 1, sizeof *r->rin);
    r->rknown = ra_calloc(r, (size_t)nq + 1, sizeof *r->rknown);
    r->rout = ra_calloc(r, (size_t)nq + 1, sizeof *r->rout);
    if (r->oom) return WRT_ERR_NOMEM;
    int extra = r->opt.recon_extra != 0 ? r->opt.recon_extra : RECON_EXTRA;
    size_t total = 0, stotal = 0;
    for (int gr = 0; gr < ng; gr++) {
        int nm, L = 0;
        const int *mem = wrt_recon_members(r->recon, gr, &nm);
        int sharp = 0;
        for (int k = 0; k < nm; k++) {
            if (r->qi[mem[k]].tex_level > L) L = r->qi[mem[k]].tex_level;
            if (r->qi[mem[k]].glossy && wrt_gather_sharp(&r->mats[r->qi[mem[k]].material])) sharp = 1;
        }
        int Lo = L + extra < r->max_tex_level ? L + extra : r->max_tex_level;
        if (Lo < 1) Lo = L < 1 ? L : 1;
        /* a sharp reflection is gathered a point per texel: its texture has the gather's
         * resolution whatever the depth of the quad's cells in the file (glossy links are
         * refined at a lower quality: cornell-glossy r0.1 at quality 5, texture 16 -> 32:
         * 64 x 64 pixels at 1024 paths: image rmse 0.321 -> 0.262, floor 0.235; r0.3: 0.112
         * -> 0.091, floor 0.069) */
        if (sharp && gather_wanted(r)) {
            int Ls = 0;
            while ((2 << Ls) <= WRT_GATHER_SHARP_RES) Ls++;
            if (Ls > r->max_tex_level) Ls = r->max_tex_level;
            if (Lo < Ls) Lo = Ls;
        }
        for (int k = 0; k < nm; k++) {
            quad_info *qi = &r->qi[mem[k]];
            qi->tex_level = L;
            qi->stex_level = Lo;
        }
    }
    for (uint32_t q = 0; q < nq; q++) {
        quad_info *qi = &r->qi[q];
        const wrt_gto_quad *gq = &g->quads[q];
        qi->tex_off = total;
        total += ((size_t)1 << (2 * qi->tex_level)) * 3;
        qi->stex_off = stotal;
        stotal += ((size_t)1 << (2 * qi->stex_level)) * 3;
        qi->known = ra_calloc(r, (((size_t)1 << (2 * qi->tex_level)) - 1) / 3 + 1, 1);
        if (!qi->known) return WRT_ERR_NOMEM;
        for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++) {
            if (r->fn_slevel[f] == FN_INVALID || r->fn_spidx[f] == 0 || r->fn_slevel[f] >= qi->tex_level) continue;
            wrt_node nd = wrt_fkey_snode(g->fkeys[f]);
            qi->known[wrt_recon_node((int)nd.level, (int)nd.x, (int)nd.y)] = 1;
        }
    }
    *tex_total = total;
    r->stex = ra_calloc(r, stotal + 1, sizeof(float));
    return r->oom ? WRT_ERR_NOMEM : WRT_OK;
}

typedef struct recon_ctx { const int *groups; } recon_ctx;

static void recon_item(wrt_relight *r, worker *w, int item, void *vctx) {
    (void)w;
    const recon_ctx *ctx = vctx;
    int gr = ctx->groups[item], nm;
    const int *mem = wrt_recon_members(r->recon, gr, &nm);
    const quad_info *q0 = &r->qi[mem[0]];
    /* in, known and out are indexed by quad: each job fills and reads only its group's. */
    const float **in = r->rin;
    const uint8_t **kn = r->rknown;
    float **out = r->rout;
    for (int k = 0; k < nm; k++) {
        const quad_info *qi = &r->qi[mem[k]];
        in[mem[k]] = r->tex + qi->tex_off;
        kn[mem[k]] = qi->known;
        out[mem[k]] = r->stex + qi->stex_off;
    }
    wrt_recon_params rp = {r->opt.recon_keep > 0 ? r->opt.recon_keep : WRT_RECON_KEEP, WRT_RECON_SHARP, 1};
    if (wrt_recon_run(r->recon, gr, q0->tex_level, q0->stex_level, 3, in, kn, out, &rp) != 0)
        atomic_store(&r->upd_oom, 1); /* out of memory: the update fails */
}

/* -------------------------------------------------------------- multiply ---- */

#define MUL_MAX_CHUNKS 256
#define MUL_PARALLEL_ENTRIES 3e7 /* entries touched above which the multiply is split */

typedef struct mul_ctx { const uint32_t *cols; uint32_t ncols; int nchunk; const float *src; } mul_ctx;

/* Rows [lo, hi) of X = Op E (E: mc->src, r->E or with K r->Ep): each chunk scans every non-zero column and takes the
 * entries of its rows (rows ascend within a column), so each X entry sums its terms in
 * column order whatever the thread count. Single precision, 4 lanes an entry (the
 * operator and X are floats; measured against double sums: ~1e-6 relative). */
static void mul_chunk(wrt_relight *r, worker *w, int item, void *vctx) {
    (void)w;
    const mul_ctx *mc = vctx;
    const op_view *op = &r->op;
    uint32_t nf = r->g->nfuncs;
    uint32_t lo = (uint32_t)((uint64_t)nf * item / mc->nchunk), hi = (uint32_t)((uint64_t)nf * (item + 1) / mc->nchunk);
    if (lo >= hi) return;
    memset(r->X4 + (size_t)lo * 4, 0, (size_t)(hi - lo) * 4 * sizeof(float));
    for (uint32_t k = 0; k < mc->ncols; k++) {
        uint32_t s = mc->cols[k];
        uint64_t a = op->col_start[s], b = op->col_start[s + 1];
        if (a == b || op->rows[b - 1] < lo || op->rows[a] >= hi) continue;
        while (a < b) { /* first entry with row >= lo */
            uint64_t m = a + (b - a) / 2;
            if (op->rows[m] < lo) a = m + 1; else b = m;
        }
        const float *e = mc->src + (size_t)s * 3;
        uint64_t end = op->col_start[s + 1], vend = end < op->nnz ? end : op->nnz - 1; /* 4-float loads stay inside */
        uint64_t i = a;
#ifdef __SSE2__
        __m128 ev = _mm_set_ps(0.0f, e[2], e[1], e[0]);
        for (; i < vend && op->rows[i] < hi; i++) {
            float *x = r->X4 + (size_t)op->rows[i] * 4;
            _mm_store_ps(x, _mm_add_ps(_mm_load_ps(x), _mm_mul_ps(ev, _mm_loadu_ps(op->vals + i * 3))));
        }
#endif
        for (; i < end && op->rows[i] < hi; i++) {
            float *x = r->X4 + (size_t)op->rows[i] * 4;
            const float *v = op->vals + i * 3;
            x[0] += e[0] * v[0];
            x[1] += e[1] * v[1];
            x[2] += e[2] * v[2];
        }
    }
}

/* ---------------------------------------------------------------- create ---- */

static int material_used_glossy(const wrt_relight *r, uint32_t m) {
    for (uint32_t q = 0; q < r->g->nquads; q++) if (r->qi[q].glossy && (uint32_t)r->qi[q].material == m) return 1;
    return 0;
}

/* perm[0..n) = first + k ordered by angular index, then by function index (a stable
 * counting sort: no comparison callback, hence no shared sort context). */
static void sort_by_ang(const uint8_t *ang, uint32_t first, uint32_t n, uint32_t *perm) {
    uint32_t start[NANG + 1] = {0};
    for (uint32_t k = 0; k < n; k++) start[ang[first + k] + 1]++;
    for (int a = 0; a < NANG; a++) start[a + 1] += start[a];
    for (uint32_t k = 0; k < n; k++) perm[start[ang[first + k]]++] = first + k;
}

/* Messages: the caller's log callback (options.log), else wrt_log. */
static void relight_log(const wrt_relight *r, int level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void relight_log(const wrt_relight *r, int level, const char *fmt, ...) {
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (r->opt.log) r->opt.log(r->opt.log_user, level, buf);
    else wrt_log(level, "%s", buf);
}

static void embree_error(void *user, enum RTCError code, const char *str) {
    relight_log(user, WRT_LOG_WARN, "Embree error %d: %s", (int)code, str ? str : "");
}

typedef struct brdf_ctx { const wrt_material *m; float *tab; } brdf_ctx;
static void brdf_cell_item(wrt_relight *r, worker *w, int item, void *vctx) {
    (void)r; (void)w;
    const brdf_ctx *bc = vctx;
    wrt_brdf_table_build_cell(bc->m, item, bc->tab);
}

static wrt_status relight_nomem(wrt_relight *r) {
    wrt_relight_destroy(r);
    return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory");
}

/* The final gather's loops and memory (gather.h): the relighter's own. */
typedef struct gather_job { wrt_gather_item_fn fn; void *ctx; } gather_job;
static void gather_item(wrt_relight *r, worker *w, int item, void *ctx) {
    (void)r; (void)w;
    const gather_job *j = ctx;
    j->fn((size_t)item, j->ctx);
}
static void gather_run(void *user, size_t n, wrt_gather_item_fn fn, void *ctx) {
    gather_job j = {fn, ctx};
    parallel_for(user, (int)n, 1e9, gather_item, &j);
}
static void *gather_alloc(void *user, size_t bytes) { return ra_calloc(user, 1, bytes); }
static void gather_free(void *user, void *p) { ra_free(user, p); }

/* With the final gather nothing shows the rows of X that are a glossy quad's angular
 * (non-root) functions: glossy quads are drawn from the gather, which reads every quad's
 * angular-root functions only (a diffuse quad has no others). The multiply then streams a
 * copy of the operator without those rows (on the glossy asset 15% of the entries are
 * kept), in the file's order, so every displayed row of X sums the same terms in the same
 * order (bit-identical); the others stay 0. Kept as the file's when it would save < 10%.
 * Returns -1 if there is no memory. */
static int display_rows_operator(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nf = g->nfuncs;
    uint64_t keep = 0;
    for (uint64_t i = 0; i < g->nnz; i++) keep += r->fn_ang[g->rows[i]] == 0;
    if (keep >= 0.9 * (double)g->nnz) return 0;
    uint64_t *cs = ra_calloc(r, (size_t)nf + 1, sizeof *cs);
    uint32_t *rows = ra_calloc(r, keep ? keep : 1, sizeof *rows);
    float *vals = ra_calloc(r, (keep ? keep : 1) * 3 + 1, sizeof *vals); /* + 1: 4-float loads */
    if (!cs || !rows || !vals) { ra_free(r, cs); ra_free(r, rows); ra_free(r, vals); return -1; }
    uint64_t n = 0;
    for (uint32_t c = 0; c < nf; c++) {
        cs[c] = n;
        for (uint64_t i = g->col_start[c]; i < g->col_start[c + 1]; i++) {
            if (r->fn_ang[g->rows[i]] != 0) continue;
            rows[n] = g->rows[i];
            memcpy(vals + n * 3, g->vals + i * 3, 3 * sizeof *vals);
            n++;
        }
    }
    cs[nf] = n;
    r->op.col_start = cs; r->op.rows = rows; r->op.vals = vals; r->op.nnz = n;
    r->op_own[0] = cs; r->op_own[1] = rows; r->op_own[2] = vals;
    return 0;
}

/* The first-bounce operator K (g->nkcols > 0): checks what the relighter relies on (the
 * reader checks the rest), then per column its spatial level and pyramid slot and its
 * angular index, per quad its range of columns, deepest spatial level and the angular
 * functions among them (the projection's K slots). K's angular levels are < 4 (2 bits
 * in a key), all in the BRDF table (levels 0..3). WRT_ERR_CORRUPT naming the column,
 * WRT_ERR_NOMEM. */
_Static_assert(WRT_BRDF_TABLE_LEVELS >= 4 && NANG == WRT_BRDF_TABLE_NANG,
               "a key's angular node level (2 bits, 0..3) must be in the BRDF table: L_K <= 4 is covered");
static wrt_status setup_first_bounce(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nk = g->nkcols, nq = g->nquads;
    if (!g->kkeys || !g->kcol_start || (g->knnz && (!g->krows || !g->kvals)))
        return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: %u columns without their arrays", nk);
    if (g->kcol_start[0] != 0 || g->kcol_start[nk] != g->knnz)
        return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column starts do not run from 0 to %llu entries",
                        (unsigned long long)g->knnz);
    for (uint32_t j = 0; j < nk; j++) {
        wrt_fkey k = g->kkeys[j];
        wrt_node sn = wrt_fkey_snode(k), an = wrt_fkey_anode(k);
        int st = wrt_fkey_stype(k), at = wrt_fkey_atype(k);
        uint32_t q = wrt_fkey_quad(k);
        if (j && k <= g->kkeys[j - 1]) return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: keys not ascending", j);
        if (q >= nq || !r->qi[q].glossy)
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: quad %u is not a glossy quad", j, q);
        if (!(sn.x < (1u << sn.level) && sn.y < (1u << sn.level) && (st != 0 || sn.level == 0) && an.x < (1u << an.level) &&
              an.y < (1u << an.level) && (at != 0 || an.level == 0)))
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: key is not a basis function", j);
        if (g->kcol_start[j + 1] < g->kcol_start[j])
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: column %u: start not monotone", j);
    }
    for (uint64_t e = 0; e < g->knnz; e++)
        if (g->krows[e] >= g->nfuncs)
            return wrt_fail(WRT_ERR_CORRUPT, "relight: first-bounce operator: entry %llu: row %u outside the %u functions",
                            (unsigned long long)e, g->krows[e], g->nfuncs);
    r->kfn_slevel = ra_calloc(r, nk, 1);
    r->kfn_ang = ra_calloc(r, nk, 1);
    r->kfn_spidx = ra_calloc(r, nk, sizeof(uint32_t));
    r->C = ra_calloc(r, (size_t)nk * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    r->Y = ra_calloc(r, (size_t)g->nfuncs * 3 + 1, sizeof(float));
    r->Ep = ra_calloc(r, (size_t)g->nfuncs * 3 + 1, sizeof(float));
    r->Y4 = ra_calloc(r, (size_t)g->nfuncs * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
#ifdef WRT_K_AVX
    __builtin_cpu_init();
    r->k_avx = __builtin_cpu_supports("avx") && !getenv("WRT_NO_AVX"); /* WRT_NO_AVX: tests, A/B */
#endif
    if (g->knnz > UINT32_MAX) return wrt_fail(WRT_ERR_NOMEM, "relight: first-bounce operator of %llu entries: too large",
                                              (unsigned long long)g->knnz);
    /* K by rows: Y = K c sums each row in registers, in column order (no store per entry).
     * Two to four consecutive rows of one quad and spatial node (a glossy receiver's
     * incident angular functions; a node's wavelets) have nearly the same columns (97% on
     * the glossy asset, where the fours of glossy receivers hold 87% of K's entries): their
     * union is stored once with 4 values an entry, one load of c serving the rows. Y on the
     * glossy asset's 1.5 M entries, one thread: the columns' scatter 1.1 ms, rows one by
     * one 0.87 ms, fours 0.58 ms, with AVX 0.45 ms, with the nodes' wavelets too 0.42 ms. */
    uint32_t nf = g->nfuncs;
    uint32_t *ts = ra_calloc(r, (size_t)nf + 1, sizeof(uint32_t));
    kt_entry *te = ra_calloc(r, (size_t)g->knnz + 1, sizeof(kt_entry));
    r->kt_start = ra_calloc(r, (size_t)nf + 1, sizeof(uint32_t));
    r->k4_row = ra_calloc(r, (size_t)nf / 2 + 1, sizeof(uint32_t));
    r->k4_start = ra_calloc(r, (size_t)nf / 2 + 2, sizeof(uint32_t));
    r->k4_n = ra_calloc(r, (size_t)nf / 2 + 1, 1);
    uint8_t *in4 = ra_calloc(r, (size_t)nf + 1, 1);
    if (r->oom) { ra_free(r, ts); ra_free(r, te); ra_free(r, in4); return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory"); }
    for (uint64_t e = 0; e < g->knnz; e++) ts[g->krows[e] + 1]++;
    for (uint32_t f = 0; f < nf; f++) ts[f + 1] += ts[f];
    for (uint32_t j = 0; j < nk; j++)
        for (uint64_t e = g->kcol_start[j]; e < g->kcol_start[j + 1]; e++) {
            uint32_t p = ts[g->krows[e]]++;
            te[p].col = j;
            te[p].val = g->kvals[e];
        }
    for (uint32_t f = nf; f > 0; f--) ts[f] = ts[f - 1];
    ts[0] = 0;
    /* the fours (2 to 4 consecutive rows of one quad and spatial node: a glossy receiver's
     * incident angular functions, or a node's three wavelets, with the root's node its
     * root function) and their union's size (a merge of ascending lists) */
    uint64_t n4 = 0, n1 = 0;
    for (uint32_t f = 0; f < nf;) {
        uint32_t n = 1;
        while (n < 4 && f + n < nf && (g->fkeys[f + n] >> 18) == (g->fkeys[f] >> 18)) n++;
        if (n < 2) { f++; continue; }
        r->k4_row[r->nk4] = f;
        r->k4_n[r->nk4] = (uint8_t)n;
        uint32_t p[4];
        for (uint32_t k = 0; k < n; k++) p[k] = ts[f + k];
        for (;;) {
            uint32_t m = UINT32_MAX;
            for (uint32_t k = 0; k < n; k++) if (p[k] < ts[f + k + 1] && te[p[k]].col < m) m = te[p[k]].col;
            if (m == UINT32_MAX) break;
            for (uint32_t k = 0; k < n; k++) if (p[k] < ts[f + k + 1] && te[p[k]].col == m) p[k]++;
            n4++;
        }
        r->k4_start[++r->nk4] = (uint32_t)n4;
        for (uint32_t k = 0; k < n; k++) in4[f + k] = 1;
        f += n;
    }
    for (uint32_t f = 0; f < nf; f++) if (!in4[f]) n1 += ts[f + 1] - ts[f];
    r->kt = ra_calloc(r, (size_t)n1 + 1, sizeof(kt_entry));
    r->k4_cols = ra_calloc(r, (size_t)n4 + 1, sizeof(uint32_t));
    r->k4_vals = ra_calloc(r, (size_t)n4 * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    if (r->oom) { ra_free(r, ts); ra_free(r, te); ra_free(r, in4); return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory"); }
    uint64_t q1 = 0;
    for (uint32_t f = 0; f < nf; f++) {
        r->kt_start[f] = (uint32_t)q1;
        if (in4[f]) continue;
        for (uint32_t e = ts[f]; e < ts[f + 1]; e++) r->kt[q1++] = te[e];
    }
    r->kt_start[nf] = (uint32_t)q1;
    for (uint32_t i = 0; i < r->nk4; i++) {
        uint32_t f = r->k4_row[i], n = r->k4_n[i], p[4], b = r->k4_start[i];
        for (uint32_t k = 0; k < n; k++) p[k] = ts[f + k];
        for (;; b++) {
            uint32_t m = UINT32_MAX;
            for (uint32_t k = 0; k < n; k++) if (p[k] < ts[f + k + 1] && te[p[k]].col < m) m = te[p[k]].col;
            if (m == UINT32_MAX) break;
            r->k4_cols[b] = m;
            for (uint32_t k = 0; k < 4; k++)
                r->k4_vals[(size_t)b * 4 + k] = k < n && p[k] < ts[f + k + 1] && te[p[k]].col == m ? te[p[k]++].val : 0;
        }
    }
    ra_free(r, ts); ra_free(r, te); ra_free(r, in4);
    for (uint32_t j = 0; j < nk;) { /* keys ascend: each quad's columns are contiguous */
        uint32_t q = wrt_fkey_quad(g->kkeys[j]), j1 = j;
        quad_info *qi = &r->qi[q];
        qi->kfirst = j;
        for (; j1 < nk && wrt_fkey_quad(g->kkeys[j1]) == q; j1++) {
            wrt_fkey k = g->kkeys[j1];
            wrt_node sn = wrt_fkey_snode(k), an = wrt_fkey_anode(k);
            r->kfn_slevel[j1] = sn.level;
            r->kfn_spidx[j1] = haar_index(sn.level, sn.x, sn.y, wrt_fkey_stype(k));
            r->kfn_ang[j1] = (uint8_t)haar_index(an.level, an.x, an.y, wrt_fkey_atype(k));
            if (sn.level > qi->kslevel) qi->kslevel = sn.level;
            if (r->kfn_ang[j1] + 1 > qi->nkang) qi->nkang = r->kfn_ang[j1] + 1;
        }
        qi->kcount = j1 - j;
        j = j1;
    }
    return WRT_OK;
}

wrt_status wrt_relight_create(const wrt_gto *g, const wrt_relight_options *opt, wrt_relight **out) {
    *out = NULL;
    if (!g) return wrt_fail(WRT_ERR_INVALID_ARG, "relight: no operator");
    wrt_relight_options o = {0};
    if (opt) o = *opt;
    if (!o.alloc != !o.free) return wrt_fail(WRT_ERR_INVALID_ARG, "relight: an allocator needs both alloc and free");
    wrt_relight *r = o.alloc ? o.alloc(sizeof *r, o.alloc_user) : malloc(sizeof *r);
    if (!r) return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory");
    memset(r, 0, sizeof *r);
    r->g = g;
    r->op.col_start = g->col_start; r->op.rows = g->rows; r->op.vals = g->vals; r->op.nnz = g->nnz;
    r->opt = o;
    if (r->opt.proj_level < 0 || r->opt.proj_level > PROJ_MAX_LEVEL) {
        ra_free(r, r);
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: projection level %d outside 0..%d", opt->proj_level, PROJ_MAX_LEVEL);
    }
    int mt = r->opt.max_tex_res > 0 ? r->opt.max_tex_res : 64;
    r->max_tex_level = 0;
    while ((2 << r->max_tex_level) <= mt && r->max_tex_level < 12) r->max_tex_level++;
    long nc = sysconf(_SC_NPROCESSORS_ONLN);
    r->nthreads = r->opt.threads > 0 ? r->opt.threads : (int)(nc > 0 ? nc : 1);
    if (r->nthreads > 64) r->nthreads = 64;
    if (r->opt.parallel_for) { /* the caller's job hook: no thread of our own */
        r->wbusy = ra_calloc(r, (size_t)r->nthreads, sizeof *r->wbusy);
        if (r->oom) { ra_free(r, r); return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory"); }
        for (int t = 0; t < r->nthreads; t++) atomic_init(&r->wbusy[t], 0);
    } else {
        if (wrt_pool_create(r->nthreads, &r->pool) != WRT_OK) {
            ra_free(r, r);
            return wrt_fail(WRT_ERR_NOMEM, "relight: no memory for the thread pool");
        }
        r->nthreads = wrt_pool_size(r->pool);
    }
    r->workers = ra_calloc(r, (size_t)r->nthreads, sizeof(worker));
    if (r->oom) return relight_nomem(r);
    for (int t = 0; t < r->nthreads; t++) {
        r->workers[t].pstate = ra_calloc(r, PROJ_TREE_CELLS, sizeof(uint32_t));
        r->workers[t].prefined = ra_calloc(r, PROJ_TREE_CELLS, 1);
        r->workers[t].pclear = ra_calloc(r, PROJ_TREE_CELLS, 1);
        r->workers[t].pcells = ra_calloc(r, PROJ_TREE_CELLS, sizeof(uint16_t));
    }
    if (r->oom) return relight_nomem(r);

    uint32_t nq = g->nquads, nf = g->nfuncs;
    r->mats = ra_calloc(r, g->nmaterials ? g->nmaterials : 1, sizeof(wrt_material));
    if (r->oom) return relight_nomem(r);
    for (uint32_t m = 0; m < g->nmaterials; m++) {
        const wrt_gto_material *gm = &g->materials[m];
        wrt_material *mm = &r->mats[m];
        memcpy(mm->name, gm->name, sizeof mm->name);
        mm->name[sizeof mm->name - 1] = 0;
        for (int c = 0; c < 3; c++) { mm->base_color[c] = gm->base_color[c]; mm->emissive[c] = gm->emissive[c]; }
        mm->metallic = gm->metallic;
        mm->roughness = gm->roughness;
        mm->lambertian = gm->lambertian != 0;
    }
    /* Per function: spatial level and pyramid slot, angular index. */
    r->fn_slevel = ra_calloc(r, nf ? nf : 1, 1);
    r->fn_ang = ra_calloc(r, nf ? nf : 1, 1);
    r->fn_spidx = ra_calloc(r, nf ? nf : 1, sizeof(uint32_t));
    if (r->oom) return relight_nomem(r);
    uint32_t nbad = 0;
    for (uint32_t f = 0; f < nf; f++) {
        wrt_fkey k = g->fkeys[f];
        wrt_node s = wrt_fkey_snode(k), a = wrt_fkey_anode(k);
        int st = wrt_fkey_stype(k), at = wrt_fkey_atype(k);
        int ok = s.x < (1u << s.level) && s.y < (1u << s.level) && (st != 0 || s.level == 0) &&
                 a.x < (1u << a.level) && a.y < (1u << a.level) && (at != 0 || a.level == 0);
        if (!ok) { /* not a basis function: never read nor written */
            r->fn_slevel[f] = FN_INVALID; r->fn_spidx[f] = UINT32_MAX; r->fn_ang[f] = 0;
            nbad++;
            continue;
        }
        r->fn_slevel[f] = s.level;
        r->fn_spidx[f] = haar_index(s.level, s.x, s.y, st);
        r->fn_ang[f] = (uint8_t)haar_index(a.level, a.x, a.y, at);
    }
    if (nbad) relight_log(r, WRT_LOG_WARN, "relight: %u function keys are not basis functions; ignored", nbad);
    /* Per quad. */
    r->qi = ra_calloc(r, nq ? nq : 1, sizeof(quad_info));
    if (r->oom) return relight_nomem(r);
    wrt_v3 bmin = v3(INFINITY, INFINITY, INFINITY), bmax = v3(-INFINITY, -INFINITY, -INFINITY);
    size_t tex_total = 0, ang_total = 0;
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_gto_quad *gq = &g->quads[q];
        quad_info *qi = &r->qi[q];
        if ((uint64_t)gq->func_first + gq->func_count > nf || gq->material >= g->nmaterials) {
            wrt_relight_destroy(r);
            return wrt_fail(WRT_ERR_CORRUPT, "relight: quad %u: functions or material out of range", q);
        }
        for (int k = 0; k < 4; k++) {
            qi->p[k] = v3(gq->p[k][0], gq->p[k][1], gq->p[k][2]);
            bmin = v3(fmin(bmin.x, qi->p[k].x), fmin(bmin.y, qi->p[k].y), fmin(bmin.z, qi->p[k].z));
            bmax = v3(fmax(bmax.x, qi->p[k].x), fmax(bmax.y, qi->p[k].y), fmax(bmax.z, qi->p[k].z));
        }
        qi->n = v3_norm(v3(gq->n[0], gq->n[1], gq->n[2]));
        qi->t = v3_norm(v3(gq->t[0], gq->t[1], gq->t[2]));
        qi->b = v3_norm(v3(gq->b[0], gq->b[1], gq->b[2]));
        qi->parallelogram = gq->flags & 1;
        qi->area = v3_len(v3_cross(v3_sub(qi->p[1], qi->p[0]), v3_sub(qi->p[3], qi->p[0])));
        if (!qi->parallelogram) qi->area = gq->area;
        qi->diam = fmax(v3_len(v3_sub(qi->p[2], qi->p[0])), v3_len(v3_sub(qi->p[3], qi->p[1])));
        qi->centre = v3_scale(v3_add(v3_add(qi->p[0], qi->p[1]), v3_add(qi->p[2], qi->p[3])), 0.25);
        for (int k = 0; k < 4; k++) qi->radius = fmax(qi->radius, v3_len(v3_sub(qi->p[k], qi->centre)));
        qi->material = (int)gq->material;
        qi->glossy = !r->mats[gq->material].lambertian;
        int sl = 0;
        for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++)
            if (r->fn_slevel[f] > sl && r->fn_slevel[f] != FN_INVALID) sl = r->fn_slevel[f];
        qi->slevel = sl;
        for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++)
            if (r->fn_slevel[f] != FN_INVALID && r->fn_ang[f] != 0) {
                int al = (int)wrt_fkey_anode(g->fkeys[f]).level;
                if (al > qi->alevel) qi->alevel = al;
            }
        qi->tex_level = sl + 1 < r->max_tex_level ? sl + 1 : r->max_tex_level;
        qi->tex_off = tex_total;
        tex_total += ((size_t)1 << (2 * qi->tex_level)) * 3;
        /* Mean of sqrt(pi / J) weighted by J: sqrt(pi) integral sqrt(J) du dv / area. */
        double sj = 0;
        for (int j = 0; j < 8; j++)
            for (int i = 0; i < 8; i++) sj += sqrt(quad_jacobian(qi, (i + 0.5) / 8, (j + 0.5) / 8));
        qi->mean_factor = sqrt(WRT_PI) * sj / 64 / qi->area;
        qi->root_func = -1;
        if (gq->func_count && g->fkeys[gq->func_first] == wrt_fkey_make(q, wrt_node_root(), 0, wrt_node_root(), 0))
            qi->root_func = (int)gq->func_first;
        /* Present angular functions. */
        uint8_t seen[NANG] = {0};
        int na = 0;
        for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++)
            if (!seen[r->fn_ang[f]]) { seen[r->fn_ang[f]] = 1; na++; }
        qi->nang = na;
        qi->ang_first = (uint32_t)ang_total;
        ang_total += (size_t)na;
    }
    if (!r->opt.haar_blocks && setup_reconstruction(r, &tex_total) != WRT_OK) return relight_nomem(r);
    r->ang_list = ra_calloc(r, ang_total ? ang_total : 1, sizeof(uint16_t));
    r->ang_start = ra_calloc(r, ang_total + nq + 1, sizeof(uint32_t));
    r->ang_full = ra_calloc(r, ang_total + 1, 1);
    r->ang_perm = ra_calloc(r, nf ? nf : 1, sizeof(uint32_t));
    if (r->oom) return relight_nomem(r);
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_gto_quad *gq = &g->quads[q];
        quad_info *qi = &r->qi[q];
        uint32_t *perm = r->ang_perm + gq->func_first;
        sort_by_ang(r->fn_ang, gq->func_first, gq->func_count, perm);
        uint16_t *al = r->ang_list + qi->ang_first;
        uint32_t *as = r->ang_start + qi->ang_first + q;
        int s = -1;
        for (uint32_t k = 0; k < gq->func_count; k++) {
            int a = r->fn_ang[perm[k]];
            if (s < 0 || al[s] != a) { s++; al[s] = (uint16_t)a; as[s] = gq->func_first + k; }
        }
        as[qi->nang] = gq->func_first + gq->func_count;
        /* Whether a synthesis pyramid (levels < tex_level) is filled without clearing. */
        for (int a = 0; a < qi->nang; a++) {
            size_t cnt = 0;
            for (uint32_t p = as[a]; p < as[a + 1]; p++) {
                uint32_t f = r->ang_perm[p];
                cnt += r->fn_slevel[f] != FN_INVALID && (r->fn_spidx[f] == 0 || r->fn_slevel[f] < qi->tex_level);
            }
            r->ang_full[qi->ang_first + a] = cnt == ((size_t)1 << (2 * qi->tex_level));
            if (al[a] == 0) qi->synth_full = r->ang_full[qi->ang_first + a];
        }
    }
    if (g->nkcols) {
        wrt_status ks = setup_first_bounce(r);
        if (ks != WRT_OK) { wrt_relight_destroy(r); return ks; }
    }
    /* Embree scene of every quad, in a frame centred on the scene (float precision). */
    r->origin = nq ? v3_scale(v3_add(bmin, bmax), 0.5) : v3(0, 0, 0);
    r->scene_diag = nq ? v3_len(v3_sub(bmax, bmin)) : 1;
    if (!(r->scene_diag > 0)) r->scene_diag = 1;
    wrt_v3 *corners = ra_calloc(r, (size_t)(nq ? nq : 1) * 4, sizeof *corners);
    if (r->oom) return relight_nomem(r);
    for (uint32_t q = 0; q < nq; q++)
        for (int k = 0; k < 4; k++) corners[4 * q + k] = r->qi[q].p[k];
    wrt_rt_scene rs;
    wrt_status est = wrt_rt_scene_build(corners, (int)nq, r->origin, NULL, 0, &rs);
    ra_free(r, corners);
    if (est != WRT_OK) { wrt_relight_destroy(r); return est; }
    r->dev = rs.dev;
    r->scene = rs.scene;
    r->eps = rs.eps;
    if (r->opt.log) rtcSetDeviceErrorFunction(r->dev, embree_error, r); /* Embree's errors to our log */
    /* State. */
    r->E = ra_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->X = ra_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->Xprev = ra_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->X4 = ra_calloc(r, (size_t)nf * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    r->cols = ra_calloc(r, (size_t)nf + 1, sizeof(uint32_t));
    r->tex = ra_calloc(r, tex_total + 1, sizeof(float));
    r->texk = ra_calloc(r, tex_total / 3 + 1, sizeof(float));
    if (r->oom) return relight_nomem(r);
    for (uint32_t q = 0; q < nq; q++) {
        const quad_info *qi = &r->qi[q];
        if (qi->parallelogram) continue;
        int res = 1 << qi->tex_level;
        for (int j = 0; j < res; j++)
            for (int i = 0; i < res; i++) {
                double J = quad_jacobian(qi, (i + 0.5) / res, (j + 0.5) / res);
                r->texk[qi->tex_off / 3 + (size_t)j * res + i] = (float)(res * sqrt(WRT_PI / J) / WRT_PI);
            }
    }
    r->tex_nonzero = ra_calloc(r, nq + 1, 1);
    r->x_nonzero = ra_calloc(r, nq + 1, 1);
    r->resynth = ra_calloc(r, nq + 1, 1);
    r->recs = ra_calloc(r, nq + 1, sizeof(out_rec));
    r->qlevel = ra_calloc(r, nq + 1, sizeof(int8_t));
    r->cones = ra_calloc(r, nq + 1, sizeof(light_cone));
    r->synth_list = ra_calloc(r, nq + 1, sizeof(int));
    if (r->oom) return relight_nomem(r);
    /* BRDF tables of the materials glossy quads use. */
    r->beta = ra_calloc(r, g->nmaterials + 1, sizeof(float *));
    if (r->oom) return relight_nomem(r);
    for (uint32_t m = 0; m < g->nmaterials; m++) {
        if (!material_used_glossy(r, m)) continue;
        r->beta[m] = ra_calloc(r, (size_t)BETA_RES * BETA_RES * NANG * 3, sizeof(float));
        if (r->oom) return relight_nomem(r);
        brdf_ctx bc = {&r->mats[m], r->beta[m]}; /* on the pool or the caller's hook */
        parallel_for(r, BETA_RES * BETA_RES, 1e9, brdf_cell_item, &bc);
    }
    /* The final gather on glossy quads (gather.h); WRT_FINAL_GATHER=0 turns it off (the
     * coarse angular synthesis alone: for before/after measurements). */
    const char *ls = getenv("WRT_LIGHT_SPLAT");
    r->light_splat = !(ls && strcmp(ls, "0") == 0);
    if (gather_wanted(r)) {
        wrt_gather_quad *gqs = ra_calloc(r, nq ? nq : 1, sizeof *gqs);
        if (!gqs) return relight_nomem(r);
        r->galb = ra_calloc(r, g->nmaterials + 1, sizeof *r->galb);
        if (!r->galb) { ra_free(r, gqs); return relight_nomem(r); }
        for (uint32_t m = 0; m < g->nmaterials; m++) { /* cosine-weighted mean over w_o of beta_root */
            if (!r->beta[m]) { for (int c = 0; c < 3; c++) r->galb[m][c] = r->mats[m].base_color[c]; continue; }
            double sum[3] = {0, 0, 0};
            for (int k = 0; k < BETA_RES * BETA_RES; k++)
                for (int c = 0; c < 3; c++) sum[c] += r->beta[m][((size_t)k * NANG) * 3 + c];
            for (int c = 0; c < 3; c++) r->galb[m][c] = (float)(sum[c] / (BETA_RES * BETA_RES));
        }
        for (uint32_t q = 0; q < nq; q++) {
            const quad_info *qi = &r->qi[q];
            memcpy(gqs[q].p, qi->p, sizeof gqs[q].p);
            memcpy(gqs[q].albedo, r->galb[qi->material], sizeof gqs[q].albedo);
            gqs[q].n = qi->n; gqs[q].t = qi->t; gqs[q].b = qi->b;
            gqs[q].mat = &r->mats[qi->material];
        }
        r->gres = ra_calloc(r, nq ? nq : 1, sizeof *r->gres);
        r->gires = ra_calloc(r, nq ? nq : 1, sizeof *r->gires);
        if (!r->gres || !r->gires) { ra_free(r, gqs); return relight_nomem(r); }
        for (uint32_t q = 0; q < nq; q++) { /* displayed sides; the gather reads gdiff (below) of glossy quads */
            r->gires[q] = r->gres[q] = wrt_relight_tex_res(r, (int)q);
            if (r->qi[q].glossy) r->gires[q] = 1 << r->qi[q].tex_level;
        }
        wrt_gather_env genv = {gather_run, gather_alloc, gather_free, r};
        wrt_status gs = wrt_gather_create((int)nq, gqs, r->gres, r->scene, r->origin, r->eps, &genv, &r->gather);
        ra_free(r, gqs);
        if (gs != WRT_OK) return relight_nomem(r);
        if (r->gather) {
            r->gtex = ra_calloc(r, nq, sizeof *r->gtex);
            r->gout = ra_calloc(r, nq, sizeof *r->gout);
            r->gdiff = ra_calloc(r, nq, sizeof *r->gdiff);
            if (!r->gtex || !r->gout || !r->gdiff) return relight_nomem(r);
            for (uint32_t q = 0; q < nq; q++) {
                r->gtex[q] = wrt_relight_tex(r, (int)q);
                r->gout[q] = (float *)r->gtex[q];
                if (!r->qi[q].glossy) continue;
                r->gdiff[q] = ra_calloc(r, (size_t)r->gires[q] * r->gires[q] * 3, sizeof(float));
                if (!r->gdiff[q]) return relight_nomem(r);
                r->gtex[q] = r->gdiff[q];
            }
            if (display_rows_operator(r) != 0) return relight_nomem(r);
        }
    }
    *out = r;
    return WRT_OK;
}

void wrt_relight_destroy(wrt_relight *r) {
    if (!r) return;
    wrt_pool_destroy(r->pool);
    wrt_gather_destroy(r->gather);
    for (int k = 0; k < 3; k++) ra_free(r, r->op_own[k]);
    if (r->gdiff) for (uint32_t q = 0; q < r->g->nquads; q++) ra_free(r, r->gdiff[q]);
    ra_free(r, r->gtex); ra_free(r, r->gout); ra_free(r, r->gres); ra_free(r, r->gires); ra_free(r, r->gdiff); ra_free(r, r->galb);
    if (r->scene) rtcReleaseScene(r->scene);
    if (r->dev) rtcReleaseDevice(r->dev);
    for (int i = 0; i < r->lights_cap; i++) {
        ra_free(r, r->lights[i].idx); ra_free(r, r->lights[i].val); ra_free(r, r->lights[i].root);
        ra_free(r, r->lights[i].kc);
    }
    ra_free(r, r->lights);
    if (r->workers)
        for (int t = 0; t < r->nthreads; t++) {
            worker *w = &r->workers[t];
            /* scratch grown in updates */
            ra_free(r, w->grid); ra_free(r, w->pyr); ra_free(r, w->acc); ra_free(r, w->wts); ra_free(r, w->cells);
            ra_free(r, w->oidx); ra_free(r, w->oval); ra_free(r, w->fpyr); ra_free(r, w->fgrid); ra_free(r, w->occ);
            ra_free(r, w->pval); ra_free(r, w->pwav);
            ra_free(r, w->pstate); ra_free(r, w->prefined); ra_free(r, w->pclear); ra_free(r, w->pcells);
        }
    ra_free(r, r->workers);
    ra_free(r, (void *)r->wbusy);
    if (r->beta) for (uint32_t m = 0; m < r->g->nmaterials; m++) ra_free(r, r->beta[m]);
    ra_free(r, r->beta);
    if (r->qi) for (uint32_t q = 0; q < r->g->nquads; q++) ra_free(r, r->qi[q].known);
    ra_free(r, r->mats); ra_free(r, r->fn_slevel); ra_free(r, r->fn_ang); ra_free(r, r->fn_spidx); ra_free(r, r->qi);
    ra_free(r, r->ang_list); ra_free(r, r->ang_start); ra_free(r, r->ang_full); ra_free(r, r->ang_perm);
    ra_free(r, r->E); ra_free(r, r->X); ra_free(r, r->Xprev); ra_free(r, r->X4); ra_free(r, r->cols); ra_free(r, r->tex); ra_free(r, r->texk); ra_free(r, r->tex_nonzero); ra_free(r, r->x_nonzero);
    ra_free(r, r->resynth); ra_free(r, r->recs); ra_free(r, r->qlevel); ra_free(r, r->cones);
    ra_free(r, r->synth_list);
    wrt_recon_destroy(r->recon); ra_free(r, r->stex); ra_free(r, r->regroup);
    ra_free(r, r->rin); ra_free(r, r->rknown); ra_free(r, r->rout);
    ra_free(r, r->kfn_slevel); ra_free(r, r->kfn_ang); ra_free(r, r->kfn_spidx);
    ra_free(r, r->kt_start); ra_free(r, r->kt);
    ra_free(r, r->k4_row); ra_free(r, r->k4_start); ra_free(r, r->k4_n); ra_free(r, r->k4_cols); ra_free(r, r->k4_vals);
    ra_free(r, r->C); ra_free(r, r->Y); ra_free(r, r->Y4); ra_free(r, r->Ep);
    ra_free(r, r);
}

/* ----------------------------------------------------------------- update ---- */

static int same_light(const wrt_light *a, const wrt_light *b) {
    return a->type == b->type && a->pos.x == b->pos.x && a->pos.y == b->pos.y && a->pos.z == b->pos.z &&
           a->dir.x == b->dir.x && a->dir.y == b->dir.y && a->dir.z == b->dir.z &&
           a->color[0] == b->color[0] && a->color[1] == b->color[1] && a->color[2] == b->color[2] &&
           a->intensity == b->intensity && a->range == b->range && a->inner_cone == b->inner_cone &&
           a->outer_cone == b->outer_cone;
}

wrt_status wrt_relight_set_lights(wrt_relight *r, const wrt_light *lights, const float *scales, int n) {
    if (n < 0) n = 0;
    if (n > r->lights_cap) {
        light_state *nl = ra_calloc(r, (size_t)n, sizeof(light_state));
        double **roots = ra_calloc(r, (size_t)n, sizeof(double *));
        float **kcs = ra_calloc(r, (size_t)n, sizeof(float *)); /* c over K's columns, if any */
        for (int i = r->lights_cap; i < n && !r->oom; i++) {
            roots[i] = ra_calloc(r, (size_t)r->g->nquads * 3 + 1, sizeof(double));
            if (r->g->nkcols) kcs[i] = ra_calloc(r, (size_t)r->g->nkcols * 3, sizeof(float));
        }
        if (r->oom) {
            r->oom = 0;
            if (roots) for (int i = r->lights_cap; i < n; i++) ra_free(r, roots[i]);
            if (kcs) for (int i = r->lights_cap; i < n; i++) ra_free(r, kcs[i]);
            ra_free(r, roots);
            ra_free(r, kcs);
            ra_free(r, nl);
            return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory for %d lights", n);
        }
        if (r->lights_cap) memcpy(nl, r->lights, (size_t)r->lights_cap * sizeof(light_state));
        for (int i = r->lights_cap; i < n; i++) { nl[i].root = roots[i]; nl[i].kc = kcs[i]; }
        ra_free(r, roots);
        ra_free(r, kcs);
        ra_free(r, r->lights);
        r->lights = nl;
        r->lights_cap = n;
    }
    if (n != r->nlights) r->e_dirty = 1;
    for (int i = 0; i < n; i++) {
        light_state *ls = &r->lights[i];
        float s = scales ? scales[i] : 1.0f;
        if (i >= r->nlights || !ls->projected || !same_light(&ls->light, &lights[i])) {
            ls->light = lights[i];
            ls->lc = light_consts(&ls->light);
            ls->projected = 0;
            r->e_dirty = 1;
        }
        if (i >= r->nlights || ls->scale != s) { ls->scale = s; r->e_dirty = 1; }
    }
    r->nlights = n;
    return WRT_OK;
}

void wrt_relight_set_eye(wrt_relight *r, const double eye[3]) {
    if (!r->have_eye || eye[0] != r->eye[0] || eye[1] != r->eye[1] || eye[2] != r->eye[2]) {
        r->eye[0] = eye[0]; r->eye[1] = eye[1]; r->eye[2] = eye[2];
        r->have_eye = 1;
        r->eye_dirty = 1;
    }
}

/* The final gather's direct irradiance: every light at x (colour, scale, shadow ray). */
static void gather_direct(void *user, wrt_v3 x, wrt_v3 n, double out[3]) {
    const wrt_relight *r = user;
    out[0] = out[1] = out[2] = 0;
    for (int i = 0; i < r->nlights; i++) {
        const light_state *ls = &r->lights[i];
        if (ls->scale == 0) continue;
        wrt_v3 dir;
        double d = 0, e = light_irradiance(&ls->lc, x, n, &dir, &d);
        if (e == 0) continue;
        if (!light_visible(r, x, n, dir, d)) continue;
        for (int c = 0; c < 3; c++) out[c] += ls->scale * ls->light.color[c] * e;
    }
}

/* Y = K c on the rows in fours (K by rows, r->k4_*): one load of c serves four rows. Each
 * row sums its even-numbered and its odd-numbered entries apart, then adds the two: the
 * same operations, in the same order, as the AVX version below, which runs an even and an
 * odd entry side by side (so Y is the same to the bit with or without AVX). */
static void k_fours(wrt_relight *r) {
    const float *C = r->C, *kv = r->k4_vals;
    const uint32_t *kc = r->k4_cols;
    for (uint32_t i = 0; i < r->nk4; i++) {
        float *y = r->Y4 + (size_t)r->k4_row[i] * 4;
        uint32_t b = r->k4_start[i], end = r->k4_start[i + 1];
#ifdef __SSE2__
        __m128 e0 = _mm_setzero_ps(), e1 = e0, e2 = e0, e3 = e0, o0 = e0, o1 = e0, o2 = e0, o3 = e0;
#define K_FOUR(a0, a1, a2, a3, bb) do { \
            __m128 cv_ = _mm_load_ps(C + (size_t)kc[bb] * 4), v_ = _mm_load_ps(kv + (size_t)(bb) * 4); \
            a0 = _mm_add_ps(a0, _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0x00))); \
            a1 = _mm_add_ps(a1, _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0x55))); \
            a2 = _mm_add_ps(a2, _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0xAA))); \
            a3 = _mm_add_ps(a3, _mm_mul_ps(cv_, _mm_shuffle_ps(v_, v_, 0xFF))); } while (0)
        for (; b + 2 <= end; b += 2) {
            K_FOUR(e0, e1, e2, e3, b);
            K_FOUR(o0, o1, o2, o3, b + 1);
        }
        if (b < end) K_FOUR(e0, e1, e2, e3, b);
        int n = r->k4_n[i]; /* 2 to 4 rows: the next group's rows follow */
        _mm_store_ps(y, _mm_add_ps(e0, o0)); _mm_store_ps(y + 4, _mm_add_ps(e1, o1));
        if (n > 2) _mm_store_ps(y + 8, _mm_add_ps(e2, o2));
        if (n > 3) _mm_store_ps(y + 12, _mm_add_ps(e3, o3));
#else
        float a[2][4][3] = {{{0}}};
        for (uint32_t n = 0; b < end; b++, n++)
            for (int k = 0; k < 4; k++)
                for (int c = 0; c < 3; c++) a[n & 1][k][c] += C[(size_t)kc[b] * 4 + c] * kv[(size_t)b * 4 + k];
        for (int k = 0; k < r->k4_n[i]; k++) for (int c = 0; c < 3; c++) y[k * 4 + c] = a[0][k][c] + a[1][k][c];
#endif
    }
}

#ifdef WRT_K_AVX
__attribute__((target("avx"))) static void k_fours_avx(wrt_relight *r) {
    const float *C = r->C, *kv = r->k4_vals;
    const uint32_t *kc = r->k4_cols;
    for (uint32_t i = 0; i < r->nk4; i++) {
        float *y = r->Y4 + (size_t)r->k4_row[i] * 4;
        uint32_t b = r->k4_start[i], end = r->k4_start[i + 1];
        __m256 a0 = _mm256_setzero_ps(), a1 = _mm256_setzero_ps(), a2 = _mm256_setzero_ps(), a3 = _mm256_setzero_ps();
        for (; b + 2 <= end; b += 2) { /* low half: entry b (even), high half: b + 1 (odd) */
            __m256 cv = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(C + (size_t)kc[b] * 4)),
                                             _mm_load_ps(C + (size_t)kc[b + 1] * 4), 1);
            __m256 v = _mm256_loadu_ps(kv + (size_t)b * 4);
            a0 = _mm256_add_ps(a0, _mm256_mul_ps(cv, _mm256_permute_ps(v, 0x00)));
            a1 = _mm256_add_ps(a1, _mm256_mul_ps(cv, _mm256_permute_ps(v, 0x55)));
            a2 = _mm256_add_ps(a2, _mm256_mul_ps(cv, _mm256_permute_ps(v, 0xAA)));
            a3 = _mm256_add_ps(a3, _mm256_mul_ps(cv, _mm256_permute_ps(v, 0xFF)));
        }
        __m128 e0 = _mm256_castps256_ps128(a0), e1 = _mm256_castps256_ps128(a1), e2 = _mm256_castps256_ps128(a2),
               e3 = _mm256_castps256_ps128(a3);
        if (b < end) K_FOUR(e0, e1, e2, e3, b); /* a last, even entry */
        int n = r->k4_n[i]; /* 2 to 4 rows: the next group's rows follow */
        _mm_store_ps(y, _mm_add_ps(e0, _mm256_extractf128_ps(a0, 1)));
        _mm_store_ps(y + 4, _mm_add_ps(e1, _mm256_extractf128_ps(a1, 1)));
        if (n > 2) _mm_store_ps(y + 8, _mm_add_ps(e2, _mm256_extractf128_ps(a2, 1)));
        if (n > 3) _mm_store_ps(y + 12, _mm_add_ps(e3, _mm256_extractf128_ps(a3, 1)));
    }
}
#endif

/* The first glossy bounce (K-SPEC): c = the sum over lights of their scaled projections
 * onto K's columns (cached per light, as E's), Y = K c (one channel K, RGB c; rows summed
 * in column order), and E' = E with every function of a quad that has K columns set to 0
 * (its direct light reaches the others through Y instead), plus Y. The multiply then
 * gives X = Op E' + Y. */
static void first_bounce(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nk = g->nkcols, nf = g->nfuncs;
    memset(r->C, 0, (size_t)nk * 4 * sizeof(float));
    for (int i = 0; i < r->nlights; i++) {
        const light_state *ls = &r->lights[i];
        if (ls->scale == 0 || !ls->projected) continue;
        for (size_t j = 0; j < nk; j++)
            for (int c = 0; c < 3; c++) r->C[j * 4 + c] += ls->scale * ls->kc[j * 3 + c];
    }
    const uint32_t *ks = r->kt_start;
    const kt_entry *kt = r->kt;
    const float *C = r->C;
    for (uint32_t f = 0; f < nf; f++) { /* Y = K c, row by row, two partial sums */
        uint32_t e = ks[f], end = ks[f + 1];
        float *y = r->Y4 + (size_t)f * 4;
#ifdef __SSE2__
        __m128 s0 = _mm_setzero_ps(), s1 = _mm_setzero_ps();
        for (; e + 2 <= end; e += 2) {
            s0 = _mm_add_ps(s0, _mm_mul_ps(_mm_load_ps(C + (size_t)kt[e].col * 4), _mm_set1_ps(kt[e].val)));
            s1 = _mm_add_ps(s1, _mm_mul_ps(_mm_load_ps(C + (size_t)kt[e + 1].col * 4), _mm_set1_ps(kt[e + 1].val)));
        }
        if (e < end) s0 = _mm_add_ps(s0, _mm_mul_ps(_mm_load_ps(C + (size_t)kt[e].col * 4), _mm_set1_ps(kt[e].val)));
        _mm_store_ps(y, _mm_add_ps(s0, s1));
#else
        float s0[3] = {0, 0, 0}, s1[3] = {0, 0, 0};
        for (; e + 2 <= end; e += 2)
            for (int c = 0; c < 3; c++) {
                s0[c] += C[(size_t)kt[e].col * 4 + c] * kt[e].val;
                s1[c] += C[(size_t)kt[e + 1].col * 4 + c] * kt[e + 1].val;
            }
        if (e < end) for (int c = 0; c < 3; c++) s0[c] += C[(size_t)kt[e].col * 4 + c] * kt[e].val;
        for (int c = 0; c < 3; c++) y[c] = s0[c] + s1[c];
#endif
    }
#ifdef WRT_K_AVX
    if (r->k_avx) k_fours_avx(r);
    else
#endif
        k_fours(r);
    memcpy(r->Ep, r->E, (size_t)nf * 3 * sizeof(float));
    for (uint32_t q = 0; q < g->nquads; q++)
        if (r->qi[q].kcount)
            memset(r->Ep + (size_t)g->quads[q].func_first * 3, 0, (size_t)g->quads[q].func_count * 3 * sizeof(float));
    for (size_t f = 0; f < nf; f++)
        for (int c = 0; c < 3; c++) {
            r->Y[f * 3 + c] = r->Y4[f * 4 + c];
            r->Ep[f * 3 + c] += r->Y4[f * 4 + c];
        }
}

/* An update that ran out of memory: -1 with a message (on the caller's thread); lights
 * not projected stay so, and textures are redone at the next update. */
static int update_nomem(wrt_relight *r, const char *stage, wrt_relight_timings *tm, const wrt_relight_timings *t) {
    r->redo_all = 1;
    if (tm) *tm = *t;
    wrt_fail(WRT_ERR_NOMEM, "relight: out of memory while %s (update abandoned; the next update redoes it)", stage);
    return -1;
}

int wrt_relight_update(wrt_relight *r, wrt_relight_timings *tm) {
    wrt_relight_timings t = {0};
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads, nf = g->nfuncs;
    int nchanged = 0;
    double t0 = wrt_now();
    atomic_store(&r->upd_oom, 0);
    for (int i = 0; i < r->nlights; i++) {
        light_state *ls = &r->lights[i];
        if (ls->projected || ls->scale == 0) continue;
        if (project_light(r, ls) != 0) return update_nomem(r, "projecting a light", tm, &t);
        t.lights_changed++;
    }
    double t1 = wrt_now();
    t.projection = (t1 - t0) * 1e3;
    memset(r->resynth, 0, nq);
    int lights_dirty = r->e_dirty || r->redo_all, eye_moved = r->eye_dirty || r->redo_all;
    if (r->redo_all) { /* the last update failed part way: every texture again */
        memset(r->resynth, 1, nq);
        memset(r->tex_nonzero, 1, nq); /* dark quads: cleared again */
    }
    if (r->e_dirty) {
        r->e_dirty = 0;
        /* E = sum of scaled per-light projections, in light order. */
        memset(r->E, 0, (size_t)nf * 3 * sizeof(float));
        for (int i = 0; i < r->nlights; i++) {
            const light_state *ls = &r->lights[i];
            if (ls->scale == 0 || !ls->projected) continue;
            for (size_t k = 0; k < ls->n; k++)
                for (int c = 0; c < 3; c++) r->E[(size_t)ls->idx[k] * 3 + c] += ls->scale * ls->val[k * 3 + c];
        }
        /* With K: the first bounce from its quads, Y = K c, and E' = E off them + Y. */
        const float *src = r->E;
        if (g->nkcols) { first_bounce(r); src = r->Ep; }
        /* X = Op E over the non-zero sources only, in column order for every row. */
        uint32_t ncols = 0;
        double entries = 0;
        for (uint32_t c = 0; c < nf; c++) {
            const float *e = src + (size_t)c * 3;
            if (e[0] == 0 && e[1] == 0 && e[2] == 0) continue;
            r->cols[ncols++] = c;
            entries += (double)(r->op.col_start[c + 1] - r->op.col_start[c]);
        }
        mul_ctx mc = {r->cols, ncols, 0, src};
        /* Bound by memory: threads that stream halves of the same columns were measured
         * slower than one on 2 cores (maze 4.2 vs 2.8 ms, glossy 14 vs 11 ms). */
        int nchunk = entries > MUL_PARALLEL_ENTRIES ? r->nthreads : 1;
        if (nchunk > MUL_MAX_CHUNKS) nchunk = MUL_MAX_CHUNKS;
        mc.nchunk = nchunk;
        parallel_for(r, nchunk, 1e9, mul_chunk, &mc);
        memcpy(r->Xprev, r->X, (size_t)nf * 3 * sizeof(float)); /* X keeps its address */
        for (size_t f = 0; f < nf; f++)
            for (int c = 0; c < 3; c++) r->X[f * 3 + c] = r->X4[f * 4 + c];
        if (g->nkcols) /* X = Op E' + Y, on the rows the multiply computes (all but a glossy
                        * quad's angular rows when the final gather displays it) */
            for (size_t f = 0; f < nf; f++)
                if (!r->op_own[0] || r->fn_ang[f] == 0)
                    for (int c = 0; c < 3; c++) r->X[f * 3 + c] += r->Y[f * 3 + c];
        for (uint32_t q = 0; q < nq; q++) {
            const wrt_gto_quad *gq = &g->quads[q];
            size_t a = (size_t)gq->func_first * 3, n = (size_t)gq->func_count * 3;
            if (memcmp(r->X + a, r->Xprev + a, n * sizeof(float)) != 0) r->resynth[q] = 1;
            int nz = 0;
            for (size_t k = a; k < a + n && !nz; k++) nz = r->X[k] != 0;
            r->x_nonzero[q] = (uint8_t)nz;
        }
    }
    double t2 = wrt_now();
    t.multiply = (t2 - t1) * 1e3;
    if (r->eye_dirty) {
        r->eye_dirty = 0;
        for (uint32_t q = 0; q < nq; q++)
            if (r->qi[q].glossy && r->x_nonzero[q]) r->resynth[q] = 1;
    }
    int *list = r->synth_list;
    int nsynth = 0, ncleared = 0;
    for (uint32_t q = 0; q < nq; q++) {
        if (!r->resynth[q]) continue;
        if (!r->x_nonzero[q]) { /* all dark: clear once */
            if (r->tex_nonzero[q]) {
                memset(r->tex + r->qi[q].tex_off, 0, ((size_t)1 << (2 * r->qi[q].tex_level)) * 3 * sizeof(float));
                r->tex_nonzero[q] = 0;
                ncleared++;
                if (r->recon) r->regroup[wrt_recon_group(r->recon, (int)q)] = 1;
            }
            continue;
        }
        if (r->qi[q].glossy && !r->have_eye) continue; /* no view yet: waits for set_eye */
        if (r->qi[q].glossy && r->gather) continue;    /* drawn by the final gather below */
        r->tex_nonzero[q] = 1;
        list[nsynth++] = (int)q;
        if (r->recon) r->regroup[wrt_recon_group(r->recon, (int)q)] = 1;
    }
    for (int tt = 0; tt < r->nthreads; tt++) r->workers[tt].brdf_time = 0;
    synth_ctx sc = {list};
    double t3 = wrt_now();
    double work = 0;
    for (int k = 0; k < nsynth; k++) {
        const quad_info *qi = &r->qi[list[k]];
        work += ldexp(qi->glossy ? 0.3 * qi->nang : 0.015, 2 * qi->tex_level); /* ~3 ns a diffuse texel */
    }
    parallel_for(r, nsynth, work, synth_item, &sc);
    if (atomic_load(&r->upd_oom)) return update_nomem(r, "synthesizing textures", tm, &t);
    double t4 = wrt_now(), bt = 0;
    for (int tt = 0; tt < r->nthreads; tt++) bt += r->workers[tt].brdf_time;
    int used = r->nthreads < nsynth ? r->nthreads : (nsynth ? nsynth : 1);
    t.brdf = bt / used * 1e3;
    t.synthesis = (t4 - t3) * 1e3 - t.brdf;
    if (t.synthesis < 0) t.synthesis = 0;
    nchanged = nsynth + ncleared;
    if (r->recon) { /* smooth display of every group that changed (reconstruct.h) */
        int ng = wrt_recon_ngroups(r->recon), nre = 0;
        double rwork = 0;
        nchanged = 0;
        for (int gr = 0; gr < ng; gr++) {
            if (!r->regroup[gr]) continue;
            r->regroup[gr] = 0;
            int nm;
            const int *mem = wrt_recon_members(r->recon, gr, &nm);
            list[nre++] = gr;
            nchanged += nm;
            rwork += 0.15 * nm * ldexp(1.0, 2 * r->qi[mem[0]].stex_level); /* ~30 ns a texel */
        }
        recon_ctx rcx = {list};
        parallel_for(r, nre, rwork, recon_item, &rcx);
        if (atomic_load(&r->upd_oom)) return update_nomem(r, "smoothing textures", tm, &t);
        t.reconstruction = (wrt_now() - t4) * 1e3;
        t.synthesis += t.reconstruction;
    }
    if (lights_dirty) r->glin_dirty = 1;
    if (r->gather && r->have_eye && (r->glin_dirty || eye_moved)) { /* gather.h */
        double t5 = wrt_now();
        if (r->glin_dirty) {
            /* A glossy quad seen by a gather ray sends its mean albedo / pi times its
             * indirect irradiance (its angular-root functions): exact for uniform
             * incident light, a diffuse approximation of its lobe otherwise. */
            for (uint32_t q = 0; q < nq; q++)
                if (r->gdiff[q]) synth_diffuse(r, &r->workers[0], (int)q, r->galb[r->qi[q].material], r->gdiff[q]);
            if (atomic_load(&r->upd_oom)) return update_nomem(r, "gathering glossy light", tm, &t);
            wrt_gather_lights(r->gather, gather_direct, r, r->gtex, r->gires);
        }
        r->glin_dirty = 0;
        wrt_gather_eye(r->gather, r->eye, r->gout, r->gres);
        for (uint32_t q = 0; q < nq; q++) nchanged += r->qi[q].glossy;
        t.synthesis += (wrt_now() - t5) * 1e3;
    }
    t.quads_resynthesized = nchanged;
    r->redo_all = 0;
    if (tm) *tm = t;
    return nchanged;
}

/* ------------------------------------------------------------- accessors ---- */

int wrt_relight_tex_res(const wrt_relight *r, int q) {
    if (q < 0 || q >= (int)r->g->nquads) return 0;
    return 1 << (r->recon ? r->qi[q].stex_level : r->qi[q].tex_level);
}

const float *wrt_relight_tex(const wrt_relight *r, int q) {
    if (q < 0 || q >= (int)r->g->nquads) return NULL;
    return r->recon ? r->stex + r->qi[q].stex_off : r->tex + r->qi[q].tex_off;
}

void wrt_relight_quad_irradiance(const wrt_relight *r, int q, double direct[3], double indirect[3]) {
    for (int c = 0; c < 3; c++) direct[c] = indirect[c] = 0;
    if (q < 0 || q >= (int)r->g->nquads) return;
    const quad_info *qi = &r->qi[q];
    for (int i = 0; i < r->nlights; i++) {
        const light_state *ls = &r->lights[i];
        if (!ls->projected || ls->scale == 0) continue;
        for (int c = 0; c < 3; c++) direct[c] += ls->scale * ls->root[q * 3 + c] * qi->mean_factor;
    }
    if (qi->root_func >= 0)
        for (int c = 0; c < 3; c++) indirect[c] = r->X[(size_t)qi->root_func * 3 + c] * qi->mean_factor;
}

const float *wrt_relight_E(const wrt_relight *r) { return r->E; }
const float *wrt_relight_Y(const wrt_relight *r) { return r->Y; }
const float *wrt_relight_X(const wrt_relight *r) { return r->X; }

double wrt_relight_bench(wrt_relight *r, int updates, wrt_relight_timings *mean) {
    wrt_relight_timings sum = {0};
    if (mean) *mean = sum;
    if (r->nlights == 0 || updates <= 0) return -1;
    wrt_light *ls = ra_calloc(r, (size_t)r->nlights, sizeof(wrt_light));
    float *sc = ra_calloc(r, (size_t)r->nlights, sizeof(float));
    if (r->oom) { r->oom = 0; ra_free(r, ls); ra_free(r, sc); return -1; }
    for (int i = 0; i < r->nlights; i++) { ls[i] = r->lights[i].light; sc[i] = r->lights[i].scale; }
    wrt_v3 p0 = ls[0].pos;
    double rad = 0.02 * r->scene_diag, t0 = wrt_now();
    for (int k = 0; k < updates; k++) {
        double a = 2 * WRT_PI * (k + 1) / updates;
        ls[0].pos = v3(p0.x + rad * cos(a), p0.y, p0.z + rad * sin(a));
        wrt_relight_set_lights(r, ls, sc, r->nlights);
        wrt_relight_timings t;
        if (wrt_relight_update(r, &t) < 0) { ra_free(r, ls); ra_free(r, sc); return -1; }
        sum.projection += t.projection; sum.multiply += t.multiply;
        sum.brdf += t.brdf; sum.synthesis += t.synthesis; sum.reconstruction += t.reconstruction;
        sum.quads_resynthesized += t.quads_resynthesized; sum.lights_changed += t.lights_changed;
    }
    double ms = (wrt_now() - t0) * 1e3 / updates;
    ls[0].pos = p0;
    wrt_relight_set_lights(r, ls, sc, r->nlights);
    wrt_relight_update(r, NULL);
    if (mean) {
        mean->projection = sum.projection / updates; mean->multiply = sum.multiply / updates;
        mean->brdf = sum.brdf / updates; mean->synthesis = sum.synthesis / updates;
        mean->reconstruction = sum.reconstruction / updates;
        mean->quads_resynthesized = sum.quads_resynthesized / updates;
        mean->lights_changed = sum.lights_changed / updates;
    }
    ra_free(r, ls); ra_free(r, sc);
    return ms;
}
