/* relight_smooth.c: the smooth display (common/reconstruct.h; docs/algorithm.md): quads
 * that share edges and a material form groups, and each group's Haar textures are
 * resampled into one smooth, continuous texture per quad, meant to be sampled bilinearly.
 * Not in Kontkanen et al. 2006, whose textures are the Haar cells as they are (which
 * options.haar_blocks keeps). At creation: the groups, each member's texel levels and
 * texture offsets, which nodes hold a function; per update, the groups whose Haar
 * textures changed. Depends on relight_internal.h and common/reconstruct.h. */
#include "relight_internal.h"

/* The smooth texture has the resolution of the finest cells (2^(slevel+1) a side, capped
 * by max_tex_res): one level finer was measured no better (cornell, quality 5: image error
 * 3.42% against 3.44%) for 4 times the texels, one level coarser worse (3.66%). Which of
 * the bake's averages are kept: reconstruct.h's defaults, chosen by measurement (README,
 * "Smooth display"). */
#define RECON_EXTRA 0

/* The groups (reconstruct.h): neighbours and groups from the quads' corners and
 * materials, and the per-update scratch. WRT_ERR_NOMEM. */
static wrt_status smooth_groups(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads;
    double (*corners)[4][3] = relight_calloc(r, nq ? nq : 1, sizeof *corners);
    uint32_t *mat = relight_calloc(r, nq ? nq : 1, sizeof(uint32_t));
    if (r->oom) { relight_free(r, corners); relight_free(r, mat); return WRT_ERR_NOMEM; }
    for (uint32_t q = 0; q < nq; q++) {
        memcpy(corners[q], g->quads[q].p, sizeof corners[q]);
        mat[q] = g->quads[q].material;
    }
    wrt_recon_allocator ral = {r->opt.alloc, r->opt.free, r->opt.alloc_user};
    /* a curved mesh's corner normals (file version 1.3) join its quads across smooth edges */
    const float (*nrm)[4][3] = g->normals ? (const float (*)[4][3])g->normals : NULL;
    r->sm.recon = wrt_recon_create_smooth((int)nq, (const double (*)[4][3])corners, mat, nrm, WRT_RECON_SMOOTH_COS, &ral);
    relight_free(r, corners);
    relight_free(r, mat);
    if (!r->sm.recon) return WRT_ERR_NOMEM;
    int ng = wrt_recon_ngroups(r->sm.recon);
    r->sm.regroup = relight_calloc(r, (size_t)ng + 1, 1);
    r->sm.rin = relight_calloc(r, (size_t)nq + 1, sizeof *r->sm.rin);
    r->sm.rknown = relight_calloc(r, (size_t)nq + 1, sizeof *r->sm.rknown);
    r->sm.rout = relight_calloc(r, (size_t)nq + 1, sizeof *r->sm.rout);
    return r->oom ? WRT_ERR_NOMEM : WRT_OK;
}

/* Every member of a group gets the group's deepest texel level (so the group is
 * resampled at one resolution), its smooth texture RECON_EXTRA levels finer (capped),
 * or the gather's resolution on a sharp reflection. */
static void smooth_levels(wrt_relight *r) {
    int ng = wrt_recon_ngroups(r->sm.recon);
    int extra = r->opt.recon_extra != 0 ? r->opt.recon_extra : RECON_EXTRA;
    for (int gr = 0; gr < ng; gr++) {
        int nm, L = 0;
        const int *mem = wrt_recon_members(r->sm.recon, gr, &nm);
        int sharp = 0;
        for (int k = 0; k < nm; k++) {
            if (r->qi[mem[k]].tex_level > L) L = r->qi[mem[k]].tex_level;
            if (r->qi[mem[k]].glossy && wrt_gather_sharp(&r->mats[r->qi[mem[k]].material])) sharp = 1;
        }
        int Lo = L + extra < r->max_tex_level ? L + extra : r->max_tex_level;
        if (Lo < 1) Lo = L < 1 ? L : 1;
        /* a group joined across a curved mesh's edges (file 1.3) gets at least 4 x 4 texels
         * a quad: at 2 x 2 every texel is an edge or corner texel and none inside can give
         * back what the edges take, so each facet kept its own mean as a visible tile */
        if (r->g->normals && nm > 1 && Lo < 2 && r->max_tex_level >= 2) Lo = 2;
        /* a sharp reflection is gathered a point per texel: its texture has the gather's
         * resolution whatever the depth of the quad's cells in the file (glossy links are
         * refined at a lower quality: cornell-glossy r0.1 at quality 5, texture 16 -> 32:
         * 64 x 64 pixels at 1024 paths: image rmse 0.321 -> 0.262, floor 0.235; r0.3: 0.112
         * -> 0.091, floor 0.069) */
        if (sharp && relight_gather_wanted(r)) {
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
}

/* The texel offsets of the Haar and the smooth textures (*tex_total: the Haar texels x 3),
 * and per quad which nodes hold a function. WRT_ERR_NOMEM. */
static wrt_status smooth_layout(wrt_relight *r, size_t *tex_total) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads;
    size_t total = 0, stotal = 0;
    for (uint32_t q = 0; q < nq; q++) {
        quad_info *qi = &r->qi[q];
        const wrt_gto_quad *gq = &g->quads[q];
        qi->tex_off = total;
        total += ((size_t)1 << (2 * qi->tex_level)) * 3;
        qi->stex_off = stotal;
        stotal += ((size_t)1 << (2 * qi->stex_level)) * 3;
        qi->known = relight_calloc(r, (((size_t)1 << (2 * qi->tex_level)) - 1) / 3 + 1, 1);
        if (!qi->known) return WRT_ERR_NOMEM;
        for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++) {
            if (r->fn_slevel[f] == FN_INVALID || r->fn_spidx[f] == 0 || r->fn_slevel[f] >= qi->tex_level) continue;
            wrt_node nd = wrt_fkey_snode(g->fkeys[f]);
            qi->known[wrt_recon_node((int)nd.level, (int)nd.x, (int)nd.y)] = 1;
        }
    }
    *tex_total = total;
    r->sm.stex = relight_calloc(r, stotal + 1, sizeof(float));
    return r->oom ? WRT_ERR_NOMEM : WRT_OK;
}

/* Each worker's scratch for a group's reconstruction, the largest group's, so that an
 * update allocates nothing (it was a block per group and update: 15 allocations and
 * 0.74 MB an update on the Cornell box). WRT_ERR_NOMEM. */
static wrt_status smooth_scratch(wrt_relight *r) {
    size_t most = 1;
    for (int gr = 0; gr < wrt_recon_ngroups(r->sm.recon); gr++) {
        int nm;
        const int *mem = wrt_recon_members(r->sm.recon, gr, &nm);
        if (nm == 0) continue;
        const quad_info *q0 = &r->qi[mem[0]];
        size_t n = wrt_recon_scratch(r->sm.recon, gr, q0->tex_level, q0->stex_level, 3);
        if (n > most) most = n;
    }
    for (int t = 0; t < r->nthreads; t++) r->workers[t].rbuf = relight_calloc(r, most, sizeof(float));
    return r->oom ? WRT_ERR_NOMEM : WRT_OK;
}


/* The smooth display (reconstruct.h): groups, each member's levels, the texel offsets
 * (recomputed: *tex_total) and which nodes hold a function. WRT_ERR_NOMEM. */
wrt_status relight_setup_smooth(wrt_relight *r, size_t *tex_total) {
    wrt_status st = smooth_groups(r);
    if (st != WRT_OK) return st;
    smooth_levels(r);
    if ((st = smooth_layout(r, tex_total)) != WRT_OK) return st;
    return smooth_scratch(r);
}

typedef struct recon_ctx { const int *groups; } recon_ctx;

static void recon_item(wrt_relight *r, worker *w, int item, void *vctx) {
    const recon_ctx *ctx = vctx;
    int gr = ctx->groups[item], nm;
    const int *mem = wrt_recon_members(r->sm.recon, gr, &nm);
    const quad_info *q0 = &r->qi[mem[0]];
    /* in, known and out are indexed by quad: each job fills and reads only its group's. */
    const float **in = r->sm.rin;
    const uint8_t **kn = r->sm.rknown;
    float **out = r->sm.rout;
    for (int k = 0; k < nm; k++) {
        const quad_info *qi = &r->qi[mem[k]];
        in[mem[k]] = r->tex + qi->tex_off;
        kn[mem[k]] = qi->known;
        out[mem[k]] = r->sm.stex + qi->stex_off;
    }
    wrt_recon_params rp = {r->opt.recon_keep > 0 ? r->opt.recon_keep : WRT_RECON_KEEP, WRT_RECON_SHARP, 1,
                           r->opt.linear_display, 0, 0};
    wrt_recon_run_in(r->sm.recon, gr, q0->tex_level, q0->stex_level, 3, in, kn, out, &rp, w->rbuf);
}

/* The smooth display of every group whose Haar textures changed (marked in
 * r->sm.regroup), in the workers' scratch. Returns the number of quads in those groups. */
int relight_smooth(wrt_relight *r) {
    int ng = wrt_recon_ngroups(r->sm.recon), nre = 0, nchanged = 0;
    int *list = r->synth_list; /* reused: the groups to reconstruct (no more than quads) */
    double rwork = 0;
    for (int gr = 0; gr < ng; gr++) {
        if (!r->sm.regroup[gr]) continue;
        r->sm.regroup[gr] = 0;
        int nm;
        const int *mem = wrt_recon_members(r->sm.recon, gr, &nm);
        list[nre++] = gr;
        nchanged += nm;
        rwork += 0.15 * nm * ldexp(1.0, 2 * r->qi[mem[0]].stex_level); /* ~30 ns a texel */
    }
    recon_ctx rcx = {list};
    if (r->opt.budget_ms <= 0) {
        relight_parallel_for(r, nre, rwork, recon_item, &rcx);
        r->run.n.groups_smoothed += nre;
        r->run.smooth_pending = 0;
        return nchanged;
    }
    /* budgeted: slices while the budget lasts; the groups left stay marked */
    int slice = r->nthreads, done = 0; /* a group can be a whole wall: one a thread */
    for (; done < nre && relight_budget_left(r); done += slice) {
        int m = nre - done < slice ? nre - done : slice;
        rcx.groups = list + done;
        relight_parallel_for(r, m, rwork * m / nre, recon_item, &rcx);
    }
    if (done > nre) done = nre;
    for (int k = done; k < nre; k++) {
        int nm;
        wrt_recon_members(r->sm.recon, list[k], &nm);
        r->sm.regroup[list[k]] = 1;
        nchanged -= nm;
    }
    r->run.n.groups_smoothed += done;
    r->run.smooth_pending = done < nre;
    return nchanged;
}
