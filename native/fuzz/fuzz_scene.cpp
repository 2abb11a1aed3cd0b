// libFuzzer entry: bytes -> SceneInput arrays -> penumbra::solve -> radiance and a lightmap.
// Built and run by scripts/fuzz.sh; crashing inputs go to native/fuzz/regressions/, which
// penumbra_tests replays (native/src/testing/fuzz_replay_test.cpp).
#include <cstddef>
#include <cstdint>

#include "testing/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    penumbra::testing::runFuzzInput(data, size);
    return 0;
}
