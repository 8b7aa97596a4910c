/* ms_png_write on libpng: the rows go through png_write_row one at a time (no
 * copy of the image), into DIR/NAME.partial renamed over the target on success.
 * libpng reports errors by longjmp; everything the jump could skip is kept in a
 * struct reachable after it (volatile where setjmp's rules ask for it). */
#include "ms_png.h"

#include <errno.h>
#include <png.h>
#include <setjmp.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct png_failure {
    char text[200];
} png_failure;

static void on_png_error(png_structp png, png_const_charp message)
{
    png_failure *failure = png_get_error_ptr(png);
    snprintf(failure->text, sizeof failure->text, "%s", message);
    png_longjmp(png, 1);
}

static void on_png_warning(png_structp png, png_const_charp message)
{
    (void)png, (void)message; /* warnings are not failures of the written file */
}

/* Writes the whole image to f; false with failure->text set on any libpng error. */
static bool write_image(FILE *f, const uint8_t *pixels, uint32_t width, uint32_t height,
                        int channels, bool compact, png_failure *failure)
{
    png_structp png =
        png_create_write_struct(PNG_LIBPNG_VER_STRING, failure, on_png_error, on_png_warning);
    if (!png) {
        snprintf(failure->text, sizeof failure->text, "cannot start libpng");
        return false;
    }
    png_infop info = png_create_info_struct(png);
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        snprintf(failure->text, sizeof failure->text, "cannot start libpng");
        return false;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return false;
    }
    png_init_io(png, f);
    png_set_IHDR(png, info, width, height, 8, channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, compact ? 9 : 6);
    /* Rows stored unfiltered: the inflated stream is the image itself, byte for
     * byte (what tests/test_png.c checks); screenshots stay small enough.
     * Compact: libpng's adaptive choice of filter per row. */
    png_set_filter(png, PNG_FILTER_TYPE_BASE, compact ? PNG_ALL_FILTERS : PNG_FILTER_NONE);
    png_write_info(png, info);
    size_t row_bytes = (size_t)width * (size_t)channels;
    for (uint32_t y = 0; y < height; ++y)
        png_write_row(png, pixels + (size_t)y * row_bytes);
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    return true;
}

static ms_status write_file(const char *path, const uint8_t *pixels, uint32_t width,
                            uint32_t height, int channels, bool compact, ms_error *err)
{
    if (width < 1 || width > 65535 || height < 1 || height > 65535 ||
        (channels != 1 && channels != 3))
        return ms_error_set(err, MS_ERR_ARG, "%s: bad PNG size %ux%u x%d", path, width, height,
                            channels);
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", tmp, strerror(errno));
    png_failure failure = {{0}};
    bool written = write_image(f, pixels, width, height, channels, compact, &failure);
    if (written && compact) /* served files: on disk before the rename, as archives */
        written = fflush(f) == 0 && fsync(fileno(f)) == 0;
    bool closed = fclose(f) == 0;
    if (!written || !closed || rename(tmp, path) != 0) {
        remove(tmp);
        return ms_error_set(err, MS_ERR_IO, "%s: write failed%s%s", path, failure.text[0] ? ": " : "",
                            failure.text);
    }
    return MS_OK;
}

ms_status ms_png_write(const char *path, const uint8_t *pixels, uint32_t width, uint32_t height,
                       int channels, ms_error *err)
{
    return write_file(path, pixels, width, height, channels, false, err);
}

ms_status ms_png_write_compact(const char *path, const uint8_t *pixels, uint32_t width,
                               uint32_t height, int channels, ms_error *err)
{
    return write_file(path, pixels, width, height, channels, true, err);
}

/* Reads the picture image began on (its header read when began), of the
 * file or memory named where, as 8-bit RGB. */
static ms_status finish_rgb(png_image *image, int began, const char *where, uint32_t max_width,
                            uint32_t max_height, uint8_t **pixels, uint32_t *width,
                            uint32_t *height, ms_error *err)
{
    ms_status st = MS_OK;
    if (!began) {
        st = ms_error_set(err, MS_ERR_FORMAT, "%s: %s", where, image->message);
    } else if (image->width > max_width || image->height > max_height) {
        st = ms_error_set(err, MS_ERR_RANGE, "%s: %ux%u pixels, at most %ux%u", where,
                          image->width, image->height, max_width, max_height);
    } else {
        image->format = PNG_FORMAT_RGB;
        uint8_t *buffer = malloc(PNG_IMAGE_SIZE(*image));
        if (!buffer)
            st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
        else if (!png_image_finish_read(image, NULL, buffer, 0, NULL))
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: %s", where, image->message);
        if (st == MS_OK) {
            *pixels = buffer;
            *width = image->width;
            *height = image->height;
        } else {
            free(buffer);
        }
    }
    png_image_free(image);
    return st;
}

ms_status ms_png_read_rgb(const char *path, uint32_t max_width, uint32_t max_height,
                          uint8_t **pixels, uint32_t *width, uint32_t *height, ms_error *err)
{
    *pixels = NULL;
    *width = *height = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    int began = png_image_begin_read_from_stdio(&image, f);
    ms_status st =
        finish_rgb(&image, began, path, max_width, max_height, pixels, width, height, err);
    fclose(f);
    return st;
}

ms_status ms_png_decode_rgb(const uint8_t *bytes, size_t size, uint32_t max_width,
                            uint32_t max_height, uint8_t **pixels, uint32_t *width,
                            uint32_t *height, ms_error *err)
{
    *pixels = NULL;
    *width = *height = 0;
    if (!bytes || size == 0)
        return ms_error_set(err, MS_ERR_FORMAT, "picture: no bytes");
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    int began = png_image_begin_read_from_memory(&image, bytes, size);
    return finish_rgb(&image, began, "picture", max_width, max_height, pixels, width, height,
                      err);
}
