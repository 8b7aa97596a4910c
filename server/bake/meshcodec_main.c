/* meshcodec: command line for the progressive lossless geometry codec.
 *
 *   meshcodec encode IN -o OUT --bits P
 *   meshcodec decode IN -o OUT.ply [--bits Q]
 *   meshcodec roundtrip IN --bits P [--json]
 *   meshcodec train IN... -o TABLE.c [--bits P]
 */
#include <errno.h>
#include <getopt.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "ms_codec.h"
#include "ms_cli.h"
#include "ms_colour_roundtrip.h"
#include "ms_input_file.h"
#include "ms_codec_prior.h"
#include "ms_json_out.h"
#include "ms_parse_number.h"
#include "ms_mesh_io.h"
#include "ms_quant.h"
#include "ms_version.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

static const char *const top_usage =
    "usage: meshcodec COMMAND [OPTIONS]\n"
    "\n"
    "Progressive lossless mesh codec (kd-tree geometry + simplicial connectivity).\n"
    "\n"
    "commands:\n"
    "  encode IN -o OUT --bits P      quantise IN (PLY/OBJ/OFF, .gz ok) to P bits and code it\n"
    "  decode IN -o OUT.ply [--bits Q] decode a stream, at Q <= P bits for a coarser level\n"
    "  roundtrip IN --bits P [--json] encode, decode, check losslessness, report sizes/times\n"
    "            [--colour-bits C]    (and the per-vertex colour's stream, C bits per channel)\n"
    "  train IN... -o TABLE.c         estimate the built-in prior from meshes (developers)\n"
    "\n"
    "`meshcodec COMMAND --help` describes each command; `meshcodec --version` prints\n"
    "the version.\n"
    "Exit status: 0 on success, 1 for an input or processing error, 2 for a usage error.\n";

static const char *const encode_usage =
    "usage: meshcodec encode IN -o OUT [--bits P] [--ahead K] [--ahead-until U]\n"
    "\n"
    "Reads IN, quantises it onto a cubic 2^P grid (P in 8..20, default 16), welds\n"
    "coincident points, drops degenerate and duplicate triangles, and writes the coded\n"
    "stream to OUT (replaced atomically). Prints one summary line.\n"
    "\n"
    "  -o, --output OUT   output stream\n"
    "  -b, --bits P       precision in bits per coordinate (default 16)\n"
    "      --ahead K      geometry ahead of connectivity by K kd-levels, 0..6 (default\n"
    "                     3): coarse levels draw each vertex at the\n"
    "                     barycentre of its known descendants instead of its cell centre\n"
    "      --ahead-until U  geometry ahead stops at U bits, 0..7 (default 0: at the\n"
    "                     last bit); finer levels code their geometry inline\n"
    "  -h, --help         print this help and exit\n"
    "      --version      print the version and exit\n";

static const char *const decode_usage =
    "usage: meshcodec decode IN -o OUT.ply [--bits Q] [--ascii]\n"
    "\n"
    "Decodes the stream IN and writes the mesh as PLY (binary little-endian, double\n"
    "coordinates, so the dequantised points are exact). With --bits Q (Q at most\n"
    "the stream's precision) writes the level of detail at Q bits: cell centres and\n"
    "the triangles surviving at that precision.\n"
    "\n"
    "  -o, --output OUT   output PLY file\n"
    "  -b, --bits Q       precision to decode to (default: the stream's)\n"
    "      --ascii        write ascii PLY\n"
    "  -h, --help         print this help and exit\n"
    "      --version      print the version and exit\n";

static const char *const roundtrip_usage =
    "usage: meshcodec roundtrip IN [--bits P] [--ahead K] [--ahead-until U] [--colour-bits C]\n"
    "                           [--json]\n"
    "\n"
    "Quantises IN at P bits (default 16), encodes, decodes at full precision and checks\n"
    "that the result equals the quantised, welded input (same points, same oriented\n"
    "triangles, compared canonically). Reports counts, weld figures, bytes, bits per\n"
    "vertex and encode/decode times; exit status 1 when the result differs.\n"
    "When IN has per-vertex colour, also codes it as its own stream (docs/COLOUR.md:\n"
    "each welded vertex the rounded mean of its input colours) and checks that it\n"
    "decodes exactly; reports its bytes (colour_bytes).\n"
    "\n"
    "  -b, --bits P       precision (default 16)\n"
    "      --ahead K      geometry ahead by K kd-levels (see encode --help)\n"
    "      --ahead-until U  where it stops, bits (see encode --help)\n"
    "      --colour-bits C  colour precision, bits per channel, 1..8 (default 8)\n"
    "      --json         print one JSON object on stdout\n"
    "  -h, --help         print this help and exit\n"
    "      --version      print the version and exit\n";

static const char *const train_usage =
    "usage: meshcodec train IN... -o TABLE.c [--bits P]\n"
    "\n"
    "Encodes every IN at P bits (default 16), counts the decisions of every context\n"
    "and writes the prior they give as the C source of common/codec/ms_codec_prior_table.c\n"
    "(docs/CODEC.md, section 4). For developers: the table is compiled into the codec,\n"
    "and changing it changes every stream of the current version.\n"
    "\n"
    "  -o, --output OUT   output C file\n"
    "  -b, --bits P       precision in bits per coordinate (default 16)\n"
    "      --ahead K      geometry ahead of connectivity by K kd-levels, 0..6 (default\n"
    "                     3): coarse levels draw each vertex at the\n"
    "                     barycentre of its known descendants instead of its cell centre\n"
    "      --ahead-until U  where it stops, bits (see encode --help)\n"
    "  -h, --help         print this help and exit\n"
    "      --version      print the version and exit\n";

/* The command's name ("meshcodec encode", or "meshcodec") for usage errors. */
static const char *command_name(const char *cmd, char *buf, size_t size)
{
    snprintf(buf, size, "meshcodec%s%s", cmd ? " " : "", cmd ? cmd : "");
    return buf;
}

static int usage_error(const char *cmd, const char *message, const char *detail)
{
    char name[64];
    return ms_cli_usage_error(command_name(cmd, name, sizeof name), message, detail);
}

static int input_error(const char *cmd, const ms_error *err)
{
    fprintf(stderr, "meshcodec %s: %s\n", cmd, err->text);
    return EXIT_INPUT;
}

static double now_seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

typedef struct options {
    const char *input, *output;
    char **inputs; /* every input (train) */
    int input_count;
    int bits; /* -1 when not given */
    int ahead; /* geometry ahead, kd-levels */
    int ahead_until; /* where it stops, bits (0: the last) */
    int colour_bits; /* roundtrip: colour precision (default 8) */
    bool json, ascii;
} options;

/* Parses argv (after the command word). Returns -1 to go on, else an exit status. */
static int parse(const char *cmd, const char *help, int argc, char **argv, options *o,
                 bool want_output, bool allow_json, bool allow_ascii, bool many_inputs)
{
    static const struct option longs[] = {
        {"output", required_argument, NULL, 'o'}, {"bits", required_argument, NULL, 'b'},
        {"json", no_argument, NULL, 'j'},         {"ascii", no_argument, NULL, 'a'},
        {"ahead", required_argument, NULL, 'A'},  {"help", no_argument, NULL, 'h'},
        {"ahead-until", required_argument, NULL, 'U'},
        {"colour-bits", required_argument, NULL, 'C'},
        {NULL, 0, NULL, 0},
    };
    memset(o, 0, sizeof *o);
    o->bits = -1;
    o->ahead = MS_CODEC_DEFAULT_AHEAD;
    o->colour_bits = MS_COLOUR_DEFAULT_BITS;
    optind = 1;
    int c;
    char name[64];
    command_name(cmd, name, sizeof name);
    while ((c = ms_cli_next(name, argc, argv, "o:b:h", longs)) != -1) {
        switch (c) {
        case 'o':
            if (!want_output)
                return usage_error(cmd, "unknown option", "-o");
            o->output = optarg;
            break;
        case 'b': {
            int64_t v;
            ms_error e;
            if (ms_option_int("--bits", optarg, 0, 64, &v, &e) != MS_OK)
                return usage_error(cmd, e.text, NULL);
            o->bits = (int)v;
            break;
        }
        case 'A': case 'U': {
            int64_t v;
            ms_error e;
            const char *opt = c == 'A' ? "--ahead" : "--ahead-until";
            if (allow_ascii) /* decode: the stream says */
                return usage_error(cmd, "unknown option", opt);
            if (ms_option_int(opt, optarg, 0, c == 'A' ? MS_CODEC_MAX_AHEAD : MS_CODEC_MAX_AHEAD_UNTIL, &v, &e) !=
                MS_OK)
                return usage_error(cmd, e.text, NULL);
            *(c == 'A' ? &o->ahead : &o->ahead_until) = (int)v;
            break;
        }
        case 'C': {
            int64_t v;
            ms_error e;
            if (!allow_json) /* roundtrip only */
                return usage_error(cmd, "unknown option", "--colour-bits");
            if (ms_option_int("--colour-bits", optarg, 1, MS_COLOUR_MAX_BITS, &v, &e) != MS_OK)
                return usage_error(cmd, e.text, NULL);
            o->colour_bits = (int)v;
            break;
        }
        case 'j':
            if (!allow_json)
                return usage_error(cmd, "unknown option", "--json");
            o->json = true;
            break;
        case 'a':
            if (!allow_ascii)
                return usage_error(cmd, "unknown option", "--ascii");
            o->ascii = true;
            break;
        case 'h': fputs(help, stdout); return EXIT_SUCCESS;
        default: return EXIT_USAGE; /* reported by ms_cli_next */
        }
    }
    o->inputs = argv + optind;
    o->input_count = argc - optind;
    if (optind < argc)
        o->input = argv[optind++];
    if (optind < argc && !many_inputs)
        return usage_error(cmd, "unexpected argument", argv[optind]);
    if (!o->input)
        return usage_error(cmd, "missing input file", NULL);
    if (want_output && !o->output)
        return usage_error(cmd, "missing -o OUT", NULL);
    return -1;
}

/* Loads and quantises; fills q and report. */
/* colours (may be NULL): the welded vertices' colours (ms_colour_weld), NULL
 * when the input has none; *alpha whether it had alpha. */
static ms_status load_quantised_colours(const char *path, unsigned bits, ms_qmesh *q,
                                        ms_weld_report *weld, ms_mesh_load_report *load,
                                        uint8_t **colours, bool *alpha, ms_error *err)
{
    ms_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    ms_status st = ms_mesh_load(path, &mesh, load, err);
    if (st != MS_OK)
        return st;
    st = ms_quantise_mesh(&mesh, bits, q, weld, err);
    if (st == MS_ERR_EMPTY)
        ms_error_set(err, MS_ERR_EMPTY, "%s: empty mesh (no vertex): nothing to encode", path);
    if (colours) {
        *colours = NULL;
        *alpha = mesh.colour_alpha;
        if (st == MS_OK && mesh.colours)
            st = ms_colour_weld(&mesh, q, colours, err);
        if (st != MS_OK)
            ms_qmesh_free(q);
    }
    ms_mesh_free(&mesh);
    return st;
}

static ms_status load_quantised(const char *path, unsigned bits, ms_qmesh *q,
                                ms_weld_report *weld, ms_mesh_load_report *load, ms_error *err)
{
    return load_quantised_colours(path, bits, q, weld, load, NULL, NULL, err);
}

static ms_status encode_q(const ms_qmesh *q, const options *o, uint64_t *context_counts,
                          uint8_t **buf, size_t *size, ms_error *err)
{
    ms_codec_state full;
    ms_status st = ms_codec_state_from_qmesh(q, &full, err);
    if (st != MS_OK)
        return st;
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box = q->box;
    par.context_counts = context_counts;
    par.ahead = (unsigned)o->ahead;
    par.ahead_until = (unsigned)o->ahead_until;
    st = ms_codec_encode(&full, &par, buf, size, NULL, err);
    ms_codec_state_free(&full);
    return st;
}

static ms_status write_file(const char *path, const uint8_t *buf, size_t size, ms_error *err)
{
    size_t n = strlen(path) + 16;
    char *tmp = malloc(n);
    if (!tmp)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    snprintf(tmp, n, "%s.tmp%ld", path, (long)getpid());
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", path, strerror(errno));
        free(tmp);
        return MS_ERR_IO;
    }
    bool ok = fwrite(buf, 1, size, f) == size;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, path) != 0) {
        ms_error_set(err, MS_ERR_IO, "%s: write failed: %s", path, strerror(errno));
        remove(tmp);
        free(tmp);
        return MS_ERR_IO;
    }
    free(tmp);
    return MS_OK;
}

static ms_status read_file(const char *path, uint8_t **buf, size_t *size, ms_error *err)
{
    FILE *f;
    ms_status opened = ms_input_fopen(path, &f, err);
    if (opened != MS_OK)
        return opened;
    size_t cap = 1 << 16, n = 0;
    uint8_t *b = malloc(cap);
    while (b) {
        size_t r = fread(b + n, 1, cap - n, f);
        n += r;
        if (n < cap)
            break;
        if (cap > ((size_t)1 << 32)) {
            free(b);
            fclose(f);
            return ms_error_set(err, MS_ERR_NOMEM, "%s: file too large", path);
        }
        uint8_t *g = realloc(b, cap * 2);
        if (!g) {
            free(b);
            b = NULL;
            break;
        }
        b = g;
        cap *= 2;
    }
    bool bad = ferror(f);
    fclose(f);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory reading", path);
    if (bad) {
        free(b);
        return ms_error_set(err, MS_ERR_IO, "%s: read error", path);
    }
    *buf = b;
    *size = n;
    return MS_OK;
}

static int check_bits(const char *cmd, int bits)
{
    if (bits < MS_QUANT_MIN_BITS || bits > MS_QUANT_MAX_BITS) {
        char v[16];
        snprintf(v, sizeof v, "%d", bits);
        return usage_error(cmd, "--bits must be in 8..20", v);
    }
    return -1;
}

static int cmd_encode(int argc, char **argv)
{
    options o;
    int r = parse("encode", encode_usage, argc, argv, &o, true, false, false, false);
    if (r >= 0)
        return r;
    if (o.bits < 0)
        o.bits = 16;
    if ((r = check_bits("encode", o.bits)) >= 0)
        return r;
    ms_error err;
    ms_qmesh q;
    ms_weld_report weld;
    if (load_quantised(o.input, (unsigned)o.bits, &q, &weld, NULL, &err) != MS_OK)
        return input_error("encode", &err);
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_status st = encode_q(&q, &o, NULL, &buf, &size, &err);
    if (st == MS_OK)
        st = write_file(o.output, buf, size, &err);
    free(buf);
    if (st != MS_OK) {
        ms_qmesh_free(&q);
        return input_error("encode", &err);
    }
    printf("%s: %zu vertices (%zu welded), %zu triangles, %u bits -> %zu bytes, %.3f bits/vertex\n",
           o.output, q.vertex_count, weld.welded_vertices, q.tri_count, (unsigned)o.bits, size,
           8.0 * (double)size / (double)q.vertex_count);
    ms_qmesh_free(&q);
    return EXIT_SUCCESS;
}

static int cmd_decode(int argc, char **argv)
{
    options o;
    int r = parse("decode", decode_usage, argc, argv, &o, true, false, true, false);
    if (r >= 0)
        return r;
    ms_error err;
    uint8_t *buf = NULL;
    size_t size = 0;
    if (read_file(o.input, &buf, &size, &err) != MS_OK)
        return input_error("decode", &err);
    ms_codec_decoder *d = NULL;
    ms_status st = ms_codec_decoder_create(buf, size, NULL, NULL, &d, &err);
    free(buf);
    if (st != MS_OK) {
        fprintf(stderr, "meshcodec decode: %s: %s\n", o.input, err.text);
        return EXIT_INPUT;
    }
    unsigned pmax = ms_codec_decoder_header(d)->p_max;
    if (o.bits < 0)
        o.bits = (int)pmax;
    if (o.bits > (int)pmax || o.bits < (int)ms_codec_decoder_header(d)->p_min) {
        char v[64];
        snprintf(v, sizeof v, "%d (stream holds %u..%u)", o.bits,
                 ms_codec_decoder_header(d)->p_min, pmax);
        ms_codec_decoder_destroy(d);
        return usage_error("decode", "--bits outside the stream's precision", v);
    }
    st = ms_codec_decoder_set_level(d, 3 * (unsigned)o.bits, &err);
    ms_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    if (st == MS_OK)
        st = ms_codec_decoder_mesh(d, &mesh, &err);
    if (st == MS_OK)
        st = ms_ply_write(o.output, &mesh, !o.ascii, true, &err);
    ms_codec_decoder_destroy(d);
    ms_mesh_free(&mesh);
    if (st != MS_OK) {
        fprintf(stderr, "meshcodec decode: %s: %s\n", o.input, err.text);
        return EXIT_INPUT;
    }
    return EXIT_SUCCESS;
}

/* The colour figures of roundtrip: into obj (JSON), or a line on stdout. */
static void report_colour(json_t *obj, int bits, bool alpha, const ms_colour_roundtrip_report *c,
                          size_t vertices)
{
    double bpv = 8.0 * (double)c->bytes / (double)vertices;
    if (!obj) {
        printf("colour at %d bits per channel%s: %zu bytes, %.3f bits/vertex; encode %.3f s, "
               "decode %.3f s; %s\n",
               bits, alpha ? " with alpha" : "", c->bytes, bpv, c->encode_seconds,
               c->decode_seconds, c->lossless ? "lossless" : "MISMATCH");
        return;
    }
    json_t *extra = json_pack("{s:i, s:b, s:I, s:o, s:o, s:o, s:b}", "colour_bits", bits,
                              "colour_alpha", alpha, "colour_bytes", (json_int_t)c->bytes,
                              "colour_bits_per_vertex", ms_json_fixed(bpv, 4),
                              "colour_encode_seconds", ms_json_fixed(c->encode_seconds, 6),
                              "colour_decode_seconds", ms_json_fixed(c->decode_seconds, 6),
                              "colour_lossless", c->lossless);
    if (extra) {
        json_object_update(obj, extra);
        json_decref(extra);
    }
}

static int cmd_roundtrip(int argc, char **argv)
{
    options o;
    int r = parse("roundtrip", roundtrip_usage, argc, argv, &o, false, true, false, false);
    if (r >= 0)
        return r;
    if (o.bits < 0)
        o.bits = 16;
    if ((r = check_bits("roundtrip", o.bits)) >= 0)
        return r;
    ms_error err;
    ms_qmesh q;
    ms_weld_report weld;
    ms_mesh_load_report load;
    uint8_t *colours = NULL;
    bool alpha = false;
    if (load_quantised_colours(o.input, (unsigned)o.bits, &q, &weld, &load, &colours, &alpha,
                               &err) != MS_OK)
        return input_error("roundtrip", &err);
    ms_colour_roundtrip_report colour = {0};
    if (colours && ms_colour_roundtrip(&q, colours, alpha, (unsigned)o.colour_bits, &colour,
                                       &err) != MS_OK) {
        free(colours);
        ms_qmesh_free(&q);
        return input_error("roundtrip", &err);
    }
    uint8_t *buf = NULL;
    size_t size = 0;
    double t0 = now_seconds();
    ms_status st = encode_q(&q, &o, NULL, &buf, &size, &err);
    double t1 = now_seconds();
    ms_codec_decoder *d = NULL;
    double t2 = 0, t3 = 0;
    ms_codec_state got = {0}, want = {0};
    bool lossless = false;
    if (st == MS_OK) {
        t2 = now_seconds();
        st = ms_codec_decoder_create(buf, size, NULL, NULL, &d, &err);
        if (st == MS_OK)
            st = ms_codec_decoder_set_level(d, 3 * (unsigned)o.bits, &err);
        t3 = now_seconds();
    }
    if (st == MS_OK)
        st = ms_codec_decoder_state(d, &got, &err);
    if (st == MS_OK)
        st = ms_codec_state_from_qmesh(&q, &want, &err);
    if (st == MS_OK)
        st = ms_codec_state_canonicalise(&want, &err);
    if (st == MS_OK)
        lossless = ms_codec_state_equal(&got, &want, true);
    ms_codec_decoder_destroy(d);
    ms_codec_state_free(&got);
    ms_codec_state_free(&want);
    free(buf);
    if (st != MS_OK) {
        free(colours);
        ms_qmesh_free(&q);
        return input_error("roundtrip", &err);
    }
    double bpv = 8.0 * (double)size / (double)q.vertex_count;
    double bpiv = 8.0 * (double)size / (double)weld.input_vertices;
    double dec = t3 - t2, enc = t1 - t0;
    if (o.json) {
        json_t *obj =
                      json_pack("{s:o, s:i, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:o, s:o, s:o, s:o, "
                                "s:o, s:b}",
                                "input", ms_json_text(o.input), "bits", o.bits, "vertices",
                                (json_int_t)q.vertex_count, "triangles", (json_int_t)q.tri_count,
                                "input_vertices", (json_int_t)weld.input_vertices, "input_triangles",
                                (json_int_t)weld.input_triangles, "welded_vertices",
                                (json_int_t)weld.welded_vertices, "degenerate_triangles",
                                (json_int_t)weld.degenerate_triangles, "duplicate_triangles",
                                (json_int_t)weld.duplicate_triangles, "isolated_vertices",
                                (json_int_t)weld.isolated_vertices, "bytes", (json_int_t)size,
                                "bits_per_vertex", ms_json_fixed(bpv, 4), "bits_per_input_vertex",
                                ms_json_fixed(bpiv, 4), "encode_seconds", ms_json_fixed(enc, 6),
                                "decode_seconds", ms_json_fixed(dec, 6), "decode_mtriangles_per_second",
                                ms_json_fixed(dec > 0 ? (double)q.tri_count / dec / 1e6 : 0.0, 3), "lossless",
                                lossless);
        if (obj && colours)
            report_colour(obj, o.colour_bits, alpha, &colour, q.vertex_count);
        ms_json_print(stdout, obj, MS_JSON_SPACED);
    } else {
        printf("%s at %d bits: %zu vertices, %zu triangles (welded %zu, dropped %zu degenerate + "
               "%zu duplicate) -> %zu bytes, %.3f bits/vertex; encode %.3f s, decode %.3f s; "
               "%s\n",
               o.input, o.bits, q.vertex_count, q.tri_count, weld.welded_vertices,
               weld.degenerate_triangles, weld.duplicate_triangles, size, bpv, enc, dec,
               lossless ? "lossless" : "MISMATCH");
        if (colours)
            report_colour(NULL, o.colour_bits, alpha, &colour, q.vertex_count);
    }
    ms_qmesh_free(&q);
    bool had_colours = colours != NULL;
    free(colours);
    if (!lossless) {
        fprintf(stderr, "meshcodec roundtrip: %s: decoded mesh differs from the input\n",
                o.input);
        return EXIT_INPUT;
    }
    if (had_colours && !colour.lossless) {
        fprintf(stderr, "meshcodec roundtrip: %s: decoded colours differ from the input\n",
                o.input);
        return EXIT_INPUT;
    }
    return EXIT_SUCCESS;
}

static const char *base_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    return slash ? slash + 1 : path;
}

/* Writes the prior table as C source. */
static ms_status write_prior_table(const char *path, const uint16_t *p0, int bits,
                                   int input_count, char **inputs, ms_error *err)
{
    char *text = NULL;
    size_t size = 0;
    FILE *f = open_memstream(&text, &size);
    if (!f)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    fprintf(f, "/* Generated by `meshcodec train --bits %d` from:\n", bits);
    for (int i = 0; i < input_count; ++i)
        fprintf(f, " *   %s\n", base_name(inputs[i]));
    fputs(" * Do not edit: regenerate (docs/CODEC.md, section 4). */\n"
          "#include \"ms_codec_prior.h\"\n\n"
          "const uint16_t ms_codec_prior_p0[MS_PRIOR_SIZE] = {", f);
    for (size_t i = 0, n = ms_codec_prior_contexts(); i < n; ++i)
        fprintf(f, "%s%u,", i % 10 ? " " : "\n    ", p0[i]);
    fputs("\n};\n", f);
    bool ok = !ferror(f);
    if (fclose(f) != 0 || !ok) {
        free(text);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory writing the table");
    }
    ms_status st = write_file(path, (const uint8_t *)text, size, err);
    free(text);
    return st;
}

static int cmd_train(int argc, char **argv)
{
    options o;
    int r = parse("train", train_usage, argc, argv, &o, true, false, false, true);
    if (r >= 0)
        return r;
    if (o.bits < 0)
        o.bits = 16;
    if ((r = check_bits("train", o.bits)) >= 0)
        return r;
    size_t n = ms_codec_prior_contexts();
    uint64_t *counts = calloc(2 * n, sizeof *counts);
    uint16_t *p0 = malloc(n * sizeof *p0);
    if (!counts || !p0) {
        free(counts);
        free(p0);
        fprintf(stderr, "meshcodec train: out of memory\n");
        return EXIT_INPUT;
    }
    ms_error err;
    ms_status st = MS_OK;
    for (int i = 0; i < o.input_count && st == MS_OK; ++i) {
        ms_qmesh q;
        ms_weld_report weld;
        st = load_quantised(o.inputs[i], (unsigned)o.bits, &q, &weld, NULL, &err);
        if (st != MS_OK)
            break;
        uint8_t *buf = NULL;
        size_t size = 0;
        st = encode_q(&q, &o, counts, &buf, &size, &err);
        if (st == MS_OK)
            printf("%s: %zu vertices, %zu bytes with the current prior\n", o.inputs[i],
                   q.vertex_count, size);
        free(buf);
        ms_qmesh_free(&q);
    }
    if (st == MS_OK) {
        ms_codec_prior_estimate(counts, p0);
        st = write_prior_table(o.output, p0, o.bits, o.input_count, o.inputs, &err);
    }
    uint64_t decisions = 0;
    for (size_t i = 0; i < 2 * n; ++i)
        decisions += counts[i];
    free(counts);
    free(p0);
    if (st != MS_OK)
        return input_error("train", &err);
    printf("%s: prior of %zu contexts from %d meshes (%llu decisions)\n", o.output, n,
           o.input_count, (unsigned long long)decisions);
    return EXIT_SUCCESS;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshcodec");
    if (argc < 2)
        return usage_error(NULL, "missing command", NULL);
    const char *cmd = argv[1];
    if (!strcmp(cmd, "-h") || !strcmp(cmd, "--help")) {
        fputs(top_usage, stdout);
        return EXIT_SUCCESS;
    }
    if (!strcmp(cmd, "encode"))
        return cmd_encode(argc - 1, argv + 1);
    if (!strcmp(cmd, "decode"))
        return cmd_decode(argc - 1, argv + 1);
    if (!strcmp(cmd, "roundtrip"))
        return cmd_roundtrip(argc - 1, argv + 1);
    if (!strcmp(cmd, "train"))
        return cmd_train(argc - 1, argv + 1);
    return usage_error(NULL, cmd[0] == '-' ? "unknown option" : "unknown command", cmd);
}
