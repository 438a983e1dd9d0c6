/*
 * libdan POSIX port (Linux): a DAN UART on a tty, for daemons and tools.
 * Not part of the portable core; link build/libdan_posix.a.
 *
 * The tty is opened O_NOCTTY|O_NONBLOCK, made raw (cfmakeraw, 8N1, no flow
 * control) at any baud (termios2/BOTHER for non-standard rates and the fast
 * bauds up to 2 Mbit/s), its driver is asked for low latency where it has
 * one, and its original settings are restored on close.
 *
 * Half-duplex modes:
 *   DAN_POSIX_ECHO    single wire: we hear our own bytes; the engine checks them
 *   DAN_POSIX_NO_ECHO the adapter suppresses our echo (or a separate RX line)
 *   a direction pin   dan_posix_de_gpio(): a GPIO (libgpiod) asserted before the
 *                     first byte and released after the last has drained;
 *                     implies NO_ECHO unless echo is requested too
 */
#ifndef DAN_POSIX_H
#define DAN_POSIX_H

#include <termios.h>

#include "dan/link.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { DAN_POSIX_ECHO = 0, DAN_POSIX_NO_ECHO = 1 } dan_posix_mode_t;

typedef struct {
    int fd;
    struct termios orig;
    bool have_orig;
    uint32_t baud;    /* as the kernel reports it after setting (the driver may round) */
    bool low_latency; /* the driver took ASYNC_LOW_LATENCY (never on a pty) */
    dan_posix_mode_t mode;
    void *gpio_chip; /* struct gpiod_chip * (libgpiod v1) */
    void *gpio_line; /* struct gpiod_line * */
    bool gpio_active_low;
    uint32_t write_errors;
    dan_port_t port;
} dan_posix_port_t;

/* Opens path raw at baud, exclusively (flock, as pyserial's exclusive
 * open: another holder is DAN_ERR_BUSY). On failure returns a negative
 * DAN_ERR_* and a one-line reason in err (e.g. "/dev/ttyUSB0: No such file
 * or directory"). */
int dan_posix_open(dan_posix_port_t *p, const char *path, uint32_t baud, dan_posix_mode_t mode,
                   char *err, size_t errlen);

/* Drives a direction (DE) pin: spec is "CHIP:LINE" where CHIP is a gpiochip
 * name, path or number (libgpiod's lookup). DAN_ERR_UNSUPPORTED when built
 * without libgpiod. */
int dan_posix_de_gpio(dan_posix_port_t *p, const char *spec, bool active_low, char *err,
                      size_t errlen);

/* Drops bytes not sent yet, drives the direction pin inactive and releases
 * it, restores the tty's settings, closes. Safe to call twice. */
void dan_posix_close(dan_posix_port_t *p);

/* The port table for the engines (valid while p is). */
const dan_port_t *dan_posix_port(dan_posix_port_t *p);

/* Non-blocking read: bytes read, 0 if none, negative on error (the device
 * went away, a hang-up included: DAN_ERR_IO). */
int dan_posix_read(dan_posix_port_t *p, uint8_t *buf, size_t cap);

/* Sets any baud on an open fd (termios2 BOTHER on Linux). */
int dan_posix_set_speed(int fd, uint32_t baud);
/* Asks the serial driver for low latency (ASYNC_LOW_LATENCY through
 * TIOCGSERIAL/TIOCSSERIAL); -1 where there is none (a pty). Open does it. */
int dan_posix_low_latency(int fd);
/* The bauds of list[0..n) this port's driver takes (it reports back
 * within 2 % of each), into out (room for n); the current baud is kept.
 * Returns the count. For a peripheral's extra_bauds. */
size_t dan_posix_usable_bauds(dan_posix_port_t *p, const uint32_t *list, size_t n, uint32_t *out);
/* Reads the output baud of an fd (for a pty master: the slave's). 0 on error. */
uint32_t dan_posix_get_speed(int fd);
/* Reads both bauds as the kernel keeps them (termios2, so non-standard
 * rates too; for a pty master: the slave's). An input speed of 0 means
 * "the same as the output speed". 0, or -1 when fd is no tty. */
int dan_posix_get_speeds(int fd, uint32_t *ispeed, uint32_t *ospeed);

/* CLOCK_MONOTONIC in microseconds. */
uint64_t dan_posix_now_us(void);

#ifdef __cplusplus
}
#endif

#endif /* DAN_POSIX_H */
