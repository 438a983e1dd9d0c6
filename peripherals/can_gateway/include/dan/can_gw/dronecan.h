/*
 * DroneCAN (UAVCAN v0) transport for the CAN-over-DAN gateway node.
 *
 * Written from the protocol description, not from libcanard; the API is
 * libcanard-like: caller-owned instance structs are passed first, time is
 * passed in as a monotonic microsecond count (nothing here reads a clock),
 * errors are negative DAN_ERR_* codes, and the receiver keeps counters
 * instead of logging. No allocation, no global mutable state.
 *
 * Contents:
 *   - 29-bit CAN ID and tail byte layout (DAN_DC_ID_*, DAN_DC_TAIL_*)
 *   - TX: a transfer split into CAN frames (dan_dc_tx_frame / dan_dc_tx_build)
 *   - TX transfer-ID bookkeeping (dan_dc_tid_table_t)
 *   - RX: reassembly with fixed session slots (dan_dc_rx_t)
 *   - transfer CRC (CRC-16-CCITT-FALSE seeded with the type signature)
 *
 * Serialization is separate, as in libcanard: bit packing in dsdl_bits.h,
 * message codecs in dsdl.h.
 */
#ifndef DAN_DRONECAN_H
#define DAN_DRONECAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/can_gw/can.h"
#include "dan/can_gw/dronecan_limits.h"
#include "dan/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Sizes (DAN_DC_RX_SESSIONS, DAN_DC_MAX_TRANSFER, DAN_DC_TX_TIDS) are
 * settings in dan/config.h. */
#if DAN_DC_MAX_TRANSFER < 7u || DAN_DC_MAX_TRANSFER > 65535u
#error "DAN_DC_MAX_TRANSFER must be within 7..65535"
#endif

/* ---- protocol constants ---- */

#define DAN_DC_PRIORITY_MAX     31u /* 0 is the most urgent */
#define DAN_DC_PRIORITY_HIGH    8u
#define DAN_DC_PRIORITY_MEDIUM  16u
#define DAN_DC_PRIORITY_LOW     24u
#define DAN_DC_TRANSFER_ID_MASK 0x1Fu /* transfer IDs count modulo 32 */

/* A receiver drops a partial transfer, and forgets the last transfer ID of a
 * session, after this long without the transfer completing (DroneCAN's
 * transfer timeout, measured from the transfer's first frame). */
#define DAN_DC_TRANSFER_TIMEOUT_US 2000000u

/* Transfer CRC (multi-frame only) and frame payload sizes. */
#define DAN_DC_FRAME_DATA_MAX 7u /* CAN bytes minus the tail byte */

/* 29-bit ID layout. Message: prio<<24 | dtid16<<8 | 0<<7 | src.
 * Anonymous message (src 0): prio<<24 | discriminator14<<10 | dtid2<<8.
 * Service: prio<<24 | dtid8<<16 | request<<15 | dst<<8 | 1<<7 | src. */
#define DAN_DC_ID_PRIORITY_SHIFT  24u
#define DAN_DC_ID_SERVICE         0x80u
#define DAN_DC_ID_REQUEST         0x8000u
#define DAN_DC_ID_ANON_DISC_SHIFT 10u
#define DAN_DC_ID_ANON_DISC_MASK  0x3FFFu
#define DAN_DC_ID_ANON_DTID_MASK  0x3u

/* Tail byte, the last data byte of every frame. */
#define DAN_DC_TAIL_SOT    0x80u /* start of transfer */
#define DAN_DC_TAIL_EOT    0x40u /* end of transfer */
#define DAN_DC_TAIL_TOGGLE 0x20u /* alternates, 0 on the first frame */

typedef enum {
    DAN_DC_TRANSFER_BROADCAST = 0, /* message */
    DAN_DC_TRANSFER_RESPONSE = 1,  /* service response */
    DAN_DC_TRANSFER_REQUEST = 2    /* service request */
} dan_dc_transfer_type_t;

/* One transfer, for TX (filled by the caller) and RX (filled by
 * dan_dc_rx_frame). */
typedef struct {
    uint64_t timestamp_us;  /* RX: now_us of the first frame; TX: unused */
    uint64_t signature;     /* data type signature: multi-frame CRC seed */
    const uint8_t *payload; /* serialized DSDL, no transfer CRC */
    size_t payload_len;
    uint16_t data_type_id;    /* messages 0..65535, services 0..255,
                                 anonymous messages 0..3 (2 low bits) */
    uint16_t discriminator;   /* anonymous messages only (14 bits); RX fills
                                 it, TX derives it from the payload */
    uint8_t transfer_type;    /* dan_dc_transfer_type_t */
    uint8_t priority;         /* 0..31 */
    uint8_t source_node;      /* 1..127; 0 = anonymous message */
    uint8_t destination_node; /* services: 1..127; messages: 0 (broadcast) */
    uint8_t transfer_id;      /* 0..31 */
} dan_dc_transfer_t;

/* Starts a TX transfer: data type, signature, type and payload set, every
 * other field 0 (the caller sets priority, nodes and transfer ID). */
void dan_dc_transfer_init(dan_dc_transfer_t *t, uint16_t data_type_id, uint64_t signature,
                          dan_dc_transfer_type_t type, const uint8_t *payload, size_t len);

/* ---- CAN ID and tail byte ---- */

/* The 29-bit CAN ID of a transfer. Returns DAN_ERR_ARG for fields out of
 * range (priority > 31, node IDs, a service DTID > 255, an anonymous DTID
 * > 3, a service with destination 0 or source 0). */
int dan_dc_make_id(const dan_dc_transfer_t *t, uint32_t *id);

/* Parses a 29-bit ID into t's data_type_id, discriminator, transfer_type,
 * priority, source_node and destination_node (0 for messages). Returns
 * DAN_ERR_MALFORMED for a service frame from node 0 or to node 0. */
int dan_dc_parse_id(uint32_t id, dan_dc_transfer_t *t);

static inline uint8_t dan_dc_tail(bool sot, bool eot, bool toggle, uint8_t tid)
{
    return (uint8_t)((sot ? DAN_DC_TAIL_SOT : 0u) | (eot ? DAN_DC_TAIL_EOT : 0u) |
                     (toggle ? DAN_DC_TAIL_TOGGLE : 0u) | (tid & DAN_DC_TRANSFER_ID_MASK));
}

/* ---- transfer CRC: CRC-16-CCITT-FALSE (poly 0x1021, init 0xFFFF) ---- */

#define DAN_DC_CRC_INIT 0xFFFFu

uint16_t dan_dc_crc16(uint16_t crc, const uint8_t *data, size_t len);
/* The CRC state after the 8 little-endian signature bytes: the seed of a
 * multi-frame transfer's CRC, which then covers the payload. */
uint16_t dan_dc_crc16_signature(uint64_t signature);
/* Transfer CRC of a payload as sent in the first two bytes (LE) of a
 * multi-frame transfer. */
uint16_t dan_dc_transfer_crc(uint64_t signature, const uint8_t *payload, size_t len);

/* ---- TX ---- */

/* Frames a payload of len bytes takes: 1 if len <= 7, else
 * ceil((len + 2) / 7). */
size_t dan_dc_tx_frame_count(size_t payload_len);

/* Builds frame number index (0-based) of transfer t into *out. crc is the
 * transfer CRC (dan_dc_transfer_crc; ignored for single-frame transfers):
 * computing it once lets a caller stream frames into a hardware queue one at
 * a time without a frame array. Returns DAN_OK, DAN_ERR_ARG (bad fields,
 * index beyond the last frame, anonymous transfer longer than 7 bytes). */
int dan_dc_tx_frame(const dan_dc_transfer_t *t, uint16_t crc, size_t index, dan_can_frame_t *out);

/* Splits transfer t into frames[0..cap). Returns the frame count, or
 * DAN_ERR_ARG (bad fields) or DAN_ERR_OVERFLOW (cap too small; nothing
 * useful is written). Frames are extended (DAN_CAN_EXT); the first frame of
 * a multi-frame transfer starts with the CRC, low byte first; toggle starts
 * at 0. An anonymous message gets discriminator = CRC-16 of its payload
 * (low 14 bits), which the DroneCAN spec allows (any value that differs
 * between nodes sending different payloads). */
int dan_dc_tx_build(const dan_dc_transfer_t *t, dan_can_frame_t *frames, size_t cap);

/* Transfer-ID counters of outgoing messages and requests, one per (data type,
 * transfer type, destination). Responses reuse the request's transfer ID and
 * need no entry. When the table is full, request flows give way in turn
 * (broadcast flows never do). Zero-initialize or dan_dc_tid_table_init. */
typedef struct {
    uint32_t key[DAN_DC_TX_TIDS]; /* 0 = unused; else key built internally */
    uint8_t next[DAN_DC_TX_TIDS];
    uint8_t evict; /* the next request flow to give way */
} dan_dc_tid_table_t;

void dan_dc_tid_table_init(dan_dc_tid_table_t *tab);
/* Returns the transfer ID (0..31) to use for the next transfer of this flow
 * and advances the counter; DAN_ERR_OVERFLOW when the table is full of
 * broadcast flows, DAN_ERR_ARG for a bad argument. */
int dan_dc_tid_next(dan_dc_tid_table_t *tab, uint16_t data_type_id, uint8_t transfer_type,
                    uint8_t destination_node);

/* ---- RX ---- */

/* Accept filter: return true to receive transfers of this data type, type
 * and source, and set *signature to the type's signature (needed to check
 * the CRC of multi-frame transfers). Called on every start frame (and on
 * single-frame transfers); must be cheap. */
typedef bool (*dan_dc_accept_fn)(void *user, uint16_t data_type_id, uint8_t transfer_type,
                                 uint8_t source_node, uint64_t *signature);

typedef struct {
    uint32_t frames;        /* frames handed to dan_dc_rx_frame */
    uint32_t transfers;     /* transfers completed and returned */
    uint32_t ignored;       /* not DroneCAN (std/RTR/error/empty), service
                               for another node, or refused by the filter */
    uint32_t crc_errors;    /* multi-frame transfer with a bad CRC */
    uint32_t toggle_errors; /* frame with the wrong toggle bit (dropped) */
    uint32_t tid_errors;    /* frame without a started transfer, with an
                               unexpected transfer ID, a repeated transfer,
                               or a new start that cut a transfer short */
    uint32_t timeouts;      /* partial transfer dropped after the timeout */
    uint32_t malformed;     /* non-final frame shorter than 8 bytes,
                               multi-frame anonymous transfer */
    uint32_t overflow;      /* transfer longer than DAN_DC_MAX_TRANSFER */
    uint32_t no_slot;       /* multi-frame start with every slot busy */
} dan_dc_rx_stats_t;

/* Reassembly state of one (data type, transfer type, source) flow. */
typedef struct {
    uint64_t ts_start_us; /* first frame of the current/last transfer */
    uint64_t signature;
    uint16_t data_type_id;
    uint16_t len; /* payload bytes so far (CRC excluded) */
    uint16_t crc; /* CRC received in the first frame */
    uint8_t transfer_type;
    uint8_t source_node; /* 0 = slot unused */
    uint8_t priority;
    uint8_t transfer_id; /* of the current/last transfer */
    uint8_t next_toggle; /* 0 or DAN_DC_TAIL_TOGGLE */
    bool in_progress;    /* a multi-frame transfer is being assembled */
    bool done;           /* transfer_id completed (duplicate filter) */
    uint8_t buf[DAN_DC_MAX_TRANSFER];
} dan_dc_rx_session_t;

/* The receiver. Caller-owned; initialize with dan_dc_rx_init. */
typedef struct {
    uint8_t local_node; /* 1..127; 0 = anonymous: services ignored */
    dan_dc_accept_fn accept;
    void *user;
    dan_dc_rx_stats_t stats;
    uint8_t single[DAN_DC_FRAME_DATA_MAX]; /* payload of the last
                                              single-frame transfer */
    dan_dc_rx_session_t sessions[DAN_DC_RX_SESSIONS];
} dan_dc_rx_t;

/* local_node may be 0 (not yet allocated) and changed later with
 * dan_dc_rx_set_node. accept must not be NULL. */
void dan_dc_rx_init(dan_dc_rx_t *rx, uint8_t local_node, dan_dc_accept_fn accept, void *user);
void dan_dc_rx_set_node(dan_dc_rx_t *rx, uint8_t local_node);

/* Feeds one received CAN frame. Returns 1 and fills *out when it completes a
 * transfer, 0 when the frame was consumed without completing one (including
 * every error case, which only bumps a counter), DAN_ERR_ARG for NULL
 * arguments. out->payload points into rx and stays valid until the next
 * call on rx. Any frame bytes are safe. Rules:
 *  - 29-bit data frames with at least the tail byte only;
 *  - services addressed to another node (or any service while local_node is
 *    0) are ignored; anonymous messages must be single-frame;
 *  - a start frame (re)starts its session's transfer, cutting short a
 *    partial one, unless it repeats the transfer ID just completed within
 *    the timeout (duplicate, dropped);
 *  - other frames must carry the session's transfer ID and expected toggle;
 *    a frame with the wrong toggle is dropped without aborting, since CAN may
 *    deliver a frame twice, and the CRC catches real losses;
 *  - frames of a multi-frame transfer other than the last carry 7 data
 *    bytes; the payload beyond DAN_DC_MAX_TRANSFER drops the transfer. */
int dan_dc_rx_frame(dan_dc_rx_t *rx, const dan_can_frame_t *frame, uint64_t now_us,
                    dan_dc_transfer_t *out);

/* Drops partial transfers and forgets sessions idle longer than the timeout
 * (counted in stats.timeouts when a transfer was in progress). Optional:
 * stale slots are also reclaimed when a new flow needs one. */
void dan_dc_rx_cleanup(dan_dc_rx_t *rx, uint64_t now_us);

#ifdef __cplusplus
}
#endif

#endif /* DAN_DRONECAN_H */
