/* Gateway node: the dynamic node ID allocation server
 * (uavcan.protocol.dynamic_node_id.Allocation, docs/PROTOCOL.md "Bus
 * management"), its table and the table's storage. */
#include <string.h>

#include "gw_node_internal.h"

#define BLOB_MAGIC     "DNA1"
#define BLOB_MAGIC_LEN 4u
#define UID_STAGES_LEN 12u /* bytes of unique ID after two stages of 6 */

static dan_gw_dna_entry_t *entry_of_uid(dan_gw_node_t *g, const uint8_t *uid)
{
    size_t i;
    for (i = 0; i < g->dna.n; i++) {
        if (memcmp(g->dna.table[i].unique_id, uid, DAN_DC_UNIQUE_ID_SIZE) == 0) {
            return &g->dna.table[i];
        }
    }
    return NULL;
}

const dan_gw_dna_entry_t *dan_gwn_dna_entry(const dan_gw_node_t *g, uint8_t node_id)
{
    size_t i;
    for (i = 0; i < g->dna.n; i++) {
        if (g->dna.table[i].node_id == node_id) {
            return &g->dna.table[i];
        }
    }
    return NULL;
}

/* ---- storage: "DNA1", u8 count, entries, u16 CRC-16/CCITT-FALSE ---- */

static size_t blob_make(const dan_gw_node_t *g, uint8_t *b)
{
    size_t i, len = BLOB_MAGIC_LEN;
    uint16_t crc;
    memcpy(b, BLOB_MAGIC, BLOB_MAGIC_LEN);
    b[len++] = g->dna.n;
    for (i = 0; i < g->dna.n; i++) {
        b[len++] = g->dna.table[i].node_id;
        memcpy(&b[len], g->dna.table[i].unique_id, DAN_DC_UNIQUE_ID_SIZE);
        len += DAN_DC_UNIQUE_ID_SIZE;
    }
    crc = dan_crc16_ccitt(0xFFFFu, b, len);
    b[len++] = (uint8_t)crc;
    b[len++] = (uint8_t)(crc >> 8);
    return len;
}

static const char *const blob_errors[] = {
    "ok",
    "shorter than an empty table",
    "wrong magic (not a DNA1 table)",
    "more entries than the table holds",
    "length does not match the entry count",
    "CRC mismatch",
    "node ID out of range 1..125",
    "a node ID or unique ID appears twice",
};

const char *dan_gw_dna_blob_error(int r)
{
    return r >= 0 && (size_t)r < sizeof blob_errors / sizeof blob_errors[0] ? blob_errors[r]
                                                                            : "unknown";
}

static const uint8_t *blob_entry(const uint8_t *b, size_t i)
{
    return &b[BLOB_MAGIC_LEN + 1u + i * DAN_GW_DNA_ENTRY_SIZE];
}

/* Entries: IDs in range, no node ID and no unique ID twice. */
static int blob_entries_check(const uint8_t *b, size_t n)
{
    size_t i, j;
    for (i = 0; i < n; i++) {
        const uint8_t *e = blob_entry(b, i);
        if (e[0] < 1u || e[0] > DAN_DC_ALLOCATION_MAX_NODE_ID) {
            return DAN_GW_DNA_BLOB_NODE_ID;
        }
        for (j = 0; j < i; j++) {
            const uint8_t *f = blob_entry(b, j);
            if (f[0] == e[0] || memcmp(f + 1, e + 1, DAN_DC_UNIQUE_ID_SIZE) == 0) {
                return DAN_GW_DNA_BLOB_TWICE;
            }
        }
    }
    return DAN_GW_DNA_BLOB_OK;
}

int dan_gw_dna_blob_check(const uint8_t *b, size_t len)
{
    size_t n;
    if (len < BLOB_MAGIC_LEN + 3u) {
        return DAN_GW_DNA_BLOB_SHORT;
    }
    if (memcmp(b, BLOB_MAGIC, BLOB_MAGIC_LEN) != 0) {
        return DAN_GW_DNA_BLOB_MAGIC;
    }
    n = b[BLOB_MAGIC_LEN];
    if (n > DAN_GW_NODE_DNA_MAX) {
        return DAN_GW_DNA_BLOB_COUNT;
    }
    if (len != BLOB_MAGIC_LEN + 1u + n * DAN_GW_DNA_ENTRY_SIZE + 2u) {
        return DAN_GW_DNA_BLOB_LENGTH;
    }
    if (dan_crc16_ccitt(0xFFFFu, b, len - 2u) != (uint16_t)(b[len - 2u] | b[len - 1u] << 8)) {
        return DAN_GW_DNA_BLOB_CRC;
    }
    return blob_entries_check(b, n);
}

/* Takes a stored table only if every byte of it checks. */
static bool blob_take(dan_gw_node_t *g, const uint8_t *b, size_t len)
{
    size_t i, n;
    if (dan_gw_dna_blob_check(b, len) != DAN_GW_DNA_BLOB_OK) {
        return false;
    }
    n = b[BLOB_MAGIC_LEN];
    for (i = 0; i < n; i++) {
        const uint8_t *e = blob_entry(b, i);
        g->dna.table[i].node_id = e[0];
        memcpy(g->dna.table[i].unique_id, e + 1, DAN_DC_UNIQUE_ID_SIZE);
    }
    g->dna.n = (uint8_t)n;
    return true;
}

void dan_gwn_dna_load(dan_gw_node_t *g)
{
    const dan_gw_storage_t *st = g->cfg.dna_storage;
    uint8_t b[DAN_GW_DNA_BLOB_MAX];
    int len;
    if (st == NULL || st->load == NULL) {
        return;
    }
    len = st->load(st->ctx, b, sizeof b);
    if (len > 0 && blob_take(g, b, (size_t)len)) {
        g->dna.flags |= DAN_GW_DNA_LOADED;
    } else if (len != 0) {
        g->dna.flags |= DAN_GW_DNA_STORE_ERROR; /* corrupt or unreadable: not trusted */
    }
}

static void store(dan_gw_node_t *g)
{
    const dan_gw_storage_t *st = g->cfg.dna_storage;
    uint8_t b[DAN_GW_DNA_BLOB_MAX];
    g->dna.dirty = false;
    if (st == NULL || st->store == NULL) {
        return;
    }
    if (st->store(st->ctx, b, blob_make(g, b)) != DAN_OK) {
        g->dna.flags |= DAN_GW_DNA_STORE_ERROR;
    }
}

/* ---- allocation ---- */

/* In use: ours, in the table, or seen on the bus (a NodeStatus since
 * start: the node table may have had no room for it, or given its slot to
 * a newer node after it went silent; review finding). */
static bool occupied(dan_gw_node_t *g, unsigned id)
{
    return id == g->cfg.node_id || dan_gwn_dna_entry(g, (uint8_t)id) != NULL ||
           (g->dna.seen[id / 8u] & (1u << (id % 8u))) != 0u;
}

/* The specification's findFreeNodeID: up from the preferred ID, then down;
 * without a preference, the highest free one. 0 if none. A preference of
 * 126 or 127 (reserved for maintenance tools, never allocated) counts as
 * 125: the pseudocode's downward search would start at it and grant it
 * (found by the dna fuzz target). */
static uint8_t free_id(dan_gw_node_t *g, uint8_t preferred)
{
    unsigned start = DAN_DC_ALLOCATION_MAX_NODE_ID, id;
    if (preferred > 0u && preferred < start) {
        start = preferred;
    }
    for (id = start; id <= DAN_DC_ALLOCATION_MAX_NODE_ID; id++) {
        if (!occupied(g, id)) {
            return (uint8_t)id;
        }
    }
    for (id = start; id > 0u; id--) {
        if (!occupied(g, id)) {
            return (uint8_t)id;
        }
    }
    return 0;
}

/* Broadcasts our answer: the bytes received so far, and the node ID once
 * allocated (0 before). */
static void answer(dan_gw_node_t *g, uint8_t node_id)
{
    dan_dc_allocation_t m;
    uint8_t buf[DAN_DC_ALLOCATION_MAX_SIZE];
    memset(&m, 0, sizeof m);
    m.node_id = node_id;
    m.uid_len = g->dna.query_len;
    memcpy(m.uid, g->dna.query, g->dna.query_len);
    /* only the newest answer matters (it carries the one query in
     * progress): a flood of requests never fills the queue; bulk, so
     * that a CAN node's request never puts frames in front of throttle */
    dan_gwn_drop_own(g, &g->q_bulk, DAN_DC_ALLOCATION_ID);
    (void)dan_gwn_broadcast(g, &g->q_bulk, DAN_DC_ALLOCATION_ID, DAN_DC_ALLOCATION_SIGNATURE,
                            DAN_DC_PRIORITY_LOW, buf,
                            dan_dc_allocation_encode(&m, buf, sizeof buf));
}

/* The ID the table holds for a unique ID is given again unless it became
 * the gateway's own (its node ID changed) or a node of the node table uses
 * it that is not proven to be this device: its GetNodeInfo gave another
 * unique ID (found by the dna fuzz target), or gave none yet or failed (a
 * static node that came up at that ID: review finding, the ID went to two
 * devices). */
static bool entry_usable(dan_gw_node_t *g, const dan_gw_dna_entry_t *e)
{
    const dan_gw_node_slot_t *n = dan_gwn_find_node(g, e->node_id);
    return e->node_id != g->cfg.node_id &&
           (n == NULL || (n->info.info_state == DAN_GW_INFO_VALID &&
                          memcmp(n->info.unique_id, e->unique_id, DAN_DC_UNIQUE_ID_SIZE) == 0));
}

static bool discovering(const dan_gw_node_t *g);

/* All 16 bytes arrived: the same ID again for a known unique ID (while
 * usable), else a free one, stored. */
static void allocate(dan_gw_node_t *g, uint8_t preferred)
{
    dan_gw_dna_entry_t *e = entry_of_uid(g, g->dna.query);
    uint8_t id;
    if (discovering(g)) {
        /* a node appeared during the handshake: no answer until its
         * GetNodeInfo is in (the allocatee starts over after its timeout) */
        g->dna.query_len = 0;
        return;
    }
    if (e == NULL || !entry_usable(g, e)) {
        id = free_id(g, preferred);
        if (id == 0u || (e == NULL && g->dna.n >= DAN_GW_NODE_DNA_MAX)) {
            g->dna.full = true;
            g->dna.query_len = 0;
            return;
        }
        if (e == NULL) {
            e = &g->dna.table[g->dna.n++];
            memcpy(e->unique_id, g->dna.query, DAN_DC_UNIQUE_ID_SIZE);
        }
        e->node_id = id;
        g->dna.dirty = true;
    }
    g->dna.full = false;
    g->stats.dna_allocations++;
    answer(g, e->node_id);
    g->dna.query_len = 0;
}

/* The allocator waits while nodes of the table are still being asked for
 * their GetNodeInfo ("all nodes discovered"). */
static bool discovering(const dan_gw_node_t *g)
{
    size_t i;
    for (i = 0; i < DAN_GW_NODE_MAX_NODES; i++) {
        uint8_t st = g->nodes[i].e.info_state;
        if (g->nodes[i].e.node_id != 0u && (st == DAN_GW_INFO_NONE || st == DAN_GW_INFO_PENDING)) {
            return true;
        }
    }
    return false;
}

static void on_request(dan_gw_node_t *g, const dan_dc_allocation_t *m, uint64_t now_us)
{
    size_t want;
    if (g->dna.query_len > 0u && now_us - g->dna.query_us > DAN_DC_ALLOCATION_FOLLOWUP_US) {
        g->dna.query_len = 0; /* the allocatee gave up: start over */
    }
    if (m->first_part) {
        if (m->uid_len != DAN_DC_ALLOCATION_UID_PER_REQUEST || discovering(g)) {
            g->stats.dna_bad += m->uid_len != DAN_DC_ALLOCATION_UID_PER_REQUEST;
            return;
        }
        g->dna.query_len = 0;
    } else {
        want = DAN_DC_UNIQUE_ID_SIZE - g->dna.query_len;
        if (g->dna.query_len == 0u || m->uid_len != (want < DAN_DC_ALLOCATION_UID_PER_REQUEST
                                                         ? want
                                                         : DAN_DC_ALLOCATION_UID_PER_REQUEST)) {
            g->stats.dna_bad++;
            return;
        }
    }
    memcpy(&g->dna.query[g->dna.query_len], m->uid, m->uid_len);
    g->dna.query_len = (uint8_t)(g->dna.query_len + m->uid_len);
    g->dna.query_us = now_us;
    if (g->dna.query_len < DAN_DC_UNIQUE_ID_SIZE) {
        answer(g, 0);
    } else {
        allocate(g, m->node_id);
    }
}

void dan_gwn_on_allocation(dan_gw_node_t *g, const dan_dc_transfer_t *t, uint64_t now_us)
{
    dan_dc_allocation_t m;
    if (dan_dc_allocation_decode(&m, t->payload, t->payload_len) != DAN_OK) {
        g->stats.dna_bad++;
        return;
    }
    if (t->source_node != 0u) {
        /* another allocator is a configuration error only while ours runs */
        if (t->source_node != g->cfg.node_id && g->cfg.dna) {
            g->dna.foreign = t->source_node;
            g->dna.foreign_us = now_us;
            g->stats.dna_foreign++;
        }
        return;
    }
    if (g->cfg.dna) {
        on_request(g, &m, now_us);
    }
}

void dan_gwn_dna_poll(dan_gw_node_t *g)
{
    if (g->dna.dirty) {
        store(g);
    }
}

void dan_gw_node_set_dna(dan_gw_node_t *g, bool on)
{
    if (g->cfg.dna == on) {
        return; /* a CONFIG that repeats it leaves an allocation in progress alone */
    }
    g->cfg.dna = on;
    g->dna.query_len = 0;
    if (!on) {
        /* off, nothing of the server's is a health reason any more
         * (PROTOCOL.md: "another allocator is the bus's allocator and no
         * conflict"); they were latched (review finding) */
        g->dna.full = false;
        g->dna.foreign = 0;
    }
}

/* DNA page: entries from index first while they fit. */
void dan_gwn_dna_page(const dan_gw_node_t *g, uint8_t first, size_t room, dan_gw_dna_hdr_t *h)
{
    size_t fit =
        room > DAN_GW_DNA_HDR_SIZE ? (room - DAN_GW_DNA_HDR_SIZE) / DAN_GW_DNA_ENTRY_SIZE : 0u;
    h->flags = (uint8_t)(g->dna.flags | (g->cfg.dna ? DAN_GW_DNA_ON : 0u));
    h->entries = g->dna.n;
    h->capacity = (uint8_t)DAN_GW_NODE_DNA_MAX;
    h->count = 0;
    h->next = DAN_GW_NONE;
    if (first < g->dna.n) {
        size_t left = (size_t)g->dna.n - first;
        h->count = (uint8_t)(left < fit ? left : fit);
        if (first + h->count < g->dna.n) {
            h->next = (uint8_t)(first + h->count);
        }
    }
}
