/* CAN-over-DAN gateway client (FC side). */
#include <string.h>

#include "gw_client_internal.h"

/* The master's reply check: a gateway reply must carry a matching seal, so
 * a reply corrupted past the frame CRC is retried, never decoded. */
static int check_seal(void *user, uint32_t code, const uint8_t *p, size_t len)
{
    (void)user;
    if (!dan_gw_sealed_code(code)) {
        return DAN_OK;
    }
    return dan_gw_unseal(code, DAN_GW_RESPONSE, p, len) < 0 ? DAN_ERR_MALFORMED : DAN_OK;
}

/* The inner length of a reply the master accepted: check_seal() verified
 * its seal already, so only its two bytes are dropped here. */
static size_t inner_len(size_t len)
{
    return (len >= DAN_GW_SEAL_SIZE) ? len - DAN_GW_SEAL_SIZE : 0u;
}

void dan_gw_init(dan_gw_t *gw, dan_master_t *m)
{
    memset(gw, 0, sizeof *gw);
    gw->m = m;
    if (m != NULL) {
        dan_master_set_reply_check(m, check_seal, gw);
    }
    gw->telem_next = DAN_GW_NONE;
    gw->last_telem = DAN_GW_NONE;
}

/* Starts a transaction with the payload in buf, sealed. */
int dan_gwc_start(dan_gw_t *gw, uint32_t code, uint8_t *buf, int len, size_t cap, uint64_t now_us)
{
    int rc;
    if (len < 0) {
        return len;
    }
    len = dan_gw_seal(code, DAN_GW_REQUEST, buf, (size_t)len, cap);
    if (len < 0) {
        return len;
    }
    rc = dan_master_request(gw->m, code, buf, (size_t)len, now_us);
    if (rc == DAN_OK) {
        gw->code = code;
    }
    return rc;
}

int dan_gwc_start_byte(dan_gw_t *gw, uint32_t code, uint8_t v, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(1u)];
    buf[0] = v;
    return dan_gwc_start(gw, code, buf, (int)n, sizeof buf, now_us);
}

bool dan_gwc_idle(const dan_gw_t *gw)
{
    return gw->m != NULL && !dan_master_busy(gw->m);
}

int dan_gw_esc_command(dan_gw_t *gw, const int16_t *values, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_ESC_CMD_SIZE(DAN_GW_ESC_MAX))];
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start(gw, DAN_GW_CODE_ESC_CMD, buf,
                         dan_gw_msg_esc_cmd_encode(values, n, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_esc_fast(dan_gw_t *gw, const int16_t *values, size_t n, bool telem, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_ESC_FAST_SIZE(DAN_GW_ESC_MAX))];
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start(gw, telem ? DAN_GW_CODE_ESC_FAST_T : DAN_GW_CODE_ESC_FAST, buf,
                         dan_gw_msg_esc_fast_encode(values, n, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_telemetry(dan_gw_t *gw, uint8_t first, uint64_t now_us)
{
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start_byte(gw, DAN_GW_CODE_ESC_TELEM, first, 1u, now_us);
}

int dan_gw_arm(dan_gw_t *gw, bool armed, uint64_t now_us)
{
    uint8_t v = armed ? DAN_GW_ARM_FULLY_ARMED : DAN_GW_ARM_DISARMED;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start_byte(gw, DAN_GW_CODE_ARM, v, 1u, now_us);
}

int dan_gw_config(dan_gw_t *gw, const dan_gw_config_t *set, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_CONFIG_REQ_MAX)];
    dan_gw_config_t none;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if (set == NULL) {
        memset(&none, 0, sizeof none);
        set = &none;
    }
    return dan_gwc_start(gw, DAN_GW_CODE_CONFIG, buf,
                         dan_gw_msg_config_req_encode(set, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_stats(dan_gw_t *gw, uint64_t now_us)
{
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start_byte(gw, DAN_GW_CODE_STATS, 0u, 0u, now_us);
}

int dan_gw_nodes(dan_gw_t *gw, uint8_t first, uint64_t now_us)
{
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start_byte(gw, DAN_GW_CODE_NODES, first, 1u, now_us);
}

int dan_gw_node_info(dan_gw_t *gw, uint8_t node_id, uint64_t now_us)
{
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start_byte(gw, DAN_GW_CODE_NODE_INFO, node_id, 1u, now_us);
}

int dan_gw_tunnel_open(dan_gw_t *gw, const dan_gw_tun_open_t *cfg, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_TUN_OPEN_REQ_MAX)];
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if (cfg == NULL || cfg->port >= DAN_GW_TUNNELS) {
        return DAN_ERR_ARG;
    }
    rc = dan_gwc_start(gw, DAN_GW_CODE_TUN_OPEN, buf,
                       dan_gw_msg_tun_open_encode(cfg, buf, DAN_GWC_CAP(buf)), sizeof buf, now_us);
    if (rc == DAN_OK) {
        gw->port = cfg->port;
    }
    return rc;
}

int dan_gw_tunnel_xfer(dan_gw_t *gw, uint8_t port, const uint8_t *data, size_t len, size_t rd_max,
                       uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    dan_gw_tun_xfer_t x;
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if (port >= DAN_GW_TUNNELS) {
        return DAN_ERR_ARG;
    }
    memset(&x, 0, sizeof x);
    x.port = port;
    x.wr_offset = gw->tun[port].wr_offset;
    x.rd_offset = gw->tun[port].rd_offset;
    x.rd_max = (uint32_t)(rd_max > DAN_GW_TUN_CHUNK_MAX ? DAN_GW_TUN_CHUNK_MAX : rd_max);
    x.data = data;
    x.len = len > DAN_GW_TUN_CHUNK_MAX ? DAN_GW_TUN_CHUNK_MAX : len;
    rc = dan_gwc_start(gw, DAN_GW_CODE_TUN_XFER, buf,
                       dan_gw_msg_tun_xfer_req_encode(&x, buf, DAN_GWC_CAP(buf)), sizeof buf,
                       now_us);
    if (rc == DAN_OK) {
        gw->port = port;
        gw->tun[port].accepted = 0;
    }
    return rc;
}

int dan_gw_can_send(dan_gw_t *gw, const dan_can_frame_t *frames, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    dan_writer_t w;
    dan_gw_can_send_t s;
    size_t i;
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if ((frames == NULL && n > 0u) || n > DAN_GW_CAN_FRAMES_MAX) {
        return DAN_ERR_ARG;
    }
    s.seq = (uint8_t)(gw->can_seq + 1u);
    s.count = (uint8_t)n;
    s.queue_free = 0;
    dan_writer_init(&w, buf, DAN_GWC_CAP(buf));
    dan_gw_msg_can_send_req_put(&w, &s);
    for (i = 0; i < n; i++) {
        dan_gw_msg_can_frame_put(&w, &frames[i]);
    }
    rc = dan_gwc_start(gw, DAN_GW_CODE_CAN_SEND, buf, dan_writer_finish(&w), sizeof buf, now_us);
    if (rc == DAN_OK) {
        /* a new number per call, not per attempt: the master's retries repeat it */
        gw->can_seq = s.seq;
    }
    return rc;
}

int dan_gw_can_recv(dan_gw_t *gw, uint8_t max, uint64_t now_us)
{
    return dan_gw_can_recv_opts(gw, max, 0, now_us);
}

int dan_gw_can_recv_opts(dan_gw_t *gw, uint8_t max, uint8_t opts, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_CAN_RECV_REQ_MAX)];
    dan_gw_can_recv_t q;
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    memset(&q, 0, sizeof q);
    q.seq = gw->can_rx_next;
    q.count = max > DAN_GW_CAN_FRAMES_MAX ? (uint8_t)DAN_GW_CAN_FRAMES_MAX : max;
    q.opts = opts;
    rc = dan_gwc_start(gw, DAN_GW_CODE_CAN_RECV, buf,
                       dan_gw_msg_can_recv_req_encode(&q, buf, DAN_GWC_CAP(buf)), sizeof buf,
                       now_us);
    if (rc == DAN_OK) {
        gw->recv_opts = opts;
    }
    return rc;
}

int dan_gw_can_filter(dan_gw_t *gw, uint8_t op, const dan_gw_filter_t *f, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    dan_writer_t w;
    size_t i;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if ((f == NULL && n > 0u) || n > DAN_GW_FILTERS_MAX || op > DAN_GW_FILTER_READ) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, buf, DAN_GWC_CAP(buf));
    dan_gw_msg_filter_hdr_put(&w, op, (uint8_t)n);
    for (i = 0; i < n; i++) {
        dan_gw_msg_filter_put(&w, &f[i]);
    }
    return dan_gwc_start(gw, DAN_GW_CODE_CAN_FILTER, buf, dan_writer_finish(&w), sizeof buf,
                         now_us);
}

/* ---- completion ---- */

static void store_telem(dan_gw_t *gw, const dan_gw_telem_t *t)
{
    gw->last_telem = t->esc_index;
    if (t->esc_index < DAN_GW_MAX_ESC) {
        gw->esc[t->esc_index] = *t;
    } else {
        gw->telem_ignored++;
    }
}

static int complete_telem(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_gw_telem_hdr_t h;
    dan_gw_telem_t t;
    size_t i;
    dan_reader_init(&r, p, len);
    if (dan_gw_msg_telem_hdr_get(&r, &h) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    gw->gw_flags = h.gw_flags;
    if (code == DAN_GW_CODE_ESC_CMD) {
        gw->esc_seen = h.aux;
        gw->last_telem = DAN_GW_NONE;
    } else {
        gw->telem_next = h.aux;
    }
    for (i = 0; i < h.count; i++) {
        if (dan_gw_msg_telem_get(&r, &t) != DAN_OK) {
            return DAN_ERR_MALFORMED;
        }
        store_telem(gw, &t);
    }
    return DAN_OK;
}

/* ESC_FAST / ESC_FAST_T: flags, and the compact record into gw->esc. */
static int complete_fast(dan_gw_t *gw, const uint8_t *p, size_t len)
{
    dan_gw_fast_rec_t rec;
    bool has;
    dan_gw_telem_t *t;
    if (dan_gw_msg_esc_fast_rsp_decode(&gw->gw_flags, &rec, &has, p, len) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    gw->last_telem = has ? rec.esc_index : DAN_GW_NONE;
    gw->telem_fresh = has && rec.fresh;
    if (!has) {
        return DAN_OK;
    }
    if (rec.esc_index >= DAN_GW_MAX_ESC) {
        gw->telem_ignored++;
        return DAN_OK;
    }
    t = &gw->esc[rec.esc_index];
    t->esc_index = rec.esc_index;
    t->flags |= DAN_GW_TELEM_STATUS;
    t->age_ms = (uint32_t)rec.age_4ms * DAN_GW_FAST_AGE_UNIT;
    t->voltage_f16 = rec.voltage_f16;
    t->current_f16 = rec.current_f16;
    t->temperature_f16 = rec.temperature_f16;
    t->rpm = rec.rpm;
    return DAN_OK;
}

static int complete_xfer(dan_gw_t *gw, const uint8_t *p, size_t len)
{
    dan_gw_tun_xfer_t x;
    dan_gw_tunnel_t *t = &gw->tun[gw->port];
    int32_t adv, skip;
    if (dan_gw_msg_tun_xfer_rsp_decode(&x, p, len) != DAN_OK || x.port != gw->port) {
        return DAN_ERR_MALFORMED;
    }
    adv = dan_gw_off_diff(x.wr_offset, t->wr_offset);
    if (adv < 0 || adv > (int32_t)DAN_GW_TUN_CHUNK_MAX) {
        return DAN_ERR_MALFORMED;
    }
    t->accepted = (uint16_t)adv;
    t->wr_offset = x.wr_offset;
    t->wr_space = x.wr_space;
    t->rd_dropped = x.rd_dropped;
    skip = dan_gw_off_diff(x.rd_offset, t->rd_offset);
    if (skip < 0) {
        return DAN_ERR_MALFORMED; /* older data than we acknowledged */
    }
    t->rd_lost += (uint32_t)skip;
    t->rd_offset = x.rd_offset + (uint32_t)x.len;
    return DAN_OK;
}

int dan_gw_complete(dan_gw_t *gw, uint64_t now_us)
{
    dan_master_t *m = gw->m;
    const uint8_t *p = m->resp;
    size_t len = m->resp_len;
    uint32_t code = gw->code;
    int rc = dan_master_result(m);
    (void)now_us;
    gw->code = 0;
    if (rc != DAN_OK || code == 0u) {
        return gw->result = rc;
    }
    len = inner_len(len);
    switch (code) {
    case DAN_GW_CODE_ESC_CMD:
    case DAN_GW_CODE_ESC_TELEM: rc = complete_telem(gw, code, p, len); break;
    case DAN_GW_CODE_ESC_FAST:
    case DAN_GW_CODE_ESC_FAST_T: rc = complete_fast(gw, p, len); break;
    case DAN_GW_CODE_ARM:
    case DAN_GW_CODE_SAFETY:
    case DAN_GW_CODE_SERVO:
    case DAN_GW_CODE_LIGHTS:
    case DAN_GW_CODE_BEEP:
        if (len < 1u) {
            rc = DAN_ERR_MALFORMED;
        } else {
            gw->gw_flags = p[0];
        }
        break;
    case DAN_GW_CODE_CONFIG:
        rc = dan_gw_msg_config_rsp_decode(&gw->config, p, len);
        if (rc == DAN_OK) {
            gw->gw_flags = gw->config.gw_flags;
        }
        break;
    case DAN_GW_CODE_STATS: {
        size_t n;
        rc = dan_gw_msg_stats_decode(gw->stats, DAN_GW_STAT_COUNT, &n, p, len);
        break;
    }
    case DAN_GW_CODE_TUN_OPEN:
        if (len < 2u || p[0] != gw->port) {
            rc = DAN_ERR_MALFORMED;
        } else if (p[1] != 0u) {
            rc = DAN_ERR_NACK;
        } else {
            memset(&gw->tun[gw->port], 0, sizeof gw->tun[gw->port]);
        }
        break;
    case DAN_GW_CODE_SERVO_FAILSAFE:
        if (len < 1u) {
            rc = DAN_ERR_MALFORMED;
        } else {
            gw->servo_fs_kept = p[0];
        }
        break;
    case DAN_GW_CODE_TUN_XFER: rc = complete_xfer(gw, p, len); break;
    case DAN_GW_CODE_CAN_SEND: {
        dan_gw_can_send_t s;
        rc = dan_gw_msg_can_send_rsp_decode(&s, p, len);
        if (rc == DAN_OK) {
            gw->can_accepted = s.count;
            gw->can_queue_free = s.queue_free;
        }
        break;
    }
    case DAN_GW_CODE_CAN_RECV: {
        dan_reader_t r;
        dan_gw_can_recv_t q;
        int32_t skip;
        rc = dan_gw_can_begin(gw, &r, &q);
        if (rc == DAN_OK) {
            skip = dan_gw_off_diff(q.seq, gw->can_rx_next);
            if (skip < 0 || skip > (int32_t)DAN_GW_CAN_RESYNC) {
                /* Not where we left off: the gateway restarted (its
                 * sequence starts elsewhere each boot). Follow it. */
                gw->can_rx_resyncs++;
            } else {
                gw->can_rx_lost += (uint32_t)skip;
            }
            gw->can_rx_next = q.seq + q.count;
            gw->can_rx_dropped = q.dropped;
        }
        break;
    }
    default: rc = dan_gwc_complete_mgmt(gw, code, p, len); break;
    }
    if (rc == DAN_ERR_MALFORMED) {
        gw->decode_errors++;
    }
    return gw->result = rc;
}

int dan_gw_poll(dan_gw_t *gw, uint64_t now_us)
{
    if (!dan_master_poll(gw->m, now_us)) {
        return 0;
    }
    (void)dan_gw_complete(gw, now_us);
    return 1;
}

/* ---- reading variable-length results out of the response ---- */

int dan_gwc_resp_reader(const dan_gw_t *gw, uint32_t code, dan_reader_t *r)
{
    const dan_master_t *m = gw->m;
    if (m->resp_code != code || dan_master_result(m) != DAN_OK) {
        return DAN_ERR_NOTFOUND;
    }
    dan_reader_init(r, m->resp, inner_len(m->resp_len));
    return DAN_OK;
}

int dan_gw_nodes_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_nodes_hdr_t *hdr)
{
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_NODES, r);
    return rc != DAN_OK ? rc : dan_gw_msg_nodes_hdr_get(r, hdr);
}

int dan_gw_nodes_next(dan_reader_t *r, dan_gw_node_entry_t *node)
{
    return dan_gw_msg_node_get(r, node);
}

int dan_gw_node_info_get(const dan_gw_t *gw, dan_gw_node_info_t *info)
{
    dan_reader_t r;
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_NODE_INFO, &r);
    return rc != DAN_OK ? rc : dan_gw_msg_node_info_decode(info, r.data, r.len);
}

int dan_gw_tunnel_data(const dan_gw_t *gw, const uint8_t **data, size_t *len)
{
    dan_reader_t r;
    dan_gw_tun_xfer_t x;
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_TUN_XFER, &r);
    *data = NULL;
    *len = 0;
    if (rc == DAN_OK) {
        rc = dan_gw_msg_tun_xfer_rsp_decode(&x, r.data, r.len);
    }
    if (rc == DAN_OK) {
        *data = x.data;
        *len = x.len;
    }
    return rc;
}

int dan_gw_can_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_can_recv_t *hdr)
{
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_CAN_RECV, r);
    hdr->opts = gw->recv_opts;
    return rc != DAN_OK ? rc : dan_gw_msg_can_recv_rsp_get(r, hdr);
}

int dan_gw_can_next(dan_reader_t *r, dan_can_frame_t *f)
{
    return dan_gw_msg_can_frame_get(r, f);
}

int dan_gw_can_next_timed(dan_reader_t *r, dan_can_frame_t *f, uint32_t *t_us)
{
    int rc = dan_gw_msg_can_frame_get(r, f);
    *t_us += dan_get_uvarint(r);
    return rc != DAN_OK ? rc : dan_reader_finish(r);
}

int dan_gw_filter_begin(const dan_gw_t *gw, dan_reader_t *r, uint8_t *result, uint8_t *count)
{
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_CAN_FILTER, r);
    return rc != DAN_OK ? rc : dan_gw_msg_filter_hdr_get(r, result, count);
}

int dan_gw_filter_next(dan_reader_t *r, dan_gw_filter_t *f)
{
    return dan_gw_msg_filter_get(r, f);
}
