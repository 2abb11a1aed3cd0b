#include "refine/convolution_site.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "convolution/cost_model.h"
#include "hierarchy/node.h"
#include "visibility/shaft.h"

namespace penumbra {
namespace {

constexpr int kEmissionImage = 64;
constexpr int kMinTexture = 64;
constexpr int kDisplayFactor = 8;  // texels per side of a multi-face source's emission image

bool emits(const ScenePolygon& p) { return maxComponent(p.emission) > 0; }
bool sendsLight(const ScenePolygon& p) { return emits(p) || maxComponent(p.rho) > 0; }

Bounds polygonBox(const ScenePolygon& p) {
    Bounds b;
    for (int k = 0; k < p.geom.n; ++k) b.extend(p.geom.v[k]);
    return b;
}

// The box less `tol` on every side (a flat side stays where it is): whether two boxes overlap
// then no longer hangs on an object resting exactly on the other, nor on float32 rounding.
Bounds shrunk(const Bounds& b, double tol) {
    Bounds s = b;
    for (int k = 0; k < 3; ++k) {
        double lo = b.lo[k] + tol, hi = b.hi[k] - tol;
        if (lo > hi) lo = hi = 0.5 * (b.lo[k] + b.hi[k]);
        s.lo[k] = lo;
        s.hi[k] = hi;
    }
    return s;
}

bool samePlane(const ScenePolygon& a, const ScenePolygon& b, double tol) {
    if (std::fabs(dot(a.normal, b.normal)) < 1 - 1e-6) return false;
    for (int k = 0; k < b.geom.n; ++k)
        if (std::fabs(dot(b.geom.v[k] - a.geom.v[0], a.normal)) > tol) return false;
    return true;
}

// +1: every corner of `b` strictly in front of p's plane (beyond tol); -1: none; 0: it straddles.
int sideOf(const ScenePolygon& p, const Bounds& b, double tol) {
    bool front = false, back = false;
    for (int i = 0; i < 8; ++i) {
        Vec3 c{(i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z};
        (dot(c - p.geom.v[0], p.normal) > tol ? front : back) = true;
    }
    return front && !back ? 1 : (back && !front ? -1 : 0);
}

bool onOrBehind(const ScenePolygon& plane, const ScenePolygon& q, double tol) {
    for (int k = 0; k < q.geom.n; ++k)
        if (dot(q.geom.v[k] - plane.geom.v[0], plane.normal) > tol) return false;
    return true;
}

bool insideConvex(const Polygon& g, const Vec3& n, const Vec3& p) {
    for (int k = 0; k < g.n; ++k)
        if (dot(cross(n, g.v[(k + 1) % g.n] - g.v[k]), p - g.v[k]) < 0) return false;
    return true;
}

// One source polygon for the convolution: the face itself, or for several coplanar faces their
// bounding rectangle in the plane with an emission image that is zero where no face is.
SourceDesc describeSource(const Scene& sc, const std::vector<int>& faces) {
    SourceDesc d;
    const ScenePolygon& f0 = sc.polygons[size_t(faces[0])];
    if (faces.size() == 1) {
        for (int k = 0; k < f0.geom.n; ++k) d.polygon.push_back(f0.geom.v[k]);
        return d;
    }
    Vec3 n = f0.normal, e1 = normalize(f0.geom.v[1] - f0.geom.v[0]), e2 = cross(n, e1);
    Vec3 o = f0.geom.v[0];
    double s0 = HUGE_VAL, s1 = -HUGE_VAL, t0 = HUGE_VAL, t1 = -HUGE_VAL;
    for (int p : faces) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k) {
            double s = dot(g.v[k] - o, e1), t = dot(g.v[k] - o, e2);
            s0 = std::min(s0, s); s1 = std::max(s1, s);
            t0 = std::min(t0, t); t1 = std::max(t1, t);
        }
    }
    auto at = [&](double s, double t) { return o + e1 * s + e2 * t; };
    d.polygon = {at(s0, t0), at(s1, t0), at(s1, t1), at(s0, t1)};
    // The image weights the source by emission; V is the emission-weighted visible fraction.
    EmissionImage& img = d.emission;
    img.width = img.height = kEmissionImage;
    img.texels.assign(size_t(kEmissionImage) * kEmissionImage, 0.0f);
    const int ss = 2;
    for (int row = 0; row < kEmissionImage; ++row)
        for (int col = 0; col < kEmissionImage; ++col) {
            double sum = 0;
            for (int a = 0; a < ss; ++a)
                for (int b = 0; b < ss; ++b) {
                    double s = s0 + (s1 - s0) * (col + (b + 0.5) / ss) / kEmissionImage;
                    double t = t0 + (t1 - t0) * (row + (a + 0.5) / ss) / kEmissionImage;
                    Vec3 p = at(s, t);
                    for (int fi : faces) {
                        const ScenePolygon& f = sc.polygons[size_t(fi)];
                        if (insideConvex(f.geom, f.normal, p)) {
                            sum += maxComponent(f.emission);
                            break;
                        }
                    }
                }
            img.texels[size_t(row) * kEmissionImage + size_t(col)] = float(sum / (ss * ss));
        }
    return d;
}

}  // namespace

ConvolutionSites::ConvolutionSites(const Hierarchy& h, const RayCaster& rays, const Settings& s)
    : h_(h), rays_(rays), settings_(s) {
    const Scene& sc = h.scene();
    tol_ = 1e-3 * sc.diagonal;
    const ClusterTree& ct = h.clusters();
    planar_.assign(ct.size(), 0);
    hasEmitter_.assign(ct.size(), 0);
    emitterGroup_.assign(ct.size(), 0);
    for (size_t c = 0; c < ct.size(); ++c) {
        const Cluster& cl = ct[int(c)];
        const ScenePolygon& first = sc.polygons[size_t(ct.polygons()[size_t(cl.begin)])];
        bool planar = true, group = true, emitter = false;
        const ScenePolygon* firstSender = nullptr;
        for (int k = cl.begin; k < cl.end; ++k) {
            const ScenePolygon& p = sc.polygons[size_t(ct.polygons()[size_t(k)])];
            planar = planar && samePlane(first, p, tol_);
            emitter = emitter || emits(p);
            if (!sendsLight(p)) continue;
            if (!emits(p)) group = false;
            if (!firstSender) firstSender = &p;
            else group = group && samePlane(*firstSender, p, tol_);
        }
        planar_[c] = planar;
        hasEmitter_[c] = emitter;
        emitterGroup_[c] = group && emitter;
    }
}

bool ConvolutionSites::receiverCandidate(int r) const {
    const Scene& sc = h_.scene();
    Bounds b;
    if (isClusterNode(r)) {
        const Cluster& c = h_.clusters()[clusterIndex(r)];
        if (!planar_[size_t(clusterIndex(r))] || !(c.rhoMax > 0)) return false;
        b = c.box;
    } else {
        if (size_t(r) >= h_.numRoots()) return false;  // receivers are whole polygons or clusters
        const ScenePolygon& p = sc.polygons[size_t(r)];
        if (!p.receives || !(maxComponent(p.rho) > 0)) return false;
        b = nodeBox(h_, r);
    }
    return length(b.diagonal()) >= settings_.aMin * sc.diagonal;
}

bool ConvolutionSites::sourceHasEmitters(int s) const {
    if (isClusterNode(s)) return hasEmitter_[size_t(clusterIndex(s))];
    return size_t(s) < h_.numRoots() && emits(h_.scene().polygons[size_t(s)]);
}

void ConvolutionSites::nodePolygons(int node, std::vector<int>& out) const {
    out.clear();
    if (!isClusterNode(node)) {
        out.push_back(node);
        return;
    }
    const ClusterTree& ct = h_.clusters();
    const Cluster& c = ct[clusterIndex(node)];
    out.assign(ct.polygons().begin() + c.begin, ct.polygons().begin() + c.end);
    std::sort(out.begin(), out.end());
}

bool ConvolutionSites::tryLink(int r, int s, ConvolutionLink& out) {
    if (r == s || !receiverCandidate(r)) return false;
    if (isClusterNode(s) ? !emitterGroup_[size_t(clusterIndex(s))] : !sourceHasEmitters(s)) return false;
    const Scene& sc = h_.scene();
    std::vector<int> rpolys, spolys;
    nodePolygons(r, rpolys);
    nodePolygons(s, spolys);
    Bounds rb = nodeBox(h_, r), sb = nodeBox(h_, s);

    // The sending faces turned toward the receiver are the source; the others must not see any of it.
    std::vector<int> faces;
    for (int p : spolys) {
        const ScenePolygon& sp = sc.polygons[size_t(p)];
        if (!sendsLight(sp)) continue;
        int side = sideOf(sp, rb, tol_);
        if (side == 0) return false;
        if (side > 0) faces.push_back(p);
    }
    if (faces.empty()) return false;
    const ScenePolygon& rplane = sc.polygons[size_t(rpolys[0])];
    Bounds fb;
    for (int p : faces) fb.extend(polygonBox(sc.polygons[size_t(p)]));
    if (sideOf(rplane, fb, tol_) <= 0) return false;  // the source must be wholly in front of the receiver
    ++stats_.tried;

    // Blocker selection (§5.2): occluders whose boxes cross the shaft between source and receiver.
    const ScenePolygon& splane = sc.polygons[size_t(faces[0])];
    Shaft shaft(rb, fb);
    std::vector<BlockerTriangle> tris;
    std::vector<int> candidates = rays_.occludersInShaft(shaft);
    std::sort(candidates.begin(), candidates.end());
    for (int q : candidates) {
        if (std::binary_search(rpolys.begin(), rpolys.end(), q) || std::binary_search(spolys.begin(), spolys.end(), q))
            continue;
        const ScenePolygon& qp = sc.polygons[size_t(q)];
        Bounds qb = shrunk(polygonBox(qp), tol_);
        if (shaft.classify(qb) == Shaft::Outside) continue;
        // In the source's or the receiver's plane, or behind it: cannot cut a segment between them.
        if (onOrBehind(splane, qp, tol_) || onOrBehind(rplane, qp, tol_)) continue;
        if (overlaps(qb, rb) || overlaps(qb, fb)) {
            ++stats_.intruder;
            return false;
        }
        const Polygon& g = qp.geom;
        for (int k = 1; k + 1 < g.n; ++k) tris.push_back({g.v[0], g.v[k], g.v[k + 1]});
    }
    if (tris.empty()) {
        ++stats_.noBlocker;
        return false;
    }

    SourceDesc src = describeSource(sc, faces);
    ReceiverDesc rec;
    for (int p : rpolys) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k) rec.points.push_back(g.v[k]);
    }
    // E_rr is judged at the resolution the brief derives from the narrowest penumbra (texels of half
    // its width), so e_max means the same whatever the display needs. That resolution puts two texels
    // across a penumbra, and bilinear lookups then miss a penumbra's corner by 6 % of the light (parallel
    // planes, measured); the texture itself is made kDisplayFactor times finer, at least kMinTexture
    // texels a side, with the same sub-blockers.
    ConvolutionSettings cs;
    cs.e_max = settings_.eMax;
    cs.maxResolution = settings_.maxTexture;
    cs.minResolution = std::min(16, settings_.maxTexture);
    ConvolutionPlan plan;
    double judged = 0;  // E_rr in the texels of half the narrowest penumbra
    try {
        plan = planSoftShadow(src, tris, rec, cs);
        judged = plan.E_rr;
        int display = std::clamp(plan.n * kDisplayFactor, std::min(kMinTexture, settings_.maxTexture), settings_.maxTexture);
        if (!plan.slices.empty() && plan.E_rr <= settings_.eMax && display > plan.n) {
            ConvolutionSettings fine = cs;
            fine.resolution = display;
            fine.e_max = cs.e_max * double(display) / plan.n;
            ConvolutionPlan finer = planSoftShadow(src, tris, rec, fine);
            if (finer.slices.size() == plan.slices.size()) {
                plan = std::move(finer);
                cs = fine;
            }
        }
    } catch (const std::domain_error&) {
        ++stats_.invalid;
        return false;
    } catch (const std::invalid_argument&) {
        ++stats_.invalid;
        return false;
    }
    if (plan.slices.empty()) {
        ++stats_.noBlocker;
        return false;
    }
    if (judged > settings_.eMax) {
        ++stats_.tooCoarse;
        return false;
    }
    if (!withinBudget(plan.fftSize, int(plan.slices.size()), settings_.tMax)) {
        ++stats_.tooSlow;
        return false;
    }
    auto t0 = std::chrono::steady_clock::now();
    try {
        out.texture = std::make_shared<const SoftShadowTexture>(computeSoftShadow(plan, src, tris, cs));
    } catch (const std::domain_error&) {
        ++stats_.invalid;
        return false;
    }
    double dt = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    for (double cur = stats_.seconds.load(); !stats_.seconds.compare_exchange_weak(cur, cur + dt);) {
    }
    out.receiver = r;
    out.source = s;
    out.receiverPolygons.clear();
    for (int p : rpolys)
        if (sc.polygons[size_t(p)].receives && maxComponent(sc.polygons[size_t(p)].rho) > 0)
            out.receiverPolygons.push_back(p);
    out.sourcePolygons = faces;
    out.blockerTriangles = int(tris.size());
    out.error = judged;
    ++stats_.made;
    return true;
}

}  // namespace penumbra
