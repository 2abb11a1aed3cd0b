#include "util/parallel.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace penumbra {
namespace {

// Items whose costs differ by orders of magnitude, as the refinement's root pairs do: every index is done
// exactly once whatever thread takes it, and the per-index results equal a serial run's.
TEST(ParallelForDynamic, DoesEveryIndexOnceWithUnevenCosts) {
    const size_t n = 997;
    auto work = [](size_t i) {
        double x = 0;
        size_t steps = (i % 97 == 0) ? 200000 : 10;
        for (size_t k = 0; k < steps; ++k) x += std::sin(double(i + k));
        return x;
    };
    std::vector<double> serial(n);
    for (size_t i = 0; i < n; ++i) serial[i] = work(i);
    for (size_t grain : {size_t(1), size_t(7), size_t(2000)}) {
        std::vector<std::atomic<int>> visits(n);
        std::vector<double> out(n, 0.0);
        parallelForDynamic(n, 3, grain, [&](size_t b, size_t e, int t) {
            EXPECT_GE(t, 0);
            EXPECT_LT(t, 3);
            for (size_t i = b; i < e; ++i) {
                ++visits[i];
                out[i] = work(i);
            }
        });
        for (size_t i = 0; i < n; ++i) {
            ASSERT_EQ(visits[i].load(), 1) << "index " << i << " grain " << grain;
            ASSERT_EQ(out[i], serial[i]);
        }
    }
}

TEST(ParallelForDynamic, RethrowsAnErrorAndStopsTheOthers) {
    std::atomic<size_t> done{0};
    EXPECT_THROW(parallelForDynamic(10000000, 2, 1,
                                    [&](size_t b, size_t, int) {
                                        if (b == 10) throw std::runtime_error("budget");
                                        ++done;
                                    }),
                 std::runtime_error);
    EXPECT_LT(done.load(), size_t(10000000) - 1);  // the other thread stopped early
}

// Keys that are never repeated sort to std::sort's order on any thread count, past the size where the runs
// split; with repeats (ties broken arbitrarily) the result is still sorted and holds the same elements.
TEST(ParallelSort, MatchesStdSortOnDistinctKeysAndSortsWithRepeats) {
    struct Item {
        uint32_t key;
        uint32_t payload;
    };
    auto less = [](const Item& a, const Item& b) { return a.key < b.key; };
    for (size_t n : {size_t(10), size_t(40000), size_t(300001)}) {
        for (uint32_t repeatEvery : {0u, 7u}) {
            std::vector<Item> items(n);
            uint64_t x = 0x9E3779B97F4A7C15ull;
            for (size_t i = 0; i < n; ++i) {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // Distinct keys: a bijection of i; repeats: every key taken from a small range.
                uint32_t key = repeatEvery ? uint32_t(x % (n / repeatEvery + 1)) : uint32_t(i * 2654435761u);
                items[i] = {key, uint32_t(i)};
            }
            std::vector<Item> expected = items;
            std::sort(expected.begin(), expected.end(), less);
            for (int threads : {1, 2, 3, 8}) {
                std::vector<Item> got = items;
                parallelSort(got.begin(), got.end(), threads, less);
                ASSERT_TRUE(std::is_sorted(got.begin(), got.end(), less)) << n << " " << threads;
                if (repeatEvery == 0) {
                    for (size_t i = 0; i < n; ++i)
                        ASSERT_EQ(got[i].payload, expected[i].payload) << "n " << n << " threads " << threads;
                } else {
                    auto byBoth = [](const Item& a, const Item& b) {
                        return a.key != b.key ? a.key < b.key : a.payload < b.payload;
                    };
                    std::sort(got.begin(), got.end(), byBoth);
                    std::vector<Item> want = expected;
                    std::sort(want.begin(), want.end(), byBoth);
                    for (size_t i = 0; i < n; ++i) ASSERT_EQ(got[i].payload, want[i].payload);
                }
            }
        }
    }
}

}  // namespace
}  // namespace penumbra
