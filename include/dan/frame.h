/*
 * DAN v1 frame codec.
 *
 * On the wire:  'D' | uvarint code | uvarint length | payload | crc8
 * The CRC (crc8_dvb_s2) covers every byte after the sync byte.
 */
#ifndef DAN_FRAME_H
#define DAN_FRAME_H

#include "dan/common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_SYNC ((uint8_t)'D')

/* A decoded frame. payload points into the decoder's buffer and stays valid
 * until the next call into that decoder. */
typedef struct {
    uint32_t code;
    const uint8_t *payload;
    size_t len;
} dan_frame_t;

/* Encodes a frame into out (cap bytes). Returns the frame length, or
 * DAN_ERR_OVERFLOW if cap is too small, or DAN_ERR_ARG if len exceeds
 * DAN_MAX_PAYLOAD (or payload is NULL with len > 0). With out == NULL,
 * returns the encoded size without writing. */
int dan_frame_encode(uint32_t code, const uint8_t *payload, size_t len, uint8_t *out, size_t cap);

/* Size of a frame with this code and payload length (no checks). */
size_t dan_frame_size(uint32_t code, size_t len);

/* Decoder counters. They wrap around at 2^32. */
typedef struct {
    uint32_t frames;     /* valid frames returned */
    uint32_t crc_errors; /* complete frames whose CRC did not match */
    uint32_t oversize;   /* frames declaring a payload > DAN_MAX_PAYLOAD */
    uint32_t bad_varint; /* code or length uvarint overlong / overflowing */
    uint32_t garbage;    /* bytes dropped while hunting for a sync byte */
    uint32_t aborted;    /* partial frames dropped by dan_decoder_abort() */
} dan_decoder_stats_t;

/*
 * Streaming decoder with caller-owned state. Feed any number of bytes at a
 * time. After a rejected candidate (bad CRC, oversize length, bad uvarint)
 * the decoder rescans the bytes it had buffered after that candidate's sync
 * byte, so a valid frame that starts inside a rejected one is still found.
 */
typedef struct {    /* the buffer last: short loads reach the rest (flash) */
    uint8_t hdr;    /* the candidate's header length (sync, code, length) */
    size_t len;     /* bytes buffered; buf[0] == DAN_SYNC when len > 0 */
    size_t scanned; /* buffered bytes already examined as the candidate */
    size_t consume; /* length of the frame last returned, dropped on the next call */
    size_t need;    /* total length of the candidate once its header is read */
    size_t guard;   /* buffered bytes that belonged to rejected candidates */
    uint32_t code;  /* the candidate's code, once its header is read */
    dan_decoder_stats_t stats;
    uint8_t buf[DAN_MAX_FRAME];
} dan_decoder_t;

void dan_decoder_init(dan_decoder_t *d);
/* Drops everything buffered (e.g. after a baud change), keeping the counters. */
void dan_decoder_reset(dan_decoder_t *d);

/*
 * Consumes bytes from data (len bytes) until a frame is complete.
 * Returns 1 with *frame filled when a frame is ready, or 0 when every input
 * byte was consumed and no complete frame remains. *consumed is the number
 * of input bytes taken in either case. Typical use:
 *
 *     for (;;) {
 *         size_t used;
 *         int got = dan_decoder_feed(&dec, p, n, &used, &frame);
 *         p += used; n -= used;
 *         if (!got) break;
 *         handle(&frame);
 *     }
 */
int dan_decoder_feed(dan_decoder_t *d, const uint8_t *data, size_t len, size_t *consumed,
                     dan_frame_t *frame);

/* True while a partial frame is buffered (a frame has started). Inline:
 * the link asks on every poll. */
static inline bool dan_decoder_busy(const dan_decoder_t *d)
{
    return d->len > d->consume;
}

/* Call when the line has been idle while a partial frame was buffered
 * (see dan_decoder_busy()): the partial frame is dropped and counted in
 * stats.aborted. If the buffered bytes end with a whole valid frame that
 * started inside the dropped one (a stray sync byte before a real frame),
 * that frame is kept: collect it with dan_decoder_feed() (len may be 0).
 * Afterwards the decoder is no longer busy. */
void dan_decoder_abort(dan_decoder_t *d);

#ifdef __cplusplus
}
#endif

#endif /* DAN_FRAME_H */
