// Who takes part in the light transfer, and the tolerances several stages share. Each is defined once
// here so that the clusters, the refiner, the convolution sites and the lookups cannot drift apart.
#pragma once
#include <cmath>

#include "scene/scene.h"

namespace penumbra {

// Emits light of its own.
inline bool emits(const ScenePolygon& p) { return maxComponent(p.emission) > 0; }

// Gathers light: a receiving face (not a light-only emitter) that reflects some of what arrives.
inline bool receivesLight(const ScenePolygon& p) { return p.receives && maxComponent(p.rho) > 0; }

// Its radiosity reaches others: diffuse rays meet it (Ray Visibility > Diffuse on), or it emits.
inline bool bouncesLight(const ScenePolygon& p) { return p.diffuseVisible || emits(p); }

// Has light to give: it emits, or it reflects where diffuse rays see it.
inline bool sendsLight(const ScenePolygon& p) { return emits(p) || (maxComponent(p.rho) > 0 && p.diffuseVisible); }

// A cluster is in its far field when its radius is at most kFarField of the distance. There the
// centre's direction stands for every face's to within about 12 degrees, and its light is evaluated
// by normal class from the centre (node.cpp's fluxAt); nearer, its own faces one by one and its
// child clusters by the same rule. Whether a cluster source is linked whole is Settings::farField's
// (when this constant decided it too, 0.3 and 0.4 measured 1.74 % and 2.08 % against Cycles on the
// Cornell box, 0.2 1.65 %; visibility was then sampled by area).
inline constexpr double kFarField = 0.2;

// How far a point handed in may lie off its own plane through float32 rounding alone: a few ulps of
// the largest input coordinate (large for a scene far from the origin; the scene is recentred, so
// this is measured before the offset is taken away). Tolerances for "lies in this plane" add a small
// fraction of the diagonal to it, never the 1e-3 touching tolerance.
inline double float32Rounding(const Scene& sc) {
    Vec3 far = vmax(vmax(sc.bounds.lo + sc.offset, -(sc.bounds.lo + sc.offset)),
                    vmax(sc.bounds.hi + sc.offset, -(sc.bounds.hi + sc.offset)));
    return 4.0 * std::ldexp(maxComponent(far), -23);
}

}  // namespace penumbra
