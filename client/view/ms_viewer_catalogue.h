/* meshview's catalogue screen: the models of a server or archive directory as
 * a list (name, triangles, size) to pick from with the arrow keys and Enter, or
 * with the mouse (a click selects, a double click or Enter opens). Beside the
 * list, where the window is wide enough, the selected model's panel: its
 * thumbnail (DIR/NAME.thumb.png from a local archive directory, or from a
 * server the THUMBNAIL document of its binary door) and its metadata (title,
 * creator, date, licence, unit, description: a local catalog.json's, or the
 * server's METADATA document), drawn as glyphs of the bitmap font (a character
 * outside ASCII shows as one '?'; text is never interpreted). Layout in
 * framebuffer pixels through the overlay pass (ms_viewer_text.h), so a click
 * maps to a row with the same arithmetic the drawing used.
 * Typing searches: letters (lower case), digits, space and '-' add to the
 * search text, Backspace takes the last one off; the list is then made again
 * with it (from a server its first page, searched by the server). Moving the
 * selection near the end of a server's fetched pages fetches the next one.
 * From a server, every fetch (the selected model's documents, a page, a
 * search's first page) runs on a worker thread (ms_viewer_fetcher.h) made at
 * the first need: drawing only takes what has arrived (ms_viewer_catalogue_poll)
 * and never waits on the network; the panel says "loading..." meanwhile, the
 * search line "(searching...)", a row "loading..." the next page; a failed
 * fetch is one line at the foot of the screen. A local directory is read at
 * once (ms_viewer_list_page: whole, filtered here).
 * Thread-safety: none shared.
 */
#ifndef MS_VIEWER_CATALOGUE_H
#define MS_VIEWER_CATALOGUE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_viewer_fetcher.h"
#include "ms_viewer_model.h"
#include "ms_viewer_text.h"

typedef struct ms_viewer_catalogue {
    ms_viewer_model_list *list;       /* not owned; a server's entries keep their
                                         documents once fetched */
    const char *where;                /* "server 127.0.0.1:7000" or the directory */
    const char *archive_dir;          /* NULL: a server */
    const ms_viewer_source *source;   /* a server's: its documents fetched through the
                                         binary door for the selected model only (NULL:
                                         none fetched) */
    size_t selected;
    size_t first;                     /* first row shown (scrolling) */
    /* the selected model's thumbnail, read when the selection changes */
    uint8_t *thumbnail;               /* RGB, owned; NULL: none */
    uint32_t thumbnail_width, thumbnail_height;
    size_t thumbnail_of;              /* entry index + 1 it was read for; 0: none */
    char search[65];                  /* the search text typed ("": none); list->query
                                         until its first page came */
    /* a server's: the worker (owned; made at the first fetch) and the page
     * asked of it and not come yet */
    ms_viewer_fetcher *fetcher;
    bool page_pending;
    char page_query[65];
    size_t page_offset;
    char failure[160];                /* the last fetch's failure ("": none) */
    char panel_name[MS_MODEL_NAME_MAX + 1]; /* the model the panel shows, selected */
    double panel_since;                     /* at this time (ms_now_seconds) */
} ms_viewer_catalogue;

/* A server's model is asked for once it has stayed selected this long: the
 * models passed by with the arrow keys (and the screen drawn once while a
 * model opens) are not. */
#define MS_CATALOGUE_SETTLE_S 0.1

/* Takes what the worker fetched: documents into their entry (by name; a
 * model no longer listed drops them), a search's first page as the new list
 * (when its text is still the one typed; the selection back to the first
 * row), a next page appended (when it continues the list). Never waits.
 * True when anything came (the screen changes). */
bool ms_viewer_catalogue_poll(ms_viewer_catalogue *cat);

/* What the panel shows for the selected model: asks the worker for its
 * documents when they have not come, once it has been selected for
 * MS_CATALOGUE_SETTLE_S (LOADING meanwhile), else reads its picture once per
 * selection (PICTURE, or NO_PICTURE when it has none or they failed). */
typedef enum {
    MS_PANEL_NONE,
    MS_PANEL_LOADING,
    MS_PANEL_PICTURE,
    MS_PANEL_NO_PICTURE
} ms_catalogue_panel;
ms_catalogue_panel ms_viewer_catalogue_panel(ms_viewer_catalogue *cat);

/* Makes the list again for search at once, waiting for a server's answer
 * (with cat->source; nothing without one): the selection back to the first
 * row. On an error the list stays as it was and err says why. The keys of a
 * server's screen search through the worker instead. */
ms_status ms_viewer_catalogue_search(ms_viewer_catalogue *cat, const char *search,
                                     ms_error *err);

/* Stops the worker (a fetch in flight is interrupted, ms_viewer_fetcher_free;
 * a search whose page has not come is dropped, the search text back to the
 * list's) and frees the thumbnail cache (the rest is borrowed); the screen
 * may be drawn again after, with a new worker. */
void ms_viewer_catalogue_free(ms_viewer_catalogue *cat);

/* Moves the selection by delta rows (clamped to the rows held) and scrolls
 * to keep it shown; within two screens of the end of a server's fetched
 * pages, asks the worker for the next page. */
void ms_viewer_catalogue_move(ms_viewer_catalogue *cat, long delta, int height, int scale);

/* A key (GLFW_KEY_*) on the catalogue screen: Up / Down and PgUp / PgDn move
 * the selection (1 and 10 rows); A-Z, 0-9, space, '-' and Backspace edit the
 * search text (from a server: its first page asked of the worker; a local
 * list: ms_viewer_catalogue_search); MS_CATALOGUE_OPEN for Enter,
 * MS_CATALOGUE_BACK for Tab (back to the model: the worker stopped, as by
 * ms_viewer_catalogue_free), else MS_CATALOGUE_STAY. */
typedef enum { MS_CATALOGUE_STAY, MS_CATALOGUE_OPEN, MS_CATALOGUE_BACK } ms_catalogue_action;
ms_catalogue_action ms_viewer_catalogue_key(ms_viewer_catalogue *cat, int key, int height, int scale);

/* The row under framebuffer point (x, y), or -1. */
long ms_viewer_catalogue_row_at(const ms_viewer_catalogue *cat, double x, double y, int width,
                                int height, int scale);

/* One row's text: name, triangles and size in columns. */
void ms_viewer_catalogue_row_text(const ms_viewer_model_entry *e, char *out, size_t size);

/* Up to max_lines lines of at most columns characters of text (UTF-8; a
 * non-ASCII character becomes one '?', a line feed breaks), words wrapped,
 * the last line cut with "..." when more is left; into out (lines separated by
 * '\n'). Returns the number of lines. */
int ms_viewer_catalogue_wrap(const char *text, int columns, int max_lines, char *out,
                             size_t size);

/* Draws the screen: takes what arrived (ms_viewer_catalogue_poll), then the
 * rows and the panel (ms_viewer_catalogue_panel). */
void ms_viewer_catalogue_draw(ms_viewer_text *text, ms_viewer_catalogue *cat, int width,
                              int height);

#endif
