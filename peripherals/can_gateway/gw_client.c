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

/* Starts a transaction with the payload in buf, sealed. Busy first, as
 * each call checked before it encoded. */
int dan_gwc_start(dan_gw_t *gw, uint32_t code, dan_gw_done_fn done, uint8_t *buf, int len,
                  size_t cap, uint64_t now_us)
{
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
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
        gw->done = done;
    }
    return rc;
}

int dan_gwc_start_byte(dan_gw_t *gw, uint32_t code, dan_gw_done_fn done, uint8_t v, size_t n,
                       uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(1u)];
    buf[0] = v;
    return dan_gwc_start(gw, code, done, buf, (int)n, sizeof buf, now_us);
}

bool dan_gwc_idle(const dan_gw_t *gw)
{
    return gw->m != NULL && !dan_master_busy(gw->m);
}

int dan_gw_esc_command(dan_gw_t *gw, const int16_t *values, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_ESC_CMD_SIZE(DAN_GW_ESC_MAX))];
    return dan_gwc_start(gw, DAN_GW_CODE_ESC_CMD, dan_gwc_done_telem, buf,
                         dan_gw_msg_esc_cmd_encode(values, n, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_esc_fast(dan_gw_t *gw, const int16_t *values, size_t n, bool telem, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_ESC_FAST_SIZE(DAN_GW_ESC_MAX))];
    return dan_gwc_start(
        gw, telem ? DAN_GW_CODE_ESC_FAST_T : DAN_GW_CODE_ESC_FAST, dan_gwc_done_fast, buf,
        dan_gw_msg_esc_fast_encode(values, n, buf, DAN_GWC_CAP(buf)), sizeof buf, now_us);
}

int dan_gw_telemetry(dan_gw_t *gw, uint8_t first, uint64_t now_us)
{
    return dan_gwc_start_byte(gw, DAN_GW_CODE_ESC_TELEM, dan_gwc_done_telem, first, 1u, now_us);
}

int dan_gw_arm(dan_gw_t *gw, bool armed, uint64_t now_us)
{
    return dan_gwc_start_byte(gw, DAN_GW_CODE_ARM, dan_gwc_done_flags,
                              armed ? DAN_GW_ARM_FULLY_ARMED : DAN_GW_ARM_DISARMED, 1u, now_us);
}

int dan_gw_config(dan_gw_t *gw, const dan_gw_config_t *set, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_CONFIG_REQ_MAX)];
    dan_gw_config_t none;
    if (set == NULL) {
        memset(&none, 0, sizeof none);
        set = &none;
    }
    return dan_gwc_start(gw, DAN_GW_CODE_CONFIG, dan_gwc_done_config, buf,
                         dan_gw_msg_config_req_encode(set, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_stats(dan_gw_t *gw, uint64_t now_us)
{
    return dan_gwc_start_byte(gw, DAN_GW_CODE_STATS, dan_gwc_done_stats, 0u, 0u, now_us);
}

int dan_gw_node_info(dan_gw_t *gw, uint8_t node_id, uint64_t now_us)
{
    return dan_gwc_start_byte(gw, DAN_GW_CODE_NODE_INFO, NULL, node_id, 1u, now_us);
}

void dan_gw_set_stats(dan_gw_t *gw, uint32_t *v)
{
    gw->stats = v;
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

/* ESC_CMD / ESC_TELEM: flags, a page of records into gw->esc. */
int dan_gwc_done_telem(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
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
int dan_gwc_done_fast(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    dan_gw_fast_rec_t rec;
    bool has;
    dan_gw_telem_t *t;
    (void)code;
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

/* One byte: the gateway flags (ARM, SAFETY, SERVO, LIGHTS, BEEP), or the
 * entries of the table SERVO_FAILSAFE kept. */
int dan_gwc_done_flags(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    if (len < 1u) {
        return DAN_ERR_MALFORMED;
    }
    if (code == DAN_GW_CODE_SERVO_FAILSAFE) {
        gw->servo_fs_kept = p[0];
    } else {
        gw->gw_flags = p[0];
    }
    return DAN_OK;
}

int dan_gwc_done_config(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    int rc = dan_gw_msg_config_rsp_decode(&gw->config, p, len);
    (void)code;
    if (rc == DAN_OK) {
        gw->gw_flags = gw->config.gw_flags;
    }
    return rc;
}

int dan_gwc_done_stats(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    size_t n;
    (void)code;
    /* checked also when not kept (no storage: dan_gw_set_stats()) */
    return dan_gw_msg_stats_decode(gw->stats, gw->stats != NULL ? DAN_GW_STAT_COUNT : 0u, &n, p,
                                   len);
}

int dan_gw_complete(dan_gw_t *gw, uint64_t now_us)
{
    dan_master_t *m = gw->m;
    uint32_t code = gw->code;
    dan_gw_done_fn done = gw->done;
    int rc = dan_master_result(m);
    (void)now_us;
    gw->code = 0;
    gw->done = NULL;
    if (rc != DAN_OK || code == 0u) {
        return gw->result = rc;
    }
    /* NULL: read on demand (NODES, NODE_INFO, CAN_FILTER, CALL_RESULT, DNA) */
    if (done != NULL) {
        rc = done(gw, code, m->resp, inner_len(m->resp_len));
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
        dan_reader_init(r, NULL, 0); /* a caller that reads anyway gets errors, not garbage */
        r->error = true;
        return DAN_ERR_NOTFOUND;
    }
    dan_reader_init(r, m->resp, inner_len(m->resp_len));
    return DAN_OK;
}

DAN_GWC_PAGED(nodes, DAN_GW_CODE_NODES, dan_gw_nodes_hdr_t, dan_gw_msg_nodes_hdr_get,
              dan_gw_node_entry_t, dan_gw_msg_node_get)

int dan_gw_node_info_get(const dan_gw_t *gw, dan_gw_node_info_t *info)
{
    dan_reader_t r;
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_NODE_INFO, &r);
    return rc != DAN_OK ? rc : dan_gw_msg_node_info_decode(info, r.data, r.len);
}
