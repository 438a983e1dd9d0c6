/* CAN-over-DAN gateway file messages (see dan/can_gw/msgs_file.h). */
#include <string.h>

#include "dan/can_gw/msgs_file.h"

/* Nibble-wise (a 16-entry table): small enough for an FC's flash, fast
 * enough for a 150-byte chunk per request. */
uint32_t dan_gw_crc32(uint32_t crc, const uint8_t *p, size_t len)
{
    static const uint32_t T[16] = {
        0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u,
        0x4DB26158u, 0x5005713Cu, 0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu,
        0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu,
    };
    size_t i;
    crc = ~crc;
    for (i = 0; i < len; i++) {
        crc ^= p[i];
        crc = (crc >> 4) ^ T[crc & 0x0Fu];
        crc = (crc >> 4) ^ T[crc & 0x0Fu];
    }
    return ~crc;
}

static bool name_len_ok(size_t n)
{
    return n >= 1u && n <= DAN_GW_FILE_NAME_MAX;
}

/* ---- FILE_OPEN ---- */

int dan_gw_msg_file_open_encode(const dan_gw_file_open_t *o, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    if (o == NULL || o->name == NULL || !name_len_ok(o->name_len) ||
        (o->flags & (uint8_t)~DAN_GW_FILE_RESTART) != 0u) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_array(&w, o->name, o->name_len);
    dan_put_u32(&w, o->size);
    dan_put_u8(&w, o->flags);
    return dan_writer_finish(&w);
}

int dan_gw_msg_file_open_decode(dan_gw_file_open_t *o, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    const uint8_t *name;
    size_t n;
    memset(o, 0, sizeof *o);
    dan_reader_init(&r, p, len);
    dan_get_array_view(&r, &name, &n);
    o->size = dan_get_u32(&r);
    o->flags = dan_get_u8(&r);
    if (dan_reader_finish(&r) != DAN_OK || !name_len_ok(n) ||
        (o->flags & (uint8_t)~DAN_GW_FILE_RESTART) != 0u) {
        return DAN_ERR_MALFORMED;
    }
    o->name = (const char *)name;
    o->name_len = (uint8_t)n;
    return DAN_OK;
}

static const dan_field_t HAVE[] = {
    DAN_FIELD(dan_gw_file_have_t, result, DAN_F_U8),
    DAN_FIELD(dan_gw_file_have_t, have, DAN_F_UV),
};

DAN_FIELDS_CODEC(dan_gw_msg_file_have, dan_gw_file_have_t, HAVE)

/* ---- FILE_WRITE ---- */

static const dan_field_t WRITE[] = {
    DAN_FIELD(dan_gw_file_write_t, offset, DAN_F_UV),
    DAN_FIELD_VIEW(dan_gw_file_write_t, data, len, DAN_GW_FILE_CHUNK_MAX),
};

int dan_gw_msg_file_write_encode(const dan_gw_file_write_t *w, uint8_t *out, size_t cap)
{
    if (w == NULL || w->len == 0u) {
        return DAN_ERR_ARG; /* a write of nothing is no request */
    }
    return dan_encode_fields(w, WRITE, DAN_NFIELDS(WRITE), out, cap);
}

int dan_gw_msg_file_write_decode(dan_gw_file_write_t *w, const uint8_t *p, size_t len)
{
    int rc;
    memset(w, 0, sizeof *w);
    rc = dan_decode_fields(w, WRITE, DAN_NFIELDS(WRITE), p, len);
    return rc == DAN_OK && w->len == 0u ? DAN_ERR_MALFORMED : rc;
}

/* ---- FILE_COMMIT ---- */

static const dan_field_t COMMIT_RSP[] = {
    DAN_FIELD(dan_gw_file_commit_t, result, DAN_F_U8),
    DAN_FIELD(dan_gw_file_commit_t, crc32, DAN_F_U32),
};

int dan_gw_msg_file_commit_req_encode(const dan_gw_file_commit_t *c, uint8_t *out, size_t cap)
{
    return dan_encode_fields(c, &COMMIT_RSP[1], 1u, out, cap);
}

int dan_gw_msg_file_commit_req_decode(dan_gw_file_commit_t *c, const uint8_t *p, size_t len)
{
    memset(c, 0, sizeof *c);
    return dan_decode_fields(c, &COMMIT_RSP[1], 1u, p, len);
}

DAN_FIELDS_CODEC(dan_gw_msg_file_commit_rsp, dan_gw_file_commit_t, COMMIT_RSP)

/* ---- FILE_LIST ---- */

static const dan_field_t LIST_HDR[] = {
    DAN_FIELD(dan_gw_file_list_hdr_t, next, DAN_F_U8),
    DAN_FIELD(dan_gw_file_list_hdr_t, count, DAN_F_U8),
};
DAN_FIELDS_ITEM(dan_gw_msg_file_list_hdr, dan_gw_file_list_hdr_t, LIST_HDR)

void dan_gw_msg_file_entry_put(dan_writer_t *w, const dan_gw_file_entry_t *e)
{
    dan_put_array(w, e->name, e->name_len);
    dan_put_uvarint(w, e->size);
}

DAN_ITEM_SIZE(dan_gw_msg_file_entry, dan_gw_file_entry_t)

int dan_gw_msg_file_entry_get(dan_reader_t *r, dan_gw_file_entry_t *e)
{
    const uint8_t *name;
    size_t n;
    memset(e, 0, sizeof *e);
    dan_get_array_view(r, &name, &n);
    e->size = dan_get_uvarint(r);
    if (dan_reader_finish(r) != DAN_OK || !name_len_ok(n)) {
        return DAN_ERR_MALFORMED;
    }
    memcpy(e->name, name, n);
    e->name_len = (uint8_t)n;
    return DAN_OK;
}

/* ---- FILE_REMOVE ---- */

int dan_gw_msg_file_name_encode(const char *name, size_t len, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    if (name == NULL || !name_len_ok(len)) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_array(&w, name, len);
    return dan_writer_finish(&w);
}

int dan_gw_msg_file_name_decode(const char **name, uint8_t *len, const uint8_t *p, size_t len_p)
{
    dan_reader_t r;
    const uint8_t *v;
    size_t n;
    dan_reader_init(&r, p, len_p);
    dan_get_array_view(&r, &v, &n);
    *name = NULL;
    *len = 0;
    if (dan_reader_finish(&r) != DAN_OK || !name_len_ok(n)) {
        return DAN_ERR_MALFORMED;
    }
    *name = (const char *)v;
    *len = (uint8_t)n;
    return DAN_OK;
}

/* ---- FW_BEGIN's result ---- */

int dan_gw_msg_fw_result_encode(const dan_gw_fw_result_t *r, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    if (r->message_len > DAN_GW_FW_MESSAGE_MAX) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, r->error);
    dan_put_array(&w, r->message, r->message_len);
    return dan_writer_finish(&w);
}

int dan_gw_msg_fw_result_decode(dan_gw_fw_result_t *r, const uint8_t *p, size_t len)
{
    dan_reader_t rd;
    memset(r, 0, sizeof *r);
    dan_reader_init(&rd, p, len);
    r->error = dan_get_u8(&rd);
    r->message_len = (uint8_t)dan_get_array(&rd, r->message, sizeof r->message);
    return dan_reader_finish(&rd);
}
