/*
 * CAN backends of the gateway daemon (Linux): SocketCAN and SLCAN (Lawicel
 * ASCII protocol on a serial port / USB-CDC adapter).
 *
 * The caller owns the dan_canif_t storage (no malloc). All I/O after open is
 * non-blocking and meant for one poll() loop in the caller:
 *
 *     poll on dan_canif_fd(c) for POLLIN (and POLLOUT while
 *     dan_canif_tx_pending(c) is true, then call dan_canif_flush(c));
 *     on POLLIN call dan_canif_recv() until it returns 0 or < 0;
 *     DAN_ERR_IO from recv/send/flush means the device is gone: report,
 *     dan_canif_close(), and try dan_canif_open() again later.
 *
 * Errors are negative DAN_ERR_* codes (dan/common.h). Nothing is printed;
 * see the counters in dan_canif_stats_t.
 */
#ifndef DAN_CAN_BACKEND_H
#define DAN_CAN_BACKEND_H

#include <stddef.h>
#include <stdint.h>
#include <termios.h>

#include "dan/can_gw/can.h"
#include "dan/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Longest SLCAN line this code handles, without its terminator:
 * 'T' + 8 id + 1 dlc + 16 data + 4 timestamp = 30 characters. */
#define DAN_SLCAN_LINE_MAX        30
/* Buffer size that always fits a formatted frame: line, '\r' and a NUL. */
#define DAN_SLCAN_FORMAT_MAX      28
/* Default serial baud of an SLCAN adapter (the CAN bitrate is 1 Mbit/s). */
#define DAN_SLCAN_DEFAULT_BAUD    115200u
/* Total time dan_canif_open() may spend on the SLCAN handshake. */
#define DAN_SLCAN_OPEN_TIMEOUT_MS 1000

typedef enum { DAN_CANIF_NONE = 0, DAN_CANIF_SOCKETCAN, DAN_CANIF_SLCAN } dan_canif_kind_t;

typedef struct {
    uint32_t tx;         /* frames accepted for sending */
    uint32_t rx;         /* frames received and returned by recv */
    uint32_t tx_dropped; /* send() calls refused with DAN_ERR_BUSY */
    uint32_t errors;     /* malformed or overlong lines, bad frames,
                             error frames, BELs, I/O errors */
    uint32_t bel;        /* SLCAN: BEL (error) answers from the adapter */
    uint32_t tx_ack;     /* SLCAN: z / Z transmit acknowledgements */
    uint32_t overlong;   /* SLCAN: lines dropped for being too long */
} dan_canif_stats_t;

/* Opaque-ish: callers use the functions below, and may read .stats. */
typedef struct {
    dan_canif_kind_t kind;
    int fd;
    dan_canif_stats_t stats;
    /* SLCAN only */
    struct termios old_tio;
    int have_old_tio;
    char line[DAN_SLCAN_LINE_MAX + 1];
    size_t line_len;
    int line_overflow; /* dropping bytes until the next terminator */
    uint8_t rxbuf[256];
    size_t rx_pos, rx_len;    /* unparsed bytes: rxbuf[rx_pos..rx_len) */
    unsigned open_timeout_ms; /* SLCAN handshake bound (dan_canif_open_opts) */
    uint32_t bitrate;         /* SLCAN CAN bitrate, bit/s (0: 1 Mbit/s) */
    char txbuf[2 * DAN_SLCAN_FORMAT_MAX];
    size_t tx_len; /* bytes of a partly written line */
    char name[64]; /* device or interface, for messages */
} dan_canif_t;

/* Opens a CAN interface. spec is "socketcan:IFNAME" or
 * "slcan:/dev/PATH[@BAUD]" (BAUD: serial speed of the adapter, default
 * 115200; the CAN bitrate is set to 1 Mbit/s with S8). For SLCAN this
 * blocks for at most DAN_SLCAN_OPEN_TIMEOUT_MS while it sends C, S8, O and
 * waits for the adapter's answers. Returns 0, or a negative DAN_ERR_* with
 * a one-line message in err (errlen bytes, may be NULL/0):
 * DAN_ERR_ARG (bad spec), DAN_ERR_NOTFOUND (no such device),
 * DAN_ERR_UNSUPPORTED (AF_CAN missing, not a tty, unknown baud),
 * DAN_ERR_IO, DAN_ERR_TIMEOUT (no answer), DAN_ERR_REMOTE (BEL).
 * c is overwritten: it must not hold an open interface (close it first). */
int dan_canif_open(dan_canif_t *c, const char *spec, char *err, size_t errlen);

/* dan_canif_open() with options. */
typedef struct {
    /* The SLCAN handshake's bound instead of DAN_SLCAN_OPEN_TIMEOUT_MS (0:
     * that): a daemon retrying a silent adapter from its poll loop keeps
     * the loop responsive with a short one. */
    unsigned timeout_ms;
    /* SLCAN: the CAN bitrate in bit/s, one of the Lawicel S0..S8 rates
     * (dan_slcan_bitrate_code; 0: 1 Mbit/s). SocketCAN: must be 0 (the
     * interface's bitrate is set with `ip link`). */
    uint32_t bitrate;
} dan_canif_opts_t;
int dan_canif_open_opts(dan_canif_t *c, const char *spec, const dan_canif_opts_t *o, char *err,
                        size_t errlen);

/* The Lawicel code k of S<k> for a CAN bitrate in bit/s: 10000 -> 0, 20000,
 * 50000, 100000, 125000, 250000, 500000, 800000, 1000000 -> 8; DAN_ERR_ARG
 * for any other rate. */
int dan_slcan_bitrate_code(uint32_t bitrate);

/* File descriptor to poll, or -1 when closed. */
int dan_canif_fd(const dan_canif_t *c);

/* Queues one frame without blocking. Returns 0; DAN_ERR_BUSY when the
 * output would block (nothing was sent; retry after POLLOUT);
 * DAN_ERR_ARG for an invalid frame; DAN_ERR_IO when the device is gone. */
int dan_canif_send(dan_canif_t *c, const dan_can_frame_t *f);

/* Returns 1 with a frame in *f, 0 when none is ready, DAN_ERR_IO when the
 * device is gone. Error frames (SocketCAN) come with DAN_CAN_ERR set. */
int dan_canif_recv(dan_canif_t *c, dan_can_frame_t *f);

/* SLCAN: true while part of a line still waits to be written. */
int dan_canif_tx_pending(const dan_canif_t *c);
/* Writes what is pending. Returns 0 when all is written, DAN_ERR_BUSY
 * when some remains, DAN_ERR_IO on error. */
int dan_canif_flush(dan_canif_t *c);

/* Closes (SLCAN: sends C and restores the old termios). Safe to call
 * twice and on a never-opened, zeroed struct. */
/* True when received bytes wait in the backend's buffer (e.g. after the
 * open handshake): call dan_canif_recv() without waiting for POLLIN. */
int dan_canif_rx_pending(const dan_canif_t *c);

void dan_canif_close(dan_canif_t *c);

/* ---- SLCAN line codec: pure functions, no I/O ---- */

/* Parses one line received from an adapter, without its '\r'.
 * Returns 1 with a frame (t, T, r, R; an optional 4-hex-digit timestamp is
 * accepted and ignored), 0 for a line that carries no frame and is no error
 * (empty, or a z / Z transmit acknowledgement), DAN_ERR_MALFORMED for
 * anything else. Hex digits may be either case. */
int dan_slcan_parse_line(const char *line, size_t len, dan_can_frame_t *f);

/* Formats a frame as an SLCAN command line ending in '\r', NUL-terminated
 * (cap >= DAN_SLCAN_FORMAT_MAX always suffices). Returns the length without
 * the NUL, DAN_ERR_ARG for an invalid frame (id out of range, dlc > 8,
 * error frame), DAN_ERR_OVERFLOW if cap is too small. */
int dan_slcan_format(const dan_can_frame_t *f, char *out, size_t cap);

/* Parses can-utils' cansend syntax: ID#DATA with 3 hex digits for an 11-bit
 * id or 8 for a 29-bit one, DATA 0..8 bytes in hex with optional dots
 * between bytes; ID#R or ID#Rn is a remote frame (n = dlc). Returns 0, or
 * DAN_ERR_MALFORMED. */
int dan_can_parse_cansend(const char *s, dan_can_frame_t *f);

/* ---- backend entry points, used by the dispatcher ---- */

/* A backend's error message, "KIND:NAME: WHAT[: strerror(errnum)]" (none
 * when err is NULL or errlen 0); returns code. */
int dan_canif_errf(char *err, size_t errlen, int code, const char *kind, const char *name,
                   const char *what, int errnum);

int dan_canif_slcan_open(dan_canif_t *c, const char *path, unsigned baud, char *err, size_t errlen);
int dan_canif_slcan_send(dan_canif_t *c, const dan_can_frame_t *f);
int dan_canif_slcan_recv(dan_canif_t *c, dan_can_frame_t *f);
int dan_canif_slcan_flush(dan_canif_t *c);
void dan_canif_slcan_close(dan_canif_t *c);

int dan_canif_socketcan_open(dan_canif_t *c, const char *ifname, char *err, size_t errlen);
int dan_canif_socketcan_send(dan_canif_t *c, const dan_can_frame_t *f);
int dan_canif_socketcan_recv(dan_canif_t *c, dan_can_frame_t *f);
void dan_canif_socketcan_close(dan_canif_t *c);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_BACKEND_H */
