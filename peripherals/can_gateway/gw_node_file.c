/* Gateway node: the DroneCAN file server. uavcan.protocol.file.GetInfo and
 * Read answered from the configured file store (docs/PROTOCOL.md section
 * 7, "Files and firmware updates"). Stateless per request: each is
 * answered from its own offset and path, to its requester with its
 * transfer ID, so any number of nodes may read at once. An answer that
 * does not fit the bulk queue waits in file_wait (the store is read when
 * it goes out): a bootloader keeps several reads in flight, and a drop
 * would cost it a timeout. */
#include <string.h>

#include "gw_node_internal.h"

bool dan_gwn_file_service(const dan_gw_node_t *g, uint16_t dtid)
{
    return g->cfg.files != NULL && (dtid == DAN_DC_FILE_GETINFO_ID || dtid == DAN_DC_FILE_READ_ID);
}

static int16_t store_error(int32_t r)
{
    if (r == DAN_GW_FS_EFBIG) {
        return DAN_DC_FILE_TOO_LARGE; /* over what the store serves (dan-gatewayd: 2 GiB) */
    }
    return r == DAN_GW_FS_ENOENT ? (int16_t)DAN_DC_FILE_NOT_FOUND : (int16_t)DAN_DC_FILE_IO_ERROR;
}

/* The request as the wait list keeps it; q->name "" for a malformed
 * request or a path that is not a name (never handed to the store). */
static void parse_request(dan_gw_node_t *g, const dan_dc_transfer_t *t, dan_gw_node_file_req_t *q,
                          uint64_t now_us)
{
    dan_dc_file_req_t *m = &g->scratch.file_req;
    int r = t->data_type_id == DAN_DC_FILE_READ_ID
                ? dan_dc_file_read_req_decode(m, t->payload, t->payload_len)
                : dan_dc_file_getinfo_req_decode(m, t->payload, t->payload_len);
    memset(q, 0, sizeof *q);
    q->dtid = t->data_type_id;
    q->src = t->source_node;
    q->tid = t->transfer_id;
    q->prio = t->priority;
    q->offset = m->offset;
    q->at_us = now_us;
    if (r != DAN_OK || !dan_gw_file_path_name(m->path, m->path_len, q->name)) {
        q->name[0] = '\0';
    }
}

/* Queues the encoded answer (len bytes in scratch_buf) if it fits whole;
 * false (nothing queued) if not. */
static bool respond(dan_gw_node_t *g, const dan_gw_node_file_req_t *q, uint64_t sig, int len)
{
    dan_dc_transfer_t req;
    if (len < 0) {
        return true; /* cannot happen: the answers are bounded; nothing to wait for */
    }
    if (dan_dc_tx_frame_count((size_t)len) > dan_gwn_txq_free(&g->q_bulk)) {
        return false;
    }
    memset(&req, 0, sizeof req);
    req.data_type_id = q->dtid;
    req.source_node = q->src;
    req.transfer_id = q->tid;
    req.priority = q->prio;
    (void)dan_gwn_respond(g, &req, sig, g->scratch_buf, len);
    return true;
}

static bool answer_getinfo(dan_gw_node_t *g, const dan_gw_node_file_req_t *q)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_dc_file_getinfo_rsp_t r;
    int32_t size = 0;
    memset(&r, 0, sizeof r);
    if (q->name[0] == '\0') {
        r.error = DAN_DC_FILE_INVALID_VALUE;
    } else if ((size = fs->size(fs->ctx, q->name)) < 0) {
        r.error = store_error(size);
    } else {
        r.size = (uint64_t)size;
        r.entry_type = DAN_DC_FILE_FLAG_FILE | DAN_DC_FILE_FLAG_READABLE;
    }
    if (!respond(g, q, DAN_DC_FILE_GETINFO_SIGNATURE,
                 dan_dc_file_getinfo_rsp_encode(&r, g->scratch_buf, sizeof g->scratch_buf))) {
        return false;
    }
    g->stats.file_errors += r.error != 0;
    return true;
}

/* Which file a node reads, in 4 bytes per slot: the CRC-32 of its name (a
 * collision only makes a commit wait for another file's reader). */
static uint32_t name_hash(const char *name)
{
    return dan_gw_crc32(0, (const uint8_t *)name, strlen(name));
}

bool dan_gwn_file_in_use(const dan_gw_node_t *g, const char *name, uint64_t now_us)
{
    uint32_t h = name_hash(name);
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        const dan_gw_node_fw_t *f = &g->nodes[i].fw;
        if (g->nodes[i].e.node_id != 0u && (f->flags & DAN_GW_FW_READING) != 0u &&
            f->name_hash == h && f->bytes_read < f->file_size &&
            now_us - f->last_read_us < DAN_GW_NODE_READER_US) {
            return true;
        }
    }
    return false;
}

/* The node's firmware-update progress (NODE_INFO): a read from 0 starts a
 * new pass over the file. */
static void note_read(dan_gw_node_t *g, const dan_gw_node_file_req_t *q, uint32_t offset,
                      uint32_t n, uint32_t size, uint64_t now_us)
{
    dan_gw_node_slot_t *s = dan_gwn_find_node(g, q->src);
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
    s->fw.name_hash = name_hash(q->name);
}

static bool answer_read(dan_gw_node_t *g, const dan_gw_node_file_req_t *q, uint64_t now_us)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_dc_file_read_rsp_t *r = &g->scratch.file_rsp;
    int32_t size = 0, n = 0;
    memset(r, 0, sizeof *r);
    if (q->name[0] == '\0') {
        r->error = DAN_DC_FILE_INVALID_VALUE;
    } else if ((size = fs->size(fs->ctx, q->name)) < 0) {
        r->error = store_error(size);
    } else if (q->offset < (uint64_t)size) { /* at or past the end: no data, OK */
        n = fs->read(fs->ctx, q->name, (uint32_t)q->offset, r->data, DAN_DC_FILE_READ_MAX);
        if (n < 0 || n > (int32_t)DAN_DC_FILE_READ_MAX) {
            r->error = store_error(n < 0 ? n : DAN_GW_FS_EIO);
            n = 0;
        }
        r->data_len = (uint16_t)n;
    }
    if (!respond(g, q, DAN_DC_FILE_READ_SIGNATURE,
                 dan_dc_file_read_rsp_encode(r, g->scratch_buf, sizeof g->scratch_buf))) {
        return false;
    }
    if (r->error != 0) {
        g->stats.file_errors++;
    } else {
        g->stats.file_reads++;
        g->stats.file_bytes += (uint32_t)n;
        note_read(g, q, q->offset < (uint64_t)size ? (uint32_t)q->offset : (uint32_t)size,
                  (uint32_t)n, (uint32_t)size, now_us);
    }
    return true;
}

/* False when the answer must wait for room. */
static bool answer(dan_gw_node_t *g, const dan_gw_node_file_req_t *q, uint64_t now_us)
{
    return q->dtid == DAN_DC_FILE_READ_ID ? answer_read(g, q, now_us) : answer_getinfo(g, q);
}

void dan_gwn_on_file_request(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_gw_node_file_req_t q;
    if (!dan_gwn_file_service(g, t->data_type_id)) {
        return; /* no store: a node ignores the services it does not serve */
    }
    parse_request(g, t, &q, now_us);
    if (g->file_nwait == 0u && answer(g, &q, now_us)) {
        return;
    }
    if (g->file_nwait >= DAN_GW_NODE_FILE_WAIT) {
        g->stats.file_dropped++; /* the reader asks again after its timeout */
        return;
    }
    g->file_wait[g->file_nwait++] = q; /* behind the older ones: first come, first served */
}

static void drop_first(dan_gw_node_t *g)
{
    g->file_nwait--;
    memmove(&g->file_wait[0], &g->file_wait[1], g->file_nwait * sizeof g->file_wait[0]);
}

void dan_gwn_file_poll(dan_gw_node_t *g, uint64_t now_us)
{
    while (g->file_nwait > 0u) {
        const dan_gw_node_file_req_t *q = &g->file_wait[0];
        if (g->cfg.files == NULL || now_us - q->at_us > DAN_GW_NODE_FILE_WAIT_US) {
            g->stats.file_dropped++; /* its reader has given up on it */
        } else if (!answer(g, q, now_us)) {
            return;
        }
        drop_first(g);
    }
}

/* Waiting requests go out as soon as the bulk queue is empty, and are
 * dropped when stale; while it drains, the port polls anyway (frames to
 * send). */
uint64_t dan_gwn_file_next_us(const dan_gw_node_t *g, uint64_t now_us, uint64_t t)
{
    uint64_t due;
    if (g->file_nwait == 0u) {
        return t;
    }
    due = g->q_bulk.len == 0u ? now_us : g->file_wait[0].at_us + DAN_GW_NODE_FILE_WAIT_US + 1u;
    return due < t ? due : t;
}
