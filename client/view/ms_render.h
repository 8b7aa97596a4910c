/* The GPU side of meshview: draws a frame of the client core (ms_client_core.h)
 * cell by cell, shaded with the APO shader (docs/APO.md, "Traversal"; the GLSL
 * lives in client/view/shaders/ and is embedded at build time).
 *
 * Cells. A frame's stitched mesh (ms_view_mesh) is split by triangle_cell into one
 * vertex/index buffer per drawing cell. Vertices go to the GPU in cell-local
 * coordinates: (world - cube origin) / cube side, as floats in about [0, 1]
 * (a stitched corner snapped into a neighbour lies slightly outside). The cube is
 * the cell's own (header box divided by n^level at the cell's position). The
 * cell-to-eye transform is computed in doubles on the CPU each draw, so 20-bit
 * models far from the origin keep their precision.
 *
 * Uploads. ms_render_set_frame derives again only the cells whose triangles
 * may have changed (the mesh's run versions) and their neighbours
 * (ms_render_frame_stats), and queues those whose drawn triangles, vertex
 * positions or vertex normals changed since the previous frame (per-cell
 * content hash); ms_render_upload sends queued data to the GPU within a byte budget per
 * call (a cell larger than the budget goes up in pieces over several calls). A
 * cell keeps drawing its previous mesh until its new one is wholly on the GPU;
 * cells absent from the new frame stop drawing at once.
 *
 * APO. Each drawn cell with a chunk prefix in the frame gets its texel words
 * (decompressed) in one unsigned-integer buffer texture shared by all cells; the
 * shader walks the octree with texelFetch, children addressed with bitCount on
 * the child mask, and reads a level not wholly received as absent, exactly as
 * ms_apo_lookup (ms_apo_traverse.h) with depth_cap and the missing-child rule of
 * the options. Where APO is not used (a cell without a chunk or whose prefix did
 * not load, or APO off), N is the smooth vertex normal (options.smooth) or the
 * triangle's flat normal.
 *
 * Vertex normals. They are those of the whole stitched mesh (made only for
 * the cells derived, from the fans of the cells around them), so they are
 * continuous across cell borders: around each
 * vertex, the triangles across edges sharper than the crease angle
 * (ms_render_set_crease_angle, default MS_RENDER_CREASE_ANGLE_DEFAULT) widened
 * by how far each of the two triangles' normals may be off (its corners' decode
 * error, 0 at full precision, over its smallest height: the arctangent), or
 * across edges of one or of more than two triangles, fall in different groups,
 * each with its own
 * normal (the sum of its unnormalised face normals: area-weighted); a triangle
 * wound against its neighbour (the edge used twice in the same direction) is
 * turned over for the sum, and its corners get the group's normal turned to
 * its own winding, so a scan with inconsistently oriented faces shades as a
 * consistent one (with the two-sided effect). A mesh vertex with several
 * normals goes up as several vertices. They go up as a second vertex attribute (GL_INT_2_10_10_10_REV,
 * normalised: 4 bytes per vertex, after the 12 of the position) and are part of
 * the cell's content hash: a cell whose vertex normals changed because a
 * neighbour refined around a shared border vertex is uploaded again.
 *
 * Vertex colours. A mesh with colours (ms_view_mesh.colours: r g b a per
 * vertex, 8-bit sRGB as scanned) gives every cell vertex its mesh vertex's
 * colour, a third vertex attribute (GL_UNSIGNED_BYTE normalised, 4 bytes per
 * vertex after the normals: 20 bytes per vertex instead of 16), part of the
 * cell's content hash, so a cell whose colours changed is uploaded again. The
 * cells derived again are those whose version changed: the data path changes
 * a run's version when its corners' colours change, as when its positions do
 * (a mesh without runs hashes the colours into the version), and a mesh
 * gaining or losing its colours derives every cell. Where a cell has colours,
 * they are the albedo: interpolated across the triangle as sRGB values and
 * made linear per pixel; the normals (APO, smooth or flat) only shade. A mesh
 * without colours draws as before, with options.albedo, to the byte.
 *
 * Shading (ms_render_options.shading):
 *   MS_SHADING_LIT      the options' lights (default: a head light at the
 *                       camera): albedo (the vertex colours where the cell
 *                       has them) times (0.05 + 0.95 * sum of Lambert),
 *                       plus the Blinn-Phong highlight (specular effect) with the
 *                       normal N (APO, smooth or flat), each light's terms times
 *                       the self-shadowing factor: max(0, L . N_geometric) where
 *                       N is an APO normal, else max(0, L . N) (meshrender's
 *                       lighting model: a flat face under the head light goes
 *                       as (N . L)^2); then haze (haze effect):
 *                       mix(haze colour, colour, exp(-density * eye distance));
 *                       gamma-correct (sRGB) output.
 *   MS_SHADING_NORMALS  N as a colour, rgb = (N + 1) / 2, linear (no gamma), N in
 *                       world coordinates, so a test can read it back exactly.
 *   MS_SHADING_CELLS    LIT tinted by a colour hashed from the cell number.
 *   MS_SHADING_CELL_ID  rgb = the drawing cell's number + 1 as 24 bits (r low
 *                       byte), a = 1; 0 is background. For picking and tests.
 *   MS_SHADING_ALBEDO   unlit: the vertex colours interpolated as they are
 *                       (no gamma step, so a pixel at a vertex is its 8-bit
 *                       colour), or options.albedo sRGB-encoded for a cell
 *                       without; the background as LIT's. No normal is used;
 *                       wireframe overlays. The picture to compare with
 *                       meshrender --albedo (ms_render_picture.h).
 * N_geometric is the flat normal of the triangle (oriented as stored, facing the
 * camera side of front faces; with the two-sided effect and options.two_sided, a
 * back face's is turned towards the camera). wireframe overlays the triangle
 * edges.
 *
 * Composed programs. The fragment shader holds only the effects of
 * options.effects (ms_render_program_source): one program per effect set and
 * wireframe variant, built the first time it is drawn with and kept; a scene
 * draws with the effects it calls for (ms_scene_effects), so an effect it does
 * not use is not compiled in. Likewise per draw: vertex colours only when a
 * drawn cell has them, sections only with a plane, and the light loop with the
 * options' light count and kinds fixed (docs/RENDERER.md, "Variants").
 * ms_render_draw_stats says which effects the program held and which of them
 * changed the picture.
 *
 * GL memory. The renderer counts the bytes of storage it asks of GL: every
 * buffer's size as given to glBufferData (a cell's vertex buffer, 16 bytes per
 * vertex, 20 with colours, and index buffer, 12 bytes per triangle, counted from the first piece
 * of their upload until they are deleted, so a cell refining holds its old and
 * new buffers at once; the APO texel buffer, 4 bytes per word of its capacity,
 * which grows by doubling and never shrinks, both buffers counted while a growth
 * copies; the warm-up's 60 bytes while it draws). The buffer texture over the
 * texel buffer adds no storage. Compiled programs, vertex arrays and whatever
 * the driver keeps of its own (shadow copies, compiled shader variants, the
 * window's framebuffers) are not counted: the driver does not say.
 * ms_render_memory gives the figures (docs/VIEWER.md, "Memory").
 *
 * Camera. The projection is OpenGL's perspective from ms_camera (fovy, width /
 * height aspect, near and far distance), clip depth in [-1, 1], window depth in
 * [0, 1]; ms_render_camera_matrices and ms_render_unproject give it to callers in
 * doubles (double-click re-centring, tests).
 *
 * Requires: a current OpenGL 4.1 core context (ms_gl_window.h) on the calling
 * thread, for every function except ms_render_camera_matrices,
 * ms_render_unproject (pure) and ms_render_memory.
 * Ownership: the renderer copies what it keeps of a frame; the caller keeps the
 * frame. Errors: ms_status with one line (MS_ERR_UNSUPPORTED when a shader does
 * not compile or link, with the driver's log's first line; MS_ERR_NOMEM).
 * Thread-safety: one renderer per context, used from the context's thread.
 */
#ifndef MS_RENDER_H
#define MS_RENDER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_client_core.h"
#include "ms_error.h"
#include "ms_view_decoder.h"

typedef struct ms_render ms_render;

typedef enum ms_shading {
    MS_SHADING_LIT = 0,
    MS_SHADING_NORMALS = 1,
    MS_SHADING_CELLS = 2,
    MS_SHADING_CELL_ID = 3,
    MS_SHADING_ALBEDO = 4
} ms_shading;

/* Effects a shader program can hold (bits). Each is compiled in only when the
 * program is built with its bit (ms_render_program_source); the single-model
 * viewer builds MS_EFFECTS_VIEWER, a scene the effects it calls for
 * (ms_scene_effects, docs/SCENES.md). */
typedef enum ms_effect {
    MS_EFFECT_DETAIL_NORMALS = 1 << 0, /* APO normals, with the self-shadowing factor */
    MS_EFFECT_SPECULAR = 1 << 1,       /* Blinn-Phong highlight (glossy materials) */
    MS_EFFECT_TWO_SIDED = 1 << 2,      /* a back face lit as its other side (open scans) */
    MS_EFFECT_HAZE = 1 << 3,           /* exponential haze with distance */
    MS_EFFECT_IMPOSTORS = 1 << 4,      /* image stand-ins for far objects */
    MS_EFFECT_DISPLACEMENT = 1 << 5    /* tessellated relief on declared surfaces */
} ms_effect;
#define MS_EFFECT_COUNT 6
#define MS_EFFECTS_ALL ((1u << MS_EFFECT_COUNT) - 1)
/* What meshview drew before scenes: APO, the head light's highlight, two-sided. */
#define MS_EFFECTS_VIEWER (MS_EFFECT_DETAIL_NORMALS | MS_EFFECT_SPECULAR | MS_EFFECT_TWO_SIDED)

/* The effect's name in scene files and reports ("detail_normals", "specular",
 * "two_sided", "haze", "impostors", "displacement"); NULL for anything but one
 * bit of MS_EFFECTS_ALL. */
const char *ms_effect_name(unsigned effect);

/* A light in world coordinates (the scene's; the model's own for a lone model). */
typedef enum ms_render_light_kind {
    MS_RENDER_LIGHT_HEAD = 0,        /* at the eye, shining where it looks, no falloff */
    MS_RENDER_LIGHT_DIRECTIONAL = 1, /* vector: direction towards the light (need not be unit) */
    MS_RENDER_LIGHT_POINT = 2        /* vector: position; falloff 1 / (1 + (d / range)^2) */
} ms_render_light_kind;

#define MS_RENDER_MAX_LIGHTS 8

typedef struct ms_render_light {
    ms_render_light_kind kind;
    float colour[3];          /* linear RGB times intensity */
    double vector[3];
    double range;             /* point lights: > 0 */
} ms_render_light;

typedef struct ms_render_options {
    ms_shading shading;
    bool apo;                 /* APO normals where a chunk is held; false: geometric */
    bool wireframe;           /* overlay triangle edges */
    uint32_t apo_depth_cap;   /* 0: no cap */
    bool apo_nearest;         /* missing child: MS_APO_MISSING_NEAREST (true) or STOP
                                 (default: the smooth normal, what a correction chunk means) */
    bool apo_filter;          /* 8-cell interpolation between neighbouring texels
                                 (ms_apo_lookup_filtered; default true) or the
                                 nearest node (ms_apo_lookup) */
    bool apo_footprint;       /* octree mip-mapping: the depth is also capped at
                                 ms_apo_footprint_depth of the fragment's footprint
                                 (ms_render_apo_footprint_scale), the first level
                                 whose texels fit in the pixel (default true) */
    float background[3];      /* linear RGB the colour buffer is cleared to */
    bool smooth;              /* interpolated vertex normals (true) or each triangle's
                                 flat normal (false), also where an APO chunk has no texel */
    /* Scenes (docs/SCENES.md). The defaults draw a lone model as before scenes. */
    unsigned effects;         /* MS_EFFECT_* compiled into the program drawn with
                                 (built on first use, kept); default MS_EFFECTS_VIEWER */
    float albedo[3];          /* linear; default 0.72 0.69 0.64 */
    float specular;           /* highlight strength, [0, 1]; default 0.18 (needs MS_EFFECT_SPECULAR) */
    float shininess;          /* Blinn-Phong exponent, >= 1; default 40 */
    bool two_sided;           /* back faces lit as their other side; default true
                                 (needs MS_EFFECT_TWO_SIDED) */
    float haze_density;       /* per world unit of eye distance, >= 0; default 0 (needs MS_EFFECT_HAZE) */
    float haze_colour[3];     /* linear */
    ms_render_light lights[MS_RENDER_MAX_LIGHTS];
    unsigned light_count;     /* default 1: a white head light */
    bool placed;              /* draw the model through placement (model to world,
                                 column-major, rotation times uniform scale plus a
                                 translation); default false: identity */
    double placement[16];
    bool clear;               /* clear colour and depth first (default true); false
                                 draws over what is there (several models in one frame) */
    /* Displacement (needs MS_EFFECT_DISPLACEMENT in effects; "Displacement"
     * above): the surface drawn as tessellated patches with relief. */
    bool displace;            /* default false */
    float displacement_amplitude; /* model units, > 0 (default 0.01) */
    float displacement_radius;    /* an atom's radius, model units, > 0 (default 0.05) */
    float displacement_density;   /* atoms per square unit, > 0 (default 100) */
    uint32_t displacement_seed;
    float tess_pixels_per_level;  /* projected edge pixels per tessellation level, >= 1 (default 8) */
    /* The switch to an impostor (ms_render_impostor.h; needs MS_EFFECT_IMPOSTORS):
     * the pixels of a 4x4 Bayer pattern below dissolve are left out, for the
     * impostor to draw. Default 0: all drawn. */
    float dissolve;
    /* Sections (docs/RENDERER.md, "Sections"): up to MS_SECTIONS_MAX planes a
     * b c d in model coordinates cut away the side a x + b y + c z + d > 0
     * (gl_ClipDistance in every program); a back face seen through the cut
     * draws in section_colour, flat (8-bit sRGB; LIT, CELLS and ALBEDO
     * shading). Default none, MS_SECTION_R G B. */
    unsigned section_count;
    double sections[MS_SECTIONS_MAX][4];
    uint8_t section_colour[3];
} ms_render_options;

/* LIT, APO on, no wireframe, no cap, STOP rule, dark grey background,
 * smooth; effects MS_EFFECTS_VIEWER with the plaster albedo, a 0.18 highlight of
 * exponent 40, two-sided, no haze, one head light, no placement, clear. */
void ms_render_options_default(ms_render_options *options);

/* Compiles the shaders and sets up the buffers for a model: its header and
 * either its whole index (cells: header.cell_count records, copied) or NULL,
 * the records then learned as frames bring them (ms_render_learn, an index by
 * subtree: docs/CLIENT.md). Per-cell state is held per sibling group for the
 * groups of the cells the latest frame draws, never for the whole model.
 * header and cells both NULL: the programs and buffers only, the model given
 * later by ms_render_set_model (a viewer compiles while the model's index head
 * is on its way); until then ms_render_learn and ms_render_set_frame are
 * MS_ERR_ARG and nothing is drawn. */
ms_status ms_render_new(const ms_archive_header *header, const ms_archive_cell *cells,
                        ms_render **render, ms_error *err);

/* The model of a renderer made without one (its header, copied; the records
 * come by ms_render_learn). MS_ERR_ARG for a bad header or a renderer that
 * already has a model; MS_ERR_NOMEM. */
ms_status ms_render_set_model(ms_render *render, const ms_archive_header *header, ms_error *err);

/* Learns the records of cells ids[0..count) (copied), for the next
 * ms_render_set_frame: every cell a frame draws must have its record, learned
 * since the previous frame or from the whole index (a frame's shown cells:
 * ms_core_frame.records). Learned records are forgotten with their group's
 * state once no cell of the group is in a frame. MS_ERR_ARG for an id beyond
 * the model or a record outside its level (nothing learned then),
 * MS_ERR_NOMEM. */
ms_status ms_render_learn(ms_render *render, const uint32_t *ids, const ms_archive_cell *records,
                          size_t count, ms_error *err);
/* The crease angle, degrees: an edge whose two triangles' normals differ by
 * more splits the vertex normals along it (a hard edge); 180 keeps every
 * manifold edge smooth, 0 splits every edge that is not flat. */
#define MS_RENDER_CREASE_ANGLE_DEFAULT 60.0

/* Sets the crease angle (degrees, [0, 180]) for the frames set from now on
 * (set the same frame again to redraw it with the new angle). MS_ERR_ARG
 * outside the range or NaN. */
ms_status ms_render_set_crease_angle(ms_render *render, double degrees, ms_error *err);

/* The crease angle in effect, degrees. */
double ms_render_crease_angle(const ms_render *render);

/* Frees every GL object and the renderer. NULL is a no-op. */
void ms_render_free(ms_render *render);

/* A new frame to draw: the stitched mesh and the APO chunk prefixes of the core's
 * frame (apo may be NULL when apo_count is 0). Queues the changed cells.
 * MS_ERR_ARG for a bad mesh or a drawing cell whose record is unknown. */
ms_status ms_render_set_frame(ms_render *render, const ms_view_mesh *mesh,
                              const ms_core_apo_chunk *apo, size_t apo_count, ms_error *err);

/* The work of the latest ms_render_set_frame. A cell's mesh (renumbered
 * vertices, corner normals, packing, content hash) is made again only when
 * its triangles changed (the mesh's run version, ms_view_mesh; a hash of its
 * corners for a mesh without runs) or when it shares a vertex with what such a
 * cell, or one that left the frame, drew before or draws now and its corner
 * normals there moved (such a neighbour is looked at: its corners at those
 * vertices compared); every other cell keeps its mesh without being looked at
 * beyond its version. A frame like the previous one derives nothing. */
typedef struct ms_render_frame_stats {
    uint32_t cells_present;    /* cells with triangles in the frame */
    uint32_t cells_changed;    /* of them, new or with another version */
    uint32_t cells_left;       /* cells of the previous frame not in this one */
    uint32_t cells_derived;    /* cells looked at: the changed cells and their neighbours */
    uint64_t vertex_fans;      /* vertices whose normals were made */
    uint64_t face_normals;     /* triangles whose face normals were made */
    uint32_t cells_rebuilt;    /* meshes made again (renumbered, packed, hashed): the
                                  changed cells and the neighbours_moved */
    uint32_t neighbours_moved; /* of cells_rebuilt, unchanged cells whose corner normals
                                  moved (a changed neighbour around a shared vertex) */
    uint32_t cells_queued;     /* of cells_rebuilt, meshes that differ from what the cell
                                  draws or waits for: queued for upload */
    uint64_t triangles_rebuilt;  /* triangles of the cells_rebuilt */
    uint64_t triangles_walked;   /* triangles of the unchanged neighbours looked at (their
                                    corners at the changed vertices) */
} ms_render_frame_stats;

/* The figures of every ms_render_set_frame since ms_render_new, summed
 * (cells_present summed too: what reading every cell's version costs). */
typedef struct ms_render_frame_totals {
    uint64_t frames;
    uint64_t cells_present, cells_changed, cells_left, cells_derived;
    uint64_t vertex_fans, face_normals;
    uint64_t cells_rebuilt, neighbours_moved, cells_queued;
    uint64_t triangles_rebuilt, triangles_walked;
} ms_render_frame_totals;

/* The figures of the latest ms_render_set_frame (zeros before the first). */
void ms_render_frame_stats_get(const ms_render *render, ms_render_frame_stats *stats);
void ms_render_frame_totals_get(const ms_render *render, ms_render_frame_totals *totals);

typedef struct ms_render_upload_stats {
    uint64_t bytes;            /* sent to the GPU by this call (vertices, indices, texels) */
    uint32_t cells_completed;  /* cells whose new mesh became current in this call */
    uint32_t cells_pending;    /* changed cells still waiting for their turn */
} ms_render_upload_stats;

/* Uploads queued data, at most budget_bytes (> 0) in this call. */
ms_status ms_render_upload(ms_render *render, uint64_t budget_bytes, ms_render_upload_stats *stats,
                           ms_error *err);

/* The renderer's GL memory ("GL memory" above), bytes. */
typedef struct ms_render_memory_stats {
    uint64_t gl_bytes;         /* every buffer and texture held now */
    uint64_t gl_bytes_peak;    /* the most gl_bytes has been since ms_render_new */
    uint64_t mesh_bytes;       /* of gl_bytes: the cells' vertex and index buffers
                                  (current and being uploaded) */
    uint64_t texel_bytes;      /* of gl_bytes: the APO texel buffer's capacity */
    uint64_t texel_used_bytes; /* of texel_bytes: words handed to cells, 4 bytes each */
} ms_render_memory_stats;

/* The figures now; all 0 for a NULL renderer. Needs no GL context. */
void ms_render_memory(const ms_render *render, ms_render_memory_stats *stats);

/* Displacement. With options.displace and the displacement effect, the cells
 * are drawn as triangle patches through tessellation stages (shaders/tess.*):
 * each edge's level is the projected size in pixels of the sphere on the
 * edge's midpoint whose diameter is the edge (both patches of an edge agree:
 * no cracks) over tess_pixels_per_level, in [1, 64], the inner level the
 * largest; a patch wholly outside the frustum gets level 1; each new vertex
 * moves along its patch's normal by the relief of height atoms scattered on a
 * jittered grid in the patch's plane (seeded, so deterministic); the flat
 * normal from screen derivatives shades the relief. Meant for flat surfaces
 * (a room's floor and walls): where patches of different planes meet, their
 * relief differs. */

typedef struct ms_render_draw_stats {
    uint32_t cells_drawn;
    uint64_t triangles_drawn;
    unsigned effects_compiled; /* MS_EFFECT_* of the program drawn with */
    unsigned effects_ran;      /* those of them that changed a pixel's shading in
                                  this draw: detail normals where a drawn cell used
                                  APO, specular with a strength > 0, two-sided on,
                                  haze with a density > 0 (LIT and CELLS shading),
                                  displacement when displaced patches were drawn */
} ms_render_draw_stats;

/* Clears the bound framebuffer (colour to options->background, depth to 1), sets
 * the viewport to the camera's width x height (framebuffer pixels) and draws
 * every current cell. stats may be NULL. */
ms_status ms_render_draw(ms_render *render, const ms_camera *camera,
                         const ms_render_options *options, ms_render_draw_stats *stats,
                         ms_error *err);

/* The fragment shader's source composed for a set of effects (MS_EFFECT_* bits
 * within MS_EFFECTS_ALL) and the wireframe variant: the embedded
 * shaders/cell.frag.glsl with, after its #version line, the wireframe define,
 * the APO traversal only with MS_EFFECT_DETAIL_NORMALS, and each
 * "#ifdef MS_EFFECT_<NAME>" ... "#else" ... "#endif" block resolved: an effect
 * not in the set leaves no line of its own in the result. *source is malloc'd
 * (caller frees). Pure (no GL). MS_ERR_ARG for bits outside MS_EFFECTS_ALL,
 * MS_ERR_FORMAT for unbalanced blocks, MS_ERR_NOMEM. */
ms_status ms_render_program_source(unsigned effects, bool wireframe, char **source, ms_error *err);

/* Column-major view (world to eye) and projection matrices the renderer draws
 * with, in doubles. */
void ms_render_camera_matrices(const ms_camera *camera, double view[16], double projection[16]);

/* The APO footprint of a pixel per unit of eye depth, in units of a cube of
 * side cube_side (eye units): 2 tan(fovy / 2) / (height * cube_side), as a
 * float. A fragment at eye depth z (distance along the view direction) covers
 * z times this in its cell's local coordinates; ms_apo_footprint_depth of that
 * is the depth the shader stops at with options.apo_footprint. It is the
 * thesis's min(|dFdx p|, |dFdy p|) without the surface's slope, exact and the
 * same on the CPU. */
float ms_render_apo_footprint_scale(const ms_camera *camera, double cube_side);

/* World point seen at framebuffer pixel (x, y), measured from the bottom-left
 * corner (pixel centres at + 0.5), at window depth depth in [0, 1); false for
 * depth >= 1 (background) or a non-finite result. */
bool ms_render_unproject(const ms_camera *camera, double x, double y, double depth,
                         double world[3]);

#endif
