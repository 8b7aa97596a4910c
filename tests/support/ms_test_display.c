/* An X display for GL tests (ms_test_display.h). */
#include "ms_test_display.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static bool display_socket_exists(int number)
{
    char path[64];
    snprintf(path, sizeof path, "/tmp/.X11-unix/X%d", number);
    struct stat st;
    return stat(path, &st) == 0 && S_ISSOCK(st.st_mode);
}

static bool display_number_free(int number)
{
    char lock[64];
    snprintf(lock, sizeof lock, "/tmp/.X%d-lock", number);
    return access(lock, F_OK) != 0 && !display_socket_exists(number);
}

/* The number in ":N" or ":N.S"; -1 for anything else (a remote display). */
static int local_display_number(const char *display)
{
    if (!display || display[0] != ':')
        return -1;
    char *end;
    long n = strtol(display + 1, &end, 10);
    if (end == display + 1 || (*end && *end != '.') || n < 0 || n > 65535)
        return -1;
    return (int)n;
}

static void sleep_ms(long ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* Starts Xvfb on :number; true once its socket exists. */
static bool start_xvfb(int number, pid_t *pid)
{
    char name[16];
    snprintf(name, sizeof name, ":%d", number);
    pid_t child = fork();
    if (child < 0)
        return false;
    if (child == 0) {
        int devnull = open("/dev/null", O_WRONLY);
        if (devnull >= 0) {
            dup2(devnull, STDOUT_FILENO);
            dup2(devnull, STDERR_FILENO);
        }
        execlp("Xvfb", "Xvfb", name, "-screen", "0", "1280x1024x24", "-nolisten", "tcp",
               (char *)NULL);
        _exit(127);
    }
    for (int waited = 0; waited < 10000; waited += 20) {
        if (display_socket_exists(number)) {
            *pid = child;
            return true;
        }
        int status;
        if (waitpid(child, &status, WNOHANG) == child)
            return false; /* exited: the number was taken meanwhile, or no Xvfb */
        sleep_ms(20);
    }
    kill(child, SIGKILL);
    waitpid(child, NULL, 0);
    return false;
}

bool ms_test_display_start(ms_test_display *display, char *why, size_t why_size)
{
    display->xvfb = 0;
    display->number = local_display_number(getenv("DISPLAY"));
    if (display->number >= 0 && display_socket_exists(display->number))
        return true;
    for (int number = 90; number < 190; number++) {
        if (!display_number_free(number))
            continue;
        pid_t pid;
        if (start_xvfb(number, &pid)) {
            char value[16];
            snprintf(value, sizeof value, ":%d", number);
            setenv("DISPLAY", value, 1);
            display->xvfb = pid;
            display->number = number;
            return true;
        }
    }
    snprintf(why, why_size, "no X display: Xvfb could not be started on :90 to :189 (%s)",
             strerror(errno));
    return false;
}

void ms_test_display_stop(ms_test_display *display)
{
    if (display->xvfb > 0) {
        kill(display->xvfb, SIGTERM);
        waitpid(display->xvfb, NULL, 0);
        display->xvfb = 0;
    }
}
