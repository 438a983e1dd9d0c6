/*
 * CAN-over-DAN gateway messages for bus management: node service calls
 * (parameters, ExecuteOpcode, RestartNode), the health verdict and the
 * dynamic node ID allocation table. docs/PROTOCOL.md section 7 ("Bus
 * management") is the byte-level definition; tests/vectors/gateway.txt pins
 * it. Conventions as dan/can_gw/msgs.h (inner payloads; the seal is added by
 * the transport).
 */
#ifndef DAN_CAN_GW_MSGS_MGMT_H
#define DAN_CAN_GW_MSGS_MGMT_H

#include "dan/can_gw/file_store.h"
#include "dan/can_gw/msgs.h"

#ifdef __cplusplus
extern "C" {
#endif

#define DAN_GW_CODE_NODE_CALL   0x4Eu /* start a DroneCAN service call */
#define DAN_GW_CODE_CALL_RESULT 0x4Fu /* read a call's result by offset */
#define DAN_GW_CODE_HEALTH      0x52u /* bus health verdict */
#define DAN_GW_CODE_DNA         0x53u /* allocation table, paged */

/* ---- parameter values (uavcan.protocol.param.Value on the DAN wire) ----
 * u8 tag, then: INTEGER i64 (8 bytes LE), REAL f32 (IEEE bits, 4 bytes LE),
 * BOOLEAN u8, STRING array (<= 128); EMPTY nothing. */
#define DAN_GW_VALUE_EMPTY      0u
#define DAN_GW_VALUE_INTEGER    1u
#define DAN_GW_VALUE_REAL       2u
#define DAN_GW_VALUE_BOOLEAN    3u
#define DAN_GW_VALUE_STRING     4u
#define DAN_GW_VALUE_STRING_MAX 128u
#define DAN_GW_PARAM_NAME_MAX   92u
#define DAN_GW_PARAM_INDEX_MAX  8191u

typedef struct {
    uint8_t tag; /* DAN_GW_VALUE_* */
    uint8_t boolean;
    uint8_t string_len;
    int64_t integer;
    float real;
    uint8_t string[DAN_GW_VALUE_STRING_MAX];
} dan_gw_value_t;

void dan_gw_msg_value_put(dan_writer_t *w, const dan_gw_value_t *v);
/* numeric: only EMPTY, INTEGER and REAL are valid (max/min values). */
int dan_gw_msg_value_get(dan_reader_t *r, dan_gw_value_t *v, bool numeric);

/* ---- NODE_CALL (0x4E) ----
 * Request: u16 call_id, u8 node_id (1..127), u8 op, then per op:
 *   PARAM_GET_INDEX uv index; PARAM_GET_NAME string name (1..92);
 *   PARAM_SET string name, value; PARAM_SAVE, PARAM_ERASE nothing;
 *   RESTART u40 magic (5 bytes LE), u8 force (0/1); FW_BEGIN string name
 *   (1..32, a committed file: docs/PROTOCOL.md "Files and firmware updates").
 * Response: u16 call_id, u8 state, and uv result_len when state is DONE. */
#define DAN_GW_CALL_PARAM_GET_INDEX 0u
#define DAN_GW_CALL_PARAM_GET_NAME  1u
#define DAN_GW_CALL_PARAM_SET       2u
#define DAN_GW_CALL_PARAM_SAVE      3u
#define DAN_GW_CALL_PARAM_ERASE     4u
#define DAN_GW_CALL_RESTART         5u
#define DAN_GW_CALL_FW_BEGIN        6u /* file.BeginFirmwareUpdate */
#define DAN_GW_CALL_OP_MAX          6u

#define DAN_GW_CALL_PENDING 0u /* sent, waiting for the node */
#define DAN_GW_CALL_DONE    1u /* the result can be read */
#define DAN_GW_CALL_TIMEOUT 2u /* no answer to every attempt */
#define DAN_GW_CALL_BUSY    3u /* no free slot: nothing was sent */

#define DAN_GW_RESTART_MAGIC 0xACCE551B1Eull /* RestartNode.MAGIC_NUMBER */

typedef struct {
    uint16_t call_id;
    uint8_t node_id;
    uint8_t op;           /* DAN_GW_CALL_* */
    uint16_t index;       /* PARAM_GET_INDEX */
    uint8_t force;        /* RESTART */
    uint64_t magic;       /* RESTART: uint40 */
    const char *name;     /* PARAM_GET_NAME, PARAM_SET, FW_BEGIN; decode: a view */
    uint8_t name_len;     /* into the payload, not NUL-terminated */
    dan_gw_value_t value; /* PARAM_SET */
} dan_gw_call_t;

DAN_CODEC(dan_gw_msg_call, dan_gw_call_t);

typedef struct {
    uint16_t call_id;
    uint8_t state;       /* DAN_GW_CALL_* */
    uint32_t result_len; /* DONE */
} dan_gw_call_state_t;

DAN_CODEC(dan_gw_msg_call_state, dan_gw_call_state_t);

/* ---- CALL_RESULT (0x4F) ----
 * Request: u16 call_id, uv offset, u8 max. Response: u16 call_id, u8
 * state, uv result_len, uv offset, array data (<= min(max, 128); empty until
 * DONE). Unknown call_id: error frame. */
#define DAN_GW_RESULT_CHUNK_MAX 128u
#define DAN_GW_RESULT_REQ_MAX   8u /* call_id, a 5-byte uvarint, max */

typedef struct {
    uint16_t call_id;
    uint8_t state; /* rsp */
    uint8_t max;   /* req */
    uint32_t offset;
    uint32_t result_len; /* rsp */
    const uint8_t *data; /* rsp; decode: a view into the payload */
    size_t len;
} dan_gw_result_t;

DAN_CODEC(dan_gw_msg_result_req, dan_gw_result_t);
DAN_CODEC(dan_gw_msg_result_rsp, dan_gw_result_t);

/* ---- call results (the bytes CALL_RESULT reads) ---- */

/* PARAM_GET_INDEX, PARAM_GET_NAME, PARAM_SET: u8 present, value, [default],
 * [max], [min], string name (empty: no such parameter). */
#define DAN_GW_PARAM_HAS_DEFAULT 0x01u
#define DAN_GW_PARAM_HAS_MAX     0x02u
#define DAN_GW_PARAM_HAS_MIN     0x04u
#define DAN_GW_PARAM_RESULT_MAX  376u /* the largest result, bytes */

typedef struct {
    uint8_t present; /* DAN_GW_PARAM_HAS_* */
    dan_gw_value_t value;
    dan_gw_value_t default_value;
    dan_gw_value_t max_value;
    dan_gw_value_t min_value;
    uint8_t name_len;
    char name[DAN_GW_PARAM_NAME_MAX + 1u]; /* decode NUL-terminates */
} dan_gw_param_t;

DAN_CODEC(dan_gw_msg_param, dan_gw_param_t);

/* PARAM_SAVE, PARAM_ERASE: u8 ok, i48 argument (6 bytes LE). RESTART: u8
 * ok (argument 0, not sent). */
typedef struct {
    uint8_t ok;
    int64_t argument;
} dan_gw_opcode_result_t;

DAN_CODEC(dan_gw_msg_opcode_result, dan_gw_opcode_result_t);

/* ---- HEALTH (0x52) ----
 * Request: empty. Response: u8 verdict, u8 reason, u8 subject, u8 detail,
 * u8 problems. */
#define DAN_GW_HEALTH_OK   0u
#define DAN_GW_HEALTH_FAIL 1u

#define DAN_GW_REASON_NONE          0u
#define DAN_GW_REASON_CAN_DOWN      1u
#define DAN_GW_REASON_DUPLICATE     2u /* subject: node ID */
#define DAN_GW_REASON_UNHEALTHY     3u /* subject: node ID, detail: health */
#define DAN_GW_REASON_OFFLINE       4u /* subject: node ID */
#define DAN_GW_REASON_ESC_TELEMETRY 5u /* subject: ESC index */
#define DAN_GW_REASON_DNA_CONFLICT  6u /* subject: the other allocator */
#define DAN_GW_REASON_DNA_FULL      7u

typedef struct {
    uint8_t verdict;
    uint8_t reason;
    uint8_t subject;
    uint8_t detail;
    uint8_t problems;
} dan_gw_health_t;

DAN_CODEC(dan_gw_msg_health, dan_gw_health_t);
/* The reason's name ("duplicate", ...), or NULL. */
const char *dan_gw_reason_name(unsigned reason);

/* ---- DNA (0x53) ----
 * Request: u8 first entry index. Response: u8 flags, u8 entries, u8
 * capacity, u8 next (DAN_GW_NONE: end), u8 count, then count entries of
 * u8 node_id, 16 bytes unique_id. */
#define DAN_GW_DNA_ON          0x01u /* the allocation server runs */
#define DAN_GW_DNA_LOADED      0x02u /* the table came from storage */
#define DAN_GW_DNA_STORE_ERROR 0x04u /* storage refused or was corrupt */
#define DAN_GW_DNA_HDR_SIZE    5u

typedef struct {
    uint8_t flags;
    uint8_t entries;
    uint8_t capacity;
    uint8_t next;
    uint8_t count;
} dan_gw_dna_hdr_t;

typedef struct {
    uint8_t node_id;
    uint8_t unique_id[DAN_DC_UNIQUE_ID_SIZE];
} dan_gw_dna_entry_t;

DAN_ITEM(dan_gw_msg_dna_hdr, dan_gw_dna_hdr_t);
DAN_ITEM(dan_gw_msg_dna_entry, dan_gw_dna_entry_t);
#define DAN_GW_DNA_ENTRY_SIZE (1u + DAN_DC_UNIQUE_ID_SIZE)

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_MSGS_MGMT_H */
