#version 410 core
// meshview: tessellation levels by screen size (seed 004). Each edge's level is
// the projected size in pixels of a sphere centred on the edge's midpoint whose
// diameter is the edge's length, over tess_pixels_per_level, in [1, 64]: it
// depends on the edge alone, so the two patches sharing an edge agree and no
// crack opens. The inner level is the largest outer one. A patch wholly
// outside the view frustum (its bounding sphere, grown by the relief's
// amplitude, outside one side plane or behind the near plane) gets level 1:
// no new vertices, and no popping at the frustum's border.

layout(vertices = 3) out;

in vec3 c_cell[];
in vec3 c_normal[];
in vec3 c_colour[];
out vec3 e_cell[];
out vec3 e_normal[];
out vec3 e_colour[];

uniform mat4 modelview;
uniform mat4 projection;
uniform vec2 viewport;
uniform float tess_pixels_per_level;
uniform float displacement_amplitude; // eye units (metres)

float edge_level(vec3 a, vec3 b, float focal)
{
    vec3 mid = 0.5 * (a + b);
    float px = length(a - b) * focal / max(length(mid), 1e-6);
    return clamp(px / tess_pixels_per_level, 1.0, 64.0);
}

bool outside_frustum(vec3 a, vec3 b, vec3 c)
{
    vec3 centre = (a + b + c) / 3.0;
    float r = max(length(a - centre), max(length(b - centre), length(c - centre))) + displacement_amplitude;
    // side planes of the symmetric perspective frustum, inward normals
    float tx = 1.0 / projection[0][0], ty = 1.0 / projection[1][1];
    vec3 planes[4] = vec3[4](normalize(vec3(1.0, 0.0, -tx)), normalize(vec3(-1.0, 0.0, -tx)),
                             normalize(vec3(0.0, 1.0, -ty)), normalize(vec3(0.0, -1.0, -ty)));
    for (int i = 0; i < 4; ++i)
        if (dot(planes[i], centre) < -r)
            return true;
    return -centre.z < -r; // behind the eye
}

void main()
{
    e_cell[gl_InvocationID] = c_cell[gl_InvocationID];
    e_normal[gl_InvocationID] = c_normal[gl_InvocationID];
    e_colour[gl_InvocationID] = c_colour[gl_InvocationID];
    if (gl_InvocationID == 0) {
        vec3 a = (modelview * vec4(c_cell[0], 1.0)).xyz;
        vec3 b = (modelview * vec4(c_cell[1], 1.0)).xyz;
        vec3 c = (modelview * vec4(c_cell[2], 1.0)).xyz;
        float l0 = 1.0, l1 = 1.0, l2 = 1.0;
        if (!outside_frustum(a, b, c)) {
            float focal = projection[1][1] * 0.5 * viewport.y; // pixels per unit at distance 1
            l0 = edge_level(b, c, focal); // outer[0]: the edge opposite corner 0
            l1 = edge_level(c, a, focal);
            l2 = edge_level(a, b, focal);
        }
        gl_TessLevelOuter[0] = l0;
        gl_TessLevelOuter[1] = l1;
        gl_TessLevelOuter[2] = l2;
        gl_TessLevelInner[0] = max(l0, max(l1, l2));
    }
}
