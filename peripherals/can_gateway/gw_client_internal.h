/* What the client's files (gw_client*.c) share. Not installed. */
#ifndef DAN_CAN_GW_CLIENT_INTERNAL_H
#define DAN_CAN_GW_CLIENT_INTERNAL_H

#include "dan/can_gw/client.h"

/* Request buffers keep room for the seal after the payload, so it is
 * sealed in place: no second frame-sized copy on the stack (the worst-case
 * stack of an ESC command, issue 17). The encoder gets DAN_GWC_CAP(buf). */
#define DAN_GWC_BUF(n)   ((n) + DAN_GW_SEAL_SIZE)
#define DAN_GWC_CAP(buf) (sizeof(buf) - DAN_GW_SEAL_SIZE)

/* Starts a transaction with the len-byte payload in buf (cap bytes, room
 * for the seal included; len < 0: an encoder's error, passed through),
 * sealed in place. done decodes its response (inner payload) when it
 * completes; NULL: nothing to decode (read on demand). Each call names
 * its own, so a program links only the decoders of the calls it makes
 * (issue 17: an FC that drives ESCs never links the tunnel or CAN ones). */
int dan_gwc_start(dan_gw_t *gw, uint32_t code, dan_gw_done_fn done, uint8_t *buf, int len,
                  size_t cap, uint64_t now_us);
/* Starts a request whose payload is one byte (n 1) or none (n 0). */
int dan_gwc_start_byte(dan_gw_t *gw, uint32_t code, dan_gw_done_fn done, uint8_t v, size_t n,
                       uint64_t now_us);
/* True when no operation runs on the master. */
bool dan_gwc_idle(const dan_gw_t *gw);
/* A NODE_CALL request of op, the rest zero (the calls of gw_client_mgmt.c
 * and FW_BEGIN). */
void dan_gwc_call_init(dan_gw_call_t *c, uint16_t call_id, uint8_t node_id, uint8_t op);
/* A reader over the completed response of code (inner payload). */
int dan_gwc_resp_reader(const dan_gw_t *gw, uint32_t code, dan_reader_t *r);
/* The three calls of a paged listing (first entry index in, a header and
 * entries out): the request, the header's reader and the entry reader. */
#define DAN_GWC_PAGED(name, code, hdr_t, hdr_get, entry_t, entry_get)          \
    int dan_gw_##name(dan_gw_t *gw, uint8_t first, uint64_t now_us)            \
    {                                                                          \
        return dan_gwc_start_byte(gw, code, NULL, first, 1u, now_us);          \
    }                                                                          \
    int dan_gw_##name##_begin(const dan_gw_t *gw, dan_reader_t *r, hdr_t *hdr) \
    {                                                                          \
        int rc = dan_gwc_resp_reader(gw, code, r);                             \
        return rc != DAN_OK ? rc : hdr_get(r, hdr);                            \
    }                                                                          \
    int dan_gw_##name##_next(dan_reader_t *r, entry_t *e)                      \
    {                                                                          \
        return entry_get(r, e);                                                \
    }
/* The response decoders (dan_gw_done_fn), by the calls that use them. */
#define DAN_GWC_DONE(name) \
    int dan_gwc_done_##name(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
/* gw_client.c: flags also for gw_client_out.c's calls */
DAN_GWC_DONE(telem);
DAN_GWC_DONE(fast);
DAN_GWC_DONE(flags);
DAN_GWC_DONE(config);
DAN_GWC_DONE(stats);
/* gw_client_can.c */
DAN_GWC_DONE(tun_open);
DAN_GWC_DONE(xfer);
DAN_GWC_DONE(can_send);
DAN_GWC_DONE(can_recv);
/* gw_client_mgmt.c */
DAN_GWC_DONE(call);
DAN_GWC_DONE(health);
/* gw_client_any.c: the decoder of any code (what its call would name). */
dan_gw_done_fn dan_gwc_done_of(uint32_t code);

#endif /* DAN_CAN_GW_CLIENT_INTERNAL_H */
