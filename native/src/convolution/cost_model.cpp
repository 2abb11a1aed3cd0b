#include "convolution/cost_model.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <stdexcept>

#include "convolution/fft_convolver.h"

namespace penumbra {

namespace {

std::atomic<double> g_constant{0.0};
std::once_flag g_calibrated;

double calibrate() {
    // Least squares through the origin of best-of-5 timings; the larger sizes dominate the fit,
    // which is where the budget matters.
    double sxy = 0, sxx = 0;
    for (int n : {64, 128, 256, 512}) {
        FftConvolver fft(n);
        RealImage img = fft.makeImage();
        Spectrum spec = fft.makeSpectrum();
        for (size_t i = 0; i < img.size(); ++i) img[i] = static_cast<float>((i * 2654435761u) % 1000) * 1e-3f;
        fft.forward(img, spec);  // warm-up
        double best = HUGE_VAL;
        for (int rep = 0; rep < 5; ++rep) {
            auto t0 = std::chrono::steady_clock::now();
            fft.forward(img, spec);
            best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        }
        double x = static_cast<double>(n) * n * std::log2(static_cast<double>(n));
        sxy += x * best;
        sxx += x * x;
    }
    return sxy / sxx;
}

}  // namespace

double fftCostConstant() {
    std::call_once(g_calibrated, [] {
        if (g_constant.load() == 0.0) g_constant.store(calibrate());
    });
    return g_constant.load();
}

void setFftCostConstant(double c) {
    if (!(c > 0) || !std::isfinite(c)) throw std::invalid_argument("FFT cost constant must be positive");
    g_constant.store(c);
}

double predictedSeconds(int n, int N) {
    if (n < 2 || N < 0) throw std::invalid_argument("predictedSeconds needs n >= 2 and N >= 0");
    double nn = static_cast<double>(n);
    return (2.0 + 2.0 * N) * fftCostConstant() * nn * nn * std::log2(nn);
}

bool withinBudget(int n, int N, double t_max) { return predictedSeconds(n, N) <= t_max; }

}  // namespace penumbra
