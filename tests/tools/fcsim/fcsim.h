/* What dan-fcsim's step files share with dan-fcsim.c (the master, the
 * client and how a step runs an operation and reports). */
#ifndef DAN_FCSIM_H
#define DAN_FCSIM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/can_gw/client.h"
#include "dan/master.h"

extern dan_master_t g_m;
extern dan_gw_t g_gw;

/* The started operation's result once it ran (rc when it did not start). */
int fcsim_finish(int rc);
/* Prints the step's failure line; returns 1. */
int fcsim_fail(const char *step, int rc);
/* rc not DAN_OK: fcsim_fail(step, rc). Else the start of the step's line,
 * {"step": "<name>", "ok": true (the caller adds its fields and the
 * closing brace), and 0. */
int fcsim_ok(const char *step, const char *name, int rc);
/* Waits us, dropping whatever the port receives meanwhile. */
void fcsim_sleep_us(uint64_t us);

/* Splits args at commas into at most cap tokens (args is cut up). */
size_t fcsim_split_commas(char *args, char **tok, size_t cap);
/* One ID=VALUE[:TYPE] (VALUE may be "hold" when hold != NULL, which then
 * tells whether it was); 0, or -1 when it does not parse. */
int fcsim_parse_servo(char *tok, dan_gw_servo_t *s, bool *hold);

/* Side traffic in the ESC loops and --restore (fcsim/mix.c). An option:
 * 1 (it took arg), 0 (no argument taken), -1 (bad). */
int fcsim_mix_option(const char *opt, char *arg);
void fcsim_mix_note_arm(bool armed);
void fcsim_mix_note_safety(bool off);
void fcsim_mix_note_servo_fs(const dan_gw_servo_fs_t *fs, size_t n);
void fcsim_mix_note_tunnel(const dan_gw_tun_open_t *cfg);
/* After a recovery: what the steps had set, again (with --restore). */
int fcsim_mix_restore(void);
/* After the turn-th ESC exchange that succeeded: the side calls due. */
void fcsim_mix_turn(uint32_t turn);
/* The ESC loop's side counts as JSON members ("k": v, ...), then zeroed. */
void fcsim_mix_print(void);

/* The file steps (fcsim/files.c): upload:NAME:PATH, files, rm:NAME,
 * fw-begin:NODE:NAME[:CALL_ID], node-info:NODE. Same contract as the
 * other steps: 0 ok, 1 failed, 2 bad step. */
int fcsim_step_upload(const char *name, const char *step, char *args);
int fcsim_step_files(const char *name, const char *step, char *args);
int fcsim_step_rm(const char *name, const char *step, char *args);
int fcsim_step_fw_begin(const char *name, const char *step, char *args);
int fcsim_step_node_info(const char *name, const char *step, char *args);

#endif
