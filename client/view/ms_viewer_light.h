/* meshview's light (docs/VIEWER.md, "Light"): by default the head light (at
 * the eye, shining where it looks); once set, a directional light given in
 * the camera's frame by azimuth and elevation in degrees, so it stays where
 * it is on the screen while the camera orbits, and moves only when the light
 * is moved (a Ctrl drag, the L key's raking presets, --light, --view).
 *
 * Directions: in eye space (x right, y up, z towards the viewer) the light
 * lies along (cos el sin az, sin el, cos el cos az): az 0, el 0 shines from
 * the eye along the view; az > 0 from the right, el > 0 from above. A face
 * seen head-on then gets L . N = cos el cos az. Azimuth in (-180, 180],
 * elevation in [-90, 90].
 *
 * Raking presets (L): from the left, the top, the right and the bottom at 80
 * degrees from the view axis (10 degrees above a face seen head-on), then the
 * head light again.
 *
 * Pure functions on a caller-owned value; thread-safe.
 */
#ifndef MS_VIEWER_LIGHT_H
#define MS_VIEWER_LIGHT_H

#include <stdbool.h>

#include "ms_camera.h"
#include "ms_render.h"

typedef struct ms_viewer_light {
    bool directional;      /* false: the head light */
    double azimuth_deg, elevation_deg;
} ms_viewer_light;

/* "AZ,EL" in degrees (each a number, azimuth in [-180, 180], elevation in
 * [-90, 90]); false, the light unchanged, otherwise. */
bool ms_viewer_light_parse(const char *text, ms_viewer_light *light);

/* The light's direction (towards the light, unit) in eye space, and in world
 * coordinates for camera; the head light's is the view's reverse. */
void ms_viewer_light_eye(const ms_viewer_light *light, double eye[3]);
void ms_viewer_light_world(const ms_viewer_light *light, const ms_camera *camera, double world[3]);

/* Makes the options' first (and only) light this one, white, for camera. */
void ms_viewer_light_apply(const ms_viewer_light *light, const ms_camera *camera, ms_render_options *options);

/* A Ctrl drag of (dx, dy) framebuffer pixels (y down) on a framebuffer
 * `height` tall: half a turn of azimuth across the height, the elevation
 * following the cursor up, clamped at the poles. From the head light it
 * starts at az 0, el 0. */
void ms_viewer_light_drag(ms_viewer_light *light, double dx, double dy, double height);

/* The L key: the next raking preset (see above). */
void ms_viewer_light_next_preset(ms_viewer_light *light);

/* "head light" or "light az A el E deg" into text. */
void ms_viewer_light_describe(const ms_viewer_light *light, char *text, size_t size);

#endif
