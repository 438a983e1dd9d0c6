/* DAN master engine: negotiating a fast baud (docs/PROTOCOL.md section 6,
 * "Fast bauds"). For a candidate c: CONFIGURE(c) to every peer at its
 * baud, the peers that refused a fast baud before first (a v1-only peer
 * refuses before anyone moves); a refusal moves the peers that already
 * moved back and verifies them; all acknowledged: switch and verify at c
 * (master_seq.c's verification and recovery). */
#include "dan/codes.h"
#include "master_internal.h"

size_t dan_mst_fast_list(const dan_master_t *m, uint32_t *out, size_t skip, size_t cap)
{
    const uint32_t *list = (m->cfg.fast_bauds != NULL) ? m->cfg.fast_bauds : dan_fast_bauds;
    size_t i = (m->cfg.fast_bauds != NULL) ? m->cfg.nfast_bauds : DAN_NFAST_BAUDS;
    size_t k = 0;
    uint32_t last = UINT32_MAX;
    if (m->cfg.fast_max_baud == 0u) {
        return 0;
    }
    while (i-- > 0u && k < DAN_MASTER_MAX_FAST) { /* ascending list: from its end */
        uint32_t b = list[i];
        if (b <= m->cfg.fast_max_baud && !dan_baud_is_v1(b) && dan_mst_port_supports(m, b) &&
            b < last) {
            if (k >= skip && k - skip < cap) {
                out[k - skip] = b;
            }
            k++;
            last = b;
        }
    }
    return k;
}

uint32_t dan_mst_cand(const dan_master_t *m, size_t i)
{
    uint32_t b = 0;
    if (m->named_baud != 0u) {
        return m->named_baud;
    }
    (void)dan_mst_fast_list(m, &b, i, 1u);
    return b;
}

bool dan_mst_fast_candidate(dan_master_t *m)
{
    size_t i;
    for (i = 0; i < DAN_MASTER_MAX_TYPES; i++) {
        m->moved[i] = false;
    }
    if (m->cidx < m->ncand) {
        m->target_baud = dan_mst_cand(m, m->cidx);
        if (m->ntried < m->cidx + 1u) {
            m->ntried = (uint8_t)(m->cidx + 1u);
        }
        m->step = DAN_ST_FAST_SEND;
        m->idx = 0;
        m->pass = 0;
        return false;
    }
    if (m->cfg_auto) {
        dan_mst_start_v1_configure(m);
        return false;
    }
    dan_mst_op_finish(m, m->fast_error); /* the baud the caller named: refused */
    return true;
}

/* Asks peer i in this pass: present, not at the candidate, not moved,
 * and in pass 0 only the peers that refused a fast baud before. */
static bool to_ask(const dan_master_t *m, size_t i)
{
    const dan_peer_t *p = &m->peers[i];
    return p->present && !m->moved[i] && p->baud != m->target_baud &&
           p->fast_refused == (m->pass == 0u);
}

static bool step_send(dan_master_t *m, uint32_t now_us)
{
    for (; m->pass < 2u; m->pass++, m->idx = 0) {
        if (dan_mst_configure_next(m, to_ask, now_us)) {
            return true;
        }
    }
    /* Everyone acknowledged (or went quiet): switch and verify at c. */
    dan_mst_start_verify(m, now_us);
    return false;
}

/* Moving back: CONFIGURE(its old baud) to each moved peer at the
 * candidate, then IDENTIFY each at its old baud; then the next one. */
static bool step_back(dan_master_t *m, uint32_t now_us)
{
    while (m->idx < m->ntypes && !(m->moved[m->idx] && m->peers[m->idx].present)) {
        m->idx++;
    }
    if (m->idx < m->ntypes) {
        dan_mst_switch_baud(m, m->peers[m->idx].baud, now_us);
        if (m->step == DAN_ST_FAST_BACK) {
            dan_mst_send_configure(m, m->peers[m->idx].first_code, m->back_baud[m->idx], now_us);
        } else {
            dan_mst_probe(m, m->peers[m->idx].first_code, (uint8_t)(m->cfg.retries + 1u), now_us);
        }
        return true;
    }
    if (m->step == DAN_ST_FAST_BACK) {
        m->step = DAN_ST_FAST_BACK_CHECK;
        m->idx = 0;
        return false;
    }
    m->cidx++;
    return dan_mst_fast_candidate(m);
}

bool dan_mst_fast_step(dan_master_t *m, uint32_t now_us)
{
    return (m->step == DAN_ST_FAST_SEND) ? step_send(m, now_us) : step_back(m, now_us);
}

/* A peer refused the candidate: it and the peers not asked yet stay; the
 * ones that moved go back. */
static void refused(dan_master_t *m, dan_peer_t *p)
{
    size_t i;
    bool any = false;
    p->fast_refused = true;
    m->stats.fast_refusals++;
    m->fast_error = dan_mst_txn_error(m);
    for (i = 0; i < m->ntypes; i++) {
        any = any || m->moved[i];
    }
    m->idx = 0;
    if (any) {
        m->step = DAN_ST_FAST_BACK;
        return;
    }
    m->cidx++;
    (void)dan_mst_fast_candidate(m);
}

void dan_mst_fast_txn_done(dan_master_t *m, uint32_t now_us)
{
    dan_peer_t *p = &m->peers[m->idx];
    bool ok_or_quiet = m->txn_result == DAN_ERR_TIMEOUT || dan_mst_ack_ok(m);
    (void)now_us;
    switch (m->step) {
    case DAN_ST_FAST_SEND:
        if (!ok_or_quiet) {
            refused(m, p);
            return;
        }
        /* ACK-OK, or no answer at the old baud (a device of several types
         * moved with its first CONFIGURE): at the candidate now. */
        m->back_baud[m->idx] = p->baud;
        m->moved[m->idx] = true;
        p->baud = m->target_baud;
        m->idx++;
        return;
    case DAN_ST_FAST_BACK:
        if (!ok_or_quiet) {
            dan_mst_start_recovery(m, dan_mst_txn_error(m));
            return;
        }
        p->baud = m->back_baud[m->idx];
        m->stats.moved_back++;
        m->idx++;
        return;
    default: /* DAN_ST_FAST_BACK_CHECK */
        if (m->txn_result != DAN_OK) {
            dan_mst_start_recovery(m, m->txn_result);
            return;
        }
        m->idx++;
        return;
    }
}
