/* PNG writer (8-bit RGB or grey, no interlace, rows unfiltered) on libpng.
 * Used for reference renders, screenshots and plots. Writes to a temporary name
 * and renames on success. Thread-safe (no shared state). */
#ifndef MS_PNG_H
#define MS_PNG_H

#include <stdint.h>

#include "ms_error.h"

/* pixels: height rows of width * channels bytes, top row first; channels is 1
 * (grey) or 3 (RGB). width and height in [1, 65535]. */
ms_status ms_png_write(const char *path, const uint8_t *pixels, uint32_t width, uint32_t height,
                       int channels, ms_error *err);

/* The same, smaller: rows filtered (libpng's adaptive choice) and deflated
 * at level 9; for pictures served over the network (thumbnails). */
ms_status ms_png_write_compact(const char *path, const uint8_t *pixels, uint32_t width,
                               uint32_t height, int channels, ms_error *err);

#endif
