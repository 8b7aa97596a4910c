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

/* Which geometry-ahead settings a check encodes with: bit k for ahead k;
 * MS_CHECK_AHEAD_UNTIL for the default ahead stopping at half the bits. */
#define MS_CHECK_AHEAD_UNTIL (1u << (MS_CODEC_MAX_AHEAD + 1))
#define MS_CHECK_AHEAD_ALL (1u | 1u << 1 | 1u << 3 | 1u << MS_CODEC_MAX_AHEAD | MS_CHECK_AHEAD_UNTIL)
#define MS_CHECK_AHEAD_DEFAULT (1u << MS_CODEC_DEFAULT_AHEAD)
#define MS_CHECK_AHEAD_BOTH (1u | MS_CHECK_AHEAD_DEFAULT)

/* For each ahead setting in the mask `aheads`: quantises mesh at bits, encodes,
 * decodes to full precision and asserts the result equals the welded input
 * (oriented). When level_step > 0, coarsens back level by level and compares
 * every level L with L % level_step == 0 (and the first three) against the
 * reference coarsener (unoriented) and, with geometry ahead, each vertex's
 * drawn point against the barycentre of its descendants; then refines again
 * and asserts the byte-identical canonical state and points. With twice, also
 * asserts that encoding twice gives identical bytes. res: the last setting's. */
void ms_codec_check_roundtrip_ex(const ms_mesh *mesh, unsigned bits, unsigned level_step,
                                 bool twice, unsigned aheads, ms_codec_check_result *res);
#define ms_codec_check_roundtrip(mesh, bits, step, res) \
    ms_codec_check_roundtrip_ex(mesh, bits, step, true, MS_CHECK_AHEAD_ALL, res)

/* A closed torus grid of nu x nv vertices (radii R, r), 2 nu nv triangles,
 * consistently oriented. */
void ms_test_torus(ms_mesh *m, unsigned nu, unsigned nv, double R, double r);

#endif
