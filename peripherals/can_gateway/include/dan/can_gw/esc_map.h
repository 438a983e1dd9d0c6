/*
 * FC side: maps the FC's motor outputs (PWM microseconds) to the values of
 * one uavcan.equipment.esc.RawCommand, by ArduPilot's rules (AP_DroneCAN
 * SRV_send_esc / scale_esc_output and the CAN_Dx_UC_ESC_BM, _ESC_OF and
 * _ESC_RV parameters), so every FC behind a gateway drives DroneCAN ESCs
 * the way ArduPilot drives them on a native CAN port.
 *
 * Rules, for output index i (0-based; ArduPilot's "output i+1"):
 *   - slots: command slot k carries output (offset + k); the command runs
 *     from the offset up to the highest output in esc_mask, at most 20
 *     slots (RawCommand's cmd[<=20]); outputs below the offset are not sent
 *     (the offset packs ESCs on outputs 5..8 into slots 0..3).
 *   - gating: a slot is 0 unless the vehicle is armed, output i is in
 *     esc_mask and in armed_mask (outputs the FC enables one by one, as
 *     ArduPilot's _ESC_armed_mask), and i < n_out.
 *   - forward (output not in reversible_mask):
 *       value = 8191 * (pwm - pwm_min) / (pwm_max - pwm_min), clamped to 0..8191
 *   - reversible (in reversible_mask), centre (pwm_min + pwm_max) / 2:
 *       value = 8191 * (pwm - centre) / ((pwm_max - pwm_min) / 2), clamped to -8191..8191
 *   Integer arithmetic, quotient truncated toward zero (as ArduPilot's
 *   float-to-int cast): pwm 1500 forward is 4095, 2000 is 8191, 1250
 *   reversible is -4095. Seed 000 abbreviates the forward rule to
 *   "pulse - 1000"; ArduPilot scales, so full throttle (2000) is 8191.
 *
 * Pure function of its arguments: no state, reentrant, no allocation.
 */
#ifndef DAN_CAN_GW_ESC_MAP_H
#define DAN_CAN_GW_ESC_MAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_ESC_MAP_OUTPUTS    32u   /* outputs a mask can name */
#define DAN_ESC_MAP_OFFSET_MAX 18u   /* as CAN_Dx_UC_ESC_OF */
#define DAN_ESC_MAP_PWM_MIN    1000u /* defaults of pwm_min / pwm_max */
#define DAN_ESC_MAP_PWM_MAX    2000u

typedef struct {
    uint32_t esc_mask;        /* outputs that are DroneCAN ESCs (CAN_Dx_UC_ESC_BM) */
    uint32_t reversible_mask; /* bidirectional ESCs (CAN_Dx_UC_ESC_RV) */
    uint8_t offset;           /* output of slot 0 (CAN_Dx_UC_ESC_OF), 0..18 */
    uint16_t pwm_min;         /* microseconds of value 0 (reversible: -8191) */
    uint16_t pwm_max;         /* microseconds of value 8191 */
} dan_esc_map_t;

/* Fills m with ArduPilot's defaults (no ESCs, offset 0, PWM 1000..2000). */
void dan_esc_map_init(dan_esc_map_t *m);

/* Maps pwm[0..n_out) to values[]. armed: the vehicle is armed; armed_mask:
 * outputs allowed to spin. values must hold cap entries; cap
 * DAN_DC_ESC_RAW_COMMAND_MAX_CMDS (20) always suffices.
 * Returns the number of values (0: nothing to send, esc_mask has no output
 * at or above the offset), or DAN_ERR_ARG (offset above 18, pwm_max not
 * above pwm_min + 1, NULL pointers with n_out > 0) or DAN_ERR_OVERFLOW
 * (cap too small). The count does not depend on armed, so the ESCs keep
 * hearing zeros while disarmed. */
int dan_esc_map(const dan_esc_map_t *m, const uint16_t *pwm, size_t n_out, bool armed,
                uint32_t armed_mask, int16_t *values, size_t cap);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_ESC_MAP_H */
