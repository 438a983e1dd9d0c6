/* Parser cost for `make bench`: feeds a fixed mix of DAN frames through
 * dan_decoder_feed (mode "decode") or runs the crc8 loop alone over the same
 * bytes (mode "crc"). Run under callgrind with --toggle-collect=bench_run_*
 * so only the measured loop counts; the driver divides by the byte count
 * this program prints.
 *
 *   bench_parser decode|crc [REPEAT]
 * Prints one JSON line: {"mode", "bytes", "frames", "mix"}. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/dan.h"
#include "dan/can_gw/msgs.h"

static uint8_t g_stream[1u << 20];
static size_t g_len;

static void add(uint32_t code, const uint8_t *p, size_t n)
{
    int r = dan_frame_encode(code, p, n, g_stream + g_len, sizeof g_stream - g_len);
    if (r < 0) {
        fprintf(stderr, "bench_parser: stream full\n");
        exit(1);
    }
    g_len += (size_t)r;
}

/* One cycle of a typical bus: ESC command + telemetry response (the hot
 * path), an identity, a CONFIGURE/ACK pair, an error frame, a tunnel
 * transfer with a full payload, and a CAN_RECV of raw frames. */
static void build_mix(void)
{
    static const int16_t esc[4] = {0, 100, 200, 300};
    uint8_t p[DAN_MAX_PAYLOAD], big[DAN_MAX_PAYLOAD];
    size_t i;
    int n;
    n = dan_gw_msg_esc_cmd_encode(esc, 4, p, sizeof p);
    add(DAN_GW_CODE_ESC_CMD, p, (size_t)n);
    for (i = 0; i < 20; i++) {
        p[i] = (uint8_t)(i * 37u + 5u);
    }
    add(DAN_GW_CODE_ESC_CMD, p, 20); /* telemetry response: header + record */
    add(0x40, NULL, 0);              /* IDENTIFY */
    {
        dan_identity_t id;
        memset(&id, 0, sizeof id);
        id.dan_version = 1;
        strcpy(id.manufacturer, "DAN Project");
        strcpy(id.model, "CAN gateway");
        strcpy(id.hw_version, "1");
        strcpy(id.sw_version, "0.1.0");
        id.baud_mask = 0x0F;
        n = dan_identity_encode(&id, p, sizeof p);
        add(0x40, p, (size_t)n);
    }
    {
        dan_configure_t c = {DAN_CONFIGURE_BPS, 115200};
        n = dan_configure_encode(&c, p, sizeof p);
        add(0x41, p, (size_t)n);
        n = dan_ack_encode(DAN_ACK_OK, p, sizeof p);
        add(0x41, p, (size_t)n);
    }
    n = dan_error_encode(0x45, 0, "bad payload", p, sizeof p);
    add(0, p, (size_t)n);
    for (i = 0; i < sizeof big; i++) {
        big[i] = (uint8_t)(i * 131u + 7u);
    }
    add(DAN_GW_CODE_TUN_XFER, big, DAN_MAX_PAYLOAD);
    add(DAN_GW_CODE_CAN_RECV, big, 150);
}

__attribute__((noinline)) size_t bench_run_decode(const uint8_t *s, size_t len, size_t chunk)
{
    static dan_decoder_t d;
    size_t frames = 0, pos = 0;
    dan_decoder_init(&d);
    while (pos < len) {
        size_t n = len - pos < chunk ? len - pos : chunk;
        const uint8_t *p = s + pos;
        pos += n;
        for (;;) {
            size_t used;
            dan_frame_t f;
            int got = dan_decoder_feed(&d, p, n, &used, &f);
            p += used;
            n -= used;
            if (!got) {
                break;
            }
            frames++;
        }
    }
    return frames;
}

__attribute__((noinline)) unsigned bench_run_crc(const uint8_t *s, size_t len)
{
    return dan_crc8(0, s, len);
}

int main(int argc, char **argv)
{
    const char *mode = argc > 1 ? argv[1] : "decode";
    size_t repeat = argc > 2 ? (size_t)strtoul(argv[2], NULL, 0) : 200u, one, i, frames = 0;
    unsigned crc = 0;
    build_mix();
    one = g_len;
    for (i = 1; i < repeat && g_len + one <= sizeof g_stream; i++) {
        memcpy(g_stream + g_len, g_stream, one);
        g_len += one;
    }
    if (!strcmp(mode, "crc")) {
        crc = bench_run_crc(g_stream, g_len);
    } else {
        frames = bench_run_decode(g_stream, g_len, 64);
    }
    printf("{\"mode\": \"%s\", \"bytes\": %zu, \"frames\": %zu, \"mix_bytes\": %zu, \"crc\": %u}\n",
           mode, g_len, frames, one, crc);
    return 0;
}
