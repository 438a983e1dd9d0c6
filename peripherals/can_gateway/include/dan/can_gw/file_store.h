/*
 * The gateway's file store: where the DroneCAN file server (file.GetInfo,
 * file.Read) reads firmware images from and where DAN uploads (FILE_OPEN,
 * FILE_WRITE, FILE_COMMIT) write them (docs/PROTOCOL.md section 7, "Files
 * and firmware updates"). The node owns the rules (names, the one upload,
 * CRC-32, resume); the store only keeps bytes: a directory for dan-gatewayd
 * (linux/file_dir.c), flash pages on an MCU gateway.
 *
 * Every name a callback receives has passed dan_gw_file_name_ok(): 1..32
 * bytes of [A-Za-z0-9._-], NUL-terminated, not starting with '.'. A store
 * keeps committed files (served, listed) apart from the one partial upload
 * (never served). Callbacks return DAN_OK / a count, or a negative
 * DAN_GW_FS_E* code. They run inside dan_gw_node_rx_can() and the DAN
 * handlers, so they must not block for long (a read of 256 bytes, a write
 * of 150).
 */
#ifndef DAN_CAN_GW_FILE_STORE_H
#define DAN_CAN_GW_FILE_STORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_GW_FILE_NAME_MAX  32u  /* bytes, without the NUL */
#define DAN_GW_FILE_CHUNK_MAX 150u /* FILE_WRITE data per request */
#define DAN_GW_FILE_READ_MAX  256u /* file.Read data per response (DSDL) */

#define DAN_GW_FS_ENOENT (-2)  /* no such file */
#define DAN_GW_FS_EIO    (-5)  /* the medium failed */
#define DAN_GW_FS_EFBIG  (-27) /* over the store's cap */
#define DAN_GW_FS_ENOSPC (-28) /* the medium is full */

typedef struct {
    /* Committed files. */
    /* Size of file name (>= 0) or DAN_GW_FS_ENOENT. */
    int32_t (*size)(void *ctx, const char *name);
    /* Up to cap bytes of file name from offset into buf: the count (0 at or
     * past the end), or negative. */
    int32_t (*read)(void *ctx, const char *name, uint32_t offset, uint8_t *buf, size_t cap);
    /* The index-th file in name order: copies its name (NUL-terminated,
     * name_cap >= DAN_GW_FILE_NAME_MAX + 1) and size; DAN_GW_FS_ENOENT past
     * the last one. */
    int32_t (*list)(void *ctx, uint32_t index, char *name, size_t name_cap, uint32_t *size);
    int32_t (*remove)(void *ctx, const char *name);

    /* The partial upload (at most one). */
    /* Opens the partial of name: keep = true keeps what a partial of that
     * name already holds and returns its length; keep = false (or none held)
     * starts it empty and returns 0. Any other partial is discarded. */
    int32_t (*up_open)(void *ctx, const char *name, bool keep);
    /* Writes len bytes at offset (<= the length held) of the partial. */
    int32_t (*up_write)(void *ctx, uint32_t offset, const uint8_t *data, size_t len);
    /* Reads the partial back (for the CRC after a gateway restart). */
    int32_t (*up_read)(void *ctx, uint32_t offset, uint8_t *buf, size_t cap);
    /* The partial becomes file name at once, replacing an older file of
     * that name (each read sees the old file or the new one; the node does
     * not commit over a file a node is reading); the partial is gone.
     * DAN_GW_FS_ENOSPC: the store is full (the partial stays). */
    int32_t (*up_commit)(void *ctx, const char *name);

    void *ctx;
    uint32_t max_size; /* largest file accepted (bytes) */
} dan_gw_file_store_t;

/* True when name (len bytes, no NUL needed) is a valid file name
 * (gw_file_name.c). */
bool dan_gw_file_name_ok(const char *name, size_t len);
/* A DroneCAN path (uavcan.protocol.file.Path bytes, not NUL-terminated):
 * the name, optionally after one leading '/'. True and name filled
 * (NUL-terminated) when the path is one; false (name untouched) for any
 * other path: "../x", "/etc/passwd", "a/b", "//x", "/.x", empty. */
bool dan_gw_file_path_name(const uint8_t *path, size_t len, char name[DAN_GW_FILE_NAME_MAX + 1u]);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_FILE_STORE_H */
