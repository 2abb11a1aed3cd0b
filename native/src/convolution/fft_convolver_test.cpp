#include "convolution/fft_convolver.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <random>
#include <thread>
#include <vector>

namespace penumbra {
namespace {

bool smooth(int m) {
    for (int f : {2, 3, 5, 7})
        while (m % f == 0) m /= f;
    return m == 1;
}

TEST(ConvFft, FastSizesAreTheNextSevenSmooth) {
    EXPECT_EQ(fastFftSize(1), 1);
    EXPECT_EQ(fastFftSize(17), 18);
    EXPECT_EQ(fastFftSize(121), 125);
    EXPECT_EQ(fastFftSize(1025), 1029);
    for (int n = 2; n < 3000; ++n) {
        int m = fastFftSize(n);
        ASSERT_GE(m, n);
        ASSERT_TRUE(smooth(m));
        for (int k = n; k < m; ++k) ASSERT_FALSE(smooth(k)) << n;
    }
}

void directCircular(const std::vector<float>& k, const std::vector<float>& b, int N, std::vector<double>& out) {
    out.assign(N * N, 0.0);
    for (int y = 0; y < N; ++y)
        for (int x = 0; x < N; ++x) {
            double s = 0;
            for (int j = 0; j < N; ++j)
                for (int i = 0; i < N; ++i)
                    s += k[j * N + i] * b[((y - j + N) % N) * N + (x - i + N) % N];
            out[y * N + x] = s;
        }
}

void checkConvolution(int N, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> U(0, 1);
    FftConvolver fft(N);
    RealImage k = fft.makeImage(), b = fft.makeImage(), out = fft.makeImage();
    Spectrum ks = fft.makeSpectrum(), scratch = fft.makeSpectrum();
    std::vector<float> kv(N * N), bv(N * N);
    double ksum = 0;
    for (int i = 0; i < N * N; ++i) {
        k[i] = kv[i] = U(rng) < 0.3f ? U(rng) : 0.0f;
        b[i] = bv[i] = U(rng);
        ksum += kv[i];
    }
    fft.forward(k, ks);
    fft.convolveNormalized(ks, ksum, b, scratch, out);
    std::vector<double> ref;
    directCircular(kv, bv, N, ref);
    for (int i = 0; i < N * N; ++i) ASSERT_NEAR(out[i], ref[i] / ksum, 1e-5) << "N=" << N << " i=" << i;
    for (int i = 0; i < N * N; ++i) ASSERT_EQ(b[i], bv[i]);  // input preserved
}

TEST(ConvFft, MatchesDirectCircularConvolution) {
    for (int N : {12, 15, 16, 21, 35}) checkConvolution(N, 100 + N);
}

TEST(ConvFft, ConcurrentPlanningIsSafe) {
    std::vector<std::thread> th;
    std::vector<int> failures(4, 0);
    for (int t = 0; t < 4; ++t)
        th.emplace_back([t, &failures] {
            try {
                checkConvolution(18 + 2 * t, t);  // distinct fresh sizes -> concurrent planner use
            } catch (...) {
                failures[t] = 1;
            }
        });
    for (auto& x : th) x.join();
    for (int f : failures) EXPECT_EQ(f, 0);
}

TEST(ConvFft, WisdomIsSavedToTheConfiguredPath) {
    char dir[] = "/tmp/penumbra_wisdom_XXXXXX";
    ASSERT_NE(mkdtemp(dir), nullptr);
    std::string path = std::string(dir) + "/sub/fftwf.wisdom";
    const char* old = std::getenv("PENUMBRA_FFTW_WISDOM");
    std::string saved = old ? old : "";
    setenv("PENUMBRA_FFTW_WISDOM", path.c_str(), 1);
    EXPECT_EQ(fftwWisdomPath(), path);
    FftConvolver fresh(46);  // a size no other test plans
    struct stat st {};
    EXPECT_EQ(stat(path.c_str(), &st), 0);
    EXPECT_GT(st.st_size, 0);
    // An unwritable location is ignored, not an error.
    setenv("PENUMBRA_FFTW_WISDOM", "/proc/penumbra/none.wisdom", 1);
    EXPECT_NO_THROW(FftConvolver(50));
    if (old) setenv("PENUMBRA_FFTW_WISDOM", saved.c_str(), 1);
    else unsetenv("PENUMBRA_FFTW_WISDOM");
    unlink(path.c_str());
}

TEST(ConvFft, RejectsBadSizes) {
    EXPECT_THROW(FftConvolver(1), std::invalid_argument);
    EXPECT_THROW(FftConvolver(20000), std::invalid_argument);
}

}  // namespace
}  // namespace penumbra
