/* dan-gatewayd's file store on a directory (file_dir.c), called as the
 * node calls it: committed files (size, read, list in name order, remove),
 * the one partial upload (DIR/~name: write, read back, commit by rename,
 * kept across a restart and resumed, another one removed), the size cap,
 * names checked again, and nothing reached through a symlink. Each test
 * has a fresh mkdtemp() directory. */
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

#include "dan/common.h"
#include "file_dir.h"
#include "unit_run.h"

static char dir[64];
static dan_file_dir_t d;
static const dan_gw_file_store_t *fs;

static void path_of(const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%s/%s", dir, name);
}

static void put_file(const char *name, const char *text)
{
    char p[128];
    FILE *f;
    path_of(name, p, sizeof p);
    f = fopen(p, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, strlen(text), f), strlen(text));
    fclose(f);
}

static bool exists(const char *name)
{
    char p[128];
    struct stat st;
    path_of(name, p, sizeof p);
    return lstat(p, &st) == 0;
}

static void open_store(uint32_t max)
{
    char err[DAN_FILE_DIR_ERR_MAX];
    assert_int_equal(dan_file_dir_open(&d, dir, max, err, sizeof err), 0);
    fs = &d.store;
}

static int setup(void **state)
{
    (void)state;
    snprintf(dir, sizeof dir, "/tmp/dan_file_dir_XXXXXX");
    assert_non_null(mkdtemp(dir));
    open_store(64);
    return 0;
}

static int teardown(void **state)
{
    char cmd[160];
    (void)state;
    dan_file_dir_close(&d);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
    return 0;
}

static void test_open_errors(void **state)
{
    static dan_file_dir_t e;
    char err[DAN_FILE_DIR_ERR_MAX], p[128];
    (void)state;
    assert_int_equal(dan_file_dir_open(&e, "/nonexistent/dir", 64, err, sizeof err), -1);
    assert_non_null(strstr(err, "No such file"));
    put_file("plain", "x");
    path_of("plain", p, sizeof p);
    assert_int_equal(dan_file_dir_open(&e, p, 64, err, sizeof err), -1);
    assert_non_null(strstr(err, "not a directory"));
    assert_int_equal(dan_file_dir_open(&e, dir, 0, err, sizeof err), -1);
    assert_non_null(strstr(err, "cap"));
}

static void test_committed(void **state)
{
    char name[DAN_GW_FILE_NAME_MAX + 1u], p[128];
    uint8_t buf[16];
    uint32_t size;
    (void)state;
    put_file("b.bin", "bravo");
    put_file("a.bin", "alpha!");
    put_file("~c.bin", "partial"); /* never listed */
    put_file(".hidden", "dot");    /* not a valid name */
    put_file("big.bin", "");
    path_of("big.bin", p, sizeof p);
    assert_int_equal(truncate(p, (off_t)3 << 30), 0); /* 3 GiB, sparse: not served, not listed */
    assert_int_equal(fs->size(fs->ctx, "big.bin"), DAN_GW_FS_EFBIG);
    path_of("sub", p, sizeof p);
    assert_int_equal(mkdir(p, 0700), 0); /* a directory is no file */
    assert_int_equal(fs->size(fs->ctx, "a.bin"), 6);
    assert_int_equal(fs->size(fs->ctx, "none"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->size(fs->ctx, "sub"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->read(fs->ctx, "a.bin", 2, buf, sizeof buf), 4);
    assert_memory_equal(buf, "pha!", 4);
    assert_int_equal(fs->read(fs->ctx, "a.bin", 6, buf, sizeof buf), 0);
    assert_int_equal(fs->read(fs->ctx, "a.bin", 100, buf, sizeof buf), 0);
    assert_int_equal(fs->read(fs->ctx, "a.bin", 0, buf, 3), 3);
    /* names are checked again here, whatever the caller did */
    assert_int_equal(fs->size(fs->ctx, "../a.bin"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->size(fs->ctx, ".hidden"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->read(fs->ctx, "/etc/passwd", 0, buf, sizeof buf), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->list(fs->ctx, 0, name, sizeof name, &size), DAN_OK);
    assert_string_equal(name, "a.bin");
    assert_int_equal(size, 6);
    assert_int_equal(fs->list(fs->ctx, 1, name, sizeof name, &size), DAN_OK);
    assert_string_equal(name, "b.bin");
    assert_int_equal(size, 5);
    assert_int_equal(fs->list(fs->ctx, 2, name, sizeof name, &size), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->remove(fs->ctx, "a.bin"), DAN_OK);
    assert_false(exists("a.bin"));
    assert_int_equal(fs->remove(fs->ctx, "a.bin"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->remove(fs->ctx, "sub"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->list(fs->ctx, 0, name, sizeof name, &size), DAN_OK);
    assert_string_equal(name, "b.bin");
}

static void test_symlinks_refused(void **state)
{
    char name[DAN_GW_FILE_NAME_MAX + 1u], p[128], target[128];
    uint8_t buf[16];
    uint32_t size;
    struct stat st;
    (void)state;
    /* a file outside DIR, and links to it from inside */
    snprintf(target, sizeof target, "%s.outside", dir);
    {
        FILE *f = fopen(target, "wb");
        assert_non_null(f);
        fputs("secret", f);
        fclose(f);
    }
    path_of("evil", p, sizeof p);
    assert_int_equal(symlink(target, p), 0);
    path_of("~up.bin", p, sizeof p);
    assert_int_equal(symlink(target, p), 0);
    assert_int_equal(fs->size(fs->ctx, "evil"), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->read(fs->ctx, "evil", 0, buf, sizeof buf), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->list(fs->ctx, 0, name, sizeof name, &size), DAN_GW_FS_ENOENT);
    assert_int_equal(fs->remove(fs->ctx, "evil"), DAN_GW_FS_ENOENT);
    /* an upload whose partial is a link: the link is replaced by a file of
     * our own, never written through */
    assert_int_equal(fs->up_open(fs->ctx, "up.bin", true), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"xx", 2), 2);
    assert_int_equal(stat(target, &st), 0);
    assert_int_equal(st.st_size, 6);
    path_of("~up.bin", p, sizeof p);
    assert_int_equal(lstat(p, &st), 0);
    assert_true(S_ISREG(st.st_mode) && st.st_size == 2);
    /* a commit over a link replaces the link, not its target */
    path_of("~up.bin", p, sizeof p);
    assert_int_equal(unlink(p), 0);
    assert_int_equal(fs->up_open(fs->ctx, "evil", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"new", 3), 3);
    assert_int_equal(fs->up_commit(fs->ctx, "evil"), DAN_OK);
    assert_int_equal(fs->size(fs->ctx, "evil"), 3);
    assert_int_equal(stat(target, &st), 0);
    assert_int_equal(st.st_size, 6);
    assert_int_equal(unlink(target), 0);
}

/* Whoever can write DIR plants a partial that is a hard link to another
 * file (the daemon's DNA table, say) or a FIFO: the upload neither
 * truncates nor writes that file, and does not block on the FIFO. */
static void test_planted_partials_replaced(void **state)
{
    char p[128], victim[128];
    struct stat st;
    (void)state;
    put_file("victim.db", "allocation table");
    path_of("victim.db", victim, sizeof victim);
    path_of("~fw.bin", p, sizeof p);
    assert_int_equal(link(victim, p), 0);
    assert_int_equal(fs->up_open(fs->ctx, "fw.bin", true), 0); /* kept: but not that one */
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"image", 5), 5);
    assert_int_equal(stat(victim, &st), 0);
    assert_int_equal(st.st_size, 16);
    assert_int_equal(st.st_nlink, 1);
    assert_int_equal(fs->up_open(fs->ctx, "fw.bin", false), 0); /* ours now: truncated */
    path_of("~pipe.bin", p, sizeof p);
    assert_int_equal(mkfifo(p, 0600), 0);
    assert_int_equal(fs->up_open(fs->ctx, "pipe.bin", true), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"ok", 2), 2);
    assert_int_equal(lstat(p, &st), 0);
    assert_true(S_ISREG(st.st_mode));
}

static void test_upload(void **state)
{
    uint8_t buf[16];
    (void)state;
    put_file("fw.bin", "old!");
    assert_int_equal(fs->up_open(fs->ctx, "fw.bin", false), 0);
    assert_true(exists("~fw.bin"));
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"new-", 4), 4);
    assert_int_equal(fs->up_write(fs->ctx, 2, (const uint8_t *)"w-image", 7), 7); /* straddles */
    assert_int_equal(fs->up_write(fs->ctx, 20, (const uint8_t *)"x", 1), DAN_GW_FS_EIO); /* gap */
    assert_int_equal(fs->up_read(fs->ctx, 0, buf, sizeof buf), 9);
    assert_memory_equal(buf, "new-image", 9);
    /* the partial is never served: the old file is */
    assert_int_equal(fs->size(fs->ctx, "fw.bin"), 4);
    assert_int_equal(fs->up_commit(fs->ctx, "fw.bin"), DAN_OK);
    assert_false(exists("~fw.bin"));
    assert_int_equal(fs->size(fs->ctx, "fw.bin"), 9);
    assert_int_equal(fs->read(fs->ctx, "fw.bin", 0, buf, sizeof buf), 9);
    assert_memory_equal(buf, "new-image", 9);
    assert_int_equal(fs->up_commit(fs->ctx, "fw.bin"), DAN_GW_FS_ENOENT); /* none open */
    assert_int_equal(fs->up_write(fs->ctx, 0, buf, 1), DAN_GW_FS_ENOENT);
}

static void test_resume_after_restart(void **state)
{
    uint8_t buf[16];
    (void)state;
    assert_int_equal(fs->up_open(fs->ctx, "a.bin", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"12345", 5), 5);
    dan_file_dir_close(&d); /* the daemon stops */
    open_store(64);
    assert_int_equal(fs->up_open(fs->ctx, "a.bin", true), 5); /* resumes */
    assert_int_equal(fs->up_read(fs->ctx, 0, buf, sizeof buf), 5);
    assert_memory_equal(buf, "12345", 5);
    assert_int_equal(fs->up_write(fs->ctx, 5, (const uint8_t *)"678", 3), 3);
    assert_int_equal(fs->up_open(fs->ctx, "a.bin", false), 0); /* restart: empty */
    assert_int_equal(fs->up_write(fs->ctx, 0, (const uint8_t *)"ab", 2), 2);
    /* another upload discards this one */
    assert_int_equal(fs->up_open(fs->ctx, "b.bin", true), 0);
    assert_false(exists("~a.bin"));
    assert_true(exists("~b.bin"));
    assert_int_equal(fs->up_open(fs->ctx, "b.bin", true), 0);
}

static void test_size_cap(void **state)
{
    uint8_t big[80];
    (void)state;
    memset(big, 0x5A, sizeof big);
    assert_int_equal(fs->up_open(fs->ctx, "big.bin", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, big, 60), 60);
    assert_int_equal(fs->up_write(fs->ctx, 60, big, 5), DAN_GW_FS_EFBIG); /* cap 64 */
    assert_int_equal(fs->up_write(fs->ctx, 60, big, 4), 4);
    assert_int_equal(fs->up_write(fs->ctx, 0, big, sizeof big), DAN_GW_FS_EFBIG);
    /* a partial over the cap left by someone else starts again */
    dan_file_dir_close(&d);
    put_file("~big.bin", "0123456789012345678901234567890123456789012345678901234567890123456789");
    open_store(64);
    assert_int_equal(fs->up_open(fs->ctx, "big.bin", true), 0);
}

/* An uploader cannot fill the volume: a commit past max_files files or
 * max_total bytes (the file it replaces not counted) is ENOSPC and keeps
 * the partial; after a remove it goes through. */
static void test_store_caps(void **state)
{
    uint8_t data[40];
    (void)state;
    memset(data, 0x33, sizeof data);
    d.max_files = 2;
    d.max_total = 100;
    put_file("a.bin", "0123456789");
    assert_int_equal(fs->up_open(fs->ctx, "b.bin", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, data, 40), 40);
    assert_int_equal(fs->up_commit(fs->ctx, "b.bin"), DAN_OK); /* 2 files, 50 bytes */
    assert_int_equal(fs->up_open(fs->ctx, "c.bin", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, data, 5), 5);
    assert_int_equal(fs->up_commit(fs->ctx, "c.bin"), DAN_GW_FS_ENOSPC); /* a third file */
    assert_true(exists("~c.bin"));
    assert_false(exists("c.bin"));
    /* replacing b.bin does not count it twice: 10 + 5 */
    assert_int_equal(fs->up_commit(fs->ctx, "b.bin"), DAN_OK);
    assert_int_equal(fs->size(fs->ctx, "b.bin"), 5);
    /* then the bytes */
    d.max_files = 3;
    assert_int_equal(fs->up_open(fs->ctx, "c.bin", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, data, 40), 40);
    assert_int_equal(fs->up_commit(fs->ctx, "c.bin"), DAN_OK); /* 10 + 5 + 40 */
    assert_int_equal(fs->up_open(fs->ctx, "d.bin", false), 0);
    assert_int_equal(fs->up_write(fs->ctx, 0, data, 40), 40);
    d.max_files = 4;
    d.max_total = 90;
    assert_int_equal(fs->up_commit(fs->ctx, "d.bin"), DAN_GW_FS_ENOSPC); /* 10 + 5 + 40 + 40 */
    assert_int_equal(fs->remove(fs->ctx, "c.bin"), DAN_OK);
    assert_int_equal(fs->up_commit(fs->ctx, "d.bin"), DAN_OK); /* 55 */
}

int main(void)
{
    return UNIT_RUN("file_dir", setup, teardown, test_open_errors, test_committed,
                    test_symlinks_refused, test_planted_partials_replaced, test_upload,
                    test_resume_after_restart, test_size_cap, test_store_caps);
}
