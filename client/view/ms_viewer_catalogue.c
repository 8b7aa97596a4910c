#include "ms_viewer_catalogue.h"

#include <GLFW/glfw3.h>
#include <stdio.h>
#include <string.h>

#include "ms_viewer_font.h"

/* Layout, in font pixels times scale: a margin, the title, the column heads,
 * then rows 1.5 lines tall. */
#define MARGIN 12.0
#define ROW (MS_FONT_LINE_HEIGHT * 1.5)
#define FIRST_ROW_Y (MARGIN + 3 * MS_FONT_LINE_HEIGHT + 6)

static size_t rows_visible(int height, int scale)
{
    double free_px = height - (FIRST_ROW_Y + 2 * MS_FONT_LINE_HEIGHT) * scale;
    long rows = (long)(free_px / (ROW * scale));
    return rows < 1 ? 1 : (size_t)rows;
}

void ms_viewer_catalogue_move(ms_viewer_catalogue *cat, long delta, int height, int scale)
{
    size_t count = cat->list->count;
    if (!count)
        return;
    long to = (long)cat->selected + delta;
    cat->selected = to < 0 ? 0 : (size_t)to >= count ? count - 1 : (size_t)to;
    size_t shown = rows_visible(height, scale);
    if (cat->selected < cat->first)
        cat->first = cat->selected;
    if (cat->selected >= cat->first + shown)
        cat->first = cat->selected + 1 - shown;
}

long ms_viewer_catalogue_row_at(const ms_viewer_catalogue *cat, double x, double y, int width,
                                int height, int scale)
{
    if (x < MARGIN * scale || x > width - MARGIN * scale)
        return -1;
    double top = FIRST_ROW_Y * scale;
    if (y < top)
        return -1;
    size_t row = (size_t)((y - top) / (ROW * scale));
    if (row >= rows_visible(height, scale))
        return -1;
    size_t index = cat->first + row;
    return index < cat->list->count ? (long)index : -1;
}

/* 1234567 -> "1,234,567" */
static void grouped(uint64_t v, char *out, size_t size)
{
    char digits[32];
    int n = snprintf(digits, sizeof digits, "%llu", (unsigned long long)v);
    size_t o = 0;
    for (int i = 0; i < n && o + 2 < size; ++i) {
        if (i && (n - i) % 3 == 0)
            out[o++] = ',';
        out[o++] = digits[i];
    }
    out[o] = 0;
}

void ms_viewer_catalogue_row_text(const ms_viewer_model_entry *e, char *out, size_t size)
{
    char tris[32] = "?";
    if (e->triangles)
        grouped(e->triangles, tris, sizeof tris);
    snprintf(out, size, "%-24.24s %13s %9.1f MB%s", e->name, tris, (double)e->bytes / 1e6,
             e->apo ? "  APO" : "");
}

void ms_viewer_catalogue_draw(ms_viewer_text *text, const ms_viewer_catalogue *cat, int width,
                              int height)
{
    int s = ms_viewer_text_scale(text);
    static const float ink[4] = {0.92f, 0.92f, 0.88f, 1}, dim[4] = {0.6f, 0.6f, 0.6f, 1},
                       title[4] = {0.45f, 0.8f, 1.0f, 1}, band[4] = {0.25f, 0.45f, 0.7f, 0.9f};
    double x = MARGIN * s, y = MARGIN * s;
    char line[160];
    snprintf(line, sizeof line, "meshstream models - %s", cat->where ? cat->where : "");
    ms_viewer_text_print(text, x, y, title, line);
    y += 2 * MS_FONT_LINE_HEIGHT * s;
    snprintf(line, sizeof line, "%-24s %13s %12s", "name", "triangles", "size");
    ms_viewer_text_print(text, x, y, dim, line);
    if (!cat->list->count) {
        ms_viewer_text_print(text, x, FIRST_ROW_Y * s, ink, "(no models)");
        return;
    }
    size_t shown = rows_visible(height, s);
    for (size_t r = 0; r < shown && cat->first + r < cat->list->count; ++r) {
        size_t i = cat->first + r;
        double row_y = (FIRST_ROW_Y + r * ROW) * s;
        if (i == cat->selected)
            ms_viewer_text_rect(text, x - 4 * s, row_y - 3 * s, width - 2 * x + 8 * s,
                                (MS_FONT_GLYPH_H + 6) * s, band);
        ms_viewer_catalogue_row_text(&cat->list->entries[i], line, sizeof line);
        ms_viewer_text_print(text, x, row_y, ink, line);
    }
    ms_viewer_text_print(text, x, height - 2 * MS_FONT_LINE_HEIGHT * s, dim,
                         "up/down or mouse: choose   enter or double-click: open   esc: quit");
}

ms_catalogue_action ms_viewer_catalogue_key(ms_viewer_catalogue *cat, int key, int height, int scale)
{
    long move = key == GLFW_KEY_DOWN ? 1 : key == GLFW_KEY_UP ? -1 : key == GLFW_KEY_PAGE_DOWN ? 10
                : key == GLFW_KEY_PAGE_UP                      ? -10 : 0;
    if (move)
        ms_viewer_catalogue_move(cat, move, height, scale);
    return key == GLFW_KEY_ENTER || key == GLFW_KEY_KP_ENTER ? MS_CATALOGUE_OPEN
           : key == GLFW_KEY_TAB                             ? MS_CATALOGUE_BACK
                                                             : MS_CATALOGUE_STAY;
}
