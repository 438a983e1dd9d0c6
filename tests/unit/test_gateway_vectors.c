/* CAN-over-DAN gateway messages against tests/vectors/gateway.txt (every
 * vector decoded to its field text and re-encoded byte for byte) and the
 * seal against tests/vectors/gateway_sealed.txt. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/codes.h"
#include "dan/can_gw/client.h"
#include "dan/can_gw/f16.h"
#include "dan/frame.h"
#include "gw_vectors.h"
#include "vectors.h"
#include "unit_run.h"

/* ---- codec vectors ---- */

static void cat_frame(char *out, size_t cap, const dan_can_frame_t *f)
{
    uint32_t id = f->id | ((f->flags & DAN_CAN_EXT) ? DAN_GW_CAN_ID_EXT : 0u) |
                  ((f->flags & DAN_CAN_RTR) ? DAN_GW_CAN_ID_RTR : 0u) |
                  ((f->flags & DAN_CAN_OWN) ? DAN_GW_CAN_ID_OWN : 0u);
    vec_cat(out, cap, " frame=%08X/%u/", (unsigned)id, f->dlc);
    vec_cat_hex(out, cap, f->data, (f->flags & DAN_CAN_RTR) ? 0u : f->dlc);
}

static void cat_value(char *out, size_t cap, const char *key, const dan_gw_value_t *v)
{
    uint32_t bits;
    vec_cat(out, cap, " %s=%u", key, v->tag);
    switch (v->tag) {
    case DAN_GW_VALUE_INTEGER: vec_cat(out, cap, "/%lld", (long long)v->integer); break;
    case DAN_GW_VALUE_REAL:
        memcpy(&bits, &v->real, sizeof bits);
        vec_cat(out, cap, "/%08lx", (unsigned long)bits);
        break;
    case DAN_GW_VALUE_BOOLEAN: vec_cat(out, cap, "/%u", v->boolean); break;
    case DAN_GW_VALUE_STRING:
        vec_cat(out, cap, "/");
        vec_cat_hex(out, cap, v->string, v->string_len);
        break;
    default: break;
    }
}

/* The bus-management messages (gen_gateway_mgmt.py). */
static int vec_call(const char *dir, const uint8_t *p, size_t len, char *txt, size_t cap,
                    uint8_t *enc, size_t ecap)
{
    if (!strcmp(dir, "req")) {
        dan_gw_call_t c;
        assert_int_equal(dan_gw_msg_call_decode(&c, p, len), DAN_OK);
        vec_cat(txt, cap, "id=%u node=%u op=%u", c.call_id, c.node_id, c.op);
        if (c.op == DAN_GW_CALL_PARAM_GET_INDEX) {
            vec_cat(txt, cap, " index=%u", c.index);
        } else if (c.op == DAN_GW_CALL_PARAM_GET_NAME || c.op == DAN_GW_CALL_PARAM_SET) {
            vec_cat(txt, cap, " name=");
            vec_cat_hex(txt, cap, (const uint8_t *)c.name, c.name_len);
            if (c.op == DAN_GW_CALL_PARAM_SET) {
                cat_value(txt, cap, "value", &c.value);
            }
        } else if (c.op == DAN_GW_CALL_RESTART) {
            vec_cat(txt, cap, " magic=%llu force=%u", (unsigned long long)c.magic, c.force);
        }
        return dan_gw_msg_call_encode(&c, enc, ecap);
    } else {
        dan_gw_call_state_t st;
        assert_int_equal(dan_gw_msg_call_state_decode(&st, p, len), DAN_OK);
        vec_cat(txt, cap, "id=%u state=%u len=%lu", st.call_id, st.state,
                (unsigned long)st.result_len);
        return dan_gw_msg_call_state_encode(&st, enc, ecap);
    }
}

static int vec_result(const char *msg, const char *dir, const uint8_t *p, size_t len, char *txt,
                      size_t cap, uint8_t *enc, size_t ecap)
{
    if (!strcmp(msg, "call_result")) {
        dan_gw_result_t q;
        if (!strcmp(dir, "req")) {
            assert_int_equal(dan_gw_msg_result_req_decode(&q, p, len), DAN_OK);
            vec_cat(txt, cap, "id=%u offset=%lu max=%u", q.call_id, (unsigned long)q.offset, q.max);
            return dan_gw_msg_result_req_encode(&q, enc, ecap);
        }
        assert_int_equal(dan_gw_msg_result_rsp_decode(&q, p, len), DAN_OK);
        vec_cat(txt, cap, "id=%u state=%u len=%lu offset=%lu data=", q.call_id, q.state,
                (unsigned long)q.result_len, (unsigned long)q.offset);
        vec_cat_hex(txt, cap, q.data, q.len);
        return dan_gw_msg_result_rsp_encode(&q, enc, ecap);
    }
    if (!strcmp(msg, "param")) {
        dan_gw_param_t pr;
        assert_int_equal(dan_gw_msg_param_decode(&pr, p, len), DAN_OK);
        vec_cat(txt, cap, "present=%u", pr.present);
        cat_value(txt, cap, "value", &pr.value);
        if (pr.present & DAN_GW_PARAM_HAS_DEFAULT) {
            cat_value(txt, cap, "default", &pr.default_value);
        }
        if (pr.present & DAN_GW_PARAM_HAS_MAX) {
            cat_value(txt, cap, "max", &pr.max_value);
        }
        if (pr.present & DAN_GW_PARAM_HAS_MIN) {
            cat_value(txt, cap, "min", &pr.min_value);
        }
        vec_cat(txt, cap, " name=");
        vec_cat_hex(txt, cap, (const uint8_t *)pr.name, pr.name_len);
        return dan_gw_msg_param_encode(&pr, enc, ecap);
    } else {
        dan_gw_opcode_result_t o;
        assert_int_equal(dan_gw_msg_opcode_result_decode(&o, p, len), DAN_OK);
        vec_cat(txt, cap, "ok=%u arg=%lld", o.ok, (long long)o.argument);
        return dan_gw_msg_opcode_result_encode(&o, enc, ecap);
    }
}

/* ESC_FAST / ESC_FAST_T; "bad" payloads must be refused (and are
 * returned as they are, so the caller's byte comparison holds). */
static int vec_fast(const char *msg, const char *dir, const uint8_t *p, size_t len, char *txt,
                    size_t cap, uint8_t *enc, size_t ecap)
{
    int16_t v[DAN_GW_ESC_MAX];
    dan_gw_fast_rec_t rec;
    uint8_t flags;
    bool has;
    size_t i, n;
    if (!strcmp(dir, "bad")) {
        if (!strcmp(msg, "esc_fast")) {
            assert_int_equal(dan_gw_msg_esc_fast_decode(p, len, v, &n), DAN_ERR_MALFORMED);
        } else {
            assert_int_equal(dan_gw_msg_esc_fast_rsp_decode(&flags, &rec, &has, p, len),
                             DAN_ERR_MALFORMED);
        }
        memcpy(enc, p, len);
        return (int)len;
    }
    if (!strcmp(dir, "req")) {
        assert_int_equal(dan_gw_msg_esc_fast_decode(p, len, v, &n), DAN_OK);
        vec_cat(txt, cap, "values=");
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, i ? ",%d" : "%d", v[i]);
        }
        return dan_gw_msg_esc_fast_encode(v, n, enc, ecap);
    }
    assert_int_equal(dan_gw_msg_esc_fast_rsp_decode(&flags, &rec, &has, p, len), DAN_OK);
    vec_cat(txt, cap, "flags=%u", flags);
    if (has) {
        vec_cat(txt, cap, " rec=%u/%u/%u/%04x/%04x/%04x/%ld", rec.esc_index, rec.fresh, rec.age_4ms,
                rec.voltage_f16, rec.current_f16, rec.temperature_f16, (long)rec.rpm);
    }
    return dan_gw_msg_esc_fast_rsp_encode(flags, has ? &rec : NULL, enc, ecap);
}

/* SAFETY, SERVO, SERVO_FAILSAFE, LIGHTS, BEEP. */
static int vec_out(const char *msg, const char *dir, const uint8_t *p, size_t len, char *txt,
                   size_t cap, uint8_t *enc, size_t ecap)
{
    size_t i, n;
    if (!strncmp(msg, "esc_fast", 8)) {
        return vec_fast(msg, dir, p, len, txt, cap, enc, ecap);
    }
    if (!strcmp(dir, "rsp") || !strcmp(msg, "safety")) {
        const char *key = !strcmp(msg, "servo_fs") ? "kept" : "flags";
        assert_int_equal(len, 1);
        vec_cat(txt, cap, "%s=%u", !strcmp(dir, "req") ? "status" : key, p[0]);
        enc[0] = p[0];
        return 1;
    }
    if (!strcmp(msg, "servo")) {
        dan_gw_servo_t s[DAN_GW_SERVO_MAX];
        assert_int_equal(dan_gw_msg_servo_decode(s, &n, p, len), DAN_OK);
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, "%scmd=%u/%u/%04x", i ? " " : "", s[i].actuator_id, s[i].command_type,
                    s[i].value_f16);
        }
        return dan_gw_msg_servo_encode(s, n, enc, ecap);
    }
    if (!strcmp(msg, "servo_fs")) {
        dan_gw_servo_fs_t f[DAN_GW_SERVO_MAX];
        assert_int_equal(dan_gw_msg_servo_fs_decode(f, &n, p, len), DAN_OK);
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, "%sfs=%u/%u/%u/%04x", i ? " " : "", f[i].value.actuator_id, f[i].mode,
                    f[i].value.command_type, f[i].value.value_f16);
        }
        return dan_gw_msg_servo_fs_encode(f, n, enc, ecap);
    }
    if (!strcmp(msg, "lights")) {
        dan_gw_light_t l[DAN_GW_LIGHTS_MAX];
        assert_int_equal(dan_gw_msg_lights_decode(l, &n, p, len), DAN_OK);
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, "%slight=%u/%04x", i ? " " : "", l[i].light_id, l[i].rgb565);
        }
        return dan_gw_msg_lights_encode(l, n, enc, ecap);
    }
    if (!strcmp(msg, "beep")) {
        dan_gw_beep_t b;
        assert_int_equal(dan_gw_msg_beep_decode(&b, p, len), DAN_OK);
        vec_cat(txt, cap, "hz=%lu ms=%lu", (unsigned long)b.frequency_hz,
                (unsigned long)b.duration_ms);
        return dan_gw_msg_beep_encode(&b, enc, ecap);
    }
    fail_msg("unknown message %s", msg);
    return -1;
}

/* A one-byte payload (a first index to ask, a status or flags): its text
 * from fmt, and the byte again. */
static int vec_byte(char *txt, size_t cap, const char *fmt, uint8_t b, uint8_t *enc, size_t ecap)
{
    dan_writer_t w;
    vec_cat(txt, cap, fmt, b);
    dan_writer_init(&w, enc, ecap);
    dan_put_u8(&w, b);
    return dan_writer_finish(&w);
}

static int vec_mgmt(const char *msg, const char *dir, const uint8_t *p, size_t len, char *txt,
                    size_t cap, uint8_t *enc, size_t ecap)
{
    dan_reader_t r;
    dan_writer_t w;
    size_t i;
    dan_reader_init(&r, p, len);
    dan_writer_init(&w, enc, ecap);
    if (!strcmp(msg, "node_call")) {
        return vec_call(dir, p, len, txt, cap, enc, ecap);
    }
    if (!strcmp(msg, "call_result") || !strcmp(msg, "param") || !strcmp(msg, "opcode")) {
        return vec_result(msg, dir, p, len, txt, cap, enc, ecap);
    }
    if (!strcmp(msg, "health")) {
        dan_gw_health_t h;
        if (!strcmp(dir, "req")) {
            assert_int_equal(len, 0);
            return 0;
        }
        assert_int_equal(dan_gw_msg_health_decode(&h, p, len), DAN_OK);
        vec_cat(txt, cap, "verdict=%u reason=%u subject=%u detail=%u problems=%u", h.verdict,
                h.reason, h.subject, h.detail, h.problems);
        return dan_gw_msg_health_encode(&h, enc, ecap);
    }
    if (!strcmp(msg, "dna")) {
        if (!strcmp(dir, "req")) {
            return vec_byte(txt, cap, "first=%u", p[0], enc, ecap);
        }
        VEC_PAGE(dan_gw_dna_hdr_t, dan_gw_dna_entry_t, dna, dna_entry,
                 vec_cat(txt, cap, "flags=%u entries=%u capacity=%u next=%u", h.flags, h.entries,
                         h.capacity, h.next),
                 {
                     vec_cat(txt, cap, " entry=%u/", e.node_id);
                     vec_cat_hex(txt, cap, e.unique_id, sizeof e.unique_id);
                 });
        return dan_writer_finish(&w);
    }
    return vec_out(msg, dir, p, len, txt, cap, enc, ecap);
}

/* The field text of the vector being checked (can_recv's response layout
 * depends on its request's opts, which the text carries). */
static const char *fields_hint = "";

/* Decodes payload p as msg/dir, writes the canonical field text into txt
 * and the re-encoded payload into enc; returns the encoded length. */
static int vec_one(const char *msg, const char *dir, const uint8_t *p, size_t len, char *txt,
                   size_t cap, uint8_t *enc, size_t ecap)
{
    dan_reader_t r;
    dan_writer_t w;
    size_t i;
    txt[0] = '\0';
    dan_reader_init(&r, p, len);
    dan_writer_init(&w, enc, ecap);
    if (!strcmp(msg, "esc_cmd")) {
        int16_t v[DAN_GW_ESC_MAX];
        size_t n;
        assert_int_equal(dan_gw_msg_esc_cmd_decode(p, len, v, &n), DAN_OK);
        vec_cat(txt, cap, "values=");
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, i ? ",%d" : "%d", v[i]);
        }
        return dan_gw_msg_esc_cmd_encode(v, n, enc, ecap);
    }
    if (!strcmp(msg, "telem")) {
        VEC_PAGE(dan_gw_telem_hdr_t, dan_gw_telem_t, telem, telem,
                 vec_cat(txt, cap, "flags=%u aux=%u", h.gw_flags, h.aux),
                 vec_cat(txt, cap,
                         " rec=%u/%u/%u/%lu/%u/%u/%u/%ld/%u/%lu/%lu/%u/%u/%d/%u/%lu/%lu/%u/%u",
                         e.esc_index, e.node_id, e.flags, (unsigned long)e.age_ms, e.voltage_f16,
                         e.current_f16, e.temperature_f16, (long)e.rpm, e.power_pct,
                         (unsigned long)e.error_count, (unsigned long)e.ext_age_ms, e.input_pct,
                         e.output_pct, e.motor_temp_c, e.motor_angle, (unsigned long)e.status_flags,
                         (unsigned long)e.dev_age_ms, e.dev_temp_f16, e.dev_flags));
        return dan_writer_finish(&w);
    }
    if (!strcmp(msg, "esc_telem") || (!strcmp(msg, "nodes") && !strcmp(dir, "req"))) {
        assert_true(len >= 1u);
        return vec_byte(txt, cap, "first=%u", p[0], enc, ecap);
    }
    if (!strcmp(msg, "arm")) {
        assert_true(len >= 1u);
        return vec_byte(txt, cap, !strcmp(dir, "req") ? "status=%u" : "flags=%u", p[0], enc, ecap);
    }
    if (!strcmp(msg, "config")) {
        dan_gw_config_t c;
        if (!strcmp(dir, "req")) {
            assert_int_equal(dan_gw_msg_config_req_decode(&c, p, len), DAN_OK);
            vec_cat(txt, cap, "mask=%u timeout=%lu rate=%lu telem=%lu dna=%u", c.set_mask,
                    (unsigned long)c.esc_timeout_ms, (unsigned long)c.arming_rate_hz,
                    (unsigned long)c.telem_timeout_ms, c.dna);
            return dan_gw_msg_config_req_encode(&c, enc, ecap);
        }
        assert_int_equal(dan_gw_msg_config_rsp_decode(&c, p, len), DAN_OK);
        vec_cat(txt, cap, "node=%u timeout=%lu rate=%lu flags=%u telem=%lu dna=%u", c.node_id,
                (unsigned long)c.esc_timeout_ms, (unsigned long)c.arming_rate_hz, c.gw_flags,
                (unsigned long)c.telem_timeout_ms, c.dna);
        return dan_gw_msg_config_rsp_encode(&c, enc, ecap);
    }
    if (!strcmp(msg, "stats")) {
        uint32_t v[64];
        size_t n;
        assert_int_equal(dan_gw_msg_stats_decode(v, 64, &n, p, len), DAN_OK);
        vec_cat(txt, cap, "values=");
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, i ? ",%lu" : "%lu", (unsigned long)v[i]);
        }
        return dan_gw_msg_stats_encode(v, n, enc, ecap);
    }
    if (!strcmp(msg, "nodes")) {
        VEC_PAGE(dan_gw_nodes_hdr_t, dan_gw_node_entry_t, nodes, node,
                 vec_cat(txt, cap, "next=%u", h.next),
                 vec_cat(txt, cap, " node=%u/%u/%u/%u/%lu/%u/%lu/%u", e.node_id, e.health, e.mode,
                         e.sub_mode, (unsigned long)e.uptime_sec, e.vendor_status,
                         (unsigned long)e.age_ms, e.info_state));
        return dan_writer_finish(&w);
    }
    if (!strcmp(msg, "node_info")) {
        dan_gw_node_info_t ni;
        if (!strcmp(dir, "req")) {
            return vec_byte(txt, cap, "node=%u", p[0], enc, ecap);
        }
        assert_int_equal(dan_gw_msg_node_info_decode(&ni, p, len), DAN_OK);
        vec_cat_node_info(txt, cap, &ni);
        return dan_gw_msg_node_info_encode(&ni, enc, ecap);
    }
    if (!strcmp(msg, "tun_open")) {
        dan_gw_tun_open_t o;
        if (!strcmp(dir, "rsp")) {
            vec_cat(txt, cap, "port=%u result=%u", p[0], p[1]);
            dan_put_raw(&w, p, 2);
            return dan_writer_finish(&w);
        }
        assert_int_equal(dan_gw_msg_tun_open_decode(&o, p, len), DAN_OK);
        vec_cat(txt, cap, "port=%u mode=%u protocol=%u target=%u serial=%d options=%u baud=%lu",
                o.port, o.mode, o.protocol, o.target, o.serial_id, o.options,
                (unsigned long)o.baud);
        return dan_gw_msg_tun_open_encode(&o, enc, ecap);
    }
    if (!strcmp(msg, "tun_xfer")) {
        dan_gw_tun_xfer_t x;
        if (!strcmp(dir, "req")) {
            assert_int_equal(dan_gw_msg_tun_xfer_req_decode(&x, p, len), DAN_OK);
            vec_cat(txt, cap, "port=%u wr=%lu rd=%lu max=%lu data=", x.port,
                    (unsigned long)x.wr_offset, (unsigned long)x.rd_offset,
                    (unsigned long)x.rd_max);
            vec_cat_hex(txt, cap, x.data, x.len);
            return dan_gw_msg_tun_xfer_req_encode(&x, enc, ecap);
        }
        assert_int_equal(dan_gw_msg_tun_xfer_rsp_decode(&x, p, len), DAN_OK);
        vec_cat(txt, cap, "port=%u wr=%lu space=%lu rd=%lu dropped=%lu data=", x.port,
                (unsigned long)x.wr_offset, (unsigned long)x.wr_space, (unsigned long)x.rd_offset,
                (unsigned long)x.rd_dropped);
        vec_cat_hex(txt, cap, x.data, x.len);
        return dan_gw_msg_tun_xfer_rsp_encode(&x, enc, ecap);
    }
    if (!strcmp(msg, "can_send")) {
        dan_gw_can_send_t s;
        dan_can_frame_t f;
        if (!strcmp(dir, "rsp")) {
            assert_int_equal(dan_gw_msg_can_send_rsp_decode(&s, p, len), DAN_OK);
            vec_cat(txt, cap, "seq=%u accepted=%u free=%lu", s.seq, s.count,
                    (unsigned long)s.queue_free);
            return dan_gw_msg_can_send_rsp_encode(&s, enc, ecap);
        }
        assert_int_equal(dan_gw_msg_can_send_req_get(&r, &s), DAN_OK);
        dan_gw_msg_can_send_req_put(&w, &s);
        vec_cat(txt, cap, "seq=%u", s.seq);
        for (i = 0; i < s.count; i++) {
            assert_int_equal(dan_gw_msg_can_frame_get(&r, &f), DAN_OK);
            dan_gw_msg_can_frame_put(&w, &f);
            cat_frame(txt, cap, &f);
        }
        return dan_writer_finish(&w);
    }
    if (!strcmp(msg, "can_recv")) {
        dan_gw_can_recv_t q;
        dan_can_frame_t f;
        if (!strcmp(dir, "req")) {
            assert_int_equal(dan_gw_msg_can_recv_req_decode(&q, p, len), DAN_OK);
            vec_cat(txt, cap, "seq=%lu max=%u opts=%u", (unsigned long)q.seq, q.count, q.opts);
            return dan_gw_msg_can_recv_req_encode(&q, enc, ecap);
        }
        /* the response's layout follows the request's opts: the text has them */
        q.opts = (uint8_t)(strstr(fields_hint, "opts=1") != NULL ? DAN_GW_RECV_TIMES : 0u);
        assert_int_equal(dan_gw_msg_can_recv_rsp_get(&r, &q), DAN_OK);
        dan_gw_msg_can_recv_rsp_put(&w, &q);
        vec_cat(txt, cap, "seq=%lu dropped=%lu opts=%u t0=%lu", (unsigned long)q.seq,
                (unsigned long)q.dropped, q.opts, (unsigned long)q.t0_us);
        for (i = 0; i < q.count; i++) {
            assert_int_equal(dan_gw_msg_can_frame_get(&r, &f), DAN_OK);
            dan_gw_msg_can_frame_put(&w, &f);
            cat_frame(txt, cap, &f);
            if (q.opts & DAN_GW_RECV_TIMES) {
                uint32_t dt = dan_get_uvarint(&r);
                dan_put_uvarint(&w, dt);
                vec_cat(txt, cap, " dt=%lu", (unsigned long)dt);
            }
        }
        return dan_writer_finish(&w);
    }
    if (!strcmp(msg, "can_filter")) {
        uint8_t op, n;
        dan_gw_filter_t f;
        assert_int_equal(dan_gw_msg_filter_hdr_get(&r, &op, &n), DAN_OK);
        dan_gw_msg_filter_hdr_put(&w, op, n);
        vec_cat(txt, cap, !strcmp(dir, "req") ? "op=%u" : "result=%u", op);
        for (i = 0; i < n; i++) {
            assert_int_equal(dan_gw_msg_filter_get(&r, &f), DAN_OK);
            dan_gw_msg_filter_put(&w, &f);
            vec_cat(txt, cap, " filter=%08X/%08X", (unsigned)f.id, (unsigned)f.mask);
        }
        return dan_writer_finish(&w);
    }
    return vec_mgmt(msg, dir, p, len, txt, cap, enc, ecap);
}

static void message_row(vec_file_t *v, void *ctx)
{
    char *fields[3];
    uint8_t p[DAN_MAX_PAYLOAD];
    size_t len = vec_message(v, fields, p, sizeof p);
    (void)ctx;
    fields_hint = fields[2];
    vec_check_message(v, fields, p, len, vec_one);
}

static void test_vectors(void **state)
{
    (void)state;
    assert_true(vec_each("gateway.txt", message_row, NULL) >= 40);
}

static void test_codec_limits(void **state)
{
    int16_t v[DAN_GW_ESC_MAX] = {0};
    uint8_t buf[64];
    size_t n;
    (void)state;
    /* 4 channels: 8-byte payload, 12-byte frame */
    assert_int_equal(dan_gw_msg_esc_cmd_encode(v, 4, buf, sizeof buf), 8);
    assert_int_equal(dan_frame_size(DAN_GW_CODE_ESC_CMD, 8), 12);
    v[0] = 8192;
    assert_int_equal(dan_gw_msg_esc_cmd_encode(v, 1, buf, sizeof buf), DAN_ERR_ARG);
    assert_int_equal(dan_gw_msg_esc_cmd_encode(v, 0, buf, sizeof buf), DAN_ERR_ARG);
    assert_int_equal(dan_gw_msg_esc_cmd_encode(v, 21, buf, sizeof buf), DAN_ERR_ARG);
    buf[0] = 4;
    assert_int_equal(dan_gw_msg_esc_cmd_decode(buf, 7, v, &n), DAN_ERR_MALFORMED);
    buf[0] = 0;
    assert_int_equal(dan_gw_msg_esc_cmd_decode(buf, 8, v, &n), DAN_ERR_MALFORMED);
    buf[0] = 21;
    assert_int_equal(dan_gw_msg_esc_cmd_decode(buf, 64, v, &n), DAN_ERR_MALFORMED);
    assert_true(dan_f16_to_f32(0x4A40) == 12.5f);
    assert_true(dan_f16_to_f32(0xBD00) == -1.25f);
    assert_true(dan_f16_to_f32(0x0001) == 5.9604644775390625e-8f);
    assert_true(dan_f16_to_f32(0x7BFF) == 65504.0f);
}

/* One gateway_sealed.txt line: the seal and the frame as the vector says,
 * bound to code and direction, every bit flip caught. */
static void sealed_row(vec_file_t *v, void *ctx)
{
    char *f[6];
    uint8_t inner[DAN_MAX_PAYLOAD], sealed[DAN_MAX_PAYLOAD], want[DAN_MAX_PAYLOAD],
        frame[DAN_MAX_FRAME], out[DAN_MAX_FRAME];
    size_t il, sl, fl, i, bit;
    uint32_t code;
    uint8_t dir;
    (void)ctx;
    assert_int_equal(vec_split(v->line, ' ', f, 6), 6);
    assert_string_equal(f[0], "sealed");
    code = (uint32_t)strtoul(f[1], NULL, 10);
    dir = (strcmp(f[2], "rsp") == 0) ? DAN_GW_RESPONSE : DAN_GW_REQUEST;
    il = vec_hex(f[3], inner, sizeof inner);
    sl = vec_hex(f[4], want, sizeof want);
    fl = vec_hex(f[5], frame, sizeof frame);
    assert_true(dan_gw_sealed_code(code));
    memcpy(sealed, inner, il);
    assert_int_equal(dan_gw_seal(code, dir, sealed, il, sizeof sealed), (int)sl);
    assert_memory_equal(sealed, want, sl);
    assert_int_equal(dan_gw_unseal(code, dir, want, sl), (int)il);
    assert_int_equal(dan_frame_encode(code, sealed, sl, out, sizeof out), (int)fl);
    assert_memory_equal(out, frame, fl);
    /* bound to its code and its direction: a reply never passes for a request */
    assert_int_equal(dan_gw_unseal(code + 1u, dir, want, sl), DAN_ERR_MALFORMED);
    assert_int_equal(dan_gw_unseal(code, (uint8_t)(dir ^ 1u), want, sl), DAN_ERR_MALFORMED);
    for (i = 0; i < sl; i++) {
        for (bit = 0; bit < 8; bit++) {
            want[i] ^= (uint8_t)(1u << bit);
            assert_int_equal(dan_gw_unseal(code, dir, want, sl), DAN_ERR_MALFORMED);
            want[i] ^= (uint8_t)(1u << bit);
        }
    }
}

/* The seal against its vectors; every single-bit flip of a sealed payload
 * is caught by the seal alone (CRC-16 detects all of them). */
static void test_sealed_vectors(void **state)
{
    (void)state;
    assert_true(vec_each("gateway_sealed.txt", sealed_row, NULL) >= 8);
    assert_int_equal(dan_gw_seal(0x42, DAN_GW_REQUEST, (uint8_t *)"", 0, 1), DAN_ERR_OVERFLOW);
    assert_int_equal(dan_gw_unseal(0x42, DAN_GW_REQUEST, (const uint8_t *)"x", 1),
                     DAN_ERR_MALFORMED);
    assert_false(dan_gw_sealed_code(DAN_CODE_CAN_GW_IDENTIFY));
    assert_false(dan_gw_sealed_code(DAN_CODE_CAN_GW_CONFIGURE));
}

int main(void)
{
    return UNIT_RUN("gateway_vectors", NULL, NULL, test_vectors, test_codec_limits,
                    test_sealed_vectors);
}
