/*
 * dan-testperiph: a DAN peripheral of test types on a serial port, for the
 * end-to-end tests of the engines.
 *
 *   dan-testperiph --port EP --types test-a,test-b [--mask 0x0F] [--no-echo]
 *
 * Type test-a serves 0x62 (reply: the payload reversed; empty payload is
 * malformed) and 0x63 (no reply). Prints "READY" once open; on SIGTERM or
 * SIGINT prints its counters as one JSON line and exits 0.
 */
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/dan.h"
#include "dan/posix.h"
#include "handlers_test_a.h"

static volatile sig_atomic_t stop_flag;

static void on_signal(int sig)
{
    (void)sig;
    stop_flag = 1;
}

int main(int argc, char **argv)
{
    static dan_posix_port_t port;
    static dan_periph_t p;
    static dan_identity_t ids[4];
    static dan_ptype_t types[4];
    static unsigned silent;
    const char *path = NULL, *types_arg = "test-a";
    unsigned long mask = 0x0F, window_ms = 50, gap_ms = 20, baud = 9600;
    bool no_echo = false;
    size_t ntypes = 0;
    char err[256], tbuf[128], *tok, *save = NULL;
    dan_periph_config_t cfg;
    int i;

    for (i = 1; i < argc; i++) {
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        if (strcmp(argv[i], "--no-echo") == 0) {
            no_echo = true;
            continue;
        }
        if (v == NULL) {
            fprintf(stderr, "dan-testperiph: bad or incomplete option %s\n", argv[i]);
            return 2;
        }
        if (strcmp(argv[i], "--port") == 0) {
            path = v;
        } else if (strcmp(argv[i], "--types") == 0) {
            types_arg = v;
        } else if (strcmp(argv[i], "--mask") == 0) {
            mask = strtoul(v, NULL, 0);
        } else if (strcmp(argv[i], "--window-ms") == 0) {
            window_ms = strtoul(v, NULL, 0);
        } else if (strcmp(argv[i], "--gap-ms") == 0) {
            gap_ms = strtoul(v, NULL, 0);
        } else if (strcmp(argv[i], "--baud") == 0) {
            baud = strtoul(v, NULL, 0);
        } else {
            fprintf(stderr, "dan-testperiph: unknown option %s\n", argv[i]);
            return 2;
        }
        i++;
    }
    if (path == NULL || baud == 0) {
        fprintf(stderr, "dan-testperiph: --port is required\n");
        return 2;
    }
    snprintf(tbuf, sizeof tbuf, "%s", types_arg);
    for (tok = strtok_r(tbuf, ",", &save); tok != NULL; tok = strtok_r(NULL, ",", &save)) {
        const dan_type_info_t *t = dan_type_lookup(tok);
        if (t == NULL || ntypes >= 4) {
            fprintf(stderr, "dan-testperiph: unknown type %s\n", tok);
            return 2;
        }
        ids[ntypes].dan_version = DAN_VERSION;
        snprintf(ids[ntypes].manufacturer, DAN_MAX_STRING, "DAN Project");
        snprintf(ids[ntypes].model, DAN_MAX_STRING, "%s", t->name);
        snprintf(ids[ntypes].hw_version, DAN_MAX_STRING, "sim");
        snprintf(ids[ntypes].sw_version, DAN_MAX_STRING, "1.0.%zu", ntypes);
        ids[ntypes].baud_mask = (uint16_t)mask;
        types[ntypes].first = t->first;
        types[ntypes].identity = &ids[ntypes];
        if (t->first == DAN_TYPE_TEST_A_FIRST) {
            types[ntypes].handlers = test_a_handlers;
            types[ntypes].nhandlers = TEST_A_NHANDLERS;
            types[ntypes].user = &silent;
        }
        ntypes++;
    }
    if (dan_posix_open(&port, path, (uint32_t)baud, no_echo ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO, err,
                       sizeof err) != DAN_OK) {
        fprintf(stderr, "dan-testperiph: %s\n", err);
        return 2;
    }
    dan_periph_config_default(&cfg);
    cfg.reply_window_us = (uint32_t)window_ms * 1000u;
    cfg.gap_us = (uint32_t)gap_ms * 1000u;
    dan_periph_init(&p, dan_posix_port(&port), types, ntypes, &cfg, (uint32_t)baud, dan_posix_now_us());
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    printf("READY\n");
    fflush(stdout);
    while (!stop_flag) {
        uint8_t buf[512];
        struct pollfd pfd = {port.fd, POLLIN, 0};
        uint64_t now = dan_posix_now_us(), next = dan_periph_next_us(&p);
        int ms = (next == UINT64_MAX) ? 100 : (next <= now) ? 0 : (int)((next - now + 999u) / 1000u);
        if (ms > 100) {
            ms = 100;
        }
        if (poll(&pfd, 1, ms) > 0) {
            int n = dan_posix_read(&port, buf, sizeof buf);
            if (n < 0) {
                fprintf(stderr, "dan-testperiph: port read failed\n");
                break;
            }
            dan_periph_rx(&p, buf, (size_t)n, dan_posix_now_us());
        }
        dan_periph_poll(&p, dan_posix_now_us());
    }
    printf("{\"requests\":%u,\"replies\":%u,\"unknown\":%u,\"errors_sent\":%u,\"late\":%u,\"overruns\":%u,"
           "\"configures\":%u,\"nacks\":%u,\"baud_changes\":%u,\"baud\":%u,\"silent\":%u,\"collisions\":%u,"
           "\"crc_errors\":%u}\n",
           p.stats.requests, p.stats.replies, p.stats.unknown, p.stats.errors_sent, p.stats.late,
           p.stats.overruns, p.stats.configures, p.stats.nacks, p.stats.baud_changes, dan_periph_baud(&p),
           silent, p.link.stats.collisions, p.link.dec.stats.crc_errors);
    dan_posix_close(&port);
    return 0;
}
