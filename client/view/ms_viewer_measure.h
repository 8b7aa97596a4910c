/* Measuring on the decoded cut (docs/VIEWER.md, "Measuring"): points picked
 * on the surface by a ray cast against the triangles of the core's frame
 * (ms_core_frame.mesh: what is drawn, in world units), a chain of them, and
 * the distance along the chain with its precision.
 *
 * Precision. A point lies on a triangle drawn by one cell, shown at b bits:
 * its vertices are held to the grid of step box_side / 2^b (each coordinate
 * within half a step of the scan's own quantised vertex), so the point's
 * precision is that step. A segment's precision is the coarser of its two
 * points' steps (two axis-aligned half steps); a chain's is the sum of its
 * segments'. A point is at full precision when its cell is shown at the
 * model's bits (the scan's own grid).
 *
 * Refinement. A point keeps the ray that picked it (its anchor on the surface
 * and the ray's direction): ms_viewer_measure_update casts it again against
 * a new frame, taking the hit nearest the anchor along the ray, so that as
 * the cut refines under it the point follows the finer surface and its
 * precision rises with the cell's bits. The client core has no way to raise
 * one cell's target, so a probe (ms_viewer_probe.h) refines the cells under
 * each point to full precision with a core of its own, and marks the point
 * refined.
 *
 * Units: world (model) units; pixels are framebuffer pixels with the origin
 * at the top-left corner, continuous (pixel (i, j)'s centre is i + 0.5,
 * j + 0.5). Pure functions on caller-owned values; thread-safe.
 */
#ifndef MS_VIEWER_MEASURE_H
#define MS_VIEWER_MEASURE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_camera.h"
#include "ms_client_core.h"

#define MS_VIEWER_MEASURE_MAX_POINTS 16
#define MS_VIEWER_MEASURE_MAX_PLANES 3 /* meshview's MS_SECTIONS_MAX */

typedef struct ms_viewer_measure_hit {
    double point[3];     /* on the drawn surface */
    double t;            /* along the ray: point = origin + t * direction */
    uint32_t cell;       /* the cell that drew the triangle hit */
    unsigned bits;       /* that cell's shown precision in the frame */
    double step;         /* box_side / 2^bits */
} ms_viewer_measure_hit;

/* The ray from the eye through framebuffer point (x, y) (top-left origin) of
 * camera: origin the camera's position, direction unit. */
void ms_viewer_measure_pixel_ray(const ms_camera *camera, double x, double y, double origin[3],
                                 double direction[3]);

/* Where camera shows world point p (framebuffer pixels, top-left origin,
 * continuous): the inverse of ms_viewer_measure_pixel_ray; false behind the
 * eye. */
bool ms_viewer_measure_project(const ms_camera *camera, const double p[3], double *x, double *y);

/* Casts the ray (direction need not be unit) against the frame's triangles:
 * of the hits with t >= t_min, the one whose t is nearest t_near (t_min 0 and
 * t_near 0: the first surface in front of the origin). box_side is the
 * model's (ms_archive_header.box_side). False when nothing is hit, or for a
 * NULL frame or a zero direction. */
bool ms_viewer_measure_cast(const ms_core_frame *frame, double box_side, const double origin[3],
                            const double direction[3], double t_min, double t_near,
                            ms_viewer_measure_hit *hit);

/* A chain of picked points. */
typedef struct ms_viewer_measure {
    size_t count;
    double anchor[MS_VIEWER_MEASURE_MAX_POINTS][3];    /* where the point was last found */
    double direction[MS_VIEWER_MEASURE_MAX_POINTS][3]; /* its ray's, unit */
    ms_viewer_measure_hit hit[MS_VIEWER_MEASURE_MAX_POINTS];
    bool found[MS_VIEWER_MEASURE_MAX_POINTS];          /* hit is on the present frame */
    bool refined[MS_VIEWER_MEASURE_MAX_POINTS];        /* done by the probe (ms_viewer_probe.h):
                                                          update leaves the point alone */
    uint64_t id[MS_VIEWER_MEASURE_MAX_POINTS];         /* each point's own, from 1 */
    uint64_t next_id;
    double planes[MS_VIEWER_MEASURE_MAX_PLANES][4];    /* the section planes: what they cut
                                                          away is not hit (ms_section.h) */
    size_t plane_count;
} ms_viewer_measure;

/* The section planes the casts of add and update respect (count clamped to
 * MS_VIEWER_MEASURE_MAX_PLANES); true when they changed, so that the caller
 * casts the chain again. */
bool ms_viewer_measure_set_planes(ms_viewer_measure *m, const double (*planes)[4], size_t count);

/* Adds the point the ray from origin along direction hits first; false (the
 * chain unchanged) when it hits nothing or the chain is full. */
bool ms_viewer_measure_add(ms_viewer_measure *m, const ms_core_frame *frame, double box_side,
                           const double origin[3], const double direction[3]);

/* Adds a point given by its anchor and direction (a shared view's,
 * ms_viewer_share.h), found on the frame by ms_viewer_measure_update; false
 * when the chain is full or the direction is zero or not finite. */
bool ms_viewer_measure_add_anchor(ms_viewer_measure *m, const double anchor[3], const double direction[3]);

/* Casts every point again on the frame: the hit nearest its anchor along its
 * ray becomes the point (and the new anchor); a point no longer hit keeps its
 * anchor and is not found. */
void ms_viewer_measure_update(ms_viewer_measure *m, const ms_core_frame *frame, double box_side);

/* Removes the last point (none: nothing). */
void ms_viewer_measure_pop(ms_viewer_measure *m);
void ms_viewer_measure_clear(ms_viewer_measure *m);

typedef struct ms_viewer_measure_result {
    size_t points;       /* in the chain */
    double length;       /* along the chain */
    double precision;    /* sum over the segments of the coarser point's step */
    double last_length, last_precision; /* the last segment's */
    unsigned bits_min;   /* the coarsest point's bits */
    bool full;           /* every point's cell at the model's bits */
    bool refined;        /* every point done by the probe */
} ms_viewer_measure_result;

/* The chain's figures; false when it has fewer than two points or one is not
 * found on the present frame. model_bits: ms_archive_header.bits. */
bool ms_viewer_measure_result_of(const ms_viewer_measure *m, unsigned model_bits,
                                 ms_viewer_measure_result *r);

#endif
