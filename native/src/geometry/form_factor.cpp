#include "geometry/form_factor.h"

#include <cmath>

namespace penumbra {

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
        double gamma = std::atan2(cl, dot(a, b));
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
