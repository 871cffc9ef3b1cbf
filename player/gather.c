/* gather.c: the final gather on glossy quads (gather.h). */
#include "gather.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/basis.h"
#include "../common/brdf.h"

#define GATHER_PTS 16   /* points a side on a glossy quad (cell centres) */
#define GATHER_DIRS 32  /* incident cells a side of the concentric map */
#define GATHER_BRES 32  /* outgoing directions a side of the beta table */
#define GATHER_BSAMP 3  /* samples a side per incident cell when integrating beta */
#define GATHER_DTEX 32  /* direct-irradiance grid a side on a quad that a gather ray sees */
#define GATHER_RG 64    /* outgoing-radiance grid a side on it (what a gather entry reads) */

#define NDIR (GATHER_DIRS * GATHER_DIRS)
#define NPT (GATHER_PTS * GATHER_PTS)

typedef struct ghit { int32_t quad; float u, v; } ghit;
#define RG2 (GATHER_RG * GATHER_RG)

typedef struct gquad {
    int glossy;
    ghit *hits;       /* NPT x NDIR (glossy quads): what each ray sees (at creation) */
    int32_t *cell;    /* NPT x NDIR: slot x RG2 + radiance cell it reads, -1: nothing */
    float *lin;       /* NPT x NDIR x 3: L_in */
    float *lout;      /* NPT x 3: L_o toward the eye at the points */
    int beta_id;      /* index into g->beta */
} gquad;

struct wrt_gather {
    int nq;
    const wrt_gather_quad *q0;
    wrt_gather_quad *q;
    gquad *gq;
    int *glossy; int nglossy;
    int32_t *slot;     /* per quad: its slot among the diffuse quads some ray sees, -1 */
    int *slot_quad; int nslot;
    float *direct;     /* nslot x GATHER_DTEX^2 x 3: direct irradiance */
    float *rad;        /* nslot x RG2 x 3: outgoing radiance (direct + indirect) */
    float **beta;      /* per glossy quad's material: GATHER_BRES^2 x NDIR x 3 */
    const wrt_material **beta_mat; int nbeta;
    RTCScene scene; wrt_v3 origin; double eps;
    wrt_gather_env env;
    /* per loop */
    wrt_gather_direct_fn dfn; void *duser;
    const float *const *tex; const int *tex_res;
    double eye[3];
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

/* -------------------------------------------------------------- creation ---- */

typedef struct trace_ctx { wrt_gather *g; int gq; } trace_ctx;

static void trace_point(size_t item, void *user) {
    trace_ctx *tc = user;
    wrt_gather *g = tc->g;
    const wrt_gather_quad *q = &g->q[tc->gq];
    int pi = (int)item % GATHER_PTS, pj = (int)item / GATHER_PTS;
    wrt_v3 x = qpoint(q, (pi + 0.5) / GATHER_PTS, (pj + 0.5) / GATHER_PTS);
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

typedef struct beta_ctx { wrt_gather *g; int b; } beta_ctx;

/* beta(a, w_o) = int_cell f_r cos dw = pi int_cell f_r da db (cosine-weighted map). */
static void beta_row(size_t item, void *user) {
    beta_ctx *bc = user;
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

wrt_status wrt_gather_create(int nq, const wrt_gather_quad *q, RTCScene scene, wrt_v3 origin, double eps,
                             const wrt_gather_env *env, wrt_gather **out) {
    *out = NULL;
    int ng = 0;
    for (int i = 0; i < nq; i++) ng += is_glossy(q[i].mat);
    if (!ng) return WRT_OK;
    wrt_gather *g = env->alloc(env->user, sizeof *g);
    if (!g) return WRT_ERR_NOMEM;
    g->env = *env;
    g->nq = nq; g->scene = scene; g->origin = origin; g->eps = eps;
    g->q = ga(g, (size_t)nq * sizeof *g->q);
    g->gq = ga(g, ((size_t)nq) * sizeof *g->gq);
    g->glossy = ga(g, (size_t)ng * sizeof(int));
    g->slot = ga(g, (size_t)nq * sizeof(int32_t));
    g->slot_quad = ga(g, (size_t)nq * sizeof(int));
    g->beta = ga(g, ((size_t)ng) * sizeof(float *));
    g->beta_mat = ga(g, ((size_t)ng) * sizeof(wrt_material *));
    if (!g->q || !g->gq || !g->glossy || !g->slot || !g->slot_quad || !g->beta || !g->beta_mat) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
    memcpy(g->q, q, (size_t)nq * sizeof *g->q);
    for (int i = 0; i < nq; i++) g->slot[i] = -1;
    for (int i = 0; i < nq; i++) {
        if (!is_glossy(q[i].mat)) continue;
        gquad *G = &g->gq[i];
        G->glossy = 1;
        g->glossy[g->nglossy++] = i;
        G->hits = ga(g, (size_t)NPT * NDIR * sizeof(ghit));
        G->lin = ga(g, ((size_t)NPT * NDIR * 3) * sizeof(float));
        G->lout = ga(g, ((size_t)NPT * 3) * sizeof(float));
        if (!G->hits || !G->lin || !G->lout) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
        G->beta_id = -1;
        for (int b = 0; b < g->nbeta; b++) if (g->beta_mat[b] == q[i].mat) G->beta_id = b;
        if (G->beta_id < 0) {
            G->beta_id = g->nbeta;
            g->beta_mat[g->nbeta] = q[i].mat;
            g->beta[g->nbeta] = ga(g, (size_t)GATHER_BRES * GATHER_BRES * NDIR * 3 * sizeof(float));
            if (!g->beta[g->nbeta]) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
            beta_ctx bc = {g, g->nbeta};
            g->env.run(g->env.user, (size_t)GATHER_BRES * GATHER_BRES, beta_row, &bc);
            g->nbeta++;
        }
        trace_ctx tc = {g, i};
        g->env.run(g->env.user, NPT, trace_point, &tc);
        for (size_t k = 0; k < (size_t)NPT * NDIR; k++) {
            int hq = G->hits[k].quad;
            if (hq < 0 || g->slot[hq] >= 0) continue;
            g->slot[hq] = g->nslot;
            g->slot_quad[g->nslot++] = hq;
        }
    }
    /* Each ray reads the nearest cell of its quad's radiance grid: a table, not a search. */
    for (int k = 0; k < g->nglossy; k++) {
        gquad *G = &g->gq[g->glossy[k]];
        G->cell = ga(g, (size_t)NPT * NDIR * sizeof(int32_t));
        if (!G->cell) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
        for (size_t e = 0; e < (size_t)NPT * NDIR; e++) {
            const ghit *h = &G->hits[e];
            if (h->quad < 0 || g->slot[h->quad] < 0) { G->cell[e] = -1; continue; }
            int cx = (int)(h->u * GATHER_RG), cy = (int)(h->v * GATHER_RG);
            cx = cx < 0 ? 0 : cx >= GATHER_RG ? GATHER_RG - 1 : cx;
            cy = cy < 0 ? 0 : cy >= GATHER_RG ? GATHER_RG - 1 : cy;
            G->cell[e] = g->slot[h->quad] * RG2 + cy * GATHER_RG + cx;
        }
        gf(g, G->hits);
        G->hits = NULL;
    }
    g->direct = ga(g, ((size_t)(g->nslot ? g->nslot : 1) * GATHER_DTEX * GATHER_DTEX * 3) * sizeof(float));
    g->rad = ga(g, ((size_t)(g->nslot ? g->nslot : 1) * RG2 * 3) * sizeof(float));
    if (!g->direct || !g->rad) { wrt_gather_destroy(g); return WRT_ERR_NOMEM; }
    *out = g;
    return WRT_OK;
}

void wrt_gather_destroy(wrt_gather *g) {
    if (!g) return;
    if (g->gq)
        for (int i = 0; i < g->nq; i++) { gf(g, g->gq[i].hits); gf(g, g->gq[i].cell); gf(g, g->gq[i].lin); gf(g, g->gq[i].lout); }
    for (int b = 0; b < g->nbeta; b++) gf(g, g->beta[b]);
    gf(g, g->beta); gf(g, g->beta_mat); gf(g, g->direct); gf(g, g->rad); gf(g, g->slot); gf(g, g->slot_quad); gf(g, g->glossy); gf(g, g->gq); gf(g, g->q);
    gf(g, g);
}

/* ---------------------------------------------------------- light change ---- */

static void direct_row(size_t item, void *user) {
    wrt_gather *g = user;
    int s = (int)(item / GATHER_DTEX), j = (int)(item % GATHER_DTEX);
    const wrt_gather_quad *Q = &g->q[g->slot_quad[s]];
    float *d = g->direct + ((size_t)s * GATHER_DTEX + j) * GATHER_DTEX * 3;
    for (int i = 0; i < GATHER_DTEX; i++) {
        double e[3];
        g->dfn(g->duser, qpoint(Q, (i + 0.5) / GATHER_DTEX, (j + 0.5) / GATHER_DTEX), Q->n, e);
        for (int c = 0; c < 3; c++) d[i * 3 + c] = (float)e[c];
    }
}

/* Bilinear lookup of an n x n RGB grid of cell values at (u, v), clamped at the edges. */
static void bilerp(const float *t, int n, double u, double v, float out[3]) {
    double fx = u * n - 0.5, fy = v * n - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    out[0] = out[1] = out[2] = 0;
    for (int k = 0; k < 4; k++) {
        int cx = x0 + (k & 1), cy = y0 + (k >> 1);
        cx = cx < 0 ? 0 : cx >= n ? n - 1 : cx;
        cy = cy < 0 ? 0 : cy >= n ? n - 1 : cy;
        float w = (float)(((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty));
        const float *p = t + ((size_t)cy * n + cx) * 3;
        for (int c = 0; c < 3; c++) out[c] += w * p[c];
    }
}

/* Row j of slot s's radiance grid: base/pi x direct + the displayed indirect radiance. */
static void rad_row(size_t item, void *user) {
    wrt_gather *g = user;
    int s = (int)(item / GATHER_RG), j = (int)(item % GATHER_RG), hq = g->slot_quad[s];
    const float *base = g->q[hq].albedo;
    const float *dt = g->direct + (size_t)s * GATHER_DTEX * GATHER_DTEX * 3;
    float *o = g->rad + ((size_t)s * RG2 + (size_t)j * GATHER_RG) * 3;
    double v = (j + 0.5) / GATHER_RG;
    for (int i = 0; i < GATHER_RG; i++) {
        double u = (i + 0.5) / GATHER_RG;
        float dv[3], iv[3] = {0, 0, 0};
        bilerp(dt, GATHER_DTEX, u, v, dv);
        if (g->tex[hq] && g->tex_res[hq] > 0) bilerp(g->tex[hq], g->tex_res[hq], u, v, iv);
        for (int c = 0; c < 3; c++) o[i * 3 + c] = (float)(base[c] / M_PI) * dv[c] + iv[c];
    }
}

static void lin_point(size_t item, void *user) {
    wrt_gather *g = user;
    int q = g->glossy[item / NPT];
    size_t p = item % NPT;
    const int32_t *cell = g->gq[q].cell + p * NDIR;
    float *lin = g->gq[q].lin + p * NDIR * 3;
    for (int a = 0; a < NDIR; a++) {
        float *l = lin + a * 3;
        if (cell[a] < 0) { l[0] = l[1] = l[2] = 0; continue; } /* sees nothing (or a back) */
        const float *rv = g->rad + (size_t)cell[a] * 3;
        l[0] = rv[0]; l[1] = rv[1]; l[2] = rv[2];
    }
}

void wrt_gather_lights(wrt_gather *g, wrt_gather_direct_fn direct, void *user, const float *const *tex,
                       const int *tex_res) {
    if (!g) return;
    g->dfn = direct; g->duser = user; g->tex = tex; g->tex_res = tex_res;
    g->env.run(g->env.user, (size_t)g->nslot * GATHER_DTEX, direct_row, g);
    g->env.run(g->env.user, (size_t)g->nslot * GATHER_RG, rad_row, g);
    g->env.run(g->env.user, (size_t)g->nglossy * NPT, lin_point, g);
}

/* ------------------------------------------------------------- eye move ---- */

static void lout_point(size_t item, void *user) {
    wrt_gather *g = user;
    int q = g->glossy[item / NPT];
    size_t p = item % NPT;
    const wrt_gather_quad *Q = &g->q[q];
    gquad *G = &g->gq[q];
    float *lo = G->lout + p * 3;
    lo[0] = lo[1] = lo[2] = 0;
    wrt_v3 x = qpoint(Q, ((p % GATHER_PTS) + 0.5) / GATHER_PTS, ((p / GATHER_PTS) + 0.5) / GATHER_PTS);
    wrt_v3 wo = v3_norm(v3_sub(v3(g->eye[0], g->eye[1], g->eye[2]), x));
    double loc[3] = {v3_dot(wo, Q->t), v3_dot(wo, Q->b), v3_dot(wo, Q->n)}, a, b;
    if (loc[2] <= 0) return;
    wrt_concentric_inv(loc, &a, &b);
    double fx = a * GATHER_BRES - 0.5, fy = b * GATHER_BRES - 0.5;
    int x0 = (int)floor(fx), y0 = (int)floor(fy);
    double tx = fx - x0, ty = fy - y0;
    const float *lin = G->lin + p * NDIR * 3;
    double s[3] = {0, 0, 0};
    for (int k = 0; k < 4; k++) {
        int cx = x0 + (k & 1), cy = y0 + (k >> 1);
        cx = cx < 0 ? 0 : cx >= GATHER_BRES ? GATHER_BRES - 1 : cx;
        cy = cy < 0 ? 0 : cy >= GATHER_BRES ? GATHER_BRES - 1 : cy;
        double w = ((k & 1) ? tx : 1 - tx) * ((k >> 1) ? ty : 1 - ty);
        if (w == 0) continue;
        const float *bt = g->beta[G->beta_id] + ((size_t)cy * GATHER_BRES + cx) * NDIR * 3;
        float acc[3] = {0, 0, 0};
        for (int i = 0; i < NDIR * 3; i += 3) {
            acc[0] += lin[i] * bt[i]; acc[1] += lin[i + 1] * bt[i + 1]; acc[2] += lin[i + 2] * bt[i + 2];
        }
        for (int c = 0; c < 3; c++) s[c] += w * acc[c];
    }
    for (int c = 0; c < 3; c++) lo[c] = (float)s[c];
}

static void out_quad(size_t item, void *user) {
    wrt_gather *g = user;
    int q = g->glossy[item];
    float *o = g->out[q];
    int n = g->out_res[q];
    if (!o || n <= 0) return;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) bilerp(g->gq[q].lout, GATHER_PTS, (i + 0.5) / n, (j + 0.5) / n, o + ((size_t)j * n + i) * 3);
}

void wrt_gather_eye(wrt_gather *g, const double eye[3], float *const *out, const int *out_res) {
    if (!g) return;
    memcpy(g->eye, eye, sizeof g->eye);
    g->out = out; g->out_res = out_res;
    g->env.run(g->env.user, (size_t)g->nglossy * NPT, lout_point, g);
    g->env.run(g->env.user, (size_t)g->nglossy, out_quad, g);
}
