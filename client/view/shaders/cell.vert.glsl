#version 410 core
// meshview: one drawing cell. Positions arrive in cell-local coordinates
// ((world - cube origin) / cube side); modelview takes them straight to eye space
// (computed in doubles on the CPU per draw, so far-from-origin models keep their
// precision in float).

layout(location = 0) in vec3 cell_position;
// The vertex normal (world frame, unit; zero where it is undefined), from
// GL_INT_2_10_10_10_REV normalised.
layout(location = 1) in vec4 cell_normal;
// The vertex colour (r g b a, 8 bits each, sRGB as scanned) from
// GL_UNSIGNED_BYTE normalised; a cell without colours has no array there and
// the fragment stage takes its albedo instead (vertex_colour false).
layout(location = 2) in vec4 cell_colour;

uniform mat4 modelview;
uniform mat4 projection;
// The program's variant (ms_render_program_variant) is defined after the
// #version line: MS_SECTIONS and MS_VERTEX_COLOUR only where the draw uses
// them (what a stage does not write costs no interpolation either).
#ifdef MS_SECTIONS
// Sections (ms_render.h): per plane, in the cell's local frame, the kept side
// where dot(xyz, position) + w >= 0; gl_ClipDistance of all three is written,
// the renderer enables those in use.
uniform vec4 section_plane[3];
out gl_PerVertex { // as cell.geom.glsl reads it
    vec4 gl_Position;
    float gl_ClipDistance[3];
};
#endif

out vec3 v_cell;
out vec3 v_eye;
out vec3 v_normal;
#ifdef MS_VERTEX_COLOUR
out vec3 v_colour;
#endif

void main()
{
    vec4 eye = modelview * vec4(cell_position, 1.0);
    v_cell = cell_position;
    v_eye = eye.xyz;
    v_normal = cell_normal.xyz;
#ifdef MS_VERTEX_COLOUR
    v_colour = cell_colour.rgb;
#endif
    gl_Position = projection * eye;
#ifdef MS_SECTIONS
    for (int k = 0; k < 3; ++k)
        gl_ClipDistance[k] = dot(section_plane[k].xyz, cell_position) + section_plane[k].w;
#endif
}
