/* Gateway node: raw CAN frames both ways. Every received frame, processed
 * or not, passes the filter table into a ring numbered by sequence; raw
 * frames from the FC queue behind throttle and arming (the bulk queue). */
#include "gw_node_internal.h"

void dan_gwn_raw_in(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us)
{
    dan_gw_node_raw_t *r = &g->raw;
    size_t at;
    size_t i;
    for (i = 0; i < r->nfilters; i++) {
        if (dan_gw_filter_match(&r->filters[i], f)) {
            break;
        }
    }
    if (i == r->nfilters) {
        return;
    }
    if (r->len >= DAN_GW_NODE_RAW_RX) {
        g->stats.raw_dropped++;
        return;
    }
    at = (r->head + r->len) % DAN_GW_NODE_RAW_RX;
    r->ring[at] = *f;
    r->ring_us[at] = (uint32_t)now_us;
    r->len++;
}

uint32_t dan_gwn_raw_time(const dan_gw_node_t *g, size_t i)
{
    return g->raw.ring_us[(g->raw.head + i) % DAN_GW_NODE_RAW_RX];
}

/* A retry repeats seq and frames; an FC that rebooted may reuse a seq with
 * other frames: those are new. The digest tells them apart. All or
 * nothing, so a refused request can simply be sent again. */
void dan_gwn_raw_send(dan_gw_node_t *g, dan_gw_can_send_t *s, const dan_can_frame_t *f,
                      uint32_t digest)
{
    dan_gw_node_raw_t *r = &g->raw;
    size_t i;
    if (!r->send_seq_valid || s->seq != r->send_seq || digest != r->send_digest) {
        r->send_accepted = 0;
        if (dan_gwn_txq_free(&g->q_bulk) >= s->count) {
            for (i = 0; i < s->count; i++) {
                dan_gwn_txq_push(&g->q_bulk, &f[i]);
            }
            g->stats.can_tx += s->count;
            r->send_accepted = s->count;
            r->send_seq = s->seq;
            r->send_digest = digest;
            r->send_seq_valid = true;
        } else {
            g->stats.can_tx_dropped += s->count;
        }
    }
    s->count = r->send_accepted;
    s->queue_free = (uint32_t)dan_gwn_txq_free(&g->q_bulk);
}

const dan_can_frame_t *dan_gwn_raw_at(const dan_gw_node_t *g, size_t i)
{
    return &g->raw.ring[(g->raw.head + i) % DAN_GW_NODE_RAW_RX];
}

void dan_gwn_raw_recv(dan_gw_node_t *g, const dan_gw_can_recv_t *q, dan_gw_can_recv_t *a,
                      size_t cap)
{
    dan_gw_node_raw_t *r = &g->raw;
    int32_t ack = dan_gw_off_diff(q->seq, r->first);
    size_t i, room = cap > DAN_GW_CAN_RECV_HDR_MAX ? cap - DAN_GW_CAN_RECV_HDR_MAX : 0u;
    if (ack > 0 && ack <= (int32_t)r->len) {
        r->head = (uint16_t)((r->head + (uint32_t)ack) % DAN_GW_NODE_RAW_RX);
        r->len = (uint16_t)(r->len - (uint32_t)ack);
        r->first += (uint32_t)ack;
    }
    a->seq = r->first;
    a->dropped = g->stats.raw_dropped;
    a->count = 0;
    a->opts = q->opts;
    if (q->opts & DAN_GW_RECV_TIMES) {
        room = room > DAN_GW_CAN_RECV_TIME_SIZE ? room - DAN_GW_CAN_RECV_TIME_SIZE : 0u;
    }
    for (i = 0; i < r->len && a->count < q->count && a->count < DAN_GW_CAN_FRAMES_MAX; i++) {
        size_t sz = dan_gw_msg_can_frame_size(dan_gwn_raw_at(g, i));
        if (q->opts & DAN_GW_RECV_TIMES) {
            sz += DAN_UVARINT_MAX_BYTES; /* its dt_us at the largest */
        }
        if (sz > room) {
            break;
        }
        room -= sz;
        a->count++;
    }
}

uint8_t dan_gwn_raw_filter(dan_gw_node_t *g, uint8_t op, const dan_gw_filter_t *f, size_t n)
{
    dan_gw_node_raw_t *r = &g->raw;
    uint8_t result = 0;
    size_t i, j;
    if (op == DAN_GW_FILTER_REPLACE) {
        r->nfilters = 0;
    }
    for (i = 0; i < n && op != DAN_GW_FILTER_READ; i++) {
        for (j = 0; j < r->nfilters; j++) {
            if (r->filters[j].id == f[i].id && r->filters[j].mask == f[i].mask) {
                break;
            }
        }
        if (op == DAN_GW_FILTER_REMOVE) {
            if (j < r->nfilters) {
                r->filters[j] = r->filters[r->nfilters - 1u];
                r->nfilters--;
            }
        } else if (j == r->nfilters) {
            if (r->nfilters >= DAN_GW_FILTERS_MAX) {
                result = 1;
            } else {
                r->filters[r->nfilters++] = f[i];
            }
        }
    }
    return result;
}
