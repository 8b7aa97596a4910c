#version 410 core
// meshview: a surface that declares displacement (docs/SCENES.md), drawn as
// triangle patches: the vertex stage only passes the cell-local corners on; the
// tessellation stages (tess.tesc.glsl, tess.tese.glsl) level and displace them.

layout(location = 0) in vec3 cell_position;
layout(location = 1) in vec4 cell_normal;
layout(location = 2) in vec4 cell_colour; // as in cell.vert.glsl

out vec3 c_cell;
out vec3 c_normal;
out vec3 c_colour;

void main()
{
    c_cell = cell_position;
    c_normal = cell_normal.xyz;
    c_colour = cell_colour.rgb;
}
