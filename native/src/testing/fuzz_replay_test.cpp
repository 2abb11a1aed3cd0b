#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "testing/fuzz_input.h"

namespace penumbra::testing {
namespace {

namespace fs = std::filesystem;

// The source tree, found from this file's own path (CMake compiles it by absolute path).
fs::path regressionDir() { return fs::path(__FILE__).parent_path() / ".." / ".." / "fuzz" / "regressions"; }

std::vector<uint8_t> readFile(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// Every input the fuzzer ever crashed on (and the seeds kept with them) must now run through.
TEST(FuzzRegressions, SavedInputsRunCleanly) {
    fs::path dir = regressionDir();
    ASSERT_TRUE(fs::is_directory(dir)) << dir;
    std::vector<fs::path> files;
    for (auto& e : fs::directory_iterator(dir))
        if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
    std::sort(files.begin(), files.end());
    ASSERT_FALSE(files.empty());
    for (auto& f : files) {
        SCOPED_TRACE(f.filename().string());
        std::vector<uint8_t> bytes = readFile(f);
        EXPECT_NO_THROW(runFuzzInput(bytes.data(), bytes.size()));
    }
}

// Random bytes from a fixed seed: the decoder and the solver's error paths run under the sanitizers
// in CI even between fuzzing sessions. Both outcomes must occur, or the decoder has gone blind.
TEST(FuzzRegressions, RandomInputsSolveOrAreRefused) {
    std::mt19937 rng(7);
    int solved = 0, refused = 0;
    for (int i = 0; i < 300; ++i) {
        std::vector<uint8_t> bytes(64 + rng() % 1500);
        for (auto& b : bytes) b = uint8_t(rng());
        // Keep most indices and values in the ranges the decoder treats as valid, so some scenes solve.
        if (i % 2)
            for (auto& b : bytes) b = uint8_t(b % 200);
        (runFuzzInput(bytes.data(), bytes.size()) == FuzzOutcome::Solved ? solved : refused)++;
    }
    EXPECT_GT(solved, 10);
    EXPECT_GT(refused, 10);
}

}  // namespace
}  // namespace penumbra::testing
