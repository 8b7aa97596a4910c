/* meshview: the window that shows streamed models (docs/VIEWER.md).
 *
 * One loop, one frame per turn: poll GLFW's events (they only change the
 * viewer's state: camera controls, toggles, requests), step the stream (the
 * core gets the camera, the newest frame goes to the renderer, at most the
 * upload budget goes to the GPU), draw, overlay the HUD, swap. Nothing in the
 * loop waits for the network or for decoding. Models open from the catalogue
 * screen or --model; opening fetches the model's index first (a bounded wait,
 * with a message on screen) and starts a fresh stream.
 *
 * Scripted runs (--path / --screenshot-dir) go to ms_viewer_script.h.
 */
#include <epoxy/gl.h>
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ms_gl_window.h"
#include "ms_process_memory.h"
#include "ms_viewer_catalogue.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_font.h"
#include "ms_viewer_hud.h"
#include "ms_viewer_inspect.h"
#include "ms_viewer_model.h"
#include "ms_viewer_options.h"
#include "ms_viewer_pick.h"
#include "ms_viewer_playback.h"
#include "ms_viewer_readback.h"
#include "ms_viewer_scene.h"
#include "ms_viewer_script.h"
#include "ms_viewer_signals.h"
#include "ms_viewer_stream.h"
#include "ms_viewer_text.h"
#include "ms_version.h"

#define DOUBLE_CLICK_S 0.35
#define DOUBLE_CLICK_PX 4.0

typedef struct viewer {
    const ms_viewer_options *o;
    ms_viewer_source source;
    char where[128];
    GLFWwindow *window;
    ms_viewer_text *text;
    ms_viewer_model_list list;
    bool have_list;
    ms_viewer_catalogue catalogue;
    bool on_catalogue;
    unsigned model_reopens;        /* new versions opened after a rescan replaced the model */
    /* the open model */
    ms_viewer_model model;
    ms_viewer_stream *stream;
    /* or the open scene (--scene) */
    ms_scene scene;
    ms_viewer_scene *vscene;
    ms_viewer_controls controls;
    ms_viewer_playback playback;   /* the path Space plays (--path, or the scene's) */
    long selected;                 /* the selected piece of a scene; -1: none */
    ms_viewer_inspect inspect;     /* measuring, the light, the view text (one model) */
    unsigned model_opens;
    ms_render_options render;
    bool apo, geometry_normals, hud;
    char message[256];             /* shown on the catalogue screen (last failure) */
    char mode_text[96];            /* the HUD's shading line (ms_viewer_hud_mode) */
    int screenshots;
    /* input */
    bool rotating, panning;
    double cursor_x, cursor_y;     /* window coordinates */
    double last_click_time, last_click_x, last_click_y;
    bool recentre_requested, pick_requested; /* a double click; a click in a scene */
    double recentre_x, recentre_y; /* framebuffer pixels, top-left origin */
    bool screenshot_requested;
    long open_delta;               /* next/previous model requested */
    bool open_requested;           /* Enter / double-click on the catalogue */
    /* frame timing */
    double frame_ms, fps, last_frame;
    ms_render_draw_stats drawn;
    bool settled;
} viewer;

/* Mesa's software driver leaks a few bytes of its own when it is unloaded, where
 * LeakSanitizer can no longer name it: meshview keeps it loaded to the end
 * (ms_gl_window_keep_driver_loaded) so that a leak report names it, and suppresses exactly that
 * module (the same rule as tests/support/ms_test_render.c). Used only by
 * sanitizer builds. */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void)
{
    return "leak:swrast_dri.so\nleak:libgallium\nleak:libLLVM\n";
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Framebuffer pixels per window coordinate (HiDPI: 2 on a retina screen). */
static double pixel_ratio(GLFWwindow *w)
{
    int ww, wh, fw, fh;
    glfwGetWindowSize(w, &ww, &wh);
    glfwGetFramebufferSize(w, &fw, &fh);
    return ww > 0 ? (double)fw / ww : 1;
}

static int text_scale(const viewer *v)
{
    int fw, fh;
    glfwGetFramebufferSize(v->window, &fw, &fh);
    return ms_viewer_text_auto_scale(fh, pixel_ratio(v->window), v->on_catalogue || (!v->stream && !v->vscene));
}

static void update_shading(viewer *v)
{
    v->render.apo = v->apo && !v->geometry_normals;
}

static void close_model(viewer *v)
{
    ms_viewer_inspect_close(&v->inspect); /* its probe streams the model too */
    ms_viewer_stream_close(v->stream);
    v->stream = NULL;
    ms_viewer_model_close(&v->model);
}

static int catalogue_frame(viewer *v, int fw, int fh);

/* Opens model `name`; on failure stays where it is with the message set. The
 * index fetch is a bounded wait (the source's time-out): a frame saying so is
 * shown first. */
static bool open_model(viewer *v, const char *name)
{
    close_model(v);
    int fw, fh;
    if (v->text) {
        glfwGetFramebufferSize(v->window, &fw, &fh);
        snprintf(v->message, sizeof v->message, "opening %s ...", name);
        if (fw > 0 && fh > 0 && catalogue_frame(v, fw, fh) == 0)
            glfwSwapBuffers(v->window);
    }
    ms_viewer_catalogue_free(&v->catalogue); /* its worker stops (a fetch in flight too) */
    ms_viewer_stream_settings settings = ms_viewer_options_stream_settings(v->o);
    ms_error err;
    /* from the catalogue already listed: opening costs no listing (at a
     * distance, a connection and a round trip) */
    if (ms_viewer_model_open_listed(&v->source, &v->list, name, &v->model, &err) != MS_OK ||
        ms_viewer_stream_open(&v->source, &v->model, &settings, &v->stream, &err) != MS_OK) {
        snprintf(v->message, sizeof v->message, "%.250s", err.text);
        close_model(v);
        return false;
    }
    double lo[3], hi[3];
    ms_viewer_model_bounds(&v->model, lo, hi);
    glfwGetFramebufferSize(v->window, &fw, &fh);
    ms_viewer_controls_init(&v->controls, lo, hi, v->o->up_axis,
                            fw > 0 && fh > 0 ? (double)fw / fh : (double)v->o->width / v->o->height);
    if (v->model_opens++ == 0) /* --view: the first model's (--model) */
        ms_viewer_inspect_view(v->o, &v->controls);
    else
        ms_viewer_measure_clear(&v->inspect.measure);
    ms_viewer_playback_stop(&v->playback);
    v->on_catalogue = false;
    v->message[0] = 0;
    char title[128];
    snprintf(title, sizeof title, "meshview - %s", name);
    glfwSetWindowTitle(v->window, title);
    return true;
}

static void open_neighbour(viewer *v, long delta)
{
    if (!v->have_list || !v->list.count)
        return;
    size_t n = v->list.count, at = v->catalogue.selected;
    for (size_t i = 0; i < n; ++i)
        if (!strcmp(v->list.entries[i].name, v->model.name))
            at = i;
    size_t next = (size_t)(((long)at + delta % (long)n + (long)n) % (long)n);
    v->catalogue.selected = next;
    if (!open_model(v, v->list.entries[next].name))
        v->on_catalogue = true;
}

/* --- GLFW callbacks: they only record what the loop acts on ---------------- */

/* K: the next crease angle (ms_viewer_next_crease_angle); the frame in hand
 * is set again with it. */
static void next_crease_angle(viewer *v)
{
    ms_error err;
    if (v->stream && ms_viewer_stream_set_crease_angle(
                         v->stream, ms_viewer_next_crease_angle(ms_viewer_stream_crease_angle(v->stream)),
                         &err) != MS_OK)
        fprintf(stderr, "meshview: %s\n", err.text);
}

/* ] / [ (PgDn / PgUp): the next or previous model, or in a scene piece. */
static void next_key(viewer *v, int delta)
{
    if (v->vscene)
        v->selected = ms_viewer_pick_cycle(v->selected, ms_viewer_scene_piece_count(v->vscene), delta);
    else
        v->open_delta = delta;
}

/* Z: the selected piece of a scene fills the view. */
static void frame_selected(viewer *v)
{
    int fw, fh;
    glfwGetFramebufferSize(v->window, &fw, &fh);
    if (v->vscene && fh > 0)
        ms_viewer_pick_frame_piece(v->vscene, v->selected, &v->controls, (double)fw / fh);
}

static void on_key(GLFWwindow *w, int key, int scancode, int action, int mods)
{
    (void)scancode;
    viewer *v = glfwGetWindowUserPointer(w);
    if (action != GLFW_PRESS && action != GLFW_REPEAT)
        return;
    v->inspect.notes.cursor_x = v->cursor_x * pixel_ratio(w), v->inspect.notes.cursor_y = v->cursor_y * pixel_ratio(w);
    if (!v->on_catalogue && !v->vscene && (action == GLFW_PRESS || v->inspect.notes.typing) &&
        ms_viewer_annotate_key(&v->inspect.notes, key, mods, &v->controls, &v->inspect.light, stderr))
        return; /* annotations: Enter, Shift+Delete, Ctrl+S; every key while typing */
    if (key == GLFW_KEY_ESCAPE) {
        glfwSetWindowShouldClose(w, GLFW_TRUE);
        return;
    }
    if (v->on_catalogue) {
        int fw, fh;
        glfwGetFramebufferSize(w, &fw, &fh);
        ms_catalogue_action act = ms_viewer_catalogue_key(&v->catalogue, key, fh, text_scale(v));
        v->open_requested |= act == MS_CATALOGUE_OPEN;
        if (act == MS_CATALOGUE_BACK && v->stream)
            v->on_catalogue = false;
        return;
    }
    if (action == GLFW_REPEAT && key != GLFW_KEY_EQUAL && key != GLFW_KEY_MINUS && key != GLFW_KEY_KP_ADD &&
        key != GLFW_KEY_KP_SUBTRACT && key != GLFW_KEY_9 && key != GLFW_KEY_0) /* held: the section moves on */
        return;
    ms_viewer_controls *c = &v->controls;
    if (!v->vscene && ms_viewer_inspect_key(&v->inspect, key, c, stdout))
        return;
    switch (key) {
    case GLFW_KEY_O: v->apo = !v->apo; break;
    case GLFW_KEY_G: v->geometry_normals = !v->geometry_normals; break;
    case GLFW_KEY_N: v->render.shading = ms_viewer_toggle_shading(v->render.shading, MS_SHADING_NORMALS); break;
    case GLFW_KEY_C: v->render.shading = ms_viewer_toggle_shading(v->render.shading, MS_SHADING_CELLS); break;
    case GLFW_KEY_B: v->render.shading = ms_viewer_toggle_shading(v->render.shading, MS_SHADING_ALBEDO); break;
    case GLFW_KEY_X: v->render.wireframe = !v->render.wireframe; break;
    case GLFW_KEY_M: v->render.smooth = !v->render.smooth; break;
    case GLFW_KEY_K: next_crease_angle(v); break;
    case GLFW_KEY_H: v->hud = !v->hud; break;
    case GLFW_KEY_P: v->screenshot_requested = true; break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD:
        if (v->stream)
            ms_viewer_stream_set_tolerance(v->stream, ms_viewer_stream_tolerance(v->stream) / 1.5);
        break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT:
        if (v->stream)
            ms_viewer_stream_set_tolerance(v->stream, ms_viewer_stream_tolerance(v->stream) * 1.5);
        break;
    case GLFW_KEY_R: ms_viewer_controls_reset(c); break;
    case GLFW_KEY_U: ms_viewer_controls_set_up(c, (c->up_axis + 1) % 3); break;
    case GLFW_KEY_F: c->fly = !c->fly; break;
    case GLFW_KEY_SPACE: ms_viewer_playback_toggle(&v->playback, c); break;
    case GLFW_KEY_PERIOD: ms_viewer_playback_step(&v->playback, 1, c); break;
    case GLFW_KEY_COMMA: ms_viewer_playback_step(&v->playback, -1, c); break;
    case GLFW_KEY_Z: frame_selected(v); break;
    case GLFW_KEY_RIGHT_BRACKET:
    case GLFW_KEY_PAGE_DOWN: next_key(v, 1); break;
    case GLFW_KEY_LEFT_BRACKET:
    case GLFW_KEY_PAGE_UP: next_key(v, -1); break;
    case GLFW_KEY_TAB:
        if (v->have_list)
            v->on_catalogue = true;
        break;
    default: break;
    }
    update_shading(v);
}

static void on_mouse_button(GLFWwindow *w, int button, int action, int mods)
{
    viewer *v = glfwGetWindowUserPointer(w);
    double x, y;
    glfwGetCursorPos(w, &x, &y);
    v->cursor_x = x, v->cursor_y = y;
    double ratio = pixel_ratio(w);
    if (action == GLFW_RELEASE) {
        v->rotating = v->panning = v->inspect.lighting = false;
        /* a click (no drag) in a scene picks the piece under it; measuring, adds a
         * point; else selects the annotation under it */
        if (button == GLFW_MOUSE_BUTTON_LEFT && fabs(x - v->last_click_x) < DOUBLE_CLICK_PX &&
            fabs(y - v->last_click_y) < DOUBLE_CLICK_PX) {
            v->pick_requested = v->vscene != NULL; /* a double click's second adds no point */
            v->inspect.add_requested = !v->vscene && v->inspect.measuring && v->last_click_time >= 0;
            v->inspect.notes.click_requested = !v->vscene && !v->inspect.measuring;
            v->recentre_x = v->inspect.add_x = v->inspect.notes.click_x = x * ratio;
            v->recentre_y = v->inspect.add_y = v->inspect.notes.click_y = y * ratio;
        }
        return;
    }
    bool pan = button == GLFW_MOUSE_BUTTON_RIGHT || button == GLFW_MOUSE_BUTTON_MIDDLE ||
               (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_SHIFT));
    double t = glfwGetTime();
    bool twice = button == GLFW_MOUSE_BUTTON_LEFT && t - v->last_click_time < DOUBLE_CLICK_S &&
                 fabs(x - v->last_click_x) < DOUBLE_CLICK_PX &&
                 fabs(y - v->last_click_y) < DOUBLE_CLICK_PX;
    if (button == GLFW_MOUSE_BUTTON_LEFT) {
        v->last_click_time = twice ? -1 : t;
        v->last_click_x = x, v->last_click_y = y;
    }
    if (v->on_catalogue) {
        if (button != GLFW_MOUSE_BUTTON_LEFT)
            return;
        int fw, fh;
        glfwGetFramebufferSize(w, &fw, &fh);
        long row = ms_viewer_catalogue_row_at(&v->catalogue, x * ratio, y * ratio, fw, fh,
                                              text_scale(v));
        if (row >= 0) {
            v->catalogue.selected = (size_t)row;
            if (twice)
                v->open_requested = true;
        }
        return;
    }
    if (twice) {
        v->recentre_requested = true;
        v->recentre_x = x * ratio, v->recentre_y = y * ratio;
        return;
    }
    if (button == GLFW_MOUSE_BUTTON_LEFT && (mods & GLFW_MOD_CONTROL) && !v->vscene)
        v->inspect.lighting = true; /* Ctrl + drag moves the light */
    else if (pan)
        v->panning = true;
    else if (button == GLFW_MOUSE_BUTTON_LEFT)
        v->rotating = true;
}

static void on_char(GLFWwindow *w, unsigned codepoint)
{
    viewer *v = glfwGetWindowUserPointer(w);
    ms_viewer_annotate_char(&v->inspect.notes, codepoint);
}

static void on_cursor(GLFWwindow *w, double x, double y)
{
    viewer *v = glfwGetWindowUserPointer(w);
    double ratio = pixel_ratio(w);
    double dx = (x - v->cursor_x) * ratio, dy = (y - v->cursor_y) * ratio;
    v->cursor_x = x, v->cursor_y = y;
    if (v->on_catalogue || (!v->rotating && !v->panning && !v->inspect.lighting))
        return;
    int fw, fh;
    glfwGetFramebufferSize(w, &fw, &fh);
    if (v->inspect.lighting)
        ms_viewer_light_drag(&v->inspect.light, dx, dy, fh);
    else if (v->panning)
        ms_viewer_controls_pan(&v->controls, dx, dy, fh);
    else
        ms_viewer_controls_rotate(&v->controls, dx, dy, fh);
}

static void on_scroll(GLFWwindow *w, double dx, double dy)
{
    (void)dx;
    viewer *v = glfwGetWindowUserPointer(w);
    if (v->on_catalogue) {
        int fw, fh;
        glfwGetFramebufferSize(w, &fw, &fh);
        ms_viewer_catalogue_move(&v->catalogue, dy > 0 ? -1 : 1, fh, text_scale(v));
        return;
    }
    ms_viewer_controls_zoom(&v->controls, dy);
}

/* --- the loop ------------------------------------------------------------ */

static void fly_keys(viewer *v, double seconds)
{
    if (!v->controls.fly)
        return;
    GLFWwindow *w = v->window;
    double f = (glfwGetKey(w, GLFW_KEY_W) == GLFW_PRESS) - (glfwGetKey(w, GLFW_KEY_S) == GLFW_PRESS);
    double r = (glfwGetKey(w, GLFW_KEY_D) == GLFW_PRESS) - (glfwGetKey(w, GLFW_KEY_A) == GLFW_PRESS);
    double u = (glfwGetKey(w, GLFW_KEY_E) == GLFW_PRESS) - (glfwGetKey(w, GLFW_KEY_Q) == GLFW_PRESS);
    if (f || r || u)
        ms_viewer_controls_fly(&v->controls, f, r, u, seconds);
}

/* What the window shows: the scene's name or the model's. */
static const char *shown_name(const viewer *v)
{
    return v->vscene ? (v->scene.name[0] ? v->scene.name : "scene") : v->model.name;
}

static void take_screenshot(viewer *v, int fw, int fh)
{
    char path[4200];
    ms_error err;
    if (ms_viewer_screenshot_numbered(v->o->screenshot_dir ? v->o->screenshot_dir : ".", shown_name(v),
                                      &v->screenshots, fw, fh, path, sizeof path, &err) != MS_OK)
        snprintf(v->message, sizeof v->message, "%.250s", err.text);
    else
        fprintf(stderr, "meshview: wrote %s\n", path);
}

/* A rescan replaced the model being viewed (the core stopped with
 * stats.model_changed): open the new version by name, keeping the user's view,
 * at most MAX_MODEL_REOPENS times in a session. True when it was reopened. */
enum { MAX_MODEL_REOPENS = 8 };
static bool reopen_changed_model(viewer *v, const char *why)
{
    if (v->vscene || !v->stream || v->model_reopens >= MAX_MODEL_REOPENS)
        return false;
    ms_core_stats cs;
    ms_viewer_stream_stats(v->stream, &cs);
    if (!cs.model_changed)
        return false;
    v->model_reopens++;
    fprintf(stderr, "meshview: %s; opening the new version\n", why);
    char name[sizeof v->model.name];
    snprintf(name, sizeof name, "%s", v->model.name);
    ms_viewer_controls kept = v->controls;
    if (!open_model(v, name)) {
        v->on_catalogue = true;
        return true;
    }
    v->controls = kept;
    return true;
}

/* Seconds since the last frame; updates the frame time (smoothed over about
 * half a second of frames) and the frame rate. */
static double frame_tick(viewer *v)
{
    double t = now_s(), seconds = t - v->last_frame;
    v->last_frame = t;
    double a = seconds > 0.5 ? 1 : seconds / 0.5;
    v->frame_ms += (seconds * 1e3 - v->frame_ms) * (v->frame_ms ? a : 1);
    v->fps = v->frame_ms > 0 ? 1e3 / v->frame_ms : 0;
    return seconds;
}

/* The window's framebuffer size; false (after waiting up to 50 ms for events)
 * while it is minimised. */
static bool framebuffer_size(viewer *v, int *fw, int *fh)
{
    glfwGetFramebufferSize(v->window, fw, fh);
    if (*fw < 1 || *fh < 1) {
        glfwWaitEventsTimeout(0.05);
        return false;
    }
    return true;
}

/* The GL storage the viewer holds (ms_render.h, "GL memory"): the renderers'
 * (a scene's impostors too) and the overlay's; the window's own framebuffer
 * is the driver's. */
static uint64_t gl_bytes(viewer *v)
{
    uint64_t bytes = 0, peak;
    ms_render_memory_stats m;
    if (v->vscene)
        ms_viewer_scene_gl_memory(v->vscene, &bytes, &peak);
    ms_render_memory(v->stream ? ms_viewer_stream_render(v->stream) : NULL, &m);
    return bytes + m.gl_bytes + ms_viewer_text_gl_bytes(v->text);
}

/* One frame of the model view. 1 on a fatal error (printed). */
static int view_frame(viewer *v, int fw, int fh, double seconds)
{
    ms_error err;
    v->controls.aspect = (double)fw / fh; /* the home view (R) frames this shape */
    fly_keys(v, seconds);
    if (!v->vscene) /* toward a selected annotation's view */
        ms_viewer_annotate_animate(&v->inspect.notes, &v->controls, &v->inspect.light, seconds);
    ms_camera camera;
    if (ms_viewer_playback_frame_camera(&v->playback, &v->controls, fw, fh, seconds, &camera, &err) != MS_OK)
        ms_viewer_controls_reset(&v->controls);
    else {
        ms_viewer_step step;
        ms_status st = v->vscene ? ms_viewer_scene_step(v->vscene, &camera, v->o->upload_budget, &step, &err)
                                 : ms_viewer_stream_step(v->stream, &camera, v->o->upload_budget, &step, &err);
        if (st == MS_OK && !v->vscene) /* the light; the chain on the frame, a click's point */
            ms_viewer_inspect_frame(&v->inspect, v->stream, &camera, &v->render);
        if (st == MS_OK)
            st = v->vscene ? ms_viewer_scene_draw(v->vscene, &camera, &v->render, &v->drawn, &err)
                           : ms_viewer_stream_draw(v->stream, &camera, &v->render, &v->drawn, &err);
        if (st != MS_OK && reopen_changed_model(v, err.text))
            return 0;
        if (st != MS_OK) {
            fprintf(stderr, "meshview: %s\n", err.text);
            return 1;
        }
        v->settled = step.settled;
        double world[3]; /* a click selects the piece under it, a double click re-centres */
        bool hit = (v->recentre_requested || v->pick_requested) &&
                   ms_viewer_pick_surface(&camera, v->recentre_x, v->recentre_y, world);
        if (hit && v->recentre_requested)
            ms_viewer_controls_recentre(&v->controls, world);
        if (v->pick_requested && v->vscene)
            v->selected = hit ? ms_viewer_pick_scene_piece(v->vscene, world) : -1;
        v->recentre_requested = v->pick_requested = false;
        if (v->screenshot_requested) {
            v->screenshot_requested = false;
            take_screenshot(v, fw, fh);
        }
    }
    ms_core_stats cs;
    if (v->vscene)
        ms_viewer_scene_stats(v->vscene, &cs);
    else
        ms_viewer_stream_stats(v->stream, &cs);
    ms_viewer_hud_info info = {.model = shown_name(v),
                               .gl_bytes = gl_bytes(v),
                               .show_effects = v->vscene != NULL,
                               .effects_ran = v->drawn.effects_ran,
                               .mode = ms_viewer_hud_mode(&v->render, v->stream ? ms_viewer_stream_crease_angle(v->stream) : -1,
                                                          v->mode_text, sizeof v->mode_text),
                               .frame_ms = v->frame_ms,
                               .fps = v->fps,
                               .triangles_drawn = v->drawn.triangles_drawn,
                               .cells_drawn = v->drawn.cells_drawn,
                               .core = &cs,
                               .settled = v->settled,
                               .fly = v->controls.fly,
                               .playback = &v->playback,
                               .extra = v->inspect.lines,
                               .extra_count = v->vscene ? 0 : ms_viewer_inspect_hud(&v->inspect, v->stream)};
    ms_viewer_scene_piece piece;
    if (v->vscene && v->selected >= 0) {
        ms_viewer_scene_piece_info(v->vscene, (size_t)v->selected, &piece);
        info.piece = &piece;
        info.piece_index = (size_t)v->selected;
        info.piece_count = ms_viewer_scene_piece_count(v->vscene);
    }
    ms_viewer_text_begin(v->text, fw, fh, text_scale(v));
    ms_viewer_hud_draw(v->text, &info, fw, fh, v->hud);
    if (!v->vscene)
        ms_viewer_inspect_markers(&v->inspect, v->text);
    if (ms_viewer_text_draw(v->text, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        return 1;
    }
    return 0;
}

static int catalogue_frame(viewer *v, int fw, int fh)
{
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, fw, fh);
    glClearColor(0.08f, 0.08f, 0.09f, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    int s = text_scale(v);
    ms_viewer_text_begin(v->text, fw, fh, s);
    ms_viewer_catalogue_draw(v->text, &v->catalogue, fw, fh);
    if (v->message[0]) {
        static const float alert[4] = {1.0f, 0.55f, 0.45f, 1};
        ms_viewer_text_print(v->text, 12.0 * s, fh - 4.0 * MS_FONT_LINE_HEIGHT * s, alert,
                             v->message);
    }
    ms_error err;
    if (ms_viewer_text_draw(v->text, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        return 1;
    }
    return 0;
}

/* --scene in a window: the scene's models and room, the controls around the
 * middle of the room (from inside it), fly with F. */
static int interactive_scene(viewer *v)
{
    const ms_viewer_options *o = v->o;
    ms_error err;
    v->selected = -1;
    if (ms_scene_load(o->scene_file, &v->scene, &err) != MS_OK ||
        ms_viewer_playback_load(&v->playback, v->scene.camera_path, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        ms_scene_free(&v->scene);
        return 1;
    }
    int rc = 0;
    if (ms_gl_window_new(o->width, o->height, "meshview", true, &v->window, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        ms_scene_free(&v->scene);
        return 1;
    }
    ms_gl_window_keep_driver_loaded();
    ms_viewer_scene_settings settings = ms_viewer_options_scene_settings(o);
    if (ms_viewer_text_new(&v->text, &err) != MS_OK ||
        ms_viewer_scene_open(&v->source, &v->scene, o->scene_file, &settings, &v->vscene, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        rc = 1;
        goto done;
    }
    /* the controls' home: a box a sixth of the room around its middle, so
     * that the home view is inside the room */
    double lo[3], hi[3];
    ms_viewer_scene_bounds(v->vscene, lo, hi);
    for (int a = 0; a < 3; ++a) {
        double mid = 0.5 * (lo[a] + hi[a]), half = (hi[a] - lo[a]) / 12.0;
        lo[a] = mid - half, hi[a] = mid + half;
    }
    ms_viewer_controls_init(&v->controls, lo, hi, 1, (double)v->o->width / v->o->height);
    glfwSetWindowUserPointer(v->window, v);
    glfwSetKeyCallback(v->window, on_key);
    glfwSetMouseButtonCallback(v->window, on_mouse_button);
    glfwSetCursorPosCallback(v->window, on_cursor);
    glfwSetScrollCallback(v->window, on_scroll);
    v->last_frame = now_s();
    while (!glfwWindowShouldClose(v->window) && !ms_viewer_signals_pending()) {
        glfwPollEvents();
        double seconds = frame_tick(v);
        int fw, fh;
        if (!framebuffer_size(v, &fw, &fh))
            continue;
        if (view_frame(v, fw, fh, seconds)) {
            rc = 1;
            break;
        }
        glfwSwapBuffers(v->window);
    }
done:
    ms_viewer_scene_close(v->vscene);
    v->vscene = NULL;
    ms_viewer_text_free(v->text);
    ms_gl_window_free(v->window);
    ms_scene_free(&v->scene);
    return rc;
}

static int interactive(viewer *v)
{
    const ms_viewer_options *o = v->o;
    ms_error err;
    if (ms_viewer_playback_load(&v->playback, o->path_file, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        return 1;
    }
    if (o->scene_file)
        return interactive_scene(v);
    /* The catalogue's first page is listed once: a missing server, or an
     * unknown model, is an error before any window; models open from it. */
    v->have_list = ms_viewer_list_page(&v->source, NULL, &v->list, &err) == MS_OK;
    if (v->have_list && o->model &&
        ms_viewer_model_open_listed(&v->source, &v->list, o->model, &v->model, &err) != MS_OK)
        v->have_list = false;
    ms_viewer_model_close(&v->model);
    if (!v->have_list) {
        fprintf(stderr, "meshview: %s\n", err.text);
        ms_viewer_model_list_free(&v->list);
        return 1;
    }
    if (ms_gl_window_new(o->width, o->height, "meshview", true, &v->window, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        return 1;
    }
    ms_gl_window_keep_driver_loaded();
    int rc = 0;
    if (ms_viewer_text_new(&v->text, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        rc = 1;
        goto done;
    }
    glfwSetWindowUserPointer(v->window, v);
    glfwSetKeyCallback(v->window, on_key);
    glfwSetMouseButtonCallback(v->window, on_mouse_button);
    glfwSetCursorPosCallback(v->window, on_cursor);
    glfwSetScrollCallback(v->window, on_scroll);
    glfwSetCharCallback(v->window, on_char);
    v->catalogue = (ms_viewer_catalogue){.list = &v->list, .where = v->where,
                                         .archive_dir = o->archive_dir, .source = &v->source};
    v->on_catalogue = true;
    if (o->model) {
        for (size_t i = 0; v->have_list && i < v->list.count; ++i)
            if (!strcmp(v->list.entries[i].name, o->model))
                v->catalogue.selected = i;
        if (!open_model(v, o->model)) {
            fprintf(stderr, "meshview: %s\n", v->message);
            rc = 1;
            goto done;
        }
    }
    v->last_frame = now_s();
    while (!glfwWindowShouldClose(v->window) && !ms_viewer_signals_pending()) {
        glfwPollEvents();
        double seconds = frame_tick(v);
        if (v->open_requested) {
            v->open_requested = false;
            if (v->list.count)
                open_model(v, v->list.entries[v->catalogue.selected].name);
        }
        if (v->open_delta) {
            open_neighbour(v, v->open_delta);
            v->open_delta = 0;
        }
        int fw, fh;
        if (!framebuffer_size(v, &fw, &fh))
            continue;
        if ((v->on_catalogue || !v->stream) ? catalogue_frame(v, fw, fh)
                                            : view_frame(v, fw, fh, seconds)) {
            rc = 1;
            break;
        }
        glfwSwapBuffers(v->window);
    }
done:
    close_model(v);
    ms_viewer_text_free(v->text);
    ms_gl_window_free(v->window);
    ms_viewer_catalogue_free(&v->catalogue);
    ms_viewer_model_list_free(&v->list);
    return rc;
}

static int scripted(viewer *v)
{
    const ms_viewer_options *o = v->o;
    ms_error err;
    GLFWwindow *window;
    ms_process_memory before, after;
    ms_viewer_rss rss = {0};
    if (ms_process_memory_read(&before, &err) == MS_OK)
        rss.start = before.rss;
    if (ms_gl_window_new(o->width, o->height, "meshview", false, &window, &err) != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        return 1;
    }
    ms_gl_window_keep_driver_loaded();
    if (ms_process_memory_read(&after, &err) == MS_OK) /* the driver loaded, the context made */
        rss.context = after.rss;
    json_t *report = NULL;
    bool complete = false;
    ms_status st = ms_viewer_script_run(o, &v->source, window, &rss, &report, &complete, &err);
    ms_gl_window_free(window);
    if (st != MS_OK) {
        fprintf(stderr, "meshview: %s\n", err.text);
        return 1;
    }
    ms_viewer_script_print(report, o->json);
    json_decref(report);
    if (!complete) {
        fprintf(stderr, "meshview: the view did not complete at every keyframe within %.1f s\n",
                o->keyframe_timeout);
        return 1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshview");
    ms_viewer_signals_block(); /* before the core's threads exist */
    ms_viewer_options o;
    int rc = ms_viewer_options_parse(argc, argv, &o, stderr);
    if (rc)
        return rc;
    if (o.help) {
        ms_viewer_options_usage(stdout);
        return 0;
    }
    viewer v = {.o = &o, .hud = true, .apo = o.apo_shading};
    v.source = (ms_viewer_source){.archive_dir = o.archive_dir,
                                  .host = o.host,
                                  .port = o.port,
                                  .token = o.token,
                                  .timeout_s = 5};
    if (o.archive_dir)
        snprintf(v.where, sizeof v.where, "%.120s", o.archive_dir);
    else
        snprintf(v.where, sizeof v.where, "server %s:%u", o.host, o.port);
    ms_render_options_default(&v.render);
    v.render.smooth = !o.flat;
    v.render.apo_filter = o.apo_filter;
    v.render.apo_footprint = o.apo_footprint;
    v.render.shading = o.shading;
    update_shading(&v);
    ms_viewer_inspect_init(&v.inspect, &o, &v.source);
    rc = o.scripted ? scripted(&v) : interactive(&v);
    ms_viewer_playback_free(&v.playback);
    return rc;
}
