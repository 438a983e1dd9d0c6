/* CAN-over-DAN gateway output messages (see dan/can_gw/msgs_out.h). */
#include <string.h>

#include "dan/can_gw/msgs_out.h"

/* ---- the lists (SERVO, SERVO_FAILSAFE, LIGHTS): u8 n in min..max, n items ----
 *
 * One encoder and one decoder for the three; an item's put and get say
 * whether it is valid (false: DAN_ERR_ARG or DAN_ERR_MALFORMED). */
typedef bool (*item_put_fn)(dan_writer_t *w, const void *item);
typedef bool (*item_get_fn)(dan_reader_t *r, void *item);

static int list_encode(const void *items, size_t n, size_t size, size_t min, size_t max,
                       item_put_fn put, uint8_t *out, size_t cap)
{
    const uint8_t *item = (const uint8_t *)items;
    dan_writer_t w;
    size_t i;
    if ((items == NULL && n > 0u) || n - min > max - min) { /* one unsigned compare */
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, (uint8_t)n);
    for (i = 0; i < n; i++) {
        if (!put(&w, item + i * size)) {
            return DAN_ERR_ARG;
        }
    }
    return dan_writer_finish(&w);
}

static int list_decode(void *items, size_t *n, size_t size, size_t min, size_t max, item_get_fn get,
                       const uint8_t *p, size_t len)
{
    uint8_t *item = (uint8_t *)items;
    dan_reader_t r;
    size_t i;
    dan_reader_init(&r, p, len);
    *n = dan_get_u8(&r);
    if (*n - min > max - min) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < *n; i++) {
        if (!get(&r, item + i * size)) {
            return DAN_ERR_MALFORMED;
        }
    }
    return dan_reader_finish(&r);
}

/* Defines DAN_GW_LIST_CODEC(NAME, TYPE) from its items' put and get. */
#define LIST_CODEC(name, type, min, max, put, get)                       \
    int name##_encode(const type *m, size_t n, uint8_t *out, size_t cap) \
    {                                                                    \
        return list_encode(m, n, sizeof *m, min, max, put, out, cap);    \
    }                                                                    \
    int name##_decode(type *m, size_t *n, const uint8_t *p, size_t len)  \
    {                                                                    \
        return list_decode(m, n, sizeof *m, min, max, get, p, len);      \
    }

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

static bool servo_item_put(dan_writer_t *w, const void *item)
{
    const dan_gw_servo_t *s = (const dan_gw_servo_t *)item;
    if (s->command_type > DAN_GW_SERVO_TYPE_MAX) {
        return false;
    }
    servo_put(w, s);
    return true;
}

static bool servo_item_get(dan_reader_t *r, void *item)
{
    return servo_get(r, (dan_gw_servo_t *)item);
}

LIST_CODEC(dan_gw_msg_servo, dan_gw_servo_t, 1u, DAN_GW_SERVO_MAX, servo_item_put, servo_item_get)

/* A failsafe entry: a servo command whose type byte has the mode in bit 7. */
static bool fs_item_put(dan_writer_t *w, const void *item)
{
    const dan_gw_servo_fs_t *f = (const dan_gw_servo_fs_t *)item;
    dan_gw_servo_t v = f->value;
    if (f->mode > DAN_GW_SERVO_VALUE || v.command_type > DAN_GW_SERVO_TYPE_MAX) {
        return false;
    }
    v.command_type = (uint8_t)(v.command_type | (f->mode << 7));
    servo_put(w, &v);
    return true;
}

static bool fs_item_get(dan_reader_t *r, void *item)
{
    dan_gw_servo_fs_t *f = (dan_gw_servo_fs_t *)item;
    uint8_t kind;
    (void)servo_get(r, &f->value); /* its type byte: kind */
    kind = f->value.command_type;
    f->mode = (uint8_t)(kind >> 7);
    f->value.command_type = kind & 0x0Fu;
    return (kind & 0x70u) == 0u && f->value.command_type <= DAN_GW_SERVO_TYPE_MAX;
}

LIST_CODEC(dan_gw_msg_servo_fs, dan_gw_servo_fs_t, 0u, DAN_GW_SERVO_MAX, fs_item_put, fs_item_get)

static bool light_put(dan_writer_t *w, const void *item)
{
    const dan_gw_light_t *l = (const dan_gw_light_t *)item;
    dan_put_u8(w, l->light_id);
    dan_put_u16(w, l->rgb565);
    return true;
}

static bool light_get(dan_reader_t *r, void *item)
{
    dan_gw_light_t *l = (dan_gw_light_t *)item;
    l->light_id = dan_get_u8(r);
    l->rgb565 = dan_get_u16(r);
    return true;
}

LIST_CODEC(dan_gw_msg_lights, dan_gw_light_t, 1u, DAN_GW_LIGHTS_MAX, light_put, light_get)

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
