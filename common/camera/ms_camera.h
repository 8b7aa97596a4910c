/* Camera, frustum culling and screen-space error: the maths the client runs every
 * frame to choose which nSP cells to show and at what precision.
 *
 * World coordinates are doubles (the model's units). A camera looks from
 * `position` along `forward`, with `up` orthogonal to it, a vertical field of
 * view `fovy` (radians) and a viewport in pixels. A kd-cell at q bits of a model
 * whose quantisation cube has side S is a cube of side S / 2^q; the error of a
 * vertex drawn at its cell centre is at most half the cell diagonal, and we use
 * the whole diagonal √3·S/2^q as the conservative bound.
 *
 * All functions are pure; thread-safe.
 */
#ifndef MS_CAMERA_H
#define MS_CAMERA_H

#include <stdbool.h>

#include "ms_error.h"

typedef struct ms_camera {
    double position[3];
    double forward[3];  /* unit */
    double up[3];       /* unit, orthogonal to forward */
    double right[3];    /* unit, forward x up */
    double fovy;        /* radians, in (0, pi) */
    double width, height; /* viewport in pixels, >= 1 */
    double near_distance, far_distance; /* > 0, far > near */
} ms_camera;

/* Builds a camera at position looking at target. up need only be roughly up.
 * fovy_degrees in (0, 180). MS_ERR_ARG for NaN/infinite input, position equal to
 * target, up parallel to the view direction, or an empty viewport. */
ms_status ms_camera_look_at(const double position[3], const double target[3],
                            const double up[3], double fovy_degrees, double width,
                            double height, double near_distance, double far_distance,
                            ms_camera *camera, ms_error *err);

/* Pixels covered by one world unit seen face-on at distance 1: H / (2 tan(fovy/2)). */
double ms_camera_pixels_per_unit(const ms_camera *camera);

/* At most this many section planes (docs/VIEWER.md, "Sections") cut a view. */
#define MS_SECTIONS_MAX 3
/* The flat colour, 8-bit sRGB, both renderers draw the cut's inside in (the
 * back faces seen through the cut: docs/RENDERER.md, "Sections"). */
#define MS_SECTION_R 214
#define MS_SECTION_G 64
#define MS_SECTION_B 48

/* The six frustum planes, normals pointing inwards: a point p is inside plane k
 * when dot(normal_k, p) + offset_k >= 0; then up to MS_SECTIONS_MAX section
 * half-spaces, the same way (ms_frustum_add_section), 0 from
 * ms_camera_frustum. */
typedef struct ms_frustum {
    double normal[6][3];
    double offset[6];
    unsigned sections;
    double section_normal[MS_SECTIONS_MAX][3];
    double section_offset[MS_SECTIONS_MAX];
} ms_frustum;

void ms_camera_frustum(const ms_camera *camera, ms_frustum *frustum);

/* Adds a section plane (a b c d): the points p with a p0 + b p1 + c p2 + d > 0
 * are cut away, those with <= 0 kept. False (nothing added) when the frustum
 * holds MS_SECTIONS_MAX already, or (a, b, c) is zero or a number is not
 * finite. */
bool ms_frustum_add_section(ms_frustum *frustum, const double plane[4]);

/* True when the box [lo, hi] intersects the frustum grown by margin (world units)
 * on every side (conservative: may keep a box slightly outside near a corner),
 * and no section cuts it wholly away (a box within margin of the kept side is
 * kept). */
bool ms_frustum_keeps_box(const ms_frustum *frustum, const double lo[3], const double hi[3],
                          double margin);

/* Distance from the camera position to the nearest point of the box (0 inside). */
double ms_camera_box_distance(const ms_camera *camera, const double lo[3], const double hi[3]);

/* Clipping distances for an eye at position that keep the whole box [lo, hi]
 * (world units) between the planes, whatever the eye's distance: far a little
 * past the box's farthest corner, near half the way to its nearest point but
 * never under far * 5e-5 (the eye inside or at the box). A fixed range loses
 * a model that is small on screen behind the far plane. A box with a NaN or
 * infinite coordinate, or lo above hi, gives near 1e-4 and far 1e4. */
void ms_camera_depth_range(const double position[3], const double lo[3], const double hi[3],
                           double *near_distance, double *far_distance);

/* The home view of a model whose bounds are the box [lo, hi] (world units) on
 * a width x height viewport: meshview's (its R key, client/view
 * ms_viewer_controls.h), which the thumbnails meshbake renders use too
 * (docs/ARCHIVE.md, "Thumbnails"). With up_axis (0 x, 1 y, 2 z; another value:
 * z) as world up, h0 = the axis after it twice and h1 = the axis after it
 * (z-up: h0 = y, h1 = x), the eye looks at the box's centre from yaw
 * 0.35 rad (plus a quarter turn when the box is longer along h0 than along
 * h1, to look across it) and pitch -0.3 rad (from above): forward =
 * -cos(pitch) (cos(yaw) h0 + sin(yaw) h1) + sin(pitch) up. The vertical field
 * of view is 40 degrees; the distance frames the sphere of 1.05 times half the
 * box's diagonal (half its largest side, or 0.5, for an empty box): radius /
 * sin(half the narrower field). Near and far from ms_camera_depth_range.
 * MS_ERR_ARG for a non-finite box or an empty viewport. */
ms_status ms_camera_home(const double lo[3], const double hi[3], int up_axis, double width,
                         double height, ms_camera *camera, ms_error *err);

/* The geometric error on screen, in pixels, of a cut at `bits` of a model whose
 * cube has side `cube_side`, seen at `distance`: the half-diagonal of a
 * kd-cell, (√3 / 2) · cube_side / 2^bits, projected. A decoded vertex sits at
 * its cell's centre and the true vertex inside the cell, and a coarse
 * triangle is the image of fine ones under that vertex map, so no point of
 * the surface moves further (docs/CLIENT.md, "The error of a cut").
 * +infinity at distance 0. */
double ms_screen_error_px(const ms_camera *camera, double cube_side, unsigned bits,
                          double distance);

/* The precision, as a real number of bits, at which ms_screen_error_px is
 * `tolerance_px`: log2((√3 / 2) · cube_side · pixels_per_unit / (distance ·
 * tolerance_px)). +infinity at distance 0. */
double ms_screen_bits_needed(const ms_camera *camera, double cube_side, double distance,
                             double tolerance_px);

/* APO fetched by footprint: how many levels of the APO chunk of a cell whose
 * cube is [cube_lo, cube_lo + cube_side]^3 (world units) are worth fetching for
 * the camera. A texel at depth d of the chunk is a cube of side
 * cube_side / 2^d (docs/APO.md); seen at the cube's nearest point, at distance
 * D (ms_camera_box_distance, but not nearer than the near plane: nothing
 * nearer is drawn), it covers
 *     px(d) = cube_side / 2^d * ms_camera_pixels_per_unit(camera) / D
 * pixels. The chunk is wanted down to the first depth whose texel projects to
 * at most tolerance_px, and no deeper:
 *     d* = max(0, ceil(log2(cube_side * pixels_per_unit / (D * tolerance_px))))
 * (with a 1e-9 allowance, so that a texel projecting exactly to the tolerance
 * counts as within it): d* + 1 levels (depths 0 .. d*), clamped to max_levels
 * (the caller's cap: the client's apo_levels, the chunk's stored levels).
 * Unlike ms_screen_bits_needed, no sqrt(3): the texel's side, not its
 * diagonal, is held against the tolerance (a texel is one normal, not a
 * position error). Returns 0 only when max_levels is 0; tolerance_px > 0. */
unsigned ms_apo_footprint_levels(const ms_camera *camera, const double cube_lo[3], double cube_side,
                                 double tolerance_px, unsigned max_levels);

/* The integer precision in [min_bits, max_bits] to show, given the current one
 * and the real-valued need: refine at once to ceil(need); coarsen only when at
 * least one bit can go with `hysteresis` bits to spare (e.g. the default
 * below), so that a cell does not flicker between two precisions when the
 * camera hovers at a boundary. */
unsigned ms_select_bits(double need, unsigned current, unsigned min_bits, unsigned max_bits,
                        double hysteresis);

/* The clients' default hysteresis: a cell coarsens once the camera is 15 %
 * farther than where it would have refined. A bit held is four times a
 * surface's triangles: with half a bit, a model moving away kept one bit
 * more than a fresh view over a 41 % band of distances (the demo 60, 30 and
 * 15 px tall: 23, 54 and 72 triangles per covered pixel against 14, 17 and
 * 19; test_core_far). */
#define MS_SELECT_HYSTERESIS_DEFAULT 0.2

#endif
