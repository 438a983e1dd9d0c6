/* dan-fcsim's file steps: an image uploaded into the gateway's file store
 * over DAN alone (resumed where the gateway is, CRC-checked commit), the
 * list, a removal, FW_BEGIN with its result, and NODE_INFO's update fields.
 * One JSON line per step, like the others (dan-fcsim --help). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "dan/posix.h"
#include "fcsim.h"

#define IMAGE_MAX    (4u * 1024u * 1024u)
#define CALL_POLL_MS 50u

/* A file result that is not OK: the failure line with it. */
static int file_fail(const char *step, uint8_t result)
{
    printf("{\"step\": \"%s\", \"ok\": false, \"result\": %u}\n", step, result);
    return 1;
}

/* Runs the started file call; its result byte and value, or a failure. */
static int file_call(const char *step, int started, uint8_t *result, uint32_t *value)
{
    int rc = fcsim_finish(started);
    if (rc == DAN_OK) {
        rc = dan_gw_file_result(&g_gw, result, value);
    }
    return rc == DAN_OK ? 0 : fcsim_fail(step, rc);
}

static uint8_t *read_image(const char *path, uint32_t *size)
{
    FILE *f = fopen(path, "rb");
    uint8_t *img = f != NULL ? malloc(IMAGE_MAX) : NULL;
    size_t n = img != NULL ? fread(img, 1, IMAGE_MAX, f) : 0u;
    if (f != NULL) {
        fclose(f);
    }
    *size = (uint32_t)n;
    return img;
}

/* upload:NAME:PATH[:STOP]: FILE_OPEN (resumes what the gateway holds),
 * FILE_WRITE from its have on, FILE_COMMIT with the CRC-32 of the image.
 * STOP: leave once have >= STOP, uncommitted (an uploader killed midway). */
int fcsim_step_upload(const char *name, const char *step, char *args)
{
    char *path = args != NULL ? strchr(args, ':') : NULL, *stop_s;
    uint32_t size, have, start, writes = 0, crc, stop;
    uint8_t result, *img;
    uint64_t t0 = dan_posix_now_us();
    (void)name;
    if (path == NULL) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    *path++ = '\0';
    stop_s = strchr(path, ':');
    if (stop_s != NULL) {
        *stop_s++ = '\0';
    }
    img = read_image(path, &size);
    stop = stop_s != NULL ? (uint32_t)strtoul(stop_s, NULL, 0) : size;
    if (img == NULL) {
        return fcsim_fail(step, DAN_ERR_IO);
    }
    crc = dan_gw_crc32(0, img, size);
    if (file_call(step, dan_gw_file_open(&g_gw, args, size, false, dan_posix_now_us()), &result,
                  &have) != 0 ||
        result != DAN_GW_FILE_OK) {
        free(img);
        return result != DAN_GW_FILE_OK ? file_fail(step, result) : 1;
    }
    start = have;
    while (have < size && have < stop) {
        size_t n = size - have < DAN_GW_FILE_CHUNK_MAX ? size - have : DAN_GW_FILE_CHUNK_MAX;
        int rc = file_call(step, dan_gw_file_write(&g_gw, have, img + have, n, dan_posix_now_us()),
                           &result, &have);
        writes++;
        if (rc != 0 || result != DAN_GW_FILE_OK) {
            free(img);
            return rc != 0 ? rc : file_fail(step, result);
        }
    }
    free(img);
    if (have < size) {
        printf("{\"step\": \"upload\", \"ok\": true, \"size\": %u, \"stopped_at\": %u, "
               "\"resumed_at\": %u, \"writes\": %u}\n",
               size, have, start, writes);
        return 0;
    }
    if (file_call(step, dan_gw_file_commit(&g_gw, crc, dan_posix_now_us()), &result, &have) != 0) {
        return 1;
    }
    if (result != DAN_GW_FILE_OK) {
        return file_fail(step, result);
    }
    printf("{\"step\": \"upload\", \"ok\": true, \"size\": %u, \"crc\": %u, \"resumed_at\": %u, "
           "\"writes\": %u, \"seconds\": %.6f}\n",
           size, crc, start, writes, (double)(dan_posix_now_us() - t0) / 1e6);
    return 0;
}

int fcsim_step_files(const char *name, const char *step, char *args)
{
    dan_gw_file_list_hdr_t h = {0u, 0u};
    dan_gw_file_entry_t e;
    dan_reader_t r;
    size_t i, n = 0;
    (void)name;
    (void)args;
    printf("{\"step\": \"files\", \"ok\": true, \"files\": [");
    do {
        int rc = fcsim_finish(dan_gw_file_list(&g_gw, h.next, dan_posix_now_us()));
        rc = rc != DAN_OK ? rc : dan_gw_file_list_begin(&g_gw, &r, &h);
        if (rc != DAN_OK) {
            printf("]}\n");
            return fcsim_fail(step, rc);
        }
        for (i = 0; i < h.count && dan_gw_file_list_next(&r, &e) == DAN_OK; i++) {
            printf("%s{\"name\": \"%s\", \"size\": %u}", n++ ? ", " : "", e.name, e.size);
        }
    } while (h.next != DAN_GW_NONE);
    printf("]}\n");
    return 0;
}

int fcsim_step_rm(const char *name, const char *step, char *args)
{
    uint8_t result;
    uint32_t v;
    (void)name;
    if (file_call(step, dan_gw_file_remove(&g_gw, args, dan_posix_now_us()), &result, &v) != 0) {
        return 1;
    }
    printf("{\"step\": \"rm\", \"ok\": %s, \"result\": %u}\n",
           result == DAN_GW_FILE_OK ? "true" : "false", result);
    return result == DAN_GW_FILE_OK ? 0 : 1;
}

/* fw-begin:NODE:NAME[:CALL_ID]: the call, then its result polled until done. */
int fcsim_step_fw_begin(const char *name, const char *step, char *args)
{
    char *file = args != NULL ? strchr(args, ':') : NULL, *id;
    uint16_t call_id;
    dan_gw_result_t res;
    dan_gw_fw_result_t fw;
    int rc;
    (void)name;
    if (file == NULL) {
        return fcsim_fail(step, DAN_ERR_ARG);
    }
    *file++ = '\0';
    id = strchr(file, ':');
    if (id != NULL) {
        *id++ = '\0';
    }
    call_id = (uint16_t)(id != NULL ? strtoul(id, NULL, 0) : 1u);
    rc = fcsim_finish(
        dan_gw_fw_begin(&g_gw, call_id, (uint8_t)strtoul(args, NULL, 0), file, dan_posix_now_us()));
    do {
        if (rc == DAN_OK) {
            fcsim_sleep_us(CALL_POLL_MS * 1000u);
            rc = fcsim_finish(
                dan_gw_call_result(&g_gw, call_id, 0, DAN_GW_RESULT_CHUNK_MAX, dan_posix_now_us()));
        }
        rc = rc != DAN_OK ? rc : dan_gw_call_result_get(&g_gw, &res);
    } while (rc == DAN_OK && res.state == DAN_GW_CALL_PENDING);
    if (rc == DAN_OK && res.state != DAN_GW_CALL_DONE) {
        rc = DAN_ERR_TIMEOUT;
    }
    rc = rc != DAN_OK ? rc : dan_gw_msg_fw_result_decode(&fw, res.data, res.len);
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    printf("{\"step\": \"fw-begin\", \"ok\": %s, \"error\": %u, \"message\": \"%.*s\"}\n",
           fw.error == DAN_GW_FW_OK ? "true" : "false", fw.error, (int)fw.message_len,
           (const char *)fw.message);
    return fw.error == DAN_GW_FW_OK ? 0 : 1;
}

int fcsim_step_node_info(const char *name, const char *step, char *args)
{
    dan_gw_node_info_t i;
    int rc = fcsim_finish(
        dan_gw_node_info(&g_gw, (uint8_t)(args ? strtoul(args, NULL, 0) : 0u), dan_posix_now_us()));
    (void)name;
    rc = rc != DAN_OK ? rc : dan_gw_node_info_get(&g_gw, &i);
    if (rc != DAN_OK) {
        return fcsim_fail(step, rc);
    }
    printf("{\"step\": \"node-info\", \"ok\": true, \"node\": %u, \"info_state\": %u, "
           "\"sw\": [%u, %u], \"follow\": %s, \"status\": %u, \"mode\": %u, \"file_flags\": %u, "
           "\"bytes_read\": %u, \"file_size\": %u, \"since_read_ms\": %u}\n",
           i.node_id, i.info_state, i.sw_major, i.sw_minor, i.follow ? "true" : "false", i.status,
           (unsigned)((i.status >> 2) & 7u), i.file_flags, i.bytes_read, i.file_size,
           i.since_read_ms);
    return 0;
}
