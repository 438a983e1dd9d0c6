/* Gateway node: set-up, our own DroneCAN presence (NodeStatus, the
 * GetNodeInfo answer), dispatch of received frames and the timers. The
 * subsystems are in gw_node_*.c (see dan/can_gw/node.h). */
#include <string.h>

#include "dan/codes.h"
#include "gw_node_internal.h"

static const dan_identity_t default_identity = {
    1, "DAN Project", "CAN gateway", "1", "0.1.0", DAN_BAUD_MASK_DEFINED, 0, false};

void dan_gw_node_config_default(dan_gw_node_config_t *c)
{
    memset(c, 0, sizeof *c);
    c->node_id = DAN_GW_NODE_DEFAULT_ID;
    c->esc_timeout_ms = DAN_GW_NODE_DEFAULT_ESC_TIMEOUT;
    c->arming_rate_hz = DAN_GW_NODE_DEFAULT_ARMING_RATE;
    c->master_timeout_ms = 1000u;
    c->sw_major = 0;
    c->sw_minor = 1;
    c->hw_major = 1;
    c->name = DAN_GW_NODE_NAME;
    c->dna = true;
    c->telem_timeout_ms = DAN_GW_NODE_DEFAULT_TELEM_TIMEOUT;
}

/* The transfers we receive: everything else is left to the raw ring. */
static bool accept_cb(void *user, uint16_t dtid, uint8_t ttype, uint8_t src, uint64_t *sig)
{
    const dan_gw_node_t *g = (const dan_gw_node_t *)user;
    (void)src;
    if (ttype == DAN_DC_TRANSFER_BROADCAST) {
        switch (dtid) {
        case DAN_DC_NODE_STATUS_ID:
        case DAN_DC_ESC_STATUS_ID:
        case DAN_DC_ESC_STATUS_EXTENDED_ID:
        case DAN_DC_TUNNEL_TARGETTED_ID:
        case DAN_DC_TUNNEL_BROADCAST_ID:
        case DAN_DC_ALLOCATION_ID:
        case DAN_DC_TEMPERATURE_ID: break;
        default: return false;
        }
    } else if (ttype == DAN_DC_TRANSFER_REQUEST) {
        if (dtid != DAN_DC_GET_NODE_INFO_ID && !dan_gwn_file_service(g, dtid)) {
            return false; /* the services we answer */
        }
    } else if (dtid != DAN_DC_GET_NODE_INFO_ID && dtid != DAN_DC_PARAM_GETSET_ID &&
               dtid != DAN_DC_PARAM_OPCODE_ID && dtid != DAN_DC_RESTART_ID &&
               dtid != DAN_DC_FW_BEGIN_ID) {
        return false; /* the services we call */
    }
    return dan_dc_dsdl_signature(ttype, dtid, sig);
}

int dan_gw_node_init(dan_gw_node_t *g, const dan_gw_node_config_t *cfg, uint64_t now_us)
{
    dan_gw_node_config_t def;
    if (cfg == NULL) {
        dan_gw_node_config_default(&def);
        cfg = &def;
    }
    if (cfg->node_id < 1u || cfg->node_id > DAN_DC_NODE_ID_MAX ||
        cfg->esc_timeout_ms < DAN_GW_ESC_TIMEOUT_MIN ||
        cfg->esc_timeout_ms > DAN_GW_ESC_TIMEOUT_MAX ||
        cfg->arming_rate_hz < DAN_GW_ARMING_RATE_MIN ||
        cfg->arming_rate_hz > DAN_GW_ARMING_RATE_MAX) {
        return DAN_ERR_ARG;
    }
    memset(g, 0, sizeof *g);
    g->cfg = *cfg;
    g->raw.first = cfg->raw_seq_start;
    if (g->cfg.name == NULL) {
        g->cfg.name = DAN_GW_NODE_NAME;
    }
    g->identity = default_identity;
    dan_dc_rx_init(&g->rx, cfg->node_id, accept_cb, g);
    dan_dc_tid_table_init(&g->tids);
    g->start_us = now_us;
    g->status_due_us = now_us;
    g->arming.due_us = now_us;
    g->can_ok = true;
    g->esc.rr = DAN_GW_NONE;
    dan_gwn_calls_init(g);
    dan_gwn_dna_load(g);
    return DAN_OK;
}

void dan_gw_node_ptype(dan_gw_node_t *g, dan_ptype_t *t)
{
    t->first = DAN_TYPE_CAN_GW_FIRST;
    t->identity = &g->identity;
    t->handlers = dan_gwn_handlers;
    t->nhandlers = dan_gwn_nhandlers;
    t->user = g;
    t->envelope = &dan_gwn_seal;
    t->blocks = 2; /* 0x40..0x4F and 0x50..0x5F (docs/PROTOCOL.md section 5) */
}

void dan_gw_node_attach(dan_gw_node_t *g, const dan_periph_t *p)
{
    g->periph = p;
}

void dan_gw_node_can_state(dan_gw_node_t *g, bool ok)
{
    g->can_ok = ok;
}

void dan_gw_node_can_error(dan_gw_node_t *g)
{
    g->stats.can_errors++;
}

uint8_t dan_gw_node_flags(const dan_gw_node_t *g)
{
    return (uint8_t)((g->arming.status != 0u ? DAN_GW_FLAG_ARMED : 0u) |
                     (g->esc.failsafe ? DAN_GW_FLAG_FAILSAFE : 0u) |
                     (g->can_ok ? DAN_GW_FLAG_CAN_OK : 0u) |
                     (g->arming.safety == DAN_DC_SAFETY_OFF ? DAN_GW_FLAG_SAFETY_OFF : 0u));
}

int dan_gw_node_set_esc_timeout(dan_gw_node_t *g, uint32_t ms)
{
    if (ms < DAN_GW_ESC_TIMEOUT_MIN || ms > DAN_GW_ESC_TIMEOUT_MAX) {
        return DAN_ERR_ARG;
    }
    g->cfg.esc_timeout_ms = ms;
    return DAN_OK;
}

uint32_t dan_gwn_age_ms(uint64_t now_us, uint64_t then_us)
{
    uint64_t ms = (now_us - then_us) / 1000u;
    return ms > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)ms;
}

void dan_gw_node_counters(const dan_gw_node_t *g, uint32_t v[DAN_GW_STAT_COUNT])
{
    memset(v, 0, sizeof(uint32_t) * DAN_GW_STAT_COUNT);
    if (g->periph != NULL) {
        const dan_periph_t *p = g->periph;
        v[DAN_GW_STAT_DAN_FRAMES] = p->link.dec.stats.frames;
        v[DAN_GW_STAT_DAN_CRC] = p->link.dec.stats.crc_errors;
        v[DAN_GW_STAT_DAN_UNKNOWN] = p->stats.unknown;
        v[DAN_GW_STAT_DAN_ERRORS_SENT] = p->stats.errors_sent;
        v[DAN_GW_STAT_DAN_REQUESTS] = p->stats.requests;
    } else {
        v[DAN_GW_STAT_DAN_REQUESTS] = g->stats.dan_requests;
    }
    v[DAN_GW_STAT_CAN_TX] = g->stats.can_tx;
    v[DAN_GW_STAT_CAN_RX] = g->stats.can_rx;
    v[DAN_GW_STAT_CAN_TX_DROPPED] = g->stats.can_tx_dropped;
    v[DAN_GW_STAT_CAN_ERRORS] = g->stats.can_errors;
    v[DAN_GW_STAT_DC_TRANSFERS] = g->rx.stats.transfers;
    v[DAN_GW_STAT_DC_CRC] = g->rx.stats.crc_errors;
    /* tid_errors too: replayed transfers and frames without their start
     * are what a hostile node sends, and STATS is where the FC sees them. */
    v[DAN_GW_STAT_DC_ERRORS] = g->rx.stats.toggle_errors + g->rx.stats.timeouts +
                               g->rx.stats.malformed + g->rx.stats.overflow + g->rx.stats.no_slot +
                               g->rx.stats.tid_errors;
    v[DAN_GW_STAT_ESC_CMDS] = g->stats.esc_cmds;
    v[DAN_GW_STAT_FAILSAFES] = g->stats.failsafes;
    v[DAN_GW_STAT_FAILSAFE_ACTIVE] = g->esc.failsafe ? 1u : 0u;
    v[DAN_GW_STAT_TUN_DROPPED] = g->stats.tun_dropped;
    v[DAN_GW_STAT_RAW_DROPPED] = g->stats.raw_dropped;
    v[DAN_GW_STAT_NODES] = dan_gwn_table_count(g);
    v[DAN_GW_STAT_BAD_CHECKS] = g->stats.bad_checks;
    v[DAN_GW_STAT_NODES_DROPPED] = g->stats.nodes_dropped;
    v[DAN_GW_STAT_DNA_ALLOCATIONS] = g->stats.dna_allocations;
    v[DAN_GW_STAT_DNA_BAD] = g->stats.dna_bad;
    v[DAN_GW_STAT_DNA_FOREIGN] = g->stats.dna_foreign;
    v[DAN_GW_STAT_DUPLICATES] = g->stats.duplicates;
    v[DAN_GW_STAT_CALLS] = g->stats.calls;
    v[DAN_GW_STAT_CALL_TIMEOUTS] = g->stats.call_timeouts;
    v[DAN_GW_STAT_SERVO_CMDS] = g->stats.servo_cmds;
    v[DAN_GW_STAT_SERVO_DROPPED] = g->stats.servo_dropped;
    v[DAN_GW_STAT_FILE_READS] = g->stats.file_reads;
    v[DAN_GW_STAT_FILE_BYTES] = g->stats.file_bytes;
    v[DAN_GW_STAT_FILE_ERRORS] = g->stats.file_errors;
    v[DAN_GW_STAT_UPLOAD_BYTES] = g->stats.upload_bytes;
    v[DAN_GW_STAT_FILE_COMMITS] = g->stats.file_commits;
    v[DAN_GW_STAT_UPLOAD_ERRORS] = g->stats.upload_errors;
    v[DAN_GW_STAT_FW_BEGINS] = g->stats.fw_begins;
    v[DAN_GW_STAT_FILE_DROPPED] = g->stats.file_dropped;
}

/* ---- our own DroneCAN presence ---- */

static void own_status(const dan_gw_node_t *g, dan_dc_node_status_t *s, uint64_t now_us)
{
    bool master = g->last_dan_us != 0u &&
                  now_us - g->last_dan_us <= (uint64_t)g->cfg.master_timeout_ms * 1000u;
    memset(s, 0, sizeof *s);
    s->uptime_sec = (uint32_t)((now_us - g->start_us) / 1000000u);
    s->health = (uint8_t)(master ? DAN_DC_HEALTH_OK : DAN_DC_HEALTH_WARNING);
    s->mode = DAN_DC_MODE_OPERATIONAL;
    s->vendor_specific_status_code = dan_gw_node_flags(g);
}

static void send_node_status(dan_gw_node_t *g, uint64_t now_us)
{
    dan_dc_node_status_t s;
    uint8_t buf[DAN_DC_NODE_STATUS_MAX_SIZE];
    own_status(g, &s, now_us);
    dan_gwn_drop_own(g, &g->q_urgent, DAN_DC_NODE_STATUS_ID);
    (void)dan_gwn_broadcast(g, &g->q_urgent, DAN_DC_NODE_STATUS_ID, DAN_DC_NODE_STATUS_SIGNATURE,
                            DAN_DC_PRIORITY_LOW, buf,
                            dan_dc_node_status_encode(&s, buf, sizeof buf));
}

static void answer_node_info(dan_gw_node_t *g, const dan_dc_transfer_t *req, uint64_t now_us)
{
    dan_dc_get_node_info_rsp_t *rp = &g->scratch.info;
    size_t nl = strlen(g->cfg.name);
    int len;
    memset(rp, 0, sizeof *rp);
    own_status(g, &rp->status, now_us);
    rp->software_version.major = g->cfg.sw_major;
    rp->software_version.minor = g->cfg.sw_minor;
    if (g->cfg.vcs_commit != 0u) {
        rp->software_version.optional_field_flags = DAN_DC_SW_FLAG_VCS_COMMIT;
        rp->software_version.vcs_commit = g->cfg.vcs_commit;
    }
    rp->hardware_version.major = g->cfg.hw_major;
    rp->hardware_version.minor = g->cfg.hw_minor;
    memcpy(rp->hardware_version.unique_id, g->cfg.unique_id, DAN_DC_UNIQUE_ID_SIZE);
    if (nl > DAN_DC_GET_NODE_INFO_NAME_MAX) {
        nl = DAN_DC_GET_NODE_INFO_NAME_MAX;
    }
    rp->name_len = (uint8_t)nl;
    memcpy(rp->name, g->cfg.name, nl);
    len = dan_dc_get_node_info_rsp_encode(rp, g->scratch_buf, sizeof g->scratch_buf);
    (void)dan_gwn_respond(g, req, DAN_DC_GET_NODE_INFO_SIGNATURE, g->scratch_buf, len);
}

/* ---- CAN input ---- */

static void on_broadcast(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    switch (t->data_type_id) {
    case DAN_DC_NODE_STATUS_ID: dan_gwn_on_node_status(g, t, now_us); break;
    case DAN_DC_ESC_STATUS_ID: dan_gwn_on_esc_status(g, t, now_us); break;
    case DAN_DC_ESC_STATUS_EXTENDED_ID: dan_gwn_on_esc_ext(g, t, now_us); break;
    case DAN_DC_TUNNEL_TARGETTED_ID: dan_gwn_on_targetted(g, t); break;
    case DAN_DC_TUNNEL_BROADCAST_ID: dan_gwn_on_tun_broadcast(g, t); break;
    case DAN_DC_ALLOCATION_ID: dan_gwn_on_allocation(g, t, now_us); break;
    case DAN_DC_TEMPERATURE_ID: dan_gwn_on_temperature(g, t, now_us); break;
    default: break;
    }
}

void dan_gw_node_rx_can(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us)
{
    g->stats.can_rx++;
    if (f->flags & DAN_CAN_ERR) {
        g->stats.can_errors++;
        /* Bus-off: nothing we send arrives; tell the FC (flags bit2). */
        if ((f->id & DAN_CAN_ERRCLASS_BUSOFF) != 0u) {
            g->can_ok = false;
        } else if ((f->id & DAN_CAN_ERRCLASS_RESTARTED) != 0u) {
            g->can_ok = true;
        }
        return;
    }
    dan_gwn_raw_in(g, f, now_us);
    dan_gwn_hear(g, f, now_us);
}

void dan_gwn_hear(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us)
{
    dan_dc_transfer_t t;
    if (dan_dc_rx_frame(&g->rx, f, now_us, &t) != 1) {
        return;
    }
    if (t.transfer_type == DAN_DC_TRANSFER_BROADCAST) {
        on_broadcast(g, &t, now_us);
    } else if (t.transfer_type == DAN_DC_TRANSFER_REQUEST &&
               t.data_type_id != DAN_DC_GET_NODE_INFO_ID) {
        dan_gwn_on_file_request(g, &t, now_us);
    } else if (t.data_type_id == DAN_DC_GET_NODE_INFO_ID) {
        if (t.transfer_type == DAN_DC_TRANSFER_REQUEST) {
            answer_node_info(g, &t, now_us);
        } else {
            dan_gwn_on_node_info_rsp(g, &t);
        }
    } else {
        dan_gwn_on_call_response(g, &t, now_us);
    }
}

/* ---- timers ---- */

void dan_gw_node_poll(dan_gw_node_t *g, uint64_t now_us)
{
    if (now_us >= g->status_due_us) {
        send_node_status(g, now_us);
        g->status_due_us = now_us + DAN_GW_NODE_STATUS_US;
    }
    dan_gwn_esc_poll(g, now_us);
    dan_gwn_servos_poll(g, now_us); /* before the ArmingStatus tick it repeats with */
    dan_gwn_arming_poll(g, now_us);
    dan_gwn_table_poll(g, now_us);
    dan_gwn_tunnel_poll(g, now_us);
    dan_gwn_calls_poll(g, now_us);
    dan_gwn_file_poll(g, now_us);
    dan_gwn_dna_poll(g);
    dan_dc_rx_cleanup(&g->rx, now_us);
}

uint64_t dan_gw_node_next_us(const dan_gw_node_t *g, uint64_t now_us)
{
    uint64_t t = g->status_due_us < g->arming.due_us ? g->status_due_us : g->arming.due_us;
    t = dan_gwn_esc_next_us(g, t);
    t = dan_gwn_servos_next_us(g, t);
    t = dan_gwn_table_next_us(g, t);
    t = dan_gwn_tunnel_next_us(g, now_us, t);
    t = dan_gwn_calls_next_us(g, t);
    t = dan_gwn_file_next_us(g, now_us, t);
    if (g->dna.dirty) {
        t = now_us;
    }
    return t < now_us ? now_us : t;
}
