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

uint8_t *wrt_bake_cover_flags(const bake_ctx *b) {
    uint8_t *f = wrt_xcalloc((size_t)(b->nq ? b->nq : 1), 1);
    for (int q = 0; q < b->nq; q++) {
        const wrt_quad *Q = &b->quads[q];
        for (int k = 0; k < WRT_COVER_GRID * WRT_COVER_GRID && !f[q]; k++) {
            double u = (k % WRT_COVER_GRID + 0.5) / WRT_COVER_GRID, v = (k / WRT_COVER_GRID + 0.5) / WRT_COVER_GRID;
            f[q] = (uint8_t)wrt_bake_covered(b, v3_mad(wrt_quad_point(Q, u, v), Q->n, b->ray_eps), Q);
        }
    }
    return f;
}
