/* The out-of-core nSP build's parts, for its own files (ms_nsp_build.c: the
 * spools, the tree and the run; ms_nsp_distribute.c: the quantisation and the
 * distribution). Not for the rest of the room: ms_nsp_build.h is the door.
 * Every function runs on the build's calling thread (they use the pool
 * themselves where they run on two); errors are ms_status with err set. */
#ifndef MS_NSP_BUILD_INTERNAL_H
#define MS_NSP_BUILD_INTERNAL_H

#include <stdio.h>

#include "ms_nsp_build.h"

/* Appends the record rec (three vertex keys; three equal keys: a lone point)
 * to every leaf below node `top` holding one of its vertices, splitting full
 * leaves and spilling blocks as the memory budget needs; *reached (if not NULL)
 * receives the number of those leaves. MS_ERR_IO or MS_ERR_NOMEM. */
ms_status ms_nsp_build_insert(ms_nsp_build *b, uint32_t top, const uint64_t rec[3],
                              unsigned *reached, ms_error *err);

/* Writes every input vertex's key, in input order, to the key file key_fd
 * from the (flushed) vertex spool; the file is the same for any thread count. */
ms_status ms_nsp_build_compute_keys(ms_nsp_build *b, FILE *vspool, int key_fd, ms_error *err);

/* Inserts every kept triangle of the spool (triangles of them), then the
 * vertices no kept triangle used, into the tree, keys through the key cache
 * over key_fd; the tree is the same for any thread count. */
ms_status ms_nsp_build_distribute(ms_nsp_build *b, FILE *tspool, uint64_t triangles, int key_fd,
                                  ms_error *err);

#endif
