/* Synthetic archives: see ms_synthetic_archive.h. */
#include "ms_synthetic_archive.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_archive_writer.h"
#include "ms_catalog.h"

uint32_t ms_synthetic_cell_count(unsigned levels)
{
    uint32_t count = 0, width = 1;
    for (unsigned l = 0; l <= levels; ++l, width *= 64)
        count += width;
    return count;
}

static uint32_t mix(uint32_t x)
{
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    return x ^ (x >> 16);
}

static void fill(uint8_t *buf, uint32_t length, uint32_t seed)
{
    uint32_t state = mix(seed) | 1u;
    for (uint32_t i = 0; i < length; ++i) {
        state ^= state << 13, state ^= state >> 17, state ^= state << 5;
        buf[i] = (uint8_t)state;
    }
}

/* mean +- 25 %, at least 16 bytes. */
static uint32_t vary(uint32_t mean, uint32_t cell, uint32_t salt)
{
    uint64_t v = (uint64_t)mean * (75u + mix(cell * 2654435761u + salt) % 51u) / 100u;
    return v < 16 ? 16 : (uint32_t)v;
}

ms_status ms_synthetic_archive_write(const char *dir, const char *name,
                                     const ms_synthetic_spec *spec, ms_error *err)
{
    if (spec->levels > 3 || spec->bits < 8 || spec->bits > 20 ||
        (spec->levels && spec->bits <= 7 + 2 * (spec->levels - 1)) || spec->geometry_bytes == 0 ||
        spec->geometry_bytes > (64u << 20) || spec->apo_bytes > (64u << 20) ||
        (spec->apo_bytes && (spec->apo_levels < 1 || spec->apo_levels > 12)) ||
        !ms_model_name_valid(name))
        return ms_error_set(err, MS_ERR_ARG, "synthetic archive: spec out of range");
    ms_archive_header h;
    memset(&h, 0, sizeof h);
    h.box_side = 1.0;
    h.bits = (uint8_t)spec->bits, h.n = 4, h.root_bits = 7;
    h.has_apo = spec->apo_bytes > 0;
    h.apo_lead = 3, h.apo_max_depth = 20;
    h.cell_count = ms_synthetic_cell_count(spec->levels);
    h.min_triangles = 8000;
    h.vertex_count = (uint64_t)h.cell_count * 4000;
    h.triangle_count = (uint64_t)h.cell_count * 8000;
    uint32_t *first_child = malloc(h.cell_count * sizeof *first_child);
    uint8_t *buf = malloc((size_t)(spec->geometry_bytes > spec->apo_bytes ? spec->geometry_bytes
                                                                            : spec->apo_bytes) *
                              5 / 4 + 64);
    if (!first_child || !buf) {
        free(first_child);
        free(buf);
        return ms_error_set(err, MS_ERR_NOMEM, "synthetic archive: out of memory");
    }
    /* Breadth first: cells of level l start at count(l-1); every cell above
     * the last level has 64 children. */
    uint32_t internal = spec->levels ? ms_synthetic_cell_count(spec->levels - 1) : 0;
    for (uint32_t i = 0; i < h.cell_count; ++i)
        first_child[i] = i < internal ? 1 + 64 * i : MS_ARCHIVE_NONE;
    char path[4200];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_archive_writer *w;
    ms_status st = ms_archive_writer_open(path, &h, first_child, &w, err);
    free(first_child);
    for (uint32_t cell = 0; st == MS_OK && cell < h.cell_count; ++cell) {
        uint8_t lo, hi;
        ms_archive_writer_window(w, cell, &lo, &hi);
        uint32_t length = vary(spec->geometry_bytes, cell, spec->seed), table[64];
        uint32_t words = hi - lo + 1u, header = length / 50 + 8;
        /* Finer bits cost more bytes: step k weighs 2^k. */
        uint64_t weight_total = (1ull << words) - 2;
        for (uint32_t k = 0; k < words; ++k)
            table[k] = header + (uint32_t)((uint64_t)(length - header) * ((1ull << (k + 1)) - 2) /
                                           (weight_total ? weight_total : 1));
        table[words - 1] = length;
        fill(buf, length, cell * 2u + spec->seed * 7919u);
        st = ms_archive_writer_put_geometry(w, cell, buf, length, table, 4000, 8000, err);
        if (st == MS_OK && h.has_apo) {
            uint32_t apo = vary(spec->apo_bytes, cell, spec->seed + 17), levels = spec->apo_levels;
            uint32_t apo_table[24], weight = (1u << levels) - 1;
            for (uint32_t l = 0; l < levels; ++l) {
                apo_table[2 * l] = (uint32_t)((uint64_t)apo * ((1u << (l + 1)) - 1) / weight);
                apo_table[2 * l + 1] = apo_table[2 * l] / 2;
            }
            apo_table[2 * (levels - 1)] = apo;
            apo_table[2 * (levels - 1) + 1] = apo / 2;
            fill(buf, apo, cell * 2u + 1 + spec->seed * 7919u);
            /* raw length: 2 bytes of texels per compressed byte, rounded to texels */
            st = ms_archive_writer_put_apo(w, cell, buf, apo, (apo / 2) * 4, apo_table,
                                           (uint8_t)levels, err);
        }
    }
    free(buf);
    if (st != MS_OK) {
        ms_archive_writer_abort(w);
        return st;
    }
    if ((st = ms_archive_writer_finish(w, err)) != MS_OK)
        return st;
    FILE *f = fopen(path, "rb");
    uint64_t size = 0;
    if (f && fseek(f, 0, SEEK_END) == 0)
        size = (uint64_t)ftell(f);
    if (f)
        fclose(f);
    ms_catalog_entry e;
    memset(&e, 0, sizeof e);
    snprintf(e.name, sizeof e.name, "%s", name);
    e.source = (char *)"synthetic";
    ms_catalog_now(e.baked_at, sizeof e.baked_at);
    e.vertices = h.vertex_count, e.triangles = h.triangle_count, e.cells = h.cell_count;
    e.archive_bytes = size;
    e.bits = h.bits, e.n = 4, e.root_bits = 7, e.min_triangles = 8000;
    e.apo = h.has_apo, e.apo_lead = 3, e.apo_max_depth = 20, e.apo_tolerance = 0.1;
    e.public_max_bits = spec->public_max_bits > h.bits ? h.bits : spec->public_max_bits;
    if ((st = ms_catalog_entry_fill_listing(&e, path, err)) != MS_OK)
        return st;
    return ms_catalog_update(dir, &e, err);
}
