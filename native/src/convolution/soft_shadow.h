// Soft shadow textures by convolution (Soler & Sillion 1998, brief §1-§5 and §9).
//
// Public interface, as the solver uses it:
//   ConvolutionPlan   planSoftShadow(source, blockers, receiver, settings)
//       cheap (depth ranges only): frame, window, resolution n, sub-blockers, E_rr, alpha_min,
//       FFT size. The refiner compares E_rr with e_max and predictedSeconds(plan.fftSize,
//       plan.slices.size()) (cost_model.h) with t_max before it creates a ConvolutionLink.
//   SoftShadowTexture computeSoftShadow(plan, source, blockers, settings)
//   SoftShadowTexture computeSoftShadow(source, blockers, receiver, settings)   // plan + compute
//       the visibility texture V (n x n floats in [0, 1]) and its homogeneous texture matrix.
//   float             lookupVisibility(texture, P)
//       V at any 3D point P by central projection from the source centre (bilinear).
// Bad input throws std::invalid_argument; a configuration the convolution cannot handle (the
// source, blocker and receiver do not follow each other in depth, ...) throws std::domain_error.
// Everything is thread-safe: links may be computed concurrently.
//
// Conventions: V is emission-weighted visible fraction of the source; visibility[t * n + s] with s
// along the frame's u axis and t along v (rows run along t); texel (a, c) is sampled at its centre.
// E_rr is measured in texels (half the spread of the penumbra width that one kernel per
// sub-blocker cannot represent); alpha_min is the smallest penumbra scale (penumbra width =
// alpha * L_S in virtual-receiver-plane units).
#pragma once
#include <array>
#include <string>
#include <vector>

#include "convolution/frame.h"
#include "convolution/raster.h"
#include "geometry/vec3.h"

namespace penumbra {

using BlockerTriangle = std::array<Vec3, 3>;

// Emission over the source's own parametrisation: s runs along the first polygon edge
// (v0 -> v1), t along n x s (n = right-hand normal of the vertex order); (s, t) in [0, 1]^2 spans
// the polygon's bounding rectangle in that frame. texels[row * width + col], row <-> t, col <-> s,
// sampled bilinearly at texel centres. Values are relative (any positive scale).
struct EmissionImage {
    int width = 0, height = 0;
    std::vector<float> texels;
    bool empty() const { return width == 0 && height == 0; }
};

struct SourceDesc {
    std::vector<Vec3> polygon;  // planar, >= 3 vertices, any winding; emits towards the receiver
    EmissionImage emission;     // optional; empty means uniform emission
};

// Receiver polygon vertices, or any points whose hull bounds the receiving objects (a cluster).
struct ReceiverDesc {
    std::vector<Vec3> points;
};

enum class DirectionChoice { Auto, SourceToReceiver, ReceiverNormal, SourceNormal };

struct ConvolutionSettings {
    int resolution = 0;          // texels per side; 0 chooses it from alpha_min (brief §5.1)
    int minResolution = 16;      // bounds of the automatic choice
    int maxResolution = 512;
    double e_max = 2.0;          // target E_rr, texels
    int n_max = 8;               // most sub-blockers
    double depthTolerance = 1e-3;  // blocker may reach this fraction of the scene depth into the receiver
    int supersample = 4;         // samples per pixel side (span: sub-rows; OSMesa: ss^2 MSAA samples)
    RasterizerKind rasterizer = RasterizerKind::Auto;
    DirectionChoice direction = DirectionChoice::Auto;
    int maxFftSize = 8192;       // larger padded sizes are refused (std::domain_error)
    bool contactSlabs = true;    // a blocker reaching the receiver gets contact sub-blockers (issue 12)
};

struct SubBlocker {
    std::vector<int> triangles;  // indices into the blocker list
    // Contact sub-blockers instead hold their own geometry: the blocker clipped to the slab, and for the
    // slab at the receiver the blocker's cross-section there (the cap), so its map is the solid's shadow.
    std::vector<std::vector<Vec3>> pieces;
    DepthRange depth;
    double alphaLo = 0, alphaHi = 0, alphaStar = 0;  // penumbra scales, virtual-plane units
    double error = 0;            // E_i, texels
    double visibilityError = 0;  // predicted max |V error| of this slice (dimensionless)
};

struct ConvolutionPlan {
    ConvolutionFrame frame;
    DirectionChoice direction = DirectionChoice::SourceToReceiver;
    ReceiverWindow window;
    DepthRange sourceDepth, blockerDepth, receiverDepth;
    std::vector<Vec2> footprint;  // source vertices in (u, v) relative to O
    double L_S = 0;               // largest side of the footprint's bounding box
    int n = 0;                    // texels per side
    double p = 0;                 // texel size in the virtual receiver plane
    int marginLoU = 0, marginLoV = 0;
    int fftSize = 0;              // padded FFT size (0 when there is no blocker)
    std::vector<SubBlocker> slices;
    double E_rr = 0;
    double alpha_min = HUGE_VAL;  // +inf without blockers
    double visibilityError = 0;   // max over slices, ~ 1.25 E / kernel width (brief §4.2)
    // The blocker reaches the receiver (an object standing on it): the slabs are the contact sub-blockers
    // of chooseContactSlices, and E_rr is in units of max(half the slab's narrowest penumbra, one texel).
    bool contact = false;
};

struct ConvolutionTimes {
    double rasterMs = 0, fftMs = 0, restMs = 0;
};

struct SoftShadowTexture {
    int n = 0;
    std::vector<float> visibility;  // n * n
    Mat4 matrix{};                  // M [x y z 1] = [s q, t q, 0, q]
    double E_rr = 0, alpha_min = HUGE_VAL, visibilityError = 0;
    int subBlockers = 0;
    int fftSize = 0;
    ConvolutionFrame frame;
    ReceiverWindow window;
    ConvolutionTimes times;
    RasterizerKind rasterizer = RasterizerKind::Span;
};

ConvolutionPlan planSoftShadow(const SourceDesc& source, const std::vector<BlockerTriangle>& blockers,
                               const ReceiverDesc& receiver, const ConvolutionSettings& settings);
SoftShadowTexture computeSoftShadow(const ConvolutionPlan& plan, const SourceDesc& source,
                                    const std::vector<BlockerTriangle>& blockers,
                                    const ConvolutionSettings& settings);
SoftShadowTexture computeSoftShadow(const SourceDesc& source, const std::vector<BlockerTriangle>& blockers,
                                    const ReceiverDesc& receiver, const ConvolutionSettings& settings);

// Bilinear, clamped to the edge texels outside the window; NaN when P is not in front of O.
float lookupVisibility(const SoftShadowTexture& tex, const Vec3& P);

}  // namespace penumbra
