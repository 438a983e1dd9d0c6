/* Gateway node: the DAN handlers of the outputs besides ESCs (SERVO,
 * SERVO_FAILSAFE, LIGHTS, BEEP; SAFETY shares ARM's); the table is in
 * gw_node_dan.c. */
#include "gw_node_internal.h"

DAN_GWN_HANDLER(dan_gwn_h_servo)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_servo_t s[DAN_GW_SERVO_MAX];
    size_t n;
    (void)code;
    if (dan_gw_msg_servo_decode(s, &n, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad servo command");
    }
    dan_gwn_servos_command(g, s, n, now_us);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_servo_failsafe)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_servo_fs_t s[DAN_GW_SERVO_MAX];
    size_t n;
    (void)code;
    if (dan_gw_msg_servo_fs_decode(s, &n, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad servo failsafe");
    }
    dan_put_u8(resp, (uint8_t)dan_gwn_servos_set_failsafe(g, s, n));
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_lights)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_light_t l[DAN_GW_LIGHTS_MAX];
    size_t n;
    (void)code;
    if (dan_gw_msg_lights_decode(l, &n, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad lights command");
    }
    dan_gwn_lights(g, l, n);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_beep)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_beep_t b;
    (void)code;
    if (dan_gw_msg_beep_decode(&b, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "BEEP: 1..65504 Hz, <65504 s");
    }
    dan_gwn_beep(g, &b);
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}
