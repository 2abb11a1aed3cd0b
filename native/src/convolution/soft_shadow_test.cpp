#include "convolution/soft_shadow.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>

#include "convolution/osmesa_raster.h"

namespace penumbra {
namespace {

// ---- exact visibility for a planar source at z = 0 and axis-aligned square blockers at z_b ----
struct Rect {
    double x0, y0, x1, y1;
};
struct SquareBlocker {
    double cx, cy, half, z;
};

std::vector<Vec2> clip(const std::vector<Vec2>& poly, double a, double b, double c) {  // keep a x + b y <= c
    std::vector<Vec2> out;
    for (size_t i = 0; i < poly.size(); ++i) {
        const Vec2& p = poly[i];
        const Vec2& q = poly[(i + 1) % poly.size()];
        double fp = a * p.x + b * p.y - c, fq = a * q.x + b * q.y - c;
        if (fp <= 0) out.push_back(p);
        if ((fp < 0) != (fq < 0) && fp != 0 && fq != 0) {
            double t = fp / (fp - fq);
            out.push_back({p.x + t * (q.x - p.x), p.y + t * (q.y - p.y)});
        }
    }
    return out;
}
std::vector<Vec2> clipRect(std::vector<Vec2> poly, const Rect& r) {
    poly = clip(poly, -1, 0, -r.x0);
    poly = clip(poly, 1, 0, r.x1);
    poly = clip(poly, 0, -1, -r.y0);
    return clip(poly, 0, 1, r.y1);
}
double area(const std::vector<Vec2>& p) {
    double a = 0;
    for (size_t i = 0; i < p.size(); ++i) {
        const Vec2& u = p[i];
        const Vec2& v = p[(i + 1) % p.size()];
        a += u.x * v.y - v.x * u.y;
    }
    return 0.5 * std::fabs(a);
}
// Shadow of a square blocker on the source plane, seen from the receiver point (x, y, zr).
Rect projected(const SquareBlocker& b, double x, double y, double zr) {
    double k = zr / (zr - b.z);
    return {x + (b.cx - b.half - x) * k, y + (b.cy - b.half - y) * k, x + (b.cx + b.half - x) * k,
            y + (b.cy + b.half - y) * k};
}
// Exact visible fraction of a convex source polygon (z = 0) behind one or two square blockers.
double exactVisibility(const std::vector<Vec2>& src, const std::vector<SquareBlocker>& bl, double x, double y,
                       double zr) {
    double A = area(src), hidden = 0;
    std::vector<Rect> r;
    for (const auto& b : bl) r.push_back(projected(b, x, y, zr));
    for (const Rect& q : r) hidden += area(clipRect(src, q));
    if (r.size() == 2) hidden -= area(clipRect(clipRect(src, r[0]), r[1]));
    return 1.0 - hidden / A;
}

std::vector<BlockerTriangle> squareTris(const SquareBlocker& b) {
    Vec3 a{b.cx - b.half, b.cy - b.half, b.z}, c{b.cx + b.half, b.cy - b.half, b.z},
        d{b.cx + b.half, b.cy + b.half, b.z}, e{b.cx - b.half, b.cy + b.half, b.z};
    return {{a, c, d}, {a, d, e}};
}
SourceDesc planarSource(const std::vector<Vec2>& p) {
    SourceDesc s;
    for (const Vec2& q : p) s.polygon.push_back({q.x, q.y, 0});
    return s;
}
ReceiverDesc squareReceiver(double half, double z) {
    return {{{-half, -half, z}, {half, -half, z}, {half, half, z}, {-half, half, z}}};
}

struct Errors {
    double max = 0, mean = 0;
};
Errors compareParallel(const SoftShadowTexture& T, const std::vector<Vec2>& src, const std::vector<SquareBlocker>& bl,
                       double half, double zr, int grid = 61) {
    Errors e;
    int count = 0;
    for (int j = 0; j < grid; ++j)
        for (int i = 0; i < grid; ++i) {
            double x = -half * 0.98 + 1.96 * half * i / (grid - 1), y = -half * 0.98 + 1.96 * half * j / (grid - 1);
            double d = std::fabs(lookupVisibility(T, {x, y, zr}) - exactVisibility(src, bl, x, y, zr));
            e.max = std::fmax(e.max, d);
            e.mean += d;
            ++count;
        }
    e.mean /= count;
    return e;
}

const std::vector<Vec2> kSquareSource{{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}};

TEST(ConvSoftShadow, ParallelSquareMatchesExactVisibility) {
    std::vector<SquareBlocker> bl{{0.15, -0.1, 0.5, 1.0}};
    ConvolutionSettings s;
    s.resolution = 128;
    SoftShadowTexture T = computeSoftShadow(planarSource(kSquareSource), squareTris(bl[0]), squareReceiver(3, 3), s);
    EXPECT_EQ(T.n, 128);
    EXPECT_EQ(T.subBlockers, 1);
    EXPECT_NEAR(T.E_rr, 0.0, 1e-9);      // parallel planes: the convolution is exact
    EXPECT_NEAR(T.alpha_min, 2.0, 1e-9);  // (3 - 1) / 1
    Errors e = compareParallel(T, kSquareSource, bl, 3, 3);
    EXPECT_LE(e.max, 0.02);
    EXPECT_LE(e.mean, 0.005);
}

TEST(ConvSoftShadow, AsymmetricSourceIsPointReflected) {
    // A triangle is not centrally symmetric: without the reflection the error is ~0.3.
    std::vector<Vec2> tri{{-0.5, -0.4}, {0.6, -0.3}, {-0.2, 0.5}};
    std::vector<SquareBlocker> bl{{0.15, -0.1, 0.4, 1.0}};
    ConvolutionSettings s;
    s.resolution = 128;
    SoftShadowTexture T = computeSoftShadow(planarSource(tri), squareTris(bl[0]), squareReceiver(3, 3), s);
    Errors e = compareParallel(T, tri, bl, 3, 3);
    EXPECT_LE(e.max, 0.02);
    EXPECT_LE(e.mean, 0.005);
}

TEST(ConvSoftShadow, UmbraIsExactlyZeroAndFullLightExactlyOne) {
    std::vector<Vec2> small{{-0.1, -0.1}, {0.1, -0.1}, {0.1, 0.1}, {-0.1, 0.1}};
    std::vector<SquareBlocker> bl{{0, 0, 1.0, 1.0}};
    ConvolutionSettings s;
    s.resolution = 200;
    SoftShadowTexture T = computeSoftShadow(planarSource(small), squareTris(bl[0]), squareReceiver(4, 2), s);
    EXPECT_EQ(lookupVisibility(T, {0, 0, 2}), 0.0f);
    EXPECT_EQ(lookupVisibility(T, {3.5, 3.5, 2}), 1.0f);
    int umbra = 0, light = 0;
    const double p = 8.0 / 200;
    for (int c = 0; c < T.n; ++c)
        for (int a = 0; a < T.n; ++a) {
            double x = -4 + (a + 0.5) * p, y = -4 + (c + 0.5) * p;
            // Shadow of the 2x2 blocker from z=2 is 4x4 wide; penumbra 0.2 wide around its edge.
            double r = std::fmax(std::fabs(x), std::fabs(y));
            float v = T.visibility[c * T.n + a];
            if (r < 1.9 - 2 * p) {
                EXPECT_EQ(v, 0.0f);
                ++umbra;
            } else if (r > 2.1 + 2 * p) {
                EXPECT_EQ(v, 1.0f);
                ++light;
            }
        }
    EXPECT_GT(umbra, 5000);
    EXPECT_GT(light, 5000);
}

TEST(ConvSoftShadow, TwoSlabErrorFallsWithN) {
    // Penumbrae of the two slabs do not overlap, where the product of slice maps is exact.
    std::vector<SquareBlocker> bl{{-0.5, 0.0, 0.3, 1.0}, {0.9, 0.2, 0.25, 2.0}};
    std::vector<BlockerTriangle> tris = squareTris(bl[0]);
    for (auto& t : squareTris(bl[1])) tris.push_back(t);
    ConvolutionSettings s;
    s.resolution = 128;
    s.e_max = 0.5;
    s.n_max = 1;
    SoftShadowTexture one = computeSoftShadow(planarSource(kSquareSource), tris, squareReceiver(3, 3), s);
    s.n_max = 8;
    SoftShadowTexture two = computeSoftShadow(planarSource(kSquareSource), tris, squareReceiver(3, 3), s);
    EXPECT_EQ(one.subBlockers, 1);
    EXPECT_EQ(two.subBlockers, 2);  // two flat slabs reach E = 0
    EXPECT_GT(one.E_rr, 5.0);
    EXPECT_NEAR(two.E_rr, 0.0, 1e-9);
    Errors e1 = compareParallel(one, kSquareSource, bl, 3, 3);
    Errors e2 = compareParallel(two, kSquareSource, bl, 3, 3);
    EXPECT_LT(e2.max, 0.5 * e1.max);
    EXPECT_LT(e2.mean, 0.5 * e1.mean);
    EXPECT_LE(e2.max, 0.03);
    // The single-convolution error stays inside its own estimate (brief §4.2 calibration).
    EXPECT_LE(e1.max, one.visibilityError + 0.02);
    std::printf("two slabs: N=1 E=%.2f est=%.3f max=%.4f mean=%.4f | N=2 max=%.4f mean=%.4f\n", one.E_rr,
                one.visibilityError, e1.max, e1.mean, e2.max, e2.mean);
}

TEST(ConvSoftShadow, ThickBlockerEstimateFallsWithSlabCount) {
    // A blocker cloud spread in depth from 1 to 2.
    std::vector<BlockerTriangle> tris;
    for (int k = 0; k < 40; ++k) {
        double z = 1.0 + k / 39.0, x = std::sin(k * 1.7) * 0.8, y = std::cos(k * 2.3) * 0.8;
        tris.push_back({Vec3{x, y, z}, Vec3{x + 0.2, y, z}, Vec3{x, y + 0.2, z}});
    }
    ConvolutionSettings s;
    s.resolution = 64;
    s.e_max = 1e-6;
    std::vector<double> E;
    for (int n = 1; n <= 8; ++n) {
        s.n_max = n;
        ConvolutionPlan P = planSoftShadow(planarSource(kSquareSource), tris, squareReceiver(3, 3), s);
        EXPECT_EQ(static_cast<int>(P.slices.size()), n);
        E.push_back(P.E_rr);
        if (n > 1) {
            EXPECT_LE(E[n - 1], E[n - 2] * 1.05);
        }
    }
    // Equal inverse-depth slabs: E(N) ~ E(1) / N.
    EXPECT_LT(E[7], E[0] / 5);
}

TEST(ConvSoftShadow, AutomaticResolutionFollowsAlphaMin) {
    std::vector<SquareBlocker> bl{{0, 0, 0.5, 1.0}};
    ConvolutionSettings s;  // resolution 0 = automatic
    s.maxResolution = 1024;
    ConvolutionPlan P = planSoftShadow(planarSource(kSquareSource), squareTris(bl[0]), squareReceiver(3, 3), s);
    // alpha_min = 2, L_S = 1 -> p = 1 -> n = ceil(6 / 1) = 6, raised to the minimum 16.
    EXPECT_EQ(P.n, 16);
    std::vector<SquareBlocker> nearRec{{0, 0, 0.5, 2.9}};  // alpha = 0.1/2.9 -> p = 0.01724 -> n = 348
    ConvolutionPlan Q = planSoftShadow(planarSource(kSquareSource), squareTris(nearRec[0]), squareReceiver(3, 3), s);
    EXPECT_EQ(Q.n, static_cast<int>(std::ceil(6.0 / (0.1 / 2.9 / 2))));
    EXPECT_GE(Q.fftSize, Q.n + 2);
}

TEST(ConvSoftShadow, ObjectRestingOnReceiverCastsShadow) {
    // A cube from z = 2 to z = 3 standing on the receiver plane z = 3.
    std::vector<BlockerTriangle> cube;
    const double h = 0.5;
    Vec3 c[8];
    for (int i = 0; i < 8; ++i) c[i] = {i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? 3.0 : 2.0};
    int f[6][4] = {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}};
    for (auto& q : f) {
        cube.push_back({c[q[0]], c[q[1]], c[q[2]]});
        cube.push_back({c[q[0]], c[q[2]], c[q[3]]});
    }
    ConvolutionSettings s;
    s.resolution = 128;
    SoftShadowTexture T = computeSoftShadow(planarSource(kSquareSource), cube, squareReceiver(3, 3), s);
    EXPECT_EQ(lookupVisibility(T, {0, 0, 3}), 0.0f);
    EXPECT_EQ(T.alpha_min, 0.0);
    EXPECT_GE(T.subBlockers, 1);
    // Beyond the tolerance it is refused.
    for (auto& t : cube)
        for (auto& v : t) v.z += (v.z > 2.5 ? 0.5 : 0);
    EXPECT_THROW(computeSoftShadow(planarSource(kSquareSource), cube, squareReceiver(3, 3), s), std::domain_error);
}

TEST(ConvSoftShadow, EmissionImageWeightsTheSource) {
    // Emission 1 on the +s half of the source, 0 elsewhere == a uniform half source.
    SourceDesc half = planarSource({{0, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {0, 0.5}});
    SourceDesc textured = planarSource(kSquareSource);
    textured.emission.width = 64;
    textured.emission.height = 8;
    for (int r = 0; r < 8; ++r)
        for (int col = 0; col < 64; ++col) textured.emission.texels.push_back(col >= 32 ? 1.0f : 0.0f);
    std::vector<SquareBlocker> bl{{0.1, 0.0, 0.5, 1.0}};
    ConvolutionSettings s;
    s.resolution = 128;
    s.direction = DirectionChoice::SourceNormal;
    SoftShadowTexture A = computeSoftShadow(half, squareTris(bl[0]), squareReceiver(3, 3), s);
    SoftShadowTexture B = computeSoftShadow(textured, squareTris(bl[0]), squareReceiver(3, 3), s);
    double maxd = 0;
    for (int j = 0; j < 41; ++j)
        for (int i = 0; i < 41; ++i) {
            Vec3 P{-2.9 + 5.8 * i / 40, -2.9 + 5.8 * j / 40, 3};
            maxd = std::fmax(maxd, std::fabs(lookupVisibility(A, P) - lookupVisibility(B, P)));
        }
    EXPECT_LT(maxd, 0.03);
    // ... and differs clearly from the uniform full source.
    SoftShadowTexture C = computeSoftShadow(planarSource(kSquareSource), squareTris(bl[0]), squareReceiver(3, 3), s);
    double maxc = 0;
    for (int i = 0; i < 41; ++i) {
        Vec3 P{-2.9 + 5.8 * i / 40, 0, 3};
        maxc = std::fmax(maxc, std::fabs(lookupVisibility(C, P) - lookupVisibility(B, P)));
    }
    EXPECT_GT(maxc, 0.2);
}

TEST(ConvSoftShadow, NoBlockerGivesFullLight) {
    SoftShadowTexture T = computeSoftShadow(planarSource(kSquareSource), {}, squareReceiver(3, 3), ConvolutionSettings{});
    EXPECT_EQ(T.subBlockers, 0);
    EXPECT_EQ(T.E_rr, 0.0);
    EXPECT_TRUE(std::isinf(T.alpha_min));
    for (float v : T.visibility) EXPECT_EQ(v, 1.0f);
    EXPECT_TRUE(std::isnan(lookupVisibility(T, {0, 0, -1})));  // behind the source centre
}

TEST(ConvSoftShadow, BadInputRaises) {
    ConvolutionSettings s;
    auto tris = squareTris({0, 0, 0.5, 1.0});
    SourceDesc nan = planarSource(kSquareSource);
    nan.polygon[2].y = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(computeSoftShadow(nan, tris, squareReceiver(3, 3), s), std::invalid_argument);
    SourceDesc line = planarSource({{0, 0}, {1, 0}, {2, 0}});
    EXPECT_THROW(computeSoftShadow(line, tris, squareReceiver(3, 3), s), std::invalid_argument);
    SourceDesc bent = planarSource(kSquareSource);
    bent.polygon[2].z = 0.3;
    EXPECT_THROW(computeSoftShadow(bent, tris, squareReceiver(3, 3), s), std::invalid_argument);
    auto badTris = tris;
    badTris[0][1].x = std::numeric_limits<double>::infinity();
    EXPECT_THROW(computeSoftShadow(planarSource(kSquareSource), badTris, squareReceiver(3, 3), s), std::invalid_argument);
    ReceiverDesc straddle{{{-1, -1, -1}, {1, -1, 3}, {1, 1, 3}, {-1, 1, 3}}};
    EXPECT_THROW(computeSoftShadow(planarSource(kSquareSource), tris, straddle, s), std::domain_error);
    ConvolutionSettings bad = s;
    bad.e_max = -1;
    EXPECT_THROW(computeSoftShadow(planarSource(kSquareSource), tris, squareReceiver(3, 3), bad), std::invalid_argument);
    SourceDesc em = planarSource(kSquareSource);
    em.emission.width = 2;
    em.emission.height = 2;
    em.emission.texels = {0, 0, 0, 0};
    EXPECT_THROW(computeSoftShadow(em, tris, squareReceiver(3, 3), s), std::invalid_argument);
}

TEST(ConvSoftShadow, OSMesaPathMatchesSpanPath) {
    std::vector<SquareBlocker> bl{{0.15, -0.1, 0.5, 1.0}};
    ConvolutionSettings s;
    s.resolution = 96;
    SoftShadowTexture A = computeSoftShadow(planarSource(kSquareSource), squareTris(bl[0]), squareReceiver(3, 3), s);
    s.rasterizer = RasterizerKind::OSMesa;
    SoftShadowTexture B;
    try {
        B = computeSoftShadow(planarSource(kSquareSource), squareTris(bl[0]), squareReceiver(3, 3), s);
    } catch (const std::runtime_error& e) {
        GTEST_SKIP() << "OSMesa unavailable: " << e.what();
    }
    EXPECT_EQ(B.rasterizer, RasterizerKind::OSMesa);
    double maxd = 0;
    for (size_t i = 0; i < A.visibility.size(); ++i) maxd = std::fmax(maxd, std::fabs(A.visibility[i] - B.visibility[i]));
    EXPECT_LT(maxd, 0.02);
    Errors e = compareParallel(B, kSquareSource, bl, 3, 3);
    EXPECT_LE(e.max, 0.03);
}

}  // namespace
}  // namespace penumbra

namespace penumbra {
namespace {

// ---- contact sub-blockers (issue 12): a box standing on the receiver ----
struct Box {
    Vec3 lo, hi;
};
std::vector<BlockerTriangle> boxTriangles(const Box& b, bool bottom) {
    Vec3 c[8];
    for (int i = 0; i < 8; ++i) c[i] = {i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z};
    // z runs from the source (z = 0) toward the receiver: the face at hi.z lies on the receiver. Wound
    // counter-clockwise seen from outside, as a modeller's closed mesh is.
    std::vector<std::array<int, 4>> f{{0, 2, 3, 1}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    if (bottom) f.push_back({4, 5, 7, 6});
    std::vector<BlockerTriangle> out;
    for (auto& q : f) {
        out.push_back({c[q[0]], c[q[1]], c[q[2]]});
        out.push_back({c[q[0]], c[q[2]], c[q[3]]});
    }
    return out;
}
// Visible fraction of the source square [-h, h]^2 at z = 0 from P, on m x m cell centres, slab test per ray.
double tracedVisibility(const Vec3& P, double h, const Box& b, int m = 64) {
    int seen = 0;
    for (int j = 0; j < m; ++j)
        for (int i = 0; i < m; ++i) {
            Vec3 q{-h + 2 * h * (i + 0.5) / m, -h + 2 * h * (j + 0.5) / m, 0};
            Vec3 d = q - P;
            double t0 = 0, t1 = 1;
            const double lo[3] = {b.lo.x, b.lo.y, b.lo.z}, hi[3] = {b.hi.x, b.hi.y, b.hi.z};
            const double o[3] = {P.x, P.y, P.z}, dd[3] = {d.x, d.y, d.z};
            for (int k = 0; k < 3 && t0 < t1; ++k) {
                if (dd[k] == 0) {
                    if (o[k] <= lo[k] || o[k] >= hi[k]) t1 = -1;
                    continue;
                }
                double a = (lo[k] - o[k]) / dd[k], c = (hi[k] - o[k]) / dd[k];
                t0 = std::fmax(t0, std::fmin(a, c));
                t1 = std::fmin(t1, std::fmax(a, c));
            }
            seen += !(t0 < t1);
        }
    return double(seen) / (m * m);
}

// A 0.6-wide, 1.0-tall box on the receiver plane z = 3, off-centre under a unit square source at z = 0. One
// convolution cannot fit a penumbra that vanishes at the contact: its E_rr is far above e_max and its map
// lets light under the box. Contact sub-blockers bring E_rr to e_max, leave the covered floor dark and keep
// the map within the stated tolerance of ray-traced visibility.
TEST(ConvSoftShadow, ContactSubBlockersKeepTheCoveredReceiverDark) {
    const Box box{{0.3, -0.3, 2.0}, {0.9, 0.3, 3.0}};
    const SourceDesc src = planarSource(kSquareSource);
    const ReceiverDesc rec = squareReceiver(2, 3);
    for (bool bottom : {false, true}) {
        std::vector<BlockerTriangle> tris = boxTriangles(box, bottom);
        ConvolutionSettings s;
        s.e_max = 1;
        s.contactSlabs = false;
        ConvolutionPlan whole = planSoftShadow(src, tris, rec, s);
        EXPECT_GT(whole.E_rr, 5 * s.e_max);
        SoftShadowTexture W = computeSoftShadow(whole, src, tris, s);
        s.contactSlabs = true;
        ConvolutionPlan P = planSoftShadow(src, tris, rec, s);
        ASSERT_TRUE(P.contact);
        EXPECT_LE(P.E_rr, s.e_max + 1e-9);
        EXPECT_GE(P.slices.size(), 3u);
        EXPECT_LE(P.slices.size(), size_t(s.n_max));
        SoftShadowTexture T = computeSoftShadow(P, src, tris, s);
        const double texel = P.window.extent / P.n;
        double leakWhole = 0, leak = 0, maxErr = 0, sumErr = 0, maxWhole = 0, sumWhole = 0;
        int count = 0;
        for (int j = 0; j < 40; ++j)
            for (int i = 0; i < 40; ++i) {
                Vec3 y{-1.9 + 3.8 * (i + 0.37) / 40, -1.9 + 3.8 * (j + 0.61) / 40, 3.0};
                bool under = y.x > box.lo.x && y.x < box.hi.x && y.y > box.lo.y && y.y < box.hi.y;
                bool edge = y.x > box.lo.x - 2 * texel && y.x < box.hi.x + 2 * texel && y.y > box.lo.y - 2 * texel &&
                            y.y < box.hi.y + 2 * texel && !under;
                if (under) {
                    // Inside by more than two texels: the bilinear lookup does not reach the lit side.
                    if (std::fmin(std::fmin(y.x - box.lo.x, box.hi.x - y.x), std::fmin(y.y - box.lo.y, box.hi.y - y.y)) >
                        2 * texel) {
                        leak = std::fmax(leak, lookupVisibility(T, y));
                        leakWhole = std::fmax(leakWhole, lookupVisibility(W, y));
                    }
                    continue;
                }
                if (edge) continue;  // the contact line itself: within a texel of the wall
                double traced = tracedVisibility(y, 0.5, box);
                double e = std::fabs(lookupVisibility(T, y) - traced), w = std::fabs(lookupVisibility(W, y) - traced);
                maxErr = std::fmax(maxErr, e);
                sumErr += e;
                maxWhole = std::fmax(maxWhole, w);
                sumWhole += w;
                ++count;
            }
        std::printf("bottom=%d: N=%zu E_rr=%.2f (one slab %.1f), light under the box %.3f (one slab %.3f), "
                    "max |dV| %.3f, mean %.4f (one slab %.3f, %.4f)\n", int(bottom), P.slices.size(), P.E_rr, whole.E_rr,
                    leak, leakWhole, maxErr, sumErr / count, maxWhole, sumWhole / count);
        // Measured: no light under the box (one slab: 0.46); max |dV| 0.19, mean 0.0062 (one slab: 0.36, 0.0115).
        // The largest misses are beside the walls, where a ray crosses two slabs and their product is
        // approximate (brief §4.4).
        EXPECT_EQ(leak, 0.0);
        EXPECT_GT(leakWhole, 0.2);
        EXPECT_LT(maxErr, 0.22);
        EXPECT_LT(sumErr / count, 0.008);
        EXPECT_LT(sumErr, sumWhole);
    }
}

}  // namespace
}  // namespace penumbra
