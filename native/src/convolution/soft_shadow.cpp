#include "convolution/soft_shadow.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "convolution/fft_convolver.h"

namespace penumbra {

namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// Newell's normal: length = 2 * area for a planar polygon, robust for non-convex ones.
Vec3 newellNormal(const std::vector<Vec3>& poly) {
    Vec3 n;
    for (size_t i = 0; i < poly.size(); ++i) {
        const Vec3& a = poly[i];
        const Vec3& b = poly[(i + 1) % poly.size()];
        n.x += (a.y - b.y) * (a.z + b.z);
        n.y += (a.z - b.z) * (a.x + b.x);
        n.z += (a.x - b.x) * (a.y + b.y);
    }
    return n;
}

Vec3 areaCentroid(const std::vector<Vec3>& poly, const Vec3& normal) {
    // Fan of triangles from vertex 0, signed areas along the normal so non-convex shapes work.
    Vec3 acc;
    double total = 0;
    for (size_t i = 1; i + 1 < poly.size(); ++i) {
        double a = dot(cross(poly[i] - poly[0], poly[i + 1] - poly[0]), normal);
        acc += (poly[0] + poly[i] + poly[i + 1]) * (a / 3.0);
        total += a;
    }
    return acc / total;
}

double bboxDiagonal(const std::vector<Vec3>& pts) {
    Bounds b;
    for (const Vec3& p : pts) b.extend(p);
    return length(b.diagonal());
}

struct SourceGeometry {
    Vec3 centroid, normal;  // unit normal, right-hand rule of the vertex order
    double diag = 0;
    Vec3 e1, e2;            // emission parametrisation axes
    double s0 = 0, s1 = 1, t0 = 0, t1 = 1;
};

SourceGeometry validateSource(const SourceDesc& src) {
    const auto& poly = src.polygon;
    if (poly.size() < 3) throw std::invalid_argument("source polygon needs at least 3 vertices");
    for (const Vec3& p : poly)
        if (!isFinite(p)) throw std::invalid_argument("source polygon has a non-finite vertex");
    SourceGeometry g;
    g.diag = bboxDiagonal(poly);
    Vec3 n = newellNormal(poly);
    double twiceArea = length(n);
    if (!(g.diag > 0) || !(twiceArea > 1e-10 * g.diag * g.diag))
        throw std::invalid_argument("source polygon is degenerate (zero area)");
    g.normal = n / twiceArea;
    g.centroid = areaCentroid(poly, g.normal);
    for (const Vec3& p : poly)
        if (std::fabs(dot(p - g.centroid, g.normal)) > 1e-4 * g.diag)
            throw std::invalid_argument("source polygon is not planar");
    Vec3 edge = poly[1] - poly[0];
    if (length(edge) <= 1e-12 * g.diag) {
        for (size_t i = 1; i < poly.size() && length(edge) <= 1e-12 * g.diag; ++i) edge = poly[(i + 1) % poly.size()] - poly[i];
    }
    g.e1 = normalize(edge - g.normal * dot(edge, g.normal));
    g.e2 = cross(g.normal, g.e1);
    g.s0 = g.t0 = HUGE_VAL;
    g.s1 = g.t1 = -HUGE_VAL;
    for (const Vec3& p : poly) {
        double s = dot(p - poly[0], g.e1), t = dot(p - poly[0], g.e2);
        g.s0 = std::fmin(g.s0, s);
        g.s1 = std::fmax(g.s1, s);
        g.t0 = std::fmin(g.t0, t);
        g.t1 = std::fmax(g.t1, t);
    }
    const EmissionImage& e = src.emission;
    if (!e.empty()) {
        if (e.width <= 0 || e.height <= 0 || e.texels.size() != static_cast<size_t>(e.width) * e.height)
            throw std::invalid_argument("emission image size does not match width * height");
        float mx = 0;
        for (float x : e.texels) {
            if (!std::isfinite(x) || x < 0)
                throw std::invalid_argument("emission image must hold finite, non-negative values");
            mx = std::fmax(mx, x);
        }
        if (!(mx > 0)) throw std::invalid_argument("emission image is zero everywhere");
    }
    return g;
}

void validateInputs(const std::vector<BlockerTriangle>& blockers, const ReceiverDesc& rec,
                    const ConvolutionSettings& s) {
    if (rec.points.empty()) throw std::invalid_argument("receiver has no points");
    for (const Vec3& p : rec.points)
        if (!isFinite(p)) throw std::invalid_argument("receiver has a non-finite point");
    for (size_t i = 0; i < blockers.size(); ++i)
        for (const Vec3& p : blockers[i])
            if (!isFinite(p)) throw std::invalid_argument("blocker triangle " + std::to_string(i) + " has a non-finite vertex");
    if (s.resolution < 0 || s.resolution > 8192) throw std::invalid_argument("resolution must be 0 (automatic) or 1..8192");
    if (s.minResolution < 1 || s.maxResolution < s.minResolution || s.maxResolution > 8192)
        throw std::invalid_argument("need 1 <= minResolution <= maxResolution <= 8192");
    if (!(s.e_max > 0) || !std::isfinite(s.e_max)) throw std::invalid_argument("e_max must be positive and finite");
    if (s.n_max < 1 || s.n_max > 64) throw std::invalid_argument("n_max must be in 1..64");
    if (!(s.depthTolerance >= 0) || !std::isfinite(s.depthTolerance))
        throw std::invalid_argument("depthTolerance must be >= 0");
    if (s.supersample < 1 || s.supersample > 16) throw std::invalid_argument("supersample must be in 1..16");
    if (s.maxFftSize < 16) throw std::invalid_argument("maxFftSize must be >= 16");
}

// Penumbra scale in virtual-plane units of a source point at depth zs, a blocker point at zb and a
// receiver point at zy (brief §3.2 item 5, extended to a source off the plane w = 0).
double alphaAt(double z_r, double zs, double zb, double zy) { return z_r * (zy - zb) / (zy * (zb - zs)); }
// Relative displacement of the shadow of a blocker point when the source point sits at depth zs
// instead of 0: the orthographic kernel misses this shear for a source tilted against w.
double shearAt(double zs, double zb, double zy) { return zb * zs * (zy - zb) / (zy * (zb - zs)); }

void estimateSlice(const ConvolutionPlan& P, double maxRadius, SubBlocker& sb) {
    const double z_r = P.window.z_r;
    const DepthRange& S = P.sourceDepth;
    const DepthRange& R = P.receiverDepth;
    sb.alphaHi = alphaAt(z_r, S.hi, sb.depth.lo, R.hi);
    sb.alphaLo = std::fmax(0.0, alphaAt(z_r, S.lo, sb.depth.hi, R.lo));
    sb.alphaHi = std::fmax(sb.alphaHi, sb.alphaLo);
    sb.alphaStar = 0.5 * (sb.alphaLo + sb.alphaHi);
    double shear = 0;
    for (double zb : {sb.depth.lo, sb.depth.hi})
        for (double zy : {R.lo, R.hi})
            shear = std::fmax(shear, std::fabs(shearAt(S.hi, zb, zy) - shearAt(S.lo, zb, zy)));
    sb.error = (P.L_S * (sb.alphaHi - sb.alphaLo) * 0.5 + maxRadius * shear) / P.p;
    const double width = sb.alphaStar * P.L_S / P.p;  // kernel width, texels
    sb.visibilityError = sb.error > 0 ? std::fmin(1.0, 1.25 * sb.error / std::fmax(width, 1e-300)) : 0.0;
}

// Per-triangle quantities the slab split needs, computed once for all N tried.
struct TriangleDepths {
    double invCentroid;  // 1 / depth of the centroid
    DepthRange depth;
    double radius;       // largest distance of a projected vertex from the axis, virtual plane
};

// Splits the blocker into N slabs of equal inverse depth (brief §4.3, slab variant); each triangle
// goes to the slab of its centroid and each slab's depth range is that of its own triangles.
std::vector<SubBlocker> slabs(const ConvolutionPlan& P, const std::vector<int>& kept,
                              const std::vector<TriangleDepths>& td, int N) {
    const double bLo = 1.0 / P.blockerDepth.hi, bHi = 1.0 / P.blockerDepth.lo;
    std::vector<SubBlocker> out(N);
    std::vector<double> radius(N, 0.0);
    for (size_t i = 0; i < kept.size(); ++i) {
        int k = bHi > bLo ? static_cast<int>(std::floor((td[i].invCentroid - bLo) / (bHi - bLo) * N)) : 0;
        k = std::clamp(k, 0, N - 1);
        out[k].triangles.push_back(kept[i]);
        out[k].depth.extend(td[i].depth);
        radius[k] = std::fmax(radius[k], td[i].radius);
    }
    std::vector<SubBlocker> nonEmpty;
    for (int k = 0; k < N; ++k)
        if (!out[k].triangles.empty()) {
            estimateSlice(P, radius[k], out[k]);
            nonEmpty.push_back(std::move(out[k]));
        }
    return nonEmpty;
}

// The steps of planWithDirection, in order. Each returns why the configuration cannot be convolved
// (empty: go on), and planWithDirection throws that reason as std::domain_error.

// The convolution axis w for `dir` (brief §3.2), pointing from the source toward the receiver.
std::string chooseAxis(const SourceGeometry& sg, const ReceiverDesc& rec, DirectionChoice dir, Vec3& w) {
    Bounds rb;
    for (const Vec3& p : rec.points) rb.extend(p);
    const Vec3 toReceiver = rb.center() - sg.centroid;
    if (dir == DirectionChoice::SourceToReceiver) {
        w = toReceiver;
    } else if (dir == DirectionChoice::SourceNormal) {
        w = sg.normal * (dot(sg.normal, toReceiver) >= 0 ? 1.0 : -1.0);
    } else {
        if (rec.points.size() < 3) return "receiver normal needs a receiver polygon";
        Vec3 n = newellNormal(rec.points);
        double diag = bboxDiagonal(rec.points);
        if (!(length(n) > 1e-10 * diag * diag)) return "receiver polygon has no normal";
        n = n / length(n);
        for (const Vec3& p : rec.points)
            if (std::fabs(dot(p - rec.points[0], n)) > 1e-4 * diag)
                return "receiver points are not planar, no receiver normal";
        w = n * (dot(n, toReceiver) >= 0 ? 1.0 : -1.0);
    }
    if (!(length(w) > 0)) return "receiver centre coincides with the source centre";
    return "";
}

// The frame along w and the depths of source and receiver; the source must face the receiver.
std::string frameAndDepths(const SourceDesc& src, const SourceGeometry& sg, const ReceiverDesc& rec,
                           const Vec3& w, ConvolutionPlan& P) {
    P.frame = ConvolutionFrame::make(sg.centroid, w, src.polygon[1] - src.polygon[0]);
    const ConvolutionFrame& f = P.frame;
    P.sourceDepth = f.depthRange(src.polygon);
    P.receiverDepth = f.depthRange(rec.points);
    // Every receiver point on the source's emitting side.
    double side = 0;
    for (const Vec3& p : rec.points) {
        double d = dot(p - sg.centroid, sg.normal);
        if (d == 0 || (side != 0 && (d > 0) != (side > 0)))
            return "receiver is not entirely on one side of the source plane";
        side = d;
    }
    if (std::fabs(dot(sg.normal, f.w)) < 1e-6) return "source is seen edge-on along the convolution direction";
    return "";
}

// The blocker triangles that can cut a source-receiver segment (the others, entirely beyond the
// receiver or behind the source, are dropped exactly), and their depth order between the two.
std::string keepBlockers(const std::vector<BlockerTriangle>& blockers, const ConvolutionSettings& s,
                         ConvolutionPlan& P, std::vector<int>& kept) {
    const ConvolutionFrame& f = P.frame;
    for (size_t i = 0; i < blockers.size(); ++i) {
        DepthRange d;
        for (const Vec3& v : blockers[i]) d.extend(f.depth(v));
        if (d.lo >= P.receiverDepth.hi || d.hi <= P.sourceDepth.lo) continue;
        kept.push_back(static_cast<int>(i));
        P.blockerDepth.extend(d);
    }
    const double tol = s.depthTolerance * (P.receiverDepth.hi - P.sourceDepth.lo);
    DepthOrder order = checkDepthOrder(P.sourceDepth, P.blockerDepth, P.receiverDepth, tol);
    if (!order.ok) return "not a valid convolution configuration: " + order.reason;
    return "";
}

// The receiver's window, the source's footprint and the texture resolution n.
std::string windowAndResolution(const SourceDesc& src, const ReceiverDesc& rec, const ConvolutionSettings& s,
                                bool anyBlocker, ConvolutionPlan& P) {
    const ConvolutionFrame& f = P.frame;
    P.window = windowByCentralProjection(f, rec.points);
    if (!(P.window.extent > 0)) return "receiver window has zero size";
    double ulo = HUGE_VAL, uhi = -HUGE_VAL, vlo = HUGE_VAL, vhi = -HUGE_VAL;
    for (const Vec3& p : src.polygon) {
        Vec2 q{f.coordU(p), f.coordV(p)};
        P.footprint.push_back(q);
        ulo = std::fmin(ulo, q.x);
        uhi = std::fmax(uhi, q.x);
        vlo = std::fmin(vlo, q.y);
        vhi = std::fmax(vhi, q.y);
    }
    P.L_S = std::fmax(uhi - ulo, vhi - vlo);
    // alpha_min does not depend on N: the slab holding the deepest triangle always has the
    // global far depth, so it can choose the resolution before the split.
    if (anyBlocker)
        P.alpha_min = std::fmax(0.0, alphaAt(P.window.z_r, P.sourceDepth.lo, P.blockerDepth.hi, P.receiverDepth.lo));
    if (s.resolution > 0) {
        P.n = s.resolution;
    } else if (!anyBlocker) {
        P.n = s.minResolution;
    } else {
        // Texels of half the narrowest penumbra resolve every penumbra (brief §5.1).
        double pWanted = P.alpha_min * P.L_S / 2;
        double pc = std::clamp(pWanted, P.window.extent / s.maxResolution, P.window.extent / s.minResolution);
        P.n = std::clamp(static_cast<int>(std::ceil(P.window.extent / pc - 1e-9)), s.minResolution, s.maxResolution);
    }
    P.p = P.window.extent / P.n;
    return "";
}

// The sub-blockers: the smallest N reaching e_max. If none does (the receiver's own depth spread may
// dominate), the smallest N within 10% of the best error reached: every extra slab costs FFTs and adds
// seams where the product of slice maps is approximate.
void chooseSlices(const std::vector<BlockerTriangle>& blockers, const std::vector<int>& kept,
                  const ConvolutionSettings& s, ConvolutionPlan& P) {
    const ConvolutionFrame& f = P.frame;
    std::vector<TriangleDepths> td(kept.size());
    for (size_t i = 0; i < kept.size(); ++i) {
        const BlockerTriangle& t = blockers[kept[i]];
        td[i].invCentroid = 1.0 / f.depth((t[0] + t[1] + t[2]) / 3.0);
        td[i].radius = 0;
        for (const Vec3& v : t) {
            double z = f.depth(v), k2 = P.window.z_r / z;
            td[i].depth.extend(z);
            td[i].radius = std::fmax(td[i].radius, std::hypot(f.coordU(v) * k2, f.coordV(v) * k2));
        }
    }
    std::vector<std::vector<SubBlocker>> tries;
    std::vector<double> errs;
    for (int N = 1; N <= s.n_max; ++N) {
        tries.push_back(slabs(P, kept, td, N));
        double e = 0;
        for (const SubBlocker& b : tries.back()) e = std::fmax(e, b.error);
        errs.push_back(e);
        if (e <= s.e_max) break;
        if (P.blockerDepth.hi == P.blockerDepth.lo) break;  // a flat blocker cannot be split
    }
    size_t pick = errs.size() - 1;
    if (errs.back() > s.e_max) {
        double best = *std::min_element(errs.begin(), errs.end());
        for (pick = 0; errs[pick] > best * 1.1 + 1e-12; ++pick) {
        }
    }
    P.slices = std::move(tries[pick]);
    P.E_rr = errs[pick];
    P.alpha_min = HUGE_VAL;
    for (const SubBlocker& b : P.slices) {
        P.alpha_min = std::fmin(P.alpha_min, b.alphaLo);
        P.visibilityError = std::fmax(P.visibilityError, b.visibilityError);
    }
}

// Contact sub-blockers (issue 12). A blocker standing on the receiver casts a penumbra whose width falls to
// zero at the contact, so no single kernel fits it and the narrowest penumbra gives no texel size. The
// blocker is cut at depth planes (triangles clipped, not assigned whole) into slabs of penumbra scale
// [0, a1], [a1, a1 r], [a1 r, a1 r^2], ...: the contact slab's penumbra spread is e_max texels (below that
// a penumbra is not resolved anyway: the paper's delta = alpha_min L_S floor), and every other slab's
// spread is e_max halves of its own narrowest penumbra, the unit E_rr has elsewhere. The slab at the
// contact also gets the blocker's cross-section (the cap): its map is then the solid's shadow, and the
// receiver under the object is dark whatever the product of the wall strips above it lets through.

// The part of t between the depth planes zlo and zhi (Sutherland-Hodgman on two half-spaces).
std::vector<Vec3> clipToDepth(const BlockerTriangle& t, const ConvolutionFrame& f, double zlo, double zhi) {
    std::vector<Vec3> poly(t.begin(), t.end()), next;
    for (int side = 0; side < 2; ++side) {
        next.clear();
        auto inside = [&](const Vec3& v) { return side == 0 ? f.depth(v) >= zlo : f.depth(v) <= zhi; };
        const double zc = side == 0 ? zlo : zhi;
        for (size_t i = 0; i < poly.size(); ++i) {
            const Vec3& a = poly[i];
            const Vec3& b = poly[(i + 1) % poly.size()];
            bool ia = inside(a), ib = inside(b);
            if (ia) next.push_back(a);
            if (ia != ib) {
                double za = f.depth(a), zb = f.depth(b);
                next.push_back(a + (b - a) * ((zc - za) / (zb - za)));
            }
        }
        poly.swap(next);
        if (poly.size() < 3) return {};
    }
    return poly;
}

// The closed loops where the depth plane zc cuts the blocker triangles. Crossing points are computed from
// each edge's endpoints in a fixed order, so neighbouring triangles produce bit-identical points and the
// segments chain by exact match; open chains (a mesh that is not closed) make no cap.
std::vector<std::vector<Vec3>> crossSection(const std::vector<BlockerTriangle>& blockers, const std::vector<int>& kept,
                                            const ConvolutionFrame& f, double zc) {
    using Key = std::tuple<double, double, double>;
    auto key = [](const Vec3& v) { return Key{v.x, v.y, v.z}; };
    std::vector<std::pair<Vec3, Vec3>> segs;
    for (int idx : kept) {
        const BlockerTriangle& t = blockers[size_t(idx)];
        Vec3 pts[2];
        int m = 0;
        for (int e = 0; e < 3; ++e) {
            Vec3 a = t[size_t(e)], b = t[size_t((e + 1) % 3)];
            if (key(b) < key(a)) std::swap(a, b);
            double za = f.depth(a), zb = f.depth(b);
            if ((za >= zc) == (zb >= zc)) continue;
            if (m < 2) pts[m] = a + (b - a) * ((zc - za) / (zb - za));
            ++m;
        }
        if (m == 2 && key(pts[0]) != key(pts[1])) segs.emplace_back(pts[0], pts[1]);
    }
    std::multimap<Key, size_t> at;
    for (size_t i = 0; i < segs.size(); ++i) {
        at.emplace(key(segs[i].first), i);
        at.emplace(key(segs[i].second), i);
    }
    std::vector<char> used(segs.size(), 0);
    std::vector<std::vector<Vec3>> loops;
    for (size_t s0 = 0; s0 < segs.size(); ++s0) {
        if (used[s0]) continue;
        used[s0] = 1;
        std::vector<Vec3> loop{segs[s0].first};
        Vec3 cur = segs[s0].second;
        bool closed = false;
        while (true) {
            if (key(cur) == key(loop.front())) {
                closed = true;
                break;
            }
            loop.push_back(cur);
            size_t nextSeg = segs.size();
            auto range = at.equal_range(key(cur));
            for (auto it = range.first; it != range.second; ++it)
                if (!used[it->second]) {
                    nextSeg = it->second;
                    break;
                }
            if (nextSeg == segs.size()) break;
            used[nextSeg] = 1;
            cur = key(segs[nextSeg].first) == key(cur) ? segs[nextSeg].second : segs[nextSeg].first;
        }
        if (closed && loop.size() >= 3) loops.push_back(std::move(loop));
    }
    return loops;
}

// Of a closed surface, the faces the whole source sees from behind. A ray from a source point through a convex
// solid enters by a face turned toward that point and leaves by one turned away; with both in the slabs it is
// counted in each slab it crosses, and the product of the slab maps darkens the penumbra. A face turned away
// from every source vertex is never where a ray enters, so it can go. A triangle counts as closed when each edge
// is run the other way by another blocker triangle (a consistently wound closed surface) or lies on the
// receiver (a box open at the floor); open surfaces (a card, a panel) and inconsistently wound ones stay.
std::vector<int> facingTheSource(const std::vector<BlockerTriangle>& blockers, const std::vector<int>& kept,
                                 const ConvolutionFrame& f, const std::vector<Vec3>& source, double zContact) {
    using Key = std::tuple<double, double, double>;
    auto key = [](const Vec3& v) { return Key{v.x, v.y, v.z}; };
    std::map<std::pair<Key, Key>, int> directed;
    for (int idx : kept)
        for (int e = 0; e < 3; ++e)
            ++directed[{key(blockers[size_t(idx)][size_t(e)]), key(blockers[size_t(idx)][size_t((e + 1) % 3)])}];
    std::vector<int> out;
    for (int idx : kept) {
        const BlockerTriangle& t = blockers[size_t(idx)];
        bool closed = true;
        for (int e = 0; e < 3 && closed; ++e) {
            const Vec3& a = t[size_t(e)];
            const Vec3& b = t[size_t((e + 1) % 3)];
            auto reverse = directed.find({key(b), key(a)});
            closed = (reverse != directed.end() && reverse->second > 0) ||
                     (f.depth(a) >= zContact && f.depth(b) >= zContact);
        }
        const Vec3 n = cross(t[1] - t[0], t[2] - t[0]);
        bool behind = closed;
        for (size_t k = 0; k < source.size() && behind; ++k) behind = dot(n, source[k] - t[0]) < 0;
        if (behind) continue;
        out.push_back(idx);
    }
    return out;
}

void chooseContactSlices(const SourceDesc& src, const std::vector<BlockerTriangle>& blockers,
                         const std::vector<int>& allKept, const ConvolutionSettings& s, ConvolutionPlan& P) {
    const ConvolutionFrame& f = P.frame;
    const double touch = s.depthTolerance * (P.receiverDepth.hi - P.sourceDepth.lo);
    const std::vector<int> kept = facingTheSource(blockers, allKept, f, src.polygon, P.receiverDepth.lo - touch);
    const double z_r = P.window.z_r;
    const double zTop = P.blockerDepth.lo, zBottom = P.blockerDepth.hi;
    // Penumbra scale of a blocker point at depth z for the source centre and the receiver plane.
    auto alphaOf = [&](double z) { return std::fmax(0.0, z_r / z - 1); };
    auto depthOf = [&](double a) { return z_r / (1 + a); };
    const double aTop = alphaOf(zTop);
    // Aim a little under e_max: the slabs' errors equal the target by construction, and the rounding of a
    // scene's coordinates (the same room scaled by 1e-3) must not decide whether the link passes.
    const double e = s.e_max * (1 - 1e-3);
    const double a1 = 2 * e * P.p / P.L_S;
    int N = 1;
    double r = 1;
    if (aTop > a1) {
        N = std::min(s.n_max, 1 + static_cast<int>(std::ceil(std::log(aTop / a1) / std::log1p(e) - 1e-9)));
        r = N > 1 ? std::pow(aTop / a1, 1.0 / (N - 1)) : 1;
    }
    // Boundaries from the receiver up: bound[0] = zBottom, bound[N] = zTop.
    std::vector<double> bound{zBottom};
    for (int k = 1; k < N; ++k) bound.push_back(std::fmin(zBottom, depthOf(a1 * std::pow(r, k - 1))));
    bound.push_back(zTop);
    P.slices.clear();
    P.contact = true;
    for (int k = 0; k < N; ++k) {
        const double zhi = bound[size_t(k)], zlo = bound[size_t(k) + 1];
        if (!(zlo < zhi)) continue;
        SubBlocker sb;
        double radius = 0;
        auto take = [&](const std::vector<Vec3>& poly) {
            for (const Vec3& v : poly) {
                double z = f.depth(v), k2 = z_r / z;
                sb.depth.extend(z);
                radius = std::fmax(radius, std::hypot(f.coordU(v) * k2, f.coordV(v) * k2));
            }
            sb.pieces.push_back(poly);
        };
        for (int idx : kept) {
            std::vector<Vec3> piece = clipToDepth(blockers[size_t(idx)], f, zlo, zhi);
            if (piece.size() >= 3) take(piece);
        }
        if (k == 0)
            for (std::vector<Vec3>& loop : crossSection(blockers, allKept, f, 0.5 * (zlo + zhi))) take(loop);
        if (sb.pieces.empty()) continue;
        estimateSlice(P, radius, sb);
        sb.error *= P.p / std::fmax(sb.alphaLo * P.L_S / 2, P.p);
        P.slices.push_back(std::move(sb));
    }
    P.E_rr = 0;
    P.alpha_min = HUGE_VAL;
    for (const SubBlocker& b : P.slices) {
        P.E_rr = std::fmax(P.E_rr, b.error);
        P.alpha_min = std::fmin(P.alpha_min, b.alphaLo);
        P.visibilityError = std::fmax(P.visibilityError, b.visibilityError);
    }
}

// Padding (brief §5.2): the blocker is needed over [y + alpha s_lo, y + alpha s_hi]; the padded size
// must fit maxFftSize.
std::string padding(const ConvolutionSettings& s, ConvolutionPlan& P) {
    double ulo = HUGE_VAL, uhi = -HUGE_VAL, vlo = HUGE_VAL, vhi = -HUGE_VAL;
    for (const Vec2& q : P.footprint) {
        ulo = std::fmin(ulo, q.x);
        uhi = std::fmax(uhi, q.x);
        vlo = std::fmin(vlo, q.y);
        vhi = std::fmax(vhi, q.y);
    }
    double alphaUse = 0;
    for (const SubBlocker& b : P.slices) alphaUse = std::fmax(alphaUse, b.alphaStar);
    auto margin = [&](double extentOut) { return static_cast<int>(std::ceil(alphaUse * extentOut / P.p)) + 1; };
    P.marginLoU = margin(-ulo);
    P.marginLoV = margin(-vlo);
    int need = std::max(P.n + P.marginLoU + margin(uhi), P.n + P.marginLoV + margin(vhi));
    if (need > s.maxFftSize) {
        std::ostringstream m;
        m << "penumbra too wide for the texture: the padded FFT would be " << need << " > " << s.maxFftSize
          << " (lower the resolution)";
        return m.str();
    }
    P.fftSize = fastFftSize(need);
    return "";
}

ConvolutionPlan planWithDirection(const SourceDesc& src, const SourceGeometry& sg,
                                  const std::vector<BlockerTriangle>& blockers, const ReceiverDesc& rec,
                                  const ConvolutionSettings& s, DirectionChoice dir) {
    auto refuse = [](const std::string& why) {
        if (!why.empty()) throw std::domain_error(why);
    };
    Vec3 w;
    refuse(chooseAxis(sg, rec, dir, w));
    ConvolutionPlan P;
    P.direction = dir;
    refuse(frameAndDepths(src, sg, rec, w, P));
    std::vector<int> kept;
    refuse(keepBlockers(blockers, s, P, kept));
    refuse(windowAndResolution(src, rec, s, !kept.empty(), P));
    if (kept.empty()) return P;
    // The blocker reaches the receiver's nearest depth (it stands on it), to the tolerance of the depth order:
    // a box resting on a floor must not fall on either side of the test with the rounding of its coordinates.
    const double touch = s.depthTolerance * (P.receiverDepth.hi - P.sourceDepth.lo);
    if (s.contactSlabs && P.blockerDepth.hi >= P.receiverDepth.lo - touch && P.blockerDepth.lo < P.blockerDepth.hi)
        chooseContactSlices(src, blockers, kept, s, P);
    else
        chooseSlices(blockers, kept, s, P);
    refuse(padding(s, P));
    return P;
}

}  // namespace

ConvolutionPlan planSoftShadow(const SourceDesc& source, const std::vector<BlockerTriangle>& blockers,
                               const ReceiverDesc& receiver, const ConvolutionSettings& settings) {
    const SourceGeometry sg = validateSource(source);
    validateInputs(blockers, receiver, settings);
    if (settings.direction != DirectionChoice::Auto)
        return planWithDirection(source, sg, blockers, receiver, settings, settings.direction);
    // Try the candidate directions of brief §3.2 and keep the one needing the fewest sub-blockers,
    // then the smallest error; the first candidate's failure is the one reported.
    std::string firstFailure;
    bool have = false;
    ConvolutionPlan best;
    for (DirectionChoice d : {DirectionChoice::SourceToReceiver, DirectionChoice::ReceiverNormal,
                              DirectionChoice::SourceNormal}) {
        ConvolutionPlan P;
        try {
            P = planWithDirection(source, sg, blockers, receiver, settings, d);
        } catch (const std::domain_error& e) {
            if (firstFailure.empty()) firstFailure = e.what();
            continue;
        }
        auto key = [&](const ConvolutionPlan& q) {
            return std::make_tuple(q.E_rr > settings.e_max, q.slices.size(), q.E_rr);
        };
        if (!have || key(P) < key(best)) {
            best = std::move(P);
            have = true;
        }
    }
    if (!have) throw std::domain_error(firstFailure);
    return best;
}

SoftShadowTexture computeSoftShadow(const ConvolutionPlan& P, const SourceDesc& source,
                                    const std::vector<BlockerTriangle>& blockers,
                                    const ConvolutionSettings& settings) {
    const auto tStart = Clock::now();
    double rasterMs = 0, fftMs = 0;
    const SourceGeometry sg = validateSource(source);
    SoftShadowTexture T;
    T.n = P.n;
    T.visibility.assign(static_cast<size_t>(P.n) * P.n, 1.0f);
    T.matrix = textureMatrix(P.frame, P.window);
    T.E_rr = P.E_rr;
    T.alpha_min = P.alpha_min;
    T.visibilityError = P.visibilityError;
    T.subBlockers = static_cast<int>(P.slices.size());
    T.fftSize = P.fftSize;
    T.frame = P.frame;
    T.window = P.window;
    T.rasterizer = settings.rasterizer == RasterizerKind::OSMesa ? RasterizerKind::OSMesa : RasterizerKind::Span;
    if (P.slices.empty()) {
        T.times.restMs = msSince(tStart);
        return T;
    }
    for (const SubBlocker& b : P.slices)
        for (int idx : b.triangles)
            if (idx < 0 || static_cast<size_t>(idx) >= blockers.size())
                throw std::invalid_argument("plan does not match the blocker list");

    const ConvolutionFrame& f = P.frame;
    const int F = P.fftSize;
    std::function<float(double, double)> emission;
    if (!source.emission.empty()) {
        // Footprint (u, v) -> point of the source plane -> the source's own (s, t) -> bilinear.
        const double nw = dot(sg.normal, f.w);
        emission = [&source, &sg, &f, nw](double x, double y) -> float {
            const EmissionImage& e = source.emission;
            Vec3 d = f.u * x + f.v * y;
            Vec3 Pt = f.O + d - f.w * (dot(sg.normal, d) / nw);
            double s = (dot(Pt - source.polygon[0], sg.e1) - sg.s0) / (sg.s1 - sg.s0);
            double t = (dot(Pt - source.polygon[0], sg.e2) - sg.t0) / (sg.t1 - sg.t0);
            double cx = std::clamp(s * e.width - 0.5, 0.0, e.width - 1.0);
            double cy = std::clamp(t * e.height - 0.5, 0.0, e.height - 1.0);
            int x0 = static_cast<int>(cx), y0 = static_cast<int>(cy);
            int x1 = std::min(x0 + 1, e.width - 1), y1 = std::min(y0 + 1, e.height - 1);
            double fx = cx - x0, fy = cy - y0;
            auto at = [&](int xx, int yy) { return static_cast<double>(e.texels[static_cast<size_t>(yy) * e.width + xx]); };
            return static_cast<float>((1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) +
                                      fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1)));
        };
    }

    std::unique_ptr<CoverageRasterizer> raster = makeRasterizer(settings.rasterizer, settings.supersample);
    FftConvolver fft(F);
    // Work images are kept per thread for the last size: fresh multi-megabyte buffers cost a page
    // fault per 4 KiB on first touch, as much as a third of the transforms at n = 1024.
    struct Work {
        int size = 0;
        RealImage kernel, blocker, occ;
        Spectrum kernelSpec, scratch;
    };
    thread_local Work work;
    if (work.size != F) {
        work = Work{};
        work.kernel = fft.makeImage();
        work.blocker = fft.makeImage();
        work.occ = fft.makeImage();
        work.kernelSpec = fft.makeSpectrum();
        work.scratch = fft.makeSpectrum();
        work.size = F;
    }
    RealImage& kernel = work.kernel;
    RealImage& blocker = work.blocker;
    RealImage& occ = work.occ;
    Spectrum& kernelSpec = work.kernelSpec;
    Spectrum& scratch = work.scratch;
    double kernelAlpha = -1, kernelSum = 0;
    PixelGrid grid{P.window.u_lo - P.marginLoU * P.p, P.window.v_lo - P.marginLoV * P.p, P.p, F, F};
    PolygonSet polys;
    // Values this close to 0 or 1 are FFT round-off (float): snapping them makes umbra exactly 0
    // and full light exactly 1.
    const float snap = 1e-4f;

    for (const SubBlocker& b : P.slices) {
        auto t0 = Clock::now();
        if (b.alphaStar != kernelAlpha) {
            kernelSum = renderSourceKernel(P.footprint, b.alphaStar, P.p, F, settings.supersample,
                                           emission ? &emission : nullptr, kernel.data());
            rasterMs += msSince(t0);
            auto t1 = Clock::now();
            fft.forward(kernel, kernelSpec);
            fftMs += msSince(t1);
            kernelAlpha = b.alphaStar;
        }
        auto t2 = Clock::now();
        polys.clear();
        for (const std::vector<Vec3>& poly : b.pieces) {
            std::vector<Vec2> q(poly.size());
            for (size_t k = 0; k < poly.size(); ++k) {
                double sc = P.window.z_r / f.depth(poly[k]);
                q[k] = {f.coordU(poly[k]) * sc, f.coordV(poly[k]) * sc};
            }
            polys.add(q.data(), static_cast<int>(q.size()));
        }
        for (int idx : b.triangles) {
            Vec2 q[3];
            for (int k = 0; k < 3; ++k) {
                const Vec3& v = blockers[idx][k];
                double s = P.window.z_r / f.depth(v);
                q[k] = {f.coordU(v) * s, f.coordV(v) * s};
            }
            polys.add(q, 3);
        }
        raster->rasterize(polys, grid, blocker.data());
        rasterMs += msSince(t2);
        auto t3 = Clock::now();
        fft.convolveNormalized(kernelSpec, kernelSum, blocker, scratch, occ);
        fftMs += msSince(t3);
        // Product of the slice maps (brief §4.4).
        for (int c = 0; c < P.n; ++c) {
            const float* row = occ.data() + static_cast<size_t>(c + P.marginLoV) * F + P.marginLoU;
            float* dst = T.visibility.data() + static_cast<size_t>(c) * P.n;
            for (int a = 0; a < P.n; ++a) {
                float v = 1.0f - row[a];
                v = v < snap ? 0.0f : (v > 1.0f - snap ? 1.0f : v);
                dst[a] *= v;
            }
        }
    }
    T.times.rasterMs = rasterMs;
    T.times.fftMs = fftMs;
    T.times.restMs = std::fmax(0.0, msSince(tStart) - rasterMs - fftMs);
    return T;
}

SoftShadowTexture computeSoftShadow(const SourceDesc& source, const std::vector<BlockerTriangle>& blockers,
                                    const ReceiverDesc& receiver, const ConvolutionSettings& settings) {
    const auto t0 = Clock::now();
    ConvolutionPlan plan = planSoftShadow(source, blockers, receiver, settings);
    double planMs = msSince(t0);
    SoftShadowTexture T = computeSoftShadow(plan, source, blockers, settings);
    T.times.restMs += planMs;
    return T;
}

float lookupVisibility(const SoftShadowTexture& tex, const Vec3& P) {
    TexCoord c = applyTextureMatrix(tex.matrix, P);
    if (!(c.q > 0) || tex.n <= 0) return std::numeric_limits<float>::quiet_NaN();
    const int n = tex.n;
    double x = std::clamp(c.s * n - 0.5, 0.0, n - 1.0), y = std::clamp(c.t * n - 0.5, 0.0, n - 1.0);
    int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    int x1 = std::min(x0 + 1, n - 1), y1 = std::min(y0 + 1, n - 1);
    double fx = x - x0, fy = y - y0;
    auto at = [&](int i, int j) { return static_cast<double>(tex.visibility[static_cast<size_t>(j) * n + i]); };
    return static_cast<float>((1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x1, y0)) +
                              fy * ((1 - fx) * at(x0, y1) + fx * at(x1, y1)));
}

}  // namespace penumbra
