// A static bounding-volume tree over boxes: the radiance field looks up leaf supports containing a
// point, the shaft culler looks up occluders that may cross a shaft. Median split on the longest
// axis of the box centres; the caller decides which nodes to descend into.
#pragma once
#include <algorithm>
#include <vector>

#include "geometry/vec3.h"

namespace penumbra {

class BoxTree {
public:
    BoxTree() = default;
    explicit BoxTree(std::vector<Bounds> boxes);
    size_t size() const { return boxes_.size(); }
    const Bounds& box(int i) const { return boxes_[i]; }

    // Calls visit(i) for every box i in a node for which descend(node bounds) holds; visit may see
    // boxes that the caller must still test one by one.
    template <class Descend, class Visit>
    void query(Descend&& descend, Visit&& visit) const {
        if (nodes_.empty()) return;
        int stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp > 0) {
            const Node& n = nodes_[stack[--sp]];
            if (!descend(n.box)) continue;
            if (n.left < 0) {
                for (int i = n.begin; i < n.end; ++i) visit(order_[i]);
            } else {
                stack[sp++] = n.left;
                stack[sp++] = n.right;
            }
        }
    }

private:
    struct Node {
        Bounds box;
        int left = -1, right = -1;  // children, or -1 for a leaf node
        int begin = 0, end = 0;     // range in order_ for leaf nodes
    };
    int build(int begin, int end);

    std::vector<Bounds> boxes_;
    std::vector<int> order_;
    std::vector<Node> nodes_;
};

inline bool overlaps(const Bounds& a, const Bounds& b) {
    return a.lo.x <= b.hi.x && b.lo.x <= a.hi.x && a.lo.y <= b.hi.y && b.lo.y <= a.hi.y && a.lo.z <= b.hi.z &&
           b.lo.z <= a.hi.z;
}
inline bool contains(const Bounds& b, const Vec3& p) {
    return p.x >= b.lo.x && p.x <= b.hi.x && p.y >= b.lo.y && p.y <= b.hi.y && p.z >= b.lo.z && p.z <= b.hi.z;
}

}  // namespace penumbra
