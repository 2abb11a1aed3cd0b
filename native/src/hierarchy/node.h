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

// Irradiance at y from `source`. An element within a few of its widths of y gives its exact form factor
// times B; farther out, the point kernel B A cos cos_y / (pi r^2) with its second-order term over the face
// (node.cpp, faceKernel); without a receiver normal, B A cos / (pi r^2 + A). A cluster emits from its centre, each
// normal class by its own cosine: sum over classes of (sum of B A) max(0, n_m . u) cos_y / (pi r^2),
// which is the sum over its faces in the far field (Hierarchy::updateClusterFlux must be current).
// Without a receiver normal (n == nullptr) cos_y is 1: the flux density that a cluster receiver then
// shares among its faces by their own cosines.
Rgb fluxAt(const Hierarchy& h, int source, const Vec3& y, const Vec3* n);

// The light of a cluster source's faces with each face's kernel given: sum of B_k weights[k], k counting the
// faces below it in the cluster tree's order.
Rgb weightedFaceLight(const Hierarchy& h, int clusterSource, const float* weights);

// A cluster source's light over a ball of receiving points that all lie in its far field, as one linear
// map of the direction: where every normal class of its faces is turned toward the whole ball or away
// from all of it, the sum over classes of flux_m max(0, n_m . u) is (sum over the classes turned toward
// it of flux_m n_m^T) u, the same sum as fluxAt's in another order (fluxAt's in single precision). at() is
// then fluxAt at any y in the ball for the cost of one class.
struct FarFieldLight {
    Vec3 center;       // the source cluster's
    Vec3 rows[3];      // per colour channel: sum of flux_m n_m over the classes turned toward the ball
    Rgb at(const Vec3& y, const Vec3* n) const;
};
// False where the ball is not wholly in the source's far field or a class turns toward part of it only.
bool farFieldLight(const Hierarchy& h, int clusterSource, const Vec3& ballCenter, double ballRadius,
                   FarFieldLight& out);

// Irradiance at y (facing n, or a sphere's cross-section with n null) per unit radiosity of element e,
// which lies on a plane with normal en: the disc estimate from e's centre, exact within a few of e's widths.
double elementKernel(const Element& e, const Vec3& en, const Vec3& y, const Vec3* n);

// Upper bound on the irradiance `source` can send to any point of a receiver whose box is `rb`: face by
// face, cosines widened by the angular radius of the other end, the distance shrunk to the gap between
// the face's box and rb, and no face's form factor above 1 (so a face touching rb adds its radiosity).
// A cluster's faces count with their radiosity as of the last Hierarchy::updateClusterFlux.
double fluxBound(const Hierarchy& h, int source, const Bounds& rb);

}  // namespace penumbra
