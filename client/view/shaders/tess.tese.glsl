#version 410 core
// meshview: procedural relief from scattered height atoms (seed 004). Atoms
// sit one per cell of a square grid of spacing 1 / sqrt(density) in the
// surface's plane (world coordinates, the axis along the patch's normal
// dropped), jittered inside their cell by a hash of the cell's coordinates and
// the seed, so every client builds the same relief; each is a bump
// amplitude * k * (1 - (d / radius)^2)^2 (k in [0.5, 1] from the hash), and
// the heights blend by their maximum. The point moves along the patch's
// normal; the fragment stage's flat normal, from the screen derivatives of the
// displaced position, shades the relief. Fractional odd spacing keeps the
// level changes smooth while zooming.

layout(triangles, fractional_odd_spacing, ccw) in;

in vec3 e_cell[];
in vec3 e_normal[];
in vec3 e_colour[];

uniform mat4 modelview;
uniform mat4 projection;
uniform vec3 cell_origin;            // world position of the cell's cube corner
uniform float cell_side;             // world units per cell unit
uniform float displacement_amplitude;
// Sections (ms_render.h): per plane, in the cell's local frame, the kept side
// where dot(xyz, position) + w >= 0; gl_ClipDistance of all three is written,
// the renderer enables those in use.
uniform vec4 section_plane[3];
out gl_PerVertex { // as cell.geom.glsl reads it
    vec4 gl_Position;
    float gl_ClipDistance[3];
};

uniform float displacement_radius;
uniform float displacement_spacing;
uniform uint displacement_seed;

out vec3 v_cell;
out vec3 v_eye;
out vec3 v_normal;
out vec3 v_colour;

uint mix_bits(uint h)
{
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return h;
}

float unit(uint h)
{
    return float(h >> 8) / 16777216.0;
}

float atoms(vec2 q)
{
    vec2 grid = q / displacement_spacing;
    ivec2 base = ivec2(floor(grid));
    int reach = min(2, int(ceil(displacement_radius / displacement_spacing)));
    float height = 0.0;
    for (int j = -reach; j <= reach; ++j)
        for (int i = -reach; i <= reach; ++i) {
            ivec2 cell = base + ivec2(i, j);
            uint h = mix_bits(uint(cell.x) * 0x9e3779b9u ^ mix_bits(uint(cell.y) + displacement_seed * 0x85ebca6bu));
            vec2 jitter = vec2(unit(h), unit(mix_bits(h + 1u)));
            float k = 0.5 + 0.5 * unit(mix_bits(h + 2u));
            vec2 centre = (vec2(cell) + jitter) * displacement_spacing;
            float d = length(q - centre) / displacement_radius;
            if (d < 1.0) {
                float s = 1.0 - d * d;
                height = max(height, displacement_amplitude * k * s * s);
            }
        }
    return height;
}

void main()
{
    vec3 t = gl_TessCoord;
    vec3 cell = t.x * e_cell[0] + t.y * e_cell[1] + t.z * e_cell[2];
    vec3 n = cross(e_cell[1] - e_cell[0], e_cell[2] - e_cell[0]);
    n = length(n) > 0.0 ? normalize(n) : vec3(0.0, 1.0, 0.0);
    vec3 world = cell_origin + cell_side * cell;
    vec3 an = abs(n);
    vec2 q = an.y >= an.x && an.y >= an.z ? world.xz : (an.x >= an.z ? world.zy : world.xy);
    cell += n * (atoms(q) / cell_side);
    v_cell = cell;
    v_normal = t.x * e_normal[0] + t.y * e_normal[1] + t.z * e_normal[2];
    v_colour = t.x * e_colour[0] + t.y * e_colour[1] + t.z * e_colour[2];
    vec4 eye = modelview * vec4(cell, 1.0);
    v_eye = eye.xyz;
    gl_Position = projection * eye;
    for (int k = 0; k < 3; ++k)
        gl_ClipDistance[k] = dot(section_plane[k].xyz, cell) + section_plane[k].w;
}
