/* What the gateway benchmarks share (see bench_escs.h). */
#include <string.h>

#include "bench_escs.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/f16.h"

int bench_esc_status(uint8_t idx, uint8_t tid, dan_can_frame_t *fr)
{
    dan_dc_esc_status_t s;
    dan_dc_transfer_t t;
    uint8_t pl[DAN_DC_ESC_STATUS_MAX_SIZE];
    int n;
    memset(&s, 0, sizeof s);
    s.voltage_f16 = dan_f16_from_f32(16.8f);
    s.current_f16 = dan_f16_from_f32(3.5f);
    s.temperature_f16 = dan_f16_from_f32(310.0f);
    s.rpm = 5000 + idx;
    s.power_rating_pct = 30;
    s.esc_index = idx;
    n = dan_dc_esc_status_encode(&s, pl, sizeof pl);
    dan_dc_transfer_init(&t, DAN_DC_ESC_STATUS_ID, DAN_DC_ESC_STATUS_SIGNATURE,
                         DAN_DC_TRANSFER_BROADCAST, pl, (size_t)n);
    t.priority = 16;
    t.source_node = (uint8_t)(20u + idx);
    t.transfer_id = tid;
    return dan_dc_tx_build(&t, fr, 8);
}
