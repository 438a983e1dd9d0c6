/* DSDL codecs of outputs and indications (see dan/can_gw/dsdl_out.h). */
#include <string.h>

#include "dan/can_gw/dsdl_out.h"

/* Decoding starts with a zeroed struct and a reader, as everywhere. */
static bool dec_begin(dan_dc_br_t *r, void *m, size_t size, const uint8_t *buf, size_t len)
{
    if (m == NULL || (buf == NULL && len > 0u)) {
        return false;
    }
    memset(m, 0, size);
    dan_dc_br_init(r, buf, len);
    return true;
}

int dan_dc_array_command_encode(const dan_dc_array_command_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    size_t i;
    if (m == NULL || m->count > DAN_DC_ARRAY_COMMAND_MAX) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    for (i = 0; i < m->count; i++) { /* TAO: no length prefix */
        dan_dc_put_uint(&w, 8, m->cmd[i].actuator_id);
        dan_dc_put_uint(&w, 8, m->cmd[i].command_type);
        dan_dc_put_uint(&w, 16, m->cmd[i].value_f16);
    }
    return dan_dc_bw_finish(&w);
}

int dan_dc_array_command_decode(dan_dc_array_command_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    size_t i, n;
    if (!dec_begin(&r, m, sizeof *m, buf, len)) {
        return DAN_ERR_ARG;
    }
    n = dan_dc_tao_count(&r, 32);
    if (n > DAN_DC_ARRAY_COMMAND_MAX) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < n; i++) {
        m->cmd[i].actuator_id = (uint8_t)dan_dc_get_uint(&r, 8);
        m->cmd[i].command_type = (uint8_t)dan_dc_get_uint(&r, 8);
        m->cmd[i].value_f16 = (uint16_t)dan_dc_get_uint(&r, 16);
    }
    m->count = (uint8_t)n;
    return dan_dc_br_finish(&r);
}

int dan_dc_lights_command_encode(const dan_dc_lights_command_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    size_t i;
    if (m == NULL || m->count > DAN_DC_LIGHTS_MAX) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    for (i = 0; i < m->count; i++) { /* TAO */
        dan_dc_put_uint(&w, 8, m->light[i].light_id);
        dan_dc_put_uint(&w, 5, (uint64_t)(m->light[i].rgb565 >> 11));
        dan_dc_put_uint(&w, 6, (uint64_t)((m->light[i].rgb565 >> 5) & 0x3Fu));
        dan_dc_put_uint(&w, 5, (uint64_t)(m->light[i].rgb565 & 0x1Fu));
    }
    return dan_dc_bw_finish(&w);
}

int dan_dc_lights_command_decode(dan_dc_lights_command_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    size_t i, n;
    if (!dec_begin(&r, m, sizeof *m, buf, len)) {
        return DAN_ERR_ARG;
    }
    n = dan_dc_tao_count(&r, 24);
    if (n > DAN_DC_LIGHTS_MAX) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < n; i++) {
        unsigned red, green, blue;
        m->light[i].light_id = (uint8_t)dan_dc_get_uint(&r, 8);
        red = (unsigned)dan_dc_get_uint(&r, 5);
        green = (unsigned)dan_dc_get_uint(&r, 6);
        blue = (unsigned)dan_dc_get_uint(&r, 5);
        m->light[i].rgb565 = (uint16_t)(red << 11 | green << 5 | blue);
    }
    m->count = (uint8_t)n;
    return dan_dc_br_finish(&r);
}

static const dan_dc_field_t BEEP_COMMAND[] = {
    DAN_DC_U(dan_dc_beep_command_t, frequency_f16, 16),
    DAN_DC_U(dan_dc_beep_command_t, duration_f16, 16),
};
DAN_DC_TABLE_CODEC(dan_dc_beep_command, dan_dc_beep_command_t, BEEP_COMMAND)

int dan_dc_safety_state_encode(uint8_t status, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 8, status);
    return dan_dc_bw_finish(&w);
}

int dan_dc_safety_state_decode(uint8_t *status, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    if (!dec_begin(&r, status, sizeof *status, buf, len)) {
        return DAN_ERR_ARG;
    }
    *status = (uint8_t)dan_dc_get_uint(&r, 8);
    return dan_dc_br_finish(&r);
}

static const dan_dc_field_t TEMPERATURE[] = {
    DAN_DC_U(dan_dc_temperature_t, device_id, 16),
    DAN_DC_U(dan_dc_temperature_t, temperature_f16, 16),
    DAN_DC_U(dan_dc_temperature_t, error_flags, 8),
};
DAN_DC_TABLE_CODEC(dan_dc_temperature, dan_dc_temperature_t, TEMPERATURE)
