#include "convolution/raster.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "convolution/osmesa_raster.h"

namespace penumbra {

RasterizerKind parseRasterizerKind(const std::string& name) {
    if (name == "auto") return RasterizerKind::Auto;
    if (name == "span" || name == "cpu") return RasterizerKind::Span;
    if (name == "osmesa") return RasterizerKind::OSMesa;
    throw std::invalid_argument("unknown rasterizer '" + name + "' (expected auto, span or osmesa)");
}

const char* rasterizerName(RasterizerKind k) {
    switch (k) {
        case RasterizerKind::Auto: return "auto";
        case RasterizerKind::Span: return "span";
        case RasterizerKind::OSMesa: return "osmesa";
    }
    return "?";
}

std::unique_ptr<CoverageRasterizer> makeRasterizer(RasterizerKind kind, int subRows) {
    if (kind == RasterizerKind::OSMesa) return std::make_unique<OSMesaRasterizer>(subRows * subRows);
    return std::make_unique<SpanRasterizer>(subRows);
}

namespace {

struct Interval {
    double a, b;
};

// x where the closed polygon's edges cross the line y, with the half-open rule so that a vertex
// on the line is counted once; the sorted list pairs up into inside intervals (even-odd).
void crossings(const Vec2* v, int count, double y, std::vector<double>& xs) {
    xs.clear();
    for (int e = 0; e < count; ++e) {
        const Vec2& a = v[e];
        const Vec2& b = v[e + 1 == count ? 0 : e + 1];
        if ((a.y <= y) != (b.y <= y)) xs.push_back(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
    }
    if (xs.size() == 2) {
        if (xs[0] > xs[1]) std::swap(xs[0], xs[1]);
    } else {
        std::sort(xs.begin(), xs.end());
    }
}

// Credits weight * (covered length) of [a, b] (pixel units, already clipped to [0, W]) to a line:
// partial end pixels go to `part`, whole pixels to the difference array `diff`.
inline void creditInterval(double a, double b, double wt, double* part, double* diff, int W) {
    int ia = static_cast<int>(a), ib = static_cast<int>(b);
    if (ia >= W) return;
    if (ia == ib) {
        part[ia] += (b - a) * wt;
        return;
    }
    part[ia] += (ia + 1 - a) * wt;
    diff[ia + 1] += wt;
    diff[ib] -= wt;
    if (ib < W) part[ib] += (b - ib) * wt;
}

}  // namespace

SpanRasterizer::SpanRasterizer(int subRows) : subRows_(subRows) {
    if (subRows < 1 || subRows > 64) throw std::invalid_argument("subRows must be in 1..64");
}

void SpanRasterizer::rasterize(const PolygonSet& polys, const PixelGrid& g, float* out) {
    const int W = g.width, H = g.height, S = subRows_;
    std::fill(out, out + static_cast<size_t>(W) * H, 0.0f);
    const int P = polys.size();
    if (P == 0 || W <= 0 || H <= 0) return;
    const int R = H * S;  // sub-rows; sub-row r samples y = (r + 0.5) / S in pixel units

    std::vector<Vec2> pv(polys.vertices.size());
    for (size_t k = 0; k < pv.size(); ++k)
        pv[k] = {(polys.vertices[k].x - g.u0) / g.p, (polys.vertices[k].y - g.v0) / g.p};

    // Bucket polygons by their first sub-row so that each line only sees the polygons crossing it.
    std::vector<int> head(R, -1), next(P, -1), last(P, -1);
    for (int k = P - 1; k >= 0; --k) {
        int s = polys.start[k], e = polys.start[k + 1];
        if (e - s < 3) continue;
        double ylo = HUGE_VAL, yhi = -HUGE_VAL;
        for (int i = s; i < e; ++i) {
            ylo = std::fmin(ylo, pv[i].y);
            yhi = std::fmax(yhi, pv[i].y);
        }
        if (!(yhi > 0) || !(ylo < H)) continue;
        int r0 = static_cast<int>(std::ceil(ylo * S - 0.5));
        int r1 = static_cast<int>(std::floor(yhi * S - 0.5));
        r0 = std::max(r0, 0);
        r1 = std::min(r1, R - 1);
        if (r0 > r1) continue;
        last[k] = r1;
        next[k] = head[r0];
        head[r0] = k;
    }

    std::vector<int> active;
    std::vector<double> xs;
    std::vector<Interval> spans;
    std::vector<double> part(W + 1), diff(W + 1);
    const double wt = 1.0 / S;
    for (int r = 0; r < R; ++r) {
        const int j = r / S;
        if (r % S == 0) {
            std::fill(part.begin(), part.end(), 0.0);
            std::fill(diff.begin(), diff.end(), 0.0);
        }
        for (int k = head[r]; k >= 0; k = next[k]) active.push_back(k);
        const double y = (r + 0.5) / S;
        spans.clear();
        for (size_t q = 0; q < active.size();) {
            int k = active[q];
            if (last[k] < r) {
                active[q] = active.back();
                active.pop_back();
                continue;
            }
            ++q;
            int s = polys.start[k], cnt = polys.start[k + 1] - s;
            if (cnt == 3) {
                // Triangles (every blocker) cross a line exactly twice: no list, no sort.
                const Vec2* v = &pv[s];
                double x[2];
                int m = 0;
                for (int e = 0; e < 3; ++e) {
                    const Vec2& a = v[e];
                    const Vec2& b = v[e == 2 ? 0 : e + 1];
                    if ((a.y <= y) != (b.y <= y)) x[m++ & 1] = a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y);
                }
                if (m == 2) {
                    double a = std::fmax(std::fmin(x[0], x[1]), 0.0);
                    double b = std::fmin(std::fmax(x[0], x[1]), static_cast<double>(W));
                    if (b > a) spans.push_back({a, b});
                }
                continue;
            }
            crossings(&pv[s], cnt, y, xs);
            for (size_t c = 0; c + 1 < xs.size(); c += 2) {
                double a = std::fmax(xs[c], 0.0), b = std::fmin(xs[c + 1], static_cast<double>(W));
                if (b > a) spans.push_back({a, b});
            }
        }
        if (!spans.empty()) {
            std::sort(spans.begin(), spans.end(), [](const Interval& x, const Interval& y2) { return x.a < y2.a; });
            double ca = spans[0].a, cb = spans[0].b;
            for (size_t q = 1; q < spans.size(); ++q) {
                if (spans[q].a <= cb) {
                    cb = std::fmax(cb, spans[q].b);
                } else {
                    creditInterval(ca, cb, wt, part.data(), diff.data(), W);
                    ca = spans[q].a;
                    cb = spans[q].b;
                }
            }
            creditInterval(ca, cb, wt, part.data(), diff.data(), W);
        }
        if (r % S == S - 1) {
            float* row = out + static_cast<size_t>(j) * W;
            double run = 0;
            for (int i = 0; i < W; ++i) {
                run += diff[i];
                row[i] = static_cast<float>(std::fmin(run + part[i], 1.0));
            }
        }
    }
}

void rasterizeWeighted(const std::vector<Vec2>& poly, const PixelGrid& g, int ss,
                       const std::function<float(double, double)>& weight, float* out) {
    const int W = g.width, H = g.height;
    std::fill(out, out + static_cast<size_t>(W) * H, 0.0f);
    if (poly.size() < 3) return;
    std::vector<Vec2> pv(poly.size());
    for (size_t k = 0; k < poly.size(); ++k) pv[k] = {(poly[k].x - g.u0) / g.p, (poly[k].y - g.v0) / g.p};
    std::vector<double> xs;
    const double inv = 1.0 / (ss * ss);
    for (int r = 0; r < H * ss; ++r) {
        const double y = (r + 0.5) / ss;
        crossings(pv.data(), static_cast<int>(pv.size()), y, xs);
        float* row = out + static_cast<size_t>(r / ss) * W;
        for (size_t c = 0; c + 1 < xs.size(); c += 2) {
            // sample columns x = (m + 0.5) / ss inside [xs[c], xs[c+1])
            int m0 = std::max(0, static_cast<int>(std::ceil(xs[c] * ss - 0.5)));
            int m1 = std::min(W * ss - 1, static_cast<int>(std::ceil(xs[c + 1] * ss - 0.5)) - 1);
            for (int m = m0; m <= m1; ++m) {
                double x = (m + 0.5) / ss;
                row[m / ss] += static_cast<float>(weight(g.u0 + x * g.p, g.v0 + y * g.p) * inv);
            }
        }
    }
}

double renderSourceKernel(const std::vector<Vec2>& footprint, double alpha, double p, int N, int ss,
                          const std::function<float(double, double)>* emission, float* out) {
    std::fill(out, out + static_cast<size_t>(N) * N, 0.0f);
    // The kernel is the footprint reflected through O and magnified by alpha (brief §1.1).
    std::vector<Vec2> k(footprint.size());
    double xlo = HUGE_VAL, xhi = -HUGE_VAL, ylo = HUGE_VAL, yhi = -HUGE_VAL;
    for (size_t i = 0; i < footprint.size(); ++i) {
        k[i] = {-alpha * footprint[i].x, -alpha * footprint[i].y};
        xlo = std::fmin(xlo, k[i].x);
        xhi = std::fmax(xhi, k[i].x);
        ylo = std::fmin(ylo, k[i].y);
        yhi = std::fmax(yhi, k[i].y);
    }
    // Pixel i is centred on displacement i*p, i.e. covers [(i - 1/2) p, (i + 1/2) p].
    const int i0 = static_cast<int>(std::floor(xlo / p + 0.5)), i1 = static_cast<int>(std::floor(xhi / p + 0.5));
    const int j0 = static_cast<int>(std::floor(ylo / p + 0.5)), j1 = static_cast<int>(std::floor(yhi / p + 0.5));
    if (i1 - i0 + 1 > N || j1 - j0 + 1 > N)
        throw std::domain_error("source kernel is wider than the FFT image");
    PixelGrid g{(i0 - 0.5) * p, (j0 - 0.5) * p, p, i1 - i0 + 1, j1 - j0 + 1};
    std::vector<float> local(static_cast<size_t>(g.width) * g.height);
    if (emission) {
        auto w = [&](double du, double dv) { return (*emission)(-du / alpha, -dv / alpha); };
        rasterizeWeighted(k, g, ss, w, local.data());
    } else {
        PolygonSet one;
        one.add(k.data(), static_cast<int>(k.size()));
        SpanRasterizer(ss).rasterize(one, g, local.data());
    }
    double sum = 0;
    for (int j = 0; j < g.height; ++j)
        for (int i = 0; i < g.width; ++i) {
            float val = local[static_cast<size_t>(j) * g.width + i];
            if (val == 0) continue;
            int wi = ((i0 + i) % N + N) % N, wj = ((j0 + j) % N + N) % N;
            out[static_cast<size_t>(wj) * N + wi] += val;
            sum += val;
        }
    if (!(sum > 0)) {
        // A kernel below one sample (alpha ~ 0: the blocker touches the receiver) is a Dirac:
        // the shadow is the blocker image itself.
        std::fill(out, out + static_cast<size_t>(N) * N, 0.0f);
        out[0] = 1.0f;
        sum = 1.0;
    }
    return sum;
}

}  // namespace penumbra
