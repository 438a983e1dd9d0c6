/* CAN-over-DAN gateway client: the response decoder of any code, for
 * dan_gw_complete_as(). Only programs that call it link every decoder. */
#include "gw_client_internal.h"

dan_gw_done_fn dan_gwc_done_of(uint32_t code)
{
    switch (code) {
    case DAN_GW_CODE_ESC_CMD:
    case DAN_GW_CODE_ESC_TELEM: return dan_gwc_done_telem;
    case DAN_GW_CODE_ESC_FAST:
    case DAN_GW_CODE_ESC_FAST_T: return dan_gwc_done_fast;
    case DAN_GW_CODE_ARM:
    case DAN_GW_CODE_SAFETY:
    case DAN_GW_CODE_SERVO:
    case DAN_GW_CODE_LIGHTS:
    case DAN_GW_CODE_BEEP:
    case DAN_GW_CODE_SERVO_FAILSAFE: return dan_gwc_done_flags;
    case DAN_GW_CODE_CONFIG: return dan_gwc_done_config;
    case DAN_GW_CODE_STATS: return dan_gwc_done_stats;
    case DAN_GW_CODE_TUN_OPEN: return dan_gwc_done_tun_open;
    case DAN_GW_CODE_TUN_XFER: return dan_gwc_done_xfer;
    case DAN_GW_CODE_CAN_SEND: return dan_gwc_done_can_send;
    case DAN_GW_CODE_CAN_RECV: return dan_gwc_done_can_recv;
    case DAN_GW_CODE_NODE_CALL: return dan_gwc_done_call;
    case DAN_GW_CODE_HEALTH: return dan_gwc_done_health;
    default: return NULL; /* NODES, NODE_INFO, CAN_FILTER, CALL_RESULT, DNA: read on demand */
    }
}

int dan_gw_complete_as(dan_gw_t *gw, uint32_t code, uint64_t now_us)
{
    gw->code = code;
    gw->done = dan_gwc_done_of(code);
    return dan_gw_complete(gw, now_us);
}
