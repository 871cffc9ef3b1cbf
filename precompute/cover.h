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

/* The quad the ray from o along the unit dir meets first, or -1 (either side). */
int wrt_bake_first_hit(const bake_ctx *b, wrt_v3 o, wrt_v3 dir);

/* 1 if the point o (already lifted off quad q along its normal) is inside closed
 * geometry: five rays from it all meet the back of a quad first. */
int wrt_bake_covered(const bake_ctx *b, wrt_v3 o, const wrt_quad *q);

/* Per quad, 1 if some point of a 16 x 16 grid on it is covered (wrt_xcalloc'd). */
uint8_t *wrt_bake_cover_flags(const bake_ctx *b);

#endif
