/* Gateway node: the DAN handlers of the outputs besides ESCs (SAFETY,
 * SERVO, SERVO_FAILSAFE, LIGHTS, BEEP); the table is in gw_node_dan.c. */
#include "gw_node_internal.h"

int dan_gwn_h_safety(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp,
                     const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    (void)code;
    if (len < 1u || (req[0] != DAN_GW_SAFETY_ON && req[0] != DAN_GW_SAFETY_OFF)) {
        *err = "SAFETY takes 0 or 255 only";
        return DAN_ERR_MALFORMED;
    }
    dan_gwn_safety_set(g, req[0], now_us);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

int dan_gwn_h_servo(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp,
                    const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_servo_t s[DAN_GW_SERVO_MAX];
    size_t n;
    (void)code;
    if (dan_gw_msg_servo_decode(s, &n, req, len) != DAN_OK) {
        *err = "bad servo command";
        return DAN_ERR_MALFORMED;
    }
    dan_gwn_servos_command(g, s, n, now_us);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

int dan_gwn_h_servo_failsafe(void *user, uint32_t code, const uint8_t *req, size_t len,
                             dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_servo_fs_t s[DAN_GW_SERVO_MAX];
    size_t n;
    (void)code;
    if (dan_gw_msg_servo_fs_decode(s, &n, req, len) != DAN_OK) {
        *err = "bad servo failsafe";
        return DAN_ERR_MALFORMED;
    }
    dan_put_u8(resp, (uint8_t)dan_gwn_servos_set_failsafe(g, s, n));
    return DAN_OK;
}

int dan_gwn_h_lights(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp,
                     const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_light_t l[DAN_GW_LIGHTS_MAX];
    size_t n;
    (void)code;
    if (dan_gw_msg_lights_decode(l, &n, req, len) != DAN_OK) {
        *err = "bad lights command";
        return DAN_ERR_MALFORMED;
    }
    dan_gwn_lights(g, l, n);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

int dan_gwn_h_beep(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp,
                   const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_beep_t b;
    (void)code;
    if (dan_gw_msg_beep_decode(&b, req, len) != DAN_OK) {
        *err = "BEEP: 1..65504 Hz, <65504 s";
        return DAN_ERR_MALFORMED;
    }
    dan_gwn_beep(g, &b);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}
