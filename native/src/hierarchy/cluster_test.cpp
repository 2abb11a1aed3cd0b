#include "hierarchy/cluster.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "hierarchy/node.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

// A room of 6 x 8 floor tiles (one object) with 12 small boxes (an object each) and a lamp.
testing::TestScene clutteredRoom() {
    testing::TestScene t;
    t.names = {"Room", "Lamp"};
    t.box({-3, -4, 0}, {3, 4, 3}, {0.6, 0.6, 0.6}, {}, true, 0);
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 8; ++j)
            t.quad({-3.0 + i, -4.0 + j, 0.01}, {-2.0 + i, -4.0 + j, 0.01}, {-2.0 + i, -3.0 + j, 0.01},
                   {-3.0 + i, -3.0 + j, 0.01}, {0.5, 0.5, 0.5}, {}, 0, 0);
    for (int k = 0; k < 12; ++k) {
        t.names.push_back("Box" + std::to_string(k));
        double x = -2.5 + (k % 4) * 1.5, y = -3 + (k / 4) * 2.5;
        t.box({x, y, 0.01}, {x + 0.4, y + 0.4, 0.5}, {0.7, 0.7, 0.7}, {}, false, int(t.names.size()) - 1);
    }
    t.quad({-0.5, -0.5, 2.9}, {-0.5, 0.5, 2.9}, {0.5, 0.5, 2.9}, {0.5, -0.5, 2.9}, {}, {20, 20, 20},
           kLightOnly, 1);
    return t;
}

TEST(ClusterTree, EveryPolygonHangsOnceAndSubtreesAreContiguous) {
    auto t = clutteredRoom();
    Scene sc = buildScene(t.input());
    ClusterTree ct(sc);
    ASSERT_GT(ct.size(), 10u);
    std::multiset<int> seen(ct.polygons().begin(), ct.polygons().end());
    EXPECT_EQ(seen.size(), sc.polygons.size());
    for (size_t p = 0; p < sc.polygons.size(); ++p) {
        EXPECT_EQ(seen.count(int(p)), 1u) << p;
        int c = ct.owner(int(p));
        ASSERT_GE(c, 0);
        // Owned means listed among the cluster's own polygons.
        bool own = false;
        for (int k = ct[c].begin; k < ct[c].ownEnd; ++k) own |= ct.polygons()[k] == int(p);
        EXPECT_TRUE(own) << p;
    }
    EXPECT_EQ(ct[0].begin, 0);
    EXPECT_EQ(ct[0].end, int(sc.polygons.size()));
    for (size_t c = 0; c < ct.size(); ++c) {
        const Cluster& cl = ct[int(c)];
        // The children's ranges tile [ownEnd, end) in order, and every box holds its polygons.
        int next = cl.ownEnd;
        for (int k = 0; k < cl.numChildren; ++k) {
            const Cluster& ch = ct[cl.firstChild + k];
            EXPECT_EQ(ch.parent, int(c));
            EXPECT_EQ(ch.begin, next);
            next = ch.end;
        }
        EXPECT_EQ(next, cl.end);
        for (int k = cl.begin; k < cl.end; ++k)
            for (int v = 0; v < sc.polygons[ct.polygons()[k]].geom.n; ++v) {
                const Vec3& p = sc.polygons[ct.polygons()[k]].geom.v[v];
                EXPECT_TRUE(p.x >= cl.box.lo.x && p.x <= cl.box.hi.x && p.y >= cl.box.lo.y &&
                            p.y <= cl.box.hi.y && p.z >= cl.box.lo.z && p.z <= cl.box.hi.z);
            }
    }
}

TEST(ClusterTree, ObjectsStayWholeAndLargeFacesHangHigh) {
    auto t = clutteredRoom();
    Scene sc = buildScene(t.input());
    ClusterTree ct(sc);
    // Each small box ends up in one cluster whose subtree holds exactly its six faces.
    for (int obj = 2; obj < int(t.names.size()); ++obj) {
        bool found = false;
        for (size_t c = 0; c < ct.size() && !found; ++c) {
            const Cluster& cl = ct[int(c)];
            std::set<int> objs;
            for (int k = cl.begin; k < cl.end; ++k) objs.insert(sc.polygons[ct.polygons()[k]].object);
            found = objs.size() == 1 && *objs.begin() == obj && cl.end - cl.begin == 6;
        }
        EXPECT_TRUE(found) << t.names[obj];
    }
    // The room's walls are as large as the scene: they hang from the root.
    for (int p = 0; p < 6; ++p) EXPECT_EQ(ct.owner(p), 0) << p;
}

// A room modelled as one mesh: a floor of 8 x 8 faces, four walls of 4 x 4 faces and a ceiling of 4 x 4;
// a lamp under the ceiling.
testing::TestScene roomMesh() {
    testing::TestScene t;
    t.names = {"Room", "Lamp"};
    const Rgb rho{0.5, 0.5, 0.5};
    for (int i = 0; i < 8; ++i)
        for (int j = 0; j < 8; ++j) {
            double x = -2 + 0.5 * i, y = -2 + 0.5 * j;
            t.quad({x, y, 0}, {x + 0.5, y, 0}, {x + 0.5, y + 0.5, 0}, {x, y + 0.5, 0}, rho, {});
        }
    for (int i = 0; i < 4; ++i)
        for (int k = 0; k < 4; ++k) {
            double a = -2 + i, b = a + 1, z0 = 0.75 * k, z1 = z0 + 0.75;
            t.quad({a, -2, z0}, {b, -2, z0}, {b, -2, z1}, {a, -2, z1}, rho, {});
            t.quad({a, 2, z0}, {a, 2, z1}, {b, 2, z1}, {b, 2, z0}, rho, {});
            t.quad({-2, a, z0}, {-2, a, z1}, {-2, b, z1}, {-2, b, z0}, rho, {});
            t.quad({2, a, z0}, {2, b, z0}, {2, b, z1}, {2, a, z1}, rho, {});
            t.quad({a, double(k) - 2, 3}, {a, double(k) - 1, 3}, {b, double(k) - 1, 3}, {b, double(k) - 2, 3}, rho, {});
        }
    t.quad({-0.5, -0.5, 2.9}, {-0.5, 0.5, 2.9}, {0.5, 0.5, 2.9}, {0.5, -0.5, 2.9}, {}, {20, 20, 20}, kLightOnly, 1);
    return t;
}

// Whether some cluster's subtree holds exactly the polygons in `want`.
bool someClusterHoldsExactly(const ClusterTree& ct, const std::set<int>& want) {
    for (size_t c = 0; c < ct.size(); ++c) {
        const Cluster& cl = ct[int(c)];
        std::set<int> has(ct.polygons().begin() + cl.begin, ct.polygons().begin() + cl.end);
        if (has == want) return true;
    }
    return false;
}

TEST(ClusterTree, PlanarGroupsKeepAFloorModelledWithItsWallsInOneCluster) {
    Scene sc = buildScene(roomMesh().input());
    // The room's planes: the floor's 64 faces first, then per wall cell the four walls' and the ceiling's.
    std::vector<std::set<int>> planes(6);
    for (int p = 0; p < 64; ++p) planes[0].insert(p);
    for (int p = 64; p < 144; ++p) planes[size_t(1 + (p - 64) % 5)].insert(p);
    // In space alone, the one object is cut across its planes: no cluster holds the floor and nothing else,
    // so no convolution link can take the whole floor.
    ClusterTree spatial(sc);
    EXPECT_FALSE(someClusterHoldsExactly(spatial, planes[0]));
    // With planar groups the floor (the largest plane) is split off first, then each plane holding at least
    // a sixth of what is left: every wall and the ceiling (16 faces of 80, 64, ...) are clusters of their own.
    ClusterTree planar(sc, true);
    for (size_t k = 0; k < planes.size(); ++k) EXPECT_TRUE(someClusterHoldsExactly(planar, planes[k])) << "plane " << k;
    std::vector<int> seen(sc.polygons.size(), 0);  // and every polygon still hangs exactly once
    for (int p : planar.polygons()) ++seen[size_t(p)];
    for (size_t p = 0; p < 144; ++p) EXPECT_EQ(seen[p], 1) << p;
}

TEST(ClusterTree, PlanarGroupsMakeATriangulatedTableTopOneClusterAndKeepObjectsWhole) {
    // The cluttered room plus a table (one object): a top of two triangles on four box legs. Its top is
    // large beside the legs, so in the default tree each triangle hangs from the table's cluster on its own.
    auto t = clutteredRoom();
    t.names.push_back("Table");
    int table = int(t.names.size()) - 1;
    Rgb wood{0.5, 0.4, 0.3};
    int top = t.triangle({1, 1, 0.75}, {2.2, 1, 0.75}, {2.2, 1.8, 0.75}, wood, {}, 0, table);
    t.triangle({1, 1, 0.75}, {2.2, 1.8, 0.75}, {1, 1.8, 0.75}, wood, {}, 0, table);
    for (double x : {1.0, 2.1})
        for (double y : {1.0, 1.7}) t.box({x, y, 0.01}, {x + 0.1, y + 0.1, 0.74}, wood, {}, false, table);
    Scene sc = buildScene(t.input());
    EXPECT_FALSE(someClusterHoldsExactly(ClusterTree(sc), {top, top + 1}));
    ClusterTree planar(sc, true);
    EXPECT_TRUE(someClusterHoldsExactly(planar, {top, top + 1}));
    // Each small box is still one cluster holding exactly its six faces, and the table one subtree.
    for (int obj = 2; obj < int(t.names.size()); ++obj) {
        std::set<int> faces;
        for (size_t p = 0; p < sc.polygons.size(); ++p)
            if (sc.polygons[p].object == obj) faces.insert(int(p));
        EXPECT_TRUE(someClusterHoldsExactly(planar, faces)) << t.names[size_t(obj)];
    }
}

// The cluster holding clutteredRoom's box of object 2 (its six faces), or -1.
int firstBoxCluster(const Scene& sc, const ClusterTree& ct) {
    int box = -1;
    for (size_t c = 0; c < ct.size(); ++c)
        if (ct[int(c)].end - ct[int(c)].begin == 6 && sc.polygons[ct.polygons()[ct[int(c)].begin]].object == 2)
            box = int(c);
    return box;
}

TEST(ClusterTransfer, FarClusterMatchesTheSumOfItsFacesAndStaysUnderItsBound) {
    auto t = clutteredRoom();
    Scene sc = buildScene(t.input());
    Hierarchy h(sc, size_t(-1), true);
    for (size_t i = 0; i < h.numRoots(); ++i) h[i].B = Rgb{1, 2, 3};
    h.updateClusterFlux();
    const ClusterTree& ct = h.clusters();
    // A box's cluster seen from a point on the far wall: in the far field the alpha transfer (by
    // normal class, from the centre) is the sum over faces (each from its own centre).
    int box = firstBoxCluster(sc, ct);
    ASSERT_GE(box, 0);
    Vec3 y{2.9, 3.9, 2.5}, n = normalize(Vec3{-1, -1, -0.5});
    Rgb sum;
    for (int k = ct[box].begin; k < ct[box].end; ++k) sum += fluxAt(h, ct.polygons()[k], y, &n);
    Rgb all = fluxAt(h, clusterNode(box), y, &n);
    EXPECT_NEAR(all.z, sum.z, 0.02 * sum.z);
    EXPECT_GT(all.z, 0);
    // Only the faces turned toward y count: the box's bottom and far sides add nothing; and no
    // point of a small box around y gets more than the bound.
    Bounds at;
    at.extend(y - Vec3{0.05, 0.05, 0.05});
    at.extend(y + Vec3{0.05, 0.05, 0.05});
    EXPECT_LE(all.z, fluxBound(h, clusterNode(box), at));
    // Touching boxes: each face's form factor is at most 1, so the bound is finite, at most the sum of
    // the faces' radiosities, and still above the light at a point on the box's own lit side.
    double sumB = 0;
    for (int k = ct[box].begin; k < ct[box].end; ++k) sumB += maxComponent(h[ct.polygons()[k]].B);
    double touching = fluxBound(h, clusterNode(box), ct[box].box);
    EXPECT_TRUE(std::isfinite(touching));
    EXPECT_LE(touching, sumB * (1 + 1e-12));
    Bounds b = ct[box].box;
    Vec3 beside{b.hi.x + 1e-3, 0.5 * (b.lo.y + b.hi.y), 0.5 * (b.lo.z + b.hi.z)};
    Bounds near;
    near.extend(beside);
    EXPECT_GT(fluxBound(h, clusterNode(box), near), 0.0);
    for (Vec3 nn : {Vec3{-1, 0, 0}, Vec3{0, 0, -1}, normalize(Vec3{-1, 0, -1})})
        EXPECT_LE(fluxAt(h, clusterNode(box), beside, &nn).z, fluxBound(h, clusterNode(box), near));
}

// The sweeps sum a far cluster's classes in single precision (ClassBlock). A scene at the edge of what validation
// accepts (a room a million times larger, 1e12 m^2 tiles, radiosity 1e30) holds class fluxes near 1e42, past a
// float's 3.4e38: the blocks hold them scaled by a power of two, and the light is what the double-precision sum
// (FarFieldLight) gives, finite, not an infinity.
TEST(ClusterTransfer, FarLightOfHugeFluxesStaysFiniteInSinglePrecision) {
    auto t = clutteredRoom();
    t.transform(1e6, {0, 0, 0});
    Scene sc = buildScene(t.input());
    Hierarchy h(sc, size_t(-1), true);
    for (size_t i = 0; i < h.numRoots(); ++i) h[i].B = Rgb{1e30, 2e30, 0.5e30};
    h.updateClusterFlux();
    const ClusterTree& ct = h.clusters();
    double largest = 0;
    for (const Rgb& f : ct.classFlux()) largest = std::max(largest, maxComponent(f));
    ASSERT_GT(largest, 1e39);  // past a float
    Vec3 y = ct[0].center + Vec3{2e7, 3e7, 4e7}, n = normalize(Vec3{-2, -3, -4});
    FarFieldLight far;
    ASSERT_TRUE(farFieldLight(h, clusterNode(0), y, 1.0, far));
    Rgb got = fluxAt(h, clusterNode(0), y, &n), want = far.at(y, &n);
    for (int c = 0; c < 3; ++c) {
        EXPECT_TRUE(std::isfinite(got[c])) << c;
        EXPECT_GT(want[c], 0.0) << c;
        EXPECT_NEAR(got[c], want[c], 1e-6 * want[c]) << c;
    }
}

TEST(ClusterTransfer, FarFieldLightEqualsFluxAtOverItsBallAndRefusesWhatItCannotHold) {
    auto t = clutteredRoom();
    Scene sc = buildScene(t.input());
    Hierarchy h(sc, size_t(-1), true);
    // Colours that differ by face, so a wrong class in the sum shows in every channel.
    for (size_t i = 0; i < h.numRoots(); ++i) h[i].B = Rgb{1.0 + (i % 3), 2.0 + (i % 5), 0.5 + (i % 7)};
    h.updateClusterFlux();
    const ClusterTree& ct = h.clusters();
    int box = firstBoxCluster(sc, ct);
    ASSERT_GE(box, 0);
    const Cluster& b = ct[box];
    // A ball up in a corner, seen from the box at an angle where every face is turned toward or away
    // from all of it: at() is fluxAt, to rounding, at points spread over the ball and every normal. fluxAt
    // sums the classes in single precision (ClassBlock), so to a float's rounding.
    Vec3 centre = b.center + Vec3{2.1, 2.9, 2.3};
    double radius = 0.3;
    FarFieldLight far;
    ASSERT_TRUE(farFieldLight(h, clusterNode(box), centre, radius, far));
    int lit = 0;
    for (int i = 0; i < 200; ++i) {
        // Fibonacci directions on the sphere, at radii over the whole ball (to its surface).
        double z = 1.0 - (i + 0.5) / 100.0, s = std::sqrt(std::max(0.0, 1.0 - z * z)), a = 2.39996323 * i;
        Vec3 y = centre + Vec3{s * std::cos(a), s * std::sin(a), z} * (radius * ((i % 10) + 1) / 10.0);
        Vec3 n = normalize(Vec3{-std::cos(2.4 * i), -std::sin(2.4 * i), (i % 2 ? -1.0 : 1.0) * std::fabs(z)});
        ASSERT_LE(length(y - centre), radius * (1 + 1e-12));
        Rgb want = fluxAt(h, clusterNode(box), y, &n), got = far.at(y, &n);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], want[c], 1e-6 * std::fabs(want[c]) + 1e-12) << i;
        lit += want.x > 0;
        Rgb want0 = fluxAt(h, clusterNode(box), y, nullptr), got0 = far.at(y, nullptr);
        EXPECT_NEAR(got0.y, want0.y, 1e-6 * want0.y + 1e-12) << i;
    }
    EXPECT_GT(lit, 20);  // the comparison saw light, not only zeros
    // A ball level with the box's top: the top's class turns toward part of it only.
    EXPECT_FALSE(farFieldLight(h, clusterNode(box), Vec3{b.center.x + 3, b.center.y, b.box.hi.z}, 0.3, far));
    // A ball reaching into the box's near field, and one holding the box's centre.
    EXPECT_FALSE(farFieldLight(h, clusterNode(box), b.center + Vec3{1.0, 1.0, 1.0}, 1.5, far));
    EXPECT_FALSE(farFieldLight(h, clusterNode(box), b.center, 0.1, far));
}

// A gather skips a source cluster marked dark (Solver::dark): the mark must hold exactly when nothing below has
// light, since a lit face under a cluster marked dark would lose its light with no other sign.
TEST(ClusterTransfer, DarkMeansNoLightBelowAndClearsUpTheTreeFromOneLitFace) {
    auto t = clutteredRoom();
    Scene sc = buildScene(t.input());
    Hierarchy h(sc, size_t(-1), true);
    for (size_t i = 0; i < h.numRoots(); ++i) h[i].B = Rgb{};
    h.updateClusterFlux();
    const ClusterTree& ct = h.clusters();
    for (size_t c = 0; c < ct.size(); ++c) EXPECT_TRUE(ct.dark(int(c))) << c;
    int box = firstBoxCluster(sc, ct);
    ASSERT_GE(box, 0);
    // One face of the box lit, in one channel only.
    int lit = ct.polygons()[size_t(ct[box].begin)];
    h[size_t(lit)].B = Rgb{0, 0, 0.25};
    h.updateClusterFlux();
    std::set<int> above;
    for (int c = ct.owner(lit); c >= 0; c = ct[c].parent) above.insert(c);
    EXPECT_TRUE(above.count(box));
    for (size_t c = 0; c < ct.size(); ++c) EXPECT_EQ(ct.dark(int(c)), above.count(int(c)) == 0) << c;
    // What a dark cluster gives is zero at any point, near or far; the lit box gives some light in front of its face.
    Vec3 n{0, 0, -1};
    for (size_t c = 0; c < ct.size(); ++c)
        if (ct.dark(int(c))) {
            EXPECT_EQ(maxComponent(fluxAt(h, clusterNode(int(c)), ct[int(c)].center + Vec3{0.1, 0.1, 0.2}, &n)), 0.0);
            EXPECT_EQ(maxComponent(fluxAt(h, clusterNode(int(c)), Vec3{0, 0, 2.5}, &n)), 0.0);
        }
    const Vec3 front = h[size_t(lit)].center + sc.polygons[size_t(lit)].normal * 0.3;
    const Vec3 back = -sc.polygons[size_t(lit)].normal;
    EXPECT_GT(fluxAt(h, clusterNode(box), front, &back).z, 0.0);
}

}  // namespace
}  // namespace penumbra
