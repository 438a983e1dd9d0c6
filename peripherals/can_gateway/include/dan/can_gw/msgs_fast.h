/*
 * CAN-over-DAN gateway: the compact ESC exchanges (docs/PROTOCOL.md
 * section 7, "Fast ESC exchanges"). The FC picks per exchange whether the
 * response carries a telemetry record, by the code alone:
 *   ESC_FAST   (0x59): command, response = gateway flags only;
 *   ESC_FAST_T (0x5A): command, response = flags + one compact record.
 * Both carry the seal like every gateway message. Conventions as
 * dan/can_gw/msgs.h; tests/vectors/gateway.txt pins the layouts.
 */
#ifndef DAN_CAN_GW_MSGS_FAST_H
#define DAN_CAN_GW_MSGS_FAST_H

#include "dan/can_gw/msgs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_GW_CODE_ESC_FAST   0x59u /* command -> flags */
#define DAN_GW_CODE_ESC_FAST_T 0x5Au /* command -> flags + one compact record */

/* Request: only the n int14 values, bit-packed as ESC_CMD's stream (value i
 * at stream bits 14i..14i+13, LSB first, last byte zero-padded), no count
 * byte: n (1..20) follows from the length, which must be exactly
 * DAN_GW_ESC_FAST_SIZE(n); any other length, or a padding bit set, is
 * malformed. 4 ESCs: 7 bytes. */
#define DAN_GW_ESC_FAST_SIZE(n) (((n)*14u + 7u) / 8u)

/* The bit stream alone (shared with ESC_CMD, which puts a count first):
 * pack writes DAN_GW_ESC_FAST_SIZE(n) bytes; values must be in range.
 * unpack reads n values and returns false if a padding bit is set. */
void dan_gw_msg_esc_pack(const int16_t *values, size_t n, uint8_t *out);
bool dan_gw_msg_esc_unpack(const uint8_t *p, size_t n, int16_t *values);

/* Values outside -8192..8191, n 0 or above 20: DAN_ERR_ARG. */
int dan_gw_msg_esc_fast_encode(const int16_t *values, size_t n, uint8_t *out, size_t cap);
/* values must hold DAN_GW_ESC_MAX entries. */
int dan_gw_msg_esc_fast_decode(const uint8_t *p, size_t len, int16_t *values, size_t *n);

/* Compact record (10 bytes), the esc.Status of one ESC:
 *   u16 voltage, u16 current, u16 temperature: binary16 bits as the ESC
 *       sent them (V, A, K);
 *   u24 bits 0-17 rpm (int18, two's complement), bits 18-22 esc_index,
 *       bit 23 fresh (an esc.Status arrived since this ESC's last compact
 *       record: the FC counts updates, never the same sample twice);
 *   u8 age in units of 4 ms since that esc.Status arrived (rounded down),
 *       255 = 1020 ms or older (ArduPilot drops RPM older than 1 s). */
#define DAN_GW_FAST_REC_SIZE 10u
#define DAN_GW_FAST_AGE_UNIT 4u   /* ms */
#define DAN_GW_FAST_AGE_MAX  255u /* saturated */
#define DAN_GW_FAST_RSP_MAX  (1u + DAN_GW_FAST_REC_SIZE)

typedef struct {
    uint8_t esc_index; /* 0..31 */
    bool fresh;
    uint8_t age_4ms;
    uint16_t voltage_f16;
    uint16_t current_f16;
    uint16_t temperature_f16;
    int32_t rpm; /* int18 */
} dan_gw_fast_rec_t;

/* The record of telemetry t (its esc.Status fields and age_ms). */
dan_gw_fast_rec_t dan_gw_fast_rec_make(const dan_gw_telem_t *t, bool fresh);
DAN_ITEM(dan_gw_msg_fast_rec, dan_gw_fast_rec_t);

/* Response: u8 gw_flags, then for ESC_FAST_T the record when some ESC has
 * sent esc.Status (absent otherwise). rec == NULL encodes flags only.
 * decode: *has_rec tells; a length other than 1 or 1 + 10 is malformed. */
int dan_gw_msg_esc_fast_rsp_encode(uint8_t gw_flags, const dan_gw_fast_rec_t *rec, uint8_t *out,
                                   size_t cap);
int dan_gw_msg_esc_fast_rsp_decode(uint8_t *gw_flags, dan_gw_fast_rec_t *rec, bool *has_rec,
                                   const uint8_t *p, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_MSGS_FAST_H */
