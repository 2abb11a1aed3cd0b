// The refiner's two decisions on a floor under a lamp: a transfer whose error is under epsilon is linked
// where it starts (at the two polygons' roots, no ray cast when the shaft is clear), and a transfer a
// card half hides is split until each link is either fully visible, fully hidden or within epsilon.
#include "refine/refiner.h"

#include <gtest/gtest.h>

#include <cmath>

#include "testing/scenes.h"

namespace penumbra {
namespace {

using testing::TestScene;

// Polygon 0: a 2 x 2 floor at z = 0 (rho 0.5). Polygon 1: a 0.5 x 0.5 lamp at z = 1 facing down
// (light-only, 10 W/m^2). With `card`, polygon 2: a 1 x 2 card at z = 0.5 over the floor's x < 0 half.
TestScene floorUnderLamp(bool card) {
    TestScene t;
    t.names = {"Floor", "Lamp", "Card"};
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    double s = 0.25;
    t.quad({-s, -s, 1}, {-s, s, 1}, {s, s, 1}, {s, -s, 1}, {}, {10, 10, 10}, kLightOnly, 1);
    if (card) t.quad({-1, -1, 0.5}, {0, -1, 0.5}, {0, 1, 0.5}, {-1, 1, 0.5}, {0.5, 0.5, 0.5}, {}, 0, 2);
    return t;
}

Settings standardOnly(double epsilon) {
    Settings s;
    s.epsilon = epsilon;
    s.minSize = 0.02;
    s.clustering = false;
    s.convolution = false;
    s.threads = 2;
    return s;
}

struct Refined : testing::SolverParts {
    std::vector<Link> links;
    Refined(const TestScene& t, const Settings& s) : SolverParts(t, s) {
        Refiner refiner(*h, *rays, s, counters);
        links = refiner.linkAll(nullptr);
    }
};

TEST(Refiner, AnUnhiddenTransferWithinEpsilonIsLinkedAtTheRoots) {
    // threshold = epsilon * 10 = 5 W/m^2 > rho * B * spread = 5 * spread, spread < 1.
    Refined r(floorUnderLamp(false), standardOnly(0.5));
    ASSERT_EQ(r.links.size(), 1u);  // the lamp receives nothing (light-only); the floor cannot see itself
    const Link& l = r.links[0];
    EXPECT_EQ(l.receiver, 0);
    EXPECT_EQ(l.source, 1);
    EXPECT_EQ(l.V, 1.0f);
    EXPECT_GT(l.Fmean, 0.0f);
    EXPECT_EQ(l.F(), l.Fmean);
    EXPECT_EQ(r.h->size(), r.h->numRoots());  // nothing split
    // Its sixteen rays (strata 4 x 4) all got through: no shaft test is taken first.
    EXPECT_EQ(r.counters.values().at("rays"), 16u);
}

TEST(Refiner, AnUnhiddenTransferOverEpsilonSplitsOnlyTheReceiver) {
    // No occluder: the error is the form factor's spread over the receiver, which only splitting the
    // receiver reduces; the source stays whole.
    Refined r(floorUnderLamp(false), standardOnly(0.01));
    ASSERT_GT(r.links.size(), 1u);
    EXPECT_GT(r.h->size(), r.h->numRoots());
    for (const Link& l : r.links) {
        EXPECT_EQ(l.source, 1);
        EXPECT_NE(l.receiver, 0);
        EXPECT_EQ(l.V, 1.0f);
    }
    // Sixteen rays per link kept, none blocked (V = 1 above), and none spent on the pairs split.
    EXPECT_EQ(r.counters.values().at("rays"), 16u * r.links.size());
}

TEST(Refiner, AHalfHiddenTransferSplitsUntilTheShadowIsResolved) {
    Settings s = standardOnly(0.01);
    Refined r(floorUnderLamp(true), s);
    EXPECT_GT(r.h->size(), r.h->numRoots());
    EXPECT_GT(r.counters.values().at("rays"), 0u);
    Refiner judge(*r.h, *r.rays, s, r.counters);
    size_t hidden = 0, visible = 0, partial = 0;
    const double threshold = s.epsilon * 10;
    for (const Link& l : r.links) {
        // The lamp's light on the floor (the lamp's elements split too once the floor's are smaller).
        if ((*r.h)[size_t(l.source)].polygon != 1 || (*r.h)[size_t(l.receiver)].polygon != 0) continue;
        EXPECT_NE(l.receiver, 0) << "the floor's root cannot be linked whole to a lamp it half sees";
        if (l.V == 0) ++hidden;
        else if (l.V == 1) ++visible;
        else {
            ++partial;
            // A partly visible link is kept only within epsilon or when neither end can split further.
            const Element& e = (*r.h)[size_t(l.receiver)];
            EXPECT_TRUE(judge.linkError(l) <= threshold || e.area <= std::pow(s.minSize * r.scene.diagonal, 2))
                << "receiver " << l.receiver;
        }
    }
    EXPECT_GT(hidden, 0u);   // under the card: kept with V = 0 for the final gather
    EXPECT_GT(visible, 0u);  // the floor's open half
    EXPECT_GT(partial, 0u);  // the penumbra
}

TEST(Refiner, LinkErrorIsTheSpreadUnlessPartlyVisible) {
    Refined r(floorUnderLamp(false), standardOnly(0.5));
    Refiner judge(*r.h, *r.rays, standardOnly(0.5), r.counters);
    Link l;
    l.receiver = 0;
    l.source = 1;
    l.Fmean = 0.2f;
    l.Fspread = 0.1f;
    l.V = 1;
    EXPECT_NEAR(judge.linkError(l), 0.5 * 10 * 0.1, 1e-6);  // rho * B * spread
    l.V = 0.5f;
    EXPECT_NEAR(judge.linkError(l), 0.5 * 10 * 0.2, 1e-6);  // a shadow edge may cross: the whole mean
    l.V = 0;
    EXPECT_NEAR(judge.linkError(l), 0.5 * 10 * 0.1, 1e-6);
}

}  // namespace
}  // namespace penumbra
