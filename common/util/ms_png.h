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

/* Reads a PNG file as 8-bit RGB (any PNG colour type converted; alpha
 * composed on black) into *pixels (malloc'ed, height rows of 3 * width bytes,
 * top row first; the caller frees it). A picture wider than max_width or
 * taller than max_height is refused before its pixels are read
 * (MS_ERR_RANGE); a file libpng cannot read is MS_ERR_FORMAT (its message),
 * a missing one MS_ERR_IO. */
ms_status ms_png_read_rgb(const char *path, uint32_t max_width, uint32_t max_height,
                          uint8_t **pixels, uint32_t *width, uint32_t *height, ms_error *err);

/* ms_png_read_rgb for a PNG held in memory (size bytes; a picture a server
 * sent): the same limits and errors, MS_ERR_FORMAT for bytes that are not a
 * PNG libpng reads. */
ms_status ms_png_decode_rgb(const uint8_t *bytes, size_t size, uint32_t max_width,
                            uint32_t max_height, uint8_t **pixels, uint32_t *width,
                            uint32_t *height, ms_error *err);

#endif
