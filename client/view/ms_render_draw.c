/* Drawing a frame (ms_render.h): the program for the options' effects, the
 * uniforms (camera, lights, material, haze, displacement), one draw call per
 * current cell, and which effects ran. */
#include <math.h>
#include <string.h>

#include "ms_render_internal.h"

static float srgb_encode(float c)
{
    c = c < 0.0f ? 0.0f : (c > 1.0f ? 1.0f : c);
    return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

/* A light, distinct linear colour per cell number (golden-ratio hue steps). */
static void cell_tint(uint32_t cell, float rgb[3])
{
    double hue = fmod((double)cell * 0.6180339887498949, 1.0) * 6.0;
    double s = 0.55, v = 0.85, f = hue - floor(hue);
    double p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    double out[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
    int i = (int)floor(hue) % 6;
    for (int a = 0; a < 3; ++a)
        rgb[a] = (float)(out[i][a] * out[i][a]); /* roughly to linear */
}

/* MS_ERR_ARG unless the scene parts of the options are usable. */
static ms_status check_scene_options(const ms_render_options *o, ms_error *err)
{
    if (o->effects & ~(unsigned)MS_EFFECTS_ALL)
        return ms_error_set(err, MS_ERR_ARG, "render: effects 0x%x unknown", o->effects);
    if (o->light_count > MS_RENDER_MAX_LIGHTS)
        return ms_error_set(err, MS_ERR_ARG, "render: %u lights, at most %d", o->light_count, MS_RENDER_MAX_LIGHTS);
    if (!(o->shininess >= 1.0f) || !isfinite(o->shininess) || !(o->specular >= 0.0f) || !isfinite(o->specular) ||
        !(o->haze_density >= 0.0f) || !isfinite(o->haze_density))
        return ms_error_set(err, MS_ERR_ARG, "render: shininess, specular or haze density out of range");
    for (unsigned i = 0; i < o->light_count; ++i) {
        const ms_render_light *l = &o->lights[i];
        if ((unsigned)l->kind > MS_RENDER_LIGHT_POINT)
            return ms_error_set(err, MS_ERR_ARG, "render: light %u of kind %d unknown", i, (int)l->kind);
        if (l->kind == MS_RENDER_LIGHT_POINT && !(l->range > 0.0))
            return ms_error_set(err, MS_ERR_ARG, "render: point light %u without a positive range", i);
        double len2 = l->vector[0] * l->vector[0] + l->vector[1] * l->vector[1] + l->vector[2] * l->vector[2];
        if (!isfinite(len2) || (l->kind == MS_RENDER_LIGHT_DIRECTIONAL && !(len2 > 0.0)))
            return ms_error_set(err, MS_ERR_ARG, "render: light %u has no usable vector", i);
    }
    if (o->displace &&
        (!(o->displacement_amplitude > 0.0f) || !isfinite(o->displacement_amplitude) ||
         !(o->displacement_radius > 0.0f) || !isfinite(o->displacement_radius) ||
         !(o->displacement_density > 0.0f) || !isfinite(o->displacement_density) ||
         !(o->tess_pixels_per_level >= 1.0f) || !isfinite(o->tess_pixels_per_level)))
        return ms_error_set(err, MS_ERR_ARG, "render: displacement amplitude, radius, density or level size out of range");
    if (o->section_count > MS_SECTIONS_MAX)
        return ms_error_set(err, MS_ERR_ARG, "render: %u sections, at most %d", o->section_count, MS_SECTIONS_MAX);
    for (unsigned k = 0; k < o->section_count; ++k) {
        const double *s = o->sections[k];
        double len2 = s[0] * s[0] + s[1] * s[1] + s[2] * s[2];
        if (!(len2 > 0.0) || !isfinite(len2) || !isfinite(s[3]))
            return ms_error_set(err, MS_ERR_ARG, "render: section %u has a zero normal or a number not finite", k);
    }
    if (o->placed) {
        double scale = sqrt(o->placement[0] * o->placement[0] + o->placement[1] * o->placement[1] +
                            o->placement[2] * o->placement[2]);
        for (int i = 0; i < 16; ++i)
            if (!isfinite(o->placement[i]))
                return ms_error_set(err, MS_ERR_ARG, "render: placement not finite");
        if (!(scale > 0.0))
            return ms_error_set(err, MS_ERR_ARG, "render: placement of scale 0");
    }
    return MS_OK;
}

/* column-major a * b, 4x4 */
static void mat4_mul(const double a[16], const double b[16], double out[16])
{
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r) {
            double v = 0;
            for (int k = 0; k < 4; ++k)
                v += a[4 * k + r] * b[4 * c + k];
            out[4 * c + r] = v;
        }
}

/* The lights in eye space for the shader (see cell.frag.glsl). */
static void set_lights(const ms_render_program *p, const ms_render_options *o, const double view[16])
{
    float eye[4 * MS_RENDER_MAX_LIGHTS] = {0}, colour[3 * MS_RENDER_MAX_LIGHTS] = {0},
          range[MS_RENDER_MAX_LIGHTS] = {0};
    for (unsigned i = 0; i < o->light_count; ++i) {
        const ms_render_light *l = &o->lights[i];
        double v[3] = {0, 0, 0};
        if (l->kind == MS_RENDER_LIGHT_DIRECTIONAL) {
            for (int r = 0; r < 3; ++r)
                v[r] = view[r] * l->vector[0] + view[4 + r] * l->vector[1] + view[8 + r] * l->vector[2];
            double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            for (int r = 0; r < 3; ++r)
                v[r] /= len;
        } else if (l->kind == MS_RENDER_LIGHT_POINT) {
            for (int r = 0; r < 3; ++r)
                v[r] = view[r] * l->vector[0] + view[4 + r] * l->vector[1] + view[8 + r] * l->vector[2] + view[12 + r];
        }
        for (int r = 0; r < 3; ++r) {
            eye[4 * i + r] = (float)v[r];
            colour[3 * i + r] = l->colour[r];
        }
        eye[4 * i + 3] = l->kind == MS_RENDER_LIGHT_DIRECTIONAL ? 0.0f : (l->kind == MS_RENDER_LIGHT_POINT ? 1.0f : 2.0f);
        range[i] = (float)(l->kind == MS_RENDER_LIGHT_POINT ? l->range : 1.0);
    }
    glUniform1i(p->light_count, (GLint)o->light_count);
    glUniform4fv(p->light_eye, MS_RENDER_MAX_LIGHTS, eye);
    glUniform3fv(p->light_colour, MS_RENDER_MAX_LIGHTS, colour);
    glUniform1fv(p->light_range, MS_RENDER_MAX_LIGHTS, range);
}

/* The frame's uniforms: camera, shading, material, lights, effects' inputs. */
static void set_frame_uniforms(const ms_render *r, const ms_render_program *p, const ms_render_options *o,
                               const ms_camera *camera, const double view[16], const double proj[16],
                               const double model_view[16], double scale, bool tessellated)
{
    float projection[16], world_to_eye[9];
    for (int i = 0; i < 16; ++i)
        projection[i] = (float)proj[i];
    for (int col = 0; col < 3; ++col)
        for (int row = 0; row < 3; ++row)
            world_to_eye[3 * col + row] = (float)(model_view[4 * col + row] / scale);
    glUseProgram(p->program);
    glUniformMatrix4fv(p->projection, 1, GL_FALSE, projection);
    glUniformMatrix3fv(p->world_to_eye, 1, GL_FALSE, world_to_eye);
    glUniform2f(p->viewport, (float)lround(camera->width), (float)lround(camera->height));
    glUniform1i(p->shading, (int)o->shading);
    glUniform1i(p->apo_nearest, o->apo_nearest);
    glUniform1i(p->apo_filter, o->apo_filter);
    glUniform1i(p->smooth, o->smooth);
    glUniform3fv(p->albedo, 1, o->albedo);
    set_lights(p, o, view);
    /* uniforms of effects not compiled in have location -1: GL ignores them */
    glUniform1f(p->specular, o->specular);
    glUniform1f(p->shininess, o->shininess);
    glUniform1i(p->two_sided, o->two_sided);
    glUniform1f(p->haze_density, o->haze_density);
    glUniform3fv(p->haze_colour, 1, o->haze_colour);
    glUniform1f(p->dissolve, o->dissolve);
    if (tessellated) {
        glUniform1f(p->tess_pixels, o->tess_pixels_per_level);
        glUniform1f(p->disp_amplitude, o->displacement_amplitude);
        glUniform1f(p->disp_radius, o->displacement_radius);
        glUniform1f(p->disp_spacing, 1.0f / sqrtf(o->displacement_density));
        glUniform1ui(p->disp_seed, o->displacement_seed);
        glPatchParameteri(GL_PATCH_VERTICES, 3);
    }
    glUniform1i(p->section_count, (GLint)o->section_count);
    glUniform3f(p->section_colour, o->section_colour[0] / 255.0f, o->section_colour[1] / 255.0f,
                o->section_colour[2] / 255.0f);
    for (unsigned k = 0; k < MS_SECTIONS_MAX; ++k) {
        if (k < o->section_count)
            glEnable(GL_CLIP_DISTANCE0 + k);
        else
            glDisable(GL_CLIP_DISTANCE0 + k);
    }
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_BUFFER, r->texels.texture);
    glUniform1i(p->apo_words, 0);
}

/* The sections in the cell's local frame for gl_ClipDistance (>= 0 kept): the
 * model point origin + side * c is kept where a . (origin + side c) + d <= 0. */
static void set_cell_sections(const ms_render_program *p, const ms_render_options *o, const double origin[3],
                              double side)
{
    float planes[4 * MS_SECTIONS_MAX] = {0};
    for (unsigned k = 0; k < o->section_count; ++k) {
        const double *s = o->sections[k];
        for (int a = 0; a < 3; ++a)
            planes[4 * k + a] = (float)(-s[a] * side);
        planes[4 * k + 3] = (float)-(s[0] * origin[0] + s[1] * origin[1] + s[2] * origin[2] + s[3]);
    }
    glUniform4fv(p->section_plane, MS_SECTIONS_MAX, planes);
}

/* Clears the bound framebuffer to the options' background (sRGB-encoded but
 * for NORMALS, 0 for CELL_ID) and depth 1. */
static void clear_frame(const ms_render_options *o)
{
    float bg[3] = {0, 0, 0};
    for (int a = 0; a < 3 && o->shading != MS_SHADING_CELL_ID; ++a) {
        float c = isfinite(o->background[a]) ? o->background[a] : 0.0f;
        bg[a] = o->shading == MS_SHADING_NORMALS ? c : srgb_encode(c);
    }
    glClearColor(bg[0], bg[1], bg[2], o->shading == MS_SHADING_CELL_ID ? 0.0f : 1.0f);
    glClearDepth(1.0);
    glDepthMask(GL_TRUE);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDisable(GL_SCISSOR_TEST);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
}

/* The effects of the program that changed the picture in this draw. */
static unsigned effects_ran(const ms_render_program *p, const ms_render_options *o, uint32_t drawn,
                            bool any_detail, bool tessellated)
{
    unsigned ran = 0;
    bool lit = o->shading == MS_SHADING_LIT || o->shading == MS_SHADING_CELLS;
    if (drawn && any_detail && o->shading != MS_SHADING_CELL_ID && o->shading != MS_SHADING_ALBEDO)
        ran |= MS_EFFECT_DETAIL_NORMALS;
    if (drawn && lit && o->specular > 0.0f && o->light_count > 0)
        ran |= MS_EFFECT_SPECULAR;
    if (drawn && lit && o->two_sided)
        ran |= MS_EFFECT_TWO_SIDED;
    if (drawn && lit && o->haze_density > 0.0f)
        ran |= MS_EFFECT_HAZE;
    if (drawn && tessellated)
        ran |= MS_EFFECT_DISPLACEMENT;
    return ran & p->effects;
}

/* The fixed state every draw of a model's cells runs with. */
static void draw_state(void)
{
    glDepthMask(GL_TRUE);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glDisable(GL_BLEND);
    glDisable(GL_FRAMEBUFFER_SRGB); /* the shader encodes sRGB itself */
}

void ms_render_warm_up(ms_render *r, const ms_render_program *p)
{
    static const uint8_t vertices[3 * 16] = {0};
    static const uint32_t indices[3] = {0, 1, 2};
    GLuint vao, buffers[2];
    glGenVertexArrays(1, &vao);
    glGenBuffers(2, buffers);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, buffers[0]);
    glBufferData(GL_ARRAY_BUFFER, sizeof vertices, vertices, GL_STATIC_DRAW);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, buffers[1]);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, sizeof indices, indices, GL_STATIC_DRAW);
    ms_render_gl_add(&r->gl, sizeof vertices + sizeof indices);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, NULL);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 4, (const void *)(uintptr_t)36);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    draw_state();
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glUseProgram(p->program);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_BUFFER, r->texels.texture);
    glUniform1i(p->apo_words, 0);
    glDrawElements(GL_TRIANGLES, 3, GL_UNSIGNED_INT, NULL);
    glFinish();
    glBindVertexArray(0);
    glDeleteVertexArrays(1, &vao);
    glDeleteBuffers(2, buffers);
    ms_render_gl_sub(&r->gl, sizeof vertices + sizeof indices);
    glBindTexture(GL_TEXTURE_BUFFER, 0);
    glUseProgram(0);
}

ms_status ms_render_draw(ms_render *r, const ms_camera *camera, const ms_render_options *o,
                         ms_render_draw_stats *stats, ms_error *err)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!r || !o)
        return ms_error_set(err, MS_ERR_ARG, "render: no renderer or options");
    ms_status st = ms_render_camera_check(camera, err);
    if (st != MS_OK)
        return st;
    if ((unsigned)o->shading > MS_SHADING_ALBEDO)
        return ms_error_set(err, MS_ERR_ARG, "render: shading mode %d unknown", (int)o->shading);
    st = check_scene_options(o, err);
    if (st != MS_OK)
        return st;
    const ms_render_program *p;
    bool tessellated = o->displace && (o->effects & MS_EFFECT_DISPLACEMENT);
    /* A frame drawn without APO takes the program without the APO traversal:
     * the picture is the same (the block's #else is the plain path), but a
     * software rasteriser runs a compiled-in branch's code under a mask even
     * when no pixel takes it (llvmpipe: most of a frame's fragment time). */
    unsigned effects = o->apo ? o->effects : o->effects & ~(unsigned)MS_EFFECT_DETAIL_NORMALS;
    /* likewise colours, sections and the light loop: only what this draw uses */
    bool coloured = false;
    for (uint32_t k = 0; k < r->frame_cell_count && !coloured; ++k) {
        const render_cell *c = ms_render_cell_at(r, r->frame_cells[k]);
        coloured = c->mesh.vao && c->mesh.coloured;
    }
    bool wireframe = o->wireframe && o->shading != MS_SHADING_CELL_ID;
    st = ms_render_find_program(r, effects, ms_render_program_variant(o, coloured, wireframe, tessellated), wireframe,
                                tessellated, &p, err);
    if (st != MS_OK)
        return st;
    double view[16], proj[16];
    ms_render_camera_matrices(camera, view, proj);
    /* the model's placement goes into the view: cells are placed in doubles */
    double model_view[16];
    if (o->placed)
        mat4_mul(view, o->placement, model_view);
    else
        memcpy(model_view, view, sizeof model_view);
    double scale = o->placed ? sqrt(o->placement[0] * o->placement[0] + o->placement[1] * o->placement[1] +
                                    o->placement[2] * o->placement[2])
                             : 1.0;
    glViewport(0, 0, (int)lround(camera->width), (int)lround(camera->height));
    if (o->clear)
        clear_frame(o);
    draw_state();
    set_frame_uniforms(r, p, o, camera, view, proj, model_view, scale, tessellated);
    bool detail_program = (p->effects & MS_EFFECT_DETAIL_NORMALS) != 0;
    uint32_t cap = o->apo_depth_cap ? o->apo_depth_cap : UINT32_MAX;
    uint32_t drawn = 0;
    uint64_t triangles = 0;
    bool any_detail = false;
    for (uint32_t k = 0; k < r->frame_cell_count; ++k) {
        uint32_t cell = r->frame_cells[k];
        const render_cell *c = ms_render_cell_at(r, cell);
        if (!c->mesh.vao)
            continue;
        double origin[3], side;
        ms_render_cell_cube(&r->header, &c->record, origin, &side);
        float modelview[16], tint[3];
        ms_render_cell_modelview(model_view, origin, side, modelview);
        cell_tint(cell, tint);
        glUniformMatrix4fv(p->modelview, 1, GL_FALSE, modelview);
        set_cell_sections(p, o, origin, side);
        if (tessellated) {
            float cell_origin[3] = {(float)origin[0], (float)origin[1], (float)origin[2]};
            glUniform3fv(p->cell_origin, 1, cell_origin);
            glUniform1f(p->cell_side, (float)side);
        }
        glUniform1ui(p->cell_number, cell);
        glUniform3fv(p->cell_tint, 1, tint);
        glUniform1i(p->vertex_colour, c->mesh.coloured);
        bool apo_on = detail_program && o->apo && c->apo.count > 0;
        any_detail = any_detail || apo_on;
        glUniform1i(p->apo_on, apo_on);
        if (apo_on) {
            uint32_t last = c->apo.levels - 1;
            glUniform1i(p->apo_base, (GLint)c->apo.start);
            glUniform1i(p->apo_root_internal, c->apo.root_internal);
            glUniform1ui(p->apo_stop_depth, cap < last ? cap : last);
            glUniform1f(p->apo_footprint_scale,
                        o->apo_footprint ? ms_render_apo_footprint_scale(camera, side * scale) : 0.0f);
        }
        glBindVertexArray(c->mesh.vao);
        glDrawElements(tessellated ? GL_PATCHES : GL_TRIANGLES, (GLsizei)(3 * c->mesh.triangle_count),
                       GL_UNSIGNED_INT, NULL);
        drawn++;
        triangles += c->mesh.triangle_count;
    }
    glBindVertexArray(0);
    glBindTexture(GL_TEXTURE_BUFFER, 0);
    glUseProgram(0);
    for (unsigned k = 0; k < MS_SECTIONS_MAX; ++k) /* what draws next (text, impostors) is not cut */
        glDisable(GL_CLIP_DISTANCE0 + k);
    if (stats) {
        stats->cells_drawn = drawn;
        stats->triangles_drawn = triangles;
        stats->effects_compiled = p->effects;
        stats->effects_ran = effects_ran(p, o, drawn, any_detail, tessellated);
    }
    GLenum e = glGetError();
    if (e != GL_NO_ERROR)
        return ms_error_set(err, e == GL_OUT_OF_MEMORY ? MS_ERR_NOMEM : MS_ERR_UNSUPPORTED,
                            "render: GL error 0x%x while drawing", e);
    return MS_OK;
}
