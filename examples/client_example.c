/* client_example: streams a model with libmeshstream-client, looks at all of
 * it, waits until the view is complete and prints what it received.
 *
 *   cc client_example.c $(pkg-config --cflags --libs meshstream-client) -o client_example
 *   ./client_example 127.0.0.1:7800/demo          # model demo from a meshserve
 *   ./client_example archives/demo.msa            # a local archive file
 *
 * An optional second argument is the screen tolerance in pixels (default 1);
 * a tiny one (0.0001) asks for every cell at full precision. Exit status 0
 * when the view completed, 1 on an error, 2 on a usage error. */
#define _GNU_SOURCE /* memrchr */
#include <meshstream-client.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int fail(const char *what, const msc_error *e)
{
    fprintf(stderr, "client_example: %s: %s\n", what, e->text);
    return 1;
}

/* "HOST:PORT/MODEL" (a numeric address; [v6]:PORT/MODEL too) into the
 * options; a path ending in .msa is an archive file. */
static msc_status set_source(msc_options *o, const char *source, msc_error *e)
{
    size_t length = strlen(source);
    if (length > 4 && strcmp(source + length - 4, ".msa") == 0)
        return msc_options_set_archive(o, source, e);
    char host[256];
    const char *slash = strrchr(source, '/');
    const char *colon = slash ? memrchr(source, ':', (size_t)(slash - source)) : NULL;
    if (!colon || colon == source || (size_t)(colon - source) >= sizeof host) {
        snprintf(e->text, sizeof e->text, "'%s' is neither HOST:PORT/MODEL nor FILE.msa", source);
        return MSC_ERR_ARG;
    }
    const char *h = source, *h_end = colon;
    if (*h == '[' && h_end[-1] == ']') /* [::1]:7800/demo */
        ++h, --h_end;
    snprintf(host, sizeof host, "%.*s", (int)(h_end - h), h);
    msc_status st = msc_options_set_server(o, host, (unsigned)strtoul(colon + 1, NULL, 10), e);
    return st != MSC_OK ? st : msc_options_set_model(o, slash + 1, e);
}

int main(int argc, char **argv)
{
    if (argc < 2 || argc > 3) {
        fprintf(stderr, "usage: client_example HOST:PORT/MODEL|ARCHIVE.msa [TOLERANCE_PX]\n");
        return 2;
    }
    msc_error e = {0};
    msc_options *o = msc_options_new();
    if (!o || set_source(o, argv[1], &e) != MSC_OK ||
        (argc > 2 && msc_options_set_tolerance(o, atof(argv[2]), &e) != MSC_OK)) {
        msc_options_free(o);
        return fail("options", &e);
    }
    msc_stream *s;
    msc_status st = msc_stream_new(o, &s, &e);
    msc_options_free(o); /* the stream copied what it needs */
    if (st != MSC_OK)
        return fail("stream", &e);

    msc_model_info info;
    if (msc_stream_wait_open(s, 20.0, &info, &e) != MSC_OK) {
        msc_stream_free(s);
        return fail("open", &e);
    }
    printf("libmeshstream-client %s: model of %llu triangles in %u cells, %u bits\n",
           msc_version(), (unsigned long long)info.triangle_count, info.cell_count, info.bits);

    /* Look at the whole box from two box sides away, along +z. */
    double centre[3], side = info.box_side;
    for (int k = 0; k < 3; ++k)
        centre[k] = info.box_origin[k] + side / 2;
    msc_camera cam = {
        .position = {centre[0], centre[1], centre[2] + 2 * side},
        .target = {centre[0], centre[1], centre[2]},
        .up = {0, 1, 0},
        .fovy_degrees = 60, .width = 800, .height = 600,
        .near_distance = side / 100, .far_distance = side * 10,
    };
    if (msc_stream_set_camera(s, &cam, &e) != MSC_OK) {
        msc_stream_free(s);
        return fail("camera", &e);
    }
    msc_progress p;
    if (msc_stream_wait_complete(s, 60.0, &p, &e) != MSC_OK) {
        msc_stream_free(s);
        return fail("view", &e);
    }

    /* The newest frame holds the complete view (frames are published before
     * the view is reported complete). */
    msc_frame *f = msc_stream_take_frame(s);
    size_t full = 0, cells = msc_frame_cell_count(f);
    for (size_t i = 0; i < cells; ++i) {
        msc_cell c;
        /* an empty cell is exact at any precision: the client leaves it at its first */
        if (msc_frame_cell(f, i, &c) == MSC_OK && (c.bits == c.bits_max || c.triangle_count == 0))
            ++full;
    }
    printf("view complete: %zu cells, %zu at full precision, %zu triangles, %zu vertices, "
           "%llu payload bytes\n",
           cells, full, msc_frame_triangle_count(f), msc_frame_vertex_count(f),
           (unsigned long long)p.bytes_received);
    msc_frame_free(f);
    msc_stream_free(s);
    return 0;
}
