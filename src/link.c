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
    l->last_rx_us = now_us; /* idle time counts from start-up */
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

int dan_link_set_baud(dan_link_t *l, uint32_t baud, uint64_t now_us)
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

bool dan_link_is_late_echo(const dan_link_t *l, const dan_frame_t *f, uint64_t now_us)
{
    size_t n = dan_frame_size(f->code, f->len);
    uint32_t code;
    if (!l->port.echo || l->echo_late_us == 0u ||
        now_us - l->echo_late_us > DAN_ECHO_LATE_HOLD_US || l->tx_len != n ||
        dan_uvarint_decode(l->tx + 1, n - 1u, &code) <= 0 || code != f->code) {
        return false;
    }
    return f->len == 0u || memcmp(l->tx + n - 1u - f->len, f->payload, f->len) == 0;
}

uint64_t dan_link_idle_us(const dan_link_t *l, uint64_t now_us)
{
    if (l->state == DAN_LINK_TX || dan_decoder_busy(&l->dec) || now_us < l->last_rx_us) {
        return 0;
    }
    return now_us - l->last_rx_us;
}

uint64_t dan_link_tx_end_us(const dan_link_t *l)
{
    return l->tx_start_us + (uint64_t)l->tx_len * l->char_us;
}

static void end_tx(dan_link_t *l, dan_link_state_t st, uint64_t now_us)
{
    if (l->port.set_tx != NULL) {
        l->port.set_tx(l->port.ctx, false);
    }
    if (st == DAN_LINK_TX_FAILED && l->port.flush_tx != NULL) {
        l->port.flush_tx(l->port.ctx);
    }
    if (l->last_rx_us < now_us && st == DAN_LINK_TX_DONE && !l->port.echo) {
        l->last_rx_us = now_us; /* our own bytes kept the line busy until now */
    }
    l->state = st;
}

void dan_link_rx(dan_link_t *l, const uint8_t *data, size_t len, uint64_t now_us)
{
    size_t i = 0;
    if (len == 0u) {
        return;
    }
    l->stats.rx_bytes += (uint32_t)len;
    l->last_rx_us = now_us;
    if (l->state == DAN_LINK_TX && l->port.echo) {
        while (i < len && l->echo_pos < l->tx_len) {
            if (data[i] != l->tx[l->echo_pos]) {
                /* Someone else drove the wire at the same time. The rest
                 * of our frame may still reach our decoder: remember it. */
                l->stats.collisions++;
                l->echo_late_us = now_us;
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
        deliver_frames(l, data + i, len - i, now_us);
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
    l->tx_len = (size_t)n;
    return DAN_OK;
}

int dan_link_transmit(dan_link_t *l, uint64_t now_us)
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

int dan_link_send(dan_link_t *l, uint32_t code, const uint8_t *payload, size_t len, uint64_t now_us)
{
    int r = dan_link_prepare(l, code, payload, len);
    return (r != DAN_OK) ? r : dan_link_transmit(l, now_us);
}

dan_link_state_t dan_link_poll(dan_link_t *l, uint64_t now_us)
{
    if (dan_decoder_busy(&l->dec) && now_us >= l->last_rx_us + dan_link_gap_us(l)) {
        /* The line went quiet in the middle of a frame. */
        dan_decoder_abort(&l->dec);
        deliver_frames(l, NULL, 0, now_us);
    }
    if (l->state == DAN_LINK_TX) {
        uint64_t end = dan_link_tx_end_us(l);
        if (l->port.echo) {
            if (now_us >= end + echo_timeout(l)) {
                l->stats.echo_timeouts++;
                l->echo_late_us = now_us;
                end_tx(l, DAN_LINK_TX_FAILED, now_us);
            }
        } else if (now_us >= end && (l->port.tx_busy == NULL || !l->port.tx_busy(l->port.ctx))) {
            end_tx(l, DAN_LINK_TX_DONE, now_us);
        }
    }
    return l->state;
}

void dan_link_ack(dan_link_t *l)
{
    if (l->state == DAN_LINK_TX_DONE || l->state == DAN_LINK_TX_FAILED) {
        l->state = DAN_LINK_IDLE;
    }
}

uint64_t dan_link_next_us(const dan_link_t *l)
{
    uint64_t next = UINT64_MAX;
    if (dan_decoder_busy(&l->dec)) {
        next = l->last_rx_us + dan_link_gap_us(l);
    }
    if (l->state == DAN_LINK_TX) {
        uint64_t end = dan_link_tx_end_us(l);
        uint64_t t = l->port.echo ? end + echo_timeout(l) : end;
        if (t < next) {
            next = t;
        }
    }
    return next;
}
