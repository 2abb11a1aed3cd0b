#include "scene/scene.h"

#include <gtest/gtest.h>

#include <cmath>

#include "testing/scenes.h"
#include "util/progress.h"

namespace penumbra {
namespace {

testing::TestScene lampOverFloor() {
    testing::TestScene t;
    t.names = {"Floor", "Lamp"};
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {}, 0, 0);
    t.quad({-0.2, -0.2, 1}, {-0.2, 0.2, 1}, {0.2, 0.2, 1}, {0.2, -0.2, 1}, {}, {5, 5, 5}, kLightOnly, 1);
    return t;
}

std::string errorOf(const testing::TestScene& t) {
    try {
        buildScene(t.input());
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(Scene, ValidSceneIsRecentred) {
    auto t = lampOverFloor();
    for (size_t i = 0; i < t.vertices.size(); i += 3) t.vertices[i] += 1e5f;
    Scene s = buildScene(t.input());
    ASSERT_EQ(s.polygons.size(), 2u);
    EXPECT_NEAR(s.offset.x, 1e5, 1);
    EXPECT_LT(std::fabs(s.bounds.center().x), 1e-6);
    EXPECT_NEAR(s.polygons[1].normal.z, -1.0, 1e-12);  // the lamp faces down
    EXPECT_FALSE(s.polygons[1].occludes);
    EXPECT_FALSE(s.polygons[1].receives);
    EXPECT_DOUBLE_EQ(s.maxEmission, 5.0);
}

TEST(Scene, BadInputNamesTheObject) {
    auto t = lampOverFloor();
    t.vertices[0] = NAN;
    EXPECT_NE(errorOf(t).find("'Floor'"), std::string::npos);
    EXPECT_NE(errorOf(t).find("NaN"), std::string::npos);

    t = lampOverFloor();
    t.vertices[4] = INFINITY;
    EXPECT_NE(errorOf(t).find("'Floor'"), std::string::npos);

    t = lampOverFloor();
    t.reflectance[1] = 1.0f;
    EXPECT_NE(errorOf(t).find("albedo"), std::string::npos);

    t = lampOverFloor();
    t.emission[4] = -1.0f;
    EXPECT_NE(errorOf(t).find("'Lamp'"), std::string::npos);

    t = lampOverFloor();
    t.polygons[2] = 99;
    EXPECT_NE(errorOf(t).find("out of range"), std::string::npos);

    t = lampOverFloor();
    for (float& e : t.emission) e = 0;
    EXPECT_NE(errorOf(t).find("nothing emits"), std::string::npos);

    testing::TestScene empty;
    EXPECT_NE(errorOf(empty).find("no faces"), std::string::npos);
}

TEST(Scene, DegenerateFacesAreSkippedAndCounted) {
    auto t = lampOverFloor();
    t.quad({0, 0, 0.5}, {1, 0, 0.5}, {2, 0, 0.5}, {3, 0, 0.5}, {0.5, 0.5, 0.5}, {}, 0, 0);  // collinear
    t.triangle({0, 0, 0.5}, {0, 0, 0.5}, {1, 1, 0.5}, {0.5, 0.5, 0.5}, {}, 0, 0);         // repeated vertex
    Scene s = buildScene(t.input());
    EXPECT_EQ(s.degenerateSkipped, 2u);
    ASSERT_EQ(s.warnings.size(), 1u);
    EXPECT_NE(s.warnings[0].find("Floor"), std::string::npos);
}

TEST(Scene, WarpedAndConcaveQuadsAreSplit) {
    auto t = lampOverFloor();
    t.quad({0, 0, 0.2}, {1, 0, 0.2}, {1, 1, 0.5}, {0, 1, 0.2}, {0.5, 0.5, 0.5}, {}, 0, 0);      // warped
    t.quad({0, 0, 0.3}, {1, 0, 0.3}, {0.3, 0.3, 0.3}, {0, 1, 0.3}, {0.5, 0.5, 0.5}, {}, 0, 0);  // concave
    Scene s = buildScene(t.input());
    ASSERT_EQ(s.polygons.size(), 6u);
    for (size_t i = 2; i < 6; ++i) {
        EXPECT_EQ(s.polygons[i].geom.n, 3);
        EXPECT_GT(s.polygons[i].normal.z, 0);
    }
    // The concave quad's area is kept: 0.5 * (1*0.3 + 0.3*1) = 0.3.
    EXPECT_NEAR(s.polygons[4].area + s.polygons[5].area, 0.3, 1e-6);
}

TEST(Scene, TwoSidedEmitterGetsABackFace) {
    testing::TestScene t;
    t.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, {0.5, 0.5, 0.5}, {2, 2, 2}, kEmitBack, 0);
    Scene s = buildScene(t.input());
    ASSERT_EQ(s.polygons.size(), 2u);
    EXPECT_NEAR(s.polygons[1].normal.z, -1, 1e-12);
    EXPECT_TRUE(s.polygons[0].occludes);
    EXPECT_FALSE(s.polygons[1].occludes);  // same triangles as its twin
    EXPECT_TRUE(s.polygons[1].receives);
}

}  // namespace
}  // namespace penumbra
