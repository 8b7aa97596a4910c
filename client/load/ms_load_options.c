#include "ms_load_options.h"
#include "ms_camera.h"
#include "ms_cli.h"

#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "ms_error.h"
#include "ms_parse_number.h"

#define MAX_CLIENTS 256

void ms_load_usage(FILE *out)
{
    fprintf(out,
            "usage: meshload --server HOST:PORT --model NAME --path CAMERA_FILE [--clients N]\n"
            "                [--bandwidth 8mbit] [--tolerance PX] [--duration S] [--json]\n"
            "       meshload --archive DIR/NAME.msa --path CAMERA_FILE [options as above]\n"
            "       meshload --baseline draco --server HOST:HTTP_PORT --model NAME [--clients N]\n"
            "                [--bandwidth 8mbit] [--json]\n\n"
            "Streams a model from meshserve through the client core along a camera path\n"
            "(docs/CAMERA_PATHS.md), without a window, for N concurrent virtual clients,\n"
            "each throttled to the given bandwidth. Each client first opens the model cold\n"
            "at the path's last keyframe (time to first display, time to view complete),\n"
            "then plays the path with its clock held at every keyframe until the view is\n"
            "complete there (time to view complete per keyframe).\n"
            "  --server HOST:PORT     numeric address and binary port (HTTP port for --baseline)\n"
            "  --model NAME           model name in the server's catalogue\n"
            "  --archive FILE         read a local archive file instead (no server; the\n"
            "                         client core's local mode, docs/CLIENT.md)\n"
            "  --path FILE            camera path file\n"
            "  --clients N            virtual clients, 1..%d (default 1)\n"
            "  --bandwidth RATE       per client, e.g. 8mbit, 500kbit, 2mbyte (default unlimited)\n"
            "  --tolerance PX         geometric screen tolerance in pixels (default 1)\n"
            "  --duration S           bound on the whole run in seconds (default: path + 120)\n"
            "  --keyframe-timeout S   longest wait for a view to complete (default 60)\n"
            "  --viewport WxH         pixels (default 1280x720)\n"
            "  --memory-target MB, --memory-ceiling MB   the cache budget (default none)\n"
            "  --hysteresis BITS      precision hysteresis (default 0.2)\n"
            "  --culled-bits-less B   precision given up on cells outside the view (default 6)\n"
            "  --decode-threads N     decoding threads per client (default 2)\n"
            "  --apo-levels L         APO on, fetching at most L levels of a chunk (default 0:\n"
            "                         APO off); bytes are reported as geometry and APO\n"
            "  --token TOKEN          access token\n"
            "  --no-cold              skip the cold-open phase\n"
            "  --raw-index            ask for the model index uncompressed (protocol v1 way)\n"
            "  --whole-index          take the whole index at open, not by subtree (as from a\n"
            "                         server without subtrees)\n"
            "  --baseline draco       download /models/NAME/draco (ARCHIVE_DIR/NAME.drc) from\n"
            "                         the HTTP side door and decode it with draco_decoder\n"
            "  --draco-decoder PATH   (default draco_decoder)\n"
            "  --json                 one JSON object on stdout\n"
            "  -h, --help             this help\n"
            "      --version          the version\n"
            "Exit status: 0 when every client completed its views, 1 otherwise, 2 for a usage "
            "error.\n",
            MAX_CLIENTS);
}

/* A bad option value: its one line (ms_option_*), exit status 2. */
static int bad_value(const ms_error *e)
{
    fprintf(stderr, "meshload: %s\n", e->text);
    return 2;
}

/* "8mbit", "500kbit", "2mbyte", "1000000" (bytes per second). */
static int parse_bandwidth(const char *text, double *out)
{
    char *end;
    double v = strtod(text, &end);
    if (end == text || !(v > 0) || !isfinite(v))
        return -1;
    double scale;
    if (!*end || !strcasecmp(end, "b") || !strcasecmp(end, "byte"))
        scale = 1;
    else if (!strcasecmp(end, "bit"))
        scale = 1 / 8.0;
    else if (!strcasecmp(end, "kbit"))
        scale = 1000 / 8.0;
    else if (!strcasecmp(end, "mbit"))
        scale = 1e6 / 8.0;
    else if (!strcasecmp(end, "gbit"))
        scale = 1e9 / 8.0;
    else if (!strcasecmp(end, "kbyte") || !strcasecmp(end, "kb"))
        scale = 1000;
    else if (!strcasecmp(end, "mbyte") || !strcasecmp(end, "mb"))
        scale = 1e6;
    else
        return -1;
    *out = v * scale;
    return 0;
}

/* The numeric options: 0 when set, 2 after a bad value, -1 when ch is not
 * one of them. */
static int numeric_option(int ch, const char *value, ms_load_options *o)
{
    double v = 0;
    int64_t i = 0;
    ms_error e;
    switch (ch) {
    case 'c':
        if (ms_option_int("--clients", value, 1, MAX_CLIENTS, &i, &e) != MS_OK)
            return bad_value(&e);
        o->clients = (unsigned)i;
        break;
    case 't':
        if (ms_option_double("--tolerance", value, 0.01, 1000, &o->tolerance, &e) != MS_OK)
            return bad_value(&e);
        break;
    case 'd':
        if (ms_option_double("--duration", value, 0.1, 86400, &o->duration, &e) != MS_OK)
            return bad_value(&e);
        break;
    case 'k':
        if (ms_option_double("--keyframe-timeout", value, 0.1, 86400, &o->keyframe_timeout, &e) != MS_OK)
            return bad_value(&e);
        break;
    case 'M':
    case 'C':
        if (ms_option_double(ch == 'M' ? "--memory-target" : "--memory-ceiling", value, 0.01,
                             1e7, &v, &e) != MS_OK)
            return bad_value(&e);
        *(ch == 'M' ? &o->memory_target : &o->memory_ceiling) = v;
        break;
    case 'H':
        if (ms_option_double("--hysteresis", value, 0, 4, &o->hysteresis, &e) != MS_OK)
            return bad_value(&e);
        break;
    case 'L':
        if (ms_option_double("--culled-bits-less", value, 0.01, 64, &o->culled_less, &e) != MS_OK)
            return bad_value(&e);
        break;
    case 'P':
        if (ms_option_int("--decode-threads", value, 1, 64, &i, &e) != MS_OK)
            return bad_value(&e);
        o->decode_threads = (unsigned)i;
        break;
    case 'a':
        if (ms_option_int("--apo-levels", value, 0, 32, &i, &e) != MS_OK)
            return bad_value(&e);
        o->apo_levels = (unsigned)i;
        break;
    default: return -1;
    }
    return 0;
}

int ms_load_options_parse(int argc, char **argv, ms_load_options *o)
{
    static const struct option opts[] = {
        {"server", required_argument, NULL, 's'},  {"model", required_argument, NULL, 'm'},
        {"path", required_argument, NULL, 'p'},    {"clients", required_argument, NULL, 'c'},
        {"bandwidth", required_argument, NULL, 'b'}, {"tolerance", required_argument, NULL, 't'},
        {"duration", required_argument, NULL, 'd'}, {"json", no_argument, NULL, 'j'},
        {"keyframe-timeout", required_argument, NULL, 'k'},
        {"viewport", required_argument, NULL, 'v'},
        {"memory-target", required_argument, NULL, 'M'},
        {"memory-ceiling", required_argument, NULL, 'C'},
        {"hysteresis", required_argument, NULL, 'H'},
        {"culled-bits-less", required_argument, NULL, 'L'},
        {"decode-threads", required_argument, NULL, 'P'},
        {"apo-levels", required_argument, NULL, 'a'}, {"token", required_argument, NULL, 'T'},
        {"no-cold", no_argument, NULL, 'n'},       {"baseline", required_argument, NULL, 'B'},
        {"raw-index", no_argument, NULL, 'R'},   {"whole-index", no_argument, NULL, 'W'},   {"archive", required_argument, NULL, 'A'},
        {"draco-decoder", required_argument, NULL, 'D'}, {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}};
    memset(o, 0, sizeof *o);
    o->clients = 1;
    o->tolerance = 1.0;
    o->keyframe_timeout = 60;
    o->width = 1280, o->height = 720;
    o->hysteresis = MS_SELECT_HYSTERESIS_DEFAULT;
    o->draco_decoder = "draco_decoder";
    const char *tmp = getenv("TMPDIR");
    o->tmp_dir = tmp && *tmp ? tmp : "/tmp";
    int ch, status;
    int64_t i = 0;
    ms_error e;
    while ((ch = ms_cli_next("meshload", argc, argv, "h", opts)) != -1) {
        switch (ch) {
        case 's': {
            const char *colon = strrchr(optarg, ':');
            if (!colon || (size_t)(colon - optarg) >= sizeof o->host_text || colon == optarg ||
                ms_option_int("port", colon + 1, 1, 65535, &i, &e) != MS_OK) {
                fprintf(stderr, "meshload: --server wants HOST:PORT, not '%s'\n", optarg);
                return 2;
            }
            memcpy(o->host_text, optarg, (size_t)(colon - optarg));
            o->host_text[colon - optarg] = 0;
            o->host = o->host_text;
            o->port = (uint16_t)i;
            break;
        }
        case 'm': o->model = optarg; break;
        case 'p': o->path_file = optarg; break;
        case 'b':
            if (parse_bandwidth(optarg, &o->bandwidth) != 0) {
                fprintf(stderr, "meshload: --bandwidth wants e.g. 8mbit, not '%s'\n", optarg);
                return 2;
            }
            break;
        case 'v':
            if (sscanf(optarg, "%lfx%lf", &o->width, &o->height) != 2 || !(o->width >= 1) ||
                !(o->height >= 1) || o->width > 65536 || o->height > 65536) {
                fprintf(stderr, "meshload: --viewport wants WxH\n");
                return 2;
            }
            break;
        case 'T': o->token = optarg; break;
        case 'j': o->json = true; break;
        case 'n': o->skip_cold = true; break;
        case 'R': o->raw_index = true; break;
        case 'W': o->whole_index = true; break;
        case 'A': o->archive = optarg; break;
        case 'B':
            if (strcmp(optarg, "draco") != 0) {
                fprintf(stderr, "meshload: the only baseline is 'draco'\n");
                return 2;
            }
            o->baseline = optarg;
            break;
        case 'D': o->draco_decoder = optarg; break;
        case 'h': o->help = true; return 0;
        case MS_CLI_ERROR: return MS_CLI_USAGE; /* reported by ms_cli_next */
        default:
            if ((status = numeric_option(ch, optarg, o)) >= 0) {
                if (status)
                    return status;
                break;
            }
            return ms_cli_usage_error("meshload", "unknown option", argv[optind - 1]);
        }
    }
    if (o->archive && (o->host || o->baseline)) {
        fprintf(stderr, "meshload: --archive reads a local file: no --server, no --baseline\n");
        return 2;
    }
    if (o->archive && !o->model)
        o->model = "local";
    if (optind != argc || (!o->host && !o->archive) || !o->model ||
        (!o->baseline && !o->path_file)) {
        fprintf(stderr, "meshload: --server (or --archive), --model and (unless --baseline) "
                        "--path are required; see --help\n");
        return 2;
    }
    if (o->memory_ceiling && o->memory_target > o->memory_ceiling) {
        fprintf(stderr, "meshload: --memory-target above --memory-ceiling\n");
        return 2;
    }
    return 0;
}
