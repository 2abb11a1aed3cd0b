#include "convolution/raster.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "convolution/osmesa_raster.h"

namespace penumbra {
namespace {

double sum(const std::vector<float>& v) {
    double s = 0;
    for (float x : v) s += x;
    return s;
}

TEST(ConvRaster, RectangleCoverageExactAlongRowsAndOnSubRows) {
    // Pixel grid of unit pixels; rectangle x in [2.3, 7.85], y in [1.25, 4.75] (on sub-row bounds
    // for 4 sub-rows, so coverage is exact in both directions).
    PixelGrid g{0, 0, 1, 10, 6};
    PolygonSet ps;
    Vec2 r[4] = {{2.3, 1.25}, {7.85, 1.25}, {7.85, 4.75}, {2.3, 4.75}};
    ps.add(r, 4);
    std::vector<float> img(60);
    SpanRasterizer(4).rasterize(ps, g, img.data());
    for (int j = 0; j < 6; ++j)
        for (int i = 0; i < 10; ++i) {
            double cx = std::fmax(0, std::fmin(i + 1, 7.85) - std::fmax(i, 2.3));
            double cy = std::fmax(0, std::fmin(j + 1, 4.75) - std::fmax(j, 1.25));
            EXPECT_NEAR(img[j * 10 + i], cx * cy, 1e-6) << i << "," << j;
        }
    EXPECT_EQ(img[2 * 10 + 4], 1.0f);  // interior exactly 1
    EXPECT_EQ(img[0], 0.0f);
}

TEST(ConvRaster, UnionNotSumAndEvenOdd) {
    PixelGrid g{-1, -1, 0.05, 40, 40};
    std::vector<float> one(1600), two(1600);
    PolygonSet a, b;
    Vec2 t[3] = {{-0.8, -0.7}, {0.9, -0.2}, {0.1, 0.85}};
    a.add(t, 3);
    b.add(t, 3);
    b.add(t, 3);  // the same triangle twice must not darken anything
    SpanRasterizer(4).rasterize(a, g, one.data());
    SpanRasterizer(4).rasterize(b, g, two.data());
    for (int i = 0; i < 1600; ++i) EXPECT_EQ(one[i], two[i]);
    double area = 0.5 * std::fabs((0.9 + 0.8) * (0.85 + 0.7) - (0.1 + 0.8) * (-0.2 + 0.7));
    EXPECT_NEAR(sum(one) * 0.05 * 0.05, area, 2e-3);
    for (float x : one) {
        EXPECT_GE(x, 0.0f);
        EXPECT_LE(x, 1.0f);
    }
    // Non-convex L-shape (area 0.75 of the unit square).
    PolygonSet l;
    Vec2 L[6] = {{0, 0}, {1, 0}, {1, 0.5}, {0.5, 0.5}, {0.5, 1}, {0, 1}};
    l.add(L, 6);
    std::vector<float> img(40 * 40);
    SpanRasterizer(4).rasterize(l, PixelGrid{-0.25, -0.25, 0.0375, 40, 40}, img.data());
    // Exact along rows; each horizontal edge is sampled on 4 sub-rows, so it may be off by up to
    // 1/8 of a pixel over its length (2 units of horizontal edges here).
    EXPECT_NEAR(sum(img) * 0.0375 * 0.0375, 0.75, 2.0 * 0.0375 / 8);
}

TEST(ConvRaster, KernelIsPointReflectedScaledAndCentredOnPixelZero) {
    const int N = 32;
    std::vector<float> k(N * N);
    // Footprint entirely at +u: its reflection must land at negative u, i.e. wrapped indices.
    std::vector<Vec2> fp{{1.0, -0.25}, {2.0, -0.25}, {2.0, 0.25}, {1.0, 0.25}};
    double s = renderSourceKernel(fp, 2.0, 0.5, N, 4, nullptr, k.data());
    // Area 0.5 magnified by alpha^2 = 4, in pixels of 0.25 area.
    EXPECT_NEAR(s, 0.5 * 4 / 0.25, 1e-3);
    double left = 0, right = 0;
    for (int j = 0; j < N; ++j)
        for (int i = 0; i < N; ++i) (i >= N / 2 ? left : right) += k[j * N + i];
    EXPECT_NEAR(left, s, 1e-3);
    EXPECT_EQ(right, 0.0);
    // Displacement -alpha*[1,2] = [-4,-2] -> pixels -8..-4 (centres), wrapped to 24..28.
    EXPECT_GT(k[0 * N + 26], 0.99f);
    EXPECT_EQ(k[0 * N + 22], 0.0f);
    EXPECT_EQ(k[0 * N + 30], 0.0f);
    // A vanishing kernel is a Dirac at pixel 0.
    std::vector<float> d(N * N);
    EXPECT_DOUBLE_EQ(renderSourceKernel(fp, 0.0, 0.5, N, 4, nullptr, d.data()), 1.0);
    EXPECT_EQ(d[0], 1.0f);
    EXPECT_THROW(renderSourceKernel(fp, 40.0, 0.5, N, 4, nullptr, d.data()), std::domain_error);
}

TEST(ConvRaster, WeightedKernelFollowsEmission) {
    const int N = 64;
    std::vector<Vec2> fp{{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    std::function<float(double, double)> e = [](double u, double) { return u > 0 ? 1.0f : 0.0f; };
    std::vector<float> k(N * N);
    double s = renderSourceKernel(fp, 1.0, 0.1, N, 4, &e, k.data());
    EXPECT_NEAR(s, 2.0 / 0.01, 2.0);  // half the 2x2 source
    // Emission at source u > 0 sits at kernel displacement < 0 (wrapped columns).
    double neg = 0, pos = 0;
    for (int j = 0; j < N; ++j) {
        for (int i = N / 2; i < N; ++i) neg += k[j * N + i];
        for (int i = 1; i < N / 2; ++i) pos += k[j * N + i];
    }
    EXPECT_EQ(pos, 0.0);
    EXPECT_GT(neg, 0.9 * s);
}

TEST(ConvRaster, OSMesaAgreesWithSpan) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(-1, 1);
    PolygonSet ps;
    for (int t = 0; t < 200; ++t) {
        double cx = U(rng), cy = U(rng);
        Vec2 v[3] = {{cx + 0.2 * U(rng), cy + 0.2 * U(rng)}, {cx + 0.2 * U(rng), cy + 0.2 * U(rng)},
                     {cx + 0.2 * U(rng), cy + 0.2 * U(rng)}};
        ps.add(v, 3);
    }
    PixelGrid g{-1.2, -1.1, 2.4 / 96, 96, 90};
    std::vector<float> a(96 * 90), b(96 * 90);
    SpanRasterizer(4).rasterize(ps, g, a.data());
    std::unique_ptr<OSMesaRasterizer> osm;
    try {
        osm = std::make_unique<OSMesaRasterizer>(16);
        osm->rasterize(ps, g, b.data());
    } catch (const std::runtime_error& e) {
        GTEST_SKIP() << "OSMesa unavailable: " << e.what();
    }
    EXPECT_GE(osm->samplesUsed(), 4);
    std::printf("OSMesa samples %d, renderer %s\n", osm->samplesUsed(), OSMesaRasterizer::rendererName().c_str());
    double maxd = 0, sumd = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        maxd = std::fmax(maxd, std::fabs(a[i] - b[i]));
        sumd += std::fabs(a[i] - b[i]);
    }
    EXPECT_NEAR(sum(a), sum(b), 0.01 * sum(a));
    EXPECT_LT(sumd / a.size(), 0.02);
    EXPECT_LT(maxd, 0.5);  // edge pixels differ by sample placement only
}

}  // namespace
}  // namespace penumbra
