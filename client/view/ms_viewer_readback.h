/* What meshview reads back from the GPU: screenshots (the colour buffer as a
 * PNG, through ms_png.h) and the depth under the cursor (double-click
 * re-centring), and the offscreen framebuffer a headless run draws into (a
 * hidden window has no pixels of its own).
 *
 * Pixel coordinates are framebuffer pixels from the bottom-left corner, as
 * OpenGL counts them. Requires a current OpenGL 4.1 core context.
 * Errors: ms_status with one line (MS_ERR_IO for the file, MS_ERR_UNSUPPORTED
 * for an incomplete framebuffer, MS_ERR_NOMEM). Thread-safety: the context's
 * thread.
 */
#ifndef MS_VIEWER_READBACK_H
#define MS_VIEWER_READBACK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

/* Writes the bound read framebuffer's width x height colour pixels to path as an
 * RGB PNG (top row first). */
ms_status ms_viewer_screenshot(const char *path, int width, int height, ms_error *err);

/* The P key: the screenshot as DIR/meshview-NAME-NNN.png, NNN from *counter
 * on, the first name not taken (at most 1000 tries); its path into written. */
ms_status ms_viewer_screenshot_numbered(const char *dir, const char *name, int *counter, int width, int height,
                                        char *written, size_t size, ms_error *err);

/* Reads width x height RGB pixels, top row first, into a malloc'd buffer. */
ms_status ms_viewer_read_rgb(int width, int height, uint8_t **pixels, ms_error *err);

/* Window depth in [0, 1] at pixel (x, y) of the bound read framebuffer; false
 * outside it. */
bool ms_viewer_read_depth(int x, int y, int width, int height, double *depth);

/* An offscreen framebuffer: RGBA8 colour and 24-bit depth. */
typedef struct ms_viewer_target {
    unsigned fbo, colour, depth;
    int width, height;
} ms_viewer_target;

ms_status ms_viewer_target_init(ms_viewer_target *target, int width, int height, ms_error *err);
/* Binds it for drawing and reading. */
void ms_viewer_target_bind(const ms_viewer_target *target);
void ms_viewer_target_free(ms_viewer_target *target);
/* Bytes of GL storage it holds: 4 a pixel of colour and 4 of depth (24 bits
 * are stored in 32 by the drivers we know): 8 width x height; 0 when freed. */
uint64_t ms_viewer_target_gl_bytes(const ms_viewer_target *target);

#endif
