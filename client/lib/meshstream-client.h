/* meshstream-client.h: the public interface of libmeshstream-client, the thin
 * client of meshstream as a library (pkg-config meshstream-client). It is
 * the only header the library installs, and the only symbols its shared
 * object exports are the msc_* functions declared here.
 *
 * What it does. An msc_stream streams one model, from meshserve's binary
 * door (a server address) or from a local archive file (NAME.msa, no
 * network), for a camera the caller moves. Behind it run the threads of
 * meshstream's client core (docs/CLIENT.md): a network (or local) thread and a
 * decode thread that choose, fetch, verify and decode the model's cells at the
 * precision the camera needs. The caller takes decoded frames: the stitched
 * triangle mesh of the cells shown, with each triangle's cell, and the list of
 * those cells with the precision at which each is shown.
 *
 *     msc_options *o = msc_options_new();
 *     msc_options_set_server(o, "127.0.0.1", 7800);   // or msc_options_set_archive
 *     msc_options_set_model(o, "demo");
 *     msc_stream *s;  msc_error e;
 *     if (msc_stream_new(o, &s, &e) != MSC_OK) { puts(e.text); ... }
 *     msc_options_free(o);                     // the stream copied what it needs
 *     msc_model_info info;  msc_stream_wait_open(s, 10.0, &info, &e);
 *     msc_camera cam = {...};  msc_stream_set_camera(s, &cam, &e);
 *     msc_stream_wait_complete(s, 30.0, NULL, &e);
 *     msc_frame *f = msc_stream_take_frame(s); ... msc_frame_free(f);
 *     msc_stream_free(s);
 *
 * Units. Positions, distances and boxes are in the model's own world units
 * (those of the mesh it was baked from); angles in degrees; tolerances and
 * viewports in pixels; times in seconds; sizes in bytes.
 *
 * Ownership. Every handle comes from a _new (or msc_stream_take_frame) and is
 * released with its _free; each _free accepts NULL. Strings passed in are
 * copied; pointers returned into a frame stay valid until that frame is
 * freed; msc_version's string is static.
 *
 * Errors. Functions that can fail return an msc_status (MSC_OK = 0, else a
 * negative code) and, given a non-NULL msc_error, fill it with the code and
 * one line of text (no newline). They never abort on bad input. A stream that
 * cannot go on (server gone, archive damaged, model replaced) keeps its last
 * frame and reports why in msc_progress.error.
 *
 * Thread-safety. Options: one thread at a time per handle. A stream:
 * msc_stream_set_camera, msc_stream_take_frame and msc_stream_get_progress
 * may be called concurrently from any threads (none blocks on the network or
 * on decoding); msc_stream_wait_open and msc_stream_wait_complete from one
 * thread at a time; msc_stream_free must not race with any other call on the
 * same stream. A frame belongs to whoever took it. Distinct streams are
 * independent.
 *
 * ABI. The shared object's soname is libmeshstream-client.so.MAJOR; the
 * structures below only grow at the end with a new MAJOR.
 */
#ifndef MESHSTREAM_CLIENT_H
#define MESHSTREAM_CLIENT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__GNUC__) && defined(MSC_BUILDING_LIBRARY)
#define MSC_API __attribute__((visibility("default")))
#else
#define MSC_API
#endif

/* Status codes (the values of meshstream's ms_status). */
typedef enum msc_status {
    MSC_OK = 0,
    MSC_ERR_IO = -1,          /* connection, file or thread failed; or no answer in time */
    MSC_ERR_FORMAT = -2,      /* an archive or answer does not follow its format */
    MSC_ERR_NOMEM = -3,       /* out of memory */
    MSC_ERR_RANGE = -4,       /* a value is out of its range */
    MSC_ERR_CORRUPT = -5,     /* checksum mismatch */
    MSC_ERR_ARG = -6,         /* bad argument from the caller */
    MSC_ERR_UNSUPPORTED = -7, /* a version the library does not handle */
    MSC_ERR_EMPTY = -8        /* nothing to work on */
} msc_status;

#define MSC_ERROR_TEXT_MAX 512

/* A plain value owned by the caller. */
typedef struct msc_error {
    msc_status code;
    char text[MSC_ERROR_TEXT_MAX]; /* one line, NUL-terminated */
} msc_error;

/* The library's version ("0.1.0"): the same string as every meshstream
 * program's --version. Static; never NULL. */
MSC_API const char *msc_version(void);

/* A short constant name for a status ("I/O error", ...). */
MSC_API const char *msc_status_name(msc_status status);

/* ---- Options: what to stream and how. ---- */

typedef struct msc_options msc_options;

/* Defaults: no source, tolerance 1 px, APO detail off, no memory budget,
 * unlimited bandwidth. NULL when out of memory. */
MSC_API msc_options *msc_options_new(void);
MSC_API void msc_options_free(msc_options *options);

/* Stream from meshserve's binary door at host (a numeric IPv4 or IPv6
 * address) and port (1..65535). Clears an archive set before. MSC_ERR_ARG. */
MSC_API msc_status msc_options_set_server(msc_options *options, const char *host, unsigned port,
                                          msc_error *err);
/* Stream from a local archive file instead (DIR/NAME.msa as meshbake writes
 * it; no network). Clears a server set before. MSC_ERR_ARG for NULL or "". */
MSC_API msc_status msc_options_set_archive(msc_options *options, const char *path,
                                           msc_error *err);
/* The model's name: required with a server, optional with an archive. */
MSC_API msc_status msc_options_set_model(msc_options *options, const char *name, msc_error *err);
/* The operator's token for precision beyond a model's public preview
 * (docs/SECURITY.md); NULL for none. */
MSC_API msc_status msc_options_set_token(msc_options *options, const char *token, msc_error *err);
/* The geometric screen tolerance: cells are refined until their projected
 * error is at most `pixels` (> 0; smaller is finer; default 1). MSC_ERR_ARG. */
MSC_API msc_status msc_options_set_tolerance(msc_options *options, double pixels, msc_error *err);
/* Fetch appearance-preserving normal detail (APO chunks), at most `levels`
 * octree levels a cell (0: off, the default). */
MSC_API msc_status msc_options_set_apo_levels(msc_options *options, unsigned levels,
                                              msc_error *err);
/* Keep the client's memory near `bytes` (0: no budget), coarsening the view
 * when needed (docs/CLIENT.md, "Memory budget"). */
MSC_API msc_status msc_options_set_memory_budget(msc_options *options, uint64_t bytes,
                                                 msc_error *err);
/* Read at most `bytes_per_second` from the source (0: unlimited). MSC_ERR_ARG
 * for a negative or non-finite figure. */
MSC_API msc_status msc_options_set_bandwidth(msc_options *options, double bytes_per_second,
                                             msc_error *err);

/* ---- A stream: one model for one moving camera. ---- */

typedef struct msc_stream msc_stream;

/* Starts streaming (returns at once; the connection or the archive is opened
 * in the background, and errors there show in msc_progress.error).
 * MSC_ERR_ARG when options name no source, or a server without a model;
 * MSC_ERR_NOMEM; MSC_ERR_IO when a thread cannot start. *stream is NULL on
 * failure. The options may be freed right after. */
MSC_API msc_status msc_stream_new(const msc_options *options, msc_stream **stream,
                                  msc_error *err);
/* Stops the threads, closes the connection and frees the stream. */
MSC_API void msc_stream_free(msc_stream *stream);

/* What the model is. */
typedef struct msc_model_info {
    uint32_t cell_count;        /* cells of the model's nSP-tree */
    uint64_t vertex_count;      /* of the baked model at full precision */
    uint64_t triangle_count;    /* of the baked model at full precision */
    unsigned bits;              /* full precision, bits per coordinate */
    double box_origin[3];       /* the quantisation cube: its lowest corner */
    double box_side;            /* and its side */
    bool has_apo;               /* the archive holds APO chunks */
    bool bounds_known;          /* the box below is known (false for an empty model) */
    double bounds_lo[3], bounds_hi[3]; /* the box the geometry occupies, within one root
                                          quantum of the vertices' box */
} msc_model_info;

/* Waits at most timeout_s seconds (> 0) for the model to open and fills
 * *info. MSC_ERR_IO when the stream failed (the reason in err) or nothing
 * came in time; MSC_ERR_ARG. */
MSC_API msc_status msc_stream_wait_open(msc_stream *stream, double timeout_s,
                                        msc_model_info *info, msc_error *err);

/* A pinhole camera looking from `position` at `target`; `up` need only be
 * roughly up. fovy_degrees in (0, 180), width and height >= 1 pixels,
 * 0 < near_distance < far_distance. */
typedef struct msc_camera {
    double position[3], target[3], up[3];
    double fovy_degrees;
    double width, height;
    double near_distance, far_distance;
} msc_camera;

/* The camera to serve from now on (copied). MSC_ERR_ARG for a degenerate
 * camera (NaN, position == target, up parallel to the view, empty viewport),
 * which leaves the previous one in force. */
MSC_API msc_status msc_stream_set_camera(msc_stream *stream, const msc_camera *camera,
                                         msc_error *err);

/* Where the stream stands. */
typedef struct msc_progress {
    double seconds;             /* since msc_stream_new */
    bool model_open;
    bool view_complete;         /* every cell the camera needs is at its precision */
    double achieved_error_px;   /* largest projected error of a visible shown cell */
    uint32_t cells_shown, cells_loading, cells_failed;
    uint64_t bytes_received;    /* payload bytes */
    uint64_t memory;            /* bytes held (payloads and decoded estimate) */
    char error[256];            /* why the stream stopped, or "" */
    char warning[256];          /* the last non-fatal problem, or "" */
} msc_progress;

MSC_API void msc_stream_get_progress(msc_stream *stream, msc_progress *progress);

/* Waits at most timeout_s seconds (> 0) for the view of the current camera to
 * be complete; fills *progress when non-NULL. MSC_OK when complete;
 * MSC_ERR_IO when the stream stopped (the reason in err) or time ran out. */
MSC_API msc_status msc_stream_wait_complete(msc_stream *stream, double timeout_s,
                                            msc_progress *progress, msc_error *err);

/* ---- Frames: what was decoded, ready to draw. ---- */

typedef struct msc_frame msc_frame;

/* The newest frame published since the last take, or NULL when there is none
 * (never blocks). The caller frees it with msc_frame_free. */
MSC_API msc_frame *msc_stream_take_frame(msc_stream *stream);
MSC_API void msc_frame_free(msc_frame *frame);

/* Increases with each frame the stream publishes. */
MSC_API uint64_t msc_frame_generation(const msc_frame *frame);

/* The stitched mesh: positions (3 doubles a vertex, world units), triangles
 * (3 vertex indices each, counter-clockwise seen from outside) and each
 * triangle's cell id. */
MSC_API size_t msc_frame_vertex_count(const msc_frame *frame);
MSC_API const double *msc_frame_positions(const msc_frame *frame);
MSC_API size_t msc_frame_triangle_count(const msc_frame *frame);
MSC_API const uint32_t *msc_frame_triangles(const msc_frame *frame);
MSC_API const uint32_t *msc_frame_triangle_cells(const msc_frame *frame);

/* One decoded cell shown in a frame. */
typedef struct msc_cell {
    uint32_t id;                /* the cell's number in the model */
    unsigned level;             /* depth in the nSP-tree (0: the root) */
    unsigned bits;              /* precision shown, bits per coordinate */
    unsigned bits_max;          /* the cell's full precision */
    bool leaf;                  /* a leaf cell (no finer cells below it) */
    uint32_t triangle_count;    /* the cell's triangles at full precision */
} msc_cell;

/* The cells the frame shows (those the mesh's triangles come from, and shown
 * cells that hold no triangle), ids ascending. */
MSC_API size_t msc_frame_cell_count(const msc_frame *frame);
/* The i-th of them (i < msc_frame_cell_count). MSC_ERR_ARG otherwise. */
MSC_API msc_status msc_frame_cell(const msc_frame *frame, size_t i, msc_cell *cell);

#ifdef __cplusplus
}
#endif

#endif
