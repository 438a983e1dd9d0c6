/* DroneCAN (UAVCAN v0) transport: IDs, TX splitting, RX reassembly,
 * transfer CRC, transfer IDs. See dan/can_gw/dronecan.h. */
#include <string.h>

#include "dan/can_gw/dronecan.h"

void dan_dc_transfer_init(dan_dc_transfer_t *t, uint16_t data_type_id, uint64_t signature,
                          dan_dc_transfer_type_t type, const uint8_t *payload, size_t len)
{
    memset(t, 0, sizeof *t);
    t->data_type_id = data_type_id;
    t->signature = signature;
    t->transfer_type = (uint8_t)type;
    t->payload = payload;
    t->payload_len = len;
}

/* ---- CAN ID ---- */

int dan_dc_make_id(const dan_dc_transfer_t *t, uint32_t *id)
{
    uint32_t v;
    if (t == NULL || id == NULL || t->priority > DAN_DC_PRIORITY_MAX ||
        t->source_node > DAN_DC_NODE_ID_MAX) {
        return DAN_ERR_ARG;
    }
    v = (uint32_t)t->priority << DAN_DC_ID_PRIORITY_SHIFT;
    switch (t->transfer_type) {
    case DAN_DC_TRANSFER_BROADCAST:
        if (t->source_node == 0u) {
            if (t->data_type_id > DAN_DC_ID_ANON_DTID_MASK) {
                return DAN_ERR_ARG;
            }
            v |= (uint32_t)(t->discriminator & DAN_DC_ID_ANON_DISC_MASK)
                 << DAN_DC_ID_ANON_DISC_SHIFT;
            v |= (uint32_t)t->data_type_id << 8;
        } else {
            v |= (uint32_t)t->data_type_id << 8 | t->source_node;
        }
        break;
    case DAN_DC_TRANSFER_REQUEST:
    case DAN_DC_TRANSFER_RESPONSE:
        if (t->data_type_id > 0xFFu || t->source_node == 0u || t->destination_node == 0u ||
            t->destination_node > DAN_DC_NODE_ID_MAX) {
            return DAN_ERR_ARG;
        }
        v |= (uint32_t)t->data_type_id << 16 | (uint32_t)t->destination_node << 8 |
             DAN_DC_ID_SERVICE | t->source_node;
        if (t->transfer_type == DAN_DC_TRANSFER_REQUEST) {
            v |= DAN_DC_ID_REQUEST;
        }
        break;
    default: return DAN_ERR_ARG;
    }
    *id = v;
    return DAN_OK;
}

int dan_dc_parse_id(uint32_t id, dan_dc_transfer_t *t)
{
    if (t == NULL) {
        return DAN_ERR_ARG;
    }
    id &= DAN_CAN_EFF_MASK;
    t->priority = (uint8_t)(id >> DAN_DC_ID_PRIORITY_SHIFT);
    t->source_node = (uint8_t)(id & 0x7Fu);
    t->discriminator = 0;
    t->destination_node = 0;
    if ((id & DAN_DC_ID_SERVICE) != 0u) {
        t->data_type_id = (uint16_t)((id >> 16) & 0xFFu);
        t->transfer_type = (uint8_t)((id & DAN_DC_ID_REQUEST) != 0u ? DAN_DC_TRANSFER_REQUEST
                                                                    : DAN_DC_TRANSFER_RESPONSE);
        t->destination_node = (uint8_t)((id >> 8) & 0x7Fu);
        if (t->source_node == 0u || t->destination_node == 0u) {
            return DAN_ERR_MALFORMED;
        }
    } else {
        t->transfer_type = DAN_DC_TRANSFER_BROADCAST;
        if (t->source_node == 0u) {
            t->discriminator =
                (uint16_t)((id >> DAN_DC_ID_ANON_DISC_SHIFT) & DAN_DC_ID_ANON_DISC_MASK);
            t->data_type_id = (uint16_t)((id >> 8) & DAN_DC_ID_ANON_DTID_MASK);
        } else {
            t->data_type_id = (uint16_t)((id >> 8) & 0xFFFFu);
        }
    }
    return DAN_OK;
}

/* ---- CRC ---- */

uint16_t dan_dc_crc16(uint16_t crc, const uint8_t *data, size_t len)
{
    return dan_crc16_ccitt(crc, data, len); /* the same CRC as libdan's */
}

uint16_t dan_dc_crc16_signature(uint64_t signature)
{
    uint8_t le[8];
    unsigned i;
    for (i = 0; i < 8u; i++) {
        le[i] = (uint8_t)(signature >> (8u * i));
    }
    return dan_dc_crc16(DAN_DC_CRC_INIT, le, sizeof le);
}

uint16_t dan_dc_transfer_crc(uint64_t signature, const uint8_t *payload, size_t len)
{
    return dan_dc_crc16(dan_dc_crc16_signature(signature), payload, len);
}

/* ---- TX ---- */

size_t dan_dc_tx_frame_count(size_t payload_len)
{
    if (payload_len <= DAN_DC_FRAME_DATA_MAX) {
        return 1u;
    }
    return (payload_len + 2u + DAN_DC_FRAME_DATA_MAX - 1u) / DAN_DC_FRAME_DATA_MAX;
}

/* Checks t and returns its CAN ID; anonymous messages get the payload-derived
 * discriminator. */
static int tx_check(const dan_dc_transfer_t *t, uint32_t *id)
{
    dan_dc_transfer_t c;
    if (t == NULL || (t->payload == NULL && t->payload_len > 0u)) {
        return DAN_ERR_ARG;
    }
    c = *t;
    if (c.transfer_type == DAN_DC_TRANSFER_BROADCAST && c.source_node == 0u) {
        if (c.payload_len > DAN_DC_FRAME_DATA_MAX) {
            return DAN_ERR_ARG; /* anonymous transfers are single-frame */
        }
        c.discriminator = (uint16_t)(dan_dc_crc16(DAN_DC_CRC_INIT, c.payload, c.payload_len) &
                                     DAN_DC_ID_ANON_DISC_MASK);
    }
    return dan_dc_make_id(&c, id);
}

static int tx_frame(const dan_dc_transfer_t *t, uint32_t id, uint16_t crc, size_t index,
                    size_t count, dan_can_frame_t *out)
{
    size_t n = 0;
    memset(out, 0, sizeof *out);
    out->id = id;
    out->flags = DAN_CAN_EXT;
    if (count == 1u) {
        if (t->payload_len > 0u) {
            memcpy(out->data, t->payload, t->payload_len);
        }
        n = t->payload_len;
    } else {
        /* Stream = CRC (LE) then payload; frame index covers 7 of it. */
        size_t stream_len = t->payload_len + 2u;
        size_t k = index * DAN_DC_FRAME_DATA_MAX;
        size_t end = k + DAN_DC_FRAME_DATA_MAX;
        if (end > stream_len) {
            end = stream_len;
        }
        for (; k < end; k++) {
            out->data[n++] = k == 0u   ? (uint8_t)crc
                             : k == 1u ? (uint8_t)(crc >> 8)
                                       : t->payload[k - 2u];
        }
    }
    out->data[n] =
        dan_dc_tail(index == 0u, index + 1u == count, (index & 1u) != 0u, t->transfer_id);
    out->dlc = (uint8_t)(n + 1u);
    return DAN_OK;
}

int dan_dc_tx_frame(const dan_dc_transfer_t *t, uint16_t crc, size_t index, dan_can_frame_t *out)
{
    uint32_t id;
    size_t count;
    int rc = tx_check(t, &id);
    if (rc < 0) {
        return rc;
    }
    count = dan_dc_tx_frame_count(t->payload_len);
    if (out == NULL || index >= count) {
        return DAN_ERR_ARG;
    }
    return tx_frame(t, id, crc, index, count, out);
}

int dan_dc_tx_build(const dan_dc_transfer_t *t, dan_can_frame_t *frames, size_t cap)
{
    uint32_t id;
    size_t count, i;
    uint16_t crc = 0;
    int rc = tx_check(t, &id);
    if (rc < 0) {
        return rc;
    }
    if (frames == NULL && cap > 0u) {
        return DAN_ERR_ARG;
    }
    count = dan_dc_tx_frame_count(t->payload_len);
    if (count > cap || count > (size_t)0x7FFFFFFF) {
        return DAN_ERR_OVERFLOW;
    }
    if (count > 1u) {
        crc = dan_dc_transfer_crc(t->signature, t->payload, t->payload_len);
    }
    for (i = 0; i < count; i++) {
        (void)tx_frame(t, id, crc, i, count, &frames[i]);
    }
    return (int)count;
}

/* ---- TX transfer IDs ---- */

void dan_dc_tid_table_init(dan_dc_tid_table_t *tab)
{
    if (tab != NULL) {
        memset(tab, 0, sizeof *tab);
    }
}

static int take_tid(dan_dc_tid_table_t *tab, size_t i, uint32_t key)
{
    uint8_t tid = tab->next[i];
    tab->key[i] = key;
    tab->next[i] = (uint8_t)((tid + 1u) & DAN_DC_TRANSFER_ID_MASK);
    return tid;
}

int dan_dc_tid_next(dan_dc_tid_table_t *tab, uint16_t data_type_id, uint8_t transfer_type,
                    uint8_t destination_node)
{
    uint32_t key;
    size_t i;
    if (tab == NULL || transfer_type > DAN_DC_TRANSFER_REQUEST ||
        destination_node > DAN_DC_NODE_ID_MAX) {
        return DAN_ERR_ARG;
    }
    /* Bit 31 keeps every key non-zero (0 marks a free entry). */
    key = 0x80000000u | (uint32_t)destination_node << 18 | (uint32_t)transfer_type << 16 |
          data_type_id;
    for (i = 0; i < DAN_DC_TX_TIDS; i++) {
        if (tab->key[i] == key || tab->key[i] == 0u) {
            return take_tid(tab, i, key);
        }
    }
    /* Full: a service request's flow gives way, in turn (calls to many
     * nodes would otherwise fill the table for good and leave no room for
     * RawCommand). Its successor starts at that counter: a request is
     * matched by its response's transfer ID, and one that a server took
     * for a duplicate (1 in 32) is retried by its caller. Broadcast flows
     * are a fixed few and never give way. */
    for (i = 0; i < DAN_DC_TX_TIDS; i++) {
        size_t k = (tab->evict + i) % DAN_DC_TX_TIDS;
        if (((tab->key[k] >> 16) & 3u) == DAN_DC_TRANSFER_REQUEST) {
            tab->evict = (uint8_t)((k + 1u) % DAN_DC_TX_TIDS);
            return take_tid(tab, k, key);
        }
    }
    return DAN_ERR_OVERFLOW;
}

/* ---- RX ---- */

void dan_dc_rx_init(dan_dc_rx_t *rx, uint8_t local_node, dan_dc_accept_fn accept, void *user)
{
    if (rx == NULL) {
        return;
    }
    memset(rx, 0, sizeof *rx);
    rx->local_node = local_node <= DAN_DC_NODE_ID_MAX ? local_node : 0u;
    rx->accept = accept;
    rx->user = user;
}

void dan_dc_rx_set_node(dan_dc_rx_t *rx, uint8_t local_node)
{
    if (rx != NULL) {
        rx->local_node = local_node <= DAN_DC_NODE_ID_MAX ? local_node : 0u;
    }
}

static bool timed_out(const dan_dc_rx_session_t *s, uint64_t now_us)
{
    /* A clock that went backwards counts as expired, never as fresh. */
    return now_us < s->ts_start_us ||
           now_us - s->ts_start_us > (uint64_t)DAN_DC_TRANSFER_TIMEOUT_US;
}

static dan_dc_rx_session_t *find_session(dan_dc_rx_t *rx, const dan_dc_transfer_t *t)
{
    size_t i;
    for (i = 0; i < DAN_DC_RX_SESSIONS; i++) {
        dan_dc_rx_session_t *s = &rx->sessions[i];
        if (s->source_node == t->source_node && s->data_type_id == t->data_type_id &&
            s->transfer_type == t->transfer_type) {
            return s;
        }
    }
    return NULL;
}

/* A free slot, else the stalest expired one; for a multi-frame transfer
 * (multi) else the stalest one with no transfer in progress. NULL if none.
 * Single-frame flows keep a slot only to filter duplicates: a flow that
 * sends every 2 s keeps it for good, and with enough of them (NodeStatus,
 * StatusExtended and Temperature of 20 ESCs) every multi-frame transfer
 * (esc.Status, GetNodeInfo, file.Read) found none (review finding). Taking
 * such a slot costs that flow its duplicate filter, nothing else. */
static dan_dc_rx_session_t *alloc_session(dan_dc_rx_t *rx, const dan_dc_transfer_t *t,
                                          uint64_t now_us, bool multi)
{
    dan_dc_rx_session_t *best = NULL, *idle = NULL;
    size_t i;
    for (i = 0; i < DAN_DC_RX_SESSIONS; i++) {
        dan_dc_rx_session_t *s = &rx->sessions[i];
        if (s->source_node == 0u) {
            best = s;
            break;
        }
        if (timed_out(s, now_us) && (best == NULL || s->ts_start_us < best->ts_start_us)) {
            best = s;
        }
        if (multi && !s->in_progress && (idle == NULL || s->ts_start_us < idle->ts_start_us)) {
            idle = s;
        }
    }
    if (best == NULL) {
        best = idle;
    }
    if (best != NULL) {
        if (best->in_progress) {
            rx->stats.timeouts++;
        }
        best->source_node = t->source_node;
        best->data_type_id = t->data_type_id;
        best->transfer_type = t->transfer_type;
        best->in_progress = false;
        best->done = false;
        best->len = 0;
    }
    return best;
}

/* A start frame arrived for session s: account for what it replaces.
 * Returns false if it repeats the transfer just completed. */
static bool session_restart_ok(dan_dc_rx_t *rx, dan_dc_rx_session_t *s, uint8_t tid,
                               uint64_t now_us)
{
    bool expired = timed_out(s, now_us);
    if (s->in_progress) {
        if (expired) {
            rx->stats.timeouts++;
        } else if (s->transfer_id != tid || s->len != DAN_DC_FRAME_DATA_MAX - 2u) {
            /* Cut short by a new transfer. (The same start frame delivered
             * twice just restarts the same transfer: not an error.) */
            rx->stats.tid_errors++;
        }
        s->in_progress = false;
    }
    if (s->done && !expired && s->transfer_id == tid) {
        rx->stats.tid_errors++; /* duplicate of the completed transfer */
        return false;
    }
    s->done = false;
    return true;
}

/* The fields of one received frame. */
typedef struct {
    dan_dc_transfer_t t; /* from the CAN ID, with transfer_id and time */
    size_t n;            /* data bytes before the tail byte */
    uint8_t toggle;
    bool sot, eot;
} rx_frame_t;

/* Parses a frame; false (counted ignored) if it is not one for us. */
static bool rx_parse(dan_dc_rx_t *rx, const dan_can_frame_t *frame, uint64_t now_us, rx_frame_t *fr)
{
    uint8_t tail;
    if ((frame->flags & DAN_CAN_EXT) == 0u || (frame->flags & (DAN_CAN_RTR | DAN_CAN_ERR)) != 0u ||
        frame->dlc < 1u || frame->dlc > 8u) {
        return false;
    }
    memset(fr, 0, sizeof *fr);
    if (dan_dc_parse_id(frame->id, &fr->t) < 0) {
        return false;
    }
    if (fr->t.transfer_type != DAN_DC_TRANSFER_BROADCAST &&
        (rx->local_node == 0u || fr->t.destination_node != rx->local_node)) {
        return false;
    }
    fr->n = (size_t)frame->dlc - 1u;
    tail = frame->data[fr->n];
    fr->t.transfer_id = (uint8_t)(tail & DAN_DC_TRANSFER_ID_MASK);
    fr->t.timestamp_us = now_us;
    fr->toggle = (uint8_t)(tail & DAN_DC_TAIL_TOGGLE);
    fr->sot = (tail & DAN_DC_TAIL_SOT) != 0u;
    fr->eot = (tail & DAN_DC_TAIL_EOT) != 0u;
    return true;
}

/* A start frame: checks it, finds or takes its session, and delivers a
 * single-frame transfer at once (1) or starts a multi-frame one (0). */
static int rx_start(dan_dc_rx_t *rx, dan_dc_rx_session_t *s, const dan_can_frame_t *frame,
                    rx_frame_t *fr, uint64_t now_us, dan_dc_transfer_t *out)
{
    uint64_t sig = 0;
    uint8_t tid = fr->t.transfer_id;
    if (fr->toggle != 0u) {
        rx->stats.toggle_errors++;
        return 0;
    }
    if ((fr->t.source_node == 0u && !fr->eot) || (!fr->eot && fr->n != DAN_DC_FRAME_DATA_MAX)) {
        rx->stats.malformed++; /* anonymous transfers are single-frame */
        return 0;
    }
    if (rx->accept == NULL ||
        !rx->accept(rx->user, fr->t.data_type_id, fr->t.transfer_type, fr->t.source_node, &sig)) {
        rx->stats.ignored++;
        return 0;
    }
    if (s != NULL) {
        if (!session_restart_ok(rx, s, tid, now_us)) {
            return 0;
        }
    } else if (fr->t.source_node != 0u) {
        s = alloc_session(rx, &fr->t, now_us, !fr->eot);
        if (s == NULL && !fr->eot) {
            rx->stats.no_slot++;
            return 0;
        }
        /* A single-frame transfer is delivered even without a slot; it
         * only loses duplicate filtering. */
    }
    if (s != NULL) {
        s->ts_start_us = now_us;
        s->transfer_id = tid;
        s->priority = fr->t.priority;
        s->signature = sig;
    }
    if (fr->eot) {
        memcpy(rx->single, frame->data, fr->n);
        if (s != NULL) {
            s->done = true;
        }
        fr->t.signature = sig;
        fr->t.payload = rx->single;
        fr->t.payload_len = fr->n;
        *out = fr->t;
        rx->stats.transfers++;
        return 1;
    }
    s->crc = (uint16_t)(frame->data[0] | (unsigned)frame->data[1] << 8);
    memcpy(s->buf, &frame->data[2], fr->n - 2u);
    s->len = (uint16_t)(fr->n - 2u);
    s->next_toggle = DAN_DC_TAIL_TOGGLE;
    s->in_progress = true;
    return 0;
}

/* Checks a continuation frame against its session; false (counted) if it
 * does not continue the transfer in progress. */
static bool rx_continues(dan_dc_rx_t *rx, dan_dc_rx_session_t *s, const rx_frame_t *fr,
                         uint64_t now_us)
{
    if (s == NULL || !s->in_progress) {
        rx->stats.tid_errors++; /* start missed (or the transfer was dropped) */
        return false;
    }
    if (timed_out(s, now_us)) {
        rx->stats.timeouts++;
        s->in_progress = false;
        return false;
    }
    if (fr->t.transfer_id != s->transfer_id) {
        rx->stats.tid_errors++;
        return false;
    }
    if (fr->toggle != s->next_toggle) {
        rx->stats.toggle_errors++;
        return false;
    }
    if (!fr->eot && fr->n != DAN_DC_FRAME_DATA_MAX) {
        rx->stats.malformed++;
        s->in_progress = false;
        return false;
    }
    if ((size_t)s->len + fr->n > DAN_DC_MAX_TRANSFER) {
        rx->stats.overflow++;
        s->in_progress = false;
        return false;
    }
    return true;
}

/* A continuation frame: appends it; at the end of the transfer checks the
 * CRC and delivers it (1). */
static int rx_continue(dan_dc_rx_t *rx, dan_dc_rx_session_t *s, const dan_can_frame_t *frame,
                       rx_frame_t *fr, uint64_t now_us, dan_dc_transfer_t *out)
{
    if (!rx_continues(rx, s, fr, now_us)) {
        return 0;
    }
    memcpy(&s->buf[s->len], frame->data, fr->n);
    s->len = (uint16_t)(s->len + fr->n);
    s->next_toggle ^= DAN_DC_TAIL_TOGGLE;
    if (!fr->eot) {
        return 0;
    }
    s->in_progress = false;
    if (dan_dc_transfer_crc(s->signature, s->buf, s->len) != s->crc) {
        rx->stats.crc_errors++;
        return 0;
    }
    s->done = true;
    fr->t.timestamp_us = s->ts_start_us;
    fr->t.priority = s->priority;
    fr->t.signature = s->signature;
    fr->t.payload = s->buf;
    fr->t.payload_len = s->len;
    *out = fr->t;
    rx->stats.transfers++;
    return 1;
}

int dan_dc_rx_frame(dan_dc_rx_t *rx, const dan_can_frame_t *frame, uint64_t now_us,
                    dan_dc_transfer_t *out)
{
    rx_frame_t fr;
    dan_dc_rx_session_t *s;
    if (rx == NULL || frame == NULL || out == NULL) {
        return DAN_ERR_ARG;
    }
    rx->stats.frames++;
    if (!rx_parse(rx, frame, now_us, &fr)) {
        rx->stats.ignored++;
        return 0;
    }
    s = fr.t.source_node != 0u ? find_session(rx, &fr.t) : NULL;
    if (fr.sot) {
        return rx_start(rx, s, frame, &fr, now_us, out);
    }
    return rx_continue(rx, s, frame, &fr, now_us, out);
}

void dan_dc_rx_cleanup(dan_dc_rx_t *rx, uint64_t now_us)
{
    size_t i;
    if (rx == NULL) {
        return;
    }
    for (i = 0; i < DAN_DC_RX_SESSIONS; i++) {
        dan_dc_rx_session_t *s = &rx->sessions[i];
        if (s->source_node != 0u && timed_out(s, now_us)) {
            if (s->in_progress) {
                rx->stats.timeouts++;
            }
            memset(s, 0, offsetof(dan_dc_rx_session_t, buf));
        }
    }
}
