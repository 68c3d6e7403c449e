// The FPSS transfer function (paper eq. 1, 2): angle = C1 + C2 N + C3 sin(C4 N + C5) + C6 sin(C7 N + C8).
#pragma once
#include <array>
#include <cmath>
#include <stdexcept>

#include "calib/units.h"

namespace fpss {

// C1..C8 of one axis: radians, N in counts (C4, C7 in rad/count).
using AxisCoeffs = std::array<double, 8>;

// One implementation for doubles and Ceres jets. C is the coefficient type, N the count type.
template <typename C, typename N>
inline auto transfer_angle(const C* c, const N& n) -> decltype(c[0] * n) {
  using std::sin;
  return c[0] + c[1] * n + c[2] * sin(c[3] * n + c[4]) + c[5] * sin(c[6] * n + c[7]);
}

// d angle / d N, rad per count.
template <typename C, typename N>
inline auto transfer_slope(const C* c, const N& n) -> decltype(c[0] * n) {
  using std::cos;
  return c[1] + c[2] * c[3] * cos(c[3] * n + c[4]) + c[5] * c[6] * cos(c[6] * n + c[7]);
}

// A single axis's transfer function with its inverse.
class AxisModel {
 public:
  explicit AxisModel(const AxisCoeffs& c) : c_(c) {}

  double angle_rad(double counts) const { return transfer_angle(c_.data(), counts); }
  double angle_arcsec(double counts) const { return rad_to_arcsec(angle_rad(counts)); }
  double slope_rad_per_count(double counts) const { return transfer_slope(c_.data(), counts); }
  const AxisCoeffs& coeffs() const { return c_; }

  // Throws NotMonotonicError naming the first count where the slope changes sign or vanishes.
  void check_monotonic(double lo_counts = kCountsMin, double hi_counts = kCountsMax) const;

  // Counts N in [lo, hi] with angle(N) = angle_rad. Throws NotMonotonicError when the
  // function is not monotonic over [lo, hi], std::out_of_range when the angle is not reached.
  double counts_for_angle(double angle_rad, double lo_counts = kCountsMin,
                          double hi_counts = kCountsMax) const;
  // The same without the monotonic scan, for callers that checked once (the bench, per frame).
  double counts_for_angle_unchecked(double angle_rad, double lo_counts = kCountsMin,
                                    double hi_counts = kCountsMax) const;

 private:
  AxisCoeffs c_;
};

struct NotMonotonicError : std::domain_error {
  using std::domain_error::domain_error;
};

}  // namespace fpss
