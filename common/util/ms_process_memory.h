/* The resident memory of this process as the kernel counts it
 * (/proc/self/status on Linux): what a program reports beside its own counts,
 * since a driver or library may hold far more than the program allocated
 * (meshview under Mesa's llvmpipe: docs/VIEWER.md, "Memory").
 *
 * Units: bytes (the kernel's kB times 1024). Errors: MS_ERR_IO with one line
 * when the file cannot be read (not Linux), MS_ERR_FORMAT when VmRSS or VmHWM
 * is missing. Thread-safety: none shared. */
#ifndef MS_PROCESS_MEMORY_H
#define MS_PROCESS_MEMORY_H

#include <stdint.h>

#include "ms_error.h"

typedef struct ms_process_memory {
    uint64_t rss;       /* VmRSS: resident now */
    uint64_t rss_peak;  /* VmHWM: the most resident at once since the start */
    uint64_t rss_anon;  /* RssAnon: of rss, anonymous pages (heaps, driver allocations) */
    uint64_t rss_file;  /* RssFile: of rss, mapped files (code of the program and its libraries) */
    uint64_t rss_shmem; /* RssShmem: of rss, shared memory (e.g. X11 shared images) */
} ms_process_memory;

/* Reads this process's figures. Absent Rss* lines (old kernels) read as 0. */
ms_status ms_process_memory_read(ms_process_memory *out, ms_error *err);

/* Parses the text of a /proc/PID/status file (pure: for tests). */
ms_status ms_process_memory_parse(const char *status_text, ms_process_memory *out, ms_error *err);

#endif
