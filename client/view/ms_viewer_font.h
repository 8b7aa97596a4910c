/* meshview's HUD font: a bitmap font drawn for the viewer, ASCII 32..126.
 *
 * Each glyph is 5 columns x 8 rows of bits; row 0 is the top, row 6 the
 * baseline row (the last row of a capital), row 7 holds descenders. A text
 * line advances MS_FONT_ADVANCE_X pixels per character and MS_FONT_LINE_HEIGHT
 * per line (at scale 1), leaving one blank column and two blank rows between
 * glyphs. Pure data; thread-safe.
 */
#ifndef MS_VIEWER_FONT_H
#define MS_VIEWER_FONT_H

#include <stdbool.h>
#include <stdint.h>

#define MS_FONT_FIRST 32
#define MS_FONT_LAST 126
#define MS_FONT_GLYPH_W 5
#define MS_FONT_GLYPH_H 8
#define MS_FONT_ADVANCE_X 6
#define MS_FONT_LINE_HEIGHT 10

/* Whether pixel (x, y) of the glyph of character c is set; characters outside
 * 32..126 draw as '?'. x in [0, 5), y in [0, 8), row 0 at the top. */
bool ms_font_pixel(char c, unsigned x, unsigned y);

/* The glyph rows of c: 8 bytes, bit 4 is the leftmost column. */
const uint8_t *ms_font_glyph(char c);

#endif
