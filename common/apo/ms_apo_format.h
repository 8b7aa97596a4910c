/* APO texel words: the bit layout of one octree node and the normal code.
 *
 * The normative description is docs/APO.md; this header is its C mirror. An APO
 * chunk is an array of 32-bit unsigned words in breadth-first order:
 *
 *   leaf           1 word   [31..24] 0            [23..0] normal code
 *   internal node  2 words  word 0: [31..8] offset to first child  [7..0] existence mask
 *                           word 1: [31..24] kind mask             [23..0] mean normal code
 *
 * Bit i of the existence mask says that octant i is stored; bit i of the kind
 * mask says that child i is an internal node (2 words) rather than a leaf (1).
 * Octant i = 4*[x upper] + 2*[y upper] + [z upper]. The offset is the index of
 * the first stored child minus the index of word 0 of the node (always >= 2).
 *
 * Normal code (24 bits): octahedral projection of the unit vector, each of the two
 * coordinates in [-1,1] mapped to an integer 0..4094 as round(c*2047)+2047. 4095
 * is not a valid component. The encoder picks, among the four codes around the
 * projected point, the one whose decoded direction is nearest to the input, so
 * the angular error stays below MS_APO_NORMAL_MAX_ERROR_RAD (measured in the tests).
 *
 * A texel is a correction of the client's smooth normal (docs/APO.md, "APO as a
 * correction"): where no node is stored, and where a node's mean word holds
 * MS_APO_NORMAL_SMOOTH, the client draws its own interpolated smooth vertex
 * normal. A leaf always holds a normal (a leaf that would not is not stored).
 *
 * Everything here is a pure function: thread-safe, no allocation.
 */
#ifndef MS_APO_FORMAT_H
#define MS_APO_FORMAT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define MS_APO_MAX_DEPTH 30u                    /* deepest level a chunk may hold */
#define MS_APO_MAX_LEVELS (MS_APO_MAX_DEPTH + 1u) /* levels 0..MS_APO_MAX_DEPTH */
#define MS_APO_MAX_OFFSET 0xFFFFFFu             /* 24-bit relative offset */
#define MS_APO_MAX_TEXELS (1u << 28)            /* 1 GiB of texels: a sanity bound */
#define MS_APO_NORMAL_BITS 24u
#define MS_APO_NORMAL_MASK 0xFFFFFFu
#define MS_APO_NORMAL_STEPS 2047                /* code = round(c * 2047) + 2047 */
#define MS_APO_NORMAL_MAX_CODE 4094u            /* per 12-bit component */
#define MS_APO_NORMAL_MAX_ERROR_RAD 0.002       /* the promised bound (measured 8.2e-4) */
#define MS_APO_NORMAL_SMOOTH 0xFFFFFFu          /* mean word only: "no correction here" */

/* Word 0 of an internal node. */
static inline uint32_t ms_apo_header_word(uint32_t offset, uint32_t exist_mask)
{
    return (offset << 8) | (exist_mask & 0xFFu);
}
static inline uint32_t ms_apo_header_offset(uint32_t word) { return word >> 8; }
static inline uint32_t ms_apo_header_exist(uint32_t word) { return word & 0xFFu; }

/* Word 1 of an internal node. */
static inline uint32_t ms_apo_mean_word(uint32_t kind_mask, uint32_t normal_code)
{
    return (kind_mask << 24) | (normal_code & MS_APO_NORMAL_MASK);
}
static inline uint32_t ms_apo_mean_kind(uint32_t word) { return word >> 24; }

/* The only word of a leaf, and the normal part of any normal-carrying word. */
static inline uint32_t ms_apo_leaf_word(uint32_t normal_code) { return normal_code & MS_APO_NORMAL_MASK; }
static inline uint32_t ms_apo_word_normal(uint32_t word) { return word & MS_APO_NORMAL_MASK; }

/* Words taken by a child of the given kind (true = internal). */
static inline uint32_t ms_apo_node_words(bool internal) { return internal ? 2u : 1u; }

/* Position of child `octant` inside its sibling block, in words: the stored
 * siblings below it, internal ones counted twice. This is the bitCount rule the
 * shader uses. */
/* Set bits of an 8-bit mask (plain arithmetic: no popcnt instruction assumed). */
static inline uint32_t ms_apo_popcount8(uint32_t x)
{
    x &= 0xFFu;
    x = x - ((x >> 1) & 0x55u);
    x = (x & 0x33u) + ((x >> 2) & 0x33u);
    return (x + (x >> 4)) & 0x0Fu;
}

static inline uint32_t ms_apo_sibling_words_below(uint32_t exist, uint32_t kind, uint32_t octant)
{
    uint32_t below = (1u << octant) - 1u;
    return ms_apo_popcount8(exist & below) + ms_apo_popcount8(exist & kind & below);
}

/* The byte form of texel words: 4 little-endian bytes each, whatever the host. */
void ms_apo_words_to_bytes(const uint32_t *words, size_t count, uint8_t *bytes);
void ms_apo_words_from_bytes(const uint8_t *bytes, size_t count, uint32_t *words);

/* Encodes a direction (need not be unit length; the zero vector and non-finite
 * input encode +z) into a 24-bit normal code. */
uint32_t ms_apo_normal_encode(const float n[3]);

/* Decodes a 24-bit code into a unit vector (components beyond 4094 are clamped;
 * callers validate codes before they get here). */
void ms_apo_normal_decode(uint32_t code, float out[3]);

/* True when both 12-bit components are <= MS_APO_NORMAL_MAX_CODE (so
 * MS_APO_NORMAL_SMOOTH is not a valid normal code). */
bool ms_apo_normal_code_valid(uint32_t code);

#endif
