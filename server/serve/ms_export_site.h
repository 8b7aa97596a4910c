/* The browser pages beside a static export (meshexport --web-dir; docs/
 * BROWSER.md "Static export"): what a plain web server needs to serve the
 * whole browser experience of the models exported into one folder, laid out
 * so that the very pages of web/ work from it:
 *
 *   OUT/index.html            the catalogue page
 *   OUT/view/NAME.html        the viewer page of model NAME (the same file
 *                             as view.html: the ".html" tells it the layout)
 *   OUT/web/FILE              every page file of web_dir (ms_http_page_type:
 *                             scripts, style, meshstream.js/.wasm when built)
 *   OUT/catalog.json          the exported models, as GET /catalog lists them,
 *                             each with "view": its page, view/NAME.html
 *                             (merged with the entries of earlier exports),
 *                             and "thumbnail": its picture's path,
 *                             models/NAME/thumbnail.png, where meshexport
 *                             wrote one, else false
 *
 * Not thread-safe for one OUT; files are written under a temporary name and
 * renamed, so a server never sends half a file. */
#ifndef MS_EXPORT_SITE_H
#define MS_EXPORT_SITE_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_catalog.h"
#include "ms_error.h"

/* Writes the pages of web_dir and model entry's page and catalogue entry
 * into out_dir. full: the export holds every byte (meshexport --full), so
 * the catalogue lists the model as public to its last bit (a static server
 * checks no token). thumbnail: the model's picture is in the export. Adds what it wrote to *bytes and *files. Errors: a
 * web_dir without index.html or view.html, a catalog.json in out_dir that is
 * not one meshexport wrote, a file that cannot be read or written. */
ms_status ms_export_site(const char *web_dir, const char *out_dir, const ms_catalog_entry *entry,
                         bool full, bool thumbnail, uint64_t *bytes, uint64_t *files, ms_error *err);

#endif
