/* relight_internal.h: what the relighter's files share (player/relight*.c), not for its
 * callers (they include relight.h). The relighter's state (struct wrt_relight), grouped
 * by the part that owns it, the per-quad and per-light records, each worker thread's
 * scratch, and the calls that cross files: the parallel loop and the allocator
 * (relight_base.c), the projection (relight_project.c, paper section 5.1), the multiply
 * (relight_multiply.c, 5.2), the first glossy bounce K (relight_bounce.c), the synthesis
 * (relight_synth.c, 5.3-5.4), the smooth display (relight_smooth.c), the final gather's
 * glue (relight_gather.c) and creation (relight_create.c); relight.c drives an update.
 * docs/algorithm.md is the algorithm they implement. Depends on formats/gto.h,
 * common/basis.h, common/brdf_table.h, common/threads.h, Embree 3. */
#ifndef WRT_RELIGHT_INTERNAL_H
#define WRT_RELIGHT_INTERNAL_H

#include "../common/cluster_tree.h"
#include "relight.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <string.h>

#include "../common/basis.h"
#include "../common/brdf.h"
#include "../common/brdf_table.h"
#include "../common/reconstruct.h"
#include "../common/threads.h"
#include "gather.h"

#if defined(__x86_64__) && defined(__GNUC__)
#define WRT_K_AVX 1 /* Y = K c's rows in fours with AVX where the processor has it */
#endif

#define PROJ_MAX_LEVEL 6     /* finest projection grid: 64 x 64 cells per quad */
#define PROJ_MIN_LEVEL 3     /* every quad is sampled on at least 8 x 8 cells (if it has them) */
#define PROJ_MIN_LEVEL_DIFFUSE 2 /* a quad without angular functions or K columns: 4 x 4 */
#define ANG_LEVELS 4         /* angular node levels 0..3 (basis.h: 2 bits of level) */
#define NANG 256             /* angular functions over node levels 0..3: 4^ANG_LEVELS */
#define BETA_RES WRT_BRDF_TABLE_RES /* beta table: common/brdf_table.h, shared with the bake */
#define FN_INVALID 255       /* fn_slevel of a key that is not a basis function */
#define WRT_RELIGHT_SUM_MAX 8 /* rl_mul.per_light: lights that keep their own product, at most */

/* Cells of levels 0..l-1 of a quadtree: the offset of level l in per-level arrays. */
#define LEVEL_OFF(l) ((((size_t)1 << (2 * (l))) - 1) / 3)
#define PROJ_TREE_CELLS LEVEL_OFF(PROJ_MAX_LEVEL + 1)

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
    int sun;                        /* directional: light along dir, no position, no falloff */
} light_c;

typedef struct light_state {
    wrt_light light;
    light_c lc;                     /* light_consts(&light), for the gather's direct light */
    float scale;
    int projected;                  /* E below is the projection of `light` */
    int have_proj;                  /* E below is a whole projection, maybe of the light's
                                     * last position (a budgeted update sums it while the
                                     * new one waits: a consistent, older E) */
    uint32_t *idx; float *val;      /* sparse E at scale 1: function index, RGB */
    size_t n, cap;
    float *kc;                      /* c over K's columns at scale 1, RGB (NULL without K) */
    double *root;                   /* nquads x 3: projected (root, root) coefficient */
    double last_work;               /* its last projection's work (samples and rays, in
                                     * parallel_for's units): an estimate of the next one's */
    float *X4;                      /* Op of its E at scale 1, 4 floats a function (NULL
                                     * unless rl_mul.per_light) */
    uint64_t proj_gen, x_gen;       /* whole projections made; the one X4 is the Op of */
} light_state;

/* One worker thread's scratch: grown on demand during updates, kept between them. */
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
    double *pflux; size_t pflux_cap; /* non-parallelograms: each cell's sampled flux */
    float *rbuf;                    /* the smooth display's scratch (made at creation, the
                                     * largest group's: an update allocates nothing) */
    double brdf_time;
    long nsamples;                  /* samples and shadow rays of the projection */
    long long noccs;                /* occluders found by the projection (all its quads) */
} worker;

typedef struct out_rec { int worker; size_t start, count; } out_rec;

/* A quad's bounding sphere seen from a light: unit direction to its centre, the cosine
 * and sine of its angular radius (cos = -1: the light is inside), distance range. */
typedef struct light_cone { wrt_v3 u; double cosa, sina, dmin, dmax; } light_cone;

/* An entry of the first-bounce operator K by rows: column and value, read together. */
typedef struct kt_entry { uint32_t col; float val; } kt_entry;

/* The operator the multiply reads: the file's, or (with the final gather) a copy of the
 * entries whose receiver is displayed (own). */
typedef struct op_view {
    const uint64_t *col_start; /* nfuncs + 1 */
    const uint32_t *rows;      /* NULL: the compact entries below */
    const float *vals;         /* nnz x 3 */
    uint64_t nnz;
    /* The compact operator (versions 2.0 and 3.0; wrt_gto's op_*), used when rows is NULL:
     * a block starts at each entry whose delta is 0 (its row row0, its base base). */
    const uint32_t *bcol;
    const uint32_t *row0;
    const int8_t *base;
    const uint32_t *codes;
    const uint8_t *deltas;
} op_view;

/* Embree: every quad, in a frame centred on the scene (float precision). */
typedef struct rl_rays {
    RTCDevice dev; RTCScene scene;
    wrt_v3 origin; double eps, scene_diag;
    int ray4;                       /* the device traces 4-ray packets (rtcOccluded4) */
} rl_rays;

/* The projection's per-light scratch (relight_project.c). */
/* A node of the tree over the quads' bounding spheres (relight_occ.c): its sphere holds
 * the spheres of its quads, occ_order[first, first + count) on a leaf; an inner node's
 * children are the next node and `right`. */
typedef struct occ_node { wrt_v3 c; double rad; uint32_t first, count, right; } occ_node;

typedef struct rl_proj {
    int8_t *qlevel;                 /* projection level per quad for the light in progress */
    light_cone *cones;              /* per quad, as seen from the light in progress */
    occ_node *onode; uint32_t nonode; /* the occluder search's tree (made at creation) */
    uint32_t *oorder;               /* its leaves' quads */
    light_cone *ocones;             /* per node, as seen from the light in progress */
    out_rec *recs;                  /* per quad: where its coefficients are in which worker */
    double size;                    /* per light: bounds the distances in the culling tests */
} rl_proj;

/* The multiply (relight_multiply.c): the operator it streams and its scratch. */
typedef struct rl_mul {
    op_view op;
    void *own[5];                   /* op's arrays when they are the relighter's copy */
    float *X4;                      /* X being summed: 4 floats a function (RGB, unused) */
    uint32_t *cols;                 /* non-zero columns of E */
    int per_light;                  /* X = sum of scale x each light's X4 (no K, no emitters):
                                     * a light change multiplies the lights that moved only */
    float *Ed;                      /* per_light: one light's E, dense (nfuncs x 3) */
} rl_mul;

/* The first-bounce operator K (g->nkcols > 0; relight_bounce.c). */
typedef struct rl_bounce {
    uint8_t *fn_slevel, *fn_ang;    /* per K column: spatial level, angular index */
    uint32_t *fn_spidx;             /* per K column: spatial pyramid slot */
    float *C;                       /* c summed over the lights: nkcols x 4 (RGB, unused) */
    uint32_t *kt_start;             /* K by rows (its transpose, columns ascending in a row): */
    kt_entry *kt;                   /* row f is entries [kt_start[f], kt_start[f + 1]), except */
    uint32_t nk4, *k4_row, *k4_start; /* rows in fours (below): the k4_n[i] rows from */
    uint8_t *k4_n;                  /* k4_row[i] are entries [k4_start[i], k4_start[i + 1]) of */
    uint32_t *k4_cols; float *k4_vals; /* k4_cols, with 4 values each in k4_vals (0 where a
                                    * row has none, and for rows past k4_n[i]), scaled by
                                    * 2^-k4_exp[i] and rounded to half precision; with F16C
                                    * the halves k4_h instead (k4_vals NULL) */
    uint16_t *k4_h;
    uint16_t *k4_c16;               /* k4_cols in 16 bits where K has at most 65,536 columns
                                    * (k4_cols NULL then) */
    int16_t *k4_exp;
    int f16c;                       /* the fours' values read as halves (AVX and F16C) */
    float *Y;                       /* Y = K c: nfuncs x 3 */
    float *Y4;                      /* Y being summed: 4 floats a function (RGB, unused) */
    int avx;                        /* the processor has AVX (Y's rows in fours with it) */
    float *Ep;                      /* E' = E off the quads with K columns, + Y: nfuncs x 3 */
} rl_bounce;

/* The smooth display (reconstruct.h; relight_smooth.c): NULL recon with haar_blocks. */
typedef struct rl_smooth {
    wrt_recon *recon;
    float *stex;                    /* the smooth textures */
    uint8_t *regroup;               /* per group: reconstruct at this update */
    const float **rin;              /* per quad, for wrt_recon_run (groups are disjoint) */
    const uint8_t **rknown;
    float **rout;
} rl_smooth;

/* The final gather on glossy quads (gather.h; relight_gather.c): NULL gather: none. */
typedef struct rl_gather {
    wrt_gather *gather;
    const float **tex; float **out; int *res; /* per quad: displayed texture, side */
    int *ires;                      /* per quad: side of tex (a glossy quad's: diff) */
    float **diff;                   /* per glossy quad: albedo/pi x indirect irradiance */
    float (*alb)[3];                /* per material: mean directional albedo (glossy) */
    int lin_dirty;                  /* the gather's incident light waits for an update */
} rl_gather;

struct wrt_relight {
    const wrt_gto *g;
    wrt_relight_options opt;
    int nthreads, max_tex_level;
    quad_info *qi;
    wrt_material *mats;
    float **beta;                   /* per material: [BETA_RES^2][NANG][3], NULL if unused */
    /* per function */
    uint8_t *fn_slevel, *fn_ang;
    uint32_t *fn_spidx;
    float *fn_flux;                 /* flux of the function's unit coefficient, sqrt(pi) int
                                     * h sqrt(J): angular roots of non-parallelograms, else 0 */
    uint32_t *ang_perm;             /* functions of each quad grouped by angular index */
    uint16_t *ang_list;             /* present angular indices per quad (qi.ang_first) */
    uint32_t *ang_start;            /* for each (quad, present angular): range in ang_perm, +1 */
    uint8_t *ang_full;              /* for each (quad, present angular): fills the pyramid */
    rl_rays rt;
    /* state */
    light_state *lights; int nlights, lights_cap;
    int e_dirty, eye_dirty, have_eye;
    double eye[3];
    float *E, *X, *Xprev;
    /* The cluster tree of a `--clusters` file (relight_cluster.c): the operator's quad
     * root slots hold the tree's functions; E is taken there (Et) before the multiply and
     * X back after it. on 0: none. */
    struct { int on, inv; wrt_ctree t; uint32_t *root; float *Et; double *scratch; } ct; /* inv: the result back too */
    float *Eapplied;                /* skip_below > 0: the E of the last multiply */
    /* The time budget (options.budget_ms; relight.c): the current call's deadline and
     * whether it did a unit yet, what waits for a later call, and the work counters. */
    struct {
        double deadline; int did;
        int synth_pending, smooth_pending; /* quads still marked in resynth, groups in regroup */
        int gl_lights, gl_eye;             /* the final gather's inputs moved since it last ran */
        int resume;                        /* the stage the next budgeted call starts with */
        int next_light;                    /* the light the projection starts with */
        wrt_relight_counters n;
    } run;
    int e_applied;                  /* 1 once Eapplied holds one */
    float *tex; uint8_t *tex_nonzero, *x_nonzero, *resynth;
    float *texk;                    /* per texel of non-parallelograms: 2^Lt sqrt(pi/J)/pi */
    int *synth_list;                /* nquads + 1: quads to synthesize this update */
    /* threads and memory */
    worker *workers;
    _Atomic unsigned char *wbusy;   /* job hook: worker slots in use (nthreads) */
    wrt_pool *pool;                 /* nthreads threads, parked between loops (NULL with a hook) */
    int oom;                        /* an allocation failed */
    atomic_int upd_oom;             /* an allocation of the update's scratch failed */
    int redo_all;                   /* an update failed part way: the next one redoes every quad */
    double prog_last;               /* creation: the last fraction given to options.progress */
    /* the parts */
    rl_proj proj;
    rl_mul mul;
    rl_bounce k;
    rl_smooth sm;
    rl_gather gat;
    float *emit_scale;              /* per material: its emission's scale (relight_emit.c) */
    int nemitters;                  /* emissive materials used by some quad */
};

/* ------------------------------------------------- shared small functions ---- */

/* Index of a 2D Haar function in a quadtree pyramid: 0 the root scaling function, then
 * level by level, node by node (row-major), the three wavelets. Levels < L use 4^L slots. */
static inline uint32_t haar_index(int level, int x, int y, int type) {
    if (type == 0) return 0;
    uint32_t before = ((1u << (2 * level)) - 1) / 3;
    return 1 + 3 * (before + (uint32_t)y * (1u << level) + (uint32_t)x) + (uint32_t)(type - 1);
}

static inline wrt_v3 quad_point(const quad_info *q, double u, double v) {
    double w0 = (1 - u) * (1 - v), w1 = u * (1 - v), w2 = u * v, w3 = (1 - u) * v;
    return v3(w0 * q->p[0].x + w1 * q->p[1].x + w2 * q->p[2].x + w3 * q->p[3].x,
              w0 * q->p[0].y + w1 * q->p[1].y + w2 * q->p[2].y + w3 * q->p[3].y,
              w0 * q->p[0].z + w1 * q->p[1].z + w2 * q->p[2].z + w3 * q->p[3].z);
}

static inline double quad_jacobian(const quad_info *q, double u, double v) {
    if (q->parallelogram) return q->area;
    wrt_v3 du = v3_add(v3_scale(v3_sub(q->p[1], q->p[0]), 1 - v), v3_scale(v3_sub(q->p[2], q->p[3]), v));
    wrt_v3 dv = v3_add(v3_scale(v3_sub(q->p[3], q->p[0]), 1 - u), v3_scale(v3_sub(q->p[2], q->p[1]), u));
    return v3_len(v3_cross(du, dv));
}

/* Direct irradiance (without colour) from light l at x with unit normal n, and the
 * unit direction toward the light; 0 if none arrives (visibility excluded). A sun gives
 * intensity x cos toward -dir at distance +inf (its shadow ray leaves the scene). */
static inline double light_irradiance(const light_c *l, wrt_v3 x, wrt_v3 n, wrt_v3 *w, double *dist) {
    if (l->sun) {
        double cosx = -v3_dot(l->dir, n);
        if (cosx <= 0) return 0;
        *w = v3_scale(l->dir, -1);
        *dist = INFINITY;
        return l->intensity * cosx;
    }
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

/* 1 if nothing blocks the shadow ray from just above x (unit normal n) along the unit
 * direction dir toward a light at distance d (+inf for a sun: the ray must escape the
 * scene); Embree sets tfar to -inf on a hit. */
static inline int light_visible(const wrt_relight *r, wrt_v3 x, wrt_v3 n, wrt_v3 dir, double d) {
    wrt_v3 o = v3_sub(v3_mad(x, n, r->rt.eps), r->rt.origin);
    struct RTCRay ray;
    ray.org_x = (float)o.x; ray.org_y = (float)o.y; ray.org_z = (float)o.z;
    ray.dir_x = (float)dir.x; ray.dir_y = (float)dir.y; ray.dir_z = (float)dir.z;
    ray.tnear = 0;
    ray.tfar = (float)(d - 2 * r->rt.eps);
    ray.time = 0; ray.mask = 0xFFFFFFFFu; ray.id = 0; ray.flags = 0;
    if (!(ray.tfar > 0)) return 1;
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    rtcOccluded1(r->rt.scene, &ic, &ray);
    return !(ray.tfar < 0);
}

/* light_visible for up to 4 rays at once (Embree's 4-wide packet, when the device has
 * it: rtcOccluded4; else one at a time): ray k (k < n) only where need[k]; vis[k] 1 if
 * nothing blocks it (as light_visible), 1 too where not needed. */
static inline void light_visible4(const wrt_relight *r, int n, const wrt_v3 *x, wrt_v3 nrm, const wrt_v3 *dir,
                                  const double *d, const int *need, int *vis) {
    if (!r->rt.ray4) {
        for (int k = 0; k < n; k++) vis[k] = !need[k] || light_visible(r, x[k], nrm, dir[k], d[k]);
        return;
    }
    struct RTCRay4 ray;
    _Alignas(16) int valid[4];
    int any = 0;
    for (int k = 0; k < 4; k++) {
        valid[k] = 0;
        vis[k] = 1;
        if (k >= n || !need[k]) continue; /* a lane not valid is not read */
        ray.tnear[k] = 0; ray.time[k] = 0; ray.mask[k] = 0xFFFFFFFFu; ray.id[k] = 0; ray.flags[k] = 0;
        wrt_v3 o = v3_sub(v3_mad(x[k], nrm, r->rt.eps), r->rt.origin);
        ray.org_x[k] = (float)o.x; ray.org_y[k] = (float)o.y; ray.org_z[k] = (float)o.z;
        ray.dir_x[k] = (float)dir[k].x; ray.dir_y[k] = (float)dir[k].y; ray.dir_z[k] = (float)dir[k].z;
        ray.tfar[k] = (float)(d[k] - 2 * r->rt.eps);
        if (!(ray.tfar[k] > 0)) continue; /* as light_visible: visible */
        valid[k] = -1;
        any = 1;
    }
    if (!any) return;
    struct RTCIntersectContext ic;
    rtcInitIntersectContext(&ic);
    rtcOccluded4(valid, r->rt.scene, &ic, &ray);
    for (int k = 0; k < 4; k++)
        if (valid[k]) vis[k] = !(ray.tfar[k] < 0);
}

/* Whether an update may start another unit of work (relight.c): always without a budget
 * and for the first unit of a call (every call makes progress), else while the budget
 * lasts. */
int relight_budget_left(wrt_relight *r);
/* Units of a budgeted stage: items per slice of the synthesis or the smoothing. */
#define RELIGHT_SLICE 16

/* ------------------------------------------------------ relight_emit.c ---- */

/* The emitters' scales (all 1) and the warnings on what cannot be carried; sets e_dirty
 * when some quad emits. Runs after the quads are made. */
wrt_status relight_setup_emitters(wrt_relight *r);
/* E += the emitting quads' source terms (docs/emitters.md), scaled. */
void relight_add_emitters(wrt_relight *r);

/* ------------------------------------------------------ relight_base.c ---- */

/* Creation's progress (options.progress): reports `fraction` (raised to the last one
 * reported, so that it never falls); 0 if the caller cancels. No callback: 1. */
int relight_progress(wrt_relight *r, double fraction);
/* Where the creation's long stages lie in its progress: the BRDF tables from
 * PROGRESS_TABLES to PROGRESS_GATHER, the final gather's tables and rays from there to 1
 * (the shares of the glossy asset's open time, measured on 2 cores: README). */
#define PROGRESS_TABLES 0.02
#define PROGRESS_GATHER 0.33

/* A parallel loop's item: fn(r, the worker whose scratch it may use, item, ctx). */
typedef void (*job_fn)(wrt_relight *r, worker *w, int item, void *ctx);
/* Runs fn over items 0..n-1 on up to nthreads threads (one if `work` is small, in units
 * of about one shadow ray; with a job hook, every loop of 2 items or more goes to the
 * hook); returns the number of threads used. Results must not depend on which worker ran
 * an item (callers write per item, or merge per item in item order). */
int relight_parallel_for(wrt_relight *r, int n, double work, job_fn fn, void *ctx);

/* The caller's allocator (options.alloc/free; malloc/free by default): zeroed blocks; a
 * failure sets r->oom and returns NULL. */
void *relight_calloc(wrt_relight *r, size_t count, size_t size);
void relight_free(const wrt_relight *r, void *p);
/* Scratch of at least `need` elements: p itself if it holds them, else a larger block
 * (the first `keep` elements copied, p freed, *cap updated). NULL if there is no memory:
 * p and *cap are left as they were and r->upd_oom is set. Called from worker threads. */
void *relight_grow_keep(wrt_relight *r, void *p, size_t *cap, size_t need, size_t elem, size_t keep);
void *relight_grow(wrt_relight *r, void *p, size_t *cap, size_t need, size_t elem);
#define GROW(r, ptr, cap, need) /* grows w->ptr, or returns (void) from the caller */ \
    do { void *np_ = relight_grow(r, ptr, &(cap), need, sizeof *(ptr)); if (!np_) return; ptr = np_; } while (0)

/* Messages: the caller's log callback (options.log), else wrt_log. */
void relight_log(const wrt_relight *r, int level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

double relight_quad_dist(const quad_info *q, wrt_v3 p);
/* relight_occ.c: the tree over the quads' bounding spheres (0, or -1 without memory);
 * the bounding cone of a sphere seen from a light (a sun: its extent along the light). */
int relight_occ_build(wrt_relight *r);
void relight_sphere_cone(const wrt_relight *r, const light_c *l, wrt_v3 centre, double radius, light_cone *cn);
light_c relight_light_consts(const wrt_light *l);

/* Haar analysis in place: `v` holds 4^L scaling coefficients of level L (row-major, nc
 * channels interleaved); on return pyr[haar_index * nc + c] holds the root scaling and
 * every wavelet of levels < L. `v` is used as scratch. */
void relight_haar_analyse(double *v, int L, int nc, double *pyr);
/* Inverse of relight_haar_analyse in single precision for 3 channels padded to 4 (SIMD):
 * from the pyramid `pyr` (levels < L, 4 floats a coefficient) to `out` (4^L texels,
 * `ostride` floats apart, 3 written); `v` is scratch for 4^(L-1) x 4 floats (at least 4);
 * pyr and v 16-byte aligned. */
void relight_haar_synthesize4f(const float *pyr, int L, float *v, float *out, int ostride);

/* --------------------------------------------------------- the parts ---- */

/* relight_project.c: projects light ls onto every quad's functions (and K's columns);
 * 0, or -1 if memory ran out (the light stays unprojected). */
int relight_project_light(wrt_relight *r, light_state *ls);
int relight_projection_cap(const wrt_relight *r, const quad_info *q);

/* relight_multiply.c: X = Op src (src = E, or E' with K; + Y with K), and per quad
 * whether its rows changed (r->resynth) and are non-zero (r->x_nonzero). */
void relight_multiply(wrt_relight *r, const float *src);
/* The same from each light's own product (rl_mul.per_light): Op E_i for the lights whose
 * whole projection changed since their X4 was made (through the cluster tree's basis when
 * the file has one), then X = sum over the lights, in their order, of scale_i X4_i. */
void relight_multiply_lights(wrt_relight *r);
/* The cluster tree (relight_cluster.c): set up from the file's section (WRT_OK when the
 * file has none), E taken to the tree's basis (returns the vector to multiply), and X
 * back to the quads' basis with the quads whose X changed marked. */
wrt_status relight_setup_clusters(wrt_relight *r);
const float *relight_cluster_forward(wrt_relight *r, const float *src);
void relight_cluster_inverse(wrt_relight *r);
/* With the final gather: the operator without the rows nothing displays. -1: no memory. */
int relight_display_rows_operator(wrt_relight *r);

/* relight_bounce.c: checks and lays out K (WRT_ERR_CORRUPT naming the column, or
 * WRT_ERR_NOMEM); per update, Y = K c and E' (r->k.Y, r->k.Ep). */
wrt_status relight_setup_first_bounce(wrt_relight *r);
void relight_first_bounce(wrt_relight *r);

/* relight_synth.c: the textures of the quads whose X changed or, glossy, whose view moved
 * (r->resynth; t: brdf and synthesis times): the number of quads whose Haar texture
 * changed, or -1 if memory ran out; the diffuse synthesis of one quad with colour `base`
 * into tex (also the gather's glossy senders). */
int relight_synthesize(wrt_relight *r, wrt_relight_timings *t);
void relight_synth_diffuse(wrt_relight *r, worker *w, int qidx, const float *base, float *tex);

/* relight_smooth.c: the smooth display's groups, texture layout (recomputes the texel
 * offsets and *tex_total) and scratch; per update, the groups that changed: returns the
 * number of quads whose smooth texture changed (it allocates nothing). */
wrt_status relight_setup_smooth(wrt_relight *r, size_t *tex_total);
int relight_smooth(wrt_relight *r);

/* relight_gather.c: the final gather on glossy quads (gather.h), unless options.no_gather;
 * per update, when the lights or the eye moved: 0, or -1 if memory ran out. */
int relight_gather_wanted(const wrt_relight *r);
wrt_status relight_setup_gather(wrt_relight *r);
int relight_gather(wrt_relight *r, int lights_moved, int eye_moved);

#endif
