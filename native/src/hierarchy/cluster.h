// Clusters above the input polygons (Smits-Arvo-Greenberg 1994, Sillion 1995): a tree of boxes built
// from object and spatial grouping. A polygon hangs from the lowest cluster that it does not dwarf, so
// a wall sits near the root and a chair's faces sit in the chair's clusters. Refinement starts from a
// single root <-> root link, which replaces the O(n^2) linking of every polygon pair.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "scene/scene.h"

namespace penumbra {

struct Cluster {
    Bounds box;
    Vec3 center;
    double radius = 0;        // half the box diagonal
    int parent = -1;
    int firstChild = -1, numChildren = 0;  // child clusters, contiguous in ClusterTree::clusters
    int begin = 0, end = 0;   // every polygon of the subtree: ClusterTree::polygons[begin, end)
    int ownEnd = 0;           // [begin, ownEnd): the polygons hanging directly from this cluster
    double area = 0;          // of all polygons below
    double rhoMax = 0;        // largest reflectance of a receiving polygon below (0: nothing receives)
    bool sends = false;       // something below emits or reflects
    uint64_t key = 0;         // seeds the ray samples of links that end here
    // The distinct face normals below (a room's furniture has a handful): the cluster's emission
    // toward any direction is a sum over these, not over its faces. [classBegin, classEnd) indexes
    // ClusterTree::classNormal and ::classFlux.
    int classBegin = 0, classEnd = 0;
    // The same classes four to a ClassBlock, the last one padded with dark classes: ClusterTree::classBlocks.
    int blockBegin = 0, blockEnd = 0;
};

// Four normal classes side by side in single precision, for a far cluster's light at a point: the sweeps
// evaluate that sum for every face of every cluster receiver and every near source's subcluster (node.cpp,
// clusterFluxAt), four classes per instruction. Padding lanes have zero normal and flux.
struct alignas(16) ClassBlock {
    float nx[4], ny[4], nz[4];
    float fr[4], fg[4], fb[4];
};

class ClusterTree {
public:
    ClusterTree() = default;
    // Over the polygons that take part in the light transport (receivers and senders). With planarGroups,
    // the faces of one object lying in one plane are kept together (Settings::planarClusters).
    explicit ClusterTree(const Scene& scene, bool planarGroups = false);
    bool empty() const { return clusters_.empty(); }
    const Cluster& operator[](int c) const { return clusters_[size_t(c)]; }
    size_t size() const { return clusters_.size(); }
    const std::vector<int>& polygons() const { return polygons_; }
    // The cluster a polygon hangs from, or -1 for polygons left out of the transport.
    int owner(int polygon) const { return owner_[size_t(polygon)]; }

    const std::vector<Vec3>& classNormal() const { return classNormal_; }
    // Per normal class: sum of B * area of its faces, refreshed from the polygons' radiosities by
    // updateFlux before every gather and refinement pass.
    const std::vector<Rgb>& classFlux() const { return classFlux_; }
    const std::vector<ClassBlock>& classBlocks() const { return classBlocks_; }
    // The blocks hold each class's light divided by this power of two (the largest class's binary exponent), so that
    // no flux a valid scene can hold (coordinates to 1e8 m, any finite float emission) overflows a float: multiply
    // their sums back by it.
    double classBlockUnit() const { return classBlockUnit_; }
    // Nothing below cluster c has light to give (every class flux zero), as of the last updateFlux: its light
    // is zero everywhere, and a gather need not walk it.
    bool dark(int c) const { return dark_[size_t(c)] != 0; }
    // polygonRadiosity(p): the current mean radiosity of polygon p.
    template <class F>
    void updateFlux(const Scene& scene, F&& polygonRadiosity) {
        for (auto& f : classFlux_) f = Rgb{};
        for (size_t c = 0; c < clusters_.size(); ++c) {
            const Cluster& cl = clusters_[c];
            const int* cls = memberClass_.data() + memberStart_[c];
            for (int k = cl.begin; k < cl.end; ++k) {
                int p = polygons_[size_t(k)];
                classFlux_[size_t(cls[k - cl.begin])] += polygonRadiosity(p) * scene.polygons[size_t(p)].area;
            }
        }
        double largest = 0;
        for (const Rgb& f : classFlux_) largest = std::max(largest, maxComponent(f));
        classBlockUnit_ = largest > 0 && std::isfinite(largest) ? std::ldexp(1.0, std::ilogb(largest)) : 1.0;
        const double scale = 1 / classBlockUnit_;  // a power of two: exact
        for (const Cluster& cl : clusters_)
            for (int m = cl.classBegin; m < cl.classEnd; ++m) {
                ClassBlock& b = classBlocks_[size_t(cl.blockBegin + (m - cl.classBegin) / 4)];
                int lane = (m - cl.classBegin) % 4;
                const Rgb& f = classFlux_[size_t(m)];
                b.fr[lane] = float(f.x * scale);
                b.fg[lane] = float(f.y * scale);
                b.fb[lane] = float(f.z * scale);
            }
        dark_.assign(clusters_.size(), 1);
        for (size_t c = 0; c < clusters_.size(); ++c)
            for (int m = clusters_[c].classBegin; m < clusters_[c].classEnd && dark_[c]; ++m) {
                const Rgb& f = classFlux_[size_t(m)];
                dark_[c] = f.x == 0 && f.y == 0 && f.z == 0;
            }
    }

private:
    void build(const Scene& scene, std::vector<int>& items, int parent, int c, int depth);
    void finish(const Scene& scene, int c);

    std::vector<Cluster> clusters_;
    std::vector<int> polygons_;
    std::vector<int> owner_;
    std::vector<Vec3> classNormal_;
    std::vector<Rgb> classFlux_;
    std::vector<ClassBlock> classBlocks_;
    double classBlockUnit_ = 1;
    std::vector<char> dark_;
    std::vector<size_t> memberStart_;  // per cluster: where its faces' class indices start
    std::vector<int> memberClass_;     // class index of each face of each cluster
    bool planarGroups_ = false;
};

// Links and the solver name nodes by one int: elements are >= 0 (a polygon's root element has the
// polygon's index), clusters are negative.
inline bool isClusterNode(int node) { return node < 0; }
inline int clusterNode(int c) { return -2 - c; }
inline int clusterIndex(int node) { return -2 - node; }

}  // namespace penumbra
