#include "geometry/vec3.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace penumbra {

// fminOf/fmaxOf replace std::fmin/fmax in hot loops; any difference, even in the sign of a zero,
// would change every recorded golden value.
TEST(Vec3, MinMaxOfGiveTheLibrarysResultsBitForBit) {
    const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
    const double values[] = {-0.0, 0.0, 1.0, -1.0, 1e-300, -inf, inf, nan, 3.5};
    for (double a : values)
        for (double b : values) {
            volatile double va = a, vb = b;  // keep the library calls from being folded
            double lmin = std::fmin(va, vb), lmax = std::fmax(va, vb);
            double omin = fminOf(a, b), omax = fmaxOf(a, b);
            ASSERT_EQ(std::isnan(lmin), std::isnan(omin)) << a << " " << b;
            ASSERT_EQ(std::isnan(lmax), std::isnan(omax)) << a << " " << b;
            if (!std::isnan(lmin)) {
                EXPECT_EQ(lmin, omin) << a << " " << b;
                EXPECT_EQ(std::signbit(lmin), std::signbit(omin)) << a << " " << b;
            }
            if (!std::isnan(lmax)) {
                EXPECT_EQ(lmax, omax) << a << " " << b;
                EXPECT_EQ(std::signbit(lmax), std::signbit(omax)) << a << " " << b;
            }
        }
    EXPECT_EQ(maxComponent(Vec3{0.25, nan, -2.0}), 0.25);
}

}  // namespace penumbra
