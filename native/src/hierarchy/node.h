// One interface over the two kinds of node a link can join: a quadtree element on a polygon, or a
// cluster of polygons. Cluster transfers follow Sillion's oriented ("alpha") clusters: each polygon
// inside is weighted by its own cosine toward the other end, so a cluster neither emits toward where
// its faces turn away nor receives on faces that look elsewhere.
#pragma once
#include "hierarchy/element.h"

namespace penumbra {

Bounds nodeBox(const Hierarchy& h, int node);
Vec3 nodeCenter(const Hierarchy& h, int node);
// A node's identity independent of creation order (an element's or a cluster's key).
uint64_t nodeKey(const Hierarchy& h, int node);

// Irradiance at y from `source`. An element is a small emitter at its centre: B A cos cos_y /
// (pi r^2 + A), the + A keeping it finite when r is small. A cluster emits from its centre, each
// normal class by its own cosine: sum over classes of (sum of B A) max(0, n_m . u) cos_y / (pi r^2),
// which is the sum over its faces in the far field (Hierarchy::updateClusterFlux must be current).
// Without a receiver normal (n == nullptr) cos_y is 1: the flux density that a cluster receiver then
// shares among its faces by their own cosines.
Rgb fluxAt(const Hierarchy& h, int source, const Vec3& y, const Vec3* n);

// Upper bound on the irradiance `source` can send to any point of a receiver whose box is `rb`, at
// distance dmin or more: cosines are widened by the angular radius of the other end, distances
// shrunk to dmin. Infinite when the boxes touch.
double fluxBound(const Hierarchy& h, int source, const Bounds& rb);

}  // namespace penumbra
