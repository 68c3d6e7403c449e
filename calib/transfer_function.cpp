#include "calib/transfer_function.h"

#include <fmt/format.h>

#include <stdexcept>

namespace fpss {
namespace {
// The fastest published sinusoid has a period of ~1e4 counts; a slope sign change cannot
// hide between samples this close.
constexpr double kSlopeScanStep = 16.0;
}  // namespace

void AxisModel::check_monotonic(double lo, double hi) const {
  if (!(lo < hi)) throw std::invalid_argument(fmt::format("empty count range [{}, {}]", lo, hi));
  const double s0 = slope_rad_per_count(lo);
  for (double n = lo;; n = std::min(n + kSlopeScanStep, hi)) {
    const double s = slope_rad_per_count(n);
    if (s == 0.0 || (s > 0) != (s0 > 0)) {
      throw NotMonotonicError(fmt::format(
          "transfer function is not monotonic over [{:.0f}, {:.0f}] counts: slope changes sign "
          "near N = {:.0f}",
          lo, hi, n));
    }
    if (n >= hi) break;
  }
}

double AxisModel::counts_for_angle(double target, double lo, double hi) const {
  check_monotonic(lo, hi);
  return counts_for_angle_unchecked(target, lo, hi);
}

double AxisModel::counts_for_angle_unchecked(double target, double lo, double hi) const {
  double a = lo, b = hi;
  double fa = angle_rad(a) - target, fb = angle_rad(b) - target;
  if (fa == 0.0) return a;
  if (fb == 0.0) return b;
  if ((fa > 0) == (fb > 0)) {
    throw std::out_of_range(fmt::format(
        "angle {:.3f} arcsec is outside the transfer function's range [{:.3f}, {:.3f}] arcsec "
        "over [{:.0f}, {:.0f}] counts",
        rad_to_arcsec(target), rad_to_arcsec(std::min(fa, fb) + target),
        rad_to_arcsec(std::max(fa, fb) + target), lo, hi));
  }
  // Newton steps safeguarded by bisection: monotonic, so the bracket always holds the root.
  double n = a - fa * (b - a) / (fb - fa);
  for (int i = 0; i < 100; ++i) {
    const double f = angle_rad(n) - target;
    if ((f > 0) == (fa > 0)) { a = n; fa = f; } else { b = n; fb = f; }
    double next = n - f / slope_rad_per_count(n);
    if (!(next > std::min(a, b) && next < std::max(a, b))) next = 0.5 * (a + b);
    if (std::abs(next - n) < 1e-9) return next;
    n = next;
  }
  return n;
}

}  // namespace fpss
