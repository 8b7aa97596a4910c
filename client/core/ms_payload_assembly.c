/* PAYLOAD reassembly: see ms_payload_assembly.h. */
#include "ms_payload_assembly.h"

#include <stdlib.h>
#include <string.h>

typedef struct pending {
    uint32_t id, cell;
    uint8_t stream;
    bool started;
    uint32_t start, end, have;
    uint8_t *data;
    struct pending *next; /* hash chain */
} pending;

struct ms_payload_assembly {
    bool keep;
    size_t max_bytes, held, count;
    pending **buckets;
    size_t bucket_count; /* power of two */
    uint8_t *completed;  /* data of the last completed range */
};

static size_t bucket_of(const ms_payload_assembly *a, uint32_t id)
{
    return (size_t)((id * 2654435761u) & (uint32_t)(a->bucket_count - 1));
}

ms_status ms_payload_assembly_new(bool keep_bytes, size_t max_bytes, ms_payload_assembly **out,
                                  ms_error *err)
{
    *out = NULL;
    ms_payload_assembly *a = calloc(1, sizeof *a);
    if (a) {
        a->bucket_count = 64;
        a->buckets = calloc(a->bucket_count, sizeof *a->buckets);
    }
    if (!a || !a->buckets) {
        free(a);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for payload reassembly");
    }
    a->keep = keep_bytes;
    a->max_bytes = max_bytes;
    *out = a;
    return MS_OK;
}

static void drop(ms_payload_assembly *a, pending *p)
{
    a->held -= p->data ? p->end - p->start : 0;
    free(p->data);
    free(p);
    a->count--;
}

void ms_payload_assembly_free(ms_payload_assembly *a)
{
    if (!a)
        return;
    for (size_t b = 0; b < a->bucket_count; ++b)
        for (pending *p = a->buckets[b], *next; p; p = next) {
            next = p->next;
            drop(a, p);
        }
    free(a->buckets);
    free(a->completed);
    free(a);
}

static pending **find_link(ms_payload_assembly *a, uint32_t id)
{
    pending **link = &a->buckets[bucket_of(a, id)];
    while (*link && (*link)->id != id)
        link = &(*link)->next;
    return link;
}

static void grow_table(ms_payload_assembly *a)
{
    size_t count = a->bucket_count * 2;
    pending **buckets = calloc(count, sizeof *buckets);
    if (!buckets)
        return; /* longer chains, still correct */
    for (size_t b = 0; b < a->bucket_count; ++b)
        for (pending *p = a->buckets[b], *next; p; p = next) {
            next = p->next;
            size_t k = (size_t)((p->id * 2654435761u) & (uint32_t)(count - 1));
            p->next = buckets[k];
            buckets[k] = p;
        }
    free(a->buckets);
    a->buckets = buckets;
    a->bucket_count = count;
}

ms_status ms_payload_assembly_expect(ms_payload_assembly *a, uint32_t id, uint32_t cell,
                                     uint8_t stream, ms_error *err)
{
    if (*find_link(a, id))
        return ms_error_set(err, MS_ERR_ARG, "request %u is already pending", id);
    pending *p = calloc(1, sizeof *p);
    if (!p)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a pending request");
    p->id = id, p->cell = cell, p->stream = stream;
    if (a->count >= a->bucket_count)
        grow_table(a);
    pending **head = &a->buckets[bucket_of(a, id)];
    p->next = *head;
    *head = p;
    a->count++;
    return MS_OK;
}

void ms_payload_assembly_forget(ms_payload_assembly *a, uint32_t id)
{
    pending **link = find_link(a, id);
    pending *p = *link;
    if (!p)
        return;
    *link = p->next;
    drop(a, p);
}

ms_status ms_payload_assembly_add(ms_payload_assembly *a, uint32_t id,
                                  const ms_proto_payload *f, bool last, bool *done,
                                  ms_assembled_range *range, ms_error *err)
{
    *done = false;
    pending **link = find_link(a, id);
    pending *p = *link;
    if (!p)
        return ms_error_set(err, MS_ERR_FORMAT, "PAYLOAD for request %u, which is not pending", id);
    if (f->cell_id != p->cell || f->stream != p->stream)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "PAYLOAD for request %u names cell %u stream %u, not cell %u stream %u",
                            id, f->cell_id, f->stream, p->cell, p->stream);
    if (!p->started) {
        p->started = true;
        p->start = f->offset;
        p->end = f->end;
        if (a->keep && p->end > p->start) {
            if (a->held + (p->end - p->start) > a->max_bytes)
                return ms_error_set(err, MS_ERR_NOMEM,
                                    "request %u: %u bytes would exceed the reassembly limit", id,
                                    p->end - p->start);
            p->data = malloc(p->end - p->start);
            if (!p->data)
                return ms_error_set(err, MS_ERR_NOMEM, "out of memory for request %u", id);
            a->held += p->end - p->start;
        }
    }
    if (f->end != p->end || f->offset != p->start + p->have ||
        (uint64_t)f->offset + f->data_length > p->end)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "request %u: frame [%u, +%u) of a range ending at %u, expected offset %u",
                            id, f->offset, f->data_length, f->end, p->start + p->have);
    if (last && f->offset + f->data_length != p->end)
        return ms_error_set(err, MS_ERR_FORMAT, "request %u: LAST frame ends at %u, not at %u", id,
                            f->offset + f->data_length, p->end);
    if (p->data && f->data_length)
        memcpy(p->data + p->have, f->data, f->data_length);
    p->have += f->data_length;
    if (!last)
        return MS_OK;
    *link = p->next;
    free(a->completed);
    a->completed = p->data;
    a->held -= p->data ? p->end - p->start : 0;
    *range = (ms_assembled_range){p->id, p->cell, p->stream, p->start, p->end, p->data};
    free(p);
    a->count--;
    *done = true;
    return MS_OK;
}

size_t ms_payload_assembly_pending(const ms_payload_assembly *a) { return a->count; }
size_t ms_payload_assembly_held_bytes(const ms_payload_assembly *a) { return a->held; }
