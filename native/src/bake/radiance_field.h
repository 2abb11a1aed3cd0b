// The solution as a function on surfaces: outgoing reflected radiance at any point. Leaf values are
// blended with tensor-product tent weights in each leaf's own frame, so the reconstruction is
// continuous across element edges, T-vertices and polygon boundaries of one surface, and exactly the
// leaf value at the centre of a leaf whose neighbours are the same size. A leaf serves only points of
// its own surface: on its plane (to float32 rounding and the warp of its face), or across a shallow
// fold onto a neighbouring facet; never a parallel surface, however close.
#pragma once
#include <memory>
#include <vector>

#include "bake/direct_light.h"
#include "bake/lights.h"
#include "geometry/box_tree.h"
#include "hierarchy/element.h"
#include "solve/convolution_link.h"

namespace penumbra {

class RadianceField {
public:
    RadianceField() = default;
    explicit RadianceField(const Hierarchy& h);
    // With convolution links: each leaf's value leaves out what its complete textures reflect
    // (`textured`, per element), and `conv` adds it back point by point, shadow detail included.
    RadianceField(const Hierarchy& h, const std::vector<Rgb>& textured, ConvolutionField conv);
    // With the final gather: `shadowed` (per element, Solver::directIrradiance) is what the leaves
    // hold of the emitters' light; it is taken out of them and `direct` evaluates it at every point
    // instead: the exact unoccluded form factors there, times the visibility blended from the leaves
    // (shadowed / unoccluded), or with its own rays when it casts them. `textured` may be empty.
    // Likewise `lightE` (per element, LightSet::leafIrradiance) is what the leaves hold of the lamps' and
    // world's light, taken out of them and evaluated by `lights` at every point instead.
    RadianceField(const Hierarchy& h, const std::vector<Rgb>& textured, ConvolutionField conv,
                  const std::vector<Rgb>& shadowed, const std::vector<Rgb>& unoccluded,
                  std::shared_ptr<const DirectLight> direct, std::shared_ptr<const LightSet> lights = nullptr,
                  const std::vector<Rgb>& lightE = {});
    // p in the scene's recentred coordinates; n the geometric normal of the surface at p.
    // With `irradiance`: E/pi, the light arriving at p without the surface's albedo (what a bake with a
    // per-texel albedo multiplies). Each leaf's value is divided by its own polygon's albedo before the
    // blend; a channel whose albedo is 0 reflected nothing, so it keeps only the light the final gather
    // evaluates at the point (emitters and lamps) and loses its share of the indirect light.
    Rgb radiance(const Vec3& p, const Vec3& n, bool irradiance = false) const;

    // The leaves and polygons whose boxes reach into `box` (a lightmap's triangles), in the order the trees
    // visit them: radiance() at a point inside the box scans these lists instead of walking the trees, with
    // the same candidates in the same order and so the same sums, bit for bit. A list longer than is worth
    // scanning is left empty, and the trees are walked for it.
    struct Region {
        Bounds box;
        std::vector<int> leaves, polygons;
        bool scanLeaves = false, scanPolygons = false;
    };
    Region region(const Bounds& box) const;
    Rgb radiance(const Vec3& p, const Vec3& n, bool irradiance, const Region* region) const;

private:
    struct Leaf {
        Vec3 center, normal, e1, e2;  // e1, e2: half-axes of the element's parallelogram
        double g11, g12, g22, det;    // Gram matrix of (e1, e2), for in-plane coordinates
        double planeTol;              // how far off its plane a point of its own surface can be
        double reach;                 // |e1| + |e2|: no corner is further from the centre
        Rgb value;                    // (B - E) / pi, less what convolution links give it
        Rgb indirect;                 // value less what the leaf's links bring straight from emitters
        Rgb invRho;                   // 1/rho of its polygon per channel, 0 where rho is 0
        Rgb vis;                      // visible fraction of the emitters' light at the leaf, as linked
        int group = 0;                // ConvolutionField's group of its polygon: blends only within it
        int surface = -1;             // connected surface of its polygon: blends only within it
        Bounds support;
    };
    void init(const Hierarchy& h, const std::vector<Rgb>* textured, const std::vector<Rgb>* shadowed,
              const std::vector<Rgb>* unoccluded, const std::vector<Rgb>* lightE = nullptr);
    // The blend of the leaves of one convolution group and (surface >= 0) one connected surface;
    // with `vis`, also the blend of their visibilities.
    Rgb smooth(const Vec3& p, const Vec3& n, int group, int surface, bool indirectOnly, Rgb* vis = nullptr,
               bool irradiance = false, const Region* region = nullptr) const;
    // The receiving polygon p lies on (normal within 26 degrees of n), or -1.
    int locate(const Vec3& p, const Vec3& n, const Region* region = nullptr) const;
    double weight(const Leaf& l, const Vec3& p, const Vec3& n) const;
    bool acrossFold(const Leaf& l, const Vec3& d, double off, const Vec3& n) const;

    ConvolutionField conv_;
    std::shared_ptr<const DirectLight> direct_;
    std::shared_ptr<const LightSet> lights_;  // null without lamps or world
    const Scene* scene_ = nullptr;
    std::vector<Leaf> leaves_;
    std::vector<int> located_;        // receiving polygons, in polygonBoxes_ order
    std::vector<double> polyTol_;     // per scene polygon: how far off its plane its own points can be
    std::vector<Vec3> centroids_;     // per scene polygon: its geometry's centroid (radiance's nudge)
    BoxTree polygonBoxes_;
    BoxTree supports_;  // over leaves_[i].support
    double diagonal_ = 0;
    double nudge_ = 0;  // how far a bake point is moved off its polygon's edge (radiance)
};

}  // namespace penumbra
