/* The codec's built-in prior (common/codec/ms_codec_prior.h): its estimate from counts,
 * model initialisation, the training counts of an encode, and a stream of
 * another version refused in one line naming it. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_codec_model.h"
#include "ms_codec_prior.h"
#include "ms_mesh_io.h"
#include "ms_quant.h"
#include "support/ms_codec_check.h"
#include "support/ms_test.h"

static void test_estimate(void **state)
{
    (void)state;
    uint64_t *counts = calloc(2 * MS_PRIOR_SIZE, sizeof *counts);
    uint16_t *p0 = malloc(MS_PRIOR_SIZE * sizeof *p0);
    assert_non_null(counts);
    assert_non_null(p0);
    assert_int_equal(ms_codec_prior_contexts(), MS_PRIOR_SIZE);
    counts[2 * 1] = 1, counts[2 * 1 + 1] = 1;      /* (n0 + 1) / (n + 2) = 1/2 */
    counts[2 * 2] = 3, counts[2 * 2 + 1] = 1;      /* 4/6 */
    counts[2 * 3] = 99;                            /* 100/101, capped at 63/64 */
    counts[2 * 4 + 1] = 1000;                      /* 1/1002, raised to 1/64 */
    counts[2 * (MS_PRIOR_SIZE - 1) + 1] = 2;       /* 1/4 */
    ms_codec_prior_estimate(counts, p0);
    assert_int_equal(p0[0], 32768);
    assert_int_equal(p0[1], 32768);
    assert_int_equal(p0[2], 43691);
    assert_int_equal(p0[3], 65536 - 1024);
    assert_int_equal(p0[4], 1024);
    assert_int_equal(p0[MS_PRIOR_SIZE - 1], 16384);
    free(counts);
    free(p0);
}

static void test_model_init(void **state)
{
    (void)state;
    const unsigned D = 36; /* a 12-bit stream */
    uint32_t n = ms_model_size(D);
    ms_rc_prob *m = malloc(n * sizeof *m);
    assert_non_null(m);
    ms_codec_model_init(m, D);
    /* Geometry is indexed by absolute kd-level, connectivity follows every level. */
    assert_int_equal(ms_prior_index(GEO_HALF(35, 3, 14), D), GEO_HALF(35, 3, 14));
    assert_int_equal(ms_prior_index(D * GEO_PER_LEVEL, D), MS_PRIOR_GEO);
    /* the freeze contexts (regions) close the model, outside the prior */
    assert_int_equal(n, D * GEO_PER_LEVEL + C_TOTAL + FRZ_CONTEXTS);
    assert_int_equal(ms_prior_index(n - 1 - FRZ_CONTEXTS, D), MS_PRIOR_SIZE - 1);
    assert_true(ms_prior_has(n - 1 - FRZ_CONTEXTS, D));
    assert_false(ms_prior_has(n - FRZ_CONTEXTS, D));
    assert_int_equal(frz_ctx(D, 0, 0), n - FRZ_CONTEXTS);
    assert_int_equal(frz_ctx(D, GEO_RUNS - 1, 9), n - 1);
    for (uint32_t i = 0; i < n; ++i) {
        uint16_t want = ms_prior_has(i, D) ? ms_codec_prior_p0[ms_prior_index(i, D)] : 32768;
        assert_int_equal(m[i].fast, want);
        assert_int_equal(m[i].slow, want);
    }
    /* The trained table is not flat where decisions are frequent: the root cell of
     * every training mesh splits in two at level 0. */
    assert_true(ms_codec_prior_p0[GEO_BOTH(0, 0, 0)] < 32768);
    free(m);
}

static void load_qmesh(const char *file, unsigned bits, ms_codec_state *canonical)
{
    char path[4096];
    ms_test_model_path(path, sizeof path, file);
    ms_mesh m;
    memset(&m, 0, sizeof m);
    ms_error err;
    if (ms_mesh_load(path, &m, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_qmesh q;
    ms_weld_report weld;
    assert_int_equal(ms_quantise_mesh(&m, bits, &q, &weld, &err), MS_OK);
    assert_int_equal(ms_codec_state_from_qmesh(&q, canonical, &err), MS_OK);
    assert_int_equal(ms_codec_state_canonicalise(canonical, &err), MS_OK);
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
}

static void decode_full(const uint8_t *data, size_t size, ms_codec_state *out)
{
    ms_error err;
    ms_codec_decoder *d = NULL;
    assert_int_equal(ms_codec_decoder_create(data, size, NULL, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(d, ms_codec_decoder_max_level(d), &err), MS_OK);
    assert_int_equal(ms_codec_decoder_state(d, out, &err), MS_OK);
    ms_codec_decoder_destroy(d);
}

/* Today's encoder writes version 3, which decodes to exactly the quantised
 * mesh; the same stream marked version 1 (the flat-context streams written
 * before the prior), 2 (before geometry ahead; neither was released) or 4 is
 * refused, by the header reader and the decoder, with one line naming the
 * version. */
static void test_other_versions_refused(void **state)
{
    (void)state;
    ms_codec_state want = {0}, got = {0};
    load_qmesh("stanford_bunny_res3.ply.gz", 12, &want);
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box.size = 1.0;
    uint8_t *stream = NULL;
    size_t size = 0;
    ms_error err;
    assert_int_equal(ms_codec_encode(&want, &par, &stream, &size, NULL, &err), MS_OK);
    assert_int_equal(stream[4], MS_CODEC_VERSION);
    decode_full(stream, size, &got);
    assert_true(ms_codec_state_equal(&got, &want, true));
    static const struct { uint8_t version; const char *text; } cases[] = {
        {1, "codec stream version 1, this build reads version 3"},
        {2, "codec stream version 2, this build reads version 3"},
        {4, "codec stream version 4, this build reads version 3"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; ++k) {
        stream[4] = cases[k].version;
        ms_codec_header h;
        assert_int_equal(ms_codec_read_header(stream, size, &h, &err), MS_ERR_UNSUPPORTED);
        assert_string_equal(err.text, cases[k].text);
        ms_codec_decoder *d = (ms_codec_decoder *)1;
        assert_int_equal(ms_codec_decoder_create(stream, size, NULL, NULL, &d, &err),
                         MS_ERR_UNSUPPORTED);
        assert_non_null(strstr(err.text, cases[k].text));
        assert_null(strchr(err.text, '\n'));
    }
    free(stream);
    ms_codec_state_free(&want);
    ms_codec_state_free(&got);
}

/* Counting decisions for training leaves the stream unchanged and counts what the
 * window codes: the root's one "both halves?" decision at level 0, nothing at
 * kd-levels past the stream's precision. */
static void test_training_counts(void **state)
{
    (void)state;
    ms_codec_state full = {0};
    load_qmesh("stanford_bunny_res3.ply.gz", 12, &full);
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box.size = 1.0;
    uint8_t *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    ms_error err;
    assert_int_equal(ms_codec_encode(&full, &par, &a, &na, NULL, &err), MS_OK);
    uint64_t *counts = calloc(2 * MS_PRIOR_SIZE, sizeof *counts);
    assert_non_null(counts);
    par.context_counts = counts;
    assert_int_equal(ms_codec_encode(&full, &par, &b, &nb, NULL, &err), MS_OK);
    assert_int_equal(na, nb);
    assert_memory_equal(a, b, na);
    uint64_t level0 = 0, beyond = 0, conn = 0;
    for (uint32_t i = 0; i < GEO_PER_LEVEL; ++i)
        level0 += counts[2 * i] + counts[2 * i + 1];
    for (uint32_t i = 36 * GEO_PER_LEVEL; i < MS_PRIOR_GEO; ++i)
        beyond += counts[2 * i] + counts[2 * i + 1];
    for (uint32_t i = MS_PRIOR_GEO; i < MS_PRIOR_SIZE; ++i)
        conn += counts[2 * i] + counts[2 * i + 1];
    assert_int_equal(counts[2 * GEO_BOTH(0, 0, 0)], 0); /* bit 1: the root splits */
    assert_int_equal(counts[2 * GEO_BOTH(0, 0, 0) + 1], 1);
    assert_int_equal(level0, 1);
    assert_int_equal(beyond, 0);
    assert_true(conn > 0);
    /* Counting again accumulates. */
    free(b);
    assert_int_equal(ms_codec_encode(&full, &par, &b, &nb, NULL, &err), MS_OK);
    assert_int_equal(counts[2 * GEO_BOTH(0, 0, 0) + 1], 2);
    free(counts);
    free(a);
    free(b);
    ms_codec_state_free(&full);
}

/* meshcodec train: writes a table of exactly the prior's size; usage and input
 * errors give exit statuses 2 and 1. */
static void test_train_cli(void **state)
{
    (void)state;
    char bin[1024], model[4096], dir[1024], out[8192], table[1200];
    static char cmd[16384];
    ms_test_bin_path(bin, sizeof bin, "meshcodec");
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(table, sizeof table, "%s/prior.c", dir);
    snprintf(cmd, sizeof cmd, "%s train %s %s --bits 8 -o %s", bin, model, model, table);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "prior of 5106 contexts from 2 meshes"));
    size_t n = 0;
    unsigned char *bytes = ms_test_read_file(table, &n);
    char *text = malloc(n + 1);
    assert_non_null(text);
    memcpy(text, bytes, n);
    text[n] = 0;
    free(bytes);
    assert_non_null(strstr(text, " *   stanford_bunny_res3.ply.gz\n"));
    const char *body = strstr(text, "ms_codec_prior_p0[MS_PRIOR_SIZE] = {");
    assert_non_null(body);
    size_t commas = 0;
    for (const char *c = body; *c; ++c)
        commas += *c == ',';
    assert_int_equal(commas, MS_PRIOR_SIZE);
    free(text);
    snprintf(cmd, sizeof cmd, "%s train -o %s ", bin, table);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s train %s --bits 7 -o %s ", bin, model, table);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s train %s/missing.ply -o %s ", bin, dir, table);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "meshcodec train: "));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_estimate),
        cmocka_unit_test(test_model_init),
        cmocka_unit_test(test_other_versions_refused),
        cmocka_unit_test(test_training_counts),
        cmocka_unit_test(test_train_cli),
    };
    return cmocka_run_group_tests_name("codec_prior", tests, NULL, NULL);
}
