#include "visibility/shaft.h"

#include <gtest/gtest.h>

#include <random>

namespace penumbra {
namespace {

Bounds randomBox(std::mt19937& rng, double lo, double hi, double maxSize) {
    std::uniform_real_distribution<double> pos(lo, hi), size(0.0, maxSize);
    Vec3 c{pos(rng), pos(rng), pos(rng)};
    Bounds b;
    b.extend(c);
    // Flat boxes too: polygons' boxes have zero thickness along their normal.
    b.extend(c + Vec3{size(rng), rng() % 4 ? size(rng) : 0.0, size(rng)});
    return b;
}

Vec3 randomPoint(std::mt19937& rng, const Bounds& b) {
    std::uniform_real_distribution<double> u(0, 1);
    return {b.lo.x + u(rng) * (b.hi.x - b.lo.x), b.lo.y + u(rng) * (b.hi.y - b.lo.y),
            b.lo.z + u(rng) * (b.hi.z - b.lo.z)};
}

// Segment-box intersection (slab test), the brute force the shaft must never contradict.
bool segmentHitsBox(const Vec3& p, const Vec3& q, const Bounds& b) {
    double t0 = 0, t1 = 1;
    Vec3 d = q - p;
    for (int i = 0; i < 3; ++i) {
        if (std::fabs(d[i]) < 1e-300) {
            if (p[i] < b.lo[i] || p[i] > b.hi[i]) return false;
            continue;
        }
        double ta = (b.lo[i] - p[i]) / d[i], tb = (b.hi[i] - p[i]) / d[i];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

TEST(Shaft, OutsideIsNeverContradictedByASegment) {
    std::mt19937 rng(7);
    int outside = 0, inside = 0, contradictions = 0;
    for (int trial = 0; trial < 400; ++trial) {
        Bounds a = randomBox(rng, -2, 2, 1.0), b = randomBox(rng, -2, 2, 1.0);
        Shaft shaft(a, b);
        for (int k = 0; k < 40; ++k) {
            Bounds occ = randomBox(rng, -2.5, 2.5, 0.6);
            Shaft::Class c = shaft.classify(occ);
            outside += c == Shaft::Outside;
            bool anyHit = false, allHit = true;
            for (int s = 0; s < 60; ++s) {
                bool hit = segmentHitsBox(randomPoint(rng, a), randomPoint(rng, b), occ);
                anyHit |= hit;
                allHit &= hit;
            }
            if (c == Shaft::Outside && anyHit) ++contradictions;
            if (c == Shaft::Inside) {
                ++inside;
                // Inside means the box lies within the shaft; it need not block every segment,
                // but it must at least lie inside the union box.
                EXPECT_TRUE(occ.lo.x >= shaft.extent().lo.x && occ.hi.x <= shaft.extent().hi.x);
            }
        }
    }
    EXPECT_EQ(contradictions, 0);
    // The test has teeth: a good share of boxes is culled, which the extent box alone would not do.
    EXPECT_GT(outside, 4000);
    // And the Inside check above ran at all (GCC 16 also flags the count as set but never read).
    EXPECT_GT(inside, 0);
}

TEST(Shaft, PlanesCutOffTheCornersOfTheUnionBox) {
    Bounds a, b;
    a.extend({0, 0, 0});
    a.extend({1, 1, 1});
    b.extend({4, 4, 0});
    b.extend({5, 5, 1});
    Shaft s(a, b);
    EXPECT_EQ(s.planes(), 2);  // the two diagonal planes of a diagonal pair
    Bounds corner;
    corner.extend({4, 0, 0.2});
    corner.extend({4.5, 0.5, 0.8});
    EXPECT_EQ(s.classify(corner), Shaft::Outside);  // inside the union box, off the diagonal
    Bounds middle;
    middle.extend({2.4, 2.4, 0.4});
    middle.extend({2.6, 2.6, 0.6});
    EXPECT_EQ(s.classify(middle), Shaft::Inside);
    Bounds straddling;
    straddling.extend({1.8, 2.5, 0.4});  // reaches past the plane y = x + 1 at its (1.8, 3.2) corner
    straddling.extend({3.5, 3.2, 0.6});
    EXPECT_EQ(s.classify(straddling), Shaft::Overlap);
}

TEST(Shaft, ContainedBoxHasNoPlanes) {
    Bounds a, b;
    a.extend({0, 0, 0});
    a.extend({4, 4, 4});
    b.extend({1, 1, 1});
    b.extend({2, 2, 2});
    EXPECT_EQ(Shaft(a, b).planes(), 0);
}

}  // namespace
}  // namespace penumbra
