/*
 * dan-fcsim: a test flight controller. libdan's master and the gateway
 * client (dan/gateway.h) over the POSIX port, driven by a script; every
 * step prints one JSON line on stdout. The steps are listed in HELP below
 * (dan-fcsim --help). Built with DAN_GW_MAX_ESC=20 (the Makefile): it keeps
 * the telemetry of as many ESCs as one ESC_CMD drives.
 * Exit: 0 all steps OK, 1 a step failed, 2 bad arguments or port.
 */
#include <errno.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/codes.h"
#include "dan/can_gw/client.h"
#include "dan/master.h"
#include "dan/posix.h"
#include "dan_tool.h"
#include "fcsim/fcsim.h"

#define POLL_CAP_MS            50  /* longest poll() while an operation runs */
#define RAMP_HZ                50u /* esc-ramp's command rate */
#define TELEM_MAX_PAGES        32 /* telemetry pages read at most (a page has >= 1 of 32 indexes) */
#define NODES_MAX              128u   /* DroneCAN node ids 0..127 */
#define TUN_PROTOCOL_UNDEFINED 255    /* tunnel protocol UNDEFINED, as ArduPilot sends */
#define TUN_OPTION_LOCK_PORT   1      /* tunnel option: lock the serial port */
#define CANDUMP_TIMEOUT_MS     10000u /* candump's default timeout */
#define CANDUMP_IDLE_US        10000u /* candump's pause when nothing was queued */

static const char HELP[] =
    "usage: dan-fcsim --port TTY [--latency-ms 50] [--gap-ms 20] [--no-echo] [--recover N]\n"
    "                 [--baud B] [--max-baud B] [--fast [--telem-every N]]\n"
    "                 [--mix-servo ID=V[:TYPE],...] [--mix-tunnel PORT:TAG:OUTFILE:RATE]\n"
    "                 [--restore] STEP...\n"
    "  --baud B       the port's starting baud (default 9600)\n"
    "  --max-baud B   configure offers the fast bauds up to B (230400..2000000)\n"
    "                 first, and discovery scans them (default 0: DAN v1 bauds)\n"
    "  --mix-servo S  the ESC loops send SERVO S after every 10th exchange\n"
    "  --mix-tunnel PORT:TAG:OUTFILE:RATE\n"
    "                 the ESC loops also write records TAG:SEQ:CK (newline-ended)\n"
    "                 at RATE B/s to tunnel PORT once a tunnel step opened it, and\n"
    "                 append what comes back to OUTFILE (counts in the esc line)\n"
    "  --restore      after a --recover: ARM, SAFETY, SERVO_FAILSAFE, the tunnel\n"
    "                 again as the steps had set them; in the ESC loops ARM and\n"
    "                 SAFETY again when the gateway's flags show them undone\n"
    "  --fast         esc and esc-ramp send ESC_FAST, and ESC_FAST_T (a telemetry\n"
    "                 record) every N-th exchange (--telem-every, default 1; 0: never)\n"
    "Steps (each prints one JSON line):\n"
    "  discover                      find the gateway (9600 first, then the others)\n"
    "  configure[:BAUD]              move the bus to BAUD (default: the fastest the\n"
    "                                gateway accepts, fast bauds first)\n"
    "  arm | disarm\n"
    "  config[:timeout=MS][:rate=HZ][:telem=MS][:dna=0|1]\n"
    "                                read / change gateway settings\n"
    "  config-dna:0|1                the allocation server off / on (CONFIG)\n"
    "  telem-timeout:MS              HEALTH's ESC telemetry timeout (0: off)\n"
    "  health                        the bus health verdict: verdict, reason\n"
    "                                (and its name), subject, detail, problems\n"
    "  dna                           the allocation table (every page): flags\n"
    "                                (and as server_on, loaded, storage_error),\n"
    "                                entries, capacity, table [{id, uid}]\n"
    "  esc:V1,V2,..[@MS[@HZ]]        1..20 ESC commands for MS ms (default one) at\n"
    "                                HZ (0: back to back); prints exchanges/s and\n"
    "                                the telemetry received\n"
    "  esc-ramp:N:FROM:TO:MS         N channels ramping FROM..TO over MS ms\n"
    "  telemetry                     every ESC's telemetry (paged); a record with\n"
    "                                device.Temperature adds dev_temp (K),\n"
    "                                dev_flags, dev_age_ms\n"
    "  nodes                         node table with GetNodeInfo data (paged)\n"
    "  stats                         gateway counters\n"
    "  safety:off|on                 SafetyState 255 (off) / 0 (on)\n"
    "  servo:ID=VALUE[:TYPE],...     actuator commands (TYPE 0 unitless (default),\n"
    "                                1 position, 2 force, 3 speed, 4 PWM)\n"
    "  servo-fs[:ID=hold|VALUE[:TYPE],...]\n"
    "                                replace the servo failsafe table (none: empty)\n"
    "  lights:ID=RGB565HEX,...       LightsCommand\n"
    "  beep:HZ:MS                    BeepCommand\n"
    "  raw:CODE[:HEX]                a hand-made gateway request (inner payload\n"
    "                                HEX, sealed here); prints the inner response\n"
    "  tunnel:PORT:targetted:NODE:SERIAL[:BAUD[:OPTIONS]]  (OPTIONS default 1: lock)\n"
    "  tunnel:PORT:broadcast:PROTO:CHANNEL[:OPTIONS]       (1: replies on any channel)\n"
    "  xfer:PORT:INFILE:OUTFILE:N[:TIMEOUT_MS]\n"
    "                                writes INFILE (\"-\": nothing) through the\n"
    "                                tunnel while reading until N bytes came back\n"
    "                                into OUTFILE; fails after 30 s in which\n"
    "                                no byte moved (\"stalled\")\n"
    "  filter:ID/MASK[,...]          replace the raw filter (ID hex; 8 digits = 29-bit)\n"
    "  filter-add:ID/MASK[,...] | filter-remove:ID/MASK[,...] | filter-read\n"
    "                                prints the result (1: table full) and the table\n"
    "  cansend:ID#DATA[,...]         raw frames (cansend syntax, no RTR)\n"
    "  candump:N[:TIMEOUT_MS]        receive N filtered frames\n"
    "  upload:NAME:PATH              PATH into the gateway's file store as NAME\n"
    "                                (resumes what it holds; CRC-checked commit)\n"
    "  files | rm:NAME               list / remove the committed files\n"
    "  fw-begin:NODE:NAME[:CALL_ID]  BeginFirmwareUpdate of NODE from file NAME;\n"
    "                                waits for its answer\n"
    "  node-info:NODE                GetNodeInfo data and the update progress\n"
    "  sleep:MS\n"
    "  stop                          exit at once, no disarm (to test the failsafe)\n";

static dan_posix_port_t g_port;
dan_master_t g_m;
static dan_identity_t g_id; /* the gateway's, reported by discovery */
dan_gw_t g_gw;
static uint32_t g_gw_stats[DAN_GW_STAT_COUNT]; /* g_gw.stats */

/* Pumps the port until the operation in flight completes; returns its result. */
static int run(void)
{
    uint8_t buf[512];
    for (;;) {
        uint64_t now = dan_posix_now_us();
        int n;
        if (dan_gw_poll(&g_gw, now)) {
            return g_gw.result;
        }
        if (tool_wait_fd(g_port.fd, POLLIN, dan_master_next_us(&g_m), POLL_CAP_MS) < 0 &&
            errno != EINTR) {
            return DAN_ERR_IO;
        }
        now = dan_posix_now_us();
        while ((n = dan_posix_read(&g_port, buf, sizeof buf)) > 0) {
            dan_master_rx(&g_m, buf, (size_t)n, now);
        }
        if (n < 0) {
            return DAN_ERR_IO;
        }
    }
}

/* Waits us, dropping whatever the port receives meanwhile. */
void fcsim_sleep_us(uint64_t us)
{
    uint64_t end = dan_posix_now_us() + us;
    uint8_t buf[256];
    while (dan_posix_now_us() < end) {
        (void)tool_wait_fd(g_port.fd, POLLIN, end, INT_MAX);
        while (dan_posix_read(&g_port, buf, sizeof buf) > 0) {
        }
    }
}

int fcsim_ok(const char *step, const char *name, int rc)
{
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    printf("{\"step\": \"%s\", \"ok\": true", name);
    return 0;
}

int fcsim_fail(const char *step, int rc)
{
    dan_error_msg_t e;
    printf("{\"step\": \"%s\", \"ok\": false, \"error\": \"%s\"", step, dan_strerror(rc));
    if (rc == DAN_ERR_REMOTE && dan_master_remote_error(&g_m, &e) == DAN_OK) {
        printf(", \"remote\": \"%s\"", e.text);
    }
    printf("}\n");
    fflush(stdout);
    return 1;
}

static void print_telem(const dan_gw_telem_t *t)
{
    printf("{\"index\": %u, \"node\": %u, \"flags\": %u", t->esc_index, t->node_id, t->flags);
    if (t->flags & DAN_GW_TELEM_STATUS) {
        printf(", \"age_ms\": %lu, \"voltage\": %.17g, \"current\": %.17g, \"temperature\": %.17g, "
               "\"rpm\": %ld, \"power_pct\": %u, \"error_count\": %lu",
               (unsigned long)t->age_ms, (double)dan_f16_to_f32(t->voltage_f16),
               (double)dan_f16_to_f32(t->current_f16), (double)dan_f16_to_f32(t->temperature_f16),
               (long)t->rpm, t->power_pct, (unsigned long)t->error_count);
    }
    if (t->flags & DAN_GW_TELEM_EXT) {
        printf(", \"ext_age_ms\": %lu, \"input_pct\": %u, \"output_pct\": %u, "
               "\"motor_temp_c\": %d, \"motor_angle\": %u, \"status_flags\": %lu",
               (unsigned long)t->ext_age_ms, t->input_pct, t->output_pct, t->motor_temp_c,
               t->motor_angle, (unsigned long)t->status_flags);
    }
    if (t->flags & DAN_GW_TELEM_DEVICE) {
        printf(", \"dev_age_ms\": %lu, \"dev_temp\": %.17g, \"dev_flags\": %u",
               (unsigned long)t->dev_age_ms, (double)dan_f16_to_f32(t->dev_temp_f16), t->dev_flags);
    }
    printf("}");
}

static void print_all_telem(void)
{
    size_t i;
    int first = 1;
    printf("\"esc\": [");
    for (i = 0; i < DAN_GW_MAX_ESC; i++) {
        if (g_gw.esc[i].flags) {
            printf(first ? "" : ", ");
            print_telem(&g_gw.esc[i]);
            first = 0;
        }
    }
    printf("]");
}

static int parse_values(char *s, int16_t *v, size_t *n)
{
    char *tok, *save = NULL;
    *n = 0;
    for (tok = strtok_r(s, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        long x = strtol(tok, NULL, 0);
        if (*n >= DAN_GW_ESC_MAX || x < -8192 || x > 8191) {
            return -1;
        }
        v[(*n)++] = (int16_t)x;
    }
    return *n > 0 ? 0 : -1;
}

/* --recover N: after N ESC exchanges failed in a row, discover and
 * configure again (the gateway was power-cycled: back at 9600), as an FC
 * should; 0 = never. */
static uint32_t g_recover;
/* --fast, --telem-every N: the compact exchanges (ESC_FAST / ESC_FAST_T). */
static bool g_fast;
static uint32_t g_telem_every = 1u;

/* One ESC exchange started: ESC_CMD, or with --fast ESC_FAST with a
 * record asked for on every g_telem_every-th attempt. */
static int esc_start(const int16_t *v, size_t n, uint32_t attempt)
{
    if (g_fast) {
        bool telem = g_telem_every > 0u && attempt % g_telem_every == 0u;
        return dan_gw_esc_fast(&g_gw, v, n, telem, dan_posix_now_us());
    }
    return dan_gw_esc_command(&g_gw, v, n, dan_posix_now_us());
}

static int recover_bus(void)
{
    int rc = dan_master_discover(&g_m, dan_posix_now_us());
    if (rc == DAN_OK) {
        rc = run();
    }
    if (rc == DAN_OK && dan_master_peer(&g_m, DAN_TYPE_CAN_GW_FIRST) == NULL) {
        rc = DAN_ERR_NOTFOUND;
    }
    if (rc == DAN_OK) {
        rc = dan_master_configure(&g_m, 0, dan_posix_now_us());
    }
    if (rc == DAN_OK) {
        rc = run();
    }
    return rc;
}

/* ESC commands for ms at hz; values may ramp (to != NULL). */
static int esc_run(const char *step, const int16_t *from, const int16_t *to, size_t n, uint32_t ms,
                   uint32_t hz)
{
    uint64_t start = dan_posix_now_us(), end = start + (uint64_t)ms * 1000u, next = start;
    uint32_t count = 0, errors = 0, telem = 0, fresh = 0, in_row = 0, recoveries = 0;
    int16_t v[DAN_GW_ESC_MAX];
    int rc;
    size_t i;
    do {
        uint64_t now = dan_posix_now_us();
        if (hz > 0u && now < next) {
            fcsim_sleep_us(next - now);
            now = dan_posix_now_us();
        }
        next += hz ? 1000000u / hz : 0u;
        for (i = 0; i < n; i++) {
            if (to != NULL && ms > 0u) {
                uint64_t el =
                    now - start > (uint64_t)ms * 1000u ? (uint64_t)ms * 1000u : now - start;
                v[i] = (int16_t)(from[i] +
                                 (int32_t)((to[i] - from[i]) * (int64_t)el / ((int64_t)ms * 1000)));
            } else {
                v[i] = from[i];
            }
        }
        rc = esc_start(v, n, count + errors);
        if (rc == DAN_OK) {
            rc = run();
        }
        if (rc != DAN_OK) {
            errors++;
            if (g_recover > 0u && ++in_row >= g_recover) {
                in_row = 0;
                if (recover_bus() == DAN_OK && fcsim_mix_restore() == DAN_OK) {
                    recoveries++;
                }
            }
        } else {
            count++;
            in_row = 0;
            telem += g_gw.last_telem != DAN_GW_NONE;
            fresh += g_fast && g_gw.telem_fresh;
            fcsim_mix_turn(count);
        }
    } while (dan_posix_now_us() < end);
    {
        double secs = (double)(dan_posix_now_us() - start) / 1e6;
        printf("{\"step\": \"%s\", \"ok\": %s, \"exchanges\": %u, \"errors\": %u, "
               "\"telemetry_records\": %u, \"seconds\": %.3f, \"rate\": %.1f, \"esc_seen\": %u, "
               "\"flags\": %u, \"baud\": %u, \"recoveries\": %u, \"fast\": %s, "
               "\"telem_every\": %u, \"fresh_records\": %u, ",
               step, errors == 0 ? "true" : "false", count, errors, telem, secs,
               secs > 0 ? count / secs : 0.0, g_gw.esc_seen, g_gw.gw_flags, dan_master_baud(&g_m),
               recoveries, g_fast ? "true" : "false", g_telem_every, fresh);
        fcsim_mix_print();
        print_all_telem();
        printf("}\n");
    }
    return errors == 0 ? 0 : 1;
}

static int parse_frame(const char *s, dan_can_frame_t *f)
{
    const char *hash = strchr(s, '#');
    size_t idlen, i;
    memset(f, 0, sizeof *f);
    if (hash == NULL) {
        return -1;
    }
    idlen = (size_t)(hash - s);
    f->id = (uint32_t)strtoul(s, NULL, 16);
    if (idlen == 8) {
        f->flags = DAN_CAN_EXT;
    }
    hash++;
    for (i = 0; hash[2 * i] && hash[2 * i + 1] && i < 8; i++) {
        char b[3] = {hash[2 * i], hash[2 * i + 1], 0};
        f->data[i] = (uint8_t)strtoul(b, NULL, 16);
    }
    f->dlc = (uint8_t)i;
    return 0;
}

/* An xfer in which nothing moved either way for this long has lost bytes
 * (a tunnel has no retransmission): it ends as failed, with "stalled". */
#define FCSIM_XFER_STALL_US 30000000u

static int step_xfer(const char *step, char *args)
{
    unsigned port;
    char infile[256], outfile[256];
    unsigned long want, timeout_ms = 120000;
    FILE *in = NULL, *out;
    static uint8_t wbuf[1u << 20];
    size_t wlen = 0, wpos = 0, got = 0;
    uint32_t xfers = 0;
    uint64_t start, deadline, moved;
    bool stalled = false;
    int rc;
    int fields =
        sscanf(args, "%u:%255[^:]:%255[^:]:%lu:%lu", &port, infile, outfile, &want, &timeout_ms);
    if (fields < 4) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    if (strcmp(infile, "-") != 0) {
        in = fopen(infile, "rb");
        if (in == NULL) {
            return fcsim_fail(step, DAN_ERR_NOTFOUND);
        }
        wlen = fread(wbuf, 1, sizeof wbuf, in);
        fclose(in);
    }
    out = fopen(outfile, "wb");
    if (out == NULL) {
        return fcsim_fail(step, DAN_ERR_IO);
    }
    start = dan_posix_now_us();
    deadline = start + timeout_ms * 1000u;
    moved = start;
    while ((wpos < wlen || got < want) && dan_posix_now_us() < deadline) {
        if (dan_posix_now_us() - moved > FCSIM_XFER_STALL_US) {
            stalled = true; /* bytes lost on the way: waiting longer finds nothing */
            break;
        }
        const uint8_t *d;
        size_t n = wlen - wpos;
        rc = dan_gw_tunnel_xfer(&g_gw, (uint8_t)port, wbuf + wpos, n, DAN_GW_TUN_CHUNK_MAX,
                                dan_posix_now_us());
        if (rc == DAN_OK) {
            rc = run();
        }
        xfers++;
        if (rc != DAN_OK) {
            continue; /* a timeout: the next call repeats the same offsets */
        }
        wpos += g_gw.tun[port].accepted;
        if (g_gw.tun[port].accepted > 0u) {
            moved = dan_posix_now_us();
        }
        if (dan_gw_tunnel_data(&g_gw, &d, &n) == DAN_OK && n > 0u) {
            fwrite(d, 1, n, out);
            got += n;
            moved = dan_posix_now_us();
        } else if (g_gw.tun[port].accepted == 0u) {
            fcsim_sleep_us(5000); /* nothing moved: do not spin */
        }
    }
    fclose(out);
    {
        double secs = (double)(dan_posix_now_us() - start) / 1e6;
        printf("{\"step\": \"%s\", \"ok\": %s, \"written\": %zu, \"read\": %zu, \"xfers\": %u, "
               "\"seconds\": %.3f, \"rd_dropped\": %u, \"rd_lost\": %u, \"stalled\": %s}\n",
               step, (wpos == wlen && got >= want) ? "true" : "false", wpos, got, xfers, secs,
               g_gw.tun[port].rd_dropped, g_gw.tun[port].rd_lost, stalled ? "true" : "false");
    }
    return (wpos == wlen && got >= want) ? 0 : 1;
}

/* Each step is a row in the table below: its name and a function that
 * gets the name, the whole step (for the JSON line) and the text after
 * the first ':' (NULL without one; the functions may cut it up). Returns
 * 0 ok, 1 failed, 2 bad step (the run stops). */
typedef int (*step_fn)(const char *name, const char *step, char *args);

/* The started operation's result once it ran (rc when it did not start). */
int fcsim_finish(int rc)
{
    return rc == DAN_OK ? run() : rc;
}

static int step_stop(const char *name, const char *step, char *args)
{
    (void)name;
    (void)step;
    (void)args;
    printf("{\"step\": \"stop\", \"ok\": true}\n");
    fflush(stdout);
    _exit(0);
}

static int step_sleep(const char *name, const char *step, char *args)
{
    (void)name;
    (void)step;
    fcsim_sleep_us(args ? strtoull(args, NULL, 0) * 1000u : 0u);
    printf("{\"step\": \"sleep\", \"ok\": true}\n");
    return 0;
}

static int step_discover(const char *name, const char *step, char *args)
{
    const dan_peer_t *p;
    int rc = fcsim_finish(dan_master_discover(&g_m, dan_posix_now_us()));
    (void)name;
    (void)args;
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    p = dan_master_peer(&g_m, DAN_TYPE_CAN_GW_FIRST);
    if (p == NULL) {
        return fcsim_fail(step, DAN_ERR_NOTFOUND);
    }
    printf("{\"step\": \"discover\", \"ok\": true, \"baud\": %u, \"manufacturer\": \"%s\", "
           "\"model\": \"%s\", \"baud_mask\": %u}\n",
           p->baud, g_id.manufacturer, g_id.model, g_id.baud_mask);
    return 0;
}

static int step_configure(const char *name, const char *step, char *args)
{
    uint32_t baud = args ? (uint32_t)strtoul(args, NULL, 0) : 0u;
    int rc = fcsim_finish(dan_master_configure(&g_m, baud, dan_posix_now_us()));
    (void)name;
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    printf("{\"step\": \"configure\", \"ok\": true, \"baud\": %u, \"fast_refusals\": %u, "
           "\"recoveries\": %u}\n",
           dan_master_baud(&g_m), g_m.stats.fast_refusals, g_m.stats.recoveries);
    return 0;
}

/* arm | disarm */
static int step_arm(const char *name, const char *step, char *args)
{
    int rc = fcsim_finish(dan_gw_arm(&g_gw, name[0] == 'a', dan_posix_now_us()));
    (void)args;
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    fcsim_mix_note_arm(name[0] == 'a');
    printf("{\"step\": \"%s\", \"ok\": true, \"flags\": %u}\n", name, g_gw.gw_flags);
    return 0;
}

/* Sends CONFIG (c: what to change; nothing set: a read) and prints the
 * settings it returns. */
static int config_run(const char *name, const char *step, const dan_gw_config_t *c)
{
    int rc = fcsim_finish(dan_gw_config(&g_gw, c, dan_posix_now_us()));
    if (fcsim_ok(step, name, rc) != 0) {
        return 1;
    }
    printf(", \"node_id\": %u, \"esc_timeout_ms\": %u, \"arming_rate_hz\": %u, \"flags\": %u, "
           "\"telem_timeout_ms\": %u, \"dna\": %u}\n",
           g_gw.config.node_id, g_gw.config.esc_timeout_ms, g_gw.config.arming_rate_hz,
           g_gw.config.gw_flags, g_gw.config.telem_timeout_ms, g_gw.config.dna);
    return 0;
}

static int step_config(const char *name, const char *step, char *args)
{
    dan_gw_config_t c;
    char *tok, *save = NULL;
    memset(&c, 0, sizeof c);
    for (tok = args ? strtok_r(args, ":", &save) : NULL; tok; tok = strtok_r(NULL, ":", &save)) {
        if (!strncmp(tok, "timeout=", 8)) {
            c.set_mask |= DAN_GW_CFG_ESC_TIMEOUT;
            c.esc_timeout_ms = (uint32_t)strtoul(tok + 8, NULL, 0);
        } else if (!strncmp(tok, "rate=", 5)) {
            c.set_mask |= DAN_GW_CFG_ARMING_RATE;
            c.arming_rate_hz = (uint32_t)strtoul(tok + 5, NULL, 0);
        } else if (!strncmp(tok, "telem=", 6)) {
            c.set_mask |= DAN_GW_CFG_TELEM_TIMEOUT;
            c.telem_timeout_ms = (uint32_t)strtoul(tok + 6, NULL, 0);
        } else if (!strncmp(tok, "dna=", 4)) {
            c.set_mask |= DAN_GW_CFG_DNA;
            c.dna = (uint8_t)strtoul(tok + 4, NULL, 0);
        }
    }
    return config_run(name, step, &c);
}

/* config-dna:0|1 and telem-timeout:MS: one CONFIG field each. */
static int step_config_field(const char *name, const char *step, char *args)
{
    dan_gw_config_t c;
    memset(&c, 0, sizeof c);
    if (args == NULL) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    if (!strcmp(name, "config-dna")) {
        c.set_mask = DAN_GW_CFG_DNA;
        c.dna = (uint8_t)strtoul(args, NULL, 0);
    } else {
        c.set_mask = DAN_GW_CFG_TELEM_TIMEOUT;
        c.telem_timeout_ms = (uint32_t)strtoul(args, NULL, 0);
    }
    return config_run(name, step, &c);
}

static int step_health(const char *name, const char *step, char *args)
{
    const dan_gw_health_t *h = &g_gw.health;
    const char *reason;
    int rc = fcsim_finish(dan_gw_health(&g_gw, dan_posix_now_us()));
    (void)args;
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    reason = dan_gw_reason_name(h->reason);
    printf("{\"step\": \"%s\", \"ok\": true, \"verdict\": %u, \"verdict_name\": \"%s\", "
           "\"reason\": %u, \"reason_name\": \"%s\", \"subject\": %u, \"detail\": %u, "
           "\"problems\": %u}\n",
           name, h->verdict, h->verdict == DAN_GW_HEALTH_OK ? "ok" : "fail", h->reason,
           reason ? reason : "unknown", h->subject, h->detail, h->problems);
    return 0;
}

/* One page of the allocation table from entry first, printed as JSON
 * objects after *printed others; the next entry to ask for (DAN_GW_NONE:
 * the end), or -1 after a failure (rc in *rc). */
static int dna_page(uint8_t first, dan_gw_dna_hdr_t *h, size_t *printed, int *rc)
{
    dan_reader_t r;
    dan_gw_dna_entry_t e;
    size_t i, k;
    *rc = fcsim_finish(dan_gw_dna(&g_gw, first, dan_posix_now_us()));
    if (*rc == DAN_OK) {
        *rc = dan_gw_dna_begin(&g_gw, &r, h);
    }
    if (*rc != DAN_OK) {
        return -1;
    }
    for (i = 0; i < h->count && dan_gw_dna_next(&r, &e) == DAN_OK; i++) {
        printf("%s{\"id\": %u, \"uid\": \"", (*printed)++ ? ", " : "", e.node_id);
        for (k = 0; k < sizeof e.unique_id; k++) {
            printf("%02x", e.unique_id[k]);
        }
        printf("\"}");
    }
    return h->next;
}

static int step_dna(const char *name, const char *step, char *args)
{
    dan_gw_dna_hdr_t h;
    size_t printed = 0;
    int next = 0, rc = DAN_OK;
    (void)step; /* a failure still ends the line as valid JSON */
    (void)args;
    printf("{\"step\": \"%s\", \"table\": [", name);
    while (next != DAN_GW_NONE && next >= 0) {
        next = dna_page((uint8_t)next, &h, &printed, &rc);
    }
    if (rc != DAN_OK) {
        printf("], \"ok\": false, \"error\": \"%s\"}\n", dan_strerror(rc));
        return 1;
    }
    printf("], \"ok\": true, \"flags\": %u, \"server_on\": %s, \"loaded\": %s, "
           "\"storage_error\": %s, \"entries\": %u, \"capacity\": %u}\n",
           h.flags, (h.flags & DAN_GW_DNA_ON) ? "true" : "false",
           (h.flags & DAN_GW_DNA_LOADED) ? "true" : "false",
           (h.flags & DAN_GW_DNA_STORE_ERROR) ? "true" : "false", h.entries, h.capacity);
    return 0;
}

/* esc-ramp:N:FROM:TO:MS */
static int step_esc_ramp(const char *name, const char *step, char *args)
{
    int16_t from[DAN_GW_ESC_MAX], to[DAN_GW_ESC_MAX];
    uint32_t ms = 0;
    unsigned nn, i;
    long a, b;
    (void)name;
    if (args == NULL || sscanf(args, "%u:%ld:%ld:%u", &nn, &a, &b, &ms) != 4 || nn < 1 ||
        nn > DAN_GW_ESC_MAX) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    for (i = 0; i < nn; i++) {
        from[i] = (int16_t)a;
        to[i] = (int16_t)b;
    }
    return esc_run("esc-ramp", from, to, nn, ms, RAMP_HZ);
}

/* esc:V1,V2,..[@MS[@HZ]] */
static int step_esc(const char *name, const char *step, char *args)
{
    int16_t from[DAN_GW_ESC_MAX];
    size_t n;
    uint32_t ms = 0, hz = 0;
    char *at;
    (void)name;
    if (args == NULL) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    at = strchr(args, '@');
    if (at) {
        *at++ = '\0';
        ms = (uint32_t)strtoul(at, &at, 0);
        if (*at == '@') {
            hz = (uint32_t)strtoul(at + 1, NULL, 0);
        }
    }
    if (parse_values(args, from, &n)) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    return esc_run("esc", from, NULL, n, ms, hz);
}

static int step_telemetry(const char *name, const char *step, char *args)
{
    uint8_t first = 0;
    int pages = 0;
    (void)name;
    (void)args;
    do {
        int rc = fcsim_finish(dan_gw_telemetry(&g_gw, first, dan_posix_now_us()));
        if (rc != DAN_OK) {
            return fcsim_fail(step, rc);
        }
        first = g_gw.telem_next;
    } while (first != DAN_GW_NONE && ++pages < TELEM_MAX_PAGES);
    printf("{\"step\": \"telemetry\", \"ok\": true, \"flags\": %u, ", g_gw.gw_flags);
    print_all_telem();
    printf("}\n");
    return 0;
}

/* The node table, page by page, into list; DAN_OK or the failure. */
static int read_nodes(dan_gw_node_entry_t *list, size_t cap, size_t *nn)
{
    uint8_t first = 1;
    *nn = 0;
    do {
        dan_reader_t r;
        dan_gw_nodes_hdr_t h;
        size_t i;
        int rc = fcsim_finish(dan_gw_nodes(&g_gw, first, dan_posix_now_us()));
        if (rc == DAN_OK) {
            rc = dan_gw_nodes_begin(&g_gw, &r, &h);
        }
        if (rc != DAN_OK) {
            return rc;
        }
        for (i = 0; i < h.count && *nn < cap; i++) {
            if (dan_gw_nodes_next(&r, &list[*nn]) == DAN_OK) {
                (*nn)++;
            }
        }
        first = h.next;
    } while (first != 0);
    return DAN_OK;
}

/* One node as JSON, with its GetNodeInfo data (zeros when it fails). */
static void print_node(const dan_gw_node_entry_t *e, bool first)
{
    dan_gw_node_info_t ni;
    size_t k;
    memset(&ni, 0, sizeof ni);
    if (fcsim_finish(dan_gw_node_info(&g_gw, e->node_id, dan_posix_now_us())) == DAN_OK) {
        (void)dan_gw_node_info_get(&g_gw, &ni);
    }
    printf("%s{\"id\": %u, \"health\": %u, \"mode\": %u, \"sub_mode\": %u, \"uptime\": %lu, "
           "\"vendor\": %u, \"age_ms\": %lu, \"info\": %u, \"name\": \"%s\", "
           "\"sw\": [%u, %u], \"hw\": [%u, %u], \"uid\": \"",
           first ? "" : ", ", e->node_id, e->health, e->mode, e->sub_mode,
           (unsigned long)e->uptime_sec, e->vendor_status, (unsigned long)e->age_ms, ni.info_state,
           ni.name, ni.sw_major, ni.sw_minor, ni.hw_major, ni.hw_minor);
    for (k = 0; k < sizeof ni.unique_id; k++) {
        printf("%02x", ni.unique_id[k]);
    }
    printf("\"}");
}

static int step_nodes(const char *name, const char *step, char *args)
{
    static dan_gw_node_entry_t list[NODES_MAX];
    size_t nn, i;
    int rc = read_nodes(list, NODES_MAX, &nn);
    (void)args;
    if (fcsim_ok(step, name, rc) != 0) {
        return 1;
    }
    printf(", \"nodes\": [");
    for (i = 0; i < nn; i++) {
        print_node(&list[i], i == 0);
    }
    printf("]}\n");
    return 0;
}

static int step_stats(const char *name, const char *step, char *args)
{
    unsigned i;
    int rc = fcsim_finish(dan_gw_stats(&g_gw, dan_posix_now_us()));
    (void)args;
    if (fcsim_ok(step, name, rc) != 0) {
        return 1;
    }
    for (i = 0; i < DAN_GW_STAT_COUNT; i++) {
        printf(", \"%s\": %u", dan_gw_stat_name(i), g_gw.stats[i]);
    }
    /* t: CLOCK_MONOTONIC seconds, to place the line among other processes' events */
    printf(", \"master_timeouts\": %u, \"master_retries\": %u, \"master_bad_replies\": %u, "
           "\"t\": %.6f}\n",
           g_m.stats.timeouts, g_m.stats.retries, g_m.stats.bad_replies,
           (double)dan_posix_now_us() / 1e6);
    return 0;
}

/* tunnel:PORT:targetted:NODE:SERIAL[:BAUD[:OPTIONS]] |
 * tunnel:PORT:broadcast:PROTO:CHANNEL[:OPTIONS] */
static int step_tunnel(const char *name, const char *step, char *args)
{
    dan_gw_tun_open_t o;
    unsigned port, a = 0, opts = 0;
    int serial = 0, rc, fields;
    unsigned long c = 0;
    char mode[16];
    (void)name;
    memset(&o, 0, sizeof o);
    fields =
        args ? sscanf(args, "%u:%15[^:]:%u:%d:%lu:%u", &port, mode, &a, &serial, &c, &opts) : 0;
    if (fields < 4) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    o.port = (uint8_t)port;
    if (!strcmp(mode, "targetted")) {
        o.mode = DAN_GW_TUN_TARGETTED;
        o.protocol = TUN_PROTOCOL_UNDEFINED;
        o.target = (uint8_t)a;
        o.serial_id = (int8_t)serial;
        o.options = (uint8_t)(fields >= 6 ? opts : TUN_OPTION_LOCK_PORT);
        o.baud = (uint32_t)c;
    } else {
        o.mode = DAN_GW_TUN_BROADCAST;
        o.protocol = (uint8_t)a;
        o.target = (uint8_t)serial; /* the channel */
        o.options = (uint8_t)c;
    }
    rc = fcsim_finish(dan_gw_tunnel_open(&g_gw, &o, dan_posix_now_us()));
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    fcsim_mix_note_tunnel(&o);
    printf("{\"step\": \"tunnel\", \"ok\": true, \"port\": %u, \"options\": %u}\n", port,
           o.options);
    return 0;
}

static int step_xfer_args(const char *name, const char *step, char *args)
{
    (void)name;
    return args ? step_xfer("xfer", args) : fcsim_fail(step, DAN_ERR_ARG);
}

/* Splits args at commas into at most cap tokens (none for NULL). */
size_t fcsim_split_commas(char *args, char **tok, size_t cap)
{
    char *t, *save = NULL;
    size_t n = 0;
    for (t = args ? strtok_r(args, ",", &save) : NULL; t && n < cap;
         t = strtok_r(NULL, ",", &save)) {
        tok[n++] = t;
    }
    return n;
}

/* Prints the CAN_FILTER response's table as JSON strings ID/MASK (the
 * step syntax); the number of entries, or -1 when it does not decode. */
static int print_filter_table(uint8_t *result)
{
    dan_reader_t r;
    dan_gw_filter_t f;
    uint8_t count, i;
    if (dan_gw_filter_begin(&g_gw, &r, result, &count) != DAN_OK) {
        return -1;
    }
    printf("\"table\": [");
    for (i = 0; i < count && dan_gw_filter_next(&r, &f) == DAN_OK; i++) {
        bool ext = (f.id & DAN_GW_CAN_ID_EXT) != 0u;
        printf("%s\"%0*lX/%lX\"", i ? ", " : "", ext ? 8 : 3,
               (unsigned long)(f.id & ~DAN_GW_CAN_ID_EXT), (unsigned long)f.mask);
    }
    printf("]");
    return i;
}

/* filter:ID/MASK[,...] (replace), filter-add:..., filter-remove:...,
 * filter-read */
static int step_filter(const char *name, const char *step, char *args)
{
    dan_gw_filter_t f[DAN_GW_FILTERS_MAX];
    char *tok[DAN_GW_FILTERS_MAX];
    size_t n = fcsim_split_commas(args, tok, DAN_GW_FILTERS_MAX), i;
    uint8_t op = !strcmp(name, "filter-add")      ? DAN_GW_FILTER_ADD
                 : !strcmp(name, "filter-remove") ? DAN_GW_FILTER_REMOVE
                 : !strcmp(name, "filter-read")   ? DAN_GW_FILTER_READ
                                                  : DAN_GW_FILTER_REPLACE;
    uint8_t result = 0;
    int rc, entries;
    for (i = 0; i < n; i++) {
        char *slash = strchr(tok[i], '/');
        if (slash == NULL) {
            return fcsim_fail(step, DAN_ERR_ARG);
        }
        f[i].id =
            (uint32_t)strtoul(tok[i], NULL, 16) | ((slash - tok[i]) == 8 ? DAN_GW_CAN_ID_EXT : 0u);
        f[i].mask = (uint32_t)strtoul(slash + 1, NULL, 16);
    }
    rc = fcsim_finish(dan_gw_can_filter(&g_gw, op, f, n, dan_posix_now_us()));
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    printf("{\"step\": \"%s\", \"count\": %zu, ", name, n);
    entries = print_filter_table(&result);
    /* result 1: the table was full, an entry was not added */
    printf(", \"entries\": %d, \"result\": %u, \"ok\": %s}\n", entries, result,
           entries >= 0 && result == 0u ? "true" : "false");
    return entries >= 0 && result == 0u ? 0 : 1;
}

/* cansend:ID#DATA[,...] */
static int step_cansend(const char *name, const char *step, char *args)
{
    dan_can_frame_t f[DAN_GW_CAN_FRAMES_MAX];
    char *tok[DAN_GW_CAN_FRAMES_MAX];
    size_t n = fcsim_split_commas(args, tok, DAN_GW_CAN_FRAMES_MAX), i;
    int rc;
    (void)name;
    for (i = 0; i < n; i++) {
        if (parse_frame(tok[i], &f[i])) {
            return fcsim_fail(step, DAN_ERR_ARG);
        }
    }
    rc = fcsim_finish(dan_gw_can_send(&g_gw, f, n, dan_posix_now_us()));
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    printf("{\"step\": \"cansend\", \"ok\": %s, \"accepted\": %u}\n",
           g_gw.can_accepted == n ? "true" : "false", g_gw.can_accepted);
    return g_gw.can_accepted == n ? 0 : 1;
}

/* One CAN_RECV exchange; prints its frames as JSON strings, counts them in
 * *got; the number of frames the gateway sent (0 after a failure). */
static size_t candump_once(size_t *got)
{
    dan_reader_t r;
    dan_gw_can_recv_t h;
    dan_can_frame_t f;
    size_t i, k;
    int rc = fcsim_finish(dan_gw_can_recv(&g_gw, DAN_GW_CAN_FRAMES_MAX, dan_posix_now_us()));
    if (rc != DAN_OK || dan_gw_can_begin(&g_gw, &r, &h) != DAN_OK) {
        return SIZE_MAX;
    }
    for (i = 0; i < h.count; i++) {
        if (dan_gw_can_next(&r, &f) != DAN_OK) {
            break;
        }
        printf("%s\"%0*X#", *got ? ", " : "", (f.flags & DAN_CAN_EXT) ? 8 : 3, (unsigned)f.id);
        for (k = 0; k < f.dlc; k++) {
            printf("%02X", f.data[k]);
        }
        printf("\"");
        (*got)++;
    }
    return h.count;
}

/* candump:N[:TIMEOUT_MS] */
static int step_candump(const char *name, const char *step, char *args)
{
    unsigned long want = 1, timeout_ms = CANDUMP_TIMEOUT_MS;
    uint64_t end;
    size_t got = 0;
    (void)name;
    (void)step;
    if (args) {
        sscanf(args, "%lu:%lu", &want, &timeout_ms);
    }
    end = dan_posix_now_us() + timeout_ms * 1000u;
    printf("{\"step\": \"candump\", \"frames\": [");
    while (got < want && dan_posix_now_us() < end) {
        if (candump_once(&got) == 0) {
            fcsim_sleep_us(CANDUMP_IDLE_US); /* nothing queued: do not spin */
        }
    }
    printf("], \"ok\": %s, \"dropped\": %u}\n", got >= want ? "true" : "false",
           g_gw.can_rx_dropped);
    return got >= want ? 0 : 1;
}

/* The result of a call answered with the gateway flags, as JSON. */
static int flags_result(const char *name, const char *step, int rc, size_t count)
{
    if (fcsim_ok(step, name, rc) != 0) {
        return 1;
    }
    printf(", \"flags\": %u, \"count\": %zu}\n", g_gw.gw_flags, count);
    return 0;
}

/* safety:off|on */
static int step_safety(const char *name, const char *step, char *args)
{
    int rc;
    if (args == NULL || (strcmp(args, "off") != 0 && strcmp(args, "on") != 0)) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    rc = fcsim_finish(dan_gw_safety(&g_gw, !strcmp(args, "off"), dan_posix_now_us()));
    if (rc == DAN_OK) {
        fcsim_mix_note_safety(!strcmp(args, "off"));
    }
    return flags_result(name, step, rc, 1);
}

int fcsim_parse_servo(char *tok, dan_gw_servo_t *s, bool *hold)
{
    char *end;
    unsigned long id = strtoul(tok, &end, 0), type = 0;
    float v = 0.0f;
    if (end == tok || *end != '=' || id > UINT8_MAX) {
        return -1;
    }
    tok = end + 1;
    if (hold != NULL) {
        *hold = !strncmp(tok, "hold", 4);
    }
    if (hold != NULL && *hold) {
        end = tok + 4;
    } else {
        v = strtof(tok, &end);
        if (end == tok) {
            return -1;
        }
    }
    if (*end == ':') {
        tok = end + 1;
        type = strtoul(tok, &end, 0);
        if (end == tok || type > UINT8_MAX) {
            return -1;
        }
    }
    if (*end != '\0') {
        return -1;
    }
    *s = dan_gw_servo_make((uint8_t)id, (uint8_t)type, v);
    return 0;
}

/* servo:ID=VALUE[:TYPE],... and servo-fs[:ID=hold|VALUE[:TYPE],...] */
static int step_servo(const char *name, const char *step, char *args)
{
    dan_gw_servo_t s[DAN_GW_SERVO_MAX];
    dan_gw_servo_fs_t fs[DAN_GW_SERVO_MAX];
    char *tok[DAN_GW_SERVO_MAX];
    size_t n = fcsim_split_commas(args, tok, DAN_GW_SERVO_MAX), i;
    bool failsafe = !strcmp(name, "servo-fs");
    int rc;
    for (i = 0; i < n; i++) {
        bool hold = false;
        if (fcsim_parse_servo(tok[i], &s[i], failsafe ? &hold : NULL)) {
            return fcsim_fail(step, DAN_ERR_ARG);
        }
        fs[i].mode = (uint8_t)(hold ? DAN_GW_SERVO_HOLD : DAN_GW_SERVO_VALUE);
        fs[i].value = s[i];
    }
    if (!failsafe) {
        return flags_result(name, step, fcsim_finish(dan_gw_servo(&g_gw, s, n, dan_posix_now_us())),
                            n);
    }
    rc = fcsim_finish(dan_gw_servo_failsafe(&g_gw, fs, n, dan_posix_now_us()));
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    fcsim_mix_note_servo_fs(fs, n);
    printf("{\"step\": \"%s\", \"ok\": true, \"count\": %zu, \"kept\": %u}\n", name, n,
           g_gw.servo_fs_kept);
    return 0;
}

/* lights:ID=RGB565HEX,... */
static int step_lights(const char *name, const char *step, char *args)
{
    dan_gw_light_t l[DAN_GW_LIGHTS_MAX];
    char *tok[DAN_GW_LIGHTS_MAX];
    size_t n = fcsim_split_commas(args, tok, DAN_GW_LIGHTS_MAX), i;
    for (i = 0; i < n; i++) {
        char *end;
        unsigned long id = strtoul(tok[i], &end, 0), rgb;
        if (end == tok[i] || *end != '=' || id > UINT8_MAX) {
            return fcsim_fail(step, DAN_ERR_ARG);
        }
        rgb = strtoul(end + 1, &end, 16);
        if (*end != '\0' || rgb > UINT16_MAX) {
            return fcsim_fail(step, DAN_ERR_ARG);
        }
        l[i].light_id = (uint8_t)id;
        l[i].rgb565 = (uint16_t)rgb;
    }
    return flags_result(name, step, fcsim_finish(dan_gw_lights(&g_gw, l, n, dan_posix_now_us())),
                        n);
}

/* beep:HZ:MS */
static int step_beep(const char *name, const char *step, char *args)
{
    unsigned long hz, ms;
    if (args == NULL || sscanf(args, "%lu:%lu", &hz, &ms) != 2) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    return flags_result(
        name, step,
        fcsim_finish(dan_gw_beep(&g_gw, (uint32_t)hz, (uint32_t)ms, dan_posix_now_us())), 1);
}

/* raw:CODE[:HEX]: a request the client's typed calls cannot make (e.g. ARM
 * with a value the gateway must refuse); sealed like every gateway request. */
static int step_raw(const char *name, const char *step, char *args)
{
    uint8_t buf[DAN_MAX_PAYLOAD];
    size_t len = 0, i;
    char *end;
    unsigned long code = args ? strtoul(args, &end, 0) : 0u;
    int n;
    if (args == NULL || end == args || code == 0u || (*end != '\0' && *end != ':')) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    for (end += *end == ':'; end[0] && end[1] && len < sizeof buf; end += 2) {
        char b[3] = {end[0], end[1], 0};
        buf[len++] = (uint8_t)strtoul(b, NULL, 16);
    }
    n = dan_gw_seal((uint32_t)code, DAN_GW_REQUEST, buf, len, sizeof buf);
    n = n < 0 ? n
              : fcsim_finish(
                    dan_master_request(&g_m, (uint32_t)code, buf, (size_t)n, dan_posix_now_us()));
    if (n != DAN_OK) {
        return fcsim_fail(step, n);
    }
    printf("{\"step\": \"%s\", \"ok\": true, \"code\": %lu, \"response\": \"", name, code);
    for (i = 0; i + DAN_GW_SEAL_SIZE < g_m.resp_len; i++) {
        printf("%02x", g_m.resp[i]);
    }
    printf("\"}\n");
    return 0;
}

static const struct {
    const char *name;
    step_fn fn;
} steps[] = {
    {"stop", step_stop},
    {"sleep", step_sleep},
    {"discover", step_discover},
    {"configure", step_configure},
    {"arm", step_arm},
    {"disarm", step_arm},
    {"config", step_config},
    {"esc", step_esc},
    {"esc-ramp", step_esc_ramp},
    {"telemetry", step_telemetry},
    {"nodes", step_nodes},
    {"stats", step_stats},
    {"tunnel", step_tunnel},
    {"xfer", step_xfer_args},
    {"filter", step_filter},
    {"filter-add", step_filter},
    {"filter-remove", step_filter},
    {"filter-read", step_filter},
    {"cansend", step_cansend},
    {"candump", step_candump},
    {"config-dna", step_config_field},
    {"telem-timeout", step_config_field},
    {"health", step_health},
    {"dna", step_dna},
    {"safety", step_safety},
    {"servo", step_servo},
    {"servo-fs", step_servo},
    {"lights", step_lights},
    {"beep", step_beep},
    {"raw", step_raw},
    {"upload", fcsim_step_upload},
    {"files", fcsim_step_files},
    {"rm", fcsim_step_rm},
    {"fw-begin", fcsim_step_fw_begin},
    {"node-info", fcsim_step_node_info},
};

static int do_step(char *step)
{
    char name[64], whole[512];
    char *args = strchr(step, ':');
    size_t i;
    snprintf(name, sizeof name, "%.*s", args ? (int)(args - step) : (int)strlen(step), step);
    /* the step as given, for a failure's line: the functions cut args up */
    snprintf(whole, sizeof whole, "%s", step);
    if (args) {
        args++;
    }
    for (i = 0; i < sizeof steps / sizeof steps[0]; i++) {
        if (!strcmp(name, steps[i].name)) {
            return steps[i].fn(name, whole, args);
        }
    }
    tool_error("unknown step '%s'", step);
    return 2;
}

int main(int argc, char **argv)
{
    static const uint32_t types[] = {DAN_TYPE_CAN_GW_FIRST};
    const char *port = NULL;
    uint32_t latency_ms = 50, gap_ms = 20, baud = 9600, max_baud = 0;
    bool no_echo = false;
    dan_master_config_t mc;
    char err[256];
    int i, rc = 0;
    tool_prog = "dan-fcsim";
    for (i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--port") && i + 1 < argc) {
            port = argv[++i];
        } else if (!strcmp(argv[i], "--latency-ms") && i + 1 < argc) {
            latency_ms = (uint32_t)strtoul(argv[++i], NULL, 0);
        } else if (!strcmp(argv[i], "--gap-ms") && i + 1 < argc) {
            gap_ms = (uint32_t)strtoul(argv[++i], NULL, 0);
        } else if (!strcmp(argv[i], "--baud") && i + 1 < argc) {
            baud = (uint32_t)strtoul(argv[++i], NULL, 0);
        } else if (!strcmp(argv[i], "--max-baud") && i + 1 < argc) {
            max_baud = (uint32_t)strtoul(argv[++i], NULL, 0);
        } else if (!strcmp(argv[i], "--no-echo")) {
            no_echo = true;
        } else if (!strcmp(argv[i], "--recover") && i + 1 < argc) {
            g_recover = (uint32_t)strtoul(argv[++i], NULL, 0);
        } else if (!strcmp(argv[i], "--fast")) {
            g_fast = true;
        } else if (!strcmp(argv[i], "--telem-every") && i + 1 < argc) {
            g_telem_every = (uint32_t)strtoul(argv[++i], NULL, 0);
        } else if (!strncmp(argv[i], "--mix-", 6) || !strcmp(argv[i], "--restore")) {
            int took = fcsim_mix_option(argv[i], i + 1 < argc ? argv[i + 1] : NULL);
            if (took < 0) {
                tool_error("bad %s", argv[i]);
                return 2;
            }
            i += took;
        } else if (!strcmp(argv[i], "--help")) {
            fputs(HELP, stdout);
            return 0;
        } else if (argv[i][0] == '-') {
            tool_error("unknown option %s", argv[i]);
            return 2;
        } else {
            break;
        }
    }
    if (port == NULL || baud == 0u) {
        tool_error("--port is required (and --baud is not 0)");
        return 2;
    }
    signal(SIGPIPE, SIG_IGN);
    tool_fine_timers();
    if (dan_posix_open(&g_port, port, baud, no_echo ? DAN_POSIX_NO_ECHO : DAN_POSIX_ECHO, err,
                       sizeof err) != DAN_OK) {
        tool_error("%s", err);
        return 2;
    }
    dan_master_config_default(&mc);
    mc.resp_latency_us = latency_ms * 1000u;
    mc.gap_us = gap_ms * 1000u;
    mc.retries = 3;
    mc.fast_max_baud = max_baud;
    if (dan_master_init(&g_m, dan_posix_port(&g_port), &mc, types, 1, baud, dan_posix_now_us()) !=
        DAN_OK) {
        tool_error("master init failed");
        return 2;
    }
    dan_master_set_identities(&g_m, &g_id, 1);
    dan_gw_init(&g_gw, &g_m);
    dan_gw_set_stats(&g_gw, g_gw_stats);
    for (; i < argc && rc != 2; i++) {
        int r = do_step(argv[i]);
        fflush(stdout);
        if (r == 2) {
            rc = 2;
        } else if (r != 0) {
            rc = 1;
        }
    }
    dan_posix_close(&g_port);
    return rc;
}
