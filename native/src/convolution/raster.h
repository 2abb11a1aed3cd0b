// The two offscreen images of the convolution (brief §1.2-1.3), rendered in virtual-receiver-plane
// units on square pixels of size p:
//  * the blocker image: coverage (0..1, anti-aliased) of the union of the blocker polygons after
//    their central projection from O onto w = z_r, over a window enlarged by the padding margins;
//  * the source image (the kernel): the source's orthographic footprint along w, point-reflected
//    through O and magnified by alpha, pixel (0,0) centred on displacement 0, wrapped FFT-style.
// Both rasterizers behind CoverageRasterizer produce the blocker image; the span rasterizer is the
// default because it measured faster here (docs/convolution.md).
#pragma once
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace penumbra {

struct Vec2 {
    double x = 0, y = 0;
};

// Pixel (i, j) covers [u0 + i p, u0 + (i+1) p] x [v0 + j p, v0 + (j+1) p]; images are row-major
// with index j * width + i, so rows run along v.
struct PixelGrid {
    double u0 = 0, v0 = 0, p = 1;
    int width = 0, height = 0;
};

// Flat storage of many small polygons (blockers are triangles): polygon k owns the vertices
// [start[k], start[k+1]).
struct PolygonSet {
    std::vector<Vec2> vertices;
    std::vector<int> start{0};
    void add(const Vec2* v, int count) {
        vertices.insert(vertices.end(), v, v + count);
        start.push_back(static_cast<int>(vertices.size()));
    }
    int size() const { return static_cast<int>(start.size()) - 1; }
    void clear() {
        vertices.clear();
        start.assign(1, 0);
    }
};

enum class RasterizerKind { Auto, Span, OSMesa };
RasterizerKind parseRasterizerKind(const std::string& name);  // "auto" | "span" | "osmesa"
const char* rasterizerName(RasterizerKind k);

class CoverageRasterizer {
public:
    virtual ~CoverageRasterizer() = default;
    // Writes the coverage of the union of the polygons (each one even-odd filled) into out[w*h].
    virtual void rasterize(const PolygonSet& polys, const PixelGrid& grid, float* out) = 0;
    virtual RasterizerKind kind() const = 0;
};

// Auto picks the span rasterizer. Throws std::runtime_error if OSMesa cannot make a context.
std::unique_ptr<CoverageRasterizer> makeRasterizer(RasterizerKind kind, int subRows = 4);

// CPU scanline rasterizer: every pixel row is sampled on `subRows` lines; along a line the covered
// intervals of all polygons are merged and their exact length is credited, so coverage is exact
// in u and supersampled in v.
class SpanRasterizer final : public CoverageRasterizer {
public:
    explicit SpanRasterizer(int subRows = 4);
    void rasterize(const PolygonSet& polys, const PixelGrid& grid, float* out) override;
    RasterizerKind kind() const override { return RasterizerKind::Span; }

private:
    int subRows_;
};

// Weighted supersampling of one polygon: each pixel gets the mean over ss x ss sample points of
// weight(u, v) where the point is inside (even-odd), 0 elsewhere. Used for a textured source.
void rasterizeWeighted(const std::vector<Vec2>& poly, const PixelGrid& grid, int ss,
                       const std::function<float(double, double)>& weight, float* out);

// The kernel image of size N x N (brief §1.3 step 2). `footprint` is the source's orthographic
// footprint in (u, v) relative to O. With `emission` set, the pixel value is the mean emission
// over its samples, emission being given at footprint coordinates (u, v). Returns the sum of the
// kernel. Throws std::domain_error if the kernel does not fit in N x N.
double renderSourceKernel(const std::vector<Vec2>& footprint, double alpha, double p, int N,
                          int ss, const std::function<float(double, double)>* emission, float* out);

}  // namespace penumbra
