/* relight.c: the relighter's driver (relight.h): the lights and the eye as the caller
 * sets them (a light that did not change keeps its projection), an update that runs only
 * the stages whose input changed, the accessors and the micro-benchmark. Kontkanen et al.
 * 2006, section 5 (the run-time loop; each stage in its own file: relight_project.c 5.1,
 * relight_multiply.c 5.2, relight_bounce.c the first glossy bounce, relight_synth.c
 * 5.3-5.4, relight_smooth.c the smooth display, relight_gather.c the final gather;
 * relight_create.c makes and frees a relighter; docs/algorithm.md). Depends on
 * relight_internal.h. Not thread-safe: one caller at a time. */
#include "relight_internal.h"

int wrt_relight_angular_index(int level, int x, int y, int type) {
    if (level < 0 || level >= ANG_LEVELS || x < 0 || y < 0 || x >= (1 << level) || y >= (1 << level) || type < 0 || type > 3)
        return -1;
    if (type == 0 && level != 0) return -1;
    return (int)haar_index(level, x, y, type);
}

/* ------------------------------------------------------------ lights, eye ---- */

/* ----------------------------------------------------------------- update ---- */

static int same_light(const wrt_light *a, const wrt_light *b) {
    return a->type == b->type && a->pos.x == b->pos.x && a->pos.y == b->pos.y && a->pos.z == b->pos.z &&
           a->dir.x == b->dir.x && a->dir.y == b->dir.y && a->dir.z == b->dir.z &&
           a->color[0] == b->color[0] && a->color[1] == b->color[1] && a->color[2] == b->color[2] &&
           a->intensity == b->intensity && a->range == b->range && a->inner_cone == b->inner_cone &&
           a->outer_cone == b->outer_cone;
}

/* A new light slot's arrays: its roots, its c over K's columns (with K) and room for its
 * projection (each function at most once), so that no update allocates. -1: no memory
 * (what was made is freed). */
static int light_slot_init(wrt_relight *r, light_state *ls, int slot) {
    size_t nf = (size_t)r->g->nfuncs + 1;
    ls->root = relight_calloc(r, (size_t)r->g->nquads * 3 + 1, sizeof(double));
    if (r->g->nkcols) ls->kc = relight_calloc(r, (size_t)r->g->nkcols * 3, sizeof(float));
    ls->idx = relight_calloc(r, nf, sizeof *ls->idx);
    ls->val = relight_calloc(r, 3 * nf, sizeof *ls->val);
    ls->cap = nf;
    if (r->mul.per_light && slot < WRT_RELIGHT_SUM_MAX)
        ls->X4 = relight_calloc(r, (size_t)r->g->nfuncs * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    if (!r->oom) return 0;
    relight_free(r, ls->root); relight_free(r, ls->kc); relight_free(r, ls->idx); relight_free(r, ls->val);
    relight_free(r, ls->X4);
    memset(ls, 0, sizeof *ls);
    return -1;
}

wrt_status wrt_relight_set_lights(wrt_relight *r, const wrt_light *lights, const float *scales, int n) {
    if (n < 0) n = 0;
    if (n > r->lights_cap) {
        light_state *nl = relight_calloc(r, (size_t)n, sizeof(light_state));
        int made = r->lights_cap;
        while (nl && made < n && light_slot_init(r, &nl[made], made) == 0) made++;
        if (made < n) {
            r->oom = 0;
            for (int i = r->lights_cap; i < made; i++) {
                relight_free(r, nl[i].root); relight_free(r, nl[i].kc); relight_free(r, nl[i].idx); relight_free(r, nl[i].val);
                relight_free(r, nl[i].X4);
            }
            relight_free(r, nl);
            return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory for %d lights", n);
        }
        if (r->lights_cap) memcpy(nl, r->lights, (size_t)r->lights_cap * sizeof(light_state));
        relight_free(r, r->lights);
        r->lights = nl;
        r->lights_cap = n;
    }
    if (n != r->nlights) r->e_dirty = 1;
    for (int i = 0; i < n; i++) {
        light_state *ls = &r->lights[i];
        float s = scales ? scales[i] : 1.0f;
        if (i >= r->nlights || !ls->projected || !same_light(&ls->light, &lights[i])) {
            ls->light = lights[i];
            ls->lc = relight_light_consts(&ls->light);
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

/* An update that ran out of memory: -1 with a message (on the caller's thread); lights
 * not projected stay so, and textures are redone at the next update. */
static int update_nomem(wrt_relight *r, const char *stage, wrt_relight_timings *tm, const wrt_relight_timings *t) {
    r->redo_all = 1;
    if (tm) *tm = *t;
    wrt_fail(WRT_ERR_NOMEM, "relight: out of memory while %s (update abandoned; the next update redoes it)", stage);
    return -1;
}

/* E = sum of the scaled per-light projections, in light order, and the emitters'. */
static void sum_lights(wrt_relight *r) {
    memset(r->E, 0, (size_t)r->g->nfuncs * 3 * sizeof(float));
    for (int i = 0; i < r->nlights; i++) {
        const light_state *ls = &r->lights[i];
        if (ls->scale == 0 || !ls->have_proj) continue;
        for (size_t k = 0; k < ls->n; k++)
            for (int c = 0; c < 3; c++) r->E[(size_t)ls->idx[k] * 3 + c] += ls->scale * ls->val[k * 3 + c];
    }
    relight_add_emitters(r); /* emissive surfaces' source terms (relight_emit.c) */
}

/* skip_below: whether E moved by less than that fraction of the E last multiplied
 * (never after a failed update, and not before a first multiply). */
static int change_too_small(const wrt_relight *r) {
    if (r->opt.skip_below <= 0 || !r->e_applied || r->redo_all) return 0;
    double d = 0, n = 0;
    for (size_t k = 0; k < (size_t)r->g->nfuncs * 3; k++) {
        double a = r->Eapplied[k], b = r->E[k];
        d += (b - a) * (b - a);
        n += a * a;
    }
    return d < r->opt.skip_below * r->opt.skip_below * n;
}

int relight_budget_left(wrt_relight *r) {
    if (r->opt.budget_ms <= 0) return 1;
    if (!r->run.did) { r->run.did = 1; return 1; }
    return wrt_now() < r->run.deadline;
}

/* E (5.2): the sum of the lights, and unless the change is below skip_below the multiply
 * (with K the first bounce first) into X, marking the quads whose X changed. */
static void apply_lights(wrt_relight *r, wrt_relight_timings *t) {
    const wrt_gto *g = r->g;
    r->e_dirty = 0;
    sum_lights(r);
    if (change_too_small(r)) {
        t->skipped = 1;
        r->run.n.skips++;
        return;
    }
    /* With K: the first bounce from its quads, Y = K c, and E' = E off them + Y. */
    const float *src = r->E;
    if (g->nkcols) { relight_first_bounce(r); src = r->k.Ep; }
    if (r->mul.per_light && r->nlights <= WRT_RELIGHT_SUM_MAX) relight_multiply_lights(r); /* the lights that moved */
    else relight_multiply(r, relight_cluster_forward(r, src)); /* the tree's basis and back, if any */
    relight_cluster_inverse(r);
    r->run.n.multiplies++;
    if (r->Eapplied) {
        memcpy(r->Eapplied, r->E, (size_t)g->nfuncs * 3 * sizeof(float));
        r->e_applied = 1;
    }
}

enum { ST_PROJECT, ST_MULTIPLY, ST_SYNTH, ST_SMOOTH, ST_GATHER, ST_COUNT };

/* One stage of an update: 0 done (or nothing to do, or waiting on an earlier stage), 1
 * stopped by the budget with work left, -1 out of memory (the message made). */
static int run_stage(wrt_relight *r, int st, wrt_relight_timings *t, int *nchanged) {
    double t0 = wrt_now();
    switch (st) {
    case ST_PROJECT:
        for (int k = 0; k < r->nlights; k++) { /* budgeted: from the light that waited */
            int i = (r->run.next_light + k) % r->nlights;
            light_state *ls = &r->lights[i];
            if (ls->projected || ls->scale == 0) continue;
            if (!relight_budget_left(r)) { r->run.next_light = i; return 1; }
            ls->have_proj = 0; /* written in place: whole again once it succeeds */
            if (relight_project_light(r, ls) != 0) return -1;
            r->e_dirty = 1;
            t->lights_changed++;
            r->run.n.projections++;
        }
        t->projection += (wrt_now() - t0) * 1e3;
        return 0;
    case ST_MULTIPLY:
        if (!r->e_dirty) return 0;
        if (!relight_budget_left(r)) return 1;
        apply_lights(r, t);
        t->multiply += (wrt_now() - t0) * 1e3;
        return 0;
    case ST_SYNTH: {
        int n = relight_synthesize(r, t);
        if (n < 0) return -1;
        if (!r->sm.recon) *nchanged += n;
        return r->run.synth_pending;
    }
    case ST_SMOOTH: {
        if (!r->sm.recon || r->run.synth_pending) return 0;
        *nchanged += relight_smooth(r);
        t->reconstruction += (wrt_now() - t0) * 1e3;
        t->synthesis += (wrt_now() - t0) * 1e3;
        return r->run.smooth_pending;
    }
    default: {
        int waits = r->e_dirty || r->run.synth_pending || r->run.smooth_pending;
        for (int i = 0; i < r->nlights && !waits; i++) waits = !r->lights[i].projected && r->lights[i].scale != 0;
        if (waits || !(r->run.gl_lights || r->run.gl_eye)) return 0;
        if (!relight_budget_left(r)) return 1;
        int ngl = relight_gather(r, r->run.gl_lights, r->run.gl_eye); /* gather.h */
        if (ngl < 0) return -1;
        r->run.gl_lights = r->run.gl_eye = 0;
        if (ngl > 0) { t->synthesis += (wrt_now() - t0) * 1e3; r->run.n.gathers++; }
        *nchanged += ngl;
        return 0;
    }
    }
}

/* The stages of an update, each only when what it reads changed: the projection of
 * every light that moved (section 5.1), E and the multiply when a light changed (5.2;
 * with K the first bounce first), the synthesis of the quads whose X changed or, glossy,
 * whose view moved (5.3-5.4), their groups' smooth display, and the final gather. With
 * a budget a call starts at the stage where the last one stopped and goes round once,
 * so a light that moves every frame does not starve the stages after its projection:
 * the multiply then sums each light's last whole projection (an older but consistent
 * E), the smoothing waits until every marked quad is synthesized and the gather until
 * everything before it is done. */
int wrt_relight_update(wrt_relight *r, wrt_relight_timings *tm) {
    wrt_relight_timings t = {0};
    uint32_t nq = r->g->nquads;
    r->run.deadline = wrt_now() + r->opt.budget_ms * 1e-3;
    r->run.did = 0;
    r->run.n.updates++;
    atomic_store(&r->upd_oom, 0);
    r->run.gl_lights |= r->e_dirty || r->redo_all;
    r->run.gl_eye |= r->eye_dirty || r->redo_all;
    if (r->redo_all) { /* the last update failed part way: every texture again */
        memset(r->resynth, 1, nq);
        memset(r->tex_nonzero, 1, nq); /* dark quads: cleared again */
    }
    if (r->eye_dirty) {
        r->eye_dirty = 0;
        for (uint32_t q = 0; q < nq; q++)
            if (r->qi[q].glossy && r->x_nonzero[q]) r->resynth[q] = 1;
    }
    static const char *what[ST_COUNT] = {"projecting a light", "multiplying", "synthesizing textures",
                                         "smoothing textures", "gathering glossy light"};
    int start = r->opt.budget_ms > 0 ? r->run.resume : 0, stopped = -1, nchanged = 0;
    for (int k = 0; k < ST_COUNT; k++) {
        int st = (start + k) % ST_COUNT;
        int rc = run_stage(r, st, &t, &nchanged);
        if (rc < 0) return update_nomem(r, what[st], tm, &t);
        if (rc > 0 && stopped < 0) stopped = st;
    }
    /* a light moved while its stage was behind us: pending too */
    int waits = r->e_dirty || r->run.synth_pending || r->run.smooth_pending || r->run.gl_lights || r->run.gl_eye;
    for (int i = 0; i < r->nlights && !waits; i++) waits = !r->lights[i].projected && r->lights[i].scale != 0;
    /* the next call resumes where this one stopped, except that the projection gets one
     * whole call at most once every light has a whole projection: lights that keep moving
     * would otherwise keep every later stage waiting (the multiply then sums their last
     * whole projections); a light never projected is not left out of E */
    int all_whole = 1;
    for (int i = 0; i < r->nlights; i++) all_whole &= r->lights[i].have_proj || r->lights[i].scale == 0;
    r->run.resume = stopped < 0 ? 0 : stopped == ST_PROJECT && start == ST_PROJECT && all_whole ? ST_MULTIPLY : stopped;
    if (r->opt.budget_ms <= 0) r->run.next_light = 0;
    t.pending = waits || stopped >= 0;
    t.quads_resynthesized = nchanged;
    r->redo_all = 0;
    if (tm) *tm = t;
    return nchanged;
}

void wrt_relight_get_counters(const wrt_relight *r, wrt_relight_counters *out) { *out = r->run.n; }

wrt_status wrt_relight_set_budget(wrt_relight *r, double budget_ms, double skip_below) {
    if (!(budget_ms >= 0 && budget_ms <= 1e9))
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: budget_ms %g: milliseconds in [0, 1e9] (0: no budget)", budget_ms);
    if (!(skip_below >= 0 && skip_below < 1))
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: skip_below %g: a fraction in [0, 1)", skip_below);
    if (skip_below > 0 && !r->Eapplied) {
        r->Eapplied = relight_calloc(r, (size_t)r->g->nfuncs * 3 + 1, sizeof(float));
        if (!r->Eapplied) { r->oom = 0; return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory for skip_below's E"); }
        r->e_applied = 0; /* the next multiply is applied, and remembered */
    }
    r->opt.budget_ms = budget_ms;
    r->opt.skip_below = skip_below;
    return WRT_OK;
}

/* ------------------------------------------------------------- accessors ---- */

int wrt_relight_tex_res(const wrt_relight *r, int q) {
    if (q < 0 || q >= (int)r->g->nquads) return 0;
    return 1 << (r->sm.recon ? r->qi[q].stex_level : r->qi[q].tex_level);
}

const float *wrt_relight_tex(const wrt_relight *r, int q) {
    if (q < 0 || q >= (int)r->g->nquads) return NULL;
    return r->sm.recon ? r->sm.stex + r->qi[q].stex_off : r->tex + r->qi[q].tex_off;
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
const float *wrt_relight_Y(const wrt_relight *r) { return r->k.Y; }
const float *wrt_relight_X(const wrt_relight *r) { return r->X; }

double wrt_relight_bench(wrt_relight *r, int updates, wrt_relight_timings *mean) {
    wrt_relight_timings sum = {0};
    if (mean) *mean = sum;
    if (r->nlights == 0 || updates <= 0) return -1;
    wrt_light *ls = relight_calloc(r, (size_t)r->nlights, sizeof(wrt_light));
    float *sc = relight_calloc(r, (size_t)r->nlights, sizeof(float));
    if (r->oom) { r->oom = 0; relight_free(r, ls); relight_free(r, sc); return -1; }
    for (int i = 0; i < r->nlights; i++) { ls[i] = r->lights[i].light; sc[i] = r->lights[i].scale; }
    wrt_v3 p0 = ls[0].pos;
    double rad = 0.02 * r->rt.scene_diag, t0 = wrt_now();
    for (int k = 0; k < updates; k++) {
        double a = 2 * WRT_PI * (k + 1) / updates;
        ls[0].pos = v3(p0.x + rad * cos(a), p0.y, p0.z + rad * sin(a));
        wrt_relight_set_lights(r, ls, sc, r->nlights);
        wrt_relight_timings t;
        if (wrt_relight_update(r, &t) < 0) { relight_free(r, ls); relight_free(r, sc); return -1; }
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
    relight_free(r, ls); relight_free(r, sc);
    return ms;
}
