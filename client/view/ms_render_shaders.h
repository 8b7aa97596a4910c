/* The viewer's GLSL sources, embedded at build time: the Makefile runs
 * client/view/shaders/embed_shaders.py over client/view/shaders/ (every .glsl file) into a
 * generated C file of libmsview (one NUL-terminated string per file, named after
 * it). Read-only constants: thread-safe. */
#ifndef MS_RENDER_SHADERS_H
#define MS_RENDER_SHADERS_H

extern const char ms_shader_cell_vert[]; /* shaders/cell.vert.glsl */
extern const char ms_shader_cell_geom[]; /* shaders/cell.geom.glsl */
extern const char ms_shader_cell_frag[]; /* shaders/cell.frag.glsl (#version on its first line) */
extern const char ms_shader_apo[];       /* shaders/apo.glsl, inserted after frag's #version */
extern const char ms_shader_tess_vert[]; /* shaders/tess.vert.glsl: displaced surfaces' vertex stage */
extern const char ms_shader_tess_tesc[]; /* shaders/tess.tesc.glsl: levels by screen size, culling */
extern const char ms_shader_tess_tese[]; /* shaders/tess.tese.glsl: the height atoms */
extern const char ms_shader_impostor_vert[]; /* shaders/impostor.vert.glsl: the impostor's quad */
extern const char ms_shader_impostor_frag[]; /* shaders/impostor.frag.glsl: the march through the image */
extern const char ms_shader_dither[];        /* shaders/dither.glsl: bayer(), inserted after #version */

#endif
