/* The client core's parts and the state they share (internal to client/; the
 * API is ms_client_core.h). One ms_core, one mutex (`lock`), three threads:
 *
 *   ms_client_core.c           the caller's API: start, stop, camera, frames, figures
 *   ms_core_link.c             a connection shared by cores (ms_core_link): members
 *                              joining and leaving, the link's thread, its figures
 *   ms_client_core_net.c       the byte source from meshserve: the link's network
 *                              thread (connection, requests in flight for every
 *                              member, merged by priority, cancels, reconnects)
 *   ms_client_core_local.c     the byte source from a local archive (archive_path)
 *   ms_client_core_decode.c    the decode thread: reception, verification, the
 *                              view decoder, one pass of dec_step's named steps
 *   ms_client_core_schedule.c  what to ask for next and in which order (priorities)
 *   ms_client_core_budget.c    the memory budget: tolerance steps and eviction
 *   ms_client_core_frames.c    frames and figures published to the caller
 *
 * Fields are grouped by who may touch them: "shared" under lock, the others by
 * one thread only. */
#ifndef MS_CLIENT_CORE_INTERNAL_H
#define MS_CLIENT_CORE_INTERNAL_H

#include <event2/event.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_client.h"
#include "ms_client_core.h"
#include "ms_codec.h"
#include "ms_core_queue.h"
#include "ms_core_sched.h"
#include "ms_parallel.h"
#include "ms_view_refine.h"

#define MAX_SLOTS 512u
#define LATENCY_KEEP 65536u
#define NO_SLOT 0xFFFFFFFFu
#define SLOT_BUCKET_BITS 10u /* 1,024 chains for at most MAX_SLOTS slots */
#define MAX_TOLERANCE_FACTOR 4096.0
/* Bits the budget gives up on cells outside the view before it coarsens any
 * cell in it (added to culled_bits_less, CULLED_GIVE_UP_STEP at a time): at
 * the most every culled cell is at its coarsest and what the view no longer
 * sees merges into the cells that reach into it. */
#define MAX_CULLED_GIVE_UP 32.0
#define CULLED_GIVE_UP_STEP 4.0
/* A stored subtree's size before its first frame tells it (a window's guess:
 * the dragon's average is 1.5 KB, a 30,000-triangle demo's 0.9 KB) */
#define SUBTREE_BYTES_GUESS 2048u

/* A request in flight on the current connection, for member `member` of the
 * link. A finished request stays (done) until the member's decode thread has
 * taken its last chunk (last_seq), so that wants computed before that do not
 * ask for its bytes again. */
typedef struct slot {
    bool used, cancelled, keep, done;
    uint64_t last_seq;
    uint32_t id, cell, start, end, got;
    uint8_t stream, member;
    double sent_at;
    uint32_t next; /* next slot of the same chain (slot_buckets) */
} slot;

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


/* A core's place in a link: what the connection knows of it. The entry is
 * filled by ms_core_link_join (under the link's lock, state JOINING) and
 * otherwise the link thread's own. */
enum { MEMBER_FREE = 0, MEMBER_JOINING, MEMBER_ACTIVE, MEMBER_LEAVING };

typedef struct link_member {
    uint8_t state;              /* MEMBER_*: under the link's lock */
    bool seen;                  /* the link's thread took it in (and has not let go) */
    bool retired;               /* failed or stopping: its model closed, nothing sent */
    ms_core *core;              /* NULL once retired and left */
    uint32_t handle;            /* its model's handle on this connection (ready) */
    uint32_t open_request;      /* the OPEN_MODEL in flight, 0 none */
    bool ready;                 /* its model is open on this connection */
    bool opened_once;           /* its model opened once: content_id, by_subtree hold */
    uint64_t content_id;
    uint32_t cell_count;        /* the model's, from its index */
    bool by_subtree;            /* it opened with its index head */
    double down_since;          /* its model not open since (link time), < 0 open */
    want *wants;                /* a copy of its decode thread's wants */
    size_t want_count, want_cap;
    uint64_t want_serial;
    uint64_t consumed_seq;      /* chunks its decode thread had taken for `wants` */
} link_member;

struct ms_core_link {
    ms_core_link_options o;
    char *host, *token, *agent;
    double t0;
    uint64_t window;

    pthread_mutex_t lock;
    pthread_cond_t left;        /* a leaving member was retired */
    /* --- shared, under lock --- */
    bool stopping;
    link_member members[MS_CORE_LINK_MAX_MEMBERS];
    bool connected;
    uint64_t connections, socket_bytes, requests;

    pthread_t thread;
    bool started;

    /* --- the link's thread only --- */
    struct event_base *base;
    struct event *tick;
    ms_client *client;
    bool dead;                  /* the connection ended: freed on the next tick */
    char dead_why[256];
    double last_activity, reconnect_at, down_since, backoff;
    bool was_waiting;           /* at the last tick something was awaited */
    uint64_t last_read;         /* ms_client_bytes_read at the last tick */
    uint64_t in_flight;         /* bytes requested, not yet received, all members */
    uint64_t plans;             /* planning rounds that sent something */
    /* OPEN_MODELs of members that left before the answer: the handle it
     * brings is closed at once */
    uint32_t orphan_opens[MS_CORE_LINK_MAX_MEMBERS];
    unsigned orphan_count;
    slot slots[MAX_SLOTS];
    unsigned slots_used, slots_active;
    uint32_t slot_buckets[1u << SLOT_BUCKET_BITS]; /* chains by (member, cell, stream) */
};

struct ms_core {
    ms_core_options o;
    ms_core_budget *shared;     /* o.shared_budget: NULL, or shared with other cores */
    int member;                 /* this core's place in it; -1 none */
    char *model, *archive_path;
    double t0;

    pthread_mutex_t lock;
    pthread_cond_t wake;
    /* --- shared, under lock --- */
    bool stopping, fatal;
    ms_camera camera;
    bool have_camera;
    uint64_t camera_serial;
    unsigned section_count;     /* ms_core_set_sections */
    double sections[MS_SECTIONS_MAX][4];
    chunk_msg *inbox, *inbox_tail;
    ms_archive *index;          /* set once by the network thread */
    ms_core_opening opening;    /* with export_frames: the index at the first open */
    bool have_opening;
    bool index_new, republish;
    /* the grant of the latest MODEL_OPENED (PROTOCOL.md section 8): geometry
     * steps this reader may read; 0 until known, and in local mode (the file
     * holds everything) */
    uint8_t permitted_geometry_steps;
    bool colour_served;      /* the connection negotiated CAP_COLOUR (or a local archive) */
    want *wants;
    size_t want_count;
    uint64_t want_serial;
    uint64_t push_seq;          /* chunks pushed by the network thread */
    uint64_t want_consumed_seq; /* chunks the decode thread had taken for `wants` */
    ms_core_frame *frame;
    ms_core_stats stats;        /* decode thread's figures */
    int content;                /* CONTENT_*: written by the decode thread (under lock) */
    double content_lo[3], content_hi[3]; /* with CONTENT_KNOWN */
    /* network figures */
    bool connected, model_open;
    uint64_t bytes_received, bytes_in_flight, requests, cancels, reconnects;
    uint64_t bytes_queued; /* received payload bytes in the inbox, not yet taken by the
                              decode thread (the budget plans them as in flight) */
    double longest_outage; /* seconds, lost connection to model open again (under lock) */
    uint64_t geometry_bytes_received, apo_bytes_received;
    uint64_t socket_bytes;      /* read from every connection, frames and index included */
    double *latencies;
    size_t latency_count;

    pthread_t local_thread, dec_thread;
    bool local_started, dec_started, locked; /* locked: lock and wake initialised */
    /* the byte source from a server: a link (o.shared_link, or a private one);
     * NULL in local mode */
    ms_core_link *link;
    bool own_link;              /* the private link of a core started without one */
    bool joined;                /* a member of link */
    uint64_t window;            /* local mode: bytes handed over a round */

    /* --- decode thread only --- */
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
    ms_sched_cell *sched_cells; /* the scheduler's snapshot (ms_client_core_schedule.c) */
    size_t sched_cells_cap;
    ms_sched_subtree *sched_subtrees;
    size_t sched_subtrees_cap;
    ms_pool *pool;          /* decode helpers */
    ms_view_refine_jobs jobs; /* their job list (ms_view_refine_parallel), kept between passes */
};

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
/* The per-cell bookkeeping held: the view's blocks of cell state and the
 * core's dcell blocks, which cover the same sibling groups. */
uint64_t ms_core_state_bytes_held(const ms_core *c);

/* ---- ms_client_core_frames.c ---- */

/* With export_frames, before publishing a freshly opened index (not yet shared
 * with the decode thread): keeps its header and records for ms_core_wait_open.
 * Out of memory leaves the opening empty (ms_core_wait_open then says so). */
void ms_core_keep_opening(ms_core *c, const ms_archive *index, bool by_subtree);

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

/* ---- ms_client_core.c: shared helpers ---- */

/* A copy of s (NULL stays NULL); sets *fail when out of memory. */
char *ms_core_copy_text(const char *s, bool *fail);
/* Bytes in flight at most (a link's window, a local responder's hand-over):
 * window_bytes, or 0.25 s of the bandwidth, at least 64 KiB (1 MiB when
 * the bandwidth is unlimited). */
uint64_t ms_core_window(uint64_t window_bytes, double bandwidth);
/* Seconds since the core started (monotonic clock). */
double ms_core_since_start(const ms_core *c);
/* Records a fatal error once; the _locked form with the lock held. */
void ms_core_fail_locked(ms_core *c, const char *fmt, const char *text);
void ms_core_fail(ms_core *c, const char *fmt, const char *text);
/* Sets stats.warning (takes the lock). */
void ms_core_warn(ms_core *c, const char *text);
/* Queues a chunk for the decode thread (takes the lock); the queue owns it. */
void ms_core_push_chunk(ms_core *c, chunk_msg *m);

/* ---- byte sources ---- */

/* The link's thread (arg: the ms_core_link) and its periodic event (5 ms),
 * created with the event base. */
void *ms_core_net_main(void *arg);
void ms_core_net_tick(evutil_socket_t fd, short what, void *arg);
/* The merge of several want lists, each best first (a link's members'):
 * the list whose next want, lists[i][cursors[i]], is the most urgent (lowest
 * priority; of equals, the lowest i), or -1 when every list is exhausted.
 * NULL lists are skipped. */
int ms_core_merge_next(const want *const *lists, const size_t *counts, const size_t *cursors,
                       unsigned n);
/* Seconds since the link started. */
double ms_core_link_since_start(const ms_core_link *link);
/* The link's requests (ms_core_link_requests.c), all on the link's thread:
 * the core of slot s's member; whether member m is live (taken in, not failed
 * or stopping); the slot of request id (UINT32_MAX: none); ending slot k
 * (forgotten, its bytes out of the window), every slot of member i (i < 0:
 * of all), or slot k on its last chunk; whether a member's model is being
 * opened (no requests go out meanwhile); and one round of requests: the
 * members' wants merged by priority under the window, cancels of the
 * unwanted, REQUEST_CELLS sent. */
ms_core *ms_core_link_core_of(ms_core_link *l, const slot *s);
bool ms_core_link_live(const link_member *m);
uint32_t ms_core_link_slot_find(ms_core_link *l, uint32_t id);
void ms_core_link_end_slot(ms_core_link *l, uint32_t k);
void ms_core_link_end_slots(ms_core_link *l, int i);
void ms_core_link_finish_slot(ms_core_link *l, uint32_t k);
bool ms_core_link_opening(const ms_core_link *l);
void ms_core_link_fill(ms_core_link *l);
/* Drops the connection at the end of this turn, with why as the reason
 * (ms_client_core_net.c). */
void ms_core_link_mark_dead(ms_core_link *l, const char *why);
/* Makes c a member (state JOINING: the link's thread opens its model);
 * MS_ERR_ARG when the link is full. */
ms_status ms_core_link_join(ms_core_link *link, ms_core *c, ms_error *err);
/* Waits until the link's thread has retired c (its model closed, its
 * requests forgotten); the link no longer touches c after. */
void ms_core_link_leave(ms_core_link *link, ms_core *c);
/* The local responder's thread (arg: the ms_core). */
void *ms_core_local_main(void *arg);

/* ---- ms_client_core_decode.c ---- */

void *ms_core_decode_main(void *arg);
void ms_core_rx_free(rx *r);
/* Adds received bytes at offset; ignores what is already held or below base.
 * False when out of memory. */
bool ms_core_rx_add(rx *r, uint32_t offset, const uint8_t *data, uint32_t length);
/* The buffer's capacity once it holds bytes up to `end` (it grows by doubling,
 * so the budget plans the growth, not only the range's bytes). */
uint64_t ms_core_rx_cap_for(const rx *r, uint64_t end);
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
/* After the view moved: takes the bounds from the root once its bytes reach
 * root precision (or gives up on them), and publishes them. */
void ms_core_content_note(ms_core *c);

/* ---- ms_client_core_frames.c ---- */

/* Drops a cell's APO bytes: its reception buffer and the frames' copy (which
 * frames still holding it keep until they are freed). */
void ms_core_apo_drop(dcell *d);
/* Frees the previous frame's cell list (at ms_core_stop). */
void ms_core_frames_free(ms_core *c);

/* First display, the frame and the pass's wants and figures, published under
 * the lock; takes pass->wl. */
void ms_core_publish(ms_core *c, dec_pass *pass, uint64_t serial, double t_start);

#endif
