/* A deterministic simulated half-duplex wire for unit tests: nodes write
 * bytes that occupy the wire for one character time at the writer's baud;
 * every node (the writer too: echo) receives each byte when it ends;
 * receivers at another baud get garbage; overlapping bytes collide. Time
 * is virtual and advanced in fixed steps. */
#ifndef DAN_TEST_SIMBUS_H
#define DAN_TEST_SIMBUS_H

#include "dan/master.h"
#include "dan/peripheral.h"

#define SIM_MAX_NODES 4
#define SIM_QUEUE     16384
#define SIM_LOG       16384

typedef struct simbus simbus_t;

typedef struct {
    simbus_t *bus;
    int idx;
    uint32_t baud;
    bool echo;             /* receives its own bytes */
    bool ignore_baud;      /* fault: set_baud does nothing (stays at baud) */
    uint32_t ignore_above; /* fault: set_baud above this does nothing (0: off) */
    bool mute;             /* fault: writes are dropped */
    bool deaf;             /* fault: other nodes' bytes do not reach it */
    uint64_t tx_free_us;
    dan_port_t port;
    dan_master_t *master;
    dan_periph_t *periph;
    int set_tx_on, set_tx_off;
    bool tx_pin;
    bool tx_pin_error; /* a byte was written while the pin was off */
} sim_node_t;

typedef struct {
    uint64_t start_us, end_us;
    uint8_t byte;
    int src;
    uint32_t baud;
    bool corrupt;
} sim_byte_t;

struct simbus {
    uint64_t now;
    uint32_t step_us;
    sim_byte_t q[SIM_QUEUE];
    size_t qhead, qlen;
    sim_byte_t log[SIM_LOG]; /* every byte delivered, for timing checks */
    size_t nlog;
    sim_node_t nodes[SIM_MAX_NODES];
    int nnodes;
    uint32_t collisions;
    uint32_t noise_ppm; /* per-byte corruption probability, parts per million */
    uint32_t rng;
};

void sim_init(simbus_t *b, uint32_t step_us);
sim_node_t *sim_add_master(simbus_t *b, dan_master_t *m, uint32_t baud, bool echo);
sim_node_t *sim_add_periph(simbus_t *b, dan_periph_t *p, uint32_t baud, bool echo);
/* Raw bytes from node idx at the current time (a babbler or noise source). */
void sim_inject(simbus_t *b, sim_node_t *n, const uint8_t *data, size_t len);
/* Advances one step: delivers finished bytes, polls every engine. */
void sim_step(simbus_t *b);
/* Runs until the master's current operation completes or max_us passes;
 * returns the result (or 1 if it did not complete). */
int sim_run_master(simbus_t *b, dan_master_t *m, uint64_t max_us);
void sim_run_for(simbus_t *b, uint64_t us);

/* A port outside the bus that only records what is written (for tests
 * that feed a master by hand with injected time): echo on, any baud. */
typedef struct {
    uint8_t buf[256];
    size_t len;
} sim_cap_t;
void sim_cap_port(sim_cap_t *c, dan_port_t *port);
/* Polls m every step_us from *now until it has written something. */
void sim_cap_wait_tx(sim_cap_t *c, dan_master_t *m, uint64_t *now, uint32_t step_us);

#endif
