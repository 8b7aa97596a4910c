/* Shared checks for the codec tests (include after cmocka.h). */
#ifndef MS_CODEC_CHECK_H
#define MS_CODEC_CHECK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_mesh.h"
#include "ms_quant.h"

typedef struct ms_codec_check_result {
    size_t vertices, triangles, bytes;
    ms_weld_report weld;
} ms_codec_check_result;

/* Quantises mesh at bits, encodes, decodes to full precision and asserts the
 * result equals the welded input (oriented). When level_step > 0, coarsens back
 * level by level and compares every level L with L % level_step == 0 (and the
 * first three) against the reference coarsener (unoriented), then refines again
 * and asserts the byte-identical canonical state. With twice, also asserts that
 * encoding twice gives identical bytes. */
void ms_codec_check_roundtrip_ex(const ms_mesh *mesh, unsigned bits, unsigned level_step,
                                 bool twice, ms_codec_check_result *res);
#define ms_codec_check_roundtrip(mesh, bits, step, res) \
    ms_codec_check_roundtrip_ex(mesh, bits, step, true, res)

/* A closed torus grid of nu x nv vertices (radii R, r), 2 nu nv triangles,
 * consistently oriented. */
void ms_test_torus(ms_mesh *m, unsigned nu, unsigned nv, double R, double r);

#endif
