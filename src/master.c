/* DAN master engine: transactions with listen-before-talk, echo/collision
 * handling and retries (the sequencers are in master_seq.c). */
#include <string.h>

#include "dan/codes.h"
#include "master_internal.h"

enum { PH_IDLE = 0, PH_LBT, PH_TX, PH_WAIT, PH_DONE };

void dan_master_config_default(dan_master_config_t *c)
{
    memset(c, 0, sizeof *c);
    c->resp_latency_us = DAN_RESP_LATENCY_US;
    c->busy_timeout_us = 200000u;
    c->settle_us = 2000u;
    c->retries = 2;
    c->discovery_attempts = 2;
    c->lbt_chars = DAN_LBT_CHARS;
    c->scan_all_bauds = true;
    c->seed = 1;
}

static uint32_t next_rand(dan_master_t *m)
{
    uint32_t x = m->rng;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    m->rng = x;
    return x;
}

static void on_frame(void *owner, const dan_frame_t *f, uint64_t now64);

int dan_master_init(dan_master_t *m, const dan_port_t *port, const dan_master_config_t *cfg,
                    const uint32_t *types, size_t ntypes, uint32_t baud, uint64_t now_us)
{
    size_t i;
    if (m == NULL || port == NULL || port->write == NULL || port->set_baud == NULL ||
        ntypes > DAN_MASTER_MAX_TYPES || (ntypes > 0u && types == NULL) || baud == 0u) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    if (cfg != NULL) {
        m->cfg = *cfg;
    } else {
        dan_master_config_default(&m->cfg);
    }
    if (m->cfg.lbt_chars < 2u) {
        m->cfg.lbt_chars = 2u; /* our rule: never less than two idle characters */
    }
    if (m->cfg.discovery_attempts == 0u) {
        m->cfg.discovery_attempts = 1u;
    }
    m->rng = (m->cfg.seed != 0u) ? m->cfg.seed : 1u;
    for (i = 0; i < ntypes; i++) {
        m->peers[i].first_code = types[i];
    }
    m->ntypes = (uint8_t)ntypes; /* <= DAN_MASTER_MAX_TYPES */
    dan_link_init(&m->link, port, baud, on_frame, m, now_us);
    m->resp = m->link.tx;
    m->link.gap_us = m->cfg.gap_us;
    /* The echo comes back the way replies do: allow it the same latency. */
    m->link.echo_timeout_us = m->cfg.resp_latency_us;
    return DAN_OK;
}

bool dan_master_busy(const dan_master_t *m)
{
    return m->op != DAN_MASTER_OP_NONE;
}

int dan_master_result(const dan_master_t *m)
{
    return m->result;
}

const dan_peer_t *dan_master_peer(const dan_master_t *m, uint32_t first_code)
{
    size_t i;
    for (i = 0; i < m->ntypes; i++) {
        if (m->peers[i].first_code == first_code && m->peers[i].present) {
            return &m->peers[i];
        }
    }
    return NULL;
}

void dan_master_set_identities(dan_master_t *m, dan_identity_t *ids, size_t n)
{
    m->ids = ids;
    m->nids = (ids != NULL) ? n : 0u;
    m->id_decode = dan_identity_decode; /* referenced here only: linked when called */
}

const dan_identity_t *dan_master_identity(const dan_master_t *m, uint32_t first_code)
{
    const dan_peer_t *p = dan_master_peer(m, first_code);
    size_t i = (p != NULL) ? (size_t)(p - m->peers) : m->nids;
    return (i < m->nids) ? &m->ids[i] : NULL;
}

bool dan_mst_port_supports(const dan_master_t *m, uint32_t baud)
{
    return m->link.port.max_baud == 0u || baud <= m->link.port.max_baud;
}

void dan_master_set_reply_check(dan_master_t *m, dan_reply_check_fn fn, void *user)
{
    m->reply_check = fn;
    m->reply_check_user = user;
}

/* ---- transactions ---- */

static uint32_t lbt_us(const dan_master_t *m)
{
    return m->cfg.lbt_chars * m->link.char_us;
}

/* Random backoff after a failed attempt: [0, 8 * 2^k) characters, k =
 * min(attempt, 4), on top of the listen-before-talk idle time. */
static void backoff(dan_master_t *m, uint32_t now_us)
{
    uint32_t k = (m->attempt < 4u) ? m->attempt : 4u;
    uint32_t slots = 8u << k;
    m->wait_until_us = now_us + (next_rand(m) % slots) * m->link.char_us;
}

static void txn_finish(dan_master_t *m, int result)
{
    if (m->link.state == DAN_LINK_TX_DONE) {
        dan_link_ack(&m->link); /* completed before a poll saw the TX end */
    }
    m->txn_result = result;
    m->txn_phase = PH_DONE;
    if (result == DAN_OK) {
        m->stats.ok++;
    }
}

void dan_mst_txn_start(dan_master_t *m, uint32_t code, const uint8_t *payload, size_t len,
                       uint8_t attempts, uint32_t now_us)
{
    m->req_code = code;
    /* The encoded frame waits in the link's TX buffer; retries resend it. */
    if (dan_link_prepare(&m->link, code, payload, len) != DAN_OK) {
        m->stats.transactions++;
        txn_finish(m, DAN_ERR_ARG);
        return;
    }
    m->attempts_left = attempts;
    m->attempt = 0;
    m->txn_phase = PH_LBT;
    m->busy_since_us = now_us;
    m->lbt_counted = false;
    m->resp_len = 0;
    m->resp_code = 0;
    m->stats.transactions++;
    /* wait_until_us is a backoff of this transaction or the settle time of
     * a baud switch just made: anything else (in the past) is over */
    if (m->wait_until_us - now_us > m->cfg.settle_us) {
        m->wait_until_us = now_us;
    }
}

/* An attempt failed (timeout or collision): retry or give up. */
static void txn_attempt_failed(dan_master_t *m, int why, uint32_t now_us)
{
    if (m->link.state == DAN_LINK_TX_DONE) {
        dan_link_ack(&m->link); /* failed from on_frame, before a poll */
    }
    if (m->attempts_left > 0u) {
        m->attempts_left--;
    }
    if (m->attempts_left == 0u) {
        txn_finish(m, why);
        return;
    }
    m->stats.retries++;
    m->attempt++;
    backoff(m, now_us);
    m->busy_since_us = now_us;
    m->txn_phase = PH_LBT;
}

/* Ends the transaction with f as its response, kept in the TX buffer (see
 * dan_master_t.resp): the request is done. tx_len stays (the end of our
 * frame on the wire); the bytes no longer match it, so no later frame
 * passes for its late echo. */
static void keep_response(dan_master_t *m, const dan_frame_t *f, int result)
{
    memcpy(m->resp, f->payload, f->len);
    m->resp_len = f->len;
    m->resp_code = f->code;
    txn_finish(m, result);
}

int dan_master_remote_error(const dan_master_t *m, dan_error_msg_t *e)
{
    if (m->resp_code != DAN_CODE_ERROR) { /* set only by an error frame for our request */
        return DAN_ERR_NOTFOUND;
    }
    return dan_error_decode(e, m->resp, m->resp_len);
}

static void on_frame(void *owner, const dan_frame_t *f, uint64_t now64)
{
    dan_master_t *m = (dan_master_t *)owner;
    uint32_t code, now_us = (uint32_t)now64;
    /* A reply may arrive in the same read as the last echo byte (or, with a
     * direction pin, before a poll has noticed the end of our frame). */
    bool sent =
        m->txn_phase == PH_WAIT ||
        (m->txn_phase == PH_TX && (!m->link.port.echo || m->link.state == DAN_LINK_TX_DONE));
    if (!sent) {
        m->stats.stray++;
        return;
    }
    if (dan_link_is_late_echo(&m->link, f, now_us)) {
        m->stats.stray++; /* our own request, echoed late: not its reply */
        return;
    }
    /* no echo, and a poll has not seen our frame end (PH_TX): a reply
     * proves it has (else the link stays in TX and refuses the next one) */
    dan_link_tx_answered(&m->link, now_us);
    if (f->code == m->req_code) {
        if (m->reply_check != NULL &&
            m->reply_check(m->reply_check_user, f->code, f->payload, f->len) != DAN_OK) {
            m->stats.bad_replies++;
            txn_attempt_failed(m, DAN_ERR_MALFORMED, now_us);
            return;
        }
        keep_response(m, f, DAN_OK);
        return;
    }
    if (f->code == DAN_CODE_ERROR && dan_error_code(f->payload, f->len, &code) == DAN_OK &&
        code == m->req_code) {
        m->stats.remote_errors++;
        keep_response(m, f, DAN_ERR_REMOTE); /* understood and refused: no retry */
        return;
    }
    m->stats.stray++;
}

/* Response deadline: the reply must start within the turnaround plus
 * resp_latency_us after our request left the wire. */
static uint32_t reply_start_deadline(const dan_master_t *m, uint32_t tx_end_us)
{
    return tx_end_us + DAN_TURNAROUND_CHARS * m->link.char_us + m->cfg.resp_latency_us;
}

/* How long past the start deadline a reply that has begun may take:
 * a maximal frame, at least the inter-byte gap (2 ms: at 1-2 Mbit/s a
 * frame is under 1 ms, shorter than a USB adapter's latency timer). */
static uint32_t reply_tail_us(const dan_master_t *m)
{
    uint32_t frame = DAN_MAX_FRAME * m->link.char_us;
    uint32_t gap = dan_link_gap_us(&m->link);
    return (frame > gap) ? frame : gap;
}

/* now_us before t (wrap-safe: both within 2^31 us) */
static bool before(uint32_t now_us, uint32_t t)
{
    return now_us - t >= 0x80000000u;
}

static void txn_poll(dan_master_t *m, uint64_t now64)
{
    dan_link_state_t ls = dan_link_poll(&m->link, now64);
    uint32_t now_us = (uint32_t)now64;
    switch (m->txn_phase) {
    case PH_LBT:
        if (before(now_us, m->wait_until_us)) {
            break;
        }
        if (dan_link_idle_us(&m->link, now_us) < lbt_us(m)) {
            if (now_us - m->busy_since_us >= m->cfg.busy_timeout_us) {
                m->stats.busy_failures++;
                txn_finish(m, DAN_ERR_BUSY);
            } else if (!m->lbt_counted) {
                m->stats.lbt_waits++;
                m->lbt_counted = true; /* once per wait */
            }
            break;
        }
        m->lbt_counted = false;
        if (dan_link_transmit(&m->link, now_us) != DAN_OK) {
            txn_finish(m, DAN_ERR_IO);
            break;
        }
        m->txn_phase = PH_TX;
        break;
    case PH_TX:
        if (ls == DAN_LINK_TX_DONE) {
            dan_link_ack(&m->link);
            m->txn_phase = PH_WAIT;
            m->deadline_us = reply_start_deadline(m, now_us);
        } else if (ls == DAN_LINK_TX_FAILED) {
            dan_link_ack(&m->link);
            txn_attempt_failed(m, DAN_ERR_COLLISION, now_us);
        }
        break;
    case PH_WAIT:
        if (before(now_us, m->deadline_us)) {
            break;
        }
        /* Past the start deadline: wait on while a reply is arriving, but
         * not longer than a whole maximal frame (or the inter-byte gap, at
         * fast bauds: a host gets a reply's bytes in bursts). */
        if (dan_link_idle_us(&m->link, now_us) < dan_link_gap_us(&m->link) &&
            before(now_us, m->deadline_us + reply_tail_us(m))) {
            break;
        }
        m->stats.timeouts++;
        txn_attempt_failed(m, DAN_ERR_TIMEOUT, now_us);
        break;
    default: break;
    }
}

void dan_mst_op_finish(dan_master_t *m, int result)
{
    m->result = result;
    m->op = DAN_MASTER_OP_NONE;
    m->step = DAN_ST_NONE;
    m->done = true;
}

int dan_mst_op_begin(dan_master_t *m, dan_master_op_t op, uint64_t now_us)
{
    if (m->op != DAN_MASTER_OP_NONE) {
        return DAN_ERR_BUSY;
    }
    dan_link_set_now(&m->link, now_us);
    m->op = op;
    m->done = false;
    m->result = DAN_OK;
    m->idx = 0;
    m->bidx = 0;
    return DAN_OK;
}

int dan_master_request(dan_master_t *m, uint32_t code, const uint8_t *payload, size_t len,
                       uint64_t now_us)
{
    int r;
    if (len > DAN_MAX_PAYLOAD || (len > 0u && payload == NULL)) {
        return DAN_ERR_ARG;
    }
    r = dan_mst_op_begin(m, DAN_MASTER_OP_TXN, now_us);
    if (r != DAN_OK) {
        return r;
    }
    dan_mst_txn_start(m, code, payload, len, (uint8_t)(m->cfg.retries + 1u), (uint32_t)now_us);
    return DAN_OK;
}

void dan_master_rx(dan_master_t *m, const uint8_t *data, size_t len, uint64_t now_us)
{
    dan_link_rx(&m->link, data, len, now_us);
}

int dan_master_poll(dan_master_t *m, uint64_t now_us)
{
    if (m->op != DAN_MASTER_OP_NONE) {
        if (m->txn_phase != PH_DONE) {
            txn_poll(m, now_us);
        }
        if (m->txn_phase == PH_DONE) {
            m->txn_phase = PH_IDLE;
            if (m->op == DAN_MASTER_OP_TXN) {
                dan_mst_op_finish(m, m->txn_result);
            } else {
                dan_mst_seq_txn_done(m, (uint32_t)now_us);
            }
        }
    } else {
        (void)dan_link_poll(&m->link, now_us);
    }
    if (m->done) {
        m->done = false;
        return 1;
    }
    return 0;
}

static uint32_t max_u32(uint32_t a, uint32_t b)
{
    return (a > b) ? a : b;
}

/* Waits from the link's last now_us (dan_link_due_in()): the earliest is
 * given back as a 64-bit time. */
uint64_t dan_master_next_us(const dan_master_t *m)
{
    const dan_link_t *l = &m->link;
    uint32_t next = dan_link_wait_us(l), t = UINT32_MAX;
    if (m->op != DAN_MASTER_OP_NONE) {
        switch (m->txn_phase) {
        case PH_LBT: {
            /* the backoff, and the line idle long enough; or the busy timeout */
            uint32_t busy = dan_link_due_in(l, m->busy_since_us + m->cfg.busy_timeout_us);
            t = max_u32(dan_link_due_in(l, m->wait_until_us),
                        dan_link_due_in(l, l->last_rx_us + lbt_us(m)));
            /* a partial frame holds the line until the gap drops it (next) */
            t = (busy < t || dan_decoder_busy(&l->dec)) ? busy : t;
            break;
        }
        case PH_WAIT:
            t = max_u32(dan_link_due_in(l, m->deadline_us),
                        dan_link_due_in(l, l->last_rx_us + dan_link_gap_us(l)));
            break;
        case PH_DONE: t = 0; break;
        default: break;
        }
    }
    return dan_link_wait_time(l, (t < next) ? t : next);
}
