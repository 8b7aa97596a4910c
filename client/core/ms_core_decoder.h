/* The client core's decoder part (internal to client/core; docs/CLIENT.md,
 * "The core's parts"): the decode thread's own state (ms_core_decoder, the
 * `dec` of ms_core) and the files that work on it, each pass in this order:
 *
 *   ms_client_core_decode.c    the thread and its pass (dec_step)
 *   ms_core_receive.c          received chunks verified and handed to the view
 *   ms_core_rx.c               reception buffers
 *   ms_client_core_cells.c     per-cell reception state (dcell), by sibling group
 *   ms_client_core_subtrees.c  an index that comes by subtree: taken, received,
 *                              kept or dropped as the scheduler's plan says
 *   ms_client_core_content.c   the model's content bounds
 *   ms_client_core_schedule.c  the scheduler's snapshot, its plan applied
 *                              (ms_core_sched.h is the scheduler itself)
 *   ms_client_core_budget.c    the memory budget: tolerance steps, eviction
 *   ms_client_core_frames.c    frames and the pass's figures published
 *   ms_core_bytes.c            bytes shared between a cell and frames
 *
 * It owns the view decoder (ms_view_decoder.h) and everything it holds (the
 * cells' decoders and caches), the reception buffers, the subtrees, the
 * budget's state and the previous frame's runs. Thread: the decode thread
 * (and its refine helpers inside ms_view_refine_parallel) only. It meets the
 * other parts through the core's shared state, under its lock: it takes the
 * inbox and the camera, publishes the want list, frames and figures. */
#ifndef MS_CORE_DECODER_H
#define MS_CORE_DECODER_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_client_core.h"
#include "ms_codec.h"
#include "ms_core_queue.h"
#include "ms_core_sched.h"
#include "ms_parallel.h"
#include "ms_view_refine.h"

#define MAX_TOLERANCE_FACTOR 4096.0
/* Bits the budget gives up on cells outside the view before it coarsens any
 * cell in it (added to culled_bits_less, CULLED_GIVE_UP_STEP at a time): at
 * the most every culled cell is at its coarsest and what the view no longer
 * sees merges into the cells that reach into it. */
#define MAX_CULLED_GIVE_UP 32.0
#define CULLED_GIVE_UP_STEP 4.0
/* How long the budget steps no finer than a tolerance whose cut went over the
 * ceiling (ms_core_decoder.too_fine_factor): longer than a view takes to
 * settle, so that it completes between two tries. */
#define TOO_FINE_SECONDS 5.0

/* Reception of one stream of one cell: the bytes from `base` (what the
 * consumer already took) onwards; out-of-order pieces as intervals. */
typedef struct rx {
    uint8_t *buf;       /* bytes [base, base + cap) */
    uint32_t base, cap;
    uint32_t end;       /* [base, end) received contiguously */
    uint32_t iv[8][2];  /* received pieces beyond end, absolute offsets */
    unsigned niv;
} rx;

typedef struct dcell {
    rx geo, apo;
    rx col;                  /* colour stream bytes (local mode; from 0: base stays 0) */
    uint32_t colour_given;   /* colour bytes handed to the view */
    ms_codec_header *header; /* parsed once the header arrived */
    uint32_t given;          /* geometry bytes handed to the view */
    uint32_t apo_given;      /* APO bytes complete (in apo.buf from 0: base stays 0) */
    ms_core_bytes *apo_shared; /* the frames' copy of apo_given's bytes (shared with
                                 the frames that show them), or NULL */
    uint32_t goal_bytes;     /* geometry prefix the current target needs */
    double handed_at;        /* last hand-over, seconds since start */
    uint8_t retries;
    bool failed, pending;    /* pending: verified bytes not yet handed over */
    bool blocked;            /* this pass: would split, its children's records missing */
} dcell;

/* A subtree of the index (an index that comes by subtree): being received,
 * held (its records known to the view), or failed twice. */
typedef struct subtree_entry {
    uint32_t id;
    uint32_t parent;        /* the cell whose children it holds (NONE: the root's) */
    uint8_t state;          /* SUBTREE_RECEIVING, _HELD, _FAILED */
    uint8_t retries;
    bool needed;            /* needed by this pass (scratch) */
    uint32_t total;         /* stored size once known, else 0 */
    rx buf;                 /* stored bytes while receiving */
} subtree_entry;

enum {
    SUBTREE_RECEIVING = MS_SCHED_SUBTREE_RECEIVING,
    SUBTREE_HELD = MS_SCHED_SUBTREE_HELD,
    SUBTREE_FAILED = MS_SCHED_SUBTREE_FAILED
};

/* The content bounds (ms_client_core_content.c): being worked out, known, or
 * not to be had (an empty model, a root that failed below root precision). */
enum { CONTENT_PENDING = 0, CONTENT_KNOWN = 1, CONTENT_NONE = 2 };

/* The decoder's state: the decode thread's only. */
typedef struct ms_core_decoder {
    ms_view *view;
    dcell **cell_groups;    /* per sibling group (as the view keeps them), NULL where
                               the view knows no record of the group */
    uint32_t group_size, group_count;
    bool by_subtree;        /* the index comes by subtree (c->index is partial) */
    unsigned subtree_levels;
    subtree_entry *subtrees; /* sorted by id */
    size_t subtree_count, subtree_cap;
    ms_view_select_report report; /* the pass's cells short of their children's records */
    unsigned preview_steps;   /* the pass's: permitted geometry steps under a public
                                 preview, 0 with full access (ms_view_select_params) */
    uint64_t index_bytes_held;  /* raw index bytes of the subtrees held */
    bool subtrees_changed;      /* a subtree came or went since the last pass's frame */
    double tolerance_factor, last_budget_step, last_blocked;
    double culled_give_up;    /* bits the budget takes off culled cells' need (on top
                                 of o.culled_bits_less), 0 .. MAX_CULLED_GIVE_UP */
    ms_view_select_report what_if_report; /* scratch of the budget's what-if selection */
    bool budget_floor_warned; /* the "budget too small" warning was given */
    /* The tolerance factor whose cut went over the ceiling (0: none) and until
     * when (ms_core_since_start) the budget steps no finer than it: its what-if
     * had said that cut would fit (it cannot see all of what a finer cut holds),
     * and stepping back and forth would keep the view from ever completing */
    double too_fine_factor, too_fine_until;
    uint64_t generation;
    /* the previous frame's drawing cells and their versions (ids ascending):
     * what the next frame's cells changed and removed are counted against */
    uint32_t *last_run_cell;
    uint64_t *last_run_version;
    size_t last_run_count, last_run_cap;
    uint64_t consumed_seq;
    bool first_display_seen;
    /* the caller's camera serial last looked at for a first display (a pass
     * that changes nothing still counts once for a new camera) */
    uint64_t display_checked_serial;
    bool display_checked;
    /* the last frame was made by a pass of the content camera: the caller's
     * next pass makes its own, whatever changed (its first display's frame) */
    bool frame_for_content;
    ms_sched_cell *sched_cells; /* the scheduler's snapshot (ms_client_core_schedule.c) */
    size_t sched_cells_cap;
    ms_sched_subtree *sched_subtrees;
    size_t sched_subtrees_cap;
    ms_pool *pool;          /* decode helpers */
    ms_view_refine_jobs jobs; /* their job list (ms_view_refine_parallel), kept between passes */
    ms_core_decode_work work; /* the passes' work, published with the figures */
} ms_core_decoder;

/* One decode pass (dec_step), carried from step to step. */
typedef struct dec_pass {
    const ms_camera *cam;
    frame_view fv;
    ms_view_select_params sp;
    double base_tol;          /* the tolerance before the budget's factor */
    double factor;            /* the budget's factor this pass selects at (fv.tolerance =
                                 base_tol x factor) */
    bool apo_on;
    bool colour_on;          /* colour streams wanted (a local archive with colour) */
    bool changed;             /* the view (or its APO bytes) changed in this pass */
    want_list wl;             /* what is missing, best first */
    double worst;             /* the largest screen error of a visible shown cell, px */
    uint32_t shown, split, cached, loading, failed;
    bool complete;
    bool for_content;         /* served the content bounds' camera, not the caller's */
    uint64_t memory;          /* the budget's measure after this pass's evictions */
    char warning[160];        /* a warning about this pass's figures ("" none): published
                                 with them, under one lock, so that no reader sees the
                                 warning beside figures it does not describe */
} dec_pass;

/* ---- ms_client_core_cells.c: the decode thread's per-cell state ---- */

/* A known cell's reception state, or NULL when the view does not know it. */
dcell *ms_core_dcell(const ms_core *c, uint32_t cell);
/* Makes room for `count` cells the view just learned: false when out of
 * memory. */
bool ms_core_dcells_grow(ms_core *c, const uint32_t *cells, size_t count);
/* Frees a cell's reception state (eviction, or its record forgotten). */
void ms_core_dcell_clear(dcell *d);
/* Frees the group blocks of `count` cells the view just forgot, where it
 * knows none of the group's cells any more. */
void ms_core_dcells_release(ms_core *c, const uint32_t *cells, size_t count);
void ms_core_dcells_free(ms_core *c);
/* Drops a cell's APO bytes: its reception buffer and the frames' copy (which
 * frames still holding it keep until they are freed). */
void ms_core_apo_drop(dcell *d);

/* ---- ms_core_bytes.c: bytes shared between a cell and frames ---- */

/* A copy of data with one hold; NULL when out of memory. */
ms_core_bytes *ms_core_bytes_copy(const uint8_t *data, size_t length);
ms_core_bytes *ms_core_bytes_retain(ms_core_bytes *b);
/* Lets go of one hold (NULL: nothing); the last frees. */
void ms_core_bytes_release(ms_core_bytes *b);
/* The bytes and their length. */
uint8_t *ms_core_bytes_data(ms_core_bytes *b, size_t *length);
/* The per-cell bookkeeping held: the view's blocks of cell state and the
 * core's dcell blocks, which cover the same sibling groups. */
uint64_t ms_core_state_bytes_held(const ms_core *c);

/* ---- ms_client_core_subtrees.c: an index that comes by subtree ---- */

/* The view over the index just opened (a whole one, or a head whose root
 * subtree it learns); false and err when that fails. */
bool ms_core_take_index(ms_core *c, ms_error *err);
/* A received chunk of a subtree's stored bytes (or a failed request). */
void ms_core_subtree_chunk(ms_core *c, const chunk_msg *m);
/* The subtrees held or being received, for the scheduler's snapshot (ids
 * ascending; NULL and 0 without an index by subtree). */
const ms_sched_subtree *ms_core_subtrees_snapshot(ms_core *c, size_t *count);
/* After the schedule: keeps the root's subtree and those the plan needs
 * (missing ones start being received), drops the others with their cells'
 * bytes; sets pass->complete false while one failed. */
void ms_core_subtrees_keep(ms_core *c, dec_pass *pass, const ms_sched_need *needs, size_t count);
void ms_core_subtrees_free(ms_core *c);

/* ---- ms_client_core_decode.c: the decode thread ---- */

void *ms_core_decode_main(void *arg);
/* The decoder's state at start (its refine helpers: `helpers` threads) and
 * its end, once the decode thread has ended (every part of it freed). */
ms_status ms_core_decoder_init(ms_core *c, unsigned helpers, ms_error *err);
void ms_core_decoder_free(ms_core *c);

/* ---- ms_core_rx.c: reception buffers ---- */

void ms_core_rx_free(rx *r);
/* Adds received bytes at offset; ignores what is already held or below base.
 * False when out of memory. */
bool ms_core_rx_add(rx *r, uint32_t offset, const uint8_t *data, uint32_t length);
/* The buffer's capacity once it holds bytes up to `end` (it grows by doubling,
 * so the budget plans the growth, not only the range's bytes). */
uint64_t ms_core_rx_cap_for(const rx *r, uint64_t end);
/* Forgets what was received beyond `keep` (>= base). */
void ms_core_rx_cut(rx *r, uint32_t keep);
/* Drops bytes below `upto` from the buffer (the consumer took them). */
void ms_core_rx_consume(rx *r, uint32_t upto);

/* ---- ms_core_receive.c: reception and verification (decode thread) ---- */

/* Received chunks into their cells' buffers, verified and handed to the view
 * (frees them); true when new APO or colour bytes changed the frame. */
bool ms_core_take_chunks(ms_core *c, chunk_msg *chunks);
/* Hands the newly received, verified geometry bytes of cell to the view (in
 * few steps: see the function). */
void ms_core_hand_over(ms_core *c, uint32_t cell);

/* ---- ms_client_core_schedule.c: the scheduler's snapshot and plan ---- */

/* The precision (real bits) the camera wants of cell; *visible tells whether
 * its cube meets the frustum (ms_sched_cell_need with the core's margin). */
double ms_core_cell_need(const ms_core *c, const frame_view *fv, uint32_t cell, bool *visible);
/* Fills pass->wl (sorted, best first) and the pass's cell counts from the
 * scheduler's plan, and keeps the subtrees it needs. */
void ms_core_schedule(ms_core *c, dec_pass *pass);
void ms_core_schedule_free(ms_core *c);

/* ---- ms_client_core_budget.c ---- */

/* Hard ceiling after the pass's selection: evicts, then coarsens at once;
 * false when decoding failed (the core is then fatal). */
bool ms_core_budget_ceiling(ms_core *c, dec_pass *pass);
/* A shared budget's membership (ms_client_core.h): join gives a place or
 * MS_ERR_ARG when full. */
ms_status ms_core_budget_join(ms_core_budget *budget, int *member, ms_error *err);
void ms_core_budget_leave(ms_core_budget *budget, int member);
/* Takes the shared tolerance factor and culled give-up into the core (decode
 * thread, pass start). */
void ms_core_budget_sync(ms_core *c);
/* Measures memory into pass->memory; with a budget, steps the tolerance,
 * evicts, and cuts pass->wl where loading would cross the ceiling. */
void ms_core_budget_step(ms_core *c, dec_pass *pass);

/* ---- ms_client_core_content.c: the content bounds (decode thread) ---- */

/* While the bounds are pending and the root is known: the camera of a pass
 * before the caller's first (one pixel seeing the model's cube; it asks for
 * the root's bytes and nothing more); else false. */
bool ms_core_content_camera(const ms_core *c, ms_camera *camera);
/* The precision whose bytes shown cell `cell` wants, given the selection's
 * goal: for the root while the bounds are pending, at least root precision. */
unsigned ms_core_content_goal(const ms_core *c, uint32_t cell, unsigned goal);
/* Whether w is one the bounds wait for (the root's geometry while they are
 * pending): the budget lets it through. */
bool ms_core_content_want(const ms_core *c, const want *w);
/* After a pass: takes the bounds from the root once its bytes reach root
 * precision (or gives up on them), and publishes them. From a root shown at
 * root precision or finer at once; from one shown coarser only when `now`
 * (the content camera's pass, or the caller's view complete): while the view
 * still streams, the selection usually takes the root there itself, and
 * decoding it there and back for the bounds would decode it twice. A pass
 * of the content camera (for_content) leaves the root there for the caller's
 * first selection. */
void ms_core_content_note(ms_core *c, bool now, bool for_content);

/* ---- ms_client_core_frames.c ---- */

/* Frees the previous frame's cell list (at ms_core_stop). */
void ms_core_frames_free(ms_core *c);

/* First display, the frame and the pass's wants and figures, published under
 * the lock; takes pass->wl. */
void ms_core_publish(ms_core *c, dec_pass *pass, uint64_t serial, double t_start);

#endif
