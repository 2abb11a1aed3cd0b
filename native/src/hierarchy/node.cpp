#include "hierarchy/node.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include "geometry/form_factor.h"
#include "hierarchy/predicates.h"

namespace penumbra {
namespace {

// Within a few of its own widths an element no longer looks like a point from y: the disc
// estimate A cos cos / (pi r^2 + A) from its centre misses what a face tilted away from that centre
// sees. There the exact point-to-polygon form factor is used; farther out the estimate's error is
// largest at grazing incidence, where little light arrives.
constexpr double kNearField2 = 16.0;  // (r / sqrt(A))^2 below which the exact form factor is used

// Irradiance at (y, n) per unit radiosity of a face of `area` centred at c, lying on a plane with
// normal en: the point kernel with its second-order term, or within the near field exact() (the face's
// exact form factor). The term is the point kernel's expansion to second order in the offset s from the
// centre, integrated over the face (taken as a square of its area: the integral of s s^T is A^2/12 in its
// plane): A a (b + t (2 b - 6 b a^2 / r^2 - 2 (n . en) a)) / (pi r^4), t = A / (6 r^2), with a and b the
// heights of y over the face's plane and of the face's centre over y's. Straight in front it is the disc's
// A / (pi r^2 + A) to that order, but it also reads the oblique transfers the disc estimate made up to 6 %
// too low (a wall lighting the floor beside it), light then lost at every bounce through a cluster: the
// 5k office with every albedo 0.5 at epsilon 0.002 kept 99.30 % of its light with it, 98.99 % with the
// disc (native/python/test_energy_balance.py measures the 1k office at its own albedos: 99.86 against
// 99.54 %), and the 20k office's bias against Cycles went from -1.19 to -0.88 %.
template <class Exact>
double faceKernel(const Vec3& c, const Vec3& en, double area, const Vec3& y, const Vec3* n, Exact&& exact) {
    Vec3 d = y - c;
    double r2 = length2(d);
    if (r2 <= 0) return 0;
    if (n) {
        if (r2 < kNearField2 * area) return exact();
        // From the unnormalised dot products, without a square root (the sweeps evaluate this for every face
        // of every near cluster source at every receiving face).
        double a = dot(en, d), b = -dot(*n, d);
        if (a <= 0 || b <= 0) return 0;
        double t = area / (6 * r2);
        double second = b + t * (2 * b - 6 * b * a * a / r2 - 2 * dot(*n, en) * a);
        return std::max(0.0, area * a * second / (M_PI * r2 * r2));
    }
    double cj = dot(en, d) / std::sqrt(r2);
    if (cj <= 0) return 0;
    return area * cj / (M_PI * r2 + area);
}

// Element e's exact form factor from (y, n), e lying on a plane with normal en.
double exactKernel(const Element& e, const Vec3& en, const Vec3& y, const Vec3& n) {
    double h = dot(en, y - e.v[0]);  // y must lie in front of e's plane (e sends one way)
    if (h <= 0) return 0.0;
    return pointToPolygonFormFactor(y, n, e.polygonShape());
}

}  // namespace

double elementKernel(const Element& e, const Vec3& en, const Vec3& y, const Vec3* n) {
    return faceKernel(e.center, en, e.area, y, n, [&] { return exactKernel(e, en, y, *n); });
}

Bounds nodeBox(const Hierarchy& h, int node) {
    if (isClusterNode(node)) return h.clusters()[clusterIndex(node)].box;
    const Element& e = h[size_t(node)];
    Bounds b;
    for (int k = 0; k < e.n; ++k) b.extend(e.v[k]);
    return b;
}

Vec3 nodeCenter(const Hierarchy& h, int node) {
    if (isClusterNode(node)) return h.clusters()[clusterIndex(node)].center;
    return h[size_t(node)].center;
}

uint64_t nodeKey(const Hierarchy& h, int node) {
    if (isClusterNode(node)) return h.clusters()[clusterIndex(node)].key;
    return h[size_t(node)].key;
}

namespace {

// The light of faces [begin, end) of the cluster tree's order at (y, n), face by face.
Rgb facesFluxAt(const Hierarchy& h, int begin, int end, const Vec3& y, const Vec3* n) {
    // The faces are read from their compact copy (Hierarchy::faceLight); only the exact form factor
    // near a face needs its element.
    const std::vector<Hierarchy::FaceLight>& faces = h.faceLight();
    assert(faces.size() == h.clusters().polygons().size());  // one per face of the cluster tree
    Rgb sum;
    for (int k = begin; k < end; ++k) {
        const Hierarchy::FaceLight& f = faces[size_t(k)];
        if (!f.lit) continue;
        sum += f.B * faceKernel(f.center, f.normal, f.area, y, n,
                                [&] { return exactKernel(h[size_t(f.polygon)], f.normal, y, *n); });
    }
    return sum;
}

Rgb clusterFluxAt(const Hierarchy& h, int ci, const Vec3& y, const Vec3* n) {
    const ClusterTree& ct = h.clusters();
    const Cluster& c = ct[ci];
    Vec3 d = y - c.center;
    double r2 = length2(d);
    if (r2 <= 0) return {};
    if (c.radius * c.radius > kFarField * kFarField * r2) {  // not in its far field (predicates.h)
        // Near a cluster its faces see y from different directions, and a face that the centre's
        // direction puts at grazing incidence may still light y: its own faces one by one, and each
        // child cluster by the same rule, so by normal class where y lies in the child's far field,
        // the approximation every far cluster link makes. Summing every face instead gave the same
        // light (10k office at far_field 0.5: 0.12 % RMS, 0.004 % in the mean; five scenes against
        // Cycles within 0.02 points) for 31 % more CPU at 50k polygons.
        Rgb sum = facesFluxAt(h, c.begin, c.ownEnd, y, n);
        for (int k = 0; k < c.numChildren; ++k) sum += clusterFluxAt(h, c.firstChild + k, y, n);
        return sum;
    }
    Vec3 u = d * (1 / std::sqrt(r2));
    double cy = n ? -dot(*n, u) : 1.0;
    if (cy <= 0) return {};
    // Without a branch on each class's side: which classes face y is as good as random from one call to the
    // next, and a class turned away adds 0.
    // GCC and Clang's vector extensions: SSE on x86-64, NEON on arm64, without target flags.
    typedef float v4 __attribute__((vector_size(16)));
    const v4 ux = {float(u.x), float(u.x), float(u.x), float(u.x)};
    const v4 uy = {float(u.y), float(u.y), float(u.y), float(u.y)};
    const v4 uz = {float(u.z), float(u.z), float(u.z), float(u.z)};
    const v4 zero = {0, 0, 0, 0};
    v4 r = zero, g = zero, b = zero;
    const ClassBlock* blocks = ct.classBlocks().data();
    for (int k = c.blockBegin; k < c.blockEnd; ++k) {
        const ClassBlock& cb = blocks[k];
        v4 nx, ny, nz, fr, fg, fb;
        std::memcpy(&nx, cb.nx, sizeof nx);
        std::memcpy(&ny, cb.ny, sizeof ny);
        std::memcpy(&nz, cb.nz, sizeof nz);
        std::memcpy(&fr, cb.fr, sizeof fr);
        std::memcpy(&fg, cb.fg, sizeof fg);
        std::memcpy(&fb, cb.fb, sizeof fb);
        v4 s = nx * ux + ny * uy + nz * uz;
        s = s > zero ? s : zero;
        r += fr * s;
        g += fg * s;
        b += fb * s;
    }
    Rgb sum{double(r[0]) + double(r[1]) + double(r[2]) + double(r[3]),
            double(g[0]) + double(g[1]) + double(g[2]) + double(g[3]),
            double(b[0]) + double(b[1]) + double(b[2]) + double(b[3])};
    return sum * (ct.classBlockUnit() * cy / (M_PI * r2));
}

}  // namespace

Rgb fluxAt(const Hierarchy& h, int source, const Vec3& y, const Vec3* n) {
    if (!isClusterNode(source)) {
        const Element& e = h[size_t(source)];
        return e.B * elementKernel(e, h.scene().polygons[e.polygon].normal, y, n);
    }
    return clusterFluxAt(h, clusterIndex(source), y, n);
}

Rgb weightedFaceLight(const Hierarchy& h, int clusterSource, const float* weights) {
    const Cluster& c = h.clusters()[clusterIndex(clusterSource)];
    const std::vector<Hierarchy::FaceLight>& faces = h.faceLight();
    Rgb sum;
    for (int k = c.begin; k < c.end; ++k) {
        float w = weights[k - c.begin];
        if (w > 0 && faces[size_t(k)].lit) sum += faces[size_t(k)].B * double(w);
    }
    return sum;
}

bool farFieldLight(const Hierarchy& h, int clusterSource, const Vec3& ballCenter, double ballRadius,
                   FarFieldLight& out) {
    const ClusterTree& ct = h.clusters();
    const Cluster& c = ct[clusterIndex(clusterSource)];
    Vec3 d = ballCenter - c.center;
    double dist = length(d);
    // Every point of the ball is at least dist - ballRadius from the centre; the margins keep rounding
    // from deciding a point that fluxAt would put on the other side.
    if (!(dist > ballRadius) || c.radius > kFarField * (dist - ballRadius) * (1 - 1e-9)) return false;
    Vec3 u = d / dist;
    // The directions to the ball's points lie within asin(ballRadius / dist) of u.
    double sinCone = ballRadius / dist + 1e-9;
    out.center = c.center;
    out.rows[0] = out.rows[1] = out.rows[2] = Vec3{};
    for (int m = c.classBegin; m < c.classEnd; ++m) {
        const Vec3& nm = ct.classNormal()[size_t(m)];
        double s = dot(nm, u);
        if (s <= -sinCone) continue;  // turned away from the whole ball
        if (s < sinCone) return false;
        const Rgb& f = ct.classFlux()[size_t(m)];
        out.rows[0] += nm * f.x;
        out.rows[1] += nm * f.y;
        out.rows[2] += nm * f.z;
    }
    return true;
}

Rgb FarFieldLight::at(const Vec3& y, const Vec3* n) const {
    Vec3 d = y - center;
    double r2 = length2(d);
    if (r2 <= 0) return {};
    double r = std::sqrt(r2);
    Vec3 u = d / r;
    double cy = n ? -dot(*n, u) : 1.0;
    if (cy <= 0) return {};
    return Rgb{dot(rows[0], u), dot(rows[1], u), dot(rows[2], u)} * (cy / (M_PI * r2));
}

double fluxBound(const Hierarchy& h, int source, const Bounds& rb) {
    Bounds sb = nodeBox(h, source);
    Vec3 rc = rb.center(), sc = sb.center();
    double rr = 0.5 * length(rb.diagonal()), sr = 0.5 * length(sb.diagonal());
    Vec3 d = rc - sc;
    double r = length(d);
    // Seen from anywhere in the source, the receiver's box lies within an angle of about
    // (rr + sr) / r of the centre line: each cosine is widened by that (capped at 1).
    double spread = r > 0 ? (rr + sr) / r : 1.0;
    Vec3 u = r > 0 ? d / r : Vec3{};
    // A face's form factor to a point is at most A cos / (pi d^2) at distance d, and at most 1 at any
    // distance: a face that touches the receiver's box adds its whole radiosity, not an infinity. Each
    // face at its own distance, not the cluster's nearest: the 20k office at the default epsilon had 6 %
    // fewer links and took 6 % less time (docs/scaling.md, stop 32).
    auto formFactorBound = [](double area, double cosine, double dist) {
        return dist > 0 ? std::min(1.0, area * cosine / (M_PI * dist * dist)) : (cosine > 0 ? 1.0 : 0.0);
    };
    if (!isClusterNode(source)) {
        const Element& e = h[size_t(source)];
        double cm = std::min(1.0, std::max(0.0, dot(h.scene().polygons[e.polygon].normal, u) + spread));
        return maxComponent(e.B) * formFactorBound(e.area, cm, boxDistance(rb, sb));
    }
    // Face by face, each with its own direction to the receiver: a large cluster's faces see a
    // nearby receiver from quite different angles, and one widening for all would be loose.
    const Cluster& c = h.clusters()[clusterIndex(source)];
    // The faces' light from its compact copy in the same order: read from the elements, a scattered load a
    // face was a quarter of this function's time (100k office).
    const std::vector<Hierarchy::FaceBox>& faces = h.faceBoxes();
    const std::vector<Hierarchy::FaceLight>& light = h.faceLight();
    double sum = 0;
    for (int k = c.begin; k < c.end; ++k) {
        const Hierarchy::FaceBox& f = faces[size_t(k)];
        if (!f.bounces) continue;
        double b = maxComponent(light[size_t(k)].B);
        if (b <= 0) continue;
        Vec3 dj = rc - f.center;
        double rj = length(dj);
        double cj = rj > 0 ? std::min(1.0, std::max(0.0, dot(f.normal, dj) / rj + (rr + std::sqrt(f.area)) / rj))
                           : 1.0;
        sum += b * formFactorBound(f.area, cj, boxDistance(rb, f.box));
    }
    return sum;
}

}  // namespace penumbra
