#include "geometry/form_factor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace penumbra {
namespace {

Polygon quad(Vec3 a, Vec3 b, Vec3 c, Vec3 d) {
    Polygon p;
    p.push(a); p.push(b); p.push(c); p.push(d);
    return p;
}

// Brute-force integral of cos(theta_x) cos(theta_y) / (pi r^2) over a planar polygon, midpoint rule on
// a fine grid of its triangle fan. Only the part above x's tangent plane counts (cos(theta_x) > 0),
// and the polygon's orientation is ignored, as in pointToPolygonFormFactor.
double quadrature(const Vec3& x, const Vec3& n, const Polygon& poly, int s) {
    Vec3 pn = poly.normal();
    double sum = 0;
    for (int t = 1; t + 1 < poly.n; ++t) {
        Vec3 a = poly.v[0], b = poly.v[t], c = poly.v[t + 1];
        double cellArea = 0.5 * length(cross(b - a, c - a)) / (double(s) * s);
        for (int i = 0; i < s; ++i)
            for (int j = 0; i + j < s; ++j) {
                for (int up = 0; up < 2; ++up) {
                    if (up && i + j + 1 >= s) continue;
                    double u = (i + (up ? 2.0 : 1.0) / 3.0) / s, v = (j + (up ? 2.0 : 1.0) / 3.0) / s;
                    Vec3 y = a + (b - a) * u + (c - a) * v;
                    Vec3 r = y - x;
                    double r2 = length2(r);
                    double cx = dot(n, r), cy = std::fabs(dot(pn, r));
                    if (cx <= 0) continue;
                    sum += cx * cy / (M_PI * r2 * r2) * cellArea;
                }
            }
    }
    return sum;
}

// Lambert's formula takes its edge angles from angleBetween, not std::atan2: the two must agree over the
// whole half turn, at every magnitude, at the reduction's seams (pi/8, pi/4, 3 pi/8, pi/2) and at the ends.
TEST(FormFactor, AngleBetweenMatchesAtan2) {
    double worst = 0;
    auto check = [&](double s, double c) {
        double err = std::fabs(angleBetween(s, c) - std::atan2(s, c));
        worst = std::max(worst, err);
        EXPECT_LE(err, 1e-13) << "sine " << s << " cosine " << c;
    };
    const int steps = 200000;
    for (double scale : {1e-200, 1e-8, 1.0, 3e5, 1e200})
        for (int i = 0; i <= steps; ++i) {
            double theta = M_PI * i / steps;
            check(scale * std::sin(theta), scale * std::cos(theta));
        }
    for (int k = 1; k < 8; ++k)
        for (double d : {-1e-12, -1e-15, 0.0, 1e-15, 1e-12}) {
            double theta = k * M_PI / 8 + d;
            check(std::sin(theta), std::cos(theta));
        }
    check(0.0, 1.0);
    check(0.0, -1.0);
    check(1.0, 0.0);
    check(1e-300, 1.0);
    check(1e-300, -1.0);
    EXPECT_EQ(angleBetween(0.0, 0.0), 0.0);
    std::printf("largest difference from atan2: %.3g rad\n", worst);
}

TEST(FormFactor, ParallelSquareMatchesQuadrature) {
    Polygon sq = quad({-0.5, -0.5, 1}, {0.5, -0.5, 1}, {0.5, 0.5, 1}, {-0.5, 0.5, 1});
    Vec3 x{0.2, -0.1, 0}, n{0, 0, 1};
    double exact = pointToPolygonFormFactor(x, n, sq);
    EXPECT_NEAR(exact, quadrature(x, n, sq, 1500), 1e-4);
    // Closed form for a point under the corner of an a x b rectangle at height c (here a square seen
    // from its centre is four such corners): F = 4 * (1/2pi)(A atan(B/A)...) — checked via symmetry.
    double centre = pointToPolygonFormFactor({0, 0, 0}, n, sq);
    double a = 0.5, c = 1.0;
    double A = a / std::sqrt(a * a + c * c);
    double corner = (1.0 / (2 * M_PI)) * (2 * A * std::atan(A));  // a == b case of the corner formula
    EXPECT_NEAR(centre, 4 * corner, 1e-12);
}

TEST(FormFactor, TiltedAndStraddlingPolygonsMatchQuadrature) {
    Polygon tilted = quad({-0.3, 0.2, 0.4}, {0.6, 0.1, 0.9}, {0.5, 0.8, 1.3}, {-0.4, 0.9, 0.8});
    Vec3 n = normalize(Vec3{0.3, -0.2, 1});
    EXPECT_NEAR(pointToPolygonFormFactor({0, 0, 0}, n, tilted), quadrature({0, 0, 0}, n, tilted, 1500),
                1e-4);
    // A wall rising from below the horizon of x: only the upper part may count (horizon clipping).
    Polygon wall = quad({1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1});
    Vec3 up{0, 0, 1};
    double clipped = pointToPolygonFormFactor({0, 0, 0}, up, wall);
    EXPECT_NEAR(clipped, quadrature({0, 0, 0}, up, wall, 1500), 1e-4);
    Polygon upper = quad({1, -1, 0}, {1, 1, 0}, {1, 1, 1}, {1, -1, 1});
    EXPECT_NEAR(clipped, pointToPolygonFormFactor({0, 0, 0}, up, upper), 1e-12);
    // Entirely below the horizon: nothing.
    Polygon below = quad({-1, -1, -2}, {1, -1, -2}, {1, 1, -2}, {-1, 1, -2});
    EXPECT_EQ(pointToPolygonFormFactor({0, 0, 0}, up, below), 0.0);
}

TEST(FormFactor, HemisphereCoveringPolygonGivesOne) {
    double s = 1e4;  // a huge square close above x fills the hemisphere
    Polygon sq = quad({-s, -s, 1}, {s, -s, 1}, {s, s, 1}, {-s, s, 1});
    EXPECT_NEAR(pointToPolygonFormFactor({0, 0, 0}, {0, 0, 1}, sq), 1.0, 1e-4);
}

TEST(FormFactor, Reciprocity) {
    Polygon i = quad({0, 0, 0}, {1, 0, 0}, {1, 0.6, 0}, {0, 0.6, 0});
    Polygon j = quad({0.2, 1.0, 0.3}, {0.2, 1.0, 1.2}, {1.4, 1.3, 1.2}, {1.4, 1.3, 0.3});
    // Face the two so that each sees the other's front.
    if (dot(j.normal(), i.centroid() - j.centroid()) < 0) std::reverse(j.v.begin(), j.v.begin() + j.n);
    double fij = polygonToPolygonFormFactor(i, j, 40);
    double fji = polygonToPolygonFormFactor(j, i, 40);
    ASSERT_GT(fij, 0.01);
    EXPECT_NEAR(i.area() * fij, j.area() * fji, 1e-4 * i.area() * fij);
}

TEST(FormFactor, ParallelSquaresClosedForm) {
    // Two coaxial parallel unit squares at distance 1: F = 0.19982 (standard tabulated value).
    Polygon a = quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0});
    Polygon b = quad({0, 0, 1}, {0, 1, 1}, {1, 1, 1}, {1, 0, 1});
    EXPECT_NEAR(polygonToPolygonFormFactor(a, b, 60), 0.199825, 2e-5);
}

}  // namespace
}  // namespace penumbra
