/* The master engine's files share these (not part of the API):
 * master.c runs transactions, master_seq.c discovery, configure and
 * recovery, master_fast.c the negotiation of fast bauds. */
#ifndef DAN_MASTER_INTERNAL_H
#define DAN_MASTER_INTERNAL_H

#include "dan/master.h"

/* Sequencer steps (dan_master_t.step). */
enum {
    DAN_ST_NONE = 0,
    DAN_ST_DISC_PROBE,     /* discovery: probing types[idx] at scan baud bidx */
    DAN_ST_CFG_SEND,       /* configure: CONFIGURE to peers[idx] */
    DAN_ST_CFG_VERIFY,     /* configure: IDENTIFY peers[idx] at the target */
    DAN_ST_REC_FIND,       /* recovery: looking for peers[idx] at candidate bidx */
    DAN_ST_REC_BACK,       /* recovery: CONFIGURE(9600) to peers[idx] */
    DAN_ST_REC_VERIFY,     /* recovery: IDENTIFY peers[idx] at 9600 */
    DAN_ST_FAST_SEND,      /* fast baud: CONFIGURE(candidate) to peers[idx] */
    DAN_ST_FAST_BACK,      /* fast baud refused: CONFIGURE(back) to a moved peer */
    DAN_ST_FAST_BACK_CHECK /* and IDENTIFY it at its old baud */
};

/* master.c */
void dan_mst_txn_start(dan_master_t *m, uint32_t code, const uint8_t *payload, size_t len,
                       uint8_t attempts, uint32_t now_us);
bool dan_mst_port_supports(const dan_master_t *m, uint32_t baud);
/* Also keeps now_us for dan_master_next_us() (the link's 64-bit time). */
int dan_mst_op_begin(dan_master_t *m, dan_master_op_t op, uint64_t now_us);
void dan_mst_op_finish(dan_master_t *m, int result);

/* master_seq.c */
void dan_mst_seq_next(dan_master_t *m, uint32_t now_us);
/* Takes the result of the sequencer's transaction; true if the caller is
 * to go on with dan_mst_seq_next() (called one after the other, not one
 * inside the other: the deepest stack path, issue 17). */
bool dan_mst_seq_txn_done(dan_master_t *m, uint32_t now_us);
void dan_mst_switch_baud(dan_master_t *m, uint32_t baud, uint32_t now_us);
void dan_mst_probe(dan_master_t *m, uint32_t first, uint8_t attempts, uint32_t now_us);
void dan_mst_send_configure(dan_master_t *m, uint32_t first, uint32_t baud, uint32_t now_us);
bool dan_mst_ack_ok(const dan_master_t *m);
int dan_mst_txn_error(const dan_master_t *m);
void dan_mst_start_recovery(dan_master_t *m, int why);
/* CONFIGURE(target) to the next peer from idx on that ask() picks, at
 * its baud: true if one was sent. */
bool dan_mst_configure_next(dan_master_t *m, bool (*ask)(const dan_master_t *m, size_t i),
                            uint32_t now_us);
/* Switches to the target and verifies every peer there. */
void dan_mst_start_verify(dan_master_t *m, uint32_t now_us);
/* Configure at the best mask baud of the peers left (the v1 sequence). */
void dan_mst_start_v1_configure(dan_master_t *m);

/* master_fast.c */
/* The fast bauds this master offers (cfg.fast_*, the port's maximum),
 * highest first, without the v1 bauds; returns the count. Baud k goes to
 * out[k - skip] for skip <= k < skip + cap (out may be NULL if cap is 0):
 * computed again when needed rather than kept in dan_master_t (RAM). */
size_t dan_mst_fast_list(const dan_master_t *m, uint32_t *out, size_t skip, size_t cap);
/* Configure's candidate i: the baud the caller named, or fast baud i. */
uint32_t dan_mst_cand(const dan_master_t *m, size_t i);
/* Starts candidate m->cidx, or the v1 fallback (auto), or finishes with
 * the refusal (a baud the caller named). Returns true when finished. */
bool dan_mst_fast_candidate(dan_master_t *m);
/* The fast steps of dan_mst_seq_next() and dan_mst_seq_txn_done(). */
bool dan_mst_fast_step(dan_master_t *m, uint32_t now_us);
void dan_mst_fast_txn_done(dan_master_t *m, uint32_t now_us);

#endif /* DAN_MASTER_INTERNAL_H */
