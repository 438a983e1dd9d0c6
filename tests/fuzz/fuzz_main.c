/* libFuzzer entry: one binary per target, chosen at compile time with
 * -DDAN_FUZZ_FN=dan_fuzz_<target> (tests/fuzz/fuzz.mk). */
#include "targets.h"

#ifndef DAN_FUZZ_FN
#error "define DAN_FUZZ_FN"
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return DAN_FUZZ_FN(data, size);
}
