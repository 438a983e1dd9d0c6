/* DAN peripheral engine: IDENTIFY/CONFIGURE, dispatch, error frames,
 * turnaround and reply window, baud switch after the ACK. */
#include <string.h>

#include "dan/codes.h"
#include "dan/peripheral.h"

void dan_periph_config_default(dan_periph_config_t *c)
{
    memset(c, 0, sizeof *c);
    c->turnaround_chars = DAN_TURNAROUND_CHARS;
    c->reply_window_us = DAN_RESP_LATENCY_US;
}

static void on_frame(void *owner, const dan_frame_t *f, uint64_t now_us);

int dan_periph_init(dan_periph_t *p, const dan_port_t *port, const dan_ptype_t *types,
                    size_t ntypes, const dan_periph_config_t *cfg, uint32_t baud, uint64_t now_us)
{
    if (p == NULL || port == NULL || port->write == NULL || port->set_baud == NULL ||
        types == NULL || ntypes == 0u || baud == 0u) {
        return DAN_ERR_ARG;
    }
    memset(p, 0, sizeof *p);
    if (cfg != NULL) {
        p->cfg = *cfg;
    } else {
        dan_periph_config_default(&p->cfg);
    }
    if (p->cfg.max_baud == 0u) {
        p->cfg.max_baud = port->max_baud;
    }
    p->types = types;
    p->ntypes = ntypes;
    dan_link_init(&p->link, port, baud, on_frame, p, now_us);
    p->link.gap_us = p->cfg.gap_us;
    return DAN_OK;
}

static const dan_ptype_t *find_type(const dan_periph_t *p, uint32_t code)
{
    size_t i;
    for (i = 0; i < p->ntypes; i++) {
        uint32_t span = DAN_TYPE_BLOCK_SIZE * (p->types[i].blocks > 1u ? p->types[i].blocks : 1u);
        if (code >= p->types[i].first && code - p->types[i].first < span) {
            return &p->types[i];
        }
    }
    return NULL;
}

static void queue_reply(dan_periph_t *p, uint32_t code, size_t len, uint64_t now_us)
{
    uint32_t turn = p->cfg.turnaround_chars * p->link.char_us;
    p->pending = true;
    p->reply_code = code;
    p->reply_len = len;
    p->reply_after_us = (uint32_t)now_us + turn;
    p->reply_before_us = (uint32_t)now_us + turn + p->cfg.reply_window_us;
}

static void queue_error(dan_periph_t *p, uint32_t code, const char *text, uint64_t now_us)
{
    int n = dan_error_encode(code, 0, text, p->reply, sizeof p->reply);
    if (n < 0) { /* text too long for a payload: send it without */
        n = dan_error_encode(code, 0, "", p->reply, sizeof p->reply);
    }
    p->stats.errors_sent++;
    queue_reply(p, DAN_CODE_ERROR, (size_t)n, now_us);
}

static bool baud_allowed(const dan_periph_t *p, const dan_ptype_t *t, uint32_t baud)
{
    size_t i;
    if (p->cfg.max_baud != 0u && baud > p->cfg.max_baud) {
        return false;
    }
    if (baud == DAN_BAUD_BASE ||
        (t->identity->baud_mask & DAN_BAUD_MASK_DEFINED & dan_mask_bit_of_baud(baud)) != 0u) {
        return true;
    }
    for (i = 0; i < p->cfg.nextra_bauds && p->cfg.extra_bauds != NULL; i++) {
        if (p->cfg.extra_bauds[i] == baud) {
            return true; /* a fast baud this device was configured for */
        }
    }
    return false;
}

static void handle_configure(dan_periph_t *p, const dan_ptype_t *t, const dan_frame_t *f,
                             uint64_t now_us)
{
    dan_configure_t c;
    int r = dan_configure_decode(&c, f->payload, f->len);
    uint8_t ack = DAN_ACK_FAIL;
    p->stats.configures++;
    if (r == DAN_ERR_MALFORMED) {
        queue_error(p, f->code, "malformed CONFIGURE payload", now_us);
        return;
    }
    if (r == DAN_OK && baud_allowed(p, t, c.baud)) {
        ack = DAN_ACK_OK;
        p->next_baud = (c.baud != p->link.baud) ? c.baud : 0u;
    } else {
        p->stats.nacks++;
        p->next_baud = 0;
    }
    (void)dan_ack_encode(ack, p->reply, sizeof p->reply);
    queue_reply(p, f->code, 1, now_us);
}

/* A request that will be answered: it supersedes a reply not sent yet
 * (the master moved on: answer the newest) and a baud switch not made.
 * Only then: a frame that is ignored (no handler, a bad seal) changes
 * nothing, as a bad CRC changes nothing. */
static void take_request(dan_periph_t *p)
{
    if (p->pending) {
        p->stats.overruns++;
        p->pending = false;
    }
    p->next_baud = 0;
    p->stats.requests++;
}

/* Runs a handler inside the type's envelope (if any) and queues its reply. */
static void serve(dan_periph_t *p, const dan_ptype_t *t, const dan_handler_t *h,
                  const dan_frame_t *f, uint64_t now_us)
{
    const dan_envelope_t *env = t->envelope;
    size_t len = f->len, room = sizeof p->reply;
    const char *text = NULL;
    dan_writer_t w;
    int r;
    if (env != NULL) {
        r = env->open(t->user, f->code, f->payload, f->len);
        if (r < 0) {
            p->stats.dropped++;
            return;
        }
        len = (size_t)r;
        room = room > env->trailer ? room - env->trailer : 0u;
    }
    take_request(p);
    dan_writer_init(&w, p->reply, room);
    r = h->fn(t->user, f->code, f->payload, len, &w, &text, now_us);
    if (r == DAN_PERIPH_NO_REPLY) {
        return;
    }
    if (r == DAN_OK && dan_writer_finish(&w) < 0) {
        r = DAN_ERR_OVERFLOW;
        text = "response too large";
    }
    if (r < 0) {
        queue_error(p, f->code, (text != NULL) ? text : dan_strerror(r), now_us);
        return;
    }
    if (env != NULL) {
        env->close(t->user, f->code, p->reply, w.len);
        w.len += env->trailer;
    }
    queue_reply(p, f->code, w.len, now_us);
}

static void on_frame(void *owner, const dan_frame_t *f, uint64_t now_us)
{
    dan_periph_t *p = (dan_periph_t *)owner;
    const dan_ptype_t *t = find_type(p, f->code);
    size_t i;
    if (dan_link_is_late_echo(&p->link, f, (uint32_t)now_us)) {
        /* Our own reply, heard after a collision broke its echo: a reply
         * has the request's code, so it must never be served as one. */
        p->stats.own_echoes++;
        return;
    }
    if (t == NULL || f->code == DAN_CODE_ERROR) {
        p->stats.unknown++;
        return;
    }
    if (f->code == DAN_TYPE_IDENTIFY(t->first)) {
        int n;
        take_request(p);
        n = dan_identity_encode(t->identity, p->reply, sizeof p->reply);
        if (n < 0) {
            queue_error(p, f->code, "identity too large", now_us);
        } else {
            queue_reply(p, f->code, (size_t)n, now_us);
        }
        return;
    }
    if (f->code == DAN_TYPE_CONFIGURE(t->first)) {
        take_request(p);
        handle_configure(p, t, f, now_us);
        return;
    }
    for (i = 0; i < t->nhandlers; i++) {
        if (t->handlers[i].code == f->code && t->handlers[i].fn != NULL) {
            serve(p, t, &t->handlers[i], f, now_us);
            return;
        }
    }
    p->stats.unknown++; /* in our block but not served: ignored, per the spec */
}

void dan_periph_rx(dan_periph_t *p, const uint8_t *data, size_t len, uint64_t now_us)
{
    dan_link_rx(&p->link, data, len, now_us);
}

void dan_periph_poll(dan_periph_t *p, uint64_t now64)
{
    dan_link_state_t ls = dan_link_poll(&p->link, now64);
    uint32_t now_us = (uint32_t)now64;
    if (ls == DAN_LINK_TX_DONE || ls == DAN_LINK_TX_FAILED) {
        dan_link_ack(&p->link);
        if (p->tx_baud != 0u) {
            /* The ACK has left the wire (echo seen or UART drained). A
             * failed send (collision) still switches: the master cannot
             * know whether the ACK reached it and will verify. */
            if (dan_link_set_baud(&p->link, p->tx_baud, now_us) == DAN_OK) {
                p->stats.baud_changes++;
            }
        }
        /* Only the frame that left: a CONFIGURE that came in while an
         * earlier reply was still on the wire (its echo not read yet, as
         * on a loaded host or behind a fast master) keeps its switch. */
        p->tx_baud = 0;
        ls = DAN_LINK_IDLE;
    }
    if (!p->pending || ls != DAN_LINK_IDLE) {
        return;
    }
    if (now_us - p->reply_before_us - 1u < 0x80000000u) { /* now_us > reply_before_us */
        p->pending = false;
        p->next_baud = 0;
        p->stats.late++;
        return;
    }
    if (now_us - p->reply_after_us >= 0x80000000u || /* now_us < reply_after_us */
        dan_link_idle_us(&p->link, now_us) < p->cfg.turnaround_chars * p->link.char_us) {
        return;
    }
    p->pending = false;
    p->tx_baud = p->next_baud; /* the switch goes with this frame */
    p->next_baud = 0;
    if (dan_link_send(&p->link, p->reply_code, p->reply, p->reply_len, now_us) == DAN_OK) {
        p->stats.replies++;
    } else {
        p->tx_baud = 0;
    }
}

uint64_t dan_periph_next_us(const dan_periph_t *p)
{
    const dan_link_t *l = &p->link;
    uint32_t next = dan_link_wait_us(l);
    if (p->pending) {
        uint32_t t = dan_link_due_in(l, p->reply_after_us);
        uint32_t idle_at = dan_link_due_in(l, l->last_rx_us + p->cfg.turnaround_chars * l->char_us);
        uint32_t late = dan_link_due_in(l, p->reply_before_us + 1u);
        if (idle_at > t) {
            t = idle_at;
        }
        if (t > late) {
            t = late;
        }
        if (t < next) {
            next = t;
        }
    }
    return dan_link_wait_time(l, next);
}
