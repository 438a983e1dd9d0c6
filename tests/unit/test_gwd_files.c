/* dan-gatewayd's files: the allocation table in a file (dna_file.c: the
 * node's storage callbacks, atomic saves, a file that does not check
 * renamed to .bad with its reason) and the unique ID (node_uid.c: --uid,
 * derived from a machine ID, the host-name fallback). Files live in a
 * fresh temporary directory per test. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "dna_file.h"
#include "node_uid.h"
#include "unit_run.h"

static char dir[64], path[128];

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/dan_gwd_files_XXXXXX");
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/dna.db", dir);
    return 0;
}

static int teardown(void **state)
{
    char cmd[160];
    (void)state;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
    return 0;
}

static void write_file(const char *p, const uint8_t *b, size_t n)
{
    FILE *f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(b, 1, n, f), n);
    fclose(f);
}

static bool exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

/* A node on the file: init loads it; the table's flags after. */
static uint8_t start_node(dan_dna_file_t *f, dan_gw_node_t *g)
{
    dan_gw_node_config_t c;
    char err[DAN_DNA_FILE_ERR_MAX];
    dan_dna_file_init(f, path);
    assert_int_equal(dan_dna_file_read(f, err, sizeof err), 0);
    dan_gw_node_config_default(&c);
    c.dna_storage = &f->storage;
    assert_int_equal(dan_gw_node_init(g, &c, 1000), DAN_OK);
    return g->dna.flags;
}

static dan_gw_node_t node; /* large: static */

static void test_missing_store_reload(void **state)
{
    static dan_dna_file_t f;
    static const uint8_t uid[16] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
    int r;
    (void)state;
    assert_int_equal(start_node(&f, &node), 0); /* no file: a fresh table, no error */
    assert_false(f.exists);
    node.dna.table[0].node_id = 77;
    memcpy(node.dna.table[0].unique_id, uid, 16);
    node.dna.n = 1;
    node.dna.dirty = true;
    dan_gw_node_poll(&node, 2000); /* stores */
    assert_int_equal(f.stores, 1);
    assert_int_equal(f.store_errors, 0);
    assert_true(exists(path));
    {
        char tmp[160];
        snprintf(tmp, sizeof tmp, "%s.tmp", path);
        assert_false(exists(tmp));
    }
    r = start_node(&f, &node);
    assert_int_equal(r, DAN_GW_DNA_LOADED);
    assert_true(f.exists);
    assert_int_equal(f.len, 4 + 1 + 17 + 2);
    assert_int_equal(node.dna.n, 1);
    assert_int_equal(node.dna.table[0].node_id, 77);
    assert_memory_equal(node.dna.table[0].unique_id, uid, 16);
}

/* Content that is no table: the node starts empty, the file goes to .bad
 * with the reason. */
static void check_refused(const uint8_t *b, size_t n, const char *reason)
{
    static dan_dna_file_t f;
    char msg[2 * DAN_DNA_FILE_ERR_MAX], bad[160], want[400];
    write_file(path, b, n);
    assert_int_equal(start_node(&f, &node), DAN_GW_DNA_STORE_ERROR);
    assert_int_equal(node.dna.n, 0);
    assert_int_equal(dan_dna_file_quarantine(&f, msg, sizeof msg), 0);
    snprintf(bad, sizeof bad, "%s.bad", path);
    snprintf(want, sizeof want, "%s: %s; renamed to %s", path, reason, bad);
    assert_string_equal(msg, want);
    assert_false(exists(path));
    assert_true(exists(bad));
    assert_int_equal(unlink(bad), 0);
}

static void test_refused_files(void **state)
{
    static uint8_t big[DAN_GW_DNA_BLOB_MAX + 10];
    static const uint8_t empty_table[7] = {'D', 'N', 'A', '1', 0, 0, 0}; /* CRC wrong */
    (void)state;
    check_refused((const uint8_t *)"hello, world", 12, "wrong magic (not a DNA1 table)");
    check_refused(empty_table, sizeof empty_table, "CRC mismatch");
    check_refused(empty_table, 0, "shorter than an empty table");
    memcpy(big, empty_table, 4);
    check_refused(big, sizeof big, "longer than any table (over 1095 bytes)");
}

static void test_unreadable_and_unwritable(void **state)
{
    static dan_dna_file_t f;
    char err[DAN_DNA_FILE_ERR_MAX];
    uint8_t blob[7] = {'D', 'N', 'A', '1', 0, 0, 0};
    (void)state;
    assert_int_equal(mkdir(path, 0755), 0); /* a directory where the file should be */
    assert_int_equal(dan_dna_file_check_path(path, err, sizeof err), -1);
    assert_non_null(strstr(err, "not a regular file"));
    dan_dna_file_init(&f, path);
    assert_int_equal(dan_dna_file_read(&f, err, sizeof err), -1);
    assert_non_null(strstr(err, "cannot read the DNA table"));
    assert_int_equal(rmdir(path), 0);
    assert_int_equal(dan_dna_file_check_path(path, err, sizeof err), 0);
    assert_int_equal(dan_dna_file_check_path("/nonexistent/dna.db", err, sizeof err), -1);
    assert_non_null(strstr(err, "directory /nonexistent does not exist"));
    dan_dna_file_init(&f, "/nonexistent/dna.db");
    assert_int_equal(f.storage.store(f.storage.ctx, blob, sizeof blob), DAN_ERR_IO);
    assert_int_equal(f.store_errors, 1);
    assert_non_null(strstr(f.err, "cannot save the DNA table: create /nonexistent/dna.db.tmp"));
}

static void test_uid(void **state)
{
    /* FNV-1a of "dan-gatewayd:K:" + the ID, K = 0..3 (computed in Python) */
    static const uint8_t want[16] = {0xA3, 0xD5, 0xF1, 0x32, 0xC6, 0x7E, 0xAD, 0x70,
                                     0x81, 0xD2, 0x54, 0x4C, 0x8C, 0x5A, 0x46, 0xD5};
    static const uint8_t zero[16];
    uint8_t uid[16], uid2[16];
    char mid[160];
    (void)state;
    assert_int_equal(dan_uid_parse("000102030405060708090a0B0c0D0e0F", uid), 0);
    assert_int_equal(uid[11], 0x0B);
    assert_int_equal(uid[15], 0x0F);
    assert_int_equal(dan_uid_parse("00000000000000000000000000000000", uid), -1);
    assert_int_equal(dan_uid_parse("000102030405060708090a0b0c0d0e0", uid), -1);
    assert_int_equal(dan_uid_parse("000102030405060708090a0b0c0d0e0g", uid), -1);
    snprintf(mid, sizeof mid, "%s/machine-id", dir);
    write_file(mid, (const uint8_t *)"0123456789abcdef0123456789abcdef\n", 33);
    assert_int_equal(dan_uid_derive(mid, uid), 0);
    assert_memory_equal(uid, want, 16);
    write_file(mid, (const uint8_t *)"uninitialized\n", 14); /* systemd's first-boot marker */
    assert_int_equal(dan_uid_derive(mid, uid), 1);
    assert_int_equal(dan_uid_derive("/nonexistent/machine-id", uid2), 1);
    assert_memory_equal(uid, uid2, 16); /* the host name's: stable */
    assert_memory_not_equal(uid, zero, 16);
    assert_memory_not_equal(uid, want, 16);
}

int main(void)
{
    return UNIT_RUN("gwd_files", setup, teardown, test_missing_store_reload, test_refused_files,
                    test_unreadable_and_unwritable, test_uid);
}
