/* libFuzzer target on the camera-path parser (common/camera/ms_camera_path.c,
 * docs/CAMERA_PATHS.md), which meshload and the viewer read from files.
 *
 * Input: the file's text. Besides the sanitizers, the target checks the
 * parser's contract and aborts when it is broken: a path accepted has at
 * least one keyframe, finite fields and non-decreasing times, and can be
 * sampled anywhere (before, inside and after it) into a finite camera; a
 * refused text leaves an empty path and a one-line error.
 *
 * tests/test_fuzz_replay.c includes this file to replay
 * tests/corpus/camera_path/ in `make test`; it then calls
 * ms_fuzz_camera_path_one() directly. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_camera.h"
#include "ms_camera_path.h"

#define MS_FUZZ_PATH_CHECK(cond)                                                               \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_camera_path: contract broken: %s (%s:%d)\n", #cond,         \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* Returns true when the text was accepted. */
static bool ms_fuzz_camera_path_one(const uint8_t *data, size_t size)
{
    ms_camera_path path = {0};
    ms_error err;
    ms_error_clear(&err);
    if (ms_camera_path_parse((const char *)data, size, "fuzz", &path, &err) != MS_OK) {
        MS_FUZZ_PATH_CHECK(path.keys == NULL && path.count == 0);
        MS_FUZZ_PATH_CHECK(err.text[0] != '\0' && !strchr(err.text, '\n'));
        return false;
    }
    MS_FUZZ_PATH_CHECK(path.count >= 1 && path.keys != NULL);
    for (size_t i = 0; i < path.count; ++i) {
        const ms_camera_key *k = &path.keys[i];
        MS_FUZZ_PATH_CHECK(isfinite(k->time) && isfinite(k->fovy_degrees));
        for (int a = 0; a < 3; ++a)
            MS_FUZZ_PATH_CHECK(isfinite(k->position[a]) && isfinite(k->target[a]) &&
                               isfinite(k->up[a]));
        MS_FUZZ_PATH_CHECK(i == 0 || k->time >= path.keys[i - 1].time);
    }
    double end = ms_camera_path_duration(&path);
    const double times[] = {-1.0, 0.0, end * 0.25, end * 0.5, end, end + 1.0};
    for (size_t i = 0; i < sizeof times / sizeof *times; ++i) {
        ms_camera camera;
        if (ms_camera_path_sample(&path, times[i], 640, 480, 0.01, 100.0, &camera, &err) != MS_OK)
            MS_FUZZ_PATH_CHECK(err.text[0] != '\0' && !strchr(err.text, '\n'));
    }
    ms_camera_path_free(&path);
    return true;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_camera_path_one(data, size);
    return 0;
}
#endif
