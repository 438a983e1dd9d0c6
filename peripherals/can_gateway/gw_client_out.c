/* CAN-over-DAN gateway client: outputs besides ESCs (safety state, servos,
 * lights, buzzer). See dan/can_gw/client.h. */
#include "dan/can_gw/f16.h"
#include "gw_client_internal.h"

/* Starts code with the payload an encoder wrote into buf (or its error).
 * Each response is the gateway flags, SERVO_FAILSAFE's the entries kept. */
static int start(dan_gw_t *gw, uint32_t code, uint8_t *buf, int len, size_t cap, uint64_t now_us)
{
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start(gw, code, dan_gwc_done_flags, buf, len, cap, now_us);
}

int dan_gw_safety(dan_gw_t *gw, bool safety_off, uint64_t now_us)
{
    uint8_t v[DAN_GWC_BUF(1u)];
    v[0] = safety_off ? DAN_GW_SAFETY_OFF : DAN_GW_SAFETY_ON;
    return start(gw, DAN_GW_CODE_SAFETY, v, 1, sizeof v, now_us);
}

dan_gw_servo_t dan_gw_servo_make(uint8_t actuator_id, uint8_t command_type, float value)
{
    dan_gw_servo_t s;
    s.actuator_id = actuator_id;
    s.command_type = command_type;
    /* command_value is a saturated float16: beyond +-65504 (infinity
     * included, as pydronecan casts) the largest finite value, never an
     * infinity on the bus */
    if (value > 65504.0f) {
        value = 65504.0f;
    } else if (value < -65504.0f) {
        value = -65504.0f;
    }
    s.value_f16 = dan_f16_from_f32(value);
    return s;
}

int dan_gw_servo(dan_gw_t *gw, const dan_gw_servo_t *s, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    return start(gw, DAN_GW_CODE_SERVO, buf, dan_gw_msg_servo_encode(s, n, buf, DAN_GWC_CAP(buf)),
                 sizeof buf, now_us);
}

int dan_gw_servo_failsafe(dan_gw_t *gw, const dan_gw_servo_fs_t *s, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    return start(gw, DAN_GW_CODE_SERVO_FAILSAFE, buf,
                 dan_gw_msg_servo_fs_encode(s, n, buf, DAN_GWC_CAP(buf)), sizeof buf, now_us);
}

int dan_gw_lights(dan_gw_t *gw, const dan_gw_light_t *l, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    return start(gw, DAN_GW_CODE_LIGHTS, buf, dan_gw_msg_lights_encode(l, n, buf, DAN_GWC_CAP(buf)),
                 sizeof buf, now_us);
}

int dan_gw_beep(dan_gw_t *gw, uint32_t frequency_hz, uint32_t duration_ms, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_BEEP_REQ_MAX)];
    dan_gw_beep_t b;
    b.frequency_hz = frequency_hz;
    b.duration_ms = duration_ms;
    return start(gw, DAN_GW_CODE_BEEP, buf, dan_gw_msg_beep_encode(&b, buf, DAN_GWC_CAP(buf)),
                 sizeof buf, now_us);
}
