#include <string.h>

#include "gw_vectors.h"
#include "vectors.h"

void vec_cat_node_info(char *txt, size_t cap, const dan_gw_node_info_t *ni)
{
    vec_cat(txt, cap, "node=%u state=%u sw=%u/%u/%u vcs=%lu hw=%u/%u uid=", ni->node_id,
            ni->info_state, ni->sw_major, ni->sw_minor, ni->sw_flags, (unsigned long)ni->vcs_commit,
            ni->hw_major, ni->hw_minor);
    vec_cat_hex(txt, cap, ni->unique_id, 16);
    vec_cat(txt, cap, " name=");
    vec_cat_hex(txt, cap, (const uint8_t *)ni->name, strlen(ni->name));
}
