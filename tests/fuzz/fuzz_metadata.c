/* libFuzzer target on the sidecar metadata parser (common/archive/ms_metadata.c,
 * ms_metadata_parse: what `meshbake --metadata FILE.json` reads, and the rules
 * catalog.json's "metadata" objects are held to).
 *
 * Input: the sidecar's bytes. Besides the sanitizers, the target checks the
 * parser's contract and aborts when one is broken: a refused sidecar gives a
 * one-line error and no metadata; an accepted one holds only fields within
 * their byte limits that pass ms_metadata_text_ok (valid UTF-8, no control
 * character but line feeds in the description, no bidirectional override),
 * and a unit among MS_METADATA_UNITS, and survives a copy unchanged.
 *
 * tests/test_fuzz_replay.c includes this file to replay tests/corpus/metadata/
 * in `make test`; it then calls ms_fuzz_metadata_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_metadata.h"

#define MS_FUZZ_METADATA_CHECK(cond)                                                           \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_metadata: contract broken: %s (%s:%d)\n", #cond, __FILE__,   \
                    __LINE__);                                                                 \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* Returns true when the sidecar was accepted. */
static bool ms_fuzz_metadata_one(const uint8_t *data, size_t size)
{
    ms_metadata *m = (ms_metadata *)&size; /* must come back NULL on failure */
    ms_error err;
    ms_error_clear(&err);
    if (ms_metadata_parse((const char *)data, size, "sidecar", &m, &err) != MS_OK) {
        MS_FUZZ_METADATA_CHECK(m == NULL);
        MS_FUZZ_METADATA_CHECK(err.text[0] && !strchr(err.text, '\n'));
        return false;
    }
    for (int k = 0; k < MS_METADATA_FIELDS; ++k) {
        const char *v = ms_metadata_field(m, k), *why = NULL;
        if (!v)
            continue;
        size_t n = strlen(v);
        MS_FUZZ_METADATA_CHECK(n >= 1 && n <= ms_metadata_field_max[k]);
        MS_FUZZ_METADATA_CHECK(ms_metadata_text_ok(v, n, k == 4, &why)); /* the description */
        MS_FUZZ_METADATA_CHECK(k != 5 || ms_metadata_unit_valid(v));
    }
    bool failed = false;
    ms_metadata *copy = ms_metadata_dup(m, &failed);
    MS_FUZZ_METADATA_CHECK(failed || ms_metadata_equal(m, copy));
    ms_metadata_free(copy);
    ms_metadata_free(m);
    return true;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_metadata_one(data, size);
    return 0;
}
#endif
