/* relight_synth.c: from the indirect incident radiance X to one texture of outgoing
 * indirect radiance per quad (Kontkanen et al. 2006, sections 5.3-5.4; docs/algorithm.md):
 * a Lambertian quad's base/pi x irradiance by Haar synthesis of its angular-root
 * functions; a glossy quad's sum over its angular functions of the synthesized spatial
 * function times the BRDF weight beta toward the eye, per texel (the BRDF table of
 * common/brdf_table.h), skipping an angular function whose beta is below 1e-3 of the
 * root's over every direction the quad sends toward the eye (the paper's Figure 5
 * pruning, per angular function). Per update, the quads whose X changed. Depends on
 * relight_internal.h (quads, per-function tables, workers' scratch, the parallel loop). */
#include "relight_internal.h"

#define PRUNE_REL 1e-3       /* glossy synthesis: skip |beta_g| < PRUNE_REL beta_root */

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

/* Outgoing radiance of a Lambertian quad: base/pi x irradiance, texel averages. The
 * texel factor 2^Lt sqrt(pi/J)/pi (h value x sqrt(pi/J) x 1/pi) and the base colour
 * are folded into the coefficients (synthesis is linear); a non-parallelogram's
 * varying factor is applied after, from r->texk. */
void relight_synth_diffuse(wrt_relight *r, worker *w, int qidx, const float *base, float *tex) {
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
    relight_haar_synthesize4f(pyr, Lt, w->fgrid, tex, 3);
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
        int *nc = relight_grow(r, w->cells, &cc, ncell * 4, sizeof(int));
        if (!nc) return;
        w->cells = nc;
        float *nw = relight_grow(r, w->wts, &cw, cc, sizeof(float));
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
        relight_haar_synthesize4f(pyr, Lt, w->fgrid, vals, 3);
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
    else relight_synth_diffuse(r, w, q, r->mats[r->qi[q].material].base_color, r->tex + r->qi[q].tex_off);
}

/* The quads to synthesize at this update into r->synth_list (a quad whose X is all zero
 * is cleared once instead; a glossy quad waits for an eye, or is the final gather's),
 * each one's smooth-display group marked. Returns their number; *ncleared the quads
 * cleared. */
static int synth_select(wrt_relight *r, int *ncleared) {
    uint32_t nq = r->g->nquads;
    int nsynth = 0;
    *ncleared = 0;
    for (uint32_t q = 0; q < nq; q++) {
        if (!r->resynth[q]) continue;
        r->resynth[q] = 0; /* done here, or by the synthesis (marked again if it waits) */
        if (!r->x_nonzero[q]) { /* all dark: clear once */
            if (r->tex_nonzero[q]) {
                memset(r->tex + r->qi[q].tex_off, 0, ((size_t)1 << (2 * r->qi[q].tex_level)) * 3 * sizeof(float));
                r->tex_nonzero[q] = 0;
                (*ncleared)++;
                if (r->sm.recon) r->sm.regroup[wrt_recon_group(r->sm.recon, (int)q)] = 1;
            }
            continue;
        }
        if (r->qi[q].glossy && !r->have_eye) continue; /* no view yet: waits for set_eye */
        if (r->qi[q].glossy && r->gat.gather) continue;    /* drawn by the final gather */
        r->tex_nonzero[q] = 1;
        r->synth_list[nsynth++] = (int)q;
        if (r->sm.recon) r->sm.regroup[wrt_recon_group(r->sm.recon, (int)q)] = 1;
    }
    return nsynth;
}

/* Synthesizes the textures of the quads that changed (t: brdf and synthesis times).
 * Returns the number of quads whose Haar texture changed, or -1 if memory ran out. */
int relight_synthesize(wrt_relight *r, wrt_relight_timings *t) {
    int ncleared;
    int nsynth = synth_select(r, &ncleared);
    const int *list = r->synth_list;
    for (int tt = 0; tt < r->nthreads; tt++) r->workers[tt].brdf_time = 0;
    synth_ctx sc = {list};
    double t3 = wrt_now();
    double work = 0;
    for (int k = 0; k < nsynth; k++) {
        const quad_info *qi = &r->qi[list[k]];
        work += ldexp(qi->glossy ? 0.3 * qi->nang : 0.015, 2 * qi->tex_level); /* ~3 ns a diffuse texel */
    }
    int done = nsynth;
    if (r->opt.budget_ms <= 0) {
        relight_parallel_for(r, nsynth, work, synth_item, &sc);
    } else { /* in slices while the budget lasts; the rest stays marked for the next update */
        int slice = RELIGHT_SLICE * r->nthreads;
        for (done = 0; done < nsynth && relight_budget_left(r); done += slice) {
            int m = nsynth - done < slice ? nsynth - done : slice;
            sc.list = list + done;
            relight_parallel_for(r, m, work * m / nsynth, synth_item, &sc);
        }
        if (done > nsynth) done = nsynth;
        for (int k = done; k < nsynth; k++) r->resynth[list[k]] = 1;
    }
    r->run.synth_pending = done < nsynth;
    r->run.n.quads_synthesized += done;
    if (atomic_load(&r->upd_oom)) return -1;
    double t4 = wrt_now(), bt = 0;
    for (int tt = 0; tt < r->nthreads; tt++) bt += r->workers[tt].brdf_time;
    int used = r->nthreads < nsynth ? r->nthreads : (nsynth ? nsynth : 1);
    t->brdf = bt / used * 1e3;
    nsynth = done;
    double ts = (t4 - t3) * 1e3 - t->brdf;
    t->synthesis += ts > 0 ? ts : 0; /* a budgeted update's smoothing may come first */
    return nsynth + ncleared;
}
