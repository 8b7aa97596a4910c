/* meshview's section planes (docs/VIEWER.md, "Sections"): one to three planes
 * that cut the model, each a point and a normal in model coordinates; the side
 * the normal points to is cut away (a point p is kept where
 * normal . (p - point) <= 0). The renderer clips with them and draws the
 * inside seen through the cut in the section colour (ms_render.h); the client
 * core requests the cells wholly cut away last (ms_core_set_sections).
 *
 * Text (--section, repeatable): ms_section.h.
 *
 * Keys (in the window, one model): Y adds a plane through the orbit centre,
 * across the axis nearest the view direction, cutting away the half towards
 * the eye; J turns the last plane over; 9 / 0 move it back / forward along its
 * normal by 1/50 of the model's box (forward: less is cut away); I removes it.
 *
 * Pure functions on a caller-owned value; thread-safe.
 */
#ifndef MS_VIEWER_SECTION_H
#define MS_VIEWER_SECTION_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_camera.h"
#include "ms_error.h"
#include "ms_render.h"

typedef struct ms_viewer_sections {
    size_t count;
    double point[MS_SECTIONS_MAX][3], normal[MS_SECTIONS_MAX][3];
} ms_viewer_sections;

/* Adds the plane a text gives (ms_section_parse). MS_ERR_FORMAT with one line (the
 * sections unchanged) for a bad text, MS_ERR_RANGE when three are held. */
ms_status ms_viewer_sections_add_text(ms_viewer_sections *sections, const char *text, ms_error *err);

/* Adds a plane; false (unchanged) when three are held, the normal is zero or a
 * number is not finite. */
bool ms_viewer_sections_add(ms_viewer_sections *sections, const double point[3], const double normal[3]);

/* The planes a b c d (a b c the normal, d = -normal . point): the side
 * a x + b y + c z + d > 0 is cut away; returns the count. */
size_t ms_viewer_sections_planes(const ms_viewer_sections *sections, double planes[MS_SECTIONS_MAX][4]);

/* Into the render options (their section colour kept). */
void ms_viewer_sections_apply(const ms_viewer_sections *sections, ms_render_options *options);

/* The keys (GLFW_KEY_*): Y, J, 9, 0, I as above, for a camera looking along
 * forward at the orbit centre `target`, a model box of side box_side. True
 * when the key is one of them. */
bool ms_viewer_sections_key(ms_viewer_sections *sections, int key, const double forward[3], const double target[3],
                            double box_side);

/* "section x=0.25" for an axis plane through a point on that axis' line
 * through the others' 0, else "section 1 at (px, py, pz) normal (nx, ny, nz)";
 * "sections: 2 ..." for several (the HUD line). Empty text for none. */
void ms_viewer_sections_describe(const ms_viewer_sections *sections, char *text, size_t size);

#endif
