#include <string.h>

#include "simbus.h"

static uint32_t sim_rand(simbus_t *b)
{
    uint32_t x = b->rng;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return b->rng = x;
}

static int node_write(void *ctx, const uint8_t *data, size_t len)
{
    sim_node_t *n = (sim_node_t *)ctx;
    if (n->port.set_tx != NULL && !n->tx_pin) {
        n->tx_pin_error = true;
    }
    if (!n->mute) {
        sim_inject(n->bus, n, data, len);
    }
    return (int)len;
}

static int node_set_baud(void *ctx, uint32_t baud)
{
    sim_node_t *n = (sim_node_t *)ctx;
    if (!n->ignore_baud && (n->ignore_above == 0u || baud <= n->ignore_above)) {
        n->baud = baud;
    }
    return 0;
}

static void node_set_tx(void *ctx, bool on)
{
    sim_node_t *n = (sim_node_t *)ctx;
    n->tx_pin = on;
    if (on) {
        n->set_tx_on++;
    } else {
        n->set_tx_off++;
        if (n->tx_free_us > n->bus->now) {
            n->tx_pin_error = true; /* released before the last byte left */
        }
    }
}

static bool node_tx_busy(void *ctx)
{
    sim_node_t *n = (sim_node_t *)ctx;
    return n->tx_free_us > n->bus->now;
}

void sim_init(simbus_t *b, uint32_t step_us)
{
    memset(b, 0, sizeof *b);
    b->step_us = step_us;
    b->now = 1000;
    b->rng = 0x1234567u;
}

static sim_node_t *add_node(simbus_t *b, uint32_t baud, bool echo)
{
    sim_node_t *n = &b->nodes[b->nnodes];
    memset(n, 0, sizeof *n);
    n->bus = b;
    n->idx = b->nnodes++;
    n->baud = baud;
    n->echo = echo;
    n->port.write = node_write;
    n->port.set_baud = node_set_baud;
    n->port.ctx = n;
    n->port.echo = echo;
    if (!echo) { /* direction-pin node: the pin and a drain check */
        n->port.set_tx = node_set_tx;
        n->port.tx_busy = node_tx_busy;
    }
    return n;
}

sim_node_t *sim_add_master(simbus_t *b, dan_master_t *m, uint32_t baud, bool echo)
{
    sim_node_t *n = add_node(b, baud, echo);
    n->master = m;
    return n;
}

sim_node_t *sim_add_periph(simbus_t *b, dan_periph_t *p, uint32_t baud, bool echo)
{
    sim_node_t *n = add_node(b, baud, echo);
    n->periph = p;
    return n;
}

void sim_inject(simbus_t *b, sim_node_t *n, const uint8_t *data, size_t len)
{
    size_t i, j;
    for (i = 0; i < len && b->qlen < SIM_QUEUE; i++) {
        sim_byte_t *e = &b->q[(b->qhead + b->qlen) % SIM_QUEUE];
        e->start_us = (n->tx_free_us > b->now) ? n->tx_free_us : b->now;
        e->end_us = e->start_us + dan_char_us(n->baud);
        e->byte = data[i];
        e->src = n->idx;
        e->baud = n->baud;
        e->corrupt = false;
        n->tx_free_us = e->end_us;
        for (j = 0; j < b->qlen; j++) {
            sim_byte_t *o = &b->q[(b->qhead + j) % SIM_QUEUE];
            if (o->src != n->idx && o->start_us < e->end_us && e->start_us < o->end_us) {
                if (!o->corrupt || !e->corrupt) {
                    b->collisions++;
                }
                o->corrupt = true;
                e->corrupt = true;
            }
        }
        b->qlen++;
    }
}

static void deliver(simbus_t *b)
{
    while (b->qlen > 0 && b->q[b->qhead].end_us <= b->now) {
        sim_byte_t e = b->q[b->qhead];
        int i;
        b->qhead = (b->qhead + 1) % SIM_QUEUE;
        b->qlen--;
        if (!e.corrupt && b->noise_ppm > 0 && sim_rand(b) % 1000000u < b->noise_ppm) {
            e.byte ^= (uint8_t)(1u << (sim_rand(b) % 8u));
        }
        if (b->nlog < SIM_LOG) {
            b->log[b->nlog++] = e;
        }
        for (i = 0; i < b->nnodes; i++) {
            sim_node_t *n = &b->nodes[i];
            uint8_t v = e.byte;
            if ((i == e.src && !n->echo) || (i != e.src && n->deaf)) {
                continue;
            }
            if (e.corrupt || n->baud != e.baud) {
                v = (uint8_t)(e.byte ^ 0x5Au ^ (uint8_t)sim_rand(b)); /* framing garbage */
            }
            if (n->master != NULL) {
                dan_master_rx(n->master, &v, 1, b->now);
            } else if (n->periph != NULL) {
                dan_periph_rx(n->periph, &v, 1, b->now);
            }
        }
    }
}

void sim_step(simbus_t *b)
{
    int i;
    b->now += b->step_us;
    deliver(b);
    for (i = 0; i < b->nnodes; i++) {
        sim_node_t *n = &b->nodes[i];
        if (n->master != NULL) {
            (void)dan_master_poll(n->master, b->now);
        } else if (n->periph != NULL) {
            dan_periph_poll(n->periph, b->now);
        }
    }
}

int sim_run_master(simbus_t *b, dan_master_t *m, uint64_t max_us)
{
    uint64_t end = b->now + max_us;
    int i;
    while (b->now < end) {
        b->now += b->step_us;
        deliver(b);
        for (i = 0; i < b->nnodes; i++) {
            sim_node_t *n = &b->nodes[i];
            if (n->master == m) {
                if (dan_master_poll(m, b->now)) {
                    return dan_master_result(m);
                }
            } else if (n->master != NULL) {
                (void)dan_master_poll(n->master, b->now);
            } else if (n->periph != NULL) {
                dan_periph_poll(n->periph, b->now);
            }
        }
    }
    return 1;
}

void sim_run_for(simbus_t *b, uint64_t us)
{
    uint64_t end = b->now + us;
    while (b->now < end) {
        sim_step(b);
    }
}

static int cap_write(void *ctx, const uint8_t *d, size_t n)
{
    sim_cap_t *c = (sim_cap_t *)ctx;
    if (n > sizeof c->buf - c->len) {
        return -1;
    }
    memcpy(c->buf + c->len, d, n);
    c->len += n;
    return (int)n;
}

static int cap_set_baud(void *ctx, uint32_t b)
{
    (void)ctx;
    (void)b;
    return 0;
}

void sim_cap_port(sim_cap_t *c, dan_port_t *port)
{
    memset(c, 0, sizeof *c);
    memset(port, 0, sizeof *port);
    port->write = cap_write;
    port->set_baud = cap_set_baud;
    port->ctx = c;
    port->echo = true;
}

void sim_cap_wait_tx(sim_cap_t *c, dan_master_t *m, uint64_t *now, uint32_t step_us)
{
    while (c->len == 0u) {
        *now += step_us;
        (void)dan_master_poll(m, *now);
    }
}
