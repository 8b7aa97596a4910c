/* Streaming mesh input: PLY (ascii, binary little/big endian), OBJ and OFF, each
 * optionally gzip-compressed. The format is detected from the content, never
 * from the file name. docs/INPUT.md lists what each format may contain and the
 * errors reported.
 *
 * ms_mesh_read parses a file from start to end and pushes what it finds to a sink
 * in bounded chunks, so a consumer can handle models larger than memory. The
 * reader's own memory is a fixed input buffer and chunk buffers plus one bit per
 * vertex for the cleaning policy (ms_mesh_clean.h), whatever the header declares.
 *
 * Order guarantee: every triangle handed to the sink references only vertices
 * already handed over (so OBJ files with interleaved v and f lines work), vertices
 * arrive in file order with indices counting from 0, and triangles arrive already
 * triangulated (polygons as fans, strips unrolled) and cleaned.
 *
 * Errors: any problem stops the read with a non-zero ms_status and a one-line
 * err->text naming the file and the line (text) or byte offset (binary), for
 * example "model.ply: byte offset 1234: vertex index 99999 out of range (5205
 * vertices)". A sink callback may also return an error to stop the read; its own
 * err text is passed through. Chunks already delivered before an error are not
 * withdrawn: the consumer must discard its result when the call fails.
 *
 * Thread-safety: independent calls may run concurrently; a sink is called from the
 * calling thread only.
 */
#ifndef MS_MESH_READER_H
#define MS_MESH_READER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef enum ms_mesh_format {
    MS_MESH_FORMAT_UNKNOWN = 0,
    MS_MESH_FORMAT_PLY_ASCII,
    MS_MESH_FORMAT_PLY_BINARY_LE,
    MS_MESH_FORMAT_PLY_BINARY_BE,
    MS_MESH_FORMAT_OBJ,
    MS_MESH_FORMAT_OFF
} ms_mesh_format;

/* "ply-ascii", "ply-binary-le", "ply-binary-be", "obj", "off" or "unknown". */
const char *ms_mesh_format_name(ms_mesh_format format);

/* Largest chunk handed to the sink, in vertices and in triangles. */
#define MS_MESH_READ_CHUNK_VERTICES 16384
#define MS_MESH_READ_CHUNK_TRIANGLES 16384

typedef struct ms_mesh_sink {
    void *context; /* passed back to every callback */
    /* `count` vertices as x y z doubles in file units; the array is valid only
     * during the call. May be NULL to ignore vertices. */
    ms_status (*vertices)(void *context, const double *positions, size_t count, ms_error *err);
    /* `count` triangles as three vertex indices each; valid only during the call.
     * May be NULL. */
    ms_status (*triangles)(void *context, const uint32_t *indices, size_t count, ms_error *err);
    /* Only for files with per-vertex colour (docs/INPUT.md): right after each
     * vertices call, the same `count` vertices' colours as r g b a bytes (a is
     * 255 when the file has no alpha; the report says which). Valid only during
     * the call. May be NULL. */
    ms_status (*colours)(void *context, const uint8_t *rgba, size_t count, ms_error *err);
    /* Called with each chunk handed over, with how far through the file on disk the read
     * is (compressed bytes for gzip input) and the file size. May be NULL. */
    void (*progress)(void *context, uint64_t disk_bytes_done, uint64_t disk_bytes_total);
} ms_mesh_sink;

typedef struct ms_mesh_read_report {
    ms_mesh_format format;
    bool gzip;                  /* input was gzip-compressed */
    uint64_t input_bytes;       /* uncompressed bytes parsed (the whole file) */
    uint64_t vertices;          /* vertices delivered */
    uint64_t triangles;         /* triangles delivered (after triangulation, cleaning) */
    uint64_t input_faces;       /* faces (or strips) as read, before triangulation */
    uint64_t dropped_faces;     /* triangles dropped for a repeated vertex index */
    uint64_t isolated_vertices; /* vertices referenced by no delivered triangle */
    bool colour;                /* the vertices have colour (handed to sink->colours) */
    bool colour_alpha;          /* ... with an alpha channel */
    double bbox_min[3];         /* bounding box of all vertices, file units */
    double bbox_max[3];
} ms_mesh_read_report;

/* Reads path completely, pushing vertices and triangles to sink. report may be
 * NULL; on success it holds the totals, on error what was known when it stopped.
 * A file that yields no triangle at all is an error (MS_ERR_EMPTY). */
ms_status ms_mesh_read(const char *path, const ms_mesh_sink *sink, ms_mesh_read_report *report,
                       ms_error *err);

#endif
