#include "geometry/polygon.h"

namespace penumbra {

Vec3 Polygon::areaVector() const {
    Vec3 s;
    for (int i = 1; i + 1 < n; ++i) s += cross(v[i] - v[0], v[i + 1] - v[0]);
    return s * 0.5;
}

Vec3 Polygon::centroid() const {
    Vec3 c;
    double total = 0;
    for (int i = 1; i + 1 < n; ++i) {
        double a = length(cross(v[i] - v[0], v[i + 1] - v[0]));
        c += (v[0] + v[i] + v[i + 1]) * (a / 3.0);
        total += a;
    }
    if (total > 0) return c / total;
    Vec3 m;
    for (int i = 0; i < n; ++i) m += v[i];
    return n > 0 ? m / n : m;
}

Polygon clipToHalfSpace(const Polygon& poly, const Vec3& origin, const Vec3& n) {
    Polygon out;
    for (int i = 0; i < poly.n; ++i) {
        const Vec3& a = poly.v[i];
        const Vec3& b = poly.v[(i + 1) % poly.n];
        double da = dot(a - origin, n), db = dot(b - origin, n);
        if (da >= 0) out.push(a);
        if ((da >= 0) != (db >= 0)) {
            double t = da / (da - db);
            out.push(a + (b - a) * t);
        }
    }
    return out;
}

}  // namespace penumbra
