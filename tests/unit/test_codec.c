/* libdan core: crc8, uvarint, payload writer/reader, frame codec, common
 * payloads, the shared vectors, and randomized resync tests (fixed seed). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "dan/dan.h"
#include "vectors.h"
#include "unit_run.h"

/* ---- helpers ---- */

/* Deterministic PRNG (xorshift32) so randomized tests repeat exactly. */
static uint32_t rng_state;
static uint32_t rng(void)
{
    uint32_t x = rng_state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return rng_state = x;
}

typedef struct {
    uint8_t wire[DAN_MAX_FRAME];
    size_t len;
} raw_frame_t;

/* Feeds data in chunks of `chunk` bytes (0 = all at once), then lets the
 * line go idle (aborting partial frames). Collects re-encoded frames. */
static size_t decode_all(dan_decoder_t *d, const uint8_t *data, size_t len, size_t chunk,
                         raw_frame_t *out, size_t max)
{
    size_t n = 0, off = 0;
    dan_frame_t f;
    size_t used;
    for (;;) {
        size_t part = (chunk == 0 || len - off < chunk) ? len - off : chunk;
        const uint8_t *p = data + off;
        size_t left = part;
        for (;;) {
            int got = dan_decoder_feed(d, p, left, &used, &f);
            assert_true(used <= left);
            p += used;
            left -= used;
            if (!got) {
                break;
            }
            assert_true(n < max);
            out[n].len =
                (size_t)dan_frame_encode(f.code, f.payload, f.len, out[n].wire, sizeof out[n].wire);
            n++;
        }
        assert_int_equal(left, 0);
        off += part;
        if (off >= len) {
            break;
        }
    }
    while (dan_decoder_busy(d)) {
        dan_decoder_abort(d);
        while (dan_decoder_feed(d, NULL, 0, &used, &f)) {
            assert_true(n < max);
            out[n].len =
                (size_t)dan_frame_encode(f.code, f.payload, f.len, out[n].wire, sizeof out[n].wire);
            n++;
        }
    }
    return n;
}

/* ---- crc8 ---- */

static void test_crc8_check(void **state)
{
    (void)state;
    assert_int_equal(dan_crc8(0, (const uint8_t *)"123456789", 9), 0xBC);
    /* and the CRC-16/CCITT-FALSE check value */
    assert_int_equal(dan_crc16_ccitt(0xFFFFu, (const uint8_t *)"123456789", 9), 0x29B1);
    /* byte-at-a-time equals bulk */
    {
        const uint8_t *s = (const uint8_t *)"123456789";
        uint8_t c = 0;
        size_t i;
        for (i = 0; i < 9; i++) {
            c = dan_crc8_byte(c, s[i]);
        }
        assert_int_equal(c, 0xBC);
    }
}

/* The table against a bitwise reference for every byte value. */
static void test_crc8_table_matches_bitwise(void **state)
{
    unsigned v;
    (void)state;
    for (v = 0; v < 256; v++) {
        uint8_t c = (uint8_t)v;
        int i;
        for (i = 0; i < 8; i++) {
            c = (uint8_t)((c & 0x80u) ? (uint8_t)(c << 1) ^ 0xD5u : (uint8_t)(c << 1));
        }
        assert_int_equal(dan_crc8_byte(0, (uint8_t)v), c);
    }
}

static void crc8_row(vec_file_t *v, void *ctx)
{
    uint8_t in[512], want[1];
    char *f[2];
    size_t n;
    (void)ctx;
    assert_int_equal(vec_split(v->line, ' ', f, 2), 2);
    n = vec_hex(f[0], in, sizeof in);
    vec_hex(f[1], want, 1);
    assert_int_equal(dan_crc8(0, in, n), want[0]);
}

static void test_crc8_vectors(void **state)
{
    (void)state;
    (void)vec_each("crc8.txt", crc8_row, NULL);
}

/* ---- uvarint ---- */

static void test_uvarint_edges(void **state)
{
    static const uint32_t vals[] = {0,       1,       127,       128,       16383,      16384,
                                    2097151, 2097152, 268435455, 268435456, 0xFFFFFFFFu};
    static const size_t sizes[] = {1, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5};
    size_t i;
    (void)state;
    for (i = 0; i < sizeof vals / sizeof vals[0]; i++) {
        uint8_t b[5];
        uint32_t back = 0;
        int n = dan_uvarint_encode(vals[i], b, sizeof b);
        assert_int_equal(n, (int)sizes[i]);
        assert_int_equal(dan_uvarint_encode(vals[i], NULL, 0), n);
        assert_int_equal(dan_uvarint_size(vals[i]), sizes[i]);
        assert_int_equal(dan_uvarint_decode(b, (size_t)n, &back), n);
        assert_int_equal(back, vals[i]);
        /* every shorter prefix is truncated, not an error */
        while (--n > 0) {
            assert_int_equal(dan_uvarint_decode(b, (size_t)n, &back), 0);
        }
        /* too small an output buffer */
        assert_int_equal(dan_uvarint_encode(vals[i], b, sizes[i] - 1), DAN_ERR_OVERFLOW);
    }
    /* 128 is 80 01 and 16384 is 80 80 01 (the classic "> 0x80" bug) */
    {
        uint8_t b[5];
        assert_int_equal(dan_uvarint_encode(128, b, 5), 2);
        assert_int_equal(b[0], 0x80);
        assert_int_equal(b[1], 0x01);
        assert_int_equal(dan_uvarint_encode(16384, b, 5), 3);
        assert_int_equal(b[0], 0x80);
        assert_int_equal(b[1], 0x80);
        assert_int_equal(b[2], 0x01);
    }
}

static void uvarint_row(vec_file_t *v, void *ctx)
{
    char *f[3];
    uint8_t b[16], enc[5];
    uint32_t val = 0;
    size_t n;
    int nf = vec_split(v->line, ' ', f, 3);
    (void)ctx;
    if (strcmp(f[0], "ok") == 0) {
        unsigned long want;
        assert_int_equal(nf, 3);
        want = strtoul(f[1], NULL, 10);
        n = vec_hex(f[2], b, sizeof b);
        assert_int_equal(dan_uvarint_decode(b, n, &val), (int)n);
        assert_int_equal(val, (uint32_t)want);
        if (dan_uvarint_size((uint32_t)want) == n) {
            assert_int_equal(dan_uvarint_encode((uint32_t)want, enc, 5), (int)n);
            assert_memory_equal(enc, b, n);
        }
    } else if (strcmp(f[0], "truncated") == 0) {
        n = vec_hex(f[1], b, sizeof b);
        assert_int_equal(dan_uvarint_decode(b, n, &val), 0);
    } else if (strcmp(f[0], "malformed") == 0) {
        n = vec_hex(f[1], b, sizeof b);
        assert_int_equal(dan_uvarint_decode(b, n, &val), DAN_ERR_MALFORMED);
    } else {
        fail_msg("%s:%d: unknown kind %s", v->path, v->lineno, f[0]);
    }
}

static void test_uvarint_vectors(void **state)
{
    (void)state;
    assert_true(vec_each("uvarint.txt", uvarint_row, NULL) >= 20);
}

/* ---- writer / reader ---- */

/* The round trip's mix of every writer call (the reads below expect it). */
static void put_sample(dan_writer_t *w)
{
    dan_put_u8(w, 0xAB);
    dan_put_u16(w, 0x1234);
    dan_put_u32(w, 0xDEADBEEFu);
    dan_put_uvarint(w, 300);
    dan_put_array(w, "\x01\x02\x03", 3);
    dan_put_string(w, "hello");
    dan_put_string(w, NULL);
}

static void test_writer_reader_roundtrip(void **state)
{
    uint8_t buf[64];
    dan_writer_t w;
    dan_reader_t r;
    char s[8];
    const uint8_t *view;
    size_t vlen;
    uint8_t arr[4];
    int n;
    (void)state;

    dan_writer_init(&w, buf, sizeof buf);
    put_sample(&w);
    n = dan_writer_finish(&w);
    assert_int_equal(n, 1 + 2 + 4 + 2 + 4 + 6 + 1);
    assert_int_equal(buf[1], 0x34); /* little endian */
    assert_int_equal(buf[2], 0x12);

    /* size-only pass gives the same length */
    dan_writer_init(&w, NULL, 0);
    put_sample(&w);
    assert_int_equal(dan_writer_finish(&w), n);

    dan_reader_init(&r, buf, (size_t)n);
    assert_int_equal(dan_get_u8(&r), 0xAB);
    assert_int_equal(dan_get_u16(&r), 0x1234);
    assert_int_equal(dan_get_u32(&r), 0xDEADBEEFu);
    assert_int_equal(dan_get_uvarint(&r), 300);
    assert_int_equal(dan_get_array(&r, arr, sizeof arr), 3);
    assert_memory_equal(arr, "\x01\x02\x03", 3);
    assert_false(dan_get_string(&r, s, sizeof s));
    assert_string_equal(s, "hello");
    dan_get_array_view(&r, &view, &vlen);
    assert_int_equal(vlen, 0);
    assert_int_equal(dan_reader_remaining(&r), 0);
    assert_int_equal(dan_reader_finish(&r), DAN_OK);

    /* reading past the end: sticky error, zeros */
    assert_int_equal(dan_get_u8(&r), 0);
    assert_int_equal(dan_reader_finish(&r), DAN_ERR_MALFORMED);
    assert_int_equal(dan_get_u16(&r), 0);
}

static void test_writer_overflow_sticky(void **state)
{
    uint8_t buf[4];
    dan_writer_t w;
    (void)state;
    dan_writer_init(&w, buf, sizeof buf);
    dan_put_u16(&w, 1);
    dan_put_u16(&w, 2);
    assert_int_equal(dan_writer_finish(&w), 4);
    dan_put_u8(&w, 3); /* no room */
    dan_put_u8(&w, 4);
    assert_int_equal(dan_writer_finish(&w), DAN_ERR_OVERFLOW);
    assert_int_equal(w.len, 4);
    dan_writer_init(&w, buf, 3);
    dan_put_string(&w, "abc"); /* needs 4 */
    assert_int_equal(dan_writer_finish(&w), DAN_ERR_OVERFLOW);
}

static void test_reader_bounds(void **state)
{
    /* an array claiming more bytes than remain */
    static const uint8_t p1[] = {0x05, 'a', 'b'};
    /* a string longer than the output: truncated, fully consumed */
    static const uint8_t p2[] = {0x06, 'a', 'b', 'c', 'd', 'e', 'f', 0x07};
    /* an endless uvarint */
    static const uint8_t p3[] = {0x80, 0x80};
    dan_reader_t r;
    char s[4];
    const uint8_t *view;
    size_t n;
    uint8_t small[2];
    (void)state;

    dan_reader_init(&r, p1, sizeof p1);
    dan_get_array_view(&r, &view, &n);
    assert_null(view);
    assert_int_equal(n, 0);
    assert_int_equal(dan_reader_finish(&r), DAN_ERR_MALFORMED);

    dan_reader_init(&r, p2, sizeof p2);
    assert_true(dan_get_string(&r, s, sizeof s));
    assert_string_equal(s, "abc");
    assert_int_equal(dan_get_u8(&r), 0x07);
    assert_int_equal(dan_reader_finish(&r), DAN_OK);

    dan_reader_init(&r, p3, sizeof p3);
    assert_int_equal(dan_get_uvarint(&r), 0);
    assert_int_equal(dan_reader_finish(&r), DAN_ERR_MALFORMED);

    /* an array larger than the output buffer is an error, nothing copied */
    dan_reader_init(&r, p2, sizeof p2);
    assert_int_equal(dan_get_array(&r, small, sizeof small), 0);
    assert_int_equal(dan_reader_finish(&r), DAN_ERR_MALFORMED);

    /* empty and NULL payloads */
    dan_reader_init(&r, NULL, 10);
    assert_int_equal(dan_reader_remaining(&r), 0);
    dan_get_raw(&r, NULL, 1);
    assert_int_equal(dan_reader_finish(&r), DAN_ERR_MALFORMED);
}

/* ---- frames ---- */

static void test_frame_anchor_vectors(void **state)
{
    static const uint8_t identify[] = {0x44, 0x20, 0x00, 0xB5};
    static const uint8_t configure[] = {0x44, 0x21, 0x04, 0x00, 0x80, 0x84, 0x07, 0xDC};
    uint8_t out[16], p[8];
    dan_configure_t c;
    int n;
    (void)state;
    assert_int_equal(dan_frame_encode(0x20, NULL, 0, out, sizeof out), 4);
    assert_memory_equal(out, identify, 4);
    c.type = DAN_CONFIGURE_BPS;
    c.baud = 115200;
    n = dan_configure_encode(&c, p, sizeof p);
    assert_int_equal(n, 4);
    assert_int_equal(dan_frame_encode(0x21, p, (size_t)n, out, sizeof out), 8);
    assert_memory_equal(out, configure, 8);
}

static void test_frame_encode_limits(void **state)
{
    static uint8_t payload[DAN_MAX_PAYLOAD + 1];
    uint8_t out[DAN_MAX_FRAME];
    (void)state;
    assert_int_equal(dan_frame_encode(1, payload, DAN_MAX_PAYLOAD + 1u, out, sizeof out),
                     DAN_ERR_ARG);
    assert_int_equal(dan_frame_encode(1, NULL, 3, out, sizeof out), DAN_ERR_ARG);
    assert_int_equal(dan_frame_encode(1, payload, 3, out, 6), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_frame_encode(1, payload, 3, NULL, 0), 7);
    /* the largest frame fits DAN_MAX_FRAME */
    assert_true(dan_frame_encode(0xFFFFFFFFu, payload, DAN_MAX_PAYLOAD, out, sizeof out) ==
                (int)DAN_MAX_FRAME);
}

static void frame_row(vec_file_t *v, void *ctx)
{
    char *f[4];
    uint8_t payload[DAN_MAX_PAYLOAD], wire[DAN_MAX_FRAME], out[DAN_MAX_FRAME];
    size_t plen, wlen, used;
    unsigned long code;
    dan_decoder_t d;
    dan_frame_t fr;
    (void)ctx;
    assert_int_equal(vec_split(v->line, ' ', f, 4), 4);
    assert_string_equal(f[0], "frame");
    code = strtoul(f[1], NULL, 10);
    plen = vec_hex(f[2], payload, sizeof payload);
    wlen = vec_hex(f[3], wire, sizeof wire);
    assert_int_equal(dan_frame_encode((uint32_t)code, payload, plen, out, sizeof out), (int)wlen);
    assert_memory_equal(out, wire, wlen);
    dan_decoder_init(&d);
    assert_int_equal(dan_decoder_feed(&d, wire, wlen, &used, &fr), 1);
    assert_int_equal(used, wlen);
    assert_int_equal(fr.code, (uint32_t)code);
    assert_int_equal(fr.len, plen);
    if (plen > 0) {
        assert_memory_equal(fr.payload, payload, plen);
    }
    assert_int_equal(dan_decoder_feed(&d, NULL, 0, &used, &fr), 0);
    assert_false(dan_decoder_busy(&d));
}

static void test_frame_vectors(void **state)
{
    (void)state;
    assert_true(vec_each("frames.txt", frame_row, NULL) >= 10);
}

static void stream_row(vec_file_t *v, void *ctx)
{
    char *f[64];
    static uint8_t wire[2048];
    static raw_frame_t got[64];
    uint8_t want[DAN_MAX_FRAME];
    size_t wlen, chunk;
    int nf = vec_split(v->line, ' ', f, 64), i;
    (void)ctx;
    assert_string_equal(f[0], "stream");
    wlen = vec_hex(f[1], wire, sizeof wire);
    for (chunk = 0; chunk <= 3; chunk++) { /* whole, 1, 2 and 3 bytes a call */
        dan_decoder_t d;
        size_t n;
        dan_decoder_init(&d);
        n = decode_all(&d, wire, wlen, chunk, got, 64);
        assert_int_equal(n, (size_t)(nf - 2));
        for (i = 2; i < nf; i++) {
            size_t wl = vec_hex(f[i], want, sizeof want);
            assert_int_equal(got[i - 2].len, wl);
            assert_memory_equal(got[i - 2].wire, want, wl);
        }
    }
}

static void test_stream_vectors(void **state)
{
    (void)state;
    assert_true(vec_each("streams.txt", stream_row, NULL) >= 8);
}

/* Every single-bit flip of a valid frame is rejected: the CRC catches
 * flips in the body, and a flipped sync byte is no frame at all. (A flip in
 * the length field moves the frame boundary; docs/PROTOCOL.md gives the
 * measured residual rate for random frames.) */
static void assert_all_flips_rejected(uint8_t *wire, size_t n)
{
    size_t i, bit;
    for (i = 0; i < n; i++) {
        for (bit = 0; bit < 8; bit++) {
            dan_decoder_t d;
            raw_frame_t got[4];
            wire[i] ^= (uint8_t)(1u << bit);
            dan_decoder_init(&d);
            assert_int_equal(decode_all(&d, wire, n, 0, got, 4), 0);
            dan_decoder_init(&d);
            assert_int_equal(decode_all(&d, wire, n, 1, got, 4), 0);
            wire[i] ^= (uint8_t)(1u << bit);
        }
    }
}

static void frame_flips_row(vec_file_t *v, void *ctx)
{
    uint8_t wire[DAN_MAX_FRAME];
    char *f[4];
    (void)ctx;
    assert_int_equal(vec_split(v->line, ' ', f, 4), 4);
    assert_all_flips_rejected(wire, vec_hex(f[3], wire, sizeof wire));
}

static void test_every_bit_flip_rejected(void **state)
{
    uint8_t payload[40], wire[DAN_MAX_FRAME];
    uint32_t codes[3] = {0x21, 0x44, 16384};
    size_t i, c;
    (void)state;
    for (i = 0; i < sizeof payload; i++) {
        payload[i] = (uint8_t)(i * 37u + 5u);
    }
    for (c = 0; c < 3; c++) {
        int n = dan_frame_encode(codes[c], payload, sizeof payload, wire, sizeof wire);
        assert_true(n > 0);
        assert_all_flips_rejected(wire, (size_t)n);
    }
    (void)vec_each("frames.txt", frame_flips_row, NULL); /* and every frame vector */
}

/* Counters say what happened. */
static void test_decoder_counters(void **state)
{
    static const uint8_t good[] = {0x44, 0x20, 0x00, 0xB5};
    static const uint8_t badcrc[] = {0x44, 0x20, 0x00, 0xB6};
    static const uint8_t oversize[] = {0x44, 0x20, 0xFF, 0x7F};
    static const uint8_t badvar[] = {0x44, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F};
    dan_decoder_t d;
    raw_frame_t got[4];
    (void)state;
    dan_decoder_init(&d);
    assert_int_equal(decode_all(&d, (const uint8_t *)"xyz", 3, 0, got, 4), 0);
    assert_int_equal(d.stats.garbage, 3);
    assert_int_equal(decode_all(&d, badcrc, sizeof badcrc, 0, got, 4), 0);
    assert_int_equal(d.stats.crc_errors, 1);
    assert_int_equal(decode_all(&d, oversize, sizeof oversize, 0, got, 4), 0);
    assert_int_equal(d.stats.oversize, 1);
    assert_int_equal(decode_all(&d, badvar, sizeof badvar, 0, got, 4), 0);
    assert_int_equal(d.stats.bad_varint, 1);
    assert_int_equal(decode_all(&d, good, 3, 0, got, 4), 0); /* idle mid-frame */
    assert_int_equal(d.stats.aborted, 1);
    assert_int_equal(decode_all(&d, good, sizeof good, 1, got, 4), 1);
    assert_int_equal(d.stats.frames, 1);
}

/* Random frames with random noise between them, fed in random chunks: every
 * frame comes out, in order. Noise is made of bytes other than the sync byte
 * so it cannot swallow a frame; a second test mixes in syncs too. */
static void test_random_roundtrip_and_resync(void **state)
{
    static uint8_t stream[65536];
    static raw_frame_t sent[256], got[512];
    size_t len = 0, nsent = 0, i;
    int round;
    (void)state;
    rng_state = 0xC0FFEEu;
    for (round = 0; round < 20; round++) {
        dan_decoder_t d;
        size_t n, chunk;
        len = 0;
        nsent = 0;
        while (nsent < 200) {
            uint8_t payload[DAN_MAX_PAYLOAD];
            size_t plen = rng() % (DAN_MAX_PAYLOAD + 1u), k, noise = rng() % 8u;
            uint32_t code = rng() >> (rng() % 32u);
            for (k = 0; k < noise; k++) {
                uint8_t b = (uint8_t)rng();
                stream[len++] = (b == DAN_SYNC) ? 0 : b;
            }
            for (k = 0; k < plen; k++) {
                payload[k] = (uint8_t)rng();
            }
            sent[nsent].len = (size_t)dan_frame_encode(code, payload, plen, sent[nsent].wire,
                                                       sizeof sent[nsent].wire);
            memcpy(stream + len, sent[nsent].wire, sent[nsent].len);
            len += sent[nsent].len;
            nsent++;
            if (len > sizeof stream - 2 * DAN_MAX_FRAME) {
                break;
            }
        }
        chunk = 1u + rng() % 64u;
        dan_decoder_init(&d);
        n = decode_all(&d, stream, len, chunk, got, 512);
        /* A noise byte run may contain a stray frame start only if it holds a
         * sync; it does not, so frames come out exactly. */
        assert_int_equal(n, nsent);
        for (i = 0; i < n; i++) {
            assert_int_equal(got[i].len, sent[i].len);
            assert_memory_equal(got[i].wire, sent[i].wire, sent[i].len);
        }
    }
}

/* Noise that may contain sync bytes and corrupted frames: the decoder never
 * returns a frame that was not sent, and once the noise is followed by an
 * idle gap, the next frames are all found. */
static void test_noise_then_idle_resync(void **state)
{
    static uint8_t stream[4096];
    static raw_frame_t got[64];
    int round;
    (void)state;
    rng_state = 12345u;
    for (round = 0; round < 500; round++) {
        dan_decoder_t d;
        size_t len = 0, k, n, noise = rng() % 300u;
        uint8_t frames[3][DAN_MAX_FRAME];
        size_t flen[3];
        for (k = 0; k < noise; k++) {
            stream[k] = (uint8_t)((rng() % 4u == 0u) ? DAN_SYNC : rng());
        }
        len = noise;
        dan_decoder_init(&d);
        n = decode_all(&d, stream, len, 1u + rng() % 7u, got, 64);
        /* Random noise may form a valid frame (CRC is 8 bits); what must not
         * happen is a crash or an out-of-bounds read (ASan build). */
        (void)n;
        for (k = 0; k < 3; k++) {
            uint8_t p[8];
            size_t j;
            for (j = 0; j < sizeof p; j++) {
                p[j] = (uint8_t)rng();
            }
            flen[k] = (size_t)dan_frame_encode(0x40u + (uint32_t)k, p, sizeof p, frames[k],
                                               DAN_MAX_FRAME);
        }
        len = 0;
        for (k = 0; k < 3; k++) {
            memcpy(stream + len, frames[k], flen[k]);
            len += flen[k];
        }
        n = decode_all(&d, stream, len, 1u + rng() % 7u, got, 64);
        assert_int_equal(n, 3);
        for (k = 0; k < 3; k++) {
            assert_memory_equal(got[k].wire, frames[k], flen[k]);
        }
    }
}

/* ---- payloads ---- */

/* The payloads.txt checks: f the line's fields, want its payload bytes. */

static void identity_row(const vec_file_t *v, char **f, const uint8_t *want, size_t wl)
{
    uint8_t out[256];
    dan_identity_t id, back;
    (void)v;
    memset(&id, 0, sizeof id);
    id.dan_version = (uint8_t)atoi(f[1]);
    strcpy(id.manufacturer, f[2]);
    strcpy(id.model, f[3]);
    strcpy(id.hw_version, f[4]);
    strcpy(id.sw_version, f[5]);
    id.baud_mask = (uint16_t)strtoul(f[6], NULL, 16);
    id.capabilities = (uint16_t)strtoul(f[7], NULL, 16);
    assert_int_equal(dan_identity_encode(&id, NULL, 0), (int)wl);
    assert_int_equal(dan_identity_encode(&id, out, sizeof out), (int)wl);
    assert_memory_equal(out, want, wl);
    assert_int_equal(dan_identity_encode(&id, out, wl - 1u), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_identity_decode(&back, want, wl), DAN_OK);
    assert_int_equal(back.dan_version, id.dan_version);
    assert_string_equal(back.manufacturer, id.manufacturer);
    assert_string_equal(back.model, id.model);
    assert_string_equal(back.hw_version, id.hw_version);
    assert_string_equal(back.sw_version, id.sw_version);
    assert_int_equal(back.baud_mask, id.baud_mask);
    assert_int_equal(back.capabilities, id.capabilities);
    assert_false(back.truncated);
}

static void configure_row(const vec_file_t *v, char **f, const uint8_t *want, size_t wl)
{
    uint8_t out[256];
    dan_configure_t c, back;
    (void)v;
    c.type = (uint8_t)atoi(f[1]);
    c.baud = (uint32_t)strtoul(f[2], NULL, 10);
    assert_int_equal(dan_configure_encode(&c, out, sizeof out), (int)wl);
    assert_memory_equal(out, want, wl);
    assert_int_equal(dan_configure_decode(&back, want, wl), DAN_OK);
    assert_int_equal(back.type, c.type);
    assert_int_equal(back.baud, c.baud);
}

static void ack_row(const vec_file_t *v, char **f, const uint8_t *want, size_t wl)
{
    uint8_t out[256], a = 0xFF;
    (void)v;
    assert_int_equal(dan_ack_encode((uint8_t)atoi(f[1]), out, sizeof out), (int)wl);
    assert_memory_equal(out, want, wl);
    assert_int_equal(dan_ack_decode(&a, want, wl), DAN_OK);
    assert_int_equal(a, atoi(f[1]));
}

static void error_row(const vec_file_t *v, char **f, const uint8_t *want, size_t wl)
{
    uint8_t out[256];
    dan_error_msg_t e;
    (void)v;
    assert_int_equal(
        dan_error_encode((uint32_t)atol(f[1]), (uint32_t)atol(f[2]), f[3], out, sizeof out),
        (int)wl);
    assert_memory_equal(out, want, wl);
    assert_int_equal(dan_error_decode(&e, want, wl), DAN_OK);
    assert_int_equal(e.code, (uint32_t)atol(f[1]));
    assert_int_equal(e.error, (uint32_t)atol(f[2]));
    assert_string_equal(e.text, f[3]);
}

/* bad_<kind>: the decoder of kind refuses the payload. */
static void bad_row(const vec_file_t *v, char **f, const uint8_t *want, size_t wl)
{
    const char *kind = f[0] + 4;
    union {
        dan_identity_t id;
        dan_configure_t c;
        uint8_t a;
        dan_error_msg_t e;
    } m;
    int rc;
    if (strcmp(kind, "identity") == 0) {
        rc = dan_identity_decode(&m.id, want, wl);
    } else if (strcmp(kind, "configure") == 0) {
        rc = dan_configure_decode(&m.c, want, wl);
    } else if (strcmp(kind, "ack") == 0) {
        rc = dan_ack_decode(&m.a, want, wl);
    } else if (strcmp(kind, "error") == 0) {
        rc = dan_error_decode(&m.e, want, wl);
    } else {
        fail_msg("%s:%d: unknown kind %s", v->path, v->lineno, f[0]);
        return;
    }
    assert_int_equal(rc, DAN_ERR_MALFORMED);
}

static void unsupported_row(const vec_file_t *v, char **f, const uint8_t *want, size_t wl)
{
    dan_configure_t c;
    (void)v;
    (void)f;
    assert_int_equal(dan_configure_decode(&c, want, wl), DAN_ERR_UNSUPPORTED);
}

/* One payloads.txt line: its kind (a prefix for bad_) picks the check; nf
 * fields (0: not checked), the payload hex in field hex. */
static void payload_row(vec_file_t *v, void *ctx)
{
    static const struct {
        const char *kind;
        bool prefix;
        int nf, hex;
        void (*check)(const vec_file_t *v, char **f, const uint8_t *want, size_t wl);
    } kinds[] = {
        {"identity", false, 9, 8, identity_row},
        {"configure", false, 4, 3, configure_row},
        {"ack", false, 3, 2, ack_row},
        {"error", false, 5, 4, error_row},
        {"bad_", true, 2, 1, bad_row},
        {"unsupported_configure", false, 0, 1, unsupported_row},
    };
    char *f[10];
    uint8_t want[256];
    int nf = vec_split(v->line, '\t', f, 10);
    size_t i;
    (void)ctx;
    for (i = 0; i < sizeof kinds / sizeof kinds[0]; i++) {
        if (kinds[i].prefix ? strncmp(f[0], kinds[i].kind, strlen(kinds[i].kind)) == 0
                            : strcmp(f[0], kinds[i].kind) == 0) {
            if (kinds[i].nf != 0) {
                assert_int_equal(nf, kinds[i].nf);
            }
            kinds[i].check(v, f, want, vec_hex(f[kinds[i].hex], want, sizeof want));
            return;
        }
    }
    fail_msg("%s:%d: unknown kind %s", v->path, v->lineno, f[0]);
}

static void test_payload_vectors(void **state)
{
    (void)state;
    assert_true(vec_each("payloads.txt", payload_row, NULL) >= 20);
}

static void test_identity_truncation(void **state)
{
    uint8_t buf[DAN_MAX_PAYLOAD];
    dan_writer_t w;
    dan_identity_t id;
    char longname[DAN_MAX_STRING + 10];
    (void)state;
    memset(longname, 'x', sizeof longname - 1);
    longname[sizeof longname - 1] = '\0';
    dan_writer_init(&w, buf, sizeof buf);
    dan_put_u8(&w, 1);
    dan_put_string(&w, longname);
    dan_put_string(&w, "m");
    dan_put_string(&w, "h");
    dan_put_string(&w, "s");
    dan_put_u16(&w, 0x0008);
    dan_put_u16(&w, 0);
    dan_put_u8(&w, 0x99); /* trailing byte of a later version: ignored */
    assert_int_equal(dan_identity_decode(&id, buf, (size_t)dan_writer_finish(&w)), DAN_OK);
    assert_true(id.truncated);
    assert_int_equal(strlen(id.manufacturer), DAN_MAX_STRING - 1u);
    assert_string_equal(id.model, "m");
    assert_int_equal(id.baud_mask, 0x0008);
}

static void test_baud_mask_helpers(void **state)
{
    (void)state;
    assert_int_equal(dan_baud_of_mask_bit(DAN_BAUD_MASK_19200), 19200);
    assert_int_equal(dan_baud_of_mask_bit(DAN_BAUD_MASK_115200), 115200);
    assert_int_equal(dan_baud_of_mask_bit(0x10), 0);
    assert_int_equal(dan_mask_bit_of_baud(57600), DAN_BAUD_MASK_57600);
    assert_int_equal(dan_mask_bit_of_baud(9600), 0);
    assert_int_equal(dan_baud_highest(0), 9600);
    assert_int_equal(dan_baud_highest(0xFFF0), 9600); /* reserved bits ignored */
    assert_int_equal(dan_baud_highest(DAN_BAUD_MASK_19200 | DAN_BAUD_MASK_57600), 57600);
    assert_int_equal(dan_baud_highest(0x000F), 115200);
    assert_int_equal(dan_ack_encode(2, NULL, 0), DAN_ERR_ARG);
    assert_string_equal(dan_strerror(DAN_ERR_TIMEOUT), "timeout");
    assert_string_equal(dan_strerror(-999), "unknown error");
}

int main(void)
{
    return UNIT_RUN("codec", NULL, NULL, test_crc8_check, test_crc8_table_matches_bitwise,
                    test_crc8_vectors, test_uvarint_edges, test_uvarint_vectors,
                    test_writer_reader_roundtrip, test_writer_overflow_sticky, test_reader_bounds,
                    test_frame_anchor_vectors, test_frame_encode_limits, test_frame_vectors,
                    test_stream_vectors, test_every_bit_flip_rejected, test_decoder_counters,
                    test_random_roundtrip_and_resync, test_noise_then_idle_resync,
                    test_payload_vectors, test_identity_truncation, test_baud_mask_helpers);
}
