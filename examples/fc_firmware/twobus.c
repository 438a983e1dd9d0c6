/*
 * Two DAN buses in one firmware (command line buses=2): UART0 and UART1,
 * each with a CAN gateway on it, each driven by its own master and gateway
 * client from the one main loop, as an FC puts devices of one type on
 * several UARTs. libdan keeps no state of its own, so a bus that fails
 * (its gateway gone) cannot disturb the other. The firmware counterpart
 * of tests/tools/dan-fc2bus.c.
 *
 * Each bus: discover (the can-gw type), configure (the best common baud),
 * ARM, then ESC commands at 100 Hz, bus k sending 10 + k, 20 + k, 30 + k,
 * 40 + k; after 3 failures in a row it starts again at discover (its
 * gateway restarted at 9600). Once a second one line per bus:
 *   {"step":"bus","ms","bus","exchanges","errors","state"}
 * (that second's counts); at the end one line per bus:
 *   {"step":"bus_summary","bus","exchanges","errors","recoveries","baud","values"}
 * It ends when a 'q' arrives on UART2 (the host's control line) or after
 * seconds=N (default 600); exit 0 when both buses ran, else 1.
 */
#include <string.h>

#include "dan/dan.h"
#include "dan/can_gw/client.h"
#include "board.h"
#include "fw_out.h"
#include "twobus.h"

#define TB_NESC        4u
#define TB_RECOVER_IN  3u       /* failures in a row that send a bus back to discovery */
#define TB_PERIOD_US   10000u   /* 100 Hz: the Python ESCs behind the hub keep up */
#define TB_REPORT_US   1000000u /* a line per bus per second */
#define TB_LATENCY_US  400000u  /* a reply may start this late: QEMU on a loaded host */
#define TB_GAP_US      20000u   /* bytes may come in bursts this far apart */
#define TB_RETRIES     2u       /* extra attempts per transaction */
#define TB_START_BAUD  9600u    /* DAN starts at 9600 */
#define TB_SECONDS     600u     /* the run's default length */
#define TB_IDLE_MIN_US 1000u    /* sleep only when nothing is due within a SysTick */
#define TB_SEED        0x2B05u  /* any value: the backoff jitter's seed */

enum { TB_DISCOVER, TB_CONFIGURE, TB_ARM, TB_ESC };
static const char *const tb_state_name[] = {"discover", "configure", "arm", "esc"};

typedef struct {
    dan_master_t m;
    dan_gw_t gw;
    dan_identity_t id;
    int state;
    bool busy;
    uint64_t not_before;
    int16_t v[TB_NESC];
    uint32_t exchanges, errors, in_row, recoveries, win_ex, win_err;
} tb_bus_t;

static tb_bus_t tb_bus[BOARD_UARTS];
static const uint32_t tb_types[] = {DAN_TYPE_CAN_GW_FIRST};

static void tb_error(tb_bus_t *b)
{
    b->errors++;
    b->win_err++;
}

/* Starts the bus's next operation (or waits for the next ESC period). */
static void tb_start(tb_bus_t *b, uint64_t now)
{
    int rc;
    if (now < b->not_before) {
        return;
    }
    if (b->state == TB_DISCOVER) {
        rc = dan_master_discover(&b->m, now);
    } else if (b->state == TB_CONFIGURE) {
        rc = dan_master_configure(&b->m, 0, now);
    } else if (b->state == TB_ARM) {
        rc = dan_gw_arm(&b->gw, true, now);
    } else {
        b->not_before = now + TB_PERIOD_US;
        rc = dan_gw_esc_command(&b->gw, b->v, TB_NESC, now);
    }
    b->busy = rc == DAN_OK;
    if (!b->busy) {
        tb_error(b);
    }
}

/* The operation ended with rc: what the bus does next. */
static void tb_done(tb_bus_t *b, int rc)
{
    b->busy = false;
    if (b->state == TB_ESC) {
        if (rc == DAN_OK) {
            b->exchanges++;
            b->win_ex++;
            b->in_row = 0;
            return;
        }
        tb_error(b);
        if (++b->in_row >= TB_RECOVER_IN) {
            b->in_row = 0;
            b->recoveries++;
            b->state = TB_DISCOVER;
        }
        return;
    }
    if (rc != DAN_OK ||
        (b->state == TB_DISCOVER && dan_master_peer(&b->m, DAN_TYPE_CAN_GW_FIRST) == NULL)) {
        b->state = TB_DISCOVER; /* try again */
        return;
    }
    b->state++;
}

static void tb_report(uint64_t t0, uint64_t now)
{
    unsigned k;
    for (k = 0; k < BOARD_UARTS; k++) {
        tb_bus_t *b = &tb_bus[k];
        o_begin("bus");
        o_key_num("ms", (now - t0) / 1000u);
        o_key_num("bus", k);
        o_key_num("exchanges", b->win_ex);
        o_key_num("errors", b->win_err);
        o_key_jstr("state", tb_state_name[b->state]);
        o_end();
        b->win_ex = b->win_err = 0;
    }
}

static int tb_summary(void)
{
    unsigned k, i;
    int code = 0;
    for (k = 0; k < BOARD_UARTS; k++) {
        tb_bus_t *b = &tb_bus[k];
        o_begin("bus_summary");
        o_key_num("bus", k);
        o_key_num("exchanges", b->exchanges);
        o_key_num("errors", b->errors);
        o_key_num("recoveries", b->recoveries);
        o_key_num("baud", dan_master_baud(&b->m));
        o_key("values");
        for (i = 0; i < TB_NESC; i++) {
            o_str(i == 0u ? "[" : ",");
            o_int(b->v[i]);
        }
        o_str("]");
        o_end();
        code |= b->exchanges == 0u;
    }
    return code;
}

/* One turn of the loop over both buses; the earliest time anything is due. */
static uint64_t tb_turn(void)
{
    uint8_t buf[64];
    uint64_t next = UINT64_MAX;
    unsigned k;
    for (k = 0; k < BOARD_UARTS; k++) {
        tb_bus_t *b = &tb_bus[k];
        size_t n;
        uint64_t now, due;
        while ((n = dan_rxring_get_many(&uart_rx[k], buf, sizeof buf)) > 0u) {
            dan_master_rx(&b->m, buf, n, clock_now_us());
        }
        now = clock_now_us();
        if (b->busy && dan_gw_poll(&b->gw, now)) {
            tb_done(b, b->gw.result);
        }
        if (!b->busy) {
            tb_start(b, now);
        }
        due = b->busy ? dan_master_next_us(&b->m) : b->not_before;
        next = due < next ? due : next;
    }
    return next;
}

static uint32_t tb_parse_seconds(const char *cmdline)
{
    const char *p = strstr(cmdline, "seconds=");
    uint32_t n = 0;
    if (p == NULL) {
        return TB_SECONDS;
    }
    for (p += 8; *p >= '0' && *p <= '9' && n < 100000u; p++) {
        n = n * 10u + (uint32_t)(*p - '0');
    }
    return n > 0u ? n : TB_SECONDS;
}

static int tb_init(void)
{
    dan_master_config_t cfg;
    unsigned k, i;
    dan_master_config_default(&cfg);
    cfg.resp_latency_us = TB_LATENCY_US;
    cfg.gap_us = TB_GAP_US;
    cfg.retries = TB_RETRIES;
    for (k = 0; k < BOARD_UARTS; k++) {
        tb_bus_t *b = &tb_bus[k];
        uart_init(k, TB_START_BAUD);
        cfg.seed = TB_SEED + k;
        if (dan_master_init(&b->m, uart_port(k), &cfg, tb_types, 1, TB_START_BAUD,
                            clock_now_us()) != DAN_OK) {
            return 1;
        }
        dan_master_set_identities(&b->m, &b->id, 1);
        dan_gw_init(&b->gw, &b->m);
        for (i = 0; i < TB_NESC; i++) {
            b->v[i] = (int16_t)(10 * (int)(i + 1u) + (int)k);
        }
    }
    ctl_init();
    return 0;
}

int twobus_main(const char *cmdline)
{
    uint64_t t0, end, tick;
    o_begin("boot");
    o_key_jstr("fw", "fc_firmware");
    o_key_jstr("cmdline", cmdline);
    o_key_num("buses", BOARD_UARTS);
    o_end();
    if (tb_init() != 0) {
        sh_puts("{\"event\":\"init failed\"}\n");
        return 1;
    }
    t0 = clock_now_us();
    end = t0 + (uint64_t)tb_parse_seconds(cmdline) * 1000000u;
    tick = t0 + TB_REPORT_US;
    for (;;) {
        uint64_t next = tb_turn(), now = clock_now_us();
        if (ctl_getc() == 'q' || now >= end) {
            break;
        }
        if (now >= tick) {
            tb_report(t0, now);
            tick += TB_REPORT_US;
        }
        next = next < tick ? next : tick;
        if (next > now + TB_IDLE_MIN_US) {
            board_idle(); /* wakes on the next SysTick (1 ms) or byte */
        }
    }
    return tb_summary();
}
