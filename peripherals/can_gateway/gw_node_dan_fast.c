/* Gateway node: the DAN handler of the compact ESC exchanges (ESC_FAST,
 * ESC_FAST_T; docs/PROTOCOL.md "Fast ESC exchanges"); the table is in
 * gw_node_dan.c. The command does what ESC_CMD's does (RawCommand at
 * once, the failsafe timer fed); the code alone says whether the response
 * carries a telemetry record. */
#include "gw_node_internal.h"

DAN_GWN_HANDLER(dan_gwn_h_esc_fast)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    int16_t v[DAN_GW_ESC_MAX];
    dan_gw_fast_rec_t rec;
    size_t n;
    if (dan_gw_msg_esc_fast_decode(req, len, v, &n) != DAN_OK) {
        return dan_gwn_refuse(err, "bad fast ESC command (length or padding)");
    }
    dan_gwn_esc_command(g, v, n, now_us);
    dan_put_u8(resp, dan_gw_node_flags(g));
    if (code == DAN_GW_CODE_ESC_FAST_T && dan_gwn_esc_next_fast(g, &rec, now_us)) {
        dan_gw_msg_fast_rec_put(resp, &rec);
    }
    return DAN_OK;
}
