/* scan.c: `wrt-bake --scan`: the scene as the bake would see it and what baking it would
 * cost, before anything starts (issue 21). The summary and the element counts come from
 * the loader (formats/scene.c, loaded with report_only so that nothing is refused); this
 * file adds what --drop-bad would change and the estimate.
 *
 * The estimate is a model, not a dry run: time, peak memory and bytes as powers of the
 * number of elements N, of how open the scene is (the share of point pairs that see
 * each other, sampled here with one ray each) and of the share of element pairs that
 * face each other (the plain bake's pair list), one factor per quality step, fitted to
 * measured bakes (docs/scan_fit.csv, tools/scan_fit.py) and set above every one of them.
 * docs/triangles.md ("--scan's estimate, refitted") gives each bake beside its estimate.
 * Depends on the bake's options and the scene only. */
#define _POSIX_C_SOURCE 200809L
#include "scan.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../common/brdf.h"
#include "../common/rt_scene.h"

/* How open the scene is: of SCAN_VIS_SAMPLES pairs of points drawn uniformly over the
 * elements' area (a fixed sequence: the same scene gives the same figure), the share that
 * face each other (each in front of the other's plane) and see each other (one ray
 * through the scene). A maze's walls hide most pairs (0.05 for the 6 x 6 asset, 0.017 at
 * 12 x 12 cells), the atrium's courtyard fewer (0.36), one furnished room fewest (0.52).
 * The bake's cost per element follows it: the refinement between two large surfaces
 * that see each other is what costs. Drawn by area, not by element: a mesh's many small
 * facets would otherwise weigh more than the walls they face. */
#define SCAN_VIS_SAMPLES 65536

static uint64_t scan_rng(uint64_t *x) { /* splitmix64 */
    uint64_t z = (*x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double scan_u01(uint64_t *x) { return (double)(scan_rng(x) >> 11) * 0x1.0p-53; }

static int quad_finite(const wrt_quad *q) {
    for (int k = 0; k < 4; k++)
        if (!isfinite(q->p[k].x) || !isfinite(q->p[k].y) || !isfinite(q->p[k].z)) return 0;
    return isfinite(q->n.x) && isfinite(q->n.y) && isfinite(q->n.z);
}

static int pick_area(const double *cum, int n, double x) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (cum[mid] > x) hi = mid; else lo = mid + 1;
    }
    return lo;
}

double wrt_scan_visible_fraction(const wrt_scene *s) {
    if (!s || s->nquads < 2) return 0;
    int *idx = wrt_xmalloc((size_t)s->nquads * sizeof *idx);
    int n = 0;
    for (int i = 0; i < s->nquads; i++)
        if (quad_finite(&s->quads[i]) && s->quads[i].area > 0) idx[n++] = i;
    if (n < 2) { free(idx); return 0; }
    wrt_v3 *corners = wrt_xmalloc((size_t)n * 4 * sizeof *corners);
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 4; k++) corners[4 * i + k] = s->quads[idx[i]].p[k];
    wrt_rt_scene rs;
    wrt_status st = wrt_rt_scene_build(corners, n, v3(0, 0, 0), "threads=1", WRT_RT_ROBUST, &rs);
    free(corners);
    if (st != WRT_OK) { free(idx); return -1; }
    double *cum = wrt_xmalloc((size_t)n * sizeof *cum);
    for (int i = 0; i < n; i++) cum[i] = (i ? cum[i - 1] : 0) + s->quads[idx[i]].area;
    uint64_t seed = 0x5CA9ull;
    long seen = 0;
    for (int k = 0; k < SCAN_VIS_SAMPLES; k++) {
        int i = pick_area(cum, n, scan_u01(&seed) * cum[n - 1]), j = pick_area(cum, n, scan_u01(&seed) * cum[n - 1]);
        if (i == j) continue; /* a planar element does not see itself */
        const wrt_quad *a = &s->quads[idx[i]], *b = &s->quads[idx[j]];
        double ua = scan_u01(&seed), va = scan_u01(&seed), ub = scan_u01(&seed), vb = scan_u01(&seed);
        wrt_v3 pa = wrt_quad_point(a, ua, va), pb = wrt_quad_point(b, ub, vb);
        wrt_v3 d = v3_sub(pb, pa);
        if (v3_dot(a->n, d) <= rs.eps || v3_dot(b->n, d) >= -rs.eps) continue; /* not facing */
        wrt_v3 o = v3_add(pa, v3_scale(a->n, rs.eps)), e = v3_add(pb, v3_scale(b->n, rs.eps));
        if (v3_len(v3_sub(e, o)) <= 0) continue;
        if (!wrt_rt_blocked(rs.scene, o, e)) seen++;
    }
    wrt_rt_scene_release(&rs);
    free(idx);
    free(cum);
    return (double)seen / SCAN_VIS_SAMPLES;
}

double wrt_scan_exchange_fraction(const wrt_scene *s) {
    if (!s || s->nquads < 2) return 0;
    int n = s->nquads;
    /* the bake's tolerance (bake.c: 1e-7 of the scene's size, its bounding box's diagonal) */
    wrt_v3 lo = s->quads[0].p[0], hi = lo;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 4; k++) {
            wrt_v3 p = s->quads[i].p[k];
            lo = v3(fmin(lo.x, p.x), fmin(lo.y, p.y), fmin(lo.z, p.z));
            hi = v3(fmax(hi.x, p.x), fmax(hi.y, p.y), fmax(hi.z, p.z));
        }
    double eps = 1e-7 * v3_len(v3_sub(hi, lo));
    uint64_t seed = 0xE7C4ull;
    long facing = 0;
    for (int k = 0; k < SCAN_VIS_SAMPLES; k++) {
        int i = (int)(scan_u01(&seed) * n), j = (int)(scan_u01(&seed) * (n - 1));
        if (i >= n) i = n - 1;
        if (j >= n - 1) j = n - 2;
        if (j >= i) j++; /* distinct */
        const wrt_quad *a = &s->quads[i], *b = &s->quads[j];
        int ab = 0, ba = 0;
        for (int c = 0; c < 4; c++) {
            ab |= v3_dot(v3_sub(b->p[c], a->p[0]), a->n) > eps;
            ba |= v3_dot(v3_sub(a->p[c], b->p[0]), b->n) > eps;
        }
        facing += ab && ba;
    }
    return (double)facing / SCAN_VIS_SAMPLES;
}

/* The model: each figure y (CPU seconds; peak memory over SCAN_MB_BASE; bytes) is
 *   y = c * step^(q - 5) * (N / 1000)^(a + k (min(q, 5) - 5)) * (f / 0.3)^g * (x / 0.1)^h
 * with N the elements, f the visible fraction and x the exchange fraction above and q
 * the quality, one set of constants for the plain bake and one for --clusters (h = 0:
 * it links clusters, not every pair of elements that face each other; k moves N's exponent
 * with the quality: with --clusters quality 5's CPU grows as N^0.7 where quality 1's grows
 * as N^1.2, and the plain bake's quality-1 rows lay 5 times over a model without it; the
 * qualities over 5, none fitted, take quality 5's exponent). Fitted over the measured
 * bakes in docs/scan_fit.csv (tools/scan_fit.py: the plain bake at quality 1, 3 and 5,
 * cornell-shapes, mazes, the atrium, the Blender scenes; with --clusters quality 1 to 5,
 * cornell-shapes and the atrium from 240 to 100,256 elements, all baked again with the
 * receivers' tree in sessions 19 and 20) to make the
 * band of estimate / measured narrowest, then c
 * raised so that no measured bake lies above its estimate, and by a rerun's spread above
 * that (tools/scan_fit.py SPREAD): the estimate is an upper bound, and docs/triangles.md
 * ("--scan's estimate, refitted (session 8)", and session 13's refit) gives how far above
 * each bake it lies. Without x (session 7's model) the
 * plain bake's band was 3.2x in CPU and 3.3x in peak after the session-7 merge: the
 * atrium's 1,060 elements, 30% of whose pairs face each other, cost more than
 * cornell-shapes' 1,885 with 1.6%. Qualities other than those fitted are extrapolated by the
 * same step; f and x are taken within the fitted bakes' range (no extrapolation in them). */
#define SCAN_MB_BASE 30.0 /* the process itself: libraries, the scene */
typedef struct scan_model { double c, step, a, g, h, k; } scan_model;
/* [0] seconds, [1] peak MB over the base, [2] bytes: {c, step, a, g, h, k}; pasted from
 * tools/scan_fit.py's output */
static const double scan_plain_range[2][2] = {{0.0102, 0.5658}, {0.0081, 0.5401}}; /* f, x */
static const double scan_clusters_range[2][2] = {{0.3610, 0.5214}, {0, 1}};
static const scan_model model_plain[3] = {
    {206, 2.2033, 0.9932, 0.3865, 0.3911, -0.2565}, /* cpu_s */
    {1663, 2.0726, 1.1071, 0.3693, 0.6034, -0.1804}, /* peak_mb */
    {1.306e+08, 2.0595, 0.8983, 0.2398, 0.0417, -0.1326}, /* bytes */
};
static const scan_model model_clusters[3] = {
    {414.3, 2.2595, 0.7249, -0.8841, 0, -0.1580}, /* cpu_s */
    {1526, 1.8806, 0.6576, 0.9170, 0, -0.1040}, /* peak_mb */
    {1.08e+08, 1.9750, 0.6425, 0.1286, 0, -0.0421}, /* bytes */
};

static double clampd(double v, const double r[2]) { return v < r[0] ? r[0] : v > r[1] ? r[1] : v; }

static double model_at(const scan_model *m, int q, double n, double f, double x, const double range[2][2]) {
    return m->c * pow(m->step, q - 5) * pow(n / 1000.0, m->a + m->k * ((q < 5 ? q : 5) - 5)) *
           pow(clampd(f, range[0]) / 0.3, m->g) *
           (m->h != 0 ? pow(clampd(x, range[1]) / 0.1, m->h) : 1);
}

wrt_scan_estimate wrt_scan_estimate_cost(const wrt_scene *s, const wrt_bake_options *o) {
    wrt_scan_estimate e;
    memset(&e, 0, sizeof e);
    e.quality = o && o->quality ? o->quality : 5;
    e.elements = s ? s->nquads : 0;
    e.visible = wrt_scan_visible_fraction(s);
    e.exchange = wrt_scan_exchange_fraction(s);
    if (e.elements == 0) { e.memory_mb = SCAN_MB_BASE; return e; }
    int cl = o && o->clusters;
    const scan_model *m = cl ? model_clusters : model_plain;
    const double(*range)[2] = cl ? scan_clusters_range : scan_plain_range;
    double f = e.visible > 0 ? e.visible : 1; /* no figure (Embree failed): the dense case */
    e.seconds = model_at(&m[0], e.quality, e.elements, f, e.exchange, range);
    e.memory_mb = SCAN_MB_BASE + model_at(&m[1], e.quality, e.elements, f, e.exchange, range);
    e.bytes = model_at(&m[2], e.quality, e.elements, f, e.exchange, range);
    return e;
}

int wrt_scan_clusters_auto(const wrt_scene *s, const wrt_bake_options *o, double *pairs) {
    if (pairs) *pairs = 0;
    /* under 1,000 elements there are under 1e6 pairs at all: no rays cast */
    if (!s || (double)s->nquads * s->nquads < WRT_CLUSTERS_AUTO_PAIRS || (o && o->gathered)) return 0;
    /* the bake's own test (bake.c): any material with an angular level, used or not */
    for (int m = 0; m < s->nmaterials; m++)
        if (wrt_brdf_angular_level(&s->materials[m]) != 0) return 0;
    double f = wrt_scan_visible_fraction(s), n = s->nquads;
    double p = n * n * (f >= 0 ? f : 1); /* no figure (Embree failed): the dense case */
    if (pairs) *pairs = p;
    return p >= WRT_CLUSTERS_AUTO_PAIRS || s->nquads >= WRT_CLUSTERS_AUTO_ELEMENTS;
}

static const char *human_time(double s, char *buf, size_t n) {
    if (s < 120) snprintf(buf, n, "%.0f s", s);
    else if (s < 7200) snprintf(buf, n, "%.0f min", s / 60);
    else snprintf(buf, n, "%.1f h", s / 3600);
    return buf;
}

void wrt_scan_print(const wrt_scene *s, const wrt_bake_options *o, int drop_bad, int clusters_auto, int json, FILE *f) {
    if (!s || !f) return;
    wrt_scan_estimate e = wrt_scan_estimate_cost(s, o);
    int refused = s->nnonfinite > 0 && !drop_bad, glossy = 0;
    for (int i = 0; i < s->nquads; i++) {
        int m = s->quads[i].material;
        glossy += m >= 0 && m < s->nmaterials && !s->materials[m].lambertian;
    }
    if (json) {
        char *buf = NULL;
        size_t len = 0;
        FILE *m = open_memstream(&buf, &len);
        if (!m) return;
        wrt_scene_print_summary(s, 1, m);
        fclose(m);
        /* the summary is one object ending in "}\n": add to it */
        while (len > 0 && (buf[len - 1] == '\n' || buf[len - 1] == ' ')) len--;
        if (len > 0 && buf[len - 1] == '}') len--;
        fwrite(buf, 1, len, f);
        free(buf);
        fprintf(f, ",\"refused\":%s,\"drop_bad\":%s,\"estimate\":{\"quality\":%d,\"elements\":%d,"
                   "\"visible_fraction\":%.4f,\"exchange_fraction\":%.4f,\"glossy_elements\":%d,\"cpu_seconds\":%.3g,\"memory_mb\":%.4g,\"bytes\":%.4g,"
                   "\"model\":\"%s: elements, visible and facing pairs, fitted to measured bakes, an upper bound\","
                   "\"clusters_chosen\":\"%s\"}}\n",
                refused ? "true" : "false", drop_bad ? "true" : "false", e.quality, e.elements, e.visible, e.exchange,
                glossy, e.seconds, e.memory_mb, e.bytes, o && o->clusters ? "clusters" : "plain",
                !(o && o->clusters) ? "none" : clusters_auto ? "auto" : "given");
        return;
    }
    wrt_scene_print_summary(s, 0, f);
    if (s->nnonfinite)
        fprintf(f, "bake: %s\n", refused ? "refused: triangles with non-finite corners (--drop-bad drops them)"
                                         : "the non-finite triangles are dropped (--drop-bad)");
    char tb[32];
    fprintf(f, "estimate at quality %d%s: %d elements, %.0f%% of the point pairs on them see each other; at most about %s "
               "of CPU (about half that on 2 idle cores), peak memory at most about %.0f MB, file at most about "
               "%.0f MB (a model of the elements, visible and facing pairs fitted to measured bakes, set above all of "
               "them; docs/triangles.md)\n",
            e.quality, o && o->clusters ? " with --clusters" : "", e.elements, 100 * e.visible,
            human_time(e.seconds, tb, sizeof tb), e.memory_mb, e.bytes / 1e6);
    if (clusters_auto)
        fprintf(f, "clusters: %d diffuse elements, %.2gM of their ordered pairs in sight: wrt-bake takes --clusters "
                   "by itself from %.0fM pairs in sight or %d elements on (--no-clusters: the plain bake)\n",
                e.elements, (double)e.elements * e.elements * (e.visible >= 0 ? e.visible : 1) / 1e6,
                WRT_CLUSTERS_AUTO_PAIRS / 1e6, WRT_CLUSTERS_AUTO_ELEMENTS);
    if (glossy)
        fprintf(f, "estimate: %d glossy elements; the model is fitted to diffuse scenes and a glossy surface's "
                   "angular refinement can cost several times more\n", glossy);
}

void wrt_scan_print_bake_hint(const wrt_scene *s, const wrt_bake_options *o, FILE *f) {
    if (!s || !o || !f || s->nquads == 0) return;
    wrt_bake_options d = *o;
    wrt_bake_defaults(&d); /* the quality and the budget the bake will use */
    wrt_scan_estimate e = wrt_scan_estimate_cost(s, &d);
    char tb[32];
    fprintf(f, "wrt-bake: estimate at quality %d%s: at most about %s of CPU, %.0f MB peak, %.0f MB file "
               "(--scan's model, an upper bound; the budget %.0f MB)\n",
            e.quality, d.clusters ? " with --clusters" : "", human_time(e.seconds, tb, sizeof tb), e.memory_mb,
            e.bytes / 1e6, d.max_memory_mb);
    int glossy = 0;
    for (int i = 0; i < s->nquads; i++) {
        int m = s->quads[i].material;
        glossy += m >= 0 && m < s->nmaterials && !s->materials[m].lambertian;
    }
    /* a large diffuse scene baked without --clusters: say what --clusters would cost */
    if (!d.clusters && !glossy && (e.memory_mb > d.max_memory_mb || e.seconds > 3600)) {
        wrt_bake_options c = d;
        c.clusters = 1;
        wrt_scan_estimate ec = wrt_scan_estimate_cost(s, &c);
        c.quality = 1;
        wrt_scan_estimate e1 = wrt_scan_estimate_cost(s, &c);
        char t1[32], t2[32];
        if (ec.seconds < e.seconds || ec.memory_mb < e.memory_mb)
            fprintf(f, "wrt-bake: hint: %d diffuse elements bake faster with --clusters: at most about %s of CPU and "
                       "%.0f MB at quality %d, %s and %.0f MB at -q 1 (docs/clusters.md)\n",
                    e.elements, human_time(ec.seconds, t1, sizeof t1), ec.memory_mb, d.quality,
                    human_time(e1.seconds, t2, sizeof t2), e1.memory_mb);
    }
    if (e.memory_mb > d.max_memory_mb)
        fprintf(f, "wrt-bake: the estimate passes the budget: the bake stops, writing nothing, at the first stage "
                   "whose measured need passes it (--max-memory MB raises it)\n");
}
