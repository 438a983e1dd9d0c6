/* Gateway node: CAN output, two bounded frame queues (urgent before bulk). */
#include <string.h>

#include "gw_node_internal.h"

size_t dan_gwn_txq_free(const dan_gw_node_txq_t *q)
{
    return DAN_GW_NODE_TXQ - q->len;
}

void dan_gwn_txq_push(dan_gw_node_txq_t *q, const dan_can_frame_t *f)
{
    q->f[(q->head + q->len) % DAN_GW_NODE_TXQ] = *f;
    q->len++;
}

bool dan_gw_node_tx_peek(const dan_gw_node_t *g, dan_can_frame_t *f)
{
    const dan_gw_node_txq_t *q = g->q_urgent.len > 0u ? &g->q_urgent : &g->q_bulk;
    if (q->len == 0u) {
        return false;
    }
    *f = q->f[q->head];
    return true;
}

/* A frame of a transfer of ours (not a raw frame the FC sent, whose last
 * byte is no tail byte) that is not its last: the rest is on its way. */
static bool ours_not_last(const dan_gw_node_t *g, const dan_can_frame_t *f)
{
    dan_dc_transfer_t id;
    return (f->flags & (DAN_CAN_EXT | DAN_CAN_RTR)) == DAN_CAN_EXT && f->dlc > 0u &&
           (f->data[f->dlc - 1u] & DAN_DC_TAIL_EOT) == 0u &&
           dan_dc_parse_id(f->id, &id) == DAN_OK && id.source_node == g->cfg.node_id;
}

void dan_gw_node_tx_pop(dan_gw_node_t *g)
{
    dan_gw_node_txq_t *q = g->q_urgent.len > 0u ? &g->q_urgent : &g->q_bulk;
    if (q->len > 0u) {
        const dan_can_frame_t *f = &q->f[q->head];
        /* (a raw frame without bit 6 in its last byte made the next
         * transfer look in flight: latest-wins kept it; review finding) */
        q->mid = ours_not_last(g, f);
        q->head = (uint16_t)((q->head + 1u) % DAN_GW_NODE_TXQ);
        q->len--;
    }
}

void dan_gw_node_tx_sent(dan_gw_node_t *g, uint64_t now_us)
{
    dan_can_frame_t f;
    dan_dc_transfer_t id;
    if (dan_gw_node_tx_peek(g, &f)) {
        dan_gw_node_tx_pop(g);
        /* A frame the FC sent (CAN_SEND) is on the bus now, and the bus
         * does not hand a controller its own frames: the node hears it
         * here, as every other node did (a GetNodeInfo from a node behind
         * the FC gets its answer; its NodeStatus enters the table). */
        if ((f.flags & DAN_CAN_EXT) != 0u && dan_dc_parse_id(f.id, &id) == DAN_OK &&
            id.source_node != g->cfg.node_id) {
            dan_gwn_hear(g, &f, now_us);
        }
        f.flags |= DAN_CAN_OWN;
        dan_gwn_raw_in(g, &f, now_us);
    }
}

size_t dan_gw_node_tx_pending(const dan_gw_node_t *g)
{
    return (size_t)g->q_urgent.len + g->q_bulk.len;
}

/* Throttle, arming and our status are states: only the newest matters,
 * and an old one waiting behind a stalled bus must never go out after a
 * newer one (nor crowd out the failsafe's zeros). A transfer whose first
 * frames are already on the bus is not cut, though: its receivers would
 * drop it, and with commands coming faster than a multi-frame transfer
 * takes (20 ESCs: 6 frames) no command would ever arrive whole. */
size_t dan_gwn_drop_own(dan_gw_node_t *g, dan_gw_node_txq_t *q, uint16_t dtid)
{
    size_t i, kept = 0, n = q->len;
    bool in_flight = q->mid; /* frames at head finish the transfer on the bus */
    for (i = 0; i < n; i++) {
        dan_can_frame_t f = q->f[(q->head + i) % DAN_GW_NODE_TXQ];
        dan_dc_transfer_t id;
        bool ours = !in_flight && (f.flags & DAN_CAN_EXT) != 0u &&
                    dan_dc_parse_id(f.id, &id) == DAN_OK &&
                    id.transfer_type == DAN_DC_TRANSFER_BROADCAST && id.data_type_id == dtid &&
                    id.source_node == g->cfg.node_id;
        if (in_flight && f.dlc > 0u && (f.data[f.dlc - 1u] & DAN_DC_TAIL_EOT) != 0u) {
            in_flight = false; /* that transfer's last frame: kept, the rest as usual */
        }
        if (!ours) {
            q->f[(q->head + kept) % DAN_GW_NODE_TXQ] = f;
            kept++;
        }
    }
    q->len = (uint16_t)kept;
    return n - kept;
}

void dan_gwn_txq_to_front(dan_gw_node_txq_t *q, size_t n)
{
    size_t keep = 0, i, k;
    if (q->mid) { /* the rest of the transfer on the bus stays first */
        while (keep < q->len) {
            const dan_can_frame_t *f = &q->f[(q->head + keep++) % DAN_GW_NODE_TXQ];
            if (f->dlc > 0u && (f->data[f->dlc - 1u] & DAN_DC_TAIL_EOT) != 0u) {
                break;
            }
        }
    }
    if (n > q->len || keep > q->len - n) {
        return;
    }
    for (k = 0; k < n; k++) { /* each of the last n frames moves back past the others */
        for (i = q->len - n + k; i > keep + k; i--) {
            dan_can_frame_t *a = &q->f[(q->head + i - 1u) % DAN_GW_NODE_TXQ];
            dan_can_frame_t *b = &q->f[(q->head + i) % DAN_GW_NODE_TXQ];
            dan_can_frame_t t = *a;
            *a = *b;
            *b = t;
        }
    }
}

/* Frames are built straight into the queue, one at a time: no frame array
 * on the stack (a GetNodeInfo response is 54 frames). */
int dan_gwn_send_transfer(dan_gw_node_t *g, dan_gw_node_txq_t *q, dan_dc_transfer_t *t)
{
    size_t n = dan_dc_tx_frame_count(t->payload_len), i;
    uint16_t crc = 0;
    t->source_node = g->cfg.node_id;
    if (n > 1u) {
        crc = dan_dc_transfer_crc(t->signature, t->payload, t->payload_len);
    }
    if (n > dan_gwn_txq_free(q)) {
        g->stats.can_tx_dropped += (uint32_t)n;
        return DAN_ERR_OVERFLOW;
    }
    for (i = 0; i < n; i++) {
        dan_can_frame_t *f = &q->f[(q->head + q->len + i) % DAN_GW_NODE_TXQ];
        int rc = dan_dc_tx_frame(t, crc, i, f);
        if (rc < 0) {
            return rc; /* nothing committed: q->len counts only whole transfers */
        }
    }
    q->len = (uint16_t)(q->len + n);
    g->stats.can_tx += (uint32_t)n;
    return DAN_OK;
}

int dan_gwn_respond(dan_gw_node_t *g, const dan_dc_transfer_t *req, uint64_t sig,
                    const uint8_t *payload, int len)
{
    dan_dc_transfer_t t;
    if (len < 0) {
        return len;
    }
    dan_dc_transfer_init(&t, req->data_type_id, sig, DAN_DC_TRANSFER_RESPONSE, payload,
                         (size_t)len);
    t.priority = req->priority;
    t.destination_node = req->source_node;
    t.transfer_id = req->transfer_id;
    return dan_gwn_send_transfer(g, &g->q_bulk, &t);
}

int dan_gwn_broadcast(dan_gw_node_t *g, dan_gw_node_txq_t *q, uint16_t dtid, uint64_t sig,
                      uint8_t prio, const uint8_t *payload, int len)
{
    dan_dc_transfer_t t;
    int tid;
    if (len < 0) {
        return len;
    }
    tid = dan_dc_tid_next(&g->tids, dtid, DAN_DC_TRANSFER_BROADCAST, 0);
    if (tid < 0) {
        g->stats.can_tx_dropped++; /* never silent */
        return tid;
    }
    dan_dc_transfer_init(&t, dtid, sig, DAN_DC_TRANSFER_BROADCAST, payload, (size_t)len);
    t.priority = prio;
    t.transfer_id = (uint8_t)tid;
    return dan_gwn_send_transfer(g, q, &t);
}
