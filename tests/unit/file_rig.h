/* The file tests' rig: the gateway rig (gw_rig.h) with a RAM store (S)
 * and an image (img) to upload through the client. */
#ifndef FILE_RIG_H
#define FILE_RIG_H

#include "file_store_ram.h"
#include "gw_rig.h"

#define IMG_SIZE 1000u

extern ram_store_t S;
extern uint8_t img[IMG_SIZE];

/* The gateway (re)started, with S or no store: S survives, RAM state not. */
void gateway_start(bool with_store);
/* setup() of gw_rig, an empty S, img filled, the gateway started with S. */
int setup_files(void **state);
/* Completes the file call in flight: its result byte; *value (may be NULL)
 * as dan_gw_file_result() gives it. */
uint8_t done(uint32_t *value);
uint8_t open_file(const char *name, uint32_t size, bool restart, uint32_t *have);
/* FILE_WRITE of img[off, off + len). */
uint8_t write_at(uint32_t off, size_t len, uint32_t *have);
uint8_t commit(uint32_t crc, uint32_t *held);
/* Writes img[from, to) in chunks of up to 150 from where the gateway is. */
void upload_range(uint32_t from, uint32_t to);
/* A whole upload of img[0, size) as name, committed. */
void upload(const char *name, uint32_t size);

#endif
