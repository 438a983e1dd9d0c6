/* Fuzz entry functions shared by the libFuzzer binaries (tests/fuzz/fuzz.mk)
 * and the plain replay test (tests/unit/test_fuzz_regressions.c).
 *
 * Each function takes one input of any length and content. It returns 0;
 * a broken invariant calls abort() (so libFuzzer and the replay test both
 * see it), and memory errors are caught by ASan/UBSan. */
#ifndef DAN_FUZZ_TARGETS_H
#define DAN_FUZZ_TARGETS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

/* An invariant: abort() when it breaks (libFuzzer and the replay see it),
 * naming the check. */
#define FUZZ_CHECK(cond)                                                                  \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            fprintf(stderr, "%s:%d: fuzz check failed: %s\n", __FILE__, __LINE__, #cond); \
            abort();                                                                      \
        }                                                                                 \
    } while (0)

typedef int (*dan_fuzz_fn)(const uint8_t *data, size_t len);

typedef struct {
    const char *name; /* also the corpus / regression directory name */
    dan_fuzz_fn fn;
} dan_fuzz_target_t;

int dan_fuzz_frame(const uint8_t *data, size_t len);       /* frame decoder */
int dan_fuzz_payloads(const uint8_t *data, size_t len);    /* identity, configure, ack, error */
int dan_fuzz_gw_handlers(const uint8_t *data, size_t len); /* gateway node via dan_periph_rx */
int dan_fuzz_dronecan_rx(const uint8_t *data, size_t len); /* reassembly + DSDL decode */
int dan_fuzz_dsdl(const uint8_t *data, size_t len);        /* DSDL decoders */
int dan_fuzz_slcan(const uint8_t *data, size_t len);       /* dan_slcan_parse_line */
int dan_fuzz_gw_client(const uint8_t *data, size_t len);   /* client response decoders */
int dan_fuzz_dna(const uint8_t *data, size_t len);         /* allocation server and node table */
int dan_fuzz_file_names(const uint8_t *data, size_t len);  /* file name and DroneCAN path rule */
int dan_fuzz_file_dir(const uint8_t *data, size_t len);    /* the Linux directory store */
int dan_fuzz_gw_msgs(const uint8_t *data, size_t len);     /* gateway message codecs, both ways */

extern const dan_fuzz_target_t dan_fuzz_targets[];
extern const size_t dan_fuzz_ntargets;

#endif
