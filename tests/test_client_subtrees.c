/* The client core with an index that comes by subtree (issue 24, docs/CLIENT.md
 * "An index by subtree"). A demo model of 30,000 triangles baked with small
 * leaves (48 triangles) has cells on four levels, so with n = 4 (one level a
 * subtree) its index comes in three levels of subtrees below the root's.
 *   - the view decoder on a partly known index: records learned and forgotten,
 *     a cell whose children are not known does not split and is reported;
 *   - streamed locally (the subtrees read from the file through
 *     ms_archive_subtree, as a server sends them) along the demo close-up, at
 *     every other keyframe (the last included) the client's cut equals the view decoder's on the whole
 *     archive, and the subtrees it holds are exactly those that cut needs
 *     (computed here from the reference cut: the root's, the children's of
 *     every split cell, and those of shown cells within a bit of splitting),
 *     holding fewer index bytes than the whole index at the close-up;
 *   - the whole index (as from a server without subtrees) gives the same cut;
 *   - against meshserve (protocol version 3) the same cut and subtrees, and
 *     not offering CAP_INDEX_SUBTREES (the whole index at open) the same cut;
 *   - through a proxy that makes meshserve a version-2 server (it rewrites the
 *     client's HELLO to versions 1..2 without CAP_INDEX_SUBTREES), a client
 *     that asks for subtrees takes the whole index and gives the same cut;
 *   - a corrupt subtree is fetched once more, then given up with one warning:
 *     its cell stays unsplit, the core goes on, nothing crashes or leaks.
 * Every wait is bounded. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_camera_path.h"
#include "ms_client_core.h"
#include "ms_nsp_check.h"
#include "ms_proto.h"
#include "ms_subtree.h"
#include "ms_test.h"
#include "ms_test_archive.h"
#include "ms_test_core.h"
#include "ms_test_net.h"
#include "ms_view_decoder.h"

#define MODEL "demo"
#define PATH_FILE "scripts/paths/demo-closeup.cam"
#define TRIANGLES 30000
#define MIN_TRIANGLES 48
#define WAIT_SECONDS 100.0 /* a bound, not a measurement: once missed at 50 s under load 16 */

static ms_test_served *g;

static int group_setup(void **state)
{
    (void)state;
    ms_test_served *f = ms_test_served_new(MODEL);
    if (!f)
        return -1;
    char ply[600];
    snprintf(ply, sizeof ply, "%s/demo.ply", f->dir);
    ms_nsp_test_demo_ply(ply, TRIANGLES);
    ms_bake_report report;
    ms_nsp_test_bake(ply, f->archives, MODEL, 16, MIN_TRIANGLES, &report);
    if (ms_test_served_open(f, PATH_FILE) != 0)
        return -1;
    ms_test_served_launch(f, 0);
    g = f;
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    ms_test_served_free(g);
    g = NULL;
    return 0;
}

static ms_camera key_camera(size_t k) { return ms_test_core_key_camera(&g->path, k); }

static ms_core_options local_options(void)
{
    ms_core_options o = {0};
    o.archive_path = g->file;
    o.model = MODEL;
    o.tolerance_px = 1.0;
    o.hysteresis_bits = 0; /* the selection is then a function of the camera alone */
    o.export_frames = true;
    o.window_bytes = 65536;
    return o;
}

static const ms_view_select_params reference_params = {
    .tolerance_px = 1.0, .margin = 0, .hysteresis = 0, .culled_bits_less = 6.0};

/* The view decoder on the whole archive, run to its cut for camera. */
static ms_view *reference_view(const ms_camera *camera)
{
    ms_view *v;
    ms_error err;
    if (ms_view_create_from_archive(g->archive, &v, &err) != MS_OK)
        fail_msg("%s", err.text);
    for (int pass = 0; pass < 12; ++pass) {
        ms_view_select(v, camera, &reference_params, NULL);
        ms_view_apply_report r;
        if (ms_view_apply(v, &r, &err) != MS_OK)
            fail_msg("%s", err.text);
        if (!r.splits && !r.merges && !r.refined && !r.coarsened)
            break;
    }
    return v;
}

/* The client's cut equals the reference's, cell for cell; returns the cells
 * shown. */
static uint32_t check_cut(const ms_core_frame *frame, const ms_view *v)
{
    uint32_t n = ms_view_cell_count(v), shown = 0;
    assert_int_equal(frame->cell_count, n);
    for (uint32_t i = 0; i < n; ++i) {
        ms_view_cell_state st = ms_view_state(v, i);
        uint8_t expect = st == MS_VIEW_SHOWN ? (uint8_t)ms_view_bits(v, i)
                         : st == MS_VIEW_SPLIT ? MS_VIEW_TARGET_SPLIT
                                               : MS_VIEW_TARGET_HIDDEN;
        if (ms_core_frame_cell_bits(frame, i) != expect)
            fail_msg("cell %u: client %u, direct %u", i, ms_core_frame_cell_bits(frame, i), expect);
        shown += st == MS_VIEW_SHOWN;
    }
    return shown;
}

static int compare_ids(const void *x, const void *y)
{
    uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return a < b ? -1 : a > b;
}

/* The subtrees the reference cut needs, ascending, computed from the design's
 * rule (docs/CLIENT.md): the root's; for a cell at a subtree's last level
 * (level + 1 a multiple of S) that is split, or shown within a bit of
 * splitting (its selection need above bits_max - 1), the subtree of its
 * children (id = its first child). */
static uint32_t *needed_subtrees(const ms_view *v, const ms_camera *camera, unsigned levels,
                                 size_t *count)
{
    uint32_t n = ms_view_cell_count(v);
    uint32_t *ids = malloc((n + 1) * sizeof *ids);
    size_t k = 0;
    ids[k++] = 0;
    for (uint32_t i = 0; i < n; ++i) {
        const ms_archive_cell *c = ms_view_cell(v, i);
        if (c->first_child == MS_ARCHIVE_NONE || (c->level + 1u) % levels != 0)
            continue;
        ms_view_cell_state st = ms_view_state(v, i);
        if (st == MS_VIEW_SPLIT ||
            (st == MS_VIEW_SHOWN && ms_view_cell_select_need(v, camera, i, &reference_params) >
                                        (double)c->bits_max - 1.0))
            ids[k++] = c->first_child;
    }
    qsort(ids, k, sizeof *ids, compare_ids);
    *count = k;
    return ids;
}

/* The cells the client keeps per-cell state for when it holds `subtrees`:
 * every cell of each sibling group one of their members belongs to (the
 * root's group is the root alone), from the whole archive's membership. */
static uint32_t state_cells_of(const uint32_t *subtrees, size_t count, unsigned levels)
{
    const ms_archive_header *h = ms_archive_get_header(g->archive);
    uint32_t group_size = (uint32_t)h->n * h->n * h->n;
    uint32_t groups = 1 + (h->cell_count - 1) / group_size;
    bool *held = calloc(groups, sizeof *held);
    assert_non_null(held);
    uint32_t cells = 0;
    for (size_t k = 0; k < count; ++k) {
        uint32_t *members;
        size_t n;
        ms_error err;
        if (ms_subtree_members(g->archive, levels, subtrees[k], &members, &n, &err) != MS_OK)
            fail_msg("%s", err.text);
        for (size_t m = 0; m < n; ++m) {
            uint32_t group = members[m] == 0 ? 0 : 1 + (members[m] - 1) / group_size;
            if (!held[group])
                cells += group == 0 ? 1 : group_size;
            held[group] = true;
        }
        free(members);
    }
    free(held);
    return cells;
}

/* The client's per-cell bookkeeping (docs/CLIENT.md, "What a cell costs"):
 * the formula over the subtrees it holds, counted in the budget's memory. */
static void check_state(const ms_core_stats *st, const ms_core_frame *frame, unsigned levels)
{
    assert_int_equal(st->state_cells, state_cells_of(frame->subtrees, frame->subtree_count, levels));
    assert_int_equal(st->state_bytes_held, (uint64_t)st->state_cells * ms_core_state_bytes_per_cell());
    assert_true(ms_core_state_bytes_per_cell() > ms_view_cell_state_size());
    assert_true(st->memory >= st->index_bytes_held + st->state_bytes_held);
}

/* ---- the view decoder on a partly known index ----------------------------- */

/* The synthetic archive (ms_test_archive.h): root, its 64 children, and the 64
 * children of cell 5. */
static void test_view_partial(void **state)
{
    (void)state;
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/t.msa", dir);
    ms_test_write_archive(path, 0);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_view *v;
    assert_int_equal(ms_view_create_partial(h, &v, &err), MS_OK);
    assert_int_equal(ms_view_known_count(v), 0);
    assert_int_equal(ms_view_next_known(v, MS_ARCHIVE_NONE), MS_ARCHIVE_NONE);
    assert_null(ms_view_cell(v, 0));

    /* the root, then the group of cell 5's children: 1..64 stay unknown */
    uint32_t ids[64];
    ms_archive_cell recs[64];
    ids[0] = 0, recs[0] = *ms_archive_get_cell(a, 0);
    assert_int_equal(ms_view_state_cells(v), 0);
    assert_int_equal(ms_view_learn(v, ids, recs, 1, &err), MS_OK);
    assert_int_equal(ms_view_state(v, 0), MS_VIEW_SHOWN);
    assert_int_equal(ms_view_state_cells(v), 1); /* the root's group is the root alone */
    assert_false(ms_view_children_known(v, 0));
    assert_int_equal(ms_view_split(v, 0, &err), MS_ERR_RANGE);

    /* a camera right at the model: the root would split, it cannot */
    ms_camera cam;
    double c[3] = {h->box_origin[0] + h->box_side / 2, h->box_origin[1] + h->box_side / 2,
                   h->box_origin[2] + h->box_side / 2};
    double eye[3] = {c[0], c[1] - 0.6 * h->box_side, c[2]};
    double up[3] = {0, 0, 1};
    assert_int_equal(ms_camera_look_at(eye, c, up, 60.0, 640, 480, 1e-4 * h->box_side,
                                       10 * h->box_side, &cam, &err), MS_OK);
    ms_view_select_params sp;
    ms_view_select_params_default(&sp);
    sp.tolerance_px = 0.01;
    ms_view_select_report rep = {0};
    ms_view_select(v, &cam, &sp, &rep);
    assert_int_equal(rep.blocked_count, 1);
    assert_int_equal(rep.blocked[0], 0);
    assert_int_equal(rep.near_count, 0);
    assert_int_equal(ms_view_target(v, 0), ms_archive_get_cell(a, 0)->bits_max);
    assert_int_equal(ms_view_target(v, 1), MS_VIEW_TARGET_HIDDEN);

    /* cell 65's record against an unknown parent is taken alone... */
    for (uint32_t k = 0; k < 64; ++k)
        ids[k] = 65 + k, recs[k] = *ms_archive_get_cell(a, 65 + k);
    assert_int_equal(ms_view_learn(v, ids, recs, 64, &err), MS_OK);
    assert_int_equal(ms_view_known_count(v), 65);
    assert_int_equal(ms_view_state_cells(v), 65);
    assert_int_equal(ms_view_next_known(v, 0), 65);
    assert_int_equal(ms_view_next_known(v, 128), MS_ARCHIVE_NONE);
    /* ...and a record that breaks the rules is refused, nothing learned */
    ids[0] = 1, recs[0] = *ms_archive_get_cell(a, 1);
    recs[0].bits_min = (uint8_t)(recs[0].bits_max + 1);
    assert_int_equal(ms_view_learn(v, ids, recs, 1, &err), MS_ERR_ARG);
    assert_false(ms_view_known(v, 1));

    /* the root's children: now it splits (as far as selection goes) */
    for (uint32_t k = 0; k < 64; ++k)
        ids[k] = 1 + k, recs[k] = *ms_archive_get_cell(a, 1 + k);
    assert_int_equal(ms_view_learn(v, ids, recs, 64, &err), MS_OK);
    assert_true(ms_view_children_known(v, 0));
    assert_int_equal(ms_view_state_cells(v), 129);
    ms_view_select(v, &cam, &sp, &rep);
    assert_int_equal(ms_view_target(v, 0), MS_VIEW_TARGET_SPLIT);
    assert_true(ms_view_target(v, 1) != MS_VIEW_TARGET_HIDDEN); /* the walk reaches the children */
    assert_int_equal(rep.blocked_count, 0);

    /* the root stays; hidden cells may go, a shown one may not */
    ids[0] = 0;
    assert_int_equal(ms_view_unlearn(v, ids, 1, &err), MS_ERR_RANGE);
    for (uint32_t k = 0; k < 64; ++k)
        ids[k] = 65 + k;
    assert_int_equal(ms_view_unlearn(v, ids, 64, &err), MS_OK);
    assert_int_equal(ms_view_known_count(v), 65);
    assert_int_equal(ms_view_state_cells(v), 65);
    assert_null(ms_view_cell(v, 70));
    assert_int_equal(ms_view_next_known(v, 64), MS_ARCHIVE_NONE);

    ms_view_select_report_free(&rep);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* ---- streaming by subtree ---------------------------------------------------- */

static void test_path_cut_and_subtrees(void **state)
{
    (void)state;
    unsigned levels = ms_archive_subtree_levels(g->archive);
    assert_true(ms_archive_subtree_count(g->archive) > 8);
    size_t whole_index = ms_archive_index_bytes_held(g->archive);
    ms_core_options o = local_options();
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_core_frame *frame = NULL;
    ms_core_stats st;
    unsigned deepest = 0;
    for (size_t k = 0; k < g->path.count; k += 2) { /* 0, 2, .., 8: the last included */
        ms_camera cam = key_camera(k);
        ms_core_set_camera(core, &cam);
        if (!ms_test_core_wait_complete(core, WAIT_SECONDS, &st, &frame))
            fail_msg("keyframe %zu not complete: %s", k, st.error);
        assert_non_null(frame);
        assert_true(st.index_by_subtree);
        ms_view *v = reference_view(&cam);
        uint32_t shown = check_cut(frame, v);
        assert_true(shown > 1);
        size_t need_count;
        uint32_t *need = needed_subtrees(v, &cam, levels, &need_count);
        if (frame->subtree_count != need_count)
            fail_msg("keyframe %zu: the client holds %zu subtrees, the cut needs %zu", k,
                     frame->subtree_count, need_count);
        assert_memory_equal(frame->subtrees, need, need_count * sizeof *need);
        assert_int_equal(st.subtrees_held, need_count);
        check_state(&st, frame, levels);
        print_message("keyframe %zu: %u cells shown, %zu subtrees held of %u, %llu index bytes "
                      "held, cell state %llu bytes (%u of %u cells)\n", k, shown, need_count,
                      ms_archive_subtree_count(g->archive), (unsigned long long)st.index_bytes_held,
                      (unsigned long long)st.state_bytes_held, st.state_cells,
                      ms_archive_get_header(g->archive)->cell_count);
        for (uint32_t i = 0; i < ms_view_cell_count(v); ++i)
            if (ms_view_state(v, i) == MS_VIEW_SHOWN && ms_view_cell(v, i)->level > deepest)
                deepest = ms_view_cell(v, i)->level;
        free(need);
        ms_view_destroy(v);
    }
    /* the close-up went three subtree levels deep and never needed the whole
     * index */
    print_message("whole index %zu bytes; peak held %llu, %llu subtrees received, %llu index "
                  "bytes received, first display %.3f s\n", whole_index,
                  (unsigned long long)st.peak_index_bytes_held,
                  (unsigned long long)st.subtrees_received,
                  (unsigned long long)st.index_bytes_received, st.first_display);
    assert_true(deepest >= 3);
    assert_true(st.subtrees_received >= 3);
    assert_true(st.peak_index_bytes_held < whole_index);
    assert_true(st.index_bytes_held <= st.peak_index_bytes_held);
    assert_true(st.index_bytes_received > 0);
    assert_true(st.first_display >= 0);
    assert_int_equal(st.cells_failed, 0);
    assert_string_equal(st.warning, "");
    ms_core_frame_free(frame);
    ms_core_stop(core);
}

/* The whole index at open (what a server without subtrees sends): the same
 * cut, no subtree figures. */
static void test_whole_index_same_cut(void **state)
{
    (void)state;
    ms_core_options o = local_options();
    o.whole_index = true;
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_core_frame *frame = NULL;
    ms_core_stats st;
    ms_camera cam = key_camera(g->path.count - 1);
    ms_core_set_camera(core, &cam);
    if (!ms_test_core_wait_complete(core, WAIT_SECONDS, &st, &frame))
        fail_msg("not complete: %s", st.error);
    assert_false(st.index_by_subtree);
    assert_int_equal(st.subtrees_received, 0);
    assert_int_equal(frame->subtree_count, 0);
    /* a whole index: state for every cell of the model, left out of the budget
     * like the index itself; by subtree at the same camera (the last keyframe
     * of test_path_cut_and_subtrees) only for the groups the cut needs */
    uint32_t cells = ms_archive_get_header(g->archive)->cell_count;
    assert_int_equal(st.state_cells, cells);
    assert_int_equal(st.state_bytes_held, (uint64_t)cells * ms_core_state_bytes_per_cell());
    size_t need_count;
    ms_view *reference = reference_view(&cam);
    unsigned levels = ms_archive_subtree_levels(g->archive);
    uint32_t *need = needed_subtrees(reference, &cam, levels, &need_count);
    uint32_t by_subtree = state_cells_of(need, need_count, levels);
    print_message("cell state: whole index %u cells, by subtree %u cells (%zu subtrees)\n", cells,
                  by_subtree, need_count);
    assert_true(by_subtree < cells / 2);
    free(need);
    ms_view_destroy(reference);
    ms_view *v = reference_view(&cam);
    assert_true(check_cut(frame, v) > 1);
    ms_view_destroy(v);
    ms_core_frame_free(frame);
    ms_core_stop(core);
}

/* Against meshserve (protocol version 3): the index head, then subtrees as
 * stream INDEX; the same cut and the same subtrees as the local mode. Then as
 * a client of a server without subtrees sees it (not offering
 * CAP_INDEX_SUBTREES: the whole index at open): the same cut. */
static void test_network(void **state)
{
    (void)state;
    ms_camera cam = key_camera(g->path.count - 1);
    ms_view *v = reference_view(&cam);
    size_t need_count;
    uint32_t *need = needed_subtrees(v, &cam, ms_archive_subtree_levels(g->archive), &need_count);
    for (int whole = 0; whole < 2; ++whole) {
        ms_core_options o = local_options();
        o.archive_path = NULL;
        o.host = "127.0.0.1";
        o.port = g->port;
        o.bandwidth = 4e6;
        o.whole_index = whole;
        ms_core *core;
        ms_error err;
        assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
        ms_core_set_camera(core, &cam);
        ms_core_frame *frame = NULL;
        ms_core_stats st;
        if (!ms_test_core_wait_complete(core, WAIT_SECONDS, &st, &frame))
            fail_msg("%s index: not complete: %s", whole ? "whole" : "subtree", st.error);
        assert_true(check_cut(frame, v) > 1);
        assert_int_equal(st.index_by_subtree, !whole);
        assert_true(st.index_bytes_received > 0);
        if (whole) {
            assert_int_equal(frame->subtree_count, 0);
            assert_int_equal(st.subtrees_received, 0);
        } else {
            assert_int_equal(frame->subtree_count, need_count);
            assert_memory_equal(frame->subtrees, need, need_count * sizeof *need);
            assert_true(st.subtrees_received >= need_count - 1);
            check_state(&st, frame, ms_archive_subtree_levels(g->archive));
            /* subtree bytes are counted as index, not payload */
            assert_int_equal(st.bytes_received, st.geometry_bytes_received);
        }
        assert_int_equal(st.bytes_in_flight, 0);
        assert_int_equal(st.cells_failed, 0);
        print_message("%s index: %llu index bytes received, %llu payload bytes, first display "
                      "%.3f s\n", whole ? "whole" : "subtree",
                      (unsigned long long)st.index_bytes_received,
                      (unsigned long long)st.bytes_received, st.first_display);
        ms_core_frame_free(frame);
        ms_core_stop(core);
    }
    free(need);
    ms_view_destroy(v);
}

/* ---- a version-2 server: meshserve behind a proxy that takes version 3 and
 * CAP_INDEX_SUBTREES out of the client's HELLO (so the server answers as a
 * version-2 server does: version 2, the whole index) and passes the rest ---- */

typedef struct v2_proxy {
    int listen_fd;
    uint16_t port, server_port;
    pthread_t thread;
    volatile int stop;
    unsigned hellos; /* HELLOs rewritten */
} v2_proxy;

static bool write_all(int fd, const uint8_t *data, size_t size)
{
    while (size) {
        ssize_t n = write(fd, data, size);
        if (n <= 0)
            return false;
        data += n, size -= (size_t)n;
    }
    return true;
}

/* Reads the client's HELLO, sends the server a version-2 one, then forwards
 * what followed it; false when the client sent no HELLO. */
static bool proxy_hello(v2_proxy *p, int cfd, int sfd)
{
    ms_proto_decoder *dec = NULL;
    ms_proto_decoder_config cfg = {MS_PROTO_ROLE_SERVER, 1u << 20, MS_PROTO_MAX_BATCH};
    if (ms_proto_decoder_new(&cfg, &dec, NULL) != MS_OK)
        return false;
    uint8_t buf[65536];
    size_t have = 0, at = 0;
    bool ok = false;
    while (!p->stop && have < sizeof buf) {
        struct pollfd pf = {cfd, POLLIN, 0};
        if (poll(&pf, 1, 50) <= 0)
            continue;
        ssize_t n = read(cfd, buf + have, sizeof buf - have);
        if (n <= 0)
            break;
        have += (size_t)n;
        ms_proto_message m;
        bool got = false;
        size_t used = 0;
        if (ms_proto_decoder_feed(dec, buf + at, have - at, &used, &m, &got, NULL, NULL) != MS_OK)
            break;
        at += used;
        if (!got)
            continue;
        if (m.type != MS_PROTO_HELLO)
            break;
        m.body.hello.max_version = 2;
        m.body.hello.capabilities &= ~MS_PROTO_CAP_INDEX_SUBTREES;
        uint8_t out[4096];
        size_t written;
        ok = ms_proto_encode(&m, out, sizeof out, &written, NULL) == MS_OK &&
             write_all(sfd, out, written) && write_all(sfd, buf + at, have - at);
        p->hellos += ok;
        break;
    }
    ms_proto_decoder_free(dec);
    return ok;
}

static void *proxy_main(void *arg)
{
    v2_proxy *p = arg;
    while (!p->stop) {
        struct pollfd lf = {p->listen_fd, POLLIN, 0};
        if (poll(&lf, 1, 50) <= 0)
            continue;
        int cfd = accept(p->listen_fd, NULL, NULL);
        if (cfd < 0)
            continue;
        int sfd = socket(AF_INET, SOCK_STREAM, 0);
        struct sockaddr_in sin = {.sin_family = AF_INET, .sin_port = htons(p->server_port),
                                  .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
        if (sfd >= 0 && connect(sfd, (struct sockaddr *)&sin, sizeof sin) == 0 &&
            proxy_hello(p, cfd, sfd)) {
            struct pollfd pf[2] = {{cfd, POLLIN, 0}, {sfd, POLLIN, 0}};
            for (bool open = true; open && !p->stop;) {
                if (poll(pf, 2, 50) <= 0)
                    continue;
                for (int k = 0; k < 2 && open; ++k) {
                    if (!(pf[k].revents & (POLLIN | POLLHUP | POLLERR)))
                        continue;
                    uint8_t buf[65536];
                    ssize_t n = read(pf[k].fd, buf, sizeof buf);
                    open = n > 0 && write_all(pf[1 - k].fd, buf, (size_t)n);
                }
            }
        }
        if (sfd >= 0)
            close(sfd);
        close(cfd);
    }
    return NULL;
}

static void v2_proxy_start(v2_proxy *p, uint16_t server_port)
{
    memset(p, 0, sizeof *p);
    p->server_port = server_port;
    p->listen_fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(p->listen_fd >= 0);
    struct sockaddr_in sin = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof sin;
    assert_int_equal(bind(p->listen_fd, (struct sockaddr *)&sin, sizeof sin), 0);
    assert_int_equal(listen(p->listen_fd, 4), 0);
    assert_int_equal(getsockname(p->listen_fd, (struct sockaddr *)&sin, &len), 0);
    p->port = ntohs(sin.sin_port);
    assert_int_equal(pthread_create(&p->thread, NULL, proxy_main, p), 0);
}

static void v2_proxy_stop(v2_proxy *p)
{
    p->stop = 1;
    pthread_join(p->thread, NULL);
    close(p->listen_fd);
}

/* A client that asks for subtrees, served by a version-2 server: it takes the
 * whole index at open and gives the same cut. */
static void test_version2_server(void **state)
{
    (void)state;
    v2_proxy proxy;
    v2_proxy_start(&proxy, g->port);
    ms_camera cam = key_camera(g->path.count - 1);
    ms_core_options o = local_options();
    o.archive_path = NULL;
    o.host = "127.0.0.1";
    o.port = proxy.port;
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_core_set_camera(core, &cam);
    ms_core_frame *frame = NULL;
    ms_core_stats st;
    bool complete = ms_test_core_wait_complete(core, WAIT_SECONDS, &st, &frame);
    ms_core_stop(core);
    v2_proxy_stop(&proxy);
    if (!complete)
        fail_msg("not complete through a version-2 server: %s", st.error);
    assert_true(proxy.hellos >= 1);
    assert_false(st.index_by_subtree);
    assert_int_equal(st.subtrees_received, 0);
    assert_int_equal(frame->subtree_count, 0);
    assert_int_equal(st.state_cells, ms_archive_get_header(g->archive)->cell_count);
    ms_view *v = reference_view(&cam);
    assert_true(check_cut(frame, v) > 1);
    ms_view_destroy(v);
    ms_core_frame_free(frame);
}

typedef struct corruption {
    uint32_t subtree; /* the subtree whose bytes are damaged, every time */
    unsigned seen;
} corruption;

static void corrupt_subtree(uint32_t subtree, uint32_t offset, uint8_t *data, size_t length,
                            void *arg)
{
    corruption *c = arg;
    if (subtree != c->subtree || length == 0)
        return;
    c->seen++;
    data[length / 2] ^= 0x5A; /* inside the zlib stream (or its Adler-32) */
    (void)offset;
}

/* A deep subtree the close-up needs, damaged every time it comes: it is fetched twice, then its cell stays
 * unsplit with one warning line; the core does not stop. */
static void test_corrupt_subtree(void **state)
{
    (void)state;
    ms_camera cam = key_camera(g->path.count - 1);
    ms_view *v = reference_view(&cam);
    unsigned levels = ms_archive_subtree_levels(g->archive);
    size_t need_count;
    uint32_t *need = needed_subtrees(v, &cam, levels, &need_count);
    assert_true(need_count >= 3);
    uint32_t victim = need[need_count - 1]; /* a deep one the cut needs */
    uint32_t parent = ms_archive_get_cell(g->archive, victim)->parent;
    free(need);
    ms_view_destroy(v);

    corruption bad = {victim, 0};
    ms_core_options o = local_options();
    o.index_filter = corrupt_subtree;
    o.payload_filter_arg = &bad;
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_core_set_camera(core, &cam);
    ms_core_stats st;
    ms_core_frame *frame = NULL;
    /* never complete: wait for the warning */
    for (int i = 0; i < 2000; ++i) {
        ms_core_get_stats(core, &st);
        if (st.warning[0] || st.error[0])
            break;
        ms_test_sleep_s(0.01);
    }
    assert_string_equal(st.error, "");
    char expect[64];
    snprintf(expect, sizeof expect, "subtree %u: ", victim);
    if (strncmp(st.warning, expect, strlen(expect)) != 0)
        fail_msg("warning '%s'", st.warning);
    assert_non_null(strstr(st.warning, "stays unsplit"));
    assert_null(strchr(st.warning, '\n'));
    assert_int_equal(bad.seen, 2); /* fetched once more, then given up */
    assert_false(ms_test_core_wait_complete(core, 1.0, &st, &frame));
    assert_string_equal(st.error, "");
    assert_non_null(frame);
    assert_true(ms_core_frame_cell_bits(frame, parent) != MS_VIEW_TARGET_SPLIT &&
                ms_core_frame_cell_bits(frame, parent) != MS_VIEW_TARGET_HIDDEN);
    assert_true(st.cells_shown > 1); /* the rest of the view refined */
    ms_core_frame_free(frame);
    ms_core_stop(core);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_view_partial),
        cmocka_unit_test(test_path_cut_and_subtrees),
        cmocka_unit_test(test_whole_index_same_cut),
        cmocka_unit_test(test_network),
        cmocka_unit_test(test_version2_server),
        cmocka_unit_test(test_corrupt_subtree),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
