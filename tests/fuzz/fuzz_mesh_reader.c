/* libFuzzer target on the mesh readers (common/mesh: PLY ascii and binary, OBJ,
 * OFF, gzip or not; docs/INPUT.md), vertex colour included.
 *
 * Input: a file's bytes, written to a scratch file (the readers take a path).
 * Besides the sanitizers, the target checks the readers' contract and aborts
 * when it is broken: a file accepted by ms_mesh_load has at least one triangle,
 * every index in range, finite positions, colours exactly when the streaming
 * reader says so (one colour handed over per vertex), and alpha 255 everywhere
 * when the file had no alpha; a refused file leaves the mesh empty and a one-line
 * error naming the file.
 *
 * tests/test_fuzz_replay.c includes this file to replay tests/corpus/mesh_reader/
 * in `make test`; it then calls ms_fuzz_mesh_reader_one() directly. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_mesh_io.h"
#include "ms_mesh_reader.h"

#define MS_FUZZ_MESH_CHECK(cond)                                                               \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_mesh_reader: contract broken: %s (%s:%d)\n", #cond,         \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* The scratch folder, made on first use (the fuzzer's process, or the replay's). */
static char ms_fuzz_mesh_dir[64];

typedef struct ms_fuzz_mesh_counts {
    uint64_t vertices, colours;
} ms_fuzz_mesh_counts;

static ms_status ms_fuzz_mesh_count_vertices(void *context, const double *positions, size_t count,
                                             ms_error *err)
{
    (void)positions, (void)err;
    ((ms_fuzz_mesh_counts *)context)->vertices += count;
    return MS_OK;
}

static ms_status ms_fuzz_mesh_count_colours(void *context, const uint8_t *rgba, size_t count,
                                            ms_error *err)
{
    (void)rgba, (void)err;
    ms_fuzz_mesh_counts *c = context;
    c->colours += count;
    MS_FUZZ_MESH_CHECK(c->colours == c->vertices); /* right after the same vertices */
    return MS_OK;
}

static bool ms_fuzz_mesh_one_line(const ms_error *err, const char *path)
{
    return err->text[0] != '\0' && !strchr(err->text, '\n') &&
           strncmp(err->text, path, strlen(path)) == 0;
}

/* Returns true when the file was accepted. */
static bool ms_fuzz_mesh_reader_one(const uint8_t *data, size_t size)
{
    if (!ms_fuzz_mesh_dir[0]) {
        snprintf(ms_fuzz_mesh_dir, sizeof ms_fuzz_mesh_dir, "/tmp/ms-fuzz-mesh.XXXXXX");
        MS_FUZZ_MESH_CHECK(mkdtemp(ms_fuzz_mesh_dir) != NULL);
    }
    char path[128];
    snprintf(path, sizeof path, "%s/input", ms_fuzz_mesh_dir);
    FILE *f = fopen(path, "wb");
    MS_FUZZ_MESH_CHECK(f && (size == 0 || fwrite(data, 1, size, f) == size) && fclose(f) == 0);

    ms_fuzz_mesh_counts counts = {0, 0};
    const ms_mesh_sink sink = {.context = &counts,
                               .vertices = ms_fuzz_mesh_count_vertices,
                               .colours = ms_fuzz_mesh_count_colours};
    ms_mesh_read_report report;
    ms_error err;
    ms_error_clear(&err);
    ms_status streamed = ms_mesh_read(path, &sink, &report, &err);
    if (streamed != MS_OK)
        MS_FUZZ_MESH_CHECK(ms_fuzz_mesh_one_line(&err, path));
    MS_FUZZ_MESH_CHECK(counts.colours == (report.colour ? counts.vertices : 0));
    MS_FUZZ_MESH_CHECK(!report.colour_alpha || report.colour);

    ms_mesh mesh;
    ms_error_clear(&err);
    ms_status loaded = ms_mesh_load(path, &mesh, NULL, &err);
    MS_FUZZ_MESH_CHECK(loaded == streamed);
    if (loaded != MS_OK) {
        MS_FUZZ_MESH_CHECK(ms_fuzz_mesh_one_line(&err, path));
        MS_FUZZ_MESH_CHECK(!mesh.positions && !mesh.triangles && !mesh.colours);
        return false;
    }
    MS_FUZZ_MESH_CHECK(mesh.vertex_count == report.vertices && mesh.triangle_count >= 1);
    for (size_t i = 0; i < 3 * mesh.vertex_count; ++i)
        MS_FUZZ_MESH_CHECK(isfinite(mesh.positions[i]));
    for (size_t i = 0; i < 3 * mesh.triangle_count; ++i)
        MS_FUZZ_MESH_CHECK(mesh.triangles[i] < mesh.vertex_count);
    MS_FUZZ_MESH_CHECK((mesh.colours != NULL) == report.colour);
    MS_FUZZ_MESH_CHECK(mesh.colour_alpha == report.colour_alpha);
    for (size_t v = 0; mesh.colours && !mesh.colour_alpha && v < mesh.vertex_count; ++v)
        MS_FUZZ_MESH_CHECK(mesh.colours[4 * v + 3] == 255);
    ms_mesh_free(&mesh);
    return true;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_mesh_reader_one(data, size);
    return 0;
}
#endif
