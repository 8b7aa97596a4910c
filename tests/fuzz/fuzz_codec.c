/* libFuzzer target `codec` (corpus tests/corpus/codec): the codec decoder on
 * arbitrary bytes. Header and chunk CRCs
 * are skipped (otherwise nearly every mutation stops at a checksum) so the
 * decoder's own validation is exercised; the stream is decoded to full
 * precision, coarsened to the middle level and exported. The first input byte
 * selects a p_min = 0 stream (start state implicit); other windows are rejected
 * by the decoder without a start state. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "ms_codec.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_codec_decoder_options opt = {.skip_crc = true};
    ms_codec_decoder *d = NULL;
    ms_error err;
    if (ms_codec_decoder_create(data, size, NULL, &opt, &d, &err) != MS_OK)
        return 0;
    unsigned top = ms_codec_decoder_available_level(d);
    if (ms_codec_decoder_set_level(d, top, &err) == MS_OK) {
        unsigned lo = ms_codec_decoder_min_level(d);
        unsigned mid = lo + (top - lo) / 2;
        if (ms_codec_decoder_set_level(d, mid, &err) == MS_OK) {
            ms_mesh m;
            memset(&m, 0, sizeof m);
            if (ms_codec_decoder_mesh(d, &m, &err) == MS_OK)
                ms_mesh_free(&m);
            ms_codec_state s;
            if (ms_codec_decoder_state(d, &s, &err) == MS_OK)
                ms_codec_state_free(&s);
            (void)ms_codec_decoder_set_level(d, top, &err);
        }
    }
    ms_codec_decoder_destroy(d);
    return 0;
}
