// Error-driven (BF) refinement after Hanrahan, Salzman and Aupperle: a transfer is linked at the
// coarsest level where the radiosity error it can cause on the receiver is below epsilon; otherwise
// the larger of the two elements is split.
#pragma once
#include <atomic>
#include <vector>

#include "hierarchy/element.h"
#include "solve/link.h"
#include "solve/settings.h"
#include "util/progress.h"
#include "visibility/ray_caster.h"

namespace penumbra {

struct RefineStats {
    std::atomic<size_t> rays{0};
    std::atomic<size_t> estimates{0};
    std::atomic<size_t> shaftsClear{0};  // links found fully visible by shaft culling, no rays cast
};

class Refiner {
public:
    Refiner(Hierarchy& h, const RayCaster& rays, const Settings& s);

    // Links every receiving root polygon with every root that can send it light, refined.
    std::vector<Link> linkAll(Progress* progress);
    // Re-judges links with the sources' current radiosities; splits those now too coarse.
    // `changed` tells whether any link was replaced.
    std::vector<Link> rerefine(const std::vector<Link>& links, Progress* progress, bool& changed);

    // Radiosity error a link can cause on its receiver (W/m^2, max over colour channels).
    double linkError(const Link& l) const;
    double threshold() const { return threshold_; }
    const RefineStats& stats() const { return stats_; }

private:
    void refine(int r, int s, std::vector<Link>& out);
    // Unoccluded estimate. False when no light can pass (back-facing or coplanar).
    bool estimateUnoccluded(int r, int s, Link& l);
    void estimateVisibility(int r, int s, Link& l);
    bool canSplit(int e) const;
    void keep(const Link& l, std::vector<Link>& out);  // appends, within settings_.maxLinks

    Hierarchy& h_;
    const RayCaster& rays_;
    Settings settings_;
    double threshold_;
    double minArea_;
    double lift_;  // ray end points are lifted off their surfaces by this much
    int strata_;   // visibility rays = strata_^2
    RefineStats stats_;
    std::atomic<size_t> linkCount_{0};  // links in the list being built
};

}  // namespace penumbra
