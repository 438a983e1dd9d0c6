/*
 * DSDL codecs of the bus-management types the gateway speaks: dynamic node
 * ID allocation, parameters, ExecuteOpcode, RestartNode. Layouts and
 * signatures from the DSDL shipped with pydronecan (dronecan/dsdl_specs,
 * uavcan/protocol/...); vectors in tests/vectors/dronecan.txt come from
 * pydronecan itself (tests/vectors/gen_dronecan.py).
 *
 * Conventions as dsdl.h: encode returns bytes or a negative DAN_ERR_*
 * (out NULL: size only), decode never reads outside the payload and
 * returns DAN_ERR_MALFORMED for a short payload or an array too long.
 */
#ifndef DAN_CAN_GW_DSDL_MGMT_H
#define DAN_CAN_GW_DSDL_MGMT_H

#include "dan/can_gw/dsdl.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- uavcan.protocol.dynamic_node_id.Allocation (message 1) ----
 * uint7 node_id, bool first_part_of_unique_id, uint8[<=16] unique_id (TAO).
 * Anonymous requests carry at most 6 bytes of the unique ID (one frame). */
#define DAN_DC_ALLOCATION_ID              1u
#define DAN_DC_ALLOCATION_SIGNATURE       0x0B2A812620A11D40ull
#define DAN_DC_ALLOCATION_MAX_SIZE        17u
#define DAN_DC_ALLOCATION_UID_PER_REQUEST 6u      /* MAX_LENGTH_OF_UNIQUE_ID_IN_REQUEST */
#define DAN_DC_ALLOCATION_FOLLOWUP_US     500000u /* FOLLOWUP_TIMEOUT_MS */
#define DAN_DC_ALLOCATION_MAX_NODE_ID     125u    /* 126 and 127: maintenance tools */

typedef struct {
    uint8_t node_id; /* requests: preferred (0: any); answers: allocated */
    bool first_part; /* requests: first stage */
    uint8_t uid_len; /* 0..16 */
    uint8_t uid[DAN_DC_UNIQUE_ID_SIZE];
} dan_dc_allocation_t;

DAN_DC_CODEC(dan_dc_allocation, dan_dc_allocation_t);

/* ---- uavcan.protocol.param.Value / NumericValue ----
 * Value: a union with a 3-bit tag (NumericValue: 2 bits, no boolean or
 * string). The string is nested, so it keeps its 8-bit length prefix. */
#define DAN_DC_PARAM_EMPTY      0u
#define DAN_DC_PARAM_INTEGER    1u
#define DAN_DC_PARAM_REAL       2u
#define DAN_DC_PARAM_BOOLEAN    3u
#define DAN_DC_PARAM_STRING     4u
#define DAN_DC_PARAM_STRING_MAX 128u
#define DAN_DC_PARAM_NAME_MAX   92u

typedef struct {
    uint8_t tag;        /* DAN_DC_PARAM_* */
    uint8_t boolean;    /* BOOLEAN: 0 or 1 as sent (uint8) */
    uint8_t string_len; /* STRING */
    int64_t integer;    /* INTEGER */
    float real;         /* REAL */
    uint8_t string[DAN_DC_PARAM_STRING_MAX];
} dan_dc_param_value_t;

/* ---- uavcan.protocol.param.GetSet (service 11) ----
 * Request: uint13 index, Value value, uint8[<=92] name (TAO).
 * Response: void5, Value value, void5, Value default_value, void6,
 * NumericValue max_value, void6, NumericValue min_value, uint8[<=92] name
 * (TAO). An empty name or value means "no such parameter". */
#define DAN_DC_PARAM_GETSET_ID           11u
#define DAN_DC_PARAM_GETSET_SIGNATURE    0xA7B622F939D1A4D5ull
#define DAN_DC_PARAM_INDEX_MAX           8191u /* uint13 */
#define DAN_DC_PARAM_GETSET_REQ_MAX_SIZE 223u
#define DAN_DC_PARAM_GETSET_RSP_MAX_SIZE 370u

typedef struct {
    uint16_t index;
    dan_dc_param_value_t value; /* EMPTY: get; else set */
    uint8_t name_len;
    char name[DAN_DC_PARAM_NAME_MAX + 1u]; /* decode NUL-terminates */
} dan_dc_param_getset_req_t;

typedef struct {
    dan_dc_param_value_t value;
    dan_dc_param_value_t default_value;
    dan_dc_param_value_t max_value; /* EMPTY, INTEGER or REAL */
    dan_dc_param_value_t min_value;
    uint8_t name_len;
    char name[DAN_DC_PARAM_NAME_MAX + 1u];
} dan_dc_param_getset_rsp_t;

DAN_DC_CODEC(dan_dc_param_getset_req, dan_dc_param_getset_req_t);
DAN_DC_CODEC(dan_dc_param_getset_rsp, dan_dc_param_getset_rsp_t);

/* ---- uavcan.protocol.param.ExecuteOpcode (service 10) ----
 * Request: uint8 opcode, int48 argument. Response: int48 argument, bool ok. */
#define DAN_DC_PARAM_OPCODE_ID        10u
#define DAN_DC_PARAM_OPCODE_SIGNATURE 0x3B131AC5EB69D2CDull
#define DAN_DC_PARAM_OPCODE_SAVE      0u
#define DAN_DC_PARAM_OPCODE_ERASE     1u

typedef struct {
    uint8_t opcode;   /* request */
    int64_t argument; /* int48 */
    bool ok;          /* response */
} dan_dc_param_opcode_t;

DAN_DC_CODEC(dan_dc_param_opcode_req, dan_dc_param_opcode_t);
DAN_DC_CODEC(dan_dc_param_opcode_rsp, dan_dc_param_opcode_t);

/* ---- uavcan.protocol.RestartNode (service 5) ----
 * Request: uint40 magic_number. Response: bool ok. A node rejects any
 * magic but DAN_DC_RESTART_MAGIC (some bootloaders define their own). */
#define DAN_DC_RESTART_ID        5u
#define DAN_DC_RESTART_SIGNATURE 0x569E05394A3017F0ull
#define DAN_DC_RESTART_MAGIC     0xACCE551B1Eull
#define DAN_DC_RESTART_MAGIC_MAX 0xFFFFFFFFFFull /* uint40 */

int dan_dc_restart_req_encode(uint64_t magic, uint8_t *buf, size_t cap);
int dan_dc_restart_req_decode(uint64_t *magic, const uint8_t *buf, size_t len);
int dan_dc_restart_rsp_encode(bool ok, uint8_t *buf, size_t cap);
int dan_dc_restart_rsp_decode(bool *ok, const uint8_t *buf, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_DSDL_MGMT_H */
