/* The allocation table in a file: the node's storage callbacks (see
 * dna_file.h). */
#include "dna_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "dan/common.h"

#define FILE_MODE 0644

/* dir gets the directory part of path ("." for a bare name). */
static void dir_of(const char *path, char *dir, size_t cap)
{
    const char *slash = strrchr(path, '/');
    if (slash == NULL) {
        snprintf(dir, cap, ".");
    } else if (slash == path) {
        snprintf(dir, cap, "/");
    } else {
        snprintf(dir, cap, "%.*s", (int)(slash - path), path);
    }
}

static int load_cb(void *ctx, uint8_t *buf, size_t cap)
{
    const dan_dna_file_t *f = (const dan_dna_file_t *)ctx;
    if (f->len > DAN_GW_DNA_BLOB_MAX || f->len > cap) {
        return DAN_ERR_OVERFLOW; /* never a table: the node flags it */
    }
    if (f->exists && f->len == 0u) {
        return DAN_ERR_MALFORMED; /* an empty file is no table either */
    }
    memcpy(buf, f->buf, f->len);
    return (int)f->len;
}

/* Writes all of b to fd; 0 or -1 (errno set). */
static int write_all(int fd, const uint8_t *b, size_t len)
{
    while (len > 0u) {
        ssize_t w = write(fd, b, len);
        if (w < 0 && errno == EINTR) {
            continue;
        }
        if (w <= 0) {
            if (w == 0) {
                errno = EIO;
            }
            return -1;
        }
        b += w;
        len -= (size_t)w;
    }
    return 0;
}

/* fsync of the directory holding path, so the rename itself is durable. */
static int sync_dir(const char *path)
{
    char dir[DAN_DNA_FILE_PATH_MAX];
    int fd, r;
    dir_of(path, dir, sizeof dir);
    fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0) {
        return -1;
    }
    r = fsync(fd);
    close(fd);
    return r;
}

static int store_fail(dan_dna_file_t *f, const char *what, const char *tmp)
{
    int e = errno;
    snprintf(f->err, sizeof f->err, "cannot save the DNA table: %s %s: %s", what, tmp, strerror(e));
    (void)unlink(tmp);
    f->store_errors++;
    return DAN_ERR_IO;
}

static int store_cb(void *ctx, const uint8_t *b, size_t len)
{
    dan_dna_file_t *f = (dan_dna_file_t *)ctx;
    char tmp[DAN_DNA_FILE_PATH_MAX + 8];
    int fd;
    snprintf(tmp, sizeof tmp, "%s.tmp", f->path);
    fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, FILE_MODE);
    if (fd < 0) {
        return store_fail(f, "create", tmp);
    }
    if (write_all(fd, b, len) < 0 || fsync(fd) < 0) {
        int e = errno;
        close(fd);
        errno = e;
        return store_fail(f, "write", tmp);
    }
    if (close(fd) < 0) {
        return store_fail(f, "close", tmp);
    }
    if (rename(tmp, f->path) < 0) {
        return store_fail(f, "rename", tmp);
    }
    if (sync_dir(f->path) < 0) {
        int e = errno;
        snprintf(f->err, sizeof f->err, "DNA table saved, but the directory of %s: fsync: %s",
                 f->path, strerror(e));
        f->store_errors++;
        return DAN_ERR_IO;
    }
    f->stores++;
    return DAN_OK;
}

void dan_dna_file_init(dan_dna_file_t *f, const char *path)
{
    memset(f, 0, sizeof *f);
    f->path = path;
    f->storage.load = load_cb;
    f->storage.store = store_cb;
    f->storage.ctx = f;
}

int dan_dna_file_check_path(const char *path, char *err, size_t errlen)
{
    char dir[DAN_DNA_FILE_PATH_MAX];
    struct stat st;
    size_t n = strlen(path);
    if (n == 0u || n >= DAN_DNA_FILE_PATH_MAX || path[n - 1u] == '/') {
        snprintf(err, errlen, "%s: not a file name (1..%d characters, not ending in /)", path,
                 DAN_DNA_FILE_PATH_MAX - 1);
        return -1;
    }
    if (stat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
        snprintf(err, errlen, "%s: not a regular file", path);
        return -1;
    }
    dir_of(path, dir, sizeof dir);
    if (stat(dir, &st) < 0 || !S_ISDIR(st.st_mode)) {
        snprintf(err, errlen, "%s: directory %s does not exist", path, dir);
        return -1;
    }
    if (access(dir, W_OK | X_OK) < 0) {
        snprintf(err, errlen, "%s: directory %s is not writable: %s", path, dir, strerror(errno));
        return -1;
    }
    return 0;
}

int dan_dna_file_read(dan_dna_file_t *f, char *err, size_t errlen)
{
    int fd = open(f->path, O_RDONLY | O_CLOEXEC);
    f->len = 0;
    f->exists = false;
    if (fd < 0 && errno == ENOENT) {
        return 0;
    }
    while (fd >= 0 && f->len < sizeof f->buf) {
        ssize_t n = read(fd, f->buf + f->len, sizeof f->buf - f->len);
        if (n == 0 || (n < 0 && errno != EINTR)) {
            f->exists = n == 0;
            break;
        }
        f->len += n > 0 ? (size_t)n : 0u;
    }
    f->exists |= f->len == sizeof f->buf; /* stopped reading one byte past any table */
    if (!f->exists) {
        snprintf(err, errlen, "%s: cannot read the DNA table: %s", f->path, strerror(errno));
    }
    if (fd >= 0) {
        close(fd);
    }
    return f->exists ? 0 : -1;
}

int dan_dna_file_quarantine(dan_dna_file_t *f, char *msg, size_t msglen)
{
    char bad[DAN_DNA_FILE_PATH_MAX + 8], why[96];
    if (f->len > DAN_GW_DNA_BLOB_MAX) {
        snprintf(why, sizeof why, "longer than any table (over %u bytes)",
                 (unsigned)DAN_GW_DNA_BLOB_MAX);
    } else {
        snprintf(why, sizeof why, "%s",
                 dan_gw_dna_blob_error(dan_gw_dna_blob_check(f->buf, f->len)));
    }
    snprintf(bad, sizeof bad, "%s.bad", f->path);
    if (rename(f->path, bad) < 0) {
        snprintf(msg, msglen, "%s: %s; cannot rename it to %s: %s", f->path, why, bad,
                 strerror(errno));
        return -1;
    }
    (void)sync_dir(f->path);
    snprintf(msg, msglen, "%s: %s; renamed to %s", f->path, why, bad);
    return 0;
}
