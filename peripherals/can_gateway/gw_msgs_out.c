/* CAN-over-DAN gateway output messages (see dan/can_gw/msgs_out.h). */
#include <string.h>

#include "dan/can_gw/msgs_out.h"

static void servo_put(dan_writer_t *w, const dan_gw_servo_t *s)
{
    dan_put_u8(w, s->actuator_id);
    dan_put_u8(w, s->command_type);
    dan_put_u16(w, s->value_f16);
}

static bool servo_get(dan_reader_t *r, dan_gw_servo_t *s)
{
    s->actuator_id = dan_get_u8(r);
    s->command_type = dan_get_u8(r);
    s->value_f16 = dan_get_u16(r);
    return s->command_type <= DAN_GW_SERVO_TYPE_MAX;
}

/* The lists' count (SERVO, SERVO_FAILSAFE, LIGHTS): u8 n in min..max (one
 * unsigned compare), n items follow. list_put() checks n (and that there
 * are items for it) and writes it; false: DAN_ERR_ARG. */
static bool list_put(dan_writer_t *w, const void *items, size_t n, size_t min, size_t max,
                     uint8_t *out, size_t cap)
{
    if ((items == NULL && n > 0u) || n - min > max - min) {
        return false;
    }
    dan_writer_init(w, out, cap);
    dan_put_u8(w, (uint8_t)n);
    return true;
}

static bool list_get(dan_reader_t *r, size_t *n, size_t min, size_t max, const uint8_t *p,
                     size_t len)
{
    size_t k;
    dan_reader_init(r, p, len);
    k = dan_get_u8(r);
    *n = k;
    return k - min <= max - min;
}

int dan_gw_msg_servo_encode(const dan_gw_servo_t *s, size_t n, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    size_t i;
    if (!list_put(&w, s, n, 1u, DAN_GW_SERVO_MAX, out, cap)) {
        return DAN_ERR_ARG;
    }
    for (i = 0; i < n; i++) {
        if (s[i].command_type > DAN_GW_SERVO_TYPE_MAX) {
            return DAN_ERR_ARG;
        }
        servo_put(&w, &s[i]);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_servo_decode(dan_gw_servo_t *s, size_t *n, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    size_t i;
    if (!list_get(&r, n, 1u, DAN_GW_SERVO_MAX, p, len)) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < *n; i++) {
        if (!servo_get(&r, &s[i])) {
            return DAN_ERR_MALFORMED;
        }
    }
    return dan_reader_finish(&r);
}

int dan_gw_msg_servo_fs_encode(const dan_gw_servo_fs_t *s, size_t n, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    size_t i;
    if (!list_put(&w, s, n, 0u, DAN_GW_SERVO_MAX, out, cap)) {
        return DAN_ERR_ARG;
    }
    for (i = 0; i < n; i++) {
        dan_gw_servo_t v = s[i].value;
        if (s[i].mode > DAN_GW_SERVO_VALUE || v.command_type > DAN_GW_SERVO_TYPE_MAX) {
            return DAN_ERR_ARG;
        }
        v.command_type = (uint8_t)(v.command_type | (s[i].mode << 7));
        servo_put(&w, &v);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_servo_fs_decode(dan_gw_servo_fs_t *s, size_t *n, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    size_t i;
    if (!list_get(&r, n, 0u, DAN_GW_SERVO_MAX, p, len)) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < *n; i++) {
        uint8_t kind;
        (void)servo_get(&r, &s[i].value); /* its type byte: kind */
        kind = s[i].value.command_type;
        s[i].mode = (uint8_t)(kind >> 7);
        s[i].value.command_type = kind & 0x0Fu;
        if ((kind & 0x70u) != 0u || s[i].value.command_type > DAN_GW_SERVO_TYPE_MAX) {
            return DAN_ERR_MALFORMED;
        }
    }
    return dan_reader_finish(&r);
}

int dan_gw_msg_lights_encode(const dan_gw_light_t *l, size_t n, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    size_t i;
    if (!list_put(&w, l, n, 1u, DAN_GW_LIGHTS_MAX, out, cap)) {
        return DAN_ERR_ARG;
    }
    for (i = 0; i < n; i++) {
        dan_put_u8(&w, l[i].light_id);
        dan_put_u16(&w, l[i].rgb565);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_lights_decode(dan_gw_light_t *l, size_t *n, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    size_t i;
    if (!list_get(&r, n, 1u, DAN_GW_LIGHTS_MAX, p, len)) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < *n; i++) {
        l[i].light_id = dan_get_u8(&r);
        l[i].rgb565 = dan_get_u16(&r);
    }
    return dan_reader_finish(&r);
}

/* BEEP's ranges, for both directions. */
static bool beep_ok(const dan_gw_beep_t *b)
{
    return b->frequency_hz >= 1u && b->frequency_hz <= DAN_GW_BEEP_HZ_MAX &&
           b->duration_ms <= DAN_GW_BEEP_MS_MAX;
}

static const dan_field_t BEEP[] = {
    DAN_FIELD(dan_gw_beep_t, frequency_hz, DAN_F_UV),
    DAN_FIELD(dan_gw_beep_t, duration_ms, DAN_F_UV),
};

int dan_gw_msg_beep_encode(const dan_gw_beep_t *b, uint8_t *out, size_t cap)
{
    if (b == NULL || !beep_ok(b)) {
        return DAN_ERR_ARG;
    }
    return dan_encode_fields(b, BEEP, DAN_NFIELDS(BEEP), out, cap);
}

int dan_gw_msg_beep_decode(dan_gw_beep_t *b, const uint8_t *p, size_t len)
{
    int rc;
    memset(b, 0, sizeof *b);
    rc = dan_decode_fields(b, BEEP, DAN_NFIELDS(BEEP), p, len);
    return rc == DAN_OK && !beep_ok(b) ? DAN_ERR_MALFORMED : rc;
}
