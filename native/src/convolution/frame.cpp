#include "convolution/frame.h"

#include <sstream>
#include <stdexcept>

namespace penumbra {

DepthRange ConvolutionFrame::depthRange(const std::vector<Vec3>& pts) const {
    DepthRange r;
    for (const Vec3& p : pts) r.extend(depth(p));
    return r;
}

ConvolutionFrame ConvolutionFrame::make(const Vec3& origin, const Vec3& direction, const Vec3& hint) {
    ConvolutionFrame f;
    f.O = origin;
    f.w = normalize(direction);
    if (length2(f.w) == 0) throw std::invalid_argument("convolution direction w has zero length");
    Vec3 h = hint - f.w * dot(hint, f.w);
    if (length(h) <= 1e-9 * length(hint) || length2(h) == 0) {
        // Any axis not parallel to w will do; take the one least aligned with it.
        Vec3 ax = std::fabs(f.w.x) < 0.6 ? Vec3{1, 0, 0} : (std::fabs(f.w.y) < 0.6 ? Vec3{0, 1, 0} : Vec3{0, 0, 1});
        h = ax - f.w * dot(ax, f.w);
    }
    f.u = normalize(h);
    f.v = cross(f.w, f.u);
    return f;
}

ReceiverWindow windowByCentralProjection(const ConvolutionFrame& f, const std::vector<Vec3>& pts) {
    if (pts.empty()) throw std::invalid_argument("receiver has no points");
    DepthRange d = f.depthRange(pts);
    if (!(d.lo > 0))
        throw std::domain_error("receiver is not entirely in front of the source centre along w");
    ReceiverWindow win;
    win.z_r = 0.5 * (d.lo + d.hi);
    double ulo = HUGE_VAL, uhi = -HUGE_VAL, vlo = HUGE_VAL, vhi = -HUGE_VAL;
    for (const Vec3& p : pts) {
        double k = win.z_r / f.depth(p);
        double pu = f.coordU(p) * k, pv = f.coordV(p) * k;
        ulo = std::fmin(ulo, pu);
        uhi = std::fmax(uhi, pu);
        vlo = std::fmin(vlo, pv);
        vhi = std::fmax(vhi, pv);
    }
    win.extent = std::fmax(uhi - ulo, vhi - vlo);
    win.u_lo = 0.5 * (ulo + uhi) - 0.5 * win.extent;
    win.v_lo = 0.5 * (vlo + vhi) - 0.5 * win.extent;
    return win;
}

DepthOrder checkDepthOrder(const DepthRange& s, const DepthRange& b, const DepthRange& r,
                           double tolerance) {
    DepthOrder out;
    std::ostringstream msg;
    if (!(r.lo > s.hi)) {
        msg << "receiver (depth " << r.lo << ".." << r.hi << ") is not entirely beyond the source ("
            << s.lo << ".." << s.hi << ") along w";
    } else if (!b.empty() && !(b.lo > s.hi)) {
        msg << "blocker (depth " << b.lo << ".." << b.hi << ") reaches the source (" << s.lo << ".."
            << s.hi << ") along w";
    } else if (!b.empty() && b.hi > r.lo + tolerance) {
        msg << "blocker (depth " << b.lo << ".." << b.hi << ") overlaps the receiver (" << r.lo
            << ".." << r.hi << ") along w beyond the tolerance " << tolerance;
    }
    out.reason = msg.str();
    out.ok = out.reason.empty();
    return out;
}

Mat4 textureMatrix(const ConvolutionFrame& f, const ReceiverWindow& win) {
    // s*q = (z_r (P-O).u - u_lo q) / extent with q = (P-O).w: linear in P, hence one matrix row.
    Mat4 m{};
    const Vec3 rs = (f.u * win.z_r - f.w * win.u_lo) / win.extent;
    const Vec3 rt = (f.v * win.z_r - f.w * win.v_lo) / win.extent;
    const Vec3* rows[2] = {&rs, &rt};
    for (int r = 0; r < 2; ++r) {
        m[4 * r + 0] = rows[r]->x;
        m[4 * r + 1] = rows[r]->y;
        m[4 * r + 2] = rows[r]->z;
        m[4 * r + 3] = -dot(*rows[r], f.O);
    }
    m[12] = f.w.x;
    m[13] = f.w.y;
    m[14] = f.w.z;
    m[15] = -dot(f.w, f.O);
    return m;
}

TexCoord applyTextureMatrix(const Mat4& m, const Vec3& P) {
    double sq = m[0] * P.x + m[1] * P.y + m[2] * P.z + m[3];
    double tq = m[4] * P.x + m[5] * P.y + m[6] * P.z + m[7];
    double q = m[12] * P.x + m[13] * P.y + m[14] * P.z + m[15];
    TexCoord c;
    c.q = q;
    c.s = sq / q;
    c.t = tq / q;
    return c;
}

}  // namespace penumbra
