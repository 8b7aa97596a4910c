/* meshbake's modes on a baked collection (an archive directory and its
 * catalog.json): each returns the program's exit status (0, 1 for an input
 * error, 2 for a usage error) and prints its own one-line errors. */
#ifndef MS_BAKE_COLLECTION_H
#define MS_BAKE_COLLECTION_H

#include <stdbool.h>

/* --set-public-bits: model name's preview becomes bits; a thumbnail finer
 * than the new preview is rendered again first (up_axis, threads; up_axis
 * < 0: the picture's own up, ms_bake_thumbnail). */
int ms_bake_cli_set_public(const char *dir, const char *name, unsigned bits, int up_axis,
                           unsigned threads);

/* --list: every model, each archive opened and every payload checked. */
int ms_bake_cli_list(const char *dir, bool json);

/* --remove: the catalogue entry, then the archive, its thumbnail and its
 * annotations. */
int ms_bake_cli_remove(const char *dir, const char *name);

/* --thumbnail: renders DIR/NAME.thumb.png again (up_axis < 0: with the up it
 * had) and records it in the catalogue (ms_bake_thumbnail.h). */
int ms_bake_cli_thumbnail(const char *dir, const char *name, int up_axis, unsigned threads,
                          bool json);

/* --annotations: checks the annotations file (ms_annotations.h) and writes
 * it, as the format writes it, to DIR/NAME.annotations.json of the baked
 * model name (whole or not at all). */
int ms_bake_cli_annotations(const char *dir, const char *name, const char *file, bool json);

#endif
