/*
 * The bare round trip of `make bench`: what dan-vbus and the host's ptys
 * allow without any DAN engine, so that the ESC loop through dan-gatewayd
 * can be compared with it in the same run.
 *
 *     bench_pty_rtt EP_A EP_B BAUD REQ_BYTES RSP_BYTES SECONDS
 *
 * Two processes, as in the real loop (an FC and a gateway): the parent
 * writes REQ_BYTES on EP_A and waits for its echo and RSP_BYTES more; the
 * child, on EP_B, waits for REQ_BYTES and answers RSP_BYTES at once. No
 * gaps are kept (the bound with the gaps is the engines' business). Prints
 * one JSON line: {"rate": exchanges/s, "exchanges": n, "seconds": s}.
 */
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "dan/posix.h"

#define MAX_BYTES 512u
#define WAIT_MS   2000 /* a byte that long overdue ends the run */

/* Reads until n bytes arrived (or WAIT_MS of silence): true if they did. */
static bool read_n(dan_posix_port_t *p, size_t n)
{
    uint8_t buf[MAX_BYTES];
    size_t got = 0;
    while (got < n) {
        struct pollfd pf = {p->fd, POLLIN, 0};
        int r;
        if (poll(&pf, 1, WAIT_MS) <= 0) {
            return false;
        }
        r = dan_posix_read(p, buf, n - got);
        if (r < 0) {
            return false;
        }
        got += (size_t)r;
    }
    return true;
}

static bool write_n(dan_posix_port_t *p, const uint8_t *b, size_t n)
{
    return write(p->fd, b, n) == (ssize_t)n;
}

static int responder(const char *ep, uint32_t baud, size_t req, size_t rsp)
{
    static const uint8_t ones[MAX_BYTES] = {0};
    dan_posix_port_t p;
    char err[200];
    if (dan_posix_open(&p, ep, baud, DAN_POSIX_ECHO, err, sizeof err) != DAN_OK) {
        fprintf(stderr, "bench_pty_rtt: %s\n", err);
        return 1;
    }
    /* the request, then our answer, then its echo */
    while (read_n(&p, req) && write_n(&p, ones, rsp) && read_n(&p, rsp)) {
    }
    dan_posix_close(&p);
    return 0;
}

int main(int argc, char **argv)
{
    static uint8_t req_bytes[MAX_BYTES];
    dan_posix_port_t p;
    char err[200];
    uint32_t baud;
    size_t req, rsp;
    double seconds;
    uint64_t t0, end, now;
    unsigned long n = 0;
    pid_t child;
    int status = 0;
    if (argc != 7) {
        fprintf(stderr, "usage: bench_pty_rtt EP_A EP_B BAUD REQ_BYTES RSP_BYTES SECONDS\n");
        return 2;
    }
    baud = (uint32_t)strtoul(argv[3], NULL, 10);
    req = (size_t)strtoul(argv[4], NULL, 10);
    rsp = (size_t)strtoul(argv[5], NULL, 10);
    seconds = strtod(argv[6], NULL);
    if (baud == 0u || req == 0u || rsp == 0u || req > MAX_BYTES || rsp > MAX_BYTES ||
        seconds <= 0.0) {
        fprintf(stderr, "bench_pty_rtt: bad arguments\n");
        return 2;
    }
    memset(req_bytes, 0x55, sizeof req_bytes);
    child = fork();
    if (child == 0) {
        return responder(argv[2], baud, req, rsp);
    }
    if (dan_posix_open(&p, argv[1], baud, DAN_POSIX_ECHO, err, sizeof err) != DAN_OK) {
        fprintf(stderr, "bench_pty_rtt: %s\n", err);
        kill(child, SIGTERM);
        return 1;
    }
    usleep(200000); /* the responder opens its end */
    t0 = dan_posix_now_us();
    end = t0 + (uint64_t)(seconds * 1e6);
    do {
        /* our request's echo, then the answer */
        if (!write_n(&p, req_bytes, req) || !read_n(&p, req + rsp)) {
            break;
        }
        n++;
        now = dan_posix_now_us();
    } while (now < end);
    now = dan_posix_now_us();
    dan_posix_close(&p);
    kill(child, SIGTERM);
    (void)waitpid(child, &status, 0);
    printf("{\"rate\": %.1f, \"exchanges\": %lu, \"seconds\": %.3f}\n",
           (double)n * 1e6 / (double)(now - t0), n, (double)(now - t0) / 1e6);
    return n > 0u ? 0 : 1;
}
