#include "convolution/sun_shadow.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

#include "bake/lights.h"
#include "scene/scene.h"
#include "testing/scenes.h"
#include "visibility/ray_caster.h"

namespace penumbra {
namespace {

// Visible share of a disk of radius 1 whose centre is s radii on the lit side of a straight edge:
// one minus the circular segment beyond the edge.
double edgeProfile(double s) {
    if (s >= 1) return 1;
    if (s <= -1) return 0;
    return 1 - (std::acos(s) - s * std::sqrt(1 - s * s)) / M_PI;
}

std::vector<BlockerTriangle> rectangle(double x0, double y0, double x1, double y1, double z) {
    Vec3 a{x0, y0, z}, b{x1, y0, z}, c{x1, y1, z}, d{x0, y1, z};
    return {{a, b, c}, {a, c, d}};
}

void append(std::vector<BlockerTriangle>& to, const std::vector<BlockerTriangle>& more) {
    to.insert(to.end(), more.begin(), more.end());
}

ReceiverDesc floorSquare(double half) {
    return {{{-half, -half, 0}, {half, -half, 0}, {half, half, 0}, {-half, half, 0}}};
}

// A straight edge at height d under a sun straight overhead: the exact penumbra is the visible share of
// the disk of radius d tan(theta / 2) around each point.
TEST(SunShadow, StraightEdgeMatchesTheDiskSegment) {
    const double d = 1.0;
    for (double degrees : {2.0, 10.0}) {
        SunDesc sun{{0, 0, -1}, degrees * M_PI / 180};
        const double rho = d * std::tan(0.5 * sun.angle);
        // Texels fixed at 2.5 mm (the 2 degree penumbra spans 14).
        ConvolutionSettings s;
        s.resolution = 400;
        SoftShadowTexture T = computeSunShadow(sun, rectangle(-3, -3, 0, 3, d), floorSquare(0.5), s);
        EXPECT_EQ(T.subBlockers, 1);
        EXPECT_LE(T.E_rr, s.e_max);
        double worst = 0;
        for (int i = -40; i <= 40; ++i) {
            double x = 1.2 * rho * i / 40;
            double got = lookupVisibility(T, {x, 0.2, 0});
            worst = std::fmax(worst, std::fabs(got - edgeProfile(x / rho)));
        }
        EXPECT_LT(worst, 0.02) << degrees << " degrees, " << T.n << " texels";
        EXPECT_EQ(lookupVisibility(T, {-0.5, 0, 0}), 0.0f);
        EXPECT_EQ(lookupVisibility(T, {0.5, 0, 0}), 1.0f);
    }
}

// The same edge, the sun tilted 50 degrees from the normal in the plane of the edge: the rays reach the
// receiver d / cos 50 after the blocker, so the penumbra across the edge is that much wider, and the shadow
// is the blocker's projection along the rays (here along the edge, so it does not move).
TEST(SunShadow, ObliqueSunAlongTheEdgeWidensThePenumbra) {
    const double d = 1.0, tilt = 50 * M_PI / 180;
    SunDesc sun{{0, std::sin(tilt), -std::cos(tilt)}, 4 * M_PI / 180};
    const double rho = d / std::cos(tilt) * std::tan(0.5 * sun.angle);
    ConvolutionSettings s;
    s.resolution = 400;
    SoftShadowTexture T = computeSunShadow(sun, rectangle(-3, -4, 0, 4, d), floorSquare(1), s);
    EXPECT_EQ(T.subBlockers, 1);
    double worst = 0;
    for (int i = -40; i <= 40; ++i) {
        double x = 1.2 * rho * i / 40;
        worst = std::fmax(worst, std::fabs(lookupVisibility(T, {x, 0.2, 0}) - edgeProfile(x / rho)));
    }
    // 0.02 as above, plus the projective stretch of the disk's footprint along the rays (tan(theta/2) tan 50).
    EXPECT_LT(worst, 0.03);
}

// Argument errors are clear, and a sun without a size is refused (hard shadows need no convolution).
TEST(SunShadow, BadInputIsRefused) {
    auto blockers = rectangle(-1, -1, 0, 1, 1);
    EXPECT_THROW(computeSunShadow({{0, 0, 0}, 0.1}, blockers, floorSquare(1), {}), std::invalid_argument);
    EXPECT_THROW(computeSunShadow({{0, 0, -1}, 0.0}, blockers, floorSquare(1), {}), std::invalid_argument);
    EXPECT_THROW(computeSunShadow({{0, 0, -1}, M_PI}, blockers, floorSquare(1), {}), std::invalid_argument);
    EXPECT_THROW(computeSunShadow({{0, 0, -1}, 0.1}, blockers, ReceiverDesc{}, {}), std::invalid_argument);
    blockers[0][1].x = std::nan("");
    EXPECT_THROW(computeSunShadow({{0, 0, -1}, 0.1}, blockers, floorSquare(1), {}), std::invalid_argument);
    // A card through the receiver: no depth order.
    std::vector<BlockerTriangle> through = {{Vec3{-1, 0, -0.5}, Vec3{1, 0, -0.5}, Vec3{1, 0, 0.5}}};
    EXPECT_THROW(computeSunShadow({{0, 0, -1}, 0.1}, through, floorSquare(1), {}), std::domain_error);
}

// Ray-traced visible share of the sun at p (normal n): a 64 x 64 grid over the disk of directions
// -w + t (x t1 + y t2), |(x, y)| <= 1 (uniform in tan-space, as Cycles spreads the strength), each weighed
// by its cosine on the receiver, every direction cast.
double tracedSun(const RayCaster& rays, const Vec3& p, const Vec3& n, const Vec3& w, double angle, double far) {
    const double t = std::tan(0.5 * angle);
    Vec3 a = std::fabs(w.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    const Vec3 t1 = normalize(cross(w, a)), t2 = cross(w, t1);
    std::vector<Vec3> to;
    std::vector<double> weight;
    const int m = 64;
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
            double x = 2 * (i + 0.5) / m - 1, y = 2 * (j + 0.5) / m - 1;
            if (x * x + y * y > 1) continue;
            Vec3 d = normalize(-w + (t1 * x + t2 * y) * t);
            to.push_back(p + d * far);
            weight.push_back(std::fmax(0.0, dot(d, n)));
        }
    std::vector<char> clear(to.size());
    rays.visibleMask(p, to.data(), int(to.size()), clear.data(), true);
    double seen = 0, all = 0;
    for (size_t k = 0; k < to.size(); ++k) {
        all += weight[k];
        seen += clear[k] ? weight[k] : 0.0;
    }
    return seen / all;
}

// A window (a 1 m square hole in a wall plate, with a cross-shaped frame of 6 cm bars) 1.5 m above a floor,
// the sun 35 degrees up and turned off every axis, with the angular diameter of the window scene (1
// degree) and a larger one: the texture against ray tracing (tracedSun, 3200 directions) at every point of a
// grid over the sunlit patch. The bake's own ray-traced sun (LightSet, as many directions as light_rays
// allows for the sun's size, the first 8 deciding full light and umbra) is printed beside it.
TEST(SunShadow, WindowFrameMatchesTheRayTracedSun) {
    const double z = 1.5;
    std::vector<BlockerTriangle> blockers;
    append(blockers, rectangle(-3, -3, -0.5, 3, z));     // the wall around the hole
    append(blockers, rectangle(0.5, -3, 3, 3, z));
    append(blockers, rectangle(-0.5, -3, 0.5, -0.5, z));
    append(blockers, rectangle(-0.5, 0.5, 0.5, 3, z));
    append(blockers, rectangle(-0.03, -0.5, 0.03, 0.5, z));  // the frame's cross
    append(blockers, rectangle(-0.5, -0.03, -0.03, 0.03, z));
    append(blockers, rectangle(0.03, -0.03, 0.5, 0.03, z));
    const double e = 35 * M_PI / 180, a = 20 * M_PI / 180;
    const Vec3 toSun{std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
    testing::TestScene t;
    t.names = {"Floor", "Wall"};
    t.quad({-4, -4, 0}, {4, -4, 0}, {4, 4, 0}, {-4, 4, 0}, {0.5, 0.5, 0.5}, {});
    for (const BlockerTriangle& b : blockers) {
        // Both sides, as the scene's faces are one-sided receivers but block from either.
        t.triangle(b[0], b[1], b[2], {}, {}, 0, 1);
        t.triangle(b[0], b[2], b[1], {}, {}, 0, 1);
    }
    Light sunLight;
    sunLight.type = LightType::Sun;
    sunLight.direction = -toSun;
    sunLight.value = {1, 1, 1};
    SceneInput in = t.input();
    in.lights = {sunLight};
    Scene sc = buildScene(in);
    RayCaster rays(sc);
    // The patch of sunlight: the hole's projection along the rays onto the floor, and a margin.
    const Vec3 shift = toSun * (-z / toSun.z);
    const double cx = shift.x, cy = shift.y;
    ReceiverDesc rec = {{{cx - 1, cy - 1, 0}, {cx + 1, cy - 1, 0}, {cx + 1, cy + 1, 0}, {cx - 1, cy + 1, 0}}};
    for (double degrees : {1.0, 6.0}) {
        sunLight.angle = degrees * M_PI / 180;
        sc.lights = {sunLight};
        LightSet bake(sc, &rays, LightSet::kMaxRays), open(sc, nullptr, LightSet::kMaxRays);
        SoftShadowTexture T = computeSunShadow({-toSun, sunLight.angle}, blockers, rec, ConvolutionSettings{});
        double worst = 0, sum = 0, bakeWorst = 0, bakeSum = 0;
        int count = 0, penumbra = 0;
        for (int i = 0; i < 60; ++i)
            for (int j = 0; j < 60; ++j) {
                Vec3 p{cx - 0.9 + 1.8 * (i + 0.5) / 60, cy - 0.9 + 1.8 * (j + 0.5) / 60, 0};
                Vec3 local = p - sc.offset;
                double ref = tracedSun(rays, local + Vec3{0, 0, 1e-6}, {0, 0, 1}, -toSun, sunLight.angle, 20);
                double got = lookupVisibility(T, p);
                double baked = bake.irradiance(local, {0, 0, 1})[0] / open.irradiance(local, {0, 0, 1})[0];
                worst = std::fmax(worst, std::fabs(got - ref));
                sum += std::fabs(got - ref);
                bakeWorst = std::fmax(bakeWorst, std::fabs(baked - ref));
                bakeSum += std::fabs(baked - ref);
                ++count;
                penumbra += ref > 0.01 && ref < 0.99;
            }
        std::printf("sun %.0f deg: %d texels, %d slab(s), %d of %d points in penumbra; texture max |dV| %.4f, "
                    "mean %.5f, %.1f ms; LightSet max %.4f, mean %.5f\n",
                    degrees, T.n, T.subBlockers, penumbra, count, worst, sum / count,
                    T.times.rasterMs + T.times.fftMs + T.times.restMs, bakeWorst, bakeSum / count);
        EXPECT_GT(penumbra, 300);
        // Measured 0.012 / 0.0006 (1 degree, 435 texels) and 0.021 / 0.0023 (6 degrees, 71 texels); the
        // LightSet's 0.16 / 0.0043 and 0.36 / 0.015 are its coarse points deciding penumbra as umbra.
        EXPECT_LT(worst, 0.03) << degrees << " degrees";
        EXPECT_LT(sum / count, 0.004) << degrees << " degrees";
    }
}

}  // namespace
}  // namespace penumbra
