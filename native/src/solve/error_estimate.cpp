#include "solve/error_estimate.h"

#include <algorithm>
#include <cmath>

#include "hierarchy/node.h"
#include "util/parallel.h"

namespace penumbra {

ErrorEstimate estimateError(const Hierarchy& h, const std::vector<Link>& links, const Settings& s,
                            double residual) {
    const Scene& sc = h.scene();
    const ClusterTree& ct = h.clusters();
    const double rms12 = 1 / std::sqrt(12.0);
    const int m = std::max(1, int(std::lround(std::sqrt(double(std::max(1, s.visibilityRays))))));
    const double n = std::min(256, m * m);
    std::vector<double> own(h.size(), 0.0), cluster(ct.size(), 0.0);
    // Each link's share (a cluster link's is a bound over the source's faces: 0.9 s of the 100k office's 1 s here,
    // serially) is worked out in parallel, a block of links at a time, and summed in link order, so the estimate
    // does not depend on the thread count.
    auto linkError2 = [&](const Link& l) {
        double rho = isClusterNode(l.receiver) ? ct[clusterIndex(l.receiver)].rhoMax
                                               : maxComponent(sc.polygons[h[l.receiver].polygon].rho);
        if (!(rho > 0)) return 0.0;
        double e2 = 0;
        if (isClusterNode(l.receiver) || isClusterNode(l.source)) {
            if (l.V <= 0) return 0.0;
            double e = rho * fluxBound(h, l.source, nodeBox(h, l.receiver)) * rms12;
            e2 = e * e;
        } else {
            const Element& src = h[l.source];
            double B = maxComponent(src.B);
            double R = s.finalGather ? maxComponent(vmax(Rgb{}, src.B - sc.polygons[src.polygon].emission)) : B;
            double spread = rho * R * l.Fspread * rms12;
            e2 = spread * spread;
            if (l.partial()) {
                // A source larger than its receiver casts a penumbra about as wide as the source
                // across it, so visibility varies over the receiver by about their size ratio: the
                // same figure as the source's parts of the receiver's size, linked apart, would give
                // (the refiner links a receiver at min_size to a whole partly seen source).
                double v = double(l.V) * (1 - double(l.V));
                double shadow = rho * B * l.Fmean;
                double share = std::min(1.0, h[l.receiver].area / src.area);
                e2 += shadow * shadow * v * (0.25 + 1 / n) * share;
            }
        }
        return e2;
    };
    constexpr size_t kBlock = size_t(1) << 18;
    std::vector<double> e2s(std::min(links.size(), kBlock));
    const int threads = resolveThreads(s.threads);
    for (size_t base = 0; base < links.size(); base += kBlock) {
        size_t count = std::min(kBlock, links.size() - base);
        parallelFor(count, threads, 4096, [&](size_t b, size_t e, int) {
            for (size_t i = b; i < e; ++i) e2s[i] = linkError2(links[base + i]);
        });
        for (size_t i = 0; i < count; ++i) {
            const Link& l = links[base + i];
            if (e2s[i] == 0) continue;
            if (isClusterNode(l.receiver))
                cluster[size_t(clusterIndex(l.receiver))] += e2s[i];
            else
                own[size_t(l.receiver)] += e2s[i];
        }
    }
    size_t objects = sc.objectNames.size();
    std::vector<double> err(objects, 0.0), sig(objects, 0.0);
    double errAll = 0, sigAll = 0;
    size_t roots = h.numRoots();
    std::vector<std::pair<int, double>> stack;
    for (size_t r = 0; r < roots; ++r) {
        const ScenePolygon& p = sc.polygons[r];
        if (!p.receives || !(maxComponent(p.rho) > 0)) continue;
        double above = 0;
        if (!ct.empty() && !h.buried(int(r)))
            for (int c = ct.owner(int(r)); c >= 0; c = ct[c].parent) above += cluster[size_t(c)];
        stack.push_back({int(r), above});
        while (!stack.empty()) {
            auto [e, acc] = stack.back();
            stack.pop_back();
            double total = acc + own[size_t(e)];
            int fc = h.firstChild(e);
            if (fc >= 0) {
                for (int k = 0; k < h[e].numChildren; ++k) stack.push_back({fc + k, total});
                continue;
            }
            const Element& leaf = h[e];
            double L = maxComponent(vmax(Rgb{}, leaf.B - p.emission));
            double e2 = total + residual * residual * L * L;
            size_t o = size_t(std::max(p.object, 0));
            if (o < objects) {
                err[o] += leaf.area * e2;
                sig[o] += leaf.area * L * L;
            }
            errAll += leaf.area * e2;
            sigAll += leaf.area * L * L;
        }
    }
    ErrorEstimate out;
    out.perObject.assign(objects, -1.0);
    for (size_t o = 0; o < objects; ++o)
        if (sig[o] > 0) out.perObject[o] = std::sqrt(err[o] / sig[o]);
    out.overall = sigAll > 0 ? std::sqrt(errAll / sigAll) : 0.0;
    return out;
}

}  // namespace penumbra
