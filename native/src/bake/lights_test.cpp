#include "bake/lights.h"

#include <gtest/gtest.h>

#include <cmath>

#include "geometry/form_factor.h"
#include "penumbra.h"
#include "testing/scenes.h"
#include "util/error.h"

namespace penumbra {
namespace {

using testing::TestScene;

constexpr double kRho = 0.5;

// One open 10 x 10 floor: it cannot see itself, so its radiance is exactly rho E / pi for the
// irradiance E the lights give it, whatever the solve does with the reflected light.
TestScene openFloor() {
    TestScene t;
    t.names = {"Floor", "Lamp"};
    t.quad({-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}, {kRho, kRho, kRho}, {}, 0, 0);
    return t;
}

std::unique_ptr<Solution> solveLit(const TestScene& t, const std::vector<Light>& lights, Settings s = {}) {
    SceneInput in = t.input();
    in.lights = lights;
    return solve(in, s, nullptr);
}

// Irradiance on the upward floor at (x, y, 0), read back from the solution's radiance.
double floorIrradiance(const Solution& sol, double x, double y) {
    float p[3] = {float(x), float(y), 0}, n[3] = {0, 0, 1};
    return sol.radiance(p, n, 1)[0] * M_PI / kRho;
}

Light pointLight(Vec3 pos, double power, double radius) {
    Light l;
    l.type = LightType::Point;
    l.position = pos;
    l.value = {power, power, power};
    l.radius = radius;
    return l;
}

TEST(Lights, PointLightInverseSquareWithCyclesRadius) {
    const Vec3 pos{0.3, -0.2, 2};
    const double P = 100;
    for (double r : {0.0, 0.25}) {
        auto sol = solveLit(openFloor(), {pointLight(pos, P, r)});
        double worst = 0;
        for (double x : {-3.0, -1.0, 0.0, 0.3, 1.5, 3.0})
            for (double y : {-2.5, -0.2, 0.7, 2.0}) {
                Vec3 d = pos - Vec3{x, y, 0};
                double d2 = length2(d);
                double expect = P * (d.z / std::sqrt(d2)) / (4 * M_PI * (d2 + r * r));
                worst = std::max(worst, std::fabs(floorIrradiance(*sol, x, y) / expect - 1));
            }
        EXPECT_LT(worst, 1e-3) << "radius " << r;
    }
}

// Cycles 3.4 spot: the point light's intensity, times the cosine from the axis inside the cone and a
// smoothstep over the blend band. A Cycles bake of this spot (100 W, 90 degrees, blend 0.3, 2 m up)
// gave E = 1.98942, 1.55131, 0.89591, 0.64848 and 0.22280 W/m^2 at 0, 20, 35, 39 and 42 degrees.
TEST(Lights, SpotInsideTheConeAndInTheBlend) {
    Light l = pointLight({0, 0, 2}, 100, 0);
    l.type = LightType::Spot;
    l.direction = {0, 0, -1};
    l.spotSize = M_PI / 2;
    l.spotBlend = 0.3;
    auto sol = solveLit(openFloor(), {l});
    const double cycles[] = {1.98942, 1.55131, 0.89591, 0.64848, 0.22280};
    const double degrees[] = {0, 20, 35, 39, 42};
    for (int i = 0; i < 5; ++i) {
        // At the float32 point the solver is handed: the blend band is steep.
        double x = float(2 * std::tan(degrees[i] * M_PI / 180)), d2 = 4 + x * x, c = 2 / std::sqrt(d2);
        double cosEdge = std::cos(M_PI / 4), smooth = (1 - cosEdge) * 0.3, t = c - cosEdge;
        double s = t >= smooth ? 1.0 : (t / smooth) * (t / smooth) * (3 - 2 * t / smooth);
        double expect = 100 / (4 * M_PI) * c / d2 * c * s;
        double got = floorIrradiance(*sol, x, 0);
        // The final gather evaluates a hair (1e-5 of the diagonal) toward the face's centre, and in the
        // blend band the light falls by 8 % per millimetre: 0.13 % at 42 degrees.
        EXPECT_NEAR(got / expect, 1, 2e-3) << degrees[i] << " degrees";
        EXPECT_NEAR(got / cycles[i], 1, 0.01) << degrees[i] << " degrees against Cycles";
    }
    EXPECT_EQ(floorIrradiance(*sol, 2 * std::tan(50 * M_PI / 180), 0), 0.0);  // outside the cone
}

// A lamp of radius r integrated by brute force at a point of the upward floor: the disk facing the point
// (`sphere` false) in polar area steps, or the sphere's visible cap in steps of solid angle, each
// element weighed by the receiver's cosine and the spot's cone at its own direction.
double bruteForce(const Light& l, const Vec3& p) {
    const int N = 400;
    Vec3 toC = l.position - p;
    double d = length(toC);
    Vec3 w = toC / d, a = std::fabs(w.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    Vec3 t1 = normalize(cross(w, a)), t2 = cross(w, t1);
    double r = l.radius, L = l.value.x / (4 * M_PI * M_PI * r * r), sum = 0;
    auto att = [&](const Vec3& fromLamp) { return l.type == LightType::Spot ? spotAttenuation(l, dot(fromLamp, l.direction)) : 1.0; };
    for (int i = 0; i < N; ++i)
        for (int j = 0; j < N; ++j) {
            double phi = 2 * M_PI * (j + 0.5) / N;
            if (!l.sphere) {
                double rho = r * (i + 0.5) / N, dA = rho * (r / N) * (2 * M_PI / N);
                Vec3 q = l.position + (t1 * std::cos(phi) + t2 * std::sin(phi)) * rho;
                Vec3 v = q - p;
                double t2q = length2(v);
                Vec3 u = v / std::sqrt(t2q);
                sum += L * std::max(0.0, u.z) * dot(u, w) * att(-u) * dA / t2q;
            } else {
                double cosA = std::sqrt(1 - r * r / (d * d));
                double cg = 1 - (1 - cosA) * (i + 0.5) / N, sg = std::sqrt(1 - cg * cg);
                double dOmega = (1 - cosA) / N * (2 * M_PI / N);
                Vec3 u = w * cg + (t1 * std::cos(phi) + t2 * std::sin(phi)) * sg;
                sum += L * std::max(0.0, u.z) * att(-u) * dOmega;
            }
        }
    return sum;
}

// Cycles 4.0+: a lamp with Soft Falloff off is a sphere (wholly above the horizon exactly the bare
// point's irradiance), and a spot no longer multiplies by the cosine from its axis. Spots with a radius,
// disk or sphere, weigh each direction by the cone: against a brute-force integral.
TEST(Lights, SphereLampsAndSpotsWithARadius) {
    const Vec3 pos{0.4, -0.3, 1.0};
    Light sphere = pointLight(pos, 120, 0.5);
    sphere.sphere = true;
    auto sol = solveLit(openFloor(), {sphere});
    for (double x : {0.4, 1.0, -1.5, 2.5}) {
        Vec3 d = pos - Vec3{x, 0.5, 0};
        double d2 = length2(d), expect = 120 * (d.z / std::sqrt(d2)) / (4 * M_PI * d2);
        EXPECT_NEAR(floorIrradiance(*sol, x, 0.5) / expect, 1, 1e-3) << x;
    }
    for (bool asSphere : {false, true})
        for (bool cosine : {false, true}) {
            Light l = pointLight(pos, 120, 0.5);
            l.type = LightType::Spot;
            l.sphere = asSphere;
            l.spotCosine = cosine;
            l.spotSize = M_PI / 2;
            l.spotBlend = 0.3;
            auto s = solveLit(openFloor(), {l});
            for (double x : {0.4, 0.9, 1.3, 1.6}) {
                Vec3 p{x, -0.3, 0};
                double expect = bruteForce(l, p), got = floorIrradiance(*s, p.x, p.y);
                EXPECT_NEAR(got, expect, 0.004 * bruteForce(l, Vec3{0.4, -0.3, 0}))
                    << (asSphere ? "sphere" : "disk") << (cosine ? " with" : " without") << " cosine at x " << x;
            }
        }
    // Without the cosine, a point spot's irradiance inside the cone is the point lamp's.
    Light bare = pointLight({0, 0, 2}, 100, 0);
    bare.type = LightType::Spot;
    bare.spotSize = M_PI / 2;
    bare.spotCosine = false;
    auto s = solveLit(openFloor(), {bare});
    double x = 1.2, d2 = 4 + x * x;
    EXPECT_NEAR(floorIrradiance(*s, x, 0) / (100 * (2 / std::sqrt(d2)) / (4 * M_PI * d2)), 1, 1e-3);
}

TEST(Lights, SunAtTwoAnglesAndTwoSizes) {
    for (double tilt : {0.0, 40.0})
        for (double size : {0.0, 10.0, 40.0}) {
            Light l;
            l.type = LightType::Sun;
            double th = tilt * M_PI / 180;
            l.direction = {std::sin(th), 0, -std::cos(th)};
            l.value = {3, 3, 3};
            l.angle = size * M_PI / 180;
            auto sol = solveLit(openFloor(), {l});
            // blender-facts: Cycles measured 0.99809 and 0.96891 of the strength for 10 and 40 degrees.
            double f = size == 0 ? 1.0 : size == 10 ? 0.99808 : 0.96888;
            double expect = 3 * f * std::cos(th);
            for (double x : {-2.0, 0.0, 3.0})
                EXPECT_NEAR(floorIrradiance(*sol, x, 1.0) / expect, 1, 1e-4) << tilt << " deg tilt, " << size << " deg sun";
        }
}

TEST(Lights, UniformWorldOnAnOpenPlane) {
    Light l;
    l.type = LightType::World;
    l.value = {0.2, 0.4, 0.8};
    auto sol = solveLit(openFloor(), {l});
    float p[3] = {1.2f, -0.7f, 0}, n[3] = {0, 0, 1};
    auto L = sol->radiance(p, n, 1);
    // E = pi L, reflected rho E / pi = rho L.
    EXPECT_NEAR(L[0], kRho * 0.2, 1e-6);
    EXPECT_NEAR(L[1], kRho * 0.4, 1e-6);
    EXPECT_NEAR(L[2], kRho * 0.8, 1e-6);
}

// An equirectangular world whose upper half is one colour: an upward floor sees only that half, and
// Cycles' mapping puts +X at u = 0.5 and +Y at u = 0.25 (checked against a Cycles bake of planes facing
// +X, -X, +Y and +Z under a four-colour map: within 0.1 %).
TEST(Lights, EnvironmentImageSkyAndMapping) {
    Light l;
    l.type = LightType::World;
    l.value = {2, 2, 2};
    l.envWidth = 8;
    l.envHeight = 4;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 8; ++x) {
            Rgb c = y >= 2 ? Rgb{0.1, 0.2, 0.3} : Rgb{5, 5, 5};  // rows from the bottom: y < 2 looks down
            l.env.insert(l.env.end(), {float(c.x), float(c.y), float(c.z)});
        }
    auto sol = solveLit(openFloor(), {l});
    float p[3] = {0.5f, 0.5f, 0}, n[3] = {0, 0, 1};
    auto L = sol->radiance(p, n, 1);
    EXPECT_NEAR(L[0], kRho * 2 * 0.1, 1e-6);
    EXPECT_NEAR(L[2], kRho * 2 * 0.3, 1e-6);
    Light m = l;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 8; ++x)
            for (int c = 0; c < 3; ++c) m.env[size_t((y * 8 + x) * 3 + c)] = float(x);
    EXPECT_EQ(envRadiance(m, {1, 0, 0}).x, 4.0);     // u = 0.5
    EXPECT_EQ(envRadiance(m, {0, 1, 0}).x, 2.0);     // u = 0.25
    EXPECT_EQ(envRadiance(m, {0, -1, 0}).x, 6.0);    // u = 0.75
    EXPECT_EQ(envRadiance(m, {-1, -1e-9, 0}).x, 7.0);  // u just under 1
}

// A wall along x = 0 (black, height H, very long) beside the floor: it hides the part of the sky a
// floor point at distance x sees as the strip form factor (1 - x / sqrt(x^2 + H^2)) / 2.
TEST(Lights, WorldIsOccludedByTheScene) {
    TestScene t;
    t.names = {"Floor", "Wall"};
    t.quad({0, -50, 0}, {10, -50, 0}, {10, 50, 0}, {0, 50, 0}, {kRho, kRho, kRho}, {}, 0, 0);
    t.quad({0, -50, 0}, {0, 50, 0}, {0, 50, 1}, {0, -50, 1}, {}, {}, 0, 1);
    Light l;
    l.type = LightType::World;
    l.value = {1, 1, 1};
    Settings s;
    s.lightRays = 1024;
    auto sol = solveLit(t, {l}, s);
    for (double x : {0.25, 0.5, 1.0, 2.0}) {
        double expect = M_PI * (1 - (1 - x / std::sqrt(x * x + 1)) / 2);
        EXPECT_NEAR(floorIrradiance(*sol, x, 0.3) / expect, 1, 0.01) << "x = " << x;
    }
}

TEST(Lights, ShadowsAndCastShadow) {
    TestScene t = openFloor();
    // A black card 1 m up over [-1, 1]^2.
    t.quad({-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}, {}, {}, 0, 1);
    t.quad({-1, -1, 1}, {-1, 1, 1}, {1, 1, 1}, {1, -1, 1}, {}, {}, 0, 1);
    Light l = pointLight({0, 0, 2}, 100, 0);
    auto sol = solveLit(t, {l});
    EXPECT_EQ(floorIrradiance(*sol, 0.5, 0.5), 0.0);
    double open = 100 / (4 * M_PI) * 2 / std::pow(4 + 16, 1.5);
    EXPECT_NEAR(floorIrradiance(*sol, 4, 0), open, 1e-3 * open);
    l.castShadow = false;
    sol = solveLit(t, {l});
    double lit = 100 / (4 * M_PI) * 2 / std::pow(4 + 0.5, 1.5);
    EXPECT_NEAR(floorIrradiance(*sol, 0.5, 0.5), lit, 1e-3 * lit);
}

// Ray Visibility > Shadow off on the card (kNoLampShadow): point and sun lamps shine through it, the
// world's occlusion still counts it.
TEST(Lights, CardHiddenFromShadowRaysLetsLampsThrough) {
    TestScene t = openFloor();
    t.quad({-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}, {}, {}, kNoLampShadow, 1);
    t.quad({-1, -1, 1}, {-1, 1, 1}, {1, 1, 1}, {1, -1, 1}, {}, {}, kNoLampShadow, 1);
    auto sol = solveLit(t, {pointLight({0, 0, 2}, 100, 0)});
    double lit = 100 / (4 * M_PI) * 2 / std::pow(4 + 0.5, 1.5);
    EXPECT_NEAR(floorIrradiance(*sol, 0.5, 0.5), lit, 1e-3 * lit);
    Light sun;
    sun.type = LightType::Sun;
    sun.value = {3, 3, 3};
    sun.angle = 0.1;
    sol = solveLit(t, {sun});
    EXPECT_NEAR(floorIrradiance(*sol, 0.2, -0.3), 3 * sunDiskFactor(0.1), 1e-3);
    Light world;
    world.type = LightType::World;
    world.value = {1, 1, 1};
    sol = solveLit(t, {world});
    EXPECT_LT(floorIrradiance(*sol, 0, 0), 0.8 * M_PI);  // the card hides a good part of the sky
}

// A sun of angular diameter alpha over a straight edge at height h: the penumbra is h tan(alpha) wide
// and the point straight under the edge sees half the sun.
TEST(Lights, SoftSunShadowIsHalfUnderTheEdge) {
    TestScene t = openFloor();
    t.quad({-5, -5, 1}, {0, -5, 1}, {0, 5, 1}, {-5, 5, 1}, {}, {}, 0, 1);
    t.quad({-5, -5, 1}, {-5, 5, 1}, {0, 5, 1}, {0, -5, 1}, {}, {}, 0, 1);
    Light l;
    l.type = LightType::Sun;
    l.value = {1, 1, 1};
    l.angle = 10 * M_PI / 180;
    Settings s;
    s.lightRays = 256;
    auto sol = solveLit(t, {l}, s);
    double full = sunDiskFactor(l.angle);
    EXPECT_NEAR(floorIrradiance(*sol, 0, 0) / full, 0.5, 0.02);
    EXPECT_EQ(floorIrradiance(*sol, -0.2, 0), 0.0);
    EXPECT_NEAR(floorIrradiance(*sol, 0.2, 0) / full, 1, 1e-4);
}

// A seed turns a lamp's sample set at every bake point: in its penumbra (a point lamp of radius 0.5 two metres up,
// over a card's edge one metre up) the light is read through other points of the lamp, within the steps of its
// set; in full light nothing moves.
TEST(Lights, ASeedTurnsTheSampleSetNotTheLight) {
    TestScene t = openFloor();
    t.quad({-5, -5, 1}, {0, -5, 1}, {0, 5, 1}, {-5, 5, 1}, {}, {}, 0, 1);
    t.quad({-5, -5, 1}, {-5, 5, 1}, {0, 5, 1}, {0, -5, 1}, {}, {}, 0, 1);
    const Light lamp = pointLight({0, 0, 2}, 100, 0.5);
    const double xs[] = {-0.3, -0.1, 0.0, 0.1, 0.3};
    double read[2][5], open[2];
    for (int k = 0; k < 2; ++k) {
        Settings s;
        s.seed = k == 0 ? 0 : 7;
        s.convolution = false;  // the lamp's shadow from its points, not from a texture (sun_textures.h)
        auto sol = solveLit(t, {lamp}, s);
        for (int i = 0; i < 5; ++i) read[k][i] = floorIrradiance(*sol, xs[i], 0);
        open[k] = floorIrradiance(*sol, 3.0, 0);
    }
    const Vec3 d = Vec3{0, 0, 2} - Vec3{0, 0, 0};
    const double full = 100 * (d.z / length(d)) / (4 * M_PI * length2(d));  // below the lamp, unshadowed
    bool moved = false;
    for (int i = 0; i < 5; ++i) {
        EXPECT_NEAR(read[0][i], read[1][i], 0.05 * full) << "x = " << xs[i];  // 2.7 % at most, measured
        moved |= read[0][i] != read[1][i];
    }
    EXPECT_TRUE(moved);
    EXPECT_EQ(open[0], open[1]);
}

// The lights' light is reflected on through the hierarchy: a point light in a closed room of uniform
// albedo rho puts rho P / (1 - rho) of reflected power on the walls in all (all of P lands on them).
TEST(Lights, PointLightInAClosedRoomConservesEnergy) {
    const double rho = 0.6, P = 50, size = 2;
    TestScene t = testing::furnaceBox(size, 2, {rho, rho, rho}, {});
    Light l = pointLight({0.9, 1.1, 1.0}, P, 0);
    for (bool gather : {true, false}) {
        Settings s;
        s.finalGather = gather;
        s.minSize = 0.05;  // fast; the energy balance holds at any subdivision
        auto sol = solveLit(t, {l}, s);
        // Midpoint rule over each inward face of the box.
        const int m = 60;
        std::vector<float> pts, nrm;
        for (int axis = 0; axis < 3; ++axis)
            for (int side = 0; side < 2; ++side)
                for (int i = 0; i < m; ++i)
                    for (int j = 0; j < m; ++j) {
                        float p[3], n[3] = {0, 0, 0};
                        p[axis] = float(side * size);
                        p[(axis + 1) % 3] = float((i + 0.5) * size / m);
                        p[(axis + 2) % 3] = float((j + 0.5) * size / m);
                        n[axis] = side ? -1.0f : 1.0f;
                        pts.insert(pts.end(), p, p + 3);
                        nrm.insert(nrm.end(), n, n + 3);
                    }
        auto L = sol->radiance(pts.data(), nrm.data(), pts.size() / 3);
        double power = 0, dA = (size / m) * (size / m);
        for (size_t k = 0; k < L.size() / 3; ++k) power += M_PI * L[k * 3] * dA;
        EXPECT_NEAR(power / (rho * P / (1 - rho)), 1, 0.01) << (gather ? "final gather" : "elements");
    }
}

// The project's promise holds with lamps and a sky: the same output for any thread count.
TEST(Lights, BitIdenticalForAnyThreadCount) {
    TestScene t = testing::litRoom();
    Light p = pointLight({0.3, -0.2, 1.2}, 40, 0.1), w;
    w.type = LightType::World;
    w.value = {0.3, 0.4, 0.5};
    std::vector<float> out[2];
    for (int k = 0; k < 2; ++k) {
        Settings s;
        s.threads = k ? 3 : 1;
        s.epsilon = 0.002;
        out[k] = testing::bakeAll(*solveLit(t, {p, w}, s), t, 32);
    }
    ASSERT_EQ(out[0].size(), out[1].size());
    EXPECT_TRUE(out[0] == out[1]);
}

TEST(Lights, LightsAloneAreEnoughAndBadLightsAreRefused) {
    TestScene t = openFloor();
    SceneInput in = t.input();
    EXPECT_THROW(solve(in, Settings{}, nullptr), InputError);  // nothing emits
    Light l = pointLight({0, 0, 1}, -1, 0);
    in.lights = {l};
    EXPECT_THROW(solve(in, Settings{}, nullptr), InputError);
    l = pointLight({0, 0, NAN}, 1, 0);
    in.lights = {l};
    EXPECT_THROW(solve(in, Settings{}, nullptr), InputError);
}

// Ray Visibility > Diffuse off on a card (kNoDiffuse) between a sunlit floor and a (nearly black) panel facing
// it from above: the card still casts the sun's shadow on the floor, but the floor's reflected light reaches the
// panel through it and the card's own sunlit top reflects nothing onto the panel. So the panel's
// irradiance is the floor's radiosity rho S outside the card's shadow (straight under it) times the exact
// form factors: E = rho S (F(floor) - F(shadow)). With the card seen by diffuse rays it hides that light.
TEST(Lights, CardHiddenFromDiffuseRaysLetsBouncedLightThrough) {
    auto scene = [](uint8_t flag) {
        // The floor in 0.5 m faces, so that the card's shadow is whole faces: the floor's radiosity is then
        // exact, face by face, whatever the refinement.
        TestScene t;
        t.names = {"Floor", "Card", "Panel"};
        for (int i = -10; i < 10; ++i)
            for (int j = -10; j < 10; ++j) {
                double x = 0.5 * i, y = 0.5 * j;
                t.quad({x, y, 0}, {x + 0.5, y, 0}, {x + 0.5, y + 0.5, 0}, {x, y + 0.5, 0}, {kRho, kRho, kRho}, {});
            }
        t.quad({-0.5, -0.5, 1}, {0.5, -0.5, 1}, {0.5, 0.5, 1}, {-0.5, 0.5, 1}, {0.8, 0.8, 0.8}, {}, flag, 1);
        t.quad({-0.5, -0.5, 1}, {-0.5, 0.5, 1}, {0.5, 0.5, 1}, {0.5, -0.5, 1}, {0.8, 0.8, 0.8}, {}, flag, 1);
        // Hidden from shadow rays, so the sun reaches the floor and the card past it; nearly black, so the
        // floor's radiosity is its own reflected sunlight alone.
        t.quad({-1, -1, 2}, {-1, 1, 2}, {1, 1, 2}, {1, -1, 2}, {0.01, 0.01, 0.01}, {}, kNoLampShadow, 2);
        return t;
    };
    Light sun;
    sun.type = LightType::Sun;
    sun.value = {1, 1, 1};
    auto polygon = [](double h, double z) {
        Polygon g;
        g.push({-h, -h, z});
        g.push({h, -h, z});
        g.push({h, h, z});
        g.push({-h, h, z});
        return g;
    };
    // The panel is nearly black so that it sends nothing back to the floor; epsilon bounds radiosity, so its
    // irradiance is held only to epsilon / rho. At the default epsilon its error was set by how coarsely the
    // floor's clusters may be linked to so dark a receiver (0.8 % at far_field 0.2, 5.1 % at 0.3, 2.6 % at 0.5);
    // at epsilon scaled by its rho it is 1.3 % whatever far_field is, and the test reads the flag alone.
    Settings fine;
    fine.epsilon *= 0.01;
    double worst[2] = {0, 0};
    for (uint8_t flag : {uint8_t(kNoDiffuse), uint8_t(0)}) {
        auto sol = solveLit(scene(flag), {sun}, fine);
        for (double x : {-0.6, 0.0, 0.3})
            for (double y : {-0.4, 0.2}) {
                float p[3] = {float(x), float(y), 2}, n[3] = {0, 0, -1};
                double E = sol->radiance(p, n, 1, true)[0] * M_PI;
                Vec3 P{x, y, 2}, N{0, 0, -1};
                double expect = kRho * (pointToPolygonFormFactor(P, N, polygon(5, 0)) -
                                        pointToPolygonFormFactor(P, N, polygon(0.5, 0)));
                worst[flag ? 0 : 1] = std::max(worst[flag ? 0 : 1], std::fabs(E / expect - 1));
            }
        // The card itself is still lit (its top by the sun) and baked.
        float top[3] = {0, 0, 1}, up[3] = {0, 0, 1};
        EXPECT_NEAR(sol->radiance(top, up, 1, true)[0] * M_PI, 1.0, 0.05) << "flag " << int(flag);
    }
    std::printf("panel irradiance against rho S (F(floor) - F(shadow)): hidden from diffuse rays %.4f, seen %.4f\n",
                worst[0], worst[1]);
    EXPECT_LT(worst[0], 0.02);
    EXPECT_GT(worst[1], 0.1);
}

}  // namespace
}  // namespace penumbra
