/* Refining the cells under measuring points: see ms_viewer_probe.h. */
#include "ms_viewer_probe.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_client_core.h"
#include "ms_progress.h"
#include "ms_viewer_stream.h"

#define PROBE_FOVY_DEG 0.01
#define PROBE_PIXELS 1000.0
#define PROBE_BACK 1e-3 /* of the box side: where the eye stands in front of the point */

struct ms_viewer_probe {
    ms_core *core;
    double box_side;
    uint64_t id;            /* the point being refined (ms_viewer_measure.id); 0: none */
    double started;         /* when its camera was set */
    double anchor[3], direction[3];
    ms_core_frame *frame;   /* the newest taken */
};

ms_status ms_viewer_probe_camera(const double anchor[3], const double direction[3], double box_side,
                                 ms_camera *camera, ms_error *err)
{
    double len = sqrt(direction[0] * direction[0] + direction[1] * direction[1] + direction[2] * direction[2]);
    if (!(len > 0) || !isfinite(len) || !(box_side > 0))
        return ms_error_set(err, MS_ERR_ARG, "probe: no direction");
    double d[3], eye[3], up[3] = {0, 0, 0}, back = PROBE_BACK * box_side;
    int least = 0;
    for (int a = 0; a < 3; ++a) {
        d[a] = direction[a] / len;
        eye[a] = anchor[a] - back * d[a];
        if (fabs(d[a]) < fabs(d[least]))
            least = a;
    }
    up[least] = 1; /* the axis least along the ray: never parallel to it */
    return ms_camera_look_at(eye, anchor, up, PROBE_FOVY_DEG, PROBE_PIXELS, PROBE_PIXELS, back / 100, back * 4,
                             camera, err);
}

ms_status ms_viewer_probe_start(const ms_viewer_source *source, const ms_viewer_model *model,
                                ms_viewer_probe **out, ms_error *err)
{
    *out = NULL;
    ms_viewer_probe *p = calloc(1, sizeof *p);
    if (!p)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a probe");
    p->box_side = model->header.box_side;
    ms_core_options co = {0};
    if (source->archive_dir) {
        co.archive_path = model->archive_path;
    } else {
        co.host = source->host, co.port = source->port, co.token = source->token;
        co.agent = MS_VIEWER_AGENT;
        co.give_up_seconds = MS_VIEWER_GIVE_UP_S;
    }
    co.model = model->name;
    co.tolerance_px = 1;
    co.culled_bits_less = 64; /* outside the point's frustum: nothing wanted */
    co.decode_threads = 1;
    co.export_frames = true;
    ms_status st = ms_core_start(&co, &p->core, err);
    if (st != MS_OK) {
        free(p);
        return st;
    }
    *out = p;
    return MS_OK;
}

void ms_viewer_probe_stop(ms_viewer_probe *p)
{
    if (!p)
        return;
    ms_core_stop(p->core);
    ms_core_frame_free(p->frame);
    free(p);
}

/* The chain's point with id, or -1. */
static long point_of(const ms_viewer_measure *m, uint64_t id)
{
    for (size_t i = 0; i < m->count; ++i)
        if (m->id[i] == id)
            return (long)i;
    return -1;
}

bool ms_viewer_probe_step(ms_viewer_probe *p, ms_viewer_measure *m)
{
    if (p->id) {
        /* figures before the take: they describe the frame taken (or one before) */
        ms_core_stats stats;
        ms_core_get_stats(p->core, &stats);
        ms_core_frame *f = ms_core_take_frame(p->core);
        if (f) {
            ms_core_frame_free(p->frame);
            p->frame = f;
        }
        long i = point_of(m, p->id);
        bool given_up = stats.error[0] || ms_now_seconds() - p->started > MS_VIEWER_PROBE_TIMEOUT_S;
        if (i >= 0 && stats.view_complete && p->frame) {
            ms_viewer_measure_hit hit;
            if (ms_viewer_measure_cast(p->frame, p->box_side, p->anchor, p->direction, -INFINITY, 0, &hit)) {
                m->hit[i] = hit;
                m->found[i] = true;
                memcpy(m->anchor[i], hit.point, sizeof hit.point);
            }
            m->refined[i] = true;
            p->id = 0;
        } else if (i < 0 || given_up) {
            if (i >= 0)
                m->refined[i] = true; /* given up: as the view has it */
            p->id = 0;
        }
    }
    for (size_t i = 0; !p->id && i < m->count; ++i) {
        if (!m->found[i] || m->refined[i])
            continue;
        ms_camera cam;
        ms_error ignored;
        if (ms_viewer_probe_camera(m->anchor[i], m->direction[i], p->box_side, &cam, &ignored) != MS_OK) {
            m->refined[i] = true;
            continue;
        }
        p->id = m->id[i];
        memcpy(p->anchor, m->anchor[i], sizeof p->anchor);
        memcpy(p->direction, m->direction[i], sizeof p->direction);
        p->started = ms_now_seconds();
        ms_core_set_camera(p->core, &cam);
    }
    return p->id != 0;
}
