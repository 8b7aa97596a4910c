/* A whole bake: see ms_bake.h. */
#include "ms_bake.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include "ms_archive_writer.h"
#include "ms_bake_thumbnail.h"
#include "ms_bake_colour.h"
#include "ms_colour.h"
#include "ms_codec.h"
#include "ms_catalog.h"
#include "ms_nsp_build.h"
#include "ms_nsp_encode.h"
#include "ms_nsp_lone.h"
#include "ms_progress.h"

void ms_bake_options_default(ms_bake_options *o)
{
    memset(o, 0, sizeof *o);
    o->bits = 16;
    o->n = 4;
    o->root_bits = 7;
    o->min_triangles = 0; /* by model size: ms_nsp_default_min_triangles */
    o->mem_mb = 512;
    o->public_bits = -1;
    o->ahead = MS_CODEC_DEFAULT_AHEAD;
    o->ahead_until = MS_BAKE_DEFAULT_AHEAD_UNTIL;
    o->smooth_rounds = MS_BAKE_DEFAULT_SMOOTH_ROUNDS;
    o->thumbnail_up = -1;
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    o->threads = cpus > 0 ? (unsigned)cpus : 1;
    ms_bake_apo_params_default(&o->apo);
}

unsigned ms_bake_smooth_bits(const uint64_t *lone_at_level, unsigned bits)
{
    uint64_t total = 0, alone = 0;
    for (unsigned l = 0; l <= 3 * bits; ++l)
        total += lone_at_level[l];
    for (unsigned b = 1, l = 0; total > 0 && b <= bits; ++b) {
        for (; l <= 3 * b; ++l)
            alone += lone_at_level[l];
        if (2 * alone >= total)
            return b;
    }
    return total > 0 ? bits : 0;
}

size_t ms_bake_min_mem_mb(unsigned threads, uint32_t min_triangles)
{
    uint64_t per_thread = ((uint64_t)min_triangles * MS_BAKE_BYTES_PER_LEAF_TRIANGLE + (1u << 20) - 1) >> 20;
    return MS_BAKE_MEM_BASE_MB + (size_t)((threads ? threads : 1) * per_thread);
}

void ms_bake_default_name(const char *path, char *out, size_t size)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    size_t n = 0;
    for (const char *c = base; *c && *c != '.' && n + 1 < size && n < MS_MODEL_NAME_MAX; ++c) {
        bool ok = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
                  *c == '_' || *c == '-';
        out[n++] = ok ? *c : '_';
    }
    if (n == 0 && size > 5)
        memcpy(out, "model", 5), n = 5;
    out[n < size ? n : size - 1] = '\0';
}

/* Progress across phases: one bar, relabelled per phase. */
typedef struct bake_progress {
    ms_progress bar;
    FILE *out;
    const char *phase;
    char label[64];
} bake_progress;

static void on_progress(void *context, const char *phase, double fraction)
{
    bake_progress *p = context;
    if (!p->out)
        return;
    if (p->phase != phase) {
        p->phase = phase;
        snprintf(p->label, sizeof p->label, "meshbake: %s", phase);
        ms_progress_finish(&p->bar);
        ms_progress_init(&p->bar, p->out, p->label, 1000);
    }
    ms_progress_update(&p->bar, (uint64_t)(fraction * 1000.0));
}

static void note_stale(void *arg, const char *file_name)
{
    if (arg)
        fprintf(arg, "meshbake: removed %s, left by an interrupted bake\n", file_name);
}

/* The checks of the options that need no file, and the tree's shape. */
static ms_status check_options(const ms_bake_options *o, ms_nsp_shape *shape, ms_error *err)
{
    ms_status s = ms_nsp_shape_init(shape, o->bits, o->n, o->root_bits, err);
    if (s != MS_OK)
        return s;
    if (o->public_bits > (int)o->bits)
        return ms_error_set(err, MS_ERR_ARG, "--public-bits %d is more than --bits %u",
                            o->public_bits, o->bits);
    /* The default threshold is known only once the input is read: check the
     * largest it can be, so that the refusal comes before reading. */
    uint32_t leaf_triangles = o->min_triangles ? o->min_triangles : MS_NSP_DEFAULT_MIN_TRIANGLES_MAX;
    size_t min_mem = ms_bake_min_mem_mb(o->threads, leaf_triangles);
    if (o->mem_mb < min_mem && o->min_triangles)
        return ms_error_set(err, MS_ERR_ARG,
                            "--mem %zu MB is below the %zu MB a bake with %u threads and "
                            "--min-tris %u works in", o->mem_mb, min_mem, o->threads ? o->threads : 1,
                            o->min_triangles);
    if (o->mem_mb < min_mem)
        return ms_error_set(err, MS_ERR_ARG,
                            "--mem %zu MB is below the %zu MB a bake with %u threads and the "
                            "default --min-tris (by model size, up to %u) works in; give "
                            "--min-tris", o->mem_mb, min_mem, o->threads ? o->threads : 1,
                            MS_NSP_DEFAULT_MIN_TRIANGLES_MAX);
    if (o->apo.enabled && (s = ms_bake_apo_params_check(&o->apo, err)) != MS_OK)
        return s;
    if (o->colour_bits > MS_COLOUR_MAX_BITS)
        return ms_error_set(err, MS_ERR_ARG, "--colour-bits %u outside 1..%u", o->colour_bits,
                            MS_COLOUR_MAX_BITS);
    return MS_OK;
}

/* r->name: --name, or one made from the input file's name. */
static ms_status choose_name(const ms_bake_options *o, ms_bake_report *r, ms_error *err)
{
    if (o->name && strlen(o->name) > MS_MODEL_NAME_MAX)
        return ms_error_set(err, MS_ERR_ARG, "model name of %zu characters; at most %d",
                            strlen(o->name), MS_MODEL_NAME_MAX);
    if (o->name)
        snprintf(r->name, sizeof r->name, "%s", o->name);
    else
        ms_bake_default_name(o->input, r->name, sizeof r->name);
    if (!ms_model_name_valid(r->name))
        return ms_error_set(err, MS_ERR_ARG, "invalid model name '%s' (1-64 of A-Z a-z 0-9 _ -)",
                            r->name);
    return MS_OK;
}

/* The archive directory and r->archive_path in it. A missing directory is
 * created (its parent must exist); an existing path that is not a directory
 * is an error. The leftovers of killed bakes into it (not of bakes at work)
 * are removed. */
static ms_status prepare_directory(const ms_bake_options *o, ms_bake_report *r, ms_error *err)
{
    struct stat sb;
    if (stat(o->archive_dir, &sb) != 0 && mkdir(o->archive_dir, 0777) != 0 && errno != EEXIST)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot create directory: %s", o->archive_dir,
                            strerror(errno));
    if (stat(o->archive_dir, &sb) != 0 || !S_ISDIR(sb.st_mode))
        return ms_error_set(err, MS_ERR_IO, "%s: not a directory", o->archive_dir);
    int n = snprintf(r->archive_path, sizeof r->archive_path, "%s/%s.msa", o->archive_dir, r->name);
    if (n < 0 || (size_t)n + 16 >= sizeof r->archive_path)
        return ms_error_set(err, MS_ERR_ARG, "archive path too long");
    ms_archive_writer_remove_stale(o->archive_dir, note_stale, o->notes);
    return MS_OK;
}

/* The figures of the tree's build into r. */
static void report_build(const ms_nsp_build *b, ms_bake_report *r)
{
    r->input_vertices = b->stats.input_vertices;
    r->input_triangles = b->stats.input_triangles;
    r->seconds_read = b->stats.seconds_read;
    r->seconds_quantise = b->stats.seconds_quantise;
    r->seconds_distribute = b->stats.seconds_distribute;
    r->cells = b->node_count;
    r->min_triangles = b->params.min_triangles;
    r->blocks_written = b->stats.blocks_written;
    r->peak_rss_build_mb = ms_peak_rss_mb();
    r->flushes = b->stats.flushes;
    r->key_page_misses = b->stats.key_page_misses;
    r->io_read = b->stats.io_read;
    r->io_quantise = b->stats.io_quantise;
    r->io_distribute = b->stats.io_distribute;
    for (uint32_t i = 0; i < b->node_count; ++i) {
        r->leaves += b->nodes[i].first_child == MS_NSP_NONE;
        if (b->nodes[i].depth > r->depth)
            r->depth = b->nodes[i].depth;
    }
}

/* Reads the input and distributes its triangles into the nSP-tree b, out of
 * core; its figures into r. */
static ms_status build_tree(const ms_bake_options *o, const ms_nsp_shape *shape,
                            bake_progress *progress, ms_nsp_build *b, ms_bake_report *r,
                            ms_error *err)
{
    ms_nsp_build_params bp = {
        .shape = *shape,
        .min_triangles = o->min_triangles,
        .buffer_budget = o->buffer_bytes ? o->buffer_bytes : o->mem_mb * (1u << 20) / 8,
        .key_cache_bytes = o->key_cache_bytes ? o->key_cache_bytes : o->mem_mb * (1u << 20) / 4,
        .tmp_dir = o->tmp_dir ? o->tmp_dir : o->archive_dir,
        .threads = o->threads ? o->threads : 1,
        .progress = on_progress,
        .progress_context = progress,
    };
    ms_status s = ms_nsp_build_run(o->input, &bp, b, err);
    if (s != MS_OK)
        return s;
    report_build(b, r);
    return MS_OK;
}

/* The archive's cells in breadth-first order: *order (the node of each
 * cell), *first_child, and *cell_of_node (the cell of each node). The
 * caller frees the three, also after an error. */
static ms_status order_cells(ms_nsp_build *b, uint32_t **order, uint32_t **first_child,
                             uint32_t **cell_of_node, ms_error *err)
{
    ms_status s = ms_nsp_build_bfs(b, order, first_child, err);
    if (s != MS_OK)
        return s;
    *cell_of_node = malloc(b->node_count * sizeof **cell_of_node);
    if (!*cell_of_node)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    for (uint32_t i = 0; i < b->node_count; ++i)
        (*cell_of_node)[(*order)[i]] = i;
    return MS_OK;
}

static ms_archive_header archive_header(const ms_bake_options *o, const ms_nsp_build *b,
                                        const ms_bake_report *r)
{
    ms_archive_header h;
    memset(&h, 0, sizeof h);
    for (int a = 0; a < 3; ++a)
        h.box_origin[a] = b->box.origin[a];
    h.box_side = b->box.size;
    h.bits = (uint8_t)o->bits;
    h.n = (uint8_t)o->n;
    h.root_bits = (uint8_t)o->root_bits;
    h.cell_count = b->node_count;
    h.min_triangles = b->params.min_triangles; /* the one used: options' or the default */
    h.has_apo = o->apo.enabled;
    h.apo_lead = o->apo.enabled ? (uint8_t)o->apo.lead : 0;
    h.apo_max_depth = o->apo.enabled ? (uint8_t)o->apo.max_depth : 0;
    h.has_colour = r->colour;
    h.colour_bits = (uint8_t)r->colour_bits;
    h.colour_alpha = r->colour_alpha;
    h.smooth_bits = o->smooth_rounds ? (uint8_t)ms_bake_smooth_bits(b->stats.lone_at_level, o->bits) : 0;
    h.smooth_rounds = h.smooth_bits ? (uint8_t)o->smooth_rounds : 0;
    return h;
}

/* The APO and duplication figures of the encoding into r (after the model
 * was found to keep triangles). */
static void report_apo_and_duplicates(const ms_nsp_encode_stats *es, unsigned threads,
                                      const ms_nsp_build *b, ms_bake_report *r)
{
    r->leaf_triangles = es->leaf_triangles;
    r->empty_cells = es->empty_cells;
    r->geometry_bytes = es->geometry_bytes;
    /* what is stored: the chunks as built less what the byte budget cut */
    const ms_bake_apo_budget_report *cut = &es->apo_budget;
    r->apo_budget = *cut;
    r->apo_bytes = es->apo_bytes - (cut->bytes_before - cut->bytes_after);
    r->apo_raw_bytes = es->apo_raw_bytes - 4 * cut->texels_dropped;
    r->apo_levels = 0;
    for (uint32_t d = 0; d < MS_APO_MAX_LEVELS; ++d)
        if ((r->apo_level_texels[d] = es->apo_level_texels[d] - cut->level_texels_dropped[d]) > 0)
            r->apo_levels = d + 1;
    r->apo_chunks = es->apo_chunks - cut->chunks_removed;
    r->apo_internal_nodes = es->apo_internal_nodes - cut->internal_dropped;
    r->apo_leaves = es->apo_leaves - cut->leaves_dropped;
    r->apo_rays = es->apo_rays;
    r->apo_point_queries = es->apo_point_queries;
    r->apo_triangle_visits = es->apo_triangle_visits;
    r->apo_samples = es->apo_samples;
    r->apo_sampled_leaves = es->apo_sampled_leaves;
    r->apo_agreed_leaves = es->apo_agreed_leaves;
    r->apo_smooth_leaves = es->apo_smooth_leaves;
    r->seconds_apo = es->apo_thread_seconds / threads;
    r->apo_sample_triangles = es->apo_sample_triangles;
    r->apo_sample_triangles_max = es->apo_sample_triangles_max;
    r->apo_accuracy_points = es->apo_accuracy.points;
    r->apo_accuracy_mean = es->apo_accuracy.points ? es->apo_accuracy.sum_degrees / (double)es->apo_accuracy.points
                                                   : 0.0;
    r->apo_accuracy_median = ms_bake_apo_accuracy_quantile(&es->apo_accuracy, 0.5);
    r->apo_accuracy_p90 = ms_bake_apo_accuracy_quantile(&es->apo_accuracy, 0.9);
    r->duplicated_percent = r->triangles ? 100.0 * (double)(r->leaf_triangles - r->triangles) /
                                               (double)r->triangles
                                         : 0.0;
    r->insertion_copies = b->stats.insertion_copies;
    r->duplicated_at_insertion_percent =
        r->triangles ? 100.0 * (double)r->insertion_copies / (double)r->triangles : 0.0;
}

/* Encodes every cell (geometry, and APO when on) into w; the figures into r.
 * A model whose every triangle welds away is an error. */
static ms_status encode_cells(const ms_bake_options *o, ms_nsp_build *b,
                              const uint32_t *cell_of_node, const ms_bake_colours *colours,
                              ms_archive_writer *w, bake_progress *progress, ms_bake_report *r,
                              ms_error *err)
{
    ms_nsp_encode_params ep = {
        .threads = o->threads ? o->threads : 1,
        .apo = &o->apo,
        .ahead = o->ahead,
        .ahead_until = o->ahead_until,
        .smooth_rounds = r->smooth_rounds,
        .smooth_level = 3 * r->smooth_bits,
        .colours = r->colour ? colours : NULL,
        .colour_bits = r->colour_bits,
        .progress = on_progress,
        .progress_context = progress,
        /* freed memory kept resident between cells' APO work: an eighth of
         * the budget, as much as distribute's leaf buffers had */
        .resident_free_max = o->mem_mb * ((size_t)1 << 20) / 8,
    };
    r->threads = ep.threads;
    ms_nsp_encode_stats es;
    ms_status s = ms_nsp_encode_all(b, cell_of_node, w, &ep, &es, err);
    if (s != MS_OK)
        return s;
    r->seconds_encode = es.seconds;
    r->colour_bytes = es.colour_bytes;
    r->io_encode = es.io;
    memcpy(r->depth_leaves, es.depth_leaves, sizeof r->depth_leaves);
    memcpy(r->depth_triangles, es.depth_triangles, sizeof r->depth_triangles);
    memcpy(r->depth_owned, es.depth_owned, sizeof r->depth_owned);
    r->vertices = es.welded_vertices;
    r->triangles = es.welded_triangles;
    if (r->triangles == 0)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "every triangle of the model degenerates at %u bits (welded away): "
                            "nothing to bake; try more --bits", o->bits);
    report_apo_and_duplicates(&es, ep.threads, b, r);
    return MS_OK;
}

/* Adds the baked model to the directory's catalogue; without its entry the
 * archive is removed. */
static ms_status record_in_catalog(const ms_bake_options *o, ms_bake_report *r,
                                   const ms_archive_header *h, ms_error *err)
{
    ms_catalog_entry e;
    memset(&e, 0, sizeof e);
    snprintf(e.name, sizeof e.name, "%s", r->name);
    e.source = (char *)o->input;
    ms_catalog_now(e.baked_at, sizeof e.baked_at);
    e.vertices = r->vertices;
    e.triangles = r->triangles;
    e.archive_bytes = r->archive_bytes;
    e.cells = r->cells;
    e.bits = (uint8_t)o->bits;
    e.n = (uint8_t)o->n;
    e.root_bits = (uint8_t)o->root_bits;
    e.min_triangles = h->min_triangles;
    e.public_max_bits = (uint8_t)(o->public_bits < 0 ? (int)o->bits : o->public_bits);
    e.apo = o->apo.enabled;
    e.apo_lead = h->apo_lead;
    e.apo_max_depth = h->apo_max_depth;
    e.apo_tolerance = o->apo.enabled ? o->apo.tolerance : 0.0;
    e.metadata = (ms_metadata *)o->metadata;
    ms_status s = ms_catalog_entry_fill_listing(&e, r->archive_path, err);
    if (s == MS_OK && !o->no_thumbnail) {
        ms_study_thumbnail_report tr;
        ms_error terr;
        int up = o->thumbnail_up;
        ms_catalog before;
        if (up < 0 && ms_catalog_load(o->archive_dir, &before, &terr) == MS_OK) {
            const ms_catalog_entry *was = ms_catalog_find(&before, e.name);
            up = was && was->has_thumbnail ? was->thumbnail_up : 2;
            ms_catalog_free(&before);
        }
        if (ms_bake_thumbnail(o->archive_dir, &e, up, o->threads, &tr, &terr) ==
            MS_OK) {
            r->seconds_thumbnail = tr.seconds;
            r->thumbnail_bytes = tr.png_bytes;
            r->thumbnail_bits = e.thumbnail_bits;
        } else if (o->notes) { /* the model is served without a picture */
            fprintf(o->notes, "meshbake: no thumbnail: %s\n", terr.text);
        }
    } else if (s == MS_OK) { /* an older picture would not match this archive */
        char png[4200];
        ms_bake_thumbnail_path(o->archive_dir, e.name, png, sizeof png);
        unlink(png);
    }
    if (s == MS_OK)
        s = ms_catalog_update(o->archive_dir, &e, err);
    if (s != MS_OK)
        unlink(r->archive_path);
    return s;
}

/* Completes the archive (after the build's temporary files went) and adds it
 * to the catalogue; takes w (freed whatever happens). */
static ms_status finish_archive(const ms_bake_options *o, ms_nsp_build *b, ms_archive_writer *w,
                                const ms_archive_header *h, ms_bake_report *r, ms_error *err)
{
    ms_archive_writer_set_counts(w, r->vertices, r->triangles);
    ms_nsp_build_free(b); /* the temporary files go now */
    ms_status s = ms_archive_writer_finish(w, err);
    if (s != MS_OK)
        return s;
    struct stat sb;
    if (stat(r->archive_path, &sb) == 0)
        r->archive_bytes = (uint64_t)sb.st_size;
    r->bits_per_vertex = r->vertices ? 8.0 * (double)r->archive_bytes / (double)r->vertices : 0;
    return record_in_catalog(o, r, h, err);
}

ms_status ms_bake(const ms_bake_options *o, ms_bake_report *r, ms_error *err)
{
    memset(r, 0, sizeof *r);
    double t_start = ms_now_seconds();
    ms_nsp_shape shape;
    ms_status s;
    if ((s = check_options(o, &shape, err)) != MS_OK || (s = choose_name(o, r, err)) != MS_OK ||
        (s = prepare_directory(o, r, err)) != MS_OK)
        return s;

    bake_progress progress = {.out = o->progress};
    ms_nsp_build b;
    if ((s = build_tree(o, &shape, &progress, &b, r, err)) != MS_OK) {
        ms_progress_finish(&progress.bar);
        return s;
    }
    uint32_t *order = NULL, *first_child = NULL, *cell_of_node = NULL;
    ms_archive_writer *w = NULL;
    ms_bake_colours colours;
    memset(&colours, 0, sizeof colours);
    if (!o->no_colour) {
        double t_colour = ms_now_seconds();
        if ((s = ms_bake_colours_read(o->input, &b.box, o->bits, &colours, &r->colour, err)) != MS_OK)
            goto done;
        r->colour_alpha = colours.alpha;
        r->colour_bits = r->colour ? (o->colour_bits ? o->colour_bits : MS_COLOUR_DEFAULT_BITS) : 0;
        r->seconds_colour = ms_now_seconds() - t_colour;
    }
    double t_lone = ms_now_seconds();
    if ((s = ms_nsp_lone_segments(&b, o->threads ? o->threads : 1, &r->io_lone, err)) != MS_OK)
        goto done;
    r->seconds_lone = ms_now_seconds() - t_lone;
    if ((s = order_cells(&b, &order, &first_child, &cell_of_node, err)) != MS_OK)
        goto done;
    ms_archive_header h = archive_header(o, &b, r);
    r->smooth_rounds = h.smooth_rounds;
    r->smooth_bits = h.smooth_bits;
    if ((s = ms_archive_writer_open(r->archive_path, &h, first_child, &w, err)) != MS_OK)
        goto done;
    if ((s = ms_archive_writer_set_subtree_levels(w, o->subtree_levels, err)) !=
        MS_OK)
        goto done;
    ms_archive_writer_set_threads(w, o->threads ? o->threads : 1);
    if ((s = encode_cells(o, &b, cell_of_node, &colours, w, &progress, r, err)) != MS_OK)
        goto done;
    ms_bake_colours_free(&colours);
    double t_write = ms_now_seconds();
    s = finish_archive(o, &b, w, &h, r, err);
    w = NULL;
    if (s != MS_OK)
        goto done;
    r->seconds_write = ms_now_seconds() - t_write;
done:
    ms_progress_finish(&progress.bar);
    if (w)
        ms_archive_writer_abort(w);
    ms_nsp_build_free(&b);
    ms_bake_colours_free(&colours);
    free(order);
    free(first_child);
    free(cell_of_node);
    r->seconds_total = ms_now_seconds() - t_start;
    r->peak_rss_mb = ms_peak_rss_mb();
    return s;
}
