/* The bake's side of the surface error (docs/CODEC.md §4.3, docs/ARCHIVE.md
 * "Per-cell tables"): each cell's encoder measures it against points of the
 * model (a leaf's own vertices; an internal cell's children's summaries), and
 * the bake turns the measurements into the archive's table. Pure functions on
 * the caller's data; not thread-safe on shared arguments. */
#ifndef MS_NSP_SURFACE_H
#define MS_NSP_SURFACE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"

/* The least error of a precision below the model's, as a share of its
 * kd-cell's half-diagonal: a flat region measures 0 however far its vertices
 * slide along it, and a model asked for at a tiny tolerance gets its full
 * precision, not a coarser one that measures 0 (at most 3 bits short of the
 * half-diagonal's need). */
#define MS_NSP_SURFACE_ERROR_FLOOR 0.125

/* A cell's surface error table (ms_archive_writer_put_error: hi - lo + 1
 * bytes) from what its encoder measured over its window [lo, hi] (surface,
 * in grid steps of its stream's `bits`): at least the floor below the
 * model's `model_bits`, never growing with the bits, in the archive's units
 * (hundredths of the half-diagonal), rounded up and capped at the diagonal. */
void ms_nsp_error_table(unsigned model_bits, unsigned bits, unsigned lo, unsigned hi, const double *surface,
                        uint8_t *table);

/* Positions of t times 2^shift (between model grid steps and a stream's). */
void ms_nsp_truth_scale(ms_codec_truth *t, int shift);

/* Appends a child's summary to its parent's points (*cap: their room, in
 * points). False when out of memory (the points stay as they were). */
bool ms_nsp_truth_append(ms_codec_truth *points, size_t *cap, const ms_codec_truth *summary);

#endif
