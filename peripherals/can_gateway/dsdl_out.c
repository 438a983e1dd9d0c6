/* DSDL codecs of outputs and indications (see dan/can_gw/dsdl_out.h). */
#include "dan/can_gw/dsdl_out.h"

/* ---- ArrayCommand: Command[<=15] (TAO), each uint8 actuator_id, uint8
 * command_type, float16 command_value ---- */

static void put_actuator(dan_dc_bw_t *w, const void *m, size_t i)
{
    const dan_dc_actuator_cmd_t *c = &((const dan_dc_array_command_t *)m)->cmd[i];
    dan_dc_put_uint(w, 8, c->actuator_id);
    dan_dc_put_uint(w, 8, c->command_type);
    dan_dc_put_uint(w, 16, c->value_f16);
}

static void get_actuator(dan_dc_br_t *r, void *m, size_t i)
{
    dan_dc_actuator_cmd_t *c = &((dan_dc_array_command_t *)m)->cmd[i];
    c->actuator_id = (uint8_t)dan_dc_get_uint(r, 8);
    c->command_type = (uint8_t)dan_dc_get_uint(r, 8);
    c->value_f16 = (uint16_t)dan_dc_get_uint(r, 16);
}

DAN_DC_TAO_ARRAY_CODEC(dan_dc_array_command, dan_dc_array_command_t, DAN_DC_ARRAY_COMMAND_MAX, 32u,
                       put_actuator, get_actuator)

/* ---- LightsCommand: SingleLightCommand[<=20] (TAO), each uint8 light_id
 * and RGB565 as uint5 red, uint6 green, uint5 blue ---- */

static void put_light(dan_dc_bw_t *w, const void *m, size_t i)
{
    const dan_dc_light_t *l = &((const dan_dc_lights_command_t *)m)->light[i];
    dan_dc_put_uint(w, 8, l->light_id);
    dan_dc_put_uint(w, 5, (uint64_t)(l->rgb565 >> 11));
    dan_dc_put_uint(w, 6, (uint64_t)((l->rgb565 >> 5) & 0x3Fu));
    dan_dc_put_uint(w, 5, (uint64_t)(l->rgb565 & 0x1Fu));
}

static void get_light(dan_dc_br_t *r, void *m, size_t i)
{
    dan_dc_light_t *l = &((dan_dc_lights_command_t *)m)->light[i];
    unsigned red, green, blue;
    l->light_id = (uint8_t)dan_dc_get_uint(r, 8);
    red = (unsigned)dan_dc_get_uint(r, 5);
    green = (unsigned)dan_dc_get_uint(r, 6);
    blue = (unsigned)dan_dc_get_uint(r, 5);
    l->rgb565 = (uint16_t)(red << 11 | green << 5 | blue);
}

DAN_DC_TAO_ARRAY_CODEC(dan_dc_lights_command, dan_dc_lights_command_t, DAN_DC_LIGHTS_MAX, 24u,
                       put_light, get_light)

static const dan_dc_field_t BEEP_COMMAND[] = {
    DAN_DC_U(dan_dc_beep_command_t, frequency_f16, 16),
    DAN_DC_U(dan_dc_beep_command_t, duration_f16, 16),
};
DAN_DC_TABLE_CODEC(dan_dc_beep_command, dan_dc_beep_command_t, BEEP_COMMAND)

/* One uint8 value: a table over the value itself. */
static const dan_dc_field_t SAFETY_STATE[] = {{0u, 1u, 8u, DAN_DC_F_UINT}};

int dan_dc_safety_state_encode(uint8_t status, uint8_t *buf, size_t cap)
{
    return dan_dc_encode_table(&status, SAFETY_STATE, 1u, buf, cap);
}

int dan_dc_safety_state_decode(uint8_t *status, const uint8_t *buf, size_t len)
{
    return dan_dc_decode_table(status, sizeof *status, SAFETY_STATE, 1u, buf, len);
}

static const dan_dc_field_t TEMPERATURE[] = {
    DAN_DC_U(dan_dc_temperature_t, device_id, 16),
    DAN_DC_U(dan_dc_temperature_t, temperature_f16, 16),
    DAN_DC_U(dan_dc_temperature_t, error_flags, 8),
};
DAN_DC_TABLE_CODEC(dan_dc_temperature, dan_dc_temperature_t, TEMPERATURE)
