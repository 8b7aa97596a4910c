/* meshbake's thumbnails (docs/ARCHIVE.md, "Thumbnails"): the picture of a
 * baked model, DIR/NAME.thumb.png beside DIR/NAME.msa, rendered by
 * ms_study_thumbnail at the model's preview precision and recorded in its
 * catalogue entry (thumbnail_bits). Used by a bake, by `meshbake --thumbnail
 * NAME` and by `meshbake --set-public-bits` (a preview made coarser than the
 * thumbnail gets a new one). Thread-safety: none shared. */
#ifndef MS_BAKE_THUMBNAIL_H
#define MS_BAKE_THUMBNAIL_H

#include <stddef.h>

#include "ms_catalog.h"
#include "ms_error.h"
#include "ms_study_thumbnail.h"

/* DIR/NAME.thumb.png into out. */
void ms_bake_thumbnail_path(const char *dir, const char *name, char *out, size_t size);

/* Renders the thumbnail of entry's archive DIR/NAME.msa at the entry's
 * preview (public_max_bits) with world up up_axis (0..2; < 0: the entry's
 * thumbnail_up when it has a thumbnail, else z), and sets
 * entry->has_thumbnail, thumbnail_bits and thumbnail_up (the catalogue is not
 * written here). On failure no file is left and the entry says no thumbnail. */
ms_status ms_bake_thumbnail(const char *dir, ms_catalog_entry *entry, int up_axis,
                            unsigned threads, ms_study_thumbnail_report *report, ms_error *err);

#endif
