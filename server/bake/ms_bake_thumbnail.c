/* meshbake's thumbnails (ms_bake_thumbnail.h). */
#include "ms_bake_thumbnail.h"

#include <stdio.h>
#include <unistd.h>

void ms_bake_thumbnail_path(const char *dir, const char *name, char *out, size_t size)
{
    snprintf(out, size, "%s/%s.thumb.png", dir, name);
}

ms_status ms_bake_thumbnail(const char *dir, ms_catalog_entry *e, int up_axis, unsigned threads,
                            ms_study_thumbnail_report *report, ms_error *err)
{
    char archive[4200], png[4200];
    snprintf(archive, sizeof archive, "%s/%s.msa", dir, e->name);
    ms_bake_thumbnail_path(dir, e->name, png, sizeof png);
    ms_study_thumbnail_options o;
    ms_study_thumbnail_options_default(&o);
    o.up_axis = up_axis >= 0 && up_axis <= 2 ? up_axis : e->has_thumbnail ? e->thumbnail_up : 2;
    o.threads = threads;
    o.permitted_bits = e->public_max_bits < e->bits ? e->public_max_bits : e->bits;
    e->has_thumbnail = false;
    e->thumbnail_bits = 0;
    ms_status st = ms_study_thumbnail(archive, png, &o, report, err);
    if (st != MS_OK) {
        unlink(png); /* an old picture may show more than the entry now allows */
        return st;
    }
    e->has_thumbnail = true;
    e->thumbnail_up = (uint8_t)o.up_axis;
    e->thumbnail_bits = (uint8_t)(report->bits < o.permitted_bits ? report->bits
                                                                   : o.permitted_bits);
    return MS_OK;
}
