#include "util/parallel.h"

#include <gtest/gtest.h>

#include <atomic>
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

}  // namespace
}  // namespace penumbra
