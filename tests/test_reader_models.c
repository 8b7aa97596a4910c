/* Every test model loads with exactly the counts in tests/data/README.md, through
 * ms_mesh_load, through the streaming reader (chunk and order guarantees), and
 * through `meshbake --info --json`. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_mesh_io.h"
#include "ms_mesh_reader.h"
#include "support/ms_test.h"

typedef struct model_case {
    const char *file;
    const char *format;
    size_t vertices;
    size_t triangles;
} model_case;

/* From tests/data/README.md. */
static const model_case models[] = {
    {"stanford_bunny_res3.ply.gz", "ply-ascii", 1889, 3851},
    {"stanford_dragon_vrip_res4.ply.gz", "ply-ascii", 5205, 11102},
    {"stanford_dragon_vrip_res3.ply.gz", "ply-ascii", 22998, 47794},
    {"stanford_dragon_vrip_res2.ply.gz", "ply-ascii", 100250, 202520},
    {"stanford_dragon_vrip.ply.gz", "ply-ascii", 437645, 871414},
    {"glmark2_bunny.obj.gz", "obj", 34835, 69666},
    {"cgal_armadillo.off.gz", "off", 26002, 52000},
    {"torus_tristrips.ply.gz", "ply-binary-le", 10240, 20480},
    {"trefoil_color.ply.gz", "ply-binary-le", 5120, 10240},
    {"snowden_bust_hi.ply.gz", "ply-binary-le", 54559, 109259},
};

static void test_every_model_loads_with_readme_counts(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof models / sizeof models[0]; ++i) {
        char path[4096];
        ms_test_model_path(path, sizeof path, models[i].file);
        ms_mesh mesh = {0};
        ms_mesh_load_report report;
        ms_error err;
        ms_status st = ms_mesh_load(path, &mesh, &report, &err);
        if (st != MS_OK)
            fail_msg("%s: %s", models[i].file, err.text);
        assert_int_equal(mesh.vertex_count, models[i].vertices);
        assert_int_equal(mesh.triangle_count, models[i].triangles);
        assert_string_equal(report.format, models[i].format);
        assert_true(report.gzip);
        assert_int_equal(report.dropped_faces, 0);
        for (size_t t = 0; t < 3 * mesh.triangle_count; ++t)
            assert_true(mesh.triangles[t] < mesh.vertex_count);
        ms_mesh_free(&mesh);
    }
}

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* The torus is a closed surface stored as strips: if the strip unrolling flips
 * every other triangle correctly, each directed edge occurs once and its reverse
 * once. */
static void test_tristrips_are_consistently_oriented(void **state)
{
    (void)state;
    char path[4096];
    ms_test_model_path(path, sizeof path, "torus_tristrips.ply.gz");
    ms_mesh mesh = {0};
    ms_error err;
    assert_int_equal(ms_mesh_load(path, &mesh, NULL, &err), MS_OK);
    size_t n = 3 * mesh.triangle_count;
    uint64_t *edges = malloc(n * sizeof *edges);
    uint64_t *reversed = malloc(n * sizeof *reversed);
    assert_non_null(edges);
    assert_non_null(reversed);
    for (size_t t = 0; t < mesh.triangle_count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint64_t a = mesh.triangles[3 * t + (size_t)k];
            uint64_t b = mesh.triangles[3 * t + (size_t)(k + 1) % 3];
            edges[3 * t + (size_t)k] = a << 32 | b;
            reversed[3 * t + (size_t)k] = b << 32 | a;
        }
    qsort(edges, n, sizeof *edges, compare_u64);
    qsort(reversed, n, sizeof *reversed, compare_u64);
    for (size_t i = 1; i < n; ++i)
        assert_true(edges[i] != edges[i - 1]);
    assert_memory_equal(edges, reversed, n * sizeof *edges);
    free(edges);
    free(reversed);
    ms_mesh_free(&mesh);
}

typedef struct stream_check {
    uint64_t vertices;
    uint64_t triangles;
    uint64_t chunks;
} stream_check;

static ms_status check_vertices(void *context, const double *positions, size_t count,
                                ms_error *err)
{
    (void)positions;
    (void)err;
    stream_check *c = context;
    assert_true(count > 0 && count <= MS_MESH_READ_CHUNK_VERTICES);
    c->vertices += count;
    ++c->chunks;
    return MS_OK;
}

static ms_status check_triangles(void *context, const uint32_t *indices, size_t count,
                                 ms_error *err)
{
    (void)err;
    stream_check *c = context;
    assert_true(count > 0 && count <= MS_MESH_READ_CHUNK_TRIANGLES);
    for (size_t i = 0; i < 3 * count; ++i)
        assert_true(indices[i] < c->vertices); /* only vertices already delivered */
    c->triangles += count;
    ++c->chunks;
    return MS_OK;
}

static void test_streaming_chunks_are_bounded_and_ordered(void **state)
{
    (void)state;
    static const char *const files[] = {"stanford_dragon_vrip_res2.ply.gz",
                                        "torus_tristrips.ply.gz", "glmark2_bunny.obj.gz",
                                        "cgal_armadillo.off.gz"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; ++i) {
        char path[4096];
        ms_test_model_path(path, sizeof path, files[i]);
        stream_check check = {0, 0, 0};
        const ms_mesh_sink sink = {.context = &check, .vertices = check_vertices,
                                   .triangles = check_triangles};
        ms_mesh_read_report report;
        ms_error err;
        if (ms_mesh_read(path, &sink, &report, &err) != MS_OK)
            fail_msg("%s", err.text);
        assert_true(check.chunks > 2);
        assert_int_equal(check.vertices, report.vertices);
        assert_int_equal(check.triangles, report.triangles);
        assert_true(report.bbox_min[0] < report.bbox_max[0]);
    }
}

/* Finds "key": in a one-line JSON object and parses the number after it. */
static double json_number(const char *json, const char *key)
{
    char pattern[128];
    snprintf(pattern, sizeof pattern, "\"%s\": ", key);
    const char *at = strstr(json, pattern);
    if (!at)
        fail_msg("no key %s in %s", key, json);
    return strtod(at + strlen(pattern), NULL);
}

static void test_meshbake_info_json(void **state)
{
    (void)state;
    char bin[4096], model[4096], command[9000], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res4.ply.gz");
    snprintf(command, sizeof command, "%s --info --json '%s' 2>/dev/null", bin, model);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    assert_non_null(strstr(out, "\"format\": \"ply-ascii\""));
    assert_true(json_number(out, "vertices") == 5205);
    assert_true(json_number(out, "triangles") == 11102);
    assert_true(json_number(out, "dropped_faces") == 0);
    assert_true(json_number(out, "isolated_vertices") >= 0);
    assert_true(json_number(out, "seconds") >= 0);
    /* The bounding box arrays hold exact doubles of the file's values. */
    const char *min = strstr(out, "\"bbox_min\": [");
    const char *max = strstr(out, "\"bbox_max\": [");
    assert_non_null(min);
    assert_non_null(max);
    char *end;
    double x0 = strtod(min + 13, &end);
    assert_true(*end == ',');
    assert_true(x0 == -0.107585);
    double x1 = strtod(max + 13, &end);
    assert_true(x1 == 0.0952357);
    assert_int_equal(out[strlen(out) - 1], '\n');
    assert_int_equal(out[0], '{');
}

static void test_meshbake_usage(void **state)
{
    (void)state;
    char bin[4096], command[9000], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(command, sizeof command, "%s --help", bin);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    assert_non_null(strstr(out, "usage: meshbake"));
    snprintf(command, sizeof command, "%s --frobnicate x.ply", bin);
    assert_int_equal(ms_test_run(command, out, sizeof out), 2);
    assert_non_null(strstr(out, "unknown option"));
    assert_non_null(strchr(out, '\n'));
    assert_null(strchr(strchr(out, '\n') + 1, '\n')); /* one line */
    snprintf(command, sizeof command, "%s --info", bin);
    assert_int_equal(ms_test_run(command, out, sizeof out), 2);
    assert_non_null(strstr(out, "missing input file"));
    snprintf(command, sizeof command, "%s --info /nonexistent/model.ply", bin);
    assert_int_equal(ms_test_run(command, out, sizeof out), 1);
    assert_non_null(strstr(out, "/nonexistent/model.ply"));
}

static void test_meshconv_round_trip(void **state)
{
    (void)state;
    char dir[4096], bin[4096], model[4096], out_path[4200], command[16384], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshconv");
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    snprintf(out_path, sizeof out_path, "%s/bunny.ply", dir);
    snprintf(command, sizeof command, "%s '%s' -o '%s' --binary --double", bin, model, out_path);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    ms_mesh a = {0}, b = {0};
    ms_mesh_load_report report;
    ms_error err;
    assert_int_equal(ms_mesh_load(model, &a, NULL, &err), MS_OK);
    assert_int_equal(ms_mesh_load(out_path, &b, &report, &err), MS_OK);
    assert_string_equal(report.format, "ply-binary-le");
    assert_int_equal(a.vertex_count, b.vertex_count);
    assert_int_equal(a.triangle_count, b.triangle_count);
    assert_memory_equal(a.positions, b.positions, 3 * a.vertex_count * sizeof(double));
    assert_memory_equal(a.triangles, b.triangles, 3 * a.triangle_count * sizeof(uint32_t));
    ms_mesh_free(&a);
    ms_mesh_free(&b);
    snprintf(command, sizeof command, "%s '%s'", bin, model);
    assert_int_equal(ms_test_run(command, out, sizeof out), 2);
    /* the colour trefoil keeps its vertex colours, alpha included, in ascii too */
    ms_test_model_path(model, sizeof model, "trefoil_color.ply.gz");
    snprintf(out_path, sizeof out_path, "%s/trefoil.ply", dir);
    snprintf(command, sizeof command, "%s '%s' -o '%s' --ascii", bin, model, out_path);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    assert_int_equal(ms_mesh_load(model, &a, NULL, &err), MS_OK);
    assert_int_equal(ms_mesh_load(out_path, &b, &report, &err), MS_OK);
    assert_string_equal(report.format, "ply-ascii");
    assert_int_equal(a.vertex_count, b.vertex_count);
    assert_true(a.colours && b.colours && a.colour_alpha && b.colour_alpha);
    assert_memory_equal(a.colours, b.colours, 4 * a.vertex_count);
    ms_mesh_free(&a);
    ms_mesh_free(&b);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_model_loads_with_readme_counts),
        cmocka_unit_test(test_tristrips_are_consistently_oriented),
        cmocka_unit_test(test_streaming_chunks_are_bounded_and_ordered),
        cmocka_unit_test(test_meshbake_info_json),
        cmocka_unit_test(test_meshbake_usage),
        cmocka_unit_test(test_meshconv_round_trip),
    };
    return cmocka_run_group_tests_name("reader_models", tests, NULL, NULL);
}
