/* APO for the GPU (ms_render_internal.h): a stored chunk prefix to validated
 * texel words, and the shared texel buffer the shader reads with texelFetch. */
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ms_apo_format.h"
#include "ms_render_internal.h"

/* Inflates as much of data as zlib can (a prefix cut at a sync flush inflates
 * cleanly; one cut elsewhere gives what precedes the cut), at most max_bytes. */
static ms_status inflate_prefix(const uint8_t *data, size_t length, size_t max_bytes, uint8_t **out,
                                size_t *out_size, ms_error *err)
{
    *out = NULL;
    *out_size = 0;
    size_t cap = 4 * length + 4096;
    if (cap > max_bytes)
        cap = max_bytes;
    uint8_t *buf = malloc(cap ? cap : 1);
    if (!buf)
        return ms_error_set(err, MS_ERR_NOMEM, "apo prefix: no memory");
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit(&z) != Z_OK) {
        free(buf);
        return ms_error_set(err, MS_ERR_NOMEM, "apo prefix: zlib cannot start");
    }
    z.next_in = (Bytef *)(uintptr_t)data;
    size_t in_left = length, produced = 0;
    ms_status st = MS_OK;
    for (;;) {
        if (produced == cap) {
            if (cap == max_bytes)
                break; /* everything the record allows: further bytes are junk */
            size_t cap2 = cap * 2 > max_bytes ? max_bytes : cap * 2;
            uint8_t *b2 = realloc(buf, cap2);
            if (!b2) {
                st = ms_error_set(err, MS_ERR_NOMEM, "apo prefix: no memory");
                break;
            }
            buf = b2;
            cap = cap2;
        }
        uInt in_now = in_left > UINT32_MAX ? UINT32_MAX : (uInt)in_left;
        size_t room = cap - produced;
        z.avail_in = in_now;
        z.next_out = buf + produced;
        z.avail_out = room > UINT32_MAX ? UINT32_MAX : (uInt)room;
        uInt out_before = z.avail_out;
        int rc = inflate(&z, Z_SYNC_FLUSH);
        produced += out_before - z.avail_out;
        in_left -= in_now - z.avail_in;
        if (rc == Z_STREAM_END)
            break;
        if (rc == Z_BUF_ERROR || (rc == Z_OK && in_left == 0 && z.avail_out > 0))
            break; /* no progress possible: the prefix ends here */
        if (rc != Z_OK) {
            st = ms_error_set(err, MS_ERR_CORRUPT, "apo prefix: zlib: %s", z.msg ? z.msg : "bad stream");
            break;
        }
    }
    inflateEnd(&z);
    if (st != MS_OK) {
        free(buf);
        return st;
    }
    *out = buf;
    *out_size = produced;
    return MS_OK;
}

ms_status ms_render_apo_words(const ms_archive_cell *record, const uint8_t *data, size_t length, unsigned levels,
                              uint32_t **words, size_t *count, bool *root_internal, ms_error *err)
{
    *words = NULL;
    *count = 0;
    *root_internal = false;
    unsigned total_levels = record->apo_levels;
    if (levels == 0 || levels > total_levels || total_levels > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_ARG, "apo prefix: %u levels of a chunk of %u", levels, total_levels);
    if (!data || length == 0)
        return ms_error_set(err, MS_ERR_ARG, "apo prefix: no bytes");
    size_t max_bytes = record->apo_raw_length & ~(size_t)3;
    if (max_bytes > 4 * (size_t)MS_APO_MAX_TEXELS)
        max_bytes = 4 * (size_t)MS_APO_MAX_TEXELS;
    uint8_t *bytes;
    size_t size;
    ms_status st = inflate_prefix(data, length, max_bytes, &bytes, &size, err);
    if (st != MS_OK)
        return st;
    size_t have = size / 4;
    uint32_t *w = malloc((have ? have : 1) * sizeof *w);
    if (!w) {
        free(bytes);
        return ms_error_set(err, MS_ERR_NOMEM, "apo prefix: no memory");
    }
    ms_apo_words_from_bytes(bytes, have, w);
    free(bytes);
    /* Level sizes from the words: a chunk of one level has a leaf root (an
     * internal node there would have children below the last level); otherwise
     * the root is internal. Level d + 1 holds the children of level d's internal
     * nodes: popcount(exist) words plus one more per internal child. The kinds of
     * a level's nodes come from the kind masks of the level above. */
    uint32_t level_texels[MS_APO_MAX_LEVELS];
    bool internal_root = total_levels >= 2;
    /* a level's nodes: at most 8 per internal node of the level above, which
     * has at most have / 2 of them */
    size_t kinds_cap = 4 * have + 8;
    uint8_t *kinds = malloc(kinds_cap), *next_kinds = malloc(kinds_cap);
    if (!kinds || !next_kinds) {
        free(kinds);
        free(next_kinds);
        free(w);
        return ms_error_set(err, MS_ERR_NOMEM, "apo prefix: no memory");
    }
    size_t kind_count = 1, cursor = 0;
    kinds[0] = internal_root;
    st = MS_OK;
    for (unsigned d = 0; d < levels && st == MS_OK; ++d) {
        size_t start = cursor, next_count = 0, next_words = 0;
        for (size_t k = 0; k < kind_count; ++k) {
            size_t node_words = kinds[k] ? 2 : 1;
            if (cursor + node_words > have) {
                st = ms_error_set(err, MS_ERR_CORRUPT, "apo prefix: %zu words hold fewer than %u levels", have,
                                  levels);
                break;
            }
            if (kinds[k]) {
                uint32_t exist = ms_apo_header_exist(w[cursor]);
                uint32_t kind = ms_apo_mean_kind(w[cursor + 1]) & exist;
                for (uint32_t o = 0; o < 8; ++o)
                    if (exist >> o & 1u) {
                        if (next_count >= kinds_cap) {
                            st = ms_error_set(err, MS_ERR_CORRUPT, "apo prefix: level %u too large", d + 1);
                            break;
                        }
                        next_kinds[next_count++] = (uint8_t)(kind >> o & 1u);
                        next_words += (kind >> o & 1u) ? 2 : 1;
                    }
                if (st != MS_OK)
                    break;
            }
            cursor += node_words;
        }
        level_texels[d] = (uint32_t)(cursor - start);
        if (st == MS_OK && d + 1 < total_levels) {
            if (next_count == 0) {
                st = ms_error_set(err, MS_ERR_CORRUPT, "apo prefix: level %u is empty", d + 1);
            } else {
                level_texels[d + 1] = (uint32_t)next_words;
                uint8_t *t = kinds;
                kinds = next_kinds;
                next_kinds = t;
                kind_count = next_count;
            }
        }
    }
    free(kinds);
    free(next_kinds);
    if (st == MS_OK) {
        /* the table of what is held plus the next level's size, so that the
         * loader accepts internal nodes on the last level held */
        unsigned table_levels = levels < total_levels ? levels + 1 : levels;
        ms_apo_view view;
        st = ms_apo_view_init(&view, level_texels, table_levels, w, cursor, err);
        if (st == MS_OK && view.complete_levels != levels)
            st = ms_error_set(err, MS_ERR_CORRUPT, "apo prefix: %u complete levels, %u expected",
                              view.complete_levels, levels);
    }
    if (st != MS_OK) {
        free(w);
        return st;
    }
    *words = w;
    *count = cursor;
    *root_internal = internal_root;
    return MS_OK;
}

/* ---- the texel buffer --------------------------------------------------- */

#define TEXELS_INITIAL_WORDS (1u << 16)

ms_status ms_render_texels_init(ms_render_texels *t, ms_render_gl_count *gl, ms_error *err)
{
    memset(t, 0, sizeof *t);
    t->gl = gl;
    GLint max_words = 0;
    glGetIntegerv(GL_MAX_TEXTURE_BUFFER_SIZE, &max_words);
    t->max_words = max_words > 0 ? (uint32_t)max_words : 65536u;
    t->capacity = TEXELS_INITIAL_WORDS < t->max_words ? TEXELS_INITIAL_WORDS : t->max_words;
    glGenBuffers(1, &t->buffer);
    glBindBuffer(GL_TEXTURE_BUFFER, t->buffer);
    glBufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)t->capacity * 4, NULL, GL_DYNAMIC_DRAW);
    ms_render_gl_add(t->gl, 4ull * t->capacity); /* the buffer texture is a view of it: no storage */
    glGenTextures(1, &t->texture);
    glBindTexture(GL_TEXTURE_BUFFER, t->texture);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_R32UI, t->buffer);
    glBindTexture(GL_TEXTURE_BUFFER, 0);
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
    t->free_cap = 16;
    t->free_ranges = malloc(t->free_cap * sizeof *t->free_ranges);
    if (!t->free_ranges || glGetError() != GL_NO_ERROR) {
        ms_render_texels_free(t);
        return ms_error_set(err, MS_ERR_NOMEM, "render: no texel buffer");
    }
    t->free_ranges[0] = (ms_render_texel_range){0, t->capacity};
    t->free_count = 1;
    return MS_OK;
}

void ms_render_texels_free(ms_render_texels *t)
{
    if (t->texture)
        glDeleteTextures(1, &t->texture);
    if (t->buffer) {
        glDeleteBuffers(1, &t->buffer);
        ms_render_gl_sub(t->gl, 4ull * t->capacity);
    }
    free(t->free_ranges);
    memset(t, 0, sizeof *t);
}

/* Inserts a free range in order, merging with its neighbours. */
static bool insert_free(ms_render_texels *t, uint32_t start, uint32_t count)
{
    size_t i = 0;
    while (i < t->free_count && t->free_ranges[i].start < start)
        ++i;
    bool joins_left = i > 0 && t->free_ranges[i - 1].start + t->free_ranges[i - 1].count == start;
    bool joins_right = i < t->free_count && start + count == t->free_ranges[i].start;
    if (joins_left && joins_right) {
        t->free_ranges[i - 1].count += count + t->free_ranges[i].count;
        memmove(&t->free_ranges[i], &t->free_ranges[i + 1], (t->free_count - i - 1) * sizeof *t->free_ranges);
        t->free_count--;
        return true;
    }
    if (joins_left) {
        t->free_ranges[i - 1].count += count;
        return true;
    }
    if (joins_right) {
        t->free_ranges[i].start = start;
        t->free_ranges[i].count += count;
        return true;
    }
    if (t->free_count == t->free_cap) {
        ms_render_texel_range *r = realloc(t->free_ranges, 2 * t->free_cap * sizeof *r);
        if (!r)
            return false;
        t->free_ranges = r;
        t->free_cap *= 2;
    }
    memmove(&t->free_ranges[i + 1], &t->free_ranges[i], (t->free_count - i) * sizeof *t->free_ranges);
    t->free_ranges[i] = (ms_render_texel_range){start, count};
    t->free_count++;
    return true;
}

/* Doubles the buffer (at least to need more free words at its end), copying the
 * words on the GPU. */
static bool grow_texels(ms_render_texels *t, uint32_t need)
{
    uint64_t cap = t->capacity;
    while (cap < (uint64_t)t->capacity + need)
        cap *= 2;
    if (cap > t->max_words)
        cap = t->max_words;
    if (cap < (uint64_t)t->capacity + need)
        return false;
    GLuint bigger;
    glGenBuffers(1, &bigger);
    glBindBuffer(GL_COPY_WRITE_BUFFER, bigger);
    glBufferData(GL_COPY_WRITE_BUFFER, (GLsizeiptr)cap * 4, NULL, GL_DYNAMIC_DRAW);
    if (glGetError() != GL_NO_ERROR) {
        glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
        glDeleteBuffers(1, &bigger);
        return false;
    }
    ms_render_gl_add(t->gl, 4 * cap); /* both buffers are held while the words are copied */
    glBindBuffer(GL_COPY_READ_BUFFER, t->buffer);
    glCopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, 0, 0, (GLsizeiptr)t->capacity * 4);
    glBindBuffer(GL_COPY_READ_BUFFER, 0);
    glBindBuffer(GL_COPY_WRITE_BUFFER, 0);
    glDeleteBuffers(1, &t->buffer);
    ms_render_gl_sub(t->gl, 4ull * t->capacity);
    t->buffer = bigger;
    glBindTexture(GL_TEXTURE_BUFFER, t->texture);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_R32UI, t->buffer);
    glBindTexture(GL_TEXTURE_BUFFER, 0);
    uint32_t old = t->capacity;
    t->capacity = (uint32_t)cap;
    return insert_free(t, old, t->capacity - old);
}

bool ms_render_texels_alloc(ms_render_texels *t, uint32_t count, uint32_t *start)
{
    if (count == 0 || count > t->max_words)
        return false;
    for (int attempt = 0; attempt < 2; ++attempt) {
        for (size_t i = 0; i < t->free_count; ++i) {
            ms_render_texel_range *r = &t->free_ranges[i];
            if (r->count < count)
                continue;
            *start = r->start;
            r->start += count;
            r->count -= count;
            if (r->count == 0) {
                memmove(r, r + 1, (t->free_count - i - 1) * sizeof *r);
                t->free_count--;
            }
            t->used += count;
            return true;
        }
        /* the free tail (if any) counts towards the growth */
        uint32_t tail = 0;
        if (t->free_count && t->free_ranges[t->free_count - 1].start + t->free_ranges[t->free_count - 1].count ==
                                 t->capacity)
            tail = t->free_ranges[t->free_count - 1].count;
        if (attempt == 0 && !grow_texels(t, count - tail))
            return false;
    }
    return false;
}

void ms_render_texels_release(ms_render_texels *t, uint32_t start, uint32_t count)
{
    if (count == 0)
        return;
    t->used -= count;
    /* Out of memory for the free list only leaks the range's space until the
     * renderer is freed: never a wrong read. */
    (void)insert_free(t, start, count);
}
