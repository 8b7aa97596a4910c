#include "ms_progress.h"

#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

double ms_now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

double ms_peak_rss_mb(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return 0.0;
    return (double)ru.ru_maxrss / 1024.0; /* Linux reports KiB */
}

void ms_progress_init(ms_progress *p, FILE *out, const char *label, uint64_t total)
{
    p->out = out;
    p->label = label;
    p->total = total;
    p->start_seconds = p->last_draw_seconds = ms_now_seconds();
    p->enabled = out && isatty(fileno(out));
    p->drawn = false;
}

void ms_progress_update(ms_progress *p, uint64_t done)
{
    if (!p->enabled)
        return;
    double now = ms_now_seconds();
    if (p->drawn && now - p->last_draw_seconds < 0.1)
        return;
    p->last_draw_seconds = now;
    p->drawn = true;
    double elapsed = now - p->start_seconds;
    if (p->total == 0) {
        fprintf(p->out, "\r%s: %llu (%.1f s)\033[K", p->label, (unsigned long long)done, elapsed);
    } else {
        double frac = done >= p->total ? 1.0 : (double)done / (double)p->total;
        int width = 30, filled = (int)(frac * width);
        char bar[31];
        for (int i = 0; i < width; ++i)
            bar[i] = i < filled ? '#' : '.';
        bar[width] = '\0';
        double eta = frac > 0.0 ? elapsed * (1.0 - frac) / frac : 0.0;
        fprintf(p->out, "\r%s [%s] %5.1f%% %.1f s, %.0f s left\033[K", p->label, bar,
                100.0 * frac, elapsed, eta);
    }
    fflush(p->out);
}

void ms_progress_finish(ms_progress *p)
{
    if (p->enabled && p->drawn) {
        fprintf(p->out, "\r\033[K");
        fflush(p->out);
    }
    p->drawn = false;
}
