/* Gateway node: the bus health verdict (HEALTH). The gateway only tells;
 * the FC decides what a FAIL means for arming. */
#include "gw_node_internal.h"

/* Notes a problem; the first one (in the caller's order) is the reason. */
static void note(dan_gw_health_t *h, uint8_t reason, uint8_t subject, uint8_t detail)
{
    if (h->problems == 0u) {
        h->verdict = DAN_GW_HEALTH_FAIL;
        h->reason = reason;
        h->subject = subject;
        h->detail = detail;
    }
    if (h->problems < 0xFFu) {
        h->problems++;
    }
}

/* Nodes: duplicates first, then unhealthy ones (worst health first), then
 * offline ones. */
static void check_nodes(dan_gw_node_t *g, dan_gw_health_t *h, uint64_t now_us)
{
    unsigned pass, health;
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        const dan_gw_node_slot_t *n = &g->nodes[i];
        if (n->e.node_id != 0u && n->duplicate && !dan_gwn_offline(n, now_us)) {
            note(h, DAN_GW_REASON_DUPLICATE, n->e.node_id, 0);
        }
    }
    for (pass = 0; pass < 3u; pass++) {
        health = DAN_DC_HEALTH_CRITICAL - pass;
        for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
            const dan_gw_node_slot_t *n = &g->nodes[i];
            if (n->e.node_id != 0u && n->e.health == health && !dan_gwn_offline(n, now_us)) {
                note(h, DAN_GW_REASON_UNHEALTHY, n->e.node_id, (uint8_t)health);
            }
        }
    }
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        const dan_gw_node_slot_t *n = &g->nodes[i];
        if (n->e.node_id != 0u && dan_gwn_offline(n, now_us)) {
            note(h, DAN_GW_REASON_OFFLINE, n->e.node_id, 0);
        }
    }
}

/* ESC indexes below the channel count of the commands flowing now, with no
 * esc.Status for telem_timeout_ms. */
static void check_escs(dan_gw_node_t *g, dan_gw_health_t *h, uint64_t now_us)
{
    uint64_t limit = (uint64_t)g->cfg.telem_timeout_ms * 1000u;
    size_t i;
    if (limit == 0u || !g->esc.active || g->esc.failsafe || now_us - g->esc.start_us < limit) {
        return;
    }
    for (i = 0; i < g->esc.n && i < DAN_GW_NODE_ESC_SLOTS; i++) {
        const dan_gw_node_esc_t *e = &g->esc.slot[i];
        if ((e->t.flags & DAN_GW_TELEM_STATUS) == 0u || now_us - e->status_us > limit) {
            note(h, DAN_GW_REASON_ESC_TELEMETRY, (uint8_t)i, 0);
        }
    }
}

void dan_gw_node_health(dan_gw_node_t *g, dan_gw_health_t *h, uint64_t now_us)
{
    h->verdict = DAN_GW_HEALTH_OK;
    h->reason = DAN_GW_REASON_NONE;
    h->subject = 0;
    h->detail = 0;
    h->problems = 0;
    if (!g->can_ok) {
        note(h, DAN_GW_REASON_CAN_DOWN, 0, 0);
    }
    check_nodes(g, h, now_us);
    check_escs(g, h, now_us);
    if (g->dna.foreign != 0u && now_us - g->dna.foreign_us < DAN_GW_NODE_FOREIGN_US) {
        note(h, DAN_GW_REASON_DNA_CONFLICT, g->dna.foreign, 0);
    }
    if (g->dna.full) {
        note(h, DAN_GW_REASON_DNA_FULL, 0, 0);
    }
}

int dan_gw_node_set_telem_timeout(dan_gw_node_t *g, uint32_t ms)
{
    if (ms != 0u && (ms < DAN_GW_TELEM_TIMEOUT_MIN || ms > DAN_GW_TELEM_TIMEOUT_MAX)) {
        return DAN_ERR_ARG;
    }
    g->cfg.telem_timeout_ms = ms;
    return DAN_OK;
}
