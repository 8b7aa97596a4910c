/* scripts/study-report.py on a tiny fixture of the JSON reports scripts/study
 * leaves (one key, two tolerances, the precision sweep at p = 16 only, and
 * meshview's frame-time reports, two repeats of each point): the frame-time
 * table joins each point's fastest repeat to the study's image error of the
 * same cut (geometry alone at T; geometry + APO to the run with K = T at 1 px),
 * the sentences compare frame times at the same PSNR, and the figure is drawn;
 * with the geometry-ahead reports (no-APO bakes with --ahead 0 and the
 * default), the section comparing them: the same tolerance and equal bytes
 * (interpolated over log bytes, or said not to be), issue 30's criterion, and
 * the ahead-0 series in the bytes figure.
 * Needs python3 and gnuplot (scripts/install-deps). Runs from the repository
 * root, like every test. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "ms_test.h"

/* One point of a meshstudy report at key 8. */
#define POINT(tol, tris, geometry, apo, h_px, psnr, psnr_apo)                                   \
    "{\"key\": 8, \"time\": 8, \"tolerance_px\": " #tol ", \"triangles\": " #tris                  \
    ", \"bytes\": {\"index\": 100, \"geometry\": " #geometry ", \"apo\": " #apo "},"                \
    " \"geometric\": {\"hausdorff_px\": " #h_px ", \"rms_px\": 0.1, \"hausdorff\": 0.001},"        \
    " \"image\": {\"psnr_db\": " #psnr ", \"normal_mean_deg\": 5},"                                \
    " \"image_apo\": {\"psnr_db\": " #psnr_apo ", \"normal_mean_deg\": 4}, \"seconds\": {\"cut\": 0.5}}"

#define STUDY_META "\"width\": 320, \"height\": 240, \"spacing\": 0.0025, \"mesh_triangles\": 871414, "

/* meshview's --json report of a held key. */
#define FRAMES(tris, apo, p50, p95)                                                                \
    "{\"complete\": true, \"keyframes\": [{\"triangles_drawn\": " #tris                            \
    ", \"geometry_bytes\": 1, \"apo_bytes\": " #apo "}], \"frames\": {\"frames\": 28,"             \
    " \"frame_ms_p50\": " #p50 ", \"frame_ms_p95\": " #p95 "}}"

#define WHOLE                                                                                      \
    "{\"points\": [{\"triangles\": 2000, \"geometric\": {\"hausdorff_px\": 0.1, \"rms_px\": 0.01," \
    " \"hausdorff\": 0.0001}, \"image\": {\"psnr_db\": null, \"normal_mean_deg\": 0}}]}"

static const char *const FIXTURE[][2] = {
    {"study-dragon-0.2-k1.json",
     "{" STUDY_META "\"points\": [" POINT(1, 1000, 2000, 0, 0.5, 32, 31) ", "
     POINT(4, 400, 800, 300, 2, 25, 28) "]}"},
    {"study-dragon-0.2-k4.json", "{" STUDY_META "\"points\": [" POINT(1, 500, 1000, 600, 1.5, 26, 33) "]}"},
    {"bake-dragon-0.2.json",
     "{\"geometry_bytes\": 3000, \"apo\": {\"bytes\": 1500}, \"seconds\": {\"total\": 2, \"apo\": 1}}"},
    {"bake-dragon-noapo.json", "{\"geometry_bytes\": 3000, \"seconds\": {\"total\": 1}}"},
    {"codec-16.json", "{\"bytes\": 5000, \"decode_seconds\": 0.2}"},
    {"draco-16.json", "{\"bytes\": 4000, \"decode_seconds\": 0.1}"},
    {"whole-ours-16.json", WHOLE},
    {"whole-draco-16.json", WHOLE},
    {"frame-dragon-meta.json", "{\"renderer\": \"llvmpipe (fixture)\", \"frames_between\": 24, \"repeats\": 2}"},
    {"frame-dragon-geo-key8-1-r1.json", FRAMES(1000, 0, 50, 60)},
    {"frame-dragon-geo-key8-1-r2.json", FRAMES(1000, 0, 70, 90)},
    {"frame-dragon-geo-key8-4-r1.json", FRAMES(400, 0, 30, 35)},
    {"frame-dragon-geo-key8-4-r2.json", FRAMES(400, 0, 20, 30)},
    {"frame-dragon-apo-key8-1-r1.json", FRAMES(1000, 0, 52, 61)},
    {"frame-dragon-apo-key8-4-r1.json", FRAMES(500, 600, 25, 35)},
    /* meshview at 32 px, where the study made no cut: frame time without an image error */
    {"frame-dragon-geo-key8-32-r1.json", FRAMES(100, 0, 10, 12)},
};

/* One point of a geometry-ahead report (no APO) at key 8: index 100 B. */
#define APOINT(tol, tris, geometry, psnr, psnr_smooth)                                             \
    "{\"key\": 8, \"tolerance_px\": " #tol ", \"triangles\": " #tris                               \
    ", \"bytes\": {\"index\": 100, \"geometry\": " #geometry ", \"apo\": 0},"                       \
    " \"geometric\": {\"hausdorff_px\": 1.5, \"rms_px\": 0.2, \"hausdorff\": 0.002, \"rms\": 0.0002}," \
    " \"image\": {\"psnr_db\": " #psnr ", \"ssim\": 0.5, \"normal_mean_deg\": 5},"                  \
    " \"image_smooth\": {\"psnr_db\": " #psnr_smooth ", \"ssim\": 0.8, \"normal_mean_deg\": 2},"     \
    " \"seconds\": {\"cut\": 0.5}}"

static const char *const AHEAD_FIXTURE[][2] = {
    {"ahead-meta.json", "{\"default\": 3}"},
    {"bake-dragon-noapo-a0.json", "{\"geometry_bytes\": 2900, \"seconds\": {\"total\": 1}}"},
    {"ahead-dragon-a0.json", "{\"points\": [" APOINT(4, 4000, 2000, 22, 26) ", " APOINT(8, 2000, 1000, 20, 24) ", "
                             APOINT(16, 1000, 500, 18, 22) "]}"},
    {"ahead-dragon-a3.json", "{\"points\": [" APOINT(4, 4000, 2600, 24, 28) ", " APOINT(8, 2000, 1100, 21.5, 25.6) ", "
                             APOINT(16, 1000, 600, 19, 23) "]}"},
};

/* The file as a NUL-terminated string (the caller frees it). */
static char *read_text(const char *path)
{
    size_t size = 0;
    unsigned char *data = ms_test_read_file(path, &size);
    char *text = realloc(data, size + 1);
    assert_non_null(text);
    text[size] = '\0';
    return text;
}

/* The fixture's study reports into dir/json (made here); meshview's frame-time
 * reports (frame-*) only with frame_times. */
static void write_study_json(const char *dir, bool frame_times)
{
    char path[512];
    snprintf(path, sizeof path, "%s/json", dir);
    assert_int_equal(mkdir(path, 0755), 0);
    for (size_t i = 0; i < sizeof FIXTURE / sizeof *FIXTURE; ++i) {
        if (!frame_times && strncmp(FIXTURE[i][0], "frame-", 6) == 0)
            continue;
        snprintf(path, sizeof path, "%s/json/%s", dir, FIXTURE[i][0]);
        ms_test_write_file(path, FIXTURE[i][1], strlen(FIXTURE[i][1]));
    }
}

static void test_frame_time_table(void **state)
{
    (void)state;
    char dir[256], path[512], cmd[1400], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    write_study_json(dir, true);
    snprintf(path, sizeof path, "%s/ACCURACY.md", dir);
    const char *kept = "# Accuracy\n\nWritten by hand.\n";
    ms_test_write_file(path, kept, strlen(kept));
    snprintf(cmd, sizeof cmd, "python3 scripts/study-report.py %s/json %s/ACCURACY.md %s/images", dir, dir,
             dir);
    /* (gnuplot warns of the one-point precision figure's empty x range) */
    if (ms_test_run(cmd, out, sizeof out) != 0)
        fail_msg("%s failed: %s", cmd, out);

    char *md = read_text(path);
    assert_non_null(md);
    assert_true(strncmp(md, kept, strlen(kept)) == 0); /* the hand-written part stays */
    const char *rows[] = {
        "**These are not GPU figures.** OpenGL here is llvmpipe (fixture): Mesa's software rasteriser",
        "of the fastest (by p50) of 2 runs of each point.",
        "Key 8:\n\n| tol px | geometry alone: triangles | frame p50 / p95 ms | PSNR | h px | "
        "geometry + APO: triangles | APO B | frame p50 / p95 ms | PSNR with APO |\n"
        "|---|---|---|---|---|---|---|---|---|\n"
        /* the fastest repeats; APO at 1 px is the K = 1 cut, at 4 px the K = 4 run's 1 px cut */
        "| 1 | 1,000 | 50.0 / 60.0 | 32.0 | 0.50 | 1,000 | 0 | 52.0 / 61.0 | 31.0 |\n"
        "| 4 | 400 | 20.0 / 30.0 | 25.0 | 2.00 | 500 | 600 | 25.0 / 35.0 | 33.0 |\n"
        "| 32 | 100 | 10.0 / 12.0 | – | – | not run | – | – | – |\n\n",
        "- Key 8, geometry + APO at 1 px: 31.0 dB with 1,000 triangles in 52.0 ms (p50); geometry alone "
        "reaches at least that at 1 px (32.0 dB) with 1,000 triangles in 50.0 ms.\n"
        "- Key 8, geometry + APO at 4 px: 33.0 dB with 500 triangles in 25.0 ms (p50); geometry alone does "
        "not reach it at any tolerance swept (at best 32.0 dB).\n\n"
        "meshview drew the same number of triangles as the study's cut at 4 of the 4 joined points.\n",
        "![frame time against image error (Mesa llvmpipe, not a GPU)](images/study-frame-time.png)\n",
    };
    for (size_t i = 0; i < sizeof rows / sizeof *rows; ++i)
        if (!strstr(md, rows[i]))
            fail_msg("ACCURACY.md lacks:\n%s\n--- it has:\n%s", rows[i], md);
    free(md);
    struct stat st;
    snprintf(path, sizeof path, "%s/images/study-frame-time.png", dir);
    assert_int_equal(stat(path, &st), 0);
    assert_true(st.st_size > 1000);
    ms_test_rmdir(dir);
}

/* The geometry-ahead section. Ahead 3 against ahead 0 at key 8: at 4 px
 * 2,600 B lies above ahead 0's dearest point (2,000 B), so nothing is
 * interpolated; at 8 px 1,100 B lies between ahead 0's 1,000 B (24 dB smooth)
 * and 2,000 B (26 dB): 24 + 2 ln(1.1) / ln 2 = 24.275 against 25.6, +1.32
 * (flat +1.22); with the index, 1,200 B between 1,100 and 2,100 B:
 * 24 + 2 ln(12/11) / ln(21/11) = 24.269, +1.33; at 16 px 600 B between 500 and
 * 1,000 B: +0.47 (with the index, 700 B between 600 and 1,100 B: +0.49). The
 * criterion (+1.5 dB at <= 1.15x the geometry bytes, smooth, same tolerance)
 * is met at 8 px (+1.60 at 1.10x), not at 16 px (+1.00 at 1.20x). */
static void test_ahead_section(void **state)
{
    (void)state;
    char dir[256], path[512], cmd[1400], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    write_study_json(dir, false);
    for (size_t i = 0; i < sizeof AHEAD_FIXTURE / sizeof *AHEAD_FIXTURE; ++i) {
        snprintf(path, sizeof path, "%s/json/%s", dir, AHEAD_FIXTURE[i][0]);
        ms_test_write_file(path, AHEAD_FIXTURE[i][1], strlen(AHEAD_FIXTURE[i][1]));
    }
    snprintf(cmd, sizeof cmd, "python3 scripts/study-report.py %s/json %s/ACCURACY.md %s/images", dir, dir,
             dir);
    if (ms_test_run(cmd, out, sizeof out) != 0)
        fail_msg("%s failed: %s", cmd, out);
    snprintf(path, sizeof path, "%s/ACCURACY.md", dir);
    char *md = read_text(path);
    assert_non_null(md);
    const char *rows[] = {
        "| no APO (ahead 3, the default) | 3,000 | 0 | 0 | 1.0 | 0 |\n| no APO, ahead 0 | 2,900 | 0 | 0 | 1.0 | 0 |\n",
        "Geometry of the whole model: dragon ahead 0: 2,900 B; dragon ahead 3: 3,000 B.",
        "Dragon, key 8 (close-up):\n\n"
        "| tol px | ahead | triangles | geometry B | index + geometry B | Hausdorff / px | RMS / px | "
        "PSNR flat / smooth | SSIM flat / smooth |\n|---|---|---|---|---|---|---|---|---|\n"
        "| 4 | 0 | 4,000 | 2,000 | 2,100 | 0.002 / 1.50 | 0.0002 / 0.200 | 22.00 / 26.00 | 0.500 / 0.800 |\n"
        "| 4 | 3 | 4,000 | 2,600 | 2,700 | 0.002 / 1.50 | 0.0002 / 0.200 | 24.00 / 28.00 | 0.500 / 0.800 |\n",
        "| tol px | geometry B ratio | index + geometry B ratio | ΔPSNR same tol, flat / smooth | "
        "ΔPSNR equal geometry B, flat / smooth | ΔPSNR equal index + geometry B, smooth |\n"
        "|---|---|---|---|---|---|\n"
        "| 4 | 1.30 | 1.286 | +2.00 / +2.00 | – / – | – |\n"
        "| 8 | 1.10 | 1.091 | +1.50 / +1.60 | +1.22 / +1.32 | +1.33 |\n"
        "| 16 | 1.20 | 1.167 | +1.00 / +1.00 | +0.47 / +0.47 | +0.49 |\n\n"
        "- 4 px, geometry bytes 2,600: not interpolated, above its dearest point (2,000 B) of ahead 0.\n"
        "- 4 px, index + geometry bytes 2,700: not interpolated, above its dearest point (2,100 B) of ahead 0.\n",
        "- Key 8, 8 px: smooth +1.60 dB (flat +1.50) at 1.10x the geometry bytes (1,000 -> 1,100 B; 1.091x with "
        "the index); at equal geometry bytes +1.32 dB smooth, +1.22 flat: criterion (>= +1.5 dB at <= 1.15x) met.\n"
        "- Key 8, 16 px: smooth +1.00 dB (flat +1.00) at 1.20x the geometry bytes (500 -> 600 B; 1.167x with the "
        "index); at equal geometry bytes +0.47 dB smooth, +0.47 flat: criterion (>= +1.5 dB at <= 1.15x) not met "
        "(gain and bytes).\n",
    };
    for (size_t i = 0; i < sizeof rows / sizeof *rows; ++i)
        if (!strstr(md, rows[i]))
            fail_msg("ACCURACY.md lacks:\n%s\n--- it has:\n%s", rows[i], md);
    free(md);
    /* the bytes figure's third series: ahead 0 drawn smooth (index + geometry B, decode s, PSNR, h px) */
    snprintf(path, sizeof path, "%s/json/plot/s2.dat", dir);
    char *dat = read_text(path);
    assert_string_equal(dat, "2100 0.5 26 1.5\n1100 0.5 24 1.5\n600 0.5 22 1.5\n");
    free(dat);
    ms_test_rmdir(dir);
}

/* Without meshview's reports the report has no frame-time section and no figure. */
static void test_no_frame_time_without_meshview(void **state)
{
    (void)state;
    char dir[256], path[512], cmd[1400], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    write_study_json(dir, false);
    snprintf(cmd, sizeof cmd, "python3 scripts/study-report.py %s/json %s/ACCURACY.md %s/images", dir, dir,
             dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(path, sizeof path, "%s/ACCURACY.md", dir);
    char *md = read_text(path);
    assert_non_null(md);
    assert_non_null(strstr(md, "### Headline"));
    assert_null(strstr(md, "Frame time"));
    assert_null(strstr(md, "study-frame-time.png"));
    assert_null(strstr(md, "### Geometry ahead")); /* no ahead-* reports */
    free(md);
    struct stat st;
    snprintf(path, sizeof path, "%s/images/study-frame-time.png", dir);
    assert_int_equal(stat(path, &st), -1);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frame_time_table),
        cmocka_unit_test(test_no_frame_time_without_meshview),
        cmocka_unit_test(test_ahead_section),
    };
    return cmocka_run_group_tests_name("study_report", tests, NULL, NULL);
}
