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
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "dan/dan.h"
#include "dan/identity_json.h"
#include "dan/posix.h"
#include "dan_tool.h"

/* Longest a poll() waits: a signal or the step's timeout is seen this soon. */
#define POLL_CAP_MS 100
/* --retries above this would make a dead peer block a step for minutes. */
#define MAX_RETRIES 10u

static void usage(FILE *f)
{
    fprintf(f, "usage: dan-master --port TTY [options] STEP...\n"
               "\n"
               "Runs the libdan master on a serial port (a real DAN wire, or a dan-vbus\n"
               "endpoint) and performs the steps in order.\n"
               "\n"
               "options:\n"
               "  --port TTY          serial port (required)\n"
               "  --baud N            the port's starting baud, any value (default 9600)\n"
               "  --max-baud N        offer the fast bauds up to N (230400..2000000) before\n"
               "                      the mask bauds, and scan them in discovery (default 0:\n"
               "                      none, DAN v1 only)\n"
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
               "  configure[:BAUD]    move the bus to BAUD (default: the fastest every peer\n"
               "                      accepts, fast bauds first) and verify\n"
               "  request:CODE[:HEX]  send a request, print the reply payload\n"
               "  repeat:N:CODE[:HEX] the same N times; prints the count and the rate\n"
               "  stats               engine counters\n");
}

typedef struct {
    dan_master_t m;
    dan_identity_t ids[DAN_MASTER_MAX_TYPES]; /* discovery reports them here */
    dan_posix_port_t port;
    bool json;
    uint64_t timeout_us;
} ctx_t;

/* The command line: options, then steps from argv[first_step] on. */
typedef struct {
    const char *port, *types, *de;
    uint32_t baud, latency_ms, gap_ms, retries, timeout_ms;
    bool no_echo, json;
    int first_step;
    uint32_t max_baud;
} opts_t;

/* Runs the poll loop until the current operation completes. */
static int run_op(ctx_t *c)
{
    uint64_t deadline = dan_posix_now_us() + c->timeout_us;
    uint8_t buf[512];
    for (;;) {
        uint64_t now = dan_posix_now_us();
        int n;
        if (dan_master_poll(&c->m, now)) {
            return dan_master_result(&c->m);
        }
        if (tool_stop) {
            return DAN_ERR_ARG;
        }
        if (now > deadline) {
            return DAN_ERR_TIMEOUT;
        }
        if (tool_wait_fd(c->port.fd, POLLIN, dan_master_next_us(&c->m), POLL_CAP_MS) > 0) {
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
        tool_json_str(stdout, r == DAN_OK ? "" : dan_strerror(r));
        printf(",\"ms\":%.1f,\"baud\":%u,\"peers\":[", ms, dan_master_baud(&c->m));
        for (i = 0; i < c->m.ntypes; i++) {
            const dan_peer_t *p = &c->m.peers[i];
            if (!p->present) {
                continue;
            }
            dan_peer_json(obj, sizeof obj, p, &c->ids[i], DAN_PEER_JSON_FULL);
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
        const dan_identity_t *id = &c->ids[i];
        if (p->present) {
            printf("%-8s 0x%02X   %-8u %-16s %-16s %-8s %-10s 0x%04X\n", type_name(p->first_code),
                   p->first_code, p->baud, id->manufacturer, id->model, id->hw_version,
                   id->sw_version, id->baud_mask);
        }
    }
}

static int hex_digit(char ch)
{
    return ch >= '0' && ch <= '9'   ? ch - '0'
           : ch >= 'a' && ch <= 'f' ? ch - 'a' + 10
           : ch >= 'A' && ch <= 'F' ? ch - 'A' + 10
                                    : -1;
}

/* Whole hex bytes only: "-1", "0g", "+f" were taken as ff, 00, 0f
 * (sscanf's %2x; review finding). */
static int parse_hex(const char *s, uint8_t *out, size_t cap, size_t *len)
{
    size_t n = 0;
    while (s[0] != '\0') {
        int hi = hex_digit(s[0]), lo = s[1] != '\0' ? hex_digit(s[1]) : -1;
        if (hi < 0 || lo < 0 || n >= cap) {
            return -1;
        }
        out[n++] = (uint8_t)(hi << 4 | lo);
        s += 2;
    }
    *len = n;
    return 0;
}

static void print_txn(ctx_t *c, const char *step, uint32_t code, int r, double ms)
{
    size_t i;
    dan_error_msg_t e;
    if (r != DAN_ERR_REMOTE || dan_master_remote_error(&c->m, &e) != DAN_OK) {
        e.text[0] = '\0';
    }
    if (c->json) {
        printf("{\"step\":\"%s\",\"code\":%u,\"result\":%d,\"error\":", step, code, r);
        tool_json_str(stdout, r == DAN_OK ? "" : r == DAN_ERR_REMOTE ? e.text : dan_strerror(r));
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
        printf("%s 0x%02X: error frame: %s\n", step, code, e.text);
    } else {
        printf("%s 0x%02X: %s\n", step, code, dan_strerror(r));
    }
}

static void print_stats(ctx_t *c)
{
    const dan_master_stats_t *s = &c->m.stats;
    const dan_link_stats_t *l = &c->m.link.stats;
    const dan_decoder_stats_t *d = &c->m.link.dec.stats;
    printf(
        "%s\"step\":\"stats\",\"transactions\":%u,\"ok\":%u,\"timeouts\":%u,\"retries\":%u,"
        "\"remote_errors\":%u,\"stray\":%u,\"lbt_waits\":%u,\"busy_failures\":%u,\"recoveries\":%u,"
        "\"tx_frames\":%u,\"tx_bytes\":%u,\"rx_bytes\":%u,\"collisions\":%u,\"echo_timeouts\":%u,"
        "\"rx_frames\":%u,\"crc_errors\":%u,\"oversize\":%u,\"bad_varint\":%u,\"garbage\":%u,"
        "\"aborted\":%u,\"fast_refusals\":%u,\"moved_back\":%u%s\n",
        c->json ? "{" : "stats: {", s->transactions, s->ok, s->timeouts, s->retries,
        s->remote_errors, s->stray, s->lbt_waits, s->busy_failures, s->recoveries, l->tx_frames,
        l->tx_bytes, l->rx_bytes, l->collisions, l->echo_timeouts, d->frames, d->crc_errors,
        d->oversize, d->bad_varint, d->garbage, d->aborted, s->fast_refusals, s->moved_back, "}");
}

static double ms_since(uint64_t t0)
{
    return (double)(dan_posix_now_us() - t0) / 1000.0;
}

/* The uint32_t an option sets, or NULL for any other option. */
static uint32_t *number_option(opts_t *o, const char *a)
{
    const struct {
        const char *name;
        uint32_t *dst;
    } nums[] = {
        {"--baud", &o->baud},       {"--latency-ms", &o->latency_ms}, {"--gap-ms", &o->gap_ms},
        {"--retries", &o->retries}, {"--timeout-ms", &o->timeout_ms}, {"--max-baud", &o->max_baud},
    };
    size_t i;
    for (i = 0; i < sizeof nums / sizeof nums[0]; i++) {
        if (strcmp(a, nums[i].name) == 0) {
            return nums[i].dst;
        }
    }
    return NULL;
}

/* The string an option sets, or NULL for any other option. */
static const char **string_option(opts_t *o, const char *a)
{
    if (strcmp(a, "--port") == 0) {
        return &o->port;
    }
    if (strcmp(a, "--types") == 0) {
        return &o->types;
    }
    if (strcmp(a, "--de-gpio") == 0) {
        return &o->de;
    }
    return NULL;
}

/* Options up to the first step. Returns -1 to go on, else the exit code. */
static int parse_options(int argc, char **argv, opts_t *o)
{
    int i;
    for (i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = (i + 1 < argc) ? argv[i + 1] : NULL;
        uint32_t *num = number_option(o, a);
        const char **str = string_option(o, a);
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "--json") == 0) {
            o->json = true;
        } else if (strcmp(a, "--no-echo") == 0) {
            o->no_echo = true;
        } else if (str != NULL) {
            if (v == NULL) {
                tool_error("%s needs a value", a);
                return 2;
            }
            *str = v;
            i++;
        } else if (num != NULL) {
            if (v == NULL || tool_parse_u32(v, 0, UINT32_MAX, num) != 0) {
                tool_error("%s needs a number", a);
                return 2;
            }
            i++;
        } else if (a[0] == '-') {
            tool_error("unknown option %s (see --help)", a);
            return 2;
        } else {
            o->first_step = i;
            break;
        }
    }
    return -1;
}

/* request:CODE[:HEX] or repeat:N:CODE[:HEX], split and checked. */
typedef struct {
    bool rep;
    uint32_t code, count;
    uint8_t payload[DAN_MAX_PAYLOAD];
    size_t plen;
} txn_args_t;

static int parse_txn(const char *s, txn_args_t *t);

/* The step is one of the syntax, whole: "configurefoo" ran an automatic
 * configure and "request:0x60:zz" failed only when reached, exit 1
 * (review finding). */
static bool valid_step(const char *s)
{
    static txn_args_t t;
    uint32_t baud;
    if (strcmp(s, "discover") == 0 || strcmp(s, "stats") == 0 || strcmp(s, "configure") == 0) {
        return true;
    }
    if (strncmp(s, "configure:", 10) == 0) {
        return tool_parse_u32(s + 10, 1, UINT32_MAX, &baud) == 0;
    }
    return (strncmp(s, "request:", 8) == 0 || strncmp(s, "repeat:", 7) == 0) &&
           parse_txn(s, &t) == 0;
}

/* Checks the whole command line before the port is touched: -1 to go on,
 * else the exit code. */
static int check_args(int argc, char **argv, opts_t *o, uint32_t *types, size_t *ntypes)
{
    const dan_type_info_t *t[DAN_MASTER_MAX_TYPES];
    char bad[128];
    size_t k;
    int i;
    if (o->port == NULL) {
        tool_error("--port is required (see --help)");
        return 2;
    }
    if (o->first_step == 0) {
        tool_error("no step given (see --help)");
        return 2;
    }
    if (o->baud == 0 || o->retries > MAX_RETRIES) {
        tool_error("bad --baud or --retries");
        return 2;
    }
    if (tool_parse_types(o->types, t, DAN_MASTER_MAX_TYPES, ntypes, bad, sizeof bad) != 0) {
        tool_error("unknown type '%s' (vtx, can-gw, test-a, test-b or a code)", bad);
        return 2;
    }
    for (k = 0; k < *ntypes; k++) {
        types[k] = t[k]->first;
    }
    for (i = o->first_step; i < argc; i++) {
        if (!valid_step(argv[i])) {
            tool_error("bad step '%s' (see --help)", argv[i]);
            return 2;
        }
    }
    return -1;
}

/* Opens the port and starts the master: 0, or 2 after a message. */
static int start(ctx_t *c, const opts_t *o, const uint32_t *types, size_t ntypes)
{
    dan_master_config_t cfg;
    char err[256];
    bool no_echo = o->no_echo || o->de != NULL; /* a direction pin hides our echo */
    if (dan_posix_open(&c->port, o->port, o->baud, no_echo ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO,
                       err, sizeof err) != DAN_OK) {
        tool_error("%s", err);
        return 2;
    }
    if (o->de != NULL && dan_posix_de_gpio(&c->port, o->de, false, err, sizeof err) != DAN_OK) {
        tool_error("%s", err);
        dan_posix_close(&c->port);
        return 2;
    }
    tool_catch_signal(SIGINT);
    tool_catch_signal(SIGTERM);
    tool_fine_timers();
    dan_master_config_default(&cfg);
    cfg.resp_latency_us = o->latency_ms * 1000u;
    cfg.gap_us = o->gap_ms * 1000u;
    cfg.retries = (uint8_t)o->retries;
    cfg.seed = (uint32_t)getpid();
    cfg.fast_max_baud = o->max_baud;
    c->json = o->json;
    c->timeout_us = (uint64_t)o->timeout_ms * 1000u;
    dan_master_init(&c->m, dan_posix_port(&c->port), &cfg, types, ntypes, o->baud,
                    dan_posix_now_us());
    dan_master_set_identities(&c->m, c->ids, DAN_MASTER_MAX_TYPES);
    return 0;
}

static int step_discover(ctx_t *c, uint64_t t0)
{
    int r;
    dan_master_discover(&c->m, t0);
    r = run_op(c);
    print_peers(c, r, ms_since(t0));
    return r;
}

/* configure[:BAUD]; 2 for a bad BAUD (the run stops). */
static int step_configure(ctx_t *c, const char *s, uint64_t t0)
{
    uint32_t target = 0;
    int r;
    if (s[9] == ':' && tool_parse_u32(s + 10, 0, UINT32_MAX, &target) != 0) {
        tool_error("bad baud in '%s'", s);
        return 2;
    }
    r = dan_master_configure(&c->m, target, t0);
    if (r == DAN_OK) {
        r = run_op(c);
    }
    if (c->json) {
        printf("{\"step\":\"configure\",\"result\":%d,\"error\":", r);
        tool_json_str(stdout, r == DAN_OK ? "" : dan_strerror(r));
        printf(",\"baud\":%u,\"ms\":%.1f,\"recoveries\":%u,\"fast_refusals\":%u,"
               "\"moved_back\":%u}\n",
               dan_master_baud(&c->m), ms_since(t0), c->m.stats.recoveries,
               c->m.stats.fast_refusals, c->m.stats.moved_back);
    } else {
        printf("configure: %s, bus at %u baud (%.1f ms)\n", r == DAN_OK ? "ok" : dan_strerror(r),
               dan_master_baud(&c->m), ms_since(t0));
    }
    return r == DAN_OK ? 0 : 1;
}

static int parse_txn(const char *s, txn_args_t *t)
{
    char tmp[1024], *parts[5], *save = NULL;
    int np = 0;
    t->rep = (s[1] == 'e' && s[2] == 'p'); /* "repeat:", not "request:" */
    t->count = 1;
    t->plen = 0;
    snprintf(tmp, sizeof tmp, "%s", s);
    for (parts[np] = strtok_r(tmp, ":", &save); parts[np] != NULL && np < 4;
         parts[++np] = strtok_r(NULL, ":", &save)) {
    }
    /* no field more than the syntax has (a trailing ":junk" was ignored) */
    if (t->rep) {
        return (np < 3 || np > 4 || parts[np] != NULL ||
                tool_parse_u32(parts[1], 1, UINT32_MAX, &t->count) != 0 ||
                tool_parse_u32(parts[2], 0, UINT32_MAX, &t->code) != 0 ||
                (np == 4 && parse_hex(parts[3], t->payload, sizeof t->payload, &t->plen) != 0))
                   ? -1
                   : 0;
    }
    return (np < 2 || np > 3 || tool_parse_u32(parts[1], 0, UINT32_MAX, &t->code) != 0 ||
            (np == 3 && parse_hex(parts[2], t->payload, sizeof t->payload, &t->plen) != 0))
               ? -1
               : 0;
}

static void print_repeat(const ctx_t *c, const txn_args_t *t, int r, uint32_t done, uint64_t t0)
{
    double secs = (double)(dan_posix_now_us() - t0) / 1e6;
    if (c->json) {
        printf("{\"step\":\"repeat\",\"code\":%u,\"result\":%d,\"done\":%u,\"seconds\":%.4f,"
               "\"per_second\":%.1f}\n",
               t->code, r, done, secs, secs > 0 ? done / secs : 0.0);
    } else {
        printf("repeat 0x%02X: %u done in %.3f s (%.1f/s)%s%s\n", t->code, done, secs,
               secs > 0 ? done / secs : 0.0,
               r == DAN_OK ? "" : ", stopped: ", r == DAN_OK ? "" : dan_strerror(r));
    }
}

/* request / repeat; 2 for a bad step (the run stops). */
static int step_txn(ctx_t *c, const char *s, uint64_t t0)
{
    static txn_args_t t;
    uint32_t k;
    int r = DAN_OK;
    if (parse_txn(s, &t) != 0) {
        tool_error("bad step '%s'", s);
        return 2;
    }
    for (k = 0; k < t.count && r == DAN_OK && !tool_stop;) {
        r = dan_master_request(&c->m, t.code, t.payload, t.plen, dan_posix_now_us());
        if (r == DAN_OK) {
            r = run_op(c);
        }
        k += r == DAN_OK ? 1u : 0u; /* done: those that succeeded */
    }
    if (t.rep) {
        print_repeat(c, &t, r, k, t0);
    } else {
        print_txn(c, "request", t.code, r, ms_since(t0));
    }
    return r == DAN_OK ? 0 : 1;
}

/* One step: 0 ok, 1 failed, 2 malformed (stops the run). */
static int run_step(ctx_t *c, const char *s)
{
    uint64_t t0 = dan_posix_now_us();
    if (strcmp(s, "discover") == 0) {
        return step_discover(c, t0) == DAN_OK ? 0 : 1;
    }
    if (strncmp(s, "configure", 9) == 0) {
        return step_configure(c, s, t0);
    }
    if (strcmp(s, "stats") == 0) {
        print_stats(c);
        return 0;
    }
    return step_txn(c, s, t0);
}

int main(int argc, char **argv)
{
    static ctx_t c;
    opts_t o = {NULL, "vtx,can-gw", NULL, 9600, 50, 20, 2, 30000, false, false, 0, 0};
    uint32_t types[DAN_MASTER_MAX_TYPES];
    size_t ntypes = 0;
    int i, failed = 0, r;

    tool_prog = "dan-master";
    r = parse_options(argc, argv, &o);
    if (r < 0) {
        r = check_args(argc, argv, &o, types, &ntypes);
    }
    if (r >= 0) {
        return r;
    }
    if (start(&c, &o, types, ntypes) != 0) {
        return 2;
    }
    for (i = o.first_step; i < argc && !tool_stop; i++) {
        r = run_step(&c, argv[i]);
        if (r == 2) {
            failed = 2; /* malformed (the header's exit code), though checked above */
            break;
        }
        fflush(stdout);
        if (r != 0) {
            failed = 1;
        }
    }
    dan_posix_close(&c.port);
    return failed;
}
