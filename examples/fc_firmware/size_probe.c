/*
 * Size probe: the smallest image that links the parts of libdan a flight
 * controller uses, so `make size` can measure them at -Os for Cortex-M4
 * (the delta over SIZE_PROBE=0, and per object from the linker map).
 *
 *   SIZE_PROBE=0  vector table and reset handler only (the baseline)
 *   SIZE_PROBE=1  + the master engine (pulls in the codec and the link)
 *   SIZE_PROBE=2  + the gateway client: ESC command (both kinds), telemetry, arm,
 *                 config, stats (what an FC's motor output needs)
 *   SIZE_PROBE=3  + the rest of the gateway client (nodes, node info,
 *                 tunnels, raw CAN, filters)
 *
 * Inputs come from volatile variables so nothing is folded away; the
 * engines' state is static (caller-owned RAM per bus, measured too).
 */
#include <stdint.h>

#if SIZE_PROBE >= 1
#include "dan/dan.h"
#endif
#if SIZE_PROBE >= 2
#include <string.h>

#include "dan/can_gw/client.h"
#endif

extern uint32_t _estack;
void Reset_Handler(void);

volatile uint32_t probe_in;
volatile uint64_t probe_time;

#if SIZE_PROBE >= 1
static int w(void *ctx, const uint8_t *d, size_t n)
{
    (void)ctx;
    probe_in = d[0];
    return (int)n;
}
static int b(void *ctx, uint32_t baud)
{
    (void)ctx;
    probe_in = baud;
    return 0;
}
static const dan_port_t port = {w, b, NULL, NULL, NULL, NULL, 0, true};
static const uint32_t types[] = {DAN_TYPE_CAN_GW_FIRST, DAN_TYPE_VTX_FIRST};
dan_master_t probe_master; /* RAM per bus: the master engine */
#endif
#if SIZE_PROBE >= 2
dan_gw_t probe_gw; /* RAM per bus: the gateway client */
#endif

#if SIZE_PROBE >= 2
/* The calls an FC's motor output needs (SIZE_PROBE=2): static and called
 * once, so -Os inlines it into the loop. */
static void probe_gw_motor(void)
{
    int16_t v[4] = {1, 2, 3, 4};
    dan_gw_config_t cfg = {0};
    /* RAM of one telemetry slot (DAN_GW_MAX_ESC), for the report: an
     * absolute symbol, no code or data */
    __asm__ volatile(
        ".global probe_esc_slot\n\t.set probe_esc_slot, %c0" ::"i"(sizeof(dan_gw_telem_t)));
    if (probe_in == 1u) {
        dan_gw_init(&probe_gw, &probe_master);
    }
    if (probe_in == 2u) {
        dan_gw_esc_command(&probe_gw, v, 4, probe_time);
    }
    if (probe_in == 20u) {
        dan_gw_esc_fast(&probe_gw, v, 4, probe_in == 21u, probe_time);
    }
    if (probe_in == 3u) {
        dan_gw_telemetry(&probe_gw, 0, probe_time);
    }
    if (probe_in == 4u) {
        dan_gw_arm(&probe_gw, probe_in == 5u, probe_time);
    }
    if (probe_in == 6u) {
        dan_gw_config(&probe_gw, &cfg, probe_time);
    }
    if (probe_in == 7u) {
        dan_gw_stats(&probe_gw, probe_time);
    }
    probe_in = (uint32_t)dan_gw_poll(&probe_gw, probe_time);
}
#endif
#if SIZE_PROBE >= 3
/* The rest of the gateway client (SIZE_PROBE=3), inlined like the above. */
static void probe_gw_rest(const uint8_t *rx)
{
    dan_reader_t r;
    dan_gw_nodes_hdr_t nh;
    dan_gw_node_entry_t node;
    dan_gw_node_info_t info;
    dan_gw_tun_open_t to = {0, 0, 0, 0, 0, 0, 0};
    dan_can_frame_t f;
    dan_gw_can_recv_t ch;
    dan_gw_filter_t flt;
    const uint8_t *data;
    size_t len;
    uint8_t res, cnt;
    memset(&f, 0, sizeof f);
    memset(&flt, 0, sizeof flt);
    if (probe_in == 8u) {
        dan_gw_nodes(&probe_gw, 1, probe_time);
    }
    if (probe_in == 9u && dan_gw_nodes_begin(&probe_gw, &r, &nh) == 0) {
        probe_in = (uint32_t)dan_gw_nodes_next(&r, &node);
    }
    if (probe_in == 10u) {
        dan_gw_node_info(&probe_gw, 5, probe_time);
    }
    if (probe_in == 11u) {
        probe_in = (uint32_t)dan_gw_node_info_get(&probe_gw, &info) + info.node_id;
    }
    if (probe_in == 12u) {
        dan_gw_tunnel_open(&probe_gw, &to, probe_time);
    }
    if (probe_in == 13u) {
        dan_gw_tunnel_xfer(&probe_gw, 0, rx, 2, 64, probe_time);
    }
    if (probe_in == 14u && dan_gw_tunnel_data(&probe_gw, &data, &len) == 0) {
        probe_in = data[0];
    }
    if (probe_in == 15u) {
        dan_gw_can_send(&probe_gw, &f, 1, probe_time);
    }
    if (probe_in == 16u) {
        dan_gw_can_recv(&probe_gw, 4, probe_time);
    }
    if (probe_in == 17u && dan_gw_can_begin(&probe_gw, &r, &ch) == 0) {
        probe_in = (uint32_t)dan_gw_can_next(&r, &f);
    }
    if (probe_in == 18u) {
        dan_gw_can_filter(&probe_gw, 0, &flt, 1, probe_time);
    }
    if (probe_in == 19u && dan_gw_filter_begin(&probe_gw, &r, &res, &cnt) == 0) {
        probe_in = (uint32_t)dan_gw_filter_next(&r, &flt);
    }
}
#endif

void Reset_Handler(void)
{
#if SIZE_PROBE >= 1
    uint8_t rx[8];
    rx[0] = (uint8_t)probe_in;
    dan_master_init(&probe_master, &port, NULL, types, 2, 9600, probe_time);
    dan_master_discover(&probe_master, probe_time);
    dan_master_configure(&probe_master, probe_in, probe_time);
    dan_master_request(&probe_master, probe_in, rx, 1, probe_time);
    for (;;) {
        dan_master_rx(&probe_master, rx, probe_in, probe_time);
        probe_in = (uint32_t)dan_master_poll(&probe_master, probe_time);
        probe_time = dan_master_next_us(&probe_master);
        probe_in = (uint32_t)dan_master_result(&probe_master);
        probe_in = (uint32_t)(uintptr_t)dan_master_peer(&probe_master, probe_in);
#if SIZE_PROBE >= 2
        probe_gw_motor();
#endif
#if SIZE_PROBE >= 3
        probe_gw_rest(rx);
#endif
    }
#else
    for (;;) {
        probe_in = probe_in + 1u;
    }
#endif
}

__attribute__((section(".isr_vector"), used))
const uintptr_t probe_vectors[2] = {(uintptr_t)&_estack, (uintptr_t)Reset_Handler};
