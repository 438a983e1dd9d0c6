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
#include <limits.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/time.h>

#include "can_backend.h"
#include "dan/posix.h"
#include "dan_tool.h"

/* Longest a poll() waits, so a signal is seen this soon. */
#define POLL_CAP_MS      1000
/* How long send may wait for the output to take all frames. */
#define SEND_TIMEOUT_US  5000000u
/* How long an SLCAN adapter may take to acknowledge them all (z/Z). */
#define ACK_TIMEOUT_US   2000000u
/* candump prints error frames with this bit above the 29-bit id. */
#define CAN_ERR_FLAG_BIT 0x20000000u

static void usage(FILE *o)
{
    fprintf(o, "usage: dan-cantool --can SPEC [--ifname NAME] send ID#DATA [...]\n"
               "       dan-cantool --can SPEC [--ifname NAME] recv [--count N] "
               "[--timeout-ms T]\n"
               "  SPEC: socketcan:IFNAME | slcan:/dev/TTY[@BAUD]\n"
               "  ID#DATA: 123#DEADBEEF (11-bit), 1401550A#0100 (29-bit), 123#R\n"
               "  recv: --count 0 means until the timeout (default count 1, "
               "timeout 5000 ms)\n"
               "exit: 0 ok, 1 runtime failure, 2 bad arguments or open error\n");
}

static void print_frame(const char *ifname, const dan_can_frame_t *f)
{
    struct timeval tv;
    gettimeofday(&tv, NULL);
    printf("(%lld.%06ld) %s ", (long long)tv.tv_sec, (long)tv.tv_usec, ifname);
    if (f->flags & DAN_CAN_ERR) {
        printf("%08X#", (unsigned)(f->id | CAN_ERR_FLAG_BIT));
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

/* Sends each frame, waiting while the output is busy; 0, or 1 after a
 * message. *sent counts the frames the backend took. */
static int send_frames(dan_canif_t *c, int argc, char **argv, uint64_t deadline, int *sent)
{
    dan_can_frame_t f;
    for (int i = 0; i < argc && !tool_stop; i++) {
        int r;
        if (dan_can_parse_cansend(argv[i], &f) < 0) {
            tool_error("bad frame '%s' (want ID#DATA)", argv[i]);
            return 2;
        }
        while ((r = dan_canif_send(c, &f)) == DAN_ERR_BUSY) {
            if (dan_posix_now_us() > deadline || tool_stop) {
                tool_error("send timed out (output blocked)");
                return 1;
            }
            tool_wait_fd(dan_canif_fd(c), POLLOUT, deadline, POLL_CAP_MS);
        }
        if (r < 0) {
            tool_error("send %s: %s", argv[i], dan_strerror(r));
            return 1;
        }
        (*sent)++;
    }
    return 0;
}

/* Writes what the backend still holds; 0, or 1 after a message. */
static int flush_all(dan_canif_t *c, uint64_t deadline)
{
    while (dan_canif_tx_pending(c)) {
        int r = dan_canif_flush(c);
        if (r == DAN_ERR_IO || dan_posix_now_us() > deadline || tool_stop) {
            tool_error("flush failed");
            return 1;
        }
        if (r == DAN_ERR_BUSY) {
            tool_wait_fd(dan_canif_fd(c), POLLOUT, deadline, POLL_CAP_MS);
        }
    }
    return 0;
}

/* SLCAN: waits for the adapter's z/Z (or BEL) for every frame sent. */
static int wait_acks(dan_canif_t *c, int sent)
{
    const uint64_t deadline = dan_posix_now_us() + ACK_TIMEOUT_US;
    dan_can_frame_t rf;
    while (c->stats.tx_ack + c->stats.bel < (uint32_t)sent && !tool_stop) {
        int r = dan_canif_recv(c, &rf);
        if (r < 0) {
            tool_error("%s", dan_strerror(r));
            return 1;
        }
        if (r == 1) {
            continue; /* bus traffic: not ours to print */
        }
        if (c->stats.tx_ack + c->stats.bel >= (uint32_t)sent) {
            break;
        }
        if (dan_posix_now_us() > deadline) {
            tool_error("no transmit ACK from the adapter for %d of %d frames",
                       sent - (int)(c->stats.tx_ack + c->stats.bel), sent);
            return 1;
        }
        tool_wait_fd(dan_canif_fd(c), POLLIN, deadline, POLL_CAP_MS);
    }
    if (c->stats.bel) {
        tool_error("adapter refused %u frame(s) (BEL)", (unsigned)c->stats.bel);
        return 1;
    }
    return 0;
}

static int do_send(dan_canif_t *c, int argc, char **argv)
{
    const uint64_t deadline = dan_posix_now_us() + SEND_TIMEOUT_US;
    int sent = 0;
    int rc = send_frames(c, argc, argv, deadline, &sent);
    if (rc == 0) {
        rc = flush_all(c, deadline);
    }
    if (rc == 0 && c->kind == DAN_CANIF_SLCAN) {
        rc = wait_acks(c, sent);
    }
    return rc;
}

static int do_recv(dan_canif_t *c, const char *ifname, unsigned long count,
                   unsigned long timeout_ms)
{
    const uint64_t deadline = dan_posix_now_us() + (uint64_t)timeout_ms * 1000u;
    unsigned long got = 0;
    dan_can_frame_t f;

    while (!tool_stop && (count == 0 || got < count)) {
        int r = dan_canif_recv(c, &f);
        if (r < 0) {
            tool_error("receive failed: %s", dan_strerror(r));
            return 1;
        }
        if (r == 1) {
            print_frame(ifname, &f);
            got++;
            continue;
        }
        if (dan_posix_now_us() >= deadline) {
            break;
        }
        tool_wait_fd(dan_canif_fd(c), POLLIN, deadline, POLL_CAP_MS);
    }
    if (count > 0 && got < count) {
        tool_error("got %lu of %lu frames before the timeout", got, count);
        return 1;
    }
    return 0;
}

/* The command line. */
typedef struct {
    const char *spec, *ifname, *cmd;
    unsigned long count, timeout_ms;
} opts_t;

/* --can, --ifname, then the command; -1 to go on, else the exit code. */
static int parse_options(int argc, char **argv, opts_t *o, int *i)
{
    for (*i = 1; *i < argc; (*i)++) {
        const char *a = argv[*i];
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--can") && *i + 1 < argc) {
            o->spec = argv[++(*i)];
        } else if (!strcmp(a, "--ifname") && *i + 1 < argc) {
            o->ifname = argv[++(*i)];
        } else if (a[0] == '-') {
            tool_error("unknown option '%s'", a);
            usage(stderr);
            return 2;
        } else {
            o->cmd = argv[(*i)++];
            break;
        }
    }
    if (!o->spec || !o->cmd) {
        tool_error("need --can SPEC and a command");
        usage(stderr);
        return 2;
    }
    return -1;
}

/* send's frames are all checked before the device is opened. */
static int check_send_args(int argc, char **argv, int i)
{
    if (i >= argc) {
        tool_error("send needs at least one ID#DATA");
        return 2;
    }
    for (int k = i; k < argc; k++) {
        dan_can_frame_t f;
        if (dan_can_parse_cansend(argv[k], &f) < 0) {
            tool_error("bad frame '%s' (want ID#DATA, e.g. 123#0102 or 1401550A#01)", argv[k]);
            return 2;
        }
    }
    return -1;
}

static int parse_recv_args(int argc, char **argv, int i, opts_t *o)
{
    for (; i < argc; i++) {
        if (!strcmp(argv[i], "--count") && i + 1 < argc) {
            if (tool_parse_ulong(argv[++i], 10, 0, LONG_MAX, &o->count) < 0) {
                tool_error("bad --count");
                return 2;
            }
        } else if (!strcmp(argv[i], "--timeout-ms") && i + 1 < argc) {
            if (tool_parse_ulong(argv[++i], 10, 0, LONG_MAX, &o->timeout_ms) < 0) {
                tool_error("bad --timeout-ms");
                return 2;
            }
        } else {
            tool_error("unknown recv argument '%s'", argv[i]);
            return 2;
        }
    }
    return -1;
}

int main(int argc, char **argv)
{
    opts_t o = {NULL, "can0", NULL, 1, 5000};
    int i, rc;
    char err[256];
    dan_canif_t c;

    tool_prog = "dan-cantool";
    rc = parse_options(argc, argv, &o, &i);
    if (rc < 0) {
        if (!strcmp(o.cmd, "send")) {
            rc = check_send_args(argc, argv, i);
        } else if (!strcmp(o.cmd, "recv")) {
            rc = parse_recv_args(argc, argv, i, &o);
        } else {
            tool_error("unknown command '%s' (send|recv)", o.cmd);
            rc = 2;
        }
    }
    if (rc >= 0) {
        return rc;
    }
    tool_catch_signal(SIGINT);
    tool_catch_signal(SIGTERM);
    if (dan_canif_open(&c, o.spec, err, sizeof err) < 0) {
        tool_error("%s", err);
        return 2;
    }
    if (!strcmp(o.cmd, "send")) {
        rc = do_send(&c, argc - i, argv + i);
    } else {
        rc = do_recv(&c, o.ifname, o.count, o.timeout_ms);
    }
    dan_canif_close(&c);
    return rc;
}
