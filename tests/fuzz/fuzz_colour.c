/* libFuzzer target `colour` (corpus tests/corpus/colour): the colour decoder
 * (common/codec/ms_colour.h, docs/COLOUR.md) on arbitrary bytes, driven by a
 * fixed geometry: a 12 x 8 torus quantised at 8 bits, whose complex gives the
 * cells and neighbours at every level (the seeds are that torus's colour
 * streams). Header and chunk CRCs are skipped so mutations reach the decoder's
 * own checks. The stream is decoded level by level to the last available one,
 * the colours read at each, then at a coarser level and at full precision.
 *
 * Besides the sanitizers, the target checks the decoder's contract and aborts
 * when it is broken: a refusal comes with a one-line message, the decoder
 * never passes its available level, and a stream accepted to its end gives
 * the full-precision cells colours whose alpha is 255 without alpha.
 *
 * tests/test_fuzz_replay.c includes this file to replay tests/corpus/colour/
 * in `make test`; it then calls ms_fuzz_colour_one() directly. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_codec.h"
#include "ms_colour.h"
#include "ms_quant.h"

#define MS_FUZZ_COLOUR_CHECK(cond)                                                             \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_colour: contract broken: %s (%s:%d)\n", #cond, __FILE__,     \
                    __LINE__);                                                                 \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* The torus (12 x 8 vertices, 8 bits): its full-precision complex and the
 * colours the seeds code (channel k of vertex i: i * (2k + 3) + 7k). */
static void ms_fuzz_colour_model(ms_codec_state *full, uint8_t **rgba)
{
    enum { NU = 12, NV = 8 };
    ms_mesh mesh;
    ms_error err;
    memset(&mesh, 0, sizeof mesh);
    MS_FUZZ_COLOUR_CHECK(ms_mesh_reserve(&mesh, NU * NV, 2 * NU * NV, &err) == MS_OK);
    MS_FUZZ_COLOUR_CHECK(ms_mesh_add_colours(&mesh, true, &err) == MS_OK);
    for (unsigned i = 0; i < NU; ++i)
        for (unsigned j = 0; j < NV; ++j) {
            double u = 2 * M_PI * i / NU, v = 2 * M_PI * j / NV;
            unsigned k = i * NV + j;
            mesh.positions[3 * k] = (1.0 + 0.4 * cos(v)) * cos(u);
            mesh.positions[3 * k + 1] = (1.0 + 0.4 * cos(v)) * sin(u);
            mesh.positions[3 * k + 2] = 0.4 * sin(v);
            for (unsigned c = 0; c < 4; ++c)
                mesh.colours[4 * k + c] = (uint8_t)(k * (2 * c + 3) + 7 * c);
            uint32_t a = k, b = ((i + 1) % NU) * NV + j, cc = ((i + 1) % NU) * NV + (j + 1) % NV,
                     d = i * NV + (j + 1) % NV;
            uint32_t *t = mesh.triangles + 6 * k;
            t[0] = a, t[1] = b, t[2] = cc, t[3] = a, t[4] = cc, t[5] = d;
        }
    mesh.vertex_count = NU * NV;
    mesh.triangle_count = 2 * NU * NV;
    ms_qmesh q;
    MS_FUZZ_COLOUR_CHECK(ms_quantise_mesh(&mesh, 8, &q, NULL, &err) == MS_OK);
    MS_FUZZ_COLOUR_CHECK(ms_colour_weld(&mesh, &q, rgba, &err) == MS_OK);
    MS_FUZZ_COLOUR_CHECK(ms_codec_state_from_qmesh(&q, full, &err) == MS_OK);
    ms_qmesh_free(&q);
    ms_mesh_free(&mesh);
}

static bool ms_fuzz_colour_one_line(const ms_error *err)
{
    return err->text[0] != '\0' && !strchr(err->text, '\n');
}

/* Returns true when the stream decoded to its last level. */
static bool ms_fuzz_colour_one(const uint8_t *data, size_t size)
{
    ms_codec_state full;
    uint8_t *rgba = NULL;
    ms_fuzz_colour_model(&full, &rgba);
    free(rgba);
    ms_colour_decoder_options opt = {.skip_crc = true};
    ms_colour_decoder *d = NULL;
    ms_error err;
    bool accepted = false;
    ms_status st = ms_colour_decoder_create(data, size, &opt, &d, &err);
    if (st != MS_OK) {
        MS_FUZZ_COLOUR_CHECK(d == NULL && ms_fuzz_colour_one_line(&err));
        ms_codec_state_free(&full);
        return false;
    }
    unsigned lo = ms_colour_decoder_min_level(d), top = ms_colour_decoder_available_level(d);
    uint8_t *got = malloc(4 * full.vertex_count);
    MS_FUZZ_COLOUR_CHECK(got != NULL);
    for (unsigned L = lo; L <= top && L <= full.level; ++L) {
        st = ms_colour_decoder_refine(d, &full, L, &err);
        if (st == MS_OK) {
            MS_FUZZ_COLOUR_CHECK(ms_colour_decoder_level(d) == L);
            st = ms_colour_decoder_colours(d, full.cells, full.vertex_count, full.level, got,
                                           &err);
        }
        if (st != MS_OK) {
            MS_FUZZ_COLOUR_CHECK(ms_fuzz_colour_one_line(&err));
            break;
        }
    }
    MS_FUZZ_COLOUR_CHECK(ms_colour_decoder_level(d) <= top);
    if (st == MS_OK && top < ms_colour_decoder_max_level(d) && top < full.level) {
        st = ms_colour_decoder_refine(d, &full, top + 1, &err);
        MS_FUZZ_COLOUR_CHECK(st != MS_OK && ms_fuzz_colour_one_line(&err));
        st = MS_ERR_FORMAT; /* not decoded to its end */
    }
    if (st == MS_OK && ms_colour_decoder_level(d) == full.level) {
        accepted = true;
        if (!ms_colour_decoder_header(d)->alpha)
            for (size_t i = 0; i < full.vertex_count; ++i)
                MS_FUZZ_COLOUR_CHECK(got[4 * i + 3] == 255);
        /* a coarser level by the rule, from the decoded one */
        unsigned mid = lo + (full.level - lo) / 2;
        uint64_t *cells = malloc(full.vertex_count * sizeof *cells);
        MS_FUZZ_COLOUR_CHECK(cells != NULL);
        size_t n = 0;
        for (size_t i = 0; i < full.vertex_count; ++i) {
            uint64_t p = full.cells[i] >> (full.level - mid);
            if (n == 0 || cells[n - 1] != p)
                cells[n++] = p;
        }
        MS_FUZZ_COLOUR_CHECK(ms_colour_decoder_colours(d, cells, n, mid, got, &err) == MS_OK);
        free(cells);
    }
    free(got);
    ms_colour_decoder_destroy(d);
    ms_codec_state_free(&full);
    return accepted;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_colour_one(data, size);
    return 0;
}
#endif
