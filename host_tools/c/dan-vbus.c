/*
 * dan-vbus: a virtual half-duplex single-wire UART bus on pseudo-terminals.
 *
 * N pty endpoints share one simulated wire. Every byte an endpoint writes
 * occupies the wire for one character time at the writer's baud rate (8N1,
 * 10 bits) and is delivered, when that time has passed, to every endpoint
 * including the writer (echo). Overlapping transmissions collide, receivers
 * at a baud rate more than 3 % off see garbage, and an optional bit error
 * rate adds noise. See --help and docs/VBUS.md.
 *
 * Structure: one ppoll() loop over the pty masters, the control socket and
 * its clients; the timeout is the next delivery or capture deadline. Signal
 * handlers only set a flag. Times are CLOCK_MONOTONIC nanoseconds.
 */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "dan/posix.h"
#include "dan_tool.h"

#define PROG              "dan-vbus"
#define EP_MIN            2
#define EP_MAX            16
#define TXQ_CAP           4096u /* bytes an endpoint may have queued for the wire */
#define TXQ_LOW           512u  /* room needed before reading from a writer again */
#define OUT_CAP           4096u /* per-receiver write batch */
#define BURST_CAP         4096u /* longest burst written as one capture line */
#define MAX_CLIENTS       8
#define CLIENT_LINE       256u
#define INIT_BAUD         9600u
#define MIN_BAUD          50u
#define DEFAULT_SEED      1u
#define TOLERANCE_PCT     3u
#define BITS_PER_CHAR     10 /* 8N1: start bit, 8 data bits, stop bit */
#define NS_PER_S          1000000000LL
/* An arbitrary odd constant (drand48's multiplier): the garbage stream
 * starts apart from the noise stream for the same --seed. */
#define GARBAGE_SEED_XOR  0x5DEECE66DULL
/* Another arbitrary constant: the --latency jitter stream. */
#define LATENCY_SEED_XOR  0x9E3779B97F4A7C15ULL
/* --latency: the default chunk is a full-speed FTDI packet's payload (64
 * bytes minus 2 modem-status bytes), handed over without waiting. */
#define LAT_CHUNK_DEFAULT 62u
#define LAT_PERIOD_MAX_MS 1000.0
/* --link PREFIX: room for the endpoint index and NUL ... */
#define LINK_INDEX_ROOM   4
/* ... and, with the temporary link's ".vbusPID" suffix, below PATH_MAX. */
#define LINK_SUFFIX_ROOM  32

typedef int64_t ns_t;

/* Returns the output (want_input == 0) or input speed of the pty's slave
 * (the port reads termios2, so BOTHER rates work: on a pty master the
 * kernel reports the slave's termios, which is what the user program set),
 * clamped to at least MIN_BAUD; INIT_BAUD if it cannot be read. */
static uint32_t pty_baud(int fd, int want_input)
{
    uint32_t in, out, b;
    if (dan_posix_get_speeds(fd, &in, &out) != 0) {
        return INIT_BAUD;
    }
    b = (want_input && in != 0u) ? in : out;
    return b < MIN_BAUD ? MIN_BAUD : b;
}

/* One character at 8N1 is BITS_PER_CHAR bits: 1e10 / baud nanoseconds. */
static ns_t char_ns(uint32_t baud)
{
    ns_t t = (ns_t)(BITS_PER_CHAR * NS_PER_S / (int64_t)baud);
    return t > 0 ? t : 1;
}

static int baud_mismatch(uint32_t rx, uint32_t tx)
{
    uint64_t d = rx > tx ? (uint64_t)rx - tx : (uint64_t)tx - rx;
    return d * 100u > (uint64_t)tx * TOLERANCE_PCT;
}

static ns_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (ns_t)ts.tv_sec * NS_PER_S + (ns_t)ts.tv_nsec;
}

/* ------------------------------------------------------------------------ */
/* Deterministic PRNG (splitmix64). Two streams: noise draws 8 values per
 * byte on the wire whenever the BER is non-zero, so a given byte sequence
 * gets the same noise for a given seed; garbage (collisions, baud
 * mismatch) has its own stream. */

struct rng {
    uint64_t s;
};

static uint64_t rng_next(struct rng *r)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static double rng_unit(struct rng *r)
{
    return (double)(rng_next(r) >> 11) * (1.0 / 9007199254740992.0);
}

/* A byte guaranteed to differ from v. */
static uint8_t rng_garble(struct rng *r, uint8_t v)
{
    uint8_t x = (uint8_t)(1u + (unsigned)(rng_next(r) % 255u));
    return (uint8_t)(v ^ x);
}

/* ------------------------------------------------------------------------ */

struct wbyte { /* one character on the wire */
    ns_t start, end;
    uint32_t baud;
    uint8_t val;
    uint8_t coll; /* overlapped another endpoint's character */
};

struct burst { /* capture accumulator, one per source */
    int open;
    ns_t start, last_end;
    uint32_t baud;
    size_t len;
    int coll, noise;
    uint8_t tx[BURST_CAP], rx[BURST_CAP];
};

struct ep {
    int mfd, sfd;
    char path[64];
    char *link;
    int linked;
    struct wbyte q[TXQ_CAP]; /* ring, ordered by time */
    size_t qhead, qlen;
    ns_t tx_end;
    uint64_t bytes_in, bytes_out, dropped;
    uint8_t out[OUT_CAP];
    size_t outlen;
    uint32_t rxbaud; /* cached per delivery round, 0 = unknown */
    ns_t flush_at;   /* --latency: when the held bytes are handed over; 0 = none held */
    struct burst cap;
};

/* --latency: a USB-serial adapter between the wire and one endpoint. The
 * adapter holds received bytes and hands them to the host in bursts: on the
 * first tick of a period-long clock (its latency timer; a random phase per
 * endpoint) after the first byte it holds, plus 0..jitter of host
 * scheduling, or as soon as it holds chunk bytes (a full USB packet). The
 * echo of the endpoint's own bytes comes back the same way, as on a real
 * adapter. Only delivery to the endpoint is modelled; its writes reach the
 * wire at once. */
struct latency {
    ns_t period, jitter, phase; /* period 0: no adapter, bytes at once */
    size_t chunk;
};

struct client {
    int fd;
    size_t len;
    char buf[CLIENT_LINE];
};

struct vbus {
    int n;
    struct ep *ep[EP_MAX];
    double ber;
    struct rng noise, garbage, jitter;
    struct latency lat[EP_MAX];
    const char *lat_arg[EP_MAX]; /* --latency options, applied once -n is known */
    int nlat_arg;
    FILE *capture;
    const char *capture_path;
    const char *control_path;
    int lfd;
    int control_bound;
    struct client cl[MAX_CLIENTS];
    int verbose;
    int quit;
    ns_t t0;
    uint64_t collisions, collided_bytes, noise_flips, noise_bytes;
    uint64_t mismatched_bytes, dropped, wire_bytes;
};

static void vlog(const struct vbus *vb, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void vlog(const struct vbus *vb, const char *fmt, ...)
{
    va_list ap;
    if (!vb->verbose) {
        return;
    }
    va_start(ap, fmt);
    tool_verror(fmt, ap);
    va_end(ap);
}

static struct wbyte *q_at(struct ep *e, size_t i)
{
    return &e->q[(e->qhead + i) % TXQ_CAP];
}

/* ------------------------------------------------------------------------ */
/* Capture */

static void burst_flush(struct vbus *vb, int src)
{
    struct burst *b = &vb->ep[src]->cap;
    if (!b->open) {
        return;
    }
    b->open = 0;
    if (!vb->capture) {
        return;
    }
    ns_t d = b->start - vb->t0;
    if (d < 0) {
        d = 0;
    }
    FILE *f = vb->capture;
    fprintf(f, "%" PRId64 ".%06" PRId64 " %d %" PRIu32 " ", (int64_t)(d / NS_PER_S),
            (int64_t)((d % NS_PER_S) / 1000), src, b->baud);
    for (size_t i = 0; i < b->len; i++) {
        fprintf(f, "%02x", b->tx[i]);
    }
    if (b->coll) {
        fputs(" collision", f);
    }
    if (b->noise) {
        fputs(" noise", f);
    }
    if (b->coll || b->noise) {
        fputs(" rx=", f);
        for (size_t i = 0; i < b->len; i++) {
            fprintf(f, "%02x", b->rx[i]);
        }
    }
    fputc('\n', f);
    fflush(f);
}

static ns_t gap_limit(uint32_t baud)
{
    ns_t ct = char_ns(baud);
    return ct + ct / 2;
}

static void burst_add(struct vbus *vb, int src, const struct wbyte *w, uint8_t rx, int noisy)
{
    struct burst *b = &vb->ep[src]->cap;
    if (b->open && (w->start - b->last_end > gap_limit(b->baud) || w->baud != b->baud ||
                    b->len == BURST_CAP)) {
        burst_flush(vb, src);
    }
    if (!b->open) {
        b->open = 1;
        b->start = w->start;
        b->baud = w->baud;
        b->len = 0;
        b->coll = b->noise = 0;
    }
    b->tx[b->len] = w->val;
    b->rx[b->len] = rx;
    b->len++;
    b->coll |= w->coll;
    b->noise |= noisy;
    b->last_end = w->end;
}

/* ------------------------------------------------------------------------ */
/* Wire */

/* Puts bytes read from endpoint src's master on the wire. */
static void schedule(struct vbus *vb, int src, const uint8_t *buf, size_t n, ns_t now)
{
    struct ep *e = vb->ep[src];
    uint32_t baud = pty_baud(e->mfd, 0);
    ns_t ct = char_ns(baud);
    size_t scan[EP_MAX] = {0};

    for (size_t k = 0; k < n && e->qlen < TXQ_CAP; k++) {
        ns_t s = e->tx_end > now ? e->tx_end : now;
        struct wbyte *pred = e->qlen ? q_at(e, e->qlen - 1) : NULL;
        int same_event = pred && pred->end == s && pred->coll;
        struct wbyte *w = q_at(e, e->qlen);
        e->qlen++;
        w->start = s;
        w->end = s + ct;
        w->baud = baud;
        w->val = buf[k];
        w->coll = 0;
        e->tx_end = w->end;

        for (int j = 0; j < vb->n; j++) {
            struct ep *o = vb->ep[j];
            if (j == src) {
                continue;
            }
            while (scan[j] < o->qlen && q_at(o, scan[j])->end <= s) {
                scan[j]++;
            }
            for (size_t m = scan[j]; m < o->qlen; m++) {
                struct wbyte *x = q_at(o, m);
                if (x->start >= w->end) {
                    break;
                }
                x->coll = 1;
                w->coll = 1;
            }
        }
        if (w->coll && !same_event) {
            vb->collisions++;
            vlog(vb, "collision: endpoint %d started a character while another was on the wire",
                 src);
        }
    }
    e->bytes_in += n;
}

static void out_flush(struct vbus *vb, int r)
{
    struct ep *e = vb->ep[r];
    if (!e->outlen) {
        return;
    }
    ssize_t w = write(e->mfd, e->out, e->outlen);
    size_t done = w > 0 ? (size_t)w : 0;
    if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
        vlog(vb, "endpoint %d: write: %s", r, strerror(errno));
    }
    if (done < e->outlen) {
        size_t lost = e->outlen - done;
        e->dropped += lost;
        vb->dropped += lost;
        vlog(vb, "endpoint %d: input queue full, dropped %zu bytes", r, lost);
    }
    e->bytes_out += done;
    e->outlen = 0;
}

static void out_put(struct vbus *vb, int r, uint8_t v)
{
    struct ep *e = vb->ep[r];
    if (e->outlen == OUT_CAP) {
        out_flush(vb, r);
    }
    e->out[e->outlen++] = v;
}

static void deliver_byte(struct vbus *vb, int src, const struct wbyte *w)
{
    uint8_t wire = w->val;
    int flips = 0;

    vb->wire_bytes++;
    if (w->coll) {
        wire = rng_garble(&vb->garbage, w->val);
        vb->collided_bytes++;
    } else if (vb->ber > 0) {
        for (int bit = 0; bit < 8; bit++) {
            if (rng_unit(&vb->noise) < vb->ber) {
                wire = (uint8_t)(wire ^ (1u << bit));
                flips++;
            }
        }
        if (flips) {
            vb->noise_flips += (uint64_t)flips;
            vb->noise_bytes++;
        }
    }
    for (int r = 0; r < vb->n; r++) {
        struct ep *e = vb->ep[r];
        uint8_t v = wire;
        if (!e->rxbaud) {
            e->rxbaud = pty_baud(e->mfd, 1);
        }
        if (baud_mismatch(e->rxbaud, w->baud)) {
            v = rng_garble(&vb->garbage, w->val);
            vb->mismatched_bytes++;
        }
        out_put(vb, r, v);
    }
    burst_add(vb, src, w, wire, flips > 0);
}

/* Hands what endpoint r holds to its pty: at once without --latency,
 * else when its adapter's latency timer fires or a packet is full. */
static void out_release(struct vbus *vb, int r, ns_t now)
{
    struct ep *e = vb->ep[r];
    const struct latency *l = &vb->lat[r];
    if (!l->period || e->outlen >= l->chunk || (e->flush_at && now >= e->flush_at)) {
        out_flush(vb, r);
        e->flush_at = 0;
    } else if (e->outlen && !e->flush_at) {
        ns_t since = now - vb->t0 - l->phase;
        ns_t tick = vb->t0 + l->phase + (since < 0 ? 0 : (since / l->period + 1) * l->period);
        ns_t extra = l->jitter ? (ns_t)(rng_unit(&vb->jitter) * (double)l->jitter) : 0;
        e->flush_at = tick + extra;
    }
}

/* Delivers every character whose time on the wire has ended, in order. */
static void deliver_due(struct vbus *vb, ns_t now)
{
    int any = 0;
    for (int r = 0; r < vb->n; r++) {
        vb->ep[r]->rxbaud = 0;
    }
    for (;;) {
        int best = -1;
        ns_t best_end = 0;
        for (int i = 0; i < vb->n; i++) {
            struct ep *e = vb->ep[i];
            if (!e->qlen) {
                continue;
            }
            ns_t end = q_at(e, 0)->end;
            if (end <= now && (best < 0 || end < best_end)) {
                best = i;
                best_end = end;
            }
        }
        if (best < 0) {
            break;
        }
        struct ep *e = vb->ep[best];
        struct wbyte w = *q_at(e, 0);
        e->qhead = (e->qhead + 1) % TXQ_CAP;
        e->qlen--;
        deliver_byte(vb, best, &w);
        any = 1;
    }
    for (int r = 0; r < vb->n; r++) {
        if (any || vb->ep[r]->flush_at) {
            out_release(vb, r, now);
        }
    }
    /* A burst ends once its source has been silent for 1.5 characters. */
    for (int i = 0; i < vb->n; i++) {
        struct ep *e = vb->ep[i];
        if (e->cap.open && !e->qlen && now - e->cap.last_end > gap_limit(e->cap.baud)) {
            burst_flush(vb, i);
        }
    }
}

/* Earliest deadline (delivery or burst end) or -1 for none. */
static ns_t next_deadline(struct vbus *vb)
{
    ns_t t = -1;
    for (int i = 0; i < vb->n; i++) {
        struct ep *e = vb->ep[i];
        ns_t d = -1;
        if (e->qlen) {
            d = q_at(e, 0)->end;
        } else if (e->cap.open) {
            d = e->cap.last_end + gap_limit(e->cap.baud) + 1;
        }
        if (e->flush_at && (d < 0 || e->flush_at < d)) {
            d = e->flush_at;
        }
        if (d >= 0 && (t < 0 || d < t)) {
            t = d;
        }
    }
    return t;
}

static void read_endpoint(struct vbus *vb, int i, ns_t now)
{
    struct ep *e = vb->ep[i];
    uint8_t buf[TXQ_CAP];
    size_t room = TXQ_CAP - e->qlen;
    if (!room) {
        return;
    }
    ssize_t r = read(e->mfd, buf, room);
    if (r > 0) {
        vlog(vb, "endpoint %d: %zd bytes to the wire", i, r);
        schedule(vb, i, buf, (size_t)r, now);
    } else if (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
        vlog(vb, "endpoint %d: read: %s", i, strerror(errno));
    }
}

/* ------------------------------------------------------------------------ */
/* Control socket */

static void client_send(struct vbus *vb, struct client *c, const char *s)
{
    size_t len = strlen(s);
    ssize_t w = send(c->fd, s, len, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (w < 0 || (size_t)w != len) {
        vlog(vb, "control client too slow or gone; closing it");
        close(c->fd);
        c->fd = -1;
    }
}

static void stats_json(struct vbus *vb, char *out, size_t cap)
{
    size_t n = 0;
#define APPEND(...)                                       \
    do {                                                  \
        int k_ = snprintf(out + n, cap - n, __VA_ARGS__); \
        if (k_ > 0)                                       \
            n += (size_t)k_;                              \
        if (n >= cap)                                     \
            n = cap - 1;                                  \
    } while (0)
    APPEND("{\"endpoints\":[");
    for (int i = 0; i < vb->n; i++) {
        struct ep *e = vb->ep[i];
        APPEND("%s{\"index\":%d,\"path\":\"%s\",\"baud\":%" PRIu32 ",\"bytes_in\":%" PRIu64
               ",\"bytes_out\":%" PRIu64 ",\"dropped\":%" PRIu64
               ",\"latency_ms\":%.6g,\"jitter_ms\":%.6g}",
               i ? "," : "", i, e->path, pty_baud(e->mfd, 0), e->bytes_in, e->bytes_out, e->dropped,
               (double)vb->lat[i].period / 1e6, (double)vb->lat[i].jitter / 1e6);
    }
    APPEND("],\"collisions\":%" PRIu64 ",\"collided_bytes\":%" PRIu64 ",\"noise_flips\":%" PRIu64
           ",\"noise_bytes\":%" PRIu64 ",\"mismatched_bytes\":%" PRIu64 ",\"dropped\":%" PRIu64
           ",\"wire_bytes\":%" PRIu64 ",\"ber\":%.9g}\n",
           vb->collisions, vb->collided_bytes, vb->noise_flips, vb->noise_bytes,
           vb->mismatched_bytes, vb->dropped, vb->wire_bytes, vb->ber);
#undef APPEND
}

static int parse_ber(const char *s, double *out)
{
    char *end;
    if (!*s) {
        return -1;
    }
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || !isfinite(v) || v < 0.0 || v > 1.0) {
        return -1;
    }
    *out = v;
    return 0;
}

/* One millisecond figure of --latency: 0..LAT_PERIOD_MAX_MS. */
static int parse_ms(const char *s, const char *end, ns_t *out)
{
    char num[32], *stop;
    size_t len = (size_t)(end - s);
    if (!len || len >= sizeof num) {
        return -1;
    }
    memcpy(num, s, len);
    num[len] = '\0';
    errno = 0;
    double v = strtod(num, &stop);
    if (errno || *stop || !isfinite(v) || v < 0.0 || v > LAT_PERIOD_MAX_MS) {
        return -1;
    }
    *out = (ns_t)(v * 1e6);
    return 0;
}

/* "EP:PERIOD_MS[:JITTER_MS[:CHUNK]]" (EP an index or "all") into vb->lat;
 * 0, or -1 with nothing changed. The phase of the latency clock is drawn
 * from the jitter stream, so it is reproducible with --seed. */
static int parse_latency(struct vbus *vb, int nep, const char *arg)
{
    struct latency l = {0, 0, 0, LAT_CHUNK_DEFAULT};
    const char *f[4] = {arg, NULL, NULL, NULL};
    int nf = 1, lo, hi;
    unsigned long v;
    for (const char *p = arg; *p; p++) {
        if (*p == ':') {
            if (nf == 4) {
                return -1;
            }
            f[nf++] = p + 1;
        }
    }
    if (nf < 2) {
        return -1;
    }
    const char *end1 = f[1] - 1;
    if (end1 - f[0] == 3 && !strncmp(f[0], "all", 3)) {
        lo = 0;
        hi = nep - 1;
    } else {
        char idx[8];
        size_t len = (size_t)(end1 - f[0]);
        if (!len || len >= sizeof idx) {
            return -1;
        }
        memcpy(idx, f[0], len);
        idx[len] = '\0';
        if (tool_parse_ulong(idx, 10, 0, (unsigned long)nep - 1, &v) != 0) {
            return -1;
        }
        lo = hi = (int)v;
    }
    if (parse_ms(f[1], nf > 2 ? f[2] - 1 : f[1] + strlen(f[1]), &l.period) < 0) {
        return -1;
    }
    if (nf > 2 && parse_ms(f[2], nf > 3 ? f[3] - 1 : f[2] + strlen(f[2]), &l.jitter) < 0) {
        return -1;
    }
    if (nf > 3) {
        if (tool_parse_ulong(f[3], 10, 1, OUT_CAP, &v) != 0) {
            return -1;
        }
        l.chunk = (size_t)v;
    }
    for (int i = lo; i <= hi; i++) {
        vb->lat[i] = l;
        vb->lat[i].phase = (ns_t)(rng_unit(&vb->jitter) * (double)l.period);
    }
    return 0;
}

static void client_command(struct vbus *vb, struct client *c, char *line)
{
    size_t len = strlen(line);
    while (len && (line[len - 1] == '\r' || line[len - 1] == ' ' || line[len - 1] == '\t')) {
        line[--len] = '\0';
    }
    while (*line == ' ' || *line == '\t') {
        line++;
    }
    if (!strcmp(line, "stats")) {
        char buf[8192];
        stats_json(vb, buf, sizeof buf);
        client_send(vb, c, buf);
    } else if (!strncmp(line, "ber", 3) && (line[3] == ' ' || line[3] == '\t')) {
        const char *arg = line + 4;
        double v;
        while (*arg == ' ' || *arg == '\t') {
            arg++;
        }
        if (parse_ber(arg, &v) == 0) {
            vb->ber = v;
            vlog(vb, "bit error rate set to %g", v);
            client_send(vb, c, "ok\n");
        } else {
            client_send(vb, c, "error: ber needs a number from 0 to 1\n");
        }
    } else if (!strncmp(line, "latency", 7) && (line[7] == ' ' || line[7] == '\t')) {
        const char *arg = line + 8;
        while (*arg == ' ' || *arg == '\t') {
            arg++;
        }
        if (parse_latency(vb, vb->n, arg) == 0) {
            vlog(vb, "latency set: %s", arg);
            client_send(vb, c, "ok\n");
        } else {
            client_send(vb, c, "error: latency needs EP:PERIOD_MS[:JITTER_MS[:CHUNK]]\n");
        }
    } else if (!strcmp(line, "quit")) {
        client_send(vb, c, "ok\n");
        vb->quit = 1;
    } else if (!*line) {
        client_send(vb, c, "error: empty command (try: stats, ber <x>, latency <spec>, quit)\n");
    } else {
        client_send(vb, c, "error: unknown command (try: stats, ber <x>, latency <spec>, quit)\n");
    }
}

static void client_read(struct vbus *vb, struct client *c)
{
    ssize_t r = recv(c->fd, c->buf + c->len, CLIENT_LINE - c->len, MSG_DONTWAIT);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
        close(c->fd);
        c->fd = -1;
        return;
    }
    if (r < 0) {
        return;
    }
    c->len += (size_t)r;
    for (;;) {
        char *nl = memchr(c->buf, '\n', c->len);
        if (!nl) {
            break;
        }
        *nl = '\0';
        size_t used = (size_t)(nl - c->buf) + 1;
        client_command(vb, c, c->buf);
        if (c->fd < 0) {
            return;
        }
        memmove(c->buf, c->buf + used, c->len - used);
        c->len -= used;
    }
    if (c->len == CLIENT_LINE) {
        client_send(vb, c, "error: line too long\n");
        c->len = 0;
    }
}

static void client_accept(struct vbus *vb)
{
    int fd = accept4(vb->lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
        return;
    }
    for (int i = 0; i < MAX_CLIENTS; i++) {
        if (vb->cl[i].fd < 0) {
            vb->cl[i].fd = fd;
            vb->cl[i].len = 0;
            vlog(vb, "control client connected");
            return;
        }
    }
    const char *msg = "error: too many control clients\n";
    (void)!send(fd, msg, strlen(msg), MSG_NOSIGNAL | MSG_DONTWAIT);
    close(fd);
}

static int control_open(struct vbus *vb, const char *path)
{
    struct sockaddr_un sa;
    struct stat st;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    memcpy(sa.sun_path, path, strlen(path) + 1);

    if (lstat(path, &st) == 0) {
        if (!S_ISSOCK(st.st_mode)) {
            tool_error("refusing to replace %s: it exists and is not a socket", path);
            return -1;
        }
        int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
        if (probe >= 0 && connect(probe, (struct sockaddr *)&sa, sizeof sa) == 0) {
            close(probe);
            tool_error("control socket %s is in use by another program", path);
            return -1;
        }
        if (probe >= 0) {
            close(probe);
        }
        unlink(path);
    }
    vb->lfd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (vb->lfd < 0) {
        tool_error("socket: %s", strerror(errno));
        return -1;
    }
    if (bind(vb->lfd, (struct sockaddr *)&sa, sizeof sa) < 0) {
        tool_error("cannot create control socket %s: %s", path, strerror(errno));
        return -1;
    }
    vb->control_bound = 1;
    if (listen(vb->lfd, MAX_CLIENTS) < 0) {
        tool_error("listen on %s: %s", path, strerror(errno));
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------------ */
/* Setup and teardown */

static int ep_open(struct vbus *vb, int i)
{
    struct ep *e = vb->ep[i];
    struct termios t;

    e->mfd = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (e->mfd < 0) {
        tool_error("cannot open a pseudo-terminal: %s", strerror(errno));
        return -1;
    }
    if (grantpt(e->mfd) < 0 || unlockpt(e->mfd) < 0 ||
        ptsname_r(e->mfd, e->path, sizeof e->path) != 0) {
        tool_error("cannot set up pseudo-terminal: %s", strerror(errno));
        return -1;
    }
    /* Holding the slave open keeps the pty alive while users close and
     * reopen it (no POLLHUP/EIO on the master). */
    e->sfd = open(e->path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (e->sfd < 0) {
        tool_error("cannot open %s: %s", e->path, strerror(errno));
        return -1;
    }
    if (tcgetattr(e->sfd, &t) < 0) {
        tool_error("tcgetattr %s: %s", e->path, strerror(errno));
        return -1;
    }
    cfmakeraw(&t);
    cfsetispeed(&t, B9600);
    cfsetospeed(&t, B9600);
    if (tcsetattr(e->sfd, TCSANOW, &t) < 0) {
        tool_error("tcsetattr %s: %s", e->path, strerror(errno));
        return -1;
    }
    vlog(vb, "endpoint %d is %s", i, e->path);
    return 0;
}

/* A link may be replaced if it is stale: it points at nothing. One that
 * points at a pty that exists belongs to a live bus (a pty's node goes
 * away with its master): a second dan-vbus replaced a running bus's links
 * and removed them on exit (review finding). */
static int link_check(const char *link)
{
    struct stat st, target;
    if (lstat(link, &st) == 0) {
        if (!S_ISLNK(st.st_mode)) {
            tool_error("refusing to replace %s: it exists and is not a symbolic link", link);
            return -1;
        }
        if (stat(link, &target) == 0 && S_ISCHR(target.st_mode)) {
            tool_error("refusing to replace %s: it points at a live pty (another bus?); "
                       "remove it if not",
                       link);
            return -1;
        }
    } else if (errno != ENOENT) {
        tool_error("cannot use %s: %s", link, strerror(errno));
        return -1;
    }
    return 0;
}

static int link_make(struct ep *e)
{
    char tmp[PATH_MAX + LINK_SUFFIX_ROOM];
    snprintf(tmp, sizeof tmp, "%s.vbus%ld", e->link, (long)getpid());
    unlink(tmp);
    if (symlink(e->path, tmp) < 0) {
        tool_error("cannot create symbolic link %s: %s", e->link, strerror(errno));
        return -1;
    }
    if (rename(tmp, e->link) < 0) {
        tool_error("cannot create symbolic link %s: %s", e->link, strerror(errno));
        unlink(tmp);
        return -1;
    }
    e->linked = 1;
    return 0;
}

/* Removes our link unless someone has pointed it elsewhere meanwhile. */
static void link_remove(struct ep *e)
{
    char buf[sizeof e->path];
    if (!e->linked) {
        return;
    }
    ssize_t n = readlink(e->link, buf, sizeof buf - 1);
    if (n >= 0) {
        buf[n] = '\0';
        if (!strcmp(buf, e->path)) {
            unlink(e->link);
        }
    }
    e->linked = 0;
}

static void cleanup(struct vbus *vb)
{
    for (int i = 0; i < vb->n; i++) {
        if (vb->ep[i]) {
            burst_flush(vb, i);
        }
    }
    for (int i = 0; i < MAX_CLIENTS; i++) {
        if (vb->cl[i].fd >= 0) {
            close(vb->cl[i].fd);
        }
    }
    if (vb->lfd >= 0) {
        close(vb->lfd);
    }
    if (vb->control_bound) {
        unlink(vb->control_path);
    }
    for (int i = 0; i < vb->n; i++) {
        struct ep *e = vb->ep[i];
        if (!e) {
            continue;
        }
        link_remove(e);
        if (e->sfd >= 0) {
            close(e->sfd);
        }
        if (e->mfd >= 0) {
            close(e->mfd);
        }
        free(e->link);
        free(e);
        vb->ep[i] = NULL;
    }
    if (vb->capture) {
        fclose(vb->capture);
    }
    vb->capture = NULL;
}

/* ------------------------------------------------------------------------ */
/* Command line */

static void usage(FILE *f)
{
    fprintf(f,
            "Usage: " PROG " [-n N] [--link PREFIX] [options]\n"
            "\n"
            "A virtual half-duplex single-wire UART bus for testing without hardware.\n"
            "It creates N pseudo-terminals (\"endpoints\"). Programs open them like serial\n"
            "ports. Every byte written to one endpoint travels on a shared simulated wire\n"
            "and is received by ALL endpoints, the writer included (its echo), just as on\n"
            "a real single-wire bus.\n"
            "\n"
            "  * Timing: a byte takes 10 bit times (8N1) at the writer's baud rate, which\n"
            "    is read from the termios the program set on its endpoint (non-standard\n"
            "    rates set with BOTHER/termios2 work). Bytes are delivered when their\n"
            "    time on the wire has ended; one writer's bytes go out back to back.\n"
            "  * Baud mismatch: a receiver whose baud rate differs from the writer's by\n"
            "    more than 3%% receives garbage bytes instead (one per byte sent).\n"
            "  * Collisions: if two endpoints' bytes overlap in time, every overlapping\n"
            "    byte is corrupted for everybody, writers included, so a writer sees the\n"
            "    collision as an echo that does not match what it sent.\n"
            "  * Noise: --ber flips each data bit with the given probability (the same\n"
            "    corrupted byte reaches every receiver). Runs are reproducible: the\n"
            "    pseudo-random generator is seeded by --seed.\n"
            "  * A receiver that does not read never blocks the bus: when its input\n"
            "    queue is full, bytes for it are dropped and counted.\n"
            "  * Endpoints start raw (no echo, no line editing) at 9600 baud.\n"
            "\n"
            "Options:\n"
            "  -n, --endpoints N   number of endpoints, 2 to 16 (default 2)\n"
            "  -l, --link PREFIX   create symbolic links PREFIX0 .. PREFIX<N-1> to the\n"
            "                      endpoints (stale links are replaced; other files are\n"
            "                      never overwritten); removed again on exit\n"
            "      --ber X         bit error rate, 0 to 1 (default 0)\n"
            "      --seed S        seed for noise and garbage, 0 to 2^64-1 (default %u)\n"
            "      --capture FILE  write one line per burst on the wire to FILE\n"
            "      --control PATH  accept commands on a Unix stream socket at PATH\n"
            "      --latency EP:PERIOD_MS[:JITTER_MS[:CHUNK]]\n"
            "                      put a USB-serial adapter model in front of endpoint EP\n"
            "                      (an index or 'all'; repeatable): bytes for it are held\n"
            "                      and handed over in bursts, on the next tick of a\n"
            "                      PERIOD_MS clock (its latency timer) plus a random\n"
            "                      0..JITTER_MS, or at once when CHUNK bytes are held\n"
            "                      (default %u, an FTDI packet); its echo too.\n"
            "                      E.g. 0:16 is an FTDI chip at its default latency timer\n"
            "  -v, --verbose       debug messages on stderr\n"
            "  -h, --help          show this help and exit\n"
            "\n"
            "Once everything is set up, one line is printed to standard output:\n"
            "  READY <endpoint0> <endpoint1> ...\n"
            "with the pseudo-terminal paths, so scripts can wait for it.\n"
            "\n"
            "Capture format (--capture): lines starting with '#' are comments; every other\n"
            "line is one burst (a run of back-to-back bytes from one writer; a silence of\n"
            "more than 1.5 character times ends it; bursts over %u bytes are split):\n"
            "  <time> <source> <baud> <hex> [collision] [noise] [rx=<hex>]\n"
            "  time      seconds since start, 6 decimals, when the first byte started\n"
            "  source    index of the writing endpoint\n"
            "  baud      writer's baud rate\n"
            "  hex       the bytes as sent, two lowercase hex digits each, no spaces\n"
            "  collision some bytes overlapped another writer's\n"
            "  noise     some bits were flipped by --ber\n"
            "  rx=<hex>  present with a flag: the bytes as they were on the wire after\n"
            "            corruption (baud-mismatch garbage at a receiver is not shown)\n"
            "Example: 0.512340 1 115200 a50102ff\n"
            "Each line is written and flushed when its burst ends, so lines are in the\n"
            "order in which bursts ended (a long burst may be logged after a short one\n"
            "that started later).\n"
            "\n"
            "Control socket (--control), one command per line, one line answered:\n"
            "  stats     JSON object: \"endpoints\": [{index, path, baud, bytes_in (bytes\n"
            "            the endpoint wrote), bytes_out (bytes delivered to it), dropped,\n"
            "            latency_ms, jitter_ms}],\n"
            "            collisions (collision events), collided_bytes, noise_flips (bits),\n"
            "            noise_bytes, mismatched_bytes (bytes garbled at a receiver by\n"
            "            baud mismatch), dropped, wire_bytes, ber\n"
            "  ber <x>   set the bit error rate; answers ok\n"
            "  latency <EP:PERIOD_MS[:JITTER_MS[:CHUNK]]>  as --latency (0 period: off);\n"
            "            answers ok\n"
            "  quit      answers ok and exits like SIGTERM\n"
            "Errors are answered with a line starting with 'error:'.\n"
            "\n"
            "SIGINT, SIGTERM or SIGHUP: remove the links and the socket, close everything,\n"
            "exit 0.\n"
            "Exit status: 0 normal, 1 setup failure, 2 bad arguments.\n"
            "\n"
            "Example with two programs:\n"
            "  " PROG " -n 2 --link /tmp/dan --capture /tmp/bus.log &\n"
            "  program-a --port /tmp/dan0 &     # e.g. a flight controller simulation\n"
            "  program-b --port /tmp/dan1       # e.g. a peripheral; each also hears itself\n"
            "  kill %%1\n",
            DEFAULT_SEED, LAT_CHUNK_DEFAULT, BURST_CAP);
}

static void bad_arg(const char *fmt, ...) __attribute__((format(printf, 1, 2), noreturn));
static void bad_arg(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, PROG ": ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\nTry '" PROG " --help' for more information.\n");
    va_end(ap);
    exit(2);
}

/* The options that take a path: non-empty, and short enough. */
static const char *path_arg(int c, const char *arg)
{
    struct sockaddr_un sa;
    if (c == 'l' && !*arg) {
        bad_arg("--link needs a non-empty PREFIX");
    }
    if (c == 'l' && strlen(arg) > PATH_MAX - LINK_SUFFIX_ROOM) {
        bad_arg("--link PREFIX is too long");
    }
    if (c == 'c' && !*arg) {
        bad_arg("--capture needs a file name");
    }
    if (c == 'C' && !*arg) {
        bad_arg("--control needs a socket path");
    }
    if (c == 'C' && strlen(arg) >= sizeof sa.sun_path) {
        bad_arg("--control path is too long (at most %zu characters)", sizeof sa.sun_path - 1);
    }
    return arg;
}

static uint64_t parse_seed(const char *arg)
{
    char *end;
    unsigned long long v;
    errno = 0;
    v = strtoull(arg, &end, 0);
    if (errno || end == arg || *end || strchr(arg, '-')) {
        bad_arg("--seed must be a whole number from 0 to 2^64-1, not '%s'", arg);
    }
    return (uint64_t)v;
}

/* Exits on --help and on bad arguments (status 2). */
static void parse_options(int argc, char **argv, struct vbus *vb, const char **link_prefix,
                          uint64_t *seed)
{
    static const struct option opts[] = {
        {"endpoints", required_argument, NULL, 'n'},
        {"link", required_argument, NULL, 'l'},
        {"ber", required_argument, NULL, 'b'},
        {"seed", required_argument, NULL, 's'},
        {"capture", required_argument, NULL, 'c'},
        {"control", required_argument, NULL, 'C'},
        {"latency", required_argument, NULL, 'L'},
        {"verbose", no_argument, NULL, 'v'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    unsigned long n;
    int c;
    opterr = 0;
    while ((c = getopt_long(argc, argv, ":n:l:vh", opts, NULL)) != -1) {
        switch (c) {
        case 'n':
            if (tool_parse_ulong(optarg, 10, EP_MIN, EP_MAX, &n) != 0) {
                bad_arg("-n/--endpoints must be a whole number from %d to %d, not '%s'", EP_MIN,
                        EP_MAX, optarg);
            }
            vb->n = (int)n;
            break;
        case 'l': *link_prefix = path_arg(c, optarg); break;
        case 'b':
            if (parse_ber(optarg, &vb->ber) < 0) {
                bad_arg("--ber must be a number from 0 to 1, not '%s'", optarg);
            }
            break;
        case 's': *seed = parse_seed(optarg); break;
        case 'c': vb->capture_path = path_arg(c, optarg); break;
        case 'C': vb->control_path = path_arg(c, optarg); break;
        case 'L':
            if (vb->nlat_arg == EP_MAX) {
                bad_arg("at most %d --latency options", EP_MAX);
            }
            vb->lat_arg[vb->nlat_arg++] = optarg;
            break;
        case 'v': vb->verbose = 1; break;
        case 'h': usage(stdout); exit(0);
        case ':': bad_arg("option '%s' needs a value", argv[optind - 1]);
        default:
            if (optopt) {
                bad_arg("unknown option '-%c'", optopt);
            }
            bad_arg("unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind < argc) {
        bad_arg("unexpected argument '%s'", argv[optind]);
    }
}

/* Handlers set tool_stop; the signals are blocked except inside ppoll,
 * whose mask (orig) lets them through. */
static void setup_signals(sigset_t *orig)
{
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    sigset_t block;
    size_t i;
    sigemptyset(&block);
    for (i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        sigaddset(&block, sigs[i]);
    }
    sigprocmask(SIG_BLOCK, &block, orig);
    for (i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        tool_catch_signal(sigs[i]);
        sigdelset(orig, sigs[i]);
    }
    signal(SIGPIPE, SIG_IGN);
}

/* Allocates the endpoints and checks their link names; 0 or -1. */
static int alloc_endpoints(struct vbus *vb, const char *link_prefix)
{
    for (int i = 0; i < vb->n; i++) {
        vb->ep[i] = calloc(1, sizeof *vb->ep[i]);
        if (!vb->ep[i]) {
            tool_error("out of memory");
            return -1;
        }
        vb->ep[i]->mfd = vb->ep[i]->sfd = -1;
        if (link_prefix) {
            size_t len = strlen(link_prefix) + LINK_INDEX_ROOM;
            vb->ep[i]->link = malloc(len);
            if (!vb->ep[i]->link) {
                tool_error("out of memory");
                return -1;
            }
            snprintf(vb->ep[i]->link, len, "%s%d", link_prefix, i);
            if (link_check(vb->ep[i]->link) < 0) {
                return -1;
            }
        }
    }
    return 0;
}

static int open_capture(struct vbus *vb)
{
    vb->capture = fopen(vb->capture_path, "w");
    if (!vb->capture) {
        tool_error("cannot open capture file %s: %s", vb->capture_path, strerror(errno));
        return -1;
    }
    fprintf(vb->capture,
            "# dan-vbus capture: <time> <source> <baud> <hex> [collision] [noise] [rx=<hex>]\n#");
    for (int i = 0; i < vb->n; i++) {
        fprintf(vb->capture, " %d=%s", i, vb->ep[i]->path);
    }
    fputc('\n', vb->capture);
    fflush(vb->capture);
    return 0;
}

/* Everything before READY: endpoints, control socket, ptys, capture file,
 * links; 0 or -1 after a message. */
static int setup(struct vbus *vb, const char *link_prefix)
{
    if (alloc_endpoints(vb, link_prefix) < 0) {
        return -1;
    }
    if (vb->control_path && control_open(vb, vb->control_path) < 0) {
        return -1;
    }
    for (int i = 0; i < vb->n; i++) {
        if (ep_open(vb, i) < 0) {
            return -1;
        }
    }
    if (vb->capture_path && open_capture(vb) < 0) {
        return -1;
    }
    for (int i = 0; i < vb->n; i++) {
        if (vb->ep[i]->link && link_make(vb->ep[i]) < 0) {
            return -1;
        }
    }
    return 0;
}

/* The fds of one ppoll round: endpoints, then the listening socket, then
 * the connected clients (who[k] is the client of pfd[cidx + k]). */
struct pollset {
    struct pollfd pfd[EP_MAX + 1 + MAX_CLIENTS];
    int who[MAX_CLIENTS];
    nfds_t nfd, lidx, cidx;
    int ncl;
};

static void pollset_add(struct pollset *ps, int fd, short events)
{
    ps->pfd[ps->nfd].fd = fd;
    ps->pfd[ps->nfd].events = events;
    ps->pfd[ps->nfd].revents = 0;
    ps->nfd++;
}

static void pollset_fill(struct vbus *vb, struct pollset *ps)
{
    ps->nfd = 0;
    for (int i = 0; i < vb->n; i++) {
        /* A full transmit queue stops reading: the writer blocks, like a
         * UART with a full FIFO. Reading resumes once a useful amount of
         * room is free again. */
        pollset_add(ps, vb->ep[i]->mfd, vb->ep[i]->qlen <= TXQ_CAP - TXQ_LOW ? POLLIN : 0);
    }
    ps->lidx = ps->nfd;
    if (vb->lfd >= 0) {
        pollset_add(ps, vb->lfd, POLLIN);
    }
    ps->cidx = ps->nfd;
    ps->ncl = 0;
    for (int i = 0; i < MAX_CLIENTS; i++) {
        if (vb->cl[i].fd >= 0) {
            pollset_add(ps, vb->cl[i].fd, POLLIN);
            ps->who[ps->ncl++] = i;
        }
    }
}

/* ppoll until an fd is ready or the next delivery or burst end is due. */
static int pollset_wait(struct vbus *vb, struct pollset *ps, const sigset_t *orig)
{
    struct timespec ts, *tsp = NULL;
    ns_t dl = next_deadline(vb);
    if (dl >= 0) {
        ns_t wait = dl - now_ns();
        if (wait < 0) {
            wait = 0;
        }
        ts.tv_sec = (time_t)(wait / NS_PER_S);
        ts.tv_nsec = (long)(wait % NS_PER_S);
        tsp = &ts;
    }
    return ppoll(ps->pfd, ps->nfd, tsp, orig);
}

static void pollset_handle(struct vbus *vb, const struct pollset *ps, ns_t now)
{
    for (int i = 0; i < vb->n; i++) {
        if (ps->pfd[i].revents & POLLIN) {
            read_endpoint(vb, i, now);
        }
    }
    if (vb->lfd >= 0 && (ps->pfd[ps->lidx].revents & POLLIN)) {
        client_accept(vb);
    }
    for (int k = 0; k < ps->ncl; k++) {
        struct client *cl = &vb->cl[ps->who[k]];
        if (cl->fd >= 0 && (ps->pfd[ps->cidx + (nfds_t)k].revents & (POLLIN | POLLHUP | POLLERR))) {
            client_read(vb, cl);
        }
    }
}

/* The bus, until a signal or "quit"; 0, or 1 when poll fails. */
static int run(struct vbus *vb, const sigset_t *orig)
{
    static struct pollset ps;
    while (!tool_stop && !vb->quit) {
        int pr;
        deliver_due(vb, now_ns());
        pollset_fill(vb, &ps);
        pr = pollset_wait(vb, &ps, orig);
        if (pr < 0) {
            if (errno == EINTR) {
                continue;
            }
            tool_error("poll: %s", strerror(errno));
            return 1;
        }
        if (pr == 0) {
            continue;
        }
        ns_t now = now_ns();
        /* Deliver what is due before new bytes join the wire, so a
         * character that already ended cannot collide. */
        deliver_due(vb, now);
        pollset_handle(vb, &ps, now);
    }
    if (tool_stop) {
        vlog(vb, "signal received, exiting");
    }
    return 0;
}

int main(int argc, char **argv)
{
    static struct vbus vbs;
    struct vbus *vb = &vbs;
    const char *link_prefix = NULL;
    uint64_t seed = DEFAULT_SEED;
    sigset_t orig;
    int rc = 1;

    tool_prog = PROG;
    vb->n = 2;
    vb->lfd = -1;
    for (int i = 0; i < MAX_CLIENTS; i++) {
        vb->cl[i].fd = -1;
    }
    parse_options(argc, argv, vb, &link_prefix, &seed);
    vb->noise.s = seed;
    vb->garbage.s = seed ^ GARBAGE_SEED_XOR;
    vb->jitter.s = seed ^ LATENCY_SEED_XOR;
    for (int i = 0; i < vb->nlat_arg; i++) {
        if (parse_latency(vb, vb->n, vb->lat_arg[i]) < 0) {
            bad_arg("--latency must be EP:PERIOD_MS[:JITTER_MS[:CHUNK]] with EP 0 to %d or 'all', "
                    "times 0 to %g ms and CHUNK 1 to %u, not '%s'",
                    vb->n - 1, LAT_PERIOD_MAX_MS, OUT_CAP, vb->lat_arg[i]);
        }
    }
    setup_signals(&orig);
    if (setup(vb, link_prefix) == 0) {
        vb->t0 = now_ns();
        fputs("READY", stdout);
        for (int i = 0; i < vb->n; i++) {
            printf(" %s", vb->ep[i]->path);
        }
        putchar('\n');
        fflush(stdout);
        rc = run(vb, &orig);
    }
    cleanup(vb);
    return rc;
}
