/* Refining the cells under measuring points to full precision
 * (docs/VIEWER.md, "Measuring"). The client core has no call that raises one
 * cell's target, and the view's core serves the view's camera; so a second
 * core of the same model, the probe, is given in turn for each point a
 * camera that sees only that point: from a thousandth of the box side in
 * front of it along its ray, a field of view of a hundredth of a degree on
 * 1000 x 1000 pixels (the cells there want more bits than the model has),
 * and cells outside that frustum wanting nothing (culled_bits_less 64). It
 * fetches the cells from the root down to the point's leaf, those at full
 * precision, and little else. Once its view is complete the point's ray is
 * cast on its frame (ms_viewer_measure_cast, the hit nearest the point): that
 * hit, at the bits the probe holds there (the model's, for a leaf), becomes
 * the point's, and the point is marked refined (ms_viewer_measure_update no
 * longer moves it). A point whose probe does not complete within
 * MS_VIEWER_PROBE_TIMEOUT_S is left as the view has it.
 *
 * Nothing blocks: ms_viewer_probe_step polls the probe's core and moves on.
 * The probe costs a second core (threads, and from a server a second
 * connection) while it lives. Ownership: the probe owns its core; the
 * source's strings and the model must outlive it. Errors: ms_status with one
 * line. Thread-safety: the caller's thread (the core's own threads aside).
 */
#ifndef MS_VIEWER_PROBE_H
#define MS_VIEWER_PROBE_H

#include <stdbool.h>

#include "ms_error.h"
#include "ms_viewer_measure.h"
#include "ms_viewer_model.h"

#define MS_VIEWER_PROBE_TIMEOUT_S 30.0

typedef struct ms_viewer_probe ms_viewer_probe;

/* Starts the probe's core on the model (opened: its header known) from the
 * source. MS_ERR_ARG, MS_ERR_NOMEM, MS_ERR_IO as ms_core_start. */
ms_status ms_viewer_probe_start(const ms_viewer_source *source, const ms_viewer_model *model,
                                ms_viewer_probe **probe, ms_error *err);
/* NULL is a no-op. */
void ms_viewer_probe_stop(ms_viewer_probe *probe);

/* One poll: when the point being refined is done (or given up, or no longer
 * in the chain), its result goes into m; then the next found, unrefined point
 * of m is begun. True while a point of m is still to be refined. */
bool ms_viewer_probe_step(ms_viewer_probe *probe, ms_viewer_measure *m);

/* The camera that sees only the point (anchor, direction) of a model of box
 * side box_side (pure; for tests). */
ms_status ms_viewer_probe_camera(const double anchor[3], const double direction[3], double box_side,
                                 ms_camera *camera, ms_error *err);

#endif
