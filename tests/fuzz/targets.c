/* Fuzz entry functions (see targets.h). Each checks invariants that must
 * hold for any input and calls abort() when one breaks. Built into every
 * libFuzzer binary (tests/fuzz/fuzz.mk) and #included by the replay test
 * tests/unit/test_fuzz_regressions.c, so it compiles with the project's
 * strict warning flags. */
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "dan/dan.h"
#include "dan/can_gw/client.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/node.h"
#include "can_backend.h"
#include "file_store_ram.h"
#include "targets.h"

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

static void check_baud_mask(uint16_t mask);

static void check_identity(const uint8_t *p, size_t n)
{
    dan_identity_t a, b;
    uint8_t buf[DAN_MAX_PAYLOAD];
    uint16_t mask = 0;
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
    /* the master's quick look at the baud mask reads what the decoder did */
    FUZZ_CHECK(dan_identity_baud_mask(p, n, &mask) == DAN_OK && mask == a.baud_mask);
    check_baud_mask(a.baud_mask);
}

/* The v1 bauds of a mask: each bit names one baud and back; the highest
 * is one of them (or the base baud). */
static void check_baud_mask(uint16_t mask)
{
    uint32_t top = dan_baud_highest(mask);
    unsigned i;
    FUZZ_CHECK(dan_baud_is_v1(top));
    FUZZ_CHECK(top == DAN_BAUD_BASE || (mask & dan_mask_bit_of_baud(top)) != 0u);
    for (i = 0; i < 16u; i++) {
        uint16_t bit = (uint16_t)(1u << i);
        uint32_t baud = dan_baud_of_mask_bit(bit);
        FUZZ_CHECK(baud == 0u || (dan_mask_bit_of_baud(baud) == bit && dan_baud_is_v1(baud)));
        FUZZ_CHECK(baud == 0u || (mask & bit) == 0u || baud <= top);
    }
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
    uint32_t code = 0;
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
    FUZZ_CHECK(dan_error_code(p, n, &code) == DAN_OK && code == a.code);
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
                   (f.code >= DAN_TYPE_CAN_GW_FIRST && f.code <= DAN_TYPE_CAN_GW_LAST) ||
                   (f.code >= DAN_TYPE_CAN_GW_BLOCK2 && f.code <= DAN_TYPE_CAN_GW_BLOCK2_LAST));
    }
    FUZZ_CHECK(d.stats.crc_errors == 0u && d.stats.garbage == 0u && d.stats.oversize == 0u &&
               d.stats.bad_varint == 0u);
    s->len = 0;
}

static dan_gw_node_t fz_node; /* large: static storage */
static ram_store_t fz_store;  /* the file store of gw_handlers' gateway */
static dan_periph_t fz_periph;
static fuzz_sink_t fz_sink;
static dan_port_t fz_port;
static dan_ptype_t fz_ptype;

/* The gateway node (cfg: NULL for the defaults) behind a peripheral engine
 * whose replies land in fz_sink. */
static void fz_gateway_start(const dan_gw_node_config_t *cfg, uint64_t now)
{
    memset(&fz_sink, 0, sizeof fz_sink);
    memset(&fz_port, 0, sizeof fz_port);
    fz_port.write = sink_write;
    fz_port.set_baud = sink_baud;
    fz_port.ctx = &fz_sink;
    fz_port.echo = false;
    FUZZ_CHECK(dan_gw_node_init(&fz_node, cfg, now) == DAN_OK);
    dan_gw_node_ptype(&fz_node, &fz_ptype);
    FUZZ_CHECK(dan_periph_init(&fz_periph, &fz_port, &fz_ptype, 1, NULL, 9600, now) == DAN_OK);
    dan_gw_node_attach(&fz_node, &fz_periph);
    dan_gw_node_can_state(&fz_node, true);
}

#define FZ_PRIO 16u /* of the transfers the targets inject */

static bool fz_accept_any(void *user, uint16_t dtid, uint8_t tt, uint8_t src, uint64_t *sig)
{
    (void)user;
    (void)src;
    return dan_dc_dsdl_signature(tt, dtid, sig);
}

/* A transfer from node src (0: anonymous) into the gateway. */
static void fz_inject(uint8_t src, uint8_t tt, uint16_t dtid, uint8_t dst, uint8_t tid,
                      const uint8_t *payload, int plen, uint64_t now)
{
    dan_dc_transfer_t t;
    dan_can_frame_t f[40];
    uint64_t sig = 0;
    int n, i;
    if (plen < 0) {
        return;
    }
    (void)dan_dc_dsdl_signature(tt, dtid, &sig);
    dan_dc_transfer_init(&t, dtid, sig, (dan_dc_transfer_type_t)tt, payload, (size_t)plen);
    t.priority = FZ_PRIO;
    t.source_node = src;
    t.destination_node = dst;
    t.transfer_id = tid;
    n = dan_dc_tx_build(&t, f, sizeof f / sizeof f[0]);
    for (i = 0; i < n; i++) {
        dan_gw_node_rx_can(&fz_node, &f[i], now);
    }
}

#define FZ_IDLE_US 2000u /* a master's pause between a reply and its next request */

/* The code of a request op: 0x40..0x4F, then the second block 0x50..0x5F
 * (0x50 and 0x51 unused there: unknown codes). */
static uint32_t fz_code(uint8_t op)
{
    uint32_t k = (uint32_t)(op >> 2) % 32u;
    return k < 16u ? DAN_TYPE_CAN_GW_FIRST + k : DAN_TYPE_CAN_GW_BLOCK2 + (k - 16u);
}

/* The end of the link's last transmission as a 64-bit time (the link
 * keeps 32-bit times; now if it has passed). */
static uint64_t fz_tx_end(const dan_link_t *l)
{
    uint32_t end = l->tx_start_us + (uint32_t)l->tx_len * l->char_us;
    return dan_link_wait_time(l, dan_link_due_in(l, end));
}

/* One DAN request to the gateway, sealed as a client would seal it (so the
 * handlers behind the seal are reached) or as is (the seal check). It
 * comes FZ_IDLE_US after the earlier reply has left: as soon as a master
 * could send it, so a script of requests is a burst of traffic and time
 * passes (timers fire, broadcasts go out) where the script says so. */
static void fz_request(uint32_t code, const uint8_t *payload, size_t plen, bool seal, uint64_t *now)
{
    uint8_t frame[DAN_MAX_FRAME], body[DAN_MAX_PAYLOAD];
    int bl = (int)plen, n;
    uint64_t end;
    memcpy(body, payload, plen);
    if (seal && dan_gw_sealed_code(code)) {
        bl = dan_gw_seal(code, DAN_GW_REQUEST, body, plen, sizeof body);
        if (bl < 0) {
            bl = (int)plen;
        }
    }
    n = dan_frame_encode(code, body, (size_t)bl, frame, sizeof frame);
    FUZZ_CHECK(n > 0);
    end = fz_tx_end(&fz_periph.link);
    *now = (end > *now ? end : *now) + FZ_IDLE_US;
    dan_periph_poll(&fz_periph, *now);
    dan_periph_rx(&fz_periph, frame, (size_t)n, *now);
    *now += 3000u; /* past the turnaround, inside the reply window */
    dan_periph_poll(&fz_periph, *now);
    dan_gw_node_poll(&fz_node, *now);
}

/* Takes a length byte (% (max + 1)) and that many bytes (fewer at the end)
 * from data at *i; returns the length, *p the bytes. */
static size_t fz_take(const uint8_t *data, size_t len, size_t *i, size_t max, const uint8_t **p)
{
    size_t n = 0;
    if (*i < len) {
        n = data[(*i)++] % (max + 1u);
    }
    if (n > len - *i) {
        n = len - *i;
    }
    *p = data + *i;
    *i += n;
    return n;
}

/* A CAN frame from 14 bytes at data[*i..]: u32 id LE, flags, dlc, 8 data. */
static void fz_can_frame(const uint8_t *data, size_t len, size_t *i, dan_can_frame_t *f)
{
    uint8_t b[14];
    size_t n = len - *i < sizeof b ? len - *i : sizeof b;
    memset(b, 0, sizeof b);
    memcpy(b, data + *i, n);
    *i += n;
    memset(f, 0, sizeof *f);
    f->id = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
    f->flags = (uint8_t)(b[4] & (DAN_CAN_EXT | DAN_CAN_RTR | DAN_CAN_ERR));
    f->id &= (f->flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK;
    f->dlc = (uint8_t)(b[5] % 9u);
    memcpy(f->data, b + 6, 8);
}

/* The one upload is what the store holds: the same name, have bytes
 * (never over the size) and their CRC-32. */
static void check_upload(const dan_gw_node_upload_t *u, const ram_store_t *s)
{
    if (!u->open) {
        return;
    }
    FUZZ_CHECK(u->have <= u->size && u->size <= s->fs.max_size);
    FUZZ_CHECK(dan_gw_file_name_ok(u->name, strlen(u->name)));
    FUZZ_CHECK(s->partial.used && strcmp(s->partial.name, u->name) == 0);
    FUZZ_CHECK(s->partial.len == u->have);
    FUZZ_CHECK(dan_gw_crc32(0, s->partial.data, u->have) == u->crc);
}

/* ---- gw_handlers: the CAN side's file reader ---------------------------- */

#define FZ_READER    100u /* the node whose file requests are checked */
#define FZ_FILE_SIZE 600u /* the store's cap: uploads reach it in a few requests */

/* A file request of FZ_READER in flight (by transfer ID). */
typedef struct {
    bool valid; /* one request of this ID, answer not seen yet */
    uint16_t dtid;
    uint32_t gen; /* fzh.gen when it was sent */
    uint64_t offset;
    bool named; /* the path is a name the store may hold */
    char name[DAN_GW_FILE_NAME_MAX + 1u];
} fz_file_req_t;

static struct {
    dan_dc_rx_t lis; /* FZ_READER: the gateway's answers, reassembled */
    fz_file_req_t req[DAN_DC_TRANSFER_ID_MASK + 1u];
    uint32_t gen; /* counts DAN requests that may change the committed files */
} fzh;

static bool fz_accept_file(void *user, uint16_t dtid, uint8_t tt, uint8_t src, uint64_t *sig)
{
    (void)user;
    (void)src;
    return tt == DAN_DC_TRANSFER_RESPONSE &&
           (dtid == DAN_DC_FILE_READ_ID || dtid == DAN_DC_FILE_GETINFO_ID) &&
           dan_dc_dsdl_signature(tt, dtid, sig);
}

/* Remembers a Read / GetInfo request FZ_READER sends (tid: its ID). */
static void fz_note_file_req(uint16_t dtid, uint8_t tid, const uint8_t *p, size_t n)
{
    static dan_dc_file_req_t m;
    fz_file_req_t *q = &fzh.req[tid & DAN_DC_TRANSFER_ID_MASK];
    int r = dtid == DAN_DC_FILE_READ_ID ? dan_dc_file_read_req_decode(&m, p, n)
                                        : dan_dc_file_getinfo_req_decode(&m, p, n);
    if (q->valid || r != DAN_OK) {
        q->valid = false; /* two in flight with one ID: answers not told apart */
        return;
    }
    q->valid = true;
    q->dtid = dtid;
    q->gen = fzh.gen;
    q->offset = m.offset;
    q->named = dan_gw_file_path_name(m.path, m.path_len, q->name);
}

/* An answer to FZ_READER. Errors are always allowed (the store may fail);
 * a success holds exactly the store's bytes at the offset (or its size),
 * as long as no DAN request could have changed the files since. */
static void fz_check_file_rsp(const dan_dc_transfer_t *t)
{
    static dan_dc_file_read_rsp_t rr;
    dan_dc_file_getinfo_rsp_t ir;
    fz_file_req_t *q = &fzh.req[t->transfer_id & DAN_DC_TRANSFER_ID_MASK];
    const ram_file_t *f;
    bool same;
    if (t->data_type_id == DAN_DC_FILE_READ_ID) {
        FUZZ_CHECK(dan_dc_file_read_rsp_decode(&rr, t->payload, t->payload_len) == DAN_OK);
        FUZZ_CHECK(rr.data_len <= DAN_DC_FILE_READ_MAX && (rr.error == 0 || rr.data_len == 0u));
    } else {
        FUZZ_CHECK(dan_dc_file_getinfo_rsp_decode(&ir, t->payload, t->payload_len) == DAN_OK);
    }
    same = q->valid && q->dtid == t->data_type_id && q->gen == fzh.gen;
    q->valid = false;
    if (!same || (t->data_type_id == DAN_DC_FILE_READ_ID ? rr.error : ir.error) != 0) {
        return;
    }
    FUZZ_CHECK(q->named); /* no path that is not a name is served */
    f = ram_store_file(&fz_store, q->name);
    FUZZ_CHECK(f != NULL);
    if (t->data_type_id == DAN_DC_FILE_GETINFO_ID) {
        FUZZ_CHECK(ir.size == f->len);
        return;
    }
    if (q->offset >= f->len) {
        FUZZ_CHECK(rr.data_len == 0u);
        return;
    }
    FUZZ_CHECK(rr.data_len == (f->len - q->offset < DAN_DC_FILE_READ_MAX ? f->len - q->offset
                                                                         : DAN_DC_FILE_READ_MAX));
    FUZZ_CHECK(!memcmp(rr.data, f->data + q->offset, rr.data_len));
}

/* What the gateway sends on CAN: well-formed frames; the answers to
 * FZ_READER checked. The bus takes them all. */
static void fz_drain_checked(uint64_t now)
{
    dan_can_frame_t f;
    dan_dc_transfer_t t;
    size_t guard = 0;
    while (dan_gw_node_tx_peek(&fz_node, &f)) {
        FUZZ_CHECK(f.dlc <= 8u && (f.flags & DAN_CAN_ERR) == 0u);
        FUZZ_CHECK(f.id <= ((f.flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK));
        FUZZ_CHECK(++guard <= 2u * DAN_GW_NODE_TXQ);
        dan_gw_node_tx_sent(&fz_node, now);
        if (dan_dc_rx_frame(&fzh.lis, &f, now, &t) == 1 && t.source_node == fz_node.cfg.node_id) {
            fz_check_file_rsp(&t);
        }
    }
}

/* The transfers of op 2 (k = op >> 2, 1..15; 0 is a raw frame). */
static const struct {
    uint16_t dtid;
    uint8_t tt;
} fz_transfers[16] = {
    {0, 0},
    {DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_REQUEST},
    {DAN_DC_FILE_GETINFO_ID, DAN_DC_TRANSFER_REQUEST},
    {DAN_DC_GET_NODE_INFO_ID, DAN_DC_TRANSFER_REQUEST},
    {DAN_DC_NODE_STATUS_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_ESC_STATUS_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_ESC_STATUS_EXTENDED_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_TUNNEL_TARGETTED_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_TUNNEL_BROADCAST_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_ALLOCATION_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_TEMPERATURE_ID, DAN_DC_TRANSFER_BROADCAST},
    {DAN_DC_GET_NODE_INFO_ID, DAN_DC_TRANSFER_RESPONSE},
    {DAN_DC_PARAM_GETSET_ID, DAN_DC_TRANSFER_RESPONSE},
    {DAN_DC_PARAM_OPCODE_ID, DAN_DC_TRANSFER_RESPONSE},
    {DAN_DC_RESTART_ID, DAN_DC_TRANSFER_RESPONSE},
    {DAN_DC_FW_BEGIN_ID, DAN_DC_TRANSFER_RESPONSE},
};

/* Op 2: a raw CAN frame (k 0: 14 bytes, see fz_can_frame) or a whole
 * transfer k (source node byte, transfer ID byte, length byte % 256,
 * payload) built with the right CRC and toggles, so the services behind
 * the transport are reached. */
static void fz_can_op(uint8_t op, const uint8_t *data, size_t len, size_t *i, uint64_t *now)
{
    unsigned k = (unsigned)(op >> 2) % 16u;
    uint8_t b[2] = {0, 0};
    const uint8_t *p;
    size_t n, plen;
    if (k == 0u) {
        dan_can_frame_t f;
        fz_can_frame(data, len, i, &f);
        *now += 100u;
        dan_gw_node_rx_can(&fz_node, &f, *now);
        return;
    }
    for (n = 0; n < 2u && *i < len; n++) {
        b[n] = data[(*i)++];
    }
    plen = fz_take(data, len, i, 255u, &p);
    b[0] %= 128u;
    b[1] &= DAN_DC_TRANSFER_ID_MASK;
    if (b[0] == FZ_READER && fz_transfers[k].tt == DAN_DC_TRANSFER_REQUEST &&
        fz_transfers[k].dtid != DAN_DC_GET_NODE_INFO_ID) {
        fz_note_file_req(fz_transfers[k].dtid, b[1], p, plen);
    }
    *now += 100u;
    fz_inject(b[0], fz_transfers[k].tt, fz_transfers[k].dtid,
              fz_transfers[k].tt == DAN_DC_TRANSFER_BROADCAST ? 0u : fz_node.cfg.node_id, b[1], p,
              (int)plen, *now);
}

/* Op 3: time passes, (op >> 2) * 25 ms, and the bus takes what the gateway
 * queued; op 3 itself (no time) makes the store fail from its next call
 * on, or heals it. */
static void fz_time_op(uint8_t op, uint64_t *now)
{
    if (op == 3u) {
        fz_store.fail_from = fz_store.fail_from == 0u ? fz_store.calls + 1u : 0u;
        return;
    }
    *now += (uint64_t)(op >> 2) * 25000u;
    dan_periph_poll(&fz_periph, *now);
    dan_gw_node_poll(&fz_node, *now);
    fz_drain_checked(*now);
}

/* A script of operations, each starting with an op byte:
 *   op % 4 == 0, 1: a DAN request, code fz_code(op) (both blocks), then a
 *                   length byte (% 161) and that many payload bytes; op 1
 *                   sealed, op 0 as is
 *   op % 4 == 2:    a CAN frame or transfer into the gateway (fz_can_op)
 *   op % 4 == 3:    time passes, the bus sends (fz_time_op)
 * The gateway has a RAM file store (tests/unit/file_store_ram.c, capped at
 * FZ_FILE_SIZE). Checked after each: the replies on DAN, the upload, the
 * next wake-up; what goes out on CAN when the bus sends. */
int dan_fuzz_gw_handlers(const uint8_t *data, size_t len)
{
    uint64_t now = 1000000u;
    size_t i = 0;
    dan_gw_node_config_t cfg;
    ram_store_init(&fz_store);
    fz_store.fs.max_size = FZ_FILE_SIZE;
    memset(fzh.req, 0, sizeof fzh.req);
    fzh.gen = 0;
    dan_dc_rx_init(&fzh.lis, FZ_READER, fz_accept_file, NULL);
    dan_gw_node_config_default(&cfg);
    cfg.files = &fz_store.fs;
    fz_gateway_start(&cfg, now);
    while (i < len) {
        uint8_t op = data[i++];
        switch (op % 4u) {
        case 0:
        case 1: {
            const uint8_t *p;
            uint32_t code = fz_code(op);
            size_t plen = fz_take(data, len, &i, DAN_MAX_PAYLOAD, &p);
            fzh.gen += code >= DAN_GW_CODE_FILE_OPEN && code <= DAN_GW_CODE_FILE_REMOVE;
            fz_request(code, p, plen, op % 4u == 1u, &now);
            break;
        }
        case 2: fz_can_op(op, data, len, &i, &now); break;
        default: fz_time_op(op, &now); break;
        }
        FUZZ_CHECK(dan_gw_node_next_us(&fz_node, now) > 0u);
        check_replies(&fz_sink);
        check_upload(&fz_node.upload, &fz_store);
    }
    now += 1000000u;
    dan_periph_poll(&fz_periph, now);
    dan_gw_node_poll(&fz_node, now);
    dan_gw_node_failsafe(&fz_node, now);
    fz_drain_checked(now);
    check_replies(&fz_sink);
    return 0;
}

/* ---- gateway node: the allocation server and the node table ---------- */

#define FZ_UIDS     6u  /* unique IDs of the allocatees and nodes */
#define FZ_REQS     16u /* service requests of the gateway remembered */
#define FZ_LISTENER 127u

typedef struct {
    uint8_t dst, tid, ttype;
    uint16_t dtid;
} fz_req_t;

/* A node of the node table before an operation. */
typedef struct {
    uint8_t id;
    bool uid_known;
    uint8_t uid[DAN_DC_UNIQUE_ID_SIZE];
} fz_seen_t;

static struct {
    dan_gw_node_config_t cfg;
    dan_gw_storage_t st;
    uint8_t blob[DAN_GW_DNA_BLOB_MAX]; /* the "flash" */
    size_t blob_len;
    fz_req_t reqs[FZ_REQS]; /* ring: the gateway's service requests */
    size_t nreq;
    dan_dc_rx_t lis; /* the gateway's broadcasts, reassembled */
    dan_dc_tid_table_t tids;
    /* the state before the operation */
    dan_gw_dna_entry_t table[DAN_GW_NODE_DNA_MAX];
    uint8_t n;
    fz_seen_t seen[DAN_GW_NODE_MAX_NODES];
} fzd;

static int fzd_load(void *ctx, uint8_t *buf, size_t cap)
{
    (void)ctx;
    FUZZ_CHECK(fzd.blob_len <= cap);
    memcpy(buf, fzd.blob, fzd.blob_len);
    return (int)fzd.blob_len;
}

static int fzd_store(void *ctx, const uint8_t *buf, size_t len)
{
    (void)ctx;
    FUZZ_CHECK(len <= sizeof fzd.blob && dan_gw_dna_blob_check(buf, len) == DAN_GW_DNA_BLOB_OK);
    memcpy(fzd.blob, buf, len);
    fzd.blob_len = len;
    return DAN_OK;
}

/* Unique ID k of the pool: pairs share the first stage's 6 bytes. */
static void fz_uid(unsigned k, uint8_t *uid)
{
    memset(uid, (int)(k / 2u + 1u), DAN_DC_ALLOCATION_UID_PER_REQUEST);
    memset(uid + DAN_DC_ALLOCATION_UID_PER_REQUEST, (int)(0x40u + k),
           DAN_DC_UNIQUE_ID_SIZE - DAN_DC_ALLOCATION_UID_PER_REQUEST);
}

static uint8_t fz_next_tid(uint16_t dtid, uint8_t tt, uint8_t dst)
{
    int tid = dan_dc_tid_next(&fzd.tids, dtid, tt, dst);
    return tid >= 0 ? (uint8_t)tid : 0u;
}

/* An Allocation request stage of allocatee k (b: k, stage; pref: the
 * preferred ID, bit7 none). Stage 3 is garbage: a length the protocol
 * does not expect. */
static void fz_alloc_stage(uint8_t b, uint8_t pref, uint64_t now)
{
    static const uint8_t off[3] = {0, 6, 12}, cnt[3] = {6, 6, 4};
    dan_dc_allocation_t m;
    uint8_t uid[DAN_DC_UNIQUE_ID_SIZE], buf[DAN_DC_ALLOCATION_MAX_SIZE];
    unsigned stage = (unsigned)(b >> 4) % 4u;
    fz_uid(b % FZ_UIDS, uid);
    memset(&m, 0, sizeof m);
    m.node_id = (pref & 0x80u) ? 0u : (uint8_t)(pref & 0x7Fu);
    m.first_part = stage == 0u || (stage == 3u && (pref & 1u));
    m.uid_len = stage < 3u ? cnt[stage] : (uint8_t)(pref % 7u);
    memcpy(m.uid, uid + (stage < 3u ? off[stage] : 0u), m.uid_len);
    fz_inject(0, DAN_DC_TRANSFER_BROADCAST, DAN_DC_ALLOCATION_ID, 0,
              fz_next_tid(DAN_DC_ALLOCATION_ID, DAN_DC_TRANSFER_BROADCAST, 0), buf,
              dan_dc_allocation_encode(&m, buf, sizeof buf), now);
}

static void fz_node_status(uint8_t src, uint8_t uptime, uint8_t health, uint64_t now)
{
    dan_dc_node_status_t ns;
    uint8_t buf[DAN_DC_NODE_STATUS_MAX_SIZE];
    memset(&ns, 0, sizeof ns);
    ns.uptime_sec = uptime;
    ns.health = (uint8_t)(health & 3u);
    fz_inject(src, DAN_DC_TRANSFER_BROADCAST, DAN_DC_NODE_STATUS_ID, 0,
              fz_next_tid(DAN_DC_NODE_STATUS_ID, DAN_DC_TRANSFER_BROADCAST, src), buf,
              dan_dc_node_status_encode(&ns, buf, sizeof buf), now);
}

/* The newest remembered request of data type dtid to node dst; NULL if none. */
static const fz_req_t *fz_find_req(uint16_t dtid, uint8_t dst)
{
    size_t k;
    for (k = 0; k < FZ_REQS && k < fzd.nreq; k++) {
        const fz_req_t *q = &fzd.reqs[(fzd.nreq - 1u - k) % FZ_REQS];
        if (q->dtid == dtid && q->dst == dst) {
            return q;
        }
    }
    return NULL;
}

/* Node src answers GetNodeInfo with pool unique ID b % FZ_UIDS, or (b bit7)
 * with the one the allocation table holds for src (an honest node). */
static void fz_node_info(uint8_t src, uint8_t b, uint64_t now)
{
    static dan_dc_get_node_info_rsp_t rsp;
    uint8_t buf[DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE];
    const fz_req_t *q = fz_find_req(DAN_DC_GET_NODE_INFO_ID, src);
    size_t k;
    memset(&rsp, 0, sizeof rsp);
    fz_uid(b % FZ_UIDS, rsp.hardware_version.unique_id);
    for (k = 0; (b & 0x80u) != 0u && k < fz_node.dna.n; k++) {
        if (fz_node.dna.table[k].node_id == src) {
            memcpy(rsp.hardware_version.unique_id, fz_node.dna.table[k].unique_id,
                   DAN_DC_UNIQUE_ID_SIZE);
        }
    }
    fz_inject(src, DAN_DC_TRANSFER_RESPONSE, DAN_DC_GET_NODE_INFO_ID, fz_node.cfg.node_id,
              q != NULL ? q->tid : (uint8_t)(b & DAN_DC_TRANSFER_ID_MASK), buf,
              dan_dc_get_node_info_rsp_encode(&rsp, buf, sizeof buf), now);
}

/* A response of any bytes to a remembered service request (b picks it). */
static void fz_service_response(uint8_t b, const uint8_t *p, size_t plen, uint64_t now)
{
    const fz_req_t *q;
    if (fzd.nreq == 0u) {
        return;
    }
    q = &fzd.reqs[(fzd.nreq - 1u - b % (fzd.nreq < FZ_REQS ? fzd.nreq : FZ_REQS)) % FZ_REQS];
    fz_inject(q->dst, DAN_DC_TRANSFER_RESPONSE, q->dtid, fz_node.cfg.node_id, q->tid, p, (int)plen,
              now);
}

/* The state the next operation is judged against. */
static void fzd_snapshot(void)
{
    size_t k;
    memcpy(fzd.table, fz_node.dna.table, sizeof fzd.table);
    fzd.n = fz_node.dna.n;
    for (k = 0; k < DAN_GW_NODE_MAX_NODES; k++) {
        const dan_gw_node_slot_t *n = &fz_node.nodes[k];
        fzd.seen[k].id = n->e.node_id;
        fzd.seen[k].uid_known = n->info.info_state == DAN_GW_INFO_VALID;
        memcpy(fzd.seen[k].uid, n->info.unique_id, DAN_DC_UNIQUE_ID_SIZE);
    }
}

/* The table never holds an ID out of range, nor a node ID or unique ID
 * twice. */
static void fzd_check_table(void)
{
    size_t a, b;
    FUZZ_CHECK(fz_node.dna.n <= DAN_GW_NODE_DNA_MAX);
    for (a = 0; a < fz_node.dna.n; a++) {
        const dan_gw_dna_entry_t *x = &fz_node.dna.table[a];
        FUZZ_CHECK(x->node_id >= 1u && x->node_id <= DAN_DC_ALLOCATION_MAX_NODE_ID);
        for (b = 0; b < a; b++) {
            const dan_gw_dna_entry_t *y = &fz_node.dna.table[b];
            FUZZ_CHECK(x->node_id != y->node_id &&
                       memcmp(x->unique_id, y->unique_id, DAN_DC_UNIQUE_ID_SIZE) != 0);
        }
    }
}

/* An allocation the gateway granted (id for uid): never its own ID; never
 * an ID the table held for another unique ID; an ID of a node in the node
 * table only when it is this device again (the table held this ID for
 * this unique ID, and the node's own unique ID, if known, is this one);
 * and the table holds it now. */
static void fzd_check_grant(uint8_t id, const uint8_t *uid)
{
    size_t k;
    bool held = false, found = false;
    FUZZ_CHECK(id != fz_node.cfg.node_id && id >= 1u && id <= DAN_DC_ALLOCATION_MAX_NODE_ID);
    for (k = 0; k < fzd.n; k++) {
        if (fzd.table[k].node_id == id) {
            FUZZ_CHECK(memcmp(fzd.table[k].unique_id, uid, DAN_DC_UNIQUE_ID_SIZE) == 0);
            held = true;
        }
    }
    for (k = 0; k < DAN_GW_NODE_MAX_NODES; k++) {
        const fz_seen_t *n = &fzd.seen[k];
        if (n->id == id) {
            FUZZ_CHECK(held);
            FUZZ_CHECK(!n->uid_known || memcmp(n->uid, uid, DAN_DC_UNIQUE_ID_SIZE) == 0);
        }
    }
    for (k = 0; k < fz_node.dna.n; k++) {
        found |= fz_node.dna.table[k].node_id == id &&
                 memcmp(fz_node.dna.table[k].unique_id, uid, DAN_DC_UNIQUE_ID_SIZE) == 0;
    }
    FUZZ_CHECK(found);
}

/* What the gateway sent: service requests remembered, its Allocation
 * grants checked. */
static void fzd_drain(uint64_t now)
{
    dan_can_frame_t f;
    dan_dc_transfer_t t, id;
    dan_dc_allocation_t m;
    size_t guard = 0;
    while (dan_gw_node_tx_peek(&fz_node, &f)) {
        FUZZ_CHECK(++guard <= 2u * DAN_GW_NODE_TXQ);
        dan_gw_node_tx_sent(&fz_node, now);
        if (f.dlc > 0u && (f.data[f.dlc - 1u] & DAN_DC_TAIL_SOT) != 0u &&
            dan_dc_parse_id(f.id, &id) == DAN_OK && id.transfer_type == DAN_DC_TRANSFER_REQUEST) {
            fz_req_t *q = &fzd.reqs[fzd.nreq++ % FZ_REQS];
            q->dst = id.destination_node;
            q->dtid = id.data_type_id;
            q->ttype = id.transfer_type;
            q->tid = (uint8_t)(f.data[f.dlc - 1u] & DAN_DC_TRANSFER_ID_MASK);
        }
        if (dan_dc_rx_frame(&fzd.lis, &f, now, &t) == 1 && t.data_type_id == DAN_DC_ALLOCATION_ID &&
            t.source_node == fz_node.cfg.node_id &&
            dan_dc_allocation_decode(&m, t.payload, t.payload_len) == DAN_OK && m.node_id != 0u) {
            FUZZ_CHECK(m.uid_len == DAN_DC_UNIQUE_ID_SIZE);
            fzd_check_grant(m.node_id, m.uid);
        }
    }
}

static void fzd_check_health(uint64_t now)
{
    dan_gw_health_t h;
    dan_gw_node_health(&fz_node, &h, now);
    FUZZ_CHECK((h.verdict == DAN_GW_HEALTH_FAIL) == (h.problems > 0u));
    FUZZ_CHECK(h.verdict <= DAN_GW_HEALTH_FAIL && dan_gw_reason_name(h.reason) != NULL);
}

/* op 6: the gateway restarts (b1 bit7: with node ID b1 % 127 + 1), after
 * b2 bit0 flipped a bit of the stored table. */
static void fz_reboot(uint8_t b1, uint8_t b2, uint64_t now)
{
    if ((b1 & 0x80u) != 0u) {
        fzd.cfg.node_id = (uint8_t)((b1 & 0x7Fu) % DAN_DC_NODE_ID_MAX + 1u);
    }
    if ((b2 & 1u) != 0u && fzd.blob_len > 0u) {
        fzd.blob[(b2 >> 1) % fzd.blob_len] ^= (uint8_t)(1u << (b2 % 8u));
    }
    fz_gateway_start(&fzd.cfg, now);
}

/* Operation op with its argument bytes at data[*i..]. */
static void fz_dna_op(uint8_t op, const uint8_t *data, size_t len, size_t *i, uint64_t *now)
{
    static const uint32_t codes[6] = {DAN_GW_CODE_NODE_CALL, DAN_GW_CODE_CALL_RESULT,
                                      DAN_GW_CODE_HEALTH,    DAN_GW_CODE_DNA,
                                      DAN_GW_CODE_CONFIG,    DAN_GW_CODE_NODES};
    uint8_t b[3] = {0, 0, 0};
    const uint8_t *p;
    size_t k, plen;
    for (k = 0; k < 2u && *i < len && op % 8u != 4u && op % 8u != 5u; k++) {
        b[k] = data[(*i)++];
    }
    switch (op % 8u) {
    case 0: fz_alloc_stage(b[0], b[1], *now); break;
    case 1: fz_node_status((uint8_t)(b[0] % 128u), b[1], (uint8_t)(op >> 3), *now); break;
    case 2: fz_node_info((uint8_t)(b[0] % 128u), b[1], *now); break;
    case 3:
        *now += (uint64_t)b[0] * 20000u + b[1];
        dan_gw_node_poll(&fz_node, *now);
        break;
    case 4:
        plen = fz_take(data, len, i, DAN_MAX_PAYLOAD, &p);
        fz_request(codes[(op >> 3) % 6u], p, plen, true, now);
        break;
    case 5:
        plen = fz_take(data, len, i, 64, &p);
        fz_service_response((uint8_t)(op >> 3), p, plen, *now);
        break;
    case 6: fz_reboot(b[0], b[1], *now); break;
    default:
        dan_gw_node_set_dna(&fz_node, (b[0] & 1u) != 0u);
        if ((b[0] & 2u) != 0u) { /* an Allocation from another allocator */
            uint8_t src = (uint8_t)(b[1] % 127u + 1u), buf[DAN_DC_ALLOCATION_MAX_SIZE];
            dan_dc_allocation_t m;
            memset(&m, 0, sizeof m);
            m.node_id = (uint8_t)(b[0] >> 2);
            fz_inject(src, DAN_DC_TRANSFER_BROADCAST, DAN_DC_ALLOCATION_ID, 0,
                      fz_next_tid(DAN_DC_ALLOCATION_ID, 0, src), buf,
                      dan_dc_allocation_encode(&m, buf, sizeof buf), *now);
        }
        break;
    }
}

/* A script of operations on the allocation server and the node table,
 * each an op byte and its arguments:
 *   op % 8 == 0  a stage of an allocatee's request (b1: allocatee of the
 *                pool and stage, b2: preferred ID)
 *            1  NodeStatus (b1: node ID, b2: uptime; health op >> 3)
 *            2  a GetNodeInfo answer (b1: node, b2: its unique ID)
 *            3  time passes: b1 * 20 ms + b2 us
 *            4  a sealed DAN request (op >> 3: NODE_CALL, CALL_RESULT,
 *               HEALTH, DNA, CONFIG, NODES), length byte, payload
 *            5  a response to a service request the gateway sent, length
 *               byte, payload
 *            6  the gateway restarts, loading the table it stored (b1:
 *               another node ID, b2: a bit of the stored table flipped)
 *            7  the server off/on (b1 bit0), another allocator (b1 bit1)
 * Checked after each: the table (IDs in range, none twice), every grant
 * (fzd_check_grant), the health verdict. */
int dan_fuzz_dna(const uint8_t *data, size_t len)
{
    uint64_t now = 1000000u;
    size_t i = 0;
    memset(&fzd, 0, sizeof fzd);
    dan_gw_node_config_default(&fzd.cfg);
    fzd.st.load = fzd_load;
    fzd.st.store = fzd_store;
    fzd.cfg.dna_storage = &fzd.st;
    dan_dc_rx_init(&fzd.lis, FZ_LISTENER, fz_accept_any, NULL);
    dan_dc_tid_table_init(&fzd.tids);
    fz_gateway_start(&fzd.cfg, now);
    fzd_snapshot();
    while (i < len) {
        fz_dna_op(data[i++], data, len, &i, &now);
        fzd_drain(now);
        fzd_check_table();
        fzd_check_health(now);
        fz_sink.len = 0; /* the DAN replies are the gw_handlers target's business */
        fzd_snapshot();
    }
    return 0;
}

/* ---- DroneCAN: reassembly and DSDL ------------------------------------ */

/* The file services, requests and responses: what decodes comes back
 * identical. */
static void dsdl_file(uint16_t dtid, const uint8_t *p, size_t n, uint8_t *buf, size_t cap)
{
    static dan_dc_file_req_t qa, qb;
    static dan_dc_file_read_rsp_t ra, rb;
    dan_dc_file_getinfo_rsp_t ia, ib;
    bool rd = dtid == DAN_DC_FILE_READ_ID;
    int r;
    if ((rd ? dan_dc_file_read_req_decode(&qa, p, n) : dan_dc_file_getinfo_req_decode(&qa, p, n)) ==
        DAN_OK) {
        r = rd ? dan_dc_file_read_req_encode(&qa, buf, cap)
               : dan_dc_file_getinfo_req_encode(&qa, buf, cap);
        FUZZ_CHECK(r >= 0);
        FUZZ_CHECK((rd ? dan_dc_file_read_req_decode(&qb, buf, (size_t)r)
                       : dan_dc_file_getinfo_req_decode(&qb, buf, (size_t)r)) == DAN_OK);
        FUZZ_CHECK(qa.path_len <= DAN_DC_FILE_PATH_MAX && qa.path_len == qb.path_len &&
                   qa.offset == qb.offset && !memcmp(qa.path, qb.path, qa.path_len));
    }
    if (rd && dan_dc_file_read_rsp_decode(&ra, p, n) == DAN_OK) {
        r = dan_dc_file_read_rsp_encode(&ra, buf, cap);
        FUZZ_CHECK(r >= 0 && dan_dc_file_read_rsp_decode(&rb, buf, (size_t)r) == DAN_OK);
        FUZZ_CHECK(ra.error == rb.error && ra.data_len == rb.data_len &&
                   !memcmp(ra.data, rb.data, ra.data_len));
    }
    if (!rd && dan_dc_file_getinfo_rsp_decode(&ia, p, n) == DAN_OK) {
        r = dan_dc_file_getinfo_rsp_encode(&ia, buf, cap);
        FUZZ_CHECK(r > 0 && dan_dc_file_getinfo_rsp_decode(&ib, buf, (size_t)r) == DAN_OK);
        FUZZ_CHECK(!memcmp(&ia, &ib, sizeof ia));
    }
}

/* A DSDL type's codec pair: what decodes re-encodes to bytes that decode
 * and encode again to the same bytes (a fixed point; no struct compare, so
 * unions and padding do not matter). */
#define DSDL_FIXED_POINT(T, name, p, n)                                             \
    do {                                                                            \
        static T a_, b_;                                                            \
        static uint8_t e1_[512], e2_[512];                                          \
        if (name##_decode(&a_, p, n) == DAN_OK) {                                   \
            int r1_ = name##_encode(&a_, e1_, sizeof e1_), r2_;                     \
            FUZZ_CHECK(r1_ >= 0 && name##_decode(&b_, e1_, (size_t)r1_) == DAN_OK); \
            r2_ = name##_encode(&b_, e2_, sizeof e2_);                              \
            FUZZ_CHECK(r2_ == r1_ && !memcmp(e1_, e2_, (size_t)r1_));               \
        }                                                                           \
    } while (0)

/* The bus-management and firmware-update types (requests and responses). */
static void dsdl_mgmt(uint16_t dtid, const uint8_t *p, size_t n)
{
    uint8_t buf[16];
    uint64_t magic;
    bool ok;
    switch (dtid) {
    case DAN_DC_ALLOCATION_ID:
        DSDL_FIXED_POINT(dan_dc_allocation_t, dan_dc_allocation, p, n);
        break;
    case DAN_DC_PARAM_GETSET_ID:
        DSDL_FIXED_POINT(dan_dc_param_getset_req_t, dan_dc_param_getset_req, p, n);
        DSDL_FIXED_POINT(dan_dc_param_getset_rsp_t, dan_dc_param_getset_rsp, p, n);
        break;
    case DAN_DC_PARAM_OPCODE_ID:
        DSDL_FIXED_POINT(dan_dc_param_opcode_t, dan_dc_param_opcode_req, p, n);
        DSDL_FIXED_POINT(dan_dc_param_opcode_t, dan_dc_param_opcode_rsp, p, n);
        break;
    case DAN_DC_RESTART_ID:
        if (dan_dc_restart_req_decode(&magic, p, n) == DAN_OK) {
            uint64_t again = 0;
            int r = dan_dc_restart_req_encode(magic, buf, sizeof buf);
            FUZZ_CHECK(r > 0 && dan_dc_restart_req_decode(&again, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(again == magic);
        }
        if (dan_dc_restart_rsp_decode(&ok, p, n) == DAN_OK) {
            bool again = !ok;
            int r = dan_dc_restart_rsp_encode(ok, buf, sizeof buf);
            FUZZ_CHECK(r > 0 && dan_dc_restart_rsp_decode(&again, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(again == ok);
        }
        break;
    default:
        DSDL_FIXED_POINT(dan_dc_fw_begin_req_t, dan_dc_fw_begin_req, p, n);
        DSDL_FIXED_POINT(dan_dc_fw_begin_rsp_t, dan_dc_fw_begin_rsp, p, n);
        break;
    }
}

/* A DSDL type's round trip (type name##_t): what decodes re-encodes to at
 * least min_len bytes, which decode again to a value that `same` (over a_
 * and b_) holds equal to the first. */
#define DSDL_ROUND_TRIP(name, min_len, same)                                              \
    do {                                                                                  \
        name##_t a_, b_;                                                                  \
        if (name##_decode(&a_, p, n) == DAN_OK) {                                         \
            int r_ = name##_encode(&a_, buf, sizeof buf);                                 \
            FUZZ_CHECK(r_ >= (min_len) && name##_decode(&b_, buf, (size_t)r_) == DAN_OK); \
            FUZZ_CHECK(same);                                                             \
        }                                                                                 \
    } while (0)
/* ... for the types with no padding or unused bytes: the whole struct. */
#define DSDL_SAME_STRUCT(name) DSDL_ROUND_TRIP(name, 1, !memcmp(&a_, &b_, sizeof a_))
/* ... for a counted list (encodes to 0 bytes when empty). */
#define DSDL_SAME_LIST(name, list) \
    DSDL_ROUND_TRIP(               \
        name, 0, a_.count == b_.count && !memcmp(a_.list, b_.list, a_.count * sizeof a_.list[0]))

/* Decodes payload as data type dtid; what decodes must re-encode, and the
 * exact-integer types must come back identical. */
static void dsdl_any(uint16_t dtid, const uint8_t *p, size_t n)
{
    uint8_t buf[DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE];
    int r;
    switch (dtid) {
    case DAN_DC_NODE_STATUS_ID:
        DSDL_ROUND_TRIP(dan_dc_node_status, 1,
                        a_.uptime_sec == b_.uptime_sec && a_.health == b_.health &&
                            a_.mode == b_.mode && a_.sub_mode == b_.sub_mode &&
                            a_.vendor_specific_status_code == b_.vendor_specific_status_code);
        break;
    case DAN_DC_GET_NODE_INFO_ID: { /* also the Allocation's ID (a broadcast) */
        static dan_dc_get_node_info_rsp_t a, b;
        dsdl_mgmt(DAN_DC_ALLOCATION_ID, p, n);
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
    case DAN_DC_ESC_STATUS_EXTENDED_ID:
        DSDL_ROUND_TRIP(dan_dc_esc_status_extended, 1,
                        a_.input_pct == b_.input_pct && a_.output_pct == b_.output_pct &&
                            a_.motor_temperature_degC == b_.motor_temperature_degC &&
                            a_.motor_angle == b_.motor_angle &&
                            a_.status_flags == b_.status_flags && a_.esc_index == b_.esc_index);
        break;
    case DAN_DC_ARMING_STATUS_ID: DSDL_SAME_STRUCT(dan_dc_arming_status); break;
    case DAN_DC_ARRAY_COMMAND_ID: DSDL_SAME_LIST(dan_dc_array_command, cmd); break;
    case DAN_DC_LIGHTS_COMMAND_ID: DSDL_SAME_LIST(dan_dc_lights_command, light); break;
    case DAN_DC_BEEP_COMMAND_ID: DSDL_SAME_STRUCT(dan_dc_beep_command); break;
    case DAN_DC_SAFETY_STATE_ID: {
        uint8_t a, b;
        if (dan_dc_safety_state_decode(&a, p, n) == DAN_OK) {
            r = dan_dc_safety_state_encode(a, buf, sizeof buf);
            FUZZ_CHECK(r > 0 && dan_dc_safety_state_decode(&b, buf, (size_t)r) == DAN_OK);
            FUZZ_CHECK(a == b);
        }
        break;
    }
    case DAN_DC_TEMPERATURE_ID: DSDL_SAME_STRUCT(dan_dc_temperature); break;
    case DAN_DC_FILE_READ_ID:
    case DAN_DC_FILE_GETINFO_ID: dsdl_file(dtid, p, n, buf, sizeof buf); break;
    case DAN_DC_PARAM_GETSET_ID:
    case DAN_DC_PARAM_OPCODE_ID:
    case DAN_DC_RESTART_ID:
    case DAN_DC_FW_BEGIN_ID: dsdl_mgmt(dtid, p, n); break;
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

/* data[0] % 20 picks the type; the rest is the serialized payload. */
int dan_fuzz_dsdl(const uint8_t *data, size_t len)
{
    static const uint16_t ids[20] = {DAN_DC_NODE_STATUS_ID,
                                     DAN_DC_GET_NODE_INFO_ID,
                                     DAN_DC_ESC_RAW_COMMAND_ID,
                                     DAN_DC_ESC_STATUS_ID,
                                     DAN_DC_ESC_STATUS_EXTENDED_ID,
                                     DAN_DC_ARMING_STATUS_ID,
                                     0u,
                                     0xFFFFu,
                                     DAN_DC_ARRAY_COMMAND_ID,
                                     DAN_DC_LIGHTS_COMMAND_ID,
                                     DAN_DC_BEEP_COMMAND_ID,
                                     DAN_DC_SAFETY_STATE_ID,
                                     DAN_DC_TEMPERATURE_ID,
                                     DAN_DC_FILE_READ_ID,
                                     DAN_DC_FILE_GETINFO_ID,
                                     0u,
                                     DAN_DC_PARAM_GETSET_ID,
                                     DAN_DC_PARAM_OPCODE_ID,
                                     DAN_DC_RESTART_ID,
                                     DAN_DC_FW_BEGIN_ID};
    if (len < 1u) {
        return 0;
    }
    dsdl_any(ids[data[0] % 20u], data + 1, len - 1u);
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

/* ---- SLCAN: line parser, the backend's stream, cansend -------------- */

static void check_can_frame(const dan_can_frame_t *f)
{
    FUZZ_CHECK(f->dlc <= 8u && (f->flags & DAN_CAN_ERR) == 0u);
    FUZZ_CHECK(f->id <= ((f->flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK));
}

/* A frame formats to a line that parses back to it. */
static void check_slcan_round_trip(const dan_can_frame_t *f)
{
    dan_can_frame_t g;
    char line[64];
    int r = dan_slcan_format(f, line, sizeof line);
    FUZZ_CHECK(r > 1 && r <= DAN_SLCAN_FORMAT_MAX && line[r - 1] == '\r' && line[r] == '\0');
    FUZZ_CHECK(dan_slcan_parse_line(line, (size_t)r - 1u, &g) == 1);
    FUZZ_CHECK(g.id == f->id && g.flags == f->flags && g.dlc == f->dlc);
    FUZZ_CHECK((f->flags & DAN_CAN_RTR) || !memcmp(g.data, f->data, f->dlc));
}

static int fz_slcan_sock[2] = {-1, -1}; /* [0]: the backend's fd, [1]: the adapter */

/* The whole input as bytes from an adapter, read by the SLCAN backend
 * (dan_canif_slcan_recv: line assembly, BEL, overlong lines); each frame
 * it returns is sent back (dan_canif_slcan_send) and must come out as the
 * line that parses to it. */
static void fz_slcan_stream(const uint8_t *data, size_t len)
{
    static dan_canif_t c;
    char line[DAN_SLCAN_FORMAT_MAX + 1];
    dan_can_frame_t f, g;
    uint32_t frames = 0;
    size_t guard = 0;
    int r;
    if (fz_slcan_sock[0] < 0) {
        FUZZ_CHECK(
            socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0, fz_slcan_sock) == 0);
    }
    memset(&c, 0, sizeof c);
    c.kind = DAN_CANIF_SLCAN;
    c.fd = fz_slcan_sock[0];
    FUZZ_CHECK(len == 0u || write(fz_slcan_sock[1], data, len) == (ssize_t)len);
    while ((r = dan_canif_slcan_recv(&c, &f)) == 1) {
        ssize_t n;
        check_can_frame(&f);
        frames++;
        FUZZ_CHECK(dan_canif_slcan_send(&c, &f) == 0);
        n = read(fz_slcan_sock[1], line, sizeof line - 1u);
        FUZZ_CHECK(n > 1 && line[n - 1] == '\r');
        FUZZ_CHECK(dan_slcan_parse_line(line, (size_t)n - 1u, &g) == 1);
        FUZZ_CHECK(g.id == f.id && g.flags == f.flags && g.dlc == f.dlc);
        FUZZ_CHECK(++guard <= len);
    }
    FUZZ_CHECK(r == 0 && c.stats.rx == frames && c.stats.tx == frames);
    FUZZ_CHECK(c.line_len <= DAN_SLCAN_LINE_MAX);
}

/* The input as one line (dan_slcan_parse_line), as a byte stream from the
 * adapter (fz_slcan_stream) and as a cansend argument
 * (dan_can_parse_cansend). */
int dan_fuzz_slcan(const uint8_t *data, size_t len)
{
    dan_can_frame_t f;
    char arg[257];
    int r = dan_slcan_parse_line((const char *)data, len, &f);
    FUZZ_CHECK(r == 0 || r == 1 || r == DAN_ERR_MALFORMED);
    if (r == 1) {
        check_can_frame(&f);
        check_slcan_round_trip(&f);
    }
    fz_slcan_stream(data, len);
    if (len < sizeof arg) {
        memcpy(arg, data, len);
        arg[len] = '\0';
        r = dan_can_parse_cansend(arg, &f);
        FUZZ_CHECK(r == 0 || r == DAN_ERR_MALFORMED);
        if (r == 0) {
            check_can_frame(&f);
        }
    }
    return 0;
}

/* ---- gateway client: response decoders -------------------------------- */

static dan_master_t fz_master;

/* A paged response: its header, then each entry the reader gives (at most
 * the header's count), each through check (a statement over e_, or none). */
#define FZ_WALK_ENTRIES(H, E, begin, next, check)                       \
    do {                                                                \
        H h_;                                                           \
        E e_;                                                           \
        if (begin(&gw, &r, &h_) == DAN_OK) {                            \
            for (i = 0; i < h_.count && next(&r, &e_) == DAN_OK; i++) { \
                check;                                                  \
            }                                                           \
        }                                                               \
    } while (0)

/* data[0] % 28: response code 0x42 + k up to 0x4F, then 0x52 + (k - 14)
 * up to 0x5F (HEALTH, DNA, the outputs, reserved ones); data[1]: tunnel port and client offsets seed; the rest is
 * the response payload. */
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
    code = DAN_GW_CODE_ESC_CMD + (uint32_t)(data[0] % 28u);
    if (code > DAN_GW_CODE_CALL_RESULT) {
        code = DAN_GW_CODE_HEALTH + (code - DAN_GW_CODE_CALL_RESULT - 1u);
    }
    seed = data[1];
    data += 2;
    len -= 2;
    n = len > DAN_MAX_PAYLOAD ? DAN_MAX_PAYLOAD : len;
    memset(&fz_master, 0, sizeof fz_master);
    fz_master.resp = fz_master.link.tx; /* as dan_master_init() sets it */
    fz_master.result = DAN_OK;
    fz_master.resp_code = code;
    memcpy(fz_master.resp, data, n);
    fz_master.resp_len = n;
    if ((seed & 0x80u) != 0u) {
        /* sealed as the gateway would, so the decoders behind the seal are
         * reached; otherwise as is (the seal check) */
        int sl = dan_gw_seal(code, DAN_GW_RESPONSE, fz_master.resp, n, DAN_MAX_PAYLOAD);
        if (sl > 0) {
            fz_master.resp_len = (size_t)sl;
        }
    }
    dan_gw_init(&gw, &fz_master);
    gw.port = (uint8_t)(seed % DAN_GW_TUNNELS);
    gw.tun[gw.port].wr_offset = (uint32_t)(seed >> 1) * 0x01010101u;
    gw.tun[gw.port].rd_offset = (uint32_t)(seed >> 2) * 0x00FF00FFu;
    gw.can_rx_next = (uint32_t)seed << 24;
    (void)dan_gw_complete_as(&gw, code, 0);
    FUZZ_CHECK(gw.code == 0u);
    FUZZ_CHECK(gw.result == DAN_OK || gw.result < 0);
    switch (code) {
    case DAN_GW_CODE_NODES:
        FZ_WALK_ENTRIES(dan_gw_nodes_hdr_t, dan_gw_node_entry_t, dan_gw_nodes_begin,
                        dan_gw_nodes_next, );
        break;
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
    case DAN_GW_CODE_CAN_RECV:
        FZ_WALK_ENTRIES(dan_gw_can_recv_t, dan_can_frame_t, dan_gw_can_begin, dan_gw_can_next,
                        FUZZ_CHECK(e_.dlc <= 8u));
        break;
    case DAN_GW_CODE_CAN_FILTER: {
        uint8_t res, cnt;
        dan_gw_filter_t f;
        if (dan_gw_filter_begin(&gw, &r, &res, &cnt) == DAN_OK) {
            for (i = 0; i < cnt && dan_gw_filter_next(&r, &f) == DAN_OK; i++) {
            }
        }
        break;
    }
    case DAN_GW_CODE_CALL_RESULT: {
        dan_gw_result_t res;
        if (dan_gw_call_result_get(&gw, &res) == DAN_OK && res.len > 0u) {
            FUZZ_CHECK(res.len <= DAN_GW_RESULT_CHUNK_MAX);
            FUZZ_CHECK(res.data >= fz_master.resp &&
                       res.data + res.len <= fz_master.resp + fz_master.resp_len);
        }
        break;
    }
    case DAN_GW_CODE_DNA:
        FZ_WALK_ENTRIES(dan_gw_dna_hdr_t, dan_gw_dna_entry_t, dan_gw_dna_begin, dan_gw_dna_next, );
        break;
    case DAN_GW_CODE_FILE_LIST:
        FZ_WALK_ENTRIES(dan_gw_file_list_hdr_t, dan_gw_file_entry_t, dan_gw_file_list_begin,
                        dan_gw_file_list_next,
                        FUZZ_CHECK(e_.name_len >= 1u && strlen(e_.name) <= e_.name_len));
        break;
    case DAN_GW_CODE_FILE_OPEN:
    case DAN_GW_CODE_FILE_WRITE:
    case DAN_GW_CODE_FILE_COMMIT:
    case DAN_GW_CODE_FILE_REMOVE: {
        uint8_t res;
        uint32_t v;
        (void)dan_gw_file_result(&gw, &res, &v);
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
    {"dna", dan_fuzz_dna},
    {"file_names", dan_fuzz_file_names},
    {"file_dir", dan_fuzz_file_dir},
    {"gw_msgs", dan_fuzz_gw_msgs},
};
const size_t dan_fuzz_ntargets = sizeof dan_fuzz_targets / sizeof dan_fuzz_targets[0];
