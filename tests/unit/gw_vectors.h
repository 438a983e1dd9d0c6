/* Vector text of the gateway messages that both gateway vector files
 * (gateway.txt, gateway_file.txt) hold. */
#ifndef GW_VECTORS_H
#define GW_VECTORS_H

#include "dan/can_gw/msgs.h"

/* Appends NODE_INFO's node, software and hardware fields, unique ID and name. */
void vec_cat_node_info(char *txt, size_t cap, const dan_gw_node_info_t *ni);

#endif
