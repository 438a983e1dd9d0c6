/* DroneCAN transport and DSDL codec tests.
 *
 * Reference frames come from pydronecan (tests/vectors/gen_dronecan.py ->
 * tests/vectors/dronecan.txt, read through $DAN_VECTORS); three of them are
 * also pinned here from the task brief. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/can_gw/dronecan.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/f16.h"
#include "dan/can_gw/dsdl_mgmt.h"
#include "dan/can_gw/dsdl_out.h"

#include "vectors.h"
#include "unit_run.h"

#define MAX_FRAMES 64
#define MAX_KV     32

/* ---- helpers ---- */

/* "1401550A#01000000003412c0" -> frame */
static void parse_frame(const char *s, dan_can_frame_t *f)
{
    const char *hash = strchr(s, '#');
    size_t n;
    assert_non_null(hash);
    memset(f, 0, sizeof *f);
    f->id = (uint32_t)strtoul(s, NULL, 16);
    f->flags = DAN_CAN_EXT;
    n = vec_hex(hash + 1, f->data, 8);
    assert_true(n >= 1u);
    f->dlc = (uint8_t)n;
}

static void assert_frames_equal(const dan_can_frame_t *a, const dan_can_frame_t *b, size_t n)
{
    size_t i;
    for (i = 0; i < n; i++) {
        assert_int_equal(a[i].id, b[i].id);
        assert_int_equal(a[i].flags, b[i].flags);
        assert_int_equal(a[i].dlc, b[i].dlc);
        assert_memory_equal(a[i].data, b[i].data, a[i].dlc);
    }
}

static bool accept_known(void *user, uint16_t dtid, uint8_t ttype, uint8_t src, uint64_t *sig)
{
    (void)user;
    (void)src;
    return dan_dc_dsdl_signature(ttype, dtid, sig);
}

/* ---- vector lines ---- */

typedef struct {
    char name[32];
    char key[MAX_KV][32];
    char *val[MAX_KV];
    size_t nkv;
    dan_can_frame_t frames[MAX_FRAMES];
    size_t nframes;
} vec_t;

static const char *kv(const vec_t *v, const char *key)
{
    size_t i;
    for (i = 0; i < v->nkv; i++) {
        if (strcmp(v->key[i], key) == 0) {
            return v->val[i];
        }
    }
    fail_msg("vector %s: missing key %s", v->name, key);
    return "";
}

static long long kv_int(const vec_t *v, const char *key)
{
    return strtoll(kv(v, key), NULL, 0);
}

static unsigned long long kv_uint(const vec_t *v, const char *key)
{
    return strtoull(kv(v, key), NULL, 0);
}

static float kv_float(const vec_t *v, const char *key)
{
    return (float)strtod(kv(v, key), NULL); /* double first, like Python */
}

static size_t kv_hex(const vec_t *v, const char *key, uint8_t *out, size_t cap)
{
    return vec_hex(kv(v, key), out, cap);
}

/* Splits line (modified in place) into v. Returns false for comments. */
static bool parse_line(char *line, vec_t *v)
{
    char *tok, *save = NULL;
    bool frames = false;
    memset(v, 0, sizeof *v);
    line[strcspn(line, "\r\n")] = '\0';
    if (line[0] == '#' || line[0] == '\0') {
        return false;
    }
    tok = strtok_r(line, " ", &save);
    assert_non_null(tok);
    snprintf(v->name, sizeof v->name, "%s", tok);
    while ((tok = strtok_r(NULL, " ", &save)) != NULL) {
        if (strcmp(tok, ":") == 0) {
            frames = true;
        } else if (frames) {
            assert_true(v->nframes < MAX_FRAMES);
            parse_frame(tok, &v->frames[v->nframes++]);
        } else {
            char *eq = strchr(tok, '=');
            assert_non_null(eq);
            assert_true(v->nkv < MAX_KV);
            *eq = '\0';
            snprintf(v->key[v->nkv], sizeof v->key[0], "%s", tok);
            v->val[v->nkv++] = eq + 1;
        }
    }
    assert_true(v->nframes > 0);
    return true;
}

/* Decoded message of any known type. */
typedef union {
    dan_dc_node_status_t ns;
    dan_dc_get_node_info_rsp_t ni;
    dan_dc_esc_raw_command_t rc;
    dan_dc_esc_status_t es;
    dan_dc_esc_status_extended_t ex;
    dan_dc_arming_status_t as;
    dan_dc_tunnel_targetted_t tt;
    dan_dc_tunnel_broadcast_t tb;
    dan_dc_allocation_t al;
    dan_dc_param_getset_req_t gq;
    dan_dc_param_getset_rsp_t gr;
    dan_dc_param_opcode_t op;
    uint64_t magic;
    bool ok;
    dan_dc_array_command_t ac;
    dan_dc_lights_command_t lc;
    dan_dc_beep_command_t bc;
    uint8_t safety;
    dan_dc_temperature_t tp;
} any_msg_t;

/* Splits "a/b/c,a/b/c" lists into up to max rows of k numbers. */
static size_t rows_of(const char *s, unsigned long (*row)[3], size_t k, size_t max)
{
    size_t n = 0, j;
    if (strcmp(s, "-") == 0) {
        return 0;
    }
    while (*s != '\0' && n < max) {
        char *end;
        for (j = 0; j < k; j++) {
            row[n][j] = strtoul(s, &end, 10);
            s = (*end == '/' || *end == ',') ? end + 1 : end;
        }
        n++;
    }
    return n;
}

/* A param value from its text: 0 | 1/<int> | 2/<float> | 3/<0|1> | 4/<hex>. */
static void value_of(const char *s, dan_dc_param_value_t *v)
{
    const char *arg = strchr(s, '/');
    memset(v, 0, sizeof *v);
    v->tag = (uint8_t)atoi(s);
    arg = arg != NULL ? arg + 1 : "";
    switch (v->tag) {
    case DAN_DC_PARAM_INTEGER: v->integer = strtoll(arg, NULL, 10); break;
    case DAN_DC_PARAM_REAL: v->real = (float)strtod(arg, NULL); break;
    case DAN_DC_PARAM_BOOLEAN: v->boolean = (uint8_t)atoi(arg); break;
    case DAN_DC_PARAM_STRING: {
        v->string_len = (uint8_t)vec_hex(arg, v->string, sizeof v->string);
        break;
    }
    default: break;
    }
}

/* ---- each vector type: its fields from the vector's keys ---- */

/* A scalar field of a vector type: its key and its member in any_msg_t.
 * INT: the key's integer (truncated to the member, as a cast does); F16:
 * the key's number as float16; FLAG: the key's integer != 0. */
typedef enum { KV_INT, KV_F16, KV_FLAG } kv_kind_t;
typedef struct {
    const char *type, *key;
    size_t offset, size;
    kv_kind_t kind;
} vec_field_t;

#define VF(type, key, member, kind)                                                    \
    {                                                                                  \
        type, key, offsetof(any_msg_t, member), sizeof(((any_msg_t *)0)->member), kind \
    }
#define NS_FIELDS(type, m)                                                              \
    VF(type, "uptime_sec", m.uptime_sec, KV_INT), VF(type, "health", m.health, KV_INT), \
        VF(type, "mode", m.mode, KV_INT), VF(type, "sub_mode", m.sub_mode, KV_INT),     \
        VF(type, "vendor", m.vendor_specific_status_code, KV_INT)

static const vec_field_t vec_fields[] = {
    NS_FIELDS("node_status", ns),
    VF("esc_status", "error_count", es.error_count, KV_INT),
    VF("esc_status", "voltage", es.voltage_f16, KV_F16),
    VF("esc_status", "current", es.current_f16, KV_F16),
    VF("esc_status", "temperature", es.temperature_f16, KV_F16),
    VF("esc_status", "rpm", es.rpm, KV_INT),
    VF("esc_status", "power_rating_pct", es.power_rating_pct, KV_INT),
    VF("esc_status", "esc_index", es.esc_index, KV_INT),
    VF("esc_status_extended", "input_pct", ex.input_pct, KV_INT),
    VF("esc_status_extended", "output_pct", ex.output_pct, KV_INT),
    VF("esc_status_extended", "motor_temperature_degC", ex.motor_temperature_degC, KV_INT),
    VF("esc_status_extended", "motor_angle", ex.motor_angle, KV_INT),
    VF("esc_status_extended", "status_flags", ex.status_flags, KV_INT),
    VF("esc_status_extended", "esc_index", ex.esc_index, KV_INT),
    VF("arming_status", "status", as.status, KV_INT),
    VF("tunnel_targetted", "protocol", tt.protocol, KV_INT),
    VF("tunnel_targetted", "target_node", tt.target_node, KV_INT),
    VF("tunnel_targetted", "serial_id", tt.serial_id, KV_INT),
    VF("tunnel_targetted", "options", tt.options, KV_INT),
    VF("tunnel_targetted", "baudrate", tt.baudrate, KV_INT),
    VF("tunnel_broadcast", "protocol", tb.protocol, KV_INT),
    VF("tunnel_broadcast", "channel_id", tb.channel_id, KV_INT),
    NS_FIELDS("get_node_info_rsp", ni.status),
    VF("get_node_info_rsp", "sw_major", ni.software_version.major, KV_INT),
    VF("get_node_info_rsp", "sw_minor", ni.software_version.minor, KV_INT),
    VF("get_node_info_rsp", "sw_flags", ni.software_version.optional_field_flags, KV_INT),
    VF("get_node_info_rsp", "vcs_commit", ni.software_version.vcs_commit, KV_INT),
    VF("get_node_info_rsp", "image_crc", ni.software_version.image_crc, KV_INT),
    VF("get_node_info_rsp", "hw_major", ni.hardware_version.major, KV_INT),
    VF("get_node_info_rsp", "hw_minor", ni.hardware_version.minor, KV_INT),
    VF("allocation", "node_id", al.node_id, KV_INT),
    VF("allocation", "first_part", al.first_part, KV_FLAG),
    VF("getset_req", "index", gq.index, KV_INT),
    VF("opcode_req", "opcode", op.opcode, KV_INT),
    VF("opcode_req", "argument", op.argument, KV_INT),
    VF("opcode_rsp", "ok", op.ok, KV_FLAG),
    VF("opcode_rsp", "argument", op.argument, KV_INT),
    VF("restart_req", "magic", magic, KV_INT),
    VF("restart_rsp", "ok", ok, KV_FLAG),
    VF("beep_command", "freq", bc.frequency_f16, KV_INT),
    VF("beep_command", "dur", bc.duration_f16, KV_INT),
    VF("safety_state", "status", safety, KV_INT),
    VF("temperature", "device_id", tp.device_id, KV_INT),
    VF("temperature", "temp", tp.temperature_f16, KV_INT),
    VF("temperature", "flags", tp.error_flags, KV_INT),
};

/* Stores x, cast to a member of size bytes, at p: the union's members all
 * start at its first byte, so its first size bytes are the cast value. */
static void store_scalar(uint8_t *p, size_t size, uint64_t x)
{
    union {
        uint8_t u8;
        uint16_t u16;
        uint32_t u32;
        uint64_t u64;
    } u;
    u.u64 = x;
    if (size == 1u) {
        u.u8 = (uint8_t)x;
    } else if (size == 2u) {
        u.u16 = (uint16_t)x;
    } else if (size == 4u) {
        u.u32 = (uint32_t)x;
    }
    memcpy(p, &u, size);
}

/* Sets the scalar fields of v's type in m from v's keys (strtoull gives a
 * negative value's two's complement bits, as the casts did). */
static void fill_scalars(const vec_t *v, any_msg_t *m)
{
    size_t i;
    for (i = 0; i < sizeof vec_fields / sizeof vec_fields[0]; i++) {
        const vec_field_t *f = &vec_fields[i];
        uint64_t x;
        if (strcmp(f->type, v->name) != 0) {
            continue;
        }
        x = f->kind == KV_F16 ? dan_f16_from_f32(kv_float(v, f->key)) : kv_uint(v, f->key);
        store_scalar((uint8_t *)m + f->offset, f->size, f->kind == KV_FLAG ? x != 0u : x);
    }
}

/* The fields that are not scalars, by type. */

static void fill_esc_raw_command(const vec_t *v, any_msg_t *m)
{
    const char *s = kv(v, "cmd");
    while (*s != '\0') {
        char *end;
        assert_true(m->rc.count < DAN_DC_ESC_RAW_COMMAND_MAX_CMDS);
        m->rc.cmd[m->rc.count++] = (int16_t)strtol(s, &end, 10);
        s = *end == ',' ? end + 1 : end;
    }
}

static void fill_tunnel_targetted(const vec_t *v, any_msg_t *m)
{
    m->tt.buffer_len = (uint8_t)kv_hex(v, "buffer", m->tt.buffer, sizeof m->tt.buffer);
}

static void fill_tunnel_broadcast(const vec_t *v, any_msg_t *m)
{
    m->tb.buffer_len = (uint8_t)kv_hex(v, "buffer", m->tb.buffer, sizeof m->tb.buffer);
}

static void fill_get_node_info_rsp(const vec_t *v, any_msg_t *m)
{
    dan_dc_get_node_info_rsp_t *n = &m->ni;
    assert_int_equal(kv_hex(v, "unique_id", n->hardware_version.unique_id, 16), 16);
    n->hardware_version.coa_len =
        (uint8_t)kv_hex(v, "coa", n->hardware_version.certificate_of_authenticity, DAN_DC_COA_MAX);
    n->name_len = (uint8_t)kv_hex(v, "name", (uint8_t *)n->name, DAN_DC_GET_NODE_INFO_NAME_MAX);
}

static void fill_allocation(const vec_t *v, any_msg_t *m)
{
    m->al.uid_len = (uint8_t)kv_hex(v, "unique_id", m->al.uid, sizeof m->al.uid);
}

static void fill_param_getset_req(const vec_t *v, any_msg_t *m)
{
    value_of(kv(v, "value"), &m->gq.value);
    m->gq.name_len = (uint8_t)kv_hex(v, "name", (uint8_t *)m->gq.name, DAN_DC_PARAM_NAME_MAX);
}

static void fill_param_getset_rsp(const vec_t *v, any_msg_t *m)
{
    value_of(kv(v, "value"), &m->gr.value);
    value_of(kv(v, "default"), &m->gr.default_value);
    value_of(kv(v, "max"), &m->gr.max_value);
    value_of(kv(v, "min"), &m->gr.min_value);
    m->gr.name_len = (uint8_t)kv_hex(v, "name", (uint8_t *)m->gr.name, DAN_DC_PARAM_NAME_MAX);
}

static void fill_array_command(const vec_t *v, any_msg_t *m)
{
    unsigned long row[20][3];
    size_t i, n = rows_of(kv(v, "acts"), row, 3, DAN_DC_ARRAY_COMMAND_MAX);
    for (i = 0; i < n; i++) {
        m->ac.cmd[i].actuator_id = (uint8_t)row[i][0];
        m->ac.cmd[i].command_type = (uint8_t)row[i][1];
        m->ac.cmd[i].value_f16 = (uint16_t)row[i][2];
    }
    m->ac.count = (uint8_t)n;
}

static void fill_lights_command(const vec_t *v, any_msg_t *m)
{
    unsigned long row[20][3];
    size_t i, n = rows_of(kv(v, "lights"), row, 2, DAN_DC_LIGHTS_MAX);
    for (i = 0; i < n; i++) {
        m->lc.light[i].light_id = (uint8_t)row[i][0];
        m->lc.light[i].rgb565 = (uint16_t)row[i][1];
    }
    m->lc.count = (uint8_t)n;
}

/* ---- each type's codec, through any_msg_t ---- */

typedef int (*enc_fn)(const any_msg_t *m, uint8_t *buf, size_t cap);
typedef int (*dec_fn)(any_msg_t *m, const uint8_t *p, size_t len);

/* enc_<type> and dec_<type> for dan_dc_<type>_encode/_decode of member f:
 * encode takes arg, &m->f (CODEC) or, for the one-value types, m->f
 * (CODEC_VALUE). */
#define CODEC_AS(type, f, arg)                                          \
    static int enc_##type(const any_msg_t *m, uint8_t *buf, size_t cap) \
    {                                                                   \
        return dan_dc_##type##_encode(arg, buf, cap);                   \
    }                                                                   \
    static int dec_##type(any_msg_t *m, const uint8_t *p, size_t len)   \
    {                                                                   \
        return dan_dc_##type##_decode(&m->f, p, len);                   \
    }
#define CODEC(type, f)       CODEC_AS(type, f, &m->f)
#define CODEC_VALUE(type, f) CODEC_AS(type, f, m->f)
CODEC(node_status, ns)
CODEC(esc_raw_command, rc)
CODEC(esc_status, es)
CODEC(esc_status_extended, ex)
CODEC(arming_status, as)
CODEC(tunnel_targetted, tt)
CODEC(tunnel_broadcast, tb)
CODEC(get_node_info_rsp, ni)
CODEC(allocation, al)
CODEC(param_getset_req, gq)
CODEC(param_getset_rsp, gr)
CODEC(param_opcode_req, op)
CODEC(param_opcode_rsp, op)
CODEC_VALUE(restart_req, magic)
CODEC_VALUE(restart_rsp, ok)
CODEC(array_command, ac)
CODEC(lights_command, lc)
CODEC(beep_command, bc)
CODEC_VALUE(safety_state, safety)
CODEC(temperature, tp)

static int enc_get_node_info_req(const any_msg_t *m, uint8_t *buf, size_t cap)
{
    (void)m;
    return dan_dc_get_node_info_req_encode(buf, cap);
}

static int dec_get_node_info_req(any_msg_t *m, const uint8_t *p, size_t len)
{
    (void)m;
    return dan_dc_get_node_info_req_decode(p, len);
}

/* Every vector type: its name in dronecan.txt, data type ID, fields, codec;
 * fixed: a fixed-size payload (each strict prefix is malformed). */
typedef struct {
    const char *name;
    uint16_t dtid;
    void (*fill)(const vec_t *v, any_msg_t *m); /* the fields besides the scalars, or NULL */
    enc_fn encode;
    dec_fn decode;
    bool fixed;
} vec_type_t;

#define VEC_TYPE(name, id, type, fill, fixed)         \
    {                                                 \
        name, id, fill, enc_##type, dec_##type, fixed \
    }

static const vec_type_t vec_types[] = {
    VEC_TYPE("node_status", DAN_DC_NODE_STATUS_ID, node_status, NULL, true),
    VEC_TYPE("raw_command", DAN_DC_ESC_RAW_COMMAND_ID, esc_raw_command, fill_esc_raw_command,
             false),
    VEC_TYPE("esc_status", DAN_DC_ESC_STATUS_ID, esc_status, NULL, true),
    VEC_TYPE("esc_status_extended", DAN_DC_ESC_STATUS_EXTENDED_ID, esc_status_extended, NULL, true),
    VEC_TYPE("arming_status", DAN_DC_ARMING_STATUS_ID, arming_status, NULL, true),
    VEC_TYPE("tunnel_targetted", DAN_DC_TUNNEL_TARGETTED_ID, tunnel_targetted,
             fill_tunnel_targetted, false),
    VEC_TYPE("tunnel_broadcast", DAN_DC_TUNNEL_BROADCAST_ID, tunnel_broadcast,
             fill_tunnel_broadcast, false),
    VEC_TYPE("get_node_info_req", DAN_DC_GET_NODE_INFO_ID, get_node_info_req, NULL, false),
    VEC_TYPE("get_node_info_rsp", DAN_DC_GET_NODE_INFO_ID, get_node_info_rsp,
             fill_get_node_info_rsp, false),
    VEC_TYPE("allocation", DAN_DC_ALLOCATION_ID, allocation, fill_allocation, false),
    VEC_TYPE("getset_req", DAN_DC_PARAM_GETSET_ID, param_getset_req, fill_param_getset_req, false),
    VEC_TYPE("getset_rsp", DAN_DC_PARAM_GETSET_ID, param_getset_rsp, fill_param_getset_rsp, false),
    VEC_TYPE("opcode_req", DAN_DC_PARAM_OPCODE_ID, param_opcode_req, NULL, false),
    VEC_TYPE("opcode_rsp", DAN_DC_PARAM_OPCODE_ID, param_opcode_rsp, NULL, false),
    VEC_TYPE("restart_req", DAN_DC_RESTART_ID, restart_req, NULL, false),
    VEC_TYPE("restart_rsp", DAN_DC_RESTART_ID, restart_rsp, NULL, false),
    VEC_TYPE("array_command", DAN_DC_ARRAY_COMMAND_ID, array_command, fill_array_command, false),
    VEC_TYPE("lights_command", DAN_DC_LIGHTS_COMMAND_ID, lights_command, fill_lights_command,
             false),
    VEC_TYPE("beep_command", DAN_DC_BEEP_COMMAND_ID, beep_command, NULL, false),
    VEC_TYPE("safety_state", DAN_DC_SAFETY_STATE_ID, safety_state, NULL, false),
    VEC_TYPE("temperature", DAN_DC_TEMPERATURE_ID, temperature, NULL, false),
};

static const vec_type_t *vec_type(const char *name)
{
    size_t i;
    for (i = 0; i < sizeof vec_types / sizeof vec_types[0]; i++) {
        if (strcmp(vec_types[i].name, name) == 0) {
            return &vec_types[i];
        }
    }
    fail_msg("unknown vector type %s", name);
    return NULL;
}

/* Builds the expected message and the transfer header from v's keys;
 * returns the encoded payload length into buf. */
static int build_from_vec(const vec_t *v, any_msg_t *m, dan_dc_transfer_t *t, uint8_t *buf,
                          size_t cap)
{
    const char *kind = kv(v, "kind");
    const vec_type_t *type = vec_type(v->name);
    memset(m, 0, sizeof *m);
    memset(t, 0, sizeof *t);
    t->priority = (uint8_t)kv_int(v, "prio");
    t->source_node = (uint8_t)kv_int(v, "src");
    t->transfer_id = (uint8_t)kv_int(v, "tid");
    if (strcmp(kind, "msg") == 0) {
        t->transfer_type = DAN_DC_TRANSFER_BROADCAST;
    } else {
        t->transfer_type =
            strcmp(kind, "req") == 0 ? DAN_DC_TRANSFER_REQUEST : DAN_DC_TRANSFER_RESPONSE;
        t->destination_node = (uint8_t)kv_int(v, "dst");
    }
    fill_scalars(v, m);
    if (type->fill != NULL) {
        type->fill(v, m);
    }
    t->data_type_id = type->dtid;
    assert_true(dan_dc_dsdl_signature(t->transfer_type, t->data_type_id, &t->signature));
    return type->encode(m, buf, cap);
}

/* Decodes payload as v's type into m; returns the decoder's result. */
static int decode_as(const char *name, any_msg_t *m, const uint8_t *p, size_t len)
{
    memset(m, 0, sizeof *m);
    return vec_type(name)->decode(m, p, len);
}

static FILE *open_vectors(void)
{
    const char *dir = getenv("DAN_VECTORS");
    char path[512];
    FILE *f;
    snprintf(path, sizeof path, "%s/dronecan.txt", dir != NULL && *dir ? dir : "tests/vectors");
    f = fopen(path, "r");
    if (f == NULL) {
        fail_msg("cannot open %s", path);
    }
    return f;
}

/* Encoder + TX splitter must reproduce the frames exactly. */
static void check_tx(const vec_t *v)
{
    any_msg_t m;
    dan_dc_transfer_t t;
    uint8_t payload[DAN_DC_MAX_TRANSFER];
    dan_can_frame_t frames[MAX_FRAMES];
    int len, n;
    size_t i;
    len = build_from_vec(v, &m, &t, payload, sizeof payload);
    assert_true(len >= 0);
    /* Size-only pass agrees. */
    {
        any_msg_t m2;
        dan_dc_transfer_t t2;
        assert_int_equal(build_from_vec(v, &m2, &t2, NULL, 0), len);
    }
    t.payload = payload;
    t.payload_len = (size_t)len;
    n = dan_dc_tx_build(&t, frames, MAX_FRAMES);
    assert_int_equal(n, (int)v->nframes);
    assert_int_equal(dan_dc_tx_frame_count((size_t)len), v->nframes);
    assert_frames_equal(frames, v->frames, v->nframes);
    /* Streaming one frame at a time gives the same frames. */
    for (i = 0; i < v->nframes; i++) {
        dan_can_frame_t f;
        uint16_t crc = dan_dc_transfer_crc(t.signature, payload, (size_t)len);
        assert_int_equal(dan_dc_tx_frame(&t, crc, i, &f), DAN_OK);
        assert_frames_equal(&f, &v->frames[i], 1);
    }
    assert_int_equal(dan_dc_tx_build(&t, frames, v->nframes - 1u), DAN_ERR_OVERFLOW);
}

/* Frames -> RX -> transfer -> decode must give the fields back. */
static void check_rx(const vec_t *v)
{
    static dan_dc_rx_t rx;
    any_msg_t want, got;
    dan_dc_transfer_t t, out;
    uint8_t payload[DAN_DC_MAX_TRANSFER], re[DAN_DC_MAX_TRANSFER];
    int len, rc = 0, relen;
    size_t i;
    len = build_from_vec(v, &want, &t, payload, sizeof payload);
    assert_true(len >= 0);
    dan_dc_rx_init(&rx, t.destination_node != 0u ? t.destination_node : 99u, accept_known, NULL);
    for (i = 0; i < v->nframes; i++) {
        rc = dan_dc_rx_frame(&rx, &v->frames[i], 1000u + i, &out);
        assert_int_equal(rc, i + 1u == v->nframes ? 1 : 0);
    }
    assert_int_equal(rx.stats.transfers, 1);
    assert_int_equal(rx.stats.frames, v->nframes);
    assert_int_equal(out.data_type_id, t.data_type_id);
    assert_int_equal(out.transfer_type, t.transfer_type);
    assert_int_equal(out.source_node, t.source_node);
    assert_int_equal(out.destination_node, t.destination_node);
    assert_int_equal(out.transfer_id, t.transfer_id);
    assert_int_equal(out.priority, t.priority);
    assert_true(out.timestamp_us == 1000u);
    assert_int_equal(out.payload_len, (size_t)len);
    assert_memory_equal(out.payload, payload, (size_t)len);
    assert_int_equal(decode_as(v->name, &got, out.payload, out.payload_len), DAN_OK);
    if (strcmp(v->name, "get_node_info_rsp") == 0) {
        /* name is NUL-terminated by decode; want's is zero-filled too. */
        want.ni.name[want.ni.name_len] = '\0';
    }
    assert_memory_equal(&got, &want, sizeof got);
    /* Decode then encode is the identity on the payload. */
    relen = vec_type(v->name)->encode(&got, re, sizeof re);
    assert_int_equal(relen, len);
    assert_memory_equal(re, payload, (size_t)len);
    /* Every strict prefix of a fixed-size payload is rejected; nothing
     * reads past the end (ASan checks the copies). */
    for (i = 0; i < (size_t)len; i++) {
        uint8_t *cut = malloc(i + 1u);
        assert_non_null(cut);
        memcpy(cut, payload, i);
        rc = decode_as(v->name, &got, i > 0u ? cut : NULL, i);
        if (vec_type(v->name)->fixed) {
            assert_int_equal(rc, DAN_ERR_MALFORMED);
        }
        free(cut);
    }
}

static size_t for_each_vector(void (*fn)(const vec_t *))
{
    static char line[8192];
    static vec_t v;
    size_t count = 0;
    FILE *f = open_vectors();
    while (fgets(line, sizeof line, f) != NULL) {
        if (parse_line(line, &v)) {
            fn(&v);
            count++;
        }
    }
    fclose(f);
    return count;
}

/* ---- tests: vectors ---- */

/* The frames of one message of the brief (src 10, prio 20, tid 0): the
 * payload (len bytes, checked to be >= 0) split must give want[0..n). */
static void assert_brief_frames(uint16_t dtid, uint64_t sig, const uint8_t *payload, int len,
                                const char *const *want, size_t n)
{
    dan_dc_transfer_t t;
    dan_can_frame_t got[4], w[4];
    size_t i;
    assert_true(len >= 0 && n <= 4u);
    memset(&t, 0, sizeof t);
    t.priority = 20;
    t.source_node = 10;
    t.data_type_id = dtid;
    t.signature = sig;
    t.payload = payload;
    t.payload_len = (size_t)len;
    assert_int_equal(dan_dc_tx_build(&t, got, 4), (int)n);
    for (i = 0; i < n; i++) {
        parse_frame(want[i], &w[i]);
    }
    assert_frames_equal(got, w, n);
}

static void test_brief_vectors(void **state)
{
    /* From the task brief (pydronecan, src 10, prio 20, tid 0). */
    static const char *const ns[] = {"1401550A#01000000003412c0"};
    static const char *const rc[] = {"1404060A#0001900c800b01c0"};
    static const char *const es[] = {"14040A0A#5681070000004080", "14040A0A#4a00bdb05c2efb20",
                                     "14040A0A#d90c40"};
    dan_dc_node_status_t m1 = {1, 0, 0, 0, 0x1234};
    dan_dc_esc_raw_command_t m2 = {4, {0, 100, 200, 300}};
    dan_dc_esc_status_t m3 = {7, 0, 0, 0, -1234, 50, 3};
    uint8_t buf[64];
    int len;
    (void)state;
    assert_brief_frames(DAN_DC_NODE_STATUS_ID, DAN_DC_NODE_STATUS_SIGNATURE, buf,
                        dan_dc_node_status_encode(&m1, buf, sizeof buf), ns, 1);
    assert_brief_frames(DAN_DC_ESC_RAW_COMMAND_ID, DAN_DC_ESC_RAW_COMMAND_SIGNATURE, buf,
                        dan_dc_esc_raw_command_encode(&m2, buf, sizeof buf), rc, 1);
    m3.voltage_f16 = dan_f16_from_f32(12.5f);
    m3.current_f16 = dan_f16_from_f32(-1.25f);
    m3.temperature_f16 = dan_f16_from_f32(300.0f);
    len = dan_dc_esc_status_encode(&m3, buf, sizeof buf);
    assert_int_equal(len, 14);
    assert_brief_frames(DAN_DC_ESC_STATUS_ID, DAN_DC_ESC_STATUS_SIGNATURE, buf, len, es, 3);
}

static void test_vector_file_tx(void **state)
{
    (void)state;
    assert_true(for_each_vector(check_tx) >= 20u);
}

static void test_vector_file_rx(void **state)
{
    (void)state;
    assert_true(for_each_vector(check_rx) >= 20u);
}

/* ---- tests: primitives ---- */

static void test_crc(void **state)
{
    static const uint8_t check[] = "123456789";
    (void)state;
    assert_int_equal(dan_dc_crc16(DAN_DC_CRC_INIT, check, 9), 0x29B1);
    /* Seeding with the signature = feeding its LE bytes first. */
    {
        uint8_t b[8 + 3] = {0};
        uint64_t sig = DAN_DC_ESC_STATUS_SIGNATURE;
        unsigned i;
        for (i = 0; i < 8; i++) {
            b[i] = (uint8_t)(sig >> (8 * i));
        }
        b[8] = 1;
        b[9] = 2;
        b[10] = 3;
        assert_int_equal(dan_dc_transfer_crc(sig, &b[8], 3),
                         dan_dc_crc16(DAN_DC_CRC_INIT, b, sizeof b));
    }
}

static void test_scalar_bits(void **state)
{
    uint8_t buf[16];
    dan_dc_bw_t w;
    dan_dc_br_t r;
    (void)state;
    /* int14 100 after int14 0: bytes 00 01 90 (see RawCommand vector). */
    memset(buf, 0xAA, sizeof buf);
    dan_dc_bw_init(&w, buf, sizeof buf);
    dan_dc_put_int(&w, 14, 0);
    dan_dc_put_int(&w, 14, 100);
    assert_int_equal(dan_dc_bw_finish(&w), 4);
    assert_int_equal(buf[0], 0x00);
    assert_int_equal(buf[1], 0x01);
    assert_int_equal(buf[2], 0x90);
    assert_int_equal(buf[3], 0x00); /* padding zeroed */
    /* 12-bit value 0xABC at offset 0: LE bytes BC 0A -> BC then low nibble A. */
    memset(buf, 0, sizeof buf);
    dan_dc_encode_scalar(buf, 0, 12, 0xABC);
    assert_int_equal(buf[0], 0xBC);
    assert_int_equal(buf[1], 0xA0);
    assert_int_equal(dan_dc_decode_scalar(buf, 0, 12, false), 0xABC);
    /* Sign extension, 64-bit values, odd offsets. */
    {
        unsigned bits, off;
        for (bits = 1; bits <= 64; bits++) {
            for (off = 0; off < 9; off++) {
                uint64_t v = 0x9E3779B97F4A7C15ull;
                uint64_t mask = bits == 64 ? ~0ull : ((1ull << bits) - 1u);
                uint64_t got;
                memset(buf, 0x5A, sizeof buf);
                dan_dc_encode_scalar(buf, off, bits, v);
                got = dan_dc_decode_scalar(buf, off, bits, false);
                assert_true(got == (v & mask));
                got = dan_dc_decode_scalar(buf, off, bits, true);
                if (bits < 64 && ((v >> (bits - 1)) & 1u)) {
                    assert_true(got == ((v & mask) | ~mask));
                } else {
                    assert_true(got == (v & mask));
                }
                /* Neighbouring bits untouched. */
                if (off > 0) {
                    assert_int_equal(buf[0] >> (8 - off), 0x5A >> (8 - off));
                }
            }
        }
    }
    /* Saturation and reader bounds. */
    dan_dc_bw_init(&w, buf, 2);
    dan_dc_put_uint(&w, 7, 200);  /* -> 127 */
    dan_dc_put_int(&w, 9, -1000); /* -> -256 */
    assert_int_equal(dan_dc_bw_finish(&w), 2);
    dan_dc_br_init(&r, buf, 2);
    assert_int_equal(dan_dc_get_uint(&r, 7), 127);
    assert_int_equal(dan_dc_get_int(&r, 9), -256);
    assert_int_equal(dan_dc_br_finish(&r), DAN_OK);
    assert_int_equal(dan_dc_get_uint(&r, 1), 0);
    assert_int_equal(dan_dc_br_finish(&r), DAN_ERR_MALFORMED);
    dan_dc_put_uint(&w, 1, 1);
    assert_int_equal(dan_dc_bw_finish(&w), DAN_ERR_OVERFLOW);
    /* Array length prefix widths. */
    assert_int_equal(dan_dc_array_len_bits(20), 5);
    assert_int_equal(dan_dc_array_len_bits(255), 8);
    assert_int_equal(dan_dc_array_len_bits(120), 7);
    assert_int_equal(dan_dc_array_len_bits(60), 6);
    assert_int_equal(dan_dc_array_len_bits(256), 9);
    assert_true(dan_dc_tao(14, true));
    assert_false(dan_dc_tao(1, true)); /* bool[<=N] keeps its prefix */
    assert_false(dan_dc_tao(8, false));
}

static void test_float16(void **state)
{
    uint32_t h;
    (void)state;
    assert_int_equal(dan_f16_from_f32(1.0f), 0x3C00);
    assert_int_equal(dan_f16_from_f32(-2.0f), 0xC000);
    assert_int_equal(dan_f16_from_f32(0.0f), 0x0000);
    assert_int_equal(dan_f16_from_f32(-0.0f), 0x8000);
    assert_int_equal(dan_f16_from_f32(65504.0f), 0x7BFF);
    assert_int_equal(dan_f16_from_f32(65519.0f), 0x7BFF);
    assert_int_equal(dan_f16_from_f32(65520.0f), 0x7C00); /* rounds to inf */
    assert_int_equal(dan_f16_from_f32(1e9f), 0x7C00);
    assert_int_equal(dan_f16_from_f32(INFINITY), 0x7C00);
    assert_int_equal(dan_f16_from_f32(-INFINITY), 0xFC00);
    assert_int_equal(dan_f16_from_f32(NAN) & 0x7FFF, 0x7FFF);
    assert_int_equal(dan_f16_from_f32(0.1f), 0x2E66);
    assert_int_equal(dan_f16_from_f32(5.9604645e-8f), 0x0001); /* 2^-24 */
    assert_int_equal(dan_f16_from_f32(2.9802322e-8f), 0x0001); /* 2^-25: tie, away */
    assert_int_equal(dan_f16_from_f32(2.98e-8f), 0x0000);
    assert_int_equal(dan_f16_from_f32(6.1035156e-5f), 0x0400);  /* smallest normal */
    assert_int_equal(dan_f16_from_f32(1.00048828125f), 0x3C01); /* 1 + 2^-11: tie, away */
    assert_int_equal(dan_f16_from_f32(1.00048816f), 0x3C00);
    assert_true(isinf(dan_f16_to_f32(0x7C00)));
    assert_true(isnan(dan_f16_to_f32(0x7E00)));
    assert_true(dan_f16_to_f32(0xC000) == -2.0f);
    assert_true(dan_f16_to_f32(0x0001) == 5.9604645e-8f);
    assert_true(dan_f16_to_f32(0x8001) == -5.9604645e-8f);
    /* Every non-NaN half survives a round trip. */
    for (h = 0; h < 0x10000u; h++) {
        uint16_t back = dan_f16_from_f32(dan_f16_to_f32((uint16_t)h));
        if ((h & 0x7C00u) == 0x7C00u && (h & 0x3FFu) != 0u) {
            assert_int_equal(back, (h & 0x8000u) | 0x7FFFu);
        } else {
            assert_int_equal(back, h);
        }
    }
    /* Serializer saturation: finite values clamp, infinity stays. */
    {
        uint8_t b[8];
        dan_dc_bw_t w;
        dan_dc_bw_init(&w, b, sizeof b);
        dan_dc_put_f16(&w, 1e6f);
        dan_dc_put_f16(&w, -1e30f);
        dan_dc_put_f16(&w, INFINITY);
        assert_int_equal(dan_dc_bw_finish(&w), 6);
        assert_int_equal(b[0] | b[1] << 8, 0x7BFF);
        assert_int_equal(b[2] | b[3] << 8, 0xFBFF);
        assert_int_equal(b[4] | b[5] << 8, 0x7C00);
    }
}

static void test_ids(void **state)
{
    dan_dc_transfer_t t, p;
    uint32_t id;
    (void)state;
    memset(&t, 0, sizeof t);
    t.priority = 20;
    t.source_node = 10;
    t.data_type_id = 341;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_OK);
    assert_int_equal(id, 0x1401550A);
    /* Service request 1 from 42 to 10, priority 30. */
    t.priority = 30;
    t.source_node = 42;
    t.destination_node = 10;
    t.data_type_id = 1;
    t.transfer_type = DAN_DC_TRANSFER_REQUEST;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_OK);
    assert_int_equal(id, 0x1E018AAA);
    assert_int_equal(dan_dc_parse_id(id, &p), DAN_OK);
    assert_int_equal(p.transfer_type, DAN_DC_TRANSFER_REQUEST);
    assert_int_equal(p.data_type_id, 1);
    assert_int_equal(p.source_node, 42);
    assert_int_equal(p.destination_node, 10);
    assert_int_equal(p.priority, 30);
    t.transfer_type = DAN_DC_TRANSFER_RESPONSE;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_OK);
    assert_int_equal(id, 0x1E010AAA);
    /* Anonymous: discriminator bits 10..23, DTID low 2 bits 8..9. */
    memset(&t, 0, sizeof t);
    t.priority = 31;
    t.data_type_id = 1;
    t.discriminator = 0x3FFF;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_OK);
    assert_int_equal(id, 0x1FFFFD00);
    assert_int_equal(dan_dc_parse_id(id, &p), DAN_OK);
    assert_int_equal(p.source_node, 0);
    assert_int_equal(p.data_type_id, 1);
    assert_int_equal(p.discriminator, 0x3FFF);
    /* Bad arguments. */
    t.data_type_id = 4;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_ERR_ARG);
    t.data_type_id = 1;
    t.priority = 32;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_ERR_ARG);
    t.priority = 0;
    t.transfer_type = DAN_DC_TRANSFER_REQUEST;
    t.source_node = 5;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_ERR_ARG); /* dst 0 */
    t.destination_node = 128;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_ERR_ARG);
    t.destination_node = 3;
    t.data_type_id = 256;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_ERR_ARG);
    t.transfer_type = 3;
    assert_int_equal(dan_dc_make_id(&t, &id), DAN_ERR_ARG);
    /* Service frames from or to node 0 are malformed. */
    assert_int_equal(dan_dc_parse_id(0x1E018A80u, &p), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_parse_id(0x1E0180AAu, &p), DAN_ERR_MALFORMED);
}

static void test_tx_misc(void **state)
{
    dan_dc_transfer_t t;
    dan_can_frame_t f[8];
    uint8_t p[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    dan_dc_rx_t *rx = malloc(sizeof *rx);
    dan_dc_transfer_t out;
    (void)state;
    assert_non_null(rx);
    memset(&t, 0, sizeof t);
    t.priority = 16;
    t.data_type_id = 1; /* anonymous, e.g. dynamic node ID allocation */
    t.payload = p;
    t.payload_len = 8;
    assert_int_equal(dan_dc_tx_build(&t, f, 8), DAN_ERR_ARG); /* anonymous > 7 */
    t.payload_len = 6;
    assert_int_equal(dan_dc_tx_build(&t, f, 8), 1);
    assert_int_equal(f[0].dlc, 7);
    assert_int_equal(f[0].data[6], DAN_DC_TAIL_SOT | DAN_DC_TAIL_EOT);
    /* The anonymous frame decodes. */
    dan_dc_rx_init(rx, 10, accept_known, NULL);
    /* DTID 1 is dynamic_node_id.Allocation: an anonymous transfer */
    assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 1);
    assert_int_equal(out.source_node, 0);
    assert_int_equal(out.data_type_id, 1);
    assert_int_equal(out.payload_len, 6);
    assert_memory_equal(out.payload, p, 6);
    t.payload = NULL;
    assert_int_equal(dan_dc_tx_build(&t, f, 8), DAN_ERR_ARG);
    assert_int_equal(dan_dc_tx_build(NULL, f, 8), DAN_ERR_ARG);
    t.payload = p;
    assert_int_equal(dan_dc_tx_frame(&t, 0, 1, &f[0]), DAN_ERR_ARG); /* index */
    /* Empty payload: one frame with only the tail byte. */
    t.source_node = 3;
    t.payload_len = 0;
    assert_int_equal(dan_dc_tx_build(&t, f, 1), 1);
    assert_int_equal(f[0].dlc, 1);
    /* Frame counts at the boundaries. */
    assert_int_equal(dan_dc_tx_frame_count(0), 1);
    assert_int_equal(dan_dc_tx_frame_count(7), 1);
    assert_int_equal(dan_dc_tx_frame_count(8), 2);
    assert_int_equal(dan_dc_tx_frame_count(12), 2);
    assert_int_equal(dan_dc_tx_frame_count(13), 3);
    free(rx);
}

static void test_tid_table(void **state)
{
    dan_dc_tid_table_t tab;
    unsigned i;
    (void)state;
    dan_dc_tid_table_init(&tab);
    for (i = 0; i < 33; i++) {
        assert_int_equal(dan_dc_tid_next(&tab, 1030, DAN_DC_TRANSFER_BROADCAST, 0), (int)(i % 32u));
    }
    assert_int_equal(dan_dc_tid_next(&tab, 1, DAN_DC_TRANSFER_REQUEST, 5), 0);
    assert_int_equal(dan_dc_tid_next(&tab, 1, DAN_DC_TRANSFER_REQUEST, 6), 0);
    assert_int_equal(dan_dc_tid_next(&tab, 1, DAN_DC_TRANSFER_REQUEST, 5), 1);
    for (i = 3; i < DAN_DC_TX_TIDS; i++) {
        assert_int_equal(dan_dc_tid_next(&tab, (uint16_t)(2000 + i), 0, 0), 0);
    }
    /* full: the request flows give way in turn (calls to many nodes once
     * filled it for good and RawCommand found no room), their counters
     * going on; broadcast flows never do */
    assert_int_equal(dan_dc_tid_next(&tab, 9, 0, 0), 2);  /* took dst 5's flow (next 2) */
    assert_int_equal(dan_dc_tid_next(&tab, 10, 0, 0), 1); /* dst 6's */
    assert_int_equal(dan_dc_tid_next(&tab, 9, 0, 0), 3);  /* its own now */
    assert_int_equal(dan_dc_tid_next(&tab, 11, 0, 0), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_dc_tid_next(&tab, 1, DAN_DC_TRANSFER_REQUEST, 5), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_dc_tid_next(&tab, 1, DAN_DC_TRANSFER_REQUEST, 128), DAN_ERR_ARG);
}

/* Service calls to 20 nodes, each its own flow, through a table of 16 that
 * also holds the broadcasts: every call gets a transfer ID, and so does
 * every broadcast after them. */
static void test_tid_table_requests_give_way(void **state)
{
    dan_dc_tid_table_t tab;
    unsigned i, round;
    (void)state;
    dan_dc_tid_table_init(&tab);
    for (i = 0; i < 4; i++) {
        assert_true(dan_dc_tid_next(&tab, (uint16_t)(1030 + i), DAN_DC_TRANSFER_BROADCAST, 0) >= 0);
    }
    for (round = 0; round < 3; round++) {
        for (i = 0; i < 20; i++) {
            assert_true(dan_dc_tid_next(&tab, 11, DAN_DC_TRANSFER_REQUEST, (uint8_t)(20 + i)) >= 0);
        }
        for (i = 0; i < 4; i++) {
            assert_int_equal(
                dan_dc_tid_next(&tab, (uint16_t)(1030 + i), DAN_DC_TRANSFER_BROADCAST, 0),
                (int)(round + 1u));
        }
    }
}

/* ---- tests: RX ---- */

/* Builds frames of a RawCommand with n channels from src, tid. */
static int make_rc(dan_can_frame_t *f, size_t cap, uint8_t src, uint8_t tid, uint8_t n)
{
    dan_dc_esc_raw_command_t m;
    dan_dc_transfer_t t;
    static uint8_t buf[64];
    uint8_t i;
    memset(&m, 0, sizeof m);
    m.count = n;
    for (i = 0; i < n; i++) {
        m.cmd[i] = (int16_t)(i * 100 + src + tid);
    }
    memset(&t, 0, sizeof t);
    t.priority = 10;
    t.source_node = src;
    t.transfer_id = tid;
    t.data_type_id = DAN_DC_ESC_RAW_COMMAND_ID;
    t.signature = DAN_DC_ESC_RAW_COMMAND_SIGNATURE;
    t.payload = buf;
    t.payload_len = (size_t)dan_dc_esc_raw_command_encode(&m, buf, sizeof buf);
    return dan_dc_tx_build(&t, f, cap);
}

static void assert_rc_transfer(const dan_dc_transfer_t *out, uint8_t src, uint8_t tid, uint8_t n)
{
    dan_dc_esc_raw_command_t m;
    uint8_t i;
    assert_int_equal(out->source_node, src);
    assert_int_equal(out->transfer_id, tid);
    assert_int_equal(dan_dc_esc_raw_command_decode(&m, out->payload, out->payload_len), 0);
    assert_int_equal(m.count, n);
    for (i = 0; i < n; i++) {
        assert_int_equal(m.cmd[i], i * 100 + src + tid);
    }
}

static dan_dc_rx_t *new_rx(uint8_t node)
{
    dan_dc_rx_t *rx = malloc(sizeof *rx);
    assert_non_null(rx);
    dan_dc_rx_init(rx, node, accept_known, NULL);
    return rx;
}

static void test_rx_interleaved(void **state)
{
    dan_can_frame_t a[8], b[8];
    dan_dc_transfer_t out;
    dan_dc_rx_t *rx = new_rx(50);
    int na, nb, i, done = 0;
    (void)state;
    na = make_rc(a, 8, 11, 3, 20);
    nb = make_rc(b, 8, 12, 7, 20);
    assert_int_equal(na, 6);
    assert_int_equal(nb, 6);
    for (i = 0; i < 6; i++) {
        int r = dan_dc_rx_frame(rx, &a[i], 100, &out);
        if (r == 1) {
            assert_rc_transfer(&out, 11, 3, 20);
            done++;
        }
        r = dan_dc_rx_frame(rx, &b[i], 100, &out);
        if (r == 1) {
            assert_rc_transfer(&out, 12, 7, 20);
            done++;
        }
    }
    assert_int_equal(done, 2);
    assert_int_equal(rx->stats.transfers, 2);
    assert_int_equal(rx->stats.crc_errors + rx->stats.toggle_errors + rx->stats.tid_errors, 0);
    free(rx);
}

static void test_rx_lost_and_toggle(void **state)
{
    dan_can_frame_t a[8];
    dan_dc_transfer_t out;
    dan_dc_rx_t *rx = new_rx(50);
    int n, i;
    (void)state;
    n = make_rc(a, 8, 11, 1, 20);
    /* Lost middle frame: the next one has the wrong toggle. */
    for (i = 0; i < n; i++) {
        if (i != 2) {
            assert_int_equal(dan_dc_rx_frame(rx, &a[i], 0, &out), 0);
        }
    }
    assert_true(rx->stats.toggle_errors >= 1);
    assert_int_equal(rx->stats.transfers, 0);
    /* The toggle realigns two frames later; the CRC rejects the result. */
    assert_int_equal(rx->stats.crc_errors, 1);
    /* Two lost frames keep the toggle in step; the CRC catches it. */
    n = make_rc(a, 8, 11, 2, 20);
    for (i = 0; i < n; i++) {
        if (i != 2 && i != 3) {
            assert_int_equal(dan_dc_rx_frame(rx, &a[i], 0, &out), 0);
        }
    }
    assert_int_equal(rx->stats.crc_errors, 2);
    /* A duplicated frame (CAN double delivery) is dropped harmlessly. */
    n = make_rc(a, 8, 11, 3, 20);
    for (i = 0; i < n; i++) {
        int r = dan_dc_rx_frame(rx, &a[i], 0, &out);
        if (i == 2) {
            assert_int_equal(dan_dc_rx_frame(rx, &a[i], 0, &out), 0);
        }
        if (i == n - 1) {
            assert_int_equal(r, 1);
            assert_rc_transfer(&out, 11, 3, 20);
        }
    }
    /* Toggle bit flipped on a middle frame. */
    {
        uint32_t before = rx->stats.toggle_errors;
        n = make_rc(a, 8, 11, 4, 20);
        a[1].data[7] ^= DAN_DC_TAIL_TOGGLE;
        for (i = 0; i < n; i++) {
            assert_int_equal(dan_dc_rx_frame(rx, &a[i], 0, &out), 0);
        }
        assert_true(rx->stats.toggle_errors > before);
    }
    /* Missing start. */
    {
        uint32_t before = rx->stats.tid_errors;
        n = make_rc(a, 8, 11, 5, 20);
        for (i = 1; i < n; i++) {
            assert_int_equal(dan_dc_rx_frame(rx, &a[i], 0, &out), 0);
        }
        assert_true(rx->stats.tid_errors > before);
    }
    /* Frame of another transfer ID in the middle is dropped. */
    {
        dan_can_frame_t other[8];
        uint32_t before = rx->stats.tid_errors;
        n = make_rc(a, 8, 11, 6, 20);
        (void)make_rc(other, 8, 11, 9, 20);
        for (i = 0; i < n; i++) {
            int r = dan_dc_rx_frame(rx, &a[i], 0, &out);
            if (i == 1) {
                assert_int_equal(dan_dc_rx_frame(rx, &other[3], 0, &out), 0);
            }
            if (i == n - 1) {
                assert_int_equal(r, 1);
            }
        }
        assert_int_equal(rx->stats.tid_errors, before + 1u);
    }
    free(rx);
}

static void test_rx_crc(void **state)
{
    dan_can_frame_t a[8];
    dan_dc_transfer_t out;
    dan_dc_rx_t *rx = new_rx(50);
    int n, i, byte;
    (void)state;
    /* Corrupt each data byte (not the tail) of each frame in turn. */
    for (byte = 0; byte < 7; byte++) {
        uint8_t tid = (uint8_t)(byte & 31);
        n = make_rc(a, 8, 11, tid, 8); /* 14 bytes + CRC: 3 frames */
        assert_int_equal(n, 3);
        a[byte % 3].data[byte % (a[byte % 3].dlc - 1)] ^= 0x10;
        for (i = 0; i < n; i++) {
            assert_int_equal(dan_dc_rx_frame(rx, &a[i], (uint64_t)byte * 3000000u, &out), 0);
        }
    }
    assert_int_equal(rx->stats.crc_errors, 7);
    assert_int_equal(rx->stats.transfers, 0);
    free(rx);
}

static void test_rx_timeout(void **state)
{
    dan_can_frame_t a[8];
    dan_dc_transfer_t out;
    dan_dc_rx_t *rx = new_rx(50);
    int n;
    (void)state;
    n = make_rc(a, 8, 11, 1, 20);
    assert_int_equal(n, 6);
    assert_int_equal(dan_dc_rx_frame(rx, &a[0], 1000, &out), 0);
    assert_int_equal(dan_dc_rx_frame(rx, &a[1], 1000 + DAN_DC_TRANSFER_TIMEOUT_US, &out), 0);
    assert_int_equal(rx->stats.timeouts, 0);
    assert_int_equal(dan_dc_rx_frame(rx, &a[2], 1001 + DAN_DC_TRANSFER_TIMEOUT_US, &out), 0);
    assert_int_equal(rx->stats.timeouts, 1);
    /* Later frames: no transfer in progress any more. */
    assert_int_equal(dan_dc_rx_frame(rx, &a[3], 1002 + DAN_DC_TRANSFER_TIMEOUT_US, &out), 0);
    assert_int_equal(rx->stats.tid_errors, 1);
    /* The same transfer ID repeated within the timeout is a duplicate... */
    n = make_rc(a, 8, 11, 2, 2);
    assert_int_equal(n, 1);
    assert_int_equal(dan_dc_rx_frame(rx, &a[0], 10000000, &out), 1);
    assert_int_equal(dan_dc_rx_frame(rx, &a[0], 10000001, &out), 0);
    assert_int_equal(rx->stats.tid_errors, 2);
    /* ... but accepted again after it. */
    assert_int_equal(dan_dc_rx_frame(rx, &a[0], 12000001, &out), 1);
    /* Cleanup drops an idle partial transfer. */
    n = make_rc(a, 8, 11, 3, 20);
    assert_int_equal(dan_dc_rx_frame(rx, &a[0], 20000000, &out), 0);
    dan_dc_rx_cleanup(rx, 20000000 + DAN_DC_TRANSFER_TIMEOUT_US + 1);
    assert_int_equal(rx->stats.timeouts, 2);
    assert_int_equal(dan_dc_rx_frame(rx, &a[1], 20000000 + DAN_DC_TRANSFER_TIMEOUT_US + 2, &out),
                     0);
    assert_int_equal(rx->stats.tid_errors, 3);
    free(rx);
}

static void test_rx_destination(void **state)
{
    dan_dc_get_node_info_rsp_t m;
    dan_dc_transfer_t t, out;
    dan_can_frame_t f[64];
    uint8_t buf[DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE];
    dan_dc_rx_t *rx = new_rx(42);
    int len, n, i;
    (void)state;
    memset(&m, 0, sizeof m);
    m.name_len = DAN_DC_GET_NODE_INFO_NAME_MAX;
    memset(m.name, 'x', m.name_len);
    m.hardware_version.coa_len = DAN_DC_COA_MAX;
    memset(m.hardware_version.certificate_of_authenticity, 0xC5, DAN_DC_COA_MAX);
    len = dan_dc_get_node_info_rsp_encode(&m, buf, sizeof buf);
    assert_int_equal(len, DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE);
    assert_int_equal(dan_dc_get_node_info_rsp_encode(&m, buf, sizeof buf - 1u), DAN_ERR_OVERFLOW);
    memset(&t, 0, sizeof t);
    t.transfer_type = DAN_DC_TRANSFER_RESPONSE;
    t.data_type_id = DAN_DC_GET_NODE_INFO_ID;
    t.signature = DAN_DC_GET_NODE_INFO_SIGNATURE;
    t.source_node = 10;
    t.destination_node = 43; /* not us */
    t.payload = buf;
    t.payload_len = (size_t)len;
    n = dan_dc_tx_build(&t, f, 64);
    assert_int_equal(n, 54);
    for (i = 0; i < n; i++) {
        assert_int_equal(dan_dc_rx_frame(rx, &f[i], 0, &out), 0);
    }
    assert_int_equal(rx->stats.ignored, (uint32_t)n);
    /* Addressed to us: the largest response reassembles. */
    t.destination_node = 42;
    n = dan_dc_tx_build(&t, f, 64);
    for (i = 0; i < n; i++) {
        assert_int_equal(dan_dc_rx_frame(rx, &f[i], 0, &out), i == n - 1 ? 1 : 0);
    }
    assert_int_equal(out.payload_len, (size_t)len);
    {
        dan_dc_get_node_info_rsp_t d;
        assert_int_equal(dan_dc_get_node_info_rsp_decode(&d, out.payload, out.payload_len), 0);
        assert_int_equal(d.name_len, 80);
        assert_int_equal(d.hardware_version.coa_len, 255);
        assert_int_equal(d.name[80], '\0');
    }
    /* An anonymous receiver (node 0) takes no services at all. */
    dan_dc_rx_set_node(rx, 0);
    assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 0);
    /* Non-DroneCAN frames are ignored. */
    {
        dan_can_frame_t g = f[0];
        uint32_t before = rx->stats.ignored;
        g.flags = 0;
        assert_int_equal(dan_dc_rx_frame(rx, &g, 0, &out), 0);
        g.flags = DAN_CAN_EXT | DAN_CAN_RTR;
        assert_int_equal(dan_dc_rx_frame(rx, &g, 0, &out), 0);
        g.flags = DAN_CAN_EXT;
        g.dlc = 0;
        assert_int_equal(dan_dc_rx_frame(rx, &g, 0, &out), 0);
        assert_int_equal(rx->stats.ignored, before + 3u);
    }
    assert_int_equal(dan_dc_rx_frame(NULL, &f[0], 0, &out), DAN_ERR_ARG);
    free(rx);
}

static bool accept_all(void *user, uint16_t dtid, uint8_t ttype, uint8_t src, uint64_t *sig)
{
    (void)user;
    (void)dtid;
    (void)ttype;
    (void)src;
    *sig = 0x1122334455667788ull;
    return true;
}

static void test_rx_overflow_and_slots(void **state)
{
    static uint8_t big[DAN_DC_MAX_TRANSFER + 1u];
    static dan_can_frame_t f[80];
    dan_dc_transfer_t t, out;
    dan_dc_rx_t *rx = malloc(sizeof *rx);
    int n, i;
    unsigned s;
    (void)state;
    assert_non_null(rx);
    dan_dc_rx_init(rx, 9, accept_all, NULL);
    memset(&t, 0, sizeof t);
    t.data_type_id = 20000;
    t.signature = 0x1122334455667788ull;
    t.source_node = 1;
    t.payload = big;
    t.payload_len = sizeof big;
    n = dan_dc_tx_build(&t, f, 80);
    assert_true(n > 0);
    for (i = 0; i < n; i++) {
        assert_int_equal(dan_dc_rx_frame(rx, &f[i], 0, &out), 0);
    }
    assert_int_equal(rx->stats.overflow, 1);
    /* Exactly DAN_DC_MAX_TRANSFER fits. */
    t.payload_len = DAN_DC_MAX_TRANSFER;
    t.transfer_id = 1;
    n = dan_dc_tx_build(&t, f, 80);
    for (i = 0; i < n; i++) {
        assert_int_equal(dan_dc_rx_frame(rx, &f[i], 0, &out), i == n - 1 ? 1 : 0);
    }
    assert_int_equal(out.payload_len, DAN_DC_MAX_TRANSFER);
    /* Fill every slot with a started transfer from distinct sources. */
    dan_dc_rx_init(rx, 9, accept_all, NULL);
    t.payload_len = 20;
    for (s = 0; s < DAN_DC_RX_SESSIONS; s++) {
        t.source_node = (uint8_t)(s + 1u);
        n = dan_dc_tx_build(&t, f, 80);
        assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 0);
    }
    t.source_node = 100;
    n = dan_dc_tx_build(&t, f, 80);
    assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 0);
    assert_int_equal(rx->stats.no_slot, 1);
    /* Anonymous single-frame messages need no slot; multi-frame ones are
     * malformed. */
    {
        dan_dc_transfer_t a = t;
        uint32_t id;
        a.source_node = 0;
        a.data_type_id = 1;
        a.payload_len = 6;
        assert_int_equal(dan_dc_tx_build(&a, f, 80), 1);
        assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 1);
        assert_int_equal(out.source_node, 0);
        assert_int_equal(out.data_type_id, 1);
        assert_int_equal(out.payload_len, 6);
        a.discriminator = out.discriminator;
        assert_int_equal(dan_dc_make_id(&a, &id), DAN_OK);
        assert_int_equal(id, f[0].id);
        f[0].data[7] = DAN_DC_TAIL_SOT; /* start, no end */
        f[0].dlc = 8;
        assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 0);
        assert_int_equal(rx->stats.malformed, 1);
    }
    /* A single-frame transfer still gets through without a slot. */
    t.payload_len = 3;
    n = dan_dc_tx_build(&t, f, 80);
    assert_int_equal(dan_dc_rx_frame(rx, &f[0], 0, &out), 1);
    /* After the timeout, a stale slot is reused. */
    t.payload_len = 20;
    n = dan_dc_tx_build(&t, f, 80);
    for (i = 0; i < n; i++) {
        assert_int_equal(dan_dc_rx_frame(rx, &f[i], 3000000, &out), i == n - 1 ? 1 : 0);
    }
    assert_int_equal(rx->stats.timeouts, 1);
    free(rx);
}

/* Single-frame flows that keep every slot (each sends within the 2 s
 * timeout: NodeStatus, StatusExtended, Temperature of 20 ESCs) must not
 * lock multi-frame transfers out: esc.Status, GetNodeInfo and file.Read
 * got no_slot for as long as those flows kept sending (review finding).
 * A multi-frame start takes the stalest slot with nothing in progress; a
 * transfer in progress is never taken. */
static void test_rx_single_frame_flows_leave_room(void **state)
{
    static dan_can_frame_t f[80];
    static const uint8_t data[14] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14};
    dan_dc_transfer_t t, out;
    dan_dc_rx_t *rx = malloc(sizeof *rx);
    unsigned s;
    int n, i;
    (void)state;
    assert_non_null(rx);
    dan_dc_rx_init(rx, 9, accept_all, NULL);
    memset(&t, 0, sizeof t);
    t.signature = 0x1122334455667788ull;
    t.payload = data;
    t.data_type_id = 341;
    t.payload_len = 7;
    for (s = 0; s < DAN_DC_RX_SESSIONS; s++) { /* one single-frame flow per slot */
        t.source_node = (uint8_t)(s + 1u);
        assert_int_equal(dan_dc_tx_build(&t, f, 80), 1);
        assert_int_equal(dan_dc_rx_frame(rx, &f[0], 1000u + s, &out), 1);
    }
    /* 1 s later (every slot still live): a 3-frame esc.Status from node 100 */
    t.source_node = 100;
    t.data_type_id = 1034;
    t.payload_len = 14;
    n = dan_dc_tx_build(&t, f, 80);
    assert_int_equal(n, 3);
    for (i = 0; i < n; i++) {
        assert_int_equal(dan_dc_rx_frame(rx, &f[i], 1000000u, &out), i == n - 1 ? 1 : 0);
    }
    assert_int_equal(out.source_node, 100);
    assert_int_equal(rx->stats.no_slot, 0);
    /* it took the stalest flow's slot (node 1); node 1 still gets through */
    t.source_node = 1;
    t.data_type_id = 341;
    t.payload_len = 7;
    t.transfer_id = 1;
    assert_int_equal(dan_dc_tx_build(&t, f, 80), 1);
    assert_int_equal(dan_dc_rx_frame(rx, &f[0], 1000100u, &out), 1);
    /* transfers in progress are never taken: start one per slot, then a
     * new multi-frame start finds none */
    dan_dc_rx_init(rx, 9, accept_all, NULL);
    t.data_type_id = 1034;
    t.payload_len = 14;
    for (s = 0; s < DAN_DC_RX_SESSIONS; s++) {
        t.source_node = (uint8_t)(s + 1u);
        n = dan_dc_tx_build(&t, f, 80);
        assert_int_equal(dan_dc_rx_frame(rx, &f[0], 1000u, &out), 0);
    }
    t.source_node = 100;
    n = dan_dc_tx_build(&t, f, 80);
    assert_int_equal(dan_dc_rx_frame(rx, &f[0], 2000u, &out), 0);
    assert_int_equal(rx->stats.no_slot, 1);
    free(rx);
}

/* ---- fuzz ---- */

static uint32_t rnd(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return *s = x;
}

static void test_fuzz(void **state)
{
    dan_dc_rx_t *rx = new_rx(10);
    dan_dc_transfer_t out;
    dan_can_frame_t f, good[8];
    uint32_t seed = 0x12345678u;
    uint64_t now = 0;
    unsigned i, j;
    (void)state;
    (void)make_rc(good, 8, 11, 0, 20);
    for (i = 0; i < 300000u; i++) {
        uint32_t r = rnd(&seed);
        memset(&f, 0, sizeof f);
        if ((r & 3u) == 0u) {
            /* A valid frame with a few bits flipped. */
            f = good[rnd(&seed) % 6u];
            f.data[rnd(&seed) % 8u] ^= (uint8_t)(1u << (rnd(&seed) % 8u));
            if ((rnd(&seed) & 7u) == 0u) {
                f.id ^= 1u << (rnd(&seed) % 29u);
            }
        } else {
            /* IDs from a few known types, sources and destinations. */
            static const uint16_t types[] = {341, 1030, 1034, 1036, 1100, 3001, 2010, 1};
            uint32_t id = (uint32_t)(rnd(&seed) & 0x1Fu) << 24;
            if ((r & 4u) != 0u) {
                id |= 0x80u | (uint32_t)(rnd(&seed) & 1u) << 16 | (rnd(&seed) & 0x8000u) |
                      (uint32_t)((rnd(&seed) & 1u) ? 10u : rnd(&seed) & 0x7Fu) << 8;
            } else {
                id |= (uint32_t)types[rnd(&seed) % 8u] << 8;
            }
            id |= rnd(&seed) % 4u;
            f.id = (r & 0x100u) != 0u ? rnd(&seed) : id; /* sometimes junk */
            f.flags = (uint8_t)((rnd(&seed) % 16u) == 0u ? rnd(&seed) & 7u : DAN_CAN_EXT);
            f.dlc = (uint8_t)(rnd(&seed) % 10u); /* includes invalid 9 */
            for (j = 0; j < 8; j++) {
                f.data[j] = (uint8_t)rnd(&seed);
            }
        }
        now += rnd(&seed) % 50000u;
        if (dan_dc_rx_frame(rx, &f, now, &out) == 1) {
            any_msg_t m;
            uint8_t *copy = malloc(out.payload_len + 1u);
            assert_true(out.payload_len <= DAN_DC_MAX_TRANSFER);
            assert_non_null(copy);
            memcpy(copy, out.payload, out.payload_len); /* exact-size copy */
            (void)decode_as("node_status", &m, copy, out.payload_len);
            (void)decode_as("raw_command", &m, copy, out.payload_len);
            (void)decode_as("esc_status", &m, copy, out.payload_len);
            (void)decode_as("tunnel_targetted", &m, copy, out.payload_len);
            (void)decode_as("tunnel_broadcast", &m, copy, out.payload_len);
            (void)decode_as("get_node_info_rsp", &m, copy, out.payload_len);
            free(copy);
        }
    }
    assert_true(rx->stats.frames == 300000u);
    free(rx);
}

static void test_decode_fuzz(void **state)
{
    static const char *const names[] = {
        "node_status",   "raw_command",      "esc_status",       "esc_status_extended",
        "arming_status", "tunnel_targetted", "tunnel_broadcast", "get_node_info_rsp"};
    uint32_t seed = 0xC0FFEEu;
    unsigned i, k;
    (void)state;
    for (i = 0; i < 20000u; i++) {
        size_t len = rnd(&seed) % 400u, j;
        uint8_t *p = malloc(len + 1u);
        assert_non_null(p);
        for (j = 0; j < len; j++) {
            p[j] = (uint8_t)rnd(&seed);
        }
        for (k = 0; k < 8; k++) {
            any_msg_t m;
            int rc = decode_as(names[k], &m, len > 0u ? p : NULL, len);
            assert_true(rc == DAN_OK || rc == DAN_ERR_MALFORMED);
        }
        free(p);
    }
}

static void test_codec_errors(void **state)
{
    uint8_t buf[64];
    dan_dc_esc_raw_command_t rc;
    dan_dc_tunnel_broadcast_t tb;
    dan_dc_get_node_info_rsp_t ni;
    uint8_t big[400];
    (void)state;
    /* Saturation to int14. */
    memset(&rc, 0, sizeof rc);
    rc.count = 2;
    rc.cmd[0] = 9000;
    rc.cmd[1] = -9000;
    assert_int_equal(dan_dc_esc_raw_command_encode(&rc, buf, sizeof buf), 4);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, buf, 4), 0);
    assert_int_equal(rc.count, 2);
    assert_int_equal(rc.cmd[0], 8191);
    assert_int_equal(rc.cmd[1], -8192);
    rc.count = 21;
    assert_int_equal(dan_dc_esc_raw_command_encode(&rc, buf, sizeof buf), DAN_ERR_ARG);
    /* 21 commands' worth of bytes is too many. */
    memset(big, 0, sizeof big);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, big, 35), 0);
    assert_int_equal(rc.count, 20);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, big, 37), DAN_ERR_MALFORMED);
    /* a byte or more left after the last element: no encoder makes it
     * (20 commands are 35 bytes, 1 is 2; pydronecan refuses these too) */
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, big, 36), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, big, 3), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, big, 2), 0);
    assert_int_equal(rc.count, 1);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, NULL, 0), 0);
    assert_int_equal(rc.count, 0);
    /* Buffers above their maxima. */
    assert_int_equal(dan_dc_tunnel_broadcast_decode(&tb, big, 62), 0);
    assert_int_equal(dan_dc_tunnel_broadcast_decode(&tb, big, 63), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_tunnel_broadcast_decode(&tb, big, 1), DAN_ERR_MALFORMED);
    memset(&tb, 0, sizeof tb);
    tb.buffer_len = 61;
    assert_int_equal(dan_dc_tunnel_broadcast_encode(&tb, buf, sizeof buf), DAN_ERR_ARG);
    tb.buffer_len = 60;
    assert_int_equal(dan_dc_tunnel_broadcast_encode(&tb, buf, 61), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_dc_tunnel_broadcast_encode(&tb, NULL, 0), 62);
    /* GetNodeInfo: certificate length beyond the payload, name too long. */
    memset(big, 0, sizeof big);
    big[7 + 15 + 2 + 16] = 10; /* coa_len 10, only 5 bytes follow */
    assert_int_equal(dan_dc_get_node_info_rsp_decode(&ni, big, 7 + 15 + 2 + 16 + 1 + 5),
                     DAN_ERR_MALFORMED);
    big[7 + 15 + 2 + 16] = 0;
    assert_int_equal(dan_dc_get_node_info_rsp_decode(&ni, big, 41 + 80), 0);
    assert_int_equal(ni.name_len, 80);
    assert_int_equal(dan_dc_get_node_info_rsp_decode(&ni, big, 41 + 81), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_node_status_decode(NULL, big, 7), DAN_ERR_ARG);
    assert_int_equal(dan_dc_node_status_encode(NULL, buf, 7), DAN_ERR_ARG);
}

int main(void)
{
    return UNIT_RUN(
        "dronecan", NULL, NULL, test_brief_vectors, test_vector_file_tx, test_vector_file_rx,
        test_crc, test_scalar_bits, test_float16, test_ids, test_tx_misc, test_tid_table,
        test_tid_table_requests_give_way, test_rx_interleaved, test_rx_lost_and_toggle, test_rx_crc,
        test_rx_timeout, test_rx_destination, test_rx_overflow_and_slots,
        test_rx_single_frame_flows_leave_room, test_fuzz, test_decode_fuzz, test_codec_errors);
}
