/*
 * systemd's service notification protocol (sd_notify(3)), without
 * libsystemd: one datagram per message to the AF_UNIX socket named by
 * $NOTIFY_SOCKET (a path, or '@' for the abstract namespace).
 *
 *     dan_sd_open(&sd, now);          // reads NOTIFY_SOCKET, WATCHDOG_USEC
 *     dan_sd_send(&sd, "READY=1");    // once the daemon serves
 *     in the poll loop: dan_sd_poll(&sd, now); wake by dan_sd_next_us()
 *     dan_sd_send(&sd, "STOPPING=1"); dan_sd_close(&sd);
 *
 * With WatchdogSec= in the unit, systemd sets WATCHDOG_USEC (and
 * WATCHDOG_PID): dan_sd_poll() sends WATCHDOG=1 every half of it, so a
 * daemon whose loop hangs stops pinging and is killed and restarted. Not
 * started by systemd (no NOTIFY_SOCKET): every call does nothing.
 */
#ifndef DAN_GWD_SD_NOTIFY_H
#define DAN_GWD_SD_NOTIFY_H

#include <stdint.h>

typedef struct {
    int fd;             /* -1: no notify socket */
    uint64_t period_us; /* watchdog ping period (0: no watchdog) */
    uint64_t due_us;    /* next ping */
    uint32_t sent, send_errors;
} dan_sd_t;

/* 0 (also without a socket), or -1 with errno when NOTIFY_SOCKET is set
 * but unusable (the daemon logs it and runs on). */
int dan_sd_open(dan_sd_t *s, uint64_t now_us);
/* One message, e.g. "READY=1" or "STATUS=text"; 0, or -1 with errno. */
int dan_sd_send(dan_sd_t *s, const char *msg);
/* Sends WATCHDOG=1 when it is due. */
void dan_sd_poll(dan_sd_t *s, uint64_t now_us);
/* When dan_sd_poll() must run next (UINT64_MAX: never). */
uint64_t dan_sd_next_us(const dan_sd_t *s);
void dan_sd_close(dan_sd_t *s);

#endif /* DAN_GWD_SD_NOTIFY_H */
