#include "bake/exr.h"

#include <OpenImageIO/imageio.h>

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <vector>

namespace penumbra {

namespace {

// EXR is little-endian whatever the host.
void store32(char* p, uint32_t v) {
    for (int i = 0; i < 4; ++i) p[i] = char((v >> (8 * i)) & 0xffu);
}

void append32(std::string& s, uint32_t v) {
    char b[4];
    store32(b, v);
    s.append(b, 4);
}

uint32_t floatBits(float f) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    return u;
}

void appendAttribute(std::string& s, const char* name, const char* type, const std::string& value) {
    s.append(name).push_back('\0');
    s.append(type).push_back('\0');
    append32(s, uint32_t(value.size()));
    s += value;
}

// Magic, version 2 (single part, scanlines), the attributes Blender's writer gives, in the name order the
// EXR library writes them in, and the header's closing zero.
std::string exrHeader(int width, int height) {
    std::string s("v/1\x01", 4);
    append32(s, 2);
    std::string channels;
    for (const char* c : {"B", "G", "R"}) {                // alphabetical, as EXR stores them
        channels.append(c).push_back('\0');
        append32(channels, 2);                             // FLOAT
        append32(channels, 0);                             // not perceptually linear; reserved bytes
        append32(channels, 1);                             // x sampling
        append32(channels, 1);                             // y sampling
    }
    channels.push_back('\0');
    std::string box;
    for (int v : {0, 0, width - 1, height - 1}) append32(box, uint32_t(v));
    std::string one, dpi;
    append32(one, floatBits(1.0f));
    append32(dpi, floatBits(72.0f));
    appendAttribute(s, "channels", "chlist", channels);
    appendAttribute(s, "compression", "compression", std::string(1, '\0'));     // none
    appendAttribute(s, "dataWindow", "box2i", box);
    appendAttribute(s, "displayWindow", "box2i", box);
    appendAttribute(s, "lineOrder", "lineOrder", std::string(1, '\0'));        // increasing y
    appendAttribute(s, "pixelAspectRatio", "float", one);
    appendAttribute(s, "screenWindowCenter", "v2f", std::string(8, '\0'));
    appendAttribute(s, "screenWindowWidth", "float", one);
    appendAttribute(s, "xDensity", "float", dpi);
    s.push_back('\0');
    return s;
}

void checkShape(int width, int height) {
    // A line's byte count (12 per texel) is a 32-bit int in the file.
    if (width <= 0 || height <= 0 || width > (1 << 24) || height > (1 << 24))
        throw std::invalid_argument("exr: bad image shape");
}

}  // namespace

size_t exrFileSize(int width, int height) {
    checkShape(width, height);
    return exrHeader(width, height).size() + size_t(height) * (8 + 8 + 12 * size_t(width));
}

void encodeExr(char* out, const float* pixels, int width, int height, int channels) {
    checkShape(width, height);
    if (channels < 3 || channels > 4) throw std::invalid_argument("exr: needs 3 or 4 channels");
    const std::string head = exrHeader(width, height);
    std::memcpy(out, head.data(), head.size());
    const size_t line = 8 + 12 * size_t(width);
    const size_t first = head.size() + 8 * size_t(height);
    char* table = out + head.size();
    for (int y = 0; y < height; ++y) {
        const uint64_t at = first + line * size_t(y);
        store32(table + 8 * size_t(y), uint32_t(at & 0xffffffffu));
        store32(table + 8 * size_t(y) + 4, uint32_t(at >> 32));
    }
    for (int y = 0; y < height; ++y) {            // EXR's line y is the y-th from the top
        char* p = out + first + line * size_t(y);
        store32(p, uint32_t(y));
        store32(p + 4, uint32_t(12 * width));
        p += 8;
        const float* row = pixels + (size_t(height) - 1 - size_t(y)) * size_t(width) * size_t(channels);
        for (int c = 2; c >= 0; --c)               // B, G, R: each channel's whole line in turn
            for (int x = 0; x < width; ++x, p += 4) store32(p, floatBits(row[size_t(x) * channels + c]));
    }
}

void writeExr(const std::string& path, const float* pixels, int width, int height, int channels) {
    if (width <= 0 || height <= 0 || channels <= 0 || channels > 4)
        throw std::invalid_argument("writeExr: bad image shape");
    auto out = OIIO::ImageOutput::create(path);
    if (!out) throw std::runtime_error("cannot write '" + path + "': " + OIIO::geterror());
    OIIO::ImageSpec spec(width, height, channels, OIIO::TypeDesc::FLOAT);
    spec.attribute("compression", "zip");
    if (!out->open(path, spec)) throw std::runtime_error("cannot open '" + path + "': " + out->geterror());
    size_t row = size_t(width) * channels;
    // A negative y stride walks the rows from the last (top) to the first (bottom).
    const float* top = pixels + (size_t(height) - 1) * row;
    bool ok = out->write_image(OIIO::TypeDesc::FLOAT, top, OIIO::AutoStride,
                               -OIIO::stride_t(row * sizeof(float)));
    if (!ok || !out->close()) throw std::runtime_error("cannot write '" + path + "': " + out->geterror());
}

}  // namespace penumbra
