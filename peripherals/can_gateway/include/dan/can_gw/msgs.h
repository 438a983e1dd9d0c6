/*
 * CAN-over-DAN gateway messages (codes 0x42..0x4F and 0x52..0x5F, the
 * rest in msgs_fast.h, msgs_mgmt.h, msgs_out.h, msgs_file.h): the payload codec
 * shared by the gateway (peripheral side) and the FC's client
 * (dan/can_gw/client.h).
 * docs/PROTOCOL.md section 7 is the byte-level definition; the vectors in
 * tests/vectors/gateway.txt pin it.
 *
 * Conventions (as in dan/payloads.h): encoders take a caller buffer and
 * return the payload length or a negative DAN_ERR_*; with out == NULL they
 * return the size only. Decoders never read outside the payload, return
 * DAN_ERR_MALFORMED for a truncated payload or a field out of range, and
 * ignore trailing bytes. Repeated items (telemetry records, node entries,
 * CAN frames, filters) are read one at a time with a dan_reader_t left
 * after the header, so nobody needs an array of them.
 *
 * Portable C99; no allocation, no globals.
 */
#ifndef DAN_GATEWAY_MSGS_H
#define DAN_GATEWAY_MSGS_H

#include "dan/can_gw/can.h"
#include "dan/can_gw/dronecan_limits.h"
#include "dan/can_gw/f16.h"
#include "dan/common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- codes (block 0x40..0x4F; 0x40 IDENTIFY, 0x41 CONFIGURE) ---- */
#define DAN_GW_CODE_ESC_CMD    0x42u /* ESC command -> one ESC's telemetry */
#define DAN_GW_CODE_ESC_TELEM  0x43u /* paged telemetry of every ESC */
#define DAN_GW_CODE_ARM        0x44u /* armed state -> ArmingStatus */
#define DAN_GW_CODE_CONFIG     0x45u /* read / set gateway settings */
#define DAN_GW_CODE_STATS      0x46u /* counters of both sides */
#define DAN_GW_CODE_NODES      0x47u /* paged node table (NodeStatus) */
#define DAN_GW_CODE_NODE_INFO  0x48u /* one node's GetNodeInfo data */
#define DAN_GW_CODE_TUN_OPEN   0x49u /* open / configure / close a tunnel */
#define DAN_GW_CODE_TUN_XFER   0x4Au /* tunnel write + read, by offset */
#define DAN_GW_CODE_CAN_SEND   0x4Bu /* raw CAN frames to the bus */
#define DAN_GW_CODE_CAN_RECV   0x4Cu /* filtered raw CAN frames from the bus */
#define DAN_GW_CODE_CAN_FILTER 0x4Du /* raw receive filter */
/* 0x4E NODE_CALL, 0x4F CALL_RESULT: msgs_mgmt.h; 0x52..0x5F: the other
 * msgs_*.h */

/* ---- limits of the message set ---- */
#define DAN_GW_ESC_MAX        DAN_DC_ESC_RAW_COMMAND_MAX_CMDS /* channels per ESC_CMD */
#define DAN_GW_ESC_INDEX_MAX  DAN_DC_ESC_INDEX_MAX
#define DAN_GW_TUN_CHUNK_MAX  128u  /* data bytes in one TUN_XFER either way */
#define DAN_GW_CAN_FRAMES_MAX 11u   /* frames in one CAN_SEND / CAN_RECV */
#define DAN_GW_FILTERS_MAX    16u   /* filters in one CAN_FILTER */
#define DAN_GW_NONE           0xFFu /* "no next page" index */

/* Gateway flags byte, in several responses. */
#define DAN_GW_FLAG_ARMED      0x01u /* ArmingStatus being broadcast: armed */
#define DAN_GW_FLAG_FAILSAFE   0x02u /* failsafe active (commands stopped) */
#define DAN_GW_FLAG_CAN_OK     0x04u /* CAN interface up */
#define DAN_GW_FLAG_SAFETY_OFF 0x08u /* SafetyState being broadcast: safety off */

/* ---- ESC command (0x42) ----
 * Request: uint8 n (1..20), then the n int14 values bit-packed: value i
 * occupies stream bits 14i..14i+13, least significant bit first, stream
 * bit k is bit (k % 8) of byte k / 8; the last byte is zero-padded.
 * Response: a telemetry header and 0 or 1 records (see below). */
#define DAN_GW_ESC_CMD_SIZE(n) (1u + ((n)*14u + 7u) / 8u)

/* Values outside -8192..8191 are DAN_ERR_ARG (no silent clipping). */
int dan_gw_msg_esc_cmd_encode(const int16_t *values, size_t n, uint8_t *out, size_t cap);
/* values must hold DAN_GW_ESC_MAX entries. n 0 or above 20 is malformed. */
int dan_gw_msg_esc_cmd_decode(const uint8_t *p, size_t len, int16_t *values, size_t *n);

/* ---- ESC telemetry record (ESC_CMD and ESC_TELEM responses) ----
 * Floats stay IEEE binary16 bit patterns exactly as the ESC sent them in
 * esc.Status (dan_f16_to_f32() in dan/can_gw/f16.h converts). */
#define DAN_GW_TELEM_STATUS 0x01u /* esc.Status fields valid */
#define DAN_GW_TELEM_EXT    0x02u /* esc.StatusExtended fields valid */
#define DAN_GW_TELEM_DEVICE 0x04u /* device.Temperature of the same node valid */
#define DAN_GW_TELEM_ALL    0x07u

typedef struct {
    uint8_t esc_index;        /* 0..31 */
    uint8_t node_id;          /* sender of the newest message */
    uint8_t flags;            /* DAN_GW_TELEM_* */
    uint8_t power_pct;        /* esc.Status.power_rating_pct */
    uint32_t age_ms;          /* since esc.Status arrived */
    uint16_t voltage_f16;     /* V */
    uint16_t current_f16;     /* A */
    uint16_t temperature_f16; /* K */
    uint16_t motor_angle;     /* StatusExtended's; here, it fills the padding */
    int32_t rpm;              /* int18 */
    uint32_t error_count;
    /* StatusExtended */
    uint32_t ext_age_ms;
    uint8_t input_pct;
    uint8_t output_pct;
    int16_t motor_temp_c;
    uint32_t status_flags; /* uint19 */
    /* device.Temperature sent by the same node (e.g. its MCU) */
    uint32_t dev_age_ms;
    uint16_t dev_temp_f16; /* K */
    uint8_t dev_flags;     /* 1 overheating, 2 overcooling */
} dan_gw_telem_t;

/* Header of both telemetry responses: uint8 gw_flags, uint8 aux (ESC_CMD:
 * ESCs known; ESC_TELEM: next esc_index to ask for, DAN_GW_NONE at the end),
 * uint8 count, then count records. */
typedef struct {
    uint8_t gw_flags;
    uint8_t aux;
    uint8_t count;
} dan_gw_telem_hdr_t;
#define DAN_GW_TELEM_HDR_SIZE 3u

DAN_ITEM(dan_gw_msg_telem_hdr, dan_gw_telem_hdr_t);
DAN_ITEM(dan_gw_msg_telem, dan_gw_telem_t);
/* Bytes of one record (a size-only pass of the put). */
size_t dan_gw_msg_telem_size(const dan_gw_telem_t *t);

/* ESC_TELEM request: uint8 first esc_index (records with index >= it). */

/* ---- ARM (0x44) ----
 * Request: uint8 status, the ArmingStatus value (0 disarmed, 255 fully
 * armed; any other value is refused with an error frame). Response:
 * uint8 gw_flags. */
#define DAN_GW_ARM_DISARMED    0u   /* ArmingStatus.STATUS_DISARMED */
#define DAN_GW_ARM_FULLY_ARMED 255u /* ArmingStatus.STATUS_FULLY_ARMED */

/* ---- CONFIG (0x45) ----
 * Request: uint8 set_mask, then for each set bit in bit order its field:
 *   bit0 uvarint esc_timeout_ms (50..60000), bit1 uvarint arming_rate_hz
 *   (1..50), bit2 uvarint telem_timeout_ms (0 or 100..60000), bit3 uint8
 *   dna (0/1). An empty request or mask 0 only reads.
 * Response: uint8 node_id, uvarint esc_timeout_ms, uvarint arming_rate_hz,
 *   uint8 gw_flags, uvarint telem_timeout_ms, uint8 dna (the last two
 *   appended: a response without them decodes with zeros). Values out of
 *   range are malformed (error frame). */
#define DAN_GW_CFG_ESC_TIMEOUT   0x01u
#define DAN_GW_CFG_ARMING_RATE   0x02u
#define DAN_GW_CFG_TELEM_TIMEOUT 0x04u /* uv ms: 0 (off) or 100..60000 */
#define DAN_GW_CFG_DNA           0x08u /* u8: allocation server off (0) / on (1) */
#define DAN_GW_TELEM_TIMEOUT_MIN 100u
#define DAN_GW_TELEM_TIMEOUT_MAX 60000u
#define DAN_GW_ESC_TIMEOUT_MIN   50u
#define DAN_GW_ESC_TIMEOUT_MAX   60000u
#define DAN_GW_ARMING_RATE_MIN   1u
#define DAN_GW_ARMING_RATE_MAX   50u
#define DAN_GW_CONFIG_REQ_MAX    17u /* mask, three 5-byte uvarints, dna */

typedef struct {
    uint8_t set_mask; /* request only */
    uint8_t node_id;  /* response only */
    uint8_t gw_flags; /* response only */
    uint32_t esc_timeout_ms;
    uint32_t arming_rate_hz;
    uint32_t telem_timeout_ms;
    uint8_t dna;
} dan_gw_config_t;

DAN_CODEC(dan_gw_msg_config_req, dan_gw_config_t);
DAN_CODEC(dan_gw_msg_config_rsp, dan_gw_config_t);

/* ---- STATS (0x46) ----
 * Request: empty. Response: uint8 n, then n uvarint counters in this order
 * (later versions append; a decoder keeps the ones it knows). */
/* X(ENUM, name, what): one list for the enum, the names (docs/PROTOCOL.md)
 * and the order on the wire. */
#define DAN_GW_STATS(X)                                                                   \
    X(DAN_FRAMES, dan_frames)           /* valid DAN frames received */                   \
    X(DAN_CRC, dan_crc_errors)          /* DAN frames with a bad CRC */                   \
    X(DAN_UNKNOWN, dan_unknown)         /* frames with codes not ours */                  \
    X(DAN_ERRORS_SENT, dan_errors_sent) /* error frames sent */                           \
    X(DAN_REQUESTS, dan_requests)       /* gateway requests */                            \
    X(CAN_TX, can_tx)                   /* CAN frames queued for the bus */               \
    X(CAN_RX, can_rx)                   /* CAN frames received */                         \
    X(CAN_TX_DROPPED, can_tx_dropped)   /* CAN output queue full */                       \
    X(CAN_ERRORS, can_errors)           /* adapter / bus errors */                        \
    X(DC_TRANSFERS, dc_transfers)       /* DroneCAN transfers received */                 \
    X(DC_CRC, dc_crc_errors)            /* DroneCAN transfer CRC errors */                \
    X(DC_ERRORS, dc_errors)             /* other DroneCAN reassembly errors */            \
    X(ESC_CMDS, esc_cmds)               /* ESC commands received */                       \
    X(FAILSAFES, failsafes)             /* failsafe events */                             \
    X(FAILSAFE_ACTIVE, failsafe_active) /* 1 while active */                              \
    X(TUN_DROPPED, tun_dropped)         /* tunnel bytes dropped (both ways) */            \
    X(RAW_DROPPED, raw_dropped)         /* raw frames dropped (receive ring full) */      \
    X(NODES, nodes)                     /* nodes in the table */                          \
    X(BAD_CHECKS, bad_checks)           /* requests whose seal did not match (dropped) */ \
    X(NODES_DROPPED, nodes_dropped)     /* new nodes with no room in the table */         \
    X(DNA_ALLOCATIONS, dna_allocations) /* node IDs handed out */                         \
    X(DNA_BAD, dna_bad)                 /* allocation requests ignored */                 \
    X(DNA_FOREIGN, dna_foreign)         /* Allocation messages of another allocator */    \
    X(DUPLICATES, duplicates)           /* nodes flagged as sharing an ID */              \
    X(CALLS, calls)                     /* service calls started */                       \
    X(CALL_TIMEOUTS, call_timeouts)     /* service calls never answered */                \
    X(SERVO_CMDS, servo_cmds)           /* SERVO requests */                              \
    X(SERVO_DROPPED, servo_dropped)     /* actuators beyond the node's table */           \
    X(FILE_READS, file_reads)           /* file.Read requests served */                   \
    X(FILE_BYTES, file_bytes)           /* file bytes served to nodes */                  \
    X(FILE_ERRORS, file_errors)         /* file.GetInfo / Read answered an error */       \
    X(UPLOAD_BYTES, upload_bytes)       /* upload bytes written to the store */           \
    X(FILE_COMMITS, file_commits)       /* uploads committed */                           \
    X(UPLOAD_ERRORS, upload_errors)     /* store failures of the DAN file messages */     \
    X(FW_BEGINS, fw_begins)             /* BeginFirmwareUpdate answered OK */             \
    X(FILE_DROPPED, file_dropped)       /* file requests not answered: no room for long */

#define DAN_GW_STAT_ENUM_(e, name) DAN_GW_STAT_##e,
enum { DAN_GW_STATS(DAN_GW_STAT_ENUM_) DAN_GW_STAT_COUNT };

/* The counter's name as in docs/PROTOCOL.md ("dan_frames"), or NULL. */
const char *dan_gw_stat_name(unsigned i);

int dan_gw_msg_stats_encode(const uint32_t *v, size_t n, uint8_t *out, size_t cap);
/* Fills v[0..cap) (unknown trailing counters skipped, missing ones 0);
 * *n is the count sent. */
int dan_gw_msg_stats_decode(uint32_t *v, size_t cap, size_t *n, const uint8_t *p, size_t len);

/* ---- NODES (0x47) ----
 * Request: uint8 first node_id. Response: uint8 next node_id to ask for
 * (0 at the end), uint8 count, then entries of node_id >= first:
 *   uint8 node_id, uint8 health | mode << 2 | sub_mode << 5,
 *   uvarint uptime_sec, uint16 vendor_status, uvarint age_ms,
 *   uint8 info_state (DAN_GW_INFO_*, bits 0-1) | flags (DAN_GW_NODE_*). */
#define DAN_GW_INFO_NONE      0u /* not asked yet */
#define DAN_GW_INFO_PENDING   1u /* GetNodeInfo requested */
#define DAN_GW_INFO_VALID     2u
#define DAN_GW_INFO_FAILED    3u    /* no answer after the retries */
#define DAN_GW_INFO_MASK      0x03u /* the entry's last byte: state | flags */
#define DAN_GW_NODE_DUPLICATE 0x04u /* two nodes use this ID */
#define DAN_GW_NODE_OFFLINE   0x08u /* seen, then silent over 3 s */
#define DAN_GW_NODE_ALLOCATED 0x10u /* its ID came from the gateway's allocator */

typedef struct {
    uint8_t node_id;
    uint8_t health;
    uint8_t mode;
    uint8_t sub_mode;
    uint32_t uptime_sec;
    uint16_t vendor_status;
    uint32_t age_ms;
    uint8_t info_state;
} dan_gw_node_entry_t;

typedef struct {
    uint8_t next;
    uint8_t count;
} dan_gw_nodes_hdr_t;
#define DAN_GW_NODES_HDR_SIZE 2u

DAN_ITEM(dan_gw_msg_nodes_hdr, dan_gw_nodes_hdr_t);
DAN_ITEM(dan_gw_msg_node, dan_gw_node_entry_t);
size_t dan_gw_msg_node_size(const dan_gw_node_entry_t *n);

/* ---- NODE_INFO (0x48) ----
 * Request: uint8 node_id. Response: uint8 node_id, uint8 info_state, and
 * when it is DAN_GW_INFO_VALID: uint8 sw_major, uint8 sw_minor, uint8
 * sw_flags, uint32 vcs_commit, uint8 hw_major, uint8 hw_minor, 16 bytes
 * unique_id, string name (<= 80). Unknown node: error frame.
 * Appended (after the info, or after info_state without it; an older
 * response lacks them: follow false): u8 status (health | mode << 2 |
 * sub_mode << 5 of its last NodeStatus, 0xFF none), u8 file_flags (bit0
 * BeginFirmwareUpdate answered OK, bit1 it has read since), uv bytes_read
 * (highest offset + length served since FW_BEGIN), uv file_size (of the
 * file it read, 0 none), u32 ms since its last read (0xFFFFFFFF never). */
#define DAN_GW_STATUS_NONE 0xFFu
#define DAN_GW_NEVER_MS    0xFFFFFFFFu
typedef struct {
    uint8_t node_id;
    uint8_t info_state;
    uint8_t sw_major, sw_minor, sw_flags;
    uint32_t vcs_commit;
    uint8_t hw_major, hw_minor;
    uint8_t unique_id[DAN_DC_UNIQUE_ID_SIZE];
    char name[DAN_DC_GET_NODE_INFO_NAME_MAX + 1u];
    bool follow; /* the fields below are sent / were received */
    uint8_t status;
    uint8_t file_flags;
    uint32_t bytes_read;
    uint32_t file_size;
    uint32_t since_read_ms;
} dan_gw_node_info_t;

DAN_CODEC(dan_gw_msg_node_info, dan_gw_node_info_t);

/* ---- TUN_OPEN (0x49) ----
 * Request: uint8 port, uint8 mode (DAN_GW_TUN_*), uint8 protocol, uint8
 * target (Targetted: node id; Broadcast: channel_id), int8 serial_id,
 * uint8 options (Targetted: the DSDL options, bit0 LOCK_PORT; Broadcast:
 * bit0 DAN_GW_TUN_ANY_CHANNEL), uvarint baud.
 * Targetted serial_id -1 (DAN_GW_TUN_DEFAULT_SERIAL) asks the node for its
 * default port; replies from the target with any serial_id are then ours,
 * because nodes answer with the port they resolved (AP_Periph does).
 * Broadcast with ANY_CHANNEL accepts replies on every channel_id of the
 * protocol (some nodes ignore channel_id when they answer).
 * Opening (again) discards buffered data and restarts both offsets at 0.
 * Response: uint8 port, uint8 result (0 OK, 1 refused: bad port or field). */
#define DAN_GW_TUN_CLOSED    0u
#define DAN_GW_TUN_TARGETTED 1u
#define DAN_GW_TUN_BROADCAST 2u

#define DAN_GW_TUN_DEFAULT_SERIAL (-1)  /* Targetted serial_id: the node's default */
#define DAN_GW_TUN_ANY_CHANNEL    0x01u /* Broadcast option: replies on any channel */

typedef struct {
    uint8_t port;
    uint8_t mode;
    uint8_t protocol;
    uint8_t target;
    int8_t serial_id;
    uint8_t options;
    uint32_t baud;
} dan_gw_tun_open_t;

#define DAN_GW_TUN_OPEN_REQ_MAX 11u /* six bytes + a 5-byte uvarint */
DAN_CODEC(dan_gw_msg_tun_open, dan_gw_tun_open_t);

/* ---- TUN_XFER (0x4A) ----
 * Request: uint8 port, uvarint wr_offset (stream offset of data[0], modulo
 * 2^32), uvarint rd_offset (every byte before it was received: the gateway
 * may forget them), uvarint rd_max, array data (<= 128).
 * The gateway appends the bytes of data from its wr_next on (a retried
 * request repeats bytes it has: they are skipped; a gap is refused) as far
 * as its buffer has space.
 * Response: uint8 port, uvarint wr_next (bytes accepted so far), uvarint
 * wr_space, uvarint rd_offset (offset of data[0]: the request's; this
 * gateway drops new bytes when full, never old ones, so never later; a
 * client counts a later one as lost), uvarint rd_dropped (total bytes
 * dropped for a full buffer, CAN -> DAN), array data (<= min(rd_max, 128)). */
typedef struct {
    uint8_t port;
    uint32_t wr_offset; /* req: offset of data; rsp: wr_next */
    uint32_t wr_space;  /* rsp */
    uint32_t rd_offset;
    uint32_t rd_max;     /* req */
    uint32_t rd_dropped; /* rsp */
    const uint8_t *data; /* decode: a view into the payload */
    size_t len;
} dan_gw_tun_xfer_t;

DAN_CODEC(dan_gw_msg_tun_xfer_req, dan_gw_tun_xfer_t);
DAN_CODEC(dan_gw_msg_tun_xfer_rsp, dan_gw_tun_xfer_t);

/* ---- CAN frame item (CAN_SEND, CAN_RECV) ----
 * uint32 id_flags (bits 0..28 identifier, bit 31 extended, bit 30 RTR),
 * uint8 dlc (0..8), dlc data bytes (none for RTR). */
#define DAN_GW_CAN_ID_EXT 0x80000000u
#define DAN_GW_CAN_ID_RTR 0x40000000u
#define DAN_GW_CAN_ID_OWN \
    0x20000000u /* CAN_RECV: sent by the gateway itself;
                                               CAN_FILTER: passes its own frames too */

DAN_ITEM(dan_gw_msg_can_frame, dan_can_frame_t);
size_t dan_gw_msg_can_frame_size(const dan_can_frame_t *f);

/* CAN_SEND request: uint8 seq, uint8 count (<= 11), frames. A request with
 * the seq and the content (CRC-32) of the previous accepted one is a retry:
 * not sent again.
 * Response: uint8 seq, uint8 accepted, uvarint queue_free. */
typedef struct {
    uint8_t seq;
    uint8_t count;       /* req: frames; rsp: accepted */
    uint32_t queue_free; /* rsp */
} dan_gw_can_send_t;

/* CAN_RECV request: uvarint next_seq (frames before it were received),
 * uint8 max. Response: uvarint first_seq (of the first frame here),
 * uvarint dropped (total), uint8 count, frames. */
#define DAN_GW_CAN_RECV_HDR_MAX 11u /* the response header at its largest */
typedef struct {
    uint32_t seq;     /* req: next_seq; rsp: first_seq */
    uint32_t dropped; /* rsp */
    uint8_t count;    /* req: max; rsp: frames */
    uint8_t opts;     /* req: DAN_GW_RECV_* (sent when not 0); rsp: as asked */
    uint32_t t0_us;   /* rsp with DAN_GW_RECV_TIMES: first frame's receive time */
} dan_gw_can_recv_t;
/* CAN_RECV request opts (an optional third byte). TIMES: the response has
 * u32 t0_us after its header and a uv dt_us after each frame (microseconds
 * since the previous frame of the response; 0 for the first). */
#define DAN_GW_RECV_TIMES         0x01u
#define DAN_GW_CAN_RECV_TIME_SIZE 4u

/* CAN_FILTER request: uint8 op (DAN_GW_FILTER_*), uint8 count (<= 16),
 * entries uint32 id_flags (bit 31 extended, bit 29 own frames too), uint32
 * mask. A frame passes when some entry has its ext flag and (id & mask) ==
 * (entry id & mask); the gateway's own frames only through an entry with
 * bit 29.
 * No entries: nothing passes (the default). ADD of an entry present and
 * REMOVE of one absent do nothing, so retries are harmless.
 * Response: uint8 result (0 OK, 1 table full), uint8 count, the table. */
#define DAN_GW_FILTER_REPLACE 0u
#define DAN_GW_FILTER_ADD     1u
#define DAN_GW_FILTER_REMOVE  2u
#define DAN_GW_FILTER_READ    3u

typedef struct {
    uint32_t id; /* with DAN_GW_CAN_ID_EXT */
    uint32_t mask;
} dan_gw_filter_t;

/* Header of CAN_SEND / CAN_RECV / CAN_FILTER: fixed fields before the
 * items; items follow with dan_gw_msg_can_frame_* / dan_gw_msg_filter_*. */
DAN_ITEM(dan_gw_msg_can_send_req, dan_gw_can_send_t);
DAN_CODEC(dan_gw_msg_can_send_rsp, dan_gw_can_send_t);
#define DAN_GW_CAN_RECV_REQ_MAX 7u /* a 5-byte uvarint, max, opts */
DAN_CODEC(dan_gw_msg_can_recv_req, dan_gw_can_recv_t);
DAN_ITEM(dan_gw_msg_can_recv_rsp, dan_gw_can_recv_t);
/* op/result byte then count */
void dan_gw_msg_filter_hdr_put(dan_writer_t *w, uint8_t op, uint8_t count);
int dan_gw_msg_filter_hdr_get(dan_reader_t *r, uint8_t *op, uint8_t *count);
DAN_ITEM(dan_gw_msg_filter, dan_gw_filter_t);
/* True if f passes filter e. */
bool dan_gw_filter_match(const dan_gw_filter_t *e, const dan_can_frame_t *f);

/* Signed difference a - b of two 32-bit stream offsets (modulo 2^32). */
static inline int32_t dan_gw_off_diff(uint32_t a, uint32_t b)
{
    return (int32_t)(a - b); /* two's complement on every target we build for */
}

/*
 * The seal. crc8 alone accepts about one in 256 frames corrupted by a
 * collision, and a gateway message moves throttle, arming and tunnel bytes:
 * every gateway message (codes 0x42-0x4F and 0x52-0x5F, requests and
 * responses) ends with
 * a u16 (little endian) check, CRC-16/CCITT-FALSE (poly 0x1021, init
 * 0xFFFF) over the code's uvarint bytes, one direction byte (0 request,
 * 1 response: a reply has its request's code and must never pass for one)
 * and the payload before the check. The message codecs above work on the
 * inner payload; the client and the gateway node seal and unseal at the
 * transport (docs/PROTOCOL.md 7).
 */
#define DAN_GW_SEAL_SIZE 2u
#define DAN_GW_REQUEST   0u
#define DAN_GW_RESPONSE  1u

/* True for the codes that carry a seal. */
bool dan_gw_sealed_code(uint32_t code);
uint16_t dan_gw_check(uint32_t code, uint8_t dir, const uint8_t *p, size_t len);
/* Appends the check to p (len bytes, cap room): the new length, or
 * DAN_ERR_OVERFLOW. dir: DAN_GW_REQUEST or DAN_GW_RESPONSE. */
int dan_gw_seal(uint32_t code, uint8_t dir, uint8_t *p, size_t len, size_t cap);
/* Verifies a sealed payload: the inner length, or DAN_ERR_MALFORMED. */
int dan_gw_unseal(uint32_t code, uint8_t dir, const uint8_t *p, size_t len);

#ifdef __cplusplus
}
#endif

#endif /* DAN_GATEWAY_MSGS_H */
