/* Gateway cost for `make bench`: the FC side (libdan master + gateway
 * client) and the portable gateway node (peripheral engine + node) joined by
 * an event-driven virtual wire at 115200 (no OS, virtual time), running N
 * ESC exchanges (4 channels). Each exchange also brings in one ESC's
 * esc.Status transfer from CAN (3 frames), the telemetry the next responses
 * carry. Every call on the gateway side goes through a gwside_* function
 * and every call on the FC side through an fcside_* function, so callgrind
 * can count either alone:
 *   valgrind --tool=callgrind --toggle-collect='gwside_*' bench_gateway N
 * Prints one JSON line: {"exchanges", "ok", "telemetry", "can_frames_out"}. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_escs.h"
#include "dan/codes.h"
#include "dan/can_gw/client.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/node.h"

#define BAUD 115200u

typedef struct {
    uint8_t buf[4096];
    size_t len;
    uint64_t busy_until; /* end of the last byte on the wire */
} wire_dir_t;

static uint64_t g_now = 1000000u;
static wire_dir_t to_gw, to_fc;
static dan_master_t g_m;
static dan_gw_t g_cl;
static dan_gw_node_t g_node;
static dan_periph_t g_p;
static dan_ptype_t g_t;
static uint32_t g_can_out;

static int wr(wire_dir_t *w, const uint8_t *d, size_t n)
{
    uint64_t start = w->busy_until > g_now ? w->busy_until : g_now;
    if (n > sizeof w->buf - w->len) {
        n = sizeof w->buf - w->len;
    }
    memcpy(w->buf + w->len, d, n);
    w->len += n;
    w->busy_until = start + (uint64_t)n * dan_char_us(BAUD);
    return (int)n;
}
static int fc_write(void *ctx, const uint8_t *d, size_t n)
{
    (void)ctx;
    return wr(&to_gw, d, n);
}
static int gw_write(void *ctx, const uint8_t *d, size_t n)
{
    (void)ctx;
    return wr(&to_fc, d, n);
}
static int set_baud(void *ctx, uint32_t b)
{
    (void)ctx;
    (void)b;
    return 0;
}

__attribute__((noinline)) void gwside_rx(const uint8_t *d, size_t n, uint64_t now)
{
    dan_periph_rx(&g_p, d, n, now);
}
__attribute__((noinline)) void gwside_poll(uint64_t now)
{
    dan_can_frame_t f;
    dan_periph_poll(&g_p, now);
    dan_gw_node_poll(&g_node, now);
    while (dan_gw_node_tx_peek(&g_node, &f)) { /* the CAN driver's part */
        dan_gw_node_tx_pop(&g_node);
        g_can_out++;
    }
}
__attribute__((noinline)) uint64_t gwside_next(uint64_t now)
{
    uint64_t a = dan_periph_next_us(&g_p), b = dan_gw_node_next_us(&g_node, now);
    return a < b ? a : b;
}
__attribute__((noinline)) void gwside_can(const dan_can_frame_t *f, uint64_t now)
{
    dan_gw_node_rx_can(&g_node, f, now);
}
__attribute__((noinline)) int fcside_cmd(const int16_t *v, uint64_t now)
{
    return dan_gw_esc_command(&g_cl, v, 4, now);
}
__attribute__((noinline)) void fcside_rx(const uint8_t *d, size_t n, uint64_t now)
{
    dan_master_rx(&g_m, d, n, now);
}
__attribute__((noinline)) int fcside_poll(uint64_t now)
{
    return dan_gw_poll(&g_cl, now);
}
__attribute__((noinline)) uint64_t fcside_next(void)
{
    return dan_master_next_us(&g_m);
}

/* Delivers a direction's bytes once the last one has left the wire. */
static void deliver(void)
{
    if (to_gw.len > 0u && to_gw.busy_until <= g_now) {
        gwside_rx(to_gw.buf, to_gw.len, g_now);
        to_gw.len = 0;
    }
    if (to_fc.len > 0u && to_fc.busy_until <= g_now) {
        fcside_rx(to_fc.buf, to_fc.len, g_now);
        to_fc.len = 0;
    }
}

/* One esc.Status transfer from ESC node 20 + idx, as CAN frames. */
static void esc_status_in(uint8_t idx, uint8_t tid)
{
    dan_can_frame_t fr[8];
    int k = bench_esc_status(idx, tid, fr), i;
    for (i = 0; i < k; i++) {
        gwside_can(&fr[i], g_now);
    }
}

int main(int argc, char **argv)
{
    static const uint32_t types[] = {DAN_TYPE_CAN_GW_FIRST};
    uint32_t n = argc > 1 ? (uint32_t)strtoul(argv[1], NULL, 0) : 2000u, i, ok = 0, telem = 0;
    dan_port_t fc_port, gw_port;
    dan_master_config_t mc;
    memset(&fc_port, 0, sizeof fc_port);
    fc_port.write = fc_write;
    fc_port.set_baud = set_baud;
    gw_port = fc_port;
    gw_port.write = gw_write;
    dan_master_config_default(&mc);
    dan_master_init(&g_m, &fc_port, &mc, types, 1, BAUD, g_now);
    dan_gw_init(&g_cl, &g_m);
    dan_gw_node_init(&g_node, NULL, g_now);
    dan_gw_node_ptype(&g_node, &g_t);
    dan_periph_init(&g_p, &gw_port, &g_t, 1, NULL, BAUD, g_now);
    dan_gw_node_attach(&g_node, &g_p);
    dan_gw_node_can_state(&g_node, true);
    for (i = 0; i < n; i++) {
        int16_t v[4] = {(int16_t)(i % 8000u), 100, 200, (int16_t) - (int16_t)(i % 100u)};
        uint32_t guard = 0;
        esc_status_in((uint8_t)(i % 4u), (uint8_t)((i / 4u) % 32u));
        if (fcside_cmd(v, g_now) != DAN_OK) {
            fprintf(stderr, "bench_gateway: command refused\n");
            return 1;
        }
        for (;;) {
            uint64_t next;
            deliver();
            gwside_poll(g_now);
            if (fcside_poll(g_now)) {
                break;
            }
            next = fcside_next();
            {
                uint64_t b = gwside_next(g_now);
                if (b < next) {
                    next = b;
                }
            }
            if (to_gw.len > 0u && to_gw.busy_until < next) {
                next = to_gw.busy_until;
            }
            if (to_fc.len > 0u && to_fc.busy_until < next) {
                next = to_fc.busy_until;
            }
            g_now = next > g_now ? next : g_now + 1u;
            if (++guard > 100000u) {
                fprintf(stderr, "bench_gateway: stuck\n");
                return 1;
            }
        }
        if (g_cl.result == DAN_OK) {
            ok++;
            telem += g_cl.last_telem != DAN_GW_NONE;
        }
    }
    printf("{\"exchanges\": %u, \"ok\": %u, \"telemetry\": %u, \"can_frames_out\": %u, "
           "\"virtual_seconds\": %.3f}\n",
           n, ok, telem, g_can_out, (double)(g_now - 1000000u) / 1e6);
    return ok == n ? 0 : 1;
}
