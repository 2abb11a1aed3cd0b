// Soft sun shadows by convolution (issue 13 item 2). A sun of angular diameter theta is a disk at
// infinity: seen from a receiver point y, the blocker hides the part of that disk which its
// projection along the sun's rays covers, and for a planar blocker parallel to the receiver at
// distance d along the rays that is the blocker's parallel projection convolved with a disk of radius
// d tan(theta / 2): exactly the convolution of Soler & Sillion with the source at infinity.
//
// The engine of soft_shadow.h projects centrally from a source at a finite distance. The sun is handed
// to it as a stand-in: the sun's cone of directions from the receiver's centre, cut by a plane parallel
// to a planar receiver at R = kSunDistance times the size of the receiver and blockers (an ellipse), with
// the receiver's normal as the convolution axis, so that source, blocker and receiver planes are parallel
// (a receiver that is not planar, or that sees the sun within 3 degrees of its horizon, takes a disk
// perpendicular to the rays and the rays' direction as the axis). Every point of the stand-in is seen from
// a receiver point within (size of the scene) / R radians of the direction the sun's point has, so its
// shadow differs from the sun's by at most that angle times the blocker's distance: 1e-5 of the scene
// (0.05 mm in a 5 m room), far below a texel. Everything else (depth slabs, contact sub-blockers, E_rr,
// the automatic resolution, lookupVisibility) is the engine's, unchanged.
//
// The texture is the visible fraction of the disk counted by area, as Cycles spreads the sun's strength
// over the disk of radius tan(theta / 2) at unit distance. Cycles' irradiance also weighs each direction by
// its cosine on the receiver; over a sun of a degree or two that weight varies by less than
// tan(theta / 2) tan(incidence) across the disk, which this texture leaves out (it multiplies the
// closed-form unoccluded irradiance, lights.h sunDiskFactor, by V).
#pragma once
#include <vector>

#include "convolution/soft_shadow.h"

namespace penumbra {

struct SunDesc {
    Vec3 direction{0, 0, -1};  // the way the light travels; any length > 0
    double angle = 0;          // angular diameter, radians, in (0, 179 degrees]
};

// The stand-in source and the settings to plan it with: the direction is set as above (the caller's is not
// used), and the depth tolerance, a fraction of the whole depth range in the engine, is rescaled so that it
// stays that fraction of the receiver and blockers' own range. The stand-in's area is uniformly weighted;
// the sun's directions are uniform over the disk perpendicular to the rays, and the plane parallel to an
// oblique receiver stretches that disk unevenly, by up to 3 t tan(incidence) across it (t = tan(theta / 2):
// 4 % for a 1 degree sun 55 degrees from the normal), which moves the middle of a penumbra by a fraction of
// that and full light and umbra not at all.
struct SunStandIn {
    SourceDesc source;
    ConvolutionSettings settings;
};

inline constexpr double kSunDistance = 1e5;
// With resolution 0, texels of this fraction of the widest extent of the narrowest penumbra (the engine's own
// choice is a half), within min/maxResolution: under a window frame of 6 cm bars and a 6 degree sun, an
// eighth left texels as wide as the bars and 0.06 of error; a sixteenth 0.021 (SunShadow.WindowFrame...).
inline constexpr double kSunTexelsPerPenumbra = 16;
inline constexpr int kSunDiskVertices = 96;  // the regular polygon has 0.07 % less area than the disk

// Throws std::invalid_argument for a zero or non-finite direction, an angle outside (0, 179 degrees], or a
// receiver or blocker with a non-finite point.
SunStandIn sunStandIn(const SunDesc& sun, const std::vector<BlockerTriangle>& blockers, const ReceiverDesc& receiver,
                      const ConvolutionSettings& settings);

// The engine's plan (soft_shadow.h) for any source, with resolution 0 meaning texels of 1/kSunTexelsPerPenumbra
// of the narrowest penumbra (E_rr and e_max still in half that penumbra): for small sources such as a lamp's disk.
ConvolutionPlan planFineSoftShadow(const SourceDesc& source, const std::vector<BlockerTriangle>& blockers,
                                   const ReceiverDesc& receiver, const ConvolutionSettings& settings);

ConvolutionPlan planSunShadow(const SunDesc& sun, const std::vector<BlockerTriangle>& blockers,
                              const ReceiverDesc& receiver, const ConvolutionSettings& settings);
// V over the receiver: lookupVisibility(texture, P) reads it at any point P. With resolution 0 the plan's E_rr
// (and e_max) is in the engine's automatic texels, half the narrowest penumbra, whatever texels it takes.
SoftShadowTexture computeSunShadow(const SunDesc& sun, const std::vector<BlockerTriangle>& blockers,
                                   const ReceiverDesc& receiver, const ConvolutionSettings& settings);

}  // namespace penumbra
