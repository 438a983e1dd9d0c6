/* What the client's files (gw_client*.c) share. Not installed. */
#ifndef DAN_CAN_GW_CLIENT_INTERNAL_H
#define DAN_CAN_GW_CLIENT_INTERNAL_H

#include "dan/can_gw/client.h"

/* Starts a transaction with the payload in buf (len < 0: an encoder's
 * error, passed through), sealed. */
int dan_gwc_start(dan_gw_t *gw, uint32_t code, const uint8_t *buf, int len, uint64_t now_us);
/* True when no operation runs on the master. */
bool dan_gwc_idle(const dan_gw_t *gw);
/* A reader over the completed response of code (inner payload). */
int dan_gwc_resp_reader(const dan_gw_t *gw, uint32_t code, dan_reader_t *r);
/* Decodes the completed bus-management calls (gw_client_mgmt.c). */
int dan_gwc_complete_mgmt(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len);

#endif /* DAN_CAN_GW_CLIENT_INTERNAL_H */
