/* Small hand-written files for each format variant, with exact expected
 * coordinates and triangles. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_mesh_io.h"
#include "ms_mesh_reader.h"
#include "support/ms_test.h"

typedef struct bytes {
    unsigned char data[65536];
    size_t size;
} bytes;

typedef enum encoding { ASCII, LITTLE, BIG } encoding;

static void put(bytes *b, const void *p, size_t n)
{
    assert_true(b->size + n <= sizeof b->data);
    memcpy(b->data + b->size, p, n);
    b->size += n;
}

static void put_text(bytes *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf((char *)b->data + b->size, sizeof b->data - b->size, fmt, ap);
    va_end(ap);
    assert_true(n >= 0 && b->size + (size_t)n < sizeof b->data);
    b->size += (size_t)n;
}

/* One value of a PLY type ('b' int8 ... 'd' double) in the given encoding. */
static void put_value(bytes *b, encoding e, char type, double v)
{
    if (e == ASCII) {
        if (type == 'f' || type == 'd')
            put_text(b, "%.17g ", v);
        else
            put_text(b, "%lld ", (long long)v);
        return;
    }
    unsigned char raw[8];
    size_t n;
    switch (type) {
    case 'b': { int8_t x = (int8_t)v; memcpy(raw, &x, n = 1); break; }
    case 'B': { uint8_t x = (uint8_t)v; memcpy(raw, &x, n = 1); break; }
    case 'h': { int16_t x = (int16_t)v; memcpy(raw, &x, n = 2); break; }
    case 'H': { uint16_t x = (uint16_t)v; memcpy(raw, &x, n = 2); break; }
    case 'i': { int32_t x = (int32_t)v; memcpy(raw, &x, n = 4); break; }
    case 'I': { uint32_t x = (uint32_t)v; memcpy(raw, &x, n = 4); break; }
    case 'f': { float x = (float)v; memcpy(raw, &x, n = 4); break; }
    default: memcpy(raw, &v, n = 8); break;
    }
    const uint16_t probe = 1;
    bool host_little = *(const uint8_t *)&probe == 1;
    if ((e == BIG) == host_little)
        for (size_t i = 0; i < n / 2; ++i) {
            unsigned char t = raw[i];
            raw[i] = raw[n - 1 - i];
            raw[n - 1 - i] = t;
        }
    put(b, raw, n);
}

static void end_record(bytes *b, encoding e)
{
    if (e == ASCII)
        put_text(b, "\n");
}

static const char *write_file(char *path, size_t size, const char *dir, const char *name,
                              const void *data, size_t n)
{
    snprintf(path, size, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
    return path;
}

static void expect_mesh(const char *path, const double *positions, size_t vertices,
                        const uint32_t *triangles, size_t triangle_count, const char *format,
                        uint64_t dropped, uint64_t isolated)
{
    ms_mesh mesh = {0};
    ms_mesh_load_report report;
    ms_error err;
    if (ms_mesh_load(path, &mesh, &report, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_string_equal(report.format, format);
    assert_int_equal(mesh.vertex_count, vertices);
    assert_int_equal(mesh.triangle_count, triangle_count);
    for (size_t i = 0; i < 3 * vertices; ++i)
        if (mesh.positions[i] != positions[i])
            fail_msg("%s: coordinate %zu is %.17g, expected %.17g", path, i, mesh.positions[i],
                     positions[i]);
    for (size_t i = 0; i < 3 * triangle_count; ++i)
        if (mesh.triangles[i] != triangles[i])
            fail_msg("%s: index %zu is %u, expected %u", path, i, mesh.triangles[i],
                     triangles[i]);
    assert_int_equal(report.dropped_faces, dropped);
    assert_int_equal(report.isolated_vertices, isolated);
    ms_mesh_free(&mesh);
}

/* ---- PLY with odd types and orders, in all three encodings ------------------ */

static const double odd_x[5] = {0.5, -1.25, 2, 3.75, -0.125};   /* float */
static const double odd_y[5] = {1, -2, 3, 40000, -5};            /* int */
static const double odd_z[5] = {0.1, -0.2, 1e-3, 123.456, 0};    /* double */
static const uint32_t odd_faces[] = {0, 1, 2, 0, 2, 3, 4, 4, 3, 2, 1, 0};
static const size_t odd_face_sizes[] = {3, 4, 5};
/* Fans: (0 1 2), (0 2 3) (0 3 4), (4 3 2) (4 2 1) (4 1 0). */
static const uint32_t odd_triangles[] = {0, 1, 2, 0, 2, 3, 0, 3, 4, 4, 3, 2, 4, 2, 1, 4, 1, 0};

static void build_odd_ply(bytes *b, encoding e, bool new_type_names)
{
    static const char *const formats[] = {"ascii", "binary_little_endian", "binary_big_endian"};
    const char *f32 = new_type_names ? "float32" : "float";
    put_text(b, "ply\nformat %s 1.0\ncomment odd layout\nobj_info made by hand\n", formats[e]);
    put_text(b, "element vertex 5\nproperty %s nx\nproperty %s z\nproperty %s red\n"
                "property list uchar int16 extra\nproperty %s x\nproperty %s y\n",
             f32, new_type_names ? "float64" : "double", new_type_names ? "uint8" : "uchar", f32,
             new_type_names ? "int32" : "int");
    put_text(b, "element edge 2\nproperty list uchar int ends\nproperty %s weight\n",
             new_type_names ? "int16" : "short");
    put_text(b, "element face 3\nproperty %s flags\nproperty list %s %s vertex_index\n"
                "property list uchar %s uv\nend_header\n",
             new_type_names ? "uint8" : "uchar", new_type_names ? "uint16" : "ushort",
             new_type_names ? "uint8" : "uchar", f32);
    for (int v = 0; v < 5; ++v) {
        put_value(b, e, 'f', 0.25 * v);
        put_value(b, e, 'd', odd_z[v]);
        put_value(b, e, 'B', 200 + v);
        put_value(b, e, 'B', v % 3); /* a list inside the vertex: general path */
        for (int k = 0; k < v % 3; ++k)
            put_value(b, e, 'h', -300 * k);
        put_value(b, e, 'f', odd_x[v]);
        put_value(b, e, 'i', odd_y[v]);
        end_record(b, e);
    }
    for (int edge = 0; edge < 2; ++edge) {
        put_value(b, e, 'B', 2);
        put_value(b, e, 'i', edge);
        put_value(b, e, 'i', edge + 1);
        put_value(b, e, 'h', -7);
        end_record(b, e);
    }
    size_t k = 0;
    for (int face = 0; face < 3; ++face) {
        put_value(b, e, 'B', 9);
        put_value(b, e, 'H', (double)odd_face_sizes[face]);
        for (size_t i = 0; i < odd_face_sizes[face]; ++i)
            put_value(b, e, 'B', odd_faces[k++]);
        put_value(b, e, 'B', 2);
        put_value(b, e, 'f', 0.5);
        put_value(b, e, 'f', 0.75);
        end_record(b, e);
    }
}

static void expect_odd_mesh(const char *path, const char *format)
{
    double positions[15];
    for (int v = 0; v < 5; ++v) {
        positions[3 * v] = (double)(float)odd_x[v];
        positions[3 * v + 1] = odd_y[v];
        positions[3 * v + 2] = odd_z[v];
    }
    expect_mesh(path, positions, 5, odd_triangles, 6, format, 0, 0);
}

static void test_ply_odd_layout_all_encodings(void **state)
{
    (void)state;
    static const char *const formats[] = {"ply-ascii", "ply-binary-le", "ply-binary-be"};
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    for (int names = 0; names < 2; ++names)
        for (int e = ASCII; e <= BIG; ++e) {
            static bytes b;
            b.size = 0;
            build_odd_ply(&b, (encoding)e, names == 1);
            write_file(path, sizeof path, dir, "odd.ply", b.data, b.size);
            expect_odd_mesh(path, formats[e]);
        }
    ms_test_rmdir(dir);
}

static void test_ply_gzip_and_crlf(void **state)
{
    (void)state;
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    static bytes b, crlf;
    b.size = crlf.size = 0;
    build_odd_ply(&b, ASCII, false);
    for (size_t i = 0; i < b.size; ++i) {
        if (b.data[i] == '\n')
            put(&crlf, "\r", 1);
        put(&crlf, &b.data[i], 1);
    }
    write_file(path, sizeof path, dir, "crlf.ply", crlf.data, crlf.size);
    expect_odd_mesh(path, "ply-ascii");
    b.size = 0;
    build_odd_ply(&b, BIG, true);
    snprintf(path, sizeof path, "%s/odd.ply.gz", dir);
    gzFile gz = gzopen(path, "wb9");
    assert_non_null(gz);
    assert_int_equal(gzwrite(gz, b.data, (unsigned)b.size), (int)b.size);
    assert_int_equal(gzclose(gz), Z_OK);
    expect_odd_mesh(path, "ply-binary-be");
    ms_mesh mesh = {0};
    ms_mesh_load_report report;
    ms_error err;
    assert_int_equal(ms_mesh_load(path, &mesh, &report, &err), MS_OK);
    assert_true(report.gzip);
    assert_int_equal(report.input_bytes, b.size);
    assert_int_equal(report.input_faces, 3);
    ms_mesh_free(&mesh);
    ms_test_rmdir(dir);
}

/* Common fast-path layout, with a degenerate face and an isolated vertex. */
static void test_ply_fast_layout_cleaning(void **state)
{
    (void)state;
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    for (int e = ASCII; e <= BIG; ++e) {
        static bytes b;
        b.size = 0;
        put_text(&b, "ply\nformat %s 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                     "property float z\nproperty float confidence\nelement face 4\n"
                     "property list uchar uint vertex_indices\nend_header\n",
                 e == ASCII ? "ascii" : e == LITTLE ? "binary_little_endian" : "binary_big_endian");
        for (int v = 0; v < 5; ++v) {
            put_value(&b, (encoding)e, 'f', v);
            put_value(&b, (encoding)e, 'f', -v);
            put_value(&b, (encoding)e, 'f', 0.5 * v);
            put_value(&b, (encoding)e, 'f', 1);
            end_record(&b, (encoding)e);
        }
        static const uint32_t faces[4][3] = {{0, 1, 2}, {1, 1, 2}, {2, 1, 3}, {0, 1, 3}};
        for (int f = 0; f < 4; ++f) {
            put_value(&b, (encoding)e, 'B', 3);
            for (int i = 0; i < 3; ++i)
                put_value(&b, (encoding)e, 'I', faces[f][i]);
            end_record(&b, (encoding)e);
        }
        write_file(path, sizeof path, dir, "fast.ply", b.data, b.size);
        const double positions[] = {0, 0, 0, 1, -1, 0.5, 2, -2, 1, 3, -3, 1.5, 4, -4, 2};
        const uint32_t triangles[] = {0, 1, 2, 2, 1, 3, 0, 1, 3};
        static const char *const names[] = {"ply-ascii", "ply-binary-le", "ply-binary-be"};
        expect_mesh(path, positions, 5, triangles, 3, names[e], 1, 1);
    }
    ms_test_rmdir(dir);
}

static void test_ply_tristrips(void **state)
{
    (void)state;
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    /* Strip 0 1 2 3 gives (0 1 2) (2 1 3); strip 3 4 5 5 6 gives (3 4 5) and two
     * degenerate triangles (5 4 5), (5 5 6) that the policy drops. */
    static const int32_t strip[] = {0, 1, 2, 3, -1, 3, 4, 5, 5, 6};
    for (int e = ASCII; e <= BIG; ++e) {
        static bytes b;
        b.size = 0;
        put_text(&b, "ply\nformat %s 1.0\nelement vertex 7\nproperty double x\nproperty double y\n"
                     "property double z\nelement tristrips 1\nproperty list int int vertex_indices\n"
                     "end_header\n",
                 e == ASCII ? "ascii" : e == LITTLE ? "binary_little_endian" : "binary_big_endian");
        double positions[21];
        for (int v = 0; v < 7; ++v) {
            for (int a = 0; a < 3; ++a) {
                positions[3 * v + a] = v * 10 + a + 0.5;
                put_value(&b, (encoding)e, 'd', positions[3 * v + a]);
            }
            end_record(&b, (encoding)e);
        }
        put_value(&b, (encoding)e, 'i', 10);
        for (int i = 0; i < 10; ++i)
            put_value(&b, (encoding)e, 'i', strip[i]);
        end_record(&b, (encoding)e);
        write_file(path, sizeof path, dir, "strips.ply", b.data, b.size);
        const uint32_t triangles[] = {0, 1, 2, 2, 1, 3, 3, 4, 5};
        static const char *const names[] = {"ply-ascii", "ply-binary-le", "ply-binary-be"};
        expect_mesh(path, positions, 7, triangles, 3, names[e], 2, 1); /* 6 only in a dropped one */
    }
    ms_test_rmdir(dir);
}

/* ---- OBJ ------------------------------------------------------------------- */

static void test_obj_all_face_forms(void **state)
{
    (void)state;
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    const char *text =
        "# hand-written\n"
        "mtllib scene.mtl\n"
        "o thing\n"
        "v 0 0 0\n"
        "v 1.5 0 0 1.0\n"
        "v 0 2.5 0\n"
        "vt 0 0\nvt 1 0\nvt 0 1\n"
        "vn 0 0 1\n"
        "g group\nusemtl red\ns 1\n"
        "f 1 2 3\n"
        "f 1/1 2/2 3/3\n"
        "f 1//1 2//1 3//1\n"
        "f 1/1/1 2/2/1 3/3/1 # trailing comment\n"
        "v -1 -1 \\\n  -1\n"
        "f -1 -4 -3\n"
        "v 4 4 4\r\n"
        "f 1 2 3 4 5\r\n"
        "l 1 2\np 1\n"
        "\tv 7e-1 0.25 -3\n"
        "f -1/1/1 -2/2/1 -3//1\n";
    write_file(path, sizeof path, dir, "forms.obj", text, strlen(text));
    const double positions[] = {0, 0, 0, 1.5, 0, 0, 0, 2.5, 0, -1, -1, -1, 4, 4, 4, 0.7, 0.25, -3};
    const uint32_t triangles[] = {0, 1, 2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 3, 0, 1,
                                  0, 1, 2, 0, 2, 3, 0, 3, 4, 5, 4, 3};
    expect_mesh(path, positions, 6, triangles, 9, "obj", 0, 0);
    ms_test_rmdir(dir);
}

/* ---- OFF ------------------------------------------------------------------- */

static void test_off_variants(void **state)
{
    (void)state;
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    const char *plain =
        "OFF\n# a comment\n5 3 0\n"
        "0 0 0\n1 0 0\n1 1 0 # trailing\n0 1 0\n\n0.5 0.5 1\n"
        "3 0 1 2\n4 0 1 3 4   255 0 0\n3 2 3 4\n";
    const double positions[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 0.5, 1};
    const uint32_t triangles[] = {0, 1, 2, 0, 1, 3, 0, 3, 4, 2, 3, 4};
    write_file(path, sizeof path, dir, "plain.off", plain, strlen(plain));
    expect_mesh(path, positions, 5, triangles, 4, "off", 0, 0);
    const char *coloured =
        "COFF 5 3 9\n"
        "0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 9\n"
        "0.5 0.5 1 1 1 1 1\n"
        "3 0 1 2\n4 0 1 3 4\n3 2 3 4\n";
    write_file(path, sizeof path, dir, "coloured.off", coloured, strlen(coloured));
    expect_mesh(path, positions, 5, triangles, 4, "off", 0, 0);
    ms_test_rmdir(dir);
}

typedef struct order_check {
    uint64_t vertices, triangles, vertex_chunks;
} order_check;

static ms_status count_vertices(void *context, const double *positions, size_t count,
                                ms_error *err)
{
    (void)positions;
    (void)err;
    order_check *c = context;
    c->vertices += count;
    ++c->vertex_chunks;
    return MS_OK;
}

static ms_status check_order(void *context, const uint32_t *indices, size_t count, ms_error *err)
{
    (void)err;
    order_check *c = context;
    for (size_t i = 0; i < 3 * count; ++i)
        assert_true(indices[i] < c->vertices);
    c->triangles += count;
    return MS_OK;
}

static ms_status refuse(void *context, const uint32_t *indices, size_t count, ms_error *err)
{
    (void)context;
    (void)indices;
    (void)count;
    return ms_error_set(err, MS_ERR_ARG, "consumer says stop");
}

/* OBJ with v and f interleaved in 40,000 blocks: every triangle reaches the sink
 * after the vertices it uses; a sink error stops the read with its message. */
static void test_obj_interleaved_streaming_order(void **state)
{
    (void)state;
    char dir[4096], path[4200];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/interleaved.obj", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    for (int block = 0; block < 40000; ++block)
        fprintf(f, "v %d 0 0\nv %d 1 0\nv %d 0 1\nf -3 -2 -1\nf %d %d %d\n", block, block,
                block, 3 * block + 1, 3 * block + 3, 3 * block + 2);
    assert_int_equal(fclose(f), 0);
    order_check check = {0, 0, 0};
    ms_mesh_sink sink = {.context = &check, .vertices = count_vertices, .triangles = check_order};
    ms_mesh_read_report report;
    ms_error err;
    if (ms_mesh_read(path, &sink, &report, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(check.vertices, 120000);
    assert_int_equal(check.triangles, 80000);
    assert_int_equal(report.triangles, 80000);
    assert_int_equal(report.input_faces, 80000);
    assert_true(check.vertex_chunks < 40); /* chunks stay large despite interleaving */
    assert_true(report.bbox_max[0] == 39999.0);
    sink.triangles = refuse;
    assert_int_equal(ms_mesh_read(path, &sink, &report, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "consumer says stop");
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ply_odd_layout_all_encodings),
        cmocka_unit_test(test_ply_gzip_and_crlf),
        cmocka_unit_test(test_ply_fast_layout_cleaning),
        cmocka_unit_test(test_ply_tristrips),
        cmocka_unit_test(test_obj_all_face_forms),
        cmocka_unit_test(test_off_variants),
        cmocka_unit_test(test_obj_interleaved_streaming_order),
    };
    return cmocka_run_group_tests_name("reader_formats", tests, NULL, NULL);
}
