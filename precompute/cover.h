/* cover.h: the parts of a quad inside closed geometry, which neither receive nor send
 * light (cover.c). */
#ifndef WRT_COVER_H
#define WRT_COVER_H

#include <stdint.h>

#include "bake_ctx.h"

/* points tested on each quad, a side, for its flag */
#define WRT_COVER_GRID 16
/* sender points drawn in turn while they are covered, at most (dto.c) */
#define WRT_COVER_REDRAWS 8

/* cells a side of the map of a quad with covered parts (cover.c) */
#define WRT_COVER_MAP 32

/* The quad the ray from o along the unit dir meets first, or -1 (either side). */
int wrt_bake_first_hit(const bake_ctx *b, wrt_v3 o, wrt_v3 dir);

/* 1 if the point o (already lifted off quad q along its normal) is inside closed
 * geometry: five rays from it all meet the back of a quad first. */
int wrt_bake_covered(const bake_ctx *b, wrt_v3 o, const wrt_quad *q);

/* Per quad, 1 if some point of a 16 x 16 grid on it is covered; the same block (one
 * free) holds each such quad's map, read by wrt_bake_covered_uv. */
uint8_t *wrt_bake_cover_flags(const bake_ctx *b);

/* wrt_bake_covered at the point (u, v) of quad qi (o: that point lifted along the
 * normal), answered from the quad's map where its cell's four corners agree; else
 * tested with rays, counted in *rays. */
int wrt_bake_covered_uv(const bake_ctx *b, int qi, double u, double v, wrt_v3 o, uint64_t *rays);

#endif
