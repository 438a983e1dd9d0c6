/* The master engine's files share these (not part of the API):
 * master.c runs transactions, master_seq.c discovery, configure,
 * recovery and the negotiation of fast bauds. */
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
/* Runs the sequencer until it waits for a transaction or has finished. */
void dan_mst_seq_next(dan_master_t *m, uint32_t now_us);
/* Takes the result of the sequencer's transaction, then goes on. */
void dan_mst_seq_txn_done(dan_master_t *m, uint32_t now_us);

#endif /* DAN_MASTER_INTERNAL_H */
