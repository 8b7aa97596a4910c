/* The request sequence of one virtual client of the load generator: a camera
 * orbiting the model (seeded phase, zooming in and out), the cells it selects
 * each step (ms_view_select.h), and, per selected cell, the geometry steps it
 * still lacks (coarse first) and its APO chunk. Cells that leave the view are
 * evicted (as a client's cache would) and their requests should be cancelled,
 * so the demand never dries up and cancels happen as in real browsing.
 *
 * Ownership: the plan borrows the index (must outlive it) and owns its arrays;
 * ms_loadgen_plan_new / ms_loadgen_plan_free.
 * Thread-safety: one plan per thread.
 */
#ifndef MS_LOADGEN_PLAN_H
#define MS_LOADGEN_PLAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_error.h"
#include "ms_view_select.h"

typedef struct ms_loadgen_item {
    uint32_t cell;
    uint8_t stream;    /* ms_proto_stream */
    uint8_t first, last; /* STEPS [first, last] */
    uint8_t priority;  /* lower is sooner */
} ms_loadgen_item;

typedef struct ms_loadgen_plan ms_loadgen_plan;

/* A new plan over index; also selects the first view (the costly part of a
 * step). On failure (MS_ERR_NOMEM) *plan is NULL. */
ms_status ms_loadgen_plan_new(const ms_archive *index, uint32_t seed,
                              uint8_t permitted_geometry_steps, bool apo, ms_loadgen_plan **plan,
                              ms_error *err);
/* Accepts NULL. */
void ms_loadgen_plan_free(ms_loadgen_plan *plan);

/* The next request to make; moves the camera (at most max_moves steps) when
 * the current view is complete. Returns false when nothing is wanted. */
bool ms_loadgen_plan_next(ms_loadgen_plan *plan, ms_loadgen_item *item, unsigned max_moves);

/* Whether cell is still in view (false: cancel its requests). */
bool ms_loadgen_plan_wanted(const ms_loadgen_plan *plan, uint32_t cell);

/* Camera steps taken so far (for pacing). */
uint64_t ms_loadgen_plan_steps(const ms_loadgen_plan *plan);

/* A request ended without its bytes (error or cancel): ask again if in view. */
void ms_loadgen_plan_forget(ms_loadgen_plan *plan, const ms_loadgen_item *item);

/* Byte range [start, end) of an item in the index's streams (for HTTP Range). */
void ms_loadgen_item_range(const ms_archive *index, const ms_loadgen_item *item, uint32_t *start,
                           uint32_t *end);

#endif
