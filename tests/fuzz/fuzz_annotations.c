/* libFuzzer target on the annotations parser (common/archive/ms_annotations.c,
 * ms_annotations_parse: what `meshbake --annotations`, meshview and the doors'
 * annotations document carry; docs/ANNOTATIONS.md).
 *
 * Input: the file's bytes. Besides the sanitizers, the target checks the
 * parser's contract and aborts when one is broken: a refused file gives a
 * one-line error and no set; an accepted one holds at most
 * MS_ANNOTATIONS_MAX annotations, each passing ms_annotation_check with a
 * unique id, and written then parsed again it gives an equal set and the same
 * text.
 *
 * tests/test_fuzz_replay.c includes this file to replay
 * tests/corpus/annotations/ in `make test`; it then calls
 * ms_fuzz_annotations_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_annotations.h"

#define MS_FUZZ_ANNOTATIONS_CHECK(cond)                                                        \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_annotations: contract broken: %s (%s:%d)\n", #cond,          \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* Returns true when the file was accepted. */
static bool ms_fuzz_annotations_one(const uint8_t *data, size_t size)
{
    ms_annotations *set = (ms_annotations *)&size; /* must come back NULL on failure */
    ms_error err;
    ms_error_clear(&err);
    if (ms_annotations_parse((const char *)data, size, "annotations", &set, &err) != MS_OK) {
        MS_FUZZ_ANNOTATIONS_CHECK(set == NULL);
        MS_FUZZ_ANNOTATIONS_CHECK(err.text[0] && !strchr(err.text, '\n'));
        return false;
    }
    size_t n = ms_annotations_count(set);
    MS_FUZZ_ANNOTATIONS_CHECK(n <= MS_ANNOTATIONS_MAX);
    for (size_t i = 0; i < n; ++i) {
        const ms_annotation *a = ms_annotations_get(set, i);
        MS_FUZZ_ANNOTATIONS_CHECK(ms_annotation_check(a, "fuzz", &err) == MS_OK);
        MS_FUZZ_ANNOTATIONS_CHECK(ms_annotations_find(set, a->id) == (long)i);
    }
    char *text = NULL, *again = NULL;
    size_t text_size = 0, again_size = 0;
    if (ms_annotations_write(set, &text, &text_size, &err) == MS_OK) {
        ms_annotations *back = NULL;
        MS_FUZZ_ANNOTATIONS_CHECK(ms_annotations_parse(text, text_size, "written", &back, &err) == MS_OK);
        MS_FUZZ_ANNOTATIONS_CHECK(ms_annotations_equal(set, back));
        MS_FUZZ_ANNOTATIONS_CHECK(ms_annotations_write(back, &again, &again_size, &err) == MS_OK);
        MS_FUZZ_ANNOTATIONS_CHECK(again_size == text_size && memcmp(text, again, text_size) == 0);
        ms_annotations_free(back);
    } else {
        /* only a set that writes past the file's limit (or no memory) */
        MS_FUZZ_ANNOTATIONS_CHECK(err.code == MS_ERR_RANGE || err.code == MS_ERR_NOMEM);
    }
    free(text);
    free(again);
    ms_annotations_free(set);
    return true;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_annotations_one(data, size);
    return 0;
}
#endif
