#include "solve/convolution_link.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "geometry/form_factor.h"
#include "util/parallel.h"

namespace penumbra {
namespace {

// Sample grid per leaf side for a leaf's mean of F * V. The mean only feeds the energy balance; the
// display evaluates every point, so a coarse grid loses no detail in the image.
constexpr int kLeafSamples = 4;

void leafSamples(const Element& e, std::vector<Vec3>& pts) {
    pts.clear();
    for (int j = 0; j < kLeafSamples; ++j)
        for (int i = 0; i < kLeafSamples; ++i) {
            double s = (i + 0.5) / kLeafSamples, t = (j + 0.5) / kLeafSamples;
            if (e.n == 3 && s + t > 1) continue;  // pointAt folds these back: keep each point once
            pts.push_back(e.pointAt(s, t));
        }
    if (e.n == 3)  // the folded half of the grid leaves the diagonal's cells: add the centre for balance
        pts.push_back(e.center);
}

// The radiosity of the face a piece was cut from (its root element's, the face's mean).
const Rgb& pieceB(const Hierarchy& h, const ConvolutionLink& l, size_t k) {
    return h[size_t(l.sourcePolygons[size_t(l.pieces[k].face)])].B;
}

void collectLeaves(const Hierarchy& h, int e, std::vector<int>& out) {
    int fc = h.firstChild(e);
    if (fc < 0) {
        out.push_back(e);
        return;
    }
    for (int k = 0; k < h[e].numChildren; ++k) collectLeaves(h, fc + k, out);
}

}  // namespace

void convolutionFactors(const Scene& sc, const ConvolutionLink& l, const Vec3& y, const Vec3& n, double* out) {
    // Called per texel and per leaf sample: the visibility of each part goes in a per-thread buffer.
    thread_local std::vector<double> vis;
    size_t parts = l.textures.size(), first = 0;
    bool lit = false;  // above every blocker of a banded link: the whole source is seen
    if (!l.bandDepths.empty()) {
        const size_t bands = l.bandDepths.size() - 1;
        parts /= bands;
        const double z = dot(y - l.bandOrigin, l.bandAxis);
        auto it = std::upper_bound(l.bandDepths.begin(), l.bandDepths.end(), z);
        lit = it == l.bandDepths.begin();
        const size_t band = std::min(bands - 1, size_t(std::max<ptrdiff_t>(0, it - l.bandDepths.begin() - 1)));
        const double a = dot(y - l.bandOrigin, l.bandAcross);
        lit = lit || a < l.bandSpans[band].first || a > l.bandSpans[band].second;
        first = band * parts;
    }
    vis.resize(parts);
    for (size_t j = 0; j < vis.size(); ++j) {
        const SoftShadowTexture* t = lit ? nullptr : l.textures[first + j].get();
        float v = t ? lookupVisibility(*t, y) : 1.0f;
        vis[j] = std::isfinite(v) ? std::clamp(double(v), 0.0, 1.0) : 0.0;
    }
    for (size_t k = 0; k < l.pieces.size(); ++k) {
        const SourcePiece& piece = l.pieces[k];
        const ScenePolygon& sp = sc.polygons[size_t(l.sourcePolygons[size_t(piece.face)])];
        double v = vis[size_t(piece.part)];
        out[k] = v > 0 && dot(y - sp.geom.v[0], sp.normal) > 0
                     ? v * piece.weight * pointToPolygonFormFactor(y, n, piece.geom)
                     : 0.0;
    }
}

CompleteTextures::CompleteTextures(const Hierarchy& h, const std::vector<ConvolutionLink>& links, int threads) {
    const Scene& sc = h.scene();
    for (size_t li = 0; li < links.size(); ++li) {
        std::vector<int> leaves;
        for (int p : links[li].receiverPolygons) collectLeaves(h, p, leaves);
        for (int leaf : leaves) {
            entries_.push_back({leaf, int(li), factors_.size()});
            factors_.resize(factors_.size() + links[li].pieces.size(), 0.0);
        }
    }
    // Each entry writes only its own factors: the result does not depend on the thread count.
    parallelFor(entries_.size(), threads, 16, [&](size_t b, size_t e, int) {
        std::vector<Vec3> pts;
        std::vector<double> f;
        for (size_t i = b; i < e; ++i) {
            const Entry& en = entries_[i];
            const ConvolutionLink& l = links[size_t(en.link)];
            const Element& leaf = h[size_t(en.leaf)];
            const Vec3& n = sc.polygons[size_t(leaf.polygon)].normal;
            leafSamples(leaf, pts);
            f.assign(l.pieces.size(), 0.0);
            double* acc = &factors_[en.factors];
            for (const Vec3& y : pts) {
                convolutionFactors(sc, l, y, n, f.data());
                for (size_t k = 0; k < f.size(); ++k) acc[k] += f[k];
            }
            for (size_t k = 0; k < f.size(); ++k) acc[k] /= double(pts.size());
        }
    });
    std::stable_sort(entries_.begin(), entries_.end(), [](const Entry& a, const Entry& b) { return a.leaf < b.leaf; });
    for (size_t i = 0; i < entries_.size(); ++i)
        if (i == 0 || entries_[i].leaf != entries_[i - 1].leaf) leafStart_.push_back(i);
    leafStart_.push_back(entries_.size());
}

void CompleteTextures::gather(Hierarchy& h, const std::vector<ConvolutionLink>& links, int threads) const {
    if (entries_.empty()) return;
    parallelFor(leafStart_.size() - 1, threads, 64, [&](size_t b, size_t e, int) {
        for (size_t g = b; g < e; ++g) {
            Rgb sum;
            for (size_t i = leafStart_[g]; i < leafStart_[g + 1]; ++i) {
                const Entry& en = entries_[i];
                const ConvolutionLink& l = links[size_t(en.link)];
                for (size_t k = 0; k < l.pieces.size(); ++k)
                    sum += pieceB(h, l, k) * factors_[en.factors + k];
            }
            h[size_t(entries_[leafStart_[g]].leaf)].irradiance += sum;
        }
    });
}

std::vector<Rgb> CompleteTextures::reflected(const Hierarchy& h, const std::vector<ConvolutionLink>& links) const {
    std::vector<Rgb> out(h.size());
    for (const Entry& en : entries_) {
        const ConvolutionLink& l = links[size_t(en.link)];
        Rgb sum;
        for (size_t k = 0; k < l.pieces.size(); ++k) sum += pieceB(h, l, k) * factors_[en.factors + k];
        const Element& leaf = h[size_t(en.leaf)];
        out[size_t(en.leaf)] += mul(h.scene().polygons[size_t(leaf.polygon)].rho, sum);
    }
    return out;
}

ConvolutionField::ConvolutionField(const Hierarchy& h, const std::vector<ConvolutionLink>& links)
    : scene_(&h.scene()), links_(links) {
    const Scene& sc = h.scene();
    // A point handed in lies on its receiver to float32 rounding of the caller's coordinates.
    tol_ = 1e-5 * sc.diagonal;
    std::vector<std::vector<int>> linksOf(sc.polygons.size());
    for (size_t li = 0; li < links_.size(); ++li) {
        std::vector<Rgb> b;
        for (size_t k = 0; k < links_[li].pieces.size(); ++k) b.push_back(pieceB(h, links_[li], k));
        sourceB_.push_back(std::move(b));
        for (int p : links_[li].receiverPolygons) linksOf[size_t(p)].push_back(int(li));
    }
    polyGroup_.assign(sc.polygons.size(), 0);
    std::map<std::vector<int>, int> ids;
    std::vector<Bounds> boxes;
    for (size_t p = 0; p < sc.polygons.size(); ++p) {
        if (linksOf[p].empty()) continue;
        auto [it, fresh] = ids.emplace(linksOf[p], int(groups_.size()) + 1);
        if (fresh) groups_.push_back(linksOf[p]);
        polyGroup_[p] = it->second;
        Bounds bx;
        const Polygon& g = sc.polygons[p].geom;
        for (int k = 0; k < g.n; ++k) bx.extend(g.v[k]);
        bx.extend(bx.lo - Vec3{tol_, tol_, tol_});
        bx.extend(bx.hi + Vec3{tol_, tol_, tol_});
        boxes.push_back(bx);
        covered_.push_back(int(p));
    }
    boxes_ = BoxTree(std::move(boxes));
}

Rgb ConvolutionField::radiance(const Vec3& p, const Vec3& n, int* group, bool irradiance) const {
    *group = 0;
    if (links_.empty()) return {};
    const Scene& sc = *scene_;
    int face = -1;
    boxes_.query([&](const Bounds& b) { return contains(b, p); },
                 [&](int i) {
                     int q = covered_[size_t(i)];
                     if ((face >= 0 && q >= face) || !contains(boxes_.box(i), p)) return;
                     const ScenePolygon& sp = sc.polygons[size_t(q)];
                     if (dot(n, sp.normal) < 0.5) return;
                     const Polygon& g = sp.geom;
                     if (std::fabs(dot(p - g.v[0], sp.normal)) > tol_) return;
                     for (int k = 0; k < g.n; ++k) {
                         Vec3 inward = cross(sp.normal, g.v[(k + 1) % g.n] - g.v[k]);
                         double len = length(inward);
                         if (len > 0 && dot(p - g.v[k], inward) / len < -tol_) return;
                     }
                     face = q;
                 });
    if (face < 0) return {};
    *group = polyGroup_[size_t(face)];
    const ScenePolygon& rp = sc.polygons[size_t(face)];
    const Rgb rho = irradiance ? Rgb{1, 1, 1} : rp.rho;
    Rgb out;
    thread_local std::vector<double> f;  // per texel: no allocation once the buffer has grown
    for (int li : groups_[size_t(*group - 1)]) {
        const ConvolutionLink& l = links_[size_t(li)];
        f.assign(l.pieces.size(), 0.0);
        convolutionFactors(sc, l, p, rp.normal, f.data());
        Rgb irr;
        for (size_t k = 0; k < f.size(); ++k) irr += sourceB_[size_t(li)][k] * f[k];
        out += mul(rho, irr) * (1.0 / M_PI);
    }
    return out;
}

}  // namespace penumbra
