/* The gateway rig of the unit tests (see gw_rig.h). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "dan/can_gw/dsdl_file.h"
#include "dan/codes.h"
#include "gw_rig.h"

rig_t *R;

static bool lis_accept(void *user, uint16_t dtid, uint8_t tt, uint8_t src, uint64_t *sig)
{
    (void)user;
    (void)src;
    return dan_dc_dsdl_signature(tt, dtid, sig);
}

void drain(void)
{
    (void)send_frames(SIZE_MAX);
}

int finish_stalled(void)
{
    int r = sim_run_master(&R->bus, &R->m, 3000000);
    assert_int_not_equal(r, 1);
    dan_gw_node_poll(&R->g, R->bus.now);
    return dan_gw_complete(&R->gw, R->bus.now);
}

size_t send_frames(size_t max)
{
    dan_can_frame_t f;
    dan_dc_transfer_t t;
    size_t sent = 0;
    while (sent < max && dan_gw_node_tx_peek(&R->g, &f)) {
        sent++;
        dan_gw_node_tx_sent(&R->g, R->bus.now); /* on the bus: a capture may keep it */
        R->nframes++;
        if (dan_dc_rx_frame(&R->lis, &f, R->bus.now, &t) == 1 && R->ncap < MAX_CAP) {
            cap_t *c = &R->cap[R->ncap++];
            c->dtid = t.data_type_id;
            c->ttype = t.transfer_type;
            c->src = t.source_node;
            c->dst = t.destination_node;
            c->tid = t.transfer_id;
            c->len = t.payload_len;
            c->at_us = R->bus.now;
            memcpy(c->payload, t.payload, t.payload_len);
        }
    }
    return sent;
}

/* Runs the wire, the node's timers and the CAN drain for us microseconds. */
void advance(uint64_t us)
{
    uint64_t end = R->bus.now + us;
    while (R->bus.now < end) {
        sim_run_for(&R->bus, 500);
        dan_gw_node_poll(&R->g, R->bus.now);
        drain();
    }
}

/* Completes the client's transaction in flight. */
/* Starts a hand-built request, sealed as the client would. */
int request_sealed(uint32_t code, const uint8_t *payload, size_t n)
{
    uint8_t buf[DAN_MAX_PAYLOAD];
    int len;
    if (n > 0) {
        memcpy(buf, payload, n);
    }
    len = dan_gw_seal(code, DAN_GW_REQUEST, buf, n, sizeof buf);
    assert_true(len > 0);
    return dan_master_request(&R->m, code, buf, (size_t)len, R->bus.now);
}

int finish(void)
{
    int r = sim_run_master(&R->bus, &R->m, 3000000);
    assert_int_not_equal(r, 1);
    dan_gw_node_poll(&R->g, R->bus.now);
    drain();
    return dan_gw_complete(&R->gw, R->bus.now);
}

void call_ok(int started)
{
    assert_int_equal(started, DAN_OK);
    assert_int_equal(finish(), DAN_OK);
}

uint32_t remote_code(void)
{
    dan_error_msg_t e;
    assert_int_equal(dan_master_remote_error(&R->m, &e), DAN_OK);
    return e.code;
}

/* The payload of the master's request in flight (it waits encoded in
 * link.tx), to send it again as a retry would. */
size_t last_req(uint8_t *out)
{
    dan_decoder_t d;
    dan_frame_t f;
    size_t used;
    dan_decoder_init(&d);
    assert_int_equal(dan_decoder_feed(&d, R->m.link.tx, R->m.link.tx_len, &used, &f), 1);
    memcpy(out, f.payload, f.len);
    return f.len;
}

void lose_response(void)
{
    uint8_t req[DAN_MAX_PAYLOAD];
    uint32_t code = R->m.req_code;
    size_t n = last_req(req);
    assert_int_equal(sim_run_master(&R->bus, &R->m, 3000000), DAN_OK);
    assert_int_equal(dan_master_request(&R->m, code, req, n, R->bus.now), DAN_OK);
}

/* Finds the n-th captured transfer of a type from index from on. */
cap_t *find_cap(uint16_t dtid, uint8_t tt, size_t *from)
{
    size_t i;
    for (i = *from; i < R->ncap; i++) {
        if (R->cap[i].dtid == dtid && R->cap[i].ttype == tt) {
            *from = i + 1;
            return &R->cap[i];
        }
    }
    return NULL;
}

cap_t *expect_cap(uint16_t dtid, uint8_t tt, size_t *from)
{
    cap_t *c = find_cap(dtid, tt, from);
    assert_non_null(c);
    return c;
}

/* Splits t into frames and gives them to the node. */
static void feed(dan_dc_transfer_t *t)
{
    dan_can_frame_t f[64];
    int n = dan_dc_tx_build(t, f, 64), i;
    assert_true(n > 0);
    for (i = 0; i < n; i++) {
        dan_gw_node_rx_can(&R->g, &f[i], R->bus.now);
    }
}

/* Sends a transfer from fake node src into the gateway. */
void inject(uint8_t src, uint16_t dtid, uint64_t sig, uint8_t tt, uint8_t dst,
            const uint8_t *payload, int len)
{
    dan_dc_transfer_t t;
    assert_true(len >= 0);
    dan_dc_transfer_init(&t, dtid, sig, (dan_dc_transfer_type_t)tt, payload, (size_t)len);
    t.priority = 16;
    t.source_node = src;
    t.destination_node = dst;
    t.transfer_id = (uint8_t)dan_dc_tid_next(&R->tids, dtid, tt, (uint8_t)(dst + src * 0));
    feed(&t);
}

void answer_cap(const cap_t *c, uint16_t dtid, uint64_t sig, uint8_t prio, const uint8_t *payload,
                int len)
{
    dan_dc_transfer_t t;
    assert_true(len > 0);
    dan_dc_transfer_init(&t, dtid, sig, DAN_DC_TRANSFER_RESPONSE, payload, (size_t)len);
    t.priority = prio;
    t.source_node = c->dst;
    t.destination_node = R->g.cfg.node_id;
    t.transfer_id = c->tid;
    feed(&t);
}

int setup(void **state)
{
    dan_master_config_t mc;
    dan_gw_node_config_t gc;
    static const uint32_t types[] = {DAN_TYPE_CAN_GW_FIRST};
    R = calloc(1, sizeof *R);
    assert_non_null(R);
    sim_init(&R->bus, 20);
    dan_master_config_default(&mc);
    R->nm = sim_add_master(&R->bus, &R->m, 115200, true);
    R->np = sim_add_periph(&R->bus, &R->p, 115200, true);
    assert_int_equal(dan_master_init(&R->m, &R->nm->port, &mc, types, 1, 115200, R->bus.now),
                     DAN_OK);
    dan_master_set_identities(&R->m, &R->id, 1);
    dan_gw_node_config_default(&gc);
    gc.unique_id[0] = 0xAB;
    assert_int_equal(dan_gw_node_init(&R->g, &gc, R->bus.now), DAN_OK);
    dan_gw_node_ptype(&R->g, &R->pt);
    assert_int_equal(dan_periph_init(&R->p, &R->np->port, &R->pt, 1, NULL, 115200, R->bus.now),
                     DAN_OK);
    dan_gw_node_attach(&R->g, &R->p);
    dan_gw_init(&R->gw, &R->m);
    dan_gw_set_stats(&R->gw, R->gw_stats);
    dan_dc_rx_init(&R->lis, LISTEN_NODE, lis_accept, NULL);
    dan_dc_tid_table_init(&R->tids);
    *state = R;
    return 0;
}

int teardown(void **state)
{
    (void)state;
    free(R);
    R = NULL;
    return 0;
}

void config_set(uint8_t mask, uint32_t value)
{
    dan_gw_config_t set;
    memset(&set, 0, sizeof set);
    set.set_mask = mask;
    set.esc_timeout_ms = (mask & DAN_GW_CFG_ESC_TIMEOUT) ? value : 0u;
    set.arming_rate_hz = (mask & DAN_GW_CFG_ARMING_RATE) ? value : 0u;
    set.telem_timeout_ms = (mask & DAN_GW_CFG_TELEM_TIMEOUT) ? value : 0u;
    set.dna = (mask & DAN_GW_CFG_DNA) ? (uint8_t)value : 0u;
    call_ok(dan_gw_config(&R->gw, &set, R->bus.now));
}

void esc_status(uint8_t src, uint8_t idx, float v, float c, float t, int32_t rpm)
{
    dan_dc_esc_status_t s;
    uint8_t buf[DAN_DC_ESC_STATUS_MAX_SIZE];
    memset(&s, 0, sizeof s);
    s.esc_index = idx;
    s.voltage_f16 = dan_f16_from_f32(v);
    s.current_f16 = dan_f16_from_f32(c);
    s.temperature_f16 = dan_f16_from_f32(t);
    s.rpm = rpm;
    s.power_rating_pct = (uint8_t)(10 + idx);
    s.error_count = 100u + idx;
    inject(src, DAN_DC_ESC_STATUS_ID, DAN_DC_ESC_STATUS_SIGNATURE, DAN_DC_TRANSFER_BROADCAST, 0,
           buf, dan_dc_esc_status_encode(&s, buf, sizeof buf));
}

void expect_flag_broadcast(int started, uint8_t flag, uint16_t dtid, uint8_t value, size_t *from)
{
    const uint64_t t0 = R->bus.now; /* when the request went out */
    cap_t *c;
    int n = 0;
    assert_int_equal(started, DAN_OK);
    assert_int_equal(finish(), DAN_OK);
    assert_true(R->gw.gw_flags & flag);
    c = expect_cap(dtid, DAN_DC_TRANSFER_BROADCAST, from);
    assert_int_equal(c->payload[0], value);
    assert_true(c->at_us - t0 < 20000u);
    advance(2000000);
    while ((c = find_cap(dtid, DAN_DC_TRANSFER_BROADCAST, from)) != NULL) {
        assert_int_equal(c->payload[0], value);
        n++;
    }
    assert_true(n >= 3 && n <= 5);
}

int tunnel_open_start(uint8_t port, uint8_t mode, uint8_t protocol, uint8_t target, int8_t serial,
                      uint8_t options, uint32_t baud)
{
    const dan_gw_tun_open_t o = {.port = port,
                                 .mode = mode,
                                 .protocol = protocol,
                                 .target = target,
                                 .serial_id = serial,
                                 .options = options,
                                 .baud = baud};
    return dan_gw_tunnel_open(&R->gw, &o, R->bus.now);
}

void three_esc_statuses(int32_t esc1_rpm)
{
    esc_status(20, 0, 12.5f, 1.25f, 300.0f, 1000);
    esc_status(21, 1, 16.8f, -3.14159f, 310.15f, esc1_rpm);
    esc_status(22, 3, 25.2f, 123.456f, 320.0f, 131071);
}

void assert_round_robin_013(const uint8_t *order, size_t n)
{
    static const uint8_t cycle[3] = {0, 1, 3};
    size_t i;
    for (i = 0; i < n; i++) {
        assert_int_equal(order[i], cycle[i % 3u]);
    }
}

void esc_status_ext_from(uint8_t src, const dan_dc_esc_status_extended_t *x)
{
    uint8_t buf[DAN_DC_ESC_STATUS_EXTENDED_MAX_SIZE];
    inject(src, DAN_DC_ESC_STATUS_EXTENDED_ID, DAN_DC_ESC_STATUS_EXTENDED_SIGNATURE,
           DAN_DC_TRANSFER_BROADCAST, 0, buf,
           dan_dc_esc_status_extended_encode(x, buf, sizeof buf));
}

void node_status_from(uint8_t src, uint32_t uptime, uint8_t health, uint8_t mode)
{
    dan_dc_node_status_t s;
    uint8_t buf[DAN_DC_NODE_STATUS_MAX_SIZE];
    memset(&s, 0, sizeof s);
    s.uptime_sec = uptime;
    s.health = health;
    s.mode = mode;
    inject(src, DAN_DC_NODE_STATUS_ID, DAN_DC_NODE_STATUS_SIGNATURE, DAN_DC_TRANSFER_BROADCAST, 0,
           buf, dan_dc_node_status_encode(&s, buf, sizeof buf));
}

void tunnel_targetted_from(uint8_t src, int8_t serial, const uint8_t *d, size_t n)
{
    dan_dc_tunnel_targetted_t m;
    uint8_t buf[DAN_DC_TUNNEL_TARGETTED_MAX_SIZE];
    memset(&m, 0, sizeof m);
    m.protocol = DAN_DC_TUNNEL_UNDEFINED;
    m.target_node = 10;
    m.serial_id = serial;
    m.buffer_len = (uint8_t)n;
    memcpy(m.buffer, d, n);
    inject(src, DAN_DC_TUNNEL_TARGETTED_ID, DAN_DC_TUNNEL_TARGETTED_SIGNATURE,
           DAN_DC_TRANSFER_BROADCAST, 0, buf, dan_dc_tunnel_targetted_encode(&m, buf, sizeof buf));
}

void file_read_from(uint8_t src, uint64_t offset, const char *path)
{
    dan_dc_file_req_t q;
    uint8_t buf[DAN_DC_FILE_READ_REQ_MAX_SIZE];
    memset(&q, 0, sizeof q);
    q.offset = offset;
    q.path_len = (uint8_t)strlen(path);
    memcpy(q.path, path, q.path_len);
    inject(src, DAN_DC_FILE_READ_ID, DAN_DC_FILE_READ_SIGNATURE, DAN_DC_TRANSFER_REQUEST,
           R->g.cfg.node_id, buf, dan_dc_file_read_req_encode(&q, buf, sizeof buf));
}
