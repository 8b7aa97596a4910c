/* The client core's parts and the state they share (internal to client/; the
 * API is ms_client_core.h; docs/CLIENT.md, "The core's parts"). One ms_core,
 * one mutex (`lock`), three threads, three parts:
 *
 *   ms_core_net.h      the network part (a link: connection, requests,
 *                      reconnects, resumption), the link's thread
 *   ms_core_sched.h    the scheduler: a pure function of a snapshot (what to
 *                      request), no thread of its own, no state
 *   ms_core_decoder.h  the decoder part (view decoder, reception, cell cache,
 *                      subtrees, budget, frames), the decode thread
 *
 * and, here, what they share: the small queue (ms_core_queue.h: chunks in
 * the inbox, the want list) and the figures, under the lock
 * (ms_core_shared.c); the caller's API (ms_client_core.c), which starts and
 * stops the parts; the local responder (ms_client_core_local.c), the byte
 * source that replaces the network for a local archive.
 *
 * Fields are grouped by who may touch them: "shared" under lock, the others by
 * one thread only. No two files of client/core call into each other both ways
 * (tests/check-circles). */
#ifndef MS_CLIENT_CORE_INTERNAL_H
#define MS_CLIENT_CORE_INTERNAL_H

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_client_core.h"
#include "ms_core_decoder.h"
#include "ms_core_net.h"
#include "ms_core_queue.h"
#include "ms_core_sched.h"

#define LATENCY_KEEP 65536u

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

    /* --- the decode thread only --- */
    ms_core_decoder dec;
};

/* ---- ms_core_shared.c: the inbox and the figures, shared by every thread ---- */

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
/* With export_frames, before publishing a freshly opened index (not yet shared
 * with the decode thread): keeps its header and records for ms_core_wait_open.
 * Out of memory leaves the opening empty (ms_core_wait_open then says so). */
void ms_core_keep_opening(ms_core *c, const ms_archive *index, bool by_subtree);

/* ---- ms_client_core_local.c: the byte source from a local archive ---- */

/* The local responder's thread (arg: the ms_core). */
void *ms_core_local_main(void *arg);

#endif
