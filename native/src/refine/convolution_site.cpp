#include "refine/convolution_site.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <stdexcept>

#include "convolution/cost_model.h"
#include "geometry/polygon.h"
#include "hierarchy/node.h"
#include "hierarchy/predicates.h"
#include "visibility/shaft.h"

namespace penumbra {
namespace {

PENUMBRA_COUNTER(kTried, "convolution_tried");  // pairs that reached the blocker selection; refused, by reason:
PENUMBRA_COUNTER(kNoBlocker, "convolution_refused/no_blocker");  // none in the shaft: standard links are cheap
PENUMBRA_COUNTER(kIntruder, "convolution_refused/intruder");  // an occluder reaches into the source's or receiver's box
PENUMBRA_COUNTER(kInvalid, "convolution_refused/invalid");  // depth order or geometry the convolution cannot take
PENUMBRA_COUNTER(kTooCoarse, "convolution_refused/too_coarse");  // E_rr > e_max
PENUMBRA_COUNTER(kTooSlow, "convolution_refused/too_slow");      // predicted time > t_max
PENUMBRA_COUNTER(kSelfShadow, "convolution_refused/self_shadow");  // a cluster receiver shading itself

constexpr int kEmissionImage = 64;  // texels per side of a multi-face source's emission image
constexpr int kMinTexture = 64;
constexpr int kDisplayFactor = 8;
// A source part's side is at most this fraction of its distance to the receiver, in at most kMaxParts x
// kMaxParts parts. The area-weighted visibility's error falls as the square of the part's size: on
// parallel planes 4.1 % of the peak with one part, 1.1 % with 2 x 2, 0.3 % with 4 x 4 (brute force).
constexpr double kPartRatio = 0.125;
constexpr int kMaxParts = 4;
constexpr double kFilledShare = 0.9;  // faces filling less of their rectangle are separate lamps (planTextures)
// wall_links: a receiver whose normal is this far from the source's (cosine below it) is steep: cut into bands
// of depth along the source's normal, from 1 up to kMaxBands (doubling) until every band passes.
constexpr double kSteep = 0.5;
constexpr int kMaxBands = 32;
// cluster_receivers: a cluster of faces in several planes is a receiver when it has at most this many faces
// (the self-shadow test looks at the pairs of its faces that a shaft to the source does not separate).
constexpr int kMaxClusterReceiverFaces = 256;


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

// The source's plane, with s along the first face's first edge and t = n x s, and the faces' bounding
// rectangle [s0, s1] x [t0, t1] in it.
struct SourceFrame {
    Vec3 o, e1, e2;
    double s0 = HUGE_VAL, s1 = -HUGE_VAL, t0 = HUGE_VAL, t1 = -HUGE_VAL;
    Vec3 at(double s, double t) const { return o + e1 * s + e2 * t; }
};

SourceFrame sourceFrame(const Scene& sc, const std::vector<int>& faces) {
    const ScenePolygon& f0 = sc.polygons[size_t(faces[0])];
    SourceFrame f;
    f.o = f0.geom.v[0];
    f.e1 = normalize(f0.geom.v[1] - f0.geom.v[0]);
    f.e2 = cross(f0.normal, f.e1);
    for (int p : faces) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k) {
            double u = dot(g.v[k] - f.o, f.e1), v = dot(g.v[k] - f.o, f.e2);
            f.s0 = std::min(f.s0, u); f.s1 = std::max(f.s1, u);
            f.t0 = std::min(f.t0, v); f.t1 = std::max(f.t1, v);
        }
    }
    return f;
}

// One part of the source: the rectangle [s0, s1] x [t0, t1] of the frame, the faces clipped to it, and the
// convolution's source polygon for it (the rectangle, with an emission image where the faces do not fill
// it evenly, zero between them).
struct SourcePart {
    SourceDesc desc;
    std::vector<SourcePiece> pieces;
};

SourcePart sourcePart(const Scene& sc, const std::vector<int>& faces, const SourceFrame& f, double s0, double s1,
                      double t0, double t1, int part, const SourceRadiosity& radiosity) {
    SourcePart out;
    Vec3 corners[4] = {f.at(s0, t0), f.at(s1, t0), f.at(s1, t1), f.at(s0, t1)};
    double rectArea = (s1 - s0) * (t1 - t0), covered = 0;
    bool uniform = true;
    for (size_t fi = 0; fi < faces.size(); ++fi) {
        const ScenePolygon& face = sc.polygons[size_t(faces[fi])];
        Polygon piece = face.geom;
        for (int k = 0; k < 4; ++k)
            piece = clipToHalfSpace(piece, corners[k], cross(face.normal, corners[(k + 1) % 4] - corners[k]));
        double a = piece.n >= 3 ? piece.area() : 0.0;
        if (!(a > 1e-9 * rectArea)) continue;
        covered += a;
        if (!out.pieces.empty()) {
            const ScenePolygon& first = sc.polygons[size_t(faces[size_t(out.pieces[0].face)])];
            uniform = uniform && first.emission.x == face.emission.x && first.emission.y == face.emission.y &&
                      first.emission.z == face.emission.z;
        }
        out.pieces.push_back({piece, int(fi), part});
    }
    out.desc.polygon.assign(corners, corners + 4);
    // A reflector's light varies over it with its own shadows and falloff: always an image (the paper's
    // source "rendered with all its radiosity textures", which keeps their correlation with visibility).
    if (radiosity) uniform = false;
    // The rectangle emits evenly: no image. Faces covering more than it overlap (a lamp doubled in place),
    // and the image then adds up their emission where they do; tiles meeting edge to edge may cover it a few
    // float32 roundings more and still need none.
    if (uniform && covered >= rectArea * (1 - 1e-9) && covered <= rectArea * (1 + 1e-4)) return out;
    // The image weights the part by emission; V is the emission-weighted visible fraction.
    EmissionImage& img = out.desc.emission;
    std::vector<double> pieceSum(out.pieces.size(), 0.0), pieceCount(out.pieces.size(), 0.0);
    img.width = img.height = kEmissionImage;
    img.texels.assign(size_t(kEmissionImage) * kEmissionImage, 0.0f);
    const int ss = 2;
    for (int row = 0; row < kEmissionImage; ++row)
        for (int col = 0; col < kEmissionImage; ++col) {
            double sum = 0;
            for (int a = 0; a < ss; ++a)
                for (int b = 0; b < ss; ++b) {
                    Vec3 p = f.at(s0 + (s1 - s0) * (col + (b + 0.5) / ss) / kEmissionImage,
                                  t0 + (t1 - t0) * (row + (a + 0.5) / ss) / kEmissionImage);
                    for (size_t k = 0; k < out.pieces.size(); ++k) {
                        const SourcePiece& pc = out.pieces[k];
                        const ScenePolygon& face = sc.polygons[size_t(faces[size_t(pc.face)])];
                        if (!insideConvex(pc.geom, face.normal, p)) continue;
                        double b = radiosity ? radiosity.at(faces[size_t(pc.face)], p) : maxComponent(face.emission);
                        sum += b;
                        pieceSum[k] += b;
                        pieceCount[k] += 1;
                    }
                }
            img.texels[size_t(row) * kEmissionImage + size_t(col)] = float(sum / (ss * ss));
        }
    // Each piece's share of its face's light: the gather multiplies the face's mean radiosity by it, so
    // a part over the bright middle of a lit ceiling sends more than one over its dim edge.
    for (size_t k = 0; radiosity && k < out.pieces.size(); ++k) {
        double mean = radiosity.mean(faces[size_t(out.pieces[k].face)]);
        if (pieceCount[k] > 0 && mean > 0) out.pieces[k].weight = pieceSum[k] / pieceCount[k] / mean;
    }
    return out;
}

}  // namespace

ConvolutionSites::ConvolutionSites(const Hierarchy& h, const RayCaster& rays, const Settings& s, Counters& counters)
    : h_(h), rays_(rays), settings_(s), counters_(counters) {
    const Scene& sc = h.scene();
    tol_ = 1e-3 * sc.diagonal;
    // Lying in a plane is a matter of float32 rounding of the caller's coordinates (a few ulps of the
    // largest, large for a scene far from the origin), not of tol_: a tile 0.1 mm under a lamp blocks it.
    planeTol_ = 1e-6 * sc.diagonal + float32Rounding(sc);
    const ClusterTree& ct = h.clusters();
    planar_.assign(ct.size(), 0);
    hasSource_.assign(ct.size(), 0);
    sourceGroup_.assign(ct.size(), 0);
    for (size_t c = 0; c < ct.size(); ++c) {
        const Cluster& cl = ct[int(c)];
        const ScenePolygon& first = sc.polygons[size_t(ct.polygons()[size_t(cl.begin)])];
        bool planar = true, group = true, source = false;
        const ScenePolygon* firstSender = nullptr;
        for (int k = cl.begin; k < cl.end; ++k) {
            const ScenePolygon& p = sc.polygons[size_t(ct.polygons()[size_t(k)])];
            planar = planar && samePlane(first, p, planeTol_);
            source = source || sourceFace(p);
            if (!sendsLight(p)) continue;
            if (!sourceFace(p)) group = false;
            if (!firstSender) firstSender = &p;
            else group = group && samePlane(*firstSender, p, planeTol_);
        }
        planar_[c] = planar;
        hasSource_[c] = source;
        sourceGroup_[c] = group && source;
    }
}

bool ConvolutionSites::receiverCandidate(int r) const {
    const Scene& sc = h_.scene();
    Bounds b;
    if (isClusterNode(r)) {
        const Cluster& c = h_.clusters()[clusterIndex(r)];
        const bool grouped = settings_.clusterReceivers && c.end - c.begin <= kMaxClusterReceiverFaces;
        if (!(planar_[size_t(clusterIndex(r))] || grouped) || !(c.rhoMax > 0)) return false;
        b = c.box;
    } else {
        if (size_t(r) >= h_.numRoots()) return false;  // receivers are whole polygons or clusters
        const ScenePolygon& p = sc.polygons[size_t(r)];
        if (!receivesLight(p)) return false;
        b = nodeBox(h_, r);
    }
    return length(b.diagonal()) >= settings_.aMin * sc.diagonal;
}

bool ConvolutionSites::sourceFace(const ScenePolygon& p) const {
    return settings_.indirectSources ? sendsLight(p) : emits(p);
}

bool ConvolutionSites::sourceCandidate(int s) const {
    if (isClusterNode(s)) return hasSource_[size_t(clusterIndex(s))];
    return size_t(s) < h_.numRoots() && sourceFace(h_.scene().polygons[size_t(s)]);
}

void ConvolutionSites::beginPass(size_t settled, const std::vector<ConvolutionLink>& conv, std::vector<Rgb> reflected) {
    {
        std::lock_guard<std::mutex> lock(refusedMutex_);
        refused_.clear();
    }
    settled_ = settled;
    field_ = conv.empty() ? ConvolutionField{} : ConvolutionField(h_, conv);
    reflected_ = std::move(reflected);
}

SourceRadiosity ConvolutionSites::sourceRadiosity(bool reflects) const {
    if (!reflects) return {};
    return {[this](int polygon, const Vec3& p) { return radiosityAt(polygon, p); },
            [this](int polygon) { return maxComponent(h_[size_t(polygon)].B); }};
}

double ConvolutionSites::radiosityAt(int polygon, const Vec3& p) const {
    const ScenePolygon& sp = h_.scene().polygons[size_t(polygon)];
    // Down the quadtree to the settled leaf holding p (the child p lies deepest inside, so a point on
    // a shared edge still picks one). Elements split during this pass carry their parent's radiosity.
    int e = polygon;
    for (int fc = h_.firstChild(e); fc >= 0 && size_t(fc) < settled_; fc = h_.firstChild(e)) {
        const int children = h_[size_t(e)].numChildren;
        int best = fc;
        double bestInside = -HUGE_VAL;
        for (int k = 0; k < children; ++k) {
            const Element& c = h_[size_t(fc + k)];
            double inside = HUGE_VAL;
            for (int i = 0; i < c.n; ++i) {
                Vec3 edge = c.v[size_t((i + 1) % c.n)] - c.v[size_t(i)];
                double len = length(edge);
                if (len > 0) inside = std::min(inside, dot(cross(sp.normal, edge), p - c.v[size_t(i)]) / len);
            }
            if (inside > bestInside) {
                bestInside = inside;
                best = fc + k;
            }
        }
        e = best;
    }
    Rgb B = h_[size_t(e)].B;
    // A face lit through convolution links holds only their mean over each leaf; the texture's detail is
    // the display's (leaf radiosity less that mean, plus the links' light at p).
    int group = 0;
    Rgb detail = field_.empty() ? Rgb{} : field_.radiance(p, sp.normal, &group) * M_PI;
    if (group != 0 && size_t(e) < reflected_.size()) B = B - reflected_[size_t(e)] + detail;
    return std::max(0.0, maxComponent(B));
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

bool ConvolutionSites::tryLink(int r, int s, ConvolutionLink& out) { return evaluate(r, s, &out) == Refusal::None; }

bool ConvolutionSites::wouldLink(int r, int s) { return evaluate(r, s, nullptr) == Refusal::None; }

bool ConvolutionSites::linkPossibleBelow(int r, int s, const std::function<bool(int)>& significant) {
    // The largest emitter groups below s: clusters whose senders all emit on one plane, and emitting
    // faces hanging from clusters that are not such groups.
    std::vector<int> stack{s};
    while (!stack.empty()) {
        int n = stack.back();
        stack.pop_back();
        if (!isClusterNode(n) || sourceGroup_[size_t(clusterIndex(n))]) {
            if (!sourceCandidate(n) || !significant(n)) continue;
            Refusal why = evaluate(r, n, nullptr);
            if (why == Refusal::None) return true;
            if (why != Refusal::TooWide || !isClusterNode(n)) continue;  // lamps too far apart: try each
        }
        const ClusterTree& ct = h_.clusters();
        const Cluster& c = ct[clusterIndex(n)];
        if (!hasSource_[size_t(clusterIndex(n))]) continue;
        for (int k = 0; k < c.numChildren; ++k) stack.push_back(clusterNode(c.firstChild + k));
        for (int k = c.begin; k < c.ownEnd; ++k) stack.push_back(ct.polygons()[size_t(k)]);
    }
    return false;
}

// A pair on its way through evaluate(): each step fills in what the next one needs.
struct ConvolutionSites::Site {
    int r = -1, s = -1;
    std::vector<int> rpolys;     // the receiver's polygons, sorted
    std::vector<int> faces;      // the source: the sending faces of s turned toward the receiver
    bool reflects = false;       // some of them do not emit (indirect_sources): bounced light
    Bounds rb, fb;               // boxes of the receiver and of the source faces
    const ScenePolygon* rplane = nullptr;  // the receiver's plane; null for a cluster receiver that is not flat
    std::vector<int> lit;        // not flat: the receiving faces with the whole source in front of them
    // The faces the textures are planned over and handed to: a flat receiver's all, a cluster's lit ones.
    const std::vector<int>& receivers() const { return rplane ? rpolys : lit; }
    const ScenePolygon* splane = nullptr;
    std::vector<BlockerTriangle> tris;
    std::vector<SourcePart> parts;
    std::vector<ConvolutionPlan> plans;
    std::vector<ConvolutionSettings> partSettings;
    double judged = 0;  // E_rr in the texels of half the narrowest penumbra
    // wall_links: the receiver is steep to the source (steep), and reaches above its plane (straddles);
    // a banded plan holds plans[band * parts.size() + part] (empty slices: the band is in full light) and
    // each band's clipped blockers.
    bool steep = false, straddles = false;
    std::vector<double> bandDepths;
    std::vector<std::vector<BlockerTriangle>> bandTris;
    std::vector<std::pair<double, double>> bandSpans;
    Vec3 bandOrigin, bandAxis, bandAcross;
};

namespace {

CounterId counterOf(ConvolutionSites::Refusal why) {
    switch (why) {
    case ConvolutionSites::Refusal::NoBlocker: return kNoBlocker;
    case ConvolutionSites::Refusal::Intruder: return kIntruder;
    case ConvolutionSites::Refusal::TooCoarse:
    case ConvolutionSites::Refusal::TooWide: return kTooCoarse;
    case ConvolutionSites::Refusal::TooSlow: return kTooSlow;
    case ConvolutionSites::Refusal::SelfShadow: return kSelfShadow;
    default: return kInvalid;
    }
}

}  // namespace

// The pair's tests, each refused pair judged once: the 100k office's refiner asked 1,456 times about 879 pairs, and
// planned 627 textures for 372 of them at 6.6 ms a plan, none passing (4.1 s of CPU; 2.3 s judged once). Without
// `out` it only asks whether a link would pass every test: nothing is counted or computed.
ConvolutionSites::Refusal ConvolutionSites::evaluate(int r, int s, ConvolutionLink* out) {
    const PairKey key{isClusterNode(r), nodeKey(h_, r), isClusterNode(s), nodeKey(h_, s)};
    Refusal why = Refusal::None;
    bool judged = false;
    {
        std::lock_guard<std::mutex> lock(refusedMutex_);
        auto it = refused_.find(key);
        if (it != refused_.end()) {
            why = it->second;
            judged = true;
        }
    }
    Site site;
    if (!judged) {
        why = judge(r, s, site);
        if (why != Refusal::None) {
            std::lock_guard<std::mutex> lock(refusedMutex_);
            refused_.emplace(key, why);
        }
    }
    // A pair that passes the tests is never in refused_: judged now, its site holds what the textures need.
    // A texture that fails to compute refuses the link but is not kept: asked without `out`, the tests answer.
    if (why == Refusal::None && out) why = computeTextures(site, *out);
    // Counted alike whether judged now or before: the report's counts do not depend on what was asked first.
    if (why != Refusal::NotASite && out) {
        counters_.add(kTried);
        if (why != Refusal::None) counters_.add(counterOf(why));
    }
    return why;
}

// Like Embree's Scene::commit_internal handing each geometry type to its builder, judge() runs the
// tests of the file's head as steps, each returning why it refuses (Refusal::None: go on), and fills `site`.
ConvolutionSites::Refusal ConvolutionSites::judge(int r, int s, Site& site) const {
    if (selectSource(r, s, site) != Refusal::None) return Refusal::NotASite;  // not counted
    Refusal why = selectBlockers(site);
    if (why == Refusal::None) {
        // A wall under a ceiling lamp: no frame orders source, blocker and whole receiver in depth (Invalid), or
        // one does but the wall's depth range is too wide for one kernel per slab (TooCoarse), or the wall
        // reaches above the lamp's plane; cut into bands below the lamp instead (wall_links).
        why = site.straddles ? Refusal::Invalid : planTextures(site);
        if ((why == Refusal::Invalid || why == Refusal::TooCoarse) && site.steep) {
            site.parts.clear();
            site.plans.clear();
            site.partSettings.clear();
            why = planBands(site);
        }
    }
    if (why == Refusal::None) why = withinTimeBudget(site);
    return why;
}

// Test 2: r a planar receiver, s an emitter group; the faces of s turned toward r are the source, and
// every other sending face of s must not see r at all.
ConvolutionSites::Refusal ConvolutionSites::selectSource(int r, int s, Site& site) const {
    if (r == s || !receiverCandidate(r)) return Refusal::NotASite;
    if (isClusterNode(s) ? !sourceGroup_[size_t(clusterIndex(s))] : !sourceCandidate(s)) return Refusal::NotASite;
    const Scene& sc = h_.scene();
    std::vector<int> spolys;
    site.r = r;
    site.s = s;
    nodePolygons(r, site.rpolys);
    nodePolygons(s, spolys);
    site.rb = nodeBox(h_, r);
    const ScenePolygon& rfirst = sc.polygons[size_t(site.rpolys[0])];
    const bool flat = !isClusterNode(r) || planar_[size_t(clusterIndex(r))];
    for (int p : spolys) {
        const ScenePolygon& sp = sc.polygons[size_t(p)];
        if (!sendsLight(sp)) continue;
        bool steep = flat && settings_.wallLinks && std::fabs(dot(sp.normal, rfirst.normal)) < kSteep;
        site.steep = site.steep || steep;
        int side = sideOf(sp, site.rb, tol_);
        // A steep receiver reaching above the lamp's plane takes bands below it (planBands): the lamp does not
        // light the part above, and the link's form factors are zero there.
        if (side == 0 && steep) site.straddles = true;
        else if (side == 0) return Refusal::NotASite;
        if (side >= 0) site.faces.push_back(p);
    }
    if (site.faces.empty()) return Refusal::NotASite;
    for (int p : site.faces) site.reflects = site.reflects || !emits(sc.polygons[size_t(p)]);
    for (int p : site.faces) site.fb.extend(polygonBox(sc.polygons[size_t(p)]));
    site.splane = &sc.polygons[size_t(site.faces[0])];
    if (!flat) {
        // Each receiving face has the whole source in front of it (lit through the textures at its own position
        // and normal) or behind it (unlit); one the source's plane of light cuts would need the texture's
        // visibility where its own horizon clips the source, which the convolution does not weigh.
        for (int p : site.rpolys) {
            const ScenePolygon& q = sc.polygons[size_t(p)];
            if (!receivesLight(q)) continue;
            int side = sideOf(q, site.fb, tol_);
            if (side == 0) return Refusal::NotASite;
            if (side > 0) site.lit.push_back(p);
        }
        return site.lit.empty() ? Refusal::NotASite : Refusal::None;
    }
    site.rplane = &rfirst;
    // The source must be wholly in front of the receiver.
    if (sideOf(*site.rplane, site.fb, tol_) <= 0) return Refusal::NotASite;
    return Refusal::None;
}

// Test 3, blocker selection (§5.2): occluders whose boxes cross the shaft between source and receiver.
ConvolutionSites::Refusal ConvolutionSites::selectBlockers(Site& site) const {
    const Scene& sc = h_.scene();
    // A light whose Cast Shadow is off has nothing to convolve (kCastsNoShadow).
    for (int p : site.faces)
        if (!sc.polygons[size_t(p)].castsShadow) return Refusal::NoBlocker;
    Shaft shaft(site.rb, site.fb);
    // A receiver that is not flat has no plane to stand behind; along the source's normal every segment from
    // the source to a lit face stays above the deepest lit point, so what lies wholly below it (the floor
    // under a cluster standing on it) cannot cut one.
    double deepest = -HUGE_VAL;
    for (int p : site.lit) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k)
            deepest = std::max(deepest, dot(g.v[k] - site.splane->geom.v[0], site.splane->normal));
    }
    auto below = [&](const ScenePolygon& q) {
        for (int k = 0; k < q.geom.n; ++k)
            if (dot(q.geom.v[k] - site.splane->geom.v[0], site.splane->normal) < deepest - planeTol_) return false;
        return true;
    };
    std::vector<int> candidates = rays_.occludersInShaft(shaft);
    std::sort(candidates.begin(), candidates.end());
    for (int q : candidates) {
        // The receiver's faces all lie in its plane; of the source's node only the emitting faces are
        // skipped: anything else in it (a lamp's housing) may block, and overlapping the source's box it
        // then refuses the link.
        if (std::binary_search(site.rpolys.begin(), site.rpolys.end(), q) ||
            std::binary_search(site.faces.begin(), site.faces.end(), q))
            continue;
        const ScenePolygon& qp = sc.polygons[size_t(q)];
        // Hidden from shadow rays (kNoLampShadow): the emitter's light passes it, as the final gather's
        // rays do where no texture is made, so it casts no shadow into the texture either.
        // Bounced light is blocked where diffuse rays are (kNoDiffuse lets them through).
        if (!(site.reflects ? qp.diffuseVisible : qp.blocksLamps)) continue;
        Bounds qb = shrunk(polygonBox(qp), tol_);
        if (shaft.classify(qb) == Shaft::Outside) continue;
        // In the source's or the receiver's plane, or behind it: cannot cut a segment between them.
        if (onOrBehind(*site.splane, qp, planeTol_) ||
            (site.rplane ? onOrBehind(*site.rplane, qp, planeTol_) : below(qp)))
            continue;
        if (overlaps(qb, site.rb) || overlaps(qb, site.fb)) return Refusal::Intruder;
        const Polygon& g = qp.geom;
        for (int k = 1; k + 1 < g.n; ++k) site.tris.push_back({g.v[0], g.v[k], g.v[k + 1]});
    }
    if (site.tris.empty()) return Refusal::NoBlocker;
    return !site.rplane && shadowsItself(site) ? Refusal::SelfShadow : Refusal::None;
}

namespace {

// Andrew's monotone chain: the convex hull of `p`, counter-clockwise, collinear points dropped.
std::vector<std::pair<double, double>> hull2(std::vector<std::pair<double, double>> p) {
    std::sort(p.begin(), p.end());
    p.erase(std::unique(p.begin(), p.end()), p.end());
    if (p.size() < 3) return p;
    auto turn = [](const std::pair<double, double>& o, const std::pair<double, double>& a,
                   const std::pair<double, double>& b) {
        return (a.first - o.first) * (b.second - o.second) - (a.second - o.second) * (b.first - o.first);
    };
    std::vector<std::pair<double, double>> h(2 * p.size());
    size_t k = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        while (k >= 2 && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    for (size_t i = p.size() - 1, lo = k + 1; i-- > 0;) {
        while (k >= lo && turn(h[k - 2], h[k - 1], p[i]) <= 0) --k;
        h[k++] = p[i];
    }
    h.resize(k - 1);
    return h;
}

// Whether two convex polygons of the plane overlap by more than `tol` along every edge normal of either
// (separating axes): touching along an edge or at a point is not overlapping.
bool overlap2(const std::vector<std::pair<double, double>>& a, const std::vector<std::pair<double, double>>& b,
              double tol) {
    for (const auto* poly : {&a, &b}) {
        const size_t n = poly->size();
        for (size_t i = 0; i < n && n >= 2; ++i) {
            const auto& p = (*poly)[i];
            const auto& q = (*poly)[(i + 1) % n];
            double ax = q.second - p.second, ay = p.first - q.first, len = std::hypot(ax, ay);
            if (!(len > 0)) continue;
            ax /= len;
            ay /= len;
            auto extent = [&](const std::vector<std::pair<double, double>>& poly2, double& lo, double& hi) {
                lo = HUGE_VAL;
                hi = -HUGE_VAL;
                for (const auto& v : poly2) {
                    const double x = v.first * ax + v.second * ay;
                    lo = std::min(lo, x);
                    hi = std::max(hi, x);
                }
            };
            double alo, ahi, blo, bhi;
            extent(a, alo, ahi);
            extent(b, blo, bhi);
            if (ahi < blo + tol || bhi < alo + tol) return false;
        }
    }
    return a.size() >= 3 && b.size() >= 3;
}

}  // namespace

// Test 3 for a cluster receiver that is not flat (cluster_receivers). The texture holds the blockers outside
// the receiver only, so a face of the cluster shading another from the source (a monitor on its desk, a table
// top over its legs) would leak the light it stops: the paper ignores such shadows (§4.1), here they refuse
// the link and the refiner opens the cluster, whose parts then take links of their own (the paper's advice,
// §7). Exact, not sampled: a face g of the cluster shades the lit face f where it reaches into the hull of f and
// the source's rectangle (every segment from one to the other) strictly in front of f. The hull's section by
// g's plane is the hull of where the segments between the hull's corners cross that plane; g, clipped to the
// front of f, is tested against it by separating axes in the plane. A neighbour sharing an edge with f and
// bending away from the source (a dome's next triangle) lies behind f's plane; one bending toward it (a trough's)
// enters the hull only where it rises more steeply than the rays to the source, which is exactly when it shades.
bool ConvolutionSites::shadowsItself(const Site& site) const {
    const Scene& sc = h_.scene();
    const SourceFrame frame = sourceFrame(sc, site.faces);
    const Vec3 lamp[4] = {frame.at(frame.s0, frame.t0), frame.at(frame.s1, frame.t0), frame.at(frame.s1, frame.t1),
                          frame.at(frame.s0, frame.t1)};
    std::vector<Vec3> corners;
    std::vector<std::pair<double, double>> section, face;
    for (int f : site.lit) {
        const ScenePolygon& fp = sc.polygons[size_t(f)];
        const Shaft shaft(polygonBox(fp), site.fb);
        corners.assign(lamp, lamp + 4);
        for (int k = 0; k < fp.geom.n; ++k) corners.push_back(fp.geom.v[k]);
        for (int q : site.rpolys) {
            const ScenePolygon& qp = sc.polygons[size_t(q)];
            if (q == f || !(site.reflects ? qp.diffuseVisible : qp.blocksLamps)) continue;
            if (shaft.classify(polygonBox(qp)) == Shaft::Outside) continue;
            const Polygon g = clipToHalfSpace(qp.geom, fp.geom.v[0] + fp.normal * planeTol_, fp.normal);
            if (g.n < 3) continue;
            // A basis of g's plane from its normal alone: clipping may leave coincident corners.
            const Vec3 n = qp.normal, o = g.v[0];
            const Vec3 e1 = normalize(std::fabs(n.x) < 0.6 ? cross(n, Vec3{1, 0, 0}) : cross(n, Vec3{0, 1, 0}));
            const Vec3 e2 = cross(n, e1);
            auto in2 = [&](const Vec3& p) { return std::make_pair(dot(p - o, e1), dot(p - o, e2)); };
            section.clear();
            for (size_t a = 0; a < corners.size(); ++a) {
                const double da = dot(corners[a] - o, n);
                if (std::fabs(da) <= planeTol_) section.push_back(in2(corners[a]));
                for (size_t b = a + 1; b < corners.size(); ++b) {
                    const double db = dot(corners[b] - o, n);
                    if ((da > planeTol_ && db < -planeTol_) || (da < -planeTol_ && db > planeTol_))
                        section.push_back(in2(corners[a] + (corners[b] - corners[a]) * (da / (da - db))));
                }
            }
            if (section.size() < 3) continue;
            face.clear();
            for (int k = 0; k < g.n; ++k) face.push_back(in2(g.v[k]));
            if (overlap2(hull2(section), hull2(face), planeTol_)) return true;
        }
    }
    return false;
}

// Test 4: the blocker error E_rr of the whole source within e_max; then the plans of its parts.
ConvolutionSites::Refusal ConvolutionSites::planTextures(Site& site) const {
    const Scene& sc = h_.scene();
    const std::vector<int>& faces = site.faces;
    const Bounds& rb = site.rb;
    SourceFrame frame = sourceFrame(sc, faces);
    SourceDesc whole;
    whole.polygon = {frame.at(frame.s0, frame.t0), frame.at(frame.s1, frame.t0), frame.at(frame.s1, frame.t1),
                     frame.at(frame.s0, frame.t1)};
    ReceiverDesc rec;
    for (int p : site.receivers()) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k) rec.points.push_back(g.v[k]);
    }
    // E_rr is judged for the whole source at the resolution the brief derives from the narrowest penumbra
    // (texels of half its width), so e_max means the same whatever the display needs. That resolution puts
    // two texels across a penumbra, and bilinear lookups then miss a penumbra's corner by 6 % of the light
    // (parallel planes, measured): the textures are made kDisplayFactor times finer, at least kMinTexture
    // texels a side.
    ConvolutionSettings cs;
    cs.e_max = settings_.eMax;
    cs.contactSlabs = settings_.contactSlabs;
    cs.maxResolution = settings_.maxTexture;
    cs.minResolution = std::min(16, settings_.maxTexture);
    // Parts no larger than kPartRatio of the source's distance to the receiver (V weights by area, not by
    // the kernel), at most kMaxParts a side.
    double dist = HUGE_VAL;
    for (int i = 0; i < 8; ++i) {
        Vec3 c{(i & 1) ? rb.hi.x : rb.lo.x, (i & 2) ? rb.hi.y : rb.lo.y, (i & 4) ? rb.hi.z : rb.lo.z};
        dist = std::min(dist, dot(c - site.splane->geom.v[0], site.splane->normal));
    }
    double side = std::max(frame.s1 - frame.s0, frame.t1 - frame.t0);
    int needed = std::max(1, int(std::ceil(side / (kPartRatio * std::max(dist, 1e-300)) - 1e-9)));
    int k = std::min(needed, kMaxParts);
    // Separate lamps (their faces fill less than kFilledShare of the rectangle) that would need more parts
    // than kMaxParts: the parts would be too large for the area weighting (two 0.5 m lamps 1 m apart, 2 m up:
    // worst 3.0 % of the peak as one source, 2.2 % as a link per lamp), so each lamp takes its own link.
    // A lamp modelled in several faces fills its rectangle and is clamped to kMaxParts as before.
    if (needed > kMaxParts && faces.size() > 1) {
        double filled = 0;
        for (int p : faces) filled += sc.polygons[size_t(p)].area;
        if (filled < kFilledShare * (frame.s1 - frame.s0) * (frame.t1 - frame.t0)) return Refusal::TooWide;
    }
    try {
        ConvolutionPlan plan = planSoftShadow(whole, site.tris, rec, cs);
        if (plan.slices.empty()) return Refusal::NoBlocker;
        site.judged = plan.E_rr;
        if (site.judged > settings_.eMax) return Refusal::TooCoarse;
        // E_rr counts texels of the plan's size, which max_texture may have made coarser than half the
        // narrowest penumbra: a 200 m floor in 512 texels has 0.4 m texels, and a 0.2 m blocker's umbra
        // under a small lamp vanished into one of them (lit at 0.068 where the exact answer is 0). Such a
        // texture cannot show the shadow; the standard refiner can, down to the receiver's min_edge. A
        // contact slab has no narrowest penumbra (zero at the contact), so it keeps its texture.
        if (!plan.contact && std::isfinite(plan.alpha_min) && plan.alpha_min * plan.L_S / 2 < plan.p * (1 - 1e-9))
            return Refusal::TooCoarse;
        ConvolutionSettings fine = cs;
        fine.resolution = std::clamp(plan.n * kDisplayFactor, std::min(kMinTexture, settings_.maxTexture),
                                     settings_.maxTexture);
        fine.e_max = cs.e_max * double(fine.resolution) / plan.n;
        for (int a = 0; a < k; ++a)
            for (int b = 0; b < k; ++b) {
                double ds = (frame.s1 - frame.s0) / k, dt = (frame.t1 - frame.t0) / k;
                SourcePart part = sourcePart(sc, faces, frame, frame.s0 + ds * b, frame.s0 + ds * (b + 1),
                                             frame.t0 + dt * a, frame.t0 + dt * (a + 1), int(site.parts.size()),
                                             sourceRadiosity(site.reflects));
                if (part.pieces.empty()) continue;
                site.plans.push_back(planSoftShadow(part.desc, site.tris, rec, fine));
                site.partSettings.push_back(fine);
                site.parts.push_back(std::move(part));
            }
    } catch (const std::domain_error&) {
        return Refusal::Invalid;
    } catch (const std::invalid_argument&) {
        return Refusal::Invalid;
    }
    return site.parts.empty() ? Refusal::Invalid : Refusal::None;
}

// Test 4 for a receiver steep to its source (wall_links): a wall under a ceiling lamp. Along the lamp's normal the
// lamp is flat (no source depth spread, no shear), and a receiver point at depth z_y is shadowed only by blocker
// points shallower than z_y, each with the exact penumbra scale z_r (1/z_b - 1/z_y) of a blocker plane parallel
// to the lamp. What breaks the depth order is the wall's own depth range, which holds the blockers'. So the
// receiver is cut into B bands of equal inverse depth below the top of the blockers (above it the whole lamp is
// seen), and band [z_a, z_b] is convolved with the blockers clipped at z_a. The parts dropped, between z_a and
// z_b, are exact to leave out when they stand further from the receiver's plane than any segment from the lamp to
// the band can be at their depth (d_max (z_b - z_a) / z_b, d_max the lamp's greatest distance from that plane);
// else (a bookcase against the wall) the band is refused. Each band's plan must pass e_max with whole-triangle
// slabs (no contact sub-blockers: a face cut at a slab boundary leaves a seam whose error E_rr does not see, and
// a tall face toward the lamp is exactly what a wall's blockers have). B doubles up to kMaxBands.
ConvolutionSites::Refusal ConvolutionSites::planBands(Site& site) const {
    const Scene& sc = h_.scene();
    const ScenePolygon& sp = *site.splane;
    const ScenePolygon& rp = *site.rplane;
    const Vec3 axis = sp.normal, org = sp.geom.v[0];
    auto depth = [&](const Vec3& p) { return dot(p - org, axis); };
    const Vec3 across = normalize(cross(axis, rp.normal));  // along the receiver at one depth (it is steep)
    double zTop = HUGE_VAL, zEnd = -HUGE_VAL, dMax = 0;
    for (const BlockerTriangle& t : site.tris)
        for (const Vec3& v : t) zTop = std::min(zTop, depth(v));
    for (int p : site.rpolys) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k) zEnd = std::max(zEnd, depth(g.v[k]));
    }
    for (int p : site.faces) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        for (int k = 0; k < g.n; ++k) dMax = std::max(dMax, dot(g.v[k] - rp.geom.v[0], rp.normal));
    }
    std::vector<Vec3> lampCorners;
    for (int p : site.faces) {
        const Polygon& g = sc.polygons[size_t(p)].geom;
        lampCorners.insert(lampCorners.end(), g.v.begin(), g.v.begin() + g.n);
    }
    if (!(zTop > planeTol_)) return Refusal::Invalid;  // a blocker reaching the lamp's plane
    if (!(zEnd > zTop)) return Refusal::NoBlocker;     // the receiver is above every blocker

    SourceFrame frame = sourceFrame(sc, site.faces);
    SourceDesc whole;
    whole.polygon = {frame.at(frame.s0, frame.t0), frame.at(frame.s1, frame.t0), frame.at(frame.s1, frame.t1),
                     frame.at(frame.s0, frame.t1)};
    ConvolutionSettings cs;
    cs.e_max = settings_.eMax;
    cs.contactSlabs = false;
    cs.direction = DirectionChoice::SourceNormal;
    cs.maxResolution = settings_.maxTexture;
    cs.minResolution = std::min(16, settings_.maxTexture);
    auto clipped = [&](const Polygon& g, double zlo, double zhi) {
        Polygon c = clipToHalfSpace(g, org + axis * zlo, axis);
        return clipToHalfSpace(c, org + axis * zhi, axis * -1.0);
    };
    auto asPolygon = [](const BlockerTriangle& t) {
        Polygon g;
        for (const Vec3& v : t) g.push(v);
        return g;
    };
    Refusal why = Refusal::TooCoarse;
    for (int B = 1; B <= kMaxBands; B *= 2) {
        std::vector<double> z(size_t(B) + 1);
        for (int i = 0; i <= B; ++i) z[size_t(i)] = 1.0 / (1.0 / zTop - (1.0 / zTop - 1.0 / zEnd) * i / B);
        z[size_t(B)] = zEnd;
        auto tris = std::vector<std::vector<BlockerTriangle>>(size_t(B));
        auto recs = std::vector<ReceiverDesc>(size_t(B));
        auto judged = std::vector<ConvolutionPlan>(size_t(B));
        auto spans = std::vector<std::pair<double, double>>(size_t(B), {-HUGE_VAL, HUGE_VAL});
        double worst = 0;
        bool ok = true;
        for (int b = 0; b < B && ok; ++b) {
            const double za = z[size_t(b)], zb = z[size_t(b) + 1];
            for (int p : site.rpolys) {
                Polygon c = clipped(sc.polygons[size_t(p)].geom, za, zb);
                for (int k = 0; k < c.n; ++k) recs[size_t(b)].points.push_back(c.v[k]);
            }
            const double reach = dMax * (zb - za) / zb;
            for (const BlockerTriangle& t : site.tris) {
                Polygon g = asPolygon(t);
                Polygon dropped = clipped(g, za, zb);
                for (int k = 0; k < dropped.n && ok; ++k)
                    if (dot(dropped.v[k] - rp.geom.v[0], rp.normal) < reach) ok = false;
                Polygon kept = clipToHalfSpace(g, org + axis * za, axis * -1.0);
                for (int k = 1; k + 1 < kept.n; ++k)
                    if (length(cross(kept.v[k] - kept.v[0], kept.v[k + 1] - kept.v[0])) > 0)
                        tris[size_t(b)].push_back({kept.v[0], kept.v[k], kept.v[k + 1]});
            }
            if (!ok) {
                why = Refusal::Invalid;  // a blocker within reach of the band: thinner bands may clear it
                break;
            }
            // Full light when no shadow reaches the band: the shadow lies in the convex hull of the blocker vertices
            // projected from the lamp's vertices onto the receiver's plane (a projection from a point, and one of
            // the lamp's plane through a point, keep convex sets convex), so in its depth range.
            // Its extent across (along the receiver at one depth) bounds the band's texture too: outside it the
            // link reads full light, and the window holds only the part a shadow can reach.
            double sLo = HUGE_VAL, sHi = -HUGE_VAL, aLo = HUGE_VAL, aHi = -HUGE_VAL;
            for (const BlockerTriangle& t : tris[size_t(b)])
                for (const Vec3& v : t) {
                    const double dv = dot(v - rp.geom.v[0], rp.normal);
                    for (const Vec3& x : lampCorners) {
                        const double dx = dot(x - rp.geom.v[0], rp.normal);
                        if (!(dv < dx)) {
                            sLo = aLo = -HUGE_VAL;
                            sHi = aHi = HUGE_VAL;
                            continue;
                        }
                        const Vec3 q = x + (v - x) * (dx / (dx - dv));
                        sLo = std::min(sLo, depth(q));
                        sHi = std::max(sHi, depth(q));
                        aLo = std::min(aLo, dot(q - org, across));
                        aHi = std::max(aHi, dot(q - org, across));
                    }
                }
            if (sHi < za || sLo > zb) tris[size_t(b)].clear();
            spans[size_t(b)] = {aLo - tol_, aHi + tol_};
            if (std::isfinite(aLo) && std::isfinite(aHi) && !tris[size_t(b)].empty()) {
                recs[size_t(b)].points.clear();
                for (int p : site.rpolys) {
                    Polygon c = clipped(sc.polygons[size_t(p)].geom, za, zb);
                    c = clipToHalfSpace(c, org + across * spans[size_t(b)].first, across);
                    c = clipToHalfSpace(c, org + across * spans[size_t(b)].second, across * -1.0);
                    for (int k = 0; k < c.n; ++k) recs[size_t(b)].points.push_back(c.v[k]);
                }
            }
            if (recs[size_t(b)].points.size() < 3 || tris[size_t(b)].empty()) continue;  // full light
            try {
                judged[size_t(b)] = planSoftShadow(whole, tris[size_t(b)], recs[size_t(b)], cs);
            } catch (const std::domain_error&) {
                why = Refusal::Invalid;
                ok = false;
                break;
            } catch (const std::invalid_argument&) {
                why = Refusal::Invalid;
                ok = false;
                break;
            }
            const ConvolutionPlan& plan = judged[size_t(b)];
            worst = std::max(worst, plan.E_rr);
            // E_rr within e_max. Not planTextures' test of the texel against the narrowest penumbra: a band just
            // below a blocker always has a nearly sharp one by depth (alpha_min -> 0), while the blocker's shadow
            // falls far lower on the wall; the textures are made at max_texture there anyway.
            if (plan.E_rr > settings_.eMax) {
                why = Refusal::TooCoarse;
                ok = false;
            }
        }
        if (!ok) continue;
        // Parts as planTextures, their distance the top of the bands: above it every part is seen whole.
        double side = std::max(frame.s1 - frame.s0, frame.t1 - frame.t0);
        int needed = std::max(1, int(std::ceil(side / (kPartRatio * zTop) - 1e-9)));
        int k = std::min(needed, kMaxParts);
        if (needed > kMaxParts && site.faces.size() > 1) {
            double filled = 0;
            for (int p : site.faces) filled += sc.polygons[size_t(p)].area;
            if (filled < kFilledShare * (frame.s1 - frame.s0) * (frame.t1 - frame.t0)) return Refusal::TooWide;
        }
        for (int a = 0; a < k; ++a)
            for (int c = 0; c < k; ++c) {
                double ds = (frame.s1 - frame.s0) / k, dt = (frame.t1 - frame.t0) / k;
                SourcePart part = sourcePart(sc, site.faces, frame, frame.s0 + ds * c, frame.s0 + ds * (c + 1),
                                             frame.t0 + dt * a, frame.t0 + dt * (a + 1), int(site.parts.size()),
                                             sourceRadiosity(site.reflects));
                if (!part.pieces.empty()) site.parts.push_back(std::move(part));
            }
        if (site.parts.empty()) return Refusal::Invalid;
        try {
            for (int b = 0; b < B; ++b) {
                const ConvolutionPlan& plan = judged[size_t(b)];
                for (const SourcePart& part : site.parts) {
                    ConvolutionSettings fine = cs;
                    if (plan.slices.empty()) {
                        site.plans.emplace_back();
                    } else {
                        fine.resolution = std::clamp(plan.n * kDisplayFactor, std::min(kMinTexture, settings_.maxTexture),
                                                     settings_.maxTexture);
                        fine.e_max = cs.e_max * double(fine.resolution) / plan.n;
                        site.plans.push_back(planSoftShadow(part.desc, tris[size_t(b)], recs[size_t(b)], fine));
                    }
                    site.partSettings.push_back(fine);
                }
            }
        } catch (const std::domain_error&) {
            return Refusal::Invalid;
        } catch (const std::invalid_argument&) {
            return Refusal::Invalid;
        }
        site.judged = worst;
        site.bandDepths = std::move(z);
        site.bandTris = std::move(tris);
        site.bandSpans = std::move(spans);
        site.bandAcross = across;
        site.bandOrigin = org;
        site.bandAxis = axis;
        return Refusal::None;
    }
    return why;
}

// Test 5: the predicted FFT time of all the parts' textures within t_max.
ConvolutionSites::Refusal ConvolutionSites::withinTimeBudget(const Site& site) const {
    double predicted = 0;
    for (const ConvolutionPlan& p : site.plans)
        if (site.bandDepths.empty() || !p.slices.empty())  // an empty band costs nothing
            predicted += predictedSeconds(p.fftSize, int(std::max<size_t>(1, p.slices.size())));
    return predicted > settings_.tMax ? Refusal::TooSlow : Refusal::None;
}

ConvolutionSites::Refusal ConvolutionSites::computeTextures(Site& site, ConvolutionLink& out) {
    auto t0 = std::chrono::steady_clock::now();
    out.textures.clear();
    out.pieces.clear();
    try {
        const size_t P = site.parts.size();
        for (size_t j = 0; j < site.plans.size(); ++j) {
            const size_t band = j / P, part = j % P;
            const bool banded = !site.bandDepths.empty();
            if (banded && site.plans[j].slices.empty())
                out.textures.push_back(nullptr);  // a band no blocker reaches: full light
            else
                out.textures.push_back(std::make_shared<const SoftShadowTexture>(
                    computeSoftShadow(site.plans[j], site.parts[part].desc, banded ? site.bandTris[band] : site.tris,
                                      site.partSettings[j])));
            if (band == 0)
                out.pieces.insert(out.pieces.end(), site.parts[part].pieces.begin(), site.parts[part].pieces.end());
        }
        out.bandDepths = site.bandDepths;
        out.bandOrigin = site.bandOrigin;
        out.bandAxis = site.bandAxis;
        out.bandAcross = site.bandAcross;
        out.bandSpans = site.bandSpans;
    } catch (const std::domain_error&) {
        return Refusal::Invalid;
    }
    double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    for (double cur = seconds_.load(); !seconds_.compare_exchange_weak(cur, cur + elapsed);) {
    }
    const Scene& sc = h_.scene();
    out.receiver = site.r;
    out.source = site.s;
    out.receiverPolygons.clear();
    for (int p : site.receivers())
        if (receivesLight(sc.polygons[size_t(p)]))
            out.receiverPolygons.push_back(p);
    out.sourcePolygons = site.faces;
    out.blockerTriangles = int(site.tris.size());
    out.error = site.judged;
    return Refusal::None;
}

}  // namespace penumbra
