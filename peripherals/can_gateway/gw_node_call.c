/* Gateway node: DroneCAN service calls made for the FC (NODE_CALL,
 * CALL_RESULT): parameters, ExecuteOpcode, RestartNode,
 * BeginFirmwareUpdate (its OK answer resets the node's update progress). Transfer IDs,
 * response matching, timeouts and retries are kept here; several calls may
 * be in flight at once, to one node or to several. */
#include <string.h>

#include "gw_node_internal.h"

typedef struct {
    uint16_t dtid;
    uint64_t signature;
    uint8_t priority;
} service_t;

static service_t service_of(uint8_t op)
{
    service_t s = {DAN_DC_PARAM_GETSET_ID, DAN_DC_PARAM_GETSET_SIGNATURE, DAN_DC_PRIORITY_LOW};
    if (op == DAN_GW_CALL_PARAM_SAVE || op == DAN_GW_CALL_PARAM_ERASE) {
        s.dtid = DAN_DC_PARAM_OPCODE_ID;
        s.signature = DAN_DC_PARAM_OPCODE_SIGNATURE;
    } else if (op == DAN_GW_CALL_RESTART) {
        s.dtid = DAN_DC_RESTART_ID;
        s.signature = DAN_DC_RESTART_SIGNATURE;
        s.priority = DAN_DC_PRIORITY_MEDIUM;
    } else if (op == DAN_GW_CALL_FW_BEGIN) {
        s.dtid = DAN_DC_FW_BEGIN_ID;
        s.signature = DAN_DC_FW_BEGIN_SIGNATURE;
        s.priority = DAN_DC_PRIORITY_MEDIUM;
    }
    return s;
}

/* dan_gw_value_t and dan_dc_param_value_t have the same members: one copy
 * serves both directions. */
#define VALUE_COPY(dst, src)                                     \
    do {                                                         \
        memset((dst), 0, sizeof *(dst));                         \
        (dst)->tag = (src)->tag;                                 \
        (dst)->boolean = (src)->boolean;                         \
        (dst)->integer = (src)->integer;                         \
        (dst)->real = (src)->real;                               \
        (dst)->string_len = (src)->string_len;                   \
        memcpy((dst)->string, (src)->string, (src)->string_len); \
    } while (0)

static void value_to_dc(dan_dc_param_value_t *d, const dan_gw_value_t *v)
{
    VALUE_COPY(d, v);
}

static void value_from_dc(dan_gw_value_t *v, const dan_dc_param_value_t *d)
{
    VALUE_COPY(v, d);
}

/* The DroneCAN request of a call, into k->req. */
static int build_request(dan_gw_node_t *g, dan_gw_node_call_t *k, const dan_gw_call_t *c)
{
    dan_dc_param_getset_req_t *q = &g->scratch.getset_req;
    dan_dc_param_opcode_t op;
    int n;
    switch (c->op) {
    case DAN_GW_CALL_PARAM_SAVE:
    case DAN_GW_CALL_PARAM_ERASE:
        memset(&op, 0, sizeof op);
        op.opcode = (uint8_t)(c->op == DAN_GW_CALL_PARAM_SAVE ? DAN_DC_PARAM_OPCODE_SAVE
                                                              : DAN_DC_PARAM_OPCODE_ERASE);
        n = dan_dc_param_opcode_req_encode(&op, k->req, sizeof k->req);
        break;
    case DAN_GW_CALL_RESTART: n = dan_dc_restart_req_encode(c->magic, k->req, sizeof k->req); break;
    case DAN_GW_CALL_FW_BEGIN:
        /* source: the gateway (its file server); path: the name */
        memset(&g->scratch.fw_req, 0, sizeof g->scratch.fw_req);
        g->scratch.fw_req.source_node_id = g->cfg.node_id;
        memcpy(g->scratch.fw_req.path, c->name, c->name_len);
        g->scratch.fw_req.path_len = c->name_len;
        n = dan_dc_fw_begin_req_encode(&g->scratch.fw_req, k->req, sizeof k->req);
        break;
    default:
        memset(q, 0, sizeof *q);
        if (c->op == DAN_GW_CALL_PARAM_GET_INDEX) {
            q->index = c->index;
        } else {
            memcpy(q->name, c->name, c->name_len);
            q->name_len = c->name_len;
        }
        if (c->op == DAN_GW_CALL_PARAM_SET) {
            value_to_dc(&q->value, &c->value);
        }
        n = dan_dc_param_getset_req_encode(q, k->req, sizeof k->req);
        break;
    }
    if (n < 0) {
        return n;
    }
    k->req_len = (uint16_t)n;
    return DAN_OK;
}

static bool tid_of_call(const dan_gw_node_call_t *k, uint8_t tid);

/* Another pending call to k's node and service answers to tid: a flow the
 * transfer-ID table evicted restarts at an old counter, and a response
 * would then complete the wrong call (review finding). */
static bool tid_held(const dan_gw_node_t *g, const dan_gw_node_call_t *k, uint16_t dtid,
                     uint8_t tid)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        const dan_gw_node_call_t *o = &g->calls[i];
        if (o != k && o->state == DAN_GW_CALL_PENDING && o->node_id == k->node_id &&
            service_of(o->op).dtid == dtid && tid_of_call(o, tid)) {
            return true;
        }
    }
    return false;
}

/* One attempt: the request again with a new transfer ID, one no other
 * pending call to that node and service answers to (at most
 * DAN_GW_NODE_CALLS * DAN_GW_NODE_CALL_ATTEMPTS of the 32 are). */
static void send_attempt(dan_gw_node_t *g, dan_gw_node_call_t *k, uint64_t now_us)
{
    service_t s = service_of(k->op);
    dan_dc_transfer_t t;
    int tid = dan_dc_tid_next(&g->tids, s.dtid, DAN_DC_TRANSFER_REQUEST, k->node_id);
    unsigned tries = 0;
    while (tid >= 0 && tid_held(g, k, s.dtid, (uint8_t)tid) && ++tries < 32u) {
        tid = dan_dc_tid_next(&g->tids, s.dtid, DAN_DC_TRANSFER_REQUEST, k->node_id);
    }
    k->due_us = now_us + DAN_GW_NODE_CALL_TIMEOUT_US *
                             (k->op == DAN_GW_CALL_RESTART ? DAN_GW_NODE_CALL_ATTEMPTS : 1u);
    if (tid < 0) {
        return; /* no transfer ID: the attempt times out like a lost one */
    }
    dan_dc_transfer_init(&t, s.dtid, s.signature, DAN_DC_TRANSFER_REQUEST, k->req, k->req_len);
    t.priority = s.priority;
    t.destination_node = k->node_id;
    t.transfer_id = (uint8_t)tid;
    k->tids[k->attempts++] = (uint8_t)tid;
    (void)dan_gwn_send_transfer(g, &g->q_bulk, &t);
}

dan_gw_node_call_t *dan_gwn_call_find(dan_gw_node_t *g, uint16_t call_id)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        if (g->calls[i].state != DAN_GW_NODE_CALL_FREE && g->calls[i].call_id == call_id) {
            return &g->calls[i];
        }
    }
    return NULL;
}

/* A free slot, else the one finished longest ago; NULL while all are in
 * flight. */
static dan_gw_node_call_t *slot_for_new(dan_gw_node_t *g)
{
    dan_gw_node_call_t *best = NULL;
    size_t i;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        dan_gw_node_call_t *k = &g->calls[i];
        if (k->state == DAN_GW_NODE_CALL_FREE) {
            return k;
        }
        if (k->state != DAN_GW_CALL_PENDING && (best == NULL || k->done_us < best->done_us)) {
            best = k;
        }
    }
    return best;
}

static void state_of(const dan_gw_node_call_t *k, uint16_t call_id, dan_gw_call_state_t *st)
{
    st->call_id = call_id;
    st->state = k != NULL ? k->state : DAN_GW_CALL_BUSY;
    st->result_len = k != NULL && k->state == DAN_GW_CALL_DONE ? k->result_len : 0u;
}

/* FW_BEGIN names a committed file: its size, or a negative error (an
 * error frame; nothing is sent). */
static int32_t fw_file_size(const dan_gw_node_t *g, const dan_gw_call_t *c)
{
    const dan_gw_file_store_t *fs = g->cfg.files;
    char name[DAN_GW_FILE_NAME_MAX + 1u];
    int32_t size;
    if (!dan_gw_file_name_ok(c->name, c->name_len)) {
        return DAN_ERR_MALFORMED;
    }
    if (fs == NULL) {
        return DAN_ERR_NOTFOUND;
    }
    memcpy(name, c->name, c->name_len);
    name[c->name_len] = '\0';
    size = fs->size(fs->ctx, name);
    return size < 0 ? DAN_ERR_NOTFOUND : size;
}

int dan_gwn_call_start(dan_gw_node_t *g, const dan_gw_call_t *c, uint32_t digest,
                       dan_gw_call_state_t *st, uint64_t now_us)
{
    dan_gw_node_call_t *k = dan_gwn_call_find(g, c->call_id);
    int32_t fw_size = 0;
    int rc;
    if (c->op == DAN_GW_CALL_RESTART && c->magic != DAN_DC_RESTART_MAGIC && !c->force) {
        return DAN_ERR_UNSUPPORTED; /* a bootloader's magic is sent only when forced */
    }
    if (k != NULL && k->digest == digest) {
        state_of(k, c->call_id, st); /* the master's retry: never sent twice */
        return DAN_OK;
    }
    if (c->op == DAN_GW_CALL_FW_BEGIN && (fw_size = fw_file_size(g, c)) < 0) {
        return (int)fw_size;
    }
    if (k == NULL) {
        k = slot_for_new(g);
    }
    if (k == NULL) {
        state_of(NULL, c->call_id, st);
        return DAN_OK;
    }
    memset(k, 0, offsetof(dan_gw_node_call_t, req));
    rc = build_request(g, k, c);
    if (rc < 0) {
        k->state = DAN_GW_NODE_CALL_FREE;
        return rc;
    }
    k->call_id = c->call_id;
    k->digest = digest;
    k->op = c->op;
    k->node_id = c->node_id;
    k->file_size = (uint32_t)fw_size;
    k->state = DAN_GW_CALL_PENDING;
    g->stats.calls++;
    send_attempt(g, k, now_us);
    state_of(k, c->call_id, st);
    return DAN_OK;
}

/* ---- responses ---- */

static bool tid_of_call(const dan_gw_node_call_t *k, uint8_t tid)
{
    size_t i;
    for (i = 0; i < k->attempts; i++) {
        if (k->tids[i] == tid) {
            return true;
        }
    }
    return false;
}

/* Keeps an encoded result of n bytes (already in k->result), or passes an
 * encoder's error on. */
static int keep_result(dan_gw_node_call_t *k, int n)
{
    if (n < 0) {
        return n;
    }
    k->result_len = (uint16_t)n;
    return DAN_OK;
}

/* The GetSet answer as the DAN result: present, value, default, max, min,
 * name (dan/can_gw/msgs_mgmt.h). */
static int param_result(dan_gw_node_t *g, dan_gw_node_call_t *k, const uint8_t *p, size_t len)
{
    dan_dc_param_getset_rsp_t *r = &g->scratch.getset_rsp;
    const dan_dc_param_value_t *opt[3];
    dan_gw_value_t v;
    dan_writer_t w;
    uint8_t present = 0;
    size_t i;
    if (dan_dc_param_getset_rsp_decode(r, p, len) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    opt[0] = &r->default_value;
    opt[1] = &r->max_value;
    opt[2] = &r->min_value;
    for (i = 0; i < 3u; i++) {
        present = (uint8_t)(present | (opt[i]->tag != DAN_DC_PARAM_EMPTY ? 1u << i : 0u));
    }
    dan_writer_init(&w, k->result, sizeof k->result);
    dan_put_u8(&w, present);
    value_from_dc(&v, &r->value);
    dan_gw_msg_value_put(&w, &v);
    for (i = 0; i < 3u; i++) {
        if (opt[i]->tag != DAN_DC_PARAM_EMPTY) {
            value_from_dc(&v, opt[i]);
            dan_gw_msg_value_put(&w, &v);
        }
    }
    dan_put_array(&w, r->name, r->name_len);
    return keep_result(k, dan_writer_finish(&w));
}

static int opcode_result(dan_gw_node_call_t *k, const uint8_t *p, size_t len)
{
    dan_dc_param_opcode_t m;
    dan_gw_opcode_result_t r;
    if (dan_dc_param_opcode_rsp_decode(&m, p, len) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    r.ok = m.ok ? 1u : 0u;
    r.argument = m.argument;
    return keep_result(k, dan_gw_msg_opcode_result_encode(&r, k->result, sizeof k->result));
}

static int restart_result(dan_gw_node_call_t *k, const uint8_t *p, size_t len)
{
    bool ok;
    if (dan_dc_restart_rsp_decode(&ok, p, len) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    k->result[0] = ok ? 1u : 0u;
    k->result_len = 1;
    return DAN_OK;
}

/* BeginFirmwareUpdate's answer as the DAN result; an OK one starts the
 * node's progress afresh (NODE_INFO's follow fields). */
static int fw_begin_result(dan_gw_node_t *g, dan_gw_node_call_t *k, const uint8_t *p, size_t len,
                           uint64_t now_us)
{
    dan_dc_fw_begin_rsp_t m;
    dan_gw_fw_result_t r;
    dan_gw_node_slot_t *n;
    int rc;
    if (dan_dc_fw_begin_rsp_decode(&m, p, len) != DAN_OK) {
        return DAN_ERR_MALFORMED;
    }
    r.error = m.error;
    r.message_len = m.message_len;
    memcpy(r.message, m.message, m.message_len);
    rc = keep_result(k, dan_gw_msg_fw_result_encode(&r, k->result, sizeof k->result));
    if (rc != DAN_OK) {
        return rc;
    }
    n = dan_gwn_find_node(g, k->node_id);
    if (m.error == DAN_DC_FW_BEGIN_OK && n != NULL) {
        n->fw.flags = DAN_GW_FW_BEGUN;
        n->fw.bytes_read = 0;
        n->fw.file_size = k->file_size;
        n->fw.last_read_us = now_us ? now_us : 1u;
    }
    g->stats.fw_begins += m.error == DAN_DC_FW_BEGIN_OK;
    return DAN_OK;
}

void dan_gwn_on_call_response(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    size_t i;
    int rc;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        dan_gw_node_call_t *k = &g->calls[i];
        if (k->state != DAN_GW_CALL_PENDING || k->node_id != t->source_node ||
            service_of(k->op).dtid != t->data_type_id || !tid_of_call(k, t->transfer_id)) {
            continue;
        }
        if (k->op == DAN_GW_CALL_RESTART) {
            rc = restart_result(k, t->payload, t->payload_len);
        } else if (k->op == DAN_GW_CALL_FW_BEGIN) {
            rc = fw_begin_result(g, k, t->payload, t->payload_len, now_us);
        } else if (k->op == DAN_GW_CALL_PARAM_SAVE || k->op == DAN_GW_CALL_PARAM_ERASE) {
            rc = opcode_result(k, t->payload, t->payload_len);
        } else {
            rc = param_result(g, k, t->payload, t->payload_len);
        }
        if (rc == DAN_OK) { /* a malformed answer is ignored: the attempt times out */
            k->state = DAN_GW_CALL_DONE;
            k->done_us = now_us;
        }
        return;
    }
}

/* ---- timers ---- */

void dan_gwn_calls_poll(dan_gw_node_t *g, uint64_t now_us)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        dan_gw_node_call_t *k = &g->calls[i];
        if (k->state != DAN_GW_CALL_PENDING || now_us < k->due_us) {
            continue;
        }
        /* RESTART goes once, its attempts' time in one wait: a node may
         * restart without answering, and a new transfer ID is a new
         * request to it (it restarted up to three times; review finding) */
        if (k->attempts < DAN_GW_NODE_CALL_ATTEMPTS && k->op != DAN_GW_CALL_RESTART) {
            send_attempt(g, k, now_us);
        } else {
            k->state = DAN_GW_CALL_TIMEOUT;
            k->done_us = now_us;
            g->stats.call_timeouts++;
        }
    }
}

uint64_t dan_gwn_calls_next_us(const dan_gw_node_t *g, uint64_t t)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        if (g->calls[i].state == DAN_GW_CALL_PENDING && g->calls[i].due_us < t) {
            t = g->calls[i].due_us;
        }
    }
    return t;
}

void dan_gwn_calls_init(dan_gw_node_t *g)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_CALLS; i++) {
        g->calls[i].state = DAN_GW_NODE_CALL_FREE;
    }
}
