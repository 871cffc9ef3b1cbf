/* cover.c: the parts of a quad that other surfaces cover (docs/triangles.md, "Covered
 * sender points").
 *
 * Where an object stands on the floor, the floor under it is inside the object: no light
 * reaches it and none leaves it, for every light. The runtime projects the direct light
 * onto the floor's cells with that part dark, so a cell's coefficient is the mean over
 * the cell, covered part included. A link that sends that cell's light to a receiver x
 * multiplies the mean by the cell's visible form factor from x, whose visibility rays to
 * points under the object are blocked as well: the covered part is counted dark twice,
 * and the light the cell sends is low by its covered fraction (the walls of
 * tests/data/blender_shapes.gltf 1 to 3% under the path tracer). The light the cell
 * really sends is its exposed part's radiosity, mean / exposed fraction, times the form
 * factor to the exposed part: that is the mean times the visible share among the exposed
 * points. So a visibility ray whose sender end is covered is not a sample of the sender
 * at all; dto.c draws another point of the sender cell in its place.
 *
 * A point is covered when it is inside closed geometry: every one of five rays from it
 * (along the normal and four at 60 degrees from it) first meets the back of a quad.
 * A point under a single-sided panel or in a narrow gap sees out along some ray and is
 * not covered. Depends on bake_ctx.h (Embree's scene of the quads); the balance (balance.c)
 * uses its first-hit query too. */

#include "cover.h"

#include "../common/rt_scene.h"
#include "../common/threads.h"

#include <stdlib.h>

int wrt_bake_first_hit(const bake_ctx *b, wrt_v3 o, wrt_v3 dir) {
    return wrt_rt_first_hit(b->rtc, o, dir);
}

int wrt_bake_covered(const bake_ctx *b, wrt_v3 o, const wrt_quad *q) {
    for (int i = 0; i < 5; i++) {
        wrt_v3 d = q->n;
        if (i) {
            double a = (i - 1) * (WRT_PI / 2);
            wrt_v3 t = v3_add(v3_scale(q->t, cos(a)), v3_scale(q->b, sin(a)));
            d = v3_norm(v3_add(v3_scale(q->n, 0.5), v3_scale(t, 0.8660254037844386)));
        }
        int hit = wrt_bake_first_hit(b, o, d);
        if (hit < 0 || !(v3_dot(d, b->quads[hit].n) > 0)) return 0;
    }
    return 1;
}

/* The block wrt_bake_cover_flags returns: nq flags, padded to 8 bytes; nq uint32 map
 * numbers (0: none, else 1 + the map's index); then the maps, each (G + 1)^2 corners'
 * cover (G = WRT_COVER_MAP) followed by G^2 cells' states. */
enum { CELL_OPEN = 0, CELL_COVERED = 1, CELL_MIXED = 2 };
#define MAP_SIDE (WRT_COVER_MAP + 1)
#define MAP_BYTES (MAP_SIDE * MAP_SIDE + WRT_COVER_MAP * WRT_COVER_MAP)

static size_t flags_bytes(int nq) { return ((size_t)nq + 7) & ~(size_t)7; }

typedef struct map_job {
    const bake_ctx *b;
    const int *quad;   /* the flagged quads, in order */
    uint8_t *maps;
} map_job;

/* A flagged quad's map: its corners' cover, then each cell's state from its corners. */
static void map_one(size_t i, int th, void *user) {
    (void)th;
    const map_job *j = user;
    const bake_ctx *b = j->b;
    const wrt_quad *Q = &b->quads[j->quad[i]];
    uint8_t *m = j->maps + i * MAP_BYTES, *cell = m + MAP_SIDE * MAP_SIDE;
    for (int y = 0; y < MAP_SIDE; y++)
        for (int x = 0; x < MAP_SIDE; x++) {
            double u = (double)x / WRT_COVER_MAP, v = (double)y / WRT_COVER_MAP;
            m[y * MAP_SIDE + x] = (uint8_t)wrt_bake_covered(b, v3_mad(wrt_quad_point(Q, u, v), Q->n, b->ray_eps), Q);
        }
    for (int y = 0; y < WRT_COVER_MAP; y++)
        for (int x = 0; x < WRT_COVER_MAP; x++) {
            const uint8_t *c = m + y * MAP_SIDE + x;
            int n = c[0] + c[1] + c[MAP_SIDE] + c[MAP_SIDE + 1];
            cell[y * WRT_COVER_MAP + x] = (uint8_t)(n == 0 ? CELL_OPEN : n == 4 ? CELL_COVERED : CELL_MIXED);
        }
}

uint8_t *wrt_bake_cover_flags(const bake_ctx *b) {
    uint8_t *f = wrt_xcalloc(flags_bytes(b->nq) + 1, 1);
    int nflag = 0;
    for (int q = 0; q < b->nq; q++) {
        const wrt_quad *Q = &b->quads[q];
        for (int k = 0; k < WRT_COVER_GRID * WRT_COVER_GRID && !f[q]; k++) {
            double u = (k % WRT_COVER_GRID + 0.5) / WRT_COVER_GRID, v = (k / WRT_COVER_GRID + 0.5) / WRT_COVER_GRID;
            f[q] = (uint8_t)wrt_bake_covered(b, v3_mad(wrt_quad_point(Q, u, v), Q->n, b->ray_eps), Q);
        }
        nflag += f[q];
    }
    /* the maps: the per-pair DTO tests its sender points on these quads many times over
     * (docs/clusters.md, "The cover tests' cost") */
    size_t head = flags_bytes(b->nq) + (size_t)b->nq * sizeof(uint32_t);
    f = wrt_xrealloc(f, head + (size_t)nflag * MAP_BYTES + 1);
    uint32_t *num = (uint32_t *)(f + flags_bytes(b->nq));
    int *quad = wrt_xmalloc((size_t)(nflag ? nflag : 1) * sizeof *quad);
    for (int q = 0, n = 0; q < b->nq; q++) {
        num[q] = f[q] ? (uint32_t)(n + 1) : 0;
        if (f[q]) quad[n++] = q;
    }
    map_job j = {b, quad, f + head};
    wrt_parallel_for((size_t)nflag, b->opt.threads, map_one, &j);
    free(quad);
    return f;
}

int wrt_bake_covered_uv(const bake_ctx *b, int qi, double u, double v, wrt_v3 o, uint64_t *rays) {
    const wrt_quad *Q = &b->quads[qi];
    uint32_t n = ((const uint32_t *)(b->cover + flags_bytes(b->nq)))[qi];
    if (!n) return ++*rays, wrt_bake_covered(b, o, Q);
    int x = (int)(u * WRT_COVER_MAP), y = (int)(v * WRT_COVER_MAP);
    x = x < 0 ? 0 : x >= WRT_COVER_MAP ? WRT_COVER_MAP - 1 : x;
    y = y < 0 ? 0 : y >= WRT_COVER_MAP ? WRT_COVER_MAP - 1 : y;
    const uint8_t *m = b->cover + flags_bytes(b->nq) + (size_t)b->nq * sizeof(uint32_t) + (size_t)(n - 1) * MAP_BYTES;
    int st = m[MAP_SIDE * MAP_SIDE + y * WRT_COVER_MAP + x];
    if (st != CELL_MIXED) return st == CELL_COVERED;
    ++*rays;
    return wrt_bake_covered(b, o, Q);
}
