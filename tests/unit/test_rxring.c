/* dan_rxring: the single-producer / single-consumer byte ring that carries
 * UART bytes from an interrupt to the main loop. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <pthread.h>
#include <cmocka.h>

#include "dan/rxring.h"
#include "unit_run.h"

static dan_rxring_t ring;

/* Puts n bytes first, first + 1, ... (mod 256), each accepted. */
static void put_run(uint8_t first, unsigned n)
{
    unsigned i;
    for (i = 0; i < n; i++) {
        assert_true(dan_rxring_put(&ring, (uint8_t)(first + i)));
    }
}

static void test_empty(void **state)
{
    uint8_t buf[8];
    (void)state;
    dan_rxring_init(&ring);
    assert_int_equal(dan_rxring_count(&ring), 0);
    assert_int_equal(dan_rxring_get_many(&ring, buf, sizeof buf), 0);
    assert_int_equal(dan_rxring_get_many(&ring, buf, 0), 0);
    assert_int_equal(dan_rxring_dropped(&ring), 0);
}

static void test_order_and_partial_reads(void **state)
{
    uint8_t buf[8];
    (void)state;
    dan_rxring_init(&ring);
    put_run(0xA0, 10);
    assert_int_equal(dan_rxring_count(&ring), 10);
    assert_int_equal(dan_rxring_get_many(&ring, buf, 4), 4);
    assert_memory_equal(buf, "\xA0\xA1\xA2\xA3", 4);
    assert_int_equal(dan_rxring_count(&ring), 6);
    assert_int_equal(dan_rxring_get_many(&ring, buf, sizeof buf), 6);
    assert_memory_equal(buf, "\xA4\xA5\xA6\xA7\xA8\xA9", 6);
    assert_int_equal(dan_rxring_get_many(&ring, buf, sizeof buf), 0);
}

static void test_full_counts_drops(void **state)
{
    static uint8_t buf[DAN_RXRING_SIZE + 4];
    unsigned i;
    (void)state;
    dan_rxring_init(&ring);
    /* The whole buffer is usable (free-running indices: no spare slot). */
    put_run(0, DAN_RXRING_SIZE);
    assert_int_equal(dan_rxring_count(&ring), DAN_RXRING_SIZE);
    assert_false(dan_rxring_put(&ring, 0x55));
    assert_false(dan_rxring_put(&ring, 0x66));
    assert_int_equal(dan_rxring_dropped(&ring), 2);
    /* Nothing stored was overwritten by the refused bytes. */
    assert_int_equal(dan_rxring_get_many(&ring, buf, sizeof buf), DAN_RXRING_SIZE);
    for (i = 0; i < DAN_RXRING_SIZE; i++) {
        assert_int_equal(buf[i], (uint8_t)i);
    }
    /* Room again after reading; the drop count stays. */
    assert_true(dan_rxring_put(&ring, 0x77));
    assert_int_equal(dan_rxring_get_many(&ring, buf, 1), 1);
    assert_int_equal(buf[0], 0x77);
    assert_int_equal(dan_rxring_dropped(&ring), 2);
    dan_rxring_init(&ring);
    assert_int_equal(dan_rxring_dropped(&ring), 0);
}

static void test_wraps_many_times(void **state)
{
    uint8_t buf[37];
    uint32_t put = 0, got = 0;
    unsigned round;
    (void)state;
    dan_rxring_init(&ring);
    for (round = 0; round < 500; round++) {
        unsigned k, n = 1 + (round * 7) % 53;
        size_t m, j;
        for (k = 0; k < n; k++) {
            assert_true(dan_rxring_put(&ring, (uint8_t)(put * 31u)));
            put++;
        }
        while ((m = dan_rxring_get_many(&ring, buf, 1 + round % sizeof buf)) > 0) {
            for (j = 0; j < m; j++) {
                assert_int_equal(buf[j], (uint8_t)(got * 31u));
                got++;
            }
        }
    }
    assert_int_equal(put, got);
    assert_int_equal(dan_rxring_dropped(&ring), 0);
}

static void test_index_counter_overflow(void **state)
{
    uint8_t buf[16];
    unsigned i;
    (void)state;
    /* Free-running indices just below their wrap: count, full and order
     * stay right across it. */
    dan_rxring_init(&ring);
    ring.head = ring.tail = (dan_rxring_index_t)(0u - 5u);
    put_run(0, 12);
    assert_true(ring.head < ring.tail); /* wrapped */
    assert_int_equal(dan_rxring_count(&ring), 12);
    assert_int_equal(dan_rxring_get_many(&ring, buf, sizeof buf), 12);
    for (i = 0; i < 12; i++) {
        assert_int_equal(buf[i], i);
    }
    ring.head = ring.tail = (dan_rxring_index_t)(0u - 3u);
    for (i = 0; i < DAN_RXRING_SIZE; i++) {
        assert_true(dan_rxring_put(&ring, (uint8_t)i));
    }
    assert_false(dan_rxring_put(&ring, 1));
    assert_int_equal(dan_rxring_count(&ring), DAN_RXRING_SIZE);
}

/* A real producer thread against a consumer: every byte arrives once, in
 * order, or is counted as dropped (the sequence numbers tell which). */
#define STRESS_BYTES 2000000u

static void *producer(void *arg)
{
    dan_rxring_t *r = arg;
    uint32_t i;
    for (i = 0; i < STRESS_BYTES; i++) {
        while (!dan_rxring_put(r, (uint8_t)(i ^ (i >> 8)))) {
            /* full: retry (a UART would drop; here we want every byte) */
        }
    }
    return NULL;
}

static void test_two_threads(void **state)
{
    pthread_t t;
    uint8_t buf[64];
    uint32_t got = 0;
    (void)state;
    dan_rxring_init(&ring);
    assert_int_equal(pthread_create(&t, NULL, producer, &ring), 0);
    while (got < STRESS_BYTES) {
        size_t n = dan_rxring_get_many(&ring, buf, 1 + got % sizeof buf), j;
        for (j = 0; j < n; j++, got++) {
            if (buf[j] != (uint8_t)(got ^ (got >> 8))) {
                fail_msg("byte %u: got 0x%02x", (unsigned)got, buf[j]);
            }
        }
    }
    assert_int_equal(pthread_join(t, NULL), 0);
    assert_int_equal(dan_rxring_count(&ring), 0);
    /* full rings were retried, so the drop counter counts the retries */
}

int main(void)
{
    return UNIT_RUN("rxring", NULL, NULL, test_empty, test_order_and_partial_reads,
                    test_full_counts_drops, test_wraps_many_times, test_index_counter_overflow,
                    test_two_threads);
}
