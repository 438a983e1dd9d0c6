/*
 * libdan common definitions: error codes, crc8_dvb_s2, uvarint, and the
 * bounds-checked payload writer and reader.
 *
 * All functions are reentrant; none allocates or keeps global state.
 */
#ifndef DAN_COMMON_H
#define DAN_COMMON_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Error codes. Functions return a negative code on failure. */
#define DAN_OK              0
#define DAN_ERR_ARG         (-1)  /* invalid argument (NULL, out of range) */
#define DAN_ERR_OVERFLOW    (-2)  /* output buffer too small */
#define DAN_ERR_MALFORMED   (-3)  /* input does not follow the format */
#define DAN_ERR_TIMEOUT     (-4)  /* no response in time */
#define DAN_ERR_BUSY        (-5)  /* an operation is already in progress */
#define DAN_ERR_REMOTE      (-6)  /* the peer answered with an error frame */
#define DAN_ERR_COLLISION   (-7)  /* echo mismatch: another talker on the wire */
#define DAN_ERR_UNSUPPORTED (-8)  /* no common baud, unknown type, ... */
#define DAN_ERR_NOTFOUND    (-9)  /* peripheral / entry not present */
#define DAN_ERR_IO          (-10) /* the port's write or set_baud failed */
#define DAN_ERR_NACK        (-11) /* the peer answered with ACK-FAIL */

/* Short English name of an error code ("timeout", ...); never NULL. */
const char *dan_strerror(int err);

/* ---- crc8_dvb_s2: poly 0xD5, init 0, no reflection, no xorout ---- */

/* CRC of len bytes continuing from crc (start with 0). */
uint8_t dan_crc8(uint8_t crc, const uint8_t *data, size_t len);
/* One byte step, for byte-at-a-time callers. */
uint8_t dan_crc8_byte(uint8_t crc, uint8_t byte);

/* ---- CRC-16/CCITT-FALSE: poly 0x1021, no reflection, no xorout ---- */

/* CRC of len bytes continuing from crc (start with 0xFFFF; check("123456789")
 * = 0x29B1). The gateway seal and DroneCAN transfers both use it. */
uint16_t dan_crc16_ccitt(uint16_t crc, const uint8_t *data, size_t len);

/* ---- uvarint: 7 bits a byte, low group first, 0x80 = more follows ---- */

/* Writes v at out (cap bytes). Returns bytes written (1..5), or
 * DAN_ERR_OVERFLOW. With out == NULL, returns the size only. */
int dan_uvarint_encode(uint32_t v, uint8_t *out, size_t cap);

/* Bytes v takes on the wire (1..5). */
size_t dan_uvarint_size(uint32_t v);
/* Writes v as a uvarint at out (room for DAN_UVARINT_MAX_BYTES assumed,
 * no checks); returns the bytes written. Inline: the frame encoder writes
 * its header with it, one call less on the master's deepest stack path. */
static inline size_t dan_uvarint_put(uint32_t v, uint8_t *out)
{
    size_t i = 0;
    while (v >= 0x80u) {
        out[i++] = (uint8_t)((v & 0x7Fu) | 0x80u);
        v >>= 7;
    }
    out[i++] = (uint8_t)v;
    return i;
}

/* Decodes one uvarint from in (len bytes available). Returns bytes used
 * (1..5); 0 if the input ends before the uvarint does (truncated: feed more);
 * DAN_ERR_MALFORMED for an encoding longer than 5 bytes or a value that does
 * not fit 32 bits. Non-minimal encodings (e.g. 0x80 0x00) are accepted. */
int dan_uvarint_decode(const uint8_t *in, size_t len, uint32_t *v);

/* ---- payload writer ---- */

/* Appends fields into a caller buffer. The first failure sets a sticky
 * error and later puts do nothing, so a caller checks once at the end with
 * dan_writer_finish(). With buf == NULL (cap ignored) the writer only
 * counts: a size-only pass. */
typedef struct {
    uint8_t *buf;
    size_t cap;
    size_t len; /* bytes written (or counted) so far */
    bool error;
} dan_writer_t;

void dan_writer_init(dan_writer_t *w, uint8_t *buf, size_t cap);
void dan_put_u8(dan_writer_t *w, uint8_t v);
void dan_put_u16(dan_writer_t *w, uint16_t v); /* little endian */
void dan_put_u32(dan_writer_t *w, uint32_t v); /* little endian */
void dan_put_uvarint(dan_writer_t *w, uint32_t v);
void dan_put_raw(dan_writer_t *w, const void *data, size_t len);   /* no length */
void dan_put_array(dan_writer_t *w, const void *data, size_t len); /* uvarint len + bytes */
void dan_put_string(dan_writer_t *w, const char *s);               /* NULL == "" */
/* For an encoder that writes in place (the dan_*_encode(..., out, cap)
 * functions): the free space (NULL in a size-only pass or after an error:
 * such encoders then return the size only), and then how much it wrote;
 * a negative count (the encoder's error) sets the sticky error.
 *     size_t cap; uint8_t *out = dan_writer_room(w, &cap);
 *     dan_writer_advance(w, dan_x_encode(&x, out, cap)); */
uint8_t *dan_writer_room(const dan_writer_t *w, size_t *cap);
void dan_writer_advance(dan_writer_t *w, int n);
/* Returns the length written, or DAN_ERR_OVERFLOW. */
int dan_writer_finish(const dan_writer_t *w);

/* ---- payload reader ---- */

/* Reads fields from a received payload. Reading past the end, a bad
 * uvarint or an array longer than what remains sets the sticky error and
 * returns zeros; nothing is ever read outside [data, data+len). */
typedef struct {
    const uint8_t *data;
    size_t len;
    size_t pos;
    bool error;
} dan_reader_t;

void dan_reader_init(dan_reader_t *r, const uint8_t *data, size_t len);
uint8_t dan_get_u8(dan_reader_t *r);
uint16_t dan_get_u16(dan_reader_t *r);
uint32_t dan_get_u32(dan_reader_t *r);
uint32_t dan_get_uvarint(dan_reader_t *r);
/* Exactly len raw bytes into out (out may be NULL to skip them). */
void dan_get_raw(dan_reader_t *r, void *out, size_t len);
/* An array[uint8] as a view into the payload (no copy). *len is its length;
 * on error *p is NULL and *len 0. */
void dan_get_array_view(dan_reader_t *r, const uint8_t **p, size_t *len);
/* An array[uint8] copied into out (cap bytes); longer arrays set the error. */
size_t dan_get_array(dan_reader_t *r, uint8_t *out, size_t cap);
/* A string copied into out as a NUL-terminated C string. Longer strings are
 * consumed whole and truncated to cap-1 bytes; returns true if truncated.
 * Embedded NUL bytes are kept in the payload but end the C string. */
bool dan_get_string(dan_reader_t *r, char *out, size_t cap);
/* Bytes not read yet. */
size_t dan_reader_remaining(const dan_reader_t *r);
/* DAN_OK if every read succeeded, else DAN_ERR_MALFORMED. Trailing bytes
 * are allowed (later protocol versions may append fields). */
int dan_reader_finish(const dan_reader_t *r);

/* ---- field tables ----
 *
 * A message that is a fixed list of fields is described once, as a table,
 * and the same table drives the writer and the reader: the layout is
 * written in one place and both directions cannot drift apart. */
typedef enum {
    DAN_F_U8,  /* u8 */
    DAN_F_U16, /* u16 little endian */
    DAN_F_U32, /* u32 little endian */
    DAN_F_UV,  /* uvarint (<= 32 bits) */
    DAN_F_VIEW /* array[uint8]: a const uint8_t * member and a size_t length */
} dan_fkind_t;

typedef struct {
    uint16_t offset; /* of the member in the struct */
    uint16_t aux;    /* DAN_F_VIEW: offset of the size_t length member */
    uint8_t size;    /* scalars: sizeof the member (1, 2 or 4; wider values
                        are truncated, narrower ones zero-extended);
                        DAN_F_VIEW: the array's maximum length (<= 255) */
    uint8_t kind;    /* dan_fkind_t */
} dan_field_t;

#define DAN_FIELD(type, member, k)                                                                \
    {                                                                                             \
        (uint16_t) offsetof(type, member), 0u, (uint8_t)sizeof(((type *)0)->member), (uint8_t)(k) \
    }
#define DAN_FIELD_VIEW(type, member, len_member, max)                                            \
    {                                                                                            \
        (uint16_t) offsetof(type, member), (uint16_t)offsetof(type, len_member), (uint8_t)(max), \
            (uint8_t)DAN_F_VIEW                                                                  \
    }
#define DAN_NFIELDS(table) (sizeof(table) / sizeof((table)[0]))

/* Writes m's fields in table order. DAN_ERR_ARG (nothing written) for a
 * view longer than its maximum or with data NULL and a length; else
 * DAN_OK (a short buffer shows in dan_writer_finish). */
int dan_put_fields(dan_writer_t *w, const void *m, const dan_field_t *f, size_t n);
/* Reads the fields into m; members not in the table are left alone. A view
 * points into the payload. DAN_ERR_MALFORMED for a short payload or a view
 * longer than its maximum, else DAN_OK. */
int dan_get_fields(dan_reader_t *r, void *m, const dan_field_t *f, size_t n);
/* Whole payloads: encode returns the length or a negative error; decode
 * DAN_OK or a negative error. */
int dan_encode_fields(const void *m, const dan_field_t *f, size_t n, uint8_t *out, size_t cap);
int dan_decode_fields(void *m, const dan_field_t *f, size_t n, const uint8_t *p, size_t len);

/* Declares the codec of a whole payload, the pattern of the message
 * headers:
 *   int NAME_encode(const TYPE *m, uint8_t *out, size_t cap);
 *   int NAME_decode(TYPE *m, const uint8_t *p, size_t len);
 * encode returns the length or a negative error, decode DAN_OK or one. */
#define DAN_CODEC(name, type)                                   \
    int name##_encode(const type *m, uint8_t *out, size_t cap); \
    int name##_decode(type *m, const uint8_t *p, size_t len)
/* Declares the writer and reader of an item or header in a longer payload:
 *   void NAME_put(dan_writer_t *w, const TYPE *m);
 *   int NAME_get(dan_reader_t *r, TYPE *m); */
#define DAN_ITEM(name, type)                         \
    void name##_put(dan_writer_t *w, const type *m); \
    int name##_get(dan_reader_t *r, type *m)

/* Defines DAN_CODEC(NAME, TYPE) from TABLE, for a message that is only its
 * table (the file needs <string.h>); decode clears *m first (members not
 * in the table read 0). */
#define DAN_FIELDS_CODEC(name, type, table)                               \
    int name##_encode(const type *m, uint8_t *out, size_t cap)            \
    {                                                                     \
        return dan_encode_fields(m, table, DAN_NFIELDS(table), out, cap); \
    }                                                                     \
    int name##_decode(type *m, const uint8_t *p, size_t len)              \
    {                                                                     \
        memset(m, 0, sizeof *m);                                          \
        return dan_decode_fields(m, table, DAN_NFIELDS(table), p, len);   \
    }
/* Defines DAN_ITEM(NAME, TYPE) from TABLE. */
#define DAN_FIELDS_ITEM(name, type, table)                      \
    void name##_put(dan_writer_t *w, const type *m)             \
    {                                                           \
        (void)dan_put_fields(w, m, table, DAN_NFIELDS(table));  \
    }                                                           \
    int name##_get(dan_reader_t *r, type *m)                    \
    {                                                           \
        return dan_get_fields(r, m, table, DAN_NFIELDS(table)); \
    }
/* Defines size_t NAME_size(const TYPE *m): the bytes NAME_put() writes for
 * m (a writer without a buffer counts them). */
#define DAN_ITEM_SIZE(name, type)      \
    size_t name##_size(const type *m)  \
    {                                  \
        dan_writer_t w_;               \
        dan_writer_init(&w_, NULL, 0); \
        name##_put(&w_, m);            \
        return w_.len;                 \
    }

#ifdef __cplusplus
}
#endif

#endif /* DAN_COMMON_H */
