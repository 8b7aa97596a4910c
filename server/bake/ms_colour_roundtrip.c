/* The colour half of `meshcodec roundtrip` (ms_colour_roundtrip.h). */
#include "ms_colour_roundtrip.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

static double seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

ms_status ms_colour_roundtrip(const ms_qmesh *q, const uint8_t *rgba, bool alpha,
                              unsigned colour_bits, ms_colour_roundtrip_report *report,
                              ms_error *err)
{
    memset(report, 0, sizeof *report);
    unsigned c = colour_bits ? colour_bits : MS_COLOUR_DEFAULT_BITS;
    ms_codec_state full;
    ms_status st = ms_codec_state_from_qmesh(q, &full, err);
    if (st != MS_OK)
        return st;
    ms_colour_encode_params par = {.p_min = 0, .colour_bits = c, .alpha = alpha};
    uint8_t *buf = NULL, *got = NULL;
    size_t size = 0;
    double t0 = seconds();
    st = ms_colour_encode(&full, rgba, &par, &buf, &size, err);
    double t1 = seconds(), t2 = t1;
    ms_colour_decoder *d = NULL;
    if (st == MS_OK)
        st = ms_colour_decoder_create(buf, size, NULL, &d, err);
    if (st == MS_OK)
        st = ms_colour_decoder_refine(d, &full, full.level, err);
    if (st == MS_OK && !(got = malloc(4 * full.vertex_count)))
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    if (st == MS_OK)
        st = ms_colour_decoder_colours(d, full.cells, full.vertex_count, full.level, got, err);
    t2 = seconds();
    if (st == MS_OK) {
        report->bytes = size;
        report->encode_seconds = t1 - t0;
        report->decode_seconds = t2 - t1;
        report->lossless = true;
        for (size_t i = 0; i < full.vertex_count; ++i)
            for (unsigned k = 0; k < 4; ++k) {
                uint8_t want = k == 3 && !alpha ? 255 : ms_colour_widen(rgba[4 * i + k] >> (8 - c), c);
                if (got[4 * i + k] != want)
                    report->lossless = false;
            }
    }
    ms_colour_decoder_destroy(d);
    ms_codec_state_free(&full);
    free(buf);
    free(got);
    return st;
}
