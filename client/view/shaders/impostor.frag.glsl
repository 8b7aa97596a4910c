#version 410 core
// meshview: an impostor's image with depth (seed 002, "images with parallax"):
// colour and window depth captured along the capture direction F by a
// near-orthographic view of the object's bounding sphere (radius r). Each
// fragment follows its view ray through the box [-r, r]^3 of the capture frame
// (R, U, F), in 48 steps and then 6 halvings, to the first point behind the
// captured surface: exact where the view is the capture's, parallax-corrected
// as the view turns away from it (until the renderer captures again). The hit
// gives the colour and the fragment's depth, so the impostor meets the rest of
// the scene as the geometry would. coverage < 1 dithers it out (the switch
// with the geometry, which draws the complementary pixels).

in vec3 w_position;

uniform sampler2D impostor_colour;
uniform sampler2D impostor_depth;
uniform mat4 view_projection;
uniform vec3 centre;            // world, relative to the camera
uniform vec3 capture_right, capture_up, capture_forward; // unit
uniform float radius;
uniform float capture_distance; // eye to centre at capture
uniform float capture_near, capture_far;
uniform float coverage;
uniform float haze_density;     // the captured colour has none: added here at
uniform vec3 haze_colour;       // the hit's true distance (linear colour)

out vec4 colour;

// The captured surface's offset along F from the centre at image point uv
// (in [0, 1]^2), or a large value where the capture saw nothing.
float surface(vec2 uv)
{
    float z = texture(impostor_depth, uv).r;
    if (z >= 1.0)
        return 1e9;
    float n = capture_near, f = capture_far;
    float ndc = 2.0 * z - 1.0;
    float eye = 2.0 * n * f / (f + n - ndc * (f - n));
    return eye - capture_distance;
}

void main()
{
    if (bayer(gl_FragCoord.xy) >= coverage)
        discard;
    // the ray from the eye (0) through this fragment, in the capture frame
    // centred on the object
    vec3 rel = -centre;
    vec3 o = vec3(dot(rel, capture_right), dot(rel, capture_up), dot(rel, capture_forward));
    vec3 w = normalize(w_position);
    vec3 d = vec3(dot(w, capture_right), dot(w, capture_up), dot(w, capture_forward));
    // the ray's stretch inside the box [-r, r]^3
    vec3 inv = 1.0 / d;
    vec3 t0 = (vec3(-radius) - o) * inv, t1 = (vec3(radius) - o) * inv;
    vec3 lo = min(t0, t1), hi = max(t0, t1);
    float enter = max(max(lo.x, lo.y), max(lo.z, 0.0)), leave = min(hi.x, min(hi.y, hi.z));
    if (enter >= leave)
        discard;
    const int STEPS = 48;
    float step_t = (leave - enter) / float(STEPS);
    float before = enter, hit = -1.0;
    for (int i = 0; i <= STEPS; ++i) {
        float t = enter + step_t * float(i);
        vec3 p = o + t * d;
        vec2 uv = p.xy / (2.0 * radius) + 0.5;
        if (p.z >= surface(uv)) {
            hit = t;
            break;
        }
        before = t;
    }
    if (hit < 0.0)
        discard;
    float a = before, b = hit;
    for (int i = 0; i < 6; ++i) {
        float m = 0.5 * (a + b);
        vec3 p = o + m * d;
        if (p.z >= surface(p.xy / (2.0 * radius) + 0.5))
            b = m;
        else
            a = m;
    }
    vec3 p = o + b * d;
    vec2 uv = p.xy / (2.0 * radius) + 0.5;
    vec3 rgb = texture(impostor_colour, uv).rgb;
    if (haze_density > 0.0) {
        vec3 linear = mix(rgb / 12.92, pow((rgb + 0.055) / 1.055, vec3(2.4)), greaterThan(rgb, vec3(0.04045)));
        linear = mix(haze_colour, linear, exp(-haze_density * b));
        linear = clamp(linear, 0.0, 1.0);
        rgb = mix(12.92 * linear, 1.055 * pow(linear, vec3(1.0 / 2.4)) - 0.055, greaterThan(linear, vec3(0.0031308)));
    }
    colour = vec4(rgb, 1.0);
    vec4 clip = view_projection * vec4(b * w, 1.0);
    gl_FragDepth = 0.5 * (clip.z / clip.w) + 0.5;
}
