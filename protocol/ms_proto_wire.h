/* Private to protocol/: little-endian field access and the table of message
 * types (section 4 of PROTOCOL.md). Not installed, not used outside protocol/. */
#ifndef MS_PROTO_WIRE_H
#define MS_PROTO_WIRE_H

#include <stdint.h>

#include "ms_proto.h"

static inline uint16_t ms_wire_get16(const uint8_t *p)
{
    return (uint16_t)(p[0] | (uint16_t)p[1] << 8);
}

static inline uint32_t ms_wire_get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint64_t ms_wire_get64(const uint8_t *p)
{
    return (uint64_t)ms_wire_get32(p) | (uint64_t)ms_wire_get32(p + 4) << 32;
}

static inline void ms_wire_put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

static inline void ms_wire_put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static inline void ms_wire_put64(uint8_t *p, uint64_t v)
{
    ms_wire_put32(p, (uint32_t)v);
    ms_wire_put32(p + 4, (uint32_t)(v >> 32));
}

/* Who may send a type. */
enum { MS_WIRE_FROM_CLIENT = 1, MS_WIRE_FROM_SERVER = 2, MS_WIRE_FROM_BOTH = 3 };
/* What the header's request_id must be. */
enum { MS_WIRE_ID_ZERO = 0, MS_WIRE_ID_NONZERO = 1, MS_WIRE_ID_ANY = 2 };
/* max_body value meaning "bounded by max_frame only". */
#define MS_WIRE_BODY_UNBOUNDED UINT32_MAX

typedef struct ms_wire_type_info {
    uint8_t type;
    uint8_t sender;       /* MS_WIRE_FROM_* */
    uint8_t id_rule;      /* MS_WIRE_ID_* */
    uint8_t last_allowed; /* 1 if MS_PROTO_FLAG_LAST may be set */
    uint32_t min_body;
    uint32_t max_body;    /* or MS_WIRE_BODY_UNBOUNDED */
    const char *name;
} ms_wire_type_info;

/* The row of a defined type, or NULL. */
const ms_wire_type_info *ms_wire_type_lookup(uint8_t type);

/* Header rules of section 2 that depend only on the header (flags, LAST,
 * request id, body length bounds), for a defined type. Returns MS_OK or
 * MS_ERR_FORMAT (MALFORMED_FRAME) with err set. max_frame bounds unbounded
 * types. */
ms_status ms_wire_check_header(const ms_wire_type_info *info, uint8_t flags, uint32_t request_id,
                               uint32_t body_length, uint32_t max_frame, ms_error *err);

#endif
