/* Archive writer: see ms_archive_writer.h. */
#include "ms_archive_writer.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "ms_parallel.h"
#include "ms_subtree.h"

typedef struct cell_state {
    ms_archive_cell cell;
    uint64_t geometry_spool, apo_spool, colour_spool; /* offsets in the spool file */
    uint32_t *geometry_table;           /* bits_max - bits_min + 1 words */
    uint32_t *apo_table;                /* 2 * apo_levels words */
    uint32_t *colour_table;             /* bits_max - bits_min + 1 words, then the CRC */
    uint8_t error_table[MS_ARCHIVE_MAX_WINDOW]; /* bits_max - bits_min + 1 bytes, if has_error */
    bool has_geometry, has_apo, has_colour, has_error;
} cell_state;

struct ms_archive_writer {
    char *path;
    char *partial_path;
    FILE *spool;
    uint64_t spool_size;
    ms_archive_header header;
    cell_state *cells;
    unsigned subtree_levels; /* S, levels per index subtree */
    unsigned threads;        /* for the subtrees at finish, >= 1 */
};

/* Words of a cell's tables (docs/ARCHIVE.md, "Per-cell tables"). */
static uint64_t cell_table_words(const ms_archive_header *h, const ms_archive_cell *c)
{
    uint64_t window = (uint64_t)c->bits_max - c->bits_min + 1;
    return window + 2ull * c->apo_levels + (h->has_colour ? window + 1 : 0) + (window + 3) / 4;
}

static void writer_free(ms_archive_writer *w)
{
    if (!w)
        return;
    if (w->spool)
        fclose(w->spool);
    if (w->cells)
        for (uint32_t i = 0; i < w->header.cell_count; ++i)
            free(w->cells[i].geometry_table), free(w->cells[i].apo_table),
                free(w->cells[i].colour_table);
    free(w->cells);
    free(w->path);
    free(w->partial_path);
    free(w);
}

void ms_archive_writer_set_counts(ms_archive_writer *w, uint64_t vertex_count,
                                  uint64_t triangle_count)
{
    w->header.vertex_count = vertex_count;
    w->header.triangle_count = triangle_count;
}

void ms_archive_writer_abort(ms_archive_writer *w)
{
    if (w)
        remove(w->partial_path);
    writer_free(w);
}

/* Derives parent, level, position and window of every cell from first_child. */
static ms_status build_topology(ms_archive_writer *w, const uint32_t *first_child, ms_error *err)
{
    ms_archive_header *h = &w->header;
    uint32_t children = (uint32_t)h->n * h->n * h->n;
    for (uint32_t id = 0; id < h->cell_count; ++id)
        w->cells[id].cell.parent = MS_ARCHIVE_NONE;
    uint32_t expected_next = 1;
    for (uint32_t id = 0; id < h->cell_count; ++id) {
        ms_archive_cell *c = &w->cells[id].cell;
        if (id > 0 && c->parent == MS_ARCHIVE_NONE)
            return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u has no parent", id);
        c->first_child = first_child[id];
        bool leaf = c->first_child == MS_ARCHIVE_NONE;
        ms_archive_cell_window(h, c->level, leaf, &c->bits_min, &c->bits_max);
        if (leaf)
            continue;
        if (c->first_child != expected_next || c->first_child > h->cell_count ||
            h->cell_count - c->first_child < children || c->bits_max >= h->bits)
            return ms_error_set(err, MS_ERR_ARG,
                                "archive writer: cell %u: children at %u break breadth-first order",
                                id, c->first_child);
        expected_next += children;
        for (uint32_t k = 0; k < children; ++k) {
            ms_archive_cell *child = &w->cells[c->first_child + k].cell;
            uint32_t offset[3] = {k % h->n, (k / h->n) % h->n, k / (h->n * h->n)};
            child->parent = id;
            child->level = (uint8_t)(c->level + 1);
            for (int a = 0; a < 3; ++a)
                child->position[a] = c->position[a] * h->n + offset[a];
        }
    }
    if (expected_next != h->cell_count)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: topology covers %u of %u cells",
                            expected_next, h->cell_count);
    return MS_OK;
}

ms_status ms_archive_writer_open(const char *path, const ms_archive_header *header,
                                 const uint32_t *first_child, ms_archive_writer **out,
                                 ms_error *err)
{
    *out = NULL;
    if (header->cell_count < 1 || header->cell_count > MS_ARCHIVE_MAX_CELLS ||
        (header->n != 2 && header->n != 4 && header->n != 8) || header->bits < 8 ||
        header->bits > 20 || header->root_bits < 1 || header->root_bits > header->bits)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: header parameters out of range");
    ms_archive_writer *w = calloc(1, sizeof *w);
    if (!w)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    w->header = *header;
    w->threads = 1;
    w->subtree_levels = ms_subtree_default_levels(header->n);
    size_t len = strlen(path);
    w->path = strdup(path);
    w->partial_path = malloc(len + 16);
    w->cells = calloc(header->cell_count, sizeof *w->cells);
    if (!w->path || !w->partial_path || !w->cells) {
        writer_free(w);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    }
    snprintf(w->partial_path, len + 16, "%s.partial", path);
    ms_status st = build_topology(w, first_child, err);
    if (st != MS_OK) {
        writer_free(w);
        return st;
    }
    /* The spool lives next to the output and is unlinked at once: the kernel
     * reclaims it however the process ends. */
    char spool_path[4096];
    snprintf(spool_path, sizeof spool_path, "%s.spool.XXXXXX", path);
    int fd = mkstemp(spool_path);
    if (fd < 0) {
        st = ms_error_set(err, MS_ERR_IO, "%s: cannot create spool file: %s", path, strerror(errno));
        writer_free(w);
        return st;
    }
    unlink(spool_path);
    w->spool = fdopen(fd, "w+b");
    if (!w->spool) {
        close(fd);
        writer_free(w);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open spool file", path);
    }
    *out = w;
    return MS_OK;
}

void ms_archive_writer_window(const ms_archive_writer *w, uint32_t cell, uint8_t *bits_min,
                              uint8_t *bits_max)
{
    *bits_min = w->cells[cell].cell.bits_min;
    *bits_max = w->cells[cell].cell.bits_max;
}

static ms_status spool_append(ms_archive_writer *w, const uint8_t *data, uint32_t length,
                              uint64_t *offset, ms_error *err)
{
    *offset = w->spool_size;
    if (length && (fseeko(w->spool, (off_t)w->spool_size, SEEK_SET) != 0 ||
                   fwrite(data, 1, length, w->spool) != length))
        return ms_error_set(err, MS_ERR_IO, "%s: spool write failed: %s", w->path, strerror(errno));
    w->spool_size += length;
    return MS_OK;
}

/* A heap copy of `words` table words. */
static uint32_t *copy_table(const uint32_t *table, size_t words)
{
    uint32_t *copy = malloc(words * sizeof *copy);
    if (copy)
        memcpy(copy, table, words * sizeof *copy);
    return copy;
}

ms_status ms_archive_writer_put_geometry(ms_archive_writer *w, uint32_t cell,
                                         const uint8_t *data, uint32_t length,
                                         const uint32_t *prefix_table, uint32_t vertex_count,
                                         uint32_t triangle_count, ms_error *err)
{
    if (cell >= w->header.cell_count || w->cells[cell].has_geometry)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: geometry for cell %u given twice or out of range", cell);
    cell_state *s = &w->cells[cell];
    size_t words = (size_t)s->cell.bits_max - s->cell.bits_min + 1;
    uint32_t previous = 0;
    for (size_t k = 0; k < words; ++k) {
        if (prefix_table[k] < previous || prefix_table[k] > length)
            return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: bad geometry prefix table", cell);
        previous = prefix_table[k];
    }
    if (previous != length)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: prefix table must end at %u", cell, length);
    s->geometry_table = copy_table(prefix_table, words);
    if (!s->geometry_table)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", w->path);
    ms_status st = spool_append(w, data, length, &s->geometry_spool, err);
    if (st != MS_OK)
        return st;
    s->cell.geometry_length = length;
    s->cell.geometry_crc = (uint32_t)crc32_z(0L, data, length);
    s->cell.vertex_count = vertex_count;
    s->cell.triangle_count = triangle_count;
    s->has_geometry = true;
    return MS_OK;
}

ms_status ms_archive_writer_put_error(ms_archive_writer *w, uint32_t cell, const uint8_t *error_table,
                                      ms_error *err)
{
    if (cell >= w->header.cell_count || w->cells[cell].has_error)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: surface errors for cell %u given twice or out of range",
                            cell);
    cell_state *s = &w->cells[cell];
    size_t window = (size_t)s->cell.bits_max - s->cell.bits_min + 1;
    for (size_t k = 0; k < window; ++k)
        if (error_table[k] > MS_ARCHIVE_ERROR_MAX || (k > 0 && error_table[k] > 2u * error_table[k - 1]))
            return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: surface errors out of range or growing",
                                cell);
    memcpy(s->error_table, error_table, window);
    s->has_error = true;
    return MS_OK;
}

ms_status ms_archive_writer_put_apo(ms_archive_writer *w, uint32_t cell, const uint8_t *data,
                                    uint32_t length, uint32_t raw_length,
                                    const uint32_t *level_table, uint8_t levels, ms_error *err)
{
    if (!w->header.has_apo || cell >= w->header.cell_count || w->cells[cell].has_apo)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: unexpected APO chunk for cell %u", cell);
    if (levels == 0 || levels > MS_ARCHIVE_MAX_APO_LEVELS || (raw_length & 3))
        return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: bad APO chunk shape", cell);
    uint32_t prev_bytes = 0, prev_texels = 0;
    for (uint8_t l = 0; l < levels; ++l) {
        if (level_table[2 * l] < prev_bytes || level_table[2 * l + 1] < prev_texels ||
            level_table[2 * l] > length)
            return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: bad APO level table", cell);
        prev_bytes = level_table[2 * l], prev_texels = level_table[2 * l + 1];
    }
    if (prev_bytes != length || prev_texels != raw_length / 4)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: APO level table must end at the chunk size", cell);
    cell_state *s = &w->cells[cell];
    s->apo_table = copy_table(level_table, 2u * levels);
    if (!s->apo_table)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", w->path);
    ms_status st = spool_append(w, data, length, &s->apo_spool, err);
    if (st != MS_OK)
        return st;
    s->cell.apo_length = length;
    s->cell.apo_raw_length = raw_length;
    s->cell.apo_crc = (uint32_t)crc32_z(0L, data, length);
    s->cell.apo_levels = levels;
    s->has_apo = true;
    return MS_OK;
}

ms_status ms_archive_writer_get_apo(ms_archive_writer *w, uint32_t cell, uint8_t **data,
                                    uint32_t *length, const uint32_t **level_table, uint8_t *levels,
                                    ms_error *err)
{
    *data = NULL, *length = 0, *level_table = NULL, *levels = 0;
    if (cell >= w->header.cell_count)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: no cell %u", cell);
    const cell_state *s = &w->cells[cell];
    if (!s->has_apo)
        return MS_OK;
    uint8_t *copy = malloc(s->cell.apo_length ? s->cell.apo_length : 1);
    if (!copy)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", w->path);
    if (s->cell.apo_length && (fseeko(w->spool, (off_t)s->apo_spool, SEEK_SET) != 0 ||
                               fread(copy, 1, s->cell.apo_length, w->spool) != s->cell.apo_length)) {
        free(copy);
        return ms_error_set(err, MS_ERR_IO, "%s: spool read failed: %s", w->path, strerror(errno));
    }
    *data = copy, *length = s->cell.apo_length, *level_table = s->apo_table, *levels = s->cell.apo_levels;
    return MS_OK;
}

void ms_archive_writer_drop_apo(ms_archive_writer *w, uint32_t cell)
{
    if (cell >= w->header.cell_count || !w->cells[cell].has_apo)
        return;
    cell_state *s = &w->cells[cell];
    free(s->apo_table);
    s->apo_table = NULL;
    s->apo_spool = 0;
    s->cell.apo_length = s->cell.apo_raw_length = s->cell.apo_crc = 0;
    s->cell.apo_levels = 0;
    s->has_apo = false;
}

ms_status ms_archive_writer_put_colour(ms_archive_writer *w, uint32_t cell, const uint8_t *data,
                                       uint32_t length, const uint32_t *prefix_table,
                                       ms_error *err)
{
    if (!w->header.has_colour || cell >= w->header.cell_count || w->cells[cell].has_colour ||
        length == 0)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: unexpected colour stream for cell %u",
                            cell);
    cell_state *s = &w->cells[cell];
    size_t words = (size_t)s->cell.bits_max - s->cell.bits_min + 1;
    uint32_t previous = 0;
    for (size_t k = 0; k < words; ++k) {
        if (prefix_table[k] < previous || prefix_table[k] > length)
            return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: bad colour prefix table", cell);
        previous = prefix_table[k];
    }
    if (previous != length)
        return ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: colour prefix table must end at %u",
                            cell, length);
    s->colour_table = malloc((words + 1) * sizeof *s->colour_table);
    if (!s->colour_table)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", w->path);
    memcpy(s->colour_table, prefix_table, words * sizeof *s->colour_table);
    s->colour_table[words] = (uint32_t)crc32_z(0L, data, length);
    ms_status st = spool_append(w, data, length, &s->colour_spool, err);
    if (st != MS_OK)
        return st;
    s->has_colour = true;
    return MS_OK;
}

/* Copies `length` spool bytes from `offset` to the output. */
static int copy_from_spool(ms_archive_writer *w, FILE *out, uint64_t offset, uint32_t length)
{
    uint8_t buf[1 << 16];
    if (fseeko(w->spool, (off_t)offset, SEEK_SET) != 0)
        return 1;
    while (length) {
        size_t chunk = length < sizeof buf ? length : sizeof buf;
        if (fread(buf, 1, chunk, w->spool) != chunk || fwrite(buf, 1, chunk, out) != chunk)
            return 1;
        length -= (uint32_t)chunk;
    }
    return 0;
}

void ms_archive_writer_set_threads(ms_archive_writer *w, unsigned threads)
{
    w->threads = threads ? threads : 1;
}

ms_status ms_archive_writer_set_subtree_levels(ms_archive_writer *w, unsigned subtree_levels,
                                               ms_error *err)
{
    if (subtree_levels != 0 &&
        (subtree_levels < MS_SUBTREE_MIN_LEVELS || subtree_levels > MS_SUBTREE_MAX_LEVELS))
        return ms_error_set(err, MS_ERR_ARG, "archive writer: subtree depth %u outside %u..%u",
                            subtree_levels, MS_SUBTREE_MIN_LEVELS, MS_SUBTREE_MAX_LEVELS);
    w->subtree_levels = subtree_levels ? subtree_levels : ms_subtree_default_levels(w->header.n);
    return MS_OK;
}

/* The subtrees are encoded and deflated in blocks of SUBTREES_PER_BLOCK on the
 * pool, each into its own buffer; the section is then laid out in id order, so
 * its bytes do not depend on the thread count. A failing block stops at its
 * first failing subtree, and the lowest failing block's error is reported: the
 * first failure in id order, as one thread would find it. */
#define SUBTREES_PER_BLOCK 8

typedef struct subtree_job {
    const ms_archive *a;
    unsigned levels;
    const uint32_t *ids;
    size_t count;
    uint8_t **stored;    /* per subtree, malloc'd */
    size_t *stored_size; /* per subtree */
    ms_status *status;   /* per block */
    ms_error *errs;      /* per block */
} subtree_job;

static void deflate_subtree_block(void *context, size_t block)
{
    subtree_job *j = context;
    size_t end = (block + 1) * SUBTREES_PER_BLOCK < j->count ? (block + 1) * SUBTREES_PER_BLOCK
                                                             : j->count;
    for (size_t i = block * SUBTREES_PER_BLOCK; i < end && j->status[block] == MS_OK; ++i) {
        uint8_t *raw = NULL;
        size_t raw_size;
        ms_status st = ms_subtree_encode(j->a, j->levels, j->ids[i], &raw, &raw_size,
                                         &j->errs[block]);
        if (st == MS_OK)
            st = ms_subtree_deflate(raw, raw_size, &j->stored[i], &j->stored_size[i],
                                    &j->errs[block]);
        free(raw);
        j->status[block] = st;
    }
}

/* Every subtree of a's stored bytes into j (allocated here; the caller frees
 * them with free_subtree_job, also after an error). */
static ms_status deflate_subtrees(const ms_archive_writer *w, const ms_archive *a,
                                  const uint32_t *ids, size_t count, subtree_job *j,
                                  ms_error *err)
{
    size_t blocks = (count + SUBTREES_PER_BLOCK - 1) / SUBTREES_PER_BLOCK;
    *j = (subtree_job){.a = a, .levels = w->subtree_levels, .ids = ids, .count = count};
    j->stored = calloc(count ? count : 1, sizeof *j->stored);
    j->stored_size = calloc(count ? count : 1, sizeof *j->stored_size);
    j->status = calloc(blocks ? blocks : 1, sizeof *j->status);
    j->errs = calloc(blocks ? blocks : 1, sizeof *j->errs);
    if (!j->stored || !j->stored_size || !j->status || !j->errs)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for the subtrees", w->path);
    ms_error no_threads; /* too few threads only slows the loop down */
    (void)ms_parallel_for(w->threads, blocks, deflate_subtree_block, j, &no_threads);
    for (size_t b = 0; b < blocks; ++b)
        if (j->status[b] != MS_OK)
            return ms_error_set(err, j->status[b], "%s", j->errs[b].text);
    return MS_OK;
}

static void free_subtree_job(subtree_job *j)
{
    if (j->stored)
        for (size_t i = 0; i < j->count; ++i)
            free(j->stored[i]);
    free(j->stored);
    free(j->stored_size);
    free(j->status);
    free(j->errs);
}

/* The index section: the subtree directory (per subtree, in ascending id: id,
 * offset from the end of the directory, stored length; then the CRC32 of those
 * entries) followed by the stored subtrees in the same order. The subtrees come
 * from the reader's own encoder over the index as an index blob, so what a
 * server computes from a blob is the same bytes. */
static ms_status encode_subtrees(const ms_archive_writer *w, const uint8_t *index,
                                 uint64_t index_size, uint64_t payload, uint32_t index_crc,
                                 uint8_t **out, uint64_t *out_size, uint32_t *out_count,
                                 ms_error *err)
{
    *out = NULL;
    *out_size = 0;
    size_t blob_size = MS_ARCHIVE_HEADER_SIZE + (size_t)index_size;
    uint8_t *blob = malloc(blob_size);
    if (!blob)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for the index", w->path);
    ms_archive_encode_blob_header(&w->header, index_size, payload, index_crc, blob);
    memcpy(blob + MS_ARCHIVE_HEADER_SIZE, index, (size_t)index_size);
    ms_archive *a;
    ms_status st = ms_archive_open_index(blob, blob_size, w->path, &a, err);
    free(blob);
    if (st != MS_OK)
        return st;
    uint32_t *ids = NULL;
    size_t count = 0;
    subtree_job j = {0};
    st = ms_subtree_list(a, w->subtree_levels, &ids, &count, err);
    if (st == MS_OK)
        st = deflate_subtrees(w, a, ids, count, &j, err);
    size_t directory = 12 * count + 4, used = directory;
    for (size_t i = 0; st == MS_OK && i < count; ++i) {
        used += j.stored_size[i];
        if (used - directory > UINT32_MAX)
            st = ms_error_set(err, MS_ERR_RANGE, "%s: stored subtrees pass 4 GiB", w->path);
    }
    uint8_t *buf = st == MS_OK ? malloc(used) : NULL;
    if (st == MS_OK && !buf)
        st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for the subtrees", w->path);
    used = directory;
    for (size_t i = 0; st == MS_OK && i < count; ++i) {
        uint8_t *e = buf + 12 * i;
        uint32_t fields[3] = {ids[i], (uint32_t)(used - directory), (uint32_t)j.stored_size[i]};
        for (int f = 0; f < 3; ++f)
            for (int b = 0; b < 4; ++b)
                e[4 * f + b] = (uint8_t)(fields[f] >> (8 * b));
        memcpy(buf + used, j.stored[i], j.stored_size[i]);
        used += j.stored_size[i];
    }
    if (st == MS_OK) {
        uint32_t crc = (uint32_t)crc32_z(0L, buf, 12 * count);
        for (int b = 0; b < 4; ++b)
            buf[12 * count + b] = (uint8_t)(crc >> (8 * b));
        *out = buf;
        *out_size = used;
        *out_count = (uint32_t)count;
    } else {
        free(buf);
    }
    free_subtree_job(&j);
    free(ids);
    ms_archive_close(a);
    return st;
}

ms_status ms_archive_writer_finish(ms_archive_writer *w, ms_error *err)
{
    ms_archive_header *h = &w->header;
    /* Place payloads in cell order and lay the tables out without gaps. */
    uint64_t payload = 0, table_words = 0;
    for (uint32_t id = 0; id < h->cell_count; ++id) {
        cell_state *s = &w->cells[id];
        if (!s->has_geometry) {
            ms_status st = ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u has no geometry", id);
            ms_archive_writer_abort(w);
            return st;
        }
        if (h->has_colour && s->has_colour != (s->cell.vertex_count > 0)) {
            ms_status st = ms_error_set(err, MS_ERR_ARG, "archive writer: cell %u: %s", id,
                                        s->has_colour ? "colour stream for an empty cell"
                                                      : "no colour stream");
            ms_archive_writer_abort(w);
            return st;
        }
        s->cell.geometry_offset = payload;
        payload += s->cell.geometry_length;
        /* the colour stream follows the geometry (docs/ARCHIVE.md) */
        size_t window = (size_t)s->cell.bits_max - s->cell.bits_min + 1;
        payload += s->has_colour ? s->colour_table[window - 1] : 0;
        s->cell.apo_offset = s->has_apo ? payload : 0;
        payload += s->cell.apo_length;
        s->cell.table_first = (uint32_t)table_words;
        table_words += cell_table_words(h, &s->cell);
    }
    if (table_words > MS_ARCHIVE_MAX_TABLE_WORDS) {
        ms_archive_writer_abort(w);
        return ms_error_set(err, MS_ERR_RANGE, "archive writer: too many table words");
    }
    h->table_words = (uint32_t)table_words;
    uint64_t index_size = (uint64_t)h->cell_count * MS_ARCHIVE_RECORD_SIZE + 4 * table_words;
    uint8_t *index = malloc(index_size);
    if (!index) {
        ms_archive_writer_abort(w);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for the index", w->path);
    }
    uint8_t *words = index + (size_t)h->cell_count * MS_ARCHIVE_RECORD_SIZE;
    for (uint32_t id = 0; id < h->cell_count; ++id) {
        cell_state *s = &w->cells[id];
        ms_archive_encode_cell(&s->cell, index + (size_t)id * MS_ARCHIVE_RECORD_SIZE);
        size_t geometry_words = (size_t)s->cell.bits_max - s->cell.bits_min + 1;
        size_t apo_end = geometry_words + 2u * s->cell.apo_levels;
        size_t n = (size_t)cell_table_words(h, &s->cell), error_first = n - (geometry_words + 3) / 4;
        for (size_t k = 0; k < error_first; ++k) {
            uint32_t v = k < geometry_words ? s->geometry_table[k]
                         : k < apo_end      ? s->apo_table[k - geometry_words]
                         : s->has_colour    ? s->colour_table[k - apo_end]
                                            : 0;
            uint8_t *p = words + 4 * ((size_t)s->cell.table_first + k);
            p[0] = (uint8_t)v, p[1] = (uint8_t)(v >> 8), p[2] = (uint8_t)(v >> 16), p[3] = (uint8_t)(v >> 24);
        }
        /* the error table's bytes, the half-diagonal where none was given */
        uint8_t *error = words + 4 * ((size_t)s->cell.table_first + error_first);
        for (size_t k = 0; k < 4 * (n - error_first); ++k)
            error[k] = k >= geometry_words ? 0 : s->has_error ? s->error_table[k] : MS_ARCHIVE_ERROR_SCALE;
    }
    /* The CRC covers the raw index; the file holds it as subtrees. */
    uint32_t index_crc = (uint32_t)crc32_z(0L, index, index_size);
    uint8_t *stored = NULL;
    uint64_t stored_size = 0;
    uint32_t subtree_count = 0;
    ms_status zst = encode_subtrees(w, index, index_size, payload, index_crc, &stored,
                                    &stored_size, &subtree_count, err);
    free(index);
    if (zst != MS_OK) {
        ms_archive_writer_abort(w);
        return zst;
    }
    uint8_t head[MS_ARCHIVE_HEADER_SIZE];
    ms_archive_encode_header(h, index_size, (uint32_t)stored_size, payload,
                             MS_ARCHIVE_HEADER_SIZE + stored_size + payload, index_crc,
                             w->subtree_levels, subtree_count, head);

    FILE *out = fopen(w->partial_path, "wb");
    int failed = !out;
    /* Held until the rename: a bake starting meanwhile leaves this file alone. */
    if (out && flock(fileno(out), LOCK_EX) != 0)
        failed = 1;
    if (out) {
        failed |= fwrite(head, 1, sizeof head, out) != sizeof head;
        failed |= fwrite(stored, 1, stored_size, out) != stored_size;
        for (uint32_t id = 0; !failed && id < h->cell_count; ++id) {
            cell_state *s = &w->cells[id];
            failed |= copy_from_spool(w, out, s->geometry_spool, s->cell.geometry_length);
            if (s->has_colour)
                failed |= copy_from_spool(w, out, s->colour_spool,
                                          s->colour_table[s->cell.bits_max - s->cell.bits_min]);
            if (s->has_apo)
                failed |= copy_from_spool(w, out, s->apo_spool, s->cell.apo_length);
        }
        failed |= fflush(out) != 0 || fsync(fileno(out)) != 0;
        failed |= fclose(out) != 0;
    }
    free(stored);
    if (failed || rename(w->partial_path, w->path) != 0) {
        ms_status st = ms_error_set(err, MS_ERR_IO, "%s: write failed: %s", w->path, strerror(errno));
        ms_archive_writer_abort(w);
        return st;
    }
    writer_free(w);
    return MS_OK;
}

unsigned ms_archive_writer_remove_stale(const char *dir, ms_archive_stale_fn removed, void *arg)
{
    static const char suffix[] = ".msa.partial";
    const size_t suffix_length = sizeof suffix - 1;
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    unsigned count = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t n = strlen(e->d_name);
        if (n <= suffix_length || strcmp(e->d_name + n - suffix_length, suffix) != 0)
            continue;
        char path[4096 + 256];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
        if (fd < 0)
            continue;
        struct stat st;
        /* Unlinked under the lock, so a writer cannot take it in between. */
        if (fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && flock(fd, LOCK_EX | LOCK_NB) == 0 &&
            unlink(path) == 0) {
            ++count;
            if (removed)
                removed(arg, e->d_name);
        }
        close(fd);
    }
    closedir(d);
    return count;
}
