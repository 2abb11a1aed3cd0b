// Lightmap texels from UV triangles. A texel takes the radiance at the point of its triangle
// nearest to its centre: at the centre itself when covered, else at the closest point of a triangle
// that still overlaps the texel, so island borders are never sampled off the surface.
// With LightmapInput::footprint > 1, a texel where the light bends (its second difference with its
// neighbours over kFootprintContrast: a shadow's edge, a contact, a leg's foot inside it), or one without
// neighbours to judge by, takes instead the mean over its footprint as Blender's bake samples it: a square
// half a texel wide about its centre (Blender 3.4 jitters a texel's samples over that square, measured with
// an emission edge swept across a texel, stop 49), on the texel's own triangle (as Cycles keeps them),
// from footprint x footprint points, a point off the triangle taken at its mirror image through the centre. Texels outside
// every island are filled by dilation so that bilinear lookups never fetch empty texels.
#pragma once
#include <vector>

#include "bake/radiance_field.h"

namespace penumbra {

struct LightmapInput {
    const float* positions = nullptr;  // T x 3 x 3, world space
    const float* uvs = nullptr;        // T x 3 x 2
    size_t triangles = 0;
    int width = 0, height = 0, margin = 0;
    bool irradiance = false;  // E/pi without the surface's albedo (RadianceField::radiance)
    // Points per side of a texel's footprint where its light bends within it (above); 1: the texel's own
    // point only (Settings::texelSamples).
    int footprint = 1;
};

// Returns height x width x 4 floats, rows bottom-to-top (v = 0 first), alpha 1 everywhere.
// `offset` is subtracted from positions to reach the field's recentred coordinates.
std::vector<float> bakeLightmap(const RadianceField& field, const LightmapInput& in, const Vec3& offset,
                                int threads);

// Several lightmaps in one call, written one after another into `out` (each height x width x 4, as
// bakeLightmap returns it; out holds the sum of their texels x 4 floats). The work is spread over `threads`
// across all of them, so many small lightmaps use every thread; each lightmap is the same, bit for bit, as
// bakeLightmap makes it alone.
void bakeLightmaps(const RadianceField& field, const LightmapInput* ins, size_t count, const Vec3& offset,
                   int threads, float* out);

// Fraction of the covered texel centres of a grid x grid raster that lie strictly inside more than one UV
// triangle (T x 3 x 2 UVs): islands that overlap share texels, so their faces all get one light. The
// arithmetic is the add-on's numpy version's (writeback.uv_overlap), operation for operation.
double uvOverlap(const float* uvs, size_t triangles, int grid);

// Fills texels with coverage == 0 from covered neighbours, one ring per pass, `passes` times.
void dilate(std::vector<float>& rgba, std::vector<uint8_t>& covered, int width, int height, int passes);
void dilate(float* rgba, uint8_t* covered, int width, int height, int passes);

}  // namespace penumbra
