/* Fast bauds (docs/PROTOCOL.md section 6, "Fast bauds") on the simulated
 * wire with injected time: negotiation to 2 Mbit/s, a peer that accepts
 * less, a v1-only peer, a peer that acknowledges and does not switch, a
 * master restarted on a fast bus, a baud the caller names, and the timing
 * rules at 1 Mbit/s (turnaround, listen before talk, backoff, the reply's
 * tail). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <string.h>
#include <cmocka.h>

#include "dan/codes.h"
#include "simbus.h"
#include "handlers_test_a.h"
#include "unit_run.h"

/* 1 us steps: a character is 5 us at 2 Mbit/s. */
#define STEP_US 1u

static const dan_identity_t ident_gw = {1, "ACME", "gateway", "1", "0.1", DAN_BAUD_MASK_DEFINED,
                                        0, false};
static const dan_identity_t ident_b = {1, "Old Co", "v1 only", "1", "0.9", DAN_BAUD_MASK_DEFINED,
                                       0, false};
static const uint32_t up_to_1m[] = {230400u, 460800u, 921600u, 1000000u};
static const uint32_t probe_types[] = {DAN_TYPE_TEST_A_FIRST, DAN_TYPE_CAN_GW_FIRST,
                                       DAN_TYPE_TEST_B_FIRST};

static unsigned silent_calls;
static dan_ptype_t type_a[1], type_gw[1], type_b[1];

typedef struct {
    simbus_t bus;
    dan_master_t m;
    dan_periph_t dev1, dev2, dev3;
    sim_node_t *nm, *n1, *n2, *n3;
} rig_t;

static rig_t rig;

static void periph(dan_periph_t *p, sim_node_t *n, const dan_ptype_t *t, const uint32_t *extra,
                   size_t nextra)
{
    dan_periph_config_t pc;
    dan_periph_config_default(&pc);
    pc.extra_bauds = extra;
    pc.nextra_bauds = nextra;
    assert_int_equal(dan_periph_init(p, &n->port, t, 1, &pc, 9600, rig.bus.now), DAN_OK);
}

static void master_init(uint32_t fast_max, uint32_t seed)
{
    dan_master_config_t mc;
    dan_master_config_default(&mc);
    mc.fast_max_baud = fast_max;
    mc.seed = seed;
    assert_int_equal(
        dan_master_init(&rig.m, &rig.nm->port, &mc, probe_types, 3, rig.nm->baud, rig.bus.now),
        DAN_OK);
}

/* Master; device 1 (type A) and device 2 (gateway type) with the fast
 * bauds (device 2 up to gw_fast_n of them); optionally device 3 (type B),
 * v1 only. */
static void rig_setup(const uint32_t *gw_fast, size_t gw_fast_n, bool with_v1)
{
    memset(&rig, 0, sizeof rig);
    type_a[0] = test_a_type(&silent_calls);
    type_gw[0] = (dan_ptype_t){.first = DAN_TYPE_CAN_GW_FIRST, .identity = &ident_gw};
    type_b[0] = (dan_ptype_t){.first = DAN_TYPE_TEST_B_FIRST, .identity = &ident_b};
    sim_init(&rig.bus, STEP_US);
    rig.nm = sim_add_master(&rig.bus, &rig.m, 9600, true);
    rig.n1 = sim_add_periph(&rig.bus, &rig.dev1, 9600, true);
    rig.n2 = sim_add_periph(&rig.bus, &rig.dev2, 9600, true);
    master_init(2000000u, 1);
    periph(&rig.dev1, rig.n1, type_a, dan_fast_bauds, DAN_NFAST_BAUDS);
    periph(&rig.dev2, rig.n2, type_gw, gw_fast, gw_fast_n);
    if (with_v1) {
        rig.n3 = sim_add_periph(&rig.bus, &rig.dev3, 9600, true);
        periph(&rig.dev3, rig.n3, type_b, NULL, 0);
    }
}

static int run(void)
{
    return sim_run_master(&rig.bus, &rig.m, 30000000u);
}

static int discover(void)
{
    assert_int_equal(dan_master_discover(&rig.m, rig.bus.now), DAN_OK);
    return run();
}

static int configure(uint32_t baud)
{
    int r = dan_master_configure(&rig.m, baud, rig.bus.now);
    return (r != DAN_OK) ? r : run();
}

/* Discovery, then CONFIGURE at the best baud everyone takes (the
 * negotiation most tests look at), both completing. */
static void discover_configure_best(void)
{
    assert_int_equal(discover(), DAN_OK);
    assert_int_equal(configure(0), DAN_OK);
}

static int request(uint32_t code, const void *p, size_t len)
{
    assert_int_equal(dan_master_request(&rig.m, code, p, len, rig.bus.now), DAN_OK);
    return run();
}

/* Every present peer answers at the master's baud. */
static void assert_all_answer(void)
{
    size_t i;
    for (i = 0; i < rig.m.ntypes; i++) {
        if (rig.m.peers[i].present) {
            assert_int_equal(rig.m.peers[i].baud, dan_master_baud(&rig.m));
            assert_int_equal(request(DAN_TYPE_IDENTIFY(rig.m.peers[i].first_code), NULL, 0),
                             DAN_OK);
        }
    }
}

static void test_negotiates_2m(void **state)
{
    uint64_t t0;
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    assert_int_equal(discover(), DAN_OK);
    t0 = rig.bus.now;
    assert_int_equal(configure(0), DAN_OK);
    print_message("configure 9600 -> 2000000: %llu us\n", (unsigned long long)(rig.bus.now - t0));
    assert_int_equal(dan_master_baud(&rig.m), 2000000u);
    assert_int_equal(rig.n1->baud, 2000000u);
    assert_int_equal(rig.n2->baud, 2000000u);
    assert_int_equal(rig.m.stats.fast_refusals, 0);
    assert_int_equal(rig.m.stats.recoveries, 0);
    assert_true(rig.bus.now - t0 < 100000u);
    assert_int_equal(request(0x62, "fast", 4), DAN_OK);
    assert_memory_equal(rig.m.resp, "tsaf", 4);
    assert_all_answer();
    assert_int_equal(rig.m.link.stats.collisions, 0);
}

/* The gateway accepts up to 1 Mbit/s: 2M moves device 1, the gateway
 * refuses, device 1 comes back; 1.5M asks the gateway first (nobody
 * moves); 1M is taken by both. */
static void test_refusal_moves_back(void **state)
{
    (void)state;
    rig_setup(up_to_1m, 4, false);
    discover_configure_best();
    assert_int_equal(dan_master_baud(&rig.m), 1000000u);
    assert_int_equal(rig.n1->baud, 1000000u);
    assert_int_equal(rig.n2->baud, 1000000u);
    assert_int_equal(rig.m.stats.fast_refusals, 2);
    assert_int_equal(rig.m.stats.moved_back, 1);
    assert_int_equal(rig.dev1.stats.baud_changes, 3); /* 2M, back to 9600, 1M */
    assert_int_equal(rig.dev2.stats.nacks, 2);
    assert_int_equal(rig.m.stats.recoveries, 0);
    assert_true(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST)->fast_refused);
    assert_all_answer();
}

/* A v1-only peer (mask bauds only) on the same bus refuses every fast
 * baud; the bus settles on the best common baud, nobody left behind. */
static void test_v1_peer_best_common(void **state)
{
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, true);
    discover_configure_best();
    assert_int_equal(dan_master_baud(&rig.m), 115200u);
    assert_int_equal(rig.n1->baud, 115200u);
    assert_int_equal(rig.n2->baud, 115200u);
    assert_int_equal(rig.n3->baud, 115200u);
    assert_int_equal(rig.dev3.stats.nacks, DAN_NFAST_BAUDS);
    assert_int_equal(rig.m.stats.fast_refusals, DAN_NFAST_BAUDS);
    /* the v1 peer is last: at 2M the two others had moved and came back;
     * from then on it is asked first and nobody moves */
    assert_int_equal(rig.m.stats.moved_back, 2);
    assert_int_equal(rig.m.stats.recoveries, 0);
    assert_all_answer();
    assert_int_equal(request(0x62, "ab", 2), DAN_OK);
}

/* The gateway acknowledges 2M but its UART cannot go above 115200: the
 * verification at 2M fails, recovery finds everyone (the gateway at its
 * old baud, device 1 at the baud tried), and configure goes on with the
 * best mask baud. */
static void test_ack_without_switch_recovered(void **state)
{
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    rig.n2->ignore_above = 115200u;
    discover_configure_best();
    assert_int_equal(rig.m.stats.recoveries, 1);
    assert_int_equal(dan_master_baud(&rig.m), 115200u);
    assert_int_equal(rig.n1->baud, 115200u);
    assert_int_equal(rig.n2->baud, 115200u);
    assert_true(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST)->fast_refused);
    assert_all_answer();
}

/* The gateway switches to 2M and then never answers (it died there):
 * recovery looks for it at every baud tried and scanned, drops it, and
 * configure goes on with device 1 alone at the best mask baud. */
static void test_switched_then_silent_dropped(void **state)
{
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    assert_int_equal(discover(), DAN_OK);
    assert_int_equal(dan_master_configure(&rig.m, 0, rig.bus.now), DAN_OK);
    while (rig.dev2.stats.baud_changes == 0u && rig.bus.now < 10000000u) {
        sim_step(&rig.bus);
    }
    assert_int_equal(rig.n2->baud, 2000000u);
    rig.n2->mute = true;
    assert_int_equal(run(), DAN_OK);
    assert_int_equal(rig.m.stats.recoveries, 1);
    assert_null(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST));
    assert_int_equal(dan_master_baud(&rig.m), 115200u);
    assert_int_equal(rig.n1->baud, 115200u);
    assert_all_answer();
}

/* The same lie when the caller names the baud: the failure is reported,
 * the bus is left working at 9600 with every peer. */
static void test_named_baud_lie_recovered(void **state)
{
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    rig.n2->ignore_above = 115200u;
    assert_int_equal(discover(), DAN_OK);
    assert_int_equal(configure(1000000u), DAN_ERR_TIMEOUT);
    assert_int_equal(dan_master_baud(&rig.m), 9600u);
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_TEST_A_FIRST));
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST));
    assert_all_answer();
}

/* A baud the caller names: taken without fast_max_baud; refused by one
 * peer: DAN_ERR_NACK and everyone where they were. */
static void test_named_baud(void **state)
{
    (void)state;
    rig_setup(up_to_1m, 4, false);
    master_init(0, 7); /* v1 master: offers nothing by itself */
    discover_configure_best();
    assert_int_equal(dan_master_baud(&rig.m), 115200u);
    assert_int_equal(configure(921600u), DAN_OK);
    assert_int_equal(rig.n2->baud, 921600u);
    assert_int_equal(configure(1500000u), DAN_ERR_NACK);
    assert_int_equal(dan_master_baud(&rig.m), 921600u);
    assert_int_equal(rig.n1->baud, 921600u);
    assert_int_equal(rig.n2->baud, 921600u);
    assert_all_answer();
    /* the port's limit */
    rig.m.link.port.max_baud = 1000000u;
    assert_int_equal(dan_master_configure(&rig.m, 2000000u, rig.bus.now), DAN_ERR_UNSUPPORTED);
}

/* A master that restarts on a bus left at 2M finds its peers there
 * (discovery scans the fast bauds after 9600) and configure keeps it. */
static void test_restart_finds_fast_bus(void **state)
{
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    discover_configure_best();
    rig.nm->baud = 9600;
    master_init(2000000u, 42);
    assert_int_equal(discover(), DAN_OK);
    assert_int_equal(dan_master_peer(&rig.m, DAN_TYPE_TEST_A_FIRST)->baud, 2000000u);
    assert_int_equal(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST)->baud, 2000000u);
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(rig.dev1.stats.baud_changes, 1);
    assert_all_answer();
    /* a v1 master (no fast bauds) does not find them: nothing to use */
    rig.nm->baud = 9600;
    master_init(0, 43);
    assert_int_equal(discover(), DAN_ERR_NOTFOUND);
}

/* Timing at 1 Mbit/s (C = 10 us): the peripheral replies no sooner than
 * 2 C after the request, the master talks only after 3 C of idle line. */
static void test_timing_1m(void **state)
{
    size_t i;
    int turns = 0, lbts = 0;
    const uint32_t c = dan_char_us(1000000u);
    (void)state;
    assert_int_equal(c, 10u);
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    master_init(1000000u, 5);
    discover_configure_best();
    assert_int_equal(dan_master_baud(&rig.m), 1000000u);
    rig.bus.nlog = 0;
    for (i = 0; i < 20; i++) {
        assert_int_equal(request(0x62, "tick", 4), DAN_OK);
    }
    for (i = 1; i < rig.bus.nlog; i++) {
        const sim_byte_t *prev = &rig.bus.log[i - 1], *e = &rig.bus.log[i];
        if (prev->src == rig.nm->idx && e->src != rig.nm->idx) {
            assert_true(e->start_us >= prev->end_us + DAN_TURNAROUND_CHARS * c);
            turns++;
        } else if (prev->src != rig.nm->idx && e->src == rig.nm->idx) {
            assert_true(e->start_us >= prev->end_us + DAN_LBT_CHARS * c);
            lbts++;
        }
    }
    assert_int_equal(turns, 20);
    assert_int_equal(lbts, 19);
}

/* Backoff after a failed attempt is counted in characters: at 1M a
 * retry waits less than 8 * 2^k * C (+ listen before talk). */
static void test_backoff_1m(void **state)
{
    uint64_t t_fail, t_retry;
    uint32_t sent;
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    master_init(1000000u, 9);
    discover_configure_best();
    rig.n1->mute = true;
    assert_int_equal(dan_master_request(&rig.m, 0x62, (const uint8_t *)"x", 1, rig.bus.now),
                     DAN_OK);
    while (rig.m.stats.timeouts == 0u) {
        sim_step(&rig.bus);
    }
    t_fail = rig.bus.now;
    sent = rig.m.link.stats.tx_frames;
    while (rig.m.link.stats.tx_frames == sent) {
        sim_step(&rig.bus);
    }
    t_retry = rig.bus.now;
    /* attempt 1: k = 1, up to 16 C; then 3 C idle */
    assert_true(t_retry - t_fail <= (16u + DAN_LBT_CHARS) * 10u + 2u * STEP_US);
    rig.n1->mute = false;
    assert_int_equal(run(), DAN_OK);
}

/* A reply that starts just before the deadline and whose tail a host
 * delivers 1.9 ms later (a USB latency timer) still counts at 1M: the
 * master waits past the deadline for max(DAN_MAX_FRAME * C, gap). */
static void test_reply_tail_1m(void **state)
{
    static sim_cap_t cap;
    dan_master_t m;
    dan_port_t port;
    uint8_t reply[32];
    uint64_t now = 1000, deadline;
    int n;
    (void)state;
    sim_cap_port(&cap, &port);
    assert_int_equal(dan_master_init(&m, &port, NULL, probe_types, 1, 1000000u, now), DAN_OK);
    assert_int_equal(dan_master_request(&m, 0x62, (const uint8_t *)"abc", 3, now), DAN_OK);
    sim_cap_wait_tx(&cap, &m, &now, 1);
    now += 100;
    dan_master_rx(&m, cap.buf, cap.len, now); /* the echo */
    assert_int_equal(dan_master_poll(&m, now), 0);
    deadline = m.deadline_us;
    assert_int_equal(deadline, now + 2u * 10u + DAN_RESP_LATENCY_US);
    n = dan_frame_encode(0x62, (const uint8_t *)"cba", 3, reply, sizeof reply);
    dan_master_rx(&m, reply, 3, deadline - 1u);
    assert_int_equal(dan_master_poll(&m, deadline + 1900u), 0); /* 1690 us: a frame at 1M */
    dan_master_rx(&m, reply + 3, (size_t)n - 3u, deadline + 1900u);
    assert_int_equal(dan_master_poll(&m, deadline + 1901u), 1);
    assert_int_equal(dan_master_result(&m), DAN_OK);
    assert_memory_equal(m.resp, "cba", 3);
}

/* The master's own list (ascending): offered highest first, without mask
 * bauds or repeats, within fast_max_baud and the port's max_baud. */
static void test_fast_list_rules(void **state)
{
    static const uint32_t mine[] = {115200u, 250000u, 250000u, 1000000u, 2000000u};
    (void)state;
    rig_setup(dan_fast_bauds, DAN_NFAST_BAUDS, false);
    rig.m.cfg.fast_bauds = mine;
    rig.m.cfg.nfast_bauds = 5;
    rig.m.cfg.fast_max_baud = 1500000u;
    assert_int_equal(discover(), DAN_OK);
    rig.dev1.cfg.extra_bauds = mine;
    rig.dev1.cfg.nextra_bauds = 5;
    rig.dev2.cfg.extra_bauds = mine;
    rig.dev2.cfg.nextra_bauds = 5;
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(dan_master_baud(&rig.m), 1000000u); /* 2M is above fast_max_baud */
    rig.m.link.port.max_baud = 500000u;
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(dan_master_baud(&rig.m), 250000u);
    assert_int_equal(rig.m.stats.fast_refusals, 0);
}

int main(void)
{
    return UNIT_RUN("fast_baud", NULL, NULL, test_negotiates_2m, test_refusal_moves_back,
                    test_v1_peer_best_common, test_ack_without_switch_recovered,
                    test_switched_then_silent_dropped, test_named_baud_lie_recovered,
                    test_named_baud, test_restart_finds_fast_bus, test_timing_1m, test_backoff_1m,
                    test_reply_tail_1m, test_fast_list_rules);
}
