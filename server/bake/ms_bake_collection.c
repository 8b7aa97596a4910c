/* meshbake's collection modes (ms_bake_collection.h): --set-public-bits,
 * --list, --remove, --thumbnail and --annotations on an archive directory. */
#include "ms_bake_collection.h"

#include <errno.h>
#include <inttypes.h>
#include <jansson.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "ms_annotations.h"
#include "ms_archive.h"
#include "ms_bake_thumbnail.h"
#include "ms_catalog.h"
#include "ms_json_out.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

/* Changes the preview of a baked model in its catalogue (under the
 * catalogue's lock, like a bake). */
int ms_bake_cli_set_public(const char *dir, const char *name, unsigned bits, int up_axis,
                           unsigned threads)
{
    ms_catalog catalog;
    ms_error err;
    if (ms_catalog_load(dir, &catalog, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    const ms_catalog_entry *found = ms_catalog_find(&catalog, name);
    int status = EXIT_SUCCESS;
    if (!found) {
        fprintf(stderr, "meshbake: no model '%s' in %s/catalog.json\n", name, dir);
        status = EXIT_INPUT;
    } else if (bits > found->bits) {
        fprintf(stderr, "meshbake: model '%s' has %u bits; --set-public-bits %u is more\n", name,
                found->bits, bits);
        status = EXIT_INPUT;
    } else {
        ms_catalog_entry e = *found;
        unsigned before = e.public_max_bits;
        e.public_max_bits = (uint8_t)bits;
        /* a coarser preview than the picture shows: a new picture first, so
         * that the file never shows more than the catalogue allows */
        if (e.has_thumbnail && e.thumbnail_bits > bits) {
            ms_study_thumbnail_report tr;
            ms_error terr;
            if (ms_bake_thumbnail(dir, &e, up_axis, threads, &tr, &terr) != MS_OK)
                fprintf(stderr, "meshbake: no thumbnail: %s\n", terr.text);
        }
        if (ms_catalog_update(dir, &e, &err) != MS_OK) {
            fprintf(stderr, "meshbake: %s\n", err.text);
            status = EXIT_INPUT;
        } else {
            printf("meshbake: model '%s': public_max_bits %u -> %u (SIGHUP a running meshserve "
                   "to apply it)\n", name, before, bits);
        }
    }
    ms_catalog_free(&catalog);
    return status;
}

/* The catalogue of a directory, each archive opened (which validates its
 * header and index) and every payload checked against its CRC. */
int ms_bake_cli_list(const char *dir, bool json)
{
    ms_catalog catalog;
    ms_error err;
    if (ms_catalog_load(dir, &catalog, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    json_t *models = json_array();
    size_t failed = 0;
    if (!json)
        printf("%-24s %12s %7s %12s %10s %8s  %s\n", "model", "triangles", "cells", "bytes",
               "colour", "preview", "checksums");
    for (size_t i = 0; i < catalog.count; ++i) {
        const ms_catalog_entry *e = &catalog.entries[i];
        char path[4200], problem[MS_ERROR_TEXT_MAX + 80] = "";
        snprintf(path, sizeof path, "%s/%s.msa", dir, e->name);
        ms_archive *a = NULL;
        uint64_t file_bytes = 0, colour_bytes = 0;
        if (ms_archive_open(path, &a, &err) != MS_OK) {
            snprintf(problem, sizeof problem, "%s", err.text);
        } else {
            const ms_archive_header *h = ms_archive_get_header(a);
            file_bytes = h->file_size;
            for (uint32_t cell = 0; cell < h->cell_count && !problem[0]; ++cell) {
                colour_bytes += ms_archive_colour_length(a, cell);
                if (ms_archive_verify_payload(a, cell, &err) != MS_OK)
                    snprintf(problem, sizeof problem, "%s.msa: %s", e->name, err.text);
            }
            ms_archive_close(a);
        }
        failed += problem[0] != 0;
        unsigned preview = e->public_max_bits < e->bits ? e->public_max_bits : e->bits;
        if (json) {
            json_array_append_new(
                models, json_pack("{s:o, s:I, s:I, s:i, s:I, s:I, s:i, s:i, s:b, s:s, s:b, s:o}",
                                  "name", ms_json_text(e->name), "triangles",
                                  (json_int_t)e->triangles, "vertices", (json_int_t)e->vertices,
                                  "cells", (int)e->cells, "bytes", (json_int_t)file_bytes,
                                  "colour_bytes", (json_int_t)colour_bytes,
                                  "bits", (int)e->bits, "public_bits", (int)preview, "apo",
                                  e->apo, "baked_at", e->baked_at, "ok", !problem[0], "error",
                                  ms_json_text(problem)));
        } else {
            char preview_text[16];
            if (preview >= e->bits)
                snprintf(preview_text, sizeof preview_text, "all");
            else
                snprintf(preview_text, sizeof preview_text, "%u/%u", preview, e->bits);
            char colour_text[24] = "-";
            if (colour_bytes)
                snprintf(colour_text, sizeof colour_text, "%" PRIu64, colour_bytes);
            printf("%-24s %12" PRIu64 " %7u %12" PRIu64 " %10s %8s  %s\n", e->name, e->triangles,
                   e->cells, file_bytes, colour_text, preview_text, problem[0] ? "FAILED" : "ok");
            if (problem[0])
                fprintf(stderr, "meshbake: %s\n", problem);
        }
    }
    if (json)
        ms_json_print(stdout,
                      json_pack("{s:o, s:I, s:I, s:o}", "directory", ms_json_text(dir), "count",
                                (json_int_t)catalog.count, "failed", (json_int_t)failed, "models",
                                models),
                      MS_JSON_SPACED);
    else
        json_decref(models);
    ms_catalog_free(&catalog);
    return failed ? EXIT_INPUT : EXIT_SUCCESS;
}

/* The catalogue entry of model name in dir, copied into *entry without its
 * strings (source and metadata NULL); EXIT_SUCCESS, or the exit status after
 * one line on stderr (a bad name, an unreadable catalogue, no such model). */
static int find_model(const char *dir, const char *name, ms_catalog_entry *entry)
{
    if (!ms_model_name_valid(name)) {
        fprintf(stderr, "meshbake: '%s' is not a model name\n", name);
        return EXIT_USAGE;
    }
    ms_catalog catalog;
    ms_error err;
    if (ms_catalog_load(dir, &catalog, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    const ms_catalog_entry *found = ms_catalog_find(&catalog, name);
    if (found) {
        *entry = *found;
        entry->source = NULL;
        entry->metadata = NULL;
    }
    ms_catalog_free(&catalog);
    if (!found) {
        fprintf(stderr, "meshbake: no model '%s' in %s/catalog.json\n", name, dir);
        return EXIT_INPUT;
    }
    return EXIT_SUCCESS;
}

/* Takes a model out of a directory: the catalogue entry first (renamed into
 * place under the lock, so a rescan that follows no longer offers it), then
 * the file (a running server's mapping keeps the old inode alive). */
int ms_bake_cli_remove(const char *dir, const char *name)
{
    ms_catalog_entry e;
    int status = find_model(dir, name, &e);
    if (status != EXIT_SUCCESS)
        return status;
    ms_error err;
    if (ms_catalog_remove(dir, name, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    char path[4200];
    ms_bake_thumbnail_path(dir, name, path, sizeof path);
    if (unlink(path) != 0 && errno != ENOENT)
        fprintf(stderr, "meshbake: %s: cannot remove: %s\n", path, strerror(errno));
    ms_annotations_sidecar_path(dir, name, path, sizeof path);
    if (unlink(path) != 0 && errno != ENOENT)
        fprintf(stderr, "meshbake: %s: cannot remove: %s\n", path, strerror(errno));
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    if (unlink(path) != 0 && errno != ENOENT) {
        fprintf(stderr, "meshbake: %s: cannot remove: %s\n", path, strerror(errno));
        return EXIT_INPUT;
    }
    printf("meshbake: model '%s' removed from %s (SIGHUP a running meshserve to apply it)\n",
           name, dir);
    return EXIT_SUCCESS;
}


int ms_bake_cli_thumbnail(const char *dir, const char *name, int up_axis, unsigned threads,
                          bool json)
{
    /* without its strings: an update without metadata keeps the entry's */
    ms_catalog_entry e;
    int status = find_model(dir, name, &e);
    if (status != EXIT_SUCCESS)
        return status;
    ms_error err;
    ms_study_thumbnail_report r;
    ms_status st = ms_bake_thumbnail(dir, &e, up_axis, threads, &r, &err);
    ms_error update_err;
    /* the entry says what is on disk now, the picture or none */
    ms_status recorded = ms_catalog_update_thumbnail(dir, name, e.has_thumbnail,
                                                     e.thumbnail_bits, e.thumbnail_up,
                                                     &update_err);
    if (st != MS_OK || recorded != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", st != MS_OK ? err.text : update_err.text);
        return EXIT_INPUT;
    }
    char path[4200];
    ms_bake_thumbnail_path(dir, name, path, sizeof path);
    if (json)
        ms_json_print(stdout,
                      json_pack("{s:o, s:o, s:i, s:i, s:i, s:I, s:I, s:f}", "name",
                                ms_json_text(name), "thumbnail", ms_json_text(path), "width",
                                (int)r.width, "height", (int)r.height, "bits", (int)e.thumbnail_bits,
                                "triangles", (json_int_t)r.triangles, "bytes",
                                (json_int_t)r.png_bytes, "seconds", r.seconds),
                      MS_JSON_COMPACT);
    else
        printf("meshbake: %s: %ux%u, %" PRIu64 " bytes, %" PRIu64 " triangles at %u bits, "
               "%.2f s\n", path, r.width, r.height, r.png_bytes, r.triangles,
               (unsigned)e.thumbnail_bits, r.seconds);
    return fflush(stdout) == 0 ? EXIT_SUCCESS : EXIT_INPUT;
}

int ms_bake_cli_annotations(const char *dir, const char *name, const char *file, bool json)
{
    ms_catalog_entry e;
    int status = find_model(dir, name, &e);
    if (status != EXIT_SUCCESS)
        return status;
    ms_annotations *set;
    ms_error err;
    if (ms_annotations_load(file, &set, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    char path[4200];
    ms_annotations_sidecar_path(dir, name, path, sizeof path);
    ms_status st = ms_annotations_save(set, path, &err);
    size_t count = ms_annotations_count(set);
    ms_annotations_free(set);
    if (st != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    if (json)
        ms_json_print(stdout,
                      json_pack("{s:o, s:o, s:I}", "name", ms_json_text(name), "annotations",
                                ms_json_text(path), "count", (json_int_t)count),
                      MS_JSON_COMPACT);
    else
        printf("meshbake: %s: %zu annotation%s installed\n", path, count, count == 1 ? "" : "s");
    return fflush(stdout) == 0 ? EXIT_SUCCESS : EXIT_INPUT;
}
