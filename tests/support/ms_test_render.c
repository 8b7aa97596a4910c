/* Scaffolding for the renderer's tests (ms_test_render.h). */
#include <dlfcn.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_bake.h"
#include "ms_demo_model.h"
#include "ms_gl_window.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_test_render.h"

/* Mesa's software driver keeps a few allocations referenced only from its own
 * data; once glfwTerminate unloads it, LeakSanitizer sees them as leaks (in an
 * "unknown module"). Keeping the driver loaded to the end (RTLD_NODELETE) keeps
 * them reachable, so no suppression is needed. */
static void pin_gl_driver(void)
{
    static const char *const drivers[] = {"swrast_dri.so", "/usr/lib/x86_64-linux-gnu/dri/swrast_dri.so"};
    for (size_t i = 0; i < sizeof drivers / sizeof *drivers; ++i) {
        void *h = dlopen(drivers[i], RTLD_NOW | RTLD_NOLOAD | RTLD_NODELETE);
        if (h) {
            dlclose(h);
            return;
        }
    }
}

void ms_test_gl_start(ms_test_gl *gl)
{
    memset(gl, 0, sizeof *gl);
    char why[256];
    if (!ms_test_display_start(&gl->display, why, sizeof why))
        fail_msg("no display: %s", why);
    ms_error err;
    if (ms_gl_window_new(64, 64, "test", false, &gl->window, &err) != MS_OK) {
        ms_test_display_stop(&gl->display);
        fail_msg("%s", err.text);
    }
    pin_gl_driver();
}

void ms_test_gl_stop(ms_test_gl *gl)
{
    ms_gl_window_free(gl->window);
    ms_test_display_stop(&gl->display);
    memset(gl, 0, sizeof *gl);
}

int ms_test_gl_group_setup(void **state)
{
    ms_test_gl *gl = malloc(sizeof *gl);
    if (!gl)
        return -1;
    ms_test_gl_start(gl);
    *state = gl;
    return 0;
}

int ms_test_gl_group_teardown(void **state)
{
    ms_test_gl_stop(*state);
    free(*state);
    return 0;
}

void ms_test_fbo_new(ms_test_fbo *f, int width, int height)
{
    memset(f, 0, sizeof *f);
    f->width = width;
    f->height = height;
    glGenFramebuffers(1, &f->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, f->fbo);
    glGenRenderbuffers(1, &f->colour);
    glBindRenderbuffer(GL_RENDERBUFFER, f->colour);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA32F, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, f->colour);
    glGenRenderbuffers(1, &f->depth);
    glBindRenderbuffer(GL_RENDERBUFFER, f->depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, f->depth);
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    assert_int_equal(glCheckFramebufferStatus(GL_FRAMEBUFFER), GL_FRAMEBUFFER_COMPLETE);
}

void ms_test_fbo_free(ms_test_fbo *f)
{
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glDeleteRenderbuffers(1, &f->colour);
    glDeleteRenderbuffers(1, &f->depth);
    glDeleteFramebuffers(1, &f->fbo);
    memset(f, 0, sizeof *f);
}

void ms_test_fbo_read(const ms_test_fbo *f, float *rgba, float *depth)
{
    glBindFramebuffer(GL_READ_FRAMEBUFFER, f->fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    if (rgba)
        glReadPixels(0, 0, f->width, f->height, GL_RGBA, GL_FLOAT, rgba);
    if (depth)
        glReadPixels(0, 0, f->width, f->height, GL_DEPTH_COMPONENT, GL_FLOAT, depth);
    assert_int_equal(glGetError(), GL_NO_ERROR);
}

ms_archive *ms_test_render_bake(const char *input, const char *dir, const char *name, unsigned bits,
                                uint32_t min_triangles, unsigned apo_max_depth)
{
    return ms_test_render_bake_apo(input, dir, name, bits, min_triangles, apo_max_depth, true);
}

ms_archive *ms_test_render_bake_apo(const char *input, const char *dir, const char *name, unsigned bits,
                                    uint32_t min_triangles, unsigned apo_max_depth, bool full_normals)
{
    ms_bake_options o;
    ms_bake_options_default(&o);
    o.input = input;
    o.archive_dir = dir;
    o.name = name;
    o.bits = bits;
    o.min_triangles = min_triangles;
    o.threads = 2;
    /* every cell gets a chunk (the default leaves none where the geometry
     * renders the input, i.e. in every leaf): the shader is tested on chunks */
    o.apo.every_cell = true;
    o.apo.full_normals = full_normals;
    if (apo_max_depth)
        o.apo.max_depth = apo_max_depth;
    ms_bake_report rep;
    ms_error err;
    if (ms_bake(&o, &rep, &err) != MS_OK)
        fail_msg("bake %s: %s", input, err.text);
    ms_archive *a;
    if (ms_archive_open(rep.archive_path, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    return a;
}

ms_archive *ms_test_render_bake_demo(uint32_t grid, const char *dir, unsigned bits, uint32_t min_triangles,
                                     unsigned apo_max_depth)
{
    ms_demo_model model = {grid, 0};
    ms_mesh mesh = {0};
    ms_error err;
    if (ms_demo_build(&model, &mesh, &err) != MS_OK)
        fail_msg("%s", err.text);
    char path[1024];
    snprintf(path, sizeof path, "%s/demo.ply", dir);
    if (ms_ply_write(path, &mesh, true, false, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_mesh_free(&mesh);
    return ms_test_render_bake(path, dir, "demo", bits, min_triangles, apo_max_depth);
}

void ms_test_render_camera(const ms_archive_header *h, const double dir[3], double distance, double fovy_degrees,
                           int width, int height, ms_camera *camera)
{
    double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    double centre[3], position[3], up[3] = {0, 1, 0};
    for (int a = 0; a < 3; ++a) {
        centre[a] = h->box_origin[a] + 0.5 * h->box_side;
        position[a] = centre[a] + dir[a] / len * distance * h->box_side;
    }
    if (fabs(dir[1]) > 0.9 * len)
        up[1] = 0, up[2] = 1;
    double d = distance * h->box_side, reach = 0.87 * h->box_side;
    ms_error err;
    if (ms_camera_look_at(position, centre, up, fovy_degrees, width, height, d - reach > 1e-3 * d ? d - reach : 1e-3 * d,
                          d + reach, camera, &err) != MS_OK)
        fail_msg("%s", err.text);
}

void ms_test_render_view(ms_view *view, const ms_camera *camera, double tolerance_px, ms_view_mesh *mesh)
{
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    params.tolerance_px = tolerance_px;
    ms_error err;
    for (int round = 0; round < 64; ++round) {
        ms_view_select(view, camera, &params, NULL);
        ms_view_apply_report rep;
        if (ms_view_apply(view, &rep, &err) != MS_OK)
            fail_msg("%s", err.text);
        if (rep.splits + rep.merges + rep.refined + rep.coarsened == 0)
            break;
    }
    if (ms_view_stitch(view, NULL, mesh, &err) != MS_OK)
        fail_msg("%s", err.text);
}

void ms_test_render_apo(const ms_archive *a, const ms_view_mesh *mesh, unsigned max_levels, bool mid_level,
                        ms_core_apo_chunk **chunks, size_t *count)
{
    uint32_t n = ms_archive_get_header(a)->cell_count;
    bool *drawing = calloc(n, sizeof *drawing);
    assert_non_null(drawing);
    for (size_t t = 0; t < mesh->triangle_count; ++t)
        drawing[mesh->triangle_cell[t]] = true;
    *chunks = calloc(n, sizeof **chunks);
    assert_non_null(*chunks);
    *count = 0;
    for (uint32_t c = 0; c < n; ++c) {
        const ms_archive_cell *rec = ms_archive_get_cell(a, c);
        if (!drawing[c] || rec->apo_levels == 0)
            continue;
        unsigned levels = max_levels && max_levels < rec->apo_levels ? max_levels : rec->apo_levels;
        size_t stored;
        const uint8_t *data = ms_archive_apo(a, c, &stored);
        uint32_t length = ms_archive_apo_prefix(a, c, levels - 1, NULL);
        if (mid_level && levels < rec->apo_levels)
            length += (ms_archive_apo_prefix(a, c, levels, NULL) - length) / 2;
        assert_true(length <= stored);
        (*chunks)[(*count)++] = (ms_core_apo_chunk){c, levels, (uint8_t *)(uintptr_t)data, length, NULL};
    }
    free(drawing);
}

void ms_test_render_show(ms_render *render, const ms_view_mesh *mesh, const ms_core_apo_chunk *apo, size_t apo_count,
                         ms_render_upload_stats *up)
{
    ms_error err;
    if (ms_render_set_frame(render, mesh, apo, apo_count, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_render_upload_stats local;
    if (ms_render_upload(render, UINT64_MAX, up ? up : &local, &err) != MS_OK)
        fail_msg("%s", err.text);
}

void ms_test_render_unit_header(unsigned n, uint32_t cell_count, ms_archive_header *h)
{
    memset(h, 0, sizeof *h);
    h->box_side = 1.0;
    h->bits = 16;
    h->n = (uint8_t)n;
    h->root_bits = 7;
    h->cell_count = cell_count;
}

ms_render *ms_test_render_one_cell(unsigned n, const double *positions, size_t vertex_count, const uint32_t *triangles,
                                   size_t triangle_count)
{
    ms_archive_header h;
    ms_test_render_unit_header(n, 1, &h);
    ms_archive_cell cell;
    memset(&cell, 0, sizeof cell);
    cell.parent = cell.first_child = MS_ARCHIVE_NONE;
    ms_render *r;
    ms_error err;
    if (ms_render_new(&h, &cell, &r, &err) != MS_OK)
        fail_msg("%s", err.text);
    uint32_t *root_cell = calloc(triangle_count ? triangle_count : 1, sizeof *root_cell);
    assert_non_null(root_cell);
    ms_view_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    mesh.vertex_count = vertex_count;
    mesh.triangle_count = triangle_count;
    mesh.positions = (double *)positions;
    mesh.triangles = (uint32_t *)triangles;
    mesh.triangle_cell = root_cell;
    ms_test_render_show(r, &mesh, NULL, 0, NULL);
    free(root_cell);
    return r;
}

void ms_test_render_open(const ms_archive *archive, ms_render **render, ms_view **view)
{
    ms_error err;
    if (ms_render_new(ms_archive_get_header(archive), ms_archive_get_cell(archive, 0), render, &err) != MS_OK)
        fail_msg("%s", err.text);
    if (ms_view_create_from_archive(archive, view, &err) != MS_OK)
        fail_msg("%s", err.text);
}

void ms_test_render_look(const ms_archive *archive, ms_view *view, const double dir[3], int width, int height,
                         double tolerance_px, ms_camera *camera, ms_view_mesh *mesh)
{
    ms_test_render_camera(ms_archive_get_header(archive), dir, 1.1, 40.0, width, height, camera);
    ms_test_render_view(view, camera, tolerance_px, mesh);
}
