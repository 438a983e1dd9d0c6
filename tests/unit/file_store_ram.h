/* A file store in RAM for the unit tests: every dan_gw_file_store_t
 * callback over static buffers (a few small files and the one partial),
 * with faults to inject. A "restart" of the gateway keeps it: the node is
 * initialised again with the same store. */
#ifndef FILE_STORE_RAM_H
#define FILE_STORE_RAM_H

#include "dan/can_gw/file_store.h"
#include "dan/common.h"

#define RAM_FILES    6u
#define RAM_FILE_CAP 2048u /* bytes per file (and the store's max_size) */

typedef struct {
    bool used;
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    uint32_t len;
    uint8_t data[RAM_FILE_CAP];
} ram_file_t;

typedef struct {
    ram_file_t files[RAM_FILES];
    ram_file_t partial;
    unsigned writes;    /* up_write calls */
    unsigned fail_from; /* callbacks from this count on fail with EIO (0: never) */
    unsigned calls;     /* callbacks so far */
    dan_gw_file_store_t fs;
} ram_store_t;

/* Empties s and fills s->fs (ctx = s, max_size = RAM_FILE_CAP). */
void ram_store_init(ram_store_t *s);
/* The committed file name, or NULL. */
const ram_file_t *ram_store_file(const ram_store_t *s, const char *name);

#endif
