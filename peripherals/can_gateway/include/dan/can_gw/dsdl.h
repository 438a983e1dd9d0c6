/*
 * DSDL message codecs the gateway node uses (DroneCAN / UAVCAN v0).
 *
 * Data type IDs and signatures are from the DroneCAN DSDL definitions as
 * shipped in pydronecan 1.0.27 (dronecan/dsdl_specs; the signatures printed
 * by get_data_type_signature()).
 *
 * Every codec follows one pattern:
 *   int dan_dc_<msg>_encode(const T *m, uint8_t *buf, size_t cap);
 *     Returns the payload length in bytes, or DAN_ERR_ARG (NULL m, array
 *     length above its maximum) or DAN_ERR_OVERFLOW (cap too small). With
 *     buf NULL it returns the size only. Integer fields wider than their
 *     DSDL bit length saturate (DSDL saturated cast); float16 fields too.
 *   int dan_dc_<msg>_decode(T *m, const uint8_t *buf, size_t len);
 *     Returns DAN_OK or DAN_ERR_MALFORMED (too short, array length above its
 *     maximum) or DAN_ERR_ARG. Never reads outside buf[0..len). *m is zeroed
 *     first. Extra trailing bytes after a fixed-size message are accepted
 *     (like pydronecan), a tail array takes all of them.
 *
 * Tail array optimization (TAO): the trailing dynamic array of a top-level
 * message (RawCommand.cmd, GetNodeInfo response's name, tunnel buffers) has
 * no length prefix; its length is what the payload holds. Arrays inside
 * nested types (HardwareVersion.certificate_of_authenticity) keep it.
 */
#ifndef DAN_DSDL_H
#define DAN_DSDL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/can_gw/dronecan.h"
#include "dan/can_gw/dronecan_limits.h"
#include "dan/can_gw/dsdl_bits.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- uavcan.protocol.NodeStatus (message 341) ---- */

#define DAN_DC_NODE_STATUS_ID        341u
#define DAN_DC_NODE_STATUS_SIGNATURE 0x0F0868D0C1A7C6F1ull
#define DAN_DC_NODE_STATUS_MAX_SIZE  7u

#define DAN_DC_HEALTH_OK                 0u
#define DAN_DC_HEALTH_WARNING            1u
#define DAN_DC_HEALTH_ERROR              2u
#define DAN_DC_HEALTH_CRITICAL           3u
#define DAN_DC_MODE_OPERATIONAL          0u
#define DAN_DC_MODE_INITIALIZATION       1u
#define DAN_DC_MODE_MAINTENANCE          2u
#define DAN_DC_MODE_SOFTWARE_UPDATE      3u
#define DAN_DC_MODE_OFFLINE              7u
/* Broadcast at least this often; a node silent for OFFLINE_TIMEOUT is gone. */
#define DAN_DC_NODE_STATUS_MAX_PERIOD_MS 1000u
#define DAN_DC_NODE_STATUS_OFFLINE_MS    3000u

typedef struct {
    uint32_t uptime_sec;
    uint8_t health;   /* uint2 */
    uint8_t mode;     /* uint3 */
    uint8_t sub_mode; /* uint3 */
    uint16_t vendor_specific_status_code;
} dan_dc_node_status_t;

DAN_DC_CODEC(dan_dc_node_status, dan_dc_node_status_t);

/* ---- uavcan.protocol.GetNodeInfo (service 1) ----
 * Request: empty. Response: NodeStatus, SoftwareVersion, HardwareVersion,
 * uint8[<=80] name (TAO). */

#define DAN_DC_GET_NODE_INFO_ID           1u
#define DAN_DC_GET_NODE_INFO_SIGNATURE    0xEE468A8121C46A9Eull
#define DAN_DC_COA_MAX                    255u
/* 7 status + 15 software + 2 + 16 + 1 + 255 hardware + 80 name */
#define DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE 376u

#define DAN_DC_SW_FLAG_VCS_COMMIT 1u
#define DAN_DC_SW_FLAG_IMAGE_CRC  2u

typedef struct {
    uint8_t major;
    uint8_t minor;
    uint8_t optional_field_flags; /* DAN_DC_SW_FLAG_* */
    uint32_t vcs_commit;
    uint64_t image_crc;
} dan_dc_software_version_t;

typedef struct {
    uint8_t major;
    uint8_t minor;
    uint8_t unique_id[DAN_DC_UNIQUE_ID_SIZE];
    uint8_t coa_len; /* 0..255 */
    uint8_t certificate_of_authenticity[DAN_DC_COA_MAX];
} dan_dc_hardware_version_t;

typedef struct {
    dan_dc_node_status_t status;
    dan_dc_software_version_t software_version;
    dan_dc_hardware_version_t hardware_version;
    uint8_t name_len;                              /* 0..80 */
    char name[DAN_DC_GET_NODE_INFO_NAME_MAX + 1u]; /* decode NUL-terminates;
                                     encode sends name_len bytes */
} dan_dc_get_node_info_rsp_t;

/* The request has no fields: encode returns 0, decode accepts any bytes. */
int dan_dc_get_node_info_req_encode(uint8_t *buf, size_t cap);
int dan_dc_get_node_info_req_decode(const uint8_t *buf, size_t len);
DAN_DC_CODEC(dan_dc_get_node_info_rsp, dan_dc_get_node_info_rsp_t);

/* ---- uavcan.equipment.esc.RawCommand (message 1030): int14[<=20] cmd ---- */

#define DAN_DC_ESC_RAW_COMMAND_ID        1030u
#define DAN_DC_ESC_RAW_COMMAND_SIGNATURE 0x217F5C87D7EC951Dull
#define DAN_DC_ESC_RAW_COMMAND_MAX_SIZE  35u /* 20 * 14 bits */

typedef struct {
    uint8_t count;                                /* 0..20 */
    int16_t cmd[DAN_DC_ESC_RAW_COMMAND_MAX_CMDS]; /* saturated to int14 */
} dan_dc_esc_raw_command_t;

DAN_DC_CODEC(dan_dc_esc_raw_command, dan_dc_esc_raw_command_t);

/* ---- uavcan.equipment.esc.Status (message 1034) ---- */

#define DAN_DC_ESC_STATUS_ID        1034u
#define DAN_DC_ESC_STATUS_SIGNATURE 0xA9AF28AEA2FBB254ull
#define DAN_DC_ESC_STATUS_MAX_SIZE  14u /* 110 bits */

/* The float16 fields stay bit patterns: the gateway passes them to the FC
 * unchanged (dan_f16_to_f32() / dan_f16_from_f32() in f16.h convert). */
typedef struct {
    uint32_t error_count;
    uint16_t voltage_f16;     /* V */
    uint16_t current_f16;     /* A, negative when braking */
    uint16_t temperature_f16; /* K */
    int32_t rpm;              /* int18 */
    uint8_t power_rating_pct; /* uint7 */
    uint8_t esc_index;        /* uint5 */
} dan_dc_esc_status_t;

DAN_DC_CODEC(dan_dc_esc_status, dan_dc_esc_status_t);

/* ---- uavcan.equipment.esc.StatusExtended (message 1036) ---- */

#define DAN_DC_ESC_STATUS_EXTENDED_ID        1036u
#define DAN_DC_ESC_STATUS_EXTENDED_SIGNATURE 0x02DC203C50960EDCull
#define DAN_DC_ESC_STATUS_EXTENDED_MAX_SIZE  7u /* 56 bits */

typedef struct {
    uint8_t input_pct;              /* uint7 */
    uint8_t output_pct;             /* uint7 */
    int16_t motor_temperature_degC; /* int9 */
    uint16_t motor_angle;           /* uint9, degrees */
    uint32_t status_flags;          /* uint19 */
    uint8_t esc_index;              /* uint5 */
} dan_dc_esc_status_extended_t;

DAN_DC_CODEC(dan_dc_esc_status_extended, dan_dc_esc_status_extended_t);

/* ---- uavcan.equipment.safety.ArmingStatus (message 1100) ---- */

#define DAN_DC_ARMING_STATUS_ID          1100u
#define DAN_DC_ARMING_STATUS_SIGNATURE   0x8700F375556A8003ull
#define DAN_DC_ARMING_STATUS_MAX_SIZE    1u
#define DAN_DC_ARMING_STATUS_DISARMED    0u
#define DAN_DC_ARMING_STATUS_FULLY_ARMED 255u

typedef struct {
    uint8_t status;
} dan_dc_arming_status_t;

DAN_DC_CODEC(dan_dc_arming_status, dan_dc_arming_status_t);

/* ---- uavcan.tunnel (Protocol is a nested uint8) ---- */

#define DAN_DC_TUNNEL_MAVLINK     0u
#define DAN_DC_TUNNEL_MAVLINK2    1u
#define DAN_DC_TUNNEL_GPS_GENERIC 2u
#define DAN_DC_TUNNEL_UNDEFINED   255u

/* uavcan.tunnel.Targetted (message 3001): Protocol protocol, uint7
 * target_node, int5 serial_id, uint4 options, uint24 baudrate,
 * uint8[<=120] buffer (TAO). */
#define DAN_DC_TUNNEL_TARGETTED_ID         3001u
#define DAN_DC_TUNNEL_TARGETTED_SIGNATURE  0xB138E7EA72A2A2E9ull
#define DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX 120u
#define DAN_DC_TUNNEL_TARGETTED_MAX_SIZE   126u
#define DAN_DC_TUNNEL_OPTION_LOCK_PORT     1u
#define DAN_DC_TUNNEL_SERIAL_ID_MIN        (-16) /* int5 */
#define DAN_DC_TUNNEL_SERIAL_ID_MAX        15
#define DAN_DC_TUNNEL_OPTIONS_MAX          15u       /* uint4 */
#define DAN_DC_TUNNEL_BAUD_MAX             0xFFFFFFu /* uint24 */

typedef struct {
    uint8_t protocol;    /* DAN_DC_TUNNEL_* */
    uint8_t target_node; /* uint7 */
    int8_t serial_id;    /* int5; -1 conventionally means "any/default" */
    uint8_t options;     /* uint4: DAN_DC_TUNNEL_OPTION_* */
    uint32_t baudrate;   /* uint24; 0 = leave unchanged */
    uint8_t buffer_len;  /* 0..120 */
    uint8_t buffer[DAN_DC_TUNNEL_TARGETTED_BUFFER_MAX];
} dan_dc_tunnel_targetted_t;

DAN_DC_CODEC(dan_dc_tunnel_targetted, dan_dc_tunnel_targetted_t);

/* uavcan.tunnel.Broadcast (message 2010): Protocol protocol, uint8
 * channel_id, uint8[<=60] buffer (TAO). */
#define DAN_DC_TUNNEL_BROADCAST_ID         2010u
#define DAN_DC_TUNNEL_BROADCAST_SIGNATURE  0x5AA2D4D9CF4B1E85ull
#define DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX 60u
#define DAN_DC_TUNNEL_BROADCAST_MAX_SIZE   62u

typedef struct {
    uint8_t protocol;
    uint8_t channel_id;
    uint8_t buffer_len; /* 0..60 */
    uint8_t buffer[DAN_DC_TUNNEL_BROADCAST_BUFFER_MAX];
} dan_dc_tunnel_broadcast_t;

DAN_DC_CODEC(dan_dc_tunnel_broadcast, dan_dc_tunnel_broadcast_t);

/* Signature of a data type this file knows, by transfer kind (messages:
 * DAN_DC_TRANSFER_BROADCAST; services: either request or response) and ID;
 * false if unknown. Handy as the core of a dan_dc_accept_fn. */
bool dan_dc_dsdl_signature(uint8_t transfer_type, uint16_t data_type_id, uint64_t *signature);

#ifdef __cplusplus
}
#endif

#endif /* DAN_DSDL_H */
