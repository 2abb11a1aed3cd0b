// The user's knobs. Thresholds are relative (to the brightest emitter, to the scene's size) so that
// a scene baked in millimetres or kilometres refines the same way.
#pragma once
#include <cstddef>

namespace penumbra {

struct Settings {
    double epsilon = 0.0002;      // max radiosity error of a link, relative to the brightest emitter
    double minSize = 0.01;       // smallest element edge, relative to the scene's bounding-box diagonal
    int visibilityRays = 16;     // rays per link estimate (rounded to a square number of strata)
    int maxIterations = 5000;    // sweeps per refinement pass; albedo 0.99 needs ~1000 for 1e-4
    double tolerance = 1e-4;     // stop when the estimated remaining relative error falls below this
    int refinePasses = 3;        // refine -> solve rounds (later passes refine with indirect light)
    int threads = 0;             // 0: all cores
    bool clustering = true;      // refine from one root <-> root cluster link instead of all face pairs
    // Convolution links (Soler & Sillion 1998, Fig. 4): a large planar receiver lit by a planar emitter
    // through blockers gets one soft shadow texture instead of a subdivided mesh of standard links.
    bool convolution = true;
    double aMin = 0.15;          // smallest receiver for a convolution link: box diagonal / scene diagonal
    double eMax = 1.0;           // largest blocker error E_rr of a convolution link, in texels of half the narrowest penumbra
    double tMax = 0.05;          // largest predicted FFT time of one convolution link, seconds
    int maxTexture = 512;        // largest soft shadow texture, texels per side
    // Final gather: the emitters' light is evaluated exactly at every bake point (form factor times
    // visibility) instead of read from the elements; the hierarchy carries the reflected remainder.
    bool finalGather = true;
    // Visibility of the gathered light: 0 takes it from the hierarchy's links (their shadowed over
    // unoccluded light, blended like the radiosity); N > 0 casts up to N rays per emitter group and
    // point to fixed low-discrepancy points (exact in full light and umbra, but a detailed shadow
    // such as a lattice shade needs hundreds: 4.8 % RMS with 64, 1.6 % with 256, against 0.9 % from
    // the links).
    int gatherRays = 0;
    // Budgets: a scene that would exceed one stops with BudgetExceeded before the memory is taken,
    // instead of being killed by the system (or, for face pairs, running for hours).
    size_t maxElements = 2000000;    // quadtree elements, ~400 bytes each at the peak (canonicalize)
    size_t maxLinks = 30000000;      // links, ~72 bytes each at the peak (per-thread lists, merge, sort)
    double maxFacePairs = 1e9;       // receiver x source face pairs linkAll visits without clustering
    size_t maxTexels = size_t(8192) * 8192;  // one bake_lightmap call, ~60 bytes each
};

}  // namespace penumbra
