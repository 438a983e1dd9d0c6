/*
 * DSDL codecs of the outputs and indications the gateway sends, and the
 * device temperature it hears: actuator ArrayCommand (servos), LightsCommand,
 * BeepCommand, ArduPilot's SafetyState, device.Temperature. Layouts and
 * signatures from the DSDL shipped with pydronecan (dronecan/dsdl_specs);
 * vectors in tests/vectors/dronecan.txt come from pydronecan itself.
 * Conventions as dsdl.h.
 */
#ifndef DAN_CAN_GW_DSDL_OUT_H
#define DAN_CAN_GW_DSDL_OUT_H

#include "dan/can_gw/dsdl.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- uavcan.equipment.actuator.ArrayCommand (message 1010) ----
 * Command[<=15] commands (TAO); Command: uint8 actuator_id, uint8
 * command_type, float16 command_value. */
#define DAN_DC_ARRAY_COMMAND_ID        1010u
#define DAN_DC_ARRAY_COMMAND_SIGNATURE 0xD8A7486238EC3AF3ull
#define DAN_DC_ARRAY_COMMAND_MAX       15u /* commands per message */
#define DAN_DC_ARRAY_COMMAND_MAX_SIZE  60u
#define DAN_DC_ACTUATOR_UNITLESS       0u /* [-1, 1] */
#define DAN_DC_ACTUATOR_POSITION       1u /* m or rad */
#define DAN_DC_ACTUATOR_FORCE          2u /* N or N m */
#define DAN_DC_ACTUATOR_SPEED          3u /* m/s or rad/s */
#define DAN_DC_ACTUATOR_PWM            4u /* microseconds */

typedef struct {
    uint8_t actuator_id;
    uint8_t command_type; /* DAN_DC_ACTUATOR_* */
    uint16_t value_f16;   /* the float16 bits */
} dan_dc_actuator_cmd_t;

typedef struct {
    uint8_t count;
    dan_dc_actuator_cmd_t cmd[DAN_DC_ARRAY_COMMAND_MAX];
} dan_dc_array_command_t;

DAN_DC_CODEC(dan_dc_array_command, dan_dc_array_command_t);

/* ---- uavcan.equipment.indication.LightsCommand (message 1081) ----
 * SingleLightCommand[<=20] commands (TAO); SingleLightCommand: uint8
 * light_id, RGB565 color (uint5 red, uint6 green, uint5 blue). */
#define DAN_DC_LIGHTS_COMMAND_ID        1081u
#define DAN_DC_LIGHTS_COMMAND_SIGNATURE 0x2031D93C8BDD1EC4ull
#define DAN_DC_LIGHTS_MAX               20u
#define DAN_DC_LIGHTS_COMMAND_MAX_SIZE  60u

typedef struct {
    uint8_t light_id;
    uint16_t rgb565; /* red << 11 | green << 5 | blue */
} dan_dc_light_t;

typedef struct {
    uint8_t count;
    dan_dc_light_t light[DAN_DC_LIGHTS_MAX];
} dan_dc_lights_command_t;

DAN_DC_CODEC(dan_dc_lights_command, dan_dc_lights_command_t);

/* ---- uavcan.equipment.indication.BeepCommand (message 1080) ----
 * float16 frequency (Hz), float16 duration (s). */
#define DAN_DC_BEEP_COMMAND_ID        1080u
#define DAN_DC_BEEP_COMMAND_SIGNATURE 0xBE9EA9FEC2B15D52ull
#define DAN_DC_BEEP_COMMAND_MAX_SIZE  4u

typedef struct {
    uint16_t frequency_f16; /* Hz */
    uint16_t duration_f16;  /* s */
} dan_dc_beep_command_t;

DAN_DC_CODEC(dan_dc_beep_command, dan_dc_beep_command_t);

/* ---- ardupilot.indication.SafetyState (message 20000) ---- uint8 status */
#define DAN_DC_SAFETY_STATE_ID        20000u
#define DAN_DC_SAFETY_STATE_SIGNATURE 0xE965701A95A1A6A1ull
#define DAN_DC_SAFETY_STATE_MAX_SIZE  1u
#define DAN_DC_SAFETY_ON              0u   /* outputs locked */
#define DAN_DC_SAFETY_OFF             255u /* outputs may move */

int dan_dc_safety_state_encode(uint8_t status, uint8_t *buf, size_t cap);
int dan_dc_safety_state_decode(uint8_t *status, const uint8_t *buf, size_t len);

/* ---- uavcan.equipment.device.Temperature (message 1110) ----
 * uint16 device_id, float16 temperature (K), uint8 error_flags. */
#define DAN_DC_TEMPERATURE_ID        1110u
#define DAN_DC_TEMPERATURE_SIGNATURE 0x70261C28A94144C6ull
#define DAN_DC_TEMPERATURE_MAX_SIZE  5u

typedef struct {
    uint16_t device_id;
    uint16_t temperature_f16; /* K */
    uint8_t error_flags;      /* 1 overheating, 2 overcooling */
} dan_dc_temperature_t;

DAN_DC_CODEC(dan_dc_temperature, dan_dc_temperature_t);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_DSDL_OUT_H */
