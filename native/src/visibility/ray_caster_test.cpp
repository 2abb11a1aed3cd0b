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

TEST(RayCaster, TouchedFacesAreTheOnesSomethingStandsOnOrMeets) {
    // Only a touched face can have part of its front inside a solid, so only there does the refiner test a
    // reflector's blocked rays for starting inside one (Refiner::estimateVisibility).
    int legTop = 0, boxBottom = 0;
    auto t = tableScene(&legTop, &boxBottom);
    Scene sc = buildScene(t.input());
    RayCaster rays(sc);
    std::vector<char> touched = rays.touchedFaces(sc, 1e-5 * sc.diagonal);
    const int tableBottom = 96, tableTop = 97;  // after six walls of 16 faces
    for (int tile : {5, 6, 9, 10}) {
        EXPECT_TRUE(touched[size_t(tile)]) << "a leg stands on floor tile " << tile;
        EXPECT_FALSE(touched[size_t(16 + tile)]) << "nothing reaches ceiling tile " << tile;
    }
    EXPECT_TRUE(touched[size_t(tableTop)]) << "the box stands on the table";
    EXPECT_TRUE(touched[size_t(tableBottom)]) << "the legs meet the top's underside";
    EXPECT_FALSE(touched[size_t(boxBottom + 1)]) << "the box's top is free";
}

TEST(RayCaster, ATileHalfUnderASlabIsNotBuried) {
    // A slab over the middle half of a tile covers its centre and the points halfway to its corners; taken for
    // buried, the tile got no light from any cluster link (native/python/test_energy_balance.py's slabs room).
    // Under a slab larger than itself the tile is buried.
    for (double half : {0.3536, 0.6}) {
        testing::TestScene t;
        t.names = {"Floor", "Slab", "Ceiling"};
        Rgb grey{0.5, 0.5, 0.5};
        t.quad({-0.5, -0.5, 0}, {0.5, -0.5, 0}, {0.5, 0.5, 0}, {-0.5, 0.5, 0}, grey, {}, 0, 0);
        t.box({-half, -half, 0}, {half, half, 0.01}, grey, {}, false, 1);
        t.quad({-1, -1, 1}, {-1, 1, 1}, {1, 1, 1}, {1, -1, 1}, grey, {10, 10, 10}, 0, 2);
        Scene sc = buildScene(t.input());
        RayCaster rays(sc);
        std::vector<char> buried = rays.buriedFaces(sc, 1e-5 * sc.diagonal);
        EXPECT_EQ(int(buried[0]), half > 0.5 ? 1 : 0) << "slab half-width " << half;
    }
}

TEST(RayCaster, FootprintFacesAreTheOnesSomethingStandsOn) {
    // A cluster link's rays test a reflector's blocked rays for starting inside a solid only from these
    // (Refiner::fromInsideSolid): a face that something merely meets at its edge has no point inside one.
    int legTop = 0, boxBottom = 0;
    auto t = tableScene(&legTop, &boxBottom);
    Scene sc = buildScene(t.input());
    RayCaster rays(sc);
    const double lift = 1e-5 * sc.diagonal;
    std::vector<char> touched = rays.touchedFaces(sc, lift);
    std::vector<char> foot = rays.footprintFaces(sc, lift, touched);
    const int tableBottom = 96, tableTop = 97, wallAtFloor = 32;
    for (int tile : {5, 6, 9, 10}) EXPECT_TRUE(foot[size_t(tile)]) << "a leg stands on floor tile " << tile;
    for (int tile : {0, 3, 12, 15}) {
        EXPECT_TRUE(touched[size_t(tile)]) << "the walls meet corner tile " << tile;
        EXPECT_FALSE(foot[size_t(tile)]) << "along its edges only: corner tile " << tile;
    }
    EXPECT_TRUE(touched[size_t(wallAtFloor)]);
    EXPECT_FALSE(foot[size_t(wallAtFloor)]) << "the floor meets the wall at its lower edge";
    EXPECT_TRUE(foot[size_t(tableTop)]) << "the box stands on the table";
    EXPECT_TRUE(foot[size_t(tableBottom)]) << "the legs' tops lie inside the top's underside";
    for (size_t i = 0; i < foot.size(); ++i) EXPECT_LE(foot[i], touched[i]) << "face " << i;
}

TEST(RayCaster, AFaceOverATwoSidedFacesBackIsNotBuried) {
    // A floor whose normals point down, two-sided (its back copy faces up and shares its triangles), under a
    // ceiling that faces down: the ceiling's rays meet the floor's triangles from behind, which is the back
    // copy's front, not the inside of a solid. One-sided, the same ceiling is taken for buried (open below
    // only through the floor's back).
    for (bool twoSided : {true, false}) {
        testing::TestScene t;
        t.names = {"Floor", "Ceiling", "Lamp"};
        Rgb grey{0.5, 0.5, 0.5};
        double l = 0.1;  // a lamp that shines down, which takes no part in the rays
        t.quad({-l, -l, 1}, {-l, l, 1}, {l, l, 1}, {l, -l, 1}, {}, {10, 10, 10}, kLightOnly, 2);
        t.quad({-1, -1, 0}, {-1, 1, 0}, {1, 1, 0}, {1, -1, 0}, grey, {}, twoSided ? kEmitBack : 0, 0);
        t.quad({-1, -1, 1.5}, {-1, 1, 1.5}, {1, 1, 1.5}, {1, -1, 1.5}, grey, {}, 0, 1);
        Scene sc = buildScene(t.input());
        ASSERT_EQ(sc.polygons.size(), twoSided ? 4u : 3u);
        RayCaster rays(sc);
        std::vector<char> buried = rays.buriedFaces(sc, 1e-5 * sc.diagonal);
        EXPECT_EQ(int(buried.back()), twoSided ? 0 : 1) << "two-sided " << twoSided;
    }
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

TEST(RayCaster, ShaftOffATiledFloorIgnoresTheFloorButNotWhatStandsOnIt) {
    // A floor of 4 x 4 tiles and a lamp above it: the padded shaft from one floor tile touches its
    // coplanar neighbours, which no ray leaving the tile's front can cross. With the floor's and the
    // lamp's planes given, the shaft is clear; a box standing on the floor inside it still blocks.
    testing::TestScene t;
    t.names = {"Floor", "Ceiling", "Box"};
    Rgb white{0.7, 0.7, 0.7};
    grid(t, {-2, -2, 0}, {4, 0, 0}, {0, 4, 0}, 4, white, 0);
    int ceiling = int(t.polygons.size() / 4);
    t.quad({-0.5, -0.5, 3}, {-0.5, 0.5, 3}, {0.5, 0.5, 3}, {0.5, -0.5, 3}, {}, {10, 10, 10}, kLightOnly, 1);
    Scene sc = buildScene(t.input());
    RayCaster rays(sc);
    double lift = 1e-5 * sc.diagonal, pad = 2 * lift;
    int tile = 5;  // x in [-1, 0], y in [-1, 0]: an inner tile with neighbours on every side
    // The scene is moved to its centre when built: boxes and planes come from its own vertices.
    auto padded = [&](int p) {
        Bounds box;
        for (int k = 0; k < sc.polygons[p].geom.n; ++k) {
            box.extend(sc.polygons[p].geom.v[k] - Vec3{pad, pad, pad});
            box.extend(sc.polygons[p].geom.v[k] + Vec3{pad, pad, pad});
        }
        return box;
    };
    Bounds a = padded(tile), b = padded(ceiling);
    RayCaster::HalfSpace planes[2] = {{sc.polygons[tile].geom.v[0], {0, 0, 1}},
                                      {sc.polygons[ceiling].geom.v[0], {0, 0, -1}}};
    EXPECT_FALSE(rays.shaftIsClear(a, b, tile, ceiling));
    EXPECT_TRUE(rays.shaftIsClear(a, b, tile, ceiling, planes, 2, 0.5 * lift));
    // Only what lies within the height of a plane's front is ignored: with the plane given one lift
    // below the floor, the neighbouring tiles count again.
    RayCaster::HalfSpace raised[2] = {{planes[0].point - Vec3{0, 0, lift}, {0, 0, 1}}, planes[1]};
    EXPECT_FALSE(rays.shaftIsClear(a, b, tile, ceiling, raised, 2, 0.5 * lift));

    // Inside the room's box, so the built scene is moved by the same offset and a, b still fit it.
    t.box({-0.6, -0.6, 0.0}, {-0.4, -0.4, 0.5}, white, {}, false, 2);
    Scene withBox = buildScene(t.input());
    RayCaster blocked(withBox);
    EXPECT_FALSE(blocked.shaftIsClear(a, b, tile, ceiling, planes, 2, 0.5 * lift));
}

}  // namespace
}  // namespace penumbra
