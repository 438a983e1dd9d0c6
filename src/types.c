/* The type registry (include/dan/codes.h) with names, for tools. */
#include <stdlib.h>
#include <string.h>

#include "dan/codes.h"
#include "dan/types.h"

const dan_type_info_t dan_type_registry[] = {
    {"vtx", DAN_TYPE_VTX_FIRST, "video transmitter (DAN draft)", 1},
    {"can-gw", DAN_TYPE_CAN_GW_FIRST, "CAN-over-DAN gateway", 2},
    {"test-a", DAN_TYPE_TEST_A_FIRST, "test type A", 1},
    {"test-b", DAN_TYPE_TEST_B_FIRST, "test type B", 1},
    {NULL, 0, NULL, 0},
};

const dan_type_info_t *dan_type_lookup(const char *s)
{
    const dan_type_info_t *t;
    char *end;
    unsigned long v;
    for (t = dan_type_registry; t->name != NULL; t++) {
        if (strcmp(t->name, s) == 0) {
            return t;
        }
    }
    v = strtoul(s, &end, 0);
    if (end != s && *end == '\0') {
        for (t = dan_type_registry; t->name != NULL; t++) {
            if (t->first == v) {
                return t;
            }
        }
    }
    return NULL;
}

const dan_type_info_t *dan_type_of_code(uint32_t code)
{
    const dan_type_info_t *t;
    for (t = dan_type_registry; t->name != NULL; t++) {
        if (code >= t->first && code - t->first < DAN_TYPE_BLOCK_SIZE * (uint32_t)t->blocks) {
            return t;
        }
    }
    return NULL;
}
