// The refiner's two decisions on a floor under a lamp: a transfer whose error is under epsilon is linked
// where it starts (at the two polygons' roots, no ray cast when the shaft is clear), and a transfer a
// card half hides is split until each link is either fully visible, fully hidden or within epsilon.
#include "refine/refiner.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "geometry/form_factor.h"
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

// A room under a lamp with a row of boxes standing in it: clusters whose light is reflected.
TestScene boxesInRoom() {
    TestScene t;
    t.names = {"Room", "Lamp"};
    t.box({-2, -2, 0}, {2, 2, 2.5}, {0.6, 0.6, 0.6}, {}, true, 0);
    double s = 0.3, zl = 2.45;
    t.quad({-s, -s, zl}, {-s, s, zl}, {s, s, zl}, {s, -s, zl}, {}, {30, 30, 30}, kLightOnly, 1);
    for (int k = 0; k < 6; ++k) {
        t.names.push_back("Box" + std::to_string(k));
        double x = -1.5 + 0.6 * k;
        t.box({x, -0.2, 0.3}, {x + 0.35, 0.2, 0.3 + 0.2 * (k % 3 + 1)}, {0.5, 0.4, 0.3}, {}, false, 2 + k);
    }
    return t;
}

TEST(Refiner, AReflectorsFirstPassLinksAreProvisionalUntilTheNextPassJudgesThemWithItsLight) {
    Settings s;
    s.epsilon = 0.002;
    s.threads = 2;
    s.convolution = false;
    TestScene t = boxesInRoom();
    // One pass only: no later pass to estimate again, so every link takes its full rays.
    s.refinePasses = 1;
    Refined once(t, s);
    for (const Link& l : once.links) EXPECT_FALSE(provisional(l));
    s.refinePasses = 3;
    Refined r(t, s);
    // The first of several passes: a reflector's cluster links are provisional (Link::Fspread = kProvisional, 4
    // rays), an emitter's never; and the same links cost fewer rays for it.
    size_t marked = 0;
    for (const Link& l : r.links) {
        if (!provisional(l)) continue;
        ++marked;
        EXPECT_TRUE(isClusterNode(l.receiver) || isClusterNode(l.source));
        bool emits = !isClusterNode(l.source) && maxComponent(r.scene.polygons[(*r.h)[size_t(l.source)].polygon].emission) > 0;
        EXPECT_FALSE(emits);
    }
    EXPECT_GT(marked, 10u);
    EXPECT_LT(r.counters.values().at("rays_cluster"), once.counters.values().at("rays_cluster"));
    // The next pass, with light on every reflector: no link stays provisional, and those whose bound is now
    // over an eighth of the threshold were made again (fewer of the first pass's links remain as they were).
    for (size_t i = 0; i < r.h->size(); ++i) {
        Element& e = (*r.h)[i];
        const ScenePolygon& p = r.scene.polygons[e.polygon];
        // The room's walls lit, the boxes nearly dark: some bounds grow past an eighth of the threshold, some not.
        e.B = maxComponent(p.emission) > 0 ? p.emission : p.rho * (p.object == 0 ? 2.0 : 0.01);
    }
    r.h->updateClusterFlux();
    Refiner again(*r.h, *r.rays, s, r.counters);
    size_t raysBefore = r.counters.values().at("rays");
    std::vector<Link> links = r.links;
    bool changed = false;
    again.rerefine(links, nullptr, changed);
    EXPECT_TRUE(changed);
    for (const Link& l : links) EXPECT_FALSE(provisional(l));
    // Where the bound is now within an eighth of the threshold the first pass's estimate stays as it was (a link
    // hidden from its 4 rays is dropped: it carries nothing); where it is more, the pair is made again with the
    // full 16 rays at least.
    size_t kept = 0, redone = 0;
    for (const Link& l : r.links) {
        if (!provisional(l)) continue;
        Link judged = l;
        judged.Fspread = 0;
        if (again.linkError(judged) > 0.125 * again.threshold()) {
            ++redone;
            continue;
        }
        if (l.V <= 0) continue;
        ++kept;
        bool found = false;
        for (const Link& m : links) found = found || (m.receiver == l.receiver && m.source == l.source && m.V == l.V);
        EXPECT_TRUE(found) << l.receiver << " <- " << l.source;
    }
    // Measured: 442 provisional, 370 kept, 14 made again (the rest hidden from their 4 rays, dropped).
    EXPECT_GT(kept, 0u);
    EXPECT_GT(redone, 0u);
    EXPECT_GE(r.counters.values().at("rays") - raysBefore, 16u * redone);
}

TEST(Refiner, ASourceWhoseLightLiesBehindTheReceiverIsSeenByItsPartInFront) {
    // A 2 x 2 floor lit on its x < 0 half only, and a card over its dark half facing +x, away from the lit
    // half: nothing stands between the card and the floor in front of it, so every link between them must
    // see all of it (V = 1). Rays drawn by the floor's light all went to the lit half behind the card,
    // none counted, and the floor's light to the card was dropped as hidden.
    TestScene t;
    t.names = {"Floor", "Card", "Lamp"};
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    t.quad({0.2, -0.1, 0.1}, {0.2, 0.1, 0.1}, {0.2, 0.1, 0.3}, {0.2, -0.1, 0.3}, {0.5, 0.5, 0.5}, {}, 0, 1);
    t.quad({-0.8, -0.1, 1}, {-0.8, 0.1, 1}, {-0.6, 0.1, 1}, {-0.6, -0.1, 1}, {}, {10, 10, 10}, kLightOnly, 2);
    Settings s = standardOnly(0.01);
    s.minSize = 0.2;  // the card cannot split
    Refined r(t, s);
    int fc = r.h->subdivide(0);
    double sum = 0;
    for (int k = 0; k < (*r.h)[0].numChildren; ++k) {
        Element& c = (*r.h)[size_t(fc + k)];
        c.B = c.center.x < 0 ? Rgb{10, 10, 10} : Rgb{0.01, 0.01, 0.01};
        sum += c.B.x * c.area;
    }
    (*r.h)[0].B = Rgb{1, 1, 1} * (sum / (*r.h)[0].area);
    r.h->updateRadiosityDeviation();
    Refiner again(*r.h, *r.rays, s, r.counters);
    std::vector<Link> links = r.links;
    bool changed = false;
    again.rerefine(links, nullptr, changed);
    size_t found = 0;
    for (const Link& l : links) {
        if ((*r.h)[size_t(l.receiver)].polygon != 1 || (*r.h)[size_t(l.source)].polygon != 0) continue;
        ++found;
        EXPECT_GT(l.Fmean, 0.0f);
        EXPECT_EQ(l.V, 1.0f) << "source element " << l.source;
    }
    EXPECT_GT(found, 0u) << "the floor's light to the card was dropped";
}

TEST(Refiner, AFaceStandingAcrossAReceiverLightsItsPartInFrontByItsMeanFormFactor) {
    // A 1 x 1 floor that cannot split and a 1 x 1 lamp standing across it at y = 0.3, facing +y: the floor behind
    // the lamp (y < 0.3) gets nothing, the floor in front a form factor that peaks at the lamp's foot. The link's
    // mean form factor must be that mean over the whole floor. Its four Gauss points over the whole floor read it
    // 52 % low (two of them behind the lamp, the other two far from its foot).
    TestScene t;
    t.names = {"Floor", "Lamp"};
    t.quad({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    const double y0 = 0.3;
    t.quad({0, y0, 0}, {0, y0, 1}, {1, y0, 1}, {1, y0, 0}, {}, {10, 10, 10}, kLightOnly, 1);
    Settings s = standardOnly(0.5);
    s.minSize = 0.9;  // the floor cannot split
    Refined r(t, s);
    ASSERT_EQ(r.links.size(), 1u);
    const Link& l = r.links[0];
    ASSERT_EQ((*r.h)[size_t(l.source)].polygon, 1);
    // The reference: the point form factor over the floor in front of the lamp, its rows graded toward the foot
    // (y = y0 + (1 - y0) u^2), midpoints of a 400 x 400 grid in (x, u).
    Polygon lamp;
    for (const Vec3& v : {Vec3{0, y0, 0}, Vec3{0, y0, 1}, Vec3{1, y0, 1}, Vec3{1, y0, 0}}) lamp.push(v);
    const int m = 400;
    double mean = 0;
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) {
            double x = (i + 0.5) / m, u = (j + 0.5) / m;
            mean += pointToPolygonFormFactor({x, y0 + (1 - y0) * u * u, 0}, {0, 0, 1}, lamp) * 2 * u * (1 - y0);
        }
    mean /= double(m) * m;
    EXPECT_NEAR(l.Fmean / mean, 1.0, 0.03) << "link " << l.Fmean << " reference " << mean;
}

}  // namespace
}  // namespace penumbra
