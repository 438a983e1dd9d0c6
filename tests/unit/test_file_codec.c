/* The file store's name rule and the DroneCAN path rule (gw_file_name.c),
 * and the codecs of uavcan.protocol.file.GetInfo and Read (dsdl_file.c):
 * round trips, byte vectors worked out by hand from the DSDL
 * (dronecan/dsdl_specs/uavcan/protocol/file/45.GetInfo, 48.Read, Path,
 * Error, EntryType as shipped with pydronecan), refused lengths. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <string.h>

#include "dan/can_gw/dsdl_file.h"
#include "dan/can_gw/file_store.h"
#include "hostile_paths.h"
#include "unit_run.h"

static bool name_ok(const char *s)
{
    return dan_gw_file_name_ok(s, strlen(s));
}

static void test_names(void **state)
{
    static const char *const good[] = {
        "a",  "fw.bin", "AP_Periph-1.2.apj",
        "x.", "a..b",   "0",
        "_x", "-x",     "abcdefghijklmnopqrstuvwxyz012345", /* 32 */
    };
    static const char *const bad[] = {
        "",         ".",     "..",
        ".hidden",  "../x",  "/etc/passwd",
        "a/b",      "a/b/c", "a\\b",
        "a b",      "~x",    "x~",
        "\xc3\xa9", "a:b",   "abcdefghijklmnopqrstuvwxyz0123456", /* 33 */
    };
    size_t i;
    (void)state;
    for (i = 0; i < sizeof good / sizeof good[0]; i++) {
        assert_true(name_ok(good[i]));
    }
    for (i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_false(name_ok(bad[i]));
    }
    assert_false(dan_gw_file_name_ok("ab\0c", 4)); /* NUL inside */
    assert_true(dan_gw_file_name_ok("ab\0c", 2));  /* len counts, not the NUL */
    assert_false(dan_gw_file_name_ok(NULL, 1));
}

static bool path_ok(const char *s, char *name)
{
    return dan_gw_file_path_name((const uint8_t *)s, strlen(s), name);
}

static void test_paths(void **state)
{
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    size_t i;
    (void)state;
    assert_true(path_ok("fw.bin", name));
    assert_string_equal(name, "fw.bin");
    assert_true(path_ok("/fw.bin", name));
    assert_string_equal(name, "fw.bin");
    assert_true(path_ok("/abcdefghijklmnopqrstuvwxyz012345", name)); /* '/' + 32 */
    assert_string_equal(name, "abcdefghijklmnopqrstuvwxyz012345");
    strcpy(name, "kept");
    for (i = 0; i < HOSTILE_PATH_COUNT; i++) {
        assert_false(path_ok(HOSTILE_PATHS[i], name));
    }
    assert_string_equal(name, "kept"); /* untouched when refused */
    assert_false(dan_gw_file_path_name((const uint8_t *)"/fw\0bin", 7, name));
}

/* Read request, offset 0x12345, path "/fw.bin": uint40 offset as its
 * little-endian bytes (45 23 01 00 00), then the path's bytes with no
 * length prefix (Path is the last field: tail array). */
static const uint8_t READ_REQ_BYTES[] = {0x45, 0x23, 0x01, 0x00, 0x00, '/',
                                         'f',  'w',  '.',  'b',  'i',  'n'};

static void test_read_req(void **state)
{
    static dan_dc_file_req_t m, d;
    uint8_t buf[DAN_DC_FILE_READ_REQ_MAX_SIZE + 4];
    int n;
    (void)state;
    memset(&m, 0, sizeof m);
    m.offset = 0x12345;
    m.path_len = 7;
    memcpy(m.path, "/fw.bin", 7);
    n = dan_dc_file_read_req_encode(&m, buf, sizeof buf);
    assert_int_equal(n, sizeof READ_REQ_BYTES);
    assert_memory_equal(buf, READ_REQ_BYTES, sizeof READ_REQ_BYTES);
    assert_int_equal(dan_dc_file_read_req_decode(&d, buf, (size_t)n), DAN_OK);
    assert_int_equal(d.offset, 0x12345);
    assert_int_equal(d.path_len, 7);
    assert_memory_equal(d.path, "/fw.bin", 7);
    /* the longest path, and one byte more */
    m.offset = DAN_DC_FILE_OFFSET_MAX;
    m.path_len = DAN_DC_FILE_PATH_MAX;
    memset(m.path, 'x', sizeof m.path);
    n = dan_dc_file_read_req_encode(&m, buf, sizeof buf);
    assert_int_equal(n, DAN_DC_FILE_READ_REQ_MAX_SIZE);
    assert_int_equal(dan_dc_file_read_req_decode(&d, buf, (size_t)n), DAN_OK);
    assert_int_equal(d.offset, DAN_DC_FILE_OFFSET_MAX);
    assert_int_equal(d.path_len, DAN_DC_FILE_PATH_MAX);
    buf[n] = 'x';
    assert_int_equal(dan_dc_file_read_req_decode(&d, buf, (size_t)n + 1u), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_file_read_req_decode(&d, buf, 4), DAN_ERR_MALFORMED); /* short */
    assert_int_equal(dan_dc_file_read_req_encode(&m, buf, 100), DAN_ERR_OVERFLOW);
}

static void test_getinfo(void **state)
{
    /* size 65536 (uint40 LE 00 00 01 00 00), error 0 (int16 LE), entry
     * type FILE | READABLE (9) */
    static const uint8_t rsp_bytes[] = {0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x09};
    static dan_dc_file_req_t q, dq;
    dan_dc_file_getinfo_rsp_t r, d;
    uint8_t buf[DAN_DC_FILE_GETINFO_REQ_MAX_SIZE + 1];
    int n;
    (void)state;
    memset(&r, 0, sizeof r);
    r.size = 65536;
    r.entry_type = DAN_DC_FILE_FLAG_FILE | DAN_DC_FILE_FLAG_READABLE;
    n = dan_dc_file_getinfo_rsp_encode(&r, buf, sizeof buf);
    assert_int_equal(n, DAN_DC_FILE_GETINFO_RSP_MAX_SIZE);
    assert_memory_equal(buf, rsp_bytes, sizeof rsp_bytes);
    r.size = 0;
    r.error = DAN_DC_FILE_NOT_FOUND;
    r.entry_type = 0;
    n = dan_dc_file_getinfo_rsp_encode(&r, buf, sizeof buf);
    assert_int_equal(dan_dc_file_getinfo_rsp_decode(&d, buf, (size_t)n), DAN_OK);
    assert_int_equal(d.error, DAN_DC_FILE_NOT_FOUND);
    assert_int_equal(dan_dc_file_getinfo_rsp_decode(&d, buf, 7), DAN_ERR_MALFORMED);
    /* the request is the path alone */
    memset(&q, 0, sizeof q);
    q.path_len = 6;
    memcpy(q.path, "fw.bin", 6);
    n = dan_dc_file_getinfo_req_encode(&q, buf, sizeof buf);
    assert_int_equal(n, 6);
    assert_memory_equal(buf, "fw.bin", 6);
    assert_int_equal(dan_dc_file_getinfo_req_decode(&dq, buf, 0), DAN_OK); /* empty path */
    assert_int_equal(dq.path_len, 0);
    memset(buf, 'y', sizeof buf);
    assert_int_equal(dan_dc_file_getinfo_req_decode(&dq, buf, sizeof buf), DAN_ERR_MALFORMED);
}

static void test_read_rsp(void **state)
{
    /* error NOT_FOUND (2) as int16 LE: 02 00; no data */
    static const uint8_t not_found[] = {0x02, 0x00};
    static dan_dc_file_read_rsp_t m, d;
    uint8_t buf[DAN_DC_FILE_READ_RSP_MAX_SIZE + 1];
    size_t i;
    int n;
    (void)state;
    memset(&m, 0, sizeof m);
    m.error = DAN_DC_FILE_NOT_FOUND;
    n = dan_dc_file_read_rsp_encode(&m, buf, sizeof buf);
    assert_int_equal(n, 2);
    assert_memory_equal(buf, not_found, 2);
    m.error = DAN_DC_FILE_OK;
    m.data_len = DAN_DC_FILE_READ_MAX;
    for (i = 0; i < DAN_DC_FILE_READ_MAX; i++) {
        m.data[i] = (uint8_t)(i * 7u);
    }
    n = dan_dc_file_read_rsp_encode(&m, buf, sizeof buf);
    assert_int_equal(n, DAN_DC_FILE_READ_RSP_MAX_SIZE);
    assert_int_equal(buf[0], 0);
    assert_int_equal(buf[1], 0);
    assert_memory_equal(buf + 2, m.data, DAN_DC_FILE_READ_MAX);
    assert_int_equal(dan_dc_file_read_rsp_decode(&d, buf, (size_t)n), DAN_OK);
    assert_int_equal(d.data_len, DAN_DC_FILE_READ_MAX);
    assert_memory_equal(d.data, m.data, DAN_DC_FILE_READ_MAX);
    buf[n] = 1; /* 257 bytes of data */
    assert_int_equal(dan_dc_file_read_rsp_decode(&d, buf, (size_t)n + 1u), DAN_ERR_MALFORMED);
    assert_int_equal(dan_dc_file_read_rsp_decode(&d, buf, 1), DAN_ERR_MALFORMED);
    m.data_len = DAN_DC_FILE_READ_MAX + 1u;
    assert_int_equal(dan_dc_file_read_rsp_encode(&m, buf, sizeof buf), DAN_ERR_ARG);
    assert_int_equal(dan_dc_file_read_rsp_encode(NULL, buf, sizeof buf), DAN_ERR_ARG);
}

static void test_signatures(void **state)
{
    uint64_t sig = 0;
    (void)state;
    assert_true(dan_dc_dsdl_signature(DAN_DC_TRANSFER_REQUEST, DAN_DC_FILE_READ_ID, &sig));
    assert_true(sig == DAN_DC_FILE_READ_SIGNATURE);
    assert_true(dan_dc_dsdl_signature(DAN_DC_TRANSFER_RESPONSE, DAN_DC_FILE_GETINFO_ID, &sig));
    assert_true(sig == DAN_DC_FILE_GETINFO_SIGNATURE);
}

int main(void)
{
    return UNIT_RUN("file_codec", NULL, NULL, test_names, test_paths, test_read_req, test_getinfo,
                    test_read_rsp, test_signatures);
}
