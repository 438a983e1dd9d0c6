/* CAN-over-DAN gateway, the DAN file messages through the client, the
 * simulated wire and the node, into a RAM store (file_store_ram.c): a whole
 * upload in chunks and its commit, retried writes (nothing written twice),
 * a gap, too large, a resume after a gateway restart (the store kept the
 * partial), a CRC mismatch (never served nor listed), LIST paging, REMOVE,
 * no store, bad names, store failures. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "file_rig.h"
#include "unit_run.h"

static void test_upload_commit(void **state)
{
    const ram_file_t *f;
    uint32_t crc = dan_gw_crc32(0, img, IMG_SIZE), held;
    (void)state;
    upload("fw.bin", IMG_SIZE);
    f = ram_store_file(&S, "fw.bin");
    assert_non_null(f);
    assert_int_equal(f->len, IMG_SIZE);
    assert_memory_equal(f->data, img, IMG_SIZE);
    assert_int_equal(R->g.stats.upload_bytes, IMG_SIZE);
    assert_int_equal(R->g.stats.file_commits, 1);
    assert_int_equal(S.writes, (IMG_SIZE + 149u) / 150u);
    /* the master's retried commit after the success: OK again, nothing done */
    assert_int_equal(commit(crc, &held), DAN_GW_FILE_OK);
    assert_int_equal(held, crc);
    assert_int_equal(R->g.stats.file_commits, 1);
    assert_int_equal(commit(crc ^ 1u, &held), DAN_GW_FILE_NO_UPLOAD);
    assert_int_equal(write_at(0, 10, NULL), DAN_GW_FILE_NO_UPLOAD);
}

/* Lost responses: the same write again writes nothing; a write reaching
 * below have writes only its new tail. */
static void test_retried_writes(void **state)
{
    uint32_t have;
    (void)state;
    assert_int_equal(open_file("esc.apj", IMG_SIZE, false, &have), DAN_GW_FILE_OK);
    assert_int_equal(dan_gw_file_write(&R->gw, 0, img, 150, R->bus.now), DAN_OK);
    lose_response(); /* the master sends the same bytes again */
    assert_int_equal(done(&have), DAN_GW_FILE_OK);
    assert_int_equal(have, 150);
    assert_int_equal(S.writes, 1);
    assert_int_equal(write_at(0, 150, &have), DAN_GW_FILE_OK); /* wholly below have */
    assert_int_equal(have, 150);
    assert_int_equal(S.writes, 1);
    assert_int_equal(write_at(100, 150, &have), DAN_GW_FILE_OK); /* straddles have */
    assert_int_equal(have, 250);
    assert_int_equal(S.writes, 2);
    assert_int_equal(R->g.stats.upload_bytes, 250);
    upload_range(250, IMG_SIZE);
    assert_int_equal(commit(dan_gw_crc32(0, img, IMG_SIZE), NULL), DAN_GW_FILE_OK);
    assert_memory_equal(ram_store_file(&S, "esc.apj")->data, img, IMG_SIZE);
}

static void test_gap_and_too_large(void **state)
{
    uint32_t have;
    (void)state;
    assert_int_equal(write_at(0, 10, &have), DAN_GW_FILE_NO_UPLOAD);
    assert_int_equal(open_file("big.bin", RAM_FILE_CAP + 1u, false, &have), DAN_GW_FILE_TOO_LARGE);
    assert_int_equal(open_file("fw.bin", 300, false, &have), DAN_GW_FILE_OK);
    assert_int_equal(write_at(0, 100, &have), DAN_GW_FILE_OK);
    assert_int_equal(write_at(101, 10, &have), DAN_GW_FILE_GAP);
    assert_int_equal(have, 100);
    assert_int_equal(write_at(200, 101, &have), DAN_GW_FILE_GAP);
    assert_int_equal(write_at(100, 150, &have), DAN_GW_FILE_OK);
    assert_int_equal(write_at(250, 51, &have), DAN_GW_FILE_TOO_LARGE); /* one past the size */
    assert_int_equal(have, 250);
    assert_int_equal(S.writes, 2);
    /* a too-large open leaves the upload held alone */
    assert_int_equal(open_file("big.bin", 0xFFFFFFFFu, true, &have), DAN_GW_FILE_TOO_LARGE);
    assert_int_equal(open_file("fw.bin", 300, false, &have), DAN_GW_FILE_OK);
    assert_int_equal(have, 250);
}

/* The gateway restarts mid-upload: RAM is gone, the store kept the
 * partial; the same name and size resume at its length (the CRC read
 * back), restart or another size start over. */
static void test_resume_after_restart(void **state)
{
    uint32_t have;
    (void)state;
    assert_int_equal(open_file("fw.bin", IMG_SIZE, false, &have), DAN_GW_FILE_OK);
    upload_range(0, 450);
    gateway_start(true);
    assert_int_equal(open_file("fw.bin", IMG_SIZE, false, &have), DAN_GW_FILE_OK);
    assert_int_equal(have, 450);
    assert_int_equal(write_at(300, 150, &have), DAN_GW_FILE_OK); /* a retry: nothing */
    assert_int_equal(have, 450);
    upload_range(450, IMG_SIZE);
    assert_int_equal(commit(dan_gw_crc32(0, img, IMG_SIZE), NULL), DAN_GW_FILE_OK);
    assert_memory_equal(ram_store_file(&S, "fw.bin")->data, img, IMG_SIZE);
    /* restart set: from 0, whatever is held */
    assert_int_equal(open_file("b.bin", IMG_SIZE, false, &have), DAN_GW_FILE_OK);
    upload_range(0, 300);
    assert_int_equal(open_file("b.bin", IMG_SIZE, false, &have), DAN_GW_FILE_OK);
    assert_int_equal(have, 300);
    assert_int_equal(open_file("b.bin", IMG_SIZE, true, &have), DAN_GW_FILE_OK);
    assert_int_equal(have, 0);
    upload_range(0, 300);
    assert_int_equal(open_file("b.bin", 500, false, &have), DAN_GW_FILE_OK); /* another size */
    assert_int_equal(have, 0);
    /* a kept partial longer than the new size is not its partial */
    upload_range(0, 300);
    gateway_start(true);
    assert_int_equal(open_file("b.bin", 200, false, &have), DAN_GW_FILE_OK);
    assert_int_equal(have, 0);
}

/* A wrong CRC is refused: the upload stays open, nothing is served or
 * listed; SHORT before the last byte. */
static void test_crc_and_short(void **state)
{
    uint32_t held, crc = dan_gw_crc32(0, img, IMG_SIZE);
    dan_reader_t r;
    dan_gw_file_list_hdr_t h;
    (void)state;
    assert_int_equal(open_file("fw.bin", IMG_SIZE, false, NULL), DAN_GW_FILE_OK);
    upload_range(0, 900);
    assert_int_equal(commit(crc, &held), DAN_GW_FILE_SHORT);
    assert_int_equal(held, dan_gw_crc32(0, img, 900));
    img[950] ^= 0x40; /* the uploader's copy was corrupted */
    upload_range(900, IMG_SIZE);
    img[950] ^= 0x40;
    assert_int_equal(commit(crc, &held), DAN_GW_FILE_CRC);
    assert_int_not_equal(held, crc);
    assert_null(ram_store_file(&S, "fw.bin"));
    assert_int_equal(S.fs.size(S.fs.ctx, "fw.bin"), DAN_GW_FS_ENOENT);
    call_ok(dan_gw_file_list(&R->gw, 0, R->bus.now));
    assert_int_equal(dan_gw_file_list_begin(&R->gw, &r, &h), DAN_OK);
    assert_int_equal(h.count, 0);
    assert_int_equal(h.next, DAN_GW_NONE);
    assert_int_equal(commit(held, NULL), DAN_GW_FILE_OK); /* still open: the bytes held */
    assert_int_equal(R->g.stats.file_commits, 1);
}

/* Reads one LIST page into names (concatenated, ';' after each). */
static uint8_t list_page(uint8_t first, char *names, size_t cap)
{
    dan_reader_t r;
    dan_gw_file_list_hdr_t h;
    dan_gw_file_entry_t e;
    size_t i;
    call_ok(dan_gw_file_list(&R->gw, first, R->bus.now));
    assert_int_equal(dan_gw_file_list_begin(&R->gw, &r, &h), DAN_OK);
    for (i = 0; i < h.count; i++) {
        assert_int_equal(dan_gw_file_list_next(&r, &e), DAN_OK);
        assert_int_equal(e.size, 10u + (uint32_t)(e.name[0] - 'a'));
        strncat(names, e.name, cap - strlen(names) - 2u);
        strcat(names, ";");
    }
    return h.next;
}

static void test_list_paging_and_remove(void **state)
{
    static const char *const names[] = {
        "e2345678901234567890123456789012", "a2345678901234567890123456789012",
        "d2345678901234567890123456789012", "c2345678901234567890123456789012",
        "b2345678901234567890123456789012"};
    char got[512] = "";
    uint8_t next;
    size_t i;
    (void)state;
    for (i = 0; i < 5; i++) {
        upload(names[i], 10u + (uint32_t)(names[i][0] - 'a'));
    }
    next = list_page(0, got, sizeof got); /* 36 bytes an entry: 4 in a payload */
    assert_int_equal(next, 4);
    assert_int_equal(list_page(next, got, sizeof got), DAN_GW_NONE);
    assert_string_equal(got, "a2345678901234567890123456789012;b2345678901234567890123456789012;"
                             "c2345678901234567890123456789012;d2345678901234567890123456789012;"
                             "e2345678901234567890123456789012;");
    assert_int_equal(dan_gw_file_remove(&R->gw, names[1], R->bus.now), DAN_OK);
    assert_int_equal(done(NULL), DAN_GW_FILE_OK);
    assert_int_equal(dan_gw_file_remove(&R->gw, names[1], R->bus.now), DAN_OK);
    assert_int_equal(done(NULL), DAN_GW_FILE_NOT_FOUND);
    got[0] = '\0';
    assert_int_equal(list_page(0, got, sizeof got), DAN_GW_NONE);
    assert_null(strstr(got, names[1]));
    assert_int_equal(list_page(200, got, sizeof got), DAN_GW_NONE); /* past the end: empty */
}

static void test_no_store(void **state)
{
    char got[64] = "";
    (void)state;
    gateway_start(false);
    assert_int_equal(open_file("fw.bin", 10, false, NULL), DAN_GW_FILE_NO_STORE);
    assert_int_equal(write_at(0, 10, NULL), DAN_GW_FILE_NO_STORE);
    assert_int_equal(commit(0, NULL), DAN_GW_FILE_NO_STORE);
    assert_int_equal(dan_gw_file_remove(&R->gw, "fw.bin", R->bus.now), DAN_OK);
    assert_int_equal(done(NULL), DAN_GW_FILE_NO_STORE);
    assert_int_equal(list_page(0, got, sizeof got), DAN_GW_NONE);
    assert_string_equal(got, "");
}

/* Names outside the rule are error frames before the store is asked,
 * whatever the bytes (hand-built requests: the client's codec refuses
 * only lengths). */
static void test_bad_names(void **state)
{
    static const char *const bad[] = {"../x", ".hidden", "a/b", "/abs",
                                      "a b",  "x\\y",    "..",  "nul\0x"};
    uint8_t p[64];
    size_t i, n;
    (void)state;
    for (i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        n = i + 1u == sizeof bad / sizeof bad[0] ? 5u : strlen(bad[i]);
        p[0] = (uint8_t)n;
        memcpy(p + 1, bad[i], n);
        memset(p + 1 + n, 0, 5); /* size 0, flags 0 */
        assert_int_equal(request_sealed(DAN_GW_CODE_FILE_OPEN, p, n + 6u), DAN_OK);
        assert_int_equal(finish(), DAN_ERR_REMOTE);
        assert_int_equal(request_sealed(DAN_GW_CODE_FILE_REMOVE, p, n + 1u), DAN_OK);
        assert_int_equal(finish(), DAN_ERR_REMOTE);
    }
    assert_int_equal(S.calls, 0);
    assert_int_equal(dan_gw_file_open(&R->gw, "", 1, false, R->bus.now), DAN_ERR_ARG);
    assert_int_equal(
        dan_gw_file_open(&R->gw, "a23456789012345678901234567890123", 1, false, R->bus.now),
        DAN_ERR_ARG);
    assert_int_equal(dan_gw_file_write(&R->gw, 0, img, 0, R->bus.now), DAN_ERR_ARG);
    assert_int_equal(dan_gw_file_write(&R->gw, 0, img, 151, R->bus.now), DAN_ERR_ARG);
}

/* The store fails: IO_ERROR, counted; the upload goes on once it works. */
static void test_store_failures(void **state)
{
    uint32_t have;
    (void)state;
    assert_int_equal(open_file("fw.bin", IMG_SIZE, false, &have), DAN_GW_FILE_OK);
    upload_range(0, 300);
    S.fail_from = S.calls + 1u;
    assert_int_equal(write_at(300, 150, &have), DAN_GW_FILE_IO_ERROR);
    assert_int_equal(have, 300);
    assert_int_equal(dan_gw_file_list(&R->gw, 0, R->bus.now), DAN_OK);
    assert_int_equal(finish(), DAN_ERR_REMOTE); /* no result byte: an error frame */
    assert_int_equal(R->g.stats.upload_errors, 2);
    S.fail_from = 0;
    upload_range(300, IMG_SIZE);
    assert_int_equal(commit(dan_gw_crc32(0, img, IMG_SIZE), NULL), DAN_GW_FILE_OK);
    assert_memory_equal(ram_store_file(&S, "fw.bin")->data, img, IMG_SIZE);
    /* a failed open drops the upload: writes find none */
    S.fail_from = S.calls + 1u;
    assert_int_equal(open_file("g.bin", IMG_SIZE, false, &have), DAN_GW_FILE_IO_ERROR);
    S.fail_from = 0;
    assert_int_equal(write_at(0, 10, &have), DAN_GW_FILE_NO_UPLOAD);
    assert_int_equal(R->g.stats.upload_errors, 3);
}

/* dan_gw_file_result() after a call that was not a file call, and a list
 * walk after a call that was not FILE_LIST: a clear error, and a reader
 * that only gives errors (it was left uninitialised: valgrind showed reads
 * of garbage; review finding). A NODE_CALL string past DAN_GW_VALUE_STRING_MAX
 * is refused, not copied from beyond string[]. */
static void test_results_of_the_wrong_call(void **state)
{
    dan_reader_t r;
    dan_gw_file_list_hdr_t h;
    dan_gw_call_t c;
    uint8_t result = 99, out[200];
    uint32_t v = 99;
    (void)state;
    assert_int_equal(dan_gw_stats(&R->gw, R->bus.now), DAN_OK);
    assert_int_equal(finish(), DAN_OK);
    assert_int_equal(dan_gw_file_result(&R->gw, &result, &v), DAN_ERR_NOTFOUND);
    assert_int_equal(result, DAN_GW_NONE); /* never DAN_GW_FILE_OK (0) without an answer */
    assert_int_equal(v, 0);
    memset(&r, 0x5A, sizeof r);
    assert_int_equal(dan_gw_file_list_begin(&R->gw, &r, &h), DAN_ERR_NOTFOUND);
    assert_true(r.error);
    assert_int_equal(dan_get_u8(&r), 0);
    assert_int_equal(dan_reader_remaining(&r), 0);
    memset(&c, 0, sizeof c);
    c.call_id = 1;
    c.node_id = 42;
    c.op = DAN_GW_CALL_PARAM_SET;
    c.name = "x";
    c.name_len = 1;
    c.value.tag = DAN_GW_VALUE_STRING;
    c.value.string_len = DAN_GW_VALUE_STRING_MAX + 1u;
    assert_int_equal(dan_gw_msg_call_encode(&c, out, sizeof out), DAN_ERR_ARG);
    c.value.string_len = DAN_GW_VALUE_STRING_MAX;
    assert_true(dan_gw_msg_call_encode(&c, out, sizeof out) > 0);
}

int main(void)
{
    return UNIT_RUN("gateway_files", setup_files, teardown, test_upload_commit, test_retried_writes,
                    test_gap_and_too_large, test_resume_after_restart, test_crc_and_short,
                    test_list_paging_and_remove, test_no_store, test_bad_names, test_store_failures,
                    test_results_of_the_wrong_call);
}
