#include "convolution/frame.h"

#include <gtest/gtest.h>

namespace penumbra {
namespace {

TEST(ConvFrame, OrthonormalRightHandedAndFollowsHint) {
    ConvolutionFrame f = ConvolutionFrame::make({1, 2, 3}, {0, 0, 5}, {1, 1, 0.5});
    EXPECT_NEAR(length(f.u), 1, 1e-12);
    EXPECT_NEAR(length(f.v), 1, 1e-12);
    EXPECT_NEAR(dot(f.u, f.w), 0, 1e-12);
    EXPECT_NEAR(dot(f.v, f.w), 0, 1e-12);
    Vec3 c = cross(f.u, f.v);
    EXPECT_NEAR(length(c - f.w), 0, 1e-12);
    EXPECT_NEAR(f.u.x, std::sqrt(0.5), 1e-12);  // hint (1,1,.5) without its w part
    // A hint parallel to w still yields a valid frame.
    ConvolutionFrame g = ConvolutionFrame::make({0, 0, 0}, {0, 0, 1}, {0, 0, 2});
    EXPECT_NEAR(dot(g.u, g.w), 0, 1e-12);
    EXPECT_NEAR(length(g.u), 1, 1e-12);
}

TEST(ConvFrame, WindowCoversCentralProjectionOfReceiver) {
    ConvolutionFrame f = ConvolutionFrame::make({0, 0, 0}, {0, 0, 1}, {1, 0, 0});
    // A tilted receiver quad: its depth spread is 2..4.
    std::vector<Vec3> rec{{-1, -1, 2}, {2, -1, 2}, {2, 1, 4}, {-1, 1, 4}};
    ReceiverWindow win = windowByCentralProjection(f, rec);
    EXPECT_DOUBLE_EQ(win.z_r, 3.0);
    Mat4 m = textureMatrix(f, win);
    double smin = 1, smax = 0, tmin = 1, tmax = 0;
    for (const Vec3& p : rec) {
        TexCoord c = applyTextureMatrix(m, p);
        EXPECT_NEAR(c.q, p.z, 1e-12);
        smin = std::fmin(smin, c.s);
        smax = std::fmax(smax, c.s);
        tmin = std::fmin(tmin, c.t);
        tmax = std::fmax(tmax, c.t);
    }
    // Square window centred on the projected rectangle: the longer side spans exactly [0, 1].
    EXPECT_GE(smin, -1e-12);
    EXPECT_LE(smax, 1 + 1e-12);
    EXPECT_GE(tmin, -1e-12);
    EXPECT_LE(tmax, 1 + 1e-12);
    EXPECT_NEAR(std::fmax(smax - smin, tmax - tmin), 1.0, 1e-12);
    EXPECT_NEAR(0.5 * (smin + smax), 0.5, 1e-12);
    // Projected u extent: -1*3/2 .. 2*3/2 = 4.5, v: -1.5 .. 0.75 -> extent 4.5.
    EXPECT_NEAR(win.extent, 4.5, 1e-12);
}

TEST(ConvFrame, TextureMatrixIsACentralProjectionFromO) {
    ConvolutionFrame f = ConvolutionFrame::make({0.3, -0.2, 1.0}, {0.2, 0.1, 1}, {1, 0, 0});
    ReceiverWindow win{2.5, -1.2, -0.7, 3.1};
    Mat4 m = textureMatrix(f, win);
    Vec3 P = f.O + f.u * 0.4 + f.v * -0.3 + f.w * 2.5;  // on the virtual plane
    TexCoord c = applyTextureMatrix(m, P);
    EXPECT_NEAR(c.s, (0.4 - win.u_lo) / win.extent, 1e-12);
    EXPECT_NEAR(c.t, (-0.3 - win.v_lo) / win.extent, 1e-12);
    // Every point on the ray from O through P maps to the same texel.
    for (double k : {0.3, 1.7, 6.0}) {
        TexCoord d = applyTextureMatrix(m, f.O + (P - f.O) * k);
        EXPECT_NEAR(d.s, c.s, 1e-12);
        EXPECT_NEAR(d.t, c.t, 1e-12);
        EXPECT_NEAR(d.q, 2.5 * k, 1e-12);
    }
}

TEST(ConvFrame, WindowRejectsPointsBehindSource) {
    ConvolutionFrame f = ConvolutionFrame::make({0, 0, 0}, {0, 0, 1}, {1, 0, 0});
    EXPECT_THROW(windowByCentralProjection(f, {{0, 0, 1}, {1, 0, -0.5}}), std::domain_error);
}

TEST(ConvFrame, DepthOrderWithTolerance) {
    DepthRange s{-0.1, 0.1}, b{1.0, 2.0}, r{2.0, 2.0};
    EXPECT_TRUE(checkDepthOrder(s, b, r, 1e-3).ok);  // resting on the receiver
    DepthRange sunk{1.0, 2.0005};
    EXPECT_TRUE(checkDepthOrder(s, sunk, r, 1e-3).ok);
    DepthRange through{1.0, 2.5};
    DepthOrder o = checkDepthOrder(s, through, r, 1e-3);
    EXPECT_FALSE(o.ok);
    EXPECT_NE(o.reason.find("overlaps the receiver"), std::string::npos);
    EXPECT_FALSE(checkDepthOrder(s, DepthRange{0.05, 1.0}, r, 1e-3).ok);  // reaches the source
    EXPECT_FALSE(checkDepthOrder(s, DepthRange{}, DepthRange{0.0, 1.0}, 1e-3).ok);
    EXPECT_TRUE(checkDepthOrder(s, DepthRange{}, r, 0).ok);  // no blocker at all
}

}  // namespace
}  // namespace penumbra
