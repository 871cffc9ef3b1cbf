/* relight_gather.c: the relighter's side of the final gather on glossy quads
 * (player/gather.h; docs/glossy/gather_runtime.md): what the gather needs from it (its parallel loop
 * and allocator, the direct light of every light at a point with its shadow ray, each
 * quad's displayed texture and a glossy quad's diffuse stand-in, albedo/pi x indirect
 * irradiance), set up at creation and run at an update when the lights or the eye moved.
 * Not in Kontkanen et al. 2006, whose glossy quads show the coarse angular synthesis
 * (relight_synth.c; options.no_gather keeps it). Depends on relight_internal.h and gather.h. */
#include "relight_internal.h"

/* The final gather on glossy quads (gather.h) unless options.no_gather turns it off (the
 * coarse angular synthesis alone: for before/after measurements). */
int relight_gather_wanted(const wrt_relight *r) { return !r->opt.no_gather; }

/* The final gather's loops and memory (gather.h): the relighter's own. */
typedef struct gather_job { wrt_gather_item_fn fn; void *ctx; } gather_job;
static void gather_item(wrt_relight *r, worker *w, int item, void *ctx) {
    (void)r; (void)w;
    const gather_job *j = ctx;
    j->fn(j->ctx, (size_t)item);
}
static void gather_run(void *user, size_t n, wrt_gather_item_fn fn, void *ctx) {
    gather_job j = {fn, ctx};
    relight_parallel_for(user, (int)n, 1e9, gather_item, &j);
}
static void *gather_alloc(void *user, size_t bytes) { return relight_calloc(user, 1, bytes); }
static void gather_free(void *user, void *p) { relight_free(user, p); }
static int gather_progress(void *user, double f) {
    return relight_progress(user, PROGRESS_GATHER + (1 - PROGRESS_GATHER) * f);
}

/* The final gather's direct irradiance: every light at a row of points (colour, scale,
 * shadow rays four at a time, as the projection's), summed in light order. */
static void gather_direct(void *user, const wrt_v3 *x, int n, wrt_v3 nrm, double *out) {
    const wrt_relight *r = user;
    for (int k = 0; k < 3 * n; k++) out[k] = 0;
    for (int i = 0; i < r->nlights; i++) {
        const light_state *ls = &r->lights[i];
        if (ls->scale == 0) continue;
        for (int k0 = 0; k0 < n; k0 += 4) {
            int n4 = n - k0 < 4 ? n - k0 : 4, need[4], vis[4];
            wrt_v3 dir[4];
            double d[4], e[4];
            for (int t = 0; t < n4; t++) {
                d[t] = 0;
                e[t] = light_irradiance(&ls->lc, x[k0 + t], nrm, &dir[t], &d[t]);
                need[t] = e[t] != 0;
            }
            light_visible4(r, n4, x + k0, nrm, dir, d, need, vis);
            for (int t = 0; t < n4; t++) {
                if (e[t] == 0 || !vis[t]) continue;
                for (int c = 0; c < 3; c++) out[(k0 + t) * 3 + c] += ls->scale * ls->light.color[c] * e[t];
            }
        }
    }
}

/* Per material the cosine-weighted mean over w_o of beta_root (the mean directional
 * albedo; a Lambertian material's base colour); per quad what the gather sees of it.
 * Returns the quads (the caller frees them), or NULL if there is no memory. */
static wrt_gather_quad *gather_quads(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads;
    wrt_gather_quad *gqs = relight_calloc(r, nq ? nq : 1, sizeof *gqs);
    if (!gqs) return NULL;
    r->gat.alb = relight_calloc(r, g->nmaterials + 1, sizeof *r->gat.alb);
    if (!r->gat.alb) { relight_free(r, gqs); return NULL; }
    for (uint32_t m = 0; m < g->nmaterials; m++) {
        if (!r->beta[m]) { for (int c = 0; c < 3; c++) r->gat.alb[m][c] = r->mats[m].base_color[c]; continue; }
        double sum[3] = {0, 0, 0};
        for (int k = 0; k < BETA_RES * BETA_RES; k++)
            for (int c = 0; c < 3; c++) sum[c] += r->beta[m][((size_t)k * NANG) * 3 + c];
        for (int c = 0; c < 3; c++) r->gat.alb[m][c] = (float)(sum[c] / (BETA_RES * BETA_RES));
    }
    for (uint32_t q = 0; q < nq; q++) {
        const quad_info *qi = &r->qi[q];
        memcpy(gqs[q].p, qi->p, sizeof gqs[q].p);
        memcpy(gqs[q].albedo, r->gat.alb[qi->material], sizeof gqs[q].albedo);
        gqs[q].n = qi->n; gqs[q].t = qi->t; gqs[q].b = qi->b;
        gqs[q].mat = &r->mats[qi->material];
    }
    return gqs;
}

/* The textures the gather reads (a glossy quad's: its diffuse stand-in, gat.diff) and
 * writes (a glossy quad's displayed texture). WRT_ERR_NOMEM. */
static wrt_status gather_textures(wrt_relight *r) {
    uint32_t nq = r->g->nquads;
    r->gat.tex = relight_calloc(r, nq, sizeof *r->gat.tex);
    r->gat.out = relight_calloc(r, nq, sizeof *r->gat.out);
    r->gat.diff = relight_calloc(r, nq, sizeof *r->gat.diff);
    if (!r->gat.tex || !r->gat.out || !r->gat.diff) return WRT_ERR_NOMEM;
    for (uint32_t q = 0; q < nq; q++) {
        r->gat.tex[q] = wrt_relight_tex(r, (int)q);
        r->gat.out[q] = (float *)r->gat.tex[q];
        if (!r->qi[q].glossy) continue;
        r->gat.diff[q] = relight_calloc(r, (size_t)r->gat.ires[q] * r->gat.ires[q] * 3, sizeof(float));
        if (!r->gat.diff[q]) return WRT_ERR_NOMEM;
        r->gat.tex[q] = r->gat.diff[q];
    }
    return relight_display_rows_operator(r) != 0 ? WRT_ERR_NOMEM : WRT_OK;
}

/* The final gather (gather.h), when options.no_gather is 0 and a quad is glossy; after
 * the textures, the BRDF tables and Embree's scene. WRT_ERR_NOMEM, WRT_ERR_CANCELLED. */
wrt_status relight_setup_gather(wrt_relight *r) {
    if (!relight_gather_wanted(r)) return WRT_OK;
    uint32_t nq = r->g->nquads;
    wrt_gather_quad *gqs = gather_quads(r);
    if (!gqs) return WRT_ERR_NOMEM;
    r->gat.res = relight_calloc(r, nq ? nq : 1, sizeof *r->gat.res);
    r->gat.ires = relight_calloc(r, nq ? nq : 1, sizeof *r->gat.ires);
    if (!r->gat.res || !r->gat.ires) { relight_free(r, gqs); return WRT_ERR_NOMEM; }
    for (uint32_t q = 0; q < nq; q++) { /* displayed sides; the gather reads gdiff (below) of glossy quads */
        r->gat.ires[q] = r->gat.res[q] = wrt_relight_tex_res(r, (int)q);
        if (r->qi[q].glossy) r->gat.ires[q] = 1 << r->qi[q].tex_level;
    }
    /* pieces of 4 points a thread between progress calls: 8192 rays on 2 threads, 20-90 ms
     * on this loaded 2-core machine */
    wrt_gather_env genv = {gather_run, gather_alloc, gather_free, r, gather_progress, 4 * r->nthreads, r->opt.no_avx ? 2 : 0, 0};
    wrt_status gs = wrt_gather_create((int)nq, gqs, r->gat.res, r->rt.scene, r->rt.origin, r->rt.eps,
                                      r->opt.gather_points, &genv, &r->gat.gather);
    relight_free(r, gqs);
    if (gs == WRT_ERR_CANCELLED) return wrt_fail(WRT_ERR_CANCELLED, "relight: cancelled by the progress callback");
    if (gs != WRT_OK) return WRT_ERR_NOMEM;
    return r->gat.gather ? gather_textures(r) : WRT_OK;
}

/* The gather's part of an update, once the eye is known: its incident light again when
 * the lights moved (lights_moved), then the glossy quads' textures toward the eye.
 * Returns the number of glossy quads redrawn, or -1 if memory ran out. */
int relight_gather(wrt_relight *r, int lights_moved, int eye_moved) {
    uint32_t nq = r->g->nquads;
    if (lights_moved) r->gat.lin_dirty = 1;
    if (!r->gat.gather || !r->have_eye || !(r->gat.lin_dirty || eye_moved)) return 0;
    if (r->gat.lin_dirty) {
        /* A glossy quad seen by a gather ray sends its mean albedo / pi times its
         * indirect irradiance (its angular-root functions): exact for uniform
         * incident light, a diffuse approximation of its lobe otherwise. */
        for (uint32_t q = 0; q < nq; q++)
            if (r->gat.diff[q]) relight_synth_diffuse(r, &r->workers[0], (int)q, r->gat.alb[r->qi[q].material], r->gat.diff[q]);
        if (atomic_load(&r->upd_oom)) return -1;
        wrt_gather_lights(r->gat.gather, gather_direct, r, r->gat.tex, r->gat.ires);
    }
    r->gat.lin_dirty = 0;
    wrt_gather_eye(r->gat.gather, r->eye, r->gat.out, r->gat.res);
    int n = 0;
    for (uint32_t q = 0; q < nq; q++) n += r->qi[q].glossy;
    return n;
}
