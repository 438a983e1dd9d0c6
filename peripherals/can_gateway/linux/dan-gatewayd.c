/*
 * dan-gatewayd: the CAN-over-DAN gateway daemon (Linux).
 *
 *   dan-gatewayd --uart TTY --can BACKEND [options]
 *
 * A DAN peripheral (type 0x40) on a UART and a DroneCAN node on a CAN
 * interface (socketcan:IF or slcan:/dev/TTY[@BAUD]). One poll() loop over
 * the UART, the CAN fd and the engines' timers; signal handlers only set a
 * flag. SIGTERM/SIGINT: failsafe (zero throttle + DISARMED, flushed to
 * CAN), then exit 0. A lost CAN adapter is reported and reopened every
 * second. Exit 2: bad arguments or a device that cannot be opened.
 */
#include <errno.h>
#include <getopt.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <syslog.h>
#include <time.h>
#include <unistd.h>

#include "dan/peripheral.h"
#include "dan/posix.h"
#include "dan/can_gw/node.h"
#include "can_backend.h"

#define REOPEN_US 1000000u
#define SHUTDOWN_FLUSH_US 500000u

static volatile sig_atomic_t g_stop;
static int g_syslog;
static int g_verbose;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static void logmsg(int prio, const char *fmt, ...)
{
    va_list ap;
    if (prio == LOG_DEBUG && !g_verbose) {
        return;
    }
    va_start(ap, fmt);
    if (g_syslog) {
        vsyslog(prio, fmt, ap);
    } else {
        fputs("dan-gatewayd: ", stderr);
        vfprintf(stderr, fmt, ap);
        fputc('\n', stderr);
    }
    va_end(ap);
}

static void usage(FILE *o)
{
    fprintf(o,
        "usage: dan-gatewayd --uart TTY --can BACKEND [options]\n"
        "  --uart TTY            DAN UART (single-wire bus)\n"
        "  --can SPEC            socketcan:IFNAME | slcan:/dev/TTY[@BAUD]\n"
        "  --node-id N           DroneCAN node id, 1..127 (default 10)\n"
        "  --uart-baud B         start baud (default 9600, the DAN power-up baud)\n"
        "  --no-echo             the UART does not hear its own bytes\n"
        "  --de-gpio CHIP:LINE   RS-485 direction pin (libgpiod)\n"
        "  --de-active-low       the pin is active low\n"
        "  --esc-timeout-ms N    failsafe after N ms without ESC commands (50..60000, default 500)\n"
        "  --arming-rate-hz N    ArmingStatus rate, 1..50 (default 2)\n"
        "  --gap-ms N            DAN inter-byte gap (default 20; ptys and USB add latency)\n"
        "  --reply-window-ms N   DAN reply window (default 50)\n"
        "  --stats-file PATH     write counters as JSON every second\n"
        "  --syslog              log to syslog instead of stderr\n"
        "  --verbose             more log lines\n"
        "  --help\n"
        "exit: 0 after SIGTERM/SIGINT, 1 runtime failure, 2 bad arguments or device\n");
}

static int parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    char *end;
    unsigned long v;
    errno = 0;
    v = strtoul(s, &end, 0);
    if (errno || *s == '\0' || *end != '\0' || v < lo || v > hi) {
        return -1;
    }
    *out = (uint32_t)v;
    return 0;
}

typedef struct {
    dan_posix_port_t uart;
    dan_periph_t periph;
    dan_gw_node_t node;
    dan_ptype_t ptype;
    dan_canif_t can;
    const char *can_spec;
    bool can_up;
    uint64_t reopen_us;
    const char *stats_file;
    uint64_t stats_due_us;
    uint32_t failsafes_logged;
} gwd_t;

static void can_down(gwd_t *d, const char *why, uint64_t now)
{
    logmsg(LOG_ERR, "CAN %s: %s; reopening every %u ms", d->can_spec, why, REOPEN_US / 1000u);
    dan_canif_close(&d->can);
    d->can_up = false;
    dan_gw_node_can_state(&d->node, false);
    dan_gw_node_can_error(&d->node);
    d->reopen_us = now + REOPEN_US;
}

/* Sends queued frames; while the CAN side is down they are dropped (stale
 * ESC commands must not go out late). */
static void can_drain(gwd_t *d, uint64_t now)
{
    dan_can_frame_t f;
    if (!d->can_up) {
        while (dan_gw_node_tx_peek(&d->node, &f)) {
            dan_gw_node_tx_pop(&d->node);
            d->node.stats.can_tx_dropped++;
        }
        return;
    }
    if (dan_canif_tx_pending(&d->can)) {
        int r = dan_canif_flush(&d->can);
        if (r == DAN_ERR_IO) {
            can_down(d, "write failed", now);
            return;
        }
        if (r == DAN_ERR_BUSY) {
            return;
        }
    }
    while (dan_gw_node_tx_peek(&d->node, &f)) {
        int r = dan_canif_send(&d->can, &f);
        if (r == DAN_ERR_BUSY) {
            break;
        }
        if (r == DAN_ERR_IO) {
            can_down(d, "write failed", now);
            return;
        }
        dan_gw_node_tx_pop(&d->node);
        if (r != DAN_OK) {
            dan_gw_node_can_error(&d->node);
        }
        if (dan_canif_tx_pending(&d->can)) {
            break;
        }
    }
}

static void can_read(gwd_t *d, uint64_t now)
{
    dan_can_frame_t f;
    int i, r;
    for (i = 0; i < 64; i++) {
        r = dan_canif_recv(&d->can, &f);
        if (r == 0) {
            return;
        }
        if (r < 0) {
            can_down(d, "adapter lost", now);
            return;
        }
        dan_gw_node_rx_can(&d->node, &f, now);
    }
}

static void write_stats(gwd_t *d)
{
    char tmp[512];
    FILE *f;
    uint32_t v[DAN_GW_STAT_COUNT];
    unsigned i;
    snprintf(tmp, sizeof tmp, "%s.tmp", d->stats_file);
    f = fopen(tmp, "w");
    if (f == NULL) {
        return;
    }
    dan_gw_node_counters(&d->node, v);
    fputc('{', f);
    for (i = 0; i < DAN_GW_STAT_COUNT; i++) {
        fprintf(f, "\"%s\": %u, ", dan_gw_stat_name(i), v[i]);
    }
    fprintf(f, "\"can_up\": %d, \"baud\": %u}\n", d->can_up ? 1 : 0, dan_periph_baud(&d->periph));
    fclose(f);
    (void)rename(tmp, d->stats_file); /* readers never see a half-written file */
}

static gwd_t g_d; /* large (tunnel buffers): static storage, used only by main */

int main(int argc, char **argv)
{
    static const struct option opts[] = {
        {"uart", required_argument, NULL, 'u'},
        {"can", required_argument, NULL, 'c'},
        {"node-id", required_argument, NULL, 'n'},
        {"uart-baud", required_argument, NULL, 'b'},
        {"no-echo", no_argument, NULL, 'E'},
        {"de-gpio", required_argument, NULL, 'g'},
        {"de-active-low", no_argument, NULL, 'L'},
        {"esc-timeout-ms", required_argument, NULL, 't'},
        {"arming-rate-hz", required_argument, NULL, 'a'},
        {"gap-ms", required_argument, NULL, 'G'},
        {"reply-window-ms", required_argument, NULL, 'W'},
        {"stats-file", required_argument, NULL, 's'},
        {"syslog", no_argument, NULL, 'S'},
        {"verbose", no_argument, NULL, 'v'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}};
    gwd_t *d = &g_d;
    dan_gw_node_config_t nc;
    dan_periph_config_t pc;
    const char *uart = NULL, *de_gpio = NULL;
    uint32_t baud = 9600, v, gap_ms = 20, window_ms = 50;
    bool no_echo = false, de_low = false;
    char err[256];
    int c, r;
    uint64_t now;
    struct sigaction sa;

    dan_gw_node_config_default(&nc);
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        switch (c) {
        case 'u': uart = optarg; break;
        case 'c': d->can_spec = optarg; break;
        case 'n':
            if (parse_u32(optarg, 1, 127, &v)) { fprintf(stderr, "dan-gatewayd: --node-id must be 1..127\n"); return 2; }
            nc.node_id = (uint8_t)v;
            break;
        case 'b':
            if (parse_u32(optarg, 1200, 4000000, &baud)) { fprintf(stderr, "dan-gatewayd: bad --uart-baud\n"); return 2; }
            break;
        case 'E': no_echo = true; break;
        case 'g': de_gpio = optarg; break;
        case 'L': de_low = true; break;
        case 't':
            if (parse_u32(optarg, DAN_GW_ESC_TIMEOUT_MIN, DAN_GW_ESC_TIMEOUT_MAX, &nc.esc_timeout_ms)) {
                fprintf(stderr, "dan-gatewayd: --esc-timeout-ms must be %u..%u\n", DAN_GW_ESC_TIMEOUT_MIN, DAN_GW_ESC_TIMEOUT_MAX);
                return 2;
            }
            break;
        case 'a':
            if (parse_u32(optarg, DAN_GW_ARMING_RATE_MIN, DAN_GW_ARMING_RATE_MAX, &nc.arming_rate_hz)) {
                fprintf(stderr, "dan-gatewayd: --arming-rate-hz must be %u..%u\n", DAN_GW_ARMING_RATE_MIN, DAN_GW_ARMING_RATE_MAX);
                return 2;
            }
            break;
        case 'G':
            if (parse_u32(optarg, 1, 1000, &gap_ms)) { fprintf(stderr, "dan-gatewayd: bad --gap-ms\n"); return 2; }
            break;
        case 'W':
            if (parse_u32(optarg, 1, 5000, &window_ms)) { fprintf(stderr, "dan-gatewayd: bad --reply-window-ms\n"); return 2; }
            break;
        case 's': d->stats_file = optarg; break;
        case 'S': g_syslog = 1; break;
        case 'v': g_verbose = 1; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "dan-gatewayd: unexpected argument '%s'\n", argv[optind]);
        return 2;
    }
    if (uart == NULL || d->can_spec == NULL) {
        fprintf(stderr, "dan-gatewayd: --uart and --can are required (--help)\n");
        return 2;
    }
    if (g_syslog) {
        openlog("dan-gatewayd", LOG_PID, LOG_DAEMON);
    }

    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGHUP, &sa, NULL);  /* a dropped SSH session: stop with the failsafe too */
    sigaction(SIGQUIT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    if (dan_posix_open(&d->uart, uart, baud, no_echo ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO,
                       err, sizeof err) != DAN_OK) {
        logmsg(LOG_ERR, "%s", err);
        return 2;
    }
    if (de_gpio != NULL &&
        dan_posix_de_gpio(&d->uart, de_gpio, de_low, err, sizeof err) != DAN_OK) {
        logmsg(LOG_ERR, "%s", err);
        dan_posix_close(&d->uart);
        return 2;
    }
    if (dan_canif_open(&d->can, d->can_spec, err, sizeof err) != DAN_OK) {
        logmsg(LOG_ERR, "%s", err);
        dan_posix_close(&d->uart);
        return 2;
    }
    d->can_up = true;
    now = dan_posix_now_us();
    {
        /* a different raw-frame sequence each boot (see raw_seq_start) */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        nc.raw_seq_start = (uint32_t)ts.tv_sec * 2654435761u ^ (uint32_t)ts.tv_nsec ^ (uint32_t)getpid();
    }
    if (dan_gw_node_init(&d->node, &nc, now) != DAN_OK) {
        logmsg(LOG_ERR, "bad node configuration");
        return 2;
    }
    dan_gw_node_ptype(&d->node, &d->ptype);
    dan_periph_config_default(&pc);
    pc.gap_us = gap_ms * 1000u;
    pc.reply_window_us = window_ms * 1000u;
    if (dan_periph_init(&d->periph, dan_posix_port(&d->uart), &d->ptype, 1, &pc, baud, now) != DAN_OK) {
        logmsg(LOG_ERR, "peripheral engine init failed");
        return 2;
    }
    dan_gw_node_attach(&d->node, &d->periph);
    logmsg(LOG_INFO, "DAN on %s at %u baud, DroneCAN node %u on %s", uart, baud, nc.node_id,
           d->can_spec);

    while (!g_stop) {
        struct pollfd pf[2];
        nfds_t nfd = 1;
        uint64_t next, t2;
        int timeout_ms;
        uint8_t buf[512];

        now = dan_posix_now_us();
        next = dan_periph_next_us(&d->periph);
        t2 = dan_gw_node_next_us(&d->node, now);
        if (t2 < next) {
            next = t2;
        }
        if (!d->can_up && d->reopen_us < next) {
            next = d->reopen_us;
        }
        if (d->stats_file && d->stats_due_us < next) {
            next = d->stats_due_us;
        }
        if (next <= now || (d->can_up && dan_canif_rx_pending(&d->can))) {
            timeout_ms = 0; /* due now, or received CAN bytes wait parsed */
        } else {
            uint64_t ms = (next - now + 999u) / 1000u;
            timeout_ms = ms > 100u ? 100 : (int)ms;
        }
        pf[0].fd = d->uart.fd;
        pf[0].events = POLLIN;
        pf[0].revents = 0;
        if (d->can_up) {
            pf[1].fd = dan_canif_fd(&d->can);
            pf[1].events = POLLIN;
            /* POLLOUT only for a line the backend has half written: a raw
             * CAN socket reports writable even with its queue full
             * (ENOBUFS), which would spin. Queued frames retry on a timer. */
            if (dan_canif_tx_pending(&d->can)) {
                pf[1].events |= POLLOUT;
            }
            pf[1].revents = 0;
            nfd = 2;
        }
        if (dan_gw_node_tx_pending(&d->node) > 0u && d->can_up && timeout_ms > 2) {
            timeout_ms = 2;
        }
        r = poll(pf, nfd, timeout_ms);
        if (r < 0 && errno != EINTR) {
            logmsg(LOG_ERR, "poll: %s", strerror(errno));
            break;
        }
        now = dan_posix_now_us();
        if (r > 0 && (pf[0].revents & (POLLIN | POLLHUP | POLLERR))) {
            int n;
            while ((n = dan_posix_read(&d->uart, buf, sizeof buf)) > 0) {
                dan_periph_rx(&d->periph, buf, (size_t)n, now);
            }
            /* With VMIN=0 a hung-up tty (USB unplug, pty closed) reads 0
             * bytes forever: POLLHUP/POLLERR with nothing read is a loss. */
            if (n == 0 && (pf[0].revents & (POLLHUP | POLLERR | POLLNVAL)) != 0) {
                n = -1;
            }
            if (n < 0) {
                logmsg(LOG_ERR, "%s: UART lost", uart);
                dan_gw_node_failsafe(&d->node, now);
                can_drain(d, now);
                break;
            }
        }
        if (d->can_up && ((r > 0 && nfd > 1 && (pf[1].revents & (POLLIN | POLLHUP | POLLERR))) ||
                          dan_canif_rx_pending(&d->can))) {
            can_read(d, now);
        }
        dan_periph_poll(&d->periph, now);
        dan_gw_node_poll(&d->node, now);
        can_drain(d, now);
        if (d->node.stats.failsafes != d->failsafes_logged) {
            d->failsafes_logged = d->node.stats.failsafes;
            logmsg(LOG_WARNING, "failsafe: no ESC command for %u ms: zero throttle, disarmed",
                   d->node.cfg.esc_timeout_ms);
        }
        if (!d->can_up && now >= d->reopen_us) {
            /* A short handshake: DAN requests wait meanwhile (at most
             * 100 ms a second while an adapter is present but silent). */
            if (dan_canif_open_ms(&d->can, d->can_spec, 100u, err, sizeof err) == DAN_OK) {
                d->can_up = true;
                dan_gw_node_can_state(&d->node, true);
                logmsg(LOG_INFO, "CAN %s reopened", d->can_spec);
            } else {
                logmsg(LOG_DEBUG, "%s", err);
                d->reopen_us = now + REOPEN_US;
            }
        }
        if (d->stats_file && now >= d->stats_due_us) {
            write_stats(d);
            d->stats_due_us = now + 1000000u;
        }
    }

    /* shutdown: zero throttle and DISARMED on the bus before leaving */
    now = dan_posix_now_us();
    dan_gw_node_failsafe(&d->node, now);
    {
        uint64_t end = now + SHUTDOWN_FLUSH_US;
        while (d->can_up && (dan_gw_node_tx_pending(&d->node) > 0u || dan_canif_tx_pending(&d->can)) &&
               dan_posix_now_us() < end) {
            struct pollfd pf;
            can_drain(d, dan_posix_now_us());
            if (!d->can_up) {
                break;
            }
            pf.fd = dan_canif_fd(&d->can);
            pf.events = POLLOUT;
            (void)poll(&pf, 1, 10);
        }
    }
    if (d->stats_file) {
        write_stats(d);
    }
    logmsg(LOG_INFO, "stopped (failsafe sent)");
    dan_canif_close(&d->can);
    dan_posix_close(&d->uart);
    return g_stop ? 0 : 1;
}
