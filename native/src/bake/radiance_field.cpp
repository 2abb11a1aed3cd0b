#include "bake/radiance_field.h"

#include <algorithm>
#include <cmath>

#include "hierarchy/predicates.h"

namespace penumbra {

namespace {

// How far a point on any triangulation of a polygon's input face can sit from the plane of one of the
// face's elements: the spread of the input face's corners along that element's normal. Zero for
// triangles; up to the planarity check's 1e-4 for quads kept whole; the warp for quads the scene split,
// whose caller (Blender's loop triangles) may cut along the other diagonal.
std::vector<double> faceThickness(const Scene& sc) {
    std::vector<std::vector<int>> byInput;
    for (size_t i = 0; i < sc.polygons.size(); ++i) {
        size_t in = size_t(std::max(sc.polygons[i].input, 0));
        if (in >= byInput.size()) byInput.resize(in + 1);
        byInput[in].push_back(int(i));
    }
    std::vector<double> out(sc.polygons.size(), 0.0);
    for (const auto& group : byInput)
        for (int i : group) {
            const ScenePolygon& p = sc.polygons[i];
            double lo = HUGE_VAL, hi = -HUGE_VAL;
            for (int j : group)
                for (int k = 0; k < sc.polygons[j].geom.n; ++k) {
                    double d = dot(sc.polygons[j].geom.v[k], p.normal);
                    lo = std::min(lo, d);
                    hi = std::max(hi, d);
                }
            out[i] = hi - lo;
        }
    return out;
}

}  // namespace

RadianceField::RadianceField(const Hierarchy& h) { init(h, nullptr, nullptr, nullptr); }

RadianceField::RadianceField(const Hierarchy& h, const std::vector<Rgb>& textured, ConvolutionField conv)
    : conv_(std::move(conv)) {
    init(h, textured.size() == h.size() ? &textured : nullptr, nullptr, nullptr);
}

RadianceField::RadianceField(const Hierarchy& h, const std::vector<Rgb>& textured, ConvolutionField conv,
                             const std::vector<Rgb>& shadowed, const std::vector<Rgb>& unoccluded,
                             std::shared_ptr<const DirectLight> direct, std::shared_ptr<const LightSet> lights,
                             const std::vector<Rgb>& lightE)
    : conv_(std::move(conv)), direct_(std::move(direct)) {
    bool ok = shadowed.size() == h.size() && unoccluded.size() == h.size();
    bool lit = ok && lights && !lights->empty() && lightE.size() == h.size();
    init(h, textured.size() == h.size() ? &textured : nullptr, ok ? &shadowed : nullptr, ok ? &unoccluded : nullptr,
         lit ? &lightE : nullptr);
    if (!ok) direct_.reset();
    if (lit) lights_ = std::move(lights);
}

void RadianceField::init(const Hierarchy& h, const std::vector<Rgb>* textured, const std::vector<Rgb>* shadowed,
                         const std::vector<Rgb>* unoccluded, const std::vector<Rgb>* lightE) {
    const Scene& sc = h.scene();
    scene_ = &sc;
    diagonal_ = sc.diagonal;
    nudge_ = 1e-7 * diagonal_;
    // A point handed in lies on its own surface up to float32 rounding of the caller's coordinates
    // (a few ulps of the largest input coordinate, which is large for a scene far from the origin) and
    // double rounding here. Anything further off a leaf's plane is another surface: a face 1 mm above a
    // floor is a different surface however coarse the floor's leaves are, so this does not grow with
    // the leaf.
    double onPlane = 1e-5 * diagonal_ + float32Rounding(sc);
    std::vector<double> thickness = faceThickness(sc);
    polyTol_.assign(sc.polygons.size(), 0.0);
    centroids_.resize(sc.polygons.size());
    for (size_t i = 0; i < sc.polygons.size(); ++i) centroids_[i] = sc.polygons[i].geom.centroid();
    std::vector<Bounds> polyBoxes;
    for (size_t i = 0; i < sc.polygons.size(); ++i) {
        const ScenePolygon& p = sc.polygons[i];
        polyTol_[i] = onPlane + thickness[i];
        if (!p.receives) continue;
        Bounds b = polygonBox(p);
        double t = 2 * polyTol_[i];
        b.extend(b.lo - Vec3{t, t, t});
        b.extend(b.hi + Vec3{t, t, t});
        polyBoxes.push_back(b);
        located_.push_back(int(i));
    }
    polygonBoxes_ = BoxTree(std::move(polyBoxes));
    for (size_t i = 0; i < h.size(); ++i) {
        const Element& e = h[i];
        if (!e.isLeaf()) continue;
        const ScenePolygon& p = sc.polygons[e.polygon];
        if (!p.receives) continue;
        Leaf l;
        l.normal = p.normal;
        l.center = e.center;
        if (e.n == 4) {
            l.e1 = (e.v[1] + e.v[2] - e.v[0] - e.v[3]) * 0.25;
            l.e2 = (e.v[2] + e.v[3] - e.v[0] - e.v[1]) * 0.25;
        } else {
            // Frame of the triangle's bounding parallelogram: half its longest edge, half its height.
            int k = 0;
            double best = -1;
            for (int j = 0; j < 3; ++j) {
                double len = length2(e.v[(j + 1) % 3] - e.v[j]);
                if (len > best) { best = len; k = j; }
            }
            Vec3 a = e.v[k], b = e.v[(k + 1) % 3], c = e.v[(k + 2) % 3];
            l.e1 = (b - a) * 0.5;
            l.e2 = (c - (a + b) * 0.5) * 0.5;
        }
        l.g11 = dot(l.e1, l.e1);
        l.g12 = dot(l.e1, l.e2);
        l.g22 = dot(l.e2, l.e2);
        l.det = l.g11 * l.g22 - l.g12 * l.g12;
        if (!(l.det > 0)) continue;
        l.reach = length(l.e1) + length(l.e2);
        double r = 2.0 * l.reach;
        l.planeTol = onPlane + thickness[e.polygon];
        // Weighted points are within a = 0.875 r of the centre in the plane and, across a fold of up to
        // 26 degrees (the normal test), within 0.44 |p - c| + planeTol of it across, which puts them
        // within 1.11 a + 1.78 planeTol of the centre.
        double ext1 = r + 2 * l.planeTol;
        Vec3 ext{ext1, ext1, ext1};
        l.support.extend(l.center - ext);
        l.support.extend(l.center + ext);
        l.value = (e.B - p.emission) / M_PI;
        if (textured) l.value = vmax(Rgb{}, l.value - (*textured)[i] / M_PI);
        l.indirect = shadowed ? vmax(Rgb{}, l.value - mul(p.rho, (*shadowed)[i]) / M_PI) : l.value;
        if (lightE) l.indirect = vmax(Rgb{}, l.value - mul(p.rho, (*shadowed)[i] + (*lightE)[i]) / M_PI);
        // No linked light from any emitter at all (a face under a box, a sealed room): nothing is
        // known to be visible, so nothing is.
        l.vis = Rgb{};
        if (shadowed)
            for (int c = 0; c < 3; ++c)
                if ((*unoccluded)[i][c] > 0) l.vis[c] = std::clamp((*shadowed)[i][c] / (*unoccluded)[i][c], 0.0, 1.0);
        for (int c = 0; c < 3; ++c) l.invRho[c] = p.rho[c] > 0 ? 1.0 / p.rho[c] : 0.0;
        l.group = conv_.polygonGroup(e.polygon);
        l.surface = p.surface;
        leaves_.push_back(l);
    }
    std::vector<Bounds> boxes;
    boxes.reserve(leaves_.size());
    for (const Leaf& l : leaves_) boxes.push_back(l.support);
    supports_ = BoxTree(std::move(boxes));
}

double RadianceField::weight(const Leaf& l, const Vec3& p, const Vec3& n) const {
    if (dot(l.normal, n) < 0.9) return 0;  // another surface (a wall meeting the floor)
    Vec3 d = p - l.center;
    double off = dot(d, l.normal);
    if (std::fabs(off) > l.planeTol && !acrossFold(l, d, off, n)) return 0;  // a parallel surface nearby
    double b1 = dot(d, l.e1), b2 = dot(d, l.e2);
    double s = (l.g22 * b1 - l.g12 * b2) / l.det, t = (l.g11 * b2 - l.g12 * b1) / l.det;
    // Support 1.75 half-widths: short of a same-size neighbour's centre, so leaf centres keep their own
    // value, and narrow enough that face averages are not flattened (2.0 measured 1.76 % against
    // Cycles on the Cornell box, 1.75 gives 1.64 %; 1.5 gives 1.58 % but point values lose 1 %).
    double ws = 1 - std::fabs(s) / 1.75, wt = 1 - std::fabs(t) / 1.75;
    return ws > 0 && wt > 0 ? ws * wt : 0;
}

// Facets of one tessellated curved surface meet at folds, and blending across them keeps the
// reconstruction continuous there. A point on the neighbouring facet, at distance a from the fold, is
// a sin(theta) off the leaf's plane, and the leaf's centre, at b from the fold on the other side, is
// b sin(theta) off the point's plane on the same side: the offsets agree in sign and are bounded by
// sin(theta) |p - c|. A parallel surface at height h gives offsets +h and -h instead, and a tilted one
// that does not reach the leaf also disagrees in sign, so both are refused.
bool RadianceField::acrossFold(const Leaf& l, const Vec3& d, double off, const Vec3& n) const {
    double back = -dot(d, n);  // the leaf centre's offset from the point's plane
    if (off > 0 ? back < -l.planeTol : back > l.planeTol) return false;
    double sinTheta = length(cross(l.normal, n));
    return std::fabs(off) <= sinTheta * length(d) + l.planeTol;
}

RadianceField::Region RadianceField::region(const Bounds& box) const {
    // Scanning more candidates than this per point costs more than the walk down the tree.
    const size_t maxScan = 128;
    Region r;
    r.box = box;
    if (box.empty()) return r;
    auto overlapsBox = [&](const Bounds& b) { return overlaps(b, box); };
    supports_.query(overlapsBox, [&](int i) { r.leaves.push_back(i); });
    polygonBoxes_.query(overlapsBox, [&](int i) { r.polygons.push_back(i); });
    r.scanLeaves = r.leaves.size() <= maxScan;
    r.scanPolygons = r.polygons.size() <= maxScan;
    if (!r.scanLeaves) r.leaves = {};
    if (!r.scanPolygons) r.polygons = {};
    return r;
}

int RadianceField::locate(const Vec3& p, const Vec3& n, const Region* region) const {
    const Scene& sc = *scene_;
    int best = -1;
    double bestMiss = HUGE_VAL;
    auto visit = [&](int i) {
        if (!contains(polygonBoxes_.box(i), p)) return;
        int q = located_[size_t(i)];
        const ScenePolygon& sp = sc.polygons[size_t(q)];
        if (dot(n, sp.normal) < 0.9) return;
        const Polygon& g = sp.geom;
        double tol = polyTol_[size_t(q)];
        double miss = std::fabs(dot(p - g.v[0], sp.normal));
        if (miss > tol) return;
        double outside = 0;
        for (int k = 0; k < g.n; ++k) {
            Vec3 inward = cross(sp.normal, g.v[(k + 1) % g.n] - g.v[k]);
            double len = length(inward);
            if (len > 0) outside = std::max(outside, -dot(p - g.v[k], inward) / len);
        }
        if (outside > 2 * tol) return;
        miss += outside;
        if (miss < bestMiss || (miss == bestMiss && q < best)) {
            bestMiss = miss;
            best = q;
        }
    };
    // Every polygon whose box holds p overlaps the region's box when p is inside it, and is on its list in
    // the tree's order.
    if (region && region->scanPolygons && contains(region->box, p)) {
        for (int i : region->polygons) visit(i);
    } else {
        polygonBoxes_.query([&](const Bounds& b) { return contains(b, p); }, visit);
    }
    return best;
}

Rgb RadianceField::radiance(const Vec3& p, const Vec3& n, bool irradiance) const {
    return radiance(p, n, irradiance, nullptr);
}

Rgb RadianceField::radiance(const Vec3& p, const Vec3& n, bool irradiance, const Region* region) const {
    int poly = locate(p, n, region);
    int surface = poly >= 0 ? scene_->polygons[size_t(poly)].surface : -1;
    bool gather = direct_ && poly >= 0;
    int group = 0;
    Rgb detail = conv_.empty() ? Rgb{} : conv_.radiance(p, n, &group, irradiance);
    Rgb vis{1, 1, 1};
    Rgb out = smooth(p, n, group, surface, gather, gather && !direct_->castsRays() ? &vis : nullptr, irradiance,
                     region) +
              detail;
    if (gather) {
        const ScenePolygon& sp = scene_->polygons[size_t(poly)];
        // A point on the polygon's edge lies in the plane of the face meeting it there (the wall
        // above a floor texel at the island border), which its form factor would see edge-on: the
        // light is the limit from inside, so the point is moved a hair toward the polygon's interior:
        // 1e-7 of the scene's size, a few float32 steps of a scene around the origin and the same
        // wherever the scene lies. 1e-5 moved a point 1.4 cm on a 1 km plane: 2 % of the light 1 m
        // from a lamp.
        Vec3 toward = centroids_[size_t(poly)] - p;
        toward = toward - sp.normal * dot(toward, sp.normal);
        double len = length(toward), nudge = nudge_;
        Vec3 q = len > nudge ? p + toward * (nudge / len) : p;
        const Rgb rho = irradiance ? Rgb{1, 1, 1} : sp.rho;
        out += mul(mul(rho, vis), direct_->irradiance(q, sp.normal, poly)) * (1.0 / M_PI);
        if (lights_) out += mul(rho, lights_->irradianceOn(poly, q, sp.normal)) * (1.0 / M_PI);
    }
    return out;
}

Rgb RadianceField::smooth(const Vec3& p, const Vec3& n, int group, int surface, bool indirectOnly, Rgb* vis,
                          bool irradiance, const Region* region) const {
    // A leaf's value is rho * E / pi with its own polygon's rho: dividing before the blend keeps a seam
    // between two materials of one surface from mixing one's albedo into the other's light.
    auto val = [&](const Leaf& l) {
        Rgb v = indirectOnly ? l.indirect : l.value;
        return irradiance ? mul(v, l.invRho) : v;
    };
    Rgb sum, vsum;
    double wsum = 0;
    auto containsP = [&](const Bounds& b) { return contains(b, p); };
    auto visit = [&](int i) {
        const Leaf& l = leaves_[i];
        if (l.group != group || (surface >= 0 && l.surface != surface) || !contains(l.support, p)) return;
        double w = weight(l, p, n);
        if (w > 0) {
            sum += val(l) * w;
            vsum += l.vis * w;
            wsum += w;
        }
    };
    // A support that holds p lies in a tree node that holds p, which overlaps the region's box when p is
    // inside it: the region's list has every such leaf, in the order of the walk (Region).
    if (region && region->scanLeaves && contains(region->box, p)) {
        for (int i : region->leaves) visit(i);
    } else {
        supports_.query(containsP, visit);
    }
    if (wsum > 0) {
        if (vis) *vis = vsum / wsum;
        return sum / wsum;
    }
    // The point lies off every leaf's support (a vertex of a modifier-displaced mesh, a face that
    // was too small to keep): take the nearest leaf facing the same way, searching wider boxes. Nearest
    // to the element rather than to its centre, so that a coarse leaf of a parallel surface whose
    // centre happens to be close does not beat the fine leaf the point is over; among leaves equally
    // near, the closest centre, then the lowest index, so the choice does not depend on rounding. A leaf
    // of the point's own group first; of any group only when there is none.
    const double band = 1e-18 * diagonal_ * diagonal_;
    for (bool strict : {true, false})
    for (double r = 1e-3 * diagonal_; r <= 4 * diagonal_; r *= 4) {
        Bounds box;
        box.extend(p - Vec3{r, r, r});
        box.extend(p + Vec3{r, r, r});
        double best = HUGE_VAL, bestCentre = HUGE_VAL;
        int bestLeaf = -1;
        supports_.query([&](const Bounds& b) { return overlaps(b, box); }, [&](int i) {
            const Leaf& l = leaves_[i];
            if ((strict && (l.group != group || (surface >= 0 && l.surface != surface))) || dot(l.normal, n) <= 0)
                return;
            Vec3 d = p - l.center;
            double off = dot(d, l.normal);
            double inPlane = std::sqrt(std::max(0.0, length2(d) - off * off));
            double excess = std::max(0.0, inPlane - l.reach);
            double d2 = off * off + excess * excess, c2 = length2(d);
            bool nearer = d2 < best - band ||
                          (d2 <= best + band && (c2 < bestCentre || (c2 == bestCentre && i < bestLeaf)));
            if (nearer) { best = d2; bestCentre = c2; bestLeaf = i; }
        });
        if (bestLeaf >= 0 && best <= r * r) {
            if (vis) *vis = leaves_[bestLeaf].vis;
            return val(leaves_[bestLeaf]);
        }
    }
    return Rgb{};
}

}  // namespace penumbra
