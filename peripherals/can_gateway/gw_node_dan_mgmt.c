/* Gateway node: the DAN handlers of bus management (NODE_CALL,
 * CALL_RESULT, HEALTH, DNA); the table is in gw_node_dan.c. */
#include <string.h>

#include "gw_node_internal.h"

DAN_GWN_HANDLER(dan_gwn_h_node_call)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_call_t c;
    dan_gw_call_state_t st;
    int rc;
    (void)code;
    if (dan_gw_msg_call_decode(&c, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad node call");
    }
    /* the digest tells a retry (same content) from a new call reusing an id:
     * a CRC-32, so a new call passes for a retry 1 in 2^32, not 1 in 2^16 */
    rc = dan_gwn_call_start(g, &c, dan_gw_crc32(0, req, len), &st, now_us);
    if (rc == DAN_ERR_UNSUPPORTED) {
        *err = "not RestartNode magic: force";
        return rc;
    }
    if (rc == DAN_ERR_NOTFOUND || rc == DAN_ERR_MALFORMED) {
        *err = "FW_BEGIN: not a committed file";
        return rc;
    }
    if (rc != DAN_OK) {
        *err = "node call does not fit";
        return rc;
    }
    PUT_ENCODED(resp, dan_gw_msg_call_state_encode, &st);
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_call_result)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_result_t q;
    dan_gw_node_call_t *k;
    size_t n = 0;
    (void)code;
    if (dan_gw_msg_result_req_decode(&q, req, len) != DAN_OK) {
        return dan_gwn_refuse(err, "bad call result request");
    }
    k = dan_gwn_call_find(g, q.call_id);
    if (k == NULL) {
        *err = "unknown call";
        return DAN_ERR_NOTFOUND;
    }
    q.state = k->state;
    q.result_len = k->state == DAN_GW_CALL_DONE ? k->result_len : 0u;
    if (q.offset < q.result_len) {
        n = q.result_len - q.offset;
        n = n < q.max ? n : q.max;
        n = n < DAN_GW_RESULT_CHUNK_MAX ? n : DAN_GW_RESULT_CHUNK_MAX;
    }
    q.data = &k->result[q.offset < q.result_len ? q.offset : 0u];
    q.len = n;
    PUT_ENCODED(resp, dan_gw_msg_result_rsp_encode, &q);
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_health)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_health_t h;
    (void)code;
    (void)req;
    (void)len;
    (void)err;
    dan_gw_node_health(g, &h, now_us);
    PUT_ENCODED(resp, dan_gw_msg_health_encode, &h);
    return DAN_OK;
}

DAN_GWN_HANDLER(dan_gwn_h_dna)
{
    dan_gw_node_t *g = dan_gwn_touch(user, now_us);
    dan_gw_dna_hdr_t h;
    size_t i;
    (void)code;
    if (len < 1u) {
        return dan_gwn_refuse(err, "missing first entry");
    }
    dan_gwn_dna_page(g, req[0], resp->cap, &h);
    dan_gw_msg_dna_hdr_put(resp, &h);
    for (i = 0; i < h.count; i++) {
        dan_gw_msg_dna_entry_put(resp, &g->dna.table[req[0] + i]);
    }
    return DAN_OK;
}
