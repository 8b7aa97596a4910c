/* The renderer's GLSL program from the embedded sources (ms_render_shaders.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_render_internal.h"
#include "ms_render_shaders.h"

/* The first line of a shader or program log, for a one-line error. */
static void first_log_line(GLuint object, bool program, char *line, size_t size)
{
    char log[1024] = "";
    if (program)
        glGetProgramInfoLog(object, sizeof log, NULL, log);
    else
        glGetShaderInfoLog(object, sizeof log, NULL, log);
    size_t n = strcspn(log, "\r\n");
    if (n >= size)
        n = size - 1;
    memcpy(line, log, n);
    line[n] = 0;
    if (!line[0])
        snprintf(line, size, "no log");
}

static ms_status compile(GLenum type, const char *const *sources, GLsizei count, const char *name, GLuint *shader,
                         ms_error *err)
{
    *shader = glCreateShader(type);
    if (!*shader)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: cannot create the %s shader", name);
    glShaderSource(*shader, count, sources, NULL);
    glCompileShader(*shader);
    GLint ok = 0;
    glGetShaderiv(*shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char line[256];
        first_log_line(*shader, false, line, sizeof line);
        glDeleteShader(*shader);
        *shader = 0;
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: %s shader does not compile: %s", name, line);
    }
    return MS_OK;
}

/* A growing text buffer. */
typedef struct text_buf {
    char *data;
    size_t len, cap;
    bool failed;
} text_buf;

static void text_add(text_buf *t, const char *s, size_t n)
{
    if (t->failed)
        return;
    if (t->len + n + 1 > t->cap) {
        size_t cap = t->cap ? t->cap : 4096;
        while (cap < t->len + n + 1)
            cap *= 2;
        char *grown = realloc(t->data, cap);
        if (!grown) {
            t->failed = true;
            return;
        }
        t->data = grown, t->cap = cap;
    }
    memcpy(t->data + t->len, s, n);
    t->len += n;
    t->data[t->len] = 0;
}

/* The effect bit a directive line names ("#ifdef MS_EFFECT_HAZE" -> HAZE), or 0. */
static unsigned effect_of(const char *name, size_t n)
{
    static const char prefix[] = "MS_EFFECT_";
    if (n <= sizeof prefix - 1 || strncmp(name, prefix, sizeof prefix - 1) != 0)
        return 0;
    name += sizeof prefix - 1, n -= sizeof prefix - 1;
    for (unsigned bit = 1; bit <= MS_EFFECTS_ALL; bit <<= 1) {
        const char *e = ms_effect_name(bit);
        size_t k = strlen(e);
        if (k != n)
            continue;
        bool same = true;
        for (size_t i = 0; i < k && same; ++i)
            same = (char)(e[i] >= 'a' && e[i] <= 'z' ? e[i] - 'a' + 'A' : e[i]) == name[i];
        if (same)
            return bit;
    }
    return 0;
}

/* Appends text with its MS_EFFECT_ blocks resolved: a line "#ifdef
 * MS_EFFECT_X" or "#ifndef MS_EFFECT_X" opens a block kept or cut by whether X is
 * in effects, "#else" swaps, "#endif" closes; the directive lines go. Other
 * preprocessor blocks pass through, tracked only to pair #else and #endif. */
static ms_status resolve_blocks(text_buf *out, const char *text, unsigned effects, ms_error *err)
{
    enum { MAX_DEPTH = 32 };
    struct {
        bool effect, keep, outer_keep;
    } stack[MAX_DEPTH];
    int depth = 0;
    bool keep = true;
    for (const char *line = text; *line;) {
        const char *end = strchr(line, '\n');
        size_t n = end ? (size_t)(end - line) + 1 : strlen(line);
        const char *p = line;
        while (*p == ' ' || *p == '\t')
            p++;
        bool drop_line = false;
        if (*p == '#') {
            const char *word = p + 1;
            while (*word == ' ')
                word++;
            size_t wn = strcspn(word, " \t\r\n");
            const char *arg = word + wn;
            while (*arg == ' ' || *arg == '\t')
                arg++;
            size_t an = strcspn(arg, " \t\r\n/");
            bool opens = (wn == 2 && !strncmp(word, "if", 2)) || (wn == 5 && !strncmp(word, "ifdef", 5)) ||
                         (wn == 6 && !strncmp(word, "ifndef", 6));
            if (opens) {
                if (depth == MAX_DEPTH)
                    return ms_error_set(err, MS_ERR_FORMAT, "render: shader blocks nested deeper than %d", MAX_DEPTH);
                unsigned bit = wn != 2 ? effect_of(arg, an) : 0;
                stack[depth].effect = bit != 0;
                stack[depth].outer_keep = keep;
                if (bit) {
                    bool on = (effects & bit) != 0;
                    stack[depth].keep = wn == 5 ? on : !on;
                    keep = keep && stack[depth].keep;
                    drop_line = true;
                }
                depth++;
            } else if ((wn == 4 && !strncmp(word, "else", 4)) || (wn == 4 && !strncmp(word, "elif", 4))) {
                if (depth == 0)
                    return ms_error_set(err, MS_ERR_FORMAT, "render: #%.4s without #if in a shader", word);
                if (stack[depth - 1].effect) {
                    if (word[2] == 'i')
                        return ms_error_set(err, MS_ERR_FORMAT, "render: #elif in an MS_EFFECT_ block");
                    stack[depth - 1].keep = !stack[depth - 1].keep;
                    keep = stack[depth - 1].outer_keep && stack[depth - 1].keep;
                    drop_line = true;
                }
            } else if (wn == 5 && !strncmp(word, "endif", 5)) {
                if (depth == 0)
                    return ms_error_set(err, MS_ERR_FORMAT, "render: #endif without #if in a shader");
                depth--;
                if (stack[depth].effect) {
                    keep = stack[depth].outer_keep;
                    drop_line = true;
                }
            }
        }
        if (keep && !drop_line)
            text_add(out, line, n);
        line += n;
    }
    if (depth != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "render: %d shader block(s) not closed", depth);
    return MS_OK;
}

uint32_t ms_render_program_variant(const ms_render_options *o, bool coloured, bool wireframe, bool tessellated)
{
    if (wireframe || tessellated)
        coloured = true;
    uint32_t v = MS_RENDER_VARIANT_LIGHTS;
    if (coloured)
        v |= MS_RENDER_VARIANT_COLOUR;
    if (o->section_count > 0 || wireframe || tessellated)
        v |= MS_RENDER_VARIANT_SECTIONS;
    unsigned n = o->light_count < MS_RENDER_MAX_LIGHTS ? o->light_count : MS_RENDER_MAX_LIGHTS;
    v |= (uint32_t)n << MS_RENDER_VARIANT_LIGHT_COUNT_SHIFT;
    for (unsigned i = 0; i < n; ++i)
        v |= ((uint32_t)o->lights[i].kind & 3u) << (MS_RENDER_VARIANT_LIGHT_KIND_SHIFT + 2 * i);
    return v;
}

/* The variant's defines, one per line, for every stage after its #version:
 * MS_VERTEX_COLOUR, MS_SECTIONS, and with fixed lights MS_LIGHT_COUNT and
 * MS_LIGHT_KINDS (each light's code as light_eye's w: 0 directional, 1
 * point, 2 the head light; one 0 for no light, the array needs a size). */
static void variant_defines(uint32_t variant, text_buf *t)
{
    char line[256];
    if (variant & MS_RENDER_VARIANT_COLOUR)
        text_add(t, "#define MS_VERTEX_COLOUR 1\n", strlen("#define MS_VERTEX_COLOUR 1\n"));
    if (variant & MS_RENDER_VARIANT_SECTIONS)
        text_add(t, "#define MS_SECTIONS 1\n", strlen("#define MS_SECTIONS 1\n"));
    if (!(variant & MS_RENDER_VARIANT_LIGHTS))
        return;
    unsigned n = (variant >> MS_RENDER_VARIANT_LIGHT_COUNT_SHIFT) & 15u;
    int len = snprintf(line, sizeof line, "#define MS_LIGHT_COUNT %u\n#define MS_LIGHT_KINDS float[](", n);
    for (unsigned i = 0; i < (n ? n : 1); ++i) {
        unsigned kind = (variant >> (MS_RENDER_VARIANT_LIGHT_KIND_SHIFT + 2 * i)) & 3u;
        const char *code = i >= n                                ? "0.0"
                           : kind == MS_RENDER_LIGHT_DIRECTIONAL ? "0.0"
                           : kind == MS_RENDER_LIGHT_POINT       ? "1.0"
                                                                 : "2.0";
        len += snprintf(line + len, sizeof line - (size_t)len, "%s%s", i ? ", " : "", code);
    }
    snprintf(line + len, sizeof line - (size_t)len, ")\n");
    text_add(t, line, strlen(line));
}

/* A stage's source with the variant's defines after its #version line. */
static ms_status stage_source(const char *src, uint32_t variant, char **out, ms_error *err)
{
    const char *after = strncmp(src, "#version", 8) == 0 ? strchr(src, '\n') : NULL;
    if (!after)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: a shader does not start with #version");
    after++;
    text_buf t = {0};
    text_add(&t, src, (size_t)(after - src));
    variant_defines(variant, &t);
    text_add(&t, after, strlen(after));
    if (t.failed) {
        free(t.data);
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the shader source");
    }
    *out = t.data;
    return MS_OK;
}

ms_status ms_render_program_source(unsigned effects, bool wireframe, char **source, ms_error *err)
{
    return ms_render_program_source_variant(effects, MS_RENDER_VARIANT_GENERAL, wireframe, source, err);
}

ms_status ms_render_program_source_variant(unsigned effects, uint32_t variant, bool wireframe, char **source,
                                           ms_error *err)
{
    if (!source)
        return ms_error_set(err, MS_ERR_ARG, "render: no result pointer");
    *source = NULL;
    if (effects & ~(unsigned)MS_EFFECTS_ALL)
        return ms_error_set(err, MS_ERR_ARG, "render: effects 0x%x outside 0x%x", effects, (unsigned)MS_EFFECTS_ALL);
    /* its first line (#version, which Mesa wants first), the variant's
     * defines, the APO traversal, then the rest */
    const char *frag = ms_shader_cell_frag;
    const char *after = strncmp(frag, "#version", 8) == 0 ? strchr(frag, '\n') : NULL;
    if (!after)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: fragment shader does not start with #version");
    after++;
    text_buf t = {0};
    text_add(&t, frag, (size_t)(after - frag));
    if (wireframe)
        text_add(&t, "#define MS_WIREFRAME 1\n", strlen("#define MS_WIREFRAME 1\n"));
    variant_defines(variant, &t);
    ms_status st = MS_OK;
    if (effects & MS_EFFECT_DETAIL_NORMALS)
        st = resolve_blocks(&t, ms_shader_apo, effects, err);
    if (st == MS_OK && (effects & MS_EFFECT_IMPOSTORS))
        text_add(&t, ms_shader_dither, strlen(ms_shader_dither));
    if (st == MS_OK)
        st = resolve_blocks(&t, after, effects, err);
    if (st == MS_OK && t.failed)
        st = ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the shader source");
    if (st != MS_OK) {
        free(t.data);
        return st;
    }
    *source = t.data;
    return MS_OK;
}

ms_status ms_render_program_build(ms_render_program *p, unsigned effects, uint32_t variant, bool wireframe,
                                  bool tessellated, ms_error *err)
{
    memset(p, 0, sizeof *p);
    if (tessellated && !(effects & MS_EFFECT_DISPLACEMENT))
        return ms_error_set(err, MS_ERR_ARG, "render: displacement stages without the displacement effect");
    char *frag = NULL, *vert = NULL;
    ms_status st0 = ms_render_program_source_variant(effects, variant, wireframe, &frag, err);
    if (st0 == MS_OK)
        st0 = stage_source(tessellated ? ms_shader_tess_vert : ms_shader_cell_vert, variant, &vert, err);
    if (st0 != MS_OK) {
        free(frag);
        return st0;
    }
    const char *vert_src[] = {vert};
    const char *tesc_src[] = {ms_shader_tess_tesc};
    const char *tese_src[] = {ms_shader_tess_tese};
    const char *geom_src[] = {ms_shader_cell_geom};
    const char *frag_src[] = {frag};
    GLuint vs = 0, tcs = 0, tes = 0, gs = 0, fs = 0;
    ms_status st = compile(GL_VERTEX_SHADER, vert_src, 1, "vertex", &vs, err);
    if (st == MS_OK && tessellated)
        st = compile(GL_TESS_CONTROL_SHADER, tesc_src, 1, "tessellation control", &tcs, err);
    if (st == MS_OK && tessellated)
        st = compile(GL_TESS_EVALUATION_SHADER, tese_src, 1, "tessellation evaluation", &tes, err);
    if (st == MS_OK && wireframe)
        st = compile(GL_GEOMETRY_SHADER, geom_src, 1, "geometry", &gs, err);
    if (st == MS_OK)
        st = compile(GL_FRAGMENT_SHADER, frag_src, 1, "fragment", &fs, err);
    free(frag);
    free(vert);
    if (st == MS_OK) {
        p->program = glCreateProgram();
        glAttachShader(p->program, vs);
        if (tcs)
            glAttachShader(p->program, tcs);
        if (tes)
            glAttachShader(p->program, tes);
        if (gs)
            glAttachShader(p->program, gs);
        glAttachShader(p->program, fs);
        glBindAttribLocation(p->program, 0, "cell_position");
        glBindAttribLocation(p->program, 1, "cell_normal");
        glBindAttribLocation(p->program, 2, "cell_colour");
        glBindFragDataLocation(p->program, 0, "colour");
        glLinkProgram(p->program);
        GLint ok = 0;
        glGetProgramiv(p->program, GL_LINK_STATUS, &ok);
        if (!ok) {
            char line[256];
            first_log_line(p->program, true, line, sizeof line);
            st = ms_error_set(err, MS_ERR_UNSUPPORTED, "render: shaders do not link: %s", line);
            glDeleteProgram(p->program);
            p->program = 0;
        }
    }
    if (vs)
        glDeleteShader(vs);
    if (tcs)
        glDeleteShader(tcs);
    if (tes)
        glDeleteShader(tes);
    if (gs)
        glDeleteShader(gs);
    if (fs)
        glDeleteShader(fs);
    if (st != MS_OK)
        return st;
    GLuint g = p->program;
    p->modelview = glGetUniformLocation(g, "modelview");
    p->projection = glGetUniformLocation(g, "projection");
    p->viewport = glGetUniformLocation(g, "viewport");
    p->shading = glGetUniformLocation(g, "shading");
    p->apo_on = glGetUniformLocation(g, "apo_on");
    p->apo_base = glGetUniformLocation(g, "apo_base");
    p->apo_root_internal = glGetUniformLocation(g, "apo_root_internal");
    p->apo_stop_depth = glGetUniformLocation(g, "apo_stop_depth");
    p->apo_nearest = glGetUniformLocation(g, "apo_nearest_rule");
    p->apo_filter = glGetUniformLocation(g, "apo_filter");
    p->apo_footprint_scale = glGetUniformLocation(g, "apo_footprint_scale");
    p->world_to_eye = glGetUniformLocation(g, "world_to_eye");
    p->cell_number = glGetUniformLocation(g, "cell_number");
    p->cell_tint = glGetUniformLocation(g, "cell_tint");
    p->apo_words = glGetUniformLocation(g, "apo_words");
    p->smooth = glGetUniformLocation(g, "smooth_on");
    p->vertex_colour = glGetUniformLocation(g, "vertex_colour");
    p->albedo = glGetUniformLocation(g, "albedo");
    p->light_count = glGetUniformLocation(g, "light_count");
    p->light_eye = glGetUniformLocation(g, "light_eye");
    p->light_colour = glGetUniformLocation(g, "light_colour");
    p->light_range = glGetUniformLocation(g, "light_range");
    p->specular = glGetUniformLocation(g, "specular_strength");
    p->shininess = glGetUniformLocation(g, "shininess");
    p->two_sided = glGetUniformLocation(g, "two_sided");
    p->haze_density = glGetUniformLocation(g, "haze_density");
    p->haze_colour = glGetUniformLocation(g, "haze_colour");
    p->dissolve = glGetUniformLocation(g, "dissolve");
    p->tess_pixels = glGetUniformLocation(g, "tess_pixels_per_level");
    p->disp_amplitude = glGetUniformLocation(g, "displacement_amplitude");
    p->disp_radius = glGetUniformLocation(g, "displacement_radius");
    p->disp_spacing = glGetUniformLocation(g, "displacement_spacing");
    p->disp_seed = glGetUniformLocation(g, "displacement_seed");
    p->cell_origin = glGetUniformLocation(g, "cell_origin");
    p->cell_side = glGetUniformLocation(g, "cell_side");
    p->section_plane = glGetUniformLocation(g, "section_plane");
    p->section_count = glGetUniformLocation(g, "section_count");
    p->section_colour = glGetUniformLocation(g, "section_colour");
    p->effects = effects;
    p->variant = variant;
    p->wireframe = wireframe;
    p->tessellated = tessellated;
    return MS_OK;
}

ms_status ms_render_link_simple(const char *vert, const char *frag, const char *frag_insert, const char *name,
                                GLuint *program, ms_error *err)
{
    *program = 0;
    /* the fragment shader: its #version line, the insert, the rest */
    const char *after = strncmp(frag, "#version", 8) == 0 ? strchr(frag, '\n') : NULL;
    if (!after)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: %s fragment shader does not start with #version", name);
    after++;
    size_t head_len = (size_t)(after - frag);
    char head[64];
    if (head_len >= sizeof head)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: %s fragment shader's first line too long", name);
    memcpy(head, frag, head_len);
    head[head_len] = 0;
    const char *vs_src[] = {vert}, *fs_src[] = {head, frag_insert ? frag_insert : "", after};
    GLuint vs = 0, fs = 0;
    ms_status st = compile(GL_VERTEX_SHADER, vs_src, 1, name, &vs, err);
    if (st == MS_OK)
        st = compile(GL_FRAGMENT_SHADER, fs_src, 3, name, &fs, err);
    if (st == MS_OK) {
        GLuint p = glCreateProgram();
        glAttachShader(p, vs);
        glAttachShader(p, fs);
        glBindFragDataLocation(p, 0, "colour");
        glLinkProgram(p);
        GLint ok = 0;
        glGetProgramiv(p, GL_LINK_STATUS, &ok);
        if (!ok) {
            char line[256];
            first_log_line(p, true, line, sizeof line);
            st = ms_error_set(err, MS_ERR_UNSUPPORTED, "render: %s shaders do not link: %s", name, line);
            glDeleteProgram(p);
        } else
            *program = p;
    }
    if (vs)
        glDeleteShader(vs);
    if (fs)
        glDeleteShader(fs);
    return st;
}

const char *ms_effect_name(unsigned effect)
{
    switch (effect) {
    case MS_EFFECT_DETAIL_NORMALS: return "detail_normals";
    case MS_EFFECT_SPECULAR: return "specular";
    case MS_EFFECT_TWO_SIDED: return "two_sided";
    case MS_EFFECT_HAZE: return "haze";
    case MS_EFFECT_IMPOSTORS: return "impostors";
    case MS_EFFECT_DISPLACEMENT: return "displacement";
    default: return NULL;
    }
}

void ms_render_program_free(ms_render_program *p)
{
    if (p->program)
        glDeleteProgram(p->program);
    memset(p, 0, sizeof *p);
}
