/* The out-of-core nSP build's first two passes over the spools: the
 * quantisation (every vertex's key into the key file, on the pool) and the
 * distribution (every kept triangle's records into the tree, a two-stage
 * pipeline); see ms_nsp_build_internal.h and ms_nsp_build.h. */
#include "ms_nsp_build_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_nsp_key_cache.h"
#include "ms_parallel.h"
#include "ms_quant.h"

#define SPOOL_CHUNK 65536    /* keys read at a time when the isolated vertices are found */
#define QUANTISE_CHUNK 32768 /* vertices a quantisation block reads (two at a time: 2 MB) */
#define PIPELINE_CHUNK 16384 /* triangles a step of the distribution keys and inserts
                              * (the spool chunk and two chunks of records: 960 KB) */

static void report(const ms_nsp_build_params *p, const char *phase, double fraction)
{
    if (p->progress)
        p->progress(p->progress_context, phase, fraction);
}

/* The quantisation runs in rounds of QUANTISE_ROUND chunks of the vertex spool,
 * one block each on the pool: a chunk's keys depend on its vertices alone and go
 * to their own place in the key file, so the file is the same for any thread
 * count. Each block has its own buffers and counters. */
#define QUANTISE_ROUND 2

typedef struct quantise_block {
    double *positions; /* QUANTISE_CHUNK * 3 */
    uint64_t *keys;    /* QUANTISE_CHUNK */
    ms_nsp_io io;
    ms_status status;
    ms_error err;
} quantise_block;

typedef struct quantisation {
    const ms_nsp_build *b;
    int vspool_fd, key_fd;
    uint64_t first_chunk; /* of the round */
    quantise_block block[QUANTISE_ROUND];
} quantisation;

static void quantise_chunk(void *context, size_t block)
{
    quantisation *q = context;
    quantise_block *qb = &q->block[block];
    const ms_nsp_build *b = q->b;
    const unsigned bits = b->params.shape.bits;
    uint64_t first = (q->first_chunk + block) * QUANTISE_CHUNK;
    if (first >= b->vertex_count)
        return;
    size_t want = b->vertex_count - first < QUANTISE_CHUNK ? (size_t)(b->vertex_count - first)
                                                           : QUANTISE_CHUNK;
    size_t bytes = want * 3 * sizeof *qb->positions;
    if (pread(q->vspool_fd, qb->positions, bytes, (off_t)(first * 3 * sizeof *qb->positions)) !=
        (ssize_t)bytes) {
        qb->status = ms_error_set(&qb->err, MS_ERR_IO, "cannot read the vertex spool");
        return;
    }
    qb->io.read_back += bytes;
    for (size_t i = 0; i < want; ++i) {
        uint32_t xyz[3];
        for (int a = 0; a < 3; ++a)
            xyz[a] = ms_quantise(&b->box, bits, a, qb->positions[3 * i + a]);
        qb->keys[i] = ms_quant_key(xyz[0], xyz[1], xyz[2], bits);
    }
    bytes = want * sizeof *qb->keys;
    if (pwrite(q->key_fd, qb->keys, bytes, (off_t)(first * sizeof *qb->keys)) != (ssize_t)bytes) {
        qb->status = ms_error_set(&qb->err, MS_ERR_IO, "cannot write the key file: %s",
                                  strerror(errno));
        return;
    }
    qb->io.spilled += bytes;
}

/* Writes every input vertex's key, in input order, to the key file (the spool
 * flushed). */
ms_status ms_nsp_build_compute_keys(ms_nsp_build *b, FILE *vspool, int key_fd, ms_error *err)
{
    quantisation q = {.b = b, .vspool_fd = fileno(vspool), .key_fd = key_fd};
    ms_status s = MS_OK;
    for (int k = 0; k < QUANTISE_ROUND && s == MS_OK; ++k) {
        q.block[k].positions = malloc(QUANTISE_CHUNK * 3 * sizeof *q.block[k].positions);
        q.block[k].keys = malloc(QUANTISE_CHUNK * sizeof *q.block[k].keys);
        if (!q.block[k].positions || !q.block[k].keys)
            s = ms_error_set(err, MS_ERR_NOMEM, "out of memory quantising");
    }
    ms_pool *pool = NULL;
    if (s == MS_OK)
        s = ms_pool_new(b->params.threads > 1 ? QUANTISE_ROUND - 1 : 0, &pool, err);
    uint64_t chunks = (b->vertex_count + QUANTISE_CHUNK - 1) / QUANTISE_CHUNK;
    for (q.first_chunk = 0; s == MS_OK && q.first_chunk < chunks; q.first_chunk += QUANTISE_ROUND) {
        ms_pool_for(pool, QUANTISE_ROUND, quantise_chunk, &q);
        for (int k = 0; k < QUANTISE_ROUND && s == MS_OK; ++k)
            if (q.block[k].status != MS_OK)
                s = ms_error_set(err, q.block[k].status, "%s", q.block[k].err.text);
        uint64_t done = q.first_chunk + QUANTISE_ROUND < chunks ? q.first_chunk + QUANTISE_ROUND
                                                                : chunks;
        report(&b->params, "quantising", (double)done / (double)chunks);
    }
    ms_pool_free(pool);
    for (int k = 0; k < QUANTISE_ROUND; ++k) {
        b->stats.io_quantise.read_back += q.block[k].io.read_back;
        b->stats.io_quantise.spilled += q.block[k].io.spilled;
        free(q.block[k].positions);
        free(q.block[k].keys);
    }
    return s;
}

/* Point records for the input vertices no kept triangle used, in input order:
 * the key file read in order once the cache has written its marks back. */
static ms_status insert_unused_vertices(ms_nsp_build *b, int key_fd, ms_error *err)
{
    uint64_t *keys = malloc(SPOOL_CHUNK * sizeof *keys);
    if (!keys)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory finding isolated vertices");
    ms_status s = MS_OK;
    for (uint64_t at = 0; s == MS_OK && at < b->vertex_count; at += SPOOL_CHUNK) {
        size_t nk = b->vertex_count - at < SPOOL_CHUNK ? (size_t)(b->vertex_count - at) : SPOOL_CHUNK;
        if (pread(key_fd, keys, nk * sizeof *keys, (off_t)(at * sizeof *keys)) !=
            (ssize_t)(nk * sizeof *keys)) {
            s = ms_error_set(err, MS_ERR_IO, "cannot read the key file: %s", strerror(errno));
            break;
        }
        b->stats.io_distribute.read_back += nk * sizeof *keys;
        for (size_t i = 0; i < nk && s == MS_OK; ++i) {
            if (keys[i] & MS_NSP_KEY_USED)
                continue;
            uint64_t rec[3] = {keys[i], keys[i], keys[i]};
            s = ms_nsp_build_insert(b, 0, rec, NULL, err);
        }
    }
    free(keys);
    return s;
}

/* The distribution is a two-stage pipeline over chunks of the triangle spool.
 * The key stage reads chunk k and turns it into records through the key cache
 * (dropping degenerate triangles, marking the vertices of the others used);
 * meanwhile the insert stage puts chunk k - 1's records into the tree. Only the
 * insert stage touches the tree, and it takes the chunks in spool order, so the
 * tree (and the archive) is the same whether the two stages share a thread or
 * not; only the key stage touches the key cache and the spool, and its counters
 * are its own until the pipeline ends. A chunk whose keys fail keeps the
 * records before the failing triangle: they are inserted before the error is
 * reported, as a triangle-by-triangle loop would have. */
typedef struct keyed_chunk {
    uint64_t first;     /* spool number of its first triangle */
    size_t records;     /* records (3 keys each) of its kept triangles */
    uint64_t *keys;     /* PIPELINE_CHUNK * 3 */
    ms_status status;   /* of the key stage; MS_OK or the error at the triangle after its records */
    ms_error err;
} keyed_chunk;

typedef struct distribution {
    ms_nsp_build *b;
    FILE *tspool;
    uint64_t triangles, read; /* in the spool, and read so far by the key stage */
    uint32_t *spool_chunk;    /* PIPELINE_CHUNK * 3 vertex numbers */
    ms_nsp_key_cache *cache;
    ms_nsp_io key_io;         /* the key stage's own counters */
    uint64_t key_page_misses, degenerate;
    keyed_chunk chunk[2];     /* chunk k is chunk[k % 2] */
    uint64_t step;            /* the key stage takes chunk step, the insert stage chunk step - 1 */
    ms_status insert_status;
    ms_error insert_err;
} distribution;

/* One triangle's keys through the cache into out; *kept is false for a degenerate one. */
static ms_status key_triangle(distribution *d, const uint32_t t[3], uint64_t number,
                              uint64_t out[3], bool *kept, ms_error *err)
{
    *kept = false;
    uint64_t vertices = d->b->vertex_count;
    if (t[0] >= vertices || t[1] >= vertices || t[2] >= vertices)
        return ms_error_set(err, MS_ERR_FORMAT, "triangle %" PRIu64 " has an index out of range",
                            number);
    ms_status s = ms_nsp_key_cache_triangle(d->cache, t, out, err);
    if (s != MS_OK)
        return s;
    if (out[0] == out[1] || out[1] == out[2] || out[0] == out[2])
        d->degenerate++;
    else
        *kept = true;
    return MS_OK;
}

/* The key stage: the next chunk of the spool into chunk[step % 2]. */
static void key_stage(distribution *d)
{
    keyed_chunk *c = &d->chunk[d->step % 2];
    c->first = d->read;
    c->records = 0;
    c->status = MS_OK;
    size_t want = d->triangles - d->read < PIPELINE_CHUNK ? (size_t)(d->triangles - d->read)
                                                          : PIPELINE_CHUNK;
    if (fread(d->spool_chunk, 12, want, d->tspool) != want) {
        c->status = ms_error_set(&c->err, MS_ERR_IO, "cannot read the triangle spool");
        return;
    }
    d->key_io.read_back += (uint64_t)want * 12;
    for (size_t i = 0; i < want && c->status == MS_OK; ++i) {
        bool kept;
        c->status = key_triangle(d, d->spool_chunk + 3 * i, c->first + i, c->keys + 3 * c->records,
                                 &kept, &c->err);
        c->records += kept;
    }
    d->read += want;
}

/* The insert stage: chunk[(step - 1) % 2]'s records into the tree. */
static void insert_stage(distribution *d)
{
    ms_nsp_build *b = d->b;
    const keyed_chunk *c = &d->chunk[(d->step - 1) % 2];
    for (size_t i = 0; i < c->records && d->insert_status == MS_OK; ++i) {
        unsigned reached = 0;
        d->insert_status = ms_nsp_build_insert(b, 0, c->keys + 3 * i, &reached, &d->insert_err);
        if (reached > 1)
            b->stats.insertion_copies += reached - 1;
    }
}

/* Block 0 runs the insert stage (from the second step on) on the calling
 * thread, so that the tree's allocations stay in one malloc arena (spread over
 * two threads' arenas, the leaf buffers took 4 to 8 MB more at 10 M
 * triangles); block 1 the key stage (while chunks are left). */
static void distribution_block(void *context, size_t block)
{
    distribution *d = context;
    if (block == 0 && d->step > 0)
        insert_stage(d);
    else if (block == 1 && d->read < d->triangles)
        key_stage(d);
}

ms_status ms_nsp_build_distribute(ms_nsp_build *b, FILE *tspool, uint64_t triangles, int key_fd,
                            ms_error *err)
{
    distribution d = {.b = b, .tspool = tspool, .triangles = triangles};
    ms_pool *pool = NULL;
    d.spool_chunk = malloc(PIPELINE_CHUNK * 3 * sizeof *d.spool_chunk);
    d.chunk[0].keys = malloc(PIPELINE_CHUNK * 3 * sizeof *d.chunk[0].keys);
    d.chunk[1].keys = malloc(PIPELINE_CHUNK * 3 * sizeof *d.chunk[1].keys);
    ms_status s = ms_nsp_key_cache_new(key_fd, b->vertex_count, b->params.key_cache_bytes,
                                       &d.key_io, &d.key_page_misses, &d.cache, err);
    if (s == MS_OK && (!d.spool_chunk || !d.chunk[0].keys || !d.chunk[1].keys))
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory distributing triangles");
    if (s == MS_OK)
        s = ms_pool_new(b->params.threads > 1 ? 1 : 0, &pool, err);
    rewind(tspool);
    /* Step k keys chunk k and inserts chunk k - 1; the last step only inserts. */
    for (d.step = 0; s == MS_OK; ++d.step) {
        bool keying = d.read < triangles;
        if (!keying && d.step == 0)
            break; /* no triangle */
        ms_pool_pair(pool, distribution_block, &d);
        if (d.insert_status != MS_OK) {
            s = ms_error_set(err, d.insert_err.code, "%s", d.insert_err.text);
            break;
        }
        if (d.step > 0 && d.chunk[(d.step - 1) % 2].status != MS_OK) {
            s = ms_error_set(err, d.chunk[(d.step - 1) % 2].status, "%s",
                             d.chunk[(d.step - 1) % 2].err.text);
            break;
        }
        if (!keying)
            break; /* that was the last chunk's insertion */
        report(&b->params, "distributing", (double)d.read / (double)triangles);
    }
    ms_pool_free(pool);
    b->stats.degenerate_triangles += d.degenerate;
    /* Isolated vertices (after welding, a key used by no kept triangle is found
     * again in its leaf: the leaf drops points whose key a triangle uses). */
    if (s == MS_OK)
        s = ms_nsp_key_cache_write_back(d.cache, err);
    ms_nsp_key_cache_free(d.cache);
    b->stats.io_distribute.spilled += d.key_io.spilled;
    b->stats.io_distribute.read_back += d.key_io.read_back;
    b->stats.key_page_misses += d.key_page_misses;
    free(d.spool_chunk);
    free(d.chunk[0].keys);
    free(d.chunk[1].keys);
    if (s == MS_OK)
        s = insert_unused_vertices(b, key_fd, err);
    return s;
}
