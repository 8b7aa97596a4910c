#version 410 core
// meshview: one drawing cell. Positions arrive in cell-local coordinates
// ((world - cube origin) / cube side); modelview takes them straight to eye space
// (computed in doubles on the CPU per draw, so far-from-origin models keep their
// precision in float).

layout(location = 0) in vec3 cell_position;

uniform mat4 modelview;
uniform mat4 projection;

out vec3 v_cell;
out vec3 v_eye;

void main()
{
    vec4 eye = modelview * vec4(cell_position, 1.0);
    v_cell = cell_position;
    v_eye = eye.xyz;
    gl_Position = projection * eye;
}
