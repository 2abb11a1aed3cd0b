// Point, spot and sun lamps and a uniform world (scene.h: Light) at a point: each light's unoccluded
// irradiance in closed form, in Cycles' units, times its visible share from shadow rays. A lamp with
// a size (a point or spot radius, a sun's angular diameter) and the world are sampled at fixed Sobol'
// points over the disk or the hemisphere, the same for every point, so soft shadows come out as fine
// staircases, never as noise. The final gather calls this at every texel; the solver takes each leaf
// element's mean of it as the light arriving there directly (LightSet::elementIrradiance), so that
// what the surfaces reflect of it travels on through the hierarchy.
#pragma once
#include <memory>
#include <vector>

#include "bake/sun_textures.h"
#include "hierarchy/element.h"
#include "scene/scene.h"
#include "visibility/ray_caster.h"

namespace penumbra {

struct LightStats {
    size_t rays = 0;
};

class LightSet {
public:
    // `rays`: null for no shadows at all. `maxRays`: sample points per light and point at most, for
    // lights with a size and the world (rounded down to a power of two, at most kMaxRays; up to 32 for
    // elements).
    // `seed`: the sample pattern (util/seed.h); 0 is the default one.
    LightSet(const Scene& sc, const RayCaster* rays, int maxRays, int seed = 0);
    bool empty() const { return sc_.lights.empty(); }
    size_t size() const { return sc_.lights.size(); }

    // Irradiance (W/m^2) at p with normal n, recentred coordinates; `maxRays` < 0 takes the set's. The sample
    // set is the one the seed turned (util/seed.h), as in irradianceOn without a shift.
    Rgb irradiance(const Vec3& p, const Vec3& n, int maxRays = -1, LightStats* stats = nullptr) const;
    // The same with the sample set turned by `shift` in [0, 1)^2 (a toroidal shift of the Sobol' net), in place
    // of the seed's turn.
    Rgb irradiance(const Vec3& p, const Vec3& n, int maxRays, const double shift[2], LightStats* stats) const;
    // The same at a point of face `polygon`, whose suns' shadows come from their textures where it has them.
    Rgb irradianceOn(int polygon, const Vec3& p, const Vec3& n, int maxRays, const double shift[2],
                     LightStats* stats) const;
    Rgb irradianceOn(int polygon, const Vec3& p, const Vec3& n) const;
    // Suns' soft shadows on the faces that have a texture (null: rays everywhere).
    void setSunTextures(std::shared_ptr<const SunTextures> t) { sunTextures_ = std::move(t); }
    // The mean over an element of a receiving face (quadrature points, fewer rays, each point's sample
    // set turned by a fixed offset from the element's key): what the solver adds to the element's
    // gathered irradiance.
    Rgb elementIrradiance(const Element& e, const Vec3& n, LightStats* stats = nullptr) const;
    // Per element of h (0 for inner elements and non-receivers), in parallel.
    std::vector<Rgb> leafIrradiance(const Hierarchy& h, int threads, LightStats* stats = nullptr) const;

    static constexpr int kMaxRays = 1024;

private:
    Rgb one(const Light& l, int index, int polygon, const Vec3& p, const Vec3& n, int maxRays, const double shift[2],
            LightStats* stats) const;
    const Scene& sc_;
    const RayCaster* rays_;
    int maxRays_;
    int seed_;
    double shift_[2];  // the seed's turn of the bake points' Sobol' set
    double lift_, far_;
    std::shared_ptr<const SunTextures> sunTextures_;
};

// The fraction of a spot's intensity sent at angle acos(cosAxis) from its axis: zero outside the cone,
// inside it the cosine (Cycles 3.x multiplies by it, measured against a Cycles 3.4 bake at 0 to 44
// degrees in a 90 degree cone; 4.0+ does not, `spotCosine` false: a 5.2 bake at 48 degrees off the axis
// of a 160 degree cone gave the bare point's irradiance), times a smoothstep over the blend band of
// width (1 - cos(size/2)) * blend in cosine.
double spotAttenuation(const Light& l, double cosAxis);
// A world's environment image at direction d (unit), without the strength.
Rgb envRadiance(const Light& l, const Vec3& d);
// A sun of angular diameter `angle` at normal incidence gives strength times this (Cycles spreads the
// strength uniformly over the disk of radius tan(angle/2) at unit distance).
double sunDiskFactor(double angle);

}  // namespace penumbra
