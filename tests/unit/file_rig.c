/* The file tests' rig (see file_rig.h). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <string.h>

#include "file_rig.h"

ram_store_t S;
uint8_t img[IMG_SIZE];

/* The gateway (re)started with the RAM store: S survives, RAM state not. */
void gateway_start(bool with_store)
{
    dan_gw_node_config_t gc = R->g.cfg;
    gc.files = with_store ? &S.fs : NULL;
    assert_int_equal(dan_gw_node_init(&R->g, &gc, R->bus.now), DAN_OK);
    dan_gw_node_attach(&R->g, &R->p);
}

int setup_files(void **state)
{
    size_t i;
    setup(state);
    ram_store_init(&S);
    for (i = 0; i < IMG_SIZE; i++) {
        img[i] = (uint8_t)(i * 7u + (i >> 8));
    }
    gateway_start(true);
    return 0;
}

/* Completes the call in flight; the result byte, *value as
 * dan_gw_file_result() gives it. */
uint8_t done(uint32_t *value)
{
    uint8_t result = 0xEE;
    uint32_t v;
    assert_int_equal(finish(), DAN_OK);
    assert_int_equal(dan_gw_file_result(&R->gw, &result, &v), DAN_OK);
    if (value != NULL) {
        *value = v;
    }
    return result;
}

uint8_t open_file(const char *name, uint32_t size, bool restart, uint32_t *have)
{
    assert_int_equal(dan_gw_file_open(&R->gw, name, size, restart, R->bus.now), DAN_OK);
    return done(have);
}

uint8_t write_at(uint32_t off, size_t len, uint32_t *have)
{
    assert_int_equal(dan_gw_file_write(&R->gw, off, img + off, len, R->bus.now), DAN_OK);
    return done(have);
}

uint8_t commit(uint32_t crc, uint32_t *held)
{
    assert_int_equal(dan_gw_file_commit(&R->gw, crc, R->bus.now), DAN_OK);
    return done(held);
}

/* Writes img[from, to) in chunks of up to 150 from where the gateway is. */
void upload_range(uint32_t from, uint32_t to)
{
    uint32_t have = from;
    while (have < to) {
        uint32_t n = to - have < DAN_GW_FILE_CHUNK_MAX ? to - have : DAN_GW_FILE_CHUNK_MAX;
        assert_int_equal(write_at(have, n, &have), DAN_GW_FILE_OK);
    }
    assert_int_equal(have, to);
}

void upload(const char *name, uint32_t size)
{
    uint32_t have = 99;
    assert_int_equal(open_file(name, size, true, &have), DAN_GW_FILE_OK);
    assert_int_equal(have, 0);
    upload_range(0, size);
    assert_int_equal(commit(dan_gw_crc32(0, img, size), NULL), DAN_GW_FILE_OK);
}
