/* CAN-over-DAN gateway: the compact ESC exchanges (ESC_FAST, ESC_FAST_T)
 * through master + client + node on the simulated wire: frame sizes, the
 * RawCommand exact for 1..20 channels, the failsafe fed, the record's round
 * robin with its fresh bit and age, the absent record, every malformed
 * length refused by the gateway. The codec's vectors are in
 * test_gateway_vectors.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/can_gw/f16.h"
#include "dan/frame.h"
#include "gw_rig.h"
#include "unit_run.h"

/* The RawCommand captured from index *from on must be exactly v[0..n). */
static void expect_raw(size_t *from, const int16_t *v, size_t n)
{
    dan_dc_esc_raw_command_t rc;
    cap_t *c = find_cap(DAN_DC_ESC_RAW_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, from);
    assert_non_null(c);
    assert_int_equal(dan_dc_esc_raw_command_decode(&rc, c->payload, c->len), DAN_OK);
    assert_int_equal(rc.count, n);
    assert_memory_equal(rc.cmd, v, n * sizeof v[0]);
}

static void test_fast_sizes_and_values(void **state)
{
    int16_t v[DAN_GW_ESC_MAX];
    size_t n, i, from = 0;
    (void)state;
    for (n = 1; n <= DAN_GW_ESC_MAX; n++) {
        for (i = 0; i < n; i++) {
            v[i] = (int16_t)((i * 977u + n * 31u) % 16384u) - 8192;
        }
        v[0] = n % 2u ? -8192 : 8191;
        assert_int_equal(dan_gw_esc_fast(&R->gw, v, n, n % 2u == 0u, R->bus.now), DAN_OK);
        assert_int_equal(dan_gw_esc_fast(&R->gw, v, n, false, R->bus.now), DAN_ERR_BUSY);
        /* 'D', code, length, ceil(14 n / 8) values, seal 2, crc 1 */
        assert_int_equal(R->m.link.tx_len, 3u + (14u * n + 7u) / 8u + 2u + 1u);
        assert_int_equal(finish(), DAN_OK);
        expect_raw(&from, v, n);
        assert_int_equal(R->gw.last_telem, DAN_GW_NONE); /* no ESC has reported */
    }
    assert_int_equal(R->g.stats.esc_cmds, DAN_GW_ESC_MAX);
    /* 4 ESCs: the 13-byte request, the 7-byte response */
    assert_int_equal(dan_gw_esc_fast(&R->gw, v, 4, false, R->bus.now), DAN_OK);
    assert_int_equal(R->m.link.tx_len, 13);
    assert_int_equal(finish(), DAN_OK);
    assert_int_equal(R->m.resp_len, 1u + DAN_GW_SEAL_SIZE);
    assert_int_equal(dan_frame_size(DAN_GW_CODE_ESC_FAST, R->m.resp_len), 7);
    /* the client refuses what the wire cannot carry */
    v[2] = 8192;
    assert_int_equal(dan_gw_esc_fast(&R->gw, v, 4, true, R->bus.now), DAN_ERR_ARG);
    assert_int_equal(dan_gw_esc_fast(&R->gw, v, 0, true, R->bus.now), DAN_ERR_ARG);
    assert_int_equal(dan_gw_esc_fast(&R->gw, v, 21, true, R->bus.now), DAN_ERR_ARG);
}

static void test_fast_record_round_robin(void **state)
{
    const int16_t v[4] = {10, 20, 30, 40};
    uint8_t order[7];
    size_t i;
    (void)state;
    three_esc_statuses(-131072);
    /* an ESC with StatusExtended only has nothing for the compact record */
    esc_status_ext_from(25, &(const dan_dc_esc_status_extended_t){.esc_index = 5});
    advance(10000); /* 10 ms: age 2 units of 4 ms */
    for (i = 0; i < 7; i++) {
        call_ok(dan_gw_esc_fast(&R->gw, v, 4, true, R->bus.now));
        order[i] = R->gw.last_telem;
        if (i == 0u) { /* 10 ms and the request's 1.1 ms: 2 units */
            assert_int_equal(R->gw.esc[0].age_ms, 8u);
        }
        /* each ESC's first record is fresh, the repeats are not */
        assert_int_equal(R->gw.telem_fresh, i < 3u);
        assert_int_equal(R->m.resp_len, 1u + DAN_GW_FAST_REC_SIZE + DAN_GW_SEAL_SIZE);
    }
    assert_int_equal(dan_frame_size(DAN_GW_CODE_ESC_FAST_T, R->m.resp_len), 17);
    assert_round_robin_013(order, 4);
    assert_int_equal(order[6], 0);
    /* the binary16 the ESC sent, the int18 rpm at both ends of its range */
    assert_true(dan_f16_to_f32(R->gw.esc[0].voltage_f16) == 12.5f);
    assert_int_equal(R->gw.esc[1].current_f16, dan_f16_from_f32(-3.14159f));
    assert_int_equal(R->gw.esc[1].temperature_f16, dan_f16_from_f32(310.15f));
    assert_int_equal(R->gw.esc[1].rpm, -131072);
    assert_int_equal(R->gw.esc[3].rpm, 131071);
    assert_int_equal(R->gw.esc[3].flags, DAN_GW_TELEM_STATUS);
    /* a new esc.Status of ESC 1 is fresh again; ESC_FAST (no T) carries none
     * and does not move the round robin */
    esc_status(21, 1, 16.0f, 2.0f, 311.0f, 42);
    call_ok(dan_gw_esc_fast(&R->gw, v, 4, false, R->bus.now));
    assert_int_equal(R->gw.last_telem, DAN_GW_NONE);
    assert_int_equal(R->m.resp_len, 1u + DAN_GW_SEAL_SIZE);
    call_ok(dan_gw_esc_fast(&R->gw, v, 4, true, R->bus.now));
    assert_int_equal(R->gw.last_telem, 1);
    assert_true(R->gw.telem_fresh);
    assert_int_equal(R->gw.esc[1].rpm, 42);
    assert_true(R->gw.esc[1].age_ms <= 4u);
}

static void test_fast_age_saturates(void **state)
{
    const int16_t v[1] = {0};
    (void)state;
    config_set(DAN_GW_CFG_ESC_TIMEOUT, 60000);
    esc_status(20, 2, 12.0f, 1.0f, 300.0f, 7);
    advance(1010000);
    call_ok(dan_gw_esc_fast(&R->gw, v, 1, true, R->bus.now));
    assert_int_equal(R->gw.last_telem, 2);
    assert_true(R->gw.esc[2].age_ms >= 1008u && R->gw.esc[2].age_ms <= 1016u);
    advance(5000000);
    call_ok(dan_gw_esc_fast(&R->gw, v, 1, true, R->bus.now));
    assert_int_equal(R->gw.esc[2].age_ms, 1020u); /* 255: 1020 ms or older */
    assert_false(R->gw.telem_fresh);
}

/* The failsafe is fed by ESC_FAST as by ESC_CMD, and ended by it. */
static void test_fast_feeds_failsafe(void **state)
{
    const int16_t v[4] = {1000, 2000, 3000, 4000};
    const int16_t zeros[4] = {0};
    size_t i, from;
    (void)state;
    config_set(DAN_GW_CFG_ESC_TIMEOUT, 100);
    for (i = 0; i < 40; i++) { /* 400 ms of commands every 10 ms */
        call_ok(dan_gw_esc_fast(&R->gw, v, 4, i % 4u == 0u, R->bus.now));
        advance(10000);
    }
    assert_int_equal(R->g.stats.failsafes, 0);
    from = R->ncap;
    advance(100000);
    assert_int_equal(R->g.stats.failsafes, 1);
    expect_raw(&from, zeros, 4);
    call_ok(dan_gw_esc_fast(&R->gw, v, 4, false, R->bus.now));
    assert_false(R->gw.gw_flags & DAN_GW_FLAG_FAILSAFE);
    expect_raw(&from, v, 4);
}

/* Every length that no channel count has, counts above 20 and set padding
 * bits: an error frame each, and nothing broadcast. */
static void test_fast_malformed(void **state)
{
    uint8_t p[40];
    size_t len, n, bad = 0;
    uint32_t errs;
    (void)state;
    memset(p, 0, sizeof p);
    advance(1000);
    errs = R->p.stats.errors_sent;
    for (len = 0; len < sizeof p; len++) {
        bool good = false;
        for (n = 1; n <= DAN_GW_ESC_MAX; n++) {
            good = good || DAN_GW_ESC_FAST_SIZE(n) == len;
        }
        if (good) {
            continue;
        }
        assert_int_equal(
            request_sealed(bad % 2u ? DAN_GW_CODE_ESC_FAST_T : DAN_GW_CODE_ESC_FAST, p, len),
            DAN_OK);
        assert_int_equal(sim_run_master(&R->bus, &R->m, 3000000), DAN_ERR_REMOTE);
        bad++;
    }
    p[1] = 0x40; /* one value: bits 14, 15 are padding */
    assert_int_equal(request_sealed(DAN_GW_CODE_ESC_FAST, p, 2), DAN_OK);
    assert_int_equal(sim_run_master(&R->bus, &R->m, 3000000), DAN_ERR_REMOTE);
    assert_int_equal(remote_code(), DAN_GW_CODE_ESC_FAST);
    assert_int_equal(R->p.stats.errors_sent - errs, bad + 1u);
    assert_int_equal(R->g.stats.esc_cmds, 0);
    assert_false(R->g.esc.active);
}

/* Codec edges: response lengths, the age's rounding and saturation, the
 * encoder's arguments. */
static void test_fast_codec_limits(void **state)
{
    uint8_t buf[DAN_GW_FAST_RSP_MAX + 1u], flags = 0;
    dan_gw_fast_rec_t rec;
    dan_gw_telem_t t;
    bool has = true;
    (void)state;
    memset(buf, 0, sizeof buf);
    memset(&t, 0, sizeof t);
    assert_int_equal(dan_gw_msg_esc_fast_rsp_decode(&flags, &rec, &has, buf, 1), DAN_OK);
    assert_false(has);
    assert_int_equal(dan_gw_msg_esc_fast_rsp_decode(&flags, &rec, &has, buf, 2), DAN_ERR_MALFORMED);
    assert_int_equal(dan_gw_msg_esc_fast_rsp_decode(&flags, &rec, &has, buf, sizeof buf),
                     DAN_ERR_MALFORMED);
    t.age_ms = 3;
    assert_int_equal(dan_gw_fast_rec_make(&t, false).age_4ms, 0);
    t.age_ms = 4294967295u;
    assert_int_equal(dan_gw_fast_rec_make(&t, false).age_4ms, 255);
    assert_int_equal(dan_gw_msg_esc_fast_encode(NULL, 4, buf, sizeof buf), DAN_ERR_ARG);
    assert_int_equal(dan_gw_msg_esc_fast_encode((const int16_t *)buf, 4, buf, 6), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_gw_msg_esc_fast_encode((const int16_t *)buf, 4, NULL, 0), 7);
}

int main(void)
{
    int failed = UNIT_RUN("gateway_fast", setup, teardown, test_fast_sizes_and_values,
                          test_fast_record_round_robin, test_fast_age_saturates,
                          test_fast_feeds_failsafe, test_fast_malformed);
    failed += UNIT_RUN("gateway_fast_codec", NULL, NULL, test_fast_codec_limits);
    return failed;
}
