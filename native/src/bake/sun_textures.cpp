#include "bake/sun_textures.h"

#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "convolution/cost_model.h"
#include "convolution/sun_shadow.h"
#include "geometry/box_tree.h"
#include "util/parallel.h"
#include "visibility/shaft.h"

namespace penumbra {
namespace {

// Coordinates across the sun's rays (a, b) and along them (depth).
struct SunFrame {
    Vec3 w, t1, t2;
    explicit SunFrame(const Vec3& dir) : w(normalize(dir)) {
        Vec3 a = std::fabs(w.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
        t1 = normalize(cross(w, a));
        t2 = cross(w, t1);
    }
};

struct Extent {
    double a0 = HUGE_VAL, a1 = -HUGE_VAL, b0 = HUGE_VAL, b1 = -HUGE_VAL, z0 = HUGE_VAL, z1 = -HUGE_VAL;
    void add(const SunFrame& f, const Vec3& p) {
        double a = dot(p, f.t1), b = dot(p, f.t2), z = dot(p, f.w);
        a0 = std::fmin(a0, a);
        a1 = std::fmax(a1, a);
        b0 = std::fmin(b0, b);
        b1 = std::fmax(b1, b);
        z0 = std::fmin(z0, z);
        z1 = std::fmax(z1, z);
    }
};

Extent boxExtent(const SunFrame& f, const Bounds& b) {
    Extent e;
    for (int k = 0; k < 8; ++k)
        e.add(f, {k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z});
    return e;
}

// Whether q stands more than `lift` in front of p's plane anywhere (on or behind it, it cannot cut a ray
// leaving p), and the height of its lowest vertex over that plane.
struct Standing {
    bool front = false;
    double low = HUGE_VAL;
};
Standing standing(const ScenePolygon& p, const ScenePolygon& q, double lift) {
    Standing st;
    for (int k = 0; k < q.geom.n; ++k) {
        double h = dot(q.geom.v[k] - p.geom.v[0], p.normal);
        st.front = st.front || h > lift;
        st.low = std::fmin(st.low, h);
    }
    return st;
}

void appendTriangles(const ScenePolygon& q, std::vector<BlockerTriangle>& out) {
    for (int k = 1; k + 1 < q.geom.n; ++k) out.push_back({q.geom.v[0], q.geom.v[k], q.geom.v[k + 1]});
}

// Whether something of extent `e` can cross a ray from the receiver (extent r) to the sun: nearer the sun
// than the receiver's far side, and across the rays within the receiver's extent widened by the penumbra
// (tan(angle / 2) times the largest depth between them).
bool inPrism(const Extent& r, const Extent& e, double t) {
    if (!(e.z0 < r.z1)) return false;
    double m = t * (r.z1 - e.z0) * 1.01;
    return e.a1 >= r.a0 - m && e.a0 <= r.a1 + m && e.b1 >= r.b0 - m && e.b0 <= r.b1 + m;
}

}  // namespace

SunTextures::SunTextures(const Scene& sc, const Settings& s, int threads) {
    slot_.assign(sc.lights.size(), {});
    std::vector<Bounds> boxes;
    std::vector<int> blockerIds;
    for (size_t i = 0; i < sc.polygons.size(); ++i) {
        const ScenePolygon& p = sc.polygons[i];
        if (!p.occludes || !p.blocksLamps) continue;
        boxes.push_back(polygonBox(p));
        blockerIds.push_back(int(i));
    }
    if (boxes.empty()) return;
    const BoxTree tree(boxes);
    ConvolutionSettings cs;
    cs.e_max = s.eMax;
    cs.maxResolution = s.maxTexture;
    cs.minResolution = std::min(16, s.maxTexture);
    cs.contactSlabs = s.contactSlabs;
    // One slab: a connected blocker cut into depth slabs (a ceiling over a wall, a wall with a window over a
    // floor) is the product of its slabs' maps, which assumes they hide independent parts of the sun; at every
    // seam both are in penumbra, and the window example's wall under the ceiling came out 0.25 too light over
    // whole faces (docs/convolution.md, Limits). Blockers that fit one kernel are the parallel case.
    cs.n_max = 1;
    for (size_t li = 0; li < sc.lights.size(); ++li) {
        const Light& l = sc.lights[li];
        if (l.type == LightType::Point) {
            if (l.radius > 0 && !l.sphere && l.castShadow) lampTextures(sc, s, threads, tree, blockerIds, cs, li);
            continue;
        }
        if (l.type != LightType::Sun || !(l.angle > 0) || !l.castShadow) continue;
        const SunFrame f(l.direction);
        const double t = std::tan(0.5 * std::min(l.angle, M_PI * (179.0 / 180.0)));
        const double sinEdge = t / std::sqrt(1 + t * t);
        std::vector<std::shared_ptr<const SoftShadowTexture>> made(sc.polygons.size());
        std::atomic<size_t> refused{0};
        parallelFor(sc.polygons.size(), threads, 16, [&](size_t b, size_t e, int) {
            for (size_t pi = b; pi < e; ++pi) {
                const ScenePolygon& p = sc.polygons[pi];
                // The stand-in needs the whole disk above the face's horizon with 3 degrees to spare
                // (sun_shadow.h); grazing faces keep the rays.
                if (!p.receives || -dot(f.w, p.normal) <= sinEdge + 0.05) continue;
                Extent r;
                ReceiverDesc rec;
                for (int k = 0; k < p.geom.n; ++k) {
                    r.add(f, p.geom.v[k]);
                    rec.points.push_back(p.geom.v[k]);
                }
                std::vector<BlockerTriangle> blockers;
                const double lift = 1e-6 * sc.diagonal, gap = 1e-3 * sc.diagonal;
                bool touching = false;
                tree.query([&](const Bounds& box) { return inPrism(r, boxExtent(f, box), t); },
                           [&](int i) {
                               const ScenePolygon& q = sc.polygons[size_t(blockerIds[size_t(i)])];
                               if (size_t(blockerIds[size_t(i)]) == pi || q.input == p.input) return;
                               Standing st = standing(p, q, lift);
                               if (!st.front) return;
                               Extent qe;
                               for (int k = 0; k < q.geom.n; ++k) qe.add(f, q.geom.v[k]);
                               if (!inPrism(r, qe, t)) return;
                               touching = touching || st.low < gap;
                               appendTriangles(q, blockers);
                           });
                if (blockers.empty()) continue;
                // A blocker reaching down to the face's plane (a wall meeting the floor, a box standing on it)
                // has a penumbra narrowing to nothing there; the window example's faces with such blockers came
                // out brighter than Cycles (its room 2.5 % -> 4.5 % RMS per texel), so the rays keep them.
                if (touching) {
                    ++refused;
                    continue;
                }
                try {
                    SunStandIn stand = sunStandIn({l.direction, l.angle}, blockers, rec, cs);
                    ConvolutionPlan plan = planSunShadow({l.direction, l.angle}, blockers, rec, cs);
                    if (plan.E_rr > s.eMax || !withinBudget(plan.fftSize, int(plan.slices.size()), s.tMax)) {
                        ++refused;
                        continue;
                    }
                    made[pi] = std::make_shared<const SoftShadowTexture>(
                        computeSoftShadow(plan, stand.source, blockers, stand.settings));
                } catch (const std::domain_error&) {
                    ++refused;  // no depth order, or a penumbra too wide for the FFT: the rays decide
                }
            }
        });
        slot_[li].assign(sc.polygons.size(), -1);
        for (size_t pi = 0; pi < made.size(); ++pi)
            if (made[pi]) {
                slot_[li][pi] = int(textures_.size());
                textures_.push_back(std::move(made[pi]));
            }
        refused_ += refused;
    }
}

void SunTextures::lampTextures(const Scene& sc, const Settings& s, int threads, const BoxTree& tree,
                               const std::vector<int>& blockerIds, const ConvolutionSettings& cs, size_t li) {
    const Light& l = sc.lights[li];
    std::vector<std::shared_ptr<const SoftShadowTexture>> made(sc.polygons.size());
    std::atomic<size_t> refused{0};
    parallelFor(sc.polygons.size(), threads, 16, [&](size_t b, size_t e, int) {
        for (size_t pi = b; pi < e; ++pi) {
            const ScenePolygon& p = sc.polygons[pi];
            // The disk must stand clear in front of the face (then it faces all of it).
            if (!p.receives || !(dot(l.position - p.geom.v[0], p.normal) > 2 * l.radius)) continue;
            bool front = true;
            for (int k = 0; k < p.geom.n; ++k) front = front && dot(l.position - p.geom.v[k], p.normal) > 2 * l.radius;
            if (!front) continue;
            // Cycles' disk faces each shaded point. The source is that disk for the face's centre c, seen from c
            // in the plane through the lamp parallel to the face (an ellipse): source, blocker and receiver
            // planes are then parallel, where a flat shade is one slab with no shear (the disk itself, tilted
            // against the face, was refused as too coarse on 47 of 49 faces under a shade). Its points keep
            // equal weights; the projection stretches the disk by up to (r / d) tan(incidence) across it.
            const Vec3 c = p.geom.centroid();
            const Vec3 axis = normalize(c - l.position);
            const double hl = dot(l.position - c, p.normal);
            Vec3 a = std::fabs(axis.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
            const Vec3 t1 = normalize(cross(axis, a)), t2 = cross(axis, t1);
            SourceDesc src;
            Bounds lb, rb;
            for (int k = 0; k < kLampDiskVertices; ++k) {
                double phi = 2 * M_PI * k / kLampDiskVertices;
                Vec3 q = l.position + (t1 * std::cos(phi) + t2 * std::sin(phi)) * l.radius;
                src.polygon.push_back(c + (q - c) * (hl / dot(q - c, p.normal)));
                lb.extend(src.polygon.back());
            }
            ReceiverDesc rec;
            for (int k = 0; k < p.geom.n; ++k) {
                rec.points.push_back(p.geom.v[k]);
                rb.extend(p.geom.v[k]);
            }
            const Shaft shaft(rb, lb);
            std::vector<BlockerTriangle> blockers;
            const double lift = 1e-6 * sc.diagonal, gap = 1e-3 * sc.diagonal;
            bool touching = false;
            tree.query([&](const Bounds& box) { return shaft.classify(box) != Shaft::Outside; },
                       [&](int i) {
                           const ScenePolygon& q = sc.polygons[size_t(blockerIds[size_t(i)])];
                           if (size_t(blockerIds[size_t(i)]) == pi || q.input == p.input) return;
                           if (shaft.classify(polygonBox(q)) == Shaft::Outside) return;
                           Standing st = standing(p, q, lift);
                           if (!st.front) return;
                           touching = touching || st.low < gap;
                           appendTriangles(q, blockers);
                       });
            if (blockers.empty()) continue;
            if (touching) {
                ++refused;
                continue;
            }
            try {
                ConvolutionPlan plan = planFineSoftShadow(src, blockers, rec, cs);
                if (plan.E_rr > s.eMax || !withinBudget(plan.fftSize, int(plan.slices.size()), s.tMax)) {
                    ++refused;
                    continue;
                }
                made[pi] = std::make_shared<const SoftShadowTexture>(computeSoftShadow(plan, src, blockers, cs));
            } catch (const std::domain_error&) {
                ++refused;
            }
        }
    });
    slot_[li].assign(sc.polygons.size(), -1);
    for (size_t pi = 0; pi < made.size(); ++pi)
        if (made[pi]) {
            slot_[li][pi] = int(textures_.size());
            textures_.push_back(std::move(made[pi]));
        }
    refused_ += refused;
}

double SunTextures::visibility(int light, int polygon, const Vec3& p) const {
    if (light < 0 || size_t(light) >= slot_.size() || slot_[size_t(light)].empty() || polygon < 0)
        return std::numeric_limits<double>::quiet_NaN();
    int k = slot_[size_t(light)][size_t(polygon)];
    if (k < 0) return std::numeric_limits<double>::quiet_NaN();
    return lookupVisibility(*textures_[size_t(k)], p);
}

size_t SunTextures::texels() const {
    size_t n = 0;
    for (const auto& t : textures_) n += size_t(t->n) * size_t(t->n);
    return n;
}

}  // namespace penumbra
