#include "geometry/box_tree.h"

namespace penumbra {

BoxTree::BoxTree(std::vector<Bounds> boxes) : boxes_(std::move(boxes)) {
    order_.resize(boxes_.size());
    for (size_t i = 0; i < order_.size(); ++i) order_[i] = int(i);
    nodes_.reserve(boxes_.size() / 2 + 2);
    if (!boxes_.empty()) build(0, int(boxes_.size()));
}

int BoxTree::build(int begin, int end) {
    int idx = int(nodes_.size());
    nodes_.push_back(Node{});
    Bounds box, centers;
    for (int i = begin; i < end; ++i) {
        box.extend(boxes_[order_[i]]);
        centers.extend(boxes_[order_[i]].center());
    }
    nodes_[idx].box = box;
    // Leaves hold up to 4 boxes; a median split keeps the depth at log2(n/4), far inside the stack.
    if (end - begin <= 4) {
        nodes_[idx].begin = begin;
        nodes_[idx].end = end;
        return idx;
    }
    Vec3 d = centers.diagonal();
    int axis = d.x > d.y ? (d.x > d.z ? 0 : 2) : (d.y > d.z ? 1 : 2);
    int mid = (begin + end) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end, [&](int a, int b) {
        double ca = boxes_[a].center()[axis], cb = boxes_[b].center()[axis];
        return ca < cb || (ca == cb && a < b);
    });
    int l = build(begin, mid);
    int r = build(mid, end);
    nodes_[idx].left = l;
    nodes_[idx].right = r;
    return idx;
}

}  // namespace penumbra
