/* The gateway's unique ID from --uid or the machine ID (node_uid.h). */
#include "node_uid.h"

#include <stdio.h>
#include <string.h>
#include <unistd.h>

#define FNV_OFFSET 2166136261u /* 32-bit FNV-1a */
#define FNV_PRIME  16777619u
#define HOST_MAX   256

static uint32_t fnv1a(uint32_t h, const char *s)
{
    for (; *s != '\0'; s++) {
        h ^= (uint8_t)*s;
        h *= FNV_PRIME;
    }
    return h;
}

#define HEX_DIGITS "0123456789abcdefABCDEF"

/* All of s is n hex digits. */
static int all_hex(const char *s, size_t n)
{
    return strlen(s) == n && strspn(s, HEX_DIGITS) == n;
}

int dan_uid_parse(const char *hex, uint8_t uid[DAN_UID_SIZE])
{
    uint8_t any = 0;
    size_t i;
    if (!all_hex(hex, DAN_UID_HEX_SIZE)) {
        return -1;
    }
    for (i = 0; i < DAN_UID_SIZE; i++) {
        unsigned v = 0;
        (void)sscanf(hex + 2 * i, "%2x", &v);
        uid[i] = (uint8_t)v;
        any |= uid[i];
    }
    return any != 0u ? 0 : -1;
}

void dan_uid_hash(const char *key, uint8_t uid[DAN_UID_SIZE])
{
    uint8_t any = 0;
    unsigned k;
    for (k = 0; k < DAN_UID_SIZE / 4u; k++) {
        char prefix[24];
        uint32_t h;
        snprintf(prefix, sizeof prefix, "dan-gatewayd:%u:", k);
        h = fnv1a(fnv1a(FNV_OFFSET, prefix), key);
        uid[4 * k] = (uint8_t)h;
        uid[4 * k + 1] = (uint8_t)(h >> 8);
        uid[4 * k + 2] = (uint8_t)(h >> 16);
        uid[4 * k + 3] = (uint8_t)(h >> 24);
        any |= (uint8_t)(h | h >> 8 | h >> 16 | h >> 24);
    }
    if (any == 0u) {
        uid[DAN_UID_SIZE - 1u] = 1; /* all zeros is DroneCAN's "undefined" */
    }
}

/* The machine ID's 32 hex digits from path into id (33 bytes); 0 or -1. */
static int read_machine_id(const char *path, char id[DAN_UID_HEX_SIZE + 1u])
{
    char line[64];
    FILE *f = fopen(path, "r");
    if (f == NULL) {
        return -1;
    }
    if (fgets(line, sizeof line, f) == NULL) {
        line[0] = '\0';
    }
    fclose(f);
    line[strcspn(line, "\r\n")] = '\0';
    if (!all_hex(line, DAN_UID_HEX_SIZE)) {
        return -1;
    }
    memcpy(id, line, DAN_UID_HEX_SIZE + 1u);
    return 0;
}

int dan_uid_derive(const char *machine_id_path, uint8_t uid[DAN_UID_SIZE])
{
    char id[DAN_UID_HEX_SIZE + 1u], host[HOST_MAX], key[HOST_MAX + 8];
    if (read_machine_id(machine_id_path, id) == 0) {
        dan_uid_hash(id, uid);
        return 0;
    }
    if (gethostname(host, sizeof host) != 0) {
        host[0] = '\0';
    }
    host[sizeof host - 1u] = '\0';
    snprintf(key, sizeof key, "host:%s", host);
    dan_uid_hash(key, uid);
    return 1;
}
