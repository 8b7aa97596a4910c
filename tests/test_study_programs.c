/* meshrender and meshstudy as programs: usage and input errors give 2 and 1; a
 * mesh renders to one PNG per keyframe; an archive's cut renders with and
 * without APO; the small study (one model, one keyframe, three tolerances) gives
 * three points whose bytes and errors move the way the tolerance says; the
 * coloured trefoil renders with its colours, lit and --albedo, the pictures
 * those of the renderer in process. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <jansson.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "ms_camera_path.h"
#include "ms_mesh_io.h"
#include "ms_study_render.h"
#include "ms_test.h"
#include "ms_test_picture.h"

typedef struct fixture {
    char dir[512], model[600], mesh[700], archive[700], path[700];
    char render[512], study[512];
} fixture;

/* The small dragon (11 k triangles), unpacked, and baked with APO. */
static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    assert_non_null(f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    ms_test_model_path(f->model, sizeof f->model, "stanford_dragon_vrip_res4.ply.gz");
    snprintf(f->mesh, sizeof f->mesh, "%s/dragon.ply.gz", f->dir);
    size_t size;
    unsigned char *data = ms_test_read_file(f->model, &size);
    ms_test_write_file(f->mesh, data, size);
    free(data);
    snprintf(f->archive, sizeof f->archive, "%s/a/dragon.msa", f->dir);
    snprintf(f->path, sizeof f->path, "scripts/paths/dragon-closeup.cam");
    ms_test_bin_path(f->render, sizeof f->render, "meshrender");
    ms_test_bin_path(f->study, sizeof f->study, "meshstudy");
    char bin[512], cmd[4096], out[4096];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s %s -o %s/a --name dragon --threads 2 --json", bin, f->mesh, f->dir);
    if (ms_test_run(cmd, out, sizeof out) != 0)
        fail_msg("meshbake: %s", out);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

static void test_exit_codes(void **state)
{
    fixture *f = *state;
    char cmd[4096], out[8192];
    const char *bins[2] = {f->render, f->study};
    for (int b = 0; b < 2; ++b) {
        snprintf(cmd, sizeof cmd, "%s --help", bins[b]);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
        assert_non_null(strstr(out, "usage:"));
        snprintf(cmd, sizeof cmd, "%s", bins[b]);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
        snprintf(cmd, sizeof cmd, "%s --bogus", bins[b]);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    }
    snprintf(cmd, sizeof cmd, "%s %s -p %s -o %s/r --width 0", f->render, f->mesh, f->path, f->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s %s -p %s -o %s/r --apo", f->render, f->mesh, f->path, f->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2); /* APO needs an archive */
    snprintf(cmd, sizeof cmd, "%s %s/missing.ply -p %s -o %s/r", f->render, f->dir, f->path, f->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(cmd, sizeof cmd, "%s %s -p %s/missing.cam -o %s/r", f->render, f->mesh, f->dir, f->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(cmd, sizeof cmd, "%s %s %s -p %s --keys 9", f->study, f->mesh, f->archive, f->path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1); /* the path has keys 0..8 */
    snprintf(cmd, sizeof cmd, "%s %s %s -p %s --apo-filter trilinear", f->study, f->mesh, f->archive, f->path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "--apo-filter wants linear, nearest or none, not 'trilinear'"));
    snprintf(cmd, sizeof cmd, "%s %s -p %s -o %s/r --apo --apo-filter Linear", f->render, f->archive, f->path, f->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s %s %s -p %s --tolerances 1,-2", f->study, f->mesh, f->archive, f->path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
}

static void test_meshrender(void **state)
{
    fixture *f = *state;
    char cmd[4096], file[900];
    snprintf(cmd, sizeof cmd, "%s %s -p %s -o %s/mesh --width 64 --height 48 --normals --json", f->render, f->mesh,
             f->path, f->dir);
    json_t *root = ms_test_run_json(cmd, 0);
    json_t *frames = json_object_get(root, "frames");
    assert_int_equal(json_array_size(frames), 9);
    for (size_t k = 0; k < 9; ++k) {
        json_t *fr = json_array_get(frames, k);
        assert_int_equal(json_integer_value(json_object_get(fr, "triangles")), 11102);
        assert_true(json_integer_value(json_object_get(fr, "pixels_covered")) > 0);
        assert_true(json_is_false(json_object_get(fr, "coloured")));
        struct stat st;
        snprintf(file, sizeof file, "%s/mesh/frame_%03zu.png", f->dir, k);
        assert_int_equal(stat(file, &st), 0);
        snprintf(file, sizeof file, "%s/mesh/normals_%03zu.png", f->dir, k);
        assert_int_equal(stat(file, &st), 0);
    }
    /* the close-up fills more of the frame as it nears */
    assert_true(json_integer_value(json_object_get(json_array_get(frames, 8), "pixels_covered")) >
                json_integer_value(json_object_get(json_array_get(frames, 0), "pixels_covered")));
    json_decref(root);
    /* the archive's cut, with APO: the same silhouette region, a cut's bytes */
    snprintf(cmd, sizeof cmd, "%s %s -p %s -o %s/cut --width 64 --height 48 --tolerance 4 --apo --json", f->render,
             f->archive, f->path, f->dir);
    root = ms_test_run_json(cmd, 0);
    frames = json_object_get(root, "frames");
    assert_int_equal(json_array_size(frames), 9);
    json_t *cut = json_object_get(json_array_get(frames, 0), "cut");
    assert_true(json_integer_value(json_object_get(cut, "geometry_bytes")) > 0);
    assert_true(json_integer_value(json_object_get(cut, "apo_bytes")) > 0);
    assert_true(json_integer_value(json_object_get(cut, "index_bytes")) > 0);
    json_decref(root);
}

/* The coloured trefoil through meshrender, lit and --albedo: the PNGs are the
 * in-process renders of the mesh with its colours at the path's camera. */
static void test_meshrender_colour(void **state)
{
    fixture *f = *state;
    char model[600], cam[700], cmd[4096], file[900];
    ms_test_model_path(model, sizeof model, "trefoil_color.ply.gz");
    snprintf(cam, sizeof cam, "%s/trefoil.cam", f->dir);
    const char *text = "meshstream-camera-path 1\n0  0.5 0.2 0.8  0 -0.028 0  0 1 0  35\n";
    ms_test_write_file(cam, text, strlen(text));
    ms_mesh mesh = {0};
    ms_study_scene *scene;
    ms_camera_path path = {0};
    ms_camera camera;
    ms_error err;
    double lo[3], hi[3];
    assert_int_equal(ms_mesh_load(model, &mesh, NULL, &err), MS_OK);
    assert_int_equal(ms_study_scene_new(mesh.positions, mesh.vertex_count, mesh.triangles, mesh.triangle_count,
                                        &scene, &err),
                     MS_OK);
    ms_study_scene_bounds(scene, lo, hi);
    assert_int_equal(ms_camera_path_load(cam, &path, &err), MS_OK);
    assert_int_equal(ms_study_key_camera(&path, 0, 96, 72, 0, 0, lo, hi, &camera, &err), MS_OK);
    for (int albedo = 0; albedo < 2; ++albedo) {
        snprintf(cmd, sizeof cmd, "%s %s -p %s -o %s/colour%d --width 96 --height 72 --smooth %s --json", f->render,
                 model, cam, f->dir, albedo, albedo ? "--albedo" : "");
        json_t *root = ms_test_run_json(cmd, 0);
        assert_true(json_is_true(json_object_get(json_array_get(json_object_get(root, "frames"), 0), "coloured")));
        json_decref(root);
        snprintf(file, sizeof file, "%s/colour%d/frame_000.png", f->dir, albedo);
        uint32_t w, h;
        uint8_t *png = ms_test_png_read(file, &w, &h);
        assert_true(w == 96 && h == 72);
        ms_study_image im = {0};
        ms_study_render_options o = {.colours = mesh.colours, .albedo = albedo != 0, .smooth = true};
        assert_int_equal(ms_study_render(scene, &camera, &o, &im, &err), MS_OK);
        assert_memory_equal(png, im.rgb, 3 * 96 * 72);
        /* in colour: a covered pixel whose channels differ */
        size_t coloured = 0;
        for (size_t p = 0; p < 96 * 72; ++p)
            coloured += png[3 * p] != png[3 * p + 1] || png[3 * p + 1] != png[3 * p + 2];
        assert_true(coloured > 500);
        free(png);
        ms_study_image_free(&im);
    }
    ms_camera_path_free(&path);
    ms_study_scene_free(scene);
    ms_mesh_free(&mesh);
}

static double number(json_t *obj, const char *a, const char *b)
{
    json_t *v = json_object_get(b ? json_object_get(obj, a) : obj, b ? b : a);
    if (!json_is_number(v))
        fail_msg("%s.%s is not a number", a, b ? b : "");
    return json_number_value(v);
}

/* The small study of `make test`: one model, three points. */
static void test_small_study(void **state)
{
    fixture *f = *state;
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s %s %s -p %s --keys 0 --tolerances 1,4,16 --width 80 --height 60 --spacing 0.004 --json",
             f->study, f->mesh, f->archive, f->path);
    json_t *root = ms_test_run_json(cmd, 0);
    assert_true(json_is_true(json_object_get(root, "apo")));
    assert_int_equal(json_integer_value(json_object_get(root, "mesh_triangles")), 11102);
    json_t *points = json_object_get(root, "points");
    assert_int_equal(json_array_size(points), 3);
    double prev_geometry = INFINITY, prev_tris = INFINITY, prev_psnr = INFINITY;
    for (size_t i = 0; i < 3; ++i) {
        json_t *p = json_array_get(points, i);
        double geometry = number(p, "bytes", "geometry"), tris = number(p, "triangles", NULL);
        double psnr = number(p, "image", "psnr_db"), h = number(p, "geometric", "hausdorff");
        print_message("%g px: %g B geometry, %g B APO, %g triangles, Hausdorff %g (%g px), normal %g deg (APO %g), "
                      "PSNR %g (APO %g)\n",
                      number(p, "tolerance_px", NULL), geometry, number(p, "bytes", "apo"), tris, h,
                      number(p, "geometric", "hausdorff_px"), number(p, "image", "normal_mean_deg"),
                      number(p, "image_apo", "normal_mean_deg"), psnr, number(p, "image_apo", "psnr_db"));
        /* a coarser tolerance never needs more bytes or triangles, nor draws better */
        assert_true(geometry > 0 && geometry <= prev_geometry);
        assert_true(tris > 0 && tris <= prev_tris);
        assert_true(psnr > 10 && psnr <= prev_psnr);
        assert_true(h > 0 && h < 0.05); /* the dragon is about 0.2 units across */
        assert_true(number(p, "geometric", "rms") <= h);
        assert_true(number(p, "image", "ssim") > 0 && number(p, "image", "ssim") < 1);
        assert_true(number(p, "image_apo", "normal_mean_deg") > 0);
        assert_true(number(p, "bytes", "index") > 0);
        assert_true(number(p, "bytes", "index") == number(json_array_get(points, 0), "bytes", "index"));
        assert_true(number(p, "seconds", "cut") > 0); /* a fresh view's selection, decoding and stitching */
        assert_true(number(p, "geometric", "samples_in_view") <= number(p, "geometric", "samples"));
        assert_true(number(p, "image", "compared_px") > 0);
        /* drawn smooth: the same cut, so the same pixels covered */
        assert_true(number(p, "image_smooth", "compared_px") == number(p, "image", "compared_px"));
        assert_true(number(p, "image_smooth", "silhouette_px") == number(p, "image", "silhouette_px"));
        assert_true(number(p, "image_smooth", "ssim") > 0 && number(p, "image_smooth", "ssim") < 1);
        prev_geometry = geometry;
        prev_tris = tris;
        prev_psnr = psnr;
    }
    /* 16 px is a real coarsening: fewer bytes than at 1 px */
    assert_true(number(json_array_get(points, 2), "bytes", "geometry") <
                number(json_array_get(points, 0), "bytes", "geometry"));
    /* APO read to 2 levels: the same cut and geometry, fewer APO bytes; 0 levels
     * means whole chunks */
    double whole_apo = number(json_array_get(points, 1), "bytes", "apo");
    double whole_geometry = number(json_array_get(points, 1), "bytes", "geometry");
    json_decref(root);
    const char *levels[3] = {"0", "2", "footprint"};
    for (int i = 0; i < 3; ++i) {
        snprintf(cmd, sizeof cmd,
                 "%s %s %s -p %s --keys 0 --tolerances 4 --width 80 --height 60 --spacing 0.004 --apo-levels %s --json",
                 f->study, f->mesh, f->archive, f->path, levels[i]);
        root = ms_test_run_json(cmd, 0);
        json_t *p = json_array_get(json_object_get(root, "points"), 0);
        assert_true(number(p, "bytes", "geometry") == whole_geometry);
        if (i == 0)
            assert_true(number(p, "bytes", "apo") == whole_apo);
        else /* at 80 x 60 pixels even the footprint rule stops short of the whole chunks */
            assert_true(number(p, "bytes", "apo") > 0 && number(p, "bytes", "apo") < whole_apo);
        json_decref(root);
    }
    /* the APO lookup: the client's filter by default; unfiltered, the same cut
     * and bytes with other normals */
    double mean_deg[2];
    const char *filters[2] = {"linear", "none"};
    for (int i = 0; i < 2; ++i) {
        snprintf(cmd, sizeof cmd,
                 "%s %s %s -p %s --keys 0 --tolerances 4 --width 80 --height 60 --spacing 0.004%s%s --json",
                 f->study, f->mesh, f->archive, f->path, i ? " --apo-filter " : "", i ? filters[i] : "");
        root = ms_test_run_json(cmd, 0);
        assert_string_equal(json_string_value(json_object_get(root, "apo_filter")), filters[i]);
        json_t *p = json_array_get(json_object_get(root, "points"), 0);
        assert_true(number(p, "bytes", "geometry") == whole_geometry && number(p, "bytes", "apo") == whole_apo);
        mean_deg[i] = number(p, "image_apo", "normal_mean_deg");
        json_decref(root);
    }
    print_message("4 px, APO normal error: filtered %.3f deg, nearest leaf %.3f deg\n", mean_deg[0], mean_deg[1]);
    assert_true(mean_deg[0] != mean_deg[1]);
}

/* The whole model against itself (meshstudy --whole): every image error
 * exactly nothing and the distances nothing to rounding, at two keyframes; the
 * report's fields as documented. */
static void test_whole_against_itself(void **state)
{
    fixture *f = *state;
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s %s --whole %s -p %s --keys 0,8 --width 64 --height 48 --spacing 0.004 --json",
             f->study, f->mesh, f->mesh, f->path);
    json_t *root = ms_test_run_json(cmd, 0);
    assert_false(json_is_true(json_object_get(root, "apo")));
    assert_string_equal(json_string_value(json_object_get(root, "archive")), f->mesh);
    json_t *points = json_object_get(root, "points");
    assert_int_equal(json_array_size(points), 2);
    for (size_t i = 0; i < 2; ++i) {
        json_t *p = json_array_get(points, i);
        assert_true(number(p, "key", NULL) == (i ? 8 : 0));
        assert_true(number(p, "tolerance_px", NULL) == 0);
        assert_true(number(p, "triangles", NULL) == 11102);
        assert_true(number(p, "bytes", "index") == 0 && number(p, "bytes", "geometry") == 0 &&
                    number(p, "bytes", "apo") == 0);
        /* zero to the rounding of a sample point computed in doubles (a
         * sub-triangle centroid lies on its own plane to about 1e-17 here) */
        assert_true(number(p, "geometric", "hausdorff") < 1e-15 && number(p, "geometric", "rms") < 1e-15);
        assert_true(number(p, "geometric", "hausdorff_px") < 1e-9 && number(p, "geometric", "rms_px") < 1e-9);
        assert_true(number(p, "geometric", "samples_in_view") > 0);
        json_t *image = json_object_get(p, "image");
        assert_true(json_is_null(json_object_get(image, "psnr_db"))); /* identical: +infinity */
        assert_true(number(image, "ssim", NULL) == 1);
        assert_true(number(image, "silhouette_px", NULL) == 0);
        assert_true(number(image, "normal_max_deg", NULL) == 0);
        assert_true(number(image, "compared_px", NULL) > 0);
        assert_null(json_object_get(p, "image_apo"));
        /* drawn smooth against the flat reference: the same pixels, other normals */
        assert_true(number(p, "image_smooth", "silhouette_px") == 0);
        assert_true(number(p, "image_smooth", "normal_max_deg") > 0);
    }
    json_decref(root);
    /* an archive and --whole together is a usage error */
    char out[4096];
    snprintf(cmd, sizeof cmd, "%s %s %s --whole %s -p %s", f->study, f->mesh, f->archive, f->mesh, f->path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_exit_codes),
        cmocka_unit_test(test_meshrender),
        cmocka_unit_test(test_meshrender_colour),
        cmocka_unit_test(test_small_study),
        cmocka_unit_test(test_whole_against_itself),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
