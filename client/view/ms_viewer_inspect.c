/* Looking closely in meshview: see ms_viewer_inspect.h. */
#include "ms_viewer_inspect.h"

#include <GLFW/glfw3.h>
#include <math.h>
#include <string.h>
#include <time.h>

#include "ms_progress.h"

#include "ms_viewer_share.h"

static double box_side(const ms_viewer_stream *stream)
{
    return ms_viewer_stream_model(stream)->header.box_side;
}

void ms_viewer_inspect_init(ms_viewer_inspect *in, const ms_viewer_options *o, const ms_viewer_source *source)
{
    memset(in, 0, sizeof *in);
    in->source = source;
    in->light = o->light;
    in->sections = o->sections; /* --section, else --view's */
    if (o->has_view)
        ms_viewer_share_give(&o->view, NULL, NULL, &in->measure);
    ms_viewer_annotate_init(&in->notes, o->annotations_file, o->annotation_id);
}

void ms_viewer_inspect_close(ms_viewer_inspect *in)
{
    ms_viewer_probe_stop(in->probe);
    in->probe = NULL;
    in->probe_failed = in->refining = false;
    in->generation = 0;
    in->sections_known = false; /* the next stream's core is told again */
    ms_viewer_annotate_free(&in->notes);
    ms_viewer_annotate_init(&in->notes, in->notes.file, in->notes.select_id);
    ms_viewer_unit_free(&in->unit);
}

/* Polls the probe once the view is settled, starting it when a point wants
 * refining. */
static void refine(ms_viewer_inspect *in, ms_viewer_stream *stream)
{
    bool wanted = false;
    for (size_t i = 0; i < in->measure.count; ++i)
        wanted |= in->measure.found[i] && !in->measure.refined[i];
    if (!in->probe && (!wanted || in->probe_failed || !in->source))
        return;
    ms_error err;
    if (!in->probe && ms_viewer_probe_start(in->source, ms_viewer_stream_model(stream), &in->probe, &err) != MS_OK) {
        in->probe_failed = true;
        return;
    }
    in->refining = ms_viewer_probe_step(in->probe, &in->measure);
}

void ms_viewer_inspect_view(const ms_viewer_options *o, ms_viewer_controls *c)
{
    if (o->has_view)
        ms_viewer_share_give(&o->view, c, NULL, NULL);
}

bool ms_viewer_inspect_key(ms_viewer_inspect *in, int key, const ms_viewer_controls *c, FILE *out)
{
    if (in->have_camera && ms_viewer_sections_key(&in->sections, key, in->camera.forward, c->target, in->box_side))
        return true;
    switch (key) {
    case GLFW_KEY_T: in->measuring = !in->measuring; return true;
    case GLFW_KEY_BACKSPACE: ms_viewer_measure_pop(&in->measure); return true;
    case GLFW_KEY_DELETE: ms_viewer_measure_clear(&in->measure); return true;
    case GLFW_KEY_L: ms_viewer_light_next_preset(&in->light); return true;
    case GLFW_KEY_V: {
        ms_viewer_share share;
        char text[MS_VIEWER_SHARE_MAX];
        ms_viewer_share_take(c, &in->light, &in->measure, &share);
        share.sections = in->sections;
        ms_viewer_share_print(&share, text, sizeof text);
        fprintf(out, "%s\n", text);
        fflush(out);
        return true;
    }
    default: return false;
    }
}

/* What the sections cut away is not measured (it is not drawn): new planes
 * cast the chain again. */
static void measure_planes(ms_viewer_inspect *in)
{
    double planes[MS_SECTIONS_MAX][4];
    size_t n = ms_viewer_sections_planes(&in->sections, planes);
    if (ms_viewer_measure_set_planes(&in->measure, (const double(*)[4])planes, n))
        in->generation = 0;
}

void ms_viewer_inspect_frame(ms_viewer_inspect *in, ms_viewer_stream *stream, const ms_camera *camera,
                             ms_render_options *render)
{
    ms_viewer_light_apply(&in->light, camera, render);
    ms_viewer_sections_apply(&in->sections, render);
    in->box_side = box_side(stream);
    if (!in->sections_known || memcmp(&in->sections_sent, &in->sections, sizeof in->sections) != 0) {
        double planes[MS_SECTIONS_MAX][4];
        size_t n = ms_viewer_sections_planes(&in->sections, planes);
        ms_error err;
        if (ms_viewer_stream_set_sections(stream, (const double(*)[4])planes, n, &err) == MS_OK) {
            in->sections_sent = in->sections;
            in->sections_known = true;
        }
    }
    in->camera = *camera;
    in->have_camera = true;
    const ms_core_frame *frame = ms_viewer_stream_frame(stream);
    if (in->source)
        ms_viewer_annotate_load(&in->notes, in->source, ms_viewer_stream_model(stream)->name, stderr);
    if (in->measuring || in->measure.count) /* asked for only by a model measured */
        ms_viewer_unit_update(&in->unit, in->source, ms_viewer_stream_model(stream), stderr);
    ms_viewer_annotate_frame(&in->notes, frame, box_side(stream), camera);
    if (!frame)
        return;
    measure_planes(in);
    /* the chain follows the cut once the view settles there (a cast reads every
     * triangle drawn: not at every frame of a refinement), or while a point is
     * not found */
    bool lost = false;
    for (size_t i = 0; i < in->measure.count; ++i)
        lost |= !in->measure.found[i];
    if (frame->generation != in->generation && (lost || ms_viewer_stream_settled(stream))) {
        ms_viewer_measure_update(&in->measure, frame, box_side(stream));
        in->generation = frame->generation;
    }
    if (in->add_requested) {
        double origin[3], direction[3];
        ms_viewer_measure_pixel_ray(camera, in->add_x, in->add_y, origin, direction);
        ms_viewer_measure_add(&in->measure, frame, box_side(stream), origin, direction);
        in->add_requested = false;
    }
    if (ms_viewer_stream_settled(stream) || in->refining)
        refine(in, stream);
}

void ms_viewer_inspect_describe(const ms_viewer_measure *m, unsigned model_bits, const char *unit, char *text,
                                size_t size)
{
    ms_viewer_measure_result r;
    if (!ms_viewer_measure_result_of(m, model_bits, &r)) {
        snprintf(text, size, "measure %zu point%s%s", m->count, m->count == 1 ? "" : "s",
                 m->count >= 2 ? ": not on the surface drawn" : "");
        return;
    }
    /* as many decimals as the precision has: its first significant digit and one more */
    int decimals = r.precision > 0 ? 1 - (int)floor(log10(r.precision)) : 6;
    decimals = decimals < 0 ? 0 : decimals > 12 ? 12 : decimals;
    snprintf(text, size, "measure %zu points: %.*f +- %.*f %s (%u bits%s)", r.points, decimals, r.length,
             decimals, r.precision, unit ? unit : MS_METADATA_NO_UNIT, r.bits_min, r.full ? ", full" : "");
}

size_t ms_viewer_inspect_hud(ms_viewer_inspect *in, const ms_viewer_stream *stream)
{
    size_t n = 0;
    if (in->light.directional)
        ms_viewer_light_describe(&in->light, in->lines[n++], MS_HUD_LINE_MAX);
    if (in->sections.count)
        ms_viewer_sections_describe(&in->sections, in->lines[n++], MS_HUD_LINE_MAX);
    if (in->measuring || in->measure.count) {
        ms_viewer_inspect_describe(&in->measure, ms_viewer_stream_model(stream)->header.bits,
                                   ms_viewer_unit_name(&in->unit), in->lines[n], MS_HUD_LINE_MAX);
        size_t used = strlen(in->lines[n]);
        snprintf(in->lines[n] + used, MS_HUD_LINE_MAX - used, "%s%s", in->refining ? "  refining" : "",
                 in->measuring ? "  [T]" : "");
        n++;
    }
    size_t notes = ms_annotations_count(in->notes.set);
    if (notes || in->notes.typing)
        snprintf(in->lines[n++], MS_HUD_LINE_MAX, "annotations %zu (%s)  Enter adds",
                 notes, in->notes.from);
    return n;
}

void ms_viewer_inspect_markers(ms_viewer_inspect *in, ms_viewer_text *text)
{
    static const float ink[4] = {1.0f, 0.85f, 0.2f, 1};
    const ms_camera *c = &in->camera;
    if (!in->have_camera)
        return;
    ms_viewer_annotate_markers(&in->notes, c, text);
    double s = 3.0 * ms_viewer_text_scale(text), px = 0, py = 0;
    bool have_previous = false;
    for (size_t i = 0; i < in->measure.count; ++i) {
        const double *p = in->measure.found[i] ? in->measure.hit[i].point : in->measure.anchor[i];
        double x, y;
        if (!ms_viewer_measure_project(c, p, &x, &y)) {
            have_previous = false;
            continue;
        }
        ms_viewer_text_rect(text, x - s, y - s, 2 * s, 2 * s, ink);
        /* the segment from the previous point: a dotted line, a dot every 2 s pixels */
        double len = hypot(x - px, y - py);
        for (int k = 1; have_previous && len < 1e5 && k < (int)(len / (2 * s)); ++k) {
            double f = k * 2 * s / len;
            ms_viewer_text_rect(text, px + f * (x - px) - s / 3, py + f * (y - py) - s / 3, 2 * s / 3, 2 * s / 3,
                                ink);
        }
        px = x, py = y, have_previous = true;
    }
}

void ms_viewer_inspect_report_light(const ms_viewer_options *o, json_t *report)
{
    if (!report)
        return;
    json_object_set_new(report, "light",
                        o->light.directional ? json_pack("{s:f, s:f}", "azimuth_deg", o->light.azimuth_deg,
                                                         "elevation_deg", o->light.elevation_deg)
                                             : json_pack("{s:b}", "head", true));
    json_t *sections = json_array();
    for (size_t k = 0; k < o->sections.count; ++k) {
        const double *p = o->sections.point[k], *m = o->sections.normal[k];
        json_array_append_new(sections, json_pack("{s:[f, f, f], s:[f, f, f]}", "point", p[0], p[1], p[2], "normal",
                                                  m[0], m[1], m[2]));
    }
    json_object_set_new(report, "sections", sections);
    if (o->has_view) {
        char view[MS_VIEWER_SHARE_MAX];
        ms_viewer_share_print(&o->view, view, sizeof view);
        json_object_set_new(report, "view", json_string(view));
    }
}

void ms_viewer_inspect_report_annotations(ms_viewer_inspect *in, json_t *report)
{
    if (in->have_camera)
        ms_viewer_annotate_markers(&in->notes, &in->camera, NULL);
    ms_viewer_annotate_report(&in->notes, report);
}

static json_t *point_json(const ms_viewer_measure *m, size_t i, const double *pixel)
{
    const ms_viewer_measure_hit *h = &m->hit[i];
    json_t *p = json_pack("{s:b}", "hit", m->found[i]);
    if (pixel)
        json_object_set_new(p, "pixel", json_pack("[f, f]", pixel[0], pixel[1]));
    if (m->found[i]) {
        json_object_set_new(p, "point", json_pack("[f, f, f]", h->point[0], h->point[1], h->point[2]));
        json_object_set_new(p, "cell", json_integer(h->cell));
        json_object_set_new(p, "bits", json_integer(h->bits));
        json_object_set_new(p, "step", json_real(h->step));
    }
    return p;
}

bool ms_viewer_inspect_report_measure(const ms_viewer_options *o, ms_viewer_inspect *look, ms_viewer_stream *stream,
                                      const ms_camera *camera, json_t *report)
{
    if (!report || (!o->measure_count && !look->measure.count))
        return false;
    const ms_core_frame *frame = ms_viewer_stream_frame(stream);
    const ms_viewer_model *model = ms_viewer_stream_model(stream);
    measure_planes(look);
    ms_viewer_measure_update(&look->measure, frame, model->header.box_side);
    size_t shared = look->measure.count;
    json_t *points = json_array();
    for (size_t i = 0; i < shared; ++i)
        json_array_append_new(points, point_json(&look->measure, i, NULL));
    for (size_t k = 0; k < o->measure_count; ++k) {
        double origin[3], direction[3];
        ms_viewer_measure_pixel_ray(camera, o->measure_px[k][0], o->measure_px[k][1], origin, direction);
        if (!ms_viewer_measure_add(&look->measure, frame, model->header.box_side, origin, direction)) {
            /* no surface there: kept in the chain as a point not found */
            double nowhere[3] = {origin[0], origin[1], origin[2]};
            ms_viewer_measure_add_anchor(&look->measure, nowhere, direction);
        }
        json_array_append_new(points, point_json(&look->measure, look->measure.count - 1, o->measure_px[k]));
    }
    ms_viewer_measure_result view, r;
    bool view_ok = ms_viewer_measure_result_of(&look->measure, model->header.bits, &view);
    /* the probe: the cells under the points to full precision (a bounded wait) */
    for (double start = ms_now_seconds(); ms_now_seconds() - start < MS_VIEWER_PROBE_TIMEOUT_S * 16;) {
        refine(look, stream);
        if (!look->refining)
            break;
        struct timespec nap = {0, 5000000};
        nanosleep(&nap, NULL);
    }
    for (size_t i = 0; i < json_array_size(points); ++i) /* the points as refined */
        if (look->measure.found[i]) {
            json_t *p = json_array_get(points, i);
            const ms_viewer_measure_hit *h = &look->measure.hit[i];
            json_object_set_new(p, "point", json_pack("[f, f, f]", h->point[0], h->point[1], h->point[2]));
            json_object_set_new(p, "cell", json_integer(h->cell));
            json_object_set_new(p, "bits", json_integer(h->bits));
            json_object_set_new(p, "step", json_real(h->step));
        }
    bool ok = ms_viewer_measure_result_of(&look->measure, model->header.bits, &r);
    double unit_wait = look->source && look->source->timeout_s > 0 ? look->source->timeout_s : 5;
    ms_viewer_unit_wait(&look->unit, look->source, model, unit_wait, stderr);
    const char *unit = ms_viewer_unit_name(&look->unit);
    char text[MS_HUD_LINE_MAX];
    ms_viewer_inspect_describe(&look->measure, model->header.bits, unit, text, sizeof text);
    json_object_set_new(report, "measure",
                        json_pack("{s:o, s:o, s:o, s:o, s:I, s:b, s:s, s:s, s:b}", "points", points, "length",
                                  ok ? json_real(r.length) : json_null(), "precision",
                                  ok ? json_real(r.precision) : json_null(), "last_length",
                                  ok ? json_real(r.last_length) : json_null(), "bits_min",
                                  (json_int_t)(ok ? r.bits_min : 0), "full_precision", ok && r.full, "unit",
                                  unit, "text", text, "refined_to_full", ok && r.refined && r.full));
    json_t *jm = json_object_get(report, "measure");
    json_object_set_new(jm, "refined", json_boolean(ok && r.refined));
    json_object_set_new(jm, "view_length", view_ok ? json_real(view.length) : json_null());
    json_object_set_new(jm, "view_precision", view_ok ? json_real(view.precision) : json_null());
    json_object_set_new(jm, "view_bits_min", json_integer((json_int_t)(view_ok ? view.bits_min : 0)));
    look->generation = frame ? frame->generation : 0;
    return true;
}
