/* DSDL message codecs. See dsdl.h; bit rules in dronecan.h. */

#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/dsdl_file.h"
#include "dan/can_gw/dsdl_fw.h"
#include "dan/can_gw/dsdl_mgmt.h"
#include "dan/can_gw/dsdl_out.h"

/* ---- NodeStatus ---- */

#define NS_FIELDS(type, m)                                                                    \
    DAN_DC_U(type, m uptime_sec, 32), DAN_DC_U(type, m health, 2), DAN_DC_U(type, m mode, 3), \
        DAN_DC_U(type, m sub_mode, 3), DAN_DC_U(type, m vendor_specific_status_code, 16)

static const dan_dc_field_t NODE_STATUS[] = {NS_FIELDS(dan_dc_node_status_t, )};
DAN_DC_TABLE_CODEC(dan_dc_node_status, dan_dc_node_status_t, NODE_STATUS)

/* ---- GetNodeInfo ---- */

int dan_dc_get_node_info_req_encode(uint8_t *buf, size_t cap)
{
    (void)buf;
    (void)cap;
    return 0;
}

int dan_dc_get_node_info_req_decode(const uint8_t *buf, size_t len)
{
    (void)buf;
    (void)len;
    return DAN_OK;
}

/* Status, software version and the hardware version up to unique_id. */
static const dan_dc_field_t NODE_INFO_HEAD[] = {
    NS_FIELDS(dan_dc_get_node_info_rsp_t, status.),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, software_version.major, 8),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, software_version.minor, 8),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, software_version.optional_field_flags, 8),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, software_version.vcs_commit, 32),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, software_version.image_crc, 64),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, hardware_version.major, 8),
    DAN_DC_U(dan_dc_get_node_info_rsp_t, hardware_version.minor, 8),
};
static const dan_dc_field_t NODE_INFO_NAME[] = {
    DAN_DC_TAO_STR(dan_dc_get_node_info_rsp_t, name, name_len, DAN_DC_GET_NODE_INFO_NAME_MAX),
};

int dan_dc_get_node_info_rsp_encode(const dan_dc_get_node_info_rsp_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    const dan_dc_hardware_version_t *hw;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    hw = &m->hardware_version;
    dan_dc_bw_init(&w, buf, cap);
    (void)dan_dc_put_fields(&w, m, NODE_INFO_HEAD, DAN_DC_NFIELDS(NODE_INFO_HEAD));
    dan_dc_put_bytes(&w, hw->unique_id, sizeof hw->unique_id);
    /* Nested type: its array keeps the length prefix. */
    dan_dc_put_array_len(&w, hw->coa_len, DAN_DC_COA_MAX);
    dan_dc_put_bytes(&w, hw->certificate_of_authenticity, hw->coa_len);
    if (!dan_dc_put_fields(&w, m, NODE_INFO_NAME, 1u)) {
        return DAN_ERR_ARG;
    }
    return dan_dc_bw_finish(&w);
}

int dan_dc_get_node_info_rsp_decode(dan_dc_get_node_info_rsp_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    dan_dc_hardware_version_t *hw;
    size_t n;
    if (!dan_dc_dec_begin(&r, m, sizeof *m, buf, len)) {
        return DAN_ERR_ARG;
    }
    hw = &m->hardware_version;
    (void)dan_dc_get_fields(&r, m, NODE_INFO_HEAD, DAN_DC_NFIELDS(NODE_INFO_HEAD));
    dan_dc_get_bytes(&r, hw->unique_id, sizeof hw->unique_id);
    n = dan_dc_get_array_len(&r, DAN_DC_COA_MAX);
    dan_dc_get_bytes(&r, hw->certificate_of_authenticity, n);
    hw->coa_len = (uint8_t)n;
    if (!dan_dc_get_fields(&r, m, NODE_INFO_NAME, 1u)) {
        return DAN_ERR_MALFORMED;
    }
    return dan_dc_br_finish(&r);
}

/* ---- esc.RawCommand ---- */

static void put_raw_cmd(dan_dc_bw_t *w, const void *m, size_t i)
{
    dan_dc_put_int(w, 14, ((const dan_dc_esc_raw_command_t *)m)->cmd[i]);
}

static void get_raw_cmd(dan_dc_br_t *r, void *m, size_t i)
{
    ((dan_dc_esc_raw_command_t *)m)->cmd[i] = (int16_t)dan_dc_get_int(r, 14);
}

DAN_DC_TAO_ARRAY_CODEC(dan_dc_esc_raw_command, dan_dc_esc_raw_command_t,
                       DAN_DC_ESC_RAW_COMMAND_MAX_CMDS, 14u, put_raw_cmd, get_raw_cmd)

/* ---- esc.Status, esc.StatusExtended, safety.ArmingStatus, tunnels ---- */

static const dan_dc_field_t ESC_STATUS[] = {
    DAN_DC_U(dan_dc_esc_status_t, error_count, 32),
    DAN_DC_U(dan_dc_esc_status_t, voltage_f16, 16),
    DAN_DC_U(dan_dc_esc_status_t, current_f16, 16),
    DAN_DC_U(dan_dc_esc_status_t, temperature_f16, 16),
    DAN_DC_I(dan_dc_esc_status_t, rpm, 18),
    DAN_DC_U(dan_dc_esc_status_t, power_rating_pct, 7),
    DAN_DC_U(dan_dc_esc_status_t, esc_index, 5),
};
DAN_DC_TABLE_CODEC(dan_dc_esc_status, dan_dc_esc_status_t, ESC_STATUS)

static const dan_dc_field_t ESC_STATUS_EXTENDED[] = {
    DAN_DC_U(dan_dc_esc_status_extended_t, input_pct, 7),
    DAN_DC_U(dan_dc_esc_status_extended_t, output_pct, 7),
    DAN_DC_I(dan_dc_esc_status_extended_t, motor_temperature_degC, 9),
    DAN_DC_U(dan_dc_esc_status_extended_t, motor_angle, 9),
    DAN_DC_U(dan_dc_esc_status_extended_t, status_flags, 19),
    DAN_DC_U(dan_dc_esc_status_extended_t, esc_index, 5),
};
DAN_DC_TABLE_CODEC(dan_dc_esc_status_extended, dan_dc_esc_status_extended_t, ESC_STATUS_EXTENDED)

static const dan_dc_field_t ARMING_STATUS[] = {DAN_DC_U(dan_dc_arming_status_t, status, 8)};
DAN_DC_TABLE_CODEC(dan_dc_arming_status, dan_dc_arming_status_t, ARMING_STATUS)

static const dan_dc_field_t TUNNEL_TARGETTED[] = {
    DAN_DC_U(dan_dc_tunnel_targetted_t, protocol, 8),
    DAN_DC_U(dan_dc_tunnel_targetted_t, target_node, 7),
    DAN_DC_I(dan_dc_tunnel_targetted_t, serial_id, 5),
    DAN_DC_U(dan_dc_tunnel_targetted_t, options, 4),
    DAN_DC_U(dan_dc_tunnel_targetted_t, baudrate, 24),
    DAN_DC_TAO(dan_dc_tunnel_targetted_t, buffer, buffer_len, DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX),
};
DAN_DC_TABLE_CODEC(dan_dc_tunnel_targetted, dan_dc_tunnel_targetted_t, TUNNEL_TARGETTED)

static const dan_dc_field_t TUNNEL_BROADCAST[] = {
    DAN_DC_U(dan_dc_tunnel_broadcast_t, protocol, 8),
    DAN_DC_U(dan_dc_tunnel_broadcast_t, channel_id, 8),
    DAN_DC_TAO(dan_dc_tunnel_broadcast_t, buffer, buffer_len, DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX),
};
DAN_DC_TABLE_CODEC(dan_dc_tunnel_broadcast, dan_dc_tunnel_broadcast_t, TUNNEL_BROADCAST)

/* ---- signatures ---- */

bool dan_dc_dsdl_signature(uint8_t transfer_type, uint16_t data_type_id, uint64_t *signature)
{
    uint64_t sig = 0;
    if (transfer_type == DAN_DC_TRANSFER_BROADCAST) {
        switch (data_type_id) {
        case DAN_DC_NODE_STATUS_ID: sig = DAN_DC_NODE_STATUS_SIGNATURE; break;
        case DAN_DC_ESC_RAW_COMMAND_ID: sig = DAN_DC_ESC_RAW_COMMAND_SIGNATURE; break;
        case DAN_DC_ESC_STATUS_ID: sig = DAN_DC_ESC_STATUS_SIGNATURE; break;
        case DAN_DC_ESC_STATUS_EXTENDED_ID: sig = DAN_DC_ESC_STATUS_EXTENDED_SIGNATURE; break;
        case DAN_DC_ARMING_STATUS_ID: sig = DAN_DC_ARMING_STATUS_SIGNATURE; break;
        case DAN_DC_TUNNEL_TARGETTED_ID: sig = DAN_DC_TUNNEL_TARGETTED_SIGNATURE; break;
        case DAN_DC_TUNNEL_BROADCAST_ID: sig = DAN_DC_TUNNEL_BROADCAST_SIGNATURE; break;
        case DAN_DC_ALLOCATION_ID: sig = DAN_DC_ALLOCATION_SIGNATURE; break;
        case DAN_DC_ARRAY_COMMAND_ID: sig = DAN_DC_ARRAY_COMMAND_SIGNATURE; break;
        case DAN_DC_LIGHTS_COMMAND_ID: sig = DAN_DC_LIGHTS_COMMAND_SIGNATURE; break;
        case DAN_DC_BEEP_COMMAND_ID: sig = DAN_DC_BEEP_COMMAND_SIGNATURE; break;
        case DAN_DC_SAFETY_STATE_ID: sig = DAN_DC_SAFETY_STATE_SIGNATURE; break;
        case DAN_DC_TEMPERATURE_ID: sig = DAN_DC_TEMPERATURE_SIGNATURE; break;
        default: return false;
        }
    } else if (transfer_type == DAN_DC_TRANSFER_REQUEST ||
               transfer_type == DAN_DC_TRANSFER_RESPONSE) {
        switch (data_type_id) {
        case DAN_DC_GET_NODE_INFO_ID: sig = DAN_DC_GET_NODE_INFO_SIGNATURE; break;
        case DAN_DC_PARAM_GETSET_ID: sig = DAN_DC_PARAM_GETSET_SIGNATURE; break;
        case DAN_DC_PARAM_OPCODE_ID: sig = DAN_DC_PARAM_OPCODE_SIGNATURE; break;
        case DAN_DC_RESTART_ID: sig = DAN_DC_RESTART_SIGNATURE; break;
        case DAN_DC_FILE_GETINFO_ID: sig = DAN_DC_FILE_GETINFO_SIGNATURE; break;
        case DAN_DC_FILE_READ_ID: sig = DAN_DC_FILE_READ_SIGNATURE; break;
        case DAN_DC_FW_BEGIN_ID: sig = DAN_DC_FW_BEGIN_SIGNATURE; break;
        default: return false;
        }
    } else {
        return false;
    }
    if (signature != NULL) {
        *signature = sig;
    }
    return true;
}
