/* DSDL codec of file.BeginFirmwareUpdate (see dan/can_gw/dsdl_fw.h). */
#include "dan/can_gw/dsdl_fw.h"

static const dan_dc_field_t FW_BEGIN_REQ[] = {
    DAN_DC_U(dan_dc_fw_begin_req_t, source_node_id, 8),
    DAN_DC_TAO(dan_dc_fw_begin_req_t, path, path_len, DAN_DC_FILE_PATH_MAX),
};
static const dan_dc_field_t FW_BEGIN_RSP[] = {
    DAN_DC_U(dan_dc_fw_begin_rsp_t, error, 8),
    DAN_DC_TAO(dan_dc_fw_begin_rsp_t, message, message_len, DAN_DC_FW_BEGIN_MESSAGE_MAX),
};
DAN_DC_TABLE_CODEC(dan_dc_fw_begin_req, dan_dc_fw_begin_req_t, FW_BEGIN_REQ)
DAN_DC_TABLE_CODEC(dan_dc_fw_begin_rsp, dan_dc_fw_begin_rsp_t, FW_BEGIN_RSP)
