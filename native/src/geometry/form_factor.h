// Exact diffuse form factors (Lambert's contour integral). These are the ground truth the refiner's
// estimates and the tests are measured against.
#pragma once
#include "geometry/polygon.h"

namespace penumbra {

// Form factor from a differential area at `x` with unit normal `n` to the convex polygon `poly`
// (the fraction of energy leaving dA_x that arrives at the polygon, which equals the irradiance at x
// per unit radiosity of the polygon). The polygon is clipped to x's upper hemisphere first, so
// polygons straddling the tangent plane of x are handled exactly. Sidedness of the polygon is not
// tested here: callers decide whether its front faces x.
double pointToPolygonFormFactor(const Vec3& x, const Vec3& n, const Polygon& poly);

// The angle between two vectors from |a x b| >= 0 and a . b: atan2(sine, cosine) in [0, pi], within
// 1e-13 rad of it. Lambert's formula takes one per polygon edge, and glibc's atan2 (rounding mode saved and
// restored around an exactly rounded result) was 6 % of a 20k-polygon office's solve: this is a polynomial
// after reduction to |t| <= tan(pi/8), and the same on every machine, where glibc's last bits follow the CPU.
double angleBetween(double sine, double cosine);

// Area-averaged form factor F_ij = (1/A_i) * integral over i of F(x <- j), by an s x s midpoint rule
// on triangle fans of i. Unoccluded; slow; for tests and reference values.
double polygonToPolygonFormFactor(const Polygon& from, const Polygon& to, int samplesPerSide);

}  // namespace penumbra
