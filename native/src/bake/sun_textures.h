// A sun's soft shadow on each receiving face, from a convolution texture (convolution/sun_shadow.h) where
// one applies, instead of shadow rays (issue 13 item 2); and a POINT lamp's with a radius (lampTextures). A sun of a degree casts a penumbra of a few
// centimetres through a window; the rays of lights.h read it at up to light_rays * 2 * angle points (8 for
// 1 degree at the default 256), the first 8 deciding full light and umbra, so its penumbrae came out as
// staircases of 8 levels and partly as umbra (0.16 off under a window frame, SunShadow.WindowFrame...).
//
// For every sun with a size that casts shadows and every receiving face that sees the whole sun disk above
// its horizon (with 3 degrees to spare), the blockers are the faces lamps' shadow rays meet (not those
// hidden from shadow rays) that lie partly in front of the face and inside its prism towards the sun,
// widened by the penumbra. The face gets a texture when no blocker reaches down to its plane, the engine
// can plan it in one slab (source, blockers and receiver in depth order along the face's normal), its
// blocker error E_rr is within e_max and its predicted FFT time within t_max, at up to max_texture texels
// per side; otherwise (and for faces without blockers, which the rays find in full light with their first
// points) the rays decide as before. One slab, because the engine's product of slab maps is wrong where
// one connected blocker is cut (sun_textures.cpp); blockers parallel to the face are the exact case.
#pragma once
#include <memory>
#include <vector>

#include "convolution/soft_shadow.h"
#include "geometry/box_tree.h"
#include "scene/scene.h"
#include "solve/settings.h"

namespace penumbra {

class SunTextures {
public:
    SunTextures() = default;
    SunTextures(const Scene& sc, const Settings& s, int threads);
    // The visible share (cosine-weighted, of Cycles' sun disk) of light `light` at p (recentred) on face
    // `polygon`, or NaN where there is no texture.
    double visibility(int light, int polygon, const Vec3& p) const;
    size_t made() const { return textures_.size(); }
    size_t refused() const { return refused_; }
    size_t texels() const;

private:
    // A POINT lamp with a radius (Cycles' disk facing the shaded point, not the 4.0+ sphere): the same for
    // each face the lamp stands clear in front of, with the disk facing the face's centre as the source and
    // the blockers from the shaft between the disk and the face.
    void lampTextures(const Scene& sc, const Settings& s, int threads, const BoxTree& tree,
                      const std::vector<int>& blockerIds, const ConvolutionSettings& cs, size_t light);
    static constexpr int kLampDiskVertices = 48;
    std::vector<std::vector<int>> slot_;  // per light, per polygon: index into textures_ or -1
    std::vector<std::shared_ptr<const SoftShadowTexture>> textures_;
    size_t refused_ = 0;
};

}  // namespace penumbra
