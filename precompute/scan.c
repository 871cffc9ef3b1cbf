/* scan.c: `wrt-bake --scan`: the scene as the bake would see it and what baking it would
 * cost, before anything starts (issue 21). The summary and the element counts come from
 * the loader (formats/scene.c, loaded with report_only so that nothing is refused); this
 * file adds what --drop-bad would change and the estimate.
 *
 * The estimate is a model, not a dry run: time, peak memory and bytes grow as N^1.4 in
 * the number of elements N (the exponent the README states for the bake's cost), scaled
 * from two measured bakes of assets/test/cornell_shapes.gltf (240 elements: a Cornell
 * room with a UV sphere, a cylinder and a bevelled box of triangles) at quality 3 and 5,
 * with one factor per quality step between them (geometric, also beyond them). How much
 * each element sees moves the real figure: docs/triangles.md gives the measured bakes
 * beside the model's figures (a closed icosphere, where every element sees every other,
 * costs several times the model). Depends on the bake's options and the scene only. */
#define _POSIX_C_SOURCE 200809L
#include "scan.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* the anchors: cornell_shapes (240 elements), 2 cores, measured (docs/triangles.md) */
#define SCAN_N0 240.0
#define SCAN_EXPONENT 1.4
#define SCAN_MB_BASE 30.0 /* the process itself: libraries, the scene */
static const double anchor_seconds[2] = {3.3, 44.5};    /* quality 3, 5: CPU seconds (user + system) */
static const double anchor_mb[2] = {81.0, 387.0};        /* peak resident (after the bake frees each series term) */
static const double anchor_bytes[2] = {4.11e6, 25.9e6}; /* the .gto, compact entries (2.0; float 1.x: 11.1e6, 70.1e6) */

static double at_quality(const double a[2], int q) {
    double step = sqrt(a[1] / a[0]); /* per quality step, from 3 to 5 */
    return a[1] * pow(step, q - 5);
}

/* --clusters: its own anchors, the atrium (wrt-scenegen atrium --detail 1: 2,704
 * elements) baked with --clusters at quality 1 (15.1 s CPU, 630 MB, 7.92 MB) and 5 (266.5 s,
 * 3,877 MB, 126.7 MB; docs/bench.md "Scale"), and its own exponents, the atrium's at
 * quality 1 over 1,060 to 8,172 elements (CPU 1.21, peak 1.04, bytes 0.71): steeper than
 * quality 5's two points (0.68, 0.66, 0.59 from 1,060 to 2,704), so the estimate errs
 * high above the anchor, which is what a memory cap needs. The plain bake's N^1.4 from
 * 240 elements put the atrium at detail 1 at 10.6 GB and detail 2 at 49.9 GB, which made
 * tools/bench_scale.sh skip every --clusters row unless CAP_MB was raised. */
#define SCAN_CL_N0 2704.0
/* quality 5's anchor and the exponents (above) */
#define CL_Q5_SECONDS 266.5
#define CL_Q5_MB 3877.0
#define CL_Q5_BYTES 126.7e6
#define CL_EXP_SECONDS 1.21
#define CL_EXP_MB 1.04
#define CL_EXP_BYTES 0.71
static const double cl_anchor_seconds[2] = {15.1, CL_Q5_SECONDS}; /* quality 1, 5 */
static const double cl_anchor_mb[2] = {630.0, CL_Q5_MB};
static const double cl_anchor_bytes[2] = {7.92e6, CL_Q5_BYTES};
static const double cl_exponent[3] = {CL_EXP_SECONDS, CL_EXP_MB, CL_EXP_BYTES}; /* time, peak, bytes */

static double cl_at_quality(const double a[2], int q) {
    double step = pow(a[1] / a[0], 0.25); /* per quality step, from 1 to 5 */
    return a[1] * pow(step, q - 5);
}

static wrt_scan_estimate scan_estimate_clusters(int quality, int elements) {
    wrt_scan_estimate e = {.quality = quality, .elements = elements};
    double x = (double)elements / SCAN_CL_N0;
    e.seconds = cl_at_quality(cl_anchor_seconds, quality) * pow(x, cl_exponent[0]);
    e.memory_mb = SCAN_MB_BASE + (cl_at_quality(cl_anchor_mb, quality) - SCAN_MB_BASE) * pow(x, cl_exponent[1]);
    e.bytes = cl_at_quality(cl_anchor_bytes, quality) * pow(x, cl_exponent[2]);
    if (elements == 0) e.seconds = e.bytes = 0, e.memory_mb = SCAN_MB_BASE;
    return e;
}

wrt_scan_estimate wrt_scan_estimate_cost(const wrt_scene *s, const wrt_bake_options *o) {
    wrt_scan_estimate e;
    memset(&e, 0, sizeof e);
    e.quality = o && o->quality ? o->quality : 5;
    e.elements = s ? s->nquads : 0;
    if (o && o->clusters) return scan_estimate_clusters(e.quality, e.elements);
    double g = pow((double)e.elements / SCAN_N0, SCAN_EXPONENT);
    e.seconds = at_quality(anchor_seconds, e.quality) * g;
    e.memory_mb = SCAN_MB_BASE + (at_quality(anchor_mb, e.quality) - SCAN_MB_BASE) * g;
    e.bytes = at_quality(anchor_bytes, e.quality) * g;
    if (e.elements == 0) e.seconds = e.bytes = 0, e.memory_mb = SCAN_MB_BASE;
    return e;
}

static const char *human_time(double s, char *buf, size_t n) {
    if (s < 120) snprintf(buf, n, "%.0f s", s);
    else if (s < 7200) snprintf(buf, n, "%.0f min", s / 60);
    else snprintf(buf, n, "%.1f h", s / 3600);
    return buf;
}

void wrt_scan_print(const wrt_scene *s, const wrt_bake_options *o, int drop_bad, int json, FILE *f) {
    if (!s || !f) return;
    wrt_scan_estimate e = wrt_scan_estimate_cost(s, o);
    double ex = o && o->clusters ? cl_exponent[0] : SCAN_EXPONENT;
    int refused = s->nnonfinite > 0 && !drop_bad;
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
                   "\"cpu_seconds\":%.3g,\"memory_mb\":%.4g,\"bytes\":%.4g,\"model\":\"N^%.1f from measured bakes\"}}\n",
                refused ? "true" : "false", drop_bad ? "true" : "false", e.quality, e.elements, e.seconds,
                e.memory_mb, e.bytes, ex);
        return;
    }
    wrt_scene_print_summary(s, 0, f);
    if (s->nnonfinite)
        fprintf(f, "bake: %s\n", refused ? "refused: triangles with non-finite corners (--drop-bad drops them)"
                                         : "the non-finite triangles are dropped (--drop-bad)");
    char tb[32];
    fprintf(f, "estimate at quality %d: %d elements, about %s of CPU (about half that on 2 idle cores), peak "
               "memory about %.0f MB, file about %.0f MB (model: N^%.1f scaled from measured bakes; the real "
               "cost varies by a factor of a few with how much each element sees)\n",
            e.quality, e.elements, human_time(e.seconds, tb, sizeof tb), e.memory_mb, e.bytes / 1e6, ex);
}
