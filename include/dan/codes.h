/*
 * The registry of DAN message codes.
 *
 * Code 0 is the error message. Each peripheral type owns a block of 16
 * codes; every block starts with IDENTIFY (first) and CONFIGURE (first+1).
 * Codes are uvarints: blocks below 0x80 cost one byte on the wire.
 *
 *   0x00         error message (DAN-ERROR-MESSAGE-V1)
 *   0x01..0x1F   reserved for bus-wide messages of later versions
 *   0x20..0x2F   VTX (the DAN draft repository's type; reserved here)
 *   0x30..0x3F   reserved for the next registered type
 *   0x40..0x4F   CAN-over-DAN gateway (docs/PROTOCOL.md)
 *   0x50..0x5F   CAN-over-DAN gateway, second block (0x50, 0x51 unused)
 *   0x60..0x6F   private / test type A (never shipped in products)
 *   0x70..0x7F   private / test type B (never shipped in products)
 *   0x80..       unassigned (two-byte codes)
 */
#ifndef DAN_CODES_H
#define DAN_CODES_H

#define DAN_CODE_ERROR 0x00u

#define DAN_TYPE_BLOCK_SIZE       16u /* a type may own several consecutive blocks */
#define DAN_TYPE_IDENTIFY(first)  (first)
#define DAN_TYPE_CONFIGURE(first) ((first) + 1u)

/* VTX: reserved for the draft's VTX messages (0x20-0x29 used there). */
#define DAN_TYPE_VTX_FIRST     0x20u
#define DAN_TYPE_VTX_LAST      0x2Fu
#define DAN_CODE_VTX_IDENTIFY  0x20u
#define DAN_CODE_VTX_CONFIGURE 0x21u

/* CAN-over-DAN gateway; its messages are in dan/can_gw/msgs.h
 * (peripherals/can_gateway/). */
#define DAN_TYPE_CAN_GW_FIRST       0x40u
#define DAN_TYPE_CAN_GW_LAST        0x4Fu
#define DAN_CODE_CAN_GW_IDENTIFY    0x40u
#define DAN_CODE_CAN_GW_CONFIGURE   0x41u
/* Its second block: 0x50 and 0x51 unused, 0x52.. messages. */
#define DAN_TYPE_CAN_GW_BLOCK2      0x50u
#define DAN_TYPE_CAN_GW_BLOCK2_LAST 0x5Fu

/* Private / test types, for bench and test peripherals. */
#define DAN_TYPE_TEST_A_FIRST 0x60u
#define DAN_TYPE_TEST_A_LAST  0x6Fu
#define DAN_TYPE_TEST_B_FIRST 0x70u
#define DAN_TYPE_TEST_B_LAST  0x7Fu

#endif /* DAN_CODES_H */
