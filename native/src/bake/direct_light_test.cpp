#include "bake/direct_light.h"

#include <gtest/gtest.h>

#include <cmath>

#include "geometry/form_factor.h"
#include "penumbra.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

using testing::TestScene;

// A 1 x 1 lamp facing down at height 1 over a 4 x 4 floor, and optionally an opaque card just under
// the lamp hiding its x < cut part from everything below; `cardFlag` goes to the card's faces.
TestScene lampOverFloor(double rho, bool card, double cut = 0.3, uint8_t cardFlag = 0) {
    TestScene t;
    t.names = {"Floor", "Lamp", "Card"};
    t.quad({-2, -2, 0}, {2, -2, 0}, {2, 2, 0}, {-2, 2, 0}, {rho, rho, rho}, {}, 0, 0);
    t.quad({-0.5, -0.5, 1}, {-0.5, 0.5, 1}, {0.5, 0.5, 1}, {0.5, -0.5, 1}, {}, {10, 10, 10}, kLightOnly, 1);
    if (card) {
        double z = 0.99;
        // Both sides, so it blocks whichever way it is seen and reflects nothing (albedo 0).
        t.quad({-0.6, -0.6, z}, {-0.6, 0.6, z}, {cut, 0.6, z}, {cut, -0.6, z}, {}, {}, cardFlag, 2);
        t.quad({-0.6, -0.6, z}, {cut, -0.6, z}, {cut, 0.6, z}, {-0.6, 0.6, z}, {}, {}, cardFlag, 2);
    }
    return t;
}

Polygon lampPart(double x0, double x1) {
    Polygon g;
    g.push({x0, -0.5, 1});
    g.push({x0, 0.5, 1});
    g.push({x1, 0.5, 1});
    g.push({x1, -0.5, 1});
    return g;
}

// Only the floor reflects and nothing lights it back: its radiance is exactly rho E F(p) / pi.
TEST(FinalGather, UnoccludedLampIsExactAtEveryPoint) {
    const double rho = 0.5, E = 10;
    TestScene t = lampOverFloor(rho, false);
    for (bool gather : {false, true}) {
        Settings s;
        s.finalGather = gather;
        auto sol = solve(t.input(), s, nullptr);
        double worst = 0;
        std::vector<float> pts, nrm;
        for (int i = 0; i <= 40; ++i)
            for (int j = 0; j <= 40; ++j) {
                pts.insert(pts.end(), {float(-2 + 0.1 * i), float(-2 + 0.1 * j), 0.0f});
                nrm.insert(nrm.end(), {0, 0, 1});
            }
        auto L = sol->radiance(pts.data(), nrm.data(), pts.size() / 3);
        for (size_t k = 0; k < L.size() / 3; ++k) {
            Vec3 p{pts[k * 3], pts[k * 3 + 1], 0};
            double expect = rho * E * pointToPolygonFormFactor(p, {0, 0, 1}, lampPart(-0.5, 0.5)) / M_PI;
            worst = std::max(worst, std::fabs(L[k * 3] - expect) / expect);
        }
        if (gather)
            EXPECT_LT(worst, 2e-4);  // the point-source shortcut for small far faces; float32 output
        else
            EXPECT_GT(worst, 2e-3);  // element averages: why the gather exists
        std::printf("final gather %d: worst relative error %.2e\n", int(gather), worst);
    }
}

// Behind the card only the lamp's x > cut part is visible from points well below it: the visible
// form factor is that part's, up to the visibility grid's steps.
TEST(FinalGather, HalfHiddenLampSeesItsVisiblePart) {
    const double rho = 0.5, E = 10;
    TestScene t = lampOverFloor(rho, true, 0.0);
    Settings s;
    auto sol = solve(t.input(), s, nullptr);
    RayCaster rays(sol->scene());
    DirectLight direct(sol->scene(), rays, 64, {});
    const Vec3 off = sol->scene().offset;
    for (double x : {-1.5, -0.5, 0.0, 0.2, 0.5, 1.5}) {
        Vec3 p{x, 0.1, 0};
        // The card at z = 0.99 hides, from p, the lamp points whose line to p crosses x < 0 there.
        double xc = x + (0.0 - x) * (1.0 / 0.99);  // lamp x seen through the card's edge
        double lo = std::clamp(xc, -0.5, 0.5);
        double expect = lo < 0.5 ? pointToPolygonFormFactor(p, {0, 0, 1}, lampPart(lo, 0.5)) : 0.0;
        // The floor is polygon 0; the card's two sides reflect nothing.
        Rgb H = direct.irradiance(p - off, {0, 0, 1}, 0);
        double full = pointToPolygonFormFactor(p, {0, 0, 1}, lampPart(-0.5, 0.5));
        EXPECT_NEAR(H.x / E, expect, 0.02 * full) << "x = " << x;
    }
}

// A seed turns the gather's Sobol' points: behind the card's edge each seed reads the visible part through
// other points, within the same steps of it.
TEST(FinalGather, ASeedTurnsTheGathersPointsNotItsAnswer) {
    const double E = 10;
    TestScene t = lampOverFloor(0.5, true, 0.0);
    auto sol = solve(t.input(), Settings{}, nullptr);
    RayCaster rays(sol->scene());
    const Vec3 off = sol->scene().offset;
    const std::vector<double> xs = {-1.5, -0.5, 0.0, 0.2, 0.5, 1.5};
    std::vector<double> read[2];
    for (int k = 0; k < 2; ++k) {
        DirectLight direct(sol->scene(), rays, 64, {}, k == 0 ? 0 : 11);
        for (double x : xs) {
            Vec3 p{x, 0.1, 0};
            double xc = x + (0.0 - x) * (1.0 / 0.99);
            double lo = std::clamp(xc, -0.5, 0.5);
            double expect = lo < 0.5 ? pointToPolygonFormFactor(p, {0, 0, 1}, lampPart(lo, 0.5)) : 0.0;
            double full = pointToPolygonFormFactor(p, {0, 0, 1}, lampPart(-0.5, 0.5));
            read[k].push_back(direct.irradiance(p - off, {0, 0, 1}, 0).x / E);
            EXPECT_NEAR(read[k].back(), expect, 0.02 * full) << "x = " << x << ", seed " << k;
        }
    }
    EXPECT_NE(read[0], read[1]);
}

// A card hiding the whole lamp from the floor's middle: in shadow as it is, but hidden from shadow rays
// (Ray Visibility > Shadow off, kNoLampShadow) it lets the final gather's rays through, and the floor
// gets the bare lamp's light exactly (the card reflects nothing, so nothing else reaches the floor).
TEST(FinalGather, CardHiddenFromShadowRaysLetsTheLampThrough) {
    const double rho = 0.5, E = 10;
    for (uint8_t flag : {uint8_t(0), uint8_t(kNoLampShadow)}) {
        TestScene t = lampOverFloor(rho, true, 0.6, flag);
        auto sol = solve(t.input(), Settings{}, nullptr);
        for (double x : {-0.3, 0.0, 0.25})
            for (double y : {-0.2, 0.1}) {
                float pt[3] = {float(x), float(y), 0}, nrm[3] = {0, 0, 1};
                double L = sol->radiance(pt, nrm, 1)[0];
                double bare = rho * E * pointToPolygonFormFactor({pt[0], pt[1], 0}, {0, 0, 1}, lampPart(-0.5, 0.5)) / M_PI;
                EXPECT_NEAR(L, flag ? bare : 0.0, 1e-3 * bare) << "flag " << int(flag) << " at " << x << ", " << y;
            }
    }
}

// The same card under a lamp whose Cast Shadow is off (kCastsNoShadow): the card hides nothing, at every
// bake point (the final gather casts no rays to it) and in the elements' light (its element links are taken
// as unoccluded), where Cycles' bake under such a card gives the bare light (blender_tests/test_ray_visibility.py).
TEST(FinalGather, LampThatCastsNoShadowShinesThroughTheCard) {
    const double rho = 0.5, E = 10;
    TestScene t = lampOverFloor(rho, true, 0.6);
    t.flags[1] |= kCastsNoShadow;
    for (bool gather : {true, false}) {
        Settings s;
        s.finalGather = gather;
        auto sol = solve(t.input(), s, nullptr);
        double worst = 0;
        for (double x : {-0.3, 0.0, 0.25})
            for (double y : {-0.2, 0.1}) {
                float pt[3] = {float(x), float(y), 0}, nrm[3] = {0, 0, 1};
                double L = sol->radiance(pt, nrm, 1)[0];
                double bare = rho * E * pointToPolygonFormFactor({pt[0], pt[1], 0}, {0, 0, 1}, lampPart(-0.5, 0.5)) / M_PI;
                worst = std::max(worst, std::fabs(L / bare - 1));
            }
        // Exact with the gather; the elements' light is their mean over each element.
        EXPECT_LT(worst, gather ? 1e-3 : 0.03) << "final gather " << gather;
    }
}

// Two closed rooms stacked 1 mm apart with their walls in the same planes; the lamp is in the lower
// one. Nothing reaches the sealed upper room, with or without the final gather (the display used to
// blend the lower walls' elements into the upper walls' points across the shared plane).
TEST(FinalGather, SealedRoomAboveALitRoomStaysBlack) {
    TestScene t;
    t.names = {"Lower", "Upper", "Lamp"};
    t.box({-1, -1, 0}, {1, 1, 2}, {0.6, 0.6, 0.6}, {}, true, 0);
    t.box({-1, -1, 2.001}, {1, 1, 4.001}, {0.6, 0.6, 0.6}, {}, true, 1);
    t.quad({-0.25, -0.25, 1.9}, {-0.25, 0.25, 1.9}, {0.25, 0.25, 1.9}, {0.25, -0.25, 1.9}, {}, {30, 30, 30},
           kLightOnly, 2);
    for (bool gather : {false, true}) {
        Settings s;
        s.finalGather = gather;
        auto sol = solve(t.input(), s, nullptr);
        std::vector<float> pts, nrm;
        // Points on the wall x = -1 (normal +x) in both rooms.
        for (int i = 0; i < 20; ++i)
            for (int j = 0; j < 20; ++j) {
                double y = -0.95 + 0.1 * i, z = 0.05 + 0.1 * j;
                pts.insert(pts.end(), {-1.0f, float(y), float(z)});
                pts.insert(pts.end(), {-1.0f, float(y), float(z + 2.001)});
                nrm.insert(nrm.end(), {1, 0, 0, 1, 0, 0});
            }
        auto L = sol->radiance(pts.data(), nrm.data(), pts.size() / 3);
        double lower = 0, upper = 0;
        for (size_t k = 0; k < L.size() / 3; k += 2) {
            lower += L[k * 3];
            upper = std::max(upper, double(L[(k + 1) * 3]));
        }
        lower /= L.size() / 6;
        EXPECT_GT(lower, 0.05);
        EXPECT_LT(upper, 1e-6 * lower) << "final gather " << gather;
    }
}

}  // namespace
}  // namespace penumbra
