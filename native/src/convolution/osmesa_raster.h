// Blocker-image rasterizer on OSMesa (Mesa's offscreen llvmpipe), the 1998 system's "render the
// blocker with the graphics hardware", kept as the alternative to SpanRasterizer.
//
// Every GL entry point is fetched with OSMesaGetProcAddress: inside Blender, a plain gl* call from
// this module binds to Blender's own libGL and silently does nothing. One context per thread is
// created on first use and kept for the thread's life (a context plus the first shader JIT costs
// 7-26 ms). Anti-aliasing: `samples` per pixel from multisampling (llvmpipe: 4 at most, resolved by a
// framebuffer blit) times a k x k larger framebuffer box-filtered on the CPU when more are asked. Polygons are fan-triangulated, so they must be convex
// (blocker polygons are triangles).
#pragma once
#include "convolution/raster.h"

namespace penumbra {

class OSMesaRasterizer final : public CoverageRasterizer {
public:
    explicit OSMesaRasterizer(int samples = 16);
    void rasterize(const PolygonSet& polys, const PixelGrid& grid, float* out) override;
    RasterizerKind kind() const override { return RasterizerKind::OSMesa; }
    // Samples per pixel actually used by this thread's context (after the first rasterize call).
    int samplesUsed() const { return samplesUsed_; }
    // Renderer string of this thread's context, e.g. "llvmpipe (LLVM 15.0.6, 256 bits)".
    static std::string rendererName();

private:
    int samples_;
    int samplesUsed_ = 0;
};

}  // namespace penumbra
