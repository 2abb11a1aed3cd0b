// ConvolutionSites on a floor under a lamp: a card floating between them makes a convolution site; a
// card resting on the floor takes contact sub-blockers; a post through it, or nothing in the shaft are refused, each counted under
// its reason; wouldLink() answers the same without counting or computing anything. A trough of two slopes is one
// receiver with cluster_receivers, gentle or steep, and refused (self_shadow) with a seat over one slope.
#include "refine/convolution_site.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "convolution/cost_model.h"
#include "convolution/soft_shadow.h"
#include "geometry/form_factor.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

using testing::TestScene;

enum class Card { None, Floating, Resting, Post };

// Polygon 0: a 2 x 2 floor at z = 0. Polygon 1: a 0.5 x 0.5 lamp at z = 1 facing down, light-only.
// Polygons 2...: the card.
TestScene floorUnderLamp(Card card, uint8_t cardFlag = 0) {
    TestScene t;
    t.names = {"Floor", "Lamp", "Card"};
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    double s = 0.25;
    t.quad({-s, -s, 1}, {-s, s, 1}, {s, s, 1}, {s, -s, 1}, {}, {10, 10, 10}, kLightOnly, 1);
    Rgb grey{0.5, 0.5, 0.5};
    switch (card) {
    case Card::None: break;
    case Card::Floating:  // 0.4 x 0.4, halfway up, touching nothing
        t.quad({-0.2, -0.2, 0.5}, {0.2, -0.2, 0.5}, {0.2, 0.2, 0.5}, {-0.2, 0.2, 0.5}, grey, {}, cardFlag, 2);
        break;
    case Card::Resting:  // a box standing on the floor: its contact shadow has no width
        t.box({-0.2, -0.2, 0}, {0.2, 0.2, 0.4}, grey, {}, false, 2);
        break;
    case Card::Post:  // a box through the floor, into the receiver's box
        t.box({-0.1, -0.1, -0.3}, {0.1, 0.1, 0.4}, grey, {}, false, 2);
        break;
    }
    return t;
}

Settings unclustered(Settings s) {
    s.clustering = false;
    return s;
}

struct Sites : testing::SolverParts {
    std::unique_ptr<ConvolutionSites> sites;
    explicit Sites(const TestScene& t, const Settings& s = {}) : SolverParts(t, unclustered(s)) {
        setFftCostConstant(1e-9);  // t_max must not depend on this machine's FFTW
        sites = std::make_unique<ConvolutionSites>(*h, *rays, unclustered(s), counters);
    }
    size_t count(const char* name) const { return counters.values().at(name); }
    size_t refused() const {
        size_t n = 0;
        for (const auto& [k, v] : counters.values())
            if (k.rfind("convolution_refused/", 0) == 0) n += v;
        return n;
    }
};

TEST(ConvolutionSites, TheFloorAndTheLampAreCandidates) {
    Sites s(floorUnderLamp(Card::Floating));
    EXPECT_TRUE(s.sites->receiverCandidate(0));
    EXPECT_FALSE(s.sites->receiverCandidate(1));  // light-only: receives nothing
    EXPECT_TRUE(s.sites->sourceCandidate(1));
    EXPECT_FALSE(s.sites->sourceCandidate(0));
    EXPECT_TRUE(s.sites->receiverCandidate(2));  // the card's box: 0.57, a_min of the diagonal: 0.15 x 3
    Settings big;
    big.aMin = 0.25;
    Sites t(floorUnderLamp(Card::Floating), big);
    EXPECT_FALSE(t.sites->receiverCandidate(2));  // now under a_min x diagonal = 0.75
    EXPECT_TRUE(t.sites->receiverCandidate(0));
}

TEST(ConvolutionSites, AReflectorIsASourceOnlyWithIndirectSources) {
    Sites off(floorUnderLamp(Card::Floating));
    EXPECT_FALSE(off.sites->sourceCandidate(2));  // the grey card reflects but does not emit
    Settings s;
    s.indirectSources = true;
    Sites on(floorUnderLamp(Card::Floating), s);
    EXPECT_TRUE(on.sites->sourceCandidate(2));
    EXPECT_TRUE(on.sites->sourceCandidate(1));
    EXPECT_TRUE(on.sites->sourceCandidate(0));  // the floor too: it sends what it reflects
    Sites hidden(floorUnderLamp(Card::Floating, kNoDiffuse), s);
    EXPECT_FALSE(hidden.sites->sourceCandidate(2));  // Diffuse off: its bounce reaches no one
}

TEST(ConvolutionSites, AFloatingCardMakesAConvolutionLink) {
    Sites s(floorUnderLamp(Card::Floating));
    EXPECT_TRUE(s.sites->wouldLink(0, 1));
    EXPECT_EQ(s.count("convolution_tried"), 0u);  // wouldLink counts nothing
    ConvolutionLink l;
    ASSERT_TRUE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(l.receiver, 0);
    EXPECT_EQ(l.source, 1);
    EXPECT_EQ(l.receiverPolygons, std::vector<int>{0});
    EXPECT_EQ(l.sourcePolygons, std::vector<int>{1});
    EXPECT_EQ(l.blockerTriangles, 2);
    ASSERT_FALSE(l.textures.empty());
    EXPECT_LE(l.error, Settings{}.eMax);
    EXPECT_EQ(s.count("convolution_tried"), 1u);
    EXPECT_EQ(s.refused(), 0u);
    EXPECT_GT(s.sites->textureSeconds(), 0.0);
}

TEST(ConvolutionSites, NothingInTheShaftIsRefusedAsNoBlocker) {
    Sites s(floorUnderLamp(Card::None));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_tried"), 1u);
    EXPECT_EQ(s.count("convolution_refused/no_blocker"), 1u);
    EXPECT_EQ(s.refused(), 1u);
}

// The same card hidden from shadow rays (kNoLampShadow): the lamp's light passes it, so it is no blocker,
// and with nothing else in the shaft the pair is refused (the final gather's rays then let the light by).
TEST(ConvolutionSites, ACardHiddenFromShadowRaysIsNoBlocker) {
    Sites s(floorUnderLamp(Card::Floating, kNoLampShadow));
    EXPECT_FALSE(s.sites->wouldLink(0, 1));  // answers as tryLink does
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/no_blocker"), 1u);
}

TEST(ConvolutionSites, ABoxRestingOnTheFloorTakesContactSubBlockers) {
    // Touching the floor is allowed (the boxes are shrunk by a tolerance). The shadow at the contact is
    // sharp, so one convolution cannot reach e_max; the contact sub-blockers (issue 12) do.
    // Seven sub-blockers at 512 texels: 51 ms at the pinned FFT cost (5 times this machine's), over the default
    // t_max of 50 ms.
    Settings slow;
    slow.tMax = 1.0;
    slow.contactSlabs = true;  // off by default (settings.h)
    Sites s(floorUnderLamp(Card::Resting), slow);
    ConvolutionLink l;
    EXPECT_TRUE(s.sites->wouldLink(0, 1));
    ASSERT_TRUE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.refused(), 0u);
    EXPECT_LE(l.error, Settings{}.eMax);
    ASSERT_FALSE(l.textures.empty());
    for (const auto& t : l.textures) EXPECT_GE(t->subBlockers, 2);
    // The floor under the box's middle is covered: no light reaches it.
    EXPECT_EQ(lookupVisibility(*l.textures[0], {0.05, -0.05, 0}), 0.0f);
}

TEST(ConvolutionSites, WithoutContactSubBlockersARestingBoxIsRefusedAsTooCoarse) {
    // The same box planned as one blocker: E_rr in units of a penumbra that vanishes at the contact.
    Settings s;
    // The box of Card::Resting without its bottom (in the floor's plane, dropped by the blocker selection).
    const double a = 0.2, h = 0.4;
    const Vec3 c[8] = {{-a, -a, 0}, {a, -a, 0}, {a, a, 0}, {-a, a, 0}, {-a, -a, h}, {a, -a, h}, {a, a, h}, {-a, a, h}};
    const int quads[5][4] = {{4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    std::vector<BlockerTriangle> tris;
    for (const auto& q : quads) {
        tris.push_back({c[q[0]], c[q[1]], c[q[2]]});
        tris.push_back({c[q[0]], c[q[2]], c[q[3]]});
    }
    SourceDesc src;
    src.polygon = {{-0.25, -0.25, 1}, {-0.25, 0.25, 1}, {0.25, 0.25, 1}, {0.25, -0.25, 1}};
    ReceiverDesc rec{{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}};
    ConvolutionSettings cs;
    cs.e_max = s.eMax;
    cs.contactSlabs = false;
    EXPECT_GT(planSoftShadow(src, tris, rec, cs).E_rr, 10 * s.eMax);
    cs.contactSlabs = true;
    EXPECT_LE(planSoftShadow(src, tris, rec, cs).E_rr, s.eMax);
}

TEST(ConvolutionSites, APostThroughTheFloorIsRefusedAsAnIntruder) {
    Sites s(floorUnderLamp(Card::Post));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/intruder"), 1u);
    EXPECT_EQ(s.refused(), 1u);
}

// A refused pair is judged once (ConvolutionSites::refused_): asked again, by the same or a later pass, it answers
// and is counted as the first time, and a pair that passes makes its link every time it is asked.
TEST(ConvolutionSites, APairAskedAgainAnswersAndCountsAsTheFirstTime) {
    Sites post(floorUnderLamp(Card::Post));
    ConvolutionLink l;
    EXPECT_FALSE(post.sites->wouldLink(0, 1));
    for (int k = 0; k < 2; ++k) EXPECT_FALSE(post.sites->tryLink(0, 1, l));
    EXPECT_FALSE(post.sites->wouldLink(0, 1));
    EXPECT_EQ(post.count("convolution_tried"), 2u);
    EXPECT_EQ(post.count("convolution_refused/intruder"), 2u);
    EXPECT_EQ(post.refused(), 2u);
    // Not a site (a receiver as its own source): never counted, however often asked.
    for (int k = 0; k < 2; ++k) EXPECT_FALSE(post.sites->tryLink(0, 0, l));
    EXPECT_EQ(post.count("convolution_tried"), 2u);

    Sites card(floorUnderLamp(Card::Floating));
    for (int k = 0; k < 2; ++k) {
        ConvolutionLink made;
        ASSERT_TRUE(card.sites->tryLink(0, 1, made));
        EXPECT_FALSE(made.textures.empty());
    }
    EXPECT_EQ(card.count("convolution_tried"), 2u);
    EXPECT_EQ(card.refused(), 0u);
}

TEST(ConvolutionSites, ATimeBudgetTooSmallIsRefusedAsTooSlow) {
    Settings tight;
    tight.tMax = 1e-12;
    Sites s(floorUnderLamp(Card::Floating), tight);
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/too_slow"), 1u);
    EXPECT_EQ(s.refused(), 1u);
}

// The floor of floorUnderLamp under a 0.4 m card at z = 0.5 and two 0.25 m lamps `gap` apart at height z, one
// object, so that the cluster tree keeps them in one cluster.
TestScene floorUnderTwoLamps(double gap, double z) {
    TestScene t;
    t.names = {"Floor", "Lamps", "Card"};
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    double s = 0.125, c = (0.25 + gap) / 2;
    for (int k = 0; k < 2; ++k) {
        double x = k ? c : -c;
        t.quad({x - s, -s, z}, {x - s, s, z}, {x + s, s, z}, {x + s, -s, z}, {}, {10, 10, 10}, kLightOnly, 1);
    }
    t.quad({-0.2, -0.2, 0.5}, {0.2, -0.2, 0.5}, {0.2, 0.2, 0.5}, {-0.2, 0.2, 0.5}, {0.5, 0.5, 0.5}, {}, 0, 2);
    return t;
}

// The node of the cluster holding exactly `polys` (sorted), or -1 if there is none.
int clusterWith(const Hierarchy& h, const std::vector<int>& polys) {
    const ClusterTree& ct = h.clusters();
    for (size_t c = 0; c < ct.size(); ++c) {
        std::vector<int> p(ct.polygons().begin() + ct[int(c)].begin, ct.polygons().begin() + ct[int(c)].end);
        std::sort(p.begin(), p.end());
        if (p == polys) return clusterNode(int(c));
    }
    return -1;
}

struct ClusteredSites : testing::SolverParts {
    std::unique_ptr<ConvolutionSites> sites;
    int pair = -1;  // the cluster node holding exactly polygons 1 and 2 (the two lamps of twoLamps)
    explicit ClusteredSites(const TestScene& t, const Settings& s = Settings{}) : SolverParts(t, s) {
        setFftCostConstant(1e-9);
        sites = std::make_unique<ConvolutionSites>(*h, *rays, s, counters);
        pair = clusterWith(*h, {1, 2});
    }
    size_t count(const char* name) const { return counters.values().at(name); }
};

TEST(ConvolutionSites, SeparateLampsTooWideForTheirPartsAreLinkedOneByOne) {
    // 1 m up, lamps 0.5 m apart: their 0.75 m rectangle would need 6 parts a side of 1/8 of the distance, and
    // the lamps fill a third of it. The pair is refused (as too coarse), each lamp is a site, and
    // linkPossibleBelow finds them below the pair.
    ClusteredSites s(floorUnderTwoLamps(0.5, 1.0));
    ASSERT_TRUE(isClusterNode(s.pair));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, s.pair, l));
    EXPECT_EQ(s.counters.values().at("convolution_refused/too_coarse"), 1u);
    EXPECT_TRUE(s.sites->wouldLink(0, 1));
    EXPECT_TRUE(s.sites->wouldLink(0, 2));
    EXPECT_TRUE(s.sites->linkPossibleBelow(0, s.pair, [](int) { return true; }));
    // 4 m up the same rectangle needs 2 parts a side: one source holding both lamps.
    ClusteredSites high(floorUnderTwoLamps(0.5, 4.0));
    ASSERT_TRUE(isClusterNode(high.pair));
    ASSERT_TRUE(high.sites->tryLink(0, high.pair, l));
    EXPECT_EQ(l.sourcePolygons, (std::vector<int>{1, 2}));
    EXPECT_EQ(l.textures.size(), 4u);
}

TEST(ConvolutionSites, AReceiverIsNeverItsOwnSource) {
    Sites s(floorUnderLamp(Card::Floating));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 0, l));
    EXPECT_FALSE(s.sites->tryLink(1, 1, l));
    EXPECT_EQ(s.count("convolution_tried"), 0u);  // refused before the blocker selection
}

// wall_links: polygon 0 a 4 x 2.8 m wall at x = -1 facing +x, reaching above the lamp (polygon 1, 0.5 m, 2.5 m up,
// 1.6 m from the wall, facing down); the furniture in front of it is black.
enum class Furniture { Shelf, ShelfOnTheWall, Cupboard };

TestScene wallUnderLamp(Furniture f) {
    TestScene t;
    t.names = {"Wall", "Lamp", "Furniture"};
    t.quad({-1, -2, 0}, {-1, 2, 0}, {-1, 2, 2.8}, {-1, -2, 2.8}, {0.7, 0.7, 0.7}, {}, 0, 0);
    double s = 0.25;
    t.quad({0.6 - s, -s, 2.5}, {0.6 - s, s, 2.5}, {0.6 + s, s, 2.5}, {0.6 + s, -s, 2.5}, {}, {10, 10, 10}, kLightOnly, 1);
    switch (f) {
    case Furniture::Shelf: t.box({-0.75, -0.6, 0.74}, {-0.15, 0.6, 0.75}, {}, {}, false, 2); break;
    case Furniture::ShelfOnTheWall: t.box({-1.0, -0.6, 0.74}, {-0.6, 0.6, 0.75}, {}, {}, false, 2); break;
    case Furniture::Cupboard: t.box({-0.7, -0.3, 0}, {-0.4, 0.3, 1.2}, {}, {}, false, 2); break;
    }
    return t;
}

Settings wallLinks(bool on) {
    Settings s;
    s.tMax = 1e6;  // what is tested is the site, not the FFT budget
    s.wallLinks = on;
    return s;
}

TEST(ConvolutionSites, AWallReachingAboveTheLampIsNotASiteWithoutWallLinks) {
    Sites s(wallUnderLamp(Furniture::Shelf), wallLinks(false));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_tried"), 0u);  // the lamp's plane cuts the wall's box
}

TEST(ConvolutionSites, AWallUnderAShelfTakesABandedLink) {
    Sites s(wallUnderLamp(Furniture::Shelf), wallLinks(true));
    ConvolutionLink l;
    ASSERT_TRUE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.refused(), 0u);
    EXPECT_LE(l.error, Settings{}.eMax);
    ASSERT_GE(l.bandDepths.size(), 3u);
    const size_t bands = l.bandDepths.size() - 1;
    ASSERT_EQ(l.textures.size() % bands, 0u);
    // Depth runs down from the lamp's plane; the bands start at the shelf's top, 0.75 m up, and end at the floor.
    EXPECT_NEAR(l.bandDepths.front(), 2.5 - 0.75, 1e-9);
    EXPECT_NEAR(l.bandDepths.back(), 2.5, 1e-9);
    const Scene& sc = s.h->scene();
    const Vec3 n{1, 0, 0};
    std::vector<double> f(l.pieces.size());
    auto delivered = [&](const Vec3& y) {  // y in the caller's coordinates; the scene is recentred
        convolutionFactors(sc, l, y - sc.offset, n, f.data());
        double sum = 0;
        for (double x : f) sum += x;
        return sum;
    };
    auto unoccluded = [&](const Vec3& y) {
        double sum = 0;
        for (const SourcePiece& p : l.pieces) sum += pointToPolygonFormFactor(y - sc.offset, n, p.geom);
        return sum;
    };
    // Above the lamp's plane: nothing; above the shelf: the whole lamp; below it a shadow.
    EXPECT_EQ(delivered({-1, 0, 2.7}), 0.0);
    const Vec3 high{-1, 0.3, 1.5};
    EXPECT_GT(unoccluded(high), 0);
    EXPECT_DOUBLE_EQ(delivered(high), unoccluded(high));
    // At the shadow's height but along the wall beyond its hull (the shelf ends at y = 0.6): full light.
    const Vec3 aside{-1, 1.95, 0.3};
    EXPECT_DOUBLE_EQ(delivered(aside), unoccluded(aside));
    double darkest = 1;
    for (double z = 0.05; z < 0.74; z += 0.05) darkest = std::min(darkest, delivered({-1, 0, z}) / unoccluded({-1, 0, z}));
    EXPECT_LT(darkest, 0.5);
}

TEST(ConvolutionSites, AShelfOnTheWallIsRefusedAsInvalid) {
    // At its own height the shelf is within reach of every band: no band can leave it out, nor convolve it.
    Sites s(wallUnderLamp(Furniture::ShelfOnTheWall), wallLinks(true));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/invalid"), 1u);
}

TEST(ConvolutionSites, ACupboardBeforeTheWallIsRefusedAsTooCoarse) {
    // Its 1.2 m face toward the lamp spans every band's blockers in depth: E_rr over e_max with 32 bands.
    Sites s(wallUnderLamp(Furniture::Cupboard), wallLinks(true));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/too_coarse"), 1u);
}

// cluster_receivers: a trough of two slopes (object 0, 4 x 4 quads each, tilted by `slope` radians toward the
// middle) under a black card (1) and a lamp (2); with `seat`, a one-sided plate 0.4 m over one slope in the
// trough's object.
TestScene trough(double slope, bool seat) {
    TestScene t;
    t.names = {"Trough", "Card", "Lamp"};
    const Rgb grey{0.5, 0.5, 0.5};
    const int n = 4;
    const double h = std::tan(slope) * 2;  // the slopes rise by h over their 2 m
    for (int side : {-1, 1})
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                // x from 0 outward to 2 * side, z = h |x| / 2, y across [-2, 2]
                double x0 = side * 2.0 * i / n, x1 = side * 2.0 * (i + 1) / n;
                double y0 = -2 + 4.0 * j / n, y1 = -2 + 4.0 * (j + 1) / n;
                Vec3 a{x0, y0, h * std::fabs(x0) / 2}, b{x1, y0, h * std::fabs(x1) / 2};
                Vec3 c{x1, y1, h * std::fabs(x1) / 2}, d{x0, y1, h * std::fabs(x0) / 2};
                if (side > 0) t.quad(a, b, c, d, grey, {}, 0, 0);
                else t.quad(a, d, c, b, grey, {}, 0, 0);  // normals up on both slopes
            }
    const double zs = 0.4 + h;
    if (seat) t.quad({0.6, -0.3, zs}, {1.2, -0.3, zs}, {1.2, 0.3, zs}, {0.6, 0.3, zs}, grey, {}, 0, 0);
    const double c = 0.3, zc = 1.0 + h, s = 0.25, zl = 2.0 + h;
    t.quad({-c, -c, zc}, {-c, c, zc}, {c, c, zc}, {c, -c, zc}, {}, {}, 0, 1);
    t.quad({-s, -s, zl}, {-s, s, zl}, {s, s, zl}, {s, -s, zl}, {}, {10, 10, 10}, kLightOnly, 2);
    return t;
}

Settings clustered(bool on) {
    Settings s;
    s.clusterReceivers = on;
    return s;
}

// The node of the cluster holding exactly the polygons [0, count).
int clusterOf(const Hierarchy& h, int count) {
    std::vector<int> polys(size_t(count), 0);
    for (int i = 0; i < count; ++i) polys[size_t(i)] = i;
    return clusterWith(h, polys);
}

TEST(ConvolutionSites, ATroughIsOneReceiverOnlyWithClusterReceivers) {
    // Slopes of 10 degrees under a lamp 2 m up: no face shades another; all 32 take the one link.
    ClusteredSites off(trough(0.1745, false), clustered(false));
    const int r = clusterOf(*off.h, 32), lamp = 33;
    ASSERT_LT(r, 0);
    ConvolutionLink l;
    EXPECT_FALSE(off.sites->receiverCandidate(r));
    ClusteredSites on(trough(0.1745, false), clustered(true));
    ASSERT_EQ(clusterOf(*on.h, 32), r);
    EXPECT_TRUE(on.sites->receiverCandidate(r));
    ASSERT_TRUE(on.sites->tryLink(r, lamp, l));
    EXPECT_EQ(l.receiverPolygons.size(), 32u);
    EXPECT_EQ(on.count("convolution_refused/self_shadow"), 0u);
}

TEST(ConvolutionSites, AClusterReceiverShadingItselfIsRefused) {
    // A seat over one slope, in the trough's object: it shades the slope under it.
    ClusteredSites seat(trough(0.1745, true), clustered(true));
    const int r = clusterOf(*seat.h, 33), lamp = 34;
    ASSERT_LT(r, 0);
    ConvolutionLink l;
    EXPECT_FALSE(seat.sites->tryLink(r, lamp, l));
    EXPECT_EQ(seat.count("convolution_refused/self_shadow"), 1u);
    // Slopes of 70 degrees: still no face shades another, the lamp being over the trough (the region above a
    // V is convex, so no segment from a slope to the lamp leaves it): a steep neighbour is no shadow by itself,
    // and the exact test links it.
    ClusteredSites steep(trough(1.2217, false), clustered(true));
    const int rs = clusterOf(*steep.h, 32);
    ASSERT_LT(rs, 0);
    EXPECT_TRUE(steep.sites->tryLink(rs, 33, l));
    EXPECT_EQ(l.receiverPolygons.size(), 32u);
    EXPECT_EQ(steep.count("convolution_refused/self_shadow"), 0u);
}

}  // namespace
}  // namespace penumbra
