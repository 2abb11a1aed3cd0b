#include "bake/radiance_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <memory>

#include "testing/scenes.h"

namespace penumbra {
namespace {

using testing::TestScene;

// A hierarchy whose leaf radiosities are set by hand, so the reconstruction is tested on its own.
struct Field {
    Scene scene;
    std::unique_ptr<Hierarchy> h;
    explicit Field(const TestScene& t) : scene(buildScene(t.input())), h(std::make_unique<Hierarchy>(scene)) {}

    Vec3 world(const Vec3& local) const { return local + scene.offset; }
    // Subdivides the root of input polygon `input` (and its descendants) `levels` times.
    void refine(int input, int levels) {
        for (size_t r = 0; r < h->numRoots(); ++r)
            if (scene.polygons[r].input == input) refineBelow(int(r), levels);
    }
    int root(int input) const {
        for (size_t r = 0; r < h->numRoots(); ++r)
            if (scene.polygons[r].input == input) return int(r);
        return -1;
    }
    void refineBelow(int e, int levels) {
        if (levels == 0) return;
        int first = h->subdivide(e);
        for (int k = 0; k < (*h)[e].numChildren; ++k) refineBelow(first + k, levels - 1);
    }
    // Every leaf of input polygon `input` gets radiosity f(world position of its centre).
    void set(int input, const std::function<double(const Vec3&)>& f) {
        for (size_t i = 0; i < h->size(); ++i) {
            Element& e = (*h)[i];
            if (e.isLeaf() && scene.polygons[e.polygon].input == input) {
                double b = f(world(e.center));
                e.B = {b, b, b};
            }
        }
    }
    RadianceField build() const { return RadianceField(*h); }
};

// p and n in world coordinates; the red channel times pi, i.e. the blended leaf radiosity.
double at(const RadianceField& f, const Field& s, const Vec3& p, const Vec3& n) {
    return f.radiance(p - s.scene.offset, normalize(n)).x * M_PI;
}

// A lamp over [0,1]^2 at height z, so that the scene is valid; light-only, so it has no leaves.
void lamp(TestScene& t, double z) {
    t.quad({0.4, 0.4, z}, {0.4, 0.6, z}, {0.6, 0.6, z}, {0.6, 0.4, z}, {}, {1, 1, 1}, kLightOnly);
}

TEST(RadianceField, ParallelSurfacesAThousandthOfTheDiagonalApartKeepTheirOwnValues) {
    TestScene t;
    lamp(t, 1.0);  // bounds [0,1]^3
    const double gap = 1e-3 * std::sqrt(3.0);
    int floor = t.quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}, {});
    int sheet = t.quad({0.2, 0.2, gap}, {0.8, 0.2, gap}, {0.8, 0.8, gap}, {0.2, 0.8, gap}, {0.5, 0.5, 0.5}, {});
    // And a ceiling over a sheet hanging below it, facing down: the same from the other side.
    int ceiling = t.quad({0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}, {0.5, 0.5, 0.5}, {});
    int below = t.quad({0.2, 0.2, 1 - gap}, {0.2, 0.8, 1 - gap}, {0.8, 0.8, 1 - gap}, {0.8, 0.2, 1 - gap},
                       {0.5, 0.5, 0.5}, {});
    Field s(t);
    ASSERT_NEAR(s.scene.diagonal, std::sqrt(3.0), 1e-6);
    // Coarse floor and ceiling (leaves 0.5 wide, 290 gaps), finer sheets (0.15 wide).
    s.refine(floor, 1);
    s.refine(ceiling, 1);
    s.refine(sheet, 2);
    s.refine(below, 2);
    s.set(floor, [](const Vec3&) { return 1.0; });
    s.set(ceiling, [](const Vec3&) { return 2.0; });
    s.set(sheet, [](const Vec3&) { return 50.0; });
    s.set(below, [](const Vec3&) { return 70.0; });
    RadianceField f = s.build();
    for (int i = 0; i <= 20; ++i)
        for (int j = 0; j <= 20; ++j) {
            double x = i / 20.0, y = j / 20.0;
            EXPECT_NEAR(at(f, s, {x, y, 0}, {0, 0, 1}), 1.0, 1e-12) << x << " " << y;
            EXPECT_NEAR(at(f, s, {x, y, 1}, {0, 0, -1}), 2.0, 1e-12) << x << " " << y;
            double u = 0.2 + 0.6 * x, v = 0.2 + 0.6 * y;
            EXPECT_NEAR(at(f, s, {u, v, gap}, {0, 0, 1}), 50.0, 1e-12) << u << " " << v;
            EXPECT_NEAR(at(f, s, {u, v, 1 - gap}, {0, 0, -1}), 70.0, 1e-12) << u << " " << v;
        }
    // A point just off the sheet (further than float32 rounding), straight above a coarse floor leaf's
    // centre but 0.035 from the nearest sheet leaf's: no leaf claims it, and the fallback must still
    // find the sheet it is 1e-4 above, not the floor 1.8e-3 below.
    EXPECT_NEAR(at(f, s, {0.25, 0.25, gap + 1e-4}, {0, 0, 1}), 50.0, 1e-12);
}

// Largest |f(a) - f(b)| / |a - b| over consecutive samples of a path, and the largest jump over
// pairs 2e-7 apart straddling each given parameter (an element or polygon edge, a fold).
struct Smoothness {
    double slope = 0, jump = 0;
};
Smoothness smoothness(const std::function<double(double)>& f, double t0, double t1, const std::vector<double>& edges) {
    Smoothness s;
    const int n = 4000;
    double h = (t1 - t0) / n, prev = f(t0);
    for (int i = 1; i <= n; ++i) {
        double cur = f(t0 + i * h);
        s.slope = std::max(s.slope, std::fabs(cur - prev) / h);
        prev = cur;
    }
    for (double e : edges) s.jump = std::max(s.jump, std::fabs(f(e + 1e-7) - f(e - 1e-7)));
    return s;
}

TEST(RadianceField, ContinuousAcrossElementEdgesTVerticesAndPolygonBoundaries) {
    TestScene t;
    lamp(t, 1.0);
    int a = t.quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}, {});
    int b = t.quad({1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}, {0.5, 0.5, 0.5}, {});
    Field s(t);
    s.refine(a, 2);  // leaves 0.25 wide, one of them split again: T-vertices inside the polygon
    s.refineBelow(s.h->firstChild(s.h->firstChild(s.root(a))) + 3, 1);
    s.refine(b, 1);  // 0.5 wide: T-vertices along x = 1
    auto linear = [](const Vec3& p) { return 1 + p.x + 2 * p.y; };
    s.set(a, linear);
    s.set(b, linear);
    RadianceField f = s.build();
    std::vector<double> edges;
    for (int k = 1; k < 16; ++k) edges.push_back(k * 0.125);
    for (double y : {0.03, 0.3, 0.5, 0.62, 0.97}) {
        auto g = smoothness([&](double x) { return at(f, s, {x, y, 0}, {0, 0, 1}); }, 0.0, 2.0, edges);
        EXPECT_LT(g.slope, 20.0) << "y = " << y;
        EXPECT_LT(g.jump, 1e-5) << "y = " << y;
    }
    for (double x : {0.03, 0.25, 0.5, 0.99, 1.0, 1.01, 1.3}) {
        auto g = smoothness([&](double y) { return at(f, s, {x, y, 0}, {0, 0, 1}); }, 0.0, 1.0, edges);
        EXPECT_LT(g.slope, 20.0) << "x = " << x;
        EXPECT_LT(g.jump, 1e-5) << "x = " << x;
    }
}

// Two facets of a tessellated curved surface (a cylinder with 18 to 36 segments has these angles).
class Fold : public ::testing::TestWithParam<double> {};

TEST_P(Fold, ContinuousAcrossAShallowFold) {
    double th = GetParam() * M_PI / 180, c = std::cos(th), sn = std::sin(th);
    TestScene t;
    lamp(t, 1.0);
    int a = t.quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}, {});
    int b = t.quad({1, 0, 0}, {1 + c, 0, sn}, {1 + c, 1, sn}, {1, 1, 0}, {0.5, 0.5, 0.5}, {});
    Field s(t);
    s.refine(a, 2);
    s.refine(b, 1);
    // Linear in arc length across the fold.
    s.set(a, [](const Vec3& p) { return 1 + 2 * p.x + p.y; });
    s.set(b, [&](const Vec3& p) { return 1 + 2 * (1 + (p.x - 1) / c) + p.y; });
    RadianceField f = s.build();
    auto onPath = [&](double u, double y) {
        if (u <= 1) return at(f, s, {u, y, 0}, {0, 0, 1});
        return at(f, s, {1 + (u - 1) * c, y, (u - 1) * sn}, {-sn, 0, c});
    };
    for (double y : {0.1, 0.5, 0.8}) {
        auto g = smoothness([&](double u) { return onPath(u, y); }, 0.5, 1.5, {0.75, 1.0, 1.25});
        EXPECT_LT(g.slope, 20.0) << "y = " << y;
        EXPECT_LT(g.jump, 1e-5) << "y = " << y;
    }
}

INSTANTIATE_TEST_SUITE_P(RadianceField, Fold, ::testing::Values(10.0, -10.0, 20.0));

TEST(RadianceField, AWarpedQuadIsSmoothOnTheOtherTriangulation) {
    TestScene t;
    lamp(t, 1.0);
    const double w = 0.01;  // 1 % of its size: Blender keeps such a quad whole, the scene splits it
    int q = t.quad({0, 0, 0}, {1, 0, 0}, {1, 1, w}, {0, 1, 0}, {0.5, 0.5, 0.5}, {});
    Field s(t);
    int parts = 0;
    for (auto& p : s.scene.polygons) parts += p.input == q;
    ASSERT_EQ(parts, 2);  // along the 0-2 diagonal
    s.refine(q, 3);
    s.set(q, [](const Vec3& p) { return 1 + p.x + 2 * p.y; });
    RadianceField f = s.build();
    // The other triangulation, (0, 1, 3) flat and (1, 2, 3) rising to the warped corner, sits up to
    // w / 2 off the scene's triangles in the middle.
    auto other = [&](double x, double y) {
        bool flat = x + y <= 1;
        Vec3 n = flat ? Vec3{0, 0, 1} : Vec3{-w, -w, 1};
        return at(f, s, {x, y, flat ? 0.0 : w * (x + y - 1)}, n);
    };
    for (double y : {0.2, 0.5, 0.7}) {
        auto g = smoothness([&](double x) { return other(x, y); }, 0.0, 1.0, {1 - y, 0.25, 0.5, 0.75});
        EXPECT_LT(g.slope, 20.0) << "y = " << y;
        EXPECT_LT(g.jump, 1e-5) << "y = " << y;
    }
    auto diag = smoothness([&](double u) { return other(u, u); }, 0.05, 0.95, {0.5});
    EXPECT_LT(diag.slope, 20.0);
    EXPECT_LT(diag.jump, 1e-5);
}

}  // namespace
}  // namespace penumbra

namespace penumbra {
namespace {

// A lightmap's points read their candidates from a Region (the leaves and polygons near its triangles, in
// the trees' order) instead of walking the trees: every value must be the walk's, bit for bit, inside the
// region's box, at its faces, and outside it (where the walk is taken).
TEST(RadianceField, ARegionGivesTheTreeWalksValuesBitForBit) {
    TestScene t;
    lamp(t, 1.0);
    int floor = t.quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}, {});
    int wall = t.quad({0, 0, 0}, {0, 1, 0}, {0, 1, 1}, {0, 0, 1}, {0.5, 0.5, 0.5}, {});
    int sheet = t.quad({0.2, 0.2, 0.3}, {0.8, 0.2, 0.3}, {0.8, 0.8, 0.3}, {0.2, 0.8, 0.3}, {0.5, 0.5, 0.5}, {});
    Field s(t);
    s.refine(floor, 3);
    s.refine(wall, 2);
    s.refine(sheet, 2);
    s.set(floor, [](const Vec3& p) { return 1 + p.x + 2 * p.y; });
    s.set(wall, [](const Vec3& p) { return 3 + p.z; });
    s.set(sheet, [](const Vec3& p) { return 5 - p.x; });
    RadianceField f = s.build();
    const Vec3 off = s.scene.offset;
    const Bounds boxes[] = {
        {Vec3{0.1, 0.1, -0.01} - off, Vec3{0.4, 0.3, 0.01} - off},   // a patch of the floor
        {Vec3{-0.01, 0.0, 0.0} - off, Vec3{0.3, 1.0, 1.0} - off},    // the wall and the floor's edge
        {Vec3{0.0, 0.0, 0.0} - off, Vec3{1.0, 1.0, 1.0} - off},      // everything
    };
    int scanned = 0;
    for (const Bounds& box : boxes) {
        RadianceField::Region r = f.region(box);
        scanned += r.scanLeaves;
        for (int i = 0; i <= 24; ++i)
            for (int j = 0; j <= 24; ++j) {
                double x = i / 24.0, y = j / 24.0;
                const Vec3 pts[][2] = {{{x, y, 0}, {0, 0, 1}}, {{0, x, y}, {1, 0, 0}}, {{x, y, 0.3}, {0, 0, 1}},
                                       {{x, y, 0.3}, {0, 0, -1}}};
                for (const auto& pn : pts) {
                    Vec3 p = pn[0] - off, n = normalize(pn[1]);
                    for (bool irr : {false, true}) {
                        Rgb a = f.radiance(p, n, irr), b = f.radiance(p, n, irr, &r);
                        EXPECT_EQ(a.x, b.x) << x << " " << y;
                        EXPECT_EQ(a.y, b.y);
                        EXPECT_EQ(a.z, b.z);
                    }
                }
            }
    }
    EXPECT_GE(scanned, 1);
}

}  // namespace
}  // namespace penumbra
