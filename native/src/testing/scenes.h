// Small scenes built in code for the unit tests: they own their arrays and hand out a SceneInput.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "hierarchy/element.h"
#include "scene/scene.h"
#include "solve/settings.h"
#include "util/counters.h"
#include "visibility/ray_caster.h"

namespace penumbra {
class Solution;
}

namespace penumbra::testing {

struct TestScene {
    std::vector<float> vertices, reflectance, emission;
    std::vector<int32_t> polygons, objectIndex;
    std::vector<uint8_t> flags;
    std::vector<std::string> names{"test"};

    // Appends a quad (counter-clockwise around its front normal) and returns its index.
    int quad(Vec3 a, Vec3 b, Vec3 c, Vec3 d, Rgb rho, Rgb emit, uint8_t flag = 0, int object = 0);
    int triangle(Vec3 a, Vec3 b, Vec3 c, Rgb rho, Rgb emit, uint8_t flag = 0, int object = 0);
    // Six faces of the box [lo, hi], looking out (a solid) or in (a room).
    void box(Vec3 lo, Vec3 hi, Rgb rho, Rgb emit, bool inward = false, int object = 0);
    // Moves and scales every vertex: p -> p * scale + offset (in double, rounded once to float).
    void transform(double scale, Vec3 offset);
    SceneInput input() const;
};

// The scene built from a TestScene with its hierarchy (clustered as `s` says) and ray caster: what the
// refiner and the convolution sites work on, for the unit tests of either.
struct SolverParts {
    Scene scene;
    std::unique_ptr<Hierarchy> h;
    std::unique_ptr<RayCaster> rays;
    Counters counters;
    SolverParts(const TestScene& t, const Settings& s);
};

// Closed axis-aligned box [0,s]^3 whose six faces look inward, each split into n x n quads.
TestScene furnaceBox(double size, int n, Rgb rho, Rgb emit);

// A closed room [-1,1]^2 x [0,2] (object 0 "Room") with a block on the floor (1 "Block") and a
// downward lamp under the ceiling (2 "Lamp", light-only): shadows and interreflection in 19 faces.
TestScene litRoom();

// Every face's triangles in their own cell of a UV grid, baked by `sol` at size x size texels.
std::vector<float> bakeAll(const Solution& sol, const TestScene& t, int size);

}  // namespace penumbra::testing
