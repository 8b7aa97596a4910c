#version 410 core
// meshview: an impostor (seed 002) drawn on a quad facing the camera at the
// object's centre, large enough to cover its bounding sphere; the fragment
// stage marches the view ray through the captured image with depth.

layout(location = 0) in vec2 corner; // in [-1, 1]^2

uniform mat4 view_projection;  // world (the scene's, relative to `centre`) to clip
uniform vec3 centre;           // world, relative to the camera
uniform vec3 quad_right;       // world, times the quad's half size
uniform vec3 quad_up;

out vec3 w_position;           // world, relative to the camera (the eye at 0)

void main()
{
    w_position = centre + corner.x * quad_right + corner.y * quad_up;
    gl_Position = view_projection * vec4(w_position, 1.0);
}
