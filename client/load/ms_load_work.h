/* meshload's JSON of a client core's decode work (ms_core_decode_work,
 * docs/CLIENT.md "Decoding on every core"). */
#ifndef MS_LOAD_WORK_H
#define MS_LOAD_WORK_H

#include <jansson.h>

#include "ms_client_core.h"

/* A new object: the CPU seconds by step and thread, the counts, and two
 * derived figures: parallel_fraction (the jobs' CPU time over all the
 * decoding's) and two_thread_bound (all of it over the serial steps plus the
 * waves' two-thread span: Amdahl's bound for two threads, jobs indivisible).
 * NULL when out of memory. */
json_t *ms_load_decode_work_json(const ms_core_decode_work *w);

#endif
