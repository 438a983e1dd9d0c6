/*
 * The DAN peripheral engine: one caller-owned dan_periph_t per UART, serving
 * one or more peripheral types on it.
 *
 * The engine answers IDENTIFY and CONFIGURE itself, dispatches the type's
 * other codes to handlers, ignores codes it does not know (counted), and
 * answers a known code with a malformed payload with an error frame
 * (code 0). It replies no sooner than the turnaround gap after the
 * request's last byte and only while the master still waits (the reply
 * window); a baud change takes effect once its ACK has left the wire.
 *
 *     dan_periph_init(&p, &port, types, ntypes, NULL, now);
 *     loop: dan_periph_rx(&p, bytes, n, now); dan_periph_poll(&p, now);
 *
 * Not reentrant: call every dan_periph_* function of one instance from one
 * context (a main loop or one task), never from an interrupt; feed bytes
 * from an ISR through a dan_rxring_t (dan/rxring.h). Distinct instances
 * are independent.
 */
#ifndef DAN_PERIPHERAL_H
#define DAN_PERIPHERAL_H

#include "dan/link.h"
#include "dan/payloads.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Handler return value: the request needs no reply. */
#define DAN_PERIPH_NO_REPLY 1

/*
 * A request handler. req/len is the request payload (inside the type's
 * envelope, if it has one). Write the response payload into resp (its
 * capacity is DAN_MAX_PAYLOAD less the envelope's trailer) and return DAN_OK to
 * send it with the request's code. Return DAN_ERR_MALFORMED (or another
 * negative code) to answer with an error frame; set *error_text to say why
 * (a static string; default: the error's name). Return DAN_PERIPH_NO_REPLY
 * to stay silent. Handlers run inside dan_periph_rx()/dan_periph_poll().
 */
typedef int (*dan_handler_fn)(void *user, uint32_t code, const uint8_t *req, size_t len,
                              dan_writer_t *resp, const char **error_text, uint64_t now_us);

typedef struct {
    uint32_t code;
    dan_handler_fn fn;
} dan_handler_t;

/*
 * An optional envelope around every message of a type but IDENTIFY,
 * CONFIGURE and error frames: e.g. the CAN gateway's seal, a check bound to
 * the code and the direction. The engine opens each request before any
 * handler sees it and closes each response after its handler wrote it, so
 * handlers work on the inner payload only.
 */
typedef struct {
    /* Bytes close() appends to a response payload. */
    size_t trailer;
    /* Checks a request payload; returns the inner length (<= len), or a
     * negative code to drop the request without any reply (the master
     * retries, as after a bad CRC). */
    int (*open)(void *user, uint32_t code, const uint8_t *req, size_t len);
    /* Appends the trailer to a response payload of len bytes; the room for
     * it is reserved (the handler's writer ends trailer bytes short). */
    void (*close)(void *user, uint32_t code, uint8_t *resp, size_t len);
} dan_envelope_t;

/* A peripheral type: a block of DAN_TYPE_BLOCK_SIZE codes starting at
 * first, with IDENTIFY = first and CONFIGURE = first + 1. */
typedef struct {
    uint32_t first;
    const dan_identity_t *identity;
    const dan_handler_t *handlers;
    size_t nhandlers;
    void *user;                     /* passed to the handlers and the envelope */
    const dan_envelope_t *envelope; /* NULL: none */
    uint8_t blocks;                 /* consecutive blocks of codes the type owns (0 and
                                     1: one); only the first has IDENTIFY/CONFIGURE */
} dan_ptype_t;

typedef struct {
    uint8_t turnaround_chars; /* idle characters before replying (default DAN_TURNAROUND_CHARS) */
    uint32_t
        reply_window_us; /* drop a reply not started by turnaround + this (default DAN_RESP_LATENCY_US) */
    uint32_t gap_us;   /* inter-byte gap (0: link default) */
    uint32_t max_baud; /* refuse CONFIGURE above this (0: port.max_baud) */
    /* Bauds beyond 9600 and the identity's mask that CONFIGURE may ask
     * for (e.g. dan_fast_bauds, or the ones the UART can do); not copied.
     * NULL/0: none, the v1 behaviour (ACK-FAIL for anything else). */
    const uint32_t *extra_bauds;
    size_t nextra_bauds;
} dan_periph_config_t;

void dan_periph_config_default(dan_periph_config_t *c);

typedef struct {
    uint32_t requests; /* frames for one of our types */
    uint32_t replies;
    uint32_t unknown;     /* frames with codes we do not serve (ignored) */
    uint32_t errors_sent; /* error frames sent */
    uint32_t late;        /* replies dropped: the window had passed */
    uint32_t overruns;    /* a request arrived before the last reply went out */
    uint32_t configures;
    uint32_t nacks; /* CONFIGURE answered ACK-FAIL */
    uint32_t baud_changes;
    uint32_t own_echoes; /* copies of our own reply ignored (after a collision) */
    uint32_t dropped;    /* requests the type's envelope refused (no reply) */
} dan_periph_stats_t;

typedef struct {
    dan_link_t link;
    dan_periph_config_t cfg;
    const dan_ptype_t *types;
    size_t ntypes;
    /* the reply waiting for the turnaround gap */
    bool pending;
    uint32_t reply_code;
    uint8_t reply[DAN_MAX_PAYLOAD];
    size_t reply_len;
    uint32_t reply_after_us; /* low 32 bits of now_us (see dan/link.h) */
    uint32_t reply_before_us;
    uint32_t next_baud; /* the queued ACK's switch (0: none) */
    uint32_t tx_baud;   /* the switch once the frame on the wire has left (0: none) */
    dan_periph_stats_t stats;
} dan_periph_t;

/* types must stay valid (not copied). baud is the start baud (9600 after
 * power-up, per the spec). cfg may be NULL. */
int dan_periph_init(dan_periph_t *p, const dan_port_t *port, const dan_ptype_t *types,
                    size_t ntypes, const dan_periph_config_t *cfg, uint32_t baud, uint64_t now_us);
void dan_periph_rx(dan_periph_t *p, const uint8_t *data, size_t len, uint64_t now_us);
void dan_periph_poll(dan_periph_t *p, uint64_t now_us);
/* Earliest time the engine needs a poll: at the latest DAN_LINK_IDLE_POLL_US
 * (8.9 minutes) after the last call when nothing is going on. */
uint64_t dan_periph_next_us(const dan_periph_t *p);
/* Current baud. */
static inline uint32_t dan_periph_baud(const dan_periph_t *p)
{
    return p->link.baud;
}

#ifdef __cplusplus
}
#endif

#endif /* DAN_PERIPHERAL_H */
