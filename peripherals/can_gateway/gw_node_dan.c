/* Gateway node: the DAN side. One handler per gateway message (decode the
 * request, call the subsystem, encode the response) and the seal, which
 * the peripheral engine applies around every one of them as the type's
 * envelope. */
#include <string.h>

#include "gw_node_internal.h"

static DAN_GWN_HANDLER(h_esc_cmd)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    int16_t v[DAN_GW_ESC_MAX];
    size_t n;
    dan_gw_telem_hdr_t h;
    const dan_gw_telem_t *t;
    (void)code;
    if (dan_gw_msg_esc_cmd_decode(req, len, v, &n) != DAN_OK) {
        return dan_gwn_refuse(err, "bad ESC command");
    }
    dan_gwn_esc_command(g, v, n, now_us);
    t = dan_gwn_esc_next_telem(g, now_us);
    h.gw_flags = dan_gw_node_flags(g);
    h.aux = dan_gwn_esc_seen(g);
    h.count = t != NULL ? 1u : 0u;
    dan_gw_msg_telem_hdr_put(resp, &h);
    if (t != NULL) {
        dan_gw_msg_telem_put(resp, t);
    }
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_esc_telem)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_telem_hdr_t h;
    size_t i, room;
    (void)code;
    if (len < 1u) {
        return dan_gwn_refuse(err, "missing first index");
    }
    h.gw_flags = dan_gw_node_flags(g);
    h.aux = DAN_GW_NONE;
    h.count = 0;
    room = resp->cap - DAN_GW_TELEM_HDR_SIZE;
    for (i = req[0]; i < DAN_GW_NODE_ESC_SLOTS; i++) {
        const dan_gw_telem_t *t = dan_gwn_esc_telem(g, i, now_us);
        if (t != NULL) {
            size_t sz = dan_gw_msg_telem_size(t);
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
        const dan_gw_telem_t *t = dan_gwn_esc_telem(g, i, now_us);
        if (t != NULL) {
            dan_gw_msg_telem_put(resp, t);
        }
    }
    return DAN_OK;
}

/* ARM and SAFETY: one byte, its two values (DISARMED or FULLY_ARMED,
 * SAFETY_ON or SAFETY_OFF); the response is the gateway flags. */
static DAN_GWN_HANDLER(h_arm_safety)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    bool arm = code == DAN_GW_CODE_ARM;
    uint8_t off = arm ? DAN_GW_ARM_DISARMED : DAN_GW_SAFETY_ON;
    uint8_t on = arm ? DAN_GW_ARM_FULLY_ARMED : DAN_GW_SAFETY_OFF;
    if (!dan_gwn_byte_of(req, len, off, on)) {
        return dan_gwn_refuse(err, arm ? "ARM takes 0 or 255 only" : "SAFETY takes 0 or 255 only");
    }
    if (arm) {
        dan_gwn_arming_set(g, req[0], now_us);
    } else {
        dan_gwn_safety_set(g, req[0], now_us);
    }
    dan_put_u8(resp, dan_gw_node_flags(g));
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_config)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_config_t c;
    (void)code;
    if (dan_gw_msg_config_req_decode(&c, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad CONFIG or value range");
    }
    if (c.set_mask & DAN_GW_CFG_ESC_TIMEOUT) {
        (void)dan_gw_node_set_esc_timeout(g, c.esc_timeout_ms);
    }
    if (c.set_mask & DAN_GW_CFG_ARMING_RATE) {
        (void)dan_gw_node_set_arming_rate(g, c.arming_rate_hz, now_us);
    }
    if (c.set_mask & DAN_GW_CFG_TELEM_TIMEOUT) {
        (void)dan_gw_node_set_telem_timeout(g, c.telem_timeout_ms);
    }
    if (c.set_mask & DAN_GW_CFG_DNA) {
        dan_gw_node_set_dna(g, c.dna != 0u);
    }
    c.node_id = g->cfg.node_id;
    c.esc_timeout_ms = g->cfg.esc_timeout_ms;
    c.arming_rate_hz = g->cfg.arming_rate_hz;
    c.telem_timeout_ms = g->cfg.telem_timeout_ms;
    c.dna = g->cfg.dna ? 1u : 0u;
    c.gw_flags = dan_gw_node_flags(g);
    PUT_ENCODED(resp, dan_gw_msg_config_rsp_encode, &c);
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_stats)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    uint32_t v[DAN_GW_STAT_COUNT];
    size_t room, n = DAN_GW_STAT_COUNT;
    uint8_t *out = dan_writer_room(resp, &room);
    int rc;
    (void)code;
    (void)req;
    (void)len;
    (void)err;
    dan_gw_node_counters(g, v);
    /* 36 counters of 5 bytes (each above 2^28) are more than a response
     * holds: the last ones are left off (n says how many), rather than
     * STATS failing for good on a gateway that ran long (review finding) */
    while ((rc = dan_gw_msg_stats_encode(v, n, out, room)) < 0 && n > 0u) {
        n--;
    }
    dan_writer_advance(resp, rc);
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_nodes)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_nodes_hdr_t h;
    size_t room = resp->cap - DAN_GW_NODES_HDR_SIZE;
    unsigned id, first, last = 0;
    (void)code;
    if (len < 1u) {
        return dan_gwn_refuse(err, "missing first node id");
    }
    first = req[0] ? req[0] : 1u;
    h.next = 0;
    h.count = 0;
    for (id = first; id <= DAN_DC_NODE_ID_MAX; id++) {
        dan_gw_node_slot_t *n = dan_gwn_find_node(g, (uint8_t)id);
        size_t sz;
        if (n == NULL) {
            continue;
        }
        n->e.age_ms = dan_gwn_age_ms(now_us, n->seen_us);
        sz = dan_gw_msg_node_size(&n->e); /* the flags do not change its size */
        if (sz > room) {
            h.next = (uint8_t)id;
            break;
        }
        room -= sz;
        h.count++;
        last = id;
    }
    dan_gw_msg_nodes_hdr_put(resp, &h);
    for (id = first; id <= last; id++) {
        dan_gw_node_slot_t *n = dan_gwn_find_node(g, (uint8_t)id);
        if (n != NULL) {
            dan_gw_node_entry_t e = n->e;
            e.info_state = dan_gwn_node_flags(g, n, now_us);
            dan_gw_msg_node_put(resp, &e);
        }
    }
    return DAN_OK;
}

/* NODE_INFO's appended fields: the node's mode and its firmware update
 * as far as the gateway saw it (BeginFirmwareUpdate, file reads). */
static void node_follow(const dan_gw_node_slot_t *n, dan_gw_node_info_t *i, uint64_t now_us)
{
    uint32_t since = dan_gwn_age_ms(now_us, n->fw.last_read_us);
    i->follow = true;
    i->status = DAN_GW_STATUS_NONE;
    if (n->seen_us != 0u) {
        i->status = (uint8_t)(n->e.health | (n->e.mode << 2) | (n->e.sub_mode << 5));
    }
    i->file_flags = n->fw.flags;
    i->bytes_read = n->fw.bytes_read;
    i->file_size = n->fw.file_size;
    i->since_read_ms = n->fw.last_read_us == 0u  ? DAN_GW_NEVER_MS
                       : since < DAN_GW_NEVER_MS ? since
                                                 : DAN_GW_NEVER_MS - 1u;
}

static DAN_GWN_HANDLER(h_node_info)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_node_slot_t *n;
    dan_gw_node_info_t tmp;
    (void)code;
    if (len < 1u) {
        return dan_gwn_refuse(err, "missing node id");
    }
    n = req[0] != 0u ? dan_gwn_find_node(g, req[0]) : NULL;
    if (n == NULL) {
        *err = "unknown node";
        return DAN_ERR_NOTFOUND;
    }
    if (n->e.info_state == DAN_GW_INFO_VALID) {
        tmp = n->info;
    } else {
        memset(&tmp, 0, sizeof tmp);
        tmp.node_id = n->e.node_id;
        tmp.info_state = n->e.info_state;
    }
    node_follow(n, &tmp, now_us);
    PUT_ENCODED(resp, dan_gw_msg_node_info_encode, &tmp);
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_tun_open)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_tun_open_t o;
    bool ok;
    (void)code;
    if (dan_gw_msg_tun_open_decode(&o, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad tunnel open");
    }
    ok = dan_gwn_tunnel_open(g, &o, now_us);
    dan_put_u8(resp, o.port);
    dan_put_u8(resp, (uint8_t)(ok ? 0u : 1u));
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_tun_xfer)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_tun_xfer_t x, r;
    uint8_t out[DAN_GW_TUN_CHUNK_MAX];
    int rc;
    (void)code;
    if (dan_gw_msg_tun_xfer_req_decode(&x, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad tunnel transfer");
    }
    rc = dan_gwn_tunnel_xfer(g, &x, &r, out, resp->cap - resp->len);
    if (rc == DAN_ERR_NOTFOUND) {
        *err = "tunnel port not open";
        return rc;
    }
    if (rc != DAN_OK) {
        *err = "tunnel write leaves a gap";
        return rc;
    }
    PUT_ENCODED(resp, dan_gw_msg_tun_xfer_rsp_encode, &r);
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_can_send)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_reader_t r;
    dan_gw_can_send_t s;
    dan_can_frame_t f[DAN_GW_CAN_FRAMES_MAX];
    size_t i;
    (void)code;
    dan_reader_init(&r, req, len);
    if (dan_gw_msg_can_send_req_get(&r, &s) != DAN_OK) {
        return dan_gwn_refuse(err, "bad CAN send");
    }
    for (i = 0; i < s.count; i++) {
        if (dan_gw_msg_can_frame_get(&r, &f[i]) != DAN_OK || (f[i].flags & DAN_CAN_OWN) != 0u) {
            return dan_gwn_refuse(err, "bad CAN frame");
        }
    }
    dan_gwn_raw_send(g, &s, f, dan_gw_crc32(0, req, len)); /* retry check: CRC-32 */
    PUT_ENCODED(resp, dan_gw_msg_can_send_rsp_encode, &s);
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_can_recv)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_can_recv_t q, a;
    size_t i;
    (void)code;
    if (dan_gw_msg_can_recv_req_decode(&q, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad CAN receive");
    }
    dan_gwn_raw_recv(g, &q, &a, resp->cap);
    a.t0_us = a.count > 0u ? dan_gwn_raw_time(g, 0) : 0u;
    dan_gw_msg_can_recv_rsp_put(resp, &a);
    for (i = 0; i < a.count; i++) {
        dan_gw_msg_can_frame_put(resp, dan_gwn_raw_at(g, i));
        if (a.opts & DAN_GW_RECV_TIMES) {
            uint32_t prev = i > 0u ? dan_gwn_raw_time(g, i - 1u) : a.t0_us;
            dan_put_uvarint(resp, dan_gwn_raw_time(g, i) - prev);
        }
    }
    return DAN_OK;
}

static DAN_GWN_HANDLER(h_can_filter)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_reader_t r;
    dan_gw_filter_t f[DAN_GW_FILTERS_MAX];
    uint8_t op, count, result;
    size_t i;
    (void)code;
    dan_reader_init(&r, req, len);
    if (dan_gw_msg_filter_hdr_get(&r, &op, &count) != DAN_OK || op > DAN_GW_FILTER_READ) {
        return dan_gwn_refuse(err, "bad filter request");
    }
    for (i = 0; i < count; i++) {
        if (dan_gw_msg_filter_get(&r, &f[i]) != DAN_OK) {
            return dan_gwn_refuse(err, "bad filter entry");
        }
    }
    result = dan_gwn_raw_filter(g, op, f, count);
    dan_gw_msg_filter_hdr_put(resp, result, g->raw.nfilters);
    for (i = 0; i < g->raw.nfilters; i++) {
        dan_gw_msg_filter_put(resp, &g->raw.filters[i]);
    }
    return DAN_OK;
}

const dan_handler_t dan_gwn_handlers[] = {
    {DAN_GW_CODE_ESC_CMD, h_esc_cmd},
    {DAN_GW_CODE_ESC_TELEM, h_esc_telem},
    {DAN_GW_CODE_ARM, h_arm_safety},
    {DAN_GW_CODE_CONFIG, h_config},
    {DAN_GW_CODE_STATS, h_stats},
    {DAN_GW_CODE_NODES, h_nodes},
    {DAN_GW_CODE_NODE_INFO, h_node_info},
    {DAN_GW_CODE_TUN_OPEN, h_tun_open},
    {DAN_GW_CODE_TUN_XFER, h_tun_xfer},
    {DAN_GW_CODE_CAN_SEND, h_can_send},
    {DAN_GW_CODE_CAN_RECV, h_can_recv},
    {DAN_GW_CODE_CAN_FILTER, h_can_filter},
    {DAN_GW_CODE_NODE_CALL, dan_gwn_h_node_call},
    {DAN_GW_CODE_CALL_RESULT, dan_gwn_h_call_result},
    {DAN_GW_CODE_HEALTH, dan_gwn_h_health},
    {DAN_GW_CODE_DNA, dan_gwn_h_dna},
    {DAN_GW_CODE_SAFETY, h_arm_safety},
    {DAN_GW_CODE_SERVO, dan_gwn_h_output},
    {DAN_GW_CODE_SERVO_FAILSAFE, dan_gwn_h_output},
    {DAN_GW_CODE_LIGHTS, dan_gwn_h_output},
    {DAN_GW_CODE_BEEP, dan_gwn_h_output},
    {DAN_GW_CODE_ESC_FAST, dan_gwn_h_esc_fast},
    {DAN_GW_CODE_ESC_FAST_T, dan_gwn_h_esc_fast},
    {DAN_GW_CODE_FILE_OPEN, dan_gwn_h_file_open},
    {DAN_GW_CODE_FILE_WRITE, dan_gwn_h_file_write},
    {DAN_GW_CODE_FILE_COMMIT, dan_gwn_h_file_commit},
    {DAN_GW_CODE_FILE_LIST, dan_gwn_h_file_list},
    {DAN_GW_CODE_FILE_REMOVE, dan_gwn_h_file_remove},
};
const size_t dan_gwn_nhandlers = sizeof dan_gwn_handlers / sizeof dan_gwn_handlers[0];

/* The seal (dan/can_gw/msgs.h): a request whose seal fails was corrupted
 * past the frame CRC (a collision): nothing acts on it and it gets no
 * reply, like a bad CRC; the master retries. */
static int seal_open(void *user, uint32_t code, const uint8_t *req, size_t len)
{
    int n = dan_gw_unseal(code, DAN_GW_REQUEST, req, len);
    if (n < 0) {
        ((dan_gw_node_t *)user)->stats.bad_checks++;
    }
    return n;
}

static void seal_close(void *user, uint32_t code, uint8_t *resp, size_t len)
{
    (void)user;
    (void)dan_gw_seal(code, DAN_GW_RESPONSE, resp, len, len + DAN_GW_SEAL_SIZE);
}

const dan_envelope_t dan_gwn_seal = {DAN_GW_SEAL_SIZE, seal_open, seal_close};
