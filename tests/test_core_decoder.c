/* The client core's decoder part (client/core/ms_core_decoder.h) without its
 * thread, a socket or a byte source: a core made bare (its decoder state
 * started, the whole index of a small baked demo taken) is handed chunks as
 * the byte source would queue them, and each test checks exactly what the
 * decoder made of them: pieces out of order put together, the verified
 * prefix handed to the view decoder, a precision bit failing its CRC cut,
 * refetched once and then given up with one warning line, an APO chunk
 * checked whole, a chunk for a cell the index does not hold ignored. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_client_core_internal.h"
#include "ms_progress.h"
#include "ms_test.h"
#include "ms_test_render.h"
#include "ms_view_decoder.h"

typedef struct fixture {
    char dir[512];
    ms_core *c;
} fixture;

/* A core with no thread: options as ms_core_start leaves them, the decoder
 * started (no helpers) and the index taken. ms_core_stop frees it. */
static ms_core *bare_core(ms_archive *index)
{
    ms_core *c = calloc(1, sizeof *c);
    assert_non_null(c);
    c->o.tolerance_px = c->o.apo_geometry_tolerance_px = 1.0;
    c->o.culled_bits_less = 6.0;
    c->member = -1;
    c->t0 = ms_now_seconds();
    c->index = index;
    c->stats.first_display = -1;
    pthread_mutex_init(&c->lock, NULL);
    pthread_cond_init(&c->wake, NULL);
    c->locked = true;
    ms_error err;
    assert_int_equal(ms_core_decoder_init(c, 0, &err), MS_OK);
    assert_true(ms_core_take_index(c, &err));
    return c;
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    /* 12 x 12 x 6 x 2 = 1,728 triangles, 16 bits, APO 4 levels deep */
    ms_archive *index = ms_test_render_bake_demo(12, f->dir, 16, 200, 4);
    assert_non_null(index);
    f->c = bare_core(index);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_core_stop(f->c); /* closes the index too */
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

static chunk_msg *chunk(uint32_t cell, uint8_t stream, uint32_t offset, const uint8_t *data,
                        uint32_t length)
{
    chunk_msg *m = calloc(1, sizeof *m + (length ? length : 1));
    assert_non_null(m);
    m->cell = cell, m->stream = stream, m->offset = offset, m->length = length;
    if (length)
        memcpy(m->data, data, length);
    return m;
}

/* Queues a list of chunks (in the order given) and lets the decoder take them. */
static bool take(ms_core *c, chunk_msg **list, size_t n)
{
    for (size_t k = 0; k + 1 < n; ++k)
        list[k]->next = list[k + 1];
    return ms_core_take_chunks(c, list[0]);
}

static ms_core_stats stats_of(ms_core *c)
{
    pthread_mutex_lock(&c->lock);
    ms_core_stats s = c->stats;
    pthread_mutex_unlock(&c->lock);
    return s;
}

/* The root's bytes in three pieces, the middle first: nothing is handed over
 * until they join up from byte 0, then all of it at once (the root goes bit
 * by bit, never held back), and the view decoder can show every bit. */
static void test_pieces_put_together(void **state)
{
    fixture *f = *state;
    ms_core *c = f->c;
    size_t len;
    const uint8_t *bytes = ms_archive_geometry(c->index, 0, &len);
    const ms_archive_cell *root = ms_archive_get_cell(c->index, 0);
    assert_true(len > 64);
    uint32_t a = (uint32_t)len / 3, b = 2 * (uint32_t)len / 3;
    chunk_msg *mid[] = {chunk(0, STREAM_GEOMETRY, a, bytes + a, b - a)};
    take(c, mid, 1);
    dcell *d = ms_core_dcell(c, 0);
    assert_int_equal(d->given, 0);
    assert_int_equal(d->geo.end, 0);
    assert_int_equal(d->geo.niv, 1);
    assert_int_equal(ms_view_available_bits(c->dec.view, 0), root->bits_min);
    chunk_msg *rest[] = {chunk(0, STREAM_GEOMETRY, b, bytes + b, (uint32_t)len - b),
                         chunk(0, STREAM_GEOMETRY, 0, bytes, a)};
    take(c, rest, 2);
    assert_int_equal(d->geo.end, len);
    assert_int_equal(d->given, len);
    assert_int_equal(ms_view_available_bits(c->dec.view, 0), root->bits_max);
    assert_non_null(d->header);
    assert_false(d->failed);
    assert_int_equal(stats_of(c).refetches, 0);
    assert_string_equal(stats_of(c).warning, "");
}

/* One byte of precision bit k wrong: what arrived since the last hand-over
 * (here everything: the bits before k too) is cut and asked for again, a
 * refetch counted; wrong again: the cell is given up at its last good
 * precision, with one warning line. */
static void test_bad_bit_refetched_then_given_up(void **state)
{
    fixture *f = *state;
    ms_core *c = f->c;
    size_t len;
    const uint8_t *bytes = ms_archive_geometry(c->index, 0, &len);
    const ms_archive_cell *root = ms_archive_get_cell(c->index, 0);
    unsigned k = root->bits_min + 2;
    assert_true(k <= root->bits_max);
    uint32_t good = ms_archive_geometry_prefix(c->index, 0, k - 1);
    uint32_t bad_end = ms_archive_geometry_prefix(c->index, 0, k);
    uint8_t *copy = malloc(len);
    memcpy(copy, bytes, len);
    copy[bad_end - 1] ^= 0x5A;
    chunk_msg *all[] = {chunk(0, STREAM_GEOMETRY, 0, copy, (uint32_t)len)};
    take(c, all, 1);
    dcell *d = ms_core_dcell(c, 0);
    assert_true(good > ms_archive_geometry_prefix(c->index, 0, root->bits_min));
    assert_int_equal(d->given, 0);
    assert_int_equal(d->geo.end, 0); /* wanted again from the last hand-over */
    assert_int_equal(ms_view_available_bits(c->dec.view, 0), root->bits_min);
    assert_int_equal(stats_of(c).refetches, 1);
    assert_false(d->failed);
    chunk_msg *again[] = {chunk(0, STREAM_GEOMETRY, 0, copy, (uint32_t)len)};
    take(c, again, 1);
    assert_true(d->failed);
    assert_int_equal(d->given, 0);
    assert_int_equal(stats_of(c).refetches, 1);
    char line[256];
    snprintf(line, sizeof line, "cell 0: precision bit %u fails its CRC (after a refetch); "
             "cell left at its last good precision", k);
    assert_string_equal(stats_of(c).warning, line);
    free(copy);
}

/* An APO chunk is checked whole: a damaged one is dropped (a retry counted on
 * the cell), the right one kept; a prefix is kept as it comes. */
static void test_apo_checked_whole(void **state)
{
    fixture *f = *state;
    ms_core *c = f->c;
    uint32_t cell = MS_ARCHIVE_NONE;
    for (uint32_t i = 0; i < ms_archive_get_header(c->index)->cell_count && cell == MS_ARCHIVE_NONE;
         ++i)
        if (ms_archive_get_cell(c->index, i)->apo_length > 8)
            cell = i;
    assert_int_not_equal(cell, MS_ARCHIVE_NONE);
    size_t len;
    const uint8_t *apo = ms_archive_apo(c->index, cell, &len);
    dcell *d = ms_core_dcell(c, cell);
    chunk_msg *part[] = {chunk(cell, STREAM_APO, 0, apo, 8)};
    assert_true(take(c, part, 1));
    assert_int_equal(d->apo_given, 8);
    uint8_t *copy = malloc(len);
    memcpy(copy, apo, len);
    copy[len - 1] ^= 0x01;
    chunk_msg *bad[] = {chunk(cell, STREAM_APO, 8, copy + 8, (uint32_t)len - 8)};
    assert_true(take(c, bad, 1));
    assert_int_equal(d->apo_given, 0);
    assert_int_equal(d->apo.end, 0);
    assert_int_equal(d->retries, 1);
    assert_false(d->failed);
    chunk_msg *whole[] = {chunk(cell, STREAM_APO, 0, apo, (uint32_t)len)};
    assert_true(take(c, whole, 1));
    assert_int_equal(d->apo_given, len);
    assert_memory_equal(d->apo.buf, apo, len);
    free(copy);
}

/* A failed request counts as a bad range (geometry); a chunk for a cell the
 * view does not know is dropped; the consumed sequence follows the queue. */
static void test_failed_and_unknown(void **state)
{
    fixture *f = *state;
    ms_core *c = f->c;
    chunk_msg *m = chunk(0, STREAM_GEOMETRY, 0, NULL, 0);
    m->failed = true;
    m->seq = 7;
    chunk_msg *unknown = chunk(ms_archive_get_header(c->index)->cell_count + 5, STREAM_GEOMETRY, 0,
                               (const uint8_t *)"abc", 3);
    unknown->seq = 8;
    chunk_msg *list[] = {m, unknown};
    assert_false(take(c, list, 2));
    assert_int_equal(c->dec.consumed_seq, 8);
    assert_int_equal(ms_core_dcell(c, 0)->retries, 1);
    assert_int_equal(stats_of(c).refetches, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_pieces_put_together, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bad_bit_refetched_then_given_up, setup, teardown),
        cmocka_unit_test_setup_teardown(test_apo_checked_whole, setup, teardown),
        cmocka_unit_test_setup_teardown(test_failed_and_unknown, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
