/* The renderer's input handling: absurd arguments give one-line errors, never
 * crashes, and leave the renderer usable; corrupt APO bytes leave a cell on its
 * geometric normals; the prefix reader (levels found from the words) gives the
 * archive reader's words for every cell and prefix; the texel buffer's ranges
 * are handed out and merged back; the camera helpers agree with each other.
 * Everything is freed (ASan's leak check). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include "ms_apo_stream.h"
#include "ms_render.h"
#include "ms_render_internal.h"
#include "ms_test.h"
#include "ms_test_render.h"

#define WIDTH 96
#define HEIGHT 72

static ms_test_gl gl;
static char dir[512];
static ms_archive *archive;

static void expect(ms_status got, ms_status want, const ms_error *err)
{
    if (got != want)
        fail_msg("status %d, expected %d (%s)", got, want, got ? err->text : "ok");
    if (want != MS_OK) {
        assert_true(err->text[0] != 0);
        assert_null(strchr(err->text, '\n'));
    }
}

static void test_bad_model(void **state)
{
    (void)state;
    const ms_archive_header *h = ms_archive_get_header(archive);
    const ms_archive_cell *cells = ms_archive_get_cell(archive, 0);
    ms_render *r = (ms_render *)(uintptr_t)1;
    ms_error err;
    expect(ms_render_new(NULL, cells, &r, &err), MS_ERR_ARG, &err);
    assert_null(r);
    expect(ms_render_new(h, cells, NULL, &err), MS_ERR_ARG, &err);
    ms_archive_header bad = *h;
    bad.cell_count = 0;
    expect(ms_render_new(&bad, cells, &r, &err), MS_ERR_ARG, &err);
    bad = *h;
    bad.box_side = 0.0;
    expect(ms_render_new(&bad, cells, &r, &err), MS_ERR_ARG, &err);
    bad.box_side = NAN;
    expect(ms_render_new(&bad, cells, &r, &err), MS_ERR_ARG, &err);
    bad = *h;
    bad.box_origin[1] = INFINITY;
    expect(ms_render_new(&bad, cells, &r, &err), MS_ERR_ARG, &err);
    bad = *h;
    bad.n = 1;
    expect(ms_render_new(&bad, cells, &r, &err), MS_ERR_ARG, &err);
    size_t n = h->cell_count;
    ms_archive_cell *copy = malloc(n * sizeof *copy);
    memcpy(copy, cells, n * sizeof *copy);
    copy[n - 1].position[2] = 1u << 30;
    expect(ms_render_new(h, copy, &r, &err), MS_ERR_ARG, &err);
    memcpy(copy, cells, n * sizeof *copy);
    copy[0].level = 200;
    expect(ms_render_new(h, copy, &r, &err), MS_ERR_ARG, &err);
    memcpy(copy, cells, n * sizeof *copy);
    copy[0].apo_levels = 40;
    expect(ms_render_new(h, copy, &r, &err), MS_ERR_ARG, &err);
    free(copy);
    assert_null(r);
    ms_render_free(NULL);
    /* no current context: an error, not a crash */
    glfwMakeContextCurrent(NULL);
    ms_status st = ms_render_new(h, cells, &r, &err);
    glfwMakeContextCurrent(gl.window);
    expect(st, MS_ERR_UNSUPPORTED, &err);
    assert_null(r);
}

/* The archive's renderer and view, and the view's mesh seen from (0.2, 0.3, 1)
 * at 2 px. */
static void open_view(ms_render **r, ms_view **view, ms_camera *cam, ms_view_mesh *mesh)
{
    ms_test_render_open(archive, r, view);
    const double d[3] = {0.2, 0.3, 1.0};
    ms_test_render_look(archive, *view, d, WIDTH, HEIGHT, 1.0, cam, mesh);
}

/* Bad frames, uploads and draws: errors, then a good frame still draws. */
static void test_bad_calls(void **state)
{
    (void)state;
    ms_render *r;
    ms_view *view;
    ms_camera cam;
    ms_view_mesh mesh = {0};
    open_view(&r, &view, &cam, &mesh);
    ms_error err;
    const ms_archive_header *h = ms_archive_get_header(archive);
    assert_true(mesh.triangle_count > 100);

    expect(ms_render_set_frame(NULL, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);
    expect(ms_render_set_frame(r, NULL, NULL, 0, &err), MS_ERR_ARG, &err);
    expect(ms_render_set_frame(r, &mesh, NULL, 3, &err), MS_ERR_ARG, &err);
    ms_view_mesh broken = mesh;
    broken.triangles = NULL;
    expect(ms_render_set_frame(r, &broken, NULL, 0, &err), MS_ERR_ARG, &err);
    broken = mesh;
    broken.triangle_count = (size_t)1 << 40;
    expect(ms_render_set_frame(r, &broken, NULL, 0, &err), MS_ERR_ARG, &err);
    uint32_t keep = mesh.triangles[7];
    mesh.triangles[7] = (uint32_t)mesh.vertex_count;
    expect(ms_render_set_frame(r, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);
    mesh.triangles[7] = keep;
    keep = mesh.triangle_cell[5];
    mesh.triangle_cell[5] = h->cell_count;
    expect(ms_render_set_frame(r, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);
    mesh.triangle_cell[5] = keep;
    double keep_x = mesh.positions[4];
    mesh.positions[4] = NAN;
    expect(ms_render_set_frame(r, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);
    mesh.positions[4] = keep_x;
    ms_core_apo_chunk bad_apo = {h->cell_count, 1, NULL, 0, NULL};
    expect(ms_render_set_frame(r, &mesh, &bad_apo, 1, &err), MS_ERR_ARG, &err);
    bad_apo = (ms_core_apo_chunk){mesh.triangle_cell[0], 1, NULL, 10, NULL};
    expect(ms_render_set_frame(r, &mesh, &bad_apo, 1, &err), MS_ERR_ARG, &err);

    ms_render_upload_stats up;
    expect(ms_render_upload(NULL, 100, &up, &err), MS_ERR_ARG, &err);
    expect(ms_render_upload(r, 0, &up, &err), MS_ERR_ARG, &err);

    ms_render_options o;
    ms_render_options_default(&o);
    ms_render_draw_stats ds;
    expect(ms_render_draw(NULL, &cam, &o, &ds, &err), MS_ERR_ARG, &err);
    expect(ms_render_draw(r, NULL, &o, &ds, &err), MS_ERR_ARG, &err);
    expect(ms_render_draw(r, &cam, NULL, &ds, &err), MS_ERR_ARG, &err);
    ms_camera c2 = cam;
    c2.width = 0;
    expect(ms_render_draw(r, &c2, &o, &ds, &err), MS_ERR_ARG, &err);
    c2 = cam;
    c2.height = 1e9;
    expect(ms_render_draw(r, &c2, &o, &ds, &err), MS_ERR_ARG, &err);
    c2 = cam;
    c2.position[0] = NAN;
    expect(ms_render_draw(r, &c2, &o, &ds, &err), MS_ERR_ARG, &err);
    c2 = cam;
    c2.fovy = 0;
    expect(ms_render_draw(r, &c2, &o, &ds, &err), MS_ERR_ARG, &err);
    c2 = cam;
    c2.far_distance = c2.near_distance;
    expect(ms_render_draw(r, &c2, &o, &ds, &err), MS_ERR_ARG, &err);
    c2 = cam;
    c2.forward[0] *= 3;
    expect(ms_render_draw(r, &c2, &o, &ds, &err), MS_ERR_ARG, &err);
    ms_render_options o2 = o;
    o2.shading = (ms_shading)7;
    expect(ms_render_draw(r, &cam, &o2, &ds, &err), MS_ERR_ARG, &err);

    /* still usable: the good frame, every mode, wireframe */
    ms_test_render_show(r, &mesh, NULL, 0, &up);
    assert_int_equal(up.cells_pending, 0);
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH, HEIGHT);
    for (int mode = MS_SHADING_LIT; mode <= MS_SHADING_CELL_ID; ++mode)
        for (int wire = 0; wire < 2; ++wire) {
            o2 = o;
            o2.shading = (ms_shading)mode;
            o2.wireframe = wire;
            o2.background[0] = NAN; /* cleared as black, not a crash */
            expect(ms_render_draw(r, &cam, &o2, &ds, &err), MS_OK, &err);
            assert_int_equal(ds.triangles_drawn, mesh.triangle_count);
        }
    /* an empty frame draws nothing */
    ms_view_mesh empty = {0};
    expect(ms_render_set_frame(r, &empty, NULL, 0, &err), MS_OK, &err);
    expect(ms_render_draw(r, &cam, &o, &ds, &err), MS_OK, &err);
    assert_int_equal(ds.cells_drawn, 0);
    ms_test_fbo_free(&fbo);
    ms_view_mesh_free(&mesh);
    ms_view_destroy(view);
    ms_render_free(r);
}

/* Records learned as frames bring them (an index by subtree): a cell drawn
 * without its record is refused, a bad record is refused, and with the records
 * of the drawing cells the picture equals the one drawn from the whole index. */
static void draw_read(ms_render *r, const ms_view_mesh *mesh, const ms_camera *cam, const ms_test_fbo *fbo,
                      float *rgba)
{
    ms_error err;
    ms_render_options o;
    ms_render_options_default(&o);
    ms_render_upload_stats up;
    expect(ms_render_set_frame(r, mesh, NULL, 0, &err), MS_OK, &err);
    expect(ms_render_upload(r, UINT64_MAX, &up, &err), MS_OK, &err);
    assert_int_equal(up.cells_pending, 0);
    ms_render_draw_stats ds;
    expect(ms_render_draw(r, cam, &o, &ds, &err), MS_OK, &err);
    assert_int_equal(ds.triangles_drawn, mesh->triangle_count);
    ms_test_fbo_read(fbo, rgba, NULL);
}

static void test_learned_records(void **state)
{
    (void)state;
    const ms_archive_header *h = ms_archive_get_header(archive);
    ms_error err;
    ms_view *view;
    expect(ms_view_create_from_archive(archive, &view, &err), MS_OK, &err);
    ms_camera cam;
    const double d[3] = {0.2, 0.3, 1.0};
    ms_test_render_camera(h, d, 1.1, 40.0, WIDTH, HEIGHT, &cam);
    ms_view_mesh mesh = {0};
    ms_test_render_view(view, &cam, 1.0, &mesh);
    assert_true(mesh.triangle_count > 100);
    /* the drawing cells, ascending, and their records */
    uint32_t *ids = malloc(h->cell_count * sizeof *ids);
    ms_archive_cell *recs = malloc(h->cell_count * sizeof *recs);
    assert_non_null(ids);
    assert_non_null(recs);
    size_t count = 0;
    for (uint32_t c = 0; c < h->cell_count; ++c) {
        bool draws = false;
        for (size_t t = 0; t < mesh.triangle_count && !draws; ++t)
            draws = mesh.triangle_cell[t] == c;
        if (draws) {
            ids[count] = c;
            recs[count++] = *ms_archive_get_cell(archive, c);
        }
    }
    assert_true(count > 1);
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH, HEIGHT);
    float *whole = malloc(4 * sizeof(float) * WIDTH * HEIGHT), *learned = malloc(4 * sizeof(float) * WIDTH * HEIGHT);
    assert_non_null(whole);
    assert_non_null(learned);
    ms_render *r;
    expect(ms_render_new(h, ms_archive_get_cell(archive, 0), &r, &err), MS_OK, &err);
    draw_read(r, &mesh, &cam, &fbo, whole);
    ms_render_free(r);

    expect(ms_render_new(h, NULL, &r, &err), MS_OK, &err);
    expect(ms_render_set_frame(r, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);  /* no records yet */
    expect(ms_render_learn(r, ids, recs, count - 1, &err), MS_OK, &err);
    expect(ms_render_set_frame(r, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);  /* one missing */
    uint32_t beyond = h->cell_count;
    expect(ms_render_learn(r, &beyond, recs, 1, &err), MS_ERR_ARG, &err);
    ms_archive_cell bad = recs[0];
    bad.position[0] = 1u << 30;
    expect(ms_render_learn(r, ids, &bad, 1, &err), MS_ERR_ARG, &err);
    expect(ms_render_learn(r, NULL, recs, 1, &err), MS_ERR_ARG, &err);
    expect(ms_render_learn(r, ids, recs, count, &err), MS_OK, &err);
    draw_read(r, &mesh, &cam, &fbo, learned);
    assert_memory_equal(whole, learned, 4 * sizeof(float) * WIDTH * HEIGHT);
    /* the state of groups no longer drawn is gone with their records: the same
     * frame again needs them learned again */
    ms_view_mesh empty = {0};
    expect(ms_render_set_frame(r, &empty, NULL, 0, &err), MS_OK, &err);
    expect(ms_render_set_frame(r, &mesh, NULL, 0, &err), MS_ERR_ARG, &err);
    expect(ms_render_learn(r, ids, recs, count, &err), MS_OK, &err);
    draw_read(r, &mesh, &cam, &fbo, learned);
    assert_memory_equal(whole, learned, 4 * sizeof(float) * WIDTH * HEIGHT);
    ms_render_free(r);
    free(whole);
    free(learned);
    free(ids);
    free(recs);
    ms_test_fbo_free(&fbo);
    ms_view_mesh_free(&mesh);
    ms_view_destroy(view);
}

/* Corrupt, short and over-claiming APO prefixes: the frame is taken, those cells
 * shade with their geometric normals (the picture equals the APO-off one). */
static void test_corrupt_apo(void **state)
{
    (void)state;
    ms_render *r;
    ms_view *view;
    ms_camera cam;
    ms_view_mesh mesh = {0};
    open_view(&r, &view, &cam, &mesh);
    ms_error err;
    ms_core_apo_chunk *apo;
    size_t count;
    ms_test_render_apo(archive, &mesh, 0, false, &apo, &count);
    assert_true(count >= 3);
    uint8_t garbage[300];
    uint64_t seed = 77;
    for (size_t i = 0; i < sizeof garbage; ++i)
        garbage[i] = (uint8_t)ms_test_random(&seed);
    uint8_t **copies = calloc(count, sizeof *copies);
    for (size_t i = 0; i < count; ++i) {
        copies[i] = malloc(apo[i].length);
        memcpy(copies[i], apo[i].data, apo[i].length);
        switch (i % 4) {
        case 0: /* random bytes */
            apo[i].data = garbage;
            apo[i].length = sizeof garbage;
            break;
        case 1: /* claims every level, holds one */
            apo[i].data = copies[i];
            apo[i].length = ms_archive_apo_prefix(archive, apo[i].cell, 0, NULL);
            break;
        case 2: /* a flipped bit inside the zlib stream */
            apo[i].data = copies[i];
            copies[i][apo[i].length / 2] ^= 0x10;
            break;
        default: /* more levels than the record: clamped to the record */
            apo[i].data = copies[i];
            apo[i].levels = 1000;
            break;
        }
    }
    ms_test_render_show(r, &mesh, apo, count, NULL);
    size_t np = (size_t)WIDTH * HEIGHT;
    float *with = malloc(np * 4 * sizeof(float)), *without = malloc(np * 4 * sizeof(float)),
          *ids = malloc(np * 4 * sizeof(float));
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH, HEIGHT);
    ms_render_options o;
    ms_render_options_default(&o);
    o.shading = MS_SHADING_NORMALS;
    expect(ms_render_draw(r, &cam, &o, NULL, &err), MS_OK, &err);
    ms_test_fbo_read(&fbo, with, NULL);
    o.apo = false;
    expect(ms_render_draw(r, &cam, &o, NULL, &err), MS_OK, &err);
    ms_test_fbo_read(&fbo, without, NULL);
    o.shading = MS_SHADING_CELL_ID;
    expect(ms_render_draw(r, &cam, &o, NULL, &err), MS_OK, &err);
    ms_test_fbo_read(&fbo, ids, NULL);
    ms_test_fbo_free(&fbo);
    /* per pixel: cells whose chunk was spoilt (cases 0..2) shade as without APO;
     * the clamped one (case 3) still has its APO */
    size_t spoilt_pixels = 0, apo_pixels = 0;
    for (size_t p = 0; p < np; ++p) {
        uint32_t id = (uint32_t)lroundf(ids[4 * p] * 255) | (uint32_t)lroundf(ids[4 * p + 1] * 255) << 8 |
                      (uint32_t)lroundf(ids[4 * p + 2] * 255) << 16;
        if (!id)
            continue;
        size_t i = 0;
        while (i < count && apo[i].cell != id - 1)
            ++i;
        assert_true(i < count);
        bool same = memcmp(&with[4 * p], &without[4 * p], 4 * sizeof(float)) == 0;
        if (i % 4 != 3) {
            assert_true(same);
            spoilt_pixels++;
        } else {
            apo_pixels += !same;
        }
    }
    print_message("%zu pixels of spoilt chunks shade geometrically, %zu of a clamped one with APO\n",
                  spoilt_pixels, apo_pixels);
    assert_true(spoilt_pixels > 0 && apo_pixels > 0);
    for (size_t i = 0; i < count; ++i)
        free(copies[i]);
    free(copies);
    free(apo);
    free(with);
    free(without);
    free(ids);
    ms_view_mesh_free(&mesh);
    ms_view_destroy(view);
    ms_render_free(r);
}

/* The renderer's prefix reader against the archive reader, for every cell with
 * a chunk and every prefix of whole levels (also cut halfway into the next). */
static void test_prefix_words(void **state)
{
    (void)state;
    const ms_archive_header *h = ms_archive_get_header(archive);
    size_t checked = 0;
    for (uint32_t c = 0; c < h->cell_count; ++c) {
        const ms_archive_cell *rec = ms_archive_get_cell(archive, c);
        if (!rec->apo_levels)
            continue;
        size_t stored;
        const uint8_t *data = ms_archive_apo(archive, c, &stored);
        uint32_t table[2 * MS_APO_MAX_LEVELS];
        for (unsigned l = 0; l < rec->apo_levels; ++l)
            table[2 * l] = ms_archive_apo_prefix(archive, c, l, &table[2 * l + 1]);
        for (unsigned levels = 1; levels <= rec->apo_levels; ++levels)
            for (int mid = 0; mid < 2; ++mid) {
                size_t length = table[2 * (levels - 1)];
                if (mid && levels < rec->apo_levels)
                    length += (table[2 * levels] - length) / 2;
                ms_apo_chunk want = {0};
                ms_error err;
                expect(ms_apo_stream_inflate(data, length, table, rec->apo_levels, &want, &err), MS_OK, &err);
                uint32_t *words;
                size_t count;
                bool root_internal;
                expect(ms_render_apo_words(rec, data, length, levels, &words, &count, &root_internal, &err), MS_OK,
                       &err);
                assert_int_equal(count, table[2 * (levels - 1) + 1]);
                assert_true(count <= want.texel_count);
                assert_memory_equal(words, want.texels, count * sizeof *words);
                assert_int_equal(root_internal, want.level_texels[0] == 2);
                free(words);
                /* one level more than the bytes hold (cut at a level's end: a cut
                 * halfway may well hold all of a small level's words) */
                if (!mid && levels < rec->apo_levels) {
                    expect(ms_render_apo_words(rec, data, length, levels + 1, &words, &count, &root_internal, &err),
                           MS_ERR_CORRUPT, &err);
                    assert_null(words);
                }
                ms_apo_chunk_free(&want);
                checked++;
            }
        uint32_t *words;
        size_t count;
        bool root_internal;
        ms_error err;
        expect(ms_render_apo_words(rec, data, stored, 0, &words, &count, &root_internal, &err), MS_ERR_ARG, &err);
        expect(ms_render_apo_words(rec, data, stored, rec->apo_levels + 1, &words, &count, &root_internal, &err),
               MS_ERR_ARG, &err);
        expect(ms_render_apo_words(rec, NULL, 0, 1, &words, &count, &root_internal, &err), MS_ERR_ARG, &err);
    }
    print_message("%zu prefixes read as the archive reader reads them\n", checked);
    assert_true(checked > 20);
}

/* Ranges of the texel buffer: first fit, merged on release, growth keeps the
 * words (checked by reading them back), refusal beyond the driver's limit. */
static void test_texel_ranges(void **state)
{
    (void)state;
    ms_render_texels t;
    ms_render_gl_count held = {0};
    ms_error err;
    expect(ms_render_texels_init(&t, &held, &err), MS_OK, &err);
    /* the count is the buffer's size as GL has it */
    GLint64 size = 0;
    glBindBuffer(GL_TEXTURE_BUFFER, t.buffer);
    glGetBufferParameteri64v(GL_TEXTURE_BUFFER, GL_BUFFER_SIZE, &size);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    assert_int_equal(held.bytes, (uint64_t)size);
    assert_int_equal(held.bytes, 4ull * t.capacity);
    assert_int_equal(held.peak, held.bytes);
    print_message("texel buffer: %u words to start, at most %u (GL_MAX_TEXTURE_BUFFER_SIZE)\n", t.capacity,
                  t.max_words);
    uint32_t a, b, c;
    assert_true(ms_render_texels_alloc(&t, 1000, &a));
    assert_true(ms_render_texels_alloc(&t, 2000, &b));
    assert_true(ms_render_texels_alloc(&t, 500, &c));
    assert_int_equal(a, 0);
    assert_int_equal(b, 1000);
    assert_int_equal(c, 3000);
    uint32_t words[500];
    for (uint32_t i = 0; i < 500; ++i)
        words[i] = 0xA5000000u + i;
    glBindBuffer(GL_TEXTURE_BUFFER, t.buffer);
    glBufferSubData(GL_TEXTURE_BUFFER, 4 * (GLintptr)c, sizeof words, words);
    ms_render_texels_release(&t, b, 2000);
    uint32_t d;
    assert_true(ms_render_texels_alloc(&t, 1500, &d));
    assert_int_equal(d, 1000); /* first fit reuses the hole */
    ms_render_texels_release(&t, a, 1000);
    ms_render_texels_release(&t, d, 1500); /* merges with the range before and the rest of the hole */
    assert_true(ms_render_texels_alloc(&t, 3000, &d));
    assert_int_equal(d, 0);
    uint32_t capacity = t.capacity, big;
    assert_true(ms_render_texels_alloc(&t, capacity, &big)); /* grows */
    assert_true(t.capacity > capacity);
    /* the old buffer is gone; while the words were copied both were held */
    glBindBuffer(GL_TEXTURE_BUFFER, t.buffer);
    glGetBufferParameteri64v(GL_TEXTURE_BUFFER, GL_BUFFER_SIZE, &size);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    assert_int_equal(held.bytes, (uint64_t)size);
    assert_int_equal(held.bytes, 4ull * t.capacity);
    assert_int_equal(held.peak, 4ull * capacity + 4ull * t.capacity);
    uint32_t back[500];
    glBindBuffer(GL_TEXTURE_BUFFER, t.buffer);
    glGetBufferSubData(GL_TEXTURE_BUFFER, 4 * (GLintptr)c, sizeof back, back);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    assert_memory_equal(back, words, sizeof words);
    uint32_t none;
    assert_false(ms_render_texels_alloc(&t, t.max_words + 1u > t.max_words ? t.max_words + 1u : UINT32_MAX, &none));
    assert_false(ms_render_texels_alloc(&t, 0, &none));
    ms_render_texels_release(&t, big, capacity);
    ms_render_texels_release(&t, d, 3000);
    ms_render_texels_release(&t, c, 500);
    assert_int_equal(t.used, 0);
    assert_int_equal(t.free_count, 1);
    assert_int_equal(t.free_ranges[0].count, t.capacity);
    ms_render_texels_free(&t);
    assert_int_equal(held.bytes, 0);
}

/* Projection and unprojection agree; the background and bad depths are refused. */
static void test_camera(void **state)
{
    (void)state;
    ms_camera cam;
    const double pos[3] = {1e5 + 3, -2, 7}, target[3] = {1e5, 0.5, 1}, up[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(pos, target, up, 50.0, 320, 200, 0.5, 40.0, &cam, NULL), MS_OK);
    double view[16], proj[16];
    ms_render_camera_matrices(&cam, view, proj);
    uint64_t seed = 5;
    for (int i = 0; i < 1000; ++i) {
        double w[4] = {1e5 + (double)(ms_test_random(&seed) % 2000) / 1000.0 - 1.0,
                       (double)(ms_test_random(&seed) % 2000) / 1000.0 - 0.5,
                       (double)(ms_test_random(&seed) % 2000) / 1000.0, 1.0};
        double eye[4] = {0}, clip[4] = {0};
        for (int r = 0; r < 4; ++r)
            for (int k = 0; k < 4; ++k)
                eye[r] += view[4 * k + r] * w[k];
        for (int r = 0; r < 4; ++r)
            for (int k = 0; k < 4; ++k)
                clip[r] += proj[4 * k + r] * eye[k];
        if (clip[3] <= 0)
            continue;
        double x = (clip[0] / clip[3] + 1) * 0.5 * cam.width, y = (clip[1] / clip[3] + 1) * 0.5 * cam.height,
               depth = (clip[2] / clip[3] + 1) * 0.5;
        double back[3];
        if (depth < 0 || depth >= 1)
            continue;
        assert_true(ms_render_unproject(&cam, x, y, depth, back));
        for (int k = 0; k < 3; ++k)
            assert_true(fabs(back[k] - w[k]) < 1e-6);
    }
    double out[3];
    assert_false(ms_render_unproject(&cam, 1, 1, 1.0, out));
    assert_false(ms_render_unproject(&cam, 1, 1, NAN, out));
    assert_false(ms_render_unproject(&cam, NAN, 1, 0.5, out));
    assert_false(ms_render_unproject(NULL, 1, 1, 0.5, out));
    /* the centre pixel at depth 0 lies on the near plane, straight ahead */
    assert_true(ms_render_unproject(&cam, cam.width / 2, cam.height / 2, 0.0, out));
    for (int k = 0; k < 3; ++k)
        assert_true(fabs(out[k] - (cam.position[k] + cam.near_distance * cam.forward[k])) < 1e-9);
}

/* ---- shading modes on one hand-made triangle ---------------------------- */

static float srgb(double c)
{
    return (float)(c <= 0.0031308 ? 12.92 * c : 1.055 * pow(c, 1.0 / 2.4) - 0.055);
}

/* Draws one triangle of a one-cell model (the unit box) through the plane
 * through the box centre with normal (0, sin t, cos t), seen from +z; returns the
 * centre pixel's colour (corner: the bottom-left one's). reversed flips the
 * winding (a back face). */
static void draw_plane_pixel(double tilt_deg, bool reversed, const ms_render_options *o, bool corner, float rgba[4])
{
    double t = tilt_deg * M_PI / 180.0;
    /* in-plane axes: x, and (0, cos t, -sin t) */
    double corners[3][2] = {{-20, -20}, {20, -20}, {0, 20}};
    double positions[9];
    for (int k = 0; k < 3; ++k) {
        positions[3 * k] = 0.5 + corners[k][0];
        positions[3 * k + 1] = 0.5 + corners[k][1] * cos(t);
        positions[3 * k + 2] = 0.5 - corners[k][1] * sin(t);
    }
    const uint32_t tri[3] = {0, reversed ? 2u : 1u, reversed ? 1u : 2u};
    ms_render *r = ms_test_render_one_cell(4, positions, 3, tri, 1);
    ms_error err;
    ms_camera cam;
    const double eye[3] = {0.5, 0.5, 3.0}, centre[3] = {0.5, 0.5, 0.5}, upv[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(eye, centre, upv, 40.0, WIDTH + 1, HEIGHT + 1, 0.5, 10.0, &cam, NULL), MS_OK);
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH + 1, HEIGHT + 1); /* odd sizes: a pixel centre on the axis */
    expect(ms_render_draw(r, &cam, o, NULL, &err), MS_OK, &err);
    size_t np = (size_t)(WIDTH + 1) * (HEIGHT + 1);
    float *px = malloc(np * 4 * sizeof *px);
    ms_test_fbo_read(&fbo, px, NULL);
    size_t at = corner ? 0 : (size_t)(HEIGHT / 2) * (WIDTH + 1) + WIDTH / 2;
    memcpy(rgba, &px[4 * at], 4 * sizeof(float));
    free(px);
    ms_test_fbo_free(&fbo);
    ms_render_free(r);
}

static void draw_plane(double tilt_deg, bool reversed, const ms_render_options *o, float rgba[4])
{
    draw_plane_pixel(tilt_deg, reversed, o, false, rgba);
}

static void expect_colour(const float got[4], double r, double g, double b)
{
    if (fabs(got[0] - r) > 2e-3 || fabs(got[1] - g) > 2e-3 || fabs(got[2] - b) > 2e-3)
        fail_msg("colour (%.4f %.4f %.4f), expected (%.4f %.4f %.4f)", got[0], got[1], got[2], r, g, b);
}

/* LIT: albedo (0.72, 0.69, 0.64) times (0.05 + 0.95 * Lambert * self-shadow) plus
 * 0.18 * specular^40 * self-shadow, sRGB-encoded; both sides lit alike; the
 * self-shadowing factor max(0, L . N_geometric) applies without APO too (the
 * head light at 60 degrees: 0.5, meshrender's lighting model). NORMALS:
 * the stored orientation's normal. CELL_ID: cell + 1. */
static void test_shading(void **state)
{
    (void)state;
    const double albedo[3] = {0.72, 0.69, 0.64};
    ms_render_options o;
    ms_render_options_default(&o);
    float c[4];
    double expected[3];
    for (int back = 0; back < 2; ++back) {
        draw_plane(0.0, back, &o, c);
        expect_colour(c, srgb(albedo[0] + 0.18), srgb(albedo[1] + 0.18), srgb(albedo[2] + 0.18));
        draw_plane(60.0, back, &o, c);
        double lambert = 0.5, spec = pow(0.5, 40.0), self_shadow = 0.5;
        for (int k = 0; k < 3; ++k) /* the light's terms times the self-shadowing factor */
            expected[k] = srgb(albedo[k] * (0.05 + 0.95 * lambert * self_shadow) + 0.18 * spec * self_shadow);
        expect_colour(c, expected[0], expected[1], expected[2]);
    }
    o.shading = MS_SHADING_NORMALS;
    /* smooth (the vertex normals of a lone triangle are its own, packed) and flat */
    for (int smooth = 1; smooth >= 0; --smooth) {
        o.smooth = smooth;
        draw_plane(60.0, false, &o, c);
        expect_colour(c, 0.5, (sin(M_PI / 3) + 1) / 2, (cos(M_PI / 3) + 1) / 2);
        draw_plane(60.0, true, &o, c);
        expect_colour(c, 0.5, (-sin(M_PI / 3) + 1) / 2, (-cos(M_PI / 3) + 1) / 2);
    }
    o.smooth = true;
    o.shading = MS_SHADING_CELL_ID;
    draw_plane(0.0, false, &o, c);
    expect_colour(c, 1.0 / 255.0, 0.0, 0.0);
    /* the background: linear as given for NORMALS, sRGB-encoded for LIT */
    o.shading = MS_SHADING_NORMALS;
    o.background[0] = 0.25f, o.background[1] = 0.5f, o.background[2] = 0.0f;
    draw_plane_pixel(89.0, false, &o, true, c); /* nearly edge-on: the corner misses */
    expect_colour(c, 0.25, 0.5, 0.0);
    o.shading = MS_SHADING_LIT;
    draw_plane_pixel(89.0, false, &o, true, c);
    expect_colour(c, srgb(0.25), srgb(0.5), 0.0);
    o.shading = MS_SHADING_CELL_ID; /* background is 0 whatever the colour asked */
    draw_plane_pixel(89.0, false, &o, true, c);
    expect_colour(c, 0.0, 0.0, 0.0);
    o.shading = MS_SHADING_LIT;
    o.wireframe = true; /* far from any edge: no change */
    draw_plane(0.0, false, &o, c);
    expect_colour(c, srgb(albedo[0] + 0.18), srgb(albedo[1] + 0.18), srgb(albedo[2] + 0.18));
}

static int setup(void **state)
{
    (void)state;
    ms_test_gl_start(&gl);
    char model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    archive = ms_test_render_bake(model, dir, "bunny", 14, 1000, 5);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    ms_archive_close(archive);
    ms_test_rmdir(dir);
    ms_test_gl_stop(&gl);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bad_model),   cmocka_unit_test(test_bad_calls),
        cmocka_unit_test(test_corrupt_apo), cmocka_unit_test(test_prefix_words),
        cmocka_unit_test(test_texel_ranges), cmocka_unit_test(test_camera),
        cmocka_unit_test(test_shading),
        cmocka_unit_test(test_learned_records),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
