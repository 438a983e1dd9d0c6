/* The gateway's DroneCAN file server (gw_node_file.c) through the node:
 * file.Read at 0, in the middle, the last partial chunk, at and past the
 * end, a missing file, bad paths (never handed to the store), a store
 * failure, GetInfo, two requests in flight, no store (not answered), the
 * reader's progress in its node table slot; and the node table asking
 * GetNodeInfo again after an update (mode SOFTWARE_UPDATE -> OPERATIONAL,
 * uptime down). The reads run twice: on a one-file fake store in RAM (it
 * counts its calls and can fail) and on the directory store of
 * dan-gatewayd (file_dir.c) in a mkdtemp() directory, where a symlink out
 * of it is refused. */
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

#include "dan/codes.h"
#include "file_dir.h"
#include "gw_rig.h"
#include "hostile_paths.h"
#include "unit_run.h"

#define IMG_SIZE 600u

static uint8_t img[IMG_SIZE];
static int calls;   /* store callbacks called */
static bool broken; /* the medium fails */

static int32_t fake_size(void *ctx, const char *name)
{
    (void)ctx;
    calls++;
    if (broken) {
        return DAN_GW_FS_EIO;
    }
    if (strcmp(name, "huge.bin") == 0) {
        return DAN_GW_FS_EFBIG; /* over what the store serves */
    }
    return strcmp(name, "fw.bin") == 0 ? (int32_t)IMG_SIZE : DAN_GW_FS_ENOENT;
}

static int32_t fake_read(void *ctx, const char *name, uint32_t off, uint8_t *buf, size_t cap)
{
    size_t n;
    (void)ctx;
    calls++;
    if (strcmp(name, "fw.bin") != 0) {
        return DAN_GW_FS_ENOENT;
    }
    n = off >= IMG_SIZE ? 0u : IMG_SIZE - off;
    n = n < cap ? n : cap;
    memcpy(buf, img + off, n);
    return (int32_t)n;
}

static const dan_gw_file_store_t fake = {fake_size, fake_read, NULL, NULL, NULL,
                                         NULL,      NULL,      NULL, NULL, 4096u};

static dan_file_dir_t store_dir;
static char dir[64];

static int setup_files(void **state)
{
    size_t i;
    int r = setup(state);
    for (i = 0; i < IMG_SIZE; i++) {
        img[i] = (uint8_t)(i * 31u + 7u);
    }
    calls = 0;
    broken = false;
    R->g.cfg.files = &fake;
    return r;
}

/* The same image as DIR/fw.bin, served by the directory store. */
static int setup_dir(void **state)
{
    char path[128], err[DAN_FILE_DIR_ERR_MAX];
    FILE *f;
    int r = setup_files(state);
    snprintf(dir, sizeof dir, "/tmp/dan_file_server_XXXXXX");
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/fw.bin", dir);
    f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(img, 1, IMG_SIZE, f), IMG_SIZE);
    fclose(f);
    assert_int_equal(dan_file_dir_open(&store_dir, dir, 4096u, err, sizeof err), 0);
    R->g.cfg.files = &store_dir.store;
    return r;
}

static int teardown_dir(void **state)
{
    char cmd[160];
    dan_file_dir_close(&store_dir);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
    return teardown(state);
}

/* Reads offset of path as node 42 (the listener): the response, decoded. */
static void read_at(uint64_t offset, const char *path, dan_dc_file_read_rsp_t *r)
{
    size_t from = R->ncap;
    cap_t *c;
    file_read_from(LISTEN_NODE, offset, path);
    drain();
    c = expect_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, &from);
    assert_int_equal(c->src, 10);
    assert_int_equal(c->dst, LISTEN_NODE);
    assert_int_equal(dan_dc_file_read_rsp_decode(r, c->payload, c->len), DAN_OK);
}

/* Node id's slot of the node table, or NULL. */
static dan_gw_node_slot_t *slot(uint8_t id)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        if (R->g.nodes[i].e.node_id == id) {
            return &R->g.nodes[i];
        }
    }
    return NULL;
}

static void get_info(const char *path, dan_dc_file_getinfo_rsp_t *r);

static void node_status(uint8_t src, uint32_t uptime, uint8_t mode)
{
    node_status_from(src, uptime, DAN_DC_HEALTH_OK, mode);
}

static void test_read_chunks(void **state)
{
    static dan_dc_file_read_rsp_t r;
    const dan_gw_node_fw_t *fw;
    (void)state;
    node_status(LISTEN_NODE, 5, DAN_DC_MODE_SOFTWARE_UPDATE);
    fw = &slot(LISTEN_NODE)->fw;
    assert_int_equal(fw->flags, 0);
    read_at(0, "/fw.bin", &r);
    assert_int_equal(r.error, 0);
    assert_int_equal(r.data_len, 256);
    assert_memory_equal(r.data, img, 256);
    assert_int_equal(fw->flags, DAN_GW_FW_READING);
    assert_int_equal(fw->bytes_read, 256);
    assert_int_equal(fw->file_size, IMG_SIZE);
    assert_int_equal(fw->last_read_us, R->bus.now);
    read_at(300, "fw.bin", &r); /* any offset, no leading '/' */
    assert_int_equal(r.data_len, 256);
    assert_memory_equal(r.data, img + 300, 256);
    assert_int_equal(fw->bytes_read, 556);
    read_at(100, "fw.bin", &r); /* lower: bytes_read stays the highest */
    assert_int_equal(fw->bytes_read, 556);
    read_at(512, "fw.bin", &r); /* the last chunk is short: the end */
    assert_int_equal(r.error, 0);
    assert_int_equal(r.data_len, IMG_SIZE - 512u);
    assert_memory_equal(r.data, img + 512, IMG_SIZE - 512u);
    assert_int_equal(fw->bytes_read, IMG_SIZE);
    read_at(IMG_SIZE, "fw.bin", &r); /* at and past the end: OK, no data */
    assert_int_equal(r.error, 0);
    assert_int_equal(r.data_len, 0);
    read_at(0xFFFFFFFFFFull, "fw.bin", &r);
    assert_int_equal(r.error, 0);
    assert_int_equal(r.data_len, 0);
    assert_int_equal(fw->bytes_read, IMG_SIZE);
    read_at(0, "fw.bin", &r); /* from 0 again: a new pass */
    assert_int_equal(fw->bytes_read, 256);
    assert_int_equal(R->g.stats.file_reads, 7);
    assert_int_equal(R->g.stats.file_bytes, 256u * 4u + 88u);
    assert_int_equal(R->g.stats.file_errors, 0);
}

static void test_read_errors(void **state)
{
    static dan_dc_file_read_rsp_t r;
    size_t i;
    (void)state;
    read_at(0, "/nope.bin", &r);
    assert_int_equal(r.error, DAN_DC_FILE_NOT_FOUND);
    assert_int_equal(r.data_len, 0);
    calls = 0;
    for (i = 0; i < HOSTILE_PATH_COUNT; i++) {
        read_at(0, HOSTILE_PATHS[i], &r);
        assert_int_equal(r.error, DAN_DC_FILE_INVALID_VALUE);
        assert_int_equal(r.data_len, 0);
    }
    assert_int_equal(calls, 0); /* never handed to the store */
    assert_int_equal(R->g.stats.file_errors, 1u + HOSTILE_PATH_COUNT);
    assert_int_equal(R->g.stats.file_reads, 0);
}

static void test_store_failure(void **state)
{
    static dan_dc_file_read_rsp_t r;
    (void)state;
    broken = true;
    read_at(0, "fw.bin", &r);
    assert_int_equal(r.error, DAN_DC_FILE_IO_ERROR);
    assert_int_equal(r.data_len, 0);
    assert_int_equal(R->g.stats.file_errors, 1);
    /* the reader is not in the node table: nothing noted, nothing broken */
    assert_null(slot(LISTEN_NODE));
}

/* DIR/evil -> a file outside DIR: never followed (not found), and a
 * FIFO of a valid name is no file either. */
static void test_dir_symlink_out(void **state)
{
    static dan_dc_file_read_rsp_t r;
    dan_dc_file_getinfo_rsp_t i;
    char path[128];
    (void)state;
    snprintf(path, sizeof path, "%s/evil", dir);
    assert_int_equal(symlink("/etc/hostname", path), 0);
    snprintf(path, sizeof path, "%s/link.bin", dir);
    assert_int_equal(symlink("fw.bin", path), 0); /* even inside DIR */
    read_at(0, "evil", &r);
    assert_int_equal(r.error, DAN_DC_FILE_NOT_FOUND);
    assert_int_equal(r.data_len, 0);
    read_at(0, "/link.bin", &r);
    assert_int_equal(r.error, DAN_DC_FILE_NOT_FOUND);
    get_info("evil", &i);
    assert_int_equal(i.error, DAN_DC_FILE_NOT_FOUND);
    snprintf(path, sizeof path, "%s/pipe", dir);
    assert_int_equal(mkfifo(path, 0600), 0);
    read_at(0, "pipe", &r); /* opened without blocking, refused */
    assert_int_equal(r.error, DAN_DC_FILE_NOT_FOUND);
    read_at(0, "fw.bin", &r);
    assert_int_equal(r.error, 0);
    assert_memory_equal(r.data, img, 256);
}

/* NUL inside a path's bytes: a different name, refused. */
static void test_read_nul_path(void **state)
{
    static dan_dc_file_read_rsp_t r;
    (void)state;
    read_at(0, "fw.bin", &r);
    assert_int_equal(r.data_len, 256);
    {
        static const uint8_t req[] = {0, 0, 0, 0, 0, 'f', 'w', 0, '.', 'b', 'i', 'n'};
        size_t from = R->ncap;
        cap_t *c;
        inject(LISTEN_NODE, DAN_DC_FILE_READ_ID, DAN_DC_FILE_READ_SIGNATURE,
               DAN_DC_TRANSFER_REQUEST, 10, req, (int)sizeof req);
        drain();
        c = expect_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, &from);
        assert_int_equal(dan_dc_file_read_rsp_decode(&r, c->payload, c->len), DAN_OK);
        assert_int_equal(r.error, DAN_DC_FILE_INVALID_VALUE);
    }
}

static void get_info(const char *path, dan_dc_file_getinfo_rsp_t *r)
{
    dan_dc_file_req_t q;
    uint8_t buf[DAN_DC_FILE_GETINFO_REQ_MAX_SIZE];
    size_t from = R->ncap;
    cap_t *c;
    memset(&q, 0, sizeof q);
    q.path_len = (uint8_t)strlen(path);
    memcpy(q.path, path, q.path_len);
    inject(LISTEN_NODE, DAN_DC_FILE_GETINFO_ID, DAN_DC_FILE_GETINFO_SIGNATURE,
           DAN_DC_TRANSFER_REQUEST, 10, buf, dan_dc_file_getinfo_req_encode(&q, buf, sizeof buf));
    drain();
    c = expect_cap(DAN_DC_FILE_GETINFO_ID, DAN_DC_TRANSFER_RESPONSE, &from);
    assert_int_equal(dan_dc_file_getinfo_rsp_decode(r, c->payload, c->len), DAN_OK);
}

static void test_getinfo_dir(void **state)
{
    dan_dc_file_getinfo_rsp_t r;
    (void)state;
    get_info("/fw.bin", &r);
    assert_int_equal(r.error, 0);
    assert_int_equal(r.size, IMG_SIZE);
    assert_int_equal(r.entry_type, DAN_DC_FILE_FLAG_FILE | DAN_DC_FILE_FLAG_READABLE);
    get_info("other.bin", &r);
    assert_int_equal(r.error, DAN_DC_FILE_NOT_FOUND);
    assert_int_equal(r.size, 0);
    assert_int_equal(r.entry_type, 0);
    get_info("../fw.bin", &r);
    assert_int_equal(r.error, DAN_DC_FILE_INVALID_VALUE);
}

static void test_getinfo(void **state)
{
    dan_dc_file_getinfo_rsp_t r;
    test_getinfo_dir(state);
    get_info("huge.bin", &r); /* file.Error FILE_TOO_LARGE, not an I/O error */
    assert_int_equal(r.error, DAN_DC_FILE_TOO_LARGE);
    assert_int_equal(r.size, 0);
    broken = true;
    get_info("fw.bin", &r);
    assert_int_equal(r.error, DAN_DC_FILE_IO_ERROR);
}

/* Reads in flight before the bus drains: each answered with its own
 * transfer ID and data, in order. Three 38-frame answers fill the bulk
 * queue; the next ones wait for room (nothing dropped) and go out as it
 * drains; a request that waited too long is dropped (its reader has
 * asked again by then), as is one beyond the wait list. */
static void test_reads_in_flight(void **state)
{
    static dan_dc_file_read_rsp_t r;
    size_t from = R->ncap;
    uint8_t tid0 = 0;
    cap_t *c;
    int i;
    (void)state;
    advance(10000); /* our own timers in the future */
    from = R->ncap;
    for (i = 0; i < 5; i++) {
        file_read_from(LISTEN_NODE, (uint64_t)(i % 2) * 256u, "fw.bin"); /* 256 bytes each */
    }
    assert_int_equal(R->g.file_nwait, 2);
    assert_int_equal(R->g.stats.can_tx_dropped, 0);
    assert_true(dan_gw_node_next_us(&R->g, R->bus.now) > R->bus.now); /* no room yet */
    drain();
    assert_int_equal(dan_gw_node_next_us(&R->g, R->bus.now), R->bus.now); /* room now */
    advance(1000);
    assert_int_equal(R->g.file_nwait, 0);
    for (i = 0; i < 5; i++) {
        c = expect_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, &from);
        if (i == 0) {
            tid0 = c->tid;
        }
        assert_int_equal(c->tid, (tid0 + (unsigned)i) & 31u);
        assert_int_equal(dan_dc_file_read_rsp_decode(&r, c->payload, c->len), DAN_OK);
        assert_int_equal(r.data_len, 256);
        assert_memory_equal(r.data, img + (i % 2) * 256, 256);
    }
    assert_int_equal(R->g.stats.file_reads, 5);
    assert_int_equal(R->g.stats.can_tx_dropped, 0);
    /* 3 answered, 8 wait, 1 dropped; then the 8 go stale */
    for (i = 0; i < 12; i++) {
        file_read_from((uint8_t)(60 + i), 0, "fw.bin");
    }
    assert_int_equal(R->g.file_nwait, DAN_GW_NODE_FILE_WAIT);
    assert_int_equal(R->g.stats.file_dropped, 1);
    dan_gw_node_poll(&R->g, R->bus.now + DAN_GW_NODE_FILE_WAIT_US + 1u);
    assert_int_equal(R->g.file_nwait, 0);
    assert_int_equal(R->g.stats.file_dropped, 1u + DAN_GW_NODE_FILE_WAIT);
    assert_int_equal(R->g.stats.file_reads, 8);
    assert_int_equal(R->g.stats.can_tx_dropped, 0);
}

static void test_no_store(void **state)
{
    size_t from = R->ncap;
    (void)state;
    R->g.cfg.files = NULL;
    file_read_from(LISTEN_NODE, 0, "fw.bin");
    drain();
    assert_null(find_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, &from));
    assert_int_equal(calls, 0);
}

static uint8_t info_state(void)
{
    return slot(LISTEN_NODE)->e.info_state;
}

/* GetNodeInfo answered by node 42 with software version major.minor. */
static void answer_info(uint8_t major, uint8_t minor)
{
    static dan_dc_get_node_info_rsp_t info;
    uint8_t buf[DAN_DC_GET_NODE_INFO_RSP_MAX_SIZE];
    memset(&info, 0, sizeof info);
    info.software_version.major = major;
    info.software_version.minor = minor;
    inject(LISTEN_NODE, DAN_DC_GET_NODE_INFO_ID, DAN_DC_GET_NODE_INFO_SIGNATURE,
           DAN_DC_TRANSFER_RESPONSE, 10, buf,
           dan_dc_get_node_info_rsp_encode(&info, buf, sizeof buf));
}

static int info_requests_since(size_t from)
{
    int n = 0;
    while (find_cap(DAN_DC_GET_NODE_INFO_ID, DAN_DC_TRANSFER_REQUEST, &from) != NULL) {
        n++;
    }
    return n;
}

static void test_info_after_update(void **state)
{
    const dan_gw_node_slot_t *n;
    size_t from;
    (void)state;
    node_status(LISTEN_NODE, 100, DAN_DC_MODE_OPERATIONAL);
    advance(10000);
    answer_info(1, 0);
    n = slot(LISTEN_NODE);
    assert_int_equal(info_state(), DAN_GW_INFO_VALID);
    /* the update: SOFTWARE_UPDATE with its uptime counting on (no restart
     * seen), then OPERATIONAL: asked again, the new version shows */
    node_status(LISTEN_NODE, 101, DAN_DC_MODE_SOFTWARE_UPDATE);
    from = R->ncap;
    advance(10000);
    assert_int_equal(info_requests_since(from), 0);
    assert_int_equal(info_state(), DAN_GW_INFO_VALID);
    node_status(LISTEN_NODE, 102, DAN_DC_MODE_OPERATIONAL);
    from = R->ncap;
    advance(10000);
    assert_int_equal(info_requests_since(from), 1);
    assert_int_equal(info_state(), DAN_GW_INFO_PENDING);
    answer_info(2, 1);
    assert_int_equal(info_state(), DAN_GW_INFO_VALID);
    assert_int_equal(n->info.sw_major, 2);
    assert_int_equal(n->info.sw_minor, 1);
    /* a restart (uptime down) in OPERATIONAL: asked again too */
    node_status(LISTEN_NODE, 0, DAN_DC_MODE_OPERATIONAL);
    from = R->ncap;
    advance(10000);
    assert_int_equal(info_requests_since(from), 1);
    answer_info(2, 2);
    assert_int_equal(n->info.sw_minor, 2);
    /* OPERATIONAL after OPERATIONAL, uptime up: not asked */
    node_status(LISTEN_NODE, 5, DAN_DC_MODE_OPERATIONAL);
    from = R->ncap;
    advance(10000);
    assert_int_equal(info_requests_since(from), 0);
    assert_false(n->duplicate);
}

/* Tunnel bytes coming faster than CAN takes them keep the bulk queue
 * topped up to 19 free frames; a file.Read answer needs 38 and never found
 * room: it waited its second and was dropped (a node's firmware update
 * stalled beside a busy tunnel; review finding). While a file request
 * waits, the tunnel leaves room for one answer. */
static void test_read_beside_a_busy_tunnel(void **state)
{
    static uint8_t data[128];
    size_t from, i;
    bool answered = false;
    (void)state;
    call_ok(tunnel_open_start(0, DAN_GW_TUN_TARGETTED, DAN_DC_TUNNEL_UNDEFINED, 20, 1, 0, 0));
    for (i = 0; i < 8; i++) { /* the bus stalled: the tunnel fills the bulk queue */
        assert_int_equal(dan_gw_tunnel_xfer(&R->gw, 0, data, sizeof data, 0, R->bus.now), DAN_OK);
        assert_int_equal(finish_stalled(), DAN_OK);
    }
    from = R->ncap;
    file_read_from(LISTEN_NODE, 0, "fw.bin");
    for (i = 0; i < 30 && !answered; i++) {
        assert_int_equal(dan_gw_tunnel_xfer(&R->gw, 0, data, sizeof data, 0, R->bus.now), DAN_OK);
        assert_int_equal(finish_stalled(), DAN_OK); /* DAN outruns CAN */
        (void)send_frames(20);
        R->bus.now += 5000u;
        dan_gw_node_poll(&R->g, R->bus.now);
        answered = find_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, &from) != NULL;
    }
    drain();
    answered = answered || find_cap(DAN_DC_FILE_READ_ID, DAN_DC_TRANSFER_RESPONSE, &from) != NULL;
    assert_true(answered);
    assert_true(i < 30);
    assert_int_equal(R->g.stats.file_dropped, 0);
}

int main(void)
{
    int failed =
        UNIT_RUN("file_server", setup_files, teardown, test_read_chunks, test_read_errors,
                 test_store_failure, test_read_nul_path, test_getinfo, test_reads_in_flight,
                 test_no_store, test_info_after_update, test_read_beside_a_busy_tunnel);
    failed +=
        UNIT_RUN("file_server_dir", setup_dir, teardown_dir, test_read_chunks, test_read_errors,
                 test_getinfo_dir, test_reads_in_flight, test_dir_symlink_out);
    return failed;
}
