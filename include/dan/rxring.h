/*
 * A byte ring buffer between a UART receive interrupt (the one producer) and
 * the main loop (the one consumer), lock-free. Portable C99, no allocation.
 *
 *     static dan_rxring_t rx;                    // dan_rxring_init(&rx) once
 *     void uart_rx_isr(void) {                   // producer: interrupt only
 *         while (byte available) dan_rxring_put(&rx, read_byte());
 *     }
 *     for (;;) {                                 // consumer: main loop only
 *         uint8_t buf[64];
 *         size_t n = dan_rxring_get_many(&rx, buf, sizeof buf);
 *         if (n) dan_master_rx(&m, buf, n, now_us());
 *         ...
 *     }
 *
 * Why it needs no lock (and no interrupt masking):
 *   - head is written only by the producer, tail only by the consumer; each
 *     side only reads the other's index. Both are free-running counters
 *     (the slot is counter & (DAN_RXRING_SIZE - 1)), so head - tail is the
 *     fill level even after they wrap, and a full ring is told apart from an
 *     empty one without a spare slot.
 *   - The indices (and the bytes) are volatile, so the compiler reloads them
 *     every time and keeps the accesses in program order; an index must be
 *     a type the CPU reads and writes in one access (DAN_RXRING_INDEX_T).
 *   - The producer stores the byte, then a barrier, then publishes it by
 *     advancing head. The consumer reads head, a barrier, the bytes, a
 *     barrier, then frees the slots by advancing tail. So a slot is never
 *     seen before its byte is stored, and never reused before it was read.
 *     On a single-core in-order MCU the barriers mostly restrain the
 *     compiler; on cores that reorder memory (or with a DMA/second core as
 *     producer) they are needed in hardware too (DAN_RXRING_BARRIER).
 *
 * Exactly one producer and one consumer: two ISRs putting into the same
 * ring, or two threads taking from it, need a lock.
 */
#ifndef DAN_RXRING_H
#define DAN_RXRING_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Its size (DAN_RXRING_SIZE) and index type (DAN_RXRING_INDEX_T) are
 * settings in dan/config.h. */

/* Memory barrier between storing a byte and publishing it (and between
 * reading bytes and freeing them). Override with -D for another compiler.
 * Defaults: GCC/clang on ARMv6-M/v7-M/v8-M: DMB; other GCC/clang targets:
 * __sync_synchronize() (a full fence); other compilers: nothing (volatile
 * alone keeps the compiler's order; enough on single-core in-order MCUs). */
#ifndef DAN_RXRING_BARRIER
#if defined(__GNUC__) && defined(__arm__) && defined(__ARM_ARCH_PROFILE) && \
    (__ARM_ARCH_PROFILE == 'M')
#define DAN_RXRING_BARRIER() __asm__ volatile("dmb" ::: "memory")
#elif defined(__GNUC__)
#define DAN_RXRING_BARRIER() __sync_synchronize()
#else
#define DAN_RXRING_BARRIER() ((void)0)
#endif
#endif

typedef DAN_RXRING_INDEX_T dan_rxring_index_t;

typedef struct {
    volatile uint8_t buf[DAN_RXRING_SIZE];
    volatile dan_rxring_index_t head; /* bytes put; written by the producer only */
    volatile dan_rxring_index_t tail; /* bytes taken; written by the consumer only */
    volatile uint32_t dropped;        /* bytes refused (ring full); producer only */
} dan_rxring_t;

/* Empties the ring and clears the drop counter. Call before the producer
 * runs (before enabling the interrupt). */
void dan_rxring_init(dan_rxring_t *r);

/* Producer (the interrupt): appends one byte. Returns false, and counts it
 * in dropped, if the ring is full. */
bool dan_rxring_put(dan_rxring_t *r, uint8_t byte);

/* Consumer (the main loop): moves up to cap bytes into buf, oldest first.
 * Returns the count (0 when empty). */
size_t dan_rxring_get_many(dan_rxring_t *r, uint8_t *buf, size_t cap);

/* Consumer: bytes waiting (a snapshot; the producer may add more). */
size_t dan_rxring_count(const dan_rxring_t *r);

/* Bytes dropped because the ring was full (any side may read it). */
uint32_t dan_rxring_dropped(const dan_rxring_t *r);

#ifdef __cplusplus
}
#endif

#endif /* DAN_RXRING_H */
