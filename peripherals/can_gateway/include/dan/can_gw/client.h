/*
 * CAN-over-DAN gateway client: the FC (master) side, typed calls on top of
 * dan_master_t transactions. Portable C99, no allocation, no globals.
 *
 * One caller-owned dan_gw_t per gateway, bound to the dan_master_t of its
 * UART (after discovery/configure). Every call starts one transaction and
 * returns at once (DAN_ERR_BUSY while another operation runs); completion
 * comes through dan_gw_poll(), which wraps dan_master_poll():
 *
 *     dan_gw_init(&gw, &m);
 *     dan_gw_esc_command(&gw, values, 4, now);        // once per cycle
 *     ... feed rx with dan_master_rx(&m, ...) ...
 *     if (dan_gw_poll(&gw, now)) {                     // 1: done
 *         if (gw.result == DAN_OK) use gw.esc[...];
 *     }
 *
 * Results land in the dan_gw_t: the newest telemetry per ESC (gw.esc),
 * the gateway flags, settings, counters, tunnel offsets. Variable-length
 * results (node table pages, node info, tunnel data, received CAN frames)
 * are read straight out of the master's response buffer with the
 * dan_gw_*_get/next functions below; they stay valid until the next
 * transaction starts, so the client itself stays small:
 *   sizeof(dan_gw_t) ~ 92 + 44 * DAN_GW_MAX_ESC + 24 * DAN_GW_TUNNELS
 *                      bytes (316 on Cortex-M4 with the defaults; `make
 *                      size` reports it); the STATS counters, if kept, in
 *                      the caller's storage (dan_gw_set_stats()).
 *
 * Retries: the master retries a transaction whose response was lost. Every
 * gateway message is idempotent under retry (ESC commands and ARM are
 * states; tunnel writes carry an offset and reads acknowledge by offset;
 * CAN_SEND carries a sequence number; CAN_RECV acknowledges by sequence).
 */
#ifndef DAN_GATEWAY_H
#define DAN_GATEWAY_H

#include "dan/can_gw/msgs.h"
#include "dan/can_gw/msgs_fast.h"
#include "dan/can_gw/msgs_file.h"
#include "dan/can_gw/msgs_mgmt.h"
#include "dan/can_gw/msgs_out.h"
#include "dan/master.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Telemetry slots (DAN_GW_MAX_ESC), tunnel ports (DAN_GW_TUNNELS) and the
 * resync distance (DAN_GW_CAN_RESYNC) are settings in dan/config.h. */

typedef struct {
    uint32_t wr_offset;  /* bytes of ours the gateway has accepted */
    uint32_t rd_offset;  /* bytes we have received */
    uint32_t wr_space;   /* gateway buffer space, last seen */
    uint32_t rd_dropped; /* bytes the gateway dropped (CAN -> DAN) */
    uint32_t rd_lost;    /* bytes skipped here (gateway dropped them) */
    uint16_t accepted;   /* of the last xfer's data */
} dan_gw_tunnel_t;

struct dan_gw_s;
/* Internal: how the response of the call in flight is decoded. */
typedef int (*dan_gw_done_fn)(struct dan_gw_s *gw, uint32_t code, const uint8_t *p, size_t len);

typedef struct dan_gw_s {   /* ordered by use, small fields first, no padding */
    uint8_t port;           /* tunnel port of the call in flight */
    uint8_t xfer_len;       /* most TUN_XFER data offered since the last answer */
    uint8_t can_seq;        /* CAN_SEND sequence number of the last call answered */
    uint8_t gw_flags;       /* DAN_GW_FLAG_*, from the last response */
    uint8_t esc_seen;       /* ESCs the gateway knows (ESC_CMD rsp) */
    uint8_t telem_next;     /* ESC_TELEM: next page (DAN_GW_NONE: end) */
    uint8_t last_telem;     /* index of the last record received, or DAN_GW_NONE */
    bool telem_fresh;       /* ESC_FAST_T: that record was a new esc.Status sample */
    uint8_t can_accepted;   /* of the last CAN_SEND */
    uint8_t recv_opts;      /* of the last CAN_RECV */
    uint8_t servo_fs_kept;  /* entries of the last SERVO_FAILSAFE table kept */
    dan_gw_health_t health; /* last HEALTH response */
    dan_master_t *m;
    uint32_t code;       /* code of the call in flight (0: none) */
    dan_gw_done_fn done; /* its response decoder (internal; NULL: none) */
    int result;          /* of the last completed call */
    uint32_t telem_ignored;
    uint32_t decode_errors; /* responses that did not decode */
    /* the STATS counters (DAN_GW_STAT_*): caller storage of
     * DAN_GW_STAT_COUNT entries, dan_gw_set_stats(); NULL: not kept */
    uint32_t *stats;
    dan_gw_telem_t esc[DAN_GW_MAX_ESC];
    dan_gw_config_t config; /* last CONFIG response */
    dan_gw_tunnel_t tun[DAN_GW_TUNNELS];
    uint32_t can_rx_next; /* next raw frame sequence number wanted */
    uint32_t can_rx_dropped;
    uint32_t can_rx_lost;    /* frames skipped (dropped at the gateway) */
    uint32_t can_rx_resyncs; /* the gateway's sequence jumped (it restarted) */
    uint32_t can_queue_free;
    dan_gw_call_state_t call; /* last NODE_CALL response */
} dan_gw_t;

void dan_gw_init(dan_gw_t *gw, dan_master_t *m);

/* Wraps dan_master_poll(): returns 1 once when the current operation
 * completes (gateway calls are decoded first; gw->result is the result,
 * for other master operations too), else 0. */
int dan_gw_poll(dan_gw_t *gw, uint64_t now_us);
/* Decodes the completed transaction (for callers that poll the master
 * themselves: call it when dan_master_poll() returned 1). Returns and
 * stores the result. */
int dan_gw_complete(dan_gw_t *gw, uint64_t now_us);
/* dan_gw_complete() as if the completed transaction were the call of
 * code (tests, fuzzing, replaying captures). It links every response
 * decoder; the calls themselves link only their own. */
int dan_gw_complete_as(dan_gw_t *gw, uint32_t code, uint64_t now_us);

/* ESC command: n (1..20) raw values -8192..8191 (RawCommand semantics). The
 * response's telemetry record (round-robin over the ESCs) updates gw->esc. */
int dan_gw_esc_command(dan_gw_t *gw, const int16_t *values, size_t n, uint64_t now_us);
/* Compact ESC command (ESC_FAST, or ESC_FAST_T with telem): the same
 * broadcast as dan_gw_esc_command() in 13 bytes for 4 ESCs; the response
 * is the gateway flags, and with telem one ESC's esc.Status (round robin)
 * into gw->esc[gw->last_telem] (voltage, current, temperature, rpm, age_ms
 * to 4 ms; its other fields keep their last values) and gw->telem_fresh.
 * gw->last_telem is DAN_GW_NONE when no record came. Ask for telemetry
 * every N-th exchange to trade it for rate (docs/PROTOCOL.md). */
int dan_gw_esc_fast(dan_gw_t *gw, const int16_t *values, size_t n, bool telem, uint64_t now_us);
/* Telemetry page from esc_index first (0 for the first page); next page
 * index in gw->telem_next. */
int dan_gw_telemetry(dan_gw_t *gw, uint8_t first, uint64_t now_us);
/* Armed state for ArmingStatus (true: 255 FULLY_ARMED, false: 0). */
int dan_gw_arm(dan_gw_t *gw, bool armed, uint64_t now_us);
/* Reads (set == NULL or set->set_mask == 0) or changes the settings; the
 * response lands in gw->config. */
int dan_gw_config(dan_gw_t *gw, const dan_gw_config_t *set, uint64_t now_us);
/* Counters into gw->stats (DAN_GW_STAT_*), the caller's storage named by
 * dan_gw_set_stats() (without it the response is checked, not kept). */
int dan_gw_stats(dan_gw_t *gw, uint64_t now_us);
/* Where dan_gw_stats() keeps the counters: v[DAN_GW_STAT_COUNT],
 * caller-owned (issue 17: 144 bytes an FC that never reads them saves);
 * NULL: not kept (the default). Set it after dan_gw_init(). */
void dan_gw_set_stats(dan_gw_t *gw, uint32_t *v);

/* Node table page from node id first (1 for the first page). After
 * completion: dan_gw_nodes_begin() then dan_gw_nodes_next() per entry. */
int dan_gw_nodes(dan_gw_t *gw, uint8_t first, uint64_t now_us);
/* Reader over the completed page; hdr gets next/count. */
int dan_gw_nodes_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_nodes_hdr_t *hdr);
int dan_gw_nodes_next(dan_reader_t *r, dan_gw_node_entry_t *node);
/* One node's GetNodeInfo data; read it with dan_gw_node_info_get(). */
int dan_gw_node_info(dan_gw_t *gw, uint8_t node_id, uint64_t now_us);
int dan_gw_node_info_get(const dan_gw_t *gw, dan_gw_node_info_t *info);

/* Opens (or reconfigures, or closes with mode DAN_GW_TUN_CLOSED) a tunnel
 * port; the client's offsets for it restart at 0. */
int dan_gw_tunnel_open(dan_gw_t *gw, const dan_gw_tun_open_t *cfg, uint64_t now_us);
/* Writes up to DAN_GW_TUN_CHUNK_MAX bytes (len may be 0: a pure read) and
 * reads up to rd_max bytes. After completion gw->tun[port].accepted says how
 * many of data were taken (send the rest again later). After a call that
 * failed it may exceed len: the gateway kept bytes of that call (the same
 * stream, offered again), never more than the most offered since its last
 * answer; a response claiming more, or older read data than acknowledged,
 * is DAN_ERR_MALFORMED and changes nothing. dan_gw_tunnel_data() gives the
 * bytes read (new ones only; up to DAN_GW_TUN_CHUNK_MAX from a gateway that
 * ignores rd_max: copy at most your room). */
int dan_gw_tunnel_xfer(dan_gw_t *gw, uint8_t port, const uint8_t *data, size_t len, size_t rd_max,
                       uint64_t now_us);
int dan_gw_tunnel_data(const dan_gw_t *gw, const uint8_t **data, size_t *len);

/* Sends up to DAN_GW_CAN_FRAMES_MAX raw frames; gw->can_accepted after. */
int dan_gw_can_send(dan_gw_t *gw, const dan_can_frame_t *frames, size_t n, uint64_t now_us);
/* Fetches up to max frames that passed the filter; then read them with
 * dan_gw_can_begin() / dan_gw_can_next(). */
int dan_gw_can_recv(dan_gw_t *gw, uint8_t max, uint64_t now_us);
int dan_gw_can_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_can_recv_t *hdr);
int dan_gw_can_next(dan_reader_t *r, dan_can_frame_t *f);
/* CAN_RECV with options (DAN_GW_RECV_TIMES: receive times). Read a timed
 * response with dan_gw_can_next_timed(): *t_us starts at hdr.t0_us and is
 * each frame's receive time (gateway clock, low 32 bits, microseconds). */
int dan_gw_can_recv_opts(dan_gw_t *gw, uint8_t max, uint8_t opts, uint64_t now_us);
int dan_gw_can_next_timed(dan_reader_t *r, dan_can_frame_t *f, uint32_t *t_us);
/* Changes the raw receive filter (op DAN_GW_FILTER_*). After completion the
 * table is read with dan_gw_filter_begin() / dan_gw_filter_next(). */
int dan_gw_can_filter(dan_gw_t *gw, uint8_t op, const dan_gw_filter_t *f, size_t n,
                      uint64_t now_us);
int dan_gw_filter_begin(const dan_gw_t *gw, dan_reader_t *r, uint8_t *result, uint8_t *count);
int dan_gw_filter_next(dan_reader_t *r, dan_gw_filter_t *f);

/* ---- bus management (gw_client_mgmt.c; docs/PROTOCOL.md "Bus management")
 *
 * Service calls run in the gateway: start one with a call_id of your
 * choosing (a new number per call; the master's retries repeat it, and the
 * gateway never sends a retried call twice), then read its state and
 * result with dan_gw_call_result() until the state is not PENDING. Several
 * calls may be in flight (pipelining, e.g. a parameter list). After
 * completion gw->call holds the NODE_CALL state. */
int dan_gw_node_call(dan_gw_t *gw, const dan_gw_call_t *c, uint64_t now_us);
int dan_gw_param_get_index(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, uint16_t index,
                           uint64_t now_us);
/* name: NUL-terminated, 1..92 bytes. */
int dan_gw_param_get(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, const char *name,
                     uint64_t now_us);
/* The request must fit one frame: a string value and the name take at
 * most 151 bytes together (each within its maximum); longer is
 * DAN_ERR_OVERFLOW, nothing sent. */
int dan_gw_param_set(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, const char *name,
                     const dan_gw_value_t *value, uint64_t now_us);
int dan_gw_param_save(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, uint64_t now_us);
/* magic: DAN_GW_RESTART_MAGIC, or another 40-bit one with force (the
 * gateway refuses any other with an error frame). */
int dan_gw_restart(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, uint64_t magic, bool force,
                   uint64_t now_us);
/* Reads up to max bytes of a call's result from offset; after completion
 * dan_gw_call_result_get() gives the state, the result length and the
 * bytes (a view into the response). */
int dan_gw_call_result(dan_gw_t *gw, uint16_t call_id, uint32_t offset, uint8_t max,
                       uint64_t now_us);
int dan_gw_call_result_get(const dan_gw_t *gw, dan_gw_result_t *res);
/* The health verdict into gw->health. */
int dan_gw_health(dan_gw_t *gw, uint64_t now_us);
/* An allocation table page from entry first; then dan_gw_dna_begin() and
 * dan_gw_dna_next() per entry. */
int dan_gw_dna(dan_gw_t *gw, uint8_t first, uint64_t now_us);
int dan_gw_dna_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_dna_hdr_t *hdr);
int dan_gw_dna_next(dan_reader_t *r, dan_gw_dna_entry_t *e);

/* ---- outputs besides ESCs (gw_client_out.c; docs/PROTOCOL.md "Outputs")
 *
 * Each is a state the gateway keeps sending (safety, servos) or a one-shot
 * command (lights, beep); the response's gw_flags land in gw->gw_flags. */

/* SafetyState: true sends STATUS_SAFETY_OFF (255: nodes may drive their
 * outputs), false STATUS_SAFETY_ON (0). The gateway's failsafe sets ON. */
int dan_gw_safety(dan_gw_t *gw, bool safety_off, uint64_t now_us);
/* Actuator commands, latest wins per actuator_id (1..DAN_GW_SERVO_MAX
 * entries). Values are binary16 bits: dan_gw_servo_make() converts,
 * saturating beyond +-65504 (infinity too) as DSDL's float16 does. */
int dan_gw_servo(dan_gw_t *gw, const dan_gw_servo_t *s, size_t n, uint64_t now_us);
dan_gw_servo_t dan_gw_servo_make(uint8_t actuator_id, uint8_t command_type, float value);
/* Replaces the servo failsafe table (0..DAN_GW_SERVO_MAX entries; an
 * actuator not listed holds its last command). gw->servo_fs_kept after. */
int dan_gw_servo_failsafe(dan_gw_t *gw, const dan_gw_servo_fs_t *s, size_t n, uint64_t now_us);
/* LightsCommand, 1..DAN_GW_LIGHTS_MAX lights, colours RGB565. */
int dan_gw_lights(dan_gw_t *gw, const dan_gw_light_t *l, size_t n, uint64_t now_us);
/* BeepCommand: frequency 1..65504 Hz, duration 0..65504000 ms. */
int dan_gw_beep(dan_gw_t *gw, uint32_t frequency_hz, uint32_t duration_ms, uint64_t now_us);

/* ---- files and firmware updates (gw_client_file.c; docs/PROTOCOL.md
 * "Files and firmware updates")
 *
 * Upload an image: dan_gw_file_open(name, size), then dan_gw_file_write()
 * from the have of the last response on (chunks of 1..DAN_GW_FILE_CHUNK_MAX
 * bytes), then dan_gw_file_commit() with dan_gw_crc32() of the whole image.
 * Every step is retry-safe; after a lost response or a restart of either
 * side, open again (restart false) and go on at the have it reports. Start
 * the update with dan_gw_fw_begin() (a NODE_CALL: read its result, a
 * dan_gw_fw_result_t, with dan_gw_call_result()) and follow it with
 * dan_gw_node_info() (status, file_flags, bytes_read, file_size). Names:
 * NUL-terminated, 1..32 bytes of [A-Za-z0-9._-], not starting with '.'. */
int dan_gw_file_open(dan_gw_t *gw, const char *name, uint32_t size, bool restart, uint64_t now_us);
/* data: 1..DAN_GW_FILE_CHUNK_MAX bytes for file offset offset. */
int dan_gw_file_write(dan_gw_t *gw, uint32_t offset, const uint8_t *data, size_t len,
                      uint64_t now_us);
int dan_gw_file_commit(dan_gw_t *gw, uint32_t crc32, uint64_t now_us);
/* A removal retried by the master answers NOT_FOUND: OK and NOT_FOUND both
 * mean the file is gone. */
int dan_gw_file_remove(dan_gw_t *gw, const char *name, uint64_t now_us);
/* After FILE_OPEN, FILE_WRITE, FILE_COMMIT or FILE_REMOVE completed: the
 * result byte (DAN_GW_FILE_*) and value: have (OPEN, WRITE), the gateway's
 * CRC-32 of the bytes it holds (COMMIT), 0 (REMOVE). When the call did
 * not complete with an answer (rc not DAN_OK) *result is DAN_GW_NONE, never
 * DAN_GW_FILE_OK (a timed-out COMMIT read as OK; review finding). */
int dan_gw_file_result(const dan_gw_t *gw, uint8_t *result, uint32_t *value);
/* A page of committed files from index first (0 for the first page); then
 * dan_gw_file_list_begin() (hdr.next: the next first, DAN_GW_NONE at the
 * end) and dan_gw_file_list_next() per entry. */
int dan_gw_file_list(dan_gw_t *gw, uint8_t first, uint64_t now_us);
int dan_gw_file_list_begin(const dan_gw_t *gw, dan_reader_t *r, dan_gw_file_list_hdr_t *hdr);
int dan_gw_file_list_next(dan_reader_t *r, dan_gw_file_entry_t *e);
/* BeginFirmwareUpdate of node_id from the committed file name (the gateway
 * refuses, with an error frame, a name that is not one). */
int dan_gw_fw_begin(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, const char *name,
                    uint64_t now_us);

#ifdef __cplusplus
}
#endif

#endif /* DAN_GATEWAY_H */
