/* Fuzz entry functions (see targets.h). Each checks invariants that must
 * hold for any input and calls abort() when one breaks. Built into every
 * libFuzzer binary (tests/fuzz/fuzz.mk) and #included by the replay test
 * tests/unit/test_fuzz_regressions.c, so it compiles with the project's
 * strict warning flags. */
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "dan/dan.h"
#include "dan/can_gw/client.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/node.h"
#include "can_backend.h"
#include "targets.h"

#define FUZZ_CHECK(cond) \
    do {                 \
        if (!(cond)) {   \
            abort();     \
        }                \
    } while (0)

/* ---- frame decoder ---------------------------------------------------- */

/* A frame the decoder returned must re-encode and decode to itself. */
static void check_frame(const dan_frame_t *f)
{
    uint8_t buf[DAN_MAX_FRAME];
    dan_decoder_t d;
    dan_frame_t g;
    size_t used;
    int n;
    FUZZ_CHECK(f->len <= DAN_MAX_PAYLOAD);
    FUZZ_CHECK(f->len == 0u || f->payload != NULL);
    n = dan_frame_encode(f->code, f->payload, f->len, buf, sizeof buf);
    FUZZ_CHECK(n > 0 && (size_t)n == dan_frame_size(f->code, f->len));
    dan_decoder_init(&d);
    FUZZ_CHECK(dan_decoder_feed(&d, buf, (size_t)n, &used, &g) == 1);
    FUZZ_CHECK(used == (size_t)n && g.code == f->code && g.len == f->len);
    FUZZ_CHECK(f->len == 0u || memcmp(g.payload, f->payload, f->len) == 0);
}

/* Feeds everything in, 'chunk' bytes at a time; returns the frames found. */
static size_t feed_all(dan_decoder_t *d, const uint8_t *p, size_t left)
{
    size_t frames = 0;
    for (;;) {
        size_t used = 0;
        dan_frame_t f;
        int got = dan_decoder_feed(d, p, left, &used, &f);
        FUZZ_CHECK(used <= left);
        p += used;
        left -= used;
        if (!got) {
            FUZZ_CHECK(left == 0u); /* 0 only once every byte was taken */
            return frames;
        }
        FUZZ_CHECK(got == 1);
        check_frame(&f);
        frames++;
    }
}

/* data[0]: chunk size (1..16, or everything at once); data[1]: after which
 * chunks the line goes idle (dan_decoder_abort), as a bit mask. */
int dan_fuzz_frame(const uint8_t *data, size_t len)
{
    dan_decoder_t d;
    size_t chunk, pos = 0, k = 0;
    uint8_t idle;
    if (len < 2u) {
        return 0;
    }
    chunk = (size_t)(data[0] % 17u) + 1u;
    idle = data[1];
    data += 2;
    len -= 2;
    dan_decoder_init(&d);
    while (pos < len) {
        size_t n = len - pos;
        if (chunk <= 16u && n > chunk) {
            n = chunk;
        }
        (void)feed_all(&d, data + pos, n);
        pos += n;
        if (((unsigned)idle >> (k++ % 8u) & 1u) != 0u && dan_decoder_busy(&d)) {
            dan_decoder_abort(&d);
            /* a whole frame kept from the dropped bytes is collected now */
            (void)feed_all(&d, data, 0);
            FUZZ_CHECK(!dan_decoder_busy(&d));
        }
        FUZZ_CHECK(d.len <= DAN_MAX_FRAME);
    }
    if (dan_decoder_busy(&d)) {
        dan_decoder_abort(&d);
        (void)feed_all(&d, data, 0);
    }
    return 0;
}

/* ---- common payloads -------------------------------------------------- */

static void check_identity(const uint8_t *p, size_t n)
{
    dan_identity_t a, b;
    uint8_t buf[DAN_MAX_PAYLOAD];
    int r;
    if (dan_identity_decode(&a, p, n) != DAN_OK) {
        return;
    }
    FUZZ_CHECK(strlen(a.manufacturer) < DAN_MAX_STRING && strlen(a.model) < DAN_MAX_STRING);
    FUZZ_CHECK(strlen(a.hw_version) < DAN_MAX_STRING && strlen(a.sw_version) < DAN_MAX_STRING);
    r = dan_identity_encode(&a, buf, sizeof buf);
    FUZZ_CHECK(r > 0);
    FUZZ_CHECK(dan_identity_decode(&b, buf, (size_t)r) == DAN_OK);
    FUZZ_CHECK(a.dan_version == b.dan_version && a.baud_mask == b.baud_mask &&
               a.capabilities == b.capabilities && !b.truncated);
    FUZZ_CHECK(!strcmp(a.manufacturer, b.manufacturer) && !strcmp(a.model, b.model) &&
               !strcmp(a.hw_version, b.hw_version) && !strcmp(a.sw_version, b.sw_version));
}

static void check_configure(const uint8_t *p, size_t n)
{
    dan_configure_t a, b;
    uint8_t buf[16];
    int r = dan_configure_decode(&a, p, n);
    if (r != DAN_OK) {
        FUZZ_CHECK(r == DAN_ERR_MALFORMED || r == DAN_ERR_UNSUPPORTED);
        return;
    }
    r = dan_configure_encode(&a, buf, sizeof buf);
    FUZZ_CHECK(r > 0);
    FUZZ_CHECK(dan_configure_decode(&b, buf, (size_t)r) == DAN_OK);
    FUZZ_CHECK(a.type == b.type && a.baud == b.baud);
}

static void check_ack(const uint8_t *p, size_t n)
{
    uint8_t a = 0xAA, b = 0x55, buf[4];
    int r = dan_ack_decode(&a, p, n);
    if (r != DAN_OK) {
        return;
    }
    FUZZ_CHECK(a == DAN_ACK_OK || a == DAN_ACK_FAIL);
    r = dan_ack_encode(a, buf, sizeof buf);
    FUZZ_CHECK(r == 1);
    FUZZ_CHECK(dan_ack_decode(&b, buf, 1) == DAN_OK && a == b);
}

static void check_error(const uint8_t *p, size_t n)
{
    dan_error_msg_t a, b;
    uint8_t buf[DAN_MAX_PAYLOAD];
    int r;
    if (dan_error_decode(&a, p, n) != DAN_OK) {
        return;
    }
    FUZZ_CHECK(strlen(a.text) < DAN_MAX_STRING);
    r = dan_error_encode(a.code, a.error, a.text, buf, sizeof buf);
    FUZZ_CHECK(r > 0);
    FUZZ_CHECK(dan_error_decode(&b, buf, (size_t)r) == DAN_OK);
    FUZZ_CHECK(a.code == b.code && a.error == b.error && !strcmp(a.text, b.text));
}

/* data[0] % 4 picks identity, configure, ack, error; the rest is the payload. */
int dan_fuzz_payloads(const uint8_t *data, size_t len)
{
    if (len < 1u) {
        return 0;
    }
    switch (data[0] % 4u) {
    case 0: check_identity(data + 1, len - 1u); break;
    case 1: check_configure(data + 1, len - 1u); break;
    case 2: check_ack(data + 1, len - 1u); break;
    default: check_error(data + 1, len - 1u); break;
    }
    return 0;
}

/* ---- gateway node: requests through the peripheral engine ------------- */

typedef struct {
    uint8_t out[1024];
    size_t len;
} fuzz_sink_t;

static int sink_write(void *ctx, const uint8_t *data, size_t len)
{
    fuzz_sink_t *s = (fuzz_sink_t *)ctx;
    size_t n = len;
    if (n > sizeof s->out - s->len) {
        n = sizeof s->out - s->len;
    }
    memcpy(s->out + s->len, data, n);
    s->len += n;
    return (int)len;
}

static int sink_baud(void *ctx, uint32_t baud)
{
    (void)ctx;
    (void)baud;
    return 0;
}

/* Everything the gateway sent on DAN decodes to valid frames of its block
 * (or error frames). */
static void check_replies(fuzz_sink_t *s)
{
    dan_decoder_t d;
    const uint8_t *p = s->out;
    size_t left = s->len;
    dan_decoder_init(&d);
    for (;;) {
        size_t used;
        dan_frame_t f;
        int got = dan_decoder_feed(&d, p, left, &used, &f);
        p += used;
        left -= used;
        if (!got) {
            break;
        }
        FUZZ_CHECK(f.code == 0u ||
                   (f.code >= DAN_TYPE_CAN_GW_FIRST && f.code <= DAN_TYPE_CAN_GW_LAST));
    }
    FUZZ_CHECK(d.stats.crc_errors == 0u && d.stats.garbage == 0u && d.stats.oversize == 0u &&
               d.stats.bad_varint == 0u);
    s->len = 0;
}

static void drain_can(dan_gw_node_t *g)
{
    dan_can_frame_t f;
    size_t guard = 0;
    while (dan_gw_node_tx_peek(g, &f)) {
        FUZZ_CHECK(f.dlc <= 8u && (f.flags & DAN_CAN_ERR) == 0u);
        FUZZ_CHECK(f.id <= ((f.flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK));
        dan_gw_node_tx_pop(g);
        FUZZ_CHECK(++guard <= 2u * DAN_GW_NODE_TXQ);
    }
}

static dan_gw_node_t fz_node; /* large: static storage */
static dan_periph_t fz_periph;

/* A script of operations, each starting with an op byte:
 *   op % 4 == 0, 1: a DAN request, code 0x40 + (op >> 2) % 16, then a
 *                   length byte (% 161) and that many payload bytes
 *   op % 4 == 2:    a CAN frame: u32 id LE, flags, dlc, 8 data bytes
 *   op % 4 == 3:    time passes: (op >> 2) * 25 ms (timers fire) */
int dan_fuzz_gw_handlers(const uint8_t *data, size_t len)
{
    fuzz_sink_t sink;
    dan_ptype_t t;
    dan_port_t port;
    uint64_t now = 1000000u;
    size_t i = 0;
    memset(&sink, 0, sizeof sink);
    memset(&port, 0, sizeof port);
    port.write = sink_write;
    port.set_baud = sink_baud;
    port.ctx = &sink;
    port.echo = false;
    FUZZ_CHECK(dan_gw_node_init(&fz_node, NULL, now) == DAN_OK);
    dan_gw_node_ptype(&fz_node, &t);
    FUZZ_CHECK(dan_periph_init(&fz_periph, &port, &t, 1, NULL, 9600, now) == DAN_OK);
    dan_gw_node_attach(&fz_node, &fz_periph);
    dan_gw_node_can_state(&fz_node, true);
    while (i < len) {
        uint8_t op = data[i++];
        switch (op % 4u) {
        case 0:
        case 1: {
            uint8_t frame[DAN_MAX_FRAME];
            size_t plen = 0;
            int n;
            if (i < len) {
                plen = data[i++] % (DAN_MAX_PAYLOAD + 1u);
            }
            if (plen > len - i) {
                plen = len - i;
            }
            {
                /* op 1: sealed as a client would, so the handlers behind
                 * the seal are reached; op 0: as is (the seal check). */
                uint32_t code = DAN_TYPE_CAN_GW_FIRST + (uint32_t)((op >> 2) % 16u);
                uint8_t body[DAN_MAX_PAYLOAD];
                int bl = (int)plen;
                memcpy(body, data + i, plen);
                if (op % 4u == 1u && dan_gw_sealed_code(code)) {
                    bl = dan_gw_seal(code, DAN_GW_REQUEST, body, plen, sizeof body);
                    if (bl < 0) {
                        bl = (int)plen;
                    }
                }
                n = dan_frame_encode(code, body, (size_t)bl, frame, sizeof frame);
            }
            FUZZ_CHECK(n > 0);
            i += plen;
            /* the line was idle long enough for any reply to have left */
            now += 200000u;
            dan_periph_poll(&fz_periph, now);
            dan_periph_rx(&fz_periph, frame, (size_t)n, now);
            now += 3000u; /* past the turnaround, inside the reply window */
            dan_periph_poll(&fz_periph, now);
            dan_gw_node_poll(&fz_node, now);
            break;
        }
        case 2: {
            dan_can_frame_t f;
            uint8_t b[14];
            size_t n = len - i < sizeof b ? len - i : sizeof b;
            memset(b, 0, sizeof b);
            memcpy(b, data + i, n);
            i += n;
            memset(&f, 0, sizeof f);
            f.id =
                (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
            f.flags = (uint8_t)(b[4] & (DAN_CAN_EXT | DAN_CAN_RTR | DAN_CAN_ERR));
            f.id &= (f.flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK;
            f.dlc = (uint8_t)(b[5] % 9u);
            memcpy(f.data, b + 6, 8);
            now += 100u;
            dan_gw_node_rx_can(&fz_node, &f, now);
            break;
        }
        default:
            now += (uint64_t)(op >> 2) * 25000u;
            dan_periph_poll(&fz_periph, now);
            dan_gw_node_poll(&fz_node, now);
            break;
        }
        FUZZ_CHECK(dan_gw_node_next_us(&fz_node, now) > 0u);
        drain_can(&fz_node);
        check_replies(&sink);
    }
    now += 1000000u;
    dan_periph_poll(&fz_periph, now);
    dan_gw_node_poll(&fz_node, now);
    dan_gw_node_failsafe(&fz_node, now);
    drain_can(&fz_node);
    check_replies(&sink);
    return 0;
}

/* ---- DroneCAN: reassembly and DSDL ------------------------------------ */

/* Decodes payload as data type dtid; what decodes must re-encode, and the
 * exact-integer types must come back identical. */
static void dsdl_any(uint16_t dtid, const uint8_t *p, size_t n)
{
    uint8_t buf[DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE];
    int r;
    switch (dtid) {
    case DAN_DC_NODE_STATUS_ID: {
        dan_dc_node_status_t a, b;
        if (dan_dc_node_status_decode(&a, p, n) == DAN_OK) {
            r = dan_dc_node_status_encode(&a, buf, sizeof buf);
            FUZZ_CHECK(r > 0 && dan_dc_node_status_decode(&b, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(a.uptime_sec == b.uptime_sec && a.health == b.health && a.mode == b.mode &&
                       a.sub_mode == b.sub_mode &&
                       a.vendor_specific_status_code == b.vendor_specific_status_code);
        }
        break;
    }
    case DAN_DC_GET_NODE_INFO_ID: {
        static dan_dc_get_node_info_rsp_t a, b;
        (void)dan_dc_get_node_info_req_decode(p, n);
        if (dan_dc_get_node_info_rsp_decode(&a, p, n) == DAN_OK) {
            FUZZ_CHECK(a.name_len <= DAN_DC_GET_NODE_INFO_NAME_MAX && a.name[a.name_len] == '\0');
            r = dan_dc_get_node_info_rsp_encode(&a, buf, sizeof buf);
            FUZZ_CHECK(r >= 0 && dan_dc_get_node_info_rsp_decode(&b, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(a.name_len == b.name_len && !memcmp(a.name, b.name, a.name_len) &&
                       a.hardware_version.coa_len == b.hardware_version.coa_len &&
                       !memcmp(a.hardware_version.unique_id, b.hardware_version.unique_id, 16));
        }
        break;
    }
    case DAN_DC_ESC_RAW_COMMAND_ID: {
        dan_dc_esc_raw_command_t a, b;
        if (dan_dc_esc_raw_command_decode(&a, p, n) == DAN_OK) {
            FUZZ_CHECK(a.count <= DAN_DC_ESC_RAW_COMMAND_MAX_CMDS);
            r = dan_dc_esc_raw_command_encode(&a, buf, sizeof buf);
            FUZZ_CHECK(r >= 0 && dan_dc_esc_raw_command_decode(&b, buf, (size_t)r) == DAN_OK);
            /* the count may differ only by zero padding read as values: never
             * when a 14-bit value fits in fewer than 8 bits */
            FUZZ_CHECK(
                !memcmp(a.cmd, b.cmd, sizeof(int16_t) * (a.count < b.count ? a.count : b.count)));
        }
        break;
    }
    case DAN_DC_ESC_STATUS_ID: {
        dan_dc_esc_status_t a;
        if (dan_dc_esc_status_decode(&a, p, n) == DAN_OK) {
            FUZZ_CHECK(dan_dc_esc_status_encode(&a, buf, sizeof buf) > 0);
        }
        break;
    }
    case DAN_DC_ESC_STATUS_EXTENDED_ID: {
        dan_dc_esc_status_extended_t a, b;
        if (dan_dc_esc_status_extended_decode(&a, p, n) == DAN_OK) {
            r = dan_dc_esc_status_extended_encode(&a, buf, sizeof buf);
            FUZZ_CHECK(r > 0 && dan_dc_esc_status_extended_decode(&b, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(a.input_pct == b.input_pct && a.output_pct == b.output_pct &&
                       a.motor_temperature_degC == b.motor_temperature_degC &&
                       a.motor_angle == b.motor_angle && a.status_flags == b.status_flags &&
                       a.esc_index == b.esc_index);
        }
        break;
    }
    case DAN_DC_ARMING_STATUS_ID: {
        dan_dc_arming_status_t a, b;
        if (dan_dc_arming_status_decode(&a, p, n) == DAN_OK) {
            r = dan_dc_arming_status_encode(&a, buf, sizeof buf);
            FUZZ_CHECK(r > 0 && dan_dc_arming_status_decode(&b, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(!memcmp(&a, &b, sizeof a));
        }
        break;
    }
    default: {
        static dan_dc_tunnel_targetted_t tt;
        static dan_dc_tunnel_broadcast_t tb;
        if (dan_dc_tunnel_targetted_decode(&tt, p, n) == DAN_OK) {
            FUZZ_CHECK(dan_dc_tunnel_targetted_encode(&tt, buf, sizeof buf) >= 0);
        }
        if (dan_dc_tunnel_broadcast_decode(&tb, p, n) == DAN_OK) {
            FUZZ_CHECK(dan_dc_tunnel_broadcast_encode(&tb, buf, sizeof buf) >= 0);
        }
        break;
    }
    }
}

/* data[0] % 8 picks the type; the rest is the serialized payload. */
int dan_fuzz_dsdl(const uint8_t *data, size_t len)
{
    static const uint16_t ids[8] = {DAN_DC_NODE_STATUS_ID,
                                    DAN_DC_GET_NODE_INFO_ID,
                                    DAN_DC_ESC_RAW_COMMAND_ID,
                                    DAN_DC_ESC_STATUS_ID,
                                    DAN_DC_ESC_STATUS_EXTENDED_ID,
                                    DAN_DC_ARMING_STATUS_ID,
                                    0u,
                                    0xFFFFu};
    if (len < 1u) {
        return 0;
    }
    dsdl_any(ids[data[0] % 8u], data + 1, len - 1u);
    return 0;
}

static bool fz_accept(void *user, uint16_t dtid, uint8_t transfer_type, uint8_t source,
                      uint64_t *signature)
{
    (void)user;
    (void)source;
    if (dan_dc_dsdl_signature(transfer_type, dtid, signature)) {
        return true;
    }
    *signature = 0x0123456789ABCDEFull; /* unknown types too: more reassembly paths */
    return (dtid & 1u) == 0u;
}

static dan_dc_rx_t fz_rx;

/* Frames of 14 bytes: u32 id LE, flags (low 3 bits: EXT/RTR/ERR; high 4:
 * ms to wait before it), dlc, 8 data bytes. */
int dan_fuzz_dronecan_rx(const uint8_t *data, size_t len)
{
    uint64_t now = 5000000u;
    size_t i = 0;
    dan_dc_rx_init(&fz_rx, len > 0u ? (uint8_t)(data[0] % 128u) : 10u, fz_accept, NULL);
    if (len > 0u) {
        i = 1;
    }
    while (i < len) {
        uint8_t b[14];
        size_t n = len - i < sizeof b ? len - i : sizeof b;
        dan_can_frame_t f;
        dan_dc_transfer_t t;
        int r;
        memset(b, 0, sizeof b);
        memcpy(b, data + i, n);
        i += n;
        memset(&f, 0, sizeof f);
        f.id = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
        f.flags = (uint8_t)(b[4] & 7u);
        f.id &= (f.flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK;
        f.dlc = (uint8_t)(b[5] % 9u);
        memcpy(f.data, b + 6, 8);
        now += (uint64_t)(b[4] >> 4) * 100000u;
        r = dan_dc_rx_frame(&fz_rx, &f, now, &t);
        FUZZ_CHECK(r == 0 || r == 1);
        if (r == 1) {
            FUZZ_CHECK(t.payload_len <= DAN_DC_MAX_TRANSFER);
            FUZZ_CHECK(t.payload_len == 0u || t.payload != NULL);
            FUZZ_CHECK(t.transfer_id <= 31u && t.priority <= 31u && t.source_node <= 127u);
            dsdl_any(t.data_type_id, t.payload, t.payload_len);
        }
        if ((b[4] & 0x80u) != 0u) {
            dan_dc_rx_cleanup(&fz_rx, now);
        }
    }
    return 0;
}

/* ---- SLCAN line parser ------------------------------------------------ */

int dan_fuzz_slcan(const uint8_t *data, size_t len)
{
    dan_can_frame_t f, g;
    char line[64];
    int r = dan_slcan_parse_line((const char *)data, len, &f);
    FUZZ_CHECK(r == 0 || r == 1 || r == DAN_ERR_MALFORMED);
    if (r != 1) {
        return 0;
    }
    FUZZ_CHECK(f.dlc <= 8u && (f.flags & DAN_CAN_ERR) == 0u);
    FUZZ_CHECK(f.id <= ((f.flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK));
    r = dan_slcan_format(&f, line, sizeof line);
    FUZZ_CHECK(r > 1 && r <= DAN_SLCAN_FORMAT_MAX && line[r - 1] == '\r' && line[r] == '\0');
    FUZZ_CHECK(dan_slcan_parse_line(line, (size_t)r - 1u, &g) == 1);
    FUZZ_CHECK(g.id == f.id && g.flags == f.flags && g.dlc == f.dlc);
    FUZZ_CHECK((f.flags & DAN_CAN_RTR) || !memcmp(g.data, f.data, f.dlc));
    return 0;
}

/* ---- gateway client: response decoders -------------------------------- */

static dan_master_t fz_master;

/* data[0] % 12: response code 0x42 + k; data[1]: tunnel port and client
 * offsets seed; the rest is the response payload. */
int dan_fuzz_gw_client(const uint8_t *data, size_t len)
{
    dan_gw_t gw;
    dan_reader_t r;
    uint32_t code;
    size_t n, i;
    uint8_t seed;
    if (len < 2u) {
        return 0;
    }
    code = DAN_GW_CODE_ESC_CMD + (uint32_t)(data[0] % 12u);
    seed = data[1];
    data += 2;
    len -= 2;
    n = len > DAN_MAX_PAYLOAD ? DAN_MAX_PAYLOAD : len;
    memset(&fz_master, 0, sizeof fz_master);
    fz_master.result = DAN_OK;
    fz_master.resp_code = code;
    memcpy(fz_master.resp, data, n);
    fz_master.resp_len = n;
    if ((seed & 0x80u) != 0u) {
        /* sealed as the gateway would, so the decoders behind the seal are
         * reached; otherwise as is (the seal check) */
        int sl = dan_gw_seal(code, DAN_GW_RESPONSE, fz_master.resp, n, sizeof fz_master.resp);
        if (sl > 0) {
            fz_master.resp_len = (size_t)sl;
        }
    }
    dan_gw_init(&gw, &fz_master);
    gw.code = code;
    gw.port = (uint8_t)(seed % DAN_GW_TUNNELS);
    gw.tun[gw.port].wr_offset = (uint32_t)(seed >> 1) * 0x01010101u;
    gw.tun[gw.port].rd_offset = (uint32_t)(seed >> 2) * 0x00FF00FFu;
    gw.can_rx_next = (uint32_t)seed << 24;
    (void)dan_gw_complete(&gw, 0);
    FUZZ_CHECK(gw.code == 0u);
    FUZZ_CHECK(gw.result == DAN_OK || gw.result < 0);
    switch (code) {
    case DAN_GW_CODE_NODES: {
        dan_gw_nodes_hdr_t h;
        dan_gw_node_entry_t e;
        if (dan_gw_nodes_begin(&gw, &r, &h) == DAN_OK) {
            for (i = 0; i < h.count && dan_gw_nodes_next(&r, &e) == DAN_OK; i++) {
            }
        }
        break;
    }
    case DAN_GW_CODE_NODE_INFO: {
        dan_gw_node_info_t ni;
        if (dan_gw_node_info_get(&gw, &ni) == DAN_OK) {
            FUZZ_CHECK(memchr(ni.name, '\0', sizeof ni.name) != NULL);
        }
        break;
    }
    case DAN_GW_CODE_TUN_XFER: {
        const uint8_t *d;
        size_t dl;
        if (dan_gw_tunnel_data(&gw, &d, &dl) == DAN_OK && dl > 0u) {
            FUZZ_CHECK(d >= fz_master.resp && d + dl <= fz_master.resp + fz_master.resp_len);
        }
        break;
    }
    case DAN_GW_CODE_CAN_RECV: {
        dan_gw_can_recv_t q;
        dan_can_frame_t f;
        if (dan_gw_can_begin(&gw, &r, &q) == DAN_OK) {
            for (i = 0; i < q.count && dan_gw_can_next(&r, &f) == DAN_OK; i++) {
                FUZZ_CHECK(f.dlc <= 8u);
            }
        }
        break;
    }
    case DAN_GW_CODE_CAN_FILTER: {
        uint8_t res, cnt;
        dan_gw_filter_t f;
        if (dan_gw_filter_begin(&gw, &r, &res, &cnt) == DAN_OK) {
            for (i = 0; i < cnt && dan_gw_filter_next(&r, &f) == DAN_OK; i++) {
            }
        }
        break;
    }
    default: break;
    }
    return 0;
}

const dan_fuzz_target_t dan_fuzz_targets[] = {
    {"frame", dan_fuzz_frame},
    {"payloads", dan_fuzz_payloads},
    {"gw_handlers", dan_fuzz_gw_handlers},
    {"dronecan_rx", dan_fuzz_dronecan_rx},
    {"dsdl", dan_fuzz_dsdl},
    {"slcan", dan_fuzz_slcan},
    {"gw_client", dan_fuzz_gw_client},
};
const size_t dan_fuzz_ntargets = sizeof dan_fuzz_targets / sizeof dan_fuzz_targets[0];
