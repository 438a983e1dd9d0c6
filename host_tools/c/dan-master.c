/*
 * dan-master: the libdan master engine from the command line.
 *
 *   dan-master --port /dev/ttyUSB0 discover configure
 *   dan-master --port EP --types test-a,test-b --json discover configure:115200 request:0x62:616263
 *
 * Steps run in order in one process (the master's state lives as long as
 * the process: a new run is a master restart). Exit: 0 all steps OK, 1 a
 * step failed, 2 bad arguments or port error.
 */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "dan/dan.h"
#include "dan/identity_json.h"
#include "dan/posix.h"

static volatile sig_atomic_t stop_flag;

static void on_signal(int sig)
{
    (void)sig;
    stop_flag = 1;
}

static void usage(FILE *f)
{
    fprintf(f,
        "usage: dan-master --port TTY [options] STEP...\n"
        "\n"
        "Runs the libdan master on a serial port (a real DAN wire, or a dan-vbus\n"
        "endpoint) and performs the steps in order.\n"
        "\n"
        "options:\n"
        "  --port TTY          serial port (required)\n"
        "  --baud N            the port's starting baud (default 9600)\n"
        "  --types LIST        types to probe, comma-separated names or first codes\n"
        "                      (default: vtx,can-gw; also test-a, test-b)\n"
        "  --no-echo           the adapter does not echo our bytes\n"
        "  --de-gpio CHIP:LINE drive a direction pin (libgpiod); implies --no-echo\n"
        "  --latency-ms N      reply start window (default 50: ptys and USB adapters)\n"
        "  --gap-ms N          inter-byte gap that ends a frame (default 20)\n"
        "  --retries N         extra attempts per transaction (default 2)\n"
        "  --json              one JSON object per step on stdout\n"
        "  --timeout-ms N      give up a step after N ms (default 30000)\n"
        "  -h, --help          this text\n"
        "\n"
        "steps:\n"
        "  discover            probe every type at 9600, then other bauds\n"
        "  configure[:BAUD]    move the bus to BAUD (default: best common) and verify\n"
        "  request:CODE[:HEX]  send a request, print the reply payload\n"
        "  repeat:N:CODE[:HEX] the same N times; prints the count and the rate\n"
        "  stats               engine counters\n");
}

typedef struct {
    dan_master_t m;
    dan_posix_port_t port;
    bool json;
    uint64_t timeout_us;
} ctx_t;

/* Runs the poll loop until the current operation completes. */
static int run_op(ctx_t *c)
{
    uint64_t deadline = dan_posix_now_us() + c->timeout_us;
    uint8_t buf[512];
    for (;;) {
        uint64_t now = dan_posix_now_us(), next;
        struct pollfd pfd;
        int n, ms;
        if (dan_master_poll(&c->m, now)) {
            return dan_master_result(&c->m);
        }
        if (stop_flag) {
            return DAN_ERR_ARG;
        }
        if (now > deadline) {
            return DAN_ERR_TIMEOUT;
        }
        next = dan_master_next_us(&c->m);
        ms = (next == UINT64_MAX) ? 100 : (next <= now) ? 0 : (int)((next - now + 999u) / 1000u);
        if (ms > 100) {
            ms = 100;
        }
        pfd.fd = c->port.fd;
        pfd.events = POLLIN;
        if (poll(&pfd, 1, ms) > 0) {
            n = dan_posix_read(&c->port, buf, sizeof buf);
            if (n < 0) {
                return DAN_ERR_IO;
            }
            if (n > 0) {
                dan_master_rx(&c->m, buf, (size_t)n, dan_posix_now_us());
            }
        }
    }
}

/* A JSON string (error texts and names: short), escaped by libdan. */
static void json_str(const char *s)
{
    char buf[6u * DAN_MAX_STRING + 3u];
    dan_json_str(buf, sizeof buf, s);
    fputs(buf, stdout);
}

static const char *type_name(uint32_t first)
{
    const dan_type_info_t *t = dan_type_of_code(first);
    return (t != NULL) ? t->name : "?";
}

static void print_peers(ctx_t *c, int r, double ms)
{
    char obj[DAN_PEER_JSON_MAX];
    size_t i;
    bool first = true;
    if (c->json) {
        printf("{\"step\":\"discover\",\"result\":%d,\"error\":", r);
        json_str(r == DAN_OK ? "" : dan_strerror(r));
        printf(",\"ms\":%.1f,\"baud\":%u,\"peers\":[", ms, dan_master_baud(&c->m));
        for (i = 0; i < c->m.ntypes; i++) {
            const dan_peer_t *p = &c->m.peers[i];
            if (!p->present) {
                continue;
            }
            dan_peer_json(obj, sizeof obj, p, DAN_PEER_JSON_FULL);
            printf("%s%s", first ? "" : ",", obj);
            first = false;
        }
        printf("]}\n");
        return;
    }
    printf("discover: %s in %.1f ms\n", r == DAN_OK ? "ok" : dan_strerror(r), ms);
    printf("%-8s %-6s %-8s %-16s %-16s %-8s %-10s %s\n", "type", "code", "baud", "manufacturer",
           "model", "hw", "sw", "mask");
    for (i = 0; i < c->m.ntypes; i++) {
        const dan_peer_t *p = &c->m.peers[i];
        if (p->present) {
            printf("%-8s 0x%02X   %-8u %-16s %-16s %-8s %-10s 0x%04X\n", type_name(p->first_code),
                   p->first_code, p->baud, p->identity.manufacturer, p->identity.model,
                   p->identity.hw_version, p->identity.sw_version, p->identity.baud_mask);
        }
    }
}

static int parse_hex(const char *s, uint8_t *out, size_t cap, size_t *len)
{
    size_t n = 0;
    while (s[0] != '\0') {
        unsigned v;
        if (s[1] == '\0' || sscanf(s, "%2x", &v) != 1 || n >= cap) {
            return -1;
        }
        out[n++] = (uint8_t)v;
        s += 2;
    }
    *len = n;
    return 0;
}

static void print_txn(ctx_t *c, const char *step, uint32_t code, int r, double ms)
{
    size_t i;
    if (c->json) {
        printf("{\"step\":\"%s\",\"code\":%u,\"result\":%d,\"error\":", step, code, r);
        json_str(r == DAN_OK ? "" : r == DAN_ERR_REMOTE ? c->m.remote_error.text : dan_strerror(r));
        printf(",\"ms\":%.2f,\"payload\":\"", ms);
        for (i = 0; r == DAN_OK && i < c->m.resp_len; i++) {
            printf("%02x", c->m.resp[i]);
        }
        printf("\"}\n");
        return;
    }
    if (r == DAN_OK) {
        printf("%s 0x%02X: ok (%.2f ms): ", step, code, ms);
        for (i = 0; i < c->m.resp_len; i++) {
            printf("%02x", c->m.resp[i]);
        }
        printf("\n");
    } else if (r == DAN_ERR_REMOTE) {
        printf("%s 0x%02X: error frame: %s\n", step, code, c->m.remote_error.text);
    } else {
        printf("%s 0x%02X: %s\n", step, code, dan_strerror(r));
    }
}

static void print_stats(ctx_t *c)
{
    const dan_master_stats_t *s = &c->m.stats;
    const dan_link_stats_t *l = &c->m.link.stats;
    const dan_decoder_stats_t *d = &c->m.link.dec.stats;
    printf("%s\"step\":\"stats\",\"transactions\":%u,\"ok\":%u,\"timeouts\":%u,\"retries\":%u,"
           "\"remote_errors\":%u,\"stray\":%u,\"lbt_waits\":%u,\"busy_failures\":%u,\"recoveries\":%u,"
           "\"tx_frames\":%u,\"tx_bytes\":%u,\"rx_bytes\":%u,\"collisions\":%u,\"echo_timeouts\":%u,"
           "\"rx_frames\":%u,\"crc_errors\":%u,\"oversize\":%u,\"bad_varint\":%u,\"garbage\":%u,"
           "\"aborted\":%u%s\n",
           c->json ? "{" : "stats: {", s->transactions, s->ok, s->timeouts, s->retries, s->remote_errors,
           s->stray, s->lbt_waits, s->busy_failures, s->recoveries, l->tx_frames, l->tx_bytes,
           l->rx_bytes, l->collisions, l->echo_timeouts, d->frames, d->crc_errors, d->oversize,
           d->bad_varint, d->garbage, d->aborted, "}");
}

static int parse_u32(const char *s, uint32_t *v)
{
    char *end;
    unsigned long x;
    errno = 0;
    x = strtoul(s, &end, 0);
    if (errno != 0 || end == s || *end != '\0' || x > 0xFFFFFFFFul) {
        return -1;
    }
    *v = (uint32_t)x;
    return 0;
}

int main(int argc, char **argv)
{
    static ctx_t c;
    const char *port = NULL, *types_arg = "vtx,can-gw", *de = NULL;
    uint32_t baud = 9600, latency_ms = 50, gap_ms = 20, retries = 2, timeout_ms = 30000;
    bool no_echo = false;
    uint32_t types[DAN_MASTER_MAX_TYPES];
    size_t ntypes = 0;
    dan_master_config_t cfg;
    char err[256], tbuf[128];
    int i, first_step = 0, failed = 0, r;

    for (i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        uint32_t *num = NULL;
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--json") == 0) {
            c.json = true;
        } else if (strcmp(a, "--no-echo") == 0) {
            no_echo = true;
        } else if (strcmp(a, "--port") == 0 || strcmp(a, "--types") == 0 || strcmp(a, "--de-gpio") == 0) {
            if (v == NULL) {
                fprintf(stderr, "dan-master: %s needs a value\n", a);
                return 2;
            }
            if (a[2] == 'p') {
                port = v;
            } else if (a[2] == 't') {
                types_arg = v;
            } else {
                de = v;
            }
            i++;
        } else if (strcmp(a, "--baud") == 0) { num = &baud;
        } else if (strcmp(a, "--latency-ms") == 0) { num = &latency_ms;
        } else if (strcmp(a, "--gap-ms") == 0) { num = &gap_ms;
        } else if (strcmp(a, "--retries") == 0) { num = &retries;
        } else if (strcmp(a, "--timeout-ms") == 0) { num = &timeout_ms;
        } else if (a[0] == '-') {
            fprintf(stderr, "dan-master: unknown option %s (see --help)\n", a);
            return 2;
        } else {
            first_step = i;
            break;
        }
        if (num != NULL) {
            if (v == NULL || parse_u32(v, num) != 0) {
                fprintf(stderr, "dan-master: %s needs a number\n", a);
                return 2;
            }
            i++;
        }
    }
    if (port == NULL) {
        fprintf(stderr, "dan-master: --port is required (see --help)\n");
        return 2;
    }
    if (first_step == 0) {
        fprintf(stderr, "dan-master: no step given (see --help)\n");
        return 2;
    }
    if (baud == 0 || retries > 10) {
        fprintf(stderr, "dan-master: bad --baud or --retries\n");
        return 2;
    }
    snprintf(tbuf, sizeof tbuf, "%s", types_arg);
    {
        char *save = NULL, *tok;
        for (tok = strtok_r(tbuf, ",", &save); tok != NULL; tok = strtok_r(NULL, ",", &save)) {
            const dan_type_info_t *t = dan_type_lookup(tok);
            if (t == NULL || ntypes >= DAN_MASTER_MAX_TYPES) {
                fprintf(stderr, "dan-master: unknown type '%s' (vtx, can-gw, test-a, test-b or a code)\n", tok);
                return 2;
            }
            types[ntypes++] = t->first;
        }
    }
    /* Check every step's syntax before touching the port. */
    for (i = first_step; i < argc; i++) {
        const char *s = argv[i];
        if (strcmp(s, "discover") != 0 && strncmp(s, "configure", 9) != 0 && strncmp(s, "request:", 8) != 0 &&
            strncmp(s, "repeat:", 7) != 0 && strcmp(s, "stats") != 0) {
            fprintf(stderr, "dan-master: unknown step '%s' (see --help)\n", s);
            return 2;
        }
    }
    r = dan_posix_open(&c.port, port, baud, (no_echo || de != NULL) ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO, err,
                       sizeof err);
    if (r != DAN_OK) {
        fprintf(stderr, "dan-master: %s\n", err);
        return 2;
    }
    if (de != NULL && dan_posix_de_gpio(&c.port, de, false, err, sizeof err) != DAN_OK) {
        fprintf(stderr, "dan-master: %s\n", err);
        dan_posix_close(&c.port);
        return 2;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    dan_master_config_default(&cfg);
    cfg.resp_latency_us = latency_ms * 1000u;
    cfg.gap_us = gap_ms * 1000u;
    cfg.retries = (uint8_t)retries;
    cfg.seed = (uint32_t)getpid();
    c.timeout_us = (uint64_t)timeout_ms * 1000u;
    dan_master_init(&c.m, dan_posix_port(&c.port), &cfg, types, ntypes, baud, dan_posix_now_us());

    for (i = first_step; i < argc && !stop_flag; i++) {
        const char *s = argv[i];
        uint64_t t0 = dan_posix_now_us();
        if (strcmp(s, "discover") == 0) {
            dan_master_discover(&c.m, t0);
            r = run_op(&c);
            print_peers(&c, r, (double)(dan_posix_now_us() - t0) / 1000.0);
        } else if (strncmp(s, "configure", 9) == 0) {
            uint32_t target = 0;
            if (s[9] == ':' && parse_u32(s + 10, &target) != 0) {
                fprintf(stderr, "dan-master: bad baud in '%s'\n", s);
                failed = 1;
                break;
            }
            r = dan_master_configure(&c.m, target, t0);
            if (r == DAN_OK) {
                r = run_op(&c);
            }
            if (c.json) {
                printf("{\"step\":\"configure\",\"result\":%d,\"error\":", r);
                json_str(r == DAN_OK ? "" : dan_strerror(r));
                printf(",\"baud\":%u,\"ms\":%.1f,\"recoveries\":%u}\n", dan_master_baud(&c.m),
                       (double)(dan_posix_now_us() - t0) / 1000.0, c.m.stats.recoveries);
            } else {
                printf("configure: %s, bus at %u baud (%.1f ms)\n", r == DAN_OK ? "ok" : dan_strerror(r),
                       dan_master_baud(&c.m), (double)(dan_posix_now_us() - t0) / 1000.0);
            }
        } else if (strcmp(s, "stats") == 0) {
            print_stats(&c);
            r = DAN_OK;
        } else {
            /* request:CODE[:HEX] or repeat:N:CODE[:HEX] */
            char tmp[1024], *parts[5], *save = NULL;
            int np = 0;
            uint32_t code, count = 1, k;
            uint8_t payload[DAN_MAX_PAYLOAD];
            size_t plen = 0;
            bool rep = (s[1] == 'e' && s[2] == 'p');
            snprintf(tmp, sizeof tmp, "%s", s);
            for (parts[np] = strtok_r(tmp, ":", &save); parts[np] != NULL && np < 4;
                 parts[++np] = strtok_r(NULL, ":", &save)) {
            }
            if (rep) {
                if (np < 3 || parse_u32(parts[1], &count) != 0 || parse_u32(parts[2], &code) != 0 ||
                    (np == 4 && parse_hex(parts[3], payload, sizeof payload, &plen) != 0)) {
                    fprintf(stderr, "dan-master: bad step '%s'\n", s);
                    failed = 1;
                    break;
                }
            } else if (np < 2 || parse_u32(parts[1], &code) != 0 ||
                       (np >= 3 && parse_hex(parts[2], payload, sizeof payload, &plen) != 0)) {
                fprintf(stderr, "dan-master: bad step '%s'\n", s);
                failed = 1;
                break;
            }
            r = DAN_OK;
            for (k = 0; k < count && r == DAN_OK && !stop_flag; k++) {
                r = dan_master_request(&c.m, code, payload, plen, dan_posix_now_us());
                if (r == DAN_OK) {
                    r = run_op(&c);
                }
            }
            if (rep) {
                double secs = (double)(dan_posix_now_us() - t0) / 1e6;
                if (c.json) {
                    printf("{\"step\":\"repeat\",\"code\":%u,\"result\":%d,\"done\":%u,\"seconds\":%.4f,"
                           "\"per_second\":%.1f}\n", code, r, k, secs, secs > 0 ? k / secs : 0.0);
                } else {
                    printf("repeat 0x%02X: %u done in %.3f s (%.1f/s)%s%s\n", code, k, secs,
                           secs > 0 ? k / secs : 0.0, r == DAN_OK ? "" : ", stopped: ",
                           r == DAN_OK ? "" : dan_strerror(r));
                }
            } else {
                print_txn(&c, "request", code, r, (double)(dan_posix_now_us() - t0) / 1000.0);
            }
        }
        fflush(stdout);
        if (r != DAN_OK) {
            failed = 1;
        }
    }
    dan_posix_close(&c.port);
    return failed;
}
