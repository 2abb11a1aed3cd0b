// Time model of a convolution link (seed §2.3, §5.2): t = (2 + 2N) * C * n^2 * log2(n), with C
// measured once per process by timing this machine's FFTW (brief §6). The refiner refuses a
// convolution link whose predicted time exceeds t_max.
#pragma once

namespace penumbra {

// Seconds per n^2 log2 n of one real-to-complex n x n transform; calibrated on first use
// (a few tens of ms, more on a cold FFTW wisdom cache) and then fixed.
double fftCostConstant();
// Overrides the calibration (deterministic tests, or a value saved from an earlier run). c > 0.
void setFftCostConstant(double c);

// n is the FFT size actually used (texture resolution plus padding, see ConvolutionPlan::fftSize),
// N the number of sub-blockers.
double predictedSeconds(int n, int N);
bool withinBudget(int n, int N, double t_max);

}  // namespace penumbra
