/* A file store in RAM for the unit tests (see file_store_ram.h). */
#include <string.h>

#include "file_store_ram.h"

/* Counts the call; true when an injected fault makes it fail. */
static bool broken(ram_store_t *s)
{
    s->calls++;
    return s->fail_from != 0u && s->calls >= s->fail_from;
}

static ram_file_t *find(ram_store_t *s, const char *name)
{
    size_t i;
    for (i = 0; i < RAM_FILES; i++) {
        if (s->files[i].used && strcmp(s->files[i].name, name) == 0) {
            return &s->files[i];
        }
    }
    return NULL;
}

const ram_file_t *ram_store_file(const ram_store_t *s, const char *name)
{
    return find((ram_store_t *)s, name);
}

static int32_t copy_out(const ram_file_t *f, uint32_t offset, uint8_t *buf, size_t cap)
{
    size_t n;
    if (offset >= f->len) {
        return 0;
    }
    n = f->len - offset < cap ? f->len - offset : cap;
    memcpy(buf, f->data + offset, n);
    return (int32_t)n;
}

static int32_t r_size(void *ctx, const char *name)
{
    ram_store_t *s = ctx;
    const ram_file_t *f = find(s, name);
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    return f != NULL ? (int32_t)f->len : DAN_GW_FS_ENOENT;
}

static int32_t r_read(void *ctx, const char *name, uint32_t offset, uint8_t *buf, size_t cap)
{
    ram_store_t *s = ctx;
    const ram_file_t *f = find(s, name);
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    return f != NULL ? copy_out(f, offset, buf, cap) : DAN_GW_FS_ENOENT;
}

/* Name order: the index-th smallest name. */
static int32_t r_list(void *ctx, uint32_t index, char *name, size_t name_cap, uint32_t *size)
{
    ram_store_t *s = ctx;
    size_t i, j;
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    for (i = 0; i < RAM_FILES; i++) {
        uint32_t below = 0;
        if (!s->files[i].used) {
            continue;
        }
        for (j = 0; j < RAM_FILES; j++) {
            below += s->files[j].used && strcmp(s->files[j].name, s->files[i].name) < 0;
        }
        if (below == index && name_cap > strlen(s->files[i].name)) {
            strcpy(name, s->files[i].name);
            *size = s->files[i].len;
            return DAN_OK;
        }
    }
    return DAN_GW_FS_ENOENT;
}

static int32_t r_remove(void *ctx, const char *name)
{
    ram_store_t *s = ctx;
    ram_file_t *f = find(s, name);
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    if (f == NULL) {
        return DAN_GW_FS_ENOENT;
    }
    f->used = false;
    return DAN_OK;
}

static int32_t r_up_open(void *ctx, const char *name, bool keep)
{
    ram_store_t *s = ctx;
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    if (!(keep && s->partial.used && strcmp(s->partial.name, name) == 0)) {
        memset(&s->partial, 0, sizeof s->partial);
        s->partial.used = true;
        strcpy(s->partial.name, name);
    }
    return (int32_t)s->partial.len;
}

static int32_t r_up_write(void *ctx, uint32_t offset, const uint8_t *data, size_t len)
{
    ram_store_t *s = ctx;
    s->writes++;
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    if (!s->partial.used || offset > s->partial.len || offset + len > RAM_FILE_CAP) {
        return DAN_GW_FS_EFBIG; /* the node broke the contract: the test sees it */
    }
    memcpy(s->partial.data + offset, data, len);
    if (offset + len > s->partial.len) {
        s->partial.len = (uint32_t)(offset + len);
    }
    return DAN_OK;
}

static int32_t r_up_read(void *ctx, uint32_t offset, uint8_t *buf, size_t cap)
{
    ram_store_t *s = ctx;
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    return s->partial.used ? copy_out(&s->partial, offset, buf, cap) : DAN_GW_FS_ENOENT;
}

static int32_t r_up_commit(void *ctx, const char *name)
{
    ram_store_t *s = ctx;
    ram_file_t *f = find(s, name);
    size_t i;
    if (broken(s)) {
        return DAN_GW_FS_EIO;
    }
    if (!s->partial.used || strcmp(s->partial.name, name) != 0) {
        return DAN_GW_FS_ENOENT;
    }
    for (i = 0; f == NULL && i < RAM_FILES; i++) {
        f = !s->files[i].used ? &s->files[i] : NULL;
    }
    if (f == NULL) {
        return DAN_GW_FS_ENOSPC;
    }
    *f = s->partial; /* replaces an older one whole */
    memset(&s->partial, 0, sizeof s->partial);
    return DAN_OK;
}

void ram_store_init(ram_store_t *s)
{
    memset(s, 0, sizeof *s);
    s->fs.size = r_size;
    s->fs.read = r_read;
    s->fs.list = r_list;
    s->fs.remove = r_remove;
    s->fs.up_open = r_up_open;
    s->fs.up_write = r_up_write;
    s->fs.up_read = r_up_read;
    s->fs.up_commit = r_up_commit;
    s->fs.ctx = s;
    s->fs.max_size = RAM_FILE_CAP;
}
