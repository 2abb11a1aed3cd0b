#include "bake/sun_textures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <cstdio>
#include <vector>

#include "bake/lights.h"
#include "penumbra.h"
#include "testing/scenes.h"
#include "visibility/ray_caster.h"

namespace penumbra {
namespace {

using testing::TestScene;

constexpr double kRho = 0.5, kPlate = 1.5;

// A floor of 1 m faces under a black plate 1.5 m up with a 1 m window and a cross of 6 cm bars, lit by a
// sun 35 degrees up, turned 20 degrees off the x axis.
TestScene windowPlate() {
    TestScene t;
    t.names = {"Floor", "Plate"};
    for (int i = -4; i < 4; ++i)
        for (int j = -4; j < 4; ++j)
            t.quad({double(i), double(j), 0}, {i + 1.0, double(j), 0}, {i + 1.0, j + 1.0, 0}, {double(i), j + 1.0, 0},
                   {kRho, kRho, kRho}, {});
    auto plate = [&](double x0, double y0, double x1, double y1) {
        t.quad({x0, y0, kPlate}, {x1, y0, kPlate}, {x1, y1, kPlate}, {x0, y1, kPlate}, {}, {}, 0, 1);
        t.quad({x0, y0, kPlate}, {x0, y1, kPlate}, {x1, y1, kPlate}, {x1, y0, kPlate}, {}, {}, 0, 1);
    };
    plate(-4, -4, -0.5, 4);
    plate(0.5, -4, 4, 4);
    plate(-0.5, -4, 0.5, -0.5);
    plate(-0.5, 0.5, 0.5, 4);
    plate(-0.03, -0.5, 0.03, 0.5);
    plate(-0.5, -0.03, -0.03, 0.03);
    plate(0.03, -0.03, 0.5, 0.03);
    return t;
}

Vec3 toSun() {
    const double e = 35 * M_PI / 180, a = 20 * M_PI / 180;
    return {std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
}

// Cosine-weighted visible share of the sun at p: every one of ~3200 directions over its disk cast.
double traced(const RayCaster& rays, const Vec3& p, const Vec3& w, double angle) {
    const double t = std::tan(0.5 * angle);
    const Vec3 t1 = normalize(cross(w, Vec3{0, 0, 1})), t2 = cross(w, t1);
    std::vector<Vec3> to;
    std::vector<double> weight;
    for (int i = 0; i < 64; ++i)
        for (int j = 0; j < 64; ++j) {
            double x = (i + 0.5) / 32 - 1, y = (j + 0.5) / 32 - 1;
            if (x * x + y * y > 1) continue;
            Vec3 d = normalize(-w + (t1 * x + t2 * y) * t);
            to.push_back(p + d * 20.0);
            weight.push_back(d.z);
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

// The bake reads a 1 degree sun's shadow through the window from the floor faces' textures: at 3600
// points over the sunlit patch, the baked irradiance over the unshadowed sun's against ray tracing. With
// convolution off the rays of lights.h decide (8 points for a 1 degree sun at light_rays 256), as before.
TEST(SunTextures, TheBakeReadsTheSunsShadowFromTextures) {
    TestScene t = windowPlate();
    Light sun;
    sun.type = LightType::Sun;
    sun.direction = -toSun();
    sun.value = {2, 2, 2};
    sun.angle = M_PI / 180;
    SceneInput in = t.input();
    in.lights = {sun};
    Scene sc = buildScene(in);
    RayCaster rays(sc);
    const Vec3 centre = toSun() * (-kPlate / toSun().z);
    const double open = 2 * sunDiskFactor(sun.angle) * toSun().z;
    double worst[2] = {0, 0}, mean[2] = {0, 0};
    int penumbra = 0, count = 0;
    for (bool convolution : {true, false}) {
        Settings s;
        s.convolution = convolution;
        s.threads = 2;
        auto sol = solve(in, s, nullptr);
        const Report& rep = sol->report();
        if (convolution) {
            // The faces the patch falls on and every face in the plate's shadow; none is refused.
            EXPECT_GE(rep.count("sun_textures"), 4u);
            EXPECT_EQ(rep.count("sun_refused"), 0u);
            std::printf("%zu sun textures in %.3f s\n", rep.count("sun_textures"), rep.seconds.at("sun_textures"));
        } else {
            EXPECT_EQ(rep.count("sun_textures"), 0u);
        }
        std::vector<float> pts, nrm;
        std::vector<double> ref;
        for (int i = 0; i < 60; ++i)
            for (int j = 0; j < 60; ++j) {
                Vec3 p{centre.x - 0.9 + 1.8 * (i + 0.5) / 60, centre.y - 0.9 + 1.8 * (j + 0.5) / 60, 0};
                pts.insert(pts.end(), {float(p.x), float(p.y), 0.0f});
                nrm.insert(nrm.end(), {0.0f, 0.0f, 1.0f});
                ref.push_back(traced(rays, Vec3{float(p.x), float(p.y), 1e-6f} - sc.offset, sun.direction, sun.angle));
            }
        std::vector<float> got = sol->radiance(pts.data(), nrm.data(), ref.size(), true);
        for (size_t k = 0; k < ref.size(); ++k) {
            double v = got[3 * k] * M_PI / open, d = std::fabs(v - ref[k]);
            worst[convolution ? 0 : 1] = std::fmax(worst[convolution ? 0 : 1], d);
            mean[convolution ? 0 : 1] += d / double(ref.size());
            if (convolution) {
                penumbra += ref[k] > 0.01 && ref[k] < 0.99;
                ++count;
            }
        }
    }
    std::printf("%d of %d points in penumbra; textures: max |dV| %.4f, mean %.5f; rays: max %.4f, mean %.5f\n",
                penumbra, count, worst[0], mean[0], worst[1], mean[1]);
    // Their cost on one thread (printed, not asserted: CPU time on a shared machine).
    std::clock_t c0 = std::clock();
    SunTextures textures(sc, Settings{}, 1);
    double cpu = double(std::clock() - c0) / CLOCKS_PER_SEC;
    std::printf("%zu textures, %zu texels, %.3f CPU s on one thread: %.2f us per texel\n", textures.made(),
                textures.texels(), cpu, 1e6 * cpu / double(std::max<size_t>(1, textures.texels())));
    EXPECT_GT(penumbra, 300);
    EXPECT_LT(worst[0], 0.03);
    EXPECT_LT(mean[0], 0.002);
    EXPECT_LT(mean[0], 0.5 * mean[1]);  // what the textures are for
}

}  // namespace
}  // namespace penumbra
