#include "convolution/cost_model.h"

#include <gtest/gtest.h>

#include <cmath>

namespace penumbra {
namespace {

TEST(ConvCost, CalibratedConstantIsPlausible) {
    double c = fftCostConstant();
    EXPECT_TRUE(std::isfinite(c));
    // Seconds per n^2 log2 n of an r2c transform: around 3e-10 on this machine; any CPU of the
    // last twenty years lies well inside these bounds, a unit slip (ms, ns) does not.
    EXPECT_GT(c, 1e-12);
    EXPECT_LT(c, 1e-7);
}

TEST(ConvCost, FollowsTheSeedFormulaAndBudget) {
    const double before = fftCostConstant();
    setFftCostConstant(1e-9);
    EXPECT_NEAR(predictedSeconds(256, 1), 4 * 1e-9 * 256.0 * 256.0 * 8, 1e-15);
    EXPECT_NEAR(predictedSeconds(512, 3) / predictedSeconds(256, 1), (8.0 / 4.0) * 4.0 * 9.0 / 8.0, 1e-12);
    const double t = predictedSeconds(128, 2);
    EXPECT_TRUE(withinBudget(128, 2, t));
    EXPECT_FALSE(withinBudget(128, 2, t * 0.999));
    EXPECT_FALSE(withinBudget(128, 3, t));
    EXPECT_THROW(predictedSeconds(1, 1), std::invalid_argument);
    EXPECT_THROW(setFftCostConstant(-1), std::invalid_argument);
    setFftCostConstant(before);
}

}  // namespace
}  // namespace penumbra
