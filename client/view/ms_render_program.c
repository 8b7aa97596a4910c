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

ms_status ms_render_program_build(ms_render_program *p, bool wireframe, ms_error *err)
{
    memset(p, 0, sizeof *p);
    /* the fragment shader: its first line (#version, which Mesa wants first),
     * the variant's define, the APO traversal, then the rest */
    const char *frag = ms_shader_cell_frag;
    const char *after = strncmp(frag, "#version", 8) == 0 ? strchr(frag, '\n') : NULL;
    if (!after)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: fragment shader does not start with #version");
    after++;
    size_t head_len = (size_t)(after - frag);
    char *head = malloc(head_len + 1);
    if (!head)
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory");
    memcpy(head, frag, head_len);
    head[head_len] = 0;
    const char *vert_src[] = {ms_shader_cell_vert};
    const char *geom_src[] = {ms_shader_cell_geom};
    const char *frag_src[] = {head, wireframe ? "#define MS_WIREFRAME 1\n" : "", ms_shader_apo, after};
    GLuint vs = 0, gs = 0, fs = 0;
    ms_status st = compile(GL_VERTEX_SHADER, vert_src, 1, "vertex", &vs, err);
    if (st == MS_OK && wireframe)
        st = compile(GL_GEOMETRY_SHADER, geom_src, 1, "geometry", &gs, err);
    if (st == MS_OK)
        st = compile(GL_FRAGMENT_SHADER, frag_src, 4, "fragment", &fs, err);
    free(head);
    if (st == MS_OK) {
        p->program = glCreateProgram();
        glAttachShader(p->program, vs);
        if (gs)
            glAttachShader(p->program, gs);
        glAttachShader(p->program, fs);
        glBindAttribLocation(p->program, 0, "cell_position");
        glBindAttribLocation(p->program, 1, "cell_normal");
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
    p->world_to_eye = glGetUniformLocation(g, "world_to_eye");
    p->cell_number = glGetUniformLocation(g, "cell_number");
    p->cell_tint = glGetUniformLocation(g, "cell_tint");
    p->apo_words = glGetUniformLocation(g, "apo_words");
    p->smooth = glGetUniformLocation(g, "smooth_on");
    return MS_OK;
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
