/*
 * DSDL codecs of the file services the gateway serves (docs/PROTOCOL.md
 * section 7, "Files and firmware updates"): uavcan.protocol.file.GetInfo
 * (45) and uavcan.protocol.file.Read (48). Layouts and signatures from the
 * DSDL shipped with pydronecan (dronecan/dsdl_specs/uavcan/protocol/file:
 * 45.GetInfo, 48.Read, Path, Error, EntryType; signatures printed by
 * get_data_type_signature()).
 *
 * Conventions as dsdl.h: encode returns bytes or a negative DAN_ERR_*
 * (buf NULL: size only), decode never reads outside the payload and
 * returns DAN_ERR_MALFORMED for a short payload or an array too long.
 *
 * Path is a nested type whose only field is uint8[<=200] path; as the last
 * field of a request it is the tail array (DSDL v0 applies the tail array
 * optimization through a nested type's last field, as pydronecan does):
 * no length prefix, its bytes are the rest of the payload.
 */
#ifndef DAN_CAN_GW_DSDL_FILE_H
#define DAN_CAN_GW_DSDL_FILE_H

#include "dan/can_gw/dsdl.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_DC_FILE_PATH_MAX   200u            /* Path.path bytes */
#define DAN_DC_FILE_READ_MAX   256u            /* Read response data bytes */
#define DAN_DC_FILE_OFFSET_MAX 0xFFFFFFFFFFull /* uint40 */

/* uavcan.protocol.file.Error values (int16). */
#define DAN_DC_FILE_OK            0
#define DAN_DC_FILE_NOT_FOUND     2
#define DAN_DC_FILE_IO_ERROR      5
#define DAN_DC_FILE_INVALID_VALUE 22
#define DAN_DC_FILE_TOO_LARGE     27
/* uavcan.protocol.file.EntryType flags (uint8). */
#define DAN_DC_FILE_FLAG_FILE     1u
#define DAN_DC_FILE_FLAG_READABLE 8u

/* ---- uavcan.protocol.file.GetInfo (service 45) ----
 * Request: Path path (TAO). Response: uint40 size, Error error (int16),
 * EntryType entry_type (uint8): 8 bytes. */
#define DAN_DC_FILE_GETINFO_ID           45u
#define DAN_DC_FILE_GETINFO_SIGNATURE    0x5004891EE8A27531ull
#define DAN_DC_FILE_GETINFO_REQ_MAX_SIZE 200u
#define DAN_DC_FILE_GETINFO_RSP_MAX_SIZE 8u

/* ---- uavcan.protocol.file.Read (service 48) ----
 * Request: uint40 offset, Path path (TAO). Response: Error error (int16),
 * uint8[<=256] data (TAO): fewer than 256 bytes means the end of the file. */
#define DAN_DC_FILE_READ_ID           48u
#define DAN_DC_FILE_READ_SIGNATURE    0x8DCDCA939F33F678ull
#define DAN_DC_FILE_READ_REQ_MAX_SIZE 205u
#define DAN_DC_FILE_READ_RSP_MAX_SIZE 258u

/* Both requests: GetInfo ignores offset. */
typedef struct {
    uint64_t offset;  /* uint40 (Read) */
    uint8_t path_len; /* 0..200 */
    uint8_t path[DAN_DC_FILE_PATH_MAX];
} dan_dc_file_req_t;

typedef struct {
    uint64_t size; /* uint40 */
    int16_t error; /* DAN_DC_FILE_* */
    uint8_t entry_type;
} dan_dc_file_getinfo_rsp_t;

typedef struct {
    int16_t error;
    uint16_t data_len; /* 0..256 */
    uint8_t data[DAN_DC_FILE_READ_MAX];
} dan_dc_file_read_rsp_t;

DAN_DC_CODEC(dan_dc_file_getinfo_req, dan_dc_file_req_t);
DAN_DC_CODEC(dan_dc_file_getinfo_rsp, dan_dc_file_getinfo_rsp_t);
DAN_DC_CODEC(dan_dc_file_read_req, dan_dc_file_req_t);
DAN_DC_CODEC(dan_dc_file_read_rsp, dan_dc_file_read_rsp_t);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_DSDL_FILE_H */
