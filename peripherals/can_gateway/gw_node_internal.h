/*
 * What the gateway node's subsystems (gw_node*.c) call of each other. Not
 * installed, not for callers: the public API is dan/can_gw/node.h.
 */
#ifndef DAN_CAN_GW_NODE_INTERNAL_H
#define DAN_CAN_GW_NODE_INTERNAL_H

#include "dan/can_gw/msgs_fast.h"
#include "dan/can_gw/msgs_file.h"
#include "dan/can_gw/node.h"

/* Milliseconds between two microsecond times, saturated to 32 bits. */
uint32_t dan_gwn_age_ms(uint64_t now_us, uint64_t then_us);

/* ---- CAN output (gw_node_txq.c) ---- */
size_t dan_gwn_txq_free(const dan_gw_node_txq_t *q);
void dan_gwn_txq_push(dan_gw_node_txq_t *q, const dan_can_frame_t *f);
/* Queues one transfer whole (source node = ours), or drops it whole
 * (counted in can_tx_dropped): DAN_ERR_OVERFLOW. */
int dan_gwn_send_transfer(dan_gw_node_t *g, dan_gw_node_txq_t *q, dan_dc_transfer_t *t);
/* The response to a service request req: same data type, priority and
 * transfer ID, to its source (len < 0: the encoder's error, passed
 * through). Queued on the bulk queue. */
int dan_gwn_respond(dan_gw_node_t *g, const dan_dc_transfer_t *req, uint64_t sig,
                    const uint8_t *payload, int len);
/* A broadcast of an encoded payload (len < 0: the encoder's error, passed
 * through). */
int dan_gwn_broadcast(dan_gw_node_t *g, dan_gw_node_txq_t *q, uint16_t dtid, uint64_t sig,
                      uint8_t prio, const uint8_t *payload, int len);
/* Latest wins: removes our own unsent broadcasts of one data type from q
 * before a newer one is queued. */
size_t dan_gwn_drop_own(dan_gw_node_t *g, dan_gw_node_txq_t *q, uint16_t dtid);
/* Moves the last n frames of q (a transfer just queued) to its front, after
 * the rest of a transfer already on the bus: throttle is not kept waiting
 * behind servo commands queued since the last one (review finding). */
void dan_gwn_txq_to_front(dan_gw_node_txq_t *q, size_t n);

/* ---- ESC commands, telemetry, failsafe (gw_node_esc.c) ---- */
void dan_gwn_esc_command(dan_gw_node_t *g, const int16_t *v, size_t n, uint64_t now_us);
/* The telemetry of ESC index idx with its ages, or NULL if none arrived. */
const dan_gw_telem_t *dan_gwn_esc_telem(dan_gw_node_t *g, size_t idx, uint64_t now_us);
/* The next ESC with telemetry after the last one reported (round robin). */
const dan_gw_telem_t *dan_gwn_esc_next_telem(dan_gw_node_t *g, uint64_t now_us);
uint8_t dan_gwn_esc_seen(const dan_gw_node_t *g);
/* The next ESC with esc.Status as a compact record (ESC_FAST_T), marked
 * not fresh; false if no ESC sent esc.Status. */
bool dan_gwn_esc_next_fast(dan_gw_node_t *g, dan_gw_fast_rec_t *rec, uint64_t now_us);
void dan_gwn_on_esc_status(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
void dan_gwn_on_esc_ext(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
void dan_gwn_on_temperature(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
void dan_gwn_esc_poll(dan_gw_node_t *g, uint64_t now_us);
uint64_t dan_gwn_esc_next_us(const dan_gw_node_t *g, uint64_t t);

/* ---- ArmingStatus (gw_node_arming.c) ---- */
void dan_gwn_arming_send(dan_gw_node_t *g, uint64_t now_us);
/* An ARM request: broadcast at once when the value changes. */
void dan_gwn_arming_set(dan_gw_node_t *g, uint8_t status, uint64_t now_us);
void dan_gwn_arming_poll(dan_gw_node_t *g, uint64_t now_us);
/* SAFETY: broadcast at once when the value changes. */
void dan_gwn_safety_set(dan_gw_node_t *g, uint8_t status, uint64_t now_us);
/* DISARMED and safety ON, broadcast at once. */
void dan_gwn_arming_failsafe(dan_gw_node_t *g, uint64_t now_us);

/* ---- servos, lights, buzzer (gw_node_out.c) ---- */
void dan_gwn_servos_command(dan_gw_node_t *g, const dan_gw_servo_t *s, size_t n, uint64_t now_us);
/* Replaces the failsafe table; returns how many actuators it holds. */
size_t dan_gwn_servos_set_failsafe(dan_gw_node_t *g, const dan_gw_servo_fs_t *s, size_t n);
/* Every commanded actuator to its failsafe command (or its last), now. */
void dan_gwn_servos_failsafe(dan_gw_node_t *g, uint64_t now_us);
void dan_gwn_servos_poll(dan_gw_node_t *g, uint64_t now_us);
uint64_t dan_gwn_servos_next_us(const dan_gw_node_t *g, uint64_t t);
void dan_gwn_lights(dan_gw_node_t *g, const dan_gw_light_t *l, size_t n);
void dan_gwn_beep(dan_gw_node_t *g, const dan_gw_beep_t *b);

/* ---- node table (gw_node_table.c) ---- */
dan_gw_node_slot_t *dan_gwn_find_node(dan_gw_node_t *g, uint8_t id);
void dan_gwn_on_node_status(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
void dan_gwn_on_node_info_rsp(dan_gw_node_t *g, const dan_dc_transfer_t *t);
void dan_gwn_table_poll(dan_gw_node_t *g, uint64_t now_us);
uint64_t dan_gwn_table_next_us(const dan_gw_node_t *g, uint64_t t);
uint32_t dan_gwn_table_count(const dan_gw_node_t *g);
/* Seen, then silent past DroneCAN's offline timeout. */
bool dan_gwn_offline(const dan_gw_node_slot_t *n, uint64_t now_us);
/* A NODES entry's last byte: info state | DAN_GW_NODE_* flags. */
uint8_t dan_gwn_node_flags(const dan_gw_node_t *g, const dan_gw_node_slot_t *n, uint64_t now_us);

/* ---- tunnels (gw_node_tunnel.c) ---- */
void dan_gwn_on_targetted(dan_gw_node_t *g, const dan_dc_transfer_t *t);
void dan_gwn_on_tun_broadcast(dan_gw_node_t *g, const dan_dc_transfer_t *t);
/* TUN_OPEN: opens, reconfigures or closes a port; false if refused. */
bool dan_gwn_tunnel_open(dan_gw_node_t *g, const dan_gw_tun_open_t *o, uint64_t now_us);
/* TUN_XFER: takes x's data from the port's wr_next on, acknowledges
 * x->rd_offset, and fills r (data copied into out, DAN_GW_TUN_CHUNK_MAX
 * bytes; no more than a response of room bytes holds). DAN_ERR_NOTFOUND:
 * port not open; DAN_ERR_MALFORMED: a gap. */
int dan_gwn_tunnel_xfer(dan_gw_node_t *g, const dan_gw_tun_xfer_t *x, dan_gw_tun_xfer_t *r,
                        uint8_t *out, size_t room);
void dan_gwn_tunnel_poll(dan_gw_node_t *g, uint64_t now_us);
uint64_t dan_gwn_tunnel_next_us(const dan_gw_node_t *g, uint64_t now_us, uint64_t t);

/* ---- raw frames (gw_node_raw.c) ---- */
/* A frame for the capture (received, or ours with DAN_CAN_OWN). */
void dan_gwn_raw_in(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us);
/* The DroneCAN side of a received frame (also the FC's own frames once sent). */
void dan_gwn_hear(dan_gw_node_t *g, const dan_can_frame_t *f, uint64_t now_us);
/* CAN_SEND: all or nothing; a retry (same seq and digest) is not sent
 * again. Fills s->count (accepted) and s->queue_free. */
void dan_gwn_raw_send(dan_gw_node_t *g, dan_gw_can_send_t *s, const dan_can_frame_t *f,
                      uint32_t digest);
/* CAN_RECV: acknowledges frames before q->seq; fills a (first_seq,
 * dropped, count for the room left in a response of cap bytes). The
 * frames are dan_gwn_raw_at(g, 0 .. a->count - 1). */
void dan_gwn_raw_recv(dan_gw_node_t *g, const dan_gw_can_recv_t *q, dan_gw_can_recv_t *a,
                      size_t cap);
/* Receive time of dan_gwn_raw_at(g, i), low 32 bits of microseconds. */
uint32_t dan_gwn_raw_time(const dan_gw_node_t *g, size_t i);
const dan_can_frame_t *dan_gwn_raw_at(const dan_gw_node_t *g, size_t i);
/* CAN_FILTER: applies op to the table; returns the result byte (0 OK,
 * 1 full). */
uint8_t dan_gwn_raw_filter(dan_gw_node_t *g, uint8_t op, const dan_gw_filter_t *f, size_t n);

/* ---- dynamic node ID allocation (gw_node_dna.c) ---- */
void dan_gwn_dna_load(dan_gw_node_t *g);
void dan_gwn_on_allocation(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
void dan_gwn_dna_poll(dan_gw_node_t *g);
/* The table's entry for a node ID, or NULL. */
const dan_gw_dna_entry_t *dan_gwn_dna_entry(const dan_gw_node_t *g, uint8_t node_id);
/* Fills h for a DNA page from entry first in room bytes of response. */
void dan_gwn_dna_page(const dan_gw_node_t *g, uint8_t first, size_t room, dan_gw_dna_hdr_t *h);

/* ---- service calls (gw_node_call.c) ---- */
void dan_gwn_calls_init(dan_gw_node_t *g);
/* NODE_CALL: starts a call, or reports the state of the same call already
 * held (a retry). DAN_ERR_UNSUPPORTED: a restart magic refused. */
int dan_gwn_call_start(dan_gw_node_t *g, const dan_gw_call_t *c, uint32_t digest,
                       dan_gw_call_state_t *st, uint64_t now_us);
dan_gw_node_call_t *dan_gwn_call_find(dan_gw_node_t *g, uint16_t call_id);
void dan_gwn_on_call_response(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
void dan_gwn_calls_poll(dan_gw_node_t *g, uint64_t now_us);
uint64_t dan_gwn_calls_next_us(const dan_gw_node_t *g, uint64_t t);

/* ---- file server (gw_node_file.c) ---- */
/* True for file.GetInfo and file.Read when a store is configured. */
bool dan_gwn_file_service(const dan_gw_node_t *g, uint16_t dtid);
void dan_gwn_on_file_request(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us);
/* Answers the requests that waited for room in the bulk queue. */
void dan_gwn_file_poll(dan_gw_node_t *g, uint64_t now_us);
/* True while a node of the table reads committed file name (it read within
 * DAN_GW_NODE_READER_US and not to its end): replacing it would give that
 * node a mix of two images. */
bool dan_gwn_file_in_use(const dan_gw_node_t *g, const char *name, uint64_t now_us);
uint64_t dan_gwn_file_next_us(const dan_gw_node_t *g, uint64_t now_us, uint64_t t);

/* ---- DAN side (gw_node_dan*.c) ---- */
/* A request reached us: the master is alive (NodeStatus health). */
static inline dan_gw_node_t *dan_gwn_touch(void *user, uint64_t now_us)
{
    dan_gw_node_t *g = (dan_gw_node_t *)user;
    g->last_dan_us = now_us ? now_us : 1u;
    g->stats.dan_requests++;
    return g;
}

/* A DAN handler of the node (dan_handler_fn of dan/peripheral.h): the one
 * signature every handler and its prototype spell. */
#define DAN_GWN_HANDLER(name)                                                               \
    int name(void *user, uint32_t code, const uint8_t *req, size_t len, dan_writer_t *resp, \
             const char **err, uint64_t now_us)

/* Refuses a request with DAN_ERR_MALFORMED; why is the error frame's text. */
static inline int dan_gwn_refuse(const char **err, const char *why)
{
    *err = why;
    return DAN_ERR_MALFORMED;
}

/* True when the request is one byte of either value (ARM, SAFETY). */
static inline bool dan_gwn_byte_of(const uint8_t *req, size_t len, uint8_t a, uint8_t b)
{
    return len >= 1u && (req[0] == a || req[0] == b);
}

/* Encodes in place into the response with one of the codec's
 * dan_gw_msg_*_encode(x, out, cap) functions. */
#define PUT_ENCODED(resp, fn, x)                          \
    do {                                                  \
        size_t room_;                                     \
        uint8_t *out_ = dan_writer_room((resp), &room_);  \
        dan_writer_advance((resp), fn((x), out_, room_)); \
    } while (0)

/* The handlers the table of gw_node_dan.c takes from the other files. */
DAN_GWN_HANDLER(dan_gwn_h_node_call);
DAN_GWN_HANDLER(dan_gwn_h_call_result);
DAN_GWN_HANDLER(dan_gwn_h_health);
DAN_GWN_HANDLER(dan_gwn_h_dna);
DAN_GWN_HANDLER(dan_gwn_h_output); /* SERVO, SERVO_FAILSAFE, LIGHTS, BEEP */
DAN_GWN_HANDLER(dan_gwn_h_esc_fast);
DAN_GWN_HANDLER(dan_gwn_h_file_open);
DAN_GWN_HANDLER(dan_gwn_h_file_write);
DAN_GWN_HANDLER(dan_gwn_h_file_commit);
DAN_GWN_HANDLER(dan_gwn_h_file_list);
DAN_GWN_HANDLER(dan_gwn_h_file_remove);
extern const dan_handler_t dan_gwn_handlers[];
extern const size_t dan_gwn_nhandlers;
extern const dan_envelope_t dan_gwn_seal;

#endif /* DAN_CAN_GW_NODE_INTERNAL_H */
