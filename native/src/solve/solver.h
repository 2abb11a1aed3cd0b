// Gather and push/pull, iterated to convergence (Jacobi sweeps over the link hierarchy, each new
// iterate mixed with the last few by Anderson's method). The links of
// a receiving cluster are gathered by every polygon below it, each at its own centre and normal,
// before the polygons' push/pull.
#pragma once
#include <algorithm>
#include <cstdint>
#include <vector>

#include "hierarchy/element.h"
#include "solve/convolution_link.h"
#include "solve/link.h"
#include "solve/settings.h"
#include "util/progress.h"

namespace penumbra {

struct SolveResult {
    int iterations = 0;
    double residual = 0;  // estimated remaining relative error of the reflected radiosity
    bool converged = false;
    // Leaves whose links gathered more than a hemisphere (form factors summing over 1), found after a solve
    // that did not converge, and the largest sum; their gathered light was capped and the solve run again.
    int overGathering = 0;
    double maxGathered = 0;
};

class Solver {
public:
    Solver(Hierarchy& h, const Settings& s) : h_(h), settings_(s) {}
    // `links` must be sorted by receiver. Radiosities already in the hierarchy are the start value.
    SolveResult solve(const std::vector<Link>& links, Progress* progress);
    // Convolution links and their complete textures for the current subdivision (both must outlive
    // the solve); leaves gather them after the standard links.
    void setConvolution(const std::vector<ConvolutionLink>* links, const CompleteTextures* textures) {
        convLinks_ = links;
        textures_ = textures;
    }

    // Each face's visible share of the partly seen links into clusters that the refiner kept rather than
    // opened (Refiner::faceVisibility); a face below such a link takes its own share instead of the
    // link's V. Must outlive the solve.
    void setClusterFaceVisibility(const ClusterFaceVisibility* v) { faceVis_ = v; }
    // The weights (form factor times visible share) of the faces of near cluster sources linked into elements
    // face by face (Refiner::sourceFaceVisibility). Must outlive the solve.
    void setSourceFaceVisibility(const ClusterFaceVisibility* v) { srcFaceVis_ = v; }
    // Per element: irradiance from the scene's lamps and world (LightSet::leafIrradiance), reflected by
    // the leaves like gathered light; null or empty without lights. Must outlive the solve.
    void setLightIrradiance(const std::vector<Rgb>* e) { lightE_ = e && !e->empty() ? e : nullptr; }
    // How many past steps each new iterate is mixed with (Anderson's method), at most kMaxMixing; 0
    // gives plain Jacobi sweeps, which the tests hold the mixed solve against.
    static constexpr int kMaxMixing = 5;
    void setMixing(int depth) { mixing_ = std::clamp(depth, 0, kMaxMixing); }
    void setTolerance(double t) { settings_.tolerance = t; }

    // The irradiance each element's links bring straight from the emitters (a gather with every
    // radiosity set to its emission, pushed down to the leaves), as linked (`shadowed`) and with every
    // link's visibility taken as 1 (`unoccluded`), for the final gather: it replaces the first by its
    // exact value at each point and takes the visibility from their ratio. Convolution links are left
    // out: their light is drawn point by point already. The radiosities are left as they were.
    void directIrradiance(const std::vector<Link>& links, std::vector<Rgb>& shadowed, std::vector<Rgb>& unoccluded);

private:
    // The sweeps from the radiosities in the hierarchy until the tolerance or max_iterations.
    SolveResult iterate(const std::vector<Link>& links, Progress* progress);
    // Sums each leaf's form factors (one gather with every radiosity 1) and caps the light of leaves whose sum
    // is over 1 (cap_); returns how many, `most` the largest sum.
    int capGathering(const std::vector<Link>& links, double& most);
    // Every element's irradiance from the links into it, its ancestors and its clusters, at the radiosities as
    // they are: one gather pushed down without a push/pull.
    void gatheredDown(const std::vector<Link>& links, std::vector<Rgb>& out);
    // One gather (irradiance from links) followed by one push/pull; returns the L1 change of B.
    double sweep(const std::vector<Link>& links);
    void gather(const std::vector<Link>& links);
    // Pushes irradiance down, returns the area-weighted radiosity pulled up.
    Rgb pushPull(int e, const Rgb& down, double& change, double& reflected);

    Hierarchy& h_;
    Settings settings_;
    void prepareClusters(const std::vector<Link>& links);
    // Irradiance each polygon takes from the links of the clusters above it, into `down` (one per root,
    // zeroed by the caller: polygons outside the cluster tree are left alone).
    void distributeClusters(const std::vector<Link>& links, std::vector<Rgb>& down) const;
    // The node has no light to give as of the last updateClusterFlux (its light is zero at every point).
    bool dark(int node) const {
        if (isClusterNode(node)) return h_.clusters().dark(clusterIndex(node));
        const Rgb& B = h_[size_t(node)].B;
        return B.x == 0 && B.y == 0 && B.z == 0;
    }

    std::vector<size_t> groupStart_;  // link index where each receiver's run begins; set per solve
    std::vector<std::pair<size_t, size_t>> clusterLinks_;  // link range of each receiving cluster
    double lastReflected_ = 0;
    // Largest ratio of successive changes seen over plain sweeps: Jacobi's contraction, by which the
    // last change predicts the error left. Kept across solves (re-refinement barely changes it).
    double contraction_ = -1;
    int mixing_ = kMaxMixing;
    bool unoccluded_ = false;  // gather with every link's visibility taken as 1
    std::vector<float> cap_;   // per element: the scale of a leaf's gathered light, or empty (capGathering)
    const std::vector<ConvolutionLink>* convLinks_ = nullptr;
    const CompleteTextures* textures_ = nullptr;
    const std::vector<Rgb>* lightE_ = nullptr;
    const ClusterFaceVisibility* faceVis_ = nullptr;
    std::vector<const float*> linkFaceV_;  // per link into a cluster: its faces' shares, or null
    const ClusterFaceVisibility* srcFaceVis_ = nullptr;
    size_t intoClusters_ = 0;  // links into clusters, which sort first
    std::vector<const float*> linkSourceWeights_;  // per link into an element: its source's face weights, or null
    std::vector<int> clusterDepth_;        // steps from the root cluster
};

}  // namespace penumbra
