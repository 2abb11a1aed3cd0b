#include "visibility/ray_caster.h"

#include <gtest/gtest.h>

#include "penumbra.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

// A table (top 0.70-0.74 m) on four legs whose tops are flush with the top's underside, a box resting on
// the table, a lamp above: the legs' tops and the box's bottom are inside solids; nothing else is (faces
// resting on the floor look into open space below it, from which no light comes either).
// Quads on origin + s u + t v, s and t in [0, 1], n x n of them, front u x v.
void grid(testing::TestScene& t, Vec3 o, Vec3 u, Vec3 v, int n, Rgb rho, int object) {
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            Vec3 a = o + u * (double(i) / n) + v * (double(j) / n), du = u * (1.0 / n), dv = v * (1.0 / n);
            t.quad(a, a + du, a + du + dv, a + dv, rho, {}, 0, object);
        }
}

testing::TestScene tableScene(int* legTop, int* boxBottom) {
    testing::TestScene t;
    t.names = {"Room", "Table", "Box", "Lamp"};
    Rgb white{0.7, 0.7, 0.7};
    // A closed 4 x 4 x 3 m room in 4 x 4 faces a wall (floor first), so that light comes back from
    // clusters of wall faces, not only from the lamp.
    grid(t, {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, 4, white, 0);
    grid(t, {-2, -2, 3}, {0, 4, 0}, {4, 0, 0}, 4, white, 0);
    grid(t, {-2, -2, 0}, {0, 4, 0}, {0, 0, 3}, 4, white, 0);
    grid(t, {2, -2, 0}, {0, 0, 3}, {0, 4, 0}, 4, white, 0);
    grid(t, {-2, -2, 0}, {0, 0, 3}, {4, 0, 0}, 4, white, 0);
    grid(t, {-2, 2, 0}, {4, 0, 0}, {0, 0, 3}, 4, white, 0);
    t.box({-0.6, -0.4, 0.70}, {0.6, 0.4, 0.74}, white, {}, false, 1);
    *legTop = int(t.polygons.size() / 4) + 1;  // a box's faces: bottom, top, then the sides
    for (double x : {-0.55, 0.5})
        for (double y : {-0.35, 0.3})
            t.box({x, y, 0.0}, {x + 0.05, y + 0.05, 0.70}, white, {}, false, 1);
    *boxBottom = int(t.polygons.size() / 4);
    t.box({-0.2, -0.2, 0.74}, {0.2, 0.2, 0.9}, white, {}, false, 2);
    // The lamp shines up: what reaches the table comes back from the ceiling's clusters.
    double z = 2.0, s = 0.3;
    t.quad({-s, -s, z}, {s, -s, z}, {s, s, z}, {-s, s, z}, {}, {20, 20, 20}, kLightOnly, 3);
    return t;
}

TEST(RayCaster, BuriedFacesAreTheOnesInsideSolids) {
    int legTop = 0, boxBottom = 0;
    auto t = tableScene(&legTop, &boxBottom);
    Scene sc = buildScene(t.input());
    RayCaster rays(sc);
    std::vector<char> buried = rays.buriedFaces(sc, 1e-5 * sc.diagonal);
    std::vector<int> expect;
    for (int leg = 0; leg < 4; ++leg) expect.push_back(legTop + 6 * leg);
    expect.push_back(boxBottom);
    std::vector<int> got;
    for (size_t i = 0; i < buried.size(); ++i)
        if (buried[i]) got.push_back(int(i));
    EXPECT_EQ(got, expect);
}

TEST(RayCaster, ClusterLinksLeaveBuriedFacesDark) {
    // Cluster links cannot see shadows inside a cluster: a leg's top flush under the table must still get
    // exactly nothing (blender_tests/test_stability.py checks the office's desks, where cluster links lit
    // such faces at half the brightness of the desk tops before).
    int legTop = 0, boxBottom = 0;
    auto t = tableScene(&legTop, &boxBottom);
    auto sol = solve(t.input(), Settings{}, nullptr);
    ASSERT_GT(sol->report().count("cluster_links"), 0u);
    const Hierarchy& h = sol->hierarchy();
    double lit = h[0].B.x;  // a floor face
    ASSERT_GT(lit, 0.01);
    for (int leg = 0; leg < 4; ++leg) EXPECT_EQ(h[size_t(legTop + 6 * leg)].B.x, 0.0) << "leg " << leg;
    EXPECT_EQ(h[size_t(boxBottom)].B.x, 0.0);
}

}  // namespace
}  // namespace penumbra
