/* APO chunks for the CPU renderer: per nSP cell, the cell's cube and a validated
 * view of its chunk (or none), so that a hit on a triangle drawn by cell c can be
 * shaded with the normal the client's shader would read (docs/APO.md,
 * "Traversal"; the CPU oracle ms_apo_lookup).
 *
 * The normal at a world point x in cell c: the cell-local coordinate
 * (x - cube origin) / cube side (as float, per axis), looked up in c's chunk with
 * the set's depth cap and missing-child rule and the set's filter, as the
 * client's shader does (docs/RENDERER.md, "Filtering"):
 *   MS_STUDY_APO_FILTER_LINEAR (the default, meshview's --apo-filter linear):
 *       the depth is limited to the pixel's footprint depth
 *       (ms_apo_footprint_depth of the footprint in cell units, below) and the
 *       normal is ms_apo_lookup_filtered's 8-cell interpolation;
 *   MS_STUDY_APO_FILTER_NEAREST (--apo-filter nearest): the footprint depth,
 *       the plain lookup (ms_apo_lookup);
 *   MS_STUDY_APO_FILTER_NONE (--apo-filter none): the plain lookup down to the
 *       nearest leaf, no footprint (the study's rule before filtering).
 * The footprint in cell units is (float)(footprint / cube side), footprint the
 * width of one pixel at the point in world units (eye depth x 2 tan(fovy/2) /
 * viewport height): the client's eye depth x ms_render_apo_footprint_scale, to
 * a float's rounding. A cell without a chunk, or a lookup that finds nothing
 * (MS_APO_STOP_EMPTY), gives no normal: the renderer falls back to the
 * geometric one.
 *
 * Ownership: the set owns its chunks (adopted by ms_study_apo_put or inflated
 * from an archive). Thread-safety: read-only after it is filled; any number of
 * threads may look up at once.
 */
#ifndef MS_STUDY_APO_H
#define MS_STUDY_APO_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_apo_chunk.h"
#include "ms_apo_traverse.h"
#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_error.h"

typedef struct ms_study_apo ms_study_apo;

typedef enum ms_study_apo_filter {
    MS_STUDY_APO_FILTER_LINEAR = 0, /* footprint depth + 8-cell interpolation (the client's default) */
    MS_STUDY_APO_FILTER_NEAREST = 1, /* footprint depth, nearest texel */
    MS_STUDY_APO_FILTER_NONE = 2    /* nearest leaf, no footprint */
} ms_study_apo_filter;

/* An empty set for cell_count cells (none has a chunk yet). levels: every chunk
 * is read as if only its first `levels` levels had been received (what a client
 * that fetches that many levels shows), 0 for whole chunks. depth_cap:
 * UINT32_MAX for none (what the viewer's default does); rule: the missing-child
 * rule (the viewer's default is MS_APO_MISSING_STOP: a correction). The filter is
 * MS_STUDY_APO_FILTER_LINEAR until ms_study_apo_set_filter. */
ms_status ms_study_apo_new(uint32_t cell_count, uint32_t levels, uint32_t depth_cap, ms_apo_missing_rule rule,
                           ms_study_apo **set, ms_error *err);
void ms_study_apo_free(ms_study_apo *set);

/* Gives cell its cube (origin in world units, side > 0) and its chunk, whose
 * words the set adopts (*chunk is zeroed, also on error). Errors: MS_ERR_RANGE
 * for a cell out of range or a bad cube, the loader's errors for a bad chunk. */
ms_status ms_study_apo_put(ms_study_apo *set, uint32_t cell, const double origin[3], double side,
                           ms_apo_chunk *chunk, ms_error *err);

/* Every chunk of an archive file, whole (each CRC-checked and inflated), cubes
 * from the header and the cell records. MS_ERR_ARG on an index-only archive. */
ms_status ms_study_apo_from_archive(const ms_archive *archive, uint32_t levels, uint32_t depth_cap,
                                    ms_apo_missing_rule rule, ms_study_apo **set, ms_error *err);

/* Reads cell's chunk as if only its first `levels` levels had been received
 * (0: the whole chunk), as a client that fetched that prefix; nothing for a cell
 * without a chunk. MS_ERR_RANGE for a cell out of range. Not thread-safe against
 * lookups of the same set. */
ms_status ms_study_apo_set_levels(ms_study_apo *set, uint32_t cell, uint32_t levels, ms_error *err);

/* The lookup filter of every cell (above). Not thread-safe against lookups. */
void ms_study_apo_set_filter(ms_study_apo *set, ms_study_apo_filter filter);

/* Parses a filter's name as meshview's --apo-filter takes it: linear, nearest
 * or none; false for anything else. */
bool ms_study_apo_filter_parse(const char *name, ms_study_apo_filter *filter);

/* The cube of an archive cell (the header's box divided by n^level, at the
 * cell's position): origin in world units and side. */
void ms_study_cell_cube(const ms_archive_header *header, const ms_archive_cell *cell, double origin[3],
                        double *side);

/* The APO normal (unit, in world axes) at world point x of cell, seen by a
 * pixel `footprint` world units wide there (used by the LINEAR and NEAREST
 * filters; <= 0: no footprint limit), over `smooth`, the normal the renderer
 * draws there without APO (unit, the model's orientation): a chunk is a
 * correction of it (docs/APO.md), so where no texel lies the filter blends
 * it in as the client's shader does. False when the cell has no chunk or the
 * lookup finds no texel (the caller keeps its smooth normal). */
bool ms_study_apo_normal(const ms_study_apo *set, uint32_t cell, const double x[3], double footprint,
                         const double smooth[3], double normal[3]);

/* Cells holding a chunk. */
uint32_t ms_study_apo_chunk_count(const ms_study_apo *set);

#endif
