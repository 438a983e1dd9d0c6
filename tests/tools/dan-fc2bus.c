/*
 * dan-fc2bus: two DAN buses in one flight-controller process, each with a
 * CAN gateway, both driving ESCs from one poll loop (docs/PROTOCOL.md
 * section 6, "Several types on one UART": the draft also puts devices on
 * several UARTs). Each bus has its own caller-owned master and gateway
 * client; libdan keeps no state of its own, so a bus that fails (its
 * gateway killed, its wire jammed) cannot disturb the other.
 *
 *   dan-fc2bus --port A --port B [--baud 115200] [--seconds 10]
 *              [--latency-ms 50] [--values 10,20,30,40]
 *
 * Each bus: discover, configure to --baud, then ESC commands back to back
 * (bus k sends the values plus k); after 3 failures in a row it discovers
 * and configures again (as an FC must after a gateway's restart). Prints
 * one JSON line per bus per second ({"t", "bus", "exchanges", "errors",
 * "state"}) and one summary line per bus at the end. Exit 0, 1 when a bus
 * never ran, 2 for bad arguments.
 */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/codes.h"
#include "dan/master.h"
#include "dan/posix.h"
#include "dan/can_gw/client.h"
#include "dan_tool.h"

#define NBUS       2
#define NESC       4
#define RECOVER_IN 3u /* failures in a row that send a bus back to discovery */
#define POLL_MS    10

enum { ST_DISCOVER, ST_CONFIGURE, ST_ESC };
static const char *const STATE_NAME[] = {"discover", "configure", "esc"};

typedef struct {
    dan_posix_port_t port;
    dan_master_t m;
    dan_gw_t gw;
    int state;
    bool busy;
    int16_t v[NESC];
    uint32_t exchanges, errors, in_row, recoveries, window_ex, window_err;
} bus_t;

static bus_t g_bus[NBUS];
static uint32_t g_baud = 115200u;

/* Starts the bus's next operation. */
static void start(bus_t *b, uint64_t now)
{
    int rc;
    if (b->state == ST_DISCOVER) {
        rc = dan_master_discover(&b->m, now);
    } else if (b->state == ST_CONFIGURE) {
        rc = dan_master_configure(&b->m, g_baud, now);
    } else {
        rc = dan_gw_esc_command(&b->gw, b->v, NESC, now);
    }
    b->busy = rc == DAN_OK;
    if (!b->busy) {
        b->errors++;
        b->window_err++;
    }
}

/* The operation ended with rc: what the bus does next. */
static void done(bus_t *b, int rc)
{
    b->busy = false;
    if (b->state == ST_ESC) {
        if (rc == DAN_OK) {
            b->exchanges++;
            b->window_ex++;
            b->in_row = 0;
            return;
        }
        b->errors++;
        b->window_err++;
        if (++b->in_row >= RECOVER_IN) {
            b->in_row = 0;
            b->recoveries++;
            b->state = ST_DISCOVER;
        }
        return;
    }
    if (rc != DAN_OK ||
        (b->state == ST_DISCOVER && dan_master_peer(&b->m, DAN_TYPE_CAN_GW_FIRST) == NULL)) {
        b->state = ST_DISCOVER; /* try again */
        return;
    }
    b->state = b->state == ST_DISCOVER ? ST_CONFIGURE : ST_ESC;
}

static void report(uint64_t t0, uint64_t now)
{
    for (int k = 0; k < NBUS; k++) {
        bus_t *b = &g_bus[k];
        printf("{\"t\": %.3f, \"bus\": %d, \"exchanges\": %u, \"errors\": %u, \"state\": \"%s\"}\n",
               (double)(now - t0) / 1e6, k, b->window_ex, b->window_err, STATE_NAME[b->state]);
        b->window_ex = b->window_err = 0;
    }
    fflush(stdout);
}

static void loop(uint64_t seconds)
{
    uint64_t t0 = dan_posix_now_us(), end = t0 + seconds * 1000000u, tick = t0 + 1000000u;
    uint8_t buf[512];
    while (!tool_stop && dan_posix_now_us() < end) {
        struct pollfd pf[NBUS];
        uint64_t now = dan_posix_now_us(), next = tick;
        int k, n;
        for (k = 0; k < NBUS; k++) {
            bus_t *b = &g_bus[k];
            if (!b->busy) {
                start(b, now);
            }
            if (b->busy && dan_gw_poll(&b->gw, now)) {
                done(b, b->gw.result);
            }
            if (dan_master_next_us(&b->m) < next) {
                next = dan_master_next_us(&b->m);
            }
            pf[k].fd = b->port.fd;
            pf[k].events = POLLIN;
            pf[k].revents = 0;
        }
        n = tool_poll_until(pf, NBUS, next, POLL_MS);
        if (n < 0 && errno != EINTR) {
            break;
        }
        now = dan_posix_now_us();
        for (k = 0; k < NBUS; k++) {
            int r;
            while ((r = dan_posix_read(&g_bus[k].port, buf, sizeof buf)) > 0) {
                dan_master_rx(&g_bus[k].m, buf, (size_t)r, now);
            }
        }
        if (now >= tick) {
            report(t0, now);
            tick += 1000000u;
        }
    }
}

static int parse_values(const char *s, int16_t *v)
{
    char *end;
    for (int i = 0; i < NESC; i++) {
        long x = strtol(s, &end, 10);
        if (end == s || x < -8192 || x > 8191 || (i < NESC - 1 && *end != ',') ||
            (i == NESC - 1 && *end != '\0')) {
            return -1;
        }
        v[i] = (int16_t)x;
        s = end + 1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    static const uint32_t types[] = {DAN_TYPE_CAN_GW_FIRST};
    const char *ports[NBUS] = {NULL, NULL};
    int16_t values[NESC] = {10, 20, 30, 40};
    unsigned long seconds = 10, latency_ms = 50, v;
    int nport = 0, rc = 0;
    char err[256];
    tool_prog = "dan-fc2bus";
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *val = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--port") && val && nport < NBUS) {
            ports[nport++] = val;
        } else if (!strcmp(a, "--baud") && val &&
                   tool_parse_ulong(val, 10, 9600, 2000000, &v) == 0) {
            g_baud = (uint32_t)v;
        } else if (!strcmp(a, "--seconds") && val &&
                   tool_parse_ulong(val, 10, 1, 3600, &seconds) == 0) {
        } else if (!strcmp(a, "--latency-ms") && val &&
                   tool_parse_ulong(val, 10, 1, 10000, &latency_ms) == 0) {
        } else if (!strcmp(a, "--values") && val && parse_values(val, values) == 0) {
        } else {
            tool_error("bad argument '%s' (usage: --port A --port B [--baud B] [--seconds S] "
                       "[--latency-ms MS] [--values V1,V2,V3,V4])",
                       a);
            return 2;
        }
        i++;
    }
    if (nport != NBUS) {
        tool_error("two --port options are needed");
        return 2;
    }
    signal(SIGPIPE, SIG_IGN);
    tool_catch_signal(SIGTERM);
    tool_catch_signal(SIGINT);
    tool_fine_timers();
    for (int k = 0; k < NBUS; k++) {
        bus_t *b = &g_bus[k];
        dan_master_config_t mc;
        if (dan_posix_open(&b->port, ports[k], 9600, DAN_POSIX_ECHO, err, sizeof err) != DAN_OK) {
            tool_error("%s", err);
            return 2;
        }
        dan_master_config_default(&mc);
        mc.resp_latency_us = (uint32_t)latency_ms * 1000u;
        mc.gap_us = 20000u;
        mc.retries = 2;
        if (dan_master_init(&b->m, dan_posix_port(&b->port), &mc, types, 1, 9600,
                            dan_posix_now_us()) != DAN_OK) {
            tool_error("master init failed");
            return 2;
        }
        dan_gw_init(&b->gw, &b->m);
        for (int i = 0; i < NESC; i++) {
            b->v[i] = (int16_t)(values[i] + k);
        }
    }
    loop(seconds);
    for (int k = 0; k < NBUS; k++) {
        bus_t *b = &g_bus[k];
        printf("{\"summary\": true, \"bus\": %d, \"exchanges\": %u, \"errors\": %u, "
               "\"recoveries\": %u, \"values\": [%d, %d, %d, %d]}\n",
               k, b->exchanges, b->errors, b->recoveries, b->v[0], b->v[1], b->v[2], b->v[3]);
        rc |= b->exchanges == 0u;
        dan_posix_close(&b->port);
    }
    return rc;
}
