#include "refine/refiner.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <unordered_map>

#include "geometry/box_tree.h"
#include "geometry/form_factor.h"
#include "hierarchy/node.h"
#include "hierarchy/predicates.h"
#include "util/error.h"
#include "util/memory.h"
#include "util/parallel.h"
#include "util/seed.h"

namespace penumbra {
namespace {

PENUMBRA_COUNTER(kRays, "rays");                 // visibility rays cast
// A partly seen link whose receiver is at min_size gets up to kRaysPerShare rays per threshold's worth
// of its error, in rounds of 256, at most kMaxBatches rounds (estimateVisibility); a reflector's link
// stops earlier once its standard error is within the threshold.
constexpr double kRaysPerShare = 16;
constexpr int kMaxBatches = 16;
// A partly seen cluster receiver of at most kMaxSharedFaces faces shares its link's light by each face's own
// visible share, from kFaceRays rays per face (shareByFaces); a larger one is opened.
// Four rays, one per quarter of the face: the link's whole transfer is within the threshold, so a face's
// share only divides it. Against eight (the benchmark's five rooms against Cycles, epsilon 0.002 and 0.0002) no
// figure moved by more than 0.03 points; rays -16 % on the 5k office at 0.002, CPU -4.4 % at 10k (alternating runs).
constexpr int kMaxSharedFaces = 64;
constexpr int kFaceRays = 4;
// A reflector's cluster links in the first pass (estimateCluster): this many rays, drawn by area since no face has
// light yet, and the link marked provisional (Link::Fspread = kProvisional). The next pass keeps the estimate
// where the link's bound with the solved radiosities is at most kProvisionalKept of the threshold and makes the
// link again, with the full rays drawn by light, where it is more. Against Cycles (bench/run_time_vs_error.py,
// 512-sample references) the four rooms came out as exact or more in about the same time: at epsilon 0.002 the 5k
// office per face 3.33 -> 2.64 %, the office 3.16 -> 2.47 %, the classroom 1.80 -> 1.79 %, the Cornell box 2.13 ->
// 2.07 %; at the default 2.14 -> 2.13, 1.51 -> 1.45, 1.48 -> 1.48, 1.18 -> 1.11 %; the floating blocks within 0.02
// points (0.87 -> 0.88 % at the default), the lattice unchanged (docs/scaling.md, stop 31).
constexpr int kProvisionalRays = 4;
// Draws of a source point before giving up on finding one in front of the receiver (estimateVisibility).
constexpr int kFrontDraws = 32;
// Levels below a source whose parts differ in light that its unoccluded form factor is weighted over
// (estimateUnoccluded).
constexpr int kWeightLevels = 3;
// A source's parts differ in light when they stray from its radiosity by more than this share of it (partsDiffer).
constexpr double kDeviates = 0.05;
constexpr double kProvisionalKept = 0.125;
// min_size is a share of the smaller of the scene's diagonal and this many median pieces (Refiner::Refiner): with the
// default min_size 0.01, elements down to 0.35 of a typical piece. The five benchmark rooms keep the diagonal's
// floor (the 5k office's pieces, 0.72 m, put it at 0.253 m against the diagonal's 0.246 m).
constexpr double kPieceScale = 35;

PENUMBRA_COUNTER(kRaysBatched, "rays_batched");  // of which: in rounds, for partly seen links at min_size
PENUMBRA_COUNTER(kRaysCluster, "rays_cluster");  // of which: for links with a cluster at either end
PENUMBRA_COUNTER(kShaftsClear, "shafts_clear");  // uneven sources proven wholly seen (sourceDeviationError)
PENUMBRA_COUNTER(kSourceSharedLinks, "source_shared_links");  // near cluster sources taken face by face
PENUMBRA_COUNTER(kSharedClusterLinks, "shared_cluster_links");  // partly seen, shared by the faces' own shares

// Deterministic per-link random numbers: the sample pattern of a link depends only on the identity
// of its two elements and the `seed` setting, never on thread timing or allocation order.
struct Rng {
    uint64_t s;
    Rng(uint64_t key, int seed) : s(seeded(key, seed)) {
        if (s == 0) s = 0x1234567ull;  // xorshift's one fixed point
    }
    double next() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        return double(s >> 11) * (1.0 / 9007199254740992.0);
    }
};

// cos cos / r^2 between x and y on surfaces of normals nx and ny; 0 where either is behind the other.
double pointKernel(const Vec3& x, const Vec3& nx, const Vec3& y, const Vec3& ny) {
    const Vec3 d = y - x;
    const double len2 = length2(d), cx = dot(nx, d), cy = -dot(ny, d);
    if (!(len2 > 0) || cx <= 0 || cy <= 0) return 0;
    return cx * cy / (len2 * len2);
}

// The weight of a ray that began inside a solid (Refiner::fromInsideSolid): it does not count.
constexpr double kLeftOut = -1;

// The visible share of rays [a, b) weighted by their kernels (the share of the light that gets through), or of
// the rays themselves where none has a weight; `seen` counts the rays through. With every ray left out the
// share is unknown, and kLeftOut is returned.
double weightedShare(const char* vis, const std::vector<double>& weight, int a, int b, int& seen) {
    double wSeen = 0, wAll = 0;
    int counted = 0;
    seen = 0;
    for (int i = a; i < b; ++i) {
        if (weight[size_t(i)] == kLeftOut) continue;
        ++counted;
        seen += vis[i];
        wAll += weight[size_t(i)];
        wSeen += vis[i] ? weight[size_t(i)] : 0.0;
    }
    if (counted == 0) return kLeftOut;
    return wAll > 0 ? wSeen / wAll : double(seen) / counted;
}

// Quadrature points on an element in its (s, t) parametrisation: 2x2 Gauss on quads, the
// degree-2 three-point rule on triangles; the centre is added for the spread.
int samplePoints(const Element& e, Vec3* pts) {
    if (e.n == 4) {
        const double a = 0.5 - 0.5 / std::sqrt(3.0), b = 0.5 + 0.5 / std::sqrt(3.0);
        pts[0] = e.pointAt(a, a); pts[1] = e.pointAt(b, a);
        pts[2] = e.pointAt(b, b); pts[3] = e.pointAt(a, b);
        return 4;
    }
    pts[0] = e.pointAt(1.0 / 6, 1.0 / 6);
    pts[1] = e.pointAt(2.0 / 3, 1.0 / 6);
    pts[2] = e.pointAt(1.0 / 6, 2.0 / 3);
    return 3;
}

// The point of the element nearest to x: x projected onto the element's plane (normal n), or, outside
// it, the nearest point of its edges. (A 5 x 5 parametric grid refined twice found it to 1/256 of the
// element's size in 75 evaluations; five such searches per standard link were 11 % of the first
// refinement pass of the 10k office.)
Vec3 nearestPoint(const Element& e, const Vec3& n, const Vec3& x) {
    Vec3 p = x - n * dot(x - e.center, n);
    bool inside = true;
    Vec3 best = p;
    double bestD = HUGE_VAL;
    for (int k = 0; k < e.n; ++k) {
        const Vec3& a = e.v[size_t(k)];
        const Vec3 ab = e.v[size_t((k + 1) % e.n)] - a;
        if (dot(cross(n, ab), p - a) >= 0) continue;
        inside = false;
        double len2 = length2(ab);
        double t = len2 > 0 ? std::clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
        Vec3 q = a + ab * t;
        double d = length2(q - p);
        if (d < bestD) {
            bestD = d;
            best = q;
        }
    }
    if (!inside) p = best;
    // Off the edge it may share with the source, where the source is seen edge-on (form factor 0)
    // though a hair inside it fills half the view.
    return p + (e.center - p) * (1.0 / 32);
}

// Appends the parts in order, each freed once copied. Links are the solve's largest array (29.5M, 700 MB at 100k
// polygons): appending the parts to a growing vector held the parts, the old and the new buffer and, in a
// refinement pass, the input links at once. The array is reserved with a quarter to spare, which costs no
// memory until used (pages of a large allocation are mapped when first written) and lets the next pass add
// its links in place (the 10k office's passes add 7.6 % and 0.1 %) instead of copying the array.
void appendParts(std::vector<Link>& links, std::vector<std::vector<Link>>& parts) {
    size_t total = links.size();
    for (const std::vector<Link>& p : parts) total += p.size();
    if (total > links.capacity()) links.reserve(total + total / 4);
    size_t copied = 0;
    for (std::vector<Link>& p : parts) {
        links.insert(links.end(), p.begin(), p.end());
        copied += p.size();
        std::vector<Link>().swap(p);
        // The parts are small blocks of the threads' heaps, which keep what is freed: unless it is handed
        // back while the copy grows, the copy and all the parts are resident at once.
        if (copied * sizeof(Link) >= (size_t(64) << 20)) {
            releaseFreedMemory();
            copied = 0;
        }
    }
    releaseFreedMemory();
}

// The plane of an element's polygon moved down to its lowest vertex (a warped quad's corners stray from
// the polygon's plane): points of the element lie on or in front of it.
RayCaster::HalfSpace lowestPlane(const Element& e, const Vec3& n) {
    double lo = 0;
    for (int k = 1; k < e.n; ++k) lo = std::min(lo, dot(e.v[k] - e.v[0], n));
    return {e.v[0] + n * lo, n};
}

// The median size (box diagonal) of the scene's pieces: its connected surfaces (ScenePolygon::surface, faces joined
// through shared corners, a corner repeated at the same position counting as one), so a desk's top, a chair's leg,
// a wall are each one piece however finely meshed, and a mesh whose vertices are split per face (flat shading, UV
// seams) is still one. Only receiving faces count. 0 without receivers.
double medianPieceSize(const Scene& sc) {
    std::unordered_map<int, Bounds> pieces;
    for (const ScenePolygon& sp : sc.polygons) {
        if (!receivesLight(sp)) continue;
        Bounds& b = pieces[sp.surface];
        for (int k = 0; k < sp.geom.n; ++k) b.extend(sp.geom.v[k]);
    }
    if (pieces.empty()) return 0;
    std::vector<double> sizes;
    sizes.reserve(pieces.size());
    for (const auto& [surface, b] : pieces) sizes.push_back(length(b.diagonal()));
    std::nth_element(sizes.begin(), sizes.begin() + long(sizes.size() / 2), sizes.end());
    return sizes[sizes.size() / 2];
}

// Lambert's form factor of source s (its shape sp, normal ns) at receiver point p with normal nr; 0 where p lies
// behind s (s sends one way).
double frontFormFactor(const Vec3& p, const Vec3& nr, const Element& s, const Vec3& ns, const Polygon& sp) {
    return dot(p - s.v[0], ns) > 0 ? pointToPolygonFormFactor(p, nr, sp) : 0.0;
}

// Most points a receiver's mean form factor takes (meanPoints): three per triangle of a quad clipped by a plane.
constexpr int kMaxMeanPoints = 9;

// The quadrature points of r's mean form factor from s, and their weights (summing to the share of r's area in front
// of s's plane): samplePoints where r lies wholly in front of s's plane (lift: how far behind a corner may be and
// still count as on it); where s's plane cuts r (a leg or a pedestal standing on a floor element), the part in front
// of it, as a fan of triangles with three points each. The 2 x 2 Gauss points over the whole element read the mean
// form factor of a face standing across a square receiver, as wide as it and as tall, 17 % low on average and 67 %
// RMS over twelve positions (a numerical check against a rule graded toward the foot): whether a point lies behind
// the face depends on where it stands, not on how much of the receiver does. Over the part in front, as here: 1.5 %
// high and 1.7 % RMS; at the position of refiner_test.cpp's test, 52 % low before and 0.7 % high now.
int meanPoints(const Element& r, const Element& s, const Vec3& ns, double lift, Vec3* pts, double* w) {
    bool cut = false;
    for (int k = 0; k < r.n; ++k) cut |= dot(r.v[k] - s.v[0], ns) < -lift;
    if (!cut) {
        int np = samplePoints(r, pts);
        for (int k = 0; k < np; ++k) w[k] = 1.0 / np;
        return np;
    }
    const Polygon front = clipToHalfSpace(r.polygonShape(), s.v[0], ns);
    int np = 0;
    for (int t = 1; t + 1 < front.n && np + 3 <= kMaxMeanPoints; ++t) {
        const Vec3 &a = front.v[0], &b = front.v[size_t(t)], &c = front.v[size_t(t + 1)];
        const double share = 0.5 * length(cross(b - a, c - a)) / r.area / 3;
        // The degree-2 three-point rule on a triangle.
        pts[np] = a * (2.0 / 3) + b * (1.0 / 6) + c * (1.0 / 6), w[np++] = share;
        pts[np] = a * (1.0 / 6) + b * (2.0 / 3) + c * (1.0 / 6), w[np++] = share;
        pts[np] = a * (1.0 / 6) + b * (1.0 / 6) + c * (2.0 / 3), w[np++] = share;
    }
    return np;
}

}  // namespace

Refiner::Refiner(Hierarchy& h, const RayCaster& rays, const Settings& s, Counters& counters)
    : h_(h), rays_(rays), settings_(s), counters_(counters) {
    const Scene& sc = h.scene();
    // Epsilon is relative to the brightest emitter's exitance, but never to more than 200 times the
    // mean exitance the emitters would give the receiving surfaces (their flux over the receiving
    // area): a 5 cm lamp of strength 3000 in a room has a huge exitance and little light, and a
    // threshold relative to that exitance let the room's bounced light go unrefined (5.9 % RMS on
    // its floor against a finer solve; 8.2 % against Cycles per 4 x 4 block, 4.9 % with this bound). Rooms whose lamps
    // cover more than 1/200 of their surfaces (the Cornell box: 1/54) refine exactly as before.
    double flux = 0, area = 0;
    for (const ScenePolygon& p : sc.polygons) {
        flux += p.area * maxComponent(p.emission);
        if (p.receives && maxComponent(p.rho) > 0) area += p.area;
    }
    // On a large open floor that mean is tiny wherever the lamps are small: a 20 cm lamp over a 100 m floor
    // refined every element within ~15 m of it to the smallest size. The bound is therefore never below
    // the brightest irradiance one emitter gives the first face straight in front of it (a disk of its
    // area at that distance): rooms keep their bound (it is larger); that floor went from 38.9k to 5.8k
    // elements at the same accuracy (native/python/test_min_edge.py).
    double peak = 0;
    for (const ScenePolygon& p : sc.polygons) {
        double e = maxComponent(p.emission);
        if (e <= 0) continue;
        RayCaster::Hit hit = rays.firstHit(p.geom.centroid() + p.normal * (1e-5 * sc.diagonal), p.normal,
                                           4 * sc.diagonal);
        if (hit.polygon < 0) continue;
        double d2 = hit.distance * hit.distance;
        peak = std::max(peak, e * p.area / (M_PI * d2 + p.area));
    }
    double scale = sc.maxEmission;
    if (area > 0 && flux > 0) scale = std::min(scale, std::max(200.0 * flux / area, peak));
    // Lamps and the world are no faces: their scale is the brightest mean irradiance they give a face.
    scale = std::max(scale, sc.lightScale);
    threshold_ = s.epsilon * scale;
    // min_size is relative to the scene's diagonal, and to kPieceScale times the median piece where that is
    // smaller: a hall grows with its furniture count while its desks and chairs do not, and a floor relative to the
    // hall alone was 0.96 m in the 100k office (6.84 % per face against Cycles at epsilon 0.002; at 0.25 m, the
    // 5k office's, 3.8 %). In rooms whose pieces are large beside the room (the five benchmark rooms, the
    // validation corpus' rooms) the diagonal still decides.
    minEdge_ = s.minSize * std::min(sc.diagonal, kPieceScale * medianPieceSize(sc));
    if (!(minEdge_ > 0)) minEdge_ = s.minSize * sc.diagonal;
    const double minEdge = minEdge_;
    minArea_.resize(sc.polygons.size());
    for (size_t p = 0; p < sc.polygons.size(); ++p) {
        double m = sc.polygons[p].minEdge > 0 ? sc.polygons[p].minEdge : minEdge;
        minArea_[p] = m * m;
    }
    if (s.contactFloor > 0) lowerFloorsAtContacts(s.contactFloor);
    lift_ = 1e-5 * sc.diagonal;
    touched_ = rays.touchedFaces(sc, lift_);
    footprint_ = rays.footprintFaces(sc, lift_, touched_);
    // An emitter's part under something gives no light, so its rays count (as in estimateVisibility).
    for (size_t p = 0; p < sc.polygons.size(); ++p) footprint_[p] &= maxComponent(sc.polygons[p].emission) <= 0;
    if (!h.clusters().empty()) {
        const ClusterTree& ct = h.clusters();
        clusterEmits_.assign(ct.size(), 0);
        for (size_t c = 0; c < ct.size(); ++c)
            for (int k = ct[int(c)].begin; k < ct[int(c)].end && !clusterEmits_[c]; ++k)
                clusterEmits_[c] = maxComponent(sc.polygons[size_t(ct.polygons()[size_t(k)])].emission) > 0;
        faceRoles_.reserve(ct.polygons().size());
        for (int p : ct.polygons()) {
            const ScenePolygon& sp = sc.polygons[size_t(p)];
            faceRoles_.push_back({sendsLight(sp), receivesLight(sp) && !h_.buried(p)});
        }
    }
    strata_ = std::max(1, int(std::lround(std::sqrt(double(std::max(1, s.visibilityRays))))));
    if (s.convolution) sites_ = std::make_unique<ConvolutionSites>(h, rays, s, counters);
}

bool Refiner::tryConvolution(int ri, int si) {
    if (!sites_ || !sites_->receiverCandidate(ri) || !sites_->sourceCandidate(si)) return false;
    // A transfer the standard refiner links at once needs no texture.
    if (receiverRho(ri) * fluxBound(h_, si, nodeBox(h_, ri)) <= threshold_) return false;
    ConvolutionLink l;
    if (!sites_->tryLink(ri, si, l)) return false;
    std::lock_guard<std::mutex> lock(convMutex_);
    conv_.push_back(std::move(l));
    return true;
}

void Refiner::setSolvedTextures(const std::vector<ConvolutionLink>& conv, const CompleteTextures& textures) {
    if (!sites_ || !settings_.indirectSources) return;
    sites_->beginPass(h_.size(), conv, conv.empty() ? std::vector<Rgb>{} : textures.reflected(h_, conv));
}

std::vector<ConvolutionLink> Refiner::convolutionLinks() const {
    std::lock_guard<std::mutex> lock(convMutex_);
    std::vector<ConvolutionLink> out = conv_;
    std::sort(out.begin(), out.end(), [](const ConvolutionLink& a, const ConvolutionLink& b) {
        return a.receiver != b.receiver ? a.receiver < b.receiver : a.source < b.source;
    });
    return out;
}

bool Refiner::emits(int node) const {
    return isClusterNode(node) ? clusterEmits_[size_t(clusterIndex(node))] != 0
                               : maxComponent(h_.scene().polygons[h_[node].polygon].emission) > 0;
}

bool Refiner::countLink(const Link& l) {
    // A hidden transfer is kept only from a source that emits: the final gather measures visibility as
    // the linked over the unoccluded light of the emitters, and the hidden ones count in the second.
    // From a reflector it carries nothing anywhere (F V = 0 in the solve, no emission in the gather),
    // and it was 18 % of the 5k office's links at epsilon 0.002 (553k cluster links alone).
    // (A first pass's provisional estimate is kept: the next pass estimates it again or drops it, rerefine.)
    if (l.V <= 0 && !emits(l.source) && !provisional(l)) return false;
    if (linkCount_.fetch_add(1, std::memory_order_relaxed) >= settings_.maxLinks)
        throw BudgetExceeded("memory guard: the scene needs more than max_links = " +
                             std::to_string(settings_.maxLinks) +
                             " links; raise epsilon or min_size, or raise max_links");
    return true;
}

void Refiner::keep(const Link& l, std::vector<Link>& out) {
    if (countLink(l)) out.push_back(l);
}

void Refiner::lowerFloorsAtContacts(double k) {
    // What a small object changes around it (the shade in front of a monitor's stand, the dark ring round
    // a chair leg) is about its own size wide, and the face it stands on must be cut that fine there to
    // show it, and to send it on. Only faces of other objects count, so that a bevel or a tessellation
    // does not lower its own mesh's floor; lamps that take no light do not count either.
    const Scene& sc = h_.scene();
    constexpr double kFloorLimit = 1e-3;  // metres: below this, a touching sliver would make millions of elements
    std::vector<Bounds> boxes;
    std::vector<int> small;
    double reach = 0;
    for (size_t q = 0; q < sc.polygons.size(); ++q) {
        const ScenePolygon& sq = sc.polygons[q];
        double size = std::sqrt(sq.area);
        if (!receivesLight(sq) || k * size * k * size >= minArea_[q]) continue;
        boxes.push_back(polygonBox(sq));
        small.push_back(int(q));
        reach = std::max(reach, 2 * size);
    }
    if (small.empty()) return;
    BoxTree tree(std::move(boxes));
    // Each face reads and writes its own floor only: the small faces' sizes come from their areas.
    parallelFor(sc.polygons.size(), resolveThreads(settings_.threads), 256, [&](size_t b, size_t e, int) {
        for (size_t p = b; p < e; ++p) {
            const ScenePolygon& sp = sc.polygons[p];
            const Bounds own = polygonBox(sp);
            Bounds near = own;
            near.extend(own.lo - Vec3{reach, reach, reach});
            near.extend(own.hi + Vec3{reach, reach, reach});
            double m2 = minArea_[p];
            tree.query([&](const Bounds& nb) { return overlaps(nb, near); }, [&](int i) {
                const ScenePolygon& sq = sc.polygons[size_t(small[size_t(i)])];
                if (sq.object == sp.object) return;
                double size = std::sqrt(sq.area);
                if (boxDistance(own, tree.box(i)) > 2 * size) return;
                double f = std::max(k * size, kFloorLimit);
                m2 = std::min(m2, f * f);
            });
            minArea_[p] = m2;
        }
    });
}

bool Refiner::canSplit(int e) const {
    return isClusterNode(e) || (h_[e].area > minArea_[size_t(h_[e].polygon)] && h_[e].depth < 250);
}

bool Refiner::receives(int node) const {
    if (isClusterNode(node)) return h_.clusters()[clusterIndex(node)].rhoMax > 0;
    return receivesLight(h_.scene().polygons[h_[node].polygon]);
}

bool Refiner::sends(int node) const {
    if (isClusterNode(node)) return h_.clusters()[clusterIndex(node)].sends;
    return sendsLight(h_.scene().polygons[h_[node].polygon]);
}

double Refiner::receiverRho(int node) const {
    if (isClusterNode(node)) return h_.clusters()[clusterIndex(node)].rhoMax;
    return maxComponent(h_.scene().polygons[h_[node].polygon].rho);
}

double Refiner::linkError(const Link& l) const {
    if (isClusterNode(l.receiver) || isClusterNode(l.source))
        return receiverRho(l.receiver) * fluxBound(h_, l.source, nodeBox(h_, l.receiver));
    const Element& r = h_[l.receiver];
    const Element& s = h_[l.source];
    const ScenePolygon& rp = h_.scene().polygons[r.polygon];
    double rhoB = std::max({rp.rho.x * s.B.x, rp.rho.y * s.B.y, rp.rho.z * s.B.z});
    double spread = std::max(double(l.Fspread), l.partial() ? double(l.Fmean) : 0.0);
    return rhoB * spread;
}

double Refiner::sourceDeviationError(const Link& l) const {
    // A source whose radiosity is far from uniform, not seen through a clear shaft: rays spread by its
    // area see a share of its area, not of its light, and the hidden part may be the bright one (a
    // ceiling over the back of a lamp mounted 5 mm under it, seen from the floor past the lamp). Such
    // a link is estimated again in the next pass, with its rays spread by light (pointByLight).
    // Sixteen rays that all get through prove nothing when the hidden part is small and bright (a
    // 0.5 m lamp under a 4 x 3 m ceiling covers 2 % of it, and the light it traps there is as much as
    // the lamp sends down); only a clear shaft does.
    if (l.V <= 0 || isClusterNode(l.source) || isClusterNode(l.receiver) || !hasSettledChildren(l.source)) return 0;
    double e = receiverRho(l.receiver) * double(h_[l.source].Bdev) * double(l.Fmean);
    if (e <= threshold_ || l.partial()) return e;
    const Element& r = h_[l.receiver];
    const Element& s = h_[l.source];
    Bounds rb, sb;
    Vec3 pad{2 * lift_, 2 * lift_, 2 * lift_};
    for (int k = 0; k < r.n; ++k) { rb.extend(r.v[k] - pad); rb.extend(r.v[k] + pad); }
    for (int k = 0; k < s.n; ++k) { sb.extend(s.v[k] - pad); sb.extend(s.v[k] + pad); }
    const Scene& sc = h_.scene();
    RayCaster::HalfSpace planes[2] = {lowestPlane(r, sc.polygons[r.polygon].normal),
                                      lowestPlane(s, sc.polygons[s.polygon].normal)};
    if (!rays_.shaftIsClear(rb, sb, r.polygon, s.polygon, planes, 2, 0.5 * lift_)) return e;
    counters_.add(kShaftsClear);
    return 0.0;
}

bool Refiner::estimateUnoccluded(int ri, int si, Link& l) {
    const Element& r = h_[ri];
    const Element& s = h_[si];
    const Scene& sc = h_.scene();
    const Vec3& nr = sc.polygons[r.polygon].normal;
    const Vec3& ns = sc.polygons[s.polygon].normal;
    // Light leaves the source's front and enters the receiver's front: some corner of each must be
    // strictly in front of the other.
    bool sInFront = false, rInFront = false;
    for (int k = 0; k < s.n; ++k) sInFront |= dot(s.v[k] - r.v[0], nr) > lift_;
    for (int k = 0; k < r.n; ++k) rInFront |= dot(r.v[k] - s.v[0], ns) > lift_;
    if (!sInFront || !rInFront) return false;

    Polygon sp = s.polygonShape();
    // The mean comes from the quadrature points; the spread also looks at the centre and the corners,
    // where the kernel varies most (a corner on the source's edge sees half a hemisphere).
    Vec3 pts[kMaxMeanPoints + 7];
    double w[kMaxMeanPoints];
    int np = meanPoints(r, s, ns, lift_, pts, w);
    int total = np;
    pts[total++] = r.center;
    for (int k = 0; k < r.n; ++k) pts[total++] = r.v[k];
    // And where the receiver comes nearest the source: a small source beside a large receiver (a
    // ceiling tile meeting a wall) lights a strip along their common edge that none of the points
    // above may touch, and the link would be judged smooth while it under-reads its mean: a closed
    // box lost 0.8 % of its light that way without clustering.
    pts[total++] = nearestPoint(r, nr, s.center);
    {
        Vec3 best = r.center;
        double bestD = HUGE_VAL;
        for (int k = 0; k < s.n; ++k) {
            Vec3 q = nearestPoint(r, nr, s.v[k]);
            double d = length2(q - s.v[k]);
            if (d < bestD) { bestD = d; best = q; }
        }
        pts[total++] = best;
    }
    double mean = 0, fmin = HUGE_VAL, fmax = 0;
    for (int k = 0; k < total; ++k) {
        double f = frontFormFactor(pts[k], nr, s, ns, sp);
        if (k < np) mean += w[k] * f;
        fmin = std::min(fmin, f);
        fmax = std::max(fmax, f);
    }
    mean *= partsWeight(ri, si, pts, np);
    l.receiver = ri;
    l.source = si;
    l.Fmean = float(mean);
    l.Fspread = float(fmax - fmin);
    l.V = 1;
    return fmax > 0;
}

// A source whose parts differ in light sends it unevenly: its mean radiosity times the whole
// source's form factor gives a receiver beside a dark part (the floor under a sphere, the wall
// behind a bookcase) the light of the bright parts. The form factor is taken part by part and
// weighted by each part's share of the radiosity (the parts' weights average to one over the
// area), so B_s * Fmean is the light the parts send. Every receiver of the source then draws on
// the same distribution and what they take sums to what the source sends; splitting the links of
// near receivers only, and leaving the far ones on the mean, lost 2-3 % of a closed box's light.
double Refiner::partsWeight(int ri, int si, const Vec3* pts, int np) const {
    const Element& s = h_[si];
    const Scene& sc = h_.scene();
    const Vec3& nr = sc.polygons[h_[ri].polygon].normal;
    const Vec3& ns = sc.polygons[s.polygon].normal;
    if (hasSettledChildren(si) && s.Bdev > 0) {
        double bs = s.B.x + s.B.y + s.B.z;
        if (bs > 0) {
            // Down to kWeightLevels below the source, through the parts whose own parts differ: receivers
            // that split the source (refineElements) see it at that depth, and those that keep it whole must
            // draw on the same distribution, or the light the first do not take is lost (a lamp in a closed
            // box reflected 0.987 of its light with the parts one level down, 0.997 three levels down).
            // Only parts whose deviation could matter to some receiver, and is more than the solve's noise
            // (partsDiffer), are opened, whatever this receiver's form factor: all receivers of the source then
            // draw on the same parts.
            // The parts only share out the whole source's exact form factor by their light, so each takes its
            // share by the kernel the sweeps use for an element (elementKernel: exact near it, the point kernel
            // with its second-order term beyond); Lambert's formula at every part took a quarter more time on the
            // 5k office at the default.
            const double rho = receiverRho(ri);
            double lit = 0, all = 0;
            int stack[4 * kWeightLevels], depth[4 * kWeightLevels], top = 0;
            stack[top] = si, depth[top++] = 0;
            while (top > 0) {
                --top;
                int e = stack[top], d = depth[top], fc = h_.firstChild(e);
                for (int k = 0; k < h_[e].numChildren; ++k) {
                    const Element& c = h_[fc + k];
                    bool open = d + 1 < kWeightLevels && rho * c.Bdev > threshold_ && partsDiffer(fc + k) &&
                                hasSettledChildren(fc + k);
                    if (open) {
                        stack[top] = fc + k, depth[top++] = d + 1;
                        continue;
                    }
                    double f = 0;
                    for (int i = 0; i < np; ++i) f += elementKernel(c, ns, pts[i], &nr);
                    all += f;
                    lit += f * (c.B.x + c.B.y + c.B.z) / bs;
                }
            }
            if (all > 0) return lit / all;
        }
    }
    return 1.0;
}

double Refiner::weightedMean(int ri, int si) const {
    const Element& r = h_[ri];
    const Element& s = h_[si];
    const Vec3& nr = h_.scene().polygons[r.polygon].normal;
    const Vec3& ns = h_.scene().polygons[s.polygon].normal;
    Polygon sp = s.polygonShape();
    Vec3 pts[kMaxMeanPoints];
    double w[kMaxMeanPoints];
    int np = meanPoints(r, s, ns, lift_, pts, w);
    double mean = 0;
    for (int k = 0; k < np; ++k) mean += w[k] * frontFormFactor(pts[k], nr, s, ns, sp);
    return mean * partsWeight(ri, si, pts, np);
}

void Refiner::estimateVisibility(int ri, int si, Link& l, int batches, double transfer) {
    const Element& r = h_[ri];
    const Element& s = h_[si];
    const Scene& sc = h_.scene();
    const Vec3 nr = sc.polygons[r.polygon].normal * lift_;
    const Vec3 ns = sc.polygons[s.polygon].normal * lift_;
    // A light whose Cast Shadow is off is seen whole (kCastsNoShadow).
    if (!sc.polygons[size_t(s.polygon)].castsShadow) {
        l.V = 1;
        return;
    }
    // No shaft test first: where the shaft is clear the rays all get through too (V = 1), and in a
    // furnished room it seldom is while its search of the box tree costs more than Embree's rays (10k office
    // at epsilon 0.002: 6 % of the links were proven clear; without the test 3 % more rays, 11 % less CPU;
    // a closed box of 13 faces, 60 % more rays for the same CPU). sourceDeviationError keeps its shaft:
    // there a clear shaft proves what passing rays cannot.
    // batches > 0: that many rounds of 16 x 16 rays, the sample pattern carried on from round to round.
    int m = batches > 0 ? 16 : strata_, n = std::min(m * m, 256);
    // With a stopping rule the first round is a quarter round: most links need no more.
    int budget = batches > 0 ? batches * 256 : n;
    if (transfer > 0) m = 8, n = 64;
    Rng rng(r.key ^ (s.key * 0x9E3779B97F4A7C15ull), settings_.seed);
    Vec3 from[256], to[256];
    // A source that has been cut into parts with different radiosities (as a receiver) is sampled by
    // its light rather than its area: V is then the visible share of what it sends, which is what the
    // link carries. Sixteen rays spread by area over a ceiling miss a lamp mounted under it that hides
    // a fifth of the ceiling's light; spread by light, they find it.
    bool byLight = hasSettledChildren(si) && s.Bdev > 0 && maxComponent(s.B) > 0;
    const Vec3 ur = sc.polygons[r.polygon].normal, us = sc.polygons[s.polygon].normal;
    // Cosines below this are rounding noise of points lying in the other's plane (a block's side
    // meeting the floor), which must not decide whether a ray counts.
    constexpr double kGrazing = 1e-4;
    // Drawn by light over the whole source, a ray to a part behind the receiver's plane counts for nothing
    // (below): a card standing on a floor, facing away from the lamp, drew all its rays from the floor's lit
    // part behind it, counted none, and the floor's light to it was dropped as hidden. Redrawn until in
    // front, the rays follow the light of the part the link carries; where next to none of the light lies
    // in front, that part is drawn by area.
    auto inFront = [&](const Vec3& p) { return dot(p - r.v[0], ur) > lift_; };
    auto inFrontByLight = [&](int stratum, int strata) {
        for (int tries = 0; tries < kFrontDraws; ++tries) {
            // In the order GCC evaluated the single draw this replaces (its arguments right to left), so
            // that links whose first point lies in front keep their rays (the goldens' counts stayed equal).
            double pt = rng.next(), ps = rng.next();
            double u = tries == 0 ? (stratum + rng.next()) / strata : rng.next();
            Vec3 p = pointByLight(si, u, ps, pt);
            if (inFront(p)) return p;
        }
        for (int tries = 0; tries < kFrontDraws; ++tries) {
            Vec3 p = s.pointAt(rng.next(), rng.next());
            if (inFront(p)) return p;
        }
        return s.pointAt(rng.next(), rng.next());
    };
    int open = 0;
    // Each ray counts by the point-to-point kernel cos cos / r^2 of its ends, so V is the visible share of
    // the form factor rather than of the areas. They differ wherever what is hidden lies nearer or farther
    // than what is seen (a whole lamp linked to a small element under a lattice shade), and the areas' share
    // does not add up: a closed 2 m room with two boxes on its floor, at epsilon 0.002 without clustering,
    // absorbed 97.3 % of its lamp's light with the areas' share and 98.0 % with the form factor's (all of
    // it is exact; native/python/test_energy_balance.py).
    double wSeen = 0, wAll = 0, w2Seen = 0, w2All = 0;
    // A reflector's radiosity is its mean over the whole element, and a part inside a closed surface (the
    // floor under a box standing on it) receives nothing: what the element reflects leaves from the rest.
    // A ray from that part meets the solid's inside and would cut the light a second time, so it does not
    // count. Only faces that something touches can have such a part (touched_); an emitter's buried part
    // gives no light, so its rays count. The 5k scaling office against Cycles at epsilon 0.002: bias -1.83 %
    // with neither, -1.42 % with the kernel's share, -1.27 % with both; the closed room with clustering kept
    // 97.6 % of its light before and 98.8 % with both.
    const bool fromInside = touched_[size_t(s.polygon)] && !emits(si);
    int cast = 0;
    for (int round = 0; cast < budget; ++round) {
        if (round > 0) m = 16, n = std::min(256, budget - cast);
        // Stratified on both ends, with the source strata visited in a shuffled order so that rays
        // do not all run parallel.
        int perm[256];
        for (int i = 0; i < n; ++i) perm[i] = i;
        for (int i = n - 1; i > 0; --i) std::swap(perm[i], perm[int(rng.next() * (i + 1))]);
        for (int i = 0; i < n; ++i) {
            int a = i, b = perm[i];
            from[i] = r.pointAt((a % m + rng.next()) / m, (a / m + rng.next()) / m) + nr;
            to[i] = (byLight ? inFrontByLight(i, n)
                             : s.pointAt((b % m + rng.next()) / m, (b / m + rng.next()) / m)) + ns;
        }
        // Only rays whose ends each lie in front of the other's surface count: Fmean already leaves
        // out the part of the source behind the receiver's plane, and a ray to it is blocked by the
        // receiver's own body (a floor element reaching under a sphere or a box standing on it).
        // Counted, such rays cut that light a second time: objects resting on a floor came out 5-10 %
        // dark.
        char vis[256];
        // Reflected light passes faces hidden from diffuse rays; an emitter's light is a shadow ray's.
        rays_.visiblePairs(from, to, n, vis, !emits(si));
        counters_.add(kRays, size_t(n));
        if (batches > 0) counters_.add(kRaysBatched, size_t(n));
        for (int i = 0; i < n; ++i) {
            Vec3 d = to[i] - from[i];
            double len = length(d);
            open += vis[i];
            if (!(len > 0) || dot(ur, d) <= kGrazing * len || -dot(us, d) <= kGrazing * len) continue;
            if (!vis[i] && fromInside && rays_.metFromBehind(sc, to[i], d * (-1.0 / len), len)) continue;
            double len2 = len * len, w = dot(ur, d) * -dot(us, d) / (len2 * len2);
            wAll += w;
            wSeen += vis[i] ? w : 0.0;
            w2All += w * w;
            w2Seen += vis[i] ? w * w : 0.0;
        }
        // Enough rounds once the estimate's standard error, times the light the link would carry
        // unshadowed, is within the threshold: the weighted share's variance is
        // sum w^2 (v - V)^2 / (sum w)^2.
        cast += n;
        if (transfer > 0 && wAll > 0 && cast < budget) {
            double V = wSeen / wAll;
            double var = (w2Seen * (1 - 2 * V) + V * V * w2All) / (wAll * wAll);
            if (transfer * std::sqrt(std::max(0.0, var)) <= threshold_) break;
        }
    }
    // Every ray that counts has a positive weight: with none, the share of all rays cast.
    l.V = float(wAll > 0 ? wSeen / wAll : double(open) / double(cast));
}

double Refiner::gradientError(const Link& l) const {
    if (isClusterNode(l.source) || isClusterNode(l.receiver) || !hasSettledChildren(l.source)) return 0;
    // The kernel varies across the source by about its size over its distance; times how far its
    // parts' radiosities stray from the one value the link uses.
    // The kernel varies across the source by about its size over its distance; times how far its
    // parts' radiosities stray from the one value the link uses.
    const Element& s = h_[l.source];
    double d = length(s.center - h_[l.receiver].center);
    double var = d > 0 ? std::min(1.0, std::sqrt(s.area) / d) : 1.0;
    return receiverRho(l.receiver) * double(s.Bdev) * double(l.Fmean) * var;
}

bool Refiner::partsDiffer(int e) const {
    // Parts whose light differs by a few per cent are the solve's own noise between passes (a furnace's faces,
    // uniform in the answer, differ by 1e-3 after the first, loose solve), not light worth resolving: taken
    // as real, the parts' frozen shares put a closed box of albedo 0.99 5 % off B = E / (1 - rho).
    const Element& s = h_[e];
    return double(s.Bdev) > kDeviates * maxComponent(s.B);
}

bool Refiner::hasSettledChildren(int e) const {
    // Children made during this pass (by other threads, splitting e as a receiver) have no radiosity
    // of their own yet, and whether they exist depends on thread timing.
    int fc = h_.firstChild(e);
    return fc >= 0 && size_t(fc) < settled_;
}

Vec3 Refiner::pointByLight(int e, double u, double s, double t) const {
    // Descends to a leaf, each child chosen with probability proportional to B * area, u rescaled at
    // each step so that stratified u stay stratified; then a point of that leaf.
    for (int fc = lightNodes_[size_t(e)].firstChild; fc >= 0; fc = lightNodes_[size_t(e)].firstChild) {
        int k = lightNodes_[size_t(e)].numChildren;
        double w[4] = {0, 0, 0, 0}, total = 0;
        for (int j = 0; j < k; ++j) total += (w[j] = lightNodes_[size_t(fc + j)].weight);
        if (!(total > 0))
            for (int j = 0; j < k; ++j) total += (w[j] = h_[fc + j].area);
        double x = u * total;
        int j = 0;
        while (j < k - 1 && x >= w[j]) x -= w[j++];
        u = w[j] > 0 ? std::clamp(x / w[j], 0.0, 1.0) : 0.5;
        e = fc + j;
    }
    return h_[e].pointAt(s, t);
}

void Refiner::refine(int ri, int si, std::vector<Link>& out) {
    if (isClusterNode(ri) || isClusterNode(si))
        refineCluster(ri, si, out, nullptr);
    else
        refineElements(ri, si, out);
}

std::vector<int> Refiner::children(int node, bool receiver) {
    std::vector<int> kids;
    if (isClusterNode(node)) {
        const ClusterTree& ct = h_.clusters();
        const Cluster& c = ct[clusterIndex(node)];
        for (int k = 0; k < c.numChildren; ++k) kids.push_back(clusterNode(c.firstChild + k));
        for (int k = c.begin; k < c.ownEnd; ++k) kids.push_back(ct.polygons()[k]);
    } else {
        int fc = h_.subdivide(node);
        for (int k = 0; k < h_[node].numChildren; ++k) kids.push_back(fc + k);
    }
    kids.erase(std::remove_if(kids.begin(), kids.end(),
                              [&](int n) { return receiver ? !receives(n) : !sends(n); }),
               kids.end());
    return kids;
}

void Refiner::refineCluster(int ri, int si, std::vector<Link>& out,
                            std::vector<std::pair<int, int>>* defer) {
    if (tryConvolution(ri, si)) return;
    auto recurse = [&](int r, int s) {
        if (defer)
            defer->push_back({r, s});
        else
            refine(r, s, out);
    };
    Bounds rb = nodeBox(h_, ri), sb = nodeBox(h_, si);
    // Touching boxes are always split, whatever their bound: there a link's few rays and its faces'
    // kernels at the receiver's centre say little of where the light lands. (Linking the dark ones of
    // the first pass whole only moved the work into the second: the 20k office at the default epsilon
    // made 1 % fewer links in 5 % more time, docs/scaling.md, stop 32.) Boxes closer
    // than a hundredth of the smaller one count as touching, so that whether a box resting on the floor
    // touches it does not hang on the last bits of float32 input (a scene far from the origin).
    bool openReceiver = false;
    double gap = 0.01 * std::min(length(rb.diagonal()), length(sb.diagonal()));
    Bounds rgrown = rb;
    rgrown.extend(rb.lo - Vec3{gap, gap, gap});
    rgrown.extend(rb.hi + Vec3{gap, gap, gap});
    // A near cluster source is opened: its one visible share stands for faces that see the receiver
    // from ever more different places. (Its light is evaluated face by face where it is near, node.cpp;
    // a cluster receiver's faces each gather at their own centre.)
    double dist = length(nodeCenter(h_, ri) - nodeCenter(h_, si));
    bool sourceFar = !isClusterNode(si) || h_.clusters()[clusterIndex(si)].radius <= settings_.farField * dist;
    const bool apart = ri != si && !overlaps(rgrown, sb);
    // A near cluster source whose whole transfer is within the threshold need not be opened for an element
    // receiver: each of its faces' light is taken with its own visible share and form factor
    // (shareSourceByFaces). Opened, it became a link per face with 16 rays each, most of the links of a
    // large furnished room (a ceiling element over desks 3 m below: 60 % of the 20k office's links at epsilon
    // 0.002 joined two elements).
    if (apart && !sourceFar && settings_.sourceShares && !isClusterNode(ri) && sharesFaces(si) &&
        receiverRho(ri) * fluxBound(h_, si, rb) <= threshold_) {
        Link l;
        if (shareSourceByFaces(ri, si, l)) {
            keep(l, out);
            return;
        }
    }
    // Into a cluster receiver small enough to share what it receives by its faces' own visibility, such a
    // source is linked as a far one is: each receiving face then gathers it face by face (fluxAt) with its
    // own share, from rays drawn toward that face (shareByFaces). Opened, it made a quarter of the 20k
    // office's links (a desk's cluster linked to each ceiling tile above it).
    const bool nearShared = !sourceFar && settings_.sourceShares && isClusterNode(ri) && sharesFaces(si) &&
                            h_.clusters()[clusterIndex(ri)].end - h_.clusters()[clusterIndex(ri)].begin <= kMaxSharedFaces;
    if (apart && (sourceFar || nearShared) && receiverRho(ri) * fluxBound(h_, si, rb) <= threshold_) {
        Link l;
        if (estimateCluster(ri, si, l)) {
            // A transfer that no ray gets through is kept with V = 0: it adds nothing to the solve, but
            // the final gather reads the unoccluded light of every transfer as the measure of visibility.
            if (l.V <= 0) {
                keep(l, out);
                return;
            }
            // A cluster shares what it receives among its faces by their cosines alone, blind to
            // shadows inside it: a partly hidden cluster would light the inside of a sealed box. Each
            // face takes its own visible share of the source instead (a few rays per face); a cluster
            // too large for that is opened, down to faces whose own links see their own visibility.
            if (!isClusterNode(ri) || l.V >= 1 || shareByFaces(ri, si, nearShared)) {
                keep(l, out);
                return;
            }
            openReceiver = true;
        } else if (!facesToward(ri, sb, true) || !facesToward(si, rb, false)) {
            return;
        }
        // Else no face of one end faces the other's centre, yet some face part of it (a sphere's
        // side beside a large floor element whose centre lies behind it): split, not drop. Dropping
        // these pairs took half the floor's light off the lower half of a sphere resting on it.
    }
    if (ri == si) {
        // Light within a cluster: every pair of its parts, but never a polygon with itself.
        std::vector<int> rk = children(ri, true), sk = children(si, false);
        for (int a : rk)
            for (int b : sk)
                if (a != b || isClusterNode(a)) recurse(a, b);
        return;
    }
    if (openReceiver) {
        for (int a : children(ri, true)) recurse(a, si);
        return;
    }
    bool canR = canSplit(ri), canS = canSplit(si);
    // An element source is never split here: its parts would share the same error among more links
    // (see refineElements), so a cluster receiver is opened down to its faces instead, and those
    // meet the source through the exact form factor.
    double sizeR = length(rb.diagonal()), sizeS = length(sb.diagonal());
    if (!isClusterNode(si)) canS = false;
    // A receiver that could take a convolution link is kept whole while the source is narrowed down
    // to its emitters (the paper's choice of source refinement before receiver refinement).
    // Only where such a link would then pass its tests: elsewhere the split is the standard one, and a
    // scene without convolution sites refines exactly as with convolution off.
    bool keepReceiver = canS && sites_ && sites_->receiverCandidate(ri) && sites_->sourceCandidate(si) &&
                        sites_->linkPossibleBelow(ri, si, [&](int g) {
                            return receiverRho(ri) * fluxBound(h_, g, nodeBox(h_, ri)) > threshold_;
                        });
    if (canR && !keepReceiver && (!canS || notSmaller(sizeR, sizeS))) {
        for (int a : children(ri, true)) recurse(a, si);
    } else {
        for (int b : children(si, false)) recurse(ri, b);
    }
}

// The faces of a cluster as sampleNode draws them: a cumulative distribution over `polys`.
struct Refiner::NodeSampler {
    std::vector<double> cdf;
    std::vector<int> polys;
    double total = 0;
    bool byLight = false;  // a source's faces drawn by their light: within each face, too
    std::vector<double> lightCdf;  // buildSampler's, kept to spare an allocation per cluster link sampled
};

bool Refiner::buildSampler(int node, const Vec3& toward, bool receiver, NodeSampler& out) const {
    const ClusterTree& ct = h_.clusters();
    const Cluster& c = ct[clusterIndex(node)];
    // A source's points are drawn by the light each face sends toward `toward` (radiosity x area x
    // cosine / r^2), so the rays' visible share is the share of the transfer that gets through, which is
    // what the link multiplies its unoccluded transfer by. Drawn by area, a near cluster's dark or far
    // faces counted as much as the bright near ones: with sources linked up to half their distance
    // (far_field 0.5) the 5k office's bias against Cycles went from -1.1 to -3.0 % at epsilon 0.002 by
    // area and to -1.3 % by light; at the defaults it went from -1.4 to -0.55 %. Before any radiosity is
    // known (every face dark) they go by area.
    std::vector<double>& lightCdf = out.lightCdf;
    lightCdf.clear();
    out.cdf.clear();
    out.polys.clear();
    double total = 0, lightTotal = 0;
    // The faces' centre, normal, area and light (as of the last updateClusterFlux) from their compact copy.
    const std::vector<Hierarchy::FaceLight>& faces = h_.faceLight();
    for (int k = c.begin; k < c.end; ++k) {
        const FaceRole& role = faceRoles_[size_t(k)];
        if (receiver ? !role.receives : !role.sends) continue;
        const Hierarchy::FaceLight& f = faces[size_t(k)];
        Vec3 d = toward - f.center;
        if (!(dot(f.normal, d) > 0)) continue;  // turned away: spares the normalisation (a square root, 3 divisions)
        double w = f.area * std::max(0.0, dot(f.normal, normalize(d)));
        if (w <= 0) continue;
        total += w;
        out.cdf.push_back(total);
        out.polys.push_back(ct.polygons()[size_t(k)]);
        if (!receiver) {
            const Rgb& b = f.B;
            lightTotal += w * (b.x + b.y + b.z) / std::max(length2(d), 1e-300);
            lightCdf.push_back(lightTotal);
        }
    }
    if (total <= 0) return false;
    out.byLight = lightTotal > 0;
    if (out.byLight) {
        out.cdf.swap(lightCdf);
        total = lightTotal;
    }
    out.total = total;
    return true;
}

void Refiner::drawFromSampler(const NodeSampler& s, uint64_t seed, int n, Vec3* pts, int* faces) const {
    const Scene& sc = h_.scene();
    Rng rng(seed, settings_.seed);
    for (int i = 0; i < n; ++i) {
        double u = (i + rng.next()) / n * s.total;
        size_t j = std::min(size_t(std::lower_bound(s.cdf.begin(), s.cdf.end(), u) - s.cdf.begin()), s.cdf.size() - 1);
        // Within a face drawn by its light, its point follows its parts' light too (a floor face half in a
        // desk's shadow, which the desk also hides from the ceiling): the 5k office's ceiling kept 0.3 % more
        // of its light (native/python/test_energy_balance.py's measure), bias against Cycles at epsilon 0.002
        // -1.23 -> -1.11 %.
        const int p = s.polys[j];
        double a = rng.next(), b = rng.next();
        Vec3 q = s.byLight && hasSettledChildren(p) ? pointByLight(p, rng.next(), a, b) : h_[p].pointAt(a, b);
        pts[i] = q + sc.polygons[size_t(p)].normal * lift_;
        if (faces) faces[i] = p;
    }
}

double Refiner::drawnWeight(const Vec3& x, const Vec3& nx, const Vec3& y, int yFace, const NodeSampler& s,
                            const Vec3& toward) const {
    const Vec3& ny = h_.scene().polygons[size_t(yFace)].normal;
    const double k = pointKernel(x, nx, y, ny);
    if (k <= 0) return 0;
    // The face was drawn by its light toward `toward` (cos / r^2 at its centre, NodeSampler), or by
    // projected area (cos) before any face had light; within the face by its parts' light or by area, as the
    // kernel wants.
    const Vec3 dc = toward - h_[yFace].center;
    const double rc2 = std::max(length2(dc), 1e-300);
    const double cc = dot(ny, dc) / std::sqrt(rc2);
    if (!(cc > 0)) return 0;
    return k / (s.byLight ? cc / rc2 : cc);
}

bool Refiner::fromInsideSolid(int face, const Vec3& sourcePoint, const Vec3& receiverPoint) const {
    if (!footprint_[size_t(face)]) return false;
    const Vec3 d = receiverPoint - sourcePoint;
    const double len = length(d);
    return len > 0 && rays_.metFromBehind(h_.scene(), sourcePoint, d * (1.0 / len), len);
}

bool Refiner::sampleNode(int node, const Vec3& toward, bool receiver, uint64_t seed, int n,
                         Vec3* pts, int* faces) const {
    const Scene& sc = h_.scene();
    if (!isClusterNode(node)) {
        Rng rng(seed, settings_.seed);
        const Element& e = h_[node];
        int m = std::max(1, int(std::lround(std::sqrt(double(n)))));
        const Vec3 lift = sc.polygons[e.polygon].normal * lift_;
        for (int i = 0; i < n; ++i) {
            int a = i % (m * m);
            pts[i] = e.pointAt((a % m + rng.next()) / m, (a / m + rng.next()) / m) + lift;
            if (faces) faces[i] = e.polygon;
        }
        return true;
    }
    thread_local NodeSampler sampler;
    if (!buildSampler(node, toward, receiver, sampler)) return false;
    drawFromSampler(sampler, seed, n, pts, faces);
    return true;
}

bool Refiner::shareByFaces(int ri, int si, bool nearSource) {
    // Opening such a cluster made half the links of the 5k office at epsilon 0.002 (each face then linked on
    // its own, with 16 rays, often through more opened sub-clusters); the link's whole transfer is within
    // the threshold already, so what each face needs is only its own share, and a few rays give it without
    // the bias of one share for all. Measured against a fine solve of the 1k office at epsilon 0.002: links
    // 280k -> 186k, RMS 7.49 -> 7.47 %.
    const ClusterTree& ct = h_.clusters();
    const Cluster& c = ct[clusterIndex(ri)];
    int k = c.end - c.begin;
    if (k > kMaxSharedFaces) return false;
    const Scene& sc = h_.scene();
    std::vector<float> share(size_t(k), 0.0f);
    uint64_t seed = nodeKey(h_, ri) ^ (nodeKey(h_, si) * 0x9E3779B97F4A7C15ull) ^ 0x5bd1e995ull;
    // A cluster source is drawn by the light it sends toward the receiver's centre, once for all its faces
    // (toward each face's own centre it cost |r| x |s| per link, 11 % of the 10k office's first pass); the
    // source is in its far field, so the directions differ little. A near source is drawn toward each face.
    thread_local NodeSampler sampler;
    const bool clusterSource = isClusterNode(si);
    // None of its faces turned toward the receiver's centre: every share stays 0, as when each face's own
    // draw found none.
    const bool anySource = !clusterSource || nearSource || buildSampler(si, nodeCenter(h_, ri), false, sampler);
    // Every face's rays are cast together: one face's few rays alone filled a quarter of a 16-wide packet
    // (an Embree packet costs nearly the same with 4 lanes as with 16).
    // Each ray counts by its kernel over the density its source point was drawn with (drawnWeight), so a face's
    // share is that of the light it gets, as a standard link's V is (estimateVisibility). Counted alike, the
    // rays under-read a floor among furniture, which hides the low, oblique directions that carry little
    // light and leaves the steep ones open: with every albedo a hundredth of its own, the 5k office at epsilon
    // 0.002 absorbed 98.4 % of its lamps' light (the floor 3.3 % short of the default epsilon's), and 99.6 %
    // with the rays weighted (native/python/test_energy_balance.py). At the scenes' own albedos the links are
    // finer and the five benchmark rooms moved by at most 0.07 points against Cycles.
    thread_local std::vector<Vec3> from, to;
    thread_local std::vector<int> start;
    thread_local std::vector<double> weight;
    thread_local std::vector<int> sourceFace;
    from.clear();
    to.clear();
    weight.clear();
    sourceFace.clear();
    start.assign(size_t(k) + 1, 0);
    const Vec3 clusterToward = nodeCenter(h_, ri);
    const Vec3 sourceNormal = clusterSource ? Vec3{} : sc.polygons[size_t(h_[si].polygon)].normal;
    for (int j = 0; anySource && j < k; ++j) {
        start[size_t(j)] = int(from.size());
        int p = ct.polygons()[size_t(c.begin + j)];
        const ScenePolygon& sp = sc.polygons[size_t(p)];
        if (!receivesLight(sp) || h_.buried(p)) continue;
        const Element& e = h_[p];
        Vec3 toFace[kFaceRays];
        int fromFace[kFaceRays] = {};
        uint64_t faceSeed = seed + uint64_t(j) * 7919u;
        if (clusterSource) {
            if (nearSource && !buildSampler(si, e.center, false, sampler)) continue;
            drawFromSampler(sampler, faceSeed, kFaceRays, toFace, fromFace);
        } else if (!sampleNode(si, e.center, false, faceSeed, kFaceRays, toFace, fromFace)) {
            continue;
        }
        Rng rng(seed ^ (uint64_t(j) + 1) * 0xBF58476D1CE4E5B9ull, settings_.seed);
        for (int i = 0; i < kFaceRays; ++i) {
            Vec3 f = e.pointAt((i % 2 + rng.next()) / 2, (i / 2 % 2 + rng.next()) / 2) + sp.normal * lift_;
            // A source point behind the face sends it nothing (its form factor is zero there); a ray to it
            // would only meet the face's own polygon.
            if (dot(sp.normal, toFace[i] - f) <= 0) continue;
            from.push_back(f);
            to.push_back(toFace[i]);
            sourceFace.push_back(fromFace[i]);
            weight.push_back(clusterSource ? drawnWeight(f, sp.normal, toFace[i], fromFace[i], sampler,
                                                         nearSource ? e.center : clusterToward)
                                           : pointKernel(f, sp.normal, toFace[i], sourceNormal));
        }
    }
    start[size_t(k)] = int(from.size());
    int n = int(from.size());
    if (n > 0) {
        thread_local std::vector<char> vis;
        vis.resize(size_t(n));
        rays_.visiblePairs(from.data(), to.data(), n, vis.data(), !emits(si));
        counters_.add(kRays, size_t(n));
        counters_.add(kRaysCluster, size_t(n));
        for (int i = 0; i < n; ++i)
            if (!vis[size_t(i)] && fromInsideSolid(sourceFace[size_t(i)], to[size_t(i)], from[size_t(i)]))
                weight[size_t(i)] = kLeftOut;
        // A face whose every ray began inside a solid (four points of a tile half under a slab, one time in
        // sixteen) takes the share of all the faces' counted rays, not none.
        int seen;
        const double all = std::max(0.0, weightedShare(vis.data(), weight, 0, n, seen));
        for (int j = 0; j < k; ++j) {
            int a = start[size_t(j)], b = start[size_t(j + 1)];
            if (b <= a) continue;
            const double f = weightedShare(vis.data(), weight, a, b, seen);
            share[size_t(j)] = float(f == kLeftOut ? all : f);
        }
    }
    counters_.add(kSharedClusterLinks);
    faceVis_.record(nodeKey(h_, ri), nodeKey(h_, si), share.data(), share.size());
    return true;
}

bool Refiner::sharesFaces(int si) const {
    if (!isClusterNode(si)) return false;
    const Cluster& c = h_.clusters()[clusterIndex(si)];
    // An emitter's light is drawn at every texel with the visibility its links give (the final gather), which
    // wants a link's full rays: a cluster with a lamp is opened as before.
    return c.end - c.begin <= kMaxSharedFaces && !clusterEmits_[size_t(clusterIndex(si))];
}

bool Refiner::shareSourceByFaces(int ri, int si, Link& l) {
    const ClusterTree& ct = h_.clusters();
    const Cluster& c = ct[clusterIndex(si)];
    const int k = c.end - c.begin;
    const Scene& sc = h_.scene();
    const Element& r = h_[ri];
    const Vec3& nr = sc.polygons[size_t(r.polygon)].normal;
    uint64_t seed = nodeKey(h_, ri) ^ (nodeKey(h_, si) * 0x9E3779B97F4A7C15ull) ^ 0x2545F4914F6CDD1Dull;
    // Every face's rays are cast together, as in shareByFaces: kFaceRays from the receiver's quarters to
    // points of the face, each counted by its kernel (drawn by area at both ends).
    thread_local std::vector<Vec3> from, to;
    thread_local std::vector<int> start;
    thread_local std::vector<double> weight;
    from.clear();
    to.clear();
    weight.clear();
    start.assign(size_t(k) + 1, 0);
    bool facing = false;
    for (int j = 0; j < k; ++j) {
        start[size_t(j)] = int(from.size());
        int p = ct.polygons()[size_t(c.begin + j)];
        const ScenePolygon& sp = sc.polygons[size_t(p)];
        if (!sendsLight(sp)) continue;
        const Element& e = h_[p];
        // Light leaves the face's front and enters the receiver's: some corner of each in front of the other.
        bool sInFront = false, rInFront = false;
        for (int q = 0; q < e.n; ++q) sInFront |= dot(e.v[q] - r.v[0], nr) > lift_;
        for (int q = 0; q < r.n; ++q) rInFront |= dot(r.v[q] - e.v[0], sp.normal) > lift_;
        if (!sInFront || !rInFront) continue;
        facing = true;
        Rng rng(seed ^ (uint64_t(j) + 1) * 0xBF58476D1CE4E5B9ull, settings_.seed);
        for (int i = 0; i < kFaceRays; ++i) {
            Vec3 f = r.pointAt((i % 2 + rng.next()) / 2, (i / 2 % 2 + rng.next()) / 2) + nr * lift_;
            Vec3 t = e.pointAt(rng.next(), rng.next()) + sp.normal * lift_;
            if (dot(nr, t - f) <= 0 || dot(sp.normal, f - t) <= 0) continue;
            from.push_back(f);
            to.push_back(t);
            weight.push_back(pointKernel(f, nr, t, sp.normal));
        }
    }
    start[size_t(k)] = int(from.size());
    const int n = int(from.size());
    if (n == 0 && facing) return false;  // faces in front, yet no ray between them: leave it to the opening
    thread_local std::vector<char> vis;
    vis.resize(size_t(n));
    if (n > 0) {
        rays_.visiblePairs(from.data(), to.data(), n, vis.data(), true);
        counters_.add(kRays, size_t(n));
        counters_.add(kRaysCluster, size_t(n));
        for (int j = 0; j < k; ++j) {
            const int p = ct.polygons()[size_t(c.begin + j)];
            for (int i = start[size_t(j)]; i < start[size_t(j + 1)]; ++i)
                if (!vis[size_t(i)] && fromInsideSolid(p, to[size_t(i)], from[size_t(i)])) weight[size_t(i)] = kLeftOut;
        }
    }
    // Each face's weight is its visible share times its form factor averaged over the receiver's quadrature
    // points: at the receiver's centre alone, the inside of the corpus's open safe, lit by its facing walls about
    // a width away, came out 6.7 % of the peak off the face-by-face solve (2.5 % opened), whatever the rays.
    std::vector<float> faceWeight(size_t(k), 0.0f);
    Vec3 pts[4];
    const int np = samplePoints(r, pts);
    int seenAll = 0;
    int seen;
    const double all = n > 0 ? std::max(0.0, weightedShare(vis.data(), weight, 0, n, seen)) : 0.0;
    for (int j = 0; j < k; ++j) {
        int a = start[size_t(j)], b = start[size_t(j + 1)];
        if (b <= a) continue;
        double share = weightedShare(vis.data(), weight, a, b, seen);
        // Every ray of the face began inside a solid: the share of all the faces' counted rays (as shareByFaces).
        if (share == kLeftOut) share = all, seen = share > 0;
        if (seen == 0) continue;
        seenAll += seen;
        int p = ct.polygons()[size_t(c.begin + j)];
        double f = 0;
        for (int q = 0; q < np; ++q) f += elementKernel(h_[p], sc.polygons[size_t(p)].normal, pts[q], &nr);
        faceWeight[size_t(j)] = float(share * f / np);
    }
    l.receiver = ri;
    l.source = si;
    l.Fmean = 0;
    l.Fspread = kSourceShared;
    l.V = n > 0 ? float(double(seenAll) / n) : 0.0f;  // 0: nothing gets through, and countLink drops it
    if (l.V > 0) {
        counters_.add(kSourceSharedLinks);
        srcFaceVis_.record(nodeKey(h_, ri), nodeKey(h_, si), faceWeight.data(), faceWeight.size());
    }
    return true;
}

bool Refiner::facesToward(int node, const Bounds& other, bool receiver) const {
    if (!isClusterNode(node)) return true;
    const Scene& sc = h_.scene();
    const ClusterTree& ct = h_.clusters();
    const Cluster& c = ct[clusterIndex(node)];
    for (int k = c.begin; k < c.end; ++k) {
        int p = ct.polygons()[k];
        const ScenePolygon& sp = sc.polygons[p];
        if (receiver ? !receivesLight(sp) || h_.buried(p) : !sends(p)) continue;
        for (int corner = 0; corner < 8; ++corner) {
            Vec3 q{corner & 1 ? other.hi.x : other.lo.x, corner & 2 ? other.hi.y : other.lo.y,
                   corner & 4 ? other.hi.z : other.lo.z};
            if (dot(sp.normal, q - h_[p].center) > 0) return true;
        }
    }
    return false;
}

bool Refiner::estimateCluster(int ri, int si, Link& l) {
    l.receiver = ri;
    l.source = si;
    l.Fmean = l.Fspread = 0;  // cluster transfers are evaluated from the faces at gather time
    int n = std::min(strata_ * strata_, 256);
    // In the first pass no reflector has radiosity yet, so its links' bounds say nothing of what they will
    // carry and its faces cannot be drawn by their light: a few rays by area stand in until the next pass,
    // which estimates again, with the solved radiosities, the links whose bound then matters (rerefine).
    if (firstPass_ && settings_.refinePasses > 1 && !emits(si)) {
        n = std::min(n, kProvisionalRays);
        l.Fspread = kProvisional;
    }
    Vec3 from[256], to[256];
    uint64_t seed = nodeKey(h_, ri) ^ (nodeKey(h_, si) * 0x9E3779B97F4A7C15ull);
    // No face of one end turned toward the other: nothing flows, no link.
    if (!sampleNode(ri, nodeCenter(h_, si), true, seed, n, from)) return false;
    int toFace[256];
    if (!sampleNode(si, nodeCenter(h_, ri), false, seed * 31 + 7, n, to, toFace)) return false;
    // A shaft between two clusters holds their own faces, so it was never found clear (rays only).
    // A ray from a reflector's point under something standing on it counts no more than an element link's
    // (estimateVisibility): the 5k office's floor gave the rest of the room 98.5 % of what it reflects with
    // such rays counted in its cluster links and face shares, 99.6 % without (a temporary probe gathering
    // the floor's solved light alone).
    char vis[256];
    rays_.visiblePairs(from, to, n, vis, !emits(si));
    int seen = 0, counted = 0;
    for (int i = 0; i < n; ++i) {
        if (!vis[i] && fromInsideSolid(toFace[i], to[i], from[i])) continue;
        ++counted;
        seen += vis[i];
    }
    l.V = counted > 0 ? float(double(seen) / counted) : 0.0f;
    counters_.add(kRays, size_t(n));
    counters_.add(kRaysCluster, size_t(n));
    return true;
}

void Refiner::refineElements(int ri, int si, std::vector<Link>& out) {
    if (tryConvolution(ri, si)) return;
    Link l;
    if (!estimateUnoccluded(ri, si, l)) return;
    bool canR = canSplit(ri), canS = canSplit(si);
    // The kernel is integrated exactly over the source (Lambert's formula), so an unoccluded transfer
    // of a uniform source only errs through the irradiance varying across the receiver: only
    // splitting the receiver reduces that. A source whose parts differ in radiosity (a ceiling bright
    // only over a lamp) errs by how its light and the kernel are distributed over it, which only
    // linking its parts reduces; they exist already (it was split as a receiver). At a receiver that
    // cannot split, its own part of the error is there to stay and must not hide the source's: a monitor
    // stand's front (under min_size) standing on a desk took the whole desk's mean light where the desk is
    // darkest, because its corners in the desk's plane made the form factor's spread (0.5) outweigh the
    // desk's deviation (the 5k scaling office against Cycles, docs/benchmark.md, stop 35).
    double dev = gradientError(l);
    if (dev > threshold_ && (dev >= linkError(l) || (!canR && partsDiffer(si))) && hasSettledChildren(si)) {
        int c = h_.firstChild(si);
        for (int k = 0; k < h_[si].numChildren; ++k) refine(ri, c + k, out);
        return;
    }
    if (linkError(l) > threshold_ && canR) {
        int c = h_.subdivide(ri);
        for (int k = 0; k < h_[ri].numChildren; ++k) refine(c + k, si, out);
        return;
    }
    // Rays are spent only once the unoccluded transfer is accurate enough to be linked.
    estimateVisibility(ri, si, l);
    if (l.partial() && linkError(l) > threshold_ && !canR) {
        // The receiver is as small as it may get and holds one value whatever the source's parts do:
        // splitting the source only shares the same error among more links (a lamp cut to min_size
        // for every receiver in its penumbra: a third of a furnished room's links). What the split
        // would buy, a finer estimate of the visible share, as many rays on the one link buy for less:
        // the split made about error/threshold parts of 16 rays each.
        double ratio = linkError(l) / threshold_;
        int batches = int(std::clamp(std::ceil(kRaysPerShare * ratio / 256), 1.0, double(kMaxBatches)));
        // Light from an emitter is shown through the final gather's visibility, which this link's V
        // sets: it takes the whole budget (a lattice shade's error grew from 0.78 to 1.15 % RMS when
        // it too stopped early). A reflector's light reaches the lightmap summed with many others'
        // whose errors are independent: it stops once its own standard error is within the threshold.
        double spread = std::max(double(l.Fspread), double(l.Fmean));
        bool emitter = maxComponent(h_.scene().polygons[h_[si].polygon].emission) > 0;
        estimateVisibility(ri, si, l, batches, !emitter && spread > 0 ? linkError(l) * l.Fmean / spread : 0.0);
        keep(l, out);
        return;
    }
    if (linkError(l) <= threshold_ || !l.partial() || (!canR && !canS)) {
        // Hidden transfers are kept too (F = 0): the final gather's visibility is the linked light
        // over the unoccluded light, and a hidden transfer must count in the second.
        if (l.Fmean > 0) keep(l, out);
        return;
    }
    // Partial visibility: either side's split narrows down where the shadow boundary runs.
    if (canR && (!canS || notSmaller(h_[ri].area, h_[si].area))) {
        int c = h_.subdivide(ri);
        for (int k = 0; k < h_[ri].numChildren; ++k) refine(c + k, si, out);
    } else {
        int c = h_.subdivide(si);
        for (int k = 0; k < h_[si].numChildren; ++k) refine(ri, c + k, out);
    }
}

std::vector<Link> Refiner::linkAll(Progress* progress) {
    std::vector<Link> links = h_.clusters().empty() ? linkFacePairs(progress) : linkFromRoot(progress);
    faceVis_.finish(resolveThreads(settings_.threads));
    srcFaceVis_.finish(resolveThreads(settings_.threads));
    return links;
}

std::vector<Link> Refiner::linkFromRoot(Progress* progress) {
    linkCount_ = 0;
    firstPass_ = true;
    int threads = resolveThreads(settings_.threads);
    int root = clusterNode(0);
    std::vector<Link> links;
    std::vector<std::pair<int, int>> frontier{{root, root}}, ready;
    // The top of the refinement runs on one thread until there are enough independent pairs to
    // share out; the split decisions do not depend on the thread count, so neither do the links.
    const size_t wanted = 256;
    while (!frontier.empty() && frontier.size() + ready.size() < wanted) {
        std::vector<std::pair<int, int>> next;
        for (auto [r, s] : frontier) {
            if (isClusterNode(r) || isClusterNode(s))
                refineCluster(r, s, links, &next);
            else
                ready.push_back({r, s});
        }
        frontier.swap(next);
    }
    ready.insert(ready.end(), frontier.begin(), frontier.end());
    std::vector<std::vector<Link>> perPair(ready.size());
    std::atomic<size_t> done{0};
    ProgressPoll poll(progress, "refine");
    parallelForDynamic(ready.size(), threads, 1, [&](size_t b, size_t e, int t) {
        for (size_t i = b; i < e && !poll.cancelled(); ++i) {
            if (poll.stop(t, double(done) / ready.size())) break;
            try {
                refine(ready[i].first, ready[i].second, perPair[i]);
            } catch (...) {
                poll.cancel();
                throw;
            }
            ++done;
        }
    });
    firstPass_ = false;
    if (poll.cancelled()) throw Cancelled();
    appendParts(links, perPair);
    return links;
}

std::vector<Link> Refiner::linkFacePairs(Progress* progress) {
    const Scene& sc = h_.scene();
    size_t roots = h_.numRoots();
    std::vector<int> receivers, sources;
    for (size_t i = 0; i < roots; ++i) {
        const ScenePolygon& p = sc.polygons[i];
        if (receivesLight(p)) receivers.push_back(int(i));
        if (sendsLight(p)) sources.push_back(int(i));
    }
    // Without clusters every receiving face meets every source face at the root level: this product
    // is a floor on the work, so a scene far past it is refused up front rather than left running.
    double pairs = double(receivers.size()) * double(sources.size());
    if (pairs > settings_.maxFacePairs)
        throw BudgetExceeded("work guard: " + std::to_string(receivers.size()) + " receiving x " +
                             std::to_string(sources.size()) + " sending faces make " +
                             std::to_string(pairs) + " face pairs, more than max_face_pairs = " +
                             std::to_string(settings_.maxFacePairs) +
                             " with clustering off; turn clustering on, bake fewer or simpler objects, "
                             "or raise max_face_pairs");
    linkCount_ = 0;
    std::vector<std::vector<Link>> perReceiver(receivers.size());
    std::atomic<size_t> done{0};
    int threads = resolveThreads(settings_.threads);
    ProgressPoll poll(progress, "refine");
    parallelFor(receivers.size(), threads, 4, [&](size_t b, size_t e, int t) {
        for (size_t i = b; i < e && !poll.cancelled(); ++i) {
            try {
                for (int s : sources) {
                    if (poll.stop(t, double(done) / receivers.size())) break;
                    if (s != receivers[i]) refine(receivers[i], s, perReceiver[i]);
                }
            } catch (...) {
                poll.cancel();  // a budget was hit: the other threads stop at their next face
                throw;
            }
            ++done;
        }
    });
    if (poll.cancelled()) throw Cancelled();
    std::vector<Link> links;
    appendParts(links, perReceiver);
    return links;
}

void Refiner::rerefine(std::vector<Link>& links, Progress* progress, bool& changed, bool reweigh) {
    settled_ = h_.size();
    lightNodes_.resize(settled_);
    parallelFor(settled_, resolveThreads(settings_.threads), 4096, [&](size_t b, size_t e, int) {
        for (size_t i = b; i < e; ++i) {
            const Element& el = h_[int(i)];
            bool settled = hasSettledChildren(int(i));
            lightNodes_[i] = {maxComponent(el.B) * el.area, settled ? h_.firstChild(int(i)) : -1,
                              settled ? el.numChildren : 0};
        }
    });
    // Kept links stay where they are and the parts hold only what replaced links are refined into: a
    // fresh copy of every link per pass (input, parts and result alive at once) was the solve's peak.
    std::vector<std::vector<Link>> out(links.size() / 256 + 1);
    std::vector<uint8_t> replaced(links.size(), 0);
    std::atomic<bool> anyChange{false};
    ProgressPoll poll(progress, "refine");
    linkCount_ = 0;
    std::atomic<size_t> done{0};
    size_t chunks = out.size();
    parallelForDynamic(chunks, resolveThreads(settings_.threads), 1, [&](size_t b, size_t e, int t) {
        for (size_t c = b; c < e && !poll.cancelled(); ++c) {
            size_t lo = c * 256, hi = std::min(links.size(), lo + 256);
            try {
                for (size_t i = lo; i < hi; ++i) {
                    if (poll.stop(t, double(done) / chunks)) break;
                    Link& l = links[i];
                    if (provisional(l)) {
                        l.Fspread = 0;
                        if (linkError(l) > kProvisionalKept * threshold_) {
                            anyChange = true;
                            replaced[i] = 1;
                            refine(l.receiver, l.source, out[c]);
                            continue;
                        }
                    }
                    // A hidden transfer stays hidden whatever its sources' radiosities become.
                    // A link whose source's parts now differ in light is estimated again (by light,
                    // estimateVisibility) even where its error alone would keep it.
                    bool deviates = sourceDeviationError(l) > threshold_ || gradientError(l) > threshold_;
                    // A partly seen element source is never split for a receiver at min_size
                    // (refineElements); a cluster source still opens.
                    bool splittable = l.V > 0 && (canSplit(l.receiver) || (l.partial() && isClusterNode(l.source)) || deviates);
                    if ((linkError(l) > threshold_ || deviates) && splittable) {
                        anyChange = true;
                        replaced[i] = 1;
                        refine(l.receiver, l.source, out[c]);
                    } else if (!countLink(l)) {
                        replaced[i] = 1;
                    } else if (reweigh && !isClusterNode(l.source) && !isClusterNode(l.receiver) && !provisional(l) &&
                               l.Fmean > 0 && hasSettledChildren(l.source) &&
                               receiverRho(l.receiver) * h_[l.source].Bdev * l.F() > 0.1 * threshold_) {
                        // A kept link's form factor is weighted by its source's parts as they were lit when
                        // it was made (estimateUnoccluded), a link made in the first pass not at all, while
                        // links made now into the same source take its parts' light of now: what the
                        // receivers take from each part no longer sums to what the part sends. A closed 2 m
                        // room without clustering lost 1.08 % of its light that way at epsilon 0.002, and
                        // 0.01 % with every kept link weighted again by the parts' present light. Only before
                        // the last solve (at every pass it cost the 100k office 5 % more CPU), and only links
                        // whose light could move by a tenth of the threshold (rho B_dev F: the parts' spread
                        // bounds how far the weight can move), which keeps the 20k office's refinement at its
                        // time without them (all of them: 3 % more, its balance the same to 0.01 %).
                        l.Fmean = float(weightedMean(l.receiver, l.source));
                    }
                }
            } catch (...) {
                poll.cancel();
                throw;
            }
            ++done;
        }
    });
    if (poll.cancelled()) throw Cancelled();
    changed = anyChange;
    size_t kept = 0;
    for (size_t i = 0; i < links.size(); ++i)
        if (!replaced[i]) links[kept++] = links[i];
    links.resize(kept);
    std::vector<uint8_t>().swap(replaced);
    appendParts(links, out);
    faceVis_.finish(resolveThreads(settings_.threads));
    srcFaceVis_.finish(resolveThreads(settings_.threads));
}

}  // namespace penumbra
