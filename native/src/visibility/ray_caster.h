// Occlusion queries with Embree (3 on Debian 12, 4 on Debian 13 and sid) over every occluding polygon of the scene.
#pragma once
// CMakeLists.txt defines PENUMBRA_EMBREE_MAJOR from the Embree package it found.
#if PENUMBRA_EMBREE_MAJOR >= 4
#include <embree4/rtcore.h>
#else
#include <embree3/rtcore.h>
#endif

#include <vector>

#include "geometry/box_tree.h"
#include "scene/scene.h"
#include "visibility/shaft.h"

namespace penumbra {

class RayCaster {
public:
    explicit RayCaster(const Scene& scene);
    ~RayCaster();
    RayCaster(const RayCaster&) = delete;
    RayCaster& operator=(const RayCaster&) = delete;

    // Every query is thread-safe.
    // visible[i] = 1 when nothing blocks the open segment (from[i], to[i]), else 0; 16-wide packets because a
    // link's samples are coherent (measured 2.4x faster than single rays here).
    // `diffuseRay`: a ray carrying reflected light, which polygons hidden from diffuse rays let through.
    void visiblePairs(const Vec3* from, const Vec3* to, int n, char* visible, bool diffuseRay = false) const;
    // visible[i] = 1 when nothing blocks the open segment (from, to[i]), else 0; 16-wide packets.
    // `lampRay`: a point, spot or sun lamp's shadow ray, which polygons without blocksLamps let through.
    void visibleMask(const Vec3& from, const Vec3* to, int n, char* visible, bool lampRay = false) const;
    // True when no occluding polygon other than the two named ones can cross the shaft between the
    // boxes (Haines-Wallace): every segment between them is then unblocked without casting a ray.
    bool shaftIsClear(const Bounds& a, const Bounds& b, int skipPolygonA, int skipPolygonB) const;
    // The same, for segments known to stay at least `height` in front of each of the planes (point, unit
    // normal) given: a polygon whose box lies within `height` of a plane's front or behind it cannot
    // cross them. A receiver's coplanar neighbours on a meshed floor touch every shaft leaving it.
    struct HalfSpace {
        Vec3 point, normal;
    };
    bool shaftIsClear(const Bounds& a, const Bounds& b, int skipPolygonA, int skipPolygonB,
                      const HalfSpace* above, int numAbove, double height) const;

    // Per polygon: its front lies inside a solid (a desk leg's top flush under the desk, a box's bottom on
    // the floor): the first surface that a ray off it meets, from its centre, the points halfway to its corners
    // and points near its corners, is always met from behind. Such a face sees nothing; cluster links, which
    // cannot see shadows inside a cluster, must not light it.
    std::vector<char> buriedFaces(const Scene& scene, double lift) const;
    // Per polygon: some other occluding polygon comes within `lift` of its box and reaches in front of it (a
    // box or a chair leg standing on a floor tile, a wall meeting it at a corner). Only such a polygon can
    // have points of its front inside a closed surface (metFromBehind from them); elsewhere the test is skipped.
    std::vector<char> touchedFaces(const Scene& scene, double lift) const;
    // Of the touched faces (touchedFaces' answer), those that another occluding polygon reaching in front of
    // them meets along a segment through their interior: the sides of a leg or a box standing on a floor
    // tile, or sunk into it. Only there can part of a face's front lie inside a closed surface without the
    // whole face being buried; a wall meeting a tile at its edge, or a foot standing on its neighbour, cannot.
    // A face that is not convex keeps touchedFaces' answer.
    std::vector<char> footprintFaces(const Scene& scene, double lift, const std::vector<char>& touched) const;
    // The first occluding polygon along the ray is met from behind: the origin lies inside a closed surface
    // (a two-sided face's back copy shares its front's triangles, so meeting those from behind is not that).
    bool metFromBehind(const Scene& scene, const Vec3& origin, const Vec3& dir, double far) const;
    // The first occluding polygon along the ray (origin, unit dir) within `far`, and its distance;
    // polygon -1 when nothing is met.
    struct Hit {
        int polygon = -1;
        double distance = 0;
    };
    Hit firstHit(const Vec3& origin, const Vec3& dir, double far) const;
    // Occluding polygons whose boxes the shaft does not classify Outside (the caller tests further).
    std::vector<int> occludersInShaft(const Shaft& shaft) const;

private:
    // Calls visit(q) for every occluding polygon q other than polygon i's own whose box comes within `lift` of i's,
    // until `done` turns true.
    template <class Visit>
    void forOccludersNear(const Scene& scene, size_t i, double lift, const bool& done, Visit&& visit) const;

    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    RTCScene lampScene_ = nullptr;      // without the polygons lamps' shadow rays pass; null when there are none
    RTCScene diffuseScene_ = nullptr;   // without the polygons diffuse rays pass; null when there are none
    size_t numTriangles_ = 0, numLampTriangles_ = 0, numDiffuseTriangles_ = 0;
    BoxTree occluders_;                 // boxes of occluding polygons
    std::vector<int> occluderPolygon_;  // scene polygon of each box
    std::vector<int> triPolygon_;       // scene polygon of each Embree triangle
};

}  // namespace penumbra
