// The convolution frame of a link (brief §3.2): origin O at the source centre, orthonormal (u, v, w)
// with w pointing from the source towards the receiver, the virtual receiver plane w = z_r, the
// square texture window on it, and the homogeneous matrix that maps any 3D point to texture
// coordinates by central projection from O (brief §1.4).
#pragma once
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "geometry/vec3.h"

namespace penumbra {

struct DepthRange {
    double lo = HUGE_VAL;
    double hi = -HUGE_VAL;
    void extend(double z) {
        lo = std::fmin(lo, z);
        hi = std::fmax(hi, z);
    }
    void extend(const DepthRange& r) {
        lo = std::fmin(lo, r.lo);
        hi = std::fmax(hi, r.hi);
    }
    bool empty() const { return lo > hi; }
};

struct ConvolutionFrame {
    Vec3 O, u, v, w;

    double depth(const Vec3& P) const { return dot(P - O, w); }
    double coordU(const Vec3& P) const { return dot(P - O, u); }
    double coordV(const Vec3& P) const { return dot(P - O, v); }
    DepthRange depthRange(const std::vector<Vec3>& pts) const;

    // u follows `hint` projected perpendicular to w, so that a rectangular source keeps its sides
    // along the image axes; any hint parallel to w falls back to a fixed perpendicular.
    static ConvolutionFrame make(const Vec3& origin, const Vec3& direction, const Vec3& hint);
};

// Square window [u_lo, u_lo + extent] x [v_lo, v_lo + extent] of the virtual receiver plane w = z_r.
struct ReceiverWindow {
    double z_r = 1;
    double u_lo = 0, v_lo = 0;
    double extent = 0;
};

// Projects every point centrally from O onto w = z_r (z_r = depth of their bounding-box centre)
// and takes the square around their (u, v) bounding rectangle. Throws std::domain_error when a
// point is not strictly in front of O, where the central projection does not exist.
ReceiverWindow windowByCentralProjection(const ConvolutionFrame& f, const std::vector<Vec3>& pts);

// Source, blocker and receiver must follow each other in depth along w. The blocker may reach
// `tolerance` into the receiver's range so that an object resting on the receiver still counts;
// on the source side no overlap is accepted because a blocker touching the source has an
// unbounded penumbra scale.
struct DepthOrder {
    bool ok = true;
    std::string reason;
};
DepthOrder checkDepthOrder(const DepthRange& source, const DepthRange& blocker,
                           const DepthRange& receiver, double tolerance);

// Row-major 4x4 matrix M with M * [x y z 1]^T = [s*q, t*q, 0, q]; (s, t) in [0, 1]^2 over the window.
using Mat4 = std::array<double, 16>;
Mat4 textureMatrix(const ConvolutionFrame& f, const ReceiverWindow& win);

struct TexCoord {
    double s = 0, t = 0, q = 0;
};
TexCoord applyTextureMatrix(const Mat4& m, const Vec3& P);

}  // namespace penumbra
