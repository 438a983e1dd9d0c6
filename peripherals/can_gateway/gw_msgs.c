/* CAN-over-DAN gateway payload codec (docs/PROTOCOL.md section 7). */
#include <stddef.h>
#include <string.h>

#include "dan/codes.h"
#include "dan/can_gw/msgs.h"
#include "dan/can_gw/msgs_fast.h"

/* ---- ESC command ---- */

int dan_gw_msg_esc_cmd_encode(const int16_t *values, size_t n, uint8_t *out, size_t cap)
{
    int len = dan_gw_msg_esc_fast_encode(values, n, out != NULL ? out + 1 : NULL,
                                         cap > 0u ? cap - 1u : 0u);
    if (len >= 0 && out != NULL) {
        out[0] = (uint8_t)n;
    }
    return len >= 0 ? len + 1 : len;
}

/* The padding bits are not checked here (ESC_FAST checks them): ESC_CMD
 * decoders never did, and senders that set them must keep working. */
int dan_gw_msg_esc_cmd_decode(const uint8_t *p, size_t len, int16_t *values, size_t *n)
{
    size_t cnt;
    if (p == NULL || values == NULL || n == NULL) {
        return DAN_ERR_ARG;
    }
    if (len < 1u) {
        return DAN_ERR_MALFORMED;
    }
    cnt = p[0];
    if (cnt == 0u || cnt > DAN_GW_ESC_MAX || len < DAN_GW_ESC_CMD_SIZE(cnt)) {
        return DAN_ERR_MALFORMED;
    }
    (void)dan_gw_msg_esc_unpack(p + 1, cnt, values);
    *n = cnt;
    return DAN_OK;
}

/* ---- records as field lists ----
 *
 * The telemetry record and the CONFIG response are lists of fields, each
 * one op: the member's offset, how it goes on the wire, and its group (a
 * bit of the FLAGS or MASK field before it: only when that has it; FLAGS
 * keeps the DAN_GW_TELEM_* bits only). One list drives both directions
 * (no encode/decode pair to drift apart). Members: 1 byte for U8, FLAGS
 * and MASK, 2 for U16, 4 for the rest. */
enum { OP_U8, OP_FLAGS, OP_MASK, OP_U16, OP_UV, OP_U24, OP_I24 };
typedef struct {
    uint8_t offset;
    uint8_t kind_group; /* kind | group << 3 */
} gw_op_t;
#define OP(type, member, kind, group)                                      \
    {                                                                      \
        (uint8_t) offsetof(type, member), (uint8_t)((kind) | (group) << 3) \
    }
#define NOPS(ops) (sizeof(ops) / sizeof((ops)[0]))

static const gw_op_t TELEM_OPS[] = {
    OP(dan_gw_telem_t, esc_index, OP_U8, 0),
    OP(dan_gw_telem_t, node_id, OP_U8, 0),
    OP(dan_gw_telem_t, flags, OP_FLAGS, 0),
    OP(dan_gw_telem_t, age_ms, OP_UV, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, voltage_f16, OP_U16, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, current_f16, OP_U16, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, temperature_f16, OP_U16, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, rpm, OP_I24, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, power_pct, OP_U8, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, error_count, OP_UV, DAN_GW_TELEM_STATUS),
    OP(dan_gw_telem_t, ext_age_ms, OP_UV, DAN_GW_TELEM_EXT),
    OP(dan_gw_telem_t, input_pct, OP_U8, DAN_GW_TELEM_EXT),
    OP(dan_gw_telem_t, output_pct, OP_U8, DAN_GW_TELEM_EXT),
    OP(dan_gw_telem_t, motor_temp_c, OP_U16, DAN_GW_TELEM_EXT),
    OP(dan_gw_telem_t, motor_angle, OP_U16, DAN_GW_TELEM_EXT),
    OP(dan_gw_telem_t, status_flags, OP_U24, DAN_GW_TELEM_EXT),
    OP(dan_gw_telem_t, dev_age_ms, OP_UV, DAN_GW_TELEM_DEVICE),
    OP(dan_gw_telem_t, dev_temp_f16, OP_U16, DAN_GW_TELEM_DEVICE),
    OP(dan_gw_telem_t, dev_flags, OP_U8, DAN_GW_TELEM_DEVICE),
};

static const gw_op_t TELEM_HDR_OPS[] = {
    OP(dan_gw_telem_hdr_t, gw_flags, OP_U8, 0),
    OP(dan_gw_telem_hdr_t, aux, OP_U8, 0),
    OP(dan_gw_telem_hdr_t, count, OP_U8, 0),
};

static const gw_op_t CONFIG_REQ_OPS[] = {
    OP(dan_gw_config_t, set_mask, OP_MASK, 0),
    OP(dan_gw_config_t, esc_timeout_ms, OP_UV, DAN_GW_CFG_ESC_TIMEOUT),
    OP(dan_gw_config_t, arming_rate_hz, OP_UV, DAN_GW_CFG_ARMING_RATE),
    OP(dan_gw_config_t, telem_timeout_ms, OP_UV, DAN_GW_CFG_TELEM_TIMEOUT),
    OP(dan_gw_config_t, dna, OP_U8, DAN_GW_CFG_DNA),
};

/* The last two are appended fields. */
static const gw_op_t CONFIG_RSP_OPS[] = {
    OP(dan_gw_config_t, node_id, OP_U8, 0),          OP(dan_gw_config_t, esc_timeout_ms, OP_UV, 0),
    OP(dan_gw_config_t, arming_rate_hz, OP_UV, 0),   OP(dan_gw_config_t, gw_flags, OP_U8, 0),
    OP(dan_gw_config_t, telem_timeout_ms, OP_UV, 0), OP(dan_gw_config_t, dna, OP_U8, 0),
};

static void ops_put(dan_writer_t *w, const void *s, const gw_op_t *ops, size_t n)
{
    const uint8_t *base = (const uint8_t *)s;
    unsigned flags = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        unsigned kind = ops[i].kind_group & 7u, group = ops[i].kind_group >> 3;
        const uint8_t *m = base + ops[i].offset;
        uint32_t v = m[0];
        uint16_t v16;
        if ((flags & group) != group) {
            continue;
        }
        if (kind == OP_U16) {
            memcpy(&v16, m, 2u);
            v = v16;
        } else if (kind > OP_U16) {
            memcpy(&v, m, 4u);
        }
        if (kind == OP_FLAGS) {
            v &= DAN_GW_TELEM_ALL;
        }
        if (kind == OP_FLAGS || kind == OP_MASK) {
            flags = v;
        }
        if (kind == OP_UV) {
            dan_put_uvarint(w, v);
        } else if (kind == OP_U16) {
            dan_put_u16(w, (uint16_t)v);
        } else {
            dan_put_u8(w, (uint8_t)(v & 0xFFu));
            if (kind >= OP_U24) { /* low byte first, then the u16 of the rest */
                dan_put_u16(w, (uint16_t)((v >> 8) & 0xFFFFu));
            }
        }
    }
}

static int ops_get(dan_reader_t *r, void *s, const gw_op_t *ops, size_t n)
{
    uint8_t *base = (uint8_t *)s;
    unsigned flags = 0;
    size_t i;
    for (i = 0; i < n; i++) {
        unsigned kind = ops[i].kind_group & 7u, group = ops[i].kind_group >> 3;
        uint8_t *m = base + ops[i].offset;
        uint32_t v;
        uint16_t v16;
        if ((flags & group) != group) {
            continue;
        }
        if (kind == OP_UV) {
            v = dan_get_uvarint(r);
        } else if (kind == OP_U16) {
            v = dan_get_u16(r);
        } else {
            v = dan_get_u8(r);
            if (kind >= OP_U24) {
                v |= (uint32_t)dan_get_u16(r) << 8;
            }
        }
        if (kind == OP_I24) {
            v = (v ^ 0x800000u) - 0x800000u; /* sign-extended, as the int32_t holds it */
        }
        if (kind == OP_FLAGS) {
            v &= DAN_GW_TELEM_ALL;
        }
        if (kind == OP_FLAGS || kind == OP_MASK) {
            flags = v;
        }
        if (kind < OP_U16) {
            m[0] = (uint8_t)v;
        } else if (kind == OP_U16) {
            v16 = (uint16_t)v;
            memcpy(m, &v16, 2u);
        } else {
            memcpy(m, &v, 4u);
        }
    }
    return dan_reader_finish(r);
}

/* ---- telemetry ---- */

/* Written out (not a field table): it is on the FC's ESC path, where the
 * table walker would cost flash. */
void dan_gw_msg_telem_hdr_put(dan_writer_t *w, const dan_gw_telem_hdr_t *h)
{
    ops_put(w, h, TELEM_HDR_OPS, NOPS(TELEM_HDR_OPS));
}

/* The decoders on the FC's ESC path are written out: the op walker is
 * slower there (make bench), and no smaller. */
int dan_gw_msg_telem_hdr_get(dan_reader_t *r, dan_gw_telem_hdr_t *h)
{
    h->gw_flags = dan_get_u8(r);
    h->aux = dan_get_u8(r);
    h->count = dan_get_u8(r);
    return dan_reader_finish(r);
}

void dan_gw_msg_telem_put(dan_writer_t *w, const dan_gw_telem_t *t)
{
    ops_put(w, t, TELEM_OPS, NOPS(TELEM_OPS));
}

DAN_ITEM_SIZE(dan_gw_msg_telem, dan_gw_telem_t)

static uint32_t get_u24(dan_reader_t *r)
{
    uint32_t lo = dan_get_u8(r);
    return lo | ((uint32_t)dan_get_u16(r) << 8);
}

/* TELEM_OPS, written out (see dan_gw_msg_telem_hdr_get()). */
int dan_gw_msg_telem_get(dan_reader_t *r, dan_gw_telem_t *t)
{
    memset(t, 0, sizeof *t);
    t->esc_index = dan_get_u8(r);
    t->node_id = dan_get_u8(r);
    t->flags = (uint8_t)(dan_get_u8(r) & DAN_GW_TELEM_ALL);
    if (t->flags & DAN_GW_TELEM_STATUS) {
        t->age_ms = dan_get_uvarint(r);
        t->voltage_f16 = dan_get_u16(r);
        t->current_f16 = dan_get_u16(r);
        t->temperature_f16 = dan_get_u16(r);
        t->rpm = (int32_t)(get_u24(r) ^ 0x800000u) - 0x800000; /* int24 */
        t->power_pct = dan_get_u8(r);
        t->error_count = dan_get_uvarint(r);
    }
    if (t->flags & DAN_GW_TELEM_EXT) {
        t->ext_age_ms = dan_get_uvarint(r);
        t->input_pct = dan_get_u8(r);
        t->output_pct = dan_get_u8(r);
        t->motor_temp_c = (int16_t)dan_get_u16(r);
        t->motor_angle = dan_get_u16(r);
        t->status_flags = get_u24(r);
    }
    if (t->flags & DAN_GW_TELEM_DEVICE) {
        t->dev_age_ms = dan_get_uvarint(r);
        t->dev_temp_f16 = dan_get_u16(r);
        t->dev_flags = dan_get_u8(r);
    }
    return dan_reader_finish(r);
}

/* ---- config ---- */

int dan_gw_msg_config_req_encode(const dan_gw_config_t *c, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    unsigned i;
    /* Written out, not ops_put(): the FC links this encoder and no other
     * ops_put() user (the field walker would cost it flash). */
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, c->set_mask);
    for (i = 1; i < NOPS(CONFIG_REQ_OPS) - 1u; i++) { /* the uvarints, in mask bit order */
        if (c->set_mask & (CONFIG_REQ_OPS[i].kind_group >> 3)) {
            uint32_t v;
            memcpy(&v, (const uint8_t *)c + CONFIG_REQ_OPS[i].offset, 4u);
            dan_put_uvarint(&w, v);
        }
    }
    if (c->set_mask & DAN_GW_CFG_DNA) {
        dan_put_u8(&w, c->dna);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_config_req_decode(dan_gw_config_t *c, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    memset(c, 0, sizeof *c);
    if (len == 0u) {
        return DAN_OK;
    }
    dan_reader_init(&r, p, len);
    if (ops_get(&r, c, CONFIG_REQ_OPS, NOPS(CONFIG_REQ_OPS)) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    /* the values given (the others are 0) in their ranges */
    if (((c->set_mask & DAN_GW_CFG_ESC_TIMEOUT) && (c->esc_timeout_ms < DAN_GW_ESC_TIMEOUT_MIN ||
                                                    c->esc_timeout_ms > DAN_GW_ESC_TIMEOUT_MAX)) ||
        ((c->set_mask & DAN_GW_CFG_ARMING_RATE) && (c->arming_rate_hz < DAN_GW_ARMING_RATE_MIN ||
                                                    c->arming_rate_hz > DAN_GW_ARMING_RATE_MAX)) ||
        (c->telem_timeout_ms != 0u && (c->telem_timeout_ms < DAN_GW_TELEM_TIMEOUT_MIN ||
                                       c->telem_timeout_ms > DAN_GW_TELEM_TIMEOUT_MAX)) ||
        c->dna > 1u) {
        return DAN_ERR_MALFORMED;
    }
    return DAN_OK;
}

int dan_gw_msg_config_rsp_encode(const dan_gw_config_t *c, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    ops_put(&w, c, CONFIG_RSP_OPS, NOPS(CONFIG_RSP_OPS));
    return dan_writer_finish(&w);
}

/* The last two fields are appended ones: a response without them decodes
 * with zeros. */
int dan_gw_msg_config_rsp_decode(dan_gw_config_t *c, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    memset(c, 0, sizeof *c);
    /* CONFIG_RSP_OPS, written out: the FC links no other ops_get() user */
    dan_reader_init(&r, p, len);
    c->node_id = dan_get_u8(&r);
    c->esc_timeout_ms = dan_get_uvarint(&r);
    c->arming_rate_hz = dan_get_uvarint(&r);
    c->gw_flags = dan_get_u8(&r);
    if (dan_reader_remaining(&r) > 0u) { /* fields a gateway of this version appends */
        c->telem_timeout_ms = dan_get_uvarint(&r);
        c->dna = dan_get_u8(&r);
    }
    return dan_reader_finish(&r);
}

/* ---- stats ---- */

int dan_gw_msg_stats_encode(const uint32_t *v, size_t n, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    size_t i;
    if (n > 255u) {
        return DAN_ERR_ARG;
    }
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, (uint8_t)n);
    for (i = 0; i < n; i++) {
        dan_put_uvarint(&w, v[i]);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_stats_decode(uint32_t *v, size_t cap, size_t *n, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    size_t i, cnt;
    dan_reader_init(&r, p, len);
    cnt = dan_get_u8(&r);
    for (i = 0; i < cap; i++) {
        v[i] = 0;
    }
    for (i = 0; i < cnt; i++) {
        uint32_t x = dan_get_uvarint(&r);
        if (i < cap) {
            v[i] = x;
        }
    }
    *n = cnt;
    return dan_reader_finish(&r);
}

/* ---- nodes ---- */

static const dan_field_t NODES_HDR[] = {
    DAN_FIELD(dan_gw_nodes_hdr_t, next, DAN_F_U8),
    DAN_FIELD(dan_gw_nodes_hdr_t, count, DAN_F_U8),
};

DAN_FIELDS_ITEM(dan_gw_msg_nodes_hdr, dan_gw_nodes_hdr_t, NODES_HDR)

void dan_gw_msg_node_put(dan_writer_t *w, const dan_gw_node_entry_t *n)
{
    dan_put_u8(w, n->node_id);
    dan_put_u8(w, (uint8_t)((n->health & 3u) | ((n->mode & 7u) << 2) | ((n->sub_mode & 7u) << 5)));
    dan_put_uvarint(w, n->uptime_sec);
    dan_put_u16(w, n->vendor_status);
    dan_put_uvarint(w, n->age_ms);
    dan_put_u8(w, n->info_state);
}

DAN_ITEM_SIZE(dan_gw_msg_node, dan_gw_node_entry_t)

int dan_gw_msg_node_get(dan_reader_t *r, dan_gw_node_entry_t *n)
{
    uint8_t b;
    n->node_id = dan_get_u8(r);
    b = dan_get_u8(r);
    n->health = (uint8_t)(b & 3u);
    n->mode = (uint8_t)((b >> 2) & 7u);
    n->sub_mode = (uint8_t)((b >> 5) & 7u);
    n->uptime_sec = dan_get_uvarint(r);
    n->vendor_status = dan_get_u16(r);
    n->age_ms = dan_get_uvarint(r);
    n->info_state = dan_get_u8(r);
    return dan_reader_finish(r);
}

int dan_gw_msg_node_info_encode(const dan_gw_node_info_t *i, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_u8(&w, i->node_id);
    dan_put_u8(&w, i->info_state);
    if (i->info_state == DAN_GW_INFO_VALID) {
        dan_put_u8(&w, i->sw_major);
        dan_put_u8(&w, i->sw_minor);
        dan_put_u8(&w, i->sw_flags);
        dan_put_u32(&w, i->vcs_commit);
        dan_put_u8(&w, i->hw_major);
        dan_put_u8(&w, i->hw_minor);
        dan_put_raw(&w, i->unique_id, sizeof i->unique_id);
        dan_put_string(&w, i->name);
    }
    if (i->follow) {
        dan_put_u8(&w, i->status);
        dan_put_u8(&w, i->file_flags);
        dan_put_uvarint(&w, i->bytes_read);
        dan_put_uvarint(&w, i->file_size);
        dan_put_u32(&w, i->since_read_ms);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_node_info_decode(dan_gw_node_info_t *i, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    memset(i, 0, sizeof *i);
    dan_reader_init(&r, p, len);
    i->node_id = dan_get_u8(&r);
    i->info_state = dan_get_u8(&r);
    if (i->info_state == DAN_GW_INFO_VALID) {
        i->sw_major = dan_get_u8(&r);
        i->sw_minor = dan_get_u8(&r);
        i->sw_flags = dan_get_u8(&r);
        i->vcs_commit = dan_get_u32(&r);
        i->hw_major = dan_get_u8(&r);
        i->hw_minor = dan_get_u8(&r);
        dan_get_raw(&r, i->unique_id, sizeof i->unique_id);
        (void)dan_get_string(&r, i->name, sizeof i->name);
    }
    i->follow = dan_reader_finish(&r) == DAN_OK && dan_reader_remaining(&r) > 0u;
    if (i->follow) {
        i->status = dan_get_u8(&r);
        i->file_flags = dan_get_u8(&r);
        i->bytes_read = dan_get_uvarint(&r);
        i->file_size = dan_get_uvarint(&r);
        i->since_read_ms = dan_get_u32(&r);
    }
    return dan_reader_finish(&r);
}

/* ---- tunnels ---- */

static const dan_field_t TUN_OPEN[] = {
    DAN_FIELD(dan_gw_tun_open_t, port, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_open_t, mode, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_open_t, protocol, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_open_t, target, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_open_t, serial_id, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_open_t, options, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_open_t, baud, DAN_F_UV),
};

DAN_FIELDS_CODEC(dan_gw_msg_tun_open, dan_gw_tun_open_t, TUN_OPEN)

static const dan_field_t TUN_XFER_REQ[] = {
    DAN_FIELD(dan_gw_tun_xfer_t, port, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_xfer_t, wr_offset, DAN_F_UV),
    DAN_FIELD(dan_gw_tun_xfer_t, rd_offset, DAN_F_UV),
    DAN_FIELD(dan_gw_tun_xfer_t, rd_max, DAN_F_UV),
    DAN_FIELD_VIEW(dan_gw_tun_xfer_t, data, len, DAN_GW_TUN_CHUNK_MAX),
};
static const dan_field_t TUN_XFER_RSP[] = {
    DAN_FIELD(dan_gw_tun_xfer_t, port, DAN_F_U8),
    DAN_FIELD(dan_gw_tun_xfer_t, wr_offset, DAN_F_UV),
    DAN_FIELD(dan_gw_tun_xfer_t, wr_space, DAN_F_UV),
    DAN_FIELD(dan_gw_tun_xfer_t, rd_offset, DAN_F_UV),
    DAN_FIELD(dan_gw_tun_xfer_t, rd_dropped, DAN_F_UV),
    DAN_FIELD_VIEW(dan_gw_tun_xfer_t, data, len, DAN_GW_TUN_CHUNK_MAX),
};

DAN_FIELDS_CODEC(dan_gw_msg_tun_xfer_req, dan_gw_tun_xfer_t, TUN_XFER_REQ)

int dan_gw_msg_tun_xfer_rsp_encode(const dan_gw_tun_xfer_t *x, uint8_t *out, size_t cap)
{
    return dan_encode_fields(x, TUN_XFER_RSP, DAN_NFIELDS(TUN_XFER_RSP), out, cap);
}

/* Written out: dan_gw_complete() links it into every FC image, where the
 * table walker would cost flash. */
int dan_gw_msg_tun_xfer_rsp_decode(dan_gw_tun_xfer_t *x, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    memset(x, 0, sizeof *x);
    dan_reader_init(&r, p, len);
    x->port = dan_get_u8(&r);
    x->wr_offset = dan_get_uvarint(&r);
    x->wr_space = dan_get_uvarint(&r);
    x->rd_offset = dan_get_uvarint(&r);
    x->rd_dropped = dan_get_uvarint(&r);
    dan_get_array_view(&r, &x->data, &x->len);
    if (x->len > DAN_GW_TUN_CHUNK_MAX) {
        return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(&r);
}

/* ---- raw CAN ---- */

void dan_gw_msg_can_frame_put(dan_writer_t *w, const dan_can_frame_t *f)
{
    uint32_t id = f->id & ((f->flags & DAN_CAN_EXT) ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK);
    uint8_t dlc = f->dlc > 8u ? 8u : f->dlc;
    if (f->flags & DAN_CAN_EXT) {
        id |= DAN_GW_CAN_ID_EXT;
    }
    if (f->flags & DAN_CAN_RTR) {
        id |= DAN_GW_CAN_ID_RTR;
    }
    if (f->flags & DAN_CAN_OWN) {
        id |= DAN_GW_CAN_ID_OWN;
    }
    dan_put_u32(w, id);
    dan_put_u8(w, dlc);
    if (!(f->flags & DAN_CAN_RTR)) {
        dan_put_raw(w, f->data, dlc);
    }
}

DAN_ITEM_SIZE(dan_gw_msg_can_frame, dan_can_frame_t)

int dan_gw_msg_can_frame_get(dan_reader_t *r, dan_can_frame_t *f)
{
    uint32_t id;
    memset(f, 0, sizeof *f);
    id = dan_get_u32(r);
    f->dlc = dan_get_u8(r);
    f->flags = (uint8_t)(((id & DAN_GW_CAN_ID_EXT) ? DAN_CAN_EXT : 0u) |
                         ((id & DAN_GW_CAN_ID_RTR) ? DAN_CAN_RTR : 0u) |
                         ((id & DAN_GW_CAN_ID_OWN) ? DAN_CAN_OWN : 0u));
    f->id = id & DAN_CAN_EFF_MASK;
    if (f->dlc > 8u || (!(f->flags & DAN_CAN_EXT) && f->id > DAN_CAN_SFF_MASK)) {
        return DAN_ERR_MALFORMED;
    }
    if (!(f->flags & DAN_CAN_RTR)) {
        dan_get_raw(r, f->data, f->dlc);
    }
    return dan_reader_finish(r);
}

void dan_gw_msg_can_send_req_put(dan_writer_t *w, const dan_gw_can_send_t *s)
{
    dan_put_u8(w, s->seq);
    dan_put_u8(w, s->count);
}

int dan_gw_msg_can_send_req_get(dan_reader_t *r, dan_gw_can_send_t *s)
{
    s->seq = dan_get_u8(r);
    s->count = dan_get_u8(r);
    s->queue_free = 0;
    if (s->count > DAN_GW_CAN_FRAMES_MAX) {
        return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(r);
}

static const dan_field_t CAN_SEND_RSP[] = {
    DAN_FIELD(dan_gw_can_send_t, seq, DAN_F_U8),
    DAN_FIELD(dan_gw_can_send_t, count, DAN_F_U8),
    DAN_FIELD(dan_gw_can_send_t, queue_free, DAN_F_UV),
};

int dan_gw_msg_can_send_rsp_encode(const dan_gw_can_send_t *s, uint8_t *out, size_t cap)
{
    return dan_encode_fields(s, CAN_SEND_RSP, DAN_NFIELDS(CAN_SEND_RSP), out, cap);
}

/* Written out: dan_gw_complete() links it into every FC image, where the
 * table walker would cost flash. */
int dan_gw_msg_can_send_rsp_decode(dan_gw_can_send_t *s, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, p, len);
    s->seq = dan_get_u8(&r);
    s->count = dan_get_u8(&r);
    s->queue_free = dan_get_uvarint(&r);
    return dan_reader_finish(&r);
}

int dan_gw_msg_can_recv_req_encode(const dan_gw_can_recv_t *q, uint8_t *out, size_t cap)
{
    dan_writer_t w;
    dan_writer_init(&w, out, cap);
    dan_put_uvarint(&w, q->seq);
    dan_put_u8(&w, q->count);
    if (q->opts != 0u) {
        dan_put_u8(&w, q->opts);
    }
    return dan_writer_finish(&w);
}

int dan_gw_msg_can_recv_req_decode(dan_gw_can_recv_t *q, const uint8_t *p, size_t len)
{
    dan_reader_t r;
    dan_reader_init(&r, p, len);
    q->seq = dan_get_uvarint(&r);
    q->count = dan_get_u8(&r);
    q->dropped = 0;
    q->t0_us = 0;
    q->opts = dan_reader_remaining(&r) > 0u ? dan_get_u8(&r) : 0u;
    return dan_reader_finish(&r);
}

void dan_gw_msg_can_recv_rsp_put(dan_writer_t *w, const dan_gw_can_recv_t *q)
{
    dan_put_uvarint(w, q->seq);
    dan_put_uvarint(w, q->dropped);
    dan_put_u8(w, q->count);
    if (q->opts & DAN_GW_RECV_TIMES) {
        dan_put_u32(w, q->t0_us);
    }
}

int dan_gw_msg_can_recv_rsp_get(dan_reader_t *r, dan_gw_can_recv_t *q)
{
    q->seq = dan_get_uvarint(r);
    q->dropped = dan_get_uvarint(r);
    q->count = dan_get_u8(r);
    q->t0_us = (q->opts & DAN_GW_RECV_TIMES) ? dan_get_u32(r) : 0u;
    if (q->count > DAN_GW_CAN_FRAMES_MAX) {
        return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(r);
}

void dan_gw_msg_filter_hdr_put(dan_writer_t *w, uint8_t op, uint8_t count)
{
    dan_put_u8(w, op);
    dan_put_u8(w, count);
}

int dan_gw_msg_filter_hdr_get(dan_reader_t *r, uint8_t *op, uint8_t *count)
{
    *op = dan_get_u8(r);
    *count = dan_get_u8(r);
    if (*count > DAN_GW_FILTERS_MAX) {
        return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(r);
}

void dan_gw_msg_filter_put(dan_writer_t *w, const dan_gw_filter_t *f)
{
    dan_put_u32(w, f->id & (DAN_GW_CAN_ID_EXT | DAN_GW_CAN_ID_OWN | DAN_CAN_EFF_MASK));
    dan_put_u32(w, f->mask & DAN_CAN_EFF_MASK);
}

int dan_gw_msg_filter_get(dan_reader_t *r, dan_gw_filter_t *f)
{
    f->id = dan_get_u32(r);
    f->mask = dan_get_u32(r);
    if ((f->id & DAN_GW_CAN_ID_RTR) != 0u || (f->mask & 0xE0000000u) != 0u) {
        return DAN_ERR_MALFORMED;
    }
    return dan_reader_finish(r);
}

bool dan_gw_filter_match(const dan_gw_filter_t *e, const dan_can_frame_t *f)
{
    bool ext = (f->flags & DAN_CAN_EXT) != 0u;
    if (ext != ((e->id & DAN_GW_CAN_ID_EXT) != 0u) ||
        ((f->flags & DAN_CAN_OWN) != 0u && (e->id & DAN_GW_CAN_ID_OWN) == 0u)) {
        return false;
    }
    return ((f->id ^ e->id) & e->mask & DAN_CAN_EFF_MASK) == 0u;
}

/* ---- the seal ---- */

bool dan_gw_sealed_code(uint32_t code)
{
    return (code >= DAN_GW_CODE_ESC_CMD && code <= DAN_TYPE_CAN_GW_LAST) ||
           (code >= DAN_TYPE_CAN_GW_BLOCK2 + 2u && code <= DAN_TYPE_CAN_GW_BLOCK2_LAST);
}

uint16_t dan_gw_check(uint32_t code, uint8_t dir, const uint8_t *p, size_t len)
{
    uint8_t c[DAN_UVARINT_MAX_BYTES + 1u];
    int n = dan_uvarint_encode(code, c, DAN_UVARINT_MAX_BYTES);
    c[n] = dir;
    return dan_crc16_ccitt(dan_crc16_ccitt(0xFFFFu, c, (size_t)n + 1u), p, len);
}

int dan_gw_seal(uint32_t code, uint8_t dir, uint8_t *p, size_t len, size_t cap)
{
    uint16_t c;
    if (cap < DAN_GW_SEAL_SIZE || len > cap - DAN_GW_SEAL_SIZE) {
        return DAN_ERR_OVERFLOW;
    }
    c = dan_gw_check(code, dir, p, len);
    p[len] = (uint8_t)(c & 0xFFu);
    p[len + 1u] = (uint8_t)(c >> 8);
    return (int)(len + DAN_GW_SEAL_SIZE);
}

int dan_gw_unseal(uint32_t code, uint8_t dir, const uint8_t *p, size_t len)
{
    uint16_t c;
    if (p == NULL || len < DAN_GW_SEAL_SIZE) {
        return DAN_ERR_MALFORMED;
    }
    len -= DAN_GW_SEAL_SIZE;
    c = dan_gw_check(code, dir, p, len);
    if (p[len] != (uint8_t)(c & 0xFFu) || p[len + 1u] != (uint8_t)(c >> 8)) {
        return DAN_ERR_MALFORMED;
    }
    return (int)len;
}

const char *dan_gw_stat_name(unsigned i)
{
#define NAME_(e, name) #name,
    static const char *const names[DAN_GW_STAT_COUNT] = {DAN_GW_STATS(NAME_)};
#undef NAME_
    return (i < DAN_GW_STAT_COUNT) ? names[i] : NULL;
}
