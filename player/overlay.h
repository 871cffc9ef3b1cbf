/* overlay.h: the window's on-screen overlay: filled rectangles and text in a small
 * built-in 5x7 bitmap font (cli/font.h), in pixels from the top-left corner, drawn over whatever the
 * current framebuffer holds (alpha blended). Batched: begin, add, draw once per frame.
 * Depends on OpenGL 4.5 core (a current context, see platform.h), wrt_common.h.
 * Not thread-safe: call from the thread whose context is current. */
#ifndef WRT_OVERLAY_H
#define WRT_OVERLAY_H

#include "../common/wrt_common.h"

typedef struct wrt_overlay wrt_overlay;

/* Errors: WRT_ERR_GL (shader compilation). */
wrt_status wrt_overlay_create(wrt_overlay **out);
void wrt_overlay_destroy(wrt_overlay *o); /* NULL is a no-op */

/* Starts a frame's batch for a framebuffer of fb_w x fb_h pixels. */
void wrt_overlay_begin(wrt_overlay *o, int fb_w, int fb_h);
void wrt_overlay_rect(wrt_overlay *o, float x, float y, float w, float h, const float rgba[4]);
/* Text at (x, y) (top-left of the first cell), each font pixel `scale` pixels wide; a
 * character cell is 6 x 9 font pixels (cli/font.h); '\n' starts a new line. Returns
 * the width of the widest line in pixels. */
float wrt_overlay_text(wrt_overlay *o, float x, float y, int scale, const float rgba[4], const char *s);
/* Width and height in pixels the text would take. */
void wrt_overlay_measure(const char *s, int scale, float *w, float *h);
/* Draws the batch into the current framebuffer (viewport fb_w x fb_h). */
void wrt_overlay_draw(wrt_overlay *o);

/* The font's 8 rows of 5 bits (bit 4 = leftmost; the 8th below the baseline) for a
 * character (blank if it has none). */
const unsigned char *wrt_overlay_glyph(int c);

#endif
