/* GLFW window with an OpenGL 4.1 core context (ms_gl_window.h). */
#include "ms_gl_window.h"

#include <dlfcn.h>
#include <epoxy/gl.h>
#include <GLFW/glfw3.h>
#include <stdio.h>
#include <string.h>

/* GLFW reports errors through a callback without a user pointer; the text of the
 * last one is kept per thread so that the failing call can quote it. */
static _Thread_local char glfw_last_error[256];

static void remember_glfw_error(int code, const char *description)
{
    snprintf(glfw_last_error, sizeof glfw_last_error, "%s (GLFW error 0x%x)",
             description ? description : "unknown", code);
}

ms_status ms_gl_window_new(int width, int height, const char *title, bool visible,
                           GLFWwindow **window, ms_error *err)
{
    *window = NULL;
    if (width < 1 || width > 16384 || height < 1 || height > 16384)
        return ms_error_set(err, MS_ERR_ARG, "window size %dx%d outside 1..16384", width, height);
    glfw_last_error[0] = 0;
    glfwSetErrorCallback(remember_glfw_error);
    if (!glfwInit())
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "no OpenGL 4.1 core context: %s",
                            glfw_last_error[0] ? glfw_last_error : "GLFW cannot start");
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_VISIBLE, visible ? GLFW_TRUE : GLFW_FALSE);
    glfwWindowHint(GLFW_SCALE_TO_MONITOR, GLFW_TRUE);
    GLFWwindow *w = glfwCreateWindow(width, height, title ? title : "meshview", NULL, NULL);
    if (!w) {
        ms_status s = ms_error_set(err, MS_ERR_UNSUPPORTED, "no OpenGL 4.1 core context: %s",
                                   glfw_last_error[0] ? glfw_last_error : "window creation failed");
        glfwTerminate();
        return s;
    }
    glfwMakeContextCurrent(w);
    glfwSwapInterval(visible ? 1 : 0);
    *window = w;
    return MS_OK;
}

void ms_gl_window_free(GLFWwindow *window)
{
    if (!window)
        return;
    glfwDestroyWindow(window);
    glfwTerminate();
}

void ms_gl_window_keep_driver_loaded(void)
{
    static const char *const drivers[] = {"swrast_dri.so",
                                          "/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so"};
    for (size_t i = 0; i < sizeof drivers / sizeof *drivers; ++i) {
        void *h = dlopen(drivers[i], RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        if (h) {
            dlclose(h);
            return;
        }
    }
}
