/* meshexport: writes a model's archive as the static file tree of meshserve's
 * HTTP side door, so any static web server (nginx, a CDN) can serve the same
 * bytes at the same paths. */
#include <errno.h>
#include <getopt.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ms_access.h"
#include "ms_cli.h"
#include "ms_archive.h"
#include "ms_catalog.h"
#include "ms_export_site.h"
#include "ms_model_document.h"
#include "ms_json_out.h"
#include "ms_progress.h"
#include "ms_registry.h"
#include "ms_subtree.h"
#include "ms_version.h"

static void usage(FILE *out)
{
    fprintf(out,
            "Usage: meshexport ARCHIVE_DIR NAME -o OUT_DIR [--full] [--web-dir DIR] [--json]\n"
            "Writes model NAME of ARCHIVE_DIR as static files laid out like meshserve's HTTP\n"
            "side door: OUT_DIR/models/NAME.index (header and cell index, served at\n"
            "/models/NAME), OUT_DIR/models/NAME.head (the index head, served at\n"
            "/models/NAME/head), OUT_DIR/models/NAME/subtrees/ID (the index in subtrees),\n"
            "OUT_DIR/models/NAME/cells/ID/geometry, .../apo and .../colour (prefixes are byte\n"
            "ranges of these files, served with Range by any static web server), and the\n"
            "model's documents as meshserve serves them: OUT_DIR/models/NAME/thumbnail.png\n"
            "(where its rule gives it to every reader) and .../annotations.json (an empty\n"
            "set where the model has none).\n"
            "Only what an anonymous reader may read is written: a model with a public\n"
            "preview (catalogue public_max_bits) gets each geometry and colour stream cut at\n"
            "the preview, each\n"
            "APO chunk cut to the levels no finer than the preview, and no files for cells\n"
            "wholly beyond it.\n\n"
            "  -o, --output DIR   where to write (created; existing files are replaced)\n"
            "      --full         write every byte, as a token holder reads them (for a\n"
            "                     server that is itself access-controlled)\n"
            "      --web-dir DIR  also write the browser pages of DIR (make wasm: build/wasm/site)\n"
            "                     beside the model: OUT_DIR/index.html, OUT_DIR/view/NAME.html,\n"
            "                     OUT_DIR/web/ and OUT_DIR/catalog.json (every model exported\n"
            "                     there), so a plain web server serves the viewer too\n"
            "                     (docs/BROWSER.md)\n"
            "      --json         print the summary as one JSON object\n"
            "  -h, --help         show this help\n"
            "      --version      show the version\n");
}

static int make_dir(const char *path)
{
    return mkdir(path, 0755) == 0 || errno == EEXIST ? 0 : -1;
}

static int write_file(const char *path, const uint8_t *data, size_t size)
{
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return -1;
    int failed = (size && fwrite(data, 1, size, f) != size);
    failed |= fclose(f) != 0;
    if (failed || rename(tmp, path) != 0) {
        remove(tmp);
        return -1;
    }
    return 0;
}

/* What a model without annotations exports: an empty set, so that a static
 * server answers the page's request with a document, not a 404. */
static const char no_annotations[] =
    "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": []}\n";

/* The model's thumbnail and annotations, as both doors serve them (the same
 * read, under the same rule: ms_model_document_read_entry), to
 * OUT/models/NAME/thumbnail.png and annotations.json. A picture that no
 * reader may have, or that the model has not, removes what an earlier export
 * left; a model without annotations gets the empty set. *thumbnail: whether
 * the picture was written. 0, -1 when a file could not be written, or 1
 * after printing an error. */
static int export_documents(const ms_model *model, const char *archive_dir, const char *out_dir,
                            const char *name, bool *thumbnail, uint64_t *bytes, uint64_t *files)
{
    static const struct {
        int kind;
        const char *file;
    } documents[] = {{MS_DOCUMENT_THUMBNAIL, "thumbnail.png"},
                     {MS_DOCUMENT_ANNOTATIONS, "annotations.json"}};
    *thumbnail = false;
    for (size_t i = 0; i < sizeof documents / sizeof documents[0]; ++i) {
        bool picture = documents[i].kind == MS_DOCUMENT_THUMBNAIL;
        char path[4200];
        snprintf(path, sizeof path, "%s/models/%s/%s", out_dir, name, documents[i].file);
        ms_model_document doc;
        ms_document_refusal refusal;
        ms_error err;
        if (ms_model_document_read_entry(&model->entry, archive_dir, documents[i].kind, &doc, &refusal,
                                         &err) != MS_OK) {
            if (refusal != MS_DOCUMENT_ABSENT) {
                fprintf(stderr, "meshexport: %s: %s\n", documents[i].file, err.text);
                return 1;
            }
            if (picture) {
                if (remove(path) != 0 && errno != ENOENT)
                    return -1;
                continue;
            }
            doc.bytes = NULL;
            doc.length = 0;
        }
        const uint8_t *data = doc.bytes ? doc.bytes : (const uint8_t *)no_annotations;
        size_t length = doc.bytes ? doc.length : sizeof no_annotations - 1;
        int failed = write_file(path, data, length);
        ms_model_document_free(&doc);
        if (failed)
            return -1;
        *bytes += length, (*files)++;
        *thumbnail |= picture;
    }
    return 0;
}

/* Writes the files of cell (or, for a cell the grant hides, removes those an
 * earlier --full export left). 0, -1 when a file could not be written, or 1
 * after printing an error of the archive. */
static int export_cell(ms_model *model, const ms_access *grant, const char *archive_dir,
                       const char *out_dir, const char *name, uint32_t cell, uint64_t *bytes,
                       uint64_t *files)
{
    const ms_archive *a = model->archive;
    static const char *const kinds[3] = {"geometry", "apo", "colour"};
    char path[4096];
    size_t size;
    ms_error err;
    int failed = 0;
    if (ms_archive_verify_payload(a, cell, &err) != MS_OK) {
        fprintf(stderr, "meshexport: %s: %s\n", archive_dir, err.text);
        return 1;
    }
    if (ms_access_cell_hidden(model, grant, cell)) {
        /* An earlier --full export into OUT_DIR must not stay behind. */
        for (int k = 0; k < 3; ++k) {
            snprintf(path, sizeof path, "%s/models/%s/cells/%u/%s", out_dir, name, cell, kinds[k]);
            remove(path);
        }
        snprintf(path, sizeof path, "%s/models/%s/cells/%u", out_dir, name, cell);
        rmdir(path);
        return 0;
    }
    snprintf(path, sizeof path, "%s/models/%s/cells/%u", out_dir, name, cell);
    failed |= make_dir(path);
    /* geometry, APO and colour (docs/ARCHIVE.md): colour follows the
     * geometric preview (ms_access.h), as its stream's steps are bits */
    for (int k = 0; k < 3 && !failed; ++k) {
        bool apo = k == 1, colour = k == 2;
        uint8_t permitted = apo ? ms_access_cell_apo_steps(model, grant, cell)
                                : grant->permitted_geometry_steps;
        const uint8_t *data = apo      ? ms_archive_apo(a, cell, &size)
                              : colour ? ms_archive_colour(a, cell, &size)
                                       : ms_archive_geometry(a, cell, &size);
        if ((apo || colour) && (!size || !permitted)) {
            /* no APO chunk or colour stream, or none of it under the preview:
             * nor one an earlier --full export left */
            snprintf(path, sizeof path, "%s/models/%s/cells/%u/%s", out_dir, name, cell, kinds[k]);
            remove(path);
            continue;
        }
        ms_proto_cell_request all = {cell,
                                     apo      ? MS_PROTO_STREAM_APO
                                     : colour ? MS_PROTO_STREAM_COLOUR
                                              : MS_PROTO_STREAM_GEOMETRY,
                                     MS_PROTO_UNIT_STEPS, 0, 0, permitted - 1u};
        if (all.b > MS_PROTO_MAX_STEP)
            all.b = MS_PROTO_MAX_STEP;
        ms_proto_byte_range range;
        if (ms_access_resolve(model, grant, &all, &range, NULL, &err) != MS_OK) {
            fprintf(stderr, "meshexport: %s: cell %u: %s\n", archive_dir, cell, err.text);
            return 1;
        }
        snprintf(path, sizeof path, "%s/models/%s/cells/%u/%s", out_dir, name, cell, kinds[k]);
        failed |= write_file(path, data, range.end);
        *bytes += range.end, (*files)++;
    }
    return failed;
}

/* The index head at models/NAME.head (served at /models/NAME/head, which a
 * static server maps like NAME.index) and every stored subtree at
 * models/NAME/subtrees/ID: the index, which anyone who may open the model
 * reads whole. 0, or -1 when a file could not be written. */
static int export_subtrees(const ms_archive *a, const char *out_dir, const char *name,
                           uint64_t *bytes, uint64_t *files)
{
    char path[4096];
    size_t size;
    const uint8_t *head = ms_archive_index_head(a, &size);
    snprintf(path, sizeof path, "%s/models/%s.head", out_dir, name);
    if (!head || write_file(path, head, size) != 0)
        return -1;
    *bytes += size, (*files)++;
    snprintf(path, sizeof path, "%s/models/%s/subtrees", out_dir, name);
    if (make_dir(path) != 0)
        return -1;
    uint32_t *ids;
    size_t count;
    ms_error err;
    if (ms_subtree_list(a, ms_archive_subtree_levels(a), &ids, &count, &err) != MS_OK)
        return -1;
    int failed = 0;
    for (size_t i = 0; !failed && i < count; ++i) {
        const uint8_t *stored = ms_archive_subtree(a, ids[i], &size);
        snprintf(path, sizeof path, "%s/models/%s/subtrees/%u", out_dir, name, ids[i]);
        failed = !stored || write_file(path, stored, size) != 0;
        *bytes += size, (*files)++;
    }
    free(ids);
    return failed ? -1 : 0;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshexport");
    static const struct option options[] = {
        {"output", required_argument, NULL, 'o'},
        {"json", no_argument, NULL, 'j'},
        {"full", no_argument, NULL, 'f'},
        {"web-dir", required_argument, NULL, 'w'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    const char *out_dir = NULL, *web_dir = NULL;
    bool json = false, full = false;
    int c;
    while ((c = ms_cli_next("meshexport", argc, argv, "o:h", options)) != -1) {
        switch (c) {
        case 'o': out_dir = optarg; break;
        case 'j': json = true; break;
        case 'f': full = true; break;
        case 'w': web_dir = optarg; break;
        case 'h': usage(stdout); return 0;
        default: return MS_CLI_USAGE; /* reported by ms_cli_next */
        }
    }
    if (optind != argc - 2 || !out_dir) {
        fprintf(stderr, "meshexport: expected ARCHIVE_DIR NAME -o OUT_DIR (try 'meshexport --help')\n");
        return 2;
    }
    const char *archive_dir = argv[optind], *name = argv[optind + 1];
    if (!ms_model_name_valid(name)) {
        fprintf(stderr, "meshexport: invalid model name '%s'\n", name);
        return 2;
    }
    char path[4096];
    ms_catalog catalog;
    ms_error err;
    if (ms_catalog_load(archive_dir, &catalog, &err) != MS_OK) {
        fprintf(stderr, "meshexport: %s\n", err.text);
        return 1;
    }
    const ms_catalog_entry *entry = ms_catalog_find(&catalog, name);
    ms_model *model = NULL;
    if (!entry)
        ms_error_set(&err, MS_ERR_ARG, "model '%s' is not in %s/catalog.json", name, archive_dir);
    ms_status opened = entry ? ms_model_open(archive_dir, entry, &model, &err) : MS_ERR_ARG;
    ms_catalog_free(&catalog);
    if (opened != MS_OK) {
        fprintf(stderr, "meshexport: %s\n", err.text);
        return 1;
    }
    const ms_archive *a = model->archive;
    /* The same grant and the same resolution as meshserve's doors. */
    const ms_access grant = ms_access_grant(model, full);
    double start = ms_now_seconds();
    const ms_archive_header *h = ms_archive_get_header(a);
    int failed = 0;
    uint64_t bytes = 0, files = 0;
    /* The index is served at models/NAME and the cells under models/NAME/cells/,
     * so "models/NAME" would have to be both a file and a directory: the index
     * goes to models/NAME.index and a static server maps the path (see
     * scripts/bench-serve for the nginx rule). */
    snprintf(path, sizeof path, "%s", out_dir);
    failed |= make_dir(path);
    snprintf(path, sizeof path, "%s/models", out_dir);
    failed |= make_dir(path);
    snprintf(path, sizeof path, "%s/models/%s", out_dir, name);
    failed |= make_dir(path);
    snprintf(path, sizeof path, "%s/models/%s/cells", out_dir, name);
    failed |= make_dir(path);
    size_t size;
    const uint8_t *index = ms_archive_index_bytes(a, &size);
    snprintf(path, sizeof path, "%s/models/%s.index", out_dir, name);
    failed |= write_file(path, index, size);
    bytes += size, files++;
    failed |= export_subtrees(a, out_dir, name, &bytes, &files);
    ms_progress progress;
    ms_progress_init(&progress, stderr, "meshexport", h->cell_count);
    for (uint32_t cell = 0; !failed && cell < h->cell_count; ++cell) {
        int r = export_cell(model, &grant, archive_dir, out_dir, name, cell, &bytes, &files);
        if (r > 0) {
            ms_model_unref(model);
            return 1;
        }
        failed |= r;
        ms_progress_update(&progress, cell);
    }
    ms_progress_finish(&progress);
    if (failed) {
        ms_model_unref(model);
        fprintf(stderr, "meshexport: cannot write under %s: %s\n", out_dir, strerror(errno));
        return 1;
    }
    bool thumbnail = false;
    int documents = export_documents(model, archive_dir, out_dir, name, &thumbnail, &bytes, &files);
    if (documents != 0) {
        ms_model_unref(model);
        if (documents < 0)
            fprintf(stderr, "meshexport: cannot write under %s: %s\n", out_dir, strerror(errno));
        return 1;
    }
    ms_status site = web_dir ? ms_export_site(web_dir, out_dir, &model->entry, full, thumbnail, &bytes,
                                              &files, &err)
                             : MS_OK;
    ms_model_unref(model);
    if (site != MS_OK) {
        fprintf(stderr, "meshexport: %s\n", err.text);
        return 1;
    }
    double seconds = ms_now_seconds() - start;
    if (json)
        ms_json_print(stdout, json_pack("{s:o, s:I, s:I, s:o}", "model", ms_json_text(name), "files",
                                        (json_int_t)files, "bytes", (json_int_t)bytes, "seconds", ms_json_fixed(seconds, 3)),
                      MS_JSON_SPACED);
    else
        printf("meshexport: %s: %llu files, %llu bytes in %.2f s\n", name,
               (unsigned long long)files, (unsigned long long)bytes, seconds);
    return 0;
}
