/*
 * IEEE 754 binary16 ("float16"), as DroneCAN carries voltages, currents and
 * temperatures. One implementation for both sides: the DSDL codecs of the
 * gateway node and an FC reading telemetry records (which carry the ESC's
 * float16 bit patterns unchanged). Pure functions, no libm.
 */
#ifndef DAN_CAN_GW_F16_H
#define DAN_CAN_GW_F16_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* float to binary16: round to nearest, ties away from zero (as libuavcan
 * and pydronecan do, so encodings match them bit for bit). Values beyond
 * the half range become +-infinity; a DSDL encoder saturates finite values
 * to +-65504 first. Infinity stays infinity, NaN becomes 0x7FFF with the
 * sign kept. */
uint16_t dan_f16_from_f32(float v);

/* binary16 to float: exact (every binary16 value is a float). */
float dan_f16_to_f32(uint16_t h);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_F16_H */
