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
    // Every counter of the solve by name, each declared with PENUMBRA_COUNTER where it is counted
    // (util/counters.h; a name "group/key" nests in the Python dict): polygons, elements, leaves, links,
    // rays, shafts_clear, clusters, cluster_links, convolution_links, convolution_tried,
    // convolution_refused/<reason>, convolution_texels, gather_emitters, iterations, refine_passes.
    std::map<std::string, size_t> counts;
    size_t count(const std::string& name) const { return counts.at(name); }  // throws for an unknown name
    double convolutionMaxError = 0;  // the largest blocker error E_rr (texels) among the convolution links
    double minEdge = 0;  // the smallest element edge of faces without their own min_edge (Refiner::minEdge)
    // Estimated relative RMS error of the reflected radiance (solve/error_estimate.h), overall and per
    // object (by object index, -1 where an object receives nothing).
    double errorEstimate = 0;
    std::vector<double> objectErrorEstimate;
    double residual = 0;
    bool converged = false;
    std::vector<std::string> warnings;
};

class Solution {
public:
    const Report& report() const { return report_; }
    // Outgoing reflected radiance (B - B_e)/pi at world-space points, n x 3 each; with `irradiance`, the
    // arriving light E/pi without the albedo (RadianceField::radiance).
    std::vector<float> radiance(const float* points, const float* normals, size_t n, bool irradiance = false) const;
    // Throws BudgetExceeded for images over Settings::maxTexels.
    std::vector<float> bakeLightmap(const LightmapInput& in) const;
    // Several lightmaps at once over all the threads (bake/lightmap.h bakeLightmaps), into `out`; each is
    // the same as bakeLightmap's. Throws BudgetExceeded as bakeLightmap does, for any one of them.
    void bakeLightmaps(const LightmapInput* ins, size_t count, float* out) const;
    // Throws the BudgetExceeded that bakeLightmap would for `in`.
    void checkTexelBudget(const LightmapInput& in) const;
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
    int texelSamples_ = 1;  // Settings::texelSamples: points per side of a lightmap texel's footprint
};

// Throws (util/error.h) InputError for bad input (message names the object), BudgetExceeded (an InputError) when
// the scene would exceed a budget in Settings, Cancelled when progress says stop.
std::unique_ptr<Solution> solve(const SceneInput& in, const Settings& settings, Progress* progress);

}  // namespace penumbra
