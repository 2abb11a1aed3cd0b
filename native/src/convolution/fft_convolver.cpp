#include "convolution/fft_convolver.h"

#include <fftw3.h>
#include <sys/stat.h>

#include <cstdlib>
#include <map>
#include <stdexcept>

namespace penumbra {

std::mutex& fftwPlannerMutex() {
    static std::mutex m;
    return m;
}

std::string fftwWisdomPath() {
    if (const char* e = std::getenv("PENUMBRA_FFTW_WISDOM"); e && *e) return e;
    const char* home = std::getenv("HOME");
    if (!home || !*home) return "";
    return std::string(home) + "/.cache/penumbra/fftwf.wisdom";
}

int fastFftSize(int n) {
    if (n <= 1) return 1;
    for (int m = n;; ++m) {
        int r = m;
        for (int f : {2, 3, 5, 7})
            while (r % f == 0) r /= f;
        if (r == 1) return m;
    }
}

template <class T>
FftBuffer<T>::FftBuffer(size_t n) : n_(n) {
    p_ = static_cast<T*>(fftwf_malloc(sizeof(T) * (n ? n : 1)));
    if (!p_) throw std::bad_alloc();
}
template <class T>
FftBuffer<T>::~FftBuffer() {
    if (p_) fftwf_free(p_);
}
template <class T>
FftBuffer<T>& FftBuffer<T>::operator=(FftBuffer&& o) noexcept {
    if (this != &o) {
        if (p_) fftwf_free(p_);
        p_ = o.p_;
        n_ = o.n_;
        o.p_ = nullptr;
        o.n_ = 0;
    }
    return *this;
}
template class FftBuffer<float>;
template class FftBuffer<std::complex<float>>;

namespace {

struct Plans {
    fftwf_plan r2c = nullptr, c2r = nullptr;
};

void makeParentDirs(const std::string& path) {
    for (size_t pos = path.find('/', 1); pos != std::string::npos; pos = path.find('/', pos + 1))
        mkdir(path.substr(0, pos).c_str(), 0755);  // failures surface as a failed export, ignored
}

bool deterministicPlans = false;  // guarded by the planner mutex

// Called with the planner mutex held. Plans live until process exit, like FFTW's own wisdom.
Plans plansFor(int n) {
    static std::map<std::pair<int, bool>, Plans> cache;
    static bool wisdomLoaded = false;
    auto it = cache.find({n, deterministicPlans});
    if (it != cache.end()) return it->second;
    if (deterministicPlans) {
        fftwf_forget_wisdom();  // ESTIMATE would otherwise take a plan MEASURE left in the wisdom
        wisdomLoaded = false;   // so that the next MEASURE plan loads the file again before saving it
        Plans p;
        const size_t real = static_cast<size_t>(n) * n, cplx = static_cast<size_t>(n) * (n / 2 + 1);
        float* r = fftwf_alloc_real(real);
        fftwf_complex* c = fftwf_alloc_complex(cplx);
        p.r2c = fftwf_plan_dft_r2c_2d(n, n, r, c, FFTW_ESTIMATE);
        p.c2r = fftwf_plan_dft_c2r_2d(n, n, c, r, FFTW_ESTIMATE);
        fftwf_free(r);
        fftwf_free(c);
        if (!p.r2c || !p.c2r) throw std::runtime_error("FFTW could not plan a " + std::to_string(n) + "^2 transform");
        cache[{n, true}] = p;
        return p;
    }
    const std::string path = fftwWisdomPath();
    if (!wisdomLoaded) {
        wisdomLoaded = true;
        if (!path.empty()) fftwf_import_wisdom_from_filename(path.c_str());
    }
    // MEASURE plans run 1.4-1.9x faster than ESTIMATE here; the cap keeps a cold first plan of a
    // large size from stalling a link (wisdom makes later runs instant).
    fftwf_set_timelimit(0.5);
    const size_t real = static_cast<size_t>(n) * n, cplx = static_cast<size_t>(n) * (n / 2 + 1);
    float* r = fftwf_alloc_real(real);
    fftwf_complex* c = fftwf_alloc_complex(cplx);
    Plans p;
    p.r2c = fftwf_plan_dft_r2c_2d(n, n, r, c, FFTW_MEASURE);
    p.c2r = fftwf_plan_dft_c2r_2d(n, n, c, r, FFTW_MEASURE);
    fftwf_free(r);
    fftwf_free(c);
    if (!p.r2c || !p.c2r) throw std::runtime_error("FFTW could not plan a " + std::to_string(n) + "^2 transform");
    cache[{n, false}] = p;
    if (!path.empty()) {
        makeParentDirs(path);
        fftwf_export_wisdom_to_filename(path.c_str());
    }
    return p;
}

}  // namespace

void setFftDeterministic(bool on) {
    std::lock_guard<std::mutex> lock(fftwPlannerMutex());
    deterministicPlans = on;
}

FftConvolver::FftConvolver(int n) : n_(n) {
    if (n < 2 || n > 16384) throw std::invalid_argument("FFT size must be in 2..16384");
    std::lock_guard<std::mutex> lock(fftwPlannerMutex());
    Plans p = plansFor(n);
    r2c_ = p.r2c;
    c2r_ = p.c2r;
}

void FftConvolver::forward(const RealImage& image, Spectrum& out) const {
    if (image.size() < realCount() || out.size() < spectrumCount())
        throw std::invalid_argument("FFT buffer too small");
    // r2c out-of-place leaves its input intact; FFTW's signature is simply not const.
    fftwf_execute_dft_r2c(static_cast<fftwf_plan>(r2c_), const_cast<float*>(image.data()),
                          reinterpret_cast<fftwf_complex*>(out.data()));
}

void FftConvolver::inverse(Spectrum& spectrum, RealImage& out) const {
    if (out.size() < realCount() || spectrum.size() < spectrumCount())
        throw std::invalid_argument("FFT buffer too small");
    fftwf_execute_dft_c2r(static_cast<fftwf_plan>(c2r_), reinterpret_cast<fftwf_complex*>(spectrum.data()),
                          out.data());
}

void FftConvolver::multiply(Spectrum& a, const Spectrum& b, float scale) const {
    const size_t m = spectrumCount();
    // Spelled out: std::complex's operator* checks for NaN/inf and calls __mulsc3, 5x slower.
    float* pa = reinterpret_cast<float*>(a.data());
    const float* pb = reinterpret_cast<const float*>(b.data());
    for (size_t i = 0; i < 2 * m; i += 2) {
        const float ar = pa[i], ai = pa[i + 1], br = pb[i], bi = pb[i + 1];
        pa[i] = (ar * br - ai * bi) * scale;
        pa[i + 1] = (ar * bi + ai * br) * scale;
    }
}

void FftConvolver::convolveNormalized(const Spectrum& kernelSpectrum, double kernelSum, const RealImage& image,
                                      Spectrum& scratch, RealImage& out) const {
    forward(image, scratch);
    // FFTW's inverse is unnormalised (a factor N^2); fold it into the kernel-sum normalisation.
    multiply(scratch, kernelSpectrum, static_cast<float>(1.0 / (kernelSum * realCount())));
    inverse(scratch, out);
}

}  // namespace penumbra
