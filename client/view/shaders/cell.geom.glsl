#version 410 core
// meshview: per triangle, the flat geometric normal (in the cell's frame, which is
// the world's frame up to a uniform scale) and, for the wireframe overlay, each
// corner's distance in pixels to the opposite edge.

layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;

in vec3 v_cell[];
in vec3 v_eye[];
in vec3 v_normal[];
in vec3 v_colour[];

uniform vec2 viewport;

// The sections' clip distances pass through (written by the stage before).
in gl_PerVertex {
    vec4 gl_Position;
    float gl_ClipDistance[3];
} gl_in[];
out gl_PerVertex {
    vec4 gl_Position;
    float gl_ClipDistance[3];
};

out vec3 g_cell;
out vec3 g_eye;
out vec3 g_vertex_normal;
out vec3 g_colour;
flat out vec3 g_normal;
noperspective out vec3 g_edge;

void main()
{
    vec3 n = cross(v_cell[1] - v_cell[0], v_cell[2] - v_cell[0]);
    float len = length(n);
    n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);

    // Heights of the screen triangle; a corner behind the eye gives no wire.
    vec3 heights = vec3(1e9);
    if (gl_in[0].gl_Position.w > 0.0 && gl_in[1].gl_Position.w > 0.0 && gl_in[2].gl_Position.w > 0.0) {
        vec2 s0 = gl_in[0].gl_Position.xy / gl_in[0].gl_Position.w * 0.5 * viewport;
        vec2 s1 = gl_in[1].gl_Position.xy / gl_in[1].gl_Position.w * 0.5 * viewport;
        vec2 s2 = gl_in[2].gl_Position.xy / gl_in[2].gl_Position.w * 0.5 * viewport;
        vec2 e0 = s2 - s1, e1 = s0 - s2, e2 = s1 - s0;
        float area = abs(e1.x * e2.y - e1.y * e2.x);
        heights = vec3(area / max(length(e0), 1e-9), area / max(length(e1), 1e-9),
                       area / max(length(e2), 1e-9));
    }
    for (int i = 0; i < 3; ++i) {
        g_cell = v_cell[i];
        g_eye = v_eye[i];
        g_vertex_normal = v_normal[i];
        g_colour = v_colour[i];
        g_normal = n;
        g_edge = vec3(0.0);
        g_edge[i] = heights[i];
        gl_Position = gl_in[i].gl_Position;
        for (int k = 0; k < 3; ++k)
            gl_ClipDistance[k] = gl_in[i].gl_ClipDistance[k];
        EmitVertex();
    }
    EndPrimitive();
}
