// Quadtree elements on the scene's polygons, and the cluster tree above the polygon roots. Links,
// gather and push/pull only ever see node indices (cluster.h: negative for clusters).
#pragma once
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "hierarchy/cluster.h"
#include "hierarchy/predicates.h"
#include "scene/scene.h"

namespace penumbra {

struct Element {
    std::array<Vec3, 4> v;  // corners, counter-clockwise; v[3] unused for triangles
    uint8_t n = 0;          // 3 or 4
    uint8_t depth = 0;
    uint8_t numChildren = 0;
    int polygon = -1;       // scene polygon it lies on
    int parent = -1;
    std::atomic<int> firstChild{-1};  // children are contiguous; set once, read by refiner threads
    uint64_t key = 0;       // identity independent of creation order: seeds ray samples
    Vec3 center;
    double area = 0;
    Rgb B;                  // radiosity (exitance), W/m^2
    Rgb irradiance;         // gathered at this level from its links
    // Largest difference, over the leaves below, between a leaf's radiosity and this element's (max
    // channel): how far this element's one value misrepresents the light it sends.
    float Bdev = 0;

    bool isLeaf() const { return firstChild.load(std::memory_order_acquire) < 0; }
    Polygon polygonShape() const;
    // Point at parametric (s, t) in [0,1]^2: bilinear on quads, (s, t) -> barycentric on triangles
    // with s + t <= 1 folded back inside.
    Vec3 pointAt(double s, double t) const;
};

// Element arena with stable addresses: refiner threads subdivide while others read.
class Hierarchy {
public:
    // Throws BudgetExceeded when the roots, or later a subdivision, would exceed maxElements.
    // With `clustering`, a cluster tree is built over the polygons (else clusters() is empty).
    explicit Hierarchy(const Scene& scene, size_t maxElements = size_t(-1), bool clustering = false,
                       bool planarClusters = false);
    const Scene& scene() const { return scene_; }
    const ClusterTree& clusters() const { return clusters_; }
    // Refreshes the clusters' emission from the polygons' current radiosities (their root elements).
    void updateClusterFlux();
    // The clusters' faces as a near cluster's light is summed over them (node.cpp's fluxAt), in the
    // cluster tree's polygon order; their geometry is set once, their light (B, lit) refreshed with the flux.
    // Every sweep sums near clusters face by face for every face below a receiving cluster; read from the
    // elements and the scene's polygons each face cost two scattered cache lines (with far_field 0.5, half
    // the solve's time at 20k polygons).
    struct FaceLight {
        Vec3 center, normal;  // the root element's centre, the polygon's normal
        Rgb B;
        double area;          // the root element's
        int polygon;
        bool lit;             // it sends light (bouncesLight) and has some
    };
    const std::vector<FaceLight>& faceLight() const { return faceLight_; }
    // The same faces' fixed geometry as fluxBound reads it for every cluster link judged: contiguous, where
    // the elements, their corners and the scene's polygons cost three scattered reads a face (fluxBound was
    // 9 % of a second refinement pass of the 20k office).
    struct FaceBox {
        Bounds box;           // the root element's corners
        Vec3 center, normal;
        double area;
        int polygon;
        bool bounces;         // bouncesLight
    };
    const std::vector<FaceBox>& faceBoxes() const { return faceBoxes_; }
    // Faces whose front is covered at contact (RayCaster::buriedFaces): no cluster link lights them.
    void setBuried(std::vector<char> buried) { buried_ = std::move(buried); }
    bool buried(int polygon) const { return !buried_.empty() && buried_[size_t(polygon)]; }
    size_t size() const { return size_.load(std::memory_order_acquire); }
    size_t numRoots() const { return numRoots_; }
    Element& operator[](size_t i) { return blocks_[i >> kBlockBits][i & kBlockMask]; }
    const Element& operator[](size_t i) const { return blocks_[i >> kBlockBits][i & kBlockMask]; }

    // Creates the children of e if it has none (thread-safe) and returns the first child's index.
    int subdivide(int e);
    int firstChild(int e) const { return (*this)[e].firstChild.load(std::memory_order_acquire); }
    // Sets every element's Bdev from the current radiosities (elements in canonical order).
    void updateRadiosityDeviation();

    // Renumbers all elements in depth-first order from the roots so that indices do not depend on
    // which thread created what. Returns old index -> new index.
    std::vector<int> canonicalize(int threads = 1);
    size_t countLeaves() const;

private:
    static constexpr int kBlockBits = 14;
    static constexpr size_t kBlockMask = (size_t(1) << kBlockBits) - 1;
    int allocate(int count);  // caller holds mutex_
    void initRoot(Element& e, const ScenePolygon& p, int polygon);

    const Scene& scene_;
    ClusterTree clusters_;
    std::vector<FaceLight> faceLight_;
    std::vector<FaceBox> faceBoxes_;
    std::vector<char> buried_;
    std::vector<std::unique_ptr<Element[]>> blocks_;  // reserved up front, so never reallocated
    std::atomic<size_t> size_{0};
    size_t numRoots_ = 0;
    size_t maxElements_;
    std::mutex mutex_;
};

void finishElement(Element& e);  // centre and area from the corners

}  // namespace penumbra
