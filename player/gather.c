/* gather.c: the final gather on glossy quads (gather.h). */
#include "gather.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define WRT_GATHER_AVX2 1 /* the light change's sums eight lanes wide where the processor has AVX2 */
#endif

#include "../common/basis.h"
#include "../common/brdf.h"

#define GATHER_PTS 16   /* points a side on a glossy quad (cell centres) */
#define GATHER_PTS_NARROW WRT_GATHER_SHARP_RES /* at most, on a sharp lobe's (roughness below GATHER_NARROW,
                              * or below GATHER_METAL on a metal) */
#define GATHER_NARROW 0.25
#define GATHER_METAL 0.5
#define GATHER_DIRS 32  /* incident cells a side of the concentric map */
#define GATHER_BRES 32  /* outgoing directions a side of the beta table */
#define GATHER_BSAMP 3  /* samples a side per incident cell when integrating beta */
#define GATHER_DTEX 32  /* direct-irradiance grid a side on a quad that a gather ray sees */
#define GATHER_RG 64    /* outgoing-radiance grid a side on it (what a gather entry reads) */

#define NDIR (GATHER_DIRS * GATHER_DIRS)
#define GLANE 4                /* floats a radiance cell (RGB, 0) */
#define EB 3                   /* bfloat16s a sum entry's beta (RGB) */
#define GROUP 4                /* a point's sum entries come in groups of 4 (four partial sums) */
#define AM_FIRST 0x8000u       /* amap: the first incident cell of its entry */
/* A beta row's cost (NDIR x 9 BRDF values) in rays, for the creation's progress: with it
 * the glossy asset's progress runs even in time (2 threads: 0.30 at 2.8 s, 0.65 at 6.9 s,
 * 1 at 9.6 s). */
#define BETA_ROW_RAYS 2000.0

typedef struct ghit { int32_t quad; float u, v; } ghit;
#define RG2 (GATHER_RG * GATHER_RG)

/* A point's sum: its entries, one per radiance cell that some of its incident cells read
 * (those cells' beta toward the eye summed), ascending by cell, padded with the black cell
 * to a multiple of GROUP; and, for the eye move, its seen incident cells in the same
 * order (amap: the cell's index a, | AM_FIRST on the first of each entry). */
typedef struct gquad {
    int glossy;
    int pts, npt;     /* points a side, pts^2 */
    ghit *hits;       /* npt x NDIR (glossy quads): what each ray sees (at creation) */
    size_t *e0;       /* npt + 1: where a point's entries start in eoff / ebeta */
    uint32_t *eoff;   /* per entry: its radiance cell's byte offset in rad (GLANE floats a cell) */
    uint16_t *ebeta;  /* per entry: beta toward the eye (bfloat16, EB: R, G, B; narrow: one),
                       * made when the eye moves, read at a light change */
    int narrow;       /* the narrow entries (eidx, one beta) instead of eoff and EB betas */
    uint16_t *eidx;   /* narrow: per entry its radiance cell's index in rad */
    size_t *a0;       /* npt + 1: where a point's seen incident cells start in amap */
    uint16_t *amap;   /* per seen incident cell (by entry): a | AM_FIRST on an entry's first */
    uint8_t *bvis;    /* npt: 1 if the point faces the eye (its row was made) */
    float *lout;      /* npt x 3: L_o toward the eye at the points */
    int beta_id;      /* index into g->beta */
} gquad;

/* Bilinear resampling of an n x n RGB grid of cell values at the centres of an m x m
 * grid, clamped at the edges: per axis the two cells and the weight of the second
 * (axis_table), then per output cell the four weights (double products rounded to
 * float) and their sum in float in a fixed order. */
typedef struct axis { int a, b; double t; } axis;
static axis axis_at(int n, int m, int i) {
    double f = (i + 0.5) / m * n - 0.5;
    int x0 = (int)floor(f);
    axis r = {x0 < 0 ? 0 : x0 >= n ? n - 1 : x0, x0 + 1 < 0 ? 0 : x0 + 1 >= n ? n - 1 : x0 + 1, f - x0};
    return r;
}
static void axis_table(int n, int m, axis *ax) {
    for (int i = 0; i < m; i++) ax[i] = axis_at(n, m, i);
}
struct wrt_gather {
    int nq;
    const wrt_gather_quad *q0;
    wrt_gather_quad *q;
    gquad *gq;
    int *glossy; int nglossy;
    int32_t *slot;     /* per quad: its slot among the diffuse quads some ray sees, -1 */
    int *slot_quad; int nslot;
    float *direct;     /* nslot x GATHER_DTEX^2 x GLANE: direct irradiance (RGB, 0) */
    float *rad;        /* (nslot x RG2 + 1) x GLANE: outgoing radiance (direct + indirect;
                        * RGB, 0), then a black cell (0) */
    int simd, avx2;    /* the sums 4 lanes wide (SSE2), 8 (AVX2 at run time): the same bits */
    float **beta;      /* per glossy quad's material: GATHER_BRES^2 x NDIR x 3 */
    uint8_t *grey;     /* per beta table: 1 if its R, G and B are the same floats everywhere */
    int wide;          /* env->wide: no narrow entries */
    axis *dax;  /* GATHER_RG: the direct grid's cells at the radiance grid's */
    axis *tax;  /* nslot x GATHER_RG: each slot's texture cells at the radiance grid's */
    const wrt_material **beta_mat; int nbeta;
    RTCScene scene; wrt_v3 origin; double eps;
    wrt_gather_env env;
    /* per loop */
    wrt_gather_direct_fn dfn; void *duser;
    const float *const *tex; const int *tex_res;
    double eye[3];
    int lq;            /* the glossy quad lout_point works on */
    int rows_eye;      /* lout_point makes each point's row toward eye (it moved) */
    int have_rows; double rows_at[3]; /* the eye the kept rows were made for */
    float *const *out; const int *out_res;
};

static wrt_v3 qpoint(const wrt_gather_quad *q, double u, double v) {
    double w0 = (1 - u) * (1 - v), w1 = u * (1 - v), w2 = u * v, w3 = (1 - u) * v;
    return v3(w0 * q->p[0].x + w1 * q->p[1].x + w2 * q->p[2].x + w3 * q->p[3].x,
              w0 * q->p[0].y + w1 * q->p[1].y + w2 * q->p[2].y + w3 * q->p[3].y,
              w0 * q->p[0].z + w1 * q->p[1].z + w2 * q->p[2].z + w3 * q->p[3].z);
}

/* (u, v) of a point x on quad q: Newton on the bilinear map, projected on the plane. */
static void qinvert(const wrt_gather_quad *q, wrt_v3 x, double *pu, double *pv) {
    double u = *pu, v = *pv;
    for (int it = 0; it < 6; it++) {
        wrt_v3 r = v3_sub(qpoint(q, u, v), x);
        wrt_v3 du = v3_add(v3_scale(v3_sub(q->p[1], q->p[0]), 1 - v), v3_scale(v3_sub(q->p[2], q->p[3]), v));
        wrt_v3 dv = v3_add(v3_scale(v3_sub(q->p[3], q->p[0]), 1 - u), v3_scale(v3_sub(q->p[2], q->p[1]), u));
        double a = v3_dot(du, du), b = v3_dot(du, dv), c = v3_dot(dv, dv);
        double ru = v3_dot(du, r), rv = v3_dot(dv, r), det = a * c - b * b;
        if (!(fabs(det) > 0)) break;
        u -= (c * ru - b * rv) / det;
        v -= (a * rv - b * ru) / det;
    }
    *pu = u < 0 ? 0 : u > 1 ? 1 : u;
    *pv = v < 0 ? 0 : v > 1 ? 1 : v;
}

static void *ga(const wrt_gather *g, size_t bytes) { return g->env.alloc(g->env.user, bytes ? bytes : 1); }
static void gf(const wrt_gather *g, void *p) { if (p) g->env.free(g->env.user, p); }

static int is_glossy(const wrt_material *m) { return m && !m->lambertian; }

int wrt_gather_sharp(const wrt_material *m) {
    return is_glossy(m) && (m->roughness < GATHER_NARROW || (m->roughness < GATHER_METAL && m->metallic >= 0.5));
}

/* -------------------------------------------------------------- creation ---- */

typedef struct trace_ctx { wrt_gather *g; int gq; size_t first; } trace_ctx; /* first: a chunk's first point */

static void trace_point(void *user, size_t item) {
    trace_ctx *tc = user;
    item += tc->first;
    wrt_gather *g = tc->g;
    const wrt_gather_quad *q = &g->q[tc->gq];
    int n = g->gq[tc->gq].pts, pi = (int)item % n, pj = (int)item / n;
    wrt_v3 x = qpoint(q, (pi + 0.5) / n, (pj + 0.5) / n);
    wrt_v3 o = v3_sub(v3_mad(x, q->n, g->eps), g->origin);
    ghit *h = g->gq[tc->gq].hits + item * NDIR;
    for (int a = 0; a < NDIR; a++) {
        double d[3];
        wrt_concentric_dir(((a % GATHER_DIRS) + 0.5) / GATHER_DIRS, ((a / GATHER_DIRS) + 0.5) / GATHER_DIRS, d);
        wrt_v3 w = v3_norm(v3_add(v3_add(v3_scale(q->t, d[0]), v3_scale(q->b, d[1])), v3_scale(q->n, d[2])));
        struct RTCRayHit rh;
        memset(&rh, 0, sizeof rh);
        rh.ray.org_x = (float)o.x; rh.ray.org_y = (float)o.y; rh.ray.org_z = (float)o.z;
        rh.ray.dir_x = (float)w.x; rh.ray.dir_y = (float)w.y; rh.ray.dir_z = (float)w.z;
        rh.ray.tnear = 0; rh.ray.tfar = INFINITY; rh.ray.mask = 0xFFFFFFFFu;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID; rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        struct RTCIntersectContext ic;
        rtcInitIntersectContext(&ic);
        rtcIntersect1(g->scene, &ic, &rh);
        h[a].quad = -1; h[a].u = h[a].v = 0;
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID || (int)rh.hit.primID >= g->nq) continue;
        int hq = (int)rh.hit.primID;
        if (v3_dot(w, g->q[hq].n) >= 0) continue; /* its back: sends nothing */
        wrt_v3 hp = v3_mad(v3_add(o, g->origin), w, rh.ray.tfar);
        double u = rh.hit.u, v = rh.hit.v;
        qinvert(&g->q[hq], hp, &u, &v);
        h[a].quad = hq; h[a].u = (float)u; h[a].v = (float)v;
    }
}

typedef struct beta_ctx { wrt_gather *g; int b; size_t first; } beta_ctx; /* first: a chunk's first row */

/* beta(a, w_o) = int_cell f_r cos dw = pi int_cell f_r da db (cosine-weighted map). */
static void beta_row(void *user, size_t item) {
    beta_ctx *bc = user;
    item += bc->first;
    const wrt_material *m = bc->g->beta_mat[bc->b];
    float *out = bc->g->beta[bc->b] + item * NDIR * 3;
    double od[3];
    wrt_concentric_dir(((item % GATHER_BRES) + 0.5) / GATHER_BRES, ((item / GATHER_BRES) + 0.5) / GATHER_BRES, od);
    wrt_v3 n = v3(0, 0, 1), wo = v3(od[0], od[1], od[2]);
    double k = M_PI / ((double)NDIR * GATHER_BSAMP * GATHER_BSAMP);
    for (int a = 0; a < NDIR; a++) {
        double s[3] = {0, 0, 0};
        for (int sj = 0; sj < GATHER_BSAMP; sj++)
            for (int si = 0; si < GATHER_BSAMP; si++) {
                double d[3], f[3];
                wrt_concentric_dir((a % GATHER_DIRS + (si + 0.5) / GATHER_BSAMP) / GATHER_DIRS,
                                   (a / GATHER_DIRS + (sj + 0.5) / GATHER_BSAMP) / GATHER_DIRS, d);
                wrt_brdf_eval(m, n, v3(d[0], d[1], d[2]), wo, f);
                for (int c = 0; c < 3; c++) s[c] += f[c];
            }
        for (int c = 0; c < 3; c++) out[a * 3 + c] = (float)(s[c] * k);
    }
}

/* The radiance cell a ray reads (the nearest of its quad's radiance grid; the black cell
 * after the grids for a ray that sees nothing or a back). */
static uint32_t ray_cell(const wrt_gather *g, const ghit *h) {
    if (h->quad < 0 || g->slot[h->quad] < 0) return (uint32_t)g->nslot * RG2;
    int cx = (int)(h->u * GATHER_RG), cy = (int)(h->v * GATHER_RG);
    cx = cx < 0 ? 0 : cx >= GATHER_RG ? GATHER_RG - 1 : cx;
    cy = cy < 0 ? 0 : cy >= GATHER_RG ? GATHER_RG - 1 : cy;
    return (uint32_t)g->slot[h->quad] * RG2 + (uint32_t)(cy * GATHER_RG + cx);
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* A glossy quad's sums (gquad): per point its seen incident cells sorted by the radiance
 * cell they read (then by index), one entry per distinct cell, padded to a multiple of
 * GROUP; frees the hits. In an open scene many incident cells see only the sky (the
 * glossy asset: floor points' upper hemisphere): they have no entry. The narrow form,
 * where the quad's lobe is grey (its BRDF table's R, G and B the same floats: one beta
 * an entry serves the three) and every cell has a 16-bit index (up to 15 seen quads):
 * 4 bytes an entry instead of 10, the same products in the same order. -1: no memory. */
static int make_entries(wrt_gather *g, gquad *G) {
    uint32_t black = (uint32_t)g->nslot * RG2;
    G->narrow = !g->wide && g->grey[G->beta_id] && black <= UINT16_MAX;
    size_t nb = G->narrow ? 1 : EB;
    G->e0 = ga(g, ((size_t)G->npt + 1) * sizeof *G->e0);
    G->a0 = ga(g, ((size_t)G->npt + 1) * sizeof *G->a0);
    G->bvis = ga(g, (size_t)G->npt);
    uint64_t *key = ga(g, NDIR * sizeof *key);
    if (!G->e0 || !G->a0 || !G->bvis || !key) { gf(g, key); return -1; }
    for (int pass = 0; pass < 2; pass++) { /* 0: count, 1: fill */
        size_t ne = 0, na = 0;
        for (size_t p = 0; p < (size_t)G->npt; p++) {
            const ghit *h = G->hits + p * NDIR;
            int n = 0;
            for (int a = 0; a < NDIR; a++) {
                uint32_t c = ray_cell(g, &h[a]);
                if (c != black) key[n++] = (uint64_t)c << 16 | (uint64_t)a;
            }
            qsort(key, (size_t)n, sizeof *key, cmp_u64);
            size_t e = ne;
            for (int k = 0; k < n; k++) {
                int first = k == 0 || key[k] >> 16 != key[k - 1] >> 16;
                if (pass) {
                    if (first) G->eoff[e++] = (uint32_t)(key[k] >> 16) * GLANE * sizeof(float);
                    G->amap[na + k] = (uint16_t)((key[k] & 0xFFFFu) | (first ? AM_FIRST : 0));
                } else e += first;
            }
            if (pass) {
                G->e0[p] = ne;
                G->a0[p] = na;
                for (; (e - ne) % GROUP; e++) G->eoff[e] = black * GLANE * sizeof(float); /* beta 0 */
            } else e += (GROUP - (e - ne) % GROUP) % GROUP;
            ne = e;
            na += (size_t)n;
        }
        if (pass) { G->e0[G->npt] = ne; G->a0[G->npt] = na; break; }
        G->eoff = ga(g, (ne ? ne : 1) * sizeof *G->eoff);
        G->ebeta = ga(g, (ne * nb + 8) * sizeof *G->ebeta); /* + 8: the 8-byte loads of the last entry */
        G->amap = ga(g, (na ? na : 1) * sizeof *G->amap);
        if (!G->eoff || !G->ebeta || !G->amap) { gf(g, key); return -1; }
    }
    gf(g, key);
    gf(g, G->hits);
    G->hits = NULL;
    if (G->narrow) {
        size_t ne = G->e0[G->npt];
        G->eidx = ga(g, (ne ? ne : 1) * sizeof *G->eidx);
        if (!G->eidx) return -1;
        for (size_t e = 0; e < ne; e++) G->eidx[e] = (uint16_t)(G->eoff[e] / (GLANE * sizeof(float)));
        gf(g, G->eoff);
        G->eoff = NULL;
    }
    return 0;
}

size_t wrt_gather_entry_bytes(const wrt_gather *g, size_t *entries) {
    size_t n = 0, bytes = 0;
    for (int k = 0; g && k < g->nglossy; k++) {
        const gquad *G = &g->gq[g->glossy[k]];
        size_t ne = G->e0 ? G->e0[G->npt] : 0;
        n += ne;
        bytes += ne * (G->narrow ? sizeof *G->eidx + sizeof *G->ebeta : sizeof *G->eoff + EB * sizeof *G->ebeta);
    }
    if (entries) *entries = n;
    return bytes;
}

wrt_status wrt_gather_create(int nq, const wrt_gather_quad *q, const int *out_res, RTCScene scene, wrt_v3 origin,
                             double eps, int points, const wrt_gather_env *env, wrt_gather **out) {
    *out = NULL;
    int ng = 0;
    for (int i = 0; i < nq; i++) ng += is_glossy(q[i].mat);
    if (!ng) return WRT_OK;
    wrt_gather *g = env->alloc(env->user, sizeof *g);
    if (!g) return WRT_ERR_NOMEM;
    g->env = *env;
    g->simd = env->simd != 1; /* 1: the plain loops (tests) */
#ifdef WRT_GATHER_AVX2
    __builtin_cpu_init();
    g->avx2 = env->simd == 0 && __builtin_cpu_supports("avx2");
#endif
    /* points = 16 or 32: every glossy quad's points a side (before/after figures and the
     * test that tells the two apart); 0: chosen per quad. */
    int force_pts = points == 16 || points == 32 ? points : 0;
    g->nq = nq; g->scene = scene; g->origin = origin; g->eps = eps;
    g->q = ga(g, (size_t)nq * sizeof *g->q);
    g->gq = ga(g, ((size_t)nq) * sizeof *g->gq);
    g->glossy = ga(g, (size_t)ng * sizeof(int));
    g->slot = ga(g, (size_t)nq * sizeof(int32_t));
    g->slot_quad = ga(g, (size_t)nq * sizeof(int));
    g->beta = ga(g, ((size_t)ng) * sizeof(float *));
    g->beta_mat = ga(g, ((size_t)ng) * sizeof(wrt_material *));
    g->grey = ga(g, (size_t)ng);
    g->wide = env->wide;
    if (!g->q || !g->gq || !g->glossy || !g->slot || !g->slot_quad || !g->beta || !g->beta_mat || !g->grey) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
    memcpy(g->q, q, (size_t)nq * sizeof *g->q);
    for (int i = 0; i < nq; i++) g->slot[i] = -1;
    for (int i = 0; i < nq; i++) {
        if (!is_glossy(q[i].mat)) continue;
        gquad *G = &g->gq[i];
        G->glossy = 1;
        g->glossy[g->nglossy++] = i;
        /* A lobe that reflects a sharp image gets its points one per texel of the texture
         * it is shown with, 16 to 32 a side: a narrow lobe (cornell-glossy r0.1, quality
         * 5, texture 32, 64 x 64 pixels at 4096 paths: image rmse 0.303 with 16 points,
         * 0.184 with 32, 0.213 with 64, floor 0.135; quality 3, texture 16: 0.297 with 16,
         * 0.314 with 32), or a metal's moderate one, all of whose reflection is the lobe
         * (r0.3: 0.114 -> 0.086 at 1024 paths, floor 0.069). A dielectric's moderate lobe
         * is a few percent of its reflection and keeps 16 (the glossy asset, r0.3-0.4:
         * 0.103 -> 0.098, floor 0.048, for 1.5x the light change). */
        G->pts = GATHER_PTS;
        int sharp = wrt_gather_sharp(q[i].mat);
        if (sharp && out_res && out_res[i] > GATHER_PTS)
            G->pts = out_res[i] < GATHER_PTS_NARROW ? out_res[i] : GATHER_PTS_NARROW;
        if (force_pts > 0) G->pts = force_pts;
        G->npt = G->pts * G->pts;
        G->hits = ga(g, (size_t)G->npt * NDIR * sizeof(ghit));
        G->lout = ga(g, ((size_t)G->npt * 3) * sizeof(float));
        if (!G->hits || !G->lout) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
        G->beta_id = -1;
        for (int b = 0; b < g->nbeta; b++) if (g->beta_mat[b] == q[i].mat) G->beta_id = b;
        if (G->beta_id < 0) {
            G->beta_id = g->nbeta;
            g->beta_mat[g->nbeta] = q[i].mat;
            /* + GLANE: the eye move's 4-float loads of the last row's last cell */
            g->beta[g->nbeta] = ga(g, ((size_t)GATHER_BRES * GATHER_BRES * NDIR * 3 + GLANE) * sizeof(float));
            if (!g->beta[g->nbeta]) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
            g->nbeta++;
        }
    }
    /* The work, in pieces of a few milliseconds between calls of env->progress: the
     * BRDF tables' rows, then each glossy quad's points (the same results as in one loop:
     * each item writes its own row or point, and the slots are numbered in quad order). */
    size_t piece = env->piece > 0 ? (size_t)env->piece : 8;
    double total = (double)g->nbeta * GATHER_BRES * GATHER_BRES * BETA_ROW_RAYS, done = 0;
    for (int k = 0; k < g->nglossy; k++) total += (double)g->gq[g->glossy[k]].npt * NDIR;
    for (int b = 0; b < g->nbeta; b++)
        for (size_t r0 = 0; r0 < (size_t)GATHER_BRES * GATHER_BRES; r0 += piece) {
            size_t n = (size_t)GATHER_BRES * GATHER_BRES - r0 < piece ? (size_t)GATHER_BRES * GATHER_BRES - r0 : piece;
            beta_ctx bc = {g, b, r0};
            g->env.run(g->env.user, n, beta_row, &bc);
            done += (double)n * BETA_ROW_RAYS;
            if (env->progress && !env->progress(env->user, done / total)) { wrt_gather_destroy(g); return WRT_ERR_CANCELLED; }
        }
    for (int b = 0; b < g->nbeta; b++) { /* a grey lobe: R, G and B the same floats (bits) */
        const float *t = g->beta[b];
        size_t k = 0, n = (size_t)GATHER_BRES * GATHER_BRES * NDIR;
        while (k < n && !memcmp(t + 3 * k, t + 3 * k + 1, sizeof *t) && !memcmp(t + 3 * k, t + 3 * k + 2, sizeof *t)) k++;
        g->grey[b] = k == n;
    }
    for (int k = 0; k < g->nglossy; k++) {
        int i = g->glossy[k];
        gquad *G = &g->gq[i];
        for (size_t p0 = 0; p0 < (size_t)G->npt; p0 += piece) {
            size_t n = (size_t)G->npt - p0 < piece ? (size_t)G->npt - p0 : piece;
            trace_ctx tc = {g, i, p0};
            g->env.run(g->env.user, n, trace_point, &tc);
            done += (double)n * NDIR;
            if (env->progress && !env->progress(env->user, k + 1 == g->nglossy && p0 + n == (size_t)G->npt ? 1.0 : done / total)) {
                wrt_gather_destroy(g);
                return WRT_ERR_CANCELLED;
            }
        }
        for (size_t k2 = 0; k2 < (size_t)G->npt * NDIR; k2++) {
            int hq = G->hits[k2].quad;
            if (hq < 0 || g->slot[hq] >= 0) continue;
            g->slot[hq] = g->nslot;
            g->slot_quad[g->nslot++] = hq;
        }
    }
    /* rad's byte offsets (uint32) reach every cell */
    if (((size_t)g->nslot * RG2 + 1) * GLANE * sizeof(float) > UINT32_MAX) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
    for (int k = 0; k < g->nglossy; k++)
        if (make_entries(g, &g->gq[g->glossy[k]]) != 0) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
    g->direct = ga(g, ((size_t)(g->nslot ? g->nslot : 1) * GATHER_DTEX * GATHER_DTEX * GLANE) * sizeof(float));
    g->rad = ga(g, ((size_t)g->nslot * RG2 + 1) * GLANE * sizeof(float)); /* + the black cell */
    g->dax = ga(g, GATHER_RG * sizeof *g->dax);
    g->tax = ga(g, ((size_t)g->nslot * GATHER_RG + 1) * sizeof *g->tax);
    if (!g->direct || !g->rad || !g->dax || !g->tax) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
    for (int i = 0; i < GATHER_RG; i++) g->dax[i] = axis_at(GATHER_DTEX, GATHER_RG, i);
    *out = g;
    return WRT_OK;
}

void wrt_gather_destroy(wrt_gather *g) {
    if (!g) return;
    if (g->gq)
        for (int i = 0; i < g->nq; i++) {
            gf(g, g->gq[i].hits); gf(g, g->gq[i].lout); gf(g, g->gq[i].e0); gf(g, g->gq[i].eoff);
            gf(g, g->gq[i].ebeta); gf(g, g->gq[i].a0); gf(g, g->gq[i].amap); gf(g, g->gq[i].bvis); gf(g, g->gq[i].eidx);
        }
    for (int b = 0; b < g->nbeta; b++) gf(g, g->beta[b]);
    gf(g, g->beta); gf(g, g->beta_mat); gf(g, g->grey); gf(g, g->direct); gf(g, g->rad); gf(g, g->dax); gf(g, g->tax); gf(g, g->slot); gf(g, g->slot_quad); gf(g, g->glossy); gf(g, g->gq); gf(g, g->q);
    gf(g, g);
}

/* ---------------------------------------------------------- light change ---- */

static void direct_row(void *user, size_t item) {
    wrt_gather *g = user;
    int s = (int)(item / GATHER_DTEX), j = (int)(item % GATHER_DTEX);
    const wrt_gather_quad *Q = &g->q[g->slot_quad[s]];
    float *d = g->direct + ((size_t)s * GATHER_DTEX + j) * GATHER_DTEX * GLANE;
    wrt_v3 x[GATHER_DTEX];
    double e[GATHER_DTEX * 3];
    for (int i = 0; i < GATHER_DTEX; i++) x[i] = qpoint(Q, (i + 0.5) / GATHER_DTEX, (j + 0.5) / GATHER_DTEX);
    g->dfn(g->duser, x, GATHER_DTEX, Q->n, e);
    for (int i = 0; i < GATHER_DTEX; i++)
        for (int c = 0; c < 3; c++) d[i * GLANE + c] = (float)e[i * 3 + c];
}

/* lerp_cell's sum on an n x n grid of cells `lane` floats apart (3 or GLANE): the weights
 * (double products rounded to float) and their sum in float in a fixed order. */
static inline void lerp_cell_w(const float *t, int n, int lane, const axis *x, const axis *y, float out[3]) {
    float w0 = (float)((1 - x->t) * (1 - y->t)), w1 = (float)(x->t * (1 - y->t));
    float w2 = (float)((1 - x->t) * y->t), w3 = (float)(x->t * y->t);
    const float *p0 = t + ((size_t)y->a * n + x->a) * lane, *p1 = t + ((size_t)y->a * n + x->b) * lane;
    const float *p2 = t + ((size_t)y->b * n + x->a) * lane, *p3 = t + ((size_t)y->b * n + x->b) * lane;
    for (int c = 0; c < 3; c++) {
        float s = w0 * p0[c];
        s += w1 * p1[c];
        s += w2 * p2[c];
        s += w3 * p3[c];
        out[c] = s;
    }
}

static inline void lerp_cell(const float *t, int n, const axis *x, const axis *y, float out[3]) {
    lerp_cell_w(t, n, 3, x, y, out);
}

/* A radiance cell of slot s's grid: albedo/pi x the direct grid's bilinear value + the
 * texture's (RGB, the fourth float 0). */
static void rad_row(void *user, size_t item) {
    wrt_gather *g = user;
    int s = (int)(item / GATHER_RG), j = (int)(item % GATHER_RG), hq = g->slot_quad[s];
    const float *base = g->q[hq].albedo;
    const float *dt = g->direct + (size_t)s * GATHER_DTEX * GATHER_DTEX * GLANE;
    float *o = g->rad + ((size_t)s * RG2 + (size_t)j * GATHER_RG) * GLANE;
    const axis *dx = g->dax, *tx = g->tax + (size_t)s * GATHER_RG;
    const float *it = g->tex[hq];
    int tn = it ? g->tex_res[hq] : 0;
    axis dy = dx[j], ty = tx[j];
    float kb[3];
    for (int c = 0; c < 3; c++) kb[c] = (float)(base[c] / M_PI);
#ifdef __SSE2__
    /* lerp_cell_w's operations four lanes at once (the same bits; the direct grid's fourth
     * lane is 0, the texture's three floats loaded as three) */
    const __m128 kv = _mm_set_ps(0.0f, kb[2], kb[1], kb[0]);
    const __m128d dy01 = _mm_set_pd(dy.t, 1 - dy.t), ty01 = _mm_set_pd(ty.t, 1 - ty.t);
#define W4(ax_, y01_, w_) do { /* w0, w1, w2, w3 */ \
        __m128 a_ = _mm_cvtpd_ps(_mm_mul_pd(_mm_set1_pd(1 - (ax_)->t), y01_)); \
        __m128 b_ = _mm_cvtpd_ps(_mm_mul_pd(_mm_set1_pd((ax_)->t), y01_)); \
        w_ = _mm_unpacklo_ps(a_, b_); } while (0)
#define LOAD3(p_) _mm_movelh_ps(_mm_castpd_ps(_mm_load_sd((const double *)(p_))), _mm_load_ss((p_) + 2))
    for (int i = 0; i < GATHER_RG; i++) {
        __m128 w;
        W4(&dx[i], dy01, w);
        const float *d0 = dt + ((size_t)dy.a * GATHER_DTEX + dx[i].a) * GLANE, *d1 = dt + ((size_t)dy.a * GATHER_DTEX + dx[i].b) * GLANE;
        const float *d2 = dt + ((size_t)dy.b * GATHER_DTEX + dx[i].a) * GLANE, *d3 = dt + ((size_t)dy.b * GATHER_DTEX + dx[i].b) * GLANE;
        __m128 v = _mm_mul_ps(_mm_shuffle_ps(w, w, 0x00), _mm_loadu_ps(d0));
        v = _mm_add_ps(v, _mm_mul_ps(_mm_shuffle_ps(w, w, 0x55), _mm_loadu_ps(d1)));
        v = _mm_add_ps(v, _mm_mul_ps(_mm_shuffle_ps(w, w, 0xAA), _mm_loadu_ps(d2)));
        v = _mm_add_ps(v, _mm_mul_ps(_mm_shuffle_ps(w, w, 0xFF), _mm_loadu_ps(d3)));
        v = _mm_mul_ps(kv, v);
        if (tn > 0) {
            W4(&tx[i], ty01, w);
            const float *t0 = it + ((size_t)ty.a * tn + tx[i].a) * 3, *t1 = it + ((size_t)ty.a * tn + tx[i].b) * 3;
            const float *t2 = it + ((size_t)ty.b * tn + tx[i].a) * 3, *t3 = it + ((size_t)ty.b * tn + tx[i].b) * 3;
            __m128 iv = _mm_mul_ps(_mm_shuffle_ps(w, w, 0x00), LOAD3(t0));
            iv = _mm_add_ps(iv, _mm_mul_ps(_mm_shuffle_ps(w, w, 0x55), LOAD3(t1)));
            iv = _mm_add_ps(iv, _mm_mul_ps(_mm_shuffle_ps(w, w, 0xAA), LOAD3(t2)));
            iv = _mm_add_ps(iv, _mm_mul_ps(_mm_shuffle_ps(w, w, 0xFF), LOAD3(t3)));
            v = _mm_add_ps(v, iv);
        } else v = _mm_add_ps(v, _mm_setzero_ps());
        _mm_storeu_ps(o + (size_t)i * GLANE, v);
    }
#undef W4
#undef LOAD3
#else
    for (int i = 0; i < GATHER_RG; i++) {
        float dv[3], iv[3] = {0, 0, 0};
        lerp_cell_w(dt, GATHER_DTEX, GLANE, &dx[i], &dy, dv);
        if (tn > 0) lerp_cell_w(it, tn, 3, &tx[i], &ty, iv);
        for (int c = 0; c < 3; c++) o[i * GLANE + c] = kb[c] * dv[c] + iv[c];
    }
#endif
}

void wrt_gather_lights(wrt_gather *g, wrt_gather_direct_fn direct, void *user, const float *const *tex,
                       const int *tex_res) {
    if (!g) return;
    g->dfn = direct; g->duser = user; g->tex = tex; g->tex_res = tex_res;
    for (int sl = 0; sl < g->nslot; sl++) {
        int tn = tex[g->slot_quad[sl]] ? tex_res[g->slot_quad[sl]] : 0;
        if (tn > 0) axis_table(tn, GATHER_RG, g->tax + (size_t)sl * GATHER_RG);
    }
    g->env.run(g->env.user, (size_t)g->nslot * GATHER_DTEX, direct_row, g);
    g->env.run(g->env.user, (size_t)g->nslot * GATHER_RG, rad_row, g);
}

/* ------------------------------------------------------------- eye move ---- */

#ifndef __SSE2__
/* bfloat16: a float's upper 16 bits, rounded to nearest even (beta is finite, >= 0). */
static uint16_t to_bf16(float f) {
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    u += 0x7fffu + ((u >> 16) & 1u);
    return (uint16_t)(u >> 16);
}
#endif

/* A point's betas toward the eye: for each of its seen incident cells amap[0..na) the four
 * beta rows bt[] blended with weights w (the bilinear outgoing direction), summed over the
 * incident cells of an entry (in amap's order), kept as bfloat16 in eb (nb an entry: EB,
 * or 1 for a grey lobe's narrow entries, R, which the three channels' equal floats give). */
static void blend_row(const float *const bt[4], const float w[4], const uint16_t *amap, size_t na, uint16_t *eb, int nb) {
    uint16_t *e = eb - nb;
#ifdef __SSE2__
    /* the scalar loop's operations, four lanes at once (the fourth, the next cell's red,
     * dropped): the same bits */
    __m128 w0 = _mm_set1_ps(w[0]), w1 = _mm_set1_ps(w[1]), w2 = _mm_set1_ps(w[2]), w3 = _mm_set1_ps(w[3]), acc = _mm_setzero_ps();
    const __m128i one = _mm_set1_epi32(1), half = _mm_set1_epi32(0x7fff);
#define BF16_STORE(dst_, v_) do { \
        __m128i u_ = _mm_castps_si128(v_); \
        u_ = _mm_add_epi32(u_, _mm_add_epi32(half, _mm_and_si128(_mm_srli_epi32(u_, 16), one))); \
        u_ = _mm_srli_epi32(u_, 16); /* beta >= 0: under 0x8000, so the signed pack keeps it */ \
        uint16_t h_[8]; \
        _mm_storeu_si128((__m128i *)h_, _mm_packs_epi32(u_, u_)); \
        memcpy(dst_, h_, (size_t)nb * sizeof *h_); } while (0)
    for (size_t k = 0; k < na; k++) {
        size_t o = (size_t)(amap[k] & ~AM_FIRST) * 3;
        __m128 t = _mm_add_ps(_mm_add_ps(_mm_mul_ps(w0, _mm_loadu_ps(bt[0] + o)), _mm_mul_ps(w1, _mm_loadu_ps(bt[1] + o))),
                              _mm_add_ps(_mm_mul_ps(w2, _mm_loadu_ps(bt[2] + o)), _mm_mul_ps(w3, _mm_loadu_ps(bt[3] + o))));
        if (amap[k] & AM_FIRST) {
            if (e >= eb) BF16_STORE(e, acc);
            e += nb;
            acc = t;
        } else acc = _mm_add_ps(acc, t);
    }
    if (na) BF16_STORE(e, acc);
#undef BF16_STORE
#else
    float acc[3] = {0, 0, 0};
    for (size_t k = 0; k <= na; k++) {
        if (k == na || (amap[k] & AM_FIRST)) {
            if (e >= eb) for (int c = 0; c < nb; c++) e[c] = to_bf16(acc[c]);
            if (k == na) break;
            e += nb;
        }
        size_t o = (size_t)(amap[k] & ~AM_FIRST) * 3;
        for (int c = 0; c < 3; c++) {
            float t = (w[0] * bt[0][o + c] + w[1] * bt[1][o + c]) + (w[2] * bt[2][o + c] + w[3] * bt[3][o + c]);
            acc[c] = (amap[k] & AM_FIRST) ? t : acc[c] + t;
        }
    }
#endif
}

/* sum over a point's entries of rad[cell] beta (RGB): entries k = 4j + l summed into four
 * partial sums l (each an entry's RGB in lanes 0-2), folded as (s0 + s1) + (s2 + s3). n: a
 * multiple of GROUP. The plain, SSE2 and AVX2 loops add the same products in the same
 * order: the same bits (a fourth lane, where there is one, is rad's 0 times a beta). An
 * entry is general (eoff: a byte offset into rad, EB betas) or, with idx non-NULL, narrow
 * (idx: a cell index, one beta for R, G and B): the same products, so the same bits as the
 * general entries of the same betas (test_gather `test_narrow_same_bits`). */
static void dot_plain(const float *rad, const uint32_t *eoff, const uint16_t *idx, const uint16_t *eb, size_t n,
                      float out[3]) {
    float s[GROUP][3] = {{0}};
    for (size_t k = 0; k < n; k++) {
        const float *r = idx ? rad + (size_t)idx[k] * GLANE : (const float *)((const char *)rad + eoff[k]);
        for (int c = 0; c < 3; c++) {
            uint32_t u = (uint32_t)eb[idx ? k : k * EB + c] << 16;
            float f;
            memcpy(&f, &u, sizeof f);
            s[k % GROUP][c] += r[c] * f;
        }
    }
    for (int c = 0; c < 3; c++) out[c] = (s[0][c] + s[1][c]) + (s[2][c] + s[3][c]);
}

#ifdef __SSE2__
static void store3(__m128 t, float out[3]) {
    float a[4];
    _mm_storeu_ps(a, t);
    for (int c = 0; c < 3; c++) out[c] = a[c];
}

static void dot_sse2(const float *rad, const uint32_t *eoff, const uint16_t *idx, const uint16_t *eb, size_t n,
                     float out[3]) {
    const char *rb = (const char *)rad;
    __m128 s0 = _mm_setzero_ps(), s1 = s0, s2 = s0, s3 = s0;
    const __m128i z = _mm_setzero_si128();
    /* a general entry's beta: 8 bytes from its first (the fourth, the next entry's red,
     * meets rad's 0); a narrow one's: its one beta in every lane */
#define BETA4(k_) (idx ? _mm_castsi128_ps(_mm_set1_epi32((int)((uint32_t)eb[k_] << 16))) \
                       : _mm_castsi128_ps(_mm_unpacklo_epi16(z, _mm_loadl_epi64((const __m128i *)(eb + (k_) * EB)))))
#define RAD4(k_) _mm_loadu_ps(idx ? rad + (size_t)idx[k_] * GLANE : (const float *)(rb + eoff[k_]))
    for (size_t k = 0; k < n; k += GROUP) {
        s0 = _mm_add_ps(s0, _mm_mul_ps(RAD4(k), BETA4(k)));
        s1 = _mm_add_ps(s1, _mm_mul_ps(RAD4(k + 1), BETA4(k + 1)));
        s2 = _mm_add_ps(s2, _mm_mul_ps(RAD4(k + 2), BETA4(k + 2)));
        s3 = _mm_add_ps(s3, _mm_mul_ps(RAD4(k + 3), BETA4(k + 3)));
    }
#undef BETA4
#undef RAD4
    store3(_mm_add_ps(_mm_add_ps(s0, s1), _mm_add_ps(s2, s3)), out);
}
#endif

#ifdef WRT_GATHER_AVX2
/* dot_sse2 eight lanes wide: entries 4j, 4j + 1 in one vector (partial sums 0 and 1 in its
 * halves), 4j + 2, 4j + 3 in the other. General entries: a group's 12 betas (24 bytes) as
 * two 16-byte loads, each broadcast to both halves and shuffled into floats (bfloat16 in
 * the upper 16 bits, the fourth lane 0); narrow ones: its four betas (8 bytes) loaded
 * once and spread, each to the four lanes of its entry. */
__attribute__((target("avx2"))) static void dot_avx2(const float *rad, const uint32_t *eoff, const uint16_t *idx,
                                                     const uint16_t *eb, size_t n, float out[3]) {
    const char *rb = (const char *)rad;
    const char Z = (char)0x80;
    const __m256i g01 = _mm256_setr_epi8(Z, Z, 0, 1, Z, Z, 2, 3, Z, Z, 4, 5, Z, Z, Z, Z,    /* entry 0: bytes 0-5 */
                                         Z, Z, 6, 7, Z, Z, 8, 9, Z, Z, 10, 11, Z, Z, Z, Z); /* entry 1: 6-11 */
    const __m256i g23 = _mm256_setr_epi8(Z, Z, 4, 5, Z, Z, 6, 7, Z, Z, 8, 9, Z, Z, Z, Z,    /* entry 2: bytes 12-17, 4-9 of the load at 8 */
                                         Z, Z, 10, 11, Z, Z, 12, 13, Z, Z, 14, 15, Z, Z, Z, Z); /* entry 3 */
    const __m256i n01 = _mm256_setr_epi8(Z, Z, 0, 1, Z, Z, 0, 1, Z, Z, 0, 1, Z, Z, 0, 1,    /* narrow: entry 0 */
                                         Z, Z, 2, 3, Z, Z, 2, 3, Z, Z, 2, 3, Z, Z, 2, 3);   /* entry 1 */
    const __m256i n23 = _mm256_setr_epi8(Z, Z, 4, 5, Z, Z, 4, 5, Z, Z, 4, 5, Z, Z, 4, 5,
                                         Z, Z, 6, 7, Z, Z, 6, 7, Z, Z, 6, 7, Z, Z, 6, 7);
    __m256 s01 = _mm256_setzero_ps(), s23 = _mm256_setzero_ps();
#define PAIR(a_, b_) _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(a_)), _mm_loadu_ps(b_), 1)
    if (idx)
        for (size_t k = 0; k < n; k += GROUP) {
            __m256 r01 = PAIR(rad + (size_t)idx[k] * GLANE, rad + (size_t)idx[k + 1] * GLANE);
            __m256 r23 = PAIR(rad + (size_t)idx[k + 2] * GLANE, rad + (size_t)idx[k + 3] * GLANE);
            __m256i bb = _mm256_broadcastsi128_si256(_mm_loadl_epi64((const __m128i *)(eb + k)));
            s01 = _mm256_add_ps(s01, _mm256_mul_ps(r01, _mm256_castsi256_ps(_mm256_shuffle_epi8(bb, n01))));
            s23 = _mm256_add_ps(s23, _mm256_mul_ps(r23, _mm256_castsi256_ps(_mm256_shuffle_epi8(bb, n23))));
        }
    else
        for (size_t k = 0; k < n; k += GROUP) {
            __m256 r01 = PAIR((const float *)(rb + eoff[k]), (const float *)(rb + eoff[k + 1]));
            __m256 r23 = PAIR((const float *)(rb + eoff[k + 2]), (const float *)(rb + eoff[k + 3]));
            __m256i b01 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(_mm_loadu_si128((const __m128i *)(eb + k * EB))), g01);
            __m256i b23 = _mm256_shuffle_epi8(_mm256_broadcastsi128_si256(_mm_loadu_si128((const __m128i *)(eb + k * EB + 4))), g23);
            s01 = _mm256_add_ps(s01, _mm256_mul_ps(r01, _mm256_castsi256_ps(b01)));
            s23 = _mm256_add_ps(s23, _mm256_mul_ps(r23, _mm256_castsi256_ps(b23)));
        }
#undef PAIR
    store3(_mm_add_ps(_mm_add_ps(_mm256_castps256_ps128(s01), _mm256_extractf128_ps(s01, 1)),
                      _mm_add_ps(_mm256_castps256_ps128(s23), _mm256_extractf128_ps(s23, 1))),
           out);
}
#endif

/* eoff (general entries) or idx (narrow ones, eoff NULL) */
static void dot_row(const wrt_gather *g, const uint32_t *eoff, const uint16_t *idx, const uint16_t *eb, size_t n,
                    float out[3]) {
#ifdef WRT_GATHER_AVX2
    if (g->avx2) { dot_avx2(g->rad, eoff, idx, eb, n, out); return; }
#endif
#ifdef __SSE2__
    if (g->simd) { dot_sse2(g->rad, eoff, idx, eb, n, out); return; }
#endif
    dot_plain(g->rad, eoff, idx, eb, n, out);
}

/* L_o at point p of a glossy quad toward the eye: the radiance of its entries' cells
 * summed against their beta toward the eye (made again first when the eye moved: the
 * beta rows of the four outgoing directions around w_o, bilinear). */
static void lout_point(void *user, size_t item) {
    wrt_gather *g = user;
    int q = g->lq;
    size_t p = item;
    const wrt_gather_quad *Q = &g->q[q];
    gquad *G = &g->gq[q];
    float *lo = G->lout + p * 3;
    lo[0] = lo[1] = lo[2] = 0;
    int np = G->pts;
    size_t e0 = G->e0[p], ne = G->e0[p + 1] - e0;
    int nb = G->narrow ? 1 : EB;
    uint16_t *eb = G->ebeta + e0 * (size_t)nb;
    if (g->rows_eye) {
        G->bvis[p] = 0;
        wrt_v3 x = qpoint(Q, ((p % np) + 0.5) / np, ((p / np) + 0.5) / np);
        wrt_v3 wo = v3_norm(v3_sub(v3(g->eye[0], g->eye[1], g->eye[2]), x));
        double loc[3] = {v3_dot(wo, Q->t), v3_dot(wo, Q->b), v3_dot(wo, Q->n)}, a, b;
        if (loc[2] <= 0) return;
        wrt_concentric_inv(loc, &a, &b);
        double fx = a * GATHER_BRES - 0.5, fy = b * GATHER_BRES - 0.5;
        int x0 = (int)floor(fx), y0 = (int)floor(fy);
        double tx = fx - x0, ty = fy - y0;
        const float *bt[4];
        float w[4];
        for (int k = 0; k < 4; k++) {
            int cx = x0 + (k & 1), cy = y0 + (k >> 1);
            cx = cx < 0 ? 0 : cx >= GATHER_BRES ? GATHER_BRES - 1 : cx;
            cy = cy < 0 ? 0 : cy >= GATHER_BRES ? GATHER_BRES - 1 : cy;
            w[k] = (float)(((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty));
            bt[k] = g->beta[G->beta_id] + ((size_t)cy * GATHER_BRES + cx) * NDIR * 3;
        }
        blend_row(bt, w, G->amap + G->a0[p], G->a0[p + 1] - G->a0[p], eb, nb);
        G->bvis[p] = 1;
    }
    if (!G->bvis[p] || ne == 0) return;
    if (G->narrow) dot_row(g, NULL, G->eidx + e0, eb, ne, lo);
    else dot_row(g, G->eoff + e0, NULL, eb, ne, lo);
}

static void out_quad(void *user, size_t item) {
    wrt_gather *g = user;
    int q = g->glossy[item];
    float *o = g->out[q];
    int n = g->out_res[q];
    if (!o || n <= 0) return;
    axis ax[256];
    int np = g->gq[q].pts;
    if (n <= 256) axis_table(np, n, ax);
    for (int j = 0; j < n; j++) {
        axis y = n <= 256 ? ax[j] : axis_at(np, n, j);
        for (int i = 0; i < n; i++) {
            axis x = n <= 256 ? ax[i] : axis_at(np, n, i);
            lerp_cell(g->gq[q].lout, np, &x, &y, o + ((size_t)j * n + i) * 3);
        }
    }
}

void wrt_gather_eye(wrt_gather *g, const double eye[3], float *const *out, const int *out_res) {
    if (!g) return;
    memcpy(g->eye, eye, sizeof g->eye);
    g->out = out; g->out_res = out_res;
    g->rows_eye = !g->have_rows || memcmp(g->rows_at, eye, sizeof g->rows_at) != 0;
    memcpy(g->rows_at, eye, sizeof g->rows_at);
    g->have_rows = 1;
    for (int k = 0; k < g->nglossy; k++) { /* quads in turn: their point counts differ */
        g->lq = g->glossy[k];
        g->env.run(g->env.user, (size_t)g->gq[g->lq].npt, lout_point, g);
    }
    g->env.run(g->env.user, (size_t)g->nglossy, out_quad, g);
}
