/* CAN-over-DAN gateway client: tunnels and raw CAN (calls, completions,
 * readers). See dan/can_gw/client.h. Apart from the ESC calls so that an
 * FC that never calls them links none of it. */
#include <string.h>

#include "gw_client_internal.h"

int dan_gw_tunnel_open(dan_gw_t *gw, const dan_gw_tun_open_t *cfg, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_TUN_OPEN_REQ_MAX)];
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if (cfg == NULL || cfg->port >= DAN_GW_TUNNELS) {
        return DAN_ERR_ARG;
    }
    rc = dan_gwc_start(gw, DAN_GW_CODE_TUN_OPEN, dan_gwc_done_tun_open, buf,
                       dan_gw_msg_tun_open_encode(cfg, buf, DAN_GWC_CAP(buf)), sizeof buf, now_us);
    if (rc == DAN_OK) {
        gw->port = cfg->port;
    }
    return rc;
}

int dan_gw_tunnel_xfer(dan_gw_t *gw, uint8_t port, const uint8_t *data, size_t len, size_t rd_max,
                       uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    dan_gw_tun_xfer_t x;
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if (port >= DAN_GW_TUNNELS) {
        return DAN_ERR_ARG;
    }
    memset(&x, 0, sizeof x);
    x.port = port;
    x.wr_offset = gw->tun[port].wr_offset;
    x.rd_offset = gw->tun[port].rd_offset;
    x.rd_max = (uint32_t)(rd_max > DAN_GW_TUN_CHUNK_MAX ? DAN_GW_TUN_CHUNK_MAX : rd_max);
    x.data = data;
    x.len = len > DAN_GW_TUN_CHUNK_MAX ? DAN_GW_TUN_CHUNK_MAX : len;
    rc = dan_gwc_start(gw, DAN_GW_CODE_TUN_XFER, dan_gwc_done_xfer, buf,
                       dan_gw_msg_tun_xfer_req_encode(&x, buf, DAN_GWC_CAP(buf)), sizeof buf,
                       now_us);
    if (rc == DAN_OK) {
        gw->port = port;
        /* the most offered since the last answer: a call that failed
         * (its answers lost) may have left more at the gateway than a
         * smaller offer now, and that is fine (review finding: the tunnel
         * locked up) */
        if (x.len > gw->xfer_len) {
            gw->xfer_len = (uint8_t)x.len; /* <= DAN_GW_TUN_CHUNK_MAX (128) */
        }
        gw->tun[port].accepted = 0;
    }
    return rc;
}

int dan_gw_can_send(dan_gw_t *gw, const dan_can_frame_t *frames, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    dan_writer_t w;
    dan_gw_can_send_t s;
    size_t i;
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if ((frames == NULL && n > 0u) || n > DAN_GW_CAN_FRAMES_MAX) {
        return DAN_ERR_ARG;
    }
    s.seq = (uint8_t)(gw->can_seq + 1u);
    s.count = (uint8_t)n;
    s.queue_free = 0;
    dan_writer_init(&w, buf, DAN_GWC_CAP(buf));
    dan_gw_msg_can_send_req_put(&w, &s);
    for (i = 0; i < n; i++) {
        dan_gw_msg_can_frame_put(&w, &frames[i]);
    }
    rc = dan_gwc_start(gw, DAN_GW_CODE_CAN_SEND, dan_gwc_done_can_send, buf, dan_writer_finish(&w),
                       sizeof buf, now_us);
    if (rc == DAN_OK) {
        gw->can_accepted = 0;
    }
    /* The number moves on when the gateway answered (dan_gwc_done_can_send):
     * the same frames sent again after a call that failed carry the same
     * number and content, and a gateway that took them then does not send
     * them twice (review finding: a new number put them on the bus twice). */
    return rc;
}

int dan_gw_can_recv(dan_gw_t *gw, uint8_t max, uint64_t now_us)
{
    return dan_gw_can_recv_opts(gw, max, 0, now_us);
}

int dan_gw_can_recv_opts(dan_gw_t *gw, uint8_t max, uint8_t opts, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_CAN_RECV_REQ_MAX)];
    dan_gw_can_recv_t q;
    int rc;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    memset(&q, 0, sizeof q);
    q.seq = gw->can_rx_next;
    q.count = max > DAN_GW_CAN_FRAMES_MAX ? (uint8_t)DAN_GW_CAN_FRAMES_MAX : max;
    q.opts = opts;
    rc = dan_gwc_start(gw, DAN_GW_CODE_CAN_RECV, dan_gwc_done_can_recv, buf,
                       dan_gw_msg_can_recv_req_encode(&q, buf, DAN_GWC_CAP(buf)), sizeof buf,
                       now_us);
    if (rc == DAN_OK) {
        gw->recv_opts = opts;
    }
    return rc;
}

int dan_gw_can_filter(dan_gw_t *gw, uint8_t op, const dan_gw_filter_t *f, size_t n, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    dan_writer_t w;
    size_t i;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    if ((f == NULL && n > 0u) || n > DAN_GW_FILTERS_MAX || op > DAN_GW_FILTER_READ) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, buf, DAN_GWC_CAP(buf));
    dan_gw_msg_filter_hdr_put(&w, op, (uint8_t)n);
    for (i = 0; i < n; i++) {
        dan_gw_msg_filter_put(&w, &f[i]);
    }
    return dan_gwc_start(gw, DAN_GW_CODE_CAN_FILTER, NULL, buf, dan_writer_finish(&w), sizeof buf,
                         now_us);
}

/* ---- completion ---- */

int dan_gwc_done_tun_open(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    (void)code;
    if (len < 2u || p[0] != gw->port) {
        return DAN_ERR_MALFORMED;
    }
    if (p[1] != 0u) {
        return DAN_ERR_NACK;
    }
    memset(&gw->tun[gw->port], 0, sizeof gw->tun[gw->port]);
    return DAN_OK;
}

int dan_gwc_done_can_send(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    dan_gw_can_send_t s;
    int rc = dan_gw_msg_can_send_rsp_decode(&s, p, len);
    (void)code;
    if (rc == DAN_OK && s.seq != (uint8_t)(gw->can_seq + 1u)) {
        rc = DAN_ERR_MALFORMED; /* not the answer to ours */
    }
    if (rc == DAN_OK) {
        gw->can_seq = s.seq;
        gw->can_accepted = s.count;
        gw->can_queue_free = s.queue_free;
    }
    return rc;
}

int dan_gwc_done_can_recv(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_gw_can_recv_t q;
    int32_t skip;
    int rc = dan_gw_can_begin(gw, &r, &q);
    (void)code;
    (void)p;
    (void)len;
    if (rc == DAN_OK) {
        skip = dan_gw_off_diff(q.seq, gw->can_rx_next);
        if (skip < 0 || skip > (int32_t)DAN_GW_CAN_RESYNC) {
            /* Not where we left off: the gateway restarted (its sequence
             * starts elsewhere each boot). Follow it. */
            gw->can_rx_resyncs++;
        } else {
            gw->can_rx_lost += (uint32_t)skip;
        }
        gw->can_rx_next = q.seq + q.count;
        gw->can_rx_dropped = q.dropped;
    }
    return rc;
}

int dan_gwc_done_xfer(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    dan_gw_tun_xfer_t x;
    dan_gw_tunnel_t *t = &gw->tun[gw->port];
    int32_t adv, skip;
    (void)code;
    if (dan_gw_msg_tun_xfer_rsp_decode(&x, p, len) != DAN_OK || x.port != gw->port) {
        return DAN_ERR_MALFORMED;
    }
    /* The gateway cannot accept more than we offered since its last answer
     * (a caller advances its buffer by accepted) nor send older data than
     * we acknowledged; either refuses the whole response, before any state
     * changes. */
    adv = dan_gw_off_diff(x.wr_offset, t->wr_offset);
    skip = dan_gw_off_diff(x.rd_offset, t->rd_offset);
    if (adv < 0 || adv > (int32_t)gw->xfer_len || skip < 0) {
        return DAN_ERR_MALFORMED;
    }
    t->accepted = (uint16_t)adv;
    t->wr_offset = x.wr_offset;
    t->wr_space = x.wr_space;
    t->rd_dropped = x.rd_dropped;
    t->rd_lost += (uint32_t)skip;
    t->rd_offset = x.rd_offset + (uint32_t)x.len;
    gw->xfer_len = 0;
    return DAN_OK;
}

/* ---- reading the response ---- */

int dan_gw_tunnel_data(const dan_gw_t *gw, const uint8_t **data, size_t *len)
{
    dan_reader_t r;
    dan_gw_tun_xfer_t x;
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_TUN_XFER, &r);
    *data = NULL;
    *len = 0;
    if (rc == DAN_OK) {
        rc = dan_gw_msg_tun_xfer_rsp_decode(&x, r.data, r.len);
    }
    if (rc == DAN_OK) {
        *data = x.data;
        *len = x.len;
    }
    return rc;
}

int dan_gw_can_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_can_recv_t *hdr)
{
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_CAN_RECV, r);
    hdr->opts = gw->recv_opts;
    return rc != DAN_OK ? rc : dan_gw_msg_can_recv_rsp_get(r, hdr);
}

int dan_gw_can_next(dan_reader_t *r, dan_can_frame_t *f)
{
    return dan_gw_msg_can_frame_get(r, f);
}

int dan_gw_can_next_timed(dan_reader_t *r, dan_can_frame_t *f, uint32_t *t_us)
{
    int rc = dan_gw_msg_can_frame_get(r, f);
    *t_us += dan_get_uvarint(r);
    return rc != DAN_OK ? rc : dan_reader_finish(r);
}

int dan_gw_filter_begin(const dan_gw_t *gw, dan_reader_t *r, uint8_t *result, uint8_t *count)
{
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_CAN_FILTER, r);
    return rc != DAN_OK ? rc : dan_gw_msg_filter_hdr_get(r, result, count);
}

int dan_gw_filter_next(dan_reader_t *r, dan_gw_filter_t *f)
{
    return dan_gw_msg_filter_get(r, f);
}
