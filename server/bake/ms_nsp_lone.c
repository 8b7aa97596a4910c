/* Lone levels of the baker's vertices: see ms_nsp_lone.h. */
#include "ms_nsp_lone.h"

#include <errno.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_big_alloc.h"
#include "ms_nsp.h"
#include "ms_parallel.h"
#include "ms_quant.h"
#include "ms_radix_sort.h"

ms_status ms_nsp_lone_levels(const uint64_t *keys, size_t n, unsigned key_bits, uint8_t **out,
                             ms_error *err)
{
    *out = NULL;
    if (n > UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "too many vertices (%zu) for lone levels", n);
    uint8_t *lone = malloc(n ? n : 1);
    uint64_t *sorted = ms_big_malloc((n ? n : 1) * sizeof *sorted);
    uint32_t *who = ms_big_malloc((n ? n : 1) * sizeof *who);
    ms_status s = MS_OK;
    if (!lone || !sorted || !who)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory finding lone levels");
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        sorted[i] = keys[i];
        who[i] = (uint32_t)i;
    }
    if (s == MS_OK)
        s = ms_radix_sort_pairs(sorted, who, n, key_bits, err);
    /* runs of one key; a run's level comes from the distinct keys around it */
    for (size_t i = 0; s == MS_OK && i < n;) {
        size_t j = i + 1;
        while (j < n && sorted[j] == sorted[i])
            ++j;
        unsigned level = 0, l;
        if (i > 0 && (l = ms_key_lcp(sorted[i - 1], sorted[i], key_bits) + 1) > level)
            level = l;
        if (j < n && (l = ms_key_lcp(sorted[i], sorted[j], key_bits) + 1) > level)
            level = l;
        for (size_t k = i; k < j; ++k)
            lone[who[k]] = (uint8_t)level;
        i = j;
    }
    free(sorted);
    free(who);
    if (s != MS_OK) {
        free(lone);
        return s;
    }
    *out = lone;
    return MS_OK;
}

/* ---- per-leaf segments (out of core) ------------------------------------- */

typedef struct segment_work {
    ms_nsp_build *b;
    const uint32_t *leaves;
    pthread_mutex_t lock;
    int64_t file_end;
    ms_nsp_io io;
    uint64_t lone_at_level[3 * MS_CODEC_MAX_BITS + 1];
    bool failed;
    ms_error err;
} segment_work;

/* Own distinct keys of leaf `node`, sorted, and their lone levels. */
static ms_status leaf_segment(segment_work *w, uint32_t node, uint64_t *io_read,
                              uint64_t *io_written, ms_error *err)
{
    ms_nsp_build *b = w->b;
    ms_nsp_node *nd = &b->nodes[node];
    const ms_nsp_shape *shape = &b->params.shape;
    const unsigned D = 3 * shape->bits;
    uint64_t *rec;
    size_t count;
    ms_status s = ms_nsp_build_read_leaf(b, node, &rec, &count, io_read, err);
    if (s != MS_OK)
        return s;
    /* own keys, in place over the records (at most 3 per record) */
    size_t n = 0;
    for (size_t i = 0; i < count; ++i) {
        int verts = rec[3 * i] == rec[3 * i + 1] ? 1 : 3;
        for (int j = 0; j < verts; ++j) {
            uint64_t k = rec[3 * i + (size_t)j];
            if (ms_nsp_prefix_inside(shape, k, D, nd->depth, nd->position))
                rec[n++] = k;
        }
    }
    uint32_t *ignored = malloc((n ? n : 1) * sizeof *ignored);
    if (!ignored) {
        free(rec);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory finding lone levels");
    }
    s = ms_radix_sort_pairs(rec, ignored, n, D, err);
    free(ignored);
    size_t u = 0;
    for (size_t i = 0; s == MS_OK && i < n; ++i)
        if (u == 0 || rec[i] != rec[u - 1])
            rec[u++] = rec[i];
    uint8_t *level = malloc(u ? u : 1);
    if (s == MS_OK && !level)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory finding lone levels");
    for (size_t i = 0; s == MS_OK && i < u; ++i) {
        unsigned l = 0, m;
        if (u > 1 && i > 0 && (m = ms_key_lcp(rec[i - 1], rec[i], D) + 1) > l)
            l = m;
        if (u > 1 && i + 1 < u && (m = ms_key_lcp(rec[i], rec[i + 1], D) + 1) > l)
            l = m;
        level[i] = (uint8_t)l;
    }
    if (s == MS_OK) {
        size_t bytes = u * 9;
        pthread_mutex_lock(&w->lock);
        int64_t at = w->file_end;
        w->file_end += (int64_t)bytes;
        pthread_mutex_unlock(&w->lock);
        if (u > 0 && (pwrite(b->lone_fd, rec, u * 8, at) != (ssize_t)(u * 8) ||
                      pwrite(b->lone_fd, level, u, at + (int64_t)(u * 8)) != (ssize_t)u))
            s = ms_error_set(err, MS_ERR_IO, "cannot write the lone-level file: %s",
                             strerror(errno));
        nd->lone_at = at;
        nd->lone_count = (uint32_t)u;
        *io_written += bytes;
        pthread_mutex_lock(&w->lock);
        for (size_t i = 0; i < u; ++i)
            w->lone_at_level[level[i] <= D ? level[i] : D]++;
        pthread_mutex_unlock(&w->lock);
    }
    free(level);
    free(rec);
    return s;
}

static void segment_block(void *context, size_t block)
{
    segment_work *w = context;
    pthread_mutex_lock(&w->lock);
    bool failed = w->failed;
    pthread_mutex_unlock(&w->lock);
    if (failed)
        return;
    ms_error err;
    ms_error_clear(&err);
    uint64_t read = 0, written = 0;
    ms_status s = leaf_segment(w, w->leaves[block], &read, &written, &err);
    pthread_mutex_lock(&w->lock);
    w->io.read_back += read;
    w->io.spilled += written;
    if (s != MS_OK && !w->failed) {
        w->failed = true;
        w->err = err;
    }
    pthread_mutex_unlock(&w->lock);
}

ms_status ms_nsp_lone_segments(ms_nsp_build *b, unsigned threads, ms_nsp_io *io, ms_error *err)
{
    memset(io, 0, sizeof *io);
    size_t leaves = 0;
    for (uint32_t i = 0; i < b->node_count; ++i)
        leaves += b->nodes[i].first_child == MS_NSP_NONE;
    uint32_t *list = malloc((leaves ? leaves : 1) * sizeof *list);
    if (!list)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory listing leaves");
    leaves = 0;
    for (uint32_t i = 0; i < b->node_count; ++i)
        if (b->nodes[i].first_child == MS_NSP_NONE)
            list[leaves++] = i;
    if (b->lone_fd < 0 && (b->lone_fd = ms_nsp_temp_file(b->params.tmp_dir, err)) < 0) {
        free(list);
        return err->code;
    }
    segment_work w = {.b = b, .leaves = list};
    pthread_mutex_init(&w.lock, NULL);
    ms_status s = ms_parallel_for(threads ? threads : 1, leaves, segment_block, &w, err);
    pthread_mutex_destroy(&w.lock);
    free(list);
    *io = w.io;
    memcpy(b->stats.lone_at_level, w.lone_at_level, sizeof w.lone_at_level);
    if (s == MS_OK && w.failed) {
        *err = w.err;
        s = err->code != MS_OK ? err->code : MS_ERR_IO;
    }
    return s;
}

ms_status ms_nsp_lone_lookup(const ms_nsp_build *b, const uint64_t *keys, size_t n,
                             uint8_t *levels, uint64_t *bytes_read, ms_error *err)
{
    uint64_t *seg = NULL;
    size_t cap = 0;
    for (size_t i = 0; i < n;) {
        uint32_t leaf = ms_nsp_build_leaf_of(b, keys[i]);
        const ms_nsp_node *nd = &b->nodes[leaf];
        size_t m = nd->lone_count;
        if (nd->lone_at < 0 || m == 0) {
            free(seg);
            return ms_error_set(err, MS_ERR_CORRUPT, "a foreign vertex's leaf has no lone levels");
        }
        if (m > cap) {
            free(seg);
            cap = m;
            seg = malloc(cap * 9);
            if (!seg)
                return ms_error_set(err, MS_ERR_NOMEM, "out of memory reading lone levels");
        }
        if (pread(b->lone_fd, seg, m * 9, nd->lone_at) != (ssize_t)(m * 9)) {
            free(seg);
            return ms_error_set(err, MS_ERR_IO, "cannot read the lone-level file: %s",
                                strerror(errno));
        }
        if (bytes_read)
            *bytes_read += m * 9;
        const uint8_t *seg_level = (const uint8_t *)(seg + m);
        /* merge the run of keys inside this leaf with its sorted segment */
        size_t at = 0;
        for (; i < n && ms_nsp_build_leaf_of(b, keys[i]) == leaf; ++i) {
            while (at < m && seg[at] < keys[i])
                ++at;
            if (at == m || seg[at] != keys[i]) {
                free(seg);
                return ms_error_set(err, MS_ERR_CORRUPT,
                                    "a foreign vertex is missing from its leaf");
            }
            levels[i] = seg_level[at];
        }
    }
    free(seg);
    return MS_OK;
}
