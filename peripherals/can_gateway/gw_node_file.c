/* Gateway node: the DroneCAN file server. uavcan.protocol.file.GetInfo and
 * Read answered from the configured file store (docs/PROTOCOL.md section
 * 7, "Files and firmware updates"). Stateless: each request is answered
 * at once from its own offset and path, so any number of nodes may read
 * at once; the response goes to the requester with its transfer ID. */
#include <string.h>

#include "gw_node_internal.h"

bool dan_gwn_file_service(const dan_gw_node_t *g, uint16_t dtid)
{
    return g->cfg.files != NULL && (dtid == DAN_DC_FILE_GETINFO_ID || dtid == DAN_DC_FILE_READ_ID);
}

static int16_t store_error(int32_t r)
{
    return r == DAN_GW_FS_ENOENT ? (int16_t)DAN_DC_FILE_NOT_FOUND : (int16_t)DAN_DC_FILE_IO_ERROR;
}

/* The request's path as a store name; false for a malformed request or a
 * path that is not a name (never handed to the store). */
static bool request_name(dan_gw_node_t *g, const dan_dc_transfer_t *t, char *name, uint64_t *offset)
{
    dan_dc_file_req_t *q = &g->scratch.file_req;
    int r = t->data_type_id == DAN_DC_FILE_READ_ID
                ? dan_dc_file_read_req_decode(q, t->payload, t->payload_len)
                : dan_dc_file_getinfo_req_decode(q, t->payload, t->payload_len);
    *offset = q->offset;
    return r == DAN_OK && dan_gw_file_path_name(q->path, q->path_len, name);
}

static void answer_getinfo(dan_gw_node_t *g, const dan_dc_transfer_t *t, const char *name,
                           bool name_ok)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_dc_file_getinfo_rsp_t r;
    int32_t size = 0;
    memset(&r, 0, sizeof r);
    if (!name_ok) {
        r.error = DAN_DC_FILE_INVALID_VALUE;
    } else if ((size = fs->size(fs->ctx, name)) < 0) {
        r.error = store_error(size);
    } else {
        r.size = (uint64_t)size;
        r.entry_type = DAN_DC_FILE_FLAG_FILE | DAN_DC_FILE_FLAG_READABLE;
    }
    g->stats.file_errors += r.error != 0;
    (void)dan_gwn_respond(
        g, t, DAN_DC_FILE_GETINFO_SIGNATURE, g->scratch_buf,
        dan_dc_file_getinfo_rsp_encode(&r, g->scratch_buf, sizeof g->scratch_buf));
}

/* The node's firmware-update progress (NODE_INFO): a read from 0 starts a
 * new pass over the file. */
static void note_read(dan_gw_node_t *g, uint8_t src, uint32_t offset, uint32_t n, uint32_t size,
                      uint64_t now_us)
{
    dan_gw_node_slot_t *s = dan_gwn_find_node(g, src);
    if (s == NULL) {
        return;
    }
    if (offset == 0u) {
        s->fw.bytes_read = 0;
    }
    if (offset + n > s->fw.bytes_read) {
        s->fw.bytes_read = offset + n;
    }
    s->fw.file_size = size;
    s->fw.last_read_us = now_us != 0u ? now_us : 1u;
    s->fw.flags |= DAN_GW_FW_READING;
}

static void answer_read(dan_gw_node_t *g, const dan_dc_transfer_t *t, const char *name,
                        bool name_ok, uint64_t offset, uint64_t now_us)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_dc_file_read_rsp_t *r = &g->scratch.file_rsp; /* the request is decoded: reuse */
    int32_t size = 0, n = 0;
    memset(r, 0, sizeof *r);
    if (!name_ok) {
        r->error = DAN_DC_FILE_INVALID_VALUE;
    } else if ((size = fs->size(fs->ctx, name)) < 0) {
        r->error = store_error(size);
    } else if (offset < (uint64_t)size) { /* at or past the end: no data, OK */
        n = fs->read(fs->ctx, name, (uint32_t)offset, r->data, DAN_DC_FILE_READ_MAX);
        if (n < 0 || n > (int32_t)DAN_DC_FILE_READ_MAX) {
            r->error = store_error(n < 0 ? n : DAN_GW_FS_EIO);
            n = 0;
        }
        r->data_len = (uint16_t)n;
    }
    if (r->error != 0) {
        g->stats.file_errors++;
    } else {
        g->stats.file_reads++;
        g->stats.file_bytes += (uint32_t)n;
        note_read(g, t->source_node, offset < (uint64_t)size ? (uint32_t)offset : (uint32_t)size,
                  (uint32_t)n, (uint32_t)size, now_us);
    }
    (void)dan_gwn_respond(g, t, DAN_DC_FILE_READ_SIGNATURE, g->scratch_buf,
                          dan_dc_file_read_rsp_encode(r, g->scratch_buf, sizeof g->scratch_buf));
}

void dan_gwn_on_file_request(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    uint64_t offset = 0;
    bool ok;
    if (!dan_gwn_file_service(g, t->data_type_id)) {
        return; /* no store: a node ignores the services it does not serve */
    }
    ok = request_name(g, t, name, &offset);
    if (t->data_type_id == DAN_DC_FILE_READ_ID) {
        answer_read(g, t, name, ok, offset, now_us);
    } else {
        answer_getinfo(g, t, name, ok);
    }
}
