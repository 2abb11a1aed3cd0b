#include "solve/link.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <thread>
#include <vector>

namespace penumbra {
namespace {

TEST(ClusterFaceVisibility, FindsEachPairsSharesAndALaterRecordingReplacesThem) {
    ClusterFaceVisibility v;
    const float a[3] = {0.25f, 0.5f, 1.0f}, b[2] = {0.0f, 0.75f}, c[3] = {1.0f, 1.0f, 0.0f};
    v.record(7, 3, a, 3);
    v.record(2, 9, b, 2);
    v.finish();
    ASSERT_EQ(v.size(), 2u);
    const float* f = v.find(7, 3);
    ASSERT_NE(f, nullptr);
    EXPECT_EQ(f[0], 0.25f);
    EXPECT_EQ(f[2], 1.0f);
    EXPECT_EQ(v.find(2, 9)[1], 0.75f);
    EXPECT_EQ(v.find(3, 7), nullptr);  // the key is ordered: (receiver, source)
    EXPECT_EQ(v.find(7, 4), nullptr);
    // A later refinement pass records the pair again: its new shares win and the old ones are dropped.
    v.record(7, 3, c, 3);
    EXPECT_THROW(v.find(7, 3), std::logic_error);  // not finished
    v.finish();
    ASSERT_EQ(v.size(), 2u);
    EXPECT_EQ(v.find(7, 3)[2], 0.0f);
    EXPECT_EQ(v.find(2, 9)[0], 0.0f);
}

// finish() moves the kept shares down over the replaced ones in place: pairs recorded again with other lengths,
// in passes, must each read back their last shares.
TEST(ClusterFaceVisibility, KeepsEachPairsLastSharesOverPassesOfReplacements) {
    ClusterFaceVisibility v;
    std::map<std::pair<uint64_t, uint64_t>, std::vector<float>> model;
    std::mt19937 rng(5);
    for (int pass = 0; pass < 4; ++pass) {
        for (int k = 0; k < 300; ++k) {
            uint64_t r = rng() % 40, s = rng() % 12;
            std::vector<float> share(1 + rng() % 70);
            for (float& x : share) x = float(rng() % 1000) / 999.0f;
            v.record(r, s, share.data(), share.size());
            model[{r, s}] = share;
        }
        v.finish();
        ASSERT_EQ(v.size(), model.size());
        for (const auto& [key, share] : model) {
            const float* f = v.find(key.first, key.second);
            ASSERT_NE(f, nullptr);
            for (size_t i = 0; i < share.size(); ++i) ASSERT_EQ(f[i], share[i]) << pass << " " << i;
        }
    }
}

TEST(ClusterFaceVisibility, RecordsFromSeveralThreads) {
    ClusterFaceVisibility v;
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&v, t] {
            for (int i = 0; i < 1000; ++i) {
                float s[2] = {float(t), float(i)};
                v.record(uint64_t(t), uint64_t(i), s, 2);
            }
        });
    for (auto& th : threads) th.join();
    v.finish();
    ASSERT_EQ(v.size(), 4000u);
    for (int t = 0; t < 4; ++t)
        for (int i = 0; i < 1000; i += 97) {
            const float* f = v.find(uint64_t(t), uint64_t(i));
            ASSERT_NE(f, nullptr);
            EXPECT_EQ(f[0], float(t));
            EXPECT_EQ(f[1], float(i));
        }
}

}  // namespace
}  // namespace penumbra
