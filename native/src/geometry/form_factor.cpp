#include "geometry/form_factor.h"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace penumbra {

namespace {

// atan(t) / t - 1 = z g(z), z = t^2, for |t| <= tan(pi/8): g by least squares on Chebyshev nodes in z
// (numpy, against its atan), largest relative error of atan 1.1e-13 there (form_factor_test.cpp).
constexpr double kAtanPoly[] = {-0.3333333333147718,  0.19999999662537327, -0.14285692615646609,
                                0.11110428915973505,  -0.09078887497503749, 0.07566877093038553,
                                -0.058852587620987905, 0.0308121027523056};

double atanReduced(double t) {
    double z = t * t, g = 0.0;
    for (int k = int(std::size(kAtanPoly)) - 1; k >= 0; --k) g = g * z + kAtanPoly[k];
    return t + t * z * g;
}

}  // namespace

double angleBetween(double sine, double cosine) {
    constexpr double kTanPi8 = 0.41421356237309504880;
    double c = std::fabs(cosine);
    double lo = std::min(sine, c), hi = std::max(sine, c);
    if (!(hi > 0)) return 0.0;
    // The angle of (hi, lo), in [0, pi/4]: atan(lo / hi), or pi/4 + atan of the reflected ratio past pi/8.
    double a = lo > kTanPi8 * hi ? M_PI / 4 + atanReduced((lo - hi) / (lo + hi)) : atanReduced(lo / hi);
    if (sine > c) a = M_PI / 2 - a;
    return cosine < 0 ? M_PI - a : a;
}

namespace {

// Lambert's formula over a polygon wholly in front of x.
double lambert(const Vec3& x, const Vec3& n, const Polygon& p) {
    if (p.n < 3) return 0.0;
    double sum = 0.0;
    for (int i = 0; i < p.n; ++i) {
        Vec3 a = p.v[i] - x, b = p.v[(i + 1) % p.n] - x;
        Vec3 c = cross(a, b);
        double cl = length(c);
        if (cl <= 1e-300) continue;  // edge passes through x's line of sight: no solid angle
        double gamma = angleBetween(cl, dot(a, b));
        sum += gamma * dot(n, c) / cl;
    }
    return std::fabs(sum) / (2.0 * M_PI);
}

}  // namespace

double pointToPolygonFormFactor(const Vec3& x, const Vec3& n, const Polygon& poly) {
    // Most polygons lie wholly in front of x: clipping would return them unchanged, vertex for vertex, after
    // building (and zeroing) a twelve-vertex copy.
    for (int i = 0; i < poly.n; ++i)
        if (dot(poly.v[i] - x, n) < 0) return lambert(x, n, clipToHalfSpace(poly, x, n));
    return lambert(x, n, poly);
}

double polygonToPolygonFormFactor(const Polygon& from, const Polygon& to, int s) {
    Vec3 n = from.normal();
    double total = 0.0, area = 0.0;
    for (int t = 1; t + 1 < from.n; ++t) {
        Vec3 a = from.v[0], b = from.v[t], c = from.v[t + 1];
        double triArea = 0.5 * length(cross(b - a, c - a));
        // Midpoints of the s*s sub-triangles of a regular subdivision (upward and downward ones).
        int count = 0;
        double acc = 0.0;
        for (int i = 0; i < s; ++i)
            for (int j = 0; j + i < s; ++j) {
                double u = (i + 1.0 / 3.0) / s, v = (j + 1.0 / 3.0) / s;
                acc += pointToPolygonFormFactor(a + (b - a) * u + (c - a) * v, n, to);
                ++count;
                if (i + j + 1 < s) {
                    double u2 = (i + 2.0 / 3.0) / s, v2 = (j + 2.0 / 3.0) / s;
                    acc += pointToPolygonFormFactor(a + (b - a) * u2 + (c - a) * v2, n, to);
                    ++count;
                }
            }
        total += acc / count * triArea;
        area += triArea;
    }
    return area > 0 ? total / area : 0.0;
}

}  // namespace penumbra
