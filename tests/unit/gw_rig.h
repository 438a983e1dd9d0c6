/* The gateway rig of the unit tests: master + client and the gateway node
 * + peripheral engine on the simulated DAN wire, a DroneCAN listener on the
 * CAN side capturing what the node sends, and fake nodes' transfers. */
#ifndef GW_RIG_H
#define GW_RIG_H

#include "dan/can_gw/client.h"
#include "dan/can_gw/node.h"
#include "simbus.h"

#define LISTEN_NODE 42u
#define MAX_CAP     512

typedef struct {
    uint16_t dtid;
    uint8_t ttype, src, dst, tid;
    uint8_t payload[DAN_DC_MAX_TRANSFER];
    size_t len;
    uint64_t at_us;
} cap_t;

typedef struct {
    simbus_t bus;
    dan_master_t m;
    dan_identity_t id; /* the gateway's, reported by discovery */
    dan_periph_t p;
    sim_node_t *nm, *np;
    dan_gw_t gw;
    uint32_t gw_stats[DAN_GW_STAT_COUNT]; /* where gw keeps the STATS counters */
    dan_gw_node_t g;
    dan_ptype_t pt;
    dan_dc_rx_t lis;         /* a DroneCAN listener on the far side */
    dan_dc_tid_table_t tids; /* for fake nodes' transfers */
    cap_t cap[MAX_CAP];
    size_t ncap;
    size_t nframes;
} rig_t;

extern rig_t *R;

/* Runs the wire, the node's timers and the CAN drain for us microseconds. */
void advance(uint64_t us);
/* Sends what the node queued to the listener (captured in R->cap). */
void drain(void);
/* The same for at most max frames (the bus takes some, then stalls): the
 * count sent. */
size_t send_frames(size_t max);
/* Completes the client's call with the CAN bus stalled (nothing drained). */
int finish_stalled(void);
/* Starts a hand-built request, sealed as the client would. */
int request_sealed(uint32_t code, const uint8_t *payload, size_t n);
/* Completes the client's transaction in flight. */
int finish(void);
/* A client call that starts (started == DAN_OK) and completes with DAN_OK. */
void call_ok(int started);
/* The request code of the error frame that refused the last transaction
 * (fails the test if there is none). */
uint32_t remote_code(void);
/* The payload of the master's request in flight, to send it again. */
size_t last_req(uint8_t *out);
/* The gateway handles the request in flight but its response is lost: the
 * master sends the same bytes again, as its retry would; the client still
 * waits for the answer (complete it with finish()). */
void lose_response(void);
/* The next captured transfer of a type from index *from on. */
cap_t *find_cap(uint16_t dtid, uint8_t tt, size_t *from);
/* The same, which must be there. */
cap_t *expect_cap(uint16_t dtid, uint8_t tt, size_t *from);
/* A transfer from fake node src into the gateway. */
void inject(uint8_t src, uint16_t dtid, uint64_t sig, uint8_t tt, uint8_t dst,
            const uint8_t *payload, int len);
/* The answer (a response of priority prio) of the node a captured request c
 * went to, with c's transfer ID. */
void answer_cap(const cap_t *c, uint16_t dtid, uint64_t sig, uint8_t prio, const uint8_t *payload,
                int len);
/* tunnel.Targetted from the far end of a tunnel (fake node src, its
 * serial port serial) to the gateway (node 10): n bytes of d. */
void tunnel_targetted_from(uint8_t src, int8_t serial, const uint8_t *d, size_t n);
/* A file.Read request from fake node src to the gateway. */
void file_read_from(uint8_t src, uint64_t offset, const char *path);
/* A NodeStatus from fake node src. */
void node_status_from(uint8_t src, uint32_t uptime, uint8_t health, uint8_t mode);
/* The client call that started (started == DAN_OK) completes and sets
 * gateway flag `flag`; broadcast dtid carries payload byte `value` at once
 * (within 20 ms, not at the next period), then steadily at the arming
 * rate (2 Hz: 3 to 5 times in the next 2 s). from: as for expect_cap(). */
void expect_flag_broadcast(int started, uint8_t flag, uint16_t dtid, uint8_t value, size_t *from);
/* Starts TUN_OPEN of a tunnel port through the client (what
 * dan_gw_tunnel_open() returned; complete it with finish() or call_ok()). */
int tunnel_open_start(uint8_t port, uint8_t mode, uint8_t protocol, uint8_t target, int8_t serial,
                      uint8_t options, uint32_t baud);
/* CONFIG of one setting (mask: one DAN_GW_CFG_* bit) to value through the
 * client, completed. */
void config_set(uint8_t mask, uint32_t value);
/* An esc.Status from fake node src. */
void esc_status(uint8_t src, uint8_t idx, float v, float c, float t, int32_t rpm);
/* esc.Status of ESCs 0, 1 and 3 from nodes 20, 21 and 22 (12.5 V, 16.8 V,
 * 25.2 V; rpm 1000, esc1_rpm, 131071): the round-robin tests' three ESCs. */
void three_esc_statuses(int32_t esc1_rpm);
/* order[0..n-1], the ESC of each telemetry record, is their round robin:
 * 0, 1, 3, 0, 1, 3, ... */
void assert_round_robin_013(const uint8_t *order, size_t n);
/* An esc.StatusExtended from fake node src. */
void esc_status_ext_from(uint8_t src, const dan_dc_esc_status_extended_t *x);
int setup(void **state);
int teardown(void **state);

#endif /* GW_RIG_H */
