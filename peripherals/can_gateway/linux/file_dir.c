/* The file store on a directory (see file_dir.h). */
#include "file_dir.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "dan/common.h"

#define FILE_MODE    0644
#define PARTIAL_MARK '~'

/* A name the store may touch: checked again here, whatever the caller did. */
static bool name_ok(const char *name)
{
    return name != NULL && dan_gw_file_name_ok(name, strnlen(name, DAN_GW_FILE_NAME_MAX + 1u));
}

/* errno after a failed call on the medium, as a store code. */
static int32_t fs_error(dan_file_dir_t *d)
{
    if (errno == ENOENT || errno == ELOOP || errno == ENOTDIR) {
        return DAN_GW_FS_ENOENT; /* ELOOP: a symlink, never followed */
    }
    d->errors++;
    return errno == ENOSPC || errno == EDQUOT ? DAN_GW_FS_ENOSPC : DAN_GW_FS_EIO;
}

/* Opens committed file name (checked again) for reading, a regular file
 * only: the descriptor, or -1 with the store code in *e. */
static int open_file(dan_file_dir_t *d, const char *name, struct stat *st, int32_t *e)
{
    int fd;
    if (!name_ok(name)) {
        *e = DAN_GW_FS_ENOENT;
        return -1;
    }
    fd = openat(d->dirfd, name, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    if (fd >= 0 && (fstat(fd, st) != 0 || !S_ISREG(st->st_mode))) {
        close(fd);
        fd = -1;
        errno = ENOENT; /* a FIFO, device or directory is no file here */
    }
    if (fd < 0) {
        *e = fs_error(d);
    }
    return fd;
}

/* Reads up to cap bytes at offset (short only at the end); count or -1. */
static ssize_t pread_full(int fd, uint8_t *buf, size_t cap, uint32_t offset)
{
    size_t got = 0;
    while (got < cap) {
        ssize_t r = pread(fd, buf + got, cap - got, (off_t)offset + (off_t)got);
        if (r < 0 && errno == EINTR) {
            continue;
        }
        if (r < 0) {
            return -1;
        }
        if (r == 0) {
            break;
        }
        got += (size_t)r;
    }
    return (ssize_t)got;
}

static int32_t size_cb(void *ctx, const char *name)
{
    struct stat st;
    int32_t e;
    int fd = open_file((dan_file_dir_t *)ctx, name, &st, &e);
    if (fd < 0) {
        return e;
    }
    close(fd);
    return st.st_size > (off_t)DAN_FILE_DIR_MAX_MAX ? DAN_GW_FS_EFBIG : (int32_t)st.st_size;
}

static int32_t read_cb(void *ctx, const char *name, uint32_t offset, uint8_t *buf, size_t cap)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    struct stat st;
    ssize_t n;
    int32_t e;
    int fd = open_file(d, name, &st, &e);
    if (fd < 0) {
        return e;
    }
    n = pread_full(fd, buf, cap > DAN_FILE_DIR_MAX_MAX ? DAN_FILE_DIR_MAX_MAX : cap, offset);
    e = n < 0 ? fs_error(d) : (int32_t)n;
    close(fd);
    return e;
}

/* A committed file of the listing: a valid name, a regular file the store
 * serves (one over DAN_FILE_DIR_MAX_MAX is FILE_TOO_LARGE to a reader). */
static bool listed(dan_file_dir_t *d, const char *name, uint32_t *size)
{
    struct stat st;
    if (!name_ok(name) || fstatat(d->dirfd, name, &st, AT_SYMLINK_NOFOLLOW) != 0 ||
        !S_ISREG(st.st_mode) || st.st_size > (off_t)DAN_FILE_DIR_MAX_MAX) {
        return false;
    }
    *size = (uint32_t)st.st_size;
    return true;
}

/* A stream over DIR (its own descriptor: closedir closes that one). */
static DIR *open_dir(dan_file_dir_t *d)
{
    int fd = openat(d->dirfd, ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    DIR *dir = fd >= 0 ? fdopendir(fd) : NULL;
    if (dir == NULL && fd >= 0) {
        close(fd);
    }
    return dir;
}

/* The index-th file in name order: the smallest name after the previous
 * one, index + 1 times over the directory (no allocation; a firmware
 * directory holds a handful of files). */
static int32_t list_cb(void *ctx, uint32_t index, char *name, size_t name_cap, uint32_t *size)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    char prev[DAN_GW_FILE_NAME_MAX + 1u] = "", best[DAN_GW_FILE_NAME_MAX + 1u];
    uint32_t best_size = 0, i;
    DIR *dir;
    if (name == NULL || name_cap < sizeof best || size == NULL) {
        return DAN_GW_FS_EIO;
    }
    dir = open_dir(d);
    if (dir == NULL) {
        return fs_error(d);
    }
    for (i = 0; i <= index; i++) {
        struct dirent *e;
        best[0] = '\0';
        rewinddir(dir);
        while ((e = readdir(dir)) != NULL) {
            uint32_t sz;
            if (strcmp(e->d_name, prev) > 0 && (best[0] == '\0' || strcmp(e->d_name, best) < 0) &&
                listed(d, e->d_name, &sz)) {
                memcpy(best, e->d_name, strlen(e->d_name) + 1u); /* listed: <= 32 */
                best_size = sz;
            }
        }
        if (best[0] == '\0') {
            closedir(dir);
            return DAN_GW_FS_ENOENT;
        }
        memcpy(prev, best, sizeof prev);
    }
    closedir(dir);
    memcpy(name, best, sizeof best);
    *size = best_size;
    return DAN_OK;
}

static int32_t remove_cb(void *ctx, const char *name)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    uint32_t size;
    if (!listed(d, name, &size)) {
        return DAN_GW_FS_ENOENT; /* only what list shows: no symlink, no directory */
    }
    return unlinkat(d->dirfd, name, 0) == 0 ? DAN_OK : fs_error(d);
}

/* "~name" of a partial. */
static void partial_path(const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%c%s", PARTIAL_MARK, name);
}

static void close_partial(dan_file_dir_t *d)
{
    if (d->up_fd >= 0) {
        close(d->up_fd);
    }
    d->up_fd = -1;
    d->up_len = 0;
    d->up_name[0] = '\0';
}

/* Removes every ~partial but ~keep (one upload at a time, also after a
 * restart that left another behind). */
static void remove_other_partials(dan_file_dir_t *d, const char *keep)
{
    DIR *dir = open_dir(d);
    struct dirent *e;
    if (dir == NULL) {
        return;
    }
    while ((e = readdir(dir)) != NULL) {
        if (e->d_name[0] == PARTIAL_MARK && name_ok(e->d_name + 1) &&
            strcmp(e->d_name + 1, keep) != 0) {
            (void)unlinkat(d->dirfd, e->d_name, 0);
        }
    }
    closedir(dir);
}

/* Opens (creates) the partial at path: a regular file with one link, or
 * -1. Anything else there (a symlink, FIFO, device, or a hard link to
 * another file, planted by whoever can write DIR) is removed and a file of
 * our own created in its place: never opened blocking, never truncated or
 * written through. */
static int open_partial(dan_file_dir_t *d, const char *path, struct stat *st)
{
    int flags = O_RDWR | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC;
    int fd = openat(d->dirfd, path, flags, FILE_MODE);
    if (fd >= 0 && fstat(fd, st) == 0 && S_ISREG(st->st_mode) && st->st_nlink == 1) {
        return fd;
    }
    if (fd >= 0) {
        close(fd);
    }
    if (unlinkat(d->dirfd, path, 0) != 0 && errno != ENOENT) {
        return -1;
    }
    fd = openat(d->dirfd, path, flags | O_EXCL, FILE_MODE);
    if (fd >= 0 && fstat(fd, st) != 0) {
        close(fd);
        fd = -1;
    }
    return fd;
}

static int32_t up_open_cb(void *ctx, const char *name, bool keep)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    char path[DAN_GW_FILE_NAME_MAX + 2u];
    struct stat st;
    if (!name_ok(name)) {
        return DAN_GW_FS_ENOENT;
    }
    close_partial(d);
    remove_other_partials(d, name);
    partial_path(name, path, sizeof path);
    d->up_fd = open_partial(d, path, &st);
    if (d->up_fd < 0) {
        return fs_error(d);
    }
    /* restart, or not one of ours (over the cap): start it again */
    if (!keep || st.st_size > (off_t)d->store.max_size) {
        if (ftruncate(d->up_fd, 0) != 0) {
            int32_t e = fs_error(d);
            close_partial(d);
            return e;
        }
        st.st_size = 0;
    }
    d->up_len = (uint32_t)st.st_size;
    snprintf(d->up_name, sizeof d->up_name, "%s", name);
    return (int32_t)d->up_len;
}

static int32_t up_write_cb(void *ctx, uint32_t offset, const uint8_t *data, size_t len)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    size_t done = 0;
    if (d->up_fd < 0) {
        return DAN_GW_FS_ENOENT;
    }
    if (offset > d->up_len) {
        return DAN_GW_FS_EIO; /* a gap: the node never asks for one */
    }
    if (len > d->store.max_size || offset > d->store.max_size - len) {
        return DAN_GW_FS_EFBIG;
    }
    while (done < len) {
        ssize_t w = pwrite(d->up_fd, data + done, len - done, (off_t)offset + (off_t)done);
        if (w < 0 && errno == EINTR) {
            continue;
        }
        if (w <= 0) {
            if (w == 0) {
                errno = EIO;
            }
            return fs_error(d);
        }
        done += (size_t)w;
    }
    if (offset + len > d->up_len) {
        d->up_len = (uint32_t)(offset + len);
    }
    return (int32_t)len;
}

static int32_t up_read_cb(void *ctx, uint32_t offset, uint8_t *buf, size_t cap)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    ssize_t n;
    if (d->up_fd < 0) {
        return DAN_GW_FS_ENOENT;
    }
    if (offset >= d->up_len) {
        return 0;
    }
    if (cap > d->up_len - offset) {
        cap = d->up_len - offset;
    }
    n = pread_full(d->up_fd, buf, cap, offset);
    return n < 0 ? fs_error(d) : (int32_t)n;
}

/* True when the store can take the partial as name: the files it holds
 * besides name, plus this one, within max_files and max_total. */
static bool room_for(dan_file_dir_t *d, const char *name)
{
    DIR *dir = open_dir(d);
    struct dirent *e;
    uint64_t total = d->up_len;
    uint32_t files = 1, size;
    if (dir == NULL) {
        return false;
    }
    while ((e = readdir(dir)) != NULL) {
        if (strcmp(e->d_name, name) != 0 && listed(d, e->d_name, &size)) {
            files++;
            total += size;
        }
    }
    closedir(dir);
    return files <= d->max_files && total <= d->max_total;
}

static int32_t up_commit_cb(void *ctx, const char *name)
{
    dan_file_dir_t *d = (dan_file_dir_t *)ctx;
    char path[DAN_GW_FILE_NAME_MAX + 2u];
    if (d->up_fd < 0) {
        return DAN_GW_FS_ENOENT;
    }
    if (!name_ok(name)) {
        return DAN_GW_FS_ENOENT;
    }
    if (!room_for(d, name)) {
        return DAN_GW_FS_ENOSPC; /* the partial stays: remove files, commit again */
    }
    partial_path(d->up_name, path, sizeof path);
    /* the bytes are on the medium before the name points at them */
    if (fsync(d->up_fd) != 0 || renameat(d->dirfd, path, d->dirfd, name) != 0) {
        return fs_error(d);
    }
    (void)fsync(d->dirfd);
    close_partial(d);
    return DAN_OK;
}

int dan_file_dir_open(dan_file_dir_t *d, const char *dir, uint32_t max_size, char *err,
                      size_t errlen)
{
    memset(d, 0, sizeof *d);
    d->dirfd = -1;
    d->up_fd = -1;
    d->max_total = DAN_FILE_DIR_DEFAULT_TOTAL;
    d->max_files = DAN_FILE_DIR_DEFAULT_FILES;
    if (max_size < 1u || max_size > DAN_FILE_DIR_MAX_MAX) {
        snprintf(err, errlen, "file size cap %u outside 1..%u", max_size, DAN_FILE_DIR_MAX_MAX);
        return -1;
    }
    d->dirfd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (d->dirfd < 0) {
        snprintf(err, errlen, "%s: %s", dir,
                 errno == ENOTDIR ? "not a directory" : strerror(errno));
        return -1;
    }
    if (faccessat(d->dirfd, ".", W_OK | X_OK, 0) != 0) {
        snprintf(err, errlen, "%s: not writable (uploads go there): %s", dir, strerror(errno));
        dan_file_dir_close(d);
        return -1;
    }
    d->store.size = size_cb;
    d->store.read = read_cb;
    d->store.list = list_cb;
    d->store.remove = remove_cb;
    d->store.up_open = up_open_cb;
    d->store.up_write = up_write_cb;
    d->store.up_read = up_read_cb;
    d->store.up_commit = up_commit_cb;
    d->store.ctx = d;
    d->store.max_size = max_size;
    return 0;
}

void dan_file_dir_close(dan_file_dir_t *d)
{
    close_partial(d);
    if (d->dirfd >= 0) {
        close(d->dirfd);
    }
    d->dirfd = -1;
}
