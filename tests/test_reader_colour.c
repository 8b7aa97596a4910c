/* Per-vertex colour read from PLY (every channel type, all three encodings), COFF
 * and OBJ, with exact bytes; the one-line errors for bad colour values and
 * counts; colour carried by ms_mesh (reserve, PLY write and read back); the
 * distinct count of `meshbake --info`; and the colour trefoil fixture. */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_mesh_colour.h"
#include "ms_mesh_io.h"
#include "support/ms_test.h"

typedef struct fixture {
    char dir[4096];
    char path[4200];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
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

static const char *write_bytes(fixture *f, const char *name, const void *data, size_t size)
{
    snprintf(f->path, sizeof f->path, "%s/%s", f->dir, name);
    ms_test_write_file(f->path, data, size);
    return f->path;
}

static const char *write_text(fixture *f, const char *name, const char *text)
{
    return write_bytes(f, name, text, strlen(text));
}

/* Loads path, which must succeed, and checks its colours exactly. */
static void expect_colours(const char *path, size_t vertices, const uint8_t *rgba, bool alpha)
{
    ms_mesh m = {0};
    ms_error err;
    if (ms_mesh_load(path, &m, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(m.vertex_count, vertices);
    assert_non_null(m.colours);
    assert_int_equal(m.colour_alpha, alpha);
    for (size_t i = 0; i < 4 * vertices; ++i)
        if (m.colours[i] != rgba[i])
            fail_msg("%s: vertex %zu channel %zu is %u, expected %u", path, i / 4, i % 4,
                     m.colours[i], rgba[i]);
    ms_mesh_free(&m);
}

static void expect_no_colour(const char *path)
{
    ms_mesh m = {0};
    ms_error err;
    if (ms_mesh_load(path, &m, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_null(m.colours);
    assert_false(m.colour_alpha);
    ms_mesh_free(&m);
}

/* Loads path, which must fail with code and the message "PATH: " + message. */
static void expect_error(const char *path, ms_status code, const char *message)
{
    ms_mesh m = {0};
    ms_error err;
    ms_error_clear(&err);
    assert_int_equal(ms_mesh_load(path, &m, NULL, &err), code);
    char want[1024];
    snprintf(want, sizeof want, "%s: %s", path, message);
    assert_string_equal(err.text, want);
    assert_null(strchr(err.text, '\n'));
    assert_null(m.colours);
    assert_null(m.positions);
}

/* ---- PLY: three vertices, one face, the colour in one type ------------------ */

typedef enum encoding { ASCII, LITTLE, BIG } encoding;

typedef struct buffer {
    unsigned char data[4096];
    size_t size;
} buffer;

static void put_text(buffer *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf((char *)b->data + b->size, sizeof b->data - b->size, fmt, ap);
    va_end(ap);
    assert_true(n >= 0 && b->size + (size_t)n < sizeof b->data);
    b->size += (size_t)n;
}

/* One value: type 'B' uchar, 'H' ushort, 'f' float, 'd' double, 'I' int. */
static void put_value(buffer *b, encoding e, char type, double v)
{
    if (e == ASCII) {
        put_text(b, type == 'f' || type == 'd' ? "%.17g " : "%.0f ", v);
        return;
    }
    unsigned char raw[8];
    size_t n;
    switch (type) {
    case 'B': { uint8_t x = (uint8_t)v; memcpy(raw, &x, n = 1); break; }
    case 'H': { uint16_t x = (uint16_t)v; memcpy(raw, &x, n = 2); break; }
    case 'I': { int32_t x = (int32_t)v; memcpy(raw, &x, n = 4); break; }
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
    assert_true(b->size + n <= sizeof b->data);
    memcpy(b->data + b->size, raw, n);
    b->size += n;
}

static const char *type_name(char type)
{
    return type == 'B' ? "uchar" : type == 'H' ? "ushort" : type == 'f' ? "float"
           : type == 'I' ? "int" : "double";
}

/* Header and body; returns the header's size. channels 3 or 4; prefix "" or
 * "diffuse_"; values[v][c] the colour of vertex v. */
static size_t build_ply(buffer *b, encoding e, char type, const char *prefix, int channels,
                        const double values[3][4])
{
    static const char *const formats[] = {"ascii", "binary_little_endian", "binary_big_endian"};
    static const char *const names[] = {"red", "green", "blue", "alpha"};
    b->size = 0;
    put_text(b, "ply\nformat %s 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\n", formats[e]);
    for (int c = 0; c < channels; ++c)
        put_text(b, "property %s %s%s\n", type_name(type), prefix, names[c]);
    put_text(b, "element face 1\nproperty list uchar int vertex_indices\nend_header\n");
    size_t header = b->size;
    for (int v = 0; v < 3; ++v) {
        put_value(b, e, 'f', v == 1);
        put_value(b, e, 'f', v == 2);
        put_value(b, e, 'f', 0);
        for (int c = 0; c < channels; ++c)
            put_value(b, e, type, values[v][c]);
        if (e == ASCII)
            put_text(b, "\n");
    }
    put_value(b, e, 'B', 3);
    for (int k = 0; k < 3; ++k)
        put_value(b, e, 'I', k);
    if (e == ASCII)
        put_text(b, "\n");
    return header;
}

typedef struct channel_case {
    char type;
    double in[3][4];
    uint8_t out[3][4];
} channel_case;

static const channel_case channel_cases[] = {
    {'B', {{0, 255, 128, 7}, {255, 0, 1, 254}, {10, 20, 30, 40}},
     {{0, 255, 128, 7}, {255, 0, 1, 254}, {10, 20, 30, 40}}},
    /* v * 255 / 65535 rounded: 128 -> 0.498, 129 -> 0.502, 385 -> 1.498, 386 -> 1.502 */
    {'H', {{0, 65535, 128, 129}, {32767, 32768, 385, 386}, {65407, 65406, 1, 0}},
     {{0, 255, 0, 1}, {127, 128, 1, 2}, {255, 254, 0, 0}}},
    /* v * 255 rounded: 0.25 -> 63.75, 0.75 -> 191.25, 0.998 -> 254.49, 0.999 -> 254.745 */
    {'f', {{0, 1, 0.5, 0.6}, {1.0 / 255, 254.0 / 255, 0.25, 0.75}, {0.001, 0.998, 0.999, 0.2}},
     {{0, 255, 128, 153}, {1, 254, 64, 191}, {0, 254, 255, 51}}},
    {'d', {{0, 1, 0.5, 0.6}, {1.0 / 255, 254.0 / 255, 0.25, 0.75}, {0.001, 0.998, 0.999, 0.2}},
     {{0, 255, 128, 153}, {1, 254, 64, 191}, {0, 254, 255, 51}}},
};

static void test_ply_channel_types(void **state)
{
    fixture *f = *state;
    for (size_t k = 0; k < sizeof channel_cases / sizeof *channel_cases; ++k)
        for (encoding e = ASCII; e <= BIG; ++e)
            for (int channels = 3; channels <= 4; ++channels) {
                const channel_case *cc = &channel_cases[k];
                buffer b;
                build_ply(&b, e, cc->type, channels == 3 ? "" : "diffuse_", channels, cc->in);
                uint8_t want[3][4];
                memcpy(want, cc->out, sizeof want);
                for (int v = 0; v < 3 && channels == 3; ++v)
                    want[v][3] = 255;
                expect_colours(write_bytes(f, "c.ply", b.data, b.size), 3, &want[0][0],
                               channels == 4);
            }
}

/* Channels of different types in one file, and a list between them (the general
 * binary path); a lone red is no colour. */
static void test_ply_mixed_layouts(void **state)
{
    fixture *f = *state;
    static const char *const formats[] = {"ascii", "binary_little_endian", "binary_big_endian"};
    /* per vertex: red (uchar), x, green (ushort), y, a list of n uchars, blue (double), z */
    static const double rows[3][7] = {{255, 0, 65535, 0, 2, 1, 0}, {0, 1, 0, 0, 0, 0, 0},
                                      {128, 0, 257, 1, 1, 0.5, 0}};
    static const char types[7] = {'B', 'f', 'H', 'f', 'L', 'd', 'f'};
    static const uint8_t want[3][4] = {{255, 255, 255, 255}, {0, 0, 0, 255}, {128, 1, 128, 255}};
    for (encoding e = ASCII; e <= BIG; ++e) {
        buffer b = {.size = 0};
        put_text(&b, "ply\nformat %s 1.0\nelement vertex 3\nproperty uchar red\n"
                     "property float x\nproperty ushort green\nproperty float y\n"
                     "property list uchar uchar extra\nproperty double blue\nproperty float z\n"
                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n",
                 formats[e]);
        for (int v = 0; v < 3; ++v) {
            for (int k = 0; k < 7; ++k) {
                if (types[k] != 'L') {
                    put_value(&b, e, types[k], rows[v][k]);
                    continue;
                }
                put_value(&b, e, 'B', rows[v][k]);
                for (int item = 0; item < (int)rows[v][k]; ++item)
                    put_value(&b, e, 'B', 7);
            }
            if (e == ASCII)
                put_text(&b, "\n");
        }
        put_value(&b, e, 'B', 3);
        for (int k = 0; k < 3; ++k)
            put_value(&b, e, 'I', k);
        expect_colours(write_bytes(f, "mixed.ply", b.data, b.size), 3, &want[0][0], false);
    }
    const char *lone = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                       "property float y\nproperty float z\nproperty int red\nproperty uchar alpha\n"
                       "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                       "0 0 0 999 1\n1 0 0 -5 2\n0 1 0 7 3\n3 0 1 2\n";
    expect_no_colour(write_text(f, "lone.ply", lone));
}

static void test_ply_bad_values(void **state)
{
    fixture *f = *state;
    static const struct {
        char type;
        int vertex, channel;
        double value;
        ms_status code;
        const char *message; /* after "line N: " or "byte offset N: " */
    } cases[] = {
        {'f', 1, 0, 1.5, MS_ERR_RANGE, "vertex 1: colour red = 1.5 is not in 0..1 (float)"},
        {'f', 2, 2, -0.25, MS_ERR_RANGE, "vertex 2: colour blue = -0.25 is not in 0..1 (float)"},
        {'d', 0, 1, NAN, MS_ERR_RANGE, "vertex 0: colour green = nan is not in 0..1 (double)"},
        {'d', 2, 3, 1.0000001, MS_ERR_RANGE,
         "vertex 2: colour alpha = 1.0000001 is not in 0..1 (double)"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; ++k)
        for (encoding e = ASCII; e <= BIG; ++e) {
            double values[3][4] = {{0, 0, 0, 1}, {0, 0, 0, 1}, {0, 0, 0, 1}};
            values[cases[k].vertex][cases[k].channel] = cases[k].value;
            buffer b;
            size_t header = build_ply(&b, e, cases[k].type, "", 4, values);
            char message[512];
            if (e == ASCII) /* 13 header lines */
                snprintf(message, sizeof message, "line %d: %s", 14 + cases[k].vertex,
                         cases[k].message);
            else /* the vertex's record: 12 bytes of position, 4 colour values */
                snprintf(message, sizeof message, "byte offset %zu: %s",
                         header + (size_t)cases[k].vertex *
                                      (12 + 4 * (cases[k].type == 'f' ? 4 : 8)),
                         cases[k].message);
            expect_error(write_bytes(f, "bad.ply", b.data, b.size), cases[k].code, message);
        }
}

static void test_ply_bad_ascii(void **state)
{
    fixture *f = *state;
    const char *head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                       "property float y\nproperty float z\n";
    static const struct {
        const char *properties, *vertices;
        ms_status code;
        const char *message;
    } cases[] = {
        {"property uchar red\nproperty uchar green\nproperty uchar blue\n", "0 0 0 1 2 3\n0 0 1 1 2\n",
         MS_ERR_FORMAT, "line 14: missing value for blue"},
        {"property uchar red\nproperty uchar green\nproperty uchar blue\n", "0 0 0 1 2 3\n0 0 1 1 2 256\n",
         MS_ERR_RANGE, "line 14: vertex 1: colour blue = 256 is not an integer in 0..255 (uchar)"},
        {"property uchar red\nproperty uchar green\nproperty uchar blue\n", "0 0 0 1.5 2 3\n0 0 1 1 2 3\n",
         MS_ERR_RANGE, "line 13: vertex 0: colour red = 1.5 is not an integer in 0..255 (uchar)"},
        {"property uchar red\nproperty uchar green\nproperty uchar blue\n", "0 0 0 -1 2 3\n0 0 1 1 2 3\n",
         MS_ERR_RANGE, "line 13: vertex 0: colour red = -1 is not an integer in 0..255 (uchar)"},
        {"property ushort red\nproperty ushort green\nproperty ushort blue\n", "0 0 0 1 65536 3\n",
         MS_ERR_RANGE, "line 13: vertex 0: colour green = 65536 is not an integer in 0..65535 (ushort)"},
        {"property float red\nproperty float green\nproperty float blue\n", "0 0 0 1 nan 0\n",
         MS_ERR_RANGE, "line 13: vertex 0: colour green = nan is not in 0..1 (float)"},
        {"property float red\nproperty float green\nproperty float blue\n", "0 0 0 1 inf 0\n",
         MS_ERR_RANGE, "line 13: vertex 0: colour green = inf is not in 0..1 (float)"},
        {"property int red\nproperty uchar green\nproperty uchar blue\n", "",
         MS_ERR_UNSUPPORTED, "line 10: colour property red of type int (uchar, ushort, float or "
                             "double expected)"},
        {"property uchar red\nproperty uchar green\nproperty uchar blue\nproperty char alpha\n", "",
         MS_ERR_UNSUPPORTED, "line 11: colour property alpha of type char (uchar, ushort, float or "
                             "double expected)"},
        {"property uchar red\nproperty list uchar uchar green\nproperty uchar blue\n", "",
         MS_ERR_FORMAT, "line 10: vertex property green is a list"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; ++k) {
        char text[1024];
        snprintf(text, sizeof text, "%s%selement face 1\nproperty list uchar int vertex_indices\n"
                 "end_header\n%s3 0 1 1\n", head, cases[k].properties, cases[k].vertices);
        expect_error(write_text(f, "bad.ply", text), cases[k].code, cases[k].message);
    }
}

/* ---- OFF -------------------------------------------------------------------- */

static void test_off_colour(void **state)
{
    fixture *f = *state;
    static const uint8_t ints[3][4] = {{0, 255, 128, 255}, {255, 0, 7, 255}, {1, 2, 3, 255}};
    expect_colours(write_text(f, "a.off", "COFF\n3 1 0\n0 0 0 0 255 128\n1 0 0 255 0 7\n"
                                          "0 1 0 1 2 3\n3 0 1 2 255 0 0\n"),
                   3, &ints[0][0], false);
    static const uint8_t rgba[3][4] = {{0, 255, 128, 64}, {255, 0, 0, 255}, {51, 153, 0, 0}};
    /* floats when any value has a fraction or an exponent; face colours ignored */
    expect_colours(write_text(f, "b.off", "COFF 3 1 0\n0 0 0 0 1. 0.5 0.25\n1 0 0 1 0 1e-3 1.0\n"
                                          "0 1 0 0.2 0.6 0 0.0\n3 0 1 2 0.5 0.5 0.5 1\n"),
                   3, &rgba[0][0], true);
    static const uint8_t normals[3][4] = {{10, 20, 30, 40}, {50, 60, 70, 80}, {255, 255, 255, 255}};
    expect_colours(write_text(f, "c.off", "CNOFF\n3 1 0\n0 0 0 0 0 1 10 20 30 40\n"
                                          "1 0 0 0 0 1 50 60 70 80\n0 1 0 0 0 1 255 255 255 255\n"
                                          "3 0 1 2\n"),
                   3, &normals[0][0], true);
    static const uint8_t texture[3][4] = {{1, 2, 3, 255}, {4, 5, 6, 255}, {7, 8, 9, 255}};
    expect_colours(write_text(f, "d.off", "STCOFF\n3 1 0\n0 0 0 1 2 3 0.5 0.5\n"
                                          "1 0 0 4 5 6 0 0\n0 1 0 7 8 9 1 1\n3 0 1 2\n"),
                   3, &texture[0][0], false);
    /* plain OFF: numbers after x y z are not colour */
    expect_no_colour(write_text(f, "e.off", "OFF\n3 1 0\n0 0 0 9 9 9\n1 0 0 9 9 9\n0 1 0\n"
                                            "3 0 1 2\n"));
}

static void test_off_bad_colour(void **state)
{
    fixture *f = *state;
    static const struct {
        const char *vertices;
        ms_status code;
        const char *message;
    } cases[] = {
        {"0 0 0 1 2 3\n1 0 0 1 2\n0 1 0 1 2 3\n", MS_ERR_FORMAT,
         "line 4: vertex 1: 2 colour values (3 or 4 expected)"},
        {"0 0 0\n1 0 0 1 2 3\n0 1 0 1 2 3\n", MS_ERR_FORMAT,
         "line 3: vertex 0: 0 colour values (3 or 4 expected)"},
        {"0 0 0 1 2 3\n1 0 0 1 2 3 4 5\n0 1 0 1 2 3\n", MS_ERR_FORMAT,
         "line 4: vertex 1: 5 colour values (3 or 4 expected)"},
        {"0 0 0 1 2 3\n1 0 0 1 2 3 4\n0 1 0 1 2 3\n", MS_ERR_FORMAT,
         "line 4: vertex 1: 4 colour values, vertex 0 has 3"},
        {"0 0 0 1 2 3 4\n1 0 0 1 2 3\n0 1 0 1 2 3\n", MS_ERR_FORMAT,
         "line 4: vertex 1: 3 colour values, vertex 0 has 4"},
        {"0 0 0 1 2 3\n1 0 0 1 256 3\n0 1 0 1 2 3\n", MS_ERR_RANGE,
         "line 4: vertex 1: colour value 256 is not in 0..255"},
        {"0 0 0 1 2 3\n1 0 0 1 2 3\n0 1 0 -1 2 3\n", MS_ERR_RANGE,
         "line 5: vertex 2: colour value -1 is not in 0..255"},
        {"0 0 0 0.5 1.5 0\n1 0 0 1 2 3\n0 1 0 1 2 3\n", MS_ERR_RANGE,
         "line 3: vertex 0: colour value 1.5 is not in 0..1"},
        {"0 0 0 1 2 3\n1 0 0 0.5 nan 0\n0 1 0 1 2 3\n", MS_ERR_RANGE,
         "line 4: vertex 1: colour value nan is not in 0..1"},
        {"0 0 0 1 2 x\n1 0 0 1 2 3\n0 1 0 1 2 3\n", MS_ERR_FORMAT,
         "line 3: non-numeric vertex value"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; ++k) {
        char text[512];
        snprintf(text, sizeof text, "COFF\n3 1 0\n%s3 0 1 2\n", cases[k].vertices);
        expect_error(write_text(f, "bad.off", text), cases[k].code, cases[k].message);
    }
}

/* ---- OBJ -------------------------------------------------------------------- */

static void test_obj_colour(void **state)
{
    fixture *f = *state;
    static const uint8_t rgb[3][4] = {{0, 255, 128, 255}, {1, 254, 64, 255}, {51, 153, 0, 255}};
    expect_colours(write_text(f, "a.obj", "v 0 0 0 0 1 0.5\nv 1 0 0 0.003921569 0.996078431 0.25\n"
                                          "v 0 1 0 0.2 0.6 0 # a comment\nf 1 2 3\n"),
                   3, &rgb[0][0], false);
    static const uint8_t rgba[3][4] = {{0, 0, 0, 0}, {255, 255, 255, 255}, {128, 128, 128, 128}};
    expect_colours(write_text(f, "b.obj", "v 0 0 0 0 0 0 0\nv 1 0 0 1 1 1 1\n"
                                          "v 0 1 0 .5 .5 .5 .5\nf 1 2 3\n"),
                   3, &rgba[0][0], true);
    expect_no_colour(write_text(f, "c.obj", "v 0 0 0\nv 1 0 0 1\nv 0 1 0\nf 1 2 3\n"));
}

static void test_obj_bad_colour(void **state)
{
    fixture *f = *state;
    static const struct {
        const char *vertices;
        ms_status code;
        const char *message;
    } cases[] = {
        {"v 0 0 0 1 1 1\nv 1 0 0 1 1\nv 0 1 0 1 1 1\n", MS_ERR_FORMAT,
         "line 2: v statement with 5 values (x y z [w], or x y z r g b [a])"},
        {"v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0 1 1 1\n", MS_ERR_FORMAT,
         "line 2: vertex 2 has 0 colour values, vertex 1 has 3 (colour must be on every vertex "
         "or on none)"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0 1 1 1\n", MS_ERR_FORMAT,
         "line 3: vertex 3 has 3 colour values, vertex 1 has 0 (colour must be on every vertex "
         "or on none)"},
        {"v 0 0 0 1 1 1 1\nv 1 0 0 1 1 1\nv 0 1 0 1 1 1\n", MS_ERR_FORMAT,
         "line 2: vertex 2 has 3 colour values, vertex 1 has 4 (colour must be on every vertex "
         "or on none)"},
        {"v 0 0 0 1 1 1\nv 1 0 0 1 255 1\nv 0 1 0 1 1 1\n", MS_ERR_RANGE,
         "line 2: vertex 2: colour value 255 is not in 0..1"},
        {"v 0 0 0 1 1 1\nv 1 0 0 1 1 1\nv 0 1 0 -0.5 1 1\n", MS_ERR_RANGE,
         "line 3: vertex 3: colour value -0.5 is not in 0..1"},
        {"v 0 0 0 nan 1 1\nv 1 0 0 1 1 1\nv 0 1 0 1 1 1\n", MS_ERR_RANGE,
         "line 1: vertex 1: colour value nan is not in 0..1"},
        {"v 0 0 0 1 1 1 1 1\n", MS_ERR_FORMAT, "line 1: too many values in v statement"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; ++k) {
        char text[512];
        snprintf(text, sizeof text, "%sf 1 2 3\n", cases[k].vertices);
        expect_error(write_text(f, "bad.obj", text), cases[k].code, cases[k].message);
    }
}

/* ---- ms_mesh carries colour -------------------------------------------------- */

static void test_mesh_colours_reserve_and_write(void **state)
{
    fixture *f = *state;
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_reserve(&m, 2, 1, &err), MS_OK);
    m.vertex_count = 2;
    memset(m.positions, 0, 6 * sizeof(double));
    assert_int_equal(ms_mesh_add_colours(&m, false, &err), MS_OK);
    assert_int_equal(m.colours[0], 255); /* existing vertices opaque white */
    assert_int_equal(m.colours[7], 255);
    assert_false(m.colour_alpha);
    m.colours[4] = 9;
    assert_int_equal(ms_mesh_reserve(&m, 5000, 2, &err), MS_OK);
    assert_true(m.vertex_capacity >= 5000);
    assert_int_equal(m.colours[4], 9); /* kept while growing */
    for (size_t v = 2; v < 5000; ++v) {
        m.positions[3 * v] = (double)v, m.positions[3 * v + 1] = 0.5 * (double)v;
        m.positions[3 * v + 2] = 1;
        const uint8_t c[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v * 7), (uint8_t)(v * 3)};
        memcpy(m.colours + 4 * v, c, 4);
    }
    m.vertex_count = 5000;
    static const uint32_t tris[6] = {0, 1, 2, 2, 3, 4999};
    memcpy(m.triangles, tris, sizeof tris);
    m.triangle_count = 2;
    for (int alpha = 0; alpha <= 1; ++alpha)
        for (int binary = 0; binary <= 1; ++binary) {
            m.colour_alpha = alpha;
            snprintf(f->path, sizeof f->path, "%s/w.ply", f->dir);
            assert_int_equal(ms_ply_write(f->path, &m, binary, false, &err), MS_OK);
            uint8_t *want = malloc(4 * 5000);
            memcpy(want, m.colours, 4 * 5000);
            for (size_t v = 0; v < 5000 && !alpha; ++v)
                want[4 * v + 3] = 255;
            expect_colours(f->path, 5000, want, alpha);
            free(want);
        }
    ms_mesh_free(&m);
    assert_null(m.colours);
}

static void test_distinct_count(void **state)
{
    (void)state;
    ms_error err;
    uint64_t n = 99;
    assert_int_equal(ms_colour_count_distinct(NULL, 0, &n, &err), MS_OK);
    assert_int_equal(n, 0);
    size_t count = 100000;
    uint8_t *rgba = malloc(4 * count);
    for (size_t i = 0; i < count; ++i) {
        rgba[4 * i] = (uint8_t)(i % 7), rgba[4 * i + 1] = (uint8_t)(i % 11);
        rgba[4 * i + 2] = 200, rgba[4 * i + 3] = 255;
    }
    assert_int_equal(ms_colour_count_distinct(rgba, count, &n, &err), MS_OK);
    assert_int_equal(n, 77);
    rgba[3] = 254; /* differs from the others only in alpha */
    assert_int_equal(ms_colour_count_distinct(rgba, count, &n, &err), MS_OK);
    assert_int_equal(n, 78);
    for (size_t i = 0; i < count; ++i) /* every colour different, across all four bytes */
        for (int c = 0; c < 4; ++c)
            rgba[4 * i + c] = (uint8_t)((i * 2654435761u) >> (8 * c));
    assert_int_equal(ms_colour_count_distinct(rgba, count, &n, &err), MS_OK);
    assert_int_equal(n, count);
    memset(rgba, 0, 4 * count);
    assert_int_equal(ms_colour_count_distinct(rgba, count, &n, &err), MS_OK);
    assert_int_equal(n, 1);
    free(rgba);
}

/* ---- the colour trefoil (tests/data, made by make-fixtures.py) --------------- */

static void test_trefoil_fixture(void **state)
{
    (void)state;
    const char *path = "tests/data/trefoil_color.ply.gz"; /* in git: tests run from the root */
    ms_mesh m = {0};
    ms_error err;
    if (ms_mesh_load(path, &m, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(m.vertex_count, 5120);
    assert_non_null(m.colours);
    assert_true(m.colour_alpha);
    static const uint8_t first[4] = {255, 63, 63, 255}, last[4] = {254, 72, 55, 255};
    assert_memory_equal(m.colours, first, 4);
    assert_memory_equal(m.colours + 4, first, 4);
    assert_memory_equal(m.colours + 4 * 5119, last, 4);
    uint64_t distinct;
    assert_int_equal(ms_colour_count_distinct(m.colours, m.vertex_count, &distinct, &err), MS_OK);
    assert_int_equal(distinct, 256);
    ms_mesh_free(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ply_channel_types),
        cmocka_unit_test(test_ply_mixed_layouts),
        cmocka_unit_test(test_ply_bad_values),
        cmocka_unit_test(test_ply_bad_ascii),
        cmocka_unit_test(test_off_colour),
        cmocka_unit_test(test_off_bad_colour),
        cmocka_unit_test(test_obj_colour),
        cmocka_unit_test(test_obj_bad_colour),
        cmocka_unit_test(test_mesh_colours_reserve_and_write),
        cmocka_unit_test(test_distinct_count),
        cmocka_unit_test(test_trefoil_fixture),
    };
    return cmocka_run_group_tests_name("reader_colour", tests, setup, teardown);
}
