/* test_stress.c: scenes made to break light transport code, each compared with a truth
 * that does not depend on the bake (precompute/) or the player core (player/relight.c):
 * furnaces at albedos up to 0.999 (rho / (1 - rho)), quads at right angles and at a one
 * degree wedge (closed forms and a dense numerical integral written here), a box scaled
 * by 1e-3 and 1e3 and moved 1e5 away (the unscaled result), a 1e-3 quad among 1e3 walls,
 * glossy and mirror furnaces (the albedo bound), lights on a surface, at a vertex and
 * outside a closed box (zero where physics says zero), coplanar and back-facing quads
 * (no transfer, no rays), a thin wall between two rooms (the reference path tracer of
 * verify/reference.h in the dark room) and degenerate files through wrt-bake (exit code 2).
 * Every case checks the bake's T and G - I and the player's E, X and textures for NaN,
 * Inf and negative energy. Each case prints its measured figure next to its truth.
 * Fast sizes by default; WRT_STRESS_FULL=1 (`make stress`) runs the full sizes. */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "common/basis.h"
#include "common/brdf.h"
#include "ff_closed.h"
#include "player/relight.h"
#include "precompute/bake.h"
#include "bake_helpers.h"
#include "claims.h"
#include "scene_build.h"
#include "test.h"
#include "verify/reference.h"

static int full;             /* WRT_STRESS_FULL=1 */

static char tmpdir[256];





/* ---------------------------------------------------------------- sanity ---- */

/* NaN / Inf anywhere in a matrix, and negative energy: an entry between two root
 * (scaling) functions is a flux transfer and must be >= -tol * the largest entry. */
static void check_matrix(const wrt_bake_result *r, const wrt_csc *m, const char *what) {
    uint64_t bad = 0, neg = 0;
    double mx = 0, worst = 0;
    for (uint64_t k = 0; k < m->nnz * 3; k++) {
        if (!isfinite(m->val[k])) bad++;
        else mx = fmax(mx, fabs(m->val[k]));
    }
    for (uint32_t j = 0; j < m->n; j++) {
        uint64_t sk = r->fkeys[j];
        if (wrt_fkey_snode(sk).level != 0 || wrt_fkey_stype(sk) != 0 || !wrt_fkey_angular_root(sk)) continue;
        for (uint64_t k = m->col[j]; k < m->col[j + 1]; k++) {
            uint64_t rk = r->fkeys[m->row[k]];
            if (wrt_fkey_snode(rk).level != 0 || wrt_fkey_stype(rk) != 0 || !wrt_fkey_angular_root(rk)) continue;
            for (int c = 0; c < 3; c++)
                if (m->val[3 * k + c] < -1e-6 * mx) { neg++; worst = fmin(worst, m->val[3 * k + c]); }
        }
    }
    CHECK(bad == 0, "%s: %llu non-finite values", what, (unsigned long long)bad);
    CHECK(neg == 0, "%s: %llu negative root-to-root entries (worst %.3g, max %.3g)", what, (unsigned long long)neg,
          worst, mx);
}

static void check_bake(const wrt_bake_result *r, const char *what) {
    char b[128];
    snprintf(b, sizeof b, "%s: T", what);
    check_matrix(r, &r->dto, b);
    snprintf(b, sizeof b, "%s: G - I", what);
    check_matrix(r, &r->op, b);
    CHECK(isfinite(r->c.energy_left) && isfinite(r->c.tail_fraction) && isfinite(r->c.series_ratio),
          "%s: series figures finite", what);
}

/* ------------------------------------------------------------- the player ---- */

typedef struct player {
    wrt_gto g;
    wrt_relight *rl;
    const wrt_scene *s;
    char path[300];
} player;

/* Writes the bake to a .gto (what wrt-bake does), opens it and makes a relighter. */
static int player_open(const wrt_scene *s, const wrt_bake_result *r, player *p) {
    static int counter;
    memset(p, 0, sizeof *p);
    p->s = s;
    snprintf(p->path, sizeof p->path, "%s/s%d.gto", tmpdir, counter++);
    wrt_scene sc = *s;
    sc.quads = malloc((size_t)s->nquads * sizeof *sc.quads);
    memcpy(sc.quads, s->quads, (size_t)s->nquads * sizeof *sc.quads);
    for (int q = 0; q < sc.nquads; q++) sc.quads[q].name = -1;
    wrt_gto_contents gc = {
        .scene = &sc, .fkeys = r->fkeys, .nfuncs = r->nfuncs, .col_start = r->op.col, .rows = r->op.row,
        .vals = r->op.val, .op_kind = (uint32_t)r->op_kind, .material_alevel = r->material_alevel,
    };
    wrt_status st = wrt_gto_write(p->path, &gc);
    free(sc.quads);
    CHECK(st == WRT_OK, "gto write: %s", wrt_last_error());
    if (st != WRT_OK) return 0;
    st = wrt_gto_open(p->path, &p->g);
    CHECK(st == WRT_OK, "gto open: %s", wrt_last_error());
    if (st != WRT_OK) return 0;
    wrt_relight_options ro = {.threads = 2, .max_tex_res = 16};
    st = wrt_relight_create(&p->g, &ro, &p->rl);
    CHECK(st == WRT_OK, "relight: %s", wrt_last_error());
    return st == WRT_OK;
}

static void player_close(player *p) {
    wrt_relight_destroy(p->rl);
    wrt_gto_close(&p->g);
    unlink(p->path);
}

static wrt_light point_light(wrt_v3 pos, double intensity) {
    wrt_light l;
    memset(&l, 0, sizeof l);
    l.type = WRT_LIGHT_POINT;
    snprintf(l.name, sizeof l.name, "point");
    l.pos = pos;
    l.dir = v3(0, 0, -1);
    l.color[0] = l.color[1] = l.color[2] = 1;
    l.intensity = (float)intensity;
    l.outer_cone = (float)(M_PI / 4);
    return l;
}

/* Fluxes and per-quad mean irradiances after lighting with `l`; checks every output of
 * the player for NaN / Inf and negative energy (means: below -1e-6 of the largest;
 * texels: below -tex_tol of the largest texel). */
typedef struct lit { double flux_direct, flux_indirect, *direct, *indirect; double tex_min_rel; } lit;

static void player_light(player *p, const wrt_light *l, lit *out, const char *what) {
    const wrt_scene *s = p->s;
    wrt_relight_set_lights(p->rl, l, NULL, 1);
    double eye[3] = {0.5 * (s->bbox_min.x + s->bbox_max.x), 0.5 * (s->bbox_min.y + s->bbox_max.y),
                     0.5 * (s->bbox_min.z + s->bbox_max.z)};
    wrt_relight_set_eye(p->rl, eye);
    wrt_relight_update(p->rl, NULL);
    memset(out, 0, sizeof *out);
    out->direct = calloc((size_t)s->nquads, sizeof(double));
    out->indirect = calloc((size_t)s->nquads, sizeof(double));
    int nonfinite = 0;
    double mx = 0, tmax = 0, tmin = 0;
    for (int q = 0; q < s->nquads; q++) {
        double d[3], ind[3];
        wrt_relight_quad_irradiance(p->rl, q, d, ind);
        for (int c = 0; c < 3; c++) if (!isfinite(d[c]) || !isfinite(ind[c])) nonfinite++;
        out->direct[q] = d[0];
        out->indirect[q] = ind[0];
        out->flux_direct += d[0] * s->quads[q].area;
        out->flux_indirect += ind[0] * s->quads[q].area;
        mx = fmax(mx, fmax(d[0], ind[0]));
        int res = wrt_relight_tex_res(p->rl, q);
        const float *t = wrt_relight_tex(p->rl, q);
        for (int k = 0; t && k < 3 * res * res; k++) {
            if (!isfinite(t[k])) nonfinite++;
            else { tmax = fmax(tmax, t[k]); tmin = fmin(tmin, t[k]); }
        }
    }
    size_t nf = p->g.nfuncs;
    const float *E = wrt_relight_E(p->rl), *X = wrt_relight_X(p->rl);
    for (size_t k = 0; k < 3 * nf; k++) if (!isfinite(E[k]) || !isfinite(X[k])) nonfinite++;
    CHECK(nonfinite == 0, "%s: %d non-finite player outputs", what, nonfinite);
    int neg = 0;
    for (int q = 0; q < s->nquads; q++) neg += out->direct[q] < -1e-6 * mx || out->indirect[q] < -1e-6 * mx;
    CHECK(neg == 0, "%s: %d quads with negative mean irradiance", what, neg);
    out->tex_min_rel = tmax > 0 ? tmin / tmax : 0;
}

static void lit_free(lit *l) { free(l->direct); free(l->indirect); }

/* --------------------------------------------------------------- furnace ---- */

/* Uniform irradiance 1 injected on every quad's root of a parallelogram scene, G - I
 * applied: each quad's mean indirect irradiance against truth. Returns the worst
 * relative error; lo, hi and the area-weighted mean come back too. */
static double uniform_response(const wrt_scene *s, const wrt_bake_result *r, double truth, double *lo, double *hi,
                               double *mean) {
    double *x = calloc(3 * r->nfuncs, sizeof *x), *y = calloc(3 * r->nfuncs, sizeof *y);
    for (int q = 0; q < s->nquads; q++) {
        int64_t f = wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q));
        for (int c = 0; c < 3; c++) x[3 * f + c] = sqrt(s->quads[q].area / M_PI);
    }
    wrt_csc_apply(&r->op, x, y);
    double worst = 0, flux = 0, area = 0;
    *lo = INFINITY; *hi = 0;
    for (int q = 0; q < s->nquads; q++) {
        int64_t f = wrt_fkey_find(r->fkeys, r->nfuncs, root_key(q));
        double e = y[3 * f] * sqrt(M_PI / s->quads[q].area);
        *lo = fmin(*lo, e); *hi = fmax(*hi, e);
        worst = fmax(worst, fabs(e / truth - 1));
        flux += e * s->quads[q].area;
        area += s->quads[q].area;
    }
    *mean = flux / area;
    free(x); free(y);
    return worst;
}

/* Injected uniform irradiance E0 = 1 on every quad of a closed box of albedo rho: the
 * converged indirect irradiance is rho / (1 - rho) everywhere. */
static void test_furnace(void) {
    double rhos[4] = {0.5, 0.9, 0.99, 0.999};
    int n = full ? 3 : 1, quality = full ? 6 : 4;
    for (int i = 0; i < 4; i++) {
        double rho = rhos[i], truth = rho / (1 - rho);
        wrt_scene s;
        tsb_init(&s);
        int m = tsb_material(&s, rho, rho, rho);
        tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), n, m);
        wrt_bake_result r;
        wrt_bake_options o = opts(quality, 0, 0);
        wrt_status st = wrt_bake_run(&s, &o, &r);
        if (st == WRT_ERR_ACCURACY) {
            /* a diverging series must be refused with a clear error, never truncated silently */
            CHECK(strstr(wrt_last_error(), "diverges") != NULL, "message: %s", wrt_last_error());
            printf("furnace rho %.3f: the bake refuses: %s\n", rho, wrt_last_error());
            CHECK(0, "furnace rho %.3f: no operator (series diverges)", rho);
            tsb_free(&s);
            continue;
        }
        CHECK(st == WRT_OK, "%s", wrt_last_error());
        check_bake(&r, "furnace");
        double lo, hi, mean, worst = uniform_response(&s, &r, truth, &lo, &hi, &mean);
        /* Before the power balance (precompute/balance.c) this failed: links refined to
         * mixed levels left fine sender wavelets delivering net power, the dominant
         * eigenvalue of T was rho (1 + 0.003..0.008), and 1 / (1 - rho) amplified it
         * (+4% at 0.9, +55% at 0.99, a diverging series at 0.999). */
        /* With one quad a wall every quad sees the same, so the worst quad is the flux;
         * with 3 x 3 (full size) corner, edge and centre quads differ, and their error is
         * the distribution within each quad (links stopped at mixed levels: docs/stress.md) */
        char id[80];
        snprintf(id, sizeof id, "stress-furnace-flux-%g", rho);
        CHECK_CLAIM(id, mean / truth - 1, CLAIM_FURNACE, "furnace rho %.3f: mean indirect %.7g vs %.7g", rho, mean, truth);
        snprintf(id, sizeof id, "stress-furnace-quad-%g", rho);
        CHECK_CLAIM(id, worst, n > 1 ? CLAIM_FURNACE_SPLIT_WALLS : CLAIM_FURNACE,
                    "furnace rho %.3f, %d x %d quads a wall, quality %d: indirect %.6g .. %.6g, truth %.6g", rho, n, n,
                    quality, lo, hi, truth);
        printf("furnace injected rho %.3f: indirect %.5g .. %.5g vs truth %.5g (worst %.3f%%); bounces %llu, "
               "tail %.3e, energy left %.3e, ratio %.5f\n", rho, lo, hi, truth, 100 * worst,
               (unsigned long long)r.c.bounces, r.c.tail_fraction, r.c.energy_left, r.c.series_ratio);

        /* a point light inside, through the player's projection */
        player p;
        if (player_open(&s, &r, &p)) {
            wrt_light l = point_light(P(0.31, 0.47, 0.62), 1.0);
            lit L;
            player_light(&p, &l, &L, "furnace light");
            double want = L.flux_direct * truth;
            snprintf(id, sizeof id, "stress-furnace-light-%g", rho);
            CHECK_CLAIM(id, L.flux_indirect / want - 1, CLAIM_FURNACE_LIGHT, "indirect flux %.7g, direct x rho/(1-rho) %.7g",
                        L.flux_indirect, want);
            snprintf(id, sizeof id, "stress-furnace-direct-%g", rho);
            CHECK_CLAIM(id, L.flux_direct / (4 * M_PI) - 1, CLAIM_FURNACE, "direct flux %.7g vs 4 pi I", L.flux_direct);
            printf("furnace light rho %.3f: indirect flux %.6g vs direct x rho/(1-rho) %.6g (%.3f%%); direct flux "
                   "%.6g vs 4 pi I %.6g (%.3f%%); texel min/max %.2e\n", rho, L.flux_indirect, want,
                   100 * (L.flux_indirect / want - 1), L.flux_direct, 4 * M_PI, 100 * (L.flux_direct / (4 * M_PI) - 1),
                   L.tex_min_rel);
            lit_free(&L);
            player_close(&p);
        }
        wrt_bake_result_free(&r);
        tsb_free(&s);
    }
}

/* A closed box with a closed box inside it (faces outward): closed, so the furnace's
 * truth rho / (1 - rho) still holds on every quad, but the inner box can come between
 * most pairs of walls, whose links sample visibility per point. The power balance
 * handles those pairs by adding what their links miss and, the scene being closed
 * (no ray escapes), by making each column deliver what it emits. Before: +1.9% at rho
 * 0.9 and +23% at 0.99. */
static void test_furnace_occluded(void) {
    double rhos[4] = {0.5, 0.9, 0.99, 0.999};
    int n = full ? 2 : 1, quality = full ? 5 : 4;
    for (int i = 0; i < 4; i++) {
        double rho = rhos[i], truth = rho / (1 - rho);
        wrt_scene s, inner;
        tsb_init(&s);
        int m = tsb_material(&s, rho, rho, rho);
        tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), n, m);
        tsb_init(&inner);
        tsb_material(&inner, rho, rho, rho);
        tsb_box_inward(&inner, P(0.35, 0.3, 0.35), P(0.65, 0.6, 0.65), 1, 0);
        for (int q = 0; q < inner.nquads; q++) /* reversed: facing out */
            tsb_quad(&s, inner.quads[q].p[0], inner.quads[q].p[3], inner.quads[q].p[2], inner.quads[q].p[1], m);
        tsb_free(&inner);
        wrt_bake_result r;
        wrt_bake_options o = opts(quality, 0, 0);
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
        check_bake(&r, "furnace with an occluder");
        CHECK(r.c.closed == 1, "the balance finds the scene closed");
        double lo, hi, mean, worst = uniform_response(&s, &r, truth, &lo, &hi, &mean);
        char id[80];
        snprintf(id, sizeof id, "stress-occluded-mean-%g", rho);
        CHECK_CLAIM(id, mean / truth - 1, rho >= 0.9 ? CLAIM_OCCLUDED_MEAN : CLAIM_OCCLUDED_MEAN_LOW,
                    "furnace with an occluder, rho %.3f: mean indirect %.7g vs %.7g", rho, mean, truth);
        snprintf(id, sizeof id, "stress-occluded-quad-%g", rho);
        CHECK_CLAIM(id, worst, CLAIM_OCCLUDED_QUAD, "furnace with an occluder, rho %.3f: worst quad", rho);
        printf("furnace with an occluder, rho %.3f: mean indirect %.6g vs truth %.6g (%.3f%%), worst quad %.3f%%; "
               "bounces %llu, ratio %.6f\n", rho, mean, truth, 100 * (mean / truth - 1), 100 * worst,
               (unsigned long long)r.c.bounces, r.c.series_ratio);
        wrt_bake_result_free(&r);
        tsb_free(&s);
    }
}

/* A closed box whose floor is two trapezoids (general quads: a bilinear map, so a
 * uniform irradiance is not the root function alone). The power a unit coefficient
 * carries, int h sqrt(J) du, is integrated here by the midpoint rule on 64 x 64 points,
 * apart from the bake's own quadrature. Before the balance counted it for general quads
 * (it took sqrt(A) on the root and 0 on the wavelets): +0.8% at rho 0.9, +11% at 0.99. */
static double func_power_midpoint(const wrt_quad *q, uint64_t key) {
    enum { N = 64 };
    double acc = 0;
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double u = (i + 0.5) / N, v = (j + 0.5) / N;
            acc += wrt_haar2(wrt_fkey_snode(key), wrt_fkey_stype(key), u, v) * sqrt(wrt_quad_jacobian(q, u, v));
        }
    return acc / (N * N);
}

static void test_furnace_general_quads(void) {
    double rhos[3] = {0.9, 0.99, 0.999};
    for (int i = 0; i < 3; i++) {
        double rho = rhos[i], truth = rho / (1 - rho);
        wrt_scene s, box;
        tsb_init(&s);
        int m = tsb_material(&s, rho, rho, rho);
        tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 0.3, 0), P(0, 0.7, 0), m);
        tsb_quad(&s, P(0, 0.7, 0), P(1, 0.3, 0), P(1, 1, 0), P(0, 1, 0), m);
        tsb_init(&box);
        tsb_material(&box, rho, rho, rho);
        tsb_box_inward(&box, P(0, 0, 0), P(1, 1, 1), 1, 0);
        for (int q = 0; q < box.nquads; q++)
            if (box.quads[q].n.z < 0.5) tsb_quad(&s, box.quads[q].p[0], box.quads[q].p[1], box.quads[q].p[2], box.quads[q].p[3], m);
        tsb_free(&box);
        CHECK(!s.quads[0].parallelogram && !s.quads[1].parallelogram, "the floor's quads are general");
        wrt_bake_result r;
        wrt_bake_options o = opts(4, 0, 0);
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
        check_bake(&r, "general quads");
        double *pw = calloc(r.nfuncs, sizeof *pw), *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
        for (uint32_t f = 0; f < r.nfuncs; f++) {
            if (!wrt_fkey_angular_root(r.fkeys[f])) continue;
            pw[f] = func_power_midpoint(&s.quads[wrt_fkey_quad(r.fkeys[f])], r.fkeys[f]);
            for (int c = 0; c < 3; c++) x[3 * f + c] = pw[f] / sqrt(M_PI); /* uniform irradiance 1 */
        }
        wrt_csc_apply(&r.op, x, y);
        double flux = 0, area = 0, worst = 0;
        for (int q = 0; q < s.nquads; q++) {
            double fq = 0;
            for (uint32_t f = 0; f < r.nfuncs; f++)
                if (wrt_fkey_quad(r.fkeys[f]) == (uint32_t)q) fq += pw[f] * y[3 * f] * sqrt(M_PI);
            worst = fmax(worst, fabs(fq / s.quads[q].area / truth - 1));
            flux += fq;
            area += s.quads[q].area;
        }
        char id[80];
        snprintf(id, sizeof id, "stress-general-mean-%g", rho);
        CHECK_CLAIM(id, flux / area / truth - 1, CLAIM_GENERAL_MEAN, "general quads, rho %.3f: mean %.7g vs %.7g", rho,
                    flux / area, truth);
        snprintf(id, sizeof id, "stress-general-quad-%g", rho);
        CHECK_CLAIM(id, worst, CLAIM_GENERAL_QUAD, "general quads, rho %.3f: worst quad", rho);
        printf("furnace with general quads, rho %.3f: mean indirect %.6g vs truth %.6g (%.3f%%), worst quad %.3f%%\n",
               rho, flux / area, truth, 100 * (flux / area / truth - 1), 100 * worst);
        free(pw); free(x); free(y);
        wrt_bake_result_free(&r);
        tsb_free(&s);
    }
}

/* ------------------------------------------------ shared edges and wedges ---- */


/* Gauss-Legendre nodes and weights on [0, 1], 8 points. */
static const double gl8x[8] = {0.0198550717512319, 0.1016667612931866, 0.2372337950418355, 0.4082826787521751,
                               0.5917173212478249, 0.7627662049581645, 0.8983332387068134, 0.9801449282487681};
static const double gl8w[8] = {0.0506142681451881, 0.1111905172266872, 0.1568533229389436, 0.1813418916891810,
                               0.1813418916891810, 0.1568533229389436, 0.1111905172266872, 0.0506142681451881};

/* Panels on [0, 1] graded geometrically toward both ends (ratio 2, `depth` halvings). */
static int graded_panels(int depth, double *edges) {
    int k = 0;
    edges[k++] = 0;
    for (int i = depth; i >= 1; i--) edges[k++] = 0.5 * ldexp(1.0, -i);
    for (int i = 1; i <= depth; i++) edges[k++] = 1 - 0.5 * ldexp(1.0, -i);
    edges[k++] = 1;
    return k - 1; /* panels */
}

/* F from the floor [0,1]^2 (z = 0, +z) to the plate hinged on its edge x = 0 at angle
 * theta: receiver integral by graded 8-point Gauss-Legendre panels. */
static double wedge_truth(double theta, int depth) {
    wrt_v3 plate[4] = {P(0, 0, 0), P(0, 1, 0), P(cos(theta), 1, sin(theta)), P(cos(theta), 0, sin(theta))};
    double e[64];
    int np = graded_panels(depth, e);
    double sum = 0;
    for (int i = 0; i < np; i++)
        for (int a = 0; a < 8; a++) {
            double xu = e[i] + (e[i + 1] - e[i]) * gl8x[a], wu = (e[i + 1] - e[i]) * gl8w[a];
            for (int j = 0; j < np; j++)
                for (int b = 0; b < 8; b++) {
                    double yv = e[j] + (e[j + 1] - e[j]) * gl8x[b], wv = (e[j + 1] - e[j]) * gl8w[b];
                    sum += wu * wv * ffc_point_polygon(P(xu, yv, 0), P(0, 0, 1), plate, 4);
                }
        }
    return sum;
}

static void wedge_scene(wrt_scene *s, double theta) {
    tsb_init(s);
    int m = tsb_material(s, 0.5, 0.5, 0.5);
    tsb_quad(s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), m);   /* floor, +z */
    double c = cos(theta), sn = sin(theta);
    /* the plate, normal (sin, 0, -cos): toward the floor */
    tsb_quad(s, P(0, 0, 0), P(0, 1, 0), P(c, 1, sn), P(c, 0, sn), m);
}

static void edge_case(double theta, double truth, const char *name, const double tol[3]) {
    wrt_scene s;
    wedge_scene(&s, theta);
    int q = 5;
    uint64_t leaves[3] = {0, 0, 0};
    int maxl[3] = {3, 4, 5};
    double fl[3] = {0, 0, 0};
    int nrun = full ? 3 : 2;
    for (int k = 0; k < nrun; k++) {
        wrt_bake_result r;
        wrt_bake_options o = opts(q, 0, maxl[k]);
        CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
        check_bake(&r, name);
        fl[k] = entry(&r, &r.dto, root_key(0), root_key(1)) / 0.5; /* T = rho F */
        leaves[k] = r.c.links_leaf;
        /* Before the power balance: 0.986, 0.968, 0.947, 0.935 at max levels 3..6 (truth
         * 0.983), the transfer lost as refinement deepened (links of mixed levels) */
        char id[80];
        snprintf(id, sizeof id, "stress-%s-level-%d", name, maxl[k]);
        for (char *c = id; *c; c++) if (*c == ' ') *c = '-';
        CHECK_CLAIM(id, fl[k] / truth - 1, tol[k], "%s: F = %.7f, truth %.7f (max level %d)", name, fl[k], truth, maxl[k]);
        printf("%s: F = %.6f vs truth %.6f (%.3f%%), quality %d, max level %d: %llu leaves, %llu refined\n", name,
               fl[k], truth, 100 * (fl[k] / truth - 1), q, maxl[k], (unsigned long long)r.c.links_leaf,
               (unsigned long long)r.c.links_refined);
        wrt_bake_result_free(&r);
    }
    /* bounded refinement: one more level allowed may not multiply the leaves by more than
     * 8 (splitting every link on both sides, as refining without end would, gives 16) */
    for (int k = 1; k < nrun; k++)
        CHECK(leaves[k] < 8 * leaves[k - 1], "%s: leaves %llu at max level %d vs %llu at %d", name,
              (unsigned long long)leaves[k], maxl[k], (unsigned long long)leaves[k - 1], maxl[k - 1]);
    tsb_free(&s);
}

static void test_right_angle(void) {
    double truth = ffc_perpendicular(0, 1, 0, 1, 0, 1, 0, 1);
    const double tol[3] = {CLAIM_FF, CLAIM_FF, CLAIM_FF};
    edge_case(M_PI / 2, truth, "right angle", tol);
}

static void test_wedge_one_degree(void) {
    double th = M_PI / 180;
    double t1 = wedge_truth(th, 20), t2 = wedge_truth(th, 26);
    CHECK(fabs(t1 - t2) < 1e-6 * t2, "the quadrature itself converges: %.9f vs %.9f", t1, t2);
    /* and it reproduces the right-angle closed form */
    double tr = wedge_truth(M_PI / 2, 20), cr = ffc_perpendicular(0, 1, 0, 1, 0, 1, 0, 1);
    CHECK(fabs(tr - cr) < 1e-6, "quadrature at 90 degrees %.8f vs closed form %.8f", tr, cr);
    printf("wedge truth: 1 degree F = %.8f (depth 20) / %.8f (depth 26); 90 degrees %.8f vs closed form %.8f\n",
           t1, t2, tr, cr);
    const double tol[3] = {CLAIM_WEDGE_L3, CLAIM_WEDGE_L4, CLAIM_WEDGE_L5};
    edge_case(th, t2, "wedge 1 degree", tol);
}

/* ------------------------------------------------------------------ scale ---- */

/* A Cornell-like box: coloured side walls and an occluding block, transformed by p s + off. */
static void cornell(wrt_scene *s, double sc, wrt_v3 off) {
    tsb_init(s);
    int white = tsb_material(s, 0.75, 0.75, 0.75), red = tsb_material(s, 0.7, 0.1, 0.1),
        green = tsb_material(s, 0.1, 0.7, 0.1);
    int n = full ? 2 : 1;
    tsb_box_inward(s, P(0, 0, 0), P(1, 1, 1), n, white);
    /* x = 0 wall red, x = 1 wall green (faces 0 .. n^2 - 1 and n^2 .. 2 n^2 - 1) */
    for (int q = 0; q < n * n; q++) { s->quads[q].material = red; s->quads[n * n + q].material = green; }
    /* the block [0.55, 0.85] x [0.2, 0.5] x [0, 0.6], faces outward, no bottom */
    double x0 = 0.55, x1 = 0.85, y0 = 0.2, y1 = 0.5, h = 0.6;
    tsb_quad(s, P(x0, y0, h), P(x1, y0, h), P(x1, y1, h), P(x0, y1, h), white);          /* top +z */
    tsb_quad(s, P(x0, y0, 0), P(x0, y0, h), P(x0, y1, h), P(x0, y1, 0), white);          /* -x */
    tsb_quad(s, P(x1, y0, 0), P(x1, y1, 0), P(x1, y1, h), P(x1, y0, h), white);          /* +x */
    tsb_quad(s, P(x0, y0, 0), P(x1, y0, 0), P(x1, y0, h), P(x0, y0, h), white);          /* -y */
    tsb_quad(s, P(x0, y1, 0), P(x0, y1, h), P(x1, y1, h), P(x1, y1, 0), white);          /* +y */
    for (int q = 0; q < s->nquads; q++) {
        wrt_quad *qq = &s->quads[q];
        for (int k = 0; k < 4; k++) qq->p[k] = v3_add(v3_scale(qq->p[k], sc), off);
        qq->area *= sc * sc;
    }
    s->bbox_min = v3_add(v3_scale(s->bbox_min, sc), off);
    s->bbox_max = v3_add(v3_scale(s->bbox_max, sc), off);
}

typedef struct scale_result { wrt_bake_result r; double *direct, *indirect; int nq; } scale_result;

static void scale_run(double sc, wrt_v3 off, scale_result *out) {
    wrt_scene s;
    cornell(&s, sc, off);
    wrt_bake_options o = opts(full ? 5 : 3, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &out->r) == WRT_OK, "%s", wrt_last_error());
    check_bake(&out->r, "scale");
    out->nq = s.nquads;
    out->direct = calloc((size_t)s.nquads, sizeof(double));
    out->indirect = calloc((size_t)s.nquads, sizeof(double));
    player p;
    if (player_open(&s, &out->r, &p)) {
        wrt_light l = point_light(v3_add(v3_scale(P(0.4, 0.6, 0.9), sc), off), 1.0);
        lit L;
        player_light(&p, &l, &L, "scale");
        for (int q = 0; q < s.nquads; q++) {
            out->direct[q] = L.direct[q] * sc * sc; /* irradiance goes as 1 / s^2 */
            out->indirect[q] = L.indirect[q] * sc * sc;
        }
        lit_free(&L);
        player_close(&p);
    }
    tsb_free(&s);
}

static void scale_free(scale_result *s) { wrt_bake_result_free(&s->r); free(s->direct); free(s->indirect); }

static void test_scale(void) {
    scale_result ref;
    scale_run(1, P(0, 0, 0), &ref);
    struct { double s; wrt_v3 off; const char *name; } cases[4] = {
        {1e-3, {0, 0, 0}, "scale 1e-3"}, {1e3, {0, 0, 0}, "scale 1e3"}, {1, {1e5, 1e5, 1e5}, "offset 1e5"},
        {1e-3, {1e5, -1e5, 3e4}, "scale 1e-3 at 1e5"}};
    double dmax = 0, imax = 0;
    for (int q = 0; q < ref.nq; q++) { dmax = fmax(dmax, ref.direct[q]); imax = fmax(imax, ref.indirect[q]); }
    for (int c = 0; c < 4; c++) {
        scale_result t;
        scale_run(cases[c].s, cases[c].off, &t);
        /* the operator's root-to-root entries are scale-free */
        double emax = 0, ediff = 0;
        for (int r = 0; r < ref.nq; r++)
            for (int s = 0; s < ref.nq; s++) {
                double a = entry(&ref.r, &ref.r.op, root_key(r), root_key(s));
                double b = entry(&t.r, &t.r.op, root_key(r), root_key(s));
                emax = fmax(emax, fabs(a));
                ediff = fmax(ediff, fabs(a - b));
            }
        double dd = 0, di = 0;
        for (int q = 0; q < ref.nq; q++) {
            dd = fmax(dd, fabs(t.direct[q] - ref.direct[q]) / fmax(ref.direct[q], 0.05 * dmax));
            di = fmax(di, fabs(t.indirect[q] - ref.indirect[q]) / fmax(ref.indirect[q], 0.05 * imax));
        }
        CHECK(ediff < 0.01 * emax, "%s: root entries differ by %.3g of the largest %.3g", cases[c].name, ediff, emax);
        CHECK(dd < 0.01 && di < 0.01, "%s: per-quad irradiance x s^2 differs by %.3f%% direct, %.3f%% indirect",
              cases[c].name, 100 * dd, 100 * di);
        printf("%s: operator root entries within %.2e of the unscaled (largest %.3f); per-quad irradiance x s^2 "
               "within %.4f%% direct, %.4f%% indirect of the unscaled; rays %llu vs %llu\n", cases[c].name,
               ediff, emax, 100 * dd, 100 * di, (unsigned long long)t.r.c.rays_traced,
               (unsigned long long)ref.r.c.rays_traced);
        scale_free(&t);
    }
    scale_free(&ref);
}

/* ------------------------------------------------- a tiny quad, huge walls ---- */

static void test_tiny_quad(void) {
    double W = 1e3, a = 1e-3, h = 0.5 * W;
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.5, 0.5, 0.5);
    tsb_box_inward(&s, P(0, 0, 0), P(W, W, W), 1, m);
    double c = 0.5 * W;
    int tq = tsb_quad(&s, P(c, c, h), P(c + a, c, h), P(c + a, c + a, h), P(c, c + a, h), m); /* faces +z */
    int ceiling = 5;                                                                         /* z = W, -z */
    wrt_bake_result r;
    wrt_bake_options o = opts(full ? 6 : 4, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    check_bake(&r, "tiny quad");
    /* uniform irradiance 1 on the ceiling: the tiny quad receives rho F(tiny -> ceiling) */
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    int64_t fc = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(ceiling)), ft = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(tq));
    CHECK(fc >= 0 && ft >= 0, "root functions exist");
    double got = 0, truth = 0, back = 0;
    if (fc >= 0 && ft >= 0) {
        for (int k = 0; k < 3; k++) x[3 * fc + k] = sqrt(s.quads[ceiling].area / M_PI);
        wrt_csc_apply(&r.dto, x, y);
        got = y[3 * ft] * sqrt(M_PI / s.quads[tq].area);
        wrt_v3 ce[4] = {s.quads[ceiling].p[0], s.quads[ceiling].p[1], s.quads[ceiling].p[2], s.quads[ceiling].p[3]};
        truth = 0.5 * ffc_point_polygon(P(c + 0.5 * a, c + 0.5 * a, h), P(0, 0, 1), ce, 4);
        /* and back: the tiny quad lit with irradiance 1 sends rho A_t F(t -> c) / A_c to the ceiling */
        memset(x, 0, 3 * r.nfuncs * sizeof *x);
        memset(y, 0, 3 * r.nfuncs * sizeof *y);
        for (int k = 0; k < 3; k++) x[3 * ft + k] = sqrt(s.quads[tq].area / M_PI);
        wrt_csc_apply(&r.dto, x, y);
        back = y[3 * fc] * sqrt(M_PI / s.quads[ceiling].area);
    }
    double back_truth = truth * s.quads[tq].area / s.quads[ceiling].area;
    /* Both entries are under the emission floor (a root entry is rho F sqrt(A_r / A_s),
     * 1e-12 of the ceiling's share here). Before the power balance the quad therefore sent
     * nothing; the balance keeps a root column's shares whatever their size, since they
     * are all the light the quad sends. */
    CHECK(fabs(got / truth - 1) < 0.02, "tiny quad from the ceiling: %.5g vs closed form %.5g", got, truth);
    CHECK(fabs(back / back_truth - 1) < 0.02, "ceiling from the tiny quad: %.5g vs closed form %.5g", back, back_truth);
    printf("tiny quad: irradiance from the ceiling %.6g vs closed form %.6g (%.3f%%); ceiling from the tiny quad "
           "%.4g vs %.4g; T entry %.3g, entries %llu\n", got, truth, 100 * (got / truth - 1), back, back_truth,
           entry(&r, &r.dto, root_key(tq), root_key(ceiling)), (unsigned long long)r.dto.nnz);
    /* a light just above the tiny quad: finite, and its indirect light reaches the walls */
    player p;
    if (player_open(&s, &r, &p)) {
        wrt_light l = point_light(P(c + 0.5 * a, c + 0.5 * a, h + 0.01), 1.0);
        lit L;
        player_light(&p, &l, &L, "tiny quad");
        double ft_dir = L.direct[tq];
        /* mean irradiance over the square = I x its solid angle from the light / its area */
        double hh = 0.01, al = 0.5 * a, omega = 4 * asin(al * al / (al * al + hh * hh));
        double tr = omega / (a * a);
        CHECK(fabs(ft_dir / tr - 1) < 0.02, "tiny quad direct %.6g vs I/d^2 %.6g", ft_dir, tr);
        printf("tiny quad: direct %.6g vs I/d^2 %.6g; flux direct %.6g, indirect %.6g\n", ft_dir, tr, L.flux_direct,
               L.flux_indirect);
        lit_free(&L);
        player_close(&p);
    }
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* ------------------------------------------------------------------ glossy ---- */

/* The truth for a closed unit box of one glossy material, by a random walk of light
 * written here (no bake, no player): photons start either as uniform isotropic incident
 * radiance on the walls (the injected furnace: a uniform wall point, a cosine-distributed
 * arriving direction) or from a point light at lpos (isotropic), reflect by the BRDF's
 * importance sampler (weight f cos / pdf, reciprocal BRDF) and travel straight to the next
 * wall; every arrival after the first reflection is indirect. Returns the indirect flux
 * over the flux arriving directly, with its standard error in *se. */
static uint64_t walk_state;
static double walk_rnd(void) {
    uint64_t z = (walk_state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return (double)((z ^ (z >> 31)) >> 11) * 0x1.0p-53;
}

/* From p along unit d to the box's inside: the hit point and the wall's inward normal. */
static wrt_v3 box_hit(wrt_v3 p, wrt_v3 d, wrt_v3 *n) {
    double pc[3] = {p.x, p.y, p.z}, dc[3] = {d.x, d.y, d.z}, tmin = INFINITY;
    int axis = 0;
    for (int a = 0; a < 3; a++) {
        double t = dc[a] > 0 ? (1 - pc[a]) / dc[a] : dc[a] < 0 ? -pc[a] / dc[a] : INFINITY;
        if (t < tmin) { tmin = t; axis = a; }
    }
    double nc[3] = {0, 0, 0};
    nc[axis] = dc[axis] > 0 ? -1 : 1;
    *n = P(nc[0], nc[1], nc[2]);
    wrt_v3 h = v3_add(p, v3_scale(d, tmin));
    double hc[3] = {h.x, h.y, h.z};
    hc[axis] = dc[axis] > 0 ? 1 : 0; /* exactly on the wall */
    for (int a = 0; a < 3; a++) hc[a] = fmin(1, fmax(0, hc[a]));
    return P(hc[0], hc[1], hc[2]);
}

static double glossy_walk(const wrt_material *m, int from_light, wrt_v3 lpos, int N, double *se) {
    walk_state = 0x1234567ULL + (uint64_t)from_light;
    double s = 0, s2 = 0;
    for (int i = 0; i < N; i++) {
        wrt_v3 p, n, d;
        if (from_light) {
            double z = 2 * walk_rnd() - 1, ph = 2 * M_PI * walk_rnd(), r = sqrt(fmax(0, 1 - z * z));
            d = P(r * cos(ph), r * sin(ph), z);
            p = box_hit(lpos, d, &n);
        } else {
            int w = (int)(walk_rnd() * 6) % 6, axis = w / 2;
            double c[3] = {walk_rnd(), walk_rnd(), walk_rnd()};
            c[axis] = w & 1;
            p = P(c[0], c[1], c[2]);
            double nc[3] = {0, 0, 0};
            nc[axis] = (w & 1) ? -1 : 1;
            n = P(nc[0], nc[1], nc[2]);
            /* arriving direction: minus a cosine-distributed direction about n */
            double r = sqrt(walk_rnd()), ph = 2 * M_PI * walk_rnd(), lz = sqrt(fmax(0, 1 - r * r));
            wrt_v3 t = fabs(n.x) < 0.9 ? v3_norm(v3_cross(n, P(1, 0, 0))) : v3_norm(v3_cross(n, P(0, 1, 0)));
            wrt_v3 b = v3_cross(n, t);
            d = v3_scale(v3_add(v3_add(v3_scale(t, r * cos(ph)), v3_scale(b, r * sin(ph))), v3_scale(n, lz)), -1);
        }
        double weight = 1, sum = 0;
        for (int k = 0; k < 20000 && weight > 1e-8; k++) { /* what is left: < 1e-8 x the ratio */
            double w3[3];
            wrt_v3 out = wrt_brdf_sample(m, n, v3_scale(d, -1), walk_rnd(), walk_rnd(), walk_rnd(), w3);
            if (!(w3[0] > 0) || !(v3_dot(out, n) > 0)) break;
            weight *= w3[0];
            d = v3_norm(out);
            p = box_hit(p, d, &n);
            sum += weight;
        }
        s += sum; s2 += sum * sum;
    }
    double mean = s / N;
    *se = sqrt(fmax(0, s2 / N - mean * mean) / N) / mean;
    return mean;
}

/* A closed box with glossy walls, against glossy_walk: uniform isotropic irradiance
 * injected on every wall (the operator's own flux ratio) and a point light inside
 * (through the player). */
static void glossy_case(double roughness, double metallic, const char *name) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.8, 0.8, 0.8);
    s.materials[m].lambertian = 0;
    s.materials[m].roughness = (float)roughness;
    s.materials[m].metallic = (float)metallic;
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), 1, m);
    wrt_v3 lpos = P(0.31, 0.47, 0.62);
    int nw = full ? 100000 : 10000;
    double t0 = wrt_now(), se_inj, se_light;
    double truth_inj = glossy_walk(&s.materials[m], 0, lpos, nw, &se_inj);
    double truth_light = glossy_walk(&s.materials[m], 1, lpos, nw, &se_light);
    double tw = wrt_now() - t0;
    wrt_bake_result r;
    wrt_bake_options o = opts(full ? 4 : 3, 0, full ? 3 : 2);
    t0 = wrt_now();
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    check_bake(&r, name);
    double tb = wrt_now() - t0;
    double *x = calloc(3 * r.nfuncs, sizeof *x), *y = calloc(3 * r.nfuncs, sizeof *y);
    double flux_in = 0, flux = 0;
    for (int q = 0; q < s.nquads; q++) {
        int64_t f = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(q));
        for (int c = 0; c < 3; c++) x[3 * f + c] = sqrt(s.quads[q].area / M_PI);
        flux_in += s.quads[q].area;
    }
    wrt_csc_apply(&r.op, x, y);
    int negq = 0;
    for (int q = 0; q < s.nquads; q++) {
        int64_t f = wrt_fkey_find(r.fkeys, r.nfuncs, root_key(q));
        double e = y[3 * f] * sqrt(M_PI / s.quads[q].area);
        negq += e < 0;
        flux += e * s.quads[q].area;
    }
    double ratio = flux / flux_in;
    char id[96];
    snprintf(id, sizeof id, "stress-glossy-%s-injected", name);
    for (char *c = id; *c; c++) if (*c == ' ' || *c == ',' || *c == '(' || *c == ')') *c = '-';
    /* the dielectric's directional albedo passes 1 toward grazing (1.59), where a level-2
     * angular basis is coarsest: under isotropic light its flux is a known limit */
    double tol_inj = metallic == 0 ? CLAIM_GLOSSY_DIELECTRIC_ISOTROPIC : CLAIM_GLOSSY_FLUX;
    CHECK_CLAIM(id, ratio / truth_inj - 1, tol_inj + 3 * se_inj, "%s furnace (injected): indirect / direct "
                "flux %.5f, random walk %.5f (standard error %.3f%%); angular entries %llu, bounces %llu, bake %.2f s, "
                "walk %.2f s", name, ratio, truth_inj, 100 * se_inj, (unsigned long long)r.c.entries_angular,
                (unsigned long long)r.c.bounces, tb, tw);
    CHECK(negq == 0, "%s: %d quads with negative indirect irradiance", name, negq);
    player p;
    if (player_open(&s, &r, &p)) {
        wrt_light l = point_light(lpos, 1.0);
        lit L;
        player_light(&p, &l, &L, name);
        double lr = L.flux_indirect / L.flux_direct;
        snprintf(id, sizeof id, "stress-glossy-%s-light", name);
        for (char *c = id; *c; c++) if (*c == ' ' || *c == ',' || *c == '(' || *c == ')') *c = '-';
        CHECK_CLAIM(id, lr / truth_light - 1, CLAIM_GLOSSY_FLUX + 3 * se_light, "%s furnace (a point light): indirect / "
                    "direct flux %.5f, random walk %.5f (standard error %.3f%%), texel min/max %.3e", name, lr,
                    truth_light, 100 * se_light, L.tex_min_rel);
        lit_free(&L);
        player_close(&p);
    }
    free(x); free(y);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

static void test_glossy(void) {
    glossy_case(0.05, 1, "glossy metal roughness 0.05");
    glossy_case(0, 1, "mirror (metal, roughness 0)");
    glossy_case(0.05, 0, "glossy dielectric roughness 0.05");
}

/* ------------------------------------------------------------------ lights ---- */

static void test_light_positions(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.5, 0.5, 0.5);
    int n = full ? 2 : 2;
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), n, m);
    wrt_bake_result r;
    wrt_bake_options o = opts(full ? 6 : 4, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    check_bake(&r, "lights");
    player p;
    if (!player_open(&s, &r, &p)) { wrt_bake_result_free(&r); tsb_free(&s); return; }
    struct { wrt_v3 pos; double flux; const char *name; } cases[5] = {
        {{0.5, 0.5, 0.5}, 4 * M_PI, "inside, centre"},
        {{0.37, 0.61, 0.0}, 2 * M_PI, "on the floor"},
        {{0, 0, 0}, 0.5 * M_PI, "at a vertex"},
        {{2, 0.5, 0.5}, 0, "outside, behind the x = 1 wall"},
        {{1.5, 1.5, 1.5}, 0, "outside, beyond a corner"}};
    for (int c = 0; c < 5; c++) {
        wrt_light l = point_light(cases[c].pos, 1.0);
        lit L;
        player_light(&p, &l, &L, cases[c].name);
        /* quads whose plane holds the light, or that face away, get exactly zero */
        int nz = 0, zero_ok = 1;
        for (int q = 0; q < s.nquads; q++) {
            double sd = v3_dot(v3_sub(cases[c].pos, s.quads[q].p[0]), s.quads[q].n);
            if (sd <= 0 || cases[c].flux == 0) { nz++; zero_ok &= L.direct[q] == 0; }
        }
        CHECK(zero_ok, "%s: direct light on a quad that cannot see the light", cases[c].name);
        if (cases[c].flux > 0) {
            char id[80];
            snprintf(id, sizeof id, "stress-light-direct-%d", c);
            CHECK_CLAIM(id, L.flux_direct / cases[c].flux - 1, CLAIM_FURNACE, "%s: direct flux %.7g vs %.7g",
                        cases[c].name, L.flux_direct, cases[c].flux);
            double want = L.flux_direct * 0.5 / (1 - 0.5);
            snprintf(id, sizeof id, "stress-light-indirect-%d", c);
            CHECK_CLAIM(id, L.flux_indirect / want - 1, CLAIM_FURNACE_LIGHT, "%s: indirect flux %.7g vs %.7g",
                        cases[c].name, L.flux_indirect, want);
        } else {
            int allzero = 1;
            const float *E = wrt_relight_E(p.rl), *X = wrt_relight_X(p.rl);
            for (size_t k = 0; k < 3 * (size_t)p.g.nfuncs; k++) allzero &= E[k] == 0 && X[k] == 0;
            for (int q = 0; q < s.nquads; q++) {
                int res = wrt_relight_tex_res(p.rl, q);
                const float *t = wrt_relight_tex(p.rl, q);
                for (int k = 0; t && k < 3 * res * res; k++) allzero &= t[k] == 0;
            }
            CHECK(allzero, "%s: light reaches inside the closed box (flux %.3g direct, %.3g indirect)", cases[c].name,
                  L.flux_direct, L.flux_indirect);
        }
        printf("light %s: direct flux %.6g vs %.6g; indirect %.6g vs direct x rho/(1-rho) %.6g; %d quads must be "
               "dark: %s; texel min/max %.2e\n", cases[c].name, L.flux_direct, cases[c].flux, L.flux_indirect,
               L.flux_direct, nz, zero_ok ? "they are" : "NOT", L.tex_min_rel);
        lit_free(&L);
    }
    player_close(&p);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* ------------------------------------------------ no transfer, no rays ---- */

static void test_no_transfer(void) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.8, 0.8, 0.8);
    tsb_quad(&s, P(0, 0, 0), P(1, 0, 0), P(1, 1, 0), P(0, 1, 0), m);      /* floor +z */
    tsb_quad(&s, P(1, 0, 0), P(2, 0, 0), P(2, 1, 0), P(1, 1, 0), m);      /* coplanar neighbour +z */
    tsb_quad(&s, P(0, 0, -1), P(0, 1, -1), P(1, 1, -1), P(1, 0, -1), m);  /* below, facing down: back to back */
    tsb_quad(&s, P(3, 0, 1), P(4, 0, 1), P(4, 1, 1), P(3, 1, 1), m);      /* above, +z: faces away from all */
    tsb_quad(&s, P(0.2, 0.2, 0), P(0.2, 0.8, 0), P(0.8, 0.8, 0), P(0.8, 0.2, 0), m); /* on the floor, -z */
    wrt_bake_result r;
    wrt_bake_options o = opts(full ? 6 : 4, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    check_bake(&r, "no transfer");
    CHECK(r.c.pairs_exchange == 0, "no pair can exchange light (%llu)", (unsigned long long)r.c.pairs_exchange);
    CHECK(r.c.pairs_skipped_facing == r.c.pairs_total && r.c.pairs_total == 20, "20 ordered pairs skipped (%llu of %llu)",
          (unsigned long long)r.c.pairs_skipped_facing, (unsigned long long)r.c.pairs_total);
    CHECK(r.c.rays_traced == 0 && r.c.samples == 0, "no rays (%llu), no samples (%llu)",
          (unsigned long long)r.c.rays_traced, (unsigned long long)r.c.samples);
    CHECK(r.dto.nnz == 0 && r.op.nnz == 0, "no entries (%llu, %llu)", (unsigned long long)r.dto.nnz,
          (unsigned long long)r.op.nnz);
    printf("no transfer: pairs %llu, skipped %llu, rays %llu, samples %llu, entries %llu (truth: 20, 20, 0, 0, 0)\n",
           (unsigned long long)r.c.pairs_total, (unsigned long long)r.c.pairs_skipped_facing,
           (unsigned long long)r.c.rays_traced, (unsigned long long)r.c.samples, (unsigned long long)r.dto.nnz);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

/* ---------------------------------------------------------- thin wall ---- */

static void thin_wall_case(double t) {
    wrt_scene s;
    tsb_init(&s);
    int m = tsb_material(&s, 0.8, 0.8, 0.8);
    int n = full ? 3 : 2;
    tsb_box_inward(&s, P(0, 0, 0), P(1, 1, 1), n, m);           /* lit room: quads 0 .. 6 n^2 - 1 */
    int first_dark = s.nquads;
    tsb_box_inward(&s, P(1 + t, 0, 0), P(2 + t, 1, 1), n, m);   /* dark room */
    wrt_bake_result r;
    wrt_bake_options o = opts(full ? 5 : 3, 0, 0);
    CHECK(wrt_bake_run(&s, &o, &r) == WRT_OK, "%s", wrt_last_error());
    check_bake(&r, "thin wall");
    /* the operator must not couple the rooms at all */
    double cross = 0, total = 0;
    for (uint32_t j = 0; j < r.op.n; j++)
        for (uint64_t k = r.op.col[j]; k < r.op.col[j + 1]; k++) {
            int a = (int)wrt_fkey_quad(r.fkeys[r.op.row[k]]) >= first_dark, b = (int)wrt_fkey_quad(r.fkeys[j]) >= first_dark;
            double v = fabs(r.op.val[3 * k]);
            total += v;
            if (a != b) cross += v;
        }
    wrt_light l = point_light(P(0.6, 0.4, 0.7), 1.0);
    player p;
    double dark_max = 0, lit_mean = 0;
    if (player_open(&s, &r, &p)) {
        lit L;
        player_light(&p, &l, &L, "thin wall");
        for (int q = 0; q < s.nquads; q++) {
            if (q >= first_dark) dark_max = fmax(dark_max, fmax(L.direct[q], L.indirect[q]));
            else lit_mean += L.indirect[q] / first_dark;
        }
        for (int q = first_dark; q < s.nquads; q++) {
            int res = wrt_relight_tex_res(p.rl, q);
            const float *tx = wrt_relight_tex(p.rl, q);
            for (int k = 0; tx && k < 3 * res * res; k++) dark_max = fmax(dark_max, fabs(tx[k]) * M_PI / 0.8);
        }
        lit_free(&L);
        player_close(&p);
    }
    /* the reference on the dark side of the shared wall (the quads at x = 1 + t, facing +x) */
    wrt_ref *ref = wrt_ref_create(&s);
    double ref_max = 0, ref_err = 0;
    int cells = 4, spc = full ? 256 : 32;
    for (int q = first_dark; q < first_dark + n * n; q++) {
        double d[48], ind[48], err[48];
        wrt_status st = wrt_ref_cell_irradiance(ref, &l, 1, q, cells, spc, 0, 2, 11, d, ind, err);
        CHECK(st == WRT_OK, "reference: %s", wrt_last_error());
        for (int k = 0; k < 3 * cells * cells; k++) {
            ref_max = fmax(ref_max, fmax(d[k], ind[k]));
            ref_err = fmax(ref_err, err[k]);
        }
    }
    wrt_ref_destroy(ref);
    double tol = fmax(3 * ref_err, 1e-6 * lit_mean);
    CHECK(cross == 0, "wall %.0e: operator couples the rooms: %.3g of %.3g", t, cross, total);
    CHECK(dark_max <= ref_max + tol, "wall %.0e: dark room irradiance %.3g, reference %.3g +- %.3g (lit mean %.3g)", t,
          dark_max, ref_max, ref_err, lit_mean);
    printf("thin wall %.0e: dark room max irradiance %.3g vs reference %.3g (stderr %.3g); lit room mean indirect "
           "%.4g; operator weight across the wall %.3g of %.3g; rays %llu\n", t, dark_max, ref_max, ref_err, lit_mean,
           cross, total, (unsigned long long)r.c.rays_traced);
    wrt_bake_result_free(&r);
    tsb_free(&s);
}

static void test_thin_wall(void) {
    thin_wall_case(1e-3);
    thin_wall_case(1e-6);
    thin_wall_case(0);
}

/* --------------------------------------------------------- bad input files ---- */

static void bad_file(const char *file, const char *word) {
    const char *build = getenv("WRT_BUILD") ? getenv("WRT_BUILD") : "build";
    char cmd[1024], out[400], err[400];
    snprintf(out, sizeof out, "%s/bad.gto", tmpdir);
    snprintf(err, sizeof err, "%s/bad.err", tmpdir);
    unlink(out);
    snprintf(cmd, sizeof cmd, "%s/wrt-bake tests/data/%s -o %s >/dev/null 2>%s", build, file, out, err);
    int st = system(cmd);
    int code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    char msg[2048] = "";
    FILE *f = fopen(err, "r");
    if (f) { size_t k = fread(msg, 1, sizeof msg - 1, f); msg[k] = 0; fclose(f); }
    struct stat sb;
    int made = stat(out, &sb) == 0;
    CHECK(code == 2, "%s: exit code %d, expected 2 (%s)", file, code, msg);
    CHECK(strstr(msg, word) != NULL, "%s: message lacks '%s': %s", file, word, msg);
    CHECK(!made, "%s: an output file was written", file);
    char *nl = strchr(msg, '\n');
    if (nl) *nl = 0;
    printf("bad input %s: exit %d (want 2), output written: %s; %.160s\n", file, code, made ? "yes" : "no", msg);
}

static void test_bad_input(void) {
    /* bad_nonplanar.gltf bakes since issue 21 (two triangle elements); a zero-area or
     * collinear mesh loses all its triangles (dropped with a warning), leaving nothing */
    bad_file("bad_index.gltf", "index 7");
    bad_file("bad_zeroarea.gltf", "zero area");
    bad_file("bad_collinear.gltf", "collinear");
    bad_file("bad_nan.gltf", "NaN");
}

int main(int argc, char **argv) {
    setvbuf(stdout, NULL, _IOLBF, 0); /* figures survive a timeout */
    const char *fe = getenv("WRT_STRESS_FULL");
    full = fe && *fe && strcmp(fe, "0") != 0;
    snprintf(tmpdir, sizeof tmpdir, "/tmp/wrt_stress_XXXXXX");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    printf("stress suite: %s sizes\n", full ? "full" : "fast");
    TEST_RUN(test_furnace);
    TEST_RUN(test_furnace_occluded);
    TEST_RUN(test_furnace_general_quads);
    TEST_RUN(test_right_angle);
    TEST_RUN(test_wedge_one_degree);
    TEST_RUN(test_scale);
    TEST_RUN(test_tiny_quad);
    TEST_RUN(test_glossy);
    TEST_RUN(test_light_positions);
    TEST_RUN(test_no_transfer);
    TEST_RUN(test_thin_wall);
    TEST_RUN(test_bad_input);
    rmdir(tmpdir);
    TEST_END();
}
