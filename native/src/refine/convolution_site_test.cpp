// ConvolutionSites on a floor under a lamp: a card floating between them makes a convolution site; a
// card resting on the floor, a post through it, or nothing in the shaft are refused, each counted under
// its reason; wouldLink() answers the same without counting or computing anything.
#include "refine/convolution_site.h"

#include <gtest/gtest.h>

#include "convolution/cost_model.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

using testing::TestScene;

enum class Card { None, Floating, Resting, Post };

// Polygon 0: a 2 x 2 floor at z = 0. Polygon 1: a 0.5 x 0.5 lamp at z = 1 facing down, light-only.
// Polygons 2...: the card.
TestScene floorUnderLamp(Card card) {
    TestScene t;
    t.names = {"Floor", "Lamp", "Card"};
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    double s = 0.25;
    t.quad({-s, -s, 1}, {-s, s, 1}, {s, s, 1}, {s, -s, 1}, {}, {10, 10, 10}, kLightOnly, 1);
    Rgb grey{0.5, 0.5, 0.5};
    switch (card) {
    case Card::None: break;
    case Card::Floating:  // 0.4 x 0.4, halfway up, touching nothing
        t.quad({-0.2, -0.2, 0.5}, {0.2, -0.2, 0.5}, {0.2, 0.2, 0.5}, {-0.2, 0.2, 0.5}, grey, {}, 0, 2);
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
    EXPECT_TRUE(s.sites->sourceHasEmitters(1));
    EXPECT_FALSE(s.sites->sourceHasEmitters(0));
    EXPECT_TRUE(s.sites->receiverCandidate(2));  // the card's box: 0.57, a_min of the diagonal: 0.15 x 3
    Settings big;
    big.aMin = 0.25;
    Sites t(floorUnderLamp(Card::Floating), big);
    EXPECT_FALSE(t.sites->receiverCandidate(2));  // now under a_min x diagonal = 0.75
    EXPECT_TRUE(t.sites->receiverCandidate(0));
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

TEST(ConvolutionSites, ABoxRestingOnTheFloorIsRefusedAsTooCoarse) {
    // Touching the floor is allowed (the boxes are shrunk by a tolerance), but the shadow at the contact
    // is sharp: no texture resolves it within e_max.
    Sites s(floorUnderLamp(Card::Resting));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->wouldLink(0, 1));
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/too_coarse"), 1u);
    EXPECT_EQ(s.refused(), 1u);
}

TEST(ConvolutionSites, APostThroughTheFloorIsRefusedAsAnIntruder) {
    Sites s(floorUnderLamp(Card::Post));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 1, l));
    EXPECT_EQ(s.count("convolution_refused/intruder"), 1u);
    EXPECT_EQ(s.refused(), 1u);
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

TEST(ConvolutionSites, AReceiverIsNeverItsOwnSource) {
    Sites s(floorUnderLamp(Card::Floating));
    ConvolutionLink l;
    EXPECT_FALSE(s.sites->tryLink(0, 0, l));
    EXPECT_FALSE(s.sites->tryLink(1, 1, l));
    EXPECT_EQ(s.count("convolution_tried"), 0u);  // refused before the blocker selection
}

}  // namespace
}  // namespace penumbra
