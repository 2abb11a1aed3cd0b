#include "testing/scenes.h"

#include <cmath>

#include "penumbra.h"

namespace penumbra::testing {

int TestScene::quad(Vec3 a, Vec3 b, Vec3 c, Vec3 d, Rgb rho, Rgb emit, uint8_t flag, int object) {
    int base = int(vertices.size() / 3);
    for (const Vec3& v : {a, b, c, d}) {
        vertices.push_back(float(v.x));
        vertices.push_back(float(v.y));
        vertices.push_back(float(v.z));
    }
    for (int k = 0; k < 4; ++k) polygons.push_back(base + k);
    for (double x : {rho.x, rho.y, rho.z}) reflectance.push_back(float(x));
    for (double x : {emit.x, emit.y, emit.z}) emission.push_back(float(x));
    flags.push_back(flag);
    objectIndex.push_back(object);
    return int(flags.size()) - 1;
}

SolverParts::SolverParts(const TestScene& t, const Settings& s) : scene(buildScene(t.input())) {
    h = std::make_unique<Hierarchy>(scene, s.maxElements, s.clustering, s.planarClusters);
    rays = std::make_unique<RayCaster>(scene);
}

int TestScene::triangle(Vec3 a, Vec3 b, Vec3 c, Rgb rho, Rgb emit, uint8_t flag, int object) {
    int i = quad(a, b, c, c, rho, emit, flag, object);
    polygons.back() = -1;
    vertices.resize(vertices.size() - 3);
    return i;
}

void TestScene::box(Vec3 lo, Vec3 hi, Rgb rho, Rgb emit, bool inward, int object) {
    Vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                 {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
    const int faces[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    for (auto& f : faces) {
        if (inward) quad(c[f[3]], c[f[2]], c[f[1]], c[f[0]], rho, emit, 0, object);
        else quad(c[f[0]], c[f[1]], c[f[2]], c[f[3]], rho, emit, 0, object);
    }
}

void TestScene::transform(double scale, Vec3 offset) {
    for (size_t i = 0; i < vertices.size(); ++i) vertices[i] = float(double(vertices[i]) * scale + offset[int(i % 3)]);
}

SceneInput TestScene::input() const {
    SceneInput in;
    in.vertices = vertices.data();
    in.numVertices = vertices.size() / 3;
    in.polygons = polygons.data();
    in.numPolygons = flags.size();
    in.reflectance = reflectance.data();
    in.emission = emission.data();
    in.flags = flags.data();
    in.objectIndex = objectIndex.data();
    in.objectNames = names;
    return in;
}

TestScene furnaceBox(double s, int n, Rgb rho, Rgb emit) {
    TestScene t;
    // For each axis and side, a grid of quads wound so the normal points into the box.
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    auto P = [&](double a, double b) {
                        Vec3 p;
                        p[axis] = side * s;
                        p[u] = a * s / n;
                        p[v] = b * s / n;
                        return p;
                    };
                    Vec3 p0 = P(i, j), p1 = P(i + 1, j), p2 = P(i + 1, j + 1), p3 = P(i, j + 1);
                    // (u, v, axis) is right-handed, so p0..p3 face +axis: inward on side 0.
                    if (side == 0) t.quad(p0, p1, p2, p3, rho, emit);
                    else t.quad(p0, p3, p2, p1, rho, emit);
                }
        }
    return t;
}

TestScene litRoom() {
    TestScene t;
    t.names = {"Room", "Block", "Lamp"};
    t.box({-1, -1, 0}, {1, 1, 2}, {0.6, 0.6, 0.6}, {}, true, 0);
    t.box({-0.5, -0.25, 0}, {0.25, 0.5, 0.75}, {0.7, 0.7, 0.7}, {}, false, 1);
    double z = 1.96875, s = 0.25;  // exact in float32 even 1e5 from the origin
    t.quad({-s, -s, z}, {-s, s, z}, {s, s, z}, {s, -s, z}, {}, {30, 30, 30}, kLightOnly, 2);
    return t;
}

std::vector<float> bakeAll(const Solution& sol, const TestScene& t, int size) {
    std::vector<float> pos, uv;
    size_t tris = 0;
    int cells = 1 + int(std::sqrt(2.0 * t.flags.size()));
    for (size_t p = 0; p < t.flags.size(); ++p) {
        int nv = t.polygons[p * 4 + 3] < 0 ? 3 : 4;
        for (int k = 1; k + 1 < nv; ++k, ++tris) {
            for (int j : {0, k, k + 1}) {
                const float* q = &t.vertices[size_t(t.polygons[p * 4 + j]) * 3];
                pos.insert(pos.end(), q, q + 3);
            }
            float u0 = float(tris % cells) / cells, v0 = float(tris / cells) / cells, d = 0.9f / cells;
            uv.insert(uv.end(), {u0, v0, u0 + d, v0, u0, v0 + d});
        }
    }
    LightmapInput in;
    in.positions = pos.data();
    in.uvs = uv.data();
    in.triangles = tris;
    in.width = in.height = size;
    in.margin = 2;
    return sol.bakeLightmap(in);
}

}  // namespace penumbra::testing
