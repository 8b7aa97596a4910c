#include "ms_test.h"

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

/* The folder scripts/fetch-models fills (scripts/models.sh computes the same). */
static void model_cache_dir(char *buf, size_t size)
{
    const char *cache = getenv("MESHSTREAM_MODEL_CACHE");
    const char *xdg = getenv("XDG_CACHE_HOME");
    const char *home = getenv("HOME");
    if (cache && *cache)
        snprintf(buf, size, "%s", cache);
    else if (xdg && *xdg)
        snprintf(buf, size, "%s/meshstream/models", xdg);
    else
        snprintf(buf, size, "%s/.cache/meshstream/models", home ? home : "");
}

const char *ms_test_model_path(char *buf, size_t size, const char *file)
{
    char cache[4096];
    model_cache_dir(cache, sizeof cache);
    const char *override = getenv("MESHSTREAM_MODELS");
    const char *const dirs[] = {override && *override ? override : NULL, "tests/data", cache};
    for (size_t i = 0; i < sizeof dirs / sizeof dirs[0]; ++i) {
        if (!dirs[i])
            continue;
        snprintf(buf, size, "%s/%s", dirs[i], file);
        if (access(buf, R_OK) == 0)
            return buf;
    }
    fail_msg("model %s not found: run scripts/fetch-models", file);
    return buf;
}

const char *ms_test_bin_path(char *buf, size_t size, const char *program)
{
    const char *dir = getenv("MESHSTREAM_BIN");
    snprintf(buf, size, "%s/%s", dir ? dir : "build/asan/bin", program);
    return buf;
}

const char *ms_test_tmpdir(char *buf, size_t size)
{
    const char *base = getenv("TMPDIR");
    snprintf(buf, size, "%s/mstest.XXXXXX", base ? base : "/tmp");
    if (!mkdtemp(buf))
        fail_msg("mkdtemp failed for %s", buf);
    return buf;
}

void ms_test_rmdir(const char *dir)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fail_msg("could not remove %s", dir);
}

int ms_test_run(const char *command, char *out, size_t size)
{
    char full[8192];
    snprintf(full, sizeof full, "(%s) 2>&1", command);
    FILE *p = popen(full, "r");
    if (!p)
        return -1;
    size_t n = 0;
    if (out && size) {
        n = fread(out, 1, size - 1, p);
        out[n] = '\0';
    }
    char sink[4096];
    while (fread(sink, 1, sizeof sink, p) > 0) {
    }
    int status = pclose(p);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

unsigned char *ms_test_read_file(const char *path, size_t *size)
{
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    *size = (size_t)ftell(fp);
    fseek(fp, 0, SEEK_SET);
    unsigned char *data = malloc(*size ? *size : 1);
    assert_non_null(data);
    assert_int_equal(fread(data, 1, *size, fp), *size);
    fclose(fp);
    return data;
}

void ms_test_write_file(const char *path, const void *data, size_t size)
{
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    assert_int_equal(fwrite(data, 1, size, fp), size);
    fclose(fp);
}

json_t *ms_test_run_json(const char *command, int want_status)
{
    const size_t size = 1 << 20;
    char *out = malloc(size);
    assert_non_null(out);
    int status = ms_test_run(command, out, size);
    if (status != want_status)
        fail_msg("'%s' exited %d, not %d: %.300s", command, status, want_status, out);
    json_error_t je;
    json_t *root = json_loads(out, 0, &je);
    if (!root)
        fail_msg("'%s': not JSON (%s): %.300s", command, je.text, out);
    free(out);
    return root;
}

int ms_test_write_bumpy_sphere(const char *path, double scale)
{
    FILE *m = fopen(path, "w");
    if (!m)
        return -1;
    enum { NU = 48, NV = 24 };
    fprintf(m, "OFF\n%d %d 0\n", NU * (NV + 1), 2 * NU * (NV - 1));
    for (int j = 0; j <= NV; ++j)
        for (int i = 0; i < NU; ++i) {
            double th = M_PI * j / NV, ph = 2 * M_PI * i / NU;
            double r = scale * (1 + 0.05 * sin(5 * ph) * sin(3 * th));
            fprintf(m, "%.17g %.17g %.17g\n", r * sin(th) * cos(ph), r * cos(th),
                    r * sin(th) * sin(ph));
        }
    for (int j = 0; j < NV; ++j)
        for (int i = 0; i < NU; ++i) {
            int a = j * NU + i, b = j * NU + (i + 1) % NU, c = a + NU, d = b + NU;
            if (j > 0)
                fprintf(m, "3 %d %d %d\n", a, b, c);
            if (j < NV - 1)
                fprintf(m, "3 %d %d %d\n", b, d, c);
        }
    return fclose(m) == 0 ? 0 : -1;
}

int ms_test_write_two_boxes(const char *path)
{
    FILE *out = fopen(path, "w");
    if (!out)
        return -1;
    fprintf(out, "OFF\n16 24 0\n");
    const double boxes[2][2][3] = {{{-1, -1, -1}, {1, 1, 1}}, {{-0.8, -2.5, -0.8}, {-0.2, -2.0, -0.2}}};
    for (int b = 0; b < 2; ++b)
        for (int v = 0; v < 8; ++v) /* vertex v: x bit 2, y bit 1, z bit 0 */
            fprintf(out, "%g %g %g\n", boxes[b][(v >> 2) & 1][0], boxes[b][(v >> 1) & 1][1], boxes[b][v & 1][2]);
    static const int quads[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    for (int b = 0; b < 2; ++b)
        for (int q = 0; q < 6; ++q) {
            const int *v = quads[q];
            fprintf(out, "3 %d %d %d\n3 %d %d %d\n", 8 * b + v[0], 8 * b + v[1], 8 * b + v[2], 8 * b + v[0],
                    8 * b + v[2], 8 * b + v[3]);
        }
    return fclose(out) == 0 ? 0 : -1;
}
