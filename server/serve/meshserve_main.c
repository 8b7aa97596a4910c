/* meshserve: serves the models of an archive directory. */
#include <getopt.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_json_out.h"
#include "ms_cli.h"
#include "ms_progress.h"
#include "ms_server.h"
#include "ms_version.h"

static void usage(FILE *out)
{
    fprintf(out,
            "Usage: meshserve ARCHIVE_DIR [options]\n"
            "       meshserve --config FILE [options]   (FILE sets archive_dir)\n"
            "Serves the models baked into ARCHIVE_DIR (see meshbake) to meshstream clients.\n"
            "SIGTERM or Ctrl-C: finish the transfers in progress, then exit with a summary.\n"
            "SIGHUP: rescan ARCHIVE_DIR for new, changed or removed models, keeping connections\n"
            "(handles on a changed or removed model get ERROR MODEL_CHANGED), and reopen the\n"
            "access log.\n\n"
            "  --port PORT          binary protocol (protocol/PROTOCOL.md), 0 = any free port\n"
            "                       (default 7800)\n"
            "  --http-port PORT     HTTP side door (catalogue, indexes, cells, /metrics), 0 = any\n"
            "                       free port, 'off' to disable (default 7801)\n"
            "  --bind ADDRESS       numeric IPv4 or IPv6 address to listen on (default\n"
            "                       127.0.0.1)\n"
            "  --max-clients N      simultaneous binary connections; more are answered with\n"
            "                       ERROR TOO_MANY_CONNECTIONS (default 1024)\n"
            "  --config FILE        settings file, one 'key = value' a line; keys: archive_dir,\n"
            "                       port, http_port, bind, token, idle_timeout (s), send_timeout (s\n"
            "                       without a byte read by a client that has bytes waiting;\n"
            "                       default 60), http_rate, http_max_connections (256),\n"
            "                       http_header_timeout (s to deliver a request header, 30),\n"
            "                       http_park (s a connection shed at the cap is held unread\n"
            "                       before its reset, 20; 0 closes it at once), http_park_max\n"
            "                       (the most held so, 4096),\n"
            "                       max_clients, max_frame (bytes), max_batch, max_outstanding,\n"
            "                       max_queued_bytes (per connection), request_rate (per s and\n"
            "                       connection), access_log (file: one JSON line per binary\n"
            "                       connection and per HTTP answer, docs/DEPLOY.md),\n"
            "                       max_open_models (archives kept open that no client\n"
            "                       holds, 256), model_idle_timeout (s before an unused\n"
            "                       model's archive closes, 300), web_dir,\n"
            "                       cors_origins\n"
            "  --web-dir DIR        serve the browser pages from DIR (make wasm builds them\n"
            "                       into build/wasm/site) at /, /view/NAME and /web/FILE\n"
            "                       (docs/BROWSER.md; default: not served)\n"
            "  --cors-origins LIST  the origins whose pages may read the HTTP answers\n"
            "                       (https://museum.example[:PORT], comma-separated) or '*'\n"
            "                       (default: none; docs/BROWSER.md)\n"
            "  --port-file FILE     write \"PORT HTTP_PORT\" there once listening (for scripts)\n"
            "  --json               print the exit summary as one JSON object\n"
            "  -h, --help           show this help\n"
            "      --version        show the version\n"
            "Command-line options override the config file. The access token for models\n"
            "with a public preview is only read from the config file ('token = ...').\n");
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshserve");
    enum { OPT_PORT = 256, OPT_MAX_CLIENTS, OPT_HTTP_PORT, OPT_BIND, OPT_CONFIG, OPT_PORT_FILE, OPT_JSON,
           OPT_WEB_DIR, OPT_CORS };
    static const struct option options[] = {
        {"port", required_argument, NULL, OPT_PORT},
        {"max-clients", required_argument, NULL, OPT_MAX_CLIENTS},
        {"http-port", required_argument, NULL, OPT_HTTP_PORT},
        {"bind", required_argument, NULL, OPT_BIND},
        {"config", required_argument, NULL, OPT_CONFIG},
        {"port-file", required_argument, NULL, OPT_PORT_FILE},
        {"json", no_argument, NULL, OPT_JSON},
        {"web-dir", required_argument, NULL, OPT_WEB_DIR},
        {"cors-origins", required_argument, NULL, OPT_CORS},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    const char *config_path = NULL;
    typedef struct setting {
        const char *key, *value, *where;
    } setting;
    setting overrides[16];
    int override_count = 0;
    bool json = false;
    int c;
    while ((c = ms_cli_next("meshserve", argc, argv, "h", options)) != -1) {
        switch (c) {
        case OPT_PORT: overrides[override_count++] = (setting){"port", optarg, "--port"}; break;
        case OPT_MAX_CLIENTS: overrides[override_count++] = (setting){"max_clients", optarg, "--max-clients"}; break;
        case OPT_HTTP_PORT: overrides[override_count++] = (setting){"http_port", optarg, "--http-port"}; break;
        case OPT_BIND: overrides[override_count++] = (setting){"bind", optarg, "--bind"}; break;
        case OPT_PORT_FILE: overrides[override_count++] = (setting){"port_file", optarg, "--port-file"}; break;
        case OPT_WEB_DIR: overrides[override_count++] = (setting){"web_dir", optarg, "--web-dir"}; break;
        case OPT_CORS: overrides[override_count++] = (setting){"cors_origins", optarg, "--cors-origins"}; break;
        case OPT_CONFIG: config_path = optarg; break;
        case OPT_JSON: json = true; break;
        case 'h': usage(stdout); return 0;
        default: return MS_CLI_USAGE; /* reported by ms_cli_next */
        }
        if (override_count == 16) {
            fprintf(stderr, "meshserve: too many options\n");
            return 2;
        }
    }
    /* ARCHIVE_DIR may come from the config file instead (archive_dir = ...),
     * as in deploy/meshserve.conf.in. */
    if (optind < argc - 1 || (optind == argc && !config_path)) {
        fprintf(stderr, "meshserve: expected one ARCHIVE_DIR (try 'meshserve --help')\n");
        return 2;
    }
    ms_server_config config;
    ms_server_config_defaults(&config);
    ms_error err;
    ms_status st = config_path ? ms_server_config_load(&config, config_path, &err) : MS_OK;
    if (st == MS_OK && optind < argc) /* the command line wins */
        st = ms_server_config_set(&config, "archive_dir", argv[optind], "ARCHIVE_DIR", &err);
    if (st == MS_OK && !config.archive_dir)
        st = ms_error_set(&err, MS_ERR_ARG, "%s: no archive_dir (and no ARCHIVE_DIR argument)",
                          config_path);
    for (int i = 0; st == MS_OK && i < override_count; ++i)
        st = ms_server_config_set(&config, overrides[i].key, overrides[i].value, overrides[i].where, &err);
    if (st != MS_OK) {
        fprintf(stderr, "meshserve: %s\n", err.text);
        ms_server_config_free(&config);
        return 2;
    }
    ms_server *server;
    if (ms_server_new(&config, &server, &err) != MS_OK) {
        fprintf(stderr, "meshserve: %s\n", err.text);
        return 1;
    }
    ms_server_log(server, "serving %zu models from %s; binary protocol on port %u, http on port %u",
                  ms_server_model_count(server), ms_server_archive_dir(server),
                  ms_server_bound_port(server, false), ms_server_bound_port(server, true));
    ms_server_run(server);
    const ms_server_metrics *m = ms_server_get_metrics(server);
    double uptime = ms_now_seconds() - ms_server_started_at(server);
    if (json)
        ms_json_print(stdout,
                      json_pack("{s:o, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I}", "uptime_seconds", ms_json_fixed(uptime, 3), "models",
                                (json_int_t)ms_server_model_count(server), "http_requests",
                                (json_int_t)m->http_requests, "http_errors", (json_int_t)m->http_errors,
                                "binary_connections", (json_int_t)m->binary_connections_total,
                                "binary_requests", (json_int_t)m->binary_requests, "binary_errors",
                                (json_int_t)m->binary_errors, "bytes_sent",
                                (json_int_t)(m->http_bytes_sent + m->binary_bytes_sent), "rescans",
                                (json_int_t)m->rescans),
                      MS_JSON_SPACED);
    else
        printf("meshserve: stopped after %.1f s: %llu HTTP requests (%llu errors), %llu binary "
               "connections, %llu binary requests (%llu errors), %llu bytes sent, %llu rescans\n",
               uptime, (unsigned long long)m->http_requests, (unsigned long long)m->http_errors,
               (unsigned long long)m->binary_connections_total,
               (unsigned long long)m->binary_requests, (unsigned long long)m->binary_errors,
               (unsigned long long)(m->http_bytes_sent + m->binary_bytes_sent),
               (unsigned long long)m->rescans);
    ms_server_free(server);
    return 0;
}
