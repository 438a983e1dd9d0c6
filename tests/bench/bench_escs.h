/* What the gateway benchmarks share: an ESC's esc.Status as CAN frames. */
#ifndef DAN_BENCH_ESCS_H
#define DAN_BENCH_ESCS_H

#include "dan/can_gw/can.h"

/* One esc.Status transfer of ESC idx from node 20 + idx (16.8 V, 3.5 A,
 * 310 K, 5000 + idx rpm) with transfer ID tid, as CAN frames into fr
 * (room for 8); returns their count. */
int bench_esc_status(uint8_t idx, uint8_t tid, dan_can_frame_t *fr);

#endif
