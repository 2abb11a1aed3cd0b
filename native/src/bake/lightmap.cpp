#include "bake/lightmap.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <stdexcept>
#include <thread>

namespace penumbra {
namespace {

struct Sample {
    double dist2 = HUGE_VAL;  // squared distance in texels from the texel centre to the triangle
    int tri = -1;
    double b0 = 0, b1 = 0, b2 = 0;  // barycentric coordinates of the sampled point
};

// Barycentric coordinates of p in triangle (a, b, c) in 2D; true when p is on the triangle.
bool barycentric(double px, double py, const double* a, const double* b, const double* c, double& u, double& v,
                 double& w) {
    double v0x = b[0] - a[0], v0y = b[1] - a[1], v1x = c[0] - a[0], v1y = c[1] - a[1];
    double v2x = px - a[0], v2y = py - a[1];
    double den = v0x * v1y - v1x * v0y;
    v = (v2x * v1y - v1x * v2y) / den;
    w = (v0x * v2y - v2x * v0y) / den;
    u = 1 - v - w;
    return u >= 0 && v >= 0 && w >= 0;
}

// Closest point of triangle (a, b, c) to p in 2D, as barycentric coordinates.
void closestBarycentric(double px, double py, const double* a, const double* b, const double* c,
                        double& u, double& v, double& w) {
    if (barycentric(px, py, a, b, c, u, v, w)) return;
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
    dilate(rgba.data(), covered.data(), W, H, passes);
}

void dilate(float* rgba, uint8_t* covered, int W, int H, int passes) {
    const size_t texels = size_t(W) * size_t(H);
    std::vector<uint8_t> next;
    for (int pass = 0; pass < passes; ++pass) {
        next.assign(covered, covered + texels);
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
        std::copy(next.begin(), next.end(), covered);
        if (!any) break;
    }
}

namespace {

// Each texel's nearest triangle point within reach of its centre (none: tri = -1).
std::vector<Sample> rasterize(const LightmapInput& in) {
    const int W = in.width, H = in.height;
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
    return samples;
}

// The footprint's side in texels, and the contrast with a neighbour above which a texel takes it (lightmap.h).
// Half a texel is what Blender 3.4's bake spreads a texel's samples over: an emission step swept across a texel
// of a plane read 1.00 with the step 0.24 texel before the centre, 0.00 with it 0.24 texel after, and
// linearly between (1024 samples).
constexpr double kFootprintSide = 0.5;
constexpr double kFootprintContrast = 0.02;

// The mean radiance over the footprint of texel (x, y) on triangle `tri` (world corners a, b, c, normal n), or
// {-1, -1, -1} where its centre is off the triangle (a texel reached only by the triangle's edge keeps its
// one point). A footprint point off the triangle is taken at its mirror image through the centre, or left out
// if that is off too: the points stay centred on the texel, so a texel on a quad's diagonal or an island's
// edge does not read its light from a place shifted into its triangle.
Rgb footprintMean(const RadianceField& field, const LightmapInput& in, const RadianceField::Region& region, int tri,
                  int x, int y, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n) {
    const Rgb none{-1, -1, -1};
    double uv[3][2];
    for (int k = 0; k < 3; ++k) {
        uv[k][0] = double(in.uvs[size_t(tri) * 6 + size_t(k) * 2]) * in.width;
        uv[k][1] = double(in.uvs[size_t(tri) * 6 + size_t(k) * 2 + 1]) * in.height;
    }
    auto bary = [&](double px, double py, double& u, double& v, double& w) {
        return barycentric(px, py, uv[0], uv[1], uv[2], u, v, w);
    };
    const double cx = x + 0.5, cy = y + 0.5;
    double u, v, w;
    if (!bary(cx, cy, u, v, w)) return none;
    const int k = in.footprint;
    Rgb sum{0, 0, 0};
    int taken = 0;
    for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
            const double ox = kFootprintSide * ((i + 0.5) / k - 0.5), oy = kFootprintSide * ((j + 0.5) / k - 0.5);
            if (!bary(cx + ox, cy + oy, u, v, w) && !bary(cx - ox, cy - oy, u, v, w)) continue;
            sum += field.radiance(a * u + b * v + c * w, n, in.irradiance, &region);
            ++taken;
        }
    return taken > 0 ? sum * (1.0 / taken) : none;
}

// Which covered texels take their footprint's mean: those where the light bends within a texel (a shadow's
// edge, a contact, a leg's foot). The footprint is symmetric about the centre, so where the light is linear
// across it its mean is the centre's value; what parts them is the second difference, here taken along each
// axis over the covered neighbours (largest channel, against the largest value of the three), marked above
// kFootprintContrast. Judged on the centres' values alone, so the choice does not depend on the order in
// which texels are refined.
std::vector<uint8_t> footprintTexels(const float* rgba, const uint8_t* covered, int W, int H) {
    std::vector<uint8_t> mark(size_t(W) * size_t(H), 0);
    auto bends = [&](size_t a, size_t i, size_t b) {
        double d = 0, m = 0;
        for (int ch = 0; ch < 3; ++ch) {
            const double l = rgba[a * 4 + ch], c = rgba[i * 4 + ch], r = rgba[b * 4 + ch];
            d = std::max(d, std::fabs(l + r - 2 * c));
            m = std::max({m, l, c, r});
        }
        return d > kFootprintContrast * m;
    };
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            size_t i = size_t(y) * W + x;
            if (!covered[i]) continue;
            const bool hx = x > 0 && x + 1 < W && covered[i - 1] && covered[i + 1];
            const bool hy = y > 0 && y + 1 < H && covered[i - W] && covered[i + W];
            // A texel with a covered pair along neither axis is an island of its own or a sliver's edge: its
            // bend cannot be judged, and its one point stands for a face that may hold a whole shadow.
            mark[i] = (hx && bends(i - 1, i, i + 1)) || (hy && bends(i - W, i, i + W)) || (!hx && !hy);
        }
    return mark;
}

// Rows [y0, y1) of one lightmap: the radiance of every covered texel, alpha 1 everywhere; with `footprints`,
// only the marked texels again, each as its footprint's mean.
void shadeRows(const RadianceField& field, const LightmapInput& in, const Vec3& offset, const Sample* samples,
               size_t y0, size_t y1, float* rgba, uint8_t* covered, const uint8_t* footprints = nullptr) {
    const int W = in.width;
    auto corners = [&](int tri, Vec3& a, Vec3& b, Vec3& c) {
        const float* P = in.positions + size_t(tri) * 9;
        a = Vec3{P[0], P[1], P[2]};
        b = Vec3{P[3], P[4], P[5]};
        c = Vec3{P[6], P[7], P[8]};
        a -= offset; b -= offset; c -= offset;
    };
    // The candidates of every texel of these rows, looked up once (RadianceField::Region): the rows' texels
    // lie on their triangles, inside the box of those triangles' corners up to rounding, which the margin
    // covers (a point outside the box walks the trees, with the same result).
    Bounds box;
    for (size_t i = y0 * W; i < y1 * W; ++i)
        if (samples[i].tri >= 0 && (!footprints || footprints[i])) {
            Vec3 a, b, c;
            corners(samples[i].tri, a, b, c);
            box.extend(a);
            box.extend(b);
            box.extend(c);
        }
    if (!box.empty()) {
        double m = 1e-9 * (std::max({std::fabs(box.lo.x), std::fabs(box.lo.y), std::fabs(box.lo.z), std::fabs(box.hi.x),
                                     std::fabs(box.hi.y), std::fabs(box.hi.z)}) + 1.0);
        box.extend(box.lo - Vec3{m, m, m});
        box.extend(box.hi + Vec3{m, m, m});
    }
    const RadianceField::Region region = field.region(box);
    for (size_t y = y0; y < y1; ++y)
        for (int x = 0; x < W; ++x) {
            size_t i = y * W + x;
            const Sample& s = samples[i];
            if (footprints) {
                if (!footprints[i] || s.tri < 0) continue;
                Vec3 a, b, c;
                corners(s.tri, a, b, c);
                Rgb r = footprintMean(field, in, region, s.tri, x, int(y), a, b, c, normalize(cross(b - a, c - a)));
                if (r.x < 0) continue;
                rgba[i * 4] = float(r.x);
                rgba[i * 4 + 1] = float(r.y);
                rgba[i * 4 + 2] = float(r.z);
                continue;
            }
            rgba[i * 4 + 3] = 1.0f;
            if (s.tri < 0) {
                rgba[i * 4] = rgba[i * 4 + 1] = rgba[i * 4 + 2] = 0.0f;
                continue;
            }
            Vec3 a, b, c;
            corners(s.tri, a, b, c);
            Vec3 n = normalize(cross(b - a, c - a));
            Vec3 p = a * s.b0 + b * s.b1 + c * s.b2;
            Rgb r = field.radiance(p, n, in.irradiance, &region);
            rgba[i * 4] = float(r.x);
            rgba[i * 4 + 1] = float(r.y);
            rgba[i * 4 + 2] = float(r.z);
            covered[i] = 1;
        }
}

// Work spread over threads by an atomic counter: items take very different times (a lightmap's rows
// near a lamp, objects of different sizes). Which thread does an item changes no result.
template <class F>
void dynamicFor(size_t n, int threads, F&& body) {
    threads = std::max(1, std::min(threads, int(std::min<size_t>(n, 1024))));
    if (threads <= 1) {
        for (size_t i = 0; i < n; ++i) body(i);
        return;
    }
    std::atomic<size_t> next{0};
    std::vector<std::exception_ptr> errors(static_cast<size_t>(threads));
    auto work = [&](int t) {
        try {
            for (size_t i; (i = next.fetch_add(1)) < n;) body(i);
        } catch (...) {
            errors[size_t(t)] = std::current_exception();
            next = n;
        }
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
    work(0);
    for (auto& th : pool) th.join();
    for (auto& e : errors)
        if (e) std::rethrow_exception(e);
}

void checkSize(const LightmapInput& in) {
    if (in.width <= 0 || in.height <= 0 || size_t(in.width) * size_t(in.height) > (size_t(1) << 28))
        throw std::invalid_argument("lightmap size must be positive and at most 16384 x 16384");
}

}  // namespace

void bakeLightmaps(const RadianceField& field, const LightmapInput* ins, size_t count, const Vec3& offset,
                   int threads, float* out) {
    std::vector<size_t> start(count + 1, 0);
    for (size_t k = 0; k < count; ++k) {
        checkSize(ins[k]);
        start[k + 1] = start[k] + size_t(ins[k].width) * size_t(ins[k].height);
    }
    // 1. Every lightmap's texel-to-triangle map, one lightmap per task.
    std::vector<std::vector<Sample>> samples(count);
    dynamicFor(count, threads, [&](size_t k) { samples[k] = rasterize(ins[k]); });
    // 2. The radiance of every covered texel, in blocks of rows of all the lightmaps together, so a batch
    // of small lightmaps and a single large one keep every thread busy alike.
    const size_t rows = 8;
    std::vector<std::pair<size_t, size_t>> blocks;  // (lightmap, first row)
    for (size_t k = 0; k < count; ++k)
        for (size_t y = 0; y < size_t(ins[k].height); y += rows) blocks.emplace_back(k, y);
    std::vector<uint8_t> covered(start[count], 0);
    dynamicFor(blocks.size(), threads, [&](size_t b) {
        auto [k, y] = blocks[b];
        shadeRows(field, ins[k], offset, samples[k].data(), y, std::min(y + rows, size_t(ins[k].height)),
                  out + start[k] * 4, covered.data() + start[k]);
    });
    // 3. Texels whose light changes within them: their footprints' means, judged on step 2's values.
    std::vector<std::vector<uint8_t>> marks(count);
    dynamicFor(count, threads, [&](size_t k) {
        if (ins[k].footprint > 1)
            marks[k] = footprintTexels(out + start[k] * 4, covered.data() + start[k], ins[k].width, ins[k].height);
    });
    dynamicFor(blocks.size(), threads, [&](size_t b) {
        auto [k, y] = blocks[b];
        if (marks[k].empty()) return;
        shadeRows(field, ins[k], offset, samples[k].data(), y, std::min(y + rows, size_t(ins[k].height)),
                  out + start[k] * 4, covered.data() + start[k], marks[k].data());
    });
    samples.clear();
    // 4. Texels outside every island filled from their neighbours, one lightmap per task.
    dynamicFor(count, threads, [&](size_t k) {
        const LightmapInput& in = ins[k];
        dilate(out + start[k] * 4, covered.data() + start[k], in.width, in.height, in.margin);
    });
}

double uvOverlap(const float* uvs, size_t triangles, int grid) {
    if (grid <= 0) return 0.0;
    std::vector<uint32_t> counts(size_t(grid) * size_t(grid), 0);
    const double eps = 1e-6;
    for (size_t tri = 0; tri < triangles; ++tri) {
        double t[3][2];
        bool finite = true;
        for (int k = 0; k < 3; ++k)
            for (int c = 0; c < 2; ++c) {
                t[k][c] = double(uvs[tri * 6 + size_t(k) * 2 + size_t(c)]) * grid - 0.5;  // texel centre j at j
                finite = finite && std::isfinite(t[k][c]);
            }
        if (!finite) continue;
        const double* a = t[0];
        const double* b = t[1];
        const double* c = t[2];
        double det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        if (!(std::fabs(det) > 1e-12)) continue;
        int lo[2], hi[2];
        for (int d = 0; d < 2; ++d) {
            double mn = std::min({a[d], b[d], c[d]}), mx = std::max({a[d], b[d], c[d]});
            lo[d] = int(std::clamp(std::ceil(mn), 0.0, double(grid - 1)));
            hi[d] = int(std::clamp(std::floor(mx), -1.0, double(grid - 1)));
        }
        for (int py = lo[1]; py <= hi[1]; ++py)
            for (int px = lo[0]; px <= hi[0]; ++px) {
                double x = px, y = py;
                double l1 = ((x - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (y - a[1])) / det;
                double l2 = ((b[0] - a[0]) * (y - a[1]) - (x - a[0]) * (b[1] - a[1])) / det;
                // Strictly inside, so a texel centre on an edge two neighbours share is not an overlap.
                if (l1 > eps && l2 > eps && 1.0 - l1 - l2 > eps) ++counts[size_t(py) * size_t(grid) + size_t(px)];
            }
    }
    size_t covered = 0, shared = 0;
    for (uint32_t n : counts) {
        covered += n > 0;
        shared += n > 1;
    }
    return covered ? double(shared) / double(covered) : 0.0;
}

std::vector<float> bakeLightmap(const RadianceField& field, const LightmapInput& in, const Vec3& offset,
                                int threads) {
    checkSize(in);
    std::vector<float> rgba(size_t(in.width) * in.height * 4, 0.0f);
    bakeLightmaps(field, &in, 1, offset, threads, rgba.data());
    return rgba;
}

}  // namespace penumbra
