/* scene_dups.c: coincident duplicate elements. Two elements that occupy the same place
 * facing the same way (a mesh exported twice, a node instanced twice at one transform)
 * each receive and reflect the full light: the wall they make is twice as bright, and
 * nothing else in the method notices (every pair of elements is a valid exchange). A
 * rasterizer shows them as one surface (they z-fight invisibly), so the file is valid
 * glTF and other tools accept it; the loader therefore warns, naming both elements and
 * where they come from, rather than refusing. Back-to-back faces (opposite normals: a
 * zero-thickness wall lit from both sides) are not duplicates. Found in O(n log n): the
 * centroids are sorted by a grid cell twice the tolerance wide and each element is
 * compared with those in its own and the 26 neighbouring cells; counting stops at 10,000
 * pairs (a file of n copies of one quad has n^2/2). Depends on scene.h. */
#include "scene.h"
#include "scene_internal.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

/* Same place: centroids within DUP_REL x the scene diagonal, normals within ~0.08
 * degrees of each other, areas within 0.1 %. */
#define DUP_REL 1e-5
#define DUP_COS (1.0 - 1e-6)
#define DUP_AREA 1e-3
#define DUP_SHOWN 3     /* pairs named in the warning; the rest are counted */
#define DUP_MAX 10000   /* counting stops here: n copies of one quad are n^2/2 pairs */

typedef struct { int64_t k[3]; int q; } dup_key;

static int cmp_key(const void *pa, const void *pb) {
    const dup_key *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->k[i] != b->k[i]) return a->k[i] < b->k[i] ? -1 : 1;
    return a->q < b->q ? -1 : a->q > b->q;
}

static wrt_v3 centroid(const wrt_quad *q) {
    return v3_scale(v3_add(v3_add(q->p[0], q->p[1]), v3_add(q->p[2], q->p[3])), 0.25);
}

static int same_place(const wrt_quad *a, const wrt_quad *b, double tol) {
    if (v3_len(v3_sub(centroid(a), centroid(b))) > tol) return 0;
    if (v3_dot(a->n, b->n) < DUP_COS) return 0;
    return fabs(a->area - b->area) <= DUP_AREA * fmax(a->area, b->area);
}

/* The first index in keys[0..n) whose cell is >= k (the element index ignored). */
static size_t lower(const dup_key *keys, size_t n, const int64_t k[3]) {
    size_t lo = 0, hi = n;
    dup_key probe = {{k[0], k[1], k[2]}, -1};
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cmp_key(&keys[mid], &probe) < 0) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

static void where(const wrt_scene *s, const wrt_quad *q, char *buf, size_t cap) {
    const char *name = q->name >= 0 && q->name < s->nnames ? s->names[q->name] : "";
    if (q->kind == WRT_ELEM_QUAD)
        snprintf(buf, cap, "mesh %d '%s' primitive %d triangles %d and %d, node %d", q->mesh, name, q->prim,
                 q->tri[0], q->tri[1], q->node);
    else
        snprintf(buf, cap, "mesh %d '%s' primitive %d triangle %d part %d, node %d", q->mesh, name, q->prim,
                 q->tri[0], q->part, q->node);
}

int wrt_scene_coincident(const wrt_scene *s, double diag, const char *label, int quiet) {
    size_t n = (size_t)(s->nquads > 0 ? s->nquads : 0);
    if (n < 2 || !(diag > 0)) return 0;
    double tol = DUP_REL * diag, h = 2 * tol;
    wrt_v3 lo = s->quads[0].p[0];
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 4; k++) {
            wrt_v3 c = s->quads[i].p[k];
            lo = v3(fmin(lo.x, c.x), fmin(lo.y, c.y), fmin(lo.z, c.z));
        }
    dup_key *keys = wrt_xmalloc(n * sizeof *keys);
    for (size_t i = 0; i < n; i++) {
        wrt_v3 c = v3_sub(centroid(&s->quads[i]), lo);
        keys[i] = (dup_key){{(int64_t)floor(c.x / h), (int64_t)floor(c.y / h), (int64_t)floor(c.z / h)}, (int)i};
    }
    qsort(keys, n, sizeof *keys, cmp_key);
    int found = 0;
    char a[200], b[200];
    for (size_t i = 0; i < n && found < DUP_MAX; i++) {
        const dup_key *ki = &keys[i];
        for (int d = 0; d < 27; d++) {
            int64_t c[3] = {ki->k[0] + d % 3 - 1, ki->k[1] + d / 3 % 3 - 1, ki->k[2] + d / 9 - 1};
            for (size_t j = lower(keys, n, c); j < n && found < DUP_MAX; j++) {
                const dup_key *kj = &keys[j];
                if (kj->k[0] != c[0] || kj->k[1] != c[1] || kj->k[2] != c[2]) break;
                if (kj->q <= ki->q) continue; /* each pair once, the lower index first */
                const wrt_quad *qa = &s->quads[ki->q], *qb = &s->quads[kj->q];
                if (!same_place(qa, qb, tol)) continue;
                if (++found <= DUP_SHOWN && !quiet) {
                    where(s, qa, a, sizeof a);
                    where(s, qb, b, sizeof b);
                    wrt_log(WRT_LOG_WARN, "%s: elements %d (%s) and %d (%s) occupy the same place facing the "
                            "same way: both reflect the full light, so that surface is counted twice; remove "
                            "one of them", label, ki->q, a, kj->q, b);
                }
            }
        }
    }
    if (found > DUP_SHOWN && !quiet)
        wrt_log(WRT_LOG_WARN, "%s: %s%d more pairs of coincident elements (%s%d in all)", label,
                found == DUP_MAX ? "at least " : "", found - DUP_SHOWN, found == DUP_MAX ? "at least " : "", found);
    free(keys);
    return found;
}
