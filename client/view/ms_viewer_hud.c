#include "ms_viewer_hud.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ms_render.h"
#include "ms_viewer_font.h"

static double mb(uint64_t bytes) { return (double)bytes / 1e6; }

static const char *drawn_as(float impostor)
{
    return impostor <= 0.0f ? "geometry" : impostor >= 1.0f ? "impostor" : "geometry to impostor";
}

/* The selected piece: what it is, its material, what it costs. */
static size_t piece_lines(const ms_viewer_hud_info *info, char (*lines)[MS_HUD_LINE_MAX])
{
    const ms_viewer_scene_piece *p = info->piece;
    const ms_scene_material *m = p->material;
    snprintf(lines[0], MS_HUD_LINE_MAX, "piece %zu of %zu: %s  %s", info->piece_index + 1,
             info->piece_count, p->model, drawn_as(p->impostor));
    int used = snprintf(lines[1], MS_HUD_LINE_MAX, "%s  albedo %.2f %.2f %.2f",
                        m->kind == MS_MATERIAL_GLOSSY ? "glossy" : "diffuse", m->albedo[0],
                        m->albedo[1], m->albedo[2]);
    if (m->kind == MS_MATERIAL_GLOSSY)
        used += snprintf(lines[1] + used, MS_HUD_LINE_MAX - (size_t)used,
                         "  specular %.2f  shininess %.0f", m->specular, m->shininess);
    if (m->two_sided)
        snprintf(lines[1] + used, MS_HUD_LINE_MAX - (size_t)used, "  two-sided");
    snprintf(lines[2], MS_HUD_LINE_MAX, "%llu triangles in %u cells  %.2f MB  error %.2f px",
             (unsigned long long)p->triangles, p->cells, mb(p->bytes), p->achieved_error_px);
    return 3;
}

size_t ms_viewer_hud_lines(const ms_viewer_hud_info *info,
                           char lines[MS_HUD_MAX_LINES][MS_HUD_LINE_MAX])
{
    const ms_core_stats *c = info->core;
    size_t n = 0;
    snprintf(lines[n++], MS_HUD_LINE_MAX, "%s  %s%s", info->model, info->mode,
             info->fly ? "  (fly)" : "");
    snprintf(lines[n++], MS_HUD_LINE_MAX, "frame %.1f ms  %.0f fps", info->frame_ms, info->fps);
    if (info->show_effects) {
        char *line = lines[n++];
        size_t used = (size_t)snprintf(line, MS_HUD_LINE_MAX, "effects:");
        for (unsigned bit = 1; bit <= MS_EFFECTS_ALL; bit <<= 1)
            if ((info->effects_ran & bit) && used < MS_HUD_LINE_MAX)
                used += (size_t)snprintf(line + used, MS_HUD_LINE_MAX - used, " %s", ms_effect_name(bit));
        if (!info->effects_ran)
            snprintf(line + used, MS_HUD_LINE_MAX - used, " none");
    }
    snprintf(lines[n++], MS_HUD_LINE_MAX, "triangles %llu in %u cells",
             (unsigned long long)info->triangles_drawn, info->cells_drawn);
    snprintf(lines[n++], MS_HUD_LINE_MAX, "cells %u shown  %u loading  %u cached", c->cells_shown,
             c->cells_loading, c->cells_cached);
    snprintf(lines[n++], MS_HUD_LINE_MAX, "received %.2f MB geometry  %.2f MB APO",
             mb(c->geometry_bytes_received), mb(c->apo_bytes_received));
    snprintf(lines[n++], MS_HUD_LINE_MAX, "error %.2f px  tolerance %.2f px",
             c->achieved_error_px, c->tolerance_px);
    snprintf(lines[n++], MS_HUD_LINE_MAX, "%s  core %.1f MB + GL %.1f MB",
             c->error[0]     ? "stopped"
             : info->settled ? "view complete"
             : c->model_open ? "refining"
                             : "connecting",
             mb(c->memory), mb(info->gl_bytes));
    if (c->preview) /* the server let this reader have a public preview only */
        snprintf(lines[n++], MS_HUD_LINE_MAX, "preview: %u bits, a token gives more",
                 c->preview_bits);
    if (c->error[0])
        snprintf(lines[n++], MS_HUD_LINE_MAX, "%.90s", c->error);
    else if (c->warning[0])
        snprintf(lines[n++], MS_HUD_LINE_MAX, "%.90s", c->warning);
    const ms_viewer_playback *pb = info->playback;
    if (pb && ms_viewer_playback_on(pb))
        snprintf(lines[n++], MS_HUD_LINE_MAX, "path %.1f of %.1f s  %s", pb->time,
                 ms_camera_path_duration(&pb->path),
                 pb->state == MS_PLAYBACK_PLAYING ? "playing" : "paused");
    if (info->piece && info->piece->material)
        n += piece_lines(info, lines + n);
    for (size_t i = 0; i < info->extra_count && n < MS_HUD_MAX_LINES; ++i)
        snprintf(lines[n++], MS_HUD_LINE_MAX, "%s", info->extra[i]);
    return n;
}

double ms_viewer_hud_progress(const ms_viewer_hud_info *info)
{
    if (info->settled)
        return 1;
    const ms_core_stats *c = info->core;
    if (!(c->achieved_error_px > 0) || !isfinite(c->achieved_error_px))
        return 0;
    double p = c->tolerance_px / c->achieved_error_px;
    /* Complete geometry can still wait for uploads or APO: never show it full. */
    return p > 0.97 ? 0.97 : p < 0 ? 0 : p;
}

void ms_viewer_hud_draw(ms_viewer_text *text, const ms_viewer_hud_info *info, int width,
                        int height, bool show_text)
{
    (void)height;
    int s = ms_viewer_text_scale(text);
    if (!info->settled) {
        static const float track[4] = {0, 0, 0, 0.35f}, bar[4] = {0.35f, 0.75f, 1.0f, 0.9f};
        double h = 2.0 * s;
        ms_viewer_text_rect(text, 0, 0, width, h, track);
        ms_viewer_text_rect(text, 0, 0, width * ms_viewer_hud_progress(info), h, bar);
    }
    if (!show_text)
        return;
    char lines[MS_HUD_MAX_LINES][MS_HUD_LINE_MAX];
    size_t n = ms_viewer_hud_lines(info, lines);
    size_t longest = 0;
    for (size_t i = 0; i < n; ++i)
        if (strlen(lines[i]) > longest)
            longest = strlen(lines[i]);
    double pad = 4.0 * s, line = MS_FONT_LINE_HEIGHT * s;
    static const float panel[4] = {0, 0, 0, 0.55f}, ink[4] = {0.92f, 0.92f, 0.88f, 1},
                       alert[4] = {1.0f, 0.55f, 0.45f, 1};
    ms_viewer_text_rect(text, pad, 3 * pad, longest * MS_FONT_ADVANCE_X * s + 2 * pad,
                        n * line + 2 * pad - 2.0 * s, panel);
    for (size_t i = 0; i < n; ++i)
        ms_viewer_text_print(text, 2 * pad, 4 * pad + i * line,
                             i == 7u + info->show_effects && info->core->error[0] ? alert : ink,
                             lines[i]);
}

const char *ms_viewer_hud_mode(const ms_render_options *render, double crease_deg, char *text, size_t size)
{
    const char *mode;
    switch (render->shading) {
    case MS_SHADING_NORMALS: mode = render->apo ? "normals (APO)" : "normals (geometry)"; break;
    case MS_SHADING_CELLS: mode = render->apo ? "cells, APO lit" : "cells, geometry lit"; break;
    case MS_SHADING_ALBEDO: mode = "albedo (unlit)"; break;
    default: mode = render->apo ? "APO lit" : "geometry lit"; break;
    }
    /* where no APO normal is used: flat, or smooth with the crease angle (M, K) */
    if (!render->smooth)
        snprintf(text, size, "%s, flat", mode);
    else if (crease_deg >= 0)
        snprintf(text, size, "%s, creases %.0f deg", mode, crease_deg);
    else
        snprintf(text, size, "%s", mode);
    return text;
}
