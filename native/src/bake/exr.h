#pragma once
#include <string>

namespace penumbra {
// Writes a float32 EXR (ZIP). `pixels` holds height rows bottom-to-top (Blender's order) of
// `channels` floats per texel; the file stores them top-to-bottom as image files do.
void writeExr(const std::string& path, const float* pixels, int width, int height, int channels);
}  // namespace penumbra
