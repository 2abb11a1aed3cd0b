// The solution as a function on surfaces: outgoing reflected radiance at any point. Leaf values are
// blended with tensor-product tent weights in each leaf's own frame, so the reconstruction is
// continuous across element edges, T-vertices and polygon boundaries of one surface, and exactly the
// leaf value at the centre of a leaf whose neighbours are the same size.
#pragma once
#include <vector>

#include "hierarchy/element.h"

namespace penumbra {

class RadianceField {
public:
    RadianceField() = default;
    explicit RadianceField(const Hierarchy& h);
    // p in the scene's recentred coordinates; n the geometric normal of the surface at p.
    Rgb radiance(const Vec3& p, const Vec3& n) const;
    size_t leaves() const { return leaves_.size(); }

private:
    struct Leaf {
        Vec3 center, normal, e1, e2;  // e1, e2: half-axes of the element's parallelogram
        double g11, g12, g22, det;    // Gram matrix of (e1, e2), for in-plane coordinates
        double planeTol;
        Rgb value;                    // (B - E) / pi
        Bounds support;
    };
    struct Node {
        Bounds box;
        int left = -1, right = -1;    // children, or -1 for a leaf node
        int begin = 0, end = 0;       // range in order_ for leaf nodes
    };
    int build(int begin, int end);
    template <class F> void query(const Bounds& box, F&& visit) const;
    double weight(const Leaf& l, const Vec3& p, const Vec3& n) const;

    std::vector<Leaf> leaves_;
    std::vector<int> order_;
    std::vector<Node> nodes_;
    double diagonal_ = 0;
};

}  // namespace penumbra
