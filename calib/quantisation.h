// Whole-count rounding of a noisy count: the expected value and variance of round(n + e), e ~ N(0, s^2),
// as functions of the true continuous count n, their inverse, and the noise from within-dwell scatter.
//
// With little noise (s ~ 0.3 counts) rounding is not fully dithered: E[round(n + e)] - n is a
// periodic function of frac(n) of up to ~0.05 counts, so a dwell mean of many whole counts is a
// biased estimate of n. counts_from_rounded_mean inverts the expectation instead.
#pragma once
#include <cstddef>
#include <optional>

namespace fpss {

// E[round(n + e)], counts.
double expected_rounded_counts(double n, double noise_counts);
// d E[round(n + e)] / dn (> 0 for noise > 0): the sum of the noise density at the rounding thresholds.
double expected_rounded_slope(double n, double noise_counts);
// Var[round(n + e)], counts^2.
double rounded_counts_variance(double n, double noise_counts);
// The n whose expected rounded count is `mean` (the dwell mean of whole counts). Noise below
// kMinQuantisationNoise is not inverted (the expectation is then a staircase): returns `mean`.
double counts_from_rounded_mean(double mean, double noise_counts);
inline constexpr double kMinQuantisationNoise = 0.05;

// One dwell's whole counts as the noise estimate sees them.
struct CountScatter {
  double mean = 0;      // mean of the dwell's whole counts
  double variance = 0;  // sample variance (n - 1 in the denominator)
  size_t samples = 0;
};
// The Gaussian count noise s (before rounding) whose rounded variance, averaged over the dwells at
// their own counts, matches the pooled within-dwell variance (weights n - 1). nullopt without
// scatter (no dwell of two or more samples).
std::optional<double> estimate_count_noise(const CountScatter* dwells, size_t count);

// The same, fed one dwell at a time (memory does not grow with the dwells).
class CountNoiseEstimator {
 public:
  void add(const CountScatter& d);
  std::optional<double> estimate() const;

 private:
  static constexpr int kBins = 1024;  // frac(mean): the rounded variance's only dependence on the count
  double w_[kBins] = {};
  double dof_ = 0, pooled_ = 0;
};

}  // namespace fpss
