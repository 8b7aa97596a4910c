/* meshview's 2D overlay pass: text in the viewer's bitmap font (ms_viewer_font.h)
 * and filled rectangles, batched and drawn in one call over whatever the frame
 * holds (HUD, progress bar, catalogue screen).
 *
 * Coordinates are framebuffer pixels with the origin at the top-left corner, y
 * down. `scale` pixels per font bit (1 on a normal screen, 2 on a HiDPI one):
 * a character is MS_FONT_ADVANCE_X * scale wide, a line MS_FONT_LINE_HEIGHT *
 * scale tall. Colours are non-premultiplied RGBA in [0, 1], alpha-blended.
 *
 * Requires a current OpenGL 4.1 core context (ms_gl_window.h) for _new, _free
 * and _draw. Errors: MS_ERR_UNSUPPORTED when the program does not build (the
 * driver's first log line), MS_ERR_NOMEM (also for a batch that could not grow,
 * reported by _draw). Thread-safety: the context's thread.
 */
#ifndef MS_VIEWER_TEXT_H
#define MS_VIEWER_TEXT_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_viewer_text ms_viewer_text;

ms_status ms_viewer_text_new(ms_viewer_text **text, ms_error *err);
void ms_viewer_text_free(ms_viewer_text *text);

/* The scale for a framebuffer `height` pixels tall with `pixel_ratio`
 * framebuffer pixels per screen point (HiDPI): the ratio rounded, doubled on
 * tall framebuffers (700 points, or 400 for `large` text such as the
 * catalogue's). */
int ms_viewer_text_auto_scale(int height, double pixel_ratio, bool large);

/* Starts an empty batch for a framebuffer of width x height pixels. */
void ms_viewer_text_begin(ms_viewer_text *text, int width, int height, int scale);
int ms_viewer_text_scale(const ms_viewer_text *text);

void ms_viewer_text_rect(ms_viewer_text *text, double x, double y, double w, double h,
                         const float rgba[4]);
/* One line of text with its top-left corner at (x, y); returns its width in
 * pixels. Characters outside 32..126 draw as '?'. */
double ms_viewer_text_print(ms_viewer_text *text, double x, double y, const float rgba[4],
                            const char *line);

/* An RGB picture (rgb: height rows of 3 * width bytes, top row first, 8-bit
 * sRGB) stretched over the rectangle (x, y, w, h), drawn after the batch's
 * rectangles and text (one picture a batch: a later call replaces it). key
 * names the picture: its texture is uploaded again only when key changes. */
void ms_viewer_text_image(ms_viewer_text *text, double x, double y, double w, double h,
                          const uint8_t *rgb, int width, int height, uint64_t key);

/* Bytes of GL storage the overlay holds: its font atlas (1 byte a texel) and
 * its vertex buffer as sized by the latest draw, and its picture's texture. 0 for NULL. No GL needed. */
uint64_t ms_viewer_text_gl_bytes(const ms_viewer_text *text);

/* Draws the batch over the bound framebuffer (no depth test, blending on; the
 * state it changes is put back) and empties it. */
ms_status ms_viewer_text_draw(ms_viewer_text *text, ms_error *err);

#endif
