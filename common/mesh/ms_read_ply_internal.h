/* PLY internals shared by the header parser (ms_read_ply.c) and the binary and
 * ascii body readers (ms_read_ply_binary.c, ms_read_ply_ascii.c). Internal to
 * common/. */
#ifndef MS_READ_PLY_INTERNAL_H
#define MS_READ_PLY_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_mesh_reader_internal.h"

#define PLY_MAX_ELEMENTS 64
#define PLY_MAX_PROPERTIES 256
#define PLY_MAX_NAME 64
#define PLY_MAX_HEADER_LINES 100000

typedef enum ply_type {
    PLY_INT8, PLY_UINT8, PLY_INT16, PLY_UINT16, PLY_INT32, PLY_UINT32, PLY_FLOAT32, PLY_FLOAT64
} ply_type;

/* Bytes of one value of type t in binary PLY. */
static inline size_t ply_type_size(ply_type t)
{
    static const unsigned char sizes[] = {1, 1, 2, 2, 4, 4, 4, 8};
    return sizes[t];
}

typedef struct ply_property {
    char name[PLY_MAX_NAME];
    bool is_list;
    ply_type type;       /* the item type for lists */
    ply_type count_type; /* lists only */
} ply_property;

typedef enum ply_role { PLY_ROLE_OTHER, PLY_ROLE_VERTEX, PLY_ROLE_FACE, PLY_ROLE_STRIPS } ply_role;

typedef struct ply_element {
    char name[PLY_MAX_NAME];
    uint64_t count;
    ply_role role;
    ply_property props[PLY_MAX_PROPERTIES];
    size_t prop_count;
    int coord[3];       /* vertex: property index of x, y, z */
    int colour[4];      /* vertex: property index of red, green, blue, alpha, or -1 */
    bool has_colour;    /* vertex: red, green and blue are there */
    int index_list;     /* face/strips: property index of the index list */
    bool all_scalar;
    size_t stride;      /* record size when all_scalar */
} ply_element;

typedef struct ply_header {
    ply_element elements[PLY_MAX_ELEMENTS];
    size_t element_count;
    bool binary;
    bool swap; /* binary byte order differs from the host's */
} ply_header;

typedef struct ply_state {
    ms_reader *r;
    ply_header *h;
    uint64_t vertex_count; /* declared by the vertex element */
} ply_state;

/* The colour channel (0 red .. 3 alpha) that property k of vertex element e
 * holds, or -1. */
static inline int ply_colour_channel(const ply_element *e, size_t k)
{
    for (int c = 0; c < 4; ++c)
        if (e->colour[c] == (int)k)
            return c;
    return -1;
}

/* Stores a vertex's colour channel value v, read as a double from a property
 * of type t, into *out as 8 bits (docs/INPUT.md: uchar as is, ushort scaled,
 * float and double 0..1). False for a value outside its type's range, NaN, or a
 * fraction in an integer type. */
bool ms_ply_colour_value(double v, ply_type t, uint8_t *out);

/* The one-line complaint about a bad colour value, without position prefix. */
void ms_ply_colour_complaint(char *buf, size_t size, uint64_t vertex, const ply_element *e,
                             int channel, double v);

/* The body readers: one element each, in the order of the header, then a check
 * that nothing follows the last element. */
ms_status ms_ply_binary_element(ply_state *s, const ply_element *e);
ms_status ms_ply_binary_check_end(ply_state *s);
ms_status ms_ply_ascii_element(ply_state *s, const ply_element *e);
ms_status ms_ply_ascii_check_end(ply_state *s);

#endif
