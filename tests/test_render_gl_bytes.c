/* The renderer's GL memory count (ms_render.h, "GL memory"; issue 32 item 5):
 * after uploading a known small frame the bytes reported are exactly the
 * buffers computed here from the frame (per drawing cell, its distinct
 * vertices x 16 bytes, position and packed normal, plus 12 bytes per
 * triangle; the APO texel buffer's capacity as GL reports its size, and the
 * words handed out as the archive's prefix words x 4), counted from the first
 * piece of an upload, both meshes while a cell refines, and back exactly to
 * the texel buffer when the cells leave the frame; the peak is the largest of
 * those states. The impostor's and the offscreen framebuffer's counts are
 * their textures' and renderbuffers' sizes. A frame with vertex colours
 * counts 20 bytes per vertex (4 of colour), as GL reports each buffer. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_render.h"
#include "ms_render_impostor.h"
#include "ms_render_internal.h"
#include "ms_test.h"
#include "ms_test_render.h"
#include "ms_viewer_readback.h"

/* What the renderer uploads per vertex (12 bytes of position, 4 of packed
 * normal) and per triangle (three 32-bit indices): ms_render.h. */
#define VERTEX_BYTES 16u
#define COLOURED_VERTEX_BYTES 20u /* and 4 of colour, with vertex colours */
#define TRIANGLE_BYTES 12u
/* The warm-up's triangle (ms_render_warm_up): 3 vertices and 3 indices. */
#define WARM_UP_BYTES (3u * VERTEX_BYTES + 3u * 4u)

/* The bytes of each drawing cell's buffers in mesh: distinct vertices of its
 * triangles x 16 (20 with colours) + triangles x 12; bytes[c] for c < cells. */
static void cell_bytes(const ms_view_mesh *m, uint32_t cells, uint64_t *bytes)
{
    memset(bytes, 0, cells * sizeof *bytes);
    for (uint32_t c = 0; c < cells; ++c) {
        bool *used = calloc(m->vertex_count + 1, sizeof *used);
        assert_non_null(used);
        for (size_t t = 0; t < m->triangle_count; ++t) {
            if (m->triangle_cell[t] != c)
                continue;
            bytes[c] += TRIANGLE_BYTES;
            for (int k = 0; k < 3; ++k) {
                uint32_t v = m->triangles[3 * t + (size_t)k];
                if (!used[v])
                    used[v] = true, bytes[c] += m->colours ? COLOURED_VERTEX_BYTES : VERTEX_BYTES;
            }
        }
        free(used);
    }
}

static uint64_t sum(const uint64_t *v, size_t n)
{
    uint64_t s = 0;
    for (size_t i = 0; i < n; ++i)
        s += v[i];
    return s;
}

static ms_render_memory_stats memory(const ms_render *r)
{
    ms_render_memory_stats m;
    ms_render_memory(r, &m);
    assert_int_equal(m.gl_bytes, m.mesh_bytes + m.texel_bytes);
    assert_true(m.gl_bytes_peak >= m.gl_bytes);
    return m;
}

/* The texel buffer's size as GL has it. */
static uint64_t texel_buffer_size(const ms_render *r)
{
    GLint64 size = 0;
    glBindBuffer(GL_TEXTURE_BUFFER, ms_render_texel_buffer(r));
    glGetBufferParameteri64v(GL_TEXTURE_BUFFER, GL_BUFFER_SIZE, &size);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    return (uint64_t)size;
}

static void set_frame(ms_render *r, const ms_view_mesh *mesh, const ms_core_apo_chunk *apo, size_t count)
{
    ms_error err;
    if (ms_render_set_frame(r, mesh, apo, count, &err) != MS_OK)
        fail_msg("%s", err.text);
}

static ms_render_upload_stats upload(ms_render *r, uint64_t budget)
{
    ms_render_upload_stats s;
    ms_error err;
    if (ms_render_upload(r, budget, &s, &err) != MS_OK)
        fail_msg("%s", err.text);
    return s;
}

#define CELLS 9 /* a root and its 8 children (n = 2) */

/* Twelve vertices; cells 1, 2 and 5 draw (cell 2 shares a vertex with cell 1,
 * which is uploaded once per cell). */
static const double positions[12 * 3] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 0, 0, 2, 1, 0,
                                         0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1, 2, 0, 1, 2, 1, 1};
static const uint32_t triangles[6 * 3] = {0, 1, 2, 0, 2, 3,            /* cell 1: 4 vertices */
                                          1, 4, 5,                     /* cell 2: 3 vertices */
                                          6, 7, 8, 6, 8, 9, 7, 10, 11}; /* cell 5: 6 vertices */
static const uint32_t triangle_cells[6] = {1, 1, 2, 5, 5, 5};

static ms_render *nine_cells(void)
{
    ms_archive_header h;
    ms_test_render_unit_header(2, CELLS, &h);
    ms_archive_cell cells[CELLS];
    memset(cells, 0, sizeof cells);
    for (uint32_t i = 0; i < CELLS; ++i) {
        cells[i].parent = i ? 0 : MS_ARCHIVE_NONE;
        cells[i].first_child = i ? MS_ARCHIVE_NONE : 1;
        cells[i].level = i ? 1 : 0;
        if (i)
            for (int a = 0; a < 3; ++a)
                cells[i].position[a] = ((i - 1) >> a) & 1u;
    }
    ms_render *r;
    ms_error err;
    if (ms_render_new(&h, cells, &r, &err) != MS_OK)
        fail_msg("%s", err.text);
    return r;
}

/* A hand-made frame: the count at each step of its life, exactly. */
static void test_frame_counted_exactly(void **state)
{
    (void)state;
    ms_render *r = nine_cells();
    GLint max_words = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_words);
    uint64_t texels = 4ull * (max_words > 0 && max_words < 65536 ? (uint64_t)max_words : 65536u);
    ms_render_memory_stats m = memory(r);
    assert_int_equal(m.texel_bytes, texels);
    assert_int_equal(texel_buffer_size(r), texels);
    assert_int_equal(m.mesh_bytes, 0);
    assert_int_equal(m.texel_used_bytes, 0);
    assert_int_equal(m.gl_bytes_peak, texels + WARM_UP_BYTES); /* the warm-up drew after the texels were made */

    ms_view_mesh mesh = {.vertex_count = 12,
                         .triangle_count = 6,
                         .positions = (double *)positions,
                         .triangles = (uint32_t *)triangles,
                         .triangle_cell = (uint32_t *)triangle_cells};
    uint64_t bytes[CELLS];
    cell_bytes(&mesh, CELLS, bytes);
    assert_int_equal(bytes[1], 4 * VERTEX_BYTES + 2 * TRIANGLE_BYTES);
    assert_int_equal(bytes[2], 3 * VERTEX_BYTES + 1 * TRIANGLE_BYTES);
    assert_int_equal(bytes[5], 6 * VERTEX_BYTES + 3 * TRIANGLE_BYTES);
    set_frame(r, &mesh, NULL, 0);
    assert_int_equal(memory(r).gl_bytes, texels); /* queued, nothing on the GPU yet */
    /* one byte sent: the first queued cell's buffers are held whole */
    ms_render_upload_stats up = upload(r, 1);
    assert_int_equal(up.bytes, 1);
    m = memory(r);
    assert_int_equal(m.mesh_bytes, bytes[1]);
    assert_int_equal(m.gl_bytes, texels + bytes[1]);
    upload(r, UINT64_MAX);
    m = memory(r);
    uint64_t all = sum(bytes, CELLS);
    assert_int_equal(m.mesh_bytes, all);
    assert_int_equal(m.gl_bytes, texels + all);
    assert_int_equal(m.gl_bytes_peak, texels + all);

    /* cells 1 and 5 leave: their buffers go at once */
    ms_view_mesh only2 = {.vertex_count = 12,
                          .triangle_count = 1,
                          .positions = (double *)positions,
                          .triangles = (uint32_t *)&triangles[6],
                          .triangle_cell = (uint32_t *)&triangle_cells[2]};
    set_frame(r, &only2, NULL, 0);
    assert_int_equal(memory(r).gl_bytes, texels + bytes[2]);

    /* cell 2 refines into the two triangles of cell 1's vertices: while its
     * new mesh goes up, the old one still draws, both held */
    const uint32_t refined_cells[2] = {2, 2};
    ms_view_mesh refined = {.vertex_count = 12,
                            .triangle_count = 2,
                            .positions = (double *)positions,
                            .triangles = (uint32_t *)triangles,
                            .triangle_cell = (uint32_t *)refined_cells};
    uint64_t refined_bytes[CELLS];
    cell_bytes(&refined, CELLS, refined_bytes);
    set_frame(r, &refined, NULL, 0);
    upload(r, 1);
    assert_int_equal(memory(r).gl_bytes, texels + bytes[2] + refined_bytes[2]);
    upload(r, UINT64_MAX);
    assert_int_equal(memory(r).gl_bytes, texels + refined_bytes[2]);

    /* nothing drawn: back to the texel buffer alone, the peak kept */
    ms_view_mesh empty = {0};
    set_frame(r, &empty, NULL, 0);
    m = memory(r);
    assert_int_equal(m.gl_bytes, texels);
    assert_int_equal(m.mesh_bytes, 0);
    uint64_t peak = all > bytes[2] + refined_bytes[2] ? all : bytes[2] + refined_bytes[2];
    assert_int_equal(m.gl_bytes_peak, texels + peak);
    ms_render_free(r);

    ms_render_memory(NULL, &m);
    assert_int_equal(m.gl_bytes + m.gl_bytes_peak, 0);
}

/* GL's own size of a buffer. */
static uint64_t buffer_size(GLuint buffer)
{
    GLint64 size = 0;
    glBindBuffer(GL_ARRAY_BUFFER, buffer);
    glGetBufferParameteri64v(GL_ARRAY_BUFFER, GL_BUFFER_SIZE, &size);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    return (uint64_t)size;
}

/* The hand-made frame with vertex colours: 20 bytes a vertex, each cell's
 * buffers as GL has them; the same frame without colours goes back to 16. */
static void test_colours_counted(void **state)
{
    (void)state;
    ms_render *r = nine_cells();
    uint64_t texels = memory(r).texel_bytes;
    uint8_t colours[12 * 4];
    for (size_t i = 0; i < sizeof colours; ++i)
        colours[i] = (uint8_t)(37 * i);
    ms_view_mesh mesh = {.vertex_count = 12,
                         .triangle_count = 6,
                         .positions = (double *)positions,
                         .triangles = (uint32_t *)triangles,
                         .triangle_cell = (uint32_t *)triangle_cells,
                         .colours = colours};
    uint64_t bytes[CELLS];
    cell_bytes(&mesh, CELLS, bytes);
    assert_int_equal(bytes[1], 4 * COLOURED_VERTEX_BYTES + 2 * TRIANGLE_BYTES);
    assert_int_equal(bytes[5], 6 * COLOURED_VERTEX_BYTES + 3 * TRIANGLE_BYTES);
    set_frame(r, &mesh, NULL, 0);
    ms_render_upload_stats up = upload(r, UINT64_MAX);
    uint64_t all = sum(bytes, CELLS);
    assert_int_equal(up.bytes, all);
    ms_render_memory_stats m = memory(r);
    assert_int_equal(m.mesh_bytes, all);
    assert_int_equal(m.gl_bytes, texels + all);
    static const uint32_t drawing[3] = {1, 2, 5};
    for (int k = 0; k < 3; ++k) {
        const gpu_mesh *g = &ms_render_cell_at(r, drawing[k])->mesh;
        assert_true(g->coloured);
        assert_int_equal(buffer_size(g->vbo) + buffer_size(g->ibo), bytes[drawing[k]]);
        assert_int_equal(g->gl_bytes, bytes[drawing[k]]);
    }
    mesh.colours = NULL;
    uint64_t grey[CELLS];
    cell_bytes(&mesh, CELLS, grey);
    set_frame(r, &mesh, NULL, 0);
    upload(r, UINT64_MAX);
    m = memory(r);
    assert_int_equal(m.mesh_bytes, sum(grey, CELLS));
    assert_int_equal(sum(bytes, CELLS) - sum(grey, CELLS), 13 * 4); /* 13 cell vertices, 4 bytes each */
    /* the cells refine in turn (1, 2, 5), each holding its old and new buffers
     * while the new go up: the peak is the largest of those states */
    uint64_t held = all, peak = all;
    for (int k = 0; k < 3; ++k) {
        uint32_t c = drawing[k];
        peak = held + grey[c] > peak ? held + grey[c] : peak;
        held = held + grey[c] - bytes[c];
    }
    assert_int_equal(peak, all + 104); /* the last: 88 + 60 + 156 held, 132 more */
    assert_int_equal(m.gl_bytes_peak, texels + peak);
    ms_render_free(r);
}

/* A baked model's view with every APO level: the meshes from the view, the
 * texel words from the archive, the texel buffer's size from GL. */
static void test_view_with_apo(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_archive *archive = ms_test_render_bake_demo(24, dir, 14, 2000, 0);
    uint32_t cells = ms_archive_get_header(archive)->cell_count;
    ms_render *r;
    ms_view *view;
    ms_test_render_open(archive, &r, &view);
    const double direction[3] = {1.0, 0.5, 0.7};
    ms_camera camera;
    ms_view_mesh mesh = {0};
    ms_test_render_look(archive, view, direction, 160, 120, 1.0, &camera, &mesh);
    ms_core_apo_chunk *apo;
    size_t apo_count;
    ms_test_render_apo(archive, &mesh, 0, false, &apo, &apo_count);
    assert_true(apo_count > 1);
    uint64_t words = 0;
    for (size_t i = 0; i < apo_count; ++i) {
        uint32_t count;
        ms_archive_apo_prefix(archive, apo[i].cell, apo[i].levels - 1, &count);
        words += count;
    }
    uint64_t *bytes = malloc(cells * sizeof *bytes);
    assert_non_null(bytes);
    cell_bytes(&mesh, cells, bytes);
    ms_render_upload_stats up;
    ms_test_render_show(r, &mesh, apo, apo_count, &up);
    assert_int_equal(up.cells_pending, 0);
    ms_render_memory_stats m = memory(r);
    assert_int_equal(m.mesh_bytes, sum(bytes, cells));
    assert_int_equal(m.texel_used_bytes, 4 * words);
    assert_int_equal(m.texel_bytes, texel_buffer_size(r));
    assert_true(m.texel_bytes >= m.texel_used_bytes);
    print_message("%zu cells with APO: %llu mesh bytes, %llu texel bytes of %llu held, peak %llu\n", apo_count,
                  (unsigned long long)m.mesh_bytes, (unsigned long long)m.texel_used_bytes,
                  (unsigned long long)m.texel_bytes, (unsigned long long)m.gl_bytes_peak);
    ms_view_mesh empty = {0};
    set_frame(r, &empty, NULL, 0);
    m = memory(r);
    assert_int_equal(m.mesh_bytes, 0);
    assert_int_equal(m.texel_used_bytes, 0);
    assert_int_equal(m.gl_bytes, texel_buffer_size(r)); /* the texel buffer does not shrink */
    free(bytes);
    free(apo);
    ms_view_mesh_free(&mesh);
    ms_view_destroy(view);
    ms_render_free(r);
    ms_archive_close(archive);
    ms_test_rmdir(dir);
}

/* The impostor's two square textures and quad; the offscreen framebuffer's
 * two renderbuffers, their sizes as GL reports them. */
static void test_impostor_and_target(void **state)
{
    (void)state;
    ms_impostor *imp;
    ms_error err;
    if (ms_impostor_new(64, &imp, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(ms_impostor_gl_bytes(imp), 64u * 64u * (4u + 4u) + 8u * sizeof(float));
    ms_impostor_free(imp);
    assert_int_equal(ms_impostor_gl_bytes(NULL), 0);

    ms_viewer_target t;
    if (ms_viewer_target_init(&t, 48, 20, &err) != MS_OK)
        fail_msg("%s", err.text);
    GLint bits[2][6];
    const GLenum names[6] = {GL_RENDERBUFFER_RED_SIZE,   GL_RENDERBUFFER_GREEN_SIZE, GL_RENDERBUFFER_BLUE_SIZE,
                             GL_RENDERBUFFER_ALPHA_SIZE, GL_RENDERBUFFER_DEPTH_SIZE, GL_RENDERBUFFER_STENCIL_SIZE};
    const GLuint buffers[2] = {t.colour, t.depth};
    uint64_t stored_bits = 0;
    for (int b = 0; b < 2; ++b) {
        glBindRenderbuffer(GL_RENDERBUFFER, buffers[b]);
        for (int k = 0; k < 6; ++k) {
            glGetRenderbufferParameteriv(GL_RENDERBUFFER, names[k], &bits[b][k]);
            stored_bits += (uint64_t)bits[b][k];
        }
    }
    glBindRenderbuffer(GL_RENDERBUFFER, 0);
    /* RGBA8 is 32 bits; depth 24 (with no stencil) is stored in 32: count 4 bytes */
    assert_int_equal(stored_bits, 32 + 24);
    assert_int_equal(ms_viewer_target_gl_bytes(&t), 48u * 20u * 8u);
    ms_viewer_target_free(&t);
    assert_int_equal(ms_viewer_target_gl_bytes(&t), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frame_counted_exactly),
        cmocka_unit_test(test_colours_counted),
        cmocka_unit_test(test_view_with_apo),
        cmocka_unit_test(test_impostor_and_target),
    };
    return cmocka_run_group_tests(tests, ms_test_gl_group_setup, ms_test_gl_group_teardown);
}
