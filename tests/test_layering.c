/* The rooms of docs/ARCHITECTURE.md and the build's enforcement of them: every
 * quoted #include of every source file names a header alone (no ".." path,
 * which would reach around the include paths) and lands, looked up as the
 * compiler does, inside the rooms its room may use (the Makefile's USES_
 * lists, read back with `make -s room-flags`), no file includes another
 * room's *_internal.h, and a file that reaches into a room it may not use
 * fails to compile. Runs from the repository root. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <limits.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "ms_test.h"

enum { MAX_ROOMS = 32, MAX_DIRS = 32, PATH_LEN = 512 };

/* make as a plain child: when the suite itself runs under make (make test), the
 * inherited MAKEFLAGS would have it warn on stderr about the jobserver. */
#define MAKE_QUIET "env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -s --no-print-directory 2>/dev/null"

typedef struct {
    char name[64];
    char dirs[MAX_DIRS][64]; /* include directories, the room's own among them */
    size_t dir_count;
} room_info;

typedef struct {
    room_info rooms[MAX_ROOMS];
    size_t count;
} room_table;

static void split_words(const char *text, void (*take)(const char *word, void *ctx), void *ctx)
{
    const char *p = text;
    while (*p) {
        while (*p == ' ' || *p == '\n' || *p == '\t')
            ++p;
        const char *start = p;
        while (*p && *p != ' ' && *p != '\n' && *p != '\t')
            ++p;
        if (p > start) {
            char word[128];
            size_t n = (size_t)(p - start) < sizeof word - 1 ? (size_t)(p - start) : sizeof word - 1;
            memcpy(word, start, n);
            word[n] = '\0';
            take(word, ctx);
        }
    }
}

static void add_room(const char *word, void *ctx)
{
    room_table *t = ctx;
    assert_true(t->count < MAX_ROOMS);
    snprintf(t->rooms[t->count++].name, sizeof t->rooms[0].name, "%s", word);
}

static void add_dir(const char *word, void *ctx)
{
    room_info *r = ctx;
    assert_true(strncmp(word, "-I", 2) == 0);
    assert_true(r->dir_count < MAX_DIRS);
    snprintf(r->dirs[r->dir_count++], sizeof r->dirs[0], "%s", word + 2);
}

static void load_rooms(room_table *t)
{
    static char out[8192];
    memset(t, 0, sizeof *t);
    assert_int_equal(ms_test_run(MAKE_QUIET " rooms", out, sizeof out), 0);
    split_words(out, add_room, t);
    assert_true(t->count >= 10);
    for (size_t i = 0; i < t->count; ++i) {
        char cmd[PATH_LEN];
        snprintf(cmd, sizeof cmd, MAKE_QUIET " room-flags ROOM=%s", t->rooms[i].name);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
        split_words(out, add_dir, &t->rooms[i]);
    }
}

static bool file_exists(const char *dir, const char *name)
{
    char path[PATH_LEN * 2];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

static bool is_source(const char *name)
{
    const char *dot = strrchr(name, '.');
    return dot && (strcmp(dot, ".c") == 0 || strcmp(dot, ".h") == 0 || strcmp(dot, ".cpp") == 0);
}

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

/* A ".." anywhere among the path's components. */
static bool climbs(const char *header)
{
    for (const char *p = header; (p = strstr(p, "..")); p += 2)
        if ((p == header || p[-1] == '/') && (p[2] == '\0' || p[2] == '/'))
            return true;
    return false;
}

/* The room (index into t) whose folder holds the file at `path` (a real path),
 * the deepest such room; -1 when none of the tree's rooms does. */
static int room_of_file(const room_table *t, const char *real_root, const char *path)
{
    size_t root_n = strlen(real_root);
    if (strncmp(path, real_root, root_n) != 0 || path[root_n] != '/')
        return -1;
    const char *rel = path + root_n + 1;
    int best = -1;
    size_t best_n = 0;
    for (size_t r = 0; r < t->count; ++r) {
        size_t n = strlen(t->rooms[r].name);
        if (n > best_n && strncmp(rel, t->rooms[r].name, n) == 0 && rel[n] == '/')
            best = (int)r, best_n = n;
    }
    return best;
}

/* Where a quoted include of a file in `room` lands, as the compiler looks:
 * the including file's folder (the room's), then the room's include paths,
 * each under root. The room it lands in, or -1 when none of ours (a system
 * or generated header, not ours to judge). */
static int landing_room(const room_table *t, const char *root, const char *real_root,
                        const room_info *room, const char *header)
{
    char dir[PATH_LEN], path[PATH_LEN * 2], real[PATH_MAX];
    for (size_t d = 0; d <= room->dir_count; ++d) {
        snprintf(dir, sizeof dir, "%s/%s", root, d == 0 ? room->name : room->dirs[d - 1]);
        if (!file_exists(dir, header))
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, header);
        assert_non_null(realpath(path, real));
        return room_of_file(t, real_root, real);
    }
    return -1;
}

static bool room_may_see(const room_info *room, const char *other)
{
    for (size_t d = 0; d < room->dir_count; ++d)
        if (strcmp(room->dirs[d], other) == 0)
            return true;
    return false;
}

/* Checks one file's quoted includes (path relative to root); returns the
 * number of violations, each printed as one line. A header is named by its
 * file name alone: a ".." path is refused wherever it lands (it would reach
 * past the include paths that enforce the rooms), and it is judged by the
 * room it lands in, not by the room it is written from. */
static size_t check_file(const room_table *t, const char *root, const char *real_root,
                         const room_info *room, const char *path)
{
    char full[PATH_LEN * 2];
    snprintf(full, sizeof full, "%s/%s", root, path);
    FILE *f = fopen(full, "r");
    assert_non_null(f);
    size_t bad = 0;
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        char header[256];
        if (sscanf(line, " #include \"%255[^\"]\"", header) != 1)
            continue;
        int lands = landing_room(t, root, real_root, room, header);
        const char *lands_in = lands >= 0 ? t->rooms[lands].name : "no room";
        if (climbs(header)) {
            printf("layering: %s includes \"%s\" (in %s): a path with '..' reaches around the "
                   "rooms; name the header alone\n",
                   path, header, lands_in);
            ++bad;
        } else if (lands >= 0 && !room_may_see(room, lands_in)) {
            printf("layering: %s includes %s from %s, which %s may not use\n", path, header,
                   lands_in, room->name);
            ++bad;
        }
        if (ends_with(header, "_internal.h") && lands != -1 && strcmp(lands_in, room->name) != 0) {
            printf("layering: %s includes another room's internal header %s\n", path, header);
            ++bad;
        }
    }
    fclose(f);
    return bad;
}

/* Checks every source file of every room under root (the repository, or a
 * scratch tree that holds only some rooms' folders: missing_ok); the files
 * checked in *files. Returns the number of violations. */
static size_t check_tree(const room_table *t, const char *root, bool missing_ok, size_t *files)
{
    char real_root[PATH_MAX];
    assert_non_null(realpath(root, real_root));
    size_t bad = 0;
    *files = 0;
    for (size_t i = 0; i < t->count; ++i) {
        const room_info *room = &t->rooms[i];
        bool sees_itself = false;
        for (size_t d = 0; d < room->dir_count; ++d)
            sees_itself |= strcmp(room->dirs[d], room->name) == 0;
        assert_true(sees_itself);
        char folder[PATH_LEN];
        snprintf(folder, sizeof folder, "%s/%s", root, room->name);
        DIR *dir = opendir(folder);
        if (!dir && missing_ok)
            continue;
        assert_non_null(dir);
        for (struct dirent *e; (e = readdir(dir));) {
            if (!is_source(e->d_name))
                continue;
            char path[PATH_LEN];
            snprintf(path, sizeof path, "%s/%s", room->name, e->d_name);
            bad += check_file(t, root, real_root, room, path);
            ++*files;
        }
        closedir(dir);
    }
    return bad;
}

static void test_every_include_stays_within_the_rooms_used(void **state)
{
    (void)state;
    room_table t;
    load_rooms(&t);
    size_t files;
    size_t bad = check_tree(&t, ".", false, &files);
    assert_true(files > 150);
    assert_int_equal(bad, 0);
}

static void put_file(const char *root, const char *path, const char *text)
{
    char full[PATH_LEN], cmd[PATH_LEN * 2], out[256];
    snprintf(full, sizeof full, "%s/%s", root, path);
    snprintf(cmd, sizeof cmd, "mkdir -p \"$(dirname '%s')\"", full);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    ms_test_write_file(full, text, strlen(text));
}

/* The checker on a scratch tree of a few rooms: a header reached with "../"
 * is refused, into a room the includer may not use (it compiles: the path
 * goes around the include paths) and into one it may; named alone, the same
 * headers pass or fail by the room they are in. */
static void test_a_relative_reach_is_refused(void **state)
{
    (void)state;
    room_table t;
    load_rooms(&t);
    char root[512];
    ms_test_tmpdir(root, sizeof root);
    put_file(root, "server/serve/ms_http_parse.h", "/* a server header */\n");
    put_file(root, "client/core/ms_client_core.h", "/* a header client/view may use */\n");
    put_file(root, "client/view/fine.c", "#include \"ms_client_core.h\"\n#include <stdio.h>\n");
    size_t files;
    assert_int_equal(check_tree(&t, root, true, &files), 0);
    assert_int_equal(files, 3);

    put_file(root, "client/view/reach.c", "#include \"../../server/serve/ms_http_parse.h\"\n");
    assert_int_equal(check_tree(&t, root, true, &files), 1);
    put_file(root, "client/view/reach.c", "#include \"../core/ms_client_core.h\"\n");
    assert_int_equal(check_tree(&t, root, true, &files), 1);
    put_file(root, "client/view/reach.c", "  #include \"./../../server/serve/ms_http_parse.h\"\n");
    assert_int_equal(check_tree(&t, root, true, &files), 1);
    put_file(root, "client/view/reach.c", "#include \"ms_http_parse.h\"\n");
    assert_int_equal(check_tree(&t, root, true, &files), 0); /* not on its paths: not found */
    put_file(root, "client/view/ms_http_parse_copy.h", "#include \"../../server/serve/ms_http_parse.h\"\n");
    assert_int_equal(check_tree(&t, root, true, &files), 1);
    ms_test_rmdir(root);
}

/* Compiles a one-line file as if it lived in `room`, with the room's include
 * paths; returns the compiler's exit status. */
static int compile_in_room(const room_table *t, const char *room_name, const char *header)
{
    const room_info *room = NULL;
    for (size_t i = 0; i < t->count; ++i)
        if (strcmp(t->rooms[i].name, room_name) == 0)
            room = &t->rooms[i];
    assert_non_null(room);
    char cmd[4096];
    int n = snprintf(cmd, sizeof cmd, "printf '#include \"%s\"\\n' | cc -std=c11 -D_DEFAULT_SOURCE -fsyntax-only", header);
    for (size_t d = 0; d < room->dir_count; ++d)
        n += snprintf(cmd + n, sizeof cmd - (size_t)n, " -I%s", room->dirs[d]);
    snprintf(cmd + n, sizeof cmd - (size_t)n, " -x c -");
    static char out[8192];
    return ms_test_run(cmd, out, sizeof out);
}

static void test_the_build_refuses_a_reach_into_a_room_not_used(void **state)
{
    (void)state;
    room_table t;
    load_rooms(&t);
    /* Below: allowed. */
    assert_int_equal(compile_in_room(&t, "common/codec", "ms_mesh.h"), 0);
    assert_int_equal(compile_in_room(&t, "client/view", "ms_client_core.h"), 0);
    assert_int_equal(compile_in_room(&t, "server/bake", "ms_tri_unify.h"), 0);
    /* Upward or sideways: refused. */
    assert_int_not_equal(compile_in_room(&t, "common/codec", "ms_client_core.h"), 0);
    assert_int_not_equal(compile_in_room(&t, "common/util", "ms_mesh.h"), 0);
    assert_int_not_equal(compile_in_room(&t, "protocol", "ms_archive.h"), 0);
    assert_int_not_equal(compile_in_room(&t, "server/serve", "ms_bake.h"), 0);
    assert_int_not_equal(compile_in_room(&t, "server/apo", "ms_nsp_build.h"), 0);
    assert_int_not_equal(compile_in_room(&t, "client/core", "ms_render.h"), 0);
    assert_int_not_equal(compile_in_room(&t, "client/view", "ms_loadgen_plan.h"), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_include_stays_within_the_rooms_used),
        cmocka_unit_test(test_a_relative_reach_is_refused),
        cmocka_unit_test(test_the_build_refuses_a_reach_into_a_room_not_used),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
