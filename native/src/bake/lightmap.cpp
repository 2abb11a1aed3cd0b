#include "bake/lightmap.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "util/parallel.h"

namespace penumbra {
namespace {

struct Sample {
    double dist2 = HUGE_VAL;  // squared distance in texels from the texel centre to the triangle
    int tri = -1;
    double b0 = 0, b1 = 0, b2 = 0;  // barycentric coordinates of the sampled point
};

// Closest point of triangle (a, b, c) to p in 2D, as barycentric coordinates.
void closestBarycentric(double px, double py, const double* a, const double* b, const double* c,
                        double& u, double& v, double& w) {
    auto bary = [&](double qx, double qy, double& bu, double& bv, double& bw) {
        double v0x = b[0] - a[0], v0y = b[1] - a[1], v1x = c[0] - a[0], v1y = c[1] - a[1];
        double v2x = qx - a[0], v2y = qy - a[1];
        double den = v0x * v1y - v1x * v0y;
        bv = (v2x * v1y - v1x * v2y) / den;
        bw = (v0x * v2y - v2x * v0y) / den;
        bu = 1 - bv - bw;
    };
    bary(px, py, u, v, w);
    if (u >= 0 && v >= 0 && w >= 0) return;
    // Outside: the nearest point lies on one of the three edges.
    const double* P[3] = {a, b, c};
    double best = HUGE_VAL;
    for (int e = 0; e < 3; ++e) {
        const double* s = P[e];
        const double* t = P[(e + 1) % 3];
        double dx = t[0] - s[0], dy = t[1] - s[1];
        double len2 = dx * dx + dy * dy;
        double k = len2 > 0 ? std::clamp(((px - s[0]) * dx + (py - s[1]) * dy) / len2, 0.0, 1.0) : 0.0;
        double qx = s[0] + k * dx, qy = s[1] + k * dy;
        double d2 = (qx - px) * (qx - px) + (qy - py) * (qy - py);
        if (d2 < best) {
            best = d2;
            double bb[3] = {0, 0, 0};
            bb[e] = 1 - k;
            bb[(e + 1) % 3] = k;
            u = bb[0]; v = bb[1]; w = bb[2];
        }
    }
}

}  // namespace

void dilate(std::vector<float>& rgba, std::vector<uint8_t>& covered, int W, int H, int passes) {
    for (int pass = 0; pass < passes; ++pass) {
        std::vector<uint8_t> next = covered;
        bool any = false;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                size_t i = size_t(y) * W + x;
                if (covered[i]) continue;
                double acc[3] = {0, 0, 0};
                int n = 0;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        int xx = x + dx, yy = y + dy;
                        if ((dx || dy) && xx >= 0 && yy >= 0 && xx < W && yy < H) {
                            size_t j = size_t(yy) * W + xx;
                            if (!covered[j]) continue;
                            for (int c = 0; c < 3; ++c) acc[c] += rgba[j * 4 + c];
                            ++n;
                        }
                    }
                if (n) {
                    for (int c = 0; c < 3; ++c) rgba[i * 4 + c] = float(acc[c] / n);
                    next[i] = 1;
                    any = true;
                }
            }
        covered.swap(next);
        if (!any) break;
    }
}

std::vector<float> bakeLightmap(const RadianceField& field, const LightmapInput& in, const Vec3& offset,
                                int threads) {
    const int W = in.width, H = in.height;
    if (W <= 0 || H <= 0 || size_t(W) * size_t(H) > (size_t(1) << 28))
        throw std::invalid_argument("lightmap size must be positive and at most 16384 x 16384");
    std::vector<Sample> samples(size_t(W) * H);
    const double reach2 = 0.5;  // a texel (half-diagonal 0.707) overlaps triangles closer than this

    for (size_t t = 0; t < in.triangles; ++t) {
        double uv[3][2];
        for (int k = 0; k < 3; ++k) {
            uv[k][0] = double(in.uvs[t * 6 + k * 2]) * W;
            uv[k][1] = double(in.uvs[t * 6 + k * 2 + 1]) * H;
        }
        double area2 = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1]) - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1]);
        if (!std::isfinite(area2) || std::fabs(area2) < 1e-12) continue;  // no UV area: nothing to own
        // Clamped while still double: a UV far outside [0, 1] must not overflow the int conversion.
        auto lo = [](double v, int n) { return int(std::clamp(std::floor(v - 1), 0.0, double(n))); };
        auto hi = [](double v, int n) { return int(std::clamp(std::ceil(v + 1), -1.0, double(n - 1))); };
        int x0 = lo(std::min({uv[0][0], uv[1][0], uv[2][0]}), W);
        int x1 = hi(std::max({uv[0][0], uv[1][0], uv[2][0]}), W);
        int y0 = lo(std::min({uv[0][1], uv[1][1], uv[2][1]}), H);
        int y1 = hi(std::max({uv[0][1], uv[1][1], uv[2][1]}), H);
        for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
                double px = x + 0.5, py = y + 0.5, u, v, w;
                closestBarycentric(px, py, uv[0], uv[1], uv[2], u, v, w);
                double qx = u * uv[0][0] + v * uv[1][0] + w * uv[2][0];
                double qy = u * uv[0][1] + v * uv[1][1] + w * uv[2][1];
                double d2 = (qx - px) * (qx - px) + (qy - py) * (qy - py);
                if (d2 > reach2) continue;
                Sample& s = samples[size_t(y) * W + x];
                if (d2 < s.dist2) s = Sample{d2, int(t), u, v, w};
            }
    }

    std::vector<float> rgba(size_t(W) * H * 4, 0.0f);
    std::vector<uint8_t> covered(size_t(W) * H, 0);
    parallelFor(size_t(H), threads, 8, [&](size_t yb, size_t ye, int) {
        for (size_t y = yb; y < ye; ++y)
            for (int x = 0; x < W; ++x) {
                size_t i = y * W + x;
                const Sample& s = samples[i];
                rgba[i * 4 + 3] = 1.0f;
                if (s.tri < 0) continue;
                const float* P = in.positions + size_t(s.tri) * 9;
                Vec3 a{P[0], P[1], P[2]}, b{P[3], P[4], P[5]}, c{P[6], P[7], P[8]};
                a -= offset; b -= offset; c -= offset;
                Vec3 n = normalize(cross(b - a, c - a));
                Vec3 p = a * s.b0 + b * s.b1 + c * s.b2;
                Rgb r = field.radiance(p, n, in.irradiance);
                rgba[i * 4] = float(r.x);
                rgba[i * 4 + 1] = float(r.y);
                rgba[i * 4 + 2] = float(r.z);
                covered[i] = 1;
            }
    });
    dilate(rgba, covered, W, H, in.margin);
    return rgba;
}

}  // namespace penumbra
