// Convolution links (Soler & Sillion 1998, §3-4): the whole transfer from a planar group of emitting
// faces S to a planar receiver R, with the shadows of the blockers between them held in one
// SoftShadowTexture per part of the source. At a receiver point y the link delivers
//     I(y) = sum over source parts j of V_j(y) * sum over the pieces of faces f in part j of B_f * w * F(y <- piece)
// (w the piece's share of its face's radiosity, 1 for emitters)
// with F Lambert's exact unoccluded point-to-polygon form factor and V_j looked up by central projection
// from the part's centre. V weights the source by area (its emission), not by the form factor's kernel, so
// a source is cut into k x k parts small against its distance to the receiver: the error of that
// approximation falls as 1/k^2 (parallel planes: worst 4.1 % of the peak with one part, 1.1 % with 2 x 2).
// Nothing is meshed for it: the receiver keeps the elements its other links need, and the shadow's detail
// lives in the textures.
//
// Gather and push/pull (§4.1-4.2): a CompleteTexture at every leaf below the receiver holds the leaf's
// mean of F * V per source face, so the leaf gathers sum B_f * mean and the energy balance (what the
// leaf reflects onward, what is pulled up) sees the shadow. The display (§4.3) draws the leaf's
// radiosity less that mean, plus rho * I(y) / pi evaluated at every point: ConvolutionField.
#pragma once
#include <memory>
#include <utility>
#include <vector>

#include "convolution/soft_shadow.h"
#include "geometry/box_tree.h"
#include "hierarchy/element.h"

namespace penumbra {

struct SourcePiece {
    Polygon geom;  // a source face clipped to one part
    int face = 0;  // index into ConvolutionLink::sourcePolygons
    int part = 0;  // index into ConvolutionLink::textures
    // The piece's mean radiosity over its face's (root element's), measured when the link was made: a
    // reflecting source (indirect_sources) is brighter in some parts than others; 1 for an emitter.
    double weight = 1;
};

struct ConvolutionLink {
    int receiver = -1;                 // node: a polygon's root element or a planar cluster
    int source = -1;                   // node: a polygon's root element or a cluster of coplanar emitters
    std::vector<int> receiverPolygons; // faces lit through the link, ascending
    std::vector<int> sourcePolygons;   // emitting faces turned toward the receiver, ascending
    std::vector<std::shared_ptr<const SoftShadowTexture>> textures;  // one per part of the source (per band)
    std::vector<SourcePiece> pieces;
    // A receiver steep to its source (wall_links) is cut into bands of depth along the source's normal:
    // band b holds depths [bandDepths[b], bandDepths[b + 1]) and textures[b * parts + part]; a null texture is
    // full light. Points shallower than bandDepths[0] lie above every blocker and see all of the source.
    // Empty bandDepths: one texture per part for the whole receiver.
    std::vector<double> bandDepths;
    Vec3 bandOrigin, bandAxis;  // depth = dot(y - bandOrigin, bandAxis)
    // Per band, the range of dot(y - bandOrigin, bandAcross) a shadow can reach; outside it, full light.
    Vec3 bandAcross;
    std::vector<std::pair<double, double>> bandSpans;
    int blockerTriangles = 0;
    double error = 0;                  // E_rr, in texels of half the narrowest penumbra (what e_max bounds)
};

// Unoccluded irradiance per unit radiosity from each source piece at y (normal n), times its part's V(y).
// `out` has one entry per piece.
void convolutionFactors(const Scene& sc, const ConvolutionLink& l, const Vec3& y, const Vec3& n, double* out);

// The leaves' share of every convolution link, for the current subdivision.
class CompleteTextures {
public:
    CompleteTextures() = default;
    CompleteTextures(const Hierarchy& h, const std::vector<ConvolutionLink>& links, int threads);
    bool empty() const { return entries_.empty(); }
    // Adds each leaf's irradiance from the links, with the sources' current radiosities.
    void gather(Hierarchy& h, const std::vector<ConvolutionLink>& links, int threads) const;
    // rho * (what the links give each element) with current radiosities; zero off the links.
    std::vector<Rgb> reflected(const Hierarchy& h, const std::vector<ConvolutionLink>& links) const;

private:
    struct Entry {
        int leaf, link;
        size_t factors;  // index of the first of the link's source pieces' mean factors
    };
    std::vector<Entry> entries_;       // sorted by leaf
    std::vector<size_t> leafStart_;    // runs of entries_ with one leaf
    std::vector<double> factors_;
};

// rho * I(y) / pi at any point of a receiver: the texture's detail, added to the smooth field. Faces
// lit by the same set of links form a group; the smooth field blends leaves of one group only, since a
// face whose direct light comes from a texture holds none of it in its leaves.
class ConvolutionField {
public:
    ConvolutionField() = default;
    ConvolutionField(const Hierarchy& h, const std::vector<ConvolutionLink>& links);
    bool empty() const { return links_.empty(); }
    int polygonGroup(int polygon) const { return polyGroup_.empty() ? 0 : polyGroup_[size_t(polygon)]; }
    // The links' radiance at p (on the lowest-numbered receiver face holding it, so a point on an edge
    // counts once), and that face's group in `group` (0 off every receiver). With `irradiance`, I(y)/pi
    // without the receiver's rho.
    Rgb radiance(const Vec3& p, const Vec3& n, int* group, bool irradiance = false) const;

private:
    const Scene* scene_ = nullptr;
    std::vector<ConvolutionLink> links_;
    std::vector<std::vector<Rgb>> sourceB_;  // per link, per source piece
    std::vector<int> polyGroup_;             // per scene polygon: 0, or 1 + index into groups_
    std::vector<std::vector<int>> groups_;   // links of each group, ascending
    std::vector<int> covered_;               // receiver faces, one entry each
    BoxTree boxes_;                          // over covered_, padded by tol_
    double tol_ = 0;
};

}  // namespace penumbra
