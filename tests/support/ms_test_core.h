/* Helpers for tests that drive the client core (ms_client_core.h). */
#ifndef MS_TEST_CORE_H
#define MS_TEST_CORE_H

#include <stdbool.h>

#include "ms_client_core.h"

/* Sleeps for seconds (>= 0). */
void ms_test_sleep_s(double seconds);

/* Polls the core every 5 ms until view complete, an error, or `seconds` pass;
 * fills *stats with the last figures and, when frame is non-NULL, keeps the
 * newest published frame in *frame (freeing the one it replaces). Returns
 * whether the view completed. */
bool ms_test_core_wait_complete(ms_core *core, double seconds, ms_core_stats *stats,
                                ms_core_frame **frame);

#endif
