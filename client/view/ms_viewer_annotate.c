/* Annotations in meshview: see ms_viewer_annotate.h. */
#include "ms_viewer_annotate.h"

#include <errno.h>
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "ms_metadata.h"
#include "ms_render.h"
#include "ms_viewer_font.h"
#include "ms_viewer_measure.h"
#include "ms_viewer_readback.h"

void ms_viewer_annotate_init(ms_viewer_annotate *a, const char *file, const char *select_id)
{
    memset(a, 0, sizeof *a);
    a->file = file;
    a->select_id = select_id;
    a->selected = -1;
    snprintf(a->from, sizeof a->from, "none");
}

void ms_viewer_annotate_free(ms_viewer_annotate *a)
{
    ms_viewer_fetcher_free(a->fetcher); /* interrupts a fetch in flight */
    a->fetcher = NULL;
    ms_annotations_free(a->set);
    a->set = NULL;
}

/* Keeps set in *out when every view it stores reads as a view text; else
 * frees it with one line naming where and the annotation. */
static ms_status check_views(ms_annotations *set, const char *where, ms_annotations **out, ms_error *err)
{
    ms_status st;
    for (size_t i = 0; i < ms_annotations_count(set); ++i) {
        const ms_annotation *n = ms_annotations_get(set, i);
        ms_viewer_share share;
        ms_error why;
        if (n->view && ms_viewer_share_parse(n->view, &share, &why) != MS_OK) {
            st = ms_error_set(err, MS_ERR_FORMAT, "%.300s: annotation %zu (%s): view: %.150s", where, i + 1, n->id,
                              why.text);
            ms_annotations_free(set);
            return st;
        }
    }
    *out = set;
    return MS_OK;
}

ms_status ms_viewer_annotate_read(const char *path, ms_annotations **out, ms_error *err)
{
    ms_annotations *set;
    ms_status st = ms_annotations_load(path, &set, err);
    return st != MS_OK ? st : check_views(set, path, out, err);
}

/* The server's annotations document as the fetcher brought it: MS_OK with
 * *out NULL when the server has none. */
static ms_status parse_fetched(ms_viewer_fetched *r, ms_annotations **out, ms_error *err)
{
    *out = NULL;
    if (r->status != MS_OK)
        return ms_error_set(err, r->status, "%s", r->why);
    if (!r->document)
        return MS_OK;
    char where[200];
    snprintf(where, sizeof where, "the server's annotations of %s", r->entry.name);
    ms_annotations *set;
    ms_status st = ms_annotations_parse((const char *)r->document, r->document_size, where, &set, err);
    return st != MS_OK ? st : check_views(set, where, out, err);
}

/* The end of a load: the set read (a->set, NULL: none) or the failure st. */
static void finish_load(ms_viewer_annotate *a, ms_status st, const char *from, const ms_error *err,
                        FILE *log)
{
    if (st != MS_OK) {
        snprintf(a->message, sizeof a->message, "%.*s", (int)sizeof a->message - 1, err->text);
        /* a server that cannot be reached is the stream's error to tell, once
         * (a failure ends with one line); a refused file or document is ours */
        bool unreachable = !strcmp(from, "server") && st == MS_ERR_IO;
        if (log && !unreachable)
            fprintf(log, "meshview: %s\n", err->text);
        return;
    }
    if (a->set)
        snprintf(a->from, sizeof a->from, "%s", from);
    if (!a->set && !(a->set = ms_annotations_new()))
        return;
    long i = ms_annotations_find(a->set, a->select_id);
    if (i >= 0)
        ms_viewer_annotate_select(a, i);
    else if (a->select_id) {
        snprintf(a->message, sizeof a->message, "--annotation: no annotation '%.40s' among %zu",
                 a->select_id, ms_annotations_count(a->set));
        if (log)
            fprintf(log, "meshview: %s\n", a->message);
    }
}

/* The server's answer, once it came. */
static void take_fetched(ms_viewer_annotate *a, FILE *log)
{
    ms_viewer_fetched r;
    while (a->fetcher && ms_viewer_fetcher_take(a->fetcher, &r)) {
        bool ours = r.kind == MS_FETCHED_ANNOTATIONS && !strcmp(r.entry.name, a->model);
        if (ours) {
            ms_error err;
            ms_status st = parse_fetched(&r, &a->set, &err);
            ms_viewer_fetcher_free(a->fetcher);
            a->fetcher = NULL;
            finish_load(a, st, "server", &err, log);
        }
        ms_viewer_fetched_free(&r);
    }
}

bool ms_viewer_annotate_pending(const ms_viewer_annotate *a) { return a->fetcher != NULL; }

void ms_viewer_annotate_load(ms_viewer_annotate *a, const ms_viewer_source *source, const char *model, FILE *log)
{
    if (!strcmp(a->model, model)) {
        take_fetched(a, log);
        return;
    }
    ms_viewer_annotate_free(a);
    snprintf(a->model, sizeof a->model, "%s", model);
    a->selected = -1;
    a->marked = 0;
    a->message[0] = 0;
    snprintf(a->from, sizeof a->from, "none");
    const char *path = a->file;
    char sidecar[4200];
    if (!path && source->archive_dir) {
        ms_annotations_sidecar_path(source->archive_dir, model, sidecar, sizeof sidecar);
        struct stat sb;
        if (stat(sidecar, &sb) == 0 || errno != ENOENT)
            path = sidecar;
    }
    if (a->file)
        snprintf(a->save_path, sizeof a->save_path, "%s", a->file);
    else if (source->archive_dir)
        ms_annotations_sidecar_path(source->archive_dir, model, a->save_path, sizeof a->save_path);
    else
        snprintf(a->save_path, sizeof a->save_path, "%s.annotations.json", model);
    ms_error err;
    if (!path && !source->archive_dir) {
        ms_status st = ms_viewer_fetcher_new(source, &a->fetcher, &err);
        if (st == MS_OK)
            ms_viewer_fetcher_want_annotations(a->fetcher, model);
        else
            finish_load(a, st, "server", &err, log);
        return;
    }
    ms_status st = path ? ms_viewer_annotate_read(path, &a->set, &err) : MS_OK;
    finish_load(a, st, a->file ? "file" : "archive", &err, log);
}

void ms_viewer_annotate_select(ms_viewer_annotate *a, long i)
{
    a->selected = i >= 0 && (size_t)i < ms_annotations_count(a->set) ? i : -1;
    a->go = a->selected >= 0;
}

/* ---- editing ------------------------------------------------------------ */

static void save(ms_viewer_annotate *a, FILE *log)
{
    ms_error err;
    if (!a->set || ms_annotations_save(a->set, a->save_path, &err) != MS_OK)
        snprintf(a->message, sizeof a->message, "%.*s", (int)sizeof a->message - 1,
                 a->set ? err.text : "no annotations to save");
    else
        snprintf(a->message, sizeof a->message, "saved %zu to %.60s", ms_annotations_count(a->set), a->save_path);
    if (log)
        fprintf(log, "meshview: %s\n", a->message);
}

static void commit(ms_viewer_annotate *a)
{
    char id[MS_ANNOTATION_ID_MAX + 1];
    ms_annotations_next_id(a->set, id, sizeof id);
    ms_annotation n = {.id = id, .point = {a->add_point[0], a->add_point[1], a->add_point[2]},
                       .title = a->title, .text = a->text, .view = a->add_view[0] ? a->add_view : NULL};
    ms_error err;
    if (ms_annotations_add(a->set, &n, &err) != MS_OK)
        snprintf(a->message, sizeof a->message, "%.*s", (int)sizeof a->message - 1, err.text);
    else {
        a->selected = (long)ms_annotations_count(a->set) - 1;
        snprintf(a->message, sizeof a->message, "added %s (Ctrl+S saves)", id);
    }
}

/* Removes the last UTF-8 character of s. */
static void backspace(char *s)
{
    size_t n = strlen(s);
    while (n > 0 && ((unsigned char)s[n - 1] & 0xC0) == 0x80)
        --n;
    s[n > 0 ? n - 1 : 0] = '\0';
}

static bool typing_key(ms_viewer_annotate *a, int key)
{
    char *field = a->typing == MS_ANNOTATE_TYPING_TITLE ? a->title : a->text;
    switch (key) {
    case GLFW_KEY_ESCAPE: a->typing = MS_ANNOTATE_NOT_TYPING; a->message[0] = 0; break;
    case GLFW_KEY_BACKSPACE: backspace(field); break;
    case GLFW_KEY_ENTER:
    case GLFW_KEY_KP_ENTER:
        if (a->typing == MS_ANNOTATE_TYPING_TITLE)
            a->typing = a->title[0] ? MS_ANNOTATE_TYPING_TEXT : MS_ANNOTATE_NOT_TYPING;
        else {
            a->typing = MS_ANNOTATE_NOT_TYPING;
            commit(a);
        }
        break;
    default: break;
    }
    return true;
}

bool ms_viewer_annotate_key(ms_viewer_annotate *a, int key, int mods, const ms_viewer_controls *c,
                            const ms_viewer_light *light, FILE *log)
{
    if (a->typing)
        return typing_key(a, key);
    if (!a->set)
        return false;
    if ((key == GLFW_KEY_ENTER || key == GLFW_KEY_KP_ENTER) && !mods) {
        ms_viewer_share share;
        ms_viewer_share_take(c, light, NULL, &share);
        memset(&share.sections, 0, sizeof share.sections);
        ms_viewer_share_print(&share, a->add_view, sizeof a->add_view);
        a->add_requested = true;
        return true;
    }
    if (key == GLFW_KEY_DELETE && (mods & GLFW_MOD_SHIFT)) {
        if (a->selected >= 0 && ms_annotations_remove(a->set, (size_t)a->selected)) {
            snprintf(a->message, sizeof a->message, "deleted (Ctrl+S saves)");
            a->selected = -1;
            a->marked = 0;
        }
        return true;
    }
    if (key == GLFW_KEY_S && (mods & GLFW_MOD_CONTROL)) {
        save(a, log);
        return true;
    }
    return false;
}

void ms_viewer_annotate_char(ms_viewer_annotate *a, unsigned cp)
{
    if (!a->typing)
        return;
    char *field = a->typing == MS_ANNOTATE_TYPING_TITLE ? a->title : a->text;
    size_t limit = a->typing == MS_ANNOTATE_TYPING_TITLE ? MS_ANNOTATION_TITLE_MAX : MS_ANNOTATION_TEXT_MAX;
    char u[5] = {0};
    if (cp < 0x80)
        u[0] = (char)cp;
    else if (cp < 0x800)
        u[0] = (char)(0xC0 | cp >> 6), u[1] = (char)(0x80 | (cp & 0x3F));
    else if (cp < 0x10000)
        u[0] = (char)(0xE0 | cp >> 12), u[1] = (char)(0x80 | ((cp >> 6) & 0x3F)), u[2] = (char)(0x80 | (cp & 0x3F));
    else if (cp <= 0x10FFFF)
        u[0] = (char)(0xF0 | cp >> 18), u[1] = (char)(0x80 | ((cp >> 12) & 0x3F)),
        u[2] = (char)(0x80 | ((cp >> 6) & 0x3F)), u[3] = (char)(0x80 | (cp & 0x3F));
    const char *why;
    size_t n = strlen(u), used = strlen(field);
    if (n && used + n <= limit && ms_metadata_text_ok(u, n, false, &why))
        memcpy(field + used, u, n + 1);
}

/* ---- per frame ---------------------------------------------------------- */

void ms_viewer_annotate_frame(ms_viewer_annotate *a, const ms_core_frame *frame, double box_side,
                              const ms_camera *camera)
{
    if (a->add_requested && frame) {
        a->add_requested = false;
        double origin[3], direction[3];
        ms_viewer_measure_hit hit;
        ms_viewer_measure_pixel_ray(camera, a->cursor_x, a->cursor_y, origin, direction);
        if (!ms_viewer_measure_cast(frame, box_side, origin, direction, 0, 0, &hit)) {
            snprintf(a->message, sizeof a->message, "no surface under the cursor to annotate");
        } else {
            memcpy(a->add_point, hit.point, sizeof a->add_point);
            a->title[0] = a->text[0] = 0;
            a->message[0] = 0;
            a->typing = MS_ANNOTATE_TYPING_TITLE;
        }
    }
    if (a->click_requested) {
        a->click_requested = false;
        double best = HUGE_VAL, reach = MS_VIEWER_ANNOTATE_MARKER_PX * 2.0;
        long found = -1;
        for (size_t i = 0; i < a->marked; ++i) {
            double dx = fabs(a->pixel[i][0] - a->click_x), dy = fabs(a->pixel[i][1] - a->click_y);
            if (a->seen[i] && dx <= reach && dy <= reach && dx + dy < best)
                best = dx + dy, found = (long)i;
        }
        ms_viewer_annotate_select(a, found);
    }
}

static double smoothstep(double t)
{
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return t * t * (3 - 2 * t);
}

void ms_viewer_annotate_animate(ms_viewer_annotate *a, ms_viewer_controls *c, ms_viewer_light *light,
                                double seconds)
{
    if (a->moving && memcmp(&a->handed, c, sizeof *c) != 0)
        a->moving = false; /* something else moved the camera */
    if (a->go) {
        a->go = false;
        const ms_annotation *n = ms_annotations_get(a->set, (size_t)a->selected);
        ms_error err;
        a->move_has_view = n && n->view && ms_viewer_share_parse(n->view, &a->move_to, &err) == MS_OK;
        if (n && !a->move_has_view) { /* no view: the orbit centre goes to the point */
            ms_viewer_share_take(c, NULL, NULL, &a->move_to);
            memcpy(a->move_to.target, n->point, sizeof a->move_to.target);
        }
        a->moving = n != NULL;
        a->move_t = 0;
        a->move_from = *c;
        c->fly = false;
        if (a->moving && a->move_to.up_axis != c->up_axis) /* no path between two up axes: there at once */
            a->move_t = MS_VIEWER_ANNOTATE_MOVE_S;
    }
    if (!a->moving)
        return;
    a->move_t += seconds;
    double f = smoothstep(a->move_t / MS_VIEWER_ANNOTATE_MOVE_S);
    if (f >= 1) {
        ms_viewer_share_give(&a->move_to, c, a->move_has_view ? light : NULL, NULL);
        a->moving = false;
        return;
    }
    const ms_viewer_controls *s = &a->move_from;
    const ms_viewer_share *e = &a->move_to;
    for (int k = 0; k < 3; ++k)
        c->target[k] = s->target[k] + f * (e->target[k] - s->target[k]);
    c->distance = s->distance * pow(e->distance / s->distance, f);
    double turn = remainder(e->yaw - s->yaw, 2 * M_PI); /* the shorter way round */
    c->yaw = s->yaw + f * turn;
    c->pitch = s->pitch + f * (e->pitch - s->pitch);
    c->fovy_degrees = s->fovy_degrees + f * (e->fovy_degrees - s->fovy_degrees);
    a->handed = *c;
}

/* ---- drawing ------------------------------------------------------------ */

/* True when the surface drawn at pixel (x, y) of the bound read framebuffer
 * lies in front of p by more than the allowance. */
static bool occluded(const ms_camera *c, const double p[3], double x, double y, double radius)
{
    int w = (int)c->width, h = (int)c->height;
    int px = (int)x, py = h - 1 - (int)y;
    double depth, s[3];
    if (!ms_viewer_read_depth(px, py, w, h, &depth) || depth >= 1.0 ||
        !ms_render_unproject(c, px + 0.5, py + 0.5, depth, s))
        return false; /* the background, or outside the picture */
    double ds = 0, dp = 0;
    for (int k = 0; k < 3; ++k)
        ds += (s[k] - c->position[k]) * (s[k] - c->position[k]), dp += (p[k] - c->position[k]) * (p[k] - c->position[k]);
    ds = sqrt(ds), dp = sqrt(dp);
    return ds < dp - fmax(radius, 0.01 * dp);
}

/* Up to max_lines lines of at most width characters of s (line feeds break
 * lines too) into lines; returns how many. */
static size_t wrap(const char *s, size_t width, char lines[][MS_HUD_LINE_MAX], size_t max_lines)
{
    size_t n = 0;
    while (*s && n < max_lines) {
        size_t len = strcspn(s, "\n"), take = len;
        if (len > width) { /* break at the last space that fits, else anywhere */
            size_t sp = width;
            while (sp > 0 && s[sp] != ' ')
                --sp;
            take = sp > 0 ? sp : width;
        }
        snprintf(lines[n++], MS_HUD_LINE_MAX, "%.*s", (int)take, s);
        s += take;
        if (take == len)
            s += *s == '\n';
        else
            while (*s == ' ')
                ++s;
    }
    return n;
}

static void draw_panel(const ms_viewer_annotate *a, ms_viewer_text *text, int height)
{
    static const float panel[4] = {0, 0, 0, 0.6f}, head[4] = {1.0f, 0.6f, 0.15f, 1}, body[4] = {1, 1, 1, 1};
    char lines[12][MS_HUD_LINE_MAX];
    size_t n = 0;
    const ms_annotation *sel = ms_annotations_get(a->set, (size_t)a->selected);
    if (a->typing) {
        snprintf(lines[n++], MS_HUD_LINE_MAX, "new annotation %s (Enter: %s, Esc: cancel):",
                 a->typing == MS_ANNOTATE_TYPING_TITLE ? "title" : "text",
                 a->typing == MS_ANNOTATE_TYPING_TITLE ? "then its text" : "done");
        const char *field = a->typing == MS_ANNOTATE_TYPING_TITLE ? a->title : a->text;
        size_t len = strlen(field); /* the end of what is typed, and a cursor */
        snprintf(lines[n++], MS_HUD_LINE_MAX, "%s_", field + (len > 80 ? len - 80 : 0));
    } else if (sel) {
        snprintf(lines[n++], MS_HUD_LINE_MAX, "[%.20s] %.70s", sel->id, sel->title);
        n += wrap(sel->text, 80, lines + n, 8);
    }
    if (a->message[0])
        snprintf(lines[n++], MS_HUD_LINE_MAX, "%s", a->message);
    if (!n)
        return;
    int s = ms_viewer_text_scale(text);
    double lh = MS_FONT_LINE_HEIGHT * s, top = height - (n + 1) * lh;
    ms_viewer_text_rect(text, 0, top - 0.5 * lh, (82.0 * MS_FONT_ADVANCE_X + 16) * s, (n + 1) * lh, panel);
    for (size_t i = 0; i < n; ++i)
        ms_viewer_text_print(text, 8.0 * s, top + i * lh, i == 0 ? head : body, lines[i]);
}

void ms_viewer_annotate_markers(ms_viewer_annotate *a, const ms_camera *camera, ms_viewer_text *text)
{
    static const float ring[4] = {0.05f, 0.05f, 0.05f, 1}, fill[4] = {0.2f, 0.85f, 1.0f, 1},
                       chosen[4] = {1.0f, 0.6f, 0.15f, 1};
    size_t count = ms_annotations_count(a->set);
    for (size_t i = 0; i < count; ++i) {
        const ms_annotation *n = ms_annotations_get(a->set, i);
        double x = -1, y = -1;
        bool front = ms_viewer_measure_project(camera, n->point, &x, &y);
        a->seen[i] = front && x >= 0 && y >= 0 && x < camera->width && y < camera->height &&
                     !occluded(camera, n->point, x, y, n->radius);
        a->pixel[i][0] = front ? x : -1, a->pixel[i][1] = front ? y : -1; /* -1, -1: behind the eye */
        if (!a->seen[i])
            continue;
        if (!text)
            continue;
        double h = MS_VIEWER_ANNOTATE_MARKER_PX * ms_viewer_text_scale(text), b = ms_viewer_text_scale(text);
        ms_viewer_text_rect(text, x - h - b, y - h - b, 2 * (h + b), 2 * (h + b), ring);
        ms_viewer_text_rect(text, x - h, y - h, 2 * h, 2 * h, (long)i == a->selected ? chosen : fill);
    }
    a->marked = count;
    if (text)
        draw_panel(a, text, (int)camera->height);
}

void ms_viewer_annotate_report(const ms_viewer_annotate *a, json_t *report)
{
    if (!report)
        return;
    json_t *markers = json_array();
    for (size_t i = 0; i < a->marked && i < ms_annotations_count(a->set); ++i) {
        const ms_annotation *n = ms_annotations_get(a->set, i);
        json_array_append_new(markers, json_pack("{s:s, s:[f, f], s:b}", "id", n->id, "pixel", a->pixel[i][0],
                                                 a->pixel[i][1], "seen", a->seen[i]));
    }
    const ms_annotation *sel = ms_annotations_get(a->set, (size_t)a->selected);
    json_object_set_new(report, "annotations",
                        json_pack("{s:s, s:I, s:s, s:o, s:o}", "from", a->from, "count",
                                  (json_int_t)ms_annotations_count(a->set), "message", a->message, "selected",
                                  sel ? json_string(sel->id) : json_null(), "markers", markers));
}
