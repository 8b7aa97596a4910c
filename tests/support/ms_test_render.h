/* Scaffolding for the renderer's tests (tests/test_render_*.c): a hidden GL 4.1
 * window under Xvfb, an offscreen framebuffer with a float colour and a 32F depth
 * attachment, small baked models, and a view decoded for a camera, stitched, with
 * the APO prefixes of the archive as the client core hands them over.
 * Every helper fails the test on error. Include after cmocka.h. Not
 * thread-safe (GL and the environment). */
#ifndef MS_TEST_RENDER_H
#define MS_TEST_RENDER_H

#include <epoxy/gl.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_client_core.h"
#include "ms_render.h"
#include "ms_test_display.h"
#include "ms_view_decoder.h"

typedef struct GLFWwindow GLFWwindow;

typedef struct ms_test_gl {
    ms_test_display display;
    GLFWwindow *window;
} ms_test_gl;

/* Display (Xvfb if needed) and a hidden 64x64 window whose context is current. */
void ms_test_gl_start(ms_test_gl *gl);
void ms_test_gl_stop(ms_test_gl *gl);

/* cmocka group setup and teardown around the two: *state holds the ms_test_gl. */
int ms_test_gl_group_setup(void **state);
int ms_test_gl_group_teardown(void **state);

typedef struct ms_test_fbo {
    GLuint fbo, colour, depth;
    int width, height;
} ms_test_fbo;

/* An RGBA32F colour + DEPTH_COMPONENT32F framebuffer, bound for drawing. */
void ms_test_fbo_new(ms_test_fbo *fbo, int width, int height);
void ms_test_fbo_free(ms_test_fbo *fbo);
/* Reads back rows bottom-up: rgba 4 floats per pixel and depth 1 per pixel (either
 * may be NULL). */
void ms_test_fbo_read(const ms_test_fbo *fbo, float *rgba, float *depth);

/* Bakes input (a mesh file) at `bits` with N_min = min_triangles into
 * dir/NAME.msa (APO on in every cell, leaves included, every texel kept
 * (apo.full_normals: chunks everywhere, not only corrections), with max depth
 * apo_max_depth; 0 = default) and opens it. */
ms_archive *ms_test_render_bake(const char *input, const char *dir, const char *name, unsigned bits,
                                uint32_t min_triangles, unsigned apo_max_depth);
/* The same with the bake's own rule inside each chunk (full_normals false: only
 * the texels that correct the smooth normal, docs/APO.md). */
ms_archive *ms_test_render_bake_apo(const char *input, const char *dir, const char *name, unsigned bits,
                                    uint32_t min_triangles, unsigned apo_max_depth, bool full_normals);
/* The demo model at `grid` (ms_demo_model.h), written to dir/demo.ply, baked. */
ms_archive *ms_test_render_bake_demo(uint32_t grid, const char *dir, unsigned bits, uint32_t min_triangles,
                                     unsigned apo_max_depth);

/* A camera at distance times the box side from the box centre, in direction dir
 * (need not be unit), near/far just around the box. */
void ms_test_render_camera(const ms_archive_header *h, const double dir[3], double distance, double fovy_degrees,
                           int width, int height, ms_camera *camera);

/* A renderer for the archive and a view decoder of it. */
void ms_test_render_open(const ms_archive *archive, ms_render **render, ms_view **view);

/* The camera ms_test_render_camera places in direction dir at distance 1.1 with a
 * 40 degree field, and the view's mesh for it (ms_test_render_view). */
void ms_test_render_look(const ms_archive *archive, ms_view *view, const double dir[3], int width, int height,
                         double tolerance_px, ms_camera *camera, ms_view_mesh *mesh);

/* Selects and applies cells for the camera (tolerance_px) until the view stops
 * changing, then stitches every shown cell into *mesh (zeroed or reused). */
void ms_test_render_view(ms_view *view, const ms_camera *camera, double tolerance_px, ms_view_mesh *mesh);

/* The APO chunks of every cell drawing a triangle in mesh, as the core hands them
 * over: at most max_levels complete levels (0: all), data borrowed from the
 * archive; mid_level adds half of the next level's bytes (a level in transit).
 * *chunks is malloc'd (free it; the data is the archive's). */
void ms_test_render_apo(const ms_archive *archive, const ms_view_mesh *mesh, unsigned max_levels, bool mid_level,
                        ms_core_apo_chunk **chunks, size_t *count);

/* Sets the renderer's frame (mesh and APO chunks; apo may be NULL when apo_count
 * is 0) and uploads it all in one call; *up (may be NULL) gets the upload's stats. */
void ms_test_render_show(ms_render *render, const ms_view_mesh *mesh, const ms_core_apo_chunk *apo, size_t apo_count,
                         ms_render_upload_stats *up);

/* A zeroed header of a hand-made model: the unit box at the origin, 16 bits,
 * subdivision n, root bits 7, cell_count cells. */
void ms_test_render_unit_header(unsigned n, uint32_t cell_count, ms_archive_header *h);

/* A renderer over a hand-made one-cell model (ms_test_render_unit_header) showing
 * the triangles given (3 vertex indices each, all drawn by the root cell),
 * uploaded. Free it with ms_render_free. */
ms_render *ms_test_render_one_cell(unsigned n, const double *positions, size_t vertex_count, const uint32_t *triangles,
                                   size_t triangle_count);

#endif
