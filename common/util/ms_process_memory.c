/* /proc/self/status, read in one go and parsed line by line. */
#include "ms_process_memory.h"

#include <errno.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The kB figure of the line starting with key (e.g. "VmRSS:"), in bytes;
 * false when there is none. */
static bool field_bytes(const char *text, const char *key, uint64_t *bytes)
{
    size_t n = strlen(key);
    const char *line = text;
    while (strncmp(line, key, n) != 0) {
        line = strchr(line, '\n');
        if (!line)
            return false;
        ++line;
    }
    char *end;
    errno = 0;
    unsigned long long kb = strtoull(line + n, &end, 10);
    if (errno || end == line + n)
        return false;
    *bytes = (uint64_t)kb * 1024u;
    return true;
}

ms_status ms_process_memory_parse(const char *text, ms_process_memory *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (!field_bytes(text, "VmRSS:", &out->rss) || !field_bytes(text, "VmHWM:", &out->rss_peak))
        return ms_error_set(err, MS_ERR_FORMAT, "process status: no VmRSS or VmHWM line");
    (void)field_bytes(text, "RssAnon:", &out->rss_anon);
    (void)field_bytes(text, "RssFile:", &out->rss_file);
    (void)field_bytes(text, "RssShmem:", &out->rss_shmem);
    return MS_OK;
}

ms_status ms_process_memory_read(ms_process_memory *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return ms_error_set(err, MS_ERR_IO, "/proc/self/status: cannot open: %s", strerror(errno));
    char text[8192]; /* the file is about 1.5 kB */
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    return ms_process_memory_parse(text, out, err);
}
