/*
 * dan-cantool: send or receive CAN frames through the gateway's CAN
 * backends (linux/can_backend.h), for tests and bring-up.
 *
 *   dan-cantool --can SPEC [--ifname NAME] send ID#DATA [ID#DATA ...]
 *   dan-cantool --can SPEC [--ifname NAME] recv [--count N] [--timeout-ms T]
 *
 * ID#DATA as in can-utils' cansend: 3 hex digits = 11-bit id, 8 = 29-bit;
 * DATA is 0..8 bytes in hex (dots allowed between bytes); ID#R or ID#Rn is
 * a remote frame (n = dlc). recv prints candump log lines
 * "(sec.usec) NAME ID#DATA" (NAME defaults to can0).
 *
 * Exit status: 0 success; 1 runtime failure (send refused, BEL, fewer than
 * N frames before the timeout, device lost); 2 bad arguments or open error.
 */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <time.h>

#include "can_backend.h"

static volatile sig_atomic_t g_stop;

static void on_signal(int sig)
{
    (void)sig;
    g_stop = 1;
}

static void usage(FILE *o)
{
    fprintf(o,
        "usage: dan-cantool --can SPEC [--ifname NAME] send ID#DATA [...]\n"
        "       dan-cantool --can SPEC [--ifname NAME] recv [--count N] "
        "[--timeout-ms T]\n"
        "  SPEC: socketcan:IFNAME | slcan:/dev/TTY[@BAUD]\n"
        "  ID#DATA: 123#DEADBEEF (11-bit), 1401550A#0100 (29-bit), 123#R\n"
        "  recv: --count 0 means until the timeout (default count 1, "
        "timeout 5000 ms)\n"
        "exit: 0 ok, 1 runtime failure, 2 bad arguments or open error\n");
}

static int hexv(char ch)
{
    if (ch >= '0' && ch <= '9') {
        return ch - '0';
    }
    if (ch >= 'a' && ch <= 'f') {
        return ch - 'a' + 10;
    }
    if (ch >= 'A' && ch <= 'F') {
        return ch - 'A' + 10;
    }
    return -1;
}

/* Parses cansend syntax; 0 or -1. */
static int parse_frame(const char *s, dan_can_frame_t *f)
{
    const char *hash = strchr(s, '#');
    size_t idlen;
    uint32_t id = 0;

    memset(f, 0, sizeof *f);
    if (!hash) {
        return -1;
    }
    idlen = (size_t)(hash - s);
    if (idlen != 3 && idlen != 8) {
        return -1;
    }
    for (size_t i = 0; i < idlen; i++) {
        int h = hexv(s[i]);
        if (h < 0) {
            return -1;
        }
        id = (id << 4) | (uint32_t)h;
    }
    if (idlen == 8) {
        if (id > DAN_CAN_EFF_MASK) {
            return -1;
        }
        f->flags |= DAN_CAN_EXT;
    } else if (id > DAN_CAN_SFF_MASK) {
        return -1;
    }
    f->id = id;
    s = hash + 1;
    if (*s == 'R' || *s == 'r') {
        f->flags |= DAN_CAN_RTR;
        if (s[1] == '\0') {
            return 0;
        }
        if (s[1] < '0' || s[1] > '8' || s[2] != '\0') {
            return -1;
        }
        f->dlc = (uint8_t)(s[1] - '0');
        return 0;
    }
    while (*s) {
        int hi, lo;
        if (*s == '.') {
            s++;
            continue;
        }
        hi = hexv(s[0]);
        lo = hi < 0 ? -1 : hexv(s[1]);
        if (lo < 0 || f->dlc >= 8) {
            return -1;
        }
        f->data[f->dlc++] = (uint8_t)((hi << 4) | lo);
        s += 2;
    }
    return 0;
}

static void print_frame(const char *ifname, const dan_can_frame_t *f)
{
    struct timeval tv;
    gettimeofday(&tv, NULL);
    printf("(%lld.%06ld) %s ", (long long)tv.tv_sec, (long)tv.tv_usec,
           ifname);
    if (f->flags & DAN_CAN_ERR) {
        printf("%08X#", (unsigned)(f->id | 0x20000000u));
    } else if (f->flags & DAN_CAN_EXT) {
        printf("%08X#", (unsigned)f->id);
    } else {
        printf("%03X#", (unsigned)f->id);
    }
    if (f->flags & DAN_CAN_RTR) {
        printf("R");
        if (f->dlc) {
            printf("%u", (unsigned)f->dlc);
        }
    } else {
        for (unsigned i = 0; i < f->dlc; i++) {
            printf("%02X", f->data[i]);
        }
    }
    printf("\n");
    fflush(stdout);
}

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static int wait_fd(int fd, short ev, long long deadline)
{
    struct pollfd p = { .fd = fd, .events = ev, .revents = 0 };
    long long left = deadline - now_ms();
    if (left < 0) {
        left = 0;
    }
    if (left > 1000) {
        left = 1000;
    }
    return poll(&p, 1, (int)left);
}

static int do_send(dan_canif_t *c, int argc, char **argv)
{
    const long long deadline = now_ms() + 5000;
    dan_can_frame_t f, rf;
    int sent = 0;

    for (int i = 0; i < argc && !g_stop; i++) {
        int r;
        if (parse_frame(argv[i], &f) < 0) {
            fprintf(stderr, "dan-cantool: bad frame '%s' (want ID#DATA)\n",
                    argv[i]);
            return 2;
        }
        while ((r = dan_canif_send(c, &f)) == DAN_ERR_BUSY) {
            if (now_ms() > deadline || g_stop) {
                fprintf(stderr, "dan-cantool: send timed out (output "
                        "blocked)\n");
                return 1;
            }
            wait_fd(dan_canif_fd(c), POLLOUT, deadline);
        }
        if (r < 0) {
            fprintf(stderr, "dan-cantool: send %s: %s\n", argv[i],
                    dan_strerror(r));
            return 1;
        }
        sent++;
    }
    while (dan_canif_tx_pending(c)) {
        int r = dan_canif_flush(c);
        if (r == DAN_ERR_IO || now_ms() > deadline || g_stop) {
            fprintf(stderr, "dan-cantool: flush failed\n");
            return 1;
        }
        if (r == DAN_ERR_BUSY) {
            wait_fd(dan_canif_fd(c), POLLOUT, deadline);
        }
    }
    /* SLCAN: wait for the adapter's z/Z (or BEL) for every frame. */
    if (c->kind == DAN_CANIF_SLCAN) {
        const long long ackdl = now_ms() + 2000;
        while (c->stats.tx_ack + c->stats.bel < (uint32_t)sent && !g_stop) {
            int r = dan_canif_recv(c, &rf);
            if (r < 0) {
                fprintf(stderr, "dan-cantool: %s\n", dan_strerror(r));
                return 1;
            }
            if (r == 1) {
                continue;           /* bus traffic: not ours to print */
            }
            if (c->stats.tx_ack + c->stats.bel >= (uint32_t)sent) {
                break;
            }
            if (now_ms() > ackdl) {
                fprintf(stderr, "dan-cantool: no transmit ACK from the "
                        "adapter for %d of %d frames\n",
                        sent - (int)(c->stats.tx_ack + c->stats.bel), sent);
                return 1;
            }
            wait_fd(dan_canif_fd(c), POLLIN, ackdl);
        }
        if (c->stats.bel) {
            fprintf(stderr, "dan-cantool: adapter refused %u frame(s) "
                    "(BEL)\n", (unsigned)c->stats.bel);
            return 1;
        }
    }
    return 0;
}

static int do_recv(dan_canif_t *c, const char *ifname, long count,
                   long timeout_ms)
{
    const long long deadline = now_ms() + timeout_ms;
    long got = 0;
    dan_can_frame_t f;

    while (!g_stop && (count == 0 || got < count)) {
        int r = dan_canif_recv(c, &f);
        if (r < 0) {
            fprintf(stderr, "dan-cantool: receive failed: %s\n",
                    dan_strerror(r));
            return 1;
        }
        if (r == 1) {
            print_frame(ifname, &f);
            got++;
            continue;
        }
        if (now_ms() >= deadline) {
            break;
        }
        wait_fd(dan_canif_fd(c), POLLIN, deadline);
    }
    if (count > 0 && got < count) {
        fprintf(stderr, "dan-cantool: got %ld of %ld frames before the "
                "timeout\n", got, count);
        return 1;
    }
    return 0;
}

static int parse_long(const char *s, long *v)
{
    char *end;
    errno = 0;
    *v = strtol(s, &end, 10);
    return (errno || end == s || *end || *v < 0) ? -1 : 0;
}

int main(int argc, char **argv)
{
    const char *spec = NULL, *ifname = "can0", *cmd = NULL;
    long count = 1, timeout_ms = 5000;
    int i, rc;
    char err[256];
    dan_canif_t c;
    struct sigaction sa;

    for (i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(argv[i], "--can") && i + 1 < argc) {
            spec = argv[++i];
        } else if (!strcmp(argv[i], "--ifname") && i + 1 < argc) {
            ifname = argv[++i];
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "dan-cantool: unknown option '%s'\n", argv[i]);
            usage(stderr);
            return 2;
        } else {
            cmd = argv[i++];
            break;
        }
    }
    if (!spec || !cmd) {
        fprintf(stderr, "dan-cantool: need --can SPEC and a command\n");
        usage(stderr);
        return 2;
    }
    if (!strcmp(cmd, "send")) {
        if (i >= argc) {
            fprintf(stderr, "dan-cantool: send needs at least one ID#DATA\n");
            return 2;
        }
        for (int k = i; k < argc; k++) {
            dan_can_frame_t f;
            if (parse_frame(argv[k], &f) < 0) {
                fprintf(stderr, "dan-cantool: bad frame '%s' (want "
                        "ID#DATA, e.g. 123#0102 or 1401550A#01)\n", argv[k]);
                return 2;
            }
        }
    } else if (!strcmp(cmd, "recv")) {
        for (; i < argc; i++) {
            if (!strcmp(argv[i], "--count") && i + 1 < argc) {
                if (parse_long(argv[++i], &count) < 0) {
                    fprintf(stderr, "dan-cantool: bad --count\n");
                    return 2;
                }
            } else if (!strcmp(argv[i], "--timeout-ms") && i + 1 < argc) {
                if (parse_long(argv[++i], &timeout_ms) < 0) {
                    fprintf(stderr, "dan-cantool: bad --timeout-ms\n");
                    return 2;
                }
            } else {
                fprintf(stderr, "dan-cantool: unknown recv argument '%s'\n",
                        argv[i]);
                return 2;
            }
        }
    } else {
        fprintf(stderr, "dan-cantool: unknown command '%s' (send|recv)\n",
                cmd);
        return 2;
    }

    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);

    rc = dan_canif_open(&c, spec, err, sizeof err);
    if (rc < 0) {
        fprintf(stderr, "dan-cantool: %s\n", err);
        return 2;
    }
    if (!strcmp(cmd, "send")) {
        rc = do_send(&c, argc - i, argv + i);
    } else {
        rc = do_recv(&c, ifname, count, timeout_ms);
    }
    dan_canif_close(&c);
    return rc;
}
