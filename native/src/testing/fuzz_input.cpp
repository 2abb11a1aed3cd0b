#include "testing/fuzz_input.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <vector>

#include "penumbra.h"

namespace penumbra::testing {
namespace {

class Reader {
public:
    Reader(const uint8_t* d, size_t n) : d_(d), n_(n) {}
    uint8_t byte() { return i_ < n_ ? d_[i_++] : 0; }
    float rawFloat() {
        uint32_t bits = 0;
        for (int k = 0; k < 4; ++k) bits |= uint32_t(byte()) << (8 * k);
        float f;
        std::memcpy(&f, &bits, sizeof f);
        return f;
    }

private:
    const uint8_t* d_;
    size_t n_, i_ = 0;
};

// Mostly small grid coordinates, so faces meet, touch and overlap; sometimes any float bit pattern
// (NaN, infinities, denormals, 1e38), or a grid point scaled far up, down or away.
float coordinate(Reader& r) {
    uint8_t mode = r.byte();
    float grid = float(int(r.byte() % 17) - 8) * 0.25f;
    switch (mode % 16) {
        case 0: return r.rawFloat();
        case 1: return grid * 1e-4f;
        case 2: return grid * 1e4f;
        case 3: return grid + 1e5f;
        default: return grid;
    }
}

float channel(Reader& r, bool emission) {
    uint8_t b = r.byte();
    static const float special[] = {0.0f, 1.0f, 0.999f, 1.5f, -0.5f, 1e-9f, 1e9f,
                                    std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()};
    if (b >= 240) return special[b % 9];
    return emission ? (b < 160 ? 0.0f : float(b - 160) * 0.5f) : float(b) / 240.0f;
}

}  // namespace

TestScene decodeFuzzScene(const uint8_t* data, size_t size) {
    Reader r(data, size);
    TestScene t;
    t.names = {"A", "B", "C"};
    int nv = 1 + r.byte() % 64, np = 1 + r.byte() % 32;
    for (int i = 0; i < nv * 3; ++i) t.vertices.push_back(coordinate(r));
    for (int p = 0; p < np; ++p) {
        // Indices mostly in range; -1 marks a triangle; others fall just outside the range on purpose.
        for (int k = 0; k < 4; ++k) {
            uint8_t b = r.byte();
            int idx = b < 224 ? b % nv : (b < 240 ? -1 : int(b) - 248 + (b & 1 ? nv : 0));
            t.polygons.push_back(idx);
        }
        for (int c = 0; c < 3; ++c) t.reflectance.push_back(channel(r, false));
        for (int c = 0; c < 3; ++c) t.emission.push_back(channel(r, true));
        uint8_t f = r.byte();
        t.flags.push_back(f < 128 ? uint8_t(f & 3) : f);
        uint8_t o = r.byte();
        t.objectIndex.push_back(o < 250 ? o % 3 : int(o) - 252);
    }
    return t;
}

FuzzOutcome runFuzzInput(const uint8_t* data, size_t size) {
    TestScene t = decodeFuzzScene(data, size);
    Settings s;
    s.epsilon = 0.01;
    s.minSize = 0.05;
    s.visibilityRays = 4;
    s.maxIterations = 50;
    s.refinePasses = 2;
    s.threads = 1;
    s.maxElements = 20000;
    s.maxLinks = 200000;
    std::unique_ptr<Solution> sol;
    try {
        sol = solve(t.input(), s, nullptr);
    } catch (const InputError&) {
        return FuzzOutcome::Refused;
    }
    // Probe at every input vertex that is finite, with the normal of a face using it, and bake the
    // triangles of all faces into a small lightmap.
    std::vector<float> pts, nrm, pos, uv;
    size_t np = t.flags.size();
    for (size_t p = 0; p < np; ++p) {
        const int32_t* idx = &t.polygons[p * 4];
        Vec3 v[3];
        for (int k = 0; k < 3; ++k) {
            const float* q = &t.vertices[size_t(idx[k]) * 3];
            v[k] = {q[0], q[1], q[2]};
        }
        Vec3 n = cross(v[1] - v[0], v[2] - v[0]);
        for (int k = 0; k < 3; ++k) {
            pts.insert(pts.end(), {float(v[k].x), float(v[k].y), float(v[k].z)});
            nrm.insert(nrm.end(), {float(n.x), float(n.y), float(n.z)});
            pos.insert(pos.end(), {float(v[k].x), float(v[k].y), float(v[k].z)});
        }
        float u0 = float(p % 6) / 6, v0 = float(p / 6) / 6;
        uv.insert(uv.end(), {u0, v0, u0 + 0.15f, v0, u0, v0 + 0.15f});
    }
    // A solved scene passed validation, so every index is in range and every vertex finite; normals
    // may still overflow to infinity in float (1e38 coordinates are refused, 1e5 are not).
    for (float& x : nrm)
        if (!std::isfinite(x)) x = 0;
    std::vector<float> rad = sol->radiance(pts.data(), nrm.data(), pts.size() / 3);
    LightmapInput in;
    in.positions = pos.data();
    in.uvs = uv.data();
    in.triangles = np;
    in.width = 16;
    in.height = 16;
    in.margin = 2;
    std::vector<float> img = sol->bakeLightmap(in);
    for (float x : rad)
        if (!(x >= 0) || !std::isfinite(x)) {
            std::fprintf(stderr, "fuzz: radiance %g\n", x);
            std::abort();
        }
    for (float x : img)
        if (!(x >= 0) || !std::isfinite(x)) {
            std::fprintf(stderr, "fuzz: texel %g\n", x);
            std::abort();
        }
    const Report& rep = sol->report();
    if (!std::isfinite(rep.residual) || rep.residual < 0) {
        std::fprintf(stderr, "fuzz: residual %g\n", rep.residual);
        std::abort();
    }
    return FuzzOutcome::Solved;
}

}  // namespace penumbra::testing
