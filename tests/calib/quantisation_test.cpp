// Whole-count rounding of a noisy count: expectation, slope and variance against direct quadrature,
// the inverse for a dwell mean, and the noise recovered from within-dwell scatter.
#include "calib/quantisation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace fpss {
namespace {

// E[round(n + e)] and E[round(n + e)^2] by the trapezoid rule over e in +-10 s (independent of the
// library's sum over thresholds).
std::pair<double, double> quadrature(double n, double s) {
  constexpr int kSteps = 200000;
  const double lo = -10 * s, h = 20 * s / kSteps;
  double m1 = 0, m2 = 0, w = 0;
  for (int i = 0; i <= kSteps; ++i) {
    const double e = lo + i * h;
    const double p = std::exp(-0.5 * e * e / (s * s)) * ((i == 0 || i == kSteps) ? 0.5 : 1.0);
    const double k = std::floor(n + e + 0.5);
    m1 += p * k;
    m2 += p * k * k;
    w += p;
  }
  return {m1 / w, m2 / w};
}

TEST(Quantisation, ExpectationSlopeAndVarianceMatchQuadrature) {
  for (double s : {0.1, 0.3, 0.6}) {
    for (double n : {1222.0, 1222.13, 1222.37, 1222.5, 1222.81, -15000.4}) {
      const auto [m1, m2] = quadrature(n, s);
      EXPECT_NEAR(expected_rounded_counts(n, s), m1, 2e-5) << n << " " << s;
      EXPECT_NEAR(rounded_counts_variance(n, s), m2 - m1 * m1, 2e-4) << n << " " << s;
      const double h = 1e-2;  // well above the quadrature grid, small against the period
      const double num = (quadrature(n + h, s).first - quadrature(n - h, s).first) / (2 * h);
      EXPECT_NEAR(expected_rounded_slope(n, s), num, 2e-2 * num + 1e-3) << n << " " << s;
    }
  }
  // At 0.3 counts rounding is not dithered: the mean is biased by a few hundredths of a count.
  EXPECT_GT(std::abs(expected_rounded_counts(10.25, 0.3) - 10.25), 0.02);
  // Well dithered (1 count) it is not.
  EXPECT_LT(std::abs(expected_rounded_counts(10.25, 1.0) - 10.25), 1e-4);
}

TEST(Quantisation, TheInverseRecoversTheTrueCount) {
  for (double n : {0.0, 0.1, 0.25, 0.49, 0.5, 0.77, 16000.3, -3.6}) {
    EXPECT_NEAR(counts_from_rounded_mean(expected_rounded_counts(n, 0.3), 0.3), n, 1e-9) << n;
  }
  // Below the noise where the staircase can be inverted, the mean is returned as it is.
  EXPECT_EQ(counts_from_rounded_mean(12.0, 0.01), 12.0);
}

// Dwells at seeded counts, half of them at one count (as the null dwells are), m frames each.
std::vector<CountScatter> scatter(double s, int m, int dwells) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, s);
  std::uniform_real_distribution<double> u(-5000, 5000);
  std::vector<CountScatter> out;
  for (int k = 0; k < dwells; ++k) {
    const double n = k % 2 ? 1222.3 : u(rng);
    double sum = 0, sum2 = 0;
    for (int i = 0; i < m; ++i) {
      const double c = std::round(n + g(rng));
      sum += c;
      sum2 += c * c;
    }
    out.push_back({sum / m, (sum2 - sum * sum / m) / (m - 1), static_cast<size_t>(m)});
  }
  return out;
}

TEST(Quantisation, NoiseFromWithinDwellScatter) {
  // Long dwells: the mean pins the true count and the estimate is unbiased (121 x 4999 degrees of
  // freedom: sigma to ~0.2 %, 1 % is 5 of those).
  for (double s : {0.2, 0.3, 0.5}) {
    const auto d = scatter(s, 5000, 121);
    EXPECT_NEAR(*estimate_count_noise(d.data(), d.size()), s, 0.01 * s) << s;
  }
  // 100 frames per dwell (29,700 degrees of freedom) at 0.3 and 0.8 counts: within 3 %.
  for (double s : {0.3, 0.8}) {
    const auto d = scatter(s, 100, 300);
    EXPECT_NEAR(*estimate_count_noise(d.data(), d.size()), s, 0.03 * s) << s;
  }
  // Five frames per dwell at 0.3 counts: high by up to ~10 % (the documented short-dwell bias),
  // never low, and far closer than the naive sqrt(variance - 1/12).
  const auto d5 = scatter(0.3, 5, 300);
  const double e5 = *estimate_count_noise(d5.data(), d5.size());
  EXPECT_GT(e5, 0.3);
  EXPECT_LT(e5, 0.34);
  CountScatter single{10, 0, 1};
  EXPECT_FALSE(estimate_count_noise(&single, 1).has_value());
}

}  // namespace
}  // namespace fpss
