/* CAN-over-DAN gateway bus-management messages (see dan/can_gw/msgs_mgmt.h). */
#include <string.h>

#include "dan/can_gw/msgs_mgmt.h"

/* Little-endian integers of 5, 6 and 8 bytes (uint40 magic, int48, i64). */
static void put_le(dan_writer_t *w, uint64_t v, unsigned bytes)
{
    unsigned i;
    for (i = 0; i < bytes; i++) {
        dan_put_u8(w, (uint8_t)(v >> (8u * i)));
    }
}

static uint64_t get_le(dan_reader_t *r, unsigned bytes)
{
    uint64_t v = 0;
    unsigned i;
    for (i = 0; i < bytes; i++) {
        v |= (uint64_t)dan_get_u8(r) << (8u * i);
    }
    return v;
}

/* Sign-extends the low bits of v. */
static int64_t sign_extend(uint64_t v, unsigned bits)
{
    uint64_t sign = (uint64_t)1 << (bits - 1u);
    return (int64_t)((v ^ sign) - sign);
}

/* ---- values ---- */

void dan_gw_msg_value_put(dan_writer_t *w, const dan_gw_value_t *v)
{
    uint32_t bits;
    dan_put_u8(w, v->tag);
    switch (v->tag) {
    case DAN_GW_VALUE_INTEGER: put_le(w, (uint64_t)v->integer, 8); break;
    case DAN_GW_VALUE_REAL:
        memcpy(&bits, &v->real, sizeof bits);
        dan_put_u32(w, bits);
        break;
    case DAN_GW_VALUE_BOOLEAN: dan_put_u8(w, v->boolean); break;
    case DAN_GW_VALUE_STRING: dan_put_array(w, v->string, v->string_len); break;
    default: break;
    }
}

int dan_gw_msg_value_get(dan_reader_t *r, dan_gw_value_t *v, bool numeric)
{
    uint32_t bits;
    memset(v, 0, sizeof *v);
    v->tag = dan_get_u8(r);
    switch (v->tag) {
    case DAN_GW_VALUE_EMPTY: break;
    case DAN_GW_VALUE_INTEGER: v->integer = (int64_t)get_le(r, 8); break;
    case DAN_GW_VALUE_REAL:
        bits = dan_get_u32(r);
        memcpy(&v->real, &bits, sizeof bits);
        break;
    case DAN_GW_VALUE_BOOLEAN:
        if (numeric) {
            return DAN_ERR_MALFORMED;
        }
        v->boolean = dan_get_u8(r);
        break;
    case DAN_GW_VALUE_STRING:
        if (numeric) {
            return DAN_ERR_MALFORMED;
        }
        v->string_len = (uint8_t)dan_get_array(r, v->string, sizeof v->string);
        break;
    default: return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(r);
}

/* ---- NODE_CALL ---- */

static bool call_ok(const dan_gw_call_t *c)
{
    bool named = c->op == DAN_GW_CALL_PARAM_GET_NAME || c->op == DAN_GW_CALL_PARAM_SET ||
                 c->op == DAN_GW_CALL_FW_BEGIN;
    size_t max = c->op == DAN_GW_CALL_FW_BEGIN ? DAN_GW_FILE_NAME_MAX : DAN_GW_PARAM_NAME_MAX;
    return c->node_id >= 1u && c->node_id <= DAN_DC_NODE_ID_MAX && c->op <= DAN_GW_CALL_OP_MAX &&
           c->index <= DAN_GW_PARAM_INDEX_MAX && c->magic <= 0xFFFFFFFFFFull && c->force <= 1u &&
           (!named || (c->name_len >= 1u && c->name_len <= max && c->name != NULL));
}

static void call_put(dan_writer_t *w, const dan_gw_call_t *c)
{
    dan_put_u16(w, c->call_id);
    dan_put_u8(w, c->node_id);
    dan_put_u8(w, c->op);
    switch (c->op) {
    case DAN_GW_CALL_PARAM_GET_INDEX: dan_put_uvarint(w, c->index); break;
    case DAN_GW_CALL_PARAM_GET_NAME:
    case DAN_GW_CALL_FW_BEGIN: dan_put_array(w, c->name, c->name_len); break;
    case DAN_GW_CALL_PARAM_SET:
        dan_put_array(w, c->name, c->name_len);
        dan_gw_msg_value_put(w, &c->value);
        break;
    case DAN_GW_CALL_RESTART:
        put_le(w, c->magic, 5);
        dan_put_u8(w, c->force);
        break;
    default: break;
    }
}

int dan_gw_msg_call_encode(const dan_gw_call_t *c, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    if (c == NULL || !call_ok(c) ||
        (c->op == DAN_GW_CALL_PARAM_SET &&
         (c->value.tag > DAN_GW_VALUE_STRING || (c->value.tag == DAN_GW_VALUE_STRING &&
                                                 c->value.string_len > DAN_GW_VALUE_STRING_MAX)))) {
        return DAN_ERR_ARG; /* string_len past string[]: never read beyond it */
    }
    dan_writer_init(&w, out, cap);
    call_put(&w, c);
    return dan_writer_finish(&w);
}

int dan_gw_msg_call_decode(dan_gw_call_t *c, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    const uint8_t *name = NULL;
    size_t name_len = 0;
    uint32_t index = 0;
    memset(c, 0, sizeof *c);
    dan_reader_init(&r, p, len);
    c->call_id = dan_get_u16(&r);
    c->node_id = dan_get_u8(&r);
    c->op = dan_get_u8(&r);
    switch (c->op) {
    case DAN_GW_CALL_PARAM_GET_INDEX: index = dan_get_uvarint(&r); break;
    case DAN_GW_CALL_PARAM_GET_NAME:
    case DAN_GW_CALL_FW_BEGIN: dan_get_array_view(&r, &name, &name_len); break;
    case DAN_GW_CALL_PARAM_SET:
        dan_get_array_view(&r, &name, &name_len);
        if (dan_gw_msg_value_get(&r, &c->value, false) != DAN_OK) {
            return DAN_ERR_MALFORMED;
        }
        break;
    case DAN_GW_CALL_RESTART:
        c->magic = get_le(&r, 5);
        c->force = dan_get_u8(&r);
        break;
    default: break;
    }
    if (dan_reader_finish(&r) != DAN_OK || index > DAN_GW_PARAM_INDEX_MAX ||
        name_len > DAN_GW_PARAM_NAME_MAX) {
        return DAN_ERR_MALFORMED;
    }
    c->index = (uint16_t)index;
    c->name = (const char *)name;
    c->name_len = (uint8_t)name_len;
    return call_ok(c) ? DAN_OK : DAN_ERR_MALFORMED;
}

int dan_gw_msg_call_state_encode(const dan_gw_call_state_t *s, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_u16(&w, s->call_id);
    dan_put_u8(&w, s->state);
    if (s->state == DAN_GW_CALL_DONE) {
        dan_put_uvarint(&w, s->result_len);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_call_state_decode(dan_gw_call_state_t *s, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    memset(s, 0, sizeof *s);
    dan_reader_init(&r, p, len);
    s->call_id = dan_get_u16(&r);
    s->state = dan_get_u8(&r);
    if (s->state == DAN_GW_CALL_DONE) {
        s->result_len = dan_get_uvarint(&r);
    }
    if (s->state > DAN_GW_CALL_BUSY) {
        return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(&r);
}

/* ---- CALL_RESULT ---- */

static const dan_field_t RESULT_REQ[] = {
    DAN_FIELD(dan_gw_result_t, call_id, DAN_F_U16),
    DAN_FIELD(dan_gw_result_t, offset, DAN_F_UV),
    DAN_FIELD(dan_gw_result_t, max, DAN_F_U8),
};
static const dan_field_t RESULT_RSP[] = {
    DAN_FIELD(dan_gw_result_t, call_id, DAN_F_U16),
    DAN_FIELD(dan_gw_result_t, state, DAN_F_U8),
    DAN_FIELD(dan_gw_result_t, result_len, DAN_F_UV),
    DAN_FIELD(dan_gw_result_t, offset, DAN_F_UV),
    DAN_FIELD_VIEW(dan_gw_result_t, data, len, DAN_GW_RESULT_CHUNK_MAX),
};

DAN_FIELDS_CODEC(dan_gw_msg_result_req, dan_gw_result_t, RESULT_REQ)

int dan_gw_msg_result_rsp_encode(const dan_gw_result_t *q, uint8_t *out, size_t cap)
{
    return dan_encode_fields(q, RESULT_RSP, DAN_NFIELDS(RESULT_RSP), out, cap);
}

int dan_gw_msg_result_rsp_decode(dan_gw_result_t *q, const uint8_t *p, size_t len)
{
    int rc;
    memset(q, 0, sizeof *q);
    rc = dan_decode_fields(q, RESULT_RSP, DAN_NFIELDS(RESULT_RSP), p, len);
    return rc == DAN_OK && q->state > DAN_GW_CALL_BUSY ? DAN_ERR_MALFORMED : rc;
}

/* ---- call results ---- */

int dan_gw_msg_param_encode(const dan_gw_param_t *p, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    if (p->name_len > DAN_GW_PARAM_NAME_MAX) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, p->present);
    dan_gw_msg_value_put(&w, &p->value);
    if (p->present & DAN_GW_PARAM_HAS_DEFAULT) {
        dan_gw_msg_value_put(&w, &p->default_value);
    }
    if (p->present & DAN_GW_PARAM_HAS_MAX) {
        dan_gw_msg_value_put(&w, &p->max_value);
    }
    if (p->present & DAN_GW_PARAM_HAS_MIN) {
        dan_gw_msg_value_put(&w, &p->min_value);
    }
    dan_put_array(&w, p->name, p->name_len);
    return dan_writer_finish(&w);
}

int dan_gw_msg_param_decode(dan_gw_param_t *p, const uint8_t *b, size_t len)
{
    dan_reader_t r;
    int rc;
    memset(p, 0, sizeof *p);
    dan_reader_init(&r, b, len);
    p->present = dan_get_u8(&r);
    rc = dan_gw_msg_value_get(&r, &p->value, false);
    if (rc == DAN_OK && (p->present & DAN_GW_PARAM_HAS_DEFAULT)) {
        rc = dan_gw_msg_value_get(&r, &p->default_value, false);
    }
    if (rc == DAN_OK && (p->present & DAN_GW_PARAM_HAS_MAX)) {
        rc = dan_gw_msg_value_get(&r, &p->max_value, true);
    }
    if (rc == DAN_OK && (p->present & DAN_GW_PARAM_HAS_MIN)) {
        rc = dan_gw_msg_value_get(&r, &p->min_value, true);
    }
    if (rc != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    p->name_len = (uint8_t)dan_get_array(&r, (uint8_t *)p->name, DAN_GW_PARAM_NAME_MAX);
    p->name[p->name_len] = '\0';
    return dan_reader_finish(&r);
}

int dan_gw_msg_opcode_result_encode(const dan_gw_opcode_result_t *o, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, o->ok);
    put_le(&w, (uint64_t)o->argument, 6);
    return dan_writer_finish(&w);
}

int dan_gw_msg_opcode_result_decode(dan_gw_opcode_result_t *o, const uint8_t *b, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, b, len);
    o->ok = dan_get_u8(&r);
    o->argument = len > 1u ? sign_extend(get_le(&r, 6), 48) : 0;
    return dan_reader_finish(&r);
}

/* ---- HEALTH ---- */

static const dan_field_t HEALTH[] = {
    DAN_FIELD(dan_gw_health_t, verdict, DAN_F_U8),  DAN_FIELD(dan_gw_health_t, reason, DAN_F_U8),
    DAN_FIELD(dan_gw_health_t, subject, DAN_F_U8),  DAN_FIELD(dan_gw_health_t, detail, DAN_F_U8),
    DAN_FIELD(dan_gw_health_t, problems, DAN_F_U8),
};

int dan_gw_msg_health_encode(const dan_gw_health_t *h, uint8_t *out, size_t cap)
{
    return dan_encode_fields(h, HEALTH, DAN_NFIELDS(HEALTH), out, cap);
}

/* Written out: dan_gw_complete() links it into every FC image, where the
 * table walker would cost flash. */
int dan_gw_msg_health_decode(dan_gw_health_t *h, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, p, len);
    h->verdict = dan_get_u8(&r);
    h->reason = dan_get_u8(&r);
    h->subject = dan_get_u8(&r);
    h->detail = dan_get_u8(&r);
    h->problems = dan_get_u8(&r);
    return dan_reader_finish(&r);
}

const char *dan_gw_reason_name(unsigned reason)
{
    static const char *const names[] = {"none",    "can_down",      "duplicate",    "unhealthy",
                                        "offline", "esc_telemetry", "dna_conflict", "dna_full"};
    return reason < sizeof names / sizeof names[0] ? names[reason] : NULL;
}

/* ---- DNA ---- */

static const dan_field_t DNA_HDR[] = {
    DAN_FIELD(dan_gw_dna_hdr_t, flags, DAN_F_U8),    DAN_FIELD(dan_gw_dna_hdr_t, entries, DAN_F_U8),
    DAN_FIELD(dan_gw_dna_hdr_t, capacity, DAN_F_U8), DAN_FIELD(dan_gw_dna_hdr_t, next, DAN_F_U8),
    DAN_FIELD(dan_gw_dna_hdr_t, count, DAN_F_U8),
};

DAN_FIELDS_ITEM(dan_gw_msg_dna_hdr, dan_gw_dna_hdr_t, DNA_HDR)

void dan_gw_msg_dna_entry_put(dan_writer_t *w, const dan_gw_dna_entry_t *e)
{
    dan_put_u8(w, e->node_id);
    dan_put_raw(w, e->unique_id, sizeof e->unique_id);
}

int dan_gw_msg_dna_entry_get(dan_reader_t *r, dan_gw_dna_entry_t *e)
{
    e->node_id = dan_get_u8(r);
    dan_get_raw(r, e->unique_id, sizeof e->unique_id);
    return dan_reader_finish(r);
}
