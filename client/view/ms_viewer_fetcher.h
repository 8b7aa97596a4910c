/* The catalogue screen's background fetches from a server (docs/VIEWER.md
 * "Catalogue"): one worker thread, so that a slow or silent server never
 * holds up the drawing thread. It fetches
 *   - the documents of one model (METADATA, then THUMBNAIL when the metadata
 *     says it has one): the name most recently asked for only; a newer one
 *     supersedes an older one still waiting, a fetch in flight finishes and
 *     its result is handed over all the same;
 *   - one page of the catalogue (LIST_PAGE: query, from offset, MS_VIEWER_PAGE
 *     models by name): again the most recent request only. A server below
 *     protocol version 3 (no pages) gets the whole catalogue asked for and
 *     filtered here (ms_viewer_list_page), for offset 0.
 *   - the annotations document of one model (ms_viewer_annotate.h, from a
 *     server), again the most recent request only.
 * One connection, opened at the first request and reused for the next ones;
 * when it turns out closed (the server dropped it while idle), the request
 * reconnects once. Every request is bounded by the source's time-out (0 = 5 s,
 * the handshake included); a request that ran out of time, or a connection
 * that failed, is dropped, and the next request connects afresh.
 *
 * Results go to a queue the drawing thread empties with
 * ms_viewer_fetcher_take, which never waits on the network (a mutex held for
 * a few pointer moves). The worker never touches the caller's lists: names
 * are copied in, results copied out.
 *
 * The worker is a thread of its own rather than a loop of the thread pool
 * (ms_parallel.h): the pool runs blocks of a loop and its caller waits for
 * them, where this work waits on a socket for seconds while the caller
 * draws on.
 *
 * ms_viewer_fetcher_free interrupts a request in flight (a pipe the worker's
 * event loop watches) and joins the thread: it returns within milliseconds,
 * also on a silent server.
 * Thread-safety: the functions below are called from one thread (the
 * drawing thread); the worker is internal.
 */
#ifndef MS_VIEWER_FETCHER_H
#define MS_VIEWER_FETCHER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_viewer_model.h"

typedef struct ms_viewer_fetcher ms_viewer_fetcher;

/* Starts the worker for source (a server: archive_dir NULL, else MS_ERR_ARG);
 * the source's strings are copied. MS_ERR_NOMEM, MS_ERR_IO when no thread or
 * pipe could be made. Nothing is fetched before a request. */
ms_status ms_viewer_fetcher_new(const ms_viewer_source *source, ms_viewer_fetcher **out,
                                ms_error *err);
/* Interrupts what is in flight, joins the worker, frees what it holds
 * (results not taken included). NULL: nothing. */
void ms_viewer_fetcher_free(ms_viewer_fetcher *f);

/* Asks for the documents of model name (a valid model name); supersedes a
 * request still waiting. Nothing when name is the one in flight or waiting,
 * or its result is waiting to be taken. */
void ms_viewer_fetcher_want_documents(ms_viewer_fetcher *f, const char *name);

/* Asks for the page of query (at most 64 bytes, lower case; "" every model)
 * from offset; supersedes a page request still waiting. query NULL takes
 * back a page request still waiting. */
void ms_viewer_fetcher_want_page(ms_viewer_fetcher *f, const char *query, size_t offset);

/* Asks for the annotations document of model name (a valid model name), as
 * ms_viewer_fetcher_want_documents does for the others. */
void ms_viewer_fetcher_want_annotations(ms_viewer_fetcher *f, const char *name);

typedef enum { MS_FETCHED_DOCUMENTS, MS_FETCHED_PAGE, MS_FETCHED_ANNOTATIONS } ms_fetched_kind;

/* One result. DOCUMENTS: entry.name the model's, entry.metadata,
 * has_thumbnail, thumbnail_png, documents_fetched set (owned here until moved
 * out). PAGE: query and offset as asked; page.entries (owned) the page's
 * models, page.count of them, page.total the models that match (offset +
 * count when nothing more comes). ANNOTATIONS: entry.name the model's,
 * document (owned, not terminated) its bytes, NULL when the server has none.
 * status MS_OK, or the failure and its line in why (the documents: what came
 * before the failure is kept). */
typedef struct ms_viewer_fetched {
    ms_fetched_kind kind;
    ms_status status;
    char why[MS_ERROR_TEXT_MAX];
    ms_viewer_model_entry entry;
    char query[65];
    size_t offset;
    ms_viewer_model_list page;
    uint8_t *document;
    size_t document_size;
} ms_viewer_fetched;

/* The oldest result not taken yet into *out (the caller frees it with
 * ms_viewer_fetched_free): true, or false at once when none has come. */
bool ms_viewer_fetcher_take(ms_viewer_fetcher *f, ms_viewer_fetched *out);
void ms_viewer_fetched_free(ms_viewer_fetched *r);

/* Whether a request is waiting or in flight. */
bool ms_viewer_fetcher_busy(ms_viewer_fetcher *f);

/* Connections opened so far (for tests: one for consecutive requests). */
unsigned ms_viewer_fetcher_connections(ms_viewer_fetcher *f);

#endif
