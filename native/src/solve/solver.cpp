#include "solve/solver.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "hierarchy/node.h"
#include "util/parallel.h"

namespace penumbra {

void Solver::prepareClusters(const std::vector<Link>& links) {
    clusterLinks_.assign(h_.clusters().size(), {0, 0});
    // Links into clusters sort first (clusters are negative nodes): only those need a face share.
    size_t intoClusters = size_t(std::partition_point(links.begin(), links.end(), [](const Link& l) {
                                     return isClusterNode(l.receiver);
                                 }) - links.begin());
    linkFaceV_.assign(intoClusters, nullptr);
    linkFaceV_.shrink_to_fit();
    const ClusterTree& ct = h_.clusters();
    if (clusterDepth_.size() != ct.size()) {
        clusterDepth_.assign(ct.size(), 0);
        for (size_t c = 0; c < ct.size(); ++c)
            for (int a = ct[int(c)].parent; a >= 0; a = ct[a].parent) ++clusterDepth_[c];
    }
    // Links into elements from near cluster sources taken face by face: each face's weight (form factor times
    // visible share), found once per solve rather than per sweep. Each link's lookup is a binary search of
    // millions of keys that fills its own slot, so both tables are filled on all threads (the 100k office's
    // five solves and gathers spent 0.88 s in this set-up on one thread, 0.48 s on two).
    const int threads = resolveThreads(settings_.threads);
    linkSourceWeights_.assign(links.size() - intoClusters, nullptr);
    if (srcFaceVis_ && !srcFaceVis_->empty())
        parallelFor(links.size() - intoClusters, threads, 4096, [&](size_t b, size_t e, int) {
            for (size_t i = intoClusters + b; i < intoClusters + e; ++i)
                if (sourceShared(links[i]))
                    linkSourceWeights_[i - intoClusters] =
                        srcFaceVis_->find(nodeKey(h_, links[i].receiver), nodeKey(h_, links[i].source));
        });
    intoClusters_ = intoClusters;
    for (size_t g = 0; g + 1 < groupStart_.size(); ++g) {
        int r = links[groupStart_[g]].receiver;
        if (!isClusterNode(r)) break;
        clusterLinks_[size_t(clusterIndex(r))] = {groupStart_[g], groupStart_[g + 1]};
    }
    if (faceVis_ && !faceVis_->empty())
        parallelFor(intoClusters, threads, 4096, [&](size_t b, size_t e, int) {
            for (size_t i = b; i < e; ++i)
                if (links[i].partial())
                    linkFaceV_[i] = faceVis_->find(nodeKey(h_, links[i].receiver), nodeKey(h_, links[i].source));
        });
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
                // A source taken face by face holds no emitter (Refiner::sharesFaces): in the unoccluded gather,
                // which reads emission only, it gives nothing either way.
                if (dark(l.source)) continue;
                if (const float* w = linkSourceWeights_[i - intoClusters_])
                    sum += weightedFaceLight(h_, l.source, w);
                else if (isClusterNode(l.source))
                    sum += fluxAt(h_, l.source, re.center, &n) * (unoccluded_ ? 1.0 : double(l.V));
                else
                    sum += h_[l.source].B * double(unoccluded_ ? l.Fmean : l.F());
            }
            re.irradiance = sum;
        }
    });
    if (textures_ && convLinks_) textures_->gather(h_, *convLinks_, resolveThreads(settings_.threads));
}

void Solver::distributeClusters(const std::vector<Link>& links, std::vector<Rgb>& down) const {
    const ClusterTree& ct = h_.clusters();
    const Scene& sc = h_.scene();
    const std::vector<int>& polys = ct.polygons();
    const std::vector<Hierarchy::FaceLight>& faces = h_.faceLight();
    // Every face below a receiving cluster gathers that cluster's links at its own centre and normal:
    // a cluster receiver is not evaluated at its centre, whose 1/r^2 would understate what its nearer
    // faces get. The faces are taken in blocks of the cluster tree's order, and within a block link by
    // link over the faces it reaches: one source's data stays in cache over all of them, and a link's
    // face shares are read in order. Face by face, each walking up its clusters, the same sums cost
    // scattered reads for every (face, link) pair: 27 % of the 50k office's CPU. Each face still adds its
    // clusters' links from its own cluster up and each cluster's in link order, so the sums are the same.
    parallelFor(polys.size(), resolveThreads(settings_.threads), 256, [&](size_t b, size_t e, int) {
        thread_local std::vector<int> reach;  // clusters with links holding a face of [b, e), deepest first
        thread_local std::vector<Rgb> sum;
        thread_local std::vector<char> gathers;
        reach.clear();
        sum.assign(e - b, Rgb{});
        gathers.assign(e - b, 0);
        for (size_t k = b; k < e; ++k) {
            int p = polys[k];
            const ScenePolygon& poly = sc.polygons[size_t(p)];
            gathers[k - b] = poly.receives && !h_.buried(p);
            // Ancestors of consecutive faces are shared: stop at the first already listed.
            for (int c = ct.owner(p); c >= 0; c = ct[c].parent) {
                if (std::find(reach.begin(), reach.end(), c) != reach.end()) break;
                reach.push_back(c);
            }
        }
        std::stable_sort(reach.begin(), reach.end(),
                         [&](int x, int y) { return clusterDepth_[size_t(x)] > clusterDepth_[size_t(y)]; });
        for (int c : reach) {
            auto [lo, hi] = clusterLinks_[size_t(c)];
            if (lo == hi) continue;
            size_t kb = std::max(b, size_t(ct[c].begin)), ke = std::min(e, size_t(ct[c].end));
            for (size_t i = lo; i < hi; ++i) {
                const float* faceV = linkFaceV_[i];
                const float V = links[i].V;
                const int source = links[i].source;
                if (dark(source)) continue;  // gives nothing (every reflector, in directIrradiance's gathers)
                // A cluster source far from the whole receiving cluster is one linear map for all its faces.
                FarFieldLight far;
                const bool linear = isClusterNode(source) && farFieldLight(h_, source, ct[c].center, ct[c].radius, far);
                for (size_t k = kb; k < ke; ++k) {
                    if (!gathers[k - b]) continue;
                    double v = faceV ? faceV[k - size_t(ct[c].begin)] : V;
                    if (unoccluded_)
                        v = 1.0;
                    else if (v <= 0)
                        continue;  // a face that sees none of the source (many under a shared link)
                    const Vec3 &y = faces[k].center, &n = faces[k].normal;
                    sum[k - b] += (linear ? far.at(y, &n) : fluxAt(h_, source, y, &n)) * v;
                }
            }
        }
        for (size_t k = b; k < e; ++k) down[size_t(polys[k])] = sum[k - b];
    });
}

Rgb Solver::pushPull(int ei, const Rgb& down, double& change, double& reflected) {
    Element& e = h_[ei];
    Rgb total = down + e.irradiance;
    Rgb B;
    int fc = h_.firstChild(ei);
    if (fc < 0) {
        const ScenePolygon& p = h_.scene().polygons[e.polygon];
        if (!cap_.empty()) total = total * double(cap_[size_t(ei)]);
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

void Solver::gatheredDown(const std::vector<Link>& links, std::vector<Rgb>& out) {
    groupStart_.clear();
    gather(links);
    size_t roots = h_.numRoots();
    std::vector<Rgb> down(roots);
    if (!h_.clusters().empty()) distributeClusters(links, down);
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
    for (bool open : {false, true}) {
        unoccluded_ = open;
        gatheredDown(links, open ? unoccluded : shadowed);
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

namespace {

// Past steps Anderson's method mixes at most (10k office: 34 sweeps plain, 24 mixing 3, 21 mixing 5 or 6).
constexpr int kDepth = Solver::kMaxMixing;

// Past steps are corrections to B, so single precision loses nothing the tolerance would see and halves
// the history (a 1.6M-element floor keeps 10 of them).
struct Rgbf {
    float v[3];
    Rgbf() = default;
    explicit Rgbf(const Rgb& c) : v{float(c.x), float(c.y), float(c.z)} {}
    double operator[](int c) const { return v[c]; }
};

// Least squares by the normal equations, ridge-regularised: m is at most kDepth and the system is
// solved afresh each sweep, so its conditioning costs nothing worse than a plain sweep (gamma = 0).
bool leastSquares(double A[kDepth][kDepth], double b[kDepth], int m, double x[kDepth]) {
    double trace = 0;
    for (int i = 0; i < m; ++i) trace += A[i][i];
    if (!(trace > 0) || !std::isfinite(trace)) return false;
    for (int i = 0; i < m; ++i) A[i][i] += 1e-12 * trace;
    for (int c = 0; c < m; ++c) {
        int piv = c;
        for (int r = c + 1; r < m; ++r)
            if (std::fabs(A[r][c]) > std::fabs(A[piv][c])) piv = r;
        if (!(std::fabs(A[piv][c]) > 0)) return false;
        std::swap(A[c], A[piv]);
        std::swap(b[c], b[piv]);
        for (int r = c + 1; r < m; ++r) {
            double f = A[r][c] / A[c][c];
            for (int k = c; k < m; ++k) A[r][k] -= f * A[c][k];
            b[r] -= f * b[c];
        }
    }
    for (int r = m - 1; r >= 0; --r) {
        double s = b[r];
        for (int k = r + 1; k < m; ++k) s -= A[r][k] * x[k];
        x[r] = s / A[r][r];
        if (!std::isfinite(x[r])) return false;
    }
    return true;
}

}  // namespace

SolveResult Solver::solve(const std::vector<Link>& links, Progress* progress) {
    cap_.clear();
    SolveResult res = iterate(links, progress);
    if (res.converged) return res;
    // Links that gather more than a hemisphere at a leaf (a fuzzed scene's faces meeting in wedges at a hair's
    // angle, each seen whole through the other: form factors summing to 2.9) make sweeps that grow instead of
    // shrinking, and no number of them converges. A leaf cannot receive more than its hemisphere sends it, so
    // each leaf's gathered light is scaled down to a form factor sum of 1, which makes every sweep contract
    // (by the largest albedo, under 1 by validation), and the solve is run again from the emission. Only
    // after a solve that did not converge: a scene that converges is solved as before, bit for bit.
    double most = 0;
    int capped = capGathering(links, most);
    if (capped == 0) return res;
    const Scene& sc = h_.scene();
    for (size_t i = 0; i < h_.size(); ++i) h_[i].B = sc.polygons[h_[i].polygon].emission;
    contraction_ = -1;
    SolveResult again = iterate(links, progress);
    again.overGathering = capped;
    again.maxGathered = most;
    return again;
}

int Solver::capGathering(const std::vector<Link>& links, double& most) {
    // One gather with every radiosity 1: each leaf's gathered irradiance is then the sum of the form factors
    // (visibility included) of every link into it and its ancestors and clusters.
    std::vector<Rgb> saved(h_.size());
    for (size_t i = 0; i < h_.size(); ++i) {
        saved[i] = h_[i].B;
        h_[i].B = Rgb{1, 1, 1};
    }
    const CompleteTextures* textures = textures_;
    textures_ = nullptr;  // their light is drawn per texel from the sources' own images, not summed here
    std::vector<Rgb> gathered;
    gatheredDown(links, gathered);
    std::vector<float> cap(h_.size(), 1.0f);
    int capped = 0;
    most = 0;
    for (size_t i = 0; i < h_.size(); ++i) {
        if (!h_[i].isLeaf()) continue;
        double sum = maxComponent(gathered[i]);
        most = std::max(most, sum);
        // Sums a hair over 1 are the quadrature's own error near contacts, not an over-gathering link.
        if (sum > 1.01) {
            cap[i] = float(1.0 / sum);
            ++capped;
        }
    }
    for (size_t i = 0; i < h_.size(); ++i) h_[i].B = saved[i];
    h_.updateClusterFlux();
    textures_ = textures;
    groupStart_.clear();
    if (capped > 0) cap_ = std::move(cap);
    return capped;
}

SolveResult Solver::iterate(const std::vector<Link>& links, Progress* progress) {
    SolveResult res;
    groupStart_.clear();  // the links may have been re-refined since the last solve
    // A sweep is the fixed-point map B -> g(B) = E + K B. Its error shrinks by K's largest eigenvalue,
    // and a room has two near it of opposite sign (floor to ceiling and back), so the ratio of
    // successive changes swings (office: 0.52, 0.60, 0.55, ...) and no one-mode extrapolation holds.
    // Anderson's method takes the next B as g(B) minus the mix of past steps whose residuals best
    // cancel this one (least squares over the leaves, area-weighted, per channel since coloured walls
    // contract each channel differently): a Krylov step on the linear map, bounded by a plain sweep.
    const size_t n = h_.size();
    const Scene& sc = h_.scene();
    std::vector<Rgb> x(n), f(n), fPrev, gPrev;
    std::vector<std::vector<Rgbf>> dF, dG;  // the last kDepth steps' changes of residual and of g(B)
    std::vector<double> w(n);
    for (size_t i = 0; i < n; ++i) w[i] = h_[i].isLeaf() ? h_[i].area : 0.0;
    double prev = -1;
    bool plain = true;  // this sweep starts from the last one's output (its ratio measures Jacobi)
    for (int it = 1; it <= settings_.maxIterations; ++it) {
        for (size_t i = 0; i < n; ++i) x[i] = h_[i].B;
        double change = sweep(links);
        res.iterations = it;
        double scale = std::max(lastReflected_, 1e-300);
        double rel = change / scale;
        // Jacobi errors shrink geometrically; the contraction predicts what is left (rel * q / (1 - q)),
        // which is what the tolerance bounds, not the last step alone. A mixed step's ratio is smaller
        // than Jacobi's, so only plain sweeps measure q.
        if (plain && prev > 0 && change < prev) contraction_ = std::max(contraction_, change / prev);
        double q = contraction_;
        double remaining = q > 0 && q < 1 ? rel * q / (1 - q) : rel;
        res.residual = remaining;
        bool grew = prev > 0 && change > prev;
        prev = change;
        if (lastReflected_ <= 0 || (it > 1 && remaining < settings_.tolerance)) {
            res.converged = true;
            break;
        }
        for (size_t i = 0; i < n; ++i) f[i] = h_[i].B - x[i];
        if (grew) {  // a mix that made things worse: start again from this plain sweep
            dF.clear();
            dG.clear();
        } else if (!fPrev.empty() && mixing_ > 0) {
            if (!dF.empty() && dF.size() >= size_t(mixing_)) {
                dF.erase(dF.begin());
                dG.erase(dG.begin());
            }
            dF.emplace_back(n);
            dG.emplace_back(n);
            for (size_t i = 0; i < n; ++i) {
                dF.back()[i] = Rgbf(f[i] - fPrev[i]);
                dG.back()[i] = Rgbf(h_[i].B - gPrev[i]);
            }
        }
        fPrev = f;
        gPrev.resize(n);
        for (size_t i = 0; i < n; ++i) gPrev[i] = h_[i].B;
        plain = true;
        int m = int(dF.size());
        if (m > 0) {
            Rgb gamma[kDepth];
            bool ok = true;
            for (int c = 0; c < 3 && ok; ++c) {
                double A[kDepth][kDepth] = {}, b[kDepth] = {}, g[kDepth] = {};
                for (size_t i = 0; i < n; ++i) {
                    if (w[i] <= 0) continue;
                    for (int j = 0; j < m; ++j) {
                        double dj = dF[size_t(j)][i][c] * w[i];
                        b[j] += dj * f[i][c];
                        for (int k = 0; k <= j; ++k) A[j][k] += dj * dF[size_t(k)][i][c];
                    }
                }
                for (int j = 0; j < m; ++j)
                    for (int k = j + 1; k < m; ++k) A[j][k] = A[k][j];
                bool zero = true;
                for (int j = 0; j < m; ++j) zero = zero && A[j][j] <= 0;
                if (zero) continue;  // this channel carries no light: nothing to mix
                ok = leastSquares(A, b, m, g);
                for (int j = 0; j < m; ++j) gamma[j][c] = g[j];
            }
            if (ok) {
                for (size_t i = 0; i < n; ++i) {
                    Rgb B = h_[i].B;
                    for (int j = 0; j < m; ++j) {
                        const Rgbf& d = dG[size_t(j)][i];
                        B -= Rgb{gamma[j].x * d[0], gamma[j].y * d[1], gamma[j].z * d[2]};
                    }
                    // B = E + rho H with H >= 0 bounds every solution from below; a mix can overshoot it (a
                    // scene whose sweeps do not contract), and a run that stops on a mix would hand out
                    // B < E: a negative reflected radiance (fuzz finding, stop 43).
                    h_[i].B = vmax(B, sc.polygons[h_[i].polygon].emission);
                }
                plain = false;
            } else {
                dF.clear();
                dG.clear();
            }
        }
        double frac = std::log(std::max(remaining, 1e-300)) / std::log(settings_.tolerance);
        checkProgress(progress, "solve", std::clamp(frac, 0.0, 1.0));
    }
    // The last sweep and its mix moved B after the gather refreshed the clusters' copies of the light: refresh them,
    // so that what reads them after a solve (the next refinement pass, the error estimate's bounds) reads its B.
    h_.updateClusterFlux();
    return res;
}

}  // namespace penumbra
