/* DroneCAN (UAVCAN v0) transport: IDs, TX splitting, RX reassembly, CRC,
 * DSDL bit serialization and float16. See dronecan.h. */
#include <string.h>

#include "dronecan.h"

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
        if (t->data_type_id > 0xFFu || t->source_node == 0u ||
            t->destination_node == 0u || t->destination_node > DAN_DC_NODE_ID_MAX) {
            return DAN_ERR_ARG;
        }
        v |= (uint32_t)t->data_type_id << 16 | (uint32_t)t->destination_node << 8 |
             DAN_DC_ID_SERVICE | t->source_node;
        if (t->transfer_type == DAN_DC_TRANSFER_REQUEST) {
            v |= DAN_DC_ID_REQUEST;
        }
        break;
    default:
        return DAN_ERR_ARG;
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
        t->transfer_type = (uint8_t)((id & DAN_DC_ID_REQUEST) != 0u ?
                                     DAN_DC_TRANSFER_REQUEST : DAN_DC_TRANSFER_RESPONSE);
        t->destination_node = (uint8_t)((id >> 8) & 0x7Fu);
        if (t->source_node == 0u || t->destination_node == 0u) {
            return DAN_ERR_MALFORMED;
        }
    } else {
        t->transfer_type = DAN_DC_TRANSFER_BROADCAST;
        if (t->source_node == 0u) {
            t->discriminator = (uint16_t)((id >> DAN_DC_ID_ANON_DISC_SHIFT) &
                                          DAN_DC_ID_ANON_DISC_MASK);
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

static int tx_frame(const dan_dc_transfer_t *t, uint32_t id, uint16_t crc,
                    size_t index, size_t count, dan_can_frame_t *out)
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
            out->data[n++] = k == 0u ? (uint8_t)crc : k == 1u ? (uint8_t)(crc >> 8) :
                             t->payload[k - 2u];
        }
    }
    out->data[n] = dan_dc_tail(index == 0u, index + 1u == count, (index & 1u) != 0u,
                               t->transfer_id);
    out->dlc = (uint8_t)(n + 1u);
    return DAN_OK;
}

int dan_dc_tx_frame(const dan_dc_transfer_t *t, uint16_t crc, size_t index,
                    dan_can_frame_t *out)
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

int dan_dc_tid_next(dan_dc_tid_table_t *tab, uint16_t data_type_id,
                    uint8_t transfer_type, uint8_t destination_node)
{
    uint32_t key;
    size_t i;
    if (tab == NULL || transfer_type > DAN_DC_TRANSFER_REQUEST ||
        destination_node > DAN_DC_NODE_ID_MAX) {
        return DAN_ERR_ARG;
    }
    /* Bit 31 keeps every key non-zero (0 marks a free entry). */
    key = 0x80000000u | (uint32_t)destination_node << 18 |
          (uint32_t)transfer_type << 16 | data_type_id;
    for (i = 0; i < DAN_DC_TX_TIDS; i++) {
        if (tab->key[i] == key || tab->key[i] == 0u) {
            uint8_t tid = tab->next[i];
            tab->key[i] = key;
            tab->next[i] = (uint8_t)((tid + 1u) & DAN_DC_TRANSFER_ID_MASK);
            return tid;
        }
    }
    return DAN_ERR_OVERFLOW;
}

/* ---- RX ---- */

void dan_dc_rx_init(dan_dc_rx_t *rx, uint8_t local_node,
                    dan_dc_accept_fn accept, void *user)
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

/* A free slot, else the stalest expired one; NULL if all are live. */
static dan_dc_rx_session_t *alloc_session(dan_dc_rx_t *rx, const dan_dc_transfer_t *t,
                                          uint64_t now_us)
{
    dan_dc_rx_session_t *best = NULL;
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

int dan_dc_rx_frame(dan_dc_rx_t *rx, const dan_can_frame_t *frame,
                    uint64_t now_us, dan_dc_transfer_t *out)
{
    dan_dc_transfer_t t;
    dan_dc_rx_session_t *s;
    uint8_t tail, tid, toggle;
    size_t n;
    bool sot, eot;
    uint64_t sig = 0;

    if (rx == NULL || frame == NULL || out == NULL) {
        return DAN_ERR_ARG;
    }
    rx->stats.frames++;
    if ((frame->flags & DAN_CAN_EXT) == 0u ||
        (frame->flags & (DAN_CAN_RTR | DAN_CAN_ERR)) != 0u ||
        frame->dlc < 1u || frame->dlc > 8u) {
        rx->stats.ignored++;
        return 0;
    }
    memset(&t, 0, sizeof t);
    if (dan_dc_parse_id(frame->id, &t) < 0) {
        rx->stats.ignored++;
        return 0;
    }
    if (t.transfer_type != DAN_DC_TRANSFER_BROADCAST &&
        (rx->local_node == 0u || t.destination_node != rx->local_node)) {
        rx->stats.ignored++;
        return 0;
    }
    n = (size_t)frame->dlc - 1u;
    tail = frame->data[n];
    tid = (uint8_t)(tail & DAN_DC_TRANSFER_ID_MASK);
    toggle = (uint8_t)(tail & DAN_DC_TAIL_TOGGLE);
    sot = (tail & DAN_DC_TAIL_SOT) != 0u;
    eot = (tail & DAN_DC_TAIL_EOT) != 0u;
    t.transfer_id = tid;
    t.timestamp_us = now_us;

    s = t.source_node != 0u ? find_session(rx, &t) : NULL;

    if (sot) {
        if (toggle != 0u) {
            rx->stats.toggle_errors++;
            return 0;
        }
        if (t.source_node == 0u && !eot) {
            rx->stats.malformed++; /* anonymous transfers are single-frame */
            return 0;
        }
        if (!eot && n != DAN_DC_FRAME_DATA_MAX) {
            rx->stats.malformed++;
            return 0;
        }
        if (rx->accept == NULL ||
            !rx->accept(rx->user, t.data_type_id, t.transfer_type, t.source_node, &sig)) {
            rx->stats.ignored++;
            return 0;
        }
        if (s != NULL) {
            if (!session_restart_ok(rx, s, tid, now_us)) {
                return 0;
            }
        } else if (t.source_node != 0u) {
            s = alloc_session(rx, &t, now_us);
            if (s == NULL && !eot) {
                rx->stats.no_slot++;
                return 0;
            }
            /* A single-frame transfer is delivered even without a slot; it
             * only loses duplicate filtering. */
        }
        if (s != NULL) {
            s->ts_start_us = now_us;
            s->transfer_id = tid;
            s->priority = t.priority;
            s->signature = sig;
        }
        if (eot) {
            memcpy(rx->single, frame->data, n);
            if (s != NULL) {
                s->done = true;
            }
            t.signature = sig;
            t.payload = rx->single;
            t.payload_len = n;
            *out = t;
            rx->stats.transfers++;
            return 1;
        }
        s->crc = (uint16_t)(frame->data[0] | (unsigned)frame->data[1] << 8);
        memcpy(s->buf, &frame->data[2], n - 2u);
        s->len = (uint16_t)(n - 2u);
        s->next_toggle = DAN_DC_TAIL_TOGGLE;
        s->in_progress = true;
        return 0;
    }

    /* Continuation frame. */
    if (s == NULL || !s->in_progress) {
        rx->stats.tid_errors++; /* start missed (or the transfer was dropped) */
        return 0;
    }
    if (timed_out(s, now_us)) {
        rx->stats.timeouts++;
        s->in_progress = false;
        return 0;
    }
    if (tid != s->transfer_id) {
        rx->stats.tid_errors++;
        return 0;
    }
    if (toggle != s->next_toggle) {
        rx->stats.toggle_errors++;
        return 0;
    }
    if (!eot && n != DAN_DC_FRAME_DATA_MAX) {
        rx->stats.malformed++;
        s->in_progress = false;
        return 0;
    }
    if ((size_t)s->len + n > DAN_DC_MAX_TRANSFER) {
        rx->stats.overflow++;
        s->in_progress = false;
        return 0;
    }
    memcpy(&s->buf[s->len], frame->data, n);
    s->len = (uint16_t)(s->len + n);
    s->next_toggle ^= DAN_DC_TAIL_TOGGLE;
    if (!eot) {
        return 0;
    }
    s->in_progress = false;
    if (dan_dc_transfer_crc(s->signature, s->buf, s->len) != s->crc) {
        rx->stats.crc_errors++;
        return 0;
    }
    s->done = true;
    t.timestamp_us = s->ts_start_us;
    t.priority = s->priority;
    t.signature = s->signature;
    t.payload = s->buf;
    t.payload_len = s->len;
    *out = t;
    rx->stats.transfers++;
    return 1;
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

/* ---- DSDL bit-level serialization ---- */

/* Copies bit_len bits, MSB first, from src at src_off to dst at dst_off. */
static void copy_bits(const uint8_t *src, size_t src_off, size_t bit_len,
                      uint8_t *dst, size_t dst_off)
{
    size_t i;
    for (i = 0; i < bit_len; i++) {
        size_t si = src_off + i, di = dst_off + i;
        unsigned bit = ((unsigned)src[si / 8u] >> (7u - si % 8u)) & 1u;
        uint8_t mask = (uint8_t)(0x80u >> (di % 8u));
        if (bit != 0u) {
            dst[di / 8u] = (uint8_t)(dst[di / 8u] | mask);
        } else {
            dst[di / 8u] = (uint8_t)(dst[di / 8u] & (uint8_t)~mask);
        }
    }
}

void dan_dc_encode_scalar(uint8_t *buf, size_t bit_offset, unsigned bit_len,
                          uint64_t value)
{
    uint8_t le[8];
    unsigned i;
    if (buf == NULL || bit_len < 1u || bit_len > 64u) {
        return;
    }
    /* Little-endian bytes; the partial last byte's bits move to its top so
     * the MSB-first copy takes exactly its n % 8 low bits. */
    for (i = 0; i < 8u; i++) {
        le[i] = (uint8_t)(value >> (8u * i));
    }
    if (bit_len % 8u != 0u) {
        le[bit_len / 8u] = (uint8_t)(le[bit_len / 8u] << (8u - bit_len % 8u));
    }
    copy_bits(le, 0, bit_len, buf, bit_offset);
}

uint64_t dan_dc_decode_scalar(const uint8_t *buf, size_t bit_offset,
                              unsigned bit_len, bool is_signed)
{
    uint8_t le[8] = {0};
    uint64_t v = 0;
    unsigned i;
    if (buf == NULL || bit_len < 1u || bit_len > 64u) {
        return 0;
    }
    copy_bits(buf, bit_offset, bit_len, le, 0);
    if (bit_len % 8u != 0u) {
        le[bit_len / 8u] = (uint8_t)(le[bit_len / 8u] >> (8u - bit_len % 8u));
    }
    for (i = 0; i < 8u; i++) {
        v |= (uint64_t)le[i] << (8u * i);
    }
    if (is_signed && bit_len < 64u && ((v >> (bit_len - 1u)) & 1u) != 0u) {
        v |= ~(uint64_t)0 << bit_len;
    }
    return v;
}

void dan_dc_bw_init(dan_dc_bw_t *w, uint8_t *buf, size_t cap)
{
    w->buf = buf;
    w->cap = buf != NULL ? cap : 0u;
    w->bit = 0;
    w->error = false;
}

/* Room for bits more bits? Sets the error if not. */
static bool bw_room(dan_dc_bw_t *w, unsigned bits)
{
    if (w->error || bits < 1u || bits > 64u) {
        w->error = true;
        return false;
    }
    if (w->buf != NULL && (w->cap > SIZE_MAX / 8u || w->cap * 8u < bits ||
                           w->bit > w->cap * 8u - bits)) {
        w->error = true;
        return false;
    }
    return true;
}

static void bw_raw(dan_dc_bw_t *w, unsigned bits, uint64_t v)
{
    if (!bw_room(w, bits)) {
        return;
    }
    if (w->buf != NULL) {
        if (w->bit % 8u == 0u) {
            w->buf[w->bit / 8u] = 0; /* new byte: padding bits read as 0 */
        }
        dan_dc_encode_scalar(w->buf, w->bit, bits, v);
        /* Zero the rest of the last byte touched, so padding is clean. */
        if ((w->bit + bits) % 8u != 0u) {
            size_t last = (w->bit + bits) / 8u;
            w->buf[last] = (uint8_t)(w->buf[last] &
                                     (uint8_t)(0xFF00u >> ((w->bit + bits) % 8u)));
        }
    }
    w->bit += bits;
}

void dan_dc_put_uint(dan_dc_bw_t *w, unsigned bits, uint64_t v)
{
    if (bits >= 1u && bits < 64u) {
        uint64_t max = ((uint64_t)1 << bits) - 1u;
        if (v > max) {
            v = max;
        }
    }
    bw_raw(w, bits, v);
}

void dan_dc_put_int(dan_dc_bw_t *w, unsigned bits, int64_t v)
{
    if (bits >= 2u && bits < 64u) {
        int64_t max = (int64_t)(((uint64_t)1 << (bits - 1u)) - 1u);
        int64_t min = -max - 1;
        if (v > max) {
            v = max;
        } else if (v < min) {
            v = min;
        }
    } else if (bits != 64u) {
        w->error = true;
        return;
    }
    bw_raw(w, bits, (uint64_t)v);
}

void dan_dc_put_bool(dan_dc_bw_t *w, bool v)
{
    bw_raw(w, 1u, v ? 1u : 0u);
}

void dan_dc_put_f16(dan_dc_bw_t *w, float v)
{
    if (v > 65504.0f && v <= 3.4028235e38f) {
        v = 65504.0f;
    } else if (v < -65504.0f && v >= -3.4028235e38f) {
        v = -65504.0f;
    }
    bw_raw(w, 16u, dan_dc_f16_from_f32(v));
}

void dan_dc_put_f32(dan_dc_bw_t *w, float v)
{
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    bw_raw(w, 32u, u);
}

void dan_dc_put_bytes(dan_dc_bw_t *w, const uint8_t *p, size_t n)
{
    size_t i;
    if (p == NULL && n > 0u) {
        w->error = true;
        return;
    }
    for (i = 0; i < n && !w->error; i++) {
        bw_raw(w, 8u, p[i]);
    }
}

unsigned dan_dc_array_len_bits(size_t max)
{
    unsigned bits = 0;
    while (max != 0u) {
        bits++;
        max >>= 1;
    }
    return bits;
}

void dan_dc_put_array_len(dan_dc_bw_t *w, size_t len, size_t max)
{
    if (len > max || max == 0u) {
        w->error = true;
        return;
    }
    bw_raw(w, dan_dc_array_len_bits(max), len);
}

int dan_dc_bw_finish(const dan_dc_bw_t *w)
{
    size_t bytes;
    if (w->error) {
        return DAN_ERR_OVERFLOW;
    }
    bytes = (w->bit + 7u) / 8u;
    if (bytes > (size_t)0x7FFFFFFF) {
        return DAN_ERR_OVERFLOW;
    }
    return (int)bytes;
}

void dan_dc_br_init(dan_dc_br_t *r, const uint8_t *data, size_t len)
{
    r->data = data;
    r->len = data != NULL ? len : 0u;
    r->bit = 0;
    r->error = false;
}

size_t dan_dc_br_remaining_bits(const dan_dc_br_t *r)
{
    if (r->error || r->len > SIZE_MAX / 8u || r->bit > r->len * 8u) {
        return 0;
    }
    return r->len * 8u - r->bit;
}

static uint64_t br_raw(dan_dc_br_t *r, unsigned bits, bool is_signed)
{
    uint64_t v;
    if (r->error || bits < 1u || bits > 64u || dan_dc_br_remaining_bits(r) < bits) {
        r->error = true;
        return 0;
    }
    v = dan_dc_decode_scalar(r->data, r->bit, bits, is_signed);
    r->bit += bits;
    return v;
}

uint64_t dan_dc_get_uint(dan_dc_br_t *r, unsigned bits)
{
    return br_raw(r, bits, false);
}

int64_t dan_dc_get_int(dan_dc_br_t *r, unsigned bits)
{
    uint64_t u;
    if (bits < 2u) {
        r->error = true;
        return 0;
    }
    u = br_raw(r, bits, true);
    /* Two's complement reinterpretation without implementation-defined
     * conversion of out-of-range unsigned values. */
    if ((u >> 63) != 0u) {
        return -(int64_t)(~u) - 1;
    }
    return (int64_t)u;
}

bool dan_dc_get_bool(dan_dc_br_t *r)
{
    return br_raw(r, 1u, false) != 0u;
}

float dan_dc_get_f16(dan_dc_br_t *r)
{
    return dan_dc_f32_from_f16((uint16_t)br_raw(r, 16u, false));
}

float dan_dc_get_f32(dan_dc_br_t *r)
{
    uint32_t u = (uint32_t)br_raw(r, 32u, false);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

void dan_dc_get_bytes(dan_dc_br_t *r, uint8_t *out, size_t n)
{
    size_t i;
    if (dan_dc_br_remaining_bits(r) / 8u < n) {
        r->error = true;
        return;
    }
    for (i = 0; i < n; i++) {
        uint8_t b = (uint8_t)br_raw(r, 8u, false);
        if (out != NULL) {
            out[i] = b;
        }
    }
}

size_t dan_dc_get_array_len(dan_dc_br_t *r, size_t max)
{
    uint64_t len;
    if (max == 0u) {
        r->error = true;
        return 0;
    }
    len = br_raw(r, dan_dc_array_len_bits(max), false);
    if (len > max) {
        r->error = true;
        return 0;
    }
    return (size_t)len;
}

int dan_dc_br_finish(const dan_dc_br_t *r)
{
    return r->error ? DAN_ERR_MALFORMED : DAN_OK;
}

size_t dan_dc_tao_count(const dan_dc_br_t *r, unsigned elem_bits)
{
    if (elem_bits == 0u) {
        return 0;
    }
    return dan_dc_br_remaining_bits(r) / elem_bits;
}

/* ---- float16 ---- */

uint16_t dan_dc_f16_from_f32(float v)
{
    uint32_t x, e, m;
    uint16_t sign, h;
    memcpy(&x, &v, sizeof x);
    sign = (uint16_t)((x >> 16) & 0x8000u);
    x &= 0x7FFFFFFFu;
    e = x >> 23;
    m = x & 0x7FFFFFu;
    if (e == 0xFFu) {
        return (uint16_t)(sign | (m != 0u ? 0x7FFFu : 0x7C00u));
    }
    if (e >= 143u) {                 /* 2^16 and up: beyond half range */
        return (uint16_t)(sign | 0x7C00u);
    }
    if (e >= 113u) {                 /* half normal: exponent -14..15 */
        h = (uint16_t)(((e - 112u) << 10) | (m >> 13));
        if ((m & 0x1000u) != 0u) {
            h++;                     /* ties away; may carry into inf */
        }
        return (uint16_t)(sign | h);
    }
    if (e >= 101u) {                 /* half subnormal, units of 2^-24 */
        uint32_t mant = m | 0x800000u;
        unsigned shift = 126u - (unsigned)e; /* 14..25 */
        h = (uint16_t)(mant >> shift);
        if (((mant >> (shift - 1u)) & 1u) != 0u) {
            h++;
        }
        return (uint16_t)(sign | h);
    }
    return sign;                     /* below half the smallest subnormal */
}

float dan_dc_f32_from_f16(uint16_t h)
{
    uint32_t sign = (uint32_t)(h & 0x8000u) << 16;
    uint32_t e = (h >> 10) & 0x1Fu;
    uint32_t m = h & 0x3FFu;
    uint32_t x;
    float f;
    if (e == 0u) {
        f = (float)m * 5.9604644775390625e-8f; /* m * 2^-24, exact */
        return sign != 0u ? -f : f;
    }
    if (e == 31u) {
        x = sign | 0x7F800000u | (m << 13);
    } else {
        x = sign | ((e + 112u) << 23) | (m << 13);
    }
    memcpy(&f, &x, sizeof f);
    return f;
}
