/* Shareable views (docs/VIEWER.md, "Shareable views"): the camera, the light
 * and the measurement points of meshview as one short line of text, printed
 * by the V key and taken by --view TEXT, in the window and in scripted runs:
 *
 *   mv1:t=X,Y,Z:d=D:o=YAW,PITCH:f=FOVY:u=AXIS[:l=AZ,EL][:s=PLANE/...][:m=POINT/POINT/...]
 *
 * t the orbit centre, d the eye's distance from it (> 0), o the view's yaw
 * and pitch about the up axis (radians, |pitch| at most 89 degrees), f the
 * vertical field of view (degrees, in (0, 180)), u the up axis (x, y or z):
 * the camera controller's state (ms_viewer_controls.h), so the view comes
 * back as it was. l a directional light (ms_viewer_light.h; absent: the head
 * light). s the section planes (ms_viewer_section.h), one to three, each
 * PX,PY,PZ,NX,NY,NZ: a point and the normal of the side cut away (not
 * zero). m the measuring chain (ms_viewer_measure.h), at most 16 points,
 * each X,Y,Z,DX,DY,DZ: where it lies and its ray's direction, cast again on
 * the model as it streams in. The fields come in this order, without spaces
 * (the text needs no quoting in a shell). Numbers are printed in the
 * shortest form that reads back to the same double, so printing what was
 * parsed gives the text back and parsing what was printed gives the state
 * back, bit for bit.
 *
 * Pure functions; thread-safe.
 */
#ifndef MS_VIEWER_SHARE_H
#define MS_VIEWER_SHARE_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_error.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_light.h"
#include "ms_viewer_measure.h"
#include "ms_viewer_section.h"

/* Longest text, terminator included: a longer one is refused. */
#define MS_VIEWER_SHARE_MAX 4096

typedef struct ms_viewer_share {
    double target[3], distance, yaw, pitch, fovy_degrees;
    int up_axis;
    ms_viewer_light light;
    ms_viewer_sections sections; /* copied by the caller of _take and _give */
    size_t points;
    double anchor[MS_VIEWER_MEASURE_MAX_POINTS][3], direction[MS_VIEWER_MEASURE_MAX_POINTS][3];
} ms_viewer_share;

/* Reads a text; MS_ERR_FORMAT with one line saying what is wrong (the state
 * undefined) otherwise. */
ms_status ms_viewer_share_parse(const char *text, ms_viewer_share *share, ms_error *err);

/* Writes the text (at most MS_VIEWER_SHARE_MAX bytes with the terminator;
 * size must allow that). */
void ms_viewer_share_print(const ms_viewer_share *share, char *text, size_t size);

/* The state of the controls, the light and the chain (NULL: none). */
void ms_viewer_share_take(const ms_viewer_controls *controls, const ms_viewer_light *light,
                          const ms_viewer_measure *measure, ms_viewer_share *share);

/* Sets the controls' view (their home kept), the light and the chain (each
 * may be NULL: left alone); fly mode off. */
void ms_viewer_share_give(const ms_viewer_share *share, ms_viewer_controls *controls, ms_viewer_light *light,
                          ms_viewer_measure *measure);

/* Exactly n finite numbers separated by sep, the whole text; false otherwise. */
bool ms_viewer_numbers(const char *text, char sep, double *out, size_t n);

#endif
