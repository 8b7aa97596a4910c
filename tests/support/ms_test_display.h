/* An X display for the tests that need OpenGL (Mesa llvmpipe under Xvfb).
 *
 * ms_test_display_start keeps $DISPLAY when an X server socket exists for it;
 * otherwise it starts Xvfb on the first free display number from :90 up (no TCP,
 * 24-bit screen), waits for its socket (at most 10 s) and sets DISPLAY, so GLFW
 * and child programs (meshview) use it. ms_test_display_stop kills what it
 * started. Not thread-safe (it sets the environment): call it from main before
 * the tests run.
 */
#ifndef MS_TEST_DISPLAY_H
#define MS_TEST_DISPLAY_H

#include <stdbool.h>
#include <stddef.h>
#include <sys/types.h>

typedef struct ms_test_display {
    pid_t xvfb;      /* 0 when an existing display is used */
    int number;      /* the display number in use */
} ms_test_display;

/* false, with one line in why, when no display can be had. */
bool ms_test_display_start(ms_test_display *display, char *why, size_t why_size);
void ms_test_display_stop(ms_test_display *display);

#endif
