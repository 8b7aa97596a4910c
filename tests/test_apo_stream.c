/* ms_apo_stream_compress's output bound: a chunk of many small levels of
 * incompressible words (a sync flush after each can cost about 11 bytes beyond
 * deflateBound) compresses at every zlib level and inflates back word for word,
 * whole and by level prefix. Before the bound allowed for it, the 871k dragon
 * baked with --apo-tol 0.4 failed with "zlib failed at level 8". */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_apo_format.h"
#include "ms_apo_stream.h"
#include "ms_test.h"

static void test_many_small_incompressible_levels(void **state)
{
    (void)state;
    for (uint32_t per_level = 1; per_level <= 3; ++per_level) {
        ms_apo_chunk chunk = {.level_count = MS_APO_MAX_LEVELS};
        chunk.level_texels[0] = 1;
        chunk.texel_count = 1;
        for (uint32_t d = 1; d < MS_APO_MAX_LEVELS; ++d) {
            chunk.level_texels[d] = per_level;
            chunk.texel_count += per_level;
        }
        chunk.texels = malloc(chunk.texel_count * sizeof *chunk.texels);
        assert_non_null(chunk.texels);
        uint64_t seed = 1234 + per_level;
        for (size_t i = 0; i < chunk.texel_count; ++i)
            chunk.texels[i] = (uint32_t)ms_test_random(&seed);
        for (int zlevel = -1; zlevel <= 9; ++zlevel) {
            uint8_t *out = NULL;
            size_t size = 0;
            uint32_t table[2 * MS_APO_MAX_LEVELS];
            ms_error err;
            if (ms_apo_stream_compress(&chunk, zlevel, &out, &size, table, &err) != MS_OK)
                fail_msg("%u words a level, zlib level %d: %s", per_level, zlevel, err.text);
            assert_int_equal(table[2 * (MS_APO_MAX_LEVELS - 1)], size);
            for (uint32_t levels = 1; levels <= MS_APO_MAX_LEVELS; levels += MS_APO_MAX_LEVELS - 1) {
                ms_apo_chunk back;
                assert_int_equal(ms_apo_stream_inflate(out, table[2 * (levels - 1)], table, MS_APO_MAX_LEVELS, &back,
                                                       &err),
                                 MS_OK);
                assert_int_equal(back.texel_count, table[2 * (levels - 1) + 1]);
                assert_memory_equal(back.texels, chunk.texels, back.texel_count * sizeof *back.texels);
                free(back.texels);
            }
            free(out);
        }
        free(chunk.texels);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_many_small_incompressible_levels),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
