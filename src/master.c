/* DAN master engine: transactions with listen-before-talk, echo/collision
 * handling and retries; discovery, configure and recovery sequencers. */
#include <string.h>

#include "dan/codes.h"
#include "dan/master.h"

enum { PH_IDLE = 0, PH_LBT, PH_TX, PH_WAIT, PH_DONE };

enum {
    ST_NONE = 0,
    ST_DISC_PROBE, /* discovery: probing types[idx] at bauds[bidx] */
    ST_CFG_SEND,   /* configure: CONFIGURE to peers[idx] */
    ST_CFG_VERIFY, /* configure: IDENTIFY peers[idx] at the target */
    ST_REC_FIND,   /* recovery: looking for peers[idx] at candidate bidx */
    ST_REC_BACK,   /* recovery: CONFIGURE(9600) to peers[idx] */
    ST_REC_VERIFY  /* recovery: IDENTIFY peers[idx] at 9600 */
};

static const uint32_t disc_bauds[DAN_DISCOVERY_NBAUDS] = {9600u, 115200u, 57600u, 38400u, 19200u};

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

static void on_frame(void *owner, const dan_frame_t *f, uint64_t now_us);

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
        m->types[i] = types[i];
        m->peers[i].first_code = types[i];
    }
    m->ntypes = ntypes;
    dan_link_init(&m->link, port, baud, on_frame, m, now_us);
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

static bool peer_supports(const dan_peer_t *p, uint32_t baud)
{
    return baud == DAN_BAUD_BASE ||
           (p->identity.baud_mask & DAN_BAUD_MASK_DEFINED & dan_mask_bit_of_baud(baud)) != 0u;
}

static bool port_supports(const dan_master_t *m, uint32_t baud)
{
    return m->link.port.max_baud == 0u || baud <= m->link.port.max_baud;
}

void dan_master_set_reply_check(dan_master_t *m, dan_reply_check_fn fn, void *user)
{
    m->reply_check = fn;
    m->reply_check_user = user;
}

uint32_t dan_master_best_baud(const dan_master_t *m)
{
    uint16_t mask = DAN_BAUD_MASK_DEFINED;
    size_t i;
    bool any = false;
    for (i = 0; i < m->ntypes; i++) {
        if (m->peers[i].present) {
            mask &= m->peers[i].identity.baud_mask;
            any = true;
        }
    }
    if (!any) {
        return DAN_BAUD_BASE;
    }
    while (mask != 0u) {
        uint32_t b = dan_baud_highest(mask);
        if (port_supports(m, b)) {
            return b;
        }
        mask &= (uint16_t)~dan_mask_bit_of_baud(b);
    }
    return DAN_BAUD_BASE;
}

/* ---- transactions ---- */

static uint32_t lbt_us(const dan_master_t *m)
{
    return m->cfg.lbt_chars * m->link.char_us;
}

/* Random backoff after a failed attempt: [0, 8 * 2^k) characters, k =
 * min(attempt, 4), on top of the listen-before-talk idle time. */
static void backoff(dan_master_t *m, uint64_t now_us)
{
    uint32_t k = (m->attempt < 4u) ? m->attempt : 4u;
    uint32_t slots = 8u << k;
    m->wait_until_us = now_us + (uint64_t)(next_rand(m) % slots) * m->link.char_us;
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

static void txn_start(dan_master_t *m, uint32_t code, const uint8_t *payload, size_t len,
                      uint8_t attempts, uint64_t now_us)
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
    if (m->wait_until_us < now_us) {
        m->wait_until_us = now_us;
    }
}

/* An attempt failed (timeout or collision): retry or give up. */
static void txn_attempt_failed(dan_master_t *m, int why, uint64_t now_us)
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

static void on_frame(void *owner, const dan_frame_t *f, uint64_t now_us)
{
    dan_master_t *m = (dan_master_t *)owner;
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
    if (f->code == m->req_code) {
        if (m->reply_check != NULL &&
            m->reply_check(m->reply_check_user, f->code, f->payload, f->len) != DAN_OK) {
            m->stats.bad_replies++;
            txn_attempt_failed(m, DAN_ERR_MALFORMED, now_us);
            return;
        }
        memcpy(m->resp, f->payload, f->len);
        m->resp_len = f->len;
        m->resp_code = f->code;
        txn_finish(m, DAN_OK);
        return;
    }
    if (f->code == DAN_CODE_ERROR &&
        dan_error_decode(&m->remote_error, f->payload, f->len) == DAN_OK &&
        m->remote_error.code == m->req_code) {
        m->stats.remote_errors++;
        m->resp_code = f->code;
        txn_finish(m, DAN_ERR_REMOTE); /* understood and refused: no retry */
        return;
    }
    m->stats.stray++;
}

/* Response deadline: the reply must start within the turnaround plus
 * resp_latency_us after our request left the wire. */
static uint64_t reply_start_deadline(const dan_master_t *m, uint64_t tx_end_us)
{
    return tx_end_us + (uint64_t)DAN_TURNAROUND_CHARS * m->link.char_us + m->cfg.resp_latency_us;
}

static void txn_poll(dan_master_t *m, uint64_t now_us)
{
    dan_link_state_t ls = dan_link_poll(&m->link, now_us);
    switch (m->txn_phase) {
    case PH_LBT:
        if (now_us < m->wait_until_us) {
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
        if (now_us < m->deadline_us) {
            break;
        }
        /* Past the start deadline: wait on while a reply is arriving, but
         * not longer than a whole maximal frame. */
        if (dan_link_idle_us(&m->link, now_us) < dan_link_gap_us(&m->link) &&
            now_us < m->deadline_us + (uint64_t)DAN_MAX_FRAME * m->link.char_us) {
            break;
        }
        m->stats.timeouts++;
        txn_attempt_failed(m, DAN_ERR_TIMEOUT, now_us);
        break;
    default: break;
    }
}

/* ---- sequencers ---- */

static void op_finish(dan_master_t *m, int result)
{
    m->result = result;
    m->op = DAN_MASTER_OP_NONE;
    m->step = ST_NONE;
    m->done = true;
}

static void switch_baud(dan_master_t *m, uint32_t baud, uint64_t now_us)
{
    if (m->link.baud != baud) {
        (void)dan_link_set_baud(&m->link, baud, now_us);
        m->wait_until_us = now_us + m->cfg.settle_us;
    }
}

static void probe(dan_master_t *m, uint32_t first, uint8_t attempts, uint64_t now_us)
{
    txn_start(m, DAN_TYPE_IDENTIFY(first), NULL, 0, attempts, now_us);
}

static void send_configure(dan_master_t *m, uint32_t first, uint32_t baud, uint64_t now_us)
{
    uint8_t p[8];
    dan_configure_t c;
    int n;
    c.type = DAN_CONFIGURE_BPS;
    c.baud = baud;
    n = dan_configure_encode(&c, p, sizeof p);
    txn_start(m, DAN_TYPE_CONFIGURE(first), p, (size_t)n, (uint8_t)(m->cfg.retries + 1u), now_us);
}

static bool reply_is_ack_ok(const dan_master_t *m)
{
    uint8_t ack;
    return m->txn_result == DAN_OK && dan_ack_decode(&ack, m->resp, m->resp_len) == DAN_OK &&
           ack == DAN_ACK_OK;
}

static int txn_error(const dan_master_t *m)
{
    uint8_t ack;
    if (m->txn_result != DAN_OK) {
        return m->txn_result;
    }
    if (dan_ack_decode(&ack, m->resp, m->resp_len) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    return (ack == DAN_ACK_OK) ? DAN_OK : DAN_ERR_NACK;
}

/* Candidate baud number bidx for finding peer p in recovery: its believed
 * baud first, then the discovery bauds. Returns 0 past the end. */
static uint32_t rec_baud(const dan_master_t *m, const dan_peer_t *p, size_t bidx)
{
    size_t i, n = 0;
    if (bidx == 0u) {
        return p->baud;
    }
    for (i = 0; i < DAN_DISCOVERY_NBAUDS; i++) {
        if (disc_bauds[i] == p->baud || !port_supports(m, disc_bauds[i])) {
            continue;
        }
        if (++n == bidx) {
            return disc_bauds[i];
        }
    }
    return 0;
}

static void start_recovery(dan_master_t *m, int why, uint64_t now_us);

/* Sequencer steps: each starts a transaction or finishes the operation
 * (returns true: wait for it), or moves on to another step or index
 * (returns false: seq_next() goes on). */

/* Counts the peers found so far. */
static size_t peers_found(const dan_master_t *m)
{
    size_t i, found = 0;
    for (i = 0; i < m->ntypes; i++) {
        found += m->peers[i].present ? 1u : 0u;
    }
    return found;
}

/* Discovery: IDENTIFY each missing type at the current discovery baud;
 * then the next baud the port supports, or the end. */
static bool step_disc_probe(dan_master_t *m, uint64_t now_us)
{
    size_t i, found;
    while (m->idx < m->ntypes && m->peers[m->idx].present) {
        m->idx++;
    }
    if (m->idx < m->ntypes) {
        switch_baud(m, disc_bauds[m->bidx], now_us);
        probe(m, m->types[m->idx], m->cfg.discovery_attempts, now_us);
        return true;
    }
    found = peers_found(m);
    do {
        m->bidx++;
    } while (m->bidx < DAN_DISCOVERY_NBAUDS && !port_supports(m, disc_bauds[m->bidx]));
    if (found == m->ntypes || !m->cfg.scan_all_bauds || m->bidx >= DAN_DISCOVERY_NBAUDS) {
        /* Leave the bus at the baud of the first peer found. */
        for (i = 0; i < m->ntypes; i++) {
            if (m->peers[i].present) {
                switch_baud(m, m->peers[i].baud, now_us);
                break;
            }
        }
        op_finish(m, found > 0u ? DAN_OK : DAN_ERR_NOTFOUND);
        return true;
    }
    m->idx = 0;
    return false;
}

/* Configure: CONFIGURE each present peer not at the target, at its baud;
 * then verify at the target. */
static bool step_cfg_send(dan_master_t *m, uint64_t now_us)
{
    while (m->idx < m->ntypes &&
           (!m->peers[m->idx].present || m->peers[m->idx].baud == m->target_baud)) {
        m->idx++;
    }
    if (m->idx < m->ntypes) {
        switch_baud(m, m->peers[m->idx].baud, now_us);
        send_configure(m, m->types[m->idx], m->target_baud, now_us);
        return true;
    }
    m->step = ST_CFG_VERIFY;
    m->idx = 0;
    switch_baud(m, m->target_baud, now_us);
    return false;
}

/* Verification (after configure, or after recovery): IDENTIFY each
 * present peer at the current baud. */
static bool step_verify(dan_master_t *m, uint64_t now_us)
{
    while (m->idx < m->ntypes && !m->peers[m->idx].present) {
        m->idx++;
    }
    if (m->idx < m->ntypes) {
        probe(m, m->types[m->idx], (uint8_t)(m->cfg.retries + 1u), now_us);
        return true;
    }
    op_finish(m, m->step == ST_CFG_VERIFY ? DAN_OK : m->result);
    return true;
}

/* Recovery: find each peer at its believed baud, then at each discovery
 * baud; a peer found nowhere is dropped. Then verify everyone at 9600. */
static bool step_rec_find(dan_master_t *m, uint64_t now_us)
{
    uint32_t b;
    while (m->idx < m->ntypes && !m->peers[m->idx].present) {
        m->idx++;
    }
    if (m->idx >= m->ntypes) {
        m->step = ST_REC_VERIFY;
        m->idx = 0;
        switch_baud(m, DAN_BAUD_BASE, now_us);
        return false;
    }
    b = rec_baud(m, &m->peers[m->idx], m->bidx);
    if (b == 0u) {
        m->peers[m->idx].present = false; /* lost */
        m->idx++;
        m->bidx = 0;
        return false;
    }
    switch_baud(m, b, now_us);
    probe(m, m->types[m->idx], m->cfg.discovery_attempts, now_us);
    return true;
}

/* Picks the next thing to do for the current operation. */
static void seq_next(dan_master_t *m, uint64_t now_us)
{
    bool waiting;
    do {
        switch (m->step) {
        case ST_DISC_PROBE: waiting = step_disc_probe(m, now_us); break;
        case ST_CFG_SEND: waiting = step_cfg_send(m, now_us); break;
        case ST_CFG_VERIFY:
        case ST_REC_VERIFY: waiting = step_verify(m, now_us); break;
        case ST_REC_FIND: waiting = step_rec_find(m, now_us); break;
        default:
            op_finish(m, DAN_ERR_ARG);
            waiting = true;
            break;
        }
    } while (!waiting);
}

/* A transaction of the current operation completed. */
static void seq_txn_done(dan_master_t *m, uint64_t now_us)
{
    dan_peer_t *p = (m->idx < m->ntypes) ? &m->peers[m->idx] : NULL;
    m->txn_phase = PH_IDLE;
    switch (m->step) {
    case ST_DISC_PROBE:
        if (m->txn_result == DAN_OK &&
            dan_identity_decode(&p->identity, m->resp, m->resp_len) == DAN_OK) {
            p->present = true;
            p->baud = m->link.baud;
        }
        m->idx++;
        break;
    case ST_CFG_SEND:
        if (m->txn_result == DAN_ERR_TIMEOUT) {
            /* No answer at the old baud: a device serving several types
             * moved them all with its first CONFIGURE. Verification at the
             * target decides. */
            p->baud = m->target_baud;
            m->idx++;
            break;
        }
        if (!reply_is_ack_ok(m)) {
            start_recovery(m, txn_error(m), now_us);
            break;
        }
        p->baud = m->target_baud; /* it switches once its ACK has left */
        m->idx++;
        break;
    case ST_CFG_VERIFY:
        if (m->txn_result != DAN_OK) {
            start_recovery(m, m->txn_result, now_us);
            break;
        }
        m->idx++;
        break;
    case ST_REC_FIND:
        if (m->txn_result == DAN_OK) {
            p->baud = m->link.baud;
            if (p->baud != DAN_BAUD_BASE) {
                m->step = ST_REC_BACK;
                send_configure(m, m->types[m->idx], DAN_BAUD_BASE, now_us);
                return;
            }
            m->idx++;
            m->bidx = 0;
        } else {
            m->bidx++;
        }
        break;
    case ST_REC_BACK:
        if (reply_is_ack_ok(m)) {
            p->baud = DAN_BAUD_BASE;
        } else {
            p->present = false; /* cannot be brought to a common baud */
        }
        m->step = ST_REC_FIND;
        m->idx++;
        m->bidx = 0;
        break;
    case ST_REC_VERIFY:
        if (m->txn_result != DAN_OK) {
            p->present = false;
        }
        m->idx++;
        break;
    default: break;
    }
    seq_next(m, now_us);
}

static void start_recovery(dan_master_t *m, int why, uint64_t now_us)
{
    m->stats.recoveries++;
    m->result = why; /* reported when recovery completes */
    m->step = ST_REC_FIND;
    m->idx = 0;
    m->bidx = 0;
    (void)now_us;
}

static int op_begin(dan_master_t *m, dan_master_op_t op, uint64_t now_us)
{
    if (m->op != DAN_MASTER_OP_NONE) {
        return DAN_ERR_BUSY;
    }
    m->op = op;
    m->done = false;
    m->result = DAN_OK;
    m->idx = 0;
    m->bidx = 0;
    (void)now_us;
    return DAN_OK;
}

int dan_master_request(dan_master_t *m, uint32_t code, const uint8_t *payload, size_t len,
                       uint64_t now_us)
{
    int r;
    if (len > DAN_MAX_PAYLOAD || (len > 0u && payload == NULL)) {
        return DAN_ERR_ARG;
    }
    r = op_begin(m, DAN_MASTER_OP_TXN, now_us);
    if (r != DAN_OK) {
        return r;
    }
    txn_start(m, code, payload, len, (uint8_t)(m->cfg.retries + 1u), now_us);
    return DAN_OK;
}

int dan_master_discover(dan_master_t *m, uint64_t now_us)
{
    size_t i;
    int r = op_begin(m, DAN_MASTER_OP_DISCOVER, now_us);
    if (r != DAN_OK) {
        return r;
    }
    for (i = 0; i < m->ntypes; i++) {
        m->peers[i].present = false;
    }
    m->step = ST_DISC_PROBE;
    seq_next(m, now_us);
    return DAN_OK;
}

int dan_master_configure(dan_master_t *m, uint32_t baud, uint64_t now_us)
{
    size_t i;
    bool any = false;
    int r;
    if (baud == 0u) {
        baud = dan_master_best_baud(m);
    }
    for (i = 0; i < m->ntypes; i++) {
        if (m->peers[i].present) {
            any = true;
            if (!peer_supports(&m->peers[i], baud)) {
                return DAN_ERR_UNSUPPORTED;
            }
        }
    }
    if (!any) {
        return DAN_ERR_NOTFOUND;
    }
    if (!port_supports(m, baud)) {
        return DAN_ERR_UNSUPPORTED;
    }
    r = op_begin(m, DAN_MASTER_OP_CONFIGURE, now_us);
    if (r != DAN_OK) {
        return r;
    }
    m->target_baud = baud;
    m->step = ST_CFG_SEND;
    seq_next(m, now_us);
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
            if (m->op == DAN_MASTER_OP_TXN) {
                m->txn_phase = PH_IDLE;
                op_finish(m, m->txn_result);
            } else {
                seq_txn_done(m, now_us);
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

static uint64_t max_u64(uint64_t a, uint64_t b)
{
    return (a > b) ? a : b;
}

uint64_t dan_master_next_us(const dan_master_t *m)
{
    uint64_t next = dan_link_next_us(&m->link), t = UINT64_MAX;
    if (m->op == DAN_MASTER_OP_NONE) {
        return next;
    }
    switch (m->txn_phase) {
    case PH_LBT:
        /* the backoff, and the line idle long enough; or the busy timeout */
        t = max_u64(m->wait_until_us, m->link.last_rx_us + lbt_us(m));
        if (m->busy_since_us + m->cfg.busy_timeout_us < t) {
            t = m->busy_since_us + m->cfg.busy_timeout_us;
        }
        break;
    case PH_WAIT:
        t = max_u64(m->deadline_us, m->link.last_rx_us + dan_link_gap_us(&m->link));
        break;
    case PH_DONE: t = 0; break;
    default: break;
    }
    return (t < next) ? t : next;
}
