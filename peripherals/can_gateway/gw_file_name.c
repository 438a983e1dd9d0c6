/* The file store's name rule and the DroneCAN path rule (docs/PROTOCOL.md
 * section 7, "Files and firmware updates"; dan/can_gw/file_store.h). Both
 * sides use it: the node before asking its store, an FC client before
 * sending a name. */
#include <string.h>

#include "dan/can_gw/file_store.h"

static bool name_char_ok(char c)
{
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
}

bool dan_gw_file_name_ok(const char *name, size_t len)
{
    size_t i;
    if (name == NULL || len < 1u || len > DAN_GW_FILE_NAME_MAX || name[0] == '.') {
        return false; /* '.' first also rules out "." and ".." */
    }
    for (i = 0; i < len; i++) {
        if (!name_char_ok(name[i])) {
            return false; /* '/', '\\', NUL, spaces, non-ASCII */
        }
    }
    return true;
}

bool dan_gw_file_path_name(const uint8_t *path, size_t len, char name[DAN_GW_FILE_NAME_MAX + 1u])
{
    if (path == NULL || name == NULL) {
        return false;
    }
    if (len > 0u && path[0] == (uint8_t)'/') {
        path++; /* one leading '/' only: "//x" fails the name check */
        len--;
    }
    if (!dan_gw_file_name_ok((const char *)path, len)) {
        return false;
    }
    memcpy(name, path, len);
    name[len] = '\0';
    return true;
}
