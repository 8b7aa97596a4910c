/* Internals of the renderer (ms_render.h), shared by its files and its tests;
 * not part of the contract the program codes against.
 *
 *   ms_render_camera.c  cell cubes, matrices and unprojection in doubles
 *   ms_render_split.c   a frame's stitched mesh split by drawing cell, cell-local
 *                       floats, one content hash per cell (CPU only)
 *   ms_render_apo.c     a stored chunk prefix to validated texel words (CPU), and
 *                       the shared GL_R32UI texel buffer with its range allocator
 *   ms_render_program.c shader compilation and uniform locations
 *   ms_render.c         the renderer: frames, the upload queue, the program cache
 *   ms_render_draw.c    drawing a frame: uniforms, lights, placement, effects
 *   ms_render_impostor.c impostors (ms_render_impostor.h)
 *
 * Thread-safety: as ms_render.h (the CPU-only parts are pure or per object).
 */
#ifndef MS_RENDER_INTERNAL_H
#define MS_RENDER_INTERNAL_H

#include <epoxy/gl.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_apo_chunk.h"
#include "ms_render.h"

/* ---- GL memory ---------------------------------------------------------- */

/* Bytes of GL buffer and texture storage a renderer asked for (the sizes given
 * to glBufferData, what it holds now and the most it held at once), counted
 * where the storage is made and deleted (ms_render.h, "GL memory"). */
typedef struct ms_render_gl_count {
    uint64_t bytes, peak;
} ms_render_gl_count;

static inline void ms_render_gl_add(ms_render_gl_count *c, uint64_t bytes)
{
    c->bytes += bytes;
    if (c->bytes > c->peak)
        c->peak = c->bytes;
}

static inline void ms_render_gl_sub(ms_render_gl_count *c, uint64_t bytes)
{
    c->bytes = bytes < c->bytes ? c->bytes - bytes : 0;
}

/* ---- ms_render_camera.c ------------------------------------------------ */

/* MS_ERR_ARG unless the camera is finite, its viewport in [1, 16384] pixels per
 * side, fovy in (0, pi), 0 < near < far and its axes unit length. */
ms_status ms_render_camera_check(const ms_camera *camera, ms_error *err);

/* A cell's cube: the header box divided by n^level at the cell's position. */
void ms_render_cell_cube(const ms_archive_header *header, const ms_archive_cell *cell,
                         double origin[3], double *side);

/* Column-major float matrix taking cell-local coordinates to eye space:
 * view * translate(origin) * scale(side), multiplied out in doubles. */
void ms_render_cell_modelview(const double view[16], const double origin[3], double side,
                              float out[16]);

/* ---- ms_render_split.c ------------------------------------------------- */

/* One drawing cell's part of a frame, in buffers owned by the splitter (valid
 * until the next ms_render_split_cell or ms_render_split_free). */
typedef struct ms_render_cell_mesh {
    uint32_t cell;
    uint32_t vertex_count, triangle_count;
    const float *vertices;   /* 3 per vertex: (world - cube origin) / cube side */
    const uint32_t *normals; /* 1 per vertex: the packed corner normal (ms_render_pack_normal); a mesh
                              * vertex with several (creases, flipped triangles) is one cell vertex
                              * per distinct normal */
    const uint32_t *indices; /* 3 per triangle, into vertices, orientation kept */
    const uint32_t *colours; /* NULL (the mesh has none), or 1 per vertex: its mesh vertex's
                              * r g b a bytes in that order (ms_view_mesh.colours) */
    uint64_t hash;           /* of the counts, vertex floats, packed normals, indices and
                              * colours (when there are) */
} ms_render_cell_mesh;

typedef struct ms_render_split {
    const ms_archive_header *header;
    uint32_t cell_count;
    const ms_view_mesh *mesh;
    double level_error[64];  /* per kd-level: how far a vertex decoded there may be off */
    /* The frame's cells (ms_render_split_frame): the mesh's own runs when it
     * has them (runs true: ms_view_stitch's, with their versions); else the
     * triangles sorted by drawing cell (a stable radix sort on the cell id)
     * and a version hashed from each cell's corners. Sized by the frame, not
     * the model. */
    bool runs;
    uint32_t *order;         /* triangles sorted by drawing cell (without runs) */
    uint64_t *sort_keys;     /* per triangle: its drawing cell, the sort's keys */
    size_t order_cap;
    uint32_t *present;       /* cells with triangles in this frame, ascending */
    uint32_t *present_start; /* present_count + 1: each present cell's first entry of order
                                (with runs: its first triangle) */
    uint64_t *present_version; /* per present cell: the same while its triangles are */
    size_t present_cap;
    uint32_t present_count;
    uint32_t *local;         /* per mesh vertex: its index in the current cell */
    uint32_t *stamp;         /* per mesh vertex: the cell pass that set local */
    size_t vertex_cap;
    uint32_t pass;
    /* The normals (ms_render_split_normals, ms_render_normals.c): per triangle
     * its unnormalised face normal, per corner its packed normal, written for
     * the triangles of the cells asked about; the corners around each vertex
     * asked about (fan_start, one more than their vertices, into fan: corner
     * numbers 3t + k, ascending); scratch for one vertex's fan. */
    double *face_normal;     /* 3 per triangle */
    uint32_t *corner_packed; /* 3 per triangle */
    size_t triangle_normal_cap;
    uint32_t *fan;           /* 3 per triangle of the cells around */
    size_t fan_corner_cap;
    uint32_t *fan_start;     /* per fan vertex + 1 */
    size_t fan_start_cap;
    uint32_t *fan_vstamp;    /* per mesh vertex: the normals pass that numbered it */
    uint32_t *fan_vlocal;    /* per mesh vertex: its fan vertex number */
    size_t fan_vertex_cap;
    uint32_t fan_pass;
    uint64_t *fan_keys;      /* 2 per fan corner: (other vertex, fan slot, direction) */
    uint32_t *fan_parent;    /* per fan corner: union-find over the fan's faces */
    uint8_t *fan_parity;     /* per fan corner: 1 when its face is flipped against its parent */
    double *fan_sum;         /* 3 per fan corner: the group sums, at the group's root */
    size_t fan_cap;
    double *face_slack;      /* per triangle: how far its normal may be off, radians
                                (its vertices' decode error over its smallest height);
                                -e until asked for (the atan2 only where an edge
                                fails the plain crease test), e its corners' error */
    double *face_rlen;       /* per triangle: 1 / |face_normal| (0 for no area) */
    double crease_cos;       /* cosine of the crease angle of the last split */
    double crease_rad;       /* the crease angle of the last split, radians */
    uint64_t fans_made;      /* the last ms_render_split_normals: vertices whose fans it made */
    uint64_t faces_made;     /* ... and triangles whose face normals it made */
    float *vertices;
    uint32_t *normals;
    uint32_t *same_next;     /* per cell vertex: the next cell vertex of the same mesh vertex */
    uint32_t *indices;
    uint32_t *colours;       /* per cell vertex, with a mesh that has colours */
    size_t cell_vertex_cap, cell_normal_cap, cell_triangle_cap, cell_colour_cap;
} ms_render_split;

/* Zeroes the splitter for a model (the header is borrowed). */
/* Grows *array (realloc, contents kept) to hold at least need elements of
 * size bytes, doubling from 64; false (nothing changed) when out of memory. */
bool ms_render_grow(void **array, size_t *cap, size_t need, size_t size);

void ms_render_split_init(ms_render_split *split, const ms_archive_header *header);
void ms_render_split_free(ms_render_split *split);

/* A unit vector (x, y, z) as GL_INT_2_10_10_10_REV: each component rounded to
 * a signed 10-bit integer over 511 (x in the low bits, w 0); a zero or
 * non-finite vector packs to 0 (the shader then uses the flat normal). The
 * vector need not be unit: it is normalised first. */
uint32_t ms_render_pack_normal(const double n[3]);

/* Groups the mesh's triangles by drawing cell and gives each present cell its
 * version. A mesh with runs (ms_view_stitch's) is checked as far as its runs
 * (ascending cells in the model, covering the triangles in order; the
 * triangles themselves are checked as ms_render_split_normals uses them);
 * one without is checked whole (indices in range, drawing cells in the model,
 * positions finite, counts below 2^32), and each cell's version is a hash of
 * its corners' positions, levels and colours (when the mesh has them) in
 * order. A run's version goes as the mesh gives it, turned by a constant when
 * the mesh has colours: the data path changes a run's version when its
 * corners' colours change (ms_view_mesh), and a mesh gaining or losing its
 * colours derives every cell again. The mesh is borrowed until the next
 * call. MS_ERR_ARG for a bad mesh or angle, MS_ERR_NOMEM. */
ms_status ms_render_split_frame(ms_render_split *split, const ms_view_mesh *mesh, double crease_angle_deg,
                                ms_error *err);

/* The number of triangles of the k-th present cell, and the i-th of them. */
static inline uint32_t ms_render_split_triangle(const ms_render_split *s, uint32_t k, uint32_t i)
{
    return s->runs ? s->present_start[k] + i : s->order[s->present_start[k] + i];
}

/* The corner normals at the mesh vertices vertices[0..vertex_count) (each once,
 * in range), written for every corner at them of the triangles of the present
 * cells around[0..around_count) (ascending, holding every cell with a triangle
 * at one of those vertices), from the fans made of those triangles: around each
 * such vertex, its triangles are joined across every edge they share with
 * exactly one other triangle whose normal (turned over when the two use the
 * edge in the same direction: one of them is flipped) lies within the crease
 * angle of theirs, widened by both triangles' slack; each group's normal is the
 * sum of its unnormalised face normals (area-weighted), each turned to the
 * group's orientation, and a corner gets its group's normal turned to its own
 * triangle's orientation. The same result as over the whole mesh. With runs,
 * checks the triangles of around (indices, drawing cell, finite positions):
 * MS_ERR_ARG; MS_ERR_NOMEM. */
ms_status ms_render_split_normals(ms_render_split *split, const uint32_t *vertices, uint32_t vertex_count,
                                  const uint32_t *around, uint32_t around_count, ms_error *err);

/* The k-th present cell's mesh (k < present_count), in the cube of record (that
 * cell's), with the normals ms_render_split_normals made for it. MS_ERR_NOMEM. */
ms_status ms_render_split_cell(ms_render_split *split, uint32_t k, const ms_archive_cell *record,
                               ms_render_cell_mesh *out, ms_error *err);

/* ---- ms_render_cells.c ------------------------------------------------- */

/* Which cells touch each vertex: a multiset of (vertex key, cell) pairs, the
 * key a hash of the vertex's position, in one open-addressing table. */
typedef struct ms_render_touch_slot {
    uint64_t key;
    uint32_t cell;
    uint32_t state; /* 0 empty, 1 held, 2 removed */
} ms_render_touch_slot;

typedef struct ms_render_touch_map {
    ms_render_touch_slot *slots;
    size_t cap, held, used; /* used: held and removed */
} ms_render_touch_map;

void ms_render_touch_map_free(ms_render_touch_map *map);

/* ---- ms_render_apo.c --------------------------------------------------- */

/* The texel words of a stored chunk prefix (docs/ARCHIVE.md: zlib with a sync
 * flush after every level), for a cell whose record says apo_levels levels:
 * inflates what data holds, finds the levels' sizes from the words themselves
 * (breadth-first: a level's size follows from the masks of the level above, so
 * no level table is needed), keeps the words of levels [0, levels) and validates
 * them with ms_apo_view_init. *words (malloc'd, caller frees) receives *count
 * words; *root_internal says whether level 0 is an internal node.
 * Errors: MS_ERR_ARG (levels 0 or beyond the record), MS_ERR_CORRUPT (zlib or the
 * words disagree, or fewer words than `levels` levels), MS_ERR_NOMEM. */
ms_status ms_render_apo_words(const ms_archive_cell *record, const uint8_t *data, size_t length,
                              unsigned levels, uint32_t **words, size_t *count, bool *root_internal,
                              ms_error *err);

/* The shared texel buffer: one GL buffer of words behind a GL_R32UI buffer
 * texture, ranges handed out first fit from a sorted free list; it grows by
 * doubling (a copy on the GPU) up to GL_MAX_TEXTURE_BUFFER_SIZE words. */
typedef struct ms_render_texel_range {
    uint32_t start, count;
} ms_render_texel_range;

typedef struct ms_render_texels {
    GLuint buffer, texture;
    ms_render_gl_count *gl; /* the renderer's count: the buffer's bytes, and both
                               buffers while a growth copies */
    uint32_t capacity;     /* words */
    uint32_t max_words;    /* GL_MAX_TEXTURE_BUFFER_SIZE */
    ms_render_texel_range *free_ranges;
    size_t free_count, free_cap;
    uint64_t used;         /* words handed out */
} ms_render_texels;

/* gl (the renderer's count) gets the buffer's bytes; it must outlive texels. */
ms_status ms_render_texels_init(ms_render_texels *texels, ms_render_gl_count *gl, ms_error *err);
void ms_render_texels_free(ms_render_texels *texels);
/* A range of count words; false when the buffer cannot hold it (too big for the
 * driver, or out of memory): the cell then goes without APO. */
bool ms_render_texels_alloc(ms_render_texels *texels, uint32_t count, uint32_t *start);
void ms_render_texels_release(ms_render_texels *texels, uint32_t start, uint32_t count);

/* ---- ms_render_program.c ----------------------------------------------- */

/* What a draw uses of the cell program's general code beyond the effects
 * (docs/RENDERER.md, "Composed programs"), each compiled in only when the draw
 * needs it: llvmpipe runs a branch's code under a mask even when no pixel
 * takes it, and a loop over uniform lights as a loop. */
#define MS_RENDER_VARIANT_COLOUR 1u   /* vertex colours (some cell drawn has them) */
#define MS_RENDER_VARIANT_SECTIONS 2u /* clip distances and the section colour */
#define MS_RENDER_VARIANT_LIGHTS 4u   /* the light count and kinds fixed in the program */
#define MS_RENDER_VARIANT_LIGHT_COUNT_SHIFT 4 /* 4 bits: 0..MS_RENDER_MAX_LIGHTS */
#define MS_RENDER_VARIANT_LIGHT_KIND_SHIFT 8  /* 2 bits per light: ms_render_light_kind */
/* The general program: colours and sections, lights from the uniforms (what
 * ms_render_program_source gives). */
#define MS_RENDER_VARIANT_GENERAL (MS_RENDER_VARIANT_COLOUR | MS_RENDER_VARIANT_SECTIONS)

/* The variant a draw of options needs (coloured: some cell it draws carries
 * vertex colours). The wireframe and tessellated programs always take colours
 * and sections (their middle stages pass both on); lights are fixed for all. */
uint32_t ms_render_program_variant(const ms_render_options *options, bool coloured, bool wireframe,
                                   bool tessellated);
/* The fragment source of ms_render_program_source for a variant. */
ms_status ms_render_program_source_variant(unsigned effects, uint32_t variant, bool wireframe, char **source,
                                           ms_error *err);

typedef struct ms_render_program {
    GLuint program;
    unsigned effects;         /* MS_EFFECT_* compiled in */
    uint32_t variant;         /* MS_RENDER_VARIANT_* and the lights */
    bool wireframe;
    bool tessellated;         /* with the displacement stages: draws GL_PATCHES */
    GLint modelview, projection, viewport;
    GLint shading, apo_on, apo_base, apo_root_internal, apo_stop_depth, apo_nearest, apo_filter,
        apo_footprint_scale;
    GLint world_to_eye, cell_number, cell_tint, apo_words, smooth, vertex_colour;
    GLint albedo, light_count, light_eye, light_colour, light_range;
    GLint specular, shininess, two_sided, haze_density, haze_colour; /* -1 when not compiled in */
    GLint dissolve;
    GLint tess_pixels, disp_amplitude, disp_radius, disp_spacing, disp_seed, cell_origin, cell_side;
    GLint section_plane, section_count, section_colour;
} ms_render_program;

/* Compiles and links the embedded shaders with the effects given (the fragment
 * source of ms_render_program_source); tessellated (only with
 * MS_EFFECT_DISPLACEMENT) adds the displacement stages (tess.*.glsl) in place of
 * cell.vert.glsl; with wireframe, the program with the
 * geometry shader (flat normal and edge distances per triangle, the overlay);
 * without, vertex + fragment only (the flat normal from screen derivatives),
 * several times faster on software rasterisers. MS_ERR_UNSUPPORTED with the
 * first line of the driver's log. */
ms_status ms_render_program_build(ms_render_program *program, unsigned effects, uint32_t variant, bool wireframe,
                                  bool tessellated, ms_error *err);
/* A program of one vertex and one fragment shader (output "colour"), with
 * frag_insert (NULL: none) after the fragment shader's #version line; name
 * for errors. MS_ERR_UNSUPPORTED with the driver's first log line. */
ms_status ms_render_link_simple(const char *vert, const char *frag, const char *frag_insert, const char *name,
                                GLuint *program, ms_error *err);

void ms_render_program_free(ms_render_program *program);

/* ---- the renderer's state (ms_render.c, ms_render_draw.c) ----------------- */

#define MS_RENDER_PROGRAM_CACHE 16 /* composed programs kept, replaced round robin */

typedef struct gpu_mesh {
    GLuint vao, vbo, ibo;
    uint64_t gl_bytes;      /* the vbo's and ibo's storage, counted in ms_render.gl */
    uint32_t vertex_count, triangle_count;
    bool coloured;          /* the vbo ends with 4 bytes of colour per vertex */
    uint64_t hash;
} gpu_mesh;

typedef struct pending_mesh {
    bool active;
    float *vertices;        /* 3 per vertex, owned */
    uint32_t *normals;      /* 1 per vertex (packed), owned */
    uint32_t *colours;      /* 1 per vertex (r g b a bytes), owned; NULL without colours */
    uint32_t *indices;      /* 3 per triangle, owned */
    gpu_mesh gpu;           /* buffers being filled (created with the first piece) */
    uint64_t sent;          /* bytes of positions, normals, colours, then indices already sent */
} pending_mesh;

typedef struct apo_range {
    uint32_t levels;        /* complete levels held; 0: no APO */
    uint32_t start, count;  /* words in the texel buffer */
    bool root_internal;
} apo_range;

typedef struct pending_apo {
    bool active;
    uint32_t *words;        /* owned */
    apo_range range;        /* start valid once allocated */
    bool allocated;
    uint64_t sent;          /* bytes */
} pending_apo;

typedef struct render_cell {
    ms_archive_cell record; /* valid when known (learned; or from the whole index) */
    bool known;
    gpu_mesh mesh;          /* current; vao 0 when nothing is drawn */
    apo_range apo;          /* current */
    pending_mesh next_mesh;
    pending_apo next_apo;
    uint32_t failed_apo_levels; /* a prefix that did not load: not retried until it changes */
    bool queued;
    bool in_frame;
    uint32_t frame_apo_entry;  /* set_frame scratch: index into the frame's apo array + 1 */
    uint32_t frame_apo_levels; /* set_frame scratch */
    /* what its mesh was derived from (ms_render_cells.c) */
    bool has_version;
    uint64_t version;          /* the frame's version of its triangles (ms_render_split) */
    uint64_t *touch;           /* the keys of the vertices its triangles use, each once */
    uint32_t touch_count;
    uint32_t *corners;         /* the packed normal of each corner of its triangles (3 per
                                  triangle, in its run's order) its mesh was made with */
    uint32_t corner_count;
    uint32_t frame_index;      /* set_frame scratch: its index in the frame's present cells */
    uint32_t mark;             /* set_frame scratch: the pass that put it in a set */
} render_cell;

/* Per-cell state is kept per sibling group, as the view decoder keeps its
 * cells (ms_view_decoder_internal.h): ids are breadth-first, so each group of
 * n^3 siblings is a block of consecutive ids from 1 + k n^3 (group 0 is the
 * root). A group's block exists while one of its cells is learned or drawn:
 * at the end of each ms_render_set_frame, blocks with no cell in the frame are
 * freed, so the renderer holds state for the frame's groups only (plus one
 * pointer per group of the model). */
struct ms_render {
    bool has_model;             /* header (and groups) set: at ms_render_new or ms_render_set_model */
    double crease_angle_deg;    /* for the next ms_render_set_frame (ms_render_set_crease_angle) */
    ms_archive_header header;
    ms_archive_cell *records;   /* the whole index when ms_render_new was given it; else NULL
                                   and the records come from ms_render_learn */
    render_cell **groups;       /* group_count blocks of group_size, NULL where none */
    uint32_t group_size, group_count;
    ms_render_split split;
    /* composed programs, built on first use (effect set x wireframe), replaced
     * round robin when full */
    ms_render_program programs[MS_RENDER_PROGRAM_CACHE];
    uint32_t program_count, program_next;
    ms_render_texels texels;
    ms_render_gl_count gl;      /* every GL buffer's and texture's bytes (ms_render_memory) */
    uint64_t mesh_bytes;        /* of them, the cells' vertex and index buffers */
    uint32_t *frame_cells;      /* cells with triangles in the latest frame */
    uint32_t frame_cell_count;
    uint32_t *queue;            /* cells with something pending, oldest first (frame cells) */
    uint32_t queue_count;
    size_t frame_cap;           /* entries frame_cells and queue hold */
    /* the cells' derivation (ms_render_cells.c) */
    ms_render_touch_map touch;
    double derived_crease;      /* the crease angle the cells' meshes were made with */
    uint32_t mark_pass;
    uint64_t *keys;             /* scratch: vertex keys */
    size_t key_count, key_cap;
    uint32_t *shade;            /* scratch: present indices (the cells derived) */
    size_t shade_count, set_cap;
    uint32_t *fan_vertices;     /* scratch: the mesh vertices whose normals are made */
    size_t fan_vertex_count, fan_vertex_cap;
    uint64_t *key_set;          /* scratch: the keys as a set (open addressing, 0 empty) */
    size_t key_set_cap;
    ms_render_frame_stats frame_stats;
    ms_render_frame_totals frame_totals;
};

/* Drops what a cell's mesh was derived from (its touch list from the map). */
void ms_render_cell_forget(ms_render *r, uint32_t id, render_cell *c);

/* The new frame's cells (split grouped, every present cell with its state and
 * in_frame, cells that left already forgotten): derives the meshes of the
 * cells whose triangles changed and of those sharing a vertex with what they
 * drew or draw now, and takes them (ms_render_take_mesh). Fills
 * r->frame_stats. On error every cell is forgotten, so the next frame derives
 * all. MS_ERR_ARG (a bad mesh), MS_ERR_NOMEM. */
ms_status ms_render_derive_cells(ms_render *r, ms_error *err);

/* The cell's mesh in the new frame (ms_render.c): nothing to do when it is what
 * the cell draws or already waits for; otherwise it becomes the pending mesh. */
ms_status ms_render_take_mesh(ms_render *r, render_cell *c, const ms_render_cell_mesh *m, ms_error *err);

/* The state of cell id, NULL when its group holds none. */
render_cell *ms_render_cell_at(const ms_render *r, uint32_t id);
/* The record of cell id: the whole index's, else the learned one; NULL when
 * unknown. */
const ms_archive_cell *ms_render_record(const ms_render *r, uint32_t id);

/* Draws one zero-area triangle laid out as a cell's mesh (positions, then
 * packed normals) with program p (not a tessellated one: displacement could
 * give it an area) and the state of a draw into the bound framebuffer, and
 * waits for it: nothing reaches the picture, but a driver that compiles its
 * pipeline on the first draw with a state (Mesa's llvmpipe: a few hundred
 * milliseconds) does it now. */
void ms_render_warm_up(ms_render *r, const ms_render_program *p);

/* The program for an effect set and variant: from the cache, else built. */
ms_status ms_render_find_program(ms_render *r, unsigned effects, uint32_t variant, bool wireframe, bool tessellated,
                                 const ms_render_program **out, ms_error *err);

/* ---- ms_render.c: for tests ----------------------------------------------- */

/* The texel range a cell currently draws with (false: none), and the GL buffer
 * holding the words, so that a test can read them back. */
bool ms_render_cell_texels(const ms_render *render, uint32_t cell, uint32_t *start, uint32_t *count,
                           uint32_t *levels);
GLuint ms_render_texel_buffer(const ms_render *render);

#endif
