/* DSDL message codecs. See dsdl.h; bit rules in dronecan.h. */
#include <string.h>

#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/dsdl_mgmt.h"
#include "dan/can_gw/dsdl_out.h"

/* Finishes an encode: DAN_ERR_OVERFLOW if the writer ran out of room. */
static int enc_finish(const dan_dc_bw_t *w)
{
    return dan_dc_bw_finish(w);
}

static int dec_finish(const dan_dc_br_t *r)
{
    return dan_dc_br_finish(r);
}

/* ---- NodeStatus ---- */

static void put_node_status(dan_dc_bw_t *w, const dan_dc_node_status_t *m)
{
    dan_dc_put_uint(w, 32, m->uptime_sec);
    dan_dc_put_uint(w, 2, m->health);
    dan_dc_put_uint(w, 3, m->mode);
    dan_dc_put_uint(w, 3, m->sub_mode);
    dan_dc_put_uint(w, 16, m->vendor_specific_status_code);
}

static void get_node_status(dan_dc_br_t *r, dan_dc_node_status_t *m)
{
    m->uptime_sec = (uint32_t)dan_dc_get_uint(r, 32);
    m->health = (uint8_t)dan_dc_get_uint(r, 2);
    m->mode = (uint8_t)dan_dc_get_uint(r, 3);
    m->sub_mode = (uint8_t)dan_dc_get_uint(r, 3);
    m->vendor_specific_status_code = (uint16_t)dan_dc_get_uint(r, 16);
}

int dan_dc_node_status_encode(const dan_dc_node_status_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    put_node_status(&w, m);
    return enc_finish(&w);
}

int dan_dc_node_status_decode(dan_dc_node_status_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    get_node_status(&r, m);
    return dec_finish(&r);
}

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

int dan_dc_get_node_info_rsp_encode(const dan_dc_get_node_info_rsp_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    const dan_dc_software_version_t *sw;
    const dan_dc_hardware_version_t *hw;
    if (m == NULL || m->name_len > DAN_DC_GET_NODE_INFO_NAME_MAX) {
        return DAN_ERR_ARG;
    }
    sw = &m->software_version;
    hw = &m->hardware_version;
    dan_dc_bw_init(&w, buf, cap);
    put_node_status(&w, &m->status);
    dan_dc_put_uint(&w, 8, sw->major);
    dan_dc_put_uint(&w, 8, sw->minor);
    dan_dc_put_uint(&w, 8, sw->optional_field_flags);
    dan_dc_put_uint(&w, 32, sw->vcs_commit);
    dan_dc_put_uint(&w, 64, sw->image_crc);
    dan_dc_put_uint(&w, 8, hw->major);
    dan_dc_put_uint(&w, 8, hw->minor);
    dan_dc_put_bytes(&w, hw->unique_id, sizeof hw->unique_id);
    /* Nested type: its array keeps the length prefix. */
    dan_dc_put_array_len(&w, hw->coa_len, DAN_DC_COA_MAX);
    dan_dc_put_bytes(&w, hw->certificate_of_authenticity, hw->coa_len);
    dan_dc_put_bytes(&w, (const uint8_t *)m->name, m->name_len); /* TAO */
    return enc_finish(&w);
}

int dan_dc_get_node_info_rsp_decode(dan_dc_get_node_info_rsp_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    dan_dc_software_version_t *sw;
    dan_dc_hardware_version_t *hw;
    size_t n;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    sw = &m->software_version;
    hw = &m->hardware_version;
    dan_dc_br_init(&r, buf, len);
    get_node_status(&r, &m->status);
    sw->major = (uint8_t)dan_dc_get_uint(&r, 8);
    sw->minor = (uint8_t)dan_dc_get_uint(&r, 8);
    sw->optional_field_flags = (uint8_t)dan_dc_get_uint(&r, 8);
    sw->vcs_commit = (uint32_t)dan_dc_get_uint(&r, 32);
    sw->image_crc = dan_dc_get_uint(&r, 64);
    hw->major = (uint8_t)dan_dc_get_uint(&r, 8);
    hw->minor = (uint8_t)dan_dc_get_uint(&r, 8);
    dan_dc_get_bytes(&r, hw->unique_id, sizeof hw->unique_id);
    n = dan_dc_get_array_len(&r, DAN_DC_COA_MAX);
    dan_dc_get_bytes(&r, hw->certificate_of_authenticity, n);
    hw->coa_len = (uint8_t)n;
    n = dan_dc_tao_count(&r, 8);
    if (n > DAN_DC_GET_NODE_INFO_NAME_MAX) {
        return DAN_ERR_MALFORMED;
    }
    dan_dc_get_bytes(&r, (uint8_t *)m->name, n);
    m->name_len = (uint8_t)n;
    m->name[n] = '\0';
    return dec_finish(&r);
}

/* ---- esc.RawCommand ---- */

int dan_dc_esc_raw_command_encode(const dan_dc_esc_raw_command_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    size_t i;
    if (m == NULL || m->count > DAN_DC_ESC_RAW_COMMAND_MAX_CMDS) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    for (i = 0; i < m->count; i++) {
        dan_dc_put_int(&w, 14, m->cmd[i]); /* TAO: no length prefix */
    }
    return enc_finish(&w);
}

int dan_dc_esc_raw_command_decode(dan_dc_esc_raw_command_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    size_t i, n;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    n = dan_dc_tao_count(&r, 14);
    if (n > DAN_DC_ESC_RAW_COMMAND_MAX_CMDS) {
        return DAN_ERR_MALFORMED;
    }
    for (i = 0; i < n; i++) {
        m->cmd[i] = (int16_t)dan_dc_get_int(&r, 14);
    }
    m->count = (uint8_t)n;
    return dec_finish(&r);
}

/* ---- esc.Status ---- */

int dan_dc_esc_status_encode(const dan_dc_esc_status_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 32, m->error_count);
    dan_dc_put_uint(&w, 16, m->voltage_f16);
    dan_dc_put_uint(&w, 16, m->current_f16);
    dan_dc_put_uint(&w, 16, m->temperature_f16);
    dan_dc_put_int(&w, 18, m->rpm);
    dan_dc_put_uint(&w, 7, m->power_rating_pct);
    dan_dc_put_uint(&w, 5, m->esc_index);
    return enc_finish(&w);
}

int dan_dc_esc_status_decode(dan_dc_esc_status_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    m->error_count = (uint32_t)dan_dc_get_uint(&r, 32);
    m->voltage_f16 = (uint16_t)dan_dc_get_uint(&r, 16);
    m->current_f16 = (uint16_t)dan_dc_get_uint(&r, 16);
    m->temperature_f16 = (uint16_t)dan_dc_get_uint(&r, 16);
    m->rpm = (int32_t)dan_dc_get_int(&r, 18);
    m->power_rating_pct = (uint8_t)dan_dc_get_uint(&r, 7);
    m->esc_index = (uint8_t)dan_dc_get_uint(&r, 5);
    return dec_finish(&r);
}

/* ---- esc.StatusExtended ---- */

int dan_dc_esc_status_extended_encode(const dan_dc_esc_status_extended_t *m, uint8_t *buf,
                                      size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 7, m->input_pct);
    dan_dc_put_uint(&w, 7, m->output_pct);
    dan_dc_put_int(&w, 9, m->motor_temperature_degC);
    dan_dc_put_uint(&w, 9, m->motor_angle);
    dan_dc_put_uint(&w, 19, m->status_flags);
    dan_dc_put_uint(&w, 5, m->esc_index);
    return enc_finish(&w);
}

int dan_dc_esc_status_extended_decode(dan_dc_esc_status_extended_t *m, const uint8_t *buf,
                                      size_t len)
{
    dan_dc_br_t r;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    m->input_pct = (uint8_t)dan_dc_get_uint(&r, 7);
    m->output_pct = (uint8_t)dan_dc_get_uint(&r, 7);
    m->motor_temperature_degC = (int16_t)dan_dc_get_int(&r, 9);
    m->motor_angle = (uint16_t)dan_dc_get_uint(&r, 9);
    m->status_flags = (uint32_t)dan_dc_get_uint(&r, 19);
    m->esc_index = (uint8_t)dan_dc_get_uint(&r, 5);
    return dec_finish(&r);
}

/* ---- safety.ArmingStatus ---- */

int dan_dc_arming_status_encode(const dan_dc_arming_status_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 8, m->status);
    return enc_finish(&w);
}

int dan_dc_arming_status_decode(dan_dc_arming_status_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    m->status = (uint8_t)dan_dc_get_uint(&r, 8);
    return dec_finish(&r);
}

/* ---- tunnel.Targetted ---- */

int dan_dc_tunnel_targetted_encode(const dan_dc_tunnel_targetted_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL || m->buffer_len > DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 8, m->protocol);
    dan_dc_put_uint(&w, 7, m->target_node);
    dan_dc_put_int(&w, 5, m->serial_id);
    dan_dc_put_uint(&w, 4, m->options);
    dan_dc_put_uint(&w, 24, m->baudrate);
    dan_dc_put_bytes(&w, m->buffer, m->buffer_len); /* TAO */
    return enc_finish(&w);
}

int dan_dc_tunnel_targetted_decode(dan_dc_tunnel_targetted_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    size_t n;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    m->protocol = (uint8_t)dan_dc_get_uint(&r, 8);
    m->target_node = (uint8_t)dan_dc_get_uint(&r, 7);
    m->serial_id = (int8_t)dan_dc_get_int(&r, 5);
    m->options = (uint8_t)dan_dc_get_uint(&r, 4);
    m->baudrate = (uint32_t)dan_dc_get_uint(&r, 24);
    n = dan_dc_tao_count(&r, 8);
    if (n > DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX) {
        return DAN_ERR_MALFORMED;
    }
    dan_dc_get_bytes(&r, m->buffer, n);
    m->buffer_len = (uint8_t)n;
    return dec_finish(&r);
}

/* ---- tunnel.Broadcast ---- */

int dan_dc_tunnel_broadcast_encode(const dan_dc_tunnel_broadcast_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL || m->buffer_len > DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 8, m->protocol);
    dan_dc_put_uint(&w, 8, m->channel_id);
    dan_dc_put_bytes(&w, m->buffer, m->buffer_len); /* TAO */
    return enc_finish(&w);
}

int dan_dc_tunnel_broadcast_decode(dan_dc_tunnel_broadcast_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    size_t n;
    if (m == NULL || (buf == NULL && len > 0u)) {
        return DAN_ERR_ARG;
    }
    memset(m, 0, sizeof *m);
    dan_dc_br_init(&r, buf, len);
    m->protocol = (uint8_t)dan_dc_get_uint(&r, 8);
    m->channel_id = (uint8_t)dan_dc_get_uint(&r, 8);
    n = dan_dc_tao_count(&r, 8);
    if (n > DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX) {
        return DAN_ERR_MALFORMED;
    }
    dan_dc_get_bytes(&r, m->buffer, n);
    m->buffer_len = (uint8_t)n;
    return dec_finish(&r);
}

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
