/*
 * The half-duplex link shared by the master and peripheral engines: the
 * platform port, frame transmission with echo checking, listen-before-talk
 * timing and reception with idle-gap handling.
 *
 * Time is always passed in as a monotonic microsecond count (now_us); the
 * library never reads a clock or sleeps. The link keeps times as their low
 * 32 bits (wrap-safe differences: every interval it times is far below
 * 2^31 us, and dan_link_poll() keeps the idle reference within 2^30 us,
 * which needs a poll at least every DAN_LINK_IDLE_POLL_US: the engines'
 * *_next_us() never ask for less), and the last 64-bit now_us passed in to
 * give them back as 64-bit times (dan_link_set_now()).
 *
 * Timing (docs/PROTOCOL.md, section 6), with C = one character time
 * = 10 bits / baud (8N1), rounded up to whole microseconds:
 *   - listen before talk: transmit only after the line was idle >= lbt_chars * C
 *   - inter-byte gap: a frame's bytes are back to back; an idle gap longer
 *     than gap_us while a frame is incomplete drops it
 *
 * Not reentrant: one instance is used from one context (its engine's).
 */
#ifndef DAN_LINK_H
#define DAN_LINK_H

#include "dan/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Timing defaults (DAN_LBT_CHARS, DAN_GAP_CHARS, DAN_GAP_MIN_US,
 * DAN_TURNAROUND_CHARS, DAN_RESP_LATENCY_US, DAN_ECHO_LATE_HOLD_US) are
 * settings in dan/config.h; the engines' config structs change them at
 * run time. */

/*
 * The platform: a small table of functions. write and set_baud are
 * required; the others may be NULL.
 */
typedef struct {
    /* Queues len bytes for transmission; returns len, or a negative error.
     * Must not block for long (a UART FIFO/DMA or a kernel buffer). */
    int (*write)(void *ctx, const uint8_t *data, size_t len);
    /* Changes the UART baud for both directions. */
    int (*set_baud)(void *ctx, uint32_t baud);
    /* Direction pin (RS-485 DE): asserted before the first byte is queued,
     * released once every byte has left the wire. NULL on a single wire. */
    void (*set_tx)(void *ctx, bool on);
    /* True while bytes are still in the UART (FIFO or shift register).
     * NULL: the engine assumes the bytes are gone after len * C. */
    bool (*tx_busy)(void *ctx);
    /* Discards bytes not yet sent (after a collision). May be NULL. */
    void (*flush_tx)(void *ctx);
    void *ctx;
    /* Highest baud the port can do (0: no limit). */
    uint32_t max_baud;
    /* The port hears its own bytes (single-wire bus, no hardware echo
     * suppression). The engine then compares the echo with what it sent;
     * a mismatch is a collision. */
    bool echo;
} dan_port_t;

typedef struct {
    uint32_t tx_frames;
    uint32_t tx_bytes;
    uint32_t rx_bytes;
    uint32_t collisions;    /* echo differed from what we sent */
    uint32_t echo_timeouts; /* echo never came back (wiring, or port.echo wrong) */
    uint32_t port_errors;   /* write or set_baud failed */
} dan_link_stats_t;

typedef enum {
    DAN_LINK_IDLE = 0,
    DAN_LINK_TX,       /* our frame is on the wire */
    DAN_LINK_TX_DONE,  /* it has left the wire (echo complete) */
    DAN_LINK_TX_FAILED /* collision or missing echo */
} dan_link_state_t;

typedef void (*dan_frame_cb_t)(void *owner, const dan_frame_t *frame, uint64_t now_us);

typedef struct {
    /* Fields ordered by use, small ones first (Thumb's short loads: flash)
     * and without padding (RAM); the frame buffers last. */
    dan_link_state_t state;
    bool rx_any;       /* a byte was received since the last frame/send */
    uint16_t tx_len;   /* bytes in tx */
    uint16_t echo_pos; /* echoed bytes matched so far */
    uint32_t baud;
    uint32_t char_us;         /* one character time at baud */
    uint32_t gap_us;          /* 0 = default: max(DAN_GAP_CHARS * C, DAN_GAP_MIN_US) */
    uint32_t echo_timeout_us; /* echo must be complete by T_end + this (0 = gap) */
    uint32_t echo_late_us;    /* when our echo last went missing or broke (0: not within
                                 DAN_ECHO_LATE_HOLD_US) */
    uint32_t tx_start_us;
    uint32_t last_rx_us; /* time of the last byte received (or echoed) */
    dan_frame_cb_t on_frame;
    void *owner;
    dan_port_t port;
    dan_link_stats_t stats;
    /* the last now_us passed in (dan_link_due_in()), as two halves: no
     * 8-byte alignment (padding) */
    uint32_t now_us;
    uint32_t now_hi;
    dan_decoder_t dec;
    uint8_t tx[DAN_MAX_FRAME];
} dan_link_t;

/* Character time at baud, in microseconds (rounded up). */
uint32_t dan_char_us(uint32_t baud);

void dan_link_init(dan_link_t *l, const dan_port_t *port, uint32_t baud, dan_frame_cb_t on_frame,
                   void *owner, uint64_t now_us);
/* Switches the port's baud; drops any partial frame (bytes at the old baud). */
int dan_link_set_baud(dan_link_t *l, uint32_t baud, uint32_t now_us);
/* Effective inter-byte gap. */
uint32_t dan_link_gap_us(const dan_link_t *l);
/* Microseconds the line has been idle at now (0 while busy). */
uint32_t dan_link_idle_us(const dan_link_t *l, uint32_t now_us);
/* Feeds received bytes: our own echo is matched and removed, everything
 * else goes to the decoder; whole frames go to on_frame. */
void dan_link_rx(dan_link_t *l, const uint8_t *data, size_t len, uint64_t now_us);
/* Encodes a frame into the link's TX buffer without sending it (the
 * master keeps it there for its retries). DAN_ERR_BUSY while a frame is
 * on the wire; DAN_ERR_ARG for an oversized payload. */
int dan_link_prepare(dan_link_t *l, uint32_t code, const uint8_t *payload, size_t len);
/* Queues the prepared frame (again, for a retry). The caller has checked
 * listen-before-talk. Returns DAN_OK, DAN_ERR_BUSY, DAN_ERR_ARG (nothing
 * prepared) or DAN_ERR_IO. */
int dan_link_transmit(dan_link_t *l, uint32_t now_us);
/* dan_link_prepare() then dan_link_transmit(). */
int dan_link_send(dan_link_t *l, uint32_t code, const uint8_t *payload, size_t len,
                  uint32_t now_us);
/* Advances timers (idle-gap abort, end of transmission, direction pin).
 * Returns the link state; TX_DONE and TX_FAILED stay until dan_link_ack(). */
dan_link_state_t dan_link_poll(dan_link_t *l, uint64_t now_us);
/* Acknowledges TX_DONE / TX_FAILED, back to IDLE. */
void dan_link_ack(dan_link_t *l);

/* True if f is a copy of the frame in our TX buffer and our echo went
 * missing or broke (collision) less than DAN_ECHO_LATE_HOLD_US ago: it is
 * our own echo, never a reply or a request. */
bool dan_link_is_late_echo(const dan_link_t *l, const dan_frame_t *f, uint32_t now_us);
/* Keeps now_us (every entry that takes a 64-bit time). */
static inline void dan_link_set_now(dan_link_t *l, uint64_t now_us)
{
    l->now_us = (uint32_t)now_us;
    l->now_hi = (uint32_t)(now_us >> 32);
}
/* Microseconds from the last now_us passed in until 32-bit time t (0 if t
 * has passed). */
static inline uint32_t dan_link_due_in(const dan_link_t *l, uint32_t t)
{
    uint32_t d = t - l->now_us;
    return (d >= 0x80000000u) ? 0u : d;
}
/* Microseconds until dan_link_poll() has something to do, from the last
 * now_us passed in: at most DAN_LINK_IDLE_POLL_US when there is nothing,
 * so that a caller sleeping as long as it says keeps the 32-bit stamps
 * within reach (a difference of 2^31 us would read as "ahead"). */
#define DAN_LINK_IDLE_POLL_US 0x20000000u /* 2^29 us, 8.9 minutes */
uint32_t dan_link_wait_us(const dan_link_t *l);
/* A reply to our frame arrived while the link still counts it as on the
 * wire (a port without echo, before a poll saw its end): it has left. */
void dan_link_tx_answered(dan_link_t *l, uint32_t now_us);
/* The 64-bit time of a wait from dan_link_wait_us(). */
static inline uint64_t dan_link_wait_time(const dan_link_t *l, uint32_t wait_us)
{
    return (((uint64_t)l->now_hi << 32) | l->now_us) + wait_us;
}

#ifdef __cplusplus
}
#endif

#endif /* DAN_LINK_H */
