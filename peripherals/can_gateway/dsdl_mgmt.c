/* DSDL codecs of the bus-management types (see dan/can_gw/dsdl_mgmt.h). */
#include <string.h>

#include "dan/can_gw/dsdl_mgmt.h"

/* ---- dynamic_node_id.Allocation ---- */

static const dan_dc_field_t ALLOCATION[] = {
    DAN_DC_U(dan_dc_allocation_t, node_id, 7),
    DAN_DC_U(dan_dc_allocation_t, first_part, 1),
    DAN_DC_TAO(dan_dc_allocation_t, uid, uid_len, DAN_DC_UNIQUE_ID_SIZE),
};

int dan_dc_allocation_encode(const dan_dc_allocation_t *m, uint8_t *buf, size_t cap)
{
    if (m != NULL && m->node_id > DAN_DC_NODE_ID_MAX) {
        return DAN_ERR_ARG;
    }
    return dan_dc_encode_table(m, ALLOCATION, DAN_DC_NFIELDS(ALLOCATION), buf, cap);
}

int dan_dc_allocation_decode(dan_dc_allocation_t *m, const uint8_t *buf, size_t len)
{
    return dan_dc_decode_table(m, sizeof *m, ALLOCATION, DAN_DC_NFIELDS(ALLOCATION), buf, len);
}

/* ---- param.Value / NumericValue ---- */

static void put_value(dan_dc_bw_t *w, const dan_dc_param_value_t *v, bool numeric)
{
    dan_dc_put_uint(w, numeric ? 2u : 3u, v->tag);
    switch (v->tag) {
    case DAN_DC_PARAM_INTEGER: dan_dc_put_int(w, 64, v->integer); break;
    case DAN_DC_PARAM_REAL: dan_dc_put_f32(w, v->real); break;
    case DAN_DC_PARAM_BOOLEAN: dan_dc_put_uint(w, 8, v->boolean); break;
    case DAN_DC_PARAM_STRING:
        dan_dc_put_array_len(w, v->string_len, DAN_DC_PARAM_STRING_MAX);
        dan_dc_put_bytes(w, v->string, v->string_len);
        break;
    default: break;
    }
}

/* False for a tag the union does not have. */
static bool value_ok(const dan_dc_param_value_t *v, bool numeric)
{
    return v->tag <= (numeric ? DAN_DC_PARAM_REAL : DAN_DC_PARAM_STRING) &&
           v->string_len <= DAN_DC_PARAM_STRING_MAX;
}

static bool get_value(dan_dc_br_t *r, dan_dc_param_value_t *v, bool numeric)
{
    memset(v, 0, sizeof *v);
    v->tag = (uint8_t)dan_dc_get_uint(r, numeric ? 2u : 3u);
    switch (v->tag) {
    case DAN_DC_PARAM_EMPTY: break;
    case DAN_DC_PARAM_INTEGER: v->integer = dan_dc_get_int(r, 64); break;
    case DAN_DC_PARAM_REAL: v->real = dan_dc_get_f32(r); break;
    case DAN_DC_PARAM_BOOLEAN:
        if (numeric) {
            return false;
        }
        v->boolean = (uint8_t)dan_dc_get_uint(r, 8);
        break;
    case DAN_DC_PARAM_STRING:
        if (numeric) {
            return false;
        }
        v->string_len = (uint8_t)dan_dc_get_array_len(r, DAN_DC_PARAM_STRING_MAX);
        dan_dc_get_bytes(r, v->string, v->string_len);
        break;
    default: return false; /* tags 5..7: not defined */
    }
    return true;
}

/* The name: the tail-optimized last field of both directions. */
static bool get_name(dan_dc_br_t *r, char *name, uint8_t *name_len)
{
    size_t n = dan_dc_tao_count(r, 8);
    if (n > DAN_DC_PARAM_NAME_MAX) {
        return false;
    }
    dan_dc_get_bytes(r, (uint8_t *)name, n);
    name[n] = '\0';
    *name_len = (uint8_t)n;
    return true;
}

/* ---- param.GetSet ---- */

int dan_dc_param_getset_req_encode(const dan_dc_param_getset_req_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL || m->index > DAN_DC_PARAM_INDEX_MAX || m->name_len > DAN_DC_PARAM_NAME_MAX ||
        !value_ok(&m->value, false)) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 13, m->index);
    put_value(&w, &m->value, false);
    dan_dc_put_bytes(&w, (const uint8_t *)m->name, m->name_len); /* TAO */
    return dan_dc_bw_finish(&w);
}

int dan_dc_param_getset_req_decode(dan_dc_param_getset_req_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    if (!dan_dc_dec_begin(&r, m, sizeof *m, buf, len)) {
        return DAN_ERR_ARG;
    }
    m->index = (uint16_t)dan_dc_get_uint(&r, 13);
    if (!get_value(&r, &m->value, false) || !get_name(&r, m->name, &m->name_len)) {
        return DAN_ERR_MALFORMED;
    }
    return dan_dc_br_finish(&r);
}

int dan_dc_param_getset_rsp_encode(const dan_dc_param_getset_rsp_t *m, uint8_t *buf, size_t cap)
{
    dan_dc_bw_t w;
    if (m == NULL || m->name_len > DAN_DC_PARAM_NAME_MAX || !value_ok(&m->value, false) ||
        !value_ok(&m->default_value, false) || !value_ok(&m->max_value, true) ||
        !value_ok(&m->min_value, true)) {
        return DAN_ERR_ARG;
    }
    dan_dc_bw_init(&w, buf, cap);
    dan_dc_put_uint(&w, 5, 0); /* void5 */
    put_value(&w, &m->value, false);
    dan_dc_put_uint(&w, 5, 0);
    put_value(&w, &m->default_value, false);
    dan_dc_put_uint(&w, 6, 0); /* void6 */
    put_value(&w, &m->max_value, true);
    dan_dc_put_uint(&w, 6, 0);
    put_value(&w, &m->min_value, true);
    dan_dc_put_bytes(&w, (const uint8_t *)m->name, m->name_len); /* TAO */
    return dan_dc_bw_finish(&w);
}

int dan_dc_param_getset_rsp_decode(dan_dc_param_getset_rsp_t *m, const uint8_t *buf, size_t len)
{
    dan_dc_br_t r;
    bool ok;
    if (!dan_dc_dec_begin(&r, m, sizeof *m, buf, len)) {
        return DAN_ERR_ARG;
    }
    (void)dan_dc_get_uint(&r, 5);
    ok = get_value(&r, &m->value, false);
    (void)dan_dc_get_uint(&r, 5);
    ok = ok && get_value(&r, &m->default_value, false);
    (void)dan_dc_get_uint(&r, 6);
    ok = ok && get_value(&r, &m->max_value, true);
    (void)dan_dc_get_uint(&r, 6);
    ok = ok && get_value(&r, &m->min_value, true);
    if (!ok || !get_name(&r, m->name, &m->name_len)) {
        return DAN_ERR_MALFORMED;
    }
    return dan_dc_br_finish(&r);
}

/* ---- param.ExecuteOpcode ---- */

static const dan_dc_field_t OPCODE_REQ[] = {
    DAN_DC_U(dan_dc_param_opcode_t, opcode, 8),
    DAN_DC_I(dan_dc_param_opcode_t, argument, 48),
};
static const dan_dc_field_t OPCODE_RSP[] = {
    DAN_DC_I(dan_dc_param_opcode_t, argument, 48),
    DAN_DC_U(dan_dc_param_opcode_t, ok, 1),
};
DAN_DC_TABLE_CODEC(dan_dc_param_opcode_req, dan_dc_param_opcode_t, OPCODE_REQ)
DAN_DC_TABLE_CODEC(dan_dc_param_opcode_rsp, dan_dc_param_opcode_t, OPCODE_RSP)

/* ---- RestartNode ---- */

/* One value each way: tables over the value itself. */
static const dan_dc_field_t RESTART_REQ[] = {{0u, sizeof(uint64_t), 40u, DAN_DC_F_UINT}};
static const dan_dc_field_t RESTART_RSP[] = {{0u, sizeof(bool), 1u, DAN_DC_F_UINT}};

int dan_dc_restart_req_encode(uint64_t magic, uint8_t *buf, size_t cap)
{
    if (magic > DAN_DC_RESTART_MAGIC_MAX) {
        return DAN_ERR_ARG;
    }
    return dan_dc_encode_table(&magic, RESTART_REQ, 1u, buf, cap);
}

int dan_dc_restart_req_decode(uint64_t *magic, const uint8_t *buf, size_t len)
{
    return dan_dc_decode_table(magic, sizeof *magic, RESTART_REQ, 1u, buf, len);
}

int dan_dc_restart_rsp_encode(bool ok, uint8_t *buf, size_t cap)
{
    return dan_dc_encode_table(&ok, RESTART_RSP, 1u, buf, cap);
}

int dan_dc_restart_rsp_decode(bool *ok, const uint8_t *buf, size_t len)
{
    return dan_dc_decode_table(ok, sizeof *ok, RESTART_RSP, 1u, buf, len);
}
