// The convolution branch of the refiner (Soler & Sillion 1998, §5.2 and Fig. 4): decides whether a
// source/receiver pair is served by one convolution link instead of standard refinement. The tests
// run in order of cost, and any that fails hands the pair back to the standard refiner:
//   1. the transfer is significant (its bound exceeds epsilon: the caller checks);
//   2. the receiver is planar (with cluster_receivers, any cluster whose own faces do not shade one
//      another from the source) and its box at least a_min of the scene's diagonal; the source is a
//      planar group of emitting faces turned toward it (with indirect_sources, of any faces that send
//      light: a reflector's source image is then its own radiosity, beginPass);
//   3. blockers stand in the shaft between the two boxes (Haines-Wallace), and every occluder in the
//      shaft is either such a blocker or lies on or behind the source's or the receiver's plane;
//   4. the convolution's blocker error E_rr, with up to n_max sub-blockers, is at most e_max;
//   5. its predicted FFT time (2 + 2N) C n^2 log n is at most t_max.
// The shadows a convolution cannot see (inside the receiver, §4.1) do not exist on a planar receiver, and a
// cluster receiver whose faces would cast them is refused (shadowsItself); an occluder that reaches into the
// receiver's or the source's box refuses the link rather than leak light through it.
#pragma once
#include <atomic>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include "hierarchy/element.h"
#include "solve/convolution_link.h"
#include "solve/settings.h"
#include "util/counters.h"
#include "visibility/ray_caster.h"

namespace penumbra {

// What a source of reflectors sends (max channel): `at` a point of a face (ConvolutionSites::radiosityAt)
// and the face's `mean` (its root element's, what the gather multiplies by). Empty for emitters, whose
// emission is taken as uniform over each face.
struct SourceRadiosity {
    std::function<double(int polygon, const Vec3& p)> at;
    std::function<double(int polygon)> mean;
    explicit operator bool() const { return bool(at); }
};


class ConvolutionSites {
public:
    // Counts tried pairs and refusals by reason into `counters` (see convolution_site.cpp).
    ConvolutionSites(const Hierarchy& h, const RayCaster& rays, const Settings& s, Counters& counters);
    // Cheap tests (2.): could r receive a convolution link at all, could s send one.
    bool receiverCandidate(int r) const;
    bool sourceCandidate(int s) const;
    // indirect_sources: the radiosities a reflector's source image is drawn from during the coming
    // refinement pass. `settled` elements existed before it (their radiosities are a solve's); `conv` are
    // the links made so far and `reflected` what they gave each leaf (CompleteTextures::reflected), so that
    // the image shows a source's own shadow textures as the display does.
    void beginPass(size_t settled, const std::vector<ConvolutionLink>& conv, std::vector<Rgb> reflected);
    // Tests 2-5 for the pair; on success fills `out`, textures computed.
    bool tryLink(int r, int s, ConvolutionLink& out);
    // The same tests, nothing computed or counted: whether tryLink would succeed.
    bool wouldLink(int r, int s);
    // Whether r could take a link from some emitter group below the cluster s whose transfer is
    // `significant`: the refiner then narrows s down rather than splitting r.
    bool linkPossibleBelow(int r, int s, const std::function<bool(int)>& significant);
    double textureSeconds() const { return seconds_.load(); }  // spent computing textures

    // Why a pair is not served by a convolution link. NotASite is not counted (the pair never reached
    // the blocker selection); the others are, as convolution_refused/<reason>.
    // TooWide: a source of separate lamps too wide for kMaxParts parts of its distance to the receiver;
    // counted as too_coarse, and the refiner looks for links from its lamps instead (linkPossibleBelow).
    // SelfShadow: a cluster receiver (cluster_receivers) whose own faces shade one another from the source.
    enum class Refusal { None, NotASite, NoBlocker, Intruder, Invalid, TooCoarse, TooSlow, TooWide, SelfShadow };

private:
    struct Site;  // a pair's polygons, boxes, blockers and plans, filled in by the steps below
    Refusal evaluate(int r, int s, ConvolutionLink* out);  // judge(), each refused pair once (refused_)
    Refusal judge(int r, int s, Site& site) const;         // tests 2-5
    Refusal selectSource(int r, int s, Site& site) const;  // test 2
    Refusal selectBlockers(Site& site) const;              // test 3
    Refusal planTextures(Site& site) const;                // test 4
    Refusal planBands(Site& site) const;                   // test 4 for a receiver steep to its source
    bool shadowsItself(const Site& site) const;            // test 3 for a receiver that is not flat
    Refusal withinTimeBudget(const Site& site) const;      // test 5
    Refusal computeTextures(Site& site, ConvolutionLink& out);
    bool planarCluster(int c) const { return planar_[size_t(c)]; }
    void nodePolygons(int node, std::vector<int>& out) const;
    bool sourceFace(const ScenePolygon& p) const;  // may light a receiver through a link
    // A sending face's radiosity at p on it (max channel), as the display would draw it: its settled leaf
    // at p, with the detail of the shadow textures it receives.
    double radiosityAt(int polygon, const Vec3& p) const;
    SourceRadiosity sourceRadiosity(bool reflects) const;  // empty for emitters

    const Hierarchy& h_;
    const RayCaster& rays_;
    Settings settings_;
    double tol_;       // boxes this close count as touching (an object resting on the receiver)
    double planeTol_;  // a point this close to a plane lies in it
    std::vector<char> planar_;       // per cluster: all its polygons share one plane
    // A source face emits; with indirect_sources, it sends light at all.
    std::vector<char> hasSource_;    // per cluster: some polygon below is a source face
    std::vector<char> sourceGroup_;  // per cluster: every polygon below that sends light is a source face, on one plane
    size_t settled_ = 0;             // beginPass's
    ConvolutionField field_;
    std::vector<Rgb> reflected_;
    Counters& counters_;
    // Pairs refused before, by their nodes' keys (stable across the passes, which renumber the elements):
    // the tests depend on the geometry and the settings only, and the refiner asks about the same pair again
    // in every pass that refines it and from every cluster above its source (linkPossibleBelow). A pair that
    // passes is not kept: its link is made once. Cleared by beginPass, after which a source that reflects is
    // drawn from new radiosities.
    using PairKey = std::tuple<bool, uint64_t, bool, uint64_t>;
    std::map<PairKey, Refusal> refused_;
    std::mutex refusedMutex_;
    std::atomic<double> seconds_{0};
};

}  // namespace penumbra
