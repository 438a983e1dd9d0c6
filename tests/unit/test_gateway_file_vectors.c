/* The file and firmware-update messages against tests/vectors/
 * gateway_file.txt (gen_gateway_file.py: independent Python): every vector
 * decoded to its field text and re-encoded byte for byte, every "bad"
 * payload refused, and the CRC-32 against zlib's. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/can_gw/client.h"
#include "dan/can_gw/msgs_file.h"
#include "gw_vectors.h"
#include "vectors.h"
#include "unit_run.h"

/* FILE_OPEN / FILE_WRITE: the request and the (shared) response. */
static int vec_open_write(const char *msg, bool req, const uint8_t *p, size_t len, char *txt,
                          size_t cap, uint8_t *enc, size_t ecap)
{
    if (!req) {
        dan_gw_file_have_t h;
        assert_int_equal(dan_gw_msg_file_have_decode(&h, p, len), DAN_OK);
        vec_cat(txt, cap, "result=%u have=%lu", h.result, (unsigned long)h.have);
        return dan_gw_msg_file_have_encode(&h, enc, ecap);
    }
    if (!strcmp(msg, "file_open")) {
        dan_gw_file_open_t o;
        assert_int_equal(dan_gw_msg_file_open_decode(&o, p, len), DAN_OK);
        vec_cat(txt, cap, "name=");
        vec_cat_hex(txt, cap, (const uint8_t *)o.name, o.name_len);
        vec_cat(txt, cap, " size=%lu flags=%u", (unsigned long)o.size, o.flags);
        return dan_gw_msg_file_open_encode(&o, enc, ecap);
    } else {
        dan_gw_file_write_t w;
        assert_int_equal(dan_gw_msg_file_write_decode(&w, p, len), DAN_OK);
        vec_cat(txt, cap, "offset=%lu data=", (unsigned long)w.offset);
        vec_cat_hex(txt, cap, w.data, w.len);
        return dan_gw_msg_file_write_encode(&w, enc, ecap);
    }
}

static int vec_list(bool req, const uint8_t *p, size_t len, char *txt, size_t cap, uint8_t *enc,
                    size_t ecap)
{
    dan_reader_t r;
    dan_writer_t w;
    size_t i;
    if (req) {
        assert_int_equal(len, 1);
        vec_cat(txt, cap, "first=%u", p[0]);
        enc[0] = p[0];
        return 1;
    }
    dan_reader_init(&r, p, len);
    dan_writer_init(&w, enc, ecap);
    VEC_PAGE(dan_gw_file_list_hdr_t, dan_gw_file_entry_t, file_list, file_entry,
             vec_cat(txt, cap, "next=%u", h.next), {
                 assert_int_equal(strlen(e.name), e.name_len);
                 vec_cat(txt, cap, " entry=");
                 vec_cat_hex(txt, cap, (const uint8_t *)e.name, e.name_len);
                 vec_cat(txt, cap, "/%lu", (unsigned long)e.size);
             });
    return dan_writer_finish(&w);
}

/* NODE_INFO with its follow fields, NODE_CALL op 6, FW_BEGIN's result,
 * STATS. */
static int vec_fw(const char *msg, const uint8_t *p, size_t len, char *txt, size_t cap,
                  uint8_t *enc, size_t ecap)
{
    if (!strcmp(msg, "node_info")) {
        dan_gw_node_info_t ni;
        assert_int_equal(dan_gw_msg_node_info_decode(&ni, p, len), DAN_OK);
        assert_true(ni.follow);
        vec_cat_node_info(txt, cap, &ni);
        vec_cat(txt, cap, " status=%u fflags=%u read=%lu size=%lu since=%lu", ni.status,
                ni.file_flags, (unsigned long)ni.bytes_read, (unsigned long)ni.file_size,
                (unsigned long)ni.since_read_ms);
        return dan_gw_msg_node_info_encode(&ni, enc, ecap);
    }
    if (!strcmp(msg, "node_call")) {
        dan_gw_call_t c;
        assert_int_equal(dan_gw_msg_call_decode(&c, p, len), DAN_OK);
        assert_int_equal(c.op, DAN_GW_CALL_FW_BEGIN);
        vec_cat(txt, cap, "id=%u node=%u op=%u name=", c.call_id, c.node_id, c.op);
        vec_cat_hex(txt, cap, (const uint8_t *)c.name, c.name_len);
        return dan_gw_msg_call_encode(&c, enc, ecap);
    }
    if (!strcmp(msg, "fw_result")) {
        dan_gw_fw_result_t r;
        assert_int_equal(dan_gw_msg_fw_result_decode(&r, p, len), DAN_OK);
        vec_cat(txt, cap, "error=%u message=", r.error);
        vec_cat_hex(txt, cap, r.message, r.message_len);
        return dan_gw_msg_fw_result_encode(&r, enc, ecap);
    }
    if (!strcmp(msg, "stats")) {
        uint32_t v[64];
        size_t n, i;
        assert_int_equal(dan_gw_msg_stats_decode(v, 64, &n, p, len), DAN_OK);
        assert_int_equal(n, DAN_GW_STAT_COUNT); /* the file counters are the last ones */
        assert_string_equal(dan_gw_stat_name(DAN_GW_STAT_FW_BEGINS), "fw_begins");
        vec_cat(txt, cap, "values=");
        for (i = 0; i < n; i++) {
            vec_cat(txt, cap, i ? ",%lu" : "%lu", (unsigned long)v[i]);
        }
        return dan_gw_msg_stats_encode(v, n, enc, ecap);
    }
    fail_msg("unknown message %s", msg);
    return -1;
}

static int vec_one(const char *msg, const char *dir, const uint8_t *p, size_t len, char *txt,
                   size_t cap, uint8_t *enc, size_t ecap)
{
    bool req = !strcmp(dir, "req");
    txt[0] = '\0';
    if (!strcmp(msg, "file_open") || !strcmp(msg, "file_write")) {
        return vec_open_write(msg, req, p, len, txt, cap, enc, ecap);
    }
    if (!strcmp(msg, "file_commit")) {
        dan_gw_file_commit_t c;
        if (req) {
            assert_int_equal(dan_gw_msg_file_commit_req_decode(&c, p, len), DAN_OK);
            vec_cat(txt, cap, "crc=%lu", (unsigned long)c.crc32);
            return dan_gw_msg_file_commit_req_encode(&c, enc, ecap);
        }
        assert_int_equal(dan_gw_msg_file_commit_rsp_decode(&c, p, len), DAN_OK);
        vec_cat(txt, cap, "result=%u crc=%lu", c.result, (unsigned long)c.crc32);
        return dan_gw_msg_file_commit_rsp_encode(&c, enc, ecap);
    }
    if (!strcmp(msg, "file_list")) {
        return vec_list(req, p, len, txt, cap, enc, ecap);
    }
    if (!strcmp(msg, "file_remove")) {
        const char *name;
        uint8_t n;
        if (!req) {
            assert_int_equal(len, 1);
            vec_cat(txt, cap, "result=%u", p[0]);
            enc[0] = p[0];
            return 1;
        }
        assert_int_equal(dan_gw_msg_file_name_decode(&name, &n, p, len), DAN_OK);
        vec_cat(txt, cap, "name=");
        vec_cat_hex(txt, cap, (const uint8_t *)name, n);
        return dan_gw_msg_file_name_encode(name, n, enc, ecap);
    }
    return vec_fw(msg, p, len, txt, cap, enc, ecap);
}

/* A payload every decoder of msg must refuse. */
static void vec_bad(const char *msg, const uint8_t *p, size_t len)
{
    union {
        dan_gw_file_open_t o;
        dan_gw_file_write_t w;
        dan_gw_file_commit_t c;
        dan_gw_call_t call;
    } u;
    dan_gw_file_list_hdr_t h;
    dan_reader_t r;
    const char *name;
    uint8_t n;
    int rc;
    if (!strcmp(msg, "file_open")) {
        rc = dan_gw_msg_file_open_decode(&u.o, p, len);
    } else if (!strcmp(msg, "file_write")) {
        rc = dan_gw_msg_file_write_decode(&u.w, p, len);
    } else if (!strcmp(msg, "file_commit")) {
        rc = dan_gw_msg_file_commit_req_decode(&u.c, p, len);
    } else if (!strcmp(msg, "file_list")) {
        dan_reader_init(&r, p, len);
        assert_int_equal(dan_gw_msg_file_list_hdr_get(&r, &h), DAN_OK);
        rc = dan_gw_msg_file_entry_get(&r, (dan_gw_file_entry_t *)&u);
    } else if (!strcmp(msg, "file_remove")) {
        rc = dan_gw_msg_file_name_decode(&name, &n, p, len);
    } else {
        assert_string_equal(msg, "node_call");
        rc = dan_gw_msg_call_decode(&u.call, p, len);
    }
    assert_int_equal(rc, DAN_ERR_MALFORMED);
}

/* The counts of the kinds of gateway_file.txt lines. */
typedef struct {
    int bad, crcs;
} file_counts_t;

/* A crc32 line: "data=<hex> crc=<decimal>", whole and chained. */
static void crc32_row(char *text)
{
    uint8_t data[512];
    char *kv[2];
    size_t dl;
    assert_int_equal(vec_split(text, ' ', kv, 2), 2);
    dl = vec_hex(kv[0] + 5, data, sizeof data);
    assert_int_equal(dan_gw_crc32(0, data, dl), strtoul(kv[1] + 4, NULL, 10));
    /* chained over two pieces: the same */
    assert_int_equal(dan_gw_crc32(dan_gw_crc32(0, data, dl / 3u), data + dl / 3u, dl - dl / 3u),
                     strtoul(kv[1] + 4, NULL, 10));
}

static void file_row(vec_file_t *v, void *ctx)
{
    file_counts_t *c = ctx;
    char *f[3];
    uint8_t p[DAN_MAX_PAYLOAD];
    size_t len = vec_message(v, f, p, sizeof p);
    if (!strcmp(f[0], "crc32")) {
        crc32_row(f[2]);
        c->crcs++;
    } else if (!strcmp(f[1], "bad")) {
        vec_bad(f[0], p, len);
        c->bad++;
    } else {
        vec_check_message(v, f, p, len, vec_one);
    }
}

static void test_file_vectors(void **state)
{
    file_counts_t c = {0, 0};
    (void)state;
    assert_true(vec_each("gateway_file.txt", file_row, &c) - (size_t)(c.bad + c.crcs) >= 40u);
    assert_true(c.bad >= 12);
    assert_int_equal(c.crcs, 4);
}

/* Encoders refuse what decoders would: names of 0 or 33 bytes, an empty
 * write, a chunk over 150 bytes, unknown flags, a message over 127. */
static void test_file_codec_limits(void **state)
{
    uint8_t buf[DAN_MAX_PAYLOAD], data[DAN_GW_FILE_CHUNK_MAX + 1u];
    char name[DAN_GW_FILE_NAME_MAX + 2u];
    dan_gw_file_open_t o;
    dan_gw_file_write_t w;
    dan_gw_fw_result_t r;
    dan_gw_call_t c;
    (void)state;
    memset(name, 'a', sizeof name);
    memset(data, 1, sizeof data);
    memset(&o, 0, sizeof o);
    o.name = name;
    o.name_len = DAN_GW_FILE_NAME_MAX;
    assert_true(dan_gw_msg_file_open_encode(&o, buf, sizeof buf) > 0);
    o.name_len = DAN_GW_FILE_NAME_MAX + 1u;
    assert_int_equal(dan_gw_msg_file_open_encode(&o, buf, sizeof buf), DAN_ERR_ARG);
    o.name_len = 0;
    assert_int_equal(dan_gw_msg_file_open_encode(&o, buf, sizeof buf), DAN_ERR_ARG);
    o.name_len = 1;
    o.flags = 2;
    assert_int_equal(dan_gw_msg_file_open_encode(&o, buf, sizeof buf), DAN_ERR_ARG);
    w.offset = 0xFFFFFFFFu;
    w.data = data;
    w.len = DAN_GW_FILE_CHUNK_MAX;
    /* the largest write and its seal fit one DAN payload */
    assert_true(dan_gw_msg_file_write_encode(&w, buf, sizeof buf) + (int)DAN_GW_SEAL_SIZE <=
                (int)DAN_MAX_PAYLOAD);
    assert_true(dan_gw_msg_file_write_encode(&w, NULL, 0) <= (int)DAN_GW_FILE_WRITE_REQ_MAX);
    w.len = DAN_GW_FILE_CHUNK_MAX + 1u;
    assert_int_equal(dan_gw_msg_file_write_encode(&w, buf, sizeof buf), DAN_ERR_ARG);
    w.len = 0;
    assert_int_equal(dan_gw_msg_file_write_encode(&w, buf, sizeof buf), DAN_ERR_ARG);
    assert_int_equal(dan_gw_msg_file_name_encode(name, 0, buf, sizeof buf), DAN_ERR_ARG);
    assert_int_equal(dan_gw_msg_file_name_encode(name, 33, buf, sizeof buf), DAN_ERR_ARG);
    memset(&r, 0, sizeof r);
    r.message_len = DAN_GW_FW_MESSAGE_MAX + 1u;
    assert_int_equal(dan_gw_msg_fw_result_encode(&r, buf, sizeof buf), DAN_ERR_ARG);
    memset(&c, 0, sizeof c);
    c.node_id = 20;
    c.op = DAN_GW_CALL_FW_BEGIN;
    c.name = name;
    c.name_len = DAN_GW_FILE_NAME_MAX + 1u; /* a parameter name may be longer, a file's not */
    assert_int_equal(dan_gw_msg_call_encode(&c, buf, sizeof buf), DAN_ERR_ARG);
    /* a NODE_INFO without the follow fields (an older gateway) decodes */
    buf[0] = 20;
    buf[1] = DAN_GW_INFO_PENDING;
    {
        dan_gw_node_info_t ni;
        assert_int_equal(dan_gw_msg_node_info_decode(&ni, buf, 2), DAN_OK);
        assert_false(ni.follow);
        buf[2] = 12; /* follow fields cut short: malformed */
        assert_int_equal(dan_gw_msg_node_info_decode(&ni, buf, 3), DAN_ERR_MALFORMED);
    }
}

int main(void)
{
    return UNIT_RUN("gateway_file_vectors", NULL, NULL, test_file_vectors, test_file_codec_limits);
}
