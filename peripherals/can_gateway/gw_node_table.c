/* Gateway node: the node table (from NodeStatus) and the GetNodeInfo
 * requests the gateway makes of every node in it. */
#include <string.h>

#include "gw_node_internal.h"

dan_gw_node_slot_t *dan_gwn_find_node(dan_gw_node_t *g, uint8_t id)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        if (g->nodes[i].e.node_id == id) {
            return &g->nodes[i];
        }
    }
    return NULL;
}

/* Silent past DroneCAN's OFFLINE_TIMEOUT, or said so: a NodeStatus with
 * mode OFFLINE means others need not wait for the timeout (the DSDL). */
bool dan_gwn_offline(const dan_gw_node_slot_t *n, uint64_t now_us)
{
    return now_us - n->seen_us > DAN_GW_NODE_OFFLINE_US || n->e.mode == DAN_DC_MODE_OFFLINE;
}

/* The NODES entry's last byte: the info state and the node's flags. */
uint8_t dan_gwn_node_flags(const dan_gw_node_t *g, const dan_gw_node_slot_t *n, uint64_t now_us)
{
    uint8_t f = n->e.info_state;
    if (n->duplicate) {
        f |= DAN_GW_NODE_DUPLICATE;
    }
    if (dan_gwn_offline(n, now_us)) {
        f |= DAN_GW_NODE_OFFLINE;
    }
    if (dan_gwn_dna_entry(g, n->e.node_id) != NULL) {
        f |= DAN_GW_NODE_ALLOCATED;
    }
    return f;
}

uint32_t dan_gwn_table_count(const dan_gw_node_t *g)
{
    uint32_t n = 0;
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        n += g->nodes[i].e.node_id != 0u;
    }
    return n;
}

/* A free slot, or, when the table is full, the slot of the node silent the
 * longest past DroneCAN's offline timeout; NULL if none. */
static dan_gw_node_slot_t *slot_for_new(dan_gw_node_t *g, uint64_t now_us)
{
    dan_gw_node_slot_t *best = dan_gwn_find_node(g, 0);
    size_t i;
    if (best != NULL) {
        return best;
    }
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        dan_gw_node_slot_t *c = &g->nodes[i];
        if (dan_gwn_offline(c, now_us) && (best == NULL || c->seen_us < best->seen_us)) {
            best = c;
        }
    }
    return best;
}

static void flag_duplicate(dan_gw_node_t *g, dan_gw_node_slot_t *n)
{
    if (!n->duplicate) {
        n->duplicate = true;
        g->stats.duplicates++;
    }
}

/* Two nodes with one ID interleave their NodeStatus: the uptime goes down
 * again and again. A node that really restarted does it once. */
static void uptime_went_down(dan_gw_node_t *g, dan_gw_node_slot_t *n, uint64_t now_us)
{
    if (n->drops == 0u || now_us - n->drops_since_us > DAN_GW_NODE_FLAP_US) {
        n->drops = 0;
        n->drops_since_us = now_us;
    }
    if (++n->drops >= DAN_GW_NODE_FLAP_COUNT) {
        flag_duplicate(g, n);
    }
}

/* A GetNodeInfo answer's unique ID: a duplicate if the allocation table
 * gave this ID to another unique ID, or if an earlier unique ID of this
 * node ID comes back after another one. */
static void check_uid(dan_gw_node_t *g, dan_gw_node_slot_t *n, const uint8_t *uid)
{
    const dan_gw_dna_entry_t *a = dan_gwn_dna_entry(g, n->e.node_id);
    bool had = n->info.info_state == DAN_GW_INFO_VALID;
    if (a != NULL && memcmp(a->unique_id, uid, DAN_DC_UNIQUE_ID_SIZE) != 0) {
        flag_duplicate(g, n);
    }
    if (had && memcmp(n->info.unique_id, uid, DAN_DC_UNIQUE_ID_SIZE) != 0) {
        if (n->had_uid && memcmp(n->prev_uid, uid, DAN_DC_UNIQUE_ID_SIZE) == 0) {
            flag_duplicate(g, n);
        }
        memcpy(n->prev_uid, n->info.unique_id, DAN_DC_UNIQUE_ID_SIZE);
        n->had_uid = true;
    }
}

static void ask_info_again(dan_gw_node_slot_t *n, uint64_t now_us)
{
    n->e.info_state = DAN_GW_INFO_NONE;
    n->info_tries = 0;
    n->info_due_us = now_us;
}

void dan_gwn_on_node_status(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_node_status_t s;
    dan_gw_node_slot_t *n;
    if (t->source_node == 0u ||
        dan_dc_node_status_decode(&s, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    /* in use from now on, even if the table has no room for it */
    g->dna.seen[t->source_node / 8u] |= (uint8_t)(1u << (t->source_node % 8u));
    n = dan_gwn_find_node(g, t->source_node);
    if (n == NULL) {
        n = slot_for_new(g, now_us);
        if (n == NULL) {
            g->stats.nodes_dropped++;
            return;
        }
        memset(n, 0, sizeof *n);
        n->e.node_id = t->source_node;
        n->info_due_us = now_us;
    } else if (s.uptime_sec < n->e.uptime_sec) {
        /* restarted: its software may have changed */
        ask_info_again(n, now_us);
        uptime_went_down(g, n, now_us);
    } else if (n->e.mode == DAN_DC_MODE_SOFTWARE_UPDATE && s.mode == DAN_DC_MODE_OPERATIONAL) {
        /* an update done without a restart we saw (its uptime kept
         * counting, or a NodeStatus lost): the version may be new */
        ask_info_again(n, now_us);
    }
    n->e.health = s.health;
    n->e.mode = s.mode;
    n->e.sub_mode = s.sub_mode;
    n->e.uptime_sec = s.uptime_sec;
    n->e.vendor_status = s.vendor_specific_status_code;
    if (dan_gwn_offline(n, now_us)) {
        n->duplicate = false; /* it was gone: judge it afresh */
        n->drops = 0;
    }
    if (t->source_node == g->cfg.node_id) {
        flag_duplicate(g, n); /* another device sends with our node ID */
    }
    n->seen_us = now_us;
}

void dan_gwn_on_node_info_rsp(dan_gw_node_t *g, const dan_dc_transfer_t *t)
{
    dan_dc_get_node_info_rsp_t *rp = &g->scratch.info;
    dan_gw_node_slot_t *n = dan_gwn_find_node(g, t->source_node);
    size_t len;
    if (n == NULL || dan_dc_get_node_info_rsp_decode(rp, t->payload, t->payload_len) != DAN_OK) {
        return;
    }
    check_uid(g, n, rp->hardware_version.unique_id);
    n->info.node_id = n->e.node_id;
    n->info.info_state = DAN_GW_INFO_VALID;
    n->info.sw_major = rp->software_version.major;
    n->info.sw_minor = rp->software_version.minor;
    n->info.sw_flags = rp->software_version.optional_field_flags;
    n->info.vcs_commit = rp->software_version.vcs_commit;
    n->info.hw_major = rp->hardware_version.major;
    n->info.hw_minor = rp->hardware_version.minor;
    memcpy(n->info.unique_id, rp->hardware_version.unique_id, DAN_DC_UNIQUE_ID_SIZE);
    len =
        rp->name_len > DAN_DC_GET_NODE_INFO_NAME_MAX ? DAN_DC_GET_NODE_INFO_NAME_MAX : rp->name_len;
    memcpy(n->info.name, rp->name, len);
    n->info.name[len] = '\0';
    n->e.info_state = DAN_GW_INFO_VALID;
}

static void request_info(dan_gw_node_t *g, dan_gw_node_slot_t *n, uint64_t now_us)
{
    dan_dc_transfer_t t;
    dan_dc_transfer_init(&t, DAN_DC_GET_NODE_INFO_ID, DAN_DC_GET_NODE_INFO_SIGNATURE,
                         DAN_DC_TRANSFER_REQUEST, NULL, 0);
    t.priority = DAN_DC_PRIORITY_LOW;
    t.destination_node = n->e.node_id;
    t.transfer_id = n->info_tid;
    if (dan_gwn_send_transfer(g, &g->q_bulk, &t) == DAN_OK) {
        n->info_tid = (uint8_t)((n->info_tid + 1u) & DAN_DC_TRANSFER_ID_MASK);
        g->stats.info_requests++;
    }
    n->info_tries++;
    n->e.info_state = DAN_GW_INFO_PENDING;
    n->info_due_us = now_us + DAN_GW_NODE_INFO_RETRY_US;
}

static bool info_wanted(const dan_gw_node_slot_t *n)
{
    return n->e.node_id != 0u &&
           (n->e.info_state == DAN_GW_INFO_NONE || n->e.info_state == DAN_GW_INFO_PENDING);
}

void dan_gwn_table_poll(dan_gw_node_t *g, uint64_t now_us)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        dan_gw_node_slot_t *n = &g->nodes[i];
        if (!info_wanted(n) || now_us < n->info_due_us) {
            continue;
        }
        if (n->info_tries >= DAN_GW_NODE_INFO_TRIES) {
            n->e.info_state = DAN_GW_INFO_FAILED;
        } else {
            request_info(g, n, now_us);
        }
    }
}

uint64_t dan_gwn_table_next_us(const dan_gw_node_t *g, uint64_t t)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        const dan_gw_node_slot_t *n = &g->nodes[i];
        if (info_wanted(n) && n->info_due_us < t) {
            t = n->info_due_us;
        }
    }
    return t;
}
