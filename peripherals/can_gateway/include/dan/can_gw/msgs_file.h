/*
 * CAN-over-DAN gateway messages for files and firmware updates: the upload
 * into the gateway's file store (FILE_OPEN, FILE_WRITE, FILE_COMMIT), its
 * listing and removal, FW_BEGIN's call result and the CRC-32 both sides
 * compute over an upload. docs/PROTOCOL.md section 7 ("Files and firmware
 * updates") is the byte-level definition; tests/vectors/gateway_file.txt
 * pins it. Conventions as dan/can_gw/msgs.h (inner payloads; the seal is
 * added by the transport). Names travel as views into the payload (not
 * NUL-terminated); the codec checks their length (1..32), the gateway
 * their characters (dan_gw_file_name_ok()).
 */
#ifndef DAN_CAN_GW_MSGS_FILE_H
#define DAN_CAN_GW_MSGS_FILE_H

#include "dan/can_gw/file_store.h"
#include "dan/can_gw/msgs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_GW_CODE_FILE_OPEN   0x5Bu /* start or resume the upload */
#define DAN_GW_CODE_FILE_WRITE  0x5Cu /* upload bytes at an offset */
#define DAN_GW_CODE_FILE_COMMIT 0x5Du /* check the CRC, make it the file */
#define DAN_GW_CODE_FILE_LIST   0x5Eu /* committed files, paged */
#define DAN_GW_CODE_FILE_REMOVE 0x5Fu /* remove a committed file */

/* Result byte of the file messages. */
#define DAN_GW_FILE_OK        0u
#define DAN_GW_FILE_NO_UPLOAD 1u /* no upload open */
#define DAN_GW_FILE_GAP       2u /* offset beyond have: nothing written */
#define DAN_GW_FILE_TOO_LARGE 3u /* size over the store's cap, or data past the size */
#define DAN_GW_FILE_SHORT     4u /* commit with have != size */
#define DAN_GW_FILE_CRC       5u /* the bytes held have another CRC-32 */
#define DAN_GW_FILE_NOT_FOUND 6u
#define DAN_GW_FILE_IO_ERROR  7u  /* the store failed */
#define DAN_GW_FILE_NO_STORE  8u  /* the gateway has no file store */
#define DAN_GW_FILE_IN_USE    9u  /* commit over a file a node is reading: the upload stays */
#define DAN_GW_FILE_NO_SPACE  10u /* the store is full (its caps, or the medium) */

#define DAN_GW_FILE_RESTART 0x01u /* FILE_OPEN flags: start over even if resumable */

/* CRC-32 as zlib's crc32() (poly 0x04C11DB7 reflected, init and xorout
 * 0xFFFFFFFF): start with crc 0 and chain the returned value over the
 * pieces. check("123456789") = 0xCBF43926. */
uint32_t dan_gw_crc32(uint32_t crc, const uint8_t *p, size_t len);

/* ---- FILE_OPEN (0x5B) ----
 * Request: string name (1..32), u32 size, u8 flags (DAN_GW_FILE_RESTART;
 * other bits malformed). Response: u8 result, uv have (bytes held). */
typedef struct {
    const char *name; /* decode: a view into the payload */
    uint8_t name_len;
    uint32_t size;
    uint8_t flags;
} dan_gw_file_open_t;

DAN_CODEC(dan_gw_msg_file_open, dan_gw_file_open_t);

/* FILE_OPEN and FILE_WRITE responses: u8 result, uv have. */
typedef struct {
    uint8_t result; /* DAN_GW_FILE_* (later ones are passed through) */
    uint32_t have;
} dan_gw_file_have_t;

DAN_CODEC(dan_gw_msg_file_have, dan_gw_file_have_t);

/* ---- FILE_WRITE (0x5C) ----
 * Request: uv offset, array data (1..DAN_GW_FILE_CHUNK_MAX). */
#define DAN_GW_FILE_WRITE_REQ_MAX (5u + 2u + DAN_GW_FILE_CHUNK_MAX)

typedef struct {
    uint32_t offset;
    const uint8_t *data; /* decode: a view into the payload */
    size_t len;
} dan_gw_file_write_t;

DAN_CODEC(dan_gw_msg_file_write, dan_gw_file_write_t);

/* ---- FILE_COMMIT (0x5D) ----
 * Request: u32 crc32 (of the whole file). Response: u8 result, u32 crc32
 * of the bytes the gateway holds. */
typedef struct {
    uint8_t result; /* response only */
    uint32_t crc32;
} dan_gw_file_commit_t;

DAN_CODEC(dan_gw_msg_file_commit_req, dan_gw_file_commit_t);
DAN_CODEC(dan_gw_msg_file_commit_rsp, dan_gw_file_commit_t);

/* ---- FILE_LIST (0x5E) ----
 * Request: u8 first index. Response: u8 next (DAN_GW_NONE: end), u8 count,
 * then count entries of string name, uv size (name order). */
#define DAN_GW_FILE_LIST_HDR_SIZE 2u

typedef struct {
    uint8_t next;
    uint8_t count;
} dan_gw_file_list_hdr_t;

typedef struct {
    uint8_t name_len;
    char name[DAN_GW_FILE_NAME_MAX + 1u]; /* NUL-terminated */
    uint32_t size;
} dan_gw_file_entry_t;

DAN_ITEM(dan_gw_msg_file_list_hdr, dan_gw_file_list_hdr_t);
/* get: a name of 0 or more than 32 bytes is malformed. */
DAN_ITEM(dan_gw_msg_file_entry, dan_gw_file_entry_t);
/* Bytes of one entry. */
size_t dan_gw_msg_file_entry_size(const dan_gw_file_entry_t *e);

/* ---- FILE_REMOVE (0x5F) ----
 * Request: string name (1..32). Response: u8 result. */
int dan_gw_msg_file_name_encode(const char *name, size_t len, uint8_t *out, size_t cap);
/* *name is a view into the payload. */
int dan_gw_msg_file_name_decode(const char **name, uint8_t *len, const uint8_t *p, size_t len_p);

/* ---- FW_BEGIN's result (NODE_CALL op DAN_GW_CALL_FW_BEGIN, read with
 * CALL_RESULT) ----
 * u8 error (BeginFirmwareUpdate's: 0 OK, 1 INVALID_MODE, 2 IN_PROGRESS,
 * 255 UNKNOWN), string optional_error_message (<= 127). */
#define DAN_GW_FW_OK           0u
#define DAN_GW_FW_INVALID_MODE 1u
#define DAN_GW_FW_IN_PROGRESS  2u
#define DAN_GW_FW_UNKNOWN      255u
#define DAN_GW_FW_MESSAGE_MAX  127u

typedef struct {
    uint8_t error;
    uint8_t message_len;
    uint8_t message[DAN_GW_FW_MESSAGE_MAX];
} dan_gw_fw_result_t;

DAN_CODEC(dan_gw_msg_fw_result, dan_gw_fw_result_t);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_MSGS_FILE_H */
