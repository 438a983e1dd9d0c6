/* CAN-over-DAN gateway client: bus management (service calls, health,
 * allocation table). See dan/can_gw/client.h. */
#include <string.h>

#include "gw_client_internal.h"

int dan_gw_node_call(dan_gw_t *gw, const dan_gw_call_t *c, uint64_t now_us)
{
    uint8_t buf[DAN_MAX_PAYLOAD]; /* the seal fits in it */
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    return dan_gwc_start(gw, DAN_GW_CODE_NODE_CALL, dan_gwc_done_call, buf,
                         dan_gw_msg_call_encode(c, buf, DAN_GWC_CAP(buf)), sizeof buf, now_us);
}

void dan_gwc_call_init(dan_gw_call_t *c, uint16_t call_id, uint8_t node_id, uint8_t op)
{
    memset(c, 0, sizeof *c);
    c->call_id = call_id;
    c->node_id = node_id;
    c->op = op;
}

static void call_name(dan_gw_call_t *c, const char *name)
{
    size_t n = name != NULL ? strlen(name) : 0u;
    c->name = name;
    c->name_len = (uint8_t)(n > DAN_GW_PARAM_NAME_MAX ? DAN_GW_PARAM_NAME_MAX + 1u : n);
}

int dan_gw_param_get_index(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, uint16_t index,
                           uint64_t now_us)
{
    dan_gw_call_t c;
    dan_gwc_call_init(&c, call_id, node_id, DAN_GW_CALL_PARAM_GET_INDEX);
    c.index = index;
    return dan_gw_node_call(gw, &c, now_us);
}

int dan_gw_param_get(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, const char *name,
                     uint64_t now_us)
{
    dan_gw_call_t c;
    dan_gwc_call_init(&c, call_id, node_id, DAN_GW_CALL_PARAM_GET_NAME);
    call_name(&c, name);
    return dan_gw_node_call(gw, &c, now_us);
}

int dan_gw_param_set(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, const char *name,
                     const dan_gw_value_t *value, uint64_t now_us)
{
    dan_gw_call_t c;
    if (value == NULL) {
        return DAN_ERR_ARG;
    }
    dan_gwc_call_init(&c, call_id, node_id, DAN_GW_CALL_PARAM_SET);
    call_name(&c, name);
    c.value = *value;
    return dan_gw_node_call(gw, &c, now_us);
}

int dan_gw_param_save(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, uint64_t now_us)
{
    dan_gw_call_t c;
    dan_gwc_call_init(&c, call_id, node_id, DAN_GW_CALL_PARAM_SAVE);
    return dan_gw_node_call(gw, &c, now_us);
}

int dan_gw_restart(dan_gw_t *gw, uint16_t call_id, uint8_t node_id, uint64_t magic, bool force,
                   uint64_t now_us)
{
    dan_gw_call_t c;
    dan_gwc_call_init(&c, call_id, node_id, DAN_GW_CALL_RESTART);
    c.magic = magic;
    c.force = force ? 1u : 0u;
    return dan_gw_node_call(gw, &c, now_us);
}

int dan_gw_call_result(dan_gw_t *gw, uint16_t call_id, uint32_t offset, uint8_t max,
                       uint64_t now_us)
{
    uint8_t buf[DAN_GWC_BUF(DAN_GW_RESULT_REQ_MAX)];
    dan_gw_result_t q;
    if (!dan_gwc_idle(gw)) {
        return DAN_ERR_BUSY;
    }
    memset(&q, 0, sizeof q);
    q.call_id = call_id;
    q.offset = offset;
    q.max = max;
    return dan_gwc_start(gw, DAN_GW_CODE_CALL_RESULT, NULL, buf,
                         dan_gw_msg_result_req_encode(&q, buf, DAN_GWC_CAP(buf)), sizeof buf,
                         now_us);
}

int dan_gw_call_result_get(const dan_gw_t *gw, dan_gw_result_t *res)
{
    dan_reader_t r;
    int rc = dan_gwc_resp_reader(gw, DAN_GW_CODE_CALL_RESULT, &r);
    return rc != DAN_OK ? rc : dan_gw_msg_result_rsp_decode(res, r.data, r.len);
}

int dan_gw_health(dan_gw_t *gw, uint64_t now_us)
{
    return dan_gwc_start_byte(gw, DAN_GW_CODE_HEALTH, dan_gwc_done_health, 0u, 0u, now_us);
}

DAN_GWC_PAGED(dna, DAN_GW_CODE_DNA, dan_gw_dna_hdr_t, dan_gw_msg_dna_hdr_get, dan_gw_dna_entry_t,
              dan_gw_msg_dna_entry_get)

int dan_gwc_done_call(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    (void)code;
    return dan_gw_msg_call_state_decode(&gw->call, p, len);
}

int dan_gwc_done_health(dan_gw_t *gw, uint32_t code, const uint8_t *p, size_t len)
{
    (void)code;
    return dan_gw_msg_health_decode(&gw->health, p, len);
}
