/* CAN-over-DAN gateway outputs with injected time: SafetyState (on change
 * at once, then at the arming rate, ON in the failsafe), ArmingStatus
 * refusing values other than 0 and 255, servos (ArrayCommand, latest wins,
 * 15 per message, failsafe hold or value), LightsCommand, BeepCommand,
 * device.Temperature in the ESC telemetry, and the tunnel fixes (Targetted
 * serial_id -1, Broadcast on any channel). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <string.h>

#include "dan/can_gw/f16.h"
#include "gw_rig.h"
#include "unit_run.h"

/* The newest SafetyState captured since *from; -1 if none. */
static int last_safety(size_t *from)
{
    cap_t *c;
    int v = -1;
    uint8_t s;
    while ((c = find_cap(DAN_DC_SAFETY_STATE_ID, DAN_DC_TRANSFER_BROADCAST, from)) != NULL) {
        assert_int_equal(dan_dc_safety_state_decode(&s, c->payload, c->len), DAN_OK);
        v = s;
    }
    return v;
}

static void test_safety_state(void **state)
{
    const int16_t v[4] = {100, 200, 300, 400};
    size_t from = 0;
    (void)state;
    advance(1200000);
    assert_int_equal(last_safety(&from), DAN_DC_SAFETY_ON); /* from the start: ON */
    assert_false(R->gw.gw_flags & DAN_GW_FLAG_SAFETY_OFF);
    config_set(DAN_GW_CFG_ESC_TIMEOUT, 200);
    expect_flag_broadcast(dan_gw_safety(&R->gw, true, R->bus.now), DAN_GW_FLAG_SAFETY_OFF,
                          DAN_DC_SAFETY_STATE_ID, DAN_DC_SAFETY_OFF, &from);
    /* armed and driving; then the master goes silent: the failsafe sends
     * DISARMED and safety ON together */
    call_ok(dan_gw_arm(&R->gw, true, R->bus.now));
    call_ok(dan_gw_esc_command(&R->gw, v, 4, R->bus.now));
    advance(250000);
    assert_int_equal(R->g.stats.failsafes, 1);
    assert_int_equal(last_safety(&from), DAN_DC_SAFETY_ON);
    assert_false(dan_gw_node_flags(&R->g) & DAN_GW_FLAG_SAFETY_OFF);
    assert_false(dan_gw_node_flags(&R->g) & DAN_GW_FLAG_ARMED);
    /* the daemon's failsafe (UART lost, stop) does the same */
    call_ok(dan_gw_safety(&R->gw, true, R->bus.now));
    assert_int_equal(last_safety(&from), DAN_DC_SAFETY_OFF);
    dan_gw_node_failsafe(&R->g, R->bus.now);
    drain();
    assert_int_equal(last_safety(&from), DAN_DC_SAFETY_ON);
}

static void test_arm_refuses_other_values(void **state)
{
    static const uint8_t seven = 7, full = 255;
    size_t from;
    cap_t *c;
    (void)state;
    advance(10000);
    from = R->ncap;
    assert_int_equal(request_sealed(DAN_GW_CODE_ARM, &seven, 1), DAN_OK);
    assert_int_equal(sim_run_master(&R->bus, &R->m, 3000000), DAN_ERR_REMOTE);
    assert_int_equal(remote_code(), DAN_GW_CODE_ARM);
    drain();
    assert_null(find_cap(DAN_DC_ARMING_STATUS_ID, DAN_DC_TRANSFER_BROADCAST, &from));
    assert_false(dan_gw_node_flags(&R->g) & DAN_GW_FLAG_ARMED);
    assert_int_equal(request_sealed(DAN_GW_CODE_ARM, &full, 1), DAN_OK);
    assert_int_equal(sim_run_master(&R->bus, &R->m, 3000000), DAN_OK);
    drain();
    c = expect_cap(DAN_DC_ARMING_STATUS_ID, DAN_DC_TRANSFER_BROADCAST, &from);
    assert_int_equal(c->payload[0], 255);
}

/* Every ArrayCommand captured since *from, in order, flattened. */
static size_t servo_caps(size_t *from, dan_dc_actuator_cmd_t *out, size_t cap, size_t *msgs)
{
    dan_dc_array_command_t m;
    cap_t *c;
    size_t n = 0, i;
    *msgs = 0;
    while ((c = find_cap(DAN_DC_ARRAY_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, from)) != NULL) {
        assert_int_equal(dan_dc_array_command_decode(&m, c->payload, c->len), DAN_OK);
        for (i = 0; i < m.count && n < cap; i++) {
            out[n++] = m.cmd[i];
        }
        (*msgs)++;
    }
    return n;
}

/* 32 actuators are three ArrayCommands (15 + 15 + 2, 20 frames). When SERVO
 * requests come faster than the bus takes all three, each request drops
 * the queued ones not yet on the bus: the last messages never went out and
 * actuators 30 and 31 were never commanded (review finding). The message
 * that leads changes after a drop, so each gets its turn. */
static void test_servos_faster_than_the_bus(void **state)
{
    dan_gw_servo_t s[32];
    dan_dc_array_command_t m;
    bool seen[32];
    size_t from = R->ncap, i, round;
    cap_t *c;
    (void)state;
    memset(seen, 0, sizeof seen);
    for (round = 0; round < 12; round++) {
        for (i = 0; i < 32; i++) {
            s[i] = dan_gw_servo_make((uint8_t)i, 0, (float)round / 16.0f);
        }
        assert_int_equal(dan_gw_servo(&R->gw, s, 32, R->bus.now), DAN_OK);
        assert_int_equal(finish_stalled(), DAN_OK);
        (void)send_frames(12); /* the bus takes a message and a bit per request */
        R->bus.now += 2500u;
    }
    while ((c = find_cap(DAN_DC_ARRAY_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, &from)) != NULL) {
        assert_int_equal(dan_dc_array_command_decode(&m, c->payload, c->len), DAN_OK);
        for (i = 0; i < m.count; i++) {
            seen[m.cmd[i].actuator_id] = true;
        }
    }
    for (i = 0; i < 32; i++) {
        assert_true(seen[i]);
    }
}

static void test_servos_and_failsafe(void **state)
{
    dan_gw_servo_t s[20];
    dan_gw_servo_fs_t fs[2];
    dan_dc_actuator_cmd_t got[64];
    size_t from, n, msgs, i;
    (void)state;
    config_set(DAN_GW_CFG_ESC_TIMEOUT, 200);
    for (i = 0; i < 20; i++) {
        s[i] = dan_gw_servo_make((uint8_t)i, DAN_DC_ACTUATOR_UNITLESS, (float)i / 32.0f);
    }
    from = R->ncap;
    call_ok(dan_gw_servo(&R->gw, s, 20, R->bus.now));
    n = servo_caps(&from, got, 64, &msgs);
    assert_int_equal(msgs, 2); /* 15 + 5 */
    assert_int_equal(n, 20);
    for (i = 0; i < 20; i++) {
        assert_int_equal(got[i].actuator_id, i);
        assert_int_equal(got[i].command_type, DAN_DC_ACTUATOR_UNITLESS);
        assert_true(dan_f16_to_f32(got[i].value_f16) == (float)i / 32.0f);
    }
    /* a saturated float16: never an infinity on the bus (review finding:
     * 70000 became +inf) */
    assert_int_equal(dan_gw_servo_make(1, 0, 70000.0f).value_f16, 0x7BFF);
    assert_int_equal(dan_gw_servo_make(1, 0, 65520.0f).value_f16, 0x7BFF);
    assert_int_equal(dan_gw_servo_make(1, 0, -INFINITY).value_f16, 0xFBFF);
    assert_int_equal(dan_gw_servo_make(1, 0, 65504.0f).value_f16, 0x7BFF);
    /* latest wins per actuator; the others repeat their last command */
    s[0] = dan_gw_servo_make(3, DAN_DC_ACTUATOR_PWM, 1900.0f);
    call_ok(dan_gw_servo(&R->gw, s, 1, R->bus.now));
    n = servo_caps(&from, got, 64, &msgs);
    assert_int_equal(n, 20);
    assert_int_equal(got[3].command_type, DAN_DC_ACTUATOR_PWM);
    assert_true(dan_f16_to_f32(got[3].value_f16) == 1900.0f);
    /* failsafe table: actuator 1 goes to -0.25, actuator 2 holds */
    fs[0].mode = DAN_GW_SERVO_VALUE;
    fs[0].value = dan_gw_servo_make(1, DAN_DC_ACTUATOR_POSITION, -0.25f);
    fs[1].mode = DAN_GW_SERVO_HOLD;
    fs[1].value = dan_gw_servo_make(2, 0, 0.0f);
    call_ok(dan_gw_servo_failsafe(&R->gw, fs, 2, R->bus.now));
    assert_int_equal(R->gw.servo_fs_kept, 2);
    advance(150000);
    n = servo_caps(&from, got, 64, &msgs);
    assert_int_equal(msgs, 0); /* before the timeout: nothing new */
    advance(100000);
    n = servo_caps(&from, got, 64, &msgs);
    assert_int_equal(n, 20);
    assert_int_equal(got[1].command_type, DAN_DC_ACTUATOR_POSITION);
    assert_true(dan_f16_to_f32(got[1].value_f16) == -0.25f);
    assert_true(dan_f16_to_f32(got[2].value_f16) == 2.0f / 32.0f);
    assert_true(dan_f16_to_f32(got[3].value_f16) == 1900.0f);
    /* and again with each ArmingStatus while the silence lasts */
    advance(1000000);
    n = servo_caps(&from, got, 64, &msgs);
    assert_true(msgs >= 2 * 2 && n == msgs * 10);
    assert_true(dan_f16_to_f32(got[1].value_f16) == -0.25f);
    /* the next SERVO ends the failsafe */
    s[0] = dan_gw_servo_make(1, DAN_DC_ACTUATOR_UNITLESS, 0.5f);
    call_ok(dan_gw_servo(&R->gw, s, 1, R->bus.now));
    n = servo_caps(&from, got, 64, &msgs);
    assert_int_equal(n, 20);
    assert_true(dan_f16_to_f32(got[1].value_f16) == 0.5f);
}

static void test_servo_table_full(void **state)
{
    dan_gw_servo_t s[DAN_GW_SERVO_MAX];
    size_t i;
    (void)state;
    for (i = 0; i < DAN_GW_SERVO_MAX; i++) {
        s[i] = dan_gw_servo_make((uint8_t)(100 + i), 0, 0.0f);
    }
    call_ok(dan_gw_servo(&R->gw, s, DAN_GW_SERVO_MAX, R->bus.now));
    s[0] = dan_gw_servo_make(7, 0, 1.0f); /* a 33rd actuator */
    call_ok(dan_gw_servo(&R->gw, s, 1, R->bus.now));
    assert_int_equal(R->g.stats.servo_dropped, 1);
}

/* Failsafe entries of actuators never commanded do not keep slots once
 * the table no longer names them; HOLD entries take none. */
static void test_servo_failsafe_slots_freed(void **state)
{
    dan_gw_servo_fs_t fs[DAN_GW_SERVO_MAX];
    dan_gw_servo_t s[DAN_GW_SERVO_MAX];
    size_t i;
    (void)state;
    for (i = 0; i < DAN_GW_SERVO_MAX; i++) {
        fs[i].mode = DAN_GW_SERVO_VALUE;
        fs[i].value = dan_gw_servo_make((uint8_t)(200 + i), 0, 0.5f);
    }
    call_ok(dan_gw_servo_failsafe(&R->gw, fs, DAN_GW_SERVO_MAX, R->bus.now));
    assert_int_equal(R->gw.servo_fs_kept, DAN_GW_SERVO_MAX);
    for (i = 0; i < DAN_GW_SERVO_MAX; i++) { /* the same, all HOLD: no slot needed */
        fs[i].mode = DAN_GW_SERVO_HOLD;
    }
    call_ok(dan_gw_servo_failsafe(&R->gw, fs, DAN_GW_SERVO_MAX, R->bus.now));
    assert_int_equal(R->gw.servo_fs_kept, DAN_GW_SERVO_MAX);
    assert_int_equal(R->g.servos.n, 0);
    for (i = 0; i < DAN_GW_SERVO_MAX; i++) {
        s[i] = dan_gw_servo_make((uint8_t)i, 0, 0.25f);
    }
    call_ok(dan_gw_servo(&R->gw, s, DAN_GW_SERVO_MAX, R->bus.now));
    assert_int_equal(R->g.stats.servo_dropped, 0);
}

/* A LightsCommand of 20 lights is 9 frames of low priority, and an
 * Allocation answer comes whenever a CAN node asks: queued in front of
 * throttle they delayed it (review finding). They take the bulk queue:
 * the next RawCommand is the first frame out. */
static void test_lights_wait_behind_throttle(void **state)
{
    static const int16_t v[4] = {500, 500, 500, 500};
    dan_gw_light_t l[20];
    dan_can_frame_t f;
    dan_dc_transfer_t id;
    size_t i;
    (void)state;
    advance(1000);
    for (i = 0; i < 20; i++) {
        l[i].light_id = (uint8_t)i;
        l[i].rgb565 = 0xFFFF;
    }
    assert_int_equal(dan_gw_lights(&R->gw, l, 20, R->bus.now), DAN_OK);
    assert_int_equal(finish_stalled(), DAN_OK);
    assert_int_equal(dan_gw_esc_command(&R->gw, v, 4, R->bus.now), DAN_OK);
    assert_int_equal(finish_stalled(), DAN_OK);
    assert_true(dan_gw_node_tx_peek(&R->g, &f));
    assert_int_equal(dan_dc_parse_id(f.id, &id), DAN_OK);
    assert_int_equal(id.data_type_id, DAN_DC_ESC_RAW_COMMAND_ID);
    assert_true(R->g.q_bulk.len >= 9u);
}

/* Throttle goes first on CAN even when SERVO requests come in between:
 * the new RawCommand was queued behind a fresh set of ArrayCommands (20
 * frames for 32 actuators), and on a bus that takes fewer frames than
 * that per cycle no RawCommand ever went out (review finding). */
static void test_throttle_ahead_of_servos(void **state)
{
    static const int16_t v[4] = {100, 200, 300, 400};
    dan_gw_servo_t s[32];
    size_t from = R->ncap, i, round, raw = 0;
    (void)state;
    for (i = 0; i < 32; i++) {
        s[i] = dan_gw_servo_make((uint8_t)i, 0, 0.5f);
    }
    for (round = 0; round < 10; round++) {
        assert_int_equal(dan_gw_servo(&R->gw, s, 32, R->bus.now), DAN_OK);
        assert_int_equal(finish_stalled(), DAN_OK);
        assert_int_equal(dan_gw_esc_command(&R->gw, v, 4, R->bus.now), DAN_OK);
        assert_int_equal(finish_stalled(), DAN_OK);
        (void)send_frames(16); /* 1 Mbit/s: about 16 frames a 2.5 ms cycle */
        R->bus.now += 2500u;
    }
    while (find_cap(DAN_DC_ESC_RAW_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, &from) != NULL) {
        raw++;
    }
    assert_int_equal(raw, 10);
}

/* A raw frame the FC sent whose last byte has no end-of-transfer bit (it
 * is no DroneCAN tail byte) made the next transfer of the bulk queue look
 * in flight: latest-wins kept an older LightsCommand (review finding). */
static void test_raw_frame_does_not_pin_lights(void **state)
{
    const dan_gw_light_t l1[1] = {{1, 0xF800}}, l2[1] = {{1, 0x001F}};
    dan_can_frame_t f;
    dan_dc_lights_command_t lm;
    size_t from;
    cap_t *c;
    (void)state;
    advance(1000);
    memset(&f, 0, sizeof f);
    f.id = 0x123;
    f.dlc = 1; /* data 00 */
    call_ok(dan_gw_can_send(&R->gw, &f, 1, R->bus.now));
    drain(); /* it is on the bus */
    assert_int_equal(dan_gw_node_tx_pending(&R->g), 0);
    from = R->ncap;
    assert_int_equal(dan_gw_lights(&R->gw, l1, 1, R->bus.now), DAN_OK);
    assert_int_equal(finish_stalled(), DAN_OK);
    assert_int_equal(dan_gw_lights(&R->gw, l2, 1, R->bus.now), DAN_OK);
    assert_int_equal(finish_stalled(), DAN_OK);
    drain();
    c = expect_cap(DAN_DC_LIGHTS_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, &from);
    assert_int_equal(dan_dc_lights_command_decode(&lm, c->payload, c->len), DAN_OK);
    assert_int_equal(lm.light[0].rgb565, 0x001F); /* only the latest */
    assert_null(find_cap(DAN_DC_LIGHTS_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, &from));
}

static void test_lights_and_beep(void **state)
{
    const dan_gw_light_t l[3] = {{0, 0xF800}, {1, 0x07E0}, {19, 0x001F}};
    dan_dc_lights_command_t lm;
    dan_dc_beep_command_t bm;
    size_t from;
    cap_t *c;
    (void)state;
    advance(1000);
    from = R->ncap;
    call_ok(dan_gw_lights(&R->gw, l, 3, R->bus.now));
    c = expect_cap(DAN_DC_LIGHTS_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, &from);
    assert_int_equal(dan_dc_lights_command_decode(&lm, c->payload, c->len), DAN_OK);
    assert_int_equal(lm.count, 3);
    assert_int_equal(lm.light[0].light_id, 0);
    assert_int_equal(lm.light[0].rgb565, 0xF800);
    assert_int_equal(lm.light[2].light_id, 19);
    assert_int_equal(lm.light[2].rgb565, 0x001F);
    call_ok(dan_gw_beep(&R->gw, 2000, 250, R->bus.now));
    c = expect_cap(DAN_DC_BEEP_COMMAND_ID, DAN_DC_TRANSFER_BROADCAST, &from);
    assert_int_equal(dan_dc_beep_command_decode(&bm, c->payload, c->len), DAN_OK);
    assert_true(dan_f16_to_f32(bm.frequency_f16) == 2000.0f);
    assert_true(dan_f16_to_f32(bm.duration_f16) == dan_f16_to_f32(dan_f16_from_f32(0.25f)));
    /* out of range: refused by the client's encoder, and by the gateway */
    assert_int_equal(dan_gw_beep(&R->gw, 0, 100, R->bus.now), DAN_ERR_ARG);
    assert_int_equal(dan_gw_lights(&R->gw, l, 0, R->bus.now), DAN_ERR_ARG);
}

static void temperature(uint8_t src, float kelvin, uint8_t flags)
{
    dan_dc_temperature_t m;
    uint8_t buf[DAN_DC_TEMPERATURE_MAX_SIZE];
    m.device_id = 0;
    m.temperature_f16 = dan_f16_from_f32(kelvin);
    m.error_flags = flags;
    inject(src, DAN_DC_TEMPERATURE_ID, DAN_DC_TEMPERATURE_SIGNATURE, DAN_DC_TRANSFER_BROADCAST, 0,
           buf, dan_dc_temperature_encode(&m, buf, sizeof buf));
}

static void test_temperature_in_telemetry(void **state)
{
    const dan_gw_telem_t *t;
    (void)state;
    advance(1000);
    esc_status(30, 2, 16.0f, 3.0f, 300.0f, 1000);
    esc_status(31, 3, 16.0f, 3.0f, 300.0f, 1000);
    temperature(30, 318.0f, 1);
    temperature(77, 400.0f, 0); /* no ESC of node 77: nowhere to go */
    advance(5000);
    call_ok(dan_gw_telemetry(&R->gw, 0, R->bus.now));
    t = &R->gw.esc[2];
    assert_true(t->flags & DAN_GW_TELEM_DEVICE);
    assert_true(dan_f16_to_f32(t->dev_temp_f16) == 318.0f);
    assert_int_equal(t->dev_flags, 1);
    assert_true(t->dev_age_ms >= 4 && t->dev_age_ms <= 7);
    t = &R->gw.esc[3];
    assert_true(t->flags & DAN_GW_TELEM_STATUS);
    assert_false(t->flags & DAN_GW_TELEM_DEVICE);
}

static void tun_open(uint8_t mode, uint8_t target, int8_t serial, uint8_t options, int want)
{
    assert_int_equal(
        tunnel_open_start(0, mode, DAN_DC_TUNNEL_UNDEFINED, target, serial, options, 0), DAN_OK);
    assert_int_equal(finish(), want);
}

static void targetted_from(uint8_t src, int8_t serial, const char *text)
{
    tunnel_targetted_from(src, serial, (const uint8_t *)text, strlen(text));
}

static void broadcast_on(uint8_t channel, const char *text)
{
    dan_dc_tunnel_broadcast_t m;
    uint8_t buf[DAN_DC_TUNNEL_BROADCAST_MAX_SIZE];
    memset(&m, 0, sizeof m);
    m.protocol = DAN_DC_TUNNEL_UNDEFINED;
    m.channel_id = channel;
    m.buffer_len = (uint8_t)strlen(text);
    memcpy(m.buffer, text, m.buffer_len);
    inject(33, DAN_DC_TUNNEL_BROADCAST_ID, DAN_DC_TUNNEL_BROADCAST_SIGNATURE,
           DAN_DC_TRANSFER_BROADCAST, 0, buf, dan_dc_tunnel_broadcast_encode(&m, buf, sizeof buf));
}

/* What port 0 has received, as a string. */
static const char *tun_read(void)
{
    static char out[DAN_GW_TUN_CHUNK_MAX + 1];
    const uint8_t *d;
    size_t n;
    call_ok(dan_gw_tunnel_xfer(&R->gw, 0, NULL, 0, 128, R->bus.now));
    assert_int_equal(dan_gw_tunnel_data(&R->gw, &d, &n), DAN_OK);
    memcpy(out, d, n);
    out[n] = '\0';
    return out;
}

static void test_tunnel_default_serial(void **state)
{
    (void)state;
    /* serial_id 2 opened: a reply from port 3 is someone else's */
    tun_open(DAN_GW_TUN_TARGETTED, 20, 2, 0, DAN_OK);
    targetted_from(20, 3, "not ours");
    targetted_from(20, 2, "ours");
    assert_string_equal(tun_read(), "ours");
    /* serial_id -1 (the node's default port): the node answers with the
     * port it resolved, any of them is ours; other nodes' are not */
    tun_open(DAN_GW_TUN_TARGETTED, 20, DAN_GW_TUN_DEFAULT_SERIAL, 0, DAN_OK);
    targetted_from(20, 3, "port3 ");
    targetted_from(21, 3, "node21 ");
    targetted_from(20, 0, "port0");
    assert_string_equal(tun_read(), "port3 port0");
}

static void test_tunnel_any_channel(void **state)
{
    (void)state;
    tun_open(DAN_GW_TUN_BROADCAST, 3, 0, 0, DAN_OK);
    broadcast_on(7, "ch7 ");
    broadcast_on(3, "ch3");
    assert_string_equal(tun_read(), "ch3");
    tun_open(DAN_GW_TUN_BROADCAST, 3, 0, DAN_GW_TUN_ANY_CHANNEL, DAN_OK);
    broadcast_on(7, "ch7 ");
    broadcast_on(3, "ch3");
    assert_string_equal(tun_read(), "ch7 ch3");
    tun_open(DAN_GW_TUN_BROADCAST, 3, 0, 2, DAN_ERR_NACK); /* no such option */
}

static void test_malformed_outputs(void **state)
{
    static const uint8_t safety7[] = {7};
    static const uint8_t servo0[] = {0};
    static const uint8_t servo_type5[] = {1, 0, 5, 0, 0};
    static const uint8_t fs_bits[] = {1, 0, 0x10, 0, 0}; /* reserved kind bits */
    static const uint8_t lights21[] = {21};
    static const uint8_t beep0[] = {0, 1};
    static const struct {
        uint32_t code;
        const uint8_t *p;
        size_t n;
    } bad[] = {
        {DAN_GW_CODE_SAFETY, safety7, 1},
        {DAN_GW_CODE_SAFETY, NULL, 0},
        {DAN_GW_CODE_SERVO, servo0, 1},
        {DAN_GW_CODE_SERVO, servo_type5, 5},
        {DAN_GW_CODE_SERVO_FAILSAFE, fs_bits, 5},
        {DAN_GW_CODE_LIGHTS, lights21, 1},
        {DAN_GW_CODE_BEEP, beep0, 2},
    };
    uint32_t errs;
    size_t i;
    (void)state;
    advance(1000);
    errs = R->p.stats.errors_sent;
    for (i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(request_sealed(bad[i].code, bad[i].p, bad[i].n), DAN_OK);
        assert_int_equal(sim_run_master(&R->bus, &R->m, 3000000), DAN_ERR_REMOTE);
        assert_int_equal(remote_code(), bad[i].code);
    }
    assert_int_equal(R->p.stats.errors_sent - errs, sizeof bad / sizeof bad[0]);
    assert_int_equal(R->g.stats.servo_cmds, 0);
    assert_int_equal(R->g.servos.n, 0);
}

int main(void)
{
    return UNIT_RUN(
        "gateway_out", setup, teardown, test_safety_state, test_arm_refuses_other_values,
        test_servos_and_failsafe, test_servos_faster_than_the_bus, test_throttle_ahead_of_servos,
        test_raw_frame_does_not_pin_lights, test_servo_table_full, test_servo_failsafe_slots_freed,
        test_lights_and_beep, test_lights_wait_behind_throttle, test_temperature_in_telemetry,
        test_tunnel_default_serial, test_tunnel_any_channel, test_malformed_outputs);
}
