/* Vector text of the gateway messages that both gateway vector files
 * (gateway.txt, gateway_file.txt) hold. */
#ifndef GW_VECTORS_H
#define GW_VECTORS_H

#include "dan/can_gw/msgs.h"

/* Appends NODE_INFO's node, software and hardware fields, unique ID and name. */
void vec_cat_node_info(char *txt, size_t cap, const dan_gw_node_info_t *ni);

/* A paged response, read from reader r and written again to writer w: its
 * header H h (dan_gw_msg_<hdr>_hdr_get/_put, then the statement hdr_text),
 * then its h.count entries E e (dan_gw_msg_<entry>_get/_put, entry_text
 * after each). i, a size_t, counts the entries. */
#define VEC_PAGE(H, E, hdr, entry, hdr_text, entry_text)                \
    do {                                                                \
        H h;                                                            \
        E e;                                                            \
        assert_int_equal(dan_gw_msg_##hdr##_hdr_get(&r, &h), DAN_OK);   \
        dan_gw_msg_##hdr##_hdr_put(&w, &h);                             \
        hdr_text;                                                       \
        for (i = 0; i < h.count; i++) {                                 \
            assert_int_equal(dan_gw_msg_##entry##_get(&r, &e), DAN_OK); \
            dan_gw_msg_##entry##_put(&w, &e);                           \
            entry_text;                                                 \
        }                                                               \
    } while (0)

#endif
