// Circular 2-D convolution of real N x N images with FFTW single precision (fftw3f), r2c/c2r.
//
// Plans are made once per size (FFTW_MEASURE, capped in time; see setFftDeterministic) and kept for the process; FFTW's
// planner is not thread-safe, so every planner call in Penumbra must hold fftwPlannerMutex().
// Executing a plan is thread-safe, so many links can convolve at once. Wisdom is loaded from and
// saved to $PENUMBRA_FFTW_WISDOM, else ~/.cache/penumbra/fftwf.wisdom; write failures are ignored.
#pragma once
#include <complex>
#include <cstddef>
#include <mutex>
#include <string>

namespace penumbra {

std::mutex& fftwPlannerMutex();
std::string fftwWisdomPath();

// MEASURE chooses among FFTW's algorithms by timing them, and their roundings differ in the last bits:
// textures are then the same for any thread count within a process, but not between processes that
// planned afresh. With `on`, plans made from then on use FFTW_ESTIMATE without wisdom (forgotten
// before each plan, never saved): the same algorithm, hence the same bits, in every process on one
// machine, at some speed. For tests that compare output with recorded values (testing/golden_test.cpp).
void setFftDeterministic(bool on);

// Smallest 2^a 3^b 5^c 7^d >= n (sizes FFTW handles with its fastest codelets).
int fastFftSize(int n);

// Owning, FFTW-aligned array (all buffers must share FFTW's alignment for plan reuse).
template <class T>
class FftBuffer {
public:
    FftBuffer() = default;
    explicit FftBuffer(size_t n);
    ~FftBuffer();
    FftBuffer(FftBuffer&& o) noexcept : p_(o.p_), n_(o.n_) { o.p_ = nullptr; o.n_ = 0; }
    FftBuffer& operator=(FftBuffer&& o) noexcept;
    FftBuffer(const FftBuffer&) = delete;
    FftBuffer& operator=(const FftBuffer&) = delete;
    T* data() { return p_; }
    const T* data() const { return p_; }
    size_t size() const { return n_; }
    T& operator[](size_t i) { return p_[i]; }
    const T& operator[](size_t i) const { return p_[i]; }

private:
    T* p_ = nullptr;
    size_t n_ = 0;
};
using RealImage = FftBuffer<float>;
using Spectrum = FftBuffer<std::complex<float>>;

class FftConvolver {
public:
    explicit FftConvolver(int n);  // throws std::invalid_argument for n < 2 or n > 16384
    int size() const { return n_; }
    size_t realCount() const { return static_cast<size_t>(n_) * n_; }
    size_t spectrumCount() const { return static_cast<size_t>(n_) * (n_ / 2 + 1); }
    RealImage makeImage() const { return RealImage(realCount()); }
    Spectrum makeSpectrum() const { return Spectrum(spectrumCount()); }

    void forward(const RealImage& image, Spectrum& out) const;
    // Destroys `spectrum` (FFTW's c2r overwrites its input); the result is not divided by N^2.
    void inverse(Spectrum& spectrum, RealImage& out) const;
    // a <- a * b * scale, element-wise.
    void multiply(Spectrum& a, const Spectrum& b, float scale) const;

    // out = (kernel (*) image) / kernelSum, circular, with kernelSpectrum = forward(kernel).
    // `image` is only read; `scratch` is a spectrum-sized work buffer.
    void convolveNormalized(const Spectrum& kernelSpectrum, double kernelSum, const RealImage& image,
                            Spectrum& scratch, RealImage& out) const;

private:
    int n_;
    void* r2c_;
    void* c2r_;
};

}  // namespace penumbra
