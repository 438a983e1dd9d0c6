/* DAN master engine: the discovery, configure and recovery sequencers
 * (docs/PROTOCOL.md section 6). Fast bauds: master_fast.c. */
#include <string.h>

#include "dan/codes.h"
#include "master_internal.h"

/* The mask bauds discovery scans after 9600 and the fast bauds. */
static const uint32_t mask_scan[DAN_DISCOVERY_NBAUDS - 1u] = {115200u, 57600u, 38400u, 19200u};

/* The longest scan: a peer's believed baud, the bauds configure tried,
 * 9600, the fast bauds, the mask bauds. */
#define SCAN_MAX (1u + DAN_MASTER_MAX_FAST + 1u + DAN_MASTER_MAX_FAST + DAN_DISCOVERY_NBAUDS)

static bool peer_supports(const dan_peer_t *p, uint32_t baud)
{
    return baud == DAN_BAUD_BASE ||
           (p->baud_mask & DAN_BAUD_MASK_DEFINED & dan_mask_bit_of_baud(baud)) != 0u;
}

uint32_t dan_master_best_baud(const dan_master_t *m)
{
    uint16_t mask = DAN_BAUD_MASK_DEFINED;
    size_t i;
    bool any = false;
    for (i = 0; i < m->ntypes; i++) {
        if (m->peers[i].present) {
            mask &= m->peers[i].baud_mask;
            any = true;
        }
    }
    if (!any) {
        return DAN_BAUD_BASE;
    }
    while (mask != 0u) {
        uint32_t b = dan_baud_highest(mask);
        if (dan_mst_port_supports(m, b)) {
            return b;
        }
        mask &= (uint16_t)~dan_mask_bit_of_baud(b);
    }
    return DAN_BAUD_BASE;
}

/* Appends b to list (n entries) unless it is there or the port cannot. */
static size_t scan_add(const dan_master_t *m, uint32_t *list, size_t n, uint32_t b)
{
    size_t i;
    if (b == 0u || n >= SCAN_MAX || !dan_mst_port_supports(m, b)) {
        return n;
    }
    for (i = 0; i < n; i++) {
        if (list[i] == b) {
            return n;
        }
    }
    list[n] = b;
    return n + 1u;
}

/* The bauds to look for a peer at: p's believed baud and the bauds this
 * configure tried (recovery only, p != NULL), then discovery's: 9600, the
 * fast bauds, the mask bauds, each from the highest. Returns the count. */
static size_t scan_list(const dan_master_t *m, const dan_peer_t *p, uint32_t list[SCAN_MAX])
{
    /* The fast list goes to list's tail, not a second array (stack): at
     * most 1 + ntried + 1 <= SCAN_MAX - DAN_MASTER_MAX_FAST entries come
     * before it, so list[n] is written below each fast entry still unread. */
    uint32_t *fast = list + (SCAN_MAX - DAN_MASTER_MAX_FAST);
    size_t n = 0, i, nf = dan_mst_fast_list(m, fast, 0, DAN_MASTER_MAX_FAST);
    if (p != NULL) {
        n = scan_add(m, list, n, p->baud);
        for (i = 0; i < m->ntried; i++) { /* the candidates tried: dan_mst_cand(m, i) */
            n = scan_add(m, list, n, m->named_baud != 0u ? m->named_baud : fast[i]);
        }
    }
    n = scan_add(m, list, n, DAN_BAUD_BASE);
    for (i = 0; i < nf; i++) {
        n = scan_add(m, list, n, fast[i]);
    }
    for (i = 0; i < DAN_DISCOVERY_NBAUDS - 1u; i++) {
        n = scan_add(m, list, n, mask_scan[i]);
    }
    return n;
}

/* Scan baud number i (0 past the end). */
static uint32_t scan_baud(const dan_master_t *m, const dan_peer_t *p, size_t i)
{
    uint32_t list[SCAN_MAX];
    size_t n = scan_list(m, p, list);
    return (i < n) ? list[i] : 0u;
}

void dan_mst_switch_baud(dan_master_t *m, uint32_t baud, uint32_t now_us)
{
    if (m->link.baud != baud) {
        (void)dan_link_set_baud(&m->link, baud, now_us);
        m->wait_until_us = now_us + m->cfg.settle_us;
    }
}

void dan_mst_probe(dan_master_t *m, uint32_t first, uint8_t attempts, uint32_t now_us)
{
    dan_mst_txn_start(m, DAN_TYPE_IDENTIFY(first), NULL, 0, attempts, now_us);
}

void dan_mst_send_configure(dan_master_t *m, uint32_t first, uint32_t baud, uint32_t now_us)
{
    /* DAN-CONFIGURE-PAYLOAD-V1 with type BPS: the type byte, the baud as a
     * uvarint (what dan_configure_encode writes, without its struct and
     * writer on the deepest stack path) */
    uint8_t p[1u + DAN_UVARINT_MAX_BYTES];
    p[0] = DAN_CONFIGURE_BPS;
    dan_mst_txn_start(m, DAN_TYPE_CONFIGURE(first), p,
                      1u + (size_t)dan_uvarint_encode(baud, p + 1, DAN_UVARINT_MAX_BYTES),
                      (uint8_t)(m->cfg.retries + 1u), now_us);
}

bool dan_mst_ack_ok(const dan_master_t *m)
{
    uint8_t ack;
    return m->txn_result == DAN_OK && dan_ack_decode(&ack, m->resp, m->resp_len) == DAN_OK &&
           ack == DAN_ACK_OK;
}

int dan_mst_txn_error(const dan_master_t *m)
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

void dan_mst_start_recovery(dan_master_t *m, int why)
{
    m->stats.recoveries++;
    m->result = why; /* reported when recovery completes */
    m->step = DAN_ST_REC_FIND;
    m->idx = 0;
    m->bidx = 0;
}

void dan_mst_start_v1_configure(dan_master_t *m)
{
    m->cidx = m->ncand; /* no fast candidate any more */
    m->target_baud = dan_master_best_baud(m);
    m->step = DAN_ST_CFG_SEND;
    m->idx = 0;
}

/* Sequencer steps: each starts a transaction or finishes the operation
 * (returns true: wait for it), or moves on to another step or index
 * (returns false: dan_mst_seq_next() goes on). */

/* Counts the peers found so far. */
static size_t peers_found(const dan_master_t *m)
{
    size_t i, found = 0;
    for (i = 0; i < m->ntypes; i++) {
        found += m->peers[i].present ? 1u : 0u;
    }
    return found;
}

/* Discovery: IDENTIFY each missing type at the current scan baud; then
 * the next scan baud, or the end. */
static bool step_disc_probe(dan_master_t *m, uint32_t now_us)
{
    size_t i, found;
    while (m->idx < m->ntypes && m->peers[m->idx].present) {
        m->idx++;
    }
    if (m->idx < m->ntypes) {
        dan_mst_switch_baud(m, scan_baud(m, NULL, m->bidx), now_us);
        dan_mst_probe(m, m->peers[m->idx].first_code, m->cfg.discovery_attempts, now_us);
        return true;
    }
    found = peers_found(m);
    m->bidx++;
    if (found == m->ntypes || !m->cfg.scan_all_bauds || scan_baud(m, NULL, m->bidx) == 0u) {
        /* Leave the bus at the baud of the first peer found. */
        for (i = 0; i < m->ntypes; i++) {
            if (m->peers[i].present) {
                dan_mst_switch_baud(m, m->peers[i].baud, now_us);
                break;
            }
        }
        dan_mst_op_finish(m, found > 0u ? DAN_OK : DAN_ERR_NOTFOUND);
        return true;
    }
    m->idx = 0;
    return false;
}

bool dan_mst_configure_next(dan_master_t *m, bool (*ask)(const dan_master_t *m, size_t i),
                            uint32_t now_us)
{
    while (m->idx < m->ntypes && !ask(m, m->idx)) {
        m->idx++;
    }
    if (m->idx >= m->ntypes) {
        return false;
    }
    dan_mst_switch_baud(m, m->peers[m->idx].baud, now_us);
    dan_mst_send_configure(m, m->peers[m->idx].first_code, m->target_baud, now_us);
    return true;
}

void dan_mst_start_verify(dan_master_t *m, uint32_t now_us)
{
    m->step = DAN_ST_CFG_VERIFY;
    m->idx = 0;
    dan_mst_switch_baud(m, m->target_baud, now_us);
}

/* Configure asks every present peer not at the target. */
static bool v1_ask(const dan_master_t *m, size_t i)
{
    return m->peers[i].present && m->peers[i].baud != m->target_baud;
}

/* Configure: CONFIGURE each present peer not at the target, at its baud;
 * then verify at the target. */
static bool step_cfg_send(dan_master_t *m, uint32_t now_us)
{
    if (dan_mst_configure_next(m, v1_ask, now_us)) {
        return true;
    }
    dan_mst_start_verify(m, now_us);
    return false;
}

/* Verification (after configure, or after recovery): IDENTIFY each
 * present peer at the current baud. After a recovery in auto mode with
 * fast candidates left, the mask baud is next. */
static bool step_verify(dan_master_t *m, uint32_t now_us)
{
    while (m->idx < m->ntypes && !m->peers[m->idx].present) {
        m->idx++;
    }
    if (m->idx < m->ntypes) {
        dan_mst_probe(m, m->peers[m->idx].first_code, (uint8_t)(m->cfg.retries + 1u), now_us);
        return true;
    }
    if (m->step == DAN_ST_REC_VERIFY && m->cfg_auto && m->cidx < m->ncand && peers_found(m) > 0u) {
        dan_mst_start_v1_configure(m);
        return false;
    }
    dan_mst_op_finish(m, m->step == DAN_ST_CFG_VERIFY ? DAN_OK : m->result);
    return true;
}

/* Recovery: find each peer at its believed baud, then at each baud
 * configure tried, then at the discovery bauds; a peer found nowhere is
 * dropped. Then verify everyone at 9600. */
static bool step_rec_find(dan_master_t *m, uint32_t now_us)
{
    uint32_t b;
    while (m->idx < m->ntypes && !m->peers[m->idx].present) {
        m->idx++;
    }
    if (m->idx >= m->ntypes) {
        m->step = DAN_ST_REC_VERIFY;
        m->idx = 0;
        dan_mst_switch_baud(m, DAN_BAUD_BASE, now_us);
        return false;
    }
    b = scan_baud(m, &m->peers[m->idx], m->bidx);
    if (b == 0u) {
        m->peers[m->idx].present = false; /* lost */
        m->idx++;
        m->bidx = 0;
        return false;
    }
    dan_mst_switch_baud(m, b, now_us);
    dan_mst_probe(m, m->peers[m->idx].first_code, m->cfg.discovery_attempts, now_us);
    return true;
}

void dan_mst_seq_next(dan_master_t *m, uint32_t now_us)
{
    bool waiting;
    do {
        switch (m->step) {
        case DAN_ST_DISC_PROBE: waiting = step_disc_probe(m, now_us); break;
        case DAN_ST_CFG_SEND: waiting = step_cfg_send(m, now_us); break;
        case DAN_ST_CFG_VERIFY:
        case DAN_ST_REC_VERIFY: waiting = step_verify(m, now_us); break;
        case DAN_ST_REC_FIND: waiting = step_rec_find(m, now_us); break;
        case DAN_ST_FAST_SEND:
        case DAN_ST_FAST_BACK:
        case DAN_ST_FAST_BACK_CHECK: waiting = dan_mst_fast_step(m, now_us); break;
        default:
            dan_mst_op_finish(m, DAN_ERR_ARG);
            waiting = true;
            break;
        }
    } while (!waiting);
}

/* Configure's transactions: CONFIGURE to the target, IDENTIFY there. */
static void cfg_txn_done(dan_master_t *m, dan_peer_t *p)
{
    if (m->step == DAN_ST_CFG_VERIFY) {
        if (m->txn_result != DAN_OK) {
            if (!dan_baud_is_v1(m->target_baud)) {
                p->fast_refused = true; /* acknowledged, then not there */
            }
            dan_mst_start_recovery(m, m->txn_result);
            return;
        }
        m->idx++;
        return;
    }
    if (m->txn_result != DAN_ERR_TIMEOUT && !dan_mst_ack_ok(m)) {
        dan_mst_start_recovery(m, dan_mst_txn_error(m));
        return;
    }
    /* ACK-OK: it switches once its ACK has left. No answer at the old
     * baud: a device serving several types moved them all with its first
     * CONFIGURE; verification at the target decides. */
    p->baud = m->target_baud;
    m->idx++;
}

/* Recovery's transactions: IDENTIFY at a scan baud, CONFIGURE(9600),
 * IDENTIFY at 9600. */
static void rec_txn_done(dan_master_t *m, dan_peer_t *p, uint32_t now_us)
{
    switch (m->step) {
    case DAN_ST_REC_FIND:
        if (m->txn_result != DAN_OK) {
            m->bidx++;
            return;
        }
        p->baud = m->link.baud;
        if (p->baud != DAN_BAUD_BASE) {
            m->step = DAN_ST_REC_BACK;
            dan_mst_send_configure(m, m->peers[m->idx].first_code, DAN_BAUD_BASE, now_us);
            return;
        }
        m->idx++;
        m->bidx = 0;
        return;
    case DAN_ST_REC_BACK:
        if (dan_mst_ack_ok(m)) {
            p->baud = DAN_BAUD_BASE;
        } else {
            p->present = false; /* cannot be brought to a common baud */
        }
        m->step = DAN_ST_REC_FIND;
        m->idx++;
        m->bidx = 0;
        return;
    default: /* DAN_ST_REC_VERIFY */
        if (m->txn_result != DAN_OK) {
            p->present = false;
        }
        m->idx++;
        return;
    }
}

/* Takes an IDENTIFY reply: the peer's baud mask, and its whole identity
 * if the caller keeps them. False if it does not decode. */
static bool probe_accept(dan_master_t *m, dan_peer_t *p)
{
    size_t i = (size_t)(p - m->peers);
    if (dan_identity_baud_mask(m->resp, m->resp_len, &p->baud_mask) != DAN_OK) {
        return false;
    }
    if (i < m->nids && m->id_decode != NULL) {
        (void)m->id_decode(&m->ids[i], m->resp, m->resp_len); /* accepted above */
    }
    return true;
}

bool dan_mst_seq_txn_done(dan_master_t *m, uint32_t now_us)
{
    dan_peer_t *p = (m->idx < m->ntypes) ? &m->peers[m->idx] : NULL;
    switch (m->step) {
    case DAN_ST_DISC_PROBE:
        if (m->txn_result == DAN_OK && probe_accept(m, p)) {
            p->present = true;
            p->baud = m->link.baud;
        }
        m->idx++;
        break;
    case DAN_ST_CFG_SEND:
    case DAN_ST_CFG_VERIFY: cfg_txn_done(m, p); break;
    case DAN_ST_REC_FIND:
    case DAN_ST_REC_BACK:
    case DAN_ST_REC_VERIFY:
        rec_txn_done(m, p, now_us);
        if (m->step == DAN_ST_REC_BACK) {
            return false; /* its CONFIGURE is under way */
        }
        break;
    default: dan_mst_fast_txn_done(m, now_us); break;
    }
    return m->op != DAN_MASTER_OP_NONE; /* not finished by the step */
}

int dan_master_discover(dan_master_t *m, uint64_t now64)
{
    size_t i;
    uint32_t now_us = (uint32_t)now64;
    int r = dan_mst_op_begin(m, DAN_MASTER_OP_DISCOVER, now64);
    if (r != DAN_OK) {
        return r;
    }
    for (i = 0; i < m->ntypes; i++) {
        m->peers[i].present = false;
    }
    m->ntried = 0;
    m->step = DAN_ST_DISC_PROBE;
    dan_mst_seq_next(m, now_us);
    return DAN_OK;
}

/* Checks a configure request; DAN_OK or why it cannot start. */
static int cfg_check(const dan_master_t *m, uint32_t baud)
{
    size_t i;
    bool any = false;
    for (i = 0; i < m->ntypes; i++) {
        if (m->peers[i].present) {
            any = true;
            if (baud != 0u && dan_baud_is_v1(baud) && !peer_supports(&m->peers[i], baud)) {
                return DAN_ERR_UNSUPPORTED;
            }
        }
    }
    if (!any) {
        return DAN_ERR_NOTFOUND;
    }
    return (baud == 0u || dan_mst_port_supports(m, baud)) ? DAN_OK : DAN_ERR_UNSUPPORTED;
}

int dan_master_configure(dan_master_t *m, uint32_t baud, uint64_t now64)
{
    uint32_t now_us = (uint32_t)now64;
    int r = cfg_check(m, baud);
    if (r != DAN_OK) {
        return r;
    }
    r = dan_mst_op_begin(m, DAN_MASTER_OP_CONFIGURE, now64);
    if (r != DAN_OK) {
        return r;
    }
    memset(m->moved, 0, sizeof m->moved);
    m->cfg_auto = (baud == 0u);
    m->ncand = 0;
    m->cidx = 0;
    m->ntried = 0;
    m->named_baud = 0;
    m->fast_error = DAN_OK;
    if (baud == 0u) {
        m->ncand = (uint8_t)dan_mst_fast_list(m, NULL, 0, 0);
    } else if (!dan_baud_is_v1(baud)) {
        m->named_baud = baud; /* one candidate, named by the caller */
        m->ncand = 1;
    }
    if (m->ncand == 0u) {
        dan_mst_start_v1_configure(m);
        if (baud != 0u) {
            m->target_baud = baud;
        }
    } else {
        (void)dan_mst_fast_candidate(m);
    }
    dan_mst_seq_next(m, now_us);
    return DAN_OK;
}
