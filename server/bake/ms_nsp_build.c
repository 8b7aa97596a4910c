/* Out-of-core nSP-tree construction: see ms_nsp_build.h. */
#define _GNU_SOURCE /* O_TMPFILE (Linux): temporary files that never have a name */
#include "ms_nsp_build.h"

#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <inttypes.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_archive.h"
#include "ms_nsp_build_internal.h"
#include "ms_progress.h"

#define BLOCK_BYTES 4096
#define BLOCK_HEAD 16 /* int64 next, u32 count, u32 reserved */
#define RECORD MS_NSP_RECORD_BYTES
#define BLOCK_RECORDS ((BLOCK_BYTES - BLOCK_HEAD) / RECORD)

/* ---- temporary files ---------------------------------------------------- */

int ms_nsp_temp_file(const char *dir, ms_error *err)
{
#ifdef O_TMPFILE
    /* a file that never had a name: a bake killed at any instant leaves
     * nothing behind (mkstemp then unlink leaves one if killed in between) */
    int tmp = open(dir, O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
    if (tmp >= 0)
        return tmp;
    if (errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL) {
        ms_error_set(err, MS_ERR_IO, "%s: cannot create a temporary file: %s", dir,
                     strerror(errno));
        return -1;
    }
#endif
    char path[4096];
    int n = snprintf(path, sizeof path, "%s/.meshbake-tmp-XXXXXX", dir);
    if (n < 0 || (size_t)n >= sizeof path) {
        ms_error_set(err, MS_ERR_ARG, "temporary directory path too long");
        return -1;
    }
    int fd = mkstemp(path);
    if (fd < 0) {
        ms_error_set(err, MS_ERR_IO, "%s: cannot create a temporary file: %s", dir,
                     strerror(errno));
        return -1;
    }
    unlink(path);
    return fd;
}

static FILE *unlinked_temp_file(const char *dir, ms_error *err)
{
    int fd = ms_nsp_temp_file(dir, err);
    if (fd < 0)
        return NULL;
    FILE *f = fdopen(fd, "w+b");
    if (!f) {
        close(fd);
        ms_error_set(err, MS_ERR_NOMEM, "out of memory opening a temporary file");
    }
    return f;
}

/* ---- pass 1: spool the input ------------------------------------------- */

typedef struct spool_sink {
    FILE *vertices, *triangles;
    uint64_t vertex_count, triangle_count;
    uint64_t spilled; /* bytes written to the spools */
    double lo[3], hi[3];
    const ms_nsp_build_params *params;
} spool_sink;

static ms_status spool_vertices(void *context, const double *p, size_t count, ms_error *err)
{
    spool_sink *s = context;
    for (size_t i = 0; i < count; ++i)
        for (int a = 0; a < 3; ++a) {
            double v = p[3 * i + a];
            if (!isfinite(v))
                return ms_error_set(err, MS_ERR_RANGE, "vertex %" PRIu64 " has a non-finite "
                                    "coordinate", s->vertex_count + i);
            if (s->vertex_count + i == 0) {
                s->lo[a] = s->hi[a] = v;
            } else {
                if (v < s->lo[a])
                    s->lo[a] = v;
                if (v > s->hi[a])
                    s->hi[a] = v;
            }
        }
    if (fwrite(p, 3 * sizeof *p, count, s->vertices) != count)
        return ms_error_set(err, MS_ERR_IO, "cannot write the vertex spool: %s", strerror(errno));
    s->vertex_count += count;
    s->spilled += count * 3 * sizeof *p;
    return MS_OK;
}

static ms_status spool_triangles(void *context, const uint32_t *t, size_t count, ms_error *err)
{
    spool_sink *s = context;
    if (fwrite(t, 3 * sizeof *t, count, s->triangles) != count)
        return ms_error_set(err, MS_ERR_IO, "cannot write the triangle spool: %s",
                            strerror(errno));
    s->triangle_count += count;
    s->spilled += count * 3 * sizeof *t;
    return MS_OK;
}

static void spool_progress(void *context, uint64_t done, uint64_t total)
{
    spool_sink *s = context;
    if (s->params->progress && total > 0)
        s->params->progress(s->params->progress_context, "reading", (double)done / (double)total);
}

/* ---- the tree ------------------------------------------------------------ */

uint32_t ms_nsp_default_min_triangles(uint64_t input_triangles, uint64_t scale_from)
{
    if (scale_from == 0)
        scale_from = MS_NSP_DEFAULT_SCALE_FROM;
    if (input_triangles <= scale_from)
        return MS_NSP_DEFAULT_MIN_TRIANGLES;
    /* sqrt is correctly rounded (IEEE 754), so the value is the same everywhere */
    double hundreds = floor(MS_NSP_DEFAULT_MIN_TRIANGLES / 100.0 *
                            sqrt(sqrt((double)input_triangles / (double)scale_from)));
    double n = 100.0 * hundreds;
    return n >= MS_NSP_DEFAULT_MIN_TRIANGLES_MAX ? MS_NSP_DEFAULT_MIN_TRIANGLES_MAX : (uint32_t)n;
}

static unsigned child_count(const ms_nsp_build *b)
{
    unsigned n = b->params.shape.n;
    return n * n * n;
}

/* The bits of a key above a depth-`depth` cell's cube: its cell's Morton number
 * at that depth (what ms_nsp_prefix_inside compares, without unkeying). */
static uint64_t key_cell(const ms_nsp_build *b, uint64_t key, unsigned depth)
{
    return key >> (3 * (b->params.shape.bits - depth * b->params.shape.log2n));
}

/* A node's Morton number among the cells of its depth. */
static uint64_t node_cell(const ms_nsp_node *node)
{
    return ms_quant_key(node->position[0], node->position[1], node->position[2], 0);
}

/* child_of_group[g]: the child offset (ms_nsp_child_offset) of the cell whose
 * 3 log2(n) key bits below its parent's are g. */
static void fill_child_of_group(ms_nsp_build *b)
{
    const ms_nsp_shape *shape = &b->params.shape;
    for (uint32_t g = 0; g < child_count(b); ++g) {
        uint32_t xyz[3];
        ms_quant_unkey(g, shape->log2n, xyz);
        for (int a = 0; a < 3; ++a)
            xyz[a] <<= shape->bits - shape->log2n; /* a depth-1 cell's corner */
        b->child_of_group[g] = (uint16_t)ms_nsp_child_offset(shape, 0, xyz);
    }
}

/* The leaf below `node` holding the key: one group of key bits per level (the
 * descent runs three times per inserted record). */
static uint32_t leaf_below(const ms_nsp_build *b, uint32_t node, uint64_t key)
{
    uint64_t mask = child_count(b) - 1;
    while (b->nodes[node].first_child != MS_NSP_NONE)
        node = b->nodes[node].first_child +
               b->child_of_group[key_cell(b, key, b->nodes[node].depth + 1u) & mask];
    return node;
}

static ms_status write_block(ms_nsp_build *b, ms_nsp_node *node, const uint64_t *records,
                             uint32_t count, ms_error *err)
{
    int64_t at;
    if (b->free_count > 0) {
        at = b->free_blocks[--b->free_count];
    } else {
        at = b->block_file_end;
        b->block_file_end += BLOCK_BYTES;
    }
    uint8_t *p = b->block_scratch;
    memset(p, 0, BLOCK_HEAD);
    memcpy(p, &node->head_block, 8);
    memcpy(p + 8, &count, 4);
    memcpy(p + BLOCK_HEAD, records, (size_t)count * RECORD);
    size_t bytes = BLOCK_HEAD + (size_t)count * RECORD;
    if (pwrite(b->block_fd, p, bytes, at) != (ssize_t)bytes)
        return ms_error_set(err, MS_ERR_IO, "cannot write the block file: %s", strerror(errno));
    b->stats.io_distribute.spilled += bytes;
    node->head_block = at;
    node->blocks++;
    b->stats.blocks_written++;
    return MS_OK;
}

static ms_status flush_node(ms_nsp_build *b, ms_nsp_node *node, ms_error *err)
{
    for (uint32_t i = 0; i < node->buffered; i += BLOCK_RECORDS) {
        uint32_t count = node->buffered - i < BLOCK_RECORDS ? node->buffered - i : BLOCK_RECORDS;
        ms_status s = write_block(b, node, node->buf + 3 * (size_t)i, count, err);
        if (s != MS_OK)
            return s;
    }
    b->buffered_bytes -= (size_t)node->buffered * RECORD;
    free(node->buf);
    node->buf = NULL;
    node->buffered = node->buffer_cap = 0;
    return MS_OK;
}

typedef struct fill {
    uint32_t buffered, node;
} fill;

static int cmp_fill_desc(const void *x, const void *y)
{
    const fill *a = x, *b = y;
    if (a->buffered != b->buffered)
        return a->buffered > b->buffered ? -1 : 1;
    return a->node < b->node ? -1 : (a->node > b->node);
}

/* Largest buffers first until the total is at most half the budget. */
static ms_status flush_largest(ms_nsp_build *b, ms_error *err)
{
    size_t n = 0;
    for (uint32_t i = 0; i < b->node_count; ++i)
        n += b->nodes[i].buffered > 0;
    fill *f = malloc((n ? n : 1) * sizeof *f);
    if (!f)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory flushing leaf buffers");
    n = 0;
    for (uint32_t i = 0; i < b->node_count; ++i)
        if (b->nodes[i].buffered > 0)
            f[n++] = (fill){b->nodes[i].buffered, i};
    qsort(f, n, sizeof *f, cmp_fill_desc);
    ms_status s = MS_OK;
    for (size_t i = 0; i < n && s == MS_OK && b->buffered_bytes > b->params.buffer_budget / 2; ++i)
        s = flush_node(b, &b->nodes[f[i].node], err);
    free(f);
    b->stats.flushes++;
    return s;
}

static ms_status read_records(const ms_nsp_build *b, const ms_nsp_node *node, uint64_t **out,
                              size_t *count, uint64_t *bytes_read, ms_error *err)
{
    *out = NULL;
    *count = 0;
    size_t cap = (size_t)node->blocks * BLOCK_RECORDS + node->buffered;
    uint64_t *rec = malloc((cap ? cap : 1) * RECORD);
    uint8_t *blocks = malloc(((size_t)node->blocks ? node->blocks : 1) * BLOCK_BYTES);
    if (!rec || !blocks) {
        free(rec);
        free(blocks);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory reading a leaf");
    }
    int64_t at = node->head_block;
    for (uint32_t k = 0; k < node->blocks; ++k) {
        uint8_t *p = blocks + (size_t)k * BLOCK_BYTES;
        if (at < 0 || pread(b->block_fd, p, BLOCK_BYTES, at) < BLOCK_HEAD) {
            free(rec);
            free(blocks);
            return ms_error_set(err, MS_ERR_IO, "cannot read the block file: %s",
                                strerror(errno));
        }
        memcpy(&at, p, 8);
    }
    if (bytes_read)
        *bytes_read += (uint64_t)node->blocks * BLOCK_BYTES;
    size_t n = 0;
    for (uint32_t k = node->blocks; k-- > 0;) {
        const uint8_t *p = blocks + (size_t)k * BLOCK_BYTES;
        uint32_t c;
        memcpy(&c, p + 8, 4);
        if (c > BLOCK_RECORDS) {
            free(rec);
            free(blocks);
            return ms_error_set(err, MS_ERR_CORRUPT, "block file damaged");
        }
        memcpy(rec + 3 * n, p + BLOCK_HEAD, (size_t)c * RECORD);
        n += c;
    }
    if (node->buffered)
        memcpy(rec + 3 * n, node->buf, (size_t)node->buffered * RECORD);
    n += node->buffered;
    free(blocks);
    *out = rec;
    *count = n;
    return MS_OK;
}

static ms_status append(ms_nsp_build *b, uint32_t index, const uint64_t rec[3], ms_error *err);

#define NO_SLOT UINT32_MAX

/* A key's share of its triangle's hash: summed over the three, so that the
 * hash does not depend on their order. */
static uint64_t key_hash(uint64_t key)
{
    uint64_t z = key * 0x9E3779B97F4A7C15ull;
    return (z ^ (z >> 31)) * 0xC2B2AE3D27D4EB4Full;
}

/* Whether two triangle records (three distinct keys each) have the same vertices. */
static bool same_vertices(const uint64_t *r, const uint64_t *k)
{
    for (int i = 0; i < 3; ++i)
        if (r[i] != k[0] && r[i] != k[1] && r[i] != k[2])
            return false;
    return true;
}

/* Removes from rec[0..*count) every triangle record whose welded vertex set
 * an earlier record already has (the first stays, in order, as the encoder's
 * ms_tri_unify would keep it); point records stay. *distinct: the triangle
 * records left. The sets seen are found by hashing, in one pass over the
 * records (a full leaf's check runs on the distribution's critical path). */
static ms_status drop_repeated_triangles(uint64_t *rec, size_t *count, size_t *distinct,
                                         ms_error *err)
{
    size_t n = *count;
    if (n >= UINT32_MAX / 2)
        return ms_error_set(err, MS_ERR_RANGE, "a leaf of %zu records is too large to split", n);
    unsigned log2_slots = 4;
    while (((size_t)1 << log2_slots) < 2 * n)
        ++log2_slots;
    size_t slots = (size_t)1 << log2_slots;
    uint32_t *slot = malloc(slots * sizeof *slot); /* a kept record's place in the output */
    if (!slot)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory finding repeated triangles");
    memset(slot, 0xFF, slots * sizeof *slot); /* NO_SLOT everywhere */
    size_t out = 0, kept = 0;
    for (size_t i = 0; i < n; ++i) {
        const uint64_t *r = rec + 3 * i;
        if (r[0] != r[1]) { /* not a point record */
            uint64_t mixed = key_hash(r[0]) + key_hash(r[1]) + key_hash(r[2]);
            size_t h = (size_t)(mixed >> (64 - log2_slots));
            while (slot[h] != NO_SLOT && !same_vertices(r, rec + 3 * (size_t)slot[h]))
                h = (h + 1) & (slots - 1);
            if (slot[h] != NO_SLOT)
                continue; /* a repeat: dropped */
            slot[h] = (uint32_t)out; /* output places below i are never written again */
            ++kept;
        }
        if (out != i)
            memcpy(rec + 3 * out, r, RECORD);
        ++out;
    }
    free(slot);
    *count = out;
    *distinct = kept;
    return MS_OK;
}

static ms_status split_node(ms_nsp_build *b, uint32_t index, ms_error *err)
{
    unsigned nc = child_count(b);
    if (b->node_count + (uint64_t)nc > MS_ARCHIVE_MAX_CELLS)
        return ms_error_set(err, MS_ERR_RANGE, "too many nSP cells (raise --min-tris)");
    if (b->node_count + nc > b->node_cap) {
        uint32_t cap = b->node_cap * 2;
        while (cap < b->node_count + nc)
            cap *= 2;
        ms_nsp_node *n = realloc(b->nodes, (size_t)cap * sizeof *n);
        if (!n)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory growing the tree");
        b->nodes = n;
        b->node_cap = cap;
    }
    uint64_t *rec;
    size_t count;
    ms_status s = read_records(b, &b->nodes[index], &rec, &count, &b->stats.io_distribute.read_back,
                               err);
    if (s != MS_OK)
        return s;
    ms_nsp_node *node = &b->nodes[index];
    /* Its blocks go back to the free list (reading is done). */
    int64_t at = node->head_block;
    if (b->free_count + node->blocks > b->free_cap) {
        size_t cap = b->free_cap ? b->free_cap : 256;
        while (cap < b->free_count + node->blocks)
            cap *= 2;
        int64_t *f = realloc(b->free_blocks, cap * sizeof *f);
        if (!f) {
            free(rec);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
        }
        b->free_blocks = f;
        b->free_cap = cap;
    }
    for (uint32_t k = 0; k < node->blocks; ++k) {
        b->free_blocks[b->free_count++] = at;
        int64_t next;
        if (pread(b->block_fd, &next, 8, at) != 8) { /* cached: just read above */
            free(rec);
            return ms_error_set(err, MS_ERR_IO, "cannot read the block file: %s", strerror(errno));
        }
        at = next;
    }
    b->buffered_bytes -= (size_t)node->buffered * RECORD;
    free(node->buf);
    node->buf = NULL;
    node->buffered = node->buffer_cap = node->blocks = 0;
    node->head_block = -1;
    /* Split on distinct triangles: repeated ones (the same welded vertices)
     * go now, and a node they alone filled takes the rest back and stays a
     * leaf. Each such check costs O(m) (hashing) for the m records of a node
     * that just reached the threshold, so copies cost O(n log n) in all. */
    size_t distinct = 0;
    s = drop_repeated_triangles(rec, &count, &distinct, err);
    if (s != MS_OK) {
        free(rec);
        return s;
    }
    if (distinct < b->params.min_triangles) {
        b->stats.leaf_triangle_records -= node->triangles;
        b->stats.point_records -= node->records - node->triangles;
        node->triangles = node->records = 0;
        for (size_t i = 0; i < count && s == MS_OK; ++i)
            s = append(b, index, rec + 3 * i, err);
        free(rec);
        return s;
    }
    node->first_child = b->node_count;
    unsigned n = b->params.shape.n;
    for (unsigned k = 0; k < nc; ++k) {
        ms_nsp_node *c = &b->nodes[b->node_count + k];
        memset(c, 0, sizeof *c);
        c->parent = index;
        c->first_child = MS_NSP_NONE;
        c->depth = (uint8_t)(node->depth + 1);
        uint32_t off[3] = {k % n, (k / n) % n, k / (n * n)};
        for (int a = 0; a < 3; ++a)
            c->position[a] = node->position[a] * n + off[a];
        c->head_block = -1;
        c->lone_at = -1;
    }
    b->node_count += nc;
    b->stats.leaf_triangle_records -= node->triangles;
    b->stats.point_records -= node->records - node->triangles;
    node->triangles = node->records = 0;
    for (size_t i = 0; i < count && s == MS_OK; ++i)
        s = ms_nsp_build_insert(b, index, rec + 3 * i, NULL, err);
    free(rec);
    return s;
}

static ms_status append(ms_nsp_build *b, uint32_t index, const uint64_t rec[3], ms_error *err)
{
    ms_nsp_node *node = &b->nodes[index];
    if (node->buffered == node->buffer_cap) {
        uint32_t cap = node->buffer_cap ? node->buffer_cap * 2 : 64;
        uint64_t *p = realloc(node->buf, (size_t)cap * RECORD);
        if (!p)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory buffering a leaf");
        node->buf = p;
        node->buffer_cap = cap;
    }
    memcpy(node->buf + 3 * (size_t)node->buffered, rec, RECORD);
    node->buffered++;
    node->records++;
    b->buffered_bytes += RECORD;
    bool point = rec[0] == rec[1];
    if (point) {
        b->stats.point_records++;
        return MS_OK;
    }
    node->triangles++;
    b->stats.leaf_triangle_records++;
    if (node->triangles >= b->params.min_triangles &&
        ms_nsp_can_split(&b->params.shape, node->depth))
        return split_node(b, index, err);
    return MS_OK;
}

/* Appends rec to every leaf below `top` holding one of its vertices; *reached (if
 * not NULL) receives the number of those leaves. */
ms_status ms_nsp_build_insert(ms_nsp_build *b, uint32_t top, const uint64_t rec[3],
                              unsigned *reached, ms_error *err)
{
    uint32_t leaves[3];
    unsigned nl = 0;
    int verts = rec[0] == rec[1] ? 1 : 3;
    unsigned top_depth = b->nodes[top].depth;
    uint64_t top_cell = node_cell(&b->nodes[top]);
    for (int i = 0; i < verts; ++i) {
        uint64_t key = rec[i];
        if (key_cell(b, key, top_depth) != top_cell)
            continue; /* outside top's cube */
        uint32_t leaf = leaf_below(b, top, key);
        if ((nl > 0 && leaves[0] == leaf) || (nl > 1 && leaves[1] == leaf))
            continue;
        leaves[nl++] = leaf;
    }
    if (reached)
        *reached = nl;
    for (unsigned i = 0; i < nl; ++i) {
        /* an earlier append may have split a leaf found above: look it up again */
        uint32_t leaf = leaves[i];
        if (b->nodes[leaf].first_child != MS_NSP_NONE)
            continue; /* the split already redistributed this record there */
        ms_status s = append(b, leaf, rec, err);
        if (s != MS_OK)
            return s;
    }
    if (b->buffered_bytes > b->params.buffer_budget)
        return flush_largest(b, err);
    return MS_OK;
}

/* ---- the run (the quantisation and the distribution: ms_nsp_distribute.c) -- */

ms_status ms_nsp_build_run(const char *path, const ms_nsp_build_params *params,
                           ms_nsp_build *b, ms_error *err)
{
    memset(b, 0, sizeof *b);
    b->params = *params;
    b->block_fd = -1;
    b->lone_fd = -1;
    int key_fd = -1;
    spool_sink sink = {.params = params};
    ms_status s = MS_OK;
    double t0 = ms_now_seconds();
    sink.vertices = unlinked_temp_file(params->tmp_dir, err);
    sink.triangles = sink.vertices ? unlinked_temp_file(params->tmp_dir, err) : NULL;
    if (!sink.vertices || !sink.triangles) {
        s = err->code;
        goto done;
    }
    ms_mesh_sink ms = {.context = &sink, .vertices = spool_vertices,
                       .triangles = spool_triangles, .progress = spool_progress};
    if ((s = ms_mesh_read(path, &ms, &b->stats.read, err)) != MS_OK)
        goto done;
    if (fflush(sink.vertices) != 0 || fflush(sink.triangles) != 0) {
        s = ms_error_set(err, MS_ERR_IO, "cannot write the input spool: %s", strerror(errno));
        goto done;
    }
    if (sink.vertex_count > UINT32_MAX) {
        s = ms_error_set(err, MS_ERR_RANGE, "too many vertices (%" PRIu64 ")", sink.vertex_count);
        goto done;
    }
    b->stats.input_vertices = sink.vertex_count;
    b->stats.io_read.spilled = sink.spilled;
    b->stats.input_triangles = sink.triangle_count;
    if (params->min_triangles == 0)
        b->params.min_triangles =
            ms_nsp_default_min_triangles(sink.triangle_count, params->default_scale_from);
    double t1 = ms_now_seconds();
    b->stats.seconds_read = t1 - t0;

    /* The cubic box, exactly as ms_quant_fit_box computes it from the extremes. */
    double corners[6] = {sink.lo[0], sink.lo[1], sink.lo[2], sink.hi[0], sink.hi[1], sink.hi[2]};
    ms_mesh extremes = {.positions = corners, .vertex_count = 2};
    if ((s = ms_quant_fit_box(&extremes, &b->box, err)) != MS_OK)
        goto done;
    /* A denormal extent loses precision in every step after it, and the
     * normals of its triangles underflow (no APO): refuse it. */
    if (b->box.size < DBL_MIN) {
        s = ms_error_set(err, MS_ERR_RANGE,
                         "the model's extent %g is below the smallest normal double (%g): scale "
                         "it up", b->box.size, DBL_MIN);
        goto done;
    }
    b->vertex_count = (size_t)sink.vertex_count;
    if ((key_fd = ms_nsp_temp_file(params->tmp_dir, err)) < 0) {
        s = err->code;
        goto done;
    }
    if ((s = ms_nsp_build_compute_keys(b, sink.vertices, key_fd, err)) != MS_OK)
        goto done;
    fclose(sink.vertices);
    sink.vertices = NULL;
    double t2 = ms_now_seconds();
    b->stats.seconds_quantise = t2 - t1;

    fill_child_of_group(b);
    b->node_cap = 1024;
    b->nodes = malloc(b->node_cap * sizeof *b->nodes);
    b->block_scratch = malloc(BLOCK_BYTES);
    if (!b->nodes || !b->block_scratch) {
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory for the tree");
        goto done;
    }
    memset(&b->nodes[0], 0, sizeof b->nodes[0]);
    b->nodes[0].parent = b->nodes[0].first_child = MS_NSP_NONE;
    b->nodes[0].head_block = -1;
    b->nodes[0].lone_at = -1;
    b->node_count = 1;
    if ((b->block_fd = ms_nsp_temp_file(params->tmp_dir, err)) < 0) {
        s = err->code;
        goto done;
    }
    if ((s = ms_nsp_build_distribute(b, sink.triangles, sink.triangle_count, key_fd, err)) != MS_OK)
        goto done;
    /* Every leaf to disk: the encoding phase then needs no buffer memory. */
    for (uint32_t i = 0; i < b->node_count && s == MS_OK; ++i)
        if (b->nodes[i].buffered > 0)
            s = flush_node(b, &b->nodes[i], err);
    if (s != MS_OK)
        goto done;
#ifdef __GLIBC__
    malloc_trim(0);
#endif
    b->stats.seconds_distribute = ms_now_seconds() - t2;
done:
    if (key_fd >= 0)
        close(key_fd);
    if (sink.vertices)
        fclose(sink.vertices);
    if (sink.triangles)
        fclose(sink.triangles);
    if (s != MS_OK)
        ms_nsp_build_free(b);
    return s;
}

ms_status ms_nsp_build_read_leaf(const ms_nsp_build *b, uint32_t node, uint64_t **records,
                                 size_t *count, uint64_t *bytes_read, ms_error *err)
{
    return read_records(b, &b->nodes[node], records, count, bytes_read, err);
}

uint32_t ms_nsp_build_leaf_of(const ms_nsp_build *b, uint64_t key)
{
    return leaf_below(b, 0, key);
}

ms_status ms_nsp_build_bfs(const ms_nsp_build *b, uint32_t **order_out, uint32_t **first_out,
                           ms_error *err)
{
    uint32_t n = b->node_count, nc = child_count(b);
    uint32_t *order = malloc(n * sizeof *order), *first = malloc(n * sizeof *first);
    if (!order || !first) {
        free(order);
        free(first);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory numbering cells");
    }
    uint32_t tail = 1;
    order[0] = 0;
    for (uint32_t i = 0; i < n; ++i) {
        const ms_nsp_node *node = &b->nodes[order[i]];
        if (node->first_child == MS_NSP_NONE) {
            first[i] = MS_NSP_NONE;
            continue;
        }
        first[i] = tail;
        for (uint32_t k = 0; k < nc; ++k)
            order[tail++] = node->first_child + k;
    }
    *order_out = order;
    *first_out = first;
    return MS_OK;
}

void ms_nsp_build_free(ms_nsp_build *b)
{
    if (b->nodes)
        for (uint32_t i = 0; i < b->node_count; ++i)
            free(b->nodes[i].buf);
    free(b->nodes);
    free(b->free_blocks);
    free(b->block_scratch);
    if (b->block_fd >= 0)
        close(b->block_fd);
    if (b->lone_fd >= 0)
        close(b->lone_fd);
    memset(b, 0, sizeof *b);
    b->block_fd = -1;
    b->lone_fd = -1;
}
