/* The client core's scheduler (internal to client/core; docs/CLIENT.md, "The
 * core's parts"): for one pass, what to ask for and in which order. A pure
 * function of a snapshot: the model's index (read only), the pass's camera,
 * frustum and tolerance, and per known cell what the view decoder holds of it
 * (state, target, precisions) and what has arrived (bytes received
 * contiguously per stream); it returns the wants, best first, the pass's cell
 * counts, and the index subtrees the cut needs. It owns nothing between
 * passes, takes no lock, touches no thread's state, and calls only the
 * index's and the camera's read-only functions, so it is tested on hand-made
 * snapshots (tests/test_core_sched.c). The decoder (ms_client_core_schedule.c)
 * builds the snapshot on the decode thread and applies the plan. */
#ifndef MS_CORE_SCHED_H
#define MS_CORE_SCHED_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_core_queue.h"

/* Decoded bytes a vertex is counted for (the budget's estimate). */
#define BYTES_PER_VERTEX 64.0

/* The camera of one pass, as selection and scheduling see it. */
typedef struct frame_view {
    ms_camera cam;
    ms_frustum frustum;
    double tolerance;
} frame_view;

/* One known cell as the view decoder and the reception buffers hold it. */
typedef struct ms_sched_cell {
    uint32_t id;
    uint8_t state;        /* ms_view_cell_state */
    uint8_t target;       /* ms_view_target: bits, MS_VIEW_TARGET_SPLIT or _HIDDEN */
    uint8_t bits;         /* shown precision (ms_view_bits) */
    uint8_t avail;        /* precision its bytes reach (ms_view_available_bits) */
    uint8_t parent_state; /* its parent's state (MS_VIEW_HIDDEN for the root) */
    bool cached;          /* hidden with payload bytes held (ms_view_held_bytes) */
    bool failed;          /* given up after a refetch */
    bool blocked;         /* would split, its children's records missing */
    uint64_t held;        /* for ms_sched_rank_evictions: the bytes it holds (payload,
                             reception buffers; with a decoder its decoded estimate) */
    uint32_t geo_end, apo_end, col_end; /* bytes received contiguously per stream */
    double error_bound;   /* shown and visible: ms_view_cell_error_bound (world
                             units, < 0 none); else unused */
} ms_sched_cell;

/* A subtree of the index the decoder holds or receives (an index by subtree). */
enum { MS_SCHED_SUBTREE_RECEIVING = 0, MS_SCHED_SUBTREE_HELD = 1, MS_SCHED_SUBTREE_FAILED = 2 };
typedef struct ms_sched_subtree {
    uint32_t id;
    uint8_t state;        /* MS_SCHED_SUBTREE_* */
    uint32_t end, total;  /* bytes received; stored size (0: not known) */
} ms_sched_subtree;

typedef struct ms_sched_input {
    const ms_archive *index;
    frame_view fv;
    double margin;            /* ms_core_options.frustum_margin */
    bool apo_on, colour_on;
    unsigned apo_levels;      /* ms_core_options.apo_levels */
    double apo_tolerance_px;  /* the detail tolerance (tolerance_px x the budget's factor) */
    unsigned preview_steps;   /* permitted geometry steps under a preview; 0 full access */
    unsigned root_goal_min;   /* the content bounds' floor on the root's goal (0 none) */
    const ms_sched_cell *cells; /* the known cells, ids ascending */
    size_t cell_count;
    /* with an index by subtree (by_subtree): the selection's report, and the
     * subtrees held or being received, ids ascending */
    bool by_subtree;
    const uint32_t *blocked, *near;
    size_t blocked_count, near_count;
    const ms_sched_subtree *subtrees;
    size_t subtree_count;
} ms_sched_input;

/* A subtree the cut needs: its id and the cell whose children it holds. */
typedef struct ms_sched_need {
    uint32_t id, parent;
} ms_sched_need;

typedef struct ms_sched_plan {
    want_list wl;             /* what is missing, best first */
    double worst;             /* largest screen error of a visible shown cell, px */
    uint32_t shown, split, cached, loading, failed;
    bool complete;            /* nothing missing for the targets, nothing failed */
    /* with an index by subtree: every subtree the cut needs but the root's
     * (held or not; in the order found, an id may repeat) */
    ms_sched_need *needs;
    size_t need_count, need_cap;
    bool out_of_memory;       /* a list could not grow: the plan is partial */
} ms_sched_plan;

/* The plan for the snapshot: fills *plan (zero it first; free with
 * ms_sched_plan_free, or take plan->wl and free the rest). */
void ms_sched_plan_make(const ms_sched_input *in, ms_sched_plan *plan);
void ms_sched_plan_free(ms_sched_plan *plan);

/* A cell the budget may evict (ms_client_core_budget.c): its usefulness
 * (the precision the camera would want of it; 64 bits less outside the
 * frustum), the bytes it holds, whether its cube meets the frustum. */
typedef struct ms_sched_candidate {
    uint32_t cell;
    double usefulness;
    uint64_t bytes;
    bool visible;
} ms_sched_candidate;

/* The eviction order: of the `n` cells given (hidden cells the view does not
 * target), those that hold bytes, least useful first (culled ones least),
 * into out (room for n); returns how many. The budget evicts from the front
 * as far as its figures say. */
size_t ms_sched_rank_evictions(const ms_archive *index, const frame_view *fv, double margin,
                               const ms_sched_cell *cells, size_t n, ms_sched_candidate *out);

/* The precision (real bits) the camera wants of cell; *visible tells whether
 * its cube meets the frustum (with margin). */
double ms_sched_cell_need(const ms_archive *index, const frame_view *fv, double margin,
                          uint32_t cell, bool *visible);
/* Whether cell's cube meets the frustum (with margin): the visible of
 * ms_sched_cell_need, without the need. */
bool ms_sched_cell_visible(const ms_archive *index, const frame_view *fv, double margin,
                           uint32_t cell);
/* The geometry goal of a shown cell for its target (bits_max for SPLIT and
 * HIDDEN, at most bits_max), at least root_goal_min for the root. */
unsigned ms_sched_goal(const ms_archive_cell *rec, uint32_t cell, uint8_t target,
                       unsigned root_goal_min);
/* The side of a cell's cube (world units) and the cube itself. */
double ms_sched_cell_side(const ms_archive_header *h, const ms_archive_cell *rec);
void ms_sched_cell_box(const ms_archive_header *h, const ms_archive_cell *rec, double lo[3],
                       double hi[3]);
/* Decoded bytes of a cell shown at `bits` (an estimate). */
double ms_sched_decoded_estimate(const ms_archive_cell *rec, unsigned bits);
/* A request priority (lower is sooner) clamped to the wire's 0..255. */
uint8_t ms_sched_clamp_priority(double p);

#endif
