// Error-driven (BF) refinement after Hanrahan, Salzman and Aupperle: a transfer is linked at the
// coarsest level where the radiosity error it can cause on the receiver is below epsilon; otherwise
// the larger of the two nodes is split. With clusters (Smits-Arvo-Greenberg) it starts from one
// root <-> root link; between clusters the error is a bound on the whole transfer (fluxBound), and
// between two elements it is the spread of the exact point-to-polygon form factor.
#pragma once
#include <atomic>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "hierarchy/element.h"
#include "refine/convolution_site.h"
#include "solve/link.h"
#include "solve/settings.h"
#include "util/counters.h"
#include "util/progress.h"
#include "visibility/ray_caster.h"

namespace penumbra {

class Refiner {
public:
    Refiner(Hierarchy& h, const RayCaster& rays, const Settings& s, Counters& counters);

    // Refines from the root cluster link, or without clusters links every receiving polygon with
    // every polygon that can send it light.
    std::vector<Link> linkAll(Progress* progress);
    // Re-judges links with the sources' current radiosities; splits those now too coarse. In place: a
    // replaced link's parts follow the kept links, so the order is not (receiver, source) afterwards.
    // `changed` tells whether any link was replaced. With `reweigh`, a kept element link into a source whose parts
    // differ enough to move its light by a tenth of the threshold takes their present light again (the last pass:
    // what the final solve reads).
    void rerefine(std::vector<Link>& links, Progress* progress, bool& changed, bool reweigh = false);

    // Radiosity error a link can cause on its receiver (W/m^2, max over colour channels).
    double linkError(const Link& l) const;
    double threshold() const { return threshold_; }  // the radiosity error a link may carry
    // The smallest element edge of faces without their own min_edge: min_size times the smaller of the scene's
    // diagonal and kPieceScale median pieces (refiner.cpp).
    double minEdge() const { return minEdge_; }
    // The part of it that comes from a partly hidden source's radiosity varying below it.
    double sourceDeviationError(const Link& l) const;
    // Convolution links made so far, in (receiver, source) order; they stand for whole transfers and
    // are never re-judged, so each pair appears once over all passes.
    std::vector<ConvolutionLink> convolutionLinks() const;
    const ConvolutionSites* convolutionSites() const { return sites_.get(); }
    // indirect_sources: the links and complete textures of the last solve, from which the next rerefine
    // draws a reflecting source's image (its radiosity with its own shadow textures).
    void setSolvedTextures(const std::vector<ConvolutionLink>& conv, const CompleteTextures& textures);

    // The faces' shares of the partly seen links into clusters that were kept rather than opened; the
    // solver reads them (Solver::setClusterFaceVisibility).
    const ClusterFaceVisibility& faceVisibility() const { return faceVis_; }
    // The near cluster sources linked into elements face by face: each face's form factor times its visible
    // share, keyed by (receiving element, source cluster); the solver reads them (setSourceFaceVisibility).
    const ClusterFaceVisibility& sourceFaceVisibility() const { return srcFaceVis_; }

private:
    // Records each face's visible share of `s` for the cluster receiver `r`; false when the cluster is too
    // large for that and must be opened. nearSource: s is a cluster within its far field of r, its points
    // drawn toward each face rather than once toward r's centre.
    bool shareByFaces(int r, int s, bool nearSource = false);
    ClusterFaceVisibility faceVis_;
    // A near cluster source s into element r as one link whose light is summed face by face, each face weighted
    // by its own form factor and visible share (recorded in srcFaceVis_); l.V = 0 when no ray gets through.
    // False when faces turned toward r got no ray to cast (the pair is then opened).
    bool shareSourceByFaces(int r, int s, Link& l);
    // A cluster small enough for shareSourceByFaces, without emitters.
    bool sharesFaces(int s) const;
    ClusterFaceVisibility srcFaceVis_;
    std::vector<Link> linkFacePairs(Progress* progress);
    std::vector<Link> linkFromRoot(Progress* progress);
    void refine(int r, int s, std::vector<Link>& out);
    void refineElements(int r, int s, std::vector<Link>& out);
    // A pair with a cluster at one end: links it, drops it, or (with `defer`) hands back the pairs
    // it splits into instead of refining them.
    void refineCluster(int r, int s, std::vector<Link>& out, std::vector<std::pair<int, int>>* defer);
    // Visibility of a cluster link from rays between faces of both ends (V may be 0); false when no
    // face of one end is turned toward the other.
    bool estimateCluster(int r, int s, Link& l);
    // Whether some face of a cluster (any element counts) has part of the box `other` in front of it.
    bool facesToward(int node, const Bounds& other, bool receiver) const;
    // Points on the faces of a node that look toward `toward`, spread by projected area; false when
    // none does.
    // faces (optional): the polygon each point was drawn from.
    bool sampleNode(int node, const Vec3& toward, bool receiver, uint64_t seed, int n, Vec3* pts,
                    int* faces = nullptr) const;
    // Whether a blocked ray from sourcePoint, a point of reflecting face `face`, toward receiverPoint began
    // inside a closed surface (see estimateVisibility): such a ray does not count.
    bool fromInsideSolid(int face, const Vec3& sourcePoint, const Vec3& receiverPoint) const;
    struct NodeSampler;
    // A cluster's faces as sampleNode draws them toward `toward`; false when none faces it.
    bool buildSampler(int cluster, const Vec3& toward, bool receiver, NodeSampler& out) const;
    // faces (optional): the polygon each point was drawn from.
    void drawFromSampler(const NodeSampler& s, uint64_t seed, int n, Vec3* pts, int* faces = nullptr) const;
    // The weight of a ray from x to y, a point of face yFace drawn by `s` toward `toward`, in a face's visible
    // share: the point-to-point kernel over the density the point was drawn with, so the share is that of
    // the light (pointKernel alone for points drawn by area).
    double drawnWeight(const Vec3& x, const Vec3& nx, const Vec3& y, int yFace, const NodeSampler& s,
                       const Vec3& toward) const;
    std::vector<int> children(int node, bool receiver);
    bool receives(int node) const;
    bool sends(int node) const;
    double receiverRho(int node) const;
    // Unoccluded estimate. False when no light can pass (back-facing or coplanar).
    bool estimateUnoccluded(int r, int s, Link& l);
    // The factor by which the source's parts' light shares out its form factor at the receiver's points `pts`
    // (1 where the parts do not differ): estimateUnoccluded's weighting, with the parts' present radiosities.
    double partsWeight(int r, int s, const Vec3* pts, int np) const;
    // estimateUnoccluded's mean alone, weighted by the parts' present light (rerefine's reweigh).
    double weightedMean(int r, int s) const;
    // batches > 0: that many rounds of 256 rays instead of the visibility_rays setting's, and V the
    // visible share of the form factor (each ray weighted by its ends' cos cos / r^2). transfer > 0:
    // the link's unshadowed light; the first round is then 64 rays and the estimate stops as soon as
    // transfer times its standard error is within the threshold.
    void estimateVisibility(int r, int s, Link& l, int batches = 0, double transfer = 0);
    bool canSplit(int e) const;
    // contact_floor: lowers minArea_ of faces near smaller faces of other objects (settings.h).
    void lowerFloorsAtContacts(double k);
    // A point of element e's leaves, chosen by their share of its light B * area (u in [0, 1)).
    Vec3 pointByLight(int e, double u, double s, double t) const;
    // e has children that existed, with radiosities, before this refinement pass.
    bool hasSettledChildren(int e) const;
    // e's parts differ in light by more than the solve's noise between passes (kDeviates of its radiosity).
    bool partsDiffer(int e) const;
    // The error of taking a source's radiosity as uniform when its parts differ (Bdev), however
    // visible: about rho * Bdev * F * min(1, size / distance).
    double gradientError(const Link& l) const;
    void keep(const Link& l, std::vector<Link>& out);  // appends, within settings_.maxLinks
    bool countLink(const Link& l);                     // false for a link not worth keeping; throws past maxLinks
    bool emits(int node) const;                        // some face of the node emits
    // Fig. 4: a significant transfer onto a large planar receiver through blockers becomes one
    // convolution link; true when it did.
    bool tryConvolution(int r, int s);

    Hierarchy& h_;
    const RayCaster& rays_;
    Settings settings_;
    double threshold_;
    double minEdge_ = 0;
    std::vector<double> minArea_;  // per scene polygon: no element of it is split at or below this area
    double lift_;  // ray end points are lifted off their surfaces by this much
    std::vector<char> touched_;    // per scene polygon: RayCaster::touchedFaces
    std::vector<char> footprint_;  // per scene polygon: RayCaster::footprintFaces, emitters left out
    int strata_;   // visibility rays = strata_^2
    bool firstPass_ = false;
    Counters& counters_;
    std::atomic<size_t> linkCount_{0};  // links in the list being built
    size_t settled_ = 0;                 // elements at the start of this pass (0 in the first)
    // Per settled element, what pointByLight descends by, packed so that a descent reads one small
    // record per level instead of four whole elements (it was 12 % of a furnished room's refinement).
    struct LightNode {
        double weight;    // maxComponent(B) * area
        int firstChild;   // -1 unless its children are settled
        int numChildren;
    };
    std::vector<LightNode> lightNodes_;
    std::vector<char> clusterEmits_;  // per cluster: some face below emits
    // What each face of the cluster tree (in its order) may be drawn as by buildSampler, which reads the rest of the
    // face from Hierarchy::faceLight: contiguous, where each face's element and polygon cost two scattered cache
    // lines (buildSampler and the predicates it called were 8 % of the 50k office's CPU).
    struct FaceRole {
        bool sends;     // sendsLight
        bool receives;  // receivesLight, and not buried
    };
    std::vector<FaceRole> faceRoles_;
    std::unique_ptr<ConvolutionSites> sites_;  // null with convolution off
    mutable std::mutex convMutex_;
    std::vector<ConvolutionLink> conv_;
};

}  // namespace penumbra
