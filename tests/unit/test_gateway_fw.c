/* CAN-over-DAN gateway, starting and following a firmware update through
 * the client and the node: FW_BEGIN sends BeginFirmwareUpdate (source =
 * the gateway, path = the committed file) once even when the master
 * retries, refuses a name that is no committed file with an error frame
 * (nothing sent), carries the node's answer to CALL_RESULT; NODE_INFO's
 * follow fields show the mode, the BEGUN / READING flags, bytes_read,
 * file_size and the time since the last read; STATS counts it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "file_rig.h"
#include "vectors.h"
#include "unit_run.h"

#define NODE LISTEN_NODE /* the rig's listener reassembles what is sent to it */

/* BeginFirmwareUpdate answered by NODE (the captured request's transfer ID). */
static void answer(const cap_t *c, uint8_t error, const char *msg)
{
    dan_dc_fw_begin_rsp_t m;
    uint8_t buf[1u + DAN_DC_FW_BEGIN_MESSAGE_MAX];
    memset(&m, 0, sizeof m);
    m.error = error;
    m.message_len = (uint8_t)strlen(msg);
    memcpy(m.message, msg, m.message_len);
    answer_cap(c, DAN_DC_FW_BEGIN_ID, DAN_DC_FW_BEGIN_SIGNATURE, 16, buf,
               dan_dc_fw_begin_rsp_encode(&m, buf, sizeof buf));
}

/* FW_BEGIN through the client, completed: the call state. */
static uint8_t fw_begin(uint16_t id, const char *name)
{
    call_ok(dan_gw_fw_begin(&R->gw, id, NODE, name, R->bus.now));
    return R->gw.call.state;
}

static void fw_result(uint16_t id, dan_gw_fw_result_t *r)
{
    dan_gw_result_t res;
    call_ok(dan_gw_call_result(&R->gw, id, 0, 128, R->bus.now));
    assert_int_equal(dan_gw_call_result_get(&R->gw, &res), DAN_OK);
    assert_int_equal(res.state, DAN_GW_CALL_DONE);
    assert_int_equal(res.len, res.result_len);
    assert_int_equal(dan_gw_msg_fw_result_decode(r, res.data, res.len), DAN_OK);
}

static void node_info(dan_gw_node_info_t *i)
{
    call_ok(dan_gw_node_info(&R->gw, NODE, R->bus.now));
    assert_int_equal(dan_gw_node_info_get(&R->gw, i), DAN_OK);
    assert_true(i->follow);
}

/* fw.bin committed, NODE operational, FW_BEGIN id started: the
 * BeginFirmwareUpdate request seen on CAN. */
static cap_t *begin_sent(uint16_t id, size_t *from)
{
    cap_t *c;
    upload("fw.bin", IMG_SIZE);
    node_status_from(NODE, 10, DAN_DC_HEALTH_OK, DAN_DC_MODE_OPERATIONAL);
    assert_int_equal(fw_begin(id, "fw.bin"), DAN_GW_CALL_PENDING);
    c = expect_cap(DAN_DC_FW_BEGIN_ID, DAN_DC_TRANSFER_REQUEST, from);
    return c;
}

static void test_fw_begin_and_follow(void **state)
{
    dan_dc_fw_begin_req_t q;
    dan_gw_fw_result_t r;
    dan_gw_node_info_t i;
    size_t from = R->ncap;
    cap_t *c;
    (void)state;
    c = begin_sent(1, &from);
    assert_int_equal(c->dst, NODE);
    assert_int_equal(dan_dc_fw_begin_req_decode(&q, c->payload, c->len), DAN_OK);
    assert_int_equal(q.source_node_id, R->g.cfg.node_id);
    assert_int_equal(q.path_len, 6);
    assert_memory_equal(q.path, "fw.bin", 6);
    /* the master retries the same call: never sent twice */
    assert_int_equal(fw_begin(1, "fw.bin"), DAN_GW_CALL_PENDING);
    assert_null(find_cap(DAN_DC_FW_BEGIN_ID, DAN_DC_TRANSFER_REQUEST, &from));
    answer(c, DAN_DC_FW_BEGIN_OK, "");
    fw_result(1, &r);
    assert_int_equal(r.error, DAN_GW_FW_OK);
    assert_int_equal(r.message_len, 0);
    assert_int_equal(R->g.stats.fw_begins, 1);
    advance(20000);
    node_info(&i);
    assert_int_equal(i.file_flags, DAN_GW_FW_BEGUN);
    assert_int_equal(i.bytes_read, 0);
    assert_int_equal(i.file_size, IMG_SIZE);
    assert_true(i.since_read_ms >= 20u && i.since_read_ms < 1000u);
    /* the node goes into its bootloader and reads */
    node_status_from(NODE, 11, DAN_DC_HEALTH_OK, DAN_DC_MODE_SOFTWARE_UPDATE);
    file_read_from(NODE, 0, "fw.bin");
    drain();
    file_read_from(NODE, 256, "/fw.bin");
    drain();
    node_info(&i);
    assert_int_equal(i.status, DAN_DC_MODE_SOFTWARE_UPDATE << 2);
    assert_int_equal(i.file_flags, DAN_GW_FW_BEGUN | DAN_GW_FW_READING);
    assert_int_equal(i.bytes_read, 512);
    assert_int_equal(i.file_size, IMG_SIZE);
    assert_true(i.since_read_ms < 20u);
    assert_int_equal(R->gw.stats[DAN_GW_STAT_FW_BEGINS], 0); /* not read yet */
    call_ok(dan_gw_stats(&R->gw, R->bus.now));
    assert_int_equal(R->gw.stats[DAN_GW_STAT_FW_BEGINS], 1);
    assert_int_equal(R->gw.stats[DAN_GW_STAT_FILE_COMMITS], 1);
    assert_int_equal(R->gw.stats[DAN_GW_STAT_UPLOAD_BYTES], IMG_SIZE);
}

/* A refusal is passed on with its message; the progress is not reset. */
static void test_fw_begin_refused(void **state)
{
    dan_gw_fw_result_t r;
    dan_gw_node_info_t i;
    size_t from = R->ncap;
    (void)state;
    answer(begin_sent(2, &from), DAN_GW_FW_INVALID_MODE, "armed");
    fw_result(2, &r);
    assert_int_equal(r.error, DAN_GW_FW_INVALID_MODE);
    assert_int_equal(r.message_len, 5);
    assert_memory_equal(r.message, "armed", 5);
    node_info(&i);
    assert_int_equal(i.status, DAN_DC_MODE_OPERATIONAL << 2);
    assert_int_equal(i.file_flags, 0);
    assert_int_equal(i.file_size, 0);
    assert_int_equal(i.since_read_ms, DAN_GW_NEVER_MS);
    assert_int_equal(R->g.stats.fw_begins, 0);
}

/* Not a committed file (missing, only partly uploaded, bad name, no
 * store): an error frame, nothing sent, no call slot taken. */
static void test_fw_begin_not_a_file(void **state)
{
    static const char *const bad[] = {"missing.bin", "part.bin", "../fw.bin", ".fw"};
    size_t from = R->ncap, k;
    (void)state;
    assert_int_equal(open_file("part.bin", IMG_SIZE, false, NULL), DAN_GW_FILE_OK);
    upload_range(0, 300);
    for (k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        assert_int_equal(dan_gw_fw_begin(&R->gw, 3, NODE, bad[k], R->bus.now), DAN_OK);
        assert_int_equal(finish(), DAN_ERR_REMOTE);
    }
    gateway_start(false);
    assert_int_equal(dan_gw_fw_begin(&R->gw, 3, NODE, "fw.bin", R->bus.now), DAN_OK);
    assert_int_equal(finish(), DAN_ERR_REMOTE);
    assert_null(find_cap(DAN_DC_FW_BEGIN_ID, DAN_DC_TRANSFER_REQUEST, &from));
    assert_int_equal(dan_gw_call_result(&R->gw, 3, 0, 128, R->bus.now), DAN_OK);
    assert_int_equal(finish(), DAN_ERR_REMOTE); /* no such call */
    assert_int_equal(R->g.stats.calls, 0);
}

/* No answer: the call times out after its attempts, like any other. */
static void test_fw_begin_timeout(void **state)
{
    size_t from = R->ncap, sent = 0;
    (void)state;
    upload("fw.bin", IMG_SIZE);
    assert_int_equal(fw_begin(4, "fw.bin"), DAN_GW_CALL_PENDING);
    advance(3500000);
    while (find_cap(DAN_DC_FW_BEGIN_ID, DAN_DC_TRANSFER_REQUEST, &from) != NULL) {
        sent++;
    }
    assert_int_equal(sent, DAN_GW_NODE_CALL_ATTEMPTS);
    assert_int_equal(fw_begin(4, "fw.bin"), DAN_GW_CALL_TIMEOUT);
}

/* The file server's answer to NODE's last read since *from. */
static int16_t read_error(size_t *from, size_t *len)
{
    static dan_dc_file_read_rsp_t r;
    cap_t *c = find_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, from);
    assert_non_null(c);
    assert_int_equal(dan_dc_file_read_rsp_decode(&r, c->payload, c->len), DAN_OK);
    *len = r.data_len;
    return r.error;
}

/* An upload whose CRC does not check is never served: NOT_FOUND to a
 * node, and FW_BEGIN refuses it; committed, it is. */
static void test_crc_refused_not_served(void **state)
{
    uint32_t crc = dan_gw_crc32(0, img, IMG_SIZE);
    size_t from = R->ncap, len;
    (void)state;
    node_status_from(NODE, 10, DAN_DC_HEALTH_OK, DAN_DC_MODE_OPERATIONAL);
    assert_int_equal(open_file("fw.bin", IMG_SIZE, false, NULL), DAN_GW_FILE_OK);
    upload_range(0, IMG_SIZE);
    assert_int_equal(commit(crc ^ 0x80u, NULL), DAN_GW_FILE_CRC);
    file_read_from(NODE, 0, "fw.bin");
    drain();
    assert_int_equal(read_error(&from, &len), DAN_DC_FILE_NOT_FOUND);
    assert_int_equal(len, 0);
    assert_int_equal(dan_gw_fw_begin(&R->gw, 9, NODE, "fw.bin", R->bus.now), DAN_OK);
    assert_int_equal(finish(), DAN_ERR_REMOTE);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_OK);
    file_read_from(NODE, 0, "fw.bin");
    drain();
    assert_int_equal(read_error(&from, &len), DAN_DC_FILE_OK);
    assert_int_equal(len, 256);
}

/* NODE reads fw.bin at offset off; the answer's data length. */
static size_t read_at(uint64_t off)
{
    size_t from = R->ncap, len;
    file_read_from(NODE, off, "fw.bin");
    drain();
    assert_int_equal(read_error(&from, &len), DAN_DC_FILE_OK);
    return len;
}

/* A new image committed over the one a node is reading would give that
 * node the first part of one and the rest of the other: the commit answers
 * IN_USE (the upload stays, nothing replaced) until the reader has read to
 * the end, or has read nothing for DAN_GW_NODE_READER_US (it failed). A
 * reader of another file does not hold it. */
static void test_commit_waits_for_reader(void **state)
{
    uint32_t crc = dan_gw_crc32(0, img, IMG_SIZE);
    uint32_t off;
    (void)state;
    node_status_from(NODE, 10, DAN_DC_HEALTH_OK, DAN_DC_MODE_SOFTWARE_UPDATE);
    upload("fw.bin", IMG_SIZE);
    upload("other.bin", IMG_SIZE);
    assert_int_equal(read_at(0), 256);
    assert_int_equal(open_file("fw.bin", IMG_SIZE, true, NULL), DAN_GW_FILE_OK);
    upload_range(0, IMG_SIZE);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_IN_USE);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_IN_USE); /* still held */
    for (off = 256; off < IMG_SIZE; off += 256) {
        assert_int_equal(read_at(off), off + 256u <= IMG_SIZE ? 256u : IMG_SIZE - off);
    }
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_OK); /* read to the end */
    /* a reader that stops halfway holds it for DAN_GW_NODE_READER_US */
    assert_int_equal(read_at(0), 256);
    assert_int_equal(open_file("fw.bin", IMG_SIZE, true, NULL), DAN_GW_FILE_OK);
    upload_range(0, IMG_SIZE);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_IN_USE);
    assert_int_equal(R->g.stats.file_commits, 3);
    advance(DAN_GW_NODE_READER_US / 2u);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_IN_USE);
    advance(DAN_GW_NODE_READER_US / 2u + 1000u);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_OK);
    /* reading fw.bin does not hold other.bin */
    assert_int_equal(read_at(0), 256);
    assert_int_equal(open_file("other.bin", IMG_SIZE, true, NULL), DAN_GW_FILE_OK);
    upload_range(0, IMG_SIZE);
    assert_int_equal(commit(crc, NULL), DAN_GW_FILE_OK);
}

/* The DSDL codec against pydronecan's bytes (tests/vectors/dronecan_fw.txt):
 * decoded to the fields, encoded back byte for byte. */
static void fw_dsdl_row(vec_file_t *v, void *ctx)
{
    char *f[3];
    uint8_t p[256], want[256], enc[256];
    size_t len = vec_message(v, f, p, sizeof p),
           wl = vec_hex(strchr(f[2], '=') + 1, want, sizeof want);
    unsigned long num = strtoul(strchr(f[1], '=') + 1, NULL, 10);
    (void)ctx;
    if (!strcmp(f[0], "fw_begin_req")) {
        dan_dc_fw_begin_req_t q;
        assert_int_equal(dan_dc_fw_begin_req_decode(&q, p, len), DAN_OK);
        assert_int_equal(q.source_node_id, num);
        assert_int_equal(q.path_len, wl);
        assert_memory_equal(q.path, want, wl);
        assert_int_equal(dan_dc_fw_begin_req_encode(&q, enc, sizeof enc), (int)len);
    } else {
        dan_dc_fw_begin_rsp_t r;
        assert_string_equal(f[0], "fw_begin_rsp");
        assert_int_equal(dan_dc_fw_begin_rsp_decode(&r, p, len), DAN_OK);
        assert_int_equal(r.error, num);
        assert_int_equal(r.message_len, wl);
        assert_memory_equal(r.message, want, wl);
        assert_int_equal(dan_dc_fw_begin_rsp_encode(&r, enc, sizeof enc), (int)len);
    }
    assert_memory_equal(enc, p, len);
}

static void test_fw_dsdl_vectors(void **state)
{
    (void)state;
    assert_int_equal(vec_each("dronecan_fw.txt", fw_dsdl_row, NULL), 8);
}

int main(void)
{
    int failed = UNIT_RUN("gateway_fw", setup_files, teardown, test_fw_begin_and_follow,
                          test_fw_begin_refused, test_fw_begin_not_a_file, test_fw_begin_timeout,
                          test_crc_refused_not_served, test_commit_waits_for_reader);
    failed += UNIT_RUN("gateway_fw_codec", NULL, NULL, test_fw_dsdl_vectors);
    return failed;
}
