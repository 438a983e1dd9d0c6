/*
 * fc_firmware: libdan's master engine inside a flight-controller firmware
 * (Cortex-M4, QEMU mps2-an386). UART0 is the DAN bus; results go out over
 * semihosting as one JSON object per line; the exit code is 0 when every
 * required phase passed, else 1 (3: a fault).
 *
 * The main loop never blocks: the RX interrupt puts bytes into a ring, the
 * loop moves them into the engine, polls it, and runs one phase at a time.
 * A phase is a pair of functions in the table below: start() begins one
 * master operation (or asks to wait, or to skip), done() takes its result
 * and says whether the phase goes on, is finished, or failed. A new step
 * of the FC's work is one more row.
 *
 * Command line (QEMU: -append "..." or -semihosting-config ...,arg=...):
 *   gw=off|try|require   the gateway phase (default try: run it when a
 *                        can-gw is present, report but do not fail on it)
 *   fast=on|N            configure offers the fast bauds the UART can do
 *                        (board_fast_bauds(), highest first), or every fast
 *                        baud up to N (default: none, DAN v1 bauds only)
 *   buses=2              two buses instead (UART0 and UART1, a gateway on
 *                        each, both driving ESCs): twobus.c
 */
#include <string.h>

#include "dan/dan.h"
#include "dan/identity_json.h"
#include "dan/rxring.h"
#include "dan/can_gw/client.h"
#include "board.h"
#include "fw_out.h"
#include "twobus.h"

#ifndef FW_RUN_LIMIT_US
#define FW_RUN_LIMIT_US 120000000u /* the whole run, as a last resort */
#endif
#define TXN_COUNT        40u    /* test-a echo transactions */
#define RAMP_STEPS       40u    /* ESC commands in the throttle ramp */
#define RAMP_PERIOD_US   20000u /* 50 Hz command rate */
#define RAMP_MAX         2000   /* raw command at the top (of 8191) */
#define NUM_ESC          4u
#define NUM_TYPES        3u      /* bus_types */
#define DAN_START_BAUD   9600u   /* DAN starts at 9600 */
#define REPLY_LATENCY_US 400000u /* a reply may start this late: QEMU on a loaded host */
#define GAP_US           20000u  /* bytes may come in bursts this far apart */
#define RETRIES          2u      /* extra attempts per transaction */
#define BACKOFF_SEED     0x5EEDu /* any value: the backoff jitter's seed */
#define IDLE_MIN_US      1000u   /* sleep only when nothing is due within a SysTick */

/* ---- the application ---- */

typedef enum { STEP_AGAIN, STEP_NEXT, STEP_FAIL } step_t;

/* start(): DAN_OK (an operation started), FW_WAIT (call again later),
 * FW_SKIP (nothing to do: next phase) or an error (the phase failed). */
#define FW_WAIT 1
#define FW_SKIP 2

enum { GW_OFF = 0, GW_TRY, GW_REQUIRE };

typedef struct app app_t;
typedef struct {
    const char *name;
    int (*start)(app_t *a, uint64_t now);
    step_t (*done)(app_t *a, int result, uint64_t now);
} phase_t;

struct app {
    dan_master_t m;
    dan_identity_t ids[NUM_TYPES]; /* discovery reports them here */
    size_t phase;
    uint32_t k;          /* step within the phase */
    uint64_t op_t0;      /* when the running operation started */
    uint64_t not_before; /* FW_WAIT: start no sooner */
    bool op_running;
    /* transactions */
    uint8_t payload[32];
    size_t plen;
    uint32_t txn_ok, txn_bad;
    uint64_t txn_sum_us, txn_max_us;
    int gw_mode;
    dan_gw_t gw;
    uint32_t esc_ok;
    int gw_result;
};

static const uint32_t bus_types[NUM_TYPES] = {DAN_TYPE_TEST_A_FIRST, DAN_TYPE_TEST_B_FIRST,
                                              DAN_TYPE_CAN_GW_FIRST};

/* -- discover -- */

static int discover_start(app_t *a, uint64_t now)
{
    return dan_master_discover(&a->m, now);
}

static step_t discover_done(app_t *a, int r, uint64_t now)
{
    size_t i;
    bool first = true;
    o_begin("discover");
    o_result(r);
    o_key_num("ms", (now - a->op_t0) / 1000u);
    o_key_num("baud", dan_master_baud(&a->m));
    o_key("peers");
    o_str("[");
    for (i = 0; i < a->m.ntypes; i++) {
        const dan_peer_t *p = &a->m.peers[i];
        if (!p->present) {
            continue;
        }
        o_str(first ? "" : ",");
        out_len +=
            dan_peer_json(out_line + out_len, sizeof out_line - 1u - out_len, p, &a->ids[i], 0);
        first = false;
    }
    o_str("]");
    o_end();
    return (r == DAN_OK) ? STEP_NEXT : STEP_FAIL;
}

/* -- configure: the best common baud -- */

static int configure_start(app_t *a, uint64_t now)
{
    return dan_master_configure(&a->m, 0, now);
}

static step_t configure_done(app_t *a, int r, uint64_t now)
{
    o_begin("configure");
    o_result(r);
    o_key_num("baud", dan_master_baud(&a->m));
    o_key_num("uart_baud", uart_actual_baud(0u)); /* 25 MHz / divisor */
    o_key_num("ms", (now - a->op_t0) / 1000u);
    o_key_num("recoveries", a->m.stats.recoveries);
    o_key_num("fast_refusals", a->m.stats.fast_refusals);
    o_end();
    return (r == DAN_OK) ? STEP_NEXT : STEP_FAIL;
}

/* -- transactions: test-a reverses the payload of 0x62 -- */

static int txn_start(app_t *a, uint64_t now)
{
    size_t i;
    if (dan_master_peer(&a->m, DAN_TYPE_TEST_A_FIRST) == NULL) {
        return DAN_ERR_NOTFOUND;
    }
    a->plen = 1u + a->k % (uint32_t)sizeof a->payload;
    for (i = 0; i < a->plen; i++) {
        a->payload[i] = (uint8_t)(a->k * 7u + i * 13u);
    }
    return dan_master_request(&a->m, DAN_TYPE_TEST_A_FIRST + 2u, a->payload, a->plen, now);
}

static step_t txn_done(app_t *a, int r, uint64_t now)
{
    uint64_t us = now - a->op_t0;
    bool good = (r == DAN_OK && a->m.resp_len == a->plen);
    size_t i;
    for (i = 0; good && i < a->plen; i++) {
        good = (a->m.resp[i] == a->payload[a->plen - 1u - i]);
    }
    if (good) {
        a->txn_ok++;
    } else {
        a->txn_bad++;
    }
    a->txn_sum_us += us;
    if (us > a->txn_max_us) {
        a->txn_max_us = us;
    }
    if (++a->k < TXN_COUNT) {
        return STEP_AGAIN;
    }
    o_begin("transactions");
    o_key_num("code", DAN_TYPE_TEST_A_FIRST + 2u);
    o_key_num("count", TXN_COUNT);
    o_key_num("ok", a->txn_ok);
    o_key_num("bad", a->txn_bad);
    o_key_num("baud", dan_master_baud(&a->m));
    o_key_num("avg_us", a->txn_sum_us / TXN_COUNT);
    o_key_num("max_us", a->txn_max_us);
    o_key("last_payload");
    o_str("\"");
    o_hex(a->m.resp, a->m.resp_len);
    o_str("\"");
    o_end();
    return (a->txn_bad == 0u) ? STEP_NEXT : STEP_FAIL;
}

/* -- IDENTIFY of test-b at the configured baud, decoded -- */

static int ident_start(app_t *a, uint64_t now)
{
    if (dan_master_peer(&a->m, DAN_TYPE_TEST_B_FIRST) == NULL) {
        return FW_SKIP;
    }
    return dan_master_request(&a->m, DAN_TYPE_IDENTIFY(DAN_TYPE_TEST_B_FIRST), NULL, 0, now);
}

static step_t ident_done(app_t *a, int r, uint64_t now)
{
    dan_identity_t id;
    (void)now;
    if (r == DAN_OK) {
        r = dan_identity_decode(&id, a->m.resp, a->m.resp_len);
    }
    o_begin("identify");
    o_key_jstr("type", "test-b");
    o_result(r);
    o_key_num("baud", dan_master_baud(&a->m));
    if (r == DAN_OK) {
        o_key_jstr("model", id.model);
    }
    o_end();
    return (r == DAN_OK) ? STEP_NEXT : STEP_FAIL;
}

/* -- gateway: arm, a throttle ramp on four ESCs, telemetry, disarm -- */

static int16_t ramp_value(uint32_t k)
{
    /* k = 1..RAMP_STEPS: up to RAMP_MAX at the middle, back down to 0 */
    uint32_t half = RAMP_STEPS / 2u, pos = (k <= half) ? k : RAMP_STEPS - k;
    return (int16_t)((int32_t)RAMP_MAX * (int32_t)pos / (int32_t)half);
}

static void o_telem(const dan_gw_telem_t *t)
{
    o_str("{\"esc\":");
    o_u32(t->esc_index);
    o_key_num("node", t->node_id);
    o_key_num("flags", t->flags);
    o_key("rpm");
    o_int(t->rpm);
    o_key("mV");
    o_int((int32_t)(dan_f16_to_f32(t->voltage_f16) * 1000.0f));
    o_key("mA");
    o_int((int32_t)(dan_f16_to_f32(t->current_f16) * 1000.0f));
    o_key_num("power_pct", t->power_pct);
    o_key_num("age_ms", t->age_ms);
    o_str("}");
}

static int gw_start(app_t *a, uint64_t now)
{
    int16_t v[NUM_ESC];
    size_t i;
    if (a->k == 0u) {
        if (a->gw_mode == GW_OFF || dan_master_peer(&a->m, DAN_TYPE_CAN_GW_FIRST) == NULL) {
            o_begin("gateway");
            o_key_jstr("skipped", a->gw_mode == GW_OFF ? "gw=off" : "no can-gw on the bus");
            o_end();
            return a->gw_mode == GW_REQUIRE ? DAN_ERR_NOTFOUND : FW_SKIP;
        }
        dan_gw_init(&a->gw, &a->m);
        a->esc_ok = 0;
        return dan_gw_arm(&a->gw, true, now);
    }
    if (a->k <= RAMP_STEPS) {
        if (now < a->not_before) {
            return FW_WAIT;
        }
        a->not_before = now + RAMP_PERIOD_US;
        for (i = 0; i < NUM_ESC; i++) {
            v[i] = ramp_value(a->k);
        }
        return dan_gw_esc_command(&a->gw, v, NUM_ESC, now);
    }
    if (a->k == RAMP_STEPS + 1u) {
        return dan_gw_telemetry(&a->gw, 0, now);
    }
    return dan_gw_arm(&a->gw, false, now);
}

/* Ends the phase: a summary line; fatal only with gw=require. */
static step_t gw_finish(app_t *a, int r, const char *at)
{
    size_t i;
    bool first = true;
    o_begin("gateway");
    o_result(r);
    o_key_jstr("at", at);
    o_key("required");
    o_str(a->gw_mode == GW_REQUIRE ? "true" : "false");
    o_key_num("esc_commands_ok", a->esc_ok);
    o_key_num("flags", a->gw.gw_flags);
    o_key("telemetry");
    o_str("[");
    for (i = 0; r == DAN_OK && i < NUM_ESC && i < DAN_GW_MAX_ESC; i++) {
        if ((a->gw.esc[i].flags & DAN_GW_TELEM_STATUS) != 0u) {
            if (!first) {
                o_str(",");
            }
            o_telem(&a->gw.esc[i]);
            first = false;
        }
    }
    o_str("]");
    o_end();
    a->gw_result = r;
    return (r == DAN_OK || a->gw_mode != GW_REQUIRE) ? STEP_NEXT : STEP_FAIL;
}

static step_t gw_done(app_t *a, int r, uint64_t now)
{
    const char *at;
    r = dan_gw_complete(&a->gw, now);
    at = (a->k == 0u)                ? "arm"
         : (a->k <= RAMP_STEPS)      ? "esc_command"
         : (a->k == RAMP_STEPS + 1u) ? "telemetry"
                                     : "disarm";
    if (r != DAN_OK) {
        return gw_finish(a, r, at);
    }
    if (a->k == 0u && (a->gw.gw_flags & DAN_GW_FLAG_ARMED) == 0u) {
        return gw_finish(a, DAN_ERR_NACK, "arm (flag not set)");
    }
    if (a->k >= 1u && a->k <= RAMP_STEPS) {
        a->esc_ok++;
        if (a->k % 10u == 0u) {
            o_begin("gw_esc");
            o_key_num("k", a->k);
            o_key("throttle");
            o_int(ramp_value(a->k));
            o_key("telem");
            if (a->gw.last_telem < DAN_GW_MAX_ESC) {
                o_telem(&a->gw.esc[a->gw.last_telem]);
            } else {
                o_str("null");
            }
            o_end();
        }
    }
    if (++a->k <= RAMP_STEPS + 2u) {
        return STEP_AGAIN;
    }
    return gw_finish(a, DAN_OK, "done");
}

static const phase_t phases[] = {
    {"discover", discover_start, discover_done},
    {"configure", configure_start, configure_done},
    {"transactions", txn_start, txn_done},
    {"identify", ident_start, ident_done},
    {"gateway", gw_start, gw_done},
};
#define NUM_PHASES (sizeof phases / sizeof phases[0])

static void print_stats(const app_t *a, int code)
{
    const dan_master_stats_t *s = &a->m.stats;
    const dan_link_stats_t *l = &a->m.link.stats;
    const dan_decoder_stats_t *d = &a->m.link.dec.stats;
    o_begin("stats");
    o_key_num("transactions", s->transactions);
    o_key_num("ok", s->ok);
    o_key_num("timeouts", s->timeouts);
    o_key_num("retries", s->retries);
    o_key_num("collisions", l->collisions);
    o_key_num("echo_timeouts", l->echo_timeouts);
    o_key_num("crc_errors", d->crc_errors);
    o_key_num("rx_bytes", l->rx_bytes);
    o_key_num("tx_bytes", l->tx_bytes);
    o_key_num("rx_irqs", uart_stats[0].rx_irqs);
    o_key_num("uart_overruns", uart_stats[0].rx_overruns);
    o_key_num("ring_dropped", dan_rxring_dropped(&uart_rx[0]));
    o_key_num("baud_changes", uart_stats[0].baud_changes);
    o_key("exit");
    o_int(code);
    o_end();
}

static int parse_gw_mode(const char *cmdline)
{
    const char *p = strstr(cmdline, "gw=");
    if (p == NULL) {
        return GW_TRY;
    }
    p += 3;
    if (strncmp(p, "off", 3) == 0) {
        return GW_OFF;
    }
    if (strncmp(p, "require", 7) == 0) {
        return GW_REQUIRE;
    }
    return GW_TRY;
}

/* fast=on|N into the master's configuration (absent: no fast bauds). */
static void parse_fast(const char *cmdline, dan_master_config_t *cfg)
{
    const char *p = strstr(cmdline, "fast=");
    uint32_t n = 0;
    size_t nb;
    if (p == NULL) {
        return;
    }
    p += 5;
    if (strncmp(p, "on", 2) == 0) {
        cfg->fast_bauds = board_fast_bauds(&nb);
        cfg->nfast_bauds = (uint8_t)nb;
        cfg->fast_max_baud = UINT32_MAX; /* the list and the port's maximum decide */
        return;
    }
    while (*p >= '0' && *p <= '9' && n < 100000000u) {
        n = n * 10u + (uint32_t)(*p++ - '0');
    }
    cfg->fast_max_baud = n;
}

static void next_phase(app_t *a)
{
    a->phase++;
    a->k = 0;
    a->not_before = 0;
}

/* Starts the phase's next operation, or skips the phase. Returns DAN_OK
 * (started or skipped: go straight on), FW_WAIT (not before
 * a->not_before) or an error (reported: the run fails). */
static int start_phase(app_t *a, uint64_t now)
{
    int r = phases[a->phase].start(a, now);
    if (r == DAN_OK) {
        a->op_running = true;
        a->op_t0 = now;
    } else if (r == FW_SKIP) {
        next_phase(a);
        r = DAN_OK;
    } else if (r != FW_WAIT) {
        o_begin(phases[a->phase].name);
        o_result(r);
        o_end();
    }
    return r;
}

/* One turn of the main loop: -1 to go on, else the exit code. */
static int tick(app_t *a, uint64_t deadline)
{
    uint8_t buf[64];
    size_t n;
    uint64_t now, next;

    /* The only consumer of the ring: bytes go to the engine in order,
     * stamped with the time they are handed over. */
    while ((n = dan_rxring_get_many(&uart_rx[0], buf, sizeof buf)) > 0u) {
        dan_master_rx(&a->m, buf, n, clock_now_us());
    }
    now = clock_now_us();
    if (now > deadline) {
        o_begin(phases[a->phase].name);
        o_result(DAN_ERR_TIMEOUT);
        o_key_jstr("note", "run limit");
        o_end();
        return 1;
    }
    if (dan_master_poll(&a->m, now) && a->op_running) {
        step_t st;
        a->op_running = false;
        st = phases[a->phase].done(a, dan_master_result(&a->m), now);
        if (st == STEP_NEXT) {
            next_phase(a);
        }
        return st == STEP_FAIL ? 1 : -1;
    }
    if (!a->op_running) {
        int r = start_phase(a, now);
        if (r != FW_WAIT) {
            return r == DAN_OK ? -1 : 1;
        }
        next = a->not_before;
    } else {
        next = dan_master_next_us(&a->m);
    }
    if (next > now + IDLE_MIN_US) {
        board_idle(); /* wakes on the next SysTick (1 ms) or byte */
    }
    return -1;
}

static void print_boot(const app_t *a, const char *cmdline)
{
    o_begin("boot");
    o_key_jstr("fw", "fc_firmware");
    o_key_jstr("cmdline", cmdline);
    o_key_jstr("gw_mode", a->gw_mode == GW_OFF       ? "off"
                          : a->gw_mode == GW_REQUIRE ? "require"
                                                     : "try");
    o_key_num("fast_max", a->m.cfg.fast_max_baud);
    o_key_num("rxring", DAN_RXRING_SIZE);
    o_key_num("master_bytes", (uint32_t)sizeof a->m);
    o_end();
}

int main(void)
{
    static app_t a;
    static char cmdline[128];
    dan_master_config_t cfg;
    uint64_t now, deadline;
    int code = -1;

    clock_init();
    uart_init(0u, DAN_START_BAUD);
    sh_cmdline(cmdline, sizeof cmdline);
    if (strstr(cmdline, "buses=2") != NULL) {
        return twobus_main(cmdline);
    }
    a.gw_mode = parse_gw_mode(cmdline);

    /* The same settings as dan-master on a pty: a reply may start 50 ms
     * late and bytes may come in bursts (QEMU and the pty, not the wire). */
    dan_master_config_default(&cfg);
    cfg.resp_latency_us = REPLY_LATENCY_US;
    cfg.gap_us = GAP_US;
    cfg.retries = RETRIES;
    cfg.seed = BACKOFF_SEED;
    parse_fast(cmdline, &cfg);
    now = clock_now_us();
    deadline = now + FW_RUN_LIMIT_US;
    if (dan_master_init(&a.m, uart_port(0u), &cfg, bus_types,
                        sizeof bus_types / sizeof bus_types[0], DAN_START_BAUD, now) != DAN_OK) {
        sh_puts("{\"event\":\"init failed\"}\n");
        return 1;
    }
    dan_master_set_identities(&a.m, a.ids, NUM_TYPES);
    print_boot(&a, cmdline);
    while (code < 0 && a.phase < NUM_PHASES) {
        code = tick(&a, deadline);
    }
    if (code < 0) {
        code = 0;
    }
    print_stats(&a, code);
    return code;
}
