/* A model's annotations (docs/ANNOTATIONS.md): hotspots on the surface, each
 * a point in model (world) coordinates, optionally the radius of a small
 * region around it, a title, a text and optionally a view stored with it in
 * meshview's shareable view text (ms_viewer_share.h). They live in a sidecar
 * beside the model's archive, DIR/NAME.annotations.json, installed by
 * `meshbake --annotations FILE`, served by both doors as the model's
 * annotations document, read and edited by meshview, shown by the browser.
 *
 * The file is one JSON object of at most MS_ANNOTATIONS_FILE_MAX bytes:
 *
 *   {"format": "meshstream-annotations", "version": 1, "annotations": [
 *     {"id": "a1", "point": [X, Y, Z], "radius": R, "title": "...",
 *      "text": "...", "view": "mv1:..."}, ...]}
 *
 * "id", "point" and "title" are required; "radius" (default 0: a point),
 * "text" (default empty) and "view" (default none) are not. At most
 * MS_ANNOTATIONS_MAX annotations; ids are 1 to MS_ANNOTATION_ID_MAX bytes of
 * A-Z a-z 0-9 . _ - and unique; coordinates finite; the radius finite and
 * >= 0; the title 1 to MS_ANNOTATION_TITLE_MAX bytes, the text at most
 * MS_ANNOTATION_TEXT_MAX bytes, both held to the sidecar metadata's rules
 * (ms_metadata_text_ok: valid UTF-8, no control character but line feeds in
 * the text, no bidirectional override or isolate); the view "mv1:" then
 * printable ASCII without spaces, at most MS_ANNOTATION_VIEW_MAX bytes (its
 * fields are read by the clients, which refuse a view they cannot read).
 * Anything else is refused with one line naming the annotation and the
 * fault: an unknown member, a missing or mistyped one, a value out of range,
 * a repeated id, another format or version. The text is kept as given: a
 * page that shows it must escape it.
 *
 * Ownership: an ms_annotations owns copies of its strings; the pointers of an
 * ms_annotation it returns stay valid until the set changes or is freed.
 * Pure; a set is used by one thread at a time.
 */
#ifndef MS_ANNOTATIONS_H
#define MS_ANNOTATIONS_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_error.h"

#define MS_ANNOTATIONS_FORMAT "meshstream-annotations"
#define MS_ANNOTATIONS_VERSION 1
#define MS_ANNOTATIONS_FILE_MAX (1024 * 1024)
#define MS_ANNOTATIONS_MAX 1000
#define MS_ANNOTATION_ID_MAX 64
#define MS_ANNOTATION_TITLE_MAX 200
#define MS_ANNOTATION_TEXT_MAX 8000
#define MS_ANNOTATION_VIEW_MAX 4095

typedef struct ms_annotation {
    const char *id;    /* 1 to MS_ANNOTATION_ID_MAX bytes of [A-Za-z0-9._-] */
    double point[3];   /* model (world) coordinates, finite */
    double radius;     /* >= 0; 0: a point */
    const char *title; /* 1 to MS_ANNOTATION_TITLE_MAX bytes, one line */
    const char *text;  /* at most MS_ANNOTATION_TEXT_MAX bytes ("" allowed; NULL as "") */
    const char *view;  /* NULL: none; else "mv1:..." (ms_viewer_share.h) */
} ms_annotation;

typedef struct ms_annotations ms_annotations;

/* An empty set; NULL when out of memory. */
ms_annotations *ms_annotations_new(void);
void ms_annotations_free(ms_annotations *set);

size_t ms_annotations_count(const ms_annotations *set);
/* Annotation i (< count), in the file's order. */
const ms_annotation *ms_annotations_get(const ms_annotations *set, size_t i);
/* The index of the annotation with this id, or -1. */
long ms_annotations_find(const ms_annotations *set, const char *id);

/* Checks a against the rules above (where names it in the error: "FILE:
 * annotation 3 (id)"). MS_ERR_FORMAT or MS_ERR_RANGE with one line. */
ms_status ms_annotation_check(const ms_annotation *a, const char *where, ms_error *err);

/* Appends a copy of a (checked; refused when its id is taken or the set is
 * full: MS_ERR_RANGE). */
ms_status ms_annotations_add(ms_annotations *set, const ms_annotation *a, ms_error *err);

/* Removes annotation i; false when there is none. */
bool ms_annotations_remove(ms_annotations *set, size_t i);

/* The first id "aN" (N = 1, 2, ...) the set does not use, in id (at least
 * MS_ANNOTATION_ID_MAX + 1 bytes). */
void ms_annotations_next_id(const ms_annotations *set, char *id, size_t size);

/* Parses a file's text (size bytes; where names it in errors) into a new set. */
ms_status ms_annotations_parse(const char *text, size_t size, const char *where, ms_annotations **out,
                               ms_error *err);

/* Reads and parses the file at path (a regular file: ms_input_file.h). */
ms_status ms_annotations_load(const char *path, ms_annotations **out, ms_error *err);

/* The file's text (malloc'd, NUL-terminated, *size bytes without the NUL):
 * what ms_annotations_parse reads back to an equal set. MS_ERR_RANGE when it
 * would pass MS_ANNOTATIONS_FILE_MAX. */
ms_status ms_annotations_write(const ms_annotations *set, char **text, size_t *size, ms_error *err);

/* Writes the file at path whole or not at all (a temporary file beside it,
 * renamed into place). */
ms_status ms_annotations_save(const ms_annotations *set, const char *path, ms_error *err);

/* Same annotations in the same order, every field equal (coordinates bit for bit). */
bool ms_annotations_equal(const ms_annotations *a, const ms_annotations *b);

/* DIR/NAME.annotations.json. */
void ms_annotations_sidecar_path(const char *dir, const char *name, char *out, size_t size);

#endif
