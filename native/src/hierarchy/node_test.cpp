#include "hierarchy/node.h"

#include <gtest/gtest.h>

#include <cmath>

#include "geometry/form_factor.h"

namespace penumbra {
namespace {

// A unit square in the z = 0 plane, facing +z, centred at the origin.
void unitSquare(Element& e) {
    e.n = 4;
    e.v = {Vec3{-0.5, -0.5, 0}, Vec3{0.5, -0.5, 0}, Vec3{0.5, 0.5, 0}, Vec3{-0.5, 0.5, 0}};
    e.center = Vec3{0, 0, 0};
    e.area = 1;
}

// Beyond the near field the kernel is the point kernel with its second-order term over the face (not
// the disc's A / (pi r^2 + A), which is right straight in front only): every direction and receiver
// orientation within a fraction of a percent of the exact form factor. The disc estimate was up to 6 %
// off at oblique incidence, low (a wall lighting the floor beside it), and that light was lost at every bounce
// through a cluster: a closed 20 x 15 x 3 m room of albedo 0.5 kept 99.46 % of its light at epsilon 0.032
// with it, 99.61 % with this term (the exact form factor everywhere: 99.64 %).
TEST(ElementKernel, FarFromAFaceMatchesTheExactFormFactorAtEveryAngle) {
    Element e;
    unitSquare(e);
    const Vec3 en{0, 0, 1};
    double worst = 0, worstDisc = 0;
    for (double r : {4.01, 5.0, 8.0}) {  // distance in face widths; the exact form is used within 4
        for (int i = 0; i <= 8; ++i) {    // elevation of y above the face's plane, 10 to 90 degrees
            double el = (10 + 10 * i) * M_PI / 180;
            for (double az : {0.0, 0.4, 0.785}) {
                Vec3 y{r * std::cos(el) * std::cos(az), r * std::cos(el) * std::sin(az), r * std::sin(el)};
                Vec3 toFace = normalize(Vec3{0, 0, 0} - y);
                // Receiver normals: facing the face, facing down, facing sideways toward it.
                for (Vec3 n : {toFace, Vec3{0, 0, -1}, normalize(Vec3{-y.x, -y.y, 0})}) {
                    // At grazing incidence on the receiver the light comes from the part of the face in
                    // front of its plane, which no expansion about the centre sees; little light arrives.
                    if (dot(n, toFace) < 0.05) continue;
                    double exact = pointToPolygonFormFactor(y, n, e.polygonShape());
                    double k = elementKernel(e, en, y, &n);
                    worst = std::max(worst, std::fabs(k / exact - 1));
                    Vec3 d = y - e.center;
                    double r2 = length2(d), disc = e.area * dot(en, d) * -dot(n, d) / (r2 * (M_PI * r2 + e.area));
                    worstDisc = std::max(worstDisc, std::fabs(disc / exact - 1));
                }
            }
        }
    }
    EXPECT_LT(worst, 0.003);       // 0.18 % at most
    EXPECT_GT(worstDisc, 0.03);    // 5.8 %: what the test would catch
}

// Within the near field the kernel is the exact form factor itself.
TEST(ElementKernel, NearAFaceIsTheExactFormFactor) {
    Element e;
    unitSquare(e);
    const Vec3 en{0, 0, 1}, y{0.7, 0.2, 0.9}, n = normalize(Vec3{-1, 0, -1});
    EXPECT_DOUBLE_EQ(elementKernel(e, en, y, &n), pointToPolygonFormFactor(y, n, e.polygonShape()));
}

}  // namespace
}  // namespace penumbra
