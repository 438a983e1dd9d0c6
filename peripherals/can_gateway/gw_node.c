/* The CAN-over-DAN gateway node (see gateway.h). */
#include <string.h>

#include "dan/codes.h"
#include "dan/can_gw/node.h"

#if (DAN_GW_NODE_TUN_TX_BUF & (DAN_GW_NODE_TUN_TX_BUF - 1u)) != 0u || \
    (DAN_GW_NODE_TUN_RX_BUF & (DAN_GW_NODE_TUN_RX_BUF - 1u)) != 0u
#error "tunnel buffer sizes must be powers of two (offsets wrap at 2^32)"
#endif

/* Frames of the largest transfer we send (GetNodeInfo response). */
#define MAX_XFER_FRAMES ((DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE + 2u + 6u) / 7u)

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
}

static bool accept_cb(void *user, uint16_t dtid, uint8_t ttype, uint8_t src, uint64_t *sig)
{
    (void)user;
    (void)src;
    if (ttype == DAN_DC_TRANSFER_BROADCAST) {
        switch (dtid) {
        case DAN_DC_NODE_STATUS_ID:
        case DAN_DC_ESC_STATUS_ID:
        case DAN_DC_ESC_STATUS_EXTENDED_ID:
        case DAN_DC_TUNNEL_TARGETTED_ID:
        case DAN_DC_TUNNEL_BROADCAST_ID:
            break;
        default:
            return false;
        }
    } else if (dtid != DAN_DC_GET_NODE_INFO_ID) {
        return false;
    }
    return dan_dc_dsdl_signature(ttype, dtid, sig);
}

static uint64_t arming_period_us(const dan_gw_node_t *g)
{
    return 1000000u / (g->cfg.arming_rate_hz ? g->cfg.arming_rate_hz : 1u);
}

int dan_gw_node_init(dan_gw_node_t *g, const dan_gw_node_config_t *cfg, uint64_t now_us)
{
    dan_gw_node_config_t def;
    if (cfg == NULL) {
        dan_gw_node_config_default(&def);
        cfg = &def;
    }
    if (cfg->node_id < 1u || cfg->node_id > DAN_DC_NODE_ID_MAX ||
        cfg->esc_timeout_ms < DAN_GW_ESC_TIMEOUT_MIN || cfg->esc_timeout_ms > DAN_GW_ESC_TIMEOUT_MAX ||
        cfg->arming_rate_hz < DAN_GW_ARMING_RATE_MIN || cfg->arming_rate_hz > DAN_GW_ARMING_RATE_MAX) {
        return DAN_ERR_ARG;
    }
    memset(g, 0, sizeof *g);
    g->cfg = *cfg;
    g->raw_first = cfg->raw_seq_start;
    if (g->cfg.name == NULL) {
        g->cfg.name = DAN_GW_NODE_NAME;
    }
    g->identity = default_identity;
    dan_dc_rx_init(&g->rx, cfg->node_id, accept_cb, g);
    dan_dc_tid_table_init(&g->tids);
    g->start_us = now_us;
    g->status_due_us = now_us;
    g->arming_due_us = now_us;
    g->can_ok = true;
    g->rr = DAN_GW_NONE;
    return DAN_OK;
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
    return (uint8_t)((g->arming != 0u ? DAN_GW_FLAG_ARMED : 0u) |
                     (g->failsafe ? DAN_GW_FLAG_FAILSAFE : 0u) |
                     (g->can_ok ? DAN_GW_FLAG_CAN_OK : 0u));
}

int dan_gw_node_set_esc_timeout(dan_gw_node_t *g, uint32_t ms)
{
    if (ms < DAN_GW_ESC_TIMEOUT_MIN || ms > DAN_GW_ESC_TIMEOUT_MAX) {
        return DAN_ERR_ARG;
    }
    g->cfg.esc_timeout_ms = ms;
    return DAN_OK;
}

int dan_gw_node_set_arming_rate(dan_gw_node_t *g, uint32_t hz, uint64_t now_us)
{
    if (hz < DAN_GW_ARMING_RATE_MIN || hz > DAN_GW_ARMING_RATE_MAX) {
        return DAN_ERR_ARG;
    }
    g->cfg.arming_rate_hz = hz;
    g->arming_due_us = now_us;
    return DAN_OK;
}

/* ---- CAN output ---- */

static size_t txq_free(const dan_gw_node_txq_t *q)
{
    return DAN_GW_NODE_TXQ - q->len;
}

static void txq_push(dan_gw_node_txq_t *q, const dan_can_frame_t *f)
{
    q->f[(q->head + q->len) % DAN_GW_NODE_TXQ] = *f;
    q->len++;
}

bool dan_gw_node_tx_peek(const dan_gw_node_t *g, dan_can_frame_t *f)
{
    const dan_gw_node_txq_t *q = g->q_urgent.len > 0u ? &g->q_urgent : &g->q_bulk;
    if (q->len == 0u) {
        return false;
    }
    *f = q->f[q->head];
    return true;
}

void dan_gw_node_tx_pop(dan_gw_node_t *g)
{
    dan_gw_node_txq_t *q = g->q_urgent.len > 0u ? &g->q_urgent : &g->q_bulk;
    if (q->len > 0u) {
        q->head = (uint16_t)((q->head + 1u) % DAN_GW_NODE_TXQ);
        q->len--;
    }
}

size_t dan_gw_node_tx_pending(const dan_gw_node_t *g)
{
    return (size_t)g->q_urgent.len + g->q_bulk.len;
}

/* Removes our own unsent broadcasts of one data type from q. Throttle,
 * arming and our status are states: only the newest matters, and an old
 * one waiting behind a stalled bus must never go out after a newer one
 * (nor crowd out the failsafe's zeros). A transfer cut in the middle is
 * dropped by its receivers, which then take the new one. */
static void txq_drop_own(dan_gw_node_t *g, dan_gw_node_txq_t *q, uint16_t dtid)
{
    size_t i, kept = 0, n = q->len;
    for (i = 0; i < n; i++) {
        dan_can_frame_t f = q->f[(q->head + i) % DAN_GW_NODE_TXQ];
        dan_dc_transfer_t id;
        bool ours = (f.flags & DAN_CAN_EXT) != 0u && dan_dc_parse_id(f.id, &id) == DAN_OK &&
                    id.transfer_type == DAN_DC_TRANSFER_BROADCAST && id.data_type_id == dtid &&
                    id.source_node == g->cfg.node_id;
        if (!ours) {
            q->f[(q->head + kept) % DAN_GW_NODE_TXQ] = f;
            kept++;
        }
    }
    q->len = (uint16_t)kept;
}

/* Queues one transfer whole, or drops it whole (counted). */
static int send_transfer(dan_gw_node_t *g, dan_gw_node_txq_t *q, dan_dc_transfer_t *t)
{
    dan_can_frame_t frames[MAX_XFER_FRAMES];
    int n, i;
    t->source_node = g->cfg.node_id;
    n = dan_dc_tx_build(t, frames, MAX_XFER_FRAMES);
    if (n < 0) {
        return n;
    }
    if ((size_t)n > txq_free(q)) {
        g->stats.can_tx_dropped += (uint32_t)n;
        return DAN_ERR_OVERFLOW;
    }
    for (i = 0; i < n; i++) {
        txq_push(q, &frames[i]);
    }
    g->stats.can_tx += (uint32_t)n;
    return DAN_OK;
}

static int broadcast(dan_gw_node_t *g, dan_gw_node_txq_t *q, uint16_t dtid, uint64_t sig,
                     uint8_t prio, const uint8_t *payload, int len)
{
    dan_dc_transfer_t t;
    int tid;
    if (len < 0) {
        return len;
    }
    tid = dan_dc_tid_next(&g->tids, dtid, DAN_DC_TRANSFER_BROADCAST, 0);
    if (tid < 0) {
        return tid;
    }
    memset(&t, 0, sizeof t);
    t.signature = sig;
    t.payload = payload;
    t.payload_len = (size_t)len;
    t.data_type_id = dtid;
    t.transfer_type = DAN_DC_TRANSFER_BROADCAST;
    t.priority = prio;
    t.transfer_id = (uint8_t)tid;
    return send_transfer(g, q, &t);
}

static void send_raw_command(dan_gw_node_t *g, const int16_t *v, size_t n)
{
    dan_dc_esc_raw_command_t m;
    uint8_t buf[DAN_DC_ESC_RAW_COMMAND_MAX_SIZE];
    memset(&m, 0, sizeof m);
    m.count = (uint8_t)n;
    if (v != NULL) {
        memcpy(m.cmd, v, n * sizeof v[0]);
    }
    txq_drop_own(g, &g->q_urgent, DAN_DC_ESC_RAW_COMMAND_ID); /* latest wins */
    (void)broadcast(g, &g->q_urgent, DAN_DC_ESC_RAW_COMMAND_ID, DAN_DC_ESC_RAW_COMMAND_SIGNATURE,
                    DAN_DC_PRIORITY_HIGH, buf, dan_dc_esc_raw_command_encode(&m, buf, sizeof buf));
}

static void send_arming(dan_gw_node_t *g, uint64_t now_us)
{
    dan_dc_arming_status_t m;
    uint8_t buf[DAN_DC_ARMING_STATUS_MAX_SIZE];
    m.status = g->arming;
    txq_drop_own(g, &g->q_urgent, DAN_DC_ARMING_STATUS_ID);
    (void)broadcast(g, &g->q_urgent, DAN_DC_ARMING_STATUS_ID, DAN_DC_ARMING_STATUS_SIGNATURE,
                    DAN_DC_PRIORITY_MEDIUM, buf, dan_dc_arming_status_encode(&m, buf, sizeof buf));
    g->arming_due_us = now_us + arming_period_us(g);
}

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
    txq_drop_own(g, &g->q_urgent, DAN_DC_NODE_STATUS_ID);
    (void)broadcast(g, &g->q_urgent, DAN_DC_NODE_STATUS_ID, DAN_DC_NODE_STATUS_SIGNATURE,
                    DAN_DC_PRIORITY_LOW, buf, dan_dc_node_status_encode(&s, buf, sizeof buf));
}

void dan_gw_node_failsafe(dan_gw_node_t *g, uint64_t now_us)
{
    static const int16_t zeros[DAN_GW_ESC_MAX] = {0};
    if (g->esc_active && g->esc_n > 0u) {
        send_raw_command(g, zeros, g->esc_n);
    }
    g->arming = DAN_DC_ARMING_STATUS_DISARMED;
    send_arming(g, now_us);
}

/* ---- CAN input ---- */

static dan_gw_node_slot_t *find_node(dan_gw_node_t *g, uint8_t id)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        if (g->nodes[i].e.node_id == id) {
            return &g->nodes[i];
        }
    }
    return NULL;
}

static void on_node_status(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_node_status_t s;
    dan_gw_node_slot_t *n;
    if (t->source_node == 0u || dan_dc_node_status_decode(&s, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    n = find_node(g, t->source_node);
    if (n == NULL) {
        n = find_node(g, 0);
        if (n == NULL) {
            /* Full: a node silent past DroneCAN's offline timeout gives
             * its slot to the new one (the longest silent first). */
            size_t i;
            for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
                dan_gw_node_slot_t *c = &g->nodes[i];
                if (now_us - c->seen_us > DAN_GW_NODE_OFFLINE_US && (n == NULL || c->seen_us < n->seen_us)) {
                    n = c;
                }
            }
        }
        if (n == NULL) {
            g->stats.nodes_dropped++;
            return;
        }
        memset(n, 0, sizeof *n);
        n->e.node_id = t->source_node;
        n->info_due_us = now_us;
    } else if (s.uptime_sec < n->e.uptime_sec) {
        /* restarted: its software may have changed */
        n->e.info_state = DAN_GW_INFO_NONE;
        n->info_tries = 0;
        n->info_due_us = now_us;
    }
    n->e.health = s.health;
    n->e.mode = s.mode;
    n->e.sub_mode = s.sub_mode;
    n->e.uptime_sec = s.uptime_sec;
    n->e.vendor_status = s.vendor_specific_status_code;
    n->seen_us = now_us;
}

static void on_node_info_rsp(dan_gw_node_t *g, const dan_dc_transfer_t *t)
{
    dan_dc_get_node_info_rsp_t *rp = &g->scratch.info;
    dan_gw_node_slot_t *n = find_node(g, t->source_node);
    size_t len;
    if (n == NULL || dan_dc_get_node_info_rsp_decode(rp, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    n->info.node_id = n->e.node_id;
    n->info.info_state = DAN_GW_INFO_VALID;
    n->info.sw_major = rp->software_version.major;
    n->info.sw_minor = rp->software_version.minor;
    n->info.sw_flags = rp->software_version.optional_field_flags;
    n->info.vcs_commit = rp->software_version.vcs_commit;
    n->info.hw_major = rp->hardware_version.major;
    n->info.hw_minor = rp->hardware_version.minor;
    memcpy(n->info.unique_id, rp->hardware_version.unique_id, 16);
    len = rp->name_len > DAN_DC_GET_NODE_INFO_NAME_MAX ? DAN_DC_GET_NODE_INFO_NAME_MAX : rp->name_len;
    memcpy(n->info.name, rp->name, len);
    n->info.name[len] = '\0';
    n->e.info_state = DAN_GW_INFO_VALID;
}

static void answer_node_info(dan_gw_node_t *g, const dan_dc_transfer_t *req, uint64_t now_us)
{
    dan_dc_get_node_info_rsp_t *rp = &g->scratch.info;
    uint8_t *buf = g->scratch_buf;
    dan_dc_transfer_t t;
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
    memcpy(rp->hardware_version.unique_id, g->cfg.unique_id, 16);
    if (nl > DAN_DC_GET_NODE_INFO_NAME_MAX) {
        nl = DAN_DC_GET_NODE_INFO_NAME_MAX;
    }
    rp->name_len = (uint8_t)nl;
    memcpy(rp->name, g->cfg.name, nl);
    len = dan_dc_get_node_info_rsp_encode(rp, buf, sizeof g->scratch_buf);
    if (len < 0) {
        return;
    }
    memset(&t, 0, sizeof t);
    t.signature = DAN_DC_GET_NODE_INFO_SIGNATURE;
    t.payload = buf;
    t.payload_len = (size_t)len;
    t.data_type_id = DAN_DC_GET_NODE_INFO_ID;
    t.transfer_type = DAN_DC_TRANSFER_RESPONSE;
    t.priority = req->priority;
    t.destination_node = req->source_node;
    t.transfer_id = req->transfer_id;
    (void)send_transfer(g, &g->q_bulk, &t);
}

static void on_esc_status(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_esc_status_t s;
    dan_gw_node_esc_t *e;
    if (dan_dc_esc_status_decode(&s, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    e = &g->esc[s.esc_index % DAN_GW_NODE_ESC_SLOTS];
    e->t.esc_index = s.esc_index;
    e->t.node_id = t->source_node;
    e->t.flags |= DAN_GW_TELEM_STATUS;
    e->t.voltage_f16 = s.voltage_f16;
    e->t.current_f16 = s.current_f16;
    e->t.temperature_f16 = s.temperature_f16;
    e->t.rpm = s.rpm;
    e->t.power_pct = s.power_rating_pct;
    e->t.error_count = s.error_count;
    e->status_us = now_us;
}

static void on_esc_ext(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_esc_status_extended_t s;
    dan_gw_node_esc_t *e;
    if (dan_dc_esc_status_extended_decode(&s, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    e = &g->esc[s.esc_index % DAN_GW_NODE_ESC_SLOTS];
    e->t.esc_index = s.esc_index;
    e->t.node_id = t->source_node;
    e->t.flags |= DAN_GW_TELEM_EXT;
    e->t.input_pct = s.input_pct;
    e->t.output_pct = s.output_pct;
    e->t.motor_temp_c = s.motor_temperature_degC;
    e->t.motor_angle = s.motor_angle;
    e->t.status_flags = s.status_flags;
    e->ext_us = now_us;
}

/* Appends received tunnel bytes; what does not fit is dropped (counted). */
static void tun_in(dan_gw_node_t *g, dan_gw_node_tun_t *p, const uint8_t *d, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        if (p->rd_end - p->rd_base >= DAN_GW_NODE_TUN_RX_BUF) {
            p->rd_dropped += (uint32_t)(n - i);
            g->stats.tun_dropped += (uint32_t)(n - i);
            return;
        }
        p->rx[p->rd_end % DAN_GW_NODE_TUN_RX_BUF] = d[i];
        p->rd_end++;
    }
}

static void on_targetted(dan_gw_node_t *g, const dan_dc_transfer_t *t)
{
    dan_dc_tunnel_targetted_t *mp = &g->scratch.targetted;
    size_t i;
    if (dan_dc_tunnel_targetted_decode(mp, t->payload, t->payload_len) != DAN_OK ||
        mp->target_node != g->cfg.node_id) {
        return;
    }
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        dan_gw_node_tun_t *p = &g->tun[i];
        if (p->cfg.mode == DAN_GW_TUN_TARGETTED && p->cfg.target == t->source_node &&
            p->cfg.serial_id == mp->serial_id) {
            tun_in(g, p, mp->buffer, mp->buffer_len);
            return;
        }
    }
}

static void on_tun_broadcast(dan_gw_node_t *g, const dan_dc_transfer_t *t)
{
    dan_dc_tunnel_broadcast_t *mp = &g->scratch.bcast;
    size_t i;
    if (dan_dc_tunnel_broadcast_decode(mp, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        dan_gw_node_tun_t *p = &g->tun[i];
        if (p->cfg.mode == DAN_GW_TUN_BROADCAST && p->cfg.protocol == mp->protocol &&
            p->cfg.target == mp->channel_id) {
            tun_in(g, p, mp->buffer, mp->buffer_len);
        }
    }
}

static void raw_in(dan_gw_node_t *g, const dan_can_frame_t *f)
{
    size_t i;
    for (i = 0; i < g->nfilters; i++) {
        if (dan_gw_filter_match(&g->filters[i], f)) {
            break;
        }
    }
    if (i == g->nfilters) {
        return;
    }
    if (g->raw_len >= DAN_GW_NODE_RAW_RX) {
        g->stats.raw_dropped++;
        return;
    }
    g->raw[(g->raw_head + g->raw_len) % DAN_GW_NODE_RAW_RX] = *f;
    g->raw_len++;
}

void dan_gw_node_rx_can(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us)
{
    dan_dc_transfer_t t;
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
    raw_in(g, f);
    if (dan_dc_rx_frame(&g->rx, f, now_us, &t) != 1) {
        return;
    }
    if (t.transfer_type == DAN_DC_TRANSFER_BROADCAST) {
        switch (t.data_type_id) {
        case DAN_DC_NODE_STATUS_ID:
            on_node_status(g, &t, now_us);
            break;
        case DAN_DC_ESC_STATUS_ID:
            on_esc_status(g, &t, now_us);
            break;
        case DAN_DC_ESC_STATUS_EXTENDED_ID:
            on_esc_ext(g, &t, now_us);
            break;
        case DAN_DC_TUNNEL_TARGETTED_ID:
            on_targetted(g, &t);
            break;
        case DAN_DC_TUNNEL_BROADCAST_ID:
            on_tun_broadcast(g, &t);
            break;
        default:
            break;
        }
    } else if (t.data_type_id == DAN_DC_GET_NODE_INFO_ID) {
        if (t.transfer_type == DAN_DC_TRANSFER_REQUEST) {
            answer_node_info(g, &t, now_us);
        } else {
            on_node_info_rsp(g, &t);
        }
    }
}

/* ---- timers ---- */

static void request_info(dan_gw_node_t *g, dan_gw_node_slot_t *n, uint64_t now_us)
{
    dan_dc_transfer_t t;
    memset(&t, 0, sizeof t);
    t.signature = DAN_DC_GET_NODE_INFO_SIGNATURE;
    t.data_type_id = DAN_DC_GET_NODE_INFO_ID;
    t.transfer_type = DAN_DC_TRANSFER_REQUEST;
    t.priority = DAN_DC_PRIORITY_LOW;
    t.destination_node = n->e.node_id;
    t.transfer_id = n->info_tid;
    if (send_transfer(g, &g->q_bulk, &t) == DAN_OK) {
        n->info_tid = (uint8_t)((n->info_tid + 1u) & DAN_DC_TRANSFER_ID_MASK);
        g->stats.info_requests++;
    }
    n->info_tries++;
    n->e.info_state = DAN_GW_INFO_PENDING;
    n->info_due_us = now_us + DAN_GW_NODE_INFO_RETRY_US;
}

/* Sends one chunk (or a Targetted keepalive). Returns true if a transfer
 * was queued. */
static bool tun_out(dan_gw_node_t *g, dan_gw_node_tun_t *p, uint64_t now_us)
{
    uint8_t buf[DAN_DC_TUNNEL_TARGETTED_MAX_SIZE];
    uint32_t start = p->wr_next - p->tx_len;
    size_t n, i;
    int rc;
    if (p->cfg.mode == DAN_GW_TUN_TARGETTED) {
        dan_dc_tunnel_targetted_t *m = &g->scratch.targetted;
        n = p->tx_len > DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX ? DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX
                                                           : p->tx_len;
        if (n == 0u && now_us - p->last_tx_us < DAN_GW_NODE_KEEPALIVE_US) {
            return false;
        }
        memset(m, 0, sizeof *m);
        m->protocol = p->cfg.protocol;
        m->target_node = p->cfg.target;
        m->serial_id = p->cfg.serial_id;
        m->options = p->cfg.options;
        m->baudrate = p->cfg.baud;
        m->buffer_len = (uint8_t)n;
        for (i = 0; i < n; i++) {
            m->buffer[i] = p->tx[(start + i) % DAN_GW_NODE_TUN_TX_BUF];
        }
        rc = broadcast(g, &g->q_bulk, DAN_DC_TUNNEL_TARGETTED_ID, DAN_DC_TUNNEL_TARGETTED_SIGNATURE,
                       DAN_DC_PRIORITY_MEDIUM, buf,
                       dan_dc_tunnel_targetted_encode(m, buf, sizeof buf));
    } else {
        dan_dc_tunnel_broadcast_t *m = &g->scratch.bcast;
        n = p->tx_len > DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX ? DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX
                                                           : p->tx_len;
        if (n == 0u) {
            return false;
        }
        m->protocol = p->cfg.protocol;
        m->channel_id = p->cfg.target;
        m->buffer_len = (uint8_t)n;
        for (i = 0; i < n; i++) {
            m->buffer[i] = p->tx[(start + i) % DAN_GW_NODE_TUN_TX_BUF];
        }
        rc = broadcast(g, &g->q_bulk, DAN_DC_TUNNEL_BROADCAST_ID, DAN_DC_TUNNEL_BROADCAST_SIGNATURE,
                       DAN_DC_PRIORITY_MEDIUM, buf,
                       dan_dc_tunnel_broadcast_encode(m, buf, sizeof buf));
    }
    if (rc != DAN_OK) {
        return false;
    }
    p->tx_len -= (uint32_t)n;
    p->last_tx_us = now_us;
    return n > 0u;
}

void dan_gw_node_poll(dan_gw_node_t *g, uint64_t now_us)
{
    static const int16_t zeros[DAN_GW_ESC_MAX] = {0};
    size_t i;
    if (now_us >= g->status_due_us) {
        send_node_status(g, now_us);
        g->status_due_us = now_us + DAN_GW_NODE_STATUS_US;
    }
    if (g->esc_active && !g->failsafe &&
        now_us - g->last_cmd_us > (uint64_t)g->cfg.esc_timeout_ms * 1000u) {
        g->failsafe = true;
        g->stats.failsafes++;
        g->arming = DAN_DC_ARMING_STATUS_DISARMED;
        send_raw_command(g, zeros, g->esc_n);
        send_arming(g, now_us);
    }
    if (now_us >= g->arming_due_us) {
        if (g->failsafe) {
            send_raw_command(g, zeros, g->esc_n); /* keep the motors stopped */
        }
        send_arming(g, now_us);
    }
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        dan_gw_node_slot_t *n = &g->nodes[i];
        if (n->e.node_id == 0u || n->e.info_state == DAN_GW_INFO_VALID ||
            n->e.info_state == DAN_GW_INFO_FAILED || now_us < n->info_due_us) {
            continue;
        }
        if (n->info_tries >= DAN_GW_NODE_INFO_TRIES) {
            n->e.info_state = DAN_GW_INFO_FAILED;
        } else {
            request_info(g, n, now_us);
        }
    }
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        dan_gw_node_tun_t *p = &g->tun[i];
        /* chunks while the bulk queue has room for a whole one (a full
         * Targetted transfer is 19 frames); the queue is the flow control */
        while (p->cfg.mode != DAN_GW_TUN_CLOSED && txq_free(&g->q_bulk) >= 19u &&
               tun_out(g, p, now_us) && p->tx_len > 0u) {
        }
    }
    dan_dc_rx_cleanup(&g->rx, now_us);
}

uint64_t dan_gw_node_next_us(const dan_gw_node_t *g, uint64_t now_us)
{
    uint64_t t = g->status_due_us < g->arming_due_us ? g->status_due_us : g->arming_due_us;
    size_t i;
    if (g->esc_active && !g->failsafe) {
        uint64_t fs = g->last_cmd_us + (uint64_t)g->cfg.esc_timeout_ms * 1000u + 1u;
        if (fs < t) {
            t = fs;
        }
    }
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        const dan_gw_node_slot_t *n = &g->nodes[i];
        if (n->e.node_id != 0u && (n->e.info_state == DAN_GW_INFO_NONE ||
                                   n->e.info_state == DAN_GW_INFO_PENDING) &&
            n->info_due_us < t) {
            t = n->info_due_us;
        }
    }
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        const dan_gw_node_tun_t *p = &g->tun[i];
        if (p->cfg.mode == DAN_GW_TUN_CLOSED) {
            continue;
        }
        if (p->tx_len > 0u) {
            t = now_us; /* waits for queue room: the caller's CAN output paces it */
        } else if (p->cfg.mode == DAN_GW_TUN_TARGETTED &&
                   p->last_tx_us + DAN_GW_NODE_KEEPALIVE_US < t) {
            t = p->last_tx_us + DAN_GW_NODE_KEEPALIVE_US;
        }
    }
    return t < now_us ? now_us : t;
}

/* ---- DAN handlers ---- */

static dan_gw_node_t *touch(void *user, uint64_t now_us)
{
    dan_gw_node_t *g = (dan_gw_node_t *)user;
    g->last_dan_us = now_us ? now_us : 1u;
    g->stats.dan_requests++;
    return g;
}

static int emit(dan_writer_t *w, int n)
{
    if (n < 0) {
        return n;
    }
    w->len = (size_t)n;
    return DAN_OK;
}

static uint32_t age_ms(uint64_t now_us, uint64_t then_us)
{
    uint64_t ms = (now_us - then_us) / 1000u;
    return ms > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)ms;
}

static const dan_gw_telem_t *telem_of(dan_gw_node_t *g, size_t idx, uint64_t now_us)
{
    dan_gw_node_esc_t *e = &g->esc[idx];
    if (e->t.flags == 0u) {
        return NULL;
    }
    e->t.age_ms = (e->t.flags & DAN_GW_TELEM_STATUS) ? age_ms(now_us, e->status_us) : 0u;
    e->t.ext_age_ms = (e->t.flags & DAN_GW_TELEM_EXT) ? age_ms(now_us, e->ext_us) : 0u;
    return &e->t;
}

static uint8_t esc_seen(const dan_gw_node_t *g)
{
    size_t i;
    uint8_t n = 0;
    for (i = 0; i < DAN_GW_NODE_ESC_SLOTS; i++) {
        n = (uint8_t)(n + (g->esc[i].t.flags != 0u));
    }
    return n;
}

static int h_esc_cmd(void *user, uint32_t code, const uint8_t *req, size_t len,
                     dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    int16_t v[DAN_GW_ESC_MAX];
    size_t n, i;
    dan_gw_telem_hdr_t h;
    const dan_gw_telem_t *t = NULL;
    (void)code;
    if (dan_gw_msg_esc_cmd_decode(req, len, v, &n) != DAN_OK) {
        *err = "bad ESC command";
        return DAN_ERR_MALFORMED;
    }
    send_raw_command(g, v, n);
    g->stats.esc_cmds++;
    g->esc_active = true;
    g->failsafe = false;
    g->esc_n = (uint8_t)n;
    g->last_cmd_us = now_us;
    /* the next ESC seen after the last one reported */
    for (i = 1; i <= DAN_GW_NODE_ESC_SLOTS && t == NULL; i++) {
        size_t idx = ((size_t)g->rr + i) % DAN_GW_NODE_ESC_SLOTS;
        t = telem_of(g, idx, now_us);
        if (t != NULL) {
            g->rr = (uint8_t)idx;
        }
    }
    h.gw_flags = dan_gw_node_flags(g);
    h.aux = esc_seen(g);
    h.count = t != NULL ? 1u : 0u;
    dan_gw_msg_telem_hdr_put(resp, &h);
    if (t != NULL) {
        dan_gw_msg_telem_put(resp, t);
    }
    return DAN_OK;
}

/* Size of one item, by a counting writer. */
static size_t telem_size(const dan_gw_telem_t *t)
{
    dan_writer_t w;
    dan_writer_init(&w, NULL, 0);
    dan_gw_msg_telem_put(&w, t);
    return w.len;
}

static int h_esc_telem(void *user, uint32_t code, const uint8_t *req, size_t len,
                       dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_telem_hdr_t h;
    size_t i, room;
    (void)code;
    if (len < 1u) {
        *err = "missing first index";
        return DAN_ERR_MALFORMED;
    }
    h.gw_flags = dan_gw_node_flags(g);
    h.aux = DAN_GW_NONE;
    h.count = 0;
    room = resp->cap - 3u;
    for (i = req[0]; i < DAN_GW_NODE_ESC_SLOTS; i++) {
        const dan_gw_telem_t *t = telem_of(g, i, now_us);
        if (t != NULL) {
            size_t sz = telem_size(t);
            if (sz > room) {
                h.aux = (uint8_t)i;
                break;
            }
            room -= sz;
            h.count++;
        }
    }
    dan_gw_msg_telem_hdr_put(resp, &h);
    for (i = req[0]; i < DAN_GW_NODE_ESC_SLOTS && (h.aux == DAN_GW_NONE || i < h.aux); i++) {
        const dan_gw_telem_t *t = telem_of(g, i, now_us);
        if (t != NULL) {
            dan_gw_msg_telem_put(resp, t);
        }
    }
    return DAN_OK;
}

static int h_arm(void *user, uint32_t code, const uint8_t *req, size_t len,
                 dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    (void)code;
    if (len < 1u) {
        *err = "missing arming status";
        return DAN_ERR_MALFORMED;
    }
    /* During a failsafe too: an explicit ARM comes from a live master that
     * chose it; the zeros keep repeating until ESC commands resume. */
    if (req[0] != g->arming) {
        g->arming = req[0];
        send_arming(g, now_us); /* at once on a change */
    }
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

static int h_config(void *user, uint32_t code, const uint8_t *req, size_t len,
                    dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_config_t c;
    (void)code;
    if (dan_gw_msg_config_req_decode(&c, req, len) != DAN_OK) {
        *err = "bad config request or value out of range";
        return DAN_ERR_MALFORMED;
    }
    if (c.set_mask & DAN_GW_CFG_ESC_TIMEOUT) {
        (void)dan_gw_node_set_esc_timeout(g, c.esc_timeout_ms);
    }
    if (c.set_mask & DAN_GW_CFG_ARMING_RATE) {
        (void)dan_gw_node_set_arming_rate(g, c.arming_rate_hz, now_us);
    }
    c.node_id = g->cfg.node_id;
    c.esc_timeout_ms = g->cfg.esc_timeout_ms;
    c.arming_rate_hz = g->cfg.arming_rate_hz;
    c.gw_flags = dan_gw_node_flags(g);
    return emit(resp, dan_gw_msg_config_rsp_encode(&c, resp->buf, resp->cap));
}

void dan_gw_node_counters(const dan_gw_node_t *g, uint32_t v[DAN_GW_STAT_COUNT])
{
    size_t i;
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
    v[DAN_GW_STAT_DC_ERRORS] = g->rx.stats.toggle_errors + g->rx.stats.timeouts +
                               g->rx.stats.malformed + g->rx.stats.overflow + g->rx.stats.no_slot;
    v[DAN_GW_STAT_ESC_CMDS] = g->stats.esc_cmds;
    v[DAN_GW_STAT_FAILSAFES] = g->stats.failsafes;
    v[DAN_GW_STAT_FAILSAFE_ACTIVE] = g->failsafe ? 1u : 0u;
    v[DAN_GW_STAT_TUN_DROPPED] = g->stats.tun_dropped;
    v[DAN_GW_STAT_RAW_DROPPED] = g->stats.raw_dropped;
    v[DAN_GW_STAT_BAD_CHECKS] = g->stats.bad_checks;
    v[DAN_GW_STAT_NODES_DROPPED] = g->stats.nodes_dropped;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        v[DAN_GW_STAT_NODES] += g->nodes[i].e.node_id != 0u;
    }
}

static int h_stats(void *user, uint32_t code, const uint8_t *req, size_t len,
                   dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    uint32_t v[DAN_GW_STAT_COUNT];
    (void)code; (void)req; (void)len; (void)err;
    dan_gw_node_counters(g, v);
    return emit(resp, dan_gw_msg_stats_encode(v, DAN_GW_STAT_COUNT, resp->buf, resp->cap));
}

static size_t node_size(const dan_gw_node_entry_t *e)
{
    dan_writer_t w;
    dan_writer_init(&w, NULL, 0);
    dan_gw_msg_node_put(&w, e);
    return w.len;
}

static int h_nodes(void *user, uint32_t code, const uint8_t *req, size_t len,
                   dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_nodes_hdr_t h;
    size_t room = resp->cap - 2u;
    unsigned id, last = 0;
    (void)code;
    if (len < 1u) {
        *err = "missing first node id";
        return DAN_ERR_MALFORMED;
    }
    h.next = 0;
    h.count = 0;
    for (id = req[0] ? req[0] : 1u; id <= DAN_DC_NODE_ID_MAX; id++) {
        dan_gw_node_slot_t *n = find_node(g, (uint8_t)id);
        size_t sz;
        if (n == NULL) {
            continue;
        }
        n->e.age_ms = age_ms(now_us, n->seen_us);
        sz = node_size(&n->e);
        if (sz > room) {
            h.next = (uint8_t)id;
            break;
        }
        room -= sz;
        h.count++;
        last = id;
    }
    dan_gw_msg_nodes_hdr_put(resp, &h);
    for (id = req[0] ? req[0] : 1u; id <= last; id++) {
        dan_gw_node_slot_t *n = find_node(g, (uint8_t)id);
        if (n != NULL) {
            dan_gw_msg_node_put(resp, &n->e);
        }
    }
    return DAN_OK;
}

static int h_node_info(void *user, uint32_t code, const uint8_t *req, size_t len,
                       dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_node_slot_t *n;
    dan_gw_node_info_t tmp;
    (void)code;
    if (len < 1u) {
        *err = "missing node id";
        return DAN_ERR_MALFORMED;
    }
    n = req[0] != 0u ? find_node(g, req[0]) : NULL;
    if (n == NULL) {
        *err = "unknown node";
        return DAN_ERR_NOTFOUND;
    }
    if (n->e.info_state == DAN_GW_INFO_VALID) {
        return emit(resp, dan_gw_msg_node_info_encode(&n->info, resp->buf, resp->cap));
    }
    memset(&tmp, 0, sizeof tmp);
    tmp.node_id = n->e.node_id;
    tmp.info_state = n->e.info_state;
    return emit(resp, dan_gw_msg_node_info_encode(&tmp, resp->buf, resp->cap));
}

static int h_tun_open(void *user, uint32_t code, const uint8_t *req, size_t len,
                      dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_tun_open_t o;
    bool ok;
    (void)code;
    if (dan_gw_msg_tun_open_decode(&o, req, len) != DAN_OK) {
        *err = "bad tunnel open";
        return DAN_ERR_MALFORMED;
    }
    ok = o.port < DAN_GW_NODE_TUNNELS && o.mode <= DAN_GW_TUN_BROADCAST &&
         (o.mode != DAN_GW_TUN_TARGETTED ||
          (o.target >= 1u && o.target <= DAN_DC_NODE_ID_MAX && o.serial_id >= -16 &&
           o.serial_id <= 15 && o.options <= 15u && o.baud <= 0xFFFFFFu));
    if (ok) {
        dan_gw_node_tun_t *p = &g->tun[o.port];
        memset(p, 0, offsetof(dan_gw_node_tun_t, tx)); /* buffers need no clearing */
        p->cfg = o;
        p->last_tx_us = now_us - DAN_GW_NODE_KEEPALIVE_US; /* first keepalive at once */
    }
    dan_put_u8(resp, o.port);
    dan_put_u8(resp, (uint8_t)(ok ? 0u : 1u));
    return DAN_OK;
}

static int h_tun_xfer(void *user, uint32_t code, const uint8_t *req, size_t len,
                      dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_tun_xfer_t x, r;
    dan_gw_node_tun_t *p;
    uint8_t out[DAN_GW_TUN_CHUNK_MAX];
    int32_t skip, ack;
    size_t i, n;
    (void)code;
    if (dan_gw_msg_tun_xfer_req_decode(&x, req, len) != DAN_OK) {
        *err = "bad tunnel transfer";
        return DAN_ERR_MALFORMED;
    }
    if (x.port >= DAN_GW_NODE_TUNNELS || g->tun[x.port].cfg.mode == DAN_GW_TUN_CLOSED) {
        *err = "tunnel port not open";
        return DAN_ERR_NOTFOUND;
    }
    p = &g->tun[x.port];
    /* write: bytes before wr_next are repeats of a retried request */
    skip = dan_gw_off_diff(p->wr_next, x.wr_offset);
    if (skip < 0) {
        *err = "tunnel write leaves a gap";
        return DAN_ERR_MALFORMED;
    }
    for (i = (size_t)skip; i < x.len && p->tx_len < DAN_GW_NODE_TUN_TX_BUF; i++) {
        p->tx[p->wr_next % DAN_GW_NODE_TUN_TX_BUF] = x.data[i];
        p->wr_next++;
        p->tx_len++;
    }
    /* read: the master has every byte before rd_offset */
    ack = dan_gw_off_diff(x.rd_offset, p->rd_base);
    if (ack > 0 && dan_gw_off_diff(p->rd_end, x.rd_offset) >= 0) {
        p->rd_base = x.rd_offset;
    }
    n = p->rd_end - p->rd_base;
    if (n > x.rd_max) {
        n = x.rd_max;
    }
    if (n > DAN_GW_TUN_CHUNK_MAX) {
        n = DAN_GW_TUN_CHUNK_MAX;
    }
    for (i = 0; i < n; i++) {
        out[i] = p->rx[(p->rd_base + i) % DAN_GW_NODE_TUN_RX_BUF];
    }
    memset(&r, 0, sizeof r);
    r.port = x.port;
    r.wr_offset = p->wr_next;
    r.wr_space = DAN_GW_NODE_TUN_TX_BUF - p->tx_len;
    r.rd_offset = p->rd_base;
    r.rd_dropped = p->rd_dropped;
    r.data = out;
    r.len = n;
    return emit(resp, dan_gw_msg_tun_xfer_rsp_encode(&r, resp->buf, resp->cap));
}

static int h_can_send(void *user, uint32_t code, const uint8_t *req, size_t len,
                      dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_reader_t r;
    dan_gw_can_send_t s;
    dan_can_frame_t f[DAN_GW_CAN_FRAMES_MAX];
    size_t i;
    uint16_t digest;
    dan_reader_init(&r, req, len);
    if (dan_gw_msg_can_send_req_get(&r, &s) != DAN_OK) {
        *err = "bad CAN send";
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < s.count; i++) {
        if (dan_gw_msg_can_frame_get(&r, &f[i]) != DAN_OK) {
            *err = "bad CAN frame";
            return DAN_ERR_MALFORMED;
        }
    }
    /* A retry repeats seq and frames; an FC that rebooted may reuse a seq
     * with other frames: those are new. The digest tells them apart. */
    digest = dan_gw_check(code, DAN_GW_REQUEST, req, len);
    if (!g->send_seq_valid || s.seq != g->send_seq || digest != g->send_digest) {
        /* all or nothing, so a refused request can simply be sent again;
         * raw frames queue behind throttle and arming (the bulk queue) */
        g->send_accepted = 0;
        if (txq_free(&g->q_bulk) >= s.count) {
            for (i = 0; i < s.count; i++) {
                txq_push(&g->q_bulk, &f[i]);
            }
            g->stats.can_tx += s.count;
            g->send_accepted = s.count;
            g->send_seq = s.seq;
            g->send_digest = digest;
            g->send_seq_valid = true;
        } else {
            g->stats.can_tx_dropped += s.count;
        }
    }
    s.count = g->send_accepted;
    s.queue_free = (uint32_t)txq_free(&g->q_bulk);
    return emit(resp, dan_gw_msg_can_send_rsp_encode(&s, resp->buf, resp->cap));
}

static int h_can_recv(void *user, uint32_t code, const uint8_t *req, size_t len,
                      dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_gw_can_recv_t q, a;
    int32_t ack;
    size_t i;
    (void)code;
    if (dan_gw_msg_can_recv_req_decode(&q, req, len) != DAN_OK) {
        *err = "bad CAN receive";
        return DAN_ERR_MALFORMED;
    }
    ack = dan_gw_off_diff(q.seq, g->raw_first);
    if (ack > 0 && ack <= (int32_t)g->raw_len) {
        g->raw_head = (uint16_t)((g->raw_head + (uint32_t)ack) % DAN_GW_NODE_RAW_RX);
        g->raw_len = (uint16_t)(g->raw_len - (uint32_t)ack);
        g->raw_first += (uint32_t)ack;
    }
    a.seq = g->raw_first;
    a.dropped = g->stats.raw_dropped;
    a.count = 0;
    {
        size_t room = resp->cap - 11u; /* header at its largest */
        for (i = 0; i < g->raw_len && a.count < q.count && a.count < DAN_GW_CAN_FRAMES_MAX; i++) {
            const dan_can_frame_t *f = &g->raw[(g->raw_head + i) % DAN_GW_NODE_RAW_RX];
            size_t sz = 5u + ((f->flags & DAN_CAN_RTR) ? 0u : f->dlc);
            if (sz > room) {
                break;
            }
            room -= sz;
            a.count++;
        }
    }
    dan_gw_msg_can_recv_rsp_put(resp, &a);
    for (i = 0; i < a.count; i++) {
        dan_gw_msg_can_frame_put(resp, &g->raw[(g->raw_head + i) % DAN_GW_NODE_RAW_RX]);
    }
    return DAN_OK;
}

static int h_can_filter(void *user, uint32_t code, const uint8_t *req, size_t len,
                        dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = touch(user, now_us);
    dan_reader_t r;
    dan_gw_filter_t f[DAN_GW_FILTERS_MAX];
    uint8_t op, count, result = 0;
    size_t i, j;
    (void)code;
    dan_reader_init(&r, req, len);
    if (dan_gw_msg_filter_hdr_get(&r, &op, &count) != DAN_OK || op > DAN_GW_FILTER_READ) {
        *err = "bad filter request";
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < count; i++) {
        if (dan_gw_msg_filter_get(&r, &f[i]) != DAN_OK) {
            *err = "bad filter entry";
            return DAN_ERR_MALFORMED;
        }
    }
    if (op == DAN_GW_FILTER_REPLACE) {
        g->nfilters = 0;
    }
    for (i = 0; i < count && op != DAN_GW_FILTER_READ; i++) {
        for (j = 0; j < g->nfilters; j++) {
            if (g->filters[j].id == f[i].id && g->filters[j].mask == f[i].mask) {
                break;
            }
        }
        if (op == DAN_GW_FILTER_REMOVE) {
            if (j < g->nfilters) {
                g->filters[j] = g->filters[g->nfilters - 1u];
                g->nfilters--;
            }
        } else if (j == g->nfilters) {
            if (g->nfilters >= DAN_GW_FILTERS_MAX) {
                result = 1;
            } else {
                g->filters[g->nfilters++] = f[i];
            }
        }
    }
    dan_gw_msg_filter_hdr_put(resp, result, g->nfilters);
    for (i = 0; i < g->nfilters; i++) {
        dan_gw_msg_filter_put(resp, &g->filters[i]);
    }
    return DAN_OK;
}

static const dan_handler_t inner_handlers[] = {
    {DAN_GW_CODE_ESC_CMD, h_esc_cmd},       {DAN_GW_CODE_ESC_TELEM, h_esc_telem},
    {DAN_GW_CODE_ARM, h_arm},               {DAN_GW_CODE_CONFIG, h_config},
    {DAN_GW_CODE_STATS, h_stats},           {DAN_GW_CODE_NODES, h_nodes},
    {DAN_GW_CODE_NODE_INFO, h_node_info},   {DAN_GW_CODE_TUN_OPEN, h_tun_open},
    {DAN_GW_CODE_TUN_XFER, h_tun_xfer},     {DAN_GW_CODE_CAN_SEND, h_can_send},
    {DAN_GW_CODE_CAN_RECV, h_can_recv},     {DAN_GW_CODE_CAN_FILTER, h_can_filter},
};

/* Every gateway message is sealed (dan/gateway_msgs.h): check the request's
 * seal before anything acts on it, and seal the response. A request whose
 * seal fails was corrupted past the frame CRC (a collision): it is dropped
 * without a reply, like a bad CRC, and the master retries. */
static int h_sealed(void *user, uint32_t code, const uint8_t *req, size_t len,
                    dan_writer_t *resp, const char **err, uint64_t now_us)
{
    dan_gw_node_t *g = (dan_gw_node_t *)user;
    int n = dan_gw_unseal(code, DAN_GW_REQUEST, req, len), rc;
    size_t i;
    if (n < 0) {
        g->stats.bad_checks++;
        return DAN_PERIPH_NO_REPLY;
    }
    for (i = 0; i < sizeof inner_handlers / sizeof inner_handlers[0]; i++) {
        if (inner_handlers[i].code == code) {
            /* the handlers fill pages to the capacity: keep the seal's room */
            size_t cap = resp->cap;
            resp->cap = (cap > DAN_GW_SEAL_SIZE) ? cap - DAN_GW_SEAL_SIZE : 0u;
            rc = inner_handlers[i].fn(user, code, req, (size_t)n, resp, err, now_us);
            resp->cap = cap;
            if (rc == DAN_OK && !resp->error && resp->buf != NULL) {
                dan_put_u16(resp, dan_gw_check(code, DAN_GW_RESPONSE, resp->buf, resp->len));
            }
            return rc;
        }
    }
    return DAN_PERIPH_NO_REPLY;
}

static const dan_handler_t handlers[] = {
    {DAN_GW_CODE_ESC_CMD, h_sealed},   {DAN_GW_CODE_ESC_TELEM, h_sealed},
    {DAN_GW_CODE_ARM, h_sealed},       {DAN_GW_CODE_CONFIG, h_sealed},
    {DAN_GW_CODE_STATS, h_sealed},     {DAN_GW_CODE_NODES, h_sealed},
    {DAN_GW_CODE_NODE_INFO, h_sealed}, {DAN_GW_CODE_TUN_OPEN, h_sealed},
    {DAN_GW_CODE_TUN_XFER, h_sealed},  {DAN_GW_CODE_CAN_SEND, h_sealed},
    {DAN_GW_CODE_CAN_RECV, h_sealed},  {DAN_GW_CODE_CAN_FILTER, h_sealed},
};

void dan_gw_node_ptype(dan_gw_node_t *g, dan_ptype_t *t)
{
    t->first = DAN_TYPE_CAN_GW_FIRST;
    t->identity = &g->identity;
    t->handlers = handlers;
    t->nhandlers = sizeof handlers / sizeof handlers[0];
    t->user = g;
}
