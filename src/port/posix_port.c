/* libdan POSIX port: raw non-blocking tty, half-duplex by echo or a
 * libgpiod direction pin. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>
#ifdef DAN_HAVE_GPIOD
#include <gpiod.h>
#endif

#include "dan/posix.h"

/* A full tty buffer is waited out for at most WRITE_SPINS * WRITE_SPIN_US
 * (0.1 s) before a write counts as failed. */
#define WRITE_SPINS   1000
#define WRITE_SPIN_US 100u

uint64_t dan_posix_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static int port_write(void *ctx, const uint8_t *data, size_t len)
{
    dan_posix_port_t *p = (dan_posix_port_t *)ctx;
    size_t off = 0;
    int spins = 0;
    while (off < len) {
        ssize_t n = write(p->fd, data + off, len - off);
        if (n > 0) {
            off += (size_t)n;
            continue;
        }
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n < 0 && errno == EAGAIN && spins++ < WRITE_SPINS) {
            /* The kernel buffer (4 KiB) is far larger than a frame; it is
             * only full if the line is stuck. Wait for room, briefly. */
            usleep(WRITE_SPIN_US);
            continue;
        }
        p->write_errors++;
        return DAN_ERR_IO;
    }
    return (int)len;
}

/* Within 2 %: what a UART's divider gives is close, another baud is not
 * (a receiver tolerates about 3 % in all). */
static bool baud_close(uint32_t got, uint32_t want)
{
    uint32_t d = (got > want) ? got - want : want - got;
    return (uint64_t)d * 50u <= want;
}

/* Sets baud and reads back what the kernel keeps (the driver may round). */
static int set_and_check(dan_posix_port_t *p, uint32_t baud)
{
    uint32_t in = 0, out = 0;
    if (dan_posix_set_speed(p->fd, baud) != 0) {
        return DAN_ERR_IO;
    }
    if (dan_posix_get_speeds(p->fd, &in, &out) != 0) {
        out = baud;
    }
    p->baud = (out != 0u) ? out : baud;
    return baud_close(p->baud, baud) ? DAN_OK : DAN_ERR_UNSUPPORTED;
}

static int port_set_baud(void *ctx, uint32_t baud)
{
    dan_posix_port_t *p = (dan_posix_port_t *)ctx;
    /* Let our last bytes leave at the old baud first. */
    (void)tcdrain(p->fd);
    return set_and_check(p, baud);
}

size_t dan_posix_usable_bauds(dan_posix_port_t *p, const uint32_t *list, size_t n, uint32_t *out)
{
    uint32_t keep = p->baud;
    size_t i, k = 0;
    for (i = 0; i < n; i++) {
        if (set_and_check(p, list[i]) == DAN_OK) {
            out[k++] = list[i];
        }
    }
    (void)set_and_check(p, keep);
    return k;
}

static bool port_tx_busy(void *ctx)
{
    dan_posix_port_t *p = (dan_posix_port_t *)ctx;
    int queued = 0;
#ifdef TIOCSERGETLSR
    unsigned int lsr = 0;
    if (ioctl(p->fd, TIOCSERGETLSR, &lsr) == 0 && (lsr & TIOCSER_TEMT) == 0u) {
        return true; /* the shift register still holds a byte */
    }
#endif
    if (ioctl(p->fd, TIOCOUTQ, &queued) == 0 && queued > 0) {
        return true;
    }
    return false;
}

static void port_flush_tx(void *ctx)
{
    dan_posix_port_t *p = (dan_posix_port_t *)ctx;
    (void)tcflush(p->fd, TCOFLUSH);
}

#ifdef DAN_HAVE_GPIOD
static void port_set_tx(void *ctx, bool on)
{
    dan_posix_port_t *p = (dan_posix_port_t *)ctx;
    int v = on ? 1 : 0;
    if (p->gpio_active_low) {
        v = !v;
    }
    if (!on) {
        (void)tcdrain(p->fd); /* never cut the last byte short */
    }
    (void)gpiod_line_set_value((struct gpiod_line *)p->gpio_line, v);
}
#endif

int dan_posix_open(dan_posix_port_t *p, const char *path, uint32_t baud, dan_posix_mode_t mode,
                   char *err, size_t errlen)
{
    struct termios t;
    memset(p, 0, sizeof *p);
    p->fd = -1;
    if (path == NULL || baud == 0u) {
        snprintf(err, errlen, "no port or baud given");
        return DAN_ERR_ARG;
    }
    p->fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (p->fd < 0) {
        int e = errno;
        snprintf(err, errlen, "%s: %s", path, strerror(e));
        return (e == ENOENT)                 ? DAN_ERR_NOTFOUND
               : (e == EBUSY || e == EACCES) ? DAN_ERR_BUSY
                                             : DAN_ERR_IO;
    }
    if (tcgetattr(p->fd, &t) != 0) {
        snprintf(err, errlen, "%s: not a serial port (%s)", path, strerror(errno));
        close(p->fd);
        p->fd = -1;
        return DAN_ERR_ARG;
    }
    /* One program a port, as pyserial's exclusive open (danprobe) takes
     * it: two masters on one wire collide (review finding). */
    if (flock(p->fd, LOCK_EX | LOCK_NB) != 0) {
        snprintf(err, errlen, "%s: port busy (another program holds it)", path);
        close(p->fd);
        p->fd = -1;
        return DAN_ERR_BUSY;
    }
    p->orig = t;
    p->have_orig = true;
    cfmakeraw(&t);
    t.c_cflag |= CLOCAL | CREAD;
    t.c_cflag &= ~(tcflag_t)(CSTOPB | PARENB | CRTSCTS);
    t.c_iflag &= ~(tcflag_t)(IXON | IXOFF | IXANY);
    /* VMIN 1 with O_NONBLOCK: no data is EAGAIN, and 0 only a hang-up (a
     * USB adapter unplugged, the pty's other side gone); with VMIN 0 both
     * read 0 and a vanished port went unnoticed, its poll loop spinning
     * (review finding) */
    t.c_cc[VMIN] = 1;
    t.c_cc[VTIME] = 0;
    if (tcsetattr(p->fd, TCSANOW, &t) != 0 || set_and_check(p, baud) == DAN_ERR_IO) {
        snprintf(err, errlen, "%s: cannot set %u baud 8N1 raw (%s)", path, baud, strerror(errno));
        dan_posix_close(p);
        return DAN_ERR_IO;
    }
    if (!baud_close(p->baud, baud)) {
        snprintf(err, errlen, "%s: asked for %u baud, the driver set %u", path, baud, p->baud);
        dan_posix_close(p);
        return DAN_ERR_UNSUPPORTED;
    }
    p->low_latency = (dan_posix_low_latency(p->fd) == 0);
    (void)tcflush(p->fd, TCIOFLUSH);
    p->mode = mode;
    p->port.write = port_write;
    p->port.set_baud = port_set_baud;
    p->port.tx_busy = port_tx_busy;
    p->port.flush_tx = port_flush_tx;
    p->port.ctx = p;
    p->port.echo = (mode == DAN_POSIX_ECHO);
    return DAN_OK;
}

int dan_posix_de_gpio(dan_posix_port_t *p, const char *spec, bool active_low, char *err,
                      size_t errlen)
{
#ifdef DAN_HAVE_GPIOD
    char chip[64];
    const char *colon = strrchr(spec, ':');
    unsigned long line;
    char *end;
    struct gpiod_chip *c;
    struct gpiod_line *l;
    if (colon == NULL || (size_t)(colon - spec) >= sizeof chip || colon == spec) {
        snprintf(err, errlen, "bad GPIO spec '%s' (want CHIP:LINE, e.g. gpiochip0:17)", spec);
        return DAN_ERR_ARG;
    }
    memcpy(chip, spec, (size_t)(colon - spec));
    chip[colon - spec] = '\0';
    line = strtoul(colon + 1, &end, 10);
    if (*end != '\0' || end == colon + 1) {
        snprintf(err, errlen, "bad GPIO line number in '%s'", spec);
        return DAN_ERR_ARG;
    }
    c = gpiod_chip_open_lookup(chip);
    if (c == NULL) {
        snprintf(err, errlen, "GPIO chip '%s': %s", chip, strerror(errno));
        return DAN_ERR_NOTFOUND;
    }
    l = gpiod_chip_get_line(c, (unsigned)line);
    if (l == NULL || gpiod_line_request_output(l, "dan-de", active_low ? 1 : 0) != 0) {
        snprintf(err, errlen, "GPIO %s line %lu: %s", chip, line, strerror(errno));
        gpiod_chip_close(c);
        return DAN_ERR_BUSY;
    }
    p->gpio_chip = c;
    p->gpio_line = l;
    p->gpio_active_low = active_low;
    p->port.set_tx = port_set_tx;
    return DAN_OK;
#else
    (void)p;
    (void)active_low;
    snprintf(err, errlen, "direction pin '%s': built without libgpiod", spec);
    return DAN_ERR_UNSUPPORTED;
#endif
}

void dan_posix_close(dan_posix_port_t *p)
{
    if (p->fd >= 0) {
        /* bytes not sent yet would go out at the restored baud: garbage */
        (void)tcflush(p->fd, TCOFLUSH);
    }
#ifdef DAN_HAVE_GPIOD
    if (p->gpio_line != NULL) {
        /* the transceiver off before the line is released: the kernel
         * keeps the last value, and a close in mid-frame (Ctrl-C) left it
         * driving the shared bus (review finding) */
        (void)gpiod_line_set_value((struct gpiod_line *)p->gpio_line, p->gpio_active_low ? 1 : 0);
        gpiod_line_release((struct gpiod_line *)p->gpio_line);
        p->gpio_line = NULL;
    }
    if (p->gpio_chip != NULL) {
        gpiod_chip_close((struct gpiod_chip *)p->gpio_chip);
        p->gpio_chip = NULL;
    }
#endif
    if (p->fd >= 0) {
        if (p->have_orig) {
            (void)tcsetattr(p->fd, TCSANOW, &p->orig);
        }
        close(p->fd);
        p->fd = -1;
    }
}

const dan_port_t *dan_posix_port(dan_posix_port_t *p)
{
    return &p->port;
}

int dan_posix_read(dan_posix_port_t *p, uint8_t *buf, size_t cap)
{
    ssize_t n = read(p->fd, buf, cap);
    if (n > 0) {
        return (int)n;
    }
    if (n == 0) {
        return cap > 0u ? DAN_ERR_IO : 0; /* end of file: the device went away */
    }
    if (errno == EAGAIN || errno == EINTR) {
        return 0;
    }
    return DAN_ERR_IO;
}
