/*
 * SLCAN (Lawicel ASCII) backend: a USB-CAN adapter on a tty.
 *
 * Host -> adapter: "C\r" close, "S0\r".."S8\r" bitrate (10 kbit/s..1 Mbit/s,
 *   default S8), "O\r" open,
 *   "tIIILDD..\r" / "TIIIIIIIILDD..\r" data frames, "rIIIL\r" / "RIIIIIIIIL\r"
 *   remote frames.
 * Adapter -> host: "\r" ACK, "\a" (BEL) error, "z\r" / "Z\r" transmit ACK,
 *   received frames in the same t/T/r/R syntax, optionally followed by a
 *   4-hex-digit millisecond timestamp (Z1 mode).
 */
#include "can_backend.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "dan/posix.h"
#include "dan_tool.h"

#define READS_PER_CALL 4 /* recv: reads at most, so garbage cannot hold the loop */
#define US_PER_MS      1000u
#define CLOSE_ACK_US   100000u   /* closing: how long the adapter gets to ACK "C" */
#define SETTLE_NS      20000000L /* closing: time for the last frames to reach CAN */

/* ---- pure line codec ---- */

static int hexval(char ch)
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

/* n hex digits at s into *v; 0 or DAN_ERR_MALFORMED. */
static int parse_hex(const char *s, size_t n, uint32_t *v)
{
    uint32_t x = 0;
    for (size_t i = 0; i < n; i++) {
        int h = hexval(s[i]);
        if (h < 0) {
            return DAN_ERR_MALFORMED;
        }
        x = (x << 4) | (uint32_t)h;
    }
    *v = x;
    return 0;
}

int dan_slcan_parse_line(const char *line, size_t len, dan_can_frame_t *f)
{
    size_t idlen, pos, need;
    uint32_t id, v;
    uint8_t flags = 0;
    int dlc;

    if (!line || !f) {
        return DAN_ERR_ARG;
    }
    if (len == 0) {
        return 0;
    }
    switch (line[0]) {
    case 'z':
    case 'Z': return len == 1 ? 0 : DAN_ERR_MALFORMED;
    case 't': idlen = 3; break;
    case 'r':
        idlen = 3;
        flags = DAN_CAN_RTR;
        break;
    case 'T':
        idlen = 8;
        flags = DAN_CAN_EXT;
        break;
    case 'R':
        idlen = 8;
        flags = DAN_CAN_EXT | DAN_CAN_RTR;
        break;
    default: return DAN_ERR_MALFORMED;
    }
    if (len < 1 + idlen + 1) {
        return DAN_ERR_MALFORMED;
    }
    if (parse_hex(line + 1, idlen, &id) < 0) {
        return DAN_ERR_MALFORMED;
    }
    if (id > ((flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK)) {
        return DAN_ERR_MALFORMED;
    }
    dlc = hexval(line[1 + idlen]);
    if (dlc < 0 || dlc > 8) {
        return DAN_ERR_MALFORMED;
    }
    pos = 2 + idlen;
    need = pos + ((flags & DAN_CAN_RTR) ? 0u : 2u * (size_t)dlc);
    /* Exactly the frame, or the frame and a 4-digit timestamp. */
    if (len != need && len != need + 4) {
        return DAN_ERR_MALFORMED;
    }
    if (len == need + 4 && parse_hex(line + need, 4, &v) < 0) {
        return DAN_ERR_MALFORMED;
    }

    memset(f, 0, sizeof *f);
    f->id = id;
    f->flags = flags;
    f->dlc = (uint8_t)dlc;
    if (!(flags & DAN_CAN_RTR)) {
        for (int i = 0; i < dlc; i++) {
            if (parse_hex(line + pos + 2 * (size_t)i, 2, &v) < 0) {
                return DAN_ERR_MALFORMED;
            }
            f->data[i] = (uint8_t)v;
        }
    }
    return 1;
}

int dan_slcan_format(const dan_can_frame_t *f, char *out, size_t cap)
{
    static const char hex[] = "0123456789ABCDEF";
    char buf[DAN_SLCAN_FORMAT_MAX];
    size_t n = 0, idlen;
    int ext, rtr;

    if (!f || !out) {
        return DAN_ERR_ARG;
    }
    ext = (f->flags & DAN_CAN_EXT) != 0;
    rtr = (f->flags & DAN_CAN_RTR) != 0;
    if ((f->flags & DAN_CAN_ERR) || f->dlc > 8 ||
        f->id > (ext ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK)) {
        return DAN_ERR_ARG;
    }
    idlen = ext ? 8u : 3u;
    buf[n++] = ext ? (rtr ? 'R' : 'T') : (rtr ? 'r' : 't');
    for (size_t i = 0; i < idlen; i++) {
        buf[n++] = hex[(f->id >> (4u * (idlen - 1u - i))) & 0xFu];
    }
    buf[n++] = hex[f->dlc];
    if (!rtr) {
        for (size_t i = 0; i < f->dlc; i++) {
            buf[n++] = hex[f->data[i] >> 4];
            buf[n++] = hex[f->data[i] & 0xFu];
        }
    }
    buf[n++] = '\r';
    if (cap < n + 1) {
        return DAN_ERR_OVERFLOW;
    }
    memcpy(out, buf, n);
    out[n] = '\0';
    return (int)n;
}

/* The part after "ID#R": nothing, or one dlc digit 0..8. */
static int parse_rtr_dlc(const char *s, dan_can_frame_t *f)
{
    f->flags |= DAN_CAN_RTR;
    if (s[0] == '\0') {
        return 0;
    }
    if (s[0] < '0' || s[0] > '8' || s[1] != '\0') {
        return DAN_ERR_MALFORMED;
    }
    f->dlc = (uint8_t)(s[0] - '0');
    return 0;
}

int dan_can_parse_cansend(const char *s, dan_can_frame_t *f)
{
    const char *hash = strchr(s, '#');
    size_t idlen;
    uint32_t id, v;

    memset(f, 0, sizeof *f);
    if (!hash) {
        return DAN_ERR_MALFORMED;
    }
    idlen = (size_t)(hash - s);
    if ((idlen != 3 && idlen != 8) || parse_hex(s, idlen, &id) < 0) {
        return DAN_ERR_MALFORMED;
    }
    if (idlen == 8) {
        f->flags |= DAN_CAN_EXT;
    }
    if (id > (idlen == 8 ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK)) {
        return DAN_ERR_MALFORMED;
    }
    f->id = id;
    s = hash + 1;
    if (*s == 'R' || *s == 'r') {
        return parse_rtr_dlc(s + 1, f);
    }
    while (*s) {
        if (*s == '.') {
            s++;
            continue;
        }
        if (f->dlc >= 8 || parse_hex(s, 2, &v) < 0) {
            return DAN_ERR_MALFORMED;
        }
        f->data[f->dlc++] = (uint8_t)v;
        s += 2;
    }
    return 0;
}

/* ---- tty helpers ---- */

static int fail(char *err, size_t errlen, int code, const char *path, const char *what, int errnum)
{
    return dan_canif_errf(err, errlen, code, "slcan", path, what, errnum);
}

static speed_t baud_to_speed(unsigned baud)
{
    switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 500000: return B500000;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 1500000: return B1500000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return B0;
    }
}

/* Waits for fd until deadline (dan_posix_now_us() time): 0 when it may be
 * ready, DAN_ERR_TIMEOUT with less than a millisecond left, DAN_ERR_IO. */
static int wait_ready(int fd, short events, uint64_t deadline)
{
    if (dan_posix_now_us() + US_PER_MS > deadline) {
        return DAN_ERR_TIMEOUT;
    }
    if (tool_wait_fd(fd, events, deadline, INT_MAX) < 0 && errno != EINTR) {
        return DAN_ERR_IO;
    }
    return 0;
}

/* Writes all of s (a short command) before the deadline. */
static int write_all(int fd, const char *s, size_t n, uint64_t deadline)
{
    while (n > 0) {
        ssize_t w = write(fd, s, n);
        int r;
        if (w > 0) {
            s += w;
            n -= (size_t)w;
            continue;
        }
        if (w < 0 && errno == EINTR) {
            continue;
        }
        if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            r = wait_ready(fd, POLLOUT, deadline);
            if (r < 0) {
                return r;
            }
            continue;
        }
        return DAN_ERR_IO;
    }
    return 0;
}

/* Waits for the adapter's answer to a command: an empty line ended by '\r'
 * (ACK) or a BEL. Non-empty lines (frames still in flight, version text)
 * are skipped. Bytes read after the answer are kept in c->rxbuf for
 * dan_canif_recv(), so frames that follow the ACK of O are not lost.
 * Returns 0 for ACK, DAN_ERR_REMOTE for BEL, DAN_ERR_TIMEOUT, DAN_ERR_IO. */
static int wait_ack(dan_canif_t *c, uint64_t deadline)
{
    size_t linelen = 0;
    c->rx_pos = c->rx_len = 0;
    for (;;) {
        ssize_t n = read(c->fd, c->rxbuf, sizeof c->rxbuf);
        if (n > 0) {
            for (size_t i = 0; i < (size_t)n; i++) {
                char b = (char)c->rxbuf[i];
                int r = 1;
                if (b == '\a') {
                    r = DAN_ERR_REMOTE;
                } else if (b == '\r' && linelen == 0) {
                    r = 0;
                } else if (b == '\r') {
                    linelen = 0;
                } else if (b != '\n') {
                    linelen++;
                }
                if (r <= 0) {
                    c->rx_pos = i + 1;
                    c->rx_len = (size_t)n;
                    return r;
                }
            }
            continue;
        }
        if (n == 0) {
            return DAN_ERR_IO;
        }
        if (errno == EINTR) {
            continue;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK) {
            return DAN_ERR_IO;
        }
        int r = wait_ready(c->fd, POLLIN, deadline);
        if (r < 0) {
            return r;
        }
    }
}

static void restore_and_close(dan_canif_t *c)
{
    if (c->fd >= 0) {
        if (c->have_old_tio) {
            tcsetattr(c->fd, TCSANOW, &c->old_tio); /* drained above, with a deadline */
        }
        close(c->fd);
    }
    c->fd = -1;
    c->have_old_tio = 0;
}

/* Closes what open got so far and reports why. */
static int close_fail(dan_canif_t *c, char *err, size_t errlen, int code, const char *path,
                      const char *what, int errnum)
{
    restore_and_close(c);
    c->kind = DAN_CANIF_NONE;
    return fail(err, errlen, code, path, what, errnum);
}

/* Opens path raw at speed, non-blocking, keeping the old settings. */
static int open_tty(dan_canif_t *c, const char *path, speed_t speed, char *err, size_t errlen)
{
    struct termios tio;
    int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        int e = errno;
        return fail(err, errlen,
                    e == ENOENT || e == ENODEV || e == ENXIO ? DAN_ERR_NOTFOUND : DAN_ERR_IO, path,
                    e == ENOENT ? "no such device" : "cannot open", e);
    }
    c->kind = DAN_CANIF_SLCAN;
    c->fd = fd;
    snprintf(c->name, sizeof c->name, "%s", path);
    if (tcgetattr(fd, &c->old_tio) < 0) {
        return close_fail(c, err, errlen, DAN_ERR_UNSUPPORTED, path,
                          "not a serial port (tcgetattr)", errno);
    }
    c->have_old_tio = 1;
    tio = c->old_tio;
    cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= (tcflag_t)~CRTSCTS;
    tio.c_cc[VMIN] = 1;
    tio.c_cc[VTIME] = 0;
    cfsetispeed(&tio, speed);
    cfsetospeed(&tio, speed);
    if (tcsetattr(fd, TCSANOW, &tio) < 0) {
        return close_fail(c, err, errlen, DAN_ERR_IO, path, "tcsetattr", errno);
    }
    tcflush(fd, TCIOFLUSH);
    return 0;
}

/* The Lawicel bitrate commands: S<k> sets slcan_bitrates[k] bit/s. */
static const uint32_t slcan_bitrates[] = {10000u,  20000u,  50000u,  100000u, 125000u,
                                          250000u, 500000u, 800000u, 1000000u};
#define SLCAN_DEFAULT_CODE 8 /* S8: 1 Mbit/s */

int dan_slcan_bitrate_code(uint32_t bitrate)
{
    size_t k;
    for (k = 0; k < sizeof slcan_bitrates / sizeof slcan_bitrates[0]; k++) {
        if (slcan_bitrates[k] == bitrate) {
            return (int)k;
        }
    }
    return DAN_ERR_ARG;
}

/* The handshake's commands, in order, and what to say when one fails
 * (NULL cmd: the bitrate command, "S<k>\r"; its messages get the command
 * and the rate appended). */
static const struct {
    const char *cmd;
    const char *refused;   /* answered with BEL; NULL: a BEL is fine too */
    const char *no_answer; /* DAN_ERR_TIMEOUT */
    const char *io;        /* any other error */
} handshake[] = {
    /* Close the channel in case it was left open: ACK or BEL are both fine
     * (some adapters refuse C when closed). */
    {"C\r", NULL, "no answer from adapter to C in time (not an SLCAN adapter, or wrong baud?)",
     "I/O error during C (close channel)"},
    {NULL, "adapter refused the bitrate with BEL",
     "no answer from adapter to the bitrate command in time (not an SLCAN adapter, or wrong "
     "baud?)",
     "I/O error while setting the bitrate"},
    {"O\r", "adapter refused O (open channel) with BEL", "no answer from adapter to O",
     "I/O error during O (open channel)"},
};

/* Sends handshake step i and waits for its answer; closes and reports on
 * a failure. */
static int handshake_step(dan_canif_t *c, size_t i, const char *path, uint64_t deadline, char *err,
                          size_t errlen)
{
    int code = c->bitrate ? dan_slcan_bitrate_code(c->bitrate) : SLCAN_DEFAULT_CODE;
    char cmd[8], what[192];
    const char *msg;
    int r;
    if (handshake[i].cmd != NULL) {
        snprintf(cmd, sizeof cmd, "%s", handshake[i].cmd);
    } else {
        snprintf(cmd, sizeof cmd, "S%d\r", code);
    }
    r = write_all(c->fd, cmd, strlen(cmd), deadline);
    if (r == 0) {
        r = wait_ack(c, deadline);
    }
    if (r == DAN_ERR_REMOTE && handshake[i].refused == NULL) {
        r = 0;
    }
    if (r >= 0) {
        return 0;
    }
    msg = r == DAN_ERR_REMOTE    ? handshake[i].refused
          : r == DAN_ERR_TIMEOUT ? handshake[i].no_answer
                                 : handshake[i].io;
    if (handshake[i].cmd != NULL) {
        snprintf(what, sizeof what, "%s", msg);
    } else {
        snprintf(what, sizeof what, "%s (S%d, %lu bit/s)", msg, code,
                 (unsigned long)slcan_bitrates[code]);
    }
    return close_fail(c, err, errlen, r, path, what, 0);
}

int dan_canif_slcan_open(dan_canif_t *c, const char *path, unsigned baud, char *err, size_t errlen)
{
    speed_t speed = baud_to_speed(baud);
    uint64_t deadline;
    size_t i;
    int r;

    if (speed == B0) {
        return fail(err, errlen, DAN_ERR_UNSUPPORTED, path,
                    "unsupported serial baud (use 9600..4000000, a standard rate)", 0);
    }
    if (c->bitrate != 0u && dan_slcan_bitrate_code(c->bitrate) < 0) {
        return fail(err, errlen, DAN_ERR_ARG, path,
                    "unsupported CAN bitrate (SLCAN: 10000, 20000, 50000, 100000, 125000, "
                    "250000, 500000, 800000 or 1000000)",
                    0);
    }
    r = open_tty(c, path, speed, err, errlen);
    if (r < 0) {
        return r;
    }
    deadline = dan_posix_now_us() + (uint64_t)c->open_timeout_ms * US_PER_MS;
    for (i = 0; i < sizeof handshake / sizeof handshake[0]; i++) {
        r = handshake_step(c, i, path, deadline, err, errlen);
        if (r < 0) {
            return r;
        }
        if (i == 0) {
            /* Drop whatever frames were still arriving on the old channel. */
            tcflush(c->fd, TCIFLUSH);
            c->rx_pos = c->rx_len = 0;
        }
    }
    return 0;
}

/* ---- sending ---- */

int dan_canif_slcan_flush(dan_canif_t *c)
{
    while (c->tx_len > 0) {
        ssize_t w = write(c->fd, c->txbuf, c->tx_len);
        if (w > 0) {
            memmove(c->txbuf, c->txbuf + w, c->tx_len - (size_t)w);
            c->tx_len -= (size_t)w;
            continue;
        }
        if (w < 0 && errno == EINTR) {
            continue;
        }
        if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            return DAN_ERR_BUSY;
        }
        c->stats.errors++;
        return DAN_ERR_IO;
    }
    return 0;
}

int dan_canif_slcan_send(dan_canif_t *c, const dan_can_frame_t *f)
{
    char line[DAN_SLCAN_FORMAT_MAX];
    int n = dan_slcan_format(f, line, sizeof line);
    ssize_t w;

    if (n < 0) {
        return DAN_ERR_ARG;
    }
    if (c->tx_len > 0) {
        int r = dan_canif_slcan_flush(c);
        if (r == DAN_ERR_BUSY) {
            c->stats.tx_dropped++;
            return DAN_ERR_BUSY;
        }
        if (r < 0) {
            return r;
        }
    }
    for (;;) {
        w = write(c->fd, line, (size_t)n);
        if (w < 0 && errno == EINTR) {
            continue;
        }
        break;
    }
    if (w < 0) {
        if (errno == EAGAIN || errno == EWOULDBLOCK) {
            c->stats.tx_dropped++;
            return DAN_ERR_BUSY;
        }
        c->stats.errors++;
        return DAN_ERR_IO;
    }
    if (w < n) {
        /* Keep the rest of the line: a frame is never half sent. */
        memcpy(c->txbuf, line + w, (size_t)(n - w));
        c->tx_len = (size_t)(n - w);
    }
    c->stats.tx++;
    return 0;
}

/* ---- receiving ---- */

/* Feeds one byte; returns 1 when a frame was completed into *f. */
static int feed(dan_canif_t *c, char b, dan_can_frame_t *f)
{
    int r;
    if (b == '\a') {
        c->stats.bel++;
        c->stats.errors++;
        c->line_len = 0;
        c->line_overflow = 0;
        return 0;
    }
    if (b != '\r' && b != '\n') {
        if (c->line_len < DAN_SLCAN_LINE_MAX) {
            c->line[c->line_len++] = b;
        } else {
            c->line_overflow = 1;
        }
        return 0;
    }
    /* End of a line. */
    if (c->line_overflow) {
        c->stats.overlong++;
        c->stats.errors++;
        c->line_len = 0;
        c->line_overflow = 0;
        return 0;
    }
    r = dan_slcan_parse_line(c->line, c->line_len, f);
    if (r == 0 && c->line_len == 1) {
        c->stats.tx_ack++;
    }
    c->line_len = 0;
    if (r == 1) {
        c->stats.rx++;
        return 1;
    }
    if (r < 0) {
        c->stats.errors++;
    }
    return 0;
}

int dan_canif_slcan_recv(dan_canif_t *c, dan_can_frame_t *f)
{
    /* A few reads at most per call, so a flood of garbage cannot keep the
     * caller's loop here; the fd stays readable and poll comes back. */
    for (int reads = 0; reads < READS_PER_CALL; reads++) {
        while (c->rx_pos < c->rx_len) {
            char b = (char)c->rxbuf[c->rx_pos++];
            if (feed(c, b, f) == 1) {
                return 1;
            }
        }
        c->rx_pos = c->rx_len = 0;
        ssize_t n = read(c->fd, c->rxbuf, sizeof c->rxbuf);
        if (n > 0) {
            c->rx_len = (size_t)n;
            continue;
        }
        if (n == 0) { /* hangup: the adapter went away */
            c->stats.errors++;
            return DAN_ERR_IO;
        }
        if (errno == EINTR) {
            reads--;
            continue;
        }
        if (errno == EAGAIN || errno == EWOULDBLOCK) {
            return 0;
        }
        c->stats.errors++;
        return DAN_ERR_IO;
    }
    /* The last read's bytes are parsed now: the fd may not become readable
     * again for a while, and complete frames must not wait for it. */
    while (c->rx_pos < c->rx_len) {
        char b = (char)c->rxbuf[c->rx_pos++];
        if (feed(c, b, f) == 1) {
            return 1;
        }
    }
    return 0;
}

/* tcdrain() with a deadline: an adapter that takes no more bytes must not
 * hold the daemon's stop (tcdrain ignores O_NONBLOCK). What is still
 * queued at the deadline is dropped. */
static void drain_until(dan_canif_t *c, uint64_t deadline)
{
    int queued = 0;
    while (ioctl(c->fd, TIOCOUTQ, &queued) == 0 && queued > 0 && dan_posix_now_us() < deadline) {
        struct timespec tick = {0, 1000000L};
        (void)nanosleep(&tick, NULL);
    }
    if (queued > 0) {
        (void)tcflush(c->fd, TCOFLUSH);
    }
}

void dan_canif_slcan_close(dan_canif_t *c)
{
    if (c->fd >= 0) {
        /* Best effort: close the CAN channel, give the adapter
         * CLOSE_ACK_US to take it, then restore the tty. */
        uint64_t deadline = dan_posix_now_us() + CLOSE_ACK_US;
        struct timespec settle = {0, SETTLE_NS};
        /* The last frames written are the failsafe's: let them leave the
         * tty and reach the bus before the channel closes (adapters may
         * drop frames still queued on C). A line cut short gets its end so
         * "C" is not glued to it. */
        if (c->tx_len > 0) {
            (void)write_all(c->fd, "\r", 1, deadline);
        }
        c->tx_len = 0;
        drain_until(c, deadline);
        (void)nanosleep(&settle, NULL); /* the adapter sends them on CAN */
        if (write_all(c->fd, "C\r", 2, deadline) == 0) {
            (void)wait_ack(c, deadline);
        }
        drain_until(c, deadline);
    }
    restore_and_close(c);
}
