// Direct light at a bake point (the final gather): every emitting face's exact unoccluded form factor
// (Lambert's formula) times its visibility from that point, times its exitance. The hierarchy's leaves
// carry the light once reflected, which varies smoothly; the light straight from the emitters, with
// its hard contact shadows and the hot spot under a lamp mounted close to a ceiling, is evaluated at
// every texel instead of being averaged over an element. Visibility comes from rays to a fixed grid
// of points on each emitter (the same grid for every bake point, so there is no noise: a penumbra is
// at worst a staircase of m^2 levels); a coarse grid first, the full one only where it sees the
// emitter partly hidden.
#pragma once
#include <vector>

#include "scene/scene.h"
#include "visibility/ray_caster.h"

namespace penumbra {

struct DirectStats {
    size_t rays = 0, pairs = 0, seenWhole = 0;  // seenWhole: pairs whose coarse points all got through
};

class DirectLight {
public:
    // `maxRays`: rays per emitter group and point at most, 0 for none; `excluded[p]`: the emitting
    // faces whose light polygon p takes some other way (a convolution link's texture), ascending.
    // `seed`: the sample pattern (util/seed.h); 0 is the default one.
    DirectLight(const Scene& sc, const RayCaster& rays, int maxRays, std::vector<std::vector<int>> excluded,
                int seed = 0);
    // Irradiance (W/m^2) at p with normal n on receiving polygon `receiver`; recentred coordinates.
    Rgb irradiance(const Vec3& p, const Vec3& n, int receiver, DirectStats* stats = nullptr) const;
    size_t emitters() const { return emitters_.size(); }
    // False with maxRays = 0: irradiance() is then unoccluded, and the caller supplies the visibility.
    // (An emitter that casts no shadow is unoccluded whatever maxRays is.)
    bool castsRays() const { return maxRays_ > 0; }

private:
    // Coplanar emitting faces of one object with one exitance (a lamp modelled as a grid of quads):
    // each face's form factor is exact, their visibility is sampled once for the group.
    struct Emitter {
        std::vector<int> polygons;
        std::vector<int> occluders;  // the polygon whose triangles each is (a back side shares its front's)
        std::vector<Polygon> geoms;
        std::vector<Vec3> centers;   // per face: area centroid
        std::vector<double> areas, sizes;  // per face: area, largest corner distance from the centroid
        Vec3 normal, center;
        Rgb E;
        Bounds box;
        double size = 0;             // box diagonal
        double area = 0;
        bool castsShadow = true;     // false: the light's Cast Shadow is off, nothing hides it
    };
    // Weighted visible fraction of the group from p over about `count` of its points.
    double visibility(const Emitter& e, const Vec3& p, const Vec3& n, const Vec3& from, int count,
                      DirectStats* stats) const;
    const Scene& sc_;
    const RayCaster& rays_;
    std::vector<Emitter> emitters_;
    std::vector<std::vector<int>> excluded_;
    int maxRays_;
    double shift_[2];  // the seed's turn of the Sobol' points
    double lift_;
};

}  // namespace penumbra
