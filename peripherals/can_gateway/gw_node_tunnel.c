/* Gateway node: serial tunnels, uavcan.tunnel.Targetted (ArduPilot's
 * AP_DroneCAN_serial semantics) and uavcan.tunnel.Broadcast, by stream
 * offset on the DAN side so the master's retries are safe. */
#include <stddef.h>
#include <string.h>

#include "gw_node_internal.h"

/* Bulk-queue room for one whole Targetted transfer (126 payload bytes + 2
 * CRC in 7-byte frames): tunnel chunks wait for it, so the queue is the
 * flow control. */
#define TARGETTED_FRAMES_MAX 19u
/* ... and, while a node's file request waits, room for its answer besides
 * (a Read: 2 + 256 bytes and the CRC, 38 frames): a tunnel fed faster than CAN takes
 * it kept the queue at 19 free, and the answers waited until dropped
 * (review finding). */
#define FILE_ANSWER_FRAMES   ((DAN_DC_FILE_READ_RSP_MAX_SIZE + 2u + 6u) / 7u)

/* A TUN_XFER response without its data: u8 port, four uvarints of 32 bits
 * (5 bytes each at most), the data's length (2 bytes for 128). */
#define TUN_XFER_RSP_HDR_MAX (1u + 4u * 5u + 2u)

static size_t room_needed(const dan_gw_node_t *g)
{
    return TARGETTED_FRAMES_MAX + (g->file_nwait > 0u ? FILE_ANSWER_FRAMES : 0u);
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

void dan_gwn_on_targetted(dan_gw_node_t *g, const dan_dc_transfer_t *t)
{
    dan_dc_tunnel_targetted_t *mp = &g->scratch.targetted;
    size_t i;
    if (dan_dc_tunnel_targetted_decode(mp, t->payload, t->payload_len) != DAN_OK ||
        mp->target_node != g->cfg.node_id) {
        return;
    }
    dan_gw_node_tun_t *any = NULL;
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        dan_gw_node_tun_t *p = &g->tun[i];
        if (p->cfg.mode != DAN_GW_TUN_TARGETTED || p->cfg.target != t->source_node) {
            continue;
        }
        if (p->cfg.serial_id == mp->serial_id) {
            tun_in(g, p, mp->buffer, mp->buffer_len);
            return;
        }
        /* serial_id -1 is "the default device": the node answers with the
         * port it resolved it to (AP_Periph does), so any serial_id of the
         * target node is its, unless a port asked for that one (review
         * finding: the first port took it) */
        if (p->cfg.serial_id == DAN_GW_TUN_DEFAULT_SERIAL && any == NULL) {
            any = p;
        }
    }
    if (any != NULL) {
        tun_in(g, any, mp->buffer, mp->buffer_len);
    }
}

void dan_gwn_on_tun_broadcast(dan_gw_node_t *g, const dan_dc_transfer_t *t)
{
    dan_dc_tunnel_broadcast_t *mp = &g->scratch.bcast;
    size_t i;
    if (dan_dc_tunnel_broadcast_decode(mp, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        dan_gw_node_tun_t *p = &g->tun[i];
        /* some nodes answer on any channel (Vertiq modules ignore channel_id) */
        if (p->cfg.mode == DAN_GW_TUN_BROADCAST && p->cfg.protocol == mp->protocol &&
            (p->cfg.target == mp->channel_id || (p->cfg.options & DAN_GW_TUN_ANY_CHANNEL))) {
            tun_in(g, p, mp->buffer, mp->buffer_len);
        }
    }
}

bool dan_gwn_tunnel_open(dan_gw_node_t *g, const dan_gw_tun_open_t *o, uint64_t now_us)
{
    dan_gw_node_tun_t *p;
    bool ok = o->port < DAN_GW_NODE_TUNNELS && o->mode <= DAN_GW_TUN_BROADCAST &&
              (o->mode != DAN_GW_TUN_BROADCAST || o->options <= DAN_GW_TUN_ANY_CHANNEL) &&
              (o->mode != DAN_GW_TUN_TARGETTED ||
               (o->target >= 1u && o->target <= DAN_DC_NODE_ID_MAX &&
                o->serial_id >= DAN_DC_TUNNEL_SERIAL_ID_MIN &&
                o->serial_id <= DAN_DC_TUNNEL_SERIAL_ID_MAX &&
                o->options <= DAN_DC_TUNNEL_OPTIONS_MAX && o->baud <= DAN_DC_TUNNEL_BAUD_MAX));
    if (!ok) {
        return false;
    }
    p = &g->tun[o->port];
    /* bytes received and not yet read are lost with the old session (a
     * retried TUN_OPEN too): counted, never silently (review finding) */
    g->stats.tun_dropped += p->rd_end - p->rd_base;
    memset(p, 0, offsetof(dan_gw_node_tun_t, tx)); /* buffers need no clearing */
    p->cfg = *o;
    p->last_tx_us = now_us - DAN_GW_NODE_KEEPALIVE_US; /* first keepalive at once */
    return true;
}

int dan_gwn_tunnel_xfer(dan_gw_node_t *g, const dan_gw_tun_xfer_t *x, dan_gw_tun_xfer_t *r,
                        uint8_t *out, size_t room)
{
    dan_gw_node_tun_t *p;
    int32_t skip, ack;
    size_t i, n;
    if (x->port >= DAN_GW_NODE_TUNNELS || g->tun[x->port].cfg.mode == DAN_GW_TUN_CLOSED) {
        return DAN_ERR_NOTFOUND;
    }
    p = &g->tun[x->port];
    /* write: bytes before wr_next are repeats of a retried request */
    skip = dan_gw_off_diff(p->wr_next, x->wr_offset);
    if (skip < 0) {
        return DAN_ERR_MALFORMED;
    }
    for (i = (size_t)skip; i < x->len && p->tx_len < DAN_GW_NODE_TUN_TX_BUF; i++) {
        p->tx[p->wr_next % DAN_GW_NODE_TUN_TX_BUF] = x->data[i];
        p->wr_next++;
        p->tx_len++;
    }
    /* read: the master has every byte before rd_offset */
    ack = dan_gw_off_diff(x->rd_offset, p->rd_base);
    if (ack > 0 && dan_gw_off_diff(p->rd_end, x->rd_offset) >= 0) {
        p->rd_base = x->rd_offset;
    }
    n = p->rd_end - p->rd_base;
    if (n > x->rd_max) {
        n = x->rd_max;
    }
    if (n > DAN_GW_TUN_CHUNK_MAX) {
        n = DAN_GW_TUN_CHUNK_MAX;
    }
    /* and what the response holds: a build with a smaller DAN_MAX_PAYLOAD
     * answered "response too large" after it had applied the write, and
     * every later transfer the same (review finding) */
    room = room > TUN_XFER_RSP_HDR_MAX ? room - TUN_XFER_RSP_HDR_MAX : 0u;
    if (n > room) {
        n = room;
    }
    for (i = 0; i < n; i++) {
        out[i] = p->rx[(p->rd_base + i) % DAN_GW_NODE_TUN_RX_BUF];
    }
    memset(r, 0, sizeof *r);
    r->port = x->port;
    r->wr_offset = p->wr_next;
    r->wr_space = DAN_GW_NODE_TUN_TX_BUF - p->tx_len;
    r->rd_offset = p->rd_base;
    r->rd_dropped = p->rd_dropped;
    r->data = out;
    r->len = n;
    return DAN_OK;
}

/* Copies the next n bytes waiting to go out of a port; returns n (at most
 * a tunnel buffer, 120). */
static uint8_t tun_peek(const dan_gw_node_tun_t *p, uint8_t *dst, size_t n)
{
    uint32_t start = p->wr_next - p->tx_len;
    size_t i;
    for (i = 0; i < n; i++) {
        dst[i] = p->tx[(start + i) % DAN_GW_NODE_TUN_TX_BUF];
    }
    return (uint8_t)n;
}

static size_t min_size(size_t a, size_t b)
{
    return a < b ? a : b;
}

/* Queues a tunnel message (len encoded bytes in buf, n of them data) on
 * the bulk queue: n, or -1 if it was not queued. */
static int chunk_sent(dan_gw_node_t *g, uint16_t dtid, uint64_t sig, const uint8_t *buf, int len,
                      size_t n)
{
    if (dan_gwn_broadcast(g, &g->q_bulk, dtid, sig, DAN_DC_PRIORITY_MEDIUM, buf, len) != DAN_OK) {
        return -1;
    }
    return (int)n;
}

/* One Targetted chunk, or an empty keepalive when the port was idle for
 * DAN_GW_NODE_KEEPALIVE_US. Returns the bytes sent, or -1 if nothing was. */
static int targetted_out(dan_gw_node_t *g, dan_gw_node_tun_t *p, uint64_t now_us)
{
    dan_dc_tunnel_targetted_t *m = &g->scratch.targetted;
    uint8_t buf[DAN_DC_TUNNEL_TARGETTED_MAX_SIZE];
    size_t n = min_size(p->tx_len, DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX);
    if (n == 0u && now_us - p->last_tx_us < DAN_GW_NODE_KEEPALIVE_US) {
        return -1;
    }
    memset(m, 0, sizeof *m);
    m->protocol = p->cfg.protocol;
    m->target_node = p->cfg.target;
    m->serial_id = p->cfg.serial_id;
    m->options = p->cfg.options;
    m->baudrate = p->cfg.baud;
    m->buffer_len = tun_peek(p, m->buffer, n);
    return chunk_sent(g, DAN_DC_TUNNEL_TARGETTED_ID, DAN_DC_TUNNEL_TARGETTED_SIGNATURE, buf,
                      dan_dc_tunnel_targetted_encode(m, buf, sizeof buf), n);
}

/* One Broadcast chunk; -1 if nothing was sent. */
static int broadcast_out(dan_gw_node_t *g, dan_gw_node_tun_t *p)
{
    dan_dc_tunnel_broadcast_t *m = &g->scratch.bcast;
    uint8_t buf[DAN_DC_TUNNEL_BROADCAST_MAX_SIZE];
    size_t n = min_size(p->tx_len, DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX);
    if (n == 0u) {
        return -1;
    }
    m->protocol = p->cfg.protocol;
    m->channel_id = p->cfg.target;
    m->buffer_len = tun_peek(p, m->buffer, n);
    return chunk_sent(g, DAN_DC_TUNNEL_BROADCAST_ID, DAN_DC_TUNNEL_BROADCAST_SIGNATURE, buf,
                      dan_dc_tunnel_broadcast_encode(m, buf, sizeof buf), n);
}

/* Sends one chunk (or a Targetted keepalive). Returns true if data went. */
static bool tun_out(dan_gw_node_t *g, dan_gw_node_tun_t *p, uint64_t now_us)
{
    int n = p->cfg.mode == DAN_GW_TUN_TARGETTED ? targetted_out(g, p, now_us) : broadcast_out(g, p);
    if (n < 0) {
        return false;
    }
    p->tx_len -= (uint32_t)n;
    p->last_tx_us = now_us;
    return n > 0;
}

void dan_gwn_tunnel_poll(dan_gw_node_t *g, uint64_t now_us)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        dan_gw_node_tun_t *p = &g->tun[i];
        /* chunks while the bulk queue has room for a whole one */
        while (p->cfg.mode != DAN_GW_TUN_CLOSED && dan_gwn_txq_free(&g->q_bulk) >= room_needed(g) &&
               tun_out(g, p, now_us) && p->tx_len > 0u) {
        }
    }
}

uint64_t dan_gwn_tunnel_next_us(const dan_gw_node_t *g, uint64_t now_us, uint64_t t)
{
    size_t i;
    /* Without room for a chunk nothing can go before a frame leaves, and
     * the caller polls again then: "now" made its loop spin for as long as
     * the queue stayed full (a firmware update's reads; review finding). */
    if (dan_gwn_txq_free(&g->q_bulk) < room_needed(g)) {
        return t;
    }
    for (i = 0; i < DAN_GW_NODE_TUNNELS; i++) {
        const dan_gw_node_tun_t *p = &g->tun[i];
        if (p->cfg.mode == DAN_GW_TUN_CLOSED) {
            continue;
        }
        if (p->tx_len > 0u) {
            t = now_us; /* room for a chunk: at once */
        } else if (p->cfg.mode == DAN_GW_TUN_TARGETTED &&
                   p->last_tx_us + DAN_GW_NODE_KEEPALIVE_US < t) {
            t = p->last_tx_us + DAN_GW_NODE_KEEPALIVE_US;
        }
    }
    return t;
}
