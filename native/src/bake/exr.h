#pragma once
#include <cstddef>
#include <string>

namespace penumbra {
// Writes a float32 EXR (ZIP). `pixels` holds height rows bottom-to-top (Blender's order) of
// `channels` floats per texel; the file stores them top-to-bottom as image files do.
void writeExr(const std::string& path, const float* pixels, int width, int height, int channels);

// The bytes of an uncompressed float32 B, G, R scanline EXR of the first three of `channels` (3 or 4) floats
// per texel, rows given bottom-to-top as above: the file Blender 3.4's Image.pack() writes for a float image
// with alpha off, byte for byte. exrFileSize gives its length; encodeExr fills `out` with exactly that many.
size_t exrFileSize(int width, int height);
void encodeExr(char* out, const float* pixels, int width, int height, int channels);
}  // namespace penumbra
