#include "ms_viewer_readback.h"

#include <epoxy/gl.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <string.h>

#include "ms_png.h"

ms_status ms_viewer_read_rgb(int width, int height, uint8_t **pixels, ms_error *err)
{
    *pixels = NULL;
    size_t row = (size_t)width * 3;
    uint8_t *p = malloc(row * (size_t)height);
    uint8_t *swap = malloc(row);
    if (!p || !swap) {
        free(p);
        free(swap);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a %dx%d picture", width, height);
    }
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, p);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    /* OpenGL's first row is the bottom one; PNG's the top. */
    for (int y = 0; y < height / 2; ++y) {
        uint8_t *a = p + (size_t)y * row, *b = p + (size_t)(height - 1 - y) * row;
        memcpy(swap, a, row);
        memcpy(a, b, row);
        memcpy(b, swap, row);
    }
    free(swap);
    *pixels = p;
    return MS_OK;
}

ms_status ms_viewer_screenshot(const char *path, int width, int height, ms_error *err)
{
    uint8_t *pixels;
    ms_status st = ms_viewer_read_rgb(width, height, &pixels, err);
    if (st != MS_OK)
        return st;
    st = ms_png_write(path, pixels, (uint32_t)width, (uint32_t)height, 3, err);
    free(pixels);
    return st;
}

bool ms_viewer_read_depth(int x, int y, int width, int height, double *depth)
{
    if (x < 0 || y < 0 || x >= width || y >= height)
        return false;
    GLfloat d = 1;
    glReadPixels(x, y, 1, 1, GL_DEPTH_COMPONENT, GL_FLOAT, &d);
    *depth = d;
    return true;
}

ms_status ms_viewer_target_init(ms_viewer_target *t, int width, int height, ms_error *err)
{
    memset(t, 0, sizeof *t);
    t->width = width, t->height = height;
    glGenFramebuffers(1, &t->fbo);
    glGenRenderbuffers(1, &t->colour);
    glGenRenderbuffers(1, &t->depth);
    glBindRenderbuffer(GL_RENDERBUFFER, t->colour);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
    glBindRenderbuffer(GL_RENDERBUFFER, t->depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    glBindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, t->colour);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, t->depth);
    GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
        ms_viewer_target_free(t);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "offscreen framebuffer %dx%d incomplete (0x%x)",
                            width, height, (unsigned)status);
    }
    return MS_OK;
}

void ms_viewer_target_bind(const ms_viewer_target *t)
{
    glBindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
}

uint64_t ms_viewer_target_gl_bytes(const ms_viewer_target *t)
{
    return t->fbo ? 8ull * (uint64_t)t->width * (uint64_t)t->height : 0;
}

void ms_viewer_target_free(ms_viewer_target *t)
{
    if (t->fbo)
        glDeleteFramebuffers(1, &t->fbo);
    if (t->colour)
        glDeleteRenderbuffers(1, &t->colour);
    if (t->depth)
        glDeleteRenderbuffers(1, &t->depth);
    memset(t, 0, sizeof *t);
}

ms_status ms_viewer_screenshot_numbered(const char *dir, const char *name, int *counter, int width, int height,
                                        char *written, size_t size, ms_error *err)
{
    struct stat sb;
    do
        snprintf(written, size, "%s/meshview-%s-%03d.png", dir, name, (*counter)++);
    while (stat(written, &sb) == 0 && *counter < 1000);
    return ms_viewer_screenshot(written, width, height, err);
}
