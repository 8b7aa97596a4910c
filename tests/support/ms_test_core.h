/* Helpers for tests that drive the client core (ms_client_core.h). */
#ifndef MS_TEST_CORE_H
#define MS_TEST_CORE_H

#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>

#include "ms_archive.h"
#include "ms_camera_path.h"
#include "ms_client_core.h"

/* Sleeps for seconds (>= 0). */
void ms_test_sleep_s(double seconds);

/* Polls the core every 5 ms until view complete, an error, or `seconds` pass;
 * fills *stats with the last figures and, when frame is non-NULL, keeps the
 * newest published frame in *frame (freeing the one it replaces). Returns
 * whether the view completed. */
bool ms_test_core_wait_complete(ms_core *core, double seconds, ms_core_stats *stats,
                                ms_core_frame **frame);

/* Fails the test unless the two frames hold the same cut, the same stitched
 * mesh (positions, keys, levels, triangles and their cells) and the same APO
 * chunk prefixes, byte for byte. */
void ms_test_core_assert_frames_equal(const ms_core_frame *a, const ms_core_frame *b);

/* The camera of a path's key k (the last key when k is past it), 640 x 480, near
 * 1e-4, far 1e4; fails the test on error. */
ms_camera ms_test_core_key_camera(const ms_camera_path *path, size_t k);

/* A meshserve for the client tests: a private folder dir holding archives/ (the
 * folder it serves), its log and its port file; the model's archive (file)
 * opened and a camera path loaded. */
typedef struct ms_test_served {
    char dir[512], archives[600], file[700], log[600], port_file[600];
    pid_t pid; /* 0: not running */
    uint16_t port, http_port;
    ms_archive *archive;
    ms_camera_path path;
} ms_test_served;

/* A zeroed ms_test_served (malloc'd) with a fresh dir, an empty archives/ in it
 * and file = archives/MODEL.msa; NULL when archives/ cannot be made. */
ms_test_served *ms_test_served_new(const char *model);
/* Opens file into archive and loads path_file into path: 0, or -1 with the
 * error on stderr. */
int ms_test_served_open(ms_test_served *s, const char *path_file);
/* Starts meshserve on archives at port (0: any free one) and reads its ports
 * into s; fails the test when it does not start within 15 s. */
void ms_test_served_launch(ms_test_served *s, uint16_t port);
/* Core options for the model on s's server at 127.0.0.1: tolerance 1 px, no
 * hysteresis (memoryless selection: equal to a fresh decode), answers within 3 s,
 * giving up after 20 s; the rest zero. */
ms_core_options ms_test_served_core_options(const ms_test_served *s, const char *model);
/* Stops the server (SIGTERM) when running, closes the archive, frees the path,
 * removes dir and frees s. NULL is a no-op. */
void ms_test_served_free(ms_test_served *s);

#endif
