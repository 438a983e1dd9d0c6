/*
 * The dynamic node ID allocation table in a file (dan-gatewayd --dna-db):
 * the gateway node's storage callbacks (dan_gw_storage_t) on a path.
 *
 *     dan_dna_file_init(&f, path);
 *     if (dan_dna_file_read(&f, err, sizeof err) < 0) exit 2;  // unreadable
 *     cfg.dna_storage = &f.storage;
 *     dan_gw_node_init(&node, &cfg, now);                      // loads
 *     if (node.dna.flags & DAN_GW_DNA_STORE_ERROR)
 *         dan_dna_file_quarantine(&f, msg, sizeof msg);        // PATH.bad
 *
 * A store writes PATH.tmp, fsyncs it, renames it over PATH and fsyncs the
 * directory: after a crash or a power cut the file holds the old table or
 * the new one, never part of one. A missing file is an empty table. A file
 * that does not check (dan_gw_dna_blob_check: magic, length, CRC, content;
 * or longer than any table) is never used: the node starts empty, and
 * dan_dna_file_quarantine() renames it to PATH.bad and says why, so the
 * next store does not overwrite the evidence.
 */
#ifndef DAN_GWD_DNA_FILE_H
#define DAN_GWD_DNA_FILE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/can_gw/node.h"

#define DAN_DNA_FILE_PATH_MAX 240 /* longest PATH (PATH.tmp and PATH.bad must fit) */
#define DAN_DNA_FILE_ERR_MAX  320

typedef struct {
    const char *path;
    dan_gw_storage_t storage;              /* give &storage to dan_gw_node_config_t.dna_storage */
    uint8_t buf[DAN_GW_DNA_BLOB_MAX + 1u]; /* one more: a longer file is no table */
    size_t len;                            /* bytes read by dan_dna_file_read() */
    bool exists;                           /* PATH was there */
    uint32_t stores;                       /* tables written */
    uint32_t store_errors;                 /* writes that failed (err says why) */
    char err[DAN_DNA_FILE_ERR_MAX];        /* the last store error */
} dan_dna_file_t;

void dan_dna_file_init(dan_dna_file_t *f, const char *path);

/* Checks that path can hold a table (not too long, not a directory, its
 * directory exists and is writable); 0, or -1 with a one-line reason. */
int dan_dna_file_check_path(const char *path, char *err, size_t errlen);

/* Reads PATH for the node's load callback: 0 (a missing file is an empty
 * table), or -1 with a one-line reason when it exists but cannot be read
 * (the daemon refuses to start: it must not overwrite a table it could
 * not read). */
int dan_dna_file_read(dan_dna_file_t *f, char *err, size_t errlen);

/* After the node refused what was read: renames PATH to PATH.bad and puts
 * "PATH: REASON; renamed to PATH.bad" in msg. 0, or -1 when the rename
 * failed (msg says so). */
int dan_dna_file_quarantine(dan_dna_file_t *f, char *msg, size_t msglen);

#endif /* DAN_GWD_DNA_FILE_H */
