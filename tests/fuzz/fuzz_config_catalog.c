/* libFuzzer target on two readers of operator files: meshserve's config file
 * (server/serve/ms_server_config.c, ms_server_config_load) and the archive
 * directory's catalog.json (common/archive/ms_catalog.c, ms_catalog_load).
 *
 * Input: one control byte (bit 0: 0 config, 1 catalogue), then the file's
 * bytes, written to a private temporary directory and read back through the
 * same functions meshserve calls. Besides the sanitizers, the target checks
 * the readers' contracts and aborts when one is broken: a refused file gives a
 * one-line error (and an empty catalogue); an accepted config holds only
 * values in their documented ranges; an accepted catalogue is sorted by name,
 * with valid names and no more than MS_CATALOG_MAX_ENTRIES entries.
 *
 * tests/test_fuzz_replay.c includes this file to replay
 * tests/corpus/config_catalog/ in `make test`; it then calls
 * ms_fuzz_config_catalog_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_catalog.h"
#include "ms_server_config.h"

#define MS_FUZZ_FILES_CHECK(cond)                                                              \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_config_catalog: contract broken: %s (%s:%d)\n", #cond,      \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

static bool one_line(const ms_error *err) { return err->text[0] && !strchr(err->text, '\n'); }

/* The temporary directory, made once per process (a harness's only state;
 * test_fuzz_replay removes it). */
static char ms_fuzz_files_dir[64];

/* Writes data to DIR/name in that directory. */
static const char *fuzz_file(const char *name, const uint8_t *data, size_t size, char *dir_out,
                             size_t dir_size)
{
    char *dir = ms_fuzz_files_dir;
    if (!dir[0]) {
        snprintf(dir, sizeof ms_fuzz_files_dir, "/tmp/ms-fuzz-files.XXXXXX");
        MS_FUZZ_FILES_CHECK(mkdtemp(dir) != NULL);
    }
    static char path[128];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    MS_FUZZ_FILES_CHECK(f && (size == 0 || fwrite(data, 1, size, f) == size) && fclose(f) == 0);
    snprintf(dir_out, dir_size, "%s", dir);
    return path;
}

/* Returns true when the file was accepted. */
static bool ms_fuzz_config_catalog_one(const uint8_t *data, size_t size)
{
    if (size < 1)
        return false;
    bool catalogue = data[0] & 1;
    char dir[64];
    ms_error err;
    ms_error_clear(&err);
    if (!catalogue) {
        const char *path = fuzz_file("meshserve.conf", data + 1, size - 1, dir, sizeof dir);
        ms_server_config c;
        ms_server_config_defaults(&c);
        bool ok = ms_server_config_load(&c, path, &err) == MS_OK;
        if (!ok) {
            MS_FUZZ_FILES_CHECK(one_line(&err));
        } else {
            MS_FUZZ_FILES_CHECK(c.port <= 65535 && c.http_port <= 65535);
            MS_FUZZ_FILES_CHECK(c.max_clients >= 1 && c.max_clients <= 100000);
            MS_FUZZ_FILES_CHECK(c.idle_timeout_s >= 1 && c.send_timeout_s >= 1);
            MS_FUZZ_FILES_CHECK(c.max_frame >= 16384 && c.max_frame <= (16u << 20));
            MS_FUZZ_FILES_CHECK(c.max_batch >= 1 && c.max_outstanding >= 1);
            MS_FUZZ_FILES_CHECK(c.http_max_connections >= 1 && c.http_header_timeout_s >= 1);
            if (c.token) {
                size_t n = strlen(c.token);
                MS_FUZZ_FILES_CHECK(n >= 1 && n <= 256);
                for (size_t i = 0; i < n; ++i)
                    MS_FUZZ_FILES_CHECK(c.token[i] > 0x20 && c.token[i] < 0x7f);
            }
        }
        ms_server_config_free(&c);
        return ok;
    }
    fuzz_file("catalog.json", data + 1, size - 1, dir, sizeof dir);
    ms_catalog catalog;
    bool ok = ms_catalog_load(dir, &catalog, &err) == MS_OK;
    if (!ok) {
        MS_FUZZ_FILES_CHECK(one_line(&err));
        return false;
    }
    MS_FUZZ_FILES_CHECK(catalog.count <= MS_CATALOG_MAX_ENTRIES);
    for (size_t i = 0; i < catalog.count; ++i) {
        const ms_catalog_entry *e = &catalog.entries[i];
        MS_FUZZ_FILES_CHECK(ms_model_name_valid(e->name));
        MS_FUZZ_FILES_CHECK(i == 0 || strcmp(catalog.entries[i - 1].name, e->name) < 0);
        MS_FUZZ_FILES_CHECK(ms_catalog_find(&catalog, e->name) == e);
    }
    ms_catalog_free(&catalog);
    return true;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_config_catalog_one(data, size);
    return 0;
}
#endif
