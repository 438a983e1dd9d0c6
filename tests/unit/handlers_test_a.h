/* The test-a type's request handlers, shared by the unit tests
 * (test_engines.c) and the end-to-end peripheral (dan-testperiph). */
#ifndef DAN_HANDLERS_TEST_A_H
#define DAN_HANDLERS_TEST_A_H

#include "dan/peripheral.h"

/* 0x62 replies with the payload reversed (an empty one is malformed);
 * 0x63 is a command without a reply that counts its calls in the type's
 * user pointer, an unsigned. */
#define TEST_A_NHANDLERS 2u
extern const dan_handler_t test_a_handlers[TEST_A_NHANDLERS];

/* The test-a type of the unit tests' peripherals: these handlers, identity
 * "DAN Project" "test A" (the defined bauds); *calls counts 0x63's calls. */
dan_ptype_t test_a_type(unsigned *calls);

#endif /* DAN_HANDLERS_TEST_A_H */
