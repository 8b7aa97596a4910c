#version 410 core
// meshview: shading of one drawing cell (modes of ms_render.h). The program is
// composed per scene (ms_render_program_source): the renderer inserts, right
// after the first line, "#define MS_WIREFRAME" for the program with the
// geometry shader (wireframe overlay), then the APO traversal (apo.glsl) when
// detail normals are compiled in and the dither (dither.glsl) with impostors,
// and keeps each "#ifdef MS_EFFECT_<NAME>"
// block only for the effects the program holds: a block of an effect not held
// is cut from the source, never compiled. Without the geometry shader (much
// faster on software rasterisers) the flat normal comes from the screen
// derivatives of the cell-local position.

#ifdef MS_WIREFRAME
in vec3 g_cell;
in vec3 g_eye;
in vec3 g_vertex_normal;
in vec3 g_colour;
flat in vec3 g_normal;
noperspective in vec3 g_edge;
#define FRAG_CELL g_cell
#define FRAG_EYE g_eye
#define FRAG_VERTEX_NORMAL g_vertex_normal
#define FRAG_COLOUR g_colour
#else
in vec3 v_cell;
in vec3 v_eye;
in vec3 v_normal;
#define FRAG_CELL v_cell
#define FRAG_EYE v_eye
#define FRAG_VERTEX_NORMAL v_normal
#ifdef MS_VERTEX_COLOUR
in vec3 v_colour;
#define FRAG_COLOUR v_colour
#endif
#endif

uniform int shading;          // 0 LIT, 1 NORMALS, 2 CELLS, 3 CELL_ID, 4 ALBEDO
#ifdef MS_EFFECT_DETAIL_NORMALS
uniform bool apo_on;          // this cell has a chunk prefix and APO is wanted
uniform int apo_base;         // first word of the cell's chunk in apo_words
uniform bool apo_root_internal;
uniform uint apo_stop_depth;  // min(depth cap, complete levels - 1)
uniform bool apo_nearest_rule; // missing child: nearest (true) or stop
uniform bool apo_filter;      // 8-cell interpolation (true) or the nearest node
uniform float apo_footprint_scale; // a pixel's width in cell units per unit of eye depth; 0: no limit
#endif
uniform mat3 world_to_eye;    // rotation part of the view (times the model's placement)
uniform uint cell_number;
uniform vec3 cell_tint;       // linear albedo for CELLS
uniform bool smooth_on;       // without APO: interpolated vertex normals, else flat
uniform vec3 albedo;          // the material's linear albedo
#ifdef MS_VERTEX_COLOUR
uniform bool vertex_colour;   // this cell's vertices carry colours (FRAG_COLOUR,
                              // sRGB as scanned): they are the albedo
#define CELL_COLOURED vertex_colour
#else
#define CELL_COLOURED false   // no cell of the draw has colours: the albedo
#ifndef FRAG_COLOUR
#define FRAG_COLOUR vec3(0.0)
#endif
#endif
// Lights in eye space: w 0 directional (xyz towards the light), 1 point (xyz
// its position, falling off with range), 2 the head light (at the eye, no
// falloff); colour times intensity, linear. A program built for the draw's
// lights (MS_LIGHT_COUNT, MS_LIGHT_KINDS: each light's w, defined after the
// #version line) has the loop unrolled and the kinds' branches resolved when
// it is compiled; the general program reads count and kinds from the uniforms.
#define MAX_LIGHTS 8
uniform int light_count;
uniform vec4 light_eye[MAX_LIGHTS];
uniform vec3 light_colour[MAX_LIGHTS];
uniform float light_range[MAX_LIGHTS];
#ifdef MS_EFFECT_SPECULAR
uniform float specular_strength; // 0 for a diffuse material
uniform float shininess;
#endif
#ifdef MS_EFFECT_TWO_SIDED
uniform bool two_sided;       // a back face is lit as its other side
#endif
#ifdef MS_EFFECT_HAZE
uniform float haze_density;   // per unit of eye distance
uniform vec3 haze_colour;     // linear
#endif
#ifdef MS_EFFECT_IMPOSTORS
// The switch to and from an impostor: the pixels whose 4x4 Bayer threshold
// (dither.glsl, inserted with this effect) is below dissolve are left to the
// impostor (impostor.frag.glsl draws exactly those), so the two cross-fade
// without sorting or blending.
uniform float dissolve;
#endif

// Sections: with a plane in use, a back face is the model's inside seen
// through the cut, drawn flat in the section colour (sRGB as given), so the
// cut reads as a filled outline (meshrender draws its back-face hits alike).
#ifdef MS_SECTIONS
uniform int section_count;
uniform vec3 section_colour;
#endif

out vec4 colour;

vec3 srgb_encode(vec3 c)
{
    c = clamp(c, 0.0, 1.0);
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}

vec3 srgb_decode(vec3 c)
{
    c = clamp(c, 0.0, 1.0);
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), greaterThan(c, vec3(0.04045)));
}

// The wireframe overlay over a shaded colour.
vec3 overlay(vec3 rgb)
{
#ifdef MS_WIREFRAME
    float d = min(g_edge.x, min(g_edge.y, g_edge.z));
    float line = 1.0 - smoothstep(0.5, 1.5, d);
    rgb = mix(rgb, vec3(0.05, 0.05, 0.08), 0.85 * line);
#endif
    return rgb;
}

// The triangle's normal in its stored orientation (cell frame = world frame up
// to a uniform scale).
vec3 geometric_normal()
{
#ifdef MS_WIREFRAME
    return g_normal;
#else
    // cross(d/dx, d/dy) points towards the eye whatever the winding; a front
    // face (counter-clockwise on screen) is stored with its normal that way.
    vec3 n = cross(dFdx(v_cell), dFdy(v_cell));
    float len = length(n);
    n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);
    return gl_FrontFacing ? n : -n;
#endif
}

void main()
{
#ifdef MS_EFFECT_IMPOSTORS
    if (bayer(gl_FragCoord.xy) < dissolve)
        discard;
#endif
    if (shading == 3) {
        uint id = cell_number + 1u;
        colour = vec4(float(id & 0xFFu), float((id >> 8) & 0xFFu), float((id >> 16) & 0xFFu), 255.0) / 255.0;
        return;
    }
#ifdef MS_SECTIONS
    if (section_count > 0 && !gl_FrontFacing && shading != 1) {
        colour = vec4(section_colour, 1.0);
        return;
    }
#endif
    if (shading == 4) {
        // ALBEDO: the surface's own colour, unlit: the vertex colours as
        // scanned, interpolated (no gamma step: a vertex's pixel is its 8-bit
        // colour), or the material's albedo sRGB-encoded.
        colour = vec4(overlay(CELL_COLOURED ? clamp(FRAG_COLOUR, 0.0, 1.0) : srgb_encode(albedo)), 1.0);
        return;
    }
    vec3 g_n = geometric_normal();
    vec3 n_world = g_n;
    bool detail = false;
    if (smooth_on) {
        // The interpolated vertex normal; a vertex whose normal is undefined
        // (only degenerate triangles around it) packs to zero: flat there.
        vec3 v = FRAG_VERTEX_NORMAL;
        float len = length(v);
        if (len > 1e-3)
            n_world = v / len;
    }
#ifdef MS_EFFECT_DETAIL_NORMALS
    if (apo_on) {
        // A correction of the normal above (docs/APO.md): where the chunk has no
        // texel around, that normal as it is. No deeper than the first texel
        // within the pixel (minification), then interpolation between
        // neighbouring texels (magnification) or the nearest one.
        uint stop = min(apo_stop_depth, apo_footprint_depth(-FRAG_EYE.z * apo_footprint_scale));
        n_world = apo_filter
                      ? apo_lookup_filtered(FRAG_CELL, apo_base, apo_root_internal, stop, apo_nearest_rule, n_world, detail)
                      : apo_lookup(FRAG_CELL, apo_base, apo_root_internal, stop, apo_nearest_rule, n_world, detail);
    }
#endif
    vec3 rgb;
    if (shading == 1) {
        rgb = (n_world + 1.0) * 0.5;
    } else {
        vec3 view_dir = normalize(-FRAG_EYE);
        vec3 ng = normalize(world_to_eye * g_n);
        vec3 n = normalize(world_to_eye * n_world);
        // An APO normal against the triangle's own was sampled on another sheet
        // of the surface (a thin part) or on a face wound the other way: it is
        // turned to the triangle's side (as meshrender does). A vertex normal
        // against it comes from a fold: the triangle's normal stands in for it.
        if (dot(n, ng) < 0.0)
            n = detail ? -n : ng;
#ifdef MS_EFFECT_TWO_SIDED
        // Two-sided: a surface seen from behind is lit as its other side.
        if (two_sided && dot(ng, view_dir) < 0.0) {
            ng = -ng;
            n = -n;
        }
#endif
        vec3 diffuse = vec3(0.0);
#ifdef MS_EFFECT_SPECULAR
        vec3 highlight = vec3(0.0);
#endif
#ifdef MS_LIGHT_COUNT
        const float light_kind[] = MS_LIGHT_KINDS;
        for (int i = 0; i < MS_LIGHT_COUNT; ++i) {
            float kind = light_kind[i];
#else
        for (int i = 0; i < light_count && i < MAX_LIGHTS; ++i) {
            float kind = light_eye[i].w;
#endif
            vec3 l;
            float falloff = 1.0;
            if (kind == 0.0) {
                l = light_eye[i].xyz;
            } else if (kind == 2.0) {
                l = view_dir;
            } else {
                vec3 to_light = light_eye[i].xyz - FRAG_EYE;
                float d = length(to_light) / light_range[i];
                l = normalize(to_light);
                falloff = 1.0 / (1.0 + d * d);
            }
            // The self-shadowing factor, for every normal: meshrender's
            // lighting model (server/study/ms_study_render.c, the study's
            // reference), so the same mesh shades alike in both (a flat face
            // under the head light as (N . L)^2). It is max(0, L . N), N the
            // APO, vertex or flat normal itself: the same as meshrender's
            // max(0, L . N_geometric) on a flat face and on a fine mesh, and
            // smooth on a coarse level, whose triangles' own normals are rough
            // (their corners sit at kd-cell centres, a staircase at 12 px) and
            // would darken whole triangles under a good APO normal.
            float self_shadow = max(0.0, dot(l, n));
            vec3 c = light_colour[i] * (falloff * self_shadow);
            diffuse += c * max(0.0, dot(n, l));
#ifdef MS_EFFECT_SPECULAR
            highlight += c * pow(max(0.0, dot(n, normalize(l + view_dir))), shininess);
#endif
        }
        vec3 base = shading == 2 ? cell_tint : (CELL_COLOURED ? srgb_decode(FRAG_COLOUR) : albedo);
        vec3 linear = base * (0.05 + 0.95 * diffuse);
#ifdef MS_EFFECT_SPECULAR
        linear += specular_strength * highlight;
#endif
#ifdef MS_EFFECT_HAZE
        linear = mix(haze_colour, linear, exp(-haze_density * length(FRAG_EYE)));
#endif
        rgb = srgb_encode(linear);
    }
    colour = vec4(overlay(rgb), 1.0);
}
