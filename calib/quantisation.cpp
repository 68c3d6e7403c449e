#include "calib/quantisation.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace fpss {
namespace {

double normal_cdf(double z) { return 0.5 * std::erfc(-z / std::numbers::sqrt2); }
double normal_pdf(double z) { return std::exp(-0.5 * z * z) / std::sqrt(2 * std::numbers::pi); }

// Whole counts k with non-negligible probability: within 9 sigma (and at least one either side).
struct Span {
  double lo, hi;
};
Span span_of(double n, double s) {
  const double w = std::ceil(9.0 * s) + 1.0;
  return {std::floor(n) - w, std::floor(n) + w};
}

// Rounding to the nearest whole count: k is reported for n + e in [k - 1/2, k + 1/2).
void moments(double n, double s, double& m1, double& m2) {
  m1 = m2 = 0;
  if (!(s > 0)) {
    m1 = std::round(n);
    m2 = m1 * m1;
    return;
  }
  const Span sp = span_of(n, s);
  // k relative to floor(n) keeps the sums exact at large counts.
  const double base = std::floor(n);
  double sum_p = 0, sum_kp = 0, sum_kkp = 0;
  // Each threshold k + 1/2 is the next count's lower one: its cdf is computed once (k +- 1/2 is exact
  // in floating point, so the sums are the same to the bit).
  double below = normal_cdf((sp.lo - 0.5 - n) / s);
  for (double k = sp.lo; k <= sp.hi; k += 1.0) {
    const double above = normal_cdf((k + 0.5 - n) / s);
    const double p = above - below;
    below = above;
    const double r = k - base;
    sum_p += p;
    sum_kp += r * p;
    sum_kkp += r * r * p;
  }
  const double mr = sum_kp / sum_p;
  m1 = base + mr;
  m2 = sum_kkp / sum_p - mr * mr;  // the variance (central), returned in m2
}

}  // namespace

double expected_rounded_counts(double n, double s) {
  double m1, m2;
  moments(n, s, m1, m2);
  return m1;
}

double rounded_counts_variance(double n, double s) {
  if (!(s > 0)) return 0.0;
  double m1, m2;
  moments(n, s, m1, m2);
  return std::max(0.0, m2);
}

double expected_rounded_slope(double n, double s) {
  if (!(s > 0)) return 0.0;
  const Span sp = span_of(n, s);
  double d = 0;
  for (double k = sp.lo; k <= sp.hi; k += 1.0) d += normal_pdf((k + 0.5 - n) / s) / s;
  return d;
}

double counts_from_rounded_mean(double mean, double s) {
  if (!(s >= kMinQuantisationNoise) || !std::isfinite(mean)) return mean;
  // E[round(n + e)] - n is periodic and smaller than 1/2 in size: the root lies within half a
  // count. Newton, kept inside the bracket (bisection when a step leaves it).
  double lo = mean - 0.5, hi = mean + 0.5, n = mean;
  for (int i = 0; i < 60 && hi - lo > 1e-11; ++i) {
    const double f = expected_rounded_counts(n, s) - mean;
    if (f == 0) return n;
    (f < 0 ? lo : hi) = n;
    const double d = expected_rounded_slope(n, s);
    double next = d > 0 ? n - f / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - n) < 1e-11) return next;
    n = next;
  }
  return n;
}

void CountNoiseEstimator::add(const CountScatter& d) {
  if (d.samples < 2 || !std::isfinite(d.variance) || !std::isfinite(d.mean)) return;
  const double f = static_cast<double>(d.samples - 1);
  dof_ += f;
  pooled_ += f * d.variance;
  const double frac = d.mean - std::floor(d.mean);
  w_[std::min(kBins - 1, static_cast<int>(frac * kBins))] += f;
}

std::optional<double> CountNoiseEstimator::estimate() const {
  // The rounded variance depends on the true count through its fractional part only: the dwells
  // are pooled into bins of frac(mean), weighted by their degrees of freedom. Exact for long dwells;
  // with a few samples per dwell the mean is a noisy guide to the true count and the estimate runs
  // high at low noise (up to ~10 % at 0.3 counts, 5 samples per dwell).
  if (!(dof_ > 0)) return std::nullopt;
  const double pooled = pooled_ / dof_;
  auto model = [&](double s) {
    double v = 0;
    for (int b = 0; b < kBins; ++b) {
      // At the count whose expected rounded value the bin's means are (the raw mean is pulled
      // towards whole counts, where the rounded variance is smallest).
      if (w_[b] > 0) v += w_[b] * rounded_counts_variance(counts_from_rounded_mean((b + 0.5) / kBins, s), s);
    }
    return v / dof_;
  };
  // Far above a count the rounding adds 1/12 (Sheppard) and nothing else.
  if (pooled > 16.0) return std::sqrt(std::max(0.0, pooled - 1.0 / 12.0));
  // The model rises with s: its root in [lo, hi] by regula falsi with the Illinois modification
  // (Dowell and Jarratt, 1971), which keeps the bracket and converges superlinearly: about ten
  // evaluations of the model where bisection took fifty to the same 1e-14.
  double lo = 1e-3, hi = 4.5;
  double f_lo = model(lo) - pooled;
  if (f_lo >= 0) return lo;
  double f_hi = model(hi) - pooled;
  if (f_hi <= 0) return hi;
  int side = 0;  // which end the last step kept: the other end's value is halved when it repeats
  double x = 0.5 * (lo + hi);
  for (int i = 0; i < 100; ++i) {
    double next = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);  // a model that is not finite: bisect
    const bool done = std::abs(next - x) <= 1e-14 * (1.0 + next) || hi - lo <= 1e-14;
    x = next;
    if (done) break;
    const double f = model(x) - pooled;
    if (f == 0) break;
    if (f < 0) {  // NaN counts as above, as it did for bisection
      lo = x;
      f_lo = f;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = x;
      f_hi = f;
      if (side == 1) f_lo *= 0.5;
      side = 1;
    }
  }
  return x;
}

std::optional<double> estimate_count_noise(const CountScatter* dwells, size_t count) {
  CountNoiseEstimator e;
  for (size_t i = 0; i < count; ++i) e.add(dwells[i]);
  return e.estimate();
}

}  // namespace fpss
