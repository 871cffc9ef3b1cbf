/* bake.c: orchestration of the bake: the scene moved to a local frame (precision far
 * from the origin), Embree's scene for visibility, the list of quad pairs that can
 * exchange light (and whether an occluder can lie between them), the DTO computed pair
 * by pair on all cores with results merged in pair order (identical output whatever the
 * thread count), the basis functions indexed, then the series (series.c).
 * Depends on Embree 3, dto.c, balance.c, series.c, sparse.c, budget.c (memory) and
 * links.c (function keys); none of them calls back into it. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/basis.h"
#include "../common/threads.h"
#include "../common/brdf.h"
#include "../common/brdf_table.h"
#include "../common/texture.h"
#include "../common/rt_scene.h"
#include "cover.h"
#include "dto.h"
#include "balance.h"
#include "series.h"
#include "budget.h"
#include "links.h"
#include "cluster.h"
#include "dist.h"

void wrt_bake_defaults(wrt_bake_options *o) {
    if (o->quality <= 0) o->quality = 5;
    if (o->quality > 9) o->quality = 9;
    int q = o->quality;
    double f = pow(0.5, q - 1);
    /* The display (common/reconstruct.h) shows the bake's cell averages down to level
     * WRT_RECON_KEEP (8 x 8 cells a quad) and interpolates below it, so those are the
     * cells it needs right. From quality 5 on, the splits of cells coarser than that use a
     * receiver threshold 3.3 times finer (0.003 at quality 5); the deepest splits keep
     * 0.16 f. Measured on cornell against the path tracer (5 lights, 16 x 16 cells a quad,
     * debiased): display cells 4.50% -> 3.46%, image 3.89% -> 3.32%, 1.25 times the bytes.
     * The finer threshold on every split (0.0035) gave 3.85% and 3.41% for 1.49 times the
     * bytes; on the deepest splits alone it changed nothing (4.48%, 3.83%). An explicit
     * eps_receiver sets both, as it did before. */
    if (o->eps_receiver_coarse <= 0)
        o->eps_receiver_coarse = o->eps_receiver > 0 ? o->eps_receiver : (q >= 5 ? 0.048 : 0.16) * f;
    if (o->eps_receiver <= 0) o->eps_receiver = 0.16 * f;
    if (o->eps_sender <= 0) o->eps_sender = 0.32 * f;
    /* Measured on cornell against the path-traced reference (docs/study): the error is
     * driven by the compression more than by the depth, and the 4 x 4 cells per quad of
     * the error metric no longer see refinement past level 4 at quality 5, so the depth
     * grows slowly with quality and the compression threshold fast. */
    if (o->eps_compress <= 0) o->eps_compress = 1e-3 * f;
    if (o->eps_final <= 0) o->eps_final = o->eps_compress;
    /* The stored operator's drop rule (drop_rule.h), chosen by error per byte against the
     * path tracer (docs/bench.md, "Which entries are stored"): on the maze at quality 5,
     * 41.3 MB -> 21.5 MB for +0.01 points of cell error and -0.03 of image error (+0.07
     * and +0.06 against a second seeded reference); the uniform --eps-final 4x took
     * 24.0 MB for +0.33 points of cells. Cornell: 4.65 -> 2.29 MB, +0.04 points of image.
     * Negative: none (kept negative, read as 0, so that resolving twice gives the same) */
    if (o->drop_sender == 0) o->drop_sender = 0.5;
    if (o->drop_receiver == 0) o->drop_receiver = 1;
    if (o->drop_receiver_from == 0) o->drop_receiver_from = 3;
    /* The sender's depth counted from supports of 0.05 of the scene's diagonal (cornell's
     * 1 m walls keep their fine senders near the light, the maze's cells of 1.23 m in a
     * 10.5 m scene about one level more): cornell 2.28 -> 3.52 MB, image error at or below
     * 46ed865's at seeds 1, 2, 3 (0.03375 -> 0.03373, 0.03344 -> 0.03330, 0.03431 ->
     * 0.03421; the rule without it: +0.0003 at each); maze 21.5 -> 24.1 MB, cells 0.01392
     * -> 0.01389, image 0.01658 -> 0.01688 (docs/bench.md, "The sender's depth from a
     * size"). Negative: none. */
    if (o->drop_sender_size == 0) o->drop_sender_size = 0.05;
    if (o->max_slevel <= 0) o->max_slevel = 1 + (q + 1) / 2;
    if (o->max_slevel > WRT_MAX_SLEVEL) o->max_slevel = WRT_MAX_SLEVEL;
    if (o->min_slevel < 0) o->min_slevel = 0;
    if (o->glossy_quality <= 0) o->glossy_quality = q <= 3 ? q : q <= 5 ? 3 : q - 2;
    double fg = pow(0.5, o->glossy_quality - 1);
    if (o->eps_receiver_glossy <= 0) o->eps_receiver_glossy = o->glossy_quality == q ? o->eps_receiver : 0.16 * fg;
    if (o->eps_sender_glossy <= 0) o->eps_sender_glossy = o->glossy_quality == q ? o->eps_sender : 0.32 * fg;
    if (o->max_slevel_glossy <= 0)
        o->max_slevel_glossy = o->glossy_quality == q ? o->max_slevel : 1 + (o->glossy_quality + 1) / 2;
    if (o->max_slevel_glossy > o->max_slevel) o->max_slevel_glossy = o->max_slevel;
    if (o->receiver_samples <= 0) o->receiver_samples = 16;
    if (o->max_bounces <= 0) o->max_bounces = 2000;
    /* 1 x eps: the products' threshold (series.c: the maze asset's errors the same, its
     * bake 0.72x the CPU; coarser factors failed the small-quads furnace) */
    if (o->series_right == 0) o->series_right = 1;
    if (o->series_right_from <= 0) o->series_right_from = 2;
    if (o->series_skip == 0) o->series_skip = WRT_SERIES_SKIP_DEFAULT;
    if (o->series_columns == 0) o->series_columns = WRT_SERIES_COLUMNS_DEFAULT;
    /* the small senders' share of the scene's area, in units of eps_compress (series.c
     * series_small_area): the icosphere furnace of 1,280 triangles at quality 1 G - I -99.2%
     * -> the DTO's series; the assets at quality 5 the same bytes. Negative: off. */
    if (o->small_share == 0) o->small_share = 10;
    if (o->small_lost == 0) o->small_lost = WRT_SMALL_LOST_DEFAULT;
    /* the oracle's share rule (dto.c refine(), wrt_depth_weight): a quad under this share of
     * the scene's area has its detail weighed by sqrt(share / depth_share). 1e-3 is under
     * every exchanging quad of the assets (cornell's smallest 1.4e-2, glossy's 1.3e-2, the
     * maze's walls and floor cells 1.2e-3): their bytes are unchanged. Negative: off. */
    if (o->depth_share == 0) o->depth_share = WRT_DEPTH_SHARE_DEFAULT;
    /* the coarse cut between bounces: with --clusters only (the default bake unchanged) */
    if (o->series_coarse == 0) o->series_coarse = o->clusters ? WRT_SERIES_COARSE_CLUSTERS : -1;
    /* Glossy materials (measured by tools/study.sh on the glossy asset and the glossy-wall
     * Cornell box, docs/study): a finer angular level blurs the light's own reflection
     * less but places it worse (its direction is a delta truncated to the level's cells),
     * so up to quality 5 the glossy materials keep level 1, and the links that touch a
     * glossy quad are refined with the thresholds of quality 3 at qualities 4-5 and of
     * Q - 2 above (finer ones bought nothing measurable at level 1): the default then
     * bakes a glossy scene in about the time of a diffuse one of its size. */
    if (o->max_alevel <= 0) o->max_alevel = q <= 5 ? 1 : q <= 7 ? 2 : 3;
    if (o->max_alevel > WRT_MAX_ALEVEL) o->max_alevel = WRT_MAX_ALEVEL;
    if (o->max_memory_mb <= 0) o->max_memory_mb = wrt_bake_memory_default();
}

/* The shared angular BRDF table (common/brdf_table.h) of every glossy material. */
static void bake_btilde_build(bake_ctx *b) {
    const wrt_scene *sc = b->scene;
    b->btilde = wrt_xcalloc((size_t)(sc->nmaterials ? sc->nmaterials : 1), sizeof *b->btilde);
    for (int m = 0; m < sc->nmaterials; m++) {
        if (!b->alevel[m]) continue;
        b->btilde[m] = wrt_xmalloc(WRT_BRDF_TABLE_FLOATS * sizeof(float));
        wrt_brdf_table_build(&sc->materials[m], b->opt.threads, b->btilde[m]);
    }
}

/* WRT_DTO_TIMES set: each stage's wall and CPU seconds since the last mark, on stderr
 * (docs/clusters.md, "The linking's growth") */
static void stage_mark(stage_clock *k, const char *what) {
    if (!k || !k->on) return;
    double w = wrt_now(), c = wrt_dist_cpu_now();
    fprintf(stderr, "dto-times: %-22s %8.3f s wall %8.3f s cpu  peak %8.0f MB  now %8.0f MB\n", what, w - k->w,
            c - k->c, (double)wrt_bake_stage_peak_bytes() / 1048576.0, (double)wrt_bake_rss_bytes() / 1048576.0);
    k->w = w;
    k->c = c;
}

static double signed_dist(const wrt_quad *q, wrt_v3 p) { return v3_dot(v3_sub(p, q->p[0]), q->n); }

/* Can light leave s and reach r: some of s in front of r and some of r in front of s. */
static int can_exchange(const bake_ctx *b, const wrt_quad *r, const wrt_quad *s) {
    int a = 0, c = 0;
    for (int i = 0; i < 4; i++) {
        if (signed_dist(r, s->p[i]) > b->plane_eps) a = 1;
        if (signed_dist(s, r->p[i]) > b->plane_eps) c = 1;
    }
    return a && c;
}

/* Clips a polygon to the half-space signed_dist(q, p) >= eps. */
static int clip_front(const wrt_quad *q, double eps, const wrt_v3 *in, int n, wrt_v3 *out) {
    int m = 0;
    for (int i = 0; i < n; i++) {
        wrt_v3 a = in[i], c = in[(i + 1) % n];
        double da = signed_dist(q, a) - eps, dc = signed_dist(q, c) - eps;
        if (da >= 0) out[m++] = a;
        if ((da >= 0) != (dc >= 0)) out[m++] = v3_add(a, v3_scale(v3_sub(c, a), da / (da - dc)));
    }
    return m;
}

/* Can quad o lie between r and s? Conservative: its part strictly in front of both
 * planes must overlap the (slightly shrunk) bounding box of r and s. */
static int may_occlude(const bake_ctx *b, const wrt_quad *r, const wrt_quad *s, const wrt_quad *o) {
    wrt_v3 p1[12], p2[16];
    int n1 = clip_front(r, b->plane_eps, o->p, 4, p1);
    if (n1 < 3) return 0;
    int n2 = clip_front(s, b->plane_eps, p1, n1, p2);
    if (n2 < 3) return 0;
    wrt_v3 lo = r->p[0], hi = r->p[0];
    for (int i = 0; i < 8; i++) {
        wrt_v3 p = i < 4 ? r->p[i] : s->p[i - 4];
        lo = v3(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
        hi = v3(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
    }
    wrt_v3 olo = p2[0], ohi = p2[0];
    for (int i = 1; i < n2; i++) {
        olo = v3(fmin(olo.x, p2[i].x), fmin(olo.y, p2[i].y), fmin(olo.z, p2[i].z));
        ohi = v3(fmax(ohi.x, p2[i].x), fmax(ohi.y, p2[i].y), fmax(ohi.z, p2[i].z));
    }
    double e = b->plane_eps;
    return olo.x < hi.x - e && ohi.x > lo.x + e && olo.y < hi.y - e && ohi.y > lo.y + e &&
           olo.z < hi.z - e && ohi.z > lo.z + e;
}

int wrt_bake_can_exchange(const bake_ctx *b, const wrt_quad *r, const wrt_quad *s) { return can_exchange(b, r, s); }
int wrt_bake_may_occlude(const bake_ctx *b, const wrt_quad *r, const wrt_quad *s, const wrt_quad *o) {
    return may_occlude(b, r, s, o);
}

typedef struct dto_job {
    const bake_ctx *b;
    const int *pr, *ps;
    const uint8_t *occl;
    pair_out *out;
    bake_thread_counters *tc;
    atomic_size_t done;
    size_t total;
    size_t phase, stride; /* this run's pairs: phase, phase + stride, ... */
    const int *owner;     /* wrt-bake-mpi: the rank that computes each pair (NULL: all here) */
    int rank;
} dto_job;

static void dto_one(size_t i, int th, void *user) {
    dto_job *j = user;
    i = j->phase + i * j->stride;
    if (j->owner && j->owner[i] != j->rank) return; /* another rank's (dist.h) */
    wrt_dto_pair(j->b, j->pr[i], j->ps[i], j->occl[i], &j->tc[th], &j->out[i]);
    atomic_fetch_add(&j->done, 1);
}

/* K's column keys (the outgoing functions its entries use, sorted) and its matrix, from
 * the K pairs' entries (value in channel 0; rows already in res->fkeys). */
typedef struct k_trip { uint64_t col; uint32_t row; float v; } k_trip;
static int cmp_kt(const void *pa, const void *pb) {
    const k_trip *a = pa, *b = pb;
    if (a->col != b->col) return a->col < b->col ? -1 : 1;
    return a->row < b->row ? -1 : a->row > b->row;
}
static void k_assemble(wrt_bake_result *res, const pair_out *out, size_t n, uint64_t nent) {
    k_trip *t = wrt_xmalloc(nent * sizeof *t);
    uint64_t m = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t k = 0; k < out[i].count; k++) {
            const pair_entry *e = &out[i].e[k]; /* K's pairs hold full entries (dto.c) */
            t[m++] = (k_trip){e->s, (uint32_t)wrt_fkey_find(res->fkeys, res->nfuncs, e->r), e->v[0]};
        }
    qsort(t, m, sizeof *t, cmp_kt);
    /* merge repeats (none are expected: a pair's links are unique and pairs differ) */
    uint64_t u = 0, ncols = 0;
    for (uint64_t i = 0; i < m; i++) {
        if (u && t[u - 1].col == t[i].col && t[u - 1].row == t[i].row) { t[u - 1].v += t[i].v; continue; }
        ncols += !u || t[u - 1].col != t[i].col;
        t[u++] = t[i];
    }
    res->nkcols = (uint32_t)ncols;
    res->knnz = u;
    res->kkeys = wrt_xmalloc((ncols ? ncols : 1) * sizeof *res->kkeys);
    res->kcol_start = wrt_xmalloc((ncols + 1) * sizeof *res->kcol_start);
    res->krows = wrt_xmalloc((u ? u : 1) * sizeof *res->krows);
    res->kvals = wrt_xmalloc((u ? u : 1) * sizeof *res->kvals);
    uint64_t c = 0;
    for (uint64_t i = 0; i < u; i++) {
        if (i == 0 || t[i - 1].col != t[i].col) {
            res->kkeys[c] = t[i].col;
            res->kcol_start[c++] = i;
        }
        res->krows[i] = t[i].row;
        res->kvals[i] = t[i].v;
    }
    res->kcol_start[c] = u;
    res->c.entries_k = u;
    res->c.nkcols = (uint32_t)ncols;
    free(t);
}

/* The albedo the transport gives a quad: from its material, with the base colour its
 * own mean over its UV footprint when the material has a base-colour texture and the
 * quad has UVs (docs/textures.md), else the material's (factor x the texture's mean). */
static void material_rho(const wrt_scene *scene, const wrt_quad *q, const wrt_material *m, double rho[3]) {
    double own[3] = {m->base_color[0], m->base_color[1], m->base_color[2]};
    if (m->base_tex > 0 && m->base_tex <= scene->ntextures && q->has_uv)
        wrt_texture_quad_mean(&scene->textures[m->base_tex - 1], q, own);
    for (int c = 0; c < 3; c++) {
        double base = own[c];
        /* non-Lambertian materials: diffuse part of the glTF model plus the
         * normal-incidence specular reflectance, as a diffuse albedo */
        if (!m->lambertian) base = (1 - m->metallic) * base * 0.96 + (0.04 * (1 - m->metallic) + m->metallic * base);
        rho[c] = base < 0 ? 0 : base > 1 ? 1 : base;
    }
}

/* The pairs of quads the operators are computed for: T's first (npt of them), then K's */
typedef struct pair_list {
    int *pr, *ps;
    uint8_t *occl;
    size_t np, npt;
} pair_list;

/* Stage 1: the local frame (the bounding box centre at the origin), the quads in it and
 * their albedos */
static wrt_status bake_frame(bake_ctx *b, const wrt_scene *scene) {
    /* local frame: translate to the bounding box centre */
    wrt_v3 centre = v3_scale(v3_add(scene->bbox_min, scene->bbox_max), 0.5);
    b->scene_size = v3_len(v3_sub(scene->bbox_max, scene->bbox_min));
    if (!(b->scene_size > 0) || !isfinite(b->scene_size))
        return wrt_fail(WRT_ERR_GEOMETRY, "scene has no extent (bounding box diagonal %g)", b->scene_size);
    b->plane_eps = 1e-7 * b->scene_size;
    b->entry_floor = 0.1 * b->opt.eps_compress; /* far below what the series keeps */
    b->quads = wrt_xmalloc((size_t)(b->nq ? b->nq : 1) * sizeof *b->quads);
    b->rho = wrt_xmalloc((size_t)(b->nq ? b->nq : 1) * sizeof *b->rho);
    int nglossy = 0;
    for (int i = 0; i < b->nq; i++) {
        b->quads[i] = scene->quads[i];
        for (int k = 0; k < 4; k++) b->quads[i].p[k] = v3_sub(scene->quads[i].p[k], centre);
        const wrt_material *m = &scene->materials[scene->quads[i].material];
        material_rho(scene, &scene->quads[i], m, b->rho[i]);
        nglossy += !m->lambertian;
    }
    (void)nglossy;
    if (b->opt.depth_share > 0) {
        double total = 0;
        for (int i = 0; i < b->nq; i++) total += b->quads[i].area;
        b->depth_area = b->opt.depth_share * total;
    }
    return WRT_OK;
}

/* Stage 2: each material's angular levels (T's incident functions, K's outgoing ones) and
 * K's tables */
static void bake_materials(bake_ctx *b, const wrt_scene *scene, wrt_bake_result *res) {
    res->material_alevel = wrt_xcalloc((size_t)(scene->nmaterials ? scene->nmaterials : 1), 1);
    b->alevel = res->material_alevel;
    for (int m = 0; m < scene->nmaterials; m++) {
        int l = wrt_brdf_angular_level(&scene->materials[m]);
        b->alevel[m] = (uint8_t)(l > b->opt.max_alevel ? b->opt.max_alevel : l);
    }
    /* The first-bounce operator K's outgoing level: the material's angular need (its lobe's
     * width, brdf.h), at most 3, whatever max_alevel caps the incident functions at */
    b->klevel = wrt_xcalloc((size_t)(scene->nmaterials ? scene->nmaterials : 1), 1);
    for (int m = 0; m < scene->nmaterials && b->opt.first_bounce_level >= 0; m++) {
        int l = wrt_brdf_angular_level(&scene->materials[m]);
        if (b->opt.first_bounce_level > 0 && l > 0) l = b->opt.first_bounce_level;
        b->klevel[m] = (uint8_t)(l > WRT_K_MAX_LEVEL ? WRT_K_MAX_LEVEL : l);
    }
    bake_btilde_build(b);
    /* K's entries are used once (not multiplied again by the series), so they are dropped
     * at emission under the series' own threshold, weighted by what the column's
     * coefficient can be at most: the largest |btilde_g| of its material over all light
     * directions (the albedo for the root) */
    b->kbmax = wrt_xcalloc((size_t)(scene->nmaterials ? scene->nmaterials : 1), sizeof *b->kbmax);
    b->k_floor = b->opt.eps_compress;
    for (int m = 0; m < scene->nmaterials; m++) {
        if (!b->klevel[m] || !b->btilde[m]) continue;
        int ng = 1 << (2 * b->klevel[m]);
        for (size_t cell = 0; cell < (size_t)WRT_BRDF_TABLE_RES * WRT_BRDF_TABLE_RES; cell++)
            for (int g = 0; g < ng; g++)
                for (int ch = 0; ch < 3; ch++)
                    b->kbmax[m][g] = fmax(b->kbmax[m][g], fabs(b->btilde[m][(cell * WRT_BRDF_TABLE_NANG + g) * 3 + ch]));
    }

}

/* Stage 3: the Embree scene of the quads */
static wrt_status bake_embree(bake_ctx *b) {
    /* Embree (common/rt_scene.h: its ray offset is the bake's too) */
    wrt_v3 *corners = wrt_xmalloc((size_t)(b->nq ? b->nq : 1) * 4 * sizeof *corners);
    for (int i = 0; i < b->nq; i++)
        for (int k = 0; k < 4; k++) corners[4 * i + k] = b->quads[i].p[k];
    wrt_rt_scene rs;
    wrt_status est = wrt_rt_scene_build(corners, b->nq, v3(0, 0, 0), "threads=1", WRT_RT_ROBUST, &rs);
    free(corners);
    if (est != WRT_OK) { free(b->quads); free(b->rho); return est; }
    b->dev = rs.dev;
    b->rtc = rs.scene;
    b->ray_eps = rs.eps;
    b->cover = wrt_bake_cover_flags(b);
    return WRT_OK;
}

/* Stage 4: the pairs that exchange light, T's then K's */
/* A quad's bounding box. */
typedef struct quad_box { wrt_v3 lo, hi; } quad_box;

static quad_box quad_box_of(const wrt_v3 *p, int n) {
    quad_box q = {p[0], p[0]};
    for (int i = 1; i < n; i++) {
        q.lo = v3(p[i].x < q.lo.x ? p[i].x : q.lo.x, p[i].y < q.lo.y ? p[i].y : q.lo.y, p[i].z < q.lo.z ? p[i].z : q.lo.z);
        q.hi = v3(p[i].x > q.hi.x ? p[i].x : q.hi.x, p[i].y > q.hi.y ? p[i].y : q.hi.y, p[i].z > q.hi.z ? p[i].z : q.hi.z);
    }
    return q;
}

/* The occluder search's scratch: every quad's box, and the slack the box test allows. */
typedef struct pair_code_ctx {
    const bake_ctx *b;
    quad_box *box;
    double slack;
    uint8_t *codes; /* a block of receivers' rows of nq kinds */
    int r0;
} pair_code_ctx;

static void pair_code_ctx_init(pair_code_ctx *pc, const bake_ctx *b) {
    *pc = (pair_code_ctx){.b = b};
    pc->box = wrt_xmalloc((size_t)(b->nq ? b->nq : 1) * sizeof *pc->box);
    double m = 0;
    for (int i = 0; i < b->nq; i++) {
        pc->box[i] = quad_box_of(b->quads[i].p, 4);
        m = fmax(m, fmax(fmax(fabs(pc->box[i].lo.x), fabs(pc->box[i].lo.y)), fabs(pc->box[i].lo.z)));
        m = fmax(m, fmax(fmax(fabs(pc->box[i].hi.x), fabs(pc->box[i].hi.y)), fabs(pc->box[i].hi.z)));
    }
    /* may_occlude's clipped polygon lies in o's box up to the clipping's rounding (a few
     * ulps of the coordinates): a box that misses r and s's box by more than this margin
     * cannot pass its test */
    pc->slack = 1e-9 * (b->scene_size + m);
}

/* A pair's kind: 0 the quads cannot exchange light, 1 they can and no quad can lie
 * between them, 3 one may. may_occlude's last test is that the part of o in front of both
 * planes overlaps r and s's (shrunk) box; that part lies in o's box, so a quad whose box
 * misses it (by more than the rounding slack) is skipped before the clipping: the same
 * kinds, and the O(N^3) search was a sixth of the 12 x 12 maze's bake (perf). The quad
 * found last for the receiver is tried first (*last; neighbouring senders share their
 * occluders); which occluder is found does not change the kind. */
static uint8_t pair_code(const pair_code_ctx *pc, int r, int s, int *last) {
    const bake_ctx *b = pc->b;
    if (!can_exchange(b, &b->quads[r], &b->quads[s])) return 0;
    wrt_v3 rs[8];
    memcpy(rs, b->quads[r].p, sizeof b->quads[r].p);
    memcpy(rs + 4, b->quads[s].p, sizeof b->quads[s].p);
    quad_box u = quad_box_of(rs, 8);
    double e = b->plane_eps - pc->slack;
    for (int t = -1; t < b->nq; t++) {
        int o = t < 0 ? *last : t;
        if (o < 0 || o == r || o == s || (t >= 0 && o == *last)) continue;
        const quad_box *ob = &pc->box[o];
        if (!(ob->lo.x < u.hi.x - e && ob->hi.x > u.lo.x + e && ob->lo.y < u.hi.y - e && ob->hi.y > u.lo.y + e &&
              ob->lo.z < u.hi.z - e && ob->hi.z > u.lo.z + e))
            continue;
        if (may_occlude(b, &b->quads[r], &b->quads[s], &b->quads[o])) {
            *last = o;
            return 3;
        }
    }
    return 1;
}

/* The kinds of receiver r0 + i's pairs, one row of nq (the threads' share of the pairs'
 * kinds; the same kinds whatever the threads) */
static void pair_code_row(size_t i, int th, void *user) {
    (void)th;
    pair_code_ctx *pc = user;
    int r = pc->r0 + (int)i, nq = pc->b->nq, last = -1;
    for (int s = 0; s < nq; s++) pc->codes[i * (size_t)nq + (size_t)s] = r == s ? 0 : pair_code(pc, r, s, &last);
}

/* The kinds of the pairs of receivers [r0, r1) on the bake's threads, in a row of nq
 * for each receiver */
static uint8_t *pair_codes_threads(pair_code_ctx *pc, int r0, int r1) {
    pc->codes = wrt_xmalloc((size_t)(r1 - r0) * (size_t)pc->b->nq + 1);
    pc->r0 = r0;
    wrt_parallel_for((size_t)(r1 - r0), pc->b->opt.threads, pair_code_row, pc);
    return pc->codes;
}

/* wrt-bake-mpi: the kinds of the pairs of receivers [r0, r1), each rank computing every
 * nranks-th receiver, gathered in receiver order (dist.h): the occluder search is
 * O(N^3), the rest of the pair list is not. NULL where the exchange failed. */
static uint8_t *pair_codes_dist(const bake_ctx *b, int r0, int r1) {
    wrt_bake_dist *d = b->opt.dist;
    size_t nq = (size_t)b->nq, mine = 0;
    uint8_t *buf = wrt_xmalloc(((size_t)(r1 - r0) / (size_t)d->nranks + 1) * nq);
    pair_code_ctx pc;
    pair_code_ctx_init(&pc, b);
    for (int r = r0 + d->rank; r < r1; r += d->nranks, mine++) {
        int last = -1;
        for (int s = 0; s < b->nq; s++) buf[mine * nq + (size_t)s] = r == s ? 0 : pair_code(&pc, r, s, &last);
    }
    free(pc.box);
    int *owner = wrt_xmalloc((size_t)(r1 - r0) * sizeof *owner);
    for (int r = r0; r < r1; r++) owner[r - r0] = (r - r0) % d->nranks;
    uint8_t *codes = wrt_dist_gather_rows(d, owner, (size_t)(r1 - r0), buf, nq);
    free(owner);
    free(buf);
    return codes;
}

static void bake_pairs(const bake_ctx *b, const wrt_scene *scene, wrt_bake_counters *C, pair_list *pl) {
    /* pairs */
    size_t cap = 64, np = 0, kcap = 16, nkp = 0;
    int *pr = wrt_xmalloc(cap * sizeof *pr), *ps = wrt_xmalloc(cap * sizeof *ps);
    uint8_t *occl = wrt_xmalloc(cap);
    int *kpr = wrt_xmalloc(kcap * sizeof *kpr), *kps = wrt_xmalloc(kcap * sizeof *kps);
    uint8_t *kocc = wrt_xmalloc(kcap);
    const int block = 256; /* wrt-bake-mpi: receivers per exchange of the pairs' kinds */
    uint8_t *codes = NULL;
    pair_code_ctx pc;
    pair_code_ctx_init(&pc, b);
    for (int r = 0; r < b->nq; r++) {
        if (wrt_dist_on(b->opt.dist) && r % block == 0) {
            free(codes);
            codes = pair_codes_dist(b, r, r + block < b->nq ? r + block : b->nq);
            if (!codes) atomic_store(b->cancel, 1); /* the exchange failed: the bake stops (bake_dto) */
        } else if (!wrt_dist_on(b->opt.dist) && r % block == 0) {
            free(codes);
            codes = pair_codes_threads(&pc, r, r + block < b->nq ? r + block : b->nq);
        }
        for (int s = 0; s < b->nq; s++) {
            if (r == s) continue;
            C->pairs_total++;
            uint8_t code = codes ? codes[(size_t)(r % block) * (size_t)b->nq + (size_t)s] : 0;
            if (!code) { C->pairs_skipped_facing++; continue; }
            /* a quad with covered parts (cover.c) needs its visibility sampled (dto.c) */
            int oc = code == 3 || b->cover[r] || b->cover[s];
            if (np + 1 >= cap) {
                cap *= 2;
                pr = wrt_xrealloc(pr, cap * sizeof *pr); ps = wrt_xrealloc(ps, cap * sizeof *ps);
                occl = wrt_xrealloc(occl, cap);
            }
            C->pairs_exchange++;
            C->pairs_unoccluded += !oc;
            if (b->klevel[scene->quads[s].material]) { /* the first-bounce operator K from s to r */
                if (nkp + 1 >= kcap) {
                    kcap *= 2;
                    kpr = wrt_xrealloc(kpr, kcap * sizeof *kpr); kps = wrt_xrealloc(kps, kcap * sizeof *kps);
                    kocc = wrt_xrealloc(kocc, kcap);
                }
                kpr[nkp] = r; kps[nkp] = s; kocc[nkp] = (uint8_t)(oc | 4); nkp++;
            }
            /* A diffuse-diffuse pair is computed once, for r < s, and both directions are
             * emitted from the same links (reciprocity, see dto.c) */
            int sym = !b->alevel[scene->quads[r].material] && !b->alevel[scene->quads[s].material];
            if (sym && r > s) continue;
            pr[np] = r; ps[np] = s; occl[np] = (uint8_t)(oc | (sym ? 2 : 0)); np++;
        }
    }

    /* K's pairs after T's: the power balance reads T's pairs only (the first npt) */
    size_t npt = np;
    if (np + nkp + 1 > cap) {
        cap = np + nkp + 1;
        pr = wrt_xrealloc(pr, cap * sizeof *pr); ps = wrt_xrealloc(ps, cap * sizeof *ps);
        occl = wrt_xrealloc(occl, cap);
    }
    memcpy(pr + np, kpr, nkp * sizeof *pr); memcpy(ps + np, kps, nkp * sizeof *ps); memcpy(occl + np, kocc, nkp);
    np += nkp;
    free(kpr); free(kps); free(kocc); free(codes); free(pc.box);

    pl->pr = pr; pl->ps = ps; pl->occl = occl; pl->np = np; pl->npt = npt;
}

/* Stage 4 with --clusters: the tree, its links, and the leaf pairs (cluster.c); the
 * links' status (wrt-bake-mpi's exchange; no pairs then) */
static wrt_status bake_cluster_pairs(bake_ctx *b, wrt_clusters *cl, wrt_bake_counters *C, pair_list *pl) {
    wrt_clusters_build(b, cl);
    wrt_status st = wrt_clusters_link(b, cl);
    b->cl = cl;
    b->balance_open = 1;
    size_t np = st == WRT_OK ? cl->np : 0;
    pl->pr = wrt_xmalloc((np + 1) * sizeof *pl->pr);
    pl->ps = wrt_xmalloc((np + 1) * sizeof *pl->ps);
    pl->occl = wrt_xmalloc(np + 1);
    memcpy(pl->pr, cl->pr, np * sizeof *pl->pr);
    memcpy(pl->ps, cl->ps, np * sizeof *pl->ps);
    memcpy(pl->occl, cl->occl, np);
    pl->np = pl->npt = np;
    for (size_t i = 0; i < np; i++) C->pairs_unoccluded += 2 * !(cl->occl[i] & 1);
    C->pairs_exchange = 2 * np;
    /* of every ordered pair of quads, as the plain bake counts them (those below a cluster
     * link or a dropped cluster pair are not tried one by one) */
    C->pairs_total = (uint64_t)b->nq * (uint64_t)(b->nq > 0 ? b->nq - 1 : 0);
    C->cluster_links = cl->nlinks;
    C->cluster_leaf_pairs = np;
    C->cluster_visits = cl->pairs_visited;
    C->cluster_oracle = cl->oracle_calls;
    C->cluster_rays = cl->rays;
    C->cluster_refused_visibility = cl->oracle_refused_vis;
    C->cluster_refused_spread = cl->oracle_refused_spread;
    C->cluster_partial = cl->links_partial;
    C->cluster_depth = cl->tree.depth;
    return st;
}

/* wrt-bake-mpi: each pair's rank (dist.h), by an estimated cost: the refinement grows
 * with how much of each other the quads see (a form factor's scale, sqrt(A_r A_s) over
 * the squared distance of their centres), and visibility rays roughly triple a pair's
 * work where an occluder may lie between: a first guess, not fitted (the ranks' DTO
 * phases came within 5% of one another on the 9 x 9 maze and the atrium, docs/mpi.md). */
static int *bake_pair_owners(const bake_ctx *b, const pair_list *pl) {
    double *cost = wrt_xmalloc((pl->np ? pl->np : 1) * sizeof *cost);
    for (size_t i = 0; i < pl->np; i++) {
        const wrt_quad *r = &b->quads[pl->pr[i]], *q = &b->quads[pl->ps[i]];
        wrt_v3 cr = v3_scale(v3_add(r->p[0], r->p[2]), 0.5), cs = v3_scale(v3_add(q->p[0], q->p[2]), 0.5);
        double d2 = v3_dot(v3_sub(cr, cs), v3_sub(cr, cs)), a = sqrt(r->area * q->area);
        cost[i] = (pl->occl[i] ? 3.0 : 1.0) * (1.0 + 8.0 * a / (d2 + 0.5 * (r->area + q->area)));
    }
    int *owner = wrt_xmalloc((pl->np ? pl->np : 1) * sizeof *owner);
    wrt_dist_assign(cost, pl->np, b->opt.dist->nranks, owner);
    free(cost);
    return owner;
}

/* Stage 5: the DTO's links and entries, pair by pair in parallel, with the memory check
 * after every chunk; the threads' counters summed; the status so far */
static wrt_status bake_dto(bake_ctx *b, wrt_bake_counters *C, const pair_list *pl, dto_job *job,
                           atomic_ullong *pool_bytes, atomic_ullong *pool_refused) {
    int *pr = pl->pr, *ps = pl->ps;
    uint8_t *occl = pl->occl;
    size_t np = pl->np;
    /* DTO, pair by pair, in parallel; pairs in order of decreasing expected cost
     * would balance better, but the order does not change the result */
    int nt = wrt_threads_resolve(b->opt.threads);
    *job = (dto_job){.b = b, .pr = pr, .ps = ps, .occl = occl, .total = np};
    if (wrt_dist_on(b->opt.dist)) {
        job->owner = bake_pair_owners(b, pl);
        job->rank = b->opt.dist->rank;
    }
    atomic_init(&job->done, 0);
    job->out = wrt_xcalloc(np ? np : 1, sizeof *job->out);
    job->tc = wrt_xcalloc((size_t)nt, sizeof *job->tc);
    /* run in chunks so the progress callback can be called between them; chunk c takes
     * the pairs c, c + nch, c + 2 nch, ...: a sample of the whole scene, not a stretch of
     * it in scene order, so the memory extrapolated from the first chunks is that of the
     * whole (in scene order, blender_shapes' first tenth of the pairs extrapolated to 13.4
     * GB and was refused; it needs 2.7 GB). The order does not change the result. */
    size_t chunk = np / 50 + 1, nch = np ? (np + chunk - 1) / chunk : 0, ndone = 0, nown = 0;
    uint64_t ent = 0, kent = 0, held = 0; /* held: the bytes the entries so far take */
    wrt_status mst = WRT_OK;
    /* the pairs' link tables may use what the budget leaves beside what is resident now */
    atomic_init(pool_bytes, 0);
    atomic_init(pool_refused, 0);
    b->pool_bytes = pool_bytes;
    b->pool_refused = pool_refused;
    wrt_bake_memory_trim();
    uint64_t rss0 = wrt_bake_rss_bytes();
    b->pool_limit = b->opt.max_memory_mb * 1024.0 * 1024.0 - (double)rss0;
    if (b->pool_limit < 0) b->pool_limit = 0;
    if (b->opt.progress) b->opt.progress("dto", 0, b->opt.progress_user);
    for (size_t c = 0; c < nch; c++) {
        size_t n = (np - c + nch - 1) / nch;
        dto_job sub = *job;
        sub.phase = c;
        sub.stride = nch;
        wrt_parallel_for(n, nt, dto_one, &sub);
        ndone += n;
        if (b->opt.progress && !b->opt.progress("dto", (double)ndone / (double)np, b->opt.progress_user))
            atomic_store(b->cancel, 1);
        if (atomic_load(b->cancel)) break;
        /* Memory: the entries so far, extrapolated over the pairs left, then their
         * conversion (bake_assemble): each pair's entries cut as they become triplets (20
         * bytes), then the matrix (16) built by ranges of columns as the triplets shrink
         * (wrt_csc_from_triplets_free: 20 bytes an entry at the most, where it was 40 with
         * the whole build's index), so on the mazes the DTO's end is the assembly's peak
         * (the maze asset 267 MB with 8.1M entries; the 12 x 12 maze 975 MB with 30.1M,
         * the balance 795): 38 counted, 6 beyond the entries, for what the balance, the
         * key set and the allocator hold beside them (the maze asset's estimate 1.14 of
         * its peak). K's entries stay whole until K's triplets (16 bytes) and arrays (8)
         * are made beside them: 24 more each (cornell-glossy q3, tests/bake.sh: 0.93 of
         * its peak without). With the whole build 54 were counted for every entry, 17 and
         * 13 bytes an entry measured beyond the entries. Before the cut the entries
         * stayed beside the triplets: 36 bytes beyond the entries. */
        for (size_t k = 0; k < n; k++)
            if (!job->owner || job->owner[c + k * nch] == job->rank) {
                ent += job->out[c + k * nch].count;
                held += wrt_pair_bytes(&job->out[c + k * nch]);
                if (job->out[c + k * nch].kmode) kent += job->out[c + k * nch].count;
                nown++;
            }
        /* wrt-bake-mpi: this rank's pairs so far stand for all the pairs so far, whose
         * entries the merge then gives every rank (the assembly holds them all) */
        double scale = nown == ndone ? 1 : nown ? (double)ndone / (double)nown : 0;
        double all = (double)ent * scale, kall = (double)kent * scale, hall = (double)held * scale;
        double done = (double)ndone / (double)np, left = (1 - done) / done;
        /* 38 an entry at the assembly, less what the entries already take (resident:
         * diffuse pairs' compact records, 8 to 16 bytes an entry, dto.h) */
        uint64_t need = (uint64_t)((all * 38.0 + kall * 24) * (1 + left) - hall);
        uint64_t known = (uint64_t)(all * 38.0 + kall * 24 - hall);
        /* the extrapolation from under a tenth of the pairs is noise: it refuses only from
         * there on, what is already computed at any time; the figure recorded is the last */
        double keep = C->mem_estimate_mb;
        mst = wrt_bake_memory_check(b->opt.max_memory_mb, &C->mem_estimate_mb, done >= 0.1 ? need : known,
                                    "the transport operator T");
        if (c + 1 < nch) C->mem_estimate_mb = keep;
        if (mst != WRT_OK) break;
    }
    for (int t = 0; t < nt; t++) {
        C->samples += job->tc[t].samples;
        C->rays_traced += job->tc[t].rays_traced;
        C->rays_skipped_facing += job->tc[t].rays_skipped_facing;
        C->rays_skipped_unoccluded += job->tc[t].rays_skipped_unoccluded;
        C->links_refined += job->tc[t].links_refined;
        C->links_leaf += job->tc[t].links_leaf;
        C->links_invisible += job->tc[t].links_invisible;
        C->t_rays += job->tc[t].t_rays;
    }
    wrt_status st = mst;
    if (st == WRT_OK && atomic_load(pool_refused)) {
        double mb = 1.0 / (1024.0 * 1024.0), need = (double)atomic_load(pool_refused) * mb;
        C->mem_estimate_mb = (double)rss0 * mb + need;
        st = wrt_fail(WRT_ERR_NOMEM,
                      "the bake would need at least %.0f MB (the links of the transport operator T being refined: "
                      "%.0f MB more than the %.0f MB in use), over the memory budget of %.0f MB (--max-memory; "
                      "default half the physical memory): lower --quality, --max-angular-level or "
                      "--first-bounce-level, or raise --max-memory", (double)rss0 * mb + need, need, (double)rss0 * mb, b->opt.max_memory_mb);
    }
    if (st == WRT_OK && atomic_load(b->cancel)) st = wrt_fail(WRT_ERR_CANCELLED, "bake cancelled");

    return st;
}

/* The power balance's memory (balance.c), counted before it runs: its entries and each
 * thread's working arrays.
 * - Entries: a sender's deltas, one per receiver root and sender column that changed,
 *   held per sender (arrays grown by doubling) until they are appended to the triplets:
 *   at most 60 bytes each. Their number is at most the receivers times the columns summed
 *   over the senders, but that bound is 4 to 8 times what they are (cornell_shapes q3
 *   0.47M against 0.11M, the atrium 6.8M against 0.85M, the maze 1.5M against 0.61M);
 *   measured they are 2.3 (cornell_shapes, the maze) to 5.7 (the atrium) per leaf link,
 *   so 8 per leaf are counted where that is under the bound. (Three a leaf of 24 bytes
 *   were counted before: the atrium's balance passed it by 42 MB.)
 * - Working arrays: for the sender it is on, arrays over (receiver, column) of about 97
 *   bytes (the deltas' and the emitted values' three doubles each, the wavelet rows'
 *   power, the occluded share, the rule's values), with the sender's receivers its leaf
 *   pairs and its columns its functions of the angular root; counted for the `threads`
 *   largest senders at once. */
static uint64_t balance_need(const bake_ctx *b, const pair_list *pl, const dto_job *job, const uint64_t *keys,
                             uint32_t nkeys, uint64_t nleaf) {
    int nq = b->nq, nt = wrt_threads_resolve(b->opt.threads);
    uint64_t *cells = wrt_xcalloc((size_t)nq + 1, sizeof *cells), *cols = wrt_xcalloc((size_t)nq + 1, sizeof *cols);
    for (size_t i = 0; i < pl->npt; i++)
        for (int d = 0; d < 2 && job->out[i].nleaf; d++)
            if (job->out[i].leaf_dirs & (1 << d)) cells[d ? pl->pr[i] : pl->ps[i]]++;
    for (uint32_t f = 0; f < nkeys; f++)
        if (wrt_fkey_angular_root(keys[f]) && wrt_fkey_quad(keys[f]) < (uint32_t)nq) cols[wrt_fkey_quad(keys[f])]++;
    uint64_t bound = 0;
    for (int q = 0; q < nq; q++) {
        cells[q] = b->alevel[b->scene->quads[q].material] ? 0 : cells[q] * (cols[q] + 1);
        bound += cells[q];
    }
    wrt_sort_u64(cells, (size_t)nq);
    uint64_t work = 0;
    for (int k = 0; k < nt && k < nq; k++) work += 97 * cells[nq - 1 - k];
    free(cells); free(cols);
    return 60 * (8 * nleaf < bound ? 8 * nleaf : bound) + work;
}

/* The assembly's passes over the pairs on the bake's threads: each thread its own
 * decoding buffer (and key set); the results do not depend on which thread took which
 * pair. */
typedef struct assemble_job {
    const bake_ctx *b;
    pair_out *out;
    size_t p0;              /* the pairs of this run: p0 + item */
    int nt;
    pair_entry **ebuf;      /* a thread's decoded entries (wrt_pair_entries) */
    size_t *ecap;
    wrt_fkey_set *sets;     /* keys: a thread's set */
    const wrt_fkey_set *ks; /* triplets: the functions' indices */
    const uint64_t *off;    /* triplets: each pair's first triplet */
    wrt_triplet *tr;
} assemble_job;

static void assemble_job_init(assemble_job *j, const bake_ctx *b, pair_out *out) {
    *j = (assemble_job){.b = b, .out = out, .nt = wrt_threads_resolve(b->opt.threads)};
    j->ebuf = wrt_xcalloc((size_t)j->nt, sizeof *j->ebuf);
    j->ecap = wrt_xcalloc((size_t)j->nt, sizeof *j->ecap);
}

static void assemble_job_free(assemble_job *j) {
    for (int t = 0; t < j->nt; t++) free(j->ebuf[t]);
    free(j->ebuf); free(j->ecap);
}

/* Pair p0 + i's functions into its thread's key set */
static void pair_keys(size_t i, int th, void *user) {
    assemble_job *j = user;
    const pair_out *o = &j->out[j->p0 + i];
    const pair_entry *pe = wrt_pair_entries(j->b, o, &j->ebuf[th], &j->ecap[th]);
    for (size_t k = 0; k < o->count; k++) {
        wrt_fkey_set_add(&j->sets[th], pe[k].r);
        if (!o->kmode) wrt_fkey_set_add(&j->sets[th], pe[k].s);
    }
}

/* Pair p0 + i's entries as triplets from its first one on, and the pair cut to the
 * entries the balance reads (wrt_balance_reads_entry, in their order) */
static void pair_triplets(size_t i, int th, void *user) {
    assemble_job *j = user;
    const bake_ctx *b = j->b;
    pair_out *o = &j->out[j->p0 + i];
    wrt_triplet *tr = j->tr + j->off[j->p0 + i];
    /* a compact pair's entries are decoded into the thread's buffer and its kept ones
     * gathered there (in order), then copied out */
    pair_entry *pe = (pair_entry *)wrt_pair_entries(b, o, &j->ebuf[th], &j->ecap[th]);
    size_t keep = 0;
    for (size_t k = 0; k < o->count; k++) {
        const pair_entry *e = &pe[k];
        tr[k].row = (uint32_t)wrt_fkey_set_find(j->ks, e->r);
        tr[k].col = (uint32_t)wrt_fkey_set_find(j->ks, e->s);
        memcpy(tr[k].v, e->v, sizeof e->v);
        if (!b->opt.no_balance && wrt_balance_reads_entry(b, e)) pe[keep++] = *e;
    }
    o->count = keep;
    if (o->d) {
        free(o->d);
        o->d = NULL;
        o->nd = 0;
        o->e = keep ? wrt_xmalloc(keep * sizeof *o->e) : NULL;
        if (keep) memcpy(o->e, pe, keep * sizeof *o->e);
    } else if (!keep) {
        free(o->e);
        o->e = NULL;
    } else {
        o->e = wrt_xrealloc(o->e, keep * sizeof *o->e);
    }
}

/* Stage 6: the basis functions indexed, T assembled and balanced, K assembled and
 * balanced; the status */
static wrt_status bake_assemble(const bake_ctx *b, wrt_bake_counters *C, const pair_list *pl, const dto_job *job,
                                wrt_status st, wrt_bake_result *res) {
    const int *pr = pl->pr, *ps = pl->ps;
    size_t np = pl->np, npt = pl->npt;
    /* index the basis functions: every key used, plus each quad's root */
    uint64_t nent = 0, nkent = 0;
    for (size_t i = 0; i < np; i++) {
        if (job->out[i].kmode) {
            nkent += job->out[i].count;
            C->links_k += job->out[i].links;
            continue;
        }
        nent += job->out[i].count;
        C->links_dto += job->out[i].links;
        C->entries_angular += job->out[i].angular;
        if (job->out[i].glossy) C->links_dto_glossy += job->out[i].links;
        else C->links_dto_diffuse += job->out[i].links;
    }
    if (st == WRT_OK) {
        /* K's rows are basis functions too (a receiver cell finer than T's links reach) */
        /* the distinct keys by a hash set: an array of every entry's two keys and its
         * sort's buffer were 1 GB beside the entries on the 12 x 12 maze, the bake's peak
         * (2.0 GB); the set holds the 2.3 MB of distinct keys */
        wrt_fkey_set ks = {0};
        for (int q = 0; q < b->nq; q++) wrt_fkey_set_add(&ks, wrt_fkey_make((uint32_t)q, wrt_node_root(), 0, wrt_node_root(), 0));
        /* each thread's pairs into its own set, then the sets' keys into one (a set: the
         * same keys whatever the threads) */
        assemble_job aj;
        assemble_job_init(&aj, b, job->out);
        aj.sets = wrt_xcalloc((size_t)aj.nt, sizeof *aj.sets);
        wrt_parallel_for(np, aj.nt, pair_keys, &aj);
        for (int t = 0; t < aj.nt; t++) {
            for (size_t h = 0; h < aj.sets[t].cap; h++)
                if (aj.sets[t].idx[h] != UINT32_MAX) wrt_fkey_set_add(&ks, aj.sets[t].key[h]);
            wrt_fkey_set_free(&aj.sets[t]);
        }
        free(aj.sets);
        aj.sets = NULL;
        uint64_t nu = ks.n;
        if (nu > UINT32_MAX - 1) {
            st = wrt_fail(WRT_ERR_INVALID_ARG, "too many basis functions (%llu)", (unsigned long long)nu);
            wrt_fkey_set_free(&ks);
            assemble_job_free(&aj);
        } else {
            uint64_t *keys = wrt_fkey_set_sorted(&ks);
            if (!keys) keys = wrt_xmalloc(sizeof *keys);
            res->nfuncs = (uint32_t)nu;
            res->fkeys = keys;
            stage_mark(b->clock, "keys");
            wrt_triplet *tr = wrt_xmalloc((nent ? nent : 1) * sizeof *tr);
            /* each pair's entries, once they are triplets, cut to those the balance reads
             * (wrt_balance_reads_entry, in their order; on the mazes their roots' rows):
             * the entries (32 bytes each) and the triplets (20) were held together, 1.72 GB
             * on the 12 x 12 maze; the freed pages go back after every 32nd of the pairs.
             * Each pair's triplets start after the earlier pairs' (the order of before),
             * the pairs on the bake's threads. */
            uint64_t *off = wrt_xmalloc((npt + 1) * sizeof *off);
            off[0] = 0;
            for (size_t i = 0; i < npt; i++) off[i + 1] = off[i] + job->out[i].count;
            uint64_t t = off[npt];
            aj.ks = &ks;
            aj.off = off;
            aj.tr = tr;
            size_t trim_every = npt / 32 + 1;
            for (size_t i0 = 0; i0 < npt; i0 += trim_every) {
                aj.p0 = i0;
                wrt_parallel_for(npt - i0 < trim_every ? npt - i0 : trim_every, aj.nt, pair_triplets, &aj);
                wrt_bake_memory_trim();
            }
            free(off);
            wrt_fkey_set_free(&ks);
            assemble_job_free(&aj);
            stage_mark(b->clock, "triplets");
            /* the balance: per leaf link a reference, the entries it sets and the threads'
             * working arrays (balance_need) */
            uint64_t nleaf = 0;
            for (size_t i = 0; i < npt; i++) nleaf += job->out[i].nleaf;
            if (!b->opt.no_balance)
                st = wrt_bake_memory_check(b->opt.max_memory_mb, &C->mem_estimate_mb,
                                           8 * nleaf + balance_need(b, pl, job, keys, res->nfuncs, nleaf),
                                           "the power balance");
            if (!b->opt.no_balance && st == WRT_OK) {
                if (b->opt.progress) b->opt.progress("balance", -1, b->opt.progress_user); /* no fraction known */
                double tb = wrt_now();
                C->t_balance_begin = tb;
                uint64_t tcap = nent ? nent : 1, t0n = t;
                int cl = wrt_balance_run(b, npt, pr, ps, job->out, keys, res->nfuncs, &tr, &t, &tcap);
                C->closed = cl > 0;
                C->open_quad = cl > 0 ? -1 : -cl - 1;
                C->balance_entries = t - t0n;
                C->t_balance = wrt_now() - tb;
            }
            /* the pairs' entries are all in tr now (the balance read them): freed before T
             * is built beside tr (on the 12 x 12 maze 1 GB of the assembly's peak) */
            for (size_t i = 0; i < npt; i++) {
                free(job->out[i].e); free(job->out[i].leaf);
                job->out[i].e = NULL; job->out[i].leaf = NULL;
            }
            /* their pages back to the system before T grows (glibc keeps freed blocks in
             * the threads' arenas: on the 12 x 12 maze T's assembly peaked on top of them,
             * at 787-792 MB; now the balance's 750 is the bake's peak) */
            wrt_bake_memory_trim();
            stage_mark(b->clock, "balance");
            res->dto = wrt_csc_from_triplets_free(res->nfuncs, tr, t, b->opt.threads); /* tr freed as T grows */
            stage_mark(b->clock, "T");
            /* --clusters with the factored series (and no angular function): T itself is
             * never formed, only E1 (T = E1 U; series_first.c), unless the DTO is the result */
            int fac = b->cl && wrt_series_factored_wanted(b), build_t = !fac || b->opt.dto_only || b->opt.cluster_factored == 3;
            for (uint32_t f = 0; f < res->nfuncs && !build_t; f++) build_t = !wrt_fkey_angular_root(keys[f]);
            if (b->cl && st == WRT_OK) /* --clusters: the links pushed down to the quads' roots,
                                        * as triplets twice and the matrix (cluster_ops.c); E1
                                        * alone: its triplets, the matrix and its row index */
                st = wrt_bake_memory_check(b->opt.max_memory_mb, &C->mem_estimate_mb,
                                           (wrt_clusters_pushed_entries(b->cl, build_t) + res->dto.nnz) *
                                               (build_t ? 2 * sizeof(wrt_triplet) + 16 : sizeof(wrt_triplet) + 20),
                                           "the cluster links' push-down");
            if (b->cl && st == WRT_OK) /* --clusters: the links added, the closed rule, the tree basis */
                C->cluster_fix_entries = wrt_clusters_assemble(b, b->cl, keys, res->nfuncs, C->closed, build_t,
                                                                &res->dto, fac ? &res->dto_e1 : NULL);
            C->t_unformed = b->cl && !build_t && st == WRT_OK;
            stage_mark(b->clock, "cluster links into T");
            if (!b->opt.no_balance && st == WRT_OK) {
                double tb = wrt_now();
                C->balance_entries += wrt_balance_glossy(b, keys, res->nfuncs, &res->dto);
                C->t_balance += wrt_now() - tb;
            }
            C->entries_dto = res->dto.nnz;
            C->entries_spatial = res->dto.nnz - C->entries_angular;
            C->nfuncs = res->nfuncs;
            for (uint32_t f = 0; f < res->nfuncs; f++) C->nfuncs_angular += !wrt_fkey_angular_root(res->fkeys[f]);
            /* K's triplets, then its arrays (the triplets' 16 bytes an entry, then 8) */
            if (nkent && st == WRT_OK)
                st = wrt_bake_memory_check(b->opt.max_memory_mb, &C->mem_estimate_mb, nkent * 24,
                                           "the first-bounce operator K");
            if (nkent && st == WRT_OK) {
                k_assemble(res, job->out + npt, np - npt, nkent);
                if (!b->opt.no_balance) {
                    double tb = wrt_now();
                    C->balance_entries += wrt_balance_k(b, res);
                    C->t_balance += wrt_now() - tb;
                }
            }
        }
    }
    return st;
}

wrt_status wrt_bake_run(const wrt_scene *scene, const wrt_bake_options *opt_in, wrt_bake_result *res) {
    memset(res, 0, sizeof *res);
    bake_ctx b = {.scene = scene, .nq = scene->nquads};
    b.opt = opt_in ? *opt_in : (wrt_bake_options){0};
    wrt_bake_defaults(&b.opt);
    if (b.opt.glossy_quality > b.opt.quality)
        return wrt_fail(WRT_ERR_INVALID_ARG, "the glossy links' quality (%d) must not exceed the quality (%d)",
                        b.opt.glossy_quality, b.opt.quality);
    if (b.opt.receiver_samples % 4 || b.opt.receiver_samples > 64)
        return wrt_fail(WRT_ERR_INVALID_ARG, "receiver samples must be a multiple of 4, at most 64 (got %d)",
                        b.opt.receiver_samples);
    atomic_int cancel;
    atomic_init(&cancel, 0);
    b.cancel = &cancel;
    wrt_bake_counters *C = &res->c;
    double t0 = wrt_now(), cpu0 = wrt_dist_cpu_now();
    stage_clock clock = {getenv("WRT_DTO_TIMES") != NULL, t0, cpu0};
    b.clock = &clock;
    C->open_quad = -1;
    /* the dto phase starts here, with its preparation (frame, materials, ray tracer, pairs) */
    if (b.opt.progress) b.opt.progress("dto", 0, b.opt.progress_user);

    wrt_status fst = bake_frame(&b, scene);
    if (fst != WRT_OK) return fst;
    bake_materials(&b, scene, res);
    wrt_status est = bake_embree(&b);
    if (est != WRT_OK) return est;
    if (clock.on) {
        int ncov = 0;
        for (int q = 0; q < b.nq; q++) ncov += b.cover[q] != 0;
        stage_mark(&clock, "preparation");
        fprintf(stderr, "dto-times:   %d quads, %d with covered parts\n", b.nq, ncov);
    }
    pair_list pl;
    wrt_clusters cl = {0};
    wrt_status lst = WRT_OK; /* the cluster links' exchange */
    if (b.opt.clusters) {
        int glossy = 0;
        for (int m = 0; m < scene->nmaterials; m++) glossy |= b.alevel[m] != 0;
        if (glossy || b.opt.gathered) {
            rtcReleaseScene(b.rtc);
            rtcReleaseDevice(b.dev);
            free(b.quads); free(b.rho); free(b.klevel); free(b.kbmax); free(b.cover);
            for (int m = 0; m < scene->nmaterials; m++) free(b.btilde[m]);
            free(b.btilde);
            wrt_bake_result_free(res);
            return wrt_fail(WRT_ERR_UNSUPPORTED, "--clusters: %s is not supported yet (docs/clusters.md)",
                            glossy ? "a glossy material" : "the gathered operator");
        }
        double c0 = wrt_dist_cpu_now();
        lst = bake_cluster_pairs(&b, &cl, C, &pl);
        stage_mark(&clock, "tree and linking");
        if (b.opt.dist) b.opt.dist->cpu_links = wrt_dist_cpu_now() - c0;
    } else {
        bake_pairs(&b, scene, C, &pl);
        stage_mark(&clock, "pairs");
    }
    /* the DTO's link pool (bake_ctx.h), counted across its threads */
    atomic_ullong pool_bytes, pool_refused;
    dto_job job;
    wrt_status st = bake_dto(&b, C, &pl, &job, &pool_bytes, &pool_refused);
    if (clock.on) {
        stage_mark(&clock, "per-pair DTO");
        wrt_dto_times_cover(job.tc, wrt_threads_resolve(b.opt.threads), pl.np, C->rays_traced);
    }
    if (lst != WRT_OK) st = lst;
    if (job.owner) { /* wrt-bake-mpi: every rank gets every pair's links, and the counters' sums */
        /* the exchange sends the pairs as the DTO keeps them (compact records), in pieces */
        if (st == WRT_OK) st = wrt_dist_merge_pairs(b.opt.dist, job.owner, job.out, pl.np);
        uint64_t sums[7] = {C->samples, C->rays_traced, C->rays_skipped_facing, C->rays_skipped_unoccluded,
                            C->links_refined, C->links_leaf, C->links_invisible};
        if (st == WRT_OK) st = wrt_dist_sum_u64(b.opt.dist, sums, 7);
        C->samples = sums[0]; C->rays_traced = sums[1]; C->rays_skipped_facing = sums[2];
        C->rays_skipped_unoccluded = sums[3]; C->links_refined = sums[4]; C->links_leaf = sums[5];
        C->links_invisible = sums[6];
        free((void *)job.owner);
    }
    double ca = wrt_dist_cpu_now();
    st = bake_assemble(&b, C, &pl, &job, st, res);
    if (b.opt.dist) b.opt.dist->cpu_assemble = wrt_dist_cpu_now() - ca;
    if (st == WRT_OK && wrt_dist_on(b.opt.dist) && atomic_load(&cancel)) /* the balance's exchange failed */
        st = wrt_fail(WRT_ERR_IO, "the ranks' exchange of the power balance failed: %s", wrt_last_error());
    int *pr = pl.pr, *ps = pl.ps;
    uint8_t *occl = pl.occl;
    size_t np = pl.np;
    for (size_t i = 0; i < np; i++) { free(job.out[i].e); free(job.out[i].d); free(job.out[i].leaf); }
    free(job.out); free(job.tc); free(pr); free(ps); free(occl);
    stage_mark(&clock, "the rest");
    double t_end = wrt_now(), cpu1 = wrt_dist_cpu_now();
    if (b.opt.dist) {
        b.opt.dist->cpu_dto = cpu1 - cpu0;
        b.opt.dist->peak_dto = wrt_bake_peak_rss_bytes(); /* the high-water mark: the DTO phase's peak */
    }
    C->t_dto = t_end - t0;
    if (clock.on) fprintf(stderr, "dto-times: the phase %.3f s wall, %.3f s cpu\n", t_end - t0, cpu1 - cpu0);
    C->t_balance_phase = C->t_balance_begin > 0 ? t_end - C->t_balance_begin : 0;

    if (st == WRT_OK && !b.opt.dto_only) {
        /* the series phase starts here (its first term's fraction follows) */
        if (b.opt.progress && !b.opt.progress("gto", 0, b.opt.progress_user)) st = wrt_fail(WRT_ERR_CANCELLED, "bake cancelled");
    }
    if (st == WRT_OK && !b.opt.dto_only) {
        double t1 = wrt_now();
        st = wrt_series_run(&b, res);
        C->t_gto = wrt_now() - t1;
        if (b.opt.dist) b.opt.dist->cpu_series = wrt_dist_cpu_now() - cpu1;
    }
    rtcReleaseScene(b.rtc);
    rtcReleaseDevice(b.dev);
    free(b.quads); free(b.rho); free(b.klevel); free(b.kbmax); free(b.cover);
    for (int m = 0; m < scene->nmaterials; m++) free(b.btilde[m]);
    free(b.btilde);
    if (b.opt.clusters) { /* the tree goes with the result when the operator is in its basis */
        if (C->cluster_tree_basis || C->cluster_senders_basis) {
            res->ctree = cl.tree;
            memset(&cl.tree, 0, sizeof cl.tree);
        }
        wrt_clusters_free(&cl);
    }
    if (st != WRT_OK) {
        char msg[1024];
        snprintf(msg, sizeof msg, "%s", wrt_last_error());
        wrt_bake_result_free(res);
        return wrt_fail(st, "%s", msg);
    }
    return WRT_OK;
}

void wrt_bake_result_free(wrt_bake_result *res) {
    free(res->fkeys);
    wrt_csc_free(&res->dto);
    wrt_csc_free(&res->dto_e1);
    wrt_csc_free(&res->op);
    free(res->material_alevel);
    free(res->kkeys); free(res->kcol_start); free(res->krows); free(res->kvals);
    wrt_ctree_free(&res->ctree);
    memset(res, 0, sizeof *res);
}
