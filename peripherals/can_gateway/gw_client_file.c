/* CAN-over-DAN gateway client: files and firmware updates (the upload,
 * listing, removal, FW_BEGIN). See dan/can_gw/client.h. A separate file so
 * an FC image that never updates a node links none of it (--gc-sections);
 * the responses are read on demand, not in dan_gw_complete(). */
#include <string.h>

#include "gw_client_internal.h"

/* A request whose payload is a name (FILE_REMOVE). */
static size_t name_len(const char *name)
{
    size_t n = 0;
    while (name != NULL && n <= DAN_GW_FILE_NAME_MAX && name[n] != '\0') {
        n++;
    }
    return n; /* DAN_GW_FILE_NAME_MAX + 1: too long, the encoder refuses it */
}

int dan_gw_file_open(dan_gw_t *gw, const char *name, uint32_t size, bool restart, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(2u + DAN_GW_FILE_NAME_MAX + 4u + 1u)];
    dan_gw_file_open_t o;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    o.name = name;
    o.name_len = (uint8_t)name_len(name);
    o.size = size;
    o.flags = restart ? DAN_GW_FILE_RESTART : 0u;
    return dan_gwc_start(gw, DAN_GW_CODE_FILE_OPEN, NULL, buf,
                         dan_gw_msg_file_open_encode(&o, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_file_write(dan_gw_t *gw, uint32_t offset, const uint8_t *data, size_t len,
                      uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_FILE_WRITE_REQ_MAX)];
    dan_gw_file_write_t w;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    w.offset = offset;
    w.data = data;
    w.len = data != NULL ? len : 0u;
    return dan_gwc_start(gw, DAN_GW_CODE_FILE_WRITE, NULL, buf,
                         dan_gw_msg_file_write_encode(&w, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_file_commit(dan_gw_t *gw, uint32_t crc32, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(4u)];
    dan_gw_file_commit_t c;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    c.result = 0;
    c.crc32 = crc32;
    return dan_gwc_start(gw, DAN_GW_CODE_FILE_COMMIT, NULL, buf,
                         dan_gw_msg_file_commit_req_encode(&c, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_file_remove(dan_gw_t *gw, const char *name, uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(2u + DAN_GW_FILE_NAME_MAX)];
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start(gw, DAN_GW_CODE_FILE_REMOVE, NULL, buf,
                         dan_gw_msg_file_name_encode(name, name_len(name), buf, DAN_GWC_CAP(buf)),
                         sizeof buf, now_us);
}

int dan_gw_file_result(const dan_gw_t *gw, uint8_t *result, uint32_t *value)
{
    dan_reader_t r;
    uint32_t code = gw->m->resp_code;
    int rc;
    if (code == DAN_GW_CODE_FILE_OPEN || code == DAN_GW_CODE_FILE_WRITE) {
        dan_gw_file_have_t h = {DAN_GW_NONE, 0u};
        rc = dan_gwc_resp_reader(gw, code, &r);
        rc = rc != DAN_OK ? rc : dan_gw_msg_file_have_decode(&h, r.data, r.len);
        *result = h.result;
        *value = h.have;
    } else if (code == DAN_GW_CODE_FILE_COMMIT) {
        dan_gw_file_commit_t c = {DAN_GW_NONE, 0u};
        rc = dan_gwc_resp_reader(gw, code, &r);
        rc = rc != DAN_OK ? rc : dan_gw_msg_file_commit_rsp_decode(&c, r.data, r.len);
        *result = c.result;
        *value = c.crc32;
    } else {
        rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_FILE_REMOVE, &r);
        *result = rc == DAN_OK ? dan_get_u8(&r) : (uint8_t)DAN_GW_NONE;
        *value = 0;
        rc = rc != DAN_OK ? rc : dan_reader_finish(&r);
    }
    return rc;
}

DAN_GWC_PAGED(file_list, DAN_GW_CODE_FILE_LIST, dan_gw_file_list_hdr_t,
              dan_gw_msg_file_list_hdr_get, dan_gw_file_entry_t, dan_gw_msg_file_entry_get)

int dan_gw_fw_begin(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, const char *name,
                    uint64_t now_us)
{
    dan_gw_call_t c;
    dan_gwc_call_init(&c, call_id, node_id, DAN_GW_CALL_FW_BEGIN);
    c.name = name;
    c.name_len = (uint8_t)name_len(name);
    return dan_gw_node_call(gw, &c, now_us);
}
