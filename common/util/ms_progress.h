/* Progress bar for long work, drawn on a terminal only.
 *
 * ms_progress_init enables drawing only when `out` is a terminal, so scripts and
 * logs see nothing. Updates redraw at most about ten times a second, so calling
 * ms_progress_update in a tight loop is cheap. One ms_progress per task, owned by
 * the caller; not thread-safe (update from one thread). */
#ifndef MS_PROGRESS_H
#define MS_PROGRESS_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

typedef struct ms_progress {
    FILE *out;
    const char *label;  /* borrowed; must outlive the progress bar */
    uint64_t total;     /* units of work; 0 = unknown (shows a count) */
    double start_seconds;
    double last_draw_seconds;
    bool enabled;
    bool drawn;
} ms_progress;

void ms_progress_init(ms_progress *p, FILE *out, const char *label, uint64_t total);
void ms_progress_update(ms_progress *p, uint64_t done);
/* Erases the bar (the summary report follows on clean lines). */
void ms_progress_finish(ms_progress *p);

/* Monotonic wall-clock seconds. */
double ms_now_seconds(void);
/* Peak resident set size of this process in MiB (0 if unknown). */
double ms_peak_rss_mb(void);

#endif
