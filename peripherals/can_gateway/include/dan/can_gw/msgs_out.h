/*
 * CAN-over-DAN gateway messages for outputs besides ESCs: the safety state,
 * servos (actuator ArrayCommand) and their failsafe, lights and the buzzer.
 * docs/PROTOCOL.md section 7 ("Outputs") is the byte-level definition;
 * tests/vectors/gateway.txt pins it. Conventions as dan/can_gw/msgs.h.
 */
#ifndef DAN_CAN_GW_MSGS_OUT_H
#define DAN_CAN_GW_MSGS_OUT_H

#include "dan/can_gw/msgs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_GW_CODE_SAFETY         0x54u /* SafetyState: on / off */
#define DAN_GW_CODE_SERVO          0x55u /* actuator commands */
#define DAN_GW_CODE_SERVO_FAILSAFE 0x56u /* what servos do in the failsafe */
#define DAN_GW_CODE_LIGHTS         0x57u /* LightsCommand */
#define DAN_GW_CODE_BEEP           0x58u /* BeepCommand */

/* Declares the codec of a list payload (u8 n, n items of TYPE):
 *   int NAME_encode(const TYPE *m, size_t n, uint8_t *out, size_t cap);
 *   int NAME_decode(TYPE *m, size_t *n, const uint8_t *p, size_t len); */
#define DAN_GW_LIST_CODEC(name, type)                                     \
    int name##_encode(const type *m, size_t n, uint8_t *out, size_t cap); \
    int name##_decode(type *m, size_t *n, const uint8_t *p, size_t len)

/* ---- SAFETY (0x54) ----
 * Request: u8 status (DAN_GW_SAFETY_ON 0, DAN_GW_SAFETY_OFF 255; anything
 * else is malformed). Response: u8 gw_flags. */
#define DAN_GW_SAFETY_ON  0u   /* SafetyState.STATUS_SAFETY_ON: outputs locked */
#define DAN_GW_SAFETY_OFF 255u /* STATUS_SAFETY_OFF */

/* ---- SERVO (0x55) ----
 * Request: u8 n (1..DAN_GW_SERVO_MAX), n x (u8 actuator_id, u8
 * command_type (0..4: unitless, position, force, speed, PWM), u16 value
 * (IEEE binary16 bits)). Response: u8 gw_flags. */
#define DAN_GW_SERVO_MAX      32u /* commands in one SERVO */
#define DAN_GW_SERVO_TYPE_MAX 4u  /* COMMAND_TYPE_PWM */

typedef struct {
    uint8_t actuator_id;
    uint8_t command_type;
    uint16_t value_f16;
} dan_gw_servo_t;

/* decode: m must hold DAN_GW_SERVO_MAX entries. */
DAN_GW_LIST_CODEC(dan_gw_msg_servo, dan_gw_servo_t);

/* ---- SERVO_FAILSAFE (0x56) ----
 * Request: u8 n (0..DAN_GW_SERVO_MAX), n x (u8 actuator_id, u8 kind, u16
 * value (binary16 bits)); kind bits 0-3 command_type (0..4), bit 7 mode
 * (0 DAN_GW_SERVO_HOLD, 1 DAN_GW_SERVO_VALUE), bits 4-6 zero.
 * Replaces the table; an actuator not in it holds. Response: u8 n kept
 * (entries beyond DAN_GW_NODE_SERVOS distinct actuators are not). */
#define DAN_GW_SERVO_HOLD  0u /* keep sending the last command */
#define DAN_GW_SERVO_VALUE 1u /* send this value instead */

typedef struct {
    uint8_t mode;
    dan_gw_servo_t value;
} dan_gw_servo_fs_t;

DAN_GW_LIST_CODEC(dan_gw_msg_servo_fs, dan_gw_servo_fs_t);

/* ---- LIGHTS (0x57) ----
 * Request: u8 n (1..20), n x (u8 light_id, u16 rgb565: red << 11 | green
 * << 5 | blue). Response: u8 gw_flags. */
#define DAN_GW_LIGHTS_MAX 20u

typedef struct {
    uint8_t light_id;
    uint16_t rgb565;
} dan_gw_light_t;

DAN_GW_LIST_CODEC(dan_gw_msg_lights, dan_gw_light_t);

/* ---- BEEP (0x58) ----
 * Request: uv frequency_hz (1..65504), uv duration_ms (0..65504000).
 * The gateway sends BeepCommand with float16 Hz and seconds. Response: u8
 * gw_flags. */
#define DAN_GW_BEEP_HZ_MAX  65504u
#define DAN_GW_BEEP_MS_MAX  65504000u
#define DAN_GW_BEEP_REQ_MAX 10u /* two 5-byte uvarints */

typedef struct {
    uint32_t frequency_hz;
    uint32_t duration_ms;
} dan_gw_beep_t;

DAN_CODEC(dan_gw_msg_beep, dan_gw_beep_t);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_MSGS_OUT_H */
