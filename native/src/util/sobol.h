// The first two dimensions of Sobol's sequence: fixed, stratified sample points shared by every bake
// point, so that sampled visibility is free of noise (a penumbra becomes a fine staircase instead).
#pragma once
#include <cstdint>

namespace penumbra {

// Dimension 0 is the base-2 radical inverse, dimension 1 Sobol's second (Pascal-matrix) dimension.
inline double sobol(uint32_t k, int dim) {
    uint32_t r = 0;
    for (uint32_t v = 1u << 31; k; k >>= 1, v = dim ? v ^ (v >> 1) : v >> 1)
        if (k & 1) r ^= v;
    return r * (1.0 / 4294967296.0);
}

}  // namespace penumbra
