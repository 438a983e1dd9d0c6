/* A classic CAN 2.0 frame, shared by the gateway, its CAN backends and the
 * master-side gateway client. */
#ifndef DAN_CAN_H
#define DAN_CAN_H

#include <stdint.h>

#define DAN_CAN_EXT 0x01u /* 29-bit identifier (else 11-bit) */
#define DAN_CAN_RTR 0x02u /* remote transmission request */
#define DAN_CAN_ERR 0x04u /* error frame reported by the controller */
#define DAN_CAN_OWN 0x08u /* a frame this node sent (in a capture of the bus) */

/* With DAN_CAN_ERR, id holds the error class; these values are the ones
 * SocketCAN uses (linux/can/error.h), so backends pass them through. */
#define DAN_CAN_ERRCLASS_BUSOFF    0x00000040u /* the controller went bus-off */
#define DAN_CAN_ERRCLASS_RESTARTED 0x00000100u /* ... and is back */

#define DAN_CAN_SFF_MASK 0x000007FFu
#define DAN_CAN_EFF_MASK 0x1FFFFFFFu

typedef struct {
    uint32_t id;   /* identifier only, no flag bits */
    uint8_t flags; /* DAN_CAN_EXT | DAN_CAN_RTR | DAN_CAN_ERR */
    uint8_t dlc;   /* 0..8 */
    uint8_t data[8];
} dan_can_frame_t;

#endif /* DAN_CAN_H */
