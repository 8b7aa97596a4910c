/* meshserve settings: see ms_server_config.h. */
#include "ms_server_config.h"
#include "ms_http_cors.h"
#include "ms_input_file.h"
#include "ms_parse_number.h"

#include <errno.h>
#include <stddef.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void ms_server_config_defaults(ms_server_config *c)
{
    memset(c, 0, sizeof *c);
    c->port = 7800;
    c->http_port = 7801;
    c->http_enabled = 1;
    c->max_clients = 1024;
    c->idle_timeout_s = 120;
    c->send_timeout_s = 60;
    c->max_frame = 1u << 20;
    c->max_batch = 1024;
    c->max_outstanding = 4096;
    c->max_queued_bytes = 64ull << 20;
    c->request_rate = 20000;
    c->http_rate = 2000;
    c->http_max_connections = 256;
    c->http_header_timeout_s = 30;
    c->http_park_s = 20;
    c->http_park_max = 4096;
    c->max_open_models = 256;
    c->model_idle_timeout_s = 300;
}

void ms_server_config_free(ms_server_config *c)
{
    free(c->archive_dir);
    free(c->bind_address);
    free(c->token);
    free(c->port_file);
    free(c->access_log);
    free(c->web_dir);
    free(c->cors_origins);
    memset(c, 0, sizeof *c);
}

static ms_status set_string(char **slot, const char *value, const char *where, ms_error *err)
{
    char *copy = strdup(value);
    if (!copy)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    free(*slot);
    *slot = copy;
    return MS_OK;
}

/* A token is 1..256 printable ASCII characters without spaces (as on the wire). */
static bool token_valid(const char *t)
{
    size_t n = strlen(t);
    if (n < 1 || n > 256)
        return false;
    for (size_t i = 0; i < n; ++i)
        if (t[i] < 0x21 || t[i] > 0x7e)
            return false;
    return true;
}

ms_status ms_server_config_set(ms_server_config *c, const char *key, const char *value,
                               const char *where, ms_error *err)
{
    static const struct {
        const char *key;
        size_t offset;
        int width; /* 4 or 8 bytes */
        int64_t min, max;
    } numbers[] = {
        {"port", offsetof(ms_server_config, port), 4, 0, 65535},
        {"max_clients", offsetof(ms_server_config, max_clients), 4, 1, 100000},
        {"idle_timeout", offsetof(ms_server_config, idle_timeout_s), 4, 1, 86400},
        {"send_timeout", offsetof(ms_server_config, send_timeout_s), 4, 1, 86400},
        {"max_frame", offsetof(ms_server_config, max_frame), 4, 16384, 16u << 20},
        {"max_batch", offsetof(ms_server_config, max_batch), 4, 1, 65536},
        {"max_outstanding", offsetof(ms_server_config, max_outstanding), 4, 1, 1u << 20},
        {"max_queued_bytes", offsetof(ms_server_config, max_queued_bytes), 8, 1u << 16, 1ull << 34},
        {"request_rate", offsetof(ms_server_config, request_rate), 4, 1, 10000000},
        {"http_rate", offsetof(ms_server_config, http_rate), 4, 1, 10000000},
        {"http_max_connections", offsetof(ms_server_config, http_max_connections), 4, 1, 100000},
        {"http_header_timeout", offsetof(ms_server_config, http_header_timeout_s), 4, 1, 3600},
        {"http_park", offsetof(ms_server_config, http_park_s), 4, 0, 3600},
        {"http_park_max", offsetof(ms_server_config, http_park_max), 4, 1, 65536},
        {"max_open_models", offsetof(ms_server_config, max_open_models), 4, 1, 1000000},
        {"model_idle_timeout", offsetof(ms_server_config, model_idle_timeout_s), 4, 1, 86400},
    };
    for (size_t i = 0; i < sizeof numbers / sizeof *numbers; ++i) {
        if (strcmp(key, numbers[i].key) != 0)
            continue;
        int64_t v;
        ms_error e;
        if (ms_option_int(key, value, numbers[i].min, numbers[i].max, &v, &e) != MS_OK)
            return ms_error_set(err, MS_ERR_RANGE, "%s: %s", where, e.text);
        char *slot = (char *)c + numbers[i].offset;
        if (numbers[i].width == 4) {
            uint32_t v32 = (uint32_t)v;
            memcpy(slot, &v32, 4);
        } else {
            memcpy(slot, &v, 8);
        }
        return MS_OK;
    }
    if (!strcmp(key, "http_port")) {
        int64_t v;
        ms_error e;
        if (!strcmp(value, "off")) {
            c->http_enabled = 0;
            return MS_OK;
        }
        if (ms_option_int(key, value, 0, 65535, &v, &e) != MS_OK)
            return ms_error_set(err, MS_ERR_RANGE, "%s: http_port wants 0..65535 or 'off', got '%s'",
                                where, value);
        c->http_port = (uint32_t)v;
        c->http_enabled = 1;
        return MS_OK;
    }
    if (!strcmp(key, "bind")) {
        if (!*value || strlen(value) > 255)
            return ms_error_set(err, MS_ERR_RANGE, "%s: bind wants an address", where);
        return set_string(&c->bind_address, value, where, err);
    }
    if (!strcmp(key, "token")) {
        if (!token_valid(value))
            return ms_error_set(err, MS_ERR_RANGE,
                                "%s: token must be 1-256 printable ASCII characters without spaces",
                                where);
        return set_string(&c->token, value, where, err);
    }
    if (!strcmp(key, "archive_dir"))
        return set_string(&c->archive_dir, value, where, err);
    if (!strcmp(key, "port_file"))
        return set_string(&c->port_file, value, where, err);
    if (!strcmp(key, "access_log")) {
        if (!*value)
            return ms_error_set(err, MS_ERR_RANGE, "%s: access_log wants a file path", where);
        return set_string(&c->access_log, value, where, err);
    }
    if (!strcmp(key, "web_dir")) {
        if (!*value)
            return ms_error_set(err, MS_ERR_RANGE, "%s: web_dir wants a folder", where);
        return set_string(&c->web_dir, value, where, err);
    }
    if (!strcmp(key, "cors_origins")) {
        ms_status checked = ms_http_cors_check(value, where, err);
        return checked != MS_OK ? checked : set_string(&c->cors_origins, value, where, err);
    }
    return ms_error_set(err, MS_ERR_ARG, "%s: unknown setting '%s'", where, key);
}

/* Trims ASCII white space at both ends, in place. */
static char *trim(char *s)
{
    while (*s == ' ' || *s == '\t')
        ++s;
    size_t n = strlen(s);
    while (n && (s[n - 1] == ' ' || s[n - 1] == '\t' || s[n - 1] == '\r' || s[n - 1] == '\n'))
        s[--n] = '\0';
    return s;
}

ms_status ms_server_config_load(ms_server_config *c, const char *path, ms_error *err)
{
    FILE *f;
    ms_status opened = ms_input_fopen(path, &f, err);
    if (opened != MS_OK)
        return opened;
    char line[1024], where[4200], seen[64][32];
    size_t seen_count = 0;
    unsigned number = 0;
    ms_status st = MS_OK;
    while (st == MS_OK && fgets(line, sizeof line, f)) {
        ++number;
        snprintf(where, sizeof where, "%s:%u", path, number);
        if (!strchr(line, '\n') && !feof(f)) {
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: line too long", where);
            break;
        }
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        char *text = trim(line);
        if (!*text)
            continue;
        char *eq = strchr(text, '=');
        if (!eq) {
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: expected 'key = value'", where);
            break;
        }
        *eq = '\0';
        char *key = trim(text), *value = trim(eq + 1);
        for (size_t i = 0; i < seen_count; ++i)
            if (!strcmp(seen[i], key))
                st = ms_error_set(err, MS_ERR_FORMAT, "%s: '%s' set twice", where, key);
        if (st != MS_OK)
            break;
        if (seen_count < 64 && strlen(key) < sizeof seen[0])
            snprintf(seen[seen_count++], sizeof seen[0], "%s", key);
        st = ms_server_config_set(c, key, value, where, err);
    }
    if (st == MS_OK && ferror(f))
        st = ms_error_set(err, MS_ERR_IO, "%s: read error", path);
    fclose(f);
    return st;
}
