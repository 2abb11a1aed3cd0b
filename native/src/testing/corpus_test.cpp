// The C++ side of the pathological corpus (native/python/test_corpus.py has the full set): the cases
// most likely to touch memory or arithmetic edge cases, so that they also run under ASan + UBSan.
#include <gtest/gtest.h>

#include <cmath>

#include "penumbra.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

using testing::TestScene;

Settings cheap() {
    Settings s;
    s.epsilon = 0.002;
    s.threads = 2;
    return s;
}

// Samples at every face's corners and centre, with the face's normal. Lamps (light-only faces) are
// not surfaces anything is baked on: a point on one has no value of its own, only whatever surface lies
// within the reconstruction's float32 tolerance (which grows far from the origin).
struct Probe {
    std::vector<float> pts, nrm;
    explicit Probe(const TestScene& t, int object = -1) {
        for (size_t p = 0; p < t.flags.size(); ++p) {
            if (object >= 0 && t.objectIndex[p] != object) continue;
            if (t.flags[p] & kLightOnly) continue;
            int nv = t.polygons[p * 4 + 3] < 0 ? 3 : 4;
            Vec3 v[4], c;
            for (int k = 0; k < nv; ++k) {
                const float* q = &t.vertices[size_t(t.polygons[p * 4 + k]) * 3];
                v[k] = {q[0], q[1], q[2]};
                c += v[k] / nv;
            }
            Vec3 n = normalize(cross(v[1] - v[0], v[2] - v[0]));
            if (!(length(n) > 0)) continue;
            for (int k = 0; k <= nv; ++k) {
                Vec3 q = k < nv ? v[k] : c;
                pts.insert(pts.end(), {float(q.x), float(q.y), float(q.z)});
                nrm.insert(nrm.end(), {float(n.x), float(n.y), float(n.z)});
            }
        }
    }
    std::vector<float> radiance(const Solution& s) const { return s.radiance(pts.data(), nrm.data(), pts.size() / 3); }
};

void expectFiniteNonNegative(const std::vector<float>& v) {
    for (float x : v) {
        ASSERT_TRUE(std::isfinite(x));
        ASSERT_GE(x, 0.0f);
    }
}

std::unique_ptr<Solution> solveAndCheck(const TestScene& t, const Settings& s = cheap()) {
    auto sol = solve(t.input(), s, nullptr);
    expectFiniteNonNegative(Probe(t).radiance(*sol));
    expectFiniteNonNegative(testing::bakeAll(*sol, t, 64));
    return sol;
}

std::string errorOf(const TestScene& t, const Settings& s = cheap()) {
    try {
        solve(t.input(), s, nullptr);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(Corpus, NanAndInfVerticesNameTheObject) {
    auto t = testing::litRoom();
    t.vertices[t.polygons[4 * 7] * 3 + 1] = NAN;  // face 7: the block's first face
    EXPECT_NE(errorOf(t).find("'Block'"), std::string::npos);
    t = testing::litRoom();
    t.vertices[2] = -INFINITY;
    EXPECT_NE(errorOf(t).find("'Room'"), std::string::npos);
    t = testing::litRoom();
    t.vertices[5] = 3e30f;
    EXPECT_NE(errorOf(t).find("from the origin"), std::string::npos);
}

TEST(Corpus, DegenerateAndMalformedFacesSolve) {
    auto t = testing::litRoom();
    Rgb g{0.5, 0.5, 0.5};
    t.triangle({0.2, 0.2, 1}, {0.2, 0.2, 1}, {0.4, 0.3, 1}, g, {});                   // zero area
    t.triangle({0, 0, 1.2}, {0.25, 0.25, 1.2}, {0.5, 0.5, 1.2}, g, {});              // collinear
    t.triangle({-0.9, -0.9, 0.5}, {0.9, -0.9, 0.5}, {0.9, -0.89999, 0.5}, g, {});    // needle
    t.quad({-0.5, 0.6, 1}, {0.5, 0.6, 1.3}, {0.5, 0.9, 1}, {-0.5, 0.9, 0.7}, g, {}); // warped
    t.quad({-0.9, -0.9, 1.5}, {0, -0.9, 1.5}, {0, 0, 1.5}, {-0.6, -0.6, 1.5}, g, {}); // concave
    t.quad({0.3, 0.3, 1.6}, {0.6, 0.6, 1.6}, {0.6, 0.3, 1.6}, {0.3, 0.6, 1.6}, g, {}); // bow tie
    for (int k = 0; k < 3; ++k)                                                       // coplanar copies
        t.quad({0.5, -0.9, 0.4}, {0.9, -0.9, 0.4}, {0.9, -0.5, 0.4}, {0.5, -0.5, 0.4}, g, {});
    t.box({0.4, 0.4, -0.2}, {0.8, 0.8, 0.3}, g, {});                                  // through the floor
    t.box({-0.9, 0.4, 0.001}, {-0.6, 0.7, 0.3}, g, {});                               // 1 mm above it
    auto sol = solveAndCheck(t);
    EXPECT_GE(sol->scene().degenerateSkipped, 2u);
}

TEST(Corpus, SealedBoxInALitRoomStaysExactlyBlack) {
    auto t = testing::litRoom();
    Rgb g{0.7, 0.7, 0.7};
    t.names.push_back("Safe");
    t.box({0.375, -0.75, 0}, {0.875, -0.25, 0.5}, g, {}, false, 3);
    t.names.push_back("Inside");
    t.box({0.40625, -0.71875, 0.03125}, {0.84375, -0.28125, 0.46875}, g, {}, true, 4);
    // The solution itself: every element inside is exactly dark, at a coarse and at the default epsilon.
    for (double eps : {0.002, Settings{}.epsilon}) {
        Settings s = cheap();
        s.epsilon = eps;
        auto sol = solveAndCheck(t, s);
        const Hierarchy& h = sol->hierarchy();
        size_t inside = 0;
        for (size_t i = 0; i < h.size(); ++i) {
            if (h.scene().polygons[h[i].polygon].object != 4) continue;
            ++inside;
            for (int c = 0; c < 3; ++c) ASSERT_EQ(h[i].B[c], 0.0) << "element " << i << " eps " << eps;
        }
        EXPECT_GE(inside, 6u);
        float outside = 0;
        for (float x : Probe(t, 3).radiance(*sol)) outside = std::max(outside, x);
        EXPECT_GT(outside, 0.01f);
        // The reconstruction at points inside. At epsilon 0.002 it blends in coarse leaves of parallel
        // surfaces a few cm away (the room's floor under the safe's floor): reported, see
        // docs/stability.md; asserted at the default epsilon only.
        if (eps == Settings{}.epsilon) {
            for (float x : Probe(t, 4).radiance(*sol)) ASSERT_EQ(x, 0.0f);
        }
    }
}

TEST(Corpus, PartlyHiddenClusterReceiversShareTheirLightByEachFacesOwnVisibility) {
    // The safe of the test above, open on top: its inner faces see the lamp only through the opening, its
    // outer faces see it in full. A link into its cluster is kept, and each face takes its own visible share
    // of the source (Refiner::shareByFaces) instead of the cluster's one share, which would light the inside
    // like the outside. Against the same scene solved face by face (clustering off), the light on the inner
    // faces agrees within 4 % of the brightest (2.5 % measured; 1.8 % when the cluster was opened instead).
    auto t = testing::litRoom();
    Rgb g{0.7, 0.7, 0.7};
    t.names.push_back("Safe");
    int safe = int(t.polygons.size() / 4);
    t.box({0.375, -0.75, 0}, {0.875, -0.25, 0.5}, g, {}, false, 3);
    t.names.push_back("Inside");
    int inside = int(t.polygons.size() / 4);
    t.box({0.40625, -0.71875, 0.03125}, {0.84375, -0.28125, 0.46875}, g, {}, true, 4);
    // Without the tops (each box's second face), the inside is open to the room above.
    for (int p : {inside + 1, safe + 1}) {
        t.polygons.erase(t.polygons.begin() + 4 * p, t.polygons.begin() + 4 * (p + 1));
        t.reflectance.erase(t.reflectance.begin() + 3 * p, t.reflectance.begin() + 3 * (p + 1));
        t.emission.erase(t.emission.begin() + 3 * p, t.emission.begin() + 3 * (p + 1));
        t.flags.erase(t.flags.begin() + p);
        t.objectIndex.erase(t.objectIndex.begin() + p);
    }
    Settings s = cheap();
    auto clustered = solveAndCheck(t, s);
    EXPECT_GT(clustered->report().count("shared_cluster_links"), 0u);
    s.clustering = false;
    auto exact = solveAndCheck(t, s);
    std::vector<float> a = Probe(t, 4).radiance(*clustered), b = Probe(t, 4).radiance(*exact);
    ASSERT_EQ(a.size(), b.size());
    float peak = 0, worst = 0;
    for (size_t i = 0; i < a.size(); ++i) peak = std::max(peak, b[i]);
    for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::fabs(a[i] - b[i]));
    ASSERT_GT(peak, 0.01f);
    EXPECT_LT(worst, 0.04f * peak);
}

TEST(Corpus, MovingAndScalingTheSceneChangesNothing) {
    auto base = testing::litRoom();
    auto ref = solve(base.input(), cheap(), nullptr);
    Probe probe(base);
    auto expect = probe.radiance(*ref);
    for (auto [scale, offset] : {std::pair{1e-3, 0.0}, std::pair{1e3, 0.0}, std::pair{1.0, 1e5}}) {
        SCOPED_TRACE(scale);
        SCOPED_TRACE(offset);
        auto t = base;
        t.transform(scale, {offset, -offset, offset});
        auto sol = solve(t.input(), cheap(), nullptr);
        Probe moved(t);
        auto got = moved.radiance(*sol);
        ASSERT_EQ(got.size(), expect.size());
        float peak = *std::max_element(expect.begin(), expect.end());
        for (size_t i = 0; i < got.size(); ++i)
            ASSERT_NEAR(got[i], expect[i], std::max(1e-3 * expect[i], 1e-6 * peak)) << i;
    }
}

TEST(Corpus, ExtremeAlbedoAndPowerStayFinite) {
    for (double rho : {0.0, 0.999}) {
        auto t = testing::litRoom();
        for (size_t i = 0; i < t.reflectance.size(); ++i)
            if (t.reflectance[i] > 0) t.reflectance[i] = float(rho);
        Settings s = cheap();
        s.maxIterations = 60;
        s.minSize = 0.05;
        auto sol = solveAndCheck(t, s);
        if (rho == 0) {
            for (float x : Probe(t).radiance(*sol)) ASSERT_EQ(x, 0.0f);
        }
    }
    for (float power : {1e-9f, 1e9f}) {
        auto t = testing::litRoom();
        for (float& e : t.emission) e *= power;
        solveAndCheck(t);
    }
    auto t = testing::litRoom();
    t.reflectance[4] = 1.0f;
    EXPECT_NE(errorOf(t).find("albedo"), std::string::npos);
}

TEST(Corpus, EmptyEmitterOnlyAndSinglePolygonScenes) {
    TestScene empty;
    EXPECT_NE(errorOf(empty).find("no faces"), std::string::npos);
    TestScene lamp;
    lamp.quad({0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1}, {}, {5, 5, 5}, kLightOnly);
    EXPECT_NE(errorOf(lamp).find("no mesh faces"), std::string::npos);
    TestScene one;
    one.quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}, {1, 1, 1});
    auto sol = solveAndCheck(one);
    for (float x : Probe(one).radiance(*sol)) EXPECT_EQ(x, 0.0f);
}

TEST(Corpus, BudgetsStopBeforeAllocating) {
    auto t = testing::litRoom();
    Settings s = cheap();
    s.maxElements = 500;
    EXPECT_THROW(solve(t.input(), s, nullptr), BudgetExceeded);
    s = cheap();
    s.maxLinks = 100;
    EXPECT_THROW(solve(t.input(), s, nullptr), BudgetExceeded);
    s = cheap();
    s.clustering = false;  // the face-pair guard is for the unclustered solver only
    s.maxFacePairs = 50;
    EXPECT_THROW(solve(t.input(), s, nullptr), BudgetExceeded);
    s = cheap();
    s.maxTexels = 1000;
    auto sol = solve(t.input(), s, nullptr);
    EXPECT_THROW(testing::bakeAll(*sol, t, 32), BudgetExceeded);
}

TEST(Corpus, LightmapsWithOccludersAreBitIdenticalAcrossThreadCounts) {
    auto t = testing::litRoom();
    t.box({0.25, -0.75, 0.5}, {0.75, -0.25, 0.625}, {0.5, 0.5, 0.5}, {});
    Settings s1 = cheap(), s2 = cheap();
    s1.threads = 1;
    s2.threads = 2;
    auto a = testing::bakeAll(*solve(t.input(), s1, nullptr), t, 96);
    auto b = testing::bakeAll(*solve(t.input(), s2, nullptr), t, 96);
    auto c = testing::bakeAll(*solve(t.input(), s2, nullptr), t, 96);
    ASSERT_EQ(a.size(), b.size());
    float lit = 0;
    for (size_t i = 0; i < a.size(); i += 4) lit = std::max(lit, a[i]);
    EXPECT_GT(lit, 0.01f);
    for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i], b[i]) << i;
        ASSERT_EQ(b[i], c[i]) << i;
    }
}

}  // namespace
}  // namespace penumbra
