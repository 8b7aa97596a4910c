/* Whole-file mesh input and output.
 *
 * ms_mesh_load reads a PLY (ascii, binary little/big endian), OBJ or OFF file,
 * optionally gzip-compressed, into an ms_mesh, applying the cleaning policy of
 * docs/INPUT.md (faces with a repeated vertex dropped and counted; zero-area faces
 * with distinct vertices kept; isolated vertices counted), with the vertex colour
 * when the file has one (mesh->colours, else NULL). It is built on the
 * streaming readers (ms_mesh_reader.h) and holds the whole mesh in memory; the
 * baker uses the streaming interface instead for models larger than memory.
 *
 * Errors: a non-zero ms_status and a one-line err->text naming the file and the
 * line (text formats) or byte offset (binary) of the problem. On error *mesh is
 * left empty (nothing to free, but ms_mesh_free is harmless).
 * Thread-safety: independent calls may run concurrently.
 */
#ifndef MS_MESH_IO_H
#define MS_MESH_IO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_mesh.h"

typedef struct ms_mesh_load_report {
    const char *format;            /* "ply-ascii", "ply-binary-le", "ply-binary-be", "obj", "off" */
    bool gzip;                     /* input was gzip-compressed */
    uint64_t input_bytes;          /* bytes of (uncompressed) input parsed */
    uint64_t input_faces;          /* faces/strips as read, before triangulation */
    uint64_t dropped_faces;        /* triangles dropped for a repeated vertex */
    uint64_t isolated_vertices;    /* vertices referenced by no kept triangle */
} ms_mesh_load_report;

/* Reads path completely into *mesh (which must be zeroed or freed). report may be
 * NULL. */
ms_status ms_mesh_load(const char *path, ms_mesh *mesh, ms_mesh_load_report *report,
                       ms_error *err);

/* Writes mesh as PLY (binary little-endian when binary is true, else ascii) with
 * float vertex coordinates (double when use_double), uchar red green blue (and
 * alpha when mesh->colour_alpha) when the mesh has colours, and uchar/int face
 * lists.
 * Writes to a temporary name and renames it over path on success, so a failed
 * write never leaves a partial file under path. */
ms_status ms_ply_write(const char *path, const ms_mesh *mesh, bool binary, bool use_double,
                       ms_error *err);

/* Streaming PLY writer, for meshes produced piece by piece (the demo generator,
 * decoders). Declare the counts up front, then write exactly that many vertices
 * followed by exactly that many triangles, then ms_ply_writer_finish, which
 * checks the counts and renames the temporary file over path. On any error, or
 * with ms_ply_writer_abort, the temporary file is removed and path is untouched.
 * The writer owns its FILE and buffers; finish and abort free it. */
typedef struct ms_ply_writer ms_ply_writer;

ms_status ms_ply_writer_open(const char *path, uint64_t vertex_count, uint64_t triangle_count,
                             bool binary, bool use_double, ms_ply_writer **writer,
                             ms_error *err);
ms_status ms_ply_writer_vertex(ms_ply_writer *writer, const double position[3], ms_error *err);
/* The same with colour: colour_channels 3 declares uchar red green blue, 4 adds
 * alpha (0: none, as ms_ply_writer_open); write the vertices with
 * ms_ply_writer_coloured_vertex, which writes the first colour_channels bytes
 * of rgba (ms_ply_writer_vertex writes white). */
ms_status ms_ply_writer_open_colour(const char *path, uint64_t vertex_count,
                                    uint64_t triangle_count, bool binary, bool use_double,
                                    int colour_channels, ms_ply_writer **writer, ms_error *err);
ms_status ms_ply_writer_coloured_vertex(ms_ply_writer *writer, const double position[3],
                                        const uint8_t rgba[4], ms_error *err);
ms_status ms_ply_writer_triangle(ms_ply_writer *writer, const uint32_t triangle[3],
                                 ms_error *err);
ms_status ms_ply_writer_finish(ms_ply_writer *writer, ms_error *err);
void ms_ply_writer_abort(ms_ply_writer *writer);

#endif
