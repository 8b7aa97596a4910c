/* The request sequence of one virtual client of the load generator: a camera
 * orbiting the model (seeded phase, zooming in and out), the cells it selects
 * each step (ms_view_select.h), and, per selected cell, the geometry steps it
 * still lacks (coarse first) and its APO chunk. Cells that leave the view are
 * evicted (as a client's cache would) and their requests should be cancelled,
 * so the demand never dries up and cancels happen as in real browsing.
 *
 * Ownership: the plan borrows the index (must outlive it) and owns its arrays.
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

typedef struct ms_loadgen_plan {
    const ms_archive *index;
    double phase, zoom_phase;
    uint64_t step;             /* camera steps taken */
    uint8_t max_geometry_step; /* permitted geometry steps - 1 */
    bool apo;                  /* request APO chunks */
    uint8_t *next_geometry;    /* per cell: first geometry step not yet requested */
    uint8_t *apo_requested;    /* per cell */
    uint8_t *selected;         /* per cell: in the current view */
    ms_view_cell *view, *spare; /* current and previous selection */
    size_t view_count, view_capacity, view_cursor;
    bool pass_produced;        /* the current pass over the view yielded a request */
} ms_loadgen_plan;

/* Also selects the first view (the costly part of a step). */
ms_status ms_loadgen_plan_init(ms_loadgen_plan *plan, const ms_archive *index, uint32_t seed,
                               uint8_t permitted_geometry_steps, bool apo, ms_error *err);
void ms_loadgen_plan_free(ms_loadgen_plan *plan);

/* The next request to make; moves the camera (at most max_moves steps) when
 * the current view is complete. Returns false when nothing is wanted. */
bool ms_loadgen_plan_next(ms_loadgen_plan *plan, ms_loadgen_item *item, unsigned max_moves);

/* Whether cell is still in view (false: cancel its requests). */
bool ms_loadgen_plan_wanted(const ms_loadgen_plan *plan, uint32_t cell);

/* A request ended without its bytes (error or cancel): ask again if in view. */
void ms_loadgen_plan_forget(ms_loadgen_plan *plan, const ms_loadgen_item *item);

/* Byte range [start, end) of an item in the index's streams (for HTTP Range). */
void ms_loadgen_item_range(const ms_archive *index, const ms_loadgen_item *item, uint32_t *start,
                           uint32_t *end);

#endif
