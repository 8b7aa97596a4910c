/* The unit meshview's measurements are given in (docs/VIEWER.md,
 * "Measuring"): the one the open model's sidecar metadata declares
 * (ms_metadata.h, "unit": "mm", ...), else "model units".
 *
 * Where it comes from: a local archive's catalog.json entry, or a server
 * entry whose documents the catalogue screen already fetched, is in the
 * model as opened (ms_viewer_model.unit_known). Otherwise, from a server, the
 * model's METADATA document once, when the model is first measured (T, or a
 * chain from --view: a model never measured costs no connection), by a
 * fetcher thread of its own
 * (ms_viewer_fetcher.h, bounded by the source's time-out), so the drawing
 * thread never waits on the network; until it comes, and when it fails
 * (logged once), measurements say "model units".
 *
 * Ownership: a zeroed ms_viewer_unit is empty; ms_viewer_unit_free stops the
 * fetch (within milliseconds) and makes it empty again. Thread-safety: the
 * drawing thread.
 */
#ifndef MS_VIEWER_UNIT_H
#define MS_VIEWER_UNIT_H

#include <stdbool.h>
#include <stdio.h>

#include "ms_metadata.h"
#include "ms_viewer_fetcher.h"
#include "ms_viewer_model.h"

typedef struct ms_viewer_unit {
    char model[MS_MODEL_NAME_MAX + 1];   /* the model it is for ("": none yet) */
    char unit[MS_METADATA_UNIT_MAX + 1]; /* "": none declared (or not known yet) */
    bool known;                          /* the answer is in (or failed) */
    ms_viewer_fetcher *fetcher;          /* a server's METADATA in flight */
} ms_viewer_unit;

/* Per frame: for a model other than the last one, starts over (takes the
 * unit from the model, or asks the server); else takes the fetch's result
 * when it came (a failure's line to log, when log is not NULL). */
void ms_viewer_unit_update(ms_viewer_unit *u, const ms_viewer_source *source,
                           const ms_viewer_model *model, FILE *log);

/* Scripted runs: ms_viewer_unit_update until the answer is in, at most
 * timeout_s seconds. True when it is. */
bool ms_viewer_unit_wait(ms_viewer_unit *u, const ms_viewer_source *source,
                         const ms_viewer_model *model, double timeout_s, FILE *log);

/* "mm", ..., or MS_METADATA_NO_UNIT ("model units"). */
const char *ms_viewer_unit_name(const ms_viewer_unit *u);

void ms_viewer_unit_free(ms_viewer_unit *u);

#endif
