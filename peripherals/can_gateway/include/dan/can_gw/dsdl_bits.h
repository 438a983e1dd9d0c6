/*
 * DSDL v0 bit-level serialization: the bounds-checked bit writer and reader
 * the message codecs (dsdl.h) are built on, and the tail array rule.
 * Transport-independent; float16 conversions are in f16.h. Reentrant, no
 * allocation, no global state.
 */
#ifndef DAN_CAN_GW_DSDL_BITS_H
#define DAN_CAN_GW_DSDL_BITS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * DSDL v0 packs fields back to back with no alignment, first field first.
 * Within the stream, bits fill each byte from its most significant bit. A
 * scalar of n bits is laid out as its little-endian bytes: each whole byte
 * takes 8 bits, then the n % 8 low bits of the last byte follow (as
 * libcanard's canardEncodeScalar/canardDecodeScalar do; checked against
 * pydronecan's output). The payload is zero-padded to whole bytes. */

/* Writes bit_len (1..64) low bits of value at bit_offset of buf, which must
 * hold bit_offset + bit_len bits (caller checks). */
void dan_dc_encode_scalar(uint8_t *buf, size_t bit_offset, unsigned bit_len, uint64_t value);
/* Reads bit_len (1..64) bits at bit_offset; sign-extends when is_signed.
 * buf must hold bit_offset + bit_len bits (caller checks). */
uint64_t dan_dc_decode_scalar(const uint8_t *buf, size_t bit_offset, unsigned bit_len,
                              bool is_signed);

/* Bounds-checked bit writer. The first failure sets a sticky error and
 * later puts do nothing; check once with dan_dc_bw_finish. With buf NULL it
 * only counts (size-only pass). Integer puts saturate to the field's range
 * (DSDL's default "saturated" cast mode). */
typedef struct {
    uint8_t *buf;
    size_t cap; /* bytes */
    size_t bit; /* bits written (or counted) so far */
    bool error;
} dan_dc_bw_t;

void dan_dc_bw_init(dan_dc_bw_t *w, uint8_t *buf, size_t cap);
void dan_dc_put_uint(dan_dc_bw_t *w, unsigned bits, uint64_t v); /* 1..64 */
void dan_dc_put_int(dan_dc_bw_t *w, unsigned bits, int64_t v);   /* 2..64 */
void dan_dc_put_bool(dan_dc_bw_t *w, bool v);
void dan_dc_put_f16(dan_dc_bw_t *w, float v); /* saturates finite values */
void dan_dc_put_f32(dan_dc_bw_t *w, float v);
void dan_dc_put_bytes(dan_dc_bw_t *w, const uint8_t *p, size_t n); /* uint8[n] */
/* Length prefix of a dynamic array: dan_dc_array_len_bits(max) bits. */
void dan_dc_put_array_len(dan_dc_bw_t *w, size_t len, size_t max);
/* Bytes written (bits rounded up, padding bits are zero), or
 * DAN_ERR_OVERFLOW. */
int dan_dc_bw_finish(const dan_dc_bw_t *w);

/* Bounds-checked bit reader: reading past the end sets the sticky error and
 * returns 0; nothing outside [data, data+len) is read. */
typedef struct {
    const uint8_t *data;
    size_t len; /* bytes */
    size_t bit; /* bits read so far */
    bool error;
} dan_dc_br_t;

void dan_dc_br_init(dan_dc_br_t *r, const uint8_t *data, size_t len);
uint64_t dan_dc_get_uint(dan_dc_br_t *r, unsigned bits); /* 1..64 */
int64_t dan_dc_get_int(dan_dc_br_t *r, unsigned bits);   /* 2..64 */
bool dan_dc_get_bool(dan_dc_br_t *r);
float dan_dc_get_f16(dan_dc_br_t *r);
float dan_dc_get_f32(dan_dc_br_t *r);
void dan_dc_get_bytes(dan_dc_br_t *r, uint8_t *out, size_t n); /* out may be NULL */
/* A dynamic array length prefix; above max sets the error. */
size_t dan_dc_get_array_len(dan_dc_br_t *r, size_t max);
size_t dan_dc_br_remaining_bits(const dan_dc_br_t *r);
/* DAN_OK if every read succeeded, else DAN_ERR_MALFORMED. */
int dan_dc_br_finish(const dan_dc_br_t *r);

/* Bits of a dynamic array's length prefix: bit length of max (e.g. 20 -> 5,
 * 255 -> 8). */
unsigned dan_dc_array_len_bits(size_t max);

/* Tail array optimization: a dynamic array that is the last field of the
 * top-level type has no length prefix (its length follows from the payload
 * length), but only when its element is at least 8 bits long: shorter
 * elements would leave the element count ambiguous with the zero padding,
 * so e.g. a trailing bool[<=N] keeps its prefix (DSDL v0 rule, as
 * pydronecan's transport.py applies it). Nested types' arrays always keep
 * their prefix. */
static inline bool dan_dc_tao(unsigned elem_min_bits, bool last_top_level_field)
{
    return last_top_level_field && elem_min_bits >= 8u;
}

/* Elements of a tail-optimized array left in r (remaining bits / element
 * bits; the leftover padding is under 8 bits). */
size_t dan_dc_tao_count(const dan_dc_br_t *r, unsigned elem_bits);

/*
 * Table-driven codecs. Most DSDL types are a fixed list of scalars, maybe
 * ending in a tail byte array: one table per type drives both directions,
 * so each layout is written once (the table is the DSDL, field by field).
 */
typedef enum {
    DAN_DC_F_UINT,      /* unsigned scalar: put_uint / get_uint */
    DAN_DC_F_INT,       /* two's complement scalar: put_int / get_int */
    DAN_DC_F_TAO_BYTES, /* tail uint8[<=max] (last field of a top-level type) */
    DAN_DC_F_TAO_STRING /* the same, decoded NUL-terminated (member holds max + 1) */
} dan_dc_fkind_t;

typedef struct {
    uint16_t offset; /* of the member in the struct */
    uint16_t aux;    /* scalars: sizeof the member (1, 2, 4, 8); tail arrays:
                        offset of the uint8_t length member */
    uint8_t bits;    /* scalars: DSDL bit length (1..64); tail arrays: max */
    uint8_t kind;    /* dan_dc_fkind_t */
} dan_dc_field_t;

#define DAN_DC_SCALAR_(type, member, nbits, k)                                    \
    {                                                                             \
        (uint16_t) offsetof(type, member), (uint16_t)sizeof(((type *)0)->member), \
            (uint8_t)(nbits), (uint8_t)(k)                                        \
    }
#define DAN_DC_U(type, member, nbits) DAN_DC_SCALAR_(type, member, nbits, DAN_DC_F_UINT)
#define DAN_DC_I(type, member, nbits) DAN_DC_SCALAR_(type, member, nbits, DAN_DC_F_INT)
#define DAN_DC_TAIL_(type, member, len_member, max, k)                                           \
    {                                                                                            \
        (uint16_t) offsetof(type, member), (uint16_t)offsetof(type, len_member), (uint8_t)(max), \
            (uint8_t)(k)                                                                         \
    }
#define DAN_DC_TAO(type, member, len_member, max) \
    DAN_DC_TAIL_(type, member, len_member, max, DAN_DC_F_TAO_BYTES)
#define DAN_DC_TAO_STR(type, member, len_member, max) \
    DAN_DC_TAIL_(type, member, len_member, max, DAN_DC_F_TAO_STRING)
#define DAN_DC_NFIELDS(table) (sizeof(table) / sizeof((table)[0]))

/* Writes the fields of m in table order. False (nothing sensible written)
 * when a tail array is longer than its maximum. */
bool dan_dc_put_fields(dan_dc_bw_t *w, const void *m, const dan_dc_field_t *f, size_t n);
/* Reads the fields into m (not cleared first). False when a tail array
 * would be longer than its maximum. */
bool dan_dc_get_fields(dan_dc_br_t *r, void *m, const dan_dc_field_t *f, size_t n);
/* A whole top-level type. Encode: bytes written, DAN_ERR_ARG (m NULL, tail
 * too long) or DAN_ERR_OVERFLOW. Decode: m (size bytes) is cleared first;
 * DAN_OK, DAN_ERR_ARG or DAN_ERR_MALFORMED. */
int dan_dc_encode_table(const void *m, const dan_dc_field_t *f, size_t n, uint8_t *buf, size_t cap);
int dan_dc_decode_table(void *m, size_t size, const dan_dc_field_t *f, size_t n, const uint8_t *buf,
                        size_t len);

/* Starts a decode: false (DAN_ERR_ARG) for m NULL or buf NULL with len > 0;
 * else m (size bytes) is zeroed and r reads buf[0..len). */
bool dan_dc_dec_begin(dan_dc_br_t *r, void *m, size_t size, const uint8_t *buf, size_t len);

/* A top-level type that is one tail array (RawCommand, ArrayCommand,
 * LightsCommand): a uint8_t count member at count_offset, at most max
 * elements of elem_bits each; put/get write or read element i. Encode and
 * decode return as the codecs do (count above max: DAN_ERR_ARG, on the wire:
 * DAN_ERR_MALFORMED). */
typedef void (*dan_dc_put_elem_t)(dan_dc_bw_t *w, const void *m, size_t i);
typedef void (*dan_dc_get_elem_t)(dan_dc_br_t *r, void *m, size_t i);
int dan_dc_encode_tao_array(const void *m, size_t count_offset, size_t max, dan_dc_put_elem_t put,
                            uint8_t *buf, size_t cap);
int dan_dc_decode_tao_array(void *m, size_t size, size_t count_offset, size_t max,
                            unsigned elem_bits, dan_dc_get_elem_t get, const uint8_t *buf,
                            size_t len);

/* Defines NAME_encode and NAME_decode of TYPE, one tail array of up to MAX
 * elements of ELEM_BITS bits counted by member count, with PUT and GET. */
#define DAN_DC_TAO_ARRAY_CODEC(name, type, max, elem_bits, put, get)                           \
    int name##_encode(const type *m, uint8_t *buf, size_t cap)                                 \
    {                                                                                          \
        return dan_dc_encode_tao_array(m, offsetof(type, count), max, put, buf, cap);          \
    }                                                                                          \
    int name##_decode(type *m, const uint8_t *buf, size_t len)                                 \
    {                                                                                          \
        return dan_dc_decode_tao_array(m, sizeof(type), offsetof(type, count), max, elem_bits, \
                                       get, buf, len);                                         \
    }

/* Declares NAME_encode and NAME_decode of TYPE, the pattern of every DSDL
 * codec (dsdl.h):
 *   int NAME_encode(const TYPE *m, uint8_t *buf, size_t cap);
 *   int NAME_decode(TYPE *m, const uint8_t *buf, size_t len); */
#define DAN_DC_CODEC(name, type)                                \
    int name##_encode(const type *m, uint8_t *buf, size_t cap); \
    int name##_decode(type *m, const uint8_t *buf, size_t len)

/* Defines NAME_encode and NAME_decode of TYPE from TABLE. */
#define DAN_DC_TABLE_CODEC(name, type, table)                                                \
    int name##_encode(const type *m, uint8_t *buf, size_t cap)                               \
    {                                                                                        \
        return dan_dc_encode_table(m, table, DAN_DC_NFIELDS(table), buf, cap);               \
    }                                                                                        \
    int name##_decode(type *m, const uint8_t *buf, size_t len)                               \
    {                                                                                        \
        return dan_dc_decode_table(m, sizeof(type), table, DAN_DC_NFIELDS(table), buf, len); \
    }

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_DSDL_BITS_H */
