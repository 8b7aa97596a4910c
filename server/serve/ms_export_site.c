/* The browser pages beside a static export: see ms_export_site.h. */
#include "ms_export_site.h"

#include <dirent.h>
#include <errno.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "ms_http_door.h"
#include "ms_input_file.h"

enum { PAGE_FILE_MAX = 64u << 20 };

static ms_status make_dir(const char *path, ms_error *err)
{
    if (mkdir(path, 0755) == 0 || errno == EEXIST)
        return MS_OK;
    return ms_error_set(err, MS_ERR_IO, "cannot make %s: %s", path, strerror(errno));
}

/* Writes size bytes to path through path.partial, renamed over it. */
static ms_status write_whole(const char *path, const void *data, size_t size, ms_error *err)
{
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return ms_error_set(err, MS_ERR_IO, "cannot write %s: %s", tmp, strerror(errno));
    int failed = size && fwrite(data, 1, size, f) != size;
    failed |= fclose(f) != 0;
    if (failed || rename(tmp, path) != 0) {
        remove(tmp);
        return ms_error_set(err, MS_ERR_IO, "cannot write %s", path);
    }
    return MS_OK;
}

/* Copies the file from to the file to. */
static ms_status copy_file(const char *from, const char *to, uint64_t *bytes, uint64_t *files,
                           ms_error *err)
{
    FILE *in;
    ms_status st = ms_input_fopen(from, &in, err);
    if (st != MS_OK)
        return st;
    size_t capacity = 1 << 16, size = 0;
    char *data = malloc(capacity);
    while (data) {
        size += fread(data + size, 1, capacity - size, in);
        if (size < capacity || capacity >= PAGE_FILE_MAX)
            break;
        char *grown = realloc(data, capacity * 2);
        if (!grown) {
            free(data);
            data = NULL;
            break;
        }
        data = grown;
        capacity *= 2;
    }
    int failed = ferror(in);
    fclose(in);
    if (!data)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", from);
    if (failed || size == capacity) {
        free(data);
        return ms_error_set(err, MS_ERR_IO, "%s: %s", from,
                            failed ? "read error" : "larger than 64 MiB: not a page file");
    }
    st = write_whole(to, data, size, err);
    free(data);
    if (st == MS_OK)
        *bytes += size, (*files)++;
    return st;
}

/* Every page file of web_dir into out_dir/web, index.html to out_dir and
 * view.html to out_dir/view/NAME.html. */
static ms_status copy_pages(const char *web_dir, const char *out_dir, const char *name,
                            uint64_t *bytes, uint64_t *files, ms_error *err)
{
    char from[4200], to[4200];
    const char *needed[] = {"index.html", "view.html"};
    for (int i = 0; i < 2; ++i) {
        struct stat st;
        snprintf(from, sizeof from, "%s/%s", web_dir, needed[i]);
        if (stat(from, &st) != 0 || !S_ISREG(st.st_mode))
            return ms_error_set(err, MS_ERR_ARG, "%s: no %s: not a folder of the browser pages "
                                "(make wasm builds them into build/wasm/site)", web_dir, needed[i]);
    }
    snprintf(to, sizeof to, "%s/web", out_dir);
    ms_status st = make_dir(to, err);
    snprintf(to, sizeof to, "%s/view", out_dir);
    if (st == MS_OK)
        st = make_dir(to, err);
    DIR *dir = st == MS_OK ? opendir(web_dir) : NULL;
    if (st == MS_OK && !dir)
        return ms_error_set(err, MS_ERR_IO, "cannot read %s: %s", web_dir, strerror(errno));
    for (struct dirent *e; st == MS_OK && (e = readdir(dir));) {
        if (!ms_http_page_type(e->d_name))
            continue;
        snprintf(from, sizeof from, "%s/%s", web_dir, e->d_name);
        snprintf(to, sizeof to, "%s/web/%s", out_dir, e->d_name);
        st = copy_file(from, to, bytes, files, err);
    }
    if (dir)
        closedir(dir);
    snprintf(from, sizeof from, "%s/index.html", web_dir);
    snprintf(to, sizeof to, "%s/index.html", out_dir);
    if (st == MS_OK)
        st = copy_file(from, to, bytes, files, err);
    snprintf(from, sizeof from, "%s/view.html", web_dir);
    snprintf(to, sizeof to, "%s/view/%s.html", out_dir, name);
    if (st == MS_OK)
        st = copy_file(from, to, bytes, files, err);
    return st;
}

static int by_name(const void *a, const void *b)
{
    const char *x = json_string_value(json_object_get(*(json_t *const *)a, "name"));
    const char *y = json_string_value(json_object_get(*(json_t *const *)b, "name"));
    return strcmp(x ? x : "", y ? y : "");
}

/* out_dir/catalog.json with entry added or replaced: {"version": 1, "total",
 * "offset": 0, "limit": total, "models": [...]} by name, as GET /catalog. */
static ms_status write_catalogue(const char *out_dir, const ms_catalog_entry *entry, bool full,
                                 bool thumbnail, uint64_t *bytes, uint64_t *files, ms_error *err)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/catalog.json", out_dir);
    json_t *old = NULL;
    struct stat st;
    if (stat(path, &st) == 0) {
        json_error_t jerr;
        old = json_load_file(path, 0, &jerr);
        if (!old || !json_is_array(json_object_get(old, "models"))) {
            json_decref(old);
            return ms_error_set(err, MS_ERR_FORMAT, "%s: not a catalogue meshexport wrote", path);
        }
    }
    json_t *models = json_array(), *mine = ms_http_catalog_entry(entry);
    if (!models || !mine) {
        json_decref(old), json_decref(models), json_decref(mine);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    }
    if (full) /* every byte is in the tree: the reader needs no token */
        json_object_set_new(mine, "public_max_bits", json_integer(entry->bits));
    /* the picture's path in the export (meshserve's is models/NAME/thumbnail),
     * or none */
    char picture[128];
    snprintf(picture, sizeof picture, "models/%s/thumbnail.png", entry->name);
    json_object_set_new(mine, "thumbnail", thumbnail ? json_string(picture) : json_false());
    /* the model's viewer page in the export (meshserve's is view/NAME) */
    char page[128];
    snprintf(page, sizeof page, "view/%s.html", entry->name);
    json_object_set_new(mine, "view", json_string(page));
    size_t i;
    json_t *m;
    json_array_foreach(old ? json_object_get(old, "models") : NULL, i, m) {
        const char *n = json_string_value(json_object_get(m, "name"));
        if (json_is_object(m) && n && strcmp(n, entry->name))
            json_array_append(models, m);
    }
    json_array_append_new(models, mine);
    json_decref(old);
    size_t count = json_array_size(models);
    json_t **sorted = malloc(count * sizeof *sorted);
    json_t *ordered = json_array();
    if (sorted && ordered) {
        for (i = 0; i < count; ++i)
            sorted[i] = json_array_get(models, i);
        qsort(sorted, count, sizeof *sorted, by_name);
        for (i = 0; i < count; ++i)
            json_array_append(ordered, sorted[i]);
    }
    free(sorted);
    json_decref(models);
    json_t *root = ordered ? json_pack("{s:i, s:I, s:i, s:I, s:o}", "version", 1, "total",
                                       (json_int_t)count, "offset", 0, "limit", (json_int_t)count,
                                       "models", ordered)
                           : NULL;
    char *text = root ? json_dumps(root, JSON_INDENT(2) | JSON_SORT_KEYS) : NULL;
    json_decref(root);
    if (!text)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    size_t length = strlen(text);
    text[length] = '\n'; /* json_dumps' NUL becomes the last line's end */
    ms_status written = write_whole(path, text, length + 1, err);
    free(text);
    if (written == MS_OK)
        *bytes += length + 1, (*files)++;
    return written;
}

ms_status ms_export_site(const char *web_dir, const char *out_dir, const ms_catalog_entry *entry,
                         bool full, bool thumbnail, uint64_t *bytes, uint64_t *files, ms_error *err)
{
    ms_status st = copy_pages(web_dir, out_dir, entry->name, bytes, files, err);
    return st != MS_OK ? st : write_catalogue(out_dir, entry, full, thumbnail, bytes, files, err);
}
