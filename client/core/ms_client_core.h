/* The client core: everything a meshstream viewer does except drawing.
 *
 * One ms_core streams one model from meshserve's binary door
 * (protocol/PROTOCOL.md) for a camera the caller moves:
 *
 *   - a network thread (libevent; the thread of the core's link: a private
 *     one, or ms_core_link shared with the other models of a scene) keeps the
 *     connection, reconnecting with
 *     backoff after a drop and resuming partly received ranges with BYTES
 *     requests (PROTOCOL.md section 10); it sends the requests the decode
 *     thread asks for, cancels those no longer wanted, throttles its reads to
 *     the configured bandwidth, and gives up on a server that does not answer;
 *   - a decode thread (with decode_threads - 1 helpers that refine distinct
 *     cells in parallel) owns the view-dependent decoder (ms_view_decoder.h): it
 *     takes the latest camera, selects cells by frustum and projected screen
 *     error with hysteresis, verifies received bytes (the codec header against
 *     the index, each precision bit against its chunk CRC, a whole APO chunk
 *     against its CRC; a corrupt range is fetched once more, then the cell is
 *     reported failed), decodes, decides what to ask for next and in which
 *     order, keeps memory within budget, and publishes frames;
 *   - the caller's thread (the one that draws) only sets the camera, takes
 *     frames and reads statistics: none of these block on decoding or I/O
 *     (they take a mutex held for a copy or a pointer swap).
 *
 * Local mode (archive_path set: a kiosk, offline): the network thread is
 * replaced by a local responder that maps the archive and hands the decode
 * thread the byte ranges of its want list, best first, at most window_bytes
 * before the decode thread takes them and plans again; everything else (the
 * index, verification, selection, budget, frames, statistics) is the same code.
 * A missing, truncated or malformed archive stops the core with stats.error
 * (one line naming the file); a corrupt payload is handled as a corrupt range
 * from the network (fetched again once, then the cell is reported failed).
 *
 * Request order. For every shown cell below its target, each missing precision
 * bit is one request, with priority 128 - 8 * (need - bit) for cells in the
 * frustum (need = the real-valued precision the camera asks for), 64 later for
 * culled ones: the bit that removes the most on-screen error goes first, and
 * every visible cell gets its first bits before any gets its last. The
 * children of a cell about to split fetch theirs 16 later, while it finishes.
 * At most `window_bytes` are in flight, so priorities follow the camera.
 *
 * Memory budget. memory = payload bytes held (decoder and reception buffers)
 * + an estimate of decoded complexes (64 bytes per vertex). Above
 * memory_target the screen tolerance is raised by half a bit every 100 ms (up
 * to 4096x), and it comes back down below 0.7 x target; hidden cells (those an
 * ancestor stands for) are evicted least useful first (usefulness = the
 * precision the camera would want of them; culled cells least). Loading
 * continues while memory + bytes in flight stay below memory_ceiling; a new
 * range that would cross it may evict only cells at least one bit less
 * useful than the cell it loads; when loading is blocked so, the tolerance
 * rises as over the target, so loading never stalls. A pass that ends above
 * the ceiling evicts what the view does not need, then coarsens at once.
 * Cells in the cut (the root, every shown cell and the split cells above
 * them) are never evicted. docs/CLIENT.md has the details.
 *
 * Two tolerances. tolerance_px is the geometric screen tolerance; with APO on
 * (apo_levels > 0 on a model that has APO chunks) geometry refines only to
 * apo_geometry_tolerance_px in the cells that carry a chunk (a cell baked
 * without one, such as every leaf, whose geometry renders the input, still
 * refines to tolerance_px) and tolerance_px is the detail tolerance: each
 * visible shown cell's APO chunk is fetched by footprint, down to the level
 * whose texel projects to tolerance_px (ms_apo_footprint_levels, ms_camera.h,
 * at the cell's nearest point; raised with the budget's tolerance), at most
 * apo_levels levels and no deeper; a cell about to split fetches none (its
 * children replace it). The chunk prefixes held are handed over in frames.
 *
 * Ownership: the core copies its options' strings. A frame returned by
 * ms_core_take_frame belongs to the caller (ms_core_frame_free).
 * Errors: ms_status with one line; a core that cannot go on (server gone for
 * longer than give_up_seconds, model changed, out of memory) keeps its last
 * state and reports the error in ms_core_stats (error[0] != 0).
 * Thread-safety: every function may be called from any one thread (typically
 * the drawing thread), and ms_core_set_camera / ms_core_take_frame /
 * ms_core_stats concurrently with each other; ms_core_stop must not race
 * with the others.
 */
#ifndef MS_CLIENT_CORE_H
#define MS_CLIENT_CORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_camera.h"
#include "ms_error.h"
#include "ms_view_decoder.h"

typedef struct ms_core ms_core;

/* One memory budget shared by several cores (the models of a scene): the cores
 * charge what they hold against one target and ceiling, follow one screen
 * tolerance factor (so every model is refined by the same screen-error rule),
 * and when the budget is exceeded the cells evicted first are the least useful
 * (smallest projected error, culled ones least) across all the cores sharing
 * it: near pieces refine first, far ones stay coarse. A core evicts only its
 * own cells (decode thread only); it evicts one when it holds the least useful
 * candidate of all the members, or when another member is refused a range at
 * least one bit more useful (docs/CLIENT.md, "A shared budget").
 * Ownership: the caller's; it must outlive every core started with it.
 * Thread-safety: every function, and the cores' threads, may use it
 * concurrently (one mutex). */
typedef struct ms_core_budget ms_core_budget;

/* Most cores one budget can serve. */
#define MS_CORE_BUDGET_MAX_MEMBERS 64

/* The geometry tolerance below which a front end fetches no APO
 * (ms_core_options.apo_min_tolerance_px), pixels: on the dragon's overview
 * the chunks add 35 % to the bytes of the 1 px cut and 0.0 dB to its picture,
 * and from 2 px on they give the picture a smooth cut needs 1.14 to 2.6
 * times the triangles for (docs/ACCURACY.md, "Where APO pays"). */
#define MS_CORE_APO_MIN_TOLERANCE_DEFAULT 2.0

/* target, ceiling: bytes (ceiling 0 = target + target / 4; target > 0 and
 * ceiling >= target else MS_ERR_ARG). MS_ERR_NOMEM. */
ms_status ms_core_budget_new(uint64_t memory_target, uint64_t memory_ceiling,
                             ms_core_budget **budget, ms_error *err);
/* NULL is a no-op; every core using it must be stopped first. */
void ms_core_budget_free(ms_core_budget *budget);
/* The memory the members hold now (their last passes' measures), and the
 * largest such sum seen, bytes. */
uint64_t ms_core_budget_held(ms_core_budget *budget);
uint64_t ms_core_budget_peak(ms_core_budget *budget);

/* One connection to meshserve shared by several cores (the models of a
 * scene): the link owns the one network thread, its event loop and the one
 * ms_client connection, with everything that belongs to a connection: the
 * requests in flight (at most window_bytes for all the members together), the
 * bandwidth throttle, reconnecting with backoff and resuming with BYTES
 * requests (PROTOCOL.md section 10), the answer time-out and giving up. Each
 * member core opens its model on it (one OPEN_MODEL handle each, PROTOCOL.md
 * 4.6) and keeps its own decode thread, index, want list and inbox; chunks
 * and OPEN answers go to the member by model handle. The members' want lists
 * are merged by priority (lower first; equal priorities in the order the
 * members joined) under the one window, so the bytes that remove the most
 * screen error go first whichever model they belong to (priorities are
 * comparable: every member follows the same screen-error rule, the more so
 * with a shared budget). A reconnect reopens every member's model and
 * resumes. A member that stops (ms_core_stop) or fails has its model closed
 * on the server (CLOSE_MODEL: its requests are cancelled there) while the
 * others go on. A core started without a link makes a private one: a single
 * core is a link of one. docs/CLIENT.md, "One connection for many models".
 * Ownership: the caller's; it must outlive every core started with it.
 * Thread-safety: ms_core_start / ms_core_stop of its members and
 * ms_core_link_get_stats may be called from any threads concurrently;
 * ms_core_link_free must not race with them. */
typedef struct ms_core_link ms_core_link;

/* Most cores one link serves (meshserve opens at most 64 models a connection). */
#define MS_CORE_LINK_MAX_MEMBERS 64

/* Test hook: called on the link's thread for every range it requests, in the
 * order sent (`plan` counts the link's planning rounds: one round's requests
 * are sent together, after the previous round's). */
typedef void (*ms_core_link_request_hook)(const ms_core *member, uint32_t cell, unsigned stream,
                                          uint8_t priority, uint64_t plan, void *arg);

typedef struct ms_core_link_options {
    const char *host;          /* numeric IPv4/IPv6 address */
    uint16_t port;
    const char *token;         /* NULL: none (preview access) */
    const char *agent;         /* NULL: "meshstream-client" */
    double bandwidth;          /* bytes per second read from the server, for all the
                                  members together; 0 = unlimited */
    uint64_t window_bytes;     /* bytes in flight at most, all members together; 0 = 0.25 s
                                  of bandwidth, at least 64 KiB (1 MiB when unlimited) */
    double answer_timeout;     /* seconds without a byte while waiting; 0 = 5 */
    double give_up_seconds;    /* reconnecting this long without success fails every
                                  member; 0 = 30 */
    bool raw_index;            /* ask for model indexes uncompressed (no CAP_INDEX_ZLIB) */
    bool whole_index;          /* do not offer CAP_INDEX_SUBTREES (ms_core_options) */
    ms_core_link_request_hook request_hook;
    void *request_hook_arg;
} ms_core_link_options;

/* Starts the link's thread; it connects once a member joins. The options'
 * strings are copied. MS_ERR_ARG for a bad host, port or figure (no host,
 * port 0, a negative or non-finite bandwidth or time-out), MS_ERR_NOMEM,
 * MS_ERR_IO when the thread cannot start. */
ms_status ms_core_link_new(const ms_core_link_options *options, ms_core_link **link,
                           ms_error *err);
/* Stops the thread and closes the connection. NULL is a no-op; every core
 * using it must be stopped first. */
void ms_core_link_free(ms_core_link *link);

typedef struct ms_core_link_stats {
    bool connected;            /* a connection is up (its HELLO may still be on its way) */
    unsigned members;          /* cores using the link now */
    uint64_t connections;      /* TCP connections made so far (1 + reconnections) */
    uint64_t socket_bytes;     /* read from every connection, frames and indexes included */
    uint64_t requests;         /* ranges requested, all members */
} ms_core_link_stats;

void ms_core_link_get_stats(ms_core_link *link, ms_core_link_stats *stats);

/* Test hook (fault injection): sees, and may alter, every received payload
 * chunk on the decode thread before it is checked. */
typedef void (*ms_core_payload_filter)(uint32_t cell, bool apo, uint32_t offset, uint8_t *data,
                                       size_t length, void *arg);
/* The same for the stored bytes of a subtree of the index (by subtree id). */
typedef void (*ms_core_index_filter)(uint32_t subtree, uint32_t offset, uint8_t *data,
                                     size_t length, void *arg);

/* Test hook: sees every cell the memory budget evicts (its bytes, or the APO
 * chunk of a shown cell outside the view), in the order evicted,
 * on the decode thread: whether its cube meets the pass's frustum (grown by
 * frustum_margin), and the budget's tolerance factor (1: no cell in view
 * coarsened for memory) and culled give-up (bits taken off the cells outside
 * the view) at that moment. */
typedef void (*ms_core_eviction_hook)(uint32_t cell, bool in_view, double tolerance_factor,
                                      double culled_give_up, void *arg);

typedef struct ms_core_options {
    const char *host;          /* numeric IPv4/IPv6 address */
    uint16_t port;
    const char *model;         /* the model's name (optional with archive_path) */
    const char *archive_path;  /* NULL: stream from host:port. Else the path of a local
                                  archive file (DIR/NAME.msa, ms_catalog.h): host, port,
                                  token, raw_index and the time-outs are ignored and
                                  no network is used; the same decode, selection,
                                  verification, budget and frames run on the byte
                                  ranges a local responder hands over from the mapped
                                  file (at most window_bytes a pass, in request order,
                                  throttled to `bandwidth` when set) */
    const char *token;         /* NULL: none (preview access) */
    const char *agent;         /* NULL: "meshstream-client" */
    double tolerance_px;       /* geometric screen tolerance, pixels; 0 = 1 */
    double hysteresis_bits;    /* ms_select_bits hysteresis; < 0 = MS_SELECT_HYSTERESIS_DEFAULT (0 is exact) */
    double culled_bits_less;   /* culled cells' need is lowered by this; 0 = 6 (64x the
                                  error outside the view) */
    double frustum_margin;     /* world units; 0 = none */
    unsigned apo_levels;       /* APO on when > 0: the most levels of a chunk fetched
                                  (MS_ARCHIVE_MAX_APO_LEVELS: no cap but the chunk's);
                                  0 = APO off */
    double apo_geometry_tolerance_px; /* geometry tolerance with APO on; 0 = tolerance_px
                                         (docs/ACCURACY.md: coarser costs more than it saves) */
    double apo_min_tolerance_px; /* APO fetched only while the geometry tolerance of the
                                    cells with a chunk (apo_geometry_tolerance_px times the
                                    budget's factor) is at least this: APO saves triangles
                                    where geometry is coarse and adds bytes and nothing
                                    else where it is fine (docs/ACCURACY.md, "Where APO
                                    pays"); 0 = at any tolerance. The front ends' default:
                                    MS_CORE_APO_MIN_TOLERANCE_DEFAULT */
    uint64_t memory_target, memory_ceiling; /* bytes; 0 = no budget */
    ms_core_link *shared_link; /* NULL: the core's own connection (host, port, token,
                                  agent, bandwidth, window_bytes, the time-outs, raw_index,
                                  whole_index). Else its model is streamed over this link
                                  shared with other cores (those fields must then be
                                  0/NULL/false: the link's options hold them; no
                                  archive_path; MS_ERR_ARG when it already serves
                                  MS_CORE_LINK_MAX_MEMBERS cores) */
    ms_core_budget *shared_budget; /* NULL: the core's own budget (memory_target/ceiling).
                                  Else one shared with other cores (memory_target and
                                  memory_ceiling must be 0; MS_ERR_ARG when it already
                                  serves MS_CORE_BUDGET_MAX_MEMBERS cores) */
    double bandwidth;          /* bytes per second read from the server; 0 = unlimited */
    uint64_t window_bytes;     /* bytes in flight at most; 0 = 0.25 s of bandwidth,
                                  at least 64 KiB (1 MiB when unlimited) */
    double answer_timeout;     /* seconds without a byte while waiting; 0 = 5 */
    double give_up_seconds;    /* reconnecting this long without success ends; 0 = 30 */
    unsigned decode_threads;   /* decoding threads in all (the decode thread and its
                                  helpers); 0 = 2 */
    bool export_frames;        /* stitch a frame after each change (for drawing/tests) */
    bool raw_index;            /* ask for the model index uncompressed (no CAP_INDEX_ZLIB) */
    bool whole_index;          /* take the whole index at open, as before subtrees: do not
                                  offer CAP_INDEX_SUBTREES (local mode: do not read the
                                  archive's index by subtree) */
    ms_core_payload_filter payload_filter;
    ms_core_index_filter index_filter; /* takes payload_filter_arg too */
    void *payload_filter_arg;
    ms_core_eviction_hook eviction_hook;
    void *eviction_hook_arg;
} ms_core_options;

/* Starts the threads and connects; returns at once (the camera may be set
 * before the model is open). MS_ERR_ARG for bad options, MS_ERR_NOMEM, or
 * MS_ERR_IO when a thread cannot start. */
ms_status ms_core_start(const ms_core_options *options, ms_core **core, ms_error *err);

/* What the model's index said when it opened: its header and the records the
 * index held then, ids ascending (records[i] is cell ids[i]'s). With an index
 * by subtree that is the head (the root subtree: the top levels of the tree,
 * whatever the model's size); with a whole index (a version-2 server,
 * whole_index) every cell.
 *
 * And the box the model's geometry occupies (content_lo / _hi, world units),
 * from its first decoded cell: the grid cells that the root's vertices at
 * root precision stand for (ms_view_cell_bounds). Every vertex of the model
 * lies in it, and it is within one root quantum (box_side / 2^root_bits) of
 * their box on every side, whatever the index held: a viewer places, frames
 * and picks the model by it. The core fetches and decodes the root that far
 * as soon as the model opens, before the caller's first camera (a few
 * kilobytes it draws first anyway). content_known is false for an empty
 * model, a root that failed below root precision, or one that did not
 * decode within the wait. */
typedef struct ms_core_opening {
    ms_archive_header header;
    uint32_t *ids;
    ms_archive_cell *records;
    size_t count;
    bool by_subtree;           /* the records are the head's */
    bool content_known;
    double content_lo[3], content_hi[3];
} ms_core_opening;

/* Waits at most timeout_s seconds (> 0) for the model to open and its content
 * bounds to be known, and copies what its index said and the bounds (the
 * core keeps them from the first open). Without export_frames (meshload) only
 * the header, by_subtree and the bounds: count 0, no records (a whole index
 * would be copied for nothing). MS_ERR_IO with the
 * core's error when it stopped first, or "no answer in time" when the index
 * did not come; the index without the bounds in time is MS_OK with
 * content_known false. MS_ERR_ARG without a time-out; MS_ERR_NOMEM. Free
 * with ms_core_opening_free (safe on a zeroed value). Call from the caller's
 * thread; it does not disturb the others. */
ms_status ms_core_wait_open(ms_core *core, double timeout_s, ms_core_opening *opening, ms_error *err);
void ms_core_opening_free(ms_core_opening *opening);

/* Stops the threads, closes the connection and frees everything. NULL is a no-op. */
void ms_core_stop(ms_core *core);

/* The camera to serve from now on (copied). */
void ms_core_set_camera(ms_core *core, const ms_camera *camera);

/* The section planes of the view from now on (copied; count 0: none; docs/
 * VIEWER.md, "Sections"): each a b c d cuts away the side a x + b y + c z + d
 * > 0 (model coordinates). A cell wholly cut away counts as outside the
 * frustum: requested coarser and after the cells seen (as a culled cell,
 * ms_view_select_params.section_count). MS_ERR_ARG, nothing changed, for more
 * than MS_SECTIONS_MAX planes, a zero normal or a number not finite. */
ms_status ms_core_set_sections(ms_core *core, const double (*planes)[4], size_t count, ms_error *err);

/* Bytes shared between frames, reference-counted (opaque): a frame's APO
 * chunk that did not change since the previous frame points at the same
 * bytes, never copied again (docs/CLIENT.md, "Frames"). */
typedef struct ms_core_bytes ms_core_bytes;

typedef struct ms_core_apo_chunk {
    uint32_t cell;
    unsigned levels;          /* complete octree levels in data */
    uint8_t *data;            /* the chunk's prefix, as stored (compressed per ARCHIVE.md);
                                 read only when shared is set */
    size_t length;
    ms_core_bytes *shared;    /* the shared bytes data points into (a core's frame;
                                 ms_core_frame_free releases them), or NULL: data is
                                 the caller's own */
} ms_core_apo_chunk;

/* Where the decode thread's work went, summed over its passes (docs/CLIENT.md,
 * "Decoding on every core"): CPU time per thread (CLOCK_THREAD_CPUTIME_ID,
 * seconds: what the work costs, which the machine's load changes little) and
 * exact counts. The waves of refine and split jobs (ms_view_refine.h) are
 * the part on the pool; everything else is the decode thread's alone. */
typedef struct ms_core_decode_work {
    uint64_t passes;
    /* the decode thread's CPU time by step of its passes */
    double take_cpu;      /* received chunks verified and handed over */
    double select_cpu;    /* ms_view_select */
    double refine_cpu;    /* the waves, as the decode thread spent them (its own jobs
                             and waiting for the pool's) */
    double apply_cpu;     /* ms_view_apply: merges, coarsening, what the waves left */
    double content_cpu;   /* the content bounds (the root decoded at root precision) */
    double plan_cpu;      /* budget, schedule and subtrees */
    double publish_cpu;   /* the frame and the figures */
    double jobs_cpu;      /* refine and split jobs, on every thread */
    double helper_cpu;    /* of jobs_cpu: on the pool's helpers */
    double jobs_span2_cpu; /* the least the waves take on two threads: per wave
                              max(longest job, half its jobs_cpu), summed */
    uint64_t waves, jobs, splits; /* pool loops, jobs run, of them splits */
    uint64_t jobs_on_helpers; /* jobs a helper ran */
    /* decode steps ms_view_apply did itself (serially) after the waves */
    uint64_t apply_refined, apply_splits;
} ms_core_decode_work;

/* What making a frame cost the core, and what changed in it against the
 * previous frame (docs/CLIENT.md, "Frames"). A cell's triangles are named by
 * its stitch version (ms_view_mesh.run_version): a cell changed is one new in
 * the frame or with another version; a cell removed drew in the previous frame
 * and draws nothing in this one. */
typedef struct ms_core_frame_work {
    uint64_t apo_bytes_copied;   /* APO bytes copied into this frame: the chunks new or
                                    grown since the previous frame, only */
    uint32_t apo_chunks_copied;  /* of apo_count: chunks copied (new or grown) */
    uint32_t apo_chunks_shared;  /* of apo_count: chunks shared with the previous frame */
    uint32_t cells_stitched;     /* shown cells whose triangles the stitch worked out again
                                    (ms_view_mesh.cells_stitched: the cells changed and the
                                    neighbours whose borders they touch; the others' kept) */
    uint64_t triangles_stitched; /* of the frame's triangles, those of cells_stitched */
    uint32_t cells_changed;      /* drawing cells new or with another version */
    uint32_t cells_removed;      /* cells that drew in the previous frame, not in this one */
} ms_core_frame_work;

/* What to draw: the stitched mesh of every shown cell (ms_view_stitch), the
 * cut, and the APO chunks of the shown cells that have one. */
typedef struct ms_core_frame {
    uint64_t generation;      /* increases with each published frame */
    double time;              /* seconds since ms_core_start */
    ms_core_frame_work work;  /* what making it cost, what changed */
    ms_view_mesh mesh;
    uint32_t cell_count;      /* cells of the model */
    /* the cut: the cells shown or split, ids ascending; cut_bits[i] is cell
     * cut_cells[i]'s shown precision, or 0xFE (MS_VIEW_TARGET_SPLIT). Every
     * other cell is hidden (0xFF). Sized by the cut, not by the model:
     * ms_core_frame_cell_bits looks a cell up. */
    uint32_t *cut_cells;
    uint8_t *cut_bits;
    size_t cut_count;
    ms_core_apo_chunk *apo;
    size_t apo_count;
    /* with an index by subtree (stats.index_by_subtree): the ids of the subtrees
     * held, ascending (docs/CLIENT.md: exactly those the cut needs); else NULL, 0 */
    uint32_t *subtrees;
    size_t subtree_count;
    /* the records of the shown cells (every cell that draws a triangle of mesh),
     * ids ascending: record_ids[i]'s record is records[i]. A renderer learns
     * them (ms_render_learn), so it never needs the whole index. */
    uint32_t *record_ids;
    ms_archive_cell *records;
    size_t record_count;
} ms_core_frame;

/* The newest frame published since the last take, or NULL (never blocks on
 * decoding). Needs export_frames. */
ms_core_frame *ms_core_take_frame(ms_core *core);
void ms_core_frame_free(ms_core_frame *frame);
/* Cell's entry in the frame's cut: its shown precision, 0xFE (split) or 0xFF
 * (hidden: not in the cut, or beyond the model). O(log cut_count). */
uint8_t ms_core_frame_cell_bits(const ms_core_frame *frame, uint32_t cell);

typedef struct ms_core_stats {
    double time;               /* seconds since start */
    bool connected, model_open; /* local mode: both true once the archive is open */
    bool view_complete;        /* every cell of the cut at its target, nothing missing */
    uint64_t camera_serial;    /* the camera set-call the figures below answer */
    double achieved_error_px;  /* largest projected error of a visible shown cell, at the
                                  precision it is shown at (under a preview, the capped one) */
    /* a public preview (PROTOCOL.md section 8): without a token the server
     * (its MODEL_OPENED) lets this reader have geometry up to preview_bits and
     * the APO levels no finer (ms_archive_preview_apo_levels). The core never
     * asks for more: selection caps every cell there and a capped cell counts
     * as at its target, so view_complete means complete at the preview. */
    bool preview;              /* false: full access (a token, a whole-public model, local) */
    unsigned preview_bits;     /* with preview: the last bit this reader may read */
    bool preview_limited;      /* the latest pass capped a cell the camera wants finer:
                                  a token gives more of this view */
    double tolerance_px;       /* effective geometric tolerance (raised over budget) */
    double first_display;      /* seconds to the first frame with a triangle; < 0 none yet */
    uint64_t first_display_generation; /* with export_frames: the generation of that frame
                                  (ms_core_frame.generation); 0 none yet */
    /* the index (docs/CLIENT.md, "An index by subtree") */
    bool index_by_subtree;     /* the model opened with its index head only */
    uint64_t subtrees_received; /* subtrees received and taken (not the root's, in the head) */
    uint64_t index_bytes_received; /* index bytes received as stored: the whole index, or
                                  the head and every subtree piece */
    uint64_t index_bytes_held, peak_index_bytes_held; /* raw index bytes held now, at most */
    uint64_t subtrees_held;    /* subtrees held now (the root's included) */
    /* per-cell bookkeeping (docs/CLIENT.md, "What a cell costs"): the view's
     * and the core's state of every cell of each sibling group the index
     * holds a record of, whatever the cell holds besides */
    uint32_t state_cells;      /* cells with state now (the whole model with a whole index) */
    uint64_t state_bytes_held; /* state_cells x ms_core_state_bytes_per_cell(); with an
                                  index by subtree counted in `memory` (the budget) */
    uint64_t bytes_received;   /* payload bytes (local mode: bytes handed over) */
    uint64_t geometry_bytes_received, apo_bytes_received; /* bytes_received by stream */
    uint64_t socket_bytes;     /* everything read from the server (frames, index), counted
                                  at each loop tick; 0 in local mode. On a shared link: what
                                  its connections read since this core joined, every
                                  member's frames included (ms_core_link_get_stats has the
                                  link's total) */
    uint64_t bytes_in_flight;  /* requested and not yet received */
    uint64_t requests, cancels, reconnects, refetches, evictions;
    double longest_outage;     /* seconds, the longest span from a lost connection to the
                                  model open again (a failover through a balancer); 0 none */
    uint32_t cells_shown, cells_split, cells_cached, cells_loading, cells_failed;
    uint64_t memory, peak_memory; /* the budget's measure: payload bytes held, decoded
                                  estimate, and with an index by subtree index_bytes_held
                                  and state_bytes_held */
    double decode_seconds;     /* decode thread busy time (verify, decode, select) */
    /* with export_frames, summed over every frame made, taken or not
     * (ms_core_frame_work; docs/CLIENT.md, "Frames") */
    uint64_t frames_made;
    double frame_seconds;      /* of decode_seconds: making frames (stitch, APO, counts) */
    uint64_t frame_triangles;  /* triangles stitched */
    uint64_t frame_apo_bytes;  /* APO bytes the frames hold (each frame all its chunks) */
    ms_core_frame_work frame_work; /* the frames' work, summed */
    ms_core_decode_work decode_work; /* the decode passes' work, by step and thread */
    double latency_p50, latency_p99; /* request send to last byte, seconds */
    char error[256];           /* why the core stopped, or "" */
    bool model_changed;        /* error says "the model changed on the server": a rescan
                                  replaced the model while it streamed (MODEL_CHANGED, or a
                                  reconnect found another content_id). What the core holds
                                  is of the old version; start a fresh core to stream the
                                  new one. A removed model stops with UNKNOWN_MODEL instead. */
    char warning[256];         /* last non-fatal problem (e.g. a failed cell), or "". A
                                  warning about the budget ("memory budget too small")
                                  comes in the same snapshot as the tolerance it names */
} ms_core_stats;

void ms_core_get_stats(ms_core *core, ms_core_stats *stats);

/* Bytes of bookkeeping a cell with state costs the core (stats.state_cells):
 * sizeof the view decoder's cell state (ms_view_cell_state_size, the record
 * included) plus sizeof the core's reception state; 480 on x86-64. The
 * payload bytes, decoders and caches the cell points to are counted apart. */
size_t ms_core_state_bytes_per_cell(void);

#endif
