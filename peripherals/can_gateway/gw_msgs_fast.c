/* CAN-over-DAN gateway: compact ESC exchanges (see dan/can_gw/msgs_fast.h). */
#include <string.h>

#include "dan/can_gw/msgs_fast.h"

void dan_gw_msg_esc_pack(const int16_t *values, size_t n, uint8_t *out)
{
    uint32_t acc = 0;
    unsigned bits = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        acc |= ((uint32_t)(uint16_t)values[i] & 0x3FFFu) << bits;
        bits += 14u;
        while (bits >= 8u) {
            *out++ = (uint8_t)(acc & 0xFFu);
            acc >>= 8;
            bits -= 8u;
        }
    }
    if (bits > 0u) {
        *out = (uint8_t)(acc & 0xFFu);
    }
}

bool dan_gw_msg_esc_unpack(const uint8_t *p, size_t n, int16_t *values)
{
    uint32_t acc = 0;
    unsigned bits = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        uint32_t v;
        while (bits < 14u) {
            acc |= (uint32_t)*p++ << bits;
            bits += 8u;
        }
        v = acc & 0x3FFFu;
        acc >>= 14;
        bits -= 14u;
        values[i] = (int16_t)((v & 0x2000u) ? (int32_t)v - 0x4000 : (int32_t)v);
    }
    return acc == 0u; /* what is left of the last byte is padding */
}

static bool values_ok(const int16_t *values, size_t n)
{
    size_t i;
    if (values == NULL || n == 0u || n > DAN_GW_ESC_MAX) {
        return false;
    }
    for (i = 0; i < n; i++) {
        if (values[i] < DAN_DC_ESC_RAW_CMD_MIN || values[i] > DAN_DC_ESC_RAW_CMD_MAX) {
            return false;
        }
    }
    return true;
}

int dan_gw_msg_esc_fast_encode(const int16_t *values, size_t n, uint8_t *out, size_t cap)
{
    size_t size = DAN_GW_ESC_FAST_SIZE(n);
    if (!values_ok(values, n)) {
        return DAN_ERR_ARG;
    }
    if (out == NULL) {
        return (int)size;
    }
    if (cap < size) {
        return DAN_ERR_OVERFLOW;
    }
    dan_gw_msg_esc_pack(values, n, out);
    return (int)size;
}

int dan_gw_msg_esc_fast_decode(const uint8_t *p, size_t len, int16_t *values, size_t *n)
{
    size_t cnt = len * 8u / 14u; /* the only count whose size can be len */
    if (p == NULL || values == NULL || n == NULL) {
        return DAN_ERR_ARG;
    }
    if (cnt == 0u || cnt > DAN_GW_ESC_MAX || DAN_GW_ESC_FAST_SIZE(cnt) != len ||
        !dan_gw_msg_esc_unpack(p, cnt, values)) {
        return DAN_ERR_MALFORMED;
    }
    *n = cnt;
    return DAN_OK;
}

dan_gw_fast_rec_t dan_gw_fast_rec_make(const dan_gw_telem_t *t, bool fresh)
{
    dan_gw_fast_rec_t rec;
    uint32_t age = t->age_ms / DAN_GW_FAST_AGE_UNIT;
    rec.esc_index = t->esc_index;
    rec.fresh = fresh;
    rec.age_4ms = (uint8_t)(age < DAN_GW_FAST_AGE_MAX ? age : DAN_GW_FAST_AGE_MAX);
    rec.voltage_f16 = t->voltage_f16;
    rec.current_f16 = t->current_f16;
    rec.temperature_f16 = t->temperature_f16;
    rec.rpm = t->rpm;
    return rec;
}

void dan_gw_msg_fast_rec_put(dan_writer_t *w, const dan_gw_fast_rec_t *rec)
{
    uint32_t packed = ((uint32_t)rec->rpm & 0x3FFFFu) | (uint32_t)(rec->esc_index & 0x1Fu) << 18 |
                      (rec->fresh ? 1u << 23 : 0u);
    dan_put_u16(w, rec->voltage_f16);
    dan_put_u16(w, rec->current_f16);
    dan_put_u16(w, rec->temperature_f16);
    dan_put_u8(w, (uint8_t)(packed & 0xFFu));
    dan_put_u16(w, (uint16_t)(packed >> 8));
    dan_put_u8(w, rec->age_4ms);
}

/* The 10 record bytes at q (little endian fields). */
static void fast_rec_parse(const uint8_t *q, dan_gw_fast_rec_t *rec)
{
    uint32_t packed = (uint32_t)q[6] | (uint32_t)q[7] << 8 | (uint32_t)q[8] << 16;
    rec->voltage_f16 = (uint16_t)(q[0] | q[1] << 8);
    rec->current_f16 = (uint16_t)(q[2] | q[3] << 8);
    rec->temperature_f16 = (uint16_t)(q[4] | q[5] << 8);
    rec->age_4ms = q[9];
    rec->rpm = (int32_t)((packed & 0x3FFFFu) ^ 0x20000u) - 0x20000; /* int18 */
    rec->esc_index = (uint8_t)((packed >> 18) & 0x1Fu);
    rec->fresh = (packed >> 23) != 0u;
}

int dan_gw_msg_fast_rec_get(dan_reader_t *r, dan_gw_fast_rec_t *rec)
{
    uint8_t q[DAN_GW_FAST_REC_SIZE];
    dan_get_raw(r, q, sizeof q);
    if (dan_reader_finish(r) != DAN_OK) {
        memset(q, 0, sizeof q); /* as the fields read past the end: zeros */
    }
    fast_rec_parse(q, rec);
    return dan_reader_finish(r);
}

int dan_gw_msg_esc_fast_rsp_encode(uint8_t gw_flags, const dan_gw_fast_rec_t *rec, uint8_t *out,
                                   size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, gw_flags);
    if (rec != NULL) {
        dan_gw_msg_fast_rec_put(&w, rec);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_esc_fast_rsp_decode(uint8_t *gw_flags, dan_gw_fast_rec_t *rec, bool *has_rec,
                                   const uint8_t *p, size_t len)
{
    if (len != 1u && len != DAN_GW_FAST_RSP_MAX) {
        return DAN_ERR_MALFORMED;
    }
    *gw_flags = p[0];
    *has_rec = len == DAN_GW_FAST_RSP_MAX;
    if (*has_rec) {
        fast_rec_parse(p + 1, rec); /* the length is exact: no reader */
    }
    return DAN_OK;
}
