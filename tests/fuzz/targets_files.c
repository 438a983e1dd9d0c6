/* Fuzz targets of the file names and of the Linux directory store (see
 * targets.h): what decides which bytes of a path may name a file, and
 * whether the store stays inside its directory. Built into every libFuzzer
 * binary (tests/fuzz/fuzz.mk) and #included by the replay test
 * tests/unit/test_fuzz_regressions.c. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <unistd.h>

#include "dan/can_gw/file_store.h"
#include "dan/common.h"
#include "file_dir.h"
#include "targets.h"

/* ---- file names and DroneCAN paths ------------------------------------ */

/* The rule of dan/can_gw/file_store.h, written again from its text. */
static bool fzn_rule(const uint8_t *p, size_t n)
{
    size_t i;
    if (n < 1u || n > DAN_GW_FILE_NAME_MAX || p[0] == '.') {
        return false;
    }
    for (i = 0; i < n; i++) {
        uint8_t c = p[i];
        if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
              c == '.' || c == '_' || c == '-')) {
            return false;
        }
    }
    return true;
}

/* The whole input is a name (dan_gw_file_name_ok) and a DroneCAN path
 * (dan_gw_file_path_name). An accepted name has 1..32 bytes, none of them
 * '/', '\\', NUL or '~' (the partial mark), and does not start with '.'
 * (so it is never "." or ".." or hidden); a path gives the name after at
 * most one leading '/', NUL-terminated, and a refused one leaves the
 * output untouched. */
int dan_fuzz_file_names(const uint8_t *data, size_t len)
{
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    size_t skip = len > 0u && data[0] == '/' ? 1u : 0u, i;
    bool ok = dan_gw_file_name_ok((const char *)data, len);
    FUZZ_CHECK(ok == fzn_rule(data, len));
    if (ok) {
        FUZZ_CHECK(len <= DAN_GW_FILE_NAME_MAX && data[0] != '.');
        FUZZ_CHECK(memchr(data, '/', len) == NULL && memchr(data, '\\', len) == NULL);
        FUZZ_CHECK(memchr(data, '\0', len) == NULL && memchr(data, '~', len) == NULL);
    }
    memset(name, 0x5A, sizeof name);
    if (dan_gw_file_path_name(data, len, name)) {
        size_t n = strnlen(name, sizeof name);
        FUZZ_CHECK(n < sizeof name && n == len - skip && !memcmp(name, data + skip, n));
        FUZZ_CHECK(dan_gw_file_name_ok(name, n) && strchr(name, '/') == NULL && name[0] != '.');
    } else {
        for (i = 0; i < sizeof name; i++) {
            FUZZ_CHECK(name[i] == 0x5A);
        }
        FUZZ_CHECK(!fzn_rule(data + skip, len - skip));
    }
    return 0;
}

/* ---- the directory store (linux/file_dir.c) --------------------------- */

#define FZF_MAX   64u /* the store's cap per file: EFBIG within reach */
#define FZF_FILES 64u /* committed files the model follows */

/* A file of the model: what the directory must hold. */
typedef struct {
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    uint32_t len;
    uint8_t data[FZF_MAX];
} fzf_file_t;

/* The fixture inside the store's directory: entries of valid names that
 * are no files of the store (symlinks out, a directory), and a symlink
 * where the partial of "keep" would go. */
typedef enum { FZF_LINK, FZF_LINK_ABS, FZF_DIR } fzf_kind_t;
static const struct {
    const char *name, *target; /* FZF_LINK_ABS: the outside file's full path */
    fzf_kind_t kind;
} fzf_fixture[] = {
    {"link", "../outside/secret", FZF_LINK},
    {"dirlink", "../outside", FZF_LINK},
    {"abs", NULL, FZF_LINK_ABS},
    {"sub", NULL, FZF_DIR},
    {"~keep", "../outside/victim", FZF_LINK},
};
#define FZF_NFIX (sizeof fzf_fixture / sizeof fzf_fixture[0])

static struct {
    bool ready;
    char base[256], store[300], outside[300], abs_target[300];
    int ino;    /* inotify on outside/ and store/sub/ (fzf_check_quiet) */
    int wd_sub; /* the watch of store/sub */
    int nfd;    /* descriptors open between inputs */
    dan_file_dir_t d;
    fzf_file_t files[FZF_FILES];
    size_t nfiles;
    bool lost;      /* more files than the model follows: its checks stop */
    bool part_disk; /* ~part.name is in the directory */
    bool part_open; /* and is the store's open partial */
    fzf_file_t part;
} fzf;

/* Open descriptors below 256 (one fcntl each: cheaper than listing
 * /proc/self/fd; the store holds a few at a time). */
static int fzf_count_fds(void)
{
    int fd, n = 0;
    for (fd = 0; fd < 256; fd++) {
        n += fcntl(fd, F_GETFD) >= 0;
    }
    return n;
}

/* At exit: the fixture and whatever the last input left. */
static void fzf_remove_tree(void)
{
    char path[600];
    DIR *dp = opendir(fzf.store);
    struct dirent *e;
    dan_file_dir_close(&fzf.d);
    while (dp != NULL && (e = readdir(dp)) != NULL) {
        snprintf(path, sizeof path, "%s/%s", fzf.store, e->d_name);
        (void)unlink(path);
    }
    if (dp != NULL) {
        closedir(dp);
    }
    snprintf(path, sizeof path, "%s/sub", fzf.store);
    (void)rmdir(path);
    (void)rmdir(fzf.store);
    snprintf(path, sizeof path, "%s/secret", fzf.outside);
    (void)unlink(path);
    snprintf(path, sizeof path, "%s/victim", fzf.outside);
    (void)unlink(path);
    (void)rmdir(fzf.outside);
    (void)rmdir(fzf.base);
}

static void fzf_write_file(const char *rel, const char *text)
{
    char path[600];
    FILE *f;
    snprintf(path, sizeof path, "%s/%s", fzf.base, rel);
    f = fopen(path, "w");
    FUZZ_CHECK(f != NULL && fputs(text, f) >= 0 && fclose(f) == 0);
}

/* base/outside/{secret,victim}, base/store/ with the fixture, watched. */
static void fzf_setup(void)
{
    const char *tmp = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : getenv("TMPDIR");
    char path[600];
    snprintf(fzf.base, sizeof fzf.base, "%s/dan-fuzz-dir.XXXXXX", tmp != NULL ? tmp : "/tmp");
    FUZZ_CHECK(mkdtemp(fzf.base) != NULL);
    snprintf(fzf.outside, sizeof fzf.outside, "%s/outside", fzf.base);
    FUZZ_CHECK(mkdir(fzf.outside, 0700) == 0);
    snprintf(fzf.store, sizeof fzf.store, "%s/store", fzf.base);
    FUZZ_CHECK(mkdir(fzf.store, 0700) == 0);
    snprintf(path, sizeof path, "%s/store/sub", fzf.base);
    FUZZ_CHECK(mkdir(path, 0700) == 0);
    snprintf(fzf.abs_target, sizeof fzf.abs_target, "%s/outside/secret", fzf.base);
    fzf_write_file("outside/secret", "secret\n");
    fzf_write_file("outside/victim", "victim\n");
    fzf.ino = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    FUZZ_CHECK(fzf.ino >= 0);
    FUZZ_CHECK(inotify_add_watch(fzf.ino, fzf.outside, IN_ALL_EVENTS) >= 0);
    snprintf(path, sizeof path, "%s/store/sub", fzf.base);
    fzf.wd_sub = inotify_add_watch(fzf.ino, path, IN_ALL_EVENTS);
    FUZZ_CHECK(fzf.wd_sub >= 0);
    fzf.d.dirfd = -1;
    fzf.d.up_fd = -1;
    fzf.ready = true;
    atexit(fzf_remove_tree);
}

/* Nothing outside the store, nor inside store/sub, was opened, read,
 * written, created, removed or changed since the last look. Opening sub
 * itself is allowed (a read of "sub" opens it, sees a directory, says "no
 * such file"); reading its listing or anything in it is not. */
static void fzf_check_quiet(void)
{
    union {
        struct inotify_event e;
        char buf[4096];
    } u;
    const uint32_t self = IN_OPEN | IN_CLOSE_NOWRITE | IN_ISDIR;
    ssize_t n = read(fzf.ino, u.buf, sizeof u.buf), at = 0;
    FUZZ_CHECK(n > 0 || errno == EAGAIN);
    while (at < n) {
        const struct inotify_event *e = (const struct inotify_event *)(const void *)(u.buf + at);
        bool ok = e->wd == fzf.wd_sub && e->len == 0u && (e->mask & ~self) == 0u;
        if (!ok) {
            fprintf(stderr, "file_dir: event 0x%x on %s/%s\n", (unsigned)e->mask,
                    e->wd == fzf.wd_sub ? "store/sub" : "outside", e->len > 0u ? e->name : "");
        }
        FUZZ_CHECK(ok);
        at += (ssize_t)(sizeof *e + e->len);
    }
}

static int fzf_fixture_at(const char *name)
{
    size_t k;
    for (k = 0; k < FZF_NFIX; k++) {
        if (strcmp(fzf_fixture[k].name, name) == 0) {
            return (int)k;
        }
    }
    return -1;
}

static fzf_file_t *fzf_find(const char *name)
{
    size_t k;
    for (k = 0; k < fzf.nfiles; k++) {
        if (strcmp(fzf.files[k].name, name) == 0) {
            return &fzf.files[k];
        }
    }
    return NULL;
}

/* Is entry e of the store what the model says? */
static void fzf_check_entry(const char *name)
{
    struct stat st;
    const fzf_file_t *f = fzf_find(name);
    int fix = fzf_fixture_at(name);
    FUZZ_CHECK(fstatat(fzf.d.dirfd, name, &st, AT_SYMLINK_NOFOLLOW) == 0);
    if (fzf.lost) {
        return;
    }
    if (f != NULL) {
        FUZZ_CHECK(S_ISREG(st.st_mode) && st.st_size == (off_t)f->len);
    } else if (name[0] == '~' && fzf.part_disk && strcmp(name + 1, fzf.part.name) == 0) {
        FUZZ_CHECK(S_ISREG(st.st_mode) && st.st_size == (off_t)fzf.part.len);
    } else {
        /* only the fixture, as it was set up */
        FUZZ_CHECK(fix >= 0);
        FUZZ_CHECK(fzf_fixture[fix].kind == FZF_DIR ? S_ISDIR(st.st_mode) : S_ISLNK(st.st_mode));
    }
}

/* The directories hold exactly what they should: base only outside/ and
 * store/; the store its fixture, the model's files and partial. */
static void fzf_check_tree(void)
{
    char path[600];
    DIR *dp = opendir(fzf.base);
    struct dirent *e;
    size_t seen = 0;
    FUZZ_CHECK(dp != NULL);
    while ((e = readdir(dp)) != NULL) {
        FUZZ_CHECK(!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..") ||
                   !strcmp(e->d_name, "outside") || !strcmp(e->d_name, "store"));
    }
    closedir(dp);
    dp = opendir(fzf.store);
    FUZZ_CHECK(dp != NULL);
    while ((e = readdir(dp)) != NULL) {
        if (strcmp(e->d_name, ".") != 0 && strcmp(e->d_name, "..") != 0) {
            fzf_check_entry(e->d_name);
            seen += fzf_find(e->d_name) != NULL;
        }
    }
    closedir(dp);
    FUZZ_CHECK(fzf.lost || seen == fzf.nfiles); /* none of the model's files is missing */
    snprintf(path, sizeof path, "%s/outside/secret", fzf.base);
    FUZZ_CHECK(access(path, F_OK) == 0);
}

/* Back to the fixture alone, the store opened again. */
static void fzf_reset(void)
{
    char path[600];
    DIR *dp = opendir(fzf.store);
    struct dirent *e;
    size_t k;
    FUZZ_CHECK(dp != NULL);
    while ((e = readdir(dp)) != NULL) {
        if (e->d_name[0] != '.' && strcmp(e->d_name, "sub") != 0) {
            snprintf(path, sizeof path, "%s/%s", fzf.store, e->d_name);
            FUZZ_CHECK(unlink(path) == 0); /* the fixture's links are made again */
        }
    }
    closedir(dp);
    for (k = 0; k < FZF_NFIX; k++) {
        const char *target =
            fzf_fixture[k].kind == FZF_LINK_ABS ? fzf.abs_target : fzf_fixture[k].target;
        if (fzf_fixture[k].kind != FZF_DIR) {
            snprintf(path, sizeof path, "%s/%s", fzf.store, fzf_fixture[k].name);
            FUZZ_CHECK(symlink(target, path) == 0);
        }
    }
    memset(fzf.files, 0, sizeof fzf.files[0] * fzf.nfiles);
    fzf.nfiles = 0;
    fzf.lost = fzf.part_disk = fzf.part_open = false;
    memset(&fzf.part, 0, sizeof fzf.part);
    {
        char err[DAN_FILE_DIR_ERR_MAX];
        FUZZ_CHECK(dan_file_dir_open(&fzf.d, fzf.store, FZF_MAX, err, sizeof err) == 0);
        /* caps out of an input's reach (256 bytes make < 128 commits): the
         * model has none; the caps are tests/unit/test_file_dir.c's */
        fzf.d.max_files = DAN_FILE_DIR_FILES_MAX;
        fzf.d.max_total = UINT32_MAX;
    }
}

/* A name argument: a length byte; bit 7 picks one of the names below,
 * else (% 41) that many raw bytes, cut at a NUL as a C string is. */
static void fzf_name(const uint8_t *data, size_t len, size_t *i, char *out, size_t cap)
{
    static const char *const names[16] = {
        "a",       "b",    "fw.bin", "link",  "dirlink",           "abs",
        "sub",     "keep", "..",     ".",     "../outside/secret", "/etc/passwd",
        "outside", "~a",   "sub/x",  "link/x"};
    uint8_t n = *i < len ? data[(*i)++] : 0u;
    size_t k;
    if ((n & 0x80u) != 0u) {
        snprintf(out, cap, "%s", names[n % 16u]);
        return;
    }
    n = (uint8_t)(n % 41u);
    for (k = 0; k < n && *i < len && k + 1u < cap; k++) {
        out[k] = (char)data[(*i)++];
    }
    out[k] = '\0';
}

static bool fzf_valid(const char *name)
{
    return dan_gw_file_name_ok(name, strnlen(name, DAN_GW_FILE_NAME_MAX + 1u));
}

static uint32_t fzf_u16(const uint8_t *data, size_t len, size_t *i)
{
    uint32_t v = 0;
    size_t k;
    for (k = 0; k < 2u && *i < len; k++) {
        v |= (uint32_t)data[(*i)++] << (8u * k);
    }
    return v % 96u; /* offsets around the cap */
}

/* Committed file name in the model: size, read. */
static void fzf_op_read(bool sized, const char *name, uint32_t off, size_t cap)
{
    static uint8_t buf[DAN_GW_FILE_READ_MAX];
    const fzf_file_t *f = fzf_valid(name) ? fzf_find(name) : NULL;
    int32_t r = sized ? fzf.d.store.size(fzf.d.store.ctx, name)
                      : fzf.d.store.read(fzf.d.store.ctx, name, off, buf, cap);
    if (fzf.lost) {
        return;
    }
    if (f == NULL) {
        FUZZ_CHECK(r == DAN_GW_FS_ENOENT); /* a symlink, directory or bad name included */
    } else if (sized) {
        FUZZ_CHECK(r == (int32_t)f->len);
    } else {
        size_t want = off >= f->len ? 0u : (f->len - off < cap ? f->len - off : cap);
        FUZZ_CHECK(r == (int32_t)want && (want == 0u || !memcmp(buf, f->data + off, want)));
    }
}

static void fzf_op_list(uint32_t index)
{
    char name[DAN_GW_FILE_NAME_MAX + 1u], prev[DAN_GW_FILE_NAME_MAX + 1u] = "";
    const fzf_file_t *want = NULL;
    uint32_t size = 0, k;
    int32_t r = fzf.d.store.list(fzf.d.store.ctx, index, name, sizeof name, &size);
    size_t j;
    if (fzf.lost) {
        return;
    }
    for (k = 0; k <= index; k++) { /* the index-th smallest name of the model */
        want = NULL;
        for (j = 0; j < fzf.nfiles; j++) {
            const fzf_file_t *f = &fzf.files[j];
            if (strcmp(f->name, prev) > 0 && (want == NULL || strcmp(f->name, want->name) < 0)) {
                want = f;
            }
        }
        if (want == NULL) {
            break;
        }
        memcpy(prev, want->name, sizeof prev);
    }
    if (want == NULL) {
        FUZZ_CHECK(r == DAN_GW_FS_ENOENT);
    } else {
        FUZZ_CHECK(r == DAN_OK && !strcmp(name, want->name) && size == want->len);
    }
}

static void fzf_op_remove(const char *name)
{
    fzf_file_t *f = fzf_valid(name) ? fzf_find(name) : NULL;
    int32_t r = fzf.d.store.remove(fzf.d.store.ctx, name);
    if (fzf.lost) {
        return;
    }
    FUZZ_CHECK(r == (f != NULL ? DAN_OK : DAN_GW_FS_ENOENT));
    if (f != NULL) {
        *f = fzf.files[--fzf.nfiles];
    }
}

static void fzf_op_open(const char *name, bool keep)
{
    int32_t r = fzf.d.store.up_open(fzf.d.store.ctx, name, keep);
    if (!fzf_valid(name)) {
        FUZZ_CHECK(r == DAN_GW_FS_ENOENT); /* refused before anything changed */
        return;
    }
    /* the fixture's ~keep (a symlink out) goes as another upload's partial
     * does, or is replaced by a file of our own: never opened through (the
     * watch on outside/ says so) */
    if (!(keep && fzf.part_disk && !strcmp(fzf.part.name, name))) {
        memset(&fzf.part, 0, sizeof fzf.part);
        memcpy(fzf.part.name, name, strlen(name) + 1u); /* valid: <= 32 bytes */
    }
    FUZZ_CHECK(r == (int32_t)fzf.part.len);
    fzf.part_open = fzf.part_disk = true;
}

static void fzf_op_write(uint32_t off, const uint8_t *p, size_t n)
{
    int32_t r = fzf.d.store.up_write(fzf.d.store.ctx, off, p, n);
    if (!fzf.part_open) {
        FUZZ_CHECK(r == DAN_GW_FS_ENOENT);
    } else if (off > fzf.part.len || n > FZF_MAX || off > FZF_MAX - n) {
        FUZZ_CHECK(r < 0); /* a gap or over the cap: nothing written */
    } else {
        FUZZ_CHECK(r == (int32_t)n);
        memcpy(fzf.part.data + off, p, n);
        if (off + n > fzf.part.len) {
            fzf.part.len = (uint32_t)(off + n);
        }
    }
}

static void fzf_op_read_partial(uint32_t off, size_t cap)
{
    uint8_t buf[FZF_MAX + 32u];
    int32_t r = fzf.d.store.up_read(fzf.d.store.ctx, off, buf, cap);
    size_t want;
    if (!fzf.part_open) {
        FUZZ_CHECK(r == DAN_GW_FS_ENOENT);
        return;
    }
    want = off >= fzf.part.len ? 0u : (fzf.part.len - off < cap ? fzf.part.len - off : cap);
    FUZZ_CHECK(r == (int32_t)want && (want == 0u || !memcmp(buf, fzf.part.data + off, want)));
}

static void fzf_op_commit(const char *name)
{
    int32_t r = fzf.d.store.up_commit(fzf.d.store.ctx, name);
    fzf_file_t *f;
    if (!fzf.part_open || !fzf_valid(name)) {
        FUZZ_CHECK(r == DAN_GW_FS_ENOENT);
        return;
    }
    if (!strcmp(name, "sub")) {
        FUZZ_CHECK(r < 0); /* a directory is not replaced; the partial stays */
        return;
    }
    FUZZ_CHECK(r == DAN_OK); /* over a symlink too: the link itself is replaced */
    f = fzf_find(name);
    if (f == NULL && fzf.nfiles == FZF_FILES) {
        fzf.lost = true;
        return;
    }
    if (f == NULL) {
        f = &fzf.files[fzf.nfiles++];
    }
    *f = fzf.part;
    memcpy(f->name, name, strlen(name) + 1u);
    fzf.part_open = fzf.part_disk = false;
}

/* One operation (op % 8) and its arguments. */
static void fzf_op(uint8_t op, const uint8_t *data, size_t len, size_t *i)
{
    char name[48];
    uint32_t off;
    size_t n;
    switch (op % 8u) {
    case 0:
    case 1:
        fzf_name(data, len, i, name, sizeof name);
        off = fzf_u16(data, len, i);
        fzf_op_read(op % 8u == 0u, name, off, (size_t)(op >> 3) * 9u); /* cap 0..279 */
        break;
    case 2: fzf_op_list((uint32_t)(op >> 3) % 8u); break;
    case 3:
        fzf_name(data, len, i, name, sizeof name);
        fzf_op_remove(name);
        break;
    case 4:
        fzf_name(data, len, i, name, sizeof name);
        fzf_op_open(name, (op & 8u) != 0u);
        break;
    case 5:
        off = fzf_u16(data, len, i);
        n = (size_t)(op >> 3) * 3u; /* 0..93 bytes */
        n = n < len - *i ? n : len - *i;
        fzf_op_write(off, data + *i, n);
        *i += n;
        break;
    case 6:
        off = fzf_u16(data, len, i);
        fzf_op_read_partial(off, (size_t)(op >> 3) * 3u);
        break;
    default:
        fzf_name(data, len, i, name, sizeof name);
        fzf_op_commit(name);
        break;
    }
}

/* A script of store calls with names of any bytes, on a directory whose
 * fixture has symlinks out (relative and absolute, and one where a partial
 * would go) and a subdirectory, next to an outside/ directory:
 *   op % 8 == 0, 1  size / read (name, u16 offset; read cap (op >> 3) * 9)
 *            2      list (index (op >> 3) % 8)
 *            3      remove (name)
 *            4      up_open (name; keep: op bit 3)
 *            5      up_write (u16 offset, (op >> 3) * 3 bytes)
 *            6      up_read (u16 offset, cap (op >> 3) * 3)
 *            7      up_commit (name)
 * a name is fzf_name's. After each call nothing outside the store (nor in
 * store/sub) was touched (inotify), the answers match a model of the
 * files; after the script the directories hold exactly the fixture, the
 * model's files and its partial, and no descriptor is left open. */
int dan_fuzz_file_dir(const uint8_t *data, size_t len)
{
    size_t i = 0;
    int nfd;
    if (!fzf.ready) {
        fzf_setup();
    }
    nfd = fzf_count_fds();
    fzf_reset();
    fzf_check_quiet();
    while (i < len) {
        fzf_op(data[i++], data, len, &i);
        fzf_check_quiet();
    }
    fzf_check_tree();
    dan_file_dir_close(&fzf.d);
    FUZZ_CHECK(fzf_count_fds() == nfd); /* the store left no descriptor open */
    return 0;
}
