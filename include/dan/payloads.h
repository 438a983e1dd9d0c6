/*
 * The common DAN v1 payloads: identity, configure, ACK and error.
 *
 * Encoders take a caller buffer and return the payload length or a negative
 * error; with out == NULL they return the size only. Decoders never read
 * outside the payload and return DAN_ERR_MALFORMED for a truncated one.
 * Trailing bytes after the known fields are ignored (room for later
 * versions); reserved mask bits are kept in the raw value and ignored.
 */
#ifndef DAN_PAYLOADS_H
#define DAN_PAYLOADS_H

#include "dan/common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_VERSION 1u

/* DAN-PERIPHERAL-SUPPORTED-BAUDRATES-MASK-V1. 9600 is always supported. */
#define DAN_BAUD_BASE         9600u
#define DAN_BAUD_MASK_19200   (1u << 0)
#define DAN_BAUD_MASK_38400   (1u << 1)
#define DAN_BAUD_MASK_57600   (1u << 2)
#define DAN_BAUD_MASK_115200  (1u << 3)
#define DAN_BAUD_MASK_DEFINED 0x000Fu /* bits defined by v1 */

/* Baud of one mask bit (DAN_BAUD_MASK_xxx), or 0 if the bit is not defined. */
uint32_t dan_baud_of_mask_bit(uint16_t bit);
/* Mask bit of a baud, 0 for 9600 or an undefined baud. */
uint16_t dan_mask_bit_of_baud(uint32_t baud);
/* Highest baud whose bit is in mask (defined bits only), or 9600. */
uint32_t dan_baud_highest(uint16_t mask);

/* Our fast bauds (docs/PROTOCOL.md section 6): not in the v1 mask (its
 * reserved bits stay zero), offered by a master after discovery with
 * CONFIGURE, which carries any baud; a peripheral that cannot do one
 * answers ACK-FAIL. Ascending. */
#define DAN_NFAST_BAUDS 6u
extern const uint32_t dan_fast_bauds[DAN_NFAST_BAUDS];
/* True for 9600 and the bauds of the v1 mask (19200..115200). */
bool dan_baud_is_v1(uint32_t baud);

/* DAN-PERIPHERAL-CAPABILITIES-MASK-V1: all bits reserved in v1. */

/* DAN-PERIPHERAL-IDENTITY-PAYLOAD-V1 */
typedef struct {
    uint8_t dan_version;
    char manufacturer[DAN_MAX_STRING];
    char model[DAN_MAX_STRING];
    char hw_version[DAN_MAX_STRING];
    char sw_version[DAN_MAX_STRING];
    uint16_t baud_mask;    /* raw, as on the wire */
    uint16_t capabilities; /* raw, as on the wire */
    bool truncated;        /* a string was longer than DAN_MAX_STRING-1 */
} dan_identity_t;

int dan_identity_encode(const dan_identity_t *id, uint8_t *out, size_t cap);
int dan_identity_decode(dan_identity_t *id, const uint8_t *p, size_t len);
/* Only the baud mask of an identity payload: DAN_OK for exactly the
 * payloads dan_identity_decode() accepts, else DAN_ERR_MALFORMED (*mask
 * then undefined). No string buffers: what the master keeps of a peer. */
int dan_identity_baud_mask(const uint8_t *p, size_t len, uint16_t *mask);

/* DAN-PERIPHERAL-CONFIGURATION-REQUEST-TYPE-ENUM-V1 */
#define DAN_CONFIGURE_BPS 0u

/* DAN-PERIPHERAL-CONFIGURE-PAYLOAD-V1 */
typedef struct {
    uint8_t type;  /* DAN_CONFIGURE_BPS */
    uint32_t baud; /* requested baud, for DAN_CONFIGURE_BPS */
} dan_configure_t;

int dan_configure_encode(const dan_configure_t *c, uint8_t *out, size_t cap);
/* Unknown request types decode as DAN_ERR_UNSUPPORTED (the peripheral
 * answers them with ACK-FAIL: the payload is well formed but not doable). */
int dan_configure_decode(dan_configure_t *c, const uint8_t *p, size_t len);

/* DAN-PERIPHERAL-ACK: our rule, a one-byte payload. */
#define DAN_ACK_OK   0u
#define DAN_ACK_FAIL 1u

int dan_ack_encode(uint8_t ack, uint8_t *out, size_t cap);
/* Any value other than 0 and 1 is malformed. */
int dan_ack_decode(uint8_t *ack, const uint8_t *p, size_t len);

/* DAN-ERROR-MESSAGE-V1 (the payload of a code-0 frame). */
typedef struct {
    uint32_t code;  /* the request code that caused the error */
    uint32_t error; /* reserved, 0 in v1 */
    char text[DAN_MAX_STRING];
    bool truncated;
} dan_error_msg_t;

int dan_error_encode(uint32_t code, uint32_t error, const char *text, uint8_t *out, size_t cap);
int dan_error_decode(dan_error_msg_t *e, const uint8_t *p, size_t len);
/* Only the request code of an error payload: DAN_OK for exactly the
 * payloads dan_error_decode() accepts (no text buffer). */
int dan_error_code(const uint8_t *p, size_t len, uint32_t *code);

#ifdef __cplusplus
}
#endif

#endif /* DAN_PAYLOADS_H */
