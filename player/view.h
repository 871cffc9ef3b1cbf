/* view.h: wrt-play's geometry questions about the scene, answered through the library's
 * getters alone (include/wrt.h), by brute-force rays against every quad:
 *  - the default camera of a scene whose file has none: the view, among the box framed
 *    from +Z outside it and 27 points inside the box each looking along the four
 *    horizontal axes and at the box's centre, whose frustum (a 7 x 7 grid of rays, back
 *    faces passed through as the renderer culls them) meets the most surface that a
 *    light reaches directly; the outside view unless an inside one shows 5% more of
 *    the picture lit. So a camera is never left inside a closed object (nothing lit
 *    there) nor outside a closed room looking at the outside of its walls (their outside
 *    is unlit), as double-sided materials would have it;
 *  - where a light moved by the window's keys stops: short of the first quad (either
 *    side) on its way, by 1e-3 of the scene's diagonal, so that it never passes through
 *    a wall. Internal to the program. */
#ifndef WRT_PLAY_VIEW_H
#define WRT_PLAY_VIEW_H

#include "../include/wrt.h"
#include "render.h"

typedef struct wrt_play_geom wrt_play_geom;

/* The quads' corners and normals, read once through the API. WRT_ERR_NOMEM,
 * WRT_ERR_INVALID_ARG (a dead runtime). */
wrt_status wrt_play_geom_create(const wrt_runtime *rt, wrt_play_geom **out);
void wrt_play_geom_destroy(wrt_play_geom *g);

/* Fills *v (eye, target, up +Y, yfov 45 degrees) as above; returns which candidate won
 * (0: outside, from +Z) and *score (may be NULL) the fraction of its rays that see lit
 * surface. Lights switched off are ignored; with no light on, the outside view. */
int wrt_play_default_view(const wrt_play_geom *g, const wrt_runtime_light *lights, int nlights, wrt_view *v,
                          double *score);

/* The fraction in [0, 1] of the way from -> to that a light may go before it would meet
 * a quad (1: nothing in the way). */
double wrt_play_geom_clip_move(const wrt_play_geom *g, const double from[3], const double to[3]);

#endif
