#include "convolution/sun_shadow.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace penumbra {

SunStandIn sunStandIn(const SunDesc& sun, const std::vector<BlockerTriangle>& blockers, const ReceiverDesc& receiver,
                      const ConvolutionSettings& settings) {
    if (!isFinite(sun.direction) || !(length(sun.direction) > 0))
        throw std::invalid_argument("sun direction must be finite and non-zero");
    if (!(sun.angle > 0) || !(sun.angle <= M_PI * (179.0 / 180.0)))
        throw std::invalid_argument("sun angle must be in (0, 179 degrees] (a sun without a size casts hard "
                                    "shadows, which need no convolution)");
    if (receiver.points.empty()) throw std::invalid_argument("receiver has no points");
    Bounds box;
    for (const Vec3& p : receiver.points) {
        if (!isFinite(p)) throw std::invalid_argument("receiver has a non-finite point");
        box.extend(p);
    }
    for (size_t i = 0; i < blockers.size(); ++i)
        for (const Vec3& p : blockers[i]) {
            if (!isFinite(p))
                throw std::invalid_argument("blocker triangle " + std::to_string(i) + " has a non-finite vertex");
            box.extend(p);
        }
    // A receiver of one point (or points all alike) still needs a scale for the distance.
    const double size = std::fmax(length(box.diagonal()), 1e-6 * std::fmax(1.0, length(box.center())));
    const Vec3 w = normalize(sun.direction);
    const double R = kSunDistance * size, t = std::tan(0.5 * sun.angle);
    Vec3 a = std::fabs(w.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    const Vec3 t1 = normalize(cross(w, a)), t2 = cross(w, t1);
    Bounds rb;
    for (const Vec3& p : receiver.points) rb.extend(p);
    const Vec3 y = rb.center();
    SunStandIn out;
    out.settings = settings;
    // A planar receiver facing the sun takes the stand-in in a plane parallel to it, R above it along its
    // normal, and the receiver's normal as the convolution axis: source, blocker and receiver planes are then
    // parallel, where the convolution is exact, and a blocker parallel to the receiver is one slab however
    // oblique the sun (along the sun's direction its depth range would overlap the receiver's). The
    // stand-in is the sun's cone of directions from the receiver's centre cut by that plane: an ellipse.
    Vec3 n;
    bool planar = receiver.points.size() >= 3;
    if (planar) {
        for (size_t i = 0; i < receiver.points.size(); ++i) {
            const Vec3& p = receiver.points[i];
            const Vec3& q = receiver.points[(i + 1) % receiver.points.size()];
            n += cross(p - y, q - y);
        }
        double len = length(n), diag = length(rb.diagonal());
        planar = len > 1e-10 * diag * diag;
        if (planar) {
            n = n / len;
            for (const Vec3& p : receiver.points) planar = planar && std::fabs(dot(p - y, n)) <= 1e-6 * diag;
        }
    }
    if (planar && dot(n, w) > 0) n = -n;  // towards the sun
    // The cone's edge must stay clear of the plane's horizon with room to spare.
    const bool parallel = planar && -dot(n, w) > t / std::sqrt(1 + t * t) + 0.05;
    out.source.polygon.reserve(kSunDiskVertices);
    for (int k = 0; k < kSunDiskVertices; ++k) {
        double phi = 2 * M_PI * k / kSunDiskVertices;
        // Turned so that the right-hand normal points away from the sun, towards the receiver.
        Vec3 d = -w + (t1 * std::cos(phi) - t2 * std::sin(phi)) * t;
        out.source.polygon.push_back(parallel ? y + d * (R / dot(d, n)) : y + d * R);
    }
    out.settings.direction = parallel ? DirectionChoice::ReceiverNormal : DirectionChoice::SourceNormal;
    if (parallel) {
        // The weight of each point q of the stand-in, direction d = q - y: uniform in tan-space (the disk
        // perpendicular to the rays at unit distance) seen through the central projection from y onto the
        // parallel plane has the density (d.n)^3 / (d.(-w))^3 (unit d), and Cycles' irradiance weighs each
        // direction by its cosine d.n on the receiver. Over the engine's parametrisation of the polygon:
        // s along v0 -> v1, t along normal x s, the bounding rectangle in that frame.
        const std::vector<Vec3>& poly = out.source.polygon;
        Vec3 nrm;
        for (size_t i = 0; i < poly.size(); ++i) nrm += cross(poly[i] - y, poly[(i + 1) % poly.size()] - y);
        nrm = normalize(nrm);
        const Vec3 e1 = normalize(poly[1] - poly[0]), e2 = cross(nrm, e1);
        double s0 = HUGE_VAL, s1 = -HUGE_VAL, u0 = HUGE_VAL, u1 = -HUGE_VAL;
        for (const Vec3& q : poly) {
            s0 = std::fmin(s0, dot(q - poly[0], e1));
            s1 = std::fmax(s1, dot(q - poly[0], e1));
            u0 = std::fmin(u0, dot(q - poly[0], e2));
            u1 = std::fmax(u1, dot(q - poly[0], e2));
        }
        EmissionImage& img = out.source.emission;
        img.width = img.height = 32;
        img.texels.resize(32 * 32);
        for (int r = 0; r < 32; ++r)
            for (int c = 0; c < 32; ++c) {
                Vec3 q = poly[0] + e1 * (s0 + (s1 - s0) * (c + 0.5) / 32) + e2 * (u0 + (u1 - u0) * (r + 0.5) / 32);
                Vec3 d = normalize(q - y);
                double cn = std::fmax(dot(d, n), 0.0), cw = std::fmax(-dot(d, w), 1e-3);
                img.texels[size_t(r) * 32 + size_t(c)] = float(cn * cn * cn * cn / (cw * cw * cw));
            }
    }
    // The engine's tolerance is a fraction of the depth from the source to the receiver's far side; keep it
    // the same fraction of the receiver and blockers' own depth.
    out.settings.depthTolerance = settings.depthTolerance * size / (R + size);
    return out;
}

// The engine's automatic texel is half the narrowest penumbra: under a window frame and a 1 degree sun that
// read 0.2 off the traced sun where a bar's penumbrae meet, bilinear over a ramp two texels wide.
ConvolutionPlan planFineSoftShadow(const SourceDesc& source, const std::vector<BlockerTriangle>& blockers,
                                   const ReceiverDesc& receiver, const ConvolutionSettings& settings) {
    const SunStandIn s{source, settings};
    ConvolutionPlan P = planSoftShadow(s.source, blockers, receiver, s.settings);
    if (s.settings.resolution != 0 || P.slices.empty() || !(P.alpha_min * P.L_S > 0)) return P;
    double texel = P.alpha_min * P.L_S / kSunTexelsPerPenumbra;
    double n = std::ceil(P.window.extent / texel);
    int want = static_cast<int>(std::clamp(n, double(s.settings.minResolution), double(s.settings.maxResolution)));
    if (want <= P.n) return P;
    // E_rr stays in the automatic texels (half the narrowest penumbra, the unit e_max is given in), so the
    // slabs are chosen for the same error at any texel size.
    const double ratio = double(want) / P.n;
    ConvolutionSettings fine = s.settings;
    fine.resolution = want;
    fine.e_max = s.settings.e_max * ratio;
    ConvolutionPlan Q = planSoftShadow(s.source, blockers, receiver, fine);
    Q.E_rr /= ratio;
    return Q;
}

ConvolutionPlan planSunShadow(const SunDesc& sun, const std::vector<BlockerTriangle>& blockers,
                              const ReceiverDesc& receiver, const ConvolutionSettings& settings) {
    SunStandIn s = sunStandIn(sun, blockers, receiver, settings);
    return planFineSoftShadow(s.source, blockers, receiver, s.settings);
}

SoftShadowTexture computeSunShadow(const SunDesc& sun, const std::vector<BlockerTriangle>& blockers,
                                   const ReceiverDesc& receiver, const ConvolutionSettings& settings) {
    SunStandIn s = sunStandIn(sun, blockers, receiver, settings);
    return computeSoftShadow(planFineSoftShadow(s.source, blockers, receiver, s.settings), s.source, blockers, s.settings);
}

}  // namespace penumbra
