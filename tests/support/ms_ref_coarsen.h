/* Independent reference for the codec tests: the image of a full-precision
 * complex at kd-level L (vertex -> key >> (3P - L); triangles mapped and
 * deduplicated; collapsed triangles and edges kept as maximal edges only when not
 * a face of a surviving triangle). Output: cells sorted, triangles with sorted
 * indices (orientation dropped), edges sorted; caller frees with
 * ms_codec_state_free. Aborts on allocation failure (test code). */
#ifndef MS_REF_COARSEN_H
#define MS_REF_COARSEN_H

#include "ms_codec.h"

void ms_ref_coarsen(const ms_codec_state *full, unsigned L, ms_codec_state *out);

#endif
