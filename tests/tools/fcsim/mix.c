/*
 * dan-fcsim's side traffic (the chaos soak, tests/bench/chaos.py): between
 * the exchanges of its ESC loops, servo commands (--mix-servo) and a
 * tunnel stream (--mix-tunnel), so the gateway carries all three at once
 * as an FC's would; and --restore: after a recovery (the gateway came back
 * at 9600, DISARMED, safety on, without tunnels) the FC sends again what
 * it had set: ARM, SAFETY, SERVO_FAILSAFE, the tunnel; and ARM, SAFETY
 * whenever the flags of a response show a failsafe of the gateway undid
 * them.
 *
 * The tunnel stream is records "TAG:SEQ:CK\n" (SEQ six digits from 0, CK
 * the sum of the bytes before it mod 256 in two hex digits), so the far
 * end and the FC's copy of what came back can tell a lost byte from a
 * wrong one; what comes back is appended to OUTFILE as it arrives.
 */
#include <fcntl.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "dan/posix.h"
#include "fcsim/fcsim.h"

#define MIX_SERVO_EVERY 10u  /* a SERVO every 10th ESC exchange */
#define MIX_TUN_CHUNK   48u  /* tunnel bytes written per xfer at most */
#define MIX_TUN_READ    96u  /* and read */
#define MIX_TUN_POLL    4u   /* a read-only xfer every 4th exchange */
#define MIX_TUN_BURST   256u /* the write budget's cap (bytes) */

static struct {
    size_t n;
    dan_gw_servo_t s[DAN_GW_SERVO_MAX];
    uint32_t ok, errors; /* of the current ESC loop */
} servo;

static struct {
    bool on, open;
    unsigned port;
    char tag[16];
    int out_fd;
    uint32_t rate; /* bytes a second */
    double budget;
    uint64_t last_us;
    uint32_t seq;
    uint8_t sum;
    uint8_t pend[64];
    size_t npend;
    uint32_t xfers, errors, written, read; /* of the current ESC loop */
} tun;

/* What --restore sends again after a recovery. */
static struct {
    bool on, armed_set, armed, safety_set, safety_off, fs_set, tun_set;
    dan_gw_servo_fs_t fs[DAN_GW_SERVO_MAX];
    size_t nfs;
    dan_gw_tun_open_t tun_cfg;
    uint32_t restored, failed, rearms, reopened;
} restore;

static int servo_option(char *arg)
{
    char *tok[DAN_GW_SERVO_MAX];
    size_t i;
    servo.n = fcsim_split_commas(arg, tok, DAN_GW_SERVO_MAX);
    for (i = 0; i < servo.n; i++) {
        if (fcsim_parse_servo(tok[i], &servo.s[i], NULL)) {
            return -1;
        }
    }
    return servo.n > 0u ? 1 : -1;
}

/* PORT:TAG:OUTFILE:RATE */
static int tunnel_option(const char *arg)
{
    char out[256];
    unsigned long rate;
    if (sscanf(arg, "%u:%15[^:]:%255[^:]:%lu", &tun.port, tun.tag, out, &rate) != 4 ||
        tun.port >= DAN_GW_TUNNELS || rate == 0u) {
        return -1;
    }
    tun.out_fd = open(out, O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (tun.out_fd < 0) {
        return -1;
    }
    tun.rate = (uint32_t)rate;
    tun.on = true;
    return 1;
}

int fcsim_mix_option(const char *opt, char *arg)
{
    if (!strcmp(opt, "--restore")) {
        restore.on = true;
        return 0;
    }
    if (arg == NULL) {
        return -1;
    }
    if (!strcmp(opt, "--mix-servo")) {
        return servo_option(arg);
    }
    if (!strcmp(opt, "--mix-tunnel")) {
        return tunnel_option(arg);
    }
    return -1;
}

/* ---- what the steps set (for --restore) ---- */

void fcsim_mix_note_arm(bool armed)
{
    restore.armed_set = true;
    restore.armed = armed;
}

void fcsim_mix_note_safety(bool off)
{
    restore.safety_set = true;
    restore.safety_off = off;
}

void fcsim_mix_note_servo_fs(const dan_gw_servo_fs_t *fs, size_t n)
{
    memcpy(restore.fs, fs, n * sizeof fs[0]);
    restore.nfs = n;
    restore.fs_set = true;
}

void fcsim_mix_note_tunnel(const dan_gw_tun_open_t *cfg)
{
    restore.tun_cfg = *cfg;
    restore.tun_set = true;
    if (tun.on && cfg->port == tun.port) {
        tun.open = cfg->mode != DAN_GW_TUN_CLOSED;
    }
}

/* The tunnel after a recovery: a gateway that kept it (the exchanges
 * failed for noise or a jammer, not for a restart) still holds its
 * buffered bytes and offsets, and opening it again would discard them
 * (docs/PROTOCOL.md "Tunnels"); so a TUN_XFER of nothing asks first, and
 * only a gateway that refuses it (the port closed: it restarted) gets
 * TUN_OPEN again. */
static int restore_tunnel(void)
{
    static const uint8_t nothing[1];
    int rc = fcsim_finish(
        dan_gw_tunnel_xfer(&g_gw, restore.tun_cfg.port, nothing, 0, 0, dan_posix_now_us()));
    if (rc == DAN_ERR_REMOTE) {
        restore.reopened++;
        rc = fcsim_finish(dan_gw_tunnel_open(&g_gw, &restore.tun_cfg, dan_posix_now_us()));
    }
    return rc;
}

int fcsim_mix_restore(void)
{
    int rc = DAN_OK;
    if (!restore.on) {
        return DAN_OK;
    }
    if (rc == DAN_OK && restore.armed_set) {
        rc = fcsim_finish(dan_gw_arm(&g_gw, restore.armed, dan_posix_now_us()));
    }
    if (rc == DAN_OK && restore.safety_set) {
        rc = fcsim_finish(dan_gw_safety(&g_gw, restore.safety_off, dan_posix_now_us()));
    }
    if (rc == DAN_OK && restore.fs_set) {
        rc =
            fcsim_finish(dan_gw_servo_failsafe(&g_gw, restore.fs, restore.nfs, dan_posix_now_us()));
    }
    if (rc == DAN_OK && restore.tun_set) {
        rc = restore_tunnel();
    }
    if (rc == DAN_OK) {
        restore.restored++;
    } else {
        restore.failed++;
    }
    return rc;
}

/* ---- the side traffic ---- */

/* The next record into tun.pend (it has room: called when empty). */
static void tun_record(void)
{
    char rec[48];
    int n = snprintf(rec, sizeof rec, "%s:%06u:", tun.tag, (unsigned)tun.seq++);
    int i;
    uint8_t sum = 0;
    for (i = 0; i < n; i++) {
        sum = (uint8_t)(sum + (uint8_t)rec[i]);
    }
    n += snprintf(rec + n, sizeof rec - (size_t)n, "%02x\n", sum);
    memcpy(tun.pend + tun.npend, rec, (size_t)n);
    tun.npend += (size_t)n;
}

/* One TUN_XFER: writes what the rate allows, reads what came back. */
static void tun_turn(uint32_t turn)
{
    uint64_t now = dan_posix_now_us();
    size_t want, n;
    const uint8_t *d;
    int rc;
    if (tun.last_us != 0u) {
        tun.budget += (double)(now - tun.last_us) * tun.rate / 1e6;
        if (tun.budget > MIX_TUN_BURST) {
            tun.budget = MIX_TUN_BURST;
        }
    }
    tun.last_us = now;
    if (tun.npend == 0u) {
        tun_record();
    }
    want = tun.budget < 1.0 ? 0u : (size_t)tun.budget;
    want = want < tun.npend ? want : tun.npend;
    want = want < MIX_TUN_CHUNK ? want : MIX_TUN_CHUNK;
    if (want == 0u && turn % MIX_TUN_POLL != 0u) {
        return;
    }
    rc = fcsim_finish(dan_gw_tunnel_xfer(&g_gw, (uint8_t)tun.port, tun.pend, want, MIX_TUN_READ,
                                         dan_posix_now_us()));
    tun.xfers++;
    if (rc != DAN_OK) {
        tun.errors++; /* the next xfer repeats the same offsets */
        return;
    }
    n = g_gw.tun[tun.port].accepted;
    memmove(tun.pend, tun.pend + n, tun.npend - n);
    tun.npend -= n;
    tun.written += (uint32_t)n;
    tun.budget -= (double)n;
    if (dan_gw_tunnel_data(&g_gw, &d, &n) == DAN_OK && n > 0u) {
        if (write(tun.out_fd, d, n) != (ssize_t)n) {
            tun.errors++;
        }
        tun.read += (uint32_t)n;
    }
}

/* A failsafe of the gateway (commands paused too long) disarmed it and set
 * safety on: an FC that still means to fly says so again. */
static void keep_state(void)
{
    if (restore.armed_set && restore.armed && (g_gw.gw_flags & DAN_GW_FLAG_ARMED) == 0u &&
        fcsim_finish(dan_gw_arm(&g_gw, true, dan_posix_now_us())) == DAN_OK) {
        restore.rearms++;
    }
    if (restore.safety_set && restore.safety_off &&
        (g_gw.gw_flags & DAN_GW_FLAG_SAFETY_OFF) == 0u) {
        (void)fcsim_finish(dan_gw_safety(&g_gw, true, dan_posix_now_us()));
    }
}

void fcsim_mix_turn(uint32_t turn)
{
    if (restore.on) {
        keep_state();
    }
    if (servo.n > 0u && turn % MIX_SERVO_EVERY == 0u) {
        if (fcsim_finish(dan_gw_servo(&g_gw, servo.s, servo.n, dan_posix_now_us())) == DAN_OK) {
            servo.ok++;
        } else {
            servo.errors++;
        }
    }
    if (tun.on && tun.open) {
        tun_turn(turn);
    }
}

void fcsim_mix_print(void)
{
    if (servo.n > 0u) {
        printf("\"servo_cmds\": %u, \"servo_errors\": %u, ", servo.ok, servo.errors);
    }
    if (tun.on) {
        printf("\"tun_xfers\": %u, \"tun_errors\": %u, \"tun_written\": %u, \"tun_read\": %u, "
               "\"rd_dropped\": %u, \"rd_lost\": %u, ",
               tun.xfers, tun.errors, tun.written, tun.read, g_gw.tun[tun.port].rd_dropped,
               g_gw.tun[tun.port].rd_lost);
    }
    if (restore.on) {
        printf("\"restored\": %u, \"restore_failed\": %u, \"rearms\": %u, "
               "\"tunnel_reopened\": %u, ",
               restore.restored, restore.failed, restore.rearms, restore.reopened);
    }
    servo.ok = servo.errors = 0;
    tun.xfers = tun.errors = tun.written = tun.read = 0;
}
