/*
 * The CAN-over-DAN gateway node: a DAN peripheral (type block 0x40) on one
 * side, a DroneCAN node on the other. Portable C99, no allocation, no
 * globals, no clock: time comes in as now_us, a monotonic 64-bit microsecond
 * count (a port with a 32-bit counter must extend it: deadlines are compared
 * as absolute times and a wrapped 32-bit count would stop the timers).
 *
 *     dan_gw_node_init(&gwn, &cfg, now);
 *     dan_gw_node_ptype(&gwn, &ptype);               // block 0x40 handlers
 *     dan_periph_init(&p, &port, &ptype, 1, &pcfg, 9600, now);
 *     dan_gw_node_attach(&gwn, &p);                  // for the DAN counters
 *     loop:
 *       CAN frame in     -> dan_gw_node_rx_can(&gwn, &frame, now);
 *       DAN bytes in     -> dan_periph_rx(&p, bytes, n, now);
 *       timers           -> dan_periph_poll(&p, now); dan_gw_node_poll(&gwn, now);
 *       CAN frames out   -> while (dan_gw_node_tx_peek(&gwn, &f)) {
 *                               if (send(&f) busy) break; dan_gw_node_tx_pop(&gwn); }
 *       sleep until min(dan_periph_next_us, dan_gw_node_next_us) or I/O
 *
 * Not reentrant: call every function of one instance from one context (the
 * same one that runs its dan_periph_t). Sizes are set in dan/config.h.
 *
 * DroneCAN behaviour (docs/PROTOCOL.md section 7), one file per subsystem:
 *   - gw_node.c: NodeStatus every second (health OK while a DAN master sent
 *     a request within cfg.master_timeout_ms, WARNING otherwise; mode
 *     OPERATIONAL; vendor-specific status code = the gateway flags byte),
 *     our GetNodeInfo answer, dispatch of received transfers, timers.
 *   - gw_node_txq.c: CAN output, two bounded queues: urgent (ESC, arming,
 *     our NodeStatus: latest-wins states) before bulk (services, raw
 *     frames, tunnels). A transfer that does not fit is dropped whole and
 *     counted.
 *   - gw_node_esc.c: ESC_CMD -> uavcan.equipment.esc.RawCommand broadcast
 *     at once (priority high); esc.Status / StatusExtended per ESC index;
 *     the failsafe: no ESC_CMD for esc_timeout_ms -> RawCommand of zeros
 *     (the channel count last used) and ArmingStatus DISARMED at once, then
 *     both repeated at the arming rate until the next ESC_CMD.
 *   - gw_node_arming.c: ArmingStatus and ArduPilot's SafetyState at
 *     arming_rate_hz, and at once on a change; the failsafe forces
 *     DISARMED and safety ON.
 *   - gw_node_out.c: servos (actuator ArrayCommand, latest wins, a
 *     failsafe value or hold per actuator), LightsCommand, BeepCommand.
 *   - gw_node_table.c: the node table from NodeStatus; GetNodeInfo asked of
 *     every new node up to DAN_GW_NODE_INFO_TRIES times a second apart (and
 *     again after the node restarts: its uptime went down, or its mode
 *     went from SOFTWARE_UPDATE to OPERATIONAL).
 *   - gw_node_tunnel.c: uavcan.tunnel.Targetted as ArduPilot's
 *     AP_DroneCAN_serial does it (chunks <= 120 bytes, an empty keepalive
 *     every 500 ms while idle, options from TUN_OPEN, received only from
 *     the target node with target_node == our id and the port's serial_id)
 *     and tunnel.Broadcast (chunks <= 60, received by protocol and
 *     channel_id).
 *   - gw_node_file.c: the file server (uavcan.protocol.file.GetInfo and
 *     Read from cfg.files; no store: the requests are not answered); notes
 *     each reader's progress in its node table slot (fw). A request whose
 *     answer does not fit the bulk queue waits (DAN_GW_NODE_FILE_WAIT of
 *     them, oldest first, up to DAN_GW_NODE_FILE_WAIT_US).
 *   - gw_node_raw.c: every received CAN frame, processed or not, goes
 *     through the raw filter into the raw receive ring; raw frames out.
 *   - gw_node_dan_file.c: the DAN file messages: one upload at a time
 *     into cfg.files (resumable, also from a partial the store kept through
 *     a restart; retried writes write nothing; committed only with its
 *     CRC-32), listing and removal.
 *   - gw_node_dan.c: the DAN handlers (decode, call the subsystem, encode)
 *     and the seal, as the type's envelope.
 */
#ifndef DAN_CAN_GW_NODE_H
#define DAN_CAN_GW_NODE_H

#include "dan/can_gw/dronecan.h"
#include "dan/can_gw/dsdl.h"
#include "dan/can_gw/dsdl_file.h"
#include "dan/can_gw/dsdl_fw.h"
#include "dan/can_gw/dsdl_mgmt.h"
#include "dan/can_gw/dsdl_out.h"
#include "dan/can_gw/file_store.h"
#include "dan/can_gw/msgs.h"
#include "dan/can_gw/msgs_mgmt.h"
#include "dan/can_gw/msgs_out.h"
#include "dan/peripheral.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- fixed by the protocols (not settings) ---- */
#define DAN_GW_NODE_ESC_SLOTS       32u      /* one per esc_index (uint5) */
#define DAN_GW_NODE_OFFLINE_US      3000000u /* DroneCAN's OFFLINE_TIMEOUT */
#define DAN_GW_NODE_STATUS_US       1000000u /* our NodeStatus period */
#define DAN_GW_NODE_KEEPALIVE_US    500000u  /* ArduPilot's tunnel keepalive */
#define DAN_GW_NODE_INFO_TRIES      3u       /* GetNodeInfo attempts per node */
#define DAN_GW_NODE_INFO_RETRY_US   1000000u
#define DAN_GW_NODE_CALL_TIMEOUT_US 1000000u /* per attempt of a service call */
#define DAN_GW_NODE_CALL_ATTEMPTS   3u
#define DAN_GW_NODE_FLAP_US         10000000u /* uptime going down 3 times in this: duplicate */
#define DAN_GW_NODE_FLAP_COUNT      3u
#define DAN_GW_NODE_FOREIGN_US      60000000u /* HEALTH shows another allocator this long */
#define DAN_GW_NODE_FILE_WAIT_US    1000000u  /* a file request waits this long for room */
/* A node that read a file this recently, and not to its end, is reading it:
 * FILE_COMMIT over that name answers IN_USE (danprobe fw-update's --stall
 * default: after it the reader counts as failed). */
#define DAN_GW_NODE_READER_US       10000000u

#define DAN_GW_NODE_DEFAULT_ID            10u
#define DAN_GW_NODE_DEFAULT_ESC_TIMEOUT   500u  /* ms */
#define DAN_GW_NODE_DEFAULT_ARMING_RATE   2u    /* Hz */
#define DAN_GW_NODE_DEFAULT_TELEM_TIMEOUT 1000u /* ms; 0: no ESC telemetry check */
#define DAN_GW_NODE_NAME                  "org.dan.can_gateway"

/* Persistent storage of the allocation table (flash on an MCU gateway, a
 * file for the daemon). load copies the stored blob into buf (cap bytes)
 * and returns its length, 0 when nothing is stored, negative on an error;
 * store replaces it (DAN_OK or negative). load runs in dan_gw_node_init(),
 * store in dan_gw_node_poll() after the table changed. */
/* The stored blob: "DNA1", u8 count, count x (u8 node_id, 16 bytes
 * unique_id), u16 CRC-16/CCITT-FALSE of everything before it (at most
 * DAN_GW_DNA_BLOB_MAX bytes). dan_gw_dna_blob_check() says why a blob does
 * not check (the node then starts with an empty table and sets
 * DAN_GW_DNA_STORE_ERROR); dan_gw_dna_blob_error() names the reason. */
#define DAN_GW_DNA_BLOB_MAX     (4u + 1u + DAN_GW_NODE_DNA_MAX * DAN_GW_DNA_ENTRY_SIZE + 2u)
#define DAN_GW_DNA_BLOB_OK      0
#define DAN_GW_DNA_BLOB_SHORT   1 /* shorter than an empty table */
#define DAN_GW_DNA_BLOB_MAGIC   2 /* does not start with "DNA1" */
#define DAN_GW_DNA_BLOB_COUNT   3 /* more entries than DAN_GW_NODE_DNA_MAX */
#define DAN_GW_DNA_BLOB_LENGTH  4 /* length and count disagree */
#define DAN_GW_DNA_BLOB_CRC     5
#define DAN_GW_DNA_BLOB_NODE_ID 6 /* an entry's node ID outside 1..125 */
#define DAN_GW_DNA_BLOB_TWICE   7 /* a node ID or a unique ID in two entries */
int dan_gw_dna_blob_check(const uint8_t *b, size_t len);
const char *dan_gw_dna_blob_error(int r);

typedef struct {
    int (*load)(void *ctx, uint8_t *buf, size_t cap);
    int (*store)(void *ctx, const uint8_t *buf, size_t len);
    void *ctx;
} dan_gw_storage_t;

typedef struct {
    uint8_t node_id;            /* 1..127 (default 10) */
    uint32_t esc_timeout_ms;    /* failsafe (default 500) */
    uint32_t arming_rate_hz;    /* ArmingStatus rate (default 2) */
    uint32_t master_timeout_ms; /* health WARNING after this without DAN (1000) */
    uint8_t sw_major, sw_minor;
    uint32_t vcs_commit;
    uint8_t hw_major, hw_minor;
    uint8_t unique_id[DAN_DC_UNIQUE_ID_SIZE];
    const char *name;                    /* GetNodeInfo name (default DAN_GW_NODE_NAME) */
    uint32_t raw_seq_start;              /* first raw-frame sequence number: give each boot a
                                   different one (the daemon uses the clock), so a
                                   client's acknowledgement from before a restart
                                   never discards new frames */
    bool dna;                            /* serve dynamic node ID allocation (default true) */
    const dan_gw_storage_t *dna_storage; /* NULL: the table lives in RAM only */
    uint32_t telem_timeout_ms;           /* HEALTH: commanded ESC without telemetry (1000; 0 off) */
    const dan_gw_file_store_t *files;    /* file server and uploads (NULL: none) */
} dan_gw_node_config_t;

void dan_gw_node_config_default(dan_gw_node_config_t *c);

/* Counters kept here; STATS adds the DAN engine's. */
typedef struct {
    uint32_t can_tx; /* frames queued */
    uint32_t can_rx;
    uint32_t can_tx_dropped; /* frames of transfers that did not fit */
    uint32_t can_errors;     /* reported by the daemon */
    uint32_t esc_cmds;
    uint32_t failsafes;
    uint32_t tun_dropped;     /* bytes, both ways */
    uint32_t raw_dropped;     /* raw receive ring full */
    uint32_t nodes_dropped;   /* node table full */
    uint32_t info_requests;   /* GetNodeInfo requests sent */
    uint32_t dan_requests;    /* gateway requests handled */
    uint32_t bad_checks;      /* requests whose seal failed (dropped) */
    uint32_t dna_allocations; /* node IDs handed out */
    uint32_t dna_bad;         /* allocation requests ignored (stage, length, timeout) */
    uint32_t dna_foreign;     /* Allocation messages of another allocator */
    uint32_t duplicates;      /* nodes flagged as sharing an ID */
    uint32_t calls;           /* service calls started */
    uint32_t call_timeouts;   /* calls no attempt of which was answered */
    uint32_t servo_cmds;      /* SERVO requests */
    uint32_t servo_dropped;   /* actuators beyond DAN_GW_NODE_SERVOS */
    uint32_t file_reads;      /* file.Read requests answered with data or the end */
    uint32_t file_bytes;      /* file bytes served by them */
    uint32_t file_errors;     /* file.GetInfo / Read answered with an error */
    uint32_t file_dropped;    /* file requests not answered: no room for long */
    uint32_t upload_bytes;    /* upload bytes written to the store */
    uint32_t file_commits;    /* uploads committed */
    uint32_t upload_errors;   /* store failures of uploads, lists, removals (IO_ERROR) */
    uint32_t fw_begins;       /* BeginFirmwareUpdate answered OK */
} dan_gw_node_stats_t;

/* ---- the subsystems' state (gw_node_*.c); read-only for callers ---- */

/* CAN output queue (gw_node_txq.c). */
typedef struct {
    dan_can_frame_t f[DAN_GW_NODE_TXQ];
    uint16_t head, len;
    bool mid; /* the last frame taken did not end its transfer: the rest is at head */
} dan_gw_node_txq_t;

/* One ESC index's newest telemetry (gw_node_esc.c). */
typedef struct {
    dan_gw_telem_t t; /* age fields filled when sent */
    uint64_t status_us, ext_us, dev_us;
    bool fresh; /* esc.Status not yet in a compact record (ESC_FAST_T) */
} dan_gw_node_esc_t;

/* ESC commands, telemetry and the failsafe (gw_node_esc.c). */
typedef struct {
    bool active;   /* commands have been received */
    bool failsafe; /* failsafe active */
    uint8_t n;     /* channel count last used */
    uint8_t rr;    /* round-robin position of telemetry records */
    uint64_t last_cmd_us;
    uint64_t start_us; /* commands (re)started flowing */
    dan_gw_node_esc_t slot[DAN_GW_NODE_ESC_SLOTS];
} dan_gw_node_escs_t;

/* ArmingStatus and SafetyState (gw_node_arming.c). */
typedef struct {
    uint8_t status;  /* ArmingStatus value broadcast */
    uint8_t safety;  /* SafetyState value broadcast (ON at start) */
    uint64_t due_us; /* next periodic broadcast */
} dan_gw_node_arming_t;

/* One servo actuator (gw_node_out.c). */
typedef struct {
    dan_gw_servo_t last; /* its newest command */
    dan_gw_servo_t fs;   /* its failsafe command (mode VALUE) */
    uint8_t fs_mode;     /* DAN_GW_SERVO_HOLD / _VALUE */
    bool commanded;      /* last is valid */
} dan_gw_node_servo_t;

/* Servos and their failsafe (gw_node_out.c). */
typedef struct {
    bool active; /* servo commands have been received */
    bool failsafe;
    uint8_t n;           /* actuators known */
    uint8_t first_group; /* the ArrayCommand sent first (of 15 actuators each) */
    uint64_t last_cmd_us;
    dan_gw_node_servo_t servo[DAN_GW_NODE_SERVOS];
} dan_gw_node_servos_t;

/* Firmware-update progress of one node (NODE_INFO's appended fields): the
 * file server (gw_node_file.c) fills it as the node reads, FW_BEGIN
 * (gw_node_call.c) resets it. */
#define DAN_GW_FW_BEGUN   0x01u /* BeginFirmwareUpdate answered OK */
#define DAN_GW_FW_READING 0x02u /* it has read since */
typedef struct {
    uint8_t flags;         /* DAN_GW_FW_* */
    uint32_t bytes_read;   /* highest offset + length served */
    uint32_t file_size;    /* of the file it read (0 none) */
    uint64_t last_read_us; /* 0: never */
    uint32_t name_hash;    /* CRC-32 of the name it read (DAN_GW_NODE_READER_US) */
} dan_gw_node_fw_t;

/* A file request waiting for room in the bulk queue (gw_node_file.c). */
typedef struct {
    uint64_t offset; /* Read */
    uint64_t at_us;  /* received */
    uint16_t dtid;   /* DAN_DC_FILE_READ_ID or DAN_DC_FILE_GETINFO_ID */
    uint8_t src, tid, prio;
    char name[DAN_GW_FILE_NAME_MAX + 1u]; /* "": not a valid path */
} dan_gw_node_file_req_t;

/* One node of the table (gw_node_table.c). */
typedef struct {
    dan_gw_node_entry_t e; /* age_ms filled when sent */
    uint64_t seen_us;
    uint64_t info_due_us;
    uint8_t info_tries;
    uint8_t info_tid; /* our GetNodeInfo transfer ID to this node */
    bool duplicate;   /* two nodes share this ID (until it goes offline) */
    bool had_uid;     /* prev_uid holds an earlier unique ID */
    uint8_t drops;    /* uptime decreases in the current window */
    uint64_t drops_since_us;
    uint8_t prev_uid[DAN_DC_UNIQUE_ID_SIZE];
    dan_gw_node_info_t info;
    dan_gw_node_fw_t fw;
} dan_gw_node_slot_t;

/* The dynamic node ID allocation server (gw_node_dna.c). */
typedef struct {
    uint8_t flags;       /* DAN_GW_DNA_LOADED | DAN_GW_DNA_STORE_ERROR */
    bool dirty;          /* the table changed: store it */
    bool full;           /* the last request found no free entry */
    uint8_t n;           /* entries in use */
    uint8_t foreign;     /* the other allocator last seen (0: none) */
    uint64_t foreign_us; /* ... when (HEALTH reports it for a minute) */
    dan_gw_dna_entry_t table[DAN_GW_NODE_DNA_MAX];
    uint8_t query[DAN_DC_UNIQUE_ID_SIZE]; /* the allocation in progress */
    uint8_t query_len;
    uint64_t query_us;
    /* bit i of seen[i / 8]: node ID i sent NodeStatus since start, whether
     * or not the node table has (or kept) a slot for it: never free */
    uint8_t seen[128u / 8u];
} dan_gw_node_dna_t;

/* One service call (gw_node_call.c). */
typedef struct {
    uint8_t state; /* DAN_GW_CALL_*, or DAN_GW_NODE_CALL_FREE */
    uint8_t op;    /* DAN_GW_CALL_* op */
    uint8_t node_id;
    uint8_t attempts;
    uint8_t tids[DAN_GW_NODE_CALL_ATTEMPTS];
    uint16_t call_id;
    uint32_t digest;    /* CRC-32 of the NODE_CALL request (retry check) */
    uint64_t due_us;    /* this attempt times out */
    uint64_t done_us;   /* finished at (the oldest makes room) */
    uint32_t file_size; /* FW_BEGIN: of the file named */
    uint16_t req_len;   /* the DroneCAN request, for re-sends */
    uint16_t result_len;
    uint8_t req[DAN_DC_PARAM_GETSET_REQ_MAX_SIZE];
    uint8_t result[DAN_GW_PARAM_RESULT_MAX];
} dan_gw_node_call_t;
#define DAN_GW_NODE_CALL_FREE 0xFFu

/* The one upload into the file store (gw_node_dan_file.c). */
typedef struct {
    bool open;      /* an upload is held */
    bool committed; /* closed by a commit: a retried FILE_COMMIT of crc is OK */
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    uint32_t size; /* declared by FILE_OPEN */
    uint32_t have; /* bytes held, contiguous from 0 */
    uint32_t crc;  /* CRC-32 of them (zlib's, chained) */
} dan_gw_node_upload_t;

/* One tunnel port (gw_node_tunnel.c). */
typedef struct {
    dan_gw_tun_open_t cfg; /* cfg.mode DAN_GW_TUN_CLOSED: unused */
    uint32_t wr_next;      /* DAN -> CAN bytes accepted */
    uint32_t tx_len;       /* of them, not yet sent on CAN */
    uint32_t rd_base;      /* CAN -> DAN: oldest byte kept */
    uint32_t rd_end;       /* next byte offset */
    uint32_t rd_dropped;
    uint64_t last_tx_us;
    uint8_t tx[DAN_GW_NODE_TUN_TX_BUF];
    uint8_t rx[DAN_GW_NODE_TUN_RX_BUF];
} dan_gw_node_tun_t;

/* Raw frames both ways and the receive filter (gw_node_raw.c). */
typedef struct {
    dan_gw_filter_t filters[DAN_GW_FILTERS_MAX];
    uint8_t nfilters;
    bool send_seq_valid;
    uint32_t send_digest; /* CRC-32 of the last accepted CAN_SEND (retry check) */
    uint8_t send_seq;     /* last CAN_SEND seq accepted */
    uint8_t send_accepted;
    dan_can_frame_t ring[DAN_GW_NODE_RAW_RX];
    uint32_t ring_us[DAN_GW_NODE_RAW_RX]; /* receive time, low 32 bits */
    uint32_t first;                       /* sequence number of ring[head] */
    uint16_t head, len;
} dan_gw_node_raw_t;

typedef struct {
    dan_gw_node_config_t cfg;
    dan_identity_t identity;
    const dan_periph_t *periph;
    dan_dc_rx_t rx;
    dan_dc_tid_table_t tids;
    dan_gw_node_txq_t q_urgent, q_bulk;
    uint64_t start_us;
    uint64_t last_dan_us; /* last gateway request (0: none yet) */
    uint64_t status_due_us;
    bool can_ok;
    dan_gw_node_escs_t esc;
    dan_gw_node_arming_t arming;
    dan_gw_node_servos_t servos;
    dan_gw_node_slot_t nodes[DAN_GW_NODE_MAX_NODES];
    dan_gw_node_tun_t tun[DAN_GW_NODE_TUNNELS];
    dan_gw_node_raw_t raw;
    dan_gw_node_dna_t dna;
    dan_gw_node_call_t calls[DAN_GW_NODE_CALLS];
    dan_gw_node_file_req_t file_wait[DAN_GW_NODE_FILE_WAIT]; /* oldest first */
    uint8_t file_nwait;
    dan_gw_node_upload_t upload;
    dan_gw_node_stats_t stats;
    /* scratch for DSDL structs too big for a small stack (per instance) */
    union {
        dan_dc_get_node_info_rsp_t info;
        dan_dc_tunnel_targetted_t targetted;
        dan_dc_tunnel_broadcast_t bcast;
        dan_dc_param_getset_req_t getset_req;
        dan_dc_param_getset_rsp_t getset_rsp;
        dan_dc_file_req_t file_req;
        dan_dc_file_read_rsp_t file_rsp;
        dan_dc_fw_begin_req_t fw_req;
    } scratch;
    uint8_t scratch_buf[DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE];
} dan_gw_node_t;

/* cfg may be NULL (defaults). Returns DAN_ERR_ARG for a bad node id. */
int dan_gw_node_init(dan_gw_node_t *g, const dan_gw_node_config_t *cfg, uint64_t now_us);
/* Fills the peripheral type for block 0x40 (user = g). */
void dan_gw_node_ptype(dan_gw_node_t *g, dan_ptype_t *t);
/* The peripheral engine whose counters STATS reports (may be NULL). */
void dan_gw_node_attach(dan_gw_node_t *g, const dan_periph_t *p);
/* The STATS counters (DAN_GW_STAT_*, names: dan_gw_stat_name()). */
void dan_gw_node_counters(const dan_gw_node_t *g, uint32_t v[DAN_GW_STAT_COUNT]);

/* A frame received from the CAN bus. */
void dan_gw_node_rx_can(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us);
/* Timers: NodeStatus, arming, failsafe, GetNodeInfo requests, tunnels. */
void dan_gw_node_poll(dan_gw_node_t *g, uint64_t now_us);
/* Earliest time a poll has something to do. Tunnel bytes waiting for room
 * in the CAN queue ask for no time of their own: poll again after frames
 * left (the loop above does). */
uint64_t dan_gw_node_next_us(const dan_gw_node_t *g, uint64_t now_us);
/* Next frame to send (urgent queue first); false if none. */
bool dan_gw_node_tx_peek(const dan_gw_node_t *g, dan_can_frame_t *f);
/* Removes the frame dan_gw_node_tx_peek() returned (not sent: dropped). */
void dan_gw_node_tx_pop(dan_gw_node_t *g);
/* The frame dan_gw_node_tx_peek() returned left on the bus: removes it and
 * keeps a copy in the raw capture (DAN_CAN_OWN) when a filter asks for the
 * gateway's own frames. */
void dan_gw_node_tx_sent(dan_gw_node_t *g, uint64_t now_us);
/* Frames waiting. */
size_t dan_gw_node_tx_pending(const dan_gw_node_t *g);

/* Forces the failsafe now (daemon shutdown): RawCommand zeros for the last
 * channel count (if commands were ever sent) and ArmingStatus DISARMED,
 * queued urgent. */
void dan_gw_node_failsafe(dan_gw_node_t *g, uint64_t now_us);
/* CAN interface state and errors, from the daemon. */
void dan_gw_node_can_state(dan_gw_node_t *g, bool ok);
void dan_gw_node_can_error(dan_gw_node_t *g);
/* Gateway flags byte (DAN_GW_FLAG_*). */
uint8_t dan_gw_node_flags(const dan_gw_node_t *g);
/* Settings that DAN CONFIG can change too (range-checked: DAN_ERR_ARG). */
int dan_gw_node_set_esc_timeout(dan_gw_node_t *g, uint32_t ms);
int dan_gw_node_set_arming_rate(dan_gw_node_t *g, uint32_t hz, uint64_t now_us);
int dan_gw_node_set_telem_timeout(dan_gw_node_t *g, uint32_t ms);
/* Turns the allocation server on or off. */
void dan_gw_node_set_dna(dan_gw_node_t *g, bool on);
/* The health verdict now (docs/PROTOCOL.md, HEALTH). */
void dan_gw_node_health(dan_gw_node_t *g, dan_gw_health_t *h, uint64_t now_us);

#ifdef __cplusplus
}
#endif

#endif /* DAN_CAN_GW_NODE_H */
