/* meshview ends cleanly on SIGINT, SIGTERM and SIGHUP without a handler or any
 * global flag: main blocks them before any thread starts (so every thread
 * inherits the mask and none is interrupted), and the draw loop polls whether
 * one is pending, once a frame, and ends as if the window had been closed.
 * Thread-safety: block from main before threads start; poll from any thread.
 */
#ifndef MS_VIEWER_SIGNALS_H
#define MS_VIEWER_SIGNALS_H

#include <stdbool.h>

/* Blocks the three signals in the calling thread (and the threads it starts). */
void ms_viewer_signals_block(void);

/* True when one of them has arrived (it stays pending). */
bool ms_viewer_signals_pending(void);

#endif
