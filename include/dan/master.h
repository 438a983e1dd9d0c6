/*
 * The DAN master engine: discovery, configure, transactions.
 *
 * One caller-owned dan_master_t per UART. Nothing blocks: the caller feeds
 * received bytes with dan_master_rx(), calls dan_master_poll() regularly (at
 * the latest by dan_master_next_us()), and starts one operation at a time:
 * a transaction, a discovery or a configure. dan_master_poll() returns 1
 * once when the operation completes; its result is dan_master_result().
 *
 *     dan_master_init(&m, &port, &cfg, types, ntypes, now);
 *     dan_master_discover(&m, now);
 *     while (!dan_master_poll(&m, now)) { feed rx; now = clock(); }
 *     if (dan_master_result(&m) == DAN_OK) dan_master_configure(&m, 0, now);
 *
 * Timing rules, retries and the discovery/configure sequences are in
 * docs/PROTOCOL.md section 6; the formulas are implemented here.
 *
 * Not reentrant: call every dan_master_* function of one instance (and the
 * clients built on it, e.g. dan_gw_*) from one context (a main loop or one
 * task), never from an interrupt; feed bytes from an ISR through a
 * dan_rxring_t (dan/rxring.h). Distinct instances are independent.
 */
#ifndef DAN_MASTER_H
#define DAN_MASTER_H

#include "dan/link.h"
#include "dan/payloads.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Peripheral types one master can probe (and so, peers per UART):
 * DAN_MASTER_MAX_TYPES, a setting in dan/config.h. */

/* Bauds a master tries during discovery: the spec's 9600 first, then the
 * fast bauds it offers (cfg.fast_max_baud; none by default), then the
 * DAN_DISCOVERY_NBAUDS - 1 mask bauds, each from the highest (where a
 * configured bus most likely is after a master reset) down. */
#define DAN_DISCOVERY_NBAUDS 5u

/* Fast bauds one master offers at most (the length of its list). */
#define DAN_MASTER_MAX_FAST 8u

typedef struct {
    uint32_t resp_latency_us;   /* a reply must start within this after our
                                   request left the wire plus the turnaround
                                   (default DAN_RESP_LATENCY_US) */
    uint32_t gap_us;            /* inter-byte gap (0: link default) */
    uint32_t busy_timeout_us;   /* give up waiting for an idle line (default 200 ms) */
    uint32_t settle_us;         /* pause after a baud switch (default 2 ms) */
    uint8_t retries;            /* extra attempts per transaction (default 2) */
    uint8_t discovery_attempts; /* attempts per type per baud when probing (default 2) */
    uint8_t lbt_chars;          /* idle characters before talking (default DAN_LBT_CHARS, min 2) */
    bool scan_all_bauds;        /* probe types missing at 9600 at the other bauds (default true) */
    uint32_t seed;              /* backoff jitter seed (any value; default 1) */
    /* Fast bauds (docs/PROTOCOL.md section 6): configure(0) offers the ones
     * up to fast_max_baud (and port.max_baud), highest first, before the
     * best mask baud; discovery and recovery scan them. 0 (the default):
     * none, the v1 behaviour. */
    uint32_t fast_max_baud;
    /* the list (NULL: dan_fast_bauds); not copied. Strictly ascending,
     * every entry above 115200: the walk assumes it (an entry below its
     * predecessor is never offered, a 0 ends the list) */
    const uint32_t *fast_bauds;
    uint8_t nfast_bauds;
} dan_master_config_t;

void dan_master_config_default(dan_master_config_t *c);

/* One discovered peripheral (one type on this UART). Its whole identity
 * goes to caller-owned storage (dan_master_set_identities()); the master
 * keeps only what the sequencers need. */
typedef struct {
    uint32_t first_code; /* its type: IDENTIFY = first_code */
    uint32_t baud;       /* baud it answers at */
    uint16_t baud_mask;  /* its identity's baud mask, raw as on the wire */
    bool present;
    bool fast_refused; /* refused (or failed at) a fast baud: asked first next time */
} dan_peer_t;

typedef struct {
    uint32_t transactions; /* started */
    uint32_t ok;
    uint32_t timeouts; /* attempts that got no reply */
    uint32_t retries;
    uint32_t remote_errors; /* error frames received for our request */
    uint32_t stray;         /* frames that answered nothing we asked */
    uint32_t lbt_waits;     /* transmissions delayed by a busy line */
    uint32_t busy_failures; /* line never went idle */
    uint32_t recoveries;    /* configure verification failed and was recovered */
    uint32_t bad_replies;   /* replies refused by the reply check (retried) */
    uint32_t fast_refusals; /* CONFIGURE to a fast baud refused (ACK-FAIL, error frame) */
    uint32_t moved_back;    /* peers moved back after another peer refused */
} dan_master_stats_t;

/* An optional check of a reply's payload beyond the frame CRC (e.g. the
 * gateway's seal): return DAN_OK to accept; anything else makes the
 * attempt fail and the transaction retry, as for a collision. */
typedef int (*dan_reply_check_fn)(void *user, uint32_t code, const uint8_t *payload, size_t len);

typedef enum {
    DAN_MASTER_OP_NONE = 0,
    DAN_MASTER_OP_TXN,
    DAN_MASTER_OP_DISCOVER,
    DAN_MASTER_OP_CONFIGURE
} dan_master_op_t;

typedef struct {
    /* Fields ordered by use, small ones first (Thumb's short loads reach
     * bytes 0..31 and words 0..124 into the struct: flash) and without
     * padding (RAM); the link and its frame buffers last. */
    /* the current operation and transaction (internal but op and ntypes) */
    dan_master_op_t op;
    uint8_t txn_phase;
    uint8_t step; /* sequencer state */
    uint8_t idx;  /* type index */
    uint8_t bidx; /* scan baud index */
    uint8_t attempts_left;
    uint8_t attempt; /* attempts made, for the backoff */
    bool lbt_counted;
    bool done;
    bool cfg_auto; /* configure(0): fall back to the best mask baud */
    /* configure's candidates (the fast bauds, highest first, or the one
     * fast baud the caller named): number cidx is being tried; ntried of
     * them were (recovery scans them) */
    uint8_t ncand, cidx, ntried;
    uint8_t pass;  /* 0: peers that refused before, 1: the others */
    uint8_t moved; /* bit i: peers[i] acknowledged the candidate */
    uint8_t ntypes;
    uint32_t req_code; /* the request itself waits in link.tx */
    /* times: the low 32 bits of now_us (see dan/link.h) */
    uint32_t wait_until_us; /* not before: backoff or settle after a baud switch */
    uint32_t deadline_us;   /* the reply must have started by then */
    uint32_t busy_since_us;
    int txn_result;
    int result;
    uint32_t target_baud;
    uint32_t named_baud;
    int fast_error; /* why the last candidate was refused */
    uint32_t rng;

    /* The response of the last transaction: its payload is kept in the
     * link's TX buffer (half duplex: the request is no longer needed once
     * its reply is in, and the next request is encoded only when the next
     * transaction starts). resp == link.tx (set by dan_master_init; do not
     * copy a dan_master_t); valid after a transaction completes, until the
     * next call that starts one. After DAN_ERR_REMOTE it is the error
     * frame's payload (resp_code DAN_CODE_ERROR): dan_master_remote_error(). */
    uint32_t resp_code;
    uint8_t *resp;
    size_t resp_len;
    dan_reply_check_fn reply_check;
    void *reply_check_user;

    dan_master_config_t cfg;
    dan_peer_t peers[DAN_MASTER_MAX_TYPES];   /* one slot per type, in types' order */
    uint32_t back_baud[DAN_MASTER_MAX_TYPES]; /* where a moved peer was */
    /* where discovery reports identities (dan_master_set_identities()) */
    dan_identity_t *ids;
    size_t nids;
    int (*id_decode)(dan_identity_t *id, const uint8_t *p, size_t len);
    dan_master_stats_t stats;
    dan_link_t link;
} dan_master_t;

/* types: the first code of each peripheral type to probe (e.g.
 * DAN_TYPE_CAN_GW_FIRST); copied. baud: the port's current baud (9600 at
 * power-up). cfg may be NULL for defaults. */
int dan_master_init(dan_master_t *m, const dan_port_t *port, const dan_master_config_t *cfg,
                    const uint32_t *types, size_t ntypes, uint32_t baud, uint64_t now_us);

/* Received bytes, as they come (any count). */
void dan_master_rx(dan_master_t *m, const uint8_t *data, size_t len, uint64_t now_us);

/* Advances the engine. Returns 1 once when the current operation has just
 * completed (see dan_master_result()), else 0. */
int dan_master_poll(dan_master_t *m, uint64_t now_us);

/* Earliest time the engine needs a poll: at the latest DAN_LINK_IDLE_POLL_US
 * (8.9 minutes) after the last call when nothing is going on. */
uint64_t dan_master_next_us(const dan_master_t *m);

/* True while an operation runs. */
bool dan_master_busy(const dan_master_t *m);

/* Result of the last completed operation: DAN_OK or a negative error. */
int dan_master_result(const dan_master_t *m);

/* Starts a transaction: sends code with payload, waits for the reply with
 * the same code (or an error frame for it), retrying per cfg.retries on
 * timeouts and collisions. The reply is in m->resp / m->resp_len (in the
 * TX buffer: valid until the next transaction, discovery or configure
 * starts). Needs the
 * bus at the peer's baud (after discovery/configure). DAN_ERR_BUSY if an
 * operation runs. */
int dan_master_request(dan_master_t *m, uint32_t code, const uint8_t *payload, size_t len,
                       uint64_t now_us);

/* Starts discovery: probes IDENTIFY of every type at 9600, then (if
 * cfg.scan_all_bauds) the types still missing at the other discovery bauds.
 * Result DAN_OK if at least one peer answered, else DAN_ERR_NOTFOUND. */
int dan_master_discover(dan_master_t *m, uint64_t now_us);

/* Starts configure: moves every present peer to baud, switches the port,
 * and verifies each peer at the new baud. baud 0: the fast bauds of
 * cfg.fast_max_baud from the highest down (a refusal moves the peers that
 * had moved back; the next one is tried), then the highest mask baud that
 * every peer and the port support. A baud outside the v1 mask is tried
 * as one fast candidate (refused: DAN_ERR_NACK or DAN_ERR_REMOTE, the bus
 * as before). If a verification fails, it recovers to a working baud
 * (9600; in auto mode it then goes on with the mask baud) and the result
 * tells what failed. */
int dan_master_configure(dan_master_t *m, uint32_t baud, uint64_t now_us);

/* Where discovery reports the identity of each peer that answers: ids[i]
 * for types[i] of dan_master_init() (i < n; the others are not kept),
 * written when its IDENTIFY reply is in. Caller-owned; it must stay valid
 * while the master runs. NULL: none kept (the default; the master itself
 * keeps only each peer's baud mask). The identity decoder is linked only
 * into programs that call this. */
void dan_master_set_identities(dan_master_t *m, dan_identity_t *ids, size_t n);

/* The identity reported for a present peer of a type (by its first code),
 * or NULL (not present, or not kept). */
const dan_identity_t *dan_master_identity(const dan_master_t *m, uint32_t first_code);

/* The error frame that refused the last transaction (its result was
 * DAN_ERR_REMOTE), decoded into e: DAN_OK, or DAN_ERR_NOTFOUND if there is
 * none (valid until the next transaction starts, as m->resp). */
int dan_master_remote_error(const dan_master_t *m, dan_error_msg_t *e);

/* Installs a reply check (NULL: none). */
void dan_master_set_reply_check(dan_master_t *m, dan_reply_check_fn fn, void *user);

/* The highest baud every present peer and the port support (9600 if none). */
uint32_t dan_master_best_baud(const dan_master_t *m);

/* The peer of a type (by its first code), or NULL if not present. */
const dan_peer_t *dan_master_peer(const dan_master_t *m, uint32_t first_code);

/* Current bus baud. */
static inline uint32_t dan_master_baud(const dan_master_t *m)
{
    return m->link.baud;
}

#ifdef __cplusplus
}
#endif

#endif /* DAN_MASTER_H */
