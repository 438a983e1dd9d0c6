/*
 * dan-testperiph: a DAN peripheral of test types on a serial port, for the
 * end-to-end tests of the engines.
 *
 *   dan-testperiph --port EP --types test-a,test-b [--mask 0x0F] [--no-echo]
 *                  [--v1-only] [--ack-no-switch]
 *
 * By default it also accepts the fast bauds (dan_fast_bauds, 230400 to
 * 2000000; docs/PROTOCOL.md section 6); --v1-only accepts only 9600 and
 * its mask, as a peripheral that knows only DAN v1. --ack-no-switch
 * acknowledges a CONFIGURE to a fast baud and does not switch (its UART
 * stays where it was): the faulty peripheral the master must recover.
 *
 * Type test-a serves 0x62 (reply: the payload reversed; empty payload is
 * malformed) and 0x63 (no reply). Prints "READY" once open; on SIGTERM or
 * SIGINT prints its counters as one JSON line and exits 0.
 */
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/dan.h"
#include "dan/posix.h"
#include "dan_tool.h"
#include "handlers_test_a.h"

/* Types one peripheral serves here: as many as the tests combine. */
#define MAX_TYPES   4u
/* Longest a poll() waits, so a signal is seen this soon. */
#define POLL_CAP_MS 100

typedef struct {
    const char *path, *types;
    unsigned long mask, window_ms, gap_ms, baud;
    bool no_echo, v1_only, ack_no_switch;
} opts_t;

/* The numbers an option sets, or NULL for any other option. */
static unsigned long *number_option(opts_t *o, const char *a)
{
    const struct {
        const char *name;
        unsigned long *dst;
    } nums[] = {
        {"--mask", &o->mask},
        {"--window-ms", &o->window_ms},
        {"--gap-ms", &o->gap_ms},
        {"--baud", &o->baud},
    };
    size_t i;
    for (i = 0; i < sizeof nums / sizeof nums[0]; i++) {
        if (strcmp(a, nums[i].name) == 0) {
            return nums[i].dst;
        }
    }
    return NULL;
}

/* Returns -1 to go on, else the exit code. Numbers are read leniently
 * (strtoul), as the tests have always passed them. */
static int parse_options(int argc, char **argv, opts_t *o)
{
    int i;
    for (i = 1; i < argc; i++) {
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        unsigned long *num = number_option(o, argv[i]);
        bool *flag = strcmp(argv[i], "--no-echo") == 0         ? &o->no_echo
                     : strcmp(argv[i], "--v1-only") == 0       ? &o->v1_only
                     : strcmp(argv[i], "--ack-no-switch") == 0 ? &o->ack_no_switch
                                                               : NULL;
        if (flag != NULL) {
            *flag = true;
            continue;
        }
        if (v == NULL) {
            tool_error("bad or incomplete option %s", argv[i]);
            return 2;
        }
        if (strcmp(argv[i], "--port") == 0) {
            o->path = v;
        } else if (strcmp(argv[i], "--types") == 0) {
            o->types = v;
        } else if (num != NULL) {
            *num = strtoul(v, NULL, 0);
        } else {
            tool_error("unknown option %s", argv[i]);
            return 2;
        }
        i++;
    }
    if (o->path == NULL || o->baud == 0) {
        tool_error("--port is required");
        return 2;
    }
    return -1;
}

/* The types of the --types list with their identities; 0 or -1. test-a
 * gets its handlers, which count silent commands in *silent. */
static int setup_types(const opts_t *o, dan_ptype_t *types, dan_identity_t *ids, size_t *n,
                       unsigned *silent)
{
    const dan_type_info_t *t[MAX_TYPES];
    char bad[128];
    size_t k;
    if (tool_parse_types(o->types, t, MAX_TYPES, n, bad, sizeof bad) != 0) {
        tool_error("unknown type %s", bad);
        return -1;
    }
    for (k = 0; k < *n; k++) {
        ids[k].dan_version = DAN_VERSION;
        snprintf(ids[k].manufacturer, DAN_MAX_STRING, "DAN Project");
        snprintf(ids[k].model, DAN_MAX_STRING, "%s", t[k]->name);
        snprintf(ids[k].hw_version, DAN_MAX_STRING, "sim");
        snprintf(ids[k].sw_version, DAN_MAX_STRING, "1.0.%zu", k);
        ids[k].baud_mask = (uint16_t)o->mask;
        types[k].first = t[k]->first;
        types[k].identity = &ids[k];
        if (t[k]->first == DAN_TYPE_TEST_A_FIRST) {
            types[k].handlers = test_a_handlers;
            types[k].nhandlers = TEST_A_NHANDLERS;
            types[k].user = silent;
        }
    }
    return 0;
}

/* Serves requests until a signal or a lost port. */
static void serve(dan_periph_t *p, dan_posix_port_t *port)
{
    uint8_t buf[512];
    while (!tool_stop) {
        if (tool_wait_fd(port->fd, POLLIN, dan_periph_next_us(p), POLL_CAP_MS) > 0) {
            int n = dan_posix_read(port, buf, sizeof buf);
            if (n < 0) {
                tool_error("port read failed");
                break;
            }
            dan_periph_rx(p, buf, (size_t)n, dan_posix_now_us());
        }
        dan_periph_poll(p, dan_posix_now_us());
    }
}

/* --ack-no-switch: the real port's set_baud, and a stand-in that ignores
 * the fast bauds (the engine believes it switched). */
static dan_port_t real_port;
static int set_baud_v1_only(void *ctx, uint32_t baud)
{
    return dan_baud_is_v1(baud) ? real_port.set_baud(ctx, baud) : DAN_OK;
}

static void print_counters(const dan_periph_t *p, unsigned silent)
{
    printf("{\"requests\":%u,\"replies\":%u,\"unknown\":%u,\"errors_sent\":%u,\"late\":%u,"
           "\"overruns\":%u,\"configures\":%u,\"nacks\":%u,\"baud_changes\":%u,\"baud\":%u,"
           "\"silent\":%u,\"collisions\":%u,\"crc_errors\":%u}\n",
           p->stats.requests, p->stats.replies, p->stats.unknown, p->stats.errors_sent,
           p->stats.late, p->stats.overruns, p->stats.configures, p->stats.nacks,
           p->stats.baud_changes, dan_periph_baud(p), silent, p->link.stats.collisions,
           p->link.dec.stats.crc_errors);
}

int main(int argc, char **argv)
{
    static dan_posix_port_t port;
    static dan_periph_t p;
    static dan_identity_t ids[MAX_TYPES];
    static dan_ptype_t types[MAX_TYPES];
    static unsigned silent;
    opts_t o = {NULL, "test-a", 0x0F, 50, 20, 9600, false, false, false};
    size_t ntypes = 0;
    char err[256];
    dan_periph_config_t cfg;
    int r;

    tool_prog = "dan-testperiph";
    r = parse_options(argc, argv, &o);
    if (r >= 0) {
        return r;
    }
    if (setup_types(&o, types, ids, &ntypes, &silent) != 0) {
        return 2;
    }
    if (dan_posix_open(&port, o.path, (uint32_t)o.baud,
                       o.no_echo ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO, err, sizeof err) != DAN_OK) {
        tool_error("%s", err);
        return 2;
    }
    dan_periph_config_default(&cfg);
    cfg.reply_window_us = (uint32_t)o.window_ms * 1000u;
    cfg.gap_us = (uint32_t)o.gap_ms * 1000u;
    if (!o.v1_only) {
        cfg.extra_bauds = dan_fast_bauds;
        cfg.nextra_bauds = DAN_NFAST_BAUDS;
    }
    real_port = *dan_posix_port(&port);
    if (o.ack_no_switch) {
        port.port.set_baud = set_baud_v1_only;
    }
    dan_periph_init(&p, dan_posix_port(&port), types, ntypes, &cfg, (uint32_t)o.baud,
                    dan_posix_now_us());
    tool_catch_signal(SIGINT);
    tool_catch_signal(SIGTERM);
    tool_fine_timers();
    printf("READY\n");
    fflush(stdout);
    serve(&p, &port);
    print_counters(&p, silent);
    dan_posix_close(&port);
    return 0;
}
