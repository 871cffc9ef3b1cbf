/* relight_create.c: a relighter's creation and destruction (relight.h): checks the
 * options, starts the thread pool (or takes the caller's job hook), copies the
 * materials, decodes every function's key (spatial level and pyramid slot, angular index),
 * lays out the quads (geometry, levels, texture offsets, angular functions), sets up the
 * smooth display, the first-bounce operator, Embree's scene of the quads, the state the
 * updates fill, the BRDF tables of glossy materials and the final gather. The stages run
 * in that order, each a named function; any failure destroys what was made. Kontkanen et
 * al. 2006, section 5 (what the run time precomputes from the file); docs/algorithm.md.
 * Depends on relight_internal.h, formats/gto.h, common/rt_scene.h (Embree), common/threads.h. */
#include "relight_internal.h"

#include <stdlib.h>
#include <unistd.h>

#include "../common/rt_scene.h"

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

static void embree_error(void *user, enum RTCError code, const char *str) {
    relight_log(user, WRT_LOG_WARN, "Embree error %d: %s", (int)code, str ? str : "");
}

typedef struct brdf_ctx { const wrt_material *m; float *tab; int first; } brdf_ctx; /* first: a piece's first cell */
static void brdf_cell_item(wrt_relight *r, worker *w, int item, void *vctx) {
    (void)r; (void)w;
    const brdf_ctx *bc = vctx;
    wrt_brdf_table_build_cell(bc->m, bc->first + item, bc->tab);
}

/* The relighter itself (*out), its options checked, the thread pool or the job hook's
 * worker slots. WRT_ERR_INVALID_ARG, WRT_ERR_NOMEM (nothing is left allocated). */
static wrt_status create_base(const wrt_gto *g, const wrt_relight_options *opt, wrt_relight **out) {
    wrt_relight_options o = {0};
    if (opt) o = *opt;
    if (!(o.skip_below >= 0 && o.skip_below < 1))
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: skip_below %g: a fraction in [0, 1)", o.skip_below);
    if (!(o.budget_ms >= 0 && o.budget_ms <= 1e9))
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: budget_ms %g: milliseconds in [0, 1e9] (0: no budget)", o.budget_ms);
    if (o.gather_points != 0 && o.gather_points != 16 && o.gather_points != 32)
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: gather points %d: 0 (chosen per quad), 16 or 32", o.gather_points);
    if (!o.alloc != !o.free) return wrt_fail(WRT_ERR_INVALID_ARG, "relight: an allocator needs both alloc and free");
    wrt_relight *r = o.alloc ? o.alloc(o.alloc_user, sizeof *r) : malloc(sizeof *r);
    if (!r) return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory");
    memset(r, 0, sizeof *r);
    r->g = g;
    r->mul.op.col_start = g->col_start; r->mul.op.rows = g->rows; r->mul.op.vals = g->vals; r->mul.op.nnz = g->nnz;
    r->mul.op.bcol = g->op_bcol; r->mul.op.row0 = g->op_row0; r->mul.op.base = g->op_base; r->mul.op.codes = g->op_codes;
    r->mul.op.deltas = g->op_deltas;
    r->opt = o;
    if (r->opt.proj_level < 0 || r->opt.proj_level > PROJ_MAX_LEVEL) {
        relight_free(r, r);
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: projection level %d outside 0..%d", opt->proj_level, PROJ_MAX_LEVEL);
    }
    int mt = r->opt.max_tex_res > 0 ? r->opt.max_tex_res : 64;
    r->max_tex_level = 0;
    while ((2 << r->max_tex_level) <= mt && r->max_tex_level < 12) r->max_tex_level++;
    long nc = sysconf(_SC_NPROCESSORS_ONLN);
    r->nthreads = r->opt.threads > 0 ? r->opt.threads : (int)(nc > 0 ? nc : 1);
    if (r->nthreads > 64) r->nthreads = 64;
    if (r->opt.parallel_for) { /* the caller's job hook: no thread of our own */
        r->wbusy = relight_calloc(r, (size_t)r->nthreads, sizeof *r->wbusy);
        if (r->oom) { relight_free(r, r); return wrt_fail(WRT_ERR_NOMEM, "relight: out of memory"); }
        for (int t = 0; t < r->nthreads; t++) atomic_init(&r->wbusy[t], 0);
    } else {
        if (wrt_pool_create(r->nthreads, &r->pool) != WRT_OK) {
            relight_free(r, r);
            return wrt_fail(WRT_ERR_NOMEM, "relight: no memory for the thread pool");
        }
        r->nthreads = wrt_pool_size(r->pool);
    }
    *out = r;
    return WRT_OK;
}

/* Each worker's scratch of fixed size (the projection's tree); the rest grows in updates. */
static wrt_status create_workers(wrt_relight *r) {
    r->workers = relight_calloc(r, (size_t)r->nthreads, sizeof(worker));
    if (r->oom) return WRT_ERR_NOMEM;
    for (int t = 0; t < r->nthreads; t++) {
        r->workers[t].pstate = relight_calloc(r, PROJ_TREE_CELLS, sizeof(uint32_t));
        r->workers[t].prefined = relight_calloc(r, PROJ_TREE_CELLS, 1);
        r->workers[t].pclear = relight_calloc(r, PROJ_TREE_CELLS, 1);
        r->workers[t].pcells = relight_calloc(r, PROJ_TREE_CELLS, sizeof(uint16_t));
    }
    return r->oom ? WRT_ERR_NOMEM : WRT_OK;
}

/* The file's materials as common/brdf.h takes them. */
static wrt_status create_materials(wrt_relight *r) {
    const wrt_gto *g = r->g;
    r->mats = relight_calloc(r, g->nmaterials ? g->nmaterials : 1, sizeof(wrt_material));
    if (r->oom) return WRT_ERR_NOMEM;
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
    return WRT_OK;
}

/* Per function: spatial level and pyramid slot, angular index (a key that is not a basis
 * function is never read nor written, with a warning). */
static wrt_status create_functions(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nf = g->nfuncs;
    r->fn_slevel = relight_calloc(r, nf ? nf : 1, 1);
    r->fn_ang = relight_calloc(r, nf ? nf : 1, 1);
    r->fn_spidx = relight_calloc(r, nf ? nf : 1, sizeof(uint32_t));
    r->fn_flux = relight_calloc(r, nf ? nf : 1, sizeof(float));
    if (r->oom) return WRT_ERR_NOMEM;
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
    return WRT_OK;
}

/* Quad q's geometry (corners, frame, area, diameter, bounding sphere) and material. */
static void quad_geometry(wrt_relight *r, uint32_t q, wrt_v3 *bmin, wrt_v3 *bmax) {
    const wrt_gto_quad *gq = &r->g->quads[q];
    quad_info *qi = &r->qi[q];
    for (int k = 0; k < 4; k++) {
        qi->p[k] = v3(gq->p[k][0], gq->p[k][1], gq->p[k][2]);
        *bmin = v3(fmin(bmin->x, qi->p[k].x), fmin(bmin->y, qi->p[k].y), fmin(bmin->z, qi->p[k].z));
        *bmax = v3(fmax(bmax->x, qi->p[k].x), fmax(bmax->y, qi->p[k].y), fmax(bmax->z, qi->p[k].z));
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
}

/* The flux of a unit coefficient of the spatial function (node n, type) on a general
 * quad: sqrt(pi) int h sqrt(J) du dv (the function is h / sqrt(J) on the surface and its
 * coefficients are of E sqrt(J / pi)). J is affine in u and v on a planar convex quad, so
 * sqrt(J) is smooth: 3 x 3 Gauss-Legendre points per quadrant (1e-9 relative on the
 * triangles' parts, whose J varies 3 to 1). */
static double func_flux(const quad_info *q, wrt_node n, int type) {
    static const double gx[3] = {0.11270166537925831, 0.5, 0.88729833462074169};
    static const double gw[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
    double size = wrt_node_size(n), h = 0.5 * size, sum = 0;
    for (int c = 0; c < 4; c++) {
        double sign = type == 0 ? 1 : wrt_haar_sign(type, c & 1, c >> 1);
        double u0 = wrt_node_x0(n) + (c & 1) * h, v0 = wrt_node_y0(n) + (c >> 1) * h;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) sum += sign * gw[i] * gw[j] * sqrt(quad_jacobian(q, u0 + h * gx[i], v0 + h * gx[j]));
    }
    return sqrt(WRT_PI) * sum * h * h / size; /* the Haar function's value is 1 / size */
}

/* Quad q's levels (spatial, angular, texture) and texture offset (*tex_total grows),
 * its mean irradiance factor, root function and the number of its angular functions
 * (*ang_total grows). */
static void quad_functions(wrt_relight *r, uint32_t q, size_t *tex_total, size_t *ang_total) {
    const wrt_gto *g = r->g;
    const wrt_gto_quad *gq = &g->quads[q];
    quad_info *qi = &r->qi[q];
    int sl = 0;
    for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++)
        if (r->fn_slevel[f] > sl && r->fn_slevel[f] != FN_INVALID) sl = r->fn_slevel[f];
    qi->slevel = sl;
    if (!qi->parallelogram) /* the projection's flux correction (relight_project.c) */
        for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++)
            if (r->fn_slevel[f] != FN_INVALID && r->fn_ang[f] == 0)
                r->fn_flux[f] = (float)func_flux(qi, wrt_fkey_snode(g->fkeys[f]), wrt_fkey_stype(g->fkeys[f]));
    for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++)
        if (r->fn_slevel[f] != FN_INVALID && r->fn_ang[f] != 0) {
            int al = (int)wrt_fkey_anode(g->fkeys[f]).level;
            if (al > qi->alevel) qi->alevel = al;
        }
    qi->tex_level = sl + 1 < r->max_tex_level ? sl + 1 : r->max_tex_level;
    qi->tex_off = *tex_total;
    *tex_total += ((size_t)1 << (2 * qi->tex_level)) * 3;
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
    qi->ang_first = (uint32_t)*ang_total;
    *ang_total += (size_t)na;
}

/* Per quad: geometry, levels, texture offsets (*tex_total), angular functions
 * (*ang_total); the scene's bounds. WRT_ERR_CORRUPT naming the quad, WRT_ERR_NOMEM. */
static wrt_status create_quads(wrt_relight *r, size_t *tex_total, size_t *ang_total, wrt_v3 *bmin, wrt_v3 *bmax) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads;
    r->qi = relight_calloc(r, nq ? nq : 1, sizeof(quad_info));
    if (r->oom) return WRT_ERR_NOMEM;
    *bmin = v3(INFINITY, INFINITY, INFINITY);
    *bmax = v3(-INFINITY, -INFINITY, -INFINITY);
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_gto_quad *gq = &g->quads[q];
        if ((uint64_t)gq->func_first + gq->func_count > g->nfuncs || gq->material >= g->nmaterials)
            return wrt_fail(WRT_ERR_CORRUPT, "relight: quad %u: functions or material out of range", q);
        quad_geometry(r, q, bmin, bmax);
        quad_functions(r, q, tex_total, ang_total);
    }
    return WRT_OK;
}

/* Each quad's functions grouped by angular index (ang_perm), its present angular indices
 * (ang_list) and their ranges (ang_start), and whether each fills its synthesis pyramid
 * (levels < tex_level) without clearing (ang_full, qi.synth_full). */
static wrt_status create_angular(wrt_relight *r, size_t ang_total) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads, nf = g->nfuncs;
    r->ang_list = relight_calloc(r, ang_total ? ang_total : 1, sizeof(uint16_t));
    r->ang_start = relight_calloc(r, ang_total + nq + 1, sizeof(uint32_t));
    r->ang_full = relight_calloc(r, ang_total + 1, 1);
    r->ang_perm = relight_calloc(r, nf ? nf : 1, sizeof(uint32_t));
    if (r->oom) return WRT_ERR_NOMEM;
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
    return WRT_OK;
}

/* Embree scene of every quad, in a frame centred on the scene (float precision). */
static wrt_status create_rays(wrt_relight *r, wrt_v3 bmin, wrt_v3 bmax) {
    uint32_t nq = r->g->nquads;
    r->rt.origin = nq ? v3_scale(v3_add(bmin, bmax), 0.5) : v3(0, 0, 0);
    r->rt.scene_diag = nq ? v3_len(v3_sub(bmax, bmin)) : 1;
    if (!(r->rt.scene_diag > 0)) r->rt.scene_diag = 1;
    wrt_v3 *corners = relight_calloc(r, (size_t)(nq ? nq : 1) * 4, sizeof *corners);
    if (r->oom) return WRT_ERR_NOMEM;
    for (uint32_t q = 0; q < nq; q++)
        for (int k = 0; k < 4; k++) corners[4 * q + k] = r->qi[q].p[k];
    wrt_rt_scene rs;
    wrt_status est = wrt_rt_scene_build(corners, (int)nq, r->rt.origin, NULL, 0, &rs);
    relight_free(r, corners);
    if (est != WRT_OK) return est;
    r->rt.dev = rs.dev;
    r->rt.scene = rs.scene;
    r->rt.eps = rs.eps;
    r->rt.ray4 = rtcGetDeviceProperty(r->rt.dev, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) != 0;
    if (r->opt.log) rtcSetDeviceErrorFunction(r->rt.dev, embree_error, r); /* Embree's errors to our log */
    return WRT_OK;
}

/* What the updates fill (E, X, the textures and their factors, per-quad flags) and the
 * projection's per-quad scratch. */
static wrt_status create_state(wrt_relight *r, size_t tex_total) {
    uint32_t nq = r->g->nquads, nf = r->g->nfuncs;
    r->E = relight_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->X = relight_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->Xprev = relight_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    if (r->opt.skip_below > 0) r->Eapplied = relight_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->mul.X4 = relight_calloc(r, (size_t)nf * 4 + 4, sizeof(float)); /* malloc: 16-byte aligned */
    r->mul.cols = relight_calloc(r, (size_t)nf + 1, sizeof(uint32_t));
    /* each light keeps its own product where X is a plain sum of the lights' (no first
     * bounce K, whose E' mixes them, and no emitters, whose terms join E) */
    r->mul.per_light = !r->g->nkcols && !r->nemitters;
    if (r->mul.per_light) r->mul.Ed = relight_calloc(r, (size_t)nf * 3 + 1, sizeof(float));
    r->tex = relight_calloc(r, tex_total + 1, sizeof(float));
    r->texk = relight_calloc(r, tex_total / 3 + 1, sizeof(float));
    if (r->oom) return WRT_ERR_NOMEM;
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
    r->tex_nonzero = relight_calloc(r, nq + 1, 1);
    r->x_nonzero = relight_calloc(r, nq + 1, 1);
    r->resynth = relight_calloc(r, nq + 1, 1);
    r->proj.recs = relight_calloc(r, nq + 1, sizeof(out_rec));
    r->proj.qlevel = relight_calloc(r, nq + 1, sizeof(int8_t));
    r->proj.cones = relight_calloc(r, nq + 1, sizeof(light_cone));
    if (!r->oom && relight_occ_build(r) != 0) return WRT_ERR_NOMEM;
    r->synth_list = relight_calloc(r, nq + 1, sizeof(int));
    return r->oom ? WRT_ERR_NOMEM : WRT_OK;
}

/* BRDF tables of the materials glossy quads use (on the pool or the caller's hook), in
 * pieces of 16 cells a thread between progress calls (about 1.2 ms a cell on one of this
 * loaded machine's 2 cores: 20-40 ms a piece). WRT_ERR_NOMEM, WRT_ERR_CANCELLED. */
static wrt_status create_brdf_tables(wrt_relight *r) {
    const int piece = 16 * r->nthreads;
    const wrt_gto *g = r->g;
    r->beta = relight_calloc(r, g->nmaterials + 1, sizeof(float *));
    if (r->oom) return WRT_ERR_NOMEM;
    int ntab = 0, done = 0;
    for (uint32_t m = 0; m < g->nmaterials; m++) ntab += material_used_glossy(r, m);
    double span = PROGRESS_GATHER - PROGRESS_TABLES;
    for (uint32_t m = 0; m < g->nmaterials; m++) {
        if (!material_used_glossy(r, m)) continue;
        r->beta[m] = relight_calloc(r, (size_t)BETA_RES * BETA_RES * NANG * 3, sizeof(float));
        if (r->oom) return WRT_ERR_NOMEM;
        for (int c0 = 0; c0 < BETA_RES * BETA_RES; c0 += piece) {
            int n = BETA_RES * BETA_RES - c0 < piece ? BETA_RES * BETA_RES - c0 : piece;
            brdf_ctx bc = {&r->mats[m], r->beta[m], c0};
            relight_parallel_for(r, n, 1e9, brdf_cell_item, &bc);
            double f = (done + (double)(c0 + n) / (BETA_RES * BETA_RES)) / ntab;
            if (!relight_progress(r, PROGRESS_TABLES + span * f))
                return wrt_fail(WRT_ERR_CANCELLED, "relight: cancelled by the progress callback");
        }
        done++;
    }
    return WRT_OK;
}

/* Each worker's scratch at the largest size any quad needs (the projection's cells and
 * pyramid, its list of occluders and output, the synthesis's pyramid and glossy
 * lookups), so that no update allocates (grown on demand, a worker that first met a
 * large quad allocated then: 2 blocks in 10 updates of a small room on 2 threads). */
static wrt_status create_scratch(wrt_relight *r) {
    const wrt_gto *g = r->g;
    size_t pval = 1, pwav = 1, pflux = 1, pyr = 1, fpyr = 1, fgrid = 1, glossy = 1;
    for (uint32_t q = 0; q < g->nquads; q++) {
        const quad_info *qi = &r->qi[q];
        size_t ncell = (size_t)1 << (2 * qi->tex_level);
        if (ncell * 4 > fpyr) fpyr = ncell * 4;
        if (ncell + 4 > fgrid) fgrid = ncell + 4;
        if (qi->glossy && ncell > glossy) glossy = ncell;
        if (g->quads[q].func_count == 0) continue;
        int cap = relight_projection_cap(r, qi);
        size_t nslot = (size_t)(qi->nang > 0 && !qi->kcount ? qi->nang : 1) + 3 * (size_t)qi->nkang;
        if (LEVEL_OFF(cap + 1) * nslot > pval) pval = LEVEL_OFF(cap + 1) * nslot;
        if (LEVEL_OFF(cap) * 3 * nslot + 1 > pwav) pwav = LEVEL_OFF(cap) * 3 * nslot + 1;
        if (!qi->parallelogram && LEVEL_OFF(cap + 1) > pflux) pflux = LEVEL_OFF(cap + 1);
        if (((size_t)1 << (2 * cap)) * nslot > pyr) pyr = ((size_t)1 << (2 * cap)) * nslot;
    }
    size_t nout = (size_t)g->nfuncs + 1, nocc = (size_t)g->nquads + 1;
    for (int t = 0; t < r->nthreads; t++) {
        worker *w = &r->workers[t];
        w->pval = relight_calloc(r, w->pval_cap = pval, sizeof *w->pval);
        w->pwav = relight_calloc(r, w->pwav_cap = pwav, sizeof *w->pwav);
        w->pflux = relight_calloc(r, w->pflux_cap = pflux, sizeof *w->pflux);
        w->pyr = relight_calloc(r, w->pyr_cap = pyr, sizeof *w->pyr);
        w->occ = relight_calloc(r, w->nocc_cap = nocc, sizeof *w->occ);
        w->oidx = relight_calloc(r, nout, sizeof *w->oidx);
        w->oval = relight_calloc(r, 3 * nout, sizeof *w->oval);
        w->ocap = nout;
        w->fpyr = relight_calloc(r, w->fpyr_cap = fpyr, sizeof *w->fpyr);
        w->fgrid = relight_calloc(r, w->fgrid_cap = fgrid, sizeof *w->fgrid);
        if (glossy > 1 || r->opt.no_gather) { /* the coarse angular synthesis of glossy quads */
            w->grid = relight_calloc(r, w->grid_cap = glossy * 3, sizeof *w->grid);
            w->acc = relight_calloc(r, w->acc_cap = glossy * 3, sizeof *w->acc);
            w->cells = relight_calloc(r, glossy * 4, sizeof *w->cells);
            w->wts = relight_calloc(r, glossy * 4, sizeof *w->wts);
            w->view_cap = glossy * 4;
        }
        if (r->oom) return WRT_ERR_NOMEM;
    }
    return WRT_OK;
}

/* The stages in order; the first failure's status (WRT_ERR_NOMEM with its message set
 * here, the others set theirs). */
static wrt_status create_stages(wrt_relight *r) {
    wrt_status st;
    size_t tex_total = 0, ang_total = 0;
    wrt_v3 bmin, bmax;
    if ((st = create_workers(r)) || (st = create_materials(r)) || (st = create_functions(r)) ||
        (st = create_quads(r, &tex_total, &ang_total, &bmin, &bmax)) || (st = relight_setup_emitters(r)))
        goto fail;
    if (!r->opt.haar_blocks && (st = relight_setup_smooth(r, &tex_total))) goto fail;
    if ((st = create_angular(r, ang_total))) goto fail;
    if (r->g->nkcols && (st = relight_setup_first_bounce(r))) return st;
    if ((st = create_rays(r, bmin, bmax))) return r->oom ? wrt_fail(WRT_ERR_NOMEM, "relight: out of memory") : st;
    if ((st = create_state(r, tex_total)) || (st = create_scratch(r))) goto fail;
    if ((st = relight_setup_clusters(r))) goto fail;
    if (!relight_progress(r, PROGRESS_TABLES)) return wrt_fail(WRT_ERR_CANCELLED, "relight: cancelled by the progress callback");
    if ((st = create_brdf_tables(r)) || (st = relight_setup_gather(r))) goto fail;
    if (!relight_progress(r, 1.0)) return wrt_fail(WRT_ERR_CANCELLED, "relight: cancelled by the progress callback");
    return WRT_OK;
fail:
    return st == WRT_ERR_NOMEM ? wrt_fail(WRT_ERR_NOMEM, "relight: out of memory") : st;
}

wrt_status wrt_relight_create(const wrt_gto *g, const wrt_relight_options *opt, wrt_relight **out) {
    *out = NULL;
    if (!g) return wrt_fail(WRT_ERR_INVALID_ARG, "relight: no operator");
    wrt_relight *r = NULL;
    wrt_status st = create_base(g, opt, &r);
    if (st != WRT_OK) return st;
    st = create_stages(r);
    if (st != WRT_OK) { wrt_relight_destroy(r); return st; }
    *out = r;
    return WRT_OK;
}

void wrt_relight_destroy(wrt_relight *r) {
    if (!r) return;
    wrt_pool_destroy(r->pool);
    wrt_gather_destroy(r->gat.gather);
    for (int k = 0; k < 5; k++) relight_free(r, r->mul.own[k]);
    if (r->gat.diff) for (uint32_t q = 0; q < r->g->nquads; q++) relight_free(r, r->gat.diff[q]);
    relight_free(r, r->gat.tex); relight_free(r, r->gat.out); relight_free(r, r->gat.res); relight_free(r, r->gat.ires); relight_free(r, r->gat.diff); relight_free(r, r->gat.alb);
    if (r->rt.scene) rtcReleaseScene(r->rt.scene);
    if (r->rt.dev) rtcReleaseDevice(r->rt.dev);
    for (int i = 0; i < r->lights_cap; i++) {
        relight_free(r, r->lights[i].idx); relight_free(r, r->lights[i].val); relight_free(r, r->lights[i].root);
        relight_free(r, r->lights[i].kc); relight_free(r, r->lights[i].X4);
    }
    relight_free(r, r->lights);
    if (r->workers)
        for (int t = 0; t < r->nthreads; t++) {
            worker *w = &r->workers[t];
            /* scratch grown in updates */
            relight_free(r, w->grid); relight_free(r, w->pyr); relight_free(r, w->acc); relight_free(r, w->wts); relight_free(r, w->cells);
            relight_free(r, w->oidx); relight_free(r, w->oval); relight_free(r, w->fpyr); relight_free(r, w->fgrid); relight_free(r, w->occ);
            relight_free(r, w->pval); relight_free(r, w->pwav); relight_free(r, w->pflux); relight_free(r, w->rbuf);
            relight_free(r, w->pstate); relight_free(r, w->prefined); relight_free(r, w->pclear); relight_free(r, w->pcells);
        }
    relight_free(r, r->workers);
    relight_free(r, (void *)r->wbusy);
    if (r->beta) for (uint32_t m = 0; m < r->g->nmaterials; m++) relight_free(r, r->beta[m]);
    relight_free(r, r->beta);
    if (r->qi) for (uint32_t q = 0; q < r->g->nquads; q++) relight_free(r, r->qi[q].known);
    relight_free(r, r->mats); relight_free(r, r->fn_slevel); relight_free(r, r->fn_ang); relight_free(r, r->fn_spidx); relight_free(r, r->fn_flux); relight_free(r, r->qi);
    relight_free(r, r->ang_list); relight_free(r, r->ang_start); relight_free(r, r->ang_full); relight_free(r, r->ang_perm);
    relight_free(r, r->E); relight_free(r, r->X); relight_free(r, r->Xprev); relight_free(r, r->Eapplied); relight_free(r, r->mul.X4); relight_free(r, r->mul.Ed); relight_free(r, r->mul.cols); relight_free(r, r->tex); relight_free(r, r->texk); relight_free(r, r->tex_nonzero); relight_free(r, r->x_nonzero);
    relight_free(r, r->resynth); relight_free(r, r->proj.recs); relight_free(r, r->proj.qlevel); relight_free(r, r->proj.cones);
    relight_free(r, r->proj.onode); relight_free(r, r->proj.ocones); relight_free(r, r->proj.oorder);
    relight_free(r, r->synth_list); relight_free(r, r->emit_scale);
    wrt_ctree_free(&r->ct.t); relight_free(r, r->ct.root); relight_free(r, r->ct.Et); relight_free(r, r->ct.scratch);
    wrt_recon_destroy(r->sm.recon); relight_free(r, r->sm.stex); relight_free(r, r->sm.regroup);
    relight_free(r, r->sm.rin); relight_free(r, r->sm.rknown); relight_free(r, r->sm.rout);
    relight_free(r, r->k.fn_slevel); relight_free(r, r->k.fn_ang); relight_free(r, r->k.fn_spidx);
    relight_free(r, r->k.kt_start); relight_free(r, r->k.kt);
    relight_free(r, r->k.k4_row); relight_free(r, r->k.k4_start); relight_free(r, r->k.k4_n); relight_free(r, r->k.k4_cols); relight_free(r, r->k.k4_vals); relight_free(r, r->k.k4_h); relight_free(r, r->k.k4_c16); relight_free(r, r->k.k4_exp);
    relight_free(r, r->k.C); relight_free(r, r->k.Y); relight_free(r, r->k.Y4); relight_free(r, r->k.Ep);
    relight_free(r, r);
}
