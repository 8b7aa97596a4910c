/* The overlay pass: one atlas texture (R8, one 6x8 cell per glyph, bits as 0 or
 * 255), one vertex buffer refilled each draw with two triangles per glyph or
 * rectangle. A rectangle's texture coordinate is negative: the shader paints it
 * solid. */
#include "ms_viewer_text.h"

#include <epoxy/gl.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_viewer_font.h"

#define GLYPHS (MS_FONT_LAST - MS_FONT_FIRST + 1)
#define FLOATS_PER_VERTEX 8 /* x, y, u, v, r, g, b, a */

struct ms_viewer_text {
    GLuint program, vao, vbo, atlas;
    GLint viewport_uniform, mode_uniform;
    /* the batch's picture (ms_viewer_text_image): an RGB8 texture */
    GLuint image;
    uint64_t image_key, image_bytes;
    bool image_shown;
    float image_rect[4];
    uint64_t atlas_bytes, vbo_bytes; /* GL storage (ms_viewer_text_gl_bytes) */
    float *vertices;
    size_t count, cap; /* vertices */
    bool out_of_memory;
    int width, height, scale;
};

static const char *vertex_source =
    "#version 410 core\n"
    "layout(location = 0) in vec2 position;\n"
    "layout(location = 1) in vec2 texel;\n"
    "layout(location = 2) in vec4 colour;\n"
    "uniform vec2 viewport;\n"
    "out vec2 v_texel;\n"
    "out vec4 v_colour;\n"
    "void main() {\n"
    "    v_texel = texel;\n"
    "    v_colour = colour;\n"
    "    gl_Position = vec4(position.x / viewport.x * 2.0 - 1.0,\n"
    "                       1.0 - position.y / viewport.y * 2.0, 0.0, 1.0);\n"
    "}\n";

static const char *fragment_source =
    "#version 410 core\n"
    "in vec2 v_texel;\n"
    "in vec4 v_colour;\n"
    "uniform sampler2D atlas;\n"
    "uniform int mode;\n"
    "out vec4 fragment;\n"
    "void main() {\n"
    "    if (mode == 1) {\n"
    "        fragment = vec4(texture(atlas, v_texel).rgb, 1.0);\n"
    "        return;\n"
    "    }\n"
    "    if (v_texel.x >= 0.0 && texelFetch(atlas, ivec2(floor(v_texel)), 0).r < 0.5)\n"
    "        discard;\n"
    "    fragment = v_colour;\n"
    "}\n";

static ms_status compile(GLenum kind, const char *source, GLuint *shader, ms_error *err)
{
    *shader = glCreateShader(kind);
    glShaderSource(*shader, 1, &source, NULL);
    glCompileShader(*shader);
    GLint ok = 0;
    glGetShaderiv(*shader, GL_COMPILE_STATUS, &ok);
    if (ok)
        return MS_OK;
    char log[512] = "";
    glGetShaderInfoLog(*shader, sizeof log, NULL, log);
    log[strcspn(log, "\n")] = 0;
    glDeleteShader(*shader);
    *shader = 0;
    return ms_error_set(err, MS_ERR_UNSUPPORTED, "overlay shader: %s", log);
}

static ms_status build_program(ms_viewer_text *t, ms_error *err)
{
    GLuint vs, fs;
    ms_status st = compile(GL_VERTEX_SHADER, vertex_source, &vs, err);
    if (st != MS_OK)
        return st;
    st = compile(GL_FRAGMENT_SHADER, fragment_source, &fs, err);
    if (st != MS_OK) {
        glDeleteShader(vs);
        return st;
    }
    t->program = glCreateProgram();
    glAttachShader(t->program, vs);
    glAttachShader(t->program, fs);
    glLinkProgram(t->program);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(t->program, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[512] = "";
        glGetProgramInfoLog(t->program, sizeof log, NULL, log);
        log[strcspn(log, "\n")] = 0;
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "overlay program: %s", log);
    }
    t->viewport_uniform = glGetUniformLocation(t->program, "viewport");
    t->mode_uniform = glGetUniformLocation(t->program, "mode");
    return MS_OK;
}

static void build_atlas(ms_viewer_text *t)
{
    enum { W = GLYPHS * MS_FONT_ADVANCE_X, H = MS_FONT_GLYPH_H };
    static const int w = W, h = H;
    uint8_t *bits = calloc((size_t)w * h, 1);
    if (bits)
        for (int g = 0; g < GLYPHS; ++g)
            for (unsigned y = 0; y < MS_FONT_GLYPH_H; ++y)
                for (unsigned x = 0; x < MS_FONT_GLYPH_W; ++x)
                    bits[y * w + g * MS_FONT_ADVANCE_X + (int)x] =
                        ms_font_pixel((char)(MS_FONT_FIRST + g), x, y) ? 255 : 0;
    glGenTextures(1, &t->atlas);
    glBindTexture(GL_TEXTURE_2D, t->atlas);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8, w, h, 0, GL_RED, GL_UNSIGNED_BYTE, bits);
    t->atlas_bytes = (uint64_t)w * (uint64_t)h;
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    if (!bits)
        t->out_of_memory = true;
    free(bits);
}

ms_status ms_viewer_text_new(ms_viewer_text **text, ms_error *err)
{
    *text = NULL;
    ms_viewer_text *t = calloc(1, sizeof *t);
    if (!t)
        return ms_error_set(err, MS_ERR_NOMEM, "overlay: out of memory");
    ms_status st = build_program(t, err);
    if (st != MS_OK) {
        ms_viewer_text_free(t);
        return st;
    }
    build_atlas(t);
    glGenVertexArrays(1, &t->vao);
    glGenBuffers(1, &t->vbo);
    glBindVertexArray(t->vao);
    glBindBuffer(GL_ARRAY_BUFFER, t->vbo);
    GLsizei stride = FLOATS_PER_VERTEX * sizeof(float);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, stride, (void *)0);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, stride, (void *)(2 * sizeof(float)));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, stride, (void *)(4 * sizeof(float)));
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    t->scale = 1;
    *text = t;
    return MS_OK;
}

void ms_viewer_text_free(ms_viewer_text *t)
{
    if (!t)
        return;
    if (t->program)
        glDeleteProgram(t->program);
    if (t->vbo)
        glDeleteBuffers(1, &t->vbo);
    if (t->vao)
        glDeleteVertexArrays(1, &t->vao);
    if (t->atlas)
        glDeleteTextures(1, &t->atlas);
    if (t->image)
        glDeleteTextures(1, &t->image);
    free(t->vertices);
    free(t);
}

void ms_viewer_text_begin(ms_viewer_text *t, int width, int height, int scale)
{
    t->count = 0;
    t->image_shown = false;
    t->width = width > 0 ? width : 1;
    t->height = height > 0 ? height : 1;
    t->scale = scale > 0 ? scale : 1;
}

int ms_viewer_text_scale(const ms_viewer_text *t) { return t->scale; }

uint64_t ms_viewer_text_gl_bytes(const ms_viewer_text *t)
{
    return t ? t->atlas_bytes + t->vbo_bytes + t->image_bytes : 0;
}

void ms_viewer_text_image(ms_viewer_text *t, double x, double y, double w, double h,
                          const uint8_t *rgb, int width, int height, uint64_t key)
{
    if (!rgb || width < 1 || height < 1 || width > 4096 || height > 4096 || !(w > 0) ||
        !(h > 0))
        return;
    if (!t->image || key != t->image_key) {
        if (!t->image)
            glGenTextures(1, &t->image);
        glBindTexture(GL_TEXTURE_2D, t->image);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, width, height, 0, GL_RGB, GL_UNSIGNED_BYTE, rgb);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
        glBindTexture(GL_TEXTURE_2D, 0);
        t->image_key = key;
        t->image_bytes = 3ull * (uint64_t)width * (uint64_t)height;
    }
    t->image_shown = true;
    t->image_rect[0] = (float)x, t->image_rect[1] = (float)y;
    t->image_rect[2] = (float)(x + w), t->image_rect[3] = (float)(y + h);
}

int ms_viewer_text_auto_scale(int height, double pixel_ratio, bool large)
{
    int base = pixel_ratio >= 1.5 ? (int)(pixel_ratio + 0.5) : 1;
    double points = height / (double)base;
    return points >= (large ? 400 : 700) ? 2 * base : base;
}

/* Appends a quad: corners (x0, y0)-(x1, y1), texels (u0, v0)-(u1, v1). */
static void quad(ms_viewer_text *t, float x0, float y0, float x1, float y1, float u0, float v0,
                 float u1, float v1, const float rgba[4])
{
    if (t->count + 6 > t->cap) {
        size_t cap = t->cap ? t->cap * 2 : 6 * 256;
        float *grown = realloc(t->vertices, cap * FLOATS_PER_VERTEX * sizeof(float));
        if (!grown) {
            t->out_of_memory = true;
            return;
        }
        t->vertices = grown;
        t->cap = cap;
    }
    const float corners[6][4] = {{x0, y0, u0, v0}, {x1, y0, u1, v0}, {x1, y1, u1, v1},
                                 {x0, y0, u0, v0}, {x1, y1, u1, v1}, {x0, y1, u0, v1}};
    for (int i = 0; i < 6; ++i) {
        float *v = t->vertices + (t->count++) * FLOATS_PER_VERTEX;
        memcpy(v, corners[i], 4 * sizeof(float));
        memcpy(v + 4, rgba, 4 * sizeof(float));
    }
}

void ms_viewer_text_rect(ms_viewer_text *t, double x, double y, double w, double h,
                         const float rgba[4])
{
    if (w > 0 && h > 0)
        quad(t, (float)x, (float)y, (float)(x + w), (float)(y + h), -1, -1, -1, -1, rgba);
}

double ms_viewer_text_print(ms_viewer_text *t, double x, double y, const float rgba[4],
                            const char *line)
{
    double s = t->scale, pen = x;
    for (const char *p = line; *p; ++p, pen += MS_FONT_ADVANCE_X * s) {
        unsigned char c = (unsigned char)*p;
        if (c == ' ')
            continue;
        if (c < MS_FONT_FIRST || c > MS_FONT_LAST)
            c = '?';
        float u0 = (float)((c - MS_FONT_FIRST) * MS_FONT_ADVANCE_X);
        quad(t, (float)pen, (float)y, (float)(pen + MS_FONT_GLYPH_W * s),
             (float)(y + MS_FONT_GLYPH_H * s), u0, 0, u0 + MS_FONT_GLYPH_W, MS_FONT_GLYPH_H, rgba);
    }
    return pen - x;
}

ms_status ms_viewer_text_draw(ms_viewer_text *t, ms_error *err)
{
    if (t->out_of_memory) {
        t->out_of_memory = false;
        t->count = 0;
        return ms_error_set(err, MS_ERR_NOMEM, "overlay: out of memory");
    }
    if (!t->count && !t->image_shown)
        return MS_OK;
    GLboolean depth = glIsEnabled(GL_DEPTH_TEST), blend = glIsEnabled(GL_BLEND),
              cull = glIsEnabled(GL_CULL_FACE);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glViewport(0, 0, t->width, t->height);
    glUseProgram(t->program);
    glUniform2f(t->viewport_uniform, (float)t->width, (float)t->height);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, t->atlas);
    glUniform1i(glGetUniformLocation(t->program, "atlas"), 0);
    glUniform1i(t->mode_uniform, 0);
    glBindVertexArray(t->vao);
    glBindBuffer(GL_ARRAY_BUFFER, t->vbo);
    size_t glyphs = t->count;
    if (t->image_shown) { /* the picture's quad after the batch, texels 0..1 */
        static const float white[4] = {1, 1, 1, 1};
        const float *r = t->image_rect;
        quad(t, r[0], r[1], r[2], r[3], 0, 0, 1, 1, white);
    }
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(t->count * FLOATS_PER_VERTEX * sizeof(float)),
                 t->vertices, GL_STREAM_DRAW);
    t->vbo_bytes = t->count * FLOATS_PER_VERTEX * sizeof(float);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)glyphs);
    if (t->count > glyphs) {
        glBindTexture(GL_TEXTURE_2D, t->image);
        glUniform1i(t->mode_uniform, 1);
        glDrawArrays(GL_TRIANGLES, (GLint)glyphs, (GLsizei)(t->count - glyphs));
    }
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    glBindTexture(GL_TEXTURE_2D, 0);
    glUseProgram(0);
    if (depth)
        glEnable(GL_DEPTH_TEST);
    if (!blend)
        glDisable(GL_BLEND);
    if (cull)
        glEnable(GL_CULL_FACE);
    t->count = 0;
    t->image_shown = false;
    return MS_OK;
}
