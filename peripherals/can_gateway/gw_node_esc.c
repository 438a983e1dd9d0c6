/* Gateway node: ESC commands (RawCommand), ESC telemetry (esc.Status and
 * StatusExtended per ESC index) and the failsafe. */
#include <string.h>

#include "gw_node_internal.h"

static const int16_t zeros[DAN_GW_ESC_MAX] = {0};

static void send_raw_command(dan_gw_node_t *g, const int16_t *v, size_t n)
{
    dan_dc_esc_raw_command_t m;
    uint8_t buf[DAN_DC_ESC_RAW_COMMAND_MAX_SIZE];
    int len;
    memset(&m, 0, sizeof m);
    m.count = (uint8_t)n;
    memcpy(m.cmd, v, n * sizeof v[0]);
    dan_gwn_drop_own(g, &g->q_urgent, DAN_DC_ESC_RAW_COMMAND_ID); /* latest wins */
    len = dan_dc_esc_raw_command_encode(&m, buf, sizeof buf);
    /* ahead of everything else queued (PROTOCOL.md: throttle first) */
    if (dan_gwn_broadcast(g, &g->q_urgent, DAN_DC_ESC_RAW_COMMAND_ID,
                          DAN_DC_ESC_RAW_COMMAND_SIGNATURE, DAN_DC_PRIORITY_HIGH, buf,
                          len) == DAN_OK) {
        dan_gwn_txq_to_front(&g->q_urgent, dan_dc_tx_frame_count((size_t)len));
    }
}

void dan_gwn_esc_command(dan_gw_node_t *g, const int16_t *v, size_t n, uint64_t now_us)
{
    send_raw_command(g, v, n);
    g->stats.esc_cmds++;
    if (!g->esc.active || g->esc.failsafe) {
        g->esc.start_us = now_us;
    }
    g->esc.active = true;
    g->esc.failsafe = false;
    g->esc.n = (uint8_t)n;
    g->esc.last_cmd_us = now_us;
}

void dan_gw_node_failsafe(dan_gw_node_t *g, uint64_t now_us)
{
    if (g->esc.active && g->esc.n > 0u) {
        send_raw_command(g, zeros, g->esc.n);
    }
    dan_gwn_servos_failsafe(g, now_us);
    dan_gwn_arming_failsafe(g, now_us);
}

/* The failsafe starts esc_timeout_ms after the last command; while it
 * lasts, the zeros go out again with every ArmingStatus. */
void dan_gwn_esc_poll(dan_gw_node_t *g, uint64_t now_us)
{
    if (g->esc.active && !g->esc.failsafe &&
        now_us - g->esc.last_cmd_us > (uint64_t)g->cfg.esc_timeout_ms * 1000u) {
        g->esc.failsafe = true;
        g->stats.failsafes++;
        send_raw_command(g, zeros, g->esc.n);
        dan_gwn_servos_failsafe(g, now_us);
        dan_gwn_arming_failsafe(g, now_us);
    }
    if (g->esc.failsafe && now_us >= g->arming.due_us) {
        send_raw_command(g, zeros, g->esc.n); /* keep the motors stopped */
    }
}

uint64_t dan_gwn_esc_next_us(const dan_gw_node_t *g, uint64_t t)
{
    if (g->esc.active && !g->esc.failsafe) {
        uint64_t fs = g->esc.last_cmd_us + (uint64_t)g->cfg.esc_timeout_ms * 1000u + 1u;
        if (fs < t) {
            t = fs;
        }
    }
    return t;
}

const dan_gw_telem_t *dan_gwn_esc_telem(dan_gw_node_t *g, size_t idx, uint64_t now_us)
{
    dan_gw_node_esc_t *e = &g->esc.slot[idx];
    if (e->t.flags == 0u) {
        return NULL;
    }
    e->t.age_ms = (e->t.flags & DAN_GW_TELEM_STATUS) ? dan_gwn_age_ms(now_us, e->status_us) : 0u;
    e->t.ext_age_ms = (e->t.flags & DAN_GW_TELEM_EXT) ? dan_gwn_age_ms(now_us, e->ext_us) : 0u;
    e->t.dev_age_ms = (e->t.flags & DAN_GW_TELEM_DEVICE) ? dan_gwn_age_ms(now_us, e->dev_us) : 0u;
    return &e->t;
}

const dan_gw_telem_t *dan_gwn_esc_next_telem(dan_gw_node_t *g, uint64_t now_us)
{
    const dan_gw_telem_t *t = NULL;
    size_t i;
    for (i = 1; i <= DAN_GW_NODE_ESC_SLOTS && t == NULL; i++) {
        size_t idx = ((size_t)g->esc.rr + i) % DAN_GW_NODE_ESC_SLOTS;
        t = dan_gwn_esc_telem(g, idx, now_us);
        if (t != NULL) {
            g->esc.rr = (uint8_t)idx;
        }
    }
    return t;
}

/* ESC_FAST_T: the next ESC with esc.Status after the last one reported
 * (the compact record has nothing else); the same round robin as ESC_CMD. */
bool dan_gwn_esc_next_fast(dan_gw_node_t *g, dan_gw_fast_rec_t *rec, uint64_t now_us)
{
    size_t i;
    for (i = 1; i <= DAN_GW_NODE_ESC_SLOTS; i++) {
        size_t idx = ((size_t)g->esc.rr + i) % DAN_GW_NODE_ESC_SLOTS;
        dan_gw_node_esc_t *e = &g->esc.slot[idx];
        if (e->t.flags & DAN_GW_TELEM_STATUS) {
            g->esc.rr = (uint8_t)idx;
            *rec = dan_gw_fast_rec_make(dan_gwn_esc_telem(g, idx, now_us), e->fresh);
            e->fresh = false;
            return true;
        }
    }
    return false;
}

uint8_t dan_gwn_esc_seen(const dan_gw_node_t *g)
{
    size_t i;
    uint8_t n = 0;
    for (i = 0; i < DAN_GW_NODE_ESC_SLOTS; i++) {
        n = (uint8_t)(n + (g->esc.slot[i].t.flags != 0u));
    }
    return n;
}

/* The slot of ESC index, now reported by node with the part flag. */
static dan_gw_node_esc_t *esc_slot(dan_gw_node_t *g, uint8_t index, uint8_t node, uint8_t flag)
{
    dan_gw_node_esc_t *e = &g->esc.slot[index % DAN_GW_NODE_ESC_SLOTS];
    e->t.esc_index = index;
    e->t.node_id = node;
    e->t.flags |= flag;
    return e;
}

void dan_gwn_on_esc_status(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_esc_status_t s;
    dan_gw_node_esc_t *e;
    if (dan_dc_esc_status_decode(&s, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    e = esc_slot(g, s.esc_index, t->source_node, DAN_GW_TELEM_STATUS);
    e->t.voltage_f16 = s.voltage_f16;
    e->t.current_f16 = s.current_f16;
    e->t.temperature_f16 = s.temperature_f16;
    e->t.rpm = s.rpm;
    e->t.power_pct = s.power_rating_pct;
    e->t.error_count = s.error_count;
    e->status_us = now_us;
    e->fresh = true;
}

/* device.Temperature joins the telemetry of every ESC index the same node
 * reports (Vertiq's older firmware sends its MCU temperature there). */
void dan_gwn_on_temperature(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_temperature_t m;
    size_t i;
    if (dan_dc_temperature_decode(&m, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    for (i = 0; i < DAN_GW_NODE_ESC_SLOTS; i++) {
        dan_gw_node_esc_t *e = &g->esc.slot[i];
        if (e->t.flags != 0u && e->t.node_id == t->source_node) {
            e->t.flags |= DAN_GW_TELEM_DEVICE;
            e->t.dev_temp_f16 = m.temperature_f16;
            e->t.dev_flags = m.error_flags;
            e->dev_us = now_us;
        }
    }
}

void dan_gwn_on_esc_ext(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_esc_status_extended_t s;
    dan_gw_node_esc_t *e;
    if (dan_dc_esc_status_extended_decode(&s, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    e = esc_slot(g, s.esc_index, t->source_node, DAN_GW_TELEM_EXT);
    e->t.input_pct = s.input_pct;
    e->t.output_pct = s.output_pct;
    e->t.motor_temp_c = s.motor_temperature_degC;
    e->t.motor_angle = s.motor_angle;
    e->t.status_flags = s.status_flags;
    e->ext_us = now_us;
}
