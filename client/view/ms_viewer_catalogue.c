#include "ms_viewer_catalogue.h"

#include <GLFW/glfw3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_png.h"
#include "ms_progress.h"
#include "ms_viewer_font.h"

/* The panel: a thumbnail is MS_THUMB_W x MS_THUMB_H (meshbake's) */
#define PANEL_THUMB_W 160.0
#define PANEL_THUMB_H 120.0
#define LIST_COLUMNS 49 /* the row text's width in characters */

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

/* A server's screen: its fetches go to the worker. */
static bool served(const ms_viewer_catalogue *cat)
{
    return cat->source && !cat->archive_dir && !cat->source->archive_dir;
}

/* The worker, made at the first need; NULL when it cannot be (the failure
 * line says why). */
static ms_viewer_fetcher *fetcher(ms_viewer_catalogue *cat)
{
    ms_error err;
    if (!cat->fetcher && served(cat) &&
        ms_viewer_fetcher_new(cat->source, &cat->fetcher, &err) != MS_OK)
        snprintf(cat->failure, sizeof cat->failure, "%.150s", err.text);
    return cat->fetcher;
}

/* Asks the worker for the page of query from offset, once. */
static void request_page(ms_viewer_catalogue *cat, const char *query, size_t offset)
{
    ms_viewer_fetcher *f = fetcher(cat);
    if (!f || (cat->page_pending && !strcmp(cat->page_query, query) && cat->page_offset == offset))
        return;
    ms_viewer_fetcher_want_page(f, query, offset);
    cat->page_pending = true;
    snprintf(cat->page_query, sizeof cat->page_query, "%s", query);
    cat->page_offset = offset;
}

void ms_viewer_catalogue_move(ms_viewer_catalogue *cat, long delta, int height, int scale)
{
    size_t shown = rows_visible(height, scale);
    /* a server's next page, when the selection comes near the end of those
     * held (not while a search's first page is on its way) */
    if (served(cat) && cat->list->total > cat->list->count && delta > 0 &&
        !strcmp(cat->search, cat->list->query) &&
        cat->selected + (size_t)delta + 2 * shown >= cat->list->count)
        request_page(cat, cat->list->query, cat->list->count);
    size_t count = cat->list->count;
    if (!count)
        return;
    long to = (long)cat->selected + delta;
    cat->selected = to < 0 ? 0 : (size_t)to >= count ? count - 1 : (size_t)to;
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
    snprintf(out, size, "%-20.20s %11s %8.1f MB%s", e->name, tris, (double)e->bytes / 1e6,
             e->apo ? "  APO" : "");
}

static void clear_thumbnail(ms_viewer_catalogue *cat)
{
    free(cat->thumbnail);
    cat->thumbnail = NULL;
    cat->thumbnail_of = 0;
}

void ms_viewer_catalogue_free(ms_viewer_catalogue *cat)
{
    clear_thumbnail(cat);
    ms_viewer_fetcher_free(cat->fetcher);
    cat->fetcher = NULL;
    cat->page_pending = false;
    if (cat->list) /* a search whose page did not come: the list's own text */
        snprintf(cat->search, sizeof cat->search, "%s", cat->list->query);
}

/* A model's documents from the worker into its entry, when it is listed. */
static void take_documents(ms_viewer_catalogue *cat, ms_viewer_fetched *r)
{
    ms_viewer_model_list *list = cat->list;
    for (size_t i = 0; i < list->count; ++i) {
        ms_viewer_model_entry *e = &list->entries[i];
        if (strcmp(e->name, r->entry.name) || e->documents_fetched)
            continue;
        ms_metadata_free(e->metadata);
        free(e->thumbnail_png);
        e->metadata = r->entry.metadata, e->has_thumbnail = r->entry.has_thumbnail;
        e->thumbnail_png = r->entry.thumbnail_png;
        e->thumbnail_png_size = r->entry.thumbnail_png_size;
        e->documents_fetched = true;
        r->entry.metadata = NULL, r->entry.thumbnail_png = NULL; /* moved */
        if (cat->thumbnail_of == i + 1)
            clear_thumbnail(cat);
        break;
    }
}

/* A page from the worker: a search's first page, or the list's next. */
static void take_page(ms_viewer_catalogue *cat, ms_viewer_fetched *r)
{
    ms_viewer_model_list *list = cat->list;
    if (cat->page_pending && !strcmp(cat->page_query, r->query) && cat->page_offset == r->offset) {
        cat->page_pending = false;
        if (r->status != MS_OK)
            snprintf(cat->failure, sizeof cat->failure, "%.150s", r->why);
    }
    if (r->status != MS_OK && r->offset == 0 && !strcmp(r->query, cat->search))
        snprintf(cat->search, sizeof cat->search, "%s", list->query); /* the list as it was */
    if (r->status != MS_OK)
        return;
    if (r->offset == 0 && !strcmp(r->query, cat->search)) {
        clear_thumbnail(cat);
        ms_viewer_model_list_free(list);
        *list = r->page;
        memset(&r->page, 0, sizeof r->page);
        cat->selected = cat->first = 0;
    } else if (r->offset == list->count && !strcmp(r->query, list->query)) {
        ms_viewer_model_entry *grown =
            r->page.count ? realloc(list->entries, (list->count + r->page.count) * sizeof *grown)
                          : list->entries;
        if (!grown) {
            snprintf(cat->failure, sizeof cat->failure, "out of memory for the catalogue");
            return;
        }
        list->entries = grown;
        memcpy(list->entries + list->count, r->page.entries, r->page.count * sizeof *grown);
        list->count += r->page.count;
        list->total = r->page.count ? r->page.total : list->count;
        r->page.count = 0; /* moved */
    }
}

bool ms_viewer_catalogue_poll(ms_viewer_catalogue *cat)
{
    bool any = false;
    ms_viewer_fetched r;
    while (cat->fetcher && ms_viewer_fetcher_take(cat->fetcher, &r)) {
        any = true;
        if (r.kind == MS_FETCHED_DOCUMENTS)
            take_documents(cat, &r);
        else
            take_page(cat, &r);
        if (r.kind == MS_FETCHED_DOCUMENTS && r.status != MS_OK)
            snprintf(cat->failure, sizeof cat->failure, "%.150s", r.why);
        else if (r.status == MS_OK)
            cat->failure[0] = 0;
        ms_viewer_fetched_free(&r);
    }
    return any;
}

int ms_viewer_catalogue_wrap(const char *text, int columns, int max_lines, char *out,
                             size_t size)
{
    if (columns < 4 || max_lines < 1 || size < 2) {
        if (size)
            out[0] = 0;
        return 0;
    }
    /* ASCII first: each UTF-8 sequence one '?' */
    size_t n = strlen(text), o = 0;
    char *flat = malloc(n + 1);
    if (!flat) {
        out[0] = 0;
        return 0;
    }
    for (size_t i = 0; i < n; ++i) {
        unsigned char c = (unsigned char)text[i];
        if (c >= 0x80 && (c & 0xC0) == 0x80)
            continue; /* a continuation byte */
        flat[o++] = c == '\n' ? '\n' : c < 0x20 || c >= 0x7F ? '?' : (char)c;
    }
    flat[o] = 0;
    int lines = 0;
    size_t at = 0, w = 0;
    while (flat[at] && lines < max_lines) {
        size_t len = strcspn(flat + at, "\n"), take = len;
        if (take > (size_t)columns) { /* break at the last space that fits */
            take = (size_t)columns;
            while (take > 0 && flat[at + take] != ' ')
                --take;
            if (take == 0)
                take = (size_t)columns;
        }
        bool last = lines + 1 == max_lines;
        bool more = flat[at + take] && !(flat[at + take] == '\n' && !flat[at + take + 1]);
        if (last && more) { /* cut, with an ellipsis */
            if (take + 3 > (size_t)columns)
                take = (size_t)columns - 3;
        }
        if (w + take + 5 >= size)
            break;
        if (lines)
            out[w++] = '\n';
        memcpy(out + w, flat + at, take);
        w += take;
        if (last && more) {
            memcpy(out + w, "...", 3);
            w += 3;
        }
        ++lines;
        at += take;
        while (flat[at] == ' ')
            ++at;
        if (flat[at] == '\n')
            ++at;
    }
    out[w] = 0;
    free(flat);
    return lines;
}

ms_catalogue_panel ms_viewer_catalogue_panel(ms_viewer_catalogue *cat)
{
    if (cat->selected >= cat->list->count)
        return MS_PANEL_NONE;
    ms_viewer_model_entry *e = &cat->list->entries[cat->selected];
    if (served(cat) && !e->documents_fetched) {
        double now = ms_now_seconds();
        if (strcmp(cat->panel_name, e->name)) { /* selected since now */
            snprintf(cat->panel_name, sizeof cat->panel_name, "%s", e->name);
            cat->panel_since = now;
        }
        if (now - cat->panel_since < MS_CATALOGUE_SETTLE_S)
            return MS_PANEL_LOADING; /* passed by, perhaps: not asked for yet */
        ms_viewer_fetcher *f = fetcher(cat);
        if (f) {
            ms_viewer_fetcher_want_documents(f, e->name); /* supersedes another waiting */
            return MS_PANEL_LOADING;
        }
        e->documents_fetched = true; /* no worker: none to show */
    }
    if (cat->thumbnail_of != cat->selected + 1) {
        clear_thumbnail(cat);
        cat->thumbnail_of = cat->selected + 1;
        ms_error err;
        char path[4200];
        if (!cat->archive_dir) {
            if (e->thumbnail_png &&
                ms_png_decode_rgb(e->thumbnail_png, e->thumbnail_png_size, 1024, 1024,
                                  &cat->thumbnail, &cat->thumbnail_width, &cat->thumbnail_height,
                                  &err) != MS_OK)
                cat->thumbnail = NULL; /* shown as "no picture" */
        } else if (e->has_thumbnail) {
            snprintf(path, sizeof path, "%s/%s.thumb.png", cat->archive_dir, e->name);
            if (ms_png_read_rgb(path, 1024, 1024, &cat->thumbnail, &cat->thumbnail_width,
                                &cat->thumbnail_height, &err) != MS_OK)
                cat->thumbnail = NULL;
        }
    }
    return cat->thumbnail ? MS_PANEL_PICTURE : MS_PANEL_NO_PICTURE;
}

/* The selected model's panel at x (width w): picture, then metadata. */
static void draw_panel(ms_viewer_text *text, ms_viewer_catalogue *cat, double x, double y,
                       double w, int height)
{
    int s = ms_viewer_text_scale(text);
    static const float ink[4] = {0.92f, 0.92f, 0.88f, 1}, dim[4] = {0.6f, 0.6f, 0.6f, 1},
                       frame[4] = {0.12f, 0.12f, 0.14f, 1};
    ms_catalogue_panel shows = ms_viewer_catalogue_panel(cat);
    double scale = w / PANEL_THUMB_W < s ? w / PANEL_THUMB_W : s;
    double tw = PANEL_THUMB_W * scale, th = PANEL_THUMB_H * scale;
    ms_viewer_text_rect(text, x, y, tw, th, frame);
    if (cat->thumbnail)
        ms_viewer_text_image(text, x, y, tw, th, cat->thumbnail, (int)cat->thumbnail_width,
                             (int)cat->thumbnail_height, cat->thumbnail_of);
    else
        ms_viewer_text_print(text, x + 8 * s, y + th / 2 - 4 * s, dim,
                             shows == MS_PANEL_LOADING ? "loading..." : "no picture");
    y += th + MS_FONT_LINE_HEIGHT * s;
    const ms_viewer_model_entry *e = &cat->list->entries[cat->selected];
    const ms_metadata *m = e->metadata;
    int columns = (int)(w / (MS_FONT_ADVANCE_X * s));
    double bottom = height - 3 * MS_FONT_LINE_HEIGHT * s;
    const char *labels[MS_METADATA_FIELDS] = {"", "by ", "", "licence: ", "", "unit: "};
    static const int order[MS_METADATA_FIELDS] = {0, 1, 2, 3, 5, 4}; /* the description last */
    char wrapped[2048], field[MS_METADATA_DESCRIPTION_MAX + 16];
    for (int i = 0; i < MS_METADATA_FIELDS && y < bottom; ++i) {
        int k = order[i];
        const char *v = k == 0 && !ms_metadata_field(m, 0) ? e->name : ms_metadata_field(m, k);
        if (!v)
            continue;
        snprintf(field, sizeof field, "%s%s", labels[k], v);
        int room = (int)((bottom - y) / (MS_FONT_LINE_HEIGHT * s));
        int lines = ms_viewer_catalogue_wrap(field, columns, k == 4 ? room : k == 0 ? 2 : 1,
                                             wrapped, sizeof wrapped);
        char *line = wrapped;
        for (int l = 0; l < lines; ++l) {
            char *next = strchr(line, '\n');
            if (next)
                *next = 0;
            ms_viewer_text_print(text, x, y, k == 0 ? ink : dim, line);
            y += MS_FONT_LINE_HEIGHT * s;
            line = next ? next + 1 : line + strlen(line);
        }
        y += (k == 0 || k == 3) ? MS_FONT_LINE_HEIGHT * s / 2 : 0;
    }
}

void ms_viewer_catalogue_draw(ms_viewer_text *text, ms_viewer_catalogue *cat, int width,
                              int height)
{
    int s = ms_viewer_text_scale(text);
    static const float ink[4] = {0.92f, 0.92f, 0.88f, 1}, dim[4] = {0.6f, 0.6f, 0.6f, 1},
                       title[4] = {0.45f, 0.8f, 1.0f, 1}, band[4] = {0.25f, 0.45f, 0.7f, 0.9f};
    double x = MARGIN * s, y = MARGIN * s;
    char line[160];
    (void)ms_viewer_catalogue_poll(cat);
    bool searching = strcmp(cat->search, cat->list->query) != 0; /* its page on its way */
    if (cat->failure[0]) {
        static const float alert[4] = {1.0f, 0.55f, 0.45f, 1};
        ms_viewer_text_print(text, x, height - 3 * MS_FONT_LINE_HEIGHT * s, alert, cat->failure);
    }
    snprintf(line, sizeof line, "meshstream models - %s", cat->where ? cat->where : "");
    ms_viewer_text_print(text, x, y, title, line);
    if (cat->search[0] || cat->list->total > cat->list->count) {
        char count[64] = "";
        if (cat->list->total > cat->list->count)
            snprintf(count, sizeof count, "  (%zu of %zu)", cat->list->count, cat->list->total);
        snprintf(line, sizeof line, "search: %s_%s%s", cat->search, count,
                 searching ? "  (searching...)" : "");
        ms_viewer_text_print(text, x, y + MS_FONT_LINE_HEIGHT * s, dim, line);
    }
    y += 2 * MS_FONT_LINE_HEIGHT * s;
    snprintf(line, sizeof line, "%-20s %11s %11s", "name", "triangles", "size");
    ms_viewer_text_print(text, x, y, dim, line);
    if (!cat->list->count) {
        ms_viewer_text_print(text, x, FIRST_ROW_Y * s, ink,
                             searching        ? "(searching...)"
                             : cat->search[0] ? "(no models match)"
                                              : "(no models)");
        return;
    }
    size_t shown = rows_visible(height, s);
    /* the panel, where it fits beside the rows */
    double list_w = (LIST_COLUMNS + 1) * MS_FONT_ADVANCE_X * s, panel_x = x + list_w + 2 * MARGIN * s;
    double panel_w = width - panel_x - MARGIN * s;
    bool panel = panel_w >= PANEL_THUMB_W && cat->selected < cat->list->count;
    double band_w = panel ? list_w + 8 * s : width - 2 * x + 8 * s;
    if (panel)
        draw_panel(text, cat, panel_x, FIRST_ROW_Y * s, panel_w, height);
    for (size_t r = 0; r < shown && cat->first + r < cat->list->count; ++r) {
        size_t i = cat->first + r;
        double row_y = (FIRST_ROW_Y + r * ROW) * s;
        if (i == cat->selected)
            ms_viewer_text_rect(text, x - 4 * s, row_y - 3 * s, band_w,
                                (MS_FONT_GLYPH_H + 6) * s, band);
        ms_viewer_catalogue_row_text(&cat->list->entries[i], line, sizeof line);
        ms_viewer_text_print(text, x, row_y, ink, line);
    }
    /* the next page on its way: a row saying so below the last */
    size_t last = cat->list->count;
    if (cat->page_pending && cat->page_offset == last && !strcmp(cat->page_query, cat->list->query) &&
        last >= cat->first && last - cat->first < shown)
        ms_viewer_text_print(text, x, (FIRST_ROW_Y + (double)(last - cat->first) * ROW) * s, dim,
                             "loading...");
    ms_viewer_text_print(text, x, height - 2 * MS_FONT_LINE_HEIGHT * s, dim,
                         "up/down or mouse: choose   enter or double-click: open   type: search   "
                         "esc: quit");
}

ms_status ms_viewer_catalogue_search(ms_viewer_catalogue *cat, const char *search,
                                     ms_error *err)
{
    if (!cat->source)
        return MS_OK;
    ms_viewer_model_list fresh;
    ms_status st = ms_viewer_list_page(cat->source, search, &fresh, err);
    if (st != MS_OK)
        return st;
    clear_thumbnail(cat);
    ms_viewer_model_list_free(cat->list);
    *cat->list = fresh;
    cat->page_pending = false;
    snprintf(cat->search, sizeof cat->search, "%s", fresh.query);
    cat->selected = cat->first = 0;
    return MS_OK;
}

/* The character a key types into the search, or 0. */
static char search_char(int key)
{
    if (key >= GLFW_KEY_A && key <= GLFW_KEY_Z)
        return (char)('a' + (key - GLFW_KEY_A));
    if (key >= GLFW_KEY_0 && key <= GLFW_KEY_9)
        return (char)('0' + (key - GLFW_KEY_0));
    return key == GLFW_KEY_SPACE ? ' ' : key == GLFW_KEY_MINUS ? '-' : 0;
}

ms_catalogue_action ms_viewer_catalogue_key(ms_viewer_catalogue *cat, int key, int height, int scale)
{
    char c = search_char(key);
    size_t n = strlen(cat->search);
    if ((c && n + 1 < sizeof cat->search) || (key == GLFW_KEY_BACKSPACE && n)) {
        char search[sizeof cat->search];
        snprintf(search, sizeof search, "%s", cat->search);
        if (c)
            search[n] = c, search[n + 1] = 0;
        else
            search[n - 1] = 0;
        ms_error err;
        if (!served(cat)) {
            (void)ms_viewer_catalogue_search(cat, search, &err); /* failed: the list as it was */
            return MS_CATALOGUE_STAY;
        }
        snprintf(cat->search, sizeof cat->search, "%s", search);
        if (strcmp(search, cat->list->query)) {
            request_page(cat, search, 0); /* supersedes an older search waiting */
        } else if (cat->page_pending && cat->page_offset == 0) { /* back to the list held */
            ms_viewer_fetcher_want_page(cat->fetcher, NULL, 0);
            cat->page_pending = false;
        }
        return MS_CATALOGUE_STAY;
    }
    long move = key == GLFW_KEY_DOWN ? 1 : key == GLFW_KEY_UP ? -1 : key == GLFW_KEY_PAGE_DOWN ? 10
                : key == GLFW_KEY_PAGE_UP                      ? -10 : 0;
    if (move)
        ms_viewer_catalogue_move(cat, move, height, scale);
    if (key == GLFW_KEY_TAB) /* the screen closes: its worker stops (made again if it stays) */
        ms_viewer_catalogue_free(cat);
    return key == GLFW_KEY_ENTER || key == GLFW_KEY_KP_ENTER ? MS_CATALOGUE_OPEN
           : key == GLFW_KEY_TAB                             ? MS_CATALOGUE_BACK
                                                             : MS_CATALOGUE_STAY;
}
