/* Installing meshstream (issue 33, item 3; docs/INSTALL.md): every program
 * answers --version with the one version of the VERSION file, and
 * `make install DESTDIR=...` lays out the programs, man pages, systemd unit,
 * deploy templates and libmeshstream-client (shared with a soname and only
 * msc_* exported, static, header, pkg-config file), against which the README's
 * example builds with pkg-config and streams a baked model from meshserve on
 * loopback and from the archive file, every cell at full precision: exactly
 * the archive's triangles, vertices and leaves. `make uninstall` removes every
 * file again. Runs from the repository root; the install builds the release
 * programs and the library when they are not built yet. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include <glob.h>
#include <signal.h>

#include "ms_archive.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_test_net.h"

enum { PROGRAM_COUNT = 12 };

/* The VERSION file's one line, without its newline. */
static void read_version(char *out, size_t size)
{
    size_t length;
    unsigned char *text = ms_test_read_file("VERSION", &length);
    while (length > 0 && (text[length - 1] == '\n' || text[length - 1] == '\r'))
        --length;
    assert_true(length > 0 && length < size);
    memcpy(out, text, length);
    out[length] = '\0';
    free(text);
    assert_null(strchr(out, '\n'));
}

/* The programs' names: one per *_main.c of a room (the Makefile's rule). */
static size_t program_names(char names[][64], size_t max)
{
    glob_t g;
    size_t n = 0;
    assert_int_equal(glob("*/*/*_main.c", 0, NULL, &g), 0);
    for (size_t i = 0; i < g.gl_pathc && n < max; ++i) {
        const char *base = strrchr(g.gl_pathv[i], '/') + 1;
        snprintf(names[n++], 64, "%.*s", (int)(strlen(base) - strlen("_main.c")), base);
    }
    globfree(&g);
    return n;
}

/* `DIR/NAME --version` prints exactly "NAME VERSION\n" on stdout, nothing on
 * stderr, and exits 0, wherever --version stands on the line. */
static void assert_version(const char *dir, const char *name, const char *version,
                           const char *err_path)
{
    static const char *const lines[] = {"--version", "--json --version", "--version --help"};
    for (size_t k = 0; k < sizeof lines / sizeof lines[0]; ++k) {
        char cmd[1400], out[512], want[256];
        snprintf(cmd, sizeof cmd, "'%s/%s' %s 2>'%s'", dir, name, lines[k], err_path);
        int rc = ms_test_run(cmd, out, sizeof out);
        snprintf(want, sizeof want, "%s %s\n", name, version);
        if (rc != 0 || strcmp(out, want) != 0)
            fail_msg("%s: exit %d, printed '%s', want '%s'", cmd, rc, out, want);
        struct stat st;
        assert_int_equal(stat(err_path, &st), 0);
        assert_int_equal(st.st_size, 0);
    }
}

static void test_every_program_answers_version(void **state)
{
    (void)state;
    char version[64], names[32][64], bin[4096], tmp[512];
    read_version(version, sizeof version);
    size_t n = program_names(names, 32);
    assert_int_equal(n, PROGRAM_COUNT);
    ms_test_bin_path(bin, sizeof bin, "meshgen");
    *strrchr(bin, '/') = '\0';
    ms_test_tmpdir(tmp, sizeof tmp);
    char err_path[600];
    snprintf(err_path, sizeof err_path, "%s/stderr", tmp);
    for (size_t i = 0; i < n; ++i)
        assert_version(bin, names[i], version, err_path);
    ms_test_rmdir(tmp);
}

/* Every program reads its command line one way (ms_cli): an unknown option,
 * alone or after an argument, and an option without its value give exactly one
 * line on stderr, "NAME: WHAT: OPTION (see NAME --help)", nothing on stdout,
 * and exit status 2. */
static void test_every_program_refuses_bad_options(void **state)
{
    (void)state;
    char names[32][64], bin[4096], tmp[512];
    size_t n = program_names(names, 32);
    assert_int_equal(n, PROGRAM_COUNT);
    ms_test_bin_path(bin, sizeof bin, "meshgen");
    *strrchr(bin, '/') = '\0';
    ms_test_tmpdir(tmp, sizeof tmp);
    for (size_t i = 0; i < n; ++i) {
        static const char *const lines[] = {"--frobnicate", "IN.ply --frobnicate"};
        for (size_t k = 0; k < sizeof lines / sizeof *lines; ++k) {
            char cmd[8192], out[512], want[256], err_path[600];
            snprintf(err_path, sizeof err_path, "%s/stderr", tmp);
            snprintf(cmd, sizeof cmd, "'%s/%s' %s 2>'%s'", bin, names[i], lines[k], err_path);
            if (strcmp(names[i], "meshcodec") == 0 && k == 1) /* its options follow a command */
                snprintf(cmd, sizeof cmd, "'%s/%s' encode --frobnicate 2>'%s'", bin, names[i],
                         err_path);
            int rc = ms_test_run(cmd, out, sizeof out);
            size_t length;
            unsigned char *err_text = ms_test_read_file(err_path, &length);
            const char *who = strcmp(names[i], "meshcodec") == 0 && k == 1 ? "meshcodec encode"
                                                                           : names[i];
            snprintf(want, sizeof want, "%s: unknown option: --frobnicate (see %s --help)\n", who,
                     who);
            if (rc != 2 || out[0] || length != strlen(want) || memcmp(err_text, want, length) != 0)
                fail_msg("%s: exit %d, stdout '%s', stderr '%.*s', want '%s'", cmd, rc, out,
                         (int)length, (const char *)err_text, want);
            free(err_text);
        }
    }
    /* an option that wants a value, given none */
    static const char *const valued[][2] = {{"meshgen", "--triangles"}, {"meshbake", "--bits"},
                                            {"meshload", "--tolerance"}, {"meshview", "--size"},
                                            {"meshserve", "--config"}, {"meshrender", "--width"}};
    for (size_t i = 0; i < sizeof valued / sizeof *valued; ++i) {
        char cmd[8192], out[512], want[256], err_path[600];
        snprintf(err_path, sizeof err_path, "%s/stderr", tmp);
        snprintf(cmd, sizeof cmd, "'%s/%s' %s 2>'%s'", bin, valued[i][0], valued[i][1], err_path);
        int rc = ms_test_run(cmd, out, sizeof out);
        size_t length;
        unsigned char *err_text = ms_test_read_file(err_path, &length);
        snprintf(want, sizeof want, "%s: option needs a value: %s (see %s --help)\n", valued[i][0],
                 valued[i][1], valued[i][0]);
        if (rc != 2 || length != strlen(want) || memcmp(err_text, want, length) != 0)
            fail_msg("%s: exit %d, stderr '%.*s', want '%s'", cmd, rc, (int)length,
                     (const char *)err_text, want);
        free(err_text);
    }
    ms_test_rmdir(tmp);
}

/* Runs a shell command that must exit 0; its output into out. */
static void run_ok(const char *cmd, char *out, size_t size)
{
    int rc = ms_test_run(cmd, out, size);
    if (rc != 0)
        fail_msg("%s: exit %d:\n%s", cmd, rc, out);
}

static size_t count_leaves(const ms_archive *a)
{
    size_t leaves = 0;
    for (uint32_t c = 0; c < ms_archive_get_header(a)->cell_count; ++c)
        leaves += ms_archive_get_cell(a, c)->first_child == MS_ARCHIVE_NONE;
    return leaves;
}

/* The installed tree: every file the install promises, in place. */
static void assert_installed(const char *root, const char *version, char names[][64], size_t n)
{
    static const char *const files[] = {
        "usr/include/meshstream-client.h", "usr/lib/libmeshstream-client.a",
        "usr/lib/libmeshstream-client.so", "usr/lib/libmeshstream-client.so.0",
        "usr/lib/pkgconfig/meshstream-client.pc", "usr/lib/systemd/system/meshserve@.service",
        "usr/share/meshstream/deploy/meshserve.conf.in", "usr/share/meshstream/deploy/haproxy.cfg.in",
        "usr/share/meshstream/deploy/nginx.conf.in", "usr/share/meshstream/deploy/fill",
        "usr/share/doc/meshstream/README.md", "usr/share/doc/meshstream/DEPLOY.md",
        "usr/share/doc/meshstream/INSTALL.md", "usr/share/doc/meshstream/examples/client_example.c"};
    char path[1200], out[8192];
    struct stat st;
    for (size_t i = 0; i < sizeof files / sizeof files[0]; ++i) {
        snprintf(path, sizeof path, "%s/%s", root, files[i]);
        if (stat(path, &st) != 0)
            fail_msg("not installed: %s", path);
    }
    snprintf(path, sizeof path, "%s/usr/lib/libmeshstream-client.so.%s", root, version);
    assert_int_equal(stat(path, &st), 0);
    for (size_t i = 0; i < n; ++i) {
        snprintf(path, sizeof path, "%s/usr/share/man/man1/%s.1", root, names[i]);
        if (stat(path, &st) != 0 || st.st_size < 500)
            fail_msg("no man page: %s", path);
        char err_path[1200];
        snprintf(path, sizeof path, "%s/usr/bin", root);
        snprintf(err_path, sizeof err_path, "%s/../stderr", root);
        assert_version(path, names[i], version, err_path);
    }
    /* the unit runs the installed server; the shared object is named by its
     * soname and exports the public header's functions only */
    snprintf(path, sizeof path,
             "grep -c '^ExecStart=/usr/bin/meshserve --config' '%s/usr/lib/systemd/system/meshserve@.service'",
             root);
    run_ok(path, out, sizeof out);
    snprintf(path, sizeof path, "objdump -p '%s/usr/lib/libmeshstream-client.so' | grep SONAME", root);
    run_ok(path, out, sizeof out);
    assert_non_null(strstr(out, "libmeshstream-client.so.0\n"));
    snprintf(path, sizeof path,
             "nm -D --defined-only '%s/usr/lib/libmeshstream-client.so' | awk '{print $3}' | sort",
             root);
    run_ok(path, out, sizeof out);
    size_t exported = 0;
    for (char *line = strtok(out, "\n"); line; line = strtok(NULL, "\n"), ++exported)
        if (strncmp(line, "msc_", 4) != 0)
            fail_msg("the shared object exports '%s'", line);
    assert_int_equal(exported, 28); /* the functions of meshstream-client.h */
}

static void test_install_example_uninstall(void **state)
{
    (void)state;
    char dir[512], archives[600], root[700], version[64], names[32][64];
    static char cmd[8192], out[65536];
    read_version(version, sizeof version);
    size_t n = program_names(names, 32);
    assert_int_equal(ms_nsp_test_demo_archive(dir, sizeof dir, archives, sizeof archives), 0);
    snprintf(root, sizeof root, "%s/root", dir);

    /* MODE and the caller's make flags (make test's jobserver) stay outside */
    snprintf(cmd, sizeof cmd,
             "env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s -j2 MODE=release install PREFIX=/usr "
             "DESTDIR='%s' 2>&1",
             root);
    run_ok(cmd, out, sizeof out);
    assert_installed(root, version, names, n);

    /* the README's example, built with pkg-config against the installed tree */
    const char *env_pc = "PKG_CONFIG_PATH='%s/usr/lib/pkgconfig' PKG_CONFIG_SYSROOT_DIR='%s'";
    char pc[1600];
    snprintf(pc, sizeof pc, env_pc, root, root);
    snprintf(cmd, sizeof cmd, "%s pkg-config --modversion meshstream-client", pc);
    run_ok(cmd, out, sizeof out);
    assert_true(strncmp(out, version, strlen(version)) == 0 && out[strlen(version)] == '\n');
    snprintf(cmd, sizeof cmd,
             "cc -std=c11 -Wall -Wextra -Werror '%s/usr/share/doc/meshstream/examples/client_example.c' "
             "$(%s pkg-config --cflags --libs meshstream-client) -o '%s/client_example'",
             root, pc, dir);
    run_ok(cmd, out, sizeof out);

    /* what it must receive: the archive at full precision */
    char file[700], port_file[700], log[700];
    snprintf(file, sizeof file, "%s/demo.msa", archives);
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(file, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    const ms_archive_header *h = ms_archive_get_header(a);
    char want_model[256], want_view[256];
    snprintf(want_model, sizeof want_model,
             "libmeshstream-client %s: model of %llu triangles in %u cells, %u bits\n", version,
             (unsigned long long)h->triangle_count, h->cell_count, (unsigned)h->bits);
    size_t leaves = count_leaves(a);
    snprintf(want_view, sizeof want_view,
             "view complete: %zu cells, %zu at full precision, %llu triangles, %llu vertices, ",
             leaves, leaves, (unsigned long long)h->triangle_count,
             (unsigned long long)h->vertex_count);
    assert_true(h->triangle_count > 3000 && leaves > 1);
    ms_archive_close(a);

    snprintf(port_file, sizeof port_file, "%s/ports", dir);
    snprintf(log, sizeof log, "%s/meshserve.log", dir);
    uint16_t port, http_port;
    pid_t server = ms_test_meshserve_start(archives, NULL, 0, port_file, log, &port, &http_port);
    assert_true(server > 0);
    const char *sources[] = {"127.0.0.1:%u/demo", "%s"};
    for (int k = 0; k < 2; ++k) {
        char source[800];
        if (k == 0)
            snprintf(source, sizeof source, sources[0], (unsigned)port);
        else
            snprintf(source, sizeof source, sources[1], file);
        snprintf(cmd, sizeof cmd,
                 "LD_LIBRARY_PATH='%s/usr/lib' timeout 120 '%s/client_example' '%s' 0.0001 2>&1", root,
                 dir, source);
        run_ok(cmd, out, sizeof out);
        if (strncmp(out, want_model, strlen(want_model)) != 0 || !strstr(out, want_view))
            fail_msg("%s printed:\n%s\nwant:\n%s%s...", source, out, want_model, want_view);
    }
    /* an unknown model: one line naming it, exit 1 */
    snprintf(cmd, sizeof cmd,
             "LD_LIBRARY_PATH='%s/usr/lib' timeout 60 '%s/client_example' 127.0.0.1:%u/nosuch 2>&1",
             root, dir, (unsigned)port);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "client_example: open: cannot open model 'nosuch'"));
    assert_int_equal(ms_test_stop(server, SIGTERM, 20.0), 0);

    /* uninstall leaves no file behind */
    snprintf(cmd, sizeof cmd,
             "env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s MODE=release uninstall PREFIX=/usr "
             "DESTDIR='%s' 2>&1 && find '%s' ! -type d",
             root, root);
    run_ok(cmd, out, sizeof out);
    if (out[0])
        fail_msg("left after uninstall:\n%s", out);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_program_answers_version),
        cmocka_unit_test(test_every_program_refuses_bad_options),
        cmocka_unit_test(test_install_example_uninstall),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
