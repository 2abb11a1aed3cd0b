// Turns arbitrary bytes into a scene, solves it with cheap settings and probes the result. Shared by
// the libFuzzer target (native/fuzz/fuzz_scene.cpp) and the gtest that replays saved inputs, so a
// crash found by the fuzzer replays exactly in CI.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

#include "testing/scenes.h"

namespace penumbra::testing {

// The scene the bytes describe: up to 64 vertices and 32 faces with arbitrary (possibly invalid)
// indices, coordinates, albedos, emissions, flags and object indices.
TestScene decodeFuzzScene(const uint8_t* data, size_t size);

enum class FuzzOutcome { Solved, Refused };

// Solves the decoded scene. Bad input must come back as InputError (Refused); anything else thrown
// escapes. A NaN, infinite or negative radiance or texel aborts, so the fuzzer records it.
FuzzOutcome runFuzzInput(const uint8_t* data, size_t size);

}  // namespace penumbra::testing
