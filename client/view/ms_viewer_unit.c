/* The unit of meshview's measurements: see ms_viewer_unit.h. */
#include "ms_viewer_unit.h"

#include <string.h>
#include <time.h>

#include "ms_progress.h"

void ms_viewer_unit_free(ms_viewer_unit *u)
{
    ms_viewer_fetcher_free(u->fetcher);
    memset(u, 0, sizeof *u);
}

/* A fetched document's result: the unit its metadata declares, if any. */
static void take(ms_viewer_unit *u, FILE *log)
{
    ms_viewer_fetched r;
    while (ms_viewer_fetcher_take(u->fetcher, &r)) {
        if (r.kind == MS_FETCHED_DOCUMENTS && !strcmp(r.entry.name, u->model)) {
            u->known = true;
            const char *unit = r.entry.metadata ? r.entry.metadata->unit : NULL;
            snprintf(u->unit, sizeof u->unit, "%s", unit ? unit : "");
            if (r.status != MS_OK && !unit && log)
                fprintf(log, "meshview: the unit of %s: %s\n", u->model, r.why);
        }
        ms_viewer_fetched_free(&r);
    }
    if (u->known) { /* one answer a model: the fetcher's thread goes */
        ms_viewer_fetcher_free(u->fetcher);
        u->fetcher = NULL;
    }
}

void ms_viewer_unit_update(ms_viewer_unit *u, const ms_viewer_source *source,
                           const ms_viewer_model *model, FILE *log)
{
    if (strcmp(u->model, model->name) != 0) {
        ms_viewer_unit_free(u);
        snprintf(u->model, sizeof u->model, "%s", model->name);
        if (model->unit_known || !source || source->archive_dir) {
            snprintf(u->unit, sizeof u->unit, "%s", model->unit);
            u->known = true;
            return;
        }
        ms_error err;
        if (ms_viewer_fetcher_new(source, &u->fetcher, &err) != MS_OK) {
            u->known = true;
            if (log)
                fprintf(log, "meshview: the unit of %s: %s\n", u->model, err.text);
            return;
        }
        ms_viewer_fetcher_want_documents(u->fetcher, u->model);
    }
    if (u->fetcher)
        take(u, log);
}

bool ms_viewer_unit_wait(ms_viewer_unit *u, const ms_viewer_source *source,
                         const ms_viewer_model *model, double timeout_s, FILE *log)
{
    double start = ms_now_seconds();
    for (;;) {
        ms_viewer_unit_update(u, source, model, log);
        if (u->known || ms_now_seconds() - start >= timeout_s)
            return u->known;
        struct timespec nap = {0, 5000000};
        nanosleep(&nap, NULL);
    }
}

const char *ms_viewer_unit_name(const ms_viewer_unit *u)
{
    return u->unit[0] ? u->unit : MS_METADATA_NO_UNIT;
}
