/* Checks shared by the nSP bake and view-decoding tests (include after cmocka.h).
 * Failures are cmocka assertion failures. */
#ifndef MS_NSP_CHECK_H
#define MS_NSP_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "ms_bake.h"
#include "ms_quant.h"
#include "ms_view_decoder.h"

/* Options of a geometry-only test bake (APO off) of input into dir/name.msa (name
 * may be set later) with 2 threads; the rest at the defaults. */
void ms_nsp_test_bake_options(const char *input, const char *dir, const char *name, ms_bake_options *o);

/* Bakes input into dir/name.msa with the given parameters (threads 2, --mem 64)
 * and fills report. */
void ms_nsp_test_bake(const char *input, const char *dir, const char *name, unsigned bits,
                      uint32_t min_triangles, ms_bake_report *report);

/* The quantised, welded reference of a model file (ms_mesh_load + ms_quantise_mesh). */
void ms_nsp_test_reference(const char *input, unsigned bits, ms_qmesh *q);

/* Writes a demo model of about `triangles` triangles as binary PLY (doubles) to path. */
void ms_nsp_test_demo_ply(const char *path, uint64_t triangles);

/* Writes a demo model of about `triangles` triangles to work_dir/demo.ply and
 * bakes it with APO on (on every cell, leaves included, every texel kept
 * (apo.full_normals: the smooth demo would need few) and no byte budget,
 * where every_cell) into
 * archive_dir/name.msa with N_min = min_triangles, 2 threads and --mem 64.
 * 0, or -1 with the error on stderr (for group setups). */
int ms_nsp_test_bake_demo(const char *work_dir, uint64_t triangles, const char *archive_dir, const char *name,
                          uint32_t min_triangles, bool every_cell);

/* The scenes' tests' archive: a fresh temporary directory into dir, and in
 * it archives/ holding "demo" (4,000 triangles, N_min 1,500, APO on internal
 * cells), whose source is dir/demo.ply. 0, or -1 with the error on stderr. */
int ms_nsp_test_demo_archive(char *dir, size_t dir_size, char *archives, size_t archives_size);

/* A baked demo for the client core's tests: a fresh temporary directory,
 * the demo of about `triangles` triangles baked as "demo" into
 * dir/archive/demo.msa (N_min = min_triangles, ms_nsp_test_bake_demo without
 * APO on every cell), and that archive's box. */
typedef struct ms_nsp_test_demo {
    char dir[512], archives[600], file[700];
    double centre[3], side;
} ms_nsp_test_demo;

/* Fills *d; 0, or -1 with the error on stderr (for group setups). The caller
 * removes d->dir (ms_test_rmdir). */
int ms_nsp_test_demo_bake(ms_nsp_test_demo *d, uint64_t triangles, uint32_t min_triangles);
/* The same, allocated: NULL (the error on stderr) when the bake fails.
 * ms_nsp_test_demo_free removes its directory and frees it (NULL: nothing). */
ms_nsp_test_demo *ms_nsp_test_demo_new(uint64_t triangles, uint32_t min_triangles);
void ms_nsp_test_demo_free(ms_nsp_test_demo *d);

/* Splits every cell down to the leaves and refines each to full precision. */
void ms_nsp_test_decode_all(ms_view *view);

typedef struct ms_nsp_view_check {
    size_t triangles;          /* in the stitched mesh */
    size_t missing, extra;     /* against the reference image of the mixed clustering */
    size_t duplicates;         /* stitched triangles with the same vertex set */
    size_t boundary_edges;     /* edges with one incident triangle */
    size_t folds;              /* boundary edges not boundary in any uniform decode, whose
                                  one triangle is the image of several input triangles */
    size_t cracks;             /* boundary edges that are neither */
    size_t snapped_frozen;     /* corners resolved through a frozen vertex's lone kd-cell */
    unsigned shown_cells, levels;
} ms_nsp_view_check;

/* Compares the stitched mesh of every shown cell with the reference: the image
 * of q's triangles when each vertex is taken to the kd-cell of the precision of
 * the shown cell holding it (the exact mesh the stitching rule must give), and
 * checks the crack criterion: every edge with a single incident triangle is such
 * an edge in q decoded uniformly (ms_ref_coarsen) at one of the shown precisions
 * not above its endpoints', or else is a fold (its one triangle stands for two
 * or more input triangles pressed together: for a closed input every boundary
 * edge of the image is of one of these kinds, by parity). With full = true, also asserts that the stitched mesh
 * is q exactly, orientation included (every cell at full precision). */
void ms_nsp_test_check_view(ms_view *view, const ms_qmesh *q, bool full,
                            ms_nsp_view_check *result);

#endif
