// Convex planar polygons (triangles and quads from the scene, clipped pieces of them), kept on the
// stack: the refiner evaluates millions of point-to-polygon form factors and must not allocate.
#pragma once
#include <array>

#include "geometry/vec3.h"

namespace penumbra {

struct Polygon {
    static constexpr int kMaxVerts = 12;  // a quad clipped by one plane has at most 5; slack for callers
    std::array<Vec3, kMaxVerts> v;
    int n = 0;

    void push(const Vec3& p) { if (n < kMaxVerts) v[n++] = p; }
    Vec3 areaVector() const;  // sum of edge cross products / 2: normal * area, orientation by winding
    double area() const { return length(areaVector()); }
    Vec3 normal() const { return normalize(areaVector()); }
    Vec3 centroid() const;    // area centroid
};

// Keeps the part of `poly` where dot(p - origin, n) >= 0 (Sutherland-Hodgman against one plane).
Polygon clipToHalfSpace(const Polygon& poly, const Vec3& origin, const Vec3& n);

}  // namespace penumbra
