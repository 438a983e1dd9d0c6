/* Half-duplex link: TX with echo check, RX with idle-gap abort. */
#include <string.h>

#include "dan/link.h"

uint32_t dan_char_us(uint32_t baud)
{
    if (baud == 0u) {
        return 0xFFFFFFFFu;
    }
    return (10000000u + baud - 1u) / baud;
}

void dan_link_init(dan_link_t *l, const dan_port_t *port, uint32_t baud, dan_frame_cb_t on_frame,
                   void *owner, uint64_t now_us)
{
    memset(l, 0, sizeof *l);
    l->port = *port;
    l->baud = baud;
    l->char_us = dan_char_us(baud);
    l->on_frame = on_frame;
    l->owner = owner;
    dan_link_set_now(l, now_us);
    l->last_rx_us = (uint32_t)now_us; /* idle time counts from start-up */
    dan_decoder_init(&l->dec);
}

uint32_t dan_link_gap_us(const dan_link_t *l)
{
    uint32_t g;
    if (l->gap_us != 0u) {
        return l->gap_us;
    }
    g = DAN_GAP_CHARS * l->char_us;
    return (g > DAN_GAP_MIN_US) ? g : DAN_GAP_MIN_US;
}

static void deliver_frames(dan_link_t *l, const uint8_t *p, size_t n, uint64_t now_us)
{
    for (;;) {
        size_t used;
        dan_frame_t f;
        int got = dan_decoder_feed(&l->dec, p, n, &used, &f);
        p += used;
        n -= used;
        if (!got) {
            break;
        }
        l->rx_any = false;
        if (l->on_frame != NULL) {
            l->on_frame(l->owner, &f, now_us);
        }
    }
}

int dan_link_set_baud(dan_link_t *l, uint32_t baud, uint32_t now_us)
{
    int r = l->port.set_baud(l->port.ctx, baud);
    if (r < 0) {
        l->stats.port_errors++;
        return DAN_ERR_IO;
    }
    l->baud = baud;
    l->char_us = dan_char_us(baud);
    dan_decoder_reset(&l->dec);
    l->last_rx_us = now_us;
    l->rx_any = false;
    return DAN_OK;
}

static uint32_t echo_timeout(const dan_link_t *l)
{
    uint32_t g = dan_link_gap_us(l);
    return (l->echo_timeout_us > g) ? l->echo_timeout_us : g;
}

/* Our echo went missing or broke less than DAN_ECHO_LATE_HOLD_US ago.
 * echo_late_us is that time with bit 0 set (never 0: none). */
static bool late_hold(const dan_link_t *l, uint32_t now_us)
{
    return l->echo_late_us != 0u && now_us - (l->echo_late_us & ~1u) <= DAN_ECHO_LATE_HOLD_US;
}

bool dan_link_is_late_echo(const dan_link_t *l, const dan_frame_t *f, uint32_t now_us)
{
    size_t n = dan_frame_size(f->code, f->len);
    uint32_t code;
    if (!l->port.echo || !late_hold(l, now_us) || l->tx_len != n ||
        dan_uvarint_decode(l->tx + 1, n - 1u, &code) <= 0 || code != f->code) {
        return false;
    }
    return f->len == 0u || memcmp(l->tx + n - 1u - f->len, f->payload, f->len) == 0;
}

/* Wrap-safe: a last_rx_us slightly ahead of now_us (a receive stamp taken
 * after the poll's) is no idle time, as before. */
uint32_t dan_link_idle_us(const dan_link_t *l, uint32_t now_us)
{
    uint32_t d = now_us - l->last_rx_us;
    if (l->state == DAN_LINK_TX || dan_decoder_busy(&l->dec) || d >= 0x80000000u) {
        return 0;
    }
    return d;
}

static uint32_t tx_end_us(const dan_link_t *l)
{
    return l->tx_start_us + (uint32_t)l->tx_len * l->char_us;
}

/* now_us at or after t (wrap-safe) */
static bool reached(uint32_t now_us, uint32_t t)
{
    return now_us - t < 0x80000000u;
}

static void end_tx(dan_link_t *l, dan_link_state_t st, uint32_t now_us)
{
    if (l->port.set_tx != NULL) {
        l->port.set_tx(l->port.ctx, false);
    }
    if (st == DAN_LINK_TX_FAILED && l->port.flush_tx != NULL) {
        l->port.flush_tx(l->port.ctx);
    }
    if (!reached(l->last_rx_us, now_us) && st == DAN_LINK_TX_DONE && !l->port.echo) {
        l->last_rx_us = now_us; /* our own bytes kept the line busy until now */
    }
    l->state = st;
}

void dan_link_rx(dan_link_t *l, const uint8_t *data, size_t len, uint64_t now64)
{
    size_t i = 0;
    uint32_t now_us = (uint32_t)now64;
    if (len == 0u) {
        return;
    }
    dan_link_set_now(l, now64);
    l->stats.rx_bytes += (uint32_t)len;
    l->last_rx_us = now_us;
    if (l->state == DAN_LINK_TX && l->port.echo) {
        while (i < len && l->echo_pos < l->tx_len) {
            if (data[i] != l->tx[l->echo_pos]) {
                /* Someone else drove the wire at the same time. The rest
                 * of our frame may still reach our decoder: remember it. */
                l->stats.collisions++;
                l->echo_late_us = now_us | 1u; /* never 0 */
                end_tx(l, DAN_LINK_TX_FAILED, now_us);
                break;
            }
            l->echo_pos++;
            i++;
        }
        if (l->state == DAN_LINK_TX && l->echo_pos == l->tx_len) {
            end_tx(l, DAN_LINK_TX_DONE, now_us);
        }
    }
    if (i < len) {
        l->rx_any = true;
        deliver_frames(l, data + i, len - i, now64);
    }
}

int dan_link_prepare(dan_link_t *l, uint32_t code, const uint8_t *payload, size_t len)
{
    int n;
    if (l->state == DAN_LINK_TX) {
        return DAN_ERR_BUSY;
    }
    n = dan_frame_encode(code, payload, len, l->tx, sizeof l->tx);
    if (n < 0) {
        l->tx_len = 0;
        return n;
    }
    l->tx_len = (uint16_t)n;
    return DAN_OK;
}

int dan_link_transmit(dan_link_t *l, uint32_t now_us)
{
    if (l->state == DAN_LINK_TX) {
        return DAN_ERR_BUSY;
    }
    if (l->tx_len == 0u) {
        return DAN_ERR_ARG;
    }
    l->echo_pos = 0;
    l->tx_start_us = now_us;
    l->state = DAN_LINK_TX;
    if (l->port.set_tx != NULL) {
        l->port.set_tx(l->port.ctx, true);
    }
    if (l->port.write(l->port.ctx, l->tx, l->tx_len) != (int)l->tx_len) {
        l->stats.port_errors++;
        end_tx(l, DAN_LINK_TX_FAILED, now_us);
        return DAN_ERR_IO;
    }
    l->stats.tx_frames++;
    l->stats.tx_bytes += (uint32_t)l->tx_len;
    return DAN_OK;
}

int dan_link_send(dan_link_t *l, uint32_t code, const uint8_t *payload, size_t len, uint32_t now_us)
{
    int r = dan_link_prepare(l, code, payload, len);
    return (r != DAN_OK) ? r : dan_link_transmit(l, now_us);
}

dan_link_state_t dan_link_poll(dan_link_t *l, uint64_t now64)
{
    uint32_t now_us = (uint32_t)now64;
    dan_link_set_now(l, now64);
    if (dan_decoder_busy(&l->dec) && reached(now_us, l->last_rx_us + dan_link_gap_us(l))) {
        /* The line went quiet in the middle of a frame. */
        dan_decoder_abort(&l->dec);
        deliver_frames(l, NULL, 0, now64);
    }
    /* 32-bit times stay within 2^30 us of now: a line idle for longer is
     * idle for 2^30 us (18 minutes), a late echo's hold is over. */
    if (now_us - l->last_rx_us > 0x40000000u && now_us - l->last_rx_us < 0x80000000u) {
        l->last_rx_us = now_us - 0x40000000u;
    }
    if (!late_hold(l, now_us)) {
        l->echo_late_us = 0;
    }
    if (l->state == DAN_LINK_TX) {
        uint32_t end = tx_end_us(l);
        if (l->port.echo) {
            if (reached(now_us, end + echo_timeout(l))) {
                l->stats.echo_timeouts++;
                l->echo_late_us = now_us | 1u;
                end_tx(l, DAN_LINK_TX_FAILED, now_us);
            }
        } else if (reached(now_us, end) &&
                   (l->port.tx_busy == NULL || !l->port.tx_busy(l->port.ctx))) {
            end_tx(l, DAN_LINK_TX_DONE, now_us);
        }
    }
    return l->state;
}

void dan_link_tx_answered(dan_link_t *l, uint32_t now_us)
{
    if (l->state == DAN_LINK_TX) {
        end_tx(l, DAN_LINK_TX_DONE, now_us);
    }
}

void dan_link_ack(dan_link_t *l)
{
    if (l->state == DAN_LINK_TX_DONE || l->state == DAN_LINK_TX_FAILED) {
        l->state = DAN_LINK_IDLE;
    }
}

uint32_t dan_link_wait_us(const dan_link_t *l)
{
    uint32_t next = DAN_LINK_IDLE_POLL_US;
    if (dan_decoder_busy(&l->dec)) {
        next = dan_link_due_in(l, l->last_rx_us + dan_link_gap_us(l));
    }
    if (l->state == DAN_LINK_TX) {
        uint32_t end = tx_end_us(l);
        uint32_t t = dan_link_due_in(l, l->port.echo ? end + echo_timeout(l) : end);
        if (t < next) {
            next = t;
        }
    }
    return next;
}
