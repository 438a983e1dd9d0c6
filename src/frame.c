/* DAN v1 frame encoder and resynchronising streaming decoder. */
#include <stddef.h>
#include <string.h>

#include "dan/frame.h"

size_t dan_frame_size(uint32_t code, size_t len)
{
    return 1u + dan_uvarint_size(code) + dan_uvarint_size((uint32_t)len) + len + 1u;
}

int dan_frame_encode(uint32_t code, const uint8_t *payload, size_t len, uint8_t *out, size_t cap)
{
    size_t n, pos;
    if (len > DAN_MAX_PAYLOAD || (payload == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    /* dan_frame_size's sum, not a call: one frame less on the deepest stack
     * path (the master's poll sends from inside its sequencer) */
    n = 2u + dan_uvarint_size(code) + dan_uvarint_size((uint32_t)len) + len;
    if (out == NULL) {
        return (int)n;
    }
    if (cap < n) {
        return DAN_ERR_OVERFLOW;
    }
    out[0] = DAN_SYNC;
    pos = 1;
    pos += dan_uvarint_put(code, out + pos); /* cap >= n: they fit */
    pos += dan_uvarint_put((uint32_t)len, out + pos);
    if (len > 0u) {
        memcpy(out + pos, payload, len);
    }
    pos += len;
    out[pos] = dan_crc8(0, out + 1, pos - 1u);
    return (int)n;
}

/*
 * Decoder state: buf[0..len) holds buffered bytes; buf[0..scanned) is the
 * candidate frame examined so far (buf[0] is its sync byte); bytes in
 * buf[scanned..len) are left over from a rejected candidate and are fed
 * again before new input. need is the candidate's total length once its
 * header has been read, else 0. buf[0..guard) are bytes of rejected
 * candidates (see examine()).
 */

void dan_decoder_init(dan_decoder_t *d)
{
    memset(d, 0, sizeof *d);
}

void dan_decoder_reset(dan_decoder_t *d)
{
    memset(d, 0, offsetof(dan_decoder_t, stats)); /* the counters (and the buffer) stay */
}

/* Drops buf[0..n) and any non-sync bytes after it; returns bytes skipped
 * after the first n. Leaves the rest pending (scanned = 0). */
static size_t drop_front(dan_decoder_t *d, size_t n)
{
    size_t k = n;
    while (k < d->len && d->buf[k] != DAN_SYNC) {
        k++;
    }
    d->len -= k;
    if (d->len > 0u) {
        memmove(d->buf, d->buf + k, d->len);
    }
    d->guard = (d->guard > k) ? d->guard - k : 0u;
    d->scanned = 0;
    d->need = 0;
    return k - n;
}

/* Rejects the candidate at buf[0]: the bytes after its sync are rescanned. */
static void reject(dan_decoder_t *d, uint32_t *counter)
{
    (*counter)++;
    if (d->guard < d->scanned) {
        d->guard = d->scanned;
    }
    (void)drop_front(d, 1);
}

/* Examines the candidate buf[0..scanned). Returns 1 when it is a complete,
 * valid frame (filled into *f), 0 when more bytes are needed, -1 when it
 * was rejected. */
static int examine(dan_decoder_t *d, dan_frame_t *f)
{
    size_t n = d->scanned;
    if (d->need == 0u) {
        uint32_t code, plen;
        int nc, nl;
        size_t total;
        nc = dan_uvarint_decode(d->buf + 1, n - 1u, &code);
        if (nc == 0) {
            return 0;
        }
        if (nc < 0) {
            reject(d, &d->stats.bad_varint);
            return -1;
        }
        nl = dan_uvarint_decode(d->buf + 1 + nc, n - 1u - (size_t)nc, &plen);
        if (nl == 0) {
            return 0;
        }
        if (nl < 0) {
            reject(d, &d->stats.bad_varint);
            return -1;
        }
        total = 1u + (size_t)nc + (size_t)nl + (size_t)plen + 1u;
        /* Also bounds non-minimal length encodings to the buffer. */
        if (plen > DAN_MAX_PAYLOAD || total > sizeof d->buf) {
            reject(d, &d->stats.oversize);
            return -1;
        }
        d->need = total;
        d->hdr = (uint8_t)(1 + nc + nl);
        d->code = code;
    }
    if (n < d->need) {
        return 0;
    }
    if (dan_crc8(0, d->buf + 1, n - 2u) != d->buf[n - 1u]) {
        reject(d, &d->stats.crc_errors);
        return -1;
    }
    /* A candidate found inside the bytes of a rejected one, and ending
     * inside them, passed an 8-bit CRC by chance as often as not: accept it
     * only if another frame starts right after it (buf[n] is buffered). */
    if (n < d->guard && d->buf[n] != DAN_SYNC) {
        reject(d, &d->stats.crc_errors);
        return -1;
    }
    d->stats.frames++;
    f->code = d->code;
    f->payload = d->buf + d->hdr;
    f->len = d->need - d->hdr - 1u;
    d->consume = d->need;
    return 1;
}

int dan_decoder_feed(dan_decoder_t *d, const uint8_t *data, size_t len, size_t *consumed,
                     dan_frame_t *frame)
{
    size_t used = 0;
    if (d->consume > 0u) {
        d->stats.garbage += (uint32_t)drop_front(d, d->consume);
        d->consume = 0;
    }
    for (;;) {
        if (d->scanned < d->len) {
            /* A pending byte from a rescan. */
            d->scanned++;
        } else if (used < len) {
            size_t take = 1;
            if (d->len == 0u) {
                /* Hunting for a sync byte. */
                const uint8_t *s = memchr(data + used, DAN_SYNC, len - used);
                if (s == NULL) {
                    d->stats.garbage += (uint32_t)(len - used);
                    used = len;
                    continue;
                }
                d->stats.garbage += (uint32_t)(s - (data + used));
                used = (size_t)(s - data);
            } else if (d->need > d->len) {
                /* Payload bytes: copy as many as the frame still needs. */
                take = d->need - d->len;
                if (take > len - used) {
                    take = len - used;
                }
            }
            memcpy(d->buf + d->len, data + used, take);
            d->len += take;
            d->scanned = d->len;
            used += take;
        } else {
            *consumed = used;
            return 0;
        }
        if (d->scanned >= 2u) {
            int r = examine(d, frame);
            if (r > 0) {
                *consumed = used;
                return 1;
            }
        }
    }
}

/* True if buf[k..len) is exactly one complete, valid frame. */
static bool whole_frame_at(const dan_decoder_t *d, size_t k)
{
    const uint8_t *p = d->buf + k;
    size_t n = d->len - k;
    uint32_t code, plen;
    int nc, nl;
    if (n < 4u || p[0] != DAN_SYNC) {
        return false;
    }
    nc = dan_uvarint_decode(p + 1, n - 1u, &code);
    if (nc <= 0) {
        return false;
    }
    nl = dan_uvarint_decode(p + 1 + nc, n - 1u - (size_t)nc, &plen);
    if (nl <= 0 || plen > DAN_MAX_PAYLOAD ||
        1u + (size_t)nc + (size_t)nl + (size_t)plen + 1u != n) {
        return false;
    }
    return dan_crc8(0, p + 1, n - 2u) == p[n - 1u];
}

void dan_decoder_abort(dan_decoder_t *d)
{
    size_t k;
    if (d->consume > 0u) {
        d->stats.garbage += (uint32_t)drop_front(d, d->consume);
        d->consume = 0;
    }
    if (d->len == 0u) {
        return;
    }
    d->stats.aborted++;
    /* The line went idle: a frame sent just before the gap ends at the last
     * byte received. Only such a frame is kept; shorter candidates inside
     * the aborted bytes would be accepted on an 8-bit CRC alone. */
    for (k = 1; k < d->len; k++) {
        if (whole_frame_at(d, k)) {
            (void)drop_front(d, k);
            return; /* returned by the next dan_decoder_feed() */
        }
    }
    d->len = 0;
    d->scanned = 0;
    d->need = 0;
    d->guard = 0;
}
