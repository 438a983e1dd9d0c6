/* Gateway node: the DAN handler of the outputs besides ESCs (SERVO,
 * SERVO_FAILSAFE, LIGHTS, BEEP; SAFETY shares ARM's); the table is in
 * gw_node_dan.c. */
#include "gw_node_internal.h"

/* One handler for the four codes: the request is decoded whole (refused
 * with its text when malformed), then acted on; the answer is u8 gw_flags
 * (SERVO_FAILSAFE: how many failsafes it keeps). */
DAN_GWN_HANDLER(dan_gwn_h_output)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    union {
        dan_gw_servo_t servo[DAN_GW_SERVO_MAX];
        dan_gw_servo_fs_t fs[DAN_GW_SERVO_MAX];
        dan_gw_light_t light[DAN_GW_LIGHTS_MAX];
        dan_gw_beep_t beep;
    } m;
    size_t n = 0;
    int rc;
    const char *why;
    if (code == DAN_GW_CODE_SERVO) {
        rc = dan_gw_msg_servo_decode(m.servo, &n, req, len);
        why = "bad servo command";
    } else if (code == DAN_GW_CODE_SERVO_FAILSAFE) {
        rc = dan_gw_msg_servo_fs_decode(m.fs, &n, req, len);
        why = "bad servo failsafe";
    } else if (code == DAN_GW_CODE_LIGHTS) {
        rc = dan_gw_msg_lights_decode(m.light, &n, req, len);
        why = "bad lights command";
    } else {
        rc = dan_gw_msg_beep_decode(&m.beep, req, len);
        why = "BEEP: 1..65504 Hz, up to 65504 s";
    }
    if (rc != DAN_OK) {
        return dan_gwn_refuse(err, why);
    }
    if (code == DAN_GW_CODE_SERVO_FAILSAFE) {
        dan_put_u8(resp, (uint8_t)dan_gwn_servos_set_failsafe(g, m.fs, n));
        return DAN_OK;
    }
    if (code == DAN_GW_CODE_SERVO) {
        dan_gwn_servos_command(g, m.servo, n, now_us);
    } else if (code == DAN_GW_CODE_LIGHTS) {
        dan_gwn_lights(g, m.light, n);
    } else {
        dan_gwn_beep(g, &m.beep);
    }
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}
