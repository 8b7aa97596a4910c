/* Scene files (ms_scene.h): every kind of bad input gives its exact one-line
 * error (bad JSON, unknown keys, wrong types, out-of-range values, missing
 * fields, a model not in the catalogue); the shipped gallery loads with its
 * camera path; the effects a scene calls for follow its materials, haze, room
 * and sizes; a model's placement puts the bottom of its bounds where asked, at
 * the asked height. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_camera_path.h"
#include "ms_scene.h"
#include "ms_test.h"

#define assert_near(a, b, eps) assert_true(fabs((double)(a) - (double)(b)) <= (eps))

/* A minimal valid scene around the given extra members (a JSON fragment that
 * starts with a comma, or ""), and the given model entry. */
static ms_status parse_with(const char *model, const char *extra, ms_scene *s, ms_error *err)
{
    char text[4096];
    snprintf(text, sizeof text, "{\"scene\": 1, \"models\": [%s]%s}", model, extra);
    return ms_scene_parse(text, strlen(text), "t.json", "/scenes", s, err);
}

#define GOOD_MODEL "{\"model\": \"bunny\", \"position\": [0, 1, 0]}"

typedef struct bad_case {
    const char *model, *extra;
    ms_status code;
    const char *message;
} bad_case;

static const bad_case bad_cases[] = {
    /* structure */
    {GOOD_MODEL, ", \"colour\": 1", MS_ERR_FORMAT, "scene t.json: unknown key \"colour\""},
    {GOOD_MODEL, ", \"models\": []", MS_ERR_FORMAT,
     "scene t.json: line 1, column 76: duplicate object key near '\"models\"'"},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"scale\": 2}", "", MS_ERR_FORMAT,
     "scene t.json: models[0]: unknown key \"scale\""},
    {"{\"position\": [0, 1, 0]}", "", MS_ERR_FORMAT, "scene t.json: models[0]: missing \"model\""},
    {"{\"model\": \"bunny\"}", "", MS_ERR_FORMAT, "scene t.json: models[0]: missing \"position\""},
    {"{\"model\": \"../etc\", \"position\": [0, 1, 0]}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].model: expected a model name (1 to 64 of A-Z a-z 0-9 _ -)"},
    /* types */
    {"{\"model\": \"bunny\", \"position\": \"here\"}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].position: expected an array of 3 numbers"},
    {"{\"model\": \"bunny\", \"position\": [0, 1]}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].position: expected an array of 3 numbers"},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"height\": \"tall\"}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].height: expected a number"},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"up\": \"w\"}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].up: expected \"x\", \"y\" or \"z\""},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"material\": {\"type\": \"metal\"}}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].material.type: expected \"diffuse\" or \"glossy\""},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"material\": {\"two_sided\": 1}}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].material.two_sided: expected true or false"},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"material\": {\"shininess\": 20}}", "", MS_ERR_FORMAT,
     "scene t.json: models[0].material: specular and shininess need \"type\": \"glossy\""},
    {GOOD_MODEL, ", \"lights\": {}", MS_ERR_FORMAT, "scene t.json: lights: expected an array"},
    {GOOD_MODEL, ", \"effects\": {\"haze\": \"no\"}", MS_ERR_FORMAT,
     "scene t.json: effects.haze: expected true or false"},
    {GOOD_MODEL, ", \"effects\": {\"shadows\": true}", MS_ERR_FORMAT,
     "scene t.json: effects: unknown key \"shadows\""},
    {GOOD_MODEL, ", \"room\": {\"size\": [4, 3, 4], \"plinths\": [{\"position\": [0, 0], \"size\": 1}]}",
     MS_ERR_FORMAT, "scene t.json: room.plinths[0].size: expected an array of 3 numbers"},
    {GOOD_MODEL, ", \"room\": {\"size\": [4, 3, 4], \"floor\": {\"displacement\": {\"seed\": 1.5}}}",
     MS_ERR_FORMAT, "scene t.json: room.floor.displacement.seed: expected an integer"},
    {GOOD_MODEL, ", \"camera_path\": 3", MS_ERR_FORMAT, "scene t.json: camera_path: expected a file name"},
    /* a scene reaches only files inside its folder (issue 32, item 7) */
    {GOOD_MODEL, ", \"camera_path\": \"/etc/passwd\"", MS_ERR_FORMAT,
     "scene t.json: camera_path: must name a file inside the scene's folder (no absolute path, "
     "no '..'; give another path with --path)"},
    {GOOD_MODEL, ", \"camera_path\": \"../other/walk.cam\"", MS_ERR_FORMAT,
     "scene t.json: camera_path: must name a file inside the scene's folder (no absolute path, "
     "no '..'; give another path with --path)"},
    {GOOD_MODEL, ", \"camera_path\": \"paths/../../walk.cam\"", MS_ERR_FORMAT,
     "scene t.json: camera_path: must name a file inside the scene's folder (no absolute path, "
     "no '..'; give another path with --path)"},
    {GOOD_MODEL, ", \"camera_path\": \"..\"", MS_ERR_FORMAT,
     "scene t.json: camera_path: must name a file inside the scene's folder (no absolute path, "
     "no '..'; give another path with --path)"},
    /* ranges */
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"material\": {\"type\": \"glossy\", \"shininess\": 0}}",
     "", MS_ERR_RANGE, "scene t.json: models[0].material.shininess: 0 out of range [1, 1000]"},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"height\": 0}", "", MS_ERR_RANGE,
     "scene t.json: models[0].height: 0 out of range (0, 100]"},
    {"{\"model\": \"bunny\", \"position\": [0, 1, 0], \"material\": {\"albedo\": [0.5, 1.5, 0]}}", "",
     MS_ERR_RANGE, "scene t.json: models[0].material.albedo: 1.5 out of range [0, 1]"},
    {GOOD_MODEL, ", \"haze\": {\"density\": 11}", MS_ERR_RANGE,
     "scene t.json: haze.density: 11 out of range [0, 10]"},
    {GOOD_MODEL, ", \"room\": {\"size\": [4, -3, 4]}", MS_ERR_RANGE,
     "scene t.json: room.size: -3 out of range [0, 1000]"},
    {GOOD_MODEL, ", \"room\": {\"size\": [4, 0, 4]}", MS_ERR_RANGE,
     "scene t.json: room.size: 0 out of range (0, 1000]"},
    {GOOD_MODEL, ", \"effects\": {\"impostor_threshold_px\": 0.5}", MS_ERR_RANGE,
     "scene t.json: effects.impostor_threshold_px: 0.5 out of range [1, 4096]"},
    {GOOD_MODEL, ", \"lights\": [{\"type\": \"directional\", \"direction\": [0, 0, 0]}]", MS_ERR_RANGE,
     "scene t.json: lights[0].direction: zero vector"},
    /* lights */
    {GOOD_MODEL, ", \"lights\": [{\"type\": \"spot\"}]", MS_ERR_FORMAT,
     "scene t.json: lights[0].type: expected \"head\", \"directional\" or \"point\""},
    {GOOD_MODEL, ", \"lights\": [{\"colour\": [1, 1, 1]}]", MS_ERR_FORMAT,
     "scene t.json: lights[0]: missing \"type\""},
    {GOOD_MODEL, ", \"lights\": [{\"type\": \"head\"}, {\"type\": \"head\"}]", MS_ERR_FORMAT,
     "scene t.json: lights[1]: a second head light"},
    {GOOD_MODEL, ", \"lights\": [{\"type\": \"point\"}]", MS_ERR_FORMAT,
     "scene t.json: lights[0]: missing \"position\""},
    {GOOD_MODEL, ", \"lights\": [{\"type\": \"directional\", \"direction\": [0, 1, 0], \"range\": 3}]",
     MS_ERR_FORMAT, "scene t.json: lights[0]: a directional light takes no position or range"},
    {GOOD_MODEL,
     ", \"lights\": [{\"type\": \"point\", \"position\": [0, 1, 0]}, {\"type\": \"point\", \"position\": [0, 1, 0]},"
     " {\"type\": \"point\", \"position\": [0, 1, 0]}, {\"type\": \"point\", \"position\": [0, 1, 0]},"
     " {\"type\": \"point\", \"position\": [0, 1, 0]}]",
     MS_ERR_RANGE, "scene t.json: lights[4]: more than 4 point lights"},
};

static void test_bad_inputs(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof bad_cases / sizeof bad_cases[0]; ++i) {
        ms_scene s;
        ms_error err;
        ms_status st = parse_with(bad_cases[i].model, bad_cases[i].extra, &s, &err);
        if (st != bad_cases[i].code || strcmp(err.text, bad_cases[i].message) != 0)
            fail_msg("case %zu: got %d \"%s\", expected %d \"%s\"", i, st, err.text, bad_cases[i].code,
                     bad_cases[i].message);
        /* a failed parse leaves nothing to free */
        assert_null(s.models);
        assert_null(s.name);
    }
}

static void test_bad_documents(void **state)
{
    (void)state;
    ms_scene s;
    ms_error err;
    const char *broken = "{\"scene\": 1,\n \"models\": [}";
    assert_int_equal(ms_scene_parse(broken, strlen(broken), "b.json", NULL, &s, &err), MS_ERR_FORMAT);
    assert_string_equal(err.text, "scene b.json: line 2, column 13: unexpected token near '}'");
    assert_int_equal(ms_scene_parse("[]", 2, "a.json", NULL, &s, &err), MS_ERR_FORMAT);
    assert_string_equal(err.text, "scene a.json: expected an object");
    const char *no_version = "{\"models\": []}";
    assert_int_equal(ms_scene_parse(no_version, strlen(no_version), "v.json", NULL, &s, &err), MS_ERR_FORMAT);
    assert_string_equal(err.text, "scene v.json: missing \"scene\" (the format version, 1)");
    const char *v2 = "{\"scene\": 2, \"models\": []}";
    assert_int_equal(ms_scene_parse(v2, strlen(v2), "v.json", NULL, &s, &err), MS_ERR_UNSUPPORTED);
    assert_string_equal(err.text, "scene v.json: scene: version 2, this viewer reads 1");
    const char *empty = "{\"scene\": 1, \"models\": []}";
    assert_int_equal(ms_scene_parse(empty, strlen(empty), "e.json", NULL, &s, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "scene e.json: models: 0 models, 1 to 64");
    assert_int_equal(ms_scene_load("/nonexistent/x.json", &s, &err), MS_ERR_IO);
    assert_string_equal(err.text, "scene /nonexistent/x.json: cannot open: No such file or directory");
}

static void test_missing_model(void **state)
{
    (void)state;
    ms_scene s;
    ms_error err;
    assert_int_equal(parse_with(GOOD_MODEL ", {\"model\": \"armadillo\", \"position\": [1, 1, 0]}", "", &s, &err),
                     MS_OK);
    ms_viewer_model_entry entries[2] = {{.name = "bunny"}, {.name = "dragon"}};
    ms_viewer_model_list list = {.entries = entries, .count = 2};
    assert_int_equal(ms_scene_check_models(&s, "t.json", &list, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "scene t.json: models[1].model: \"armadillo\" is not in the catalogue");
    snprintf(entries[1].name, sizeof entries[1].name, "armadillo");
    assert_int_equal(ms_scene_check_models(&s, "t.json", &list, &err), MS_OK);
    ms_scene_free(&s);
}

static void test_defaults(void **state)
{
    (void)state;
    ms_scene s;
    ms_error err;
    assert_int_equal(parse_with(GOOD_MODEL, ", \"camera_path\": \"walk.cam\"", &s, &err), MS_OK);
    assert_string_equal(s.name, "");
    assert_string_equal(s.camera_path, "/scenes/walk.cam");
    ms_scene_free(&s);
    /* a sub-folder, and a name that merely starts with dots, stay inside */
    assert_int_equal(parse_with(GOOD_MODEL, ", \"camera_path\": \"paths/..walk.cam\"", &s, &err),
                     MS_OK);
    assert_string_equal(s.camera_path, "/scenes/paths/..walk.cam");
    ms_scene_free(&s);
    assert_int_equal(parse_with(GOOD_MODEL, ", \"camera_path\": \"walk.cam\"", &s, &err), MS_OK);
    assert_int_equal(s.model_count, 1);
    assert_int_equal(s.models[0].up_axis, 1);
    assert_near(s.models[0].height, 1.0, 0);
    assert_int_equal(s.models[0].material.kind, MS_MATERIAL_DIFFUSE);
    assert_near(s.models[0].material.specular, 0.0, 0);
    assert_int_equal(s.light_count, 1);
    assert_int_equal(s.lights[0].kind, MS_LIGHT_HEAD);
    assert_false(s.room.on);
    assert_int_equal(s.effects_allowed, MS_EFFECTS_ALL);
    /* no glossy, two-sided, haze, room: only detail normals (and impostors: a
     * 1 m model 20 m away is 43 px at the reference view, under 100) */
    assert_int_equal(ms_scene_effects(&s), MS_EFFECT_DETAIL_NORMALS | MS_EFFECT_IMPOSTORS);
    ms_scene_free(&s);
    ms_scene_free(&s); /* zeroed: a no-op */
}

static void test_effects_called_for(void **state)
{
    (void)state;
    ms_scene s;
    ms_error err;
    /* glossy model, two-sided plinth, haze, floor relief, 3 m model in a 4 m room */
    assert_int_equal(
        parse_with("{\"model\": \"bunny\", \"position\": [0, 1, 0], \"height\": 3,"
                   " \"material\": {\"type\": \"glossy\", \"shininess\": 12}}",
                   ", \"haze\": {\"density\": 0.1}, \"room\": {\"size\": [4, 3, 4],"
                   " \"floor\": {\"displacement\": {}},"
                   " \"plinths\": [{\"position\": [0, 0], \"size\": [1, 1, 1], \"material\": {\"two_sided\": true}}]}",
                   &s, &err),
        MS_OK);
    assert_int_equal(ms_scene_effects(&s), MS_EFFECT_DETAIL_NORMALS | MS_EFFECT_SPECULAR | MS_EFFECT_TWO_SIDED |
                                               MS_EFFECT_HAZE | MS_EFFECT_DISPLACEMENT);
    assert_near(s.models[0].material.specular, 0.18, 1e-6);
    assert_near(s.models[0].material.shininess, 12, 0);
    assert_true(s.room.floor.displacement.on);
    assert_false(s.room.walls.displacement.on);
    ms_scene_free(&s);
    /* the same, with specular and haze not allowed; a glossy material with
     * no strength calls for no highlight */
    assert_int_equal(
        parse_with("{\"model\": \"bunny\", \"position\": [0, 1, 0], \"height\": 3,"
                   " \"material\": {\"type\": \"glossy\", \"specular\": 0}}",
                   ", \"haze\": {\"density\": 0}, \"effects\": {\"haze\": false, \"detail_normals\": false}", &s,
                   &err),
        MS_OK);
    assert_int_equal(s.effects_allowed, MS_EFFECTS_ALL & ~(unsigned)(MS_EFFECT_HAZE | MS_EFFECT_DETAIL_NORMALS));
    assert_int_equal(ms_scene_effects(&s), 0);
    ms_scene_free(&s);
}

static void test_gallery(void **state)
{
    (void)state;
    ms_scene s;
    ms_error err;
    if (ms_scene_load("scripts/scenes/gallery.json", &s, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_string_equal(s.name, "gallery");
    assert_int_equal(s.model_count, 9);
    assert_string_equal(s.camera_path, "scripts/scenes/gallery.cam");
    assert_int_equal(s.light_count, 4);
    assert_int_equal(s.room.plinth_count, 9);
    assert_int_equal(ms_scene_effects(&s), MS_EFFECTS_ALL);
    const char *names[] = {"bunny", "dragon", "armadillo", "igea", "nefertiti", "laurana", "demo", "snowden",
                           "gargoyle"};
    for (size_t i = 0; i < 9; ++i)
        assert_string_equal(s.models[i].model, names[i]);
    ms_camera_path path;
    if (ms_camera_path_load(s.camera_path, &path, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_near(ms_camera_path_duration(&path), 26.0, 0);
    ms_camera_path_free(&path);
    ms_scene_free(&s);
}

/* transform * (x, y, z, 1) */
static void apply(const double m[16], const double p[3], double out[3])
{
    for (int r = 0; r < 3; ++r)
        out[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
}

static void test_model_transform(void **state)
{
    (void)state;
    ms_scene_model m = {.model = "x", .position = {1, 2, 3}, .yaw_degrees = 90, .height = 0.5, .up_axis = 2};
    const double lo[3] = {10, 20, 30}, hi[3] = {12, 24, 40}; /* z up, 10 tall */
    double t[16], p[3];
    ms_scene_model_transform(&m, lo, hi, t);
    /* the bottom centre lands on position */
    apply(t, (double[3]){11, 22, 30}, p);
    assert_near(p[0], 1, 1e-12);
    assert_near(p[1], 2, 1e-12);
    assert_near(p[2], 3, 1e-12);
    /* the top centre is 0.5 m above it */
    apply(t, (double[3]){11, 22, 40}, p);
    assert_near(p[0], 1, 1e-12);
    assert_near(p[1], 2.5, 1e-12);
    assert_near(p[2], 3, 1e-12);
    /* model x goes to scene z (cyclic: z up), then yaw 90 about y takes z to x */
    apply(t, (double[3]){12, 22, 30}, p);
    assert_near(p[0], 1 + 0.05, 1e-12);
    assert_near(p[1], 2, 1e-12);
    assert_near(p[2], 3, 1e-12);
    /* right-handed: the determinant of the linear part is positive (scale^3) */
    double det = t[0] * (t[5] * t[10] - t[9] * t[6]) - t[4] * (t[1] * t[10] - t[9] * t[2]) +
                 t[8] * (t[1] * t[6] - t[5] * t[2]);
    assert_near(det, 0.05 * 0.05 * 0.05, 1e-15);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bad_inputs),     cmocka_unit_test(test_bad_documents),
        cmocka_unit_test(test_missing_model),  cmocka_unit_test(test_defaults),
        cmocka_unit_test(test_effects_called_for), cmocka_unit_test(test_gallery),
        cmocka_unit_test(test_model_transform),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
