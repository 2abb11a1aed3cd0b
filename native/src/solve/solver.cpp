#include "solve/solver.h"

#include <algorithm>
#include <cmath>

#include "hierarchy/node.h"
#include "util/parallel.h"

namespace penumbra {

void Solver::prepareClusters(const std::vector<Link>& links) {
    clusterLinks_.assign(h_.clusters().size(), {0, 0});
    linkFaceV_.assign(links.size(), nullptr);
    const ClusterTree& ct = h_.clusters();
    if (polyPos_.empty() && !ct.empty()) {
        polyPos_.assign(h_.scene().polygons.size(), -1);
        for (size_t k = 0; k < ct.polygons().size(); ++k) polyPos_[size_t(ct.polygons()[k])] = int(k);
    }
    // Links into clusters sort first (clusters are negative nodes).
    for (size_t g = 0; g + 1 < groupStart_.size(); ++g) {
        int r = links[groupStart_[g]].receiver;
        if (!isClusterNode(r)) break;
        clusterLinks_[size_t(clusterIndex(r))] = {groupStart_[g], groupStart_[g + 1]};
        if (faceVis_ && !faceVis_->shares.empty())
            for (size_t i = groupStart_[g]; i < groupStart_[g + 1]; ++i) {
                auto it = faceVis_->shares.find({nodeKey(h_, r), nodeKey(h_, links[i].source)});
                if (it != faceVis_->shares.end() && links[i].partial()) linkFaceV_[i] = &it->second;
            }
    }
}

void Solver::gather(const std::vector<Link>& links) {
    if (groupStart_.empty()) {
        for (size_t i = 0; i < links.size(); ++i)
            if (i == 0 || links[i].receiver != links[i - 1].receiver) groupStart_.push_back(i);
        groupStart_.push_back(links.size());
        prepareClusters(links);
    }
    for (size_t i = 0; i < h_.size(); ++i) h_[i].irradiance = Rgb{};
    h_.updateClusterFlux();
    size_t groups = groupStart_.size() - 1;
    const Scene& sc = h_.scene();
    // Each receiver's links form one run, handled by one thread: the sum order is fixed.
    parallelFor(groups, resolveThreads(settings_.threads), 64, [&](size_t b, size_t e, int) {
        for (size_t g = b; g < e; ++g) {
            int r = links[groupStart_[g]].receiver;
            if (isClusterNode(r)) continue;  // its faces gather in distributeClusters
            Element& re = h_[r];
            const Vec3& n = sc.polygons[re.polygon].normal;
            Rgb sum;
            for (size_t i = groupStart_[g]; i < groupStart_[g + 1]; ++i) {
                const Link& l = links[i];
                if (isClusterNode(l.source))
                    sum += fluxAt(h_, l.source, re.center, &n) * (unoccluded_ ? 1.0 : double(l.V));
                else
                    sum += h_[l.source].B * double(unoccluded_ ? l.Fmean : l.F);
            }
            re.irradiance = sum;
        }
    });
    if (textures_ && convLinks_) textures_->gather(h_, *convLinks_, resolveThreads(settings_.threads));
}

void Solver::distributeClusters(const std::vector<Link>& links, std::vector<Rgb>& down) const {
    const ClusterTree& ct = h_.clusters();
    const Scene& sc = h_.scene();
    // Every face below a receiving cluster gathers that cluster's links at its own centre and normal:
    // a cluster receiver is not evaluated at its centre, whose 1/r^2 would understate what its nearer
    // faces get.
    parallelFor(down.size(), resolveThreads(settings_.threads), 256, [&](size_t b, size_t e, int) {
        for (size_t p = b; p < e; ++p) {
            const ScenePolygon& poly = sc.polygons[p];
            if (!poly.receives || h_.buried(int(p))) continue;
            Rgb sum;
            const Vec3& y = h_[p].center;
            for (int c = ct.owner(int(p)); c >= 0; c = ct[c].parent) {
                auto [lo, hi] = clusterLinks_[size_t(c)];
                for (size_t i = lo; i < hi; ++i) {
                    double v = links[i].V;
                    if (linkFaceV_[i]) v = (*linkFaceV_[i])[size_t(polyPos_[p] - ct[c].begin)];
                    if (unoccluded_)
                        v = 1.0;
                    else if (v <= 0)
                        continue;  // a face that sees none of the source (many under a shared link)
                    sum += fluxAt(h_, links[i].source, y, &poly.normal) * v;
                }
            }
            down[p] = sum;
        }
    });
}

Rgb Solver::pushPull(int ei, const Rgb& down, double& change, double& reflected) {
    Element& e = h_[ei];
    Rgb total = down + e.irradiance;
    Rgb B;
    int fc = h_.firstChild(ei);
    if (fc < 0) {
        const ScenePolygon& p = h_.scene().polygons[e.polygon];
        if (lightE_) total += (*lightE_)[size_t(ei)];
        Rgb refl = mul(p.rho, total);
        B = p.emission + refl;
        change += e.area * maxComponent(Rgb{std::fabs(B.x - e.B.x), std::fabs(B.y - e.B.y),
                                            std::fabs(B.z - e.B.z)});
        reflected += e.area * maxComponent(refl);
    } else {
        for (int k = 0; k < e.numChildren; ++k) B += pushPull(fc + k, total, change, reflected) * h_[fc + k].area;
        B = B / e.area;
    }
    e.B = B;
    return B;
}

void Solver::directIrradiance(const std::vector<Link>& links, std::vector<Rgb>& shadowed,
                              std::vector<Rgb>& unoccluded) {
    const Scene& sc = h_.scene();
    std::vector<Rgb> saved(h_.size());
    for (size_t i = 0; i < h_.size(); ++i) {
        saved[i] = h_[i].B;
        h_[i].B = sc.polygons[h_[i].polygon].emission;
    }
    const std::vector<ConvolutionLink>* convLinks = convLinks_;
    const CompleteTextures* textures = textures_;
    convLinks_ = nullptr;
    textures_ = nullptr;
    size_t roots = h_.numRoots();
    for (bool open : {false, true}) {
        unoccluded_ = open;
        groupStart_.clear();
        gather(links);
        std::vector<Rgb> down(roots);
        if (!h_.clusters().empty()) distributeClusters(links, down);
        std::vector<Rgb>& out = open ? unoccluded : shadowed;
        out.assign(h_.size(), Rgb{});
        parallelFor(roots, resolveThreads(settings_.threads), 64, [&](size_t b, size_t e, int) {
            std::vector<std::pair<int, Rgb>> stack;
            for (size_t r = b; r < e; ++r) {
                stack.push_back({int(r), down[r]});
                while (!stack.empty()) {
                    auto [ei, above] = stack.back();
                    stack.pop_back();
                    Rgb total = above + h_[ei].irradiance;
                    out[size_t(ei)] = total;
                    int fc = h_.firstChild(ei);
                    for (int k = 0; fc >= 0 && k < h_[ei].numChildren; ++k) stack.push_back({fc + k, total});
                }
            }
        });
    }
    unoccluded_ = false;
    for (size_t i = 0; i < h_.size(); ++i) h_[i].B = saved[i];
    h_.updateClusterFlux();
    convLinks_ = convLinks;
    textures_ = textures;
    groupStart_.clear();
}

double Solver::sweep(const std::vector<Link>& links) {
    gather(links);
    size_t roots = h_.numRoots();
    std::vector<Rgb> down(roots);
    if (!h_.clusters().empty()) distributeClusters(links, down);
    std::vector<double> change(roots, 0.0), refl(roots, 0.0);
    parallelFor(roots, resolveThreads(settings_.threads), 64, [&](size_t b, size_t e, int) {
        for (size_t r = b; r < e; ++r) pushPull(int(r), down[r], change[r], refl[r]);
    });
    double c = 0, rf = 0;
    for (size_t r = 0; r < roots; ++r) { c += change[r]; rf += refl[r]; }
    lastReflected_ = rf;
    return c;
}

SolveResult Solver::solve(const std::vector<Link>& links, Progress* progress) {
    SolveResult res;
    groupStart_.clear();  // the links may have been re-refined since the last solve
    double prev = -1;
    for (int it = 1; it <= settings_.maxIterations; ++it) {
        double change = sweep(links);
        res.iterations = it;
        double scale = std::max(lastReflected_, 1e-300);
        double rel = change / scale;
        // Jacobi errors shrink geometrically; the ratio of successive changes predicts what is left
        // (rel * q / (1 - q)), which is what the tolerance bounds, not the last step alone.
        double q = prev > 0 ? change / prev : 0.0;
        double remaining = q > 0 && q < 1 ? rel * q / (1 - q) : rel;
        res.residual = remaining;
        prev = change;
        if (lastReflected_ <= 0 || (it > 1 && remaining < settings_.tolerance)) {
            res.converged = true;
            break;
        }
        double frac = std::log(std::max(remaining, 1e-300)) / std::log(settings_.tolerance);
        checkProgress(progress, "solve", std::clamp(frac, 0.0, 1.0));
    }
    return res;
}

}  // namespace penumbra
