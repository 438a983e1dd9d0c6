/* DAN master engine: the discovery, configure and recovery sequencers and
 * the negotiation of fast bauds (docs/PROTOCOL.md section 6).
 *
 * Every step walks the peers from idx on: the first one its row of
 * step_walk[] picks gets one request (IDENTIFY or CONFIGURE) at the baud
 * the row names; its reply is taken by seq_took(); when no peer is left,
 * step_end() moves on. Fast bauds: for a candidate c, CONFIGURE(c) to
 * every peer at its baud, the peers that refused a fast baud before first
 * (a v1-only peer refuses before anyone moves); a refusal moves the peers
 * that already moved back and checks them; all acknowledged: switch and
 * verify at c (then recovery, as for a v1 configure). */
#include "dan/codes.h"
#include "master_internal.h"

/* The mask bauds discovery scans after 9600 and the fast bauds. */
static const uint32_t mask_scan[DAN_DISCOVERY_NBAUDS - 1u] = {115200u, 57600u, 38400u, 19200u};

/* Which peers a step asks, where, and what. */
#define W_PRESENT 0x01u /* present peers (else the missing ones) */
#define W_AWAY    0x02u /* not at the target baud */
#define W_MOVED   0x04u /* moved to the fast candidate */
#define W_STAYED  0x08u /* not moved, and in this pass's group (refused before: pass 0) */
#define W_SCAN    0x10u /* at scan baud bidx (else at the peer's baud) */
#define W_HERE    0x20u /* at the current baud (no switch) */
#define W_CONF    0x40u /* CONFIGURE (else IDENTIFY) */
#define W_RETRY   0x80u /* IDENTIFY with retries + 1 attempts (else discovery_attempts) */

static const uint8_t step_walk[] = {
    [DAN_ST_DISC_PROBE] = W_SCAN,
    [DAN_ST_CFG_SEND] = W_PRESENT | W_AWAY | W_CONF,
    [DAN_ST_CFG_VERIFY] = W_PRESENT | W_HERE | W_RETRY,
    [DAN_ST_REC_FIND] = W_PRESENT | W_SCAN,
    [DAN_ST_REC_BACK] = W_PRESENT | W_CONF, /* CONFIGURE(9600) */
    [DAN_ST_REC_VERIFY] = W_PRESENT | W_HERE | W_RETRY,
    [DAN_ST_FAST_SEND] = W_PRESENT | W_AWAY | W_STAYED | W_CONF,
    [DAN_ST_FAST_BACK] = W_PRESENT | W_MOVED | W_CONF, /* CONFIGURE(its old baud) */
    [DAN_ST_FAST_BACK_CHECK] = W_PRESENT | W_MOVED | W_RETRY,
};

/* ---- bauds ---- */

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
    while (any && mask != 0u) {
        uint32_t b = dan_baud_highest(mask);
        if (dan_mst_port_supports(m, b)) {
            return b;
        }
        mask &= (uint16_t)~dan_mask_bit_of_baud(b);
    }
    return DAN_BAUD_BASE;
}

/* Fast baud k this master offers (cfg.fast_*, the port's maximum), highest
 * first, without the v1 bauds or repeats; 0 past the end. Computed again
 * when needed rather than kept (RAM). */
static uint32_t fast_baud(const dan_master_t *m, size_t k)
{
    const uint32_t *list = (m->cfg.fast_bauds != NULL) ? m->cfg.fast_bauds : dan_fast_bauds;
    size_t i = (m->cfg.fast_bauds != NULL) ? m->cfg.nfast_bauds : DAN_NFAST_BAUDS;
    size_t n = 0;
    uint32_t last = UINT32_MAX;
    if (m->cfg.fast_max_baud == 0u) {
        return 0;
    }
    while (i-- > 0u && n < DAN_MASTER_MAX_FAST) { /* ascending list: from its end */
        uint32_t b = list[i];
        if (b <= m->cfg.fast_max_baud && !dan_baud_is_v1(b) && dan_mst_port_supports(m, b) &&
            b < last) {
            if (n++ == k) {
                return b;
            }
            last = b;
        }
    }
    return 0;
}

/* Configure's candidate i: the baud the caller named, or fast baud i. */
static uint32_t cand(const dan_master_t *m, size_t i)
{
    return (m->named_baud != 0u) ? m->named_baud : fast_baud(m, i);
}

/* Entry k of the scan before repeats are dropped: p's believed baud and the
 * candidates this configure tried (recovery only, p != NULL), then
 * discovery's: 9600, the fast bauds, the mask bauds, each from the highest.
 * UINT32_MAX past the end. */
static uint32_t scan_entry(const dan_master_t *m, const dan_peer_t *p, size_t k)
{
    size_t nf = 0;
    if (p != NULL) {
        if (k-- == 0u) {
            return p->baud;
        }
        if (k < m->ntried) {
            return cand(m, k);
        }
        k -= m->ntried;
    }
    if (k-- == 0u) {
        return DAN_BAUD_BASE;
    }
    while (fast_baud(m, nf) != 0u) {
        nf++;
    }
    if (k < nf) {
        return fast_baud(m, k);
    }
    k -= nf;
    return (k < DAN_DISCOVERY_NBAUDS - 1u) ? mask_scan[k] : UINT32_MAX;
}

/* Scan baud number i (0 past the end): the entries the port can do, each
 * once. Found again from the start each time (no list on the stack). */
static uint32_t scan_baud(const dan_master_t *m, const dan_peer_t *p, size_t i)
{
    size_t k, j;
    for (k = 0;; k++) {
        uint32_t b = scan_entry(m, p, k);
        if (b == UINT32_MAX) {
            return 0;
        }
        if (b == 0u || !dan_mst_port_supports(m, b)) {
            continue;
        }
        for (j = 0; j < k && scan_entry(m, p, j) != b; j++) {
        }
        if (j == k && i-- == 0u) {
            return b;
        }
    }
}

static void switch_baud(dan_master_t *m, uint32_t baud, uint32_t now_us)
{
    if (m->link.baud != baud) {
        (void)dan_link_set_baud(&m->link, baud, now_us);
        m->wait_until_us = now_us + m->cfg.settle_us;
    }
}

/* ---- steps ---- */

static size_t peers_found(const dan_master_t *m)
{
    size_t i, found = 0;
    for (i = 0; i < m->ntypes; i++) {
        found += m->peers[i].present ? 1u : 0u;
    }
    return found;
}

static void start_step(dan_master_t *m, uint8_t step)
{
    m->step = step;
    m->idx = 0;
}

static void start_recovery(dan_master_t *m, int why)
{
    m->stats.recoveries++;
    m->result = why; /* reported when recovery completes */
    start_step(m, DAN_ST_REC_FIND);
    m->bidx = 0;
}

/* Configure at the best mask baud of the peers left (the v1 sequence). */
static void start_v1_configure(dan_master_t *m)
{
    m->cidx = m->ncand; /* no fast candidate any more */
    m->target_baud = dan_master_best_baud(m);
    start_step(m, DAN_ST_CFG_SEND);
}

/* Switches to the target and verifies every peer there. */
static void start_verify(dan_master_t *m, uint32_t now_us)
{
    start_step(m, DAN_ST_CFG_VERIFY);
    switch_baud(m, m->target_baud, now_us);
}

/* Starts candidate cidx, or the v1 fallback (auto), or finishes with the
 * refusal (a baud the caller named). */
static void fast_candidate(dan_master_t *m)
{
    m->moved = 0;
    if (m->cidx < m->ncand) {
        m->target_baud = cand(m, m->cidx);
        if (m->ntried <= m->cidx) {
            m->ntried = (uint8_t)(m->cidx + 1u);
        }
        start_step(m, DAN_ST_FAST_SEND);
        m->pass = 0;
    } else if (m->cfg_auto) {
        start_v1_configure(m);
    } else {
        dan_mst_op_finish(m, m->fast_error); /* the baud the caller named: refused */
    }
}

/* Sends the step's request to the next peer it picks: false if none is left. */
static bool walk(dan_master_t *m, uint32_t now_us)
{
    uint8_t w = step_walk[m->step];
    for (; m->idx < m->ntypes; m->idx++) {
        dan_peer_t *p = &m->peers[m->idx];
        bool moved = (((unsigned)m->moved >> m->idx) & 1u) != 0u;
        uint32_t baud = p->baud, arg = m->target_baud;
        if (p->present != ((w & W_PRESENT) != 0u) || ((w & W_AWAY) && p->baud == arg) ||
            ((w & W_MOVED) && !moved) ||
            ((w & W_STAYED) && (moved || p->fast_refused != (m->pass == 0u)))) {
            continue;
        }
        if (w & W_SCAN) {
            baud = scan_baud(m, (m->step == DAN_ST_REC_FIND) ? p : NULL, m->bidx);
            if (baud == 0u) {
                p->present = false; /* recovery: found nowhere, lost */
                m->bidx = 0;
                continue;
            }
        }
        if (!(w & W_HERE)) {
            switch_baud(m, baud, now_us);
        }
        if (w & W_CONF) {
            /* DAN-CONFIGURE-PAYLOAD-V1 with type BPS: the type byte, the
             * baud as a uvarint (what dan_configure_encode writes) */
            uint8_t pl[1u + DAN_UVARINT_MAX_BYTES];
            arg = (m->step == DAN_ST_REC_BACK)    ? DAN_BAUD_BASE
                  : (m->step == DAN_ST_FAST_BACK) ? m->back_baud[m->idx]
                                                  : arg;
            pl[0] = DAN_CONFIGURE_BPS;
            dan_mst_txn_start(m, DAN_TYPE_CONFIGURE(p->first_code), pl,
                              1u + dan_uvarint_put(arg, pl + 1), (uint8_t)(m->cfg.retries + 1u),
                              now_us);
        } else {
            dan_mst_txn_start(
                m, DAN_TYPE_IDENTIFY(p->first_code), NULL, 0,
                (w & W_RETRY) ? (uint8_t)(m->cfg.retries + 1u) : m->cfg.discovery_attempts, now_us);
        }
        return true;
    }
    return false;
}

/* No peer left for the step: the next step, or the end. */
static void step_end(dan_master_t *m, uint32_t now_us)
{
    size_t i, found = peers_found(m);
    switch (m->step) {
    case DAN_ST_DISC_PROBE:
        m->idx = 0;
        m->bidx++;
        if (found < m->ntypes && m->cfg.scan_all_bauds && scan_baud(m, NULL, m->bidx) != 0u) {
            return;
        }
        for (i = 0; i < m->ntypes; i++) { /* leave the bus at the first peer's baud */
            if (m->peers[i].present) {
                switch_baud(m, m->peers[i].baud, now_us);
                break;
            }
        }
        dan_mst_op_finish(m, found > 0u ? DAN_OK : DAN_ERR_NOTFOUND);
        return;
    case DAN_ST_FAST_SEND:
    case DAN_ST_CFG_SEND:
        if (m->step == DAN_ST_FAST_SEND && m->pass++ == 0u) {
            m->idx = 0; /* the second pass */
            return;
        }
        start_verify(m, now_us); /* everyone acknowledged (or went quiet) */
        return;
    case DAN_ST_REC_FIND:
        start_step(m, DAN_ST_REC_VERIFY);
        switch_baud(m, DAN_BAUD_BASE, now_us);
        return;
    case DAN_ST_REC_VERIFY:
        if (m->cfg_auto && m->cidx < m->ncand && found > 0u) {
            start_v1_configure(m); /* after a failed fast candidate: the mask baud */
            return;
        }
        dan_mst_op_finish(m, m->result);
        return;
    case DAN_ST_FAST_BACK: start_step(m, DAN_ST_FAST_BACK_CHECK); return;
    case DAN_ST_FAST_BACK_CHECK:
        m->cidx++;
        fast_candidate(m);
        return;
    default: dan_mst_op_finish(m, m->step == DAN_ST_CFG_VERIFY ? DAN_OK : DAN_ERR_ARG); return;
    }
}

void dan_mst_seq_next(dan_master_t *m, uint32_t now_us)
{
    while (m->op != DAN_MASTER_OP_NONE && !walk(m, now_us)) {
        step_end(m, now_us);
    }
}

/* ---- replies ---- */

/* A CONFIGURE's outcome: DAN_OK for ACK-OK, DAN_ERR_NACK for ACK-FAIL,
 * DAN_ERR_MALFORMED for anything else, or the transaction's error. */
static int ack_result(const dan_master_t *m)
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

/* A fast candidate refused: this peer and the ones not asked yet stay; the
 * ones that moved go back. */
static void refused(dan_master_t *m, dan_peer_t *p, int why)
{
    p->fast_refused = true;
    m->stats.fast_refusals++;
    m->fast_error = why;
    m->idx = 0;
    if (m->moved != 0u) {
        m->step = DAN_ST_FAST_BACK;
        return;
    }
    m->cidx++;
    fast_candidate(m);
}

/* The reply (or failure) of the step's request to peers[idx]. A
 * CONFIGURE is good when acknowledged, or unanswered at the old baud (a
 * device serving several types moved them all with its first CONFIGURE,
 * or its ACK was lost; verification decides: recovery's too). */
void dan_mst_seq_txn_done(dan_master_t *m, uint32_t now_us)
{
    dan_peer_t *p = &m->peers[m->idx];
    uint8_t step = m->step;
    bool conf = (step_walk[step] & W_CONF) != 0u;
    int e = conf ? ack_result(m) : m->txn_result;
    bool good = e == DAN_OK || (conf && e == DAN_ERR_TIMEOUT);
    switch (step) {
    case DAN_ST_DISC_PROBE:
        if (good && probe_accept(m, p)) {
            p->present = true;
            p->baud = m->link.baud;
        }
        break;
    case DAN_ST_REC_FIND:
        if (!good) {
            m->bidx++;
            break;
        }
        p->baud = m->link.baud;
        if (p->baud != DAN_BAUD_BASE) {
            m->step = DAN_ST_REC_BACK; /* CONFIGURE(9600) to it, here */
            break;
        }
        m->bidx = 0;
        m->idx++;
        break;
    case DAN_ST_REC_BACK:
        p->baud = DAN_BAUD_BASE;
        p->present = good; /* refused 9600: no common baud (unanswered: verify) */
        m->step = DAN_ST_REC_FIND;
        m->bidx = 0;
        m->idx++;
        break;
    case DAN_ST_REC_VERIFY: p->present = good; break;
    default: /* configure's steps and the fast ones */
        if (good) {
            break;
        }
        if (step == DAN_ST_FAST_SEND) {
            refused(m, p, e);
        } else {
            if (step == DAN_ST_CFG_VERIFY && !dan_baud_is_v1(m->target_baud)) {
                p->fast_refused = true; /* acknowledged, then not there */
            }
            start_recovery(m, e);
        }
        dan_mst_seq_next(m, now_us);
        return;
    }
    if (good && step == DAN_ST_FAST_SEND) { /* at the candidate now */
        m->back_baud[m->idx] = p->baud;
        m->moved |= (uint8_t)(1u << m->idx);
    }
    if (good && (step == DAN_ST_FAST_SEND || step == DAN_ST_CFG_SEND)) {
        p->baud = m->target_baud;
    }
    if (step == DAN_ST_FAST_BACK) {
        p->baud = m->back_baud[m->idx];
        m->stats.moved_back++;
    }
    if (step < DAN_ST_REC_FIND || step > DAN_ST_REC_BACK) {
        m->idx++;
    }
    dan_mst_seq_next(m, now_us);
}

/* ---- operations ---- */

int dan_master_discover(dan_master_t *m, uint64_t now64)
{
    size_t i;
    int r = dan_mst_op_begin(m, DAN_MASTER_OP_DISCOVER, now64);
    if (r != DAN_OK) {
        return r;
    }
    for (i = 0; i < m->ntypes; i++) {
        m->peers[i].present = false;
    }
    m->ntried = 0;
    start_step(m, DAN_ST_DISC_PROBE);
    m->bidx = 0;
    dan_mst_seq_next(m, (uint32_t)now64);
    return DAN_OK;
}

/* Checks a configure request; DAN_OK or why it cannot start. */
static int cfg_check(const dan_master_t *m, uint32_t baud)
{
    size_t i;
    bool any = false;
    for (i = 0; i < m->ntypes; i++) {
        const dan_peer_t *p = &m->peers[i];
        if (p->present) {
            any = true;
            if (baud != DAN_BAUD_BASE && dan_baud_is_v1(baud) &&
                (p->baud_mask & dan_mask_bit_of_baud(baud)) == 0u) {
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
    int r = cfg_check(m, baud);
    if (r == DAN_OK) {
        r = dan_mst_op_begin(m, DAN_MASTER_OP_CONFIGURE, now64);
    }
    if (r != DAN_OK) {
        return r;
    }
    m->moved = 0;
    m->cfg_auto = (baud == 0u);
    m->ncand = 0;
    m->cidx = 0;
    m->ntried = 0;
    m->named_baud = 0;
    m->fast_error = DAN_OK;
    if (baud == 0u) {
        while (fast_baud(m, m->ncand) != 0u) {
            m->ncand++;
        }
    } else if (!dan_baud_is_v1(baud)) {
        m->named_baud = baud; /* one candidate, named by the caller */
        m->ncand = 1;
    }
    if (m->ncand == 0u) {
        start_v1_configure(m);
        if (baud != 0u) {
            m->target_baud = baud;
        }
    } else {
        fast_candidate(m);
    }
    dan_mst_seq_next(m, (uint32_t)now64);
    return DAN_OK;
}
