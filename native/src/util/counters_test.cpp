#include "util/counters.h"

#include <gtest/gtest.h>

#include <thread>
#include <vector>

#include "penumbra.h"
#include "testing/scenes.h"

namespace penumbra {
namespace {

PENUMBRA_COUNTER(kTestHits, "test/hits");
PENUMBRA_COUNTER(kTestHitsAgain, "test/hits");  // the same name in another file is the same counter

TEST(Counters, OneNameIsOneCounter) { EXPECT_EQ(kTestHits, kTestHitsAgain); }

TEST(Counters, ThreadsSumExactlyAndTwoRegistriesStayApart) {
    Counters a, b;
    std::vector<std::thread> pool;
    for (int t = 0; t < 4; ++t)
        pool.emplace_back([&] {
            for (int i = 0; i < 10000; ++i) a.add(kTestHits);
            b.add(kTestHits, 3);
        });
    for (auto& th : pool) th.join();
    EXPECT_EQ(a.value(kTestHits), 40000u);
    EXPECT_EQ(b.value(kTestHits), 12u);
    EXPECT_EQ(a.values().at("test/hits"), 40000u);
}

// Every counter declared in the solver reaches the report, and a second solve starts from zero.
TEST(Counters, EachSolveReportsItsOwnCounts) {
    Settings s;
    s.epsilon = 0.002;
    s.threads = 2;
    auto t = testing::litRoom();
    auto first = solve(t.input(), s, nullptr);
    auto second = solve(t.input(), s, nullptr);
    EXPECT_EQ(first->report().counts, second->report().counts);
    EXPECT_GT(first->report().count("rays"), 0u);
    EXPECT_EQ(first->report().count("polygons"), t.flags.size());
    EXPECT_EQ(first->report().count("test/hits"), 0u);  // registered in this file, never counted by a solve
    s.convolution = false;
    auto off = solve(t.input(), s, nullptr);
    EXPECT_EQ(off->report().count("convolution_tried"), 0u);
    EXPECT_EQ(off->report().count("convolution_refused/too_coarse"), 0u);
}

}  // namespace
}  // namespace penumbra
