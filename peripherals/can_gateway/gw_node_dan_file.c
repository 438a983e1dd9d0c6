/* Gateway node: the DAN handlers of the file store (FILE_OPEN, FILE_WRITE,
 * FILE_COMMIT, FILE_LIST, FILE_REMOVE; docs/PROTOCOL.md "Files and firmware
 * updates"); the table is in gw_node_dan.c. The gateway holds one upload:
 * its name, declared size, the bytes held (contiguous from 0) and their
 * CRC-32, so a lost response or a killed uploader costs nothing (FILE_OPEN
 * again, go on at have) and a retried write writes nothing. The store only
 * keeps bytes; every rule is here. */
#include <string.h>

#include "gw_node_internal.h"

/* bytes read back per step to resume a kept partial (on the stack; the
 * store contract allows reads of 256) */
#define UP_READ_CHUNK 256u

/* A store's negative code as the result byte (failures counted). */
static uint8_t store_result(dan_gw_node_t *g, int32_t rc)
{
    if (rc == DAN_GW_FS_ENOENT) {
        return DAN_GW_FILE_NOT_FOUND;
    }
    if (rc == DAN_GW_FS_EFBIG) {
        return DAN_GW_FILE_TOO_LARGE;
    }
    if (rc == DAN_GW_FS_ENOSPC) {
        return DAN_GW_FILE_NO_SPACE; /* not the medium failing: remove files */
    }
    g->stats.upload_errors++;
    return DAN_GW_FILE_IO_ERROR;
}

/* The request's name checked (dan_gw_file_name_ok) and copied with a NUL:
 * the store never sees another one. */
static bool take_name(const char *name, size_t len, char out[DAN_GW_FILE_NAME_MAX + 1u])
{
    if (!dan_gw_file_name_ok(name, len)) {
        return false;
    }
    memcpy(out, name, len);
    out[len] = '\0';
    return true;
}

/* CRC-32 of the partial's first len bytes, read back: a partial the store
 * kept through a gateway restart has no CRC in RAM. */
static int32_t partial_crc(const dan_gw_file_store_t *fs, uint32_t len, uint32_t *crc)
{
    uint8_t buf[UP_READ_CHUNK];
    uint32_t off = 0;
    *crc = 0;
    while (off < len) {
        size_t want = len - off < sizeof buf ? len - off : sizeof buf;
        int32_t n = fs->up_read(fs->ctx, off, buf, want);
        if (n <= 0 || (size_t)n > want) {
            return n < 0 ? n : DAN_GW_FS_EIO; /* shorter than it said: broken */
        }
        *crc = dan_gw_crc32(*crc, buf, (size_t)n);
        off += (uint32_t)n;
    }
    return DAN_OK;
}

static void upload_start(dan_gw_node_upload_t *u, const char *name, uint32_t size, uint32_t have,
                         uint32_t crc)
{
    memset(u, 0, sizeof *u);
    u->open = true;
    strcpy(u->name, name); /* checked: <= DAN_GW_FILE_NAME_MAX */
    u->size = size;
    u->have = have;
    u->crc = crc;
}

/* FILE_OPEN: resumes the upload of this name and size (held in RAM, or a
 * partial kept by the store when RAM holds none), else starts it empty. */
static void upload_open(dan_gw_node_t *g, const dan_gw_file_open_t *o, const char *name,
                        dan_gw_file_have_t *h)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_gw_node_upload_t *u = &g->upload;
    bool resume = (o->flags & DAN_GW_FILE_RESTART) == 0u;
    uint32_t crc = 0;
    int32_t rc;
    h->have = 0;
    if (o->size > fs->max_size) {
        h->result = DAN_GW_FILE_TOO_LARGE; /* the upload held is left alone */
        return;
    }
    if (resume && u->open && u->size == o->size && strcmp(u->name, name) == 0) {
        h->result = DAN_GW_FILE_OK;
        h->have = u->have;
        return;
    }
    /* RAM holds another upload (or its size differs): that one is replaced */
    rc = fs->up_open(fs->ctx, name, resume && !u->open);
    if (rc > 0 && (uint32_t)rc <= o->size) {
        int32_t e = partial_crc(fs, (uint32_t)rc, &crc);
        rc = e < 0 ? e : rc;
    } else if (rc > 0) {
        rc = fs->up_open(fs->ctx, name, false); /* longer than this upload: not its partial */
        rc = rc > 0 ? DAN_GW_FS_EIO : rc;       /* not emptied: a broken store */
    }
    if (rc < 0) {
        memset(u, 0, sizeof *u);
        h->result = store_result(g, rc);
        return;
    }
    upload_start(u, name, o->size, (uint32_t)rc, crc);
    h->result = DAN_GW_FILE_OK;
    h->have = u->have;
}

/* FILE_WRITE: appends at have; bytes below have are a retry (nothing
 * written again); a write straddling have writes its new tail. */
static void upload_write(dan_gw_node_t *g, const dan_gw_file_write_t *w, dan_gw_file_have_t *h)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_gw_node_upload_t *u = &g->upload;
    uint64_t end = (uint64_t)w->offset + w->len;
    h->have = u->have;
    if (!u->open) {
        h->result = DAN_GW_FILE_NO_UPLOAD;
        return;
    }
    if (w->offset > u->have) {
        h->result = DAN_GW_FILE_GAP;
        return;
    }
    if (end > u->size) {
        h->result = DAN_GW_FILE_TOO_LARGE;
        return;
    }
    if (end > u->have) {
        size_t skip = u->have - w->offset;
        int32_t rc = fs->up_write(fs->ctx, u->have, w->data + skip, w->len - skip);
        if (rc < 0) {
            h->result = store_result(g, rc);
            return;
        }
        u->crc = dan_gw_crc32(u->crc, w->data + skip, w->len - skip);
        g->stats.upload_bytes += (uint32_t)(w->len - skip);
        u->have = (uint32_t)end;
    }
    h->result = DAN_GW_FILE_OK;
    h->have = u->have;
}

/* FILE_COMMIT: have = size and the CRC of the bytes held, and no node
 * reading the file it replaces; then the store makes it the file. A retry
 * after success answers OK again. */
static void upload_commit(dan_gw_node_t *g, uint32_t crc, dan_gw_file_commit_t *c, uint64_t now_us)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_gw_node_upload_t *u = &g->upload;
    int32_t rc;
    c->crc32 = u->open || u->committed ? u->crc : 0u;
    if (!u->open) {
        c->result =
            (uint8_t)(u->committed && crc == u->crc ? DAN_GW_FILE_OK : DAN_GW_FILE_NO_UPLOAD);
        return;
    }
    if (u->have != u->size) {
        c->result = DAN_GW_FILE_SHORT;
        return;
    }
    if (crc != u->crc) {
        c->result = DAN_GW_FILE_CRC; /* still open: restart it */
        return;
    }
    if (dan_gwn_file_in_use(g, u->name, now_us)) {
        c->result = DAN_GW_FILE_IN_USE; /* still open: commit when the reader is done */
        return;
    }
    rc = fs->up_commit(fs->ctx, u->name);
    if (rc < 0) {
        c->result = store_result(g, rc);
        return;
    }
    u->open = false;
    u->committed = true;
    g->stats.file_commits++;
    c->result = DAN_GW_FILE_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_file_open)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_file_open_t o;
    dan_gw_file_have_t h = {DAN_GW_FILE_NO_STORE, 0u};
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    (void)code;
    if (dan_gw_msg_file_open_decode(&o, req, len) != DAN_OK ||
        !take_name(o.name, o.name_len, name)) {
        return dan_gwn_refuse(err, "bad FILE_OPEN or file name");
    }
    if (g->cfg.files != NULL) {
        upload_open(g, &o, name, &h);
    }
    PUT_ENCODED(resp, dan_gw_msg_file_have_encode, &h);
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_file_write)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_file_write_t w;
    dan_gw_file_have_t h = {DAN_GW_FILE_NO_STORE, 0u};
    (void)code;
    if (dan_gw_msg_file_write_decode(&w, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad FILE_WRITE (1..150 bytes)");
    }
    if (g->cfg.files != NULL) {
        upload_write(g, &w, &h);
    }
    PUT_ENCODED(resp, dan_gw_msg_file_have_encode, &h);
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_file_commit)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_file_commit_t q, c = {DAN_GW_FILE_NO_STORE, 0u};
    (void)code;
    if (dan_gw_msg_file_commit_req_decode(&q, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad FILE_COMMIT");
    }
    if (g->cfg.files != NULL) {
        upload_commit(g, q.crc32, &c, now_us);
    }
    PUT_ENCODED(resp, dan_gw_msg_file_commit_rsp_encode, &c);
    return DAN_OK;
}

/* The index-th committed file into e; false past the last one (or on a
 * store failure: *rc negative). */
static bool list_entry(const dan_gw_file_store_t *fs, uint32_t index, dan_gw_file_entry_t *e,
                       int32_t *rc)
{
    memset(e, 0, sizeof *e);
    *rc = fs->list(fs->ctx, index, e->name, sizeof e->name, &e->size);
    e->name[DAN_GW_FILE_NAME_MAX] = '\0'; /* whatever the store did */
    e->name_len = (uint8_t)strlen(e->name);
    if (*rc == DAN_GW_FS_ENOENT) {
        *rc = DAN_OK;
        return false;
    }
    return *rc >= 0;
}

/* FILE_LIST: entries from index first while they fit; the header is
 * written first and completed at the end. No store: an empty list. */
DAN_GWN_HANDLER(dan_gwn_h_file_list)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    const dan_gw_file_store_t *fs = g->cfg.files;
    dan_gw_file_list_hdr_t h = {DAN_GW_NONE, 0u};
    dan_gw_file_entry_t e;
    size_t at = resp->len, room;
    uint32_t i;
    int32_t rc = DAN_OK;
    (void)code;
    if (len < 1u) {
        return dan_gwn_refuse(err, "missing first index");
    }
    dan_gw_msg_file_list_hdr_put(resp, &h);
    room = resp->cap - resp->len;
    for (i = req[0]; fs != NULL && i < DAN_GW_NONE && list_entry(fs, i, &e, &rc); i++) {
        size_t sz = dan_gw_msg_file_entry_size(&e);
        if (e.name_len == 0u) {
            continue; /* a store's empty name is no file name */
        }
        if (sz > room) {
            h.next = (uint8_t)i;
            break;
        }
        room -= sz;
        dan_gw_msg_file_entry_put(resp, &e);
        h.count++;
    }
    if (rc < 0) {
        g->stats.upload_errors++;
        *err = "file store failed";
        return DAN_ERR_IO;
    }
    resp->buf[at] = h.next;
    resp->buf[at + 1u] = h.count;
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_file_remove)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    const dan_gw_file_store_t *fs = g->cfg.files;
    const char *raw;
    uint8_t n, result = DAN_GW_FILE_NO_STORE;
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    (void)code;
    if (dan_gw_msg_file_name_decode(&raw, &n, req, len) != DAN_OK || !take_name(raw, n, name)) {
        return dan_gwn_refuse(err, "bad file name");
    }
    if (fs != NULL) {
        int32_t rc = fs->remove(fs->ctx, name);
        result = rc < 0 ? store_result(g, rc) : DAN_GW_FILE_OK;
        if (rc >= 0 && strcmp(name, g->upload.name) == 0) {
            g->upload.committed = false; /* a late COMMIT retry must not say OK */
        }
    }
    dan_put_u8(resp, result);
    return DAN_OK;
}
