/* Dispatcher: parses the interface spec and forwards to the backend. */
#include "can_backend.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

#define SOCKETCAN_PREFIX  "socketcan:"
#define SLCAN_PREFIX      "slcan:"
/* A baud with more digits than this bound is nonsense; stopping here keeps
 * v * 10 from overflowing. */
#define BAUD_DIGITS_LIMIT 100000000ul

static int set_err(char *err, size_t errlen, int code, const char *msg, const char *spec)
{
    if (err && errlen) {
        snprintf(err, errlen, "%s: %s", spec, msg);
    }
    return code;
}

/* Parses "[@]digits" at s; returns the value, or 0 if not all digits. */
static unsigned long parse_baud(const char *s)
{
    unsigned long v = 0;
    if (*s == '\0') {
        return 0;
    }
    for (; *s; s++) {
        if (*s < '0' || *s > '9' || v > BAUD_DIGITS_LIMIT) {
            return 0;
        }
        v = v * 10u + (unsigned long)(*s - '0');
    }
    return v;
}

int dan_canif_errf(char *err, size_t errlen, int code, const char *kind, const char *name,
                   const char *what, int errnum)
{
    if (err && errlen) {
        if (errnum) {
            snprintf(err, errlen, "%s:%s: %s: %s", kind, name, what, strerror(errnum));
        } else {
            snprintf(err, errlen, "%s:%s: %s", kind, name, what);
        }
    }
    return code;
}

int dan_canif_open(dan_canif_t *c, const char *spec, char *err, size_t errlen)
{
    return dan_canif_open_opts(c, spec, NULL, err, errlen);
}

int dan_canif_open_opts(dan_canif_t *c, const char *spec, const dan_canif_opts_t *o, char *err,
                        size_t errlen)
{
    if (err && errlen) {
        err[0] = '\0';
    }
    if (!c || !spec) {
        return set_err(err, errlen, DAN_ERR_ARG, "no interface given", "can");
    }
    memset(c, 0, sizeof *c);
    c->fd = -1;
    c->open_timeout_ms = o && o->timeout_ms ? o->timeout_ms : DAN_SLCAN_OPEN_TIMEOUT_MS;
    c->bitrate = o ? o->bitrate : 0u;

    if (strncmp(spec, SOCKETCAN_PREFIX, sizeof SOCKETCAN_PREFIX - 1) == 0) {
        const char *ifname = spec + sizeof SOCKETCAN_PREFIX - 1;
        if (*ifname == '\0') {
            return set_err(err, errlen, DAN_ERR_ARG, "missing interface name (socketcan:can0)",
                           spec);
        }
        if (c->bitrate != 0u) {
            return set_err(err, errlen, DAN_ERR_ARG,
                           "a SocketCAN interface's bitrate is set with ip link "
                           "(ip link set IF type can bitrate N)",
                           spec);
        }
        return dan_canif_socketcan_open(c, ifname, err, errlen);
    }
    if (strncmp(spec, SLCAN_PREFIX, sizeof SLCAN_PREFIX - 1) == 0) {
        char path[256];
        unsigned long baud = DAN_SLCAN_DEFAULT_BAUD;
        const char *p = spec + sizeof SLCAN_PREFIX - 1;
        const char *at = strrchr(p, '@');
        size_t n = strlen(p);
        if (at && at[1] >= '0' && at[1] <= '9') {
            baud = parse_baud(at + 1);
            if (baud == 0) {
                return set_err(err, errlen, DAN_ERR_ARG, "bad serial baud after '@'", spec);
            }
            n = (size_t)(at - p);
        }
        if (n == 0) {
            return set_err(err, errlen, DAN_ERR_ARG, "missing device path (slcan:/dev/ttyACM0)",
                           spec);
        }
        if (n >= sizeof path) {
            return set_err(err, errlen, DAN_ERR_ARG, "device path too long", spec);
        }
        memcpy(path, p, n);
        path[n] = '\0';
        return dan_canif_slcan_open(c, path, (unsigned)baud, err, errlen);
    }
    return set_err(err, errlen, DAN_ERR_ARG,
                   "unknown CAN interface type (use socketcan:IF or "
                   "slcan:/dev/TTY[@BAUD])",
                   spec);
}

int dan_canif_fd(const dan_canif_t *c)
{
    return (c && c->kind != DAN_CANIF_NONE) ? c->fd : -1;
}

/* The backend of an open interface, NULL for a closed one. */
typedef struct {
    int (*send)(dan_canif_t *c, const dan_can_frame_t *f);
    int (*recv)(dan_canif_t *c, dan_can_frame_t *f);
    void (*close)(dan_canif_t *c);
} backend_t;

static const backend_t *backend_of(const dan_canif_t *c)
{
    static const backend_t slcan = {dan_canif_slcan_send, dan_canif_slcan_recv,
                                    dan_canif_slcan_close};
    static const backend_t socketcan = {dan_canif_socketcan_send, dan_canif_socketcan_recv,
                                        dan_canif_socketcan_close};
    switch (c->kind) {
    case DAN_CANIF_SLCAN: return &slcan;
    case DAN_CANIF_SOCKETCAN: return &socketcan;
    default: return NULL;
    }
}

int dan_canif_send(dan_canif_t *c, const dan_can_frame_t *f)
{
    const backend_t *b;
    if (!c || !f) {
        return DAN_ERR_ARG;
    }
    b = backend_of(c);
    return b ? b->send(c, f) : DAN_ERR_IO;
}

int dan_canif_recv(dan_canif_t *c, dan_can_frame_t *f)
{
    const backend_t *b;
    if (!c || !f) {
        return DAN_ERR_ARG;
    }
    b = backend_of(c);
    return b ? b->recv(c, f) : DAN_ERR_IO;
}

int dan_canif_tx_pending(const dan_canif_t *c)
{
    return c && c->kind == DAN_CANIF_SLCAN && c->tx_len > 0;
}

int dan_canif_flush(dan_canif_t *c)
{
    if (!c) {
        return DAN_ERR_ARG;
    }
    if (c->kind == DAN_CANIF_SLCAN) {
        return dan_canif_slcan_flush(c);
    }
    return c->kind == DAN_CANIF_NONE ? DAN_ERR_IO : 0;
}

void dan_canif_close(dan_canif_t *c)
{
    const backend_t *b;
    if (!c) {
        return;
    }
    b = backend_of(c);
    if (b) {
        b->close(c);
    }
    c->kind = DAN_CANIF_NONE;
    c->fd = -1;
}

int dan_canif_rx_pending(const dan_canif_t *c)
{
    return c->rx_pos < c->rx_len;
}
