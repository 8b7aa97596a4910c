/* Section planes (docs/VIEWER.md, "Sections"), in process:
 *   - the --section text (ms_section_parse): axis and free forms read
 *     exactly, hostile texts refused with one line; meshview's set of planes
 *     (at most three), their planes a b c d, its keys (Y across the axis
 *     nearest the view, cutting the half towards the eye; J, 9, 0, I) and its
 *     HUD line;
 *   - meshview's --section options (ms_viewer_options_parse): repeated, with
 *     --view's s= as the default, and hostile values one line and status 2;
 *   - the frustum's section half-spaces (ms_frustum_add_section): a box wholly
 *     on the side cut away is culled, one that straddles the plane or lies
 *     within the margin kept;
 *   - the selection (ms_view_select on a sphere baked at 20 bits): with a
 *     plane x = 0.5 cutting away x > 0.5, every cell whose cube lies wholly
 *     beyond it gets the need of a culled cell (its need less
 *     culled_bits_less, ms_view_cell_need -1), every other cell the need it
 *     had without the plane, to the bit; in the converged cut the cells
 *     beyond are shown at fewer bits in all (none at more), every other cell
 *     as without the plane, and the kept side's triangles are as many; a
 *     local client core given the plane (ms_core_set_sections) completes
 *     with fewer bits beyond it and every other cell as without; more than
 *     three planes or a zero normal are MS_ERR_ARG. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>
#include <GLFW/glfw3.h>

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_camera.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_section.h"
#include "ms_client_core.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_view_decoder.h"
#include "ms_viewer_options.h"
#include "ms_viewer_section.h"

static void test_section_text(void **state)
{
    (void)state;
    double p[3], n[3];
    ms_error err;
    assert_int_equal(ms_section_parse("x=0.25", p, n, &err), MS_OK);
    assert_true(p[0] == 0.25 && p[1] == 0 && p[2] == 0 && n[0] == 1 && n[1] == 0 && n[2] == 0);
    assert_int_equal(ms_section_parse("-z=-1.5e-3", p, n, &err), MS_OK);
    assert_true(p[2] == -1.5e-3 && n[2] == -1 && n[0] == 0 && n[1] == 0);
    assert_int_equal(ms_section_parse("y=-2", p, n, &err), MS_OK);
    assert_true(p[1] == -2 && n[1] == 1);
    assert_int_equal(ms_section_parse("-1,2,3.5,0,-0.5,0.25", p, n, &err), MS_OK);
    assert_true(p[0] == -1 && p[1] == 2 && p[2] == 3.5 && n[0] == 0 && n[1] == -0.5 && n[2] == 0.25);
    double plane[4];
    ms_section_plane(p, n, plane);
    assert_true(plane[0] == 0 && plane[1] == -0.5 && plane[2] == 0.25 && plane[3] == -(-1.0 + 0.875));
    static const char *const bad[] = {
        "", "x", "x=", "x=1,2", "w=1", "+x=1", "--x=1", "x=nan", "x=inf", "x=1e999", "x= 1", "x=0x10",
        "X=1", "1,2,3,0,0,0", "1,2,3,0,0", "1,2,3,0,0,1,7", "1,2,3,0,0,1,", ",1,2,3,0,0", "1,,2,3,0,0,1",
        "1e300,0,0,1e300,0,0", "1,2,3,0,0,1e200", "a,b,c,d,e,f", "x=1\n", "0,0,0,nan,0,1",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        err.text[0] = 0;
        if (ms_section_parse(bad[i], p, n, &err) == MS_OK)
            fail_msg("'%s' accepted", bad[i]);
        assert_int_equal(err.code, MS_ERR_FORMAT);
        assert_true(err.text[0] != 0);
        assert_null(strchr(err.text, '\n'));
    }
    assert_int_not_equal(ms_section_parse(NULL, p, n, &err), MS_OK);
    /* a long text is quoted shortened, on one line */
    char longer[600];
    memset(longer, '7', sizeof longer - 1);
    longer[sizeof longer - 1] = 0;
    assert_int_not_equal(ms_section_parse(longer, p, n, &err), MS_OK);
    assert_true(strlen(err.text) < 200);
}

static void test_viewer_sections(void **state)
{
    (void)state;
    ms_viewer_sections s = {0};
    ms_error err;
    assert_int_equal(ms_viewer_sections_add_text(&s, "x=0.5", &err), MS_OK);
    assert_int_equal(ms_viewer_sections_add_text(&s, "-y=0.25", &err), MS_OK);
    assert_int_equal(ms_viewer_sections_add_text(&s, "bad", &err), MS_ERR_FORMAT);
    assert_int_equal(s.count, 2);
    assert_int_equal(ms_viewer_sections_add_text(&s, "0,0,1,1,1,1", &err), MS_OK);
    assert_int_equal(ms_viewer_sections_add_text(&s, "z=0", &err), MS_ERR_RANGE);
    assert_non_null(strstr(err.text, "at most 3"));
    assert_int_equal(s.count, 3);
    double planes[MS_SECTIONS_MAX][4];
    assert_int_equal(ms_viewer_sections_planes(&s, planes), 3);
    assert_true(planes[0][0] == 1 && planes[0][1] == 0 && planes[0][2] == 0 && planes[0][3] == -0.5);
    assert_true(planes[1][0] == 0 && planes[1][1] == -1 && planes[1][2] == 0 && planes[1][3] == 0.25);
    assert_true(planes[2][0] == 1 && planes[2][1] == 1 && planes[2][2] == 1 && planes[2][3] == -1);
    char text[256];
    ms_viewer_sections_describe(&s, text, sizeof text);
    assert_string_equal(text, "sections x=0.5  -y=0.25  at 0,0,1 normal 1,1,1");
    ms_render_options ro;
    ms_render_options_default(&ro);
    ms_viewer_sections_apply(&s, &ro);
    assert_int_equal(ro.section_count, 3);
    assert_memory_equal(ro.sections, planes, sizeof planes);
    assert_true(ro.section_colour[0] == MS_SECTION_R && ro.section_colour[1] == MS_SECTION_G &&
                ro.section_colour[2] == MS_SECTION_B);

    /* keys: I removes the last; Y adds across the axis nearest the view, the eye's half cut away */
    const double forward[3] = {0.3, -0.2, -0.9}, target[3] = {1, 2, 3};
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_I, forward, target, 5));
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_I, forward, target, 5));
    assert_int_equal(s.count, 1);
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_Y, forward, target, 5));
    assert_int_equal(s.count, 2);
    assert_true(s.point[1][0] == 1 && s.point[1][1] == 2 && s.point[1][2] == 3);
    assert_true(s.normal[1][0] == 0 && s.normal[1][1] == 0 && s.normal[1][2] == 1); /* the eye at +z */
    ms_viewer_sections_describe(&s, text, sizeof text);
    assert_string_equal(text, "sections x=0.5  z=3");
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_J, forward, target, 5));
    assert_true(s.normal[1][2] == -1);
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_0, forward, target, 5)); /* along the normal: z - 0.1 */
    assert_true(s.point[1][2] == 3 - 0.1);
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_9, forward, target, 5));
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_9, forward, target, 5));
    assert_true(fabs(s.point[1][2] - 3.1) < 1e-15);
    assert_false(ms_viewer_sections_key(&s, GLFW_KEY_Q, forward, target, 5));
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_Y, forward, target, 5));
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_Y, forward, target, 5)); /* a fourth: refused */
    assert_int_equal(s.count, 3);
    for (int i = 0; i < 4; ++i)
        assert_true(ms_viewer_sections_key(&s, GLFW_KEY_I, forward, target, 5));
    assert_int_equal(s.count, 0);
    /* keys on no section change nothing */
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_J, forward, target, 5));
    assert_true(ms_viewer_sections_key(&s, GLFW_KEY_0, forward, target, 5));
    assert_int_equal(s.count, 0);
    ms_viewer_sections_describe(&s, text, sizeof text);
    assert_string_equal(text, "");
    const double zero[3] = {0, 0, 0}, huge[3] = {1e300, 0, 0};
    assert_false(ms_viewer_sections_add(&s, target, zero));
    assert_false(ms_viewer_sections_add(&s, huge, huge));
    assert_int_equal(s.count, 0);
}

/* meshview's options from a command line; the status, what went to err. */
static int parse_line(const char *line, ms_viewer_options *o, char *out, size_t size)
{
    char copy[2048], *argv[32];
    int argc = 0;
    snprintf(copy, sizeof copy, "meshview %s", line);
    for (char *t = strtok(copy, " "); t && argc < 31; t = strtok(NULL, " "))
        argv[argc++] = t;
    argv[argc] = NULL;
    FILE *err = tmpfile();
    assert_non_null(err);
    int status = ms_viewer_options_parse(argc, argv, o, err);
    rewind(err);
    size_t n = fread(out, 1, size - 1, err);
    out[n] = 0;
    fclose(err);
    return status;
}

static void test_section_options(void **state)
{
    (void)state;
    ms_viewer_options o;
    char out[1024];
    assert_int_equal(parse_line("/a --model m --section x=1 --section 0,0,0,0,1,-1e-3", &o, out, sizeof out), 0);
    assert_string_equal(out, "");
    assert_int_equal(o.sections.count, 2);
    assert_true(o.sections.point[0][0] == 1 && o.sections.normal[0][0] == 1);
    assert_true(o.sections.normal[1][1] == 1 && o.sections.normal[1][2] == -1e-3);
    /* the view's sections, unless --section is given */
    assert_int_equal(parse_line("/a --model m --view mv1:t=0,0,0:d=1:o=0,0:f=40:u=y:s=0,0,2,0,0,-1", &o, out,
                                sizeof out),
                     0);
    assert_int_equal(o.sections.count, 1);
    assert_true(o.sections.point[0][2] == 2 && o.sections.normal[0][2] == -1);
    assert_int_equal(parse_line("/a --model m --view mv1:t=0,0,0:d=1:o=0,0:f=40:u=y:s=0,0,2,0,0,-1 --section y=3",
                                &o, out, sizeof out),
                     0);
    assert_int_equal(o.sections.count, 1);
    assert_true(o.sections.point[0][1] == 3 && o.sections.normal[0][1] == 1);
    assert_int_equal(parse_line("/a --model m", &o, out, sizeof out), 0);
    assert_int_equal(o.sections.count, 0);
    static const char *const bad[] = {
        "/a --model m --section x",
        "/a --model m --section x=nan",
        "/a --model m --section x=1e400",
        "/a --model m --section q=1",
        "/a --model m --section 1,2,3,0,0,0",
        "/a --model m --section 1,2,3,4,5",
        "/a --model m --section 1,2,3,4,5,6,7",
        "/a --model m --section x=1 --section y=1 --section z=1 --section x=2",
        "/a --section x=1",
        "/a --model m --view mv1:t=0,0,0:d=1:o=0,0:f=40:u=y:s=0,0,2,0,0,0",
        "/a --model m --section 77777777777777777777777777777777777777777777777777777777777777777777777777777777",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        int status = parse_line(bad[i], &o, out, sizeof out);
        size_t lines = 0;
        for (const char *p = out; *p; ++p)
            lines += *p == '\n';
        if (status != 2 || lines != 1 || strncmp(out, "meshview: ", 10) != 0 || strlen(out) > 200)
            fail_msg("'%s': status %d, output '%s'", bad[i], status, out);
    }
}

static void test_frustum_sections(void **state)
{
    (void)state;
    ms_camera c;
    ms_error err;
    const double eye[3] = {0, 0, 10}, at[3] = {0, 0, 0}, up[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(eye, at, up, 90, 100, 100, 0.1, 100, &c, &err), MS_OK);
    ms_frustum f;
    ms_camera_frustum(&c, &f);
    assert_int_equal(f.sections, 0);
    const double plane[4] = {2, 0, 0, -1}; /* cuts away x > 0.5 */
    assert_true(ms_frustum_add_section(&f, plane));
    const double lo_cut[3] = {0.6, -1, -1}, hi_cut[3] = {1.0, 1, 1};
    const double lo_across[3] = {0.4, -1, -1}, hi_across[3] = {1.0, 1, 1};
    const double lo_kept[3] = {-1, -1, -1}, hi_kept[3] = {0.2, 1, 1};
    assert_false(ms_frustum_keeps_box(&f, lo_cut, hi_cut, 0));
    assert_true(ms_frustum_keeps_box(&f, lo_cut, hi_cut, 0.1)); /* within the margin */
    assert_true(ms_frustum_keeps_box(&f, lo_across, hi_across, 0));
    assert_true(ms_frustum_keeps_box(&f, lo_kept, hi_kept, 0));
    const double flat[4] = {0, 0, 0, 1}, nan_plane[4] = {1, 0, 0, NAN};
    assert_false(ms_frustum_add_section(&f, flat));
    assert_false(ms_frustum_add_section(&f, nan_plane));
    assert_true(ms_frustum_add_section(&f, plane));
    assert_true(ms_frustum_add_section(&f, plane));
    assert_false(ms_frustum_add_section(&f, plane)); /* a fourth */
    assert_int_equal(f.sections, 3);
    ms_camera_frustum(&c, &f); /* a fresh frustum has none */
    assert_true(ms_frustum_keeps_box(&f, lo_cut, hi_cut, 0));
}

/* --- the selection on a baked sphere -------------------------------------- */

static void add_vertex(ms_mesh *m, double x, double y, double z)
{
    ms_error err;
    assert_int_equal(ms_mesh_reserve(m, m->vertex_count + 1, m->triangle_count, &err), MS_OK);
    double *p = &m->positions[3 * m->vertex_count++];
    p[0] = x, p[1] = y, p[2] = z;
}

static void add_triangle(ms_mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    ms_error err;
    assert_int_equal(ms_mesh_reserve(m, m->vertex_count, m->triangle_count + 1, &err), MS_OK);
    uint32_t *t = &m->triangles[3 * m->triangle_count++];
    t[0] = a, t[1] = b, t[2] = c;
}

/* A latitude-longitude sphere of radius 0.5 about (0.5, 0.5, 0.5). */
static void sphere(ms_mesh *m)
{
    enum { RINGS = 48, SEGMENTS = 96 };
    add_vertex(m, 0.5, 0.5, 1.0);
    add_vertex(m, 0.5, 0.5, 0.0);
    for (int r = 1; r < RINGS; ++r)
        for (int k = 0; k < SEGMENTS; ++k) {
            double theta = M_PI * r / RINGS, phi = 2.0 * M_PI * k / SEGMENTS;
            add_vertex(m, 0.5 + 0.5 * sin(theta) * cos(phi), 0.5 + 0.5 * sin(theta) * sin(phi),
                       0.5 + 0.5 * cos(theta));
        }
#define RING(r, k) (2u + (uint32_t)((r) - 1) * SEGMENTS + (uint32_t)(((k) + SEGMENTS) % SEGMENTS))
    for (int k = 0; k < SEGMENTS; ++k) {
        add_triangle(m, 0, RING(1, k), RING(1, k + 1));
        add_triangle(m, 1, RING(RINGS - 1, k + 1), RING(RINGS - 1, k));
    }
    for (int r = 1; r < RINGS - 1; ++r)
        for (int k = 0; k < SEGMENTS; ++k) {
            add_triangle(m, RING(r, k), RING(r + 1, k), RING(r + 1, k + 1));
            add_triangle(m, RING(r, k), RING(r + 1, k + 1), RING(r, k + 1));
        }
#undef RING
}

/* Triangles of the view's converged cut for camera and params whose three
 * corners lie beyond x = 0.5 (*beyond) and the others (*kept). */
static void converged_cut(ms_view *v, const ms_camera *camera, const ms_view_select_params *p, size_t *beyond,
                          size_t *kept)
{
    ms_error err;
    for (int pass = 0; pass < 32; ++pass) {
        ms_view_select(v, camera, p, NULL);
        ms_view_apply_report r;
        if (ms_view_apply(v, &r, &err) != MS_OK)
            fail_msg("%s", err.text);
        if (!r.splits && !r.merges && !r.refined && !r.coarsened)
            break;
    }
    ms_view_mesh m = {0};
    if (ms_view_stitch(v, NULL, &m, &err) != MS_OK)
        fail_msg("%s", err.text);
    *beyond = *kept = 0;
    for (size_t t = 0; t < m.triangle_count; ++t) {
        bool all = true;
        for (int k = 0; k < 3; ++k)
            all = all && m.positions[3 * m.triangles[3 * t + k]] > 0.5;
        *(all ? beyond : kept) += 1;
    }
    ms_view_mesh_free(&m);
}

static void test_selection_culls_the_side_cut_away(void **state)
{
    (void)state;
    char dir[512], archives[600], ply[700];
    ms_error err;
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(archives, sizeof archives, "%s/archive", dir);
    assert_int_equal(mkdir(archives, 0755), 0);
    snprintf(ply, sizeof ply, "%s/sphere.ply", dir);
    ms_mesh mesh = {0};
    sphere(&mesh);
    assert_int_equal(ms_ply_write(ply, &mesh, true, true, &err), MS_OK);
    ms_mesh_free(&mesh);
    ms_bake_options o;
    ms_bake_options_default(&o);
    o.apo.enabled = false;
    o.input = ply, o.archive_dir = archives, o.name = "sphere";
    o.bits = 20;
    o.min_triangles = 300;
    o.threads = 2, o.mem_mb = 64;
    ms_bake_report report;
    if (ms_bake(&o, &report, &err) != MS_OK)
        fail_msg("bake: %s", err.text);
    ms_archive *archive;
    assert_int_equal(ms_archive_open(report.archive_path, &archive, &err), MS_OK);
    ms_view *plain, *cut;
    assert_int_equal(ms_view_create_from_archive(archive, &plain, &err), MS_OK);
    assert_int_equal(ms_view_create_from_archive(archive, &cut, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(archive);

    /* the whole sphere in view, from the side (-y), close enough for a tree of cells */
    ms_camera camera;
    const double eye[3] = {0.5, -1.2, 0.5}, at[3] = {0.5, 0.5, 0.5}, up[3] = {0, 0, 1};
    assert_int_equal(ms_camera_look_at(eye, at, up, 60, 300, 300, 0.01, 10, &camera, &err), MS_OK);
    ms_view_select_params p;
    ms_view_select_params_default(&p);
    p.tolerance_px = 1;
    p.culled_bits_less = 6;
    ms_view_select_params q = p;
    q.section_count = 1;
    const double plane[4] = {1, 0, 0, -0.5};
    memcpy(q.sections[0], plane, sizeof plane);

    size_t plain_beyond, plain_kept, cut_beyond, cut_kept;
    converged_cut(plain, &camera, &p, &plain_beyond, &plain_kept);
    converged_cut(cut, &camera, &q, &cut_beyond, &cut_kept);
    /* every known cell: culled exactly where its cube lies beyond the plane */
    uint32_t beyond_cells = 0, other_cells = 0;
    unsigned plain_bits_beyond = 0, cut_bits_beyond = 0;
    for (uint32_t i = 0; i < ms_view_cell_count(cut); ++i) {
        if (!ms_view_known(cut, i) || !ms_view_known(plain, i))
            continue;
        const ms_archive_cell *rec = ms_archive_get_cell(archive, i);
        double side = h->box_side / pow((double)h->n, rec->level);
        double lo_x = h->box_origin[0] + side * rec->position[0];
        double need = ms_view_cell_select_need(plain, &camera, i, &p);
        double with = ms_view_cell_select_need(cut, &camera, i, &q);
        unsigned plain_bits = ms_view_state(plain, i) == MS_VIEW_SHOWN ? ms_view_bits(plain, i) : 0;
        unsigned cut_bits = ms_view_state(cut, i) == MS_VIEW_SHOWN ? ms_view_bits(cut, i) : 0;
        if (lo_x > 0.5) {
            beyond_cells++;
            assert_true(ms_view_cell_need(cut, &camera, i, &q) == -1.0);
            assert_true(with == need - p.culled_bits_less);
            assert_true(cut_bits <= plain_bits);
            plain_bits_beyond += plain_bits, cut_bits_beyond += cut_bits;
        } else {
            other_cells++;
            assert_int_equal(ms_view_state(cut, i), ms_view_state(plain, i));
            assert_int_equal(cut_bits, plain_bits);
            assert_true(with == need);
            assert_true(ms_view_cell_need(cut, &camera, i, &q) == ms_view_cell_need(plain, &camera, i, &p));
        }
    }
    printf("sphere: %u cells beyond x = 0.5, %u others; the bits shown beyond: %u without the plane, %u with; "
           "triangles beyond %zu, %zu; kept side %zu, %zu\n",
           beyond_cells, other_cells, plain_bits_beyond, cut_bits_beyond, plain_beyond, cut_beyond, plain_kept,
           cut_kept);
    assert_true(beyond_cells >= 2 && other_cells >= 2);
    assert_true(cut_bits_beyond < plain_bits_beyond);
    assert_true(cut_beyond <= plain_beyond);
    assert_int_equal(cut_kept, plain_kept);
    ms_view_destroy(plain);
    ms_view_destroy(cut);

    /* the core: the planes through ms_core_set_sections cull alike */
    ms_core_frame *frames[2] = {NULL, NULL};
    for (int with = 0; with < 2; ++with) {
        ms_core_options co = {0};
        co.archive_path = report.archive_path;
        co.tolerance_px = 1;
        co.hysteresis_bits = 0.0;
        co.culled_bits_less = 6;
        co.export_frames = true;
        ms_core *core;
        if (ms_core_start(&co, &core, &err) != MS_OK)
            fail_msg("%s", err.text);
        if (with) {
            const double too_many[4][4] = {{1, 0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0}, {1, 0, 0, 0}};
            const double flat[1][4] = {{0, 0, 0, 1}};
            assert_int_equal(ms_core_set_sections(core, too_many, 4, &err), MS_ERR_ARG);
            assert_int_equal(ms_core_set_sections(core, flat, 1, &err), MS_ERR_ARG);
            assert_int_equal(ms_core_set_sections(core, (const double(*)[4])q.sections, 1, &err), MS_OK);
        }
        ms_core_set_camera(core, &camera);
        ms_core_stats stats;
        bool complete = ms_test_core_wait_complete(core, 60.0, &stats, &frames[with]);
        ms_core_stop(core);
        if (!complete || !frames[with])
            fail_msg("the view did not complete: %s", stats.error);
    }
    unsigned core_plain = 0, core_cut = 0;
    for (uint32_t i = 0; i < frames[0]->cell_count && i < frames[1]->cell_count; ++i) {
        const ms_archive_cell *rec = ms_archive_get_cell(archive, i);
        double side = h->box_side / pow((double)h->n, rec->level);
        uint8_t a = ms_core_frame_cell_bits(frames[0], i), b = ms_core_frame_cell_bits(frames[1], i);
        if (h->box_origin[0] + side * rec->position[0] > 0.5) {
            core_plain += a <= 64 ? a : 0, core_cut += b <= 64 ? b : 0;
        } else if (a != b) {
            fail_msg("cell %u on the kept side: %u without the plane, %u with", i, a, b);
        }
    }
    printf("the core: bits shown beyond x = 0.5: %u without the plane, %u with\n", core_plain, core_cut);
    assert_true(core_cut < core_plain);
    ms_core_frame_free(frames[0]);
    ms_core_frame_free(frames[1]);
    ms_archive_close(archive);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_section_text),
        cmocka_unit_test(test_viewer_sections),
        cmocka_unit_test(test_section_options),
        cmocka_unit_test(test_frustum_sections),
        cmocka_unit_test(test_selection_culls_the_side_cut_away),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
