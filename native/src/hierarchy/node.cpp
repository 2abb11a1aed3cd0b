#include "hierarchy/node.h"

#include <algorithm>
#include <cmath>

namespace penumbra {
namespace {

double boxDistance(const Bounds& a, const Bounds& b) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
        double gap = std::max({0.0, b.lo[k] - a.hi[k], a.lo[k] - b.hi[k]});
        d2 += gap * gap;
    }
    return std::sqrt(d2);
}

// Calls f(B, area, centre, normal) for every polygon of a cluster node, or once for an element.
template <class F>
void forEachEmitter(const Hierarchy& h, int node, F&& f) {
    const Scene& sc = h.scene();
    if (!isClusterNode(node)) {
        const Element& e = h[size_t(node)];
        f(e.B, e.area, e.center, sc.polygons[e.polygon].normal);
        return;
    }
    const ClusterTree& ct = h.clusters();
    const Cluster& c = ct[clusterIndex(node)];
    const std::vector<int>& polys = ct.polygons();
    for (int k = c.begin; k < c.end; ++k) {
        int p = polys[k];
        const Element& e = h[size_t(p)];  // the polygon's root element holds its mean radiosity
        if (maxComponent(e.B) <= 0) continue;
        f(e.B, e.area, e.center, sc.polygons[p].normal);
    }
}

}  // namespace

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

Rgb fluxAt(const Hierarchy& h, int source, const Vec3& y, const Vec3* n) {
    Rgb sum;
    forEachEmitter(h, source, [&](const Rgb& B, double area, const Vec3& c, const Vec3& nj) {
        Vec3 d = y - c;
        double r2 = length2(d);
        if (r2 <= 0) return;
        double r = std::sqrt(r2);
        double cj = dot(nj, d) / r;
        if (cj <= 0) return;
        double cy = n ? -dot(*n, d) / r : 1.0;
        if (cy <= 0) return;
        sum += B * (area * cj * cy / (M_PI * r2 + area));
    });
    return sum;
}

double fluxBound(const Hierarchy& h, int source, const Bounds& rb) {
    Bounds sb = nodeBox(h, source);
    double dmin = boxDistance(rb, sb);
    if (!(dmin > 0)) return HUGE_VAL;
    Vec3 rc = rb.center();
    double rr = 0.5 * length(rb.diagonal());
    double sum = 0;
    forEachEmitter(h, source, [&](const Rgb& B, double area, const Vec3& c, const Vec3& nj) {
        Vec3 d = rc - c;
        double r = length(d);
        if (!(r > 0)) {
            sum += maxComponent(B) * area;
            return;
        }
        // The receiver's box spans an angle of about rr / r around d; the emitter's own extent, of
        // sqrt(area) / r more: a cosine bound widened by both (capped at 1).
        double spread = (rr + std::sqrt(area)) / r;
        double cj = std::min(1.0, std::max(0.0, dot(nj, d) / r + spread));
        sum += maxComponent(B) * area * cj;
    });
    return sum / (M_PI * dmin * dmin);
}

}  // namespace penumbra
