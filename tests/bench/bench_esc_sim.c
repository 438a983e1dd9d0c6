/* ESC loops in simulated time for `make bench`: the real master engine and
 * gateway client on one side, the real peripheral engine and gateway node
 * on the other, joined by the unit tests' simulated single wire
 * (tests/unit/simbus.c, echo on, 1 us steps) at the baud under test, set
 * directly on both engines (no negotiation). The FC starts the next
 * exchange as soon as the last one completes, so the rate is what the
 * engines and the bytes allow. Behind the gateway every ESC sends
 * esc.Status every 10 ms (CAN frames into the node).
 *
 * Per row: exchanges/s in simulated time, the bound of the same bytes with
 * the mandatory gaps (every exchange: (request + response + 2 C turnaround
 * + 3 C listen-before-talk) x C, C = dan_char_us(baud), the rounded-up
 * character time of section 6), and the telemetry records each ESC got
 * per second. Modes: cmd (ESC_CMD, a record every exchange), fast
 * (ESC_FAST), fast_t/N (ESC_FAST_T every N-th exchange, the others
 * ESC_FAST).
 *
 *   bench_esc_sim [seconds]        one JSON line per row on stdout
 *   bench_esc_sim ESCS BAUD N [seconds]   one row (N: 0 cmd, -1 fast, N >= 1)
 * Exit 1 if an exchange failed. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_escs.h"
#include "dan/codes.h"
#include "dan/frame.h"
#include "dan/can_gw/client.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/node.h"
#include "simbus.h"

#define MODE_CMD  0
#define MODE_FAST (-1)

typedef struct {
    unsigned escs;
    uint32_t baud;
    int every; /* MODE_CMD, MODE_FAST or N >= 1 */
    double seconds;
    /* results */
    uint32_t exchanges, failed, records[DAN_GW_MAX_ESC], fresh[DAN_GW_MAX_ESC];
    uint64_t wire_chars; /* request + response + 5 gap characters, summed */
    double sim_seconds;
} row_t;

static simbus_t bus;
static dan_master_t m;
static dan_periph_t p;
static dan_gw_t gw;
static dan_gw_node_t node;
static dan_ptype_t pt;
static uint8_t tids[32];

/* esc.Status from ESC idx (node 20 + idx) into the gateway as CAN frames. */
static void esc_status_in(unsigned idx, uint64_t now)
{
    dan_can_frame_t fr[8];
    int k = bench_esc_status((uint8_t)idx, (uint8_t)(tids[idx]++ % 32u), fr), i;
    for (i = 0; i < k; i++) {
        dan_gw_node_rx_can(&node, &fr[i], now);
    }
}

static void setup(uint32_t baud)
{
    static const uint32_t types[] = {DAN_TYPE_CAN_GW_FIRST};
    dan_master_config_t mc;
    sim_init(&bus, 1);
    dan_master_config_default(&mc);
    sim_add_master(&bus, &m, baud, true);
    sim_add_periph(&bus, &p, baud, true);
    (void)dan_master_init(&m, &bus.nodes[0].port, &mc, types, 1, baud, bus.now);
    (void)dan_gw_node_init(&node, NULL, bus.now);
    dan_gw_node_ptype(&node, &pt);
    (void)dan_periph_init(&p, &bus.nodes[1].port, &pt, 1, NULL, baud, bus.now);
    dan_gw_node_attach(&node, &p);
    dan_gw_node_can_state(&node, true);
    dan_gw_init(&gw, &m);
    memset(tids, 0, sizeof tids);
}

static int start(const row_t *r, uint32_t i, uint32_t *code)
{
    int16_t v[DAN_GW_ESC_MAX];
    unsigned k;
    for (k = 0; k < r->escs; k++) {
        v[k] = (int16_t)((i * 7u + k * 1000u) % 8000u);
    }
    if (r->every == MODE_CMD) {
        *code = DAN_GW_CODE_ESC_CMD;
        return dan_gw_esc_command(&gw, v, r->escs, bus.now);
    }
    *code = r->every >= 1 && i % (uint32_t)r->every == 0u ? DAN_GW_CODE_ESC_FAST_T
                                                          : DAN_GW_CODE_ESC_FAST;
    return dan_gw_esc_fast(&gw, v, r->escs, *code == DAN_GW_CODE_ESC_FAST_T, bus.now);
}

/* One step of everything: the wire and both engines (sim_step), the
 * node's timers and its CAN output drained, the ESCs' telemetry. */
static void step(const row_t *r, uint64_t *next_status)
{
    dan_can_frame_t f;
    unsigned k;
    sim_step(&bus);
    dan_gw_node_poll(&node, bus.now);
    while (dan_gw_node_tx_peek(&node, &f)) {
        dan_gw_node_tx_pop(&node);
    }
    if (bus.now >= *next_status) {
        for (k = 0; k < r->escs; k++) {
            esc_status_in(k, bus.now);
        }
        *next_status += 10000u;
    }
}

static void run(row_t *r)
{
    uint64_t t0, end, next_status;
    uint32_t code = 0;
    bool busy = false;
    setup(r->baud);
    next_status = bus.now;
    t0 = bus.now;
    end = t0 + (uint64_t)(r->seconds * 1e6);
    while (bus.now < end || busy) {
        if (!busy) {
            if (start(r, r->exchanges + r->failed, &code) != DAN_OK) {
                r->failed++;
                break;
            }
            busy = true;
        }
        step(r, &next_status);
        if (busy && !dan_master_busy(&m)) {
            (void)dan_gw_complete(&gw, bus.now);
            busy = false;
            if (gw.result != DAN_OK) {
                r->failed++;
                continue;
            }
            r->exchanges++;
            r->wire_chars += m.link.tx_len + dan_frame_size(code, m.resp_len) + 5u;
            if (gw.last_telem < DAN_GW_MAX_ESC) {
                r->records[gw.last_telem]++;
                r->fresh[gw.last_telem] += code != DAN_GW_CODE_ESC_CMD && gw.telem_fresh;
            }
        }
    }
    r->sim_seconds = (double)(bus.now - t0) / 1e6;
}

static void print_row(const row_t *r)
{
    double rate = r->exchanges / r->sim_seconds;
    double bound = r->exchanges / ((double)r->wire_chars * dan_char_us(r->baud) / 1e6);
    uint32_t lo = UINT32_MAX, lo_fresh = UINT32_MAX;
    unsigned k;
    for (k = 0; k < r->escs; k++) {
        lo = r->records[k] < lo ? r->records[k] : lo;
        lo_fresh = r->fresh[k] < lo_fresh ? r->fresh[k] : lo_fresh;
    }
    printf("{\"escs\": %u, \"baud\": %lu, \"mode\": \"%s\", \"every\": %d, \"exchanges\": %lu, "
           "\"failed\": %lu, \"sim_seconds\": %.6f, \"rate\": %.2f, \"bound\": %.2f, "
           "\"ratio\": %.4f, \"bytes_per_exchange\": %.2f, \"telem_hz_min\": %.2f, "
           "\"fresh_hz_min\": %.2f}\n",
           r->escs, (unsigned long)r->baud,
           r->every == MODE_CMD    ? "cmd"
           : r->every == MODE_FAST ? "fast"
                                   : "fast_t",
           r->every, (unsigned long)r->exchanges, (unsigned long)r->failed, r->sim_seconds, rate,
           bound, rate / bound, (double)r->wire_chars / r->exchanges - 5.0, lo / r->sim_seconds,
           lo_fresh / r->sim_seconds);
    fflush(stdout);
}

/* The bound of one exchange in characters for n ESCs. */
static unsigned chars_of(unsigned n, uint32_t rsp_code, size_t rsp_inner)
{
    return (unsigned)(dan_frame_size(DAN_GW_CODE_ESC_FAST, DAN_GW_ESC_FAST_SIZE(n) + 2u) +
                      dan_frame_size(rsp_code, rsp_inner + 2u) + 5u);
}

/* The largest N whose bound still gives every ESC a record at >= 25 Hz
 * (AM32's default telemetry rate); 1 if none does. */
static int pick_every(unsigned escs, uint32_t baud)
{
    double c_us = dan_char_us(baud);
    unsigned plain = chars_of(escs, DAN_GW_CODE_ESC_FAST, 1u);
    unsigned telem = chars_of(escs, DAN_GW_CODE_ESC_FAST_T, DAN_GW_FAST_RSP_MAX);
    int n;
    for (n = 1; n < 1000; n++) {
        double cycle_us = ((double)(n - 1) * plain + telem) * c_us; /* n exchanges */
        if (1e6 / cycle_us / escs < 25.0) {
            return n > 1 ? n - 1 : 1;
        }
    }
    return n;
}

int main(int argc, char **argv)
{
    static const uint32_t bauds[] = {115200u, 1000000u, 2000000u};
    static const unsigned escs[] = {4u, 8u};
    row_t r;
    size_t b, e;
    int mode, bad = 0;
    if (argc >= 4) {
        memset(&r, 0, sizeof r);
        r.escs = (unsigned)strtoul(argv[1], NULL, 0);
        r.baud = (uint32_t)strtoul(argv[2], NULL, 0);
        r.every = atoi(argv[3]);
        r.seconds = argc > 4 ? atof(argv[4]) : 1.0;
        run(&r);
        print_row(&r);
        return r.failed ? 1 : 0;
    }
    for (e = 0; e < sizeof escs / sizeof escs[0]; e++) {
        for (b = 0; b < sizeof bauds / sizeof bauds[0]; b++) {
            for (mode = 0; mode < 4; mode++) {
                static const int fixed[] = {MODE_CMD, MODE_FAST, 0, 1};
                memset(&r, 0, sizeof r);
                r.escs = escs[e];
                r.baud = bauds[b];
                r.every = mode == 2 ? pick_every(escs[e], bauds[b]) : fixed[mode];
                if (mode == 2 && r.every == 1) {
                    continue; /* the every-exchange row below */
                }
                r.seconds = argc > 1 ? atof(argv[1]) : 1.0;
                run(&r);
                print_row(&r);
                bad |= r.failed != 0u;
            }
        }
    }
    return bad;
}
