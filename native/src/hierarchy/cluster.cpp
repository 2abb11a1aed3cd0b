#include "hierarchy/cluster.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

#include "hierarchy/predicates.h"

namespace penumbra {
namespace {

constexpr size_t kLeafPolygons = 8;  // a cluster this small links its polygons directly
// A polygon whose box is at least this fraction of its cluster's box hangs there: splitting the
// cluster would not separate it from anything.
constexpr double kLargeFraction = 0.5;
// With planar groups on, a cluster first splits off the faces lying in one plane, when they are at least two,
// hold at least this share of its faces or of their area, and, among several objects, make up whole objects (a
// chair stays in one subtree, as a blocker should). A room modelled as one mesh then has its floor in one planar
// cluster, which takes one convolution link per lamp instead of one per spatial piece, and a triangulated floor
// or table top is one receiver. Smaller planes are split in space, so a mesh of many small planes (stairs, a
// tessellated sphere) keeps a balanced tree. Off by default: planar clusters are long and flat, not compact, so
// fewer of them are in each other's far field (the furnace box of 8 x 8 faces a wall, one object: 884 cluster
// links -> 0, links +1.2 %).
constexpr double kPlaneShareDivisor = 6;

int longestAxis(const Bounds& b) {
    Vec3 d = b.diagonal();
    return notSmaller(d.x, d.y) && notSmaller(d.x, d.z) ? 0 : (notSmaller(d.y, d.z) ? 1 : 2);
}

uint64_t clusterKey(int c) {
    uint64_t x = uint64_t(c) * 0x9E3779B97F4A7C15ull + 0xC1A5732Bull;
    x ^= x >> 31;
    x *= 0xBF58476D1CE4E5B9ull;
    return x ^ (x >> 29);
}

// The faces of `items` in the plane of largest area that may be split off (kPlaneShareDivisor), or empty.
// Planes are keyed by their normal and offset rounded to `tol`: a plane that straddles a rounding boundary
// falls into two groups, which only makes it less likely to be split off whole.
std::vector<int> planeToSplitOff(const Scene& scene, const std::vector<int>& items, double tol) {
    std::map<std::array<long long, 4>, std::vector<int>> planes;
    std::map<int, size_t> perObject;
    double total = 0;
    for (int p : items) {
        const ScenePolygon& sp = scene.polygons[size_t(p)];
        const Vec3& n = sp.normal;
        double d = dot(n, sp.geom.v[0]);
        planes[{std::llround(n.x * 1e4), std::llround(n.y * 1e4), std::llround(n.z * 1e4), std::llround(d / tol)}]
            .push_back(p);
        ++perObject[sp.object];
        total += sp.area;
    }
    const std::vector<int>* best = nullptr;
    double bestArea = 0;
    for (const auto& [key, group] : planes) {
        if (group.size() < 2 || group.size() == items.size()) continue;
        double area = 0;
        std::map<int, size_t> objects;
        for (int p : group) {
            area += scene.polygons[size_t(p)].area;
            ++objects[scene.polygons[size_t(p)].object];
        }
        if (double(group.size()) * kPlaneShareDivisor < double(items.size()) && area * kPlaneShareDivisor < total)
            continue;
        if (perObject.size() > 1 &&
            !std::all_of(objects.begin(), objects.end(), [&](const auto& o) { return perObject[o.first] == o.second; }))
            continue;
        if (!best || area > bestArea) {
            best = &group;
            bestArea = area;
        }
    }
    return best ? *best : std::vector<int>{};
}

}  // namespace

ClusterTree::ClusterTree(const Scene& scene, bool planarGroups) : planarGroups_(planarGroups) {
    owner_.assign(scene.polygons.size(), -1);
    std::vector<int> items;
    for (size_t i = 0; i < scene.polygons.size(); ++i) {
        const ScenePolygon& p = scene.polygons[i];
        if (receivesLight(p) || sendsLight(p)) items.push_back(int(i));
    }
    if (items.empty()) return;
    clusters_.emplace_back();
    build(scene, items, -1, 0, 0);
    // Normals equal to 1e-6 share a class (the faces of one box, a tiled floor).
    memberStart_.resize(clusters_.size());
    for (size_t c = 0; c < clusters_.size(); ++c) {
        Cluster& cl = clusters_[c];
        memberStart_[c] = memberClass_.size();
        cl.classBegin = int(classNormal_.size());
        std::map<std::array<long long, 3>, int> classes;
        for (int k = cl.begin; k < cl.end; ++k) {
            const Vec3& n = scene.polygons[size_t(polygons_[size_t(k)])].normal;
            std::array<long long, 3> key{std::llround(n.x * 1e6), std::llround(n.y * 1e6), std::llround(n.z * 1e6)};
            auto it = classes.find(key);
            if (it == classes.end()) {
                it = classes.emplace(key, int(classNormal_.size())).first;
                classNormal_.push_back(n);
            }
            memberClass_.push_back(it->second);
        }
        cl.classEnd = int(classNormal_.size());
        cl.blockBegin = int(classBlocks_.size());
        for (int m = cl.classBegin; m < cl.classEnd; m += 4) {
            ClassBlock b{};
            for (int lane = 0; lane < 4 && m + lane < cl.classEnd; ++lane) {
                const Vec3& n = classNormal_[size_t(m + lane)];
                b.nx[lane] = float(n.x);
                b.ny[lane] = float(n.y);
                b.nz[lane] = float(n.z);
            }
            classBlocks_.push_back(b);
        }
        cl.blockEnd = int(classBlocks_.size());
    }
    classFlux_.assign(classNormal_.size(), Rgb{});
}

// Fills slot c: own polygons first, then the children's, so that every subtree's polygons are one
// contiguous range. Slots are addressed by index: the vector grows during the recursion.
void ClusterTree::build(const Scene& scene, std::vector<int>& items, int parent, int c, int depth) {
    clusters_[c].parent = parent;
    clusters_[c].begin = int(polygons_.size());

    Bounds all;
    for (int p : items) all.extend(polygonBox(scene.polygons[p]));
    double diag = length(all.diagonal());
    std::vector<int> own, rest;
    bool oneObject = std::all_of(items.begin(), items.end(), [&](int p) {
        return scene.polygons[p].object == scene.polygons[items[0]].object;
    });
    std::vector<int> plane;
    if (planarGroups_ && items.size() > 2 && depth <= 60)
        plane = planeToSplitOff(scene, items, 1e-5 * std::max(diag, 1e-30));
    if (!plane.empty()) {
        rest = items;  // split below: the plane, and the others
    } else if ((items.size() <= kLeafPolygons && oneObject) || items.size() <= 2 || depth > 60) {
        own = items;
    } else {
        for (int p : items)
            (notSmaller(length(polygonBox(scene.polygons[p]).diagonal()), kLargeFraction * diag) ? own : rest).push_back(p);
        if (rest.size() <= 2) {
            own.insert(own.end(), rest.begin(), rest.end());
            rest.clear();
        }
    }
    for (int p : own) {
        owner_[p] = c;
        polygons_.push_back(p);
    }
    clusters_[c].ownEnd = int(polygons_.size());

    if (!rest.empty()) {
        // Objects are kept whole while the cluster holds several: a chair stays one cluster, which is
        // what a convolution link wants as a blocker. One object is split in space.
        std::map<int, std::pair<Bounds, int>> objects;  // object -> (box of centres, polygon count)
        for (int p : rest) {
            auto& o = objects[scene.polygons[p].object];
            o.first.extend(polygonBox(scene.polygons[p]).center());
            ++o.second;
        }
        std::vector<int> left, right;
        if (!plane.empty()) {
            std::sort(plane.begin(), plane.end());
            for (int p : rest) (std::binary_search(plane.begin(), plane.end(), p) ? left : right).push_back(p);
        } else if (objects.size() > 1) {
            Bounds centres;
            for (auto& [obj, o] : objects) centres.extend(o.first.center());
            int axis = longestAxis(centres);
            std::vector<std::pair<double, int>> order;
            for (auto& [obj, o] : objects) order.push_back({o.first.center()[axis], obj});
            std::sort(order.begin(), order.end());
            size_t half = rest.size() / 2, count = 0;
            std::map<int, bool> goesLeft;
            for (size_t k = 0; k < order.size(); ++k) {
                // The first object always goes left and the last right, so both sides are non-empty.
                bool l = k == 0 || (k + 1 < order.size() && count < half);
                goesLeft[order[k].second] = l;
                if (l) count += size_t(objects[order[k].second].second);
            }
            for (int p : rest) (goesLeft[scene.polygons[p].object] ? left : right).push_back(p);
        } else {
            Bounds centres;
            for (int p : rest) centres.extend(polygonBox(scene.polygons[p]).center());
            int axis = longestAxis(centres);
            std::vector<std::pair<double, int>> order;
            for (int p : rest) order.push_back({polygonBox(scene.polygons[p]).center()[axis], p});
            std::sort(order.begin(), order.end());
            size_t half = order.size() / 2;
            for (size_t k = 0; k < order.size(); ++k) (k < half ? left : right).push_back(order[k].second);
        }
        int first = int(clusters_.size());
        clusters_[c].firstChild = first;
        clusters_[c].numChildren = 2;
        clusters_.emplace_back();
        clusters_.emplace_back();
        build(scene, left, c, first, depth + 1);
        build(scene, right, c, first + 1, depth + 1);
    }
    clusters_[c].end = int(polygons_.size());
    finish(scene, c);
}

void ClusterTree::finish(const Scene& scene, int c) {
    Cluster& cl = clusters_[c];
    cl.box = Bounds{};
    cl.area = 0;
    cl.rhoMax = 0;
    cl.sends = false;
    for (int i = cl.begin; i < cl.end; ++i) {
        const ScenePolygon& p = scene.polygons[polygons_[i]];
        cl.box.extend(polygonBox(p));
        cl.area += p.area;
        if (p.receives) cl.rhoMax = std::max(cl.rhoMax, maxComponent(p.rho));
        cl.sends |= sendsLight(p);
    }
    cl.center = cl.box.center();
    cl.radius = 0.5 * length(cl.box.diagonal());
    cl.key = clusterKey(c);
}

}  // namespace penumbra
