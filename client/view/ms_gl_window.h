/* A GLFW window with an OpenGL 4.1 core-profile context: the one way meshview and
 * the GL tests get a context (4.1 so that the viewer also runs on macOS). GL entry
 * points come from libepoxy.
 *
 * visible = false gives a hidden window: rendering then goes into framebuffer
 * objects (headless runs under Xvfb, tests). The context is made current on the
 * calling thread, with vsync off for hidden windows.
 *
 * Errors: MS_ERR_UNSUPPORTED with one line ("no OpenGL 4.1 core context: ...")
 * when GLFW cannot start (no display) or the driver offers less than 4.1 core;
 * nothing is left allocated then.
 * Thread-safety: GLFW's rules: create, poll and free on the main thread.
 */
#ifndef MS_GL_WINDOW_H
#define MS_GL_WINDOW_H

#include <stdbool.h>

#include "ms_error.h"

typedef struct GLFWwindow GLFWwindow;

/* Initialises GLFW if needed and opens the window (width, height in screen
 * coordinates, each in [1, 16384]). *window is NULL on failure. */
ms_status ms_gl_window_new(int width, int height, const char *title, bool visible,
                           GLFWwindow **window, ms_error *err);

/* Destroys the window and terminates GLFW. NULL is a no-op. */
void ms_gl_window_free(GLFWwindow *window);

/* Keeps Mesa's software driver mapped until the process ends (RTLD_NODELETE),
 * so that LeakSanitizer can still name it in a report at exit; a no-op where
 * it is not loaded. */
void ms_gl_window_keep_driver_loaded(void);

#endif
