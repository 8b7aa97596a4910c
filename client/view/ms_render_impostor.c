/* Impostors (ms_render_impostor.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_render_impostor.h"
#include "ms_render_internal.h"
#include "ms_render_shaders.h"
#include "ms_vec3.h"

/* The capture camera stands this many radii from the centre: close enough to
 * orthographic for the fragment stage's parallel-ray model. */
#define CAPTURE_DISTANCE_RADII 50.0

struct ms_impostor {
    int size;
    GLuint fbo, colour, depth;
    GLuint program, vao, vbo;
    GLint u_view_projection, u_centre, u_quad_right, u_quad_up, u_colour, u_depth, u_cap_right, u_cap_up,
        u_cap_forward, u_radius, u_cap_distance, u_cap_near, u_cap_far, u_coverage, u_haze_density, u_haze_colour;
    bool captured;
    double centre[3], radius;
    double right[3], up[3], forward[3]; /* the capture's frame */
    double distance, near_distance, far_distance;
};

void ms_impostor_free(ms_impostor *imp)
{
    if (!imp)
        return;
    if (imp->fbo)
        glDeleteFramebuffers(1, &imp->fbo);
    if (imp->colour)
        glDeleteTextures(1, &imp->colour);
    if (imp->depth)
        glDeleteTextures(1, &imp->depth);
    if (imp->program)
        glDeleteProgram(imp->program);
    if (imp->vao)
        glDeleteVertexArrays(1, &imp->vao);
    if (imp->vbo)
        glDeleteBuffers(1, &imp->vbo);
    free(imp);
}

uint64_t ms_impostor_gl_bytes(const ms_impostor *imp)
{
    if (!imp)
        return 0;
    uint64_t pixels = (uint64_t)imp->size * (uint64_t)imp->size;
    return (imp->colour ? 4 * pixels : 0) + (imp->depth ? 4 * pixels : 0) + (imp->vbo ? 8 * sizeof(float) : 0);
}

static GLuint make_texture(GLenum internal, GLenum format, GLenum type, int size)
{
    GLuint t;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexImage2D(GL_TEXTURE_2D, 0, (GLint)internal, size, size, 0, format, type, NULL);
    /* nearest: a filtered texel would mix the surface with the empty
     * background around it (seed 001's dark fringes) */
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glBindTexture(GL_TEXTURE_2D, 0);
    return t;
}

ms_status ms_impostor_new(int size, ms_impostor **out, ms_error *err)
{
    *out = NULL;
    if (size < 16 || size > 2048)
        return ms_error_set(err, MS_ERR_ARG, "impostor: %d pixels, 16 to 2048", size);
    ms_impostor *imp = calloc(1, sizeof *imp);
    if (!imp)
        return ms_error_set(err, MS_ERR_NOMEM, "impostor: no memory");
    imp->size = size;
    ms_status st = ms_render_link_simple(ms_shader_impostor_vert, ms_shader_impostor_frag, ms_shader_dither,
                                         "impostor", &imp->program, err);
    if (st != MS_OK) {
        ms_impostor_free(imp);
        return st;
    }
    GLuint g = imp->program;
    imp->u_view_projection = glGetUniformLocation(g, "view_projection");
    imp->u_centre = glGetUniformLocation(g, "centre");
    imp->u_quad_right = glGetUniformLocation(g, "quad_right");
    imp->u_quad_up = glGetUniformLocation(g, "quad_up");
    imp->u_colour = glGetUniformLocation(g, "impostor_colour");
    imp->u_depth = glGetUniformLocation(g, "impostor_depth");
    imp->u_cap_right = glGetUniformLocation(g, "capture_right");
    imp->u_cap_up = glGetUniformLocation(g, "capture_up");
    imp->u_cap_forward = glGetUniformLocation(g, "capture_forward");
    imp->u_radius = glGetUniformLocation(g, "radius");
    imp->u_cap_distance = glGetUniformLocation(g, "capture_distance");
    imp->u_cap_near = glGetUniformLocation(g, "capture_near");
    imp->u_cap_far = glGetUniformLocation(g, "capture_far");
    imp->u_coverage = glGetUniformLocation(g, "coverage");
    imp->u_haze_density = glGetUniformLocation(g, "haze_density");
    imp->u_haze_colour = glGetUniformLocation(g, "haze_colour");
    imp->colour = make_texture(GL_RGBA8, GL_RGBA, GL_UNSIGNED_BYTE, size);
    imp->depth = make_texture(GL_DEPTH_COMPONENT32F, GL_DEPTH_COMPONENT, GL_FLOAT, size);
    GLint previous = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
    glGenFramebuffers(1, &imp->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, imp->fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, imp->colour, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, imp->depth, 0);
    GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    glBindFramebuffer(GL_FRAMEBUFFER, (GLuint)previous);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
        ms_impostor_free(imp);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "impostor: framebuffer incomplete (0x%x)", status);
    }
    const float corners[8] = {-1, -1, 1, -1, 1, 1, -1, 1};
    glGenVertexArrays(1, &imp->vao);
    glGenBuffers(1, &imp->vbo);
    glBindVertexArray(imp->vao);
    glBindBuffer(GL_ARRAY_BUFFER, imp->vbo);
    glBufferData(GL_ARRAY_BUFFER, sizeof corners, corners, GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 8, NULL);
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    *out = imp;
    return MS_OK;
}

ms_status ms_impostor_capture(ms_impostor *imp, ms_render *r, const ms_render_options *options,
                              const double centre[3], double radius, const ms_camera *camera, ms_error *err)
{
    if (!imp || !r || !options || !camera || !(radius > 0.0) || !isfinite(radius))
        return ms_error_set(err, MS_ERR_ARG, "impostor: bad capture arguments");
    double dir[3], len = 0;
    for (int a = 0; a < 3; ++a) {
        dir[a] = centre[a] - camera->position[a];
        len += dir[a] * dir[a];
    }
    len = sqrt(len);
    if (!(len > 0.0))
        return ms_error_set(err, MS_ERR_ARG, "impostor: the camera is at the object's centre");
    double d = CAPTURE_DISTANCE_RADII * radius, eye[3];
    for (int a = 0; a < 3; ++a)
        eye[a] = centre[a] - dir[a] / len * d;
    /* the view's up, unless it runs along the capture direction */
    const double *up = fabs(ms_vec3_dot(camera->up, dir) / len) < 0.99 ? camera->up : camera->right;
    double fovy = 2.0 * atan(radius / d) * 180.0 / M_PI;
    ms_camera cap;
    ms_status st = ms_camera_look_at(eye, centre, up, fovy, imp->size, imp->size, d - 1.05 * radius,
                                     d + 1.05 * radius, &cap, err);
    if (st != MS_OK)
        return st;
    GLint previous = 0, viewport[4];
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &previous);
    glGetIntegerv(GL_VIEWPORT, viewport);
    glBindFramebuffer(GL_FRAMEBUFFER, imp->fbo);
    ms_render_options o = *options;
    o.clear = true;
    o.wireframe = false;
    o.dissolve = 0.0f;
    o.haze_density = 0.0f; /* added at the true distance when drawn */
    st = ms_render_draw(r, &cap, &o, NULL, err);
    glBindFramebuffer(GL_FRAMEBUFFER, (GLuint)previous);
    glViewport(viewport[0], viewport[1], viewport[2], viewport[3]);
    if (st != MS_OK)
        return st;
    imp->captured = true;
    memcpy(imp->centre, centre, sizeof imp->centre);
    imp->radius = radius;
    memcpy(imp->right, cap.right, sizeof imp->right);
    memcpy(imp->up, cap.up, sizeof imp->up);
    memcpy(imp->forward, cap.forward, sizeof imp->forward);
    imp->distance = d;
    imp->near_distance = cap.near_distance;
    imp->far_distance = cap.far_distance;
    return MS_OK;
}

double ms_impostor_angle(const ms_impostor *imp, const ms_camera *camera)
{
    if (!imp || !imp->captured)
        return 180.0;
    double dir[3], len = 0;
    for (int a = 0; a < 3; ++a) {
        dir[a] = imp->centre[a] - camera->position[a];
        len += dir[a] * dir[a];
    }
    len = sqrt(len);
    if (!(len > 0.0))
        return 180.0;
    double c = ms_vec3_dot(dir, imp->forward) / len;
    return acos(c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c)) * 180.0 / M_PI;
}

ms_status ms_impostor_draw(ms_impostor *imp, const ms_camera *camera, float coverage, float haze_density,
                           const float haze_colour[3], ms_error *err)
{
    if (!imp || !camera)
        return ms_error_set(err, MS_ERR_ARG, "impostor: nothing to draw");
    if (!imp->captured)
        return ms_error_set(err, MS_ERR_ARG, "impostor: nothing captured");
    ms_status st = ms_render_camera_check(camera, err);
    if (st != MS_OK)
        return st;
    /* camera-relative world: the view's rotation only, in doubles */
    double view[16], proj[16], rot[16], vp[16];
    ms_render_camera_matrices(camera, view, proj);
    memcpy(rot, view, sizeof rot);
    rot[12] = rot[13] = rot[14] = 0.0;
    for (int c = 0; c < 4; ++c)
        for (int row = 0; row < 4; ++row) {
            double v = 0;
            for (int k = 0; k < 4; ++k)
                v += proj[4 * k + row] * rot[4 * c + k];
            vp[4 * c + row] = v;
        }
    float vpf[16], centre[3], right[3], up[3], cr[3], cu[3], cf[3];
    for (int i = 0; i < 16; ++i)
        vpf[i] = (float)vp[i];
    /* the quad faces the camera and covers the sphere's outline from its
     * distance (the sphere's silhouette is a circle of radius r d / sqrt(d^2 - r^2)) */
    double dist = 0;
    for (int a = 0; a < 3; ++a)
        dist += (imp->centre[a] - camera->position[a]) * (imp->centre[a] - camera->position[a]);
    dist = sqrt(dist);
    double half = dist > 1.01 * imp->radius ? imp->radius * dist / sqrt(dist * dist - imp->radius * imp->radius)
                                            : 100.0 * imp->radius;
    half *= 1.02;
    for (int a = 0; a < 3; ++a) {
        centre[a] = (float)(imp->centre[a] - camera->position[a]);
        right[a] = (float)(camera->right[a] * half);
        up[a] = (float)(camera->up[a] * half);
        cr[a] = (float)imp->right[a];
        cu[a] = (float)imp->up[a];
        cf[a] = (float)imp->forward[a];
    }
    glUseProgram(imp->program);
    glUniformMatrix4fv(imp->u_view_projection, 1, GL_FALSE, vpf);
    glUniform3fv(imp->u_centre, 1, centre);
    glUniform3fv(imp->u_quad_right, 1, right);
    glUniform3fv(imp->u_quad_up, 1, up);
    glUniform3fv(imp->u_cap_right, 1, cr);
    glUniform3fv(imp->u_cap_up, 1, cu);
    glUniform3fv(imp->u_cap_forward, 1, cf);
    glUniform1f(imp->u_radius, (float)imp->radius);
    glUniform1f(imp->u_cap_distance, (float)imp->distance);
    glUniform1f(imp->u_cap_near, (float)imp->near_distance);
    glUniform1f(imp->u_cap_far, (float)imp->far_distance);
    glUniform1f(imp->u_coverage, coverage);
    glUniform1f(imp->u_haze_density, haze_density);
    const float none[3] = {0, 0, 0};
    glUniform3fv(imp->u_haze_colour, 1, haze_colour ? haze_colour : none);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, imp->colour);
    glUniform1i(imp->u_colour, 1);
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D, imp->depth);
    glUniform1i(imp->u_depth, 2);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDisable(GL_CULL_FACE);
    glBindVertexArray(imp->vao);
    glDrawArrays(GL_TRIANGLE_FAN, 0, 4);
    glBindVertexArray(0);
    glBindTexture(GL_TEXTURE_2D, 0);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, 0);
    glActiveTexture(GL_TEXTURE0);
    glUseProgram(0);
    GLenum e = glGetError();
    if (e != GL_NO_ERROR)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "impostor: GL error 0x%x while drawing", e);
    return MS_OK;
}
