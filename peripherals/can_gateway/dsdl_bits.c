/* DSDL v0 bit-level serialization (see dan/can_gw/dsdl_bits.h). */
#include <string.h>

#include "dan/can_gw/dsdl_bits.h"
#include "dan/can_gw/f16.h"

/* Copies bit_len bits, MSB first, from src at src_off to dst at dst_off:
 * up to a whole destination byte per step (a bit per step made the DSDL
 * codecs the fuzz targets' hottest loop). */
static void copy_bits(const uint8_t *src, size_t src_off, size_t bit_len, uint8_t *dst,
                      size_t dst_off)
{
    while (bit_len > 0u) {
        unsigned sb = (unsigned)(src_off % 8u), db = (unsigned)(dst_off % 8u);
        unsigned n = 8u - db; /* the bits left in this destination byte */
        unsigned w, shift, mask;
        if (n > bit_len) {
            n = (unsigned)bit_len;
        }
        /* a 16-bit window: the next source byte only when the n bits reach it */
        w = (unsigned)src[src_off / 8u] << 8;
        if (sb + n > 8u) {
            w |= src[src_off / 8u + 1u];
        }
        shift = 8u - db - n;
        mask = ((1u << n) - 1u) << shift;
        w = ((w >> (16u - sb - n)) << shift) & mask;
        dst[dst_off / 8u] = (uint8_t)((dst[dst_off / 8u] & ~mask) | w);
        src_off += n;
        dst_off += n;
        bit_len -= n;
    }
}

void dan_dc_encode_scalar(uint8_t *buf, size_t bit_offset, unsigned bit_len, uint64_t value)
{
    uint8_t le[8];
    unsigned i;
    if (buf == NULL || bit_len < 1u || bit_len > 64u) {
        return;
    }
    /* Little-endian bytes; the partial last byte's bits move to its top so
     * the MSB-first copy takes exactly its n % 8 low bits. */
    for (i = 0; i < 8u; i++) {
        le[i] = (uint8_t)(value >> (8u * i));
    }
    if (bit_len % 8u != 0u) {
        le[bit_len / 8u] = (uint8_t)(le[bit_len / 8u] << (8u - bit_len % 8u));
    }
    copy_bits(le, 0, bit_len, buf, bit_offset);
}

uint64_t dan_dc_decode_scalar(const uint8_t *buf, size_t bit_offset, unsigned bit_len,
                              bool is_signed)
{
    uint8_t le[8] = {0};
    uint64_t v = 0;
    unsigned i;
    if (buf == NULL || bit_len < 1u || bit_len > 64u) {
        return 0;
    }
    copy_bits(buf, bit_offset, bit_len, le, 0);
    if (bit_len % 8u != 0u) {
        le[bit_len / 8u] = (uint8_t)(le[bit_len / 8u] >> (8u - bit_len % 8u));
    }
    for (i = 0; i < 8u; i++) {
        v |= (uint64_t)le[i] << (8u * i);
    }
    if (is_signed && bit_len < 64u && ((v >> (bit_len - 1u)) & 1u) != 0u) {
        v |= ~(uint64_t)0 << bit_len;
    }
    return v;
}

void dan_dc_bw_init(dan_dc_bw_t *w, uint8_t *buf, size_t cap)
{
    w->buf = buf;
    w->cap = buf != NULL ? cap : 0u;
    w->bit = 0;
    w->error = false;
}

/* Room for bits more bits? Sets the error if not. */
static bool bw_room(dan_dc_bw_t *w, unsigned bits)
{
    if (w->error || bits < 1u || bits > 64u) {
        w->error = true;
        return false;
    }
    if (w->buf != NULL &&
        (w->cap > SIZE_MAX / 8u || w->cap * 8u < bits || w->bit > w->cap * 8u - bits)) {
        w->error = true;
        return false;
    }
    return true;
}

static void bw_raw(dan_dc_bw_t *w, unsigned bits, uint64_t v)
{
    if (!bw_room(w, bits)) {
        return;
    }
    if (w->buf != NULL) {
        if (w->bit % 8u == 0u) {
            w->buf[w->bit / 8u] = 0; /* new byte: padding bits read as 0 */
        }
        dan_dc_encode_scalar(w->buf, w->bit, bits, v);
        /* Zero the rest of the last byte touched, so padding is clean. */
        if ((w->bit + bits) % 8u != 0u) {
            size_t last = (w->bit + bits) / 8u;
            w->buf[last] = (uint8_t)(w->buf[last] & (uint8_t)(0xFF00u >> ((w->bit + bits) % 8u)));
        }
    }
    w->bit += bits;
}

void dan_dc_put_uint(dan_dc_bw_t *w, unsigned bits, uint64_t v)
{
    if (bits >= 1u && bits < 64u) {
        uint64_t max = ((uint64_t)1 << bits) - 1u;
        if (v > max) {
            v = max;
        }
    }
    bw_raw(w, bits, v);
}

void dan_dc_put_int(dan_dc_bw_t *w, unsigned bits, int64_t v)
{
    if (bits >= 2u && bits < 64u) {
        int64_t max = (int64_t)(((uint64_t)1 << (bits - 1u)) - 1u);
        int64_t min = -max - 1;
        if (v > max) {
            v = max;
        } else if (v < min) {
            v = min;
        }
    } else if (bits != 64u) {
        w->error = true;
        return;
    }
    bw_raw(w, bits, (uint64_t)v);
}

void dan_dc_put_bool(dan_dc_bw_t *w, bool v)
{
    bw_raw(w, 1u, v ? 1u : 0u);
}

void dan_dc_put_f16(dan_dc_bw_t *w, float v)
{
    if (v > 65504.0f && v <= 3.4028235e38f) {
        v = 65504.0f;
    } else if (v < -65504.0f && v >= -3.4028235e38f) {
        v = -65504.0f;
    }
    bw_raw(w, 16u, dan_f16_from_f32(v));
}

void dan_dc_put_f32(dan_dc_bw_t *w, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    bw_raw(w, 32u, u);
}

void dan_dc_put_bytes(dan_dc_bw_t *w, const uint8_t *p, size_t n)
{
    size_t i;
    if (p == NULL && n > 0u) {
        w->error = true;
        return;
    }
    for (i = 0; i < n && !w->error; i++) {
        bw_raw(w, 8u, p[i]);
    }
}

unsigned dan_dc_array_len_bits(size_t max)
{
    unsigned bits = 0;
    while (max != 0u) {
        bits++;
        max >>= 1;
    }
    return bits;
}

void dan_dc_put_array_len(dan_dc_bw_t *w, size_t len, size_t max)
{
    if (len > max || max == 0u) {
        w->error = true;
        return;
    }
    bw_raw(w, dan_dc_array_len_bits(max), len);
}

int dan_dc_bw_finish(const dan_dc_bw_t *w)
{
    size_t bytes;
    if (w->error) {
        return DAN_ERR_OVERFLOW;
    }
    bytes = (w->bit + 7u) / 8u;
    if (bytes > (size_t)0x7FFFFFFF) {
        return DAN_ERR_OVERFLOW;
    }
    return (int)bytes;
}

void dan_dc_br_init(dan_dc_br_t *r, const uint8_t *data, size_t len)
{
    r->data = data;
    r->len = data != NULL ? len : 0u;
    r->bit = 0;
    r->error = false;
}

size_t dan_dc_br_remaining_bits(const dan_dc_br_t *r)
{
    if (r->error || r->len > SIZE_MAX / 8u || r->bit > r->len * 8u) {
        return 0;
    }
    return r->len * 8u - r->bit;
}

static uint64_t br_raw(dan_dc_br_t *r, unsigned bits, bool is_signed)
{
    uint64_t v;
    if (r->error || bits < 1u || bits > 64u || dan_dc_br_remaining_bits(r) < bits) {
        r->error = true;
        return 0;
    }
    v = dan_dc_decode_scalar(r->data, r->bit, bits, is_signed);
    r->bit += bits;
    return v;
}

uint64_t dan_dc_get_uint(dan_dc_br_t *r, unsigned bits)
{
    return br_raw(r, bits, false);
}

int64_t dan_dc_get_int(dan_dc_br_t *r, unsigned bits)
{
    uint64_t u;
    if (bits < 2u) {
        r->error = true;
        return 0;
    }
    u = br_raw(r, bits, true);
    /* Two's complement reinterpretation without implementation-defined
     * conversion of out-of-range unsigned values. */
    if ((u >> 63) != 0u) {
        return -(int64_t)(~u) - 1;
    }
    return (int64_t)u;
}

bool dan_dc_get_bool(dan_dc_br_t *r)
{
    return br_raw(r, 1u, false) != 0u;
}

float dan_dc_get_f16(dan_dc_br_t *r)
{
    return dan_f16_to_f32((uint16_t)br_raw(r, 16u, false));
}

float dan_dc_get_f32(dan_dc_br_t *r)
{
    uint32_t u = (uint32_t)br_raw(r, 32u, false);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

void dan_dc_get_bytes(dan_dc_br_t *r, uint8_t *out, size_t n)
{
    size_t i;
    if (dan_dc_br_remaining_bits(r) / 8u < n) {
        r->error = true;
        return;
    }
    for (i = 0; i < n; i++) {
        uint8_t b = (uint8_t)br_raw(r, 8u, false);
        if (out != NULL) {
            out[i] = b;
        }
    }
}

size_t dan_dc_get_array_len(dan_dc_br_t *r, size_t max)
{
    uint64_t len;
    if (max == 0u) {
        r->error = true;
        return 0;
    }
    len = br_raw(r, dan_dc_array_len_bits(max), false);
    if (len > max) {
        r->error = true;
        return 0;
    }
    return (size_t)len;
}

int dan_dc_br_finish(const dan_dc_br_t *r)
{
    return r->error ? DAN_ERR_MALFORMED : DAN_OK;
}

size_t dan_dc_tao_count(const dan_dc_br_t *r, unsigned elem_bits)
{
    if (elem_bits == 0u) {
        return 0;
    }
    return dan_dc_br_remaining_bits(r) / elem_bits;
}

/* ---- table-driven codecs ---- */

/* A scalar member of size bytes, widened (sign-extended when is_signed). */
static uint64_t member_load(const uint8_t *p, unsigned size, bool is_signed)
{
    uint8_t u8;
    uint16_t u16;
    uint32_t u32;
    uint64_t u64;
    switch (size) {
    case 1u: memcpy(&u8, p, 1u); return is_signed ? (uint64_t)(int64_t)(int8_t)u8 : u8;
    case 2u: memcpy(&u16, p, 2u); return is_signed ? (uint64_t)(int64_t)(int16_t)u16 : u16;
    case 4u: memcpy(&u32, p, 4u); return is_signed ? (uint64_t)(int64_t)(int32_t)u32 : u32;
    default: memcpy(&u64, p, 8u); return u64;
    }
}

static void member_store(uint8_t *p, unsigned size, uint64_t v)
{
    uint8_t u8 = (uint8_t)v;
    uint16_t u16 = (uint16_t)v;
    uint32_t u32 = (uint32_t)v;
    switch (size) {
    case 1u: memcpy(p, &u8, 1u); break;
    case 2u: memcpy(p, &u16, 2u); break;
    case 4u: memcpy(p, &u32, 4u); break;
    default: memcpy(p, &v, 8u); break;
    }
}

bool dan_dc_put_fields(dan_dc_bw_t *w, const void *m, const dan_dc_field_t *f, size_t n)
{
    const uint8_t *base = (const uint8_t *)m;
    size_t i;
    for (i = 0; i < n; i++) {
        const uint8_t *p = base + f[i].offset;
        if (f[i].kind == DAN_DC_F_UINT) {
            dan_dc_put_uint(w, f[i].bits, member_load(p, f[i].aux, false));
        } else if (f[i].kind == DAN_DC_F_INT) {
            dan_dc_put_int(w, f[i].bits, (int64_t)member_load(p, f[i].aux, true));
        } else {
            uint8_t len = base[f[i].aux];
            if (len > f[i].bits) {
                return false;
            }
            dan_dc_put_bytes(w, p, len); /* TAO: no length prefix */
        }
    }
    return true;
}

bool dan_dc_get_fields(dan_dc_br_t *r, void *m, const dan_dc_field_t *f, size_t n)
{
    uint8_t *base = (uint8_t *)m;
    size_t i;
    for (i = 0; i < n; i++) {
        uint8_t *p = base + f[i].offset;
        if (f[i].kind == DAN_DC_F_UINT || f[i].kind == DAN_DC_F_INT) {
            bool is_signed = f[i].kind == DAN_DC_F_INT;
            uint64_t v =
                is_signed ? (uint64_t)dan_dc_get_int(r, f[i].bits) : dan_dc_get_uint(r, f[i].bits);
            member_store(p, f[i].aux, v);
        } else {
            size_t len = dan_dc_tao_count(r, 8u);
            if (len > f[i].bits) {
                return false;
            }
            dan_dc_get_bytes(r, p, len);
            base[f[i].aux] = (uint8_t)len;
            if (f[i].kind == DAN_DC_F_TAO_STRING) {
                p[len] = 0u;
            }
        }
    }
    return true;
}

int dan_dc_encode_table(const void *m, const dan_dc_field_t *f, size_t n, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    if (!dan_dc_put_fields(&w, m, f, n)) {
        return DAN_ERR_ARG;
    }
    return dan_dc_bw_finish(&w);
}

bool dan_dc_dec_begin(dan_dc_br_t *r, void *m, size_t size, const uint8_t *buf, size_t len)
{
    if (m == NULL || (buf == NULL && len > 0u)) {
        return false;
    }
    memset(m, 0, size);
    dan_dc_br_init(r, buf, len);
    return true;
}

int dan_dc_decode_table(void *m, size_t size, const dan_dc_field_t *f, size_t n, const uint8_t *buf,
                        size_t len)
{
    dan_dc_br_t r;
    if (!dan_dc_dec_begin(&r, m, size, buf, len)) {
        return DAN_ERR_ARG;
    }
    if (!dan_dc_get_fields(&r, m, f, n)) {
        return DAN_ERR_MALFORMED;
    }
    return dan_dc_br_finish(&r);
}

int dan_dc_encode_tao_array(const void *m, size_t count_offset, size_t max, dan_dc_put_elem_t put,
                            uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    size_t i, n;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    n = ((const uint8_t *)m)[count_offset];
    if (n > max) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    for (i = 0; i < n; i++) { /* TAO: no length prefix */
        put(&w, m, i);
    }
    return dan_dc_bw_finish(&w);
}

int dan_dc_decode_tao_array(void *m, size_t size, size_t count_offset, size_t max,
                            unsigned elem_bits, dan_dc_get_elem_t get, const uint8_t *buf,
                            size_t len)
{
    dan_dc_br_t r;
    size_t i, n;
    if (!dan_dc_dec_begin(&r, m, size, buf, len)) {
        return DAN_ERR_ARG;
    }
    n = dan_dc_tao_count(&r, elem_bits);
    /* No encoder leaves 8 or more bits after the last element (pydronecan
     * refuses such a payload: a 3-byte RawCommand, a 36-byte one). */
    if (n > max || dan_dc_br_remaining_bits(&r) - n * elem_bits >= 8u) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < n; i++) {
        get(&r, m, i);
    }
    ((uint8_t *)m)[count_offset] = (uint8_t)n;
    return dan_dc_br_finish(&r);
}
