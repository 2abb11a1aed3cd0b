// The one entry to the native solver: a validated scene and settings in, a Solution out.
//   scene (arrays) -> Hierarchy -> Refiner -> links -> Solver -> RadianceField -> bake
#pragma once
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "bake/lightmap.h"
#include "bake/radiance_field.h"
#include "hierarchy/element.h"
#include "scene/scene.h"
#include "solve/link.h"
#include "solve/settings.h"
#include "util/progress.h"
#include "visibility/ray_caster.h"

namespace penumbra {

struct Report {
    std::map<std::string, double> seconds;  // per stage
    size_t polygons = 0, elements = 0, leaves = 0, links = 0, rays = 0, shaftsClear = 0;
    size_t clusters = 0, clusterLinks = 0;  // cluster nodes; links with a cluster at either end
    // Convolution links made; pairs that reached blocker selection; why the others were refused;
    // texels of all their textures; the largest blocker error E_rr (texels) among them.
    size_t convolutionLinks = 0, convolutionTried = 0, convolutionTexels = 0;
    std::map<std::string, size_t> convolutionRefused;
    double convolutionMaxError = 0;
    // Estimated relative RMS error of the reflected radiance (solve/error_estimate.h), overall and per
    // object (by object index, -1 where an object receives nothing).
    double errorEstimate = 0;
    std::vector<double> objectErrorEstimate;
    size_t gatherEmitters = 0;  // emitting faces the final gather evaluates at every bake point
    int iterations = 0, refinePasses = 0;
    double residual = 0;
    bool converged = false;
    std::vector<std::string> warnings;
};

class Solution {
public:
    const Report& report() const { return report_; }
    // Outgoing reflected radiance (B - B_e)/pi at world-space points, n x 3 each.
    std::vector<float> radiance(const float* points, const float* normals, size_t n) const;
    // Throws BudgetExceeded for images over Settings::maxTexels.
    std::vector<float> bakeLightmap(const LightmapInput& in) const;
    const Scene& scene() const { return *scene_; }
    const Hierarchy& hierarchy() const { return *hierarchy_; }
    const std::vector<Link>& links() const { return links_; }
    const std::vector<ConvolutionLink>& convolutionLinks() const { return convLinks_; }

private:
    friend std::unique_ptr<Solution> solve(const SceneInput&, const Settings&, Progress*);
    std::unique_ptr<Scene> scene_;
    std::unique_ptr<Hierarchy> hierarchy_;
    std::shared_ptr<RayCaster> rays_;  // kept for the final gather at bake time
    std::vector<Link> links_;
    std::vector<ConvolutionLink> convLinks_;
    RadianceField field_;
    Report report_;
    int threads_ = 1;
    size_t maxTexels_ = 0;
};

// Throws InputError for bad input (message names the object), BudgetExceeded (an InputError) when
// the scene would exceed a budget in Settings, Cancelled when progress says stop.
std::unique_ptr<Solution> solve(const SceneInput& in, const Settings& settings, Progress* progress);

}  // namespace penumbra
