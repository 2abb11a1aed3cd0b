#include "bake/exr.h"

#include <OpenImageIO/imageio.h>

#include <stdexcept>
#include <vector>

namespace penumbra {

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
