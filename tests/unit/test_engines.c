/* Master and peripheral engines on a simulated wire, with injected time:
 * discovery, configure, verification and recovery, transactions, error
 * frames, unknown codes, listen-before-talk, echo and collisions, noise,
 * the direction pin, turnaround and baud switch timing. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <string.h>
#include <cmocka.h>

#include "dan/codes.h"
#include "simbus.h"
#include "../../src/master_internal.h" /* the sequencer's steps (white box) */
#include "handlers_test_a.h"
#include "unit_run.h"

#define STEP_US 10u

/* ---- test peripherals ---- */

static const dan_identity_t ident_b = {
    1,       "DAN Project", "test B",
    "rev 2", "2.0.0",       DAN_BAUD_MASK_19200 | DAN_BAUD_MASK_57600 | DAN_BAUD_MASK_115200,
    0,       false};
static const dan_identity_t ident_gw = {1, "ACME", "gateway", "1", "0.1", DAN_BAUD_MASK_DEFINED,
                                        0, false};

static unsigned silent_calls;

static dan_ptype_t types_dev1[2];
static dan_ptype_t types_dev2[1];
static const uint32_t probe_types[] = {DAN_TYPE_TEST_A_FIRST, DAN_TYPE_TEST_B_FIRST,
                                       DAN_TYPE_CAN_GW_FIRST, DAN_TYPE_VTX_FIRST};

typedef struct {
    simbus_t bus;
    dan_master_t m;
    dan_identity_t ids[4]; /* one per probe type */
    dan_periph_t dev1, dev2;
    sim_node_t *nm, *n1, *n2;
} rig_t;

static rig_t rig;

/* Master (echo), device 1 (types A and B), device 2 (gateway type). */
static void rig_setup(bool echo)
{
    dan_master_config_t cfg;
    memset(&rig, 0, sizeof rig);
    types_dev1[0] = test_a_type(&silent_calls);
    types_dev1[1] = (dan_ptype_t){.first = DAN_TYPE_TEST_B_FIRST, .identity = &ident_b};
    types_dev2[0] = (dan_ptype_t){.first = DAN_TYPE_CAN_GW_FIRST, .identity = &ident_gw};
    sim_init(&rig.bus, STEP_US);
    dan_master_config_default(&cfg);
    rig.nm = sim_add_master(&rig.bus, &rig.m, 9600, echo);
    rig.n1 = sim_add_periph(&rig.bus, &rig.dev1, 9600, echo);
    rig.n2 = sim_add_periph(&rig.bus, &rig.dev2, 9600, echo);
    assert_int_equal(
        dan_master_init(&rig.m, &rig.nm->port, &cfg, probe_types, 4, 9600, rig.bus.now), DAN_OK);
    dan_master_set_identities(&rig.m, rig.ids, 4);
    assert_int_equal(
        dan_periph_init(&rig.dev1, &rig.n1->port, types_dev1, 2, NULL, 9600, rig.bus.now), DAN_OK);
    assert_int_equal(
        dan_periph_init(&rig.dev2, &rig.n2->port, types_dev2, 1, NULL, 9600, rig.bus.now), DAN_OK);
    silent_calls = 0;
}

static int discover(void)
{
    assert_int_equal(dan_master_discover(&rig.m, rig.bus.now), DAN_OK);
    return sim_run_master(&rig.bus, &rig.m, 20000000u);
}

/* The rig with echo, discovery done: what most tests start from. */
static void rig_discovered(void)
{
    rig_setup(true);
    assert_int_equal(discover(), DAN_OK);
}

static int configure(uint32_t baud)
{
    int r = dan_master_configure(&rig.m, baud, rig.bus.now);
    if (r != DAN_OK) {
        return r;
    }
    return sim_run_master(&rig.bus, &rig.m, 20000000u);
}

static int request(uint32_t code, const void *p, size_t len)
{
    assert_int_equal(dan_master_request(&rig.m, code, p, len, rig.bus.now), DAN_OK);
    return sim_run_master(&rig.bus, &rig.m, 20000000u);
}

/* ---- tests ---- */

static void test_discovery_identities(void **state)
{
    const dan_peer_t *a, *b, *g;
    uint64_t t0;
    (void)state;
    rig_setup(true);
    t0 = rig.bus.now;
    assert_int_equal(discover(), DAN_OK);
    a = dan_master_peer(&rig.m, DAN_TYPE_TEST_A_FIRST);
    b = dan_master_peer(&rig.m, DAN_TYPE_TEST_B_FIRST);
    g = dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST);
    assert_non_null(a);
    assert_non_null(b);
    assert_non_null(g);
    assert_null(dan_master_peer(&rig.m, DAN_TYPE_VTX_FIRST)); /* nobody is a VTX */
    assert_string_equal(dan_master_identity(&rig.m, DAN_TYPE_TEST_A_FIRST)->model, "test A");
    assert_string_equal(dan_master_identity(&rig.m, DAN_TYPE_TEST_B_FIRST)->sw_version, "2.0.0");
    assert_string_equal(dan_master_identity(&rig.m, DAN_TYPE_CAN_GW_FIRST)->manufacturer, "ACME");
    assert_int_equal(a->baud, 9600);
    assert_int_equal(rig.m.link.stats.collisions, 0);
    /* the absent VTX type was probed at every discovery baud */
    assert_true(rig.m.stats.timeouts >= 2u * DAN_DISCOVERY_NBAUDS);
    assert_true(rig.bus.now - t0 < 3000000u);
}

/* Configure picks the highest common baud (B lacks 38400 but has 115200),
 * moves everyone, verifies at the new baud; later transactions work. */
static void test_configure_best_baud(void **state)
{
    uint8_t out[3];
    (void)state;
    rig_discovered();
    assert_int_equal(dan_master_best_baud(&rig.m), 115200);
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(dan_master_baud(&rig.m), 115200);
    assert_int_equal(dan_periph_baud(&rig.dev1), 115200);
    assert_int_equal(dan_periph_baud(&rig.dev2), 115200);
    assert_int_equal(rig.dev1.stats.baud_changes, 1); /* one UART, two types */
    assert_int_equal(rig.m.stats.recoveries, 0);
    assert_int_equal(request(0x62, "abc", 3), DAN_OK);
    assert_int_equal(rig.m.resp_len, 3);
    memcpy(out, rig.m.resp, 3);
    assert_memory_equal(out, "cba", 3);
    /* a baud one peer lacks is refused up front */
    assert_int_equal(dan_master_configure(&rig.m, 38400, rig.bus.now), DAN_ERR_UNSUPPORTED);
    /* and a port limit lowers the best baud */
    rig.m.link.port.max_baud = 57600;
    assert_int_equal(dan_master_best_baud(&rig.m), 57600);
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(dan_periph_baud(&rig.dev2), 57600);
}

/* The ACK leaves the wire at the old baud; the switch comes after it. */
static void test_baud_switch_after_ack(void **state)
{
    size_t i;
    int acks_at_9600 = 0;
    (void)state;
    rig_discovered();
    rig.bus.nlog = 0;
    assert_int_equal(configure(115200), DAN_OK);
    for (i = 0; i + 3 < rig.bus.nlog; i++) {
        const sim_byte_t *e = &rig.bus.log[i];
        /* an ACK frame from a peripheral: 'D', code, 01, 00, crc */
        if (e->src != rig.nm->idx && e->byte == 'D' && rig.bus.log[i + 2].byte == 1 &&
            rig.bus.log[i + 3].byte == 0) {
            assert_int_equal(e->baud, 9600);
            assert_int_equal(rig.bus.log[i + 4].baud, 9600);
            acks_at_9600++;
        }
    }
    assert_int_equal(acks_at_9600, 2); /* device 1 and device 2 */
}

/* The peripheral waits at least the turnaround gap after a request. */
static void test_turnaround_gap(void **state)
{
    size_t i;
    int checked = 0;
    (void)state;
    rig_discovered();
    for (i = 1; i < rig.bus.nlog; i++) {
        const sim_byte_t *prev = &rig.bus.log[i - 1], *e = &rig.bus.log[i];
        if (prev->src == rig.nm->idx && e->src != rig.nm->idx) {
            assert_true(e->start_us >= prev->end_us + DAN_TURNAROUND_CHARS * dan_char_us(9600));
            checked++;
        }
    }
    assert_int_equal(checked, 3);
}

/* Unknown codes are ignored (counted); a known code with a malformed
 * payload gets an error frame whose text reaches the caller; handlers may
 * stay silent. */
static void test_unknown_malformed_silent(void **state)
{
    uint32_t unknown0;
    dan_error_msg_t e;
    (void)state;
    rig_discovered();
    unknown0 = rig.dev1.stats.unknown;
    assert_int_equal(request(0x64, NULL, 0), DAN_ERR_TIMEOUT); /* in A's block, not served */
    assert_int_equal(rig.dev1.stats.unknown - unknown0, 3);    /* every attempt ignored */
    assert_int_equal(request(0x62, NULL, 0), DAN_ERR_REMOTE);
    assert_int_equal(dan_master_remote_error(&rig.m, &e), DAN_OK);
    assert_int_equal(e.code, 0x62);
    assert_string_equal(e.text, "empty payload");
    assert_int_equal(rig.dev1.stats.errors_sent, 1);
    /* a malformed CONFIGURE is an error frame too */
    assert_int_equal(request(DAN_TYPE_CONFIGURE(DAN_TYPE_TEST_A_FIRST), NULL, 0), DAN_ERR_REMOTE);
    assert_int_equal(dan_master_remote_error(&rig.m, &e), DAN_OK);
    assert_string_equal(e.text, "malformed CONFIGURE payload");
    /* a CONFIGURE for a baud not in the mask is ACK-FAIL, and nothing moves */
    {
        uint8_t p[8];
        dan_configure_t c = {DAN_CONFIGURE_BPS, 38400};
        int n = dan_configure_encode(&c, p, sizeof p);
        assert_int_equal(request(DAN_TYPE_CONFIGURE(DAN_TYPE_TEST_B_FIRST), p, (size_t)n), DAN_OK);
        assert_int_equal(rig.m.resp_len, 1);
        assert_int_equal(rig.m.resp[0], DAN_ACK_FAIL);
        assert_int_equal(dan_periph_baud(&rig.dev1), 9600);
    }
    assert_int_equal(request(0x63, "x", 1), DAN_ERR_TIMEOUT);
    assert_int_equal(silent_calls, 3);
    /* the bus still works */
    assert_int_equal(request(0x62, "yz", 2), DAN_OK);
}

/* After a master reset (new master at 9600) with peripherals left at
 * 115200, discovery finds them at 115200 and configure keeps the bus. */
static void test_master_restart_recovery(void **state)
{
    dan_master_config_t cfg;
    const dan_peer_t *g;
    (void)state;
    rig_discovered();
    assert_int_equal(configure(0), DAN_OK);
    /* the firmware resets: fresh master state, UART back at 9600 */
    dan_master_config_default(&cfg);
    cfg.seed = 99;
    rig.nm->baud = 9600;
    assert_int_equal(
        dan_master_init(&rig.m, &rig.nm->port, &cfg, probe_types, 4, 9600, rig.bus.now), DAN_OK);
    dan_master_set_identities(&rig.m, rig.ids, 4);
    assert_int_equal(discover(), DAN_OK);
    g = dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST);
    assert_non_null(g);
    assert_int_equal(g->baud, 115200);
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_TEST_B_FIRST));
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(dan_master_baud(&rig.m), 115200);
    assert_int_equal(request(0x62, "ok", 2), DAN_OK);
}

/* A peripheral that ACKs but cannot really switch: verification fails, the
 * master recovers everyone to 9600, reports the failure, and the bus works. */
static void test_configure_verify_failure_recovers(void **state)
{
    (void)state;
    rig_discovered();
    rig.n2->ignore_baud = true; /* device 2's UART stays at 9600 */
    assert_int_equal(configure(115200), DAN_ERR_TIMEOUT);
    assert_int_equal(rig.m.stats.recoveries, 1);
    assert_int_equal(dan_master_baud(&rig.m), 9600);
    assert_int_equal(rig.n1->baud, 9600);
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_TEST_A_FIRST));
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST));
    assert_int_equal(request(0x62, "ab", 2), DAN_OK);
    assert_int_equal(request(DAN_TYPE_IDENTIFY(DAN_TYPE_CAN_GW_FIRST), NULL, 0), DAN_OK);
}

/* Recovery brings a moved peer back with CONFIGURE(9600); the peer
 * acknowledges and switches, but the master does not hear the ACK (noise
 * on its side). The peer is where it was asked to go: verification at 9600
 * finds it, and it stays in the table (it was dropped as "refusing 9600"). */
static void test_recovery_ack_lost_peer_kept(void **state)
{
    uint32_t writes;
    (void)state;
    rig_discovered();
    rig.n2->ignore_baud = true; /* device 2 stays at 9600: verification fails */
    assert_int_equal(dan_master_configure(&rig.m, 115200, rig.bus.now), DAN_OK);
    while (rig.m.step != DAN_ST_REC_BACK && rig.bus.now < 20000000u) {
        sim_step(&rig.bus);
    }
    assert_int_equal(rig.m.step, DAN_ST_REC_BACK);
    assert_int_equal(rig.n1->baud, 115200);
    /* the CONFIGURE(9600) goes out whole, then the master hears nothing */
    writes = rig.m.link.stats.tx_frames;
    while ((rig.m.link.stats.tx_frames == writes || rig.m.link.state == DAN_LINK_TX) &&
           rig.bus.now < 30000000u) {
        sim_step(&rig.bus);
    }
    rig.nm->deaf = true;
    while (rig.n1->baud != 9600 && rig.bus.now < 40000000u) {
        sim_step(&rig.bus);
    }
    assert_int_equal(rig.n1->baud, 9600); /* it acknowledged and moved */
    rig.nm->deaf = false;
    assert_int_equal(sim_run_master(&rig.bus, &rig.m, 20000000u), DAN_ERR_TIMEOUT);
    assert_int_equal(rig.m.stats.recoveries, 1);
    assert_int_equal(dan_master_baud(&rig.m), 9600);
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_TEST_A_FIRST));
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST));
    assert_int_equal(request(0x62, "ab", 2), DAN_OK);
}

/* A peripheral that vanishes mid-configure is dropped; the others work. */
static void test_configure_peer_vanishes(void **state)
{
    (void)state;
    rig_discovered();
    rig.n2->mute = true;
    assert_true(configure(115200) < 0);
    assert_null(dan_master_peer(&rig.m, DAN_TYPE_CAN_GW_FIRST));
    assert_non_null(dan_master_peer(&rig.m, DAN_TYPE_TEST_A_FIRST));
    assert_int_equal(request(0x62, "ab", 2), DAN_OK);
}

/* Another talker starts while the master transmits: the echo differs, the
 * master stops, backs off, retries and succeeds. */
static void test_collision_detected_and_retried(void **state)
{
    static const uint8_t junk[] = {0x13, 0x37, 0x00, 0xFF, 0x55};
    int r;
    (void)state;
    rig_discovered();
    assert_int_equal(dan_master_request(&rig.m, 0x62, (const uint8_t *)"hello", 5, rig.bus.now),
                     DAN_OK);
    /* let the master start, then talk over it */
    while (rig.m.link.state != DAN_LINK_TX) {
        sim_step(&rig.bus);
    }
    sim_inject(&rig.bus, rig.n2, junk, sizeof junk);
    r = sim_run_master(&rig.bus, &rig.m, 5000000u);
    assert_int_equal(r, DAN_OK);
    assert_true(rig.m.link.stats.collisions >= 1);
    assert_true(rig.m.stats.retries >= 1);
    assert_memory_equal(rig.m.resp, "olleh", 5);
}

/* Listen before talk: while the line is busy the master waits; it talks
 * only after the line was idle for lbt_chars characters. */
static void test_listen_before_talk(void **state)
{
    uint8_t noise[40];
    size_t i;
    uint64_t noise_end;
    (void)state;
    rig_discovered();
    for (i = 0; i < sizeof noise; i++) {
        noise[i] = (uint8_t)(0x10 + i); /* no sync byte */
    }
    sim_inject(&rig.bus, rig.n2, noise, sizeof noise);
    noise_end = rig.n2->tx_free_us;
    sim_step(&rig.bus);
    rig.bus.nlog = 0;
    assert_int_equal(request(0x62, "qr", 2), DAN_OK);
    assert_true(rig.m.stats.lbt_waits >= 1);
    for (i = 0; i < rig.bus.nlog; i++) {
        if (rig.bus.log[i].src == rig.nm->idx) {
            assert_true(rig.bus.log[i].start_us >= noise_end + 3u * dan_char_us(9600));
            break;
        }
    }
    assert_true(i < rig.bus.nlog);
    assert_int_equal(rig.m.link.stats.collisions, 0);
}

/* A line that never goes idle: the transaction gives up with BUSY. */
static void test_busy_line_times_out(void **state)
{
    uint8_t noise[400];
    (void)state;
    rig_discovered();
    memset(noise, 0x11, sizeof noise); /* 400 chars = 417 ms at 9600 */
    sim_inject(&rig.bus, rig.n2, noise, sizeof noise);
    sim_step(&rig.bus);
    assert_int_equal(request(0x62, "qr", 2), DAN_ERR_BUSY);
    assert_int_equal(rig.m.stats.busy_failures, 1);
}

/* Noise on the wire: transactions retry; any reply delivered is correct. */
static void test_noise_no_wrong_data(void **state)
{
    int i, ok = 0, failed = 0;
    (void)state;
    rig_discovered();
    assert_int_equal(configure(0), DAN_OK);
    rig.bus.noise_ppm = 20000; /* 2 % of bytes get a flipped bit */
    for (i = 0; i < 200; i++) {
        uint8_t req[4] = {(uint8_t)i, (uint8_t)(i >> 8), 0xA5, 0x5A};
        int r = request(0x62, req, 4);
        if (r == DAN_OK) {
            uint8_t want[4] = {0x5A, 0xA5, (uint8_t)(i >> 8), (uint8_t)i};
            assert_int_equal(rig.m.resp_len, 4);
            assert_memory_equal(rig.m.resp, want, 4);
            ok++;
        } else {
            failed++;
        }
    }
    assert_true(ok >= 190);
    assert_true(rig.m.stats.retries > 0);
    rig.bus.noise_ppm = 0;
    assert_int_equal(request(0x62, "xy", 2), DAN_OK);
    print_message("noise: %d ok, %d failed, %u retries\n", ok, failed, rig.m.stats.retries);
}

/* Direction-pin ports (no echo): the pin is asserted before the first byte
 * and released only after the last byte left; everything still works. */
static void test_direction_pin(void **state)
{
    (void)state;
    rig_setup(false);
    assert_int_equal(discover(), DAN_OK);
    assert_int_equal(configure(0), DAN_OK);
    assert_int_equal(request(0x62, "pin", 3), DAN_OK);
    assert_false(rig.nm->tx_pin_error);
    assert_false(rig.n1->tx_pin_error);
    assert_false(rig.n2->tx_pin_error);
    assert_true(rig.nm->set_tx_on > 0);
    assert_int_equal(rig.nm->set_tx_on, rig.nm->set_tx_off);
    assert_false(rig.nm->tx_pin);
}

/* Time bound: discovery + configure of 3 types on 2 devices (the absent VTX
 * probed at 5 bauds) stays within what the rules allow. */
static void test_discovery_configure_time(void **state)
{
    uint64_t t0, t;
    (void)state;
    rig_setup(true);
    t0 = rig.bus.now;
    assert_int_equal(discover(), DAN_OK);
    assert_int_equal(configure(0), DAN_OK);
    t = rig.bus.now - t0;
    print_message("discovery+configure (3 present, 1 absent type): %llu us\n",
                  (unsigned long long)t);
    assert_true(t < 1500000u);
}

/* A reply identical to its request is accepted normally; but after our echo
 * went missing, a copy of our own request is our late echo, not a reply. */
static void test_late_echo_is_not_a_reply(void **state)
{
    uint8_t frame[16];
    uint32_t sent, stray;
    int n;
    (void)state;
    rig_discovered();
    assert_int_equal(request(0x62, "aba", 3), DAN_OK); /* reversed = itself: fine */
    /* The master's echo goes missing (a stalled adapter) and the peripheral
     * stays silent: echo timeout. */
    rig.nm->echo = false;
    rig.n1->mute = true;
    assert_int_equal(dan_master_request(&rig.m, 0x62, (const uint8_t *)"xyz", 3, rig.bus.now),
                     DAN_OK);
    while (rig.m.link.stats.echo_timeouts == 0 && rig.bus.now < 10000000u) {
        sim_step(&rig.bus);
    }
    assert_int_equal(rig.m.link.stats.echo_timeouts, 1);
    /* The retry goes out with its echo; the peripheral is still silent. */
    rig.nm->echo = true;
    sent = rig.m.link.stats.tx_frames;
    while ((rig.m.link.stats.tx_frames == sent || rig.m.link.state != DAN_LINK_IDLE) &&
           rig.bus.now < 20000000u) {
        sim_step(&rig.bus);
    }
    /* While the master waits, the late copy of its request arrives (another
     * node plays it): it is not the reply. */
    stray = rig.m.stats.stray;
    n = dan_frame_encode(0x62, (const uint8_t *)"xyz", 3, frame, sizeof frame);
    sim_inject(&rig.bus, rig.n2, frame, (size_t)n);
    sim_run_for(&rig.bus, 20000);
    assert_int_equal(rig.m.stats.stray, stray + 1);
    assert_true(dan_master_busy(&rig.m));
    /* The peripheral wakes up: the next attempt gets the real reply. */
    rig.n1->mute = false;
    assert_int_equal(sim_run_master(&rig.bus, &rig.m, 5000000u), DAN_OK);
    assert_memory_equal(rig.m.resp, "zyx", 3);
}

/* A slow host reads the last echo byte and the whole reply in one go (a
 * USB adapter's latency timer does this): the reply still counts. */
static void test_reply_in_same_read_as_echo(void **state)
{
    static sim_cap_t cap;
    dan_master_t m;
    dan_port_t port;
    uint8_t rx[64];
    uint64_t now = 1000;
    int n;
    (void)state;
    sim_cap_port(&cap, &port);
    assert_int_equal(dan_master_init(&m, &port, NULL, probe_types, 1, 115200, now), DAN_OK);
    assert_int_equal(dan_master_request(&m, 0x62, (const uint8_t *)"abc", 3, now), DAN_OK);
    sim_cap_wait_tx(&cap, &m, &now, 100);
    /* one read: our echo, then the whole reply */
    memcpy(rx, cap.buf, cap.len);
    n = dan_frame_encode(0x62, (const uint8_t *)"cba", 3, rx + cap.len, sizeof rx - cap.len);
    dan_master_rx(&m, rx, cap.len + (size_t)n, now + 2000);
    assert_int_equal(dan_master_poll(&m, now + 2001), 1);
    assert_int_equal(dan_master_result(&m), DAN_OK);
    assert_memory_equal(m.resp, "cba", 3);
    assert_int_equal(m.stats.stray, 0);
}

static int pin_released; /* set_tx(false) calls */
static void count_release(void *ctx, bool on)
{
    (void)ctx;
    pin_released += !on;
}

/* Gives cap's frame (our request "abc" to 0x62) the reply "cba" at
 * reply_us, before any poll, and checks the transaction completed. */
static void reply_cba(dan_master_t *m, uint64_t reply_us)
{
    uint8_t rx[32];
    int n = dan_frame_encode(0x62, (const uint8_t *)"cba", 3, rx, sizeof rx);
    dan_master_rx(m, rx, (size_t)n, reply_us);
    assert_int_equal(dan_master_poll(m, reply_us + 1u), 1);
    assert_int_equal(dan_master_result(m), DAN_OK);
    assert_memory_equal(m->resp, "cba", 3);
    assert_int_equal(m->link.state, DAN_LINK_IDLE);
}

/* A direction pin and no echo: the whole reply arrives (the FC's loop reads
 * before it polls) while the link still counts our frame as on the wire.
 * The reply proves the frame has left: the pin is released and the next
 * request goes out (it failed at once, unsent, and so did every one after
 * it: a discovery found nothing more, a configure split the bus). */
static void test_direction_pin_reply_before_poll(void **state)
{
    static sim_cap_t cap;
    dan_master_t m;
    dan_port_t port;
    uint64_t now = 1000;
    int round;
    (void)state;
    sim_cap_port(&cap, &port);
    port.echo = false;
    port.set_tx = count_release;
    pin_released = 0;
    assert_int_equal(dan_master_init(&m, &port, NULL, probe_types, 1, 115200, now), DAN_OK);
    for (round = 1; round <= 3; round++) {
        cap.len = 0;
        assert_int_equal(dan_master_request(&m, 0x62, (const uint8_t *)"abc", 3, now), DAN_OK);
        sim_cap_wait_tx(&cap, &m, &now, 100);
        assert_int_equal(m.link.state, DAN_LINK_TX);
        now += 2000u;
        reply_cba(&m, now);
        assert_int_equal(pin_released, round);
    }
    assert_int_equal(m.link.stats.tx_frames, 3);
}

/* A caller may sleep as long as dan_master_next_us() says. It said "never"
 * when nothing was going on, and 40 minutes later (32-bit stamps 2^31 us
 * and more behind) a request failed with DAN_ERR_BUSY: the old last-byte
 * stamp read as "ahead", the line as busy. Now an idle engine asks for a
 * poll every DAN_LINK_IDLE_POLL_US, and the request goes out at once. */
static void test_request_after_40_minutes_idle(void **state)
{
    static sim_cap_t cap;
    dan_master_t m;
    dan_port_t port;
    uint64_t now = 1000, start;
    (void)state;
    sim_cap_port(&cap, &port);
    assert_int_equal(dan_master_init(&m, &port, NULL, probe_types, 1, 115200, now), DAN_OK);
    while (now < 2400000000ull) {
        uint64_t next = dan_master_next_us(&m);
        assert_true(next > now && next <= now + DAN_LINK_IDLE_POLL_US);
        now = next;
        (void)dan_master_poll(&m, now);
    }
    start = now;
    assert_int_equal(dan_master_request(&m, 0x62, (const uint8_t *)"abc", 3, now), DAN_OK);
    while (cap.len == 0u && now - start < 100000u) {
        now += 100u;
        (void)dan_master_poll(&m, now);
    }
    assert_true(cap.len > 0u);
    assert_true(now - start <= 1000u);               /* listen-before-talk only */
    dan_master_rx(&m, cap.buf, cap.len, now + 700u); /* the echo */
    reply_cba(&m, now + 2000u);
    assert_int_equal(m.stats.busy_failures, 0);
}

/* A frame starts and stops while a request waits to talk: the line is not
 * idle until the inter-byte gap drops the partial frame, and next_us says
 * so (it said "now" on every call until then: a caller sleeping until
 * next_us spun for the whole gap, 2 ms here and 20 ms in the Linux tools). */
static void test_partial_frame_next_us_waits_for_gap(void **state)
{
    static sim_cap_t cap;
    static const uint8_t part[3] = {DAN_SYNC, 0x60, 0x10};
    dan_master_t m;
    dan_port_t port;
    uint64_t now = 1000, gap_end;
    int polls = 0;
    (void)state;
    sim_cap_port(&cap, &port);
    assert_int_equal(dan_master_init(&m, &port, NULL, probe_types, 1, 115200, now), DAN_OK);
    now += 5000u;
    dan_master_rx(&m, part, sizeof part, now);
    gap_end = now + dan_link_gap_us(&m.link);
    assert_int_equal(dan_master_request(&m, 0x62, (const uint8_t *)"abc", 3, now), DAN_OK);
    now += 500u; /* listen-before-talk's 3 C have passed, the gap has not */
    while (cap.len == 0u && polls < 100) {
        uint64_t next;
        (void)dan_master_poll(&m, now);
        next = dan_master_next_us(&m);
        assert_true(next > now || cap.len > 0u || now >= gap_end);
        now = next > now ? next : now + 1u;
        polls++;
    }
    assert_true(cap.len > 0u);
    assert_true(polls <= 4);
}

/* A test-a/test-b peripheral at 9600 on a capture port, its clock at
 * 1000 us. */
typedef struct {
    sim_cap_t cap;
    dan_periph_t p;
    uint64_t now;
} cap_rig_t;

static cap_rig_t *cap_periph(void)
{
    static cap_rig_t r;
    dan_port_t port;
    rig_setup(true); /* for types_dev1 */
    sim_cap_port(&r.cap, &port);
    r.now = 1000u;
    assert_int_equal(dan_periph_init(&r.p, &port, types_dev1, 2, NULL, 9600, r.now), DAN_OK);
    return &r;
}

/* Polls the peripheral every 100 us until it has written something. */
static void periph_wait_tx(cap_rig_t *r)
{
    while (r->cap.len == 0u && r->now < 10000000u) {
        r->now += 100u;
        dan_periph_poll(&r->p, r->now);
    }
}

/* CONFIGURE(baud) to test-a, encoded into out: its length. */
static size_t configure_a(uint32_t baud, uint8_t *out, size_t cap)
{
    uint8_t pl[8];
    int n;
    pl[0] = DAN_CONFIGURE_BPS;
    n = dan_frame_encode(DAN_TYPE_CONFIGURE(DAN_TYPE_TEST_A_FIRST), pl,
                         1u + dan_uvarint_put(baud, pl + 1), out, cap);
    assert_true(n > 0);
    return (size_t)n;
}

/* A loaded peripheral reads the echo of its IDENTIFY reply and the
 * master's CONFIGURE in one go: the end of that reply must not cancel the
 * switch the CONFIGURE asked for (it did: the ACK went out, the baud
 * stayed, the master's verification failed; seen in make test). */
static void test_configure_in_same_read_as_echo(void **state)
{
    cap_rig_t *r = cap_periph();
    uint8_t rx[128];
    size_t len;
    int n;
    (void)state;
    n = dan_frame_encode(DAN_TYPE_IDENTIFY(DAN_TYPE_TEST_A_FIRST), NULL, 0, rx, sizeof rx);
    dan_periph_rx(&r->p, rx, (size_t)n, r->now);
    periph_wait_tx(r);
    assert_true(r->cap.len > 0u);
    /* one read: the echo of the identity, then CONFIGURE(115200) */
    memcpy(rx, r->cap.buf, r->cap.len);
    len = r->cap.len;
    len += configure_a(115200u, rx + len, sizeof rx - len);
    r->cap.len = 0;
    r->now += 20000u;
    dan_periph_rx(&r->p, rx, len, r->now);
    periph_wait_tx(r);
    assert_int_equal(r->p.stats.configures, 1);
    assert_int_equal(r->p.stats.nacks, 0);
    assert_int_equal(dan_periph_baud(&r->p), 9600); /* the ACK goes out at the old baud */
    /* the ACK's echo: it has left, the switch follows */
    dan_periph_rx(&r->p, r->cap.buf, r->cap.len, r->now + 10000u);
    dan_periph_poll(&r->p, r->now + 10001u);
    assert_int_equal(dan_periph_baud(&r->p), 115200);
    assert_int_equal(r->p.stats.baud_changes, 1);
}

/* A frame the peripheral ignores (a code of its block with no handler, like
 * one whose seal fails) arrives between a CONFIGURE and its ACK: it changes
 * nothing, as a bad CRC changes nothing. It cancelled the queued ACK and
 * the switch (review finding): the master then lost the peripheral. */
static void test_ignored_frame_keeps_configure_ack(void **state)
{
    cap_rig_t *r = cap_periph();
    uint8_t rx[32];
    int n;
    (void)state;
    dan_periph_rx(&r->p, rx, configure_a(115200u, rx, sizeof rx), r->now);
    n = dan_frame_encode(0x64, (const uint8_t *)"x", 1, rx, sizeof rx); /* no handler */
    dan_periph_rx(&r->p, rx, (size_t)n, r->now + 100u);
    periph_wait_tx(r);
    assert_true(r->cap.len > 0u); /* the ACK */
    assert_int_equal(r->p.stats.configures, 1);
    assert_int_equal(r->p.stats.overruns, 0);
    dan_periph_rx(&r->p, r->cap.buf, r->cap.len, r->now + 2000u); /* its echo: it has left */
    dan_periph_poll(&r->p, r->now + 2001u);
    assert_int_equal(dan_periph_baud(&r->p), 115200);
}

/* A collision breaks a peripheral's reply; the rest of that reply (it has
 * the request's code) later reaches the peripheral's decoder whole. It must
 * not be served as a request: that is how telemetry once became throttle. */
static void test_peripheral_ignores_own_reply_after_collision(void **state)
{
    static const uint8_t junk[] = {0x13, 0x37};
    uint8_t frame[16];
    uint32_t requests, replies;
    int n;
    (void)state;
    rig_discovered();
    assert_int_equal(dan_master_request(&rig.m, 0x62, (const uint8_t *)"abc", 3, rig.bus.now),
                     DAN_OK);
    while (rig.dev1.link.state != DAN_LINK_TX && rig.bus.now < 10000000u) {
        sim_step(&rig.bus);
    }
    sim_inject(&rig.bus, rig.n2, junk, sizeof junk); /* talks over the reply */
    while (rig.dev1.link.stats.collisions == 0 && rig.bus.now < 10000000u) {
        sim_step(&rig.bus);
    }
    assert_int_equal(rig.dev1.link.stats.collisions, 1);
    sim_run_for(&rig.bus, 50000);
    requests = rig.dev1.stats.requests;
    replies = rig.dev1.stats.replies;
    /* the whole reply arrives after all (another node plays it back) */
    n = dan_frame_encode(0x62, (const uint8_t *)"cba", 3, frame, sizeof frame);
    sim_inject(&rig.bus, rig.n2, frame, (size_t)n);
    sim_run_for(&rig.bus, 50000);
    assert_int_equal(rig.dev1.stats.own_echoes, 1);
    assert_int_equal(rig.dev1.stats.requests, requests);
    assert_int_equal(rig.dev1.stats.replies, replies);
    /* the master's retry still gets its answer (maybe already, meanwhile) */
    if (dan_master_busy(&rig.m)) {
        assert_int_equal(sim_run_master(&rig.bus, &rig.m, 5000000u), DAN_OK);
    }
    assert_int_equal(dan_master_result(&rig.m), DAN_OK);
    assert_memory_equal(rig.m.resp, "cba", 3);
}

/* API misuse gets clear errors. */
static void test_api_errors(void **state)
{
    dan_master_t m;
    dan_periph_t p;
    dan_port_t bad;
    (void)state;
    rig_setup(true);
    memset(&bad, 0, sizeof bad);
    assert_int_equal(dan_master_init(&m, &bad, NULL, probe_types, 1, 9600, 0), DAN_ERR_ARG);
    assert_int_equal(
        dan_master_init(&m, &rig.nm->port, NULL, probe_types, DAN_MASTER_MAX_TYPES + 1, 9600, 0),
        DAN_ERR_ARG);
    assert_int_equal(dan_periph_init(&p, &rig.n1->port, NULL, 0, NULL, 9600, 0), DAN_ERR_ARG);
    assert_int_equal(dan_master_configure(&rig.m, 0, rig.bus.now), DAN_ERR_NOTFOUND);
    assert_int_equal(dan_master_request(&rig.m, 0x62, NULL, 1, rig.bus.now), DAN_ERR_ARG);
    assert_int_equal(dan_master_request(&rig.m, 0x62, (const uint8_t *)"a", 1, rig.bus.now),
                     DAN_OK);
    assert_int_equal(dan_master_request(&rig.m, 0x62, (const uint8_t *)"a", 1, rig.bus.now),
                     DAN_ERR_BUSY);
    assert_int_equal(dan_master_discover(&rig.m, rig.bus.now), DAN_ERR_BUSY);
}

int main(void)
{
    return UNIT_RUN("engines", NULL, NULL, test_discovery_identities, test_configure_best_baud,
                    test_baud_switch_after_ack, test_turnaround_gap, test_unknown_malformed_silent,
                    test_master_restart_recovery, test_configure_verify_failure_recovers,
                    test_recovery_ack_lost_peer_kept, test_configure_peer_vanishes,
                    test_collision_detected_and_retried, test_listen_before_talk,
                    test_busy_line_times_out, test_noise_no_wrong_data, test_direction_pin,
                    test_discovery_configure_time, test_late_echo_is_not_a_reply,
                    test_reply_in_same_read_as_echo, test_direction_pin_reply_before_poll,
                    test_request_after_40_minutes_idle, test_partial_frame_next_us_waits_for_gap,
                    test_configure_in_same_read_as_echo, test_ignored_frame_keeps_configure_ack,
                    test_peripheral_ignores_own_reply_after_collision, test_api_errors);
}
