/* What dan-fcsim's step files share with dan-fcsim.c (the master, the
 * client and how a step runs an operation and reports). */
#ifndef DAN_FCSIM_H
#define DAN_FCSIM_H

#include <stdint.h>

#include "dan/can_gw/client.h"
#include "dan/master.h"

extern dan_master_t g_m;
extern dan_gw_t g_gw;

/* The started operation's result once it ran (rc when it did not start). */
int fcsim_finish(int rc);
/* Prints the step's failure line; returns 1. */
int fcsim_fail(const char *step, int rc);
/* Waits us, dropping whatever the port receives meanwhile. */
void fcsim_sleep_us(uint64_t us);

/* The file steps (fcsim/files.c): upload:NAME:PATH, files, rm:NAME,
 * fw-begin:NODE:NAME[:CALL_ID], node-info:NODE. Same contract as the
 * other steps: 0 ok, 1 failed, 2 bad step. */
int fcsim_step_upload(const char *name, const char *step, char *args);
int fcsim_step_files(const char *name, const char *step, char *args);
int fcsim_step_rm(const char *name, const char *step, char *args);
int fcsim_step_fw_begin(const char *name, const char *step, char *args);
int fcsim_step_node_info(const char *name, const char *step, char *args);

#endif
