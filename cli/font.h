/* font.h: a 5x7 bitmap font for text in pixels: the window's overlay (player/overlay.c)
 * uploads it as a texture, wrt-compare labels its panels with wrt_font_draw_rgb8. A
 * character cell is 6 x 9 font pixels (the glyph at column 1, row 1 of its cell); a
 * character it lacks is drawn as a blank. No dependencies;
 * read-only data, thread-safe. */
#ifndef WRT_FONT_H
#define WRT_FONT_H

#include <stdint.h>

#define WRT_FONT_CELL_W 6
#define WRT_FONT_CELL_H 9
#define WRT_FONT_NGLYPH 95

/* The glyphs: ' ' .. '`', then '{' '|' '}' '~', then 'a' .. 'z'; each 7 rows of 5 bits
 * down to the baseline and an 8th for descenders (g j p q y), bit 4 leftmost. */
extern const unsigned char wrt_font[WRT_FONT_NGLYPH][8];
/* The index in wrt_font of a character (0, the blank, if the font has none). */
int wrt_font_index(int c);
/* Width and height in pixels text takes at `scale` image pixels per font pixel ('\n'
 * starts a new line). */
void wrt_font_measure(const char *s, int scale, int *w, int *h);
/* Draws text into a w x h RGB8 image (rows top to bottom) with its first cell's top-left
 * corner at (x, y), in colour rgb; only the glyphs' pixels are written, clipped to the
 * image. */
void wrt_font_draw_rgb8(uint8_t *img, int w, int h, int x, int y, int scale, const uint8_t rgb[3], const char *s);

#endif
