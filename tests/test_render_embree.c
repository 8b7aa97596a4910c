/* Geometry = Embree (issue 17, docs/RENDERER.md "Tests"): the silhouette
 * mask of a renderer frame equals an Embree 3 ray cast of the same stitched mesh,
 * one ray through every pixel centre with the same projection (ms_render_unproject
 * gives the ray): intersection over union >= 0.995. Where both hit, the GL depth
 * and the ray's hit distance agree. Run on the dragon at resolution 3 and on the
 * demo model moved 200,000 units from the origin, where vertices in world floats
 * would be 1/64 apart: cell-local coordinates keep the picture exact there. */
#include <embree3/rtcore.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_demo_model.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_render.h"
#include "ms_test.h"
#include "ms_test_render.h"

#define WIDTH 200
#define HEIGHT 150

/* Hit distance along each pixel's ray (INFINITY: miss); positions are taken
 * relative to `centre` in doubles before Embree's floats. */
static void ray_cast(const ms_view_mesh *mesh, const ms_camera *cam, const double centre[3], double *hit)
{
    RTCDevice device = rtcNewDevice("threads=1");
    assert_non_null(device);
    RTCScene scene = rtcNewScene(device);
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *v = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                       mesh->vertex_count);
    unsigned *t = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                          mesh->triangle_count);
    assert_true(v && t);
    for (size_t i = 0; i < 3 * mesh->vertex_count; ++i)
        v[i] = (float)(mesh->positions[i] - centre[i % 3]);
    for (size_t i = 0; i < 3 * mesh->triangle_count; ++i)
        t[i] = mesh->triangles[i];
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (int y = 0; y < HEIGHT; ++y)
        for (int x = 0; x < WIDTH; ++x) {
            double near_point[3], far_point[3];
            assert_true(ms_render_unproject(cam, x + 0.5, y + 0.5, 0.0, near_point));
            assert_true(ms_render_unproject(cam, x + 0.5, y + 0.5, 0.5, far_point));
            double dir[3], len = 0;
            for (int a = 0; a < 3; ++a) {
                dir[a] = far_point[a] - near_point[a];
                len += dir[a] * dir[a];
            }
            len = sqrt(len);
            struct RTCRayHit rh;
            memset(&rh, 0, sizeof rh);
            rh.ray.org_x = (float)(cam->position[0] - centre[0]);
            rh.ray.org_y = (float)(cam->position[1] - centre[1]);
            rh.ray.org_z = (float)(cam->position[2] - centre[2]);
            rh.ray.dir_x = (float)(dir[0] / len);
            rh.ray.dir_y = (float)(dir[1] / len);
            rh.ray.dir_z = (float)(dir[2] / len);
            rh.ray.tnear = 0.0f;
            rh.ray.tfar = INFINITY;
            rh.ray.mask = 0xFFFFFFFFu;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rtcIntersect1(scene, &ctx, &rh);
            hit[(size_t)y * WIDTH + (size_t)x] = rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? INFINITY : rh.ray.tfar;
        }
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
}

/* Renders the model's view at the camera and compares with the ray cast. */
static void compare_with_embree(ms_archive *a, const char *name, const double dir[3], double tolerance_px)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_view *view;
    ms_render *r;
    ms_test_render_open(a, &r, &view);
    ms_camera cam;
    ms_view_mesh mesh = {0};
    ms_test_render_look(a, view, dir, WIDTH, HEIGHT, tolerance_px, &cam, &mesh);
    ms_test_render_show(r, &mesh, NULL, 0, NULL);
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH, HEIGHT);
    ms_render_options o;
    ms_render_options_default(&o);
    ms_render_draw_stats ds;
    ms_error err;
    if (ms_render_draw(r, &cam, &o, &ds, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(ds.triangles_drawn, mesh.triangle_count);
    size_t np = (size_t)WIDTH * HEIGHT;
    float *depth = malloc(np * sizeof *depth);
    double *hit = malloc(np * sizeof *hit);
    assert_true(depth && hit);
    ms_test_fbo_read(&fbo, NULL, depth);
    ms_test_fbo_free(&fbo);
    double centre[3];
    for (int k = 0; k < 3; ++k)
        centre[k] = h->box_origin[k] + 0.5 * h->box_side;
    ray_cast(&mesh, &cam, centre, hit);
    size_t both = 0, either = 0, gl_only = 0, rays_only = 0, depth_close = 0;
    double worst_depth = 0;
    for (size_t p = 0; p < np; ++p) {
        bool g = depth[p] < 1.0f, e = isfinite(hit[p]);
        both += g && e;
        either += g || e;
        gl_only += g && !e;
        rays_only += e && !g;
        if (g && e) {
            double world[3], d2 = 0;
            assert_true(ms_render_unproject(&cam, (double)(p % WIDTH) + 0.5, (double)(p / WIDTH) + 0.5, depth[p],
                                            world));
            for (int k = 0; k < 3; ++k)
                d2 += (world[k] - cam.position[k]) * (world[k] - cam.position[k]);
            double diff = fabs(sqrt(d2) - hit[p]) / h->box_side;
            depth_close += diff < 1e-4;
            if (diff > worst_depth)
                worst_depth = diff;
        }
    }
    double iou = either ? (double)both / (double)either : 0.0;
    print_message("%-28s %zu triangles, %5zu px covered, IoU %.5f (GL only %zu, rays only %zu), "
                  "%.2f %% of common pixels at the same distance (1e-4 of the box), worst %.2e\n",
                  name, mesh.triangle_count, both, iou, gl_only, rays_only,
                  100.0 * (double)depth_close / (double)(both ? both : 1), worst_depth);
    assert_true(both > np / 10);
    assert_true(iou >= 0.995);
    assert_true((double)depth_close >= 0.99 * (double)both);
    free(depth);
    free(hit);
    ms_view_mesh_free(&mesh);
    ms_render_free(r);
    ms_view_destroy(view);
}

static void test_dragon(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    ms_archive *a = ms_test_render_bake(model, dir, "dragon", 16, 1500, 4);
    const double d0[3] = {0.3, 0.2, 1.0}, d1[3] = {-1.0, 0.4, -0.2};
    compare_with_embree(a, "dragon res3, 1 px", d0, 1.0);
    compare_with_embree(a, "dragon res3, 1 px, behind", d1, 1.0);
    compare_with_embree(a, "dragon res3, 8 px (coarse)", d0, 8.0);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* The demo model 200,000 units out on x, y and z. */
static void test_far_from_origin(void **state)
{
    (void)state;
    char dir[512], path[1024];
    ms_test_tmpdir(dir, sizeof dir);
    ms_demo_model model = {40, 0};
    ms_mesh mesh = {0};
    assert_int_equal(ms_demo_build(&model, &mesh, NULL), MS_OK);
    for (size_t i = 0; i < 3 * mesh.vertex_count; ++i)
        mesh.positions[i] += 200000.0;
    snprintf(path, sizeof path, "%s/far.ply", dir);
    assert_int_equal(ms_ply_write(path, &mesh, true, true, NULL), MS_OK);
    ms_mesh_free(&mesh);
    ms_archive *a = ms_test_render_bake(path, dir, "far", 16, 2000, 4);
    assert_true(ms_archive_get_header(a)->box_origin[0] > 199990.0);
    const double d0[3] = {1.0, 0.5, 0.7};
    compare_with_embree(a, "demo 40 at 200,000", d0, 1.0);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dragon),
        cmocka_unit_test(test_far_from_origin),
    };
    return cmocka_run_group_tests(tests, ms_test_gl_group_setup, ms_test_gl_group_teardown);
}
