/* Helpers shared by the cmocka test programs. Include after cmocka.h. */
#ifndef MS_TEST_H
#define MS_TEST_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

/* Full path of a test model, written into buf: the first of $MESHSTREAM_MODELS
 * (when set), tests/data (the generated fixtures; tests run from the repository
 * root) and the cache scripts/fetch-models fills ($MESHSTREAM_MODEL_CACHE, default
 * ${XDG_CACHE_HOME:-$HOME/.cache}/meshstream/models) that holds the file. A model
 * found nowhere fails the test with one line naming scripts/fetch-models. */
const char *ms_test_model_path(char *buf, size_t size, const char *file);

/* Full path of a built program (MESHSTREAM_BIN, default build/asan/bin). */
const char *ms_test_bin_path(char *buf, size_t size, const char *program);

/* A fresh private directory under $TMPDIR for one test; the caller removes it with
 * ms_test_rmdir. Aborts the test on failure. */
const char *ms_test_tmpdir(char *buf, size_t size);
void ms_test_rmdir(const char *dir);

/* Runs a shell command line, capturing stdout+stderr into out (NUL-terminated,
 * truncated to size). Returns the exit status, or -1 if it did not exit normally. */
int ms_test_run(const char *command, char *out, size_t size);

/* Runs a command line (ms_test_run, up to 1 MiB of output) that must exit with
 * want_status and print one JSON document; returns it (json_decref it). Fails the
 * test otherwise, quoting the command and its output. */
json_t *ms_test_run_json(const char *command, int want_status);

/* Writes path: an OFF bumpy sphere of radius about `scale` (48 x 24 grid,
 * 2,256 triangles, closed), for tests that bake a small real model.
 * 0, or -1 when the file cannot be written. */
int ms_test_write_bumpy_sphere(const char *path, double scale);

/* Writes path: an OFF of two boxes, 24 triangles, outward-facing: the cube
 * [-1, 1]^3 and the small box [-0.8, -0.2] x [-2.5, -2] x [-0.8, -0.2] in
 * front of its y = -1 face (for the annotation tests: a marker behind it is
 * hidden from an eye on -y). 0, or -1 when the file cannot be written. */
int ms_test_write_two_boxes(const char *path);

/* A whole file into a malloc'd buffer (the caller frees it), and a buffer into
 * a file; both fail the test on any error. */
unsigned char *ms_test_read_file(const char *path, size_t *size);
void ms_test_write_file(const char *path, const void *data, size_t size);

/* Deterministic xorshift64 generator, so that a failing random test reproduces:
 * advances *state (never 0) and returns it. */
static inline uint64_t ms_test_random(uint64_t *state)
{
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    return *state;
}

#endif
