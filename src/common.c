/* Error names, uvarint, and the payload writer and reader. */
#include <string.h>

#include "dan/common.h"

const char *dan_strerror(int err)
{
    switch (err) {
    case DAN_OK: return "ok";
    case DAN_ERR_ARG: return "invalid argument";
    case DAN_ERR_OVERFLOW: return "buffer too small";
    case DAN_ERR_MALFORMED: return "malformed payload";
    case DAN_ERR_TIMEOUT: return "timeout";
    case DAN_ERR_BUSY: return "busy";
    case DAN_ERR_REMOTE: return "peer answered with an error frame";
    case DAN_ERR_COLLISION: return "collision";
    case DAN_ERR_UNSUPPORTED: return "unsupported";
    case DAN_ERR_NOTFOUND: return "not found";
    case DAN_ERR_IO: return "port I/O error";
    case DAN_ERR_NACK: return "peer answered ACK-FAIL";
    default: return "unknown error";
    }
}

/* ---- uvarint ---- */

size_t dan_uvarint_size(uint32_t v)
{
    size_t n = 1;
    while (v >= 0x80u) { /* >= : 128 and 16384 need the extra byte */
        v >>= 7;
        n++;
    }
    return n;
}

int dan_uvarint_encode(uint32_t v, uint8_t *out, size_t cap)
{
    size_t n = dan_uvarint_size(v);
    if (out == NULL) {
        return (int)n;
    }
    if (cap < n) {
        return DAN_ERR_OVERFLOW;
    }
    return (int)dan_uvarint_put(v, out);
}

int dan_uvarint_decode(const uint8_t *in, size_t len, uint32_t *v)
{
    uint32_t acc = 0;
    size_t i;
    for (i = 0; i < DAN_UVARINT_MAX_BYTES; i++) {
        uint8_t b;
        if (i >= len) {
            return 0; /* truncated: needs more bytes */
        }
        b = in[i];
        if (i == DAN_UVARINT_MAX_BYTES - 1u && (b & 0xF0u) != 0u) {
            /* 5th byte carries bits 28..31 only; anything more overflows
             * or continues into a 6th byte (overlong). */
            return DAN_ERR_MALFORMED;
        }
        acc |= (uint32_t)(b & 0x7Fu) << (7u * i);
        if ((b & 0x80u) == 0u) {
            if (v != NULL) {
                *v = acc;
            }
            return (int)(i + 1u);
        }
    }
    return DAN_ERR_MALFORMED; /* not reached */
}

/* ---- writer ---- */

void dan_writer_init(dan_writer_t *w, uint8_t *buf, size_t cap)
{
    w->buf = buf;
    w->cap = (buf == NULL) ? 0u : cap;
    w->len = 0;
    w->error = false;
}

static bool writer_room(dan_writer_t *w, size_t n)
{
    if (w->error) {
        return false;
    }
    if (w->buf == NULL) { /* size-only pass: count */
        w->len += n;
        return false;
    }
    if (n > w->cap - w->len) {
        w->error = true;
        return false;
    }
    return true;
}

void dan_put_raw(dan_writer_t *w, const void *data, size_t len)
{
    if (len == 0u || !writer_room(w, len)) {
        return;
    }
    memcpy(w->buf + w->len, data, len);
    w->len += len;
}

void dan_put_u8(dan_writer_t *w, uint8_t v)
{
    dan_put_raw(w, &v, 1);
}

void dan_put_u16(dan_writer_t *w, uint16_t v)
{
    uint8_t b[2];
    b[0] = (uint8_t)(v & 0xFFu);
    b[1] = (uint8_t)(v >> 8);
    dan_put_raw(w, b, 2);
}

void dan_put_u32(dan_writer_t *w, uint32_t v)
{
    uint8_t b[4];
    b[0] = (uint8_t)(v & 0xFFu);
    b[1] = (uint8_t)((v >> 8) & 0xFFu);
    b[2] = (uint8_t)((v >> 16) & 0xFFu);
    b[3] = (uint8_t)(v >> 24);
    dan_put_raw(w, b, 4);
}

void dan_put_uvarint(dan_writer_t *w, uint32_t v)
{
    uint8_t b[DAN_UVARINT_MAX_BYTES];
    int n = dan_uvarint_encode(v, b, sizeof b);
    dan_put_raw(w, b, (size_t)n);
}

void dan_put_array(dan_writer_t *w, const void *data, size_t len)
{
    if (len > 0xFFFFFFFFu) {
        w->error = true;
        return;
    }
    dan_put_uvarint(w, (uint32_t)len);
    dan_put_raw(w, data, len);
}

void dan_put_string(dan_writer_t *w, const char *s)
{
    dan_put_array(w, s, (s == NULL) ? 0u : strlen(s));
}

uint8_t *dan_writer_room(const dan_writer_t *w, size_t *cap)
{
    if (w->error || w->buf == NULL) {
        *cap = 0;
        return NULL; /* an encoder given NULL counts (size-only pass) */
    }
    *cap = w->cap - w->len;
    return w->buf + w->len;
}

void dan_writer_advance(dan_writer_t *w, int n)
{
    if (n < 0) {
        w->error = true;
    } else if (!w->error) {
        w->len += (size_t)n;
    }
}

int dan_writer_finish(const dan_writer_t *w)
{
    if (w->error || w->len > 0x7FFFFFFFu) {
        return DAN_ERR_OVERFLOW;
    }
    return (int)w->len;
}

/* ---- reader ---- */

void dan_reader_init(dan_reader_t *r, const uint8_t *data, size_t len)
{
    r->data = data;
    r->len = (data == NULL) ? 0u : len;
    r->pos = 0;
    r->error = false;
}

size_t dan_reader_remaining(const dan_reader_t *r)
{
    return r->error ? 0u : r->len - r->pos;
}

/* Returns a pointer to the next n bytes and advances, or NULL (and sets the
 * error) if fewer remain. The one place a read is bounds-checked. */
static const uint8_t *reader_take(dan_reader_t *r, size_t n)
{
    const uint8_t *p;
    if (r->error || n > r->len - r->pos) {
        r->error = true;
        return NULL;
    }
    p = r->data + r->pos;
    r->pos += n;
    return p;
}

uint8_t dan_get_u8(dan_reader_t *r)
{
    const uint8_t *p = reader_take(r, 1);
    return (p == NULL) ? 0u : p[0];
}

uint16_t dan_get_u16(dan_reader_t *r)
{
    const uint8_t *p = reader_take(r, 2);
    if (p == NULL) {
        return 0;
    }
    return (uint16_t)((unsigned)p[0] | ((unsigned)p[1] << 8));
}

uint32_t dan_get_u32(dan_reader_t *r)
{
    const uint8_t *p = reader_take(r, 4);
    if (p == NULL) {
        return 0;
    }
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

uint32_t dan_get_uvarint(dan_reader_t *r)
{
    uint32_t v = 0;
    int n;
    if (r->error) {
        return 0;
    }
    n = dan_uvarint_decode(r->data + r->pos, r->len - r->pos, &v);
    if (n <= 0) { /* truncated or malformed: both are errors inside a payload */
        r->error = true;
        return 0;
    }
    r->pos += (size_t)n;
    return v;
}

void dan_get_raw(dan_reader_t *r, void *out, size_t len)
{
    const uint8_t *p = reader_take(r, len);
    if (p != NULL && out != NULL && len > 0u) {
        memcpy(out, p, len);
    }
}

void dan_get_array_view(dan_reader_t *r, const uint8_t **p, size_t *len)
{
    uint32_t n = dan_get_uvarint(r);
    const uint8_t *q = reader_take(r, n);
    *p = q;
    *len = (q == NULL) ? 0u : (size_t)n;
}

size_t dan_get_array(dan_reader_t *r, uint8_t *out, size_t cap)
{
    const uint8_t *p;
    size_t n;
    dan_get_array_view(r, &p, &n);
    if (p == NULL) {
        return 0;
    }
    if (n > cap) {
        r->error = true;
        return 0;
    }
    if (n > 0u) {
        memcpy(out, p, n);
    }
    return n;
}

bool dan_get_string(dan_reader_t *r, char *out, size_t cap)
{
    const uint8_t *p;
    size_t n, keep;
    if (cap == 0u) {
        r->error = true;
        return false;
    }
    out[0] = '\0';
    dan_get_array_view(r, &p, &n);
    if (p == NULL) {
        return false;
    }
    keep = (n < cap) ? n : cap - 1u;
    if (keep > 0u) {
        memcpy(out, p, keep);
    }
    out[keep] = '\0';
    return keep < n;
}

int dan_reader_finish(const dan_reader_t *r)
{
    return r->error ? DAN_ERR_MALFORMED : DAN_OK;
}

/* ---- field tables ---- */

static uint32_t field_load(const uint8_t *p, uint8_t size)
{
    uint8_t u8;
    uint16_t u16;
    uint32_t u32;
    if (size == 1u) {
        memcpy(&u8, p, 1u);
        return u8;
    }
    if (size == 2u) {
        memcpy(&u16, p, 2u);
        return u16;
    }
    memcpy(&u32, p, 4u);
    return u32;
}

static void field_store(uint8_t *p, uint8_t size, uint32_t v)
{
    uint8_t u8 = (uint8_t)v;
    uint16_t u16 = (uint16_t)v;
    if (size == 1u) {
        memcpy(p, &u8, 1u);
    } else if (size == 2u) {
        memcpy(p, &u16, 2u);
    } else {
        memcpy(p, &v, 4u);
    }
}

int dan_put_fields(dan_writer_t *w, const void *m, const dan_field_t *f, size_t n)
{
    const uint8_t *base = (const uint8_t *)m;
    size_t i;
    for (i = 0; i < n; i++) { /* check first: all or nothing */
        if (f[i].kind == DAN_F_VIEW) {
            const uint8_t *data;
            size_t len;
            memcpy(&data, base + f[i].offset, sizeof data);
            memcpy(&len, base + f[i].aux, sizeof len);
            if (len > f[i].size || (len > 0u && data == NULL)) {
                return DAN_ERR_ARG;
            }
        }
    }
    for (i = 0; i < n; i++) {
        const uint8_t *p = base + f[i].offset;
        switch (f[i].kind) {
        case DAN_F_U8: dan_put_u8(w, (uint8_t)field_load(p, f[i].size)); break;
        case DAN_F_U16: dan_put_u16(w, (uint16_t)field_load(p, f[i].size)); break;
        case DAN_F_U32: dan_put_u32(w, field_load(p, f[i].size)); break;
        case DAN_F_UV: dan_put_uvarint(w, field_load(p, f[i].size)); break;
        default: {
            const uint8_t *data;
            size_t len;
            memcpy(&data, p, sizeof data);
            memcpy(&len, base + f[i].aux, sizeof len);
            dan_put_array(w, data, len);
            break;
        }
        }
    }
    return DAN_OK;
}

int dan_get_fields(dan_reader_t *r, void *m, const dan_field_t *f, size_t n)
{
    uint8_t *base = (uint8_t *)m;
    size_t i;
    for (i = 0; i < n; i++) {
        uint8_t *p = base + f[i].offset;
        switch (f[i].kind) {
        case DAN_F_U8: field_store(p, f[i].size, dan_get_u8(r)); break;
        case DAN_F_U16: field_store(p, f[i].size, dan_get_u16(r)); break;
        case DAN_F_U32: field_store(p, f[i].size, dan_get_u32(r)); break;
        case DAN_F_UV: field_store(p, f[i].size, dan_get_uvarint(r)); break;
        default: {
            const uint8_t *data;
            size_t len;
            dan_get_array_view(r, &data, &len);
            if (len > f[i].size) {
                r->error = true;
                data = NULL;
                len = 0;
            }
            memcpy(p, &data, sizeof data);
            memcpy(base + f[i].aux, &len, sizeof len);
            break;
        }
        }
    }
    return dan_reader_finish(r);
}

int dan_encode_fields(const void *m, const dan_field_t *f, size_t n, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    int rc;
    dan_writer_init(&w, out, cap);
    rc = dan_put_fields(&w, m, f, n);
    return rc < 0 ? rc : dan_writer_finish(&w);
}

int dan_decode_fields(void *m, const dan_field_t *f, size_t n, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, p, len);
    return dan_get_fields(&r, m, f, n);
}
