/* A corpus of broken files made from the real models: each must fail with the
 * expected status and a one-line message naming the file and the line or byte
 * offset. Runs under ASan/UBSan, so a crash or leak fails it too. */
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
#include "support/ms_test.h"

typedef struct blob {
    char *data;
    size_t size;
} blob;

typedef struct corpus {
    char dir[4096];
    blob ascii;  /* stanford_dragon_vrip_res4.ply: 10 header lines, 5205 V, 11102 F */
    blob binary; /* trefoil_color.ply: LE, 28-byte vertices, 13-byte faces */
    size_t binary_header;
    blob obj;    /* glmark2_bunny.obj */
    int cases;
} corpus;

static blob read_model(const char *file)
{
    char path[4096];
    ms_test_model_path(path, sizeof path, file);
    gzFile gz = gzopen(path, "rb");
    assert_non_null(gz);
    blob b = {NULL, 0};
    size_t cap = 0;
    for (;;) {
        if (cap - b.size < 65536) {
            cap = cap ? 2 * cap : 1 << 20;
            b.data = realloc(b.data, cap);
            assert_non_null(b.data);
        }
        int got = gzread(gz, b.data + b.size, 65536);
        assert_true(got >= 0);
        if (got == 0)
            break;
        b.size += (size_t)got;
    }
    gzclose(gz);
    return b;
}

static int setup(void **state)
{
    corpus *c = calloc(1, sizeof *c);
    ms_test_tmpdir(c->dir, sizeof c->dir);
    c->ascii = read_model("stanford_dragon_vrip_res4.ply.gz");
    c->binary = read_model("trefoil_color.ply.gz");
    c->obj = read_model("glmark2_bunny.obj.gz");
    const char *end = strstr(c->binary.data, "end_header\n");
    c->binary_header = (size_t)(end - c->binary.data) + strlen("end_header\n");
    *state = c;
    return 0;
}

static int teardown(void **state)
{
    corpus *c = *state;
    ms_test_rmdir(c->dir);
    free(c->ascii.data);
    free(c->binary.data);
    free(c->obj.data);
    free(c);
    return 0;
}

/* Writes base[0..cut) + insert + base[resume..) as a new case file. */
static const char *write_case(corpus *c, char *path, size_t size, const char *ext,
                              const blob *base, size_t cut, const void *insert, size_t insert_len,
                              size_t resume)
{
    snprintf(path, size, "%s/case%03d.%s", c->dir, c->cases++, ext);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    if (cut)
        assert_int_equal(fwrite(base->data, 1, cut, f), cut);
    if (insert_len)
        assert_int_equal(fwrite(insert, 1, insert_len, f), insert_len);
    if (resume < base->size)
        assert_int_equal(fwrite(base->data + resume, 1, base->size - resume, f),
                         base->size - resume);
    assert_int_equal(fclose(f), 0);
    return path;
}

/* Loads path and checks the status and that the message names the file and holds
 * `where` (e.g. "line 12:" or "byte offset 300:"). */
static void expect_failure(const char *path, ms_status code, const char *where)
{
    ms_mesh mesh = {0};
    ms_error err;
    ms_error_clear(&err);
    ms_status st = ms_mesh_load(path, &mesh, NULL, &err);
    if (st != code)
        fail_msg("%s: status %d (%s), expected %d; message: %s", path, st, ms_status_name(st),
                 code, err.text);
    assert_int_equal(err.code, code);
    assert_null(mesh.positions);
    assert_int_equal(mesh.triangle_count, 0);
    if (strncmp(err.text, path, strlen(path)) != 0)
        fail_msg("message does not start with the file name: %s", err.text);
    if (!strstr(err.text, where))
        fail_msg("message lacks '%s': %s", where, err.text);
    assert_null(strchr(err.text, '\n'));
}

/* Byte offset where line n (1-based) starts. */
static size_t line_start(const blob *b, int n)
{
    size_t at = 0;
    for (int line = 1; line < n; ++line) {
        const char *nl = memchr(b->data + at, '\n', b->size - at);
        assert_non_null(nl);
        at = (size_t)(nl - b->data) + 1;
    }
    return at;
}

/* Lines in b (each ends with a newline). */
static int line_count(const blob *b)
{
    int n = 0;
    for (size_t i = 0; i < b->size; ++i)
        n += b->data[i] == '\n';
    return n;
}

/* A line of a base file replaced by text (a line past the last one: text
 * appended), and how loading must fail. */
typedef struct line_case {
    int line;
    const char *text;
    ms_status code;
    const char *where;
} line_case;

/* Writes each case from base as a .ext file and expects it to fail as it says. */
static void expect_line_cases(corpus *c, const char *ext, const blob *base, const line_case *cases, size_t count)
{
    char path[4200];
    int lines = line_count(base);
    for (size_t i = 0; i < count; ++i) {
        size_t from = cases[i].line <= lines ? line_start(base, cases[i].line) : base->size;
        size_t to = cases[i].line <= lines ? line_start(base, cases[i].line + 1) : base->size;
        expect_failure(write_case(c, path, sizeof path, ext, base, from, cases[i].text, strlen(cases[i].text), to),
                       cases[i].code, cases[i].where);
    }
}

static void test_ascii_ply_truncated(void **state)
{
    corpus *c = *state;
    char path[4200], where[64];
    const blob *a = &c->ascii;
    /* In the header. */
    expect_failure(write_case(c, path, sizeof path, "ply", a, 30, NULL, 0, a->size), MS_ERR_FORMAT,
                   "line ");
    expect_failure(write_case(c, path, sizeof path, "ply", a, line_start(a, 10), NULL, 0, a->size),
                   MS_ERR_FORMAT, "ends inside the PLY header");
    /* At line boundaries in the vertex and face sections: the next record is missing. */
    static const int lines[] = {11, 12, 100, 5215, 5216, 5217, 9000, 16317};
    for (size_t i = 0; i < sizeof lines / sizeof lines[0]; ++i) {
        write_case(c, path, sizeof path, "ply", a, line_start(a, lines[i]), NULL, 0, a->size);
        snprintf(where, sizeof where, "line %d: file ends inside element %s", lines[i] - 1,
                 lines[i] <= 5215 ? "vertex" : "face");
        expect_failure(path, MS_ERR_FORMAT, where);
    }
    /* Inside a line: a vertex missing z, a face missing its last index. */
    size_t v = line_start(a, 2000);
    const char *space = memchr(a->data + v, ' ', 40);
    space = memchr(space + 1, ' ', 40);
    expect_failure(write_case(c, path, sizeof path, "ply", a, (size_t)(space - a->data), NULL, 0,
                              a->size),
                   MS_ERR_FORMAT, "line 2000: missing value for z");
    size_t f = line_start(a, 7001) - 2; /* the line ends with "INDEX \n" */
    while (a->data[f - 1] != ' ')
        --f;
    expect_failure(write_case(c, path, sizeof path, "ply", a, f, NULL, 0, a->size),
                   MS_ERR_FORMAT, "line 7000: missing value");
}

static void test_ascii_ply_counts_lie(void **state)
{
    corpus *c = *state;
    char path[4200];
    const blob *a = &c->ascii;
    /* line 4: the vertex count; line 8: the face count */
    static const line_case cases[] = {
        {4, "element vertex 5206\n", MS_ERR_FORMAT, "line 5216: extra values"},
        {4, "element vertex 5204\n", MS_ERR_FORMAT, "line 5215: bad integer"},
        {4, "element vertex 4000000000\n", MS_ERR_FORMAT, "line 5216: extra values"},
        {4, "element vertex 99999999999\n", MS_ERR_RANGE, "line 4: 99999999999 vertices declared"},
        {4, "element vertex 1e3\n", MS_ERR_FORMAT, "line 4: bad element line"},
        {4, "element vertex -5\n", MS_ERR_FORMAT, "line 4: bad element line"},
        {8, "element face 11103\n", MS_ERR_FORMAT, "line 16317: file ends inside element face"},
        {8, "element face 11101\n", MS_ERR_FORMAT, "line 16317: data after the last element"},
        {8, "element face 999999999999999\n", MS_ERR_FORMAT, "file ends inside element face"},
        {8, "element face 0\n", MS_ERR_FORMAT, "line 5216: data after the last element"},
    };
    expect_line_cases(c, "ply", a, cases, sizeof cases / sizeof cases[0]);
    size_t fline = line_start(a, 8);
    /* No face element at all, vertices only: an empty mesh. */
    const char *no_faces = "end_header\n";
    size_t body_end = line_start(a, 5216);
    snprintf(path, sizeof path, "%s/case%03d.ply", c->dir, c->cases++);
    FILE *out = fopen(path, "wb");
    assert_non_null(out);
    fwrite(a->data, 1, fline, out);
    fwrite(no_faces, 1, strlen(no_faces), out);
    size_t body = line_start(a, 11);
    fwrite(a->data + body, 1, body_end - body, out);
    fclose(out);
    ms_mesh mesh = {0};
    ms_error err;
    assert_int_equal(ms_mesh_load(path, &mesh, NULL, &err), MS_ERR_EMPTY);
    assert_non_null(strstr(err.text, path));
    assert_non_null(strstr(err.text, "no triangles"));
}

static void test_ascii_ply_bad_values(void **state)
{
    corpus *c = *state;
    char path[4200];
    const blob *a = &c->ascii;
    static const line_case cases[] = {
        {3000, "nan 0.1 0.1 \n", MS_ERR_RANGE, "line 3000: vertex 2989 has a non-finite"},
        {3000, "0.1 inf 0.1 \n", MS_ERR_RANGE, "line 3000: vertex 2989 has a non-finite"},
        {3000, "0.1 0.1 1e999 \n", MS_ERR_RANGE, "line 3000: vertex 2989 has a non-finite"},
        {3000, "0.1 abc 0.1 \n", MS_ERR_FORMAT, "line 3000: non-numeric value for y"},
        {3000, "0.1 0.2,5 0.1 \n", MS_ERR_FORMAT, "line 3000: non-numeric value for y"},
        {3000, "0.1 0.2 0.3 0.4\n", MS_ERR_FORMAT, "line 3000: extra values"},
        {8000, "3 1 2 5205 \n", MS_ERR_RANGE, "line 8000: vertex index 5205 out of range"},
        {8000, "3 1 -1 2 \n", MS_ERR_RANGE, "line 8000: vertex index -1 out of range"},
        {8000, "3 1 2 99999999999999999999 \n", MS_ERR_FORMAT, "line 8000: bad integer"},
        {8000, "2 1 2 \n", MS_ERR_FORMAT, "line 8000: face with 2 vertices"},
        {8000, "0\n", MS_ERR_FORMAT, "line 8000: face with 0 vertices"},
        {8000, "3 1 2 3.5 \n", MS_ERR_FORMAT, "line 8000: bad integer"},
        {8000, "3 1 2 3 4 \n", MS_ERR_FORMAT, "line 8000: extra values"},
        {16318, "garbage after the end\n", MS_ERR_FORMAT, "line 16318: data after the last"},
    };
    expect_line_cases(c, "ply", a, cases, sizeof cases / sizeof cases[0]);
    /* An overlong line (2 MiB of digits) is refused, not buffered. */
    size_t n = 2u << 20;
    char *longline = malloc(n + 1);
    memset(longline, '1', n);
    longline[n] = '\n';
    size_t at = line_start(a, 4000);
    expect_failure(write_case(c, path, sizeof path, "ply", a, at, longline, n + 1, at),
                   MS_ERR_FORMAT, "line 4000: line longer than");
    free(longline);
    /* Header problems. */
    const char *bad_type = "property flaot x\n";
    size_t x = line_start(a, 5);
    expect_failure(write_case(c, path, sizeof path, "ply", a, x, bad_type, strlen(bad_type),
                              line_start(a, 6)),
                   MS_ERR_FORMAT, "line 5: unknown property type");
    expect_failure(write_case(c, path, sizeof path, "ply", a, x, NULL, 0, line_start(a, 6)),
                   MS_ERR_FORMAT, "has no property x");
    const char *format = "format binary_middle_endian 1.0\n";
    expect_failure(write_case(c, path, sizeof path, "ply", a, line_start(a, 2), format,
                              strlen(format), line_start(a, 3)),
                   MS_ERR_UNSUPPORTED, "line 2: unknown PLY format");
}

static void test_binary_ply(void **state)
{
    corpus *c = *state;
    char path[4200], where[96];
    const blob *b = &c->binary;
    const size_t h = c->binary_header, vertices = 5120, faces = 10240, stride = 28;
    const size_t face0 = h + vertices * stride;
    assert_int_equal(face0 + faces * 13, b->size);
    /* Truncation at many offsets: header, vertex records, face records. */
    static const size_t header_cuts[] = {5, 40, 150};
    for (size_t i = 0; i < 3; ++i)
        expect_failure(write_case(c, path, sizeof path, "ply", b, header_cuts[i], NULL, 0, b->size),
                       MS_ERR_FORMAT, "line ");
    const size_t body_cuts[] = {h, h + 1, h + 27, h + 28 * 1000 + 5, face0 - 1, face0,
                                face0 + 1, face0 + 13 * 777 + 12, b->size - 1};
    for (size_t i = 0; i < sizeof body_cuts / sizeof body_cuts[0]; ++i) {
        size_t cut = body_cuts[i];
        /* The message names the start of the record that is incomplete. */
        /* The message names the vertex record, or the face list item (count or
         * index), that is incomplete. */
        size_t record = cut < face0 ? h + (cut - h) / stride * stride
                                    : face0 + (cut - face0) / 13 * 13;
        if (cut > record && cut >= face0)
            record += 1 + (cut - record - 1) / 4 * 4;
        snprintf(where, sizeof where, "byte offset %zu: file ends inside the %s", record,
                 cut < face0 ? "vertex list" : "face list");
        expect_failure(write_case(c, path, sizeof path, "ply", b, cut, NULL, 0, b->size),
                       MS_ERR_FORMAT, where);
    }
    /* Trailing garbage. */
    snprintf(where, sizeof where, "byte offset %zu: 5 bytes after the last element", b->size);
    expect_failure(write_case(c, path, sizeof path, "ply", b, b->size, "junk\n", 5, b->size),
                   MS_ERR_FORMAT, where);
    /* An index out of range and a negative index, exactly located. */
    size_t at = face0 + 13 * 4321 + 1 + 4 * 2;
    int32_t bad = (int32_t)vertices;
    snprintf(where, sizeof where, "byte offset %zu: vertex index 5120 out of range", at);
    expect_failure(write_case(c, path, sizeof path, "ply", b, at, &bad, 4, at + 4), MS_ERR_RANGE,
                   where);
    bad = -7;
    snprintf(where, sizeof where, "byte offset %zu: vertex index -7 out of range", at);
    expect_failure(write_case(c, path, sizeof path, "ply", b, at, &bad, 4, at + 4), MS_ERR_RANGE,
                   where);
    /* A face with 2 vertices. */
    at = face0 + 13 * 100;
    snprintf(where, sizeof where, "byte offset %zu: face with 2 vertices", at);
    expect_failure(write_case(c, path, sizeof path, "ply", b, at, "\2", 1, at + 1), MS_ERR_FORMAT,
                   where);
    /* NaN and infinity in a coordinate. */
    float nan_value = __builtin_nanf(""), inf_value = __builtin_inff();
    at = h + stride * 10;
    snprintf(where, sizeof where, "byte offset %zu: vertex 10 has a non-finite coordinate", at);
    expect_failure(write_case(c, path, sizeof path, "ply", b, at + 4, &nan_value, 4, at + 8),
                   MS_ERR_RANGE, where);
    expect_failure(write_case(c, path, sizeof path, "ply", b, at + 8, &inf_value, 4, at + 12),
                   MS_ERR_RANGE, where);
    /* Wrong byte order declared: the big-endian reading of the first index is
     * out of range (or a coordinate is not finite); either way it is refused. */
    const char *le = strstr(b->data, "binary_little_endian");
    size_t le_at = (size_t)(le - b->data);
    write_case(c, path, sizeof path, "ply", b, le_at, "binary_big_endian", 17, le_at + 20);
    ms_mesh mesh = {0};
    ms_error err;
    ms_status st = ms_mesh_load(path, &mesh, NULL, &err);
    assert_true(st == MS_ERR_RANGE);
    assert_non_null(strstr(err.text, "byte offset"));
    assert_non_null(strstr(err.text, path));
    /* Counts that lie. */
    const char *vline = strstr(b->data, "element vertex 5120\n");
    size_t vl = (size_t)(vline - b->data);
    const char *more = "element vertex 5121\n";
    expect_failure(write_case(c, path, sizeof path, "ply", b, vl, more, strlen(more),
                              vl + strlen(more)),
                   MS_ERR_FORMAT, "byte offset");
    const char *fline = strstr(b->data, "element face 10240\n");
    size_t fl = (size_t)(fline - b->data);
    const char *fewer = "element face 10239\n";
    snprintf(where, sizeof where, "byte offset %zu: 13 bytes after the last element",
             b->size - 13);
    expect_failure(write_case(c, path, sizeof path, "ply", b, fl, fewer, strlen(fewer),
                              fl + strlen(fewer)),
                   MS_ERR_FORMAT, where);
    const char *lots = "element face 10241\n";
    snprintf(where, sizeof where, "byte offset %zu: file ends inside the face list", b->size);
    expect_failure(write_case(c, path, sizeof path, "ply", b, fl, lots, strlen(lots),
                              fl + strlen(lots)),
                   MS_ERR_FORMAT, where);
    const char *absurd = "element face 4000000000000000000\n";
    expect_failure(write_case(c, path, sizeof path, "ply", b, fl, absurd, strlen(absurd),
                              fl + strlen(fewer)),
                   MS_ERR_FORMAT, "file ends inside the face list");
}

static void test_obj(void **state)
{
    corpus *c = *state;
    char path[4200];
    const blob *o = &c->obj;
    /* The bunny: v lines 1..34835, f lines 34836..104501, nothing else. */
    static const line_case cases[] = {
        {35963, "f 1 2\n", MS_ERR_FORMAT, "line 35963: face with 2 vertices"},
        {35963, "f 1 2 34836\n", MS_ERR_RANGE, "line 35963: vertex index 34836 out of range"},
        {35963, "f 1 0 3\n", MS_ERR_RANGE, "line 35963: vertex index 0"},
        {35963, "f 1 2 -34836\n", MS_ERR_RANGE, "line 35963: vertex index -34836 out of range"},
        {35963, "f 1 2/x 3\n", MS_ERR_FORMAT, "line 35963: bad face corner"},
        {500, "v 0 nan 0\n", MS_ERR_RANGE, "line 500: vertex 500 has a non-finite"},
        {500, "v 0 0\n", MS_ERR_FORMAT, "line 500: v statement with 2 values"},
        {500, "v 0 0 zero\n", MS_ERR_FORMAT, "line 500: non-numeric value"},
        {500, "\x01\x02\x03\n", MS_ERR_FORMAT, "line 500: not an OBJ statement"},
    };
    expect_line_cases(c, "obj", o, cases, sizeof cases / sizeof cases[0]);
    /* Truncated in the middle of a face line. */
    size_t mid = line_start(o, 50000) + 3;
    write_case(c, path, sizeof path, "obj", o, mid, NULL, 0, o->size);
    ms_mesh mesh = {0};
    ms_error err;
    ms_status st = ms_mesh_load(path, &mesh, NULL, &err);
    assert_int_equal(st, MS_ERR_FORMAT);
    assert_non_null(strstr(err.text, "line 50000: face with"));
    /* A comment only, then vertices only: no triangles. */
    const char *comment = "# only a comment\n";
    expect_failure(write_case(c, path, sizeof path, "obj", o, 0, comment, strlen(comment),
                              o->size + 1),
                   MS_ERR_EMPTY, "no triangles");
    expect_failure(write_case(c, path, sizeof path, "obj", o, line_start(o, 34836), NULL, 0,
                              o->size + 1),
                   MS_ERR_EMPTY, "no triangles");
}

static void test_off_unknown_and_gzip(void **state)
{
    corpus *c = *state;
    char path[4200];
    static const struct { const char *text; ms_status code; const char *where; } cases[] = {
        {"OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n", MS_ERR_FORMAT, "line 5: file ends after 3 of 4"},
        {"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", MS_ERR_FORMAT, "line 6: file ends after 1 of 2"},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", MS_ERR_FORMAT, "line 7: data after"},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", MS_ERR_RANGE, "line 6: vertex index 3"},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 inf 0\n3 0 1 2\n", MS_ERR_RANGE, "line 5: vertex 2"},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 0 0\n", MS_ERR_EMPTY, "no triangles"},
        {"OFF\nthree 1 0\n", MS_ERR_FORMAT, "line 2: bad vertex count"},
        {"4OFF\n3 1 0\n", MS_ERR_UNSUPPORTED, "line 1: unsupported OFF variant"},
        {"MESH 3 1\n1 2 3\n", MS_ERR_UNSUPPORTED, "byte offset 0: unknown format"},
        {"\x89PNG\r\n\x1a\n", MS_ERR_UNSUPPORTED, "byte offset 0: unknown format"},
        {"plyx\n", MS_ERR_UNSUPPORTED, "unknown format"},
        {"", MS_ERR_EMPTY, "file is empty"},
        {"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
         "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
         MS_ERR_UNSUPPORTED, "line 9: element face before element vertex"},
        {"ply\nformat ascii 1.0\nproperty float x\n", MS_ERR_FORMAT,
         "line 3: property before any element"},
        {"ply\nelement vertex 3\n", MS_ERR_FORMAT, "line 2: 'element' before the format line"},
        {"ply\nformat ascii 2.0\n", MS_ERR_UNSUPPORTED, "line 2: PLY version 2.0"},
        {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float x\n",
         MS_ERR_FORMAT, "line 5: duplicate property x"},
        {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list float int vertex_indices\n",
         MS_ERR_FORMAT, "line 8: list count type must be an integer"},
        {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list uchar int corners\nend_header\n",
         MS_ERR_FORMAT, "line 9: element face has no vertex_indices list"},
        {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0\n1 0 0\n0 1 0\n3 0 1 1\n",
         MS_ERR_EMPTY, "no triangles (1 faces read, 1 dropped)"},
        {"ply\nformat ascii 1.0\nbogus line\n", MS_ERR_FORMAT, "line 3: unknown header keyword"},
    };
    blob none = {NULL, 0};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i)
        expect_failure(write_case(c, path, sizeof path, "off", &none, 0, cases[i].text,
                                  strlen(cases[i].text), 0),
                       cases[i].code, cases[i].where);
    /* A truncated gzip stream. */
    char model[4096];
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res4.ply.gz");
    FILE *f = fopen(model, "rb");
    assert_non_null(f);
    static char gz[200000];
    size_t n = fread(gz, 1, sizeof gz, f);
    fclose(f);
    assert_true(n > 100000);
    blob whole = {gz, n};
    expect_failure(write_case(c, path, sizeof path, "ply.gz", &whole, n / 2, NULL, 0, n),
                   MS_ERR_IO, "byte offset");
    /* Missing file and directory. */
    ms_mesh mesh = {0};
    ms_error err;
    assert_int_equal(ms_mesh_load("/nonexistent/x.ply", &mesh, NULL, &err), MS_ERR_IO);
    assert_non_null(strstr(err.text, "/nonexistent/x.ply"));
    assert_int_equal(ms_mesh_load(c->dir, &mesh, NULL, &err), MS_ERR_IO);
}


/* Random byte changes and cuts in small files of every format: whatever comes
 * out, the reader must not crash or leak (ASan/UBSan watch), and a failure must
 * carry a one-line message naming the file. */
static void test_random_mutations_never_crash(void **state)
{
    corpus *c = *state;
    char model[4096], path[4200];
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    ms_mesh mesh = {0};
    ms_error err;
    assert_int_equal(ms_mesh_load(model, &mesh, NULL, &err), MS_OK);
    mesh.vertex_count = 300; /* keep the files small: the first 300 vertices */
    size_t kept = 0;
    for (size_t t = 0; t < mesh.triangle_count; ++t)
        if (mesh.triangles[3 * t] < 300 && mesh.triangles[3 * t + 1] < 300 &&
            mesh.triangles[3 * t + 2] < 300)
            memmove(mesh.triangles + 3 * kept++, mesh.triangles + 3 * t, 3 * sizeof(uint32_t));
    mesh.triangle_count = kept;
    blob sources[4];
    for (int k = 0; k < 2; ++k) {
        snprintf(path, sizeof path, "%s/small%d.ply", c->dir, k);
        assert_int_equal(ms_ply_write(path, &mesh, k == 1, false, &err), MS_OK);
        FILE *f = fopen(path, "rb");
        sources[k].data = malloc(1 << 20);
        sources[k].size = fread(sources[k].data, 1, 1 << 20, f);
        fclose(f);
    }
    for (int k = 2; k < 4; ++k) {
        sources[k].data = malloc(1 << 20);
        size_t n = 0;
        n += (size_t)snprintf(sources[k].data + n, 64, k == 2 ? "# obj\n" : "OFF\n%zu %zu 0\n",
                              mesh.vertex_count, mesh.triangle_count);
        for (size_t v = 0; v < mesh.vertex_count; ++v)
            n += (size_t)snprintf(sources[k].data + n, 128, "%s%.9g %.9g %.9g\n",
                                  k == 2 ? "v " : "", mesh.positions[3 * v],
                                  mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]);
        for (size_t t = 0; t < mesh.triangle_count; ++t)
            n += (size_t)snprintf(sources[k].data + n, 128, k == 2 ? "f %u %u/1 %u//2\n" : "3 %u %u %u\n",
                                  mesh.triangles[3 * t] + (k == 2), mesh.triangles[3 * t + 1] + (k == 2),
                                  mesh.triangles[3 * t + 2] + (k == 2));
        sources[k].size = n;
    }
    ms_mesh_free(&mesh);
    static const char *const ext[4] = {"ply", "ply", "obj", "off"};
    static const char tokens[] = "0123456789 -.e\n\r#/nanif\xff\x00";
    uint64_t rng = 0x1234567u;
    int failures = 0, successes = 0;
    for (int i = 0; i < 2400; ++i) {
        int k = i % 4;
        blob *src = &sources[k];
        static char mutated[1 << 20];
        memcpy(mutated, src->data, src->size);
        size_t size = src->size;
        int edits = 1 + (int)(ms_test_random(&rng) % 4);
        for (int e = 0; e < edits; ++e) {
            size_t at = (size_t)(ms_test_random(&rng) % size);
            uint64_t how = ms_test_random(&rng) % 4;
            if (how == 0)
                size = at + 1; /* cut */
            else if (how == 1)
                mutated[at] = (char)ms_test_random(&rng);
            else
                mutated[at] = tokens[ms_test_random(&rng) % (sizeof tokens - 1)];
        }
        blob m = {mutated, size};
        snprintf(path, sizeof path, "%s/mutant.%s", c->dir, ext[k]);
        FILE *f = fopen(path, "wb");
        fwrite(m.data, 1, m.size, f);
        fclose(f);
        ms_mesh out = {0};
        ms_error_clear(&err);
        ms_status st = ms_mesh_load(path, &out, NULL, &err);
        if (st == MS_OK) {
            ++successes;
            for (size_t t = 0; t < 3 * out.triangle_count; ++t)
                assert_true(out.triangles[t] < out.vertex_count);
            ms_mesh_free(&out);
        } else {
            ++failures;
            assert_int_equal(err.code, st);
            if (!strstr(err.text, path) || strchr(err.text, '\n'))
                fail_msg("bad message: %s", err.text);
            assert_null(out.positions);
        }
    }
    assert_true(failures > 1000);
    assert_true(successes > 10);
    for (int k = 0; k < 4; ++k)
        free(sources[k].data);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ascii_ply_truncated),
        cmocka_unit_test(test_ascii_ply_counts_lie),
        cmocka_unit_test(test_ascii_ply_bad_values),
        cmocka_unit_test(test_binary_ply),
        cmocka_unit_test(test_obj),
        cmocka_unit_test(test_off_unknown_and_gzip),
        cmocka_unit_test(test_random_mutations_never_crash),
    };
    return cmocka_run_group_tests_name("reader_broken", tests, setup, teardown);
}
