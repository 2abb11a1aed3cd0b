// A small double-precision 3-vector. The solver works in doubles: Blender scenes can sit 1e5 from the
// origin and hold 1e-4-sized features, which float32 cannot resolve together.
#pragma once
#include <algorithm>
#include <cmath>

namespace penumbra {

struct Vec3 {
    double x = 0, y = 0, z = 0;
    Vec3() = default;
    constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    double operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    double& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
    Vec3 operator+(const Vec3& b) const { return {x + b.x, y + b.y, z + b.z}; }
    Vec3 operator-(const Vec3& b) const { return {x - b.x, y - b.y, z - b.z}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
    Vec3& operator+=(const Vec3& b) { x += b.x; y += b.y; z += b.z; return *this; }
    Vec3& operator-=(const Vec3& b) { x -= b.x; y -= b.y; z -= b.z; return *this; }
    Vec3& operator*=(double s) { x *= s; y *= s; z *= s; return *this; }
};

inline Vec3 operator*(double s, const Vec3& v) { return v * s; }
inline double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& a) { return std::sqrt(dot(a, a)); }
inline double length2(const Vec3& a) { return dot(a, a); }
inline Vec3 normalize(const Vec3& a) {
    double l = length(a);
    return l > 0 ? a / l : Vec3{};
}
// std::fmin/fmax's results (NaN dropped, the first of two equal values, so -0 and +0 as glibc gives
// them) without their library call, which was 4 % of a furnished room's refinement.
inline double fminOf(double a, double b) { return a <= b || b != b ? a : b; }
inline double fmaxOf(double a, double b) { return a >= b || b != b ? a : b; }
inline Vec3 vmin(const Vec3& a, const Vec3& b) { return {fminOf(a.x, b.x), fminOf(a.y, b.y), fminOf(a.z, b.z)}; }
inline Vec3 vmax(const Vec3& a, const Vec3& b) { return {fmaxOf(a.x, b.x), fmaxOf(a.y, b.y), fmaxOf(a.z, b.z)}; }
inline bool isFinite(const Vec3& a) {
    return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z);
}

// RGB quantities (reflectance, radiosity, irradiance) are carried per colour channel.
using Rgb = Vec3;
inline Rgb mul(const Rgb& a, const Rgb& b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline double maxComponent(const Vec3& a) { return fmaxOf(a.x, fmaxOf(a.y, a.z)); }

// a >= b, with sizes within a millionth counted equal: a choice between two equal faces of a regular mesh
// (which to split, a cube's split axis) must not hang on the rounding of their coordinates, so that a
// scene scaled by 1e-3, which is no dyadic copy of the original, refines the same way.
inline bool notSmaller(double a, double b) { return a >= b * (1 - 1e-6); }

// Axis-aligned bounding box, used by the hierarchy, the shafts and the scene's scale.
struct Bounds {
    Vec3 lo{HUGE_VAL, HUGE_VAL, HUGE_VAL};
    Vec3 hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    void extend(const Vec3& p) { lo = vmin(lo, p); hi = vmax(hi, p); }
    void extend(const Bounds& b) { lo = vmin(lo, b.lo); hi = vmax(hi, b.hi); }
    bool empty() const { return lo.x > hi.x; }
    Vec3 center() const { return (lo + hi) * 0.5; }
    Vec3 diagonal() const { return hi - lo; }
};

// Distance between two boxes, 0 where they overlap.
inline double boxDistance(const Bounds& a, const Bounds& b) {
    double d2 = 0;
    for (int k = 0; k < 3; ++k) {
        double gap = std::max({0.0, b.lo[k] - a.hi[k], a.lo[k] - b.hi[k]});
        d2 += gap * gap;
    }
    return std::sqrt(d2);
}

}  // namespace penumbra
