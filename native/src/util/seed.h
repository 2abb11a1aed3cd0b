// The `seed` setting: which of many equally good sample patterns a bake uses. Every random stream (a link's
// rays, a face's share) is seeded by the identities of its elements, so a bake does not depend on thread
// timing; the seed is mixed into those seeds, and turns the fixed Sobol' nets of the lamps and the gather by a
// toroidal shift. Seed 0 leaves every pattern as it was before the setting existed. Two seeds' bakes differ by
// the sampling noise alone, which is how that noise is measured (bench/seed_spread.py).
#pragma once
#include <cstdint>

namespace penumbra {

// SplitMix64's finaliser: nearby seeds give unrelated salts.
inline uint64_t mixBits(uint64_t x) {
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

// What a stream seeded by `key` starts from under `seed`: `key` itself for seed 0.
inline uint64_t seeded(uint64_t key, int seed) {
    return seed == 0 ? key : mixBits(key ^ mixBits(uint64_t(uint32_t(seed)) * 0x9E3779B97F4A7C15ull));
}

// The toroidal shift of a Sobol' net under `seed`, in [0, 1)^2: {0, 0} for seed 0.
inline void seedShift(int seed, double shift[2]) {
    if (seed == 0) {
        shift[0] = shift[1] = 0;
        return;
    }
    uint64_t h = mixBits(uint64_t(uint32_t(seed)) + 0x632BE59BD9B4E019ull);
    shift[0] = double(h & 0xFFFFFFFFu) / 4294967296.0;
    shift[1] = double(h >> 32) / 4294967296.0;
}

}  // namespace penumbra
