/*
 * dan-gatewayd: the CAN-over-DAN gateway daemon (Linux).
 *
 *   dan-gatewayd --uart TTY --can BACKEND [options]
 *
 * A DAN peripheral (type 0x40) on a UART and a DroneCAN node on a CAN
 * interface (socketcan:IF or slcan:/dev/TTY[@BAUD]). One poll() loop over
 * the UART, the CAN fd and the engines' timers; signal handlers only set a
 * flag. SIGTERM/SIGINT: failsafe (zero throttle + DISARMED, flushed to
 * CAN), then exit 0. A lost CAN adapter is reported and reopened every
 * second. Exit 2: bad arguments or a device that cannot be opened.
 *
 * The dynamic node ID allocation server runs unless --no-dna; --dna-db
 * keeps its table in a file (dna_file.h: written to PATH.tmp, synced,
 * renamed; a file that does not check is renamed to PATH.bad and the
 * table starts empty). The GetNodeInfo unique ID is --uid or derived from
 * /etc/machine-id (node_uid.h). --file-dir makes the gateway the bus's
 * file server and the FC's upload target (file_dir.h: DIR/name, partial
 * uploads DIR/~name, no symlink followed).
 */
#include <errno.h>
#include <getopt.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <syslog.h>
#include <time.h>
#include <unistd.h>

#include "dan/peripheral.h"
#include "dan/posix.h"
#include "dan/can_gw/node.h"
#include "can_backend.h"
#include "dan_tool.h"
#include "dna_file.h"
#include "file_dir.h"
#include "node_uid.h"
#include "sd_notify.h"

#define REOPEN_US           1000000u /* a lost CAN adapter is tried again once a second */
#define STATS_PATH_MAX      512u     /* --stats-file, with its ".tmp" */
#define CAN_STALL_US        500000u  /* an SLCAN adapter that took no byte this long is lost */
#define REOPEN_HANDSHAKE_MS 100u     /* a reopen's SLCAN handshake: DAN waits at most this */
#define SHUTDOWN_FLUSH_US   500000u  /* on exit, the failsafe frames get this long to leave */
#define SHUTDOWN_POLL_MS    10       /* meanwhile, how often the CAN output is retried */
#define STATS_PERIOD_US     1000000u /* --stats-file is rewritten once a second */
#define POLL_CAP_MS         100      /* longest poll(): a signal is seen this soon */
#define TX_RETRY_MS         2        /* queued CAN frames retry on this timer (no POLLOUT) */
#define CAN_RX_BURST        64       /* CAN frames read per wakeup, so DAN is never starved */
#define UART_READ_MAX       512u     /* bytes read from the UART at a time */
#define ANSWER_SPIN_US      250u     /* a reply due this soon is waited for in the same pass */

/* Command-line defaults and limits. */
#define DEFAULT_BAUD      9600u /* the DAN power-up baud */
#define DEFAULT_GAP_MS    20u   /* inter-byte gap: ptys and USB adapters add latency */
#define DEFAULT_WINDOW_MS 50u   /* reply window */
#define NODE_ID_MIN       1u    /* DroneCAN node ids: 0 is anonymous, 127 the highest */
#define NODE_ID_MAX       127u
#define UART_BAUD_MIN     1200u /* the range a UART adapter can do */
#define UART_BAUD_MAX     4000000u
#define GAP_MS_MAX        1000u /* beyond these the bus would be unusably slow */
#define WINDOW_MS_MAX     5000u

/* Knuth's multiplicative hash constant (2^32 / golden ratio): spreads the
 * boot time over the raw-frame sequence start. */
#define SEQ_HASH 2654435761u

static int g_syslog;
static int g_verbose;

static void logmsg(int prio, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void logmsg(int prio, const char *fmt, ...)
{
    va_list ap;
    if (prio == LOG_DEBUG && !g_verbose) {
        return;
    }
    va_start(ap, fmt);
    if (g_syslog) {
        vsyslog(prio, fmt, ap);
    } else {
        tool_verror(fmt, ap);
    }
    va_end(ap);
}

static void usage(FILE *o)
{
    fprintf(o, "usage: dan-gatewayd --uart TTY --can BACKEND [options]\n"
               "  --uart TTY            DAN UART (single-wire bus)\n"
               "  --can SPEC            socketcan:IFNAME | slcan:/dev/TTY[@BAUD]\n"
               "  --node-id N           DroneCAN node id, 1..127 (default 10)\n"
               "  --uart-baud B         start baud (default 9600, the DAN power-up baud)\n"
               "  --max-baud B          accept CONFIGURE to fast bauds (230400..2000000) up to B\n"
               "                        (default: every fast baud the UART's driver takes)\n"
               "  --no-fast-bauds       accept only 9600 and the mask bauds (DAN v1)\n"
               "  --can-bitrate N       SLCAN adapters: CAN bitrate in bit/s, one of 10000 20000\n"
               "                        50000 100000 125000 250000 500000 800000 1000000 (S0..S8;\n"
               "                        default 1000000); SocketCAN: set it with ip link\n"
               "                        (ip link set can0 type can bitrate 1000000)\n"
               "  --no-echo             the UART does not hear its own bytes\n"
               "  --de-gpio CHIP:LINE   RS-485 direction pin (libgpiod); implies --no-echo\n"
               "  --de-active-low       the pin is active low\n"
               "  --esc-timeout-ms N    failsafe after N ms without ESC commands (50..60000, "
               "default 500)\n"
               "  --arming-rate-hz N    ArmingStatus rate, 1..50 (default 2)\n"
               "  --gap-ms N            DAN inter-byte gap (default 20; ptys and USB add latency)\n"
               "  --reply-window-ms N   DAN reply window (default 50)\n"
               "  --dna-db PATH         keep the dynamic node ID allocation table in PATH\n"
               "                        (written to PATH.tmp, synced, renamed; a file that does\n"
               "                        not check is renamed to PATH.bad and the table starts\n"
               "                        empty; default: in memory only)\n"
               "  --no-dna              no allocation server (the bus has its own allocator)\n"
               "  --file-dir DIR        serve firmware files from DIR (file.GetInfo/Read) and\n"
               "                        take uploads there (FILE_OPEN..COMMIT); it must exist\n"
               "                        and be writable\n"
               "  --file-max BYTES      largest file uploaded, 1..2147483647 (default 4194304)\n"
               "  --file-total BYTES    all files together, 1..4294967295 (default 67108864)\n"
               "  --file-count N        files in the store, 1..254 (default 64); a commit past\n"
               "                        either cap is refused (NO_SPACE)\n"
               "  --uid HEX32           GetNodeInfo unique ID, 32 hex digits, not all zeros\n"
               "                        (default: derived from /etc/machine-id, FNV-1a of\n"
               "                        \"dan-gatewayd:K:\" + the ID for K=0..3; without one,\n"
               "                        of \"host:\" + the host name)\n"
               "  --stats-file PATH     write counters as JSON every second\n"
               "  --syslog              log to syslog instead of stderr\n"
               "  --verbose             more log lines\n"
               "  --help\n"
               "exit: 0 after SIGTERM/SIGINT, 1 runtime failure, 2 bad arguments or device\n");
}

typedef struct {
    dan_posix_port_t uart;
    const char *uart_path;
    dan_periph_t periph;
    dan_gw_node_t node;
    dan_ptype_t ptype;
    dan_canif_t can;
    const char *can_spec;
    bool can_up;
    uint64_t reopen_us;
    uint64_t can_stuck_us; /* SLCAN: since when no byte could be written (0: none) */
    dan_canif_opts_t can_opts;
    const char *stats_file;
    uint64_t stats_due_us;
    uint32_t failsafes_logged;
    uint32_t baud_logged;        /* the DAN baud last logged */
    uint32_t port_errors_logged; /* the link's port errors last logged */
    const char *dna_db;          /* --dna-db, or NULL */
    dan_dna_file_t dna_file;
    uint32_t fast[DAN_NFAST_BAUDS]; /* the fast bauds CONFIGURE may ask for */
    size_t nfast;
    uint32_t dna_stores_logged, dna_errors_logged;
    dan_sd_t sd;          /* systemd notifications and watchdog (Type=notify) */
    const char *file_dir; /* --file-dir, or NULL: no file store */
    dan_file_dir_t files;
} gwd_t;

/* The UART side of the command line, and what is checked after it. */
typedef struct {
    const char *de_gpio;
    uint32_t baud, gap_ms, window_ms, node_id;
    bool no_echo, de_low;
    const char *uid;         /* --uid, or NULL: derived */
    const char *can_bitrate; /* --can-bitrate, or NULL: 1 Mbit/s */
    uint32_t max_baud;       /* --max-baud, or 0: what the UART takes */
    bool no_fast;            /* --no-fast-bauds */
    uint32_t file_max;       /* --file-max (0: not given) */
    uint32_t file_total;     /* --file-total (0: not given) */
    uint32_t file_count;     /* --file-count (0: not given) */
} opts_t;

static void can_down(gwd_t *d, const char *why, uint64_t now)
{
    logmsg(LOG_ERR, "CAN %s: %s; reopening every %u ms", d->can_spec, why, REOPEN_US / 1000u);
    dan_canif_close(&d->can);
    d->can_up = false;
    dan_gw_node_can_state(&d->node, false);
    dan_gw_node_can_error(&d->node);
    d->reopen_us = now + REOPEN_US;
}

/* After each write's result r: an SLCAN adapter that is there but takes
 * no bytes (wedged firmware) would be EAGAIN forever with CAN_OK still
 * reported; after CAN_STALL_US it counts as lost and is reopened. SocketCAN
 * is left out: a full queue there is a bus without ACKs, which the kernel
 * reports. */
static void watch_stall(gwd_t *d, int r, uint64_t now)
{
    if (r != DAN_ERR_BUSY || d->can.kind != DAN_CANIF_SLCAN) {
        d->can_stuck_us = 0;
    } else if (d->can_stuck_us == 0) {
        d->can_stuck_us = now;
    } else if (now - d->can_stuck_us >= CAN_STALL_US) {
        d->can_stuck_us = 0;
        can_down(d, "adapter takes no bytes (writes blocked 500 ms)", now);
    }
}

/* Sends queued frames (dan_gw_node_tx_sent: the raw capture may include
 * them); while the CAN side is down they are dropped (stale ESC commands
 * must not go out late). */
static void can_drain(gwd_t *d, uint64_t now)
{
    dan_can_frame_t f;
    if (!d->can_up) {
        while (dan_gw_node_tx_peek(&d->node, &f)) {
            dan_gw_node_tx_pop(&d->node);
            d->node.stats.can_tx_dropped++;
        }
        return;
    }
    if (dan_canif_tx_pending(&d->can)) {
        int r = dan_canif_flush(&d->can);
        if (r == DAN_ERR_IO) {
            can_down(d, "adapter lost (write failed)", now);
            return;
        }
        watch_stall(d, r, now);
        if (r == DAN_ERR_BUSY) {
            return;
        }
    }
    while (dan_gw_node_tx_peek(&d->node, &f)) {
        int r = dan_canif_send(&d->can, &f);
        watch_stall(d, r, now);
        if (r == DAN_ERR_BUSY) {
            break;
        }
        if (r == DAN_ERR_IO) {
            can_down(d, "adapter lost (write failed)", now);
            return;
        }
        if (r == DAN_OK) {
            dan_gw_node_tx_sent(&d->node, now); /* on its way: the capture may see it */
        } else {
            dan_gw_node_tx_pop(&d->node); /* a frame the backend refused */
            dan_gw_node_can_error(&d->node);
        }
        if (dan_canif_tx_pending(&d->can)) {
            break;
        }
    }
}

static void can_read(gwd_t *d, uint64_t now)
{
    dan_can_frame_t f;
    int i, r;
    for (i = 0; i < CAN_RX_BURST; i++) {
        r = dan_canif_recv(&d->can, &f);
        if (r == 0) {
            return;
        }
        if (r < 0) {
            can_down(d, "adapter lost (read failed)", now);
            return;
        }
        dan_gw_node_rx_can(&d->node, &f, now);
    }
}

static void write_stats(gwd_t *d)
{
    char tmp[STATS_PATH_MAX];
    FILE *f;
    uint32_t v[DAN_GW_STAT_COUNT];
    unsigned i;
    snprintf(tmp, sizeof tmp, "%s.tmp", d->stats_file);
    f = fopen(tmp, "w");
    if (f == NULL) {
        return;
    }
    dan_gw_node_counters(&d->node, v);
    fputc('{', f);
    for (i = 0; i < DAN_GW_STAT_COUNT; i++) {
        fprintf(f, "\"%s\": %u, ", dan_gw_stat_name(i), v[i]);
    }
    /* the DAN engine's own counters: a reply dropped as late or a request
     * that overran the last reply is what a stalled host looks like */
    fprintf(f,
            "\"periph_late\": %u, \"periph_overruns\": %u, \"periph_configures\": %u, "
            "\"periph_nacks\": %u, \"periph_baud_changes\": %u, ",
            d->periph.stats.late, d->periph.stats.overruns, d->periph.stats.configures,
            d->periph.stats.nacks, d->periph.stats.baud_changes);
    fprintf(f, "\"link_collisions\": %u, \"link_echo_timeouts\": %u, \"link_port_errors\": %u, ",
            d->periph.link.stats.collisions, d->periph.link.stats.echo_timeouts,
            d->periph.link.stats.port_errors);
    fprintf(f, "\"can_up\": %d, \"baud\": %u}\n", d->can_up ? 1 : 0, dan_periph_baud(&d->periph));
    /* readers never see a half-written file, nor one a full disk cut short */
    if (ferror(f) | fclose(f)) {
        (void)unlink(tmp);
        return;
    }
    (void)rename(tmp, d->stats_file);
}

/* A number option: its getopt letter, range, where it goes, and whether
 * the error names the range ("--node-id must be 1..127") or not ("bad
 * --gap-ms"). */
typedef struct {
    int letter;
    const char *name;
    uint32_t lo, hi;
    uint32_t *dst;
    bool say_range;
} num_opt_t;

/* Sets a number option; -1 if c is none, 0, or 2 after a message. */
static int number_option(int c, const char *arg, opts_t *o, dan_gw_node_config_t *nc)
{
    const num_opt_t nums[] = {
        {'n', "--node-id", NODE_ID_MIN, NODE_ID_MAX, &o->node_id, true},
        {'b', "--uart-baud", UART_BAUD_MIN, UART_BAUD_MAX, &o->baud, false},
        {'t', "--esc-timeout-ms", DAN_GW_ESC_TIMEOUT_MIN, DAN_GW_ESC_TIMEOUT_MAX,
         &nc->esc_timeout_ms, true},
        {'a', "--arming-rate-hz", DAN_GW_ARMING_RATE_MIN, DAN_GW_ARMING_RATE_MAX,
         &nc->arming_rate_hz, true},
        {'G', "--gap-ms", 1, GAP_MS_MAX, &o->gap_ms, false},
        {'W', "--reply-window-ms", 1, WINDOW_MS_MAX, &o->window_ms, false},
        {'M', "--max-baud", UART_BAUD_MIN, UART_BAUD_MAX, &o->max_baud, true},
        {'X', "--file-max", 1, DAN_FILE_DIR_MAX_MAX, &o->file_max, true},
        {'T', "--file-total", 1, UINT32_MAX, &o->file_total, true},
        {'C', "--file-count", 1, DAN_FILE_DIR_FILES_MAX, &o->file_count, true},
    };
    size_t i;
    for (i = 0; i < sizeof nums / sizeof nums[0]; i++) {
        const num_opt_t *n = &nums[i];
        if (n->letter != c) {
            continue;
        }
        if (tool_parse_u32(arg, n->lo, n->hi, n->dst) == 0) {
            return 0;
        }
        if (n->say_range) {
            tool_error("%s must be %u..%u", n->name, n->lo, n->hi);
        } else {
            tool_error("bad %s", n->name);
        }
        return 2;
    }
    return -1;
}

/* --file-dir opened (and --file-max checked against it): -1 to go on, else
 * 2 after a message. */
static int check_file_dir(gwd_t *d, const opts_t *o, dan_gw_node_config_t *nc)
{
    char err[DAN_FILE_DIR_ERR_MAX];
    uint32_t max = o->file_max != 0u ? o->file_max : DAN_FILE_DIR_DEFAULT_MAX;
    if (d->file_dir == NULL) {
        if (o->file_max != 0u || o->file_total != 0u || o->file_count != 0u) {
            tool_error("%s needs --file-dir", o->file_max != 0u     ? "--file-max"
                                              : o->file_total != 0u ? "--file-total"
                                                                    : "--file-count");
            return 2;
        }
        return -1;
    }
    if (dan_file_dir_open(&d->files, d->file_dir, max, err, sizeof err) != 0) {
        tool_error("--file-dir %s", err);
        return 2;
    }
    if (o->file_total != 0u) {
        d->files.max_total = o->file_total;
    }
    if (o->file_count != 0u) {
        d->files.max_files = o->file_count;
    }
    nc->files = &d->files.store;
    return -1;
}

/* The options checked against each other and the system once all are
 * read: the CAN bitrate, the unique ID, the DNA table's path. -1 to go on,
 * else 2 after a message. */
static int check_options(gwd_t *d, const opts_t *o, dan_gw_node_config_t *nc)
{
    char err[DAN_DNA_FILE_ERR_MAX];
    if (d->stats_file != NULL && strlen(d->stats_file) + sizeof ".tmp" > STATS_PATH_MAX) {
        tool_error("--stats-file path longer than %u bytes", STATS_PATH_MAX - 5u);
        return 2;
    }
    if (o->can_bitrate != NULL &&
        (tool_parse_u32(o->can_bitrate, 1, UINT32_MAX, &d->can_opts.bitrate) != 0 ||
         dan_slcan_bitrate_code(d->can_opts.bitrate) < 0)) {
        tool_error("--can-bitrate must be one of the SLCAN rates 10000 20000 50000 100000 "
                   "125000 250000 500000 800000 1000000 (bit/s: S0..S8)");
        return 2;
    }
    if (o->can_bitrate != NULL && strncmp(d->can_spec, "slcan:", 6) != 0) {
        tool_error("--can-bitrate is for slcan: adapters; set a SocketCAN interface's bitrate "
                   "with ip link (ip link set can0 type can bitrate N)");
        return 2;
    }
    if (o->uid != NULL && dan_uid_parse(o->uid, nc->unique_id) != 0) {
        tool_error("--uid must be 32 hex digits (16 bytes), not all zeros (DroneCAN: undefined)");
        return 2;
    }
    if (d->dna_db != NULL && dan_dna_file_check_path(d->dna_db, err, sizeof err) != 0) {
        tool_error("--dna-db %s", err);
        return 2;
    }
    return check_file_dir(d, o, nc);
}

/* Where the option c that takes a text (a path, a spec) keeps it; NULL
 * for the other options. */
static const char **text_option(int c, gwd_t *d, opts_t *o)
{
    switch (c) {
    case 'u': return &d->uart_path;
    case 'c': return &d->can_spec;
    case 'g': return &o->de_gpio;
    case 's': return &d->stats_file;
    case 'D': return &d->dna_db;
    case 'f': return &d->file_dir;
    case 'U': return &o->uid;
    case 'B': return &o->can_bitrate;
    default: return NULL;
    }
}

/* Returns -1 to go on, else the exit code. */
static int parse_options(int argc, char **argv, gwd_t *d, opts_t *o, dan_gw_node_config_t *nc)
{
    static const struct option opts[] = {{"uart", required_argument, NULL, 'u'},
                                         {"can", required_argument, NULL, 'c'},
                                         {"node-id", required_argument, NULL, 'n'},
                                         {"uart-baud", required_argument, NULL, 'b'},
                                         {"max-baud", required_argument, NULL, 'M'},
                                         {"no-fast-bauds", no_argument, NULL, 'F'},
                                         {"no-echo", no_argument, NULL, 'E'},
                                         {"de-gpio", required_argument, NULL, 'g'},
                                         {"de-active-low", no_argument, NULL, 'L'},
                                         {"esc-timeout-ms", required_argument, NULL, 't'},
                                         {"arming-rate-hz", required_argument, NULL, 'a'},
                                         {"gap-ms", required_argument, NULL, 'G'},
                                         {"reply-window-ms", required_argument, NULL, 'W'},
                                         {"stats-file", required_argument, NULL, 's'},
                                         {"can-bitrate", required_argument, NULL, 'B'},
                                         {"dna-db", required_argument, NULL, 'D'},
                                         {"no-dna", no_argument, NULL, 'N'},
                                         {"file-dir", required_argument, NULL, 'f'},
                                         {"file-max", required_argument, NULL, 'X'},
                                         {"file-total", required_argument, NULL, 'T'},
                                         {"file-count", required_argument, NULL, 'C'},
                                         {"uid", required_argument, NULL, 'U'},
                                         {"syslog", no_argument, NULL, 'S'},
                                         {"verbose", no_argument, NULL, 'v'},
                                         {"help", no_argument, NULL, 'h'},
                                         {NULL, 0, NULL, 0}};
    int c, r;
    const char **text;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        r = number_option(c, optarg, o, nc);
        if (r >= 0) {
            if (r != 0) {
                return r;
            }
            continue;
        }
        text = text_option(c, d, o);
        if (text != NULL) {
            *text = optarg; /* checked by check_options() */
            continue;
        }
        switch (c) {
        case 'E': o->no_echo = true; break;
        case 'F': o->no_fast = true; break;
        case 'L': o->de_low = true; break;
        case 'N': nc->dna = false; break;
        case 'S': g_syslog = 1; break;
        case 'v': g_verbose = 1; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind < argc) {
        tool_error("unexpected argument '%s'", argv[optind]);
        return 2;
    }
    if (d->uart_path == NULL || d->can_spec == NULL) {
        tool_error("--uart and --can are required (--help)");
        return 2;
    }
    nc->node_id = (uint8_t)o->node_id;
    return check_options(d, o, nc);
}

/* Opens the UART (and its direction pin) and the CAN interface; 0 or 2. */
static int open_devices(gwd_t *d, const opts_t *o)
{
    char err[256];
    /* a direction pin hides our echo (dan/posix.h; dan-master does the same) */
    bool no_echo = o->no_echo || o->de_gpio != NULL;
    if (dan_posix_open(&d->uart, d->uart_path, o->baud,
                       no_echo ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO, err, sizeof err) != DAN_OK) {
        logmsg(LOG_ERR, "%s", err);
        return 2;
    }
    if (o->de_gpio != NULL &&
        dan_posix_de_gpio(&d->uart, o->de_gpio, o->de_low, err, sizeof err) != DAN_OK) {
        logmsg(LOG_ERR, "%s", err);
        dan_posix_close(&d->uart);
        return 2;
    }
    if (dan_canif_open_opts(&d->can, d->can_spec, &d->can_opts, err, sizeof err) != DAN_OK) {
        logmsg(LOG_ERR, "%s", err);
        dan_posix_close(&d->uart);
        return 2;
    }
    d->can_up = true;
    return 0;
}

/* The unique ID: --uid (parsed into nc already), else derived from the
 * machine ID, or from the host name with a warning. */
static void set_unique_id(const opts_t *o, dan_gw_node_config_t *nc)
{
    char hex[2u * DAN_UID_SIZE + 1u];
    int derived = o->uid == NULL ? dan_uid_derive(DAN_MACHINE_ID, nc->unique_id) : 0;
    size_t i;
    for (i = 0; i < DAN_UID_SIZE; i++) {
        snprintf(hex + 2u * i, 3, "%02x", nc->unique_id[i]);
    }
    if (derived == 1) {
        logmsg(LOG_WARNING,
               "no usable %s: DroneCAN unique ID %s derived from the host name (a gateway "
               "with the same host name would share it; give --uid)",
               DAN_MACHINE_ID, hex);
    } else {
        logmsg(LOG_INFO, "DroneCAN unique ID %s (%s)", hex,
               o->uid != NULL ? "--uid" : "derived from " DAN_MACHINE_ID);
    }
}

/* --dna-db: the file is read before the node starts, which loads it; 0,
 * or 2 when it exists but cannot be read (it must not be overwritten). */
static int open_dna_db(gwd_t *d, dan_gw_node_config_t *nc)
{
    char err[DAN_DNA_FILE_ERR_MAX];
    if (d->dna_db == NULL) {
        return 0;
    }
    dan_dna_file_init(&d->dna_file, d->dna_db);
    if (dan_dna_file_read(&d->dna_file, err, sizeof err) != 0) {
        logmsg(LOG_ERR, "%s (not overwritten: fix its permissions or move it away)", err);
        return 2;
    }
    nc->dna_storage = &d->dna_file.storage;
    return 0;
}

/* After the node loaded the table: a file that did not check is never
 * used silently: renamed to PATH.bad and reported; 0, or 2 when it cannot
 * be moved away (the next store would overwrite it). */
static int check_dna_db(gwd_t *d)
{
    char msg[2 * DAN_DNA_FILE_ERR_MAX];
    int r;
    if (!d->node.cfg.dna) {
        logmsg(LOG_INFO, "dynamic node ID allocation off (--no-dna)");
    }
    if (d->dna_db == NULL) {
        return 0;
    }
    if ((d->node.dna.flags & DAN_GW_DNA_STORE_ERROR) == 0u) {
        logmsg(LOG_INFO, "DNA table %s: %u entries%s", d->dna_db, d->node.dna.n,
               d->dna_file.exists ? "" : " (no file yet)");
        return 0;
    }
    r = dan_dna_file_quarantine(&d->dna_file, msg, sizeof msg);
    logmsg(LOG_ERR, "DNA table %s; %s", msg,
           r == 0 ? "starting with an empty table" : "not starting");
    return r == 0 ? 0 : 2;
}

/* The fast bauds to accept: those up to --max-baud that the UART's driver
 * sets (a pty takes them all; a real UART's divider may not reach some). */
static void find_fast_bauds(gwd_t *d, const opts_t *o)
{
    uint32_t want[DAN_NFAST_BAUDS];
    size_t i, n = 0;
    char list[128];
    int len = 0;
    for (i = 0; i < DAN_NFAST_BAUDS && !o->no_fast; i++) {
        if (o->max_baud == 0u || dan_fast_bauds[i] <= o->max_baud) {
            want[n++] = dan_fast_bauds[i];
        }
    }
    d->nfast = dan_posix_usable_bauds(&d->uart, want, n, d->fast);
    list[0] = '\0';
    for (i = 0; i < d->nfast && len >= 0 && (size_t)len < sizeof list; i++) {
        len += snprintf(list + len, sizeof list - (size_t)len, " %u", d->fast[i]);
    }
    logmsg(LOG_INFO, "fast bauds accepted:%s%s (ASYNC_LOW_LATENCY %s)", list,
           d->nfast == 0u ? " none (DAN v1 bauds only)" : "",
           d->uart.low_latency ? "on" : "not offered by the driver");
}

/* The DroneCAN node and the DAN peripheral engine on the UART; 0 or 2. */
static int start_engines(gwd_t *d, const opts_t *o, dan_gw_node_config_t *nc)
{
    dan_periph_config_t pc;
    uint64_t now = dan_posix_now_us();
    struct timespec ts;
    /* a different raw-frame sequence each boot (see raw_seq_start) */
    clock_gettime(CLOCK_REALTIME, &ts);
    nc->raw_seq_start = (uint32_t)ts.tv_sec * SEQ_HASH ^ (uint32_t)ts.tv_nsec ^ (uint32_t)getpid();
    set_unique_id(o, nc);
    if (open_dna_db(d, nc) != 0) {
        return 2;
    }
    if (dan_gw_node_init(&d->node, nc, now) != DAN_OK) {
        logmsg(LOG_ERR, "bad node configuration");
        return 2;
    }
    if (check_dna_db(d) != 0) {
        return 2;
    }
    dan_gw_node_ptype(&d->node, &d->ptype);
    dan_periph_config_default(&pc);
    pc.gap_us = o->gap_ms * 1000u;
    pc.reply_window_us = o->window_ms * 1000u;
    find_fast_bauds(d, o);
    pc.extra_bauds = d->fast;
    pc.nextra_bauds = d->nfast;
    if (dan_periph_init(&d->periph, dan_posix_port(&d->uart), &d->ptype, 1, &pc, o->baud, now) !=
        DAN_OK) {
        logmsg(LOG_ERR, "peripheral engine init failed");
        return 2;
    }
    dan_gw_node_attach(&d->node, &d->periph);
    logmsg(LOG_INFO, "DAN on %s at %u baud, DroneCAN node %u on %s", d->uart_path, o->baud,
           nc->node_id, d->can_spec);
    d->baud_logged = o->baud;
    if (d->file_dir != NULL) {
        logmsg(LOG_INFO, "file store %s (files up to %u bytes)", d->file_dir,
               d->files.store.max_size);
    }
    return 0;
}

/* When poll() must return: the engines', the reopen's or the stats' next
 * deadline, to the microsecond (a reply is due 2 characters after its
 * request: 10 us at 2 Mbit/s); now while received CAN bytes wait to be
 * parsed. */
static uint64_t poll_deadline_us(gwd_t *d, uint64_t now)
{
    uint64_t next = dan_periph_next_us(&d->periph);
    uint64_t t2 = dan_gw_node_next_us(&d->node, now);
    if (t2 < next) {
        next = t2;
    }
    if (!d->can_up && d->reopen_us < next) {
        next = d->reopen_us;
    }
    if (d->stats_file && d->stats_due_us < next) {
        next = d->stats_due_us;
    }
    if (dan_sd_next_us(&d->sd) < next) {
        next = dan_sd_next_us(&d->sd);
    }
    if (d->can_up && dan_canif_rx_pending(&d->can)) {
        return now;
    }
    if (dan_gw_node_tx_pending(&d->node) > 0u && d->can_up && next > now + TX_RETRY_MS * 1000u) {
        next = now + TX_RETRY_MS * 1000u;
    }
    return next;
}

/* pf[0] the UART, pf[1] the CAN interface while it is up; the count. */
static nfds_t fill_pollfds(gwd_t *d, struct pollfd pf[2])
{
    pf[0].fd = d->uart.fd;
    pf[0].events = POLLIN;
    pf[0].revents = 0;
    if (!d->can_up) {
        return 1;
    }
    pf[1].fd = dan_canif_fd(&d->can);
    pf[1].events = POLLIN;
    /* POLLOUT only for a line the backend has half written: a raw CAN
     * socket reports writable even with its queue full (ENOBUFS), which
     * would spin. Queued frames retry on a timer. */
    if (dan_canif_tx_pending(&d->can)) {
        pf[1].events |= POLLOUT;
    }
    pf[1].revents = 0;
    return 2;
}

/* Feeds the UART's bytes to the engine; -1 when the UART is lost (the
 * failsafe is then on its way to CAN). */
static int uart_rx(gwd_t *d, short revents, uint64_t now)
{
    uint8_t buf[UART_READ_MAX];
    int n;
    while ((n = dan_posix_read(&d->uart, buf, sizeof buf)) > 0) {
        dan_periph_rx(&d->periph, buf, (size_t)n, now);
    }
    /* A hung-up tty (USB unplug, pty closed) reads as DAN_ERR_IO; POLLERR
     * or POLLNVAL with nothing read is a loss too. */
    if (n == 0 && (revents & (POLLHUP | POLLERR | POLLNVAL)) != 0) {
        n = -1;
    }
    if (n < 0) {
        logmsg(LOG_ERR, "%s: UART lost", d->uart_path);
        dan_gw_node_failsafe(&d->node, now);
        can_drain(d, now);
        return -1;
    }
    return 0;
}

static void can_reopen(gwd_t *d, uint64_t now)
{
    char err[256];
    /* A short handshake: DAN requests wait meanwhile (at most
     * REOPEN_HANDSHAKE_MS a second while an adapter is present but silent). */
    dan_canif_opts_t co = d->can_opts;
    co.timeout_ms = REOPEN_HANDSHAKE_MS;
    if (dan_canif_open_opts(&d->can, d->can_spec, &co, err, sizeof err) == DAN_OK) {
        d->can_up = true;
        dan_gw_node_can_state(&d->node, true);
        logmsg(LOG_INFO, "CAN %s reopened", d->can_spec);
    } else {
        logmsg(LOG_DEBUG, "%s", err);
        d->reopen_us = now + REOPEN_US;
    }
}

/* The DNA table's saves since the last call, in the log. */
static void log_dna_saves(gwd_t *d)
{
    const dan_dna_file_t *f = &d->dna_file;
    if (f->store_errors != d->dna_errors_logged) {
        d->dna_errors_logged = f->store_errors;
        logmsg(LOG_ERR, "%s", f->err);
    }
    if (f->stores != d->dna_stores_logged) {
        d->dna_stores_logged = f->stores;
        logmsg(LOG_INFO, "DNA table saved to %s: %u entries", d->dna_db, d->node.dna.n);
    }
}

/* After the engines ran: log a new failsafe, reopen CAN, write stats. */
static void housekeeping(gwd_t *d, uint64_t now)
{
    if (dan_periph_baud(&d->periph) != d->baud_logged) {
        /* a CONFIGURE moved us (or a recovery asked at another baud) */
        d->baud_logged = dan_periph_baud(&d->periph);
        logmsg(LOG_INFO, "DAN at %u baud", d->baud_logged);
    }
    if (d->periph.link.stats.port_errors != d->port_errors_logged) {
        /* a reply not written or a CONFIGURE's baud not set: else silent */
        d->port_errors_logged = d->periph.link.stats.port_errors;
        logmsg(LOG_WARNING, "UART write or baud change failed (%u so far)", d->port_errors_logged);
    }
    if (d->node.stats.failsafes != d->failsafes_logged) {
        d->failsafes_logged = d->node.stats.failsafes;
        logmsg(LOG_WARNING, "failsafe: no ESC command for %u ms: zero throttle, disarmed",
               d->node.cfg.esc_timeout_ms);
    }
    if (!d->can_up && now >= d->reopen_us) {
        can_reopen(d, now);
    }
    if (d->dna_db != NULL) {
        log_dna_saves(d);
    }
    if (d->stats_file && now >= d->stats_due_us) {
        write_stats(d);
        d->stats_due_us = now + STATS_PERIOD_US;
    }
    /* Pinged from the loop: a hung loop stops the pings, and systemd
     * restarts the daemon (which starts DISARMED, safety on). */
    dan_sd_poll(&d->sd, now);
}

/* A reply due within ANSWER_SPIN_US (its turnaround: 2 characters, 10 us
 * at 2 Mbit/s, 174 us at 115200) goes out in this loop pass: a sleep until
 * then would cost a wakeup latency of tens of us or more on a busy host. */
static void answer_in_this_pass(gwd_t *d, uint64_t now)
{
    uint64_t end = now + ANSWER_SPIN_US;
    while (d->periph.pending && now < end && dan_periph_next_us(&d->periph) <= end) {
        now = dan_posix_now_us();
        dan_periph_poll(&d->periph, now);
    }
}

/* The poll loop, until a signal or a lost UART. */
static void run(gwd_t *d)
{
    while (!tool_stop) {
        struct pollfd pf[2];
        uint64_t now = dan_posix_now_us();
        uint64_t deadline = poll_deadline_us(d, now);
        nfds_t nfd = fill_pollfds(d, pf);
        int r = tool_poll_until(pf, nfd, deadline, POLL_CAP_MS);
        if (r < 0 && errno != EINTR) {
            logmsg(LOG_ERR, "poll: %s", strerror(errno));
            break;
        }
        now = dan_posix_now_us();
        if (r > 0 && (pf[0].revents & (POLLIN | POLLHUP | POLLERR)) &&
            uart_rx(d, pf[0].revents, now) < 0) {
            break;
        }
        if (d->can_up && ((r > 0 && nfd > 1 && (pf[1].revents & (POLLIN | POLLHUP | POLLERR))) ||
                          dan_canif_rx_pending(&d->can))) {
            can_read(d, now);
        }
        dan_periph_poll(&d->periph, now);
        answer_in_this_pass(d, now);
        dan_gw_node_poll(&d->node, now);
        can_drain(d, now);
        housekeeping(d, now);
    }
}

/* Zero throttle and DISARMED on the bus before leaving: what the log
 * says about it. */
static const char *shutdown_failsafe(gwd_t *d)
{
    uint64_t now = dan_posix_now_us();
    uint64_t end = now + SHUTDOWN_FLUSH_US;
    dan_gw_node_failsafe(&d->node, now);
    while (d->can_up && (dan_gw_node_tx_pending(&d->node) > 0u || dan_canif_tx_pending(&d->can)) &&
           dan_posix_now_us() < end) {
        struct timespec tick = {0, 1000000L};
        can_drain(d, dan_posix_now_us());
        if (!d->can_up) {
            break;
        }
        tool_wait_fd(dan_canif_fd(&d->can), POLLOUT, UINT64_MAX, SHUTDOWN_POLL_MS);
        /* a CAN_RAW socket is always writable, ENOBUFS or not: no spin */
        (void)nanosleep(&tick, NULL);
    }
    if (!d->can_up) {
        return "CAN down: failsafe not sent";
    }
    if (dan_gw_node_tx_pending(&d->node) > 0u || dan_canif_tx_pending(&d->can)) {
        return "failsafe queued, CAN did not take it all in time";
    }
    return "failsafe sent";
}

static gwd_t g_d; /* large (tunnel buffers): static storage, used only by main */

int main(int argc, char **argv)
{
    gwd_t *d = &g_d;
    dan_gw_node_config_t nc;
    const char *why;
    opts_t o = {NULL,
                DEFAULT_BAUD,
                DEFAULT_GAP_MS,
                DEFAULT_WINDOW_MS,
                0,
                false,
                false,
                NULL,
                NULL,
                0,
                false,
                0,
                0,
                0};
    int r;

    tool_prog = "dan-gatewayd";
    dan_gw_node_config_default(&nc);
    o.node_id = nc.node_id;
    r = parse_options(argc, argv, d, &o, &nc);
    if (r >= 0) {
        return r;
    }
    if (g_syslog) {
        openlog("dan-gatewayd", LOG_PID, LOG_DAEMON);
    }
    tool_catch_signal(SIGTERM);
    tool_catch_signal(SIGINT);
    tool_catch_signal(SIGHUP); /* a dropped SSH session: stop with the failsafe too */
    tool_catch_signal(SIGQUIT);
    signal(SIGPIPE, SIG_IGN);
    tool_fine_timers();
    if (open_devices(d, &o) != 0) {
        return 2;
    }
    if (start_engines(d, &o, &nc) != 0) {
        /* e.g. a --dna-db that cannot be read: the UART and the SLCAN
         * adapter get their termios (and the adapter its "C") back */
        dan_canif_close(&d->can);
        dan_posix_close(&d->uart);
        return 2;
    }
    if (dan_sd_open(&d->sd, dan_posix_now_us()) != 0) {
        logmsg(LOG_WARNING, "NOTIFY_SOCKET unusable (%s): no systemd notifications",
               strerror(errno));
    }
    (void)dan_sd_send(&d->sd, "READY=1");
    run(d);
    (void)dan_sd_send(&d->sd, "STOPPING=1");
    why = shutdown_failsafe(d);
    if (d->stats_file) {
        write_stats(d);
    }
    logmsg(LOG_INFO, "stopped (%s)", why);
    dan_sd_close(&d->sd);
    dan_canif_close(&d->can);
    dan_posix_close(&d->uart);
    if (d->file_dir != NULL) {
        dan_file_dir_close(&d->files);
    }
    return tool_stop ? 0 : 1;
}
