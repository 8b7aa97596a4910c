/* Per-connection request queue: see ms_request_queue.h. */
#include "ms_request_queue.h"

#include <assert.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

void ms_request_queue_init(ms_request_queue *q) { memset(q, 0, sizeof *q); }

void ms_request_queue_free(ms_request_queue *q)
{
    for (size_t i = 0; i < q->count; ++i)
        free(q->heap[i]);
    free(q->heap);
    free(q->buckets);
    memset(q, 0, sizeof *q);
}

static size_t bucket_of(const ms_request_queue *q, uint32_t id)
{
    return (size_t)((id * 2654435761u) & (uint32_t)(q->bucket_count - 1));
}

static bool sooner(const ms_cell_request *a, const ms_cell_request *b)
{
    return a->priority != b->priority ? a->priority < b->priority : a->seq < b->seq;
}

static void place(ms_request_queue *q, size_t pos, ms_cell_request *r)
{
    q->heap[pos] = r;
    r->heap_pos = pos;
}

static void sift_up(ms_request_queue *q, size_t pos)
{
    ms_cell_request *r = q->heap[pos];
    while (pos > 0) {
        size_t parent = (pos - 1) / 2;
        if (!sooner(r, q->heap[parent]))
            break;
        place(q, pos, q->heap[parent]);
        pos = parent;
    }
    place(q, pos, r);
}

static void sift_down(ms_request_queue *q, size_t pos)
{
    ms_cell_request *r = q->heap[pos];
    for (;;) {
        size_t child = 2 * pos + 1;
        if (child >= q->count)
            break;
        if (child + 1 < q->count && sooner(q->heap[child + 1], q->heap[child]))
            ++child;
        if (!sooner(q->heap[child], r))
            break;
        place(q, pos, q->heap[child]);
        pos = child;
    }
    place(q, pos, r);
}

static void rehash(ms_request_queue *q, ms_cell_request **buckets, size_t bucket_count)
{
    free(q->buckets);
    q->buckets = buckets;
    q->bucket_count = bucket_count;
    for (size_t i = 0; i < q->count; ++i) {
        ms_cell_request *r = q->heap[i];
        size_t b = bucket_of(q, r->id);
        r->hash_next = q->buckets[b];
        q->buckets[b] = r;
    }
}

ms_status ms_request_queue_reserve(ms_request_queue *q, size_t extra, ms_error *err)
{
    size_t need = q->count + extra;
    if (need <= q->capacity)
        return MS_OK;
    size_t capacity = q->capacity ? q->capacity : 16;
    while (capacity < need)
        capacity *= 2;
    ms_cell_request **heap = realloc(q->heap, capacity * sizeof *heap);
    if (!heap)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %zu requests", need);
    q->heap = heap;
    q->capacity = capacity;
    ms_cell_request **buckets = calloc(capacity, sizeof *buckets);
    if (!buckets)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %zu requests", need);
    rehash(q, buckets, capacity);
    return MS_OK;
}

void ms_request_queue_push(ms_request_queue *q, ms_cell_request *r)
{
    assert(q->count < q->capacity && !ms_request_queue_find(q, r->id));
    r->seq = q->next_seq++;
    size_t b = bucket_of(q, r->id);
    r->hash_next = q->buckets[b];
    q->buckets[b] = r;
    q->heap[q->count++] = r;
    sift_up(q, q->count - 1);
    q->queued_bytes += r->end - r->next;
}

ms_cell_request *ms_request_queue_find(const ms_request_queue *q, uint32_t id)
{
    if (!q->bucket_count)
        return NULL;
    for (ms_cell_request *r = q->buckets[bucket_of(q, id)]; r; r = r->hash_next)
        if (r->id == id)
            return r;
    return NULL;
}

ms_cell_request *ms_request_queue_top(const ms_request_queue *q)
{
    return q->count ? q->heap[0] : NULL;
}

void ms_request_queue_remove(ms_request_queue *q, ms_cell_request *r)
{
    ms_cell_request **link = &q->buckets[bucket_of(q, r->id)];
    while (*link != r)
        link = &(*link)->hash_next;
    *link = r->hash_next;
    q->queued_bytes -= r->end - r->next;
    size_t pos = r->heap_pos;
    ms_cell_request *last = q->heap[--q->count];
    if (pos < q->count) {
        place(q, pos, last);
        sift_down(q, pos);
        sift_up(q, last->heap_pos);
    }
}

void ms_request_queue_sent(ms_request_queue *q, ms_cell_request *r, uint32_t bytes)
{
    assert(bytes <= r->end - r->next);
    r->next += bytes;
    q->queued_bytes -= bytes;
}
