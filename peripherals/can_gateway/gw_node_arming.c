/* Gateway node: uavcan.equipment.safety.ArmingStatus and ArduPilot's
 * SafetyState, at the arming rate and at once on a change. AP_Periph nodes
 * built with safety-switch support output nothing until they hear safety
 * OFF; the gateway starts with safety ON and the failsafe forces it ON. */
#include "gw_node_internal.h"

static uint64_t arming_period_us(const dan_gw_node_t *g)
{
    return 1000000u / (g->cfg.arming_rate_hz ? g->cfg.arming_rate_hz : 1u);
}

/* Both states go out together: at the rate, at once on a change of either. */
void dan_gwn_arming_send(dan_gw_node_t *g, uint64_t now_us)
{
    dan_dc_arming_status_t m;
    uint8_t buf[DAN_DC_ARMING_STATUS_MAX_SIZE];
    uint8_t sbuf[DAN_DC_SAFETY_STATE_MAX_SIZE];
    m.status = g->arming.status;
    dan_gwn_drop_own(g, &g->q_urgent, DAN_DC_ARMING_STATUS_ID);
    (void)dan_gwn_broadcast(g, &g->q_urgent, DAN_DC_ARMING_STATUS_ID,
                            DAN_DC_ARMING_STATUS_SIGNATURE, DAN_DC_PRIORITY_MEDIUM, buf,
                            dan_dc_arming_status_encode(&m, buf, sizeof buf));
    dan_gwn_drop_own(g, &g->q_urgent, DAN_DC_SAFETY_STATE_ID);
    (void)dan_gwn_broadcast(g, &g->q_urgent, DAN_DC_SAFETY_STATE_ID, DAN_DC_SAFETY_STATE_SIGNATURE,
                            DAN_DC_PRIORITY_MEDIUM, sbuf,
                            dan_dc_safety_state_encode(g->arming.safety, sbuf, sizeof sbuf));
    g->arming.due_us = now_us + arming_period_us(g);
}

void dan_gwn_safety_set(dan_gw_node_t *g, uint8_t status, uint64_t now_us)
{
    if (status != g->arming.safety) {
        g->arming.safety = status;
        dan_gwn_arming_send(g, now_us);
    }
}

/* The failsafe: DISARMED and safety ON, at once. */
void dan_gwn_arming_failsafe(dan_gw_node_t *g, uint64_t now_us)
{
    g->arming.status = DAN_DC_ARMING_STATUS_DISARMED;
    g->arming.safety = DAN_DC_SAFETY_ON;
    dan_gwn_arming_send(g, now_us);
}

/* During a failsafe too: an explicit ARM comes from a live master that
 * chose it; the zeros keep repeating until ESC commands resume. */
void dan_gwn_arming_set(dan_gw_node_t *g, uint8_t status, uint64_t now_us)
{
    if (status != g->arming.status) {
        g->arming.status = status;
        dan_gwn_arming_send(g, now_us);
    }
}

void dan_gwn_arming_poll(dan_gw_node_t *g, uint64_t now_us)
{
    if (now_us >= g->arming.due_us) {
        dan_gwn_arming_send(g, now_us);
    }
}

int dan_gw_node_set_arming_rate(dan_gw_node_t *g, uint32_t hz, uint64_t now_us)
{
    if (hz < DAN_GW_ARMING_RATE_MIN || hz > DAN_GW_ARMING_RATE_MAX) {
        return DAN_ERR_ARG;
    }
    g->cfg.arming_rate_hz = hz;
    g->arming.due_us = now_us;
    return DAN_OK;
}
