/* meshbake in bounded memory: a model baked with a --mem so small that every
 * phase works through its temporary files (the key file read back through a
 * cache smaller than it, leaf buffers flushed while distributing, lone levels
 * and leaf records read back) gives the archive a large --mem gives, byte for
 * byte, on one thread and on two (the distribution's pipeline, the quantisation
 * and the subtrees on the pool); the report counts each phase's temporary-file
 * traffic, the same on one thread and two; and a --mem below what a bake works in
 * is refused before the input is read. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <jansson.h>

#include "ms_test.h"

/* The model: meshgen's 300k triangles (150k vertices, 1.2 MB of keys: 19 steps
 * of the distribution's pipeline, five chunks of the quantisation). With --mem 4
 * the key cache holds 1 MiB (256 pages of 512 keys) and the leaf buffers 512
 * KiB, against 7 MB of leaf records. */
#define MODEL_TRIANGLES 300000

static json_t *bake(const char *bin, const char *model, const char *dir, const char *name,
                    const char *options)
{
    char cmd[16384];
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name %s --no-apo --min-tris 1000 --json %s", bin,
             model, dir, name, options);
    return ms_test_run_json(cmd, 0);
}

static uint64_t io_bytes(json_t *report, const char *phase, const char *which)
{
    json_t *v = json_object_get(json_object_get(json_object_get(report, "temporary_io"), phase),
                                which);
    if (!json_is_integer(v))
        fail_msg("no temporary_io.%s.%s in the report", phase, which);
    return (uint64_t)json_integer_value(v);
}

static void test_small_mem_gives_the_same_archive(void **state)
{
    (void)state;
    char dir[512], bin[4096], gen[4096], model[1024], cmd[16384], out[4096], path[1200];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_bin_path(gen, sizeof gen, "meshgen");
    snprintf(model, sizeof model, "%s/model.ply", dir);
    snprintf(cmd, sizeof cmd, "%s -o '%s' --triangles %d", gen, model, MODEL_TRIANGLES);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);

    json_t *big = bake(bin, model, dir, "big", "--mem 256 --threads 2");
    json_t *small = bake(bin, model, dir, "small", "--mem 4 --threads 1");
    json_t *small2 = bake(bin, model, dir, "small2", "--mem 4 --threads 2");
    uint64_t vertices = (uint64_t)json_integer_value(json_object_get(small, "input_vertices"));
    assert_true(vertices * 8 > (1u << 20)); /* the keys do not fit in the cache */
    /* every phase spills, or reads back what an earlier one spilled */
    assert_true(io_bytes(small, "read", "spilled_bytes") >= vertices * 24);
    assert_int_equal(io_bytes(small, "quantise", "spilled_bytes"), vertices * 8);
    assert_int_equal(io_bytes(small, "quantise", "read_back_bytes"), vertices * 24);
    /* the key file read back at least once through the cache, then once in order */
    assert_true(io_bytes(small, "distribute", "read_back_bytes") >= 2 * vertices * 8);
    assert_true(json_integer_value(json_object_get(small, "key_page_misses")) >=
                (json_int_t)((vertices + 511) / 512));
    assert_true(io_bytes(small, "distribute", "spilled_bytes") >
                io_bytes(big, "distribute", "spilled_bytes")); /* flushed while distributing */
    assert_true(io_bytes(small, "lone", "read_back_bytes") > 0);
    assert_true(io_bytes(small, "lone", "spilled_bytes") > 0);
    assert_true(io_bytes(small, "encode", "read_back_bytes") >
                io_bytes(small, "lone", "read_back_bytes")); /* the records and the segments */
    assert_true(json_integer_value(json_object_get(small, "depth")) >= 2);
    assert_true(json_real_value(json_object_get(small, "peak_rss_mb")) > 0);
    /* two threads move the same bytes through the same cache */
    const char *phases[] = {"read", "quantise", "distribute", "lone", "encode"};
    for (size_t i = 0; i < sizeof phases / sizeof *phases; ++i) {
        assert_int_equal(io_bytes(small2, phases[i], "spilled_bytes"),
                         io_bytes(small, phases[i], "spilled_bytes"));
        assert_int_equal(io_bytes(small2, phases[i], "read_back_bytes"),
                         io_bytes(small, phases[i], "read_back_bytes"));
    }
    assert_int_equal(json_integer_value(json_object_get(small2, "key_page_misses")),
                     json_integer_value(json_object_get(small, "key_page_misses")));
    assert_int_equal(json_integer_value(json_object_get(small2, "threads")), 2);
    json_decref(big);
    json_decref(small);
    json_decref(small2);

    size_t big_size, small_size;
    snprintf(path, sizeof path, "%s/big.msa", dir);
    unsigned char *a = ms_test_read_file(path, &big_size);
    snprintf(path, sizeof path, "%s/small.msa", dir);
    unsigned char *b = ms_test_read_file(path, &small_size);
    assert_int_equal(big_size, small_size);
    assert_memory_equal(a, b, big_size);
    free(b);
    snprintf(path, sizeof path, "%s/small2.msa", dir);
    b = ms_test_read_file(path, &small_size);
    assert_int_equal(big_size, small_size);
    assert_memory_equal(a, b, big_size);
    free(a);
    free(b);
    ms_test_rmdir(dir);
}

static void test_too_small_mem_refused_before_reading(void **state)
{
    (void)state;
    char dir[512], bin[4096], cmd[16384], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    /* the input does not exist: a refusal that names --mem did not read it */
    snprintf(cmd, sizeof cmd, "%s '%s/missing.ply' -o '%s' --no-apo --threads 2 --min-tris 8000 --mem 9",
             bin, dir, dir);
    assert_int_not_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_string_equal(out, "meshbake: --mem 9 MB is below the 10 MB a bake with 2 threads and "
                             "--min-tris 8000 works in\n");
    /* at the floor, the same command gets as far as the input */
    snprintf(cmd, sizeof cmd, "%s '%s/missing.ply' -o '%s' --no-apo --threads 2 --min-tris 8000 --mem 10",
             bin, dir, dir);
    assert_int_not_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "missing.ply"));
    assert_null(strstr(out, "--mem"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_small_mem_gives_the_same_archive),
        cmocka_unit_test(test_too_small_mem_refused_before_reading),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
