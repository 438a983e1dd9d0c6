/*
 * DSDL codec of uavcan.protocol.file.BeginFirmwareUpdate (service 40), the
 * call FW_BEGIN makes (docs/PROTOCOL.md "Files and firmware updates").
 * Layout and signature from the DSDL shipped with pydronecan
 * (dronecan/dsdl_specs/uavcan/protocol/file/40.BeginFirmwareUpdate.uavcan;
 * the signature as get_data_type_signature() prints it); vectors in
 * tests/vectors/dronecan_fw.txt come from pydronecan itself.
 *
 * Request: uint8 source_node_id (0: the caller's), Path
 * image_file_remote_path (uint8[<=200], the tail array: no length).
 * Response: uint8 error (0 OK, 1 INVALID_MODE, 2 IN_PROGRESS, 255
 * UNKNOWN), uint8[<128] optional_error_message (the tail array).
 * Conventions as dsdl.h.
 */
#ifndef DAN_CAN_GW_DSDL_FW_H
#define DAN_CAN_GW_DSDL_FW_H

#include "dan/can_gw/dsdl_file.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_DC_FW_BEGIN_ID           40u
#define DAN_DC_FW_BEGIN_SIGNATURE    0xB7D725DF72724126ull
#define DAN_DC_FW_BEGIN_REQ_MAX_SIZE (1u + DAN_DC_FILE_PATH_MAX)
#define DAN_DC_FW_BEGIN_MESSAGE_MAX  127u
#define DAN_DC_FW_BEGIN_OK           0u /* ERROR_OK */

typedef struct {
    uint8_t source_node_id;
    uint8_t path_len;
    uint8_t path[DAN_DC_FILE_PATH_MAX];
} dan_dc_fw_begin_req_t;

typedef struct {
    uint8_t error;
    uint8_t message_len;
    uint8_t message[DAN_DC_FW_BEGIN_MESSAGE_MAX];
} dan_dc_fw_begin_rsp_t;

DAN_DC_CODEC(dan_dc_fw_begin_req, dan_dc_fw_begin_req_t);
DAN_DC_CODEC(dan_dc_fw_begin_rsp, dan_dc_fw_begin_rsp_t);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_DSDL_FW_H */
