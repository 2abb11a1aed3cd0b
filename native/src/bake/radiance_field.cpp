#include "bake/radiance_field.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

RadianceField::RadianceField(const Hierarchy& h) {
    const Scene& sc = h.scene();
    diagonal_ = sc.diagonal;
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
        double r = 2.0 * (length(l.e1) + length(l.e2));
        l.planeTol = 0.25 * r + 1e-7 * diagonal_;
        Vec3 ext{r + l.planeTol, r + l.planeTol, r + l.planeTol};
        l.support.extend(l.center - ext);
        l.support.extend(l.center + ext);
        l.value = (e.B - p.emission) / M_PI;
        leaves_.push_back(l);
    }
    order_.resize(leaves_.size());
    for (size_t i = 0; i < order_.size(); ++i) order_[i] = int(i);
    nodes_.reserve(2 * leaves_.size() / 4 + 2);
    if (!leaves_.empty()) build(0, int(leaves_.size()));
}

int RadianceField::build(int begin, int end) {
    int idx = int(nodes_.size());
    nodes_.push_back(Node{});
    Bounds box, centers;
    for (int i = begin; i < end; ++i) {
        box.extend(leaves_[order_[i]].support);
        centers.extend(leaves_[order_[i]].center);
    }
    nodes_[idx].box = box;
    if (end - begin <= 4) {
        nodes_[idx].begin = begin;
        nodes_[idx].end = end;
        return idx;
    }
    Vec3 d = centers.diagonal();
    int axis = d.x > d.y ? (d.x > d.z ? 0 : 2) : (d.y > d.z ? 1 : 2);
    int mid = (begin + end) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](int a, int b) {
                         double ca = leaves_[a].center[axis], cb = leaves_[b].center[axis];
                         return ca < cb || (ca == cb && a < b);
                     });
    int l = build(begin, mid);
    int r = build(mid, end);
    nodes_[idx].left = l;
    nodes_[idx].right = r;
    return idx;
}

template <class F>
void RadianceField::query(const Bounds& q, F&& visit) const {
    if (nodes_.empty()) return;
    int stack[128];
    int sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        const Node& n = nodes_[stack[--sp]];
        if (n.box.hi.x < q.lo.x || n.box.lo.x > q.hi.x || n.box.hi.y < q.lo.y || n.box.lo.y > q.hi.y ||
            n.box.hi.z < q.lo.z || n.box.lo.z > q.hi.z)
            continue;
        if (n.left < 0) {
            for (int i = n.begin; i < n.end; ++i) visit(order_[i]);
        } else if (sp < 126) {
            stack[sp++] = n.left;
            stack[sp++] = n.right;
        }
    }
}

double RadianceField::weight(const Leaf& l, const Vec3& p, const Vec3& n) const {
    if (dot(l.normal, n) < 0.9) return 0;  // another surface (a wall meeting the floor)
    Vec3 d = p - l.center;
    if (std::fabs(dot(d, l.normal)) > l.planeTol) return 0;  // a parallel surface nearby
    double b1 = dot(d, l.e1), b2 = dot(d, l.e2);
    double s = (l.g22 * b1 - l.g12 * b2) / l.det, t = (l.g11 * b2 - l.g12 * b1) / l.det;
    double ws = 1 - std::fabs(s) * 0.5, wt = 1 - std::fabs(t) * 0.5;
    return ws > 0 && wt > 0 ? ws * wt : 0;
}

Rgb RadianceField::radiance(const Vec3& p, const Vec3& n) const {
    Bounds q;
    q.extend(p);
    Rgb sum;
    double wsum = 0;
    query(q, [&](int i) {
        const Leaf& l = leaves_[i];
        if (p.x < l.support.lo.x || p.x > l.support.hi.x || p.y < l.support.lo.y ||
            p.y > l.support.hi.y || p.z < l.support.lo.z || p.z > l.support.hi.z)
            return;
        double w = weight(l, p, n);
        if (w > 0) {
            sum += l.value * w;
            wsum += w;
        }
    });
    if (wsum > 0) return sum / wsum;
    // The point lies off every leaf's support (a vertex of a modifier-displaced mesh, a face that
    // was too small to keep): take the nearest leaf facing the same way, searching wider boxes.
    for (double r = 1e-3 * diagonal_; r <= 4 * diagonal_; r *= 4) {
        Bounds box;
        box.extend(p - Vec3{r, r, r});
        box.extend(p + Vec3{r, r, r});
        double best = HUGE_VAL;
        int bestLeaf = -1;
        query(box, [&](int i) {
            const Leaf& l = leaves_[i];
            if (dot(l.normal, n) <= 0) return;
            double d2 = length2(l.center - p);
            if (d2 < best || (d2 == best && i < bestLeaf)) { best = d2; bestLeaf = i; }
        });
        if (bestLeaf >= 0 && best <= r * r) return leaves_[bestLeaf].value;
    }
    return Rgb{};
}

}  // namespace penumbra
