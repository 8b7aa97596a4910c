/* Helpers for tests that drive the client core (ms_test_core.h). */
#include "ms_test_core.h"

#include <math.h>
#include <time.h>

#include "ms_progress.h"

void ms_test_sleep_s(double seconds)
{
    struct timespec ts = {(time_t)seconds, (long)((seconds - floor(seconds)) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Replaces *frame by the core's newest frame, if one was published. */
static void keep_newest_frame(ms_core *core, ms_core_frame **frame)
{
    ms_core_frame *f = ms_core_take_frame(core);
    if (f) {
        ms_core_frame_free(*frame);
        *frame = f;
    }
}

bool ms_test_core_wait_complete(ms_core *core, double seconds, ms_core_stats *stats,
                                ms_core_frame **frame)
{
    double until = ms_now_seconds() + seconds;
    for (;;) {
        if (frame)
            keep_newest_frame(core, frame);
        ms_core_get_stats(core, stats);
        if (stats->view_complete || stats->error[0] || ms_now_seconds() > until) {
            if (frame && stats->view_complete)
                keep_newest_frame(core, frame);
            return stats->view_complete;
        }
        ms_test_sleep_s(0.005);
    }
}
