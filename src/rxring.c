/* Single-producer / single-consumer byte ring (see dan/rxring.h for why it
 * is safe between an interrupt and the main loop). */
#include "dan/rxring.h"

#define RING_MASK ((dan_rxring_index_t)(DAN_RXRING_SIZE - 1u))

void dan_rxring_init(dan_rxring_t *r)
{
    r->head = 0;
    r->tail = 0;
    r->dropped = 0;
    DAN_RXRING_BARRIER();
}

bool dan_rxring_put(dan_rxring_t *r, uint8_t byte)
{
    dan_rxring_index_t head = r->head; /* ours: no one else writes it */
    dan_rxring_index_t tail = r->tail; /* the consumer's: a snapshot */
    if ((dan_rxring_index_t)(head - tail) >= (dan_rxring_index_t)DAN_RXRING_SIZE) {
        r->dropped = r->dropped + 1u;
        return false;
    }
    r->buf[head & RING_MASK] = byte;
    DAN_RXRING_BARRIER(); /* the byte is stored before it is published */
    r->head = (dan_rxring_index_t)(head + 1u);
    return true;
}

size_t dan_rxring_get_many(dan_rxring_t *r, uint8_t *buf, size_t cap)
{
    dan_rxring_index_t tail = r->tail; /* ours */
    dan_rxring_index_t head = r->head; /* the producer's: a snapshot */
    size_t avail = (size_t)(dan_rxring_index_t)(head - tail);
    size_t n, i;
    DAN_RXRING_BARRIER(); /* read the bytes only after seeing head */
    n = (avail < cap) ? avail : cap;
    for (i = 0; i < n; i++) {
        buf[i] = r->buf[(dan_rxring_index_t)(tail + (dan_rxring_index_t)i) & RING_MASK];
    }
    DAN_RXRING_BARRIER(); /* the bytes are read before their slots are freed */
    r->tail = (dan_rxring_index_t)(tail + (dan_rxring_index_t)n);
    return n;
}

size_t dan_rxring_count(const dan_rxring_t *r)
{
    return (size_t)(dan_rxring_index_t)(r->head - r->tail);
}

uint32_t dan_rxring_dropped(const dan_rxring_t *r)
{
    return r->dropped;
}
