// One interface over the two kinds of node a link can join: a quadtree element on a polygon, or a
// cluster of polygons. Cluster transfers follow Sillion's oriented ("alpha") clusters: each polygon
// inside is weighted by its own cosine toward the other end, so a cluster neither emits toward where
// its faces turn away nor receives on faces that look elsewhere.
#pragma once
#include "hierarchy/element.h"

namespace penumbra {

Bounds nodeBox(const Hierarchy& h, int node);
Vec3 nodeCenter(const Hierarchy& h, int node);

// Irradiance at y from the polygons of `source` (a cluster), or from the element itself, each taken
// as a small emitter at its centre: sum of B_j A_j cos_j cos_y / (pi r^2 + A_j). Without a receiver
// normal (n == nullptr) cos_y is 1: the flux density that a cluster receiver then shares among its
// faces by their own cosines. The + A_j keeps the point approximation finite when r is small.
Rgb fluxAt(const Hierarchy& h, int source, const Vec3& y, const Vec3* n);

// Upper bound on the irradiance `source` can send to any point of a receiver whose box is `rb`, at
// distance dmin or more: cosines are widened by the angular radius of the other end, distances
// shrunk to dmin. Infinite when the boxes touch.
double fluxBound(const Hierarchy& h, int source, const Bounds& rb);

}  // namespace penumbra
