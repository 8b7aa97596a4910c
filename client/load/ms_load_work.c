/* meshload's JSON of a core's decode work (ms_load_work.h). */
#include "ms_load_work.h"

#include "ms_json_out.h"

json_t *ms_load_decode_work_json(const ms_core_decode_work *w)
{
    double serial = w->take_cpu + w->select_cpu + w->apply_cpu + w->content_cpu + w->plan_cpu +
                    w->publish_cpu;
    double all = serial + w->refine_cpu + w->helper_cpu; /* refine_cpu: the decode thread's jobs */
    double span = serial + w->jobs_span2_cpu;
    const struct {
        const char *key;
        double value;
    } seconds[] = {
        {"take_cpu", w->take_cpu},
        {"select_cpu", w->select_cpu},
        {"refine_cpu", w->refine_cpu},
        {"apply_cpu", w->apply_cpu},
        {"content_cpu", w->content_cpu},
        {"plan_cpu", w->plan_cpu},
        {"publish_cpu", w->publish_cpu},
        {"jobs_cpu", w->jobs_cpu},
        {"helper_cpu", w->helper_cpu},
        {"jobs_span2_cpu", w->jobs_span2_cpu},
        {"parallel_fraction", all > 0 ? w->jobs_cpu / all : 0.0},
        {"two_thread_bound", span > 0 ? all / span : 0.0},
    };
    const struct {
        const char *key;
        uint64_t value;
    } counts[] = {
        {"passes", w->passes},
        {"waves", w->waves},
        {"jobs", w->jobs},
        {"splits", w->splits},
        {"jobs_on_helpers", w->jobs_on_helpers},
        {"apply_refined", w->apply_refined},
        {"apply_splits", w->apply_splits},
    };
    json_t *o = json_object();
    if (!o)
        return NULL;
    for (size_t k = 0; k < sizeof seconds / sizeof *seconds; ++k)
        json_object_set_new(o, seconds[k].key, ms_json_fixed(seconds[k].value, 4));
    for (size_t k = 0; k < sizeof counts / sizeof *counts; ++k)
        json_object_set_new(o, counts[k].key, json_integer((json_int_t)counts[k].value));
    return o;
}
